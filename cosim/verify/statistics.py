"""Campaign verdicts: the three-valued verdict of a requirement from confidence bounds.

:func:`judge` turns the per-run metrics of one requirement (:mod:`cosim.verify.requirements`)
into a :class:`~cosim.verify.requirements.Verdict`: satisfied when the statistic's
one-sided upper confidence bound meets the limit, violated when its lower bound is over
it (``max``: when a run is over it), else undecided, with the claim about all runs it
supports in words. The bounds are in :mod:`cosim.verify.bounds` (re-exported here); the
theory of each statistic is in docs/verification.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from cosim.verify.advice import advise as runs_advice
from cosim.verify.advice import replay_advice
from cosim.verify.bounds import (
    BOOTSTRAP_MIN_RUNS,
    clopper_pearson,
    ksigma_bootstrap_bounds,
    ksigma_normal_bounds,
    max_bounds,
    rms_bounds,
    wilks_lower_rank,
    wilks_min_runs,
    wilks_upper_bound,
    wilks_upper_rank,
)
from cosim.verify.requirements import (
    DEFAULT_ASSUME,
    DEFAULT_CONFIDENCE,
    DEFAULT_MAX_PROBABILITY,
    SATISFIED,
    UNDECIDED,
    VIOLATED,
    Requirement,
    RunMetric,
    Verdict,
)

__all__ = [
    "clopper_pearson",
    "judge",
    "ksigma_bootstrap_bounds",
    "ksigma_normal_bounds",
    "max_bounds",
    "overall_exit_code",
    "rms_bounds",
    "wilks_lower_rank",
    "wilks_min_runs",
    "wilks_upper_bound",
    "wilks_upper_rank",
]


# ------------------------------------------------------------------------------ verdicts
def judge(
    req: Requirement,
    metrics: Sequence[RunMetric | None],
    *,
    confidence: float | None = None,
    advise: bool = True,
    replayed: Sequence[str] = (),
) -> Verdict:
    """The campaign verdict of one requirement.

    Parameters
    ----------
    req : Requirement
        The requirement.
    metrics : sequence of RunMetric or None, shape (n_runs,)
        One per run in run order; None for a run that failed.
    confidence : float, optional
        Confidence of every bound instead of the requirement's own (e.g. a share of
        ``1 - confidence`` spent at one look of a sequential campaign).
    advise : bool
        Add to an undecided verdict the runs in total that would decide it
        (:func:`cosim.verify.advice.advise`, from the runs made): ``details``
        ``runs_to_decide`` and one clause in ``reason`` and ``claim``.
    replayed : sequence of str
        Blocks that replay a recorded log: every run sees the same data, so more runs
        redraw only the other blocks' seeds and cannot decide; the advice of an undecided
        verdict says so and what would (:func:`cosim.verify.advice.replay_advice`).

    Returns
    -------
    Verdict
        See docs/verification.md ("Verdict rules"): satisfied when the statistic's upper bound
        meets the limit, violated when its lower bound is over it (``max``: when a run
        is over it), else undecided; a run too short to decide makes the verdict
        undecided; failed runs follow ``req.on_failure``. ``claim`` says in words what
        the verdict shows about all runs.
    """
    gamma = confidence if confidence is not None else req.confidence
    gamma = DEFAULT_CONFIDENCE if gamma is None else float(gamma)
    if not 0.0 < gamma < 1.0:
        raise ValueError(f"confidence: expected a value in (0, 1), got {gamma}")
    changes: dict[str, Any] = {"confidence": gamma}
    if req.statistic == "max" and req.probability is None:
        changes["probability"] = DEFAULT_MAX_PROBABILITY
    if req.statistic in DEFAULT_ASSUME and req.assume is None:
        changes["assume"] = DEFAULT_ASSUME[req.statistic]
    full = replace(req, **changes)
    verdict = _judge(full, metrics)
    verdict.statistic = req.statistic
    verdict.details.setdefault("confidence", gamma)
    flagged = [(i, m.note) for i, m in enumerate(metrics) if m and m.passed is False and m.note]
    if req.criterion == "consistent" and flagged:  # say where the filter is off
        verdict.reason += (
            f"; {len(flagged)} run(s) flagged, e.g. run {flagged[0][0]}: {flagged[0][1]}"
        )
        verdict.details["flagged_runs"] = [i for i, _ in flagged]
    if advise and verdict.verdict == UNDECIDED:
        if replayed:
            tip = replay_advice(replayed, len(metrics))
        else:
            tip = runs_advice(full, metrics, gamma)
        verdict.details["runs_to_decide"] = tip.runs
        verdict.details["runs_advice"] = tip.method
        verdict.details["verdict_then"] = tip.verdict
        verdict.details["runs_promised"] = tip.promised
        verdict.details["advice"] = tip.text()
        verdict.reason += f"; {tip.text()}"  # the claim stays what is shown (not the advice)
    return verdict


def _judge(req: Requirement, metrics: Sequence[RunMetric | None]) -> Verdict:
    """:func:`judge` without the statistic's name."""
    n_runs = len(metrics)
    failed = [i for i, m in enumerate(metrics) if m is None]
    used: list[RunMetric] = []
    for m in metrics:
        if m is not None:
            used.append(m)
        elif req.on_failure == "fail":
            used.append(RunMetric(math.inf, False, "run failed"))
    base = {"n_runs": n_runs, "n_failed": len(failed)}
    if not used:
        why = f"no completed run (all {n_runs} failed)" if n_runs else "no run"
        return Verdict(
            req.id,
            UNDECIDED,
            math.nan,
            *_limit(req),
            why,
            n_used=0,
            claim="nothing is shown about the runs",
            **base,
        )
    short = [m for m in used if m.passed is None]
    if short:
        why = f"{len(short)} of {len(used)} runs cannot decide: {short[0].note}"
        return Verdict(
            req.id,
            UNDECIDED,
            math.nan,
            *_limit(req),
            why,
            n_used=len(used),
            claim="nothing is shown about the runs",
            **base,
        )
    verdict = _statistic(req, used)
    verdict.n_runs, verdict.n_failed = n_runs, len(failed)
    if failed and req.on_failure == "undecided":
        runs = ", ".join(str(i) for i in failed[:10]) + (" ..." if len(failed) > 10 else "")
        # Still violated if the failed runs could not have changed that: replace them by
        # their most favourable outcome and judge again.
        best = _best_case(req, used, len(failed))
        if best is not None and best.verdict == VIOLATED:
            verdict.reason += (
                f" (violated whatever the {len(failed)} failed run(s) would have given: "
                f"run(s) {runs})"
            )
            verdict.claim += f", whatever the {len(failed)} failed run(s) would have given"
            return verdict
        verdict.details["judged_on_completed_runs"] = verdict.verdict
        verdict.verdict = UNDECIDED
        verdict.reason = (
            f"{len(failed)} of {n_runs} runs failed (run(s) {runs}); on_failure = 'undecided'. "
            f"On the {len(used)} completed runs: {verdict.reason}"
        )
        verdict.claim = (
            f"nothing is shown while {len(failed)} run(s) failed; the completed runs alone "
            f"would show: {verdict.claim}"
        )
    elif failed and req.on_failure == "exclude":
        verdict.reason += f" ({len(failed)} failed run(s) excluded)"
        verdict.claim += f" (of runs that complete; {len(failed)} failed run(s) excluded)"
    elif failed:
        verdict.reason += f" ({len(failed)} failed run(s) counted as failing)"
    return verdict


