"""Error model of the stationary self-alignment (seed 003): 10-state psi-angle KF.

Frames (``models.conventions``): ``n`` NED, ``b`` the base (FRD), ``t`` the table
(rotated by the encoder angle ``gamma`` about the base z axis), ``s`` the sensors
(``C_s_t`` from the table mounting)::

    C_s_n = C_b_n Rz(gamma) C_s_t,      C_t_n = C_b_n Rz(gamma)

Without a turntable ``gamma = 0`` and the mounting is zero, so ``s = t = b``.

The static-base psi-angle error model
-------------------------------------
The computed attitude is ``C^_s_n = (I - [psi x]) C_s_n`` (``psi`` = misalignment of
the computed navigation frame, NED), the computed velocity ``v^ = v + dv``. The
mechanisation (:data:`cosim.alignment.nav.STATIC_BASE`) is
``v^' = C^_s_n f~_s + g_n - 2 w_ie x v^`` and ``C^' = C^ [w~_is x] - [w_ie x] C^`` with
the measured ``f~ = f + nabla``, ``w~ = w + eps``. Subtracting the true equations and
keeping first-order terms, on a stationary base (``v = 0``, ``f_n = [0, 0, -g]``,
transport rate zero)::

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
at 45 deg, :func:`cosim.alignment.coarse.heading_limit`). Noise: ``w = [w_a (2), w_g
(3)]`` enters ``dv`` and ``psi`` directly (``G = [I_5; 0]``), ``Qc = diag(q_accel^2 I_2,
q_gyro^2 I_3)`` (seed 003's Q as densities, per second). Measurement:
``z = v^_NE = H x + n``, ``H = [I_2, 0]``, ``R = r_vel^2 I_2`` every ``kf_period``.

Discretisation in the block (every step ``h``): ``Phi = I + F h + (F h)^2 / 2``
(the chains ``dv <- psi <- eps`` need the second-order term at ``h = 0.1 s``),
``Qd = (Phi G Qc G^T Phi^T + G Qc G^T) h / 2``, ``F`` with ``C_t_n`` averaged over
the step. The covariance analysis (:func:`static_covariance`) is independent of it:
exact Van Loan discretisation of the same continuous model, on the one covariance
loop :func:`cosim.estimation.covariance.covariance_analysis`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.nav import AlignmentConfigError, AlignmentError
from cosim.estimation import van_loan
from cosim.estimation.covariance import (
    CovarianceBudget,
    CovarianceHistory,
    covariance_analysis,
)
from cosim.estimation.error_model import StepGrid, propagate
from cosim.models.constants import DEG, DEG_PER_HOUR, MICRO_G, OMEGA_IE
from cosim.models.conventions import euler_to_dcm_3
from cosim.models.earth import gravity

FloatArray = NDArray[np.float64]

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

    @classmethod
    def from_parameters(cls, p: Mapping[str, float]) -> FilterTuning:
        """The tuning of an alignment block from its parameter values.

        Parameters
        ----------
        p : mapping
            The block's parameters by FMI name (``p0_vel``, ``p0_att[1..3]``,
            ``p0_accel_bias``, ``p0_gyro_drift``, ``q_accel``, ``q_gyro``, ``r_vel``), in
            the units of the attributes.

        Returns
        -------
        FilterTuning
        """
        return cls(
            p0_vel=p["p0_vel"],
            p0_att=(float(p["p0_att[1]"]), float(p["p0_att[2]"]), float(p["p0_att[3]"])),
            p0_accel_bias=p["p0_accel_bias"],
            p0_gyro_drift=p["p0_gyro_drift"],
            q_accel=p["q_accel"],
            q_gyro=p["q_gyro"],
            r_vel=p["r_vel"],
        )

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


# ------------------------------------------------------------------ small helpers
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


def table_dcm(gamma: float) -> FloatArray:
    """``Rz(gamma)``: table to base for encoder angle ``gamma`` [rad], shape (3, 3).

    Parameters
    ----------
    gamma : float
        Table encoder angle, a right-handed turn about the base z axis (down) [rad].

    Returns
    -------
    ndarray, shape (3, 3)
        ``C_t_b`` (scalar math, like :func:`models.conventions.rot_z`).
    """
    c, s = math.cos(gamma), math.sin(gamma)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


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
        Transition matrix and process-noise covariance of the step.
    """
    A = F * h
    Phi = np.eye(F.shape[0]) + A + 0.5 * (A @ A)
    Qd = 0.5 * h * (Phi @ Gq @ Phi.T + Gq)
    return Phi, Qd


