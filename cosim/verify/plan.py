"""``ins-cosim plan``: a pilot campaign, and the runs each requirement needs to be decided.

The pilot is the first ``pilot`` runs of the scenario's campaign (its seed and seed rule:
a later ``verify`` with the same seed repeats them). The runs each requirement needs are
the advice :func:`cosim.verify.statistics.judge` gives under its verdict on the pilot's
runs (:func:`cosim.verify.advice.advise`): the fewest runs in total, the pilot's runs
included (failed runs counted as the requirement's ``on_failure`` says), at which the
campaign is decided with probability :data:`cosim.verify.advice.ADVICE_SHARE` (80 %),
predicted from the pilot. ``verify --runs pilot`` with the same seed makes the same runs
and prints the same number. When the pilot already decides a requirement, the plan gives
the fewest of its first runs that decide it (what ``verify --runs n`` would show).

The wall time of n runs is the pilot's fixed cost (preparing the scenario, starting
workers) plus n times its time per run divided by the worker count. The runs ``verify
--until-decided`` takes (:mod:`cosim.verify.sequential`) are predicted by judging, at
its looks, *typical* campaigns: the campaign of n runs whose metrics are the pilot's
empirical quantiles at the levels (i + 1/2) / n (the pilot's distribution, sampled
evenly), a point prediction (such a campaign decides with roughly even odds). A
``[campaign] stratify`` scenario is planned the same way: its pilot is the fixed campaign
of ``pilot`` runs, which is also the first look batch of ``verify --until-decided --runs
pilot`` (one Latin hypercube per look batch), and the predictions assume nothing about
how the runs were drawn.
"""

from __future__ import annotations

import math
import os
import tempfile
import textwrap
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.verify.advice import ADVICE_SHARE, CAP, PROMISE_LEVEL
from cosim.verify.campaign import CampaignError, run_campaign
from cosim.verify.requirements import UNDECIDED, Requirement, RunMetric
from cosim.verify.sequential import (
    Looks,
    default_max_runs,
    judge_at,
    plan_looks,
    requirement_confidence,
)
from cosim.verify.statistics import judge

__all__ = [
    "CAP",
    "DEFAULT_PILOT",
    "Plan",
    "RequirementPlan",
    "format_duration",
    "format_plan",
    "make_plan",
    "plan_requirement",
    "typical_metrics",
]

#: Pilot runs when not given.
DEFAULT_PILOT = 20


@dataclass
class RequirementPlan:
    """The plan of one requirement.

    Attributes
    ----------
    id : str
        Requirement id.
    statistic : str
        As written (``"p95"``, ``"rms"``, ...).
    confidence : float
        The confidence it is judged at.
    estimate : float
        The pilot's statistic (sample value: max, rms, mean + k std, sample quantile;
        pass fraction for pass_rate), in ``unit``; nan when it has none.
    limit : float
        The limit of ``estimate`` (the required probability for pass_rate).
    unit : str
        Unit of ``estimate`` and ``limit``.
    pilot_verdict : str
        The verdict on the pilot's runs.
    runs : int or None
        Runs in total to decide at ``confidence`` with probability ``ADVICE_SHARE`` (the
        pilot's runs included; None: not by the cap, or cannot plan).
    verdict : str
        The decision a campaign of ``runs`` runs is aimed at.
    sequential_runs : int or None
        Runs ``verify --until-decided`` takes on typical runs (None: not by its cap).
    note : str
        Why it cannot be planned, or failed pilot runs.
    interval : tuple of float or None
        The pilot's confidence bounds of the statistic (``estimate``'s unit), if any.
    promised : bool
        False when the pilot cannot exclude a true value at the limit: ``runs`` then holds
        only for a true value equal to the pilot's estimate (docs/statistics.md).
    """

    id: str
    statistic: str
    confidence: float
    estimate: float
    limit: float
    unit: str
    pilot_verdict: str
    runs: int | None
    verdict: str
    sequential_runs: int | None
    note: str = ""
    interval: tuple[float, float] | None = None
    promised: bool = True


