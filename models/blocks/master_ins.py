"""Master INS as the transfer-alignment filter receives it: delayed, with its own errors.

Inputs are the true navigation state (NED velocity ``v_n``, attitude
``rpy = [roll, pitch, yaw]`` of the ZYX convention, position ``lat``, ``lon``,
``h`` as in :mod:`models.conventions`). Outputs, at the end of each step
``t_k = t + dt`` (``dt``: the step size)::

    x_d(t_k)      = x_true(t_k - d)                          latency d [s]
    v_master_n    = v_d + e_gm(t_k) + w_k,   w_k ~ N(0, sigma_w^2 I)
    rpy_master    = wrap(rpy_d + delta + a_k)    constant error, white a_k ~ N(0, sigma_a^2 I)
    e_gm'         = -e_gm / tau + u,   E[u u] = 2 sigma_gm^2 / tau   (per axis)
    lat_master, lon_master, h_master = position delayed by d (no errors)

``a_k`` (``attitude_noise_std`` = sigma_a, per sample, on roll, pitch, yaw) comes from a
generator of its own, ``default_rng([seed, 1])``, drawn only when sigma_a > 0: the other
outputs' random numbers are the same with or without it.
``delta = attitude_error + attitude_error_sigma * z`` is drawn once at
initialisation (Euler-angle errors added to roll, pitch, yaw). The angle outputs
roll, yaw and longitude are wrapped to (-pi, pi]
(:func:`models.conventions.wrap_angle`); pitch and latitude are not.
``e_gm`` starts from its stationary distribution and is propagated exactly::

    e+ = exp(-dt / tau) e + sigma_gm sqrt(1 - exp(-2 dt / tau)) z

Latency: every step appends the true inputs at ``t_k`` to a buffer of timestamped
samples (a ring buffer that keeps only what the delay needs, about ``d / dt + 2``
samples). The delayed value at ``t_k - d`` is

* the buffered sample itself when ``t_k - d`` falls on a sample time (within
  ``1e-9 dt``): a latency that is a whole number of steps is an exact shift;
* otherwise the linear interpolation between the two neighbouring samples
  (angles interpolated along the shorter arc), so a latency that is not a multiple
  of ``dt`` is honoured exactly for inputs linear in time;
* the value at the start time while ``t_k - d`` precedes it (the vehicle is taken to
  be in its initial state before the start).

Because samples carry their times, a step size that varies (as fmpy's last step may)
needs no special handling. Random numbers: ``numpy.random.default_rng(seed)``; at
initialisation 3 normals (attitude error) then 3 (initial Gauss-Markov state); per
step 3 (Gauss-Markov) then 3 (white noise), drawn :data:`AHEAD_STEPS` steps at a time
(the same numbers in the same order).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from cosim.models.block import Block, input_, output, parameter
from cosim.models.conventions import wrap_angle

_V3 = (0.0, 0.0, 0.0)
# Layout of a buffered sample: v_n (0:3), rpy (3:6), lat, lon, h (6:9).
_ANGLE = np.array([False, False, False, True, True, True, False, True, False])


class MasterIns(Block):
    """Master INS outputs with latency, attitude error and velocity noise."""

    variables = (
        parameter("latency", 0.0, "s", "delay d of the master data (any value >= 0)"),
        parameter("attitude_error", _V3, "rad", "constant roll, pitch, yaw error"),
        parameter("attitude_error_sigma", 0.0, "rad", "sigma of a turn-on attitude error"),
        parameter("velocity_noise_std", 0.0, "m/s", "white velocity noise std per sample"),
        parameter("velocity_gm_sigma", 0.0, "m/s", "Gauss-Markov velocity error sigma"),
        parameter("velocity_gm_tau", 100.0, "s", "Gauss-Markov velocity error correlation time"),
        parameter("attitude_noise_std", 0.0, "rad", "white attitude noise std per sample"),
        parameter("seed", 0, description="random seed"),
        input_("v_n", _V3, "m/s", "true velocity, NED"),
        input_("rpy", _V3, "rad", "true attitude [roll, pitch, yaw] (ZYX)"),
        input_("lat", 0.0, "rad", "true latitude"),
        input_("lon", 0.0, "rad", "true longitude"),
        input_("h", 0.0, "m", "true height above the ellipsoid"),
        output("v_master_n", _V3, "m/s", "master velocity, NED"),
        output("rpy_master", _V3, "rad", "master attitude [roll, pitch, yaw]"),
        output("lat_master", 0.0, "rad", "master latitude (delayed)"),
        output("lon_master", 0.0, "rad", "master longitude (delayed)"),
        output("h_master", 0.0, "m", "master height (delayed)"),
    )
    default_step = 0.01
    default_stop = 1.0

    def initialize(self) -> None:
        if not self.latency >= 0.0:
            raise ValueError(f"MasterIns.latency must be >= 0, got {self.latency}")
        for name in (
            "attitude_error_sigma",
            "velocity_noise_std",
            "velocity_gm_sigma",
            "attitude_noise_std",
        ):
            if getattr(self, name) < 0.0:
                raise ValueError(f"MasterIns.{name} must be >= 0, got {getattr(self, name)}")
        if self.velocity_gm_sigma > 0.0 and not self.velocity_gm_tau > 0.0:
            raise ValueError(f"MasterIns.velocity_gm_tau must be > 0, got {self.velocity_gm_tau}")
        self._rng = np.random.default_rng(int(self.seed))
        self._rng_att = np.random.default_rng([int(self.seed), 1])
        z = self._rng.standard_normal(6)
        self._delta = np.asarray(self.attitude_error, float) + self.attitude_error_sigma * z[:3]
        self._gm = self.velocity_gm_sigma * z[3:]
        self._z = np.empty((0, 6))  # normals drawn ahead, 6 per step
        self._pos = 0
        self._buffer: deque[tuple[float, np.ndarray]] = deque()
        self._buffer.append((self.start_time, self._sample()))
        self._publish(self._buffer[0][1], np.zeros(3))

    def _sample(self) -> np.ndarray:
        x = np.empty(9)
        x[0:3] = self.v_n
        x[3:6] = self.rpy
        x[6:9] = (float(self.lat), float(self.lon), float(self.h))
        return x

    def _delayed(self, target: float, tol: float) -> np.ndarray:
        buf = self._buffer
        # Drop samples that no longer bracket the target (keep one at or before it).
        while len(buf) >= 2 and buf[1][0] <= target + tol:
            buf.popleft()
        t0, x0 = buf[0]
        if target <= t0 + tol or len(buf) == 1:
            return x0
        t1, x1 = buf[1]
        w = (target - t0) / (t1 - t0)
        diff = x1 - x0
        diff = np.where(_ANGLE, wrap_angle(diff), diff)
        return x0 + w * diff

    def _publish(self, x: np.ndarray, white: np.ndarray) -> None:
        # written in place (the block's buffer views); roll and yaw wrapped with the scalar
        # wrap_angle (the same numbers as its array form), pitch not
        self.v_master_n[:] = x[0:3] + self._gm + white
        rpy = x[3:6] + self._delta
        if self.attitude_noise_std > 0.0:
            rpy = rpy + self.attitude_noise_std * self._rng_att.standard_normal(3)
        roll, pitch, yaw = rpy.tolist()
        self.rpy_master[:] = (wrap_angle(roll), pitch, wrap_angle(yaw))
        lat, lon, hgt = x[6:9].tolist()
        self.lat_master = lat
        self.lon_master = wrap_angle(lon)
        self.h_master = hgt

    def step(self, t: float, h: float) -> None:
        t_end = t + h
        self._buffer.append((t_end, self._sample()))
        x = self._delayed(t_end - self.latency, 1e-9 * h)
        if self._pos >= len(self._z):  # the same numbers as one draw of 6 per step
            self._z = self._rng.standard_normal((AHEAD_STEPS, 6))
            self._pos = 0
        z = self._z[self._pos]
        self._pos += 1
        if self.velocity_gm_sigma > 0.0:
            x_h = h / self.velocity_gm_tau
            gain = self.velocity_gm_sigma * math.sqrt(-math.expm1(-2.0 * x_h))
            self._gm = math.exp(-x_h) * self._gm + gain * z[:3]
        self._publish(x, self.velocity_noise_std * z[3:])


#: Steps of random numbers drawn ahead (one call instead of one per step).
AHEAD_STEPS = 64
