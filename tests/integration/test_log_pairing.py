"""Two logs in one run checked against each other (cosim.sensors.pairing; issue 26, item 6).

Acceptance 5: a simulated transfer-alignment run (scenarios/transfer_alignment.toml, 20 s)
writes its slave-IMU and master-INS logs; the master log stamped 110 ms late is refused by
``ins-cosim check`` (and ``run``) with the numbers and the fix, exit code 3; with
``time_offset = "110 ms"`` the replayed run equals the simulated one. The tolerance is
1e-12 in the filter's outputs and is in fact met bit for bit: the logs are written with
``repr`` (shortest round-trip text, so every value reads back exactly), a macro step
holds one sample of each log, and ``time_offset`` is a statement about the stamps, not a
shift of the data; the ship, flexure and lever blocks still give the truth (same seeds).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import ScenarioError
from cosim.sensors.demo import transfer_run, write_transfer_logs
from cosim.sensors.pairing import LogSpan, check_pair, check_rate

ROOT = Path(__file__).resolve().parents[2]
TRANSFER = ROOT / "scenarios" / "transfer_alignment.toml"
STOP = "20 s"


def replay_scenario(folder: Path, imu: Path, master: Path, offset: str | None) -> Path:
    """transfer_alignment.toml with its IMU and master INS replaced by the two logs."""
    text = TRANSFER.read_text().split("[campaign]")[0]  # a replay is no campaign
    imu_block = re.search(r"\[blocks\.imu\]\nmodel = .*\nparameters = .*\n", text).group(0)
    master_block = re.search(r"\[blocks\.master\]\nmodel = .*\nparameters = .*\n", text).group(0)
    extra = "" if offset is None else f', time_offset = "{offset}"'
    text = text.replace(
        imu_block,
        f'[blocks.imu]\nmodel = "ImuLogReplay"\nparameters = {{ log = "{imu}" }}\n'
        'unconnected_ok = ["dtheta_b", "dv_b"]\n',
    )
    text = text.replace(
        master_block,
        f'[blocks.master]\nmodel = "MasterInsLogReplay"\n'
        f'parameters = {{ log = "{master}"{extra} }}\n'
        'unconnected_ok = ["v_n", "rpy", "lat", "lon", "h"]\n',
    )
    text = text.replace('stop = "120 s"', f'stop = "{STOP}"')
    outputs = '[output]\nvariables = ["align", "master"]\n'
    text = re.sub(r"\[output\]\nvariables = .*\n", outputs, text)
    path = folder / ("replay.toml" if offset is None else "replay_offset.toml")
    path.write_text(text)
    return path


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cosim.cli", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> tuple[cosim.RunResult, Path, Path]:
    """The simulated run and its two logs, the master's stamped 110 ms late."""
    sim = transfer_run(STOP)
    imu, master = write_transfer_logs(tmp_path_factory.mktemp("logs"), sim, master_delay=0.110)
    return sim, imu, master


def test_a_log_110_ms_out_of_step_is_refused_with_the_numbers(
    simulated: tuple[cosim.RunResult, Path, Path], tmp_path: Path
) -> None:
    _, imu, master = simulated
    scenario = replay_scenario(tmp_path, imu, master, offset=None)
    commands = (
        ["check", str(scenario)],
        ["run", str(scenario), "--out", str(tmp_path / "o")],
        ["verify", str(scenario), "--report", str(tmp_path / "v"), "--no-progress"],
    )
    for command in commands:
        proc = cli(*command)
        assert proc.returncode == 3, proc.stderr
        lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("error:")]
        assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
        msg = lines[0]
        assert "logs out of step" in msg
        assert "'imu' (" in msg and "first interval starts at 0 s" in msg  # 0.05 - 0.05
        assert "'master' (" in msg and "first sample is at 0.11 s" in msg
        assert "110 ms apart, more than half a sample (25 ms)" in msg
        assert 'time_offset = "110 ms"' in msg
        assert "blocks.master.parameters.time_offset" in msg
    assert not (tmp_path / "o" / "results.csv").exists()
    assert not (tmp_path / "v" / "report.json").exists()