@dataclass
class Plan:
    """A pilot and the plan of every requirement.

    Attributes
    ----------
    scenario : str
        Scenario name.
    seed : int
        Campaign seed of the pilot.
    pilot : int
        Pilot runs.
    workers : int
        Local worker processes of the pilot (and of the predicted wall times).
    pilot_wall : float
        Wall time of the whole pilot [s].
    run_time : float
        Mean wall time of one run in a worker [s].
    requirements : list of RequirementPlan
        In file order.
    looks : Looks or None
        The looks of ``verify --until-decided --runs pilot`` (None: not predicted).
    cap : int
        Most runs looked at.
    """

    scenario: str
    seed: int
    pilot: int
    workers: int
    pilot_wall: float
    run_time: float
    requirements: list[RequirementPlan]
    looks: Looks | None
    cap: int = CAP

    @property
    def overhead(self) -> float:
        """Fixed cost of a campaign [s]: the pilot's wall time not spent in its runs."""
        return max(0.0, self.pilot_wall - self.pilot * self.run_time / self.workers)

    def wall_time(self, runs: int) -> float:
        """Predicted wall time of a campaign of ``runs`` runs on this machine [s].

        Parameters
        ----------
        runs : int
            Number of runs.

        Returns
        -------
        float
            ``overhead + ceil(runs / workers) * run_time`` [s].
        """
        return self.overhead + math.ceil(runs / self.workers) * self.run_time

    def sequential_wall_time(self, runs: int) -> float:
        """Predicted wall time of ``verify --until-decided`` up to the look at ``runs`` [s].

        Each look is a campaign of its batch (the fixed cost once per look).

        Parameters
        ----------
        runs : int
            One of the looks.

        Returns
        -------
        float
            Sum over the looks up to ``runs`` of ``overhead + ceil(batch / workers) *
            run_time`` [s].
        """
        looks = [n for n in (self.looks.runs if self.looks else (runs,)) if n <= runs]
        batches = np.diff([0, *looks])
        return float(
            sum(self.overhead + math.ceil(b / self.workers) * self.run_time for b in batches)
        )


def typical_metrics(req: Requirement, values: Sequence[float], n: int) -> list[RunMetric]:
    """A campaign of n runs spread as the pilot: its quantiles at (i + 1/2) / n.

    Parameters
    ----------
    req : Requirement
        The requirement (its limit decides each run's pass).
    values : sequence of float, shape (m,)
        The pilot's metrics (completed runs; inf allowed: a run that never settled).
    n : int
        Runs of the typical campaign.

    Returns
    -------
    list of RunMetric, length n
        Nearest-rank quantiles of ``values``, each passing when <= ``req.limit``.
    """
    x = np.sort(np.asarray(values, dtype=float))
    idx = np.minimum((np.floor((np.arange(n) + 0.5) / n * x.size)).astype(int), x.size - 1)
    return [RunMetric(float(v), bool(v <= req.limit)) for v in x[idx]]


def _estimate(req: Requirement, values: np.ndarray) -> tuple[float, float, str]:
    """The pilot's point statistic, its limit and unit."""
    n = values.size
    with np.errstate(over="ignore", invalid="ignore"):
        if req.statistic == "pass_rate":
            return float(np.mean(values <= req.limit)), float(req.probability), "1"
        if req.statistic == "max":
            value = float(np.max(values))
        elif req.statistic == "rms":
            value = float(np.sqrt(np.mean(values**2)))
        elif req.statistic == "mean+ksigma":
            value = float(np.mean(values) + req.k * np.std(values, ddof=1)) if n > 1 else math.nan
        else:
            value = (
                float(np.quantile(values, req.probability))
                if np.isfinite(values).all()
                else math.inf
            )
    return value, req.limit, req.metric_unit


