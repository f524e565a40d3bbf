"""The navigation core of the alignment filters: one strapdown integrator, small rotations.

Every alignment filter that mechanises an IMU runs :class:`Strapdown`; what differs
between filters is set by :class:`Mechanisation` (the increment algorithm, transport
rate, vertical channel, ...), not by another integrator. Frames (``models.conventions``):
``n`` NED, ``s`` the sensor axes (FRD); ``C_s_n`` the sensor-to-NED DCM.

Mechanisation (every step ``h`` of increments ``dtheta``, ``dv``)
-----------------------------------------------------------------
The increments are first corrected with the bias estimates (sensor axes),
``dth = dtheta - gyro_bias h``, ``dvb = dv - accel_bias h``. Then the rotation vector
``phi`` of the step and the velocity increment ``u`` in the sensor axes at the start of
the step, by one of two algorithms (``Mechanisation.coning``):

``"two-sample"`` (a moving base; the previous step's increments ``dth', dvb'``)::

    phi = dth + dth' x dth / 12
    u   = dvb + dth x dvb / 2 + dth x (dth x dvb) / 6 + (dth' x dvb + dvb' x dth) / 12

``"table-axis"`` (a stationary base, possibly on a table turning about ``a`` at a
constant rate; exact to first order in the earth rate)::

    phi = theta a + k (dth - theta a),   theta = a . dth,   k = (theta / 2)^2 / sin^2(theta / 2)
    u   = J(-phi)^-1 dvb                 (:func:`rotation_compensation`)

Then, with ``w_in = w_ie + w_en`` (the transport rate ``w_en`` only with
``transport_rate``, evaluated at ``v_ref``), ``zeta = w_in h``::

    C_s_n <- exp(-[zeta x]) C_s_n exp([phi x])
    dv_n   = (I - [zeta x] / 2) C_s_n u
    v_n   <- v_n + dv_n + (g_n - (2 w_ie + w_en) x v_ref) h          (vertical = True)
    v_N   <- v_N + dv_N + c_D h v_ref,E,   v_E <- v_E + dv_E - c_D h v_ref,N,   v_D = 0
                                          (vertical = False; c = 2 w_ie + w_en)
    L     <- L + v_ref,N h / (R_M + h)                               (transport_rate)

``v_ref`` is the mid-step velocity extrapolated from the last two steps,
``1.5 v_k - 0.5 v_(k-1)`` (``midpoint_velocity``), else the velocity at the start of
the step. The latitude-dependent constants (radii, earth rate, gravity) are evaluated
at construction and by :meth:`Strapdown.refresh` only (a filter refreshes them once
per filter period: the latitude moves by metres per period). With
``orthonormalise_every = k`` the attitude is re-orthonormalised every k-th step
(``C <- 1.5 C - 0.5 C C^T C``).

The two presets are the filters' own: :data:`STATIC_BASE` (seed 003's stationary
self-alignment: table-axis increments, earth rate only, level channel) and
:data:`MOVING_BASE` (seed 001's transfer alignment: two-sample increments, transport
rate, vertical channel, latitude integrated).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.models.constants import OMEGA_IE
from cosim.models.conventions import cross, rotvec_to_dcm_3
from cosim.models.earth import R_M, R_N, gravity

FloatArray = NDArray[np.float64]

_I3 = np.eye(3)
_EZ = np.array([0.0, 0.0, 1.0])


class AlignmentConfigError(ValueError):
    """A parameter of an alignment filter is invalid (the message says which and why)."""


class AlignmentError(RuntimeError):
    """The alignment cannot proceed with the inputs it receives (e.g. a moving table)."""


# ------------------------------------------------------------------ earth rates
def earth_rate(lat: float) -> FloatArray:
    """Earth rate in NED, ``[W cos L, 0, -W sin L]`` [rad/s], shape (3,) (scalar math).

    Parameters
    ----------
    lat : float
        Latitude ``L`` [rad].

    Returns
    -------
    ndarray, shape (3,)
        ``omega_ie_n`` [rad/s].
    """
    return np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])


def nav_rates(v_n: ArrayLike, lat: float, height: float) -> tuple[FloatArray, FloatArray]:
    """Earth rate and transport rate in NED [rad/s].

    Parameters
    ----------
    v_n : array_like, shape (3,)
        Velocity w.r.t. the earth, NED [m/s].
    lat : float
        Latitude [rad].
    height : float
        Height [m].

    Returns
    -------
    w_ie, w_en : ndarray, shape (3,)
        ``omega_ie_n`` and ``omega_en_n = [v_E / (R_N + h), -v_N / (R_M + h),
        -v_E tan L / (R_N + h)]`` [rad/s].
    """
    v = np.asarray(v_n, dtype=float)
    rn = float(R_N(lat)) + height
    rm = float(R_M(lat)) + height
    w_en = np.array([v[1] / rn, -v[0] / rm, -v[1] * math.tan(lat) / rn])
    return earth_rate(lat), w_en


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


def _norm2(v: ArrayLike) -> float:
    x, y, z = np.asarray(v, dtype=float).tolist()
    return x * x + y * y + z * z


def dcm_to_rotvec_3(c: ArrayLike) -> FloatArray:
    """Rotation vector (logarithm) of one DCM, angle below pi, with scalar math [rad].

    The one-matrix fast path beside :func:`models.conventions.dcm_to_rotvec`: the
    antisymmetric part ``w`` and ``phi = w atan2(|w|, (tr c - 1) / 2) / |w|``.

    Parameters
    ----------
    c : array_like, shape (3, 3)
        Orthonormal DCM ``exp([phi x])``; ``phi`` is resolved in the frame in which
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


