r"""Error model of the two-position HRG platform alignment (seed 000): measurement, eq. 16-21.

The filters that estimate with it are in :mod:`cosim.alignment.hrg_filters`, the block in
:mod:`cosim.alignment.hrg_two_position`.

Frames and symbols
------------------
ENU geographic frame ``n``; platform frame ``p`` (x, y level, z up, azimuth ``A``
counter-clockwise from ENU), as in :mod:`models.blocks.hrg_platform`. ``L`` latitude,
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

from cosim.models.constants import OMEGA_IE
from cosim.models.conventions import wrap_angle

#: Std of a uniform angle on the circle, ``pi / sqrt 3`` [rad] (the unknown-azimuth prior).
UNIFORM_SIGMA = math.pi / math.sqrt(3.0)
#: Index of the azimuth ``psi`` in the state ``[theta_N0, theta_E0, D_N, psi]``.
PSI = 3


# ----------------------------------------------------------------------------------------
# Measurement model
# ----------------------------------------------------------------------------------------
def series_e1_e2(t: float, w: float) -> tuple[complex, complex]:
    """``e1(t) = int_0^t exp(-i w s) ds`` and ``e2(t) = int_0^t e1(s) ds`` by power series.

    ``e1 = sum_k (-i w)^k t^(k+1) / (k+1)!``, ``e2 = sum_k (-i w)^k t^(k+2) / (k+2)!``:
    no cancellation for small ``w t`` (the closed forms lose ``1 / (w t)`` digits).

    Parameters
    ----------
    t : float
        Time since the position start [s].
    w : float
        Rate ``Os = Omega sin L`` [rad/s], nonzero.

    Returns
    -------
    e1, e2 : complex
        The two integrals [s, s^2].
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
    e1_tau, e2_tau = series_e1_e2(tau, w)
    e1_t0, _ = series_e1_e2(t0, w)
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
    c, s = np.cos(x[..., PSI]), np.sin(x[..., PSI])
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
    r = cmath.exp(-1j * float(x[PSI]))
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
    e1, _ = series_e1_e2(t, w) if w != 0.0 else (complex(t), 0j)
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
    e1 = series_e1_e2(t, w)[0] if w != 0.0 else complex(t)
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


def polar_to_linear(x: np.ndarray, lat: float) -> np.ndarray:
    """``[theta_N0, theta_E0, D_N, psi]`` -> ``[Re p, Im p, Re q, Im q]`` (platform axes).

    Parameters
    ----------
    x : ndarray, shape (4,)
        Polar state [rad, rad, rad/s, rad].
    lat : float
        Latitude [rad].

    Returns
    -------
    ndarray, shape (4,)
        Linear platform-frame state: initial tilt ``p`` [rad] and tilt rate ``q`` [rad/s].
    """
    oc = OMEGA_IE * math.cos(lat)
    r = cmath.exp(-1j * float(x[PSI]))
    p = complex(x[1], x[0]) * r
    q = 1j * (float(x[2]) - oc) * r
    return np.array([p.real, p.imag, q.real, q.imag])


def linear_to_polar(y: np.ndarray, lat: float) -> np.ndarray:
    """Inverse of :func:`polar_to_linear` (``psi = -arg(i q)``, ``D_N = Oc - |q|``).

    Parameters
    ----------
    y : ndarray, shape (4,)
        ``[Re p, Im p, Re q, Im q]`` [rad, rad, rad/s, rad/s].
    lat : float
        Latitude [rad].

    Returns
    -------
    ndarray, shape (4,)
        ``[theta_N0, theta_E0, D_N, psi]`` [rad, rad, rad/s, rad].
    """
    oc = OMEGA_IE * math.cos(lat)
    q = complex(y[2], y[3])
    psi = -cmath.phase(1j * q)
    u0 = complex(y[0], y[1]) * cmath.exp(1j * psi)
    return np.array([u0.imag, u0.real, oc - abs(q), psi])


def numeric_jacobian(
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


def state_steps(P: np.ndarray) -> np.ndarray:
    """Finite-difference steps: a small fraction of each standard deviation (never zero).

    Parameters
    ----------
    P : ndarray, shape (4, 4)
        Covariance of the polar state.

    Returns
    -------
    ndarray, shape (4,)
        ``max(1e-3 sigma, floor)`` per component (state units).
    """
    floor = np.array([1e-9, 1e-9, 1e-13, 1e-9])
    return np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(P), 0.0)), floor)


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
    v = np.array([x1[PSI], x1[2], x2[PSI], x2[2]])
    cov = np.zeros((4, 4))
    sel = [PSI, 2]
    cov[:2, :2] = P1[np.ix_(sel, sel)]
    cov[2:, 2:] = P2[np.ix_(sel, sel)]
    out = _solve(v, index_angle, oc)
    steps = np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(cov), 0.0)), [1e-9, 1e-13, 1e-9, 1e-13])
    J = numeric_jacobian(lambda w: _solve(w, index_angle, oc), v, steps, (0, 1, 2, 3, 4))
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
    steps = np.concatenate([state_steps(P1), [max(1e-3 * sigma_drift, 1e-13), 1e-9]])
    J = numeric_jacobian(prior, v, steps, (2,))
    m = prior(v)
    C = J @ cov @ J.T
    x2 = np.array([m[0], m[1], 0.0, float(wrap_angle(m[2]))])
    P2 = np.zeros((4, 4))
    idx = [0, 1, PSI]
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
