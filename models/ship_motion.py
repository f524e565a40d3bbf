"""Moored ship: sinusoidal roll/pitch/yaw and optional surge/sway/heave (truth motion).

Equations (per axis ``k``; ``rpy = [roll, pitch, yaw]``, Z-Y-X Euler angles of
``C_b_n``, see :mod:`models.conventions`)::

    rpy_k(t)  = rpy_mean_k + amp_k sin(w_k t + phase_k),     w_k = 2 pi / period_k
    rpy_k'    = amp_k w_k cos(w_k t + phase_k)
    rpy_k''   = -amp_k w_k^2 sin(w_k t + phase_k)

    d_l(t)    = lin_amp sin(wl t + lin_phase)     (surge, sway, heave) in the level frame
                                                 of the mean heading (x along it, z down)
    d_n       = Rz(yaw_mean) d_l,   v_n = d_n',   a_n = d_n''

    omega_nb_b from the Euler rates (exact, conventions.euler_rate_to_body_rate)
    omega_ib_b = omega_nb_b + C_n_b (omega_ie_n + omega_en_n)
    f_b        = C_n_b (a_n + (2 omega_ie_n + omega_en_n) x v_n - g_n(L, h))
    omega_dot_b = d(omega_ib_b)/dt in body axes (analytic)

Position: ``L = L0 + d_N / (R_M + h0)``, ``lon = lon0 + d_E / ((R_N + h0) cos L0)``,
``h = h0 - d_D`` (first order in the metre-sized displacement). Everything at an
instant is closed form; the increments over a step are the plain integrals

    dtheta_b = integral omega_ib_b dt,    dv_b = integral f_b dt      (over [t, t + h])

by composite Simpson on ``n = round(h / dt_truth)`` sub-steps (error ~ dt^4 |f''''|,
below 1e-15 of the increment at the defaults). They contain no coning or sculling
correction: they are what an ideal strapdown IMU measures; the navigation
algorithm applies the compensations. A period <= 0 switches that axis off.

Defaults follow seed 001: latitude 30 deg, roll 12.5 deg / 12 s, pitch 10 deg / 6 s,
yaw 5 deg / 8 s about a mean heading of 0, no linear motion.
"""

from __future__ import annotations

import math

import numpy as np

from models.block import Block, output, parameter
from models.conventions import simpson_nodes, substeps
from models.earth import ImuTruth, euler_motion_truth

_DEG = math.pi / 180.0


