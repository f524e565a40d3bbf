"""Export a scenario as an SSP 1.0 archive (System Structure and Parameterization).

``ins-cosim export-ssp SCENARIO OUT.ssp`` writes a zip archive::

    SystemStructure.ssd          the system: components, connections, parameters
    resources/<Name>.fmu         every FMU the components use (one copy per file)

``SystemStructure.ssd`` (namespace ``http://ssp-standard.org/SSP1/SystemStructureDescription``,
validated against the SSP 1.0 schemas in the tests):

- one ``ssd:Component`` per block, ``source="resources/<Name>.fmu"``,
  ``implementation="CoSimulation"``, with an ``ssd:Connector`` for each of its inputs and
  outputs, named as in the FMU (a block's rename map is undone: SSP tools see the FMU's
  own names);
- the block's parameters (and constant inputs) as an inline ``ssd:ParameterBindings`` /
  ``ssd:ParameterValues`` / ``ssv:ParameterSet`` with exact values (shortest repr of the
  double), already converted to the FMU's units, so a tool applies them as they are;
- one ``ssd:Connection`` per scalar connection; a connection that converts units
  carries an ``ssc:LinearTransformation`` with our factor and
  ``suppressUnitConversion="true"`` (so a unit-aware tool does not convert twice); a
  connection of an imported archive (:class:`~cosim.interop.ssp_import.SspScenario`)
  carries its factor and offset the same way, so that import -> export -> import gives
  the same scenario (sub-systems and signal dictionaries come back flattened, mappings
  applied);
- each connector declares the FMU variable's type (``ssc:Real``, ``ssc:Integer``,
  ``ssc:Boolean``, ``ssc:String``, ``ssc:Enumeration``), which the import checks;
- ``ssd:DefaultExperiment`` with start and stop time and, as an annotation of type
  ``com.opensimulationplatform``, ``osp:FixedStepAlgorithm baseStepSize`` (the macro
  step); a block of rate k gets ``osp:StepSizeHint value = k * step`` (libcosim's way to
  step it every k macro steps; equivalence with our master is tested for k = 1 only);
- an annotation of type ``org.ins-cosim.scenario`` records the scenario file, its
  sha256 and its coupling.

SSP describes structure, not the master algorithm: libcosim runs the archive with its
fixed-step Jacobi algorithm, which equals our master with ``coupling = "jacobi"``
(tests/interop/test_ssp.py). Built-in models are exported from the FMUs ``make fmus`` builds
(``fmus/build/<Model>.fmu``); Python blocks (alignment filters, ``class = ...``) have no
FMU: the export names them and ``exclude`` (``--exclude BLOCK``) leaves them out, with
the connections that are cut listed.

Units: every unit of a Real connector is defined once in ``ssd:Units`` (``ssc:Unit`` with
its ``ssc:BaseUnit`` exponents and factor) and named by the connector (``ssc:Real
unit="deg"``); a unit SSP cannot define (a non-integer exponent: ``deg/sqrt(h)``) is left
off its connector and listed in :attr:`SspExport.left_out`. Enumeration connectors refer
to their ``ssd:Enumerations`` type (items from the FMU); connectors of FMI 3 types that
SSP 1.0 does not know (Float32, Int8..UInt64, Binary, Clock) are left out and listed.

The prefixes ``ssd``, ``ssc``, ``ssv`` and ``osp`` are the ones the standard uses; keep
them (libcosim's reader matches the prefixed element names).

The other direction is :mod:`cosim.interop.ssp_import` (``ins-cosim run|check x.ssp``):
an exported archive read back runs to the scenario's results (1e-12), and the same
archive gives the same outputs in ins-cosim, libcosim and fmpy
(:mod:`cosim.interop.fmpy_ssp`) with Jacobi coupling (tests/acceptance/test_three_masters.py).
"""

from __future__ import annotations

import copy
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from cosim import registry
from cosim.blocks import BlockHost
from cosim.errors import UnitError, UserError
from cosim.scenario import Scenario, load_scenario
from cosim.units import FMI_BASE_UNITS, Unit, resolve_unit

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
INS = "urn:ins-cosim:ssp"
for _prefix, _uri in (("ssd", SSD), ("ssc", SSC), ("ssv", SSV), ("osp", OSP), ("ic", INS)):
    ET.register_namespace(_prefix, _uri)

DEFAULT_FMU_DIR = Path("fmus/build")
_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
#: pint dimension -> SSP BaseUnit attribute (the FMI ones).
_SSP_BASE = {dim: attr for attr, dim in FMI_BASE_UNITS.items()}


