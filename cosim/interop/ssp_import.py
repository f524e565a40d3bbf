"""Import an SSP 1.0 archive (System Structure and Parameterization) as a scenario.

``ins-cosim run system.ssp --out DIR`` (and ``check``) read the archive with
:func:`load_ssp`, which returns a :class:`SspScenario`: a
:class:`~cosim.scenario.Scenario` whose blocks are the archive's FMUs, so that it runs,
records and is checked like a TOML scenario. What is read from ``SystemStructure.ssd``:

- ``ssd:Component`` elements of the top-level ``ssd:System`` (``type`` absent or
  ``application/x-fmu-sharedlibrary``, ``implementation`` absent, ``CoSimulation`` or
  ``any``) whose ``source`` is an FMU inside the archive; an FMU variable whose name is
  not ``name`` or ``name[i]`` (``body.mass``, ``der(x)``) is exposed under that name with
  every other character replaced by ``_`` (``body_mass``);
- ``ssd:Connection`` between two components; units are converted between the FMUs'
  own units (a connector that states a unit must state the FMU's unit, or an equal one)
  unless ``suppressUnitConversion="true"``; an ``ssc:LinearTransformation`` multiplies
  the (converted) value by its ``factor`` (a non-zero ``offset`` is refused);
- ``ssd:ParameterBinding`` of a component or of the system, with its parameter set
  inline (``ssd:ParameterValues/ssv:ParameterSet``) or in an ``.ssv`` file of the archive
  (``source=``), optionally with a ``prefix`` (prepended to the set's names, as SSP says:
  at system level a parameter is named ``Component.variable``, so a component's own set
  binds there with ``prefix="Component."``); ``ssv:Real`` values with a ``unit``
  are converted to the FMU's unit (units from the set's ``ssv:Units``, the SSD's
  ``ssd:Units``, or parsed from the name), ``ssv:Enumeration`` values are item names;
- ``ssd:Units`` (``ssc:Unit`` / ``ssc:BaseUnit``);
- ``ssd:DefaultExperiment`` start and stop time; the macro step from the OSP annotation
  ``osp:FixedStepAlgorithm baseStepSize`` (SSP 1.0 has no element for it; this is what
  ``export-ssp`` writes and libcosim reads); the coupling from the
  ``org.ins-cosim.scenario`` annotation (``export-ssp`` writes the scenario's), else
  ``"jacobi"`` (what libcosim and most SSP masters do). ``step``, ``stop``, ``start`` and
  ``coupling`` given to :func:`load_ssp` override them.

Everything else that would change the result is refused, one line naming the archive,
the file inside it and the element: nested systems, signal dictionaries, connections to
the system's own connectors, connections of variables that are not Real, parameter
mappings (``.ssm``), Boolean / Integer / Enumeration mapping transformations, offsets,
Model Exchange components, references outside the archive, SSD versions other than 1.0,
and whatever fails the SSP 1.0 schemas that fmpy ships (the ``.ssd`` and every ``.ssv``
are validated).

The FMUs are unpacked into a temporary folder that lives as long as the process.
"""

from __future__ import annotations

import atexit
import dataclasses
import hashlib
import re
import shutil
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any
from xml.etree import ElementTree as ET

from cosim.archives import check_archive
from cosim.errors import FmuError, ScenarioError, UnitError
from cosim.master import GAUSS_SEIDEL, JACOBI, MasterSettings, System
from cosim.scenario import BlockSpec, Scenario
from cosim.units import Unit, conversion_factor, parse_unit, unit_from_fmi
from cosim.variables import SCALAR_NAME, Variable, fmu_variables

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
INS = "urn:ins-cosim:ssp"
NS = {"ssd": SSD, "ssc": SSC, "ssv": SSV, "osp": OSP, "ic": INS}
_FMU_TYPES = ("", "application/x-fmu-sharedlibrary")
_BASE_ATTRS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")


class SspImportError(ScenarioError):
    """An SSP archive cannot be imported; the message names the archive, file and element."""


@dataclass
class _Link:
    """One SSP connection as the master will run it."""

    start: tuple[str, str]  # (component, FMU variable name)
    end: tuple[str, str]
    factor: float
    suppress: bool
    where: str


