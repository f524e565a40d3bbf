"""Issue 16, acceptance 1: a rate/force vendor IMU from check-fmu to a verify report.

The fixture (tests/fixtures/rate_imu, C, compiled by the test run) is the usual vendor
shape: it takes the true angular rate [deg/s] and specific force [g], integrates them
over the step itself (trapezoid rule) and publishes increments in mrad and ft/s; its
parameters are in deg/h, mg, deg/sqrt(h) and m/s/sqrt(h), its seed is ``NoiseSeed``.
The scenario is edited with exactly what ``ins-cosim check-fmu --scenario`` prints
(the README's swap-in steps), and nothing else but the vendor's data-sheet values.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from cosim.interop.cbuild import build_c_fmu

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "transfer_alignment.toml"
FIXTURE = ROOT / "tests" / "fixtures" / "rate_imu"
RUNS = "4"
#: The data sheet: what a user sets after pasting the block table (same error budget as
#: the fixed-bias StrapdownImu of tests/integration/test_swap_in_transfer.py).
DATA_SHEET = {
    "GyroBias_X": '"0.01 deg/h"',
    "GyroBias_Y": '"0.01 deg/h"',
    "GyroBias_Z": '"0.01 deg/h"',
    "AccelBias_X": '"300 ug"',
    "AccelBias_Y": '"300 ug"',
    "AccelBias_Z": '"300 ug"',
    "GyroNoise": '"0.001 deg/h/sqrt(Hz)"',
    "AccelNoise": '"50 ug/sqrt(Hz)"',
    "seed": "2",
}


@pytest.fixture(scope="module")
def rate_imu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_c_fmu(FIXTURE, tmp_path_factory.mktemp("rate_imu") / "RateImu.fmu")


def section(lines: list[str], start: str, stop: re.Pattern[str]) -> list[str]:
    i = next(k for k, line in enumerate(lines) if line.startswith(start)) + 1
    out = []
    for line in lines[i:]:
        if stop.match(line):
            break
        out.append(line)
    return out


def swapped(text: str, printed: str) -> str:
    """The scenario edited with what check-fmu printed, the way the guide says."""
    lines = printed.splitlines()
    table = [lines[lines.index("[blocks.imu]")]] + section(
        lines, "[blocks.imu]", re.compile(r"^2\. ")
    )
    table = [
        re.sub(
            r"(\w+) = (\"[^\"]*\"|[-\w.]+)",
            lambda m: f"{m[1]} = {DATA_SHEET.get(m[1], m[2])}",
            line,
        )
        if line.startswith("parameters = ")
        else line
        for line in table
    ]
    text, n = re.subn(
        r"\[blocks\.imu\]\n.*?(?=\n\[blocks\.)", "\n".join(table) + "\n", text, flags=re.S
    )
    assert n == 1
    for line in section(lines, "2. in connections, remove:", re.compile(r"^\d\. ")):
        assert f"  {line}\n" in text, line
        text = text.replace(f"  {line}\n", "")
    add = section(lines, "3. in connections, add:", re.compile(r"^(\d\. |   \()"))
    text = text.replace("connections = [\n", "connections = [\n" + "".join(f"  {a}\n" for a in add))
    for line in lines:
        m = re.match(r'^   \[(?:output|campaign)\] \w+: remove ("[^"]+")', line)
        if m:
            text, n = re.subn(rf"{re.escape(m[1])},?\s*", "", text)
            assert n == 1, line
    return text


def check_fmu(cli, fmu: Path) -> str:
    res = cli("check-fmu", fmu, "--role", "imu", "--block", "imu", "--scenario", SCENARIO)
    assert res.code == 0, res.out + res.err
    return res.out


def test_check_fmu_finds_the_rate_form_and_prints_the_edits(cli, rate_imu: Path) -> None:
    out = check_fmu(cli, rate_imu)
    assert "input form: 'rates'" in out
    assert '"AngRate_Y" = "omega_b[2]"' in out and '"NoiseSeed" = "seed"' in out
    assert '"lever.omega_is_s -> imu.omega_b",' in out and '"lever.f_s -> imu.f_b",' in out
    assert '"lever.dtheta_s -> imu.dtheta_b",' in out
    # every variable of the FMU is listed, parameters with their units
    for name in ["GyroBias_X", "AccelBias_Z", "GyroNoise", "AccelNoise"]:
        assert re.search(rf"^  {name}\s+parameter\s+Real", out, re.M), name
    assert "deg/sqrt(h)" in out and "mg (= 0.00980665 m s^-2)" in out


def test_the_printed_edits_check_clean(cli, rate_imu: Path, tmp_path: Path) -> None:
    path = tmp_path / "vendor.toml"
    path.write_text(swapped(SCENARIO.read_text(), check_fmu(cli, rate_imu)))
    res = cli("check", path)
    assert res.code == 0, res.err
    assert "warning" not in res.err, res.err
    assert f"  imu     FMU {rate_imu.resolve()}" in res.out


def test_forgetting_an_edit_is_caught_by_check(cli, rate_imu: Path, tmp_path: Path) -> None:
    full = swapped(SCENARIO.read_text(), check_fmu(cli, rate_imu))
    # the connections to the rate inputs forgotten: a required role input left unconnected
    path = tmp_path / "noconn.toml"
    path.write_text(full.replace('  "lever.f_s -> imu.f_b",\n', ""))
    res = cli("check", path)
    assert res.code == 3, res.out + res.err
    assert "required input(s) f_b[1], f_b[2], f_b[3] are not connected" in res.err
    assert "Traceback" not in res.err
    # the seed rename forgotten: the campaign cannot randomize the block
    path = tmp_path / "noseed.toml"
    path.write_text(
        full.replace('"NoiseSeed" = "seed"\n', "").replace("seed = 2 }", "NoiseSeed = 2 }")
    )
    for args in (("check", path), ("verify", path, "--runs", "1", "--report", tmp_path / "r")):
        res = cli(*args)
        assert res.code == 3, res.out + res.err
        assert "block 'imu' has no seed parameter to randomize" in res.err
        assert "Traceback" not in res.err


def heading(cli, scenario: Path, out: Path) -> dict:
    res = cli("verify", scenario, "--runs", RUNS, "--report", out, "--no-progress")
    assert res.code in (0, 2), res.out + res.err  # 2: the pass-rate needs more than 4 runs
    data = json.loads((out / "report.json").read_text())
    assert data["campaign"]["completed"] == int(RUNS)
    return next(r["result"] for r in data["requirements"] if r["id"] == "TA-HDG-1")


# A 4-run Monte Carlo campaign of 120 s transfer alignments through the C FMU, twice (~30 s).
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_rate_imu_meets_the_heading_requirement_like_ours(cli, rate_imu: Path, tmp_path) -> None:
    from test_swap_in_transfer import OURS

    vendor = tmp_path / "vendor.toml"
    vendor.write_text(swapped(SCENARIO.read_text(), check_fmu(cli, rate_imu)))
    theirs = heading(cli, vendor, tmp_path / "v")
    # ours with the same fixed biases: no stratified draws either
    text = re.sub(r"\[blocks\.imu\]\n.*?(?=\n\[blocks\.)", OURS, SCENARIO.read_text(), flags=re.S)
    text = re.sub(r"\nstratify = \[[^]]*\]", "", text)
    (tmp_path / "ours.toml").write_text(text)
    ours = heading(cli, tmp_path / "ours.toml", tmp_path / "ours")
    # 4 runs: the RMS is within the limit, but 4 runs bound it only to 2.37 times itself at
    # 95 % (chi-square, 4 dof): not shown below 7' either, so undecided, never violated
    for r in (ours, theirs):
        assert r["value"] <= r["limit"] and r["verdict"] in ("satisfied", "undecided"), r
    assert 0.5 < theirs["value"] / ours["value"] < 2.0, (ours["value"], theirs["value"])
