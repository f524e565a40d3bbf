"""WGS-84 earth model and navigation-frame (NED) kinematics shared by the motion blocks.

Equations (``L`` latitude, ``h`` height, ``a, f, e^2`` WGS-84, ``Omega`` earth rate)::

    R_M(L) = a (1 - e^2) / (1 - e^2 sin^2 L)^(3/2)          meridian radius
    R_N(L) = a / (1 - e^2 sin^2 L)^(1/2)                     transverse (prime-vertical) radius
    gamma_0(L) = gamma_e (1 + k sin^2 L) / (1 - e^2 sin^2 L)^(1/2)     Somigliana
    g(L, h) = gamma_0 [1 - 2/a (1 + f + m - 2 f sin^2 L) h + 3 h^2 / a^2]
    g_n = [0, 0, g]                          (normal gravity along the ellipsoid normal)
    omega_ie_n = [Omega cos L, 0, -Omega sin L]
    omega_en_n = [v_E / (R_N + h), -v_N / (R_M + h), -v_E tan L / (R_N + h)]
    L' = v_N / (R_M + h),  lon' = v_E / ((R_N + h) cos L),  h' = -v_D

Strapdown relations (the truth the motion blocks output, and what a navigation
algorithm inverts)::

    omega_ib_b = omega_nb_b + C_n_b (omega_ie_n + omega_en_n)
    f_b        = C_n_b (v_n' + (2 omega_ie_n + omega_en_n) x v_n - g_n)

``g`` is the normal gravity (gravitation plus centrifugal) of the WGS-84
ellipsoid; the deflection of the vertical and the small north component of the
height-dependent normal gravity are neglected.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .block import Var, input_, output
from .constants import E2, GAMMA_E, K_SOMIGLIANA, M_RATIO, OMEGA_IE, A, F
from .conventions import (
    cross,
    euler_accel_to_body_accel,
    euler_rate_to_body_rate,
    euler_to_dcm,
    vec3,
)


def R_M(lat: ArrayLike) -> np.ndarray:
    """Meridian radius of curvature [m] at latitude ``lat`` [rad] (any shape).

    Parameters
    ----------
    lat : array_like
        Geodetic latitude [rad], any shape.

    Returns
    -------
    ndarray
        ``R_M(lat)`` [m], same shape as ``lat``.
    """
    s = np.sin(np.asarray(lat, dtype=float))
    return A * (1.0 - E2) / (1.0 - E2 * s * s) ** 1.5


def R_N(lat: ArrayLike) -> np.ndarray:
    """Transverse (prime-vertical) radius of curvature [m] at latitude ``lat`` [rad].

    Parameters
    ----------
    lat : array_like
        Geodetic latitude [rad], any shape.

    Returns
    -------
    ndarray
        ``R_N(lat)`` [m], same shape as ``lat``.
    """
    s = np.sin(np.asarray(lat, dtype=float))
    return A / np.sqrt(1.0 - E2 * s * s)


def gravity(lat: ArrayLike, h: ArrayLike = 0.0) -> np.ndarray:
    """Normal gravity magnitude [m/s^2] (Somigliana with the second-order height correction).

    Parameters
    ----------
    lat : array_like
        Geodetic latitude [rad].
    h : array_like
        Height above the ellipsoid [m].

    Returns
    -------
    ndarray
        ``g(lat, h)``, broadcast shape of the inputs.
    """
    s2 = np.sin(np.asarray(lat, dtype=float)) ** 2
    h = np.asarray(h, dtype=float)
    g0 = GAMMA_E * (1.0 + K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s2) * h + 3.0 * h * h / A**2)


def g_n(lat: ArrayLike, h: ArrayLike = 0.0) -> np.ndarray:
    """Gravity vector in NED ``[0, 0, g]`` [m/s^2], shape ``(..., 3)``.

    Parameters
    ----------
    lat : array_like
        Geodetic latitude [rad].
    h : array_like
        Height above the ellipsoid [m]; broadcasts with ``lat``.

    Returns
    -------
    ndarray, shape (..., 3)
        Normal gravity (:func:`gravity`) along NED down; ``...`` is the broadcast
        shape of the inputs.
    """
    g = gravity(lat, h)
    out = np.zeros(np.shape(g) + (3,))
    out[..., 2] = g
    return out


def omega_ie_n(lat: ArrayLike) -> np.ndarray:
    """Earth rate in NED ``[Omega cos L, 0, -Omega sin L]`` [rad/s], shape ``(..., 3)``.

    Parameters
    ----------
    lat : array_like, shape (...)
        Geodetic latitude [rad].

    Returns
    -------
    ndarray, shape (..., 3)
        ``omega_ie_n`` [rad/s].
    """
    lat = np.asarray(lat, dtype=float)
    return np.stack([OMEGA_IE * np.cos(lat), np.zeros_like(lat), -OMEGA_IE * np.sin(lat)], axis=-1)


def omega_en_n(v_n: ArrayLike, lat: ArrayLike, h: ArrayLike = 0.0) -> np.ndarray:
    """Transport rate in NED [rad/s], shape ``(..., 3)``.

    Parameters
    ----------
    v_n : array_like, shape (..., 3)
        Velocity w.r.t. the earth in NED [m/s].
    lat : array_like
        Latitude [rad].
    h : array_like
        Height [m].

    Returns
    -------
    ndarray, shape (..., 3)
        ``[v_E / (R_N + h), -v_N / (R_M + h), -v_E tan L / (R_N + h)]``.
    """
    v_n = np.asarray(v_n, dtype=float)
    lat = np.asarray(lat, dtype=float)
    rn = R_N(lat) + h
    rm = R_M(lat) + h
    return np.stack([v_n[..., 1] / rn, -v_n[..., 0] / rm, -v_n[..., 1] * np.tan(lat) / rn], axis=-1)


def position_rate(
    v_n: ArrayLike, lat: ArrayLike, h: ArrayLike = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rates of latitude [rad/s], longitude [rad/s] and height [m/s] from the NED velocity.

    Parameters
    ----------
    v_n : array_like, shape (..., 3)
        Velocity w.r.t. the earth in NED [m/s].
    lat : array_like, shape (...)
        Geodetic latitude [rad] (not at a pole).
    h : array_like, shape (...)
        Height above the ellipsoid [m].

    Returns
    -------
    lat_dot, lon_dot, h_dot : ndarray, shape (...)
        ``v_N / (R_M + h)`` [rad/s], ``v_E / ((R_N + h) cos L)`` [rad/s], ``-v_D`` [m/s].
    """
    v_n = np.asarray(v_n, dtype=float)
    lat = np.asarray(lat, dtype=float)
    lat_dot = v_n[..., 0] / (R_M(lat) + h)
    lon_dot = v_n[..., 1] / ((R_N(lat) + h) * np.cos(lat))
    return lat_dot, lon_dot, -v_n[..., 2]


