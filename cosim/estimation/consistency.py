"""Consistency of one filter run over time windows: NIS and NEES against chi-square bands.

A filter is consistent when its covariance is the covariance of its actual errors. Two
statistics test that (Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4):

* the **NIS** ``nu_k = y_k^T S_k^-1 y_k`` of each measurement update ``k`` (innovation
  ``y_k``, its covariance ``S_k``, ``d_k`` measurements). Under the filter's own model
  (linear, Gaussian, correct ``Q``, ``R``, ``P0``) ``nu_k`` is chi-square with ``d_k``
  degrees of freedom and the innovations are **white**, so over a window of updates
  ``sum nu_k`` is chi-square with ``D = sum d_k`` degrees of freedom. The window mean
  ``m = sum nu_k / D`` has the two-sided band ``[chi2.ppf(a/2, D), chi2.ppf(1 - a/2, D)] / D``
  at false-alarm rate ``a``. It needs no truth: it runs on real logs.
* the **NEES** ``e^T P^-1 e`` of the estimation error ``e`` (needs the truth, so a
  simulation). At each instant it is chi-square with ``d`` degrees of freedom, but the
  errors of successive instants are strongly correlated (a heading error drifts slowly),
  so the window sum is *not* chi-square with ``N d`` degrees of freedom. The band of the
  window mean is therefore one that holds for **any** dependence between the samples:
  every sample ``X_i = NEES_i / d`` has the law of ``X = chi2(d) / d``, the window mean
  ``M`` is smaller than ``X`` in the convex order, and Markov's inequality on the
  stop-loss transforms gives ``P(M >= c) <= min_{a<c} E[(X - a)+] / (c - a)`` and
  ``P(M <= c) <= min_{a>c} E[(a - X)+] / (a - c)``. The band is wide (a window cannot
  show more than one sample's worth of evidence) but its false-alarm rate holds.

What a flagged window means: the mean ``m`` estimates ``k^2``, the ratio of the actual
error variance to the filter's (for NIS: of the innovation's), so the filter's sigma is
**too small by about** ``k = sqrt(m)`` when ``m`` is above the band and **too large by
about** ``1 / sqrt(m)`` when below it.

Multiple windows: a run is cut into windows and each is tested at ``a_run / n_tests``
(Bonferroni over every window of every signal judged together), so a consistent filter
is flagged in at most ``a_run`` of its runs whatever the dependence between windows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize, stats

__all__ = [
    "ConsistencyWindow",
    "InconsistentSpan",
    "any_dependence_band",
    "inconsistent_spans",
    "update_instants",
    "white_band",
    "window_edges",
    "window_test",
]

SMALL = "small"
"""Direction of a flagged window: the filter's sigma is too small (mean above the band)."""
LARGE = "large"
"""Direction of a flagged window: the filter's sigma is too large (mean below the band)."""


@lru_cache(maxsize=4096)
def white_band(total_dof: float, alpha: float) -> tuple[float, float]:
    """Two-sided band of ``sum nu_k / D`` for white chi-square samples (NIS).

    Parameters
    ----------
    total_dof : float
        ``D``, the degrees of freedom summed over the window's samples (> 0).
    alpha : float
        False-alarm rate of this window (both tails together), ``0 < alpha < 1``.

    Returns
    -------
    (float, float)
        Lower and upper limit of the window mean (dimensionless; 1 is the expectation).
    """
    lo = stats.chi2.ppf(alpha / 2.0, total_dof) / total_dof
    hi = stats.chi2.isf(alpha / 2.0, total_dof) / total_dof
    return float(lo), float(hi)


def _stop_loss_above(a: np.ndarray, dof: int) -> np.ndarray:
    """``E[(X - a)+]`` for ``X = chi2(dof) / dof``, elementwise."""
    y = dof * a
    return stats.chi2.sf(y, dof + 2) - a * stats.chi2.sf(y, dof)


def _stop_loss_below(a: np.ndarray, dof: int) -> np.ndarray:
    """``E[(a - X)+]`` for ``X = chi2(dof) / dof``, elementwise."""
    y = dof * a
    return a * stats.chi2.cdf(y, dof) - stats.chi2.cdf(y, dof + 2)


_GRID = np.geomspace(1e-12, 1.0, 400)  # relative offsets of the Markov point a