def euler_rate_matrix(rpy: ArrayLike) -> FloatArray:
    """``A`` with ``exp([A d(rpy) x]) C(rpy) = C(rpy + d(rpy))`` to first order (left perturbation).

    For ``C = Rz(yaw) Ry(pitch) Rx(roll)`` the columns are the axes of the roll, pitch
    and yaw rotations resolved in the reference (left) frame: ``Rz Ry e_x``, ``Rz e_y``,
    ``e_z``.

    Parameters
    ----------
    rpy : array_like, shape (..., 3)
        ``[roll, pitch, yaw]`` [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    rpy = np.asarray(rpy, dtype=float)
    if rpy.shape == (3,):  # one set of angles: scalar math (np.cos, np.sin = math.cos, sin)
        _, p, y = rpy.tolist()
        cp, sp, cy, sy = math.cos(p), math.sin(p), math.cos(y), math.sin(y)
        return np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    a = np.zeros(rpy.shape[:-1] + (3, 3))
    a[..., 0, 0] = cy * cp
    a[..., 1, 0] = sy * cp
    a[..., 2, 0] = -sp
    a[..., 0, 1] = -sy
    a[..., 1, 1] = cy
    a[..., 2, 2] = 1.0
    return a


def euler_rate_matrix_inv(rpy: ArrayLike) -> FloatArray:
    """Inverse of :func:`euler_rate_matrix`: ``d rpy = M e`` for ``C -> exp([e x]) C``.

    ``M = [[cos y / cos p, sin y / cos p, 0], [-sin y, cos y, 0], [tan p cos y,
    tan p sin y, 1]]`` (closed form, scalar math).

    Parameters
    ----------
    rpy : array_like, shape (3,)
        ``[roll, pitch, yaw]`` [rad] (Z-Y-X); pitch away from +-90 deg.

    Returns
    -------
    ndarray, shape (3, 3)
        Maps a small rotation-vector error (reference frame) to Euler-angle errors.
    """
    _, p, y = np.asarray(rpy, dtype=float).tolist()
    cp, tp, cy, sy = math.cos(p), math.tan(p), math.cos(y), math.sin(y)
    return np.array([[cy / cp, sy / cp, 0.0], [-sy, cy, 0.0], [tp * cy, tp * sy, 1.0]])


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
        Rotation vector of the step, sensor axes [rad].
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


# ------------------------------------------------------------------ the integrator
@dataclass(frozen=True)
class Mechanisation:
    """What a filter's strapdown integrator does (see the module docstring).

    Attributes
    ----------
    coning : {"two-sample", "table-axis"}
        Increment algorithm: two-sample coning and sculling with the previous step, or
        the table-axis coning with the exact rotation compensation ``J(-phi)^-1``.
    transport_rate : bool
        Include ``w_en`` in the navigation-frame rotation and the Coriolis term, and
        integrate the latitude.
    vertical : bool
        Mechanise the vertical channel (gravity, 3-D Coriolis); False holds ``v_D = 0``.
    midpoint_velocity : bool
        Evaluate the rates and the Coriolis term at the extrapolated mid-step velocity.
    orthonormalise_every : int
        Re-orthonormalise the attitude every this many steps (0: never).
    """

    coning: Literal["two-sample", "table-axis"] = "two-sample"
    transport_rate: bool = True
    vertical: bool = True
    midpoint_velocity: bool = True
    orthonormalise_every: int = 0

    def __post_init__(self) -> None:
        if self.coning not in ("two-sample", "table-axis"):
            raise ValueError(
                f"Mechanisation.coning: expected 'two-sample' or 'table-axis', got {self.coning!r}"
            )
        if self.orthonormalise_every < 0:
            raise ValueError(
                "Mechanisation.orthonormalise_every: expected >= 0, got "
                f"{self.orthonormalise_every}"
            )


#: Seed 003's stationary base: table-axis increments, earth rate only, level channel.
STATIC_BASE = Mechanisation(
    coning="table-axis",
    transport_rate=False,
    vertical=False,
    midpoint_velocity=False,
    orthonormalise_every=64,
)
#: Seed 001's moving base: two-sample increments, transport rate, vertical channel.
MOVING_BASE = Mechanisation()


class Strapdown:
    """The strapdown integrator of every alignment filter (NED, sensor axes).

    Parameters
    ----------
    C_s_n : array_like, shape (3, 3)
        Initial attitude, sensor to NED.
    lat : float
        Initial latitude [rad] (held unless ``options.transport_rate``).
    height : float
        Height [m] (held: the vertical position is not mechanised).
    v_n : array_like, shape (3,), optional
        Initial velocity, NED [m/s] (default zero).
    options : Mechanisation
        What the integrator does (default :data:`MOVING_BASE`).
    table_axis : array_like, shape (3,), optional
        Unit table axis in sensor axes, for ``coning = "table-axis"`` (default ``e_z``).

    Attributes
    ----------
    C_s_n : ndarray, shape (3, 3)
        Attitude.
    v_n : ndarray, shape (3,)
        Velocity, NED [m/s].
    v_prev : ndarray, shape (3,)
        Velocity at the start of the last step [m/s].
    lat : float
        Latitude [rad].
    gyro_bias, accel_bias : ndarray, shape (3,)
        Gyro drift and accelerometer bias subtracted from the increments, sensor axes
        [rad/s, m/s2].
    C_prev : ndarray, shape (3, 3)
        Attitude at the start of the last step.
    phi : ndarray, shape (3,)
        Rotation vector of the last step, sensor axes [rad].
    dv_n : ndarray, shape (3,)
        Specific-force velocity increment of the last step, NED [m/s].
    w_in, cor : ndarray, shape (3,)
        ``w_ie + w_en`` and ``2 w_ie + w_en`` of the last step [rad/s].
    w_ie : ndarray, shape (3,)
        Earth rate at :attr:`lat` of the last :meth:`refresh` [rad/s].
    g : float
        Gravity at that latitude and :attr:`height` [m/s2].
    """

    def __init__(
        self,
        C_s_n: ArrayLike,
        lat: float,
        height: float = 0.0,
        v_n: ArrayLike | None = None,
        *,
        options: Mechanisation = MOVING_BASE,
        table_axis: ArrayLike | None = None,
    ) -> None:
        self.options = options
        self.C_s_n = np.array(C_s_n, dtype=float)
        self.v_n = np.zeros(3) if v_n is None else np.array(v_n, dtype=float)
        self.v_prev = self.v_n.copy()
        self.lat = float(lat)
        self.height = float(height)
        self.table_axis = _EZ.copy() if table_axis is None else np.asarray(table_axis, float)
        self.gyro_bias = np.zeros(3)
        self.accel_bias = np.zeros(3)
        self.C_prev = self.C_s_n.copy()
        self.phi = np.zeros(3)
        self.dv_n = np.zeros(3)
        self._prev: tuple[float, ...] | None = None  # last (dth, dvb), two-sample
        self._count = 0
        self.refresh()
        self.w_in = self.w_ie
        self.cor = self._cor_ie

    def refresh(self) -> None:
        """Re-evaluate the latitude-dependent constants (radii, earth rate, gravity)."""
        lat = self.lat
        self._rm = float(R_M(lat)) + self.height
        self._rn = float(R_N(lat)) + self.height
        self._tan = math.tan(lat)
        self.w_ie = earth_rate(lat)
        self._cor_ie = 2.0 * self.w_ie
        self.g = float(gravity(lat, self.height))
        self._g_n = np.array([0.0, 0.0, self.g])
        self._h_nav = -1.0
        self._nav_rot = _I3

    def step(self, dtheta: ArrayLike, dv: ArrayLike, h: float) -> None:
        """Advance by one step of measured increments.

        Parameters
        ----------
        dtheta : array_like, shape (3,)
            Angle increment over the step, sensor axes [rad].
        dv : array_like, shape (3,)
            Velocity increment (integral of specific force), sensor axes [m/s].
        h : float
            Step [s].
        """
        if self.options.coning == "two-sample":
            self._step_two_sample(dtheta, dv, h)
        else:
            self._step_table_axis(dtheta, dv, h)
        self._count += 1
        every = self.options.orthonormalise_every
        if every and self._count % every == 0:
            c = self.C_s_n
            self.C_s_n = 1.5 * c - 0.5 * (c @ c.T @ c)

    def _step_two_sample(self, dtheta: ArrayLike, dv: ArrayLike, h: float) -> None:
        """:meth:`step` with two-sample increments, in scalar arithmetic.

        The same operations, in the same order, as the array formulas of the module
        docstring (every elementwise result bit for bit); only the two attitude products
        stay numpy matrix products.
        """
        o = self.options
        t0, t1, t2 = np.asarray(dtheta, dtype=float).tolist()
        d0, d1, d2 = np.asarray(dv, dtype=float).tolist()
        b0, b1, b2 = self.gyro_bias.tolist()
        a0, a1, a2 = self.accel_bias.tolist()
        t0, t1, t2 = t0 - b0 * h, t1 - b1 * h, t2 - b2 * h
        d0, d1, d2 = d0 - a0 * h, d1 - a1 * h, d2 - a2 * h
        if self._prev is None:  # no previous increment: no coning/sculling terms this step
            self._prev = (t0, t1, t2, d0, d1, d2)
        p0, p1, p2, q0, q1, q2 = self._prev
        self._prev = (t0, t1, t2, d0, d1, d2)
        # phi = dth + dth' x dth / 12
        phi = (
            t0 + (p1 * t2 - p2 * t1) / 12.0,
            t1 + (p2 * t0 - p0 * t2) / 12.0,
            t2 + (p0 * t1 - p1 * t0) / 12.0,
        )
        # u = dvb + c1 / 2 + dth x c1 / 6 + (dth' x dvb + dvb' x dth) / 12,  c1 = dth x dvb
        c0_, c1_, c2_ = t1 * d2 - t2 * d1, t2 * d0 - t0 * d2, t0 * d1 - t1 * d0
        u = (
            d0
            + 0.5 * c0_
            + (t1 * c2_ - t2 * c1_) / 6.0
            + ((p1 * d2 - p2 * d1) + (q1 * t2 - q2 * t1)) / 12.0,
            d1
            + 0.5 * c1_
            + (t2 * c0_ - t0 * c2_) / 6.0
            + ((p2 * d0 - p0 * d2) + (q2 * t0 - q0 * t2)) / 12.0,
            d2
            + 0.5 * c2_
            + (t0 * c1_ - t1 * c0_) / 6.0
            + ((p0 * d1 - p1 * d0) + (q0 * t1 - q1 * t0)) / 12.0,
        )
        v = self.v_n
        v0, v1, v2 = v.tolist()
        if o.midpoint_velocity:
            w0, w1, w2 = self.v_prev.tolist()
            r0, r1, r2 = 1.5 * v0 - 0.5 * w0, 1.5 * v1 - 0.5 * w1, 1.5 * v2 - 0.5 * w2
        else:
            r0, r1, r2 = v0, v1, v2
        e0, e1, e2 = self.w_ie.tolist()
        k0, k1, k2 = self._cor_ie.tolist()
        if o.transport_rate:
            n0, n1, n2 = r1 / self._rn, -r0 / self._rm, -r1 * self._tan / self._rn
            e0, e1, e2 = e0 + n0, e1 + n1, e2 + n2
            k0, k1, k2 = k0 + n0, k1 + n1, k2 + n2
            z0, z1, z2 = e0 * h, e1 * h, e2 * h
            nav_rot = rotvec_to_dcm_3((-z0, -z1, -z2))
            w_in, cor = np.array([e0, e1, e2]), np.array([k0, k1, k2])
        else:
            w_in, cor = self.w_ie, self._cor_ie
            z0, z1, z2 = e0 * h, e1 * h, e2 * h
            nav_rot = self._rot_nav(np.array([z0, z1, z2]), h)
        c0 = self.C_s_n
        u0, u1, u2 = (c0 @ np.array(u)).tolist()
        # dv_n = cu - zeta x cu / 2
        f0 = u0 - 0.5 * (z1 * u2 - z2 * u1)
        f1 = u1 - 0.5 * (z2 * u0 - z0 * u2)
        f2 = u2 - 0.5 * (z0 * u1 - z1 * u0)
        if o.vertical:
            g = self.g
            v_new = np.array(
                [
                    v0 + f0 + (0.0 - (k1 * r2 - k2 * r1)) * h,
                    v1 + f1 + (0.0 - (k2 * r0 - k0 * r2)) * h,
                    v2 + f2 + (g - (k0 * r1 - k1 * r0)) * h,
                ]
            )
        else:
            k = k2 * h  # -(2 w_ie + w_en) x v, horizontal, v_D = 0: [c_D v_E, -c_D v_N]
            v_new = np.array([v0 + f0 + k * r1, v1 + f1 - k * r0, 0.0])
        if o.transport_rate:
            self.lat += r0 * h / self._rm
        self.C_prev, self.w_in, self.cor = c0, w_in, cor
        self.phi = np.array(phi)
        self.dv_n = np.array([f0, f1, f2])
        self.v_prev = v
        self.v_n = v_new
        self.C_s_n = nav_rot @ c0 @ rotvec_to_dcm_3(phi)

    def _step_table_axis(self, dtheta: ArrayLike, dv: ArrayLike, h: float) -> None:
        """:meth:`step` with table-axis increments (array arithmetic)."""
        o = self.options
        dth = np.asarray(dtheta, dtype=float) - self.gyro_bias * h
        dvb = np.asarray(dv, dtype=float) - self.accel_bias * h
        phi = table_axis_coning(dth, self.table_axis)
        u = rotation_compensation(phi) @ dvb
        v = self.v_n
        v_ref = 1.5 * v - 0.5 * self.v_prev if o.midpoint_velocity else v
        if o.transport_rate:
            w_en = np.array(
                [v_ref[1] / self._rn, -v_ref[0] / self._rm, -v_ref[1] * self._tan / self._rn]
            )
            w_in = self.w_ie + w_en
            cor = self._cor_ie + w_en
            zeta = w_in * h
            nav_rot = rotvec_to_dcm_3(-zeta)
        else:
            w_in, cor = self.w_ie, self._cor_ie
            zeta = w_in * h
            nav_rot = self._rot_nav(zeta, h)
        c0 = self.C_s_n
        cu = c0 @ u
        dv_n = cu - 0.5 * cross(zeta, cu)
        if o.vertical:
            v_new = v + dv_n + (self._g_n - cross(cor, v_ref)) * h
        else:
            v_n, v_e, _ = v.tolist()
            ref_n, ref_e, _ = v_ref.tolist()
            k = cor[2] * h  # -(2 w_ie + w_en) x v, horizontal, v_D = 0: [c_D v_E, -c_D v_N]
            v_new = np.array([v_n + dv_n[0] + k * ref_e, v_e + dv_n[1] - k * ref_n, 0.0])
        if o.transport_rate:
            self.lat += v_ref[0] * h / self._rm
        self.C_prev, self.phi, self.dv_n, self.w_in, self.cor = c0, phi, dv_n, w_in, cor
        self.v_prev = v
        self.v_n = v_new
        self.C_s_n = nav_rot @ c0 @ rotvec_to_dcm_3(phi)

    def _rot_nav(self, zeta: FloatArray, h: float) -> FloatArray:
        """``exp(-[zeta x])`` for a constant ``w_in`` (cached per step size)."""
        if h != self._h_nav:
            self._h_nav = h
            self._nav_rot = rotvec_to_dcm_3(-zeta)
        return self._nav_rot

    def mean_attitude(self) -> FloatArray:
        """``C_s_n`` averaged over the last step, ``C_prev J(phi)``, shape (3, 3).

        Returns
        -------
        ndarray, shape (3, 3)
            The mean attitude (the navigation frame's own turn over the step neglected).
        """
        return self.C_prev @ step_mean_dcm(self.phi)

    def correct(
        self,
        *,
        rotation: FloatArray | None = None,
        d_v: ArrayLike | None = None,
        d_lat: float = 0.0,
    ) -> None:
        """Closed-loop feedback of estimated errors (computed minus true).

        Parameters
        ----------
        rotation : ndarray, shape (3, 3), optional
            Correction DCM applied in the navigation frame, ``C_s_n <- rotation C_s_n``
            (the inverse of the estimated error rotation ``C^ C^T``).
        d_v : array_like, shape (3,), optional
            Velocity error, NED [m/s]: subtracted from :attr:`v_n` and :attr:`v_prev`.
        d_lat : float
            Latitude error [rad], subtracted from :attr:`lat`.
        """
        if d_v is not None:
            self.v_n = self.v_n - d_v
            self.v_prev = self.v_prev - d_v
        if rotation is not None:
            self.C_s_n = rotation @ self.C_s_n
        self.lat -= d_lat
