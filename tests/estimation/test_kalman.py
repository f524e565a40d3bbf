"""Tests of cosim.estimation.kalman: KF, EKF and the Joseph-form update."""

from __future__ import annotations

import numpy as np
import pytest
from estimation_models import DT, F_CV, H_CV, P0_CV, Q_CV, R_CV, X0_CV, cv_hx, cv_kf, simulate_cv

from cosim.estimation import (
    ExtendedKalmanFilter,
    KalmanFilter,
    ShapeError,
    anees_bounds,
    joseph_update,
    nees,
)


def test_ekf_equals_kf_on_a_linear_model() -> None:
    rng = np.random.default_rng(13)
    _, zs = simulate_cv(rng, 20, 1)
    kf = cv_kf()
    ekf = ExtendedKalmanFilter(4, 2)
    ekf.x, ekf.P, ekf.Q, ekf.R = X0_CV, P0_CV, Q_CV, R_CV
    for z in zs[0]:
        kf.predict()
        ekf.predict(DT, f=lambda x, dt: F_CV @ x, F=lambda x, dt: F_CV)
        kf.update(z)
        ekf.update(z, h=lambda x: H_CV @ x, H_jac=H_CV)
        np.testing.assert_allclose(ekf.x, kf.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ekf.P, kf.P, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ekf.S, kf.S, rtol=0, atol=1e-12)


def test_joseph_form_keeps_p_positive_definite_where_the_simple_form_fails() -> None:
    # Two nearly parallel, very accurate measurements (Grewal & Andrews' ill-conditioned
    # example). Exact posterior eigenvalues: 1 / (1 + lambda_max(H^T H) / d^2), 3/4, 1.
    d = 1e-7
    H = np.array([[1.0, 1.0, 1.0], [1.0, 1.0, 1.0 + d]])
    R = d**2 * np.eye(2)
    kf = KalmanFilter(3, 2)
    kf.P, kf.H, kf.R = np.eye(3), H, R
    kf.update([0.0, 0.0])
    assert np.array_equal(kf.P, kf.P.T)  # exactly symmetric
    exact = np.array([1 / (1 + np.linalg.eigvalsh(H.T @ H).max() / d**2), 0.75, 1.0])
    eig = np.linalg.eigvalsh(kf.P)
    assert eig[0] > 0
    assert eig[0] == pytest.approx(exact[0], rel=0.05)  # ~1.7e-15, right to a few %
    np.testing.assert_allclose(eig[1:], exact[1:], rtol=1e-3)  # 3/4 itself is O(d) off
    np.linalg.cholesky(kf.P)  # usable for the next sigma-point set
    # the textbook form P - K H P (explicit inverse of S) goes indefinite
    K = np.linalg.inv(H @ H.T + R)
    P_simple = np.eye(3) - H.T @ K @ H
    assert np.linalg.eigvalsh(0.5 * (P_simple + P_simple.T))[0] < -1e-6


def test_kf_control_input_and_skipped_update() -> None:
    kf = KalmanFilter(2, 1, dim_u=1)
    kf.F, kf.B, kf.Q = [[1.0, 1.0], [0.0, 1.0]], [[0.5], [1.0]], 0.01
    kf.x = [1.0, 2.0]
    kf.predict(u=[3.0])
    np.testing.assert_allclose(kf.x_prior, [1.0 + 2.0 + 1.5, 2.0 + 3.0])
    kf.update(None)
    assert kf.K is None and np.array_equal(kf.x_post, kf.x_prior)
    np.testing.assert_array_equal(kf.P_post, kf.P_prior)


def test_kf_symmetry_survives_many_steps() -> None:
    kf = cv_kf()
    rng = np.random.default_rng(5)
    for _ in range(300):
        kf.predict()
        kf.update(rng.standard_normal(2))
        assert np.array_equal(kf.P, kf.P.T)
        assert np.array_equal(kf.P_prior, kf.P_prior.T)


