"""Scenario files (TOML): blocks, parameters with units, connections, master, output.

Format (README, "Scenario files", is the user's reference)::

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

Loading checks everything that can be checked without running: every problem is a
:class:`~cosim.errors.ScenarioError` naming the file and key and saying how to fix it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import hashlib
import importlib
import math
import re
import sys
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim import limits, parses, provenance, registry
from cosim.blocks import BlockHost, FmuHost, InProcessHost
from cosim.errors import FmuError, ScenarioError, UnitError, did_you_mean, shorten
from cosim.master import GAUSS_SEIDEL, Master, MasterSettings, System
from cosim.models.block import Block
from cosim.units import to_unit
from cosim.variables import REAL, Variable
from cosim.wiring import (
    base_names,
    check_inputs,
    expand,
    fmu_name_note,
    recorded_outputs,
    resolve_connections,
)

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
#: Value range of every integer type (FMI 2 Integer, FMI 3 Int8..UInt64, Enumeration).
INTEGER_RANGES = {
    "Integer": (-(2**31), 2**31 - 1),
    "Enumeration": (-(2**63), 2**63 - 1),
    **{f"Int{n}": (-(2 ** (n - 1)), 2 ** (n - 1) - 1) for n in (8, 16, 32, 64)},
    **{f"UInt{n}": (0, 2**n - 1) for n in (8, 16, 32, 64)},
}
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
class Scenario:
    """A parsed scenario file (not yet instantiated: see :meth:`build`).

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

    def build(self) -> tuple[System, dict[str, Any]]:
        """Instantiate every block and resolve parameters, connections and outputs.

        Returns
        -------
        system : System
            Ready for :class:`cosim.master.Master`.
        metadata : dict
            Scenario file, hash, blocks' provenance, seeds, units of the columns.

        Raises
        ------
        ScenarioError, FmuError
            With the file and key of the problem.
        """
        hosts: dict[str, BlockHost] = {}
        try:
            with collector_paused():
                for spec in self.blocks.values():
                    hosts[spec.name] = self._host(spec)
            parameters = {
                name: self._parameters(spec, hosts[name]) for name, spec in self.blocks.items()
            }
            connections = resolve_connections(self, hosts)
            unconnected = check_inputs(self, hosts, parameters, connections)
            record = recorded_outputs(self, hosts)
        except Exception:
            for host in hosts.values():
                try:
                    host.terminate()
                except Exception:  # cleanup of a half-built system must not mask the error
                    pass
            raise
        system = System(
            blocks=hosts,
            connections=connections,
            parameters=parameters,
            rates={n: s.rate for n, s in self.blocks.items()},
            record=record,
        )
        metadata = self._metadata(hosts, parameters, system)
        # inputs that run on their start values (connected to nothing, set by nothing)
        metadata["unconnected"] = unconnected
        return system, metadata

    # ----------------------------------------------------------------- blocks
    def _host(self, spec: BlockSpec) -> BlockHost:
        host = self._new_host(spec)
        if spec.rename:
            try:
                host.rename(spec.rename)
            except FmuError as exc:
                host.terminate()
                raise self.error(str(exc), key=f"blocks.{spec.name}.rename") from exc
        return host

    def _new_host(self, spec: BlockSpec) -> BlockHost:
        key = f"blocks.{spec.name}"
        if spec.kind == "fmu":
            try:
                return FmuHost(spec.name, Path(spec.source))
            except FmuError as exc:
                raise self.error(str(exc), key=f"{key}.fmu") from exc
        if spec.kind == "model":
            try:
                cls = registry.find_block(spec.source)
            except ScenarioError as exc:
                raise self.error(exc.message, key=f"{key}.model") from exc
            return InProcessHost(spec.name, cls)
        return InProcessHost(spec.name, self._user_class(spec.source, f"{key}.class"))

    def _user_class(self, source: str, key: str) -> type:
        """The class of ``class = "module:Class"``: a Block subclass, found on ``sys.path``
        or in a module beside the scenario file."""
        module_name, colon, class_name = source.partition(":")
        if not colon or not module_name or not class_name:
            raise self.error(f"expected 'package.module:ClassName', got {shorten(source)}", key=key)
        folder = str(self.path.resolve().parent)
        added = folder not in sys.path
        if added:  # a module beside the scenario is importable (sys.path comes first)
            sys.path.append(folder)
        try:
            obj = getattr(importlib.import_module(module_name), class_name)
        except ModuleNotFoundError as exc:
            raise self.error(
                f"cannot import '{source}' ({exc}); write it as 'package.module:ClassName' "
                f"with the module importable: installed, on PYTHONPATH, or a file "
                f"{module_name.split('.')[0]}.py beside the scenario (in {folder})",
                key=key,
            ) from exc
        except (ImportError, AttributeError, ValueError) as exc:
            raise self.error(
                f"cannot import '{source}' ({type(exc).__name__}: {exc}); write it as "
                f"'package.module:ClassName'",
                key=key,
            ) from exc
        finally:
            if added and folder in sys.path:
                sys.path.remove(folder)
        if not (isinstance(obj, type) and issubclass(obj, Block)):
            what = type(obj).__name__ if not isinstance(obj, type) else f"class {obj.__name__}"
            raise self.error(
                f"'{source}' is a {what}, not a block; class = 'module:Class' must name a "
                f"subclass of cosim.models.block.Block",
                key=key,
            )
        return obj

    def _parameters(self, spec: BlockSpec, host: BlockHost) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for pname, raw in spec.parameters.items():
            key = f"blocks.{spec.name}.parameters.{pname}"
            scalars = expand(host, pname)
            kinds = ("parameter", "input")
            settable = base_names([v.name for v in host.variables.values() if v.causality in kinds])
            tip = did_you_mean(pname, settable)
            if not scalars:
                raise self.error(
                    f"block '{spec.name}' has no variable '{pname}'.{tip} "
                    f"Parameters and inputs: {', '.join(settable)}",
                    key=key,
                )
            var0 = scalars[0]
            if var0.causality not in kinds:
                raise self.error(
                    f"'{spec.name}.{pname}' is an {var0.causality}; only parameters and "
                    f"inputs can be set.{tip}",
                    key=key,
                )
            try:
                real = var0.type in (REAL, "Float32")
                value = to_unit(raw, var0.conversion_unit) if real else raw
            except UnitError as exc:
                raise self.error(
                    f"{exc.message} (variable '{spec.name}.{pname}'{fmu_name_note(var0)})", key=key
                ) from exc
            values = value if isinstance(value, list) else [value]
            if len(values) != len(scalars):
                raise self.error(
                    f"expected {len(scalars)} value(s) for '{spec.name}.{pname}', "
                    f"got {len(values)}",
                    key=key,
                )
            for var, v in zip(scalars, values, strict=True):
                out[var.name] = self._typed(v, var, key)
        return out

    def _typed(self, value: Any, var: Variable, key: str) -> Any:
        """The value as the variable's FMI type takes it, or one line saying why not."""
        t = var.type
        if t in (REAL, "Float32"):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise self.error(
                    f"expected a number for '{var.name}', got {shorten(value)}", key=key
                )
            if not math.isfinite(value):
                raise self.error(
                    f"parameter '{var.name}' is {value}; expected a finite number", key=key
                )
            return float(value)
        if t == "Enumeration" and var.items:
            return self._item(value, var, key)
        if t in INTEGER_RANGES:
            lo, hi = INTEGER_RANGES[t]
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                what = "the item's integer value" if t == "Enumeration" else "an integer"
                raise self.error(
                    f"expected {what} in [{lo}, {hi}] for '{var.name}' ({t}), got {value!r}",
                    key=key,
                )
            return value
        if t == "Boolean":
            if not isinstance(value, bool):
                raise self.error(f"expected true or false for '{var.name}', got {value!r}", key=key)
            return value
        if t == "String":
            if not isinstance(value, str):
                raise self.error(f"expected a string for '{var.name}', got {value!r}", key=key)
            return value
        if t == "Binary":
            try:
                return bytes.fromhex(value) if isinstance(value, str) else bytes(value)
            except (TypeError, ValueError):
                raise self.error(
                    f"expected hex digits such as '0a1bff' for '{var.name}' (Binary), got "
                    f"{value!r}",
                    key=key,
                ) from None
        raise self.error(
            f"'{var.name}' is a {t} variable; ins-cosim sets Real, Float32, the integer types, "
            f"Enumeration, Boolean, String and Binary variables, not {t}",
            key=key,
        )

    def _item(self, value: Any, var: Variable, key: str) -> int:
        """An Enumeration value given by item name (or by the item's value)."""
        values = {name: v for name, v in var.items}
        if isinstance(value, str) and value in values:
            return values[value]
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if isinstance(value, int) and not isinstance(value, bool) and value in values.values():
            return value
        allowed = ", ".join(f"'{name}' ({v})" for name, v in var.items)
        tip = did_you_mean(value, values) if isinstance(value, str) else ""
        raise self.error(
            f"{shorten(value)} is not an item of the Enumeration '{var.name}'.{tip} "
            f"Items: {allowed}",
            key=key,
        )

    def _metadata(
        self, hosts: dict[str, BlockHost], parameters: dict[str, dict[str, Any]], system: System
    ) -> dict[str, Any]:
        record = system.record or [
            (b, v.name)
            for b, h in hosts.items()
            for v in h.by_causality("output")
            if v.type != "Clock"
        ]
        units = {"time": "s"}
        units.update({f"{b}.{v}": hosts[b].variables[v].unit for b, v in record})
        return {
            "scenario": {"file": str(self.path), "name": self.name, "sha256": self.sha256},
            "blocks": {
                name: {
                    "kind": h.kind,
                    "source": h.source,
                    "guid": h.guid,
                    "sha256": h.sha256,
                    "fmi_version": h.fmi_version,
                    "rate": self.blocks[name].rate,
                    **({"rename": self.blocks[name].rename} if self.blocks[name].rename else {}),
                }
                for name, h in hosts.items()
            },
            "parameters": parameters,
            "seeds": {name: p["seed"] for name, p in parameters.items() if "seed" in p},
            "units": units,
            "descriptions": {f"{b}.{v}": hosts[b].variables[v].description for b, v in record},
            "software": provenance.versions(),
        }


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


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario file (blocks are not instantiated yet).

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file.

    Returns
    -------
    Scenario

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
    return Scenario(
        path=path,
        sha256=hashlib.sha256(data).hexdigest(),
        name=str(head.get("name", path.stem)),
        settings=settings,
        blocks=blocks,
        connections=connections,
        outputs=outputs,
        raw=doc,
    )