@dataclass
class SspScenario(Scenario):
    """A scenario read from an SSP archive (see the module docstring), made by
    :func:`load_ssp`.

    Attributes
    ----------
    path : Path
        The ``.ssp`` archive.
    sha256 : str
        Hash of the archive's bytes.
    name : str
        The ``.ssd``'s name.
    settings : MasterSettings
        Step, stop, start and coupling (see :func:`load_ssp`).
    blocks : dict
        Component name -> :class:`~cosim.scenario.BlockSpec` of its unpacked FMU.
    connections : list of str
        The connections as ``"a.x -> b.u"``.
    outputs : None
        Every output is recorded.
    raw : dict
        ``scenario.name`` and the archive path (no requirements or campaign).
    links : list
        The archive's connections with their linear-transformation factors and whether
        unit conversion is suppressed (applied by :meth:`build`).
    notes : list of str
        What the import did that a reader should know (renamed variables, defaults).
    resources : dict
        Component name -> its FMU inside the archive (``resources/X.fmu``); the blocks run
        from copies unpacked into a temporary folder.
    """

    links: list[_Link] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    resources: dict[str, str] = field(default_factory=dict)

    def build(self) -> tuple[System, dict[str, Any]]:
        """Build as a scenario, then give each connection the factor SSP defines.

        Returns
        -------
        system : System
            Ready for :class:`cosim.master.Master`.
        metadata : dict
            As :meth:`cosim.scenario.Scenario.build`, with ``ssp`` (the archive).

        Raises
        ------
        ScenarioError, FmuError
            With the archive and element of the problem.
        """
        system, metadata = super().build()
        by_pair = {}
        for link in self.links:
            src = _scenario_name(self.blocks[link.start[0]], link.start[1])
            dst = _scenario_name(self.blocks[link.end[0]], link.end[1])
            by_pair[(link.start[0], src, link.end[0], dst)] = link
        connections = []
        for c in system.connections:
            link = by_pair[(c.src_block, c.src_var, c.dst_block, c.dst_var)]
            unit_factor = 1.0 if link.suppress else c.factor
            connections.append(dataclasses.replace(c, factor=unit_factor * link.factor))
        system.connections = connections
        metadata["ssp"] = {
            "file": str(self.path),
            "sha256": self.sha256,
            "components": self.resources,
            "notes": self.notes,
        }
        return system, metadata


def _scenario_name(spec: BlockSpec, fmu_name: str) -> str:
    return spec.rename.get(fmu_name, fmu_name)


# --------------------------------------------------------------------------- reading
class _Archive:
    """The zip file, its parsed XML files and the place errors point to."""

    def __init__(self, path: Path) -> None:
        self.path = path
        if path.is_file() and zipfile.is_zipfile(path):
            check_archive(path, "SSP archive")  # the unpack limits, before any member is read
        try:
            self.zip = zipfile.ZipFile(path)
        except (OSError, zipfile.BadZipFile) as exc:
            raise SspImportError(
                f"not an SSP archive ({exc}); expected a zip file with SystemStructure.ssd",
                file=str(path),
            ) from None
        self.names = set(self.zip.namelist())

    def error(self, inner: str, element: str, message: str) -> SspImportError:
        return SspImportError(message, file=f"{self.path}!{inner}", key=element)

    def xml(self, inner: str, schema: str, referrer: tuple[str, str]) -> ET.Element:
        """Parse and validate one XML file of the archive."""
        if inner not in self.names:
            raise self.error(
                referrer[0],
                referrer[1],
                f"'{inner}' is not in the archive (it holds: {', '.join(sorted(self.names))})",
            )
        data = self.zip.read(inner)
        _validate(data, schema, self, inner)
        try:
            return ET.fromstring(data)
        except ET.ParseError as exc:  # pragma: no cover - the schema check parses first
            raise self.error(inner, "XML", f"not well-formed: {exc}") from None


def _validate(data: bytes, schema: str, archive: _Archive, inner: str) -> None:
    """Validate against the SSP 1.0 schema fmpy ships (lxml); first error in one line."""
    from fmpy.ssp import ssd as fmpy_ssd
    from lxml import etree

    folder = Path(fmpy_ssd.__file__).parent / "schema"
    try:
        doc = etree.fromstring(data)
    except etree.XMLSyntaxError as exc:
        raise archive.error(inner, "XML", f"not well-formed XML: {exc}") from None
    version = doc.get("version")
    if version is not None and version != "1.0":
        raise archive.error(
            inner,
            f"{etree.QName(doc).localname} version",
            f'SSP version {version!r}; ins-cosim imports SSP 1.0 (version="1.0")',
        )
    validator = etree.XMLSchema(file=str(folder / schema))
    if not validator.validate(doc):
        first = validator.error_log[0]
        raise archive.error(
            inner,
            f"line {first.line}",
            f"does not validate against the SSP 1.0 schema {schema}: {first.message}",
        )