# ------------------------------------------------------------------ covariance analysis
@dataclass(frozen=True)
class _TableModel:
    """The steps and error model of the analysis and of the budget (one definition).

    ``n`` steps of ``dt``, an update after every ``k_upd``-th step, the base attitude
    ``c_b_n`` (3, 3) and the encoder angle ``gammas`` [rad] at each step's midpoint,
    shape (n,).
    """

    n: int
    k_upd: int
    c_b_n: FloatArray
    gammas: FloatArray
    lat: float
    h: float
    coriolis: bool

    def key(self, i: int) -> float:
        """Cache key of step ``i``: its encoder angle modulo 2 pi, rounded.

        F depends on the encoder angle only through Rz(gamma), and reversing or
        continuous profiles revisit the same angles.
        """
        return round(float(self.gammas[i]) % (2.0 * math.pi), 12)

    def F(self, i: int) -> FloatArray:
        """Continuous error model at step ``i``'s midpoint, shape (10, 10)."""
        return error_model(self.c_b_n @ table_dcm(self.gammas[i]), self.lat, self.h, self.coriolis)


def _table_model(
    t_end: float,
    lat: float,
    h: float,
    dt: float,
    kf_period: float,
    angle: Callable[[FloatArray], FloatArray] | None,
    base_rpy: ArrayLike,
    coriolis: bool,
) -> _TableModel:
    """Check the steps and build :class:`_TableModel` (arguments of :func:`static_covariance`)."""
    n = int(round(t_end / dt))
    k_upd = int(round(kf_period / dt))
    if n < 1 or abs(n * dt - t_end) > 1e-9 * max(1.0, t_end):
        raise AlignmentConfigError(f"t_end = {t_end} s is not a whole number of dt = {dt} s")
    if k_upd < 1 or abs(k_upd * dt - kf_period) > 1e-9 * kf_period:
        raise AlignmentConfigError(f"kf_period = {kf_period} s is not a multiple of dt = {dt} s")
    c_b_n = euler_to_dcm_3(base_rpy)
    mid = (np.arange(n) + 0.5) * dt
    gammas = np.zeros(n) if angle is None else np.asarray(angle(mid), dtype=float)
    return _TableModel(n, k_upd, c_b_n, gammas, lat, h, coriolis)


