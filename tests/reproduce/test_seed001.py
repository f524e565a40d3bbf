"""Tests of the seed-001 reproduction (cosim/reproduce/seed001.py).

Default tests use few runs; the 30-run campaign, the sweeps and the full reproduction are
``@pytest.mark.slow`` (``make test-slow``). Every bound says where it comes from.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.alignment.transfer_analysis import transfer_covariance
from cosim.alignment.transfer_model import StateLayout
from cosim.models.constants import ARCMIN
from cosim.reproduce.seed001 import reproduce
from cosim.reproduce.seed001_runs import (
    HEADING_LIMIT,
    HEADINGS,
    LEVEL_TOL,
    SCENARIO,
    SEEDED,
    make_case,
    plan,
    run_cases,
    stats,
)
from cosim.reproductions import update_docs
from cosim.verify.campaign import CampaignError, campaign_jobs, prepare, run_campaign
from cosim.verify.records import decimation
from cosim.verify.seeds import latin_hypercube_normal

ROOT = Path(__file__).resolve().parents[2]


def test_run_seeds_follow_the_campaign_mapping() -> None:
    """Our runs use ``ins-cosim verify``'s seeds and draws: the scenario's own campaign."""
    prep = prepare(SCENARIO)
    assert tuple(prep.seeded) == SEEDED
    assert [(s.block, s.name, s.size) for s in prep.stratified] == [
        ("imu", "accel_bias", 3),
        ("imu", "gyro_bias", 3),
    ]
    jobs = campaign_jobs(prep, 2011, 30, indices=[0, 7])
    for job in jobs:
        i = job.index
        expected = np.random.SeedSequence(2011).spawn(30)[i].generate_state(3, np.uint32) >> 1
        assert list(job.seeds.values()) == [int(v) for v in expected]
        z = latin_hypercube_normal(30, 6, 2011)[i]
        assert job.stratified == (
            ("imu", "accel_bias", tuple(z[:3])),
            ("imu", "gyro_bias", tuple(z[3:])),
        )


def test_reset_between_runs_reproduces_a_run() -> None:
    """One built system, reset between runs: the same seeds give the same numbers, others not."""
    a, b, c = make_case("a"), make_case("b"), make_case("c")
    res = run_cases([(a, 0), (b, 1), (c, 0)], 5, stop=30.0)
    np.testing.assert_array_equal(res["a"][0].err, res["c"][0].err)
    np.testing.assert_array_equal(res["a"][0].sigma, res["c"][0].sigma)
    assert not np.allclose(res["a"][0].err[-1], res["b"][0].err[-1])


def test_stratified_case_gives_each_run_its_row_of_the_design() -> None:
    """Run i's true turn-on bias is sigma * row i of the design; nothing else changes."""
    sigma = float(prepare(SCENARIO).parameters["imu"]["accel_bias_sigma"])
    case = make_case("s", stratified=4)
    z = latin_hypercube_normal(4, 6, 9)
    res = run_cases([(case, 0), (case, 3)], 9, stop=1.0)
    for run in res["s"]:
        # accel_bias_b = turn-on bias + in-run random walk (5e-5 g/sqrt(Hz) over 1 s):
        # within 1e-3 sigma of the drawn value
        np.testing.assert_allclose(run.accel_bias, sigma * z[run.index, :3], atol=1e-3 * sigma)
    with pytest.raises(CampaignError, match="outside"):
        run_cases([(case, 4)], 9, stop=1.0)
    assert make_case("p", paper_sensor=True, stratified=4).stratified == 0
    assert all(c.stratified == 30 for c, _ in plan(30)["jobs"] if not c.name.startswith("paper"))


def test_a_run_alone_equals_that_run_of_the_campaign() -> None:
    """Run i of a stratified campaign alone (another process count) is run i of the whole."""
    case = make_case("m", stratified=30)
    whole = run_cases([(case, i) for i in range(3)], 2011, stop=10.0, workers=2)["m"]
    alone = run_cases([(case, 2)], 2011, stop=10.0)["m"][0]
    assert alone.index == whole[2].index == 2
    np.testing.assert_array_equal(alone.err, whole[2].err)
    np.testing.assert_array_equal(alone.accel_bias, whole[2].accel_bias)


