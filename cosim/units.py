"""Engineering units of scenario files and FMU variables, converted to SI once at load.

Built on pint (a maintained unit library: parsing, dimensions and factors), with the
navigation spellings that pint reads differently:

=============  =====================================  =================================
written        meaning                                why it needs care
=============  =====================================  =================================
``g``          standard gravity 9.80665 m/s2          pint: gram
``mg``, ``ug``  milli-g, micro-g (``µg`` too)          pint: milligram, microgram
``sqrt(X)``    ``(X)**0.5``                           e.g. ``deg/sqrt(h)``, ``ug/sqrt(Hz)``
``m/s2``       ``m/s**2``                             the FMI habit of writing exponents
``ppm``        1e-6
``1``, ``""``  dimensionless
=============  =====================================  =================================

Angles: pint treats the radian as dimensionless; here the angle exponent is checked
as well, so ``deg/h`` converts to ``rad/s`` but not to ``1/s``.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import pint

from cosim.errors import UnitError

_REG = pint.UnitRegistry()
_REG.define("nav_g = 9.80665 * meter / second ** 2")
_REG.define("nav_mg = 1e-3 * nav_g")
_REG.define("nav_ug = 1e-6 * nav_g")
_REG.define("nav_ppm = 1e-6")

_TOKENS = {"g": "nav_g", "mg": "nav_mg", "ug": "nav_ug", "µg": "nav_ug", "ppm": "nav_ppm"}
_WORD = re.compile(r"(?<![\w.])(µg|ug|mg|g|ppm)(?![\w(])")
_POWER = re.compile(r"(?<=[A-Za-z])(\d+)\b")
_SQRT = re.compile(r"sqrt\(([^()]*)\)")


@dataclass(frozen=True)
class Unit:
    """A parsed unit.

    Attributes
    ----------
    text : str
        The unit as written.
    factor : float
        Multiply a value in this unit by ``factor`` to get SI (pint base units).
    dimension : tuple
        Sorted (dimension, exponent) pairs, the angle included as ``[angle]``.
    """

    text: str
    factor: float
    dimension: tuple[tuple[str, float], ...]

    def compatible(self, other: Unit) -> bool:
        """True when both units measure the same physical quantity."""
        return self.dimension == other.dimension


def _normalise(text: str) -> str:
    s = text.strip()
    if s in ("", "1", "-"):
        return "dimensionless"
    s = s.replace("·", "*").replace("^", "**")
    while _SQRT.search(s):
        s = _SQRT.sub(r"(\1)**0.5", s)
    s = _WORD.sub(lambda m: _TOKENS[m.group(1)], s)
    s = _POWER.sub(r"**\1", s)
    return s


@functools.lru_cache(maxsize=512)
def parse_unit(text: str) -> Unit:
    """Parse a unit string.

    Parameters
    ----------
    text : str
        E.g. ``"deg/h"``, ``"deg/sqrt(h)"``, ``"ug/sqrt(Hz)"``, ``"m/s2"``, ``"arcmin"``.

    Returns
    -------
    Unit

    Raises
    ------
    UnitError
        If the unit is not known.
    """
    try:
        q = _REG.Quantity(1.0, _normalise(text)).to_base_units()
    except Exception as exc:  # pint raises several unrelated types
        raise UnitError(
            f"unknown unit '{text}' (examples of valid units: rad, deg, arcmin, deg/h, "
            f"deg/sqrt(h), ug, ug/sqrt(Hz), m/s2, s, ms)"
        ) from exc
    dims = dict(q.dimensionality)
    angle = dict(q.units._units).get("radian", 0.0)
    if angle:
        dims["[angle]"] = angle
    return Unit(text, float(q.magnitude), tuple(sorted(dims.items())))


def conversion_factor(from_unit: str, to_unit: str) -> float:
    """Factor that converts a value in ``from_unit`` to ``to_unit``.

    Raises
    ------
    UnitError
        If the two units have different dimensions (the message names both).
    """
    a, b = parse_unit(from_unit), parse_unit(to_unit)
    if not a.compatible(b):
        raise UnitError(f"unit '{from_unit}' cannot be converted to '{to_unit}'")
    return a.factor / b.factor


_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def to_unit(value: Any, unit: str) -> float | int | bool | list[float]:
    """Convert a scenario value to ``unit``.

    Parameters
    ----------
    value : number, bool, str, list or dict
        ``12.5`` (already in ``unit``), ``"12.5 deg"``, ``[1, 2, 3]``,
        ``["1 deg", "1 deg", "30 deg"]``, ``{value = [10, 10, 5], unit = "m"}``.
    unit : str
        The target unit (the variable's declared unit).

    Returns
    -------
    float, int, bool or list of float

    Raises
    ------
    UnitError
        Unknown unit, wrong dimension, or a value that is not a number.
    """
    if isinstance(value, bool) or isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float):
        return value
    if isinstance(value, dict):
        if set(value) != {"value", "unit"}:
            raise UnitError(
                f"expected a table with keys 'value' and 'unit', got keys {sorted(value)}"
            )
        inner = value["value"]
        factor = conversion_factor(str(value["unit"]), unit)
        if isinstance(inner, list):
            return [float(x) * factor for x in inner]
        return float(inner) * factor
    if isinstance(value, list):
        return [float(to_unit(v, unit)) for v in value]
    if isinstance(value, str):
        m = _QUANTITY.match(value)
        if not m:
            raise UnitError(f"expected a number with a unit such as '12.5 deg', got '{value}'")
        number, written = float(m.group(1)), m.group(2)
        if not written:
            return number
        return number * conversion_factor(written, unit)
    raise UnitError(f"expected a number, a string like '12.5 deg' or a list, got {value!r}")


def si(value: Any, unit: str) -> np.ndarray:
    """Convert a value in ``unit`` to SI base units (helper for tests and reports)."""
    return np.asarray(value, dtype=float) * parse_unit(unit).factor
