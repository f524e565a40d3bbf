"""Shared models of the estimator tests (test_kalman, test_unscented, test_particle, ...).

A constant-velocity model in the plane, ``x = [px, vx, py, vy]``, ``z = [px, py]``, and a
pendulum with a nonlinear measurement; each function acts on the last axis, so it works
for a point ``(n,)``, a sigma-point set ``(m, n)`` and a particle stack ``(N, m, n)``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from cosim.estimation import (
    KalmanFilter,
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
    van_loan,
)

DT = 0.1
A_CV = np.array([[0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0]], dtype=float)
G_CV = np.array([[0, 0], [1, 0], [0, 0], [0, 1]], dtype=float)
H_CV = np.array([[1, 0, 0, 0], [0, 0, 1, 0]], dtype=float)
F_CV, Q_CV = van_loan(A_CV, G_CV, 0.5 * np.eye(2), DT)
R_CV = np.diag([0.3, 0.4])
X0_CV = np.array([1.0, 2.0, 3.0, -1.0])
P0_CV = np.diag([10.0, 1.0, 10.0, 1.0])


def cv_kf() -> KalmanFilter:
    kf = KalmanFilter(4, 2)
    kf.F, kf.Q, kf.H, kf.R = F_CV, Q_CV, H_CV, R_CV
    kf.x, kf.P = X0_CV, P0_CV
    return kf


def cv_fx(x: np.ndarray, dt: float) -> np.ndarray:
    # acts on the last axis: works for (n,), (2n+1, n) and (N, 2n+1, n)
    F = F_CV if dt == DT else expm(A_CV * dt)
    return x @ F.T


def cv_hx(x: np.ndarray) -> np.ndarray:
    return x @ H_CV.T


def cv_ukf(alpha: float) -> UnscentedKalmanFilter:
    ukf = UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints(4, alpha, 2.0, 0.0))
    ukf.Q, ukf.R = Q_CV, R_CV
    ukf.x, ukf.P = X0_CV, P0_CV
    return ukf


def simulate_cv(rng: np.random.Generator, n_steps: int, n_runs: int) -> tuple[np.ndarray, ...]:
    """Truth and measurements of the CV model for ``n_runs`` independent runs."""
    LQ, LR, LP = (np.linalg.cholesky(M) for M in (Q_CV, R_CV, P0_CV))
    x = X0_CV + rng.standard_normal((n_runs, 4)) @ LP.T  # truth drawn from the prior
    xs, zs = [], []
    for _ in range(n_steps):
        x = x @ F_CV.T + rng.standard_normal((n_runs, 4)) @ LQ.T
        xs.append(x)
        zs.append(x @ H_CV.T + rng.standard_normal((n_runs, 2)) @ LR.T)
    return np.stack(xs, axis=1), np.stack(zs, axis=1)  # (runs, steps, .)


def pendulum_fx(x: np.ndarray, dt: float) -> np.ndarray:
    out = np.empty_like(x)
    out[..., 0] = x[..., 0] + x[..., 1] * dt
    out[..., 1] = x[..., 1] - 9.81 * np.sin(x[..., 0]) * dt
    return out


def pendulum_hx(x: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(x[..., 0]), x[..., 1] ** 2], axis=-1)


def pts4() -> MerweScaledSigmaPoints:
    """Merwe points for the CV model (alpha 0.5)."""
    return MerweScaledSigmaPoints(4, 0.5)
