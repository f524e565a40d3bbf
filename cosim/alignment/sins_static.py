"""Stationary SINS self north-finding (seed 003): coarse alignment, then a 10-state KF.

The block :class:`SinsStaticAlignment` reads the measured increments of a strapdown
IMU (optionally on a turntable), aligns analytically, runs its own strapdown
mechanisation and a 10-state error-state Kalman filter with zero-velocity
measurements, and feeds every estimate back (closed loop). With the IMU on a
turntable turning with reversals it removes the table rotation with the encoder
angle, and the modulation of the sensor errors makes the east gyro drift observable.

Frames (``models.conventions``): ``n`` NED, ``b`` the base (FRD), ``t`` the table
(rotated by the encoder angle ``gamma`` about the base z axis), ``s`` the sensors
(``C_s_t`` from the table mounting ``mount_rpy``)::

    C_s_n = C_b_n Rz(gamma) C_s_t,      C_t_n = C_b_n Rz(gamma)

Without a turntable ``gamma = 0`` and ``mount_rpy = 0``, so ``s = t = b``.

Coarse alignment (analytic, TRIAD)
----------------------------------
Over ``coarse_time`` the mean specific force ``f_s`` and rate ``w_s`` (sums of the
increments over the time) are the images of the references ``f_n = [0, 0, -g]`` and
``w_n = omega_ie_n = [W cos L, 0, -W sin L]``. Orthonormal triads built the same way
in both frames::

    u1 = f / |f|,   u2 = (f x w) / |f x w|,   u3 = u1 x u2,      C_s_n = U_n U_s^T

make gravity define the level exactly and ``f x w`` (east-west) the heading; with a
perfect IMU on a static base the result is exact. With sensor errors ``nabla``
(accelerometer) and ``eps`` (gyro), resolved in ``n``, the residual misalignment is
(psi angle, see below; ``e = -psi`` is the estimate-minus-truth rotation)::

    psi_N = nabla_E / g,    psi_E = -nabla_N / g,
    psi_D = eps_E / (W cos L) - tan L nabla_E / g.

Fine alignment: the static-base psi-angle error model
-----------------------------------------------------
The computed attitude is ``C^_s_n = (I - [psi x]) C_s_n`` (``psi`` = misalignment of
the computed navigation frame, NED), the computed velocity ``v^ = v + dv``. The
mechanisation (below) is ``v^' = C^_s_n f~_s + g_n - 2 w_ie x v^`` and
``C^' = C^ [w~_is x] - [w_ie x] C^`` with the measured ``f~ = f + nabla``,
``w~ = w + eps``. Subtracting the true equations and keeping first-order terms, on
a stationary base (``v = 0``, ``f_n = [0, 0, -g]``, transport rate zero)::

    dv'  = f_n x psi - 2 w_ie x dv + C_t_n nabla_t
    psi' = -w_ie x psi - C_t_n eps_t

Component-wise, with ``W_N = W cos L``, ``W_D = -W sin L`` and only the horizontal
velocity (the vertical channel is not mechanised: ``v_D = 0``)::

    dv_N'  =  g psi_E - 2 W sin L dv_E + (C_t_n nabla_t)_N
    dv_E'  = -g psi_N + 2 W sin L dv_N + (C_t_n nabla_t)_E
    psi_N' = -W sin L psi_E                - (C_t_n eps_t)_N
    psi_E' =  W sin L psi_N + W cos L psi_D - (C_t_n eps_t)_E
    psi_D' = -W cos L psi_E                - (C_t_n eps_t)_D

The state is ``x = [dv_N, dv_E, psi_N, psi_E, psi_D, nabla_x, nabla_y, eps_x, eps_y,
eps_z]`` (SI: m/s, rad, m/s2, rad/s). The sensor errors are random constants in the
*table* frame: ``nabla_t = C_s_t nabla_s``, ``eps_t = C_s_t eps_s``. On a level base
the horizontal part of ``C_t_n nabla_t`` depends on ``nabla_x, nabla_y`` only, so the
10-state model holds for any tilted mounting of the sensors on the table (seed 003's
rate-biasing mount); without a table ``t = s = b`` and these are the paper's states.
With the table turning, ``C_t_n = C_b_n Rz(gamma(t))`` is time varying: this
modulation makes ``eps_x, eps_y, nabla_x, nabla_y`` observable (rank 10); on a fixed
base the rank is 7 (``psi_D`` cannot be told from ``eps_E``, nor the level angles
from ``nabla``), hence the heading limit ``eps_E / (W cos L)`` (6.46' for 0.02 deg/h
at 45 deg). Noise: ``w = [w_a (2), w_g (3)]`` enters ``dv`` and ``psi`` directly
(``G = [I_5; 0]``), ``Qc = diag(q_accel^2 I_2, q_gyro^2 I_3)`` (seed 003's Q as
densities, per second). Measurement: ``z = v^_NE = H x + n``, ``H = [I_2, 0]``,
``R = r_vel^2 I_2`` every ``kf_period``. The simulated base is perfectly still;
``zupt_noise`` adds white noise of that sigma to each measurement (the disturbance of a
quasi-static base that seed 003's R stands for; the block's ``seed`` draws it).

Discretisation in the block (every step ``h``): ``Phi = I + F h + (F h)^2 / 2``
(the chains ``dv <- psi <- eps`` need the second-order term at ``h = 0.1 s``),
``Qd = (Phi G Qc G^T Phi^T + G Qc G^T) h / 2``, ``F`` with ``C_t_n`` averaged over
the step. The covariance analysis (:func:`covariance_analysis`) is independent of
it: exact Van Loan discretisation of the same continuous model.

Mechanisation (sensor frame, every step)
----------------------------------------
Increments are corrected with the bias estimates, ``dth = dtheta_s - C_s_t^T eps^ h``,
``dv = dv_s - C_s_t^T [nabla^_x, nabla^_y, 0] h``. Then::

    phi    = theta a + k(theta) (dth - theta a),   theta = a . dth,
             k = (theta / 2)^2 / sin^2(theta / 2)                  (table-axis coning)
    C_s_n <- exp(-[zeta x]) C_s_n exp([phi x]),    zeta = w_ie h
    v_n   <- v_n + (I - [zeta x] / 2) C_s_n J(-phi)^-1 dv + (-2 w_ie x v_n) h,  v_D = 0

``a = C_s_t^T e_z`` is the table axis in sensor axes. For a table turning at a
constant rate on a stationary base, the part of the increment perpendicular to the
axis is the earth rate averaged over a turning frame; ``k`` turns it into the exact
rotation vector (to first order in the earth rate). The usual two-sample coning
correction agrees with ``k = 1 + theta^2 / 12 + ...`` to second order but leaves a
residual ``theta^3 / 24`` of the earth rate turned by 90 deg: at 10 deg per step an
east drift of 0.002 deg/h (flipping sign with each reversal). ``J(x) = I +
(1 - cos a) / a^2 [x x] + (a - sin a) / a^3 [x x]^2`` is the mean of ``exp([x s x])``
over ``s in [0, 1]``; ``J(-phi)^-1 dv`` is the exact rotation compensation when the
specific force is constant in inertial space over the step (a stationary base, any
tilt). Both reduce to the classical first-order terms for small steps. During the
table's acceleration ramps (200 deg/s2 at the reversals) the constant-rate
assumption leaves velocity glitches of about 0.1 mm/s, far below the measurement
noise. A lever arm between the axis and the sensors (centrifugal acceleration) is
not compensated: the sensors sit on the axis.

Closed loop: after each measurement update ``C^_s_n <- exp([psi^ x]) C^_s_n``,
``v^ <- v^ - dv^``, ``nabla^ += x_nabla``, ``eps^ += x_eps`` and ``x <- 0``; ``P``
is kept.

Outputs (estimate minus truth, the truth from the motion block's ``rpy``):
``phi_err`` is the rotation from the true to the estimated base attitude,
``C^_b_n = exp([phi_err x]) C_b_n`` (``= -psi``; for a level base ``phi_err_D``
is the heading error), ``rpy_err`` the Euler-angle errors, their 1-sigma from
``P`` and the NEES ``phi_err^T P_psi^-1 phi_err`` of the three angles.
``phi_hat = log(C^_b_n(t_f) C^_b_n(t)^T)`` estimates ``phi_err`` at the start of the
fine alignment ``t_f`` (what the paper adds to the coarse heading); on a stationary
base its own error is about ``-phi_err(t)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.estimation import KalmanFilter, van_loan
from models.block import Block, input_, output, parameter
from models.constants import OMEGA_IE
from models.conventions import euler_to_dcm_3, rotvec_to_dcm_3
from models.earth import gravity

FloatArray = NDArray[np.float64]

DEG = math.pi / 180.0  #: 1 deg [rad]
ARCMIN = DEG / 60.0  #: 1 arcmin [rad]
ARCSEC = DEG / 3600.0  #: 1 arcsec [rad]
DEG_PER_HOUR = DEG / 3600.0  #: 1 deg/h [rad/s]
MICRO_G = 9.80665e-6  #: 1 ug [m/s2]

#: State names, in order.
STATES = (
    "dv_N",
    "dv_E",
    "psi_N",
    "psi_E",
    "psi_D",
    "nabla_x",
    "nabla_y",
    "eps_x",
    "eps_y",
    "eps_z",
)
N_STATES = 10
_I3 = np.eye(3)
_EZ = np.array([0.0, 0.0, 1.0])


class AlignmentConfigError(ValueError):
    """A parameter of the alignment block is invalid (the message says which and why)."""


class AlignmentError(RuntimeError):
    """The alignment cannot proceed with the inputs it receives (e.g. a moving table)."""


# ------------------------------------------------------------------ tuning
@dataclass(frozen=True)
class FilterTuning:
    """Initial covariance, process and measurement noise of the 10-state filter.

    Defaults are seed 003's P0, Q and R.

    Attributes
    ----------
    p0_vel : float
        Initial velocity-error sigma [m/s] (N and E).
    p0_att : tuple of float
        Initial misalignment sigmas ``(N, E, D)`` [rad].
    p0_accel_bias : float
        Accelerometer bias sigma [m/s2] (x and y of the table frame).
    p0_gyro_drift : float
        Gyro drift sigma [rad/s] (x, y, z of the table frame).
    q_accel : float
        Accelerometer white-noise density [m/s/sqrt(s)] (seed 003: 50 ug per second).
    q_gyro : float
        Gyro white-noise density [rad/sqrt(s)] (seed 003: 0.01 deg/h per second).
    r_vel : float
        Zero-velocity measurement sigma [m/s] per update.
    """

    p0_vel: float = 0.1
    p0_att: tuple[float, float, float] = (DEG, DEG, DEG)
    p0_accel_bias: float = 100.0 * MICRO_G
    p0_gyro_drift: float = 0.02 * DEG_PER_HOUR
    q_accel: float = 50.0 * MICRO_G
    q_gyro: float = 0.01 * DEG_PER_HOUR
    r_vel: float = 0.1

    def P0(self) -> FloatArray:
        """Initial covariance, shape (10, 10), SI units squared."""
        d = [self.p0_vel] * 2 + list(self.p0_att) + [self.p0_accel_bias] * 2
        d += [self.p0_gyro_drift] * 3
        return np.diag(np.square(np.asarray(d, dtype=float)))

    def Qc(self) -> FloatArray:
        """Continuous noise intensity of ``[w_a (N, E), w_g (N, E, D)]``, shape (5, 5)."""
        return np.diag([self.q_accel**2] * 2 + [self.q_gyro**2] * 3)

    def R(self) -> FloatArray:
        """Measurement noise covariance, shape (2, 2) [(m/s)^2]."""
        return np.eye(2) * self.r_vel**2


#: Seed 003's P0, Q and R.
SEED003 = FilterTuning()


# ------------------------------------------------------------------ small rotations
def _so3_poly(v: ArrayLike, alpha: float, beta: float) -> FloatArray:
    """``I + alpha [v x] + beta [v x]^2`` (using ``[v x]^2 = v v^T - |v|^2 I``), shape (3, 3)."""
    x, y, z = np.asarray(v, dtype=float).tolist()
    d = 1.0 - beta * (x * x + y * y + z * z)
    return np.array(
        [
            [d + beta * x * x, beta * x * y - alpha * z, beta * x * z + alpha * y],
            [beta * x * y + alpha * z, d + beta * y * y, beta * y * z - alpha * x],
            [beta * x * z - alpha * y, beta * y * z + alpha * x, d + beta * z * z],
        ]
    )


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a x b`` for two 3-vectors (``np.cross`` is slow on small arrays)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _norm2(v: ArrayLike) -> float:
    x, y, z = np.asarray(v, dtype=float).tolist()
    return x * x + y * y + z * z


def dcm_rotvec(c: ArrayLike) -> FloatArray:
    """Rotation vector (logarithm) of a DCM, shape (3,) [rad], for angles below pi.

    Parameters
    ----------
    c : array_like, shape (3, 3)
        Orthonormal DCM (``exp([phi x])``); the result is ``phi``, in the frame in which
        ``c`` rotates (e.g. NED for a nav-frame error ``C^ C^T``).

    Returns
    -------
    ndarray, shape (3,)
        Rotation vector [rad].
    """
    c = np.asarray(c, dtype=float)
    w = 0.5 * np.array([c[2, 1] - c[1, 2], c[0, 2] - c[2, 0], c[1, 0] - c[0, 1]])
    s = math.sqrt(_norm2(w))
    if s < 1e-12:
        return w
    return w * (math.atan2(s, 0.5 * (c[0, 0] + c[1, 1] + c[2, 2] - 1.0)) / s)


def step_mean_dcm(phi: ArrayLike) -> FloatArray:
    """``J(phi)``: the mean of ``exp([phi s x])`` over ``s in [0, 1]``, shape (3, 3).

    ``J = I + (1 - cos a) / a^2 [phi x] + (a - sin a) / a^3 [phi x]^2``, ``a = |phi|``.

    Parameters
    ----------
    phi : array_like, shape (3,)
        Rotation vector of the step, sensor axes [rad].

    Returns
    -------
    ndarray, shape (3, 3)
        ``J(phi)``.
    """
    a2 = _norm2(phi)
    if a2 < 1e-6:
        s2 = 0.5 - a2 / 24.0 + a2 * a2 / 720.0
        s3 = 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0
    else:
        a = math.sqrt(a2)
        s2 = (1.0 - math.cos(a)) / a2
        s3 = (a - math.sin(a)) / (a2 * a)
    return _so3_poly(phi, s2, s3)


def rotation_compensation(phi: ArrayLike) -> FloatArray:
    """``J(-phi)^-1 = I + [phi x] / 2 + c [phi x]^2``, shape (3, 3).

    ``c = 1 / a^2 - (1 + cos a) / (2 a sin a)`` (``1/12 + a^2/720 + ...`` for small ``a``).
    Maps the raw velocity increment of a step turning by ``phi`` at a constant rate to
    the velocity change resolved in the sensor axes at the start of the step, when the
    specific force is constant in inertial space.

    Parameters
    ----------
    phi : array_like, shape (3,)
        Rotation vector of the step, sensor axes [rad].

    Returns
    -------
    ndarray, shape (3, 3)
        ``J(-phi)^-1``.
    """
    a2 = _norm2(phi)
    if a2 < 1e-4:
        c = 1.0 / 12.0 + a2 / 720.0 + a2 * a2 / 30240.0
    else:
        a = math.sqrt(a2)
        c = 1.0 / a2 - (1.0 + math.cos(a)) / (2.0 * a * math.sin(a))
    return _so3_poly(phi, 0.5, c)


def table_axis_coning(dtheta: ArrayLike, axis: ArrayLike) -> FloatArray:
    """Rotation vector of a step from its increment, for a table turning about ``axis``.

    ``phi = theta a + k (dtheta - theta a)``, ``theta = a . dtheta``,
    ``k = (theta / 2)^2 / sin^2(theta / 2)``. Exact (to first order in the earth
    rate) for a table turning at a constant rate on a stationary base.

    Parameters
    ----------
    dtheta : array_like, shape (3,)
        Angle increment over the step, sensor axes [rad].
    axis : array_like, shape (3,)
        Unit vector of the table axis in sensor axes.

    Returns
    -------
    ndarray, shape (3,)
    """
    dx, dy, dz = np.asarray(dtheta, dtype=float).tolist()
    ax, ay, az = np.asarray(axis, dtype=float).tolist()
    theta = ax * dx + ay * dy + az * dz
    t2 = theta * theta
    if t2 < 1e-4:
        k = 1.0 + t2 / 12.0 + t2 * t2 / 240.0
    else:
        k = (0.5 * theta / math.sin(0.5 * theta)) ** 2
    m = theta * (1.0 - k)
    return np.array([k * dx + m * ax, k * dy + m * ay, k * dz + m * az])


def dcm_euler(c: FloatArray) -> FloatArray:
    """Z-Y-X Euler angles of a DCM (inverse of :func:`models.conventions.euler_to_dcm_3`).

    Parameters
    ----------
    c : ndarray, shape (3, 3)
        Body (here: sensor) to NED DCM ``C_b_n``; Z-Y-X Euler angles, pitch away from +-90 deg.

    Returns
    -------
    ndarray, shape (3,)
        ``[roll, pitch, yaw]`` [rad], roll and yaw in (-pi, pi].
    """
    return np.array(
        [
            math.atan2(c[2, 1], c[2, 2]),
            math.atan2(-c[2, 0], math.hypot(c[2, 1], c[2, 2])),
            math.atan2(c[1, 0], c[0, 0]),
        ]
    )


def euler_error_jacobian(rpy: ArrayLike) -> FloatArray:
    """``M`` with ``d rpy = M e`` for a small nav-frame rotation ``C -> exp([e x]) C``.

    The nav-frame angular velocity of Z-Y-X angles is
    ``w_n = roll' Rz Ry e_x + pitch' Rz e_y + yaw' e_z = E rpy'``, and::

        M = E^-1 = [[cos y / cos p, sin y / cos p, 0],
                    [-sin y,        cos y,         0],
                    [tan p cos y,   tan p sin y,   1]]

    Parameters
    ----------
    rpy : array_like, shape (3,)
        ``[roll, pitch, yaw]`` [rad] (pitch away from +-90 deg).

    Returns
    -------
    ndarray, shape (3, 3)
    """
    _, p, y = np.asarray(rpy, dtype=float).tolist()
    cp, tp, cy, sy = math.cos(p), math.tan(p), math.cos(y), math.sin(y)
    return np.array([[cy / cp, sy / cp, 0.0], [-sy, cy, 0.0], [tp * cy, tp * sy, 1.0]])


def quad_form_inv3(e: ArrayLike, P: ArrayLike) -> float:
    """``e^T P^-1 e`` for a 3-vector and a 3x3 SPD matrix (explicit Cholesky, no LAPACK call).

    Parameters
    ----------
    e : array_like, shape (3,)
        Error vector, e.g. the attitude error ``phi_err`` [rad], NED.
    P : array_like, shape (3, 3)
        Its covariance, symmetric positive definite, e.g. ``P_att`` [rad^2]; only the
        upper triangle is read.

    Returns
    -------
    float
        The squared Mahalanobis distance (dimensionless).

    Raises
    ------
    AlignmentError
        When ``P`` is not positive definite.
    """
    (a, b, c), (_, d, f), (_, _, k) = np.asarray(P, dtype=float).tolist()
    e1, e2, e3 = np.asarray(e, dtype=float).tolist()
    try:
        l11 = math.sqrt(a)
        l21, l31 = b / l11, c / l11
        l22 = math.sqrt(d - l21 * l21)
        l32 = (f - l31 * l21) / l22
        l33 = math.sqrt(k - l31 * l31 - l32 * l32)
    except (ValueError, ZeroDivisionError) as exc:
        raise AlignmentError("attitude covariance is not positive definite") from exc
    y1 = e1 / l11
    y2 = (e2 - l21 * y1) / l22
    y3 = (e3 - l31 * y1 - l32 * y2) / l33
    return y1 * y1 + y2 * y2 + y3 * y3


def wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi] [rad].

    Parameters
    ----------
    a : float
        Angle [rad].

    Returns
    -------
    float
        ``a`` plus a multiple of ``2 pi``, in (-pi, pi] [rad].
    """
    return math.pi - (math.pi - a) % (2.0 * math.pi)


