"""A small Monte Carlo helper for the alignment scenarios (seed 003), through ``Master.reset``.

Seed mapping (documented contract, so a run can be replayed on its own)::

    children = numpy.random.SeedSequence(seed).spawn(runs)
    words    = children[i].generate_state(n_blocks, dtype=uint32)
    block j's seed in run i = int(words[j] >> 1)        (31 bits: a valid FMI Integer)

where the blocks ``j = 0 .. n_blocks - 1`` are those with an Integer parameter ``seed``,
in the scenario's declaration order. Every run therefore draws fresh, independent
streams for every stochastic block, and run ``i`` does not depend on ``runs``.

The blocks are instantiated once per worker; between runs the master resets them
(``Master.reset``) and only the seeds change. ``workers > 1`` splits the runs over
forked processes (each builds its own system once).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.master import Master
from cosim.scenario import Scenario, load_scenario


class CampaignError(ValueError):
    """A campaign was asked for something inconsistent (no runs, unknown column, ...)."""


@dataclass
class CampaignResult:
    """Recorded columns of every run.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Recorded times [s] (identical for every run).
    columns : dict
        ``"block.variable"`` -> ndarray, shape (runs, m), in the unit the block declares.
    seeds : list of dict
        Per run, ``{block: seed}``.
    units : dict
        ``"block.variable"`` -> unit.
    """

    time: np.ndarray
    columns: dict[str, np.ndarray]
    seeds: list[dict[str, int]]
    units: dict[str, str] = field(default_factory=dict)

    @property
    def runs(self) -> int:
        """Number of runs."""
        return len(self.seeds)

    def __getitem__(self, name: str) -> np.ndarray:
        """A scalar column ``(runs, m)``, or a vector ``"block.vec"`` as ``(runs, m, k)``."""
        if name in self.columns:
            return self.columns[name]
        parts = []
        i = 1
        while f"{name}[{i}]" in self.columns:
            parts.append(self.columns[f"{name}[{i}]"])
            i += 1
        if not parts:
            raise KeyError(f"no column '{name}' (recorded: {', '.join(sorted(self.columns))})")
        return np.stack(parts, axis=-1)

    def index(self, t: float) -> int:
        """Index of the recorded time closest to ``t`` [s].

        Parameters
        ----------
        t : float
            Simulation time [s].

        Returns
        -------
        int
            Index into :attr:`time` (and the last axis of every column).
        """
        return int(np.argmin(np.abs(self.time - t)))


def block_seeds(scenario: Scenario, seed: int, runs: int) -> list[dict[str, int]]:
    """Per-run block seeds (see the module docstring for the mapping).

    Parameters
    ----------
    scenario : Scenario
        A loaded scenario (its blocks are built to find those with a ``seed``).
    seed : int
        Campaign seed (root of the SeedSequence).
    runs : int
        Number of runs.

    Returns
    -------
    list of dict
        ``[{block: seed}]``, one dict per run.
    """
    system, _ = scenario.build()
    try:
        names = [
            name
            for name, host in system.blocks.items()
            if "seed" in host.variables and host.variables["seed"].type == "Integer"
        ]
    finally:
        for host in system.blocks.values():
            host.terminate()
    return _seeds(names, seed, runs)


def _seeds(names: Sequence[str], seed: int, runs: int) -> list[dict[str, int]]:
    children = np.random.SeedSequence(int(seed)).spawn(int(runs))
    out = []
    for child in children:
        words = child.generate_state(max(1, len(names)), dtype=np.uint32)
        out.append({name: int(words[j] >> 1) for j, name in enumerate(names)})
    return out


def _prepare(
    path: str | Path,
    overrides: Mapping[str, Mapping[str, Any]] | None,
    stop: float | None,
    columns: Sequence[str] | None,
    record_every: int | None,
) -> Scenario:
    scenario = load_scenario(path)
    for block, params in (overrides or {}).items():
        if block not in scenario.blocks:
            raise CampaignError(
                f"override for unknown block '{block}' ({', '.join(scenario.blocks)})"
            )
        scenario.blocks[block].parameters.update(params)
    if stop is not None:
        scenario.settings = scenario.master_settings(stop=float(stop))
    if record_every is not None:
        scenario.settings = scenario.master_settings(record_every=int(record_every))
    if columns is not None:
        scenario.outputs = list(columns)
    return scenario


def _run_chunk(
    path: str,
    overrides: Mapping[str, Mapping[str, Any]] | None,
    stop: float | None,
    columns: Sequence[str] | None,
    record_every: int | None,
    seeds: list[dict[str, int]],
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, str]]:
    scenario = _prepare(path, overrides, stop, columns, record_every)
    system, metadata = scenario.build()
    master = Master(system, scenario.settings, metadata)
    rows: list[np.ndarray] = []
    try:
        for run_seeds in seeds:
            for block, s in run_seeds.items():
                system.parameters.setdefault(block, {})["seed"] = s
            rows.append(master.run().data)
            master.reset()
    finally:
        master.terminate()
    names = [n for n in rows[0].dtype.names if n != "time"]
    data = {n: np.stack([r[n] for r in rows]) for n in names}
    return rows[0]["time"], data, dict(metadata.get("units", {}))


def run_campaign(
    path: str | Path,
    runs: int,
    seed: int,
    *,
    columns: Sequence[str] | None = None,
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
    stop: float | None = None,
    record_every: int | None = None,
    workers: int = 1,
) -> CampaignResult:
    """Run a scenario ``runs`` times with fresh seeds and collect the recorded columns.

    Parameters
    ----------
    path : str or Path
        Scenario file.
    runs : int
        Number of runs (>= 1).
    seed : int
        Campaign seed (see the module docstring for the mapping to block seeds).
    columns : sequence of str, optional
        What to record (``output.variables`` syntax: blocks or ``block.variable``);
        default the scenario's ``[output]``.
    overrides : dict, optional
        ``{block: {parameter: value}}`` written into the scenario before it is built
        (values as in the TOML file, units allowed, e.g. ``"0.01 m/s"``).
    stop : float, optional
        Stop time [s] (default the scenario's).
    record_every : int, optional
        Record every k-th macro step (default the scenario's).
    workers : int
        Processes (1: in this process).

    Returns
    -------
    CampaignResult

    Raises
    ------
    CampaignError
        ``runs < 1`` or an override for an unknown block.
    ScenarioError
        From loading or building the scenario.
    """
    if int(runs) < 1:
        raise CampaignError(f"runs must be >= 1, got {runs}")
    path = str(path)
    scenario = _prepare(path, overrides, stop, columns, record_every)
    seeds = block_seeds(scenario, seed, runs)
    workers = max(1, min(int(workers), len(seeds)))
    args = (path, overrides, stop, columns, record_every)
    if workers == 1:
        time, data, units = _run_chunk(*args, seeds)
    else:
        chunks = [list(c) for c in np.array_split(np.arange(len(seeds)), workers)]
        methods = multiprocessing.get_all_start_methods()
        ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            futures = [pool.submit(_run_chunk, *args, [seeds[i] for i in c]) for c in chunks]
            parts = [f.result() for f in futures]
        time, units = parts[0][0], parts[0][2]
        data = {n: np.concatenate([p[1][n] for p in parts]) for n in parts[0][1]}
    return CampaignResult(time=time, columns=data, seeds=seeds, units=units)
