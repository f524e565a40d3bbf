"""Turntable: a hold / indexing / continuously rotating mount between a base and the sensors.

Frames: base ``b`` (the motion block's body frame), table ``t`` rotated by the
encoder angle ``gamma`` about the base z axis (down), sensor frame ``s`` fixed on
the table with the mounting rotation ``C_s_t = euler_to_dcm(mount_rpy)``::

    C_s_b(gamma) = Rz(gamma) @ C_s_t,      C_s_n = C_b_n(rpy) @ C_s_b

Seed 003's tilted rate-biasing mount (``C_a^i``: Z by gamma, Y by 90 deg + beta,
X by alpha) is ``mount_rpy = [alpha, pi/2 + beta, 0]``; the symmetric tilt that
puts the axis along ``[1, 1, 1]/sqrt(3)`` of the sensor frame is
``mount_rpy = [45 deg, -35.264 deg, 0]``.

Kinematics (``omega = omega_ib_b``, ``r = Rz(gamma) offset`` the sensor position from
the axis in base axes, derivatives taken in the base frame)::

    omega_is_s = C_s_t^T (Rz^T omega + gamma' e_z)
    f_s        = C_s_b^T (f_b + omega' x r + omega x (omega x r) + 2 omega x r' + r'')
    r'  = gamma' e_z x r,       r'' = gamma'' e_z x r + gamma' e_z x r'

(uniform gravity over the offset). Increments over ``[t, t + h]``::

    dtheta_s = C_s_t^T (integral Rz(gamma)^T omega dt + (gamma(t + h) - gamma(t)) e_z)
    dv_s     = integral f_s dt

The table angle is closed form, so its share of ``dtheta_s`` is exact; the
integrals are composite Simpson on ``n = round(h / dt_truth)`` sub-steps. The
base's path inside the step is rebuilt (:class:`models.step_paths.StepPath`)
from the previous and current step-end values and the increments: ``omega``
quartic from ``omega_ib_b``, ``omega_dot_b`` (optional input) and ``dtheta_b``;
``f_b`` quadratic from ``f_b`` and ``dv_b``. This is exact for a stationary base
(constant rate and specific force) and to ~h^5 for a smooth moving base. Inputs
must come from a block stepping at the same rate.

Angle profile ``gamma(t)`` (``mode``):

- 0, hold: ``gamma = angle0``.
- 1, indexing: at each ``index_times[k] >= 0`` (or when the previous move ends,
  if later) move to ``index_angles[k]`` with a trapezoidal rate profile limited by
  ``rate_limit`` and ``accel_limit`` (triangular when the move is short).
- 2, rate biasing: from ``rotation_start`` the rate is ``+-rate`` and reverses
  sign every ``reversal_period`` (``<= 0``: never); each half period is a
  trapezoidal rate pulse ``min(rate, A tau, A (T - tau))``, ``A = accel_limit``,
  so the rate passes through zero exactly at ``rotation_start + k T``.

``angle`` is the unwrapped encoder angle.
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, output, parameter
from cosim.models.constants import DEG
from cosim.models.conventions import cross, dcm_to_euler, euler_to_dcm, vec3
from cosim.models.earth import motion_inputs
from cosim.models.step_paths import StepPath, simpson_nodes, substeps


class Turntable(Block):
    """Single-axis turntable (hold, indexing, reversing rotation) carrying the sensors."""

    variables = (
        parameter("mode", 0, description="0 hold, 1 indexing, 2 continuous reversing rotation"),
        parameter("angle0", 0.0, "rad", "initial (and hold) table angle"),
        parameter("index_times", (200.0, -1.0, -1.0, -1.0), "s", "indexing times (< 0: unused)"),
        parameter("index_angles", (0.5 * math.pi, 0.0, 0.0, 0.0), "rad", "indexing target angles"),
        parameter("rate_limit", 30.0 * DEG, "rad/s", "indexing rate limit"),
        parameter("accel_limit", 200.0 * DEG, "rad/s2", "acceleration limit (modes 1, 2)"),
        parameter("rate", 100.0 * DEG, "rad/s", "rotation rate in mode 2"),
        parameter("reversal_period", 10.0, "s", "time between reversals in mode 2 (<= 0: none)"),
        parameter("rotation_start", 0.0, "s", "start of the rotation in mode 2"),
        parameter("mount_rpy", (0.0, 0.0, 0.0), "rad", "sensor mounting on the table, C_s_t"),
        parameter("offset", (0.0, 0.0, 0.0), "m", "sensor position from the axis, table frame"),
        parameter("dt_truth", 1.0e-3, "s", "inner integration step"),
        *motion_inputs(("omega_ib_b", "omega_dot_b", "f_b", "dtheta_b", "dv_b", "rpy"), "base"),
        output("omega_is_s", (0.0, 0.0, 0.0), "rad/s", "sensor rate w.r.t. inertial, sensor axes"),
        output("f_s", (0.0, 0.0, 0.0), "m/s2", "specific force at the sensor, sensor axes"),
        output("dtheta_s", (0.0, 0.0, 0.0), "rad", "integral of omega_is_s over the step"),
        output("dv_s", (0.0, 0.0, 0.0), "m/s", "integral of f_s over the step"),
        output("rpy_s", (0.0, 0.0, 0.0), "rad", "sensor attitude (roll, pitch, yaw of C_s_n)"),
        output("angle", 0.0, "rad", "encoder angle gamma (unwrapped)"),
        output("table_rate", 0.0, "rad/s", "table rate gamma'"),
        output("table_accel", 0.0, "rad/s2", "table acceleration gamma''"),
    )
    default_stop = 2.0

    def initialize(self) -> None:
        if self.mode not in (0, 1, 2):
            raise ValueError(f"Turntable.mode must be 0, 1 or 2, got {self.mode}")
        if self.mode in (1, 2) and not self.accel_limit > 0.0:
            raise ValueError("Turntable.accel_limit must be > 0 in modes 1 and 2")
        if self.mode == 1 and not self.rate_limit > 0.0:
            raise ValueError("Turntable.rate_limit must be > 0 in mode 1")
        if (
            self.mode == 2
            and self.reversal_period > 0.0
            and 2.0 * self.rate / self.accel_limit > self.reversal_period
        ):
            raise ValueError(
                "Turntable: reversal_period must be >= 2 rate / accel_limit "
                f"= {2.0 * self.rate / self.accel_limit:g} s"
            )
        self._c_s_t = euler_to_dcm(np.asarray(self.mount_rpy, dtype=float))
        self._offset = np.asarray(self.offset, dtype=float).copy()
        self._lever = bool(np.any(self._offset))
        self._moves = self._plan_moves() if self.mode == 1 else None
        self._nodes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._w_path = StepPath()
        self._w_path.reset(self.start_time, self.omega_ib_b, self.omega_dot_b)
        self._f_path = StepPath()
        self._f_path.reset(self.start_time, self.f_b)
        t0 = np.array([self.start_time])
        g, gd, gdd = self.profile(t0)
        w = np.asarray(self.omega_ib_b, dtype=float)[None, :]
        wd = np.asarray(self.omega_dot_b, dtype=float)[None, :]
        f = np.asarray(self.f_b, dtype=float)[None, :]
        w_s, f_s = self._sensor(g, gd, gdd, w, wd, f)
        self._publish(g, gd, gdd, w_s, f_s)
        self.dtheta_s = np.zeros(3)
        self.dv_s = np.zeros(3)

    # ------------------------------------------------------------ angle profile
    def _plan_moves(self) -> np.ndarray:
        """Rows ``[start, angle_from, sign, distance, t_acc, t_cruise, v_peak]`` per move."""
        a_max, v_max = float(self.accel_limit), float(self.rate_limit)
        pairs = sorted(
            (float(t), float(a))
            for t, a in zip(self.index_times, self.index_angles, strict=True)
            if t >= 0.0
        )
        rows, current, free_at = [], float(self.angle0), -math.inf
        for t_k, target in pairs:
            dist = abs(target - current)
            if dist == 0.0:
                continue
            start = max(t_k, free_at)
            if dist >= v_max * v_max / a_max:
                t_acc, t_cru, v_pk = v_max / a_max, (dist - v_max * v_max / a_max) / v_max, v_max
            else:
                t_acc = math.sqrt(dist / a_max)
                t_cru, v_pk = 0.0, a_max * t_acc
            rows.append(
                [start, current, math.copysign(1.0, target - current), dist, t_acc, t_cru, v_pk]
            )
            free_at = start + 2.0 * t_acc + t_cru
            current = target
        return np.array(rows, dtype=float).reshape(-1, 7)

    def profile(self, tt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Table angle [rad], rate [rad/s] and acceleration [rad/s2] at instants ``tt`` (m,).

        Parameters
        ----------
        tt : ndarray, shape (m,)
            Simulation times [s], any order.

        Returns
        -------
        angle, rate, accel : ndarray, shape (m,)
            Unwrapped encoder angle ``gamma`` about the base z axis (down) [rad], its
            rate [rad/s] and acceleration [rad/s2], from the parameters ``mode``,
            ``angle0``, ``rate``, ... (see the module docstring).
        """
        tt = np.asarray(tt, dtype=float)
        angle = np.full(tt.shape, float(self.angle0))
        zero = np.zeros(tt.shape)
        if self.mode == 0:
            return angle, zero, zero.copy()
        a_max = float(self.accel_limit)
        if self.mode == 1:
            moves = self._moves
            if moves.shape[0] == 0:
                return angle, zero, zero.copy()
            idx = np.searchsorted(moves[:, 0], tt, side="right") - 1
            active = idx >= 0
            mv = moves[np.maximum(idx, 0)]
            start, a0, sgn, dist, ta, tc, vp = mv.T
            tau = tt - start
            t_end = 2.0 * ta + tc
            left = t_end - tau
            pos = np.select(
                [tau < ta, tau < ta + tc, tau < t_end],
                [
                    0.5 * a_max * tau**2,
                    0.5 * a_max * ta**2 + vp * (tau - ta),
                    dist - 0.5 * a_max * left**2,
                ],
                dist,
            )
            vel = np.select(
                [tau < ta, tau < ta + tc, tau < t_end], [a_max * tau, vp, a_max * left], 0.0
            )
            acc = np.select([tau < ta, tau < ta + tc, tau < t_end], [a_max, 0.0, -a_max], 0.0)
            return (
                np.where(active, a0 + sgn * pos, angle),
                np.where(active, sgn * vel, 0.0),
                np.where(active, sgn * acc, 0.0),
            )
        # mode 2: reversing rotation
        r = float(self.rate)
        t1 = r / a_max
        u = tt - float(self.rotation_start)
        active = u >= 0.0
        u = np.maximum(u, 0.0)
        period = float(self.reversal_period)
        if period <= 0.0:
            pos = np.where(u < t1, 0.5 * a_max * u**2, 0.5 * r * t1 + r * (u - t1))
            vel = np.minimum(a_max * u, r)
            acc = np.where(u < t1, a_max, 0.0)
            return (
                np.where(active, angle + pos, angle),
                np.where(active, vel, 0.0),
                np.where(active, acc, 0.0),
            )
        k = np.floor(u / period)
        tau = u - k * period
        odd = np.mod(k, 2.0) == 1.0
        sgn = np.where(odd, -1.0, 1.0)
        left = period - tau
        pos = np.select(
            [tau <= t1, tau <= period - t1],
            [0.5 * a_max * tau**2, 0.5 * r * t1 + r * (tau - t1)],
            r * (period - t1) - 0.5 * a_max * left**2,
        )
        vel = np.minimum(np.minimum(a_max * tau, a_max * left), r)
        acc = np.select([tau < t1, tau < period - t1], [a_max, 0.0], -a_max)
        base = np.where(odd, r * (period - t1), 0.0)
        return (
            np.where(active, angle + base + sgn * pos, angle),
            np.where(active, sgn * vel, 0.0),
            np.where(active, sgn * acc, 0.0),
        )

    # ------------------------------------------------------------ kinematics
    def _sensor(
        self,
        g: np.ndarray,
        gd: np.ndarray,
        gdd: np.ndarray,
        w: np.ndarray,
        wd: np.ndarray,
        f: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Sensor rate and specific force (m, 3) from table angles (m,) and base values (m, 3)."""
        c, s = np.cos(g), np.sin(g)
        if self._lever:
            o = self._offset
            r = vec3(c * o[0] - s * o[1], s * o[0] + c * o[1], np.full(g.shape, o[2]))
            ezr = vec3(-r[:, 1], r[:, 0], np.zeros(g.shape))  # e_z x r
            r_dot = gd[:, None] * ezr
            r_ddot = gdd[:, None] * ezr - (gd * gd)[:, None] * vec3(
                r[:, 0], r[:, 1], np.zeros(g.shape)
            )
            f = f + cross(wd, r) + cross(w, cross(w, r)) + 2.0 * cross(w, r_dot) + r_ddot
        w_t = vec3(c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2] + gd)
        f_t = vec3(c * f[:, 0] + s * f[:, 1], -s * f[:, 0] + c * f[:, 1], f[:, 2])
        return w_t @ self._c_s_t, f_t @ self._c_s_t

    def _publish(
        self, g: np.ndarray, gd: np.ndarray, gdd: np.ndarray, w_s: np.ndarray, f_s: np.ndarray
    ) -> None:
        self.angle = float(g[-1])
        self.table_rate = float(gd[-1])
        self.table_accel = float(gdd[-1])
        self.omega_is_s = w_s[-1].copy()
        self.f_s = f_s[-1].copy()
        c, s = math.cos(self.angle), math.sin(self.angle)
        rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        c_s_n = euler_to_dcm(np.asarray(self.rpy, dtype=float)) @ rz @ self._c_s_t
        self.rpy_s = dcm_to_euler(c_s_n)

    def step(self, t: float, h: float) -> None:
        n = substeps(h, self.dt_truth)
        if n not in self._nodes:
            self._nodes[n] = simpson_nodes(n)
        s, wts = self._nodes[n]
        g, gd, gdd = self.profile(t + h * s)
        w, wd = self._w_path.nodes(t, h, self.omega_ib_b, self.dtheta_b, s, self.omega_dot_b)
        f, _ = self._f_path.nodes(t, h, self.f_b, self.dv_b, s)
        w_s, f_s = self._sensor(g, gd, gdd, w, wd, f)
        # Table share of the angle increment from the closed-form angle (exact).
        w_base = w_s - gd[:, None] * self._c_s_t[2, :]
        self.dtheta_s = h * (wts @ w_base) + (g[-1] - g[0]) * self._c_s_t[2, :]
        self.dv_s = h * (wts @ f_s)
        self._publish(g, gd, gdd, w_s, f_s)