def _units(parent: ET.Element | None, path: str) -> dict[str, Unit]:
    """``ssc:Unit`` definitions under ``parent`` (``ssd:Units`` or ``ssv:Units``)."""
    out: dict[str, Unit] = {}
    if parent is None:
        return out
    for u in parent.findall("ssc:Unit", NS):
        base = u.find("ssc:BaseUnit", NS)
        attrs = base.attrib if base is not None else {}
        exponents = {k: float(attrs.get(k, 0)) for k in _BASE_ATTRS}
        name = u.get("name", "")
        try:
            out[name] = unit_from_fmi(
                name, exponents, float(attrs.get("factor", 1.0)), float(attrs.get("offset", 0.0))
            )
        except UnitError as exc:
            raise SspImportError(exc.message, file=path, key=f"Unit '{name}'") from None
    return out


def _unit(name: str, *tables: dict[str, Unit]) -> Unit | str:
    for table in tables:
        if name in table:
            return table[name]
    return name


def _number(text: str | None, default: float | None, archive: _Archive, where: str) -> float:
    if text is None:
        if default is None:
            raise archive.error("SystemStructure.ssd", where, "missing")
        return default
    return float(text)


def _safe_name(name: str, taken: set[str]) -> str:
    """A scalar name (``name`` or ``name[i]``) for an FMU variable name that is not one."""
    m = re.match(r"^(.*)\[([1-9]\d*)\]$", name)
    base, index = (m.group(1), f"[{m.group(2)}]") if m else (name, "")
    base = re.sub(r"\W", "_", base) or "v"
    if not re.match(r"^[A-Za-z_]", base):
        base = f"v_{base}"
    new = f"{base}{index}"
    while new in taken:
        new = f"{base}_{index}" if index else f"{new}_"
    return new