class ShipMotion(Block):
    """Moored ship motion: sinusoidal attitude and linear motion, exact rates and specific force."""

    variables = (
        parameter("lat0", 30.0 * _DEG, "rad", "latitude of the mooring"),
        parameter("lon0", 0.0, "rad", "longitude of the mooring"),
        parameter("h0", 0.0, "m", "height of the master IMU above the ellipsoid"),
        parameter("rpy_mean", (0.0, 0.0, 0.0), "rad", "mean roll, pitch, heading"),
        parameter("amp", (12.5 * _DEG, 10.0 * _DEG, 5.0 * _DEG), "rad", "roll/pitch/yaw amplitude"),
        parameter("period", (12.0, 6.0, 8.0), "s", "roll/pitch/yaw period (<= 0: axis off)"),
        parameter("phase", (0.0, 0.0, 0.0), "rad", "roll/pitch/yaw phase"),
        parameter("lin_amp", (0.0, 0.0, 0.0), "m", "surge/sway/heave amplitude"),
        parameter("lin_period", (10.0, 10.0, 10.0), "s", "surge/sway/heave period (<= 0: off)"),
        parameter("lin_phase", (0.0, 0.0, 0.0), "rad", "surge/sway/heave phase"),
        parameter("dt_truth", 1.0e-3, "s", "inner integration step for the increments"),
        output("rpy", (0.0, 0.0, 0.0), "rad", "roll, pitch, yaw of C_b_n at the step end"),
        output("v_n", (0.0, 0.0, 0.0), "m/s", "velocity w.r.t. earth, NED"),
        output("lat", 0.0, "rad", "latitude"),
        output("lon", 0.0, "rad", "longitude"),
        output("h", 0.0, "m", "height"),
        output("omega_ib_b", (0.0, 0.0, 0.0), "rad/s", "body rate w.r.t. inertial, body axes"),
        output("omega_dot_b", (0.0, 0.0, 0.0), "rad/s2", "time derivative of omega_ib_b"),
        output("f_b", (0.0, 0.0, 0.0), "m/s2", "specific force, body axes"),
        output("dtheta_b", (0.0, 0.0, 0.0), "rad", "integral of omega_ib_b over the step"),
        output("dv_b", (0.0, 0.0, 0.0), "m/s", "integral of f_b over the step"),
    )
    default_stop = 2.0

    def initialize(self) -> None:
        per = np.asarray(self.period, dtype=float)
        self._w = np.where(per > 0.0, 2.0 * np.pi / np.where(per > 0.0, per, 1.0), 0.0)
        self._amp = np.where(per > 0.0, np.asarray(self.amp, dtype=float), 0.0)
        lper = np.asarray(self.lin_period, dtype=float)
        self._wl = np.where(lper > 0.0, 2.0 * np.pi / np.where(lper > 0.0, lper, 1.0), 0.0)
        self._lamp = np.where(lper > 0.0, np.asarray(self.lin_amp, dtype=float), 0.0)
        self._moving = bool(np.any(self._lamp != 0.0))
        cy, sy = math.cos(self.rpy_mean[2]), math.sin(self.rpy_mean[2])
        self._c_l_n = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        self._nodes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        truth = self._truth(np.array([self.start_time]))
        self._publish(truth)
        self.dtheta_b = np.zeros(3)
        self.dv_b = np.zeros(3)

    def _truth(self, tt: np.ndarray) -> ImuTruth:
        """Closed-form trajectory and inertial truth at the instants ``tt`` (shape (m,))."""
        arg = tt[:, None] * self._w + np.asarray(self.phase)
        sa, ca = np.sin(arg), np.cos(arg)
        rpy = np.asarray(self.rpy_mean) + self._amp * sa
        rpy_dot = self._amp * self._w * ca
        rpy_ddot = -self._amp * self._w**2 * sa
        if not self._moving:
            self._last = (rpy[-1], np.zeros(3))
            return euler_motion_truth(rpy, rpy_dot, rpy_ddot, None, None, None, *self._ref())
        argl = tt[:, None] * self._wl + np.asarray(self.lin_phase)
        sl, cl = np.sin(argl), np.cos(argl)
        c = self._c_l_n.T  # row vectors: x_n = x_l @ C_l_n.T
        d_n = (self._lamp * sl) @ c
        v_n = (self._lamp * self._wl * cl) @ c
        a_n = (-self._lamp * self._wl**2 * sl) @ c
        self._last = (rpy[-1], v_n[-1])
        return euler_motion_truth(rpy, rpy_dot, rpy_ddot, d_n, v_n, a_n, *self._ref())

    def _ref(self) -> tuple[float, float, float]:
        return float(self.lat0), float(self.lon0), float(self.h0)

    def _publish(self, truth: ImuTruth) -> None:
        rpy, v_n = self._last
        self.rpy = np.array(rpy)
        self.rpy[2] = math.remainder(self.rpy[2], 2.0 * math.pi)
        self.v_n = np.array(v_n)
        self.lat = float(truth.lat[-1])
        self.lon = float(truth.lon[-1])
        self.h = float(truth.h[-1])
        self.omega_ib_b = truth.omega_ib_b[-1].copy()
        self.omega_dot_b = truth.omega_dot_b[-1].copy()
        self.f_b = truth.f_b[-1].copy()

    def step(self, t: float, h: float) -> None:
        n = substeps(h, self.dt_truth)
        if n not in self._nodes:
            self._nodes[n] = simpson_nodes(n)
        s, w = self._nodes[n]
        truth = self._truth(t + h * s)
        self.dtheta_b = h * (w @ truth.omega_ib_b)
        self.dv_b = h * (w @ truth.f_b)
        self._publish(truth)
