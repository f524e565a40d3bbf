"""The error-model protocol (cosim.estimation.error_model) and a user's filter's budget.

``propagate`` is checked against the covariance loop it stands on; then the toy
levelling filter of docs/filter_budget.md, installed as a distribution of its own with its
entry point (the way docs/filter_budget.md and the README's "Adding your own model or
filter" say), gets an error budget in its verification report whose lines add up to the
filter's own covariance.
"""

from __future__ import annotations

import importlib
import json
import math
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim import registry
from cosim.estimation import van_loan
from cosim.estimation.covariance import covariance_analysis
from cosim.estimation.error_model import LinearErrorModel, RunFacts, StepGrid, propagate
from cosim.models.constants import ARCMIN

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "filter_budget.md"


class Oscillator:
    """A damped oscillator with position updates: a LinearErrorModel written for the test."""

    names = ("x", "v")
    block, description, t0 = "osc", "test oscillator", 2.0

    def __init__(self, noise: bool = True) -> None:
        self.grid = StepGrid(0.1, 50, record_every=5)
        self.noise = noise

    def initial_covariance(self) -> dict[str, np.ndarray]:
        return {"x0": np.diag([1.0, 0.0]), "v0": np.diag([0.0, 0.25])}

    def dynamics(self, k: int) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        F = np.array([[0.0, 1.0], [-0.5, -0.1]])
        lines = {"force": np.array([[0.02]]), "drag": np.array([[0.01]])} if self.noise else {}
        return F, np.array([[0.0], [1.0]]), lines

    def step_key(self, k: int) -> int:
        return 0

    def measurement(self, k: int) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        return (np.array([[1.0, 0.0]]), {"sensor": np.array([[0.04]])}) if k % 3 == 2 else None

    def signal_row(self, variable: str, t: float) -> np.ndarray | None:
        return np.array([1.0, 0.0]) if variable == "x" else None

    def regressors(self, draws: dict) -> list:
        return []


@pytest.mark.parametrize("noise", [True, False])
def test_propagate_is_the_covariance_loop_split_by_line(noise: bool) -> None:
    """The lines add up to covariance_analysis of the summed model (Van Loan, Joseph)."""
    model = Oscillator(noise)
    assert isinstance(model, LinearErrorModel)
    bud = propagate(model)
    F, G, lines = model.dynamics(0)
    Qc = sum(lines.values(), np.zeros((1, 1)))
    Phi, Qd = van_loan(F, G, Qc, 0.1)
    ref = covariance_analysis(
        np.diag([1.0, 0.25]),
        50,
        0.1,
        lambda k: (Phi, Qd),
        lambda k: (np.array([[1.0, 0.0]]), np.array([[0.04]])) if k % 3 == 2 else None,
        record_every=5,
    )
    np.testing.assert_allclose(bud.time, ref.time, rtol=0, atol=1e-12)
    assert np.max(np.abs(bud.total - ref.P)) <= 1e-12 * np.max(np.abs(ref.P))
    assert np.max(np.abs(sum(bud.parts.values()) - bud.total)) <= 1e-12 * np.max(bud.total)
    expected = ["x0", "v0", "force", "drag", "sensor"] if noise else ["x0", "v0", "sensor"]
    assert list(bud.parts) == expected
    assert bud.total[-1, 0, 0] < 0.1  # the updates pull the position's variance down


def test_a_grid_with_its_own_times() -> None:
    grid = StepGrid(0.1, 30, record_every=10, include_start=False)
    np.testing.assert_array_equal(grid.recorded_times(), [1.0, 2.0, 3.0])
    grid = StepGrid(0.1, 30, 10, False, np.array([1.0, 2.0, 3.0]) * 1.5)
    np.testing.assert_array_equal(grid.recorded_times(), [1.5, 3.0, 4.5])


def test_run_facts_find_blocks_and_vectors() -> None:
    run = RunFacts(
        block="align",
        models={"base": "StationaryBase", "align": "", "imu": "StrapdownImu"},
        values={"base": {"rpy0[1]": 0.1, "rpy0[2]": 0.2, "rpy0[3]": 0.3}, "align": {"a": 1}},
        start=0.0,
        stop=10.0,
        step=0.1,
    )
    assert run.find("StrapdownImu") == "imu" and run.find("Turntable") is None
    np.testing.assert_array_equal(run.vector("base", "rpy0"), [0.1, 0.2, 0.3])
    assert run.parameters == {"a": 1}


