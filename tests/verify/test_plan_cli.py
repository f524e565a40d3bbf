"""``ins-cosim plan`` and ``verify --until-decided`` end to end (issue 15, item 2).

One cheap scenario (the demo's flexure and sensor, 6 s simulated, no FMU) with two
pass-rate requirements whose runs all pass: their decisions follow from Clopper-Pearson
arithmetic alone. With n runs all passing, the lower bound at confidence c is
``(1 - c)^(1/n)``. Looks 10, 20, 40, 80 (``--runs 10 --max-runs 80``) spend
alpha = 0.05 as 0.05 x (10, 10, 20, 40) / 80:

- RATE-50 (probability 0.5): look 1, 0.00625^(1/10) = 0.60 >= 0.5: decided at 10 runs;
- RATE-85 (probability 0.85): look 2, 0.00625^(1/20) = 0.776 < 0.85; look 3,
  0.0125^(1/40) = 0.896 >= 0.85: decided at 40 runs, and the campaign stops there,
  before its cap of 80. (Naive re-testing at 95 % would stop at 20: 0.05^(1/20) = 0.861.)

A fixed campaign at 95 % needs n >= ln 0.05 / ln P runs, all passing: 5 runs for P = 0.5
(the pilot's first 5 runs decide RATE-50: what ``plan`` prints), 19 for 0.85. The 10-run
pilot leaves RATE-85 undecided. Its one-sided 80 % Clopper-Pearson lower bound,
0.2^(1/10) = 0.8513, lies above 0.85 by so little that no run count up to 10 000 decides
80 % of campaigns at it, so no number of runs is promised (cosim/verify/advice.py): ``plan``
prints "(19)", the runs that decide it if the true pass rate is the pilot's 1 (19 runs,
all passing), with a note saying so; ``verify --runs 10`` advises the same.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parents[1]

SCENARIO = """
connections = ["flexure.x -> sensor.u"]

[scenario]
name = "tiny_rates"

[master]
step = "10 ms"
stop = "6 s"

[blocks.flexure]
model = "GaussMarkov2"
parameters = { tau = "60 s", sigma = "2 arcmin", seed = 7 }

[blocks.sensor]
model = "FirstOrderSensor"
[blocks.sensor.parameters]
time_constant = "50 ms"
bias = "0.5 arcmin"
noise_density = "0.01 arcmin/sqrt(Hz)"
seed = 11

[output]
variables = ["flexure", "sensor"]

[campaign]
runs = 10
seed = 2024
randomize = ["flexure", "sensor"]
history_points = 50
"""
REQUIREMENT = """
[[requirements]]
id = "{id}"
signal = "sensor.m"
minus = "flexure.x"
unit = "arcmin"
criterion = "bound"
bound = "1 arcmin"
from = "5 s"
statistic = "pass_rate"
probability = {p}
confidence = 0.95
"""


def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    reqs = "".join(REQUIREMENT.format(id=i, p=p) for i, p in (("RATE-50", 0.5), ("RATE-85", 0.85)))
    path.write_text(SCENARIO + reqs)
    return path


def env() -> dict[str, str]:
    return dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    )


def command(*args: object) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", *map(str, args)]


def run(tmp_path: Path, *args: object) -> subprocess.CompletedProcess:
    return subprocess.run(
        command(*args), capture_output=True, text=True, env=env(), cwd=tmp_path, timeout=300
    )


def row(text: str, rid: str) -> list[str]:
    """The cells of a requirement's row (columns are two or more spaces apart)."""
    lines = [ln for ln in text.splitlines() if ln.startswith(rid + " ")]
    assert len(lines) == 1, text
    return re.split(r"\s{2,}", lines[0].strip())


