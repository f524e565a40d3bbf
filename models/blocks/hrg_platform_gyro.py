"""Three hemispherical resonator gyros (HRG) on a gimballed platform (seed 000, eq. 1).

Platform frame p (the paper's): x, y level, z up. At azimuth ``A = 0`` the axes are
east, north, up; ``A`` is the rotation of the platform about its z (up) axis,
positive counter-clockwise seen from above, so a level platform at rest on the Earth
turns with the earth rate ``omega_ip_p = Omega [cos L sin A, cos L cos A, sin L]``.

Output model per axis (``i = x, y, z``; ``omega = omega_ip_p``, the inertial angular
rate of the platform along its own axes)::

    U_x / k_x = omega_x + eta_yx omega_y + eta_zx omega_z + D_x0 + h_x(A) + n_x
    U_y / k_y = omega_y + eta_xy omega_x + eta_zy omega_z + D_y0 + h_y(A) + n_y
    U_z / k_z = omega_z + eta_xz omega_x + eta_yz omega_y + D_z0 + h_z(A) + n_z

With the level stationary-platform rate above this is eq. (1) of seed 000 term by
term (``eta_ij``: mounting error coupling the rate about axis j into gyro i).

Heading effect (the paper names ``h_i(A)`` but gives no form; our assumption, kept
visible as parameters): a two-harmonic Fourier series of the platform azimuth::

    h_i(A) = a1_i sin A + b1_i cos A + a2_i sin 2A + b2_i cos 2A

Noise ``n_i``: white rate noise of density ``N`` [rad/sqrt(s)]; the output is the mean
over the step, so ``n_i ~ N(0, N^2 / h)``. One (3,) block of standard normals is drawn
per step from ``numpy.random.default_rng(seed)``.

Outputs: the voltage ``U`` [V] and the torque-command-equivalent rate
``omega_meas_p = U / k`` [rad/s] (the rate that the output voltage stands for, i.e.
what the platform servo loop nulls or feeds back), and the gyro error rate
``omega_err_p = omega_meas_p - omega_ip_p`` [rad/s] (mounting terms, drift, heading
effect and noise) that a platform-dynamics block can integrate as platform drift.
The inputs are taken as constant over the step (the master's zero-order hold); the
outputs at the start time (after initialisation) are the noise-free model.
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, input_, output, parameter

_V3 = (0.0, 0.0, 0.0)


def mounting_matrix(
    eta_yx: float, eta_zx: float, eta_xy: float, eta_zy: float, eta_xz: float, eta_yz: float
) -> np.ndarray:
    """Mounting-error matrix ``H`` with ``U / k = (I + H) omega + ...``.

    Parameters
    ----------
    eta_yx, eta_zx, eta_xy, eta_zy, eta_xz, eta_yz : float
        Mounting errors [rad]; ``eta_ji`` couples the rate about axis j into sensor i.

    Returns
    -------
    ndarray, shape (3, 3)
        ``H[i, j] = eta_ji`` (zero diagonal).
    """
    return np.array(
        [
            [0.0, eta_yx, eta_zx],
            [eta_xy, 0.0, eta_zy],
            [eta_xz, eta_yz, 0.0],
        ]
    )


class HrgPlatformGyro(Block):
    """HRG platform gyro triad: output voltage per seed 000 eq. (1)."""

    variables = (
        parameter("k", (1.0, 1.0, 1.0), "V.s/rad", "scale factor per axis [V/(rad/s)]"),
        parameter("eta_yx", 0.0, "rad", "mounting error: y rate into x gyro"),
        parameter("eta_zx", 0.0, "rad", "mounting error: z rate into x gyro"),
        parameter("eta_xy", 0.0, "rad", "mounting error: x rate into y gyro"),
        parameter("eta_zy", 0.0, "rad", "mounting error: z rate into y gyro"),
        parameter("eta_xz", 0.0, "rad", "mounting error: x rate into z gyro"),
        parameter("eta_yz", 0.0, "rad", "mounting error: y rate into z gyro"),
        parameter("drift", _V3, "rad/s", "constant drift D0 per axis"),
        parameter("heading_a1", _V3, "rad/s", "heading effect: coefficient of sin A"),
        parameter("heading_b1", _V3, "rad/s", "heading effect: coefficient of cos A"),
        parameter("heading_a2", _V3, "rad/s", "heading effect: coefficient of sin 2A"),
        parameter("heading_b2", _V3, "rad/s", "heading effect: coefficient of cos 2A"),
        parameter("noise_density", 0.0, "rad/sqrt(s)", "white rate noise density (ARW)"),
        parameter("seed", 0, description="random seed"),
        input_("omega_ip_p", _V3, "rad/s", "inertial angular rate of the platform, p axes"),
        input_("azimuth", 0.0, "rad", "platform azimuth A (about up, counter-clockwise)"),
        output("U", _V3, "V", "gyro output voltage per axis"),
        output("omega_meas_p", _V3, "rad/s", "torque-command-equivalent rate U / k"),
        output("omega_err_p", _V3, "rad/s", "gyro error rate omega_meas_p - omega_ip_p"),
    )
    default_step = 0.01
    default_stop = 1.0

    def initialize(self) -> None:
        self._k = np.asarray(self.k, dtype=float).copy()
        if np.any(self._k == 0.0):
            raise ValueError(f"HrgPlatformGyro.k must be non-zero on every axis, got {self._k}")
        if self.noise_density < 0.0:
            raise ValueError(
                f"HrgPlatformGyro.noise_density must be >= 0, got {self.noise_density}"
            )
        self._rng = np.random.default_rng(int(self.seed))
        self._m = np.eye(3) + mounting_matrix(
            self.eta_yx, self.eta_zx, self.eta_xy, self.eta_zy, self.eta_xz, self.eta_yz
        )
        self._evaluate(np.zeros(3))

    def heading_effect(self, azimuth: float) -> np.ndarray:
        """Heading effect ``h(A)`` per axis.

        Parameters
        ----------
        azimuth : float
            Platform azimuth A [rad].

        Returns
        -------
        ndarray, shape (3,)
            Equivalent rate [rad/s].
        """
        a = float(azimuth)
        return (
            np.asarray(self.heading_a1, float) * math.sin(a)
            + np.asarray(self.heading_b1, float) * math.cos(a)
            + np.asarray(self.heading_a2, float) * math.sin(2.0 * a)
            + np.asarray(self.heading_b2, float) * math.cos(2.0 * a)
        )

    def _evaluate(self, noise: np.ndarray) -> None:
        omega = np.asarray(self.omega_ip_p, dtype=float)
        rate = self._m @ omega + np.asarray(self.drift, float) + self.heading_effect(self.azimuth)
        rate = rate + noise
        self.U = self._k * rate
        self.omega_meas_p = rate
        self.omega_err_p = rate - omega

    def step(self, t: float, h: float) -> None:
        z = self._rng.standard_normal(3)
        self._evaluate(self.noise_density / math.sqrt(h) * z)
