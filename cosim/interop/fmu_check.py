"""Check an FMU against a role without instantiating it: the ``ins-cosim check-fmu`` report.

:func:`check_fmu` matches the FMU's variables with a role spec
(:func:`cosim.interop.interfaces.match_role`) and adds what the model description and
the binary say about the FMU: FMI version, co-simulation, reset, FMU state, variable
step, platforms. :func:`format_report` prints it all, with the rename map to paste into
a scenario; :func:`read_rename_file` reads such a map back.
"""

from __future__ import annotations

import ctypes
import re
import tempfile
import tomllib
import warnings
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.archives import check_archive
from cosim.errors import FmuError
from cosim.interop.interfaces import InterfaceError, RoleMatch, RoleSpec, load_role, match_role
from cosim.units import name_disagreement
from cosim.variables import Variable, apply_rename, fmu_variables


@dataclass
class FmuReport:
    """Everything :func:`check_fmu` found out about an FMU and a role.

    Attributes
    ----------
    path : Path
        The FMU file.
    fmi_version : str
        ``"2.0"`` or ``"3.0"`` (others are reported as problems).
    model_name, model_identifier, guid : str
        From the model description (identifier of the co-simulation interface).
    capabilities : dict
        Capability name -> ``(available, detail)``.
    platforms : list of str
        Binary folders in the archive (plus ``"sources"`` when C sources are shipped).
    display_units : dict
        Variable name -> its ``displayUnit`` (presentation only, never converted).
    match : RoleMatch
        The role comparison.
    variables : dict
        Every variable of the FMU (after the rename map), by name.
    unit_notes : list of str
        Units whose name and ``BaseUnit`` definition disagree (the definition is used).
    interfaces : list of str
        The FMI interfaces the FMU implements (``co-simulation``, ``model exchange``,
        ``scheduled execution``).
    """

    path: Path
    fmi_version: str
    model_name: str
    model_identifier: str
    guid: str
    capabilities: dict[str, tuple[bool | None, str]]
    platforms: list[str]
    display_units: dict[str, str]
    match: RoleMatch
    variables: dict[str, Variable] = field(default_factory=dict)
    unit_notes: list[str] = field(default_factory=list)
    interfaces: list[str] = field(default_factory=list)

    @property
    def problems(self) -> list[str]:
        """Everything that stops the FMU from filling the role."""
        out = []
        if self.fmi_version not in ("2.0", "3.0"):
            out.append(f"FMI version is {self.fmi_version}, expected 2.0 or 3.0")
        if not self.capabilities["co-simulation"][0]:
            has = " and ".join(self.interfaces) or "no interface"
            out.append(
                f"no co-simulation interface (the FMU implements {has} only); expected "
                f"Co-Simulation: ask the vendor for a Co-Simulation FMU"
            )
        else:
            platform = host_platform(self.fmi_version)
            if platform not in self.platforms and "sources" not in self.platforms:
                out.append(
                    f"no binary for this machine ({platform}) and no C sources in the archive "
                    f"(binaries: {', '.join(self.platforms) or 'none'}); ask the vendor for a "
                    f"{platform} build"
                )
        return out + self.match.problems

    @property
    def satisfied(self) -> bool:
        """True when the FMU fills the role (with :attr:`RoleMatch.rename` applied)."""
        return not self.problems


