"""The transfer-alignment truth and sensor chain: co-simulation vs monolithic numpy, FMUs.

Chain: ``benchmarks/transfer_chain.toml`` (ship motion -> deck flexure -> lever arm ->
slave IMU, 120 s, 10 ms macro step, 1 ms truth step, every output recorded).

Rows (ratios of wall times measured side by side, best of interleaved repetitions):

- co-simulation in-process / monolithic numpy (``benchmarks/monolithic.py``); the run
  also checks that both give the same outputs (1e-9, as ``tests/benchmarks/test_monolithic.py``);
- co-simulation with every block an FMU (fmpy) / in-process.

Only ``Master.run`` and ``monolithic.simulate`` are timed (building the blocks,
loading FMUs and reading parameters are one-off costs, shown in the info column).
A pyinstrument profile of a 20 s in-process run is written to
``out/bench/profile_chain.txt``; the row's info column gives its breakdown (share and
microseconds per macro step) and which path the models take (compiled kernels or numpy,
:func:`models.native.status`; ``INS_COSIM_NATIVE=0`` measures the numpy path).
"""

from __future__ import annotations

import dataclasses
import time
from collections import Counter
from typing import Any

import numpy as np

import cosim
from benchmarks.monolithic import CHAIN_BLOCKS, CHAIN_SCENARIO, chain_parameters, simulate
from benchmarks.timing import ROOT, fmu_dir, interleaved_best, load_note
from cosim.models import native
from cosim.scenario import build_master

REPEATS = 2
PROFILE_STOP = 20.0
PROFILE_FILE = ROOT / "out" / "bench" / "profile_chain.txt"


class _Chain:
    """One co-simulation of the chain, built once, run (reset in between) on demand."""

    def __init__(self, fmus: Any = None) -> None:
        sc = cosim.load_scenario(CHAIN_SCENARIO)
        if fmus is not None:
            sc.use_fmus(fmus)
        start = time.perf_counter()
        self.master = build_master(sc)
        self.build_time = time.perf_counter() - start
        self.result: cosim.RunResult | None = None
        self._ran = False

    def run(self) -> None:
        if self._ran:
            self.master.reset()
        self.result = self.master.run()
        self._ran = True

    def close(self) -> None:
        self.master.terminate()


def _agreement(result: cosim.RunResult, mono: dict[str, np.ndarray]) -> float:
    """Largest difference over every column, relative to the column's magnitude."""
    worst = 0.0
    for name in result.names:
        base, _, index = name.partition("[")
        col = mono[base] if not index else mono[base][:, int(index[:-1]) - 1]
        ref = result.data[name]
        scale = float(np.max(np.abs(ref))) or 1.0
        worst = max(worst, float(np.max(np.abs(col - ref))) / scale)
    return worst


def profile_breakdown(stop: float = PROFILE_STOP) -> str:
    """Profile an in-process run with pyinstrument; write the profile, return its breakdown.

    Parameters
    ----------
    stop : float
        Simulated time of the profiled run [s].

    Returns
    -------
    str
        Share of ``Master.run`` spent in each model's ``step``, in the hosts' value
        get/set, and in the rest (master loop, FMI-shaped calls); or why there is none.
    """
    try:
        from pyinstrument import Profiler
    except ImportError:
        return "no profile (pyinstrument is not installed: pip install -e '.[test]')"
    chain = _Chain()
    chain.master.settings = dataclasses.replace(chain.master.settings, stop=stop)
    profiler = Profiler(interval=0.0005)
    profiler.start()
    try:
        chain.run()
    finally:
        profiler.stop()
        chain.close()
    PROFILE_FILE.parent.mkdir(parents=True, exist_ok=True)
    PROFILE_FILE.write_text(profiler.output_text(unicode=False, color=False))
    shares: Counter[str] = Counter()
    models = set(CHAIN_BLOCKS.values())

    def walk(frame: Any, inside: bool) -> None:
        if frame.function == "run" and frame.class_name == "Master":
            inside = True
        if inside and frame.function == "step" and frame.class_name in models:
            shares[frame.class_name] += frame.time
            return
        if (
            inside
            and frame.function in ("get_real", "set_real")
            and frame.class_name == ("InProcessHost")
        ):
            shares["host get/set"] += frame.time
            return
        children = list(frame.children)
        if inside:
            shares["master loop"] += frame.time - sum(c.time for c in children)
        for child in children:
            walk(child, inside)

    root = profiler.last_session.root_frame()
    if root is not None:
        walk(root, False)
    total = sum(shares.values())
    if not total:
        return "profile empty"
    steps = round(stop / chain.master.settings.step)
    parts = [f"{k} {100 * v / total:.0f}% ({1e6 * v / steps:.0f})" for k, v in shares.most_common()]
    return (
        f"profile ({stop:g} s run, {PROFILE_FILE.relative_to(ROOT)}; us per macro step; "
        f"models: {native.status()}): " + ", ".join(parts)
    )


def bench() -> list[dict[str, Any]]:
    """Rows: co-simulation vs monolithic, FMUs vs in-process."""
    note = load_note()
    params = chain_parameters()
    n_steps = params.n_steps
    fmus = fmu_dir(sorted(set(CHAIN_BLOCKS.values())))
    inproc = _Chain()
    fmu = _Chain(fmus)
    mono: dict[str, np.ndarray] = {}

    def run_mono() -> None:
        mono.update(simulate(params))

    try:
        best = interleaved_best(
            {"mono": run_mono, "inproc": inproc.run, "fmu": fmu.run}, repeats=REPEATS
        )
        assert inproc.result is not None and fmu.result is not None
        agree = _agreement(inproc.result, mono)
        fmu_equal = max(
            float(np.max(np.abs(fmu.result.data[n] - inproc.result.data[n])))
            for n in inproc.result.names
        )
    finally:
        inproc.close()
        fmu.close()
    profile = profile_breakdown()
    per_step = {k: 1e6 * v / n_steps for k, v in best.items()}
    ratio_mono = best["inproc"] / best["mono"]
    ratio_fmu = best["fmu"] / best["inproc"]
    same = agree <= 1e-9
    return [
        {
            "name": "chain 120 s: co-simulation in-process / monolithic numpy",
            "ratio": ratio_mono,
            "target": "<= 2",
            "met": ratio_mono <= 2.0 and same,
            "info": (
                f"co-sim {best['inproc']:.2f} s ({per_step['inproc']:.0f} us/step), "
                f"monolithic {best['mono']:.2f} s ({per_step['mono']:.0f} us/step); "
                f"outputs agree to {agree:.1e} (relative){'' if same else ' > 1e-9: DIFFER'}; "
                f"{profile}; {note}"
            ),
        },
        {
            "name": "chain 120 s: co-simulation FMUs (fmpy) / in-process",
            "ratio": ratio_fmu,
            "target": "<= 3",
            "met": ratio_fmu <= 3.0,
            "info": (
                f"FMUs {best['fmu']:.2f} s ({per_step['fmu']:.0f} us/step), in-process "
                f"{best['inproc']:.2f} s; outputs differ by {fmu_equal:.1e} at most; loading "
                f"the 4 FMUs {fmu.build_time:.1f} s (not timed), building in-process "
                f"{inproc.build_time:.2f} s; {note}"
            ),
        },
    ]
