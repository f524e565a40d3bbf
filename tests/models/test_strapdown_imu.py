"""StrapdownImu: perfect pass-through, error terms against theory, presets, RLG modes.

Every block runs through the FMI life cycle of the base class (instantiate, set
parameters, setup_experiment, exit_initialization_mode, do_step at t = n h).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.estimation.allan import allan_deviation, relative_error
from cosim.models.blocks.strapdown_imu import (
    PRESETS,
    StrapdownImu,
    integrated_first_order,
    white_density_from_random,
)
from cosim.models.constants import DEG_PER_HOUR, DEG_PER_SQRT_HOUR, G0, MICRO_G


def make(**params: object) -> StrapdownImu:
    """A StrapdownImu with the given parameters, initialised at t0 = 0."""
    imu = StrapdownImu()
    for name, value in params.items():
        if isinstance(value, (tuple, list, np.ndarray)):
            value = np.asarray(value, dtype=float)
        setattr(imu, name, value)
    imu.setup_experiment(0.0)
    imu.exit_initialization_mode()
    return imu


def run(
    imu: StrapdownImu,
    h: float,
    n: int,
    dtheta: np.ndarray | None = None,
    dv: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Step ``n`` times with the given true increments (rows per step); outputs (n, 3)."""
    names = ("dtheta_meas_b", "dv_meas_b", "omega_meas_b", "f_meas_b", "gyro_bias_b")
    out = {name: np.empty((n, 3)) for name in names}
    zero = np.zeros(3)
    for k in range(n):
        imu.dtheta_b = zero if dtheta is None else dtheta[k]
        imu.dv_b = zero if dv is None else dv[k]
        imu.do_step(k * h, h)
        for name in names:
            out[name][k] = getattr(imu, name)
    return out


def test_default_instance_is_a_perfect_imu() -> None:
    h, n = 0.01, 2000
    rng = np.random.default_rng(1)
    dtheta = rng.standard_normal((n, 3)) * np.radians(100.0) * h  # up to a few 100 deg/s
    dv = rng.standard_normal((n, 3)) * 20.0 * h + np.array([0.0, 0.0, -G0 * h])
    imu = make()
    out = run(imu, h, n, dtheta, dv)
    assert np.max(np.abs(out["dtheta_meas_b"] - dtheta)) <= 1e-15
    assert np.max(np.abs(out["dv_meas_b"] - dv)) <= 1e-15
    assert np.max(np.abs(out["omega_meas_b"] - dtheta / h)) <= 1e-15 / h
    assert np.max(np.abs(out["f_meas_b"] - dv / h)) <= 1e-15 / h
    assert np.all(out["gyro_bias_b"] == 0.0)


@pytest.mark.parametrize(
    ("paper", "gyro_drift", "gyro_random", "accel_bias", "accel_random"),
    [
        # seed 001, slave IMU: drift 0.01 deg/h, random 0.001 deg/h; bias 3e-4 g, random 5e-5 g
        ("seed001", 0.01, 0.001, 3.0e-4, 5.0e-5),
        # seed 003: drift 0.02 deg/h, random 0.01 deg/h; bias 100 ug, random 50 ug
        ("seed003", 0.02, 0.01, 1.0e-4, 0.5e-4),
    ],
)
def test_paper_figures_arw_vrw_from_allan_deviation(
    paper: str, gyro_drift: float, gyro_random: float, accel_bias: float, accel_random: float
) -> None:
    # Mapping under test: a paper's "random" figure is the Allan deviation at 1 s of a
    # white noise, so ARW = random * sqrt(1 s); the constant figure is the fixed bias.
    arw = white_density_from_random(gyro_random * DEG_PER_HOUR)
    vrw = white_density_from_random(accel_random * G0)
    h, n = 0.1, 40_000  # 4000 s; tau = 1 s is a cluster of m = 10 samples
    imu = make(
        seed=3,
        gyro_bias=[gyro_drift * DEG_PER_HOUR] * 3,
        gyro_arw=arw,
        accel_bias=[accel_bias * G0] * 3,
        accel_vrw=vrw,
    )
    out = run(imu, h, n)
    m = round(1.0 / h)
    # Theory: white noise gives adev(tau) = N / sqrt(tau); with n = 40000 samples and
    # m = 10 the overlapping estimator has edf ~ 6000, a relative standard error of
    # ~0.9 % (asserted below), so the 5 % bound is more than five standard errors.
    assert relative_error(n, m, "white") < 0.01
    _, adev_g = allan_deviation(out["omega_meas_b"], h, m)
    _, adev_a = allan_deviation(out["f_meas_b"], h, m)
    np.testing.assert_allclose(adev_g[0], arw, rtol=0.05)
    np.testing.assert_allclose(adev_a[0], vrw, rtol=0.05)
    # The constant parts: the mean of a record of length T has a white-noise error of
    # N / sqrt(T); five of those.
    t_total = n * h
    mean_g, mean_a = out["omega_meas_b"].mean(axis=0), out["f_meas_b"].mean(axis=0)
    assert np.all(np.abs(mean_g - gyro_drift * DEG_PER_HOUR) < 5.0 * arw / math.sqrt(t_total))
    assert np.all(np.abs(mean_a - accel_bias * G0) < 5.0 * vrw / math.sqrt(t_total))