def _anees_of_kf(Q_filter: np.ndarray, truth: np.ndarray, zs: np.ndarray) -> np.ndarray:
    n_runs, n_steps, _ = truth.shape
    out = np.zeros((n_runs, n_steps))
    for r in range(n_runs):
        kf = cv_kf()
        kf.Q = Q_filter
        for k in range(n_steps):
            kf.predict()
            kf.update(zs[r, k])
            out[r, k] = nees(kf.x - truth[r, k], kf.P)
    return out.mean(axis=0)


def test_kf_is_consistent_in_the_nees_sense() -> None:
    # 200 runs of 40 steps; if the KF is consistent, 200 * ANEES_k ~ chi2(200 * 4), so
    # the two-sided 95 % band is [chi2.ppf(0.025, 800), chi2.ppf(0.975, 800)] / 200
    # = [3.618, 4.401]. At the last step ANEES must lie in it, and at least 90 % of the
    # steps (expected 95 %) must too. A filter told Q/10 must fall above the band.
    rng = np.random.default_rng(2024)
    n_runs = 200
    truth, zs = simulate_cv(rng, 40, n_runs)
    lo, hi = anees_bounds(4, n_runs, 0.95)
    assert (lo, hi) == pytest.approx((3.618, 4.401), abs=1e-3)
    anees = _anees_of_kf(Q_CV, truth, zs)
    assert lo <= anees[-1] <= hi, anees[-1]
    assert np.mean((anees >= lo) & (anees <= hi)) >= 0.9, anees
    overconfident = _anees_of_kf(Q_CV / 10, truth, zs)
    assert np.all(overconfident[10:] > hi)


def test_joseph_update_is_the_kalman_filter_update() -> None:
    kf = cv_kf()
    kf.predict()
    x, P = kf.x.copy(), kf.P.copy()
    z = np.array([1.5, 2.5])
    kf.update(z)
    x_post, P_post, K, S, loglik = joseph_update(x, P, z - H_CV @ x, H_CV, R_CV)
    for got, want in ((x_post, kf.x), (P_post, kf.P), (K, kf.K), (S, kf.S)):
        np.testing.assert_array_equal(got, want)
    assert loglik == kf.log_likelihood
    # y = 0 propagates the covariance alone (the covariance-analysis use)
    x0, P0, *_ = joseph_update(x, P, np.zeros(2), H_CV, R_CV)
    np.testing.assert_array_equal(x0, x)
    np.testing.assert_array_equal(P0, P_post)


def set_attr(obj: object, name: str, value: object) -> None:
    setattr(obj, name, value)


BAD_SHAPES = [
    ("x", lambda: set_attr(cv_kf(), "x", np.zeros(3))),
    ("P", lambda: set_attr(cv_kf(), "P", np.eye(3))),
    ("H", lambda: set_attr(cv_kf(), "H", np.zeros((2, 3)))),
    ("R", lambda: set_attr(cv_kf(), "R", np.eye(3))),
    ("z", lambda: cv_kf().update([1.0, 2.0, 3.0])),
    ("F", lambda: cv_kf().predict(F=np.eye(3))),
    ("u", lambda: KalmanFilter(2, 1, dim_u=1).predict(u=[1.0, 2.0])),
    ("R", lambda: cv_kf().update([1.0], H=[[1, 0, 0, 0]])),
    ("H_jac", lambda: ExtendedKalmanFilter(4, 2).update([1, 2], cv_hx, np.eye(4))),
]  # fmt: skip


@pytest.mark.parametrize("arg, call", BAD_SHAPES, ids=[a for a, _ in BAD_SHAPES])
def test_bad_shapes_raise_a_value_error_naming_the_argument(arg: str, call) -> None:
    with pytest.raises(ShapeError, match=rf"^{arg}\b.*expected") as info:
        call()
    assert isinstance(info.value, ValueError)
    assert "got" in str(info.value)


def test_bad_values() -> None:
    with pytest.raises(ValueError, match="^z: expected finite"):
        cv_kf().update([np.nan, 1.0])
