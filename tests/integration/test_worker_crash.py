"""A worker process that dies is a failed run, not a lost campaign (issue 14, item 2).

The block ``crashblocks:Crasher`` ends its process for two chosen runs of a 40-run
campaign (SIGKILL in run 7, ``os._exit(3)`` in run 23, at t = 0.5 s of a 2 s run): the
parent sees which run each worker was running, runs it again once on a fresh process
and records it as crashed when it dies again.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from crashblocks import crasher_module

from cosim.verify.campaign import CampaignError, run_campaign
from cosim.verify.records import read_records
from cosim.verify.requirements import UNDECIDED
from cosim.verify.seeds import run_seeds

TESTS = Path(__file__).resolve().parents[1]
DEMO = TESTS.parent / "scenarios" / "demo_verify.toml"
SEEDED = ["flexure", "sensor", "crasher"]  # blocks with a seed, in file order
KILLED, EXITED = 7, 23


def scenario(
    tmp_path: Path,
    runs: int = 40,
    name: str = "crash.toml",
    module: str = "crashblocks",
    **crash: int,
) -> Path:
    """demo_verify.toml cut to 2 s, with the Crasher block set to end the given runs."""
    text = DEMO.read_text()
    for old, new in {
        'stop = "20 s"': 'stop = "2 s"',
        'from = "5 s"': 'from = "1.5 s"',
        "runs = 20 ": f"runs = {runs} ",
        'randomize = ["flexure", "sensor"]': f"randomize = {SEEDED!r}".replace("'", '"'),
    }.items():
        assert old in text, old
        text = text.replace(old, new)
    params = ", ".join(f"{k} = {run_seeds(2024, i, SEEDED)['crasher']}" for k, i in crash.items())
    block = f'[blocks.crasher]\nclass = "{module}:Crasher"\nparameters = {{ {params} }}\n\n'
    path = tmp_path / name
    path.write_text(text.replace("[output]", block + "[output]"))
    return path


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_forty_runs_with_two_killed_workers_complete_and_name_the_two_runs(
    tmp_path: Path,
) -> None:
    """Acceptance 3 of issue 14 (the campaign, in this process; --resume below)."""
    path = scenario(tmp_path, kill_seed=KILLED, exit_seed=EXITED)
    out = tmp_path / "report"
    campaign = run_campaign(path, out, workers=2, progress=False)
    status = {r.index: r.status for r in campaign.records}
    assert len(status) == 40
    assert [i for i, s in status.items() if s != "completed"] == [KILLED, EXITED]
    killed, exited = campaign.records[KILLED], campaign.records[EXITED]
    assert killed.status == exited.status == "crashed"
    assert "killed by signal SIGKILL (9)" in killed.error
    assert "exited with code 3" in exited.error
    for rec in (killed, exited):
        assert "block 'crasher' was stepping from t = 0.5 s" in rec.error
        assert "in each of 2 attempts" in rec.error
        assert rec.seeds == run_seeds(2024, rec.index, SEEDED)
        assert rec.t_end == pytest.approx(0.5)
        assert all(m is None for m in rec.metrics.values())
    # judged under on_failure ("undecided" by default), naming the two runs
    for v in campaign.verdicts:
        assert v.verdict == UNDECIDED and "run(s) 7, 23" in v.reason
        assert v.n_failed == 2
    assert campaign.exit_code == 2
    table = rows(out / "metrics.csv")
    assert [r["run"] for r in table if r["status"] == "crashed"] == ["7", "23"]
    assert table[KILLED]["seed.crasher"] == str(killed.seeds["crasher"])
    # the runs around the crashes are the runs of a campaign without them
    clean = run_campaign(
        scenario(tmp_path, name="clean.toml", kill_seed=99), tmp_path / "clean", workers=1,
        progress=False, only_runs=[6, 8, 24],
    )  # fmt: skip
    for rec in clean.records:
        assert campaign.records[rec.index].metrics == rec.metrics

    # --resume does not run a crashed run again; --rerun-crashed does (and it crashes again)
    again = run_campaign(path, out, workers=2, progress=False, resume=True)
    assert again.execution["runs_this_session"] == 0
    assert [r.index for r in again.failed_runs] == [KILLED, EXITED]
    stamp = (out / "runs" / "run_00008.json").stat().st_mtime_ns
    rerun = run_campaign(path, out, workers=2, progress=False, resume=True, rerun_crashed=True)
    assert rerun.execution["runs_this_session"] == 2
    assert [r.index for r in rerun.failed_runs] == [KILLED, EXITED]
    assert (out / "runs" / "run_00008.json").stat().st_mtime_ns == stamp


def test_a_worker_that_dies_once_is_replaced_and_its_run_completes(tmp_path: Path) -> None:
    once = tmp_path / "once"
    once.mkdir()
    module = crasher_module(tmp_path, ONCE=str(once))
    path = scenario(tmp_path, runs=6, module=module, kill_seed=2, exit_seed=4)
    campaign = run_campaign(path, tmp_path / "report", workers=2, progress=False)
    assert [r.status for r in campaign.records] == ["completed"] * 6
    assert sorted(p.name for p in once.iterdir()) == sorted(
        f"died_{run_seeds(2024, i, SEEDED)['crasher']}" for i in (2, 4)
    )
    reference = run_campaign(
        scenario(tmp_path, runs=6, name="clean.toml", kill_seed=99), tmp_path / "ref", workers=1,
        progress=False,
    )  # fmt: skip
    assert [r.metrics for r in campaign.records] == [r.metrics for r in reference.records]


def test_workers_that_die_while_loading_stop_the_campaign_in_one_line(tmp_path: Path) -> None:
    module = crasher_module(tmp_path, PARENT=os.getpid())  # the workers exit(5)
    path = scenario(tmp_path, runs=4, module=module)
    with pytest.raises(CampaignError, match="worker processes die before they can run") as info:
        run_campaign(path, tmp_path / "report", workers=2, progress=False)
    assert "exited with code 5 while loading the blocks" in str(info.value)
    assert "\n" not in str(info.value)


# slow (~17 s): three campaigns of real worker processes, one interrupted and resumed
@pytest.mark.slow
def test_resume_of_an_interrupted_campaign_with_crashing_runs_finishes_it(tmp_path: Path) -> None:
    """Acceptance 3 of issue 14, --resume: the CLI interrupted (SIGINT) after 16 run
    starts (the gate holds the rest), then resumed; the crashed run 7 is not run again."""
    path = scenario(tmp_path, kill_seed=KILLED, exit_seed=EXITED)
    out, gate = tmp_path / "report", tmp_path / "gate"
    gate.mkdir()
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    )
    cmd = [sys.executable, "-m", "cosim.cli", "verify", str(path), "--report", str(out)]
    cmd += ["--workers", "2", "--no-progress"]
    proc = subprocess.Popen(
        cmd, env=dict(env, CRASHERS_GATE=str(gate), CRASHERS_OPEN="16"), cwd=tmp_path,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 240
    # 16 starts pass (runs 0-14, run 7 twice), the two workers then wait at slots 16 and 17
    while len(list(gate.glob("slot_*"))) < 18:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the gate was never reached"
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, (stdout, stderr)
    assert "Traceback" not in stderr and "--resume" in stderr
    kept = read_records(out / "runs")
    assert kept[KILLED].status == "crashed" and EXITED not in kept
    assert sorted(kept) == list(range(15))
    assert all(r.status == "completed" for i, r in kept.items() if i != KILLED)
    stamp = (out / "runs" / f"run_{KILLED:05d}.json").stat().st_mtime_ns

    res = subprocess.run(
        [*cmd, "--resume"], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 2, res.stderr  # undecided: two runs crashed
    assert "Traceback" not in res.stderr
    assert "40 run(s), 2 failed" in res.stdout and "run(s) 7, 23" in res.stdout
    data = json.loads((out / "report.json").read_text())
    assert data["campaign"]["runs_this_session"] == 40 - 15
    assert (out / "runs" / f"run_{KILLED:05d}.json").stat().st_mtime_ns == stamp
    table = rows(out / "metrics.csv")
    assert [r["run"] for r in table if r["status"] == "crashed"] == ["7", "23"]
    assert data["campaign"]["failed"] == 2 and data["campaign"]["completed"] == 38
    html = (out / "report.html").read_text()
    assert "SIGKILL" in html and "exited with code 3" in html
    bad = subprocess.run(
        [*cmd, "--rerun-crashed"], env=env, cwd=tmp_path, capture_output=True, text=True
    )
    assert bad.returncode == 3 and bad.stderr.count("\n") == 1, bad.stderr
    assert "add --resume" in bad.stderr


@pytest.mark.slow
def test_a_run_that_kills_its_dask_workers_is_recorded_as_crashed(tmp_path: Path) -> None:
    """Dask retries a task whose worker died, up to ``allowed-failures``, then the run is
    recorded as crashed (KilledWorker); the other runs are those of a local campaign."""
    distributed = pytest.importorskip("distributed")
    import dask

    path = scenario(tmp_path, runs=4, kill_seed=1)
    with (
        dask.config.set({"distributed.scheduler.allowed-failures": 1}),
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
    ):  # fmt: skip
        campaign = run_campaign(
            path, tmp_path / "dask", cluster=cluster.scheduler_address, progress=False
        )
    assert [r.status for r in campaign.records] == [
        "completed",
        "crashed",
        "completed",
        "completed",
    ]
    assert "the Dask workers running it died" in campaign.records[1].error
    local = run_campaign(path, tmp_path / "local", workers=1, progress=False, only_runs=[0, 2, 3])
    for rec in local.records:
        assert campaign.records[rec.index].metrics == rec.metrics


def test_ctrl_c_inside_a_pythonfmu_fmu_interrupts_an_in_process_campaign(tmp_path: Path) -> None:
    """A Ctrl-C raised inside an FMU's own Python code (PythonFMU) reaches the campaign
    as an interruption, not as a failed run (the FMU reports it as a fatal fmi2DoStep)."""
    import threading

    from crashblocks import Sleeper

    from cosim.interop.packaging import build_fmu
    from cosim.verify.campaign import CampaignInterrupted

    fmu = build_fmu(Sleeper, tmp_path / "fmu", extra_files=(TESTS / "crashblocks.py",))
    path = tmp_path / "sleepy.toml"
    path.write_text(
        f'[master]\nstep = "10 ms"\nstop = "1 s"\n\n[blocks.s]\nfmu = "{fmu}"\n\n'
        "[campaign]\nruns = 40\n\n"
        '[[requirements]]\nid = "R"\nsignal = "s.y"\nunit = "s"\ncriterion = "value"\n'
        'bound = "2 s"\n'
    )
    out = tmp_path / "report"

    def interrupt() -> None:  # Ctrl-C once a run is on disk: the FMU sleeps 90 % of a run
        deadline = time.monotonic() + 120
        while not (out / "runs" / "run_00000.json").exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=interrupt, daemon=True).start()
    with pytest.raises(CampaignInterrupted):
        run_campaign(path, out, workers=1, progress=False)
    kept = read_records(out / "runs")
    assert 1 <= len(kept) < 40 and all(r.status == "completed" for r in kept.values())
