"""Log replay: a block that fills the ``imu`` role from a recorded IMU log.

Outputs are those of the role (``fmus/interfaces/imu.toml``): the measured increments
``dtheta_meas_b`` [rad] and ``dv_meas_b`` [m/s] over the macro step, and their means over
the step ``omega_meas_b`` [rad/s], ``f_meas_b`` [m/s2]. The role's inputs ``dtheta_b``,
``dv_b`` are declared so that the block drops into a scenario in place of
``StrapdownImu`` with the same connections; the replay ignores them (the log *is* the
measurement).

The log has its own sample rate ``f_s`` (``sample_rate``, or from its timestamps). A macro
step ``h`` must hold a whole number ``m = h f_s`` of samples (otherwise the step is
refused with the numbers: splitting a sample would mean interpolating it). Each step
replays the next ``m`` samples::

    dtheta_meas_b = fsum(dtheta_k, k = n m .. n m + m - 1)     (per axis, correctly rounded)

so a step of one sample reproduces the log's increments bit for bit and any step
conserves the log's total increment to rounding. Rate columns were integrated by the
reader (``rate_k (t_k - t_{k-1})``, exact for interval means: :mod:`cosim.sensors.logs`).
The first macro step starts with the log's first sample; ``log_time`` is the log time of
the last sample replayed.

In-process the parameter ``log`` names the file (relative paths from the working
directory); :meth:`initialize` checks the whole log first in one streaming pass, so a bad
log stops the run before its first step with the file, line and time. Inside an FMU
(:func:`cosim.sensors.fmu.build_replay_fmu`) ``log`` is empty and the block reads the
samples checked and converted at build time from the FMU's resources
(``imu_log/time.npy``, ``imu_log/increments.npy``, memory-mapped). Memory is bounded by
the read buffer (``chunk_rows``) in both cases.

Only numpy and ``models`` are imported at module level: the module runs inside an FMU.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Variability
from pythonfmu.variables import String

from cosim.models.block import Block, input_, output, parameter, same_step

#: Folder of the log inside an FMU's resources, and its files.
RESOURCE_DIR = "imu_log"
TIME_FILE = "time.npy"
INCREMENT_FILE = "increments.npy"
#: Relative tolerance on ``h f_s`` being a whole number.
RATIO_TOL = 1e-6


class ReplayError(ValueError):
    """The log cannot feed the run: a macro step the sample rate does not divide, or too short.

    Inside the run it reaches the user as the master's one-line error with block and time.
    """


def _npy_chunks(folder: Path, chunk_rows: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``(time, increments (n, 6))`` chunks of the converted log in an FMU's resources."""
    time = np.load(folder / TIME_FILE, mmap_mode="r")
    inc = np.load(folder / INCREMENT_FILE, mmap_mode="r")
    for lo in range(0, len(time), chunk_rows):
        yield np.array(time[lo : lo + chunk_rows]), np.array(inc[lo : lo + chunk_rows])


#: Parameters every log replay has.
REPLAY_PARAMETERS = (
    parameter("sample_rate", 0.0, "Hz", "log sample rate; 0: from its timestamps"),
    parameter("jitter", 0.05, "1", "tolerance on timestamps off the grid, in intervals"),
    parameter("drop_duplicates", False, description="drop rows repeating the previous row"),
    parameter("chunk_rows", 65536, description="read buffer [rows]"),
    parameter(
        "time_offset",
        0.0,
        "s",
        "this log's time stamps minus the run's common time (a clock offset between two logs); "
        "checked against the other log of the run, the samples are replayed as they are",
    ),
)


