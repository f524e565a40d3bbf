"""Verify around the real sensor (issue 17, item 3): a real run placed in a campaign.

Acceptance 4: the README workflow runs end to end on a log the test writes (the demo log
of cosim.sensors.demo stands in for a lab recording), and the placement report gives the
real run's percentile per requirement (a campaign of 6 runs, about 20 s). The other tests
check the placement arithmetic and its messages on small reports.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from cosim.cli import main
from cosim.sensors.placement import PlacementError, place, read_report

ROOT = Path(__file__).resolve().parents[2]


def _report(metrics: list[float | None], ids: tuple[str, ...] = ("R1",)) -> dict:
    return {
        "requirements": [
            {"id": i, "text": f"req {i}", "limit": 1.0, "limit_unit": "arcmin"} for i in ids
        ],
        "runs": [
            {
                "status": "completed" if v is not None else "failed",
                "metrics": {
                    i: None if v is None else {"value": v, "passed": v <= 1.0, "note": ""}
                    for i in ids
                },
            }
            for v in metrics
        ],
    }


def test_percentile_is_the_mid_rank() -> None:
    campaign = _report([0.1 * k for k in range(1, 11)] + [None])  # a failed run is left out
    (p,) = place(_report([0.45]), campaign)
    assert p.runs == 10 and p.percentile == pytest.approx(40.0)
    assert p.low == pytest.approx(0.1) and p.high == pytest.approx(1.0)
    assert p.median == pytest.approx(0.55) and p.finding == ""
    (p,) = place(_report([0.5]), campaign)  # a tie counts half
    assert p.percentile == pytest.approx(45.0)
    (p,) = place(_report([0.98]), campaign)
    assert p.percentile == pytest.approx(90.0)


def test_a_real_run_outside_the_distribution_is_a_finding() -> None:
    campaign = _report([0.1 * k for k in range(1, 21)])
    (p,) = place(_report([3.0]), campaign)
    assert p.percentile == 100.0 and p.real_passed is False
    assert p.finding.startswith("outside the simulated distribution: 3 arcmin is above")
    (p,) = place(_report([0.01]), campaign)
    assert "below the smallest of the 20 simulated runs" in p.finding
    (p,) = place(_report([1.99]), campaign)
    assert p.finding == "in the upper 5 % tail of the campaign"


def test_reports_that_cannot_be_placed(tmp_path: Path) -> None:
    with pytest.raises(PlacementError, match="share no requirement"):
        place(_report([0.5], ("A",)), _report([0.5], ("B",)))
    with pytest.raises(PlacementError, match="no completed run"):
        place(_report([None]), _report([0.5]))
    with pytest.raises(PlacementError, match="run ins-cosim verify SCENARIO --report"):
        read_report(tmp_path / "nothing")
    undecided = _report([0.5])
    undecided["runs"][0]["metrics"]["R1"] = {"value": "nan", "passed": None, "note": "short"}
    (p,) = place(undecided, _report([0.5]))
    assert math.isnan(p.percentile) and "did not decide it (short)" in p.finding


def test_place_command(tmp_path: Path) -> None:
    for name, metrics in (("real", [0.45]), ("campaign", [0.1 * k for k in range(1, 11)])):
        (tmp_path / name).mkdir()
        (tmp_path / name / "report.json").write_text(json.dumps(_report(metrics)))
    res = CliRunner().invoke(main, ["place", str(tmp_path / "real"), str(tmp_path / "campaign")])
    assert res.exit_code == 0, res.output
    assert "| R1 | 0.45 arcmin (meets) | 1 arcmin | 40.0 |" in res.output
    assert (tmp_path / "real" / "placement.md").is_file()
    data = json.loads((tmp_path / "real" / "placement.json").read_text())
    assert data["placements"][0]["percentile"] == pytest.approx(40.0)
    bad = CliRunner().invoke(main, ["place", str(tmp_path / "x"), str(tmp_path / "campaign")])
    assert bad.exit_code == 3 and bad.output.startswith("error: ")


def test_readme_workflow_end_to_end(tmp_path: Path) -> None:
    from cosim.sensors.demo import write_demo_log

    log = write_demo_log(tmp_path / "static_imu.csv", seed=7)
    runner = CliRunner()
    # 1. characterise the log
    res = runner.invoke(
        main, ["characterize", str(log), "--out", str(tmp_path / "char"), "--bootstrap", "30"]
    )
    assert res.exit_code == 0, res.output
    pasted = (tmp_path / "char" / "imu_parameters.toml").read_text()
    params = re.search(r"^parameters = \{ (.*) \}$", pasted, re.M).group(1)
    # 2. the campaign scenario with the pasted block (+ the data sheet's turn-on sigmas)
    text = (ROOT / "scenarios" / "real_sensor_campaign.toml").read_text()
    text = re.sub(
        r"(\[blocks\.imu\]\nmodel = \"StrapdownImu\"\n(?:#.*\n)*)parameters = \{ .* \}",
        lambda m: m.group(1) + "parameters = { " + params
        + ', gyro_bias_sigma = "0.02 deg/h", accel_bias_sigma = "100 ug", seed = 1 }',
        text,
    )  # fmt: skip
    campaign = tmp_path / "campaign.toml"
    campaign.write_text(text)
    # 3. the real-run scenario on the test's log
    real = tmp_path / "real.toml"
    real.write_text(
        (ROOT / "scenarios" / "real_sensor_north_finding.toml")
        .read_text()
        .replace("out/real_sensor/static_imu.csv", str(log))
    )
    for scenario, report, runs in ((real, "real", "1"), (campaign, "campaign", "6")):
        res = runner.invoke(
            main,
            ["verify", str(scenario), "--runs", runs, "--report", str(tmp_path / report),
             "--workers", "1", "--no-progress"],
        )  # fmt: skip
        assert res.exit_code in (0, 1, 2), res.output
    # 4. place the real run in the campaign
    res = runner.invoke(main, ["place", str(tmp_path / "real"), str(tmp_path / "campaign")])
    assert res.exit_code == 0, res.output
    data = json.loads((tmp_path / "real" / "placement.json").read_text())
    ids = [p["id"] for p in data["placements"]]
    assert ids == ["SEED003-HDG-300", "SEED003-ROLL-60", "SEED003-PITCH-60"]
    for p in data["placements"]:
        assert p["runs"] == 6
        assert 0.0 <= float(p["percentile"]) <= 100.0