def table_dcm(gamma: float) -> FloatArray:
    """``Rz(gamma)``: table to base for encoder angle ``gamma`` [rad], shape (3, 3).

    Parameters
    ----------
    gamma : float
        Table encoder angle, a right-handed turn about the base z axis (down) [rad].

    Returns
    -------
    ndarray, shape (3, 3)
        ``C_t_b``.
    """
    c, s = math.cos(gamma), math.sin(gamma)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ------------------------------------------------------------------ coarse alignment
def _triad(a: FloatArray, b: FloatArray) -> FloatArray:
    u1 = a / np.linalg.norm(a)
    c = _cross(a, b)
    norm = np.linalg.norm(c)
    if not norm > 0.0:
        raise AlignmentError(
            "coarse alignment: specific force and angular rate are parallel (at a pole, "
            "or the IMU outputs are zero); cannot find the heading"
        )
    u2 = c / norm
    return np.column_stack([u1, u2, _cross(u1, u2)])


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
    w_n = np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])
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


# ------------------------------------------------------------------ error model
def error_model(C_t_n: ArrayLike, lat: float, h: float = 0.0, coriolis: bool = True) -> FloatArray:
    """Continuous system matrix ``F`` of the 10-state static-base psi-angle model.

    Parameters
    ----------
    C_t_n : array_like, shape (3, 3)
        Table (carrier of the sensors) to NED; the base attitude without a table.
    lat : float
        Latitude [rad].
    h : float
        Height [m].
    coriolis : bool
        Include the ``-2 w_ie x dv`` terms (the mechanisation has them; their effect
        on the alignment is below 0.1 %).

    Returns
    -------
    ndarray, shape (10, 10)
        ``x' = F x + G w``, states :data:`STATES` (SI).
    """
    c = np.asarray(C_t_n, dtype=float)
    g = float(gravity(lat, h))
    sl, cl = math.sin(lat), math.cos(lat)
    F = np.zeros((N_STATES, N_STATES))
    F[0, 3] = g
    F[1, 2] = -g
    if coriolis:
        F[0, 1] = -2.0 * OMEGA_IE * sl
        F[1, 0] = 2.0 * OMEGA_IE * sl
    F[2, 3] = -OMEGA_IE * sl
    F[3, 2] = OMEGA_IE * sl
    F[3, 4] = OMEGA_IE * cl
    F[4, 3] = -OMEGA_IE * cl
    F[0:2, 5:7] = c[0:2, 0:2]
    F[2:5, 7:10] = -c
    return F


