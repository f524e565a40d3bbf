"""Error budgets per requirement (issue 15, item 3; acceptance 4).

The budget splits the covariance of a linear filter by error source
(:func:`cosim.estimation.covariance.covariance_budget`); the regression of a campaign's
runs on its drawn parameters (:mod:`cosim.verify.regression`) is the evidence beside it.
"""

from __future__ import annotations

import ast
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from cosim.alignment.static_model import static_budget, static_covariance
from cosim.estimation import van_loan
from cosim.estimation.covariance import covariance_analysis, covariance_budget
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR, G0, MICRO_G, OMEGA_IE
from cosim.verify.budget import campaign_budgets, linear_model, scenario_values, signal_budget
from cosim.verify.campaign import prepare, run_campaign
from cosim.verify.regression import ols

ROOT = Path(__file__).resolve().parents[2]
STATIC = ROOT / "scenarios" / "sins_north_finding.toml"
ROTATING = ROOT / "scenarios" / "sins_north_finding_rotating.toml"
TRANSFER = ROOT / "scenarios" / "transfer_alignment.toml"


def _requirements(path: Path) -> tuple[dict, float]:
    """The scenario's requirements by id, and its stop time [s]."""
    prep = prepare(path)
    return {r.id: r for r in prep.requirements}, prep.scenario.settings.stop


def _part(entry: dict, source: str) -> dict:
    return next(p for p in entry["parts"] if p["source"] == source)


# ----------------------------------------------------------------------- the loop
def test_parts_and_transfer_of_a_small_filter() -> None:
    """A 2-state filter: the parts sum to covariance_analysis's P, and T maps e_0 exactly."""
    F = np.array([[0.0, 1.0], [0.0, -0.1]])
    G = np.eye(2)
    Qa, Qb = np.diag([1e-3, 0.0]), np.diag([0.0, 2e-3])
    Phi, Qd_a = van_loan(F, G, Qa, 0.1)
    _, Qd_b = van_loan(F, G, Qb, 0.1)
    H, R = np.array([[1.0, 0.0]]), np.array([[0.04]])
    P0 = {"x0": np.diag([1.0, 0.0]), "v0": np.diag([0.0, 0.25])}

    def meas(k: int):  # noqa: ANN202
        return (H, {"noise": R}) if k % 3 == 2 else None

    bud = covariance_budget(P0, 60, 0.1, lambda k: (Phi, {"a": Qd_a, "b": Qd_b}), meas)
    ref = covariance_analysis(
        P0["x0"] + P0["v0"],
        60,
        0.1,
        lambda k: (Phi, Qd_a + Qd_b),
        lambda k: (H, R) if k % 3 == 2 else None,
    )
    assert np.max(np.abs(bud.total - ref.P)) <= 1e-12 * np.max(np.abs(ref.P))
    assert np.max(np.abs(sum(bud.parts.values()) - bud.total)) <= 1e-12 * np.max(bud.total)
    assert list(bud.parts) == ["x0", "v0", "a", "b", "noise"]
    # the initial-error parts are T P0_s T^T: the deterministic response to e_0
    T = bud.transfer[-1]
    assert np.allclose(bud.parts["v0"][-1], T @ P0["v0"] @ T.T, rtol=1e-10, atol=1e-15)


def test_static_budget_total_is_the_covariance_analysis() -> None:
    """static_budget keeps static_covariance's numbers (no result moves)."""
    kw = {"base_rpy": np.array([0.3, -0.5, 30.0]) * DEG, "coriolis": True, "record_every": 50}
    bud = static_budget(300.0, **kw)
    ref = static_covariance(300.0, **kw)
    assert np.max(np.abs(bud.total - ref.P)) <= 1e-10 * np.max(np.abs(ref.P))


# ----------------------------------------------------------------------- acceptance 4
def test_seed003_heading_budget_at_300s() -> None:
    """One position, heading at 300 s: parts add; the east drift part is eps_E / (W cos L)."""
    reqs, stop = _requirements(STATIC)
    req = reqs["SEED003-HDG-300"]
    model = linear_model(STATIC)
    entry, _, _ = signal_budget(model, req, stop)
    assert entry["window"] == [300.0, 300.0]
    assert abs(entry["sum_check"]) < 0.01  # acceptance: 1 %; in fact rounding, ~1e-12
    assert abs(entry["sum_check"]) < 1e-9
    assert round(entry["total"]["sigma"], 2) == 7.84  # README, seed 003 covariance table
    _, values = scenario_values(STATIC)
    sigma_eps = values["imu"]["gyro_bias_sigma"]  # the scenario's drift sigma [rad/s]
    lat = values["align"]["lat"]
    limit = sigma_eps / (OMEGA_IE * math.cos(lat)) / ARCMIN  # 6.46'
    east = _part(entry, "gyro drift E")["sigma"]
    assert abs(east / limit - 1.0) < 0.05, (east, limit)
    # it is the largest part; the north and down drifts do not reach the heading
    assert max(entry["parts"], key=lambda p: p["variance"])["source"] == "gyro drift E"
    assert _part(entry, "gyro drift N")["sigma"] < 0.01 * east
    assert _part(entry, "gyro drift D")["sigma"] < 0.01 * east


