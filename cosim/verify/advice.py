"""Runs-needed advice: how many runs in total would decide a requirement, given the runs made.

One function, :func:`advise`, gives the advice that ``verify`` prints under an undecided
verdict and that ``plan`` prints for its pilot, so the two agree on the same runs. It
predicts, from the runs already made (failed runs included as the requirement's
``on_failure`` counts them), the distribution of the verdict after more runs of the same
campaign, and returns the fewest runs in total N at which the campaign is decided
(satisfied or violated) with probability at least ``share`` (default
:data:`ADVICE_SHARE`, 80 %). The runs made stay in the campaign: with 19 of 20 runs
passing, the advice is about the 20 runs plus a few more, not a fresh campaign.

The prediction per statistic (each with the statistic's own bound at N runs, as
:func:`cosim.verify.statistics.judge` applies it):

- ``pass_rate``, ``p<q>``, ``max``: these verdicts depend only on how many runs meet the
  limit. With k of the n runs made over it, the share of runs over the limit has the
  Jeffreys posterior Beta(k + 1/2, n - k + 1/2), so the count over the limit among m
  more runs is beta-binomial; the verdict at N = n + m is evaluated for every count
  (Clopper-Pearson bounds for ``pass_rate``, Wilks' order-statistic ranks for ``p<q>``,
  every run passing and ``1 - p^N >= confidence`` for ``max``) and weighted by its
  probability. Exact sums, no simulation.
- ``rms``: under the bound's own model (each metric is ``|e|`` of a zero-mean normal e)
  the sum of squares S_m of m more runs over the sum S_n of the n made is
  ``(m / n) F(m, n)`` whatever the true sigma (a pivot), so the probability that
  ``S_n + S_m`` lands outside the chi-square bounds at N is one F-distribution value.
- ``mean+ksigma``: normal metrics; the mean and variance of the runs to come are drawn
  from the posterior predictive of the runs made (noninformative prior; 4000 draws with a
  fixed seed), and judged with the noncentral-t factors at N. With ``assume = "none"``
  (bootstrap bounds, at least 10 runs) the advice uses the same normal-theory factors: an
  approximation, said in the method.

Failed runs: ``on_failure = "fail"`` counts them as runs over the limit (and future runs
fail as often, through the posterior); ``"exclude"`` predicts the completed runs and
scales the runs in total by the share that completed; ``"undecided"`` gives no advice
while a run failed (no number of runs decides it). Runs too short to decide give none.

The share is a prediction, not a guarantee: tests/test_advice.py simulates campaigns
that follow the advice and counts how many it decides.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cosim.verify.bounds import (
    BOOTSTRAP_MIN_RUNS,
    wilks_lower_rank,
    wilks_min_runs,
    wilks_upper_rank,
)
from cosim.verify.requirements import SATISFIED, UNDECIDED, VIOLATED, Requirement, RunMetric

__all__ = ["ADVICE_SHARE", "CAP", "PREDICTIVE_DRAWS", "Advice", "advise", "decide_probability"]

#: Probability of a decision the advised run count is chosen for.
ADVICE_SHARE = 0.8
#: Most runs in total the advice looks at.
CAP = 10_000
#: Posterior-predictive draws of the ``mean+ksigma`` advice (fixed seed).
PREDICTIVE_DRAWS = 4000
_SEED = 27
#: Runs beyond those made that are tried one by one for the count statistics.
SCAN = 256


@dataclass(frozen=True)
class Advice:
    """Runs-needed advice for one requirement.

    Attributes
    ----------
    runs : int or None
        Runs in total (those made included) at which the campaign is decided with
        probability >= ``share``; None when not by ``CAP`` or when it cannot be advised.
    made : int
        Runs made (failed runs included).
    share : float
        The probability the run count was chosen for.
    probability : float
        Predicted probability of a decision at ``runs`` (nan without ``runs``).
    verdict : str
        The likelier decision at ``runs`` (satisfied or violated; undecided without).
    method : str
        How the prediction was made.
    note : str
        Why there is no advice, if there is none.
    """

    runs: int | None
    made: int
    share: float
    probability: float
    verdict: str
    method: str
    note: str = ""

    @property
    def more(self) -> int | None:
        """Runs still to make (``runs - made``), or None."""
        return None if self.runs is None else self.runs - self.made

    def text(self) -> str:
        """The advice in one clause, for a verdict's reason and claim.

        Returns
        -------
        str
            E.g. ``"about 22 runs in total (2 more) would decide it in 80 % of campaigns
            (likely satisfied)"``.
        """
        if self.runs is None:
            return self.note or f"not decided by {CAP} runs"
        return (
            f"about {self.runs} runs in total ({self.more} more) would decide it in "
            f"{100 * self.share:g} % of campaigns (likely {self.verdict})"
        )


def _binomial(req: Requirement, passed: np.ndarray, confidence: float) -> Callable:
    """P(satisfied), P(violated) at N runs for pass_rate, p<q>, max (module docstring)."""
    from scipy import stats

    n = passed.size
    k = int(np.sum(~passed))  # runs over the limit (failed runs counted as over)
    p = float(req.probability)
    n_min = wilks_min_runs(p, confidence) if req.statistic == "max" else 0

    def probability(total: int) -> tuple[float, float]:
        m = total - n
        over = k + np.arange(m + 1)  # runs over the limit at N
        w = stats.betabinom.pmf(np.arange(m + 1), m, k + 0.5, n - k + 0.5)
        good = total - over
        if req.statistic == "pass_rate":
            with np.errstate(invalid="ignore"):
                lower = np.where(
                    good > 0, stats.beta.ppf(1.0 - confidence, good, total - good + 1), 0.0
                )
                upper = np.where(
                    good < total, stats.beta.ppf(confidence, good + 1, total - good), 1.0
                )
            sat, vio = lower >= p, upper < p
        elif req.statistic == "max":
            sat, vio = (over == 0) & (total >= n_min), over > 0
        else:  # quantile: decided by the count of runs meeting the limit
            r_up = wilks_upper_rank(total, p, confidence)
            r_lo = wilks_lower_rank(total, p, confidence)
            sat = good >= r_up if r_up is not None else np.zeros(m + 1, bool)
            vio = good < r_lo if r_lo is not None else np.zeros(m + 1, bool)
        return float(w @ sat), float(w @ vio)

    return probability


def _rms(req: Requirement, values: np.ndarray, confidence: float) -> Callable:
    """P(satisfied), P(violated) at N runs for rms, by the F pivot (module docstring)."""
    from scipy import stats

    n = values.size
    ss = float(np.sum(values**2))
    lim2 = float(req.limit) ** 2

    def probability(total: int) -> tuple[float, float]:
        m = total - n
        if ss <= 0.0:
            return 1.0, 0.0
        # satisfied: ss + S_m <= lim^2 chi2_{1-c}(N); violated: ss + S_m > lim^2 chi2_c(N)
        a = (lim2 * stats.chi2.ppf(1.0 - confidence, total) - ss) / ss * n / m
        b = (lim2 * stats.chi2.ppf(confidence, total) - ss) / ss * n / m
        sat = float(stats.f.cdf(a, m, n)) if a > 0 else 0.0
        vio = float(stats.f.sf(b, m, n)) if b > 0 else 1.0
        return sat, vio

    return probability


def _ksigma(req: Requirement, values: np.ndarray, confidence: float) -> Callable:
    """P(satisfied), P(violated) at N runs for mean+ksigma (normal predictive draws)."""
    from scipy import stats

    n = values.size
    mean, var = float(np.mean(values)), float(np.var(values, ddof=1))
    k, lim = float(req.k), float(req.limit)
    need = BOOTSTRAP_MIN_RUNS if req.assume == "none" else 2

    def probability(total: int) -> tuple[float, float]:
        if total < need:
            return 0.0, 0.0
        m = total - n
        rng = np.random.default_rng(_SEED)
        r = PREDICTIVE_DRAWS
        sigma2 = (n - 1) * var / rng.chisquare(n - 1, r)
        mu = mean + np.sqrt(sigma2 / n) * rng.standard_normal(r)
        mean_new = mu + np.sqrt(sigma2 / m) * rng.standard_normal(r)
        ss_new = sigma2 * rng.chisquare(m - 1, r) if m > 1 else np.zeros(r)
        grand = (n * mean + m * mean_new) / total
        ss = (n - 1) * var + ss_new + n * m / total * (mean - mean_new) ** 2
        s = np.sqrt(ss / (total - 1))
        delta = k * math.sqrt(total)
        c_up = stats.nct.ppf(confidence, total - 1, delta) / math.sqrt(total)
        c_lo = stats.nct.ppf(1.0 - confidence, total - 1, delta) / math.sqrt(total)
        return float(np.mean(grand + c_up * s <= lim)), float(np.mean(grand + c_lo * s > lim))

    return probability


_METHOD = {
    "pass_rate": "beta-binomial prediction of the runs meeting the limit, Clopper-Pearson",
    "quantile": "beta-binomial prediction of the runs meeting the limit, Wilks",
    "max": "beta-binomial prediction of the runs meeting the limit, Wilks",
    "rms": "F-distribution prediction of the sum of squares, chi-square bounds",
    "mean+ksigma": "normal posterior predictive, noncentral-t bounds",
}


def decide_probability(
    req: Requirement, metrics: Sequence[RunMetric], confidence: float
) -> Callable[[int], tuple[float, float]]:
    """The predicted probabilities of each decision after more runs.

    Parameters
    ----------
    req : Requirement
        The requirement (statistic, limit, probability, k, assume filled in).
    metrics : sequence of RunMetric, shape (n,)
        The runs judged (failed runs already replaced or left out as ``on_failure``
        says; none too short to decide).
    confidence : float
        Confidence of the verdict.

    Returns
    -------
    callable
        ``f(N) -> (P(satisfied at N), P(violated at N))`` for N > n runs in total.
    """
    values = np.array([m.value for m in metrics], dtype=float)
    if req.statistic in ("pass_rate", "quantile", "max"):
        return _binomial(req, values <= req.limit, confidence)
    if req.statistic == "rms":
        return _rms(req, values, confidence)
    return _ksigma(req, values, confidence)


def advise(
    req: Requirement,
    metrics: Sequence[RunMetric | None],
    confidence: float,
    *,
    share: float = ADVICE_SHARE,
    cap: int = CAP,
) -> Advice:
    """The runs in total that would decide the requirement with probability ``share``.

    Parameters
    ----------
    req : Requirement
        The requirement, its defaults filled in (as :func:`cosim.verify.statistics.judge`
        judges it).
    metrics : sequence of RunMetric or None, shape (n_runs,)
        The runs made, in run order; None for a failed run.
    confidence : float
        Confidence of the verdict.
    share : float
        Probability of a decision to choose the run count for, 0 < share < 1.
    cap : int
        Most runs in total looked at.

    Returns
    -------
    Advice
    """
    made = len(metrics)
    method = _METHOD[req.statistic]
    if req.statistic == "mean+ksigma" and req.assume == "none":
        method += " (normal-theory factors standing in for the bootstrap bound)"

    def none(note: str) -> Advice:
        return Advice(None, made, share, math.nan, UNDECIDED, method, note)

    failed = sum(m is None for m in metrics)
    if failed and req.on_failure == "undecided":
        return none(
            f"no number of runs decides it while {failed} run(s) failed (on_failure = "
            f"'undecided'): fix what makes them fail, or set on_failure"
        )
    if req.on_failure == "fail":
        used = [m if m is not None else RunMetric(math.inf, False, "run failed") for m in metrics]
    else:
        used = [m for m in metrics if m is not None]
    if not used:
        return none("no completed run to predict from")
    short = [m for m in used if m.passed is None]
    if short:
        return none(f"runs too short to decide: {short[0].note}")
    n = len(used)
    if req.statistic == "mean+ksigma" and n < 2:
        return none("mean+ksigma needs 2 runs before more can be predicted")
    probability = decide_probability(req, used, confidence)

    def ok(total: int) -> bool:
        return sum(probability(total)) >= share

    # The probability grows with N, in a saw tooth for the statistics decided by a count
    # (each whole run over the limit): those are scanned run by run over the first
    # SCAN runs; beyond, and for the smooth ones, doubling, bisection, then a scan.
    lo = n
    if req.statistic in ("pass_rate", "quantile", "max"):
        first = next((t for t in range(n + 1, min(cap, n + SCAN) + 1) if ok(t)), None)
        if first is not None:
            return _advice(probability, first, n, made, share, method)
        lo = min(cap, n + SCAN)
    step = 1
    hi = lo + step
    while hi < cap and not ok(hi):
        lo, step = hi, 2 * step
        hi = lo + step
    hi = min(hi, cap)
    if hi <= lo or not ok(hi):
        return none(f"not decided in {100 * share:g} % of campaigns by {cap} runs")
    counts = req.statistic in ("pass_rate", "quantile", "max")
    while hi - lo > (64 if counts else 1):
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    hi = next(total for total in range(lo + 1, hi + 1) if total == hi or ok(total))
    return _advice(probability, hi, n, made, share, method)


def _advice(
    probability: Callable[[int], tuple[float, float]],
    total: int,
    n: int,
    made: int,
    share: float,
    method: str,
) -> Advice:
    """The advice of ``total`` runs judged (``n`` judged so far, ``made`` made)."""
    p_sat, p_vio = probability(total)
    runs = made + math.ceil((total - n) * made / n - 1e-9)  # "exclude": failed runs cost too
    verdict = SATISFIED if p_sat >= p_vio else VIOLATED
    return Advice(runs, made, share, p_sat + p_vio, verdict, method)
