"""The master's clock: the time handed to the blocks at the end of macro step ``n``.

Two rules (``[master] clock``; docs/coupling.md):

- ``"exact"`` (default): ``t_n`` is the double nearest the exact ``t0 + n h``, rounded
  once. ``t0`` and ``h`` are read as the numbers the user meant (:func:`exact_value`:
  ``"0.1 ms"`` is 1/10000 s, not the double nearest it), kept as one integer numerator
  over a common denominator, and ``t_n = (A + n P) / Q`` is one correctly rounded
  integer division (Python's ``int / int``). This is what libcosim's integer-nanosecond
  clock gives for steps that are whole nanoseconds, so both masters hand an FMU the same
  double at every step.
- ``"fmpy"``: ``t_n = t0 + n * h`` in floating point (the double ``h`` times ``n``,
  rounded, plus ``t0``, rounded), the rule of fmpy's ``simulate_fmu`` for co-simulation,
  for bit-for-bit comparisons with it.

Either way a block stepping from ``t_a`` to ``t_b`` is given the step size ``t_b - t_a``
(rounded once), so that its step ends exactly on the clock's ``t_b``.
"""

from __future__ import annotations

import math
from fractions import Fraction

__all__ = ["CLOCKS", "EXACT", "FMPY", "Clock", "exact_value"]

EXACT = "exact"
FMPY = "fmpy"
CLOCKS = (EXACT, FMPY)
#: How far [ulp] the decimal or fraction meant may lie from the double given (a unit
#: conversion such as 100 * 1e-6 s ends 1 ulp from 1e-4).
ULP_TOLERANCE = 2
#: The largest denominator tried for a time that is no short decimal (1/3 s).
MAX_DENOMINATOR = 10**6


def exact_value(value: float | int | Fraction) -> Fraction:
    """The exact number a time setting stands for.

    A Fraction or an int is taken as it is. A float is read as the shortest decimal (up to
    15 significant digits) within :data:`ULP_TOLERANCE` ulp of it: what the user typed
    (``0.0001``), also after a unit conversion that rounded (``100 us`` gives
    ``9.999999999999999e-05``, read as 1/10000); else as the fraction of smallest
    denominator up to :data:`MAX_DENOMINATOR` within that distance (``0.3333333333333333``
    is 1/3); else as the double's own exact value.

    Parameters
    ----------
    value : float, int or Fraction
        A time [s].

    Returns
    -------
    Fraction
        The exact time [s].
    """
    if isinstance(value, Fraction):
        return value
    if isinstance(value, int):
        return Fraction(value)
    x = float(value)
    if x == 0.0 or not math.isfinite(x):
        return Fraction(x)
    exact = Fraction(x)
    tolerance = ULP_TOLERANCE * Fraction(math.ulp(x))
    for digits in range(15):  # 1 to 15 significant digits
        decimal = Fraction(f"{x:.{digits}e}")
        if abs(decimal - exact) <= tolerance:
            return decimal
    simple = exact.limit_denominator(MAX_DENOMINATOR)
    if abs(simple - exact) <= tolerance:
        return simple
    return exact


class Clock:
    """The time of macro step ``n`` under one of the rules :data:`CLOCKS`.

    Parameters
    ----------
    start : float
        Start time t0 [s].
    step : float
        Macro step h [s], > 0.
    rule : str
        :data:`EXACT` or :data:`FMPY`.

    Attributes
    ----------
    start, step : Fraction
        The exact t0 and h [s] (:func:`exact_value`) of the exact rule.
    """

    def __init__(self, start: float, step: float, rule: str = EXACT) -> None:
        if rule not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {rule!r}")
        self.rule = rule
        self._t0, self._h = float(start), float(step)
        self.start, self.step = exact_value(start), exact_value(step)
        q = math.lcm(self.start.denominator, self.step.denominator)
        self._a = self.start.numerator * (q // self.start.denominator)
        self._p = self.step.numerator * (q // self.step.denominator)
        self._q = q
        self.time = self._exact if rule == EXACT else self._fmpy

    def _exact(self, n: int) -> float:
        return (self._a + n * self._p) / self._q

    def _fmpy(self, n: int) -> float:
        return self._t0 + n * self._h

    def __call__(self, n: int) -> float:
        """The time t_n [s] at the end of macro step ``n`` (``t_0`` for ``n = 0``).

        Parameters
        ----------
        n : int
            Macro step count, >= 0.

        Returns
        -------
        float
            t_n [s].
        """
        return self.time(n)
