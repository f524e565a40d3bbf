"""How a scenario's blocks are wired: connections, unconnected inputs, recorded outputs.

Connections are resolved to scalar links with unit factors, inputs checked for a value,
and the outputs to record chosen.

Called by :meth:`cosim.scenario.Scenario.build` once the blocks are instantiated; every
problem is a :class:`~cosim.errors.ScenarioError` located in the scenario file.
"""

from __future__ import annotations

import re
import warnings
from typing import TYPE_CHECKING, Any

from cosim.blocks import BlockHost
from cosim.errors import UnitError, did_you_mean
from cosim.master import Connection
from cosim.typed_values import canonical_type, link_refusal, shape_refusal
from cosim.units import conversion_factor, resolve_unit
from cosim.variables import Variable

if TYPE_CHECKING:
    from cosim.scenario import Scenario

_LINK = re.compile(r"^\s*(\w+)\.([\w\[\],]+)\s*->\s*(\w+)\.([\w\[\],]+)\s*$")


class UnconnectedInputWarning(UserWarning):
    """An input is neither connected nor set: the block runs on its start value."""


def expand(host: BlockHost, name: str) -> list[Variable]:
    """The scalars a name stands for: itself, or the elements ``name[1]``, ``name[2]`` ...

    Parameters
    ----------
    host : BlockHost
        The block.
    name : str
        A scalar name or the base name of a vector.

    Returns
    -------
    list of Variable
        Empty when the block has no such variable.
    """
    if name in host.variables:
        return [host.variables[name]]
    elements = []
    i = 1
    while f"{name}[{i}]" in host.variables:
        elements.append(host.variables[f"{name}[{i}]"])
        i += 1
    if not elements:  # an FMI 3 array of two or more dimensions: A[1,1], A[1,2], ...
        elements = [
            v for v in host.variables.values() if v.element and v.name.split("[", 1)[0] == name
        ]
    return elements


def resolve_connections(scenario: Scenario, hosts: dict[str, BlockHost]) -> list[Connection]:
    """The scenario's connection strings as checked scalar links with their unit factors.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its ``connections`` and, for messages, its file).
    hosts : dict
        Block name -> host, instantiated.

    Returns
    -------
    list of Connection
        One per scalar link, vectors expanded.

    Raises
    ------
    ScenarioError
        A malformed link, unknown block or variable, wrong causality or type, a length or
        unit mismatch, or an input connected twice.
    """
    out: list[Connection] = []
    seen: dict[str, str] = {}
    for i, text in enumerate(scenario.connections):
        key = f"connections[{i}]"
        m = _LINK.match(text) if isinstance(text, str) else None
        if not m:
            raise scenario.error(f"expected 'block.output -> block.input', got {text!r}", key=key)
        sb, sv, db, dv = m.groups()
        src = _endpoint(scenario, hosts, sb, sv, "output", key, text)
        dst = _endpoint(scenario, hosts, db, dv, "input", key, text)
        mismatch = shape_refusal(src, dst)
        if mismatch:
            raise scenario.error(f"'{text}': '{sb}.{sv}' and '{db}.{dv}' {mismatch}", key=key)
        if len(src) != len(dst):
            raise scenario.error(
                f"'{text}': '{sb}.{sv}' has {len(src)} element(s) but '{db}.{dv}' has "
                f"{len(dst)}; connect elements explicitly, e.g. '{sb}.{sv}[1] -> {db}.{dv}'",
                key=key,
            )
        for a, b in zip(src, dst, strict=True):
            why = link_refusal(a, b)
            if why:
                raise scenario.error(
                    f"'{text}': '{sb}.{a.name}' is an output of type {canonical_type(a.type)} "
                    f"and '{db}.{b.name}' an input of type {canonical_type(b.type)}: {why}; "
                    f"ins-cosim links equal types and the widenings that keep every value "
                    f"exact (docs/coupling.md, Types and arrays): convert in a block, or "
                    f"give the input a constant value under parameters",
                    key=key,
                )
            try:
                factor = conversion_factor(a.conversion_unit, b.conversion_unit)
            except UnitError as exc:
                raise scenario.error(
                    f"'{text}': incompatible units: '{sb}.{a.name}'{fmu_name_note(a)} is in "
                    f"'{a.unit}' but '{db}.{b.name}'{fmu_name_note(b)} expects '{b.unit}' "
                    f"({_why(exc, a, b)})",
                    key=key,
                ) from exc
            sink = f"{db}.{b.name}"
            if sink in seen:
                raise scenario.error(
                    f"input '{sink}' is connected twice ({seen[sink]} and {text!r}); "
                    f"an input takes one source",
                    key=key,
                )
            seen[sink] = repr(text)
            out.append(Connection(sb, a.name, db, b.name, factor))
    return out


def _endpoint(
    scenario: Scenario,
    hosts: dict[str, BlockHost],
    block: str,
    var: str,
    causality: str,
    key: str,
    text: str,
) -> list[Variable]:
    if block not in hosts:
        tip = did_you_mean(block, hosts)
        raise scenario.error(
            f"'{text}': unknown block '{block}'.{tip} Blocks: {', '.join(hosts)}", key=key
        )
    host = hosts[block]
    scalars = expand(host, var)
    if not scalars:
        names = base_names([v.name for v in host.by_causality(causality)])
        tip = did_you_mean(var, names)
        raise scenario.error(
            f"'{text}': block '{block}' has no variable '{var}'.{tip} "
            f"Its {causality}s: {', '.join(names) or 'none'}",
            key=key,
        )
    for v in scalars:
        if v.causality != causality:
            side = "left" if causality == "output" else "right"
            raise scenario.error(
                f"'{text}': '{block}.{v.name}' is an {v.causality}, but the {side} side of "
                f"a connection must be an {causality}",
                key=key,
            )
    return scalars


