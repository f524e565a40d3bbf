"""Gimballed HRG inertial platform on a stationary base (seed 000): truth dynamics.

Frames
------
``n`` is the local geographic frame **ENU** (east, north, up) and ``p`` the paper's
platform frame (x, y level, z up), as in :mod:`models.blocks.hrg_platform_gyro`: at azimuth
``A = 0`` the platform axes are east, north, up, and ``A`` is the rotation about up,
**positive counter-clockwise seen from above**. The platform attitude is the exact
direction cosine matrix ``C = C_p_n`` (``v_n = C v_p``), written with the paper's
"large azimuth, small tilt" split::

    C = exp([phi x]) Rz(A),   phi = [theta_E, theta_N, 0],
    Rz(A) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]

``theta_E``, ``theta_N`` are the level misalignments (rotations about geographic east
and north; the horizontal rotation vector that turns the local vertical onto the
platform z axis) and ``A`` the platform azimuth, which may be anything. Nothing in
this block is linearised in ``A`` or in the tilts.

Dynamics
--------
After coarse levelling the two level gimbal loops are released (no torque command),
so the level axes hold their orientation in inertial space; the azimuth loop is
commanded with the vertical earth rate so that the azimuth follows the earth; at
``index_time`` the azimuth loop turns the platform by ``index_angle`` (the 90 deg
indexing of the two-position method) with a trapezoidal rate profile ``alpha(t)``
limited by ``index_rate`` and ``index_accel``. Each gyro loop nulls the gyro output
minus its command, so a gyro error ``eps = omega_meas_p - omega_ip_p`` (input
``omega_err_p``, from :class:`~models.blocks.hrg_platform_gyro.HrgPlatformGyro`) turns the
platform the other way. The platform's inertial rate, in its own axes, is therefore::

    omega_ip_p = [0, 0, (1 + dk_z) Omega sin L + alpha'(t)] - eps

(``dk_z``: scale-factor error of the azimuth torque command, the ``(1 + delta k_z)`` of
seed 000 eq. 5). The attitude follows exactly from
``C' = C [omega_ip_p x] - [omega_in_n x] C`` with ``omega_in_n = Omega [0, cos L, sin L]``
(stationary base, no transport rate)::

    C(t + h) = exp(-[omega_in_n x] h) C(t) prod_j exp([omega_ip_p(t_j) x] delta)

one exact exponential per step when the platform is not indexing (the rates are then
constant over the step), ``n = round(h / dt_truth)`` sub-steps carrying the exact
profile increments ``alpha(t_(j+1)) - alpha(t_j)`` while it is. Linearised in the tilts
(and only there) this is eq. (5) of seed 000 with the full large-azimuth matrix::

    theta_E' =  Omega sin L theta_N + d_E
    theta_N' = -Omega sin L theta_E - Omega cos L + d_N,      d = -Rz(A) eps  (east, north)
    A'       = -eps_z + dk_z Omega sin L  (+ alpha' while indexing)

so the free level axes tilt about north at the earth rate ``Omega cos L`` (35' in 200 s
at 45 deg), and the gyro drifts enter rotated by the (large) azimuth.

Outputs (values at the end of the step)
---------------------------------------
- ``f_p = C^T [0, 0, g]``: the specific force along the platform axes (input of
  :class:`~models.blocks.platform_accelerometer.PlatformAccelerometer`). Linearised:
  ``f_x = g (sin A theta_E - cos A theta_N)``, ``f_y = g (cos A theta_E + sin A theta_N)``.
- ``omega_ip_p`` and ``azimuth``: the inputs of the gyro triad.
- ``theta_E``, ``theta_N``, ``azimuth``: the true misalignment, for error signals.
- ``drift_rate_n = -C eps``: the platform's drift rate caused by the gyro errors, ENU.
- ``position``: 1 until ``index_time``, 0 while indexing and for ``settle_time`` after,
  then 2 (1 for ever when ``index_time < 0``). A filter uses a step only when the
  status is the same non-zero value at both its ends.

The gyro-to-platform connection closes the (real) servo loop; under Gauss-Seidel
the master delays it by one macro step and says so. Constant drifts are unaffected.

Assumptions (seed 000 is silent or garbled; all are parameters)
-----------------------------------------------------------------
- Indexing profile: trapezoidal rate, default 10 deg/s and 10 deg/s^2 (10 s for 90 deg);
  ``index_error`` is the positioning error of the indexing (the paper's ``delta < 6'``).
- Gravity is ``g`` along the local vertical; the paper's g = 9.7966 m/s^2 by default.
- The base is perfectly still (no sway, no vibration).
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, input_, output, parameter, same_step
from cosim.models.constants import ARCMIN, DEG, OMEGA_IE
from cosim.models.conventions import rot_z, rotvec_to_dcm
from cosim.models.step_paths import substeps

_V3 = (0.0, 0.0, 0.0)


def indexing_profile(
    tau: float, angle: float, rate: float, accel: float
) -> tuple[float, float, float]:
    """Trapezoidal rate profile of one indexing move.

    Parameters
    ----------
    tau : float
        Time since the start of the move [s].
    angle : float
        Signed angle to turn [rad].
    rate : float
        Largest rate [rad/s], > 0.
    accel : float
        Angular acceleration and deceleration [rad/s^2], > 0.

    Returns
    -------
    alpha : float
        Angle turned so far [rad] (0 before, ``angle`` after the move).
    alpha_dot : float
        Rate [rad/s].
    duration : float
        Length of the whole move [s] (triangular when ``|angle| < rate^2 / accel``).
    """
    size = abs(angle)
    sign = 1.0 if angle >= 0.0 else -1.0
    if size >= rate * rate / accel:
        t_acc = rate / accel
        peak = rate
        t_cruise = (size - rate * rate / accel) / rate
    else:
        t_acc = math.sqrt(size / accel)
        peak = accel * t_acc
        t_cruise = 0.0
    duration = 2.0 * t_acc + t_cruise
    if tau <= 0.0:
        return 0.0, 0.0, duration
    if tau >= duration:
        return angle, 0.0, duration
    if tau < t_acc:
        return sign * 0.5 * accel * tau * tau, sign * accel * tau, duration
    if tau < t_acc + t_cruise:
        return sign * (0.5 * accel * t_acc * t_acc + peak * (tau - t_acc)), sign * peak, duration
    rest = duration - tau
    return sign * (size - 0.5 * accel * rest * rest), sign * accel * rest, duration


def split_attitude(c_p_n: np.ndarray) -> tuple[float, float, float]:
    """Level misalignments and azimuth of a platform DCM, ``C = exp([phi x]) Rz(A)``.

    Parameters
    ----------
    c_p_n : ndarray, shape (3, 3)
        Platform-to-ENU direction cosine matrix.

    Returns
    -------
    theta_E, theta_N : float
        Tilt rotation vector components about east and north [rad] (exact, any size
        below 180 deg).
    azimuth : float
        Platform azimuth ``A`` in (-pi, pi] [rad], counter-clockwise from east/north.
    """
    z = c_p_n[:, 2]
    horizontal = math.hypot(z[0], z[1])
    angle = math.atan2(horizontal, z[2])
    scale = angle / horizontal if horizontal > 1e-300 else 1.0
    phi = np.array([-z[1] * scale, z[0] * scale, 0.0])
    level = rotvec_to_dcm(-phi) @ c_p_n
    return float(phi[0]), float(phi[1]), math.atan2(level[1, 0], level[0, 0])


class HrgPlatform(Block):
    """Gimballed HRG platform on a stationary base: free level axes, 90 deg azimuth indexing."""

    variables = (
        parameter("lat", 45.0 * DEG, "rad", "geodetic latitude L"),
        parameter("g", 9.7966, "m/s2", "gravity magnitude"),
        parameter("azimuth0", 100.0 * DEG, "rad", "initial platform azimuth A (CCW from ENU)"),
        parameter("theta_E0", 3.0 * ARCMIN, "rad", "initial level misalignment about east"),
        parameter("theta_N0", 3.0 * ARCMIN, "rad", "initial level misalignment about north"),
        parameter("index_time", 200.0, "s", "start of the indexing move (< 0: never)"),
        parameter("index_angle", 90.0 * DEG, "rad", "commanded indexing angle (CCW > 0)"),
        parameter("index_error", 0.0, "rad", "indexing error: turned minus commanded angle"),
        parameter("index_rate", 10.0 * DEG, "rad/s", "largest indexing rate"),
        parameter("index_accel", 10.0 * DEG, "rad/s2", "indexing acceleration"),
        parameter("settle_time", 0.0, "s", "wait after the move before position = 2"),
        parameter("torque_scale_error", 0.0, "1", "scale error dk_z of the azimuth command"),
        parameter("dt_truth", 0.01, "s", "inner step while indexing"),
        input_("omega_err_p", _V3, "rad/s", "gyro error rates (measured - true), p axes"),
        output("omega_ip_p", _V3, "rad/s", "inertial angular rate of the platform, p axes"),
        output("azimuth", 100.0 * DEG, "rad", "platform azimuth A in (-pi, pi]"),
        output("f_p", _V3, "m/s2", "specific force along the platform axes"),
        output("theta_E", 3.0 * ARCMIN, "rad", "level misalignment about east"),
        output("theta_N", 3.0 * ARCMIN, "rad", "level misalignment about north"),
        output("drift_rate_n", _V3, "rad/s", "platform drift rate from gyro errors, ENU"),
        output("position", 1.0, "1", "1: position 1, 0: indexing or settling, 2: position 2"),
    )
    default_step = 0.01
    default_stop = 1.0
    shared_values = {"lat": "latitude", "g": "gravity"}

    def initialize(self) -> None:
        if not self.g > 0.0:
            raise ValueError(f"HrgPlatform.g must be > 0, got {self.g}")
        if self.index_time >= 0.0 and not (self.index_rate > 0.0 and self.index_accel > 0.0):
            raise ValueError(
                "HrgPlatform.index_rate and index_accel must be > 0 when indexing, got "
                f"{self.index_rate} and {self.index_accel}"
            )
        if self.settle_time < 0.0:
            raise ValueError(f"HrgPlatform.settle_time must be >= 0, got {self.settle_time}")
        lat = float(self.lat)
        self._w_z = (1.0 + float(self.torque_scale_error)) * OMEGA_IE * math.sin(lat)
        self._w_in_n = OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)])
        self._turn = float(self.index_angle) + float(self.index_error)
        if self.index_time >= 0.0:
            _, _, self._move = indexing_profile(
                0.0, self._turn, float(self.index_rate), float(self.index_accel)
            )
        else:
            self._move = 0.0
        self._cache_key: tuple[float, ...] | None = None
        self._cache_rot = np.eye(3)
        self._earth_h: float | None = None
        self._earth = np.eye(3)
        phi0 = np.array([float(self.theta_E0), float(self.theta_N0), 0.0])
        self._c = rotvec_to_dcm(phi0) @ rot_z(float(self.azimuth0))
        self._publish(self.start_time)

    # ---------------------------------------------------------------- helpers
    def _alpha(self, t: float) -> tuple[float, float]:
        """Indexing angle turned and its rate at time ``t`` [rad, rad/s]."""
        if self.index_time < 0.0:
            return 0.0, 0.0
        a, a_dot, _ = indexing_profile(
            t - float(self.index_time), self._turn, float(self.index_rate), float(self.index_accel)
        )
        return a, a_dot

    def status(self, t: float) -> float:
        """Position status at time ``t``: 1, 0 (moving or settling) or 2.

        Parameters
        ----------
        t : float
            Simulation time [s] (compared with ``index_time``, the move and
            ``settle_time``, with a 1e-9 s round-off tolerance).

        Returns
        -------
        float
            1.0 before the indexing move, 0.0 while moving or settling, 2.0 afterwards.
        """
        tol = 1e-9  # s: step ends computed as t0 + n h may miss an exact instant by round-off
        if self.index_time < 0.0 or t <= self.index_time + tol:
            return 1.0
        if t >= self.index_time + self._move + self.settle_time - tol:
            return 2.0
        return 0.0

    def _publish(self, t: float) -> None:
        eps = np.asarray(self.omega_err_p, dtype=float)
        c = self._c
        self.f_p = c[2, :] * float(self.g)
        _, a_dot = self._alpha(t)
        self.omega_ip_p = np.array([0.0, 0.0, self._w_z + a_dot]) - eps
        self.theta_E, self.theta_N, self.azimuth = split_attitude(c)
        self.drift_rate_n = -(c @ eps)
        self.position = self.status(t)

    # ------------------------------------------------------------------- step
    def step(self, t: float, h: float) -> None:
        eps = np.asarray(self.omega_err_p, dtype=float)
        base = np.array([-eps[0], -eps[1], self._w_z - eps[2]])
        moving = self.index_time >= 0.0 and (
            t + h > self.index_time and t < self.index_time + self._move
        )
        if not moving:
            key = (h, *base)
            if self._cache_key != key:  # constant rates: the step's rotation repeats
                self._cache_key, self._cache_rot = key, rotvec_to_dcm(base * h)
            rot = self._cache_rot
        else:
            n = substeps(h, float(self.dt_truth))
            delta = h / n
            rot = np.eye(3)
            a_prev, _ = self._alpha(t)
            for j in range(n):
                a_next, _ = self._alpha(t + (j + 1) * delta)
                inc = base * delta
                inc[2] += a_next - a_prev
                rot = rot @ rotvec_to_dcm(inc)
                a_prev = a_next
        if not same_step(h, self._earth_h):
            self.step_setups += 1
            self._earth_h, self._earth = h, rotvec_to_dcm(-self._w_in_n * h)
        c = self._earth @ self._c @ rot
        # Re-orthonormalise (one Newton step of the polar decomposition): the product of
        # exact rotations drifts from orthogonality only by round-off.
        self._c = 1.5 * c - 0.5 * c @ c.T @ c
        self._publish(t + h)
