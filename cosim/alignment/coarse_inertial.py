"""Inertial-frame (sway-robust) coarse alignment and its first-order error theory.

On a swaying or jittering base the mean gyro output is dominated by the sway, not by
the earth rate, and the analytic alignment (:mod:`cosim.alignment.coarse`) fails. The
inertial-frame alignment (Gaiffe 2000; Savage, Strapdown Analytics 6.1; Wu and Pan
2013, "Optimization-based alignment", IEEE TAES 49(4)) splits the attitude into three
factors::

    C_b_n(t) = C_n0_n(t) C_b0_n0 C_b_b0(t)

* ``C_b_b0(t)``: the body's turn since the start, integrated from the gyros
  (``omega_ib_b``: the sway is measured, not averaged away);
* ``C_n0_n(t) = exp(-[w_ie t x])``: the earth's turn since the start (known);
* ``C_b0_n0``: the constant unknown, the body attitude at the start.

Specific force seen in both inertial frames, integrated to velocities::

    b(t) = int_0^t C_b_b0 f_b dtau        (measured: the increments turned into b0)
    r(t) = int_0^t C_n_n0 f_n dtau        (known: f_n = [0, 0, -g] turning with the earth)
         = t f + (1 - cos W t) / W [u x] f + (t - sin(W t) / W) [u x]^2 f,
           u = w_ie / W

satisfy ``b(t) = C_n0_b0 (r(t) + dv(t))`` where ``dv`` is the velocity the base gained
since the start (sway). The constant rotation is solved over the whole window as
Wahba's problem on every step's pair, with both sets centred (an unknown constant
velocity offset ``c`` -- the sway velocity at the start -- is eliminated exactly:
minimising ``sum |b_k - A r_k - c|^2`` over ``c`` leaves Wahba's problem on
``b_k - mean(b)``, ``r_k - mean(r)``)::

    B = sum_k (b_k - b_mean)(r_k - r_mean)^T = U S V^T,
    C_n0_b0 = U diag(1, 1, det U det V) V^T                  (SVD solution)

The sway enters only through ``dv(t)`` (centimetres per second, oscillating) against
a signal that grows like ``g t``; the earth's turn of the gravity vector,
``W g cos L t^2 / 2`` east, carries the heading.

First-order error theory
------------------------
With the estimate-minus-truth rotation ``e`` of ``C_b0_n0`` (``C^ = exp([e x]) C``, n0
axes) the loss linearises to least squares, ``e = M sum_k [r~_k x]^T dr_k`` with
``r~`` centred, ``M = (sum_k [r~_k x]^T [r~_k x])^-1`` and ``dr_k`` the error of
``b_k`` in n0 axes::

    dr(t) = int_0^t ( f_n0 x dth(tau) ... ) = int_0^t ( -[f_n0 x] dth + C_n_n0 (nabla + w_a) ) dtau
    dth(t) = int_0^t C_n_n0 (eps + w_g) dtau          (gyro error of C_b_b0, n0 axes)

(``nabla``, ``eps``: accelerometer and gyro biases in NED, constant on a stationary
base; ``w_a``, ``w_g``: white noise of densities ``q_accel``, ``q_gyro``). The attitude
error at the window's end ``T`` is ``phi_err = C_n0_n(T) (e + dth(T))``. Swapping the
sums (step ``j`` of ``h``, ``S_j = sum_{k > j} M [r~_k x]^T``,
``R_i = sum_{j > i} h S_j [f_j x]``)::

    phi_err = J_a nabla + J_g eps + sum_j h C_T^T S_j C_j w_a,j + sum_i h C_T^T (I - R_i) C_i w_g,i
    J_a = C_T^T sum_j h S_j C_j,      J_g = C_T^T sum_i h (I - R_i) C_i

so ``P_phi = J_a J_a^T s_a^2 + J_g J_g^T s_g^2 + h C_T^T (q_a^2 sum S S^T + q_g^2 sum
(I - R)(I - R)^T) C_T`` for isotropic turn-on sigmas ``s_a``, ``s_g``
(:func:`inertial_coarse_theory`). For a long window the bias part tends to the
one-position limits (``phi_D -> -eps_E / (W cos L)``, level ``nabla / g``); for a short
one the white noise dominates: ARW like ``N / (W cos L sqrt(T))`` (the angle random walk
tilts the east signal, as in the one-position case), VRW like ``T^-3/2`` (velocity noise
``q sqrt(T)`` against the heading signal ``W g cos L T^2 / 2``).

Where it stops working: at a pole (no heading signal: ``cos L -> 0``); when the
window is so short that the earth's turn ``W T`` is swamped (the theory's sigma says
so); when the base translates by more than its sway (a moving vehicle: the velocity
``dv`` is then not small against ``W g cos L T^2 / 2``); when the gyros cannot follow
the sway (saturation, or a step too long for the coning of large fast sway).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.nav import AlignmentError, earth_rate
from cosim.models.constants import OMEGA_IE
from cosim.models.conventions import rotvec_to_dcm_3, skew
from cosim.models.earth import gravity

FloatArray = NDArray[np.float64]

_I3 = np.eye(3)


def earth_turn(lat: float, t: ArrayLike) -> FloatArray:
    """``C_n_n0(t) = exp([w_ie t x])``: the NED frame at ``t`` in the NED frame at 0.

    Parameters
    ----------
    lat : float
        Latitude [rad].
    t : array_like, shape (m,)
        Times since the start [s].

    Returns
    -------
    ndarray, shape (m, 3, 3)
        ``C_n_n0`` at each time (a vector fixed in NED, expressed in n0).
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    u = earth_rate(lat) / OMEGA_IE
    K = skew(u)
    th = OMEGA_IE * t
    return _I3 + np.sin(th)[:, None, None] * K + (1.0 - np.cos(th))[:, None, None] * (K @ K)


