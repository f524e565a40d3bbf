"""Campaigns with real runs: seeds, workers, Dask, failing runs, resume."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from cosim.errors import ScenarioError
from cosim.verify.campaign import CampaignError, campaign_jobs, prepare, run_campaign
from cosim.verify.records import read_records
from cosim.verify.requirements import SATISFIED, UNDECIDED, VIOLATED
from cosim.verify.seeds import latin_hypercube_normal, run_seeds
from cosim.verify.workers import Job, WorkerSpec, release_worker_state, run_one

TESTS = Path(__file__).resolve().parents[1]
ROOT = TESTS.parent
DEMO = ROOT / "scenarios" / "demo_verify.toml"


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def assert_same_runs(a, b) -> None:
    """Same seeds, status, metrics and histories, run by run (bit for bit)."""
    assert len(a.records) == len(b.records)
    for ra, rb in zip(a.records, b.records, strict=True):
        assert (ra.index, ra.seeds, ra.status, ra.error) == (
            rb.index,
            rb.seeds,
            rb.status,
            rb.error,
        )
        assert ra.metrics == rb.metrics
        assert sorted(ra.history) == sorted(rb.history)
        for key in ra.history:
            np.testing.assert_array_equal(ra.history[key], rb.history[key])


def assert_judged_from_the_saved_runs(campaign) -> None:
    """The records a campaign judged are the ones on disk, field by field (it no longer
    reads them back)."""
    on_disk = read_records(campaign.out_dir / "runs")
    assert set(on_disk) >= {r.index for r in campaign.records}
    for r in campaign.records:
        saved = on_disk[r.index]
        assert r.to_dict() == saved.to_dict()
        assert (r.tag, r.columns, r.parameters) == (saved.tag, saved.columns, saved.parameters)
        assert sorted(r.history) == sorted(saved.history)
        for key, values in saved.history.items():
            assert r.history[key].dtype == values.dtype
            np.testing.assert_array_equal(r.history[key], values)


@pytest.fixture(scope="module")
def pool_campaign(tmp_path_factory: pytest.TempPathFactory):
    """The demo verification campaign (20 runs) on 2 worker processes."""
    return run_campaign(DEMO, tmp_path_factory.mktemp("pool"), workers=2, progress=False)


def test_seeds_derive_from_the_campaign_seed_by_spawning() -> None:
    blocks = ["flexure", "sensor"]
    children = np.random.SeedSequence(2024).spawn(20)
    for i in (0, 7, 19):
        state = children[i].generate_state(2, dtype=np.uint32)
        expected = {"flexure": int(state[0]) >> 1, "sensor": int(state[1]) >> 1}
        assert run_seeds(2024, i, blocks) == expected
    # A run's seeds do not depend on the number of runs, and fit an FMI Integer.
    assert run_seeds(2024, 7, blocks) == {
        b: int(s) >> 1
        for b, s in zip(
            blocks,
            np.random.SeedSequence(2024).spawn(500)[7].generate_state(2, np.uint32),
            strict=True,
        )
    }
    seeds = [s for i in range(200) for s in run_seeds(1, i, blocks).values()]
    assert len(set(seeds)) == len(seeds) and max(seeds) < 2**31


def test_latin_hypercube_puts_one_run_in_each_stratum() -> None:
    """Every column of the design has exactly one run in each probability stratum 1/N."""
    from scipy.special import ndtr

    z = latin_hypercube_normal(30, 6, 2011)
    assert z.shape == (30, 6)
    for col in z.T:
        assert sorted(np.floor(ndtr(col) * 30).astype(int)) == list(range(30))
    np.testing.assert_array_equal(z, latin_hypercube_normal(30, 6, 2011))
    assert not np.allclose(z, latin_hypercube_normal(30, 6, 2011, stream=1))
    assert not np.allclose(z, latin_hypercube_normal(30, 6, 2012))


def test_latin_hypercube_pins_the_sample_spread() -> None:
    """Over 400 designs of 30 runs: rows are N(0, 1) and the mean square spreads far less.

    Independent draws: the mean square of 30 N(0, 1) has std sqrt(2/30) = 0.258. The
    stratified design leaves mostly the two tail strata's spread: std about 0.09; the bound
    0.13 is half the independent value. Unbiased: the mean of the 400 mean squares is 1
    within 4 of its standard errors (0.09 / sqrt(400) = 0.0045 -> 0.02), the pooled mean 0
    within 4 standard errors (1 / sqrt(12000) -> 0.037).
    """
    z = np.stack([latin_hypercube_normal(30, 1, s)[:, 0] for s in range(400)])
    ms = np.mean(z**2, axis=1)
    assert np.std(ms) < 0.13
    assert abs(np.mean(ms) - 1.0) < 0.02
    assert abs(np.mean(z)) < 0.037


@pytest.mark.parametrize("args", [(0, 3, 1), (3, 0, 1), (3, 3, -1)])
def test_latin_hypercube_refuses_bad_sizes(args: tuple[int, int, int]) -> None:
    with pytest.raises(ValueError, match="expected"):
        latin_hypercube_normal(*args)


def test_process_pool_equals_one_process_and_each_run_alone(pool_campaign, tmp_path) -> None:
    serial = run_campaign(DEMO, tmp_path, workers=1, progress=False)
    assert_same_runs(pool_campaign, serial)
    assert_judged_from_the_saved_runs(pool_campaign)
    assert_judged_from_the_saved_runs(serial)
    assert (tmp_path / "metrics.csv").read_text() == (
        pool_campaign.out_dir / "metrics.csv"
    ).read_text()
    # both worker processes did work, each having built the blocks once
    assert len({r.worker for r in pool_campaign.records}) == 2
    # seeds are the documented ones, and differ between runs
    assert pool_campaign.records[7].seeds == run_seeds(2024, 7, ["flexure", "sensor"])
    assert pool_campaign.records[0].seeds != pool_campaign.records[1].seeds
    # any run reproduces alone, in a fresh worker state
    prep = prepare(DEMO)
    spec = WorkerSpec(str(DEMO), prep.scenario.sha256, None, tuple(prep.requirements), 400)
    release_worker_state()
    try:
        alone = run_one(spec, Job(13, pool_campaign.records[13].seeds))
    finally:
        release_worker_state()
    assert alone.metrics == pool_campaign.records[13].metrics
    # the demo's verdicts (the scenario is chosen so that all are satisfied)
    assert [v.verdict for v in pool_campaign.verdicts] == [SATISFIED] * 3
    table = rows(pool_campaign.out_dir / "metrics.csv")
    assert len(table) == 20 and table[0]["status"] == "completed"
    assert float(table[0]["DEMO-1 [arcmin]"]) == pool_campaign.records[0].metrics["DEMO-1"].value


def test_dask_local_cluster_gives_the_same_metrics(pool_campaign, tmp_path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        campaign = run_campaign(DEMO, tmp_path, cluster=cluster.scheduler_address, progress=False)
    assert campaign.execution["cluster"].startswith("tcp://127.0.0.1:")
    assert_same_runs(pool_campaign, campaign)
    assert (tmp_path / "metrics.csv").read_text() == (
        pool_campaign.out_dir / "metrics.csv"
    ).read_text()


def failing_scenario(tmp_path: Path, fmu: Path, failing_run: int) -> Path:
    fail_seed = run_seeds(5, failing_run, ["filter"])["filter"]
    text = f"""
