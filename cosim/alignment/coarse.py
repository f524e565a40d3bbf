"""Analytic coarse alignment of a stationary IMU (TRIAD), and its first-order error.

Over a window the mean specific force ``f_s`` and rate ``w_s`` (sums of the increments
over the window's length) are the images of the references ``f_n = [0, 0, -g]`` and
``w_n = omega_ie_n = [W cos L, 0, -W sin L]``. Orthonormal triads built the same way
in both frames::

    u1 = f / |f|,   u2 = (f x w) / |f x w|,   u3 = u1 x u2,      C_s_n = U_n U_s^T

make gravity define the level exactly and ``f x w`` (east-west) the heading; with a
perfect IMU on a static base the result is exact. With sensor errors ``nabla``
(accelerometer) and ``eps`` (gyro), resolved in ``n``, the residual misalignment is
(psi angle: ``C^ = (I - [psi x]) C``; ``e = -psi`` is the estimate-minus-truth rotation)::

    psi_N = nabla_E / g,    psi_E = -nabla_N / g,
    psi_D = eps_E / (W cos L) - tan L nabla_E / g.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.nav import AlignmentError, earth_rate
from cosim.models.constants import OMEGA_IE
from cosim.models.conventions import cross
from cosim.models.earth import gravity

FloatArray = NDArray[np.float64]


def _triad(a: FloatArray, b: FloatArray) -> FloatArray:
    u1 = a / np.linalg.norm(a)
    c = cross(a, b)
    norm = np.linalg.norm(c)
    if not norm > 0.0:
        raise AlignmentError(
            "coarse alignment: specific force and angular rate are parallel (at a pole, "
            "or the IMU outputs are zero); cannot find the heading"
        )
    u2 = c / norm
    return np.column_stack([u1, u2, cross(u1, u2)])


def coarse_alignment(f_s: ArrayLike, w_s: ArrayLike, lat: float, h: float = 0.0) -> FloatArray:
    """Analytic coarse alignment from mean specific force and angular rate (TRIAD).

    Parameters
    ----------
    f_s : array_like, shape (3,)
        Mean specific force over the alignment window, sensor axes [m/s2].
    w_s : array_like, shape (3,)
        Mean angular rate w.r.t. inertial space, sensor axes [rad/s].
    lat : float
        Latitude [rad] (not at a pole).
    h : float
        Height [m] (sets g; the result does not depend on |g|).

    Returns
    -------
    ndarray, shape (3, 3)
        ``C_s_n`` (sensor to NED), orthonormal.

    Raises
    ------
    AlignmentError
        When the two vectors are parallel or zero.
    """
    f_n = np.array([0.0, 0.0, -float(gravity(lat, h))])
    w_n = earth_rate(lat)
    f_s = np.asarray(f_s, dtype=float)
    w_s = np.asarray(w_s, dtype=float)
    if not np.linalg.norm(f_s) > 0.0:
        raise AlignmentError("coarse alignment: zero mean specific force (no IMU data?)")
    return _triad(f_n, w_n) @ _triad(f_s, w_s).T


def coarse_error_theory(
    nabla_n: ArrayLike, eps_n: ArrayLike, lat: float, h: float = 0.0
) -> FloatArray:
    """First-order residual of :func:`coarse_alignment` as ``phi_err`` (estimate minus truth).

    ``phi_err = -psi`` with ``psi_N = nabla_E / g``, ``psi_E = -nabla_N / g``,
    ``psi_D = eps_E / (W cos L) - tan L nabla_E / g``.

    Parameters
    ----------
    nabla_n : array_like, shape (3,)
        Accelerometer error averaged over the window, resolved in NED [m/s2].
    eps_n : array_like, shape (3,)
        Gyro error averaged over the window, resolved in NED [rad/s].
    lat, h : float
        Latitude [rad], height [m].

    Returns
    -------
    ndarray, shape (3,)
        ``phi_err`` [rad], NED.
    """
    g = float(gravity(lat, h))
    nab = np.asarray(nabla_n, dtype=float)
    eps = np.asarray(eps_n, dtype=float)
    psi = np.array(
        [
            nab[1] / g,
            -nab[0] / g,
            eps[1] / (OMEGA_IE * math.cos(lat)) - math.tan(lat) * nab[1] / g,
        ]
    )
    return -psi


def heading_limit(gyro_drift: float, lat: float) -> float:
    """Single-position heading limit ``eps_E / (W cos L)`` [rad] for an east drift [rad/s].

    Parameters
    ----------
    gyro_drift : float
        East gyro drift ``eps_E`` [rad/s].
    lat : float
        Latitude [rad] (not at a pole).

    Returns
    -------
    float
        Heading error of a stationary single-position alignment [rad].
    """
    return float(gyro_drift) / (OMEGA_IE * math.cos(lat))
