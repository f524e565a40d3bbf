"""FMI variables as the master sees them, and as an FMU's model description declares them.

The scalar :class:`Variable` record, scalar names, rename maps, and reading variables
and units from an FMU's model description.

Both hosts (:mod:`cosim.blocks`) describe their blocks with these records; check-fmu and the
role specs (:mod:`cosim.interop`) read FMUs with the same functions.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import math
import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from cosim.errors import FmuError, UnitError
from cosim.units import Unit, unit_from_fmi


class UnitWarning(UserWarning):
    """An FMU's unit name says something else than its definition (the definition is used)."""


#: Variable types that connections and the recorder handle.
REAL = "Real"


@dataclass(frozen=True)
class ArrayElement:
    """Where a scalar sits in an FMI 3 array variable (:mod:`cosim.arrays`).

    Attributes
    ----------
    array : str
        The array's name.
    array_vr : int
        The array's FMI value reference.
    index : int
        The element's position in the array, row-major, 0-based.
    shape : tuple of int
        The array's shape.
    """

    array: str
    array_vr: int
    index: int
    shape: tuple[int, ...]


@dataclass(frozen=True)
class Variable:
    """One scalar variable of a block.

    Attributes
    ----------
    name : str
        Scalar name, ``x`` or ``x[i]`` for vector elements.
    vr : int
        Value reference.
    type : str
        ``"Real"``, ``"Integer"``, ``"Boolean"`` or ``"String"``.
    causality : str
        FMI causality (``parameter``, ``input``, ``output``, ``local``, ...).
    variability : str
        FMI variability.
    unit : str
        Unit as declared (``"1"`` when none).
    start : Any
        Start value, or None when the block declares none.
    description : str
        The block's description of the variable.
    unit_def : Unit or None
        The unit as defined by the FMU's ``UnitDefinitions`` (``BaseUnit`` exponents,
        factor, offset), or None when the FMU gives no definition (the name is parsed).
    fmu_name : str
        The variable's own name in the FMU when a rename map exposes it under ``name``
        (empty when not renamed).
    items : tuple of (str, int)
        An Enumeration variable's items (name, value) from its declared type (empty for
        other types, or when the FMU declares none).
    element : ArrayElement or None
        For an element of an FMI 3 array: its array and place (then :attr:`vr` is an
        element reference, not an FMI value reference); None for a scalar.
    """

    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: str = "1"
    start: Any = None
    description: str = ""
    unit_def: Unit | None = None
    fmu_name: str = ""
    items: tuple[tuple[str, int], ...] = ()
    element: ArrayElement | None = None

    @property
    def conversion_unit(self) -> str | Unit:
        """What unit conversions use: the FMU's unit definition when it has one, else the name."""
        return self.unit_def if self.unit_def is not None else self.unit

    @property
    def own_name(self) -> str:
        """The variable's name in its block or FMU (differs from :attr:`name` when renamed)."""
        return self.fmu_name or self.name


#: A scalar variable name a scenario can use: ``name``, ``name[i]`` or ``name[i,j]``.
SCALAR_NAME = re.compile(r"^[A-Za-z_]\w*(\[[1-9]\d*(,[1-9]\d*)*\])?$")


def apply_rename(
    variables: Mapping[str, Variable], mapping: Mapping[str, str], owner: str
) -> dict[str, Variable]:
    """The variables with names changed by a rename map.

    Parameters
    ----------
    variables : mapping of str to Variable
        A block's variables by name (declaration order).
    mapping : mapping of str to str
        Own name -> new name. A key may also be the base of a vector (``acc`` for
        ``acc[1]`` .. ``acc[n]``) when the value is a base name too (``f_meas_b``): each
        element is renamed (``acc[i]`` -> ``f_meas_b[i]``). Variables not in the map
        keep their names.
    owner : str
        Who the variables belong to, for messages (``"block 'imu'"``).

    Returns
    -------
    dict
        New name -> :class:`Variable` (``name`` changed, ``fmu_name`` the own name).

    Raises
    ------
    FmuError
        A key that names no variable (with the closest names), a new name that is not
        ``name`` or ``name[i]``, or two variables that would share a name.
    """
    by_own = {v.own_name: v for v in variables.values()}
    scalar: dict[str, str] = {}
    for old, new in mapping.items():
        if not isinstance(new, str) or not SCALAR_NAME.match(new):
            raise FmuError(
                f"{owner}: rename '{old}': expected a new name like 'dtheta_meas_b[1]' or "
                f"'lat', got {new!r}"
            )
        if old in by_own:
            scalar[old] = new
            continue
        elements = [n for n in by_own if n.startswith(f"{old}[") and n.endswith("]")]
        if elements and "[" not in new:
            for n in elements:
                scalar[n] = f"{new}{n[len(old) :]}"
            continue
        hint = difflib.get_close_matches(old, list(by_own), n=3)
        tip = f" Closest names: {', '.join(hint)}." if hint else ""
        raise FmuError(f"{owner}: rename: expected a variable of the FMU, got '{old}'.{tip}")
    out: dict[str, Variable] = {}
    for v in variables.values():
        new = scalar.get(v.own_name, v.name)
        if new in out:
            first = out[new].own_name
            raise FmuError(
                f"{owner}: rename: '{v.own_name}' and '{first}' would both be called "
                f"'{new}'; expected one variable per name (rename or drop one of them)"
            )
        out[new] = v if new == v.name else dataclasses.replace(v, name=new, fmu_name=v.own_name)
    return out