def _upper_tail_bound(c: float, dof: int) -> float:
    """``min_{a < c} E[(X - a)+] / (c - a)``: bounds ``P(M >= c)`` under any dependence.

    Every ``a`` gives a valid bound; the minimum is taken over a geometric grid of
    ``c - a`` (robust where the optimum sits near 0 or near ``c``)."""
    return float(np.min(_stop_loss_above(c - _GRID * c, dof) / (_GRID * c)))


def _lower_tail_bound(c: float, dof: int) -> float:
    """``min_{a > c} E[(a - X)+] / (a - c)``: bounds ``P(M <= c)`` under any dependence."""
    return float(np.min(_stop_loss_below(c + _GRID * 20.0, dof) / (_GRID * 20.0)))


@lru_cache(maxsize=256)
def any_dependence_band(dof: int, alpha: float) -> tuple[float, float]:
    """Two-sided band of the window mean of ``NEES / dof`` valid under any dependence.

    Each tail gets ``alpha / 2`` through the stop-loss (convex-order) bounds of the module
    docstring; the band does not narrow with the number of samples.

    Parameters
    ----------
    dof : int
        Degrees of freedom of one sample (the state block's size, e.g. 3 angles).
    alpha : float
        False-alarm rate of this window (both tails), ``0 < alpha < 1``.

    Returns
    -------
    (float, float)
        Lower and upper limit of the window mean of ``NEES / dof``.
    """
    half = alpha / 2.0
    hi = optimize.brentq(lambda c: _upper_tail_bound(c, dof) - half, 1.0 + 1e-9, 1e4)
    # the lower bound falls from 1 at c = 1 towards 0 at c = 0
    lo = optimize.brentq(lambda c: _lower_tail_bound(c, dof) - half, 1e-12, 1.0 - 1e-9)
    return float(lo), float(hi)


@dataclass(frozen=True)
class ConsistencyWindow:
    """One window of one statistic and its verdict.

    Attributes
    ----------
    t_start, t_end : float
        Times of the window's first and last sample [s].
    n : int
        Samples in the window (updates for NIS).
    dof : float
        Degrees of freedom summed over the samples.
    mean : float
        ``sum(statistic) / dof``: estimates the ratio of actual to stated variance.
    lower, upper : float
        The window's band of ``mean`` at its share of the false-alarm rate.
    flag : str
        ``""`` inside the band, ``"small"`` above it (sigma too small), ``"large"`` below.
    """

    t_start: float
    t_end: float
    n: int
    dof: float
    mean: float
    lower: float
    upper: float
    flag: str = ""

    def to_dict(self) -> dict[str, float | int | str]:
        """Plain data for JSON."""
        return {
            "t_start": self.t_start,
            "t_end": self.t_end,
            "n": self.n,
            "dof": self.dof,
            "mean": self.mean,
            "lower": self.lower,
            "upper": self.upper,
            "flag": self.flag,
        }


@dataclass(frozen=True)
class InconsistentSpan:
    """Consecutive windows flagged in the same direction, merged.

    Attributes
    ----------
    t_start, t_end : float
        First and last sample time of the merged windows [s].
    flag : str
        ``"small"`` (sigma too small) or ``"large"`` (sigma too large).
    factor : float
        How far off the sigma is, ``>= 1``: ``sqrt(mean)`` for ``"small"``,
        ``1 / sqrt(mean)`` for ``"large"``, ``mean`` pooled over the merged windows.
    mean : float
        The pooled window mean (statistic over its dof).
    """

    t_start: float
    t_end: float
    flag: str
    factor: float
    mean: float

    def message(self) -> str:
        """``"sigma too small by about 5.2x between 40 s and 200 s"``."""
        return (
            f"sigma too {self.flag} by about {self.factor:.2g}x between {self.t_start:.4g} s "
            f"and {self.t_end:.4g} s"
        )


