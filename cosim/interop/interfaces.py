"""Role interface specs, and how well a block or an FMU fills a role.

A *role* is a place in a scenario that a block fills: ``motion``, ``flexure``, ``imu``,
``hrg_gyro``, ``accelerometer``, ``master_ins``. Its spec, ``fmus/interfaces/<role>.toml``,
lists the variables a block must expose to fill it::

    [role]
    name = "imu"
    description = "..."
    models = ["StrapdownImu"]          # our models that fill the role (tested)

    [[variables]]
    name = "dtheta_b"                  # the name the scenario uses
    causality = "input"                # input | output | parameter
    unit = "rad"                       # the scenario side's unit; any compatible unit will do
    size = 3                           # vector: dtheta_b[1] .. dtheta_b[3]; default 1 (scalar)
    required = true                    # default true
    type = "Real"                      # default Real
    description = "..."
    aliases = ["true_dtheta", ...]     # words vendors use; only for suggesting a rename map

:func:`match_role` compares a block's variables with a spec: each role scalar is found
under its own name (possibly after a rename map), or a candidate is *suggested*: FMU
variables are grouped into vectors by their axis suffix (``_x``/``_y``/``_z``, ``X``,
``_1``, ``[1]``), and each role variable takes the group that scores best on
causality, unit dimension, type, name (the role's name and aliases against the
group's, word by word) and coverage; required variables choose first, each group
serves one role variable; a candidate needs at least one word in common with the
role's name or aliases (a prefix of 3 letters or more counts). Every matched scalar
is then checked: causality, type and unit (the factor from the FMU's unit to the
role's, or the reason it cannot convert).

:func:`check_fmu` adds what the model description and binary say about the FMU (FMI
version, co-simulation, reset, FMU state, variable step, platforms) and
:func:`format_report` prints it all, with the rename map to paste into a scenario.
"""

from __future__ import annotations

import ctypes
import difflib
import re
import tempfile
import tomllib
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.blocks import Variable, apply_rename, fmu_variables
from cosim.errors import FmuError, UnitError, UserError
from cosim.units import conversion_factor

#: Folder of the role specs shipped with ins-cosim.
ROLE_DIR = Path(__file__).resolve().parents[2] / "fmus" / "interfaces"

_CAUSALITIES = ("input", "output", "parameter")
_TYPES = ("Real", "Integer", "Boolean", "String")
_ROLE_KEYS = {"name", "description", "models"}
_VARIABLE_KEYS = {
    "name",
    "causality",
    "unit",
    "size",
    "required",
    "type",
    "description",
    "aliases",
}
# Words that say where a vector lives rather than what it is (frame suffixes).
_FRAME_WORDS = {"b", "n", "p", "s", "e", "i"}


class InterfaceError(UserError):
    """An unknown role, or a role spec file that is malformed."""


@dataclass(frozen=True)
class RoleVariable:
    """One (scalar or vector) variable of a role.

    Attributes
    ----------
    name : str
        Base name the scenario uses (``dtheta_b``).
    causality : str
        ``input``, ``output`` or ``parameter``.
    unit : str
        Unit on the scenario's side (SI, e.g. ``rad``).
    size : int
        1 for a scalar ``name``; n for ``name[1]`` .. ``name[n]``.
    required : bool
        False: the role is filled without it (it is checked when present).
    type : str
        FMI type, ``Real`` unless stated.
    description : str
        What it is, with frame and direction.
    aliases : tuple of str
        Names vendors commonly use (only for suggestions).
    """

    name: str
    causality: str
    unit: str
    size: int = 1
    required: bool = True
    type: str = "Real"
    description: str = ""
    aliases: tuple[str, ...] = ()

    def scalars(self) -> list[str]:
        """The scalar names: ``[name]`` or ``[name[1], ..., name[size]]``."""
        if self.size == 1:
            return [self.name]
        return [f"{self.name}[{i}]" for i in range(1, self.size + 1)]


@dataclass(frozen=True)
class RoleSpec:
    """A role interface spec (one ``fmus/interfaces/<role>.toml``).

    Attributes
    ----------
    name : str
        Role name.
    description : str
        One line.
    models : tuple of str
        Our model classes that fill the role.
    variables : tuple of RoleVariable
        In file order.
    path : Path
        The spec file.
    """

    name: str
    description: str
    models: tuple[str, ...]
    variables: tuple[RoleVariable, ...]
    path: Path


def available_roles() -> list[str]:
    """Names of the role specs in :data:`ROLE_DIR`, sorted."""
    return sorted(p.stem for p in ROLE_DIR.glob("*.toml"))


