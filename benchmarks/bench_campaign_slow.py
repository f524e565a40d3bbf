"""A 1000-run transfer-alignment campaign on 2 workers (issue 18, acceptance 5): slow.

``make bench-slow`` (or ``python -m benchmarks.bench_campaign_slow [RUNS]``) runs the
campaign of ``scenarios/transfer_alignment.toml`` with 1000 runs on a
:class:`cosim.verify.pool.WorkerPool` of 2 and prints its wall time against the target
(under 5 minutes on an idle 2-core machine) with the machine's load before and after,
the cores the workers obtained and the time per run. It is not a timed test and not in
``make bench``'s table: there its :func:`bench` gives no row unless the environment sets
``INS_COSIM_BENCH_SLOW=1``. With fewer runs the 1000-run time is extrapolated from the
measured one (the fixed start-up kept, the rest scaled by the run count) and not judged.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path
from typing import Any

from benchmarks.bench_campaign import SCENARIO, run, start_forkserver
from benchmarks.timing import load_note

RUNS = 1000
#: Seconds the 1000-run campaign may take (5 minutes).
TARGET = 300.0
ENV = "INS_COSIM_BENCH_SLOW"
NAME = f"campaign of {RUNS} transfer-alignment runs on 2 workers: wall time [s]"


def measure(runs: int = RUNS) -> dict[str, Any]:
    """Run the campaign of ``runs`` runs on 2 workers and make the row.

    Parameters
    ----------
    runs : int
        Runs (1000 for the judged figure; fewer give an extrapolation).

    Returns
    -------
    dict
        The benchmark row: ``ratio`` the wall time of 1000 runs [s] (measured, or
        extrapolated when ``runs < 1000``).
    """
    row: dict[str, Any] = {"name": NAME, "ratio": None, "target": f"< {TARGET:.0f}", "met": None}
    if not SCENARIO.is_file():
        return {**row, "info": f"not available ({SCENARIO.name} missing)"}
    before = load_note()
    forkserver = start_forkserver()
    with tempfile.TemporaryDirectory(prefix="ins_cosim_bench_") as tmp:
        got = run(Path(tmp) / "slow", 2, runs)
    fixed = got["ready"] if got["ready"] == got["ready"] else 0.0  # nan: no pool start
    per_run = (got["wall"] - fixed) / runs
    total = got["wall"] if runs == RUNS else fixed + per_run * RUNS
    measured = runs == RUNS
    free = fixed + got["cpu"] / runs * RUNS / 2  # the 1000 runs' CPU time on two free cores
    return {
        **row,
        "ratio": total,
        "met": total < TARGET if measured else None,
        "info": (
            f"{'measured' if measured else f'extrapolated from {runs} runs'}: "
            f"{got['wall']:.1f} s for {runs} runs ({per_run:.3f} s of wall time per run, "
            f"{got['cpu'] / runs:.2f} s of CPU per run), workers ready after "
            f"{fixed:.2f} s, cores obtained {got['cores']:.2f} (2.00 = both cores free; on "
            f"two free cores at this CPU time per run: {free:.0f} s); "
            f"forkserver start {forkserver:.1f} s (outside the timing); {before} before, "
            f"{load_note()} after"
        ),
    }


def bench() -> list[dict[str, Any]]:
    """The row, only when ``INS_COSIM_BENCH_SLOW=1`` (``make bench-slow``)."""
    if os.environ.get(ENV) != "1":
        return []
    return [measure(RUNS)]


if __name__ == "__main__":
    result = measure(int(sys.argv[1]) if len(sys.argv) > 1 else RUNS)
    met = {True: "yes", False: "NO", None: "-"}[result["met"]]
    figure = "-" if result["ratio"] is None else f"{result['ratio']:.0f}"
    print(f"{result['name']}: {figure} (target {result['target']}, met {met})")
    print(f"  {result['info']}")