[master]
step = "10 ms"
stop = "3 s"

[blocks.filter]
fmu = "{fmu}"

[blocks.filter.parameters]
sigma0 = "10 arcmin"
tau = "0.5 s"
noise = "0.05 arcmin"
fail_seed = {fail_seed}
fail_time = "1.5 s"

[campaign]
runs = 8
seed = 5

[[requirements]]
id = "ALIGN-1"
text = "settles within 1 arcmin in 2.5 s"
signal = "filter.error"
sigma = "filter.sigma"
unit = "arcmin"
criterion = "settling"
band = "1 arcmin"
within = "2.5 s"
probability = 0.6  # 7 passing runs show the 60 % quantile at 1 - 0.6^7 = 97 % confidence

[[requirements]]
id = "ALIGN-2"
text = "within 1 arcmin from 2 s on, judged on the completed runs"
signal = "filter.error"
unit = "arcmin"
criterion = "bound"
bound = "1 arcmin"
from = "2 s"
probability = 0.6
on_failure = "exclude"

[[requirements]]
id = "ALIGN-3"
text = "final error below 0.5 arcmin, a failed run counts as failing"
signal = "filter.error"
unit = "arcmin"
criterion = "value"
bound = "0.5 arcmin"
on_failure = "fail"
"""
    path = tmp_path / "failing.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def converging_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``testblocks.Converging`` (a stand-in alignment filter) as an FMU."""
    from testblocks import Converging

    from cosim.interop.packaging import build_fmu

    out = tmp_path_factory.mktemp("converging")
    return build_fmu(Converging, out, extra_files=(TESTS / "testblocks.py",))


