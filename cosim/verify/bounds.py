"""Confidence bounds of campaign statistics: order statistics, binomial, chi-square, t, bootstrap.

Each function bounds one population value of the per-run metrics one-sidedly at a given
confidence; :func:`cosim.verify.statistics.judge` turns the bounds into a three-valued
verdict. The assumption each bound needs is in its docstring and in docs/verification.md
("Statistics over the runs").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "BOOTSTRAP_MIN_RUNS",
    "BOOTSTRAP_RESAMPLES",
    "BOOTSTRAP_SEED",
    "clopper_pearson",
    "ksigma_bootstrap_bounds",
    "ksigma_normal_bounds",
    "max_bounds",
    "rms_bounds",
    "wilks_lower_rank",
    "wilks_min_runs",
    "wilks_upper_bound",
    "wilks_upper_rank",
]


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


# ------------------------------------------------------------------ bounds of rms, mean+ksigma, max
#: Bootstrap resamples of the ``mean+ksigma`` bound without a distribution assumption.
BOOTSTRAP_RESAMPLES = 2000
#: Fixed seed of the resampling: the same metrics give the same bound in every report.
BOOTSTRAP_SEED = 15
#: Fewest runs a bootstrap bound is computed from (fewer: undecided).
BOOTSTRAP_MIN_RUNS = 10
_CHUNK = 4_000_000  # resampled values held at once


def rms_bounds(values: Sequence[float] | np.ndarray, confidence: float) -> tuple[Any, Any]:
    """One-sided chi-square confidence bounds of the population RMS of the metrics.

    If each metric is ``|x|`` (or ``x``) of a zero-mean normal ``x`` with standard deviation
    sigma, the population RMS is sigma and ``sum(m_i^2) / sigma^2`` is chi-square with n
    degrees of freedom, so ``U = sqrt(sum(m_i^2) / chi2_{1-confidence}(n))`` is an exact
    upper and ``L = sqrt(sum(m_i^2) / chi2_{confidence}(n))`` an exact lower bound, each
    holding with probability ``confidence``. The bounds stay valid (conservative) when
    ``m^2`` is less dispersed than ``sigma^2 chi2(1)``, i.e. for metrics no heavier-tailed
    than ``|x|`` of a normal: a normal ``x`` with a mean, the largest ``|e|`` over a window,
    a Rayleigh magnitude (shown by tests/acceptance/test_confidence_coverage.py). Heavier-tailed
    metrics (``mean(m^4) / mean(m^2)^2`` well over 3) break them.

    Parameters
    ----------
    values : array_like, shape (n,) or (c, n)
        Metrics of n runs (of c campaigns), >= 0 or signed.
    confidence : float
        Confidence of each one-sided bound, 0 < confidence < 1.

    Returns
    -------
    (lower, upper) : float, or ndarray of shape (c,)
        In the unit of ``values``.
    """
    from scipy import stats

    x = np.asarray(values, dtype=float)
    n = x.shape[-1]
    with np.errstate(over="ignore"):
        ss = np.sum(x**2, axis=-1)
    lower = np.sqrt(ss / stats.chi2.ppf(confidence, n))
    upper = np.sqrt(ss / stats.chi2.ppf(1.0 - confidence, n))
    return (float(lower), float(upper)) if x.ndim == 1 else (lower, upper)


def ksigma_normal_bounds(
    values: Sequence[float] | np.ndarray, k: float, confidence: float
) -> tuple[Any, Any]:
    """One-sided noncentral-t bounds of ``mu + k sigma`` for normally distributed metrics.

    With mean ``m`` and standard deviation ``s`` (ddof = 1) of n normal samples,
    ``P(m + c s >= mu + k sigma) = P(T' <= c sqrt(n))`` where ``T'`` is noncentral t with
    n - 1 degrees of freedom and noncentrality ``k sqrt(n)`` (the one-sided normal
    tolerance factor). So ``m + s t'_{confidence} / sqrt(n)`` is an exact upper and
    ``m + s t'_{1-confidence} / sqrt(n)`` an exact lower bound. Exact under normality only:
    a skewed metric (``|e|``, a window's maximum) makes them cover less often (about 90 %
    instead of 95 % for a window maximum at 30 runs).

    Parameters
    ----------
    values : array_like, shape (n,) or (c, n)
        Metrics of n >= 2 runs (of c campaigns).
    k : float
        Factor of sigma, >= 0.
    confidence : float
        Confidence of each one-sided bound.

    Returns
    -------
    (lower, upper) : float, or ndarray of shape (c,)
    """
    from scipy import stats

    x = np.asarray(values, dtype=float)
    n = x.shape[-1]
    m, s = x.mean(axis=-1), x.std(axis=-1, ddof=1)
    delta = k * math.sqrt(n)
    c_up = stats.nct.ppf(confidence, n - 1, delta) / math.sqrt(n)
    c_lo = stats.nct.ppf(1.0 - confidence, n - 1, delta) / math.sqrt(n)
    lower, upper = m + c_lo * s, m + c_up * s
    return (float(lower), float(upper)) if x.ndim == 1 else (lower, upper)


def _pivots(x: np.ndarray) -> tuple[np.ndarray, ...]:
    """Mean, std (ddof = 1), standard error of the mean and of log(std); shape (...,)."""
    n = x.shape[-1]
    m = x.mean(axis=-1)
    d = x - m[..., None]
    m2 = np.mean(d**2, axis=-1)
    m4 = np.mean(d**4, axis=-1)
    s = np.sqrt(m2 * n / (n - 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        # delta method: Var(s^2) ~ (mu4 - sigma^4) / n and d(log s) = d(s^2) / (2 s^2)
        se_log_s = 0.5 * np.sqrt(np.maximum(m4 - m2**2, 0.0) / n) / m2
    return m, s, s / math.sqrt(n), se_log_s


def ksigma_bootstrap_bounds(
    values: Sequence[float] | np.ndarray,
    k: float,
    confidence: float,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[Any, Any]:
    """One-sided bounds of ``mu + k sigma`` without a distribution assumption (bootstrap).

    Bonferroni union of two studentized-bootstrap bounds, each at ``(1 - confidence) / 2``:
    the mean, pivot ``(m* - m) / (s* / sqrt(n))``, and the standard deviation on the log
    scale, pivot ``(log s* - log s) / se*`` with the delta-method standard error
    ``se = sqrt((mu4 - sigma^4) / n) / (2 sigma^2)`` from the sample's central moments.
    Upper bound ``U_mean + k U_sigma``, lower bound ``L_mean + k L_sigma``. Approximate: no
    bound of a mean is exact without a model (Bahadur & Savage 1956); in
    tests/acceptance/test_confidence_coverage.py it covers in at least the nominal share of
    campaigns for normal and window-maximum metrics at 30 runs, and the Bonferroni split keeps
    it conservative for moderately skewed ones (half-normal, Rayleigh, lognormal with sigma
    0.25); heavier tails (lognormal sigma 0.5) cover about 92 % for 95 %.

    Parameters
    ----------
    values : array_like, shape (n,) or (c, n)
        Metrics of n >= 2 runs (of c campaigns).
    k : float
        Factor of sigma, >= 0.
    confidence : float
        Confidence of each one-sided bound.
    resamples : int
        Bootstrap resamples.
    seed : int
        Seed of the resampling (fixed: the bound is a function of the metrics).

    Returns
    -------
    (lower, upper) : float, or ndarray of shape (c,)
        Equal to the sample's ``m + k s`` when every metric is the same; the sigma part
        is the sample's s when the metrics take two values in equal shares.
    """
    x = np.asarray(values, dtype=float)
    one = x.ndim == 1
    x = np.atleast_2d(x)
    c, n = x.shape
    a = 0.5 * (1.0 - confidence)
    m, s, se_m, se_ls = _pivots(x)
    flat = s <= 1e-12 * np.maximum(np.abs(m), 1e-300)  # constant up to rounding
    s = np.where(flat, 0.0, s)
    se_m, se_ls = np.where(flat, 0.0, se_m), np.where(flat, 0.0, se_ls)
    # Resample through multinomial counts w (one row per resample, shared by the
    # campaigns): the resampled power sums of the standardized metrics are products w @ z^j.
    z = np.where(flat[:, None], 0.0, (x - m[:, None]) / np.where(s > 0, s, 1.0)[:, None])
    powers = [(z**j).T for j in range(1, 5)]  # each (n, c)
    rng = np.random.default_rng(seed)
    b = max(1, min(resamples, _CHUNK // n))
    tm, ts = [], []
    for j0 in range(0, resamples, b):
        rows = min(b, resamples - j0)
        idx = rng.integers(0, n, size=(rows, n)) + n * np.arange(rows)[:, None]
        w = np.bincount(idx.ravel(), minlength=rows * n).reshape(rows, n) / n
        e1, e2, e3, e4 = (w @ pw for pw in powers)  # (b, c) raw moments of a resample
        var = np.maximum(e2 - e1 * e1, 0.0)
        m4 = e4 - e1 * (4.0 * e3 - e1 * (6.0 * e2 - 3.0 * e1 * e1))  # 4th central moment
        with np.errstate(divide="ignore", invalid="ignore"):
            tm.append(e1 * np.sqrt((n - 1) / var))  # (m* - m) / se(m*), scale-free
            # (log s* - log s) / se(log s*), se(log s) = sqrt((mu4 - var^2) / n) / (2 var)
            log_s = 0.5 * np.log(var * (n / (n - 1)))
            kurt = np.sqrt(np.maximum(m4 - var * var, 0.0))
            ts.append(log_s * (2.0 * math.sqrt(n)) * var / kurt)
    q = np.empty((4, c))
    for row, t in ((0, tm), (2, ts)):
        tt = np.concatenate(t, axis=0)
        tt[np.isnan(tt)] = 0.0  # a resample of one repeated value
        q[row : row + 2] = np.quantile(tt, [a, 1.0 - a], axis=0, method="inverted_cdf")
    with np.errstate(invalid="ignore", over="ignore"):
        # no spread of log s to resample (constant or two equal halves): the sample's s
        f_up, f_lo = (np.where(se_ls > 0, np.exp(-qq * se_ls), 1.0) for qq in (q[2], q[3]))
    upper = m - q[0] * se_m + k * s * f_up
    lower = m - q[1] * se_m + k * s * f_lo
    return (float(lower[0]), float(upper[0])) if one else (lower, upper)


def max_bounds(
    values: Sequence[float] | np.ndarray, p: float, confidence: float
) -> tuple[Any, Any]:
    """Confidence bounds of the p-quantile that a ``max`` requirement shows.

    The sample maximum of n runs bounds the p-quantile from above with confidence
    ``1 - p^n`` (Wilks, rank n): an upper bound at ``confidence`` when
    ``n >= wilks_min_runs(p, confidence)``, else none (``inf``). The lower bound is Wilks'
    order statistic of :func:`wilks_lower_rank` (``-inf`` when n is too small).

    Parameters
    ----------
    values : array_like, shape (n,) or (c, n)
        Metrics of n runs (of c campaigns).
    p : float
        Quantile level, 0 < p < 1.
    confidence : float
        Confidence of each one-sided bound.

    Returns
    -------
    (lower, upper) : float, or ndarray of shape (c,)
    """
    x = np.sort(np.asarray(values, dtype=float), axis=-1)
    n = x.shape[-1]
    r_lo = wilks_lower_rank(n, p, confidence)
    upper = x[..., -1] if n >= wilks_min_runs(p, confidence) else np.full(x.shape[:-1], np.inf)
    lower = x[..., r_lo - 1] if r_lo is not None else np.full(x.shape[:-1], -np.inf)
    return (float(lower), float(upper)) if x.ndim == 1 else (lower, upper)