def load_role(role: str | Path) -> RoleSpec:
    """Read a role spec by name (``"imu"``) or from a ``.toml`` path.

    Parameters
    ----------
    role : str or Path
        A name among :func:`available_roles`, or the path of a spec file.

    Returns
    -------
    RoleSpec

    Raises
    ------
    InterfaceError
        Unknown role (the known ones are listed), or a malformed spec (file and key named).
    """
    text = str(role)
    if text.endswith(".toml") or "/" in text:
        path = Path(text)
        if not path.is_file():
            raise InterfaceError(f"role spec file '{path}' does not exist")
    else:
        path = ROLE_DIR / f"{text}.toml"
        if not path.is_file():
            known = available_roles()
            hint = difflib.get_close_matches(text, known, n=1)
            tip = f" Did you mean '{hint[0]}'?" if hint else ""
            raise InterfaceError(
                f"unknown role '{text}'.{tip} Known roles: {', '.join(known)} "
                f"(or give the path of a role spec .toml)"
            )
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InterfaceError(f"{path}: not valid TOML: {exc}") from exc
    return _parse_spec(doc, path)


def _parse_spec(doc: dict[str, Any], path: Path) -> RoleSpec:
    def bad(key: str, expected: str, got: Any) -> InterfaceError:
        return InterfaceError(f"{path}, key '{key}': expected {expected}, got {got!r}")

    head = doc.get("role")
    if not isinstance(head, dict) or not isinstance(head.get("name"), str):
        raise bad("role.name", "a [role] table with name = '...'", head)
    for k in head:
        if k not in _ROLE_KEYS:
            raise bad(f"role.{k}", f"one of {sorted(_ROLE_KEYS)}", k)
    models = head.get("models", [])
    if not isinstance(models, list) or not all(isinstance(m, str) for m in models):
        raise bad("role.models", "a list of model class names", models)
    raw_vars = doc.get("variables")
    if not isinstance(raw_vars, list) or not raw_vars:
        raise bad("variables", "one or more [[variables]] tables", raw_vars)
    variables = []
    seen: set[str] = set()
    for i, v in enumerate(raw_vars):
        key = f"variables[{i}]"
        if not isinstance(v, dict):
            raise bad(key, "a table", v)
        for k in v:
            if k not in _VARIABLE_KEYS:
                raise bad(f"{key}.{k}", f"one of {sorted(_VARIABLE_KEYS)}", k)
        name = v.get("name")
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_]\w*", name):
            raise bad(f"{key}.name", "an identifier", name)
        if name in seen:
            raise bad(f"{key}.name", "a name not used before in the spec", name)
        seen.add(name)
        causality = v.get("causality")
        if causality not in _CAUSALITIES:
            raise bad(f"{key}.causality", " or ".join(_CAUSALITIES), causality)
        vtype = v.get("type", "Real")
        if vtype not in _TYPES:
            raise bad(f"{key}.type", " or ".join(_TYPES), vtype)
        unit = v.get("unit", "1")
        if not isinstance(unit, str):
            raise bad(f"{key}.unit", "a unit string such as 'rad/s'", unit)
        size = v.get("size", 1)
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise bad(f"{key}.size", "a positive integer", size)
        required = v.get("required", True)
        if not isinstance(required, bool):
            raise bad(f"{key}.required", "true or false", required)
        aliases = v.get("aliases", [])
        if not isinstance(aliases, list) or not all(isinstance(a, str) for a in aliases):
            raise bad(f"{key}.aliases", "a list of strings", aliases)
        variables.append(
            RoleVariable(
                name=name,
                causality=causality,
                unit=unit,
                size=size,
                required=required,
                type=vtype,
                description=str(v.get("description", "")),
                aliases=tuple(aliases),
            )
        )
    return RoleSpec(
        name=head["name"],
        description=str(head.get("description", "")),
        models=tuple(models),
        variables=tuple(variables),
        path=path,
    )


