"""Attitude matching and lag estimation of TransferAlignment (issue 26, item 4).

The measurement model is checked against rotations built from the truth (exact in the
mounting, flexure and attitude error; the lag term to first order); the land-vehicle
scenario runs short here (30 s, one seed: velocity against velocity+attitude, a 20 ms
lag, and every truth input left out). The 50-run figures of acceptance 3 are in the slow
tests at the end.
"""

from __future__ import annotations

import numpy as np
import pytest
from transfer_vehicle import MOUNT_DEG, final_figures, vehicle_run

from cosim.alignment.transfer import TransferAlignment
from cosim.alignment.transfer_filter import StageSettings
from cosim.alignment.transfer_matching import MatchingFilter, turned_residual
from cosim.alignment.transfer_model import StateLayout, TransferConfigError, TransferTuning
from cosim.models import native
from cosim.models.constants import ARCMIN, DEG
from cosim.models.conventions import dcm_to_rotvec, euler_to_dcm, rotvec_to_dcm
from cosim.verify.calibration import calibrate

LAT = 34.2 * DEG
C_B_N = euler_to_dcm(np.array([0.1, -0.05, 1.0]))
W_EB_B = np.array([0.01, 0.02, -0.03])
V_M = np.array([10.0, 5.0, 0.0])
C_NOM = euler_to_dcm(np.array([0.01, 0.02, 0.3]))


def started(matching: int, lag: bool = False, flexure: bool = True) -> MatchingFilter:
    """A matching filter started on the fixed master state above."""
    f = MatchingFilter(
        StateLayout(flexure),
        TransferTuning(p0_heading=3.0 * DEG),
        np.array([1.2, 0.4, -0.6]),
        StageSettings(),
        LAT,
        matching=matching,
        estimate_lag=lag,
        r_att=ARCMIN,
        p0_lag=0.05,
        c_nom=C_NOM,
    )
    f.start(C_B_N, W_EB_B, V_M, LAT, 0.0)
    return f