def load_ssp(
    path: str | Path,
    *,
    step: float | None = None,
    stop: float | None = None,
    start: float | None = None,
    coupling: str | None = None,
) -> SspScenario:
    """Read an SSP 1.0 archive as a scenario of FMU blocks.

    Parameters
    ----------
    path : str or Path
        The ``.ssp`` file.
    step, stop, start : float, optional
        Macro step, stop and start time [s]; override the archive's.
    coupling : str, optional
        ``"jacobi"`` or ``"gauss-seidel"``; overrides the archive's (default: the
        ``org.ins-cosim.scenario`` annotation, else ``"jacobi"``).

    Returns
    -------
    SspScenario
        Run it with :func:`cosim.run` or :func:`cosim.scenario.build_master`.

    Raises
    ------
    SspImportError
        The archive, the file inside it and the element that cannot be imported, and why.
    """
    path = Path(path)
    if not path.is_file():
        raise SspImportError("file not found; give the path of an .ssp archive", file=str(path))
    archive = _Archive(path)
    ssd_name = "SystemStructure.ssd"
    root = archive.xml(ssd_name, "SystemStructureDescription.xsd", (ssd_name, "archive"))
    ssd_path = f"{path}!{ssd_name}"
    ssd_units = _units(root.find("ssd:Units", NS), ssd_path)
    system = root.find("ssd:System", NS)
    assert system is not None  # the schema requires one
    sys_name = system.get("name", "")
    where = f"System '{sys_name}'"
    for tag, what in (
        ("ssd:Elements/ssd:System", "a nested ssd:System"),
        ("ssd:Elements/ssd:SignalDictionaryReference", "an ssd:SignalDictionaryReference"),
        ("ssd:SignalDictionaries", "ssd:SignalDictionaries"),
    ):
        found = system.find(tag, NS)
        if found is not None:
            raise archive.error(
                ssd_name,
                f"{where}/{tag.split(':')[-1]} '{found.get('name', '')}'",
                f"{what} is not supported; ins-cosim imports one flat system of FMU components",
            )
    workdir = Path(tempfile.mkdtemp(prefix="ins_cosim_ssp_"))
    atexit.register(shutil.rmtree, workdir, True)
    blocks: dict[str, BlockSpec] = {}
    variables: dict[str, dict[str, Variable]] = {}
    connector_units: dict[tuple[str, str], str] = {}
    notes: list[str] = []
    resources: dict[str, str] = {}
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        name = comp.get("name", "")
        cwhere = f"Component '{name}'"
        if not re.match(r"^[A-Za-z_]\w*$", name):
            raise archive.error(
                ssd_name, cwhere, "component names must be Python-style identifiers here"
            )
        ctype = comp.get("type", "")
        if ctype not in _FMU_TYPES:
            raise archive.error(
                ssd_name, cwhere, f"type {ctype!r} is not supported; expected an FMU component"
            )
        impl = comp.get("implementation", "any")
        if impl not in ("any", "CoSimulation"):
            raise archive.error(
                ssd_name, cwhere, f"implementation {impl!r}; ins-cosim runs CoSimulation FMUs"
            )
        source = comp.get("source", "")
        inner = str(PurePosixPath(source.removeprefix("./")))
        if ":" in source or inner.startswith("..") or inner not in archive.names:
            raise archive.error(
                ssd_name,
                f"{cwhere} source",
                f"{source!r} is not a file inside the archive; expected e.g. resources/X.fmu",
            )
        fmu = workdir / name / PurePosixPath(inner).name
        fmu.parent.mkdir(parents=True, exist_ok=True)
        fmu.write_bytes(archive.zip.read(inner))
        check_archive(fmu)
        variables[name] = _fmu_vars(fmu, archive, cwhere)
        taken = {v for v in variables[name] if SCALAR_NAME.match(v)}
        rename = {}
        for own in variables[name]:
            if not SCALAR_NAME.match(own):
                rename[own] = _safe_name(own, taken)
                taken.add(rename[own])
        if rename:
            notes.append(
                f"{name}: FMU variables renamed to scenario names: "
                f"{', '.join(f'{a} -> {b}' for a, b in rename.items())}"
            )
        for conn in comp.findall("ssd:Connectors/ssd:Connector", NS):
            real = conn.find("ssc:Real", NS)
            if real is not None and real.get("unit"):
                connector_units[(name, conn.get("name", ""))] = real.get("unit", "")
        blocks[name] = BlockSpec(name, "fmu", str(fmu.resolve()), rename=rename)
        resources[name] = inner
    if not blocks:
        raise archive.error(ssd_name, where, "no ssd:Component; nothing to run")
    # parameters: system level (names Component.variable), then each component's own
    _bind(archive, system, None, blocks, variables, ssd_units)
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        _bind(archive, comp, comp.get("name", ""), blocks, variables, ssd_units)
    links, connections = _connections(
        archive, system, blocks, variables, connector_units, ssd_units
    )
    settings = _settings(archive, root, step, stop, start, coupling, notes)
    data = path.read_bytes()
    return SspScenario(
        path=path,
        sha256=hashlib.sha256(data).hexdigest(),
        name=root.get("name") or sys_name or path.stem,
        settings=settings,
        blocks=blocks,
        connections=connections,
        outputs=None,
        raw={"scenario": {"name": root.get("name", path.stem)}, "ssp": str(path)},
        links=links,
        notes=notes,
        resources=resources,
    )


def _fmu_vars(fmu: Path, archive: _Archive, where: str) -> dict[str, Variable]:
    from fmpy import read_model_description

    try:
        md = read_model_description(str(fmu), validate=False)
        return fmu_variables(md)
    except (FmuError, Exception) as exc:
        raise archive.error(
            "SystemStructure.ssd", f"{where} source", f"cannot read the FMU: {exc}"
        ) from None


