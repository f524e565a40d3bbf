"""A campaign's runs as a worker makes them: the jobs, one run, runs in this process.

A worker builds the scenario's blocks (loads its FMUs) once, the first time it sees a
:class:`WorkerSpec`, and resets them between runs; each :class:`Job` sets its
parameters on a copy of the built system's own before the run. A run's numbers depend
only on its job (seeds, parameters, stratified draws), never on the worker that ran it
nor on the runs it ran before.

Where the jobs go is :func:`cosim.verify.dispatch.run_jobs`:

- ``workers == 1``: in this process, one after the other; in one worker process when the
  scenario holds an FMU not built by ins-cosim (:attr:`WorkerSpec.isolate`), so that its
  crash is one crashed run, as with more workers.
- ``workers > 1``: local worker processes (:class:`cosim.verify.pool.WorkerPool`), each
  running one job at a time sent to it through its own pipe, so the parent always knows
  which run each process is running. A pool given to
  :func:`cosim.verify.dispatch.run_jobs` keeps its processes, and their built blocks,
  from one call to the next (the looks of ``verify --until-decided``); without one, a
  pool lives for one call.
- ``cluster = "tcp://host:8786"``: a Dask distributed cluster; each worker thread builds
  the blocks once on its first run. The workers must see the scenario and FMU files at
  the same paths (a shared file system).

A worker process that dies (an FMU calling ``abort()``, a segmentation fault, a model
calling ``os._exit``, the kernel's OOM killer) loses only the run it was running
(:mod:`cosim.verify.pool`): that run is run again on a fresh process and recorded as
``"crashed"`` when its worker dies again. On Dask the scheduler retries a task whose
worker died and gives up after ``distributed.scheduler.allowed-failures`` deaths
(``KilledWorker``): that run is recorded as crashed (without the block: Dask workers
keep no board).
"""

from __future__ import annotations

import contextlib
import copy
import os
import signal
import socket
import threading
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import cosim.blocks
from cosim.blocks import FmuHost
from cosim.errors import SimulationError, UserError
from cosim.isolate import BoardObserver, StepBoard
from cosim.observers import Observer
from cosim.runs import assemble, make_run
from cosim.scenario import Scenario, load_scenario
from cosim.verify.consistency import ConsistencyRequirement, record_consistency
from cosim.verify.records import RunRecord, decimation
from cosim.verify.requirements import Requirement, RunMetric, error_signal, evaluate


