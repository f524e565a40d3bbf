"""A full transfer-alignment run with the UKF: wall time per simulated second.

Scenario ``scenarios/transfer_alignment.toml`` (seed 001: moored ship, flexure, lever
arm, slave IMU, master INS, 19-state scaled UKF updating every 0.5 s; 120 s). The
figure is the run's wall time over its simulated time (a real-time factor: below 1 is
faster than real time). Side by side, the same scenario without the alignment block
(truth and sensors only) gives the filter's share of the run.

A second row (issue 18, acceptance 4) times the same run against a hand-written
program: the monolithic numpy chain (:func:`benchmarks.monolithic.simulate` and
:func:`~benchmarks.monolithic.master_ins`, the truth and sensor outputs of the whole run
in whole-array calls) feeding the same filter (the TransferAlignment class, stepped
directly in a loop, its outputs read every recorded step). The ratio co-simulation /
fed program is at most 1.3 when the co-simulation adds at most 30 %; the run checks that
both give the same alignment errors. Its info column splits the fed program into the
monolithic chain and the filter loop, and gives the filter's profile: a pyinstrument
profile of the fed filter loop alone (``out/bench/profile_filter.txt``), its time per
macro step split into the UKF's time and measurement updates, the acquisition bank, the
rest of the period update (process noise, feedback), the strapdown and period sums, the
published outputs and the master rate.

Until the transfer-alignment block and scenario exist the row says so (met = None).
"""

from __future__ import annotations

import time
from collections import Counter
from typing import Any

import numpy as np

import cosim
from benchmarks.monolithic import chain_parameters, master_ins, simulate
from benchmarks.timing import ROOT, interleaved_best, load_note
from cosim.scenario import build_master

SCENARIO = ROOT / "scenarios" / "transfer_alignment.toml"
PROFILE_FILE = ROOT / "out" / "bench" / "profile_filter.txt"
MODEL = "TransferAlignment"
NAME = "transfer alignment with UKF, 120 s: wall time / simulated time"
FED_NAME = "transfer alignment 120 s: co-simulation / filter fed by the monolithic chain"
REPEATS = 2
#: The fed program's alignment errors equal the co-simulation's within this [arcmin]
#: (the monolithic chain equals the co-simulated one to ~1e-11 relative).
FED_TOL = 1e-6
#: Chain role -> block name in the scenario (see benchmarks.monolithic.CHAIN_BLOCKS).
NAMES = {"flexure": "flex"}
#: Filter input <- monolithic output (the scenario's connections into ``align``).
FEED = {
    "dtheta_s": "imu.dtheta_meas_b",
    "dv_s": "imu.dv_meas_b",
    "v_master_n": "master.v_master_n",
    "rpy_master": "master.rpy_master",
    "lat_master": "master.lat_master",
    "h_master": "master.h_master",
    "rpy_s_true": "lever.rpy_s",
    "rpy_m_true": "ship.rpy",
}


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
        run.result = result  # type: ignore[attr-defined]

    return master, run


class FedFilter:
    """The scenario's filter fed by the monolithic chain: a hand-written program.

    Parameters
    ----------
    sc : cosim.Scenario
        The transfer-alignment scenario (blocks ``ship``, ``flex``, ``lever``, ``imu``,
        ``master``, ``align``; Gauss-Seidel coupling).
    """

    def __init__(self, sc: cosim.Scenario) -> None:
        from cosim import registry

        self.params = chain_parameters(sc, names=NAMES)
        self.cls = registry.find_block(sc.blocks["align"].source)
        self.every = sc.settings.record_every
        self.outputs = [v.name for v in self.cls.variables if v.causality == "output"]
        self.recorded: dict[str, np.ndarray] = {}

    def inputs(self, stop: float | None = None) -> tuple[int, list[tuple[str, np.ndarray]]]:
        """The filter's inputs over the whole run: chain and master INS in whole-array calls.

        Parameters
        ----------
        stop : float, optional
            Stop time [s] instead of the scenario's (a whole number of steps).

        Returns
        -------
        n_steps : int
            Macro steps of the run.
        feed : list of (str, ndarray)
            Filter input name and its values at every macro-step time, shape (n + 1, ...).
        """
        p = self.params
        n_steps = p.n_steps if stop is None else int(round((stop - p.start) / p.step))
        out = simulate(p, stop=stop)
        for name, values in master_ins(p.blocks["master"], out, p.step).items():
            out[f"master.{name}"] = values
        return n_steps, [(name, out[source]) for name, source in FEED.items()]

    def loop(self, n_steps: int, feed: list[tuple[str, np.ndarray]]) -> None:
        """The filter stepped in a plain loop on ``feed``; outputs every recorded step.

        Parameters
        ----------
        n_steps : int
            Macro steps.
        feed : list of (str, ndarray)
            From :meth:`inputs`.
        """
        p = self.params
        h, t0 = p.step, p.start
        block = self.cls()
        for name, value in p.blocks["align"].items():
            setattr(block, name, value)
        block.setup_experiment(t0)
        for name, values in feed:
            setattr(block, name, values[0])
        block.exit_initialization_mode()
        rows = n_steps // self.every + 1
        rec = {name: [np.array(getattr(block, name), dtype=float)] for name in self.outputs}
        for n in range(n_steps):
            for name, values in feed:
                setattr(block, name, values[n + 1])
            t_begin = t0 + n * h
            block.do_step(t_begin, (t0 + (n + 1) * h) - t_begin)
            if (n + 1) % self.every == 0:
                for name, values in rec.items():
                    values.append(np.array(getattr(block, name), dtype=float))
        self.recorded = {name: np.array(v, dtype=float) for name, v in rec.items()}
        assert all(len(v) == rows for v in self.recorded.values())

    def run(self, stop: float | None = None) -> None:
        """The whole run: :meth:`inputs` then :meth:`loop` (``chain_time``, ``filter_time`` [s]).

        Parameters
        ----------
        stop : float, optional
            Stop time [s] instead of the scenario's (a whole number of steps).
        """
        start = time.perf_counter()
        n_steps, feed = self.inputs(stop)
        middle = time.perf_counter()
        self.loop(n_steps, feed)
        self.chain_time = middle - start
        self.filter_time = time.perf_counter() - middle


