"""Frames, attitude conventions and rotation algebra shared by every model.

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

The seed-001 ENU/RFU conversions are in :mod:`models.frames`; the step conventions
(what a block's inputs and outputs mean over ``[t, t + h]``) and the step paths are in
:mod:`models.step_paths`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

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
        ``C_b_n = Rz(yaw) @ Ry(pitch) @ Rx(roll)``; one set of angles (shape (3,))
        takes the scalar path :func:`euler_to_dcm_3` (same arithmetic, a third of
        the time).
    """
    rpy = np.asarray(rpy, dtype=float)
    if rpy.shape == (3,):
        return euler_to_dcm_3(rpy)
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
        One DCM (shape (3, 3)) takes the scalar path :func:`dcm_to_euler_3`.
    """
    c = np.asarray(c, dtype=float)
    if c.shape == (3, 3):
        return dcm_to_euler_3(c)
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = np.arctan2(-c[..., 2, 0], np.hypot(c[..., 2, 1], c[..., 2, 2]))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return vec3(roll, pitch, yaw)


def dcm_to_euler_3(c: np.ndarray) -> np.ndarray:
    """:func:`dcm_to_euler` of one DCM with scalar math (fast path).

    Parameters
    ----------
    c : ndarray, shape (3, 3)
        ``C_b_n``.

    Returns
    -------
    ndarray, shape (3,)
        ``[roll, pitch, yaw]`` [rad]; roll and yaw in (-pi, pi], pitch in [-pi/2, pi/2].
    """
    (c00, _, _), (c10, _, _), (c20, c21, c22) = c.tolist()
    return np.array(
        [math.atan2(c21, c22), math.atan2(-c20, math.hypot(c21, c22)), math.atan2(c10, c00)]
    )


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

    Elementwise arithmetic in a fixed order (``[phi x]^2`` written out, no matrix
    products), which the compiled lever arm (``models/blocks/lever_arm.c``) repeats.

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
    x, y, z = phi[..., 0], phi[..., 1], phi[..., 2]
    xx, yy, zz = x * x, y * y, z * z
    a = np.sqrt(xx + yy + zz)
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
        s2 = np.where(small, 0.5 - a2 / 24.0 + a4 / 720.0, (1.0 - np.cos(safe)) / (safe * safe))
        s3 = np.where(
            small,
            1.0 / 6.0 - a2 / 120.0 + a4 / 5040.0,
            (safe - np.sin(safe)) / (safe * safe * safe),
        )
    k = skew(phi)
    k2 = np.empty(phi.shape[:-1] + (3, 3))  # [phi x]^2
    k2[..., 0, 0] = -zz - yy
    k2[..., 0, 1] = y * x
    k2[..., 0, 2] = z * x
    k2[..., 1, 0] = x * y
    k2[..., 1, 1] = -zz - xx
    k2[..., 1, 2] = z * y
    k2[..., 2, 0] = x * z
    k2[..., 2, 1] = y * z
    k2[..., 2, 2] = -yy - xx
    s1, s2, s3 = s1[..., None, None], s2[..., None, None], s3[..., None, None]
    return _EYE3 + s1 * k + s2 * k2, _EYE3 - s2 * k + s3 * k2