class CampaignError(UserError):
    """A campaign cannot start: bad ``[campaign]`` table, options, jobs or report folder."""


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
        Resolved requirements, evaluated on every run (may be empty).
    history_points : int
        Samples kept per requirement history.
    stop : float or None
        Stop time [s] replacing the scenario's.
    record_every : int or None
        Recording interval (macro steps) replacing the scenario's.
    outputs : tuple of str or None
        What to record (``output.variables`` syntax), replacing the scenario's.
    keep : bool
        Return every recorded column in full, and the run's parameters, in the record
        (:attr:`RunRecord.columns`, :attr:`RunRecord.parameters`).
    isolate : bool
        Run in worker processes even with one worker (``--workers 1``): the scenario
        holds an FMU not built by ins-cosim (:func:`cosim.foreign.foreign_fmus`), whose
        crash must cost one run, not the campaign.
    """

    scenario: str
    sha256: str
    fmu_dir: str | None = None
    requirements: tuple[Requirement, ...] = ()
    history_points: int = 500
    stop: float | None = None
    record_every: int | None = None
    outputs: tuple[str, ...] | None = None
    keep: bool = False
    isolate: bool = False


@dataclass(frozen=True)
class Job:
    """One run of a campaign.

    Attributes
    ----------
    index : int
        Run number (its seeds come from it: :func:`cosim.verify.seeds.run_seeds`).
    seeds : dict
        Block -> seed; blocks left out keep the seed of the scenario file.
    parameters : dict
        ``{block: {parameter: SI value}}`` over the scenario's; a vector parameter may be
        given as a list (``{"r0": [10, 10, 5]}`` sets ``r0[1..3]``).
    stratified : tuple
        ``(block, name, z)`` per stratified parameter
        (:func:`cosim.verify.seeds.stratified_draws`): the run uses ``name = name +
        name_sigma * z`` and ``name_sigma = 0``.
    tag : str
        A label copied into the record (a reproduction's case name).
    """

    index: int
    seeds: Mapping[str, int]
    parameters: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    stratified: tuple[tuple[str, str, tuple[float, ...]], ...] = ()
    tag: str = ""


def expand_parameters(
    parameters: Mapping[str, Mapping[str, Any]],
) -> dict[str, dict[str, Any]]:
    """Vector values as their components: ``{"r0": [1, 2]}`` -> ``{"r0[1]": 1, "r0[2]": 2}``.

    Parameters
    ----------
    parameters : dict
        ``{block: {parameter: value or list of values}}``.

    Returns
    -------
    dict
        ``{block: {parameter name: value}}``, one entry per scalar variable.
    """
    out: dict[str, dict[str, Any]] = {}
    for block, values in parameters.items():
        flat = out.setdefault(block, {})
        for name, value in values.items():
            if isinstance(value, (list, tuple)):
                for k, v in enumerate(value):
                    flat[f"{name}[{k + 1}]"] = v
            else:
                flat[name] = value
    return out


class _State:
    """A worker thread's built system, kept between runs of one campaign.

    The scenario is the one this process parsed for the campaign (:func:`share_scenario`:
    runs in the campaign's own process), else read from its file (once per worker
    process or Dask worker thread).
    """

    def __init__(self, spec: WorkerSpec) -> None:
        scenario = _SHARED.get((spec.scenario, spec.sha256))
        if scenario is None:
            scenario = load_scenario(spec.scenario)
        if scenario.sha256 != spec.sha256:
            raise CampaignError(
                f"the scenario file {spec.scenario} on worker {worker_id()} differs from the "
                f"one the campaign started with (sha256 {scenario.sha256[:12]} != "
                f"{spec.sha256[:12]})"
            )
        self.spec = spec
        self.assembly = assemble(
            scenario, fmu_dir=spec.fmu_dir, outputs=spec.outputs, stop=spec.stop,
            record_every=spec.record_every,
        )  # fmt: skip
        self.master = self.assembly.master
        # what watches every run: the step board of a local worker process, Ctrl-C
        self.observers: list[Observer] = [_CtrlC()]
        if _BOARD is not None:
            self.observers.append(BoardObserver(_BOARD))
        self.settings = self.master.settings
        self.system = self.master.system
        self.base = self.assembly.parameters

    def parameters(self, job: Job) -> dict[str, dict[str, Any]]:
        """The run's parameters: the built system's, then the job's, draws and seeds."""
        params = copy.deepcopy(self.base)
        for block, values in expand_parameters(job.parameters).items():
            params.setdefault(block, {}).update(values)
        for block, name, z in job.stratified:
            host = self.system.blocks[block]
            own = params.setdefault(block, {})
            sigma = float(own.get(f"{name}_sigma", host.variables[f"{name}_sigma"].start))
            names = (
                [name] if name in host.variables else [f"{name}[{k + 1}]" for k in range(len(z))]
            )
            for n, zk in zip(names, z, strict=True):
                own[n] = float(own.get(n, host.variables[n].start)) + sigma * zk
            own[f"{name}_sigma"] = 0.0
        for block, seed in job.seeds.items():
            params.setdefault(block, {})["seed"] = int(seed)
        return params

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.assembly.close()


_LOCAL = threading.local()
#: Scenarios parsed by this process for its campaigns, by (absolute path, sha256).
_SHARED: dict[tuple[str, str], Scenario] = {}
_BLOCKS_FILE = cosim.blocks.__file__  # FmuHost's frames, for _in_fmu_code
_BOARD: StepBoard | None = None  # set in a local worker process


def worker_id() -> str:
    """``host:pid`` of this process (recorded with each run).

    Returns
    -------
    str
    """
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


def share_scenario(scenario: Scenario) -> None:
    """Let the runs made in this process build from ``scenario`` instead of reading its file.

    A campaign's process parses its scenario once (:func:`cosim.verify.campaign.prepare`)
    and shares it here; its worker processes read the file themselves, once each.

    Parameters
    ----------
    scenario : Scenario
        As parsed (its path and sha256 identify it); it is not changed.
    """
    _SHARED.clear()  # one campaign's scenario at a time
    _SHARED[(str(scenario.path.resolve()), scenario.sha256)] = scenario


def release_worker_state() -> None:
    """Terminate the blocks this thread keeps for campaigns (if any)."""
    state: _State | None = getattr(_LOCAL, "state", None)
    if state is not None:
        state.close()
        _LOCAL.state = None


def run_one(spec: WorkerSpec, job: Job) -> RunRecord:
    """Run one job in this worker and evaluate every requirement on it.

    The blocks are built on the first call in a thread and reset between calls
    (:func:`cosim.runs.assemble`, :func:`cosim.runs.make_run`). A failing run is
    returned as a record with ``status = "failed"`` and its error.

    Parameters
    ----------
    spec : WorkerSpec
        The campaign.
    job : Job
        The run: index, seeds, parameters, stratified draws.

    Returns
    -------
    RunRecord
    """
    started, cpu = time.perf_counter(), time.process_time()
    state = _state(spec)
    if state.assembly.used:
        try:
            state.master.reset()
            state.assembly.used = False
        except Exception:  # a block that failed may refuse to reset: build it anew
            release_worker_state()
            state = _state(spec)
    params = state.parameters(job)
    result = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # loop warnings were shown once by the parent
        try:
            result = make_run(state.assembly, parameters=params, observers=state.observers)
            status, error = "completed", ""
        except SimulationError as exc:
            result, status, error = exc.result, "failed", str(exc)
        except Exception as exc:  # a block raising outside the FMI protocol
            status, error = "failed", f"{type(exc).__name__}: {exc}"
            release_worker_state()
    metrics: dict[str, RunMetric | None] = {r.id: None for r in spec.requirements}
    history: dict[str, np.ndarray] = {}
    columns: dict[str, np.ndarray] = {}
    t_end = float("nan")
    if result is not None and len(result.data):
        t_end = float(result.time[-1])
        idx = decimation(len(result.data), spec.history_points)
        history["time"] = np.asarray(result.time, dtype=float)[idx]
        for k, req in enumerate(spec.requirements):
            t, e, sigma = error_signal(req, result)
            if status == "completed" and isinstance(req, ConsistencyRequirement):
                metrics[req.id] = req.judge(result)[0]
            elif status == "completed":
                metrics[req.id] = evaluate(req, t, e, state.settings.start, state.settings.stop)
            history[f"e_{k}"] = e[idx]
            if sigma is not None:
                history[f"s_{k}"] = sigma[idx]
        if spec.keep:
            columns = {n: np.array(result.data[n], dtype=float) for n in result.data.dtype.names}
    consistency = record_consistency(result) if status == "completed" and result else {}
    return RunRecord(
        index=job.index,
        seeds=dict(job.seeds),
        status=status,
        error=error,
        metrics=metrics,
        history=history,
        wall_time=time.perf_counter() - started,
        cpu_time=time.process_time() - cpu,
        worker=worker_id(),
        t_end=t_end,
        tag=job.tag,
        columns=columns,
        parameters=params if spec.keep else {},
        consistency=consistency,
    )


def build_worker(spec: WorkerSpec, board: StepBoard | None = None) -> None:
    """Build the blocks of a campaign in this thread, ready for :func:`run_one`.

    Parameters
    ----------
    spec : WorkerSpec
        The campaign.
    board : StepBoard, optional
        In a local worker process: the board where every block call is noted (set once,
        for the process's life).

    Raises
    ------
    CampaignError
        The scenario file changed since the campaign started.
    """
    global _BOARD
    if board is not None:
        _BOARD = board
    _state(spec)


def run_here(
    spec: WorkerSpec, jobs: Sequence[Job], done: Callable[[RunRecord], None], *, keep: bool = False
) -> None:
    """Run jobs in this process, one after the other (``--workers 1``).

    Parameters
    ----------
    spec : WorkerSpec
        The campaign.
    jobs : sequence of Job
        The runs.
    done : callable
        Called with each :class:`RunRecord` as it finishes.
    keep : bool
        Keep the built blocks for the next call (a pool of one); they are released on an
        error or a Ctrl-C, and by :func:`release_worker_state`.
    """
    with _interrupts_outside_fmus():
        try:
            for job in jobs:
                record = run_one(spec, job)
                _raise_pending()
                done(record)
        except BaseException:
            release_worker_state()
            raise
        if not keep:
            release_worker_state()


#: Ctrl-C noted while an FMU's own Python code ran, raised after the macro step.
_PENDING: list[int] = []


def _raise_pending(row: Any = None) -> None:
    if _PENDING:
        _PENDING.clear()
        raise KeyboardInterrupt


class _CtrlC(Observer):
    """Raises a Ctrl-C noted in FMU code (:func:`_interrupts_outside_fmus`) after the step."""

    def after_step(self, n: int, t: float) -> object:
        if _PENDING:
            _PENDING.clear()
            raise KeyboardInterrupt
        return None


def _in_fmu_code(frame: Any) -> bool:
    """Whether Python code runs inside a call into an FMU.

    That is, below a frame of an FMU host (:class:`cosim.blocks.FmuHost`, which may call
    the FMU's C functions directly: a PythonFMU's model code then runs with the host's
    frame as its caller) or below fmpy's Python wrappers; not in the host's or fmpy's
    own code between two calls.
    """

    def fmpy(f: Any) -> bool:
        return f"{os.sep}fmpy{os.sep}" in f.f_code.co_filename

    def host(f: Any) -> bool:
        return f.f_code.co_filename == _BLOCKS_FILE and isinstance(f.f_locals.get("self"), FmuHost)

    if frame is None or fmpy(frame) or host(frame):
        return False
    f = frame.f_back
    while f is not None:
        if fmpy(f) or host(f):
            return True
        f = f.f_back
    return False


@contextlib.contextmanager
def _interrupts_outside_fmus() -> Any:
    """Raise a Ctrl-C in this process's runs outside FMU code only.

    The KeyboardInterrupt of a Ctrl-C is raised wherever the main thread runs Python
    code, also inside an FMU made with PythonFMU (its model runs in this interpreter).
    That FMU reports it as a fatal fmi2DoStep (the run would be recorded as failed and
    the campaign would go on) and its instance is left broken: freeing it, or collecting
    its objects later, crashes the process. A Ctrl-C that lands in FMU code is therefore
    only noted, and raised when the master records its next row (or the run ends).
    """
    if threading.current_thread() is not threading.main_thread() or (
        signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return

    def on_sigint(signum: int, frame: Any) -> None:
        if _in_fmu_code(frame):
            _PENDING.append(signum)
            return
        raise KeyboardInterrupt

    _PENDING.clear()
    signal.signal(signal.SIGINT, on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        _PENDING.clear()


def crashed_record(
    spec: WorkerSpec, job: Job, error: str, worker: str = "", t_end: float = float("nan")
) -> RunRecord:
    """The record of a run whose worker process died (no metric, no history).

    Parameters
    ----------
    spec : WorkerSpec
        The campaign (its requirements get no metric).
    job : Job
        The run.
    error : str
        How the worker died, and where (block, time) when known.
    worker : str
        ``host:pid`` of the (last) process that died running it.
    t_end : float
        The simulated time of the death [s], when known.

    Returns
    -------
    RunRecord
        ``status = "crashed"``.
    """
    return RunRecord(
        index=job.index,
        seeds=dict(job.seeds),
        status="crashed",
        error=error,
        metrics={r.id: None for r in spec.requirements},
        worker=worker,
        t_end=t_end,
        tag=job.tag,
    )