@pytest.mark.parametrize("workers", [2, 1])
def test_a_failing_fmu_run_is_recorded_and_the_campaign_goes_on(
    tmp_path: Path, converging_fmu: Path, workers: int
) -> None:
    scenario = failing_scenario(tmp_path, converging_fmu, failing_run=3)
    campaign = run_campaign(scenario, tmp_path / "out", workers=workers, progress=False)
    status = [r.status for r in campaign.records]
    assert status == ["completed"] * 3 + ["failed"] + ["completed"] * 4
    failed = campaign.records[3]
    assert "block 'filter'" in failed.error and "fmi2DoStep" in failed.error
    assert "t = 1.5 s" in failed.error
    assert failed.history["time"][-1] == pytest.approx(1.5)  # partial history kept
    assert all(m is None for m in failed.metrics.values())
    assert_judged_from_the_saved_runs(campaign)
    v1, v2, v3 = campaign.verdicts
    # default: undecided, saying which run failed and what the completed runs show
    assert v1.verdict == UNDECIDED and "run(s) 3" in v1.reason
    assert v1.details["judged_on_completed_runs"] == SATISFIED
    # exclude: judged on the 7 completed runs
    assert v2.verdict == SATISFIED and (v2.n_used, v2.n_failed) == (7, 1)
    # fail: the failed run fails the requirement
    assert v3.verdict == VIOLATED
    assert campaign.exit_code == 1
    table = rows(tmp_path / "out" / "metrics.csv")
    assert table[3]["status"] == "failed" and "fmi2DoStep" in table[3]["error"]
    assert table[3]["ALIGN-2 [arcmin]"] == "" and table[4]["ALIGN-2 pass"] == "1"
    # the runs after the failure (same worker, blocks reset) match a clean run of them
    clean = run_campaign(
        failing_scenario(tmp_path, converging_fmu, failing_run=99),
        tmp_path / "clean",
        workers=1,
        progress=False,
    )
    for i in (0, 4, 7):
        assert clean.records[i].metrics == campaign.records[i].metrics


def test_resume_runs_only_what_is_missing(tmp_path: Path) -> None:
    first = run_campaign(DEMO, tmp_path, runs=6, workers=1, progress=False)
    reference = (tmp_path / "metrics.csv").read_text()
    for i in (2, 4):
        (tmp_path / "runs" / f"run_{i:05d}.json").unlink()
    (tmp_path / "runs" / ".run_00004.npz.tmp").write_bytes(b"half-written")
    assert sorted(read_records(tmp_path / "runs")) == [0, 1, 3, 5]
    resumed = run_campaign(DEMO, tmp_path, resume=True, workers=1, progress=False)
    assert resumed.execution["runs_this_session"] == 2 and resumed.settings.runs == 6
    assert (tmp_path / "metrics.csv").read_text() == reference
    assert_same_runs(first, resumed)
    assert_judged_from_the_saved_runs(resumed)
    assert not list((tmp_path / "runs").glob(".*.tmp"))
    # --runs may grow a campaign: runs 0..5 are kept, 6..7 are new
    grown = run_campaign(DEMO, tmp_path, runs=8, resume=True, workers=1, progress=False)
    assert grown.execution["runs_this_session"] == 2
    # refusing to mix campaigns
    with pytest.raises(CampaignError, match="seed was 2024, now 1"):
        run_campaign(DEMO, tmp_path, seed=1, resume=True, workers=1, progress=False)
    with pytest.raises(CampaignError, match="can add runs, not remove"):
        run_campaign(DEMO, tmp_path, runs=3, resume=True, workers=1, progress=False)
    with pytest.raises(CampaignError, match="no campaign to resume"):
        run_campaign(DEMO, tmp_path / "empty", resume=True, workers=1, progress=False)
    # without --resume the folder starts over
    again = run_campaign(DEMO, tmp_path, runs=2, workers=1, progress=False)
    assert again.execution["runs_this_session"] == 2
    assert sorted(read_records(tmp_path / "runs")) == [0, 1]