def test_plan_prints_runs_and_time_per_requirement(tmp_path: Path) -> None:
    res = run(tmp_path, "plan", tiny(tmp_path), "--pilot", 10, "--workers", 1, "--max-runs", 80,
              "--no-progress")  # fmt: skip
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "pilot: 10 runs of 'tiny_rates' (campaign seed 2024, runs 0 to 9)" in out
    assert "s per run and worker" in out and "runs to decide" in out
    a, b = row(out, "RATE-50"), row(out, "RATE-85")
    # id, statistic, pilot value, pilot bounds, limit, pilot verdict, runs to decide,
    # verdict then, wall time, --until-decided runs and wall time. 10 of 10 pilot runs
    # pass: Clopper-Pearson bounds [0.05^(1/10), 1] = [0.7411, 1].
    assert a[1:8] == ["pass_rate (95 %)", "1", "[0.7411, 1]", "0.5", "satisfied", "5", "satisfied"]
    assert b[1:8] == [
        "pass_rate (95 %)",
        "1",
        "[0.7411, 1]",
        "0.85",
        "undecided",
        "(19)",
        "satisfied",
    ]
    assert a[9].startswith("10 runs, ") and b[9].startswith("40 runs, "), (a, b)
    assert "note: RATE-85: the pilot cannot exclude a true pass rate at the limit" in out
    assert "only if the true pass rate is 1 (the pilot's estimate)" in out
    assert b[8].endswith((" s", " min")) and float(b[8].split()[0]) > 0
    assert "--until-decided --runs 10 --max-runs 80" in out.replace("\n", " ")
    assert not list(tmp_path.glob("ins-cosim-plan-*")), "the pilot folder is removed"
    # issue 27, acceptance 4: verify on the same 10 runs advises the same number
    verify = run(tmp_path, "verify", tmp_path / "tiny.toml", "--runs", 10, "--workers", 1,
                 "--report", tmp_path / "v", "--no-progress")  # fmt: skip
    assert verify.returncode == 2, verify.stderr  # RATE-85 undecided
    advised = re.search(r"RATE-85: .*about (\d+) runs in total \((\d+) more\)", verify.stdout)
    assert advised, verify.stdout
    assert f"({advised.group(1)})" == b[6] == "(19)" and advised.group(2) == "9"
    assert "no number of runs can promise a decision" in verify.stdout


# slow (~17 s): an interrupted sequential campaign of real processes, resumed, and its
# reference; tests/verify/test_sequential_strata.py resumes a sequential design in the default run
@pytest.mark.slow
def test_until_decided_stops_and_resume_finishes_an_interrupted_one(tmp_path: Path) -> None:
    # The block crashblocks:Crasher (its output is in no requirement and it is not
    # randomized: no metric changes) holds every run after the first 14 at its
    # initialisation while CRASHERS_GATE is set: the campaign, about 70 runs/s on an idle
    # machine, cannot reach its end before the SIGINT. The resumed run has no gate.
    scenario = tiny(tmp_path)
    scenario.write_text(scenario.read_text() + '\n[blocks.gate]\nclass = "crashblocks:Crasher"\n')
    (tmp_path / "gate").mkdir()
    out = tmp_path / "seq"
    args = ("verify", scenario, "--until-decided", "--runs", 10, "--max-runs", 80,
            "--report", out, "--workers", 1)  # fmt: skip
    gated = dict(env(), CRASHERS_GATE=str(tmp_path / "gate"), CRASHERS_OPEN="14")
    proc = subprocess.Popen(
        command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=gated,
        cwd=tmp_path,
    )  # fmt: skip
    runs_dir = out / "runs"
    deadline = time.monotonic() + 120
    while len(list(runs_dir.glob("run_*.json"))) < 14:  # inside look 2 (runs 10 .. 19)
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no run finished in time"
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, (stdout, stderr)
    assert "Traceback" not in stderr and "--until-decided --resume" in stderr
    assert "look 1 of 4: 10 runs" in stdout and "decided: RATE-50 satisfied" in stdout
    kept = len(list(runs_dir.glob("run_*.json")))
    assert 14 <= kept < 40 and not (out / "report.html").exists()

    # a fixed --resume would re-judge at full confidence: refused
    fixed = run(tmp_path, "verify", scenario, "--report", out, "--resume")
    assert fixed.returncode == 3 and "--until-decided --resume" in fixed.stderr, fixed.stderr

    res = run(tmp_path, *args, "--resume", "--no-progress")
    assert res.returncode == 0, res.stderr
    text = res.stdout
    assert "look 2 of 4: 20 runs, judged at 99.375 %; decided: none; undecided: RATE-85" in text
    assert "look 3 of 4: 40 runs, judged at 98.75 %; decided: RATE-85 satisfied" in text
    assert "look 4" not in text  # stopped before the cap
    assert "RATE-50: satisfied after 10 runs (look 1)" in text
    assert "RATE-85: satisfied after 40 runs (look 3)" in text
    data = json.loads((out / "report.json").read_text())
    seq = data["campaign"]["sequential"]
    assert seq["looks"] == [10, 20, 40, 80] and seq["stopped_at"] == 40
    assert seq["alpha_per_look"]["0.95"] == [0.00625, 0.00625, 0.0125, 0.025]
    assert "alpha spending" in seq["rule"] and data["campaign"]["resumed"] is True
    assert data["campaign"]["runs_this_session"] == 40 - kept
    by_id = {r["id"]: r["result"] for r in data["requirements"]}
    assert by_id["RATE-85"]["n_runs"] == 40 and by_id["RATE-50"]["n_runs"] == 10
    assert "decided at look 3 of 4 (40 runs" in by_id["RATE-85"]["reason"]
    claim = by_id["RATE-85"]["claim"]  # what the rule shows: at 95 % over the looks
    assert "with 95 % confidence over the looks of --until-decided" in claim, claim

    # the 40 runs are those of a fixed campaign of 40 runs (same seed rule)
    ref = run(tmp_path, "verify", scenario, "--runs", 40, "--report", tmp_path / "fixed",
              "--workers", 1, "--no-progress")  # fmt: skip
    assert ref.returncode == 0, ref.stderr
    assert (out / "metrics.csv").read_text() == (tmp_path / "fixed" / "metrics.csv").read_text()


