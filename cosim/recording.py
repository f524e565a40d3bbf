"""The recording of a run: an observer of the master that writes the rows of its result.

:class:`Recorder` watches :meth:`cosim.master.Master.execute` (:mod:`cosim.observers`):
it allocates the whole recording when the run starts (rows ``n_steps // record_every +
1``, ``time`` first, then every recorded variable), writes a row after the
initialisation and after every ``record_every``-th macro step, and one more at an early
end (a block or an observer ended the run), and makes the :class:`~cosim.results.RunResult`
with its metadata. After a failure its result holds the rows recorded before it.

Real columns are copied from the master's value table (one slice copy per row when the
recorded outputs are consecutive in it, the usual case); Integer, Boolean, Enumeration,
FMI 3 number and String/Binary columns are read from their blocks when a row is written
(they hold between steps like everything else; text columns hold NaN, their text is in
``RunResult.strings``).

:func:`record_run` is a run with the standard observers: the finiteness check, the
recorder, then the caller's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from cosim.errors import ScenarioError, SimulationError
from cosim.observers import Ending, FinitenessCheck, Observer
from cosim.results import RunResult
from cosim.variables import REAL

__all__ = ["MAX_RECORDING_BYTES", "Recorder", "record_run", "recorded_columns"]

#: The largest recording a run may keep in memory [bytes] (refused when the recording is
#: planned, before any run): rows (``n_steps // record_every + 1``) x columns (``time`` and
#: every recorded variable) x 8 bytes.
MAX_RECORDING_BYTES = 2 * 2**30


def recorded_columns(system: Any) -> list[tuple[str, str]]:
    """What a run of ``system`` records: ``system.record``, else every output.

    Parameters
    ----------
    system : cosim.master.System
        Blocks and what to record.

    Returns
    -------
    list of (str, str)
        ``(block, scalar output)`` per column after ``time``.
    """
    if system.record is not None:
        return list(system.record)
    return [(b, v.name) for b in system.blocks for v in system.blocks[b].by_causality("output")]


class Recorder(Observer):
    """Records a run of ``master`` (see the module docstring); checks its size when made.

    Parameters
    ----------
    master : cosim.master.Master
        The master it will watch (its system, settings and metadata).
    on_row : callable, optional
        Called with each row as soon as it is written: a float64 view, shape (1 +
        recorded columns,), time [s] first, then the columns in SI units (text columns
        NaN); copy it to keep it (:mod:`cosim.isolate` streams the rows of an isolated
        run to its parent this way).

    Attributes
    ----------
    record : list of (str, str)
        The recorded ``(block, output)`` pairs.
    names : list of str
        Column names, ``time`` first.
    types : dict
        Column name -> FMI type of every recorded variable.

    Raises
    ------
    ScenarioError
        The recording would exceed :data:`MAX_RECORDING_BYTES` (key ``output.every``).
    """

    def __init__(self, master: Any, on_row: Callable[[np.ndarray], None] | None = None) -> None:
        sys_ = master.system
        self.master = master
        self.on_row = on_row
        self.record = recorded_columns(sys_)
        self.names = ["time"] + [f"{b}.{v}" for b, v in self.record]
        self.types = {f"{b}.{v}": sys_.blocks[b].variables[v].type for b, v in self.record}
        s = master.settings
        rows, columns = s.n_steps // s.record_every + 1, len(self.record) + 1
        if rows * columns * 8 > MAX_RECORDING_BYTES:
            raise ScenarioError(
                f"the recording would hold {rows} rows x {columns} columns = "
                f"{rows * columns * 8 / 2**30:.3g} GiB, more than the limit of "
                f"{MAX_RECORDING_BYTES / 2**30:g} GiB; record less often (output.every), "
                f"fewer variables (output.variables) or a shorter run (master.stop)",
                key="output.every",
            )
        self.n_rows = rows
        # Real columns come from the value table, the others from their blocks; columns
        # are 1-based (0 is the time)
        real = [
            (i, r)
            for i, r in enumerate(self.record, start=1)
            if sys_.blocks[r[0]].variables[r[1]].type == REAL
        ]
        self._real_cols = np.array([i for i, _r in real], dtype=int)
        self._real_slots = np.array([master.slots[r] for _i, r in real], dtype=int)
        typed: dict[tuple[str, str], list[tuple[int, int, str]]] = {}
        for i, (b, v) in enumerate(self.record, start=1):
            var = sys_.blocks[b].variables[v]
            if var.type != REAL:
                typed.setdefault((b, var.type), []).append((i, var.vr, f"{b}.{v}"))
        self._typed = [
            (
                sys_.blocks[b],
                vtype,
                [vr for _i, vr, _n in items],
                [i for i, _vr, _n in items],
                [n for *_x, n in items],
            )
            for (b, vtype), items in typed.items()
        ]
        self.data = np.zeros(0, dtype=[(n, "f8") for n in self.names])
        self.strings: dict[str, list[str]] = {}
        self.rows = 0
        self.ending: Ending | None = None

    def on_start(self, master: Any, t0: float) -> None:
        # allocate the recording and bind the row writer to this run's value table
        values = master.values
        every = master.settings.record_every
        self.data = data = np.zeros(self.n_rows, dtype=[(n, "f8") for n in self.names])
        self.rows = 0
        self.ending = None
        # the recording as a plain (rows, columns) float view of the structured array
        table = data.view(np.float64).reshape(self.n_rows, len(self.names))
        real_slots, typed, on_row = self._real_slots, self._typed, self.on_row
        cols = _as_slice(self._real_cols)
        part = _as_slice(real_slots)
        source = values[part] if isinstance(part, slice) else None  # a view: no gather
        strings: dict[str, list[str]] = {
            n: [] for _h, vtype, _v, _c, ns in typed if vtype in ("String", "Binary") for n in ns
        }
        self.strings = strings

        def write(t: float) -> None:
            line = table[self.rows]
            line[0] = t
            line[cols] = values[real_slots] if source is None else source
            for host, vtype, vrs, tcols, ns in typed:
                got = host.get_values(vtype, vrs)
                if vtype in ("String", "Binary"):  # text columns: NaN here, text in the CSV
                    for n, x in zip(ns, got, strict=True):
                        if isinstance(x, bytes):  # Binary as hex digits; FMI 2 strings as bytes
                            x = x.hex() if vtype == "Binary" else x.decode("utf-8", "replace")
                        strings[n].append(str(x))
                    line[tcols] = np.nan
                else:  # Integer, Boolean, Enumeration, FMI 3 numbers: exact up to 2**53
                    line[tcols] = [float(x) for x in got]
            self.rows += 1
            if on_row is not None:
                on_row(line)

        if not typed and on_row is None and source is not None:

            def write(t: float) -> None:  # noqa: F811 (the usual case, leaner)
                line = table[self.rows]
                line[0] = t
                line[cols] = source
                self.rows += 1

        self.write = write

        def after_step(n: int, t: float) -> None:
            if (n + 1) % every == 0:
                write(t)

        self.after_step = after_step  # type: ignore[method-assign]  # bound per run

    def after_step(self, n: int, t: float) -> object:
        # a row after every record_every-th macro step: bound per run by on_start
        return None

    def on_stop(self, ending: Ending) -> None:
        # keep how the run ended; after an early end, record the last values
        self.ending = ending
        if ending.terminated is not None:
            self.write(ending.time)
        elif ending.stopped is not None and (
            self.rows == 0 or self.data["time"][self.rows - 1] != ending.time
        ):
            self.write(ending.time)

    def result(self) -> RunResult:
        """The recording so far, with the run's metadata.

        Returns
        -------
        RunResult
            ``status`` ``"completed"`` or ``"failed"`` (with the error's text); the
            metadata holds the master's settings, stepping order, delayed connections,
            rates, the seeds in force, the columns' types, and ``terminated`` or
            ``stopped`` after an early end.
        """
        master = self.master
        s, sys_ = master.settings, master.system
        ending = self.ending
        meta = dict(master.metadata)
        meta["types"] = self.types
        if ending is not None and ending.terminated is not None:  # not a failure
            meta["terminated"] = ending.terminated
        if ending is not None and ending.stopped is not None:
            meta["stopped"] = ending.stopped
        # the seeds in force for this run (campaigns change them between runs)
        meta["seeds"] = {b: p["seed"] for b, p in sys_.parameters.items() if "seed" in p}
        meta["master"] = {
            "step": s.step,
            "start": s.start,
            "stop": s.stop,
            "coupling": s.coupling,
            "clock": s.clock,
            "record_every": s.record_every,
            "order": master.order,
            "delayed": [str(c) for c in master.delayed],
            "rates": dict(zip(master.order, master.rates, strict=True)),
        }
        texts = {n: list(x) for n, x in self.strings.items()}
        failed = ending is not None and ending.status == "failed"
        error = ""
        if ending is not None and failed and ending.error is not None:
            error = str(ending.error)
        status = "failed" if failed else "completed"
        data = self.data[: self.rows].copy()
        return RunResult(data, meta, status=status, error=error, strings=texts)


def record_run(
    master: Any,
    on_row: Callable[[np.ndarray], None] | None = None,
    observers: Sequence[Any] = (),
    recorder: Recorder | None = None,
) -> RunResult:
    """Run ``master`` with the finiteness check, a :class:`Recorder` and ``observers``.

    Parameters
    ----------
    master : cosim.master.Master
        Built (and reset, if it ran before).
    on_row : callable, optional
        The recorder's ``on_row``.
    observers : sequence, optional
        More observers, after the check and the recorder.
    recorder : Recorder, optional
        The recorder, made by the caller (its names and types known before the run);
        ``on_row`` is then its own.

    Returns
    -------
    RunResult
        The recording.

    Raises
    ------
    SimulationError
        A block failed, or an output was not finite; ``error.result`` holds the rows
        recorded before.
    """
    recorder = recorder if recorder is not None else Recorder(master, on_row)
    try:
        master.execute([FinitenessCheck(), recorder, *observers])
    except SimulationError as err:
        err.result = recorder.result()
        raise
    return recorder.result()


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice when it is consecutive (a view instead of a copy), else itself."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index
