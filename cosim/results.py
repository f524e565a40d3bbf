"""Run results: a structured numpy array (``time`` first) with its metadata.

On disk a result is two files side by side::

    results.csv    header row of column names, one row per recorded time, SI units;
                   Integer, Boolean (0/1) and Enumeration outputs as integers, String
                   outputs as text (quoted when needed)
    results.json   metadata: scenario file and sha256, blocks (source, FMU GUID and
                   sha256, FMI version), seeds, units and types of every column,
                   master settings, status and error (and ``terminated`` when a block
                   ended the run early), software versions, the recorded columns'
                   descriptions; ``ins-cosim run`` adds ``consistency``
                   (docs/consistency.md)
"""

from __future__ import annotations

import csv as csv_module
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class RunResult:
    """The recording of one run.

    Attributes
    ----------
    data : numpy structured array, shape (n_rows,)
        Field ``time`` [s] first, then ``block.variable`` fields in SI units.
    metadata : dict
        Provenance and settings (see module docstring).
    status : str
        ``"completed"`` or ``"failed"``.
    error : str
        The failure message when ``status == "failed"``.
    strings : dict
        Column name -> its values, one per row, for String outputs (their columns in
        :attr:`data` hold NaN).
    """

    data: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)
    status: str = "completed"
    error: str = ""
    strings: dict[str, list[str]] = field(default_factory=dict)

    @property
    def time(self) -> np.ndarray:
        """Recorded times [s], shape (n_rows,)."""
        return self.data["time"]

    @property
    def names(self) -> list[str]:
        """Column names, ``time`` first."""
        return list(self.data.dtype.names or ())

    def __getitem__(self, name: str) -> np.ndarray:
        """A column ``"block.var"``, shape (n,), or a vector ``"block.vec"``, shape (n, m).

        The elements of an FMI 3 array of two or more dimensions come as columns in
        row-major order (``A[1,1]``, ``A[1,2]``, ...).
        """
        if name in (self.data.dtype.names or ()):
            return self.data[name]
        cols = [c for c in self.data.dtype.names or () if c.startswith(f"{name}[")]
        if not cols:
            raise KeyError(f"no recorded variable '{name}'; recorded: {', '.join(self.names[1:])}")
        # row-major: x[2] before x[10]; A[1,2] before A[2,1] (FMI 3 arrays)
        cols.sort(key=lambda c: tuple(int(i) for i in c[len(name) + 1 : -1].split(",")))
        return np.column_stack([self.data[c] for c in cols])

    def save(self, out_dir: Path, stem: str = "results") -> tuple[Path, Path]:
        """Write ``<stem>.csv`` and ``<stem>.json`` into ``out_dir``.

        Parameters
        ----------
        out_dir : Path
            Folder, created if missing; existing files of the same stem are overwritten.
        stem : str
            File name without suffix (default ``"results"``).

        Returns
        -------
        (Path, Path)
            The CSV and the metadata file.
        """
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        csv = out_dir / f"{stem}.csv"
        header = ",".join(self.names)
        table = self.data.view((np.float64, len(self.names))).reshape(-1, len(self.names))
        if not self.strings:
            np.savetxt(csv, table, delimiter=",", header=header, comments="", fmt="%.17g")
        else:
            text = {self.names.index(n): values for n, values in self.strings.items()}
            types = self.metadata.get("types", {})
            floats = ("Real", "Float64", "Float32")
            whole = {i for i, n in enumerate(self.names) if types.get(n, "Real") not in floats}
            buffer = io.StringIO()
            writer = csv_module.writer(buffer, lineterminator="\n")
            writer.writerow(self.names)
            for r, row in enumerate(table):
                writer.writerow(
                    [
                        text[i][r] if i in text else (f"{int(x)}" if i in whole else f"{x:.17g}")
                        for i, x in enumerate(row)
                    ]
                )
            csv.write_text(buffer.getvalue())
        meta = dict(self.metadata)
        meta["status"] = self.status
        meta["error"] = self.error
        meta["rows"] = int(len(self.data))
        js = out_dir / f"{stem}.json"
        js.write_text(json.dumps(meta, indent=2, default=_jsonable) + "\n")
        return csv, js

    @classmethod
    def load(cls, csv: Path) -> RunResult:
        """Read a result written by :meth:`save` (the ``.json`` beside it is optional).

        Parameters
        ----------
        csv : Path
            The ``<stem>.csv`` file; metadata, status and error come from
            ``<stem>.json`` beside it when it exists.

        Returns
        -------
        RunResult
        """
        csv = Path(csv)
        meta_file = csv.with_suffix(".json")
        meta = json.loads(meta_file.read_text()) if meta_file.exists() else {}
        types = meta.get("types", {})
        text_cols = [n for n, t in types.items() if t in ("String", "Binary")]
        strings: dict[str, list[str]] = {}
        if not text_cols:
            names = csv.read_text().split("\n", 1)[0].strip().split(",")
            raw = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
        else:
            rows = list(csv_module.reader(io.StringIO(csv.read_text())))
            names, body = rows[0], rows[1:]
            strings = {n: [r[names.index(n)] for r in body] for n in text_cols if n in names}
            raw = np.array(
                [
                    [np.nan if n in strings else float(x) for n, x in zip(names, r, strict=True)]
                    for r in body
                ],
                dtype=float,
            ).reshape(len(body), len(names))
        data = np.zeros(len(raw), dtype=[(n, "f8") for n in names])
        for i, n in enumerate(names):
            data[n] = raw[:, i]
        status, error = meta.get("status", "completed"), meta.get("error", "")
        return cls(data, meta, status, error, strings)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (bytes, bytearray)):  # a Binary value: hex digits, as in the CSV
        return obj.hex()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
