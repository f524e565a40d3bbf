"""IMU log readers (cosim.sensors.logs): formats, units, and one clear line per bad log.

Acceptance 2 of issue 17: missing column, unknown unit, a gap, a duplicate time, time
going backwards, NaN, a truncated last line each give one line naming the file, the line
(or row) and the time, and the fix; nothing is interpolated. A log far larger than the
read buffer is streamed with bounded peak memory (slow test; a quick version counts the
chunks).
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from cosim.errors import UserError
from cosim.models.constants import DEG, G0
from cosim.sensors.formats import LogColumnError, LogTimeError, LogValueError
from cosim.sensors.logs import ImuLog

HEADER = "time [s],gyro_x [deg/s],gyro_y [deg/s],gyro_z [deg/s],acc_x [m/s2],acc_y [m/s2],acc_z [g]"


def _rows(n: int, fs: float = 100.0) -> list[str]:
    return [f"{(k + 1) / fs!r},0.1,-0.2,0.3,0.01,0.02,1.0" for k in range(n)]


def _write(tmp_path: Path, rows: list[str], header: str = HEADER, end: str = "\n") -> Path:
    path = tmp_path / "imu.csv"
    path.write_text("\n".join([header, *rows]) + end)
    return path


def _one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text
    assert isinstance(exc.value, UserError)
    return text


def test_csv_rates_in_any_unit_become_si_increments(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(50))
    log = ImuLog(path)
    chunks = list(log.chunks())
    assert len(chunks) == 1
    c = chunks[0]
    assert c.line[0] == 2 and c.line[-1] == 51
    assert np.allclose(c.dtheta, np.array([0.1, -0.2, 0.3]) * DEG * 0.01)
    assert np.allclose(c.dv, np.array([0.01, 0.02, G0]) * 0.01)
    assert log.sample_rate == pytest.approx(100.0)


def test_accel_prefix_and_extra_columns(tmp_path: Path) -> None:
    header = (
        "temp [degC],time [ms],gyro_x [rad],gyro_y [rad],gyro_z [rad],"
        "accel_x [m/s],accel_y [m/s],accel_z [m/s]"
    )
    rows = [f"20,{10 * (k + 1)},1e-6,2e-6,3e-6,0,0,0.098" for k in range(10)]
    s = ImuLog(_write(tmp_path, rows, header)).scan()
    assert s.samples == 10 and s.dt == pytest.approx(0.01)
    assert np.allclose(s.dtheta_sum, [1e-5, 2e-5, 3e-5]) and np.isclose(s.dv_sum[2], 0.98)


def test_parquet_and_hdf5_give_the_csv_samples(tmp_path: Path) -> None:
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    h5py = pytest.importorskip("h5py")
    csv = _write(tmp_path, _rows(300))
    ref = np.vstack([np.hstack([c.dtheta, c.dv]) for c in ImuLog(csv).chunks()])
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    names = [h.strip() for h in HEADER.split(",")]
    pq.write_table(pa.table({n: data[:, i] for i, n in enumerate(names)}), tmp_path / "imu.parquet")
    with h5py.File(tmp_path / "imu.h5", "w") as f:
        g = f.create_group("imu")
        for i, n in enumerate(names):
            key, unit = n.split(" [")
            g.create_dataset(key, data=data[:, i]).attrs["unit"] = unit.rstrip("]")
    for path, kw in ((tmp_path / "imu.parquet", {}), (tmp_path / "imu.h5", {"group": "imu"})):
        log = ImuLog(path, chunk_rows=64, **kw)
        chunks = list(log.chunks())
        assert len(chunks) == 5 and chunks[1].line[0] == 65  # rows counted from 1
        got = np.vstack([np.hstack([c.dtheta, c.dv]) for c in chunks])
        assert np.array_equal(got, ref)


def test_missing_column(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(5), HEADER.replace("gyro_y", "gyr_y"))
    with pytest.raises(LogColumnError) as exc:
        ImuLog(path)
    text = _one_line(exc)
    assert text.startswith(f"{path}, line 1: no column 'gyro_y'")
    assert "Did you mean" in text and "name the columns time, gyro_x" in text


def test_unknown_unit(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(5), HEADER.replace("gyro_z [deg/s]", "gyro_z [dps]"))
    with pytest.raises(LogColumnError) as exc:
        ImuLog(path)
    assert "line 1: column 'gyro_z [dps]': unknown unit 'dps'" in _one_line(exc)


def test_unit_of_the_wrong_kind_and_missing_unit(tmp_path: Path) -> None:
    with pytest.raises(LogColumnError, match=r"'acc_x \[deg/s\]'.*neither an increment"):
        ImuLog(_write(tmp_path, _rows(5), HEADER.replace("acc_x [m/s2]", "acc_x [deg/s]")))
    with pytest.raises(LogColumnError, match=r"column 'time' has no unit"):
        ImuLog(_write(tmp_path, _rows(5), HEADER.replace("time [s]", "time")))
    with pytest.raises(LogColumnError, match=r"mix rates and increments"):
        ImuLog(_write(tmp_path, _rows(5), HEADER.replace("gyro_x [deg/s]", "gyro_x [deg]")))


def test_gap(tmp_path: Path) -> None:
    rows = _rows(20)
    del rows[9:12]  # samples at 0.10, 0.11, 0.12 lost
    path = _write(tmp_path, rows)
    with pytest.raises(LogTimeError) as exc:
        ImuLog(path).scan()
    text = _one_line(exc)
    assert text.startswith(f"{path}, line 11, t = 0.13 s: gap of 0.04 s after the sample at 0.09 s")
    assert "3 sample(s) missing" in text and "nothing is interpolated" in text


def test_duplicate_time_and_its_policy(tmp_path: Path) -> None:
    rows = _rows(20)
    rows.insert(5, rows[4])  # an exact retransmission of line 6
    path = _write(tmp_path, rows)
    with pytest.raises(LogTimeError) as exc:
        ImuLog(path).scan()
    assert f"{path}, line 7, t = 0.05 s: duplicate time" in _one_line(exc)
    s = ImuLog(path, duplicates="drop").scan()
    assert s.samples == 20 and s.dropped == 1
    rows[5] = rows[5].replace("0.1,", "0.7,", 1)  # same time, other values: still an error
    with pytest.raises(LogTimeError, match="line 7, t = 0.05 s: duplicate time"):
        ImuLog(_write(tmp_path, rows), duplicates="drop").scan()


def test_time_going_backwards(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[8] = rows[8].replace("0.09,", "0.05,", 1)  # the logger's clock jumped back
    path = _write(tmp_path, rows)
    with pytest.raises(LogTimeError) as exc:
        ImuLog(path).scan()
    text = _one_line(exc)
    assert "line 10, t = 0.05 s: time goes backwards by 0.03 s" in text
    assert "sort the log by time" in text


def test_jitter_beyond_the_tolerance(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[10] = rows[10].replace("0.11,", "0.1108,", 1)
    path = _write(tmp_path, rows)
    assert ImuLog(path, jitter=0.1).scan().samples == 20  # within 10 % of the interval
    with pytest.raises(LogTimeError) as exc:
        ImuLog(path).scan()
    text = _one_line(exc)
    assert "line 12, t = 0.1108 s: timestamp +0.08 sample intervals off" in text
    assert "tolerance 0.05" in text and "raise jitter" in text


def test_nan(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[13] = rows[13].replace("-0.2", "nan")
    with pytest.raises(LogValueError) as exc:
        ImuLog(_write(tmp_path, rows)).scan()
    text = _one_line(exc)
    assert "line 15, t = 0.14 s: column 'gyro_y [deg/s]' is nan" in text
    assert "nothing is interpolated" in text


def test_truncated_last_line(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[-1] = rows[-1][:12]
    with pytest.raises(LogValueError) as exc:
        ImuLog(_write(tmp_path, rows, end="")).scan()
    text = _one_line(exc)
    assert "line 21: the last line is cut short (3 of 7 fields, no end of line)" in text
    assert "copy it again, or delete line 21" in text


def test_text_in_a_field_and_a_short_line_inside(tmp_path: Path) -> None:
    rows = _rows(20)
    rows[3] = rows[3].replace("0.3", "x")
    with pytest.raises(LogValueError, match=r"line 5: column 'gyro_z \[deg/s\]' holds 'x'"):
        ImuLog(_write(tmp_path, rows)).scan()
    rows = _rows(20)
    rows[3] = "0.04,1"
    with pytest.raises(LogValueError, match=r"line 5: 2 fields where the header has 7"):
        ImuLog(_write(tmp_path, rows)).scan()


def test_streams_in_chunks(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(1000))
    log = ImuLog(path, chunk_rows=64)
    sizes = [len(c.time) for c in log.chunks()]
    assert max(sizes) == 64 and sum(sizes) == 1000 and len(sizes) == 16
    # the check of the timestamps runs across the chunk boundaries
    rows = _rows(1000)
    rows[128] = rows[127]
    with pytest.raises(LogTimeError, match="line 130, t = 1.28 s: duplicate"):
        ImuLog(_write(tmp_path, rows), chunk_rows=64).scan()


@pytest.mark.slow
def test_log_far_larger_than_the_buffer_is_streamed_with_bounded_memory(tmp_path: Path) -> None:
    n, chunk = 1_000_000, 8192
    path = tmp_path / "big.csv"
    k = np.arange(1, n + 1)
    with path.open("w") as f:
        f.write(HEADER + "\n")
        for lo in range(0, n, 100_000):
            t = k[lo : lo + 100_000] / 200.0
            block = np.column_stack(
                [t] + [np.full_like(t, v) for v in (0.1, -0.2, 0.3, 0.0, 0.0, 1.0)]
            )
            np.savetxt(f, block, delimiter=",", fmt="%.10g")
    size = path.stat().st_size
    assert size > 25e6  # the file: tens of MB; the buffer: 8192 rows (about 0.3 MB of text)
    tracemalloc.start()
    summary = ImuLog(path, chunk_rows=chunk).scan()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert summary.samples == n
    assert np.allclose(summary.dtheta_sum, np.array([0.1, -0.2, 0.3]) * DEG * n / 200.0)
    # bounded by the buffer, not the file: under 10 MB for a log of tens of MB
    assert peak < 10e6, (peak, size)
    assert peak < size / 3
