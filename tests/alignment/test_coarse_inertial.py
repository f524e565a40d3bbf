"""Inertial-frame (sway-robust) coarse alignment and its error theory (issue 26, item 1).

The theory (:func:`cosim.alignment.coarse_inertial.inertial_coarse_theory`) gives the
1-sigma of the heading error; a campaign of N independent runs of a consistent theory
has ``N RMS^2 / sigma^2 ~ chi-square(N)``, so ``RMS / sigma`` lies in
``[sqrt(chi2_N(0.005) / N), sqrt(chi2_N(0.995) / N)]`` with probability 99 %
(:func:`cosim.reproduce.seed003.rms_band`). The seeds are fixed, so each test is
deterministic; the band says how unlikely a failure of a correct theory would be.
Acceptance 2 (100 runs, within 20 % at 30, 60 and 120 s) is the slow test.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.alignment.coarse import coarse_alignment
from cosim.alignment.coarse_inertial import (
    InertialCoarse,
    earth_turn,
    heading_sigma_inertial,
    inertial_coarse_theory,
    reference_velocity,
)
from cosim.alignment.nav import AlignmentConfigError, dcm_to_rotvec_3, earth_rate
from cosim.alignment.sins_static import SinsStaticAlignment
from cosim.models.blocks.ship_motion import ShipMotion
from cosim.models.blocks.stationary_base import StationaryBase
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, MICRO_G, OMEGA_IE
from cosim.models.conventions import euler_to_dcm_3
from cosim.models.earth import gravity
from cosim.reproduce import seed003

ROOT = Path(__file__).resolve().parents[2]
SWAY = ROOT / "scenarios" / "sins_north_finding_sway.toml"
LAT = 45.0 * DEG
RPY = np.array([0.3, -0.5, 30.0]) * DEG


def test_reference_velocity_is_the_integral_of_the_turning_gravity() -> None:
    t = np.linspace(0.0, 3600.0, 36001)
    f_n = np.array([0.0, 0.0, -float(gravity(LAT))])
    f0 = np.einsum("kij,j->ki", earth_turn(LAT, t), f_n)
    trap = np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (f0[1:] + f0[:-1]) * 0.1, axis=0)])
    np.testing.assert_allclose(reference_velocity(LAT, 0.0, t), trap, atol=1e-6)
    # first order: east component W g cos L t^2 / 2
    r = reference_velocity(LAT, 0.0, [60.0])[0]
    assert r[1] == pytest.approx(OMEGA_IE * 9.806 * math.cos(LAT) * 1800.0, rel=1e-3)


def _make(cls, **params):
    m = cls()
    for name, value in params.items():
        setattr(m, name, np.array(value, dtype=float) if isinstance(value, tuple) else value)
    return m


def _perfect_base_run(base: StationaryBase, T: float, h: float = 0.1):
    """Step a base with a perfect IMU: (inertial estimate, analytic TRIAD estimate, truth)."""
    base.setup_experiment(0.0)
    base.exit_initialization_mode()
    ic = InertialCoarse(LAT)
    sdth, sdv = np.zeros(3), np.zeros(3)
    n = int(round(T / h))
    for k in range(n):
        base.step(k * h, h)
        ic.step(base.dtheta_b, base.dv_b, h)
        sdth += base.dtheta_b
        sdv += base.dv_b
    truth = euler_to_dcm_3(base.rpy)
    return ic.attitude(), coarse_alignment(sdv / T, sdth / T, LAT), truth


def test_a_perfect_imu_on_a_swaying_base_aligns_where_the_analytic_method_fails() -> None:
    """10' sinusoidal sway at 5 s plus 1 cm linear sway at 2 s, perfect sensors, 61.25 s.

    (A quarter sway period over a whole number: the mean sway rate is largest.)

    The sway rate (~0.2 deg/s) swamps the earth rate in the averaged gyro output: the
    analytic TRIAD is off by degrees; the inertial-frame method only sees the sway
    through the centred velocity (a few arcmin at most after 30 s).
    """
    base = _make(StationaryBase, lat0=LAT, rpy0=RPY, sway_amp=(10 * ARCMIN,) * 3,
                 sway_period=(5.0,) * 3, lin_amp=(0.01,) * 3, lin_period=(2.0,) * 3,
                 dt_truth=0.01)  # fmt: skip
    c_in, c_triad, truth = _perfect_base_run(base, 61.25)  # not a whole number of periods
    e_in = dcm_to_rotvec_3(c_in @ truth.T) / ARCMIN
    e_tr = dcm_to_rotvec_3(c_triad @ truth.T) / ARCMIN
    assert abs(e_tr[2]) > 60.0
    # the linear sway's velocity near the window's end (3 cm/s) leaves up to ~20' at 60 s,
    # falling like T^-2 to T^-4 with the phase (docs/self_alignment.md); the angular sway
    # alone leaves < 0.2'; seed 003's IMU gives a theory sigma of 30' at 60 s
    assert abs(e_in[2]) < 20.0 and np.all(np.abs(e_in[:2]) < 0.1)
    c_in, _, truth = _perfect_base_run(base, 121.25)
    assert abs(dcm_to_rotvec_3(c_in @ truth.T)[2]) / ARCMIN < 4.0


def test_theory_against_a_monte_carlo_of_the_accumulator() -> None:
    """Noisy IMU on a still base, 20 runs at 15 and 30 s, heading and level within 99 % bands."""
    h = 0.1
    qa, qg = 50.0 * MICRO_G, 0.01 * DEG_PER_SQRT_HOUR
    sa, sg = 100.0 * MICRO_G, 0.02 * DEG_PER_HOUR
    c = euler_to_dcm_3(RPY)
    w_b = c.T @ earth_rate(LAT)
    f_b = c.T @ np.array([0.0, 0.0, -float(gravity(LAT))])
    rng = np.random.default_rng(26)
    runs, marks = 20, (150, 300)
    err = np.zeros((runs, len(marks), 3))
    for i in range(runs):
        eps, nab = sg * rng.standard_normal(3), sa * rng.standard_normal(3)
        ic = InertialCoarse(LAT)
        for k in range(1, marks[-1] + 1):
            dth = (w_b + eps) * h + qg * math.sqrt(h) * rng.standard_normal(3)
            ic.step(dth, (f_b + nab) * h + qa * math.sqrt(h) * rng.standard_normal(3), h)
            if k in marks:
                err[i, marks.index(k)] = dcm_to_rotvec_3(ic.attitude() @ c.T)
    lo, hi = seed003.rms_band(runs, 0.99)
    lo2, hi2 = seed003.rms_band(2 * runs, 0.99)
    for j, k in enumerate(marks):
        th = inertial_coarse_theory(k * h, LAT, dt=h, q_accel=qa, q_gyro=qg,
                                    sigma_accel_bias=sa, sigma_gyro_bias=sg)  # fmt: skip
        assert lo <= seed003.rms(err[:, j, 2]) / th.sigma[2] <= hi
        level = float(seed003.rms(err[:, j, :2].ravel()))
        assert lo2 <= level / math.sqrt(0.5 * (th.P_phi[0, 0] + th.P_phi[1, 1])) <= hi2


def test_bias_sensitivities_predict_the_error_of_each_run() -> None:
    """No noise, drawn biases: ``phi_err = J_a nabla_n + J_g eps_n`` run by run (to 2 %).

    These sensitivities (with their signs) give the fine filter's P0 cross-covariances.
    """
    h, T = 0.1, 40.0
    c = euler_to_dcm_3(RPY)
    w_b = c.T @ earth_rate(LAT)
    f_b = c.T @ np.array([0.0, 0.0, -float(gravity(LAT))])
    th = inertial_coarse_theory(T, LAT, dt=h)
    rng = np.random.default_rng(3)
    for _ in range(3):
        eps_b = 0.02 * DEG_PER_HOUR * rng.standard_normal(3)
        nab_b = 100.0 * MICRO_G * rng.standard_normal(3)
        ic = InertialCoarse(LAT)
        for _k in range(int(round(T / h))):
            ic.step((w_b + eps_b) * h, (f_b + nab_b) * h, h)
        err = dcm_to_rotvec_3(ic.attitude() @ c.T)
        pred = th.J_accel @ (c @ nab_b) + th.J_gyro @ (c @ eps_b)
        assert np.linalg.norm(err - pred) < 0.02 * np.linalg.norm(pred)


def test_theory_tends_to_the_one_position_limit_and_falls_with_time() -> None:
    sg = 0.02 * DEG_PER_HOUR
    s = [heading_sigma_inertial(T, LAT, arw=0.01 * DEG_PER_SQRT_HOUR, gyro_bias=0.0)
         for T in (30.0, 60.0, 120.0)]  # fmt: skip
    # ARW alone: the angle random walk g N sqrt(T) tilts the east signal W g cos L T:
    # heading sigma ~ N / (W cos L sqrt(T)), as in the one-position limit
    assert s[0] / s[1] == pytest.approx(2.0**0.5, rel=0.05)
    assert s[1] / s[2] == pytest.approx(2.0**0.5, rel=0.05)
    v = [heading_sigma_inertial(T, LAT, arw=0.0, gyro_bias=0.0, vrw=50.0 * MICRO_G)
         for T in (30.0, 60.0, 120.0)]  # fmt: skip
    # VRW alone: velocity noise q sqrt(T) against the signal W g cos L T^2 / 2: T^-3/2
    assert v[0] / v[1] == pytest.approx(2.0**1.5, rel=0.1)
    # bias alone, long window: eps_E / (W cos L) (6.46' at 45 deg for 0.02 deg/h)
    limit = sg / (OMEGA_IE * math.cos(LAT))
    long = heading_sigma_inertial(3600.0, LAT, arw=0.0, gyro_bias=sg, dt=1.0)
    assert long == pytest.approx(limit, rel=0.15)


def test_a_coarse_window_too_short_for_the_fine_filter_is_refused() -> None:
    blk = _make(SinsStaticAlignment, init_mode=2, coarse_time=30.0, coarse_sigma_max=DEG)
    blk.setup_experiment(0.0)
    with pytest.raises(AlignmentConfigError, match=r"coarse_time >= \d+ s"):
        blk.exit_initialization_mode()
    blk = _make(SinsStaticAlignment, init_mode=2, coarse_time=600.0, coarse_sigma_max=ARCMIN)
    blk.setup_experiment(0.0)
    with pytest.raises(AlignmentConfigError, match="no window reaches it"):
        blk.exit_initialization_mode()


def _coarse_campaign(runs: int, stop: float):
    return seed003.campaign(
        SWAY, runs, 2024, columns=["align.rpy_err", "align.rpy_sigma", "align.phase"],
        parameters={"align": {"coarse_time": 120.0}}, stop=stop, record_every=1, workers=2,
    )  # fmt: skip


def _ratios(camp, times: tuple[float, ...]) -> list[float]:
    out = []
    for t in times:
        k = int(round(t / 0.1))
        err = camp["align.rpy_err"][:, k, 2]
        sig = camp["align.rpy_sigma"][:, k, 2]
        assert np.ptp(sig) < 1e-5 * sig[0]  # the theory: one value (Euler map aside)
        out.append(float(seed003.rms(err)) / float(sig[0]))
    return out


def test_coarse_stage_on_the_jittering_base_follows_the_theory_fast() -> None:
    """4 runs of the sway scenario's coarse stage to 20 s: RMS / theory in the 99 % band."""
    camp = _coarse_campaign(4, 20.0)
    assert np.all(camp["align.phase"][:, -1] == 0.0)
    lo, hi = seed003.rms_band(4, 0.99)
    (r,) = _ratios(camp, (20.0,))
    assert lo <= r <= hi