def test_gauss_markov_bias_variance_and_correlation_time() -> None:
    sigma_g, sigma_a, tau = 2.0e-6, 3.0e-4, 1.0  # rad/s, m/s2, s
    h, n = 0.2, 50_000  # T / tau = 10000 correlation times
    imu = make(
        seed=5, gyro_bi_sigma=sigma_g, gyro_bi_tau=tau, accel_bi_sigma=sigma_a, accel_bi_tau=tau
    )
    out = run(imu, h, n)
    # Only the Gauss-Markov term is on: the measured rate is the step mean of the bias.
    np.testing.assert_allclose(out["omega_meas_b"], out["gyro_bias_b"], rtol=1e-12)
    phi = math.exp(-h / tau)
    # Theory for the mean over a step of a first-order Gauss-Markov process x:
    #   var = sigma^2 * 2 (tau/h)^2 (h/tau - 1 + phi),
    #   cov(lag k >= 1) = sigma^2 (tau/h)^2 (1 - phi)^2 phi^(k-1)  (geometric in k).
    # Sample variance over T = 10000 tau: relative std sqrt(2 tau / T) = 1.4 %, so the
    # 10 % bound is seven standard deviations. The correlation time is fitted to the
    # log autocovariance at lags 1..5 (one correlation time); its relative std from
    # such a record is ~2 % (checked over seeds), so 10 % is five of them.
    factor = 2.0 * (tau / h) ** 2 * (h / tau - 1.0 + phi)
    lags = np.arange(1, 6)
    for rate, sigma in ((out["omega_meas_b"], sigma_g), (out["f_meas_b"], sigma_a)):
        x = rate - rate.mean(axis=0)
        var = np.mean(x**2, axis=0)
        np.testing.assert_allclose(var, sigma**2 * factor, rtol=0.10)
        cov = np.array([np.mean(x[k:] * x[:-k], axis=0) for k in lags])  # (5, 3)
        slope = np.polyfit(lags, np.log(cov), 1)[0]  # per axis
        np.testing.assert_allclose(-h / slope, tau, rtol=0.10)


def test_rate_random_walk_allan_slope() -> None:
    # Theory: a bias random walk of density K gives avar(tau) = K^2 tau / 3 (the step
    # means are exact averages of the continuous process). At tau = 1 s (m = 10) with
    # n = 40000 the relative standard error is ~1.1 %; 5 % is > 4 of them.
    k_g, k_a = 1.0e-7, 1.0e-5
    h, n = 0.1, 40_000
    out = run(make(seed=9, gyro_rrw=k_g, accel_rrw=k_a), h, n)
    m = 10
    assert relative_error(n, m, "rrw") < 0.0125
    _, adev_g = allan_deviation(out["omega_meas_b"], h, m)
    _, adev_a = allan_deviation(out["f_meas_b"], h, m)
    np.testing.assert_allclose(adev_g[0], k_g * math.sqrt(1.0 / 3.0), rtol=0.05)
    np.testing.assert_allclose(adev_a[0], k_a * math.sqrt(1.0 / 3.0), rtol=0.05)


def test_scale_factor_and_misalignment_are_applied_exactly() -> None:
    sf_g = np.array([100e-6, -200e-6, 300e-6])
    sf_a = np.array([-50e-6, 20e-6, 400e-6])
    m_g = np.array([[0.0, 1e-4, -2e-4], [3e-4, 0.0, 4e-4], [-5e-4, 6e-4, 0.0]])
    m_a = np.array([[0.0, -1e-3, 2e-3], [5e-4, 0.0, -7e-4], [1e-4, 9e-4, 0.0]])
    imu = make(
        gyro_sf=sf_g, gyro_misalignment=m_g.ravel(), accel_sf=sf_a, accel_misalignment=m_a.ravel()
    )
    h = 0.01
    dtheta = np.radians([10.0, -20.0, 100.0]) * h
    dv = np.array([0.3, -0.2, -G0]) * h
    out = run(imu, h, 3, np.tile(dtheta, (3, 1)), np.tile(dv, (3, 1)))
    expected_g = (np.eye(3) + np.diag(sf_g) + m_g) @ dtheta
    expected_a = (np.eye(3) + np.diag(sf_a) + m_a) @ dv
    np.testing.assert_allclose(out["dtheta_meas_b"], np.tile(expected_g, (3, 1)), rtol=1e-14)
    np.testing.assert_allclose(out["dv_meas_b"], np.tile(expected_a, (3, 1)), rtol=1e-14)
    # Per-axis check by hand for one element: x gyro sees (1 + sf_x) wx + M_xy wy + M_xz wz.
    x_by_hand = (1 + sf_g[0]) * dtheta[0] + m_g[0, 1] * dtheta[1] + m_g[0, 2] * dtheta[2]
    assert out["dtheta_meas_b"][0, 0] == pytest.approx(x_by_hand, rel=1e-14)


