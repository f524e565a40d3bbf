"""Seed-001 ENU / RFU frames and their conversion to our NED / FRD (:mod:`models.conventions`).

Seed 001 works in ENU with a body frame RFU (x right, y forward, z up) and
Euler angles heading ``psi`` (about up, counter-clockwise positive, i.e. north
towards west), pitch ``theta`` (about the right axis), roll ``gamma`` (about the
forward axis), in the order yaw, pitch, roll. The permutation

    T = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]      (T = T.T = inv(T))

maps ENU to NED vectors and RFU to FRD vectors (``v_ned = T @ v_enu``) and back, so
``C_frd_ned = T @ C_rfu_enu @ T`` (and back) and the angles are
``rpy = [gamma, theta, -psi]``. If a paper quotes a heading measured clockwise
from north, it is already our yaw.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .conventions import vec3

#: ENU <-> NED (and RFU <-> FRD) axis permutation; symmetric and its own inverse.
T_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def swap_enu_ned(v: ArrayLike) -> np.ndarray:
    """``T @ v``: ENU vector(s) to NED and NED to ENU, RFU body axes to FRD and back.

    ``[e, n, u] -> [n, e, -u]`` and ``[n, e, d] -> [e, n, -d]`` (the same
    permutation, its own inverse); for body axes ``[r, f, u] -> [f, r, -u]`` and
    ``[f, r, d] -> [r, f, -d]``.

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s) resolved in ENU, NED, RFU or FRD (any unit).

    Returns
    -------
    ndarray, shape (..., 3)
        The same vector(s) resolved in the paired frame (NED, ENU, FRD or RFU).
    """
    v = np.asarray(v, dtype=float)
    return vec3(v[..., 1], v[..., 0], -v[..., 2])


def swap_enu_ned_dcm(c: ArrayLike) -> np.ndarray:
    """``T @ c @ T``: an RFU-to-ENU attitude as FRD-to-NED, and back, shape (..., 3, 3).

    Parameters
    ----------
    c : array_like, shape (..., 3, 3)
        Attitude DCM(s) ``C_rfu_enu`` (or ``C_frd_ned``).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``C_frd_ned`` (or ``C_rfu_enu``): the same attitude in the paired frames.
    """
    return T_NED_ENU @ np.asarray(c, dtype=float) @ T_NED_ENU


def enu_euler_to_rpy(pitch: ArrayLike, roll: ArrayLike, heading: ArrayLike) -> np.ndarray:
    """Seed-001 ENU/RFU Euler angles to our ``rpy``.

    Parameters
    ----------
    pitch, roll : array_like
        Pitch (about the right axis, nose up positive) and roll (about the forward
        axis, right wing down positive) [rad].
    heading : array_like
        Heading about the up axis, counter-clockwise (north towards west) positive [rad].

    Returns
    -------
    ndarray, shape (..., 3)
        ``[roll, pitch, -heading]``.
    """
    return np.stack(np.broadcast_arrays(roll, pitch, -np.asarray(heading, dtype=float)), axis=-1)


def rpy_to_enu_euler(rpy: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`enu_euler_to_rpy`: ``(pitch, roll, heading_ccw)`` [rad].

    Parameters
    ----------
    rpy : array_like, shape (..., 3)
        Our Z-Y-X angles ``[roll, pitch, yaw]`` of ``C_b_n`` (FRD to NED) [rad].

    Returns
    -------
    pitch, roll, heading_ccw : ndarray, shape (...)
        Seed-001 angles [rad]: pitch, roll, and the heading counter-clockwise from
        north (``-yaw``).
    """
    rpy = np.asarray(rpy, dtype=float)
    return rpy[..., 1], rpy[..., 0], -rpy[..., 2]
