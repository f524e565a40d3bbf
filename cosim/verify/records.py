"""What a campaign keeps of a run: :class:`RunRecord`, its files, and stacked histories.

On disk, under a report folder's ``runs/``::

    run_00042.json    one finished run: seeds, status, error, metrics per requirement
    run_00042.npz     its decimated histories: time, e_<k> and s_<k> per requirement k

Every file of a report folder is written to a temporary name in the same folder and
renamed into place (:func:`write_atomic`), so a reader never sees a half-written file.
Full recorded columns (``keep`` of :class:`cosim.verify.workers.WorkerSpec`, what the
reproductions analyse) stay in memory and are not written.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.verify.requirements import RunMetric


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
        ``"completed"``, ``"failed"`` (the run stopped: a block error or a non-finite
        output) or ``"crashed"`` (the worker process running it died twice: a signal or
        an exit code; no metric, no history).
    error : str
        The failure message (block, variable or call, time; for a crash the signal or
        exit code and the block that was stepping), else empty.
    metrics : dict
        Requirement id -> :class:`RunMetric`, or None for a failed run.
    history : dict
        ``"time"`` [s] shape (m,), ``"e_<k>"`` and ``"s_<k>"`` [unit of requirement k]
        shape (m,): the decimated error and 1-sigma (partial for a failed run).
    wall_time : float
        Seconds the run took (not part of the results' identity).
    cpu_time : float
        CPU seconds the worker spent on it (not part of the results' identity).
    worker : str
        ``host:pid`` of the process that ran it.
    t_end : float
        Last recorded time [s].
    tag : str
        The job's label (a reproduction's case name), else empty.
    columns : dict
        Full recorded columns kept for the caller (``"time"`` and ``"block.var"`` ->
        ndarray, shape (n,), in the block's unit); empty unless asked for.
    parameters : dict
        The parameters the run used, ``{block: {name: SI value}}``; empty unless full
        columns were asked for.
    consistency : dict
        Column -> ``{"consistent": bool or None, "message": str}``: the automatic check of
        every NIS/NEES output of a completed run (:func:`cosim.verify.consistency.check_run`).
    """

    index: int
    seeds: dict[str, int]
    status: str
    error: str
    metrics: dict[str, RunMetric | None]
    history: dict[str, np.ndarray] = field(default_factory=dict)
    wall_time: float = 0.0
    cpu_time: float = 0.0
    worker: str = ""
    t_end: float = math.nan
    tag: str = ""
    columns: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict, repr=False)
    consistency: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def failed(self) -> bool:
        """True when the run stopped before its end."""
        return self.status != "completed"

    def column(self, name: str) -> np.ndarray:
        """A kept column, or a vector ``"block.vec"`` stacked from ``block.vec[k]``.

        Parameters
        ----------
        name : str
            ``"time"``, ``"block.var"`` or a vector's base name.

        Returns
        -------
        ndarray, shape (n,) or (n, k)
            In the block's unit.

        Raises
        ------
        KeyError
            Not among the kept columns.
        """
        if name in self.columns:
            return self.columns[name]
        parts: list[np.ndarray] = []
        while f"{name}[{len(parts) + 1}]" in self.columns:
            parts.append(self.columns[f"{name}[{len(parts) + 1}]"])
        if not parts:
            raise KeyError(f"no kept column '{name}' (kept: {', '.join(sorted(self.columns))})")
        return np.column_stack(parts)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (no histories), non-finite numbers as strings."""
        return {
            "index": self.index,
            "seeds": self.seeds,
            "status": self.status,
            "error": self.error,
            "t_end": _num(self.t_end),
            "wall_time": self.wall_time,
            "cpu_time": self.cpu_time,
            "worker": self.worker,
            "metrics": {
                k: None
                if m is None
                else {"value": _num(m.value), "passed": m.passed, "note": m.note}
                for k, m in self.metrics.items()
            },
            **({"consistency": self.consistency} if self.consistency else {}),
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
            cpu_time=float(d.get("cpu_time", 0.0)),
            worker=d.get("worker", ""),
            t_end=float(d.get("t_end", math.nan)),
            consistency=d.get("consistency", {}),
        )


def _num(x: float) -> float | str:
    return x if math.isfinite(x) else str(x)


def run_stem(index: int) -> str:
    """File stem of run ``index`` under ``runs/`` (``run_00042``).

    Parameters
    ----------
    index : int
        Run number, 0-based.

    Returns
    -------
    str
    """
    return f"run_{index:05d}"


def write_atomic(path: Path, data: str | bytes) -> Path:
    """Write a file so that a reader sees either the old file or all of the new one.

    The data go to a temporary file in the same folder (same file system), which is
    then renamed over ``path`` (:func:`os.replace`, atomic on POSIX).

    Parameters
    ----------
    path : Path
        The file.
    data : str or bytes
        Its new content (text is written as UTF-8).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def save_record(record: RunRecord, runs_dir: Path) -> RunRecord:
    """Write ``run_<i>.npz`` then ``run_<i>.json`` (the marker of a finished run).

    Both are written to a temporary name and renamed, so an interruption never leaves
    a half-written run that :func:`read_records` would take for finished.

    Parameters
    ----------
    record : RunRecord
        The run.
    runs_dir : Path
        ``<report>/runs``.

    Returns
    -------
    RunRecord
        The run as :func:`read_records` gives it back, made from the JSON text just
        written and the histories as arrays (same dtype and values): what is not written
        is dropped (the tag, kept columns and parameters). A campaign judges the runs it
        has just saved from these instead of reading every file back.
    """
    runs_dir.mkdir(parents=True, exist_ok=True)
    stem = run_stem(record.index)
    history = {k: np.asarray(v) for k, v in record.history.items()}
    tmp = runs_dir / f".{stem}.npz.tmp"
    with open(tmp, "wb") as fh:
        np.savez(fh, **history)
    os.replace(tmp, runs_dir / f"{stem}.npz")
    text = json.dumps(record.to_dict(), indent=1)
    tmp = runs_dir / f".{stem}.json.tmp"
    tmp.write_text(text + "\n")
    os.replace(tmp, runs_dir / f"{stem}.json")
    return RunRecord.from_dict(json.loads(text), history)