def update_instants(values: ArrayLike, *, held: bool = True) -> np.ndarray:
    """Indices of the samples that carry a new value of a statistic.

    A filter publishes its NIS at each update and holds it in between; 0 (before the
    first update, or a filter restarting, e.g. at a new position) is not a sample. With
    ``held = False`` (a NEES, new at every step) every sample from the first nonzero one
    on counts.

    Parameters
    ----------
    values : array_like, shape (n,)
        The recorded statistic.
    held : bool
        The statistic is held between updates (NIS) or not (NEES).

    Returns
    -------
    ndarray of int, shape (k,)
    """
    v = np.asarray(values, dtype=float)
    nonzero = np.flatnonzero(v != 0.0)
    if nonzero.size == 0:
        return nonzero
    first = int(nonzero[0])
    if not held:
        idx = np.arange(first, v.size)
    else:
        new = np.flatnonzero(np.diff(v) != 0.0) + 1
        idx = np.concatenate(([first], new[new > first]))
        idx = idx[v[idx] != 0.0]
    return idx[np.isfinite(v[idx])]


def window_edges(t0: float, t1: float, window: float | None, windows: int = 10) -> np.ndarray:
    """Edges of equal windows covering ``[t0, t1]``.

    Parameters
    ----------
    t0, t1 : float
        The span judged [s].
    window : float or None
        Window length [s]; None cuts the span into ``windows`` equal windows.
    windows : int
        Number of windows when ``window`` is None.

    Returns
    -------
    ndarray, shape (m + 1,)
        Increasing edges [s]; the last window may be shorter.
    """
    if t1 <= t0:
        return np.array([t0, t1])
    if window is None:
        return np.linspace(t0, t1, windows + 1)
    n = max(1, int(math.ceil((t1 - t0) / window - 1e-9)))
    return np.minimum(t0 + window * np.arange(n + 1), t1)


def window_test(
    t: ArrayLike,
    values: ArrayLike,
    dof: ArrayLike,
    edges: ArrayLike,
    alpha: float,
    *,
    white: bool = True,
    min_samples: int = 1,
) -> list[ConsistencyWindow]:
    """Judge a statistic's samples window by window against its chi-square band.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s] (update instants for NIS).
    values : array_like, shape (n,)
        The statistic at those instants (NIS or NEES, dimensionless).
    dof : array_like, shape (n,) or scalar
        Degrees of freedom of each sample.
    edges : array_like, shape (m + 1,)
        Window edges [s] (:func:`window_edges`); a sample at an inner edge belongs to
        the later window, the last edge is inclusive.
    alpha : float
        False-alarm rate of **each** window (the caller divides the run's rate).
    white : bool
        True: white samples, the chi-square band of the sum (NIS). False: samples of
        unknown dependence, the band of :func:`any_dependence_band` (NEES; needs a
        scalar integer ``dof``).
    min_samples : int
        Windows with fewer samples are skipped.

    Returns
    -------
    list of ConsistencyWindow
        The windows with at least ``min_samples`` samples, in time order.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(values, dtype=float)
    d = np.broadcast_to(np.asarray(dof, dtype=float), t.shape)
    edges = np.asarray(edges, dtype=float)
    which = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, edges.size - 2)
    out = []
    for w in range(edges.size - 1):
        sel = (which == w) & (t >= edges[0]) & (t <= edges[-1])
        n = int(sel.sum())
        if n < max(1, min_samples):
            continue
        total = float(d[sel].sum())
        mean = float(v[sel].sum() / total)
        if white:
            lo, hi = white_band(total, alpha)
        else:
            lo, hi = any_dependence_band(int(round(d[sel][0])), float(alpha))
        flag = SMALL if mean > hi else (LARGE if mean < lo else "")
        ts = t[sel]
        out.append(ConsistencyWindow(float(ts[0]), float(ts[-1]), n, total, mean, lo, hi, flag))
    return out


def inconsistent_spans(windows: list[ConsistencyWindow]) -> list[InconsistentSpan]:
    """Merge consecutive flagged windows of the same direction into spans.

    Parameters
    ----------
    windows : list of ConsistencyWindow
        From :func:`window_test`, in time order.

    Returns
    -------
    list of InconsistentSpan
        In time order; empty when no window is flagged.
    """
    spans: list[InconsistentSpan] = []
    run: list[ConsistencyWindow] = []

    def close() -> None:
        if run:
            mean = sum(w.mean * w.dof for w in run) / sum(w.dof for w in run)
            root = math.sqrt(max(mean, 1e-300))
            factor = root if run[0].flag == SMALL else 1.0 / root
            spans.append(InconsistentSpan(run[0].t_start, run[-1].t_end, run[0].flag, factor, mean))
            run.clear()

    for w in windows:
        if run and w.flag != run[0].flag:
            close()
        if w.flag:
            run.append(w)
    close()
    return spans
