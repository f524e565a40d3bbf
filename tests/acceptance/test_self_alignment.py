"""Sway-robust self-alignment pipeline (issue 26, items 2 and 8; acceptance 1 and 7).

Statistics: for a consistent filter the heading error at 300 s is N(0, sigma^2) with
sigma its own 1-sigma, so over N runs ``N RMS^2 / sigma^2 ~ chi-square(N)``; the ANEES
of N runs (3 angles) has ``N * ANEES ~ chi-square(3 N)`` (95 % band). The acceptance
campaigns (50 runs each, about 10 min) are slow tests; their measured figures are in
docs/self_alignment.md.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

import cosim
from cosim.models.constants import ARCMIN, DEG
from cosim.reproduce import seed003

ROOT = Path(__file__).resolve().parents[2]
SWAY = ROOT / "scenarios" / "sins_north_finding_sway.toml"
REAL = ROOT / "scenarios" / "real_sensor_north_finding.toml"
COLUMNS = ["align.rpy_err", "align.rpy_sigma", "align.nees", "align.phase"]
#: the variant of acceptance 1 (docs/self_alignment.md): 10' sway at 5 s, 1 cm at 2 s
VARIANT = {
    "base": {"jitter_sigma": [0.0] * 3, "sway_amp": [10 * ARCMIN] * 3, "sway_period": [5.0] * 3,
             "lin_amp": [0.01] * 3, "lin_period": [2.0] * 3},
    "align": {"r_vel": math.hypot(0.1, 0.01 * math.pi / math.sqrt(2.0))},
}  # fmt: skip
STILL = {"base": {"jitter_sigma": [0.0] * 3}}


def test_filter_runs_without_truth_and_outputs_attitude_with_sigma() -> None:
    """rpy_true unconnected: the estimate and its 1-sigma still come out (90 s, one run)."""
    sc = cosim.load_scenario(SWAY)
    sc.connections = [c for c in sc.connections if "rpy_true" not in str(c)]
    sc.blocks["align"].unconnected_ok = ["angle", "rpy_true"]
    sc.outputs = ["align.rpy", "align.rpy_sigma", "align.phase", "base.rpy"]
    res = cosim.run(sc, stop=90.0, record_every=10)
    assert res["align.phase"][-1] == 1.0
    rpy = np.column_stack([res[f"align.rpy[{i}]"] for i in (1, 2, 3)])[-1]
    sig = np.column_stack([res[f"align.rpy_sigma[{i}]"] for i in (1, 2, 3)])[-1] * ARCMIN
    true = np.array([0.3, -0.5, 30.0]) * DEG
    assert np.all(sig > 0.0) and sig[2] < 30.0 * ARCMIN
    # the jitter (5'/5'/3' rms) moves the truth about its mean: allow it in quadrature
    jit = np.array([5.0, 5.0, 3.0]) * ARCMIN
    assert np.all(np.abs(rpy - true) < 4.0 * np.hypot(sig, jit))


def _summary(camp) -> dict:
    e, s, nees = camp["align.rpy_err"], camp["align.rpy_sigma"], camp["align.nees"]
    t = np.arange(e.shape[1]) * 1.0
    m60 = t >= 60.0
    n = e.shape[0]
    anees = nees[:, m60].mean(axis=0)
    return {
        "heading_rms": float(seed003.rms(e[:, -1, 2])),
        "heading_sigma": float(np.sqrt(np.mean(s[:, -1, 2] ** 2))),
        "level_max_rms": [float(seed003.rms(np.max(np.abs(e[:, m60, i]), axis=1))) for i in (0, 1)],
        "anees_in_band": float(
            np.mean((anees >= chi2.ppf(0.025, 3 * n) / n) & (anees <= chi2.ppf(0.975, 3 * n) / n))
        ),  # fmt: skip
    }


@pytest.mark.slow
def test_acceptance_1_sway_and_variant_against_the_still_base() -> None:
    """Acceptance 1: 50 runs from the coarse stage, jitter and sway variant vs still base."""
    kw = {"columns": COLUMNS, "record_every": 10, "workers": 2}
    still = _summary(seed003.campaign(SWAY, 50, 2024, parameters=STILL, **kw))
    for params in (None, VARIANT):
        s = _summary(seed003.campaign(SWAY, 50, 2024, parameters=params, **kw))
        assert abs(s["heading_rms"] / still["heading_rms"] - 1.0) <= 0.15
        assert abs(s["heading_rms"] / s["heading_sigma"] - 1.0) <= 0.10
        assert max(s["level_max_rms"]) <= 0.5
        assert s["anees_in_band"] >= 0.95


@pytest.mark.slow
def test_acceptance_7_shipped_real_sensor_scenario_on_a_swaying_log(tmp_path: Path) -> None:
    """Acceptance 7: a log written from the jittering base, replayed by the shipped scenario.

    The scenario starts from the coarse stage (init_mode 2; the stated attitude only
    computes the errors); its heading error at 300 s, taken against the true attitude of
    the simulation that wrote the log, meets acceptance 1's figure for one run: within 3
    sigma of the filter's own bound and within the 9' of SWAY-HDG-300.
    """
    from cosim.sensors.logs import write_csv

    text = REAL.read_text()
    params = cosim.load_scenario(REAL).blocks["align"].parameters
    assert params["init_mode"] == 2 and "init_offset" not in params
    sc = cosim.load_scenario(SWAY)
    sc.outputs = ["imu.dtheta_meas_b", "imu.dv_meas_b", "base.rpy"]
    res = cosim.run(sc, record_every=1)
    dth = np.column_stack([res[f"imu.dtheta_meas_b[{i}]"] for i in (1, 2, 3)])
    dv = np.column_stack([res[f"imu.dv_meas_b[{i}]"] for i in (1, 2, 3)])
    log = write_csv(tmp_path / "sway_imu.csv", res.time[1:], dth[1:], dv[1:])
    real = tmp_path / "real.toml"
    real.write_text(text.replace("out/real_sensor/static_imu.csv", str(log)))
    out = cosim.run(cosim.load_scenario(real), record_every=10)
    err, sig = out["align.rpy_err[3]"][-1], out["align.rpy_sigma[3]"][-1]
    assert out["align.phase"][-1] == 1.0
    # the scenario's errors are against the stated (mean) attitude; the base's yaw jitter
    # at 300 s (3' rms) is known here from the simulation that wrote the log
    jitter = (res["base.rpy[3]"][-1] - 30.0 * DEG) / ARCMIN
    assert abs(err - jitter) <= 3.0 * sig and abs(err - jitter) <= 9.0  # estimate - truth