def plan_requirement(
    req: Requirement,
    metrics: Sequence[RunMetric | None],
    looks: Looks | None = None,
    cap: int = CAP,
) -> RequirementPlan:
    """Plan one requirement from its pilot metrics.

    Parameters
    ----------
    req : Requirement
        The requirement.
    metrics : sequence of RunMetric or None, shape (pilot,)
        Its metric in each pilot run (None: a failed run).
    looks : Looks, optional
        Looks of ``verify --until-decided`` to predict its runs too.
    cap : int
        Most runs looked at.

    Returns
    -------
    RequirementPlan
    """
    conf = requirement_confidence(req)
    pilot_verdict = judge(req, metrics, confidence=conf)  # the verdict and advice of verify
    used = [m for m in metrics if m is not None]
    failed = len(metrics) - len(used)
    note = (
        f"{failed} of {len(metrics)} pilot runs failed (on_failure = '{req.on_failure}')"
        if failed
        else ""
    )
    short = [m for m in used if m.passed is None]
    base: dict[str, Any] = {"id": req.id, "statistic": req.statistic_text, "confidence": conf}
    if not used or short:
        why = "every pilot run failed" if not used else f"pilot runs cannot decide: {short[0].note}"
        return RequirementPlan(
            **base, estimate=math.nan, limit=req.limit, unit=req.metric_unit,
            pilot_verdict=pilot_verdict.verdict, runs=None, verdict=UNDECIDED,
            sequential_runs=None, note=why,
        )  # fmt: skip
    values = np.array([m.value for m in used], dtype=float)
    estimate, limit, unit = _estimate(req, values)
    promised = True
    if pilot_verdict.verdict != UNDECIDED:  # the fewest first runs that decide it
        runs = next(
            n for n in range(1, len(metrics) + 1)
            if judge_at(req, metrics[:n], conf).verdict != UNDECIDED
        )  # fmt: skip
        verdict = judge_at(req, metrics[:runs], conf).verdict
    else:
        runs = pilot_verdict.details.get("runs_to_decide")
        verdict = pilot_verdict.details.get("verdict_then", UNDECIDED)
        promised = bool(pilot_verdict.details.get("runs_promised"))
        if runs is None or not promised:
            tip = pilot_verdict.details["advice"]
            note = f"{note}; {tip}" if note else tip
        elif runs > cap:
            runs, verdict = None, UNDECIDED
    seq = None
    if looks is not None:
        for n, c in zip(looks.runs, looks.confidences(conf), strict=True):
            if judge_at(req, typical_metrics(req, values, n), float(c)).verdict != UNDECIDED:
                seq = n
                break
    return RequirementPlan(
        **base, estimate=estimate, limit=limit, unit=unit,
        pilot_verdict=pilot_verdict.verdict, runs=runs, verdict=verdict,
        sequential_runs=seq, note=note, interval=pilot_verdict.interval, promised=promised,
    )  # fmt: skip


def make_plan(
    scenario: str | Path,
    *,
    pilot: int = DEFAULT_PILOT,
    seed: int | None = None,
    workers: int | None = None,
    fmu_dir: str | Path | None = None,
    max_runs: int | None = None,
    progress: bool = True,
    cap: int = CAP,
) -> Plan:
    """Run a pilot campaign (in a temporary folder) and plan every requirement.

    Parameters
    ----------
    scenario : str or Path
        Scenario file with ``[[requirements]]``.
    pilot : int
        Pilot runs (runs 0 .. pilot - 1 of the campaign).
    seed : int, optional
        Campaign seed (default ``[campaign] seed``).
    workers : int, optional
        Local worker processes (default: the CPU count).
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    max_runs : int, optional
        Cap of the ``--until-decided`` prediction (default 16 x pilot).
    progress : bool
        Progress bar on stderr.
    cap : int
        Most runs a requirement's plan looks at.

    Returns
    -------
    Plan

    Raises
    ------
    ScenarioError, FmuError, CampaignError
        Bad input (before any run).
    CampaignInterrupted
        On Ctrl-C.
    """
    if pilot < 1:
        raise CampaignError(f"--pilot must be >= 1, got {pilot}")
    if workers is None:
        workers = os.cpu_count() or 1
    with tempfile.TemporaryDirectory(prefix="ins-cosim-plan-") as tmp:
        t0 = time.perf_counter()
        campaign = run_campaign(
            scenario, Path(tmp) / "pilot", runs=pilot, seed=seed, workers=workers,
            fmu_dir=fmu_dir, progress=progress,
        )  # fmt: skip
        wall = time.perf_counter() - t0
    # a stratified pilot is the first look of --until-decided too (its first look batch)
    looks = plan_looks(pilot, max_runs if max_runs is not None else default_max_runs(pilot))
    plans = []
    for req in campaign.requirements:
        metrics = [r.metrics.get(req.id) for r in campaign.records]
        plans.append(plan_requirement(req, metrics, looks, cap))
    times = [r.wall_time for r in campaign.records if r.wall_time > 0]
    return Plan(
        scenario=campaign.scenario["name"], seed=campaign.settings.seed, pilot=pilot,
        workers=workers, pilot_wall=wall, run_time=float(np.mean(times)) if times else 0.0,
        requirements=plans, looks=looks, cap=cap,
    )  # fmt: skip


