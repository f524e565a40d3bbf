"""The ``[campaign]`` and ``[[requirements]]`` tables checked against a built system.

One check for the two commands that read them: ``ins-cosim verify`` (through
:func:`cosim.verify.campaign.prepare`, before the first run) and ``ins-cosim check`` (which
therefore catches whatever ``verify`` would refuse: a requirement on a signal that is not
recorded, a window after the stop time, a ``randomize`` block without a seed parameter, a
``stratify`` parameter without its sigma).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cosim.errors import ScenarioError
from cosim.recording import recorded_columns
from cosim.scenario import Scenario
from cosim.verify.consistency import load_all
from cosim.verify.estimates import check_truth
from cosim.verify.requirements import Requirement
from cosim.verify.seeds import Stratified
from cosim.verify.windows import check_windows


@dataclass(frozen=True)
class CheckedTables:
    """What the tables resolve to on the built system.

    Attributes
    ----------
    requirements : list of Requirement
        The ``[[requirements]]``, checked (empty when not read).
    seeded : list of str
        Blocks with an Integer ``seed`` parameter, in the system's order.
    declared : dict
        Block -> names of its parameters (what a campaign job may set).
    stratified : tuple of Stratified
        The resolved ``[campaign] stratify`` parameters.
    parameters : dict
        The scenario's parameters after the build, ``{block: {name: SI value}}``.
    """

    requirements: list[Requirement]
    seeded: list[str]
    declared: dict[str, set[str]]
    stratified: tuple[Stratified, ...]
    parameters: dict[str, dict[str, Any]]


def check_tables(
    sc: Scenario,
    settings: Any,
    master: Any,
    *,
    requirements: bool = True,
    required: bool = True,
) -> CheckedTables:
    """Check the campaign and requirement tables of ``sc`` against its built ``master``.

    Parameters
    ----------
    sc : Scenario
        The loaded scenario (for its file name and raw tables).
    settings : CampaignSettings
        Its parsed ``[campaign]`` table (:func:`cosim.verify.campaign.parse_campaign`).
    master : Master
        The system built from it (not stepped; the caller terminates it).
    requirements : bool
        Read and check ``[[requirements]]``.
    required : bool
        Refuse a scenario without requirements (``verify``); ``check`` accepts one.

    Returns
    -------
    CheckedTables

    Raises
    ------
    ScenarioError
        Naming the file and key: an unknown signal or unit, a window outside the run, a
        ``randomize`` block without a seed, a ``stratify`` item without its sigma.
    """
    system = master.system
    file = str(sc.path)
    seeded = [
        b
        for b, h in system.blocks.items()
        if "seed" in h.variables
        and h.variables["seed"].causality == "parameter"
        and h.variables["seed"].type == "Integer"
    ]
    declared = {
        b: {v.name for v in h.variables.values() if v.causality == "parameter"}
        for b, h in system.blocks.items()
    }
    stratified = _stratified(sc, settings, system)
    for i, b in enumerate(settings.randomize or ()):
        if b not in seeded:
            raise ScenarioError(
                f"block '{b}' has no seed parameter to randomize; blocks with one: "
                f"{', '.join(seeded) or 'none'} (a vendor FMU's own seed parameter is "
                "renamed to 'seed' in the block's rename map)",
                file=file,
                key=f"campaign.randomize[{i}]",
            )
    reqs: list[Requirement] = []
    tables = sc.raw.get("requirements", []) if requirements else []
    if requirements and not tables and required:
        raise ScenarioError(
            "no requirements: add [[requirements]] tables (id, signal, criterion, bound, ...)",
            file=file,
            key="requirements",
        )
    if tables:
        outputs = [
            f"{b}.{v.name}"
            for b, h in system.blocks.items()
            for v in h.by_causality("output")
            if v.type == "Real"
        ]
        # the unit conversions use (an FMU's own unit definition when it has one)
        units: dict[str, Any] = {"time": "s"}
        for b, v in recorded_columns(system):
            var = system.blocks[b].variables[v]
            units[f"{b}.{v}"] = getattr(var, "conversion_unit", var.unit)
        descriptions = {
            f"{b}.{v}": system.blocks[b].variables[v].description
            for b, v in recorded_columns(system)
        }
        reqs = load_all(tables, units, file, outputs, descriptions, settings.on_failure)
        check_windows(reqs, master.settings.start, master.settings.stop, file)
        check_truth(reqs, system, master.metadata.get("unconnected", {}), file)
    parameters = {b: dict(p) for b, p in system.parameters.items()}
    return CheckedTables(reqs, seeded, declared, stratified, parameters)


def _stratified(sc: Scenario, settings: Any, system: Any) -> tuple[Stratified, ...]:
    """Resolve ``[campaign] stratify`` against the built blocks."""
    out = []
    for i, item in enumerate(settings.stratify):
        block, name = item.split(".")
        host = system.blocks.get(block)
        params = (
            set()
            if host is None
            else {v.name for v in host.variables.values() if v.causality == "parameter"}
        )
        size = sum(1 for n in params if n.startswith(f"{name}[") and n.endswith("]"))
        sigma = f"{name}_sigma"
        if host is None or not (name in params or size) or sigma not in params:
            raise sc.error(
                f"'{item}': expected a parameter of a block with a sibling '{sigma}' (the "
                f"sigma the block would draw it with)",
                key=f"campaign.stratify[{i}]",
            )
        out.append(Stratified(block, name, size or 1, vector=bool(size)))
    return tuple(out)
