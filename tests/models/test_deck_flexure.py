"""DeckFlexure: stationary statistics, PSD against the transfer function, white-noise term."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from scipy import signal

from cosim.models.blocks.deck_flexure import DeckFlexure, discretize_flexure
from cosim.models.constants import ARCMIN


def run(tau: tuple, sigma: tuple, h: float, steps: int, seed: int = 1) -> dict[str, np.ndarray]:
    """Run the block through its life cycle; return the outputs per step, shape (steps, 3)."""
    m = DeckFlexure()
    m.tau = np.array(tau, dtype=float)
    m.sigma = np.array(sigma, dtype=float)
    m.seed = seed
    m.setup_experiment(0.0)
    m.exit_initialization_mode()
    names = ("theta", "theta_dot", "theta_ddot", "eta", "dtheta_flex", "dtheta_dot_flex")
    out = {n: np.empty((steps + 1, 3)) for n in names}
    for n in names:
        out[n][0] = getattr(m, n)
    for k in range(steps):
        m.do_step(k * h, h)
        for n in names:
            out[n][k + 1] = getattr(m, n)
    return out


@pytest.fixture(scope="module")
def fast_run() -> dict[str, np.ndarray]:
    # tau = 10 s (beta = 0.2146 /s), h = 0.1 s, 1e5 steps = 1e4 s = 1000 tau per axis.
    return run((10.0, 10.0, 10.0), (1e-3, 2e-3, 3e-3), 0.1, 100_000, seed=7)


def test_stationary_std(fast_run: dict[str, np.ndarray]) -> None:
    # Theory: for rho(t) = (1 + beta t) exp(-beta t), var(s^2)/sigma^4 = 2 int rho^2 dt / T
    # = 5 / (beta T) -> relative std of s = sqrt(5 / (beta T)) / 2 = 2.4 % at beta T = 2146;
    # the 10 % bound is > 4 standard deviations.
    beta = 2.146 / 10.0
    sigma = np.array([1e-3, 2e-3, 3e-3])
    np.testing.assert_allclose(fast_run["theta"].std(axis=0), sigma, rtol=0.10)
    np.testing.assert_allclose(fast_run["theta_dot"].std(axis=0), beta * sigma, rtol=0.10)


def test_stationary_std_default_tau_large_step() -> None:
    # Default tau = 600 s, sigma = 2': the exact discretisation holds at h = 30 s
    # (beta h = 0.107); 2e4 steps = 6e5 s, beta T = 2146 -> 2.4 % sampling error.
    out = run((600.0, 600.0, 600.0), (2 * ARCMIN,) * 3, 30.0, 20_000, seed=3)
    np.testing.assert_allclose(out["theta"].std(axis=0), 2 * ARCMIN, rtol=0.10)


def test_psd_matches_transfer_function(fast_run: dict[str, np.ndarray]) -> None:
    # One-sided PSD of theta: S(f) = 2 q |H(j 2 pi f)|^2, H(s) = 1 / (s^2 + 2 beta s + beta^2)
    # (integrates to sigma^2). Welch with 2^14-sample Hann segments (df = 6.1e-4 Hz) gives
    # ~56 bins below beta / 2 pi = 0.034 Hz. Sampling error of a band mean: the band holds
    # B T = 0.034 Hz x 1e4 s = 340 independent cells -> 1/sqrt(340) = 5.4 % per axis,
    # 3.1 % for the mean of the three axes' ratios; bounds: 15 % on the mean (4.8 sigma),
    # 25 % per axis (4.6 sigma). Aliasing at fs = 10 Hz is < 1e-6 in the band.
    h = 0.1
    beta = 2.146 / 10.0
    sigma = np.array([1e-3, 2e-3, 3e-3])
    q = 4.0 * beta**3 * sigma**2
    f, pxx = signal.welch(fast_run["theta"], fs=1.0 / h, nperseg=2**14, axis=0)
    band = (f > 1.5 * f[1]) & (f < beta / (2.0 * np.pi))
    sys = control.tf([1.0], [1.0, 2.0 * beta, beta**2])
    mag2 = np.abs(sys(2j * np.pi * f[band])) ** 2
    theory = 2.0 * q[None, :] * mag2[:, None]
    ratio = pxx[band].mean(axis=0) / theory.mean(axis=0)
    assert band.sum() > 40
    assert ratio.mean() == pytest.approx(1.0, abs=0.15)
    np.testing.assert_allclose(ratio, 1.0, atol=0.25)
    # Total power check by the same route (integral of the theoretical PSD = sigma^2).
    fine = np.linspace(0.0, 5.0, 200_001)
    total = np.trapezoid(2.0 * np.abs(sys(2j * np.pi * fine)) ** 2, fine)
    assert total * q[0] == pytest.approx(sigma[0] ** 2, rel=1e-3)


def test_white_noise_term(fast_run: dict[str, np.ndarray]) -> None:
    # eta is the exact mean of the white noise over each step: variance q / h for any h,
    # independent between steps. 1e5 samples per axis: variance known to 0.45 % (1 sigma),
    # lag-1 correlation to 0.003; bounds 3 % and 0.015.
    h = 0.1
    beta = 2.146 / 10.0
    sigma = np.array([1e-3, 2e-3, 3e-3])
    q = 4.0 * beta**3 * sigma**2
    eta = fast_run["eta"][1:]
    np.testing.assert_allclose(eta.var(axis=0), q / h, rtol=0.03)
    for a in range(3):
        rho = np.corrcoef(eta[:-1, a], eta[1:, a])[0, 1]
        assert abs(rho) < 0.015
    # theta_ddot = -2 beta theta' - beta^2 theta + eta (eq. 1 with the step-mean noise)
    th, thd, thdd = fast_run["theta"][1:], fast_run["theta_dot"][1:], fast_run["theta_ddot"][1:]
    np.testing.assert_allclose(thdd, -2 * beta * thd - beta**2 * th + eta, rtol=0, atol=1e-18)


def test_increments(fast_run: dict[str, np.ndarray]) -> None:
    th, thd = fast_run["theta"], fast_run["theta_dot"]
    np.testing.assert_allclose(fast_run["dtheta_flex"][1:], np.diff(th, axis=0), atol=1e-18)
    np.testing.assert_allclose(fast_run["dtheta_dot_flex"][1:], np.diff(thd, axis=0), atol=1e-20)


def test_discretisation_against_quadrature() -> None:
    # Qd = integral_0^h e^(A s) G q G^T e^(A^T s) ds, by adaptive quadrature of the
    # closed-form impulse response [I, theta, theta'](s) = [(1 - (1 + b s) e^(-b s)) / b^2,
    # s e^(-b s), (1 - b s) e^(-b s)]; small, medium and large beta h (doubling branch).
    from scipy.integrate import quad

    beta, q = 0.2146, 1.0

    def resp(s: float) -> np.ndarray:
        e = math.exp(-beta * s)
        return np.array([(1.0 - (1.0 + beta * s) * e) / beta**2, s * e, (1.0 - beta * s) * e])

    for h in (0.01, 1.0, 40.0):
        _, qd = discretize_flexure(beta, q, h)
        ref = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                ref[i, j] = quad(
                    lambda s, i=i, j=j: q * resp(s)[i] * resp(s)[j], 0.0, h, epsrel=1e-11
                )[0]
        scale = np.sqrt(np.outer(np.diag(ref), np.diag(ref)))
        np.testing.assert_allclose(qd / scale, ref / scale, atol=1e-8)


def test_seed_and_reset() -> None:
    a = run((600.0,) * 3, (2 * ARCMIN,) * 3, 0.01, 50, seed=4)
    b = run((600.0,) * 3, (2 * ARCMIN,) * 3, 0.01, 50, seed=4)
    c = run((600.0,) * 3, (2 * ARCMIN,) * 3, 0.01, 50, seed=5)
    np.testing.assert_array_equal(a["theta"], b["theta"])
    assert np.max(np.abs(a["theta"] - c["theta"])) > 1e-6
    # defaults: sigma = 2 arcmin, tau = 600 s
    m = DeckFlexure()
    np.testing.assert_allclose(m.sigma, 5.8178e-4, rtol=1e-4)
    np.testing.assert_allclose(m.tau, 600.0)


def test_bad_tau() -> None:
    m = DeckFlexure()
    m.tau = np.array([600.0, 0.0, 600.0])
    m.setup_experiment(0.0)
    with pytest.raises(ValueError, match="tau"):
        m.exit_initialization_mode()