def test_randomize_keeps_the_file_seed_of_other_blocks(tmp_path: Path) -> None:
    text = DEMO.read_text().replace('randomize = ["flexure", "sensor"]', 'randomize = ["sensor"]')
    path = tmp_path / "s.toml"
    path.write_text(text)
    campaign = run_campaign(path, tmp_path / "out", runs=3, workers=1, progress=False)
    assert all(set(r.seeds) == {"sensor"} for r in campaign.records)
    # the flexure truth is the same in every run (its file seed), the sensor noise is not
    e = [r.history["e_0"] for r in campaign.records]
    assert not np.array_equal(e[0], e[1])
    assert campaign.provenance["file_seeds"]["flexure"] == 7


@pytest.mark.parametrize(
    "campaign_table, key, fragment",
    [
        ("runs = 0", "campaign.runs", "integer >= 1"),
        ("seed = -1", "campaign.seed", "integer >= 0"),
        ("rnus = 3", "campaign.rnus", "Did you mean 'runs'"),
        ("randomize = ['sensr']", "campaign.randomize[0]", "no seed parameter"),
        ("on_failure = 'skip'", "campaign.on_failure", "'exclude'"),
    ],
)
def test_bad_campaign_table(tmp_path: Path, campaign_table: str, key: str, fragment: str) -> None:
    text = DEMO.read_text()
    start = text.index("[campaign]")
    end = text.index("[[requirements]]")
    path = tmp_path / "bad.toml"
    path.write_text(text[:start] + f"[campaign]\n{campaign_table}\n\n" + text[end:])
    with pytest.raises(ScenarioError) as info:
        run_campaign(path, tmp_path / "out", workers=1, progress=False)
    assert str(path) in str(info.value) and key in str(info.value)
    assert fragment in str(info.value)


def test_a_scenario_without_requirements_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match=r"key 'requirements'.*no requirements"):
        run_campaign(ROOT / "scenarios" / "demo.toml", tmp_path, workers=1, progress=False)


# ----------------------------------------------------------------------- the one seed rule
#: Seeds the runners before the one engine gave, as literal numbers (seed 000's
#: ``run_seeds(2024, i)``, seed 001's ``run_seeds(2011, i)``, seed 003's ``_seeds`` of
#: base, imu, align at 2024 and the verify campaign's of flexure, sensor at 2024).
HRG = ("gyro", "accel", "filter", "truth")
OLD_SEEDS = [
    (2024, 0, HRG, (1427649267, 462515364, 1033992852, 1785329617)),
    (2024, 7, HRG, (184274787, 1115197804, 827982798, 716376889)),
    (2024, 29, HRG, (1644296582, 236043143, 1040755436, 1027887620)),
    (2011, 0, ("flex", "imu", "master"), (779035943, 857496566, 749523806)),
    (2011, 7, ("flex", "imu", "master"), (735736606, 1729268132, 751260297)),
    (2011, 29, ("flex", "imu", "master"), (858347003, 848765987, 1278633035)),
    (2024, 49, ("base", "imu", "align"), (924981200, 1107026240, 1843027452)),
    (2024, 7, ("flexure", "sensor"), (184274787, 1115197804)),
]  # fmt: skip


@pytest.mark.parametrize("seed, index, names, expected", OLD_SEEDS)
def test_the_one_seed_rule_keeps_every_old_runner_seed(seed, index, names, expected) -> None:
    assert run_seeds(seed, index, names) == dict(zip(names, expected, strict=True))
    # a stream appended after the blocks leaves their seeds alone (seed 000's truth)
    assert run_seeds(seed, index, names[:2]) == dict(zip(names[:2], expected[:2], strict=True))


def test_the_stratified_design_keeps_the_old_seed001_draws() -> None:
    """Rows 0, 7, 29 of seed 001's ``sensor_draws(2011, 30)`` (accel x, y, z, gyro x, y, z)."""
    z = latin_hypercube_normal(30, 6, 2011)
    assert z[0].tolist() == [
        0.056708497084157455, -0.23986205378877606, -0.6295455033186849,
        1.6166255989358058, 0.8104671218017474, 0.31280263747332265,
    ]  # fmt: skip
    assert z[7].tolist() == [
        0.6044910635079676, 0.6575722557966909, 2.555745794888638,
        0.762848453250819, -0.1261011163380491, 0.5021920958661085,
    ]  # fmt: skip
    assert z[29].tolist() == [
        -0.2902891882598529, -0.298701748414455, 0.6735190943150219,
        -0.048349348576533877, -2.0324889867874285, -0.4255833053843837,
    ]  # fmt: skip