def _limit(req: Requirement) -> tuple[float, str]:
    if req.statistic == "pass_rate":
        return float(req.probability), "1"
    return req.limit, req.metric_unit


def _best_case(req: Requirement, used: list[RunMetric], n_failed: int) -> Verdict | None:
    """The verdict if every failed run had given the most favourable metric."""
    if req.statistic in ("max", "quantile", "pass_rate"):
        best = -math.inf
    elif req.statistic == "rms":
        best = 0.0
    else:  # mean + k sigma is not monotone in each sample
        return None
    return _statistic(req, used + [RunMetric(best, True)] * n_failed)


def _fmt(x: float, unit: str) -> str:
    if math.isinf(x):
        return "not settled" if unit == "s" and x > 0 else f"{x}"
    return f"{x:.4g} {unit}" if unit not in ("1", "") else f"{x:.4g}"


_ASSUMPTION = {  # (method, assumption) of the rms and mean+ksigma bounds
    ("rms", "normal"): ("chi-square", "assumes metrics no heavier-tailed than |e| of a normal e"),
    ("mean+ksigma", "normal"): ("noncentral t", "assumes normally distributed metrics"),
    ("mean+ksigma", "none"): ("bootstrap", "approximate, no distribution assumed"),
}


def _statistic(req: Requirement, used: list[RunMetric]) -> Verdict:
    values = np.array([m.value for m in used], dtype=float)
    n = values.size
    n_pass = int(sum(bool(m.passed) for m in used))
    unit = req.metric_unit
    lim = _fmt(req.limit, unit)
    gamma = float(req.confidence)
    conf = f"{100 * gamma:g} %"
    common: dict[str, Any] = {"n_used": n, "n_pass": n_pass}
    name = req.statistic_text
    if req.statistic == "max":
        return _max(req, values, common)
    if req.statistic in ("rms", "mean+ksigma"):
        what = "the RMS" if req.statistic == "rms" else name
        key = (req.statistic, req.assume)
        method, assumption = _ASSUMPTION[key]
        details: dict[str, Any] = {"method": method, "assumption": f"{method} bound, {assumption}"}
        if req.statistic == "rms":
            with np.errstate(over="ignore"):
                value = float(np.sqrt(np.mean(values**2)))
                if math.isfinite(value) and value > 0:
                    details["tail_ratio"] = float(np.mean(values**4) / np.mean(values**2) ** 2)
            lower, upper = rms_bounds(values, gamma)
        else:
            need = BOOTSTRAP_MIN_RUNS if req.assume == "none" else 2
            if n < need:
                why = f"{name} needs at least {need} runs for its {conf} bounds, got {n}"
                if req.assume == "none":
                    why += " (assume = 'normal' needs 2, for normally distributed metrics)"
                return Verdict(
                    req.id,
                    UNDECIDED,
                    math.nan,
                    req.limit,
                    unit,
                    why,
                    claim="nothing is shown about the runs",
                    details={"runs_to_decide": need, **details},
                    **common,
                )
            if np.any(np.isinf(values)):
                value = lower = upper = math.inf
            else:
                value = float(np.mean(values) + req.k * np.std(values, ddof=1))
                bounds = ksigma_bootstrap_bounds if req.assume == "none" else ksigma_normal_bounds
                lower, upper = bounds(values, req.k, gamma)
        return _bounded(req, value, lower, upper, what, details, common)
    if req.statistic == "quantile":
        return _quantile(req, values, common)
    # pass rate
    p = float(req.probability)
    lower, upper = clopper_pearson(n_pass, n, gamma)
    rate = n_pass / n
    observed = f"{n_pass}/{n} runs meet {lim}"
    share = f"of runs meet {lim}"
    if lower >= p:
        verdict = SATISFIED
        reason = f"{observed}; {conf} lower bound of the pass rate {lower:.4f} >= {p:g}"
        claim = f"with {conf} confidence at least {100 * lower:.3g} % {share} (>= {100 * p:g} %)"
    elif upper < p:
        verdict = VIOLATED
        reason = f"{observed}; {conf} upper bound of the pass rate {upper:.4f} < {p:g}"
        claim = f"with {conf} confidence fewer than {100 * upper:.3g} % {share} (< {100 * p:g} %)"
    else:
        verdict = UNDECIDED
        reason = (
            f"{observed}; the pass rate's {conf} bounds [{lower:.4f}, {upper:.4f}] contain "
            f"{p:g}: more runs needed"
        )
        claim = (
            f"with {conf} confidence between {100 * lower:.3g} % and {100 * upper:.3g} % {share}: "
            f"neither at least {100 * p:g} % nor less is shown"
        )
    return Verdict(
        req.id,
        verdict,
        rate,
        p,
        "1",
        reason,
        interval=(lower, upper),
        details={"per_run_limit": req.limit, "per_run_unit": unit, "method": "Clopper-Pearson"},
        claim=claim + " (no distribution assumed)",
        **common,
    )


