"""Runs that survive a block killing its process (``run --isolate``, campaign workers).

An FMU is native code in the simulating process: an ``abort()``, a segmentation fault or
an ``exit()`` in it ends that process, with no Python exception to catch. Two things
make such a death a failed run instead of a lost one:

- :class:`StepBoard`, a small block of memory shared with the parent process, where the
  simulating process notes what it is doing before each block call
  (:class:`BoardObserver`, an observer of the master):
  loading the blocks, initialising block *b*, stepping block *b* from *t* (the note
  stays until the next block call: reading *b*'s outputs counts as its step). A parent
  that sees its child die reads the last note (:func:`describe_death`): the block and
  time of the crash, the signal or exit code.
- :func:`run_isolated`: the whole run (loading the FMUs included) in a child process
  that streams every recorded row to the parent as soon as the recorder writes it
  (:class:`cosim.recording.Recorder`, ``on_row``; the run made by
  :func:`cosim.runs.make_run`). When the child dies the parent still
  has every row recorded before the crash and raises :class:`IsolatedRunError` with the
  partial result, the block, the time and the signal (``ins-cosim run`` writes the
  partial results and exits with 4, as for any failed run).

This is what FMPy's remoting and OSP's proxy-fmu do per FMU; here the unit of isolation
is the whole run (one process boundary, rows sent once per recorded time, not one
round trip per FMI call). Text (String, Binary) columns of a crashed run's partial
results are empty.
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import multiprocessing
import pickle
import signal
import struct
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import SimulationError, UserError
from cosim.observers import Observer
from cosim.results import RunResult

__all__ = [
    "BoardObserver",
    "IsolatedRunError",
    "StepBoard",
    "describe_death",
    "describe_exit",
    "run_isolated",
]

#: What the simulating process was doing (the first field of the board).
IDLE, LOADING, INITIALISING, STEPPING = range(4)
_HEAD = struct.Struct("<iid")  # phase, block index, time [s]
_NAMES_AT = 32  # the block names (JSON, length-prefixed) follow the head


class StepBoard:
    """What a process is doing, in memory its parent can read after the process died.

    Parameters
    ----------
    raw : ctypes array of char
        Shared memory of :attr:`SIZE` bytes (:meth:`shared`), passed to the child at
        its start.
    """

    SIZE = 1 << 16

    def __init__(self, raw: Any) -> None:
        self.raw = raw
        self.view = memoryview(raw).cast("B")

    @classmethod
    def shared(cls, ctx: Any = None) -> StepBoard:
        """A new board in shared memory.

        Parameters
        ----------
        ctx : multiprocessing context, optional
            The context of the processes that will share it.

        Returns
        -------
        StepBoard
        """
        ctx = ctx or multiprocessing.get_context()
        return cls(ctx.RawArray(ctypes.c_char, cls.SIZE))

    def post(self, phase: int, block: int = -1, time: float = float("nan")) -> None:
        """Note what this process does now.

        Parameters
        ----------
        phase : int
            :data:`IDLE`, :data:`LOADING`, :data:`INITIALISING` or :data:`STEPPING`.
        block : int
            Index of the block in :meth:`names` (-1: none).
        time : float
            Simulated time [s]: the step's start (stepping) or the start time
            (initialising).
        """
        _HEAD.pack_into(self.view, 0, phase, block, time)

    def set_names(self, names: list[str]) -> None:
        """Write the block names that :meth:`post` indexes.

        Parameters
        ----------
        names : list of str
            Block names in the order of their indices (cut to what fits the board).
        """
        data = json.dumps(names).encode()
        room = self.SIZE - _NAMES_AT - 4
        while len(data) > room and names:
            names = names[: len(names) // 2]
            data = json.dumps(names).encode()
        struct.pack_into("<i", self.view, _NAMES_AT, len(data))
        self.view[_NAMES_AT + 4 : _NAMES_AT + 4 + len(data)] = data

    def read(self) -> tuple[int, str | None, float]:
        """The last note: ``(phase, block name or None, time [s])``.

        Returns
        -------
        tuple
            Phase, the block's name (None when unknown), simulated time [s] (nan).
        """
        phase, block, time = _HEAD.unpack_from(self.view, 0)
        (size,) = struct.unpack_from("<i", self.view, _NAMES_AT)
        names: list[str] = []
        if 0 < size <= self.SIZE - _NAMES_AT - 4:
            with contextlib.suppress(ValueError, UnicodeDecodeError):
                names = json.loads(bytes(self.view[_NAMES_AT + 4 : _NAMES_AT + 4 + size]))
        name = names[block] if 0 <= block < len(names) else None
        return phase, name, time


class BoardObserver(Observer):
    """Notes every block call of a run on a :class:`StepBoard`, before the call.

    An observer of the master (:mod:`cosim.observers`): its ``before_block`` packs
    (phase, block, time) into the board, about 0.3 µs per block step, a few % of the
    demo's in-process blocks (10 µs a step), less for FMUs. The note stays until the next
    block call: reading a block's outputs counts as its step.

    Parameters
    ----------
    board : StepBoard
        Where to note.
    """

    def __init__(self, board: StepBoard) -> None:
        self.board = board
        self.pack, self.view = _HEAD.pack_into, board.view

    def on_start(self, master: Any, t0: float) -> None:
        self.board.set_names(list(master.order))  # before_block's indices

    def before_block(self, i: int, t: float, initialising: bool) -> None:
        self.pack(self.view, 0, INITIALISING if initialising else STEPPING, i, t)


def describe_exit(exitcode: int | None) -> str:
    """How a process ended, in words.

    Parameters
    ----------
    exitcode : int or None
        :attr:`multiprocessing.Process.exitcode` (negative: the signal that killed it).

    Returns
    -------
    str
        ``"killed by signal SIGABRT (6)"`` or ``"exited with code 3"``.
    """
    if exitcode is None:
        return "ended without an exit code"
    if exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = "signal"
        return f"killed by signal {name} ({-exitcode})"
    return f"exited with code {exitcode}"


def describe_death(board: StepBoard) -> tuple[str, str | None, float]:
    """Where a process was when it died, from its board.

    Parameters
    ----------
    board : StepBoard
        The board the dead process noted on.

    Returns
    -------
    tuple
        ``(text, block or None, time [s] or nan)``: the text reads
        ``"while block 'imu' was stepping from t = 12.3 s"``.
    """
    phase, block, t = board.read()
    name = f"block '{block}'" if block else "a block"
    if phase == STEPPING:
        return f"while {name} was stepping from t = {t:.6g} s", block, t
    if phase == INITIALISING:
        return f"while {name} was initialising at t = {t:.6g} s", block, t
    if phase == LOADING:
        return "while loading the blocks", None, float("nan")
    return "between runs", None, float("nan")


class IsolatedRunError(SimulationError):
    """An isolated run failed or its process died; :attr:`result` holds what it recorded.

    Parameters
    ----------
    text : str
        The full message.
    block : str or None
        The block concerned, when known.
    time : float
        Simulated time of the failure [s] (nan when unknown).
    result : RunResult or None
        The rows recorded up to the failure.
    crash : dict, optional
        For a dead process: ``exit_code``, ``how`` (the signal or exit code in words),
        ``block``, ``time``.
    """

    def __init__(
        self,
        text: str,
        block: str | None,
        time: float,
        result: RunResult | None = None,
        crash: dict[str, Any] | None = None,
    ) -> None:
        self.block, self.time, self.variable, self.call = block, time, None, None
        self.result, self.crash = result, crash
        Exception.__init__(self, text)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
    print(f"warning: {message}", file=sys.stderr, flush=True)


def _send(conn: Any, *message: Any) -> None:
    conn.send_bytes(b"P" + pickle.dumps(message))


def _child(
    conn: Any,
    raw: Any,
    scenario: str,
    fmu_dir: str | None,
    overrides: dict[str, Any],
    check: Callable[[Any, Any], None] | None,
    loader: Callable[[str], Any] | None = None,
) -> None:
    """The isolated process: build, check, run, stream the rows, send the result."""
    from cosim.runs import Assembly, assemble, make_run
    from cosim.scenario import load_scenario

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's business
    warnings.showwarning = _show_warning
    board = StepBoard(raw)
    board.post(LOADING)
    send = conn.send_bytes

    def on_row(row: np.ndarray) -> None:
        send(b"R" + row.tobytes())

    def started(assembly: Assembly) -> None:
        if check is not None:
            check(assembly.scenario, assembly.master)
        s, rec = assembly.master.settings, assembly.recorder
        meta = dict(assembly.master.metadata, types=rec.types)
        info = {"name": sc.name, "blocks": len(assembly.master.system.blocks)}
        info.update(n_steps=s.n_steps, step=s.step, coupling=s.coupling)
        info.update(names=rec.names, metadata=meta)
        _send(conn, "started", info)

    try:
        sc = (loader or load_scenario)(scenario)
        assembly = assemble(sc, fmu_dir=fmu_dir, on_row=on_row, **overrides)
    except UserError as exc:
        _send(conn, "error", str(exc), exc.exit_code)
        return
    try:  # the blocks are terminated after the parent has the outcome
        try:
            result = make_run(assembly, observers=[BoardObserver(board)], before=started)
        except SimulationError as exc:
            _send(conn, "failed", str(exc), exc.block, exc.time, exc.result)
            return
        except UserError as exc:  # the check refused the scenario: nothing ran
            _send(conn, "error", str(exc), exc.exit_code)
            return
        board.post(IDLE)
        _send(conn, "done", result)
    finally:
        assembly.close()


def run_isolated(
    scenario: str | Path,
    *,
    fmu_dir: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
    check: Callable[[Any, Any], None] | None = None,
    started: Callable[[dict[str, Any]], None] | None = None,
    loader: Callable[[str], Any] | None = None,
) -> RunResult:
    """Run a scenario once in a child process that may die without taking this one along.

    Parameters
    ----------
    scenario : str or Path
        The scenario file.
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    overrides : dict, optional
        Master settings replacing the scenario's (``stop`` [s], ...).
    check : callable, optional
        ``check(scenario, master)`` run in the child after the build, before the run (a
        module-level function: it is pickled); raises a UserError to refuse.
    started : callable, optional
        Called here with ``name``, ``blocks``, ``n_steps``, ``step`` [s], ``coupling``
        once the child has built the blocks.
    loader : callable, optional
        ``loader(path)`` reads the scenario in the child (a module-level function: it is
        pickled); default :func:`cosim.scenario.load_scenario` (``.toml`` files).

    Returns
    -------
    RunResult
        The recording, as :meth:`cosim.master.Master.run` returns it.

    Raises
    ------
    UserError
        The child refused the scenario (the message and exit code it gave).
    IsolatedRunError
        The run failed (a block error, a non-finite output) or the child died (a
        signal, an exit code); ``result`` holds every row recorded up to then.
    KeyboardInterrupt
        Ctrl-C: the child is stopped.
    """
    ctx = multiprocessing.get_context("spawn")
    board = StepBoard.shared(ctx)
    receive, give = ctx.Pipe(duplex=False)
    fmu = None if fmu_dir is None else str(Path(fmu_dir).resolve())
    proc = ctx.Process(
        target=_child,
        args=(
            give,
            board.raw,
            str(Path(scenario).resolve()),
            fmu,
            dict(overrides or {}),
            check,
            loader,
        ),
        daemon=True,
        name="ins-cosim-isolated-run",
    )
    proc.start()
    give.close()
    rows: list[bytes] = []
    info: dict[str, Any] = {}
    final: tuple[Any, ...] | None = None
    try:
        while final is None:
            try:
                msg = receive.recv_bytes()
            except EOFError:
                break
            if msg[:1] == b"R":
                rows.append(msg[1:])
                continue
            kind, *rest = pickle.loads(msg[1:])
            if kind == "started":
                info = rest[0]
                if started is not None:
                    started(info)
            else:
                final = (kind, *rest)
    except BaseException:
        proc.terminate()
        proc.join(10)
        raise
    finally:
        receive.close()
    proc.join(30)
    if proc.is_alive():  # pragma: no cover - a child that sent its result ends at once
        proc.kill()
        proc.join()
    if final is not None and final[0] == "done":
        return final[1]
    if final is not None and final[0] == "error":
        err = UserError(final[1])
        err.exit_code = final[2]
        raise err
    if final is not None:  # "failed": a block error, relayed
        _kind, text, block, time, result = final
        raise IsolatedRunError(text, block, time, result)
    # the child died
    how = describe_exit(proc.exitcode)
    where, block, time = describe_death(board)
    names = info.get("names", ["time"])
    data = np.frombuffer(b"".join(rows), dtype=[(n, "f8") for n in names]).copy()
    kept = (
        f"; {len(data)} row(s) recorded up to t = {data['time'][-1]:.6g} s are kept"
        if len(data)
        else ""
    )
    text = f"the isolated simulation process (pid {proc.pid}) {how} {where}{kept}"
    crash = {"exit_code": proc.exitcode, "how": how, "block": block, "time": time}
    meta = dict(info.get("metadata", {}), crashed=crash, isolated=True)
    result = RunResult(data, meta, status="failed", error=text)
    raise IsolatedRunError(text, block, time, result, crash)
