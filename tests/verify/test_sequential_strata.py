"""``verify --until-decided`` on a stratified scenario: one Latin hypercube per look batch.

The looks n_1 < ... < n_K are fixed before the first run; batch j (runs n_{j-1} ..
n_j - 1) is its own hypercube of n_j - n_{j-1} runs, stream j of the campaign seed
(:func:`cosim.verify.seeds.design_batches`). A cheap scenario (``stratblocks:TurnOnError``,
2 s at 0.1 s) stratifies a 2-vector bias and a scalar gain; its ``drawn`` output is the
value each run was given (``drawn_bias``), so the campaign's own metrics show the draws.

Then, by simulation, the sequential rule on batch designs: with a metric whose spread is
dominated by a stratified draw the statistic scatters less than the bounds assume (Stein
1987: the additive part of the variance is removed), so the wrong-verdict rate stays below
alpha, and below the rate on independent runs (3-sigma binomial tolerance, fixed seeds).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats
from scipy.special import ndtr

from cosim.verify.campaign import MANIFEST, CampaignError, run_campaign
from cosim.verify.seeds import (
    batch_of,
    design_batches,
    design_draws,
    latin_hypercube_normal,
    stratified_draws,
)
from cosim.verify.sequential import (
    SEQUENTIAL_FILE,
    first_decisions,
    plan_looks,
    run_alone,
    run_until_decided,
)

TESTS = Path(__file__).resolve().parents[1]
SEED = 77

SCENARIO = """
[scenario]
name = "strat_tiny"

[master]
step = "100 ms"
stop = "2 s"

[blocks.dev]
class = "stratblocks:TurnOnError"

[blocks.dev.parameters]
bias = ["5 arcmin", "0 arcmin"]
bias_sigma = "1 arcmin"
gain_sigma = "0.1 arcmin/s"
noise = "0.05 arcmin"
seed = 3

[output]
variables = ["dev"]

[campaign]
runs = 8
seed = 77
stratify = ["dev.bias", "dev.gain"]

# the drawn bias[1] = 5' + 1' z (positive for z > -5): its metric |drawn| shows z
[[requirements]]
id = "DRAWN"
signal = "dev.drawn_bias[1]"
unit = "arcmin"
criterion = "value"
bound = "100 arcmin"
statistic = "max"       # every run passes: undecided up to 32 runs (1 - 0.95^32 < 0.95)

[[requirements]]
id = "RMS-END"
signal = "dev.error"
sigma = "dev.sigma"
unit = "arcmin"
criterion = "value"
bound = "20 arcmin"
statistic = "rms"
"""


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("strat") / "strat_tiny.toml"
    path.write_text(SCENARIO)
    return path


@pytest.fixture(scope="module")
def sequential(scenario: Path, tmp_path_factory: pytest.TempPathFactory):
    """The until-decided campaign, looks 8, 16, 32 (DRAWN keeps it going to the cap)."""
    out = tmp_path_factory.mktemp("seq") / "r"
    return run_until_decided(scenario, out, max_runs=32, workers=1, progress=False)


def drawn_z(campaign) -> np.ndarray:
    """Each run's z of bias[1], read back from its DRAWN metric (arcmin): z = metric - 5."""
    return np.array([r.metrics["DRAWN"].value - 5.0 for r in campaign.records])


# ------------------------------------------------------------------- the design itself
def test_each_batch_is_its_own_latin_hypercube() -> None:
    design = (8, 16, 40)
    z = design_draws(design, 3, SEED)
    assert z.shape == (40, 3)
    # batch 1 is the design of a fixed campaign of 8 runs; batch j is stream j
    np.testing.assert_array_equal(z[:8], latin_hypercube_normal(8, 3, SEED))
    np.testing.assert_array_equal(z[8:16], latin_hypercube_normal(8, 3, SEED, stream=1))
    np.testing.assert_array_equal(z[16:], latin_hypercube_normal(24, 3, SEED, stream=2))
    for a, b in ((0, 8), (8, 16), (16, 40)):  # one draw per stratum per component
        for col in z[a:b].T:
            assert sorted(np.floor(ndtr(col) * (b - a)).astype(int)) == list(range(b - a))
    assert not np.allclose(z[:8], z[8:16])  # independent streams, not a copy
    # a run's draws are those of its row; a fixed campaign is the one batch (N,)
    assert batch_of(20, design) == (2, 16, 24) and batch_of(7, 8) == (0, 0, 8)
    assert design_batches(30) == (30,) and design_batches([8, 16]) == (8, 16)
    from cosim.verify.seeds import Stratified

    strat = (Stratified("dev", "bias", 2, True), Stratified("dev", "gain", 1, False))
    for i in (0, 9, 39):
        (_, _, zb), (_, _, zg) = stratified_draws(strat, design, SEED, i)
        assert (*zb, *zg) == tuple(z[i])
    assert stratified_draws(strat, 8, SEED, 3) == stratified_draws(strat, design, SEED, 3)
    with pytest.raises(ValueError, match="outside the stratified design of 40 runs"):
        stratified_draws(strat, design, SEED, 40)
    with pytest.raises(ValueError, match="increasing"):
        design_batches((8, 8))


