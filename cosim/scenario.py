"""Building a parsed scenario: blocks instantiated, parameters set, the master made.

:func:`load_scenario` reads a scenario file (:func:`cosim.scenario_parse.parse_scenario`:
the format and its checks live there) into a :class:`Scenario`, the parsed description
with :meth:`Scenario.build`: every block instantiated (in-process or as an FMU),
parameters converted to the variables' units and types, connections and outputs
resolved. :func:`build_master` is the one place a :class:`~cosim.master.Master` is made
from a scenario. Problems found while building (an unknown variable, a value of the
wrong type) are :class:`~cosim.errors.ScenarioError` naming the file and key.

The parsing side's names (:class:`BlockSpec`, :func:`parse_seconds`, ...) are importable
from here too.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import math
import sys
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from typing import Any

from cosim import provenance, registry
from cosim.arrays import nested_values
from cosim.blocks import BlockHost, FmuHost, InProcessHost
from cosim.errors import FmuError, ScenarioError, UnitError, did_you_mean, shorten
from cosim.master import Master, System
from cosim.models.block import Block
from cosim.scenario_parse import (
    BlockSpec,
    ScenarioSpec,
    parse_scenario,
    parse_seconds,
)
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

__all__ = [
    "BlockSpec",
    "Scenario",
    "ScenarioSpec",
    "build_master",
    "collector_paused",
    "load_scenario",
    "parse_seconds",
]

#: The causalities a scenario's ``parameters`` table may set.
SETTABLE = ("parameter", "input")
#: Value range of every integer type (FMI 2 Integer, FMI 3 Int8..UInt64, Enumeration).
INTEGER_RANGES = {
    "Integer": (-(2**31), 2**31 - 1),
    "Enumeration": (-(2**63), 2**63 - 1),
    **{f"Int{n}": (-(2 ** (n - 1)), 2 ** (n - 1) - 1) for n in (8, 16, 32, 64)},
    **{f"UInt{n}": (0, 2**n - 1) for n in (8, 16, 32, 64)},
}


class Scenario(ScenarioSpec):
    """A parsed scenario file that builds: :meth:`build` instantiates its blocks.

    The attributes are those of :class:`~cosim.scenario_parse.ScenarioSpec` (file, hash,
    name, settings, blocks, connections, outputs, the raw document).
    """

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
            if not scalars or scalars[0].causality not in SETTABLE:
                raise self.error(self._not_settable(spec.name, pname, scalars, host), key=key)
            var0 = scalars[0]
            raw = nested_values(raw, scalars, partial(self.error, key=key))
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

    @staticmethod
    def _not_settable(block: str, name: str, scalars: list[Variable], host: BlockHost) -> str:
        """Why ``block.name`` cannot be set, with the names that can (made on error only)."""
        settable = base_names([v.name for v in host.variables.values() if v.causality in SETTABLE])
        tip = did_you_mean(name, settable)
        if not scalars:
            return f"block '{block}' has no variable '{name}'.{tip} " + (
                f"Parameters and inputs: {', '.join(settable)}"
            )
        return (
            f"'{block}.{name}' is an {scalars[0].causality}; only parameters and inputs can "
            f"be set.{tip}"
        )

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


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario file (blocks are not instantiated yet).

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file.

    Returns
    -------
    Scenario
        The description of :func:`cosim.scenario_parse.parse_scenario`, able to build.

    Raises
    ------
    ScenarioError
        Missing file, malformed TOML, unknown or missing keys, bad values.
    """
    spec = parse_scenario(path)
    return Scenario(**{f: getattr(spec, f) for f in spec.__dataclass_fields__})


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
