"""Turntable: indexing profile, reversing rotation, exact sensor-frame increments."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_ship_motion import ARCSEC, Strapdown
from test_ship_motion import make as make_ship

from cosim.models import conventions as cv
from cosim.models import earth
from cosim.models.blocks.stationary_base import StationaryBase
from cosim.models.blocks.turntable import Turntable
from cosim.models.constants import DEG

BASE = ("omega_ib_b", "omega_dot_b", "f_b", "dtheta_b", "dv_b", "rpy")


def make_table(**params: object) -> Turntable:
    m = Turntable()
    for name, value in params.items():
        setattr(m, name, np.array(value, dtype=float) if isinstance(value, tuple) else value)
    return m


def start(m: Turntable, base=None) -> Turntable:
    if base is not None:
        for name in BASE:
            setattr(m, name, getattr(base, name).copy())
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    return m


def make_base(**params: object) -> StationaryBase:
    b = StationaryBase()
    for name, value in params.items():
        setattr(b, name, np.array(value, dtype=float) if isinstance(value, tuple) else value)
    b.setup_experiment(0.0)
    b.exit_initialization_mode()
    return b


def record(m: Turntable, h: float, steps: int, base=None) -> dict[str, np.ndarray]:
    names = ("angle", "table_rate", "table_accel")
    out = {n: np.empty(steps + 1) for n in names}
    out["t"] = np.arange(steps + 1) * h
    for n in names:
        out[n][0] = getattr(m, n)
    for k in range(steps):
        if base is not None:
            base.do_step(k * h, h)
            for name in BASE:
                setattr(m, name, getattr(base, name).copy())
        m.do_step(k * h, h)
        for n in names:
            out[n][k + 1] = getattr(m, n)
    return out


def test_two_position_indexing_default_schedule() -> None:
    # Defaults: 90 deg at t = 200 s, 30 deg/s, 200 deg/s2: trapezoid with t_acc = 0.15 s,
    # cruise (pi/2 - v^2/a)/v = 2.85 s -> the move ends at 203.15 s.
    m = start(make_table(mode=1))
    h = 0.05
    out = record(m, h, int(round(205.0 / h)))
    t, ang, rate, acc = out["t"], out["angle"], out["table_rate"], out["table_accel"]
    v_max, a_max = 30.0 * DEG, 200.0 * DEG
    assert np.all(np.abs(ang[t <= 200.0]) < 1e-15)  # t = k h vs the block's t + h: 1 ulp
    assert np.all(np.abs(rate) <= v_max * (1 + 1e-12))
    assert np.max(np.abs(rate)) == pytest.approx(v_max, rel=1e-12)
    assert np.all(np.abs(acc) <= a_max * (1 + 1e-12))
    # finite-difference acceleration of the sampled rate within the limit
    assert np.all(np.abs(np.diff(rate)) / h <= a_max * (1 + 1e-9))
    t_end = 200.0 + 2 * v_max / a_max + (math.pi / 2 - v_max**2 / a_max) / v_max
    assert t_end == pytest.approx(203.15, abs=1e-12)
    np.testing.assert_allclose(ang[t >= t_end], math.pi / 2, rtol=0, atol=1e-15)
    assert np.all(rate[t >= t_end] == 0.0)
    # monotonic move
    assert np.all(np.diff(ang) >= -1e-15)


def test_indexing_short_and_queued_moves() -> None:
    # A 2 deg move is triangular (peak sqrt(a d) < v_max); a move scheduled while the
    # previous one runs starts when it ends.
    m = start(
        make_table(
            mode=1,
            index_times=(1.0, 3.0, 3.5, -1.0),
            index_angles=(2.0 * DEG, 92.0 * DEG, 0.0, 0.0),
            rate_limit=30.0 * DEG,
            accel_limit=200.0 * DEG,
        )
    )
    t_tri = 2 * math.sqrt(2.0 / 200.0)  # 2 sqrt(d / a): 0.2 s
    h = 0.01
    out = record(m, h, 1200)
    t, ang, rate = out["t"], out["angle"], out["table_rate"]
    peak1 = np.max(np.abs(rate[(t > 1.0) & (t < 2.0)]))
    assert peak1 == pytest.approx(math.sqrt(200.0 * DEG * 2.0 * DEG), rel=1e-3)
    np.testing.assert_allclose(ang[(t >= 1.0 + t_tri) & (t <= 3.0)], 2.0 * DEG, atol=1e-15)
    # 90 deg move from 3.0 s lasts 3.15 s, so the third move (to 0) starts at 6.15 s
    move2_end = 3.0 + 2 * 0.15 + (90.0 * DEG - (30 * DEG) ** 2 / (200 * DEG)) / (30 * DEG)
    assert move2_end == pytest.approx(6.15, abs=1e-12)
    i = int(round(6.15 / h))
    assert ang[i] == pytest.approx(92.0 * DEG, abs=1e-12)
    assert rate[i + 1] < 0.0
    assert ang[-1] == pytest.approx(0.0, abs=1e-15)


def test_continuous_rotation_reverses_on_schedule() -> None:
    m = start(make_table(mode=2, rate=100.0 * DEG, reversal_period=10.0, accel_limit=500.0 * DEG))
    h = 0.01
    out = record(m, h, 4000)
    t, ang, rate = out["t"], out["angle"], out["table_rate"]
    r, ramp = 100.0 * DEG, 0.2  # rate / accel_limit
    for k in range(4):
        # zero crossing exactly at k T
        assert rate[int(round(10.0 * k / h))] == pytest.approx(0.0, abs=1e-12)
        window = (t > 10.0 * k + ramp + 1e-9) & (t < 10.0 * (k + 1) - ramp - 1e-9)
        np.testing.assert_allclose(rate[window], (-1) ** k * r, rtol=1e-14)
    # each half period turns r (T - ramp); the angle returns to angle0 every 2 T
    assert ang[1000] == pytest.approx(r * (10.0 - ramp), rel=1e-13)
    assert ang[2000] == pytest.approx(0.0, abs=1e-12)
    assert ang[4000] == pytest.approx(0.0, abs=1e-12)
    # angle is the integral of the rate (trapezoid on 10 ms, error < r * a * h^2 ~ 1e-5 rad)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * h)])
    np.testing.assert_allclose(ang, integral, atol=2e-5)


def test_sensor_increment_closed_form_in_cruise() -> None:
    """Stationary base, table at constant rate: dtheta_s and dv_s in closed form.

    dtheta_s = C_s_t^T ( int Rz(gamma)^T dt w_b + (gamma1 - gamma0) e_z ),
    int Rz^T dt = [[S, C, 0], [-C, S, 0], [0, 0, h]] with S = (sin g1 - sin g0) / r,
    C = (cos g0 - cos g1) / r. Simpson error at dt_truth = 1 ms ~ (r dt)^4 / 180 ~ 1e-13
    relative of the base share; bound 1e-12 relative.
    """
    base = make_base(rpy0=(0.02, -0.01, 0.7), lat0=45.0 * DEG)
    mount = np.array([45.0, -35.26438968, 0.0]) * DEG
    m = start(make_table(mode=2, reversal_period=0.0, mount_rpy=tuple(mount)), base)
    c_s_t = cv.euler_to_dcm(mount)
    r = 100.0 * DEG
    h = 0.01
    for k in range(300):  # spin-up ramp ends at 0.5 s; cruise after
        base.do_step(k * h, h)
        for name in BASE:
            setattr(m, name, getattr(base, name).copy())
        g0 = m.angle
        m.do_step(k * h, h)
        g1 = m.angle
        if k * h < 0.6:
            continue
        assert g1 - g0 == pytest.approx(r * h, rel=1e-12)
        big_s = (math.sin(g1) - math.sin(g0)) / r
        big_c = (math.cos(g0) - math.cos(g1)) / r
        integ = np.array([[big_s, big_c, 0.0], [-big_c, big_s, 0.0], [0.0, 0.0, h]])
        expect_th = c_s_t.T @ (integ @ base.omega_ib_b + np.array([0.0, 0.0, g1 - g0]))
        expect_v = c_s_t.T @ (integ @ base.f_b)
        np.testing.assert_allclose(
            m.dtheta_s, expect_th, rtol=0, atol=1e-12 * np.abs(expect_th).max()
        )
        np.testing.assert_allclose(m.dv_s, expect_v, rtol=0, atol=1e-12 * np.abs(expect_v).max())
    # step-end values: C_s_b^T of the base's plus the table rate on the axis
    c = cv.rot_z(m.angle) @ c_s_t
    np.testing.assert_allclose(
        m.omega_is_s, c.T @ base.omega_ib_b + r * c_s_t[2, :], rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(m.f_s, c.T @ base.f_b, rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        cv.euler_to_dcm(m.rpy_s), cv.euler_to_dcm(base.rpy) @ c, rtol=0, atol=1e-14
    )


def test_hold_mode_passes_base_motion_through() -> None:
    # Table held at 30 deg on a ship: C_s_b is constant, so dtheta_s = C_s_b^T dtheta_b exactly.
    ship = make_ship()
    m = start(make_table(mode=0, angle0=30.0 * DEG), ship)
    c = cv.rot_z(30.0 * DEG)
    for k in range(10):
        ship.do_step(k * 0.01, 0.01)
        for name in BASE:
            setattr(m, name, getattr(ship, name).copy())
        m.do_step(k * 0.01, 0.01)
        np.testing.assert_allclose(m.dtheta_s, c.T @ ship.dtheta_b, rtol=0, atol=1e-17)
        np.testing.assert_allclose(m.dv_s, c.T @ ship.dv_b, rtol=0, atol=1e-15)


def test_centrifugal_and_tangential_terms() -> None:
    # Sensor 0.2 m from the axis; base at rest in inertial space (zero inputs): in the table
    # frame f = gamma'' e_z x offset - gamma'^2 offset.
    offset = np.array([0.2, 0.1, 0.05])
    m = start(
        make_table(mode=2, reversal_period=10.0, accel_limit=100.0 * DEG, offset=tuple(offset))
    )
    h = 0.01
    for k in range(150):
        m.do_step(k * h, h)
        g_d, g_dd = m.table_rate, m.table_accel
        expect = g_dd * np.array([-offset[1], offset[0], 0.0]) - g_d**2 * np.array(
            [offset[0], offset[1], 0.0]
        )
        np.testing.assert_allclose(m.f_s, expect, rtol=0, atol=1e-14)
    # in cruise (after 1 s): pure centripetal, magnitude r^2 |offset_xy|
    assert np.linalg.norm(m.f_s) == pytest.approx(
        (100 * DEG) ** 2 * math.hypot(0.2, 0.1), rel=1e-12
    )


def test_sensor_strapdown_consistency_through_reversals() -> None:
    """Stationary base + tilted table reversing at 100 deg/s: increments navigate 25 s.

    The sensor sits on the axis (no lever arm), so its velocity stays zero. Theory for the
    reference navigator at 1.75 rad/s and h = 10 ms: two-sample coning exact for linear
    rates (the profile is piecewise linear in rate), residual < 1e-3"; velocity residual
    from the truncated rotation compensation ~|dtheta|^3 |dv| / 24 per step, < 1e-5 m/s
    over 2500 steps (observed 1e-5" and 2e-7 m/s). Bounds 1e-3" and 1e-5 m/s; dropping the
    table rate from dtheta_s for one step, or a sign error in the mount, fails by arcminutes.
    """
    base = make_base(rpy0=(0.01, 0.02, 0.3), lat0=45.0 * DEG)
    m = start(
        make_table(mode=2, reversal_period=5.0, mount_rpy=(45.0 * DEG, -35.26 * DEG, 0.0)), base
    )
    nav = Strapdown(m.rpy_s, np.zeros(3), base.lat, base.lon, base.h)
    h = 0.01
    worst_att = worst_vel = 0.0
    for k in range(2500):
        base.do_step(k * h, h)
        for name in BASE:
            setattr(m, name, getattr(base, name).copy())
        m.do_step(k * h, h)
        nav.update(m.dtheta_s, m.dv_s, h, (np.zeros(3), base.lat, base.h))
        c_err = cv.euler_to_dcm(m.rpy_s).T @ cv.quat_to_dcm(np.array(nav.q))
        worst_att = max(worst_att, np.max(np.abs(cv.dcm_to_rotvec(c_err))))
        worst_vel = max(worst_vel, np.max(np.abs(nav.v)))
    assert worst_att < 1e-3 * ARCSEC
    assert worst_vel < 1e-5
    assert base.f_b[2] == pytest.approx(
        -earth.gravity(45.0 * DEG) * math.cos(0.01) * math.cos(0.02)
    )


def test_invalid_parameters() -> None:
    for params, match in (
        (dict(mode=3), "mode"),
        (dict(mode=2, rate=100.0 * DEG, accel_limit=10.0 * DEG, reversal_period=10.0), "reversal"),
        (dict(mode=1, accel_limit=0.0), "accel_limit"),
    ):
        m = make_table(**params)
        m.setup_experiment(0.0)
        with pytest.raises(ValueError, match=match):
            m.exit_initialization_mode()
