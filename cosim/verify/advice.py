"""Runs-needed advice: how many runs in total would decide a requirement, given the runs made.

One function, :func:`advise`, gives the advice that ``verify`` prints under an undecided
verdict and that ``plan`` prints for its pilot, so the two agree on the same runs. The
runs made stay in the campaign (failed runs included as the requirement's ``on_failure``
counts them): with 19 of 20 runs passing, the advice is about the 20 runs plus more.

The rule. The verdict turns on one parameter: the probability that a run meets the limit
(``pass_rate``, ``p<q>``, ``max``), the RMS (``rms``) or ``mu + k sigma``
(``mean+ksigma``). Its estimate from the runs made lies on one side of the limit: the
decision on that side (satisfied or violated) is the one aimed at. The run count is
computed at the end of the one-sided :data:`PROMISE_LEVEL` (80 %) confidence bound of
the parameter nearest the limit (Clopper-Pearson, chi-square, noncentral t): the fewest
runs in total N at which, with the runs made kept and N - n more drawn at that value, the
aimed decision has probability at least ``share`` (:data:`ADVICE_SHARE`, 80 %). The
probability of the aimed decision only grows as the true value moves away from the limit
(more runs meeting it, a smaller RMS), so the advice is a **promise** for every true value
at or beyond the bound, and the text names that bound.

When the bound is not on the estimate's side of the limit (or lies so close to it that
``CAP`` runs do not reach the share), the pilot cannot exclude a true value at the limit,
where no run count decides often (about 2 (1 - confidence) of campaigns): the text says
that no number of runs can promise a decision and gives the N for a true value equal to
the pilot's estimate, marked as such (``Advice.promised`` False). A plug-in N without that
condition decided 69 to 79 % of campaigns near the limit (docs/statistics.md).

The probabilities at a given true value, each with the statistic's own bound at N runs as
:func:`cosim.verify.statistics.judge` applies it:

- ``pass_rate``, ``p<q>``, ``max``: the count meeting the limit among m more runs is
  binomial; the verdict at N = n + m is evaluated for every count (Clopper-Pearson for
  ``pass_rate``, Wilks' order-statistic ranks for ``p<q>``, every run passing and
  ``1 - p^N >= confidence`` for ``max``). Exact sums.
- ``rms``: each metric is ``|e|`` of a zero-mean normal e (the bound's model); the sum of
  squares of m more runs is ``sigma^2 chi2(m)``: one chi-square value per N.
- ``mean+ksigma``: normal metrics with the runs' standard deviation taken at the pilot's
  s and the mean at the bound minus k s (the spread is not bounded: an approximation);
  the mean and variance of the runs to come are drawn (4000 draws, fixed seed) and judged
  with the noncentral-t factors at N. With ``assume = "none"`` (bootstrap bounds) the same
  normal-theory factors stand in, said in the method.

Failed runs: ``on_failure = "fail"`` counts them as runs over the limit; ``"exclude"``
advises on the completed runs and scales the runs to come by the share that completed;
``"undecided"`` gives no advice while a run failed. Runs too short to decide give none.
tests/verify/test_advice.py follows the advice in simulated campaigns near and away from the
limit.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cosim.verify.bounds import (
    BOOTSTRAP_MIN_RUNS,
    clopper_pearson,
    ksigma_normal_bounds,
    wilks_lower_rank,
    wilks_min_runs,
    wilks_upper_rank,
)
from cosim.verify.requirements import SATISFIED, UNDECIDED, VIOLATED, Requirement, RunMetric

__all__ = [
    "ADVICE_SHARE",
    "CAP",
    "PREDICTIVE_DRAWS",
    "PROMISE_LEVEL",
    "Advice",
    "advise",
    "decide_probability",
    "replay_advice",
]

#: Probability of a decision the advised run count is chosen for.
ADVICE_SHARE = 0.8
#: One-sided confidence of the pilot's bound the promised run count is computed at.
PROMISE_LEVEL = 0.8
#: Most runs in total the advice looks at.
CAP = 10_000
#: Draws of the runs to come in the ``mean+ksigma`` advice (fixed seed).
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
        probability >= ``share`` at the true value the advice is computed for; None when
        not by ``CAP`` or when it cannot be advised.
    made : int
        Runs made (failed runs included).
    share : float
        The probability the run count was chosen for.
    probability : float
        Probability of the decision at ``runs`` at that true value (nan without ``runs``).
    verdict : str
        The decision aimed at: the one on the pilot's side of the limit (undecided
        without ``runs``).
    method : str
        How the prediction was made.
    note : str
        Why there is no advice, if there is none.
    promised : bool
        True when ``runs`` is computed at the pilot's one-sided :data:`PROMISE_LEVEL`
        bound, which lies on the estimate's side of the limit: the share holds for every
        true value at least as far from the limit. False when the pilot cannot exclude a
        true value at the limit: ``runs`` is then computed at the pilot's estimate, and
        the text says that no number of runs can promise a decision.
    template : str
        The text around ``{advice}`` (the condition, and the preface when not promised).
    """

    runs: int | None
    made: int
    share: float
    probability: float
    verdict: str
    method: str
    note: str = ""
    promised: bool = False
    template: str = "{advice}"

    @property
    def more(self) -> int | None:
        """Runs still to make (``runs - made``), or None."""
        return None if self.runs is None else self.runs - self.made

    def text(self) -> str:
        """The advice in one clause, for a verdict's reason.

        Returns
        -------
        str
            E.g. ``"about 23 runs in total (3 more) would decide it (satisfied) in 80 % of
            campaigns for a true pass rate of 0.8512 or more (the pilot's one-sided 80 %
            bound)"``.
        """
        if self.runs is None:
            return self.note or f"not decided by {CAP} runs"
        advice = (
            f"about {self.runs} runs in total ({self.more} more) would decide it "
            f"({self.verdict}) in {100 * self.share:g} % of campaigns"
        )
        return self.template.replace("{advice}", advice)