def _bounded(
    req: Requirement,
    value: float,
    lower: float,
    upper: float,
    what: str,
    details: dict[str, Any],
    common: dict[str, Any],
) -> Verdict:
    """Three-valued verdict of an estimate with one-sided bounds (rms, mean+ksigma)."""
    unit, n = req.metric_unit, common["n_used"]
    lim = _fmt(req.limit, unit)
    conf = f"{100 * req.confidence:g} %"
    pop = f"{what} over all runs"
    interval = f"[{_fmt(lower, unit)}, {_fmt(upper, unit)}]"
    observed = f"{req.statistic_text} = {_fmt(value, unit)} over {n} run(s)"
    if upper <= req.limit:
        verdict = SATISFIED
        reason = f"{observed}; its {conf} upper bound {_fmt(upper, unit)} <= {lim}"
        claim = f"with {conf} confidence {pop} is below {_fmt(upper, unit)} (<= {lim})"
    elif lower > req.limit:
        verdict = VIOLATED
        reason = f"{observed}; its {conf} lower bound {_fmt(lower, unit)} > {lim}"
        claim = f"with {conf} confidence {pop} is above {_fmt(lower, unit)} (> {lim})"
    else:
        verdict = UNDECIDED
        tip = "more runs needed"
        side = "<=" if value <= req.limit else ">"
        reason = (
            f"{observed} {side} {lim}, but its {conf} confidence bounds {interval} contain "
            f"{lim}: {tip}"
        )
        claim = (
            f"with {conf} confidence {pop} lies in {interval}: it is not shown to be below "
            f"{lim}, nor above it; {tip}"
        )
    return Verdict(
        req.id,
        verdict,
        value,
        req.limit,
        unit,
        reason,
        interval=(lower, upper),
        details=details,
        claim=f"{claim} ({details['assumption']})",
        **common,
    )


