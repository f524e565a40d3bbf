"""Master-INS log replay: a block that fills the ``master_ins`` role from a recorded log.

For transfer alignment with a real ship's master INS. The log holds the master's
navigation solution at each sample time (:data:`cosim.sensors.logs.MASTER_INS`)::

    time [s],v_n [m/s],v_e [m/s],v_d [m/s],roll [deg],pitch [deg],yaw [deg],lat [deg],lon [deg],
    h [m]          (one line in the file)

These are *states*, not increments: nothing is summed. The first sample is the state at
the start time ``t0`` (the outputs after initialisation); each macro step of ``m = h f_s``
samples (a whole number, as for :class:`~cosim.sensors.replay.ImuLogReplay`) outputs the
last sample of the step, the state at ``t + h``. The samples in between are checked like
every other but not used (nothing is interpolated or averaged). Outputs are those of the
role (``fmus/interfaces/master_ins.toml``): ``v_master_n`` [m/s], ``rpy_master`` [rad],
``lat_master``, ``lon_master`` [rad], ``h_master`` [m]; the role's inputs (the true
state) are declared and ignored. Runs in-process (the ``log`` parameter names the file).
"""

from __future__ import annotations

import numpy as np

from cosim.models.block import input_, output
from cosim.sensors.replay import REPLAY_PARAMETERS, LogReplay


class MasterInsLogReplay(LogReplay):
    """Replay of a recorded master-INS log: its state at each macro step (role ``master_ins``)."""

    variables = (
        *REPLAY_PARAMETERS,
        input_("v_n", (0.0, 0.0, 0.0), "m/s", "true velocity NED (ignored: role input)"),
        input_("rpy", (0.0, 0.0, 0.0), "rad", "true attitude (ignored: role input)"),
        input_("lat", 0.0, "rad", "true latitude (ignored: role input)"),
        input_("lon", 0.0, "rad", "true longitude (ignored: role input)"),
        input_("h", 0.0, "m", "true height (ignored: role input)"),
        output("v_master_n", (0.0, 0.0, 0.0), "m/s", "logged master velocity, NED"),
        output("rpy_master", (0.0, 0.0, 0.0), "rad", "logged master attitude [roll, pitch, yaw]"),
        output("lat_master", 0.0, "rad", "logged master latitude"),
        output("lon_master", 0.0, "rad", "logged master longitude"),
        output("h_master", 0.0, "m", "logged master height"),
        output("log_time", 0.0, "s", "log time of the sample output"),
    )
    default_step = 0.01
    default_stop = 1.0
    layout = "MASTER_INS"
    covers_interval = False

    def initialize(self) -> None:
        self.open_log(self.layout)
        values, self.log_time = self.take(1, self.start_time, 0.0)
        self._publish(values[0])

    def _publish(self, x: np.ndarray) -> None:
        self.v_master_n = np.array(x[0:3])
        self.rpy_master = np.array(x[3:6])
        self.lat_master = float(x[6])
        self.lon_master = float(x[7])
        self.h_master = float(x[8])

    def step(self, t: float, h: float) -> None:
        m = self.samples_per_step(h)
        values, self.log_time = self.take(m, t, h)
        self._publish(values[-1])
