"""Pack a recorded IMU log and the replay block into an FMI 2.0 co-simulation FMU.

The FMU is :func:`cosim.interop.packaging.build_fmu` of
:class:`~cosim.sensors.replay.ImuLogReplay` with two folders added to its resources:

``imu_log/``
    the log checked and converted at build time (:class:`~cosim.sensors.logs.ImuLog`,
    every check of the reader): ``time.npy`` (n,) [s], ``increments.npy`` (n, 6) SI
    increments (dtheta [rad], dv [m/s], body axes), ``sample_rate.npy`` [Hz], and a copy of
    the original file for provenance;
``cosim/``
    a package holding only ``cosim/sensors/replay.py`` (and empty ``__init__`` files), so
    the FMU needs no more than the interpreter's numpy and pythonfmu, like the FMUs of
    ``models/``; pint and the readers stay at build time.

The FMU's parameter ``log`` is empty: the block then replays its resources
(:meth:`ImuLogReplay.initialize`). ``ins-cosim check-fmu FMU --role imu`` reports that it
fills the ``imu`` role.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

import cosim.sensors
from cosim.interop.packaging import build_fmu
from cosim.sensors import replay
from cosim.sensors.logs import CHUNK_ROWS, JITTER, ImuLog


def build_replay_fmu(
    log: str | Path,
    out_dir: str | Path,
    *,
    sample_rate: float | None = None,
    jitter: float = JITTER,
    duplicates: str = "error",
    chunk_rows: int = CHUNK_ROWS,
) -> Path:
    """Build ``out_dir/ImuLogReplay.fmu`` that replays ``log``.

    Parameters
    ----------
    log : str or Path
        The recorded log (:mod:`cosim.sensors.logs` formats).
    out_dir : str or Path
        Destination folder (created if missing).
    sample_rate : float, optional
        Nominal sample rate [Hz]; default from the timestamps.
    jitter : float, optional
        Timestamp tolerance in sample intervals (:class:`~cosim.sensors.logs.ImuLog`).
    duplicates : {"error", "drop"}, optional
        Duplicate-row policy.
    chunk_rows : int, optional
        Rows converted at a time (memory bound of the build).

    Returns
    -------
    Path
        The FMU file.

    Raises
    ------
    LogError
        A log that fails a check: nothing is built.
    """
    reader = ImuLog(
        log, sample_rate=sample_rate, jitter=jitter, duplicates=duplicates, chunk_rows=chunk_rows
    )
    summary = reader.scan()
    with tempfile.TemporaryDirectory(prefix="ins_cosim_replay_") as tmp:
        data = Path(tmp) / replay.RESOURCE_DIR
        data.mkdir()
        times = np.lib.format.open_memmap(
            data / replay.TIME_FILE, mode="w+", dtype=float, shape=(summary.samples,)
        )
        inc = np.lib.format.open_memmap(
            data / replay.INCREMENT_FILE, mode="w+", dtype=float, shape=(summary.samples, 6)
        )
        for chunk in reader.chunks():
            lo, hi = chunk.first, chunk.first + len(chunk.time)
            times[lo:hi] = chunk.time
            inc[lo:hi] = chunk.values
        times.flush()
        inc.flush()
        del times, inc
        np.save(data / "sample_rate.npy", np.array(reader.sample_rate))
        shutil.copy2(log, data / Path(log).name)
        package = Path(tmp) / "cosim"
        (package / "sensors").mkdir(parents=True)
        (package / "__init__.py").write_text('"""The part of ins-cosim a replay FMU carries."""\n')
        shutil.copy2(cosim.sensors.__file__, package / "sensors" / "__init__.py")
        shutil.copy2(replay.__file__, package / "sensors" / "replay.py")
        return build_fmu(replay.ImuLogReplay, Path(out_dir), extra_files=(package, data))