def check_fmu(
    path: str | Path, role: str | Path | RoleSpec, rename: Mapping[str, str] | None = None
) -> FmuReport:
    """Check how an FMU fills a role, without instantiating it.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file.
    role : str, Path or RoleSpec
        Role name, spec file, or a loaded spec.
    rename : mapping of str to str, optional
        FMU name -> role name to apply first (the map a scenario would use).

    Returns
    -------
    FmuReport

    Raises
    ------
    FmuError
        Missing or unreadable FMU, or a rename map that does not fit it.
    InterfaceError
        Unknown or malformed role spec.
    """
    from fmpy import read_model_description

    spec = role if isinstance(role, RoleSpec) else load_role(role)
    path = Path(path)
    if not path.is_file():
        raise FmuError(f"FMU file '{path}' does not exist")
    check_archive(path)  # the unpack limits, before any member is read
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise FmuError(f"cannot read the model description of '{path}': {exc}") from exc
    try:
        variables = fmu_variables(md)
    except FmuError as exc:
        raise FmuError(f"'{path}': {exc}") from exc
    try:
        match = match_role(variables, spec, rename)
    except FmuError as exc:
        raise FmuError(f"'{path}': {exc}") from exc
    cs = md.coSimulation
    with zipfile.ZipFile(path) as zf:
        names = zf.namelist()
        platforms = sorted(
            {n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2}
        )
        if any(n.startswith("sources/") for n in names):
            platforms.append("sources")
        reset = _probe_reset(zf, md, names)
    capabilities: dict[str, tuple[bool | None, str]] = {
        "co-simulation": (
            cs is not None,
            f"modelIdentifier '{cs.modelIdentifier}'" if cs is not None else "none",
        ),
        "model exchange": (md.modelExchange is not None, ""),
        "reset": reset,
        "get/set state": (
            bool(cs and cs.canGetAndSetFMUstate),
            "canGetAndSetFMUstate",
        ),
        "serialize state": (bool(cs and cs.canSerializeFMUstate), "canSerializeFMUstate"),
        "variable step": (
            bool(cs and cs.canHandleVariableCommunicationStepSize),
            "canHandleVariableCommunicationStepSize",
        ),
    }
    display = {v.name: v.displayUnit for v in md.modelVariables if v.displayUnit}
    notes = list(
        dict.fromkeys(
            name_disagreement(v.unit_def) for v in variables.values() if v.unit_def is not None
        )
    )
    interfaces = [
        label
        for label, part in (
            ("co-simulation", cs),
            ("model exchange", md.modelExchange),
            ("scheduled execution", getattr(md, "scheduledExecution", None)),
        )
        if part is not None
    ]
    return FmuReport(
        path=path,
        fmi_version=md.fmiVersion,
        model_name=md.modelName,
        model_identifier=cs.modelIdentifier if cs is not None else "",
        guid=md.guid,
        capabilities=capabilities,
        platforms=platforms,
        display_units=display,
        match=match,
        variables=apply_rename(variables, match.rename, "FMU") if match.rename else variables,
        unit_notes=[n for n in notes if n],
        interfaces=interfaces,
    )


def host_platform(fmi_version: str) -> str:
    """The binary folder an FMU needs for this machine (x86_64 Linux).

    Parameters
    ----------
    fmi_version : str
        ``"2.0"`` or ``"3.0"``.

    Returns
    -------
    str
        ``linux64`` (FMI 2) or ``x86_64-linux`` (FMI 3).
    """
    return "x86_64-linux" if fmi_version.startswith("3") else "linux64"


def _probe_reset(zf: zipfile.ZipFile, md: Any, names: list[str]) -> tuple[bool | None, str]:
    """Whether the binary for this machine exports the FMI reset function."""
    symbol = "fmi3Reset" if md.fmiVersion.startswith("3") else "fmi2Reset"
    if md.coSimulation is None:
        return None, "no co-simulation interface"
    platform = host_platform(md.fmiVersion)
    member = f"binaries/{platform}/{md.coSimulation.modelIdentifier}.so"
    if member not in names:
        return None, f"unknown: no binary for {platform} ({member})"
    with tempfile.TemporaryDirectory(prefix="ins_cosim_probe_") as tmp:
        library = Path(zf.extract(member, tmp))
        try:
            lib = ctypes.CDLL(str(library), mode=ctypes.RTLD_LOCAL)
        except OSError as exc:
            return False, f"the binary does not load: {exc}"
        found = hasattr(lib, symbol)
    return found, f"{symbol} {'exported' if found else 'missing from the binary'}"


# ----------------------------------------------------------------------- formatting
def _fmt_factor(factor: float | None) -> str:
    if factor is None:
        return ""
    if factor == 1.0:
        return "same"
    return f"x{factor:.6g}"


def format_rename(rename: Mapping[str, str], block: str = "<block>") -> str:
    """A rename map as the TOML table to paste into a scenario.

    Parameters
    ----------
    rename : mapping of str to str
        FMU name -> scenario name.
    block : str
        The block's name in the scenario.

    Returns
    -------
    str
        ``[blocks.<block>.rename]`` and one ``"fmu_name" = "scenario_name"`` line each.
    """
    lines = [f"[blocks.{block}.rename]"]
    lines += [f'"{old}" = "{new}"' for old, new in rename.items()]
    return "\n".join(lines)


