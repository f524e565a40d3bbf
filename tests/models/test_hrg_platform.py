"""HrgPlatform: exact gimballed-platform kinematics against the linearised eq. (5) of seed 000."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from cosim.blocks import FmuHost, InProcessHost
from cosim.interop.references import drive
from cosim.models.blocks.hrg_platform import HrgPlatform, indexing_profile, split_attitude
from cosim.models.constants import ARCMIN, DEG, OMEGA_IE
from cosim.models.conventions import rot_z, rotvec_to_dcm

DEG_H = math.pi / 180.0 / 3600.0


def make(**params: object) -> HrgPlatform:
    p = HrgPlatform()
    for name, value in params.items():
        if isinstance(value, (tuple, list, np.ndarray)):
            value = np.asarray(value, dtype=float)
        setattr(p, name, value)
    p.setup_experiment(0.0)
    p.exit_initialization_mode()
    return p


def linear_tilt(lat: float, a: float, eps: np.ndarray, theta0: np.ndarray, t: float) -> np.ndarray:
    """Eq. (5) linearised in the tilts, full azimuth matrix, solved with a matrix exponential.

    theta_E' = Os theta_N + d_E, theta_N' = -Os theta_E - Oc + d_N, d = -Rz(A) eps.
    """
    os_, oc = OMEGA_IE * math.sin(lat), OMEGA_IE * math.cos(lat)
    d = -(rot_z(a)[:2, :2] @ eps[:2])
    m = np.zeros((3, 3))
    m[0, 1], m[1, 0] = os_, -os_
    m[0, 2], m[1, 2] = d[0], d[1] - oc
    return (expm(m * t) @ np.array([theta0[0], theta0[1], 1.0]))[:2]


@pytest.mark.parametrize(
    "theta_e, theta_n, a",
    [(3 * ARCMIN, 3 * ARCMIN, 100 * DEG), (-0.2, 0.5, -2.0), (1e-9, -2e-9, 3.1), (0.0, 0.0, 0.3)],
)
def test_split_attitude_inverts_the_tilt_azimuth_product(
    theta_e: float, theta_n: float, a: float
) -> None:
    c = rotvec_to_dcm(np.array([theta_e, theta_n, 0.0])) @ rot_z(a)
    e, n, az = split_attitude(c)
    assert e == pytest.approx(theta_e, abs=1e-14)
    assert n == pytest.approx(theta_n, abs=1e-14)
    assert az == pytest.approx(a, abs=1e-14)


def test_initial_outputs_are_gravity_in_platform_axes() -> None:
    p = make(azimuth0=100 * DEG, theta_E0=3 * ARCMIN, theta_N0=-2 * ARCMIN)
    assert p.azimuth == pytest.approx(100 * DEG, abs=1e-15)
    assert (p.theta_E, p.theta_N) == pytest.approx((3 * ARCMIN, -2 * ARCMIN), abs=1e-15)
    assert np.linalg.norm(p.f_p) == pytest.approx(p.g, rel=1e-15)
    # linearised: f_x = g (sin A theta_E - cos A theta_N), f_y = g (cos A theta_E + sin A theta_N);
    # the neglected terms are second order, g |theta|^2 / 2 < 1e-5 m/s2 for 3.6'
    c, s = math.cos(p.azimuth0), math.sin(p.azimuth0)
    fx = p.g * (s * p.theta_E0 - c * p.theta_N0)
    fy = p.g * (c * p.theta_E0 + s * p.theta_N0)
    assert np.allclose(p.f_p[:2], [fx, fy], rtol=0, atol=p.g * (5 * ARCMIN) ** 2)
    assert p.position == 1.0
    assert p.omega_ip_p == pytest.approx([0.0, 0.0, OMEGA_IE * math.sin(p.lat)], abs=1e-20)


@pytest.mark.parametrize(
    "a0, eps_deg_h",
    [(100.0, (0.0, 0.0, 0.0)), (100.0, (0.1, 0.2, 0.2)), (-120.0, (0.3, -0.2, 0.1))],
)
def test_free_platform_follows_linearised_equation_5(a0: float, eps_deg_h: tuple) -> None:
    eps = np.array(eps_deg_h) * DEG_H
    p = make(azimuth0=a0 * DEG, index_time=-1.0, omega_err_p=eps)
    theta0 = np.array([p.theta_E0, p.theta_N0])
    h = 0.1
    for n in range(4000):
        p.do_step(n * h, h)
        if (n + 1) % 500:
            continue
        t = (n + 1) * h
        ref = linear_tilt(p.lat, p.azimuth0, eps, theta0, t)
        size = float(np.hypot(*ref))
        # Exact kinematics minus the tilt-linearised ones: second order in the tilt, so
        # below |theta|^2 / 2 (1.2e-4 rad at 68'). A first-order slip (a sign, a missing
        # azimuth rotation of the drift) would be of order |theta| or Oc t ~ 2e-2 rad.
        err = np.array([p.theta_E, p.theta_N]) - ref
        assert np.max(np.abs(err)) <= 0.5 * size**2, (t, err)
        # azimuth: A' = -eps_z plus the second-order z part of the rotation-vector
        # kinematics, (1/2) theta_E Oc (2e-8 rad/s for 3'): bounded by |theta| Oc t
        oc_t = OMEGA_IE * math.cos(p.lat) * t
        assert abs(p.azimuth - p.azimuth0 + eps[2] * t) <= max(size, 3 * ARCMIN) * oc_t
    # after 400 s the free level axes have tilted by Oc t = 70' about north
    assert p.theta_N == pytest.approx(
        3 * ARCMIN - OMEGA_IE * math.cos(p.lat) * 400.0 + 0.0, abs=3 * ARCMIN
    )


def test_drift_rate_output_is_the_gyro_error_rotated_into_enu() -> None:
    eps = np.array([0.1, 0.2, 0.2]) * DEG_H
    p = make(azimuth0=100 * DEG, index_time=-1.0, omega_err_p=eps)
    p.do_step(0.0, 1.0)
    a = p.azimuth
    expected = -(rotvec_to_dcm(np.array([p.theta_E, p.theta_N, 0.0])) @ rot_z(a) @ eps)
    assert np.allclose(p.drift_rate_n, expected, rtol=0, atol=1e-20)
    # level part: d = -Rz(A) eps to first order in the tilt (3.6' -> 1e-3 relative)
    d = -(rot_z(a)[:2, :2] @ eps[:2])
    assert np.allclose(p.drift_rate_n[:2], d, rtol=0, atol=2e-3 * np.linalg.norm(eps))


def test_indexing_profile_is_trapezoidal_within_the_limits() -> None:
    rate, accel = 10 * DEG, 10 * DEG
    _, _, duration = indexing_profile(0.0, 90 * DEG, rate, accel)
    assert duration == pytest.approx(10.0, rel=1e-14)  # 1 s up, 8 s at 10 deg/s, 1 s down
    taus = np.linspace(-1.0, 11.0, 1201)
    prof = np.array([indexing_profile(t, 90 * DEG, rate, accel)[:2] for t in taus])
    assert prof[0, 0] == 0.0 and prof[-1, 0] == pytest.approx(90 * DEG, abs=1e-15)
    assert np.all(np.abs(prof[:, 1]) <= rate * (1 + 1e-14))
    # the angle is the integral of the rate (trapezoid rule on a 10 ms grid: error ~ a dt^2)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (prof[1:, 1] + prof[:-1, 1]) * 0.01)])
    assert np.allclose(prof[:, 0], integral, atol=accel * 0.01**2)
    # short moves are triangular; negative moves are mirrored
    a, _, dur = indexing_profile(0.3, -2 * DEG, rate, accel)
    assert dur == pytest.approx(2.0 * math.sqrt(2.0 / 10.0), rel=1e-14)
    assert a == pytest.approx(-0.5 * accel * 0.09, rel=1e-14)  # still accelerating (0.45 s)


def test_indexing_turns_the_azimuth_and_leaves_the_tilt() -> None:
    # Turning about the platform's own z axis cannot move that axis: the tilt of an
    # indexing platform equals that of one that does not index (no drifts), to round-off.
    error = 5 * ARCMIN
    moving = make(index_time=20.0, index_error=error)
    still = make(index_time=-1.0)
    h = 0.1
    statuses = []
    for n in range(400):
        moving.do_step(n * h, h)
        still.do_step(n * h, h)
        statuses.append(moving.position)
        assert moving.theta_E == pytest.approx(still.theta_E, abs=1e-13)
        assert moving.theta_N == pytest.approx(still.theta_N, abs=1e-13)
        assert abs(moving.omega_ip_p[2] - still.omega_ip_p[2]) <= 10 * DEG * (1 + 1e-12)
    turned = math.remainder(moving.azimuth - still.azimuth, 2 * math.pi)
    assert turned == pytest.approx(90 * DEG + error, abs=1e-12)
    t = (np.arange(400) + 1) * h
    s = np.array(statuses)
    assert np.all(s[t <= 20.0 + 1e-9] == 1.0)
    assert np.all(s[(t > 20.0 + 1e-9) & (t < 30.0 + 0.05 * error / (10 * DEG))] == 0.0)
    assert np.all(s[t >= 30.1] == 2.0)


def test_settle_time_delays_position_2() -> None:
    p = make(index_time=1.0, index_rate=90 * DEG, index_accel=360 * DEG, settle_time=0.5)
    # move: 0.25 s up, 0.75 s at 90 deg/s, 0.25 s down = 1.25 s; status 2 from 2.75 s
    assert p.status(2.74) == 0.0
    assert p.status(2.75) == 2.0
    assert p.status(1.0) == 1.0


@pytest.mark.parametrize(
    "params, match",
    [
        ({"g": 0.0}, "g must be > 0"),
        ({"index_rate": 0.0}, "index_rate and index_accel"),
        ({"settle_time": -1.0}, "settle_time"),
    ],
)
def test_bad_parameters_raise_value_errors(params: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make(**params)


def test_fmu_equals_in_process_through_an_indexing_move(fmu_dir: Path) -> None:
    params = {"index_time": 0.5, "index_rate": 90 * DEG, "index_accel": 360 * DEG}

    def run(host: InProcessHost | FmuHost) -> np.ndarray:
        host.setup(0.0, params)
        host.exit_init()
        outs = [v for v in host.by_causality("output") if v.type == "Real"]
        rows = [host.get_real([v.vr for v in outs])]
        for n in range(200):
            host.set_real([host.variables[f"omega_err_p[{k}]"].vr for k in (1, 2, 3)], [1e-6] * 3)
            host.do_step(n * 0.01, 0.01)
            rows.append(host.get_real([v.vr for v in outs]))
        host.terminate()
        return np.array(rows)

    a = run(InProcessHost("p", HrgPlatform))
    b = run(FmuHost("p", fmu_dir / "HrgPlatform.fmu"))
    assert a.shape == b.shape == (201, 13)
    assert np.max(np.abs(a - b)) <= 1e-12
    # and it really indexed (1.25 s move from 0.5 s, over by 2 s): 90 deg less the
    # z gyro error of 1e-6 rad/s over 2 s, up to the second-order azimuth terms
    # (1/2) |theta| Oc t ~ 1e-7 rad
    az = a[:, 3]
    assert math.remainder(az[-1] - az[0], 2 * math.pi) == pytest.approx(90 * DEG - 2e-6, abs=2e-7)


def test_reference_drive_runs_standalone() -> None:
    data = drive(InProcessHost("p", HrgPlatform), 100, HrgPlatform.default_step)
    assert all(np.all(np.isfinite(data[n])) for n in data.dtype.names)
