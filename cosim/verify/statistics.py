"""Campaign statistics: order-statistic and binomial bounds, and the verdict of a requirement.

:func:`judge` turns the per-run metrics of one requirement (:mod:`cosim.verify.requirements`)
into a three-valued :class:`~cosim.verify.requirements.Verdict`; the theory of each
statistic is in the README ("Verification and campaigns") and in the docstring of
:mod:`cosim.verify.requirements`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cosim.verify.requirements import (
    SATISFIED,
    UNDECIDED,
    VIOLATED,
    Requirement,
    RunMetric,
    Verdict,
)


def wilks_upper_rank(n: int, p: float, confidence: float) -> int | None:
    """Rank of the order statistic that is an upper tolerance bound (Wilks).

    The r-th smallest of n independent samples, X_(r), exceeds the p-quantile x_p of a
    continuous distribution unless at least r samples fall below x_p, so
    ``P(X_(r) >= x_p) = P(B <= r - 1)`` with ``B ~ Binomial(n, p)``. The smallest r with
    ``P >= confidence`` gives the tightest bound; r = n (the sample maximum) needs
    ``1 - p**n >= confidence`` (59 runs at 95 %/95 %).

    Parameters
    ----------
    n : int
        Number of samples.
    p : float
        Quantile level (coverage), 0 < p < 1.
    confidence : float
        Confidence level, 0 < confidence < 1.

    Returns
    -------
    int or None
        Rank r (1 = smallest, n = largest), or None when n samples are too few.
    """
    from scipy import stats  # imported here: campaign workers never need it

    if n < 1:
        return None
    ranks = np.arange(1, n + 1)
    ok = stats.binom.cdf(ranks - 1, n, p) >= confidence
    return int(ranks[ok][0]) if ok.any() else None


def wilks_lower_rank(n: int, p: float, confidence: float) -> int | None:
    """Rank of the order statistic that is a lower confidence bound of the p-quantile.

    ``P(X_(r) <= x_p) = P(B >= r)`` with ``B ~ Binomial(n, p)``; the largest r with
    ``P >= confidence`` gives the tightest bound.

    Parameters
    ----------
    n : int
        Number of samples.
    p : float
        Quantile level, 0 < p < 1.
    confidence : float
        Confidence level, 0 < confidence < 1.

    Returns
    -------
    int or None
        Rank r (1 = smallest), or None when n samples are too few.
    """
    from scipy import stats

    if n < 1:
        return None
    ranks = np.arange(1, n + 1)
    ok = stats.binom.sf(ranks - 1, n, p) >= confidence
    return int(ranks[ok][-1]) if ok.any() else None


def wilks_min_runs(p: float, confidence: float) -> int:
    """Fewest samples for which the maximum bounds the p-quantile at ``confidence``.

    ``1 - p**n >= confidence``  <=>  ``n >= ln(1 - confidence) / ln(p)``.

    Parameters
    ----------
    p : float
        Quantile level, 0 < p < 1.
    confidence : float
        Confidence level, 0 < confidence < 1.

    Returns
    -------
    int
        The smallest such n (59 for 0.95/0.95, 45 for 0.95/0.90, 299 for 0.99/0.95).
    """
    n = max(1, math.ceil(math.log1p(-confidence) / math.log(p) - 1e-12))
    while 1.0 - p**n < confidence:  # guard the ceil against rounding
        n += 1
    return n


def wilks_upper_bound(values: Sequence[float], p: float, confidence: float) -> float | None:
    """Wilks' one-sided upper tolerance bound of the p-quantile.

    Parameters
    ----------
    values : sequence of float, shape (n,)
        Independent samples.
    p, confidence : float
        Quantile level and confidence.

    Returns
    -------
    float or None
        The order statistic of rank :func:`wilks_upper_rank`, or None if too few samples.
    """
    x = np.sort(np.asarray(values, dtype=float))
    r = wilks_upper_rank(x.size, p, confidence)
    return None if r is None else float(x[r - 1])


def clopper_pearson(k: int, n: int, confidence: float) -> tuple[float, float]:
    """One-sided Clopper-Pearson bounds of a success probability.

    With k successes in n trials, the lower bound L solves ``P(Bin(n, L) >= k) =
    1 - confidence`` and the upper bound U solves ``P(Bin(n, U) <= k) = 1 - confidence``:
    ``L = Beta.ppf(1 - confidence; k, n - k + 1)`` (0 when k = 0) and
    ``U = Beta.ppf(confidence; k + 1, n - k)`` (1 when k = n). Each bound holds on its
    own with probability >= ``confidence``.

    Parameters
    ----------
    k : int
        Successes (runs that met the limit), 0 <= k <= n.
    n : int
        Trials (runs), n >= 1.
    confidence : float
        Confidence of each one-sided bound.

    Returns
    -------
    (float, float)
        (L, U).
    """
    from scipy import stats

    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k = {k}, n = {n}")
    lower = 0.0 if k == 0 else float(stats.beta.ppf(1.0 - confidence, k, n - k + 1))
    upper = 1.0 if k == n else float(stats.beta.ppf(confidence, k + 1, n - k))
    return lower, upper


def judge(req: Requirement, metrics: Sequence[RunMetric | None]) -> Verdict:
    """The campaign verdict of one requirement.

    Parameters
    ----------
    req : Requirement
        The requirement.
    metrics : sequence of RunMetric or None, shape (n_runs,)
        One per run in run order; None for a run that failed.

    Returns
    -------
    Verdict
        See the README ("Verdict rules"): a run too short to decide makes the verdict
        undecided; failed runs follow ``req.on_failure``.
    """
    verdict = _judge(req, metrics)
    verdict.statistic = req.statistic
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
        return Verdict(
            req.id,
            UNDECIDED,
            math.nan,
            *_limit(req),
            f"no completed run (all {n_runs} failed)" if n_runs else "no run",
            n_used=0,
            **base,
        )
    short = [m for m in used if m.passed is None]
    if short:
        return Verdict(
            req.id,
            UNDECIDED,
            math.nan,
            *_limit(req),
            f"{len(short)} of {len(used)} runs cannot decide: {short[0].note}",
            n_used=len(used),
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
            return verdict
        verdict.details["judged_on_completed_runs"] = verdict.verdict
        verdict.verdict = UNDECIDED
        verdict.reason = (
            f"{len(failed)} of {n_runs} runs failed (run(s) {runs}); on_failure = 'undecided'. "
            f"On the {len(used)} completed runs: {verdict.reason}"
        )
    elif failed and req.on_failure == "exclude":
        verdict.reason += f" ({len(failed)} failed run(s) excluded)"
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


def _statistic(req: Requirement, used: list[RunMetric]) -> Verdict:
    values = np.array([m.value for m in used], dtype=float)
    n = values.size
    n_pass = int(sum(bool(m.passed) for m in used))
    unit = req.metric_unit
    lim = _fmt(req.limit, unit)
    common = {"n_used": n, "n_pass": n_pass}
    name = req.statistic_text

    def decide(value: float, what: str) -> Verdict:
        ok = value <= req.limit
        sign = "<=" if ok else ">"
        return Verdict(
            req.id,
            SATISFIED if ok else VIOLATED,
            value,
            req.limit,
            unit,
            f"{what} = {_fmt(value, unit)} {sign} {lim} over {n} run(s)",
            **common,
        )

    if req.statistic == "max":
        return decide(float(np.max(values)), "max")
    if req.statistic == "rms":
        with np.errstate(over="ignore"):
            return decide(float(np.sqrt(np.mean(values**2))), "rms")
    if req.statistic == "mean+ksigma":
        if n < 2:
            return Verdict(
                req.id,
                UNDECIDED,
                math.nan,
                req.limit,
                unit,
                f"{name} needs at least 2 runs, got {n}",
                **common,
            )
        if np.any(np.isinf(values)):
            value = math.inf
        else:
            value = float(np.mean(values) + req.k * np.std(values, ddof=1))
        return decide(value, name)
    if req.statistic == "quantile":
        p, gamma = float(req.probability), float(req.confidence)
        x = np.sort(values)
        r_up = wilks_upper_rank(n, p, gamma)
        r_lo = wilks_lower_rank(n, p, gamma)
        upper = float(x[r_up - 1]) if r_up is not None else math.inf
        lower = float(x[r_lo - 1]) if r_lo is not None else -math.inf
        finite = x[np.isfinite(x)]
        details = {
            "sample_quantile": float(np.quantile(x, p)) if finite.size == n else math.nan,
            "upper_rank": r_up,
            "lower_rank": r_lo,
            "runs_needed_for_max": wilks_min_runs(p, gamma),
        }
        conf = f"{100 * gamma:g} %"
        if r_up is not None and upper <= req.limit:
            verdict, value = SATISFIED, upper
            reason = (
                f"{name} upper bound ({conf} confidence, order statistic {r_up} of {n}) = "
                f"{_fmt(upper, unit)} <= {lim}"
            )
        elif r_lo is not None and lower > req.limit:
            verdict, value = VIOLATED, lower
            reason = (
                f"{name} lower bound ({conf} confidence, order statistic {r_lo} of {n}) = "
                f"{_fmt(lower, unit)} > {lim}"
            )
        else:
            verdict, value = UNDECIDED, upper
            if r_up is None:
                reason = (
                    f"too few runs: a {conf} upper bound of the {name} needs at least "
                    f"{details['runs_needed_for_max']} runs, got {n}"
                )
            else:
                reason = (
                    f"the {conf} confidence interval of the {name}, [{_fmt(lower, unit)}, "
                    f"{_fmt(upper, unit)}], contains the bound {lim}: more runs needed"
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
            **common,
        )
    # pass rate
    p, gamma = float(req.probability), float(req.confidence)
    lower, upper = clopper_pearson(n_pass, n, gamma)
    rate = n_pass / n
    conf = f"{100 * gamma:g} %"
    observed = f"{n_pass}/{n} runs meet {lim}"
    if lower >= p:
        verdict = SATISFIED
        reason = f"{observed}; {conf} lower bound of the pass rate {lower:.4f} >= {p:g}"
    elif upper < p:
        verdict = VIOLATED
        reason = f"{observed}; {conf} upper bound of the pass rate {upper:.4f} < {p:g}"
    else:
        verdict = UNDECIDED
        need = wilks_min_runs(p, gamma)
        reason = (
            f"{observed}; the pass rate's {conf} bounds [{lower:.4f}, {upper:.4f}] contain "
            f"{p:g}: more runs needed (at least {need} runs, all passing)"
        )
    return Verdict(
        req.id,
        verdict,
        rate,
        p,
        "1",
        reason,
        interval=(lower, upper),
        details={"per_run_limit": req.limit, "per_run_unit": unit},
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