def check_inputs(
    scenario: Scenario,
    hosts: dict[str, BlockHost],
    parameters: dict[str, dict[str, Any]],
    connections: list[Connection],
) -> dict[str, dict[str, Any]]:
    """Refuse inputs with no value; warn about those left on their start values.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its blocks' ``unconnected_ok`` and, for messages, its file).
    hosts : dict
        Block name -> host.
    parameters : dict
        Block name -> {scalar name: value} given in the scenario.
    connections : list of Connection
        The resolved links.

    Returns
    -------
    dict
        Block -> {input: start value} of every input left on its start value.

    Raises
    ------
    ScenarioError
        An input with neither a source, a value nor a start value; an input both connected
        and given a value; ``unconnected_ok`` naming something that is not an input.
    """
    wired = {(c.dst_block, c.dst_var): c for c in connections}
    unconnected: dict[str, dict[str, Any]] = {}
    for name, host in hosts.items():
        ok = set(scenario.blocks[name].unconnected_ok)
        left: list[Variable] = []
        for v in host.by_causality("input"):
            if (name, v.name) in wired and v.name in parameters[name]:
                raise scenario.error(
                    f"input '{name}.{v.name}' is connected ({wired[(name, v.name)]}) and "
                    f"also given a value under blocks.{name}.parameters, which the "
                    f"connection would override; remove one of them",
                    key=f"blocks.{name}.parameters.{v.name.split('[', 1)[0]}",
                )
            if (name, v.name) in wired or v.name in parameters[name]:
                continue
            if v.start is None:
                raise scenario.error(
                    f"input '{name}.{v.name}' is not connected and has no start value; "
                    f"connect it or give it a value under blocks.{name}.parameters",
                    key=f"blocks.{name}",
                )
            unconnected.setdefault(name, {})[v.name] = v.start
            if v.name not in ok and v.name.split("[", 1)[0] not in ok:
                left.append(v)
        if left:
            bases = base_names([v.name for v in left])
            values = ", ".join(f"{v.name} = {_plain(v.start)!r}" for v in left)
            warnings.warn(
                f"{scenario.path}: block '{name}': input(s) not connected, running on their "
                f"start values: {values}; connect them, or state it with "
                f"[blocks.{name}] unconnected_ok = {bases!r}",
                UnconnectedInputWarning,
                stacklevel=2,
            )
    for name, spec in scenario.blocks.items():
        unknown = [
            n
            for n in spec.unconnected_ok
            if not any(
                v.name == n or v.name.split("[", 1)[0] == n
                for v in hosts[name].by_causality("input")
            )
        ]
        if unknown:
            inputs = base_names([v.name for v in hosts[name].by_causality("input")])
            raise scenario.error(
                f"unconnected_ok names {', '.join(unknown)}, which are not inputs of block "
                f"'{name}'; its inputs: {', '.join(inputs) or 'none'}",
                key=f"blocks.{name}.unconnected_ok",
            )
    return unconnected


def recorded_outputs(
    scenario: Scenario, hosts: dict[str, BlockHost]
) -> list[tuple[str, str]] | None:
    """The (block, scalar output) pairs ``output.variables`` asks for.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its ``outputs``).
    hosts : dict
        Block name -> host.

    Returns
    -------
    list of (str, str) or None
        None when the scenario records every output.

    Raises
    ------
    ScenarioError
        An unknown block, or a name that is not a recordable output.
    """
    if scenario.outputs is None:
        return None
    out: list[tuple[str, str]] = []
    for i, item in enumerate(scenario.outputs):
        key = f"output.variables[{i}]"
        block, _, var = str(item).partition(".")
        if block not in hosts:
            raise scenario.error(
                f"unknown block '{block}' in {item!r}; blocks: {', '.join(hosts)}", key=key
            )
        host = hosts[block]
        if not var:
            out += [(block, v.name) for v in host.by_causality("output") if v.type != "Clock"]
            continue
        scalars = expand(host, var)
        if not scalars or any(v.causality != "output" or v.type == "Clock" for v in scalars):
            names = base_names([v.name for v in host.by_causality("output")])
            raise scenario.error(
                f"'{item}' is not an output of block '{block}' that can be recorded; "
                f"outputs: {', '.join(names)}",
                key=key,
            )
        out += [(block, v.name) for v in scalars]
    return out


def _why(exc: UnitError, a: Variable, b: Variable) -> str:
    """Why two units do not convert: their SI dimensions, or the parser's message."""
    try:
        ua, ub = resolve_unit(a.conversion_unit), resolve_unit(b.conversion_unit)
    except UnitError:
        return exc.message
    if ua.compatible(ub):
        return exc.message
    return f"dimensions {ua.si_text()} and {ub.si_text()}"


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python number it holds (for messages)."""
    return value.item() if hasattr(value, "item") else value


def fmu_name_note(var: Variable) -> str:
    """`` (FMU variable 'x')`` for a renamed variable, else nothing (for messages).

    Parameters
    ----------
    var : Variable
        A block's variable.

    Returns
    -------
    str
        The note, or an empty string.
    """
    return f" (FMU variable '{var.fmu_name}')" if var.fmu_name else ""


def base_names(names: list[str]) -> list[str]:
    """Base names of scalar names, in order: ``['x', 'v[1]', 'v[2]']`` -> ``['x', 'v']``.

    Parameters
    ----------
    names : list of str
        Scalar names.

    Returns
    -------
    list of str
        Each base name once.
    """
    seen: dict[str, None] = {}
    for n in names:
        seen.setdefault(n.split("[", 1)[0], None)
    return list(seen)