def test_batch_rows_are_standard_normal() -> None:
    """Each row of each batch is N(0, 1) per component (its stratum and place are uniform).

    Over 400 campaign seeds, the draws at runs 0, 11 and 31 of the design (8, 16, 32) (one
    per batch) pass a Kolmogorov-Smirnov test against N(0, 1) at the 0.1 % level each, and
    their correlation across components is within 4 standard errors (4 / sqrt(400)) of 0.
    """
    rows = np.stack([design_draws((8, 16, 32), 2, s)[[0, 11, 31]] for s in range(400)])
    for k in range(3):
        for c in range(2):
            assert stats.kstest(rows[:, k, c], "norm").pvalue > 1e-3, (k, c)
        assert abs(np.corrcoef(rows[:, k, 0], rows[:, k, 1])[0, 1]) < 4 / math.sqrt(400)


# -------------------------------------------------------- the campaign on real runs
def test_the_refusal_is_gone_and_the_design_is_recorded(sequential) -> None:
    assert len(sequential.records) == 32
    seq = sequential.execution["sequential"]
    assert seq["looks"] == [8, 16, 32]
    assert seq["stratified"]["batches"] == [8, 16, 32]
    assert seq["stratified"]["parameters"] == ["dev.bias", "dev.gain"]
    design = json.loads((sequential.out_dir / SEQUENTIAL_FILE).read_text())
    assert design["stratified"] == seq["stratified"]
    assert json.loads((sequential.out_dir / MANIFEST).read_text())["strata"] == [8, 16, 32]
    assert sequential.settings.design == (8, 16, 32)
    # RMS-END decides at the first look; DRAWN stays undecided to the cap
    assert seq["requirements"]["RMS-END"]["look"] == 1
    assert seq["requirements"]["DRAWN"]["look"] is None


def test_the_runs_carry_the_batch_draws(sequential) -> None:
    """The drawn bias[1] of each run is 5' + 1' z_i, z the design (8, 16, 32), and each
    look batch of the campaign has one run in each of its strata."""
    z = drawn_z(sequential)
    np.testing.assert_allclose(z, design_draws((8, 16, 32), 3, SEED)[:, 0], rtol=0, atol=1e-9)
    for a, b in ((0, 8), (8, 16), (16, 32)):
        assert sorted(np.floor(ndtr(z[a:b]) * (b - a)).astype(int)) == list(range(b - a))


def test_first_look_equals_the_fixed_campaign_of_its_runs(scenario, sequential, tmp_path) -> None:
    """Runs 0 .. 7 are ``verify --runs 8`` run for run (seeds, metrics, histories)."""
    fixed = run_campaign(scenario, tmp_path / "fixed", runs=8, workers=1, progress=False)
    for a, b in zip(fixed.records, sequential.records[:8], strict=True):
        assert (a.index, a.seeds, a.metrics) == (b.index, b.seeds, b.metrics)
        for key in a.history:
            np.testing.assert_array_equal(a.history[key], b.history[key])
    # a fixed campaign of 16 runs is one hypercube over 16: not the second look's runs
    z16 = latin_hypercube_normal(16, 3, SEED)[:, 0]
    assert not np.allclose(drawn_z(sequential)[:16], z16, atol=1e-6)


def test_resume_continues_with_the_same_draws(scenario, sequential, tmp_path) -> None:
    """Runs 20 .. 31 lost (an interrupted third look): --resume makes the same runs."""
    import shutil

    out = tmp_path / "r"
    shutil.copytree(sequential.out_dir, out)
    for i in range(20, 32):
        for f in (out / "runs").glob(f"run_{i:05d}.*"):
            f.unlink()
    resumed = run_until_decided(scenario, out, resume=True, workers=1, progress=False)
    assert resumed.execution["runs_this_session"] == 12
    assert [r.metrics for r in resumed.records] == [r.metrics for r in sequential.records]
    # the design on disk is fixed: another cap is refused
    with pytest.raises(CampaignError, match="cannot resume: looks was"):
        run_until_decided(scenario, out, max_runs=64, resume=True, workers=1, progress=False)


def test_a_run_is_rerun_alone_with_its_batch_draws(scenario, sequential, tmp_path) -> None:
    alone = run_alone(scenario, tmp_path / "a", [21, 3], max_runs=32, workers=1, progress=False)
    assert [r.index for r in alone.records] == [3, 21]
    for rec in alone.records:
        assert rec.metrics == sequential.records[rec.index].metrics
    with pytest.raises(CampaignError, match="runs 0 to 31"):
        run_alone(scenario, tmp_path / "b", [32], max_runs=32, workers=1, progress=False)