def read_records(
    runs_dir: Path, runs: int | None = None, *, crashed: bool = True
) -> dict[int, RunRecord]:
    """Finished runs on disk.

    Parameters
    ----------
    runs_dir : Path
        ``<report>/runs``.
    runs : int, optional
        Only runs ``0 .. runs - 1``.
    crashed : bool
        Include the runs recorded as crashed (False: ``--resume --rerun-crashed`` runs
        them again).

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
        if not crashed and d.get("status") == "crashed":
            continue
        if runs is None or d["index"] < runs:
            out[int(d["index"])] = RunRecord.from_dict(d, history)
    return out


def decimation(n: int, points: int) -> np.ndarray:
    """Indices of at most ``points`` rows out of ``n``, evenly strided, the last included.

    Parameters
    ----------
    n : int
        Rows recorded.
    points : int
        Rows to keep (>= 2).

    Returns
    -------
    ndarray of int, shape (<= points,)
    """
    if n <= points:
        return np.arange(n)
    stride = math.ceil((n - 1) / (points - 1))
    idx = np.arange(0, n, stride)
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


@dataclass
class Histories:
    """The kept columns of a set of runs, stacked run by run.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Recorded times [s] (identical for every run).
    columns : dict
        ``"block.variable"`` -> ndarray, shape (runs, m), in the unit the block declares.
    seeds : list of dict
        Per run, ``{block: seed}``.
    """

    time: np.ndarray
    columns: dict[str, np.ndarray]
    seeds: list[dict[str, int]]

    @classmethod
    def of(cls, records: Sequence[RunRecord]) -> Histories:
        """Stack the kept columns of completed runs (in the given order).

        Parameters
        ----------
        records : sequence of RunRecord
            Runs with kept columns, all completed.

        Returns
        -------
        Histories

        Raises
        ------
        ValueError
            No runs, or a failed run (its error is in the message).
        """
        if not records:
            raise ValueError("no runs to stack")
        for r in records:
            if r.failed:
                raise ValueError(f"run {r.index} ({r.tag or 'campaign'}) failed: {r.error}")
        names = [n for n in records[0].columns if n != "time"]
        data = {n: np.stack([r.columns[n] for r in records]) for n in names}
        return cls(records[0].columns["time"], data, [dict(r.seeds) for r in records])

    @property
    def runs(self) -> int:
        """Number of runs."""
        return len(self.seeds)

    def __getitem__(self, name: str) -> np.ndarray:
        """A scalar column ``(runs, m)``, or a vector ``"block.vec"`` as ``(runs, m, k)``."""
        if name in self.columns:
            return self.columns[name]
        parts: list[np.ndarray] = []
        while f"{name}[{len(parts) + 1}]" in self.columns:
            parts.append(self.columns[f"{name}[{len(parts) + 1}]"])
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


# ----------------------------------------------------------------------- metrics table
def metrics_columns(campaign: Any) -> list[str]:
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


def metrics_rows(campaign: Any) -> Iterable[list[Any]]:
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


def write_metrics_table(campaign: Any, path: Path) -> Path:
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
    buffer = io.StringIO(newline="")
    w = csv.writer(buffer)
    w.writerow(metrics_columns(campaign))
    w.writerows(metrics_rows(campaign))
    return write_atomic(path, buffer.getvalue())