def replay_advice(replayed: Sequence[str], made: int) -> Advice:
    """The advice of an undecided verdict when the runs replay recorded logs.

    Every run of such a campaign reads the same samples; a second run redraws only the
    seeds of the simulated blocks (the filter's own draws), so no number of runs decides
    a requirement on the sensor the log recorded.

    Parameters
    ----------
    replayed : sequence of str
        The blocks that replay a log.
    made : int
        Runs made.

    Returns
    -------
    Advice
        ``runs`` None, ``method`` ``"replay"``; its text says what would decide it.
    """
    names = ", ".join(f"'{b}'" for b in replayed)
    return Advice(
        runs=None,
        made=made,
        share=ADVICE_SHARE,
        probability=math.nan,
        verdict=UNDECIDED,
        method="replay",
        note=(
            f"but every run replays the same log (block {names}): more runs redraw only the "
            "simulated blocks' seeds and cannot decide it; what would: a longer log, more "
            "logs of the sensor (one run each), or a requirement on the filter's own sigma"
        ),
    )


def _binomial(req: Requirement, passed: np.ndarray, confidence: float, q: float) -> Callable:
    """P(satisfied), P(violated) at N runs for pass_rate, p<q>, max, if a run meets the
    limit with probability ``q`` (module docstring)."""
    from scipy import stats

    n = passed.size
    k = int(np.sum(~passed))  # runs over the limit (failed runs counted as over)
    p = float(req.probability)
    n_min = wilks_min_runs(p, confidence) if req.statistic == "max" else 0

    def probability(total: int) -> tuple[float, float]:
        m = total - n
        over = k + np.arange(m + 1)  # runs over the limit at N
        w = stats.binom.pmf(np.arange(m + 1), m, 1.0 - q)
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


def _rms(req: Requirement, values: np.ndarray, confidence: float, sigma2: float) -> Callable:
    """P(satisfied), P(violated) at N runs for rms if the true RMS is sqrt(``sigma2``)."""
    from scipy import stats

    ss = float(np.sum(values**2))
    lim2 = float(req.limit) ** 2
    n = values.size

    def probability(total: int) -> tuple[float, float]:
        m = total - n
        # satisfied: ss + S_m <= lim^2 chi2_{1-c}(N); violated: ss + S_m > lim^2 chi2_c(N),
        # S_m = sigma2 chi2(m)
        a = (lim2 * stats.chi2.ppf(1.0 - confidence, total) - ss) / sigma2
        b = (lim2 * stats.chi2.ppf(confidence, total) - ss) / sigma2
        sat = float(stats.chi2.cdf(a, m)) if a > 0 else 0.0
        vio = float(stats.chi2.sf(b, m)) if b > 0 else 1.0
        return sat, vio

    return probability


