"""Issue 6, acceptance 1: the transfer-alignment scenario with the C vendor IMU swapped in.

The vendor FMU (fmus/vendor_example, compiled from C by the test run) has its own variable
names, outputs in deg and m/s and parameters in deg/h, ug, deg/sqrt(h) and ug/sqrt(Hz).
Swapped in through a rename map and the automatic unit conversion, with the same error
parameters as our StrapdownImu (fixed biases, white noise), it must meet the same heading
requirement as our IMU over the same campaign seeds.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from test_vendor_fmu import rename_table

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "transfer_alignment.toml"
RUNS = "4"

OURS = (
    '[blocks.imu]\nmodel = "StrapdownImu"\nparameters = { grade = 0, '
    'gyro_bias = ["0.01 deg/h", "0.01 deg/h", "0.01 deg/h"], '
    'accel_bias = ["300 ug", "300 ug", "300 ug"], '
    'gyro_arw = "0.001 deg/h/sqrt(Hz)", accel_vrw = "50 ug/sqrt(Hz)", seed = 2 }\n'
)


def vendor(fmu: Path) -> str:
    axes = "xyz"
    params = ", ".join(
        [f'gyro_bias_{a} = "0.01 deg/h"' for a in axes]
        + [f'accel_bias_{a} = "300 ug"' for a in axes]
        + ['gyro_arw = "0.001 deg/h/sqrt(Hz)"', 'accel_vrw = "50 ug/sqrt(Hz)"', "seed = 2"]
    )
    return f'[blocks.imu]\nfmu = "{fmu}"\nparameters = {{ {params} }}\n' + rename_table("imu")


def variant(tmp_path: Path, name: str, imu_block: str) -> Path:
    text = SCENARIO.read_text()
    text, n = re.subn(r"\[blocks\.imu\]\n.*?(?=\n\[blocks\.master\])", imu_block, text, flags=re.S)
    assert n == 1
    # the vendor IMU has no bias truth outputs: record only what both IMUs have
    text = text.replace('"imu.accel_bias_b", "imu.gyro_bias_b", ', "")
    # fixed biases in both: the campaign draws none (stratify needs the IMU's *_sigma)
    text = re.sub(r"\nstratify = \[[^]]*\]", "", text)
    path = tmp_path / name
    path.write_text(text)
    return path


def heading(cli, scenario: Path, out: Path) -> dict:
    res = cli("verify", scenario, "--runs", RUNS, "--report", out, "--no-progress")
    assert res.code in (0, 2), res.out + res.err  # 2: the pass-rate needs more than 4 runs
    data = json.loads((out / "report.json").read_text())
    assert data["campaign"]["completed"] == int(RUNS)
    return next(r["result"] for r in data["requirements"] if r["id"] == "TA-HDG-1")


# A 4-run Monte Carlo campaign of 120 s transfer alignments through the C FMU, twice (~40 s).
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_vendor_imu_meets_the_heading_requirement_like_ours(cli, tmp_path, vendor_imu_fmu):
    ours = heading(cli, variant(tmp_path, "ours.toml", OURS), tmp_path / "ours")
    theirs = heading(cli, variant(tmp_path, "vendor.toml", vendor(vendor_imu_fmu)), tmp_path / "v")
    # 4 runs: the RMS is within the limit, but 4 runs bound it only to 2.37 times itself at
    # 95 % (chi-square, 4 dof): not shown below 7' either, so undecided, never violated
    for r in (ours, theirs):
        assert r["value"] <= r["limit"] and r["verdict"] in ("satisfied", "undecided"), r
    # Same deterministic errors, independent white noise: the heading metric is dominated
    # by the bias-driven part, so both RMS values are of one size (not bit-equal).
    assert 0.5 < theirs["value"] / ours["value"] < 2.0, (ours["value"], theirs["value"])


def test_vendor_scenario_checks_and_converts_units(cli, tmp_path, vendor_imu_fmu) -> None:
    res = cli("check", variant(tmp_path, "vendor.toml", vendor(vendor_imu_fmu)))
    assert res.code == 0, res.err
    assert "OK" in res.out
