"""Shared helpers of the benchmarks: interleaved timing, FMUs, profiles.

Every judged figure is a ratio of two timings taken in the same run, interleaved
(``a b c a b c ...``) and reduced to the best of each, so that a burst of load from
another process hits both sides alike and the best repetition of each is compared.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: FMUs built by ``make fmus`` (``make bench`` builds them first).
FMU_DIR = ROOT / "fmus" / "build"


def interleaved_best(tasks: dict[str, Callable[[], Any]], repeats: int) -> dict[str, float]:
    """Best wall time of each task over ``repeats`` interleaved rounds.

    Parameters
    ----------
    tasks : dict
        Name -> function of no argument (its result is discarded).
    repeats : int
        Rounds; each round runs every task once, in the given order.

    Returns
    -------
    dict
        Name -> smallest wall-clock time [s].
    """
    best = {name: float("inf") for name in tasks}
    for _ in range(repeats):
        for name, task in tasks.items():
            start = time.perf_counter()
            task()
            best[name] = min(best[name], time.perf_counter() - start)
    return best


def load_note() -> str:
    """The 1-minute load average against the core count, e.g. ``"load 2.4 on 2 cores"``."""
    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover - not on every platform
        return f"{os.cpu_count()} cores"
    return f"load {load:.1f} on {os.cpu_count()} cores"


def fmu_dir(models: list[str]) -> Path:
    """A folder with up-to-date FMUs of the given models.

    ``fmus/build`` when it holds every one of them, newer than every source file of
    ``models/`` (``make bench`` builds them first); otherwise they are built into
    ``fmus/build/bench`` (a few seconds per model).

    Parameters
    ----------
    models : list of str
        Model class names.

    Returns
    -------
    Path
        The folder.
    """
    newest_source = max(p.stat().st_mtime for p in (ROOT / "models").glob("*.py"))

    def fresh(folder: Path) -> bool:
        files = [folder / f"{m}.fmu" for m in models]
        return all(f.is_file() and f.stat().st_mtime >= newest_source for f in files)

    if fresh(FMU_DIR):
        return FMU_DIR
    out = FMU_DIR / "bench"
    if not fresh(out):
        from cosim.interop.packaging import build_fmu
        from cosim.registry import truth_models

        classes = truth_models()
        for name in models:
            build_fmu(classes[name], out)
    return out
