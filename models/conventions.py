"""Frames, attitude conventions and step conventions shared by every model.

Frames
------
- ``i``: inertial frame; ``e``: earth-fixed frame (ECEF, WGS-84).
- ``n``: navigation frame, **NED** (x north, y east, z down), local-level at the
  vehicle's position.
- ``b``: body frame, **FRD** (x forward, y right, z down). Other body-like frames
  (sensor ``s`` on a turntable, slave IMU ``s``) follow the same axis rules.

Names state frame and direction: ``omega_ib_b`` is the angular rate of ``b``
with respect to ``i``, resolved in ``b``; ``f_b`` the specific force resolved in
``b``; ``v_n`` the velocity with respect to the earth resolved in ``n``;
``lat, lon, h`` the geodetic latitude, longitude [rad] and height [m].

Attitude
--------
- ``C_b_n`` is the direction cosine matrix from ``b`` to ``n``:
  ``v_n = C_b_n @ v_b``; ``C_n_b = C_b_n.T``.
- Euler angles, sequence Z-Y-X (yaw about D, then pitch about the new y, then
  roll about the new x); stored as ``rpy = [roll, pitch, yaw]`` [rad]::

      C_b_n = Rz(yaw) @ Ry(pitch) @ Rx(roll)

  with ``Rz(a) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]`` (and cyclically), so yaw
  is the heading, positive clockwise seen from above (north to east), pitch is
  positive nose up and roll positive right wing down. Singular at pitch = +-90 deg.
- Quaternions are scalar first, ``q_b_n = [q0, q1, q2, q3]`` with
  ``v_n = q_b_n (x) [0, v_b] (x) conj(q_b_n)``, Hamilton product ``(x)``; hence
  ``q_c_n = q_b_n (x) q_c_b`` matches ``C_c_n = C_b_n @ C_c_b``.
- A rotation vector ``phi`` (angle ``|phi|`` about the unit axis ``phi/|phi|``)
  gives ``exp([phi x]) = I + sin|phi|/|phi| [phi x] + (1 - cos|phi|)/|phi|^2 [phi x]^2``.
  A body rotation by ``phi`` (resolved in the old body axes) updates the attitude as
  ``C_b(k+1)_n = C_b(k)_n @ exp([phi x])``.
- ``[a x]`` is the skew-symmetric matrix with ``[a x] @ b = cross(a, b)``.

Seed 001 (ENU) conversion
-------------------------
Seed 001 works in ENU with a body frame RFU (x right, y forward, z up) and
Euler angles heading ``psi`` (about up, counter-clockwise positive, i.e. north
towards west), pitch ``theta`` (about the right axis), roll ``gamma`` (about the
forward axis), in the order yaw, pitch, roll. The permutation

    T = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]      (T = T.T = inv(T))

maps ENU to NED vectors and RFU to FRD vectors (``v_ned = T @ v_enu``), so
``C_frd_ned = T @ C_rfu_enu @ T`` and the angles are
``rpy = [gamma, theta, -psi]``. If a paper quotes a heading measured clockwise
from north, it is already our yaw.

Step conventions
----------------
A block's ``do_step(t, h)`` advances from ``t`` to ``t + h``. Outputs named as
states (``rpy``, ``omega_ib_b``, ``f_b``, ...) are values at ``t + h``; outputs
named ``d...`` (``dtheta_b``, ``dv_b``) are plain integrals over ``[t, t + h]``
(no coning or sculling terms: what an ideal IMU delivers). Inputs follow the
same rule (the master's default Gauss-Seidel order delivers a source's step-end
values and its increments over the same step). Where a block needs an input's
path inside the step it rebuilds it from the step-end value, the step-end
derivative when one is connected, and the increment, with the functions at the
end of this module; fine inner grids use ``n = max(1, round(h / dt_truth))``
sub-steps (an integer count, never accumulated floating time).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import ArrayLike

#: ENU <-> NED (and RFU <-> FRD) axis permutation; symmetric and its own inverse.
T_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

_EYE3 = np.eye(3)


# ------------------------------------------------------------------ basic algebra
def vec3(x: ArrayLike, y: ArrayLike, z: ArrayLike) -> np.ndarray:
    """Stack components into vectors, shape (..., 3) (a fast ``np.stack``).

    ``x`` sets the shape; ``y`` and ``z`` must broadcast to it.

    Parameters
    ----------
    x : array_like, shape (...)
        First components; sets the leading shape.
    y, z : array_like, broadcastable to ``x``'s shape
        Second and third components (same unit and frame as ``x``).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    x = np.asarray(x, dtype=float)
    out = np.empty(x.shape + (3,))
    out[..., 0] = x
    out[..., 1] = y
    out[..., 2] = z
    return out