def noise_input() -> FloatArray:
    """``G``, shape (10, 5): accelerometer noise into ``dv``, gyro noise into ``psi``."""
    G = np.zeros((N_STATES, 5))
    G[0:5, 0:5] = np.eye(5)
    return G


def measurement_matrix() -> FloatArray:
    """``H``, shape (2, 10): the zero-velocity measurement sees ``dv_N, dv_E``."""
    H = np.zeros((2, N_STATES))
    H[0, 0] = H[1, 1] = 1.0
    return H


def discretize_taylor(F: FloatArray, Gq: FloatArray, h: float) -> tuple[FloatArray, FloatArray]:
    """The block's per-step discretisation: ``Phi = I + A + A^2/2`` (``A = F h``), trapezoid Qd.

    Parameters
    ----------
    F : ndarray, shape (n, n)
        System matrix [1/s].
    Gq : ndarray, shape (n, n)
        ``G Qc G^T`` [state units^2 / s].
    h : float
        Step [s].

    Returns
    -------
    Phi, Qd : ndarray, shape (n, n)
    """
    A = F * h
    Phi = np.eye(F.shape[0]) + A + 0.5 * (A @ A)
    Qd = 0.5 * h * (Phi @ Gq @ Phi.T + Gq)
    return Phi, Qd


