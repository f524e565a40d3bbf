"""Frames and attitude conventions: DCM, Euler, quaternion, rotation vector, ENU/NED."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from models import conventions as cv

RNG = np.random.default_rng(20240611)


def random_rpy(n: int) -> np.ndarray:
    """Euler angles away from the pitch singularity."""
    return np.column_stack(
        [RNG.uniform(-np.pi, np.pi, n), RNG.uniform(-1.4, 1.4, n), RNG.uniform(-np.pi, np.pi, n)]
    )


def test_skew_and_cross() -> None:
    a, b = RNG.standard_normal((2, 5, 3))
    np.testing.assert_allclose(cv.skew(a) @ b[..., None], np.cross(a, b)[..., None], atol=1e-15)
    np.testing.assert_allclose(cv.cross(a, b), np.cross(a, b), atol=1e-15)
    np.testing.assert_allclose(cv.skew(a[0]), -cv.skew(a[0]).T)


def test_euler_dcm_matches_scipy_intrinsic_zyx() -> None:
    # Independent reference: scipy's intrinsic Z-Y-X (yaw, pitch, roll) rotation matrix.
    rpy = random_rpy(50)
    ref = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    np.testing.assert_allclose(cv.euler_to_dcm(rpy), ref, atol=1e-14)
    np.testing.assert_allclose(cv.dcm_to_euler(ref), rpy, atol=1e-12)


def test_euler_meaning() -> None:
    # Yaw 90 deg: body x (forward) points east. Pitch +10 deg: nose up (x has -D component).
    c = cv.euler_to_dcm([0.0, 0.0, math.pi / 2])
    np.testing.assert_allclose(c @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    c = cv.euler_to_dcm([0.0, math.radians(10), 0.0])
    assert (c @ [1, 0, 0])[2] < 0
    # Roll +: right wing (body y) goes down (+D).
    c = cv.euler_to_dcm([math.radians(10), 0.0, 0.0])
    assert (c @ [0, 1, 0])[2] > 0


def test_quaternion_round_trip_and_product() -> None:
    rpy = random_rpy(40)
    c = cv.euler_to_dcm(rpy)
    q = cv.dcm_to_quat(c)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(cv.quat_to_dcm(q), c, atol=1e-14)
    # scipy is scalar-last; same rotation (up to sign)
    ref = Rotation.from_matrix(c).as_quat()[:, [3, 0, 1, 2]]
    ref *= np.sign(ref[:, :1])
    np.testing.assert_allclose(q, ref, atol=1e-14)
    # q_c_n = q_b_n (x) q_c_b  <=>  C_c_n = C_b_n C_c_b
    c2 = cv.euler_to_dcm(random_rpy(40))
    prod = cv.quat_multiply(q, cv.dcm_to_quat(c2))
    np.testing.assert_allclose(cv.quat_to_dcm(prod), c @ c2, atol=1e-14)
    np.testing.assert_allclose(
        cv.quat_multiply(q, cv.quat_conjugate(q)), np.tile([1, 0, 0, 0], (40, 1)), atol=1e-15
    )
    np.testing.assert_allclose(cv.quat_normalize(3.0 * q), q, atol=1e-15)
    np.testing.assert_allclose(cv.quat_to_euler(cv.euler_to_quat(rpy)), rpy, atol=1e-12)


def test_dcm_to_quat_near_pi_rotations() -> None:
    # Shepperd's branch choice: rotations by ~pi about each axis.
    for axis in np.eye(3):
        c = cv.rotvec_to_dcm((math.pi - 1e-9) * axis)
        np.testing.assert_allclose(cv.quat_to_dcm(cv.dcm_to_quat(c)), c, atol=1e-14)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1e-3, 0.5, 3.0])
def test_rotation_vector_exponential_exact(angle: float) -> None:
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    phi = angle * axis
    ref = Rotation.from_rotvec(phi).as_matrix()
    np.testing.assert_allclose(cv.rotvec_to_dcm(phi), ref, atol=2e-16 * 8)
    np.testing.assert_allclose(cv.quat_to_dcm(cv.rotvec_to_quat(phi)), ref, atol=2e-15)
    np.testing.assert_allclose(cv.dcm_to_rotvec(ref), phi, atol=1e-15 + 1e-14 * angle)


def test_body_update_convention() -> None:
    # C_b(k+1)_n = C_b(k)_n exp([phi x]): a body yaw rotation by phi about body z adds phi to yaw.
    c0 = cv.euler_to_dcm([0.0, 0.0, 0.3])
    c1 = c0 @ cv.rotvec_to_dcm([0.0, 0.0, 0.2])
    np.testing.assert_allclose(cv.dcm_to_euler(c1), [0.0, 0.0, 0.5], atol=1e-15)


def test_euler_rates_to_body_rate_by_finite_difference() -> None:
    # [omega x] = C^T dC/dt; central difference over 1e-6 s: error ~1e-12 x rate^3.
    rpy = random_rpy(10)
    rpy_dot = RNG.standard_normal((10, 3))
    rpy_ddot = RNG.standard_normal((10, 3))
    dt = 1e-6
    c0 = cv.euler_to_dcm(rpy)
    cdot = (cv.euler_to_dcm(rpy + rpy_dot * dt) - cv.euler_to_dcm(rpy - rpy_dot * dt)) / (2 * dt)
    wx = np.swapaxes(c0, -1, -2) @ cdot
    w_fd = np.stack([wx[:, 2, 1], wx[:, 0, 2], wx[:, 1, 0]], axis=-1)
    np.testing.assert_allclose(cv.euler_rate_to_body_rate(rpy, rpy_dot), w_fd, atol=1e-8)

    # derivative of omega_nb_b along the path rpy(t) = rpy + rpy_dot t + rpy_ddot t^2 / 2
    def w_at(t: float) -> np.ndarray:
        return cv.euler_rate_to_body_rate(
            rpy + rpy_dot * t + 0.5 * rpy_ddot * t * t, rpy_dot + rpy_ddot * t
        )

    wd_fd = (w_at(1e-5) - w_at(-1e-5)) / 2e-5
    np.testing.assert_allclose(
        cv.euler_accel_to_body_accel(rpy, rpy_dot, rpy_ddot), wd_fd, atol=1e-8
    )


def test_right_jacobian() -> None:
    # exp([phi(t) x]): C^T dC/dt = [(J_r phi') x], checked by central differences.
    for scale in (1e-5, 0.3, 2.0):
        phi = scale * np.array([0.6, -0.3, 0.7])
        phid = np.array([0.2, 0.5, -0.4])
        dt = 1e-6
        c0 = cv.rotvec_to_dcm(phi)
        cdot = (cv.rotvec_to_dcm(phi + phid * dt) - cv.rotvec_to_dcm(phi - phid * dt)) / (2 * dt)
        wx = c0.T @ cdot
        w = np.array([wx[2, 1], wx[0, 2], wx[1, 0]])
        np.testing.assert_allclose(cv.so3_right_jacobian(phi) @ phid, w, atol=1e-9)


def test_enu_ned_conversion() -> None:
    v = RNG.standard_normal(3)
    np.testing.assert_allclose(cv.enu_to_ned(v), [v[1], v[0], -v[2]])
    np.testing.assert_allclose(cv.ned_to_enu(cv.enu_to_ned(v)), v)
    np.testing.assert_allclose(cv.T_NED_ENU @ cv.T_NED_ENU, np.eye(3))
    # Earth rate: ENU [0, W cosL, W sinL] is NED [W cosL, 0, -W sinL].
    lat = 0.5
    np.testing.assert_allclose(
        cv.enu_to_ned([0.0, math.cos(lat), math.sin(lat)]), [math.cos(lat), 0.0, -math.sin(lat)]
    )


def test_seed001_euler_conversion() -> None:
    # Build the ENU/RFU attitude from its own definition: heading psi about up (ccw),
    # then pitch about the right axis (x_rfu), then roll about the forward axis (y_rfu).
    pitch, roll, psi = 0.1, -0.2, 0.7
    c_rfu_enu = cv.rot_z(psi) @ cv.rot_x(pitch) @ cv.rot_y(roll)
    rpy = cv.enu_euler_to_rpy(pitch, roll, psi)
    np.testing.assert_allclose(cv.dcm_enu_to_ned(c_rfu_enu), cv.euler_to_dcm(rpy), atol=1e-15)
    np.testing.assert_allclose(cv.dcm_ned_to_enu(cv.euler_to_dcm(rpy)), c_rfu_enu, atol=1e-15)
    back = cv.rpy_to_enu_euler(rpy)
    np.testing.assert_allclose(back, (pitch, roll, psi))
    # body vectors: RFU forward [0, 1, 0] is FRD [1, 0, 0]
    np.testing.assert_allclose(cv.rfu_to_frd([0.0, 1.0, 0.0]), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(cv.frd_to_rfu([0.0, 0.0, 1.0]), [0.0, 0.0, -1.0])


def test_substeps_and_simpson() -> None:
    assert cv.substeps(0.01, 1e-3) == 10
    assert cv.substeps(0.0105, 1e-3) == 10  # round, not floor/ceil of accumulated time
    assert cv.substeps(1e-4, 1e-3) == 1
    s, w = cv.simpson_nodes(5)
    assert s.shape == (11,) and s[0] == 0.0 and s[-1] == 1.0
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    # exact for cubics
    assert w @ (s**3) == pytest.approx(0.25, abs=1e-15)


def test_step_paths_are_exact_for_their_degree() -> None:
    h = 0.02
    s = np.linspace(0.0, 1.0, 7)
    tt = h * s
    a, b, c = RNG.standard_normal((3, 3))
    # quadratic x = a + b t + c t^2 on [0, h]
    x = a + b * tt[:, None] + c * tt[:, None] ** 2
    inc = a * h + b * h**2 / 2 + c * h**3 / 3
    xq, xqd = cv.step_quadratic(x[-1], b + 2 * c * h, inc, h, s)
    np.testing.assert_allclose(xq, x, atol=1e-13)
    np.testing.assert_allclose(xqd, b + 2 * c * tt[:, None], atol=1e-11)
    # linear
    xl = a + b * tt[:, None]
    yl, yld = cv.step_linear(xl[-1], a * h + b * h**2 / 2, h, s)
    np.testing.assert_allclose(yl, xl, atol=1e-14)
    np.testing.assert_allclose(yld, np.tile(b, (7, 1)), atol=1e-11)
    # Hermite: exact for cubics; derivative integrals exact
    d = RNG.standard_normal(3)
    xc = a + b * tt[:, None] + c * tt[:, None] ** 2 + d * tt[:, None] ** 3
    xcd = b + 2 * c * tt[:, None] + 3 * d * tt[:, None] ** 2
    xh, xhd, xhdd = cv.step_hermite(xc[0], xcd[0], xc[-1], xcd[-1], h, s)
    np.testing.assert_allclose(xh, xc, atol=1e-14)
    np.testing.assert_allclose(xhd, xcd, atol=1e-12)
    np.testing.assert_allclose(xhdd, 2 * c + 6 * d * tt[:, None], atol=1e-9)


def test_step_path_memory_quartic_and_fallback() -> None:
    h = 0.05
    s = np.linspace(0.0, 1.0, 5)
    coef = RNG.standard_normal((5, 3))  # quartic x(t) = sum coef_k t^k

    def x(t: float) -> np.ndarray:
        return sum(coef[k] * t**k for k in range(5))

    def xd(t: float) -> np.ndarray:
        return sum(k * coef[k] * t ** (k - 1) for k in range(1, 5))

    def integral(t0: float, t1: float) -> np.ndarray:
        return sum(coef[k] * (t1 ** (k + 1) - t0 ** (k + 1)) / (k + 1) for k in range(5))

    path = cv.StepPath()
    path.reset(0.0, x(0.0), xd(0.0))
    t = 0.0
    vals, ders = path.nodes(t, h, x(h), integral(0.0, h), s, xd(h))
    np.testing.assert_allclose(vals, np.array([x(h * u) for u in s]), atol=1e-13)
    np.testing.assert_allclose(ders, np.array([xd(h * u) for u in s]), atol=1e-11)
    # A start value inconsistent with the increment (not forwarded: zero) -> memoryless quadratic,
    # which matches the end value, end rate and the increment.
    bad = cv.StepPath()
    bad.reset(0.0, np.zeros(3) + 100.0, np.zeros(3))
    vals, ders = bad.nodes(0.0, h, x(h), integral(0.0, h), s, xd(h))
    np.testing.assert_allclose(vals[-1], x(h), atol=1e-14)
    np.testing.assert_allclose(ders[-1], xd(h), atol=1e-12)
    w = np.array([1, 4, 2, 4, 1]) / 12.0
    np.testing.assert_allclose(h * (w @ vals), integral(0.0, h), atol=1e-14)
