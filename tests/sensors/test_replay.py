"""ImuLogReplay (cosim.sensors.replay): recorded increments replayed into the seed 003 filter.

Acceptance 1 of issue 17: a log written from the simulated IMU of the seed 003 scenario
replays into the same filter with the same alignment result (the tolerance is 1e-12; the
increments are written with repr() so they round-trip exactly and one sample per step is
copied, hence the result is in fact bit for bit); a 200 Hz log replayed into 100 Hz and
20 Hz macro steps conserves its increments to rounding.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import SimulationError
from cosim.models.constants import DEG
from cosim.scenario import BlockSpec
from cosim.sensors.logs import ImuLog, write_csv
from cosim.sensors.replay import ImuLogReplay, ReplayError

ROOT = Path(__file__).resolve().parents[2]
SEED003 = ROOT / "scenarios" / "sins_north_finding.toml"


def write_increment_log(path: Path, time: np.ndarray, dtheta: np.ndarray, dv: np.ndarray) -> Path:
    """A CSV log of increments, every float written with repr (exact round trip)."""
    return write_csv(path, time, dtheta, dv)


def seed003_with_imu_recorded(stop: str = "300 s") -> cosim.RunResult:
    sc = cosim.load_scenario(SEED003)
    sc.outputs = ["align", "imu.dtheta_meas_b", "imu.dv_meas_b"]
    return cosim.run(sc, record_every=1, stop=stop)


def seed003_replayed(log: Path, stop: str = "300 s", **parameters: object) -> cosim.RunResult:
    sc = cosim.load_scenario(SEED003)
    sc.blocks["imu"] = BlockSpec(
        "imu", "model", "ImuLogReplay", parameters={"log": str(log), **parameters}
    )
    sc.outputs = ["align", "imu.dtheta_meas_b", "imu.dv_meas_b"]
    return cosim.run(sc, record_every=1, stop=stop)


def recorded(result: cosim.RunResult, name: str) -> np.ndarray:
    return np.column_stack([result[f"{name}[{i}]"] for i in (1, 2, 3)])


def test_seed003_log_replays_to_the_same_alignment(tmp_path: Path) -> None:
    sim = seed003_with_imu_recorded()
    # Row k > 0 holds the increment over the step ending at time[k]: one sample per step.
    log = write_increment_log(
        tmp_path / "seed003_imu.csv",
        sim.time[1:],
        recorded(sim, "imu.dtheta_meas_b")[1:],
        recorded(sim, "imu.dv_meas_b")[1:],
    )
    rep = seed003_replayed(log)
    assert np.array_equal(rep.time, sim.time)
    align = [n for n in sim.names if n.startswith("align.")]
    assert len(align) > 20
    for name in align:
        a, b = sim[name], rep[name]
        assert np.allclose(a, b, rtol=0.0, atol=1e-12), name
    # in fact bit for bit: the replayed increments are the simulated ones
    assert np.array_equal(sim["align.rpy_err[3]"], rep["align.rpy_err[3]"])
    assert np.array_equal(recorded(sim, "imu.dv_meas_b"), recorded(rep, "imu.dv_meas_b"))


def _log_200hz(tmp_path: Path, n: int = 2000) -> tuple[Path, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    dtheta = 1e-5 * rng.standard_normal((n, 3)) + 1e-7
    dv = 1e-3 * rng.standard_normal((n, 3)) + np.array([0.0, 0.0, -9.81 / 200])
    path = write_increment_log(tmp_path / "imu200.csv", np.arange(1, n + 1) / 200.0, dtheta, dv)
    return path, dtheta, dv


def _replay(path: Path, h: float, steps: int, **params: object) -> tuple[np.ndarray, np.ndarray]:
    block = ImuLogReplay(instance_name="imu")
    block.log = str(path)
    for key, value in params.items():
        setattr(block, key, value)
    block.initialize()
    out_theta, out_v = [], []
    for k in range(steps):
        block.step(k * h, h)
        out_theta.append(block.dtheta_meas_b.copy())
        out_v.append(block.dv_meas_b.copy())
        assert np.allclose(block.omega_meas_b, block.dtheta_meas_b / h)
    return np.array(out_theta), np.array(out_v)


@pytest.mark.parametrize(("h", "m"), [(0.01, 2), (0.05, 10)])
def test_200hz_log_into_100hz_and_20hz_steps_conserves_increments(
    tmp_path: Path, h: float, m: int
) -> None:
    path, dtheta, dv = _log_200hz(tmp_path)
    steps = len(dtheta) // m
    got_theta, got_v = _replay(path, h, steps)
    # each step is the correctly rounded sum of its m samples ...
    for j in range(3):
        want = [math.fsum(dtheta[k * m : (k + 1) * m, j]) for k in range(steps)]
        assert np.array_equal(got_theta[:, j], want)
    # ... and the whole record is conserved to rounding
    for got, ref in ((got_theta, dtheta), (got_v, dv)):
        total = np.array([math.fsum(got[:, j]) for j in range(3)])
        exact = np.array([math.fsum(ref[:, j]) for j in range(3)])
        scale = np.abs(ref).sum(axis=0)
        assert np.all(np.abs(total - exact) <= 4 * np.finfo(float).eps * scale)


def test_step_not_a_multiple_of_the_sample_interval_is_refused(tmp_path: Path) -> None:
    path, _, _ = _log_200hz(tmp_path, 100)
    block = ImuLogReplay(instance_name="imu")
    block.log = str(path)
    block.initialize()
    with pytest.raises(ReplayError, match=r"0\.0125 s holds 2\.5 samples .* 200 Hz") as exc:
        block.step(0.0, 0.0125)
    assert "0.01 s or 0.015 s" in str(exc.value)
    with pytest.raises(ReplayError, match="holds 0.2 samples"):
        block.step(0.0, 0.001)


def test_log_shorter_than_the_run_is_reported(tmp_path: Path) -> None:
    path, _, _ = _log_200hz(tmp_path, 100)
    with pytest.raises(ReplayError, match=r"ends after 100 samples .* master.stop <= 0.5 s"):
        _replay(path, 0.05, 11)


def test_rate_columns_are_integrated(tmp_path: Path) -> None:
    n, fs = 400, 100.0
    path = tmp_path / "rates.csv"
    lines = [
        "time [ms],gyro_x [deg/s],gyro_y [deg/h],gyro_z [rad/s],acc_x [g],acc_y [mg],acc_z [m/s2]"
    ]
    lines += [f"{10 * (k + 1)},1.5,36,0.25,0.5,2,-9.8" for k in range(n)]
    path.write_text("\n".join(lines) + "\n")
    theta, v = _replay(path, 0.1, 40)
    t_total = n / fs
    assert np.allclose(theta.sum(axis=0), np.array([1.5 * DEG, 36 * DEG / 3600, 0.25]) * t_total)
    assert np.allclose(v.sum(axis=0), np.array([0.5 * 9.80665, 2e-3 * 9.80665, -9.8]) * t_total)
    assert ImuLog(path).scan().dt == pytest.approx(0.01)


def test_bad_log_stops_the_run_before_its_first_step(tmp_path: Path) -> None:
    path, dtheta, dv = _log_200hz(tmp_path, 3000)
    lines = path.read_text().splitlines(keepends=True)
    del lines[1500]  # line 1501: one sample lost
    path.write_text("".join(lines))
    with pytest.raises(SimulationError, match=r"imu200.csv, line 1501, t = 7.505 s: gap"):
        seed003_replayed(path, stop="1 s", sample_rate=200.0)


# ------------------------------------------------------------------------- as an FMU
@pytest.fixture(scope="module")
def seed003_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[cosim.RunResult, Path]:
    sim = seed003_with_imu_recorded(stop="60 s")
    log = write_increment_log(
        tmp_path_factory.mktemp("seed003") / "seed003_imu.csv",
        sim.time[1:],
        recorded(sim, "imu.dtheta_meas_b")[1:],
        recorded(sim, "imu.dv_meas_b")[1:],
    )
    return sim, log


@pytest.fixture(scope="module")
def seed003_fmu(seed003_log: tuple[cosim.RunResult, Path], tmp_path_factory) -> Path:
    from cosim.sensors.fmu import build_replay_fmu

    return build_replay_fmu(seed003_log[1], tmp_path_factory.mktemp("fmu"))


def test_replay_fmu_fills_the_imu_role(seed003_fmu: Path) -> None:
    from click.testing import CliRunner

    from cosim.cli import main
    from cosim.interop.fmu_check import check_fmu

    report = check_fmu(seed003_fmu, "imu")
    assert report.satisfied, report.problems
    cli = CliRunner().invoke(main, ["check-fmu", str(seed003_fmu), "--role", "imu"])
    assert cli.exit_code == 0, cli.output
    with zipfile.ZipFile(seed003_fmu) as z:
        names = set(z.namelist())
    for name in ("time.npy", "increments.npy", "sample_rate.npy", "seed003_imu.csv"):
        assert f"resources/imu_log/{name}" in names
    assert "resources/cosim/sensors/replay.py" in names
    assert not any(n.startswith("resources/cosim/sensors/logs") for n in names)


def test_replay_fmu_in_the_seed003_scenario_gives_the_simulated_alignment(
    seed003_log: tuple[cosim.RunResult, Path], seed003_fmu: Path
) -> None:
    sim, _ = seed003_log
    sc = cosim.load_scenario(SEED003)
    sc.blocks["imu"] = BlockSpec("imu", "fmu", str(seed003_fmu))
    sc.outputs = ["align", "imu.dtheta_meas_b", "imu.dv_meas_b"]
    rep = cosim.run(sc, record_every=1, stop="60 s")
    for name in (n for n in sim.names if n.startswith("align.")):
        assert np.allclose(sim[name], rep[name], rtol=0.0, atol=1e-12), name


def test_replay_fmu_under_fmpy_alone_gives_the_in_process_outputs(
    seed003_log: tuple[cosim.RunResult, Path], seed003_fmu: Path, tmp_path: Path
) -> None:
    # A fresh interpreter: the FMU imports its own resources (cosim/sensors/replay.py), not
    # this checkout; two samples per step (h = 0.2 s for the 10 Hz log).
    _, log = seed003_log
    out = tmp_path / "out.npy"
    script = (
        "import sys, numpy as np, fmpy\n"
        f"r = fmpy.simulate_fmu({str(seed003_fmu)!r}, output_interval=0.2, stop_time=20.0,"
        " output=['dtheta_meas_b[1]','dtheta_meas_b[2]','dtheta_meas_b[3]','dv_meas_b[1]',"
        "'dv_meas_b[2]','dv_meas_b[3]','log_time'])\n"
        "import cosim.sensors.replay as m\n"
        "assert 'resources' in m.__file__, m.__file__\n"
        f"np.save({str(out)!r}, np.column_stack([r[n] for n in r.dtype.names]))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(
        [sys.executable, "-c", script],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    fmu = np.load(out)
    theta, v = _replay(log, 0.2, 100)
    assert np.array_equal(fmu[1:, 1:4], theta)
    assert np.array_equal(fmu[1:, 4:7], v)
    assert np.allclose(fmu[1:, 7], np.arange(1, 101) * 0.2)


# ------------------------------------------------------------------ master-INS replay
MASTER_COLUMNS = ("v_master_n", "rpy_master", "lat_master", "lon_master", "h_master")


def _master_log(result: cosim.RunResult, path: Path, angle: str = "rad") -> Path:
    f = 1.0 if angle == "rad" else 1.0 / DEG
    cols = [result["time"]]
    cols += [result[f"master.v_master_n[{i}]"] for i in (1, 2, 3)]
    cols += [result[f"master.rpy_master[{i}]"] * f for i in (1, 2, 3)]
    cols += [result["master.lat_master"] * f, result["master.lon_master"] * f]
    cols += [result["master.h_master"]]
    a = f"[{angle}]"
    header = (
        f"time [s],v_n [m/s],v_e [m/s],v_d [m/s],roll {a},pitch {a},yaw {a},lat {a},lon {a},h [m]"
    )
    with path.open("w") as fh:
        fh.write(header + "\n")
        for row in np.column_stack(cols).tolist():
            fh.write(",".join(map(repr, row)) + "\n")
    return path


def _transfer(stop: str, master: BlockSpec | None = None) -> cosim.RunResult:
    sc = cosim.load_scenario(ROOT / "scenarios" / "transfer_alignment.toml")
    if master is not None:
        sc.blocks["master"] = master
    sc.outputs = ["align", "master"]
    return cosim.run(sc, record_every=1, stop=stop)


def test_master_ins_log_replays_into_transfer_alignment(tmp_path: Path) -> None:
    sim = _transfer("20 s")
    log = _master_log(sim, tmp_path / "master.csv")
    rep = _transfer(
        "20 s", BlockSpec("master", "model", "MasterInsLogReplay", parameters={"log": str(log)})
    )
    for name in (n for n in sim.names if n.startswith(("align.", "master."))):
        assert np.allclose(sim[name], rep[name], rtol=0.0, atol=1e-12), name
    assert np.array_equal(sim["align.rpy_err[3]"], rep["align.rpy_err[3]"])
    # the same log in degrees: the outputs agree to rounding
    from cosim.sensors.master_replay import MasterInsLogReplay

    block = MasterInsLogReplay(instance_name="master")
    block.log = str(_master_log(sim, tmp_path / "master_deg.csv", "deg"))
    block.initialize()
    assert np.allclose(block.rpy_master, [sim[f"master.rpy_master[{i}]"][0] for i in (1, 2, 3)])
    for k in range(1, 11):
        block.step((k - 1) * 0.05, 0.05)
    assert block.lat_master == pytest.approx(sim["master.lat_master"][10], rel=1e-15)
    assert block.log_time == pytest.approx(0.5)