# ------------------------------------------------------------------ covariance analysis
@dataclass
class CovarianceHistory:
    """Filter covariance of the linear model over time (no simulation).

    Attributes
    ----------
    time : ndarray, shape (m,)
        Times after the start of fine alignment [s] (0 first).
    sigma : ndarray, shape (m, 10)
        Posterior 1-sigma of every state (SI).
    P_att : ndarray, shape (m, 3, 3)
        Posterior covariance of ``psi`` [rad^2].
    """

    time: FloatArray
    sigma: FloatArray
    P_att: FloatArray

    def index(self, t: float) -> int:
        """Index of the recorded time closest to ``t`` [s].

        Parameters
        ----------
        t : float
            Time after the start of fine alignment [s].

        Returns
        -------
        int
            Index into :attr:`time`.
        """
        return int(np.argmin(np.abs(self.time - t)))

    def at(self, t: float) -> FloatArray:
        """1-sigma of every state at the recorded time closest to ``t``, shape (10,).

        Parameters
        ----------
        t : float
            Time after the start of fine alignment [s].

        Returns
        -------
        ndarray, shape (10,)
            A row of :attr:`sigma` (SI, states :data:`STATES`).
        """
        return self.sigma[self.index(t)]

    def heading_sigma(self) -> FloatArray:
        """1-sigma of ``psi_D`` [rad], shape (m,)."""
        return self.sigma[:, 4]


