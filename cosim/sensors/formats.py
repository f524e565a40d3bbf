"""The file formats of the sensor logs: CSV, Parquet, HDF5 as raw chunks, and the log errors.

:mod:`cosim.sensors.logs` reads every format through these functions and checks what they
return; each error here is one line with the file, the line (CSV) or row, and the fix.
Parquet and HDF5 need the ``logs`` extra (pyarrow, h5py), imported only when such a log
is opened (:func:`import_optional`).
"""

from __future__ import annotations

import importlib
import itertools
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import UserError


class LogError(UserError, ValueError):
    """A log cannot be used as it is: one line with the file, where, the time and the fix.

    Parameters
    ----------
    file : str
        The log file.
    message : str
        What is wrong.
    fix : str
        How to repair it.
    where : str, optional
        ``"line 12"`` (CSV) or ``"row 12"`` (Parquet, HDF5).
    time : float, optional
        The sample's time [s].
    """

    def __init__(
        self, file: str, message: str, fix: str, where: str | None = None, time: float | None = None
    ) -> None:
        self.file, self.where, self.time, self.fix = file, where, time, fix
        place = ", ".join(
            x for x in (file, where, None if time is None else f"t = {time:.9g} s") if x
        )
        super().__init__(f"{place}: {message}; {fix}")


class LogColumnError(LogError):
    """A required column is missing, or a column's unit is unknown or of the wrong kind."""


class LogValueError(LogError):
    """A value cannot be read (truncated line, text) or is NaN / infinite."""


class LogTimeError(LogError):
    """Timestamps: a duplicate, time going backwards, a gap, or jitter beyond the tolerance."""


def csv_header(path: Path) -> list[str]:
    """The header names of a CSV log (its first line).

    Parameters
    ----------
    path : Path
        The log.

    Returns
    -------
    list of str

    Raises
    ------
    LogColumnError
        An empty file or a blank first line.
    """
    with path.open("r", newline="") as handle:
        header = handle.readline()
    if not header.strip():
        raise LogColumnError(
            str(path),
            "the file is empty or its first line is blank",
            "write the header 'time [s],gyro_x [deg/s],...' on line 1",
            "line 1",
        )
    return [h.strip() for h in header.rstrip("\r\n").split(",")]


def csv_lines(path: Path, chunk_rows: int) -> Iterator[tuple[np.ndarray, list[str]]]:
    """``(line numbers, text lines)`` of a CSV log after its header, ``chunk_rows`` at a time.

    Parameters
    ----------
    path : Path
        The log.
    chunk_rows : int
        Lines per chunk.

    Yields
    ------
    tuple
        ``(ndarray of int (n,), list of str (n,))``: file line numbers (header = 1), lines.
    """
    with path.open("r", newline="") as handle:
        handle.readline()
        line_no = 2
        while True:
            block = list(itertools.islice(handle, chunk_rows))
            if not block:
                return
            yield np.arange(line_no, line_no + len(block)), block
            line_no += len(block)


def parse_csv(
    file: str,
    lines: np.ndarray,
    block: list[str],
    n_fields: int,
    index: tuple[int, ...],
    used: tuple[str, ...],
    last_chunk_end: bool,
) -> np.ndarray:
    """Parse CSV text lines into the used columns, checked field by field on failure.

    Parameters
    ----------
    file : str
        The log, for messages.
    lines : ndarray of int, shape (n,)
        File line numbers of ``block``.
    block : list of str
        The text lines.
    n_fields : int
        Fields of the header.
    index : tuple of int
        Positions of the used columns.
    used : tuple of str
        Their headers, for messages.
    last_chunk_end : bool
        True when ``block`` ends the file (a short last line is then "truncated").

    Returns
    -------
    ndarray, shape (n, len(index))

    Raises
    ------
    LogValueError
        A line with the wrong number of fields, a blank line, text in a used field, a
        truncated last line.
    """
    counts = [s.count(",") + 1 for s in block]
    if counts.count(n_fields) != len(counts):  # the lines one by one only then (long logs)
        for k, (count, text) in enumerate(zip(counts, block, strict=True)):
            complete = text.endswith("\n")
            if count != n_fields or not text.strip():
                _bad_line(file, int(lines[k]), text, count, n_fields, truncated=not complete)
    try:
        data = np.loadtxt(block, delimiter=",", usecols=index, ndmin=2, dtype=float)
    except ValueError:
        for k, text in enumerate(block):
            fields = text.rstrip("\r\n").split(",")
            for i, name in zip(index, used, strict=True):
                try:
                    float(fields[i])
                except ValueError:
                    _bad_line(
                        file,
                        int(lines[k]),
                        text,
                        len(fields),
                        n_fields,
                        truncated=not text.endswith("\n") and last_chunk_end,
                        column=name,
                        field=fields[i],
                    )
        raise  # pragma: no cover - loadtxt failed on a line every field of which parses
    return data


