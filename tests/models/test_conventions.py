"""Attitude conventions and rotation algebra: DCM, Euler, quaternion, rotation vector."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cosim.models import conventions as cv

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


def test_scalar_fast_paths_match_the_array_functions() -> None:
    for rpy in random_rpy(20):
        c = cv.euler_to_dcm(rpy)
        np.testing.assert_allclose(cv.euler_to_dcm_3(rpy), c, rtol=0, atol=1e-15)
        np.testing.assert_allclose(cv.dcm_to_euler_3(c), cv.dcm_to_euler(c), rtol=0, atol=1e-15)
        phi = 0.3 * rpy
        np.testing.assert_allclose(cv.rotvec_to_dcm_3(phi), cv.rotvec_to_dcm(phi), atol=1e-15)


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
