"""Reproduction of seed 001: shipboard transfer alignment, large heading, flexure, lever arm, UKF.

The entry point ``seed001`` of the group ``ins_cosim.reproductions``: runs the cases of
:mod:`cosim.reproduce.seed001_runs` (where the cases, the seeds and the metrics are
described), plots them (:mod:`.seed001_plots`) and writes the Markdown block.
"""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path

import numpy as np

from cosim.alignment.transfer_analysis import transfer_covariance
from cosim.alignment.transfer_model import StateLayout
from cosim.models.constants import ARCMIN
from cosim.reproduce.seed001_plots import plot_headings, plot_lever, plot_modelled_ignored
from cosim.reproduce.seed001_runs import (
    FLEX_SIGMAS,
    HEADING_LIMIT,
    HEADINGS,
    LEVEL_TOL,
    LEVER_ARMS,
    PAPER_TABLE1,
    T_FROM,
    CampaignStats,
    Case,
    covariance_lines,
    fmt,
    ok,
    plan,
    run_cases,
    stats,
)
from cosim.verify.campaign import CampaignError

#: Runs and campaign seed of the published block (``ins-cosim reproduce`` defaults).
DEFAULT_RUNS = 30
DEFAULT_SEED = 2011
#: The case ``--run I`` reruns when no ``--case`` is given.
DEFAULT_CASE = "campaign modelled"


def rerun(case: str, index: int, runs: int, seed: int) -> str:
    """Run ``index`` of one case of the reproduction alone, with its numbers.

    Parameters
    ----------
    case : str
        A case name of :func:`plan` (``"campaign modelled"``, ``"lever 20 flexure 10
        ignored"``, ``"heading 120"``, ``"paper 2 modelled"``, ...).
    index : int
        Run number (below ``runs``; the paper's single cases have run 0 only).
    runs : int
        Runs of the reproduction's main campaigns (the stratified design's size).
    seed : int
        Campaign seed.

    Returns
    -------
    str
        The run's RMS error and RMS sigma from 30 s, final and largest error per axis
        (arcmin), and its true accelerometer bias (m/s2).

    Raises
    ------
    CampaignError
        An unknown case, or a run outside the case's runs.
    """
    p = plan(runs)
    named = {c.name: c for g in ("single", "camp", "flex", "lever", "head") for c in p[g].values()}
    if case not in named:
        raise CampaignError(f"seed001 has no case '{case}' (cases: {', '.join(named)})")
    if not named[case].stratified and index != 0:
        raise CampaignError(f"case '{case}' has run 0 only")
    r = run_cases([(named[case], index)], seed)[case][0]

    def axes(v: np.ndarray) -> str:
        return ", ".join(f"{x:.6g}" for x in v)

    return "\n".join(
        [
            f"seed001 '{case}', run {index} of {runs}, seed {seed} (roll, pitch, heading):",
            f"  RMS error from {T_FROM:g} s: {axes(r.rms())} arcmin",
            f"  RMS sigma from {T_FROM:g} s: {axes(r.sigma_rms())} arcmin",
            f"  final error: {axes(r.final)} arcmin; largest: {axes(r.max_abs())} arcmin",
            f"  true accelerometer bias: {axes(r.accel_bias)} m/s2",
        ]
    )