def test_seed003_rotating_budget_adds_up() -> None:
    """Turntable: the parts add, the total is the README's 1.27' at 600 s."""
    reqs, stop = _requirements(ROTATING)
    req = reqs["SEED003-ROT-HDG-600"]
    entry, _, _ = signal_budget(linear_model(ROTATING), req, stop)
    assert abs(entry["sum_check"]) < 1e-9
    assert round(entry["total"]["sigma"], 2) == 1.27
    # the modulated east drift is no longer the limit (it was 66 % on one position)
    drift = sum(p["share"] for p in entry["parts"] if p["source"].startswith("gyro drift"))
    assert drift < 0.3


def test_seed001_level_budget_is_the_accelerometer_bias() -> None:
    """Seed 001: the level errors' budget is led by the accelerometer bias (README: nabla/g).

    Over the judged window (30 s to 120 s) the bias along the slave's x axis makes most of
    the pitch variance, along y most of the roll variance; the bias together is more than
    half of each, more than the velocity-matching noise, while the heading is the noise's.
    """
    model = linear_model(TRANSFER)
    shares = {}
    reqs, stop = _requirements(TRANSFER)
    for rid in ("TA-PITCH-1", "TA-ROLL-1", "TA-HDG-1"):
        entry, _, _ = signal_budget(model, reqs[rid], stop)
        assert entry["window"] == [30.0, 120.0]
        assert abs(entry["sum_check"]) < 1e-9
        share = {p["source"]: p["share"] for p in entry["parts"]}
        bias = sum(v for s, v in share.items() if s.startswith("accelerometer bias"))
        shares[rid] = (share, bias)
    pitch, bias_p = shares["TA-PITCH-1"]
    roll, bias_r = shares["TA-ROLL-1"]
    hdg, bias_h = shares["TA-HDG-1"]
    noise = "measurement noise (velocity matching)"
    assert bias_p > 0.5 and bias_r > 0.5
    assert bias_p > pitch[noise] and bias_r > roll[noise]
    assert max(pitch, key=pitch.get) == "accelerometer bias x"
    assert max(roll, key=roll.get) == "accelerometer bias y"
    assert hdg[noise] > 0.9 and bias_h < 0.1


# ----------------------------------------------------------------------- regression
def test_ols_standard_errors_cover_the_true_slope() -> None:
    """Synthetic fits: b +- t_(0.975, n-p-1) se covers the true slope in 95 % of them.

    Gaussian residuals make (b - beta) / se exactly Student-t; 1000 fits give the
    coverage to +-3 binomial sigma = +-0.021.
    """
    rng = np.random.default_rng(15)
    n, beta = 12, np.array([2.0, -0.5, 0.0])
    t975 = stats.t.ppf(0.975, n - 4)
    hits = 0
    for _ in range(1000):
        X = rng.standard_normal((n, 3))
        y = 1.0 + X @ beta + 0.7 * rng.standard_normal(n)
        fit = ols(y, X, ("a", "b", "c"), ("1", "1", "1"))
        hits += int(abs(fit.slope[0] - beta[0]) <= t975 * fit.se[0])
    assert abs(hits / 1000 - 0.95) < 3 * math.sqrt(0.95 * 0.05 / 1000)


def test_ols_refuses_too_few_runs() -> None:
    with pytest.raises(ValueError, match="at least 5"):
        ols(np.zeros(4), np.zeros((4, 3)), ("a", "b", "c"), ("1", "1", "1"))


def _stratified_static(tmp_path: Path) -> Path:
    """The one-position scenario with the campaign drawing the gyro drift (stratified)."""
    text = STATIC.read_text()
    old = "[campaign]\nruns = 50\nseed = 2024\n"
    assert old in text
    path = tmp_path / "sins_north_finding_drift.toml"
    path.write_text(text.replace(old, old + 'stratify = ["imu.gyro_bias"]\n'))
    return path


def _heading_regression(tmp_path: Path, runs: int) -> tuple[dict, float]:
    scenario = _stratified_static(tmp_path)
    campaign = run_campaign(scenario, tmp_path / "report", runs=runs, workers=2, progress=False)
    budget = campaign_budgets(campaign)[0]
    assert budget["id"] == "SEED003-HDG-300"
    row = next(r for r in budget["regression"]["rows"] if r["name"] == "gyro drift E")
    lat = scenario_values(scenario)[1]["align"]["lat"]
    slope_theory = DEG_PER_HOUR / (OMEGA_IE * math.cos(lat)) / ARCMIN  # arcmin per deg/h
    return row, slope_theory