def format_duration(seconds: float) -> str:
    """A duration for people: ``"42 s"``, ``"3.5 min"``, ``"2.1 h"``, ``"3.0 d"``.

    Parameters
    ----------
    seconds : float
        Duration [s].

    Returns
    -------
    str
    """
    if seconds < 60:
        return f"{seconds:.2g} s" if seconds < 10 else f"{seconds:.0f} s"
    if seconds < 3600:
        return f"{seconds / 60:.1f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} d"


def _value(x: float, unit: str) -> str:
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf" if unit != "s" else "not settled"
    return f"{x:.4g}" if unit in ("1", "") else f"{x:.4g} {unit}"


def format_plan(plan: Plan) -> str:
    """The plan as text: the pilot, one row per requirement, the method.

    Parameters
    ----------
    plan : Plan
        From :func:`make_plan`.

    Returns
    -------
    str
        Lines without a trailing newline.
    """
    lines = [
        f"pilot: {plan.pilot} runs of '{plan.scenario}' (campaign seed {plan.seed}, runs 0 to "
        f"{plan.pilot - 1}) in {format_duration(plan.pilot_wall)} on {plan.workers} worker(s): "
        f"{plan.run_time:.3g} s per run and worker, {format_duration(plan.overhead)} fixed cost"
    ]
    seq_head = "--until-decided" if plan.looks is not None else ""
    header = ["requirement", "statistic", "pilot value", "pilot bounds", "limit",
              "pilot verdict", "runs to decide", "verdict then", "wall time", seq_head]  # fmt: skip
    rows = []
    for p in plan.requirements:
        runs = f"> {plan.cap}" if p.runs is None else str(p.runs)
        if p.runs is not None and not p.promised:
            runs = f"({p.runs})"
        wall = "-" if p.runs is None else format_duration(plan.wall_time(p.runs))
        if plan.looks is None:
            seq = ""
        elif p.sequential_runs is None:
            seq = f"not by {plan.looks.cap}"
        else:
            seq = p.sequential_runs
            seq = f"{seq} runs, {format_duration(plan.sequential_wall_time(seq))}"
        conf = f"{p.statistic} ({100 * p.confidence:g} %)"
        then = p.verdict if p.runs is not None else "-"
        value, limit = _value(p.estimate, p.unit), _value(p.limit, p.unit)
        bounds = "-"
        if p.interval is not None:
            bounds = f"[{_value(p.interval[0], '1')}, {_value(p.interval[1], '1')}]"
        rows.append([p.id, conf, value, bounds, limit, p.pilot_verdict, runs, then, wall, seq])
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for r in [header, *rows]:
        lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())
    for p in plan.requirements:
        if p.note:
            lines.append(f"note: {p.id}: {p.note}")
    lines.append(
        f"runs to decide: the runs in total, the pilot's included, at which the campaign is "
        f"decided with probability {100 * ADVICE_SHARE:g} % for a true value at or beyond the "
        f"pilot's one-sided {100 * PROMISE_LEVEL:g} % bound (what "
        f"`verify --runs {plan.pilot}` advises on the same runs; docs/statistics.md); for a "
        f"requirement the pilot decides, the fewest of its first runs that decide it; (N): the "
        f"pilot cannot exclude a true value at the limit, N holds only if the truth is as "
        f"far from it as the pilot's estimate (note). The "
        f"pilot's value is itself uncertain (pilot bounds: its confidence bounds at the "
        f"requirement's confidence)."
    )
    if plan.looks is not None:
        looks = ", ".join(str(n) for n in plan.looks.runs)
        lines.append(
            f"--until-decided: the look at which `verify --until-decided --runs {plan.pilot} "
            f"--max-runs {plan.looks.cap}` (looks at {looks} runs) decides those runs."
        )
    lines.append(
        f"wall time: {format_duration(plan.overhead)} + runs / {plan.workers} x "
        f"{plan.run_time:.3g} s on this machine (from the pilot); --until-decided pays the "
        f"fixed cost once per look."
    )
    notes = len(rows) + 1 + sum(bool(p.note) for p in plan.requirements)
    return "\n".join(lines[: notes + 1] + [textwrap.fill(t, 100) for t in lines[notes + 1 :]])