# ------------------------------------------------------------------------ matching
@dataclass
class Entry:
    """How one role scalar is filled.

    Attributes
    ----------
    role_name : str
        Scalar name in the role (``dtheta_b[1]``).
    variable : RoleVariable
        Its role variable.
    how : str
        ``"exact"`` (same name), ``"renamed"`` (through the given rename map),
        ``"suggested"`` (a candidate proposed here) or ``"missing"``.
    fmu : Variable or None
        The block's variable (``fmu.own_name`` is its name in the FMU).
    factor : float or None
        Unit factor from the FMU's unit to the role's (``value_role = factor *
        value_fmu``), None when the units cannot be converted or do not apply.
    problems : list of str
        What is wrong with the match (empty: fine).
    """

    role_name: str
    variable: RoleVariable
    how: str
    fmu: Variable | None = None
    factor: float | None = None
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when a variable fills this scalar without problems."""
        return self.fmu is not None and not self.problems


@dataclass
class RoleMatch:
    """The outcome of :func:`match_role`.

    Attributes
    ----------
    role : RoleSpec
        The spec matched against.
    entries : list of Entry
        One per role scalar, in spec order.
    given_rename : dict
        The rename map that was given (FMU name -> role name).
    """

    role: RoleSpec
    entries: list[Entry]
    given_rename: dict[str, str] = field(default_factory=dict)

    @property
    def rename(self) -> dict[str, str]:
        """The full rename map to use: FMU name -> role name, for every entry that needs one."""
        out = dict(self.given_rename)
        for e in self.entries:
            if e.fmu is not None and e.fmu.own_name != e.role_name:
                out.setdefault(e.fmu.own_name, e.role_name)
        return out

    @property
    def problems(self) -> list[str]:
        """Problems of required scalars (missing, wrong causality, type or unit)."""
        return [msg for e in self.entries if e.variable.required for msg in _messages(e)]

    @property
    def warnings(self) -> list[str]:
        """Problems of optional scalars that are present (they would matter if used)."""
        return [
            msg
            for e in self.entries
            if not e.variable.required and e.fmu is not None
            for msg in _messages(e)
        ]

    @property
    def satisfied(self) -> bool:
        """True when every required scalar is filled without problems."""
        return not self.problems

    @property
    def needs_rename(self) -> bool:
        """True when filling the role needs names changed."""
        return bool(self.rename)


def _messages(e: Entry) -> list[str]:
    if e.fmu is None:
        kind = "required" if e.variable.required else "optional"
        return [
            f"{e.role_name}: missing ({kind} {e.variable.causality}, {e.variable.unit}): "
            f"the FMU has no variable for it"
        ]
    return [f"{e.role_name} <- '{e.fmu.own_name}': {p}" for p in e.problems]


def match_role(
    variables: Mapping[str, Variable],
    role: RoleSpec,
    rename: Mapping[str, str] | None = None,
    suggest: bool = True,
) -> RoleMatch:
    """Compare a block's variables with a role spec.

    Parameters
    ----------
    variables : mapping of str to Variable
        The block's variables (``BlockHost.variables`` or :func:`cosim.blocks.fmu_variables`).
    role : RoleSpec
        The spec.
    rename : mapping of str to str, optional
        FMU name -> role name, applied first (as a scenario's ``rename`` table would be).
    suggest : bool
        Propose candidates for the role scalars not found by name.

    Returns
    -------
    RoleMatch

    Raises
    ------
    FmuError
        The rename map names a variable the block does not have, or collides.
    """
    given = dict(rename or {})
    named = apply_rename(variables, given, "FMU") if given else dict(variables)
    entries: dict[str, Entry] = {}
    used: set[str] = set()
    for rv in role.variables:
        for scalar in rv.scalars():
            var = named.get(scalar)
            if var is not None:
                how = "renamed" if var.fmu_name else "exact"
                entries[scalar] = _checked(Entry(scalar, rv, how, var))
                used.add(scalar)
            else:
                entries[scalar] = Entry(scalar, rv, "missing")
    if suggest:
        role_names = {s for rv in role.variables for s in rv.scalars()}
        pool = {n: v for n, v in named.items() if n not in used and n not in role_names}
        for rv, group in _assign(role, entries, pool):
            for i, scalar in enumerate(rv.scalars(), start=1):
                var = group.get(i if rv.size > 1 else None)
                if var is not None:
                    entries[scalar] = _checked(Entry(scalar, rv, "suggested", var))
    ordered = [entries[s] for rv in role.variables for s in rv.scalars()]
    return RoleMatch(role=role, entries=ordered, given_rename=given)


def _checked(e: Entry) -> Entry:
    rv, var = e.variable, e.fmu
    assert var is not None
    if var.causality != rv.causality:
        e.problems.append(f"causality is '{var.causality}', expected '{rv.causality}'")
    if var.type != rv.type:
        e.problems.append(f"type is {var.type}, expected {rv.type}")
    elif rv.type == "Real":
        try:
            e.factor = conversion_factor(var.conversion_unit, rv.unit)
        except UnitError as exc:
            e.problems.append(exc.message)
    return e


# Suggestions -------------------------------------------------------------------
_AXIS_PATTERNS = (
    re.compile(r"^(?P<base>.+)\[(?P<i>[1-9]\d*)\]$"),
    re.compile(r"^(?P<base>.+?)[_.](?P<a>[xyzXYZ])$"),
    re.compile(r"^(?P<base>.*[a-z0-9])(?P<a>[XYZ])$"),
    re.compile(r"^(?P<base>.+?)_(?P<i>[1-9])$"),
)


def _split_axis(name: str) -> tuple[str, int | None]:
    for pattern in _AXIS_PATTERNS:
        m = pattern.match(name)
        if m:
            if m.groupdict().get("a"):
                return m["base"], "xyz".index(m["a"].lower()) + 1
            return m["base"], int(m["i"])
    return name, None


def _words(name: str) -> set[str]:
    spaced = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", name)
    return {w for w in re.split(r"[^A-Za-z0-9]+", spaced.lower()) if w} - _FRAME_WORDS


def _same_word(a: str, b: str) -> bool:
    """Equal, or one a prefix of the other of 3 letters or more ("vel", "velocity")."""
    if a == b:
        return True
    short, long_ = sorted((a, b), key=len)
    return len(short) >= 3 and long_.startswith(short)


def _name_score(rv: RoleVariable, base: str) -> float:
    """Word overlap (Jaccard) of a group's base name with the role name or an alias."""
    theirs = _words(base)
    best = 0.0
    for candidate in (rv.name, *rv.aliases):
        ours = _words(candidate)
        if ours and theirs:
            common = sum(any(_same_word(w, t) for t in theirs) for w in ours)
            best = max(best, common / (len(ours) + len(theirs) - common))
    return best


def _groups(pool: Mapping[str, Variable]) -> dict[str, dict[int | None, Variable]]:
    groups: dict[str, dict[int | None, Variable]] = {}
    for name, var in pool.items():
        base, axis = _split_axis(name)
        key = base if axis is not None else f"{name}\0scalar"
        groups.setdefault(key, {})[axis] = var
    return groups


def _score(rv: RoleVariable, group: Mapping[int | None, Variable], base: str) -> float | None:
    """Score of a group for a role variable, None when it is not a candidate."""
    if rv.size == 1:
        if set(group) != {None}:
            return None
        present = [group[None]]
        coverage = 1.0
    else:
        if None in group or any(i > rv.size for i in group):
            return None
        present = [group[i] for i in range(1, rv.size + 1) if i in group]
        coverage = len(present) / rv.size
    n = len(present)
    causality = sum(v.causality == rv.causality for v in present) / n
    vtype = sum(v.type == rv.type for v in present) / n
    units = 0
    for v in present:
        try:
            conversion_factor(v.conversion_unit, rv.unit)
            units += 1
        except UnitError:
            pass
    unit = units / n
    name = _name_score(rv, base)
    complete = causality == 1.0 and unit == 1.0 and vtype == 1.0
    # a candidate needs a word in common with the role's names; required variables may
    # take a group with problems (to report them), optional ones only a fitting group
    # (so that, e.g., vendor bias parameters are not proposed as truth outputs)
    if not ((complete and name > 0.0) or (rv.required and name >= 0.5)):
        return None
    return 3 * causality + 3 * unit + 2 * name + coverage + vtype


def _assign(
    role: RoleSpec, entries: Mapping[str, Entry], pool: Mapping[str, Variable]
) -> list[tuple[RoleVariable, dict[int | None, Variable]]]:
    """Greedy one-to-one assignment of groups to the role variables not found by name."""
    groups = _groups(pool)
    wanted = [rv for rv in role.variables if all(entries[s].how == "missing" for s in rv.scalars())]
    scored = []
    for rv in wanted:
        for key, group in groups.items():
            base = key.split("\0", 1)[0]
            s = _score(rv, group, base)
            if s is not None:
                tie = difflib.SequenceMatcher(None, rv.name, base).ratio()
                scored.append((not rv.required, -s, -tie, rv.name, key))
    scored.sort()
    chosen: list[tuple[RoleVariable, dict[int | None, Variable]]] = []
    done_vars: set[str] = set()
    done_groups: set[str] = set()
    by_name = {rv.name: rv for rv in wanted}
    for _optional, _s, _tie, rv_name, key in scored:
        if rv_name in done_vars or key in done_groups:
            continue
        done_vars.add(rv_name)
        done_groups.add(key)
        chosen.append((by_name[rv_name], groups[key]))
    return chosen


# ----------------------------------------------------------------------- FMU report
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
