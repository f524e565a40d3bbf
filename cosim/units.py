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

Units of FMU variables
    An FMU names the unit of each Real variable and may define it in its model
    description: ``<Unit name="degps"><BaseUnit rad="1" s="-1" factor="0.0174..."/></Unit>``
    means ``value_SI = factor * value + offset`` with the SI base exponents given
    (kg, m, s, A, K, mol, cd, rad). :func:`unit_from_fmi` turns such a definition into
    a :class:`Unit`; when an FMU gives no ``BaseUnit`` (FMI exponents are integers, so
    ``deg/sqrt(h)`` cannot be given one) the name is parsed as above. The definition,
    when present, wins over the name: a vendor may call a unit anything.
    A ``displayUnit`` is presentation only: values cross the FMI interface in the
    variable's ``unit``, so display units never enter a conversion.
    Affine units (a non-zero offset, e.g. degC) convert only to themselves: connections
    scale by a factor, they never add an offset.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pint

from cosim.errors import UnitError, shorten
from cosim.models.constants import G0, PPM

_REG: pint.UnitRegistry[Any] = pint.UnitRegistry()
_REG.define(f"nav_g = {G0!r} * meter / second ** 2")
_REG.define("nav_mg = 1e-3 * nav_g")
_REG.define("nav_ug = 1e-6 * nav_g")
_REG.define(f"nav_ppm = {PPM!r}")