def format_report(report: FmuReport, block: str = "<block>") -> str:
    """The report :command:`ins-cosim check-fmu` prints.

    Parameters
    ----------
    report : FmuReport
        From :func:`check_fmu`.
    block : str
        Block name used in the suggested ``[blocks.<block>.rename]`` table.

    Returns
    -------
    str
        Several lines of text (no trailing newline).
    """
    m = report.match
    lines = [
        f"{report.path.name}: FMI {report.fmi_version}, model '{report.model_name}', "
        f"GUID {report.guid}",
        f"  platforms: {', '.join(report.platforms) or 'none'}",
        "  capabilities:",
    ]
    for name, (value, detail) in report.capabilities.items():
        word = {True: "yes", False: "no", None: "?"}[value]
        lines.append(f"    {name:<16} {word:<4} {detail}")
    n_req = sum(rv.required for rv in m.role.variables)
    lines += [
        "",
        f"role '{m.role.name}' ({m.role.path}): {m.role.description}",
        f"  {len(m.role.variables)} variables ({n_req} required, "
        f"{len(m.role.variables) - n_req} optional), {len(m.entries)} scalars",
    ]
    if m.form:
        others = ", ".join(f"'{f}'" for f in m.role.forms if f != m.form)
        lines.append(
            f"  input form: '{m.form}' (the role's alternatives: {', '.join(m.role.forms)}; "
            f"the variables of {others} are not needed)"
        )
    lines += [
        "",
        f"  {'role variable':<18} {'FMU variable':<18} {'causality':<10} "
        f"{'FMU unit':<16} {'to role':<12} status",
    ]
    for e in m.entries:
        required = m.required(e)
        req = "" if required else " (optional)"
        if e.variable.form and e.variable.form != m.form:
            req = f" (form '{e.variable.form}', not used)"
        if e.fmu is None:
            status = "MISSING" + req if required else "absent" + req
            lines.append(
                f"  {e.role_name:<18} {'-':<18} {e.variable.causality:<10} "
                f"{'':<16} {'':<12} {status}"
            )
            continue
        status = "ok" if e.ok else "PROBLEM: " + "; ".join(e.problems)
        if e.how in ("renamed", "suggested"):
            status += f" [{e.how}]"
        display = report.display_units.get(e.fmu.own_name)
        unit = e.fmu.unit + (f" ({display})" if display else "")
        lines.append(
            f"  {e.role_name:<18} {e.fmu.own_name:<18} {e.fmu.causality:<10} "
            f"{unit:<16} {_fmt_factor(e.factor):<12} {status}{req}"
        )
    if report.display_units:
        lines += [
            "",
            "  (units in parentheses are display units: presentation only, values cross "
            "FMI in the unit)",
        ]
    lines += _other_variables(report)
    if report.unit_notes:
        lines += ["", "units:"] + [f"  WARNING {n}" for n in report.unit_notes]
    if m.needs_rename:
        lines += [
            "",
            "rename map (paste into the scenario's block table; check the suggestions):",
            format_rename(m.rename, block),
        ]
    lines.append("")
    if report.satisfied:
        how = " with this rename map" if m.needs_rename else ""
        lines.append(f"result: '{report.path.name}' fills role '{m.role.name}'{how}")
        for w in m.warnings:
            lines.append(f"  warning (optional variable): {w}")
    else:
        lines.append(
            f"result: '{report.path.name}' does not fill role '{m.role.name}': "
            f"{len(report.problems)} problem(s)"
        )
        lines += [f"  - {p}" for p in report.problems]
        lines += [f"  warning (optional variable): {w}" for w in m.warnings]
    return "\n".join(lines)


def _unit_text(v: Variable) -> str:
    if v.type != "Real":
        return "-"
    if v.unit_def is not None and v.unit_def.factor != 1.0:
        return f"{v.unit} (= {v.unit_def.factor:.6g} {v.unit_def.si_text()})"
    return v.unit


def _other_variables(report: FmuReport) -> list[str]:
    """Every FMU variable the role does not use: its inputs, parameters and outputs."""
    used = {e.fmu.own_name for e in report.match.entries if e.fmu is not None}
    rest = [
        v
        for v in report.variables.values()
        if v.own_name not in used and v.causality in ("input", "parameter", "output")
    ]
    if not rest:
        return []
    lines = [
        "",
        "FMU variables outside the role (inputs left unconnected run on their start value):",
        f"  {'FMU variable':<22} {'causality':<10} {'type':<8} {'unit':<32} {'start':<10} "
        f"description",
    ]
    for v in rest:
        start = "-" if v.start is None else str(v.start)
        lines.append(
            f"  {v.name:<22} {v.causality:<10} {v.type:<8} {_unit_text(v):<32} {start:<10} "
            f"{v.description}"
        )
    return lines