def _bind(
    archive: _Archive,
    element: ET.Element,
    component: str | None,
    blocks: dict[str, BlockSpec],
    variables: dict[str, dict[str, Variable]],
    ssd_units: dict[str, Unit],
) -> None:
    """Apply the parameter bindings of a component (or, ``component=None``, the system)."""
    owner = f"Component '{component}'" if component else f"System '{element.get('name', '')}'"
    for i, binding in enumerate(element.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)):
        bwhere = f"{owner}/ParameterBinding[{i + 1}]"
        if binding.find("ssd:ParameterMapping", NS) is not None:
            raise archive.error(
                "SystemStructure.ssd",
                f"{bwhere}/ParameterMapping",
                "parameter mappings (.ssm) are not supported; give the values under the "
                "FMU's variable names",
            )
        btype = binding.get("type", "application/x-ssp-parameter-set")
        if btype != "application/x-ssp-parameter-set":
            raise archive.error(
                "SystemStructure.ssd", bwhere, f"type {btype!r}; expected a parameter set"
            )
        source = binding.get("source")
        if source is not None:
            inner = str(PurePosixPath(source.removeprefix("./")))
            if ":" in source or inner.startswith(".."):
                raise archive.error(
                    "SystemStructure.ssd",
                    f"{bwhere} source",
                    f"{source!r} is outside the archive; expected a .ssv file inside it",
                )
            pset = archive.xml(
                inner,
                "SystemStructureParameterValues.xsd",
                ("SystemStructure.ssd", f"{bwhere} source"),
            )
            file = inner
        else:
            pset = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            file = "SystemStructure.ssd"
            if pset is None:
                continue
        prefix = binding.get("prefix", "")
        set_units = _units(pset.find("ssv:Units", NS), f"{archive.path}!{file}")
        for p in pset.findall("ssv:Parameters/ssv:Parameter", NS):
            pname = p.get("name", "")
            pwhere = f"Parameter '{pname}'" + (
                f" ({bwhere})" if file != "SystemStructure.ssd" else f" of {bwhere}"
            )
            name = prefix + pname  # SSP: the prefix is prepended to the set's names
            target = component
            if target is None:
                target, dot, name = name.partition(".")
                if not dot or target not in blocks:
                    raise archive.error(
                        file,
                        pwhere,
                        f"a system-level parameter must be named 'Component.variable' with a "
                        f"component of the system ({', '.join(blocks)})",
                    )
            fmu_vars = variables[target]
            if name not in fmu_vars:
                import difflib

                close = difflib.get_close_matches(name, list(fmu_vars), n=3)
                tip = f" Closest names: {', '.join(close)}." if close else ""
                raise archive.error(
                    file, pwhere, f"component '{target}' has no variable '{name}'.{tip}"
                )
            var = fmu_vars[name]
            if var.causality not in ("parameter", "input"):
                raise archive.error(
                    file,
                    pwhere,
                    f"'{target}.{name}' is an {var.causality}; only parameters and inputs "
                    f"can be set",
                )
            value = _value(p, var, archive, file, pwhere, set_units, ssd_units)
            spec = blocks[target]
            spec.parameters[_scenario_name(spec, name)] = value


def _value(
    p: ET.Element,
    var: Variable,
    archive: _Archive,
    file: str,
    where: str,
    set_units: dict[str, Unit],
    ssd_units: dict[str, Unit],
) -> Any:
    """The value of one ``ssv:Parameter``, in the FMU variable's unit and type."""
    kinds = [child for child in p if child.tag.split("}")[-1] in _VALUE_TYPES]
    kind = kinds[0].tag.split("}")[-1]
    text = kinds[0].get("value", "")
    if kind == "Real":
        value = float(text)
        unit = kinds[0].get("unit")
        if unit:
            try:
                value *= conversion_factor(_unit(unit, set_units, ssd_units), var.conversion_unit)
            except UnitError as exc:
                raise archive.error(file, where, exc.message) from None
        return value
    if kind == "Integer":
        return int(text)
    if kind == "Boolean":
        return text in ("true", "1")
    return text  # String, Enumeration (item name), Binary (hex digits)


