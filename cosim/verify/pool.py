"""Local worker processes that start once and stay: the engine's pool.

A :class:`WorkerPool` of ``n`` processes runs the jobs of one campaign after another.
Each process is forked from a ``forkserver`` that imported the simulation code once
(where the platform has no ``forkserver``: spawned), builds the campaign's blocks when
it starts (:func:`cosim.verify.workers.build_worker`), then runs one job at a time, sent
to it through its own pipe, resetting the blocks between runs
(:func:`cosim.verify.workers.run_one`). The processes and their built blocks stay from
one :meth:`WorkerPool.run` to the next while the campaign (:class:`WorkerSpec`) is the
same: the looks of ``verify --until-decided`` run on the processes of its first look.
A run's numbers depend only on its job, so they are the same bit for bit whichever
process ran it and whatever it ran before.

A worker process that dies (an FMU calling ``abort()``, a segmentation fault, a model
calling ``os._exit``, the kernel's OOM killer) loses only the run it was running: the
parent sees its pipe close, reads what the process last noted on its
:class:`cosim.isolate.StepBoard` (the block that was stepping, the time), starts a
fresh process in its place and runs that run again first. A run whose worker dies
:data:`CRASH_ATTEMPTS` times is recorded as ``"crashed"`` (its seeds, the signal or exit
code, the block and time), a failed run for the requirements' ``on_failure``, and the
campaign goes on.

A worker never outlives its campaign's process: on Linux the kernel sends it SIGTERM
when the forkserver that forked it ends (``PR_SET_PDEATHSIG``; the forkserver ends when
the campaign's process does, however it died), and a thread of the worker checks every
:data:`ORPHAN_POLL` seconds that the campaign's process and its own parent are still
there; when not, it sends itself SIGTERM (the run unwinds, its FMUs are freed) and, if it
is still there :data:`ORPHAN_GRACE` seconds later (held in native code, SIGTERM
blocked), SIGKILL.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import gc
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import Any

from cosim.isolate import IDLE, LOADING, StepBoard, describe_death, describe_exit
from cosim.verify.records import RunRecord
from cosim.verify.workers import (
    CampaignError,
    Job,
    WorkerSpec,
    build_worker,
    crashed_record,
    release_worker_state,
    run_here,
    run_one,
)

__all__ = [
    "CRASH_ATTEMPTS",
    "WorkerPool",
    "die_with",
    "keeps_workers",
    "pool_context",
    "start_forkserver",
]

#: Modules the forkserver imports once, so that forked workers start without imports.
PRELOAD = ["cosim.verify.workers", "cosim.verify.pool", "cosim.alignment", "cosim.models"]
#: Imported last by the forkserver: the built-in blocks' identities, cached for every worker.
PRELOAD_LAST = "cosim.verify.preload"
#: A run whose worker process dies this many times is recorded as crashed.
CRASH_ATTEMPTS = 2
#: Worker processes that may die before they are ready (building the blocks) in a row.
MAX_START_FAILURES = 3
#: Seconds between a worker's checks that its campaign's process is still there.
ORPHAN_POLL = 0.5
#: Seconds an orphaned worker gives its own unwinding (SIGTERM) before SIGKILL.
ORPHAN_GRACE = 5.0
_PR_SET_PDEATHSIG = 1  # linux/prctl.h
#: Threads of the numerical libraries in each worker, unless the environment sets them:
#: one (the pool's processes are the parallelism; two workers' BLAS threads on two
#: cores only took CPU from each other, 5-8 % per run).
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def pool_context() -> multiprocessing.context.BaseContext:
    """The start method of local workers: a preloaded forkserver, else spawn.

    The forkserver starts with the first pool of this process (:func:`start_forkserver`)
    and imports the simulation code once: :data:`PRELOAD`, every module of ``models`` and
    ``cosim.alignment`` (the built-in blocks) and whatever this process has loaded from
    ``cosim`` and ``models`` by then, then :mod:`cosim.verify.preload` (the built-in
    blocks' identities); every worker is forked from it, with no imports of its own (a
    block from another package is imported by each worker).

    Returns
    -------
    multiprocessing context
    """
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        loaded = {m for m in sys.modules if m.split(".")[0] == "cosim"}
        rest = sorted((loaded | _builtin_blocks()) - {*PRELOAD, PRELOAD_LAST})
        ctx.set_forkserver_preload([*PRELOAD, *rest, PRELOAD_LAST])
        return ctx
    return multiprocessing.get_context("spawn")


def _builtin_blocks() -> set[str]:
    import pkgutil

    import cosim.alignment
    from cosim import models

    return {
        f"{package.__name__}.{info.name}"
        for package in (models, cosim.alignment)
        for info in pkgutil.iter_modules(package.__path__)
    }


@contextlib.contextmanager
def _one_thread_each() -> Any:
    """:data:`ONE_THREAD` in the environment of the processes started meanwhile."""
    added = {k: v for k, v in ONE_THREAD.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


def start_forkserver() -> None:
    """Start this process's forkserver now, if it does not run (it imports on its own).

    A pool calls it when it is made, so that the forkserver imports the simulation code
    on another core while this process checks the scenario; the first worker forked
    from it waits until it is done. The forkserver, hence every worker, runs numpy's BLAS
    on one thread (:data:`ONE_THREAD`, unless this process's environment sets it). Nothing
    where the platform has no forkserver.
    """
    if "forkserver" in multiprocessing.get_all_start_methods():
        pool_context()
        from multiprocessing import forkserver

        with _one_thread_each():  # the forkserver's environment is its workers'
            forkserver.ensure_running()


def die_with(campaign: int) -> None:
    """End this process when the process ``campaign`` or this process's parent ends.

    On Linux the kernel sends SIGTERM when the parent ends (``PR_SET_PDEATHSIG``); a
    daemon thread also checks every :data:`ORPHAN_POLL` s that ``campaign`` exists and
    that the parent is the one this process started with. When either is gone it sends
    SIGTERM to this process, then SIGKILL :data:`ORPHAN_GRACE` s later.

    Parameters
    ----------
    campaign : int
        Process id of the campaign (the process that owns the pool).
    """
    parent = os.getppid()
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):  # best effort: the thread below still runs
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)

    def gone() -> bool:
        if os.getppid() != parent:  # re-parented: the forkserver (or spawning parent) died
            return True
        try:
            os.kill(campaign, 0)
        except ProcessLookupError:
            return True
        except PermissionError:  # exists, owned by someone else (not ours, but there)
            return False
        return False

    def watch() -> None:
        while not gone():  # checked at once too: the parent may be gone before prctl
            time.sleep(ORPHAN_POLL)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(ORPHAN_GRACE)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="ins-cosim-orphan-watch", daemon=True).start()


def _exit_on_terminate(signum: int, frame: Any) -> None:
    raise SystemExit(128 + signum)  # unwinds: the blocks are terminated, folders removed


def _picklable(exc: BaseException) -> BaseException:
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return CampaignError(f"{type(exc).__name__}: {exc}")


def _worker_main(spec: WorkerSpec, conn: Any, raw: Any, campaign: int) -> None:
    """A local worker process: build the blocks, then run the jobs the parent sends.

    Messages to the parent: ``("ready",)`` once built, ``("done", record)`` per job,
    ``("error", exception)`` when it cannot go on; a job of None ends the process.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's business
    signal.signal(signal.SIGTERM, _exit_on_terminate)
    die_with(campaign)
    board = StepBoard(raw)
    board.post(LOADING)
    try:
        try:
            build_worker(spec, board)
        except Exception as exc:
            conn.send(("error", _picklable(exc)))
            return
        # what the process holds now (the preloaded code, the blocks) stays for its life:
        # out of the garbage collector's sight, whose full passes walked it in every run
        # (2-4 ms of a 0.16 s transfer-alignment run; 0.7 ms after this)
        gc.freeze()
        board.post(IDLE)
        conn.send(("ready",))
        while True:
            try:
                job = conn.recv()
            except EOFError:  # the parent is gone
                return
            if job is None:
                return
            try:
                record = run_one(spec, job)
            except Exception as exc:  # a scenario that changed on disk, or a bug
                conn.send(("error", _picklable(exc)))
                return
            board.post(IDLE)
            conn.send(("done", record))
    finally:
        release_worker_state()


class _Process:
    """One local worker process, its pipe and its board, and the job it runs."""

    def __init__(self, ctx: Any, spec: WorkerSpec) -> None:
        self.board = StepBoard.shared(ctx)
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(
            target=_worker_main, args=(spec, child, self.board.raw, os.getpid()), daemon=True
        )
        self.born = time.perf_counter()
        with _one_thread_each():  # for spawned workers (forked ones have the forkserver's)
            self.proc.start()
        child.close()
        self.ready = False
        self.job: Job | None = None

    def give(self, job: Job) -> None:
        self.job = job
        self.conn.send(job)

    def receive(self) -> tuple[Any, ...] | None:
        """The next message, or None when the process has died (its pipe closed)."""
        try:
            if self.conn.poll():
                return self.conn.recv()
        except (EOFError, OSError):
            pass
        if self.proc.is_alive():
            return ("nothing",)
        return None

    def death(self) -> tuple[str, str, float]:
        """``(how, where, time)``: the signal or exit code, the block and time noted."""
        self.proc.join(5)
        with contextlib.suppress(Exception):
            self.conn.close()
        where, _block, t = describe_death(self.board)
        return describe_exit(self.proc.exitcode), where, t

    def stop(self, wait: float) -> None:
        with contextlib.suppress(Exception):
            if self.proc.is_alive():
                if wait:
                    self.conn.send(None)
                else:
                    self.proc.terminate()  # SIGTERM: it unwinds and frees its blocks
                self.proc.join(wait or 5)
            if self.proc.is_alive():
                self.proc.kill()
                self.proc.join(5)
        with contextlib.suppress(Exception):
            self.conn.close()


class WorkerPool:
    """Local worker processes kept across the runs of a campaign and across campaigns.

    Use it as a context manager (or call :meth:`close`). ``workers == 1`` runs the jobs
    in this process, keeping the built blocks between calls as well; a call with a single
    job while the pool has no process runs it in this process too (without keeping its
    blocks). A campaign with :attr:`WorkerSpec.isolate` (a foreign FMU) always runs in
    worker processes, one with ``workers == 1``. Making a pool of more than one starts
    this process's forkserver (:func:`start_forkserver`).

    Parameters
    ----------
    workers : int
        Processes (1: this process).

    Raises
    ------
    CampaignError
        ``workers < 1``.
    """

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise CampaignError(f"--workers must be >= 1, got {workers}")
        self.workers = int(workers)
        self.started = 0  # processes started over the pool's life (replacements included)
        #: Wall time [s] each process took from its start to ready (blocks built).
        self.ready_times: list[float] = []
        self._procs: list[_Process] = []
        self._spec: WorkerSpec | None = None
        self._here = False
        if self.workers > 1:
            start_forkserver()  # it imports while the caller checks the scenario

    @property
    def pids(self) -> list[int]:
        """Process ids of the live worker processes (empty for a pool of one).

        Returns
        -------
        list of int
        """
        return [p.proc.pid for p in self._procs if p.proc.pid is not None]

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop the processes (each finishes nothing: it is idle) and free the blocks."""
        self._stop_all(30)
        if self._here:
            release_worker_state()
            self._here = False

    def _stop_all(self, wait: float) -> None:
        procs, self._procs = self._procs, []
        for p in procs:
            p.stop(wait)

    def _start(self, ctx: Any, spec: WorkerSpec) -> _Process:
        self.started += 1
        return _Process(ctx, spec)

    def run(self, spec: WorkerSpec, jobs: Sequence[Job], done: Callable[[RunRecord], None]) -> None:
        """Run jobs and hand each finished record to ``done`` (in completion order).

        The processes stay for the next call; a call with another campaign (``spec``)
        replaces them. On an error or a Ctrl-C the processes are stopped at once (the runs
        in progress are lost; the pool starts fresh ones on its next call).

        Parameters
        ----------
        spec : WorkerSpec
            The campaign.
        jobs : sequence of Job
            The runs.
        done : callable
            Called in this process with each :class:`RunRecord` as it finishes.

        Raises
        ------
        CampaignError
            Worker processes die before they can run, or cannot go on.
        """
        jobs = list(jobs)
        if not jobs:
            return
        if self.workers == 1 and not spec.isolate:
            self._here = True
            run_here(spec, jobs, done, keep=True)
            return
        if len(jobs) == 1 and not self._procs and not spec.isolate:
            run_here(spec, jobs, done)  # one run: not worth a process's start
            return
        if spec != self._spec:
            self._stop_all(30)
            self._spec = spec
        try:
            self._run(spec, jobs, done)
        except BaseException:
            # Ctrl-C or an error: stop the workers now, without waiting for the runs in
            # progress (they are not on disk and will run again on --resume).
            self._stop_all(0)
            raise

    def _run(self, spec: WorkerSpec, jobs: list[Job], done: Callable[[RunRecord], None]) -> None:
        ctx = pool_context()
        queue = list(reversed(jobs))  # pop() takes the next
        deaths: dict[int, int] = {}
        start_failures = 0
        procs = self._procs
        while len(procs) < min(self.workers, len(jobs)):
            procs.append(self._start(ctx, spec))
        while queue or any(p.job is not None for p in procs):
            for p in procs:
                if p.ready and p.job is None and queue:
                    p.give(queue.pop())
            waiting = {p.conn: p for p in procs} | {p.proc.sentinel: p for p in procs}
            for p in {waiting[x] for x in multiprocessing.connection.wait(list(waiting))}:
                msg = p.receive()
                if msg is not None and msg[0] == "nothing":
                    continue
                if msg is not None and msg[0] == "ready":
                    p.ready, start_failures = True, 0
                    self.ready_times.append(time.perf_counter() - p.born)
                elif msg is not None and msg[0] == "done":
                    # the next job first, then the saving: the worker runs while this
                    # process writes the record (it waited for it before)
                    p.job = None
                    if queue:
                        p.give(queue.pop())
                    done(msg[1])
                elif msg is not None and msg[0] == "error":
                    raise msg[1]
                else:  # the process died: replace it (if there is work left)
                    how, where, t = p.death()
                    job, pid = p.job, p.proc.pid
                    if job is None:
                        start_failures += not p.ready
                        if start_failures >= MAX_START_FAILURES:
                            raise CampaignError(
                                f"worker processes die before they can run: the last one "
                                f"(pid {pid}) {how} {where}; try --workers 1 to see why"
                            )
                    else:
                        deaths[job.index] = deaths.get(job.index, 0) + 1
                        if deaths[job.index] < CRASH_ATTEMPTS:
                            queue.append(job)  # again, first, on a fresh process
                        else:
                            text = (
                                f"the worker process (pid {pid}) {how} {where}, in each of "
                                f"{CRASH_ATTEMPTS} attempts: recorded as crashed "
                                f"(--resume --rerun-crashed runs it again)"
                            )
                            worker = f"{socket.gethostname()}:{pid}"
                            done(crashed_record(spec, job, text, worker, t))
                    if queue:
                        procs[procs.index(p)] = self._start(ctx, spec)
                    else:
                        procs.remove(p)


def keeps_workers(func: Callable[..., Any]) -> Callable[..., Any]:
    """Give every call of ``func`` one :class:`WorkerPool` for the whole call.

    The pool is passed as the keyword ``pool`` (sized by the call's ``workers``, default
    the CPU count) and closed when the call returns or raises; a call with a ``cluster``
    or its own ``pool`` is left as it is. ``verify --until-decided`` runs all its looks on
    one pool this way.

    Parameters
    ----------
    func : callable
        A function with the keywords ``workers``, ``cluster`` and ``pool``.

    Returns
    -------
    callable
        The wrapped function.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if kwargs.get("pool") is not None or kwargs.get("cluster"):
            return func(*args, **kwargs)
        workers = kwargs.get("workers")
        size = (os.cpu_count() or 1) if workers is None else workers
        with WorkerPool(size) as pool:
            return func(*args, **{**kwargs, "pool": pool})

    return wrapper