def _check_slope(row: dict, slope_theory: float) -> None:
    # the model's sign: heading error = -eps_E / (W cos L) (psi_D takes up the drift)
    assert row["predicted"] < 0
    assert abs(abs(row["predicted"]) / slope_theory - 1.0) < 0.05
    assert np.sign(row["slope"]) == np.sign(row["predicted"])
    assert abs(abs(row["slope"]) - slope_theory) <= 2.0 * row["se"], row


@pytest.mark.slow
def test_campaign_regression_slope_on_the_east_drift(tmp_path: Path) -> None:
    """12 runs through the engine: slope of the heading error on the drawn east drift.

    Magnitude 1 / (W cos L) (323' per deg/h at 45 deg) and the model's sign, within two
    standard errors (the slope is Student-t about its true value; |t| <= 2 holds in
    about 92 % of campaigns of 12 runs and 3 regressors: a fixed seed, 2024). About
    20 s on two idle cores (300 s runs); the default suite has the cheap variant in
    tests/verify/test_budget_report.py (60 s runs, the level errors on the drawn bias).
    """
    row, theory = _heading_regression(tmp_path, 12)
    _check_slope(row, theory)
    assert row["se"] < 0.4 * theory  # 12 stratified runs resolve the slope to ~20 %


@pytest.mark.slow
def test_campaign_regression_slope_50_runs(tmp_path: Path) -> None:
    """The README's 50 runs (seed 2024): the same check, the slope to about 10 %."""
    row, theory = _heading_regression(tmp_path, 50)
    _check_slope(row, theory)
    assert row["se"] < 0.15 * theory


# ------------------------------------------- regression without stratify: the runs' own draws
def _short_unstratified(tmp_path: Path) -> Path:
    """Seed 003, one position, 60 s, no ``stratify``: the IMU draws from its own seed."""
    text = STATIC.read_text()
    for old, new in (('stop = "300 s"', 'stop = "60 s"'), ('at = "300 s"', 'at = "60 s"')):
        assert old in text
        text = text.replace(old, new)
    assert "stratify" not in text
    path = tmp_path / "sins_north_finding_60s.toml"
    path.write_text(text)
    return path


def test_recorded_draws_are_the_runs_own_bias_outputs(tmp_path: Path) -> None:
    """The draw read from a run's seed is what the run's IMU output as truth at t0.

    Three runs of a 60 s campaign; each run simulated again for 1 s with its seeds,
    recording ``imu.gyro_bias_b`` and ``imu.accel_bias_b``: equal to rounding.
    """
    from cosim.scenario import build_master, load_scenario
    from cosim.verify.regression import RECORDED_METHOD, recorded_draws

    scenario = _short_unstratified(tmp_path)
    campaign = run_campaign(scenario, tmp_path / "report", runs=3, workers=1, progress=False)
    draws = recorded_draws(str(scenario), list(campaign.records), set())
    assert set(draws) == {"imu.gyro_bias", "imu.accel_bias"}
    for row, rec in enumerate(campaign.records):
        sc = load_scenario(scenario)
        sc.outputs = ["imu.gyro_bias_b", "imu.accel_bias_b"]
        master = build_master(sc, stop=1.0, record_every=1)
        try:
            for block, seed in rec.seeds.items():
                master.system.parameters.setdefault(block, {})["seed"] = int(seed)
            data = master.run().data
        finally:
            master.terminate()
        for key, out in (("imu.gyro_bias", "gyro_bias_b"), ("imu.accel_bias", "accel_bias_b")):
            first = np.array([data[f"imu.{out}[{k}]"][0] for k in (1, 2, 3)])
            assert np.allclose(draws[key][row], first, rtol=1e-12, atol=0.0), key
    assert len({tuple(v) for v in draws["imu.gyro_bias"]}) == 3  # the runs differ
    budgets = campaign_budgets(campaign)
    origin = budgets[0]["regression"].get("regressors_from", {})
    assert origin == {"imu.gyro_bias": RECORDED_METHOD, "imu.accel_bias": RECORDED_METHOD}