def test_verify_only_run_is_the_reproduction_campaign_run(tmp_path: Path) -> None:
    """``ins-cosim verify --seed 2011 --runs 30 --only-run 1`` runs the campaign's run 1."""
    camp = run_campaign(
        SCENARIO, tmp_path, runs=30, seed=2011, workers=1, progress=False, only_runs=[1]
    )
    (rec,) = camp.records
    run = run_cases([(make_case("campaign modelled", stratified=30), 1)], 2011)[
        "campaign modelled"
    ][0]
    assert rec.index == 1 and rec.seeds == dict(zip(SEEDED, rec.seeds.values(), strict=True))
    idx = decimation(len(run.time), 601)
    np.testing.assert_array_equal(rec.history["time"], run.time[idx])
    heading = [k for k, r in enumerate(camp.requirements) if r.id == "TA-HDG-1"][0]
    np.testing.assert_array_equal(rec.history[f"e_{heading}"], run.err[idx, 2])
    largest = float(np.max(np.abs(run.err[run.window(30.0), 2])))
    assert rec.metrics["TA-HDG-1"].value == pytest.approx(largest, rel=1e-12)


def test_short_campaign_meets_the_requirements() -> None:
    """Fast version of acceptance 1: 3 runs instead of 30.

    Heading RMS from 30 s <= 7' (the 30-run campaign gives about 3'). Level: RMS error over
    RMS sigma in [0.25, 1.8], the central 95 % of ``sqrt(chi2_3 / 3)`` for a consistent
    filter (each run's level error is essentially one draw of its bias: 3 degrees of
    freedom); the 30-run test narrows this to the acceptance's +-25 %.
    """
    res = run_cases([(make_case("m"), i) for i in range(3)], 2011)
    s = stats(res["m"])
    assert s.rms[2] <= HEADING_LIMIT
    assert np.all((s.level_ratio >= 0.25) & (s.level_ratio <= 1.8))


def test_largest_initial_heading_error_converges() -> None:
    """Fast version of acceptance 4: the 180 deg case (the hardest), one run.

    Heading RMS from 30 s and the final heading error within 7'.
    """
    res = run_cases([(make_case("h180", heading_deg=180.0), 0)], 2011)
    run = res["h180"][0]
    assert abs(run.err[0, 2]) > 170 * 60
    assert run.rms()[2] <= HEADING_LIMIT
    assert abs(run.final[2]) <= HEADING_LIMIT


def test_digest_flexure_is_too_small_to_matter() -> None:
    """Fast version of acceptance 2 at the digest's 2' flexure: modelled and ignored agree.

    Same run (same flexure, sensor and master noise): the flexure's lever-arm velocity,
    below 1 mm/s on the 10 m arm, is under the 10 mm/s velocity-matching noise, and the
    slave's gyros follow the flexure in both filters; heading RMS ratio within 1 +- 0.25
    (30-run campaign: 0.97). The large-flexure case, where ignoring it fails, is in
    tests/alignment/test_transfer.py.
    """
    res = run_cases([(make_case("m"), 0), (make_case("i", flexure_states=0), 0)], 2011)
    ratio = res["i"][0].rms()[2] / res["m"][0].rms()[2]
    assert abs(ratio - 1.0) <= 0.25


def test_lever_arm_sets_heading_observability() -> None:
    """Fast version of acceptance 3: the covariance analysis over the lever arm, one run at 40 m.

    Without a lever arm the moored ship gives no horizontal specific force at the slave and
    the heading comes from gyrocompassing only: its sigma from 30 s on stays above the 7'
    requirement. The heading sigma falls with the arm (the heading signal is the lever-arm
    velocity, proportional to L). One run at L = 40 m: heading RMS within 3 times the
    analysis' RMS sigma.
    """
    rms_sigma = {}
    for a in (0.0, 10.0, 40.0):
        h = transfer_covariance(120.0, r0=(a, a, 0.5 * a), dt=0.5)
        m = h.time >= 30.0
        heading = h.sigma[m, StateLayout.heading] / ARCMIN
        rms_sigma[a] = float(np.sqrt(np.mean(heading**2)))
    assert rms_sigma[0.0] > HEADING_LIMIT
    assert rms_sigma[0.0] > rms_sigma[10.0] > rms_sigma[40.0]
    res = run_cases([(make_case("l40", lever=40.0), 0)], 2011)
    assert res["l40"][0].rms()[2] <= 3.0 * rms_sigma[40.0]


def test_plan_shares_the_scenario_configuration() -> None:
    """The sweeps reuse the campaign's runs where their configuration is the scenario's."""
    p = plan(30)
    names = [c.name for c, _ in p["jobs"]]
    assert names.count("campaign modelled") == 30
    assert "heading 30" not in names and "lever 10 flexure 2 modelled" not in names
    assert len(p["jobs"]) == len(set((c.name, i) for c, i in p["jobs"]))
    assert p["alias"]["heading 30"] == ("campaign modelled", 10)