def rho_of(phi: np.ndarray, mu: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The filter's residual state for attitude error ``phi`` (Euler), mounting residual
    ``mu`` and flexure ``theta`` (master axes), from its definition
    ``exp([rho x]) = E(phi) exp([C_b_n theta x]) E(nu)^T``,
    ``E(nu) = C_b_n exp(-[mu x]) C_b_n^T``."""
    e_nu = C_B_N @ rotvec_to_dcm(-mu) @ C_B_N.T
    return dcm_to_rotvec(euler_to_dcm(phi) @ rotvec_to_dcm(C_B_N @ theta) @ e_nu.T)


def set_truth(f: MatchingFilter, phi: np.ndarray, mu: np.ndarray, theta: np.ndarray) -> None:
    """Turn the mechanisation's attitude to ``E(phi) C_b_n exp(theta) exp(mu) C_nom``."""
    c_s_n = C_B_N @ rotvec_to_dcm(theta) @ rotvec_to_dcm(mu) @ C_NOM
    target = euler_to_dcm(phi) @ c_s_n
    f.nav.correct(rotation=target @ f.nav.C_s_n.T)


def test_attitude_measurement_is_exact_in_mounting_flexure_and_attitude_error() -> None:
    """z_a = rotvec(C^_s_n C_nom^T C_b_n^T) equals h(x) at the true state to rounding,
    for errors of degrees (the model is exact, not small-angle): the residual state
    defined from phi, the mounting and the flexure is what the mechanisation shows; a
    mounting alone gives C_b_n mu (the rotation vector of a conjugated rotation)."""
    f = started(2)
    phi = np.array([1.0, -2.0, 3.0]) * DEG
    mu = np.array([0.5, -0.8, 1.5]) * DEG
    theta = np.array([2.0, 1.0, -3.0]) * ARCMIN
    set_truth(f, phi, mu, theta)
    x = np.zeros(f.n)
    x[4:7] = phi
    x[7:10] = theta
    x[f.rho] = rho_of(phi, mu, theta)
    z = f.measured(C_B_N, W_EB_B, V_M)
    h = f.measurement_model(x, C_B_N, C_B_N @ W_EB_B, np.zeros(3))
    np.testing.assert_allclose(z[3:], h[3:], rtol=0, atol=1e-12)
    assert f.dim_z == 6 and z.shape == (6,)
    x_mount = np.zeros(f.n)
    x_mount[f.rho] = rho_of(np.zeros(3), np.array([0.0, 0.0, 1.0 * DEG]), np.zeros(3))
    moved = f.measurement_model(x_mount, C_B_N, C_B_N @ W_EB_B, np.zeros(3))[3:]
    np.testing.assert_allclose(moved, C_B_N[:, 2] * DEG, rtol=0, atol=1e-14)


def test_the_filter_starts_on_master_times_nominal_mounting_with_a_zero_residual() -> None:
    """At the start the attitude residual is zero (the mechanisation is the master's
    attitude times C_nom): rho is the master's attitude noise alone, Var(rho) = r_att^2,
    and phi = rho + nu - C_b_n theta: Var(phi - rho + C_b_n theta) is the mounting's
    prior in navigation axes, C_b_n diag(p0_level^2, p0_level^2, p0_heading^2) C_b_n^T."""
    f = started(1)
    assert np.max(np.abs(f.measured(C_B_N, W_EB_B, V_M))) < 1e-12
    P = f.P_show
    np.testing.assert_allclose(P[f.rho, f.rho], ARCMIN**2 * np.eye(3), rtol=1e-12)
    np.testing.assert_allclose(P[4:7, f.rho], ARCMIN**2 * np.eye(3), rtol=1e-12)
    G = np.zeros((3, f.n))
    G[:, 4:7] = np.eye(3)
    G[:, f.rho] = -np.eye(3)
    G[:, 7:10] = C_B_N
    tu = f.tuning
    mount = C_B_N @ np.diag([tu.p0_level, tu.p0_level, tu.p0_heading]) ** 2 @ C_B_N.T
    np.testing.assert_allclose(G @ P @ G.T, mount, rtol=1e-9, atol=1e-18)


def test_the_mounting_seen_by_the_state_turns_with_the_master() -> None:
    """Over a period, E(nu) = exp(-[rho x]) E(phi) exp([C_b_n theta x]) of every sigma
    point turns exactly as the true mounting does, E(nu1) = dC E(nu0) dC^T, whatever
    phi and theta do (degree-sized errors, a 2 deg turn of the master)."""
    f = started(2)
    c1 = euler_to_dcm(np.array([0.12, -0.03, 1.035])) @ rotvec_to_dcm(np.array([0, 0, 0.01]))
    f.turn_master(c1)  # as update() does before the prediction
    rng = np.random.default_rng(5)
    x = np.zeros((4, f.n))
    x[:, 4:7] = rng.normal(0.0, 2.0 * DEG, (4, 3))
    x[:, 7:10] = rng.normal(0.0, 3.0 * ARCMIN, (4, 3))
    x[:, f.rho] = rng.normal(0.0, 2.0 * DEG, (4, 3))
    for _ in range(10):  # a period of the slave's increments (turning, accelerating)
        f.step(np.array([1e-3, -2e-4, 1.7e-3]), np.array([0.02, 0.01, -0.098]), 0.01)
    sums, T, _ = f.close_period(c1, W_EB_B)
    out = f.transition(x, T, sums)

    def e_nu(xx: np.ndarray, c: np.ndarray) -> np.ndarray:
        return rotvec_to_dcm(xx[f.rho]).T @ euler_to_dcm(xx[4:7]) @ rotvec_to_dcm(c @ xx[7:10])

    for k in range(4):
        assert np.max(np.abs(out[k, 4:7] - x[k, 4:7])) > 1e-9  # phi moved
        dc = c1 @ C_B_N.T
        want = dc @ e_nu(x[k], C_B_N) @ dc.T
        np.testing.assert_allclose(e_nu(out[k], c1), want, rtol=0, atol=1e-13)


def test_the_feedback_turns_the_residual_with_its_exact_jacobian() -> None:
    """turned_residual: rho_new = rotvec(E(phi^)^T exp([rho x])), and its Jacobian (from
    the right Jacobians of SO(3)) equals central differences of that map to 1e-8, for
    residuals and corrections from arcminutes to half a radian."""
    rng = np.random.default_rng(3)
    for scale in (3.0 * ARCMIN, 3.0 * DEG, 0.5):
        turn = euler_to_dcm(rng.normal(0.0, scale, 3)).T
        rho = rng.normal(0.0, scale, 3)
        new, jac = turned_residual(turn, rho)
        np.testing.assert_allclose(rotvec_to_dcm(new), turn @ rotvec_to_dcm(rho), atol=1e-15)
        step = 1e-6
        fd = np.column_stack(
            [
                (turned_residual(turn, rho + d)[0] - turned_residual(turn, rho - d)[0])
                / (2.0 * step)
                for d in step * np.eye(3)
            ]
        )
        np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-8)


