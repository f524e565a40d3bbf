"""Moored-ship self-alignment (issue 26, item 3; acceptance 4).

The slave IMU alone, 10/10/5 m from the ship's point at rest, under seed 001's ship
motion. Statistics as in tests/acceptance/test_self_alignment.py: for a consistent filter
``N RMS^2 / sigma^2 ~ chi-square(N)`` at a given time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.reproduce import seed003

ROOT = Path(__file__).resolve().parents[2]
SHIP = ROOT / "scenarios" / "ship_self_alignment.toml"
PERFECT = {k: 0.0 for k in ("gyro_bias_sigma", "gyro_arw", "accel_bias_sigma", "accel_vrw")}


def _coarse_heading_error(lever: bool, stop: float) -> float:
    sc = cosim.load_scenario(SHIP)
    sc.blocks["imu"].parameters.update(PERFECT)
    if not lever:
        sc.blocks["align"].parameters["lever_s"] = [0.0, 0.0, 0.0]
    sc.outputs = ["align.rpy_err", "align.phase"]
    res = cosim.run(sc, stop=stop, record_every=20)
    assert res["align.phase"][-2] == 0.0  # the last instant of the coarse window
    return float(res["align.rpy_err[3]"][-2])


def test_the_lever_arm_takes_the_imu_velocity_out_of_the_coarse_stage() -> None:
    """Perfect IMU on the rolling ship, the coarse window's last recorded instant.

    Without ``lever_s`` the IMU's own velocity (up to ~3 m/s) is read as gravity
    turning: hundreds of arcmin after 20 s. With it, after the full 120 s window, what
    remains is the 50 ms integration (coning, sculling, the step means of the lever-arm
    velocity): < 0.1', against the theory's 9' for the scenario's IMU.
    """
    assert abs(_coarse_heading_error(lever=False, stop=21.0)) > 60.0
    assert abs(_coarse_heading_error(lever=True, stop=120.0)) < 0.1


@pytest.mark.slow
def test_acceptance_4_ship_heading_against_the_covariance_bound() -> None:
    """Acceptance 4: 50 runs, heading error RMS against the filter's sigma at 300 and 600 s.

    For a consistent filter ``50 RMS^2 / sigma^2 ~ chi-square(50)``: passes when RMS / sigma
    lies in its 95 % band ([0.80, 1.20]). Measured (seed 2011): 0.85 at 300 s, 0.88 at
    600 s (docs/self_alignment.md).
    """
    camp = seed003.campaign(SHIP, 50, 2011, columns=["align.rpy_err", "align.rpy_sigma"],
                            record_every=20, workers=2)  # fmt: skip
    lo, hi = seed003.rms_band(50, 0.95)
    for t in (300.0, 600.0):
        k = int(round(t))
        r = float(seed003.rms(camp["align.rpy_err"][:, k, 2]))
        s = float(np.sqrt(np.mean(camp["align.rpy_sigma"][:, k, 2] ** 2)))
        assert lo <= r / s <= hi, (t, r, s)