_TOKENS = {"g": "nav_g", "mg": "nav_mg", "ug": "nav_ug", "µg": "nav_ug", "ppm": "nav_ppm"}
_WORD = re.compile(r"(?<![\w.])(µg|ug|mg|g|ppm)(?![\w(])")
_POWER = re.compile(r"(?<=[A-Za-z])(\d+)\b")
_PAREN = re.compile(r"(?<![\w.])sqrt\s*\(|[()]")


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
    offset : float
        ``value_SI = factor * value + offset`` (non-zero only for affine units such as degC).
    origin : str
        ``"name"`` (parsed from the text) or ``"BaseUnit"`` (an FMU's unit definition).
    """

    text: str
    factor: float
    dimension: tuple[tuple[str, float], ...]
    offset: float = 0.0
    origin: str = "name"

    def compatible(self, other: Unit) -> bool:
        """True when both units measure the same physical quantity.

        Parameters
        ----------
        other : Unit
            The unit to compare with (angles count as a dimension: ``rad`` and ``1``
            are not compatible).

        Returns
        -------
        bool
        """
        return self.dimension == other.dimension

    def si_text(self) -> str:
        """The dimension in SI base units, e.g. ``"rad s^-1"`` (``"1"`` when dimensionless)."""
        parts = []
        for dim, exp in self.dimension:
            symbol = _SYMBOL.get(dim, dim)
            parts.append(symbol if exp == 1 else f"{symbol}^{exp:g}")
        return " ".join(parts) or "1"


#: FMI ``BaseUnit`` attribute -> pint dimension name (the angle kept apart, as above).
FMI_BASE_UNITS = {
    "kg": "[mass]",
    "m": "[length]",
    "s": "[time]",
    "A": "[current]",
    "K": "[temperature]",
    "mol": "[substance]",
    "cd": "[luminosity]",
    "rad": "[angle]",
}
_SYMBOL = {dim: symbol for symbol, dim in FMI_BASE_UNITS.items()}


#: The longest unit string read (characters); a longer one is refused unread.
MAX_UNIT_CHARS = 200


def _sqrt_powers(s: str) -> str:
    """``sqrt(X)`` -> ``(X)**0.5`` for every (nested) sqrt, in one pass over the text."""
    out: list[str] = []
    opened: list[bool] = []  # per open parenthesis: was it a sqrt(
    i = 0
    for m in _PAREN.finditer(s):
        out.append(s[i : m.start()])
        i = m.end()
        token = m.group()
        if token == ")":
            out.append(")**0.5" if opened and opened.pop() else ")")
        else:
            opened.append(token != "(")
            out.append("(")
    out.append(s[i:])
    return "".join(out)


def _normalise(text: str) -> str:
    s = text.strip()
    if s in ("", "1", "-"):
        return "dimensionless"
    s = s.replace("·", "*").replace("^", "**")
    if "sqrt" in s:
        s = _sqrt_powers(s)
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
    if len(text) > MAX_UNIT_CHARS:
        raise UnitError(
            f"unit {shorten(text)} is longer than the limit of {MAX_UNIT_CHARS} characters"
        )
    try:
        normalised = _normalise(text)
        q = _REG.Quantity(1.0, normalised).to_base_units()
        zero = float(_REG.Quantity(0.0, normalised).to_base_units().magnitude)
    except Exception as exc:  # pint raises several unrelated types
        raise UnitError(
            f"unknown unit {shorten(text)} (examples of valid units: rad, deg, arcmin, deg/h, "
            f"deg/sqrt(h), ug, ug/sqrt(Hz), m/s2, s, ms)"
        ) from exc
    dims = dict(q.dimensionality)
    angle = dict(q.unit_items()).get("radian", 0.0)
    if angle:
        dims["[angle]"] = angle
    dimension = tuple(sorted((k, float(e)) for k, e in dims.items() if e))
    return Unit(text, float(q.magnitude) - zero, dimension, offset=zero)


def unit_from_fmi(
    name: str, exponents: Mapping[str, float], factor: float = 1.0, offset: float = 0.0
) -> Unit:
    """A unit from an FMU's ``<Unit><BaseUnit .../></Unit>`` definition.

    Parameters
    ----------
    name : str
        The unit's name in the model description (any text: ``"degps"``, ``"deg/s"``).
    exponents : mapping of str to number
        ``BaseUnit`` exponents by attribute name (keys of :data:`FMI_BASE_UNITS`);
        zero or missing exponents are ignored.
    factor, offset : float
        ``value_SI = factor * value + offset``.

    Returns
    -------
    Unit

    Raises
    ------
    UnitError
        An exponent attribute that FMI does not define, or a factor that is not > 0.
    """
    dims = []
    for key, exp in exponents.items():
        if key not in FMI_BASE_UNITS:
            raise UnitError(
                f"unit '{name}': expected BaseUnit exponents among "
                f"{', '.join(FMI_BASE_UNITS)}, got '{key}'"
            )
        if exp:
            dims.append((FMI_BASE_UNITS[key], float(exp)))
    if not factor > 0.0:
        raise UnitError(f"unit '{name}': expected a BaseUnit factor > 0, got {factor!r}")
    return Unit(name, float(factor), tuple(sorted(dims)), float(offset), origin="BaseUnit")


def resolve_unit(unit: str | Unit) -> Unit:
    """``unit`` itself when it is a :class:`Unit`, else :func:`parse_unit` of the text.

    Parameters
    ----------
    unit : str or Unit
        Unit text (e.g. ``"deg/h"``) or an already resolved unit.

    Returns
    -------
    Unit

    Raises
    ------
    UnitError
        If the text is not a known unit.
    """
    return unit if isinstance(unit, Unit) else parse_unit(unit)


def conversion_factor(from_unit: str | Unit, to_unit: str | Unit) -> float:
    """Factor that converts a value in ``from_unit`` to ``to_unit``.

    Parameters
    ----------
    from_unit, to_unit : str or Unit
        Unit texts (parsed) or resolved units (e.g. from an FMU's unit definitions).

    Returns
    -------
    float
        ``value_in_to_unit = factor * value_in_from_unit``.

    Raises
    ------
    UnitError
        If the two units have different dimensions (the message names both, and their
        dimensions in SI base units), or if one of them is affine and they differ.
    """
    a, b = resolve_unit(from_unit), resolve_unit(to_unit)
    if not a.compatible(b):
        notes = [n for n in (name_disagreement(a), name_disagreement(b)) if n]
        tail = f"; {'; '.join(notes)}" if notes else ""
        raise UnitError(
            f"unit '{a.text}'{_defined(a)} cannot be converted to '{b.text}'{_defined(b)} "
            f"(dimensions {a.si_text()} and {b.si_text()}){tail}"
        )
    if a.offset or b.offset:
        if (a.factor, a.offset) == (b.factor, b.offset):
            return 1.0
        raise UnitError(
            f"unit '{a.text}' cannot be converted to '{b.text}': one of them has an offset "
            f"(affine units such as degC convert only to themselves; expected a unit "
            f"without offset, got offsets {a.offset:g} and {b.offset:g})"
        )
    return a.factor / b.factor


def _defined(u: Unit) -> str:
    """`` (BaseUnit: 0.001 s)`` for an FMU's unit whose name does not say it, else nothing."""
    if u.origin != "BaseUnit":
        return ""
    try:
        said = not name_disagreement(u) and parse_unit(u.text) is not None
    except UnitError:
        said = False
    return "" if said else f" (BaseUnit: {u.factor:.10g} {u.si_text()})"


def name_disagreement(unit: Unit) -> str:
    """What is wrong when an FMU's unit definition says something else than its name.

    FMI makes the ``BaseUnit`` definition authoritative: the name is a label. A name that
    reads as another unit (``deg/h`` defined with the factor of ``deg/s``, or
    ``deg/sqrt(h)`` given integer exponents) is almost always a vendor's mistake, so it
    is reported with both readings and the factor that is used.

    Parameters
    ----------
    unit : Unit
        A unit, normally from :func:`unit_from_fmi`.

    Returns
    -------
    str
        Empty when the unit is not an FMU definition, its name is no unit pint knows
        (``degps``), or name and definition agree (factor to 1e-9, dimension, offset);
        else one sentence.
    """
    if unit.origin != "BaseUnit":
        return ""
    try:
        named = parse_unit(unit.text)
    except UnitError:
        return ""
    if (
        named.compatible(unit)
        and math.isclose(named.factor, unit.factor, rel_tol=1e-9)
        and math.isclose(named.offset, unit.offset, rel_tol=1e-9, abs_tol=1e-12)
    ):
        return ""
    return (
        f"unit '{unit.text}': its name reads {named.factor:.10g} {named.si_text()} but its "
        f"BaseUnit defines {unit.factor:.10g} {unit.si_text()}; the definition is used "
        f"(FMI: the definition wins over the name), factor {unit.factor:.10g} to SI"
    )


_NUMBER = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


def to_unit(value: Any, unit: str | Unit) -> float | int | bool | list[float]:
    """Convert a scenario value to ``unit``.

    Parameters
    ----------
    value : number, bool, str, list or dict
        ``12.5`` (already in ``unit``), ``"12.5 deg"``, ``[1, 2, 3]``,
        ``["1 deg", "1 deg", "30 deg"]``, ``{value = [10, 10, 5], unit = "m"}``.
    unit : str or Unit
        The target unit (the variable's declared unit, or its resolved definition).

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
        items = inner if isinstance(inner, list) else [inner]
        for x in items:
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                raise UnitError(
                    f"expected the 'value' of a {{value, unit}} table to be a number or a "
                    f"flat list of numbers, got {shorten(inner)}"
                )
        if isinstance(inner, list):
            return [float(x) * factor for x in inner]
        return float(inner) * factor
    if isinstance(value, list):
        for v in value:
            if isinstance(v, (list, dict)):
                raise UnitError(
                    f"expected a flat list of numbers or strings such as '1 deg', got a "
                    f"nested {'list' if isinstance(v, list) else 'table'} {shorten(v)}"
                )
        return [float(to_unit(v, unit)) for v in value]
    if isinstance(value, str):
        m = _NUMBER.match(value)
        if not m:
            raise UnitError(
                f"expected a number with a unit such as '12.5 deg', got {shorten(value)}"
            )
        number, written = float(m.group(1)), value[m.end() :].strip()
        if not written:
            return number
        return number * conversion_factor(written, unit)
    raise UnitError(f"expected a number, a string like '12.5 deg' or a list, got {value!r}")


def si(value: Any, unit: str | Unit) -> np.ndarray:
    """Convert a value in ``unit`` to SI base units (helper for tests and reports).

    Parameters
    ----------
    value : float or array_like
        Value(s) in ``unit``.
    unit : str or Unit
        Their unit, e.g. ``"deg/h"`` (affine units such as degC get their offset).

    Returns
    -------
    ndarray, same shape as ``value``
        ``factor * value + offset`` in SI base units (angles in rad).
    """
    u = resolve_unit(unit)
    return np.asarray(value, dtype=float) * u.factor + u.offset