def _ksigma(
    req: Requirement, values: np.ndarray, confidence: float, mu: float, sigma2: float
) -> Callable:
    """P(satisfied), P(violated) at N runs for mean+ksigma if the metrics are
    N(``mu``, ``sigma2``) (fixed-seed draws of the runs to come)."""
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
        mean_new = mu + math.sqrt(sigma2 / m) * rng.standard_normal(r)
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


@dataclass(frozen=True)
class _Truth:
    """The parameter the verdict turns on, as the pilot estimates and bounds it."""

    name: str  # e.g. "pass rate", "RMS"
    unit: str
    level: float  # its value at the limit
    estimate: float
    bound: float  # end of the one-sided PROMISE_LEVEL interval nearest the limit
    side: str  # SATISFIED or VIOLATED: the decision on the estimate's side of the limit
    higher_is_better: bool

    def beyond(self, value: float) -> str:
        """``"0.83 or more"`` / ``"7.1 arcmin or less"``: values at least as far."""
        up = self.higher_is_better == (self.side == SATISFIED)
        unit = "" if self.unit in ("", "1") else f" {self.unit}"
        if self.unit == "1" and value == (1.0 if up else 0.0):  # nothing lies beyond
            return f"{value:g}"
        return f"{value:.4g}{unit} or {'more' if up else 'less'}"

    @property
    def promised(self) -> bool:
        """Whether the bound lies on the estimate's side of the limit (strictly)."""
        return (self.bound > self.level) == (self.estimate > self.level) and (
            self.bound != self.level
        )


def _truth(req: Requirement, values: np.ndarray, level: float) -> _Truth | None:
    """The pilot's estimate and one-sided ``level`` bound of the verdict's parameter
    (None when the estimate is at the limit: no side to aim at)."""
    from scipy import stats

    n = values.size
    if req.statistic in ("pass_rate", "quantile", "max"):
        p = float(req.probability)
        good = int(np.sum(values <= req.limit))
        est = good / n
        lower, upper = clopper_pearson(good, n, level)
        name = "pass rate" if req.statistic == "pass_rate" else "share of runs meeting the limit"
        if est == p:
            return None
        sat = est > p
        return _Truth(name, "1", p, est, lower if sat else upper,
                      SATISFIED if sat else VIOLATED, True)  # fmt: skip
    lim = float(req.limit)
    if req.statistic == "rms":
        ss = float(np.sum(values**2))
        est = math.sqrt(ss / n)
        if est == lim:
            return None
        sat = est < lim
        bound = math.sqrt(ss / stats.chi2.ppf(1.0 - level if sat else level, n))
        return _Truth("RMS", req.unit, lim, est, bound, SATISFIED if sat else VIOLATED, False)
    mean, s = float(np.mean(values)), float(np.std(values, ddof=1))
    est = mean + float(req.k) * s
    if est == lim:
        return None
    sat = est < lim
    lower, upper = ksigma_normal_bounds(values, float(req.k), level)
    name = f"mean+{float(req.k):g}sigma"
    return _Truth(name, req.unit, lim, est, upper if sat else lower,
                  SATISFIED if sat else VIOLATED, False)  # fmt: skip