def test_with_the_right_time_offset_the_replay_equals_the_simulation(
    simulated: tuple[cosim.RunResult, Path, Path], tmp_path: Path
) -> None:
    sim, imu, master = simulated
    scenario = replay_scenario(tmp_path, imu, master, offset="110 ms")
    proc = cli("check", str(scenario))
    assert proc.returncode == 0, proc.stderr
    assert "warning" not in proc.stderr  # the replays' ignored inputs are stated
    sc = cosim.load_scenario(scenario)
    sc.outputs = ["align", "imu.dtheta_meas_b", "imu.dv_meas_b", "master"]
    rep = cosim.run(sc, record_every=1)
    assert np.array_equal(rep.time, sim.time)
    names = [n for n in sim.names if n.startswith("align.")]
    assert len(names) > 20
    for name in names:
        assert np.allclose(sim[name], rep[name], rtol=0.0, atol=1e-12), name
    assert np.array_equal(sim["align.rpy_err[3]"], rep["align.rpy_err[3]"])  # bit for bit
    assert np.allclose(rep["master.log_time"], sim.time + 0.110, rtol=0.0, atol=1e-12)


def _span(block: str, start: float, dt: float, samples: int, interval: bool) -> LogSpan:
    end = start + (samples if interval else samples - 1) * dt
    first = start + (dt if interval else 0.0)
    return LogSpan(block, f"{block}.csv", start, end, dt, samples, 0.0, first, interval)


def test_half_a_sample_is_the_tolerance_and_a_cut_is_named() -> None:
    imu = _span("imu", 0.0, 0.01, 10_000, True)  # 100 Hz
    check_pair(imu, _span("master", 0.0049, 0.1, 1000, False))  # within 5 ms: accepted
    with pytest.raises(ScenarioError, match=r"5\.1 ms apart, more than half a sample \(5 ms\)"):
        check_pair(imu, _span("master", 0.0051, 0.1, 1000, False))
    # The master log starts 0.2 s later (20 IMU samples): the fix names the cut.
    with pytest.raises(ScenarioError) as exc:
        check_pair(imu, _span("master", 0.2, 0.1, 1000, False))
    assert 'time_offset = "200 ms"' in exc.value.message
    assert "or cut the first 20 samples of imu.csv" in exc.value.message


def test_a_step_that_splits_a_sample_and_a_short_log_are_refused() -> None:
    master = _span("master", 0.0, 0.1, 101, False)  # 10 Hz, 10 s of data
    check_rate(master, 0.01, 10, 10.0, 0.0)  # steps every 0.1 s: one sample
    with pytest.raises(ScenarioError, match=r"holds 0\.5 samples .* use master\.step") as exc:
        check_rate(master, 0.05, 1, 10.0, 0.0)
    assert exc.value.key == "master.step"
    with pytest.raises(ScenarioError, match=r"holds 10 s of data .* master\.stop <= 10 s"):
        check_rate(master, 0.1, 1, 12.0, 0.0)


def test_the_shipped_scenario_refuses_logs_shorter_than_its_run(
    simulated: tuple[cosim.RunResult, Path, Path], tmp_path: Path
) -> None:
    """scenarios/transfer_alignment_logs.toml (100 s) on the 20 s logs, from a folder
    holding them where the scenario looks (out/transfer_logs/)."""
    import shutil

    _, imu, master = simulated
    logs = tmp_path / "out" / "transfer_logs"
    logs.mkdir(parents=True)
    shutil.copy(imu, logs / "slave_imu.csv")
    shutil.copy(master, logs / "master_ins.csv")
    shipped = ROOT / "scenarios" / "transfer_alignment_logs.toml"
    proc = subprocess.run(
        [str(Path(sys.executable).parent / "ins-cosim"), "check", str(shipped)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 3
    (line,) = proc.stderr.strip().splitlines()
    # the IMU log is checked first: 400 increments at 20 Hz hold 20 s of data
    assert "key 'master.stop'" in line
    assert "the run lasts 100 s, but the log out/transfer_logs/slave_imu.csv" in line
    assert "holds 20 s of data (400 samples at 20 Hz); set master.stop <= 20 s" in line
