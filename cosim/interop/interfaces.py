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
    form = "increments"                # optional: one of the role's alternative input forms

*Forms*: vendors deliver the same sensor in different shapes (an IMU that takes true
increments, or true rates and specific force). Variables with a ``form`` belong to one
alternative; the role is filled when every required variable without a form and every
required variable of *one* form is filled (:attr:`RoleMatch.form` says which). The
variables of the other forms are then optional. The scenario wires the chosen form's
inputs (``ins-cosim check-fmu --scenario`` prints the connection lines).

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

:mod:`cosim.interop.fmu_check` adds what an FMU's model description and binary say
(``ins-cosim check-fmu``).
"""

from __future__ import annotations

import difflib
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.errors import UnitError, UserError
from cosim.package_data import role_dir
from cosim.units import conversion_factor
from cosim.variables import Variable, apply_rename

#: Folder of the role specs shipped with ins-cosim.
ROLE_DIR = role_dir()

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
    "form",
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
    form : str
        The alternative input form the variable belongs to (empty: every form).
    """

    name: str
    causality: str
    unit: str
    size: int = 1
    required: bool = True
    type: str = "Real"
    description: str = ""
    aliases: tuple[str, ...] = ()
    form: str = ""

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

    @property
    def forms(self) -> list[str]:
        """The alternative input forms, in file order (empty: the role has one shape)."""
        return list(dict.fromkeys(v.form for v in self.variables if v.form))


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
        form = v.get("form", "")
        if not isinstance(form, str) or (form and not re.fullmatch(r"[A-Za-z_]\w*", form)):
            raise bad(f"{key}.form", "a form name such as 'rates'", form)
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
                form=form,
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
    def form(self) -> str:
        """The input form the block fills (empty when the role has no forms).

        The first form (in spec order) whose required scalars are all filled without
        problems; when none is, the form with the most of them filled (ties: the first).
        """
        forms = self.role.forms
        if not forms:
            return ""

        def filled(form: str) -> tuple[bool, int]:
            mine = [e for e in self.entries if e.variable.form == form and e.variable.required]
            return all(e.ok for e in mine), sum(e.ok for e in mine)

        return max(forms, key=lambda f: (filled(f), -forms.index(f)))

    def required(self, entry: Entry) -> bool:
        """Whether an entry must be filled: a required variable of no form or of :attr:`form`.

        Parameters
        ----------
        entry : Entry
            One of :attr:`entries`.

        Returns
        -------
        bool
        """
        v = entry.variable
        return v.required and (not v.form or v.form == self.form)

    @property
    def problems(self) -> list[str]:
        """Problems of required scalars (missing, wrong causality, type or unit)."""
        return [msg for e in self.entries if self.required(e) for msg in _messages(e, True)]

    @property
    def warnings(self) -> list[str]:
        """Problems of optional scalars that are present (they would matter if used)."""
        return [
            msg
            for e in self.entries
            if not self.required(e) and e.fmu is not None
            for msg in _messages(e, False)
        ]

    @property
    def satisfied(self) -> bool:
        """True when every required scalar is filled without problems."""
        return not self.problems

    @property
    def needs_rename(self) -> bool:
        """True when filling the role needs names changed."""
        return bool(self.rename)


def _messages(e: Entry, required: bool) -> list[str]:
    if e.fmu is None:
        kind = "required" if required else "optional"
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
        The block's variables (``BlockHost.variables`` or :func:`cosim.variables.fmu_variables`).
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


def name_score(rv: RoleVariable, base: str) -> float:
    """Word overlap (Jaccard) of a name with the role variable's name or an alias.

    Words are split at ``_``, digits and camelCase; frame suffixes (``b``, ``n``, ...) are
    dropped; a prefix of 3 letters or more matches the longer word (``vel``, ``velocity``).

    Parameters
    ----------
    rv : RoleVariable
        The role variable.
    base : str
        A variable's name without its axis suffix (``AngRate``, ``omega_is_s``).

    Returns
    -------
    float
        In [0, 1]; 0 when no word is shared.
    """
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
    name = name_score(rv, base)
    complete = causality == 1.0 and unit == 1.0 and vtype == 1.0
    # a candidate needs a word in common with the role's names; required variables may
    # take a group with problems (to report them), optional ones only a fitting group
    # (so that, e.g., vendor bias parameters are not proposed as truth outputs)
    # (a variable of an input form is an alternative: it takes a group with problems only
    # when most of the group has its causality)
    loose = rv.required and name >= 0.5 and (not rv.form or causality >= 0.5)
    if not ((complete and name > 0.0) or loose):
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
                rank = 0 if rv.required and not rv.form else 1 if rv.required else 2
                scored.append((rank, -s, -tie, rv.name, key))
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


# ------------------------------------------------------------- scenario checks
def block_role(kind: str, source: str, role: str = "") -> str:
    """The role a scenario block fills: its ``role`` key, else the role listing its model.

    Parameters
    ----------
    kind : str
        ``"model"``, ``"fmu"`` or ``"class"`` (:class:`cosim.scenario.BlockSpec`).
    source : str
        The model name, FMU path or class.
    role : str
        The block's ``role`` key (empty when not stated).

    Returns
    -------
    str
        A role name, or empty when the block fills no known role.
    """
    if role:
        return role
    if kind != "model":
        return ""
    return next((r for r in available_roles() if source in load_role(r).models), "")


def check_role_inputs(scenario: Any, system: Any, unconnected: Mapping[str, Any]) -> None:
    """Refuse a required input of a block's role that is left on its start value.

    An unconnected input of a role the block fills is almost always a forgotten
    connection (an IMU with no true increments measures a body at rest): ``check`` and
    ``run`` stop with the block, the inputs and how to find the connection lines, unless
    the block states them in ``unconnected_ok``.

    Parameters
    ----------
    scenario : cosim.scenario.Scenario
        The loaded scenario (block specs, file).
    system : cosim.master.System
        Its built system (hosts with their variables, after rename maps).
    unconnected : mapping
        Block -> {input: start value} of the inputs left on their start values (the
        ``unconnected`` entry of the build metadata).

    Raises
    ------
    ScenarioError
        For the first block with such inputs, keyed ``blocks.<name>``.
    InterfaceError
        A ``role`` key that names no role spec.
    """
    for name, spec in scenario.blocks.items():
        left = unconnected.get(name) or {}
        if not left:  # the role specs are read only for blocks with inputs left unset
            continue
        role = block_role(spec.kind, spec.source, spec.role)
        if not role:
            continue
        match = match_role(system.blocks[name].variables, load_role(role), suggest=False)
        stated = set(spec.unconnected_ok)
        missing = [
            e.role_name
            for e in match.entries
            if match.required(e)
            and e.variable.causality == "input"
            and e.role_name in left
            and e.role_name not in stated
            and e.variable.name not in stated
        ]
        if missing:
            where = spec.source if spec.kind == "fmu" else "FMU"
            raise scenario.error(
                f"block '{name}' fills role '{role}', but its required input(s) "
                f"{', '.join(missing)} are not connected (they would run on their start "
                f"values); connect them: `ins-cosim check-fmu {where} --role {role} "
                f"--scenario {scenario.path} --block {name}` prints the connection lines",
                key=f"blocks.{name}",
            )