def _max(req: Requirement, values: np.ndarray, common: dict[str, Any]) -> Verdict:
    """``max``: every run must meet the limit.

    A run over the limit proves the requirement false (no confidence needed). No number
    of passing runs proves that every run passes; n passing runs show, with confidence
    ``1 - p^n``, that the p-quantile meets the limit, so the verdict is satisfied when
    that confidence reaches the requirement's.
    """
    unit, n = req.metric_unit, common["n_used"]
    lim = _fmt(req.limit, unit)
    p, gamma = float(req.probability), float(req.confidence)
    conf = f"{100 * gamma:g} %"
    top = float(np.max(values))
    lower, upper = max_bounds(values, p, gamma)
    need = wilks_min_runs(p, gamma)
    n_over = int(np.sum(values > req.limit))
    details: dict[str, Any] = {
        "probability": p,
        "runs_needed": need,
        "population_max_lower_bound": top,
        "method": "Wilks (sample maximum)",
    }
    if top > req.limit:
        rate_up = clopper_pearson(n - n_over, n, gamma)[1]
        verdict = VIOLATED
        reason = f"max = {_fmt(top, unit)} > {lim} ({n_over} of {n} runs over the limit)"
        claim = (
            f"not every run meets {lim}: {n_over} of {n} runs exceed it (up to "
            f"{_fmt(top, unit)}), which is certain, and with {conf} confidence fewer than "
            f"{100 * rate_up:.3g} % of runs meet it"
        )
    else:
        shown = (1.0 - gamma) ** (1.0 / n)  # largest p with 1 - p^n >= gamma
        details["fraction_shown"] = shown
        ok = n >= need
        verdict = SATISFIED if ok else UNDECIDED
        reason = f"max = {_fmt(top, unit)} <= {lim} over {n} run(s)"
        claim = (
            f"all {n} runs meet {lim}: with {conf} confidence at least {100 * shown:.3g} % of "
            f"runs meet it"
        )
        if ok:
            reason += f"; 1 - {p:g}^{n} = {1 - p**n:.4f} >= {gamma:g}"
            claim += f" (>= {100 * p:g} %); that every run meets it is not shown"
        else:
            reason += (
                f", but {n} passing runs show the {100 * p:g} % quantile only at "
                f"{100 * (1 - p**n):.3g} % confidence: {need} runs in total, all passing, "
                f"show it"
            )
            claim += f", less than {100 * p:g} %"
    return Verdict(
        req.id,
        verdict,
        top,
        req.limit,
        unit,
        reason,
        interval=(lower, upper),
        details=details,
        claim=claim + " (no distribution assumed)",
        **common,
    )


