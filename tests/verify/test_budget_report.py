"""The error budget in the verification reports (issue 15, item 3; acceptance 5, budget half).

A short seed 003 campaign (60 s runs, the campaign drawing the sensor biases) through the
engine and the report writer: report.json carries each requirement's budget and the
regression, the HTML shows the bar chart and the tables in every requirement's section;
a scenario without a linear model says so in one line.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from cosim.models.constants import ARCMIN, G0, MICRO_G
from cosim.verify.budget import NO_MODEL
from cosim.verify.campaign import run_campaign
from cosim.verify.report import write_reports

ROOT = Path(__file__).resolve().parents[2]
STATIC = ROOT / "scenarios" / "sins_north_finding.toml"
DEMO = ROOT / "scenarios" / "demo_verify.toml"
RUNS = 12


def _short_static(folder: Path) -> Path:
    """Seed 003, one position, stopped at 60 s: heading at 60 s, levels from 30 s on."""
    text = STATIC.read_text()
    edits = [
        ('stop = "300 s"', 'stop = "60 s"'),
        ('at = "300 s"', 'at = "60 s"'),
        ('from = "60 s"', 'from = "30 s"'),
        (
            "[campaign]\nruns = 50\n",
            '[campaign]\nruns = 50\nstratify = ["imu.accel_bias", "imu.gyro_bias"]\n',
        ),
    ]
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    path = folder / "sins_north_finding_60s.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def static_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, str]:
    folder = tmp_path_factory.mktemp("budget_report")
    scenario = _short_static(folder)
    campaign = run_campaign(scenario, folder / "report", runs=RUNS, workers=2, progress=False)
    paths = write_reports(campaign)
    return json.loads(paths["json"].read_text()), paths["html"].read_text()


def test_report_json_carries_the_budget(static_report: tuple[dict, str]) -> None:
    data, _ = static_report
    budgets = data["budgets"]
    assert list(budgets) == [r["id"] for r in data["requirements"]]
    json.dumps(budgets, allow_nan=False)  # strict JSON: no NaN or Infinity in the budget
    for b in budgets.values():
        assert b["unit"] == "arcmin"
        assert "note" not in b
        total = b["total"]["variance"]
        assert abs(sum(p["variance"] for p in b["parts"]) / total - 1.0) < 1e-9
        assert math.isclose(b["total"]["sigma"], math.sqrt(total))
        assert {p["source"] for p in b["parts"]} >= {
            "initial misalignment",
            "gyro drift E",
            "accelerometer bias N",
            "accelerometer white noise",
            "measurement noise (zero velocity)",
        }
        reg = b["regression"]
        assert reg["n"] == RUNS
        assert [r["name"] for r in reg["rows"]] == [
            "gyro drift N",
            "gyro drift E",
            "gyro drift D",
            "accelerometer bias N",
            "accelerometer bias E",
        ]
        assert all(r["se"] > 0 for r in reg["rows"])
    assert budgets["SEED003-HDG-300"]["window"] == [60.0, 60.0]
    assert budgets["SEED003-ROLL-60"]["window"] == [30.0, 60.0]


def test_level_regression_matches_the_model(static_report: tuple[dict, str]) -> None:
    """The cheap variant of acceptance 4's regression: level errors on the drawn bias.

    A horizontal accelerometer bias tilts the computed vertical by nabla / g (seed 003's
    levels settle in ~50 s), so the slope of the roll error on the east bias and of the
    pitch error on the north bias tends to 1/g = 0.00344' per ug in magnitude (the
    window's mean, from 30 s on, a little less); the linear model predicts it, and the
    campaign's slope agrees within three standard errors (Student-t with 12 - 6 = 6
    degrees of freedom: |t| > 3 in 2.4 % of campaigns; seed 2024 fixed). The bias makes
    most of the level variance, so the fit is sharp.
    """
    data, _ = static_report
    per_ug = MICRO_G / G0 / ARCMIN
    for rid, bias in (
        ("SEED003-ROLL-60", "accelerometer bias E"),
        ("SEED003-PITCH-60", "accelerometer bias N"),
    ):
        row = next(r for r in data["budgets"][rid]["regression"]["rows"] if r["name"] == bias)
        # averaged over [30 s, 60 s] the levels are still settling towards nabla / g
        assert 0.8 < abs(row["predicted"]) / per_ug < 1.0, row
        assert np.sign(row["slope"]) == np.sign(row["predicted"])
        assert abs(row["z"]) < 3.0, row
        assert row["se"] < 0.2 * per_ug


def test_html_shows_budget_per_requirement(static_report: tuple[dict, str]) -> None:
    data, page = static_report
    for rid in data["budgets"]:
        section = re.search(
            rf'<section class="requirement" id="req-{re.escape(rid)}".*?</section>', page, re.S
        )
        assert section is not None, rid
        text = section.group(0)
        assert f'<div class="budget" data-id="{rid}">' in text
        assert re.search(
            r'alt="[^"]*error budget" src="data:image/png;base64,[A-Za-z0-9+/=]{200,}"', text
        )
        assert '<table class="budget-parts">' in text and '<table class="regression">' in text
        assert "gyro drift E" in text and "standard error" in text


def test_a_filter_without_a_linear_model_says_so(tmp_path: Path) -> None:
    campaign = run_campaign(DEMO, tmp_path / "report", runs=3, workers=1, progress=False)
    paths = write_reports(campaign)
    data = json.loads(paths["json"].read_text())
    assert all(b["note"] == NO_MODEL for b in data["budgets"].values())
    assert all("parts" not in b for b in data["budgets"].values())
    page = paths["html"].read_text()
    assert page.count(f'<p class="no-budget">{NO_MODEL}.</p>') == len(data["budgets"])