# ---------------------------------------------------------------- the docs' toy filter
def docs_code(language: str, first_line: str) -> str:
    """The docs page's code block of a language that starts with a given line."""
    blocks = re.findall(rf"```{language}\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.S)
    found = [b for b in blocks if b.startswith(first_line)]
    assert len(found) == 1, f"{PAGE.name}: one {language} block starting {first_line!r}"
    return found[0]


SCENARIO = """
connections = [
  "base.dtheta_b -> imu.dtheta_b",
  "base.dv_b -> imu.dv_b",
  "imu.dtheta_meas_b -> align.dtheta_s",
  "imu.dv_meas_b -> align.dv_s",
]

[master]
step = "100 ms"
stop = "60 s"

[blocks.base]
model = "StationaryBase"
parameters = { lat0 = "45 deg", rpy0 = ["0.01 rad", "-0.005 rad", "0 deg"] }

[blocks.imu]
model = "StrapdownImu"
[blocks.imu.parameters]
grade = 0
gyro_bias_sigma = 0.0
accel_bias_sigma = 0.0
gyro_arw = "0.05 deg/h/sqrt(Hz)"
accel_vrw = "50 ug/sqrt(Hz)"
seed = 1

[blocks.align]
model = "ToyLevelling"
[blocks.align.parameters]
lat = "45 deg"
q_accel = "50 ug/sqrt(Hz)"
q_gyro = "0.05 deg/h/sqrt(Hz)"
r_vel = "0.001 m/s"

[output]
variables = ["align"]

[campaign]
runs = 5
seed = 7
"""


@pytest.fixture
def installed_toy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """docs/filter_budget.md's filter installed as ``my-filters 0.1`` (modules + dist-info)."""
    site = tmp_path / "site"
    package = site / "my_filters"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "level.py").write_text(docs_code("python", "# my_filters/level.py"))
    info = site / "my_filters-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-filters\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        f"[{registry.GROUP}]\nToyLevelling = my_filters.level:ToyLevelling\n"
    )
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", f"{site}{os.pathsep}{ROOT}")  # workers
    importlib.invalidate_caches()
    yield site
    for name in [m for m in sys.modules if m == "my_filters" or m.startswith("my_filters.")]:
        del sys.modules[name]
    importlib.invalidate_caches()


def test_the_docs_toy_filter_gets_a_budget_that_adds_up_to_its_covariance(
    installed_toy: Path, tmp_path: Path
) -> None:
    """The report's budget of the roll requirement: its lines, their sum, the filter's sigma.

    The budget runs the docs' model through the verifier's covariance loop; the filter
    runs its own Kalman filter on the same model. Both are linear with the same Phi, Qd,
    H, R and gain, so the budget's total variance is the filter's ``level_sigma[1]``
    squared to rounding (1e-6 relative allows for the two Van Loan sums), and the lines'
    variances add up to the total to rounding.
    """
    from cosim.verify.campaign import run_campaign
    from cosim.verify.report import write_reports

    text = SCENARIO + "\n" + docs_code("toml", "[[requirements]]")
    scenario = tmp_path / "toy_level.toml"
    scenario.write_text(text)
    campaign = run_campaign(scenario, tmp_path / "report", runs=5, workers=1, progress=False)
    paths = write_reports(campaign)
    budget = json.loads(paths["json"].read_text())["budgets"]["LEVEL-ROLL"]
    assert "note" not in budget, budget
    assert budget["model"].startswith("toy levelling KF")
    assert budget["time"] == pytest.approx(60.0)
    sources = [p["source"] for p in budget["parts"]]
    assert sources == [
        "initial velocity error",
        "initial tilt N",
        "initial tilt E",
        "accelerometer white noise",
        "gyro white noise",
        "zero-velocity measurement noise",
    ]
    total = budget["total"]["variance"]
    assert abs(sum(p["variance"] for p in budget["parts"]) / total - 1.0) < 1e-9
    # the roll (psi_N) is seen by the east velocity only: no part from the initial tilt E
    share = {p["source"]: p["share"] for p in budget["parts"]}
    assert share["initial tilt E"] < 1e-12 and share["gyro white noise"] > 0.01
    # the filter's own sigma at the same time, from a run of the same scenario
    own = cosim.run(scenario)["align.level_sigma[1]"][-1] / ARCMIN
    assert math.sqrt(total) == pytest.approx(own, rel=1e-6)
    page = paths["html"].read_text()
    section = re.search(r'<div class="budget" data-id="LEVEL-ROLL">.*?</div>', page, re.S)
    assert section is not None and "gyro white noise" in page
