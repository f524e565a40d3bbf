"""Sigma calibration over a campaign (cosim.verify.calibration): false alarms and power.

Synthetic campaigns of ``n`` runs whose error is Gaussian with the stated sigma, strongly
correlated in time (a first-order Gauss-Markov process, as a heading error drifts) or
white. The theory (module docstring): the window mean of ``(e/s)^2`` averaged over the runs
is smaller than ``chi2(n) / n`` in the convex order whatever the time dependence, the band
is the any-dependence band of that law, and Bonferroni over the windows bounds the
campaign's false-alarm probability by ``false_alarm`` (1 %).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from cosim.verify.calibration import CALIBRATION_FALSE_ALARM, calibrate

T = np.linspace(0.0, 100.0, 201)


def gauss_markov(rng: np.random.Generator, n: int, rho: float) -> np.ndarray:
    """Unit-variance first-order Gauss-Markov sequences, shape (n, len(T))."""
    x = np.empty((n, T.size))
    x[:, 0] = rng.standard_normal(n)
    w = rng.standard_normal((n, T.size)) * np.sqrt(1.0 - rho**2)
    for i in range(1, T.size):
        x[:, i] = rho * x[:, i - 1] + w[:, i]
    return x


@pytest.mark.parametrize("rho", [0.0, 0.9, 0.999])
def test_a_consistent_filter_is_flagged_at_most_at_the_stated_rate(rho: float) -> None:
    """1000 campaigns of 20 consistent runs (sigma varying in time as a filter's converges):
    flagged in at most 1 % of campaigns plus three binomial sigmas (the Bonferroni and
    convex-order bound of the module docstring; white errors make it conservative)."""
    rng = np.random.default_rng(7 + int(1000 * rho))
    s = 3.0 * np.exp(-T / 30.0) + 0.5  # a converging filter's stated sigma
    flagged = 0
    campaigns = 1000
    for _ in range(campaigns):
        e = s * gauss_markov(rng, 20, rho)
        flagged += calibrate(T, e, np.broadcast_to(s, e.shape))["consistent"] is False
    p = CALIBRATION_FALSE_ALARM
    assert flagged <= campaigns * p + 3 * np.sqrt(campaigns * p * (1 - p))


def test_a_sigma_half_the_spread_early_on_is_found_and_placed() -> None:
    """50 runs whose stated sigma is half the actual spread before 20 s, right after: the
    first window(s) are flagged "too small by about 2x" (mean 4, upper band 1.87 at 50 runs
    and 0.1 % per window) in at least 95 % of 200 campaigns, nothing after 30 s."""
    rng = np.random.default_rng(11)
    s = np.full(T.size, 2.0)
    actual = np.where(T < 20.0, 2.0 * s, s)
    hits = 0
    for _ in range(200):
        e = actual * gauss_markov(rng, 50, 0.95)
        res = calibrate(T, e, np.broadcast_to(s, e.shape))
        spans = res["spans"]
        if spans and spans[0]["t_start"] == 0.0 and spans[0]["sigma"] == "too small":
            hits += 1
            assert 1.4 <= spans[0]["factor"] <= 2.8
            assert all(sp["t_end"] <= 30.0 for sp in spans), spans
            assert res["message"].startswith("INCONSISTENT: sigma too small by about")
    assert hits >= 190


def test_a_sigma_three_times_too_large_is_found() -> None:
    """A pessimistic filter (sigma 3x the spread, mean 1/9 against a lower band of 0.44 at
    50 runs): "too large by about 3x" over the whole span."""
    rng = np.random.default_rng(3)
    e = gauss_markov(rng, 50, 0.9)
    res = calibrate(T, e, np.full(e.shape, 3.0))
    assert res["consistent"] is False
    assert [sp["sigma"] for sp in res["spans"]] == ["too large"]
    assert res["spans"][0]["t_start"] == 0.0 and res["spans"][0]["t_end"] == 100.0
    assert 2.4 <= res["spans"][0]["factor"] <= 3.6


def test_the_band_is_the_any_dependence_band_of_chi2_n_over_n() -> None:
    """Every window's band: at 50 runs and 0.1 % it is [0.44, 1.87] (any_dependence_band
    with 50 dof), and a consistent campaign's windows lie inside and near 1."""
    rng = np.random.default_rng(5)
    e = gauss_markov(rng, 50, 0.0)
    res = calibrate(T, e, np.ones_like(e))
    assert res["consistent"] is True and len(res["windows"]) == 10
    for w in res["windows"]:
        assert w["lower"] == pytest.approx(0.439, abs=0.002)
        assert w["upper"] == pytest.approx(1.870, abs=0.002)
        assert w["dof"] == 50 * w["n"]
    # the pooled mean of a white campaign: chi2(50 * 201) / (50 * 201), 99.9 % two-sided
    pooled = np.mean(e**2)
    assert (
        stats.chi2.ppf(5e-4, e.size) / e.size < pooled < stats.chi2.ppf(1 - 5e-4, e.size) / e.size
    )


def test_instants_without_a_sigma_are_skipped_and_one_run_is_not_judged() -> None:
    """Before the first update the sigma is 0: the judged span starts at the first instant
    where every run states a sigma; a single run is the NEES's business, not judged."""
    rng = np.random.default_rng(2)
    e = gauss_markov(rng, 10, 0.5)
    s = np.ones_like(e)
    s[:, :10] = 0.0
    s[3, 10] = np.nan
    res = calibrate(T, e, s)
    assert res["t_start"] == T[11] and res["samples"] == T.size - 11
    one = calibrate(T, e[:1], s[:1])
    assert (
        one["consistent"] is None and one["message"] == "not judged: 1 run(s) with a recorded sigma"
    )
