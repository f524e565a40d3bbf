"""MasterIns: latency as an exact delay, attitude error, velocity noise statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.models.blocks.master_ins import MasterIns
from cosim.models.conventions import wrap_angle

RATE_V = np.array([1.0, -2.0, 0.5])  # m/s per s
RATE_RPY = np.array([0.01, -0.02, 0.3])  # rad/s; yaw crosses +-pi during the run
RPY0 = np.array([0.1, 0.05, 2.9])


def make(**params: object) -> MasterIns:
    ins = MasterIns()
    for name, value in params.items():
        if isinstance(value, (tuple, list, np.ndarray)):
            value = np.asarray(value, dtype=float)
        setattr(ins, name, value)
    ins.setup_experiment(0.0)
    ins.exit_initialization_mode()
    return ins


def truth(t: float) -> dict[str, object]:
    """Ramp inputs at time t (yaw wrapped as a motion block would deliver it)."""
    rpy = RPY0 + RATE_RPY * t
    rpy[2] = wrap_angle(rpy[2])
    return {
        "v_n": RATE_V * t,
        "rpy": rpy,
        "lat": 0.5 + 1e-6 * t,
        "lon": 2.0 + 2e-6 * t,
        "h": 10.0 + 0.1 * t,
    }


def run_ramp(ins: MasterIns, h: float, n: int, jitter: bool = False) -> dict[str, np.ndarray]:
    out = {k: np.empty((n, 3)) for k in ("v", "rpy", "pos")}
    out["t"] = np.empty(n)
    for k in range(n):
        step = h * (1.0 + (1e-15 if jitter and k % 2 else 0.0))  # fmpy-like step jitter
        t_end = (k + 1) * h
        for name, value in truth(t_end).items():
            setattr(ins, name, value)
        ins.do_step(k * h, step)
        out["t"][k] = t_end
        out["v"][k] = ins.v_master_n
        out["rpy"][k] = ins.rpy_master
        out["pos"][k] = (ins.lat_master, ins.lon_master, ins.h_master)
    return out


@pytest.mark.parametrize(
    ("latency", "jitter"),
    [(0.0, False), (0.05, False), (0.05, True), (0.037, False), (1.234, True)],
)
def test_ramp_shows_exactly_the_configured_delay(latency: float, jitter: bool) -> None:
    h, n = 0.01, 400
    ins = MasterIns()
    for name, value in truth(0.0).items():  # the start state, before initialisation
        setattr(ins, name, value)
    ins.latency = latency
    ins.setup_experiment(0.0)
    ins.exit_initialization_mode()
    out = run_ramp(ins, h, n, jitter)
    delayed = np.maximum(out["t"] - latency, 0.0)  # before t0 the initial state holds
    # Whole-step latency: an exact shift; otherwise linear interpolation, exact on a ramp.
    np.testing.assert_allclose(out["v"], RATE_V * delayed[:, None], rtol=0, atol=1e-12)
    expected_rpy = RPY0 + RATE_RPY * delayed[:, None]
    np.testing.assert_allclose(wrap_angle(out["rpy"] - expected_rpy), 0.0, atol=1e-12)
    np.testing.assert_allclose(out["pos"][:, 2], 10.0 + 0.1 * delayed, atol=1e-12)
    # The delay read back from the velocity ramp, where it is defined (t > latency).
    valid = out["t"] > latency + 1e-9
    measured = out["t"][valid] - out["v"][valid, 0] / RATE_V[0]
    np.testing.assert_allclose(measured, latency, atol=1e-10)
    # Angle outputs wrapped; yaw went through +-pi without a jump.
    assert np.all(out["rpy"][:, 2] >= -math.pi) and np.all(out["rpy"][:, 2] < math.pi)


def record_velocity(ins: MasterIns, h: float, n: int) -> np.ndarray:
    v = np.empty((n, 3))
    for k in range(n):
        ins.do_step(k * h, h)
        v[k] = ins.v_master_n
    return v


def test_attitude_error_is_added() -> None:
    delta = np.array([1e-3, -2e-3, 5e-3])
    ins = make(attitude_error=delta)
    ins.rpy = np.array([0.2, -0.1, 3.14])
    ins.do_step(0.0, 0.01)
    expected = ins.rpy + delta
    np.testing.assert_allclose(ins.rpy_master[:2], expected[:2], rtol=1e-15)
    # Yaw 3.14 + 0.005 passes +pi: it is wrapped to (-pi, pi].
    np.testing.assert_allclose(ins.rpy_master[2], expected[2] - 2.0 * math.pi, rtol=1e-15)
    assert ins.rpy_master[2] < -3.0


def test_velocity_gauss_markov_error_variance_and_correlation_time() -> None:
    sigma_gm, tau = 0.1, 1.0
    h, n = 0.2, 50_000  # T / tau = 10000
    v = record_velocity(make(velocity_gm_sigma=sigma_gm, velocity_gm_tau=tau, seed=12), h, n)
    # Theory (exact discretisation): var = sigma^2, cov(lag k) = sigma^2 exp(-k h / tau).
    # Over T = 10000 tau the variance has a relative std ~sqrt(2 tau / T) = 1.4 % and the
    # correlation time fitted on lags 1..5 (one tau) ~2 %; both are checked at 10 %.
    x = v - v.mean(axis=0)
    np.testing.assert_allclose(np.mean(x**2, axis=0), sigma_gm**2, rtol=0.10)
    lags = np.arange(1, 6)
    cov = np.array([np.mean(x[k:] * x[:-k], axis=0) for k in lags])
    slope = np.polyfit(lags, np.log(cov), 1)[0]
    np.testing.assert_allclose(-h / slope, tau, rtol=0.10)


def test_velocity_white_noise_std() -> None:
    # n = 20000 independent samples: the sample std has a relative error 1/sqrt(2n) = 0.5 %.
    std_w = 0.02
    v = record_velocity(make(velocity_noise_std=std_w, seed=13), 0.01, 20_000)
    np.testing.assert_allclose(v.std(axis=0), std_w, rtol=0.05)
    # White: the lag-1 correlation is within 4/sqrt(n) of zero.
    x = v - v.mean(axis=0)
    rho1 = np.mean(x[1:] * x[:-1], axis=0) / np.mean(x**2, axis=0)
    assert np.all(np.abs(rho1) < 4.0 / math.sqrt(v.shape[0]))


def test_seed_reproducibility_and_bad_parameters() -> None:
    def record(seed: int) -> np.ndarray:
        ins = make(velocity_noise_std=0.1, attitude_error_sigma=1e-3, seed=seed)
        rows = []
        for k in range(20):
            ins.do_step(k * 0.01, 0.01)
            rows.append(np.concatenate([ins.v_master_n, ins.rpy_master]))
        return np.array(rows)

    np.testing.assert_array_equal(record(5), record(5))
    assert not np.array_equal(record(5), record(6))
    with pytest.raises(ValueError):
        make(latency=-0.1)