def decide_probability(
    req: Requirement, metrics: Sequence[RunMetric], confidence: float, truth: float
) -> Callable[[int], tuple[float, float]]:
    """The probabilities of each decision after more runs, at a given true value.

    Parameters
    ----------
    req : Requirement
        The requirement (statistic, limit, probability, k, assume filled in).
    metrics : sequence of RunMetric, shape (n,)
        The runs judged (failed runs already replaced or left out as ``on_failure``
        says; none too short to decide).
    confidence : float
        Confidence of the verdict.
    truth : float
        The true value of the verdict's parameter: the probability that a run meets the
        limit (``pass_rate``, ``p<q>``, ``max``), the RMS (``rms``, requirement's unit),
        or ``mu + k sigma`` with sigma the runs' standard deviation (``mean+ksigma``).

    Returns
    -------
    callable
        ``f(N) -> (P(satisfied at N), P(violated at N))`` for N > n runs in total, the
        n runs made kept and N - n more drawn at ``truth``.
    """
    values = np.array([m.value for m in metrics], dtype=float)
    if req.statistic in ("pass_rate", "quantile", "max"):
        return _binomial(req, values <= req.limit, confidence, truth)
    if req.statistic == "rms":
        return _rms(req, values, confidence, truth**2)
    s = float(np.std(values, ddof=1))
    return _ksigma(req, values, confidence, truth - float(req.k) * s, s**2)


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
    values = np.array([m.value for m in used], dtype=float)
    if req.statistic == "mean+ksigma" and not np.std(values) > 0:
        return none("mean+ksigma: the runs made do not vary, nothing to predict from")
    truth = _truth(req, values, PROMISE_LEVEL)
    if truth is None:
        return none(
            "the pilot's estimate is at the limit: no number of runs can promise a decision"
        )
    side = 0 if truth.side == SATISFIED else 1
    counts = req.statistic in ("pass_rate", "quantile", "max")
    unit = "" if truth.unit in ("", "1") else f" {truth.unit}"
    bound = f"its one-sided {100 * PROMISE_LEVEL:g} % bound {truth.bound:.4g}{unit}"
    total = None
    if truth.promised:
        probability = decide_probability(req, used, confidence, truth.bound)
        total = _search(lambda t: probability(t)[side] >= share, n, cap, counts)
    promised = total is not None
    if promised:
        condition = (
            f"for a true {truth.name} of {truth.beyond(truth.bound)} (the pilot's one-sided "
            f"{100 * PROMISE_LEVEL:g} % bound)"
        )
        preface = ""
    else:
        why = (
            f"is not on the {truth.side} side of {truth.level:.4g}{unit}"
            if not truth.promised
            else f"is too close to {truth.level:.4g}{unit} to decide by {cap} runs"
        )
        preface = (
            f"the pilot cannot exclude a true {truth.name} at the limit ({bound} {why}): "
            f"no number of runs can promise a decision; "
        )
        condition = (
            f"only if the true {truth.name} is {truth.beyond(truth.estimate)} "
            f"(the pilot's estimate)"
        )
        probability = decide_probability(req, used, confidence, truth.estimate)
        total = _search(lambda t: probability(t)[side] >= share, n, cap, counts)
    if total is None:
        return none(
            f"{preface}not decided ({truth.side}) in {100 * share:g} % of campaigns by {cap} "
            f"runs {condition}"
        )
    p_side = probability(total)[side]
    runs = made + math.ceil((total - n) * made / n - 1e-9)  # "exclude": failed runs cost too
    return Advice(runs, made, share, p_side, truth.side, method, "", promised,
                  f"{preface}{{advice}} {condition}")  # fmt: skip


def _search(ok: Callable[[int], bool], n: int, cap: int, counts: bool) -> int | None:
    """The fewest runs in total N > n with ``ok(N)``, searched up to ``cap``.

    The probability grows with N, in a saw tooth for the statistics decided by a count
    (each whole run over the limit): those are scanned run by run over the first SCAN
    runs; beyond, and for the smooth ones, doubling, bisection, then a scan.
    """
    lo = n
    if counts:
        first = next((t for t in range(n + 1, min(cap, n + SCAN) + 1) if ok(t)), None)
        if first is not None:
            return first
        lo = min(cap, n + SCAN)
    step = 1
    hi = lo + step
    while hi < cap and not ok(hi):
        lo, step = hi, 2 * step
        hi = lo + step
    hi = min(hi, cap)
    if hi <= lo or not ok(hi):
        return None
    while hi - lo > (64 if counts else 1):
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return next(total for total in range(lo + 1, hi + 1) if total == hi or ok(total))