def test_a_run_is_rerun_alone_from_the_command_line(scenario, sequential, tmp_path) -> None:
    """``verify --until-decided --max-runs 32 --only-run 21``: the campaign's run 21."""
    import csv
    import os

    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    )
    args = ["verify", scenario, "--until-decided", "--max-runs", 32, "--only-run", 21,
            "--workers", 1, "--no-progress", "--report", tmp_path / "cli"]  # fmt: skip
    proc = subprocess.run(
        [sys.executable, "-m", "cosim.cli", *map(str, args)],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr  # one run decides nothing
    with open(tmp_path / "cli" / "metrics.csv", newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert row["run"] == "21"
    assert float(row["DRAWN [arcmin]"]) == sequential.records[21].metrics["DRAWN"].value


def test_plan_predicts_the_looks_of_a_stratified_scenario(scenario) -> None:
    from cosim.verify.plan import format_plan, make_plan

    plan = make_plan(scenario, pilot=8, workers=1, max_runs=32, progress=False)
    assert plan.looks is not None and plan.looks.runs == (8, 16, 32)
    by_id = {p.id: p for p in plan.requirements}
    assert by_id["RMS-END"].sequential_runs == 8  # rms ~1.1' against 20': decided at once
    assert by_id["DRAWN"].sequential_runs is None  # max: not by 32 runs
    text = format_plan(plan)
    assert "--until-decided --runs 8 --max-runs 32" in text and "refused" not in text


# ------------------------------------------- the rule's error rate on batch designs
ALPHA = 0.05
M = 4000  # synthetic campaigns per case


def tolerance(alpha: float, m: int) -> float:
    """3-sigma binomial tolerance of a rate alpha estimated from m campaigns."""
    return 3.0 * math.sqrt(alpha * (1.0 - alpha) / m)


def batch_metrics(looks, a: float, scale: float, rng: np.random.Generator) -> tuple:
    """Metrics |scale (a z + b e)|, b = sqrt(1 - a^2), e independent: z from the batch
    design of the looks (campaign seeds 0 .. M - 1, the code verify runs) and, for the
    comparison, z independent. Both are |N(0, scale^2)| run by run."""
    b = math.sqrt(1.0 - a * a)
    z = np.stack([design_draws(looks.runs, 1, s)[:, 0] for s in range(M)])
    e = rng.standard_normal(z.shape)
    z_iid = rng.standard_normal(z.shape)
    return np.abs(scale * (a * z + b * e)), np.abs(scale * (a * z_iid + b * e))


def test_the_rule_keeps_its_error_rate_on_batch_designs() -> None:
    """True RMS 10 % above the limit (satisfied is wrong) and true p95 at the limit
    (violated is wrong), looks 20, 40, 80, 160, 320, metric spread 90 % from the draw."""
    from cosim.verify.bounds import rms_bounds
    from cosim.verify.statistics import wilks_lower_rank, wilks_upper_rank

    looks = plan_looks(20, 320)
    conf = looks.confidences(1 - ALPHA)
    rng = np.random.default_rng(15)
    tol = tolerance(ALPHA, M)

    def rms_wrong(m: np.ndarray) -> float:
        codes = np.zeros((M, len(looks.runs)), dtype=int)
        for j, (n, c) in enumerate(zip(looks.runs, conf, strict=True)):
            lower, upper = rms_bounds(m[:, :n], float(c))
            codes[:, j] = np.where(upper <= 1.0, 1, np.where(lower > 1.0, -1, 0))
        final, _ = first_decisions(codes)
        return float(np.mean(final == 1))

    def p95_wrong(m: np.ndarray, limit: float) -> float:
        codes = np.zeros((M, len(looks.runs)), dtype=int)
        for j, (n, c) in enumerate(zip(looks.runs, conf, strict=True)):
            up, lo = wilks_upper_rank(n, 0.95, float(c)), wilks_lower_rank(n, 0.95, float(c))
            k = np.sum(m[:, :n] <= limit, axis=1)
            sat = k >= up if up is not None else np.zeros(M, bool)
            vio = k <= lo - 1 if lo is not None else np.zeros(M, bool)
            codes[:, j] = np.where(sat, 1, np.where(vio, -1, 0))
        final, _ = first_decisions(codes)
        return float(np.mean(final == -1))

    lhs, iid = batch_metrics(looks, 0.95, 1.1, rng)
    r_lhs, r_iid = rms_wrong(lhs), rms_wrong(iid)
    assert r_lhs <= ALPHA + tol and r_lhs <= r_iid + tolerance(r_iid + 1e-3, M), (r_lhs, r_iid)
    lhs, iid = batch_metrics(looks, 0.95, 1.0, rng)
    limit = stats.norm.ppf(0.975)  # the p95 of |N(0, 1)|
    p_lhs, p_iid = p95_wrong(lhs, limit), p95_wrong(iid, limit)
    assert p_lhs <= ALPHA + tol and p_lhs <= p_iid + tolerance(p_iid, M), (p_lhs, p_iid)
