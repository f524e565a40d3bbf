"""LeverArm: rigid lever-arm terms, seed 001 eq. (11) with flexure, slave strapdown consistency."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_ship_motion import ARCSEC, Strapdown
from test_ship_motion import make as make_ship

from cosim.models import conventions as cv
from cosim.models.blocks.deck_flexure import DeckFlexure
from cosim.models.blocks.lever_arm import LeverArm
from cosim.models.constants import DEG

MASTER = ("omega_ib_b", "omega_dot_b", "f_b", "dtheta_b", "dv_b", "rpy", "v_n")
FLEX = ("theta", "theta_dot", "theta_ddot", "dtheta_flex", "dtheta_dot_flex")


def sk(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def mount_dcm(rpy: np.ndarray) -> np.ndarray:
    """C_s_d from [roll, pitch, yaw] via scipy (intrinsic Z-Y-X)."""
    return Rotation.from_euler("ZYX", np.asarray(rpy)[::-1]).as_matrix()


def make_lever(**params: object) -> LeverArm:
    m = LeverArm()
    for name, value in params.items():
        setattr(m, name, np.array(value, dtype=float) if isinstance(value, tuple) else value)
    return m


def set_constant_master(m: LeverArm, w, wd, f, h: float) -> None:
    """Master inputs of a motion with constant rate and specific force over the step."""
    m.omega_ib_b = np.array(w)
    m.omega_dot_b = np.array(wd)
    m.f_b = np.array(f)
    m.dtheta_b = np.array(w) * h
    m.dv_b = np.array(f) * h


def test_rigid_lever_arm_terms() -> None:
    # Flexure off: f_s = C_s_d^T (f + w x (w x r) + w' x r), omega_is_s = C_s_d^T w,
    # to 1e-9 relative (the arithmetic gives ~1e-16).
    rng = np.random.default_rng(2)
    r0 = np.array([10.0, 10.0, 5.0])
    mount = np.array([1.0, 1.0, 30.0]) * DEG
    c = mount_dcm(mount)
    m = make_lever(flexure=0)
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    h = 0.01
    for k in range(5):
        w, wd, f = (
            rng.standard_normal(3) * 0.2,
            rng.standard_normal(3) * 0.3,
            rng.standard_normal(3),
        )
        set_constant_master(m, w, wd, f, h)
        m.do_step(k * h, h)
        expect = c.T @ (f + np.cross(w, np.cross(w, r0)) + np.cross(wd, r0))
        np.testing.assert_allclose(m.f_s, expect, rtol=0, atol=1e-9 * np.linalg.norm(expect))
        np.testing.assert_allclose(m.omega_is_s, c.T @ w, rtol=0, atol=1e-15)
        np.testing.assert_allclose(m.dtheta_s, c.T @ (w * h), rtol=0, atol=1e-17)
        np.testing.assert_allclose(m.r_p, r0)


def test_rigid_increment_closed_form() -> None:
    # Constant w (w' = 0), constant f: dv_s = C^T (f + w x (w x r0)) h exactly.
    r0 = np.array([10.0, 10.0, 5.0])
    c = mount_dcm(np.array([1.0, 1.0, 30.0]) * DEG)
    w, f = np.array([0.1, -0.2, 0.05]), np.array([0.3, 0.1, -9.8])
    m = make_lever(flexure=0)
    set_constant_master(m, w, np.zeros(3), f, 0.02)
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    m.do_step(0.0, 0.02)
    expect = c.T @ (f + np.cross(w, np.cross(w, r0))) * 0.02
    np.testing.assert_allclose(m.dv_s, expect, rtol=0, atol=1e-15)


def test_attitude_and_velocity_outputs() -> None:
    r0 = np.array([10.0, 10.0, 5.0])
    m = make_lever(flexure=0)
    m.rpy = np.array([0.1, -0.05, 2.0])
    m.v_n = np.array([1.0, 2.0, 0.5])
    m.lat = 0.5
    m.omega_ib_b = np.array([0.01, 0.02, -0.03])
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    c_b_n = mount_dcm(np.array([0.1, -0.05, 2.0]))
    c_s_n = c_b_n @ mount_dcm(np.array([1.0, 1.0, 30.0]) * DEG)
    ref = Rotation.from_matrix(c_s_n).as_euler("ZYX")[::-1]
    np.testing.assert_allclose(m.rpy_s, ref, atol=1e-14)
    w_ie_n = 7.292115e-5 * np.array([math.cos(0.5), 0.0, -math.sin(0.5)])
    w_eb = m.omega_ib_b - c_b_n.T @ w_ie_n
    np.testing.assert_allclose(m.v_n_s, m.v_n + c_b_n @ np.cross(w_eb, r0), atol=1e-14)


def test_flexure_terms_match_eq11() -> None:
    """Slave specific force vs an independent evaluation of seed 001 eq. (11).

    eq. (11): a = w x (w x r0) + w' x r0 + ([w x][w x] + [w' x]) R0 theta - R2 theta
                  + (2 [w x] R0 - R1) theta' + R0 eta
    with R1 = R0 x 2 beta_(y, z, x) and R2 = R0 x beta^2_(y, z, x) entrywise, eta the
    DeckFlexure's step-mean noise. f_s = C_s_b^T (f_b + a), C_s_b = exp([theta x]) C_s_d.
    Tolerance 1e-9 relative to |a| (arithmetic differences only).
    """
    tau = np.array([30.0, 45.0, 60.0])
    beta = 2.146 / tau
    x0, y0, z0 = r0 = np.array([10.0, 10.0, 5.0])
    R0 = np.array([[0, z0, 0], [0, 0, x0], [y0, 0, 0]], dtype=float)
    R1 = np.array([[0, 2 * z0 * beta[1], 0], [0, 0, 2 * x0 * beta[2]], [2 * y0 * beta[0], 0, 0]])
    R2 = np.array([[0, z0 * beta[1] ** 2, 0], [0, 0, x0 * beta[2] ** 2], [y0 * beta[0] ** 2, 0, 0]])
    flex = DeckFlexure()
    flex.tau = tau
    flex.sigma = np.array([0.5, 1.0, 1.5]) * DEG
    flex.seed = 9
    flex.setup_experiment(0.0)
    flex.exit_initialization_mode()
    m = make_lever(flexure=1)
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    c_s_d = mount_dcm(np.array([1.0, 1.0, 30.0]) * DEG)
    rng = np.random.default_rng(5)
    h = 0.05
    for k in range(20):
        flex.do_step(k * h, h)
        w, wd, f = (
            rng.standard_normal(3) * 0.2,
            rng.standard_normal(3) * 0.3,
            rng.standard_normal(3),
        )
        set_constant_master(m, w, wd, f, h)
        for name in FLEX:
            setattr(m, name, getattr(flex, name).copy())
        m.do_step(k * h, h)
        th, thd, eta = flex.theta, flex.theta_dot, flex.eta
        a = (
            np.cross(w, np.cross(w, r0))
            + np.cross(wd, r0)
            + (sk(w) @ sk(w) + sk(wd)) @ R0 @ th
            - R2 @ th
            + (2 * sk(w) @ R0 - R1) @ thd
            + R0 @ eta
        )
        c_s_b = Rotation.from_rotvec(th).as_matrix() @ c_s_d
        np.testing.assert_allclose(c_s_b @ m.f_s - f, a, rtol=0, atol=1e-9 * np.linalg.norm(a))
        np.testing.assert_allclose(m.r_p, r0 + R0 @ th, atol=1e-14)
        # Slave rate: C_s_d^T (C_d_b^T w + J_r(theta) theta'); J_r by a central difference of
        # the flexure DCM along theta' (independent of the model's closed form), error ~1e-12.
        dt = 1e-5
        cp = Rotation.from_rotvec(th + thd * dt).as_matrix()
        cm = Rotation.from_rotvec(th - thd * dt).as_matrix()
        c0 = Rotation.from_rotvec(th).as_matrix()
        wx = c0.T @ (cp - cm) / (2 * dt)
        w_flex = np.array([wx[2, 1], wx[0, 2], wx[1, 0]])
        np.testing.assert_allclose(m.omega_is_s, c_s_d.T @ (c0.T @ w + w_flex), atol=1e-11)


def test_flexure_increment_of_the_noise_term() -> None:
    # Master at rest (w = 0, f = 0): dv_s = integral C_s_b^T R0 theta'' dt. With the Hermite
    # path theta moves by ~1e-4 rad over the step, so C_s_b is constant to 1e-4 and the
    # integral is C_s_b(mid)^T R0 dtheta_dot_flex to ~1e-4 relative.
    flex = DeckFlexure()
    flex.tau = np.array([20.0, 20.0, 20.0])
    flex.sigma = np.array([1.0, 1.0, 1.0]) * DEG
    flex.setup_experiment(0.0)
    flex.exit_initialization_mode()
    m = make_lever()
    for name in FLEX:
        setattr(m, name, getattr(flex, name).copy())
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    h = 0.1
    flex.do_step(0.0, h)
    for name in FLEX:
        setattr(m, name, getattr(flex, name).copy())
    m.do_step(0.0, h)
    R0 = np.array([[0, 5.0, 0], [0, 0, 10.0], [10.0, 0, 0]])
    c_s_d = mount_dcm(np.array([1.0, 1.0, 30.0]) * DEG)
    th_mid = flex.theta - 0.5 * flex.dtheta_flex
    c_s_b = Rotation.from_rotvec(th_mid).as_matrix() @ c_s_d
    expect = c_s_b.T @ R0 @ flex.dtheta_dot_flex
    np.testing.assert_allclose(m.dv_s, expect, rtol=0, atol=1e-3 * np.linalg.norm(expect))


def test_slave_strapdown_consistency() -> None:
    """Ship + exaggerated flexure + lever arm: slave increments navigate to the slave truth.

    The reference navigator (test_ship_motion) runs in the master's NED frame (transport
    rate from the master velocity, gravity at the master: the truth's uniform-gravity
    assumption). Theory for the residual over 60 s: algorithm truncation < 1e-3" and
    ~1e-6 m/s, plus the centrifugal difference Omega^2 |r| t = 5e-6 m/s neglected by the
    uniform gravity of eq. (2); bounds 0.01" and 2e-5 m/s. Omitting any term of f_p
    (e.g. 2 w x r', ~1e-3 m/s2 here: 4e-3 m/s) or the flexure rate in omega_is_s (~1000")
    fails them.
    """
    ship = make_ship(lin_amp=(0.5, 1.0, 1.5), lin_period=(9.0, 11.0, 7.0))
    flex = DeckFlexure()
    flex.tau = np.array([30.0, 40.0, 50.0])
    flex.sigma = np.array([0.1, 0.2, 0.3]) * DEG
    flex.seed = 21
    flex.setup_experiment(0.0)
    flex.exit_initialization_mode()
    lever = LeverArm()

    def connect() -> None:
        for name in MASTER:
            setattr(lever, name, getattr(ship, name).copy())
        lever.lat = ship.lat
        for name in FLEX:
            setattr(lever, name, getattr(flex, name).copy())

    connect()
    lever.setup_experiment(0.0)
    lever.exit_initialization_mode()
    nav = Strapdown(lever.rpy_s, lever.v_n_s, ship.lat, ship.lon, ship.h)
    h = 0.01
    worst_att = worst_vel = 0.0
    for k in range(6000):
        before = (ship.v_n.copy(), ship.lat, ship.h)
        ship.do_step(k * h, h)
        flex.do_step(k * h, h)
        connect()
        lever.do_step(k * h, h)
        frame = (
            0.5 * (before[0] + ship.v_n),
            0.5 * (before[1] + ship.lat),
            0.5 * (before[2] + ship.h),
        )
        nav.update(lever.dtheta_s, lever.dv_s, h, frame)
        c_err = cv.euler_to_dcm(lever.rpy_s).T @ cv.quat_to_dcm(np.array(nav.q))
        worst_att = max(worst_att, np.max(np.abs(cv.dcm_to_rotvec(c_err))))
        worst_vel = max(worst_vel, np.max(np.abs(np.subtract(nav.v, lever.v_n_s))))
    assert worst_att < 0.01 * ARCSEC
    assert worst_vel < 2e-5


def test_defaults_and_bad_flag() -> None:
    m = LeverArm()
    np.testing.assert_allclose(m.r0, [10.0, 10.0, 5.0])
    np.testing.assert_allclose(m.mount_rpy, np.array([1.0, 1.0, 30.0]) * DEG)
    m.flexure = 2
    m.setup_experiment(0.0)
    with pytest.raises(ValueError, match="flexure"):
        m.exit_initialization_mode()
