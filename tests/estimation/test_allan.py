"""Overlapping Allan deviation (cosim.estimation.allan) against the theory of its noise terms.

Tolerances: the estimate's relative standard error is ``1 / sqrt(2 edf)`` with the
equivalent degrees of freedom of NIST SP 1065 (``cosim.estimation.allan.relative_error``); each
check allows four of those standard errors (a fixed seed makes the outcome
deterministic; four sigma keeps it robust to a change of generator stream).
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.estimation.allan import (
    allan_deviation,
    allan_variance,
    cluster_sizes,
    edf_overlapping,
    relative_error,
)

DT = 0.01  # s
N_SAMPLES = 1_000_000


def test_white_rate_noise_follows_n_over_sqrt_tau() -> None:
    # Theory: white rate noise of density N sampled as means over dt has variance
    # N^2 / dt per sample and avar(tau) = N^2 / tau exactly.
    density = 3.0e-6  # rad/sqrt(s)
    rng = np.random.default_rng(11)
    y = density / np.sqrt(DT) * rng.standard_normal(N_SAMPLES)
    m = np.array([1, 10, 100, 1000])
    tau, adev = allan_deviation(y, DT, m)
    expected = density / np.sqrt(tau)
    for mi, a, e in zip(m, adev, expected, strict=True):
        tol = 4.0 * relative_error(N_SAMPLES, int(mi), "white")
        assert abs(a / e - 1.0) < tol, (mi, a / e - 1.0, tol)


def test_rate_random_walk_follows_k_sqrt_tau_over_3() -> None:
    # Theory: for y_k = y_(k-1) + K sqrt(dt) w_k (sampled random walk) the exact
    # discrete Allan variance is K^2 (tau / 3 + dt^2 / (6 tau)) (cosim.estimation.allan docstring).
    k_rrw = 2.0e-7  # rad/s/sqrt(s)
    rng = np.random.default_rng(12)
    y = np.cumsum(k_rrw * np.sqrt(DT) * rng.standard_normal(N_SAMPLES))
    m = np.array([1, 10, 100, 1000])
    tau, avar = allan_variance(y, DT, m)
    expected = k_rrw**2 * (tau / 3.0 + DT**2 / (6.0 * tau))
    for mi, a, e in zip(m, np.sqrt(avar), np.sqrt(expected), strict=True):
        tol = 4.0 * relative_error(N_SAMPLES, int(mi), "rrw")
        assert abs(a / e - 1.0) < tol, (mi, a / e - 1.0, tol)
    # The slope on the log-log plot is +1/2 at long tau.
    slope = np.diff(np.log(np.sqrt(avar[1:]))) / np.diff(np.log(tau[1:]))
    assert np.all(np.abs(slope - 0.5) < 0.1)


def test_increments_rates_and_axes_are_equivalent() -> None:
    rng = np.random.default_rng(13)
    y = rng.standard_normal((20_000, 3)) + np.array([5.0, -2.0, 9.81])  # offsets are ignored
    m = cluster_sizes(y.shape[0])
    tau_r, adev_r = allan_deviation(y, DT, m)
    tau_i, adev_i = allan_deviation(y * DT, DT, m, increments=True)
    np.testing.assert_array_equal(tau_r, tau_i)
    np.testing.assert_allclose(adev_i, adev_r, rtol=1e-10)
    for axis in range(3):
        _, single = allan_deviation(y[:, axis] - y[:, axis].mean(), DT, m)
        np.testing.assert_allclose(single, adev_r[:, axis], rtol=1e-10)


def test_edf_matches_the_spread_of_repeated_estimates() -> None:
    # 400 independent white-noise records; the spread of their ADEV at m = 10 must
    # match 1 / sqrt(2 edf). The spread of a std estimated from 400 values has a
    # relative error of about 1 / sqrt(2 * 399) = 3.5 %, so 15 % is > 4 sigma.
    n, m = 5_000, 10
    rng = np.random.default_rng(14)
    y = rng.standard_normal((n, 400))
    _, adev = allan_deviation(y, 1.0, m)
    spread = np.std(adev[0]) / np.mean(adev[0])
    assert abs(spread / relative_error(n, m, "white") - 1.0) < 0.15


def test_cluster_sizes_and_argument_checks() -> None:
    m = cluster_sizes(1000)
    assert m[0] == 1 and m[-1] == 499 and np.all(np.diff(m) > 0)
    assert edf_overlapping(1000, 1, "white") > edf_overlapping(1000, 100, "white")
    with pytest.raises(ValueError):
        allan_variance(np.zeros(10), DT, 6)
    with pytest.raises(ValueError):
        allan_variance(np.zeros(10), -1.0, 1)
    with pytest.raises(ValueError):
        edf_overlapping(10, 1, "flicker")


@pytest.mark.parametrize("kind", ["white", "random_walk", "increments"])
def test_equals_allantools_oadev_to_1e_12(kind: str) -> None:
    # cosim.estimation.allan stays (README, "Real sensor data"): the model tests use it on
    # (n, 3) records and on increments without a dependency of models/ on allantools;
    # it must be the same estimator as allantools' oadev, which characterize uses.
    allantools = pytest.importorskip("allantools")
    rng = np.random.default_rng(15)
    n = 50_000
    y = rng.standard_normal(n) * 1e-3 + 0.7
    if kind == "random_walk":
        y = np.cumsum(y - 0.7) * 1e-2
    m = cluster_sizes(n)
    if kind == "increments":
        tau, ours = allan_deviation(y * DT, DT, m, increments=True)
    else:
        tau, ours = allan_deviation(y, DT, m)
    taus, theirs, _, _ = allantools.oadev(y, rate=1.0 / DT, data_type="freq", taus=tau)
    np.testing.assert_allclose(taus, tau, rtol=1e-15)
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=0.0)


# ------------------------------------------------------------------ streamed octaves
def test_octave_allan_streamed_equals_oadev_and_the_stride_subset() -> None:
    """OctaveAllan (one pass, in chunks) against allantools' oadev and the direct sums.

    Up to ``m = span`` it is the fully overlapping estimator: allantools ``oadev`` to
    1e-12. Beyond, it sums exactly the second differences whose start index is a multiple
    of ``m / span``: the direct sum over that subset, to 1e-12. Chunking changes nothing.
    """
    import allantools

    from cosim.estimation.allan import OctaveAllan

    rng = np.random.default_rng(21)
    n, span = 50_000, 32
    y = rng.standard_normal((n, 2)) + np.cumsum(1e-3 * rng.standard_normal((n, 2)), axis=0) + 7.0
    results = []
    for chunk in (n, 4096, 999):
        acc = OctaveAllan(2, span=span)
        for lo in range(0, n, chunk):
            acc.update(y[lo : lo + chunk] * DT)
        m, avar = acc.avar(DT)
        results.append(avar)
    assert np.allclose(results[1], results[0], rtol=1e-12, atol=0.0)
    assert np.allclose(results[2], results[0], rtol=1e-12, atol=0.0)
    assert list(m) == [2**j for j in range(int(np.log2(n // 4)) + 1)]
    full = m <= span
    _, dev, _, _ = allantools.oadev(y[:, 1], rate=1.0 / DT, data_type="freq", taus=m[full] * DT)
    assert np.allclose(results[0][full, 1], dev**2, rtol=1e-12, atol=0.0)
    theta = np.concatenate([[0.0], np.cumsum((y[:, 0] - y[:4096, 0].mean()) * DT)])
    for i in np.flatnonzero(~full):
        p = theta[:: m[i] // span]
        second = p[2 * span :] - 2.0 * p[span:-span] + p[: -2 * span]
        direct = np.mean(second**2) / (2.0 * (m[i] * DT) ** 2)
        assert results[0][i, 0] == pytest.approx(direct, rel=1e-12)


@pytest.mark.parametrize("kind", ["white", "random walk"])
def test_octave_allan_beyond_span_keeps_the_overlapping_variance(kind: str) -> None:
    """The stride-``m / span`` estimate varies as the fully overlapping one does.

    200 records of 2^13 samples, span 16 (the package uses 1024): at the four largest
    octaves (m = 128 .. 1024, strides 8 .. 64) the variance of the estimate over the
    records is that of the fully overlapping estimate within 10 %. Both are computed on
    the same records, so the ratio's own sampling error is small (it was within 3 % in
    a 400-record run of 2^15 samples).
    """
    from cosim.estimation.allan import OctaveAllan

    rng = np.random.default_rng(22)
    n, reps = 2**13, 200
    ours, full = [], []
    for _ in range(reps):
        y = rng.standard_normal(n)
        if kind == "random walk":
            y = np.cumsum(y)
        for span, out in ((16, ours), (2**20, full)):
            acc = OctaveAllan(1, span=span, octaves=12)
            acc.update(y[:, None])
            out.append(acc.avar(1.0)[1][-4:, 0])
    ratio = np.var(ours, axis=0) / np.var(full, axis=0)
    assert np.all(np.abs(ratio - 1.0) < 0.1), ratio
