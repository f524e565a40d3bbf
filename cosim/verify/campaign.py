"""Monte Carlo campaigns: per-run seeds, parallel runs, resume, metrics table, histories.

A campaign runs one scenario ``runs`` times with seeds derived from one campaign seed,
evaluates every requirement on every run (in the worker, on the full recording) and
judges each requirement over the runs (:func:`cosim.verify.requirements.judge`).

Where runs go:

- ``workers == 1``: in this process, one after the other.
- ``workers > 1`` (default: the number of CPUs): a :class:`ProcessPoolExecutor` of
  spawned processes; each builds the scenario's blocks (loads its FMUs) once, in its
  initializer, and resets them between runs.
- ``cluster = "tcp://host:8786"``: a Dask distributed cluster (``distributed.Client``);
  each worker thread builds the blocks once on its first run, the same way. The workers
  must see the scenario and FMU files at the same paths (a shared file system).

A run's numbers depend only on its seeds, never on the worker that ran it.

Seeds (README, "Verification and campaigns")::

    state = SeedSequence(campaign_seed).spawn(runs)[i].generate_state(len(seeded), uint32)
    seed of the j-th seeded block in run i = int(state[j] >> 1)        # 0 .. 2**31 - 1

``seeded`` lists every block with an Integer ``seed`` parameter, in file order; blocks
left out of ``[campaign] randomize`` keep the seed written in the file.

On disk, under the report folder::

    campaign.json          what the campaign is (scenario hash, seed, runs, ...), for --resume
    runs/run_00042.json    one finished run: seeds, status, error, metrics per requirement
    runs/run_00042.npz     its decimated histories: time, e_<k> and s_<k> per requirement k
    metrics.csv            one row per run: status, seeds, metric and pass per requirement
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
import uuid
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import ScenarioError, SimulationError, UserError
from cosim.master import Master
from cosim.scenario import Scenario, load_scenario
from cosim.verify.requirements import (
    Requirement,
    RunMetric,
    Verdict,
    error_signal,
    evaluate,
    judge,
    load_requirements,
    overall_exit_code,
)

CAMPAIGN_KEYS = {"runs", "seed", "randomize", "history_points", "on_failure"}
MANIFEST = "campaign.json"
RUNS_DIR = "runs"
METRICS_FILE = "metrics.csv"
REPORT_FILES = ("report.html", "junit.xml", "report.json")  # written by cosim.verify.report
FORMAT = "ins-cosim-campaign/1"
_SEED_SHIFT = 1  # uint32 >> 1: seeds fit an FMI Integer (int32), 0 .. 2**31 - 1


class CampaignError(UserError):
    """A campaign cannot start: bad ``[campaign]`` table, options, or report folder."""


class CampaignInterrupted(Exception):  # noqa: N818 (an interruption, not an error)
    """The campaign was interrupted (Ctrl-C); finished runs are on disk.

    Parameters
    ----------
    done : int
        Runs finished and on disk.
    total : int
        Runs in the campaign.
    out_dir : Path
        The report folder (``--resume`` continues there).
    """

    def __init__(self, done: int, total: int, out_dir: Path) -> None:
        self.done, self.total, self.out_dir = done, total, out_dir
        super().__init__(
            f"interrupted: {done} of {total} runs are finished and kept in "
            f"{Path(out_dir) / RUNS_DIR}; continue with --resume"
        )


# --------------------------------------------------------------------------- settings
@dataclass
class CampaignSettings:
    """The ``[campaign]`` table.

    Attributes
    ----------
    runs : int
        Number of runs (default 1).
    seed : int
        Campaign seed (default 0), the entropy of the SeedSequence.
    randomize : tuple of str or None
        Blocks whose ``seed`` is drawn per run; None: every block with a seed parameter.
    history_points : int
        At most this many samples of each run's error histories are kept (for plots).
    on_failure : str
        Default ``on_failure`` of the requirements (``"undecided"``, ``"exclude"``,
        ``"fail"``).
    """

    runs: int = 1
    seed: int = 0
    randomize: tuple[str, ...] | None = None
    history_points: int = 500
    on_failure: str = "undecided"


def parse_campaign(scenario: Scenario) -> CampaignSettings:
    """Read ``[campaign]`` of a scenario (all keys optional).

    Parameters
    ----------
    scenario : Scenario
        A loaded scenario.

    Returns
    -------
    CampaignSettings

    Raises
    ------
    ScenarioError
        Unknown key or bad value, naming the file and key.
    """
    table = scenario.raw.get("campaign", {})
    file = str(scenario.path)
    if not isinstance(table, dict):
        raise ScenarioError("expected a [campaign] table", file=file, key="campaign")
    for k in table:
        if k not in CAMPAIGN_KEYS:
            import difflib

            hint = difflib.get_close_matches(k, CAMPAIGN_KEYS, n=1)
            tip = f" Did you mean '{hint[0]}'?" if hint else ""
            raise ScenarioError(
                f"unknown key '{k}'.{tip} Allowed: {', '.join(sorted(CAMPAIGN_KEYS))}",
                file=file,
                key=f"campaign.{k}",
            )
    out = CampaignSettings()
    for key in ("runs", "seed", "history_points"):
        if key in table:
            value = table[key]
            low = 0 if key == "seed" else (2 if key == "history_points" else 1)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ScenarioError(
                    f"expected an integer >= {low}, got {value!r}", file=file, key=f"campaign.{key}"
                )
            setattr(out, key, value)
    if "randomize" in table:
        value = table["randomize"]
        if not isinstance(value, list) or not all(isinstance(b, str) for b in value):
            raise ScenarioError(
                "expected a list of block names, e.g. ['imu', 'flexure']",
                file=file,
                key="campaign.randomize",
            )
        out.randomize = tuple(value)
    if "on_failure" in table:
        value = table["on_failure"]
        if value not in ("undecided", "exclude", "fail"):
            raise ScenarioError(
                f"expected 'undecided', 'exclude' or 'fail', got {value!r}",
                file=file,
                key="campaign.on_failure",
            )
        out.on_failure = value
    return out


def run_seeds(campaign_seed: int, index: int, blocks: Sequence[str]) -> dict[str, int]:
    """Seeds of one run, one per seeded block, from the campaign seed.

    ``SeedSequence(campaign_seed, spawn_key=(index,))`` is the ``index``-th child of
    ``SeedSequence(campaign_seed).spawn(runs)`` for any ``runs > index``, so a run's
    seeds do not depend on how many runs the campaign has.

    Parameters
    ----------
    campaign_seed : int
        Non-negative campaign seed.
    index : int
        Run number, 0-based.
    blocks : sequence of str
        Every block with a ``seed`` parameter, in file order.

    Returns
    -------
    dict
        Block name -> seed in [0, 2**31 - 1].
    """
    child = np.random.SeedSequence(campaign_seed, spawn_key=(index,))
    state = child.generate_state(max(1, len(blocks)), dtype=np.uint32)
    return {b: int(s) >> _SEED_SHIFT for b, s in zip(blocks, state, strict=False)}


def latin_hypercube_normal(runs: int, dims: int, campaign_seed: int, stream: int = 0) -> np.ndarray:
    """Standard normal draws for a campaign, stratified per dimension (Latin hypercube).

    Each column splits the probability axis into ``runs`` equal strata and puts exactly
    one run in each, at a uniform position inside it, in a random order; the draw is
    ``z = Phi^-1(u)``. Every run's row is still marginally ``N(0, I)``, but the campaign's
    sample moments are far closer to the population's than with independent draws: for
    30 runs the mean square of a column spreads by about +-9 % (1 sigma) instead of
    +-26 % (``sqrt(2 / 30)``). Use it for turn-on errors whose spread dominates a
    campaign statistic (a sensor bias the motion cannot separate), so that the campaign
    measures the filter and not the luck of the draw.

    The generator is ``SeedSequence(campaign_seed, spawn_key=(2**63, stream))``: a
    two-element spawn key, never equal to a run's ``(index,)`` of :func:`run_seeds`.

    Parameters
    ----------
    runs : int
        Number of runs (strata per dimension), >= 1.
    dims : int
        Number of independent standard normal variables per run, >= 1.
    campaign_seed : int
        Non-negative campaign seed.
    stream : int
        Independent design number for the same campaign seed (>= 0).

    Returns
    -------
    ndarray, shape (runs, dims)
        Row ``i``: the draws of run ``i`` (dimensionless; scale by the sigmas).

    Raises
    ------
    ValueError
        ``runs`` or ``dims`` below 1, or a negative seed or stream.
    """
    if int(runs) < 1 or int(dims) < 1:
        raise ValueError(f"runs and dims: expected >= 1, got {runs} and {dims}")
    if int(campaign_seed) < 0 or int(stream) < 0:
        raise ValueError(f"campaign_seed, stream: expected >= 0, got {campaign_seed}, {stream}")
    from scipy.special import ndtri

    seq = np.random.SeedSequence(int(campaign_seed), spawn_key=(2**63, int(stream)))
    rng = np.random.default_rng(seq)
    n, d = int(runs), int(dims)
    strata = np.argsort(rng.random((d, n)), axis=1).T  # one permutation per column
    u = (strata + rng.random((n, d))) / n
    return ndtri(u)


# ----------------------------------------------------------------------- run records
@dataclass
class RunRecord:
    """One finished run (completed or failed).

    Attributes
    ----------
    index : int
        Run number, 0-based.
    seeds : dict
        Block -> seed used.
    status : str
        ``"completed"`` or ``"failed"``.
    error : str
        The failure message (block, variable or call, time), else empty.
    metrics : dict
        Requirement id -> :class:`RunMetric`, or None for a failed run.
    history : dict
        ``"time"`` [s] shape (m,), ``"e_<k>"`` and ``"s_<k>"`` [unit of requirement k]
        shape (m,): the decimated error and 1-sigma (partial for a failed run).
    wall_time : float
        Seconds the run took (not part of the results' identity).
    worker : str
        ``host:pid`` of the process that ran it.
    t_end : float
        Last recorded time [s].
    """

    index: int
    seeds: dict[str, int]
    status: str
    error: str
    metrics: dict[str, RunMetric | None]
    history: dict[str, np.ndarray] = field(default_factory=dict)
    wall_time: float = 0.0
    worker: str = ""
    t_end: float = math.nan

    @property
    def failed(self) -> bool:
        """True when the run stopped before its end."""
        return self.status != "completed"

    def to_dict(self) -> dict[str, Any]:
        """Plain data (no histories), non-finite numbers as strings."""
        return {
            "index": self.index,
            "seeds": self.seeds,
            "status": self.status,
            "error": self.error,
            "t_end": _num(self.t_end),
            "wall_time": self.wall_time,
            "worker": self.worker,
            "metrics": {
                k: None
                if m is None
                else {"value": _num(m.value), "passed": m.passed, "note": m.note}
                for k, m in self.metrics.items()
            },
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], history: dict[str, np.ndarray]) -> RunRecord:
        """Inverse of :meth:`to_dict`.

        Parameters
        ----------
        d : dict
            The run's JSON record (``runs/run_NNNNN.json``).
        history : dict
            Its decimated histories (``runs/run_NNNNN.npz``): name -> array, shape (m,).

        Returns
        -------
        RunRecord
        """
        metrics = {
            k: None if m is None else RunMetric(float(m["value"]), m["passed"], m["note"])
            for k, m in d["metrics"].items()
        }
        return cls(
            index=int(d["index"]),
            seeds={k: int(v) for k, v in d["seeds"].items()},
            status=d["status"],
            error=d["error"],
            metrics=metrics,
            history=history,
            wall_time=float(d.get("wall_time", 0.0)),
            worker=d.get("worker", ""),
            t_end=float(d.get("t_end", math.nan)),
        )


def _num(x: float) -> float | str:
    return x if math.isfinite(x) else str(x)


def _run_stem(index: int) -> str:
    return f"run_{index:05d}"


def save_record(record: RunRecord, runs_dir: Path) -> None:
    """Write ``run_<i>.npz`` then ``run_<i>.json`` (the marker of a finished run).

    Both are written to a temporary name and renamed, so an interruption never leaves
    a half-written run that :func:`read_records` would take for finished.

    Parameters
    ----------
    record : RunRecord
        The run.
    runs_dir : Path
        ``<report>/runs``.
    """
    runs_dir.mkdir(parents=True, exist_ok=True)
    stem = _run_stem(record.index)
    tmp = runs_dir / f".{stem}.npz.tmp"
    with open(tmp, "wb") as fh:
        np.savez(fh, **record.history)
    os.replace(tmp, runs_dir / f"{stem}.npz")
    tmp = runs_dir / f".{stem}.json.tmp"
    tmp.write_text(json.dumps(record.to_dict(), indent=1) + "\n")
    os.replace(tmp, runs_dir / f"{stem}.json")


def read_records(runs_dir: Path, runs: int | None = None) -> dict[int, RunRecord]:
    """Finished runs on disk.

    Parameters
    ----------
    runs_dir : Path
        ``<report>/runs``.
    runs : int, optional
        Only runs ``0 .. runs - 1``.

    Returns
    -------
    dict
        Run index -> RunRecord (with histories).
    """
    out: dict[int, RunRecord] = {}
    if not runs_dir.is_dir():
        return out
    for js in sorted(runs_dir.glob("run_*.json")):
        npz = js.with_suffix(".npz")
        try:
            d = json.loads(js.read_text())
            with np.load(npz) as z:
                history = {k: z[k] for k in z.files}
        except (OSError, ValueError, KeyError):
            continue  # unreadable: run it again
        if runs is None or d["index"] < runs:
            out[int(d["index"])] = RunRecord.from_dict(d, history)
    return out


# ------------------------------------------------------------------------- the worker
@dataclass(frozen=True)
class WorkerSpec:
    """What a worker needs to run any run of a campaign (picklable).

    Attributes
    ----------
    scenario : str
        Absolute path of the scenario file.
    sha256 : str
        Its hash: a worker that reads a different file refuses to run.
    fmu_dir : str or None
        Run built-in models from the FMUs in this folder.
    requirements : tuple of Requirement
        Resolved requirements.
    history_points : int
        Samples kept per history.
    """

    scenario: str
    sha256: str
    fmu_dir: str | None
    requirements: tuple[Requirement, ...]
    history_points: int = 500


class _State:
    """A worker thread's built system, kept between runs."""

    def __init__(self, spec: WorkerSpec) -> None:
        scenario = load_scenario(spec.scenario)
        if scenario.sha256 != spec.sha256:
            raise CampaignError(
                f"the scenario file {spec.scenario} on worker {_worker_id()} differs from the "
                f"one the campaign started with (sha256 {scenario.sha256[:12]} != "
                f"{spec.sha256[:12]})"
            )
        if spec.fmu_dir is not None:
            scenario.use_fmus(spec.fmu_dir)
        self.spec = spec
        self.settings = scenario.settings
        self.system, metadata = scenario.build()
        self.master = Master(self.system, self.settings, metadata)
        self.used = False

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.master.terminate()


_LOCAL = threading.local()


def _worker_id() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _state(spec: WorkerSpec) -> _State:
    state: _State | None = getattr(_LOCAL, "state", None)
    if state is not None and state.spec != spec:
        release_worker_state()
        state = None
    if state is None:
        state = _State(spec)
        _LOCAL.state = state
    return state


def release_worker_state() -> None:
    """Terminate the blocks this thread keeps for campaigns (if any)."""
    state: _State | None = getattr(_LOCAL, "state", None)
    if state is not None:
        state.close()
        _LOCAL.state = None


def _init_process_worker(spec: WorkerSpec) -> None:
    """ProcessPoolExecutor initializer: Ctrl-C is the parent's business; build once.

    The blocks are terminated when the worker process exits (FMU instances freed, their
    unpacked folders removed): a multiprocessing finalizer, since worker processes end
    without running ``atexit`` handlers.
    """
    from multiprocessing import util

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _state(spec)
    util.Finalize(None, release_worker_state, exitpriority=10)


def _decimation(n: int, points: int) -> np.ndarray:
    """Indices of at most ``points`` rows out of ``n``, evenly strided, the last included."""
    if n <= points:
        return np.arange(n)
    stride = math.ceil((n - 1) / (points - 1))
    idx = np.arange(0, n, stride)
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


def run_one(spec: WorkerSpec, index: int, seeds: dict[str, int]) -> RunRecord:
    """Run one run of a campaign in this worker and evaluate every requirement on it.

    The blocks are built on the first call in a thread and reset between calls. A
    failing run is returned as a record with ``status = "failed"`` and its error.

    Parameters
    ----------
    spec : WorkerSpec
        The campaign.
    index : int
        Run number.
    seeds : dict
        Block -> seed for this run.

    Returns
    -------
    RunRecord
    """
    started = time.perf_counter()
    state = _state(spec)
    if state.used:
        try:
            state.master.reset()
        except Exception:  # a block that failed may refuse to reset: build it anew
            release_worker_state()
            state = _state(spec)
    state.used = True
    for block, seed in seeds.items():
        state.system.parameters.setdefault(block, {})["seed"] = seed
    result = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # loop warnings were shown once by the parent
        try:
            result = state.master.run()
            status, error = "completed", ""
        except SimulationError as exc:
            result, status, error = exc.result, "failed", str(exc)
        except Exception as exc:  # a block raising outside the FMI protocol
            status, error = "failed", f"{type(exc).__name__}: {exc}"
            release_worker_state()
    metrics: dict[str, RunMetric | None] = {r.id: None for r in spec.requirements}
    history: dict[str, np.ndarray] = {}
    t_end = math.nan
    if result is not None and len(result.data):
        t_end = float(result.time[-1])
        idx = _decimation(len(result.data), spec.history_points)
        history["time"] = np.asarray(result.time, dtype=float)[idx]
        for k, req in enumerate(spec.requirements):
            t, e, sigma = error_signal(req, result)
            if status == "completed":
                metrics[req.id] = evaluate(req, t, e, state.settings.start, state.settings.stop)
            history[f"e_{k}"] = e[idx]
            if sigma is not None:
                history[f"s_{k}"] = sigma[idx]
    return RunRecord(
        index=index,
        seeds=dict(seeds),
        status=status,
        error=error,
        metrics=metrics,
        history=history,
        wall_time=time.perf_counter() - started,
        worker=_worker_id(),
        t_end=t_end,
    )


# ------------------------------------------------------------------------- executors
def _run_serial(
    spec: WorkerSpec, jobs: list[tuple[int, dict[str, int]]], done: Callable[[RunRecord], None]
) -> None:
    try:
        for index, seeds in jobs:
            done(run_one(spec, index, seeds))
    finally:
        release_worker_state()


def _run_pool(
    spec: WorkerSpec,
    jobs: list[tuple[int, dict[str, int]]],
    done: Callable[[RunRecord], None],
    workers: int,
) -> None:
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    pool = ProcessPoolExecutor(
        max_workers=min(workers, len(jobs)),
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_init_process_worker,
        initargs=(spec,),
    )
    try:
        pending = {pool.submit(run_one, spec, i, s) for i, s in jobs}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                done(fut.result())
    except BaseException:
        # Ctrl-C or a crash: drop queued runs and stop the workers now, without waiting
        # for the runs in progress (they are not on disk and will run again on --resume).
        procs = list((getattr(pool, "_processes", None) or {}).values())  # no API in 3.11
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            with contextlib.suppress(Exception):
                proc.terminate()
        raise
    pool.shutdown(wait=True)


def _run_dask(
    spec: WorkerSpec,
    jobs: list[tuple[int, dict[str, int]]],
    done: Callable[[RunRecord], None],
    address: str,
) -> None:
    from distributed import Client, as_completed

    try:
        client = Client(address, timeout="30s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise CampaignError(f"cannot connect to the Dask scheduler at {address}: {exc}") from exc
    token = uuid.uuid4().hex[:12]
    futures = []
    try:
        futures = [
            client.submit(run_one, spec, i, s, key=f"ins-cosim-run-{token}-{i:05d}")
            for i, s in jobs
        ]
        for fut in as_completed(futures):
            done(fut.result())
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel(futures)
        raise
    finally:
        client.close()


# ------------------------------------------------------------------------- campaigns
@dataclass
class Campaign:
    """A finished campaign: runs, verdicts and provenance.

    Attributes
    ----------
    out_dir : Path
        The report folder.
    scenario : dict
        ``file``, ``name``, ``sha256``.
    settings : CampaignSettings
        Effective runs, seed, randomized blocks.
    requirements : list of Requirement
        In file order.
    records : list of RunRecord
        One per run, by index.
    verdicts : list of Verdict
        One per requirement.
    provenance : dict
        Blocks (kind, source, GUID, sha256), master settings, seeded blocks, seed rule,
        software versions.
    execution : dict
        Workers or cluster, runs done in this session, whether it was resumed.
    """

    out_dir: Path
    scenario: dict[str, Any]
    settings: CampaignSettings
    requirements: list[Requirement]
    records: list[RunRecord]
    verdicts: list[Verdict]
    provenance: dict[str, Any]
    execution: dict[str, Any]

    @property
    def exit_code(self) -> int:
        """0 all satisfied, 1 any violated, 2 any undecided (and none violated)."""
        return overall_exit_code(self.verdicts)

    @property
    def failed_runs(self) -> list[RunRecord]:
        """Runs that stopped before their end."""
        return [r for r in self.records if r.failed]

    def metric_values(self, req: Requirement) -> np.ndarray:
        """Per-run metrics of a requirement.

        Parameters
        ----------
        req : Requirement
            One of :attr:`requirements`.

        Returns
        -------
        ndarray, shape (runs,)
            Metric per run in the requirement's metric unit; nan for failed or undecided
            runs.
        """
        out = np.full(len(self.records), math.nan)
        for i, rec in enumerate(self.records):
            m = rec.metrics.get(req.id)
            if m is not None:
                out[i] = m.value
        return out


@dataclass
class Prepared:
    """A checked scenario, ready for a campaign (see :func:`prepare`).

    Attributes
    ----------
    scenario : Scenario
        The loaded scenario.
    settings : CampaignSettings
        Its ``[campaign]`` table.
    requirements : list of Requirement
        Its ``[[requirements]]``, checked against the built system.
    seeded : list of str
        Blocks with a ``seed`` parameter that the campaign draws, in file order.
    metadata : dict
        Provenance (scenario hash, FMU hashes, versions) recorded with the campaign.
    """

    scenario: Scenario
    settings: CampaignSettings
    requirements: list[Requirement]
    seeded: list[str]
    metadata: dict[str, Any]


def prepare(scenario: str | Path, fmu_dir: str | Path | None = None) -> Prepared:
    """Load a scenario, build it once to check requirements and collect provenance.

    Parameters
    ----------
    scenario : str or Path
        The scenario file.
    fmu_dir : str or Path, optional
        Run built-in models from these FMUs.

    Returns
    -------
    Prepared
        Scenario, campaign settings, requirements, seeded blocks, metadata.

    Raises
    ------
    ScenarioError, FmuError
        Bad scenario, requirement or campaign table.
    """
    sc = load_scenario(scenario)
    if fmu_dir is not None:
        sc.use_fmus(fmu_dir)
    settings = parse_campaign(sc)
    system, metadata = sc.build()
    try:
        master = Master(system, sc.settings, metadata)
        master.warn_loops()  # once here; the workers run silently
        outputs = [
            f"{b}.{v.name}"
            for b, h in system.blocks.items()
            for v in h.by_causality("output")
            if v.type == "Real"
        ]
        # the unit conversions use (an FMU's own unit definition when it has one)
        units: dict[str, Any] = {"time": "s"}
        for b, v in master.record:
            var = system.blocks[b].variables[v]
            units[f"{b}.{v}"] = getattr(var, "conversion_unit", var.unit)
        seeded = [
            b
            for b, h in system.blocks.items()
            if "seed" in h.variables
            and h.variables["seed"].causality == "parameter"
            and h.variables["seed"].type == "Integer"
        ]
    finally:
        for host in system.blocks.values():
            with contextlib.suppress(Exception):
                host.terminate()
    tables = sc.raw.get("requirements", [])
    if not tables:
        raise ScenarioError(
            "no requirements: add [[requirements]] tables (id, signal, criterion, bound, ...)",
            file=str(sc.path),
            key="requirements",
        )
    reqs = load_requirements(tables, units, str(sc.path), outputs, on_failure=settings.on_failure)
    if settings.randomize is not None:
        for i, b in enumerate(settings.randomize):
            if b not in seeded:
                raise ScenarioError(
                    f"block '{b}' has no seed parameter to randomize; blocks with one: "
                    f"{', '.join(seeded) or 'none'}",
                    file=str(sc.path),
                    key=f"campaign.randomize[{i}]",
                )
    return Prepared(sc, settings, reqs, seeded, metadata)


def _manifest(prep: Prepared, runs: int, seed: int, fmu_dir: str | None) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "scenario": {
            "file": str(prep.scenario.path.resolve()),
            "name": prep.scenario.name,
            "sha256": prep.scenario.sha256,
        },
        "fmu_dir": fmu_dir,
        "runs": runs,
        "seed": seed,
        "seeded_blocks": prep.seeded,
        "randomize": list(prep.settings.randomize) if prep.settings.randomize is not None else None,
        "history_points": prep.settings.history_points,
        "requirements": [r.id for r in prep.requirements],
    }


def _check_resume(old: dict[str, Any], new: dict[str, Any], out_dir: Path) -> None:
    def refuse(what: str) -> CampaignError:
        return CampaignError(
            f"{out_dir / MANIFEST}: cannot resume: {what}; run without --resume to start "
            f"over, or use another --report folder"
        )

    if old.get("format") != FORMAT:
        raise refuse("not a campaign written by this version of ins-cosim")
    if old["scenario"]["sha256"] != new["scenario"]["sha256"]:
        raise refuse(
            f"the scenario file changed since the campaign started (sha256 "
            f"{old['scenario']['sha256'][:12]} -> {new['scenario']['sha256'][:12]})"
        )
    for key in ("seed", "fmu_dir", "seeded_blocks", "randomize", "history_points"):
        if old.get(key) != new.get(key):
            raise refuse(f"{key} was {old.get(key)!r}, now {new.get(key)!r}")
    if new["runs"] < old["runs"]:
        raise refuse(f"it has {old['runs']} runs; --runs can add runs, not remove them")


def run_campaign(
    scenario: str | Path,
    out_dir: str | Path,
    *,
    runs: int | None = None,
    seed: int | None = None,
    workers: int | None = None,
    cluster: str | None = None,
    fmu_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
) -> Campaign:
    """Run (or resume) a Monte Carlo campaign and judge its requirements.

    Parameters
    ----------
    scenario : str or Path
        Scenario file with ``[[requirements]]`` (and optionally ``[campaign]``).
    out_dir : str or Path
        Report folder: ``campaign.json``, ``runs/``, ``metrics.csv``.
    runs, seed : int, optional
        Override ``[campaign] runs`` and ``seed``.
    workers : int, optional
        Local worker processes (default: the number of CPUs; 1 runs in this process).
    cluster : str, optional
        Address of a Dask scheduler (``tcp://host:8786``); replaces local workers.
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    resume : bool
        Keep the finished runs in ``out_dir`` and run the rest. Without it, runs left
        in ``out_dir`` by an earlier campaign are deleted first.
    progress : bool
        Show a progress bar with ETA on stderr.

    Returns
    -------
    Campaign

    Raises
    ------
    ScenarioError, FmuError, CampaignError
        Bad input (before any run).
    CampaignInterrupted
        On Ctrl-C; the finished runs are on disk.
    """
    fmu = None if fmu_dir is None else str(Path(fmu_dir).resolve())
    prep = prepare(scenario, fmu)
    settings = prep.settings
    if runs is not None:
        if runs < 1:
            raise CampaignError(f"--runs must be >= 1, got {runs}")
        settings.runs = runs
    if seed is not None:
        if seed < 0:
            raise CampaignError(f"--seed must be >= 0, got {seed}")
        settings.seed = seed
    if workers is None:
        workers = os.cpu_count() or 1
    if workers < 1:
        raise CampaignError(f"--workers must be >= 1, got {workers}")

    out = Path(out_dir)
    runs_dir = out / RUNS_DIR
    manifest = _manifest(prep, settings.runs, settings.seed, fmu)
    manifest_file = out / MANIFEST
    if resume:
        if not manifest_file.is_file():
            raise CampaignError(f"{out}: no campaign to resume (no {MANIFEST}); drop --resume")
        old = json.loads(manifest_file.read_text())
        if runs is None:
            manifest["runs"] = settings.runs = int(old["runs"])
        _check_resume(old, manifest, out)
    else:
        stale = [out / name for name in (METRICS_FILE, *REPORT_FILES)]
        for f in (*runs_dir.glob("run_*"), *runs_dir.glob(".run_*"), *stale):
            f.unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    manifest_file.write_text(json.dumps(manifest, indent=2) + "\n")
    for tmp in runs_dir.glob(".run_*.tmp"):
        tmp.unlink()

    finished = read_records(runs_dir, settings.runs) if resume else {}
    randomized = prep.seeded if settings.randomize is None else list(settings.randomize)
    jobs = []
    for i in range(settings.runs):
        if i not in finished:
            seeds = run_seeds(settings.seed, i, prep.seeded)
            jobs.append((i, {b: s for b, s in seeds.items() if b in randomized}))
    spec = WorkerSpec(
        scenario=str(prep.scenario.path.resolve()),
        sha256=prep.scenario.sha256,
        fmu_dir=fmu,
        requirements=tuple(prep.requirements),
        history_points=settings.history_points,
    )

    bar = _progress(settings.runs, len(finished), progress)
    count = [len(finished)]

    def done(record: RunRecord) -> None:
        save_record(record, runs_dir)
        count[0] += 1
        bar.update(1)
        if record.failed:
            bar.write(f"run {record.index} failed: {record.error}", file=sys.stderr)

    try:
        if jobs and cluster:
            _run_dask(spec, jobs, done, cluster)
        elif jobs and workers > 1 and len(jobs) > 1:
            _run_pool(spec, jobs, done, workers)
        elif jobs:
            _run_serial(spec, jobs, done)
    except KeyboardInterrupt:
        raise CampaignInterrupted(count[0], settings.runs, out) from None
    finally:
        bar.close()

    records_by_index = read_records(runs_dir, settings.runs)
    missing = [i for i in range(settings.runs) if i not in records_by_index]
    if missing:  # only if files vanished under us
        raise CampaignError(f"runs {missing[:5]} are missing from {runs_dir}")
    records = [records_by_index[i] for i in range(settings.runs)]
    verdicts = [judge(req, [r.metrics.get(req.id) for r in records]) for req in prep.requirements]
    meta = prep.metadata
    blocks_seeds = {b: meta["seeds"].get(b) for b in prep.seeded}
    campaign = Campaign(
        out_dir=out,
        scenario=manifest["scenario"],
        settings=settings,
        requirements=prep.requirements,
        records=records,
        verdicts=verdicts,
        provenance={
            "blocks": meta["blocks"],
            "master": {
                "step": prep.scenario.settings.step,
                "start": prep.scenario.settings.start,
                "stop": prep.scenario.settings.stop,
                "coupling": prep.scenario.settings.coupling,
                "record_every": prep.scenario.settings.record_every,
            },
            "seeded_blocks": prep.seeded,
            "randomized_blocks": randomized,
            "file_seeds": blocks_seeds,
            "seed_rule": (
                "seeds of run i = SeedSequence(campaign seed).spawn(runs)[i]"
                ".generate_state(len(seeded_blocks), uint32) >> 1, in seeded_blocks order; "
                "blocks not randomized keep the seed of the scenario file"
            ),
            "units": meta["units"],
            "software": software_versions(),
        },
        execution={
            "workers": None if cluster else workers,
            "cluster": cluster,
            "resumed": resume,
            "runs_this_session": len(jobs),
            "fmu_dir": fmu,
        },
    )
    write_metrics_table(campaign, out / METRICS_FILE)
    return campaign


def _progress(total: int, initial: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="run",
        desc="runs",
        file=sys.stderr,
        disable=not enabled,
        dynamic_ncols=True,
    )


def software_versions() -> dict[str, str]:
    """Versions of Python, ins-cosim and every package a campaign and its report use.

    Returns
    -------
    dict
        Package -> version (missing packages are left out).
    """
    from importlib import metadata

    from cosim import provenance

    out = provenance.versions()
    for name in ("dask", "distributed", "matplotlib", "tqdm", "click"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            out[name] = metadata.version(name)
    return out


def metrics_columns(campaign: Campaign) -> list[str]:
    """Header of the metrics table.

    Parameters
    ----------
    campaign : Campaign
        A finished (or resumed) campaign.

    Returns
    -------
    list of str
        ``run``, ``status``, one ``seed.<block>`` per drawn block, the metric and pass
        columns of every requirement, ``error``.
    """
    seeds = [f"seed.{b}" for b in campaign.provenance["randomized_blocks"]]
    per_req: list[str] = []
    for r in campaign.requirements:
        per_req += [f"{r.id} [{r.metric_unit}]", f"{r.id} pass"]
    return ["run", "status", *seeds, *per_req, "error"]


def metrics_rows(campaign: Campaign) -> Iterable[list[Any]]:
    """Rows of the metrics table (see :func:`metrics_columns`), one per run.

    Parameters
    ----------
    campaign : Campaign
        A finished (or resumed) campaign.

    Yields
    ------
    list
        One row per run, in run order.
    """
    for rec in campaign.records:
        row: list[Any] = [rec.index, rec.status]
        row += [rec.seeds.get(b, "") for b in campaign.provenance["randomized_blocks"]]
        for r in campaign.requirements:
            m = rec.metrics.get(r.id)
            if m is None:
                row += ["", ""]
            else:
                row += [
                    "" if math.isnan(m.value) else repr(float(m.value)),
                    "" if m.passed is None else int(m.passed),
                ]
        row.append(rec.error)
        yield row


def write_metrics_table(campaign: Campaign, path: Path) -> Path:
    """Write the per-run metrics table as CSV (full float precision, repr).

    Parameters
    ----------
    campaign : Campaign
        The campaign.
    path : Path
        The CSV file.

    Returns
    -------
    Path
    """
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(metrics_columns(campaign))
        w.writerows(metrics_rows(campaign))
    return path