def static_covariance(
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
    ``kf_period`` the zero-velocity update follows (the estimators' Joseph update).

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
        Times after the start of fine alignment (0 first), states :data:`STATES`.

    Raises
    ------
    AlignmentConfigError
        When the steps do not fit.
    """
    m = _table_model(t_end, lat, h, dt, kf_period, angle, base_rpy, coriolis)
    G = noise_input()
    Qc = tuning.Qc()
    update = (measurement_matrix(), tuning.R())
    cache: dict[float, tuple[FloatArray, FloatArray]] = {}  # by encoder angle

    def transition(i: int) -> tuple[FloatArray, FloatArray]:
        key = m.key(i)
        if key not in cache:
            cache[key] = van_loan(m.F(i), G, Qc, dt)
        return cache[key]

    return covariance_analysis(
        tuning.P0(),
        m.n,
        dt,
        transition,
        lambda i: update if (i + 1) % m.k_upd == 0 else None,
        record_every=record_every,
        names=STATES,
    )


# ------------------------------------------------------------------ error budget
def static_sources(
    tuning: FilterTuning, C_t_n: ArrayLike, nav_axes: bool = True
) -> dict[str, FloatArray]:
    """The initial covariance of :meth:`FilterTuning.P0` split into independent sources.

    The sensor errors' blocks are ``sigma^2 I`` (isotropic), so any orthonormal basis
    splits them exactly: with ``nav_axes`` the gyro drift is split along the
    navigation axes (``eps_N, eps_E, eps_D``: the basis vectors ``C_t_n^T e_k`` of the
    table frame) and the accelerometer bias along north and east of the table's
    heading; otherwise along the table axes x, y (z).

    Parameters
    ----------
    tuning : FilterTuning
        P0 of the filter.
    C_t_n : array_like, shape (3, 3)
        Table (sensor carrier) to NED at the start.
    nav_axes : bool
        Split the sensor errors along north/east/down (a fixed base) or the table axes.

    Returns
    -------
    dict
        Source name -> its part of ``P0``, shape (10, 10) [SI^2]; they sum to ``P0``.
    """
    P0 = tuning.P0()
    c = np.asarray(C_t_n, dtype=float)
    out: dict[str, FloatArray] = {}

    def block(sl: slice) -> FloatArray:
        part = np.zeros_like(P0)
        part[sl, sl] = P0[sl, sl]
        return part

    out["initial velocity error"] = block(slice(0, 2))
    out["initial misalignment"] = block(slice(2, 5))
    yaw = math.atan2(c[1, 0], c[0, 0])
    cy, sy = math.cos(yaw), math.sin(yaw)
    acc = {"N": (cy, -sy), "E": (sy, cy)} if nav_axes else {"x": (1.0, 0.0), "y": (0.0, 1.0)}
    for axis, w in acc.items():
        part = np.zeros_like(P0)
        part[5:7, 5:7] = tuning.p0_accel_bias**2 * np.outer(w, w)
        out[f"accelerometer bias {axis}"] = part
    gyro = (
        dict(zip("NED", c, strict=True)) if nav_axes else dict(zip("xyz", np.eye(3), strict=True))
    )
    for axis, w in gyro.items():
        part = np.zeros_like(P0)
        part[7:10, 7:10] = tuning.p0_gyro_drift**2 * np.outer(w, w)
        out[f"gyro drift {axis}"] = part
    return out


def static_budget(
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
) -> CovarianceBudget:
    """:func:`static_covariance` split by error source (the same total, to rounding).

    Sources: the initial velocity error and misalignment, the accelerometer bias and
    gyro drift per axis (:func:`static_sources`: navigation axes without a table,
    table axes with one), the accelerometer and gyro white noise, the zero-velocity
    measurement noise.

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
        Encoder angle ``gamma(t)`` [rad] for an array of times [s]; None: no table.
    base_rpy : array_like, shape (3,)
        Base attitude [rad].
    coriolis : bool
        Include the Coriolis terms.
    record_every : int
        Keep every k-th step.

    Returns
    -------
    CovarianceBudget
        Times after the start of fine alignment, states :data:`STATES`.

    Raises
    ------
    AlignmentConfigError
        When the steps do not fit.
    """
    lines = static_lines(
        t_end,
        tuning=tuning,
        lat=lat,
        h=h,
        dt=dt,
        kf_period=kf_period,
        angle=angle,
        base_rpy=base_rpy,
        coriolis=coriolis,
        record_every=record_every,
    )
    return propagate(lines)


@dataclass(frozen=True)
class StaticLines:
    """The 10-state filter's error model split into budget lines (:func:`static_lines`).

    The numerical half of :class:`cosim.estimation.error_model.LinearErrorModel`
    (``grid``, ``names``, ``initial_covariance``, ``dynamics``, ``step_key``,
    ``measurement``); :mod:`cosim.alignment.error_models` adds the scenario's half.

    Attributes
    ----------
    model : object
        Steps, base attitude and table angles (this module's table model).
    grid : StepGrid
        Steps of ``dt``, rows kept every ``record_every`` steps and at 0.
    P0_parts : dict
        :func:`static_sources` of the tuning.
    Qc_parts : dict
        Accelerometer and gyro white noise, each (5, 5) [SI^2 s].
    H : ndarray, shape (2, 10)
        Zero-velocity measurement.
    R : dict
        The measurement noise, (2, 2) [m^2/s^2].
    names : tuple of str
        :data:`STATES`.
    """

    model: _TableModel
    grid: StepGrid
    P0_parts: dict[str, FloatArray]
    Qc_parts: dict[str, FloatArray]
    H: FloatArray
    R: dict[str, FloatArray]
    names: tuple[str, ...] = STATES

    def initial_covariance(self) -> dict[str, FloatArray]:
        """P0 by line, each (10, 10) [SI^2]."""
        return self.P0_parts

    def dynamics(self, k: int) -> tuple[FloatArray, FloatArray, dict[str, FloatArray]]:
        """``F`` at step ``k``'s midpoint (10, 10), ``G`` (10, 5), ``Qc`` by line.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return self.model.F(k), noise_input(), self.Qc_parts

    def step_key(self, k: int) -> float:
        """The encoder angle of step ``k`` (its encoder angle, rounded).

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return self.model.key(k)

    def measurement(self, k: int) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """The zero-velocity update after every ``kf_period``, else None.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return (self.H, self.R) if (k + 1) % self.model.k_upd == 0 else None


def static_lines(
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
) -> StaticLines:
    """The budget lines of :func:`static_budget` (same arguments), not yet propagated.

    Parameters
    ----------
    t_end : float
        Duration [s] (a multiple of ``dt``).
    tuning : FilterTuning
        P0, Q, R.
    lat, h : float
        Latitude [rad], height [m].
    dt : float
        Propagation step [s].
    kf_period : float
        Measurement period [s].
    angle : callable, optional
        Encoder angle ``gamma(t)`` [rad]; None: no table.
    base_rpy : array_like, shape (3,)
        Base attitude [rad].
    coriolis : bool
        Include the Coriolis terms.
    record_every : int
        Keep every k-th step.

    Returns
    -------
    StaticLines
    """
    m = _table_model(t_end, lat, h, dt, kf_period, angle, base_rpy, coriolis)
    q = np.diag(tuning.Qc())
    Qc_parts = {
        "accelerometer white noise": np.diag(np.where(np.arange(5) < 2, q, 0.0)),
        "gyro white noise": np.diag(np.where(np.arange(5) >= 2, q, 0.0)),
    }
    R = {"measurement noise (zero velocity)": tuning.R()}
    gamma0 = 0.0 if angle is None else float(np.asarray(angle(np.zeros(1)), dtype=float)[0])
    P0_parts = static_sources(tuning, m.c_b_n @ table_dcm(gamma0), nav_axes=angle is None)
    grid = StepGrid(dt, m.n, record_every)
    return StaticLines(m, grid, P0_parts, Qc_parts, measurement_matrix(), R)