def test_until_decided_reports_undecided_at_the_cap(tmp_path: Path) -> None:
    """Looks 5 and 10, alpha 0.025 each: RATE-50 needs both (0.025^(1/5) = 0.48 < 0.5,
    0.025^(1/10) = 0.69), RATE-85 more (0.69 < 0.85): exit 2 (undecided)."""
    res = run(tmp_path, "verify", tiny(tmp_path), "--until-decided", "--runs", 5, "--max-runs",
              10, "--report", tmp_path / "r", "--workers", 1, "--no-progress")  # fmt: skip
    assert res.returncode == 2, res.stderr
    assert "RATE-85: not decided by 10 runs (the cap is 10)" in res.stdout
    assert "RATE-50: satisfied after 10 runs (look 2)" in res.stdout
    bad = run(tmp_path, "verify", tiny(tmp_path), "--max-runs", 10, "--report", tmp_path / "x")
    assert bad.returncode == 3 and "add --until-decided" in bad.stderr


@pytest.mark.slow  # a Dask LocalCluster starts in about 10 s, the looks in another 20 s
def test_until_decided_on_a_dask_cluster_runs_the_same_runs(tmp_path: Path) -> None:
    """Each look goes through run_campaign(cluster=...): the runs of a local campaign."""
    distributed = pytest.importorskip("distributed")
    from cosim.verify.campaign import run_campaign
    from cosim.verify.sequential import run_until_decided

    scenario = tiny(tmp_path)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:  # fmt: skip
        campaign = run_until_decided(
            scenario, tmp_path / "dask", runs=5, max_runs=10,
            cluster=cluster.scheduler_address, progress=False,
        )  # fmt: skip
    assert campaign.execution["cluster"].startswith("tcp://127.0.0.1:")
    assert campaign.execution["sequential"]["looks"] == [5, 10] and len(campaign.records) == 10
    assert [v.verdict for v in campaign.verdicts] == ["satisfied", "undecided"]
    fixed = run_campaign(scenario, tmp_path / "fixed", runs=10, workers=1, progress=False)
    assert (tmp_path / "dask/metrics.csv").read_text() == fixed.out_dir.joinpath(
        "metrics.csv"
    ).read_text()
