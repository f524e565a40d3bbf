"""Check an FMU against a role without instantiating it: the ``ins-cosim check-fmu`` report.

:func:`check_fmu` matches the FMU's variables with a role spec
(:func:`cosim.interop.interfaces.match_role`) and adds what the model description and
the binary say about the FMU: FMI version, co-simulation, reset, FMU state, variable
step, platforms. :func:`format_report` prints it all, with the rename map to paste into
a scenario; :func:`read_rename_file` reads such a map back.
"""

from __future__ import annotations

import ctypes
import tempfile
import tomllib
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.blocks import fmu_variables
from cosim.errors import FmuError
from cosim.interop.interfaces import InterfaceError, RoleMatch, RoleSpec, load_role, match_role


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

    @property
    def problems(self) -> list[str]:
        """Everything that stops the FMU from filling the role."""
        out = []
        if self.fmi_version not in ("2.0", "3.0"):
            out.append(f"FMI version is {self.fmi_version}, expected 2.0 or 3.0")
        if not self.capabilities["co-simulation"][0]:
            out.append("no co-simulation interface (Model Exchange only); expected Co-Simulation")
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
    )


def _host_platform(fmi_version: str) -> str:
    return "x86_64-linux" if fmi_version.startswith("3") else "linux64"


def _probe_reset(zf: zipfile.ZipFile, md: Any, names: list[str]) -> tuple[bool | None, str]:
    """Whether the binary for this machine exports the FMI reset function."""
    symbol = "fmi3Reset" if md.fmiVersion.startswith("3") else "fmi2Reset"
    if md.coSimulation is None:
        return None, "no co-simulation interface"
    platform = _host_platform(md.fmiVersion)
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
        "",
        f"  {'role variable':<18} {'FMU variable':<18} {'causality':<10} "
        f"{'FMU unit':<16} {'to role':<12} status",
    ]
    for e in m.entries:
        req = "" if e.variable.required else " (optional)"
        if e.fmu is None:
            status = "MISSING" + req if e.variable.required else "absent" + req
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
