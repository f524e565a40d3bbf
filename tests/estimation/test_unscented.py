"""Tests of cosim.estimation.unscented, sigma_points and angles: the UKF and its points."""

from __future__ import annotations

import numpy as np
import pytest
from estimation_models import (
    DT,
    P0_CV,
    Q_CV,
    R_CV,
    X0_CV,
    cv_fx,
    cv_hx,
    cv_kf,
    cv_ukf,
    pts4,
    simulate_cv,
)

from cosim.estimation import (
    CovarianceError,
    EstimatorTypeError,
    JulierSigmaPoints,
    MerweScaledSigmaPoints,
    ShapeError,
    UnscentedKalmanFilter,
    UnscentedParticleFilter,
    angle_mean,
    angle_mean_fn,
    angle_residual,
    angle_residual_fn,
    unscented_transform,
)
from cosim.models.conventions import wrap_angle


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
# Sigma points are duck-typed: Julier's, Merwe's or a user's own set
# ----------------------------------------------------------------------------------------
class CubaturePoints:
    """A user's own set, written against the documented interface only.

    The cubature rule (Arasaratnam & Haykin 2009): ``2n`` points ``x +/- sqrt(n) a_i``
    for the columns ``a_i`` of a symmetric square root of ``P``, equal weights. It has
    no central point, no ``batched`` flag and no ``robust`` keyword, and lays its points
    out one per row as filterpy does.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.Wm = np.full(2 * n, 0.5 / n)
        self.Wc = self.Wm.copy()
        self.calls = 0

    def num_sigmas(self) -> int:
        return 2 * self.n

    def sigma_points(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:
        assert x.shape == (self.n,) and P.shape == (self.n, self.n)  # never a stack
        self.calls += 1
        w, V = np.linalg.eigh(P)
        D = (V * np.sqrt(self.n * w)).T  # rows: sqrt(n) times the columns of sqrt(P)
        return np.concatenate([x + D, x - D])


def linear_map_case(n: int = 4, d: int = 3) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(7)
    M = rng.standard_normal((n, n))
    P = M @ M.T + 0.1 * np.eye(n)
    x = rng.standard_normal(n)
    T, b = rng.standard_normal((d, n)), rng.standard_normal(d)
    return x, P, T, b


@pytest.mark.parametrize("kappa", [0.0, 1.0, -1.0, 2.5])
def test_julier_points_are_exact_for_linear_maps(kappa: float) -> None:
    x, P, T, b = linear_map_case()
    pts = JulierSigmaPoints(4, kappa)
    assert pts.num_sigmas() == 9 and pts.sigma_points(x, P).shape == (9, 4)
    assert np.sum(pts.Wm) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_array_equal(pts.Wm, pts.Wc)
    noise = np.diag([0.1, 0.2, 0.3])
    mean, cov = unscented_transform(pts.sigma_points(x, P) @ T.T + b, pts.Wm, pts.Wc, noise)
    exact_mean, exact_cov = T @ x + b, T @ P @ T.T + noise
    np.testing.assert_allclose(mean, exact_mean, rtol=0, atol=1e-12 * np.abs(exact_mean).max())
    np.testing.assert_allclose(cov, exact_cov, rtol=0, atol=1e-12 * np.abs(exact_cov).max())
    # Julier's set is Merwe's with alpha = 1, beta = 0
    merwe = MerweScaledSigmaPoints(4, 1.0, 0.0, kappa)
    np.testing.assert_allclose(pts.Wm, merwe.Wm, rtol=1e-15, atol=1e-16)
    np.testing.assert_allclose(pts.Wc, merwe.Wc, rtol=1e-15, atol=1e-16)
    np.testing.assert_array_equal(pts.sigma_points(x, P), merwe.sigma_points(x, P))


@pytest.mark.parametrize("kappa", [1.0, -1.0])
def test_ukf_with_julier_points_equals_the_kf(kappa: float) -> None:
    rng = np.random.default_rng(11)
    _, zs = simulate_cv(rng, 50, 1)
    kf = cv_kf()
    ukf = UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, JulierSigmaPoints(4, kappa))
    ukf.Q, ukf.R, ukf.x, ukf.P = Q_CV, R_CV, X0_CV, P0_CV
    for z in zs[0]:
        kf.predict()
        ukf.predict(DT)
        kf.update(z)
        ukf.update(z)
        for name in ("x_prior", "P_prior", "x", "P", "K", "y", "S"):
            np.testing.assert_allclose(getattr(ukf, name), getattr(kf, name), rtol=0, atol=1e-9)
        assert ukf.log_likelihood == pytest.approx(kf.log_likelihood, abs=1e-9)


def test_a_users_own_sigma_points_run_in_the_ukf_and_the_upf() -> None:
    # the UKF with the user's set is still exact on the linear model
    rng = np.random.default_rng(12)
    _, zs = simulate_cv(rng, 30, 1)
    kf = cv_kf()
    ukf = UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, CubaturePoints(4))
    ukf.Q, ukf.R, ukf.x, ukf.P = Q_CV, R_CV, X0_CV, P0_CV
    for z in zs[0]:
        kf.predict()
        ukf.predict(DT)
        kf.update(z)
        ukf.update(z)
        np.testing.assert_allclose(ukf.x, kf.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ukf.P, kf.P, rtol=0, atol=1e-9)
    assert ukf.sigmas_f.shape == (8, 4) and ukf.points.calls == 60
    # the UPF calls an unbatched set once per particle; its proposals are per-particle
    # UKF steps with the same set, and the "full" weight (which needs fx at each
    # particle, here not a sigma point) is finite
    upf = UnscentedParticleFilter(
        4, 2, cv_fx, cv_hx, CubaturePoints(4), rng=np.random.default_rng(4),
        n_particles=5, resample_threshold=0.0,
    )  # fmt: skip
    upf.Q, upf.R = 1000 * Q_CV, R_CV
    upf.initialize(X0_CV, P0_CV)
    start, start_P = upf.particles.copy(), upf.particle_P.copy()
    upf.step(zs[0][0], DT)
    assert upf.points.calls == 10  # 5 particles, predict + update
    assert np.all(np.isfinite(upf.weights)) and upf.weights.sum() == pytest.approx(1.0)
    for i in range(5):
        one = UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, CubaturePoints(4))
        one.Q, one.R, one.x, one.P = 1000 * Q_CV, R_CV, start[i], start_P[i]
        one.predict(DT)
        one.update(zs[0][0])
        np.testing.assert_allclose(upf.proposal_mean[i], one.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(upf.particle_P[i], one.P, rtol=0, atol=1e-12)


class OnlyPoints:
    n = 4

    def sigma_points(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:
        return np.zeros((9, 4))


class CountNotCallable(CubaturePoints):
    num_sigmas = 8  # an attribute, not filterpy's method


def test_points_without_the_interface_raise_a_type_error_naming_what_is_missing() -> None:
    with pytest.raises(
        TypeError, match=r"^points: expected .* got OnlyPoints without Wm, Wc, num_sigmas$"
    ):
        UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, OnlyPoints())
    with pytest.raises(TypeError, match=r"without num_sigmas\(\) \(not callable\)$"):
        UnscentedParticleFilter(
            4, 2, cv_fx, cv_hx, CountNotCallable(4), rng=np.random.default_rng(0)
        )
    with pytest.raises(
        TypeError, match=r"^points: .* got class MerweScaledSigmaPoints \(pass an instance\)"
    ):
        UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, MerweScaledSigmaPoints)  # the class
    ukf = cv_ukf(0.5)
    with pytest.raises(TypeError, match="without Wm, Wc, num_sigmas"):
        ukf.points = OnlyPoints()  # assignment is checked like the constructor
    bad = CubaturePoints(4)
    bad.Wc = np.ones(9)
    with pytest.raises(ShapeError, match=r"^points.Wc: expected shape \(8,\)"):
        UnscentedKalmanFilter(4, 2, cv_fx, cv_hx, bad)


def drop_one(x: np.ndarray, dt: float) -> np.ndarray:
    return x[..., :3]


BAD_SHAPES = [
    ("P", lambda: pts4().sigma_points(np.zeros(4), np.eye(3))),
    ("x", lambda: pts4().sigma_points(np.zeros(3), np.eye(4))),
    ("Wm", lambda: unscented_transform(np.zeros((9, 2)), np.ones(8), np.ones(9))),
    ("points", lambda: UnscentedKalmanFilter(3, 2, cv_fx, cv_hx, pts4())),
    ("fx", lambda: UnscentedKalmanFilter(4, 2, drop_one, cv_hx, pts4()).predict(0.1)),
]  # fmt: skip


@pytest.mark.parametrize("arg, call", BAD_SHAPES, ids=[a for a, _ in BAD_SHAPES])
def test_bad_shapes_raise_a_value_error_naming_the_argument(arg: str, call) -> None:
    with pytest.raises(ShapeError, match=rf"^{arg}\b.*expected") as info:
        call()
    assert isinstance(info.value, ValueError)
    assert "got" in str(info.value)


def test_bad_types_and_values() -> None:
    with pytest.raises(EstimatorTypeError, match="^fx: expected a callable, got int"):
        UnscentedKalmanFilter(4, 2, 3, cv_hx, pts4())
    with pytest.raises(CovarianceError, match="^P:"):
        pts4().sigma_points(np.zeros(4), -np.eye(4))
