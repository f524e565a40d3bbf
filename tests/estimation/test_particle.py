"""Tests of cosim.estimation.particle: systematic resampling and the UPF."""

from __future__ import annotations

import numpy as np
import pytest
from estimation_models import (
    DT,
    F_CV,
    H_CV,
    P0_CV,
    Q_CV,
    R_CV,
    X0_CV,
    cv_fx,
    cv_hx,
    cv_kf,
    pendulum_fx,
    pendulum_hx,
    pts4,
    simulate_cv,
)

from cosim.estimation import (
    CovarianceError,
    KalmanFilter,
    MerweScaledSigmaPoints,
    ShapeError,
    UnscentedKalmanFilter,
    UnscentedParticleFilter,
    nis,
    systematic_resample,
)


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


BAD_SHAPES = [
    ("weights", lambda: systematic_resample(np.ones((2, 2)), np.random.default_rng(0))),
]  # fmt: skip


@pytest.mark.parametrize("arg, call", BAD_SHAPES, ids=[a for a, _ in BAD_SHAPES])
def test_bad_shapes_raise_a_value_error_naming_the_argument(arg: str, call) -> None:
    with pytest.raises(ShapeError, match=rf"^{arg}\b.*expected") as info:
        call()
    assert isinstance(info.value, ValueError)
    assert "got" in str(info.value)


def test_bad_types_and_values() -> None:
    with pytest.raises(TypeError, match="^rng: expected numpy.random.Generator"):
        systematic_resample([0.5, 0.5], 0)
    with pytest.raises(ValueError, match="^weights: expected finite non-negative"):
        systematic_resample([0.5, -0.5], np.random.default_rng(0))
    with pytest.raises(ValueError, match="^proposal:"):
        UnscentedParticleFilter(
            4, 2, cv_fx, cv_hx, pts4(), rng=np.random.default_rng(0), proposal="best"
        )