def covariance_analysis(
    t_end: float,
    *,
    tuning: FilterTuning = SEED003,
    lat: float = 45.0 * DEG,
    h: float = 0.0,
    dt: float = 0.1,
    kf_period: float = 0.1,
    angle: Callable[[FloatArray], FloatArray] | None = None,
    base_rpy: ArrayLike = (0.0, 0.0, 0.0),
    coriolis: bool = False,
    record_every: int = 1,
) -> CovarianceHistory:
    """Covariance of the 10-state filter over ``[0, t_end]``, from the linear model alone.

    Every ``dt`` the covariance is propagated with the exact (Van Loan) discretisation
    of the continuous model, ``F`` evaluated with the table at mid-step; every
    ``kf_period`` the zero-velocity update (Joseph form) follows.

    Parameters
    ----------
    t_end : float
        Duration [s] (a multiple of ``dt``).
    tuning : FilterTuning
        P0, Q, R (default seed 003's).
    lat, h : float
        Latitude [rad], height [m].
    dt : float
        Propagation step [s]; ``kf_period`` must be a multiple of it.
    kf_period : float
        Measurement period [s].
    angle : callable, optional
        Encoder angle ``gamma(t)`` [rad] for an array of times [s] (e.g.
        ``lambda t: rate * t`` for continuous rotation, or ``Turntable.profile``'s
        angle); None: no table.
    base_rpy : array_like, shape (3,)
        Base attitude [rad] (the result is insensitive to the heading).
    coriolis : bool
        Include the Coriolis terms (default False: the model as written in the issue).
    record_every : int
        Keep every k-th step.

    Returns
    -------
    CovarianceHistory

    Raises
    ------
    AlignmentConfigError
        When the steps do not fit.
    """
    n = int(round(t_end / dt))
    k_upd = int(round(kf_period / dt))
    if n < 1 or abs(n * dt - t_end) > 1e-9 * max(1.0, t_end):
        raise AlignmentConfigError(f"t_end = {t_end} s is not a whole number of dt = {dt} s")
    if k_upd < 1 or abs(k_upd * dt - kf_period) > 1e-9 * kf_period:
        raise AlignmentConfigError(f"kf_period = {kf_period} s is not a multiple of dt = {dt} s")
    c_b_n = euler_to_dcm_3(base_rpy)
    G = noise_input()
    Qc = tuning.Qc()
    H = measurement_matrix()
    R = tuning.R()
    P = tuning.P0()
    mid = (np.arange(n) + 0.5) * dt
    gammas = np.zeros(n) if angle is None else np.asarray(angle(mid), dtype=float)
    # F depends on the encoder angle only through Rz(gamma): reversing or continuous
    # profiles revisit the same angles, so the discretisations are cached by angle.
    cache: dict[float, tuple[FloatArray, FloatArray]] = {}
    times, sig, patt = [0.0], [np.sqrt(np.diag(P))], [P[2:5, 2:5].copy()]
    eye = np.eye(N_STATES)
    for i in range(n):
        key = round(float(gammas[i]) % (2.0 * math.pi), 12)
        if key not in cache:
            F = error_model(c_b_n @ table_dcm(gammas[i]), lat, h, coriolis)
            cache[key] = van_loan(F, G, Qc, dt)
        Phi, Qd = cache[key]
        P = Phi @ P @ Phi.T + Qd
        if (i + 1) % k_upd == 0:
            S = H @ P @ H.T + R
            K = np.linalg.solve(S, H @ P).T
            ikh = eye - K @ H
            P = ikh @ P @ ikh.T + K @ R @ K.T
        P = 0.5 * (P + P.T)
        if (i + 1) % record_every == 0:
            times.append((i + 1) * dt)
            sig.append(np.sqrt(np.diag(P)))
            patt.append(P[2:5, 2:5].copy())
    return CovarianceHistory(np.array(times), np.array(sig), np.array(patt))


