"""One way to make a run (cosim.runs): a campaign parses its scenario once per process, and
a kept assembly runs as a fresh one does."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np

import cosim
from cosim import parses
from cosim.runs import assemble, make_run
from cosim.verify.campaign import run_campaign

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "scenarios" / "demo_verify.toml"


def short_demo(folder: Path) -> Path:
    """demo_verify.toml cut to 2 s (runs of about 0.1 s)."""
    text = DEMO.read_text()
    for old, new in {'stop = "20 s"': 'stop = "2 s"', 'from = "5 s"': 'from = "1.5 s"'}.items():
        assert old in text, old
        text = text.replace(old, new)
    path = folder / "short.toml"
    path.write_text(text)
    return path


def test_verify_with_two_workers_parses_once_in_the_parent_and_once_per_worker(
    tmp_path: Path,
) -> None:
    """A 4-run, 2-worker ``verify``: the log of every process's parses (cosim.parses)."""
    path, log, report = short_demo(tmp_path), tmp_path / "parses.log", tmp_path / "report"
    env = dict(os.environ, **{parses.LOG_ENV: str(log)})
    proc = subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", "verify", str(path), "--runs", "4",
         "--workers", "2", "--report", str(report), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    _out, err = proc.communicate(timeout=600)
    assert proc.returncode in (0, 1, 2), err
    lines = [line.split(" ", 1) for line in log.read_text().splitlines()]
    assert {name for _pid, name in lines} == {str(path)}
    by_pid = Counter(int(pid) for pid, _name in lines)
    assert by_pid[proc.pid] == 1  # the parent: echo, prepare, budget share one parse
    workers = {
        int(json.loads(f.read_text())["worker"].rsplit(":", 1)[1])
        for f in (report / "runs").glob("run_*.json")
    }
    assert len(list((report / "runs").glob("run_*.json"))) == 4
    assert proc.pid not in workers and 1 <= len(workers) <= 2
    # every worker that ran runs parsed, once; besides the parent only the two workers
    # parsed (a worker that started but got no run, on a busy machine, parsed once too)
    others = set(by_pid) - {proc.pid}
    assert workers <= others and len(others) <= 2
    assert all(by_pid[w] == 1 for w in others)


def test_a_campaign_in_this_process_parses_once(tmp_path: Path) -> None:
    path = short_demo(tmp_path)
    before = parses.COUNT[str(path)]
    campaign = run_campaign(path, tmp_path / "one", runs=3, workers=1, progress=False)
    assert len(campaign.records) == 3 and all(r.status == "completed" for r in campaign.records)
    assert parses.COUNT[str(path)] - before == 1


def test_a_kept_assembly_runs_as_a_fresh_one_and_leaves_the_scenario_alone(
    tmp_path: Path,
) -> None:
    sc = cosim.load_scenario(short_demo(tmp_path))
    before = repr(sc)
    kept = assemble(sc, stop=1.0)
    try:
        runs = [make_run(kept, parameters={"sensor": {"seed": s}}) for s in (5, 6, 5)]
    finally:
        kept.close()
    fresh = make_run(sc, overrides={"stop": 1.0}, parameters={"sensor": {"seed": 6}})
    assert repr(sc) == before  # built from a copy
    assert runs[1].metadata["seeds"]["sensor"] == 6
    np.testing.assert_array_equal(runs[1].data, fresh.data)  # reset between runs
    np.testing.assert_array_equal(runs[0].data, runs[2].data)
    assert not np.array_equal(runs[0].data, runs[1].data)
    assert fresh.time[-1] == 1.0