def test_turn_on_draws_scale_with_their_sigma() -> None:
    # Same seed, doubled turn-on sigmas: the error part doubles exactly (draws are
    # independent of the configuration), and only off-diagonal misalignments are drawn.
    h = 0.01
    dtheta = np.tile(np.radians([30.0, 40.0, 50.0]) * h, (2, 1))
    errs = []
    for scale in (1.0, 2.0):
        imu = make(seed=21, gyro_sf_sigma=1e-4 * scale, gyro_misalignment_sigma=1e-4 * scale)
        errs.append(run(imu, h, 2, dtheta)["dtheta_meas_b"] - dtheta)
    np.testing.assert_allclose(errs[1], 2.0 * errs[0], rtol=1e-9)
    assert np.all(np.abs(errs[0]) > 0.0)
    # With only the misalignment sigma, a rate about x alone does not show on x.
    imu = make(seed=21, gyro_misalignment_sigma=1e-3)
    out = run(imu, h, 1, np.array([[0.01, 0.0, 0.0]]))
    assert out["dtheta_meas_b"][0, 0] == 0.01
    assert np.all(out["dtheta_meas_b"][0, 1:] != 0.0)


def test_quantisation_outputs_whole_lsb_and_does_not_accumulate() -> None:
    lsb_g, lsb_a = 1.0e-5, 1.0e-4  # rad, m/s
    h, n = 0.01, 10_000
    t = np.arange(n)[:, None] * h
    dtheta = 0.003 * np.sin(0.7 * t + np.array([0.0, 1.0, 2.0])) * h + 3.3e-6
    dv = np.array([0.11, -0.07, -G0]) * h + 0.02 * np.cos(1.3 * t) * h
    imu = make(gyro_lsb=lsb_g, accel_lsb=lsb_a)
    out = run(imu, h, n, dtheta, dv)
    for meas, true, lsb in ((out["dtheta_meas_b"], dtheta, lsb_g), (out["dv_meas_b"], dv, lsb_a)):
        counts = meas / lsb
        assert np.max(np.abs(counts - np.round(counts))) < 1e-6
        # Residual carried: |sum q - sum y| <= LSB / 2 at every step (rounding quantiser),
        # within the requirement of one LSB.
        drift = np.abs(np.cumsum(meas, axis=0) - np.cumsum(true, axis=0))
        assert np.max(drift) <= 0.5 * lsb * (1.0 + 1e-6)
        assert np.max(drift) > 0.1 * lsb  # the quantiser is really active
    # Without the carry the error would grow: truncating each step separately drifts.
    naive = lsb_g * np.round(dtheta / lsb_g)
    assert np.max(np.abs(np.cumsum(naive - dtheta, axis=0))) > 10 * lsb_g