class ImuTruth(NamedTuple):
    """Exact inertial quantities of a trajectory at a set of instants (shapes (m, 3) / (m,)).

    Attributes
    ----------
    C_b_n : ndarray, shape (m, 3, 3)
        Attitude, body (FRD) to NED.
    lat, lon : ndarray, shape (m,)
        Geodetic latitude and longitude [rad].
    h : ndarray, shape (m,)
        Height above the ellipsoid [m].
    omega_ib_b : ndarray, shape (m, 3)
        Body rate w.r.t. inertial space, body axes [rad/s].
    omega_dot_b : ndarray, shape (m, 3)
        Time derivative of ``omega_ib_b`` (body axes) [rad/s2].
    f_b : ndarray, shape (m, 3)
        Specific force, body axes [m/s2].
    """

    C_b_n: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    omega_ib_b: np.ndarray
    omega_dot_b: np.ndarray
    f_b: np.ndarray


#: The outputs of every motion block (the ``motion`` role of fmus/interfaces), in order:
#: the state at the step end and the exact increments over the step.
MOTION_OUTPUTS = (
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


def motion_inputs(names: tuple[str, ...], source: str) -> tuple[Var, ...]:
    """Inputs that take the :data:`MOTION_OUTPUTS` of the same names from a motion block.

    Parameters
    ----------
    names : tuple of str
        Names of motion outputs, in the order the inputs are declared.
    source : str
        What the motion block is to this block (``"base"``, ``"master"``): it leads each
        input's description.

    Returns
    -------
    tuple of Var
        One input per name, with the output's start value and unit.
    """
    by_name = {v.name: v for v in MOTION_OUTPUTS}
    return tuple(
        input_(n, by_name[n].start, by_name[n].unit, f"{source}: {by_name[n].description}")
        for n in names
    )


def euler_motion_truth(
    rpy: np.ndarray,
    rpy_dot: np.ndarray,
    rpy_ddot: np.ndarray,
    d_n: np.ndarray | None,
    v_n: np.ndarray | None,
    a_n: np.ndarray | None,
    lat0: float,
    lon0: float,
    h0: float,
) -> ImuTruth:
    """Inertial truth of a trajectory given by Euler angles and a small NED displacement.

    The vehicle's reference point is displaced by ``d_n`` (NED, metres) from the
    fixed point ``(lat0, lon0, h0)``; its velocity is ``v_n = d_n'`` and
    ``v_n' = a_n``. Position (to first order in ``d_n / R``, error ~ ``|d|^2 / R``)::

        L = L0 + d_N / (R_M(L0) + h0),  lon = lon0 + d_E / ((R_N(L0) + h0) cos L0),  h = h0 - d_D

    Rates and specific force (see the module docstring)::

        omega_ib_b  = omega_nb_b + C_n_b omega_in_n
        omega_dot_b = omega_nb_b' + C_n_b omega_in_n' - omega_nb_b x (C_n_b omega_in_n)
        f_b         = C_n_b (a_n + (2 omega_ie_n + omega_en_n) x v_n - g_n(L, h))

    with ``omega_in_n'`` from ``L'`` and ``a_n`` (the change of the radii neglected).

    Parameters
    ----------
    rpy, rpy_dot, rpy_ddot : ndarray, shape (m, 3)
        Euler angles [rad] and their derivatives [rad/s, rad/s2].
    d_n, v_n, a_n : ndarray, shape (m, 3), or None
        Displacement [m], velocity [m/s] and acceleration [m/s2] in NED; ``None``
        for a vehicle that stays at the reference point (a faster path).
    lat0, lon0, h0 : float
        Reference position [rad, rad, m].

    Returns
    -------
    ImuTruth
        ``C_b_n`` (m, 3, 3); ``lat, lon, h`` (m,); ``omega_ib_b``, ``omega_dot_b``, ``f_b`` (m, 3).
    """
    c_b_n = euler_to_dcm(rpy)
    w_nb = euler_rate_to_body_rate(rpy, rpy_dot)
    w_nb_dot = euler_accel_to_body_accel(rpy, rpy_dot, rpy_ddot)
    m = rpy.shape[0]
    if d_n is None:
        # Fixed position: earth rate and gravity are constants, no transport rate.
        lat = np.full(m, float(lat0))
        lon = np.full(m, float(lon0))
        hgt = np.full(m, float(h0))
        w_in_b = c_b_n[:, 0, :] * (OMEGA_IE * np.cos(lat0)) - c_b_n[:, 2, :] * (
            OMEGA_IE * np.sin(lat0)
        )
        omega_ib_b = w_nb + w_in_b
        omega_dot_b = w_nb_dot - cross(w_nb, w_in_b)
        f_b = c_b_n[:, 2, :] * (-float(gravity(lat0, h0)))
        return ImuTruth(c_b_n, lat, lon, hgt, omega_ib_b, omega_dot_b, f_b)

    rm0 = float(R_M(lat0)) + h0
    rn0 = float(R_N(lat0)) + h0
    lat = lat0 + d_n[:, 0] / rm0
    cos0 = np.cos(lat0)
    lon = lon0 + (d_n[:, 1] / (rn0 * cos0) if abs(cos0) > 1e-12 else 0.0 * d_n[:, 1])
    hgt = h0 - d_n[:, 2]

    sl, cl = np.sin(lat), np.cos(lat)
    rm = R_M(lat) + hgt
    rn = R_N(lat) + hgt
    lat_dot = v_n[:, 0] / rm
    h_dot = -v_n[:, 2]
    w_ie = vec3(OMEGA_IE * cl, 0.0, -OMEGA_IE * sl)
    w_en = vec3(v_n[:, 1] / rn, -v_n[:, 0] / rm, -v_n[:, 1] * sl / (cl * rn))
    w_ie_dot = vec3(-OMEGA_IE * sl * lat_dot, 0.0, -OMEGA_IE * cl * lat_dot)
    w_en_dot = vec3(
        a_n[:, 1] / rn - v_n[:, 1] * h_dot / rn**2,
        -a_n[:, 0] / rm + v_n[:, 0] * h_dot / rm**2,
        -(a_n[:, 1] * sl / cl + v_n[:, 1] * lat_dot / cl**2) / rn
        + v_n[:, 1] * sl / cl * h_dot / rn**2,
    )
    w_in_b = _transpose_apply(c_b_n, w_ie + w_en)
    omega_ib_b = w_nb + w_in_b
    omega_dot_b = w_nb_dot + _transpose_apply(c_b_n, w_ie_dot + w_en_dot) - cross(w_nb, w_in_b)
    f_n = a_n + cross(2.0 * w_ie + w_en, v_n)
    f_n[:, 2] -= gravity(lat, hgt)
    f_b = _transpose_apply(c_b_n, f_n)
    return ImuTruth(c_b_n, lat, lon, hgt, omega_ib_b, omega_dot_b, f_b)


def _transpose_apply(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``C.T @ x`` for stacks: c (m, 3, 3), x (m, 3) -> (m, 3)."""
    return (x[:, None, :] @ c)[:, 0, :]