@pytest.mark.slow
def test_coarse_stage_on_the_jittering_base_follows_the_theory_acceptance_2() -> None:
    """Acceptance 2: 100 runs, heading RMS within 20 % of the theory at 30, 60 and 120 s.

    (The 99 % band of RMS / sigma for 100 runs is [0.82, 1.18]: 20 % is about 2.6 sigma.)
    """
    camp = _coarse_campaign(100, 120.0)
    for r in _ratios(camp, (30.0, 60.0, 120.0)):
        assert 0.8 <= r <= 1.2, r


def test_coning_and_sculling_hold_under_the_ship_motion_from_reused_buffers() -> None:
    """Perfect increments of seed 001's ship (12.5/10/5 deg at 12/6/8 s), 50 ms, 120 s.

    The increments are passed as views of one buffer overwritten each step, as the
    co-simulation blocks pass their inputs. The accumulator must keep copies of the
    previous step's increments: with references the two-sample coning and sculling
    terms vanish (``dth' x dth = 0``) and the ship's sway left 6.7' of heading here.
    With them the residual is the algorithm's, far below any IMU's (< 0.05').
    """
    ship = ShipMotion()
    ship.dt_truth = 0.005
    ship.initialize()
    h = 0.05
    ic = InertialCoarse(30.0 * DEG)
    buf = np.zeros(6)
    for k in range(int(round(120.0 / h))):
        ship.step(k * h, h)
        buf[0:3], buf[3:6] = ship.dtheta_b, ship.dv_b
        ic.step(buf[0:3], buf[3:6], h)
    truth = euler_to_dcm_3(ship.rpy)
    e = dcm_to_rotvec_3(ic.attitude() @ truth.T) / ARCMIN
    assert np.all(np.abs(e) < 0.05), e
