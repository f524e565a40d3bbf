"""Land vehicle driving straight: along-track speed profile, road-induced attitude (truth motion).

Equations (``rpy = [roll, pitch, yaw]``, Z-Y-X Euler angles of ``C_b_n``, see
:mod:`models.conventions`; the course is the mean yaw ``rpy_mean[3]``)::

    speed  u(t)  = speed0 + accel t + speed_amp sin(wu t),        wu = 2 pi / speed_period
    along  s(t)  = speed0 t + accel t^2 / 2 + speed_amp (1 - cos(wu t)) / wu
    u'(t)        = accel + speed_amp wu cos(wu t)
    d_n = Rz(yaw_mean) [s, 0, 0],  v_n = Rz(yaw_mean) [u, 0, 0],  a_n = Rz(yaw_mean) [u', 0, 0]

    rpy_k(t) = rpy_mean_k + amp_k sin(w_k t + phase_k),   w_k = 2 pi / period_k   (per axis)

The attitude oscillation is the body's response to the road (roll and pitch of a few
tenths of a degree at periods of 1-5 s) and a small yaw wander; the path stays on the
straight course (the yaw wander is a crab of ``u amp_3`` m/s at most, no lateral path):
a land vehicle's lateral accelerations are not modelled. Inertial truth (rates, specific
force, their exact increments) as in :func:`models.earth.euler_motion_truth`::

    omega_ib_b = omega_nb_b + C_n_b (omega_ie_n + omega_en_n)
    f_b        = C_n_b (a_n + (2 omega_ie_n + omega_en_n) x v_n - g_n(L, h))

Position to first order in the distance driven (``L = L0 + d_N / (R_M + h0)``; error
``|d|^2 / R``, 0.3 m after 1.4 km). Increments over a step by composite Simpson on
``round(h / dt_truth)`` sub-steps, as :class:`models.blocks.ship_motion.ShipMotion`: what an
ideal strapdown IMU measures (no coning or sculling correction). The truth is closed form
in time, so :data:`AHEAD_STEPS` steps on the master's grid are evaluated in one call (a
step off that grid starts a new evaluation). A period <= 0 switches
that axis (or the speed oscillation) off.

Defaults: the transfer-alignment land vehicle of ``scenarios/transfer_alignment_vehicle.toml``
(issue 26): 12.5 m/s accelerating at 0.025 m/s2 (15 m/s after 100 s) with a 1 m/s
speed oscillation over 20 s, roll 0.3 deg / 2.5 s, pitch 0.2 deg / 1.7 s, yaw 0.3 deg / 9 s,
course 60 deg, latitude 34.2 deg.
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import STEP_RTOL, Block, parameter, same_step
from cosim.models.constants import DEG
from cosim.models.earth import MOTION_OUTPUTS, ImuTruth, euler_motion_truth
from cosim.models.step_paths import simpson_nodes, substeps


class LandVehicle(Block):
    """Land vehicle on a straight course: speed ramp and oscillation, sinusoidal attitude."""

    variables = (
        parameter("lat0", 34.2 * DEG, "rad", "latitude at the start"),
        parameter("lon0", 0.0, "rad", "longitude at the start"),
        parameter("h0", 0.0, "m", "height of the master IMU above the ellipsoid"),
        parameter("rpy_mean", (0.0, 0.0, 60.0 * DEG), "rad", "mean roll, pitch; course (yaw)"),
        parameter("amp", (0.3 * DEG, 0.2 * DEG, 0.3 * DEG), "rad", "roll/pitch/yaw amplitude"),
        parameter("period", (2.5, 1.7, 9.0), "s", "roll/pitch/yaw period (<= 0: axis off)"),
        parameter("phase", (0.0, 0.0, 0.0), "rad", "roll/pitch/yaw phase"),
        parameter("speed0", 12.5, "m/s", "speed at the start (along the course)"),
        parameter("accel", 0.025, "m/s2", "constant along-track acceleration"),
        parameter("speed_amp", 1.0, "m/s", "amplitude of the speed oscillation"),
        parameter("speed_period", 20.0, "s", "period of the speed oscillation (<= 0: off)"),
        parameter("dt_truth", 1.0e-3, "s", "inner integration step for the increments"),
        *MOTION_OUTPUTS,
    )
    default_step = 0.01
    default_stop = 2.0

    def initialize(self) -> None:
        if not self.dt_truth > 0.0:
            raise ValueError(f"LandVehicle.dt_truth must be > 0 s, got {self.dt_truth}")
        per = np.asarray(self.period, dtype=float)
        self._w = np.where(per > 0.0, 2.0 * np.pi / np.where(per > 0.0, per, 1.0), 0.0)
        self._amp = np.where(per > 0.0, np.asarray(self.amp, dtype=float), 0.0)
        sp = float(self.speed_period)
        self._wu = 2.0 * math.pi / sp if sp > 0.0 else 0.0
        self._uamp = float(self.speed_amp) if sp > 0.0 else 0.0
        yaw = float(self.rpy_mean[2])
        self._course = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        self._nodes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._ahead: tuple[list[float], float, np.ndarray, int] | None = None
        truth, rpy, v_n = self._truth(np.array([self.start_time]))
        self._publish(truth, rpy, v_n, 0)
        self.dtheta_b[:] = 0.0
        self.dv_b[:] = 0.0

    def _truth(self, tt: np.ndarray) -> tuple[ImuTruth, np.ndarray, np.ndarray]:
        """Closed-form trajectory and inertial truth at the instants ``tt`` [s], shape (m,).

        Returns
        -------
        truth : ImuTruth
            Inertial quantities at ``tt``.
        rpy, v_n : ndarray, shape (m, 3)
            Euler angles [rad] and NED velocity [m/s].
        """
        arg = tt[:, None] * self._w + np.asarray(self.phase, dtype=float)
        sa, ca = np.sin(arg), np.cos(arg)
        rpy = np.asarray(self.rpy_mean, dtype=float) + self._amp * sa
        rpy_dot = self._amp * self._w * ca
        rpy_ddot = -self._amp * self._w**2 * sa
        u0, acc = float(self.speed0), float(self.accel)
        if self._wu > 0.0:
            su, cu = np.sin(self._wu * tt), np.cos(self._wu * tt)
            along = u0 * tt + 0.5 * acc * tt**2 + self._uamp * (1.0 - cu) / self._wu
            speed = u0 + acc * tt + self._uamp * su
            rate = acc + self._uamp * self._wu * cu
        else:
            along = u0 * tt + 0.5 * acc * tt**2
            speed = u0 + acc * tt
            rate = np.full_like(tt, acc)
        d_n = along[:, None] * self._course
        v_n = speed[:, None] * self._course
        a_n = rate[:, None] * self._course
        ref = (float(self.lat0), float(self.lon0), float(self.h0))
        return euler_motion_truth(rpy, rpy_dot, rpy_ddot, d_n, v_n, a_n, *ref), rpy, v_n

    def _publish(self, truth: ImuTruth, rpy: np.ndarray, v_n: np.ndarray, i: int) -> None:
        """Set the state outputs from row ``i`` of the evaluated truth."""
        self.rpy[:] = rpy[i]
        self.rpy[2] = math.remainder(self.rpy[2], 2.0 * math.pi)
        self.v_n[:] = v_n[i]
        self.lat = float(truth.lat[i])
        self.lon = float(truth.lon[i])
        self.h = float(truth.h[i])
        self.omega_ib_b[:] = truth.omega_ib_b[i]
        self.omega_dot_b[:] = truth.omega_dot_b[i]
        self.f_b[:] = truth.f_b[i]

    def step(self, t: float, h: float) -> None:
        ahead = self._ahead
        if ahead is None or not (
            ahead[3] < len(ahead[0])
            and abs(ahead[0][ahead[3]] - t) <= STEP_RTOL * h
            and same_step(h, ahead[1])
        ):
            ahead = self._look_ahead(t, h)
        k = ahead[3]
        self._ahead = (ahead[0], ahead[1], ahead[2], k + 1)
        rows = ahead[2]
        self.rpy[:] = rows[k, 0:3]
        self.v_n[:] = rows[k, 3:6]
        self.lat, self.lon, self.h = rows[k, 6:9].tolist()
        self.omega_ib_b[:] = rows[k, 9:12]
        self.omega_dot_b[:] = rows[k, 12:15]
        self.f_b[:] = rows[k, 15:18]
        self.dtheta_b[:] = rows[k, 18:21]
        self.dv_b[:] = rows[k, 21:24]

    def _look_ahead(self, t: float, h: float) -> tuple[list[float], float, np.ndarray, int]:
        """Evaluate :data:`AHEAD_STEPS` steps of size ``h`` from ``t`` in one vectorised call.

        Returns the step starts, ``h``, the rows (step-end ``rpy`` (yaw wrapped), ``v_n``,
        ``lat, lon, h``, ``omega_ib_b``, ``omega_dot_b``, ``f_b``, then ``dtheta_b``,
        ``dv_b``: 24 values per step) and the next row to serve (0).
        """
        n = substeps(h, self.dt_truth)
        if n not in self._nodes:
            self._nodes[n] = simpson_nodes(n)
        s, w = self._nodes[n]
        starts = t + h * np.arange(AHEAD_STEPS)
        truth, rpy, v_n = self._truth((starts[:, None] + h * s).ravel())
        m = len(s)
        ends = np.arange(1, AHEAD_STEPS + 1) * m - 1
        rows = np.concatenate(
            [
                rpy[ends],
                v_n[ends],
                np.stack([truth.lat[ends], truth.lon[ends], truth.h[ends]], axis=1),
                truth.omega_ib_b[ends],
                truth.omega_dot_b[ends],
                truth.f_b[ends],
                h * np.einsum("j,kjc->kc", w, truth.omega_ib_b.reshape(AHEAD_STEPS, m, 3)),
                h * np.einsum("j,kjc->kc", w, truth.f_b.reshape(AHEAD_STEPS, m, 3)),
            ],
            axis=1,
        )
        rows[:, 2] = [math.remainder(y, 2.0 * math.pi) for y in rows[:, 2].tolist()]
        return starts.tolist(), h, rows, 0


#: Steps evaluated in one vectorised call.
AHEAD_STEPS = 64