def test_rate_biased_rlg_reduces_random_walk_by_the_configured_factor() -> None:
    # Seed 003: RWC 0.001 deg/sqrt(h); rate biasing at ~100 deg/s, reversing every 10 s,
    # reduces the random walk ~10x. The IMU sits on the turntable: its inputs carry
    # the table rate and the centrifugal acceleration, and it must measure them.
    h, n = 0.01, 20_000  # 200 s per mode
    k = np.arange(n)
    table_rate = np.radians(100.0) * np.where((k * h // 10.0) % 2 == 0, 1.0, -1.0)
    dtheta = np.zeros((n, 3))
    dtheta[:, 2] = table_rate * h
    radius = 0.05  # m, accelerometer offset from the table axis
    dv = np.zeros((n, 3))
    dv[:, 0] = -radius * table_rate**2 * h  # centripetal (specific force towards the axis)
    dv[:, 2] = -G0 * h
    rwc = 0.001 * DEG_PER_SQRT_HOUR
    results = {}
    for mode, seed in ((1, 1), (2, 2)):
        imu = make(seed=seed, gyro_arw=rwc, rlg_mode=mode, rlg_rw_reduction=10.0)
        out = run(imu, h, n, dtheta, dv)
        # Nothing removes the table motion: the accelerometers see exactly the input and
        # the gyros the table rate (plus noise only).
        np.testing.assert_array_equal(out["dv_meas_b"], dv)
        assert np.max(np.abs(out["omega_meas_b"][:, 2] - table_rate)) < 1e-3 * np.radians(100.0)
        heading_error = np.cumsum(out["dtheta_meas_b"][:, 2] - dtheta[:, 2])
        # Random walk coefficient from the variance growth of the integrated angle:
        # var(theta(t0 + L h) - theta(t0)) = N^2 L h, from non-overlapping windows.
        estimates, weights = [], []
        for window in (10, 20, 50, 100):
            seg = heading_error[window - 1 :: window]
            growth = np.diff(seg)
            estimates.append(np.mean(growth**2) / (window * h))
            weights.append(growth.size)
        estimates = np.array(estimates)
        # Linear growth: every window gives the same N^2 (within 3 standard errors).
        assert np.all(
            np.abs(estimates / estimates[0] - 1.0) < 3.0 * np.sqrt(2.0 / np.array(weights))
        )
        results[mode] = math.sqrt(np.average(estimates, weights=weights))
    # Theory: each N estimate from M windows has relative std 1/sqrt(2M) (~1.6 % for
    # M = 2000 at L = 10), the ratio ~2.5 %: the 20 % bound is ~8 standard errors.
    ratio = results[1] / results[2]
    assert abs(ratio / 10.0 - 1.0) < 0.20, ratio
    assert abs(results[1] / rwc - 1.0) < 0.1


def test_grade_presets_and_explicit_overrides() -> None:
    res0 = make().resolved_parameters()
    assert all(v == 0.0 for k, v in res0.items() if not k.endswith("_tau"))
    res1 = make(grade=1).resolved_parameters()
    for name, value in PRESETS[1].items():
        assert res1[name] == value
    assert res1["gyro_arw"] == pytest.approx(0.002 * DEG_PER_SQRT_HOUR)
    assert res1["accel_bias_sigma"] == pytest.approx(25.0 * MICRO_G)
    # An explicit value (>= 0, including zero) wins over the preset; the rest stays.
    res2 = make(grade=2, gyro_arw=0.0, accel_vrw=1e-3).resolved_parameters()
    assert res2["gyro_arw"] == 0.0 and res2["accel_vrw"] == 1e-3
    assert res2["gyro_bias_sigma"] == PRESETS[2]["gyro_bias_sigma"]
    # Rate-biased RLG divides the (preset) ARW.
    res3 = make(grade=1, rlg_mode=2, rlg_rw_reduction=4.0).resolved_parameters()
    assert res3["gyro_arw_effective"] == pytest.approx(PRESETS[1]["gyro_arw"] / 4.0)
    for bad in ({"grade": 3}, {"rlg_mode": 5}, {"gyro_bi_sigma": 1e-6, "gyro_bi_tau": 0.0}):
        with pytest.raises(ValueError):
            make(**bad)


def test_same_seed_same_outputs_and_grades_make_errors() -> None:
    h, n = 0.01, 200
    dv = np.tile([0.0, 0.0, -G0 * h], (n, 1))
    a = run(make(grade=2, seed=7, gyro_lsb=1e-7), h, n, dv=dv)
    b = run(make(grade=2, seed=7, gyro_lsb=1e-7), h, n, dv=dv)
    c = run(make(grade=2, seed=8, gyro_lsb=1e-7), h, n, dv=dv)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name])
    assert not np.array_equal(a["dtheta_meas_b"], c["dtheta_meas_b"])
    # A tactical IMU at rest shows a turn-on bias of the order of its preset sigma.
    bias = np.abs(a["gyro_bias_b"].mean(axis=0))
    assert np.all(bias < 5.0 * math.hypot(1.0, 0.5) * DEG_PER_HOUR) and np.any(bias > 0.0)


def test_integrated_first_order_matches_random_walk_limit() -> None:
    # beta -> 0 tends to the random walk: Q = [[h, h^2/2], [h^2/2, h^3/3]].
    h = 0.1
    _, g0, c0 = integrated_first_order(0.0, h)
    _, g1, c1 = integrated_first_order(1e-9, h)
    assert g0 == h
    np.testing.assert_allclose(c0 @ c0.T, [[h, h * h / 2], [h * h / 2, h**3 / 3]], rtol=1e-14)
    np.testing.assert_allclose(c1 @ c1.T, c0 @ c0.T, rtol=1e-8)
    assert g1 == pytest.approx(h, rel=1e-8)
