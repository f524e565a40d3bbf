"""Import an SSP archive (System Structure and Parameterization, 1.0 or 2.0) as a scenario.

``ins-cosim run system.ssp --out DIR`` (and ``check``) read the archive with
:func:`load_ssp`, which returns a :class:`SspScenario`: a
:class:`~cosim.scenario.Scenario` whose blocks are the archive's FMUs, so that it runs,
records and is checked like a TOML scenario. What is read from ``SystemStructure.ssd``:

- ``ssd:Component`` elements (``type`` absent or ``application/x-fmu-sharedlibrary``,
  ``implementation`` absent, ``CoSimulation`` or ``any``) whose ``source`` is an FMU
  inside the archive, in the top-level ``ssd:System`` and in its sub-systems, which
  are flattened (:mod:`cosim.interop.ssp_structure`: a component ``imu`` of the
  sub-system ``deck`` is the block ``deck_imu``); an FMU variable whose name is not
  ``name`` or ``name[i]`` (``body.mass``, ``der(x)``) is exposed under that name with
  every other character replaced by ``_`` (``body_mass``);
- ``ssd:Connection`` elements, followed through sub-system connectors and signal
  dictionaries (``ssd:SignalDictionaries``, ``ssd:SignalDictionaryReference``) to the
  component at each end; connector types are checked (a mismatch is refused); units
  are converted between the FMUs' own units (a connector that states a unit must
  state the FMU's unit, or an equal one) unless ``suppressUnitConversion="true"``; an
  ``ssc:LinearTransformation`` gives ``factor * value + offset`` (after the unit
  conversion; the offset in the end connector's unit);
- ``ssd:ParameterBinding`` elements with ``.ssv`` parameter sets (units converted) and
  ``.ssm`` parameter mappings (:mod:`cosim.interop.ssp_params`);
- ``ssd:Units`` (``ssc:Unit`` / ``ssc:BaseUnit``);
- ``ssd:DefaultExperiment`` start and stop time; the macro step from the OSP annotation
  ``osp:FixedStepAlgorithm baseStepSize`` (SSP 1.0 has no element for it; this is what
  ``export-ssp`` writes and libcosim reads); the coupling from the
  ``org.ins-cosim.scenario`` annotation (``export-ssp`` writes the scenario's), else
  ``"jacobi"`` (what libcosim and most SSP masters do). ``step``, ``stop``, ``start`` and
  ``coupling`` given to :func:`load_ssp` override them.

Everything else that would change the result is refused, one line naming the archive,
the file inside it and the element: connections from the top-level system's own
connectors, Boolean / Integer / Enumeration mapping transformations on connections, a
linear transformation on a link that is not Real, Model Exchange components,
references outside the archive, SSD versions other than 1.x and 2.0, and whatever fails
the SSP 1.0 schemas that fmpy ships (the ``.ssd`` and every ``.ssv``, ``.ssm`` and
``.ssb`` are validated; an SSP 2.0 file as :mod:`cosim.interop.ssp_xml` says).

The FMUs are unpacked into a temporary folder that lives as long as the process.
"""

from __future__ import annotations

import atexit
import copy
import dataclasses
import hashlib
import re
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from cosim.archives import check_archive
from cosim.errors import FmuError, ScenarioError, UnitError
from cosim.interop.ssp_params import bind_binding_list
from cosim.interop.ssp_structure import Flat, Link, flatten, resolve_links
from cosim.interop.ssp_xml import (
    NS,
    SSD_FILE,
    Archive,
    SspImportError,
    connector_type,
    read_units,
)
from cosim.master import GAUSS_SEIDEL, JACOBI, Connection, MasterSettings, System
from cosim.scenario import BlockSpec, Scenario
from cosim.units import Unit, conversion_factor, parse_unit
from cosim.variables import SCALAR_NAME, Variable, fmu_variables