def test_lag_term_matches_a_delayed_master_to_first_order() -> None:
    """A master attitude tau old, C_b_n exp(-tau [w x]), is modelled by + tau C_b_n w; a
    velocity tau old by + tau a_n. Residual of the model: second order, below 2 % of the
    lag term here (tau 20 ms, |w| 0.04 rad/s, phi 0.2 deg)."""
    tau = 0.02
    f = started(2, lag=True)
    phi = np.array([0.1, -0.1, 0.2]) * DEG
    mu = np.array([0.5, -0.8, 1.5]) * DEG
    set_truth(f, phi, mu, np.zeros(3))
    c_late = C_B_N @ rotvec_to_dcm(-tau * W_EB_B)
    z = f.measured(c_late, W_EB_B, V_M)
    x = np.zeros(f.n)
    x[4:7] = phi
    x[f.rho] = rho_of(phi, mu, np.zeros(3))
    x[f.tau] = tau
    h = f.measurement_model(x, c_late, c_late @ W_EB_B, np.zeros(3))
    lag_term = tau * np.linalg.norm(W_EB_B)
    assert np.max(np.abs(z[3:] - h[3:])) < 0.02 * lag_term
    x[f.tau] = 0.0
    h0 = f.measurement_model(x, c_late, c_late @ W_EB_B, np.zeros(3))
    assert np.max(np.abs(z[3:] - h0[3:])) > 0.5 * lag_term  # the term is needed
    a_n = np.array([0.3, -0.1, 0.0])
    x[f.tau] = tau
    hv = f.measurement_model(x, c_late, c_late @ W_EB_B, a_n)[:3]
    np.testing.assert_allclose(hv - x[1:4], tau * a_n, rtol=1e-12)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"matching": 3}, "matching must be 0"),
        ({"estimate_lag": 2}, "estimate_lag must be 0 or 1"),
        ({"matching": 2, "p0_heading": 30.0 * DEG}, "p0_heading .* must be at most 10 deg"),
        ({"r_att": 0.0}, "r_att must be > 0"),
        ({"master_period": -0.1}, "master_period must be >= 0"),
    ],
)
def test_bad_parameters_are_named(params: dict, match: str) -> None:
    block = TransferAlignment()
    for name, value in params.items():
        setattr(block, name, value)
    block.setup_experiment(0.0)
    with pytest.raises(TransferConfigError, match=match):
        block.exit_initialization_mode()