#: Objects tracked by the garbage collector made in one :func:`collector_paused` body at
#: and above which they go straight to its oldest generation (about 400 blocks).
PROMOTE_AFTER = 50_000


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """Build long-lived objects without Python's cyclic garbage collector walking them.

    Building a block makes many small objects that all live as long as the block does
    (its variables, their accessors, its buffers: about 120 per block). The collector's
    passes walk every object made so far, and the full ones come more often as the count
    grows: on a check of 10^4 blocks they took about a third of the time, and the time
    per block grew to 2.2-2.4 times that of 100 blocks. So the collector is paused for
    the ``with`` body, and what the body made then goes straight to the oldest
    generation (``gc.freeze`` then ``gc.unfreeze``: two list moves, no walk), where it
    would have ended up after two more walks. That move is made only for a large build
    (:data:`PROMOTE_AFTER` objects or more: a system of a few hundred blocks; a run's
    dozen blocks are left to the collector, so that the garbage of earlier runs in a loop
    is not moved with them) and only when nothing else in the process is frozen (it would
    thaw that too). Reference counting still frees whatever dies at once; a collector
    that the caller had turned off stays off.

    Yields
    ------
    None
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if gc.get_count()[0] >= PROMOTE_AFTER and gc.get_freeze_count() == 0:
            gc.freeze()
            gc.unfreeze()
        if enabled:
            gc.enable()


def build_master(
    scenario: Scenario | str | Path, *, fmu_dir: str | Path | None = None, **overrides: Any
) -> Master:
    """Instantiate a scenario's blocks and the master that steps them: the one place a
    :class:`~cosim.master.Master` is made from a scenario.

    Parameters
    ----------
    scenario : Scenario, str or Path
        A loaded scenario or the path of its TOML file.
    fmu_dir : str or Path, optional
        Run built-in models from ``<fmu_dir>/<Model>.fmu`` (see :meth:`Scenario.use_fmus`).
    **overrides
        Master settings to replace (:meth:`Scenario.master_settings`).

    Returns
    -------
    Master
        Ready to :meth:`~cosim.master.Master.run`; ``master.system`` holds the hosts and
        ``master.metadata`` the provenance. The caller terminates it.

    Raises
    ------
    ScenarioError, FmuError
        Before anything runs, with the file and key of the problem.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if fmu_dir is not None:
        scenario.use_fmus(fmu_dir)
    settings = scenario.master_settings(**overrides)
    system, metadata = scenario.build()
    try:
        return Master(system, settings, metadata)
    except BaseException as exc:
        for host in system.blocks.values():
            host.terminate()
        if isinstance(exc, ScenarioError) and exc.file is None:
            raise scenario.error(exc.message, key=exc.key) from None
        raise