__all__ = ["SspImportError", "SspScenario", "load_ssp"]
_FMU_TYPES = ("", "application/x-fmu-sharedlibrary")


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
        The archive's connections resolved to component ends, with their linear
        transformations and whether unit conversion is suppressed (applied by
        :meth:`build`).
    notes : list of str
        What the import did that a reader should know (renamed variables, defaults).
    resources : dict
        Component name -> its FMU inside the archive (``resources/X.fmu``); the blocks run
        from copies unpacked into a temporary folder.
    version : str
        The SSD's SSP version (``"1.0"``, ``"2.0"``).
    """

    links: list[Link] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    resources: dict[str, str] = field(default_factory=dict)
    version: str = "1.0"

    @property
    def offsets(self) -> dict[str, float]:
        """Connection text (``"a.x -> b.u"``) -> its offset, for the links that have one."""
        return {self._text(link): link.offset for link in self.links if link.offset != 0.0}

    @property
    def suppressed(self) -> set[str]:
        """Connection texts of the links that suppress unit conversion."""
        return {self._text(link) for link in self.links if link.suppress}

    def _text(self, link: Link) -> str:
        src = _scenario_name(self.blocks[link.start[0]], link.start[1])
        dst = _scenario_name(self.blocks[link.end[0]], link.end[1])
        return f"{link.start[0]}.{src} -> {link.end[0]}.{dst}"

    def build(self) -> tuple[System, dict[str, Any]]:
        """Build as a scenario, then give each connection the transformation SSP defines.

        Returns
        -------
        system : System
            Ready for :class:`cosim.master.Master`; a block with an input whose link has
            an offset is wrapped so that the offset is added where the master writes it.
        metadata : dict
            As :meth:`cosim.scenario.Scenario.build`, with ``ssp`` (the archive).

        Raises
        ------
        ScenarioError, FmuError
            With the archive and element of the problem.
        """
        by_text = {self._text(link): link for link in self.links}
        # a link that suppresses unit conversion may join variables of different
        # dimensions (a unitless output to an input in rad): it bypasses the scenario's
        # unit check, and its sink is not "unconnected" while the scenario builds
        raw = {text: link for text, link in by_text.items() if link.suppress}
        saved = (self.connections, self.blocks)
        self.connections = [text for text in self.connections if text not in raw]
        self.blocks = {name: copy.copy(spec) for name, spec in self.blocks.items()}
        for link in raw.values():
            spec = self.blocks[link.end[0]]
            spec.unconnected_ok = [*spec.unconnected_ok, _scenario_name(spec, link.end[1])]
        try:
            system, metadata = super().build()
        finally:
            self.connections, self.blocks = saved
        for link in raw.values():
            dst = _scenario_name(self.blocks[link.end[0]], link.end[1])
            metadata.get("unconnected", {}).get(link.end[0], {}).pop(dst, None)
            src = _scenario_name(self.blocks[link.start[0]], link.start[1])
            system.connections.append(Connection(link.start[0], src, link.end[0], dst))
        connections = []
        offsets: dict[str, dict[int, float]] = {}
        for c in system.connections:
            link = by_text[str(c)]
            unit_factor = 1.0 if link.suppress else c.factor
            connections.append(dataclasses.replace(c, factor=unit_factor * link.factor))
            if link.offset != 0.0:
                vr = system.blocks[c.dst_block].variables[c.dst_var].vr
                offsets.setdefault(c.dst_block, {})[vr] = link.offset
        system.connections = connections
        for name, by_vr in offsets.items():
            system.blocks[name] = OffsetInputs(system.blocks[name], by_vr)
        metadata["ssp"] = {
            "file": str(self.path),
            "sha256": self.sha256,
            "version": self.version,
            "components": self.resources,
            "notes": self.notes,
        }
        return system, metadata


class OffsetInputs:
    """A block host whose Real inputs get an SSP connection's offset added when written.

    Everything but :meth:`real_writer` is the wrapped host's: the master writes the
    connected inputs through ``real_writer`` (at initialisation and every step), so
    ``input = factor * output + offset`` with the factor applied by the master.

    Parameters
    ----------
    host : BlockHost
        The block.
    offsets : dict
        Input value reference -> offset [the input's unit].
    """

    def __init__(self, host: Any, offsets: dict[int, float]) -> None:
        self._host = host
        self._offsets = offsets

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("_host", "_offsets"):
            raise AttributeError(name)  # copy/pickle probe before __init__ ran
        return getattr(self._host, name)

    def real_writer(self, vrs: list[int]) -> Callable[[np.ndarray], None]:
        """The host's writer for ``vrs``, adding each input's offset.

        Parameters
        ----------
        vrs : list of int
            Value references of Real inputs.

        Returns
        -------
        callable
            ``write(x)``, ``x`` float64 of shape (len(vrs),).
        """
        write = self._host.real_writer(vrs)
        add = np.array([self._offsets.get(vr, 0.0) for vr in vrs])

        def put(x: np.ndarray) -> None:
            write(x + add)

        return put


def _scenario_name(spec: BlockSpec, fmu_name: str) -> str:
    return spec.rename.get(fmu_name, fmu_name)


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
    """Read an SSP 1.0 or 2.0 archive as a scenario of FMU blocks.

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
    archive = Archive(path)
    root = archive.xml(SSD_FILE, "SystemStructureDescription.xsd", (SSD_FILE, "archive"))
    ssd_units = read_units(root.find("ssd:Units", NS), f"{path}!{SSD_FILE}")
    system = root.find("ssd:System", NS)
    assert system is not None  # the schema requires one
    sys_name = system.get("name", "")
    flat = flatten(archive, system)
    workdir = Path(tempfile.mkdtemp(prefix="ins_cosim_ssp_"))
    atexit.register(shutil.rmtree, workdir, True)
    blocks: dict[str, BlockSpec] = {}
    variables: dict[str, dict[str, Variable]] = {}
    declared: dict[tuple[str, str], tuple[str, ET.Element]] = {}
    notes: list[str] = []
    resources: dict[str, str] = {}
    for name, (comp, cwhere) in flat.components.items():
        blocks[name], variables[name], inner = _component(archive, comp, name, cwhere, workdir)
        resources[name] = inner
        for conn in comp.findall("ssd:Connectors/ssd:Connector", NS):
            kind = connector_type(conn)
            if kind is not None:
                declared[(name, conn.get("name", ""))] = kind
        if blocks[name].rename:
            notes.append(
                f"{name}: FMU variables renamed to scenario names: "
                f"{', '.join(f'{a} -> {b}' for a, b in blocks[name].rename.items())}"
            )
    if not blocks:
        raise archive.error(SSD_FILE, f"System '{sys_name}'", "no ssd:Component; nothing to run")
    _bind_all(archive, flat, (), blocks, variables, ssd_units)
    links, dead = resolve_links(archive, flat)
    notes.extend(f"not connected to a component (exposed by the system only): {d}" for d in dead)
    _check_links(archive, flat, links, variables, declared, ssd_units)
    settings = _settings(archive, root, step, stop, start, coupling, notes)
    data = path.read_bytes()
    return SspScenario(
        path=path,
        sha256=hashlib.sha256(data).hexdigest(),
        name=root.get("name") or sys_name or path.stem,
        settings=settings,
        blocks=blocks,
        connections=[
            f"{lk.start[0]}.{_scenario_name(blocks[lk.start[0]], lk.start[1])} -> "
            f"{lk.end[0]}.{_scenario_name(blocks[lk.end[0]], lk.end[1])}"
            for lk in links
        ],
        outputs=None,
        raw={"scenario": {"name": root.get("name", path.stem)}, "ssp": str(path)},
        links=links,
        notes=notes,
        resources=resources,
        version=archive.version,
    )


def _component(
    archive: Archive, comp: ET.Element, name: str, cwhere: str, workdir: Path
) -> tuple[BlockSpec, dict[str, Variable], str]:
    """The block spec of one component (its FMU unpacked), its variables, its resource."""
    ctype = comp.get("type", "")
    if ctype not in _FMU_TYPES:
        raise archive.error(
            SSD_FILE, cwhere, f"type {ctype!r} is not supported; expected an FMU component"
        )
    impl = comp.get("implementation", "any")
    if impl not in ("any", "CoSimulation"):
        raise archive.error(
            SSD_FILE, cwhere, f"implementation {impl!r}; ins-cosim runs CoSimulation FMUs"
        )
    source = comp.get("source", "")
    inner = archive.member(source, (SSD_FILE, f"{cwhere} source"), "e.g. resources/X.fmu")
    fmu = workdir / name / PurePosixPath(inner).name
    fmu.parent.mkdir(parents=True, exist_ok=True)
    fmu.write_bytes(archive.zip.read(inner))
    check_archive(fmu)
    from fmpy import read_model_description

    try:
        fmu_vars = fmu_variables(read_model_description(str(fmu), validate=False))
    except (FmuError, Exception) as exc:
        raise archive.error(SSD_FILE, f"{cwhere} source", f"cannot read the FMU: {exc}") from None
    taken = {v for v in fmu_vars if SCALAR_NAME.match(v)}
    rename = {}
    for own in fmu_vars:
        if not SCALAR_NAME.match(own):
            rename[own] = _safe_name(own, taken)
            taken.add(rename[own])
    return BlockSpec(name, "fmu", str(fmu.resolve()), rename=rename), fmu_vars, inner


def _bind_all(
    archive: Archive,
    flat: Flat,
    path: tuple[str, ...],
    blocks: dict[str, BlockSpec],
    variables: dict[str, dict[str, Variable]],
    ssd_units: dict[str, Unit],
) -> None:
    """Apply the parameter bindings of the system at ``path`` and below, lowest first
    (SSP: a binding at a higher level takes precedence)."""
    system = flat.systems[path]
    for el in system.findall("ssd:Elements/*", NS):
        sub = (*path, el.get("name", ""))
        block = flat.paths.get(sub)
        if block:  # a component: its own names

            def own(name: str, block: str = block) -> tuple[str, str] | None:
                return (block, name) if name in variables[block] else None

            owner = f"Component '{'/'.join(sub)}'"
            bind_binding_list(archive, el, owner, own, blocks, variables, ssd_units)
        elif block == "":
            _bind_all(archive, flat, sub, blocks, variables, ssd_units)

    def hierarchical(name: str) -> tuple[str, str] | None:
        scope = path
        rest = name
        while "." in rest:
            head, rest = rest.split(".", 1)
            scope = (*scope, head)
            target = flat.paths.get(scope)
            if target is None:
                return None
            if target:
                return (target, rest) if rest in variables[target] else None
        return None

    owner = f"System '{'/'.join(path) if path else system.get('name', '')}'"
    bind_binding_list(archive, system, owner, hierarchical, blocks, variables, ssd_units)


def _check_links(
    archive: Archive,
    flat: Flat,
    links: list[Link],
    variables: dict[str, dict[str, Variable]],
    declared: dict[tuple[str, str], tuple[str, ET.Element]],
    ssd_units: dict[str, Unit],
) -> None:
    """Connector types and units of every link, one line per problem."""
    sinks: dict[tuple[str, str], str] = {}
    for link in links:
        if link.end in sinks:
            raise archive.error(
                SSD_FILE,
                link.where,
                f"the input {link.end[0]}.{link.end[1]} is also fed by {sinks[link.end]}; "
                f"an input takes one source",
            )
        sinks[link.end] = link.where
        types = []
        for comp, conn in (link.start, link.end):
            if conn not in variables[comp]:
                raise archive.error(
                    SSD_FILE, link.where, f"the FMU of '{comp}' has no variable '{conn}'"
                )
            var = variables[comp][conn]
            types.append(var.type)
            kind = declared.get((comp, conn))
            if kind is not None and kind[0] != var.type:
                raise archive.error(
                    SSD_FILE,
                    f"Component '{comp}'/Connector '{conn}'",
                    f"the connector is declared ssc:{_local(kind[1])} but the FMU's variable "
                    f"is {var.type}; declare the FMU's type",
                )
            unit = kind[1].get("unit") if kind is not None else None
            if unit and not _same_unit(unit, var, ssd_units):
                raise archive.error(
                    SSD_FILE,
                    f"Component '{comp}'/Connector '{conn}'",
                    f"the connector's unit '{unit}' is not the FMU's unit '{var.unit}'; "
                    f"ins-cosim converts between the FMUs' own units",
                )
        for node in link.via:
            on_way = flat.types.get(node)
            if on_way is not None and on_way != types[0]:
                what = "signal dictionary entry" if node[0] == "dict" else "system connector"
                raise archive.error(
                    SSD_FILE,
                    link.where,
                    f"the {what} '{node[1]}.{node[2]}' is declared {on_way} but carries "
                    f"{link.start[0]}.{link.start[1]}, a {types[0]}; declare {types[0]}",
                )
        if types[0] != types[1]:
            raise archive.error(
                SSD_FILE,
                link.where,
                f"{_an(types[0])} output ({link.start[0]}.{link.start[1]}) to {_an(types[1])} "
                f"input ({link.end[0]}.{link.end[1]}): FMI connects variables of one type; "
                f"connect {_an(types[1])} output or convert inside an FMU",
            )
        if types[0] != "Real" and (link.factor != 1.0 or link.offset != 0.0):
            raise archive.error(
                SSD_FILE,
                f"{link.where}/LinearTransformation",
                f"a linear transformation on {_an(types[0])} link; only Real links are "
                f"transformed, remove it",
            )


def _an(word: str) -> str:
    return f"an {word}" if word[0] in "AEIOU" else f"a {word}"


def _local(element: ET.Element) -> str:
    return element.tag.rsplit("}", 1)[-1]


def _same_unit(declared: str, var: Variable, ssd_units: dict[str, Unit]) -> bool:
    if declared == var.unit:
        return True
    try:
        a = ssd_units.get(declared) or parse_unit(declared)
        return conversion_factor(a, var.conversion_unit) == 1.0
    except UnitError:
        return False


def _settings(
    archive: Archive,
    root: ET.Element,
    step: float | None,
    stop: float | None,
    start: float | None,
    coupling: str | None,
    notes: list[str],
) -> MasterSettings:
    ssd = SSD_FILE
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