#: (class, method) -> the profile part that takes its frames' own time: everything below
#: them except the frames of other parts (which are their direct children here).
PROFILE_PARTS = {
    ("UnscentedKalmanFilter", "predict"): "UKF time update",
    ("UnscentedKalmanFilter", "update"): "UKF measurement update",
    ("UnscentedParticleFilter", "step"): "acquisition bank (stage 1)",
    ("TransferFilter", "update"): "period update: noise, feedback, restart",
    ("TransferFilter", "step"): "strapdown + period sums",
    ("TransferAlignment", "_publish"): "publishing the outputs",
    ("TransferAlignment", "_master_state"): "master rate",
    ("TransferAlignment", "step"): "block step (the rest)",
}


def filter_profile(fed: FedFilter) -> str:
    """Profile the fed filter loop with pyinstrument; write it, return its breakdown.

    Parameters
    ----------
    fed : FedFilter
        The fed program (its chain is computed outside the profile).

    Returns
    -------
    str
        The filter's time per macro step [us] and its split over :data:`PROFILE_PARTS`
        (shares of the block's step); or why there is none.
    """
    try:
        from pyinstrument import Profiler
    except ImportError:
        return "no filter profile (pyinstrument is not installed: pip install -e '.[test]')"
    n_steps, feed = fed.inputs()
    profiler = Profiler(interval=0.0005)
    profiler.start()
    try:
        fed.loop(n_steps, feed)
    finally:
        profiler.stop()
    PROFILE_FILE.parent.mkdir(parents=True, exist_ok=True)
    PROFILE_FILE.write_text(profiler.output_text(unicode=False, color=False))
    shares: Counter[str] = Counter()

    def walk(frame: Any) -> None:
        here = PROFILE_PARTS.get((frame.class_name, frame.function))
        if here is not None:
            shares[here] += frame.time - sum(
                c.time for c in frame.children if (c.class_name, c.function) in PROFILE_PARTS
            )
        for child in frame.children:
            walk(child)

    root = profiler.last_session.root_frame()
    if root is not None:
        walk(root)
    total = sum(shares.values())
    if not total:
        return "filter profile empty"
    parts = [f"{k} {100 * v / total:.0f}%" for k, v in shares.most_common()]
    return (
        f"filter profile ({PROFILE_FILE.relative_to(ROOT)}, {1e6 * total / n_steps:.0f} us "
        f"per macro step under the profiler): " + ", ".join(parts)
    )


def _fed_difference(result: cosim.RunResult, fed: FedFilter) -> float:
    """Largest |co-simulation - fed program| of the alignment errors ``rpy_err`` [arcmin]."""
    co = np.column_stack([result.data[f"align.rpy_err[{i}]"] for i in (1, 2, 3)])
    return float(np.max(np.abs(co - fed.recorded["rpy_err"])))


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
        fed = FedFilter(cosim.load_scenario(SCENARIO))
        fed_best = {"chain": float("inf"), "filter": float("inf")}

        def run_fed() -> None:
            fed.run()
            fed_best["chain"] = min(fed_best["chain"], fed.chain_time)
            fed_best["filter"] = min(fed_best["filter"], fed.filter_time)

        best = interleaved_best(
            {"full": run_full, "truth": run_truth, "fed": run_fed}, repeats=REPEATS
        )
    except Exception as exc:
        return [{**row, "info": f"not available yet: the run failed: {type(exc).__name__}: {exc}"}]
    finally:
        for master in masters:
            master.terminate()
    factor = best["full"] / sim_time
    share = 1.0 - best["truth"] / best["full"]
    differ = _fed_difference(run_full.result, fed)
    same = differ <= FED_TOL
    profile = filter_profile(fed)
    ratio_fed = best["full"] / best["fed"]
    fed_row = {
        "name": FED_NAME,
        "ratio": ratio_fed,
        "target": "<= 1.3",
        "met": ratio_fed <= 1.3 and same,
        "info": (
            f"co-simulation {best['full']:.2f} s, fed program {best['fed']:.2f} s (monolithic "
            f"chain and master INS {fed_best['chain']:.2f} s + the same filter class stepped in "
            f"a loop {fed_best['filter']:.2f} s, best of each); alignment errors agree to "
            f"{differ:.1e} arcmin{'' if same else f' > {FED_TOL:g}: DIFFER'}; {profile}; {note}"
        ),
    }
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
        },
        fed_row,
    ]