def test_unstratified_regression_of_the_level_on_the_recorded_bias(tmp_path: Path) -> None:
    """The cheap variant (default suite): 12 runs of 60 s, no stratify, seed 2024.

    The roll and pitch errors from 30 s on settle towards ``nabla / g`` of the
    accelerometer bias; the regression on the runs' recorded draws (no stratify: each
    run's IMU drew from its own seed) finds the model's slope within three standard
    errors (Student-t, 12 - 6 = 6 dof: |t| > 3 in 2.4 % of campaigns; seed 2024 fixed;
    the two-standard-error check is the slow heading test below), with its sign, and
    the fit is sharp (R^2 > 0.5).
    """
    text = _short_unstratified(tmp_path).read_text().replace('from = "60 s"', 'from = "30 s"')
    scenario = tmp_path / "sins_60s_levels.toml"
    scenario.write_text(text)
    campaign = run_campaign(scenario, tmp_path / "report", runs=12, workers=2, progress=False)
    budgets = {b["id"]: b for b in campaign_budgets(campaign)}
    for rid, name in (
        ("SEED003-ROLL-60", "accelerometer bias E"),
        ("SEED003-PITCH-60", "accelerometer bias N"),
    ):
        reg = budgets[rid]["regression"]
        row = next(r for r in reg["rows"] if r["name"] == name)
        per_ug = MICRO_G / G0 / ARCMIN
        assert 0.8 < abs(row["predicted"]) / per_ug < 1.0, row  # still settling to 1/g
        assert np.sign(row["slope"]) == np.sign(row["predicted"])
        assert abs(row["z"]) < 3.0, row
        assert row["se"] < 0.2 * per_ug
        assert reg["r2"] > 0.5


def _unstratified_heading(tmp_path: Path, runs: int) -> tuple[dict, float]:
    campaign = run_campaign(STATIC, tmp_path / "report", runs=runs, workers=2, progress=False)
    budget = campaign_budgets(campaign)[0]
    assert budget["id"] == "SEED003-HDG-300"
    assert "recorded seeds" in budget["regression"]["regressors_from"]["imu.gyro_bias"]
    row = next(r for r in budget["regression"]["rows"] if r["name"] == "gyro drift E")
    lat = scenario_values(STATIC)[1]["align"]["lat"]
    return row, DEG_PER_HOUR / (OMEGA_IE * math.cos(lat)) / ARCMIN


@pytest.mark.slow
def test_unstratified_regression_slope_on_the_east_drift(tmp_path: Path) -> None:
    """The shipped scenario as it is (no stratify), 50 runs, seed 2024: the heading error's
    slope on each run's recorded east drift has the magnitude 1 / (W cos L) and the
    model's sign within two standard errors (50 runs of 300 s: one to two minutes on two
    cores)."""
    row, theory = _unstratified_heading(tmp_path, 50)
    _check_slope(row, theory)
    assert row["se"] < 0.3 * theory


# ----------------------------------------------------------- the engine knows no paper
#: A seed (reproduction) name or the HRG filter's family, in any spelling.
PAPER_WORDS = re.compile(r"seed[\s_-]*0\d\d|\bhrg", re.I)


def filter_class_names() -> set[str]:
    """Every class the alignment package defines (the filters and their machinery) and every
    block the distribution registers (pyproject's ``ins_cosim.blocks``), by name."""
    names = set()
    for path in sorted((ROOT / "cosim" / "alignment").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names |= {n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    names |= set(project["project"]["entry-points"]["ins_cosim.blocks"])
    return names


def test_no_filter_class_or_seed_name_in_verify_or_the_core() -> None:
    """grep: cosim/verify and the core (cosim/*.py) name no filter class and no paper."""
    names = filter_class_names()
    assert {"SinsStaticAlignment", "TransferAlignment", "HrgTwoPositionAlignment"} <= names
    words = re.compile(r"\b(" + "|".join(sorted(names)) + r")\b")
    files = sorted((ROOT / "cosim" / "verify").glob("*.py")) + sorted((ROOT / "cosim").glob("*.py"))
    hits = []
    for path in files:
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for found in (words.search(line), PAPER_WORDS.search(line)):
                if found:
                    hits.append(f"{path.relative_to(ROOT)}:{i}: {found.group(0)}")
    assert not hits, "the engine names a filter or a paper:\n" + "\n".join(hits)
    assert not (ROOT / "cosim" / "verify" / "budget_hrg.py").exists()
    # the checker sees what it must
    assert PAPER_WORDS.search("see seed 000") and PAPER_WORDS.search("cosim.reproduce.seed001")
    assert PAPER_WORDS.search("the HRG UPF") and not PAPER_WORDS.search("a seed of 7")


@pytest.mark.parametrize("name", ["sins_north_finding_sway", "transfer_alignment_vehicle"])
def test_a_filter_run_its_model_does_not_describe_has_no_budget(name: str) -> None:
    """The swaying-base self-alignment (init_mode 2) and attitude matching run filters the
    static and velocity-matching models are not: no model rather than a wrong budget."""
    assert linear_model(ROOT / "scenarios" / f"{name}.toml") is None
