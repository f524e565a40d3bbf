"""Workers that start once and stay (issue 18, item 3), and never outlive their campaign.

A :class:`cosim.verify.pool.WorkerPool` keeps its processes (imports done, blocks built)
from one campaign to the next, and ``verify --until-decided`` runs all its looks on one
pool: the worker pids recorded with the runs stay the same. A worker held inside a run
(the gate of ``crashblocks:Crasher``) ends when its campaign's process is killed, also
when it blocks SIGTERM (the watch thread's SIGKILL).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import textwrap
import time
import uuid
from pathlib import Path

import pytest

from cosim.verify.campaign import run_campaign
from cosim.verify.pool import ORPHAN_GRACE, WorkerPool
from cosim.verify.sequential import run_until_decided

TESTS = Path(__file__).resolve().parents[1]
DEMO = TESTS.parent / "scenarios" / "demo_verify.toml"
HOST = socket.gethostname()


def short_demo(folder: Path, extra: str = "") -> Path:
    """demo_verify.toml cut to 2 s (runs of about 0.1 s), with an extra block table."""
    text = DEMO.read_text()
    for old, new in {'stop = "20 s"': 'stop = "2 s"', 'from = "5 s"': 'from = "1.5 s"'}.items():
        assert old in text, old
        text = text.replace(old, new)
    path = folder / f"short_{uuid.uuid4().hex[:8]}.toml"
    path.write_text(text.replace("[output]", extra + "[output]"))
    return path


def test_a_pool_keeps_its_processes_across_campaigns_with_the_same_numbers(
    tmp_path: Path,
) -> None:
    path = short_demo(tmp_path)
    out = tmp_path / "pool"
    with WorkerPool(2) as pool:
        run_campaign(path, out, runs=6, pool=pool, progress=False)
        pids = sorted(pool.pids)
        grown = run_campaign(path, out, runs=12, resume=True, pool=pool, progress=False)
        assert sorted(pool.pids) == pids and len(pids) == 2
        assert pool.started == 2  # no process was started for the second campaign
    assert pool.pids == []  # closed: its processes have ended
    if sys.platform.startswith("linux"):
        assert not [pid for pid in pids if _alive(pid)]
    assert grown.execution["runs_this_session"] == 6
    assert {r.worker for r in grown.records} <= {f"{HOST}:{pid}" for pid in pids}
    # reset between runs, whatever ran before: the numbers of runs made one by one here
    serial = run_campaign(path, tmp_path / "serial", runs=12, workers=1, progress=False)
    assert [r.metrics for r in grown.records] == [r.metrics for r in serial.records]
    assert all(r.status == "completed" for r in grown.records)


def test_the_looks_of_until_decided_run_on_the_processes_of_the_first_look(
    tmp_path: Path,
) -> None:
    looks: list[str] = []
    campaign = run_until_decided(
        short_demo(tmp_path), tmp_path / "seq", runs=4, max_runs=64, workers=2, progress=False,
        echo=looks.append,
    )  # fmt: skip
    assert len(looks) >= 3 and len(campaign.records) >= 16  # (4, 8, 16, ...: several looks)
    # a pool per look would show up to two new pids per look
    workers = {r.worker for r in campaign.records}
    assert 1 <= len(workers) <= 2, workers
    assert all(w.startswith(f"{HOST}:") for w in workers)
    first = {r.worker for r in campaign.records if r.index < 4}
    assert first <= workers
    if sys.platform.startswith("linux"):  # the pool is closed when the command returns
        assert not [w for w in workers if _alive(int(w.rsplit(":", 1)[1]))]


def _alive(pid: int) -> bool:
    """Whether the process exists and is not a zombie (Linux /proc)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _descendants(root: int) -> list[int]:
    """Process ids below ``root`` (the forkserver and the workers forked from it)."""
    parent: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                parent[int(entry.name)] = int(
                    (entry / "stat").read_text().rsplit(")", 1)[1].split()[1]
                )
            except (OSError, ValueError, IndexError):
                continue
    found, frontier = [], [root]
    while frontier:
        kids = [p for p, pp in parent.items() if pp in frontier]
        found += kids
        frontier = kids
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sigterm_blocked", [False, True])
def test_workers_held_inside_a_run_end_when_their_campaign_is_killed(
    tmp_path: Path, sigterm_blocked: bool
) -> None:
    """SIGKILL the campaign while both workers wait at a closed gate inside a run: the
    workers end (with SIGTERM blocked in the run: by the watch thread's SIGKILL after
    ORPHAN_GRACE). Before the pool watched its campaign they waited there forever."""
    gate = tmp_path / "gate"
    gate.mkdir()
    module = f"held_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{module}.py").write_text(
        textwrap.dedent(
            f"""
            import signal

            from crashblocks import Crasher as Base


            class Crasher(Base):
                GATE = {str(gate)!r}
                OPEN = 0

                def initialize(self):
                    if {sigterm_blocked!r}:
                        signal.pthread_sigmask(signal.SIG_BLOCK, {{signal.SIGTERM}})
                    super().initialize()
            """
        )
    )
    path = short_demo(tmp_path, f'[blocks.gate]\nclass = "{module}:Crasher"\n\n')
    script = (
        "from cosim.verify.campaign import run_campaign\n"
        "if __name__ == '__main__':\n"
        f"    run_campaign({str(path)!r}, {str(tmp_path / 'out')!r}, runs=8, workers=2,"
        " progress=False)\n"
    )
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    )
    proc = subprocess.Popen([sys.executable, "-c", script], env=env, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 240
        while len(list(gate.glob("slot_*"))) < 2:  # both workers are inside a run
            assert proc.poll() is None, "the campaign ended before its workers were held"
            assert time.monotonic() < deadline, "the gate was never reached"
            time.sleep(0.05)
        below = [p for p in _descendants(proc.pid) if _alive(p)]
        assert len(below) >= 3  # the forkserver and two workers
        proc.kill()
        proc.wait(30)
        deadline = time.monotonic() + ORPHAN_GRACE + 60
        while any(_alive(p) for p in below) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = [p for p in below if _alive(p)]
        assert not left, f"processes of the killed campaign still run: {left}"
    finally:
        if proc.poll() is None:
            proc.kill()
        (gate / "open").touch()  # whatever is left goes on and ends