class LogReplay(Block):
    """Common part of the log replays: the ``log`` parameter, the read buffer, the step check.

    A subclass declares its variables (starting with :data:`REPLAY_PARAMETERS`), its
    :attr:`layout` and :attr:`covers_interval`, calls :meth:`open_log` in
    :meth:`initialize` and takes its samples with :meth:`take`.
    """

    #: Name of the :mod:`cosim.sensors.logs` layout the log has.
    layout = ""
    #: True when a sample is a quantity over the interval ending at its time stamp
    #: (increments), False when it is a state at its time stamp.
    covers_interval = False

    def __init__(self, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.log = ""
        self.register_variable(
            String(
                "log",
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.fixed,
                description="log file (.csv, .parquet, .h5); empty inside an FMU",
                getter=lambda: self.log,
                setter=lambda v: setattr(self, "log", v),
            ),
            nested=False,
        )

    def open_log(self, layout: str) -> None:
        """Check the whole log (one streaming pass), then open it for :meth:`take`.

        Parameters
        ----------
        layout : str
            Name of a :mod:`cosim.sensors.logs` layout: ``"IMU"`` or ``"MASTER_INS"``.

        Raises
        ------
        ReplayError
            ``chunk_rows < 1`` or an empty ``log``.
        LogError
            The log fails a check (file, line, time and fix).
        """
        rows = int(self.chunk_rows)
        if rows < 1:
            raise ReplayError(f"chunk_rows must be >= 1, got {rows}")
        if not self.log:
            raise ReplayError(f"{type(self).__name__}.log is empty: set it to the log file")
        from cosim.sensors import logs

        rate = float(self.sample_rate)
        log = logs.SensorLog(
            self.log,
            getattr(logs, layout),
            sample_rate=rate if rate > 0.0 else None,
            jitter=float(self.jitter),
            duplicates="drop" if self.drop_duplicates else "error",
            chunk_rows=rows,
        )
        summary = log.scan()  # every check, before the first step
        self.start_source(
            log.sample_rate, summary.samples, ((c.time, c.values) for c in log.chunks()), self.log
        )

    def start_source(
        self, rate: float, samples: int, source: Iterator[tuple[np.ndarray, np.ndarray]], name: str
    ) -> None:
        """Replay ``source`` from its first sample.

        Parameters
        ----------
        rate : float
            Sample rate [Hz].
        samples : int
            Samples in the source.
        source : iterator of (ndarray (n,), ndarray (n, k))
            Sample times [s] and values (SI), chunk by chunk.
        name : str
            The log, for messages.
        """
        self._rate, self._samples, self._source, self._name = rate, samples, source, name
        self._buf: np.ndarray | None = None
        self._buf_t = np.zeros(0)
        self._used = 0
        self._m_for: tuple[float, int] | None = None

    def samples_per_step(self, h: float) -> int:
        """Samples of the log in one macro step, checked.

        Parameters
        ----------
        h : float
            Macro step [s].

        Returns
        -------
        int
            ``m = h f_s``, >= 1.

        Raises
        ------
        ReplayError
            When ``h f_s`` is not a whole number (within :data:`RATIO_TOL`) or is < 1.
        """
        if self._m_for is not None and same_step(h, self._m_for[0]):
            return self._m_for[1]
        ratio = h * self._rate
        m = round(ratio)
        if m < 1 or abs(ratio - m) > RATIO_TOL * max(ratio, 1.0):
            dt = 1.0 / self._rate
            lo, hi = max(1, math.floor(ratio)), max(1, math.ceil(ratio))
            steps = f"{lo * dt:.9g} s" + ("" if lo == hi else f" or {hi * dt:.9g} s")
            raise ReplayError(
                f"macro step {h:.9g} s holds {ratio:.9g} samples of the log at "
                f"{self._rate:.9g} Hz (interval {dt:.9g} s): a step must hold a whole number "
                f"of samples (nothing is interpolated); use master.step = {steps} (or a "
                f"multiple of {dt:.9g} s), or resample the log"
            )
        self._m_for = (h, m)
        return m

    def take(self, m: int, t: float, h: float) -> tuple[np.ndarray, float]:
        """The next ``m`` samples.

        Parameters
        ----------
        m : int
            Samples.
        t, h : float
            The macro step asking [s], for the message when the log ends.

        Returns
        -------
        values : ndarray, shape (m, k)
            SI values (increments for an IMU log).
        time : float
            Log time of the last of them [s].

        Raises
        ------
        ReplayError
            The log ends before.
        """
        while self._buf is None or len(self._buf) < m:
            nxt = next(self._source, None)
            if nxt is None:
                dt = 1.0 / self._rate
                raise ReplayError(
                    f"{self._name} ends after {self._samples} samples "
                    f"({self._samples * dt:.9g} s at {self._rate:.9g} Hz); the step to "
                    f"{t + h:.9g} s needs {self._used + m}: set master.stop <= "
                    f"{self._samples * dt:.9g} s"
                )
            self._buf = nxt[1] if self._buf is None else np.concatenate([self._buf, nxt[1]])
            self._buf_t = np.concatenate([self._buf_t, nxt[0]])
        inc, self._buf = self._buf[:m], self._buf[m:]
        t_last, self._buf_t = float(self._buf_t[m - 1]), self._buf_t[m:]
        self._used += m
        return inc, t_last


class ImuLogReplay(LogReplay):
    """Replay of a recorded IMU log: measured increments per macro step (role ``imu``)."""

    #: The log's layout (:mod:`cosim.sensors.logs`); a sample is an increment over the
    #: interval ending at its time, so the log's data start one interval before its first
    #: time stamp (:mod:`cosim.sensors.pairing`).
    layout = "IMU"
    covers_interval = True

    variables = (
        *REPLAY_PARAMETERS,
        input_("dtheta_b", (0.0, 0.0, 0.0), "rad", "true angle increment (ignored: role input)"),
        input_("dv_b", (0.0, 0.0, 0.0), "m/s", "true velocity increment (ignored: role input)"),
        output("dtheta_meas_b", (0.0, 0.0, 0.0), "rad", "logged angle increment over the step"),
        output("dv_meas_b", (0.0, 0.0, 0.0), "m/s", "logged velocity increment over the step"),
        output("omega_meas_b", (0.0, 0.0, 0.0), "rad/s", "mean logged rate dtheta_meas_b / h"),
        output("f_meas_b", (0.0, 0.0, 0.0), "m/s2", "mean logged specific force dv_meas_b / h"),
        output("log_time", 0.0, "s", "log time of the last sample replayed"),
    )
    default_step = 0.01
    default_stop = 1.0

    # ------------------------------------------------------------ life cycle
    def initialize(self) -> None:
        folder = Path(self.resources or "") / RESOURCE_DIR
        if not self.log and self.resources and (folder / TIME_FILE).is_file():
            rows = int(self.chunk_rows)
            if rows < 1:
                raise ReplayError(f"chunk_rows must be >= 1, got {rows}")
            rate = float(self.sample_rate)
            stated = float(np.load(folder / "sample_rate.npy"))
            samples = len(np.load(folder / TIME_FILE, mmap_mode="r"))
            self.start_source(
                rate if rate > 0.0 else stated, samples, _npy_chunks(folder, rows), "the FMU's log"
            )
        else:
            self.open_log(self.layout)
        for name in ("dtheta_meas_b", "dv_meas_b", "omega_meas_b", "f_meas_b"):
            setattr(self, name, np.zeros(3))
        self.log_time = 0.0

    def step(self, t: float, h: float) -> None:
        m = self.samples_per_step(h)
        inc, self.log_time = self.take(m, t, h)
        if m == 1:
            total = inc[0].copy()
        else:
            total = np.array([math.fsum(inc[:, j]) for j in range(6)])
        self.dtheta_meas_b = total[:3]
        self.dv_meas_b = total[3:]
        self.omega_meas_b = total[:3] / h
        self.f_meas_b = total[3:] / h