# ----------------------------------------------------------------------------- slow
@pytest.mark.slow
def test_campaign_of_30_runs_acceptance_1() -> None:
    """Acceptance 1: 30 runs (the README's campaign seed), flexure modelled, as reproduced.

    Heading RMS from 30 s <= 7'. Level: RMS error within 25 % of the filter's RMS sigma,
    with the turn-on bias and drift stratified over the 30 runs (:func:`sensor_draws`, as
    in :func:`plan`): the level error is mostly the drawn bias over g, so independent
    draws would move the ratio by +-13 % (1 sigma, ``sqrt(chi2_30 / 30)``) with the luck
    of the draw (seed 2011 drew x biases of RMS 1.30 sigma: pitch ratio 1.28); stratified,
    each axis's drawn RMS spreads by about 4 % (1 sigma). Per unit of drawn bias as well.
    """
    res = run_cases([(make_case("m", stratified=30), i) for i in range(30)], 2011, workers=2)
    s = stats(res["m"])
    assert s.rms[2] <= HEADING_LIMIT
    assert np.all(np.abs(s.bias_draw - 1.0) <= 0.06)  # this design: 0.98, 0.96, 1.01
    assert np.all(np.abs(s.level_ratio - 1.0) <= LEVEL_TOL)
    assert np.all(np.abs(s.level_ratio_per_draw - 1.0) <= LEVEL_TOL)


@pytest.mark.slow
def test_ignoring_a_large_flexure_campaign() -> None:
    """Acceptance 2 where the flexure matters (sigma 30'), 10 runs each on the same seeds.

    The ignored filter is inconsistent (largest RMS error / RMS sigma above 2) and its
    heading is worse than the modelled one's; the modelled one stays consistent (<= 1.5).
    """
    big = {"flex": {"sigma": [30 * math.pi / 180 / 60] * 3}}
    big["align"] = {"flexure_sigma": big["flex"]["sigma"]}
    cases = [make_case("m", extra=big), make_case("i", flexure_states=0, extra=big)]
    res = run_cases([(c, i) for c in cases for i in range(10)], 2011, workers=2)
    m, i = stats(res["m"]), stats(res["i"])
    assert np.max(i.rms / i.sigma) > 2.0
    assert np.max(m.rms / m.sigma) <= 1.5
    assert i.rms[2] > m.rms[2]


@pytest.mark.slow
def test_heading_sweep_acceptance_4() -> None:
    """Acceptance 4: initial heading 0 to 180 deg in 30 deg steps, 5 runs each, RMS <= 7'."""
    cases = [make_case(f"h{h:g}", heading_deg=h) for h in HEADINGS]
    res = run_cases([(c, i) for c in cases for i in range(5)], 2011, workers=2)
    for c in cases:
        assert stats(res[c.name]).rms[2] <= HEADING_LIMIT, c.name


@pytest.mark.slow
def test_lever_arm_sweep_acceptance_3() -> None:
    """Acceptance 3: lever arms 10, 20, 40 m, flexure 10' modelled and ignored, 6 runs each.

    Modelled: the heading RMS falls as the arm grows. The flexure's cost grows with the arm:
    at 40 m the ignored filter is inconsistent (largest RMS error / RMS sigma above 1.5)
    and worse than the modelled one.
    """
    ten = {"flex": {"sigma": [10 * math.pi / 180 / 60] * 3}}
    ten["align"] = {"flexure_sigma": ten["flex"]["sigma"]}
    cases = {
        (a, f): make_case(f"{a} {f}", flexure_states=f, lever=a, extra=ten)
        for a in (10.0, 20.0, 40.0)
        for f in (1, 0)
    }
    res = run_cases([(c, i) for c in cases.values() for i in range(6)], 2011, workers=2)
    s = {k: stats(res[c.name]) for k, c in cases.items()}
    assert s[(10.0, 1)].rms[2] > s[(20.0, 1)].rms[2] > s[(40.0, 1)].rms[2]
    assert np.max(s[(40.0, 0)].rms / s[(40.0, 0)].sigma) > 1.5
    assert np.linalg.norm(s[(40.0, 0)].rms) > np.linalg.norm(s[(40.0, 1)].rms)


@pytest.mark.slow
def test_reproduce_writes_the_readme_block(tmp_path: Path) -> None:
    """The whole reproduction with one run per point: tables, plots, README markers."""
    md = reproduce(tmp_path, runs=1, seed=2011, workers=2)
    for title in ("Table 1 of seed 001", "Flexure modelled against ignored", "Lever-arm sweep",
                  "Initial heading misalignment sweep", "Linear covariance analysis"):  # fmt: skip
        assert title in md
    for png in ("modelled_vs_ignored", "lever_arm", "heading_sweep"):
        assert (tmp_path / f"seed001_{png}.png").stat().st_size > 10_000
    page = tmp_path / "reproductions.md"
    page.write_text("# Reproductions\n<!-- seed001:begin -->\nold\n<!-- seed001:end -->\n")
    update_docs(page, "seed001", md)
    assert "Table 1 of seed 001" in page.read_text() and "old" not in page.read_text()
