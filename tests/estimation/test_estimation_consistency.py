"""Window consistency tests (cosim.estimation.consistency): bands, coverage, detection.

The coverage is simulated on a real Kalman filter (cosim.estimation.KalmanFilter gives the
covariance sequence of a constant-velocity model; the runs are vectorised): 1000 runs of
200 updates, fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from cosim.estimation import KalmanFilter
from cosim.estimation.consistency import (
    ConsistencyWindow,
    any_dependence_band,
    inconsistent_spans,
    update_instants,
    white_band,
    window_edges,
    window_test,
)

N_UPDATES = 200
N_WINDOWS = 10
ALPHA_RUN = 0.05


def simulate(
    runs: int, q_scale: float = 1.0, r_scale: float = 1.0, seed: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """NIS and NEES of ``runs`` runs of a constant-velocity KF, shape (runs, N_UPDATES).

    The truth: position/velocity, velocity random walk q = 0.01 (m/s)^2 per step, position
    measured with R = 1 m^2, x0 ~ N(0, P0). The filter uses ``q * q_scale``, ``R *
    r_scale`` (1, 1: correctly tuned). Its P, K, S do not depend on the data, so they are
    computed once with :class:`KalmanFilter` and applied to every run at once.
    """
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q = np.diag([0.0, 0.01])
    R = np.array([[1.0]])
    P0 = np.diag([4.0, 0.25])
    kf = KalmanFilter(2, 1)
    kf.F, kf.H, kf.Q, kf.R, kf.P = F, H, Q * q_scale, R * r_scale, P0
    gains, s_list, p_list = [], [], []
    for _ in range(N_UPDATES):
        kf.predict()
        kf.update(np.zeros(1))
        gains.append(kf.K.copy())
        s_list.append(float(kf.S[0, 0]))
        p_list.append(np.linalg.inv(kf.P))
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((runs, 2)) * np.sqrt(np.diag(P0))
    xh = np.zeros((runs, 2))
    nis = np.empty((runs, N_UPDATES))
    nees = np.empty((runs, N_UPDATES))
    for k in range(N_UPDATES):
        x = x @ F.T + rng.standard_normal((runs, 2)) * np.sqrt(np.diag(Q))
        xh = xh @ F.T
        z = x[:, 0] + rng.standard_normal(runs) * np.sqrt(R[0, 0])
        y = z - xh[:, 0]
        nis[:, k] = y * y / s_list[k]
        xh = xh + y[:, None] * gains[k][:, 0]
        e = xh - x
        nees[:, k] = np.einsum("ri,ij,rj->r", e, p_list[k], e)
    return nis, nees


def flagged_runs(values: np.ndarray, dof: int, white: bool) -> np.ndarray:
    """Per run: True when any window is flagged at ALPHA_RUN per run (Bonferroni)."""
    t = np.arange(N_UPDATES, dtype=float)
    edges = window_edges(0.0, t[-1], None, N_WINDOWS)
    alpha = ALPHA_RUN / N_WINDOWS
    return np.array(
        [any(w.flag for w in window_test(t, row, dof, edges, alpha, white=white)) for row in values]
    )


def test_correct_filter_is_flagged_at_the_stated_rate() -> None:
    """1000 runs of a correctly tuned KF: the innovations are independent chi-square(1)
    samples, so the 10 windows are independent and a run is flagged with probability
    exactly p0 = 1 - (1 - a/10)^10 (4.9 % for a = 5 %). The count must lie in the
    binomial 99.9 % band of p0, so the rate is neither above the stated 5 % nor a band
    too wide to ever fire."""
    nis, _ = simulate(1000, seed=11)
    count = int(flagged_runs(nis, 1, white=True).sum())
    p0 = 1.0 - (1.0 - ALPHA_RUN / N_WINDOWS) ** N_WINDOWS
    lo, hi = stats.binom.ppf([0.0005, 0.9995], 1000, p0)
    assert lo <= count <= hi, (count, lo, hi)
    assert count <= stats.binom.ppf(0.999, 1000, ALPHA_RUN)


@pytest.mark.parametrize(("q_scale", "r_scale", "least"), [(1.0, 0.1, 0.99), (0.1, 1.0, 0.75)])
def test_ten_times_too_small_noise_is_detected(
    q_scale: float, r_scale: float, least: float
) -> None:
    """R (or Q) ten times too small in the filter: 500 runs, the NIS flags at least
    ``least`` of them (measured at these seeds: 100 % for R; 82 % for Q, which shows less
    because R dominates the innovation variance of this model) and the flagged spans say
    "sigma too small"."""
    nis, _ = simulate(500, q_scale=q_scale, r_scale=r_scale, seed=12)
    flagged = flagged_runs(nis, 1, white=True)
    assert flagged.mean() >= least, flagged.mean()
    t = np.arange(N_UPDATES, dtype=float)
    windows = window_test(t, nis[0], 1, window_edges(0.0, t[-1], None, N_WINDOWS), 0.005)
    assert {s.flag for s in inconsistent_spans(windows)} <= {"small"}


def test_nees_band_holds_under_dependence_and_detects_ten_times() -> None:
    """NEES of successive updates are strongly correlated; the any-dependence band keeps
    the false-alarm rate at most 5 % per run (binomial 99.9 % bound over 1000 runs) and
    still flags a filter whose R is ten times too small in most runs (measured 91 %)."""
    _, nees = simulate(1000, seed=13)
    count = int(flagged_runs(nees, 2, white=False).sum())
    assert count <= stats.binom.ppf(0.999, 1000, ALPHA_RUN)
    _, nees_bad = simulate(500, r_scale=0.1, seed=14)
    assert flagged_runs(nees_bad, 2, white=False).mean() >= 0.8


@pytest.mark.parametrize("dof", [1, 2, 3, 6])
def test_any_dependence_band_covers_the_comonotone_case(dof: int) -> None:
    """With all samples equal the window mean is one chi2(d)/d sample: each tail beyond
    the band has probability at most alpha / 2 (the bound is valid there too), and the
    band contains the white band of any window (it is the wider one)."""
    alpha = 0.002
    lo, hi = any_dependence_band(dof, alpha)
    assert stats.chi2.sf(dof * hi, dof) <= alpha / 2
    assert stats.chi2.cdf(dof * lo, dof) <= alpha / 2
    wlo, whi = white_band(dof, alpha)
    assert lo <= wlo and whi <= hi


def test_white_band_is_the_chi_square_quantile() -> None:
    """Band of the mean of 30 x 3 dof at 1 %: chi2(90) quantiles over 90."""
    lo, hi = white_band(90, 0.01)
    assert lo == pytest.approx(stats.chi2.ppf(0.005, 90) / 90)
    assert hi == pytest.approx(stats.chi2.ppf(0.995, 90) / 90)


def test_update_instants_take_each_held_value_once() -> None:
    """A NIS held between updates, 0 before the first: one sample per new nonzero value."""
    v = np.array([0.0, 0.0, 1.5, 1.5, 1.5, 0.7, 0.7, 2.0])
    assert update_instants(v).tolist() == [2, 5, 7]
    assert update_instants(v, held=False).tolist() == [2, 3, 4, 5, 6, 7]
    assert update_instants(np.zeros(4)).size == 0
    # a filter restarting (a new position) publishes 0 again: not a sample
    assert update_instants(np.array([0.0, 1.5, 1.5, 0.0, 0.0, 0.7])).tolist() == [1, 5]


def test_spans_merge_windows_and_say_how_far_off() -> None:
    """Two adjacent windows above the band merge; the factor is sqrt of the pooled mean."""
    w = [
        ConsistencyWindow(0.0, 9.0, 10, 20.0, 1.0, 0.5, 1.6),
        ConsistencyWindow(10.0, 19.0, 10, 20.0, 25.0, 0.5, 1.6, "small"),
        ConsistencyWindow(20.0, 29.0, 10, 20.0, 25.0, 0.5, 1.6, "small"),
        ConsistencyWindow(30.0, 39.0, 10, 20.0, 0.04, 0.5, 1.6, "large"),
    ]
    spans = inconsistent_spans(w)
    assert [(s.t_start, s.t_end, s.flag) for s in spans] == [
        (10.0, 29.0, "small"),
        (30.0, 39.0, "large"),
    ]
    assert spans[0].factor == pytest.approx(5.0)
    assert spans[1].factor == pytest.approx(5.0)
    assert spans[0].message() == "sigma too small by about 5x between 10 s and 29 s"


def test_window_edges() -> None:
    """Ten equal windows by default; given a length, the last one is cut at the end."""
    assert window_edges(0.0, 100.0, None).tolist() == pytest.approx(np.linspace(0, 100, 11))
    assert window_edges(0.0, 50.0, 20.0).tolist() == [0.0, 20.0, 40.0, 50.0]