def _ssp_unit(unit: Unit) -> dict[str, str] | None:
    """The ``ssc:BaseUnit`` attributes of a unit, or None when SSP cannot define it."""
    attrs: dict[str, str] = {}
    for dim, exp in unit.dimension:
        if dim not in _SSP_BASE or not float(exp).is_integer():
            return None
        attrs[_SSP_BASE[dim]] = str(int(exp))
    if unit.factor != 1.0:
        attrs["factor"] = _number(unit.factor)
    if unit.offset:
        attrs["offset"] = _number(unit.offset)
    return attrs


class SspError(UserError):
    """A scenario cannot be exported as SSP (a Python block, a missing FMU, ...)."""


@dataclass
class SspExport:
    """What :func:`export_ssp` wrote.

    Attributes
    ----------
    path : Path
        The ``.ssp`` archive.
    components : dict
        Block name -> resource path inside the archive (``resources/<Name>.fmu``).
    connections : int
        Number of scalar connections.
    parameters : int
        Number of parameter values.
    fmu_names : dict
        Block name -> {scenario variable name -> FMU variable name} for renamed variables.
    excluded : list of str
        The blocks left out (``exclude``).
    cut : list of str
        The scalar connections to or from an excluded block (not in the archive).
    left_out : list of str
        What the archive does not carry, one line each with the reason.
    """

    path: Path
    components: dict[str, str]
    connections: int
    parameters: int
    fmu_names: dict[str, dict[str, str]] = field(default_factory=dict)
    excluded: list[str] = field(default_factory=list)
    cut: list[str] = field(default_factory=list)
    left_out: list[str] = field(default_factory=list)


def _q(namespace: str, tag: str) -> str:
    return f"{{{namespace}}}{tag}"


def _number(value: float) -> str:
    """Shortest text that reads back as the same double."""
    return repr(float(value))


def _parameter_value(
    parent: ET.Element, vtype: str, value: Any, items: tuple[tuple[str, int], ...] = ()
) -> None:
    names = {int(v): n for n, v in items}
    if vtype == "Enumeration" and not isinstance(value, str) and int(value) in names:
        value = names[int(value)]  # an item by its name, as SSP and the FMU's type say
    if vtype == "Real":
        ET.SubElement(parent, _q(SSV, "Real"), value=_number(value))
    elif vtype == "Integer":
        ET.SubElement(parent, _q(SSV, "Integer"), value=str(int(value)))
    elif vtype == "Boolean":
        ET.SubElement(parent, _q(SSV, "Boolean"), value="true" if value else "false")
    elif vtype == "Enumeration" and isinstance(value, str):
        ET.SubElement(parent, _q(SSV, "Enumeration"), value=value)
    elif vtype == "Enumeration":
        ET.SubElement(parent, _q(SSV, "Integer"), value=str(int(value)))
    else:
        ET.SubElement(parent, _q(SSV, "String"), value=str(value))


def _osp_annotation(parent: ET.Element, tag: str, ns: str = SSD) -> ET.Element:
    annotations = ET.SubElement(parent, _q(ns, "Annotations"))
    annotation = ET.SubElement(
        annotations, _q(SSC, "Annotation"), type="com.opensimulationplatform"
    )
    return ET.SubElement(annotation, _q(OSP, tag))


def _component(
    elements: ET.Element,
    name: str,
    host: BlockHost,
    resource: str,
    parameters: dict[str, Any],
    step_hint: float | None,
    units: dict[str, dict[str, str] | None],
    enums: dict[str, list[tuple[str, int]]],
    left_out: list[str],
) -> None:
    comp = ET.SubElement(
        elements,
        _q(SSD, "Component"),
        name=name,
        type="application/x-fmu-sharedlibrary",
        source=resource,
        implementation="CoSimulation",
    )
    ports = []
    for v in host.variables.values():
        if v.causality not in ("input", "output"):
            continue
        if v.type in _TYPES:
            ports.append(v)
        else:
            left_out.append(
                f"{name}.{v.own_name}: {v.type} {v.causality}, a type SSP 1.0 connectors do "
                f"not have"
            )
    declared = _declared_types(host)
    if ports:
        connectors = ET.SubElement(comp, _q(SSD, "Connectors"))
        for v in ports:
            connector = ET.SubElement(
                connectors, _q(SSD, "Connector"), name=v.own_name, kind=v.causality
            )
            kind = ET.SubElement(connector, _q(SSC, v.type))
            if v.type == "Real" and v.unit not in ("", "1"):
                if v.unit not in units:
                    try:
                        units[v.unit] = _ssp_unit(resolve_unit(v.conversion_unit))
                    except UnitError:
                        units[v.unit] = None
                    if units[v.unit] is None:
                        left_out.append(
                            f"unit '{v.unit}' (of {name}.{v.own_name} and others): SSP unit "
                            f"definitions have integer exponents; connectors in it carry "
                            f"no unit"
                        )
                if units[v.unit] is not None:
                    kind.set("unit", v.unit)
            elif v.type == "Enumeration":
                type_name, items = declared.get(v.own_name, (f"{name}_{v.own_name}", []))
                enums.setdefault(type_name, items)
                kind.set("name", type_name)
    if parameters:
        bindings = ET.SubElement(comp, _q(SSD, "ParameterBindings"))
        binding = ET.SubElement(bindings, _q(SSD, "ParameterBinding"))
        values = ET.SubElement(binding, _q(SSD, "ParameterValues"))
        pset = ET.SubElement(values, _q(SSV, "ParameterSet"), version="1.0", name="parameters")
        plist = ET.SubElement(pset, _q(SSV, "Parameters"))
        for scalar, value in parameters.items():
            var = host.variables[scalar]
            parameter = ET.SubElement(plist, _q(SSV, "Parameter"), name=var.own_name)
            _parameter_value(parameter, var.type, value, tuple(var.items))
    if step_hint is not None:
        _osp_annotation(comp, "StepSizeHint").set("value", _number(step_hint))