def test_the_velocity_path_stays_compiled_and_unextended() -> None:
    """Defaults (matching 0, no lag, master every step) keep seed 001's compiled path."""
    block = TransferAlignment()
    block.setup_experiment(0.0)
    block.exit_initialization_mode()
    assert not block.extended
    assert type(block.estimator).__name__ == "TransferFilter"
    assert block.nis_dof == 3.0
    assert block.kernel_path == (1.0 if native.library() is not None else 0.0)
    block = TransferAlignment()
    block.matching = 2
    block.p0_heading = 3.0 * DEG
    block.setup_experiment(0.0)
    block.exit_initialization_mode()
    assert block.extended and block.kernel_path == 0.0 and block.nis_dof == 6.0


# ----------------------------------------------------------------------------- scenario runs
@pytest.fixture(scope="module")
def short_runs() -> dict[str, np.ndarray]:
    """Run 0 of the land-vehicle scenario to 30 s: velocity only; velocity+attitude with a
    20 ms master lag and the lag state; the same without the truth inputs."""
    lag = {"matching": 2, "estimate_lag": 1, "latency": 0.02}
    return {
        "velocity": vehicle_run(0, stop=30.0, matching=0),
        "both": vehicle_run(0, stop=30.0, **lag),
        "no_truth": vehicle_run(0, stop=30.0, truth=False, **lag),
    }


def test_attitude_matching_beats_velocity_matching_in_heading(short_runs: dict) -> None:
    """At 30 s the heading sigma with velocity+attitude matching is under half the
    velocity-only one (the attitude residual makes the z gyro bias observable), the
    errors are within 3 sigma, and the NIS has the measurement's dimension."""
    v, b = short_runs["velocity"][-1], short_runs["both"][-1]
    assert b["align.rpy_sigma[3]"] < 0.5 * v["align.rpy_sigma[3]"]
    for row in (v, b):
        for i in (1, 2, 3):
            assert abs(row[f"align.rpy_err[{i}]"]) < 3.0 * row[f"align.rpy_sigma[{i}]"]
    assert v["align.nis_dof"] == 3.0 and b["align.nis_dof"] == 6.0
    both = short_runs["both"]
    nis = both["align.nis"][both["time"] > 5.0]
    # the mean of 250 chi-square(6) values (sd 0.22 if independent; the motion correlates
    # them): 6 within a factor 1.5 either way; an r_att ten times off moves it 10-100 x
    assert 4.0 < float(np.mean(nis)) < 9.0


def test_a_20ms_lag_is_seen(short_runs: dict) -> None:
    """A 20 ms master lag is within 3 sigma of its estimate at 30 s, and the sigma is
    below 2 ms (the 100 s, 50-run figure is the slow test's)."""
    row = short_runs["both"][-1]
    assert abs(row["align.lag"] - 0.02) < 3.0 * row["align.lag_sigma"]
    assert row["align.lag_sigma"] < 0.002


def test_without_truth_inputs_the_estimates_and_sigmas_are_the_same(short_runs: dict) -> None:
    """Every truth input left out: the estimates (mounting, relative attitude, biases,
    lag) and their sigmas are those of the run with truth, bit for bit (truth only feeds
    rpy_err, rpy_sigma and nees); rel_rpy_sigma (from the master's reported attitude) is
    the truth run's rpy_sigma to the master's attitude noise, and the mounting estimate
    is within 3 mount_sigma of the true mounting."""
    a, b = short_runs["both"], short_runs["no_truth"]
    for name in ("mount", "mount_sigma", "rel_rpy", "rel_rpy_sigma", "gyro_drift", "accel_bias"):
        for i in (1, 2, 3):
            np.testing.assert_array_equal(a[f"align.{name}[{i}]"], b[f"align.{name}[{i}]"])
    np.testing.assert_array_equal(a["align.lag_sigma"], b["align.lag_sigma"])
    assert np.all(np.isfinite(b["align.nis"]))
    row, last = a[-1], b[-1]
    for i in (1, 2, 3):
        assert row[f"align.rel_rpy_sigma[{i}]"] == pytest.approx(
            row[f"align.rpy_sigma[{i}]"], rel=0.02
        )
        err = (last[f"align.mount[{i}]"] - np.radians(MOUNT_DEG[i - 1])) / ARCMIN
        assert abs(err) < 3.0 * last[f"align.mount_sigma[{i}]"]


