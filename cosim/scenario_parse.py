"""Scenario files (TOML) read into a checked description; building it is :mod:`cosim.scenario`.

Format (docs/scenario_files.md is the user's reference)::

    [scenario]
    name = "demo"

    [master]
    step = "10 ms"              # numbers are SI; strings carry a unit
    stop = "60 s"
    start = 0.0                 # optional
    coupling = "gauss-seidel"   # or "jacobi"

    [blocks.flexure]
    model = "GaussMarkov2"      # a registered name (cosim.registry: models/, filters) ... or
    # fmu = "../fmus/build/GaussMarkov2.fmu"   (relative to this file) ... or
    # class = "package.module:ClassName"
    rate = 1                    # steps every k-th macro step
    parameters = { tau = "300 s", sigma = "2 arcmin", seed = 1 }
    # rename = { "vendor_name" = "our_name[1]" }   # expose FMU variables under our names
    # role = "imu"                 # the role it fills (fmus/interfaces/): `check` then
    #                              # refuses a required role input left unconnected
    # unconnected_ok = ["angle"]   # inputs meant to stay on their start values (no warning)

    connections = ["flexure.x -> sensor.u"]   # vectors expand: a.v -> b.w wires [1]..[n]

    [output]
    variables = ["flexure", "sensor.m"]        # blocks or variables; default every output
    every = 1                                  # record every k-th macro step

Parsing (:func:`parse_scenario`) checks everything that can be checked without a block:
keys, kinds, times, sizes; every problem is a :class:`~cosim.errors.ScenarioError`
naming the file and key and saying how to fix it. The result, a :class:`ScenarioSpec`,
knows nothing about hosts or the master; :func:`cosim.scenario.load_scenario` wraps it into
a :class:`cosim.scenario.Scenario`, which also builds.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim import limits, parses, registry
from cosim.errors import ScenarioError, UnitError, did_you_mean, shorten
from cosim.master import GAUSS_SEIDEL, MasterSettings
from cosim.units import to_unit

TOP_KEYS = {"scenario", "master", "blocks", "connections", "output", "requirements", "campaign"}
BLOCK_KEYS = {
    "model",
    "fmu",
    "class",
    "rate",
    "parameters",
    "description",
    "rename",
    "role",
    "unconnected_ok",
}
SCENARIO_KEYS = {"name", "description"}
MASTER_KEYS = {"step", "stop", "start", "coupling", "clock"}
SETTING_KEYS = {"step", "stop", "start", "coupling", "record_every", "clock"}
OUTPUT_KEYS = {"variables", "every"}
_NAME = re.compile(r"^[A-Za-z_]\w*$")
_DUPLICATE = re.compile(r"Cannot (?:declare|overwrite) \('blocks', '(\w+)'\) twice \(at (line \d+)")


@dataclass
class BlockSpec:
    """One ``[blocks.<name>]`` table.

    Attributes
    ----------
    name : str
        Block name.
    kind : str
        ``"model"``, ``"fmu"`` or ``"class"``.
    source : str
        Model class name, FMU path (absolute) or ``module:Class``.
    rate : int
        Steps every ``rate``-th macro step.
    parameters : dict
        Raw values as written (units not yet applied).
    rename : dict
        The block's own variable name -> the name the scenario uses (``rename`` table).
    role : str
        The role the block fills (``role`` key; empty when not stated).
    unconnected_ok : list of str
        Inputs (scalar or vector base names) meant to run on their start values.
    """

    name: str
    kind: str
    source: str
    rate: int = 1
    parameters: dict[str, Any] = field(default_factory=dict)
    rename: dict[str, str] = field(default_factory=dict)
    role: str = ""
    unconnected_ok: list[str] = field(default_factory=list)


@dataclass
class ScenarioSpec:
    """A parsed scenario file: what to build, not built (:class:`cosim.scenario.Scenario` builds).

    Attributes
    ----------
    path : Path
        The file.
    sha256 : str
        Hash of the file's bytes.
    name : str
        ``scenario.name`` (default: the file stem).
    settings : MasterSettings
        Step, stop, start, coupling, record interval (SI).
    blocks : dict
        Block name -> :class:`BlockSpec`, in file order.
    connections : list of str
        Connection strings as written.
    outputs : list of str or None
        ``output.variables`` (None: every output).
    raw : dict
        The whole TOML document (requirements and campaign tables are read elsewhere).
    """

    path: Path
    sha256: str
    name: str
    settings: MasterSettings
    blocks: dict[str, BlockSpec]
    connections: list[str]
    outputs: list[str] | None
    raw: dict[str, Any]

    def error(self, message: str, key: str | None = None) -> ScenarioError:
        """A :class:`ScenarioError` located in this file.

        Parameters
        ----------
        message : str
            What is wrong and how to fix it.
        key : str, optional
            The TOML key (dotted path) where the problem is.

        Returns
        -------
        ScenarioError
            To be raised by the caller.
        """
        return ScenarioError(message, file=str(self.path), key=key)

    def master_settings(self, **overrides: Any) -> MasterSettings:
        """The scenario's master settings with some of them replaced.

        Parameters
        ----------
        **overrides
            ``step``, ``stop``, ``start`` (seconds, or strings with a time unit),
            ``coupling``, ``record_every``; a value of None keeps the scenario's.

        Returns
        -------
        MasterSettings
            A new, checked object; :attr:`settings` is not changed.

        Raises
        ------
        ScenarioError
            An override that makes the settings inconsistent (e.g. a stop time that is not
            a whole number of steps).
        TypeError
            An unknown override name (a programming error, not a user's).
        """
        changes: dict[str, Any] = {}
        for key, value in overrides.items():
            if key not in SETTING_KEYS:
                raise TypeError(f"unknown master setting '{key}' (known: {sorted(SETTING_KEYS)})")
            if value is None:
                continue
            if key in ("step", "stop", "start"):
                value = parse_seconds(value, str(self.path), f"master.{key}")
            changes[key] = value
        if not changes:
            return self.settings
        try:
            return dataclasses.replace(self.settings, **changes)
        except ScenarioError as exc:
            raise self.error(exc.message, key=exc.key) from None

    def use_fmus(self, fmu_dir: str | Path) -> None:
        """Run every truth model from ``<fmu_dir>/<Model>.fmu`` instead of in-process.

        Truth models are the classes of ``models/`` (:func:`cosim.registry.truth_models`,
        what ``make fmus`` packs); alignment filters and other blocks found through entry
        points have no FMU and stay in-process.

        Parameters
        ----------
        fmu_dir : str or Path
            Folder of FMUs built by ``make fmus`` (normally ``fmus/build``).
        """
        for spec in self.blocks.values():
            if spec.kind == "model" and registry.is_truth_model(spec.source):
                spec.kind = "fmu"
                spec.source = str((Path(fmu_dir) / f"{spec.source}.fmu").resolve())


def _check_keys(table: dict[str, Any], allowed: set[str], where: str, file: str) -> None:
    for k in table:
        if k not in allowed:
            tip = did_you_mean(k, allowed)
            if k in TOP_KEYS and where != "the top level":
                tip = (
                    f" '{k}' is a top-level key: write it before the first [table] header "
                    f"(TOML puts a key under the table header above it)."
                )
            raise ScenarioError(
                f"unknown key '{k}'.{tip} Allowed in {where}: {', '.join(sorted(allowed))}",
                file=file,
                key=f"{where}.{k}" if where != "the top level" else k,
            )


def parse_seconds(value: Any, file: str, key: str) -> float:
    """A time from a scenario value or a command-line option, in seconds.

    Parameters
    ----------
    value : float, int or str
        Seconds, or a string with a time unit (``"10 ms"``, ``"2 min"``).
    file : str
        Where the value comes from (for the message).
    key : str
        The key or option that holds it (for the message).

    Returns
    -------
    float
        The time [s].

    Raises
    ------
    ScenarioError
        Not a time.
    """
    try:
        v = to_unit(value, "s")
    except UnitError as exc:
        raise ScenarioError(str(exc), file=file, key=key) from exc
    if isinstance(v, (list, bool)):
        raise ScenarioError(
            f"expected a time such as '10 ms', got {shorten(value)}", file=file, key=key
        )
    if not math.isfinite(v):
        raise ScenarioError(
            f"expected a finite time such as '60 s', got {shorten(value)}",
            file=file,
            key=key,
        )
    return float(v)


def parse_scenario(path: str | Path) -> ScenarioSpec:
    """Read and check a scenario file (no block is instantiated).

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file.

    Returns
    -------
    ScenarioSpec

    Raises
    ------
    ScenarioError
        Missing file, malformed TOML, unknown or missing keys, bad values.
    """
    path = Path(path)
    f = parses.note(path)  # the file's name; the parse is counted
    if not path.is_file():
        raise ScenarioError("file not found; give the path of a scenario .toml file", file=f)
    size = path.stat().st_size
    if size > limits.MAX_FILE_BYTES:
        raise ScenarioError(
            f"the file is {size} bytes, more than the limit of {limits.MAX_FILE_BYTES} bytes for a "
            f"scenario",
            file=f,
        )
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
        depth, line = limits.nesting_depth(text)
        if depth > limits.MAX_DEPTH:
            raise ScenarioError(
                f"arrays and inline tables nest {depth} levels deep (from line {line}), more "
                f"than the limit of {limits.MAX_DEPTH}",
                file=f,
            )
        doc = tomllib.loads(text)
    except RecursionError:  # pragma: no cover - nesting_depth refuses such files first
        raise ScenarioError(
            f"nested too deep to parse (the limit is {limits.MAX_DEPTH} levels)", file=f
        ) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        dup = _DUPLICATE.search(str(exc))
        if dup:
            raise ScenarioError(
                f"block '{dup.group(1)}' is defined twice ({dup.group(2)}); block names must "
                f"be unique: rename one of them",
                file=f,
                key=f"blocks.{dup.group(1)}",
            ) from exc
        raise ScenarioError(f"not valid TOML: {exc}", file=f) from exc
    limits.check_document(doc, f)
    _check_keys(doc, TOP_KEYS, "the top level", f)
    head = doc.get("scenario", {})
    if not isinstance(head, dict):
        raise ScenarioError(
            f"expected a table such as [scenario] name = 'demo', got {shorten(head)}",
            file=f,
            key="scenario",
        )
    _check_keys(head, SCENARIO_KEYS, "scenario", f)
    master = doc.get("master")
    if not isinstance(master, dict):
        raise ScenarioError(
            "missing [master] table; add e.g. [master] step = '10 ms', stop = '60 s'",
            file=f,
            key="master",
        )
    _check_keys(master, MASTER_KEYS, "master", f)
    for req in ("step", "stop"):
        if req not in master:
            raise ScenarioError(
                f"missing master.{req} (a time, e.g. '10 ms')", file=f, key=f"master.{req}"
            )
    output = doc.get("output", {})
    _check_keys(output, OUTPUT_KEYS, "output", f)
    try:
        settings = MasterSettings(
            step=parse_seconds(master["step"], f, "master.step"),
            stop=parse_seconds(master["stop"], f, "master.stop"),
            start=parse_seconds(master.get("start", 0.0), f, "master.start"),
            coupling=master.get("coupling", GAUSS_SEIDEL),
            record_every=output.get("every", 1),
            clock=master.get("clock", MasterSettings.clock),
        )
    except ScenarioError as exc:
        raise ScenarioError(exc.message, file=f, key=exc.key) from None
    blocks_raw = doc.get("blocks")
    if not isinstance(blocks_raw, dict) or not blocks_raw:
        raise ScenarioError(
            "no blocks; add at least one [blocks.<name>] table with model = '...' or fmu = '...'",
            file=f,
            key="blocks",
        )
    if len(blocks_raw) > limits.MAX_BLOCKS:
        raise ScenarioError(
            f"{len(blocks_raw)} blocks, more than the limit of {limits.MAX_BLOCKS}",
            file=f,
            key="blocks",
        )
    blocks: dict[str, BlockSpec] = {}
    for name, table in blocks_raw.items():
        key = f"blocks.{name}"
        if not _NAME.match(name):
            raise ScenarioError(
                f"block name '{name}' must be a Python-style identifier", file=f, key=key
            )
        if not isinstance(table, dict):
            raise ScenarioError(f"expected a table, got {table!r}", file=f, key=key)
        _check_keys(table, BLOCK_KEYS, key, f)
        kinds = [k for k in ("model", "fmu", "class") if k in table]
        if len(kinds) != 1:
            raise ScenarioError(
                "give exactly one of model = 'Name', fmu = 'path.fmu' or class = 'module:Class'",
                file=f,
                key=key,
            )
        kind = kinds[0]
        source = str(table[kind])
        if kind == "fmu":
            source = str((path.parent / source).resolve())
        rate = table.get("rate", 1)
        if isinstance(rate, bool) or not isinstance(rate, int) or rate < 1:
            raise ScenarioError(
                f"expected a positive integer, got {rate!r}", file=f, key=f"{key}.rate"
            )
        params = table.get("parameters", {})
        if not isinstance(params, dict):
            raise ScenarioError(
                f"expected a table, got {params!r}", file=f, key=f"{key}.parameters"
            )
        rename = table.get("rename", {})
        if not isinstance(rename, dict) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in rename.items()
        ):
            raise ScenarioError(
                f"expected a table of strings such as {{ gyro_x = 'dtheta_meas_b[1]' }} "
                f"(FMU name = scenario name), got {rename!r}",
                file=f,
                key=f"{key}.rename",
            )
        role = table.get("role", "")
        if not isinstance(role, str):
            raise ScenarioError(
                f"expected a role name such as 'imu', got {role!r}", file=f, key=f"{key}.role"
            )
        unconnected_ok = table.get("unconnected_ok", [])
        if not isinstance(unconnected_ok, list) or not all(
            isinstance(n, str) for n in unconnected_ok
        ):
            raise ScenarioError(
                f"expected a list of input names such as ['angle'], got {unconnected_ok!r}",
                file=f,
                key=f"{key}.unconnected_ok",
            )
        blocks[name] = BlockSpec(
            name, kind, source, rate, dict(params), dict(rename), role, list(unconnected_ok)
        )
    connections = doc.get("connections", [])
    if not isinstance(connections, list):
        raise ScenarioError(
            "expected a list of strings like 'a.x -> b.u'", file=f, key="connections"
        )
    if len(connections) > limits.MAX_CONNECTIONS:
        raise ScenarioError(
            f"{len(connections)} connections, more than the limit of {limits.MAX_CONNECTIONS}",
            file=f,
            key="connections",
        )
    outputs = output.get("variables")
    if outputs is not None and not isinstance(outputs, list):
        raise ScenarioError(
            "expected a list of 'block' or 'block.variable'", file=f, key="output.variables"
        )
    return ScenarioSpec(
        path=path,
        sha256=hashlib.sha256(data).hexdigest(),
        name=str(head.get("name", path.stem)),
        settings=settings,
        blocks=blocks,
        connections=connections,
        outputs=outputs,
        raw=doc,
    )
