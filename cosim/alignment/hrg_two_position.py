r"""Two-position self-alignment of a gimballed HRG platform with a large azimuth error (seed 000).

Frames and symbols
------------------
ENU geographic frame ``n``; platform frame ``p`` (x, y level, z up, azimuth ``A``
counter-clockwise from ENU), as in :mod:`models.hrg_platform`. ``L`` latitude,
``Omega`` earth rate, ``Oc = Omega cos L``, ``Os = Omega sin L``, ``g`` gravity.
Level misalignments ``theta_E``, ``theta_N`` are small rotations about geographic
east and north; the platform azimuth ``A`` is not small. Complex shorthand for
horizontal vectors: ``u = theta_E + i theta_N``, ``b = b_E + i b_N``.

1. Platform error dynamics (seed 000 eq. 4-5, rederived)
---------------------------------------------------------
After coarse levelling the level gimbal loops are opened, so the level axes stay
fixed in inertial space; the azimuth loop is torqued with ``Os`` so the azimuth
follows the earth. With the gyro errors ``eps`` (platform axes) the servo turns the
platform by ``-eps``; in geographic axes, with the full large-azimuth matrix
``C_p_n = exp([phi x]) Rz(A)`` and linearised only in the tilts ``phi``::

    theta_E' =  Os theta_N + d_E                 d = [d_E, d_N] = -Rz(A) [eps_x, eps_y]
    theta_N' = -Os theta_E - Oc + d_N            (drift rates in geographic axes)
    A'       = -eps_z                            (azimuth drift D_A, unobserved)

i.e. ``u' = -i Os u + b``, ``b = d_E + i (d_N - Oc)``: the released platform tilts
about north at the earth rate (``Oc t``, 35' in 200 s at 45 deg) and the gyro drifts
enter rotated by the large azimuth. This is eq. (5) with ``T_ep`` replaced by the
exact rotation; the paper's small-angle ``T_ep`` (eq. 4) would put ``theta_A Oc``
where ``Oc sin(theta_A)`` belongs. Solution from the start ``t = 0`` of a position::

    u(t) = exp(-i Os t) u0 + b e1(t),       e1(t) = (1 - exp(-i Os t)) / (i Os)     (eq. 10)

2. Accelerometer outputs of the tilted platform (eq. 11-13)
-----------------------------------------------------------
``f_p = C_p_n^T [0, 0, g]`` gives, to first order in the tilts,
``f_x = -g Im(u e^{-iA})``, ``f_y = g Re(u e^{-iA})`` (``A = 0``: ``f_x = -g theta_N``,
``f_y = g theta_E``): the large azimuth mixes north and east. Integrating over a
filter period ``[t0, t1]`` (what the accelerometer pulses deliver)::

    dv_x + i ... :  W = (u0 E0 + b E1) e^{-iA},   dv = g [-Im W, Re W] + bias (t1 - t0) + noise
    E0 = int exp(-i Os s) ds,   E1 = int e1(s) ds           (closed form, power series)

The leading terms, ``-g theta_E0 t - g D'_E0 t^2 / 2`` and cyclically, are those of the
paper's eq. (12)/(13) at ``A = 0``; its third-order terms are garbled (not even
dimensionally consistent) and are replaced here by the exact integrals.

3. What one position observes (eq. 14-15)
-----------------------------------------
``W`` is linear in ``p = u0 e^{-iA}`` (initial tilt in platform axes) and
``q = b e^{-iA}`` (tilt rate in platform axes): the paper's 4 states
``[theta_N0, theta_E0, D'_N0, D'_E0]`` are ``p`` and ``q`` in the (nominal) platform
axes, and that model is *linear*. Turning ``A`` by ``delta`` and ``b`` by
``-delta`` changes nothing, so only ``|b| ~ Oc - d_N`` and the direction of ``q``
are observable: the azimuth is known up to ``delta = atan2(-d_E, Oc - d_N) ~ -d_E/Oc``
(eq. 15: the east drift and the azimuth cannot be separated; 0.1 deg/h gives 32').
The accelerometer bias adds ``-bias / g`` to the tilts (1e-5 g: 0.03').

4. Nonlinear state (our design, since the azimuth must be carried explicitly)
-----------------------------------------------------------------------------
Per position the filter state is::

    x = [theta_N0, theta_E0, D_N, psi]

``psi = A + delta`` is the *apparent* azimuth (the azimuth with the unobservable
east drift folded in; it replaces the paper's ``D'_E0 = D_E + theta_A Oc - ...``,
which is the azimuth in disguise) and ``D_N = Oc - |b|`` the apparent north drift
rate (the deviation of the tilt rate from the earth rate, what eq. 14 gives). The
measurement ``dv = h(x)`` with ``b = i (D_N - Oc)`` is nonlinear (sin/cos) in ``psi``.
It also has a mirror solution ``psi + pi``, ``D_N = 2 Oc``, ``theta -> -theta``
(the earth-rate tilt explained as the opposite tilt of a platform turned round); only
the prior on ``D_N`` (0.2 deg/h against 2 Oc = 21 deg/h) excludes it. An EKF started
far from the azimuth falls into it; the unscented particle filter does not.

Priors: the paper's ``P0`` for the tilts (3') and the drift (0.2 deg/h), and for the
azimuth (which the paper does not give) the variance of an unknown azimuth,
``(pi / sqrt 3)^2`` (uniform on the circle) by default.

5. Two positions (eq. 16-21)
----------------------------
After ``index_angle`` (90 deg) of indexing the same gyros point elsewhere: with drifts
constant in platform axes (the "equal regular drift" pair of eq. 3),
``d^(2) = Rz(90) d^(1)``: ``d_E2 = -d_N1``, ``d_N2 = d_E1``. Each position's
``D_N`` therefore gives the other position's east drift:
``(d_E1, d_N1)`` solve ``Oc - D_N1 = |(d_E1, d_N1 - Oc)|`` and
``Oc - D_N2 = |(-d_N1, d_E1 - Oc)|`` (fixed point, contraction ``|d| / Oc``), then::

    (theta_AP)_1 = psi_1 - delta(d_E1, d_N1)                     eq. (18)-(19)
    (theta_AP)_2 = psi_2 - delta(-d_N1, d_E1) - index_angle      eq. (16)-(17), in position 1
    theta_AP = circular mean of the two                          eq. (20)
    [D_E, D_N] = -Rz(theta_AP)^T [d_E1, d_N1]                    (x and y gyro drifts, eq. 14-15)
    H_E = (D_E)_2 - (D_E)_1                                      eq. (21)

with ``(D_E)_1`` the drift of the direction that points east at position 1 from
``psi_1`` and ``theta_AP`` (eq. 15), ``(D_E)_2`` the same direction's drift measured
at position 2, where it points north (eq. 14). ``H_E`` is zero up to noise when the
drifts are equal in both positions; a heading-dependent ("regular") drift ``Delta`` of
that direction shows in it as ``Delta / 2``: eq. (20) averages two azimuths of which
only one is corrected with the changed drift, so it shares the inconsistency.

6. Filters (``method``)
-----------------------
- 0 **EKF** on ``x`` (analytic Jacobian, Joseph update).
- 1 **UPF**: :class:`~cosim.estimation.UnscentedParticleFilter`, a UKF per particle,
  ``n_particles`` (200) vectorised, systematic resampling, ``rng`` from ``seed``.
  The states are random constants (Q = 0), for which the exact "full" importance weight
  collapses (see the estimators' notes; sampling with roughening also failed here,
  ending in the mirror solution or collapsing), so we use ``proposal="mean"``: every
  particle moves to its UKF posterior mean and is weighted by the predictive likelihood
  of the innovation (a bank of UKFs, exact Gaussian-sum bookkeeping). The particles are
  drawn from the prior with the azimuth stratified (systematic sampling with the
  ``rng`` offset) over the circle, or over +-4 sigma of a Gaussian azimuth prior, and
  each carries the prior covariance with the azimuth variance narrowed to
  ``(kernel x spacing)^2``. Systematic resampling when the effective sample size falls
  below ``resample`` x N, 0.1 by default: with a deterministic proposal the copies of a
  resampled particle stay identical, so every resampling loses diversity for good; at
  0.5 N (or 0.25 N) one run in 41 kept only components 15-40' off after the first
  20 s and ended 4' off, at 0.1 N none did (the first resampling, at ~3 s, still
  discards the far side of the circle).
- 2 **KF** (reference, not in the paper): the linear platform-frame model (``p``, ``q``
  above, the paper's eq. 13 taken literally) and the exact ``psi = -arg(i q)``,
  ``D_N = Oc - |q|`` afterwards; its prior on ``q`` is isotropic with ``E|q|^2 = Oc^2``.

Position 2 starts from position 1: tilts propagated over the gap and rotated by the
expected change of ``delta``, with the level prior ``sigma_theta0`` added (the bias
turns with the platform, the drift turns during the move: without it position 2
inherits a 0.1' tilt bias and a 0.006 deg/h drift bias);
``psi_2 = psi_1 + index_angle + D_N1 / Oc`` with the variance of ``psi_1``, of the
unknown east drift (``sigma_drift / Oc``) and of the indexing error; ``D_N2`` from the
drift prior. The two positions are then treated as
independent in eq. 16-20 (the position-2 prior is ~100 times wider than its posterior).

Measurement and noise: the filter period ``period`` (1 s) sums the accelerometer's
velocity increments; ``R = N^2 period + q^2 / 6`` per axis (white-noise density ``N``,
and the difference of two uniform rounding errors of the pulse count, quantum
``q``). We use the increments rather than the cumulative ``v(t)`` of eq. (12): the
cumulative velocity's noise is a random walk, not the white noise eq. (22) assumes.

Garbled or missing in the paper, kept as parameters here: the azimuth prior
(``sigma_azimuth``), the measurement noise (``accel_noise``, ``dv_quantum``), the
filter period, the UPF proposal and initialisation (``kernel``), the indexing accuracy
(``sigma_index``), the convergence criterion (``conv_band`` on 3 sigma).
Neglected: the azimuth drift ``D_A`` within a position (0.67' per 200 s at 0.2 deg/h),
the slow rotation of the bias-equivalent tilt (``Os t``), the half-step delay of the
accelerometer's zero-order hold (``Oc h / 2``, 0.009' at h = 0.1 s).
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cosim.estimation import (
    ExtendedKalmanFilter,
    KalmanFilter,
    MerweScaledSigmaPoints,
    UnscentedParticleFilter,
    angle_mean_fn,
    angle_residual_fn,
)
from models.block import Block, input_, output, parameter
from models.constants import OMEGA_IE
from models.conventions import wrap_angle

__all__ = [
    "AlignmentSequenceError",
    "HrgTwoPositionAlignment",
    "PositionFilter",
    "TwoPositionAligner",
    "TwoPositionSolution",
    "apparent_azimuth",
    "combine_positions",
    "dv_coefficients",
    "predict_dv",
    "propagate_tilt",
]

ARCMIN = math.pi / 180.0 / 60.0
DEG_H = math.pi / 180.0 / 3600.0
_UNIFORM_SIGMA = math.pi / math.sqrt(3.0)  # std of a uniform angle on the circle [rad]
_PSI = 3  # index of the azimuth in the state
METHODS = {0: "EKF", 1: "UPF", 2: "KF"}


class AlignmentSequenceError(RuntimeError):
    """The platform status does not follow position 1 -> indexing -> position 2."""


# ----------------------------------------------------------------------------------------
# Measurement model
# ----------------------------------------------------------------------------------------
def _series_e1_e2(t: float, w: float) -> tuple[complex, complex]:
    """``e1(t) = int_0^t exp(-i w s) ds`` and ``e2(t) = int_0^t e1(s) ds`` by power series.

    ``e1 = sum_k (-i w)^k t^(k+1) / (k+1)!``, ``e2 = sum_k (-i w)^k t^(k+2) / (k+2)!``:
    no cancellation for small ``w t`` (the closed forms lose ``1 / (w t)`` digits).
    """
    z = -1j * w * t
    if abs(z) > 4.0:  # long runs: the closed forms are accurate there
        e1 = (1.0 - cmath.exp(z)) / (1j * w)
        return e1, (t - e1) / (1j * w)
    term1, term2 = complex(t), complex(0.5 * t * t)
    e1, e2 = term1, term2
    for k in range(1, 40):
        term1 *= z / (k + 1)
        term2 *= z / (k + 2)
        e1 += term1
        e2 += term2
        if abs(term1) <= 1e-18 * abs(e1) and abs(term2) <= 1e-18 * abs(e2):
            break
    return e1, e2


def dv_coefficients(t0: float, t1: float, lat: float) -> tuple[complex, complex]:
    """Coefficients of the velocity increment over ``[t0, t1]`` (times from the position start).

    Parameters
    ----------
    t0, t1 : float
        Window [s], ``t1 > t0 >= 0``.
    lat : float
        Latitude [rad].

    Returns
    -------
    E0, E1 : complex
        ``E0 = int exp(-i Os s) ds`` and ``E1 = int e1(s) ds`` over the window [s, s^2],
        computed as ``E0 = exp(-i Os t0) e1(tau)``, ``E1 = tau e1(t0) + exp(-i Os t0) e2(tau)``
        (``tau = t1 - t0``), which are exact and free of cancellation.
    """
    w = OMEGA_IE * math.sin(lat)
    tau = t1 - t0
    if w == 0.0:
        return complex(tau), complex(tau * t0 + 0.5 * tau * tau)
    rot = cmath.exp(-1j * w * t0)
    e1_tau, e2_tau = _series_e1_e2(tau, w)
    e1_t0, _ = _series_e1_e2(t0, w)
    return rot * e1_tau, tau * e1_t0 + rot * e2_tau


def predict_dv(x: np.ndarray, E0: complex, E1: complex, lat: float, g: float) -> np.ndarray:
    """Velocity increment along the platform x, y axes predicted from the polar state.

    Parameters
    ----------
    x : ndarray, shape (..., 4)
        ``[theta_N0, theta_E0, D_N, psi]`` [rad, rad, rad/s, rad].
    E0, E1 : complex
        From :func:`dv_coefficients`.
    lat : float
        Latitude [rad].
    g : float
        Gravity [m/s^2].

    Returns
    -------
    ndarray, shape (..., 2)
        ``g [-Im W, Re W]`` with ``W = (u0 E0 + i (D_N - Oc) E1) exp(-i psi)`` [m/s].
    """
    oc = OMEGA_IE * math.cos(lat)
    u_r, u_i = x[..., 1], x[..., 0]
    br = x[..., 2] - oc  # b = i br
    # V = u0 E0 + i br E1, componentwise
    v_r = u_r * E0.real - u_i * E0.imag - br * E1.imag
    v_i = u_r * E0.imag + u_i * E0.real + br * E1.real
    c, s = np.cos(x[..., _PSI]), np.sin(x[..., _PSI])
    w_r = v_r * c + v_i * s
    w_i = v_i * c - v_r * s
    out = np.empty(x.shape[:-1] + (2,))
    out[..., 0] = -g * w_i
    out[..., 1] = g * w_r
    return out


def dv_jacobian(x: np.ndarray, E0: complex, E1: complex, lat: float, g: float) -> np.ndarray:
    """Jacobian of :func:`predict_dv` with respect to the state, shape (2, 4).

    Parameters
    ----------
    x : ndarray, shape (4,)
        ``[theta_N0, theta_E0, D_N, psi]`` [rad, rad, rad/s, rad] (one state, not a batch).
    E0, E1 : complex
        From :func:`dv_coefficients` [s, s^2].
    lat : float
        Latitude [rad].
    g : float
        Gravity [m/s^2].

    Returns
    -------
    ndarray, shape (2, 4)
        ``d dv / d x``: rows platform x, y [m/s per unit of each state].
    """
    oc = OMEGA_IE * math.cos(lat)
    r = cmath.exp(-1j * float(x[_PSI]))
    v = (complex(x[1], x[0]) * E0 + 1j * (float(x[2]) - oc) * E1) * r
    cols = (1j * E0 * r, E0 * r, 1j * E1 * r, -1j * v)
    return np.array([[-g * c.imag for c in cols], [g * c.real for c in cols]])


def propagate_tilt(u0: complex, d_n: float, t: float, lat: float) -> complex:
    """Tilt ``u(t) = exp(-i Os t) u0 + i (d_n - Oc) e1(t)`` of eq. (10) in the model frame.

    Parameters
    ----------
    u0 : complex
        ``theta_E0 + i theta_N0`` [rad].
    d_n : float
        Apparent north drift rate ``D_N`` [rad/s].
    t : float
        Time since the position start [s].
    lat : float
        Latitude [rad].

    Returns
    -------
    complex
        ``theta_E(t) + i theta_N(t)`` [rad].
    """
    w = OMEGA_IE * math.sin(lat)
    oc = OMEGA_IE * math.cos(lat)
    e1, _ = _series_e1_e2(t, w) if w != 0.0 else (complex(t), 0j)
    return cmath.exp(-1j * w * t) * u0 + 1j * (d_n - oc) * e1


def tilt_jacobian(x: np.ndarray, t: float, delta: float, lat: float) -> tuple[complex, np.ndarray]:
    """Geographic tilt at ``t`` from the polar state and its Jacobian (the map is linear).

    Parameters
    ----------
    x : ndarray, shape (4,)
        ``[theta_N0, theta_E0, D_N, psi]``.
    t : float
        Time since the position start [s].
    delta : float
        Rotation of the model frame from geographic (``psi - A``) [rad].
    lat : float
        Latitude [rad].

    Returns
    -------
    u : complex
        ``(theta_E + i theta_N)(t) = propagate_tilt(...) exp(-i delta)`` [rad].
    J : ndarray, shape (2, 3)
        ``d[theta_E, theta_N] / d[theta_N0, theta_E0, D_N]``.
    """
    w = OMEGA_IE * math.sin(lat)
    rot = cmath.exp(-1j * delta)
    e1 = _series_e1_e2(t, w)[0] if w != 0.0 else complex(t)
    decay = cmath.exp(-1j * w * t)
    u = propagate_tilt(complex(x[1], x[0]), float(x[2]), t, lat) * rot
    cols = (1j * decay * rot, decay * rot, 1j * e1 * rot)
    return u, np.array([[c.real for c in cols], [c.imag for c in cols]])


def apparent_azimuth(
    azimuth: float, drift_e: float, drift_n: float, lat: float
) -> tuple[float, float]:
    """The observable pair of one position: apparent azimuth and apparent north drift.

    Parameters
    ----------
    azimuth : float
        True platform azimuth A [rad].
    drift_e, drift_n : float
        Geographic drift rates ``d_E``, ``d_N`` of the platform tilt [rad/s]
        (``d = -Rz(A) eps``, HrgPlatform's ``drift_rate_n[1:2]``).
    lat : float
        Latitude [rad].

    Returns
    -------
    psi : float
        ``A + atan2(-d_E, Oc - d_N)`` wrapped to (-pi, pi] [rad].
    d_n_apparent : float
        ``Oc - |(d_E, d_N - Oc)|`` [rad/s].
    """
    oc = OMEGA_IE * math.cos(lat)
    delta = math.atan2(-drift_e, oc - drift_n)
    return float(wrap_angle(azimuth + delta)), oc - math.hypot(drift_e, oc - drift_n)


def _polar_to_linear(x: np.ndarray, lat: float) -> np.ndarray:
    """``[theta_N0, theta_E0, D_N, psi]`` -> ``[Re p, Im p, Re q, Im q]`` (platform axes)."""
    oc = OMEGA_IE * math.cos(lat)
    r = cmath.exp(-1j * float(x[_PSI]))
    p = complex(x[1], x[0]) * r
    q = 1j * (float(x[2]) - oc) * r
    return np.array([p.real, p.imag, q.real, q.imag])


def _linear_to_polar(y: np.ndarray, lat: float) -> np.ndarray:
    """Inverse of :func:`_polar_to_linear` (``psi = -arg(i q)``, ``D_N = Oc - |q|``)."""
    oc = OMEGA_IE * math.cos(lat)
    q = complex(y[2], y[3])
    psi = -cmath.phase(1j * q)
    u0 = complex(y[0], y[1]) * cmath.exp(1j * psi)
    return np.array([u0.imag, u0.real, oc - abs(q), psi])


def _numeric_jacobian(
    fn: Callable[[np.ndarray], np.ndarray],
    x: np.ndarray,
    steps: np.ndarray,
    angle_out: tuple[int, ...] = (),
) -> np.ndarray:
    """Central-difference Jacobian of ``fn`` at ``x`` with per-component steps.

    Parameters
    ----------
    fn : callable
        ``fn(x) -> (m,)``.
    x : ndarray, shape (n,)
        Point.
    steps : ndarray, shape (n,)
        Step per component (same units as ``x``).
    angle_out : tuple of int
        Output components that are angles: their differences are wrapped.

    Returns
    -------
    ndarray, shape (m, n)
    """
    cols = []
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = steps[k]
        d = np.asarray(fn(x + dx)) - np.asarray(fn(x - dx))
        for j in angle_out:
            d[j] = wrap_angle(d[j])
        cols.append(d / (2.0 * steps[k]))
    return np.array(cols).T


def _state_steps(P: np.ndarray) -> np.ndarray:
    """Finite-difference steps: a small fraction of each standard deviation (never zero)."""
    floor = np.array([1e-9, 1e-9, 1e-13, 1e-9])
    return np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(P), 0.0)), floor)


# ----------------------------------------------------------------------------------------
# One position
# ----------------------------------------------------------------------------------------
class PositionFilter:
    """One position's filter on the polar state ``[theta_N0, theta_E0, D_N, psi]``.

    Parameters
    ----------
    method : int
        0 EKF, 1 UPF, 2 KF (linear platform-frame model); see the module docstring.
    x0 : ndarray, shape (4,)
        Prior mean.
    P0 : ndarray, shape (4, 4)
        Prior covariance (for a uniform azimuth: ``P0[3, 3] >= (pi / sqrt 3)^2``).
    lat, g : float
        Latitude [rad], gravity [m/s^2].
    r_var : float
        Measurement noise variance per axis [(m/s)^2].
    rng : numpy.random.Generator
        Randomness of the UPF (stratification offset and resampling).
    n_particles : int
        UPF particles.
    kernel : float
        UPF: component azimuth std as a multiple of the particle spacing.
    alpha : float
        UKF sigma-point spread (Merwe ``alpha``; ``kappa = 0``, ``beta = 2``).
    resample : float
        UPF: resample when the effective sample size falls below ``resample`` x N.

    Attributes
    ----------
    x : ndarray, shape (4,)
        Estimate (azimuth wrapped to (-pi, pi]).
    P : ndarray, shape (4, 4)
        Covariance (UPF: mixture covariance; KF: linearised from the linear state).
    ess : float
        UPF effective sample size (1 for the Kalman filters).
    n_resamples : int
        UPF resampling steps so far (0 for the Kalman filters).
    """

    def __init__(
        self,
        method: int,
        x0: np.ndarray,
        P0: np.ndarray,
        lat: float,
        g: float,
        r_var: float,
        rng: np.random.Generator,
        n_particles: int = 200,
        kernel: float = 1.0,
        alpha: float = 1.0,
        resample: float = 0.1,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"method: expected one of {sorted(METHODS)}, got {method}")
        self.method = int(method)
        self.lat, self.g = float(lat), float(g)
        self.R = np.eye(2) * float(r_var)
        x0 = np.asarray(x0, dtype=float).copy()
        P0 = np.asarray(P0, dtype=float).copy()
        uniform = P0[_PSI, _PSI] >= _UNIFORM_SIGMA**2 * (1.0 - 1e-9)
        self.n_updates = 0
        if self.method == 0:
            self._f = ExtendedKalmanFilter(4, 2)
            self._f.x = x0
            self._f.P = P0
            self._f.R = self.R
        elif self.method == 2:
            self._f = KalmanFilter(4, 2)
            self._f.R = self.R
            oc = OMEGA_IE * math.cos(self.lat)
            if uniform:
                # Unknown direction: p and q isotropic, moment-matched (E|q|^2 = |b|^2).
                self._f.x = np.zeros(4)
                tilt_var = 0.5 * (P0[0, 0] + P0[1, 1]) + 0.5 * (x0[0] ** 2 + x0[1] ** 2)
                rate_var = 0.5 * ((oc - x0[2]) ** 2 + P0[2, 2])
                self._f.P = np.diag([tilt_var, tilt_var, rate_var, rate_var])
            else:
                J = _numeric_jacobian(lambda v: _polar_to_linear(v, self.lat), x0, _state_steps(P0))
                self._f.x = _polar_to_linear(x0, self.lat)
                self._f.P = J @ P0 @ J.T
        else:
            pts = MerweScaledSigmaPoints(4, alpha=alpha, beta=2.0, kappa=0.0)
            self._f = UnscentedParticleFilter(
                4,
                2,
                _identity,
                self._hx,
                pts,
                rng=rng,
                n_particles=int(n_particles),
                resample_threshold=float(resample) * int(n_particles),
                proposal="mean",
                residual_x=angle_residual_fn([_PSI]),
                x_mean_fn=angle_mean_fn([_PSI]),
            )
            self._f.R = self.R
            parts, cov, weights = azimuth_grid(x0, P0, int(n_particles), rng, uniform, kernel)
            self._f.set_particles(parts, cov, weights)
        self._refresh()

    def _hx(self, x: np.ndarray, E0: complex, E1: complex) -> np.ndarray:
        return predict_dv(x, E0, E1, self.lat, self.g)

    def update(self, dv: np.ndarray, t0: float, t1: float) -> None:
        """Process one velocity increment.

        Parameters
        ----------
        dv : ndarray, shape (2,)
            Velocity increment along the platform x, y axes over ``[t0, t1]`` [m/s].
        t0, t1 : float
            Window, seconds from the start of the position.
        """
        E0, E1 = dv_coefficients(t0, t1, self.lat)
        z = np.asarray(dv, dtype=float)
        if self.method == 0:
            f = self._f
            f.update(
                z,
                lambda x: predict_dv(x, E0, E1, self.lat, self.g),
                lambda x: dv_jacobian(x, E0, E1, self.lat, self.g),
            )
            x = f.x.copy()
            x[_PSI] = wrap_angle(x[_PSI])
            f.x = x
        elif self.method == 2:
            cols = (E0, 1j * E0, E1, 1j * E1)
            H = np.array([[-self.g * c.imag for c in cols], [self.g * c.real for c in cols]])
            self._f.update(z, H=H)
        else:
            self._f.step(z, t1 - t0, hx_args={"E0": E0, "E1": E1})
        self.n_updates += 1
        self._refresh()

    def _refresh(self) -> None:
        if self.method == 2:
            y, Py = self._f.x, self._f.P
            self.x = _linear_to_polar(y, self.lat)
            steps = np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(Py), 0.0)), 1e-13)
            J = _numeric_jacobian(lambda v: _linear_to_polar(v, self.lat), y, steps, (_PSI,))
            self.P = J @ Py @ J.T
            self.ess = 1.0
        elif self.method == 0:
            self.x, self.P, self.ess = self._f.x.copy(), self._f.P.copy(), 1.0
        else:
            self.x = self._f.x.copy()
            self.x[_PSI] = wrap_angle(self.x[_PSI])
            self.P = self._f.P
            self.ess = self._f.ess
        self.n_resamples = self._f.n_resamples if self.method == 1 else 0


def _identity(x: np.ndarray, dt: float) -> np.ndarray:
    """Random-constant states: the process model is the identity."""
    return x


def azimuth_grid(
    x0: np.ndarray,
    P0: np.ndarray,
    n: int,
    rng: np.random.Generator,
    uniform: bool,
    kernel: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian-sum prior for the UPF: azimuth stratified, the rest conditional Gaussian.

    Parameters
    ----------
    x0 : ndarray, shape (4,)
        Prior mean (azimuth last).
    P0 : ndarray, shape (4, 4)
        Prior covariance.
    n : int
        Number of particles.
    rng : numpy.random.Generator
        Draws the common stratification offset ``u ~ U(0, 1)``.
    uniform : bool
        Azimuth uniform on the circle (equal weights); else Gaussian, the grid spanning
        +-4 sigma with weights proportional to the prior density.
    kernel : float
        Component azimuth std = ``kernel`` x grid spacing.

    Returns
    -------
    particles : ndarray, shape (n, 4)
    cov : ndarray, shape (n, 4, 4)
    weights : ndarray, shape (n,)
    """
    u = rng.uniform()
    rest = slice(0, _PSI)
    if uniform:
        spacing = 2.0 * math.pi / n
        psi = x0[_PSI] - math.pi + (np.arange(n) + u) * spacing
        weights = np.full(n, 1.0 / n)
        sig = 0.0
    else:
        sig = math.sqrt(P0[_PSI, _PSI])
        spacing = 8.0 * sig / n
        dev = -4.0 * sig + (np.arange(n) + u) * spacing
        psi = x0[_PSI] + dev
        weights = np.exp(-0.5 * (dev / sig) ** 2)
        weights /= weights.sum()
    parts = np.tile(x0, (n, 1))
    cov = np.empty((n, 4, 4))
    c_rest = P0[rest, rest].copy()
    if not uniform and sig > 0.0:
        gain = P0[rest, _PSI] / P0[_PSI, _PSI]
        parts[:, rest] += np.outer(psi - x0[_PSI], gain)
        c_rest = c_rest - np.outer(gain, P0[_PSI, rest])
    parts[:, _PSI] = wrap_angle(psi)
    cov[:] = 0.0
    cov[:, rest, rest] = c_rest
    cov[:, _PSI, _PSI] = (kernel * spacing) ** 2
    return parts, cov, weights


# ----------------------------------------------------------------------------------------
# Two positions
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TwoPositionSolution:
    """Result of eq. (16)-(21) from the two positions' ``psi`` and ``D_N``.

    Attributes
    ----------
    azimuth_1, azimuth_2, azimuth_avg : float
        ``(theta_AP)_1``, ``(theta_AP)_2`` (referred to position 1) and their circular
        mean, eq. (19), (17), (20) [rad].
    sigma_1, sigma_2, sigma_avg : float
        Their 1-sigma [rad].
    delta_1, delta_2 : float
        Apparent-azimuth offsets ``psi_k - A_k`` [rad].
    drift_e1, drift_n1 : float
        Geographic drift rates at position 1 [rad/s].
    D_E, D_N : float
        Drifts of the platform x ("east") and y ("north") gyros [rad/s] (gyro sign:
        measured minus true rate).
    sigma_D_E, sigma_D_N : float
        Their 1-sigma [rad/s].
    H_E : float
        Eq. (21): drift of the direction east at position 1 measured at position 2 minus
        at position 1 [rad/s].
    """

    azimuth_1: float
    azimuth_2: float
    azimuth_avg: float
    sigma_1: float
    sigma_2: float
    sigma_avg: float
    delta_1: float
    delta_2: float
    drift_e1: float
    drift_n1: float
    D_E: float
    D_N: float
    sigma_D_E: float
    sigma_D_N: float
    H_E: float


def _solve(v: np.ndarray, index_angle: float, oc: float) -> np.ndarray:
    """Eq. (16)-(21) for ``v = [psi_1, D_N1, psi_2, D_N2]``; returns the outputs as a vector."""
    psi1, dn1p, psi2, dn2p = v
    rho1, rho2 = oc - dn1p, oc - dn2p
    d_e1, d_n1 = dn2p, dn1p  # first order: each position's D_N is the other's east drift
    for _ in range(4):  # fixed point, contraction ~ |d| / Oc ~ 0.02
        d_n1 = oc - math.sqrt(max(rho1 * rho1 - d_e1 * d_e1, 0.0))
        d_e1 = oc - math.sqrt(max(rho2 * rho2 - d_n1 * d_n1, 0.0))
    delta1 = math.atan2(-d_e1, oc - d_n1)
    delta2 = math.atan2(d_n1, oc - d_e1)  # d_E2 = -d_N1, d_N2 = d_E1
    a1 = float(wrap_angle(psi1 - delta1))
    a2 = float(wrap_angle(psi2 - delta2 - index_angle))
    avg = float(wrap_angle(a1 + 0.5 * float(wrap_angle(a2 - a1))))
    c, s = math.cos(avg), math.sin(avg)
    # eps = -Rz(A)^T d  (gyro drifts in platform axes)
    d_x = -(c * d_e1 + s * d_n1)
    d_y = -(-s * d_e1 + c * d_n1)
    # eq. (21): the direction east at position 1, from each position separately
    east_1 = -rho1 * math.sin(float(wrap_angle(psi1 - avg)))  # geographic east drift, pos 1
    north_2 = oc - rho2 * math.cos(float(wrap_angle(psi2 - avg - index_angle)))  # pos 2
    h_e = -(north_2 - east_1)  # gyro sign: drift = -tilt rate
    return np.array([a1, a2, avg, delta1, delta2, d_e1, d_n1, d_x, d_y, h_e])


def combine_positions(
    x1: np.ndarray, P1: np.ndarray, x2: np.ndarray, P2: np.ndarray, index_angle: float, lat: float
) -> TwoPositionSolution:
    """Two-position azimuth, drifts and regular drift (eq. 16-21) with linearised sigmas.

    Parameters
    ----------
    x1, x2 : ndarray, shape (4,)
        Position estimates ``[theta_N0, theta_E0, D_N, psi]``.
    P1, P2 : ndarray, shape (4, 4)
        Their covariances (the positions are taken as independent).
    index_angle : float
        Nominal indexing angle, position 2 minus position 1 azimuth [rad].
    lat : float
        Latitude [rad].

    Returns
    -------
    TwoPositionSolution
    """
    oc = OMEGA_IE * math.cos(lat)
    v = np.array([x1[_PSI], x1[2], x2[_PSI], x2[2]])
    cov = np.zeros((4, 4))
    sel = [_PSI, 2]
    cov[:2, :2] = P1[np.ix_(sel, sel)]
    cov[2:, 2:] = P2[np.ix_(sel, sel)]
    out = _solve(v, index_angle, oc)
    steps = np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(cov), 0.0)), [1e-9, 1e-13, 1e-9, 1e-13])
    J = _numeric_jacobian(lambda w: _solve(w, index_angle, oc), v, steps, (0, 1, 2, 3, 4))
    C = J @ cov @ J.T
    sd = np.sqrt(np.maximum(np.diag(C), 0.0))
    return TwoPositionSolution(
        azimuth_1=out[0],
        azimuth_2=out[1],
        azimuth_avg=out[2],
        sigma_1=sd[0],
        sigma_2=sd[1],
        sigma_avg=sd[2],
        delta_1=out[3],
        delta_2=out[4],
        drift_e1=out[5],
        drift_n1=out[6],
        D_E=out[7],
        D_N=out[8],
        sigma_D_E=sd[7],
        sigma_D_N=sd[8],
        H_E=out[9],
    )