def reproduce(out_dir: Path, runs: int, seed: int, workers: int | None = None) -> str:
    """Run every case of seed 001, write the plots, return the published block.

    Parameters
    ----------
    out_dir : Path
        Folder for ``seed001_*.png``.
    runs : int
        Runs per main campaign (the other points use ``min(runs, 10)``).
    seed : int
        Campaign seed.
    workers : int, optional
        Processes (default: the number of CPUs).

    Returns
    -------
    str
        Markdown.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    workers = workers or multiprocessing.cpu_count()
    started = time.perf_counter()
    p = plan(runs)
    sweep = p["sweep_runs"]
    res = run_cases(p["jobs"], seed, workers=workers)
    for name, (src, n) in p["alias"].items():
        res[name] = res[src][:n]

    def st(case: Case) -> CampaignStats:
        return stats(res[case.name])

    single = {k: res[c.name][0] for k, c in p["single"].items()}
    s_camp = {k: st(c) for k, c in p["camp"].items()}
    s_flex = {k: st(c) for k, c in p["flex"].items()}
    s_lever = {k: st(c) for k, c in p["lever"].items()}
    s_head = {h: st(c) for h, c in p["head"].items()}
    cov_lever = {}
    for a in LEVER_ARMS:
        h = transfer_covariance(120.0, r0=(a, a, 0.5 * a), dt=0.25)
        m = h.time >= T_FROM - 1e-9
        heading = h.sigma[m, StateLayout.heading] / ARCMIN
        cov_lever[a] = float(np.sqrt(np.mean(heading**2)))
    sig_plot = (FLEX_SIGMAS[0], FLEX_SIGMAS[-1])
    camp_curves = {(FLEX_SIGMAS[0], lab): res[c.name] for lab, c in p["camp"].items()}
    camp_curves.update(
        {
            (FLEX_SIGMAS[-1], lab): res[p["flex"][(FLEX_SIGMAS[-1], lab)].name]
            for lab in ("modelled", "ignored")
        }
    )
    plot_modelled_ignored(
        out_dir / "seed001_modelled_vs_ignored.png", single, camp_curves, sig_plot
    )
    plot_lever(out_dir / "seed001_lever_arm.png", s_lever, cov_lever, FLEX_SIGMAS[:2])
    plot_headings(
        out_dir / "seed001_heading_sweep.png", {h: res[c.name] for h, c in p["head"].items()}
    )
    cov_rows, _ = covariance_lines()
    elapsed = time.perf_counter() - started

    pm, pi = single[(2.0, "modelled")], single[(2.0, "ignored")]
    cm, ci = s_camp["modelled"], s_camp["ignored"]
    lines = [
        f"Generated by `cosim.reproduce.seed001.reproduce(out_dir, runs={runs}, seed={seed})`: "
        f"{len(p['jobs'])} runs of 120 s in {elapsed / 60:.0f} min on {workers} workers. Errors: "
        "the slave's attitude relative to the master (mounting + flexure), estimate minus "
        "truth, arcmin. RMS: over the samples from 30 s to 120 s (and over the runs).",
        "",
        "**Table 1 of seed 001 next to ours** (flexure sigma 2', lever arm [10, 10, 5] m). "
        "Paper: the steady error of its one run. Ours: its single case (fixed bias 3e-4 g and "
        "drift 0.01 deg/h on every axis), final error / RMS; and the campaign with bias and "
        f"drift drawn per run, stratified over the {runs} runs (Latin hypercube), RMS with the "
        "filter's own RMS sigma in brackets.",
        "",
        "| angle | paper: true | ours: true | paper: modelled | ours: single, final / RMS | "
        "ours: campaign (sigma) | paper: ignored | ours: single ignored, final / RMS | "
        "ours: campaign ignored (sigma) | acceptance |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, k in (("pitch", 1), ("roll", 0), ("heading", 2)):
        true_p, err_m, err_i = PAPER_TABLE1[name]
        if k == 2:
            acc = (
                f"RMS <= {HEADING_LIMIT:g}': {fmt(cm.rms[2])}' -> {ok(cm.rms[2] <= HEADING_LIMIT)}"
            )
        else:
            ratio = cm.rms[k] / cm.sigma[k]
            draw = cm.bias_draw[1 - k]
            acc = (
                f"RMS / sigma = {fmt(ratio)} (1 +- 0.25) -> "
                f"{ok(abs(ratio - 1.0) <= LEVEL_TOL)}; the runs drew {'xy'[1 - k]} biases "
                f"of RMS {fmt(draw)} sigma: per unit of drawn bias {fmt(ratio / draw)} -> "
                f"{ok(abs(ratio / draw - 1.0) <= LEVEL_TOL)}"
            )
        lines.append(
            f"| {name} | {true_p:.6f} deg | {abs(pm.true_rel_deg[k]):.6f} deg | {err_m:.3f}' | "
            f"{fmt(abs(pm.final[k]), 3)}' / {fmt(pm.rms()[k], 3)}' | "
            f"{fmt(cm.rms[k])}' ({fmt(cm.sigma[k])}') | {err_i:.3f}' | "
            f"{fmt(abs(pi.final[k]), 3)}' / {fmt(pi.rms()[k], 3)}' | "
            f"{fmt(ci.rms[k])}' ({fmt(ci.sigma[k])}') | {acc} |"
        )
    lines += [
        "",
        "**Flexure modelled against ignored** (same runs; `seed001_modelled_vs_ignored.png`). "
        "`z` = largest RMS error / RMS sigma over the three axes (about 1 for a consistent "
        "filter):",
        "",
        "| flexure sigma | runs | heading RMS, modelled | heading RMS, ignored | ignored / "
        "modelled | level RMS (roll, pitch), modelled | level RMS, ignored | z modelled | "
        "z ignored |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for sig in FLEX_SIGMAS:
        m_ = s_camp["modelled"] if sig == 2.0 else s_flex[(sig, "modelled")]
        i_ = s_camp["ignored"] if sig == 2.0 else s_flex[(sig, "ignored")]
        lines.append(
            f"| {sig:g}' | {m_.runs} | {fmt(m_.rms[2])}' | {fmt(i_.rms[2])}' | "
            f"{fmt(i_.rms[2] / m_.rms[2])} | {fmt(m_.rms[0])}', {fmt(m_.rms[1])}' | "
            f"{fmt(i_.rms[0])}', {fmt(i_.rms[1])}' | {fmt(np.max(m_.rms / m_.sigma))} | "
            f"{fmt(np.max(i_.rms / i_.sigma))} |"
        )
    lines += [
        "",
        f"**Lever-arm sweep** (`r0 = [L, L, L/2]` m in the truth and the filter, {sweep} runs "
        "per point, same seeds; heading RMS from 30 s; ideal = RMS of the covariance "
        "analysis' heading sigma from 30 s, rigid arm; `seed001_lever_arm.png`):",
        "",
        "| L [m] | ideal | flexure 2': modelled | ignored | ratio | flexure 10': modelled | "
        "ignored | ratio | level RMS 10' (roll, pitch): modelled / ignored | heading <= 7' "
        "(2', modelled) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for a in LEVER_ARMS:
        m2, i2 = s_lever[(2.0, a, "modelled")], s_lever[(2.0, a, "ignored")]
        m10, i10 = s_lever[(10.0, a, "modelled")], s_lever[(10.0, a, "ignored")]
        lines.append(
            f"| {a:g} | {fmt(cov_lever[a])}' | {fmt(m2.rms[2])}' | {fmt(i2.rms[2])}' | "
            f"{fmt(i2.rms[2] / m2.rms[2])} | {fmt(m10.rms[2])}' | {fmt(i10.rms[2])}' | "
            f"{fmt(i10.rms[2] / m10.rms[2])} | {fmt(m10.rms[0])}', {fmt(m10.rms[1])}' / "
            f"{fmt(i10.rms[0])}', {fmt(i10.rms[1])}' | {ok(m2.rms[2] <= HEADING_LIMIT)} |"
        )
    lines += [
        "",
        "**Initial heading misalignment sweep** (true mounting heading; roll and pitch 1 deg; "
        f"flexure modelled; {sweep} runs each; `seed001_heading_sweep.png`):",
        "",
        "| heading [deg] | heading RMS from 30 s | final heading RMS | largest \\|heading\\| "
        "from 30 s | level RMS (roll, pitch) | heading RMS <= 7' |",
        "|---|---|---|---|---|---|",
    ]
    for h in HEADINGS:
        s_ = s_head[h]
        lines.append(
            f"| {h:g} | {fmt(s_.rms[2])}' | {fmt(s_.final_rms[2])}' | {fmt(s_.max_abs[2])}' | "
            f"{fmt(s_.rms[0])}', {fmt(s_.rms[1])}' | {ok(s_.rms[2] <= HEADING_LIMIT)} |"
        )
    lines += [
        "",
        "**Linear covariance analysis** "
        "(`cosim.alignment.transfer_analysis.transfer_covariance`: the small-error model "
        "along the ship's closed-form motion, Van Loan every 0.1 s, velocity "
        "matching every 0.5 s with 0.01 m/s noise; level = RMS of the north and east sigmas):",
        "",
        *cov_rows,
        "",
        "Plots (`--update-docs` publishes them to `docs/figures/seed001/`):",
        "",
    ]
    for png, alt in (
        ("seed001_modelled_vs_ignored.png", "seed001 modelled vs ignored"),
        ("seed001_lever_arm.png", "seed001 lever arm"),
        ("seed001_heading_sweep.png", "seed001 heading sweep"),
    ):
        lines.append(f"![{alt}]({(out_dir / png).as_posix()})")
    return "\n".join(lines) + "\n"
