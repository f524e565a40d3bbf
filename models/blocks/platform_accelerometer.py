"""Pulse-output accelerometer triad on a gimballed platform (seed 000, eq. 2).

Platform frame p as in :mod:`models.blocks.hrg_platform_gyro` (x, y level, z up; east,
north, up at azimuth 0). Input: the true specific force ``A = f_p`` along the
platform axes [m/s2], held constant over the step.

Output model (eq. 2, with ``N_i`` read as the pulse rate)::

    N_x / K1_x = K_x0 + A_x + K_yx A_y + K_zx A_z
    N_y / K1_y = K_y0 + A_y + K_xy A_x + K_zy A_z
    N_z / K1_z = K_z0 + A_z + K_xz A_x + K_yz A_y

``K1`` [pulses per m/s], ``K_i0`` bias [m/s2], ``K_ij`` mounting errors [rad]
(``K_ji`` couples the specific force along axis j into accelerometer i). The pulses
over a step ``h`` are counted from the accumulated (real) pulse number::

    r_k = r_{k-1} + K1 (h (K0 + (I + K) A) + n_k),   n_k ~ N(0, N^2 h)
    pulses_k = floor(r_k),   r_k <- r_k - pulses_k,   r_0 = 1/2

so the fractional remainder is carried to the next step and the cumulative count is
the nearest integer of the cumulative real pulse number (error at most half a
pulse, never growing). ``N`` is the white-noise (VRW) density [m/s/sqrt(s)];
one (3,) block of standard normals is drawn per step from
``numpy.random.default_rng(seed)``.

Outputs: ``pulses`` (FMI Integer, per step), the velocity increment they stand for
``dv_meas_p = pulses / K1`` [m/s] and the equivalent specific force
``f_meas_p = pulses / (K1 h)`` [m/s2].
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, input_, output, parameter
from cosim.models.blocks.hrg_platform_gyro import mounting_matrix

_V3 = (0.0, 0.0, 0.0)


class PlatformAccelerometer(Block):
    """Platform accelerometer triad with pulse outputs per seed 000 eq. (2)."""

    variables = (
        parameter("K1", (1.0e4, 1.0e4, 1.0e4), "s/m", "scale factor K1: pulses per m/s"),
        parameter("K0", _V3, "m/s2", "bias K_i0 per axis"),
        parameter("K_yx", 0.0, "rad", "mounting error: y specific force into x"),
        parameter("K_zx", 0.0, "rad", "mounting error: z specific force into x"),
        parameter("K_xy", 0.0, "rad", "mounting error: x specific force into y"),
        parameter("K_zy", 0.0, "rad", "mounting error: z specific force into y"),
        parameter("K_xz", 0.0, "rad", "mounting error: x specific force into z"),
        parameter("K_yz", 0.0, "rad", "mounting error: y specific force into z"),
        parameter("noise_density", 0.0, "m/s/sqrt(s)", "white-noise density (VRW)"),
        parameter("seed", 0, description="random seed"),
        input_("f_p", _V3, "m/s2", "true specific force along the platform axes"),
        output("pulses", (0, 0, 0), "1", "pulse count over the step"),
        output("dv_meas_p", _V3, "m/s", "velocity increment of the pulses, pulses / K1"),
        output("f_meas_p", _V3, "m/s2", "equivalent specific force, pulses / (K1 h)"),
    )
    default_step = 0.01
    default_stop = 1.0

    def initialize(self) -> None:
        self._k1 = np.asarray(self.K1, dtype=float).copy()
        if not np.all(self._k1 > 0.0):
            raise ValueError(f"PlatformAccelerometer.K1 must be > 0 on every axis, got {self._k1}")
        if self.noise_density < 0.0:
            raise ValueError(
                f"PlatformAccelerometer.noise_density must be >= 0, got {self.noise_density}"
            )
        self._rng = np.random.default_rng(int(self.seed))
        self._m = np.eye(3) + mounting_matrix(
            self.K_yx, self.K_zx, self.K_xy, self.K_zy, self.K_xz, self.K_yz
        )
        self._resid = np.full(3, 0.5)
        self.pulses = np.zeros(3, dtype=int)
        self.dv_meas_p = np.zeros(3)
        self.f_meas_p = np.zeros(3)

    def pulse_rate(self, f_p: np.ndarray) -> np.ndarray:
        """Noise-free right-hand side of eq. (2), ``N / K1``.

        Parameters
        ----------
        f_p : ndarray, shape (3,)
            Specific force along the platform axes [m/s2].

        Returns
        -------
        ndarray, shape (3,)
            ``K0 + (I + K) f_p`` [m/s2].
        """
        return np.asarray(self.K0, float) + self._m @ np.asarray(f_p, float)

    def step(self, t: float, h: float) -> None:
        z = self._rng.standard_normal(3)
        dv = h * self.pulse_rate(self.f_p) + self.noise_density * math.sqrt(h) * z
        acc = self._resid + self._k1 * dv
        count = np.floor(acc)
        self._resid = acc - count
        self.pulses = count.astype(int)
        self.dv_meas_p = count / self._k1
        self.f_meas_p = self.dv_meas_p / h
