"""Tests of cosim.estimation: KF, EKF, UKF, UPF, Van Loan, observability, resampling.

Every stochastic test uses a fixed ``numpy.random.default_rng`` seed, so each is
deterministic. Statistical bounds come from theory where there is one (chi-square
NEES band, systematic-resampling count variance, Monte Carlo error ~ 1/sqrt(ESS));
the one engineering bound (UPF multi-step tracking) says so in its comment.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm, solve_continuous_lyapunov

from cosim.estimation import (
    CovarianceError,
    EstimatorTypeError,
    ExtendedKalmanFilter,
    KalmanFilter,
    MerweScaledSigmaPoints,
    ShapeError,
    UnscentedKalmanFilter,
    UnscentedParticleFilter,
    anees_bounds,
    angle_mean,
    angle_mean_fn,
    angle_residual,
    angle_residual_fn,
    nees,
    nis,
    observability_rank,
    piecewise_observability_rank,
    stripped_condition_holds,
    systematic_resample,
    unscented_transform,
    van_loan,
)
from models.conventions import wrap_angle

# ----------------------------------------------------------------------------------------
# A constant-velocity model in the plane: x = [px, vx, py, vy], z = [px, py]
# ----------------------------------------------------------------------------------------
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


# ----------------------------------------------------------------------------------------
# Van Loan
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt", [0.01, 0.5, 3.0])
def test_van_loan_double_integrator(dt: float) -> None:
    q = 0.7
    Phi, Qd = van_loan([[0, 1], [0, 0]], [[0], [1]], q, dt)
    np.testing.assert_allclose(Phi, [[1, dt], [0, 1]], rtol=0, atol=1e-14)
    Qd_exact = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    np.testing.assert_allclose(Qd, Qd_exact, rtol=1e-12, atol=1e-16)


@pytest.mark.parametrize("dt", [0.01, 1.0, 250.0])
def test_van_loan_first_order_gauss_markov(dt: float) -> None:
    # x' = -x/tau + w, PSD 2 sigma^2 / tau -> stationary variance sigma^2
    tau, sigma = 100.0, 3e-4
    Phi, Qd = van_loan([[-1 / tau]], [[1.0]], 2 * sigma**2 / tau, dt)
    assert Phi[0, 0] == pytest.approx(np.exp(-dt / tau), rel=1e-13)
    assert Qd[0, 0] == pytest.approx(sigma**2 * (1 - np.exp(-2 * dt / tau)), rel=1e-11)


def test_van_loan_second_order_markov_keeps_stationary_covariance() -> None:
    # The deck-flexure model of seed 001: theta'' + 2 beta theta' + beta^2 theta = eta.
    # A stationary process satisfies P = Phi P Phi^T + Qd exactly, for any step.
    tau, sigma = 600.0, 2 * 2.9089e-4
    beta = 2.146 / tau
    A = np.array([[0, 1], [-(beta**2), -2 * beta]])
    G = np.array([[0.0], [1.0]])
    q = 4 * beta**3 * sigma**2
    P_ss = solve_continuous_lyapunov(A, -q * G @ G.T)
    assert np.sqrt(P_ss[0, 0]) == pytest.approx(sigma, rel=1e-12)
    for dt in (0.001, 0.5, 60.0):
        Phi, Qd = van_loan(A, G, q, dt)
        np.testing.assert_allclose(Phi, expm(A * dt), rtol=1e-13, atol=1e-16)
        np.testing.assert_allclose(Qd, P_ss - Phi @ P_ss @ Phi.T, rtol=1e-8, atol=1e-22)


# ----------------------------------------------------------------------------------------
# Observability
# ----------------------------------------------------------------------------------------
def static_alignment_model(heading: float, lat: float = np.deg2rad(45.0)) -> tuple:
    """10-state static-base psi-angle model of seed 003 (NED), heading about D.

    x = [dvN, dvE, phiN, phiE, phiD, bax, bay, egx, egy, egz], z = [dvN, dvE].
    """
    g, om = 9.8, 7.292115e-5
    c, s = np.cos(heading), np.sin(heading)
    C = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    w = np.array([om * np.cos(lat), 0, -om * np.sin(lat)])
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    A = np.zeros((10, 10))
    A[0, 3], A[1, 2] = g, -g  # dv' = f^n x phi with f^n = [0, 0, -g]
    A[0:2, 5:7] = C[0:2, 0:2]
    A[2:5, 2:5] = -W
    A[2:5, 7:10] = -C
    H = np.zeros((2, 10))
    H[0, 0] = H[1, 1] = 1
    return A, H


def test_observability_rank_of_simple_models() -> None:
    assert observability_rank(A_CV, H_CV) == 4
    assert observability_rank(A_CV, [[0, 1, 0, 0], [0, 0, 0, 1]]) == 2  # velocity only


def test_two_position_alignment_makes_the_static_model_observable() -> None:
    # One position: 7 of 10 (two accelerometer biases hide behind the level angles,
    # the east drift behind the heading). A 90 deg heading change makes all 10 observable.
    A1, H1 = static_alignment_model(0.3)
    A2, H2 = static_alignment_model(0.3 + np.pi / 2)
    assert observability_rank(A1, H1) == 7
    one = [(A1, H1, 100.0), (A1, H1, 100.0)]
    two = [(A1, H1, 100.0), (A2, H2, 100.0)]
    assert piecewise_observability_rank(one) == 7
    assert piecewise_observability_rank(two, method="total") == 10
    assert piecewise_observability_rank(two, method="stripped") == 10
    # Goshen-Meskin & Bar-Itzhack: for the stationary INS the unobservable directions
    # of each position are constant (null(O_j) in null(A_j)), so SOM rank = TOM rank.
    assert stripped_condition_holds(two)


def test_stripped_condition_detects_moving_unobservable_modes() -> None:
    # An unseen oscillator: its unobservable plane is not constant, so the SOM may lie.
    A = np.zeros((3, 3))
    A[0, 1], A[1, 0] = 1.0, -1.0
    H = np.array([[0.0, 0.0, 1.0]])
    assert not stripped_condition_holds([(A, H, 1.0)])
    assert stripped_condition_holds([(A_CV, [[0, 1, 0, 0], [0, 0, 0, 1]], 1.0)])  # positions


# ----------------------------------------------------------------------------------------
# Unscented transform and UKF vs KF
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("alpha, kappa", [(1.0, 0.0), (0.5, -1.0), (0.1, 0.0), (1e-3, 0.0)])
def test_unscented_transform_is_exact_for_linear_maps(alpha: float, kappa: float) -> None:
    rng = np.random.default_rng(7)
    n, d = 4, 3
    M = rng.standard_normal((n, n))
    P = M @ M.T + 0.1 * np.eye(n)
    x = rng.standard_normal(n)
    T, b = rng.standard_normal((d, n)), rng.standard_normal(d)
    pts = MerweScaledSigmaPoints(n, alpha, 2.0, kappa)
    sig = pts.sigma_points(x, P)
    # the central weight is of order 1/alpha^2: that is the round-off scale
    scale = 1e-12 * max(1.0, abs(pts.Wm[0]))
    assert np.sum(pts.Wm) == pytest.approx(1.0, abs=scale)
    noise = np.diag([0.1, 0.2, 0.3])
    mean, cov = unscented_transform(sig @ T.T + b, pts.Wm, pts.Wc, noise)
    np.testing.assert_allclose(mean, T @ x + b, rtol=0, atol=scale * np.abs(T @ x + b).max())
    cov_exact = T @ P @ T.T + noise
    np.testing.assert_allclose(cov, cov_exact, rtol=0, atol=scale * np.abs(cov_exact).max())


def test_sigma_points_are_batched() -> None:
    rng = np.random.default_rng(3)
    pts = MerweScaledSigmaPoints(3, 0.5)
    xs = rng.standard_normal((5, 3))
    Ps = np.array([np.diag(rng.uniform(0.5, 2.0, 3)) for _ in range(5)])
    batch = pts.sigma_points(xs, Ps)
    assert batch.shape == (5, 7, 3)
    for i in range(5):
        np.testing.assert_array_equal(batch[i], pts.sigma_points(xs[i], Ps[i]))
    mean, cov = unscented_transform(batch, pts.Wm, pts.Wc)
    np.testing.assert_allclose(mean, xs, atol=1e-13)
    np.testing.assert_allclose(cov, Ps, atol=1e-13)


@pytest.mark.parametrize("alpha", [1.0, 0.1])
def test_ukf_equals_kf_on_a_linear_model(alpha: float) -> None:
    # Exact equality needs the update's sigma points redrawn from the prior (they then
    # carry Q); alpha = 1e-3 loses ~1e-8 to cancellation in the weights.
    rng = np.random.default_rng(11)
    _, zs = simulate_cv(rng, 50, 1)
    kf, ukf = cv_kf(), cv_ukf(alpha)
    for z in zs[0]:
        kf.predict()
        ukf.predict(DT)
        np.testing.assert_allclose(ukf.x_prior, kf.x_prior, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ukf.P_prior, kf.P_prior, rtol=0, atol=1e-9)
        kf.update(z)
        ukf.update(z)
        for name in ("x", "P", "K", "y", "S"):
            np.testing.assert_allclose(getattr(ukf, name), getattr(kf, name), rtol=0, atol=1e-9)
        assert ukf.log_likelihood == pytest.approx(kf.log_likelihood, abs=1e-9)
    assert ukf.sigmas_f.shape == (9, 4)


def test_ukf_point_by_point_models_give_the_same_result() -> None:
    rng = np.random.default_rng(12)
    _, zs = simulate_cv(rng, 10, 1)
    vec = cv_ukf(0.5)
    one = UnscentedKalmanFilter(
        4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints(4, 0.5), vectorized=False
    )
    one.Q, one.R, one.x, one.P = Q_CV, R_CV, X0_CV, P0_CV
    for z in zs[0]:
        vec.predict(DT)
        one.predict(DT)
        vec.update(z)
        one.update(z)
    np.testing.assert_allclose(one.x, vec.x, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(one.P, vec.P, rtol=1e-13, atol=1e-14)


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


# ----------------------------------------------------------------------------------------
# Joseph form, consistency
# ----------------------------------------------------------------------------------------
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


def test_nees_and_nis_broadcast_and_agree_with_the_definition() -> None:
    rng = np.random.default_rng(1)
    P = np.array([[2.0, 0.3], [0.3, 0.5]])
    e = rng.standard_normal((7, 2))
    expected = np.einsum("ki,ij,kj->k", e, np.linalg.inv(P), e)
    np.testing.assert_allclose(nees(e, P), expected, rtol=1e-12)
    np.testing.assert_allclose(nis(e, np.broadcast_to(P, (7, 2, 2))), expected, rtol=1e-12)
    assert isinstance(nees(e[0], P), float)


# ----------------------------------------------------------------------------------------
# Angles
# ----------------------------------------------------------------------------------------
def test_angle_residual_wraps_to_minus_pi_pi() -> None:
    a = np.array([[3.1, 5.0, -3.1], [np.pi, 0.0, -np.pi]])
    b = np.array([[-3.1, 5.0, 3.1], [0.0, 0.0, 0.0]])
    r = angle_residual(a, b, [0, 2])
    np.testing.assert_allclose(r[0], [6.2 - 2 * np.pi, 0.0, -6.2 + 2 * np.pi], atol=1e-14)
    assert r[1, 0] == np.pi and r[1, 2] == np.pi  # (-pi, pi]: -pi maps to +pi
    assert wrap_angle(-np.pi) == np.pi
    # the non-angle column is a plain difference
    assert angle_residual([[10.0, 10.0]], [[0.0, 0.0]], [1])[0, 0] == 10.0


def test_angle_mean_across_the_cut_and_with_negative_weights() -> None:
    pts = MerweScaledSigmaPoints(2, 0.3)  # Wm[0] = -4.6
    x = np.array([np.pi - 0.01, 1.0])
    sig = pts.sigma_points(x, np.diag([0.04, 1.0]))
    sig[:, 0] = wrap_angle(sig[:, 0])  # one point now sits near -pi
    assert np.sum(sig[:, 0] < 0) == 1
    m = angle_mean(sig, pts.Wm, [0])
    assert abs(angle_residual(m, x, [0])).max() < 1e-12
    assert abs(angle_residual(pts.Wm @ sig, x, [0])[0]) > 1.0  # the plain mean is off
    # batched over a leading axis, as the particle filter calls it
    mb = angle_mean(np.stack([sig, sig]), pts.Wm, [0])
    np.testing.assert_array_equal(mb, np.stack([m, m]))


def _heading_run(mode: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # state [heading, yaw rate]; the model keeps heading in (-pi, pi]; a compass
    # measures the wrapped heading. Truth starts at 3.0 rad and turns through +pi.
    # alpha = 0.3 gives Wm = [-4.6, 2.8, 2.8, 2.8, 2.8]: a sigma point wrapped by
    # 2 pi moves a plain weighted mean by 2.8 * 2 pi, which is not a whole turn.
    rng = np.random.default_rng(99)
    dt, r_true = 0.1, 0.05

    def fx(x: np.ndarray, dt: float) -> np.ndarray:
        out = x.copy()
        out[..., 0] = wrap_angle(x[..., 0] + x[..., 1] * dt)
        return out

    def hx(x: np.ndarray) -> np.ndarray:
        return x[..., :1]

    kw = {}
    if mode in ("full", "residual_only"):
        kw = dict(residual_x=angle_residual_fn([0]), residual_z=angle_residual_fn([0]))
    if mode == "full":
        kw.update(x_mean_fn=angle_mean_fn([0]), z_mean_fn=angle_mean_fn([0]))
    ukf = UnscentedKalmanFilter(2, 1, fx, hx, MerweScaledSigmaPoints(2, 0.3), **kw)
    ukf.x, ukf.P = [3.0, 0.0], np.diag([0.05**2, 0.05**2])
    ukf.Q, ukf.R = np.diag([1e-4, 1e-6]), 0.05**2
    est, err_prior, err_post = [], [], []
    for k in range(1, 121):
        truth = wrap_angle(3.0 + r_true * k * dt)
        ukf.predict(dt)
        err_prior.append(angle_residual([ukf.x[0]], [truth], [0])[0])
        ukf.update([wrap_angle(truth + 0.05 * rng.standard_normal())])
        est.append(ukf.x[0])
        err_post.append(angle_residual([ukf.x[0]], [truth], [0])[0])
    return np.array(est), np.array(err_prior), np.array(err_post)


def test_ukf_heading_does_not_jump_at_plus_minus_pi() -> None:
    # posterior heading sd is ~0.03 rad: 0.15 rad is 5 sigma
    est, err_prior, err_post = _heading_run("full")
    assert np.any(est > 3.1) and np.any(est < -3.1)  # the run does cross the cut
    steps = angle_residual(est[1:, None], est[:-1, None], [0])[:, 0]
    assert np.max(np.abs(steps)) < 0.1  # true step 0.005 rad
    assert np.max(np.abs(err_prior)) < 0.15 and np.max(np.abs(err_post)) < 0.15
    # without the circular mean the prior jumps where the sigma points straddle the cut
    _, err_prior, _ = _heading_run("residual_only")
    assert np.max(np.abs(err_prior)) > 1.0
    # and without any angle handling the estimate itself jumps
    _, _, err_post = _heading_run("none")
    assert np.max(np.abs(err_post)) > 1.0


# ----------------------------------------------------------------------------------------
# Resampling
# ----------------------------------------------------------------------------------------
def test_systematic_resample_counts_are_floor_or_ceil() -> None:
    rng = np.random.default_rng(0)
    for N in (1, 2, 7, 200):
        for _ in range(50):
            w = rng.exponential(size=N) ** 3
            w /= w.sum()
            idx = systematic_resample(w, rng)
            assert idx.shape == (N,) and np.all(np.diff(idx) >= 0)
            counts = np.bincount(idx, minlength=N)
            assert np.all(counts >= np.floor(N * w - 1e-9))
            assert np.all(counts <= np.ceil(N * w + 1e-9))


def test_systematic_resample_is_unbiased_for_the_weighted_mean() -> None:
    # Theory: n_i is floor(N w_i) or ceil(N w_i) with P(ceil) = frac(N w_i), so
    # sd(n_i) = sqrt(f_i (1 - f_i)). The resampled mean minus the weighted mean is
    # sum_i (n_i - N w_i)(x_i - c) / N, whose sd is at most
    # s_max = sum_i |x_i - c| sqrt(f_i (1 - f_i)) / N (Minkowski). Each draw must stay
    # within the deterministic bound sum_i |x_i - c| / N, and the average of M draws
    # within 4 s_max / sqrt(M) of the weighted mean.
    rng = np.random.default_rng(31)
    N, M = 50, 4000
    x = rng.normal(3.0, 2.0, N)
    w = rng.exponential(size=N)
    w /= w.sum()
    target = w @ x
    c = np.median(x)
    f = np.mod(N * w, 1.0)
    s_max = np.sum(np.abs(x - c) * np.sqrt(f * (1 - f))) / N
    hard = np.sum(np.abs(x - c)) / N
    means = np.array([x[systematic_resample(w, rng)].mean() for _ in range(M)])
    assert np.max(np.abs(means - target)) <= hard
    assert abs(means.mean() - target) <= 4 * s_max / np.sqrt(M)
    assert means.std() <= s_max
    # and the counts average to N w_i (per-index 5-sigma bound from the same theory)
    counts = np.array([np.bincount(systematic_resample(w, rng), minlength=N) for _ in range(M)])
    sd = np.sqrt(np.maximum(f * (1 - f), 1e-12) / M)
    assert np.all(np.abs(counts.mean(axis=0) - N * w) <= 5 * sd + 1e-12)


# ----------------------------------------------------------------------------------------
# Unscented particle filter
# ----------------------------------------------------------------------------------------
def pendulum_fx(x: np.ndarray, dt: float) -> np.ndarray:
    out = np.empty_like(x)
    out[..., 0] = x[..., 0] + x[..., 1] * dt
    out[..., 1] = x[..., 1] - 9.81 * np.sin(x[..., 0]) * dt
    return out


def pendulum_hx(x: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(x[..., 0]), x[..., 1] ** 2], axis=-1)


def test_upf_with_one_particle_equals_the_ukf() -> None:
    # Convention that makes it exact: proposal="mean" puts the particle at its UKF
    # posterior mean instead of a draw, and the filter covariance is then the mixture
    # covariance, i.e. the particle's own P for one particle. No resampling can occur
    # (threshold 0; with one particle ESS is always 1 anyway).
    Q, R = np.diag([1e-4, 1e-3]), np.diag([0.01, 0.05])
    x0, P0 = np.array([0.8, 0.0]), np.diag([0.1, 0.2])
    rng = np.random.default_rng(8)
    upf = UnscentedParticleFilter(
        2, 2, pendulum_fx, pendulum_hx, MerweScaledSigmaPoints(2, 0.5),
        rng=rng, n_particles=1, resample_threshold=0.0, proposal="mean",
    )  # fmt: skip
    upf.Q, upf.R = Q, R
    upf.initialize(x0, P0, spread=False)
    ukf = UnscentedKalmanFilter(2, 2, pendulum_fx, pendulum_hx, MerweScaledSigmaPoints(2, 0.5))
    ukf.Q, ukf.R, ukf.x, ukf.P = Q, R, x0, P0
    assert np.isnan(upf.particle_nis[0])  # no update yet
    truth = x0.copy()
    for _ in range(60):
        truth = pendulum_fx(truth, 0.05)
        z = pendulum_hx(truth) + rng.normal(0.0, [0.1, 0.2])
        ukf.predict(0.05)
        ukf.update(z)
        upf.step(z, 0.05)
        np.testing.assert_allclose(upf.x, ukf.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(upf.P, ukf.P, rtol=0, atol=1e-12)
        # the particle's innovation statistic is the UKF's
        assert upf.particle_nis[0] == pytest.approx(nis(ukf.y, ukf.S), rel=1e-9)
        assert upf.weights[0] == 1.0 and not upf.resampled
    assert upf.n_resamples == 0
    upf.step(None, 0.05)  # prediction only: no innovation
    assert np.isnan(upf.particle_nis[0])


def test_upf_sampling_proposal_is_the_per_particle_ukf() -> None:
    # In the default (sampling) mode every particle's proposal N(m_i, P_i) is a UKF step
    # from that particle: compare one step of 5 particles with 5 separate UKFs.
    Q, R = np.diag([1e-4, 1e-3]), np.diag([0.01, 0.05])
    rng = np.random.default_rng(4)
    upf = UnscentedParticleFilter(
        2, 2, pendulum_fx, pendulum_hx, MerweScaledSigmaPoints(2, 0.5),
        rng=rng, n_particles=5, resample_threshold=0.0,
    )  # fmt: skip
    upf.Q, upf.R = Q, R
    upf.initialize([0.8, 0.0], np.diag([0.1, 0.2]))
    start, start_P = upf.particles.copy(), upf.particle_P.copy()
    z = np.array([0.7, 0.1])
    upf.step(z, 0.05)
    for i in range(5):
        ukf = UnscentedKalmanFilter(2, 2, pendulum_fx, pendulum_hx, MerweScaledSigmaPoints(2, 0.5))
        ukf.Q, ukf.R, ukf.x, ukf.P = Q, R, start[i], start_P[i]
        ukf.predict(0.05)
        ukf.update(z)
        np.testing.assert_allclose(upf.proposal_mean[i], ukf.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(upf.particle_P[i], ukf.P, rtol=0, atol=1e-12)
    assert not upf.resampled
    # the particles are draws around those means, not the means themselves
    assert not np.allclose(upf.particles, upf.proposal_mean)


@pytest.mark.parametrize("rule", ["full", "likelihood"])
def test_upf_weights_give_the_exact_posterior_in_the_large_n_limit(rule: str) -> None:
    # One step from particles drawn from the exact prior, no resampling: the weighted
    # particles are an importance sample of the exact posterior p(x_1 | z_1), which on a
    # linear-Gaussian model is the KF's N(x, P). With ESS effective samples the weighted
    # mean has sd sqrt(P_jj / ESS) and the weighted variance sd P_jj sqrt(2 / ESS): both
    # must be within 5 sd. The heuristic "likelihood" rule (no p/q correction) counts
    # z twice and must fail the same check.
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    Q = np.array([[0.5, 0.1], [0.1, 0.3]])
    H = np.array([[1.0, 0.5]])
    R, x0, P0 = np.array([[0.5]]), np.array([0.3, -0.2]), np.diag([2.0, 1.0])
    z = np.array([2.0])
    upf = UnscentedParticleFilter(
        2, 1, lambda x, dt: x @ F.T, lambda x: x @ H.T, MerweScaledSigmaPoints(2, 1.0),
        rng=np.random.default_rng(3), n_particles=100_000, resample_threshold=0.0,
        weight_rule=rule,
    )  # fmt: skip
    upf.Q, upf.R = Q, R
    upf.initialize(x0, P0)
    upf.step(z, 1.0)
    kf = KalmanFilter(2, 1)
    kf.F, kf.Q, kf.H, kf.R, kf.x, kf.P = F, Q, H, R, x0, P0
    kf.predict()
    kf.update(z)
    d = np.diag(kf.P)
    ok_mean = np.all(np.abs(upf.x - kf.x) <= 5 * np.sqrt(d / upf.ess))
    ok_var = np.all(np.abs(np.diag(upf.P) - d) <= 5 * d * np.sqrt(2 / upf.ess))
    assert upf.ess > 10_000
    assert (ok_mean and ok_var) == (rule == "full"), (upf.x, kf.x, np.diag(upf.P), d)


def test_upf_tracks_the_kalman_posterior_on_a_linear_gaussian_model() -> None:
    # Engineering bound, not a theorem (this seed gives 0.33 and 0.84):
    # over 30 steps with 500 particles the UPF mean must stay within 0.5 posterior sigma
    # of the KF mean (time-averaged |error| / sigma) and its variance within a factor 2.
    # The process noise is made comparable to the posterior covariance: the UPF proposal
    # N(m_i, P_i) is as wide as the posterior, so with Q << P the p(x_k | x_k-1) / q
    # ratio makes the weights degenerate (ESS ~ 1 every step; a known UPF limitation).
    rng = np.random.default_rng(77)
    Q = 1000 * Q_CV
    L = np.linalg.cholesky(Q)
    x, zs = X0_CV.copy(), []
    for _ in range(30):
        x = F_CV @ x + L @ rng.standard_normal(4)
        zs.append(H_CV @ x + np.sqrt(np.diag(R_CV)) * rng.standard_normal(2))
    kf = cv_kf()
    kf.Q = Q
    upf = UnscentedParticleFilter(
        4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints(4, 0.5), rng=rng, n_particles=500
    )
    upf.Q, upf.R = Q, R_CV
    upf.initialize(X0_CV, P0_CV)
    rel_err, var_ratio = [], []
    for z in zs:
        kf.predict()
        kf.update(z)
        upf.step(z, DT)
        sd = np.sqrt(np.diag(kf.P))
        rel_err.append(np.abs(upf.x - kf.x) / sd)
        var_ratio.append(np.diag(upf.P) / np.diag(kf.P))
        assert 1.0 <= upf.last_ess <= 500.0 and upf.resampled == (upf.last_ess < 250.0)
    assert np.mean(rel_err) < 0.5, np.mean(rel_err)
    assert 0.5 < np.median(var_ratio) < 2.0, np.median(var_ratio)
    assert np.sum(upf.weights) == pytest.approx(1.0)
    assert upf.particles.shape == (500, 4) and upf.particle_P.shape == (500, 4, 4)


def test_upf_full_rule_degenerates_when_q_is_much_smaller_than_p() -> None:
    # The documented limitation: with the CV model's own small Q the proposal N(m_i, P_i)
    # is far wider than p(x_k | x_k-1), and the ESS collapses to ~1 at every step.
    rng = np.random.default_rng(5)
    _, zs = simulate_cv(rng, 15, 1)
    upf = UnscentedParticleFilter(
        4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints(4, 0.5), rng=rng, n_particles=200
    )
    upf.Q, upf.R = Q_CV, R_CV
    upf.initialize(X0_CV, P0_CV)
    ess = []
    for z in zs[0]:
        upf.step(z, DT)
        ess.append(upf.last_ess)
    assert np.median(ess) < 5.0 and upf.n_resamples == 15


def test_gaussian_sum_mode_picks_the_right_hypothesis() -> None:
    # proposal="mean": two UKF components at -5 and +5; data near +5. The weight of the
    # right component must go to 1 and the estimate to that component's KF solution.
    rng = np.random.default_rng(6)
    upf = UnscentedParticleFilter(
        1, 1, lambda x, dt: x, lambda x: x, MerweScaledSigmaPoints(1, 1.0),
        rng=rng, n_particles=2, proposal="mean", resample_threshold=0.0,
    )  # fmt: skip
    upf.Q, upf.R = 1e-4, 0.25
    upf.set_particles([[-5.0], [5.0]], np.eye(1), weights=[0.9, 0.1])
    kf = KalmanFilter(1, 1)
    kf.x, kf.P, kf.Q, kf.H, kf.R = [5.0], 1.0, 1e-4, [[1.0]], 0.25
    for _ in range(10):
        z = [4.8 + 0.5 * rng.standard_normal()]
        upf.step(z, 1.0)
        kf.predict()
        kf.update(z)
    assert upf.weights[1] > 1 - 1e-12
    assert upf.x[0] == pytest.approx(kf.x[0], abs=1e-9)
    np.testing.assert_allclose(upf.particle_P[1], kf.P, atol=1e-12)


def test_upf_is_reproducible_for_a_seed() -> None:
    def run(seed: int) -> np.ndarray:
        upf = UnscentedParticleFilter(
            4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints(4, 0.5),
            rng=np.random.default_rng(seed), n_particles=50,
        )  # fmt: skip
        upf.Q, upf.R = Q_CV, R_CV
        upf.initialize(X0_CV, P0_CV)
        for k in range(5):
            upf.step([0.1 * k, 3.0], DT)
        return upf.x

    np.testing.assert_array_equal(run(5), run(5))
    assert not np.array_equal(run(5), run(6))


def test_upf_full_weight_rule_needs_a_positive_definite_q() -> None:
    upf = UnscentedParticleFilter(
        4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints(4, 0.5),
        rng=np.random.default_rng(0), n_particles=10,
    )  # fmt: skip
    upf.initialize(X0_CV, P0_CV)  # Q left at zero
    with pytest.raises(CovarianceError, match="Q"):
        upf.step([1.0, 3.0], DT)
    upf.weight_rule = "likelihood"
    upf.step([1.0, 3.0], DT)
    assert np.all(np.isfinite(upf.x))


# ----------------------------------------------------------------------------------------
# Bad input
# ----------------------------------------------------------------------------------------
def _pts4() -> MerweScaledSigmaPoints:
    return MerweScaledSigmaPoints(4, 0.5)


def _drop_one(x: np.ndarray, dt: float) -> np.ndarray:
    return x[..., :3]


def _set(obj: object, name: str, value: object) -> None:
    setattr(obj, name, value)


BAD_SHAPES = [
    ("x", lambda: _set(cv_kf(), "x", np.zeros(3))),
    ("P", lambda: _set(cv_kf(), "P", np.eye(3))),
    ("H", lambda: _set(cv_kf(), "H", np.zeros((2, 3)))),
    ("R", lambda: _set(cv_kf(), "R", np.eye(3))),
    ("z", lambda: cv_kf().update([1.0, 2.0, 3.0])),
    ("F", lambda: cv_kf().predict(F=np.eye(3))),
    ("u", lambda: KalmanFilter(2, 1, dim_u=1).predict(u=[1.0, 2.0])),
    ("R", lambda: cv_kf().update([1.0], H=[[1, 0, 0, 0]])),
    ("G", lambda: van_loan(np.eye(2), np.ones((3, 1)), 1.0, 0.1)),
    ("Qc", lambda: van_loan(np.eye(2), np.ones((2, 1)), np.eye(2), 0.1)),
    ("A", lambda: van_loan(np.ones((2, 3)), np.ones((2, 1)), 1.0, 0.1)),
    ("H", lambda: observability_rank(np.eye(3), np.ones((1, 2)))),
    ("P", lambda: _pts4().sigma_points(np.zeros(4), np.eye(3))),
    ("x", lambda: _pts4().sigma_points(np.zeros(3), np.eye(4))),
    ("Wm", lambda: unscented_transform(np.zeros((9, 2)), np.ones(8), np.ones(9))),
    ("points", lambda: UnscentedKalmanFilter(3, 2, cv_fx, cv_hx, _pts4())),
    ("fx", lambda: UnscentedKalmanFilter(4, 2, _drop_one, cv_hx, _pts4()).predict(0.1)),
    ("H_jac", lambda: ExtendedKalmanFilter(4, 2).update([1, 2], cv_hx, np.eye(4))),
    ("weights", lambda: systematic_resample(np.ones((2, 2)), np.random.default_rng(0))),
    ("P", lambda: nees(np.zeros(3), np.eye(2))),
    ("S", lambda: nis(np.zeros(3), np.eye(2))),
]  # fmt: skip


@pytest.mark.parametrize("arg, call", BAD_SHAPES, ids=[a for a, _ in BAD_SHAPES])
def test_bad_shapes_raise_a_value_error_naming_the_argument(arg: str, call) -> None:
    with pytest.raises(ShapeError, match=rf"^{arg}\b.*expected") as info:
        call()
    assert isinstance(info.value, ValueError)
    assert "got" in str(info.value)


def test_bad_types_and_values() -> None:
    with pytest.raises(EstimatorTypeError, match="^fx: expected a callable, got int"):
        UnscentedKalmanFilter(4, 2, 3, cv_hx, _pts4())
    with pytest.raises(TypeError, match="^rng: expected numpy.random.Generator"):
        systematic_resample([0.5, 0.5], 0)
    with pytest.raises(ValueError, match="^weights: expected finite non-negative"):
        systematic_resample([0.5, -0.5], np.random.default_rng(0))
    with pytest.raises(CovarianceError, match="^P:"):
        _pts4().sigma_points(np.zeros(4), -np.eye(4))
    with pytest.raises(ValueError, match="^z: expected finite"):
        cv_kf().update([np.nan, 1.0])
    with pytest.raises(ValueError, match="^dt:"):
        van_loan(np.eye(1), np.eye(1), 1.0, -1.0)
    with pytest.raises(ValueError, match="^proposal:"):
        UnscentedParticleFilter(
            4, 2, cv_fx, cv_hx, _pts4(), rng=np.random.default_rng(0), proposal="best"
        )