#: FMI 3 types that the host maps onto the FMI 2 type names the rest of ins-cosim uses.
_FMI3_TYPES = {"Float64": "Real", "Int32": "Integer"}
#: The other FMI 3 numeric types, kept under their own names (integer ranges by name).
FMI3_NUMERIC_TYPES = (
    "Float32",
    "Int8",
    "UInt8",
    "Int16",
    "UInt16",
    "UInt32",
    "Int64",
    "UInt64",
)


def fmu_units(md: Any) -> dict[str, Unit | None]:
    """The unit definitions of a model description.

    Parameters
    ----------
    md : fmpy.model_description.ModelDescription
        The FMU's model description.

    Returns
    -------
    dict
        Unit name -> :class:`~cosim.units.Unit` built from its ``BaseUnit``, or None for
        a unit declared without one (its name will be parsed).

    Raises
    ------
    FmuError
        A ``BaseUnit`` that cannot be read (e.g. a factor of 0).
    """
    out: dict[str, Unit | None] = {}
    for u in md.unitDefinitions:
        b = u.baseUnit
        if b is None:
            out[u.name] = None
            continue
        exponents = {k: getattr(b, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")}
        try:
            out[u.name] = unit_from_fmi(u.name, exponents, float(b.factor), float(b.offset))
        except UnitError as exc:
            raise FmuError(f"model description: {exc.message}") from exc
    return out


def fmu_variables(md: Any) -> dict[str, Variable]:
    """The scalar variables of a model description, as :class:`Variable` s.

    Parameters
    ----------
    md : fmpy.model_description.ModelDescription
        FMI 2.0 or 3.0.

    Returns
    -------
    dict
        Name -> Variable, in declaration order. FMI 3 ``Float64`` and ``Int32`` are
        reported as ``Real`` and ``Integer``; other FMI 3 types keep their names.

    Raises
    ------
    FmuError
        A bad unit definition.

    Notes
    -----
    An FMI 3 array variable becomes one scalar per element (:mod:`cosim.arrays`).
    """
    units = fmu_units(md)
    out: dict[str, Variable] = {}
    element_vrs = iter(range(ELEMENT_VR_BASE, ELEMENT_VR_BASE + 2**31))
    for v in md.modelVariables:
        array = bool(getattr(v, "dimensions", None))
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        vtype = _FMI3_TYPES.get(v.type, v.type)
        start = None if array else v.start
        if start is not None and vtype == "Real":
            start = float(start)
        elif start is not None and vtype == "Integer":
            start = int(start)
        elif start is not None and vtype == "Boolean":
            start = start in (True, "true", "1", 1)
        var = Variable(
            name=v.name,
            vr=v.valueReference,
            type=vtype,
            causality=v.causality,
            variability=v.variability or "continuous",
            unit=unit or "1",
            start=start,
            description=v.description or "",
            unit_def=units.get(unit) if unit else None,
            items=_items(v) if vtype == "Enumeration" else (),
        )
        for e in expand_array(v, var, element_vrs.__next__) if array else [var]:
            out[e.name] = e
    return out


def _items(v: Any) -> tuple[tuple[str, int], ...]:
    """The (name, value) items of an Enumeration variable's declared type."""
    declared = getattr(v, "declaredType", None)
    return tuple((i.name, int(i.value)) for i in getattr(declared, "items", None) or ())


#: Element references start here (above every uint32 FMI value reference).
ELEMENT_VR_BASE = 2**32


def element_names(name: str, shape: tuple[int, ...]) -> Iterator[str]:
    """The scalar names of an array's elements, row-major.

    Parameters
    ----------
    name : str
        The array's name.
    shape : tuple of int
        Its shape.

    Returns
    -------
    iterator of str
        ``x[1]``, ``x[2]``, ... for one dimension; ``A[1,1]``, ``A[1,2]``, ... for more.
    """
    for index in itertools.product(*(range(1, n + 1) for n in shape)):
        yield f"{name}[{','.join(str(i) for i in index)}]"


def element_starts(start: Any, vtype: str, size: int) -> list[Any]:
    """An array's start values, one per element (None where the FMU declares none).

    Parameters
    ----------
    start : str or None
        The ``start`` attribute as fmpy reads it (values separated by blanks).
    vtype : str
        The variable type.
    size : int
        The number of elements.

    Returns
    -------
    list
        ``size`` values (float, int or bool); one start value is used for every element.
    """
    if start is None:
        return [None] * size
    words = str(start).split()
    if len(words) == 1:
        words *= size
    if len(words) != size:
        return [None] * size
    if vtype in ("Float64", "Float32", "Real"):
        return [float(w) for w in words]
    if vtype == "Boolean":
        return [w in ("true", "1") for w in words]
    if vtype in ("String", "Binary"):
        return words
    return [int(w) for w in words]


def expand_array(v: Any, base: Variable, next_vr: Callable[[], int]) -> list[Variable]:
    """The element variables of an FMI 3 array variable.

    Parameters
    ----------
    v : fmpy.model_description.ModelVariable
        The array (``v.shape`` set by fmpy).
    base : Variable
        The array as one variable (name, type, causality, unit, ...; start unused).
    next_vr : callable
        Gives the next free element reference.

    Returns
    -------
    list of Variable
        One per element, row-major.
    """
    shape = tuple(int(n) for n in v.shape)
    starts = element_starts(v.start, v.type, math.prod(shape))
    return [
        dataclasses.replace(
            base,
            name=name,
            vr=next_vr(),
            start=start,
            element=ArrayElement(array=base.name, array_vr=base.vr, index=i, shape=shape),
        )
        for i, (name, start) in enumerate(zip(element_names(base.name, shape), starts, strict=True))
    ]
