"""Glue between the inertial-frame coarse alignment and the 10-state fine filter.

The fine filter (:mod:`cosim.alignment.static_model`) starts from the coarse result
with the coarse error theory's covariance (:func:`coarse_p0`), not an assumed 1 deg:
the misalignment block is the theory's ``P_phi`` and its cross-covariance with the
bias states follows from the theory's sensitivities, because the coarse heading error
*is* mostly the east gyro bias over ``W cos L`` and the level error the accelerometer
bias over ``g``. The fine filter's state is ``psi = -phi_err``, so::

    P0[psi, psi]      = P_phi
    P0[psi, nabla_t]  = -J_accel C_t_n[:, 0:2] s_a^2      (nabla_x, nabla_y of the table)
    P0[psi, eps_t]    = -J_gyro C_t_n s_g^2
    P0[nabla, nabla]  = s_a^2 I,  P0[eps, eps] = s_g^2 I,  P0[dv, dv] = p0_vel^2 I

with ``s_a = p0_accel_bias``, ``s_g = p0_gyro_drift`` and the theory evaluated with the
filter's own ``q_accel`` and ``q_gyro``: the coarse and the fine stage share one
statement of the IMU.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from cosim.alignment.coarse_inertial import InertialCoarseTheory, inertial_coarse_theory
from cosim.alignment.static_model import N_STATES, FilterTuning

FloatArray = NDArray[np.float64]


@lru_cache(maxsize=4096)
def _theory(
    T: float, lat: float, h: float, dt: float, qa: float, qg: float, sa: float, sg: float
) -> InertialCoarseTheory:
    return inertial_coarse_theory(
        T, lat, h, dt=dt, q_accel=qa, q_gyro=qg, sigma_accel_bias=sa, sigma_gyro_bias=sg
    )


def coarse_theory_cached(
    T: float, lat: float, h: float, dt: float, tuning: FilterTuning
) -> InertialCoarseTheory:
    """:func:`~cosim.alignment.coarse_inertial.inertial_coarse_theory` for a filter tuning, cached.

    Parameters
    ----------
    T : float
        Coarse window [s].
    lat, h : float
        Latitude [rad], height [m].
    dt : float
        Step [s].
    tuning : FilterTuning
        Supplies ``q_accel``, ``q_gyro`` (white noise) and ``p0_accel_bias``,
        ``p0_gyro_drift`` (turn-on sigmas).

    Returns
    -------
    InertialCoarseTheory
    """
    return _theory(
        round(float(T), 9),
        float(lat),
        float(h),
        float(dt),
        float(tuning.q_accel),
        float(tuning.q_gyro),
        float(tuning.p0_accel_bias),
        float(tuning.p0_gyro_drift),
    )


def required_coarse_time(
    lat: float, h: float, dt: float, tuning: FilterTuning, sigma_max: float
) -> float | None:
    """Shortest window (to 1 s, up to 2 h) whose theoretical heading sigma is <= ``sigma_max``.

    Parameters
    ----------
    lat, h : float
        Latitude [rad], height [m].
    dt : float
        Step [s].
    tuning : FilterTuning
        The IMU statement (see :func:`coarse_theory_cached`).
    sigma_max : float
        Heading 1-sigma wanted [rad].

    Returns
    -------
    float or None
        The window [s], or None when no window up to 2 h reaches ``sigma_max``.
    """

    def sig(T: float) -> float:
        th = _theory(T, float(lat), float(h), max(dt, T / 5000.0), tuning.q_accel,
                     tuning.q_gyro, tuning.p0_accel_bias, tuning.p0_gyro_drift)  # fmt: skip
        return float(np.sqrt(th.P_phi[2, 2]))

    lo, hi = 1.0, 2.0
    while sig(hi) > sigma_max:
        lo, hi = hi, 2.0 * hi
        if hi > 7200.0:
            return None
    while hi - lo > 1.0:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if sig(mid) > sigma_max else (lo, mid)
    return float(np.ceil(hi))


def coarse_p0(th: InertialCoarseTheory, C_t_n: FloatArray, tuning: FilterTuning) -> FloatArray:
    """Initial covariance of the 10-state fine filter from the coarse error theory.

    Parameters
    ----------
    th : InertialCoarseTheory
        Theory of the coarse window just ended.
    C_t_n : ndarray, shape (3, 3)
        Estimated table (sensor carrier) to NED attitude at the start of the fine stage.
    tuning : FilterTuning
        ``p0_vel``, ``p0_accel_bias``, ``p0_gyro_drift`` (``p0_att`` is not used).

    Returns
    -------
    ndarray, shape (10, 10)
        ``P0`` in the states of :data:`cosim.alignment.static_model.STATES` (SI).
    """
    sa2 = float(tuning.p0_accel_bias) ** 2
    sg2 = float(tuning.p0_gyro_drift) ** 2
    P = np.zeros((N_STATES, N_STATES))
    P[0, 0] = P[1, 1] = float(tuning.p0_vel) ** 2
    P[2:5, 2:5] = th.P_phi
    P[5:7, 5:7] = sa2 * np.eye(2)
    P[7:10, 7:10] = sg2 * np.eye(3)
    c = np.asarray(C_t_n, dtype=float)
    P[2:5, 5:7] = -sa2 * (th.J_accel @ c[:, 0:2])
    P[2:5, 7:10] = -sg2 * (th.J_gyro @ c)
    P[5:7, 2:5] = P[2:5, 5:7].T
    P[7:10, 2:5] = P[2:5, 7:10].T
    return P