def _connections(
    archive: _Archive,
    system: ET.Element,
    blocks: dict[str, BlockSpec],
    variables: dict[str, dict[str, Variable]],
    connector_units: dict[tuple[str, str], str],
    ssd_units: dict[str, Unit],
) -> tuple[list[_Link], list[str]]:
    links: list[_Link] = []
    texts: list[str] = []
    for c in system.findall("ssd:Connections/ssd:Connection", NS):
        se, sc = c.get("startElement"), c.get("startConnector", "")
        ee, ec = c.get("endElement"), c.get("endConnector", "")
        where = f"Connection {se or '(system)'}.{sc} -> {ee or '(system)'}.{ec}"
        if not se or not ee:
            raise archive.error(
                "SystemStructure.ssd",
                where,
                "connections to the system's own connectors are not supported; connect "
                "component to component",
            )
        for comp, conn in ((se, sc), (ee, ec)):
            if comp not in blocks:
                raise archive.error(
                    "SystemStructure.ssd", where, f"no component '{comp}' in the system"
                )
            if conn not in variables[comp]:
                raise archive.error(
                    "SystemStructure.ssd",
                    where,
                    f"the FMU of '{comp}' has no variable '{conn}'",
                )
            declared = connector_units.get((comp, conn))
            var = variables[comp][conn]
            if var.type != "Real":
                raise archive.error(
                    "SystemStructure.ssd",
                    where,
                    f"'{comp}.{conn}' is {var.type}; ins-cosim connects Real variables only",
                )
            if declared and not _same_unit(declared, var, ssd_units):
                raise archive.error(
                    "SystemStructure.ssd",
                    f"Component '{comp}'/Connector '{conn}'",
                    f"the connector's unit '{declared}' is not the FMU's unit '{var.unit}'; "
                    f"ins-cosim converts between the FMUs' own units",
                )
        factor = 1.0
        for t in c:
            tag = t.tag.split("}")[-1]
            if tag == "LinearTransformation":
                factor = float(t.get("factor", 1.0))
                if float(t.get("offset", 0.0)) != 0.0:
                    raise archive.error(
                        "SystemStructure.ssd",
                        f"{where}/LinearTransformation",
                        f"offset {t.get('offset')}: ins-cosim connections scale, they do "
                        f"not shift; only factor is supported",
                    )
            elif tag.endswith("MappingTransformation"):
                raise archive.error(
                    "SystemStructure.ssd",
                    f"{where}/{tag}",
                    f"{tag} is not supported; connections carry Real values",
                )
        suppress = c.get("suppressUnitConversion", "false") in ("true", "1")
        links.append(_Link((se, sc), (ee, ec), factor, suppress, where))
        texts.append(
            f"{se}.{_scenario_name(blocks[se], sc)} -> {ee}.{_scenario_name(blocks[ee], ec)}"
        )
    return links, texts


def _same_unit(declared: str, var: Variable, ssd_units: dict[str, Unit]) -> bool:
    if declared == var.unit:
        return True
    try:
        a = ssd_units.get(declared) or parse_unit(declared)
        return conversion_factor(a, var.conversion_unit) == 1.0
    except UnitError:
        return False


def _settings(
    archive: _Archive,
    root: ET.Element,
    step: float | None,
    stop: float | None,
    start: float | None,
    coupling: str | None,
    notes: list[str],
) -> MasterSettings:
    ssd = "SystemStructure.ssd"
    experiment = root.find("ssd:DefaultExperiment", NS)
    if start is None:
        start = float(experiment.get("startTime", 0.0)) if experiment is not None else 0.0
    if stop is None:
        text = experiment.get("stopTime") if experiment is not None else None
        if text is None:
            raise archive.error(
                ssd, "DefaultExperiment stopTime", "missing; give it in the archive or --stop"
            )
        stop = float(text)
    if step is None:
        found = root.find(".//osp:FixedStepAlgorithm", NS)
        if found is None or not found.get("baseStepSize"):
            raise archive.error(
                ssd,
                "DefaultExperiment",
                "no macro step: SSP 1.0 has no element for it; expected the annotation "
                "<osp:FixedStepAlgorithm baseStepSize=...> (type com.opensimulationplatform, "
                "as export-ssp writes and libcosim reads), or give the step to load_ssp",
            )
        step = float(found.get("baseStepSize", ""))
    if coupling is None:
        note = root.find("ssd:Annotations/ssc:Annotation/ic:Scenario", NS)
        coupling = note.get("coupling") if note is not None else None
        if coupling is None:
            coupling = JACOBI
            notes.append("coupling: jacobi (the archive does not say; SSP masters step Jacobi)")
    if coupling not in (JACOBI, GAUSS_SEIDEL):
        raise archive.error(ssd, "coupling", f"expected jacobi or gauss-seidel, got {coupling!r}")
    try:
        return MasterSettings(step=step, stop=stop, start=start, coupling=coupling)
    except ScenarioError as exc:
        raise archive.error(ssd, "DefaultExperiment", exc.message) from None
