"""Shipboard transfer alignment (seed 001): slave strapdown, 19-state nonlinear model, scaled UKF.

The block :class:`TransferAlignment` aligns a slave strapdown IMU on a ship's deck to
the ship's master INS by **velocity matching**: it runs its own strapdown mechanisation
from the slave's angle and velocity increments (every increment it receives), starts it
with the master's attitude (so the slave's initial attitude error is the unknown mounting,
seed 001: roll 1 deg, pitch 1 deg, heading 30 deg, plus the deck flexure), and corrects it
with a scaled unscented Kalman filter whose process model is the nonlinear error model of
seed 001, eq. (12)-(30), rewritten in our frames (NED, FRD) below.

Frames and symbols (:mod:`models.conventions`)
----------------------------------------------
``n`` true NED frame at the master, ``n^`` the slave's computed NED frame, ``b`` master
body (FRD), ``s`` slave body (FRD). ``C_s_n`` true slave attitude, ``C^_s_n`` the slave
mechanisation's attitude, ``C_b_n`` master attitude (from the master INS). ``r_0`` the
nominal lever arm from master to slave in master axes, ``theta`` the deck flexure angle
(master axes, :mod:`models.deck_flexure`), ``R_0`` seed 001's lever-arm matrix
(:func:`models.lever_arm.r0_matrix`), ``Omega`` earth rate, ``L`` latitude.

Seed 001 works in ENU with a right-forward-up body; its heading is counter-clockwise.
Every equation below is written directly in NED/FRD (``T = [[0,1,0],[1,0,0],[0,0,-1]]``
maps one into the other, :data:`models.conventions.T_NED_ENU`); where the paper's sign
conventions differ (its ``psi`` is true-minus-computed, ours is computed-minus-true) it
says so.

State (19; 13 with ``flexure_states = 0``, the paper's "flexure ignored" case)
-----------------------------------------------------------------------------
``x = [dL, dV (3), phi (3), theta (3), theta' (3), nabla (3), eps (3)]``:

* ``dL = L^ - L_s`` relative latitude error of the slave mechanisation [rad] (eq. 12);
* ``dV = v^ - v_m - v_lr`` the **velocity difference** slave minus master with the rigid
  lever-arm velocity ``v_lr = C_b_n (omega_eb_b x r_0)`` removed [m/s, NED]: exactly the
  quantity measured (eq. 15-23 with the rigid lever arm compensated);
* ``phi = [phi_N, phi_E, phi_D]`` the attitude error, **large heading**: the error rotation
  ``E = C^_s_n C_s_n^T`` (true -> computed navigation frame, ``C_n^n^`` of eq. 26) is
  parametrised by its Z-Y-X Euler angles, ``E = Rz(phi_D) Ry(phi_E) Rx(phi_N)``. ``phi_D``
  is the heading error (any size, kept on the circle by the UKF's angle-aware mean and
  residual); ``phi_N, phi_E`` are the level errors (small after the first updates, never
  linearised). Estimate minus truth: the paper's ``psi`` is ``-phi`` for small angles;
* ``theta, theta'`` deck flexure angle and rate (master axes, eq. 1);
* ``nabla, eps`` residual accelerometer bias and gyro drift, slave axes (random constants).

Error model (continuous time, exact in ``E``)
---------------------------------------------
The mechanisation (below) integrates ``C^' = C^ [w~_is x] - [w^_in x] C^`` and
``v^' = C^ f~ - (2 w^_ie + w^_en) x v^ + g`` with the measured (bias-compensated) rate
``w~ = w_is + eps`` and specific force ``f~ = f_s + nabla``, where ``w_is`` and ``f_s``
are the slave's **true** rate and specific force: they include the flexure rate and the
lever-arm accelerations, which the slave's sensors measure. Differentiating ``E``::

    E' = [w x] E,   w = C^ eps + (E - I) w^_in - E dw_in                     (eq. 26-29)
    dw_in = w^_in - w_in = dw_ie + dw_en,
    dw_ie = Omega [cos L^ - cos L, 0, -(sin L^ - sin L)],   L = L^ - dL     (eq. 18-19)
    dw_en = [dv_E / R_N, -dv_N / R_M, -dv_E tan L^ / R_N - v^_E dL / (R_N cos^2 L^)]  (eq. 21)

This is eq. (28) with our sign: the paper's ``omega_nn^ = (I - C_n^n^) w_in + dw_in -
eps - w_fs``. There is **no flexure-rate term** here: ``E`` compares the computed attitude
with the true, flexed slave attitude, and the flexure rate ``w_fs`` is part of the true
rate the slave gyros measure and the mechanisation integrates. (The paper measures ``psi``
against the rigidly mounted slave, which moves ``theta`` from the measurement into
``psi' = ... - w_fs``; the two are the same model under the time-varying change of
variables ``psi_rigid = phi + C_b_n theta``.) The slave velocity error
``dv = v^ - v_s`` (``v_s`` true slave velocity) obeys, exactly in ``E``::

    dv' = (I - E^T) C^ f~ + E^T C^ nabla - (2 w_ie + w_en) x dv - (2 dw_ie + dw_en) x v^   (eq. 23)

(``g^ - g ~ 0``, eq. 22). The true slave velocity is ``v_s = v_m + C_b_n (omega_eb_b x r_p
+ r_p')`` with ``r_p = r_0 + R_0 theta``, ``r_p' = R_0 theta'`` (eq. 10), hence::

    dV = dv + M(t) [theta; theta'],      M(t) = C_b_n [ [omega_eb_b x] R_0,  R_0 ]    (3 x 6)

and ``d/dt (M xi)`` is exactly the flexure part of eq. (11)/(30):
``C_b_n {(([w x]^2 + [w' x]) R_0 - R_2) theta + (2 [w x] R_0 - R_1) theta' + R_0 eta}``.
Flexure: ``theta'' = -2 beta theta' - beta^2 theta + eta`` per axis (eq. 1; eq. 30 prints
``beta^2 theta^2``, a typo), ``beta = 2.146 / tau``, ``E[eta eta] = 4 beta^3 sigma^2``.
``dL' = dv_N / (R_M + h)`` (eq. 12). ``nabla' = eps' = 0``.

Discrete process model over one filter period ``T`` (the UKF's ``fx``)
----------------------------------------------------------------------
Over ``[t, t + T]`` the mechanisation accumulates, from every IMU increment,
``S_f = int C^ f~ dt``, ``S_C = int C^ dt``, ``S_v = int v^ dt``, ``S_w = int w^_in dt``,
``S_c = int (2 w^_ie + w^_en) dt``. The error states vary slowly compared with the ship's
motion, so with ``E0 = E(t)``::

    E1  = exp([(S_C eps + (E0 - I) S_w - E0 dw_in T) x]) E0,     phi1 = euler(E1)
    dv1 = dv0 + (I - Eb^T) S_f + Eb^T S_C nabla - S_c x dv0 - (2 dw_ie + dw_en) x S_v
    xi1 = Phi_flex xi0,   dV1 = dv1 + M(t + T) xi1,   dv0 = dV0 - M(t) xi0
    dL1 = dL0 + (dv0_N + dv1_N) T / (2 (R_M + h))

with ``Eb = (E0 + E1) / 2``. The large-heading nonlinearity is in ``(I - Eb^T) S_f`` (a
heading error rotates the slave's lever-arm acceleration), in ``Eb^T S_C nabla`` and in
``(E0 - I) S_w`` (a heading error tilts the computed frame at ``Omega cos L sin(phi_D)``,
about 1.1 arcmin/s for 30 deg at 30 deg N). Process noise (additive): accelerometer white
noise ``q_accel^2 T`` on ``dV``, gyro white noise ``q_gyro^2 T`` on ``phi``, the exact flexure
noise ``Q_flex`` (Van Loan) on ``xi`` and, through ``M(t + T)``, on ``dV``.

Measurement (velocity matching with lever-arm compensation, every ``T``)::

    z = v^ - v_master - C_b_n (omega_eb_b x r_0) = dV + v_noise

``omega_eb_b = omega_nb_b + C_n_b omega_en_n`` comes from the master's attitude: a
five-point backward difference of ``rotvec(C_b_n(t_k)^T C_b_n(t_k - j h))`` (``j = 0..4``),
exact for attitudes quartic in time (error ``h^4 |omega^(5)| / 5``, about 1e-8 rad/s at
``h = 20 ms`` for seed 001's motion; no master rate output is needed). ``h(x) = dV`` is
linear; the UKF is still used for it (same code path, exact for linear ``h``).

Filter: two stages, both scaled UKFs (Merwe sigma points ``ukf_alpha``, ``ukf_beta``,
``ukf_kappa``; heading-aware mean and residual, :func:`cosim.estimation.angle_mean_fn`
and :func:`~cosim.estimation.angle_residual_fn` on ``phi_D``). Seed 001 augments the state
with the noises; with additive noise the augmented and the plain UKF give the same first
two moments, so we do not augment.

* **Stage 1, acquisition** (``stage = 1``): a Gaussian-sum bank of ``acquire_hypotheses``
  UKFs (:class:`cosim.estimation.UnscentedParticleFilter` with ``proposal="mean"``: each
  particle is a UKF, weighted by its innovations' likelihood), whose prior headings are
  spread evenly over the circle with sigma ``p0_heading`` each (6 x 30 deg by default), so
  any initial heading error, up to 180 deg, is within about one sigma of a hypothesis.
  The mechanisation runs open loop (the model is exact for large errors). One UKF with a
  60 deg prior and a 30 deg error converged, but its Gaussian posterior became
  overconfident within the first seconds (a level error of 1 deg is then "explained" by a
  heading swing of 15-25 deg) and from 90 deg on it locked onto wrong headings.
* The acquisition ends (at ``acquire_min_time`` at the earliest) when the hypotheses on
  the best heading hold ``acquire_weight`` of the weight and that hypothesis' heading
  sigma is below ``acquire_sigma``. Its estimate is fed back; its accelerometer bias,
  gyro drift and flexure estimates are discarded (back to their priors, uncorrelated)
  and ``relevel_sigma^2`` is added to the level variances: in the large-error transient
  the Gaussian approximation leaves wrong, overconfident values in the weakly observable
  direction "level tilt vs bias / g", which no later data would correct (a noise-free
  run kept a 1.4 arcmin level error and a 1000 ug bias estimate without this restart).
* **Stage 2, fine alignment** (``stage = 2``): one UKF with the same model, closed loop.
  After each update the estimate is fed back, ``C^ <- E(phi^)^T C^``,
  ``v^ <- v^ - (dV^ - M xi^)``, ``L^ <- L^ - dL^``, ``nabla^ += nabla_x``,
  ``eps^ += eps_x``, and those states are reset to zero; the covariance is carried
  through the reset with its Jacobian (``phi_new = A(phi^) dphi``, the Euler-rate matrix
  of ``phi^``; identity for everything else). The flexure states are not fed back (they
  are not mechanisation errors).

Mechanisation (slave axes, every IMU increment ``dtheta, dv`` over ``h``)
----------------------------------------------------------------------------
Two-sample coning and sculling with the previous increment::

    a = dtheta + dtheta_prev x dtheta / 12
    u = dv + dtheta x dv / 2 + dtheta x (dtheta x dv) / 6
          + (dtheta_prev x dv + dv_prev x dtheta) / 12
    C^ <- exp(-[zeta x]) C^ exp([a x]),   zeta = w^_in h
    v^ <- v^ + (I - [zeta x] / 2) C^ u + (g(L^, h_m) - (2 w^_ie + w^_en) x v^_mid) h
    L^ <- L^ + v^_N,mid h / (R_M + h_m)

``v^_mid`` extrapolated from the last two velocities; the height is the master's (the
vertical position is not mechanised, so there is no height state, as in the paper).

Outputs ("alignment accuracy")
------------------------------
What is compared: the slave's estimated attitude ``C^_s_n`` against its true attitude
``C_s_n`` (from :class:`models.lever_arm.LeverArm`'s ``rpy_s``), both referred to the
master's true attitude, i.e. the **relative attitude** (misalignment) of the slave in
master axes, ``C_s_b = C_b_n^T C_s_n``, which is the mounting plus the current flexure
(seed 001's "true misalignment" of Table 1: 1.055706 deg, 1.015315 deg, 29.98939 deg).
``rpy_err = euler(C_b_n^T C^_s_n) - euler(C_b_n^T C_s_n)`` [arcmin], Z-Y-X angles of the
relative attitude: roll, pitch, heading of the slave relative to the master. Its 1-sigma
``rpy_sigma`` maps ``P_phi`` through ``C_n_b`` and the inverse Euler-rate matrix of the
relative attitude. The rigid mounting estimate is the relative attitude minus the flexure
estimate ``flex`` (master axes, with its own sigma). In stage 1 the outputs are those of
the most probable hypothesis (``nis`` too: its own UKF's innovation). Also: ``rel_rpy``
(the estimated relative attitude, from the master's reported attitude), bias and drift
estimates with their sigmas, ``nees`` (attitude error against ``P``, 3 degrees of
freedom), ``nis`` (0 before the first update) and ``stage``.

Limits: the block must step every macro step (rate 1) with a constant step that divides
``period``: its strapdown needs every increment; it starts once it has five master
attitudes (for the rate), i.e. four steps after the start. Without a lever arm the
heading is observable only by gyrocompassing (tens of minutes), which the acquisition
stage is not designed for (README, seed 001).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.estimation import (
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
    UnscentedParticleFilter,
    angle_mean_fn,
    angle_residual_fn,
    van_loan,
)
from models.block import Block, input_, output, parameter
from models.constants import OMEGA_IE
from models.conventions import (
    dcm_to_euler,
    dcm_to_rotvec,
    euler_to_dcm,
    rotvec_to_dcm,
    rotvec_to_dcm_3,
    skew,
)
from models.earth import R_M, R_N, euler_motion_truth, gravity
from models.lever_arm import r0_matrix

FloatArray = NDArray[np.float64]

DEG = math.pi / 180.0  #: 1 deg [rad]
ARCMIN = DEG / 60.0  #: 1 arcmin [rad]
DEG_PER_HOUR = DEG / 3600.0  #: 1 deg/h [rad/s]
G0 = 9.80665  #: standard gravity [m/s2] (the papers' "g" in sensor figures)
MICRO_G = 1e-6 * G0  #: 1 ug [m/s2]
#: Seed 001's flexure damping rule ``beta = BETA_TAU / tau`` (shared/SEEDS.md).
BETA_TAU = 2.146

_I3 = np.eye(3)
_ZERO3 = (0.0, 0.0, 0.0)

#: State names of the 19-state model, in order.
STATES_19 = (
    "dL",
    "dV_N",
    "dV_E",
    "dV_D",
    "phi_N",
    "phi_E",
    "phi_D",
    "theta_x",
    "theta_y",
    "theta_z",
    "theta_dot_x",
    "theta_dot_y",
    "theta_dot_z",
    "nabla_x",
    "nabla_y",
    "nabla_z",
    "eps_x",
    "eps_y",
    "eps_z",
)


class TransferConfigError(ValueError):
    """A parameter of the transfer-alignment block is invalid (the message says which)."""


class TransferRuntimeError(RuntimeError):
    """The block received inputs it cannot use (e.g. a step that does not divide the period)."""


# ----------------------------------------------------------------------------- layout
@dataclass(frozen=True)
class StateLayout:
    """Index layout of the 19-state (``flexure=True``) or 13-state model.

    Attributes
    ----------
    flexure : bool
        Whether the flexure states ``theta, theta'`` are in the state.
    """

    flexure: bool = True

    @property
    def n(self) -> int:
        """State dimension (19 or 13)."""
        return 19 if self.flexure else 13

    #: Index of ``dL``.
    dl: ClassVar[int] = 0
    #: The velocity difference ``dV``.
    dv: ClassVar[slice] = slice(1, 4)
    #: The attitude error ``phi``.
    att: ClassVar[slice] = slice(4, 7)
    #: Index of the heading error ``phi_D``.
    heading: ClassVar[int] = 6

    @property
    def xi(self) -> slice:
        """``[theta, theta']`` (only with flexure)."""
        return slice(7, 13)

    @property
    def nabla(self) -> slice:
        """Accelerometer bias."""
        return slice(13, 16) if self.flexure else slice(7, 10)

    @property
    def eps(self) -> slice:
        """Gyro drift."""
        return slice(16, 19) if self.flexure else slice(10, 13)

    @property
    def names(self) -> tuple[str, ...]:
        """State names in order."""
        if self.flexure:
            return STATES_19
        return STATES_19[:7] + STATES_19[13:]


# ----------------------------------------------------------------------------- tuning
@dataclass(frozen=True)
class TransferTuning:
    """Filter statistics: initial covariance, noises, flexure model (SI units).

    Defaults are seed 001's conditions (sec. 5) read as in ``scenarios/transfer_alignment.toml``.

    Attributes
    ----------
    p0_pos : float
        Initial north/east position error behind ``dL`` [m] (the slave starts at the
        master's latitude: the lever arm).
    p0_vel : float
        Initial velocity-difference sigma beyond the flexure part [m/s].
    p0_level : float
        Initial level error sigma [rad].
    p0_heading : float
        Initial heading error sigma [rad].
    p0_accel_bias : float
        Accelerometer bias sigma [m/s2] (seed 001: 3e-4 g).
    p0_gyro_drift : float
        Gyro drift sigma [rad/s] (seed 001: 0.01 deg/h).
    q_accel : float
        Accelerometer white-noise density [m/s/sqrt(s)] (seed 001's random 5e-5 g per second).
    q_gyro : float
        Gyro white-noise density [rad/sqrt(s)] (random 0.001 deg/h per second).
    r_vel : float
        Velocity-matching noise per update [m/s].
    flex_tau : tuple of float
        Flexure correlation times [s] (600 s).
    flex_sigma : tuple of float
        Flexure stationary sigmas [rad] (2 arcmin, shared/SEEDS.md's assumption).
    """

    p0_pos: float = 15.0
    p0_vel: float = 0.01
    p0_level: float = 1.0 * DEG
    p0_heading: float = 30.0 * DEG
    p0_accel_bias: float = 3e-4 * G0
    p0_gyro_drift: float = 0.01 * DEG_PER_HOUR
    q_accel: float = 5e-5 * G0
    q_gyro: float = 0.001 * DEG_PER_HOUR
    r_vel: float = 0.01
    flex_tau: tuple[float, float, float] = (600.0, 600.0, 600.0)
    flex_sigma: tuple[float, float, float] = (2.0 * ARCMIN,) * 3

    @property
    def beta(self) -> FloatArray:
        """Flexure damping ``beta = 2.146 / tau`` per axis [1/s]."""
        return BETA_TAU / np.asarray(self.flex_tau, dtype=float)

    def flexure_model(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Continuous flexure model of ``xi = [theta (3), theta' (3)]``.

        Returns
        -------
        F : ndarray, shape (6, 6)
            ``xi' = F xi + G eta``.
        G : ndarray, shape (6, 3)
        Qc : ndarray, shape (3, 3)
            PSD of ``eta``, ``diag(4 beta^3 sigma^2)`` [rad^2/s^3].
        """
        beta = self.beta
        F = np.zeros((6, 6))
        F[0:3, 3:6] = _I3
        F[3:6, 0:3] = -np.diag(beta**2)
        F[3:6, 3:6] = -np.diag(2.0 * beta)
        G = np.vstack([np.zeros((3, 3)), _I3])
        Qc = np.diag(4.0 * beta**3 * np.asarray(self.flex_sigma, dtype=float) ** 2)
        return F, G, Qc

    def flexure_p0(self) -> FloatArray:
        """Stationary covariance of ``xi``: ``diag(sigma^2, (beta sigma)^2)``, shape (6, 6)."""
        sig = np.asarray(self.flex_sigma, dtype=float)
        return np.diag(np.concatenate([sig**2, (self.beta * sig) ** 2]))

    def P0(self, layout: StateLayout, lat: float, m0: FloatArray | None = None) -> FloatArray:
        """Initial covariance.

        Parameters
        ----------
        layout : StateLayout
            19- or 13-state layout.
        lat : float
            Latitude [rad] (for ``dL`` in radians).
        m0 : ndarray, shape (3, 6), optional
            Flexure lever-arm matrix at the start: ``dV_0 = dv_0 + M xi_0`` is then
            correlated with ``xi_0``.

        Returns
        -------
        ndarray, shape (n, n)
        """
        n = layout.n
        P = np.zeros((n, n))
        P[layout.dl, layout.dl] = (self.p0_pos / float(R_M(lat))) ** 2
        P[layout.dv, layout.dv] = self.p0_vel**2 * _I3
        P[layout.att, layout.att] = np.diag([self.p0_level**2] * 2 + [self.p0_heading**2])
        P[layout.nabla, layout.nabla] = self.p0_accel_bias**2 * _I3
        P[layout.eps, layout.eps] = self.p0_gyro_drift**2 * _I3
        if layout.flexure:
            Px = self.flexure_p0()
            P[layout.xi, layout.xi] = Px
            if m0 is not None:
                P[layout.dv, layout.dv] += m0 @ Px @ m0.T
                P[layout.dv, layout.xi] = m0 @ Px
                P[layout.xi, layout.dv] = (m0 @ Px).T
        return P


# ----------------------------------------------------------------------------- helpers
def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product over the last axis (broadcasting)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


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


def wrap_pi(a: ArrayLike) -> FloatArray:
    """Wrap angles to (-pi, pi].

    Parameters
    ----------
    a : array_like, any shape
        Angles [rad].

    Returns
    -------
    ndarray, same shape
        The same angles in (-pi, pi] [rad].
    """
    a = np.asarray(a, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def flexure_matrix(c_b_n: FloatArray, omega_eb_b: FloatArray, R0: FloatArray) -> FloatArray:
    """``M = C_b_n [[omega_eb_b x] R_0, R_0]``: flexure part of the slave velocity, shape (3, 6).

    ``v_s - v_m - C_b_n (omega_eb_b x r_0) = M [theta; theta']`` (seed 001 eq. 10).

    Parameters
    ----------
    c_b_n : ndarray, shape (3, 3)
        Master attitude.
    omega_eb_b : ndarray, shape (3,)
        Master rate w.r.t. the earth, master axes [rad/s].
    R0 : ndarray, shape (3, 3)
        Seed 001's ``R_0``.

    Returns
    -------
    ndarray, shape (3, 6)
    """
    return np.hstack([c_b_n @ skew(omega_eb_b) @ R0, c_b_n @ R0])


# ----------------------------------------------------------------------------- period sums
@dataclass
class PeriodSums:
    """What the mechanisation accumulates over one filter period (inputs of ``fx``).

    Attributes
    ----------
    T : float
        Period length [s].
    dv_f : ndarray, shape (3,)
        ``int C^ f~ dt`` [m/s] (computed navigation frame).
    c_int : ndarray, shape (3, 3)
        ``int C^_s_n dt`` [s].
    v_int : ndarray, shape (3,)
        ``int v^ dt`` [m].
    w_in : ndarray, shape (3,)
        ``int w^_in dt`` [rad].
    cor : ndarray, shape (3,)
        ``int (2 w^_ie + w^_en) dt`` [rad].
    lat : float
        Mechanisation latitude ``L^`` at the start [rad].
    height : float
        Height [m].
    m0, m1 : ndarray, shape (3, 6), or None
        Flexure matrices at the start and the end of the period.
    phi_flex : ndarray, shape (6, 6), or None
        Flexure transition over ``T``.
    """

    T: float = 0.0
    dv_f: FloatArray = field(default_factory=lambda: np.zeros(3))
    c_int: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))
    v_int: FloatArray = field(default_factory=lambda: np.zeros(3))
    w_in: FloatArray = field(default_factory=lambda: np.zeros(3))
    cor: FloatArray = field(default_factory=lambda: np.zeros(3))
    lat: float = 0.0
    height: float = 0.0
    m0: FloatArray | None = None
    m1: FloatArray | None = None
    phi_flex: FloatArray | None = None

    @classmethod
    def constant(
        cls,
        T: float,
        f_n: ArrayLike,
        c_s_n: ArrayLike,
        v_n: ArrayLike,
        lat: float,
        height: float = 0.0,
        m: ArrayLike | None = None,
        phi_flex: ArrayLike | None = None,
    ) -> PeriodSums:
        """Sums for inputs held constant over ``T`` (tests and linearisation checks).

        Parameters
        ----------
        T : float
            Period [s].
        f_n : array_like, shape (3,)
            Specific force in the computed frame [m/s2].
        c_s_n : array_like, shape (3, 3)
            Attitude.
        v_n : array_like, shape (3,)
            Velocity [m/s].
        lat, height : float
            Position [rad, m].
        m : array_like, shape (3, 6), optional
            Flexure matrix (used at both ends).
        phi_flex : array_like, shape (6, 6), optional
            Flexure transition over ``T``.

        Returns
        -------
        PeriodSums
        """
        v = np.asarray(v_n, dtype=float)
        w_ie, w_en = _nav_rates(v, lat, height)
        mm = None if m is None else np.asarray(m, dtype=float)
        return cls(
            T=float(T),
            dv_f=np.asarray(f_n, dtype=float) * T,
            c_int=np.asarray(c_s_n, dtype=float) * T,
            v_int=v * T,
            w_in=(w_ie + w_en) * T,
            cor=(2.0 * w_ie + w_en) * T,
            lat=float(lat),
            height=float(height),
            m0=mm,
            m1=mm,
            phi_flex=None if phi_flex is None else np.asarray(phi_flex, dtype=float),
        )


def _nav_rates(v: FloatArray, lat: float, height: float) -> tuple[FloatArray, FloatArray]:
    """Earth rate and transport rate in NED [rad/s], shape (3,) each."""
    rn = float(R_N(lat)) + height
    rm = float(R_M(lat)) + height
    w_ie = np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])
    w_en = np.array([v[1] / rn, -v[0] / rm, -v[1] * math.tan(lat) / rn])
    return w_ie, w_en


# ----------------------------------------------------------------------------- nonlinear model
def propagate(x: ArrayLike, sums: PeriodSums, layout: StateLayout) -> FloatArray:
    """Nonlinear error model over one filter period (the UKF's ``fx``), batched.

    Parameters
    ----------
    x : array_like, shape (..., n)
        Error state(s) at the start of the period (see the module docstring).
    sums : PeriodSums
        The mechanisation's integrals over the period.
    layout : StateLayout
        19- or 13-state layout.

    Returns
    -------
    ndarray, shape (..., n)
        Error state(s) at the end of the period.
    """
    x = np.asarray(x, dtype=float)
    T = sums.T
    out = np.empty_like(x)
    dl = x[..., layout.dl]
    dV = x[..., layout.dv]
    att = x[..., layout.att]
    nab = x[..., layout.nabla]
    eps = x[..., layout.eps]
    if layout.flexure:
        xi = x[..., layout.xi]
        dv0 = dV - xi @ sums.m0.T
    else:
        dv0 = dV
    lat_h = sums.lat
    rm = float(R_M(lat_h)) + sums.height
    rn = float(R_N(lat_h)) + sums.height
    cl, sl, tl = math.cos(lat_h), math.sin(lat_h), math.tan(lat_h)
    lat_t = lat_h - dl
    zero = np.zeros_like(dl)
    d_wie = OMEGA_IE * np.stack([cl - np.cos(lat_t), zero, -(sl - np.sin(lat_t))], axis=-1)
    v_mean_e = sums.v_int[1] / T if T > 0 else 0.0
    d_wen = np.stack(
        [
            dv0[..., 1] / rn,
            -dv0[..., 0] / rm,
            -dv0[..., 1] * tl / rn - v_mean_e * dl / (rn * cl * cl),
        ],
        axis=-1,
    )
    d_win = d_wie + d_wen
    E0 = euler_to_dcm(att)
    rot = (
        eps @ sums.c_int.T + (E0 @ sums.w_in) - sums.w_in - (E0 @ (d_win[..., :, None] * T))[..., 0]
    )
    E1 = rotvec_to_dcm(rot) @ E0
    EbT = 0.5 * np.swapaxes(E0 + E1, -1, -2)
    dv1 = (
        dv0
        + sums.dv_f
        - EbT @ sums.dv_f
        + (EbT @ (nab @ sums.c_int.T)[..., :, None])[..., 0]
        - _cross(np.broadcast_to(sums.cor, dv0.shape), dv0)
        - _cross(2.0 * d_wie + d_wen, np.broadcast_to(sums.v_int, dv0.shape))
    )
    out[..., layout.dl] = dl + 0.5 * (dv0[..., 0] + dv1[..., 0]) * T / rm
    out[..., layout.att] = dcm_to_euler(E1)
    out[..., layout.nabla] = nab
    out[..., layout.eps] = eps
    if layout.flexure:
        xi1 = xi @ sums.phi_flex.T
        out[..., layout.xi] = xi1
        out[..., layout.dv] = dv1 + xi1 @ sums.m1.T
    else:
        out[..., layout.dv] = dv1
    return out


def measurement(x: ArrayLike, layout: StateLayout) -> FloatArray:
    """Velocity-matching measurement ``h(x) = dV``.

    Parameters
    ----------
    x : array_like, shape (..., n)
        Error states (one or many: sigma points along the first axes).
    layout : StateLayout
        19- or 13-state layout (where ``dV`` sits in ``x``).

    Returns
    -------
    ndarray, shape (..., 3)
        Slave-minus-master velocity error, NED [m/s].
    """
    return np.asarray(x, dtype=float)[..., layout.dv]


def reset_jacobian(x_hat: ArrayLike, layout: StateLayout) -> FloatArray:
    """Jacobian of the closed-loop reset at the estimate ``x_hat``, shape (n, n).

    After the feedback ``C^ <- E(phi^)^T C^`` the new error rotation is
    ``E(phi) E(phi^)^T``; to first order its Euler angles are ``A(phi^) (phi - phi^)``
    with ``A`` the Euler-rate matrix (:func:`euler_rate_matrix`). Every other state is
    shifted, so its block is the identity.

    Parameters
    ----------
    x_hat : array_like, shape (n,)
        The estimate fed back.
    layout : StateLayout
        19- or 13-state layout.

    Returns
    -------
    ndarray, shape (n, n)
    """
    J = np.eye(layout.n)
    J[layout.att, layout.att] = euler_rate_matrix(np.asarray(x_hat)[layout.att])
    return J


# ----------------------------------------------------------------------------- linear model
def linear_error_model(
    f_n: ArrayLike,
    c_s_n: ArrayLike,
    v_n: ArrayLike,
    lat: float,
    height: float = 0.0,
    layout: StateLayout | None = None,
    m: ArrayLike | None = None,
    m_dot: ArrayLike | None = None,
    tuning: TransferTuning | None = None,
) -> FloatArray:
    """Continuous-time small-error model ``x' = A x`` of the filter's state.

    Derived from the equations of the module docstring with ``E = I + [phi x]``, first
    in the slave-velocity form ``y = [dL, dv, phi, xi, nabla, eps]``::

        dL'  = dv_N / R_M
        dv'  = -[f x] phi + C_s_n nabla - [(2 w_ie + w_en) x] dv + [v x](2 dw_ie + dw_en)
        phi' = -[w_in x] phi + C_s_n eps - dw_ie - dw_en
        xi'  = F_flex xi
        dw_ie = Omega [-sin L, 0, -cos L] dL,
        dw_en = [dv_E / R_N, -dv_N / R_M, -dv_E tan L / R_N - v_E dL / (R_N cos^2 L)]

    then transformed to the filter's ``dV = dv + M xi``: ``A = S A_y S^-1 + S' S^-1`` with
    ``S = I + (M in the (dV, xi) block)``.

    Parameters
    ----------
    f_n : array_like, shape (3,)
        Slave specific force in NED [m/s2].
    c_s_n : array_like, shape (3, 3)
        Slave attitude.
    v_n : array_like, shape (3,)
        Slave velocity [m/s].
    lat, height : float
        Position [rad, m].
    layout : StateLayout, optional
        Default: 19 states.
    m, m_dot : array_like, shape (3, 6), optional
        Flexure matrix ``M`` and its time derivative (default zero).
    tuning : TransferTuning, optional
        For the flexure model (default :class:`TransferTuning`).

    Returns
    -------
    ndarray, shape (n, n) [1/s]
    """
    layout = layout or StateLayout()
    tuning = tuning or TransferTuning()
    f = np.asarray(f_n, dtype=float)
    C = np.asarray(c_s_n, dtype=float)
    v = np.asarray(v_n, dtype=float)
    n = layout.n
    rm = float(R_M(lat)) + height
    rn = float(R_N(lat)) + height
    w_ie, w_en = _nav_rates(v, lat, height)
    sl, cl, tl = math.sin(lat), math.cos(lat), math.tan(lat)
    N = np.array([[0.0, 1.0 / rn, 0.0], [-1.0 / rm, 0.0, 0.0], [0.0, -tl / rn, 0.0]])
    l_ie = OMEGA_IE * np.array([-sl, 0.0, -cl])
    l_en = np.array([0.0, 0.0, -v[1] / (rn * cl * cl)])
    dl, dv, att = layout.dl, layout.dv, layout.att
    A = np.zeros((n, n))
    A[dl, dv.start] = 1.0 / rm
    A[dv, dv] = -skew(2.0 * w_ie + w_en) + skew(v) @ N
    A[dv, dl] = skew(v) @ (2.0 * l_ie + l_en)
    A[dv, att] = -skew(f)
    A[dv, layout.nabla] = C
    A[att, att] = -skew(w_ie + w_en)
    A[att, dv] = -N
    A[att, dl] = -(l_ie + l_en)
    A[att, layout.eps] = C
    if not layout.flexure:
        return A
    F, _, _ = tuning.flexure_model()
    A[layout.xi, layout.xi] = F
    M = np.zeros((3, 6)) if m is None else np.asarray(m, dtype=float)
    Md = np.zeros((3, 6)) if m_dot is None else np.asarray(m_dot, dtype=float)
    S = np.eye(n)
    S[dv, layout.xi] = M
    S_inv = np.eye(n)
    S_inv[dv, layout.xi] = -M
    S_dot = np.zeros((n, n))
    S_dot[dv, layout.xi] = Md
    return S @ A @ S_inv + S_dot @ S_inv


# ----------------------------------------------------------------------------- covariance analysis
@dataclass
class CovarianceHistory:
    """Result of :func:`covariance_analysis` (sigmas after each update).

    Attributes
    ----------
    time : ndarray, shape (m,)
        Update times [s].
    sigma_nav : ndarray, shape (m, 3)
        1-sigma of ``phi_N, phi_E, phi_D`` (navigation-frame attitude error) [arcmin].
    sigma_rel : ndarray, shape (m, 3)
        1-sigma of the relative-attitude roll, pitch, heading errors [arcmin].
    sigma_level_rms : ndarray, shape (m,)
        ``sqrt((sigma_N^2 + sigma_E^2) / 2)`` [arcmin].
    sigma_accel_bias : ndarray, shape (m, 3)
        1-sigma of the accelerometer bias, slave axes [ug].
    P : ndarray, shape (m, n, n)
        Covariances in SI units, state ``[dL, dv, phi, (xi), nabla, eps]``.
    """

    time: FloatArray
    sigma_nav: FloatArray
    sigma_rel: FloatArray
    sigma_level_rms: FloatArray
    sigma_accel_bias: FloatArray
    P: FloatArray

    def at(self, t: float) -> int:
        """Index of the update time closest to ``t``.

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        int
            Row of :attr:`time` (and of the sigma arrays).
        """
        return int(np.argmin(np.abs(self.time - t)))


def ship_truth(
    t: ArrayLike,
    *,
    lat: float = 30.0 * DEG,
    amp: ArrayLike = (12.5 * DEG, 10.0 * DEG, 5.0 * DEG),
    period: ArrayLike = (12.0, 6.0, 8.0),
    phase: ArrayLike = _ZERO3,
    rpy_mean: ArrayLike = _ZERO3,
) -> dict[str, FloatArray]:
    """Closed-form moored-ship motion (the equations of :mod:`models.ship_motion`).

    Parameters
    ----------
    t : array_like, shape (m,)
        Times [s].
    lat : float
        Latitude [rad].
    amp, period, phase, rpy_mean : array_like, shape (3,)
        Roll/pitch/yaw amplitude [rad], period [s], phase [rad], mean [rad].

    Returns
    -------
    dict
        ``rpy, rpy_dot`` (m, 3); ``C_b_n`` (m, 3, 3); ``omega_ib_b, omega_dot_b, f_b``
        (m, 3) in master axes; ``omega_nb_b`` (m, 3).
    """
    tt = np.atleast_1d(np.asarray(t, dtype=float))
    per = np.asarray(period, dtype=float)
    w = np.where(per > 0.0, 2.0 * np.pi / np.where(per > 0.0, per, 1.0), 0.0)
    a = np.where(per > 0.0, np.asarray(amp, dtype=float), 0.0)
    arg = tt[:, None] * w + np.asarray(phase, dtype=float)
    rpy = np.asarray(rpy_mean, dtype=float) + a * np.sin(arg)
    rpy_dot = a * w * np.cos(arg)
    rpy_ddot = -a * w**2 * np.sin(arg)
    truth = euler_motion_truth(rpy, rpy_dot, rpy_ddot, None, None, None, lat, 0.0, 0.0)
    w_ie_b = np.einsum(
        "mji,j->mi",
        truth.C_b_n,
        np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)]),
    )
    return {
        "rpy": rpy,
        "rpy_dot": rpy_dot,
        "C_b_n": truth.C_b_n,
        "omega_ib_b": truth.omega_ib_b,
        "omega_dot_b": truth.omega_dot_b,
        "omega_eb_b": truth.omega_ib_b - w_ie_b,
        "f_b": truth.f_b,
    }


def _repeat_steps(period: ArrayLike, dt: float) -> int:
    """Steps after which the ship's motion repeats (0 if not a whole number of steps).

    The least common multiple of the active periods, on a 1 microsecond grid.
    """
    us = [int(round(p * 1e6)) for p in np.asarray(period, dtype=float) if p > 0.0]
    if not us or any(
        abs(u - p * 1e6) > 1e-3
        for u, p in zip(us, [p for p in np.asarray(period, dtype=float) if p > 0.0], strict=True)
    ):
        return 0
    lcm = math.lcm(*us) * 1e-6
    n = lcm / dt
    return int(round(n)) if abs(n - round(n)) < 1e-9 * max(1.0, n) and n >= 1 else 0


def covariance_analysis(
    t_end: float = 120.0,
    *,
    r0: ArrayLike = (10.0, 10.0, 5.0),
    mount_rpy: ArrayLike = (1.0 * DEG, 1.0 * DEG, 30.0 * DEG),
    lat: float = 30.0 * DEG,
    amp: ArrayLike = (12.5 * DEG, 10.0 * DEG, 5.0 * DEG),
    period: ArrayLike = (12.0, 6.0, 8.0),
    tuning: TransferTuning | None = None,
    flexure: bool = False,
    update_period: float = 0.5,
    dt: float = 0.1,
) -> CovarianceHistory:
    """Linear covariance analysis of velocity-matching transfer alignment along the ship's motion.

    Independent of the simulation and of the filter's bookkeeping: the ship's motion is
    evaluated in closed form (:func:`ship_truth`), the slave's kinematics from it (rigid
    lever arm ``r_0``, mounting ``mount_rpy``), and the small-error model is used in its
    **slave-velocity form** ``y = [dL, dv, phi, (xi), nabla, eps]`` (the filter uses
    ``dV = dv + M xi``), where the flexure enters only the measurement::

        z = dv + M(t) xi + n,   E[n n^T] = r_vel^2 I    every update_period

    The model (:func:`linear_error_model` without the transformation) is held constant
    over ``dt`` at the interval's midpoint and discretised exactly with
    :func:`cosim.estimation.van_loan` (noise: accelerometer ``q_accel`` on ``dv``, gyro
    ``q_gyro`` on ``phi``, flexure ``eta``). Updates use the Joseph form.

    Parameters
    ----------
    t_end : float
        Duration [s].
    r0 : array_like, shape (3,)
        Lever arm, master axes [m].
    mount_rpy : array_like, shape (3,)
        Slave mounting [rad].
    lat : float
        Latitude [rad].
    amp, period : array_like, shape (3,)
        Ship roll/pitch/yaw amplitude [rad] and period [s].
    tuning : TransferTuning, optional
        P0, noises (default seed 001's).
    flexure : bool
        Include the flexure states (and the flexure part of the measurement).
    update_period : float
        Velocity-matching period [s].
    dt : float
        Propagation step [s]; must divide ``update_period``.

    Returns
    -------
    CovarianceHistory
    """
    tuning = tuning or TransferTuning()
    layout = StateLayout(flexure)
    n = layout.n
    k_up = int(round(update_period / dt))
    if k_up < 1 or abs(k_up * dt - update_period) > 1e-9:
        raise TransferConfigError(f"dt ({dt}) must divide update_period ({update_period})")
    n_steps = int(round(t_end / dt))
    r0 = np.asarray(r0, dtype=float)
    R0 = r0_matrix(r0)
    c_s_b = euler_to_dcm(np.asarray(mount_rpy, dtype=float))
    t_mid = (np.arange(n_steps) + 0.5) * dt
    t_up = np.arange(1, n_steps // k_up + 1) * update_period
    mid = ship_truth(t_mid, lat=lat, amp=amp, period=period)
    up = ship_truth(t_up, lat=lat, amp=amp, period=period)

    def slave(tr: dict[str, FloatArray]) -> tuple[FloatArray, FloatArray, FloatArray]:
        w, wd = tr["omega_ib_b"], tr["omega_dot_b"]
        wr = np.sum(w * r0, axis=-1, keepdims=True)
        f_p = (
            tr["f_b"]
            + _cross(wd, np.broadcast_to(r0, wd.shape))
            + w * wr
            - r0 * np.sum(w * w, axis=-1, keepdims=True)
        )
        c_b_n = tr["C_b_n"]
        f_n = np.einsum("mij,mj->mi", c_b_n, f_p)
        v_n = np.einsum("mij,mj->mi", c_b_n, _cross(tr["omega_eb_b"], np.broadcast_to(r0, w.shape)))
        return f_n, v_n, c_b_n @ c_s_b

    f_mid, v_mid, cs_mid = slave(mid)
    y_layout = StateLayout(flexure)
    G = np.zeros((n, 9))
    G[layout.dv, 0:3] = _I3
    G[layout.att, 3:6] = _I3
    Qc = np.zeros((9, 9))
    Qc[0:3, 0:3] = tuning.q_accel**2 * _I3
    Qc[3:6, 3:6] = tuning.q_gyro**2 * _I3
    if flexure:
        _, Gf, Qf = tuning.flexure_model()
        G[layout.xi, 6:9] = Gf
        Qc[6:9, 6:9] = Qf
    P = tuning.P0(layout, lat)  # slave-velocity form: dv_0 independent of xi_0
    R = tuning.r_vel**2 * _I3
    H = np.zeros((3, n))
    H[:, layout.dv] = _I3
    # The motion repeats with the least common multiple of the periods (24 s for seed
    # 001): the discretised model of step k equals that of step k - n_rep.
    n_rep = _repeat_steps(period, dt)
    cache: dict[int, tuple[FloatArray, FloatArray]] = {}
    Ps, sig_nav, sig_rel = [], [], []
    for k in range(n_steps):
        key = k % n_rep if n_rep else k
        if key not in cache:
            A = linear_error_model(f_mid[k], cs_mid[k], v_mid[k], lat, 0.0, y_layout, tuning=tuning)
            cache[key] = van_loan(A, G, Qc, dt)
        Phi, Qd = cache[key]
        P = Phi @ P @ Phi.T + Qd
        if (k + 1) % k_up:
            continue
        j = (k + 1) // k_up - 1
        if flexure:
            H[:, layout.xi] = flexure_matrix(up["C_b_n"][j], up["omega_eb_b"][j], R0)
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        IKH = np.eye(n) - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T
        P = 0.5 * (P + P.T)
        Ps.append(P.copy())
        P_att = P[layout.att, layout.att]
        sig_nav.append(np.sqrt(np.diag(P_att)))
        c_b_n = up["C_b_n"][j]
        rel = dcm_to_euler(c_s_b)
        B = np.linalg.solve(euler_rate_matrix(rel), c_b_n.T)
        sig_rel.append(np.sqrt(np.diag(B @ P_att @ B.T)))
    Ps_a = np.array(Ps)
    nav = np.array(sig_nav) / ARCMIN
    return CovarianceHistory(
        time=t_up,
        sigma_nav=nav,
        sigma_rel=np.array(sig_rel) / ARCMIN,
        sigma_level_rms=np.sqrt(0.5 * (nav[:, 0] ** 2 + nav[:, 1] ** 2)),
        sigma_accel_bias=np.sqrt(np.diagonal(Ps_a[:, layout.nabla, layout.nabla], axis1=1, axis2=2))
        / MICRO_G,
        P=Ps_a,
    )


# ----------------------------------------------------------------------------- mechanisation
class SlaveStrapdown:
    """NED strapdown mechanisation of the slave IMU with the period sums of :class:`PeriodSums`.

    Parameters
    ----------
    c_s_n : array_like, shape (3, 3)
        Initial attitude.
    v_n : array_like, shape (3,)
        Initial velocity [m/s].
    lat : float
        Initial latitude [rad].
    height : float
        Height [m] (held: the vertical position is not mechanised).

    Attributes
    ----------
    C : ndarray, shape (3, 3)
        Attitude ``C^_s_n``.
    v : ndarray, shape (3,)
        Velocity [m/s].
    lat : float
        Latitude [rad].
    nabla, eps : ndarray, shape (3,)
        Accelerometer bias and gyro drift subtracted from the increments [m/s2, rad/s].
    sums : PeriodSums
        Integrals since the last :meth:`start_period`.
    """

    def __init__(self, c_s_n: ArrayLike, v_n: ArrayLike, lat: float, height: float = 0.0) -> None:
        self.C = np.array(c_s_n, dtype=float)
        self.v = np.array(v_n, dtype=float)
        self.v_prev = self.v.copy()
        self.lat = float(lat)
        self.height = float(height)
        self.nabla = np.zeros(3)
        self.eps = np.zeros(3)
        self._dth_prev = np.zeros(3)
        self._dv_prev = np.zeros(3)
        self._first = True
        self._set_constants()
        self.sums = PeriodSums(lat=self.lat, height=self.height)

    def _set_constants(self) -> None:
        lat = self.lat
        self._rm = float(R_M(lat)) + self.height
        self._rn = float(R_N(lat)) + self.height
        self._tan = math.tan(lat)
        self._w_ie = np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])
        self._g = np.array([0.0, 0.0, float(gravity(lat, self.height))])

    def start_period(self) -> None:
        """Restart the period sums (and refresh the latitude-dependent constants)."""
        self._set_constants()
        self.sums = PeriodSums(lat=self.lat, height=self.height)

    def step(self, dtheta: FloatArray, dv: FloatArray, h: float) -> None:
        """Integrate one pair of increments over ``h`` and add to the period sums.

        Parameters
        ----------
        dtheta, dv : ndarray, shape (3,)
            Measured angle [rad] and velocity [m/s] increments, slave axes.
        h : float
            Step [s].
        """
        dth = dtheta - self.eps * h
        dvb = dv - self.nabla * h
        if self._first:  # no previous increment: no coning/sculling terms this step
            self._dth_prev, self._dv_prev = dth, dvb
            self._first = False
        p_th, p_dv = self._dth_prev, self._dv_prev
        a = dth + _cross3(p_th, dth) / 12.0
        c1 = _cross3(dth, dvb)
        u = dvb + 0.5 * c1 + _cross3(dth, c1) / 6.0
        u += (_cross3(p_th, dvb) + _cross3(p_dv, dth)) / 12.0
        v = self.v
        v_mid = 1.5 * v - 0.5 * self.v_prev
        w_en = np.array(
            [v_mid[1] / self._rn, -v_mid[0] / self._rm, -v_mid[1] * self._tan / self._rn]
        )
        w_in = self._w_ie + w_en
        zeta = w_in * h
        c_old = self.C
        cu = c_old @ u
        dv_f = cu - 0.5 * _cross3(zeta, cu)
        cor = 2.0 * self._w_ie + w_en
        v_new = v + dv_f + (self._g - _cross3(cor, v_mid)) * h
        c_new = rotvec_to_dcm_3(-zeta) @ c_old @ rotvec_to_dcm_3(a)
        s = self.sums
        s.T += h
        s.dv_f += dv_f
        s.c_int += 0.5 * h * (c_old + c_new)
        s.v_int += 0.5 * h * (v + v_new)
        s.w_in += w_in * h
        s.cor += cor * h
        self.lat += v_mid[0] * h / self._rm
        self.v_prev = v
        self.v = v_new
        self.C = c_new
        self._dth_prev, self._dv_prev = dth, dvb

    def correct(self, d_lat: float, d_v: FloatArray, e_err: FloatArray) -> None:
        """Remove estimated errors: ``L -= d_lat``, ``v -= d_v``, ``C <- e_err^T C``.

        Parameters
        ----------
        d_lat : float
            Latitude error [rad].
        d_v : ndarray, shape (3,)
            Velocity error [m/s].
        e_err : ndarray, shape (3, 3)
            Estimated error rotation ``E = C^ C^T`` (true to computed frame).
        """
        self.lat -= d_lat
        self.v = self.v - d_v
        self.v_prev = self.v_prev - d_v
        self.C = e_err.T @ self.C


def euler_rate_matrix_inv(rpy: ArrayLike) -> FloatArray:
    """Inverse of :func:`euler_rate_matrix` (closed form).

    Parameters
    ----------
    rpy : array_like, shape (3,)
        Roll, pitch, yaw [rad] (Z-Y-X); pitch must not be +-90 deg.

    Returns
    -------
    ndarray, shape (3, 3)
        Maps small rotation-vector errors to Euler-angle errors.
    """
    _, p, y = (float(v) for v in np.asarray(rpy, dtype=float))
    cp, tp = math.cos(p), math.tan(p)
    cy, sy = math.cos(y), math.sin(y)
    return np.array([[cy / cp, sy / cp, 0.0], [-sy, cy, 0.0], [cy * tp, sy * tp, 1.0]])


def _cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of two 3-vectors (no broadcasting; cheaper than ``np.cross``)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def master_rate(c_hist: list[FloatArray], h: float) -> FloatArray:
    """Master body rate w.r.t. the navigation frame at the newest sample, master axes.

    Five-point backward difference of ``rho_j = rotvec(C_0^T C_j)`` (``C_0`` the newest
    attitude, ``C_j`` the one ``j`` steps before)::

        omega_nb_b = (-48 rho_1 + 36 rho_2 - 16 rho_3 + 3 rho_4) / (12 h)

    exact for ``rho`` quartic in time; with fewer samples the 3- or 2-point formula.

    Parameters
    ----------
    c_hist : list of ndarray, shape (3, 3)
        Attitudes ``C_b_n``, newest first, equally spaced by ``h``.
    h : float
        Spacing [s].

    Returns
    -------
    ndarray, shape (3,) [rad/s]
    """
    c0 = c_hist[0]
    k = len(c_hist)
    if k < 2:
        return np.zeros(3)
    rho = dcm_to_rotvec(np.array([c0.T @ c for c in c_hist[1:5]]))
    if k >= 5:
        return (-48.0 * rho[0] + 36.0 * rho[1] - 16.0 * rho[2] + 3.0 * rho[3]) / (12.0 * h)
    if k >= 3:
        return (-4.0 * rho[0] + rho[1]) / (2.0 * h)
    return -rho[0] / h


# ----------------------------------------------------------------------------- the block
class TransferAlignment(Block):
    """Shipboard transfer alignment by velocity matching: slave strapdown + 19-state scaled UKF."""

    variables = (
        parameter("r0", (10.0, 10.0, 5.0), "m", "nominal lever arm master -> slave, master axes"),
        parameter("flexure_states", 1, description="1: 19 states with flexure, 0: 13 (ignored)"),
        parameter("period", 0.5, "s", "filter period (a whole number of macro steps)"),
        parameter("p0_pos", TransferTuning.p0_pos, "m", "P0: position error behind dL"),
        parameter("p0_vel", TransferTuning.p0_vel, "m/s", "P0: velocity difference sigma"),
        parameter("p0_level", TransferTuning.p0_level, "rad", "P0: level error sigma"),
        parameter("p0_heading", TransferTuning.p0_heading, "rad", "P0: heading error sigma"),
        parameter(
            "p0_accel_bias", TransferTuning.p0_accel_bias, "m/s2", "P0: accelerometer bias sigma"
        ),
        parameter("p0_gyro_drift", TransferTuning.p0_gyro_drift, "rad/s", "P0: gyro drift sigma"),
        parameter("q_accel", TransferTuning.q_accel, "m/s/sqrt(s)", "Q: accelerometer noise"),
        parameter("q_gyro", TransferTuning.q_gyro, "rad/sqrt(s)", "Q: gyro noise density"),
        parameter("r_vel", TransferTuning.r_vel, "m/s", "R: velocity-matching noise sigma"),
        parameter("flexure_tau", TransferTuning.flex_tau, "s", "flexure model: tau per axis"),
        parameter(
            "flexure_sigma", TransferTuning.flex_sigma, "rad", "flexure model: sigma per axis"
        ),
        parameter("acquire_hypotheses", 6, description="stage 1: headings in the UKF bank"),
        parameter(
            "acquire_sigma", 1.0 * DEG, "rad", "stage 1 ends when the heading sigma is below this"
        ),
        parameter(
            "acquire_weight", 0.99, "1", "... and the hypotheses on the best heading this weight"
        ),
        parameter("acquire_min_time", 5.0, "s", "shortest stage 1 (acquisition)"),
        parameter(
            "relevel_sigma", 10.0 * ARCMIN, "rad", "level sigma added at the stage-2 restart"
        ),
        parameter("ukf_alpha", 0.1, "1", "UKF sigma-point spread alpha"),
        parameter("ukf_beta", 2.0, "1", "UKF beta (2: Gaussian prior)"),
        parameter("ukf_kappa", 0.0, "1", "UKF kappa"),
        input_("dtheta_s", _ZERO3, "rad", "slave angle increment over the step, slave axes"),
        input_("dv_s", _ZERO3, "m/s", "slave velocity increment over the step, slave axes"),
        input_("v_master_n", _ZERO3, "m/s", "master velocity, NED"),
        input_("rpy_master", _ZERO3, "rad", "master attitude (roll, pitch, yaw)"),
        input_("lat_master", 30.0 * DEG, "rad", "master latitude"),
        input_("h_master", 0.0, "m", "master height"),
        input_("rpy_s_true", _ZERO3, "rad", "truth: slave attitude (LeverArm.rpy_s)"),
        input_("rpy_m_true", _ZERO3, "rad", "truth: master attitude (ShipMotion.rpy)"),
        output("rpy_err", _ZERO3, "arcmin", "relative attitude error: roll, pitch, heading"),
        output("rpy_sigma", _ZERO3, "arcmin", "1-sigma of rpy_err from P"),
        output("rel_rpy", _ZERO3, "rad", "estimated slave attitude in master axes (misalignment)"),
        output("flex", _ZERO3, "arcmin", "estimated flexure angle, master axes"),
        output("flex_sigma", _ZERO3, "arcmin", "1-sigma of flex"),
        output("accel_bias", _ZERO3, "m/s2", "estimated accelerometer bias, slave axes"),
        output("accel_bias_sigma", _ZERO3, "m/s2", "1-sigma of accel_bias"),
        output("gyro_drift", _ZERO3, "rad/s", "estimated gyro drift, slave axes"),
        output("gyro_drift_sigma", _ZERO3, "rad/s", "1-sigma of gyro_drift"),
        output("nees", 0.0, "1", "NEES of the attitude error (chi-square, 3 dof)"),
        output("nis", 0.0, "1", "NIS of the last velocity update (chi-square, 3 dof)"),
        output("stage", 0.0, "1", "0 waiting for the master, 1 acquisition, 2 fine alignment"),
    )
    default_step = 0.02
    default_stop = 10.0

    # ------------------------------------------------------------------ set-up
    def tuning(self) -> TransferTuning:
        """The filter statistics from the parameters."""
        return TransferTuning(
            p0_pos=float(self.p0_pos),
            p0_vel=float(self.p0_vel),
            p0_level=float(self.p0_level),
            p0_heading=float(self.p0_heading),
            p0_accel_bias=float(self.p0_accel_bias),
            p0_gyro_drift=float(self.p0_gyro_drift),
            q_accel=float(self.q_accel),
            q_gyro=float(self.q_gyro),
            r_vel=float(self.r_vel),
            flex_tau=tuple(float(v) for v in self.flexure_tau),
            flex_sigma=tuple(float(v) for v in self.flexure_sigma),
        )

    def _check(self) -> None:
        if self.flexure_states not in (0, 1):
            raise TransferConfigError(
                f"TransferAlignment.flexure_states must be 0 or 1, got {self.flexure_states}"
            )
        if not self.period > 0.0:
            raise TransferConfigError(f"TransferAlignment.period must be > 0 s, got {self.period}")
        positive = ("p0_pos", "p0_vel", "p0_level", "p0_heading", "r_vel")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be > 0, got {getattr(self, name)}"
                )
        for name in ("p0_accel_bias", "p0_gyro_drift", "q_accel", "q_gyro"):
            if getattr(self, name) < 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be >= 0, got {getattr(self, name)}"
                )
        if self.flexure_states and not (
            np.all(np.asarray(self.flexure_tau) > 0.0)
            and np.all(np.asarray(self.flexure_sigma) > 0.0)
        ):
            raise TransferConfigError(
                "TransferAlignment.flexure_tau and flexure_sigma must be > 0 on every axis "
                "when flexure_states = 1"
            )
        for name in ("acquire_sigma", "relevel_sigma"):
            if not getattr(self, name) > 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be > 0, got {getattr(self, name)}"
                )
        if int(self.acquire_hypotheses) < 1:
            raise TransferConfigError(
                f"TransferAlignment.acquire_hypotheses must be >= 1, got {self.acquire_hypotheses}"
            )
        if not 0.0 < self.acquire_weight <= 1.0:
            raise TransferConfigError(
                f"TransferAlignment.acquire_weight must be in (0, 1], got {self.acquire_weight}"
            )
        if self.acquire_min_time < 0.0:
            raise TransferConfigError(
                f"TransferAlignment.acquire_min_time must be >= 0 s, got {self.acquire_min_time}"
            )
        if not self.ukf_alpha > 0.0:
            raise TransferConfigError(
                f"TransferAlignment.ukf_alpha must be > 0, got {self.ukf_alpha}"
            )

    def initialize(self) -> None:
        self._check()
        self._layout = StateLayout(bool(self.flexure_states))
        self._tune = self.tuning()
        self._R0 = r0_matrix(np.asarray(self.r0, dtype=float))
        self._r0 = np.asarray(self.r0, dtype=float).copy()
        self._hist: deque[FloatArray] = deque(maxlen=5)
        self._hist.appendleft(euler_to_dcm(np.asarray(self.rpy_master, dtype=float)))
        self._h: float | None = None
        self._k = 0
        self._n = 0
        self._sd: SlaveStrapdown | None = None
        self._ukf: UnscentedKalmanFilter | None = None
        self._bank: UnscentedParticleFilter | None = None
        self._best = 0
        self._m_prev: FloatArray | None = None
        self._flex_cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        lay = self._layout
        self._P_show = self._tune.P0(lay, float(self.lat_master))
        self._x_show = np.zeros(lay.n)
        self._P_cached: FloatArray | None = None
        self.nis = 0.0
        self.stage = 0.0
        self._publish()

    def _check_step(self, h: float) -> None:
        if self._h is None:
            k = int(round(self.period / h))
            if k < 1 or abs(k * h - self.period) > 1e-9 * self.period:
                raise TransferRuntimeError(
                    f"TransferAlignment.period ({self.period} s) must be a whole number of "
                    f"steps; the block steps by {h} s (run it at rate 1, every macro step)"
                )
            self._h, self._k = h, k
        elif abs(h - self._h) > 1e-9 * self._h:
            raise TransferRuntimeError(
                f"TransferAlignment needs a constant step; got {h} s after {self._h} s"
            )

    # ------------------------------------------------------------------ helpers
    def _master_state(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Newest master attitude, rate w.r.t. earth (master axes) and velocity."""
        c = self._hist[0]
        v_m = np.asarray(self.v_master_n, dtype=float)
        _, w_en = _nav_rates(v_m, float(self.lat_master), float(self.h_master))
        w_eb = master_rate(list(self._hist), self._h) + c.T @ w_en
        return c, w_eb, v_m

    def _flex(self, T: float) -> tuple[FloatArray, FloatArray]:
        key = round(T, 12)
        if key not in self._flex_cache:
            F, G, Qc = self._tune.flexure_model()
            self._flex_cache[key] = van_loan(F, G, Qc, T)
        return self._flex_cache[key]

    def _make_points(self) -> MerweScaledSigmaPoints:
        return MerweScaledSigmaPoints(
            self._layout.n, float(self.ukf_alpha), float(self.ukf_beta), float(self.ukf_kappa)
        )

    def _fx(self, x: FloatArray, dt: float, sums: PeriodSums) -> FloatArray:
        return propagate(x, sums, self._layout)

    def _hx(self, x: FloatArray) -> FloatArray:
        return x[..., StateLayout.dv]

    def _start(self) -> None:
        """Start the mechanisation with the master's attitude and the acquisition bank."""
        c, w_eb, v_m = self._master_state()
        lay = self._layout
        v_lr = c @ np.cross(w_eb, self._r0)
        lat = float(self.lat_master)
        self._sd = SlaveStrapdown(c, v_m + v_lr, lat, float(self.h_master))
        m0 = flexure_matrix(c, w_eb, self._R0) if lay.flexure else None
        self._m_prev = m0
        k = int(self.acquire_hypotheses)
        bank = UnscentedParticleFilter(
            lay.n,
            3,
            self._fx,
            self._hx,
            self._make_points(),
            rng=np.random.default_rng(0),  # never used: deterministic proposal, no resampling
            n_particles=k,
            resample_threshold=0.0,
            proposal="mean",
            residual_x=angle_residual_fn([lay.heading]),
            x_mean_fn=angle_mean_fn([lay.heading]),
        )
        parts = np.zeros((k, lay.n))
        parts[:, lay.heading] = wrap_pi(2.0 * np.pi * np.arange(k) / k)
        bank.set_particles(parts, self._tune.P0(lay, lat, m0))
        self._bank = bank
        self._best = 0
        self._show_bank()
        self.stage = 1.0

    def _show_bank(self) -> None:
        bank = self._bank
        self._best = int(np.argmax(bank.weights))
        self._x_show = bank.particles[self._best]
        self._P_show = bank.particle_P[self._best]

    def _process_noise(self, T: float, m1: FloatArray | None) -> FloatArray:
        lay, tu = self._layout, self._tune
        Q = np.zeros((lay.n, lay.n))
        Q[lay.dv, lay.dv] = tu.q_accel**2 * T * _I3
        Q[lay.att, lay.att] = tu.q_gyro**2 * T * _I3
        if lay.flexure:
            _, Qf = self._flex(T)
            mq = m1 @ Qf
            Q[lay.xi, lay.xi] = Qf
            Q[lay.dv, lay.dv] += mq @ m1.T
            Q[lay.dv, lay.xi] = mq
            Q[lay.xi, lay.dv] = mq.T
        return 0.5 * (Q + Q.T)

    def _update(self) -> None:
        """One filter period: predict with the period sums, velocity update, feedback."""
        sd, lay = self._sd, self._layout
        sums = sd.sums
        T = sums.T
        c, w_eb, v_m = self._master_state()
        m1 = None
        if lay.flexure:
            m1 = flexure_matrix(c, w_eb, self._R0)
            sums.m0, sums.m1 = self._m_prev, m1
            sums.phi_flex = self._flex(T)[0]
            self._m_prev = m1
        Q = self._process_noise(T, m1)
        R = self._tune.r_vel**2 * _I3
        z = sd.v - v_m - c @ np.cross(w_eb, self._r0)
        if self.stage == 1.0:
            self._bank.step(z, T, Q=Q, R=R, fx_args={"sums": sums})
            self._show_bank()
            bank = self._bank
            self.nis = float(bank.particle_nis[self._best])
            sig_best = math.sqrt(bank.particle_P[self._best][lay.heading, lay.heading])
            # hypotheses that converged onto the best one's heading count with it
            gap = np.abs(wrap_pi(bank.particles[:, lay.heading] - self._x_show[lay.heading]))
            weight = float(np.sum(bank.weights[gap < self.acquire_sigma]))
            t = self._n * self._h
            done = (
                t >= self.acquire_min_time - 1e-9
                and weight >= self.acquire_weight
                and sig_best < self.acquire_sigma
            )
            if done:
                self._restart_fine(m1)
            sd.start_period()
            return
        ukf = self._ukf
        ukf.predict(T, Q=Q, sums=sums)
        ukf.update(z, R=R)
        self.nis = float(ukf.y @ np.linalg.solve(ukf.S, ukf.y))
        x = ukf.x.copy()
        P = self._feedback(x, ukf.P, m1)
        x_new = np.zeros(lay.n)
        if lay.flexure:
            x_new[lay.xi] = x[lay.xi]
            x_new[lay.dv] = m1 @ x[lay.xi]
        ukf.x = x_new
        ukf.P = P
        self._x_show = ukf.x
        self._P_show = ukf.P
        sd.start_period()

    def _feedback(self, x: FloatArray, P: FloatArray, m1: FloatArray | None) -> FloatArray:
        """Correct the mechanisation with the estimate ``x``; return the reset covariance."""
        lay, sd = self._layout, self._sd
        x[lay.heading] = wrap_pi(x[lay.heading])
        d_v = x[lay.dv] - (m1 @ x[lay.xi] if lay.flexure else 0.0)
        sd.correct(float(x[lay.dl]), d_v, euler_to_dcm(x[lay.att]))
        sd.nabla = sd.nabla + x[lay.nabla]
        sd.eps = sd.eps + x[lay.eps]
        J = reset_jacobian(x, lay)
        P = J @ P @ J.T
        return 0.5 * (P + P.T)

    def _restart_fine(self, m1: FloatArray | None) -> None:
        """End the acquisition (stage 1) and start the fine alignment (stage 2).

        The most probable hypothesis of the bank is fed back into the mechanisation
        (attitude, velocity, latitude). In stage 1 the heading error is large and the
        Gaussian approximation is poor; what it leaves in the weakly observable
        directions (accelerometer bias against level tilt, flexure, gyro drift) is not
        trustworthy. So those estimates are discarded (back to their priors,
        uncorrelated, in the slave-velocity form ``dv = dV - M xi``) and the level
        variance is increased by ``relevel_sigma^2``: stage 2, quasi-linear, splits
        tilt and bias afresh. Stage 2 is a single UKF with the same model.
        """
        lay, sd = self._layout, self._sd
        n = lay.n
        x = self._bank.particles[self._best].copy()
        x[lay.nabla] = 0.0  # discarded: not fed back
        x[lay.eps] = 0.0
        P = self._feedback(x, self._bank.particle_P[self._best], m1)
        S_inv = np.eye(n)
        if lay.flexure:
            S_inv[lay.dv, lay.xi] = -m1
        P = S_inv @ P @ S_inv.T
        P0 = self._tune.P0(lay, float(sd.lat))
        blocks = [lay.nabla, lay.eps] + ([lay.xi] if lay.flexure else [])
        for blk in blocks:
            P[blk, :] = 0.0
            P[:, blk] = 0.0
            P[blk, blk] = P0[blk, blk]
        P[4, 4] += self.relevel_sigma**2
        P[5, 5] += self.relevel_sigma**2
        if lay.flexure:
            S = np.eye(n)
            S[lay.dv, lay.xi] = m1
            P = S @ P @ S.T
        ukf = UnscentedKalmanFilter(
            n,
            3,
            self._fx,
            self._hx,
            self._make_points(),
            residual_x=angle_residual_fn([lay.heading]),
            x_mean_fn=angle_mean_fn([lay.heading]),
        )
        ukf.x = np.zeros(n)
        ukf.P = 0.5 * (P + P.T)
        self._ukf = ukf
        self._bank = None
        self._x_show = ukf.x
        self._P_show = ukf.P
        self.stage = 2.0

    # ------------------------------------------------------------------ stepping
    def step(self, t: float, h: float) -> None:
        self._check_step(h)
        self._hist.appendleft(euler_to_dcm(np.asarray(self.rpy_master, dtype=float)))
        self._n += 1
        if self._sd is None:
            if len(self._hist) == self._hist.maxlen:
                self._start()
        else:
            self._sd.step(
                np.asarray(self.dtheta_s, dtype=float), np.asarray(self.dv_s, dtype=float), h
            )
            if self._n % self._k == 0:
                self._update()
        self._publish()

    def _publish(self) -> None:
        lay = self._layout
        if self._P_show is not self._P_cached:
            P = self._P_show
            self._P_cached = P
            self._P_att = P[lay.att, lay.att].copy()
            self._P_att_inv = np.linalg.inv(self._P_att)
            self.accel_bias_sigma = np.sqrt(np.diag(P[lay.nabla, lay.nabla]))
            self.gyro_drift_sigma = np.sqrt(np.diag(P[lay.eps, lay.eps]))
            if lay.flexure:
                self.flex = self._x_show[7:10] / ARCMIN
                self.flex_sigma = np.sqrt(np.diag(P[7:10, 7:10])) / ARCMIN
            else:
                self.flex = np.zeros(3)
                self.flex_sigma = np.zeros(3)
            sd = self._sd
            self.accel_bias = (sd.nabla if sd is not None else 0.0) + self._x_show[lay.nabla]
            self.gyro_drift = (sd.eps if sd is not None else 0.0) + self._x_show[lay.eps]
        if self._sd is None:
            c_est = self._hist[0]
        else:  # stage 1 runs open loop: apply the best hypothesis' attitude error
            c_est = self._sd.C
            if self.stage == 1.0:
                c_est = euler_to_dcm(self._x_show[lay.att]).T @ c_est
        c_m = euler_to_dcm(np.asarray(self.rpy_m_true, dtype=float))
        c_s = euler_to_dcm(np.asarray(self.rpy_s_true, dtype=float))
        rel_est = dcm_to_euler(c_m.T @ c_est)
        rel_true = dcm_to_euler(c_m.T @ c_s)
        self.rpy_err = wrap_pi(rel_est - rel_true) / ARCMIN
        B = euler_rate_matrix_inv(rel_est) @ c_m.T
        self.rpy_sigma = np.sqrt(np.clip(np.diag(B @ self._P_att @ B.T), 0.0, None)) / ARCMIN
        self.rel_rpy = dcm_to_euler(self._hist[0].T @ c_est)
        d = c_est @ c_s.T  # small-angle rotation vector of the error (exact for NEES use)
        e_n = 0.5 * np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]])
        self.nees = float(e_n @ self._P_att_inv @ e_n)
