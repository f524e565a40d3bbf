"""Checks across a system's blocks before a run: step multiples and values blocks share.

Two optional class attributes of a block class (a :class:`models.block.Block` subclass)
feed them, so no check knows a class by name:

- ``step_multiples``: Real parameters [s] that must be whole multiples of the block's own
  step (the master step times the block's ``rate``), e.g. a filter's update period.
  A period off the grid is refused here, before the first step, with the block, the key,
  both values rounded to nine significant digits and the two nearest periods that work
  (at run time the filter would stop at its first update).
- ``shared_values``: parameters that state a quantity another block states too
  (parameter name -> quantity, e.g. ``{"lat0": "latitude"}`` on the base and
  ``{"lat": "latitude"}`` on the filter). Every block of the system that declares a
  quantity must give it the same value (given, or its default): a filter told 45 deg
  while the base stands at 60 deg computes the wrong earth rate and gravity, and its
  heading error then holds a bias its sigma does not know. The scenario is refused
  (not warned about), naming both keys and values.

Blocks run from an FMU carry no class here and are not checked.
"""

from __future__ import annotations

import math
from typing import Any

from cosim.errors import ScenarioError

__all__ = ["SHARED_RTOL", "STEP_RTOL", "check_blocks", "show"]

#: Relative tolerance of "a whole multiple of the step".
STEP_RTOL = 1e-9
#: Relative tolerance within which two blocks' shared values agree.
SHARED_RTOL = 1e-9


def show(value: float, unit: str) -> str:
    """A value for a message, rounded to nine significant digits (a time also in ms).

    Parameters
    ----------
    value : float
        In SI ``unit``.
    unit : str
        ``"s"`` (shown in ms below 1 s), ``"rad"`` (shown in deg) or another unit.

    Returns
    -------
    str
        E.g. ``"10 ms"`` for 0.009999999999999787 s, ``"45 deg"`` for 0.7853981633974483 rad.
    """
    if unit == "s" and 0.0 < abs(value) < 1.0:
        return f"{value * 1e3:.9g} ms"
    if unit == "rad":
        return f"{math.degrees(value):.9g} deg"
    return f"{value:.9g} {unit}".rstrip()


def _value(system: Any, name: str, var: str) -> tuple[float, bool]:
    """A block's parameter value (given in the scenario, else its start) and if given."""
    given = system.parameters.get(name, {})
    if var in given:
        return float(given[var]), True
    return float(system.blocks[name].variables[var].start), False


def check_blocks(system: Any, step: float) -> None:
    """Refuse periods off a block's step grid and shared values that disagree.

    Parameters
    ----------
    system : cosim.master.System
        Hosts, given parameters and rates.
    step : float
        The master's macro step [s].

    Raises
    ------
    ScenarioError
        One line with the key (``blocks.<name>.parameters.<parameter>``), the values and
        the fix.
    """
    shared: dict[str, tuple[str, str, float, str, bool]] = {}
    for name, host in system.blocks.items():
        cls = getattr(host, "cls", None)
        if cls is None:
            continue
        for var in getattr(cls, "step_multiples", ()):
            _check_multiple(system, name, var, step)
        for var, quantity in getattr(cls, "shared_values", {}).items():
            value, given = _value(system, name, var)
            unit = host.variables[var].unit
            first = shared.setdefault(quantity, (name, var, value, unit, given))
            if first[0] == name:
                continue
            other, other_var, other_value, _, other_given = first
            if abs(value - other_value) <= SHARED_RTOL * max(abs(value), abs(other_value)):
                continue
            raise ScenarioError(
                f"{_said(name, var, value, unit, given)} disagrees with "
                f"{_said(other, other_var, other_value, unit, other_given)}: both state the "
                f"{quantity}; give both the same value",
                key=f"blocks.{name}.parameters.{var}",
            )


def _said(block: str, var: str, value: float, unit: str, given: bool) -> str:
    """``blocks.<block>.parameters.<var> = <value>``, marked when it is the default."""
    how = "" if given else " (its default)"
    return f"blocks.{block}.parameters.{var} = {show(value, unit)}{how}"


def _check_multiple(system: Any, name: str, var: str, step: float) -> None:
    """Refuse ``var`` of block ``name`` unless it is a whole multiple of the block's step."""
    rate = system.rates.get(name, 1)
    h = step * rate
    period, _ = _value(system, name, var)
    if not period > 0.0:  # the block's own check says what a period must be
        return
    k = round(period / h)
    if k >= 1 and abs(k * h - period) <= STEP_RTOL * period:
        return
    lo, hi = max(1, math.floor(period / h)) * h, max(1, math.ceil(period / h)) * h
    fix = show(hi, "s") if lo == hi else f"{show(lo, 's')} or {show(hi, 's')}"
    grid = f"master step {show(step, 's')}" + (f" x rate {rate}" if rate != 1 else "")
    raise ScenarioError(
        f"blocks.{name}.parameters.{var} = {show(period, 's')} is not a whole multiple of "
        f"the block's step {show(h, 's')} ({grid}): use {fix}",
        key=f"blocks.{name}.parameters.{var}",
    )