# ------------------------------------------------------------------ strapdown
@dataclass
class Strapdown:
    """Sensor-frame strapdown mechanisation of a stationary (or turntable-carried) IMU.

    Parameters
    ----------
    C_s_n : ndarray, shape (3, 3)
        Initial sensor attitude.
    lat, h : float
        Position [rad, m] (fixed).
    table_axis : ndarray, shape (3,)
        Unit table axis in sensor axes (``C_s_t[2, :]``); any unit vector without a table.

    Attributes
    ----------
    C_s_n : ndarray, shape (3, 3)
        Attitude.
    v_n : ndarray, shape (3,)
        Velocity, NED; ``v_D`` is held at 0 (no vertical channel).
    C_mean : ndarray, shape (3, 3)
        ``C_s_n`` averaged over the last step (``C_s_n(t_k) J(phi)``).
    """

    C_s_n: FloatArray
    lat: float
    h: float = 0.0
    table_axis: FloatArray = field(default_factory=lambda: _EZ.copy())
    v_n: FloatArray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        self.C_s_n = np.array(self.C_s_n, dtype=float)
        self.table_axis = np.asarray(self.table_axis, dtype=float)
        self.w_ie = np.array([OMEGA_IE * math.cos(self.lat), 0.0, -OMEGA_IE * math.sin(self.lat)])
        self.g = float(gravity(self.lat, self.h))
        self.C_mean = self.C_s_n.copy()
        self._w_d = float(self.w_ie[2])
        self._count = 0
        self._h_nav = -1.0
        self._nav_rot = _I3

    def step(self, dtheta: FloatArray, dv: FloatArray, h: float) -> None:
        """Advance by one step of corrected increments.

        Parameters
        ----------
        dtheta : ndarray, shape (3,)
            Angle increment, sensor axes [rad].
        dv : ndarray, shape (3,)
            Velocity increment (integral of specific force), sensor axes [m/s].
        h : float
            Step [s].
        """
        phi = table_axis_coning(dtheta, self.table_axis)
        zeta = self.w_ie * h
        c0 = self.C_s_n
        self.C_mean = c0 @ step_mean_dcm(phi)
        dv_n = c0 @ (rotation_compensation(phi) @ dv)
        dv_n = dv_n - 0.5 * _cross(zeta, dv_n)
        vn, ve, _ = self.v_n.tolist()
        cor = 2.0 * self._w_d * h  # -2 w_ie x v, horizontal: [2 W_D v_E, -2 W_D v_N] h
        self.v_n = np.array([vn + dv_n[0] + cor * ve, ve + dv_n[1] - cor * vn, 0.0])
        self.C_s_n = self._rot_nav(h) @ c0 @ rotvec_to_dcm_3(phi)
        self._count += 1
        if self._count % 64 == 0:
            c = self.C_s_n
            self.C_s_n = 1.5 * c - 0.5 * (c @ c.T @ c)

    def _rot_nav(self, h: float) -> FloatArray:
        """``exp(-[w_ie h x])`` (cached per step size)."""
        if h != self._h_nav:
            self._h_nav = h
            self._nav_rot = rotvec_to_dcm_3(-self.w_ie * h)
        return self._nav_rot

    def correct(self, dv_n: FloatArray, psi: FloatArray) -> None:
        """Closed-loop feedback of a velocity error [m/s] (N, E) and a psi angle [rad].

        Parameters
        ----------
        dv_n : ndarray, shape (2,)
            Estimated velocity error ``[dv_N, dv_E]`` (computed minus true), NED [m/s];
            subtracted from :attr:`v_n`.
        psi : ndarray, shape (3,)
            Estimated misalignment of the computed navigation frame, NED [rad]; the
            attitude becomes ``exp([psi x]) C_s_n``, undoing ``C^ = (I - [psi x]) C``.
        """
        self.v_n = np.array([self.v_n[0] - dv_n[0], self.v_n[1] - dv_n[1], 0.0])
        self.C_s_n = rotvec_to_dcm_3(psi) @ self.C_s_n


# ------------------------------------------------------------------ the block
_ZERO3 = (0.0, 0.0, 0.0)


