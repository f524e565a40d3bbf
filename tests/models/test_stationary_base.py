"""StationaryBase: perfect static readings, sway and jitter consistency, seeding."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_ship_motion import ARCSEC, Strapdown

from cosim.models import constants, earth
from cosim.models import conventions as cv
from cosim.models.blocks.stationary_base import StationaryBase
from cosim.models.constants import DEG


def make(**params: object) -> StationaryBase:
    m = StationaryBase()
    for name, value in params.items():
        setattr(m, name, np.array(value, dtype=float) if isinstance(value, tuple) else value)
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    return m


@pytest.mark.parametrize("lat_deg", [0.0, 30.0, 45.0, 89.0])
def test_perfect_readings(lat_deg: float) -> None:
    rpy = np.array([2.0, -3.0, 130.0]) * DEG
    lat = lat_deg * DEG
    m = make(rpy0=tuple(rpy), lat0=lat, h0=120.0)
    c_b_n = cv.euler_to_dcm(rpy)
    f_ref = c_b_n.T @ np.array([0.0, 0.0, -earth.gravity(lat, 120.0)])
    w_ref = c_b_n.T @ (constants.OMEGA_IE * np.array([math.cos(lat), 0.0, -math.sin(lat)]))
    h = 0.01
    for k in range(5):
        m.do_step(k * h, h)
        # 1e-9 relative (the brief's bound; the arithmetic gives ~1e-16)
        np.testing.assert_allclose(m.f_b, f_ref, rtol=0, atol=1e-9 * np.linalg.norm(f_ref))
        np.testing.assert_allclose(m.omega_ib_b, w_ref, rtol=0, atol=1e-9 * np.linalg.norm(w_ref))
        np.testing.assert_allclose(m.dv_b, f_ref * h, rtol=0, atol=1e-9 * np.linalg.norm(f_ref) * h)
        np.testing.assert_allclose(
            m.dtheta_b, w_ref * h, rtol=0, atol=1e-9 * np.linalg.norm(w_ref) * h
        )
        np.testing.assert_allclose(m.rpy, rpy, atol=1e-15)
        np.testing.assert_allclose(m.v_n, 0.0)
        np.testing.assert_allclose(m.omega_dot_b, 0.0, atol=1e-20)
        assert (m.lat, m.lon, m.h) == (lat, 0.0, 120.0)


def test_sway_closed_form_and_strapdown_consistency() -> None:
    # Sinusoidal angular and linear sway; the reference navigator (see test_ship_motion)
    # integrates the increments for 60 s: attitude < 0.01", velocity < 1e-5 m/s
    # (algorithm truncation ~1e-4" / 1e-7 m/s at these rates).
    params = dict(
        rpy0=(0.01, -0.02, 1.0),
        sway_amp=(0.5 * DEG, 0.3 * DEG, 0.2 * DEG),
        sway_period=(3.0, 4.0, 5.0),
        lin_amp=(0.01, 0.02, 0.05),
        lin_period=(2.0, 3.0, 1.5),
    )
    m = make(**params)
    nav = Strapdown(m.rpy, m.v_n, m.lat, m.lon, m.h)
    h = 0.01
    worst_att = worst_vel = 0.0
    for k in range(6000):
        m.do_step(k * h, h)
        nav.update(m.dtheta_b, m.dv_b, h)
        c_err = cv.euler_to_dcm(m.rpy).T @ cv.quat_to_dcm(np.array(nav.q))
        worst_att = max(worst_att, np.max(np.abs(cv.dcm_to_rotvec(c_err))))
        worst_vel = max(worst_vel, np.max(np.abs(np.subtract(nav.v, m.v_n))))
    t = 6000 * h
    w = 2 * np.pi / np.array([3.0, 4.0, 5.0])
    ref = np.array([0.01, -0.02, 1.0]) + np.array([0.5, 0.3, 0.2]) * DEG * np.sin(w * t)
    np.testing.assert_allclose(m.rpy, ref, atol=1e-12)
    assert worst_att < 0.01 * ARCSEC
    assert worst_vel < 1e-5


@pytest.mark.parametrize(("order", "h"), [(1, 0.01), (2, 0.05)])
def test_jitter_statistics_and_consistency(order: int, h: float) -> None:
    sigma = np.array([1e-4, 2e-4, 3e-4])
    tau = 0.5
    params = dict(
        jitter_sigma=tuple(sigma),
        jitter_tau=(tau, tau, tau),
        jitter_order=order,
        seed=11,
        dt_truth=0.01,
    )
    m = make(**params)
    nav = Strapdown(m.rpy, m.v_n, m.lat, m.lon, m.h)
    n = int(round(120.0 / h))  # 120 s = 240 tau
    rpy = np.empty((n, 3))
    worst = 0.0
    for k in range(n):
        m.do_step(k * h, h)
        nav.update(m.dtheta_b, m.dv_b, h)
        rpy[k] = m.rpy
        c_err = cv.euler_to_dcm(m.rpy).T @ cv.quat_to_dcm(np.array(nav.q))
        worst = max(worst, np.max(np.abs(cv.dcm_to_rotvec(c_err))))
    # Sample std: relative sampling error sqrt(2 tau_c / T) / 2 with tau_c = integral of
    # rho^2 over +-inf (tau for order 1, 2.5 / beta for order 2): 4.6 % and 3.5 % at
    # T = 120 s; 20 % is > 4 sigma.
    std = rpy.std(axis=0)
    np.testing.assert_allclose(std, sigma, rtol=0.2)
    # The increments integrate to the jittered attitude. Order 2: C1 path, the two-sample
    # coning of the reference navigator leaves ~0.002". Order 1: the rate jumps at every
    # inner node (no derivative exists), so the reference's coning term is spurious by
    # ~|dtheta|^2 / 12 ~ 3e-10 rad per step, a random walk of ~0.01" over 12000 steps
    # (hence h = dt_truth there; at h = 5 dt_truth the commutation error of the 5 linear
    # pieces makes the random walk ~0.1").
    assert worst < 0.05 * ARCSEC


def test_seed_reproducibility_and_reset() -> None:
    params = dict(jitter_sigma=(1e-4, 1e-4, 1e-4), seed=5)

    def run(block: StationaryBase) -> np.ndarray:
        out = []
        for k in range(20):
            block.do_step(k * 0.01, 0.01)
            out.append(np.concatenate([block.rpy, block.dtheta_b, block.f_b]))
        return np.array(out)

    a = run(make(**params))
    b = run(make(**params))
    np.testing.assert_array_equal(a, b)
    other = run(make(**{**params, "seed": 6}))
    assert np.max(np.abs(a - other)) > 1e-6
    blk = make(**params)
    run(blk)
    blk.reset()
    for name, value in params.items():
        setattr(blk, name, np.array(value) if isinstance(value, tuple) else value)
    blk.setup_experiment(0.0)
    blk.exit_initialization_mode()
    np.testing.assert_array_equal(run(blk), a)


def test_bad_jitter_order() -> None:
    m = StationaryBase()
    m.jitter_order = 3
    m.setup_experiment(0.0)
    with pytest.raises(ValueError, match="jitter_order"):
        m.exit_initialization_mode()


def test_default_run_zero_inputs() -> None:
    m = make()
    for k in range(int(round(m.default_stop / m.default_step))):
        m.do_step(k * m.default_step, m.default_step)
    assert np.all(np.isfinite(m.f_b))
    assert m.f_b[2] == pytest.approx(-earth.gravity(45.0 * DEG))