def test_the_sigmas_are_consistent_from_the_first_seconds() -> None:
    """Ten runs of 20 s with velocity+attitude matching: the relative-attitude errors
    over the stated sigmas pass the campaign's own sigma check on every axis
    (:func:`cosim.verify.calibration.calibrate`: each window's mean of (e/sigma)^2 over
    the runs against the any-dependence band of chi2(10)/10, 1 % false alarm over the
    span; it flags a sigma too small by about 1.7x). The mounting as navigation-frame
    Euler angles in the state failed here: heading sigma about 5x too small from 1 s to
    5 s and 2x until 15 s (docs/transfer_alignment.md, "Consistency")."""
    runs = [vehicle_run(1000 + i, stop=20.0, matching=2) for i in range(10)]
    t = runs[0]["time"]
    for k in (1, 2, 3):
        e = np.array([r[f"align.rpy_err[{k}]"] for r in runs])
        s = np.array([r[f"align.rpy_sigma[{k}]"] for r in runs])
        verdict = calibrate(t, e, s)
        assert verdict["consistent"] is True, (k, verdict["message"])


# ----------------------------------------------------------------------------- acceptance 3
@pytest.fixture(scope="module")
def campaign() -> dict[str, list[dict]]:
    """50 runs of 100 s with velocity+attitude matching, 50 with velocity only."""
    return {
        "both": [final_figures(vehicle_run(i, matching=2)) for i in range(50)],
        "velocity": [final_figures(vehicle_run(i, matching=0)) for i in range(50)],
    }


def within_3_sigma(runs: list[dict], err: str, sigma: str) -> float:
    """Share of runs whose three axes of ``err`` are all within 3 ``sigma``."""
    return float(np.mean([np.all(np.abs(r[err]) <= 3.0 * r[sigma]) for r in runs]))


@pytest.mark.slow
def test_acceptance_3_heading_sigma_and_consistency_over_50_runs(campaign: dict) -> None:
    """Issue 26, acceptance 3: velocity+attitude matching gives heading sigma <= 3' at
    100 s against about 14' with velocity only; the estimate errors (relative attitude,
    accelerometer bias, gyro drift) are within 3 sigma in at least 95 % of the 50 runs.

    Theory: for a consistent filter each axis is within 3 sigma with probability 0.9973,
    all three with >= 0.992; 95 % of 50 runs (47) then fails with probability < 1e-2
    (binomial), while a sigma too small by 2 gives about 87 % per run (3 axes) and fails.
    """
    both, vel = campaign["both"], campaign["velocity"]
    hdg_both = np.mean([r["rpy_sigma"][2] for r in both])
    hdg_vel = np.mean([r["rpy_sigma"][2] for r in vel])
    assert hdg_both <= 3.0
    assert 10.0 <= hdg_vel <= 20.0
    for runs in (both, vel):
        assert within_3_sigma(runs, "rpy_err", "rpy_sigma") >= 0.95
        assert within_3_sigma(runs, "accel_err", "accel_sigma") >= 0.95
        assert within_3_sigma(runs, "gyro_err", "gyro_sigma") >= 0.95
    assert all(r["nis_dof"] == 6.0 for r in both)


@pytest.mark.slow
def test_acceptance_3_a_20ms_lag_is_recovered_within_2ms() -> None:
    """Issue 26, acceptance 3: a simulated 20 ms lag of the master's data is recovered
    within 2 ms at 100 s, in each of 10 runs, and within 3 of its own sigma."""
    for i in range(10):
        f = final_figures(vehicle_run(i, matching=2, estimate_lag=1, latency=0.02))
        assert abs(f["lag"] - 0.02) < 0.002
        assert abs(f["lag"] - 0.02) < 3.0 * f["lag_sigma"]
