"""Parameter bindings of an SSP archive: ``.ssv`` parameter sets and ``.ssm`` mappings.

What :func:`bind_parameters` applies, in the standard's order of precedence (a binding at
a higher level of the hierarchy wins over one below it; at one level a later binding wins
over an earlier one):

- ``ssd:ParameterBinding`` of a component (names are the FMU's variable names), of a
  sub-system or of the top-level system (hierarchical names ``Element.variable``,
  ``Sub.Element.variable``), optionally with a ``prefix`` prepended to the set's names;
- the parameter set inline (``ssd:ParameterValues/ssv:ParameterSet``) or in an ``.ssv``
  file of the archive (``source=``); ``ssv:Real`` (SSP 2.0: ``ssv:Float64``) values with a
  ``unit`` are converted to the FMU variable's unit with ins-cosim's units module (unit
  definitions from the set's ``ssv:Units``, the SSD's ``ssd:Units``, else the unit's
  name as ins-cosim reads it: ``deg``, ``min``, ``deg/h``); a unit none of these knows is
  refused in one line naming the file and the parameter;
- a parameter mapping (``ssd:ParameterMapping``: an ``.ssm`` file of the archive, or
  inline ``ssm:ParameterMapping``): each ``ssm:MappingEntry`` binds the set's parameter
  ``source`` to the variable ``target``, with an optional transformation applied after
  the unit conversion (``suppressUnitConversion="true"``: no conversion):
  ``ssc:LinearTransformation`` (``factor * value + offset``),
  ``ssc:BooleanMappingTransformation``, ``ssc:IntegerMappingTransformation`` and
  ``ssc:EnumerationMappingTransformation`` (``ssc:MapEntry source -> target``; a value
  the map does not list is refused). Parameters the mapping does not name bind by name.

A name that is no variable of the component is refused (the standard lets a tool ignore
it; a misspelt parameter then passes unnoticed), as is a parameter bound to an output.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any
from xml.etree import ElementTree as ET

from cosim.errors import UnitError
from cosim.interop.ssp_xml import NS, SSD_FILE, SSP2_TYPES, Archive, local, read_units
from cosim.scenario import BlockSpec
from cosim.units import Unit, conversion_factor
from cosim.variables import Variable

_VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary", *SSP2_TYPES)
_SET = "application/x-ssp-parameter-set"
_MAPPING = "application/x-ssp-parameter-mapping"


@dataclass
class Mapping:
    """One ``ssm:MappingEntry``: the variable a set's parameter binds to, and how.

    Attributes
    ----------
    target : str
        The name it binds to (relative to the binding's element).
    suppress : bool
        ``suppressUnitConversion``.
    transform : callable or None
        The value's transformation (after unit conversion).
    where : str
        The file it is in (for errors).
    """

    target: str
    suppress: bool
    transform: Callable[[Any], Any] | None
    where: str


#: Resolves a name relative to an element of the hierarchy to (block, FMU variable name);
#: None when it names nothing.
Resolver = Callable[[str], "tuple[str, str] | None"]


def bind_binding_list(
    archive: Archive,
    element: ET.Element,
    owner: str,
    resolve: Resolver,
    blocks: dict[str, BlockSpec],
    variables: dict[str, dict[str, Variable]],
    ssd_units: dict[str, Unit],
) -> None:
    """Apply the ``ssd:ParameterBindings`` of one component or system, in order.

    Parameters
    ----------
    archive : Archive
        Where the files are and errors point.
    element : Element
        The ``ssd:Component`` or ``ssd:System``.
    owner : str
        How errors name the element (``Component 'imu'``, ``System 'deck'``).
    resolve : callable
        Name relative to the element -> (block, FMU variable), or None.
    blocks : dict
        Block specs; the values are written into their ``parameters``.
    variables : dict
        Block -> FMU variable name -> :class:`~cosim.variables.Variable`.
    ssd_units : dict
        The SSD's unit definitions.
    """
    bindings = element.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)
    for i, binding in enumerate(bindings):
        bwhere = f"{owner}/ParameterBinding[{i + 1}]"
        btype = binding.get("type", _SET)
        if btype != _SET:
            raise archive.error(
                SSD_FILE, bwhere, f"type {btype!r}; expected {_SET} (an .ssv parameter set)"
            )
        source = binding.get("source")
        if source is not None:
            inner = archive.member(source, (SSD_FILE, f"{bwhere} source"), "an .ssv file in it")
            pset = archive.xml(
                inner, "SystemStructureParameterValues.xsd", (SSD_FILE, f"{bwhere} source")
            )
            file = inner
        else:
            found = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if found is None:
                continue
            pset, file = found, SSD_FILE
        mappings = _mappings(archive, binding, bwhere)
        prefix = binding.get("prefix", "")
        set_units = read_units(pset.find("ssv:Units", NS), f"{archive.path}!{file}")
        for p in pset.findall("ssv:Parameters/ssv:Parameter", NS):
            pname = p.get("name", "")
            pwhere = f"Parameter '{pname}'" + (
                f" ({bwhere})" if file != SSD_FILE else f" of {bwhere}"
            )
            mapping = mappings.get(pname)
            name = mapping.target if mapping else prefix + pname
            found_var = resolve(name)
            if found_var is None:
                close = difflib.get_close_matches(
                    name, [f"{b}.{v}" for b in variables for v in variables[b]], n=3
                )
                tip = f" Closest: {', '.join(close)}." if close else ""
                raise archive.error(
                    mapping.where if mapping else file,
                    pwhere,
                    f"{owner} has no variable '{name}'; name a variable of the FMU "
                    f"(hierarchical names Element.variable at system level).{tip}",
                )
            block, var_name = found_var
            var = variables[block][var_name]
            if var.causality not in ("parameter", "input"):
                raise archive.error(
                    file,
                    pwhere,
                    f"'{block}.{var_name}' is an {var.causality}; only parameters and inputs "
                    f"can be set",
                )
            suppress = mapping.suppress if mapping else False
            value = _value(p, var, archive, file, pwhere, set_units, ssd_units, suppress)
            if mapping and mapping.transform is not None:
                value = mapping.transform(value)
            spec = blocks[block]
            spec.parameters[spec.rename.get(var_name, var_name)] = value


def _mappings(archive: Archive, binding: ET.Element, bwhere: str) -> dict[str, Mapping]:
    """The ``ssm:MappingEntry`` elements of a binding's parameter mapping, by source."""
    element = binding.find("ssd:ParameterMapping", NS)
    if element is None:
        return {}
    where = f"{bwhere}/ParameterMapping"
    mtype = element.get("type", _MAPPING)
    if mtype != _MAPPING:
        raise archive.error(SSD_FILE, where, f"type {mtype!r}; expected {_MAPPING} (.ssm)")
    if element.get("source") is not None:
        inner = archive.member(
            element.get("source", ""), (SSD_FILE, f"{where} source"), "an .ssm file in it"
        )
        root = archive.xml(
            inner, "SystemStructureParameterMapping.xsd", (SSD_FILE, f"{where} source")
        )
        file = inner
    else:
        found = element.find("ssm:ParameterMapping", NS)
        if found is None:
            return {}
        root, file = found, SSD_FILE
    out: dict[str, Mapping] = {}
    for entry in root.findall("ssm:MappingEntry", NS):
        source, target = entry.get("source", ""), entry.get("target", "")
        ewhere = f"MappingEntry '{source}' -> '{target}'"
        transform = None
        for t in entry:
            if local(t.tag) != "Annotations":
                transform = _transform(archive, t, file, f"{ewhere}/{local(t.tag)}")
        out[source] = Mapping(
            target=target,
            suppress=entry.get("suppressUnitConversion", "false") in ("true", "1"),
            transform=transform,
            where=file,
        )
    return out


def _transform(
    archive: Archive, t: ET.Element, file: str, where: str
) -> Callable[[Any], Any] | None:
    """The function a parameter mapping's transformation element applies to a value."""
    kind = local(t.tag)
    if kind == "LinearTransformation":
        factor, offset = float(t.get("factor", 1.0)), float(t.get("offset", 0.0))
        return lambda v: factor * float(v) + offset
    if kind in ("BooleanMappingTransformation", "IntegerMappingTransformation"):
        cast: Callable[[str], Any] = (
            (lambda s: s in ("true", "1")) if kind.startswith("Boolean") else int
        )
        table = {
            cast(e.get("source", "")): cast(e.get("target", ""))
            for e in t.findall("ssc:MapEntry", NS)
        }
    elif kind == "EnumerationMappingTransformation":
        table = {e.get("source", ""): e.get("target", "") for e in t.findall("ssc:MapEntry", NS)}
    else:
        return None

    def lookup(v: Any) -> Any:
        if v not in table:
            raise archive.error(
                file, where, f"value {v!r} is not a source of the map ({sorted(table)}); add it"
            )
        return table[v]

    return lookup


def _value(
    p: ET.Element,
    var: Variable,
    archive: Archive,
    file: str,
    where: str,
    set_units: dict[str, Unit],
    ssd_units: dict[str, Unit],
    suppress: bool,
) -> Any:
    """The value of one ``ssv:Parameter``, in the FMU variable's unit and type."""
    kinds = [child for child in p if local(child.tag) in _VALUE_TYPES]
    kind = local(kinds[0].tag)
    kind = SSP2_TYPES.get(kind, kind)
    text = kinds[0].get("value", "")
    if kind == "Real":
        value = float(text)
        unit = kinds[0].get("unit")
        if unit and not suppress:
            table = set_units.get(unit) or ssd_units.get(unit)
            try:
                value *= conversion_factor(table or unit, var.conversion_unit)
            except UnitError as exc:
                how = (
                    "define it with an ssc:Unit in the set's ssv:Units or the SSD's ssd:Units"
                    if table is None
                    else "give the value in a unit of the variable's dimension"
                )
                raise archive.error(file, where, f"{exc.message.rstrip('.')}; {how}") from None
        return value
    if kind == "Integer":
        return int(text)
    if kind == "Boolean":
        return text in ("true", "1")
    return text  # String, Enumeration (item name), Binary (hex digits)