# ------------------------------------------------------------- scenario edits
_LINK = re.compile(r"^\s*(\w+)\.([\w\[\]]+)\s*->\s*(\w+)\.([\w\[\]]+)\s*$")


def _base(name: str) -> str:
    return name.split("[", 1)[0]


def _scenario_variables(sc: Any, block: str) -> dict[str, dict[str, Variable]]:
    """The variables of every block of a scenario but ``block`` (built once, then freed)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        system, _ = sc.build()
    try:
        return {n: dict(h.variables) for n, h in system.blocks.items() if n != block}
    finally:
        for host in system.blocks.values():
            host.terminate()


def _groups(variables: Mapping[str, Variable], causality: str) -> dict[str, list[Variable]]:
    out: dict[str, list[Variable]] = {}
    for v in variables.values():
        if v.causality == causality:
            out.setdefault(_base(v.name), []).append(v)
    return out


def scenario_edits(report: FmuReport, scenario: str | Path, block: str) -> list[str]:
    """What to change in a scenario to swap this FMU in for one of its blocks.

    Printed by ``ins-cosim check-fmu --scenario``: the block table (FMU path, role, the
    FMU's parameters at their start values, the rename map), the connection lines to
    remove and to add (the role inputs of the FMU's input form, fed by the outputs of the
    scenario that fit: the blocks that feed the block now first, then by name), what
    could feed the FMU's other inputs, and the scenario entries that name variables the
    FMU lacks (``[output]``, ``[campaign]``, requirements). Each line works as pasted.

    Parameters
    ----------
    report : FmuReport
        From :func:`check_fmu`.
    scenario : str or Path
        The scenario file.
    block : str
        The block the FMU replaces (or a new block's name).

    Returns
    -------
    list of str
        Lines of text.

    Raises
    ------
    ScenarioError
        The scenario cannot be read.
    """
    from cosim.interop.interfaces import name_score
    from cosim.scenario import load_scenario
    from cosim.units import conversion_factor

    sc = load_scenario(scenario)
    m = report.match
    mine = report.variables
    others = _scenario_variables(sc, block)
    inputs = _groups(mine, "input")
    links = [_LINK.match(c) for c in sc.connections if isinstance(c, str)]
    into = [(c, lk) for c, lk in zip(sc.connections, links, strict=True) if lk and lk[3] == block]
    feeders = list(dict.fromkeys(lk[1] for _c, lk in into))
    keep = [c for c, lk in into if _base(lk[4]) in inputs]
    drop = [c for c, lk in into if _base(lk[4]) not in inputs]
    wired = {_base(lk[4]) for _c, lk in into if _base(lk[4]) in inputs}

    def fits(src: list[Variable], dst: list[Variable]) -> bool:
        if len(src) != len(dst) or any(v.type != "Real" for v in src + dst):
            return False
        try:
            for a, b in zip(src, dst, strict=True):
                conversion_factor(a.conversion_unit, b.conversion_unit)
        except Exception:
            return False
        return True

    def candidates(name: str, dst: list[Variable], rv: Any) -> list[str]:
        found = []
        for b, variables in others.items():
            for base, outs in _groups(variables, "output").items():
                if fits(outs, dst):
                    score = name_score(rv, base) if rv is not None else 0.0
                    rank = feeders.index(b) if b in feeders else len(feeders)
                    found.append((rank, -score, f"{b}.{base}"))
        return [c for *_k, c in sorted(found)]

    roles = {rv.name: rv for rv in m.role.variables}
    add, unfed = [], []
    for base, dst in inputs.items():
        if base in wired:
            continue
        rv = roles.get(base)
        options = candidates(base, dst, rv)
        if rv is not None and m.required(next(e for e in m.entries if e.variable is rv)):
            if options:
                add.append(f'"{options[0]} -> {block}.{base}",')
            else:
                unfed.append(f"  {block}.{base}: required, and no output of the scenario fits")
        else:
            feed = ", ".join(options[:4]) or "no output of the scenario fits"
            unfed.append(f"  {block}.{base} (start {dst[0].start}): could be fed by {feed}")

    fmu_path = report.path.resolve()
    params = [v for v in mine.values() if v.causality == "parameter"]

    def value(v: Variable) -> str:
        start = v.start if v.start is not None else 0
        if v.type == "Real":
            return f'"{start} {v.unit}"' if v.unit not in ("", "1") else str(start)
        if v.type == "Boolean":
            return "true" if start else "false"
        return f'"{start}"' if v.type == "String" else str(start)

    vector: dict[str, list[Variable]] = {}
    for v in params:
        vector.setdefault(_base(v.name) if "[" in v.name else v.name, []).append(v)
    items = []
    for base, vs in vector.items():
        if len(vs) == 1 and "[" not in vs[0].name:
            items.append(f"{base} = {value(vs[0])}")
        else:
            items.append(f"{base} = [{', '.join(value(v) for v in vs)}]")
    lines = [
        "",
        f"scenario edits to swap '{report.path.name}' in for block '{block}' of {sc.path}:",
        f"1. replace the table [blocks.{block}] (and its sub-tables) by (set the parameters to "
        f"the vendor's data sheet; these are the FMU's start values):",
        f"[blocks.{block}]",
        f'fmu = "{fmu_path}"',
        f'role = "{m.role.name}"',
        f"parameters = {{ {', '.join(items)} }}",
    ]
    if m.needs_rename:
        lines.append(format_rename(m.rename, block))
    lines.append("2. in connections, remove:" if drop else "2. no connection to remove")
    lines += [f'"{c}",' for c in drop]
    lines.append("3. in connections, add:" if add else "3. no connection to add")
    lines += add
    if keep:
        lines.append(f"   (kept as they are: {', '.join(keep)})")
    if unfed:
        lines.append("4. inputs left on their start value (connect them, or list them under")
        lines.append(f"   [blocks.{block}] unconnected_ok = [...]):")
        lines += unfed
    lines += _dangling(sc, block, mine)
    return lines


def _dangling(sc: Any, block: str, mine: Mapping[str, Variable]) -> list[str]:
    """Scenario entries that name variables of ``block`` the FMU does not have."""
    outputs = {_base(v.name) for v in mine.values() if v.causality == "output"} | {
        v.name for v in mine.values() if v.causality == "output"
    }
    params = {v.name for v in mine.values() if v.causality == "parameter"}
    out = []
    for item in sc.outputs or []:
        b, _, var = str(item).partition(".")
        if b == block and var and var not in outputs:
            out.append(f'   [output] variables: remove "{item}" (the FMU has no such output)')
    campaign = sc.raw.get("campaign", {})
    for item in campaign.get("stratify", []):
        b, _, name = str(item).partition(".")
        if b == block and f"{name}_sigma" not in params:
            out.append(
                f'   [campaign] stratify: remove "{item}" (the FMU draws no {name}: set its '
                f"own parameters instead)"
            )
    if block in campaign.get("randomize", []) and "seed" not in params:
        out.append(
            f'   [campaign] randomize: remove "{block}", or rename the FMU\'s seed parameter '
            f'to "seed" (the campaign sets "seed" per run)'
        )
    for i, req in enumerate(sc.raw.get("requirements", [])):
        for key in ("signal", "sigma", "minus"):
            b, _, var = str(req.get(key, "")).partition(".")
            if b == block and _base(var) not in outputs:
                out.append(f"   requirements[{i}].{key} = {req[key]!r}: the FMU has no such output")
    return ["5. scenario entries that name what the FMU lacks:", *out] if out else []


def read_rename_file(path: str | Path) -> dict[str, str]:
    """A rename map from a TOML file.

    Parameters
    ----------
    path : str or Path
        A TOML file with a ``[rename]`` table, or a scenario-like file with exactly one
        ``[blocks.<name>.rename]`` table, or a plain table of ``"fmu_name" = "name"``.

    Returns
    -------
    dict
        FMU name -> scenario name.

    Raises
    ------
    InterfaceError
        Missing or malformed file, or no single rename table in it.
    """
    path = Path(path)
    if not path.is_file():
        raise InterfaceError(f"rename file '{path}' does not exist")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InterfaceError(f"{path}: not valid TOML: {exc}") from exc
    if isinstance(doc.get("rename"), dict):
        table = doc["rename"]
    elif isinstance(doc.get("blocks"), dict):
        tables = [
            b["rename"] for b in doc["blocks"].values() if isinstance(b, dict) and "rename" in b
        ]
        if len(tables) != 1:
            raise InterfaceError(
                f"{path}: expected exactly one [blocks.<name>.rename] table, got {len(tables)}"
            )
        table = tables[0]
    else:
        table = doc
    if not table or not all(isinstance(k, str) and isinstance(v, str) for k, v in table.items()):
        raise InterfaceError(
            f'{path}: expected a table of "fmu_name" = "scenario_name" strings, got {table!r}'
        )
    return dict(table)
