"""Recorded IMU logs: CSV, Parquet and HDF5 with unit-labelled columns, read in chunks.

Format
------
One row per sample, a time column and the six sensor columns, each named with its unit
in brackets (CSV header, Parquet column names; HDF5 as described below)::

    time [s],gyro_x [deg/s],gyro_y [deg/s],gyro_z [deg/s],acc_x [m/s2],acc_y [m/s2],acc_z [m/s2]

=============================  ==============================================================
column                         meaning
=============================  ==============================================================
``time``                       sample time, any time unit (``s``, ``ms``, ``us``)
``gyro_x`` .. ``gyro_z``       body axes x, y, z of the IMU case (``accel_`` and ``acc_`` are
``acc_x`` .. ``acc_z``         both accepted for the accelerometers)
=============================  ==============================================================

The *unit* says what a sensor column holds: an angle (``rad``, ``deg``, ``arcsec``) or a
velocity (``m/s``) is an **increment** over the sample interval; a rate (``deg/s``,
``deg/h``) or a specific force (``m/s2``, ``g``, ``mg``) is the **mean over the interval**
ending at the sample's time (what an IMU's integrating front end delivers). Any unit
:mod:`cosim.units` knows is accepted; the three axes of a triad share one kind. Sample
``k`` covers ``(t_{k-1}, t_k]``; the first covers ``(t_0 - dt, t_0]`` with ``dt`` the
sample interval. Rates become increments as ``rate_k * (t_k - t_{k-1})`` (exact for
interval means). Other columns (temperature, status) are ignored.

HDF5: a group (the file root, or the one named by ``group``) holding one 1-D dataset per
column, named ``time``, ``gyro_x``, ...; each dataset's unit is its attribute ``unit``
(or the name carries it, ``"gyro_x [deg/s]"``).

Checks
------
Every problem is one :class:`~cosim.sensors.formats.LogError` naming the file, the line
(CSV, counting the header as line 1) or the row (Parquet, HDF5, counting the first data
row as row 1), the sample's time, and the fix. Nothing is interpolated, filled or reordered:

=====================  =========================================================================
problem                rule
=====================  =========================================================================
missing column         a required column is absent (the message lists those present)
unknown unit           a unit :func:`cosim.units.parse_unit` does not know, or of the wrong kind
unreadable value       a field that is not a number (a truncated last line is named as such)
NaN / inf              any non-finite value
duplicate time         ``t_k == t_{k-1}``; policy ``duplicates = "drop"`` drops the row when its
                       values equal the previous row's (a logger's retransmission), else error
time going backwards   ``t_k < t_{k-1}``
gap                    ``t_k - t_{k-1} > 1.5 dt`` (samples lost: no policy can invent them)
jitter / clock drift   ``|t_k - (t_0 + k dt)| > jitter * dt``: the stated tolerance on the
                       deviation from the nominal grid (default 5 % of the interval)
=====================  =========================================================================

The nominal interval ``dt`` is ``1 / sample_rate`` when given, else the median interval of
the first chunk. Memory is bounded by the chunk size (``chunk_rows``), whatever the log's
length: :meth:`ImuLog.chunks` streams, and :meth:`ImuLog.scan` checks a whole log in one
streaming pass.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import UnitError, UserError, did_you_mean
from cosim.sensors.formats import (
    LogColumnError,
    LogError,
    LogTimeError,
    LogValueError,
    csv_header,
    csv_lines,
    parse_csv,
    table_chunks,
    table_header,
)
from cosim.units import parse_unit

#: Default chunk size of the readers [rows].
CHUNK_ROWS = 65536
#: Default tolerance on the deviation of a timestamp from the nominal grid [sample intervals].
JITTER = 0.05
#: An interval longer than this many nominal intervals is a gap (samples lost).
GAP_FACTOR = 1.5

AXES = ("x", "y", "z")
_HEADER = re.compile(r"^\s*([^\[\]]+?)\s*(?:\[([^\[\]]*)\])?\s*$")


@dataclass(frozen=True)
class Layout:
    """The columns a kind of log holds besides ``time``, and what their units may be.

    Attributes
    ----------
    name : str
        The kind of log, for messages (``"IMU"``).
    columns : tuple of str
        Canonical column names, in output order.
    kinds : tuple of dict
        Per column: kind (``"increment"``, ``"rate"``, ``"state"``) -> SI reference unit;
        a ``"rate"`` column is integrated into an increment.
    aliases : dict
        Column prefix -> other accepted prefixes (``{"acc": ("accel",)}``).
    groups : tuple
        ``(name, start, stop)``: columns that must share one kind (a sensor triad).
    example : str
        A header for the messages (``"gyro_x [deg/s]"``).
    hint : str
        How to choose units, for the wrong-kind message.
    """

    name: str
    columns: tuple[str, ...]
    kinds: tuple[dict[str, str], ...]
    aliases: dict[str, tuple[str, ...]]
    groups: tuple[tuple[str, int, int], ...]
    example: str
    hint: str


_GYRO = {"increment": "rad", "rate": "rad/s"}
_ACC = {"increment": "m/s", "rate": "m/s2"}
#: An IMU log: gyro and accelerometer triads, increments or rates.
IMU = Layout(
    "IMU",
    tuple(f"{p}_{a}" for p in ("gyro", "acc") for a in AXES),
    (_GYRO,) * 3 + (_ACC,) * 3,
    {"acc": ("accel",)},
    (("gyro", 0, 3), ("acc", 3, 6)),
    "gyro_x [deg/s]",
    "give gyro columns an angle or angular-rate unit and acc columns a velocity or "
    "acceleration unit",
)
#: A master-INS log: its navigation solution at each sample time (NED, ZYX roll-pitch-yaw).
MASTER_INS = Layout(
    "master INS",
    ("v_n", "v_e", "v_d", "roll", "pitch", "yaw", "lat", "lon", "h"),
    ({"state": "m/s"},) * 3 + ({"state": "rad"},) * 5 + ({"state": "m"},),
    {},
    (),
    "yaw [deg]",
    "give velocities a speed unit (m/s), attitude and position angles an angle unit (deg, "
    "rad) and h a length unit (m)",
)


@dataclass(frozen=True)
class Columns:
    """Where the seven used columns are and how to turn them into SI increments.

    Attributes
    ----------
    index : tuple of int
        Column positions of time and the layout's columns in the file (IMU: time, gyro x
        y z, acc x y z).
    names : tuple of str
        Their headers as written.
    time_factor : float
        Time unit -> s.
    factor : ndarray, shape (k,)
        Column unit -> SI (rad, rad/s, m/s or m/s2; m for a height).
    rate : ndarray of bool, shape (k,)
        True where the column is a rate (mean over the interval), False for increments.
    kinds : tuple of str
        The kind of each sensor column (``"increment"``, ``"rate"``, ``"state"``).
    present : tuple of str
        The layout's columns read, canonical names in layout order (all of them unless
        the log was opened with ``partial``).
    """

    index: tuple[int, ...]
    names: tuple[str, ...]
    time_factor: float
    factor: np.ndarray
    rate: np.ndarray
    kinds: tuple[str, ...] = ()
    present: tuple[str, ...] = ()


@dataclass(frozen=True)
class Chunk:
    """Checked samples, in SI units (rates integrated into increments).

    Attributes
    ----------
    first : int
        Number of the first sample in the log (0-based sample index).
    line : ndarray of int, shape (n,)
        Line (CSV) or row (Parquet, HDF5) of each sample, for messages.
    time : ndarray, shape (n,)
        Sample times [s].
    values : ndarray, shape (n, k)
        The layout's columns in order, SI. IMU: angle increments [rad] then velocity
        increments [m/s] over each sample interval, body axes.
    """

    first: int
    line: np.ndarray
    time: np.ndarray
    values: np.ndarray

    @property
    def dtheta(self) -> np.ndarray:
        """IMU: angle increments, shape (n, 3) [rad]."""
        return self.values[:, :3]

    @property
    def dv(self) -> np.ndarray:
        """IMU: velocity increments, shape (n, 3) [m/s]."""
        return self.values[:, 3:6]


@dataclass(frozen=True)
class LogSummary:
    """What a full scan of a log found.

    Attributes
    ----------
    samples : int
        Samples kept (after the duplicate policy).
    t_first, t_last : float
        First and last sample time [s].
    dt : float
        Nominal sample interval [s].
    dropped : int
        Duplicate rows dropped by ``duplicates = "drop"``.
    sums : ndarray, shape (k,)
        Sum of each column over the log (:func:`math.fsum` per chunk); for an IMU log the
        total angle [rad] and velocity [m/s] increments.
    """

    samples: int
    t_first: float
    t_last: float
    dt: float
    dropped: int
    sums: np.ndarray

    @property
    def dtheta_sum(self) -> np.ndarray:
        """IMU: total angle increment, shape (3,) [rad]."""
        return self.sums[:3]

    @property
    def dv_sum(self) -> np.ndarray:
        """IMU: total velocity increment, shape (3,) [m/s]."""
        return self.sums[3:6]


def parse_header(
    names: list[str],
    file: str,
    where: str = "line 1",
    layout: Layout = IMU,
    *,
    partial: bool = False,
) -> Columns:
    """Find the time and the layout's columns in a list of ``"name [unit]"`` headers.

    Parameters
    ----------
    names : list of str
        Column headers as written.
    file : str
        The log, for messages.
    where : str, optional
        Where the headers are (``"line 1"``).
    layout : Layout, optional
        The columns wanted (default :data:`IMU`).
    partial : bool, optional
        Read whichever of the layout's columns are present (at least one), e.g. a
        gyro-only or a one-axis log; by default every one is required.

    Returns
    -------
    Columns

    Raises
    ------
    LogColumnError
        A missing column, a column without unit, an unknown unit or one of the wrong kind.
    """
    parsed: dict[str, tuple[int, str, str]] = {}
    for i, raw in enumerate(names):
        m = _HEADER.match(str(raw))
        if m:
            parsed.setdefault(m.group(1).strip().lower(), (i, str(raw).strip(), m.group(2)))
    index, shown, units, slots = [], [], [], []
    for slot, key in enumerate(("time", *layout.columns)):
        prefix, sep, rest = key.partition("_")
        spellings = [key] + [f"{a}{sep}{rest}" for a in layout.aliases.get(prefix, ())]
        found = next((parsed[s] for s in spellings if s in parsed), None)
        if found is None and partial and slot > 0:
            continue
        if found is None:
            tip = did_you_mean(key, parsed)
            raise LogColumnError(
                file,
                f"no column '{key}' (columns found: {', '.join(map(str, names))}).{tip}",
                f"name the columns time, {', '.join(layout.columns)}, each with its unit, "
                f"e.g. '{layout.example}'",
                where,
            )
        i, text, unit = found
        if unit is None or not unit.strip():
            refs = ["s"] if key == "time" else list(layout.kinds[slot - 1].values())
            examples = " or ".join(f"'{text} [{r}]'" for r in refs)
            raise LogColumnError(
                file,
                f"column '{text}' has no unit",
                f"write its unit in brackets, e.g. {examples}",
                where,
            )
        index.append(i)
        shown.append(text)
        units.append(unit.strip())
        slots.append(slot - 1)
    if len(index) == 1:
        raise LogColumnError(
            file,
            f"no sensor column (columns found: {', '.join(map(str, names))})",
            f"name at least one of {', '.join(layout.columns)} with its unit, "
            f"e.g. '{layout.example}'",
            where,
        )
    try:
        time_unit = parse_unit(units[0])
    except UnitError as exc:
        raise LogColumnError(
            file, f"column '{shown[0]}': {exc.message}", "use s, ms or us", where
        ) from exc
    if time_unit.dimension != parse_unit("s").dimension or time_unit.offset:
        raise LogColumnError(
            file, f"column '{shown[0]}' has unit '{units[0]}', not a time", "use s, ms or us", where
        )
    slots = slots[1:]
    factor = np.empty(len(slots))
    kinds: list[str] = []
    for j, (text, unit) in enumerate(zip(shown[1:], units[1:], strict=True)):
        try:
            u = parse_unit(unit)
        except UnitError as exc:
            raise LogColumnError(
                file,
                f"column '{text}': {exc.message}",
                "use a unit the unit system knows (docs/scenario_files.md)",
                where,
            ) from exc
        allowed = layout.kinds[slots[j]]
        for kind, ref in allowed.items():
            if u.compatible(parse_unit(ref)) and not u.offset:
                factor[j] = u.factor / parse_unit(ref).factor
                kinds.append(kind)
                break
        else:
            options = [
                f"{'an' if kd[0] in 'aeiou' else 'a'} {kd} ({r})" for kd, r in allowed.items()
            ]
            what = " nor ".join(options)
            raise LogColumnError(
                file,
                f"column '{text}' has unit '{unit}' ({u.si_text()}), which is "
                f"{'neither ' if len(options) > 1 else 'not '}{what}",
                layout.hint,
                where,
            )
    for group, lo, hi in layout.groups:
        own = [j for j, slot in enumerate(slots) if lo <= slot < hi]
        mixed = {kinds[j] for j in own}
        if len(mixed) > 1:
            raise LogColumnError(
                file,
                f"the {group} columns mix "
                f"{' and '.join(f'{kd}s' for kd in sorted(mixed, reverse=True))} "
                f"({', '.join(shown[1 + j] for j in own)})",
                "give the three axes of a triad the same kind of unit",
                where,
            )
    rate = np.array([kd == "rate" for kd in kinds], dtype=bool)
    present = tuple(layout.columns[slot] for slot in slots)
    return Columns(
        tuple(index), tuple(shown), time_unit.factor, factor, rate, tuple(kinds), present
    )


# ----------------------------------------------------------------------------- the log
class SensorLog:
    """A recorded log of a :class:`Layout`, read and checked chunk by chunk.

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.parquet`` / ``.pq`` or ``.h5`` / ``.hdf5``.
    layout : Layout
        Its columns (:data:`IMU`, :data:`MASTER_INS`).
    sample_rate : float, optional
        Nominal sample rate [Hz]; default: from the median interval of the first chunk.
    jitter : float, optional
        Tolerance on ``|t_k - (t_0 + k dt)|`` in sample intervals (default :data:`JITTER`).
    duplicates : {"error", "drop"}, optional
        ``"drop"`` drops a row whose time and values repeat the previous row's.
    chunk_rows : int, optional
        Rows read at a time (the memory bound).
    group : str, optional
        HDF5 group holding the datasets (default: the file root).
    partial : bool, optional
        Accept any non-empty subset of the layout's columns (:func:`parse_header`); the
        chunks then hold those columns only (``columns.present``).

    Raises
    ------
    LogError
        An unreadable header (missing column, unknown unit) at construction; the samples
        are checked as they are read (:meth:`chunks`, :meth:`scan`).
    """

    def __init__(
        self,
        path: str | Path,
        layout: Layout,
        *,
        sample_rate: float | None = None,
        jitter: float = JITTER,
        duplicates: str = "error",
        chunk_rows: int = CHUNK_ROWS,
        group: str | None = None,
        partial: bool = False,
    ) -> None:
        self.path = Path(path)
        self.file = str(path)
        if not self.path.is_file():
            raise LogError(
                self.file,
                "no such file",
                "check the path (a relative one is taken from the working directory)",
            )
        suffix = self.path.suffix.lower()
        formats = {
            ".csv": "csv",
            ".parquet": "parquet",
            ".pq": "parquet",
            ".h5": "hdf5",
            ".hdf5": "hdf5",
        }
        if suffix not in formats:
            raise LogError(
                self.file,
                f"unknown log format '{suffix}'",
                "use .csv, .parquet (.pq) or .h5 (.hdf5)",
            )
        if duplicates not in ("error", "drop"):
            raise UserError(f"duplicates must be 'error' or 'drop', got {duplicates!r}")
        if not (sample_rate is None or sample_rate > 0.0):
            raise UserError(f"sample_rate must be > 0 Hz, got {sample_rate!r}")
        if not jitter > 0.0 or jitter >= GAP_FACTOR - 1.0:
            raise UserError(f"jitter must lie in (0, {GAP_FACTOR - 1.0:g}), got {jitter!r}")
        self.format = formats[suffix]
        self.sample_rate = sample_rate
        self.jitter = float(jitter)
        self.duplicates = duplicates
        self.chunk_rows = int(chunk_rows)
        self.group = group
        self.where = "line" if self.format == "csv" else "row"
        if self.format == "csv":
            names = csv_header(self.path)
        else:
            names = table_header(self.path, self.format, group)
        self.names = names
        self.layout = layout
        self.columns = parse_header(
            names,
            self.file,
            "line 1" if self.format == "csv" else "column names",
            layout,
            partial=partial,
        )

    # --------------------------------------------------------------- raw values
    def _raw(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        if self.format != "csv":
            yield from table_chunks(
                self.path,
                self.format,
                self.group,
                self.columns.index,
                self.names,
                self.chunk_rows,
            )
            return
        raw = csv_lines(self.path, self.chunk_rows)
        pending = next(raw, None)
        while pending is not None:
            following = next(raw, None)
            lines, block = pending
            yield (
                lines,
                parse_csv(
                    self.file,
                    lines,
                    block,
                    len(self.names),
                    self.columns.index,
                    self.columns.names,
                    following is None,
                ),
            )
            pending = following

    # --------------------------------------------------------------- checked samples
    def chunks(self) -> Iterator[Chunk]:
        """The checked samples as SI increments, one chunk at a time.

        Yields
        ------
        Chunk
            At most ``chunk_rows`` samples.

        Raises
        ------
        LogError
            At the first bad value or timestamp (see the module docstring).
        """
        cols = self.columns
        dt = None if self.sample_rate is None else 1.0 / self.sample_rate
        prev_t: float | None = None
        prev_row: np.ndarray | None = None
        t0 = 0.0
        count = 0
        for lines, data in self._raw():
            bad = ~np.isfinite(data)
            if bad.any():
                k, c = np.argwhere(bad)[0]
                t = data[k, 0] * cols.time_factor
                raise LogValueError(
                    self.file,
                    f"column '{cols.names[c]}' is {float(data[k, c])!r}",
                    "nothing is interpolated: repair or cut the log around this sample",
                    f"{self.where} {lines[k]}",
                    None if not math.isfinite(t) else float(t),
                )
            t = data[:, 0] * cols.time_factor
            values = data[:, 1:] * cols.factor
            if self.duplicates == "drop":
                prev_t_arr = np.concatenate([[np.nan if prev_t is None else prev_t], t[:-1]])
                prev_v = np.vstack(
                    [values[:1] * np.nan if prev_row is None else prev_row, values[:-1]]
                )
                same = (t == prev_t_arr) & np.all(values == prev_v, axis=1)
                if same.any():
                    keep = ~same
                    lines, t, values = lines[keep], t[keep], values[keep]
                    self._dropped += int(same.sum())
                if len(t) == 0:
                    continue
            if dt is None:
                d = np.diff(t)
                if len(d) == 0:
                    raise LogTimeError(
                        self.file,
                        "one sample: the sample interval cannot be found",
                        "give the block's sample_rate",
                        f"{self.where} {lines[0]}",
                        float(t[0]),
                    )
                dt = float(np.median(d))
                if not dt > 0.0:
                    k = int(np.argmax(d <= 0.0))
                    self._time_error(lines, t, k + 1, float(t[k]), 1.0)
                self.sample_rate = 1.0 / dt
            if prev_t is None:
                t0 = float(t[0])
            before = np.concatenate([[t[0] - dt if prev_t is None else prev_t], t])
            d = np.diff(before)
            grid = t - (t0 + (count + np.arange(len(t))) * dt)
            wrong = (d <= 0.0) | (d > GAP_FACTOR * dt) | (np.abs(grid) > self.jitter * dt)
            if wrong.any():
                k = int(np.argmax(wrong))
                self._time_error(lines, t, k, float(before[k]), dt, float(grid[k]))
            inc = np.where(cols.rate, values * d[:, None], values)
            yield Chunk(count, lines, t, inc)
            count += len(t)
            prev_t = float(t[-1])
            prev_row = values[-1:].copy()
        if prev_t is None:
            raise LogValueError(
                self.file,
                "no samples after the header",
                "record at least two samples",
                f"{self.where} 2",
            )
        self.dt = dt

    _dropped = 0

    def _time_error(
        self, lines: np.ndarray, t: np.ndarray, k: int, t_before: float, dt: float, off: float = 0.0
    ) -> None:
        at = f"{self.where} {lines[k]}"
        d = float(t[k]) - t_before
        if d == 0.0:
            raise LogTimeError(
                self.file,
                "duplicate time (the same as the previous sample's)",
                "delete the repeated row, or set duplicates = 'drop' if it repeats the previous "
                "row exactly",
                at,
                float(t[k]),
            )
        if d < 0.0:
            raise LogTimeError(
                self.file,
                f"time goes backwards by {-d:.6g} s (previous sample at {t_before:.9g} s)",
                "sort the log by time or cut it where the clock jumped",
                at,
                float(t[k]),
            )
        if d > GAP_FACTOR * dt:
            missing = round(d / dt) - 1
            raise LogTimeError(
                self.file,
                f"gap of {d:.6g} s after the sample at {t_before:.9g} s (about "
                f"{missing} sample(s) missing at {1.0 / dt:.6g} Hz)",
                "nothing is interpolated: cut the log at the gap and replay the parts separately",
                at,
                float(t[k]),
            )
        raise LogTimeError(
            self.file,
            f"timestamp {off / dt:+.3g} sample intervals off the nominal "
            f"{1.0 / dt:.6g} Hz grid (tolerance {self.jitter:g})",
            "state the log's true sample_rate, or raise jitter if the clock is known to be "
            "this loose",
            at,
            float(t[k]),
        )

    def scan(self) -> LogSummary:
        """Check the whole log in one streaming pass.

        Returns
        -------
        LogSummary

        Raises
        ------
        LogError
            At the first problem.
        """
        self._dropped = 0
        n = 0
        t_first = t_last = math.nan
        sums = np.zeros(len(self.columns.factor))
        for chunk in self.chunks():
            if n == 0:
                t_first = float(chunk.time[0])
            n += len(chunk.time)
            t_last = float(chunk.time[-1])
            sums = np.array(
                [
                    math.fsum([s, math.fsum(col)])
                    for s, col in zip(sums, chunk.values.T, strict=True)
                ]
            )
        return LogSummary(n, t_first, t_last, self.dt, self._dropped, sums)


class ImuLog(SensorLog):
    """An IMU log (:data:`IMU` layout); the parameters are :class:`SensorLog`'s but ``layout``.

    Parameters
    ----------
    path : str or Path
        The log.
    **options
        ``sample_rate``, ``jitter``, ``duplicates``, ``chunk_rows``, ``group``,
        ``partial``.
    """

    def __init__(self, path: str | Path, **options: Any) -> None:
        super().__init__(path, IMU, **options)


class MasterInsLog(SensorLog):
    """A master-INS log (:data:`MASTER_INS` layout: states at each sample time).

    Parameters
    ----------
    path : str or Path
        The log.
    **options
        ``sample_rate``, ``jitter``, ``duplicates``, ``chunk_rows``, ``group``.
    """

    def __init__(self, path: str | Path, **options: Any) -> None:
        super().__init__(path, MASTER_INS, **options)


#: Header of the logs :func:`write_csv` writes (increments in SI units).
INCREMENT_HEADER = (
    "time [s],gyro_x [rad],gyro_y [rad],gyro_z [rad],acc_x [m/s],acc_y [m/s],acc_z [m/s]"
)


def write_csv(path: str | Path, time: np.ndarray, dtheta: np.ndarray, dv: np.ndarray) -> Path:
    """Write an increment log that this module reads back exactly.

    Every value is written with ``repr`` (shortest round-trip text), so the log replays
    the increments bit for bit (:class:`~cosim.sensors.replay.ImuLogReplay`).

    Parameters
    ----------
    path : str or Path
        The ``.csv`` file (overwritten).
    time : array_like, shape (n,)
        Sample times [s], the end of each sample interval.
    dtheta : array_like, shape (n, 3)
        Angle increments, body axes [rad].
    dv : array_like, shape (n, 3)
        Velocity increments, body axes [m/s].

    Returns
    -------
    Path
    """
    rows = np.column_stack([np.asarray(time, dtype=float), dtheta, dv])
    path = Path(path)
    with path.open("w") as f:
        f.write(INCREMENT_HEADER + "\n")
        for row in rows.tolist():
            f.write(",".join(map(repr, row)) + "\n")
    return path
