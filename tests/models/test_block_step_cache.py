"""Models keep their per-step caches over the master's time grid.

The master passes each block ``h_n = t_{n+1} - t_n`` with ``t_n = t0 + n h`` so that a step
ends exactly on its grid point (cosim/master.py). Those steps differ from ``h`` by a rounding
of ``t``; a cache keyed on the exact step recomputed the flexure's matrix exponentials and the
IMU's noise batch on every step (a transfer-alignment run took ten times as long). These tests
step each caching model over such a grid and check that the cache is the one computed at the
first step and that the outputs equal those of constant steps to rounding (1e-12 relative).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from cosim.models.block import STEP_RTOL, Block, same_step
from cosim.models.blocks.deck_flexure import DeckFlexure
from cosim.models.blocks.gauss_markov import GaussMarkov2
from cosim.models.blocks.strapdown_imu import AHEAD_STEPS, StrapdownImu

H = 0.05
N = 2400  # 120 s, the transfer-alignment scenario's step and length


def grid_steps(t0: float, h: float, n: int) -> list[tuple[float, float]]:
    """(t_n, t_{n+1} - t_n) as the master computes them."""
    t = [t0 + k * h for k in range(n + 1)]
    return [(t[k], t[k + 1] - t[k]) for k in range(n)]


def test_the_grid_steps_differ_from_h_and_are_the_same_step() -> None:
    steps = [dt for _, dt in grid_steps(3.0, H, N)]
    assert any(dt != H for dt in steps)  # else this test would prove nothing
    assert all(same_step(dt, H) for dt in steps)
    assert not same_step(H * (1.0 + 10 * STEP_RTOL), H)  # a real change is a new step
    assert not same_step(H, None)


def _flexure() -> Block:
    m = DeckFlexure()
    m.tau = np.array([30.0, 60.0, 90.0])
    m.sigma = np.array([1e-3, 2e-3, 3e-3])
    m.seed = 4
    return m


def _gm() -> Block:
    m = GaussMarkov2()
    m.tau, m.sigma, m.seed = 20.0, 1e-3, 5
    return m


def _imu() -> Block:
    m = StrapdownImu()
    m.seed, m.grade = 6, 1  # the navigation preset: white noise and bias instability
    return m


CASES: dict[str, tuple[Callable[[], Block], tuple[str, ...]]] = {
    "DeckFlexure": (_flexure, ("theta", "theta_dot", "dtheta_flex")),
    "GaussMarkov2": (_gm, ("x", "x_dot")),
    "StrapdownImu": (_imu, ("dtheta_meas_b", "dv_meas_b", "gyro_bias_b")),
}


def _run(make: Callable[[], Block], steps: list[tuple[float, float]], names: tuple[str, ...]):
    m = make()
    m.setup_experiment(steps[0][0])
    m.exit_initialization_mode()
    out = []
    for t, h in steps:
        m.do_step(t, h)
        out.append(np.hstack([np.atleast_1d(np.asarray(getattr(m, n), float)) for n in names]))
    return np.array(out), m


@pytest.mark.parametrize("name", list(CASES))
def test_cache_survives_the_grid_and_outputs_equal_constant_steps(name: str) -> None:
    make, names = CASES[name]
    grid = grid_steps(3.0, H, N)
    constant = [(t, H) for t, _ in grid]
    y_grid, m = _run(make, grid, names)
    y_const, _ = _run(make, constant, names)
    assert m.step_setups == 1, f"{name} recomputed its step coefficients on the master's grid"
    scale = np.max(np.abs(y_const), axis=0)
    assert np.all(scale > 0)
    np.testing.assert_allclose(y_grid, y_const, rtol=0, atol=1e-12 * float(np.max(scale)))


def test_imu_draws_its_noise_batch_once_per_batch_on_the_grid() -> None:
    m = _imu()
    m.setup_experiment(3.0)
    m.exit_initialization_mode()
    for t, h in grid_steps(3.0, H, N):
        m.do_step(t, h)
    assert m.noise_batches == -(-N // AHEAD_STEPS)  # one batch per AHEAD_STEPS steps