def test_only_run_reruns_a_run_alone_with_its_numbers(pool_campaign, tmp_path) -> None:
    alone = run_campaign(DEMO, tmp_path, workers=1, progress=False, only_runs=[13, 4])
    assert [r.index for r in alone.records] == [4, 13]
    for rec in alone.records:
        whole = pool_campaign.records[rec.index]
        assert (rec.seeds, rec.metrics) == (whole.seeds, whole.metrics)
        for key in whole.history:
            np.testing.assert_array_equal(rec.history[key], whole.history[key])
    assert alone.execution["only_runs"] == [4, 13]
    with pytest.raises(CampaignError, match="runs 0 to 19"):
        run_campaign(DEMO, tmp_path, workers=1, progress=False, only_runs=[20])
    with pytest.raises(CampaignError, match="cannot be resumed"):
        run_campaign(DEMO, tmp_path, workers=1, progress=False, resume=True)


def stratified_scenario(tmp_path: Path, stratify: str) -> Path:
    """The seed 003 static scenario, 1 s long, with a ``[campaign] stratify`` line."""
    text = (ROOT / "scenarios" / "sins_north_finding.toml").read_text()
    text = text.replace("[campaign]\n", f"[campaign]\n{stratify}\n", 1)
    path = tmp_path / "stratified.toml"
    path.write_text(text)
    return path


def test_stratify_draws_the_parameters_from_one_design(tmp_path: Path) -> None:
    from cosim.verify.campaign import simulate

    path = stratified_scenario(tmp_path, 'stratify = ["imu.accel_bias", "imu.gyro_bias"]')
    prep = prepare(path)
    assert [(s.block, s.name, s.size) for s in prep.stratified] == [
        ("imu", "accel_bias", 3),
        ("imu", "gyro_bias", 3),
    ]
    imu = prep.parameters["imu"]
    z = latin_hypercube_normal(5, 6, 3)
    records = simulate(prep, campaign_jobs(prep, 3, 5, indices=[0, 4]), stop=0.1)
    for rec in records:
        p = rec.parameters["imu"]
        assert p["accel_bias_sigma"] == p["gyro_bias_sigma"] == 0.0
        for k in range(3):
            fixed = imu.get(f"accel_bias[{k + 1}]", 0.0)
            assert p[f"accel_bias[{k + 1}]"] == fixed + imu["accel_bias_sigma"] * z[rec.index, k]
            fixed = imu.get(f"gyro_bias[{k + 1}]", 0.0)
            assert p[f"gyro_bias[{k + 1}]"] == fixed + imu["gyro_bias_sigma"] * z[rec.index, 3 + k]
    # without stratify the IMU draws from its seed, and the campaign sets no bias
    plain = simulate(prep, campaign_jobs(prep, 3, 5, indices=[0], stratify=False), stop=0.1)
    assert plain[0].parameters["imu"]["accel_bias_sigma"] == imu["accel_bias_sigma"] > 0.0
    # a stratified campaign cannot change its run count on --resume
    run_campaign(path, tmp_path / "r", runs=2, workers=1, progress=False)
    with pytest.raises(CampaignError, match="cannot change the design"):
        run_campaign(path, tmp_path / "r", runs=3, resume=True, workers=1, progress=False)


@pytest.mark.parametrize(
    "line, key, fragment",
    [
        ("stratify = 'imu.accel_bias'", "campaign.stratify", "list of 'block.parameter'"),
        ("stratify = ['accel_bias']", "campaign.stratify", "list of 'block.parameter'"),
        ("stratify = ['imu.seed']", "campaign.stratify[0]", "sibling 'seed_sigma'"),
        ("stratify = ['nope.accel_bias']", "campaign.stratify[0]", "sibling"),
    ],
)
def test_bad_stratify(tmp_path: Path, line: str, key: str, fragment: str) -> None:
    with pytest.raises(ScenarioError) as info:
        prepare(stratified_scenario(tmp_path, line))
    assert key in str(info.value) and fragment in str(info.value)
