"""Tests of the seed-001 transfer-alignment filter (cosim/alignment/transfer*.py).

The UKF itself is tested in tests/estimation/test_unscented.py (on a linear model the UKF equals the
linear KF, x and P to 1e-9 after each step: ``test_ukf_equals_kf_on_a_linear_model``);
here: the error model against its linearisation and against the mechanisation, the
strapdown (cosim.alignment.nav) and master-rate accuracy, the covariance analysis against
the issue's figures, and closed-loop runs of the block in the scenario.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from cosim.alignment.nav import Strapdown, euler_rate_matrix, euler_rate_matrix_inv
from cosim.alignment.transfer import TransferAlignment
from cosim.alignment.transfer_analysis import transfer_covariance
from cosim.alignment.transfer_model import (
    PeriodSums,
    StateLayout,
    TransferConfigError,
    TransferRuntimeError,
    TransferTuning,
    linear_error_model,
    master_rate,
    propagate,
    reset_jacobian,
)
from cosim.estimation import van_loan
from cosim.models.constants import ARCMIN, DEG, G0, OMEGA_IE
from cosim.models.conventions import dcm_to_euler, dcm_to_rotvec, euler_to_dcm
from cosim.scenario import build_master, load_scenario

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "transfer_alignment.toml"
LAT = 30.0 * DEG

# State scales for finite differences and comparisons (typical sizes, SI).
SCALES = {
    "dL": 1e-7,
    "dV": 1e-2,
    "phi": 1e-3,
    "theta": 5e-4,
    "theta_dot": 2e-6,
    "nabla": 3e-3,
    "eps": 5e-8,
}


def _scale_vector(layout: StateLayout) -> np.ndarray:
    d = np.zeros(layout.n)
    d[layout.dl] = SCALES["dL"]
    d[layout.dv] = SCALES["dV"]
    d[layout.att] = SCALES["phi"]
    d[layout.nabla] = SCALES["nabla"]
    d[layout.eps] = SCALES["eps"]
    if layout.flexure:
        d[7:10] = SCALES["theta"]
        d[10:13] = SCALES["theta_dot"]
    return d


def _constant_sums(layout: StateLayout, T: float) -> tuple[PeriodSums, dict]:
    """Period sums of constant, ship-like inputs, and the same inputs for the linear model."""
    rng = np.random.default_rng(11)
    f_n = np.array([0.8, -1.3, -9.7])
    c_s_n = euler_to_dcm([0.15, -0.1, 0.6])
    v_n = np.array([1.6, -2.1, 0.4])
    m = rng.normal(0.0, 2.0, (3, 6)) if layout.flexure else None
    tune = TransferTuning()
    phi_flex = None
    if layout.flexure:
        F, G, Qc = tune.flexure_model()
        phi_flex, _ = van_loan(F, G, Qc, T)
    sums = PeriodSums.constant(T, f_n, c_s_n, v_n, LAT, 0.0, m, phi_flex)
    return sums, {"f_n": f_n, "c_s_n": c_s_n, "v_n": v_n, "m": m}


@pytest.mark.parametrize("flexure", [True, False])
def test_error_model_matches_the_numerical_jacobian_of_the_nonlinear_model(flexure: bool) -> None:
    """``propagate`` at zero error, differentiated numerically, equals ``I + A T`` (to O(T^2)).

    ``A`` is :func:`linear_error_model` (the small-error model used by the covariance
    analysis). Compared in scaled units (each state by its typical size) so that every
    block counts. Over T = 0.05 s the neglected terms are ``(A T)^2 / 2``; the largest
    products (``g T`` through ``phi -> dV -> dL``, ``f T`` with ``nabla``) stay below
    1e-3 of the scaled entries, hence the 2e-3 bound; a sign or factor error in any
    block shows up as an O(1) difference.
    """
    layout = StateLayout(flexure)
    T = 0.05
    sums, inp = _constant_sums(layout, T)
    d = _scale_vector(layout)
    n = layout.n
    J = np.zeros((n, n))
    for j in range(n):
        step = np.zeros(n)
        step[j] = 1e-3 * d[j]
        J[:, j] = (propagate(step, sums, layout) - propagate(-step, sums, layout)) / (2 * step[j])
    A = linear_error_model(
        inp["f_n"], inp["c_s_n"], inp["v_n"], LAT, 0.0, layout, m=inp["m"], m_dot=None
    )
    lin = np.eye(n) + A * T
    scaled_diff = (J - lin) * d[None, :] / d[:, None]
    scaled_a = (A * T) * d[None, :] / d[:, None]
    assert np.max(np.abs(scaled_diff)) < 2e-3 * max(1.0, np.max(np.abs(scaled_a)))
    # the model is not trivially the identity: the coupling blocks are present
    assert abs(J[layout.dv.start, layout.att.start + 1]) > 0.1 * 9.0 * T
    assert np.max(np.abs(J[layout.att, layout.eps])) > 0.5 * T


@pytest.fixture(scope="module")
def truth_record() -> dict[str, np.ndarray]:
    """60 s of the scenario's truth with a perfect slave IMU and a 30' flexure (visible)."""
    sc = load_scenario(SCENARIO)
    sc.settings = sc.master_settings(stop=60.0, record_every=1)
    sc.blocks["imu"].parameters.update(
        gyro_bias_sigma=0.0, gyro_arw=0.0, accel_bias_sigma=0.0, accel_vrw=0.0
    )
    sc.blocks["flex"].parameters["sigma"] = ["30 arcmin"] * 3
    sc.outputs = [
        "lever.rpy_s",
        "lever.v_n_s",
        "ship.rpy",
        "ship.omega_ib_b",
        "imu.dtheta_meas_b",
        "imu.dv_meas_b",
    ]
    master = build_master(sc)
    try:
        r = master.run()
    finally:
        master.terminate()
    out = {k: np.asarray(r[k]) for k in sc.outputs}
    out["time"] = np.asarray(r["time"])
    out["h"] = np.array(sc.settings.step)
    return out


def test_strapdown_reproduces_the_slave_truth(truth_record: dict[str, np.ndarray]) -> None:
    """Started on the truth, the mechanisation follows LeverArm's ``rpy_s``, ``v_n_s``.

    Perfect increments at the scenario's 50 ms step (truth integrated at 1 ms inside),
    flexure 30' so that the gyros sense a real flexure rate. Bounds: 0.01 arcmin and 1 mm/s
    after 60 s, 100 times below the filter's accuracy and velocity noise (measured
    1.5e-4 arcmin and 5e-5 m/s; without the third-order velocity term the vertical
    velocity drifts 6 mm/s in 60 s).
    """
    rec = truth_record
    h = float(rec["h"])
    sd = Strapdown(euler_to_dcm(rec["lever.rpy_s"][0]), LAT, 0.0, rec["lever.v_n_s"][0])
    att, vel = [], []
    for k in range(1, len(rec["time"])):
        sd.step(rec["imu.dtheta_meas_b"][k], rec["imu.dv_meas_b"][k], h)
        att.append(dcm_to_rotvec(sd.C_s_n @ euler_to_dcm(rec["lever.rpy_s"][k]).T))
        vel.append(sd.v_n - rec["lever.v_n_s"][k])
    assert np.max(np.abs(att)) / ARCMIN < 0.01
    assert np.max(np.abs(vel)) < 1e-3


def test_nonlinear_model_predicts_the_mechanisation_with_large_errors(
    truth_record: dict[str, np.ndarray],
) -> None:
    """``propagate`` predicts the error of a mechanisation started 30 deg off, period by period.

    Two mechanisations take the same increments: one started on the truth, one on the
    master's attitude (the slave's mounting 1, 1, 30 deg is its error) with a wrong bias
    compensation. Their actual difference (error rotation, velocity, latitude) after each
    0.5 s is compared with the model's prediction from the actual difference at the
    period's start. Bounds 1e-3 arcmin and 1e-4 m/s (100 times below R); the linearised
    model (:func:`linear_error_model`) misses by more than 0.1 m/s, which is why the
    filter propagates the nonlinear model.
    """
    rec = truth_record
    h = float(rec["h"])
    lay = StateLayout(False)
    a = Strapdown(euler_to_dcm(rec["lever.rpy_s"][0]), LAT, 0.0, rec["lever.v_n_s"][0])
    b = Strapdown(euler_to_dcm(rec["ship.rpy"][0]), LAT, 0.0, rec["lever.v_n_s"][0])
    nab = np.array([3e-4, -2e-4, 1e-4]) * G0
    b.accel_bias = -nab
    sums = PeriodSums(lat=b.lat, height=b.height)

    def actual() -> np.ndarray:
        x = np.zeros(lay.n)
        x[lay.att] = dcm_to_euler(b.C_s_n @ a.C_s_n.T)
        x[lay.dv] = b.v_n - a.v_n
        x[lay.dl] = b.lat - a.lat
        x[lay.nabla] = nab
        return x

    x0 = actual()
    assert abs(x0[lay.heading]) > 29.0 * DEG
    err_att, err_v, err_lin = 0.0, 0.0, 0.0
    for k in range(1, len(rec["time"])):
        a.step(rec["imu.dtheta_meas_b"][k], rec["imu.dv_meas_b"][k], h)
        b.step(rec["imu.dtheta_meas_b"][k], rec["imu.dv_meas_b"][k], h)
        sums.add(b, h)
        if k % 10:
            continue
        x1 = actual()
        xp = propagate(x0, sums, lay)
        err_att = max(err_att, float(np.max(np.abs(xp[lay.att] - x1[lay.att]))))
        err_v = max(err_v, float(np.max(np.abs(xp[lay.dv] - x1[lay.dv]))))
        T = sums.T
        f_mean = sums.dv_f / T
        A = linear_error_model(f_mean, sums.c_int / T, sums.v_int / T, b.lat, 0.0, lay)
        x_lin = x0 + A @ x0 * T
        err_lin = max(err_lin, float(np.max(np.abs(x_lin[lay.dv] - x1[lay.dv]))))
        a.refresh()
        b.refresh()
        sums = PeriodSums(lat=b.lat, height=b.height)
        x0 = x1
    assert err_att / ARCMIN < 1e-3
    assert err_v < 1e-4
    assert err_lin > 0.1


def test_master_rate_from_attitudes(truth_record: dict[str, np.ndarray]) -> None:
    """The five-point difference of the master's attitudes gives its body rate.

    Truth: ``omega_nb_b = omega_ib_b - C_n_b omega_ie_n``. At 50 ms the formula's error
    is ``h^4 |omega^(5)| / 5`` ~ 1e-7 rad/s for seed 001's motion; bound 1e-6 rad/s, i.e.
    0.02 mm/s of lever-arm velocity on the 15 m arm (R is 10 mm/s).
    """
    rec = truth_record
    h = float(rec["h"])
    w_ie = np.array([OMEGA_IE * math.cos(LAT), 0.0, -OMEGA_IE * math.sin(LAT)])
    worst = 0.0
    for k in range(4, len(rec["time"]), 7):
        hist = [euler_to_dcm(rec["ship.rpy"][k - j]) for j in range(5)]
        w_nb = rec["ship.omega_ib_b"][k] - hist[0].T @ w_ie
        worst = max(worst, float(np.max(np.abs(master_rate(hist, h) - w_nb))))
    assert worst < 1e-6


def test_euler_rate_matrix_and_the_reset_jacobian() -> None:
    """Left-perturbation Euler Jacobian, its closed-form inverse, and the feedback reset."""
    rng = np.random.default_rng(3)
    rpy = np.array([0.2, -0.3, 2.5])
    d = rng.normal(0.0, 1e-7, 3)
    rot = dcm_to_rotvec(euler_to_dcm(rpy + d) @ euler_to_dcm(rpy).T)
    np.testing.assert_allclose(rot, euler_rate_matrix(rpy) @ d, rtol=1e-5, atol=1e-13)
    np.testing.assert_allclose(
        euler_rate_matrix_inv(rpy) @ euler_rate_matrix(rpy), np.eye(3), atol=1e-12
    )
    # reset: new error angles = euler(E(phi) E(phi_hat)^T) ~ J (phi - phi_hat), phi_hat large
    lay = StateLayout(True)
    x_hat = np.zeros(lay.n)
    x_hat[lay.att] = [0.01, -0.02, 2.0]
    dphi = rng.normal(0.0, 1e-6, 3)
    new = dcm_to_euler(euler_to_dcm(x_hat[lay.att] + dphi) @ euler_to_dcm(x_hat[lay.att]).T)
    J = reset_jacobian(x_hat, lay)
    np.testing.assert_allclose(new, J[lay.att, lay.att] @ dphi, rtol=1e-4, atol=1e-14)
    assert np.array_equal(J[lay.nabla, lay.nabla], np.eye(3))


def test_covariance_analysis_matches_the_issue_figures() -> None:
    """Independent linear covariance analysis against the issue's physics check.

    Issue: rigid lever arm [10, 10, 5] m, velocity matching every 0.5 s with 0.01 m/s noise:
    heading sigma about 4.5' at 30 s and 3.1' at 60 s, level 0.85-0.95' at 30 s and
    0.6-0.8' at 120 s. Tolerances: +-10 % on the heading ("about"), the stated level ranges
    widened by 0.05' (the issue's P0 is not given). Level here: each of the north and east
    sigmas. Also: bias/g = 1.03' bounds the level from above (what the ship's motion
    separates is little), and the flexure states never reduce the uncertainty.
    """
    rigid = transfer_covariance(120.0, dt=0.25)
    flex = transfer_covariance(120.0, dt=0.25, flexure=True)
    i30, i60, i120 = rigid.index(30.0), rigid.index(60.0), rigid.index(120.0)
    nav = rigid.sigma[:, StateLayout.att] / ARCMIN
    nav_flex = flex.sigma[:, StateLayout.att] / ARCMIN
    assert 4.5 * 0.9 <= nav[i30, 2] <= 4.5 * 1.1
    assert 3.1 * 0.9 <= nav[i60, 2] <= 3.1 * 1.1
    assert np.all((nav[i30, :2] >= 0.80) & (nav[i30, :2] <= 1.00))
    assert np.all((nav[i120, :2] >= 0.55) & (nav[i120, :2] <= 0.85))
    bias_over_g = 3e-4 / ARCMIN
    assert np.all(nav[:, :2][rigid.time >= 30.0] < bias_over_g)
    assert np.all(nav_flex[i120] >= nav[i120] - 1e-6)


def test_block_rejects_bad_configuration() -> None:
    """Typed errors for a bad switch and for a step that does not divide the period."""
    block = TransferAlignment()
    block.flexure_states = 2
    block.setup_experiment(0.0)
    with pytest.raises(TransferConfigError, match="flexure_states"):
        block.exit_initialization_mode()
    block = TransferAlignment()
    block.setup_experiment(0.0)
    block.exit_initialization_mode()
    with pytest.raises(TransferRuntimeError, match="whole number of steps"):
        block.do_step(0.0, 0.3)


def _run(overrides: dict[str, dict], stop: float = 120.0) -> dict[str, np.ndarray]:
    sc = load_scenario(SCENARIO)
    sc.settings = sc.master_settings(stop=stop)
    for block, params in overrides.items():
        sc.blocks[block].parameters.update(params)
    sc.outputs = ["align.rpy_err", "align.rpy_sigma", "align.stage", "align.rel_rpy", "align.nis"]
    master = build_master(sc)
    try:
        r = master.run()
    finally:
        master.terminate()
    return {k: np.asarray(r[k]) for k in ("time", *sc.outputs)}


def _rms_from(r: dict[str, np.ndarray], key: str, t0: float = 30.0) -> np.ndarray:
    m = r["time"] >= t0
    return np.sqrt(np.mean(r[key][m] ** 2, axis=0))


@pytest.fixture(scope="module")
def scenario_run() -> dict[str, np.ndarray]:
    """The transfer-alignment scenario as written (seeds 1, 2, 3), 120 s."""
    return _run({})


def test_fixed_seed_run_meets_the_heading_requirement(scenario_run: dict[str, np.ndarray]) -> None:
    """The scenario as written (seeds 1, 2, 3): heading RMS from 30 s <= 7', errors consistent.

    Consistency per axis: RMS error below 2.5 times the RMS of the filter's sigma (a single
    run's level error is one draw of the bias: a 2.5-sigma margin).
    """
    r = scenario_run
    rms = _rms_from(r, "align.rpy_err")
    sig = _rms_from(r, "align.rpy_sigma")
    assert rms[2] <= 7.0
    assert np.all(rms <= 2.5 * sig)
    assert r["align.stage"][-1] == 2.0
    assert abs(r["align.rpy_err"][0, 2]) > 25 * 60  # it really started 30 deg off


def test_fixed_seed_run_innovations_are_consistent_in_both_stages(
    scenario_run: dict[str, np.ndarray],
) -> None:
    """NIS of the velocity updates (every 0.5 s), acquisition and fine alignment apart.

    For a consistent filter the NIS of K independent updates sum to chi-square with 3K
    degrees of freedom: each stage's mean NIS lies in that distribution's central 99.9 %
    (the acquisition reports its most probable hypothesis' own UKF innovation).
    """
    r = scenario_run
    t, stage, nis = r["time"], r["align.stage"], r["align.nis"]
    at_update = np.isclose(np.round(t / 0.5) * 0.5, t) & (t >= 0.5)
    for s in (1.0, 2.0):
        v = nis[at_update & (stage == s)]
        k = v.size
        assert k >= 5 and np.all(v > 0.0), (s, v)
        lo, hi = chi2.ppf([0.0005, 0.9995], 3 * k) / k
        assert lo <= v.mean() <= hi, (s, k, v.mean(), lo, hi)


def test_paper_single_case() -> None:
    """Seed 001's case: fixed bias 3e-4 g and drift 0.01 deg/h on every axis.

    The paper (Table 1, flexure modelled) gives pitch 0.334', roll 0.191', heading 6.94'.
    Checked: final heading within the paper's 7' requirement; final level errors within
    the bias limit bias/g = 1.03' (a fixed 3e-4 g bias cannot be told from tilt much
    better); the true relative attitude at the end is the mounting plus a flexure of a
    few arcmin (paper: 1.055706, 1.015315, 29.98939 deg).
    """
    r = _run(
        {
            "imu": {
                "gyro_bias_sigma": 0.0,
                "accel_bias_sigma": 0.0,
                "gyro_bias": ["0.01 deg/h"] * 3,
                "accel_bias": ["300 ug"] * 3,
            }
        }
    )
    final = r["align.rpy_err"][-1]
    assert abs(final[2]) <= 7.0
    assert np.all(np.abs(final[:2]) <= 3e-4 / ARCMIN)
    true_rel = r["align.rel_rpy"][-1] / DEG - final / 60.0
    np.testing.assert_allclose(true_rel, [1.0, 1.0, 30.0], atol=0.15)


def test_ignoring_a_large_flexure_degrades_the_alignment() -> None:
    """Modelled against ignored flexure on the same run, flexure sigma 30' (10 m arm).

    With the digest's 2' the flexure's lever-arm velocity (< 1 mm/s) is far below the
    10 mm/s velocity noise and both filters agree (README); at 30' the 13-state filter
    mistakes the flexing arm's velocity for attitude and bias errors. Measure: the
    normalised squared error ``sum_axes (RMS_e / RMS_sigma)^2`` from 30 s (3 for a
    consistent filter). Seeds 1, 5, 9 of the flexure give 11-96 ignored against 1.4-1.6
    modelled; checked: ignored > 4 x modelled, modelled < 3 per axis.
    """
    big = {"flex": {"sigma": ["30 arcmin"] * 3}, "align": {"flexure_sigma": ["30 arcmin"] * 3}}
    mod = _run(big)
    ign = _run({**big, "align": {**big["align"], "flexure_states": 0}})
    z_mod = _rms_from(mod, "align.rpy_err") / _rms_from(mod, "align.rpy_sigma")
    z_ign = _rms_from(ign, "align.rpy_err") / _rms_from(ign, "align.rpy_sigma")
    assert np.sum(z_ign**2) > 4.0 * np.sum(z_mod**2)
    assert np.all(z_mod**2 < 3.0)
