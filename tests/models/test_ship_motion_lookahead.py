"""ShipMotion evaluates its closed-form truth many steps at a time on the master's grid.

The master passes ``h_n = t_{n+1} - t_n`` (``t_n = t0 + n h``), which differs from ``h`` by
a rounding of ``t``. The look-ahead once compared ``h`` bit for bit, so it mispredicted and
fell back to one evaluation per step on most steps (1701 evaluations for the 2400 steps of
a transfer-alignment run). These tests step the model over that grid.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.models.blocks.ship_motion import AHEAD_STEPS, ShipMotion

H = 0.05
N = 2400  # 120 s, the transfer-alignment scenario's step and length
NAMES = ("rpy", "omega_ib_b", "f_b", "dtheta_b", "dv_b")


def _run(steps: list[tuple[float, float]]) -> tuple[np.ndarray, ShipMotion]:
    m = ShipMotion()
    m.setup_experiment(steps[0][0])
    m.exit_initialization_mode()
    out = []
    for t, h in steps:
        m.do_step(t, h)
        out.append(np.hstack([np.asarray(getattr(m, n), float) for n in NAMES]))
    return np.array(out), m


@pytest.mark.parametrize("t0", [0.0, 3.0])
def test_grid_steps_are_served_from_the_look_ahead(t0: float) -> None:
    t = [t0 + k * H for k in range(N + 1)]
    grid = [(t[k], t[k + 1] - t[k]) for k in range(N)]
    assert any(h != H for _, h in grid)  # else this would prove nothing
    y, m = _run(grid)
    # doubling from 1 to AHEAD_STEPS (7 evaluations for 127 steps), then one per batch
    assert m.truth_evaluations <= 7 + -(-(N - 127) // AHEAD_STEPS)
    # the same outputs as evaluating that one step alone (a fresh model whose first
    # step is it: the truth is a function of time only), to the rounding of the grid
    scale = np.max(np.abs(y), axis=0)
    for k in range(0, N, 97):
        one = ShipMotion()
        one.setup_experiment(t0)
        one.exit_initialization_mode()
        one.do_step(*grid[k])
        ref = np.hstack([np.asarray(getattr(one, n), float) for n in NAMES])
        assert np.all(np.abs(y[k] - ref) <= 1e-12 * scale), k
