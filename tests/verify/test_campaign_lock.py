"""A report folder belongs to one campaign at a time (issue 14, item 1).

``<report>/campaign.lock`` names its owner (pid, host, start, command) and is held with
``flock`` while the campaign runs and writes its reports; a second campaign is refused
in one line; the lock of a campaign that was killed is taken over with a note; files
of the folder are replaced whole (a reader sees the old file or the new one).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

from cosim.verify.campaign import CampaignError, run_campaign
from cosim.verify.lock import LOCK_FILE, StaleLockNote, read_lock, report_folder_lock
from cosim.verify.records import write_atomic

TESTS = Path(__file__).resolve().parents[1]
DEMO = TESTS.parent / "scenarios" / "demo_verify.toml"


def short_demo(tmp_path: Path, runs: int = 6) -> Path:
    """demo_verify.toml cut to 2 s, with the gate block crashblocks:Crasher (no metric)."""
    text = DEMO.read_text()
    for old, new in {
        'stop = "20 s"': 'stop = "2 s"',
        'from = "5 s"': 'from = "1.5 s"',
        "runs = 20 ": f"runs = {runs} ",
        "[output]": '[blocks.gate]\nclass = "crashblocks:Crasher"\n\n[output]',
    }.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "short.toml"
    path.write_text(text)
    return path


def env_with_tests() -> dict[str, str]:
    return dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    )


def test_a_second_campaign_on_the_folder_is_refused_and_the_first_finishes(
    tmp_path: Path,
) -> None:
    """Acceptance 2 of issue 14, with two real ``ins-cosim verify`` processes."""
    scenario, out, gate = short_demo(tmp_path), tmp_path / "report", tmp_path / "gate"
    gate.mkdir()
    cmd = [sys.executable, "-m", "cosim.cli", "verify", str(scenario), "--report", str(out)]
    cmd += ["--workers", "1", "--no-progress"]
    env = env_with_tests()
    # the first holds its first run at the gate (CRASHERS_OPEN = 0) until the test opens it
    first = subprocess.Popen(
        cmd, env=dict(env, CRASHERS_GATE=str(gate)), cwd=tmp_path, text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not (gate / "slot_0000").exists():
        assert first.poll() is None, first.communicate()
        assert time.monotonic() < deadline, "the first campaign never started its first run"
        time.sleep(0.05)
    owner = read_lock(out)
    assert owner is not None and owner["pid"] == first.pid
    assert owner["host"] == socket.gethostname() and "verify" in owner["command"]
    try:
        for extra in ([], ["--runs", "3", "--seed", "1"]):
            second = subprocess.run(
                [*cmd, *extra], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120
            )
            assert second.returncode == 3, (second.stdout, second.stderr)
            lines = second.stderr.strip().splitlines()
            assert len(lines) == 1 and "Traceback" not in second.stderr, second.stderr
            assert f"pid {first.pid} on host {socket.gethostname()}" in lines[0]
            assert "is in use by another campaign" in lines[0]
            assert "use another --report folder" in lines[0]
            assert not (out / "report.json").exists()
    finally:
        (gate / "open").touch()
    stdout, stderr = first.communicate(timeout=300)
    assert "Traceback" not in stderr and "wrote" in stdout, (stdout, stderr)
    assert not (out / LOCK_FILE).exists()
    # the first campaign's report is whole and its own: its 6 runs, its seed
    data = json.loads((out / "report.json").read_text())
    assert data["campaign"]["runs"] == 6 and data["campaign"]["completed"] == 6
    assert data["campaign"]["seed"] == 2024
    reference = run_campaign(scenario, tmp_path / "reference", workers=1, progress=False)
    assert first.returncode == reference.exit_code  # the verdicts of these 6 runs
    assert (out / "metrics.csv").read_text() == (reference.out_dir / "metrics.csv").read_text()


def test_the_lock_of_a_killed_campaign_is_taken_over_with_a_note(tmp_path: Path) -> None:
    out = tmp_path / "report"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = {"pid": dead.pid, "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
    (out / LOCK_FILE).write_text(json.dumps(stale))
    with pytest.warns(StaleLockNote, match=f"pid {dead.pid} on host {socket.gethostname()}"):
        campaign = run_campaign(short_demo(tmp_path, runs=2), out, workers=1, progress=False)
    assert len(campaign.records) == 2
    assert not (out / LOCK_FILE).exists()


def test_a_lock_of_another_host_is_not_taken_over(tmp_path: Path) -> None:
    out = tmp_path / "report"
    out.mkdir()
    other = {"pid": 1, "host": "elsewhere.example", "started": "2026-01-01T00:00:00+00:00"}
    (out / LOCK_FILE).write_text(json.dumps(other))
    with pytest.raises(CampaignError) as info:
        run_campaign(short_demo(tmp_path, runs=2), out, workers=1, progress=False)
    text = str(info.value)
    assert "pid 1 on host elsewhere.example" in text and f"delete {out / LOCK_FILE}" in text
    assert json.loads((out / LOCK_FILE).read_text()) == other  # left as it was


def test_the_lock_is_released_after_an_error_and_a_refused_folder_is_not_left_behind(
    tmp_path: Path,
) -> None:
    out = tmp_path / "new" / "report"
    with pytest.raises(CampaignError, match="--runs must be >= 1"):
        run_campaign(short_demo(tmp_path), out, runs=0, workers=1, progress=False)
    assert not out.exists()  # created for the lock, removed again: nothing was written
    out.mkdir(parents=True)
    with pytest.raises(CampaignError):
        run_campaign(short_demo(tmp_path), out, runs=0, workers=1, progress=False)
    assert out.is_dir() and not (out / LOCK_FILE).exists()


def test_the_lock_is_reentrant_in_one_process_and_exclusive_between_two(tmp_path: Path) -> None:
    out = tmp_path / "report"
    probe = (
        "import sys\nfrom cosim.verify.lock import report_folder_lock\n"
        "try:\n    with report_folder_lock(sys.argv[1]):\n        pass\n"
        "except Exception as exc:\n    print(exc)\n    sys.exit(3)\n"
    )
    with report_folder_lock(out) as lock:
        assert read_lock(out)["pid"] == os.getpid()
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no note: it is this process's own lock
            campaign = run_campaign(short_demo(tmp_path, runs=2), out, workers=1, progress=False)
        assert lock.exists() and len(campaign.records) == 2  # still held after the campaign
        res = subprocess.run(
            [sys.executable, "-c", probe, str(out)], capture_output=True, text=True
        )
        assert res.returncode == 3 and f"pid {os.getpid()}" in res.stdout
    assert not lock.exists()
    res = subprocess.run([sys.executable, "-c", probe, str(out)], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr


def test_files_are_replaced_whole(tmp_path: Path) -> None:
    """A reader that opened the old file keeps reading it whole; nothing temporary stays."""
    path = tmp_path / "metrics.csv"
    write_atomic(path, "old\n" * 1000)
    with open(path) as reader:
        write_atomic(path, "new\n")
        assert reader.read() == "old\n" * 1000
    assert path.read_text() == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.csv"]
