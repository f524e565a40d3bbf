"""Error model of shipboard transfer alignment (seed 001): 19-state nonlinear model.

The filter block is :class:`cosim.alignment.transfer.TransferAlignment`; this module
holds what it estimates with: the state layout, the statistics, the nonlinear error
model over one filter period (the UKF's ``fx``), its measurement, the closed-loop
reset, and the small-error (linear) model of the covariance analysis
(:mod:`cosim.alignment.transfer_analysis`). Seed 001's nonlinear error model, eq.
(12)-(30), is rewritten in our frames (NED, FRD) below.

Frames and symbols (:mod:`models.conventions`)
----------------------------------------------
``n`` true NED frame at the master, ``n^`` the slave's computed NED frame, ``b`` master
body (FRD), ``s`` slave body (FRD). ``C_s_n`` true slave attitude, ``C^_s_n`` the slave
mechanisation's attitude, ``C_b_n`` master attitude (from the master INS). ``r_0`` the
nominal lever arm from master to slave in master axes, ``theta`` the deck flexure angle
(master axes, :mod:`models.blocks.deck_flexure`), ``R_0`` seed 001's lever-arm matrix
(:func:`models.blocks.lever_arm.r0_matrix`), ``Omega`` earth rate, ``L`` latitude.

Seed 001 works in ENU with a right-forward-up body; its heading is counter-clockwise.
Every equation below is written directly in NED/FRD (``T = [[0,1,0],[1,0,0],[0,0,-1]]``
maps one into the other, :data:`models.frames.T_NED_ENU`); where the paper's sign
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
The mechanisation (:data:`cosim.alignment.nav.MOVING_BASE`) integrates
``C^' = C^ [w~_is x] - [w^_in x] C^`` and ``v^' = C^ f~ - (2 w^_ie + w^_en) x v^ + g``
with the measured (bias-compensated) rate ``w~ = w_is + eps`` and specific force
``f~ = f_s + nabla``, where ``w_is`` and ``f_s`` are the slave's **true** rate and
specific force: they include the flexure rate and the
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.nav import AlignmentConfigError, Strapdown, euler_rate_matrix, nav_rates
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR, G0, OMEGA_IE
from cosim.models.conventions import (
    dcm_to_euler,
    euler_to_dcm,
    rotvec_to_dcm,
    skew,
)
from cosim.models.earth import R_M, R_N

FloatArray = NDArray[np.float64]

#: Seed 001's flexure damping rule ``beta = BETA_TAU / tau``.
BETA_TAU = 2.146

_I3 = np.eye(3)

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


class TransferConfigError(AlignmentConfigError):
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
        Flexure stationary sigmas [rad] (2 arcmin: our assumption for seed 001,
        docs/reproductions.md).
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
    m = np.empty((3, 6))
    m[:, :3] = c_b_n @ skew(omega_eb_b) @ R0
    m[:, 3:] = c_b_n @ R0
    return m


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
        w_ie, w_en = nav_rates(v, lat, height)
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

    def add(self, nav: Strapdown, h: float) -> None:
        """Add the integrator's last step (trapezoidal in attitude and velocity).

        Parameters
        ----------
        nav : Strapdown
            The mechanisation, just after :meth:`Strapdown.step`.
        h : float
            That step [s].
        """
        self.T += h
        self.dv_f += nav.dv_n
        self.c_int += 0.5 * h * (nav.C_prev + nav.C_s_n)
        self.v_int += 0.5 * h * (nav.v_prev + nav.v_n)
        self.w_in += nav.w_in * h
        self.cor += nav.cor * h


# ----------------------------------------------------------------------------- nonlinear model
def propagate(x: ArrayLike, sums: PeriodSums, layout: StateLayout) -> FloatArray:
    """Nonlinear error model over one filter period (the UKF's ``fx``), batched.

    The readable statement of the model and the fallback of its C twin
    ``transfer_propagate`` (``cosim/alignment/transfer_model.c``, the same formulas in the
    same order), which :func:`cosim.alignment.transfer_native.make_propagate` picks.

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
    nabla, eps_ = layout.nabla, layout.eps
    dl = x[..., 0]
    dV = x[..., 1:4]
    att = x[..., 4:7]
    nab = x[..., nabla]
    eps = x[..., eps_]
    if layout.flexure:
        xi = x[..., 7:13]
        dv0 = dV - xi @ sums.m0.T
    else:
        dv0 = dV
    lat_h = sums.lat
    rm = float(R_M(lat_h)) + sums.height
    rn = float(R_N(lat_h)) + sums.height
    cl, sl, tl = math.cos(lat_h), math.sin(lat_h), math.tan(lat_h)
    lat_t = lat_h - dl
    # the vectors below are filled column by column: the same elementwise operations as
    # stacking them, without the stacks (this function runs on every sigma point)
    vec = dl.shape + (3,)
    d_wie = np.empty(vec)
    d_wie[..., 0] = OMEGA_IE * (cl - np.cos(lat_t))
    d_wie[..., 1] = 0.0
    d_wie[..., 2] = OMEGA_IE * -(sl - np.sin(lat_t))
    v_mean_e = sums.v_int[1] / T if T > 0 else 0.0
    dv0_n, dv0_e = dv0[..., 0], dv0[..., 1]
    d_wen = np.empty(vec)
    d_wen[..., 0] = dv0_e / rn
    d_wen[..., 1] = -dv0_n / rm
    d_wen[..., 2] = -dv0_e * tl / rn - v_mean_e * dl / (rn * cl * cl)
    d_win = d_wie + d_wen
    E0 = euler_to_dcm(att)
    rot = (
        eps @ sums.c_int.T + (E0 @ sums.w_in) - sums.w_in - (E0 @ (d_win[..., :, None] * T))[..., 0]
    )
    E1 = rotvec_to_dcm(rot) @ E0
    EbT = 0.5 * np.swapaxes(E0 + E1, -1, -2)
    # cor x dv0 and (2 dw_ie + dw_en) x v_int, with the constant vectors' components
    c0, c1, c2 = sums.cor.tolist()
    s0, s1, s2 = sums.v_int.tolist()
    dv0_d = dv0[..., 2]
    w = 2.0 * d_wie + d_wen
    w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
    cc = np.empty(vec)
    cc[..., 0] = c1 * dv0_d - c2 * dv0_e
    cc[..., 1] = c2 * dv0_n - c0 * dv0_d
    cc[..., 2] = c0 * dv0_e - c1 * dv0_n
    cv = np.empty(vec)
    cv[..., 0] = w1 * s2 - w2 * s1
    cv[..., 1] = w2 * s0 - w0 * s2
    cv[..., 2] = w0 * s1 - w1 * s0
    dv1 = (
        dv0
        + sums.dv_f
        - EbT @ sums.dv_f
        + (EbT @ (nab @ sums.c_int.T)[..., :, None])[..., 0]
        - cc
        - cv
    )
    out[..., 0] = dl + 0.5 * (dv0_n + dv1[..., 0]) * T / rm
    out[..., 4:7] = dcm_to_euler(E1)
    out[..., nabla] = nab
    out[..., eps_] = eps
    if layout.flexure:
        xi1 = xi @ sums.phi_flex.T
        out[..., 7:13] = xi1
        out[..., 1:4] = dv1 + xi1 @ sums.m1.T
    else:
        out[..., 1:4] = dv1
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
    w_ie, w_en = nav_rates(v, lat, height)
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
    c0_t = c0.T
    rho = relative_rotvecs([c0_t @ c for c in c_hist[1:5]])
    if k >= 5:
        r1, r2, r3, r4 = rho
        s = 12.0 * h
        return np.array(
            [(-48.0 * r1[i] + 36.0 * r2[i] - 16.0 * r3[i] + 3.0 * r4[i]) / s for i in range(3)]
        )
    if k >= 3:
        r1, r2 = rho[:2]
        return np.array([(-4.0 * r1[i] + r2[i]) / (2.0 * h) for i in range(3)])
    return np.array([-r / h for r in rho[0]])


def relative_rotvecs(mats: list[FloatArray]) -> list[tuple[float, float, float]]:
    """Rotation vectors of a few DCMs: :func:`models.conventions.dcm_to_rotvec`, per matrix.

    The same arithmetic as the batched function (Shepperd's quaternion, normalised,
    then ``2 atan2(|q_v|, q_0) q_v / |q_v|``), bit for bit, in scalar operations around
    one ``np.arctan2`` call: for the master's rate from four attitudes the batched
    call's array bookkeeping costs ten times the arithmetic.

    Parameters
    ----------
    mats : list of ndarray, shape (3, 3)
        Orthonormal DCMs.

    Returns
    -------
    list of tuple of float
        One rotation vector [rad] per matrix (angle in [0, pi]).
    """
    quats = []
    for c in mats:
        (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = c.tolist()
        tr = c00 + c11 + c22
        cand = (1.0 + tr, 1.0 + 2.0 * c00 - tr, 1.0 + 2.0 * c11 - tr, 1.0 + 2.0 * c22 - tr)
        j = cand.index(max(cand))
        big = math.sqrt(max(cand[j], 0.0))
        d32, d13, d21 = c21 - c12, c02 - c20, c10 - c01
        s10, s20, s21 = c10 + c01, c20 + c02, c21 + c12
        if j == 0:
            q = (big, d32 / big, d13 / big, d21 / big)
        elif j == 1:
            q = (d32 / big, big, s10 / big, s20 / big)
        elif j == 2:
            q = (d13 / big, s10 / big, big, s21 / big)
        else:
            q = (d21 / big, s20 / big, s21 / big, big)
        q0, q1, q2, q3 = (0.5 * e for e in q)
        if q0 < 0.0:
            q0, q1, q2, q3 = -q0, -q1, -q2, -q3
        n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
        if q0 < 0.0:
            q0, q1, q2, q3 = -q0, -q1, -q2, -q3
        quats.append((q0, q1, q2, q3, math.sqrt(q1 * q1 + q2 * q2 + q3 * q3)))
    angles = (2.0 * np.arctan2([q[4] for q in quats], [q[0] for q in quats])).tolist()
    out = []
    for (q0, q1, q2, q3, sv), angle in zip(quats, angles, strict=True):
        f = 2.0 / q0 if sv < 1e-12 else angle / sv
        out.append((f * q1, f * q2, f * q3))
    return out