def reference_velocity(lat: float, h: float, t: ArrayLike) -> FloatArray:
    """``r(t) = int_0^t C_n_n0 f_n dtau``: the specific force of a still base, integrated in n0.

    Parameters
    ----------
    lat, h : float
        Latitude [rad], height [m].
    t : array_like, shape (m,)
        Times since the start [s].

    Returns
    -------
    ndarray, shape (m, 3)
        ``r(t)`` [m/s], n0 (NED at the start) axes; closed form.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    f_n = np.array([0.0, 0.0, -float(gravity(lat, h))])
    K = skew(earth_rate(lat) / OMEGA_IE)
    th = OMEGA_IE * t
    a = (1.0 - np.cos(th)) / OMEGA_IE
    b = t - np.sin(th) / OMEGA_IE
    return t[:, None] * f_n + a[:, None] * (K @ f_n) + b[:, None] * (K @ K @ f_n)


def wahba_svd(B: ArrayLike) -> FloatArray:
    """The rotation ``A`` maximising ``tr(A^T B)`` (Wahba's problem, SVD solution).

    Parameters
    ----------
    B : array_like, shape (3, 3)
        Attitude profile matrix ``sum_k w_k b_k r_k^T``.

    Returns
    -------
    ndarray, shape (3, 3)
        Proper rotation ``A`` with ``b ~ A r``.
    """
    U, _, Vt = np.linalg.svd(np.asarray(B, dtype=float))
    d = np.linalg.det(U) * np.linalg.det(Vt)
    return U @ np.diag([1.0, 1.0, d]) @ Vt


class InertialCoarse:
    """Step-by-step accumulator of the inertial-frame coarse alignment.

    Parameters
    ----------
    lat, h : float
        Latitude [rad] (not at a pole), height [m].
    lever_b : array_like, shape (3,), optional
        Position of the IMU from the sway centre (the point at rest), sensor axes [m]:
        its velocity ``C_b_b0 (w x l) = d(C_b_b0 l)/dt`` is taken out of each vector,
        exactly as the step mean ``(C_k - C_k-1) l / h`` (the pairs are then the step
        means of ``b`` and ``r``, the trapezoid of their ends).

    Attributes
    ----------
    C_b_b0 : ndarray, shape (3, 3)
        Body turn since the start, integrated from the gyros (sensor axes).
    elapsed : float
        Time since the start [s].
    n : int
        Vector pairs accumulated (one per step).
    """

    def __init__(self, lat: float, h: float = 0.0, lever_b: ArrayLike | None = None) -> None:
        self.lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
        self.lat = float(lat)
        self.h = float(h)
        self.C_b_b0 = _I3.copy()
        self.elapsed = 0.0
        self.n = 0
        self._b = np.zeros(3)
        self._sum_b = np.zeros(3)
        self._sum_r = np.zeros(3)
        self._sum_br = np.zeros((3, 3))
        self._prev_dth = np.zeros(3)
        self._prev_dv = np.zeros(3)
        self._b_prev = np.zeros(3)
        self._r_prev = np.zeros(3)

    def step(self, dtheta_b: ArrayLike, dv_b: ArrayLike, dt: float) -> None:
        """Add one step of measured increments.

        Parameters
        ----------
        dtheta_b : array_like, shape (3,)
            Angle increment over the step (w.r.t. inertial space), sensor axes [rad].
        dv_b : array_like, shape (3,)
            Velocity increment (specific force integral), sensor axes [m/s].
        dt : float
            Step [s].
        """
        # copies: the previous step's increments are kept, and a caller may pass views of
        # input buffers that the next step overwrites in place (that would zero the coning
        # and sculling terms)
        dth = np.array(dtheta_b, dtype=float)
        dv = np.array(dv_b, dtype=float)
        # rotation compensation and two-sample sculling / coning (previous step's increments)
        scul = (np.cross(self._prev_dth, dv) + np.cross(self._prev_dv, dth)) / 12.0
        self._b = self._b + self.C_b_b0 @ (dv + 0.5 * np.cross(dth, dv) + scul)
        phi = dth + np.cross(self._prev_dth, dth) / 12.0
        self._prev_dth, self._prev_dv = dth, dv
        C_prev = self.C_b_b0
        self.C_b_b0 = self.C_b_b0 @ rotvec_to_dcm_3(phi)
        self.elapsed += float(dt)
        self.n += 1
        r = reference_velocity(self.lat, self.h, [self.elapsed])[0]
        b = self._b
        if np.any(self.lever_b):
            # step means: the IMU's velocity about the point at rest, d(C_b_b0 l)/dt, has
            # the exact mean (C_k - C_k-1) l / h over the step; b and r by the trapezoid
            b_mean = 0.5 * (self._b_prev + b) - (self.C_b_b0 - C_prev) @ self.lever_b / float(dt)
            r_mean = 0.5 * (self._r_prev + r)
            self._b_prev, self._r_prev = b, r
            b, r = b_mean, r_mean
        self._sum_b += b
        self._sum_r += r
        self._sum_br += np.outer(b, r)

    def attitude(self) -> FloatArray:
        """``C_b_n`` at the current time from every pair so far.

        Returns
        -------
        ndarray, shape (3, 3)
            Sensor to NED.

        Raises
        ------
        AlignmentError
            With fewer than three pairs, or when the vectors span no plane (no IMU data).
        """
        if self.n < 3:
            raise AlignmentError("inertial coarse alignment needs at least three steps")
        B = self._sum_br - np.outer(self._sum_b, self._sum_r) / self.n
        s = np.linalg.svd(B, compute_uv=False)
        if not s[1] > 1e-12 * max(s[0], 1e-300):
            raise AlignmentError(
                "inertial coarse alignment: the specific force does not turn in inertial "
                "space (zero IMU data, or at a pole); cannot find the heading"
            )
        C_n0_b0 = wahba_svd(B)
        C_n_n0 = earth_turn(self.lat, [self.elapsed])[0]
        return C_n_n0.T @ C_n0_b0.T @ self.C_b_b0


@dataclass(frozen=True)
class InertialCoarseTheory:
    """First-order error of :class:`InertialCoarse` at the window's end.

    Attributes
    ----------
    T : float
        Window [s].
    P_phi : ndarray, shape (3, 3)
        Covariance of ``phi_err`` (estimate minus truth), NED at ``T`` [rad^2].
    J_accel : ndarray, shape (3, 3)
        ``d phi_err / d nabla_n`` (accelerometer bias in NED) [rad / (m/s2)].
    J_gyro : ndarray, shape (3, 3)
        ``d phi_err / d eps_n`` (gyro bias in NED) [rad / (rad/s)].
    """

    T: float
    P_phi: FloatArray
    J_accel: FloatArray
    J_gyro: FloatArray

    @property
    def sigma(self) -> FloatArray:
        """1-sigma of ``phi_err`` N, E, D [rad], shape (3,)."""
        return np.sqrt(np.diag(self.P_phi))


def inertial_coarse_theory(
    T: float,
    lat: float,
    h: float = 0.0,
    *,
    dt: float = 0.1,
    q_accel: float = 0.0,
    q_gyro: float = 0.0,
    sigma_accel_bias: float = 0.0,
    sigma_gyro_bias: float = 0.0,
) -> InertialCoarseTheory:
    """First-order error of the inertial-frame coarse alignment over ``[0, T]``.

    Evaluates the module's equations on the steps of ``dt`` (one vector pair per step,
    as :class:`InertialCoarse` uses them); the base's sway is not in it (its effect is
    second order, see the module docstring).

    Parameters
    ----------
    T : float
        Window [s] (at least three steps).
    lat, h : float
        Latitude [rad], height [m].
    dt : float
        Step [s].
    q_accel : float
        Accelerometer white-noise density (VRW) [m/s/sqrt(s)].
    q_gyro : float
        Gyro white-noise density (ARW) [rad/sqrt(s)].
    sigma_accel_bias : float
        Accelerometer turn-on bias sigma per axis [m/s2].
    sigma_gyro_bias : float
        Gyro turn-on bias sigma per axis [rad/s].

    Returns
    -------
    InertialCoarseTheory

    Raises
    ------
    AlignmentError
        When ``T`` is shorter than three steps.
    """
    n = int(round(T / dt))
    if n < 3:
        raise AlignmentError(f"inertial coarse theory: T = {T} s is under three steps of {dt} s")
    tk = dt * np.arange(1, n + 1)
    r = reference_velocity(lat, h, tk)
    rc = r - r.mean(axis=0)
    Kr = np.stack([skew(v) for v in rc])  # [r~_k x], (n, 3, 3)
    Kt = np.transpose(Kr, (0, 2, 1))
    M = np.linalg.inv(np.einsum("kij,kjl->il", Kt, Kr))
    L = M @ Kt  # (n, 3, 3): L_k = M [r~_k x]^T
    # S_j = sum_{k > j} L_k for steps j = 0..n-1 (sample k = j + 1 .. n follows step j)
    S = np.cumsum(L[::-1], axis=0)[::-1]
    tm = dt * (np.arange(n) + 0.5)  # mid-step times
    C = earth_turn(lat, tm)
    f_n = np.array([0.0, 0.0, -float(gravity(lat, h))])
    Kf = np.stack([skew(c @ f_n) for c in C])
    SKf = dt * (S @ Kf)  # h S_j [f_j x]
    tail = np.cumsum(SKf[::-1], axis=0)[::-1]  # sum_{j >= i}
    R = tail - 0.5 * SKf  # j > i, plus half of step i (error at mid-step)
    C_T = earth_turn(lat, [n * dt])[0]
    IR = _I3 - R
    J_a = C_T.T @ (dt * np.einsum("jab,jbc->ac", S, C))
    J_g = C_T.T @ (dt * np.einsum("jab,jbc->ac", IR, C))
    P = (sigma_accel_bias**2) * (J_a @ J_a.T) + (sigma_gyro_bias**2) * (J_g @ J_g.T)
    P = P + dt * (q_accel**2) * (C_T.T @ np.einsum("jab,jcb->ac", S, S) @ C_T)
    P = P + dt * (q_gyro**2) * (C_T.T @ np.einsum("jab,jcb->ac", IR, IR) @ C_T)
    return InertialCoarseTheory(float(n * dt), 0.5 * (P + P.T), J_a, J_g)


def heading_sigma_inertial(
    T: float,
    lat: float,
    *,
    arw: float,
    gyro_bias: float,
    vrw: float = 0.0,
    accel_bias: float = 0.0,
    dt: float = 0.1,
) -> float:
    """1-sigma heading error [rad] of the inertial-frame coarse alignment after ``T``.

    Parameters
    ----------
    T : float
        Window [s].
    lat : float
        Latitude [rad].
    arw : float
        Gyro angle random walk [rad/sqrt(s)].
    gyro_bias : float
        Gyro turn-on bias sigma per axis [rad/s].
    vrw : float
        Accelerometer velocity random walk [m/s/sqrt(s)].
    accel_bias : float
        Accelerometer turn-on bias sigma per axis [m/s2].
    dt : float
        Step [s].

    Returns
    -------
    float
        ``sqrt(P_phi[D, D])`` [rad] (the heading error on a level base).
    """
    th = inertial_coarse_theory(
        T,
        lat,
        dt=dt,
        q_accel=vrw,
        q_gyro=arw,
        sigma_accel_bias=accel_bias,
        sigma_gyro_bias=gyro_bias,
    )
    return float(math.sqrt(th.P_phi[2, 2]))
