"""A full transfer-alignment run with the UKF: wall time per simulated second.

Scenario ``scenarios/transfer_alignment.toml`` (seed 001: moored ship, flexure, lever
arm, slave IMU, master INS, 19-state scaled UKF updating every 0.5 s; 120 s). The
figure is the run's wall time over its simulated time (a real-time factor: below 1 is
faster than real time). Side by side, the same scenario without the alignment block
(truth and sensors only) gives the filter's share of the run.

Until the transfer-alignment block and scenario exist the row says so (met = None).
"""

from __future__ import annotations

from typing import Any

import cosim
from benchmarks.timing import ROOT, interleaved_best, load_note
from cosim.scenario import build_master

SCENARIO = ROOT / "scenarios" / "transfer_alignment.toml"
MODEL = "TransferAlignment"
NAME = "transfer alignment with UKF, 120 s: wall time / simulated time"
REPEATS = 2


def _without(sc: cosim.Scenario, block: str) -> cosim.Scenario:
    """The scenario with one block, its connections and its recorded outputs removed."""
    sc.blocks.pop(block)
    sc.connections = [c for c in sc.connections if f"{block}." not in c]
    if sc.outputs is not None:
        sc.outputs = [o for o in sc.outputs if o != block and not o.startswith(f"{block}.")]
    return sc


def _runner(sc: cosim.Scenario) -> Any:
    master = build_master(sc)
    state = {"ran": False}

    def run() -> None:
        if state["ran"]:
            master.reset()
        result = master.run()
        if result.status != "completed":
            raise RuntimeError(result.error)
        state["ran"] = True

    return master, run


def bench() -> list[dict[str, Any]]:
    """Row: wall time per simulated second of the transfer-alignment run."""
    row: dict[str, Any] = {"name": NAME, "ratio": None, "target": "report", "met": None}
    try:
        from cosim import registry

        available = SCENARIO.is_file() and MODEL in registry.names()
        registry.find_block(MODEL)  # imports it: a broken filter package fails here
    except Exception as exc:  # the alignment package itself is broken
        return [{**row, "info": f"not available yet: {type(exc).__name__}: {exc}"}]
    if not available:
        return [{**row, "info": f"not available yet ({SCENARIO.name} / {MODEL} missing)"}]
    note = load_note()
    full = cosim.load_scenario(SCENARIO)
    sim_time = full.settings.stop - full.settings.start
    masters = []
    try:
        master, run_full = _runner(full)
        masters.append(master)
        master, run_truth = _runner(_without(cosim.load_scenario(SCENARIO), "align"))
        masters.append(master)
        best = interleaved_best({"full": run_full, "truth": run_truth}, repeats=REPEATS)
    except Exception as exc:
        return [{**row, "info": f"not available yet: the run failed: {type(exc).__name__}: {exc}"}]
    finally:
        for master in masters:
            master.terminate()
    factor = best["full"] / sim_time
    share = 1.0 - best["truth"] / best["full"]
    return [
        {
            **row,
            "ratio": factor,
            "info": (
                f"{best['full']:.2f} s for {sim_time:g} s simulated "
                f"(master step {full.settings.step * 1e3:g} ms); without the alignment block "
                f"{best['truth']:.2f} s, so the filter (strapdown + UKF) takes "
                f"{100 * share:.0f}% of the run; {note}"
            ),
        }
    ]
