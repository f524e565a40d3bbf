"""Campaign scaling: the same 40-run campaign with 2 worker processes vs 1.

The campaign of ``scenarios/transfer_alignment.toml`` (120 s transfer alignment with
the UKF, every requirement judged), 40 runs, run by :func:`cosim.verify.campaign.run_campaign`
with ``workers=1`` (in this process) and ``workers=2`` (two processes forked from a
forkserver that imported the simulation code once, each building the blocks once and
resetting them between runs). The figure is the speed-up
``T(1 worker) / T(2 workers)`` of the whole campaign, process start-up included. Both
campaigns must give the same metrics (a run's numbers do not depend on who ran it).

Each campaign runs once (about a minute and a half for one worker): on a machine
shared with other jobs the 2-worker figure is only as good as the second core is free
(the info column gives the load average).
"""

from __future__ import annotations

import resource
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.timing import ROOT, load_note

SCENARIO = ROOT / "scenarios" / "transfer_alignment.toml"
RUNS = 40
NAME = f"campaign of {RUNS} transfer-alignment runs: 2 workers vs 1 (speed-up)"


def _cpu() -> float:
    """CPU time [s] of this process and of its terminated children (the workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _campaign(out: Path, workers: int) -> tuple[float, float, dict[int, Any]]:
    """Wall time [s], CPU time [s] and the metrics of every run of one campaign.

    The CPU time is this process's plus the runs' own (each record's ``cpu_time``): the
    workers are forked from a forkserver, not from this process, so they are not among
    its children.
    """
    from cosim.verify.campaign import run_campaign

    cpu = _cpu()
    start = time.perf_counter()
    campaign = run_campaign(SCENARIO, out, runs=RUNS, workers=workers, progress=False)
    elapsed = time.perf_counter() - start
    own = _cpu() - cpu
    if workers > 1:
        own += sum(r.cpu_time for r in campaign.records)
    return elapsed, own, {r.index: r.metrics for r in campaign.records}


def bench() -> list[dict[str, Any]]:
    """Row: campaign speed-up with two workers."""
    row: dict[str, Any] = {"name": NAME, "ratio": None, "target": ">= 1.8", "met": None}
    try:
        import cosim.verify.campaign  # noqa: F401
        from cosim import registry

        ready = SCENARIO.is_file() and "TransferAlignment" in registry.names()
        registry.find_block("TransferAlignment")  # imports it: a broken filter fails here
    except Exception as exc:
        return [{**row, "info": f"not available yet: {type(exc).__name__}: {exc}"}]
    if not ready:
        return [{**row, "info": f"not available yet ({SCENARIO.name} or its filter missing)"}]
    note = load_note()
    with tempfile.TemporaryDirectory(prefix="ins_cosim_bench_") as tmp:
        try:
            t2, cpu2, m2 = _campaign(Path(tmp) / "two", 2)
            t1, cpu1, m1 = _campaign(Path(tmp) / "one", 1)
        except Exception as exc:
            return [{**row, "info": f"not available yet: {type(exc).__name__}: {exc}"}]
    speedup = t1 / t2
    same = m1 == m2
    return [
        {
            **row,
            "ratio": speedup,
            "met": speedup >= 1.8,
            "info": (
                f"1 worker {t1:.1f} s, 2 workers {t2:.1f} s ({t1 / RUNS:.2f} s per run); "
                f"CPU time {cpu1:.0f} s and {cpu2:.0f} s: the 2 workers got "
                f"{cpu2 / t2:.2f} cores on average (2.00 = both cores free); metrics of the "
                f"two campaigns {'identical' if same else 'DIFFER'}; {note}"
            ),
        }
    ]