def position2_prior(
    x1: np.ndarray,
    P1: np.ndarray,
    gap: float,
    index_angle: float,
    lat: float,
    sigma_drift: float,
    sigma_index: float,
    sigma_tilt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Prior of position 2 from position 1's estimate (see the module docstring).

    Parameters
    ----------
    x1, P1 : ndarray, shapes (4,), (4, 4)
        Position 1 estimate and covariance (its initial tilts refer to its own start).
    gap : float
        Time from the start of position 1 to the start of position 2 [s].
    index_angle : float
        Nominal indexing angle [rad].
    lat : float
        Latitude [rad].
    sigma_drift : float
        Prior std of a geographic drift rate (the unknown east drift, and ``D_N2``) [rad/s].
    sigma_index : float
        Std of the indexing error [rad].
    sigma_tilt : float
        Std added to each level misalignment for what the propagation leaves out [rad].

    Returns
    -------
    x2 : ndarray, shape (4,)
    P2 : ndarray, shape (4, 4)
    """
    oc = OMEGA_IE * math.cos(lat)

    def prior(v: np.ndarray) -> np.ndarray:
        th_n, th_e, dn, psi, d_e1, err = v
        # expected change of the apparent-azimuth offset between the positions
        change = math.atan2(dn, oc - d_e1) - math.atan2(-d_e1, oc - dn)
        u = propagate_tilt(complex(th_e, th_n), dn, gap, lat) * cmath.exp(1j * change)
        return np.array([u.imag, u.real, psi + index_angle + err + change])

    v = np.concatenate([x1, [0.0, 0.0]])
    cov = np.zeros((6, 6))
    cov[:4, :4] = P1
    cov[4, 4] = sigma_drift**2
    cov[5, 5] = sigma_index**2
    steps = np.concatenate([_state_steps(P1), [max(1e-3 * sigma_drift, 1e-13), 1e-9]])
    J = _numeric_jacobian(prior, v, steps, (2,))
    m = prior(v)
    C = J @ cov @ J.T
    x2 = np.array([m[0], m[1], 0.0, float(wrap_angle(m[2]))])
    P2 = np.zeros((4, 4))
    idx = [0, 1, _PSI]
    P2[np.ix_(idx, idx)] = C
    P2[2, 2] = sigma_drift**2
    # Unmodelled over the gap: the accelerometer bias turns with the platform (its
    # equivalent tilt changes by up to sqrt(2) bias / g), the drift vector turns during
    # the move, and the linearised rotation above. The propagated covariance alone is
    # tighter than these (0.05' against ~0.1'), and position 2 would inherit their bias;
    # the level prior of position 1 is added, which the data of position 2 overrule.
    P2[0, 0] += sigma_tilt**2
    P2[1, 1] += sigma_tilt**2
    return x2, P2


class TwoPositionAligner:
    """The alignment procedure without the block layer: positions, priors, eq. (16)-(21).

    Feed it the accelerometer's velocity increments and the platform status with
    :meth:`step`; read the results from its attributes.

    Parameters
    ----------
    method : int
        0 EKF, 1 UPF, 2 KF.
    lat, g : float
        Latitude [rad], gravity [m/s^2].
    period : float
        Filter period: increments are summed over this long [s].
    accel_noise : float
        Accelerometer white-noise density ``N`` [m/s/sqrt(s)].
    dv_quantum : float
        Velocity per pulse ``q`` [m/s] (0: no quantisation term).
    sigma_theta0, sigma_drift, sigma_azimuth : float
        Prior stds (3', 0.2 deg/h, unknown azimuth ``pi / sqrt 3``) [rad, rad/s, rad].
    azimuth0 : float
        Prior azimuth estimate [rad].
    index_angle, sigma_index : float
        Nominal indexing angle and its accuracy [rad].
    n_particles : int
        UPF particles.
    seed : int
        UPF random seed.
    kernel, alpha : float
        UPF component width (grid spacings) and sigma-point spread.
    resample : float
        UPF resampling threshold as a fraction of the particles.
    """

    def __init__(
        self,
        method: int = 1,
        lat: float = 45.0 * math.pi / 180.0,
        g: float = 9.7966,
        period: float = 1.0,
        accel_noise: float = 5e-6 * 9.80665,
        dv_quantum: float = 1e-4,
        sigma_theta0: float = 3.0 * ARCMIN,
        sigma_drift: float = 0.2 * DEG_H,
        sigma_azimuth: float = _UNIFORM_SIGMA,
        azimuth0: float = 0.0,
        index_angle: float = math.pi / 2.0,
        sigma_index: float = 6.0 * ARCMIN,
        n_particles: int = 200,
        seed: int = 0,
        kernel: float = 1.0,
        alpha: float = 1.0,
        resample: float = 0.1,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"method: expected 0 (EKF), 1 (UPF) or 2 (KF), got {method}")
        if not period > 0.0:
            raise ValueError(f"period: expected a positive filter period, got {period}")
        if not (accel_noise > 0.0 or dv_quantum > 0.0):
            raise ValueError("accel_noise and dv_quantum: expected at least one > 0, got both 0")
        if int(n_particles) < 1:
            raise ValueError(f"n_particles: expected >= 1, got {n_particles}")
        self.method, self.lat, self.g = int(method), float(lat), float(g)
        self.period = float(period)
        self.r_var = accel_noise**2 * self.period + dv_quantum**2 / 6.0
        self.sigma_drift = float(sigma_drift)
        self.index_angle, self.sigma_index = float(index_angle), float(sigma_index)
        self.n_particles, self.kernel, self.alpha = int(n_particles), float(kernel), float(alpha)
        self.resample = float(resample)
        self.rng = np.random.default_rng(int(seed))
        self.x0 = np.array([0.0, 0.0, 0.0, float(azimuth0)])
        self.P0 = np.diag(
            [
                sigma_theta0**2,
                sigma_theta0**2,
                sigma_drift**2,
                min(sigma_azimuth, _UNIFORM_SIGMA) ** 2,
            ]
        )
        self.filters: dict[int, PositionFilter] = {}
        self.starts: dict[int, float] = {}
        self.final: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.active = 0
        self.solution: TwoPositionSolution | None = None
        self._prev_status: float | None = None
        self._acc = np.zeros(2)
        self._acc_t0: float | None = None
        self._last_t = 0.0

    # ------------------------------------------------------------------ feeding
    def start(self, t: float, status: float) -> None:
        """Record the platform status at the start time ``t`` [s].

        Parameters
        ----------
        t : float
            Start time of the run [s].
        status : float
            Platform status at ``t``: 1 position 1, 0 indexing, 2 position 2.
        """
        self._prev_status = float(status)
        self._last_t = float(t)

    def step(self, t: float, h: float, dv_p: np.ndarray, status: float) -> bool:
        """Take the increment of one step ``[t, t + h]``.

        Parameters
        ----------
        t, h : float
            Step start and length [s].
        dv_p : ndarray, shape (2,) or (3,)
            Accelerometer velocity increment over the step, platform axes [m/s]
            (x, y used).
        status : float
            Platform status at ``t + h`` (1, 0, 2).

        Returns
        -------
        bool
            Whether a filter update happened in this step.

        Raises
        ------
        AlignmentSequenceError
            When position 2 data arrive before any position 1 data.
        """
        prev = self._prev_status if self._prev_status is not None else float(status)
        self._prev_status = float(status)
        self._last_t = t + h
        if not (prev == status and status in (1.0, 2.0)):
            self._acc[:] = 0.0
            self._acc_t0 = None
            return False
        pos = int(status)
        if pos != self.active:
            self._begin(pos, t)
        if self._acc_t0 is None:
            self._acc_t0 = t
            self._acc[:] = 0.0
        self._acc += np.asarray(dv_p, dtype=float)[:2]
        if t + h - self._acc_t0 < self.period - 1e-9 * self.period:
            return False
        t0 = self._acc_t0 - self.starts[pos]
        t1 = t + h - self.starts[pos]
        self.filters[pos].update(self._acc.copy(), t0, t1)
        self._acc[:] = 0.0
        self._acc_t0 = None
        if pos == 2:
            self._combine()
        return True

    def _begin(self, pos: int, t: float) -> None:
        if pos == 1 and self.active == 0:
            x0, P0 = self.x0, self.P0
        elif pos == 2 and self.active == 1:
            f1 = self.filters[1]
            self.final[1] = (f1.x.copy(), f1.P.copy())
            x0, P0 = position2_prior(
                f1.x,
                f1.P,
                t - self.starts[1],
                self.index_angle,
                self.lat,
                self.sigma_drift,
                self.sigma_index,
                math.sqrt(self.P0[0, 0]),
            )
        else:
            raise AlignmentSequenceError(
                f"platform status: expected position 1, indexing, then position 2, got "
                f"position {pos} after position {self.active} at t = {t:g} s"
            )
        self.active = pos
        self.starts[pos] = t
        self._acc_t0 = None
        self.filters[pos] = PositionFilter(
            self.method,
            x0,
            P0,
            self.lat,
            self.g,
            self.r_var,
            self.rng,
            self.n_particles,
            self.kernel,
            self.alpha,
            self.resample,
        )

    def _combine(self) -> None:
        x1, P1 = self.final[1]
        f2 = self.filters[2]
        self.solution = combine_positions(x1, P1, f2.x, f2.P, self.index_angle, self.lat)

    # ------------------------------------------------------------------ results
    @property
    def oc(self) -> float:
        """Horizontal earth rate ``Omega cos L`` [rad/s]."""
        return OMEGA_IE * math.cos(self.lat)

    def azimuth(self) -> tuple[float, float]:
        """Current platform azimuth estimate and 1-sigma [rad].

        Position 1: ``psi_1`` (the east drift is unknown: sigma includes
        ``sigma_drift / Oc``); position 2: eq. (20) plus the indexing angle.
        """
        if self.active == 2 and self.solution is not None:
            s = self.solution
            return float(wrap_angle(s.azimuth_avg + self.index_angle)), s.sigma_avg
        if self.active == 0:
            return float(self.x0[_PSI]), math.sqrt(self.P0[_PSI, _PSI])
        f = self.filters[self.active]
        sig = math.sqrt(f.P[_PSI, _PSI] + (self.sigma_drift / self.oc) ** 2)
        return float(f.x[_PSI]), sig

    def tilts(self, t: float) -> tuple[float, float, float, float]:
        """Current level misalignments ``theta_E``, ``theta_N`` and their 1-sigma [rad].

        The model frame of a position is geographic turned by ``delta``; it is turned
        back with the two-position ``delta`` when known (position 2), else with 0 and
        the unknown ``delta`` (``sigma_drift / Oc``) added to the sigma.

        Parameters
        ----------
        t : float
            Time at which to evaluate the tilts [s] (the active position's filter state is
            propagated from its position start to ``t``).

        Returns
        -------
        theta_E, theta_N, sigma_E, sigma_N : float
            Geographic level misalignments about east and north and their 1-sigma [rad].
        """
        if self.active == 0:
            s = math.sqrt(self.P0[0, 0])
            return 0.0, 0.0, s, s
        f = self.filters[self.active]
        dt = t - self.starts[self.active]
        if self.active == 2 and self.solution is not None:
            delta, sig_delta = self.solution.delta_2, 0.0
        else:
            delta, sig_delta = 0.0, self.sigma_drift / self.oc

        x = f.x
        u, J = tilt_jacobian(x, dt, delta, self.lat)
        C = J @ f.P[:3, :3] @ J.T
        # an unknown turn of the frame moves the tilt across itself: i u = (-u_N, u_E)
        var_e = C[0, 0] + (u.imag * sig_delta) ** 2
        var_n = C[1, 1] + (u.real * sig_delta) ** 2
        return u.real, u.imag, math.sqrt(var_e), math.sqrt(var_n)


# ----------------------------------------------------------------------------------------
# Block
# ----------------------------------------------------------------------------------------
_DEG = math.pi / 180.0


class HrgTwoPositionAlignment(Block):
    """Two-position HRG platform self-alignment (seed 000): EKF, UPF or KF per position."""

    variables = (
        parameter("method", 1, description="0 EKF, 1 UPF, 2 KF (linear platform-frame model)"),
        parameter("n_particles", 200, description="UPF particles"),
        parameter("seed", 0, description="UPF random seed"),
        parameter("lat", 45.0 * _DEG, "rad", "latitude"),
        parameter("g", 9.7966, "m/s2", "gravity"),
        parameter("period", 1.0, "s", "filter period (increments summed)"),
        parameter("accel_noise", 5e-6 * 9.80665, "m/s/sqrt(s)", "accelerometer VRW density N"),
        parameter("dv_quantum", 1e-4, "m/s", "velocity per accelerometer pulse (1/K1)"),
        parameter("sigma_theta0", 3.0 * ARCMIN, "rad", "prior std of the level misalignments"),
        parameter("sigma_drift", 0.2 * DEG_H, "rad/s", "prior std of a drift rate"),
        parameter(
            "sigma_azimuth", _UNIFORM_SIGMA, "rad", "prior azimuth std (>= pi/sqrt3: unknown)"
        ),
        parameter("azimuth0", 0.0, "rad", "prior azimuth estimate (theta_C)"),
        parameter("index_angle", 90.0 * _DEG, "rad", "nominal indexing angle"),
        parameter("sigma_index", 6.0 * ARCMIN, "rad", "indexing accuracy (1 sigma)"),
        parameter("kernel", 1.0, "1", "UPF component azimuth std in grid spacings"),
        parameter("alpha", 1.0, "1", "UKF sigma-point spread"),
        parameter("resample", 0.1, "1", "UPF: resample when ESS < resample x n_particles"),
        parameter("conv_band", 4.0 * ARCMIN, "rad", "converged when 3 sigma(psi) <= conv_band"),
        input_("dv_p", (0.0, 0.0, 0.0), "m/s", "accelerometer velocity increments, p axes"),
        input_("position", 1.0, "1", "platform status: 1, 0 (indexing), 2"),
        input_("azimuth_true", 0.0, "rad", "true platform azimuth (error signals only)"),
        input_("theta_E_true", 0.0, "rad", "true level misalignment about east (errors only)"),
        input_("theta_N_true", 0.0, "rad", "true level misalignment about north (errors only)"),
        output("azimuth_est", 0.0, "rad", "current platform azimuth estimate"),
        output("azimuth_sigma", 0.0, "arcmin", "1-sigma of azimuth_est"),
        output("azimuth_err", 0.0, "arcmin", "azimuth_est - azimuth_true, wrapped"),
        output("psi_est", 0.0, "rad", "apparent azimuth of the current position (state)"),
        output("psi_sigma", 0.0, "arcmin", "1-sigma of psi_est"),
        output("azimuth_1", 0.0, "rad", "(theta_AP)_1, eq. (19)"),
        output("azimuth_2", 0.0, "rad", "(theta_AP)_2 referred to position 1, eq. (17)"),
        output("azimuth_avg", 0.0, "rad", "(theta_AP) two-position mean, eq. (20)"),
        output("azimuth_avg_sigma", 0.0, "arcmin", "1-sigma of azimuth_avg"),
        output("theta_E_est", 0.0, "rad", "current level misalignment about east"),
        output("theta_N_est", 0.0, "rad", "current level misalignment about north"),
        output("theta_E_sigma", 0.0, "arcmin", "1-sigma of theta_E_est"),
        output("theta_N_sigma", 0.0, "arcmin", "1-sigma of theta_N_est"),
        output("theta_E_err", 0.0, "arcmin", "theta_E_est - theta_E_true"),
        output("theta_N_err", 0.0, "arcmin", "theta_N_est - theta_N_true"),
        output("theta_N0_est", 0.0, "rad", "initial tilt about north of this position (state)"),
        output("theta_E0_est", 0.0, "rad", "initial tilt about east of this position (state)"),
        output(
            "drift_north_est", 0.0, "rad/s", "apparent north drift D_N of this position (state)"
        ),
        output("drift_north_sigma", 0.0, "deg/h", "1-sigma of drift_north_est"),
        output("D_N_est", 0.0, "rad/s", "drift of the y ('north') gyro, after position 2 starts"),
        output("D_E_est", 0.0, "rad/s", "drift of the x ('east') gyro, after position 2 starts"),
        output("D_N_sigma", 0.0, "deg/h", "1-sigma of D_N_est"),
        output("D_E_sigma", 0.0, "deg/h", "1-sigma of D_E_est"),
        output("H_E", 0.0, "rad/s", "east-gyro regular drift, eq. (21)"),
        output("converged", 0.0, "1", "1 when 3 sigma(psi) <= conv_band in this position"),
        output("t_conv_1", -1.0, "s", "position 1: time from its start to convergence (-1: not)"),
        output("t_conv_2", -1.0, "s", "position 2: time from its start to convergence (-1: not)"),
        output("position_active", 0.0, "1", "position being filtered (0 before the first)"),
        output("ess", 1.0, "1", "UPF effective sample size (1 for the Kalman filters)"),
    )
    default_step = 0.1
    default_stop = 2.0

    def initialize(self) -> None:
        self._core = TwoPositionAligner(
            method=int(self.method),
            lat=float(self.lat),
            g=float(self.g),
            period=float(self.period),
            accel_noise=float(self.accel_noise),
            dv_quantum=float(self.dv_quantum),
            sigma_theta0=float(self.sigma_theta0),
            sigma_drift=float(self.sigma_drift),
            sigma_azimuth=float(self.sigma_azimuth),
            azimuth0=float(self.azimuth0),
            index_angle=float(self.index_angle),
            sigma_index=float(self.sigma_index),
            n_particles=int(self.n_particles),
            seed=int(self.seed),
            kernel=float(self.kernel),
            alpha=float(self.alpha),
            resample=float(self.resample),
        )
        self._core.start(self.start_time, float(self.position))
        self._publish(self.start_time)

    def step(self, t: float, h: float) -> None:
        updated = self._core.step(t, h, self.dv_p, float(self.position))
        if updated:
            self._publish(t + h)
        elif self._core.active:
            self._publish_tilts(t + h)

    # ------------------------------------------------------------------ outputs
    def _publish(self, t: float) -> None:
        core = self._core
        az, az_sig = core.azimuth()
        self.azimuth_est = az
        self.azimuth_sigma = az_sig / ARCMIN
        self.azimuth_err = float(wrap_angle(az - float(self.azimuth_true))) / ARCMIN
        self.position_active = float(core.active)
        if core.active:
            f = core.filters[core.active]
            self.psi_est = float(f.x[_PSI])
            self.psi_sigma = math.sqrt(f.P[_PSI, _PSI]) / ARCMIN
            self.theta_N0_est, self.theta_E0_est = float(f.x[0]), float(f.x[1])
            self.drift_north_est = float(f.x[2])
            self.drift_north_sigma = math.sqrt(f.P[2, 2]) / DEG_H
            self.ess = float(f.ess)
            conv = 3.0 * math.sqrt(f.P[_PSI, _PSI]) <= float(self.conv_band)
            name = f"t_conv_{core.active}"
            if conv and getattr(self, name) < 0.0:
                setattr(self, name, t - core.starts[core.active])
            elif not conv:
                setattr(self, name, -1.0)
            self.converged = 1.0 if conv else 0.0
        else:
            self.psi_est = float(core.x0[_PSI])
            self.psi_sigma = math.sqrt(core.P0[_PSI, _PSI]) / ARCMIN
            self.drift_north_sigma = math.sqrt(core.P0[2, 2]) / DEG_H
        s = core.solution
        if s is not None:
            self.azimuth_1, self.azimuth_2, self.azimuth_avg = (
                s.azimuth_1,
                s.azimuth_2,
                s.azimuth_avg,
            )
            self.azimuth_avg_sigma = s.sigma_avg / ARCMIN
            self.D_N_est, self.D_E_est = s.D_N, s.D_E
            self.D_N_sigma, self.D_E_sigma = s.sigma_D_N / DEG_H, s.sigma_D_E / DEG_H
            self.H_E = s.H_E
        else:
            if core.active:
                self.azimuth_1 = self.azimuth_avg = self.psi_est
            self.azimuth_avg_sigma = az_sig / ARCMIN
            self.D_N_sigma = self.D_E_sigma = core.sigma_drift / DEG_H
        self._publish_tilts(t)

    def _publish_tilts(self, t: float) -> None:
        e, n, se, sn = self._core.tilts(t)
        self.theta_E_est, self.theta_N_est = e, n
        self.theta_E_sigma, self.theta_N_sigma = se / ARCMIN, sn / ARCMIN
        self.theta_E_err = (e - float(self.theta_E_true)) / ARCMIN
        self.theta_N_err = (n - float(self.theta_N_true)) / ARCMIN
