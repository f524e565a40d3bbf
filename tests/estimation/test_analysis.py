"""Tests of cosim.estimation.analysis: Van Loan, observability ranks, NEES/NIS."""

from __future__ import annotations

import numpy as np
import pytest
from estimation_models import A_CV, H_CV
from scipy.linalg import expm, solve_continuous_lyapunov

from cosim.estimation import (
    ShapeError,
    nees,
    nis,
    observability_rank,
    piecewise_observability_rank,
    stripped_condition_holds,
    van_loan,
)


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


def test_nees_and_nis_broadcast_and_agree_with_the_definition() -> None:
    rng = np.random.default_rng(1)
    P = np.array([[2.0, 0.3], [0.3, 0.5]])
    e = rng.standard_normal((7, 2))
    expected = np.einsum("ki,ij,kj->k", e, np.linalg.inv(P), e)
    np.testing.assert_allclose(nees(e, P), expected, rtol=1e-12)
    np.testing.assert_allclose(nis(e, np.broadcast_to(P, (7, 2, 2))), expected, rtol=1e-12)
    assert isinstance(nees(e[0], P), float)


BAD_SHAPES = [
    ("G", lambda: van_loan(np.eye(2), np.ones((3, 1)), 1.0, 0.1)),
    ("Qc", lambda: van_loan(np.eye(2), np.ones((2, 1)), np.eye(2), 0.1)),
    ("A", lambda: van_loan(np.ones((2, 3)), np.ones((2, 1)), 1.0, 0.1)),
    ("H", lambda: observability_rank(np.eye(3), np.ones((1, 2)))),
    ("P", lambda: nees(np.zeros(3), np.eye(2))),
    ("S", lambda: nis(np.zeros(3), np.eye(2))),
]  # fmt: skip


@pytest.mark.parametrize("arg, call", BAD_SHAPES, ids=[a for a, _ in BAD_SHAPES])
def test_bad_shapes_raise_a_value_error_naming_the_argument(arg: str, call) -> None:
    with pytest.raises(ShapeError, match=rf"^{arg}\b.*expected") as info:
        call()
    assert isinstance(info.value, ValueError)
    assert "got" in str(info.value)


def test_bad_values() -> None:
    with pytest.raises(ValueError, match="^dt:"):
        van_loan(np.eye(1), np.eye(1), 1.0, -1.0)