def _declared_types(host: BlockHost) -> dict[str, tuple[str, list[tuple[str, int]]]]:
    """FMU variable -> (its enumeration type name, [(item, value)]) from the FMU."""
    md = getattr(host, "model_description", None)
    out: dict[str, tuple[str, list[tuple[str, int]]]] = {}
    if md is None:
        return out
    for v in md.modelVariables:
        t = getattr(v, "declaredType", None)
        if v.type == "Enumeration" and t is not None:
            out[v.name] = (t.name, [(i.name, int(i.value)) for i in t.items])
    return out


def export_ssp(
    scenario: Scenario | str | Path,
    out: str | Path,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
    exclude: tuple[str, ...] | list[str] = (),
) -> SspExport:
    """Write a scenario's FMU blocks, connections and parameters as an SSP 1.0 archive.

    Parameters
    ----------
    scenario : Scenario, str or Path
        A loaded scenario or its TOML file (not modified).
    out : str or Path
        The ``.ssp`` file to write (its folder is created; replaced if it exists).
    fmu_dir : str or Path
        Where the FMUs of built-in models are (``make fmus`` builds ``fmus/build``).
    exclude : sequence of str
        Blocks to leave out (Python blocks have no FMU); their connections are cut and
        listed in :attr:`SspExport.cut`.

    Returns
    -------
    SspExport

    Raises
    ------
    SspError
        A Python block not excluded (named, with the ``--exclude`` that exports the rest
        and the connections it would cut), an unknown excluded block, or a built-in model
        whose FMU is not in ``fmu_dir``.
    ScenarioError, FmuError
        The scenario itself is inconsistent (as ``ins-cosim check`` reports).
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    fmu_dir = Path(fmu_dir)
    unknown = [b for b in exclude if b not in sc.blocks]
    if unknown:
        raise SspError(
            f"cannot exclude {', '.join(unknown)}: no such block; blocks: {', '.join(sc.blocks)}"
        )
    python = [
        spec
        for spec in sc.blocks.values()
        if spec.name not in exclude
        and (
            spec.kind == "class"
            or (spec.kind == "model" and not registry.is_truth_model(spec.source))
        )
    ]
    if python:
        names = [spec.name for spec in python]
        cut = [c for c in sc.connections if _touches(c, names)]
        raise SspError(
            f"block(s) {', '.join(f'{s.name} ({s.source})' for s in python)} run in Python "
            f"and have no FMU; SSP holds FMUs only. Export the rest with "
            f"{' '.join(f'--exclude {n}' for n in names)} (cuts {len(cut)} connection(s): "
            f"{'; '.join(cut)})"
        )
    if exclude:
        sc = copy.deepcopy(sc)
        sc.connections = [c for c in sc.connections if not _touches(c, exclude)]
        sc.outputs = [o for o in sc.outputs or [] if str(o).split(".")[0] not in exclude] or None
        for b in exclude:
            del sc.blocks[b]
    for spec in sc.blocks.values():
        if spec.kind == "model" and not (fmu_dir / f"{spec.source}.fmu").is_file():
            raise SspError(
                f"block '{spec.name}' uses the built-in model '{spec.source}' but "
                f"'{fmu_dir / (spec.source + '.fmu')}' does not exist; run `make fmus` "
                f"(or give --fmu-dir)"
            )
    original = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    cut = [c for c in original.connections if _touches(c, exclude)]
    sc = copy.deepcopy(sc)
    sc.use_fmus(fmu_dir)
    system, _meta = sc.build()
    try:
        root, summary = _describe(sc, system)
    finally:
        for host in system.blocks.values():
            host.terminate()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    ET.indent(root, space="  ")
    ssd = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    partial = out.with_name(out.name + ".part")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for source, resource in sorted(summary.pop("files").items(), key=lambda kv: kv[1]):
            zf.write(source, resource)
    os.replace(partial, out)
    return SspExport(path=out, excluded=list(exclude), cut=cut, **summary)


def _touches(connection: Any, blocks: Any) -> bool:
    """Whether a connection string ``a.x -> b.u`` starts or ends at one of ``blocks``."""
    if not isinstance(connection, str) or "->" not in connection:
        return False
    left, right = (part.strip().split(".", 1)[0] for part in connection.split("->", 1))
    return left in blocks or right in blocks


def _describe(sc: Scenario, system: Any) -> tuple[ET.Element, dict[str, Any]]:
    """The SSD tree and the export summary (``files``: FMU path -> resource name)."""
    from cosim import provenance

    s = sc.settings
    tool = f"ins-cosim {provenance.versions().get('ins-cosim', '')}".strip()
    root = ET.Element(_q(SSD, "SystemStructureDescription"), version="1.0", name=sc.name)
    root.set("generationTool", tool)
    system_el = ET.SubElement(
        root, _q(SSD, "System"), name=sc.name, description=f"exported from {sc.path.name}"
    )
    elements = ET.SubElement(system_el, _q(SSD, "Elements"))
    files: dict[str, str] = {}
    components: dict[str, str] = {}
    renamed: dict[str, dict[str, str]] = {}
    n_parameters = 0
    units: dict[str, dict[str, str] | None] = {}
    enums: dict[str, list[tuple[str, int]]] = {}
    left_out: list[str] = []
    for name, host in system.blocks.items():
        source = str(Path(sc.blocks[name].source).resolve())
        if source not in files:
            resource = f"resources/{Path(source).name}"
            if resource in files.values():
                resource = f"resources/{name}_{Path(source).name}"
            files[source] = resource
        components[name] = files[source]
        params = system.parameters.get(name, {})
        n_parameters += len(params)
        rate = system.rates.get(name, 1)
        _component(
            elements,
            name,
            host,
            files[source],
            params,
            rate * s.step if rate != 1 else None,
            units,
            enums,
            left_out,
        )
        names = {v.name: v.fmu_name for v in host.variables.values() if v.fmu_name}
        if names:
            renamed[name] = names
    offsets = getattr(sc, "offsets", {})  # an imported archive's (SspScenario)
    suppressed: set[Any] = getattr(sc, "suppressed", set())
    if system.connections:
        connections = ET.SubElement(system_el, _q(SSD, "Connections"))
        for c in system.connections:
            src = system.blocks[c.src_block].variables[c.src_var].own_name
            dst = system.blocks[c.dst_block].variables[c.dst_var].own_name
            link = ET.SubElement(
                connections,
                _q(SSD, "Connection"),
                startElement=c.src_block,
                startConnector=src,
                endElement=c.dst_block,
                endConnector=dst,
            )
            offset = offsets.get(str(c), 0.0)
            if str(c) in suppressed:
                link.set("suppressUnitConversion", "true")
            if c.factor != 1.0 or offset != 0.0:
                link.set("suppressUnitConversion", "true")
                ET.SubElement(
                    link,
                    _q(SSC, "LinearTransformation"),
                    factor=_number(c.factor),
                    offset=_number(offset) if offset else "0",
                )
    if enums:
        enum_el = ET.SubElement(root, _q(SSD, "Enumerations"))
        for type_name, items in enums.items():
            e = ET.SubElement(enum_el, _q(SSC, "Enumeration"), name=type_name)
            for item, value in items:
                ET.SubElement(e, _q(SSC, "Item"), name=item, value=str(value))
    defined = {u: attrs for u, attrs in units.items() if attrs is not None}
    if defined:
        units_el = ET.SubElement(root, _q(SSD, "Units"))
        for unit, attrs in defined.items():
            u = ET.SubElement(units_el, _q(SSC, "Unit"), name=unit)
            ET.SubElement(u, _q(SSC, "BaseUnit"), **attrs)
    experiment = ET.SubElement(
        root, _q(SSD, "DefaultExperiment"), startTime=_number(s.start), stopTime=_number(s.stop)
    )
    algorithm = _osp_annotation(experiment, "Algorithm")
    ET.SubElement(algorithm, _q(OSP, "FixedStepAlgorithm"), baseStepSize=_number(s.step))
    notes = ET.SubElement(root, _q(SSD, "Annotations"))
    note = ET.SubElement(notes, _q(SSC, "Annotation"), type="org.ins-cosim.scenario")
    ET.SubElement(
        note,
        _q(INS, "Scenario"),
        file=str(sc.path),
        sha256=sc.sha256,
        coupling=s.coupling,
    )
    summary = {
        "components": components,
        "connections": len(system.connections),
        "parameters": n_parameters,
        "fmu_names": renamed,
        "files": files,
        "left_out": left_out,
    }
    return root, summary