def cross(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Cross product of vectors along the last axis, shape (..., 3) (fast ``np.cross``).

    Parameters
    ----------
    a, b : array_like, shape (..., 3)
        Vectors resolved in the same frame; leading axes broadcast.

    Returns
    -------
    ndarray, shape (..., 3)
        ``a x b`` in that frame (unit: the product of the units).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape == (3,) and b.shape == (3,):  # one pair: scalar arithmetic beats array calls
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    return vec3(
        a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
        a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
        a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
    )


def wrap_angle(a: ArrayLike) -> np.ndarray | float:
    """Angles wrapped to the interval (-pi, pi] [rad]: the one wrap of the code base.

    Parameters
    ----------
    a : float or array_like, any shape
        Angles [rad].

    Returns
    -------
    float or ndarray, same shape as ``a``
        ``a`` plus a multiple of ``2 pi``, in (-pi, pi] [rad]; a Python float for a
        Python float (the scalar path is cheaper), an ndarray otherwise.
    """
    if isinstance(a, float):
        return math.pi - (math.pi - a) % (2.0 * math.pi)
    a = np.asarray(a, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def skew(v: ArrayLike) -> np.ndarray:
    """Skew-symmetric (cross-product) matrix.

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``[v x]`` such that ``skew(v) @ w == cross(v, w)``.
    """
    v = np.asarray(v, dtype=float)
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1] = -v[..., 2]
    k[..., 0, 2] = v[..., 1]
    k[..., 1, 0] = v[..., 2]
    k[..., 1, 2] = -v[..., 0]
    k[..., 2, 0] = -v[..., 1]
    k[..., 2, 1] = v[..., 0]
    return k


def rot_x(a: float) -> np.ndarray:
    """Elementary rotation about x: ``Rx(a) = [[1, 0, 0], [0, c, -s], [0, s, c]]``.

    Parameters
    ----------
    a : float
        Angle, right-handed about x [rad].

    Returns
    -------
    ndarray, shape (3, 3)
    """
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Elementary rotation about y: ``Ry(a) = [[c, 0, s], [0, 1, 0], [-s, 0, c]]``.

    Parameters
    ----------
    a : float
        Angle, right-handed about y [rad].

    Returns
    -------
    ndarray, shape (3, 3)
    """
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """Elementary rotation about z: ``Rz(a) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]``.

    Parameters
    ----------
    a : float
        Angle, right-handed about z [rad].

    Returns
    -------
    ndarray, shape (3, 3)
    """
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ------------------------------------------------------------------ Euler angles
def euler_to_dcm(rpy: ArrayLike) -> np.ndarray:
    """Body-to-navigation DCM from Z-Y-X Euler angles.

    Parameters
    ----------
    rpy : array_like, shape (..., 3)
        ``[roll, pitch, yaw]`` [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``C_b_n = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
    """
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    c = np.empty(rpy.shape[:-1] + (3, 3))
    c[..., 0, 0] = cp * cy
    c[..., 0, 1] = sr * sp * cy - cr * sy
    c[..., 0, 2] = cr * sp * cy + sr * sy
    c[..., 1, 0] = cp * sy
    c[..., 1, 1] = sr * sp * sy + cr * cy
    c[..., 1, 2] = cr * sp * sy - sr * cy
    c[..., 2, 0] = -sp
    c[..., 2, 1] = sr * cp
    c[..., 2, 2] = cr * cp
    return c


def euler_to_dcm_3(rpy: ArrayLike) -> np.ndarray:
    """:func:`euler_to_dcm` of one ``[roll, pitch, yaw]`` [rad] with scalar math (fast path).

    Parameters
    ----------
    rpy : array_like, shape (3,)
        ``[roll, pitch, yaw]`` of ``C_b_n`` (Z-Y-X) [rad].

    Returns
    -------
    ndarray, shape (3, 3)
        ``C_b_n = Rz(yaw) Ry(pitch) Rx(roll)``.
    """
    r, p, y = np.asarray(rpy, dtype=float).tolist()
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    return np.array(
        [
            [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp],
        ]
    )


def rotvec_to_dcm_3(v: ArrayLike) -> np.ndarray:
    """:func:`rotvec_to_dcm` of one rotation vector [rad], shape (3,), with scalar math.

    ``exp([v x]) = I + s1 [v x] + s2 [v x]^2`` (Rodrigues), ``s1 = sin a / a``,
    ``s2 = (1 - cos a) / a^2``, ``a = |v|``; Taylor series below ``a = 1e-3`` rad.

    Parameters
    ----------
    v : array_like, shape (3,)
        Rotation vector [rad] (angle ``|v|`` about the axis ``v / |v|``).

    Returns
    -------
    ndarray, shape (3, 3)
    """
    x, y, z = np.asarray(v, dtype=float).tolist()
    a2 = x * x + y * y + z * z
    if a2 < 1e-6:
        s1 = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
        s2 = 0.5 - a2 / 24.0 + a2 * a2 / 720.0
    else:
        a = math.sqrt(a2)
        s1 = math.sin(a) / a
        s2 = (1.0 - math.cos(a)) / a2
    return np.array(
        [
            [1.0 - s2 * (y * y + z * z), s2 * x * y - s1 * z, s2 * x * z + s1 * y],
            [s2 * x * y + s1 * z, 1.0 - s2 * (x * x + z * z), s2 * y * z - s1 * x],
            [s2 * x * z - s1 * y, s2 * y * z + s1 * x, 1.0 - s2 * (x * x + y * y)],
        ]
    )


def dcm_to_euler(c: ArrayLike) -> np.ndarray:
    """Z-Y-X Euler angles from a body-to-navigation DCM.

    Parameters
    ----------
    c : array_like, shape (..., 3, 3)
        ``C_b_n``.

    Returns
    -------
    ndarray, shape (..., 3)
        ``[roll, pitch, yaw]`` [rad]; roll and yaw in (-pi, pi], pitch in [-pi/2, pi/2].
    """
    c = np.asarray(c, dtype=float)
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = np.arctan2(-c[..., 2, 0], np.hypot(c[..., 2, 1], c[..., 2, 2]))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return vec3(roll, pitch, yaw)


def euler_rate_to_body_rate(rpy: ArrayLike, rpy_dot: ArrayLike) -> np.ndarray:
    """Body rate relative to the navigation frame from Euler-angle rates.

    Equations (Z-Y-X angles phi = roll, theta = pitch, psi = yaw)::

        p = phi' - psi' sin(theta)
        q = theta' cos(phi) + psi' sin(phi) cos(theta)
        r = -theta' sin(phi) + psi' cos(phi) cos(theta)

    Parameters
    ----------
    rpy : array_like, shape (..., 3)
        Euler angles [rad].
    rpy_dot : array_like, shape (..., 3)
        Their time derivatives [rad/s].

    Returns
    -------
    ndarray, shape (..., 3)
        ``omega_nb_b = [p, q, r]`` [rad/s].
    """
    rpy = np.asarray(rpy, dtype=float)
    d = np.asarray(rpy_dot, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    p = d[..., 0] - d[..., 2] * sp
    q = d[..., 1] * cr + d[..., 2] * sr * cp
    r = -d[..., 1] * sr + d[..., 2] * cr * cp
    return vec3(p, q, r)


def euler_accel_to_body_accel(
    rpy: ArrayLike, rpy_dot: ArrayLike, rpy_ddot: ArrayLike
) -> np.ndarray:
    """Time derivative of ``omega_nb_b`` (in body axes) from Euler angles and derivatives.

    The exact derivative of :func:`euler_rate_to_body_rate`::

        p' = phi'' - psi'' s_th - psi' th' c_th
        q' = th'' c_ph - th' ph' s_ph + psi'' s_ph c_th + psi' ph' c_ph c_th - psi' th' s_ph s_th
        r' = -th'' s_ph - th' ph' c_ph + psi'' c_ph c_th - psi' ph' s_ph c_th - psi' th' c_ph s_th

    Parameters
    ----------
    rpy, rpy_dot, rpy_ddot : array_like, shape (..., 3)
        Euler angles [rad] and their first [rad/s] and second [rad/s2] derivatives.

    Returns
    -------
    ndarray, shape (..., 3)
        ``d(omega_nb_b)/dt`` [rad/s2].
    """
    rpy = np.asarray(rpy, dtype=float)
    d = np.asarray(rpy_dot, dtype=float)
    dd = np.asarray(rpy_ddot, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    rd, pd, yd = d[..., 0], d[..., 1], d[..., 2]
    p = dd[..., 0] - dd[..., 2] * sp - yd * pd * cp
    q = (
        dd[..., 1] * cr
        - pd * rd * sr
        + dd[..., 2] * sr * cp
        + yd * rd * cr * cp
        - yd * pd * sr * sp
    )
    r = (
        -dd[..., 1] * sr
        - pd * rd * cr
        + dd[..., 2] * cr * cp
        - yd * rd * sr * cp
        - yd * pd * cr * sp
    )
    return vec3(p, q, r)


# ------------------------------------------------------------------ quaternions
def quat_multiply(p: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Hamilton product ``p (x) q`` of scalar-first quaternions.

    Parameters
    ----------
    p : array_like, shape (..., 4)
        Left factor.
    q : array_like, shape (..., 4)
        Right factor.

    Returns
    -------
    ndarray, shape (..., 4)
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    p0, pv = p[..., :1], p[..., 1:]
    q0, qv = q[..., :1], q[..., 1:]
    scalar = p0 * q0 - np.sum(pv * qv, axis=-1, keepdims=True)
    vector = p0 * qv + q0 * pv + cross(pv, qv)
    return np.concatenate([scalar, vector], axis=-1)


def quat_conjugate(q: ArrayLike) -> np.ndarray:
    """Conjugate ``[q0, -q1, -q2, -q3]`` (the inverse of a unit quaternion), shape (..., 4).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first quaternion(s), e.g. ``q_b_n`` (its conjugate is ``q_n_b``).

    Returns
    -------
    ndarray, shape (..., 4)
        A new array (``q`` is not modified).
    """
    q = np.array(q, dtype=float)
    q[..., 1:] *= -1.0
    return q


def quat_normalize(q: ArrayLike) -> np.ndarray:
    """Unit quaternion ``q / |q|``, shape (..., 4); the sign is kept.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first quaternion(s), non-zero.

    Returns
    -------
    ndarray, shape (..., 4)
    """
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_dcm(q: ArrayLike) -> np.ndarray:
    """DCM of a unit quaternion: ``q_b_n`` -> ``C_b_n``.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first unit quaternion(s).

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = np.asarray(q, dtype=float)
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    c = np.empty(q.shape[:-1] + (3, 3))
    c[..., 0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c[..., 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    c[..., 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    c[..., 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    c[..., 1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c[..., 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    c[..., 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    c[..., 2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    c[..., 2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    return c


def dcm_to_quat(c: ArrayLike) -> np.ndarray:
    """Unit quaternion of a DCM (Shepperd's method), with ``q0 >= 0``.

    Parameters
    ----------
    c : array_like, shape (..., 3, 3)
        ``C_b_n``.

    Returns
    -------
    ndarray, shape (..., 4)
        ``q_b_n``, scalar first.
    """
    c = np.asarray(c, dtype=float)
    tr = c[..., 0, 0] + c[..., 1, 1] + c[..., 2, 2]
    # 4 q_k^2 for k = 0..3; pick the largest for a well-conditioned division.
    cand = np.stack(
        [
            1.0 + tr,
            1.0 + 2.0 * c[..., 0, 0] - tr,
            1.0 + 2.0 * c[..., 1, 1] - tr,
            1.0 + 2.0 * c[..., 2, 2] - tr,
        ],
        axis=-1,
    )
    k = np.argmax(cand, axis=-1)
    big = np.sqrt(np.maximum(np.take_along_axis(cand, k[..., None], -1)[..., 0], 0.0))
    d32 = c[..., 2, 1] - c[..., 1, 2]
    d13 = c[..., 0, 2] - c[..., 2, 0]
    d21 = c[..., 1, 0] - c[..., 0, 1]
    s10 = c[..., 1, 0] + c[..., 0, 1]
    s20 = c[..., 2, 0] + c[..., 0, 2]
    s21 = c[..., 2, 1] + c[..., 1, 2]
    rows = [
        np.stack([big, d32 / big, d13 / big, d21 / big], axis=-1),
        np.stack([d32 / big, big, s10 / big, s20 / big], axis=-1),
        np.stack([d13 / big, s10 / big, big, s21 / big], axis=-1),
        np.stack([d21 / big, s20 / big, s21 / big, big], axis=-1),
    ]
    q = np.choose(k[..., None], rows) * 0.5
    q = np.where(q[..., :1] < 0.0, -q, q)
    return quat_normalize(q)


def euler_to_quat(rpy: ArrayLike) -> np.ndarray:
    """``q_b_n`` from Euler angles ``[roll, pitch, yaw]``, shape (..., 4), ``q0 >= 0``.

    Parameters
    ----------
    rpy : array_like, shape (..., 3)
        Z-Y-X Euler angles ``[roll, pitch, yaw]`` of ``C_b_n`` [rad].

    Returns
    -------
    ndarray, shape (..., 4)
        ``q_b_n``, scalar first.
    """
    return dcm_to_quat(euler_to_dcm(rpy))


def quat_to_euler(q: ArrayLike) -> np.ndarray:
    """Euler angles ``[roll, pitch, yaw]`` [rad] from ``q_b_n``, shape (..., 3).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first unit quaternion(s) ``q_b_n``.

    Returns
    -------
    ndarray, shape (..., 3)
        ``[roll, pitch, yaw]`` [rad], as :func:`dcm_to_euler`.
    """
    return dcm_to_euler(quat_to_dcm(q))


# ------------------------------------------------------------------ rotation vectors
def _sinc_terms(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin(a)/a`` and ``(1 - cos a)/a^2`` with series below 1e-4 rad."""
    small = a < 1e-4
    safe = np.where(small, 1.0, a)
    a2 = a * a
    s1 = np.where(small, 1.0 - a2 / 6.0 + a2 * a2 / 120.0, np.sin(safe) / safe)
    s2 = np.where(small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - np.cos(safe)) / safe**2)
    return s1, s2


def rotvec_to_dcm(phi: ArrayLike) -> np.ndarray:
    """Exact exponential of a rotation vector (Rodrigues' formula).

    ``exp([phi x]) = I + sin(a)/a [phi x] + (1 - cos a)/a^2 [phi x]^2``, ``a = |phi|``.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    phi = np.asarray(phi, dtype=float)
    a = np.linalg.norm(phi, axis=-1)
    s1, s2 = _sinc_terms(a)
    k = skew(phi)
    return _EYE3 + s1[..., None, None] * k + s2[..., None, None] * (k @ k)


def rotvec_to_quat(phi: ArrayLike) -> np.ndarray:
    """Quaternion of a rotation vector: ``[cos(a/2), sin(a/2) phi / a]``, shape (..., 4).

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) [rad], ``a = |phi|``.

    Returns
    -------
    ndarray, shape (..., 4)
        Scalar-first unit quaternion(s) of ``exp([phi x])``.
    """
    phi = np.asarray(phi, dtype=float)
    a = np.linalg.norm(phi, axis=-1)
    small = a < 1e-4
    safe = np.where(small, 1.0, a)
    half = np.where(small, 0.5 - a * a / 48.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([np.cos(0.5 * a)[..., None], half[..., None] * phi], axis=-1)


def quat_to_rotvec(q: ArrayLike) -> np.ndarray:
    """Rotation vector of a unit quaternion (angle in [0, pi]), shape (..., 3).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first unit quaternion(s); ``q`` and ``-q`` give the same result.

    Returns
    -------
    ndarray, shape (..., 3)
        Rotation vector(s) [rad].
    """
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0.0, -q, q)
    v = q[..., 1:]
    sv = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(sv, q[..., 0])
    small = sv < 1e-12
    factor = np.where(small, 2.0 / np.where(small, q[..., 0], 1.0), angle / np.where(small, 1, sv))
    return factor[..., None] * v


def dcm_to_rotvec(c: ArrayLike) -> np.ndarray:
    """Rotation vector (logarithm) of a DCM, shape (..., 3); inverse of :func:`rotvec_to_dcm`.

    Parameters
    ----------
    c : array_like, shape (..., 3, 3)
        Orthonormal DCM(s).

    Returns
    -------
    ndarray, shape (..., 3)
        Rotation vector(s) [rad], angle in [0, pi].
    """
    return quat_to_rotvec(dcm_to_quat(c))


def so3_right_jacobian(phi: ArrayLike) -> np.ndarray:
    """Right Jacobian of SO(3): body rate of ``exp([phi x])`` is ``J_r(phi) @ phi_dot``.

    ``J_r = I - (1 - cos a)/a^2 [phi x] + (a - sin a)/a^3 [phi x]^2``, ``a = |phi|``;
    i.e. ``C = exp([phi x])`` satisfies ``C.T @ dC/dt = [(J_r phi') x]``.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    phi = np.asarray(phi, dtype=float)
    a = np.linalg.norm(phi, axis=-1)
    small = a < 1e-3
    safe = np.where(small, 1.0, a)
    a2 = a * a
    s2 = np.where(small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - np.cos(safe)) / safe**2)
    s3 = np.where(small, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0, (safe - np.sin(safe)) / safe**3)
    k = skew(phi)
    return _EYE3 - s2[..., None, None] * k + s3[..., None, None] * (k @ k)


def rotvec_to_dcm_and_jacobian(phi: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rotvec_to_dcm` and :func:`so3_right_jacobian` of the same vectors, together.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) [rad].

    Returns
    -------
    c : ndarray, shape (..., 3, 3)
        ``exp([phi x])``.
    j_r : ndarray, shape (..., 3, 3)
        Right Jacobian ``J_r(phi)``.
    """
    phi = np.asarray(phi, dtype=float)
    a = np.sqrt((phi * phi).sum(axis=-1))
    small = a < 1e-3
    a2 = a * a
    a4 = a2 * a2
    if small.all():  # the series alone (same values as the np.where below picks)
        s1 = 1.0 - a2 / 6.0 + a4 / 120.0
        s2 = 0.5 - a2 / 24.0 + a4 / 720.0
        s3 = 1.0 / 6.0 - a2 / 120.0 + a4 / 5040.0
    else:
        safe = np.where(small, 1.0, a)
        s1 = np.where(small, 1.0 - a2 / 6.0 + a4 / 120.0, np.sin(safe) / safe)
        s2 = np.where(small, 0.5 - a2 / 24.0 + a4 / 720.0, (1.0 - np.cos(safe)) / safe**2)
        s3 = np.where(small, 1.0 / 6.0 - a2 / 120.0 + a4 / 5040.0, (safe - np.sin(safe)) / safe**3)
    k = skew(phi)
    k2 = k @ k
    s1, s2, s3 = s1[..., None, None], s2[..., None, None], s3[..., None, None]
    return _EYE3 + s1 * k + s2 * k2, _EYE3 - s2 * k + s3 * k2


# ------------------------------------------------------------------ ENU <-> NED
def enu_to_ned(v: ArrayLike) -> np.ndarray:
    """ENU vector(s) to NED, shape (..., 3): ``[e, n, u] -> [n, e, -u]``.

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s) resolved in ENU (any unit).

    Returns
    -------
    ndarray, shape (..., 3)
        The same vector(s) resolved in NED.
    """
    v = np.asarray(v, dtype=float)
    return vec3(v[..., 1], v[..., 0], -v[..., 2])


def ned_to_enu(v: ArrayLike) -> np.ndarray:
    """NED vector(s) to ENU, shape (..., 3): ``[n, e, d] -> [e, n, -d]``.

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s) resolved in NED (any unit).

    Returns
    -------
    ndarray, shape (..., 3)
        The same vector(s) resolved in ENU.
    """
    return enu_to_ned(v)


def rfu_to_frd(v: ArrayLike) -> np.ndarray:
    """Body vector(s) from RFU (right, forward, up) to FRD axes, shape (..., 3).

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s) resolved in RFU body axes (any unit).

    Returns
    -------
    ndarray, shape (..., 3)
        The same vector(s) resolved in FRD: ``[f, r, -u]``.
    """
    return enu_to_ned(v)


def frd_to_rfu(v: ArrayLike) -> np.ndarray:
    """Body vector(s) from FRD to RFU (right, forward, up) axes, shape (..., 3).

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s) resolved in FRD body axes (any unit).

    Returns
    -------
    ndarray, shape (..., 3)
        The same vector(s) resolved in RFU: ``[r, f, -d]``.
    """
    return enu_to_ned(v)


def dcm_enu_to_ned(c_rfu_enu: ArrayLike) -> np.ndarray:
    """``C_frd_ned = T @ C_rfu_enu @ T`` (RFU-to-ENU attitude to FRD-to-NED), shape (..., 3, 3).

    Parameters
    ----------
    c_rfu_enu : array_like, shape (..., 3, 3)
        Attitude DCM(s) from RFU body axes to ENU.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``C_frd_ned``, the same attitude from FRD body axes to NED.
    """
    return T_NED_ENU @ np.asarray(c_rfu_enu, dtype=float) @ T_NED_ENU


def dcm_ned_to_enu(c_frd_ned: ArrayLike) -> np.ndarray:
    """``C_rfu_enu = T @ C_frd_ned @ T`` (inverse of :func:`dcm_enu_to_ned`), shape (..., 3, 3).

    Parameters
    ----------
    c_frd_ned : array_like, shape (..., 3, 3)
        Attitude DCM(s) from FRD body axes to NED.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``C_rfu_enu``, the same attitude from RFU body axes to ENU.
    """
    return dcm_enu_to_ned(c_frd_ned)


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


# ------------------------------------------------------------------ step conventions
def substeps(h: float, dt_truth: float) -> int:
    """Number of inner sub-steps ``n = max(1, round(h / dt_truth))`` (an integer).

    Parameters
    ----------
    h : float
        Communication step [s].
    dt_truth : float
        Wanted inner (truth) step [s]; ``<= 0`` gives one sub-step.

    Returns
    -------
    int
        ``n >= 1``; the sub-step is ``h / n``.
    """
    if not dt_truth > 0.0:
        return 1
    return max(1, int(round(h / dt_truth)))


def simpson_nodes(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Composite Simpson rule on ``[0, 1]`` with ``n`` sub-intervals.

    Parameters
    ----------
    n : int
        Number of sub-steps (>= 1); each gets a mid node.

    Returns
    -------
    s : ndarray, shape (2n + 1,)
        Nodes ``k / (2n)``.
    w : ndarray, shape (2n + 1,)
        Weights summing to 1: multiply by the step ``h`` to integrate over ``[t, t + h]``.
    """
    m = 2 * n
    s = np.arange(m + 1) / m
    w = np.full(m + 1, 2.0)
    w[1::2] = 4.0
    w[0] = w[-1] = 1.0
    return s, w / (3.0 * m)


def step_quadratic(
    end: ArrayLike, end_rate: ArrayLike, increment: ArrayLike, h: float, s: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic path over a step from its end value, end derivative and integral.

    ``x(s h) = x1 + x1' h (s - 1) + c (s - 1)^2`` with ``c`` chosen so that
    ``integral_0^h x dt = increment``; exact when ``x`` is quadratic in time.

    Parameters
    ----------
    end : array_like, shape (3,)
        ``x(t + h)``.
    end_rate : array_like, shape (3,)
        ``x'(t + h)`` (per second).
    increment : array_like, shape (3,)
        ``integral of x over [t, t + h]``.
    h : float
        Step [s].
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    x : ndarray, shape (m, 3)
        Values at the nodes.
    x_dot : ndarray, shape (m, 3)
        Time derivatives at the nodes (per second).
    """
    x1 = np.asarray(end, dtype=float)
    d1 = np.asarray(end_rate, dtype=float) * h
    c = 3.0 * (np.asarray(increment, dtype=float) / h - x1 + 0.5 * d1)
    u = (np.asarray(s, dtype=float) - 1.0)[:, None]
    return x1 + d1 * u + c * u * u, (d1 + 2.0 * c * u) / h


def step_linear(
    end: ArrayLike, increment: ArrayLike, h: float, s: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Linear path over a step from its end value and integral (exact for linear ``x``).

    ``x(s h) = x1 + b (s - 1)`` with ``b = 2 (x1 - increment / h)``.

    Parameters
    ----------
    end : array_like, shape (3,)
        ``x(t + h)``.
    increment : array_like, shape (3,)
        ``integral of x over [t, t + h]``.
    h : float
        Step [s].
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    x : ndarray, shape (m, 3)
        Values at the nodes.
    x_dot : ndarray, shape (m, 3)
        The (constant) slope, per second.
    """
    x1 = np.asarray(end, dtype=float)
    b = 2.0 * (x1 - np.asarray(increment, dtype=float) / h)
    u = (np.asarray(s, dtype=float) - 1.0)[:, None]
    return x1 + b * u, np.broadcast_to(b / h, (u.shape[0], x1.shape[-1])).copy()


def step_hermite(
    x0: ArrayLike, xd0: ArrayLike, x1: ArrayLike, xd1: ArrayLike, h: float, s: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite path over a step from end values and end derivatives.

    Parameters
    ----------
    x0, xd0 : array_like, shape (3,)
        Value and time derivative at ``t``.
    x1, xd1 : array_like, shape (3,)
        Value and time derivative at ``t + h``.
    h : float
        Step [s].
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    x, x_dot, x_ddot : ndarray, shape (m, 3)
        Value and first and second time derivatives at the nodes. ``x_dot``
        integrates to ``x1 - x0`` and ``x_ddot`` to ``xd1 - xd0`` exactly.
    """
    s = np.ascontiguousarray(s, dtype=float)
    b0, b1, b2 = _hermite_basis(s.tobytes())
    p = np.array([x0, np.asarray(xd0, dtype=float) * h, x1, np.asarray(xd1, dtype=float) * h])
    return b0 @ p, (b1 @ p) / h, (b2 @ p) / (h * h)


def hermite_basis(s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite basis at the nodes ``s`` (cached per ``s``).

    Parameters
    ----------
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    b0, b1, b2 : ndarray, shape (m, 4)
        Value, first and second derivative (in ``s``) of the path from the rows
        ``[x0, h x0', x1, h x1']``; :func:`step_hermite` is ``b0 @ p``, ``b1 @ p / h``,
        ``b2 @ p / h^2``.
    """
    return _hermite_basis(np.ascontiguousarray(s, dtype=float).tobytes())


@functools.lru_cache(maxsize=64)
def _hermite_basis(key: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite basis (value, first and second derivative) at the nodes, each (m, 4)."""
    u = np.frombuffer(key, dtype=float)[:, None]
    u2, u3 = u * u, u * u * u
    b0 = np.hstack([2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2])
    b1 = np.hstack([6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u])
    b2 = np.hstack([12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2])
    for b in (b0, b1, b2):
        b.setflags(write=False)
    return b0, b1, b2


@functools.lru_cache(maxsize=64)
def _path_basis(key: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bases of :class:`StepPath`'s paths at the nodes ``u`` (``key``: their bytes).

    Returns
    -------
    quartic, quartic_d : ndarray, shape (m, 5)
        Value and ``h`` times the time derivative of the quartic from the rows
        ``[x0, h x0', x1, h x1', c]``: the cubic Hermite basis plus ``u^2 (1 - u)^2``.
    quadratic, quadratic_d : ndarray, shape (m, 3)
        The same for the quadratic from ``[x0, x1, c]``: ``x0 (1 - u) + x1 u + c u (1 - u)``.
    """
    u = np.frombuffer(key, dtype=float)[:, None]
    b0, b1, _ = _hermite_basis(key)
    bump = u * (1.0 - u)
    quartic = np.hstack([b0, bump * bump])
    quartic_d = np.hstack([b1, 2.0 * bump * (1.0 - 2.0 * u)])
    quadratic = np.hstack([1.0 - u, u, bump])
    quadratic_d = np.hstack([-np.ones_like(u), np.ones_like(u), 1.0 - 2.0 * u])
    out = (quartic, quartic_d, quadratic, quadratic_d)
    for b in out:
        b.setflags(write=False)
    return out


def path_basis(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bases that turn :meth:`StepPath.coefficients` into node values (cached per ``s``).

    Parameters
    ----------
    s : ndarray, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    quartic, quartic_d : ndarray, shape (m, 5)
        ``x = quartic @ coef``, ``x' = quartic_d @ coef / h`` for a path with a derivative.
    quadratic, quadratic_d : ndarray, shape (m, 3)
        The same for a path without one.
    """
    return _path_basis(np.ascontiguousarray(s, dtype=float).tobytes())


class StepPath:
    """Path of a 3-vector input inside each step, rebuilt from step-end values and increments.

    Keeps the previous step-end value (and derivative, when one is connected) so
    that the start of the step is known exactly. With a derivative the path is
    the quartic ``x0, x0', x1, x1'`` Hermite cubic plus ``c u^2 (1 - u)^2``
    (``u = (tau - t) / h``) with ``c`` matching the increment; without, the
    quadratic through ``x0, x1`` matching the increment. Both are exact for
    polynomials of that degree. Without a valid start (first step after a
    time jump, or a start value inconsistent with the increment by more than
    ``rel_tol`` of the path's size, e.g. an input not forwarded at
    initialisation), the memoryless :func:`step_quadratic` / :func:`step_linear`
    is used for that step.

    Parameters
    ----------
    rel_tol : float
        Largest accepted mismatch between the increment and the path through
        the stored start, relative to ``|x0| + |x1| + h (|x0'| + |x1'|)``.
    """

    def __init__(self, rel_tol: float = 1e-2) -> None:
        self.rel_tol = rel_tol
        self._t: float | None = None
        self._x = np.zeros(3)
        self._xd: np.ndarray | None = None

    def reset(self, t: float, x: ArrayLike, xd: ArrayLike | None = None) -> None:
        """Store the value (and derivative) at time ``t`` as the start of the next step.

        Parameters
        ----------
        t : float
            Time of the value, the start of the next step [s].
        x : array_like, shape (3,)
            Value of the input at ``t`` (its unit and frame).
        xd : array_like, shape (3,), optional
            Its time derivative at ``t`` (unit per second); None when no derivative is
            connected (the next step then uses the quadratic path).
        """
        self._t = float(t)
        self._x = np.array(x, dtype=float)
        self._xd = None if xd is None else np.array(xd, dtype=float)

    def coefficients(
        self,
        t: float,
        h: float,
        end: ArrayLike,
        increment: ArrayLike,
        end_rate: ArrayLike | None = None,
    ) -> np.ndarray | None:
        """This step's path as coefficient rows for :func:`path_basis`, and advance.

        Parameters
        ----------
        t, h : float
            Step start and size [s].
        end : array_like, shape (3,)
            Value at ``t + h``.
        increment : array_like, shape (3,)
            Integral over the step.
        end_rate : array_like, shape (3,), optional
            Derivative at ``t + h`` (per second).

        Returns
        -------
        ndarray or None
            With ``end_rate``: shape (5, 3), rows ``[x0, h x0', x1, h x1', c]`` of the
            quartic; without: shape (3, 3), rows ``[x0, x1, c]`` of the quadratic. None
            when the stored start is not valid for this step: use the memoryless
            :func:`step_quadratic` / :func:`step_linear` (what :meth:`nodes` does).
        """
        x1 = np.asarray(end, dtype=float)
        mean = np.asarray(increment, dtype=float) / h
        valid = self._t is not None and abs(t - self._t) <= 1e-6 * h
        out = None
        if end_rate is None:
            if valid:
                x0 = self._x
                c = mean - 0.5 * (x0 + x1)
                out = np.array([x0, x1, 6.0 * c])
                norms = np.sqrt((out * out).sum(axis=1))  # |x0|, |x1|, 6 |c|
                if not norms[2] <= 6.0 * (self.rel_tol * (norms[0] + norms[1]) + 1e-300):
                    out = None
            self.reset(t + h, x1)
            return out
        xd1 = np.asarray(end_rate, dtype=float)
        if valid and self._xd is not None:
            x0, m0, m1 = self._x, self._xd * h, xd1 * h
            mismatch = mean - (0.5 * (x0 + x1) + (m0 - m1) / 12.0)
            out = np.array([x0, m0, x1, m1, 30.0 * mismatch])
            norms = np.sqrt((out * out).sum(axis=1))  # |x0|, |m0|, |x1|, |m1|, 30 |mismatch|
            scale = norms[0] + norms[2] + norms[1] + norms[3]
            if not norms[4] <= 30.0 * (self.rel_tol * scale + 1e-300):
                out = None
        self.reset(t + h, x1, xd1)
        return out

    def nodes(
        self,
        t: float,
        h: float,
        end: ArrayLike,
        increment: ArrayLike,
        s: np.ndarray,
        end_rate: ArrayLike | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Values and time derivatives (m, 3) at normalised times ``s`` of ``[t, t + h]``.

        Parameters
        ----------
        t, h : float
            Step start and size [s].
        end : array_like, shape (3,)
            Value at ``t + h``.
        increment : array_like, shape (3,)
            Integral over the step.
        s : ndarray, shape (m,)
            Normalised times in [0, 1].
        end_rate : array_like, shape (3,), optional
            Derivative at ``t + h`` (per second).

        Returns
        -------
        x, x_dot : ndarray, shape (m, 3)
        """
        coef = self.coefficients(t, h, end, increment, end_rate)
        if coef is None:
            if end_rate is None:
                return step_linear(end, increment, h, s)
            return step_quadratic(end, end_rate, increment, h, s)
        quartic, quartic_d, quadratic, quadratic_d = path_basis(s)
        if end_rate is None:
            return quadratic @ coef, (quadratic_d @ coef) / h
        return quartic @ coef, (quartic_d @ coef) / h