class SinsStaticAlignment(Block):
    """Stationary SINS self north-finding: coarse alignment, 10-state KF, optional turntable."""

    variables = (
        parameter("lat", 45.0 * DEG, "rad", "latitude"),
        parameter("h", 0.0, "m", "height"),
        parameter("init_mode", 0, description="0: coarse alignment first; 1: truth + init_offset"),
        parameter("coarse_time", 5.0, "s", "coarse alignment window (init_mode 0)"),
        parameter(
            "init_offset",
            (DEG, DEG, DEG),
            "rad",
            "init_mode 1: initial attitude error, estimate minus truth (NED rotation vector)",
        ),
        parameter(
            "init_offset_random",
            False,
            description="init_mode 1: draw the offset per axis from N(0, init_offset^2)",
        ),
        parameter("kf_period", 0.1, "s", "zero-velocity update period (a multiple of the step)"),
        parameter("p0_vel", SEED003.p0_vel, "m/s", "P0: velocity error sigma"),
        parameter("p0_att", SEED003.p0_att, "rad", "P0: misalignment sigmas N, E, D"),
        parameter("p0_accel_bias", SEED003.p0_accel_bias, "m/s2", "P0: accelerometer bias sigma"),
        parameter("p0_gyro_drift", SEED003.p0_gyro_drift, "rad/s", "P0: gyro drift sigma"),
        parameter("q_accel", SEED003.q_accel, "m/s/sqrt(s)", "Q: accelerometer noise density"),
        parameter("q_gyro", SEED003.q_gyro, "rad/sqrt(s)", "Q: gyro noise density"),
        parameter("r_vel", SEED003.r_vel, "m/s", "R: zero-velocity measurement sigma"),
        parameter(
            "zupt_noise",
            0.0,
            "m/s",
            "sigma of white noise added to each zero-velocity measurement (base disturbance)",
        ),
        parameter("mount_rpy", _ZERO3, "rad", "sensor mounting on the table, C_s_t (as Turntable)"),
        parameter("seed", 0, description="random seed (offset draw, measurement noise)"),
        input_("dtheta_s", _ZERO3, "rad", "measured angle increment over the step, sensor axes"),
        input_("dv_s", _ZERO3, "m/s", "measured velocity increment over the step, sensor axes"),
        input_("rpy_true", _ZERO3, "rad", "truth: base attitude (for the error outputs)"),
        input_("angle", 0.0, "rad", "turntable encoder angle (0 without a table)"),
        output("phase", 0.0, "1", "0 coarse alignment, 1 fine alignment"),
        output("rpy", _ZERO3, "rad", "estimated base attitude: roll, pitch, yaw"),
        output("v_n", _ZERO3, "m/s", "estimated velocity, NED (v_D = 0)"),
        output(
            "phi_hat",
            _ZERO3,
            "arcmin",
            "estimated misalignment of the fine-start attitude (stationary base), NED",
        ),
        output("phi_err", _ZERO3, "arcmin", "attitude error, estimate minus truth, NED"),
        output("phi_sigma", _ZERO3, "arcmin", "1-sigma of phi_err from P"),
        output("rpy_err", _ZERO3, "arcmin", "roll, pitch, heading error, estimate minus truth"),
        output("rpy_sigma", _ZERO3, "arcmin", "1-sigma of rpy_err from P"),
        output("nees", 0.0, "1", "NEES of the three angles (chi-square, 3 dof)"),
        output("nis", 0.0, "1", "NIS of the last zero-velocity update (chi-square, 2 dof)"),
        output("accel_bias", (0.0, 0.0), "m/s2", "estimated accelerometer bias, table x, y"),
        output("gyro_drift", _ZERO3, "rad/s", "estimated gyro drift, table x, y, z"),
        output("accel_bias_sigma", (0.0, 0.0), "m/s2", "1-sigma of accel_bias"),
        output("gyro_drift_sigma", _ZERO3, "rad/s", "1-sigma of gyro_drift"),
    )
    default_step = 0.1
    default_stop = 300.0

    # ------------------------------------------------------------ set-up
    def tuning(self) -> FilterTuning:
        """The filter tuning given by the parameters."""
        return FilterTuning(
            p0_vel=float(self.p0_vel),
            p0_att=tuple(float(a) for a in self.p0_att),
            p0_accel_bias=float(self.p0_accel_bias),
            p0_gyro_drift=float(self.p0_gyro_drift),
            q_accel=float(self.q_accel),
            q_gyro=float(self.q_gyro),
            r_vel=float(self.r_vel),
        )

    def _check(self) -> None:
        if self.init_mode not in (0, 1):
            raise AlignmentConfigError(
                f"SinsStaticAlignment.init_mode must be 0 (coarse) or 1 (truth + offset), "
                f"got {self.init_mode}"
            )
        if self.init_mode == 0 and not self.coarse_time > 0.0:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.coarse_time must be > 0 s, got {self.coarse_time}"
            )
        if not self.kf_period > 0.0:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.kf_period must be > 0 s, got {self.kf_period}"
            )
        if not abs(self.lat) < 89.0 * DEG:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.lat must be within +-89 deg (heading is undefined at "
                f"the poles), got {self.lat / DEG:g} deg"
            )
        tun = self.tuning()
        sig = [tun.p0_vel, *tun.p0_att, tun.p0_accel_bias, tun.p0_gyro_drift, tun.r_vel]
        if not all(s > 0.0 for s in sig):
            raise AlignmentConfigError(
                "SinsStaticAlignment: p0_vel, p0_att, p0_accel_bias, p0_gyro_drift and r_vel "
                "must be > 0"
            )
        if tun.q_accel < 0.0 or tun.q_gyro < 0.0 or self.zupt_noise < 0.0:
            raise AlignmentConfigError(
                "SinsStaticAlignment: q_accel, q_gyro and zupt_noise must be >= 0"
            )

    def initialize(self) -> None:
        self._check()
        self._rng = np.random.default_rng(int(self.seed))
        z = self._rng.standard_normal(3)  # always drawn: the stream does not depend on options
        self._C_s_t = euler_to_dcm_3(self.mount_rpy)
        self._axis = self._C_s_t[2, :].copy()
        tun = self.tuning()
        self._tun = tun
        self._Gq = noise_input() @ tun.Qc() @ noise_input().T
        self._F = error_model(_I3, float(self.lat), float(self.h))
        self._kf = KalmanFilter(N_STATES, 2)
        self._kf.H = measurement_matrix()
        self._kf.R = tun.R()
        self._nav: Strapdown | None = None
        self._bias_a = np.zeros(2)
        self._bias_g = np.zeros(3)
        self._sum_dth = np.zeros(3)
        self._sum_dv = np.zeros(3)
        self._elapsed = 0.0
        self._angle0 = float(self.angle)
        self._k_upd: int | None = None
        self._n_fine = 0
        self._C0_b_n = _I3.copy()
        self.phase = 0.0
        if self.init_mode == 1:
            offset = np.asarray(self.init_offset, dtype=float)
            if self.init_offset_random:
                offset = offset * z
            c_s_n = self._sensor_dcm(euler_to_dcm_3(self.rpy_true))
            self._start_fine(rotvec_to_dcm_3(offset) @ c_s_n)
        self._publish()

    def _sensor_dcm(self, c_b_n: FloatArray) -> FloatArray:
        """``C_s_n`` from a base attitude and the current encoder angle."""
        return c_b_n @ table_dcm(float(self.angle)) @ self._C_s_t

    def _base_dcm(self) -> FloatArray:
        """Estimated ``C_b_n`` from the sensor attitude, the encoder angle and the mount."""
        assert self._nav is not None
        return self._nav.C_s_n @ self._C_s_t.T @ table_dcm(float(self.angle)).T

    def _start_fine(self, c_s_n: FloatArray) -> None:
        self._nav = Strapdown(c_s_n, float(self.lat), float(self.h), self._axis)
        self._kf.x = np.zeros(N_STATES)
        self._kf.P = self._tun.P0()
        self._C0_b_n = self._base_dcm()
        self._n_fine = 0
        self.phase = 1.0

    # ------------------------------------------------------------ stepping
    def step(self, t: float, h: float) -> None:
        dth = np.asarray(self.dtheta_s, dtype=float)
        dv = np.asarray(self.dv_s, dtype=float)
        if self._nav is None:
            self._coarse_step(dth, dv, h)
        else:
            self._fine_step(dth, dv, h)
        self._publish()

    def _coarse_step(self, dth: FloatArray, dv: FloatArray, h: float) -> None:
        if abs(float(self.angle) - self._angle0) > 1e-9:
            raise AlignmentError(
                "the turntable moved during coarse alignment; hold it (Turntable "
                "rotation_start >= coarse_time) or use init_mode = 1"
            )
        self._sum_dth += dth
        self._sum_dv += dv
        self._elapsed += h
        if self._elapsed >= float(self.coarse_time) - 1e-9 * max(1.0, float(self.coarse_time)):
            T = self._elapsed
            self._start_fine(
                coarse_alignment(
                    self._sum_dv / T, self._sum_dth / T, float(self.lat), float(self.h)
                )
            )

    def _fine_step(self, dth: FloatArray, dv: FloatArray, h: float) -> None:
        if self._k_upd is None:
            k = int(round(float(self.kf_period) / h))
            if k < 1 or abs(k * h - float(self.kf_period)) > 1e-9 * float(self.kf_period):
                raise AlignmentConfigError(
                    f"SinsStaticAlignment.kf_period = {self.kf_period} s must be a whole "
                    f"multiple of the block's step {h} s"
                )
            self._k_upd = k
        nav = self._nav
        assert nav is not None
        cst_t = self._C_s_t.T
        bias_a = np.array([self._bias_a[0], self._bias_a[1], 0.0])
        nav.step(dth - (cst_t @ self._bias_g) * h, dv - (cst_t @ bias_a) * h, h)
        F = self._F
        c_t_n = nav.C_mean @ cst_t
        F[0:2, 5:7] = c_t_n[0:2, 0:2]
        F[2:5, 7:10] = -c_t_n
        Phi, Qd = discretize_taylor(F, self._Gq, h)
        kf = self._kf
        kf.predict(F=Phi, Q=Qd)
        self._n_fine += 1
        if self._n_fine % self._k_upd == 0:
            noise = self._rng.standard_normal(2) * float(self.zupt_noise)
            kf.update(nav.v_n[0:2] + noise)
            x = kf.x
            nav.correct(x[0:2], x[2:5])
            self._bias_a += x[5:7]
            self._bias_g += x[7:10]
            kf.x = np.zeros(N_STATES)
            (y1, y2), ((s11, s12), (_, s22)) = kf.y.tolist(), kf.S.tolist()
            self.nis = (s22 * y1 * y1 - 2.0 * s12 * y1 * y2 + s11 * y2 * y2) / (
                s11 * s22 - s12 * s12
            )

    # ------------------------------------------------------------ outputs
    def _publish(self) -> None:
        if self._nav is None:
            return
        c_b_n = self._base_dcm()
        rpy_hat = dcm_euler(c_b_n)
        rpy_true = np.asarray(self.rpy_true, dtype=float)
        e = dcm_rotvec(c_b_n @ euler_to_dcm_3(rpy_true).T)
        P = self._kf.P
        p_att = P[2:5, 2:5]
        m = euler_error_jacobian(rpy_hat)
        sd = np.sqrt(np.diag(P))
        d = (rpy_hat - rpy_true).tolist()
        self.rpy = rpy_hat
        self.v_n = self._nav.v_n.copy()
        self.phi_hat = dcm_rotvec(self._C0_b_n @ c_b_n.T) / ARCMIN
        self.phi_err = e / ARCMIN
        self.phi_sigma = sd[2:5] / ARCMIN
        self.rpy_err = np.array([wrap(d[0]), d[1], wrap(d[2])]) / ARCMIN
        self.rpy_sigma = np.sqrt(np.diag(m @ p_att @ m.T)) / ARCMIN
        self.nees = quad_form_inv3(e, p_att)
        self.accel_bias = self._bias_a.copy()
        self.gyro_drift = self._bias_g.copy()
        self.accel_bias_sigma = sd[5:7]
        self.gyro_drift_sigma = sd[7:10]