def _quantile(req: Requirement, values: np.ndarray, common: dict[str, Any]) -> Verdict:
    """``p<q>``: Wilks' order-statistic bounds of the q-th percentile."""
    unit, n = req.metric_unit, common["n_used"]
    lim = _fmt(req.limit, unit)
    name = req.statistic_text
    p, gamma = float(req.probability), float(req.confidence)
    conf = f"{100 * gamma:g} %"
    x = np.sort(values)
    r_up = wilks_upper_rank(n, p, gamma)
    r_lo = wilks_lower_rank(n, p, gamma)
    upper = float(x[r_up - 1]) if r_up is not None else math.inf
    lower = float(x[r_lo - 1]) if r_lo is not None else -math.inf
    finite = x[np.isfinite(x)]
    details = {
        "sample_quantile": float(np.quantile(x, p)) if finite.size == n else math.nan,
        "statistic_text": name,
        "upper_rank": r_up,
        "lower_rank": r_lo,
        "runs_needed_for_max": wilks_min_runs(p, gamma),
        "method": "Wilks",
    }
    pct = f"{100 * p:g} %"
    if r_up is not None and upper <= req.limit:
        verdict, value = SATISFIED, upper
        reason = (
            f"{name} upper bound ({conf} confidence, order statistic {r_up} of {n}) = "
            f"{_fmt(upper, unit)} <= {lim}"
        )
        claim = (
            f"{pct} of runs meet {lim} with {conf} confidence (the {name} is at most "
            f"{_fmt(upper, unit)})"
        )
    elif r_lo is not None and lower > req.limit:
        verdict, value = VIOLATED, lower
        reason = (
            f"{name} lower bound ({conf} confidence, order statistic {r_lo} of {n}) = "
            f"{_fmt(lower, unit)} > {lim}"
        )
        claim = (
            f"with {conf} confidence more than {100 * (1 - p):.3g} % of runs exceed {lim} "
            f"(the {name} is above {_fmt(lower, unit)})"
        )
    else:
        verdict, value = UNDECIDED, upper
        if r_up is None:
            reason = (
                f"too few runs: a {conf} upper bound of the {name} needs at least "
                f"{details['runs_needed_for_max']} runs, got {n}"
            )
            claim = (
                f"{n} runs bound the {name} from above at {conf} confidence by nothing: "
                f"that {pct} of runs meet {lim} is not shown"
            )
        else:
            reason = (
                f"the {conf} confidence interval of the {name}, [{_fmt(lower, unit)}, "
                f"{_fmt(upper, unit)}], contains the bound {lim}"
            )
            claim = (
                f"with {conf} confidence the {name} lies in [{_fmt(lower, unit)}, "
                f"{_fmt(upper, unit)}]: neither that {pct} of runs meet {lim} nor that they "
                f"do not is shown"
            )
    return Verdict(
        req.id,
        verdict,
        value,
        req.limit,
        unit,
        reason,
        interval=(lower, upper),
        details=details,
        claim=claim + " (no distribution assumed)",
        **common,
    )


def overall_exit_code(verdicts: Sequence[Verdict]) -> int:
    """0 when every verdict is satisfied, 1 when any is violated, else 2 (undecided).

    Parameters
    ----------
    verdicts : sequence of Verdict
        The campaign's verdicts.

    Returns
    -------
    int
        The exit code of ``ins-cosim verify``.
    """
    kinds = {v.verdict for v in verdicts}
    if VIOLATED in kinds:
        return 1
    if UNDECIDED in kinds or not verdicts:
        return 2
    return 0
