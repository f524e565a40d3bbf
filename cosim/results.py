"""Run results: a structured numpy array (``time`` first) with its metadata.

On disk a result is two files side by side::

    results.csv    header row of column names, one row per recorded time, SI units
    results.json   metadata: scenario file and sha256, blocks (source, FMU GUID and
                   sha256, FMI version), seeds, units of every column, master settings,
                   status and error, software versions
"""

from __future__ import annotations

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
    """

    data: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)
    status: str = "completed"
    error: str = ""

    @property
    def time(self) -> np.ndarray:
        """Recorded times [s], shape (n_rows,)."""
        return self.data["time"]

    @property
    def names(self) -> list[str]:
        """Column names, ``time`` first."""
        return list(self.data.dtype.names)

    def __getitem__(self, name: str) -> np.ndarray:
        """A column ``"block.var"``, shape (n,), or a vector ``"block.vec"``, shape (n, m)."""
        if name in self.data.dtype.names:
            return self.data[name]
        cols = [c for c in self.data.dtype.names if c.startswith(f"{name}[")]
        if not cols:
            raise KeyError(f"no recorded variable '{name}'; recorded: {', '.join(self.names[1:])}")
        cols.sort(key=lambda c: int(c[len(name) + 1 : -1]))
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
        np.savetxt(
            csv,
            self.data.view((np.float64, len(self.names))).reshape(-1, len(self.names)),
            delimiter=",",
            header=header,
            comments="",
            fmt="%.17g",
        )
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
        names = csv.read_text().split("\n", 1)[0].strip().split(",")
        raw = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
        data = np.zeros(len(raw), dtype=[(n, "f8") for n in names])
        for i, n in enumerate(names):
            data[n] = raw[:, i]
        meta_file = csv.with_suffix(".json")
        meta = json.loads(meta_file.read_text()) if meta_file.exists() else {}
        return cls(data, meta, meta.get("status", "completed"), meta.get("error", ""))


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