def _bad_line(
    file: str,
    line: int,
    text: str,
    count: int,
    n_fields: int,
    *,
    truncated: bool,
    column: str | None = None,
    field: str | None = None,
) -> None:
    if truncated:
        raise LogValueError(
            file,
            f"the last line is cut short ({count} of {n_fields} fields, no end of line): "
            f"{text.strip()[:60]!r}",
            "the log was still being written or the copy was interrupted: copy it again, "
            f"or delete line {line}",
            f"line {line}",
        )
    if column is not None:
        raise LogValueError(
            file,
            f"column '{column}' holds {field.strip()!r}, not a number",
            "write a number there (empty fields are not filled in)",
            f"line {line}",
        )
    raise LogValueError(
        file,
        f"{count} fields where the header has {n_fields}" if text.strip() else "blank line",
        "give every line one value per header column (delete blank lines)",
        f"line {line}",
    )


def table_header(path: Path, fmt: str, group: str | None) -> list[str]:
    """Column names of a Parquet log, or ``"name [unit]"`` of an HDF5 group's 1-D datasets.

    Parameters
    ----------
    path : Path
        The log.
    fmt : {"parquet", "hdf5"}
        Its format.
    group : str or None
        HDF5 group (None: the root).

    Returns
    -------
    list of str
    """
    if fmt == "parquet":
        pq = import_optional("pyarrow.parquet", "pyarrow")
        return list(pq.ParquetFile(path).schema_arrow.names)
    h5py = import_optional("h5py", "h5py")
    with h5py.File(path, "r") as f:
        g = f[group] if group else f
        names = []
        for key, ds in g.items():
            if not isinstance(ds, h5py.Dataset) or ds.ndim != 1:
                continue
            unit = ds.attrs.get("unit")
            if isinstance(unit, bytes):
                unit = unit.decode()
            names.append(f"{key} [{unit}]" if unit is not None and "[" not in key else key)
        return names


def table_chunks(
    path: Path,
    fmt: str,
    group: str | None,
    index: tuple[int, ...],
    names: list[str],
    chunk_rows: int,
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``(row numbers, values)`` chunks of a Parquet or HDF5 log.

    Parameters
    ----------
    path : Path
        The log.
    fmt : {"parquet", "hdf5"}
        Its format.
    group : str or None
        HDF5 group of the datasets (None: the root).
    index : tuple of int
        Positions of the used columns in ``names``.
    names : list of str
        Every column, as :func:`table_header` gives them.
    chunk_rows : int
        Rows per chunk.

    Yields
    ------
    tuple
        ``(ndarray of int (n,), ndarray (n, len(index)))``: rows counted from 1, values.

    Raises
    ------
    LogValueError
        HDF5 datasets of different lengths.
    """
    used = [names[i] for i in index]
    row = 1
    if fmt == "parquet":
        pq = import_optional("pyarrow.parquet", "pyarrow")
        pf = pq.ParquetFile(path)
        for batch in pf.iter_batches(batch_size=chunk_rows, columns=used):
            data = np.column_stack(
                [
                    batch.column(i).to_numpy(zero_copy_only=False).astype(float)
                    for i in range(len(used))
                ]
            )
            yield np.arange(row, row + len(data)), data
            row += len(data)
        return
    h5py = import_optional("h5py", "h5py")
    with h5py.File(path, "r") as f:
        g = f[group] if group else f
        keys = [u.split("[")[0].strip() if u.split("[")[0].strip() in g else u for u in used]
        sets = [g[k] for k in keys]
        n = min(len(s) for s in sets)
        if any(len(s) != n for s in sets):
            lengths = ", ".join(f"{k}: {len(s)}" for k, s in zip(keys, sets, strict=True))
            raise LogValueError(
                str(path),
                f"the datasets differ in length ({lengths})",
                "write one value per sample in every dataset",
                f"row {n + 1}",
            )
        for lo in range(0, n, chunk_rows):
            hi = min(n, lo + chunk_rows)
            data = np.column_stack([np.asarray(s[lo:hi], dtype=float) for s in sets])
            yield np.arange(lo + 1, hi + 1), data


def import_optional(module: str, dist: str) -> Any:
    """Import a module of the ``logs`` extra, or say how to install it.

    Parameters
    ----------
    module : str
        Module name (``"pyarrow.parquet"``).
    dist : str
        Its distribution (``"pyarrow"``).

    Returns
    -------
    module

    Raises
    ------
    UserError
        Not installed: the message gives the pip command.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise UserError(
            f"reading this log needs {dist}, which is not installed: "
            f"pip install 'ins-cosim[logs]' (or pip install {dist})"
        ) from exc
