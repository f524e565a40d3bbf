"""The one covariance-analysis loop and its history (cosim/estimation/covariance.py)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.estimation import van_loan
from cosim.estimation.covariance import CovarianceHistory, covariance_analysis


def _model() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 3-state chain (position, velocity, bias) seen in position: Phi, Qd, H, R."""
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -0.01]])
    G = np.array([[0.0], [1.0], [0.0]])
    Phi, Qd = van_loan(A, G, np.array([[0.04]]), 0.1)
    return Phi, Qd, np.array([[1.0, 0.0, 0.0]]), np.array([[0.25]])


def test_loop_equals_the_hand_written_joseph_recursion() -> None:
    """Predict every step, Joseph update every 5th: the textbook recursion, to 1e-12."""
    Phi, Qd, H, R = _model()
    P0 = np.diag([1.0, 0.5, 0.1])
    hist = covariance_analysis(
        P0, 200, 0.1, lambda k: (Phi, Qd), lambda k: (H, R) if (k + 1) % 5 == 0 else None
    )
    P, want = P0.copy(), [P0.copy()]
    for k in range(200):
        P = Phi @ P @ Phi.T + Qd
        if (k + 1) % 5 == 0:
            S = H @ P @ H.T + R
            K = np.linalg.solve(S, H @ P).T
            ikh = np.eye(3) - K @ H
            P = ikh @ P @ ikh.T + K @ R @ K.T
            P = 0.5 * (P + P.T)
        want.append(P)
    np.testing.assert_allclose(hist.P, np.array(want), rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(hist.time, np.arange(201) * 0.1, rtol=1e-15)
    assert hist.sigma.shape == (201, 3)
    np.testing.assert_array_equal(hist.sigma[7], np.sqrt(np.diag(hist.P[7])))


def test_recording_options_and_the_meaning_of_at_and_index() -> None:
    """``at(t)`` is the covariance matrix, ``index(t)`` its row, at the nearest time."""
    Phi, Qd, H, R = _model()
    hist = covariance_analysis(
        np.eye(3),
        100,
        0.1,
        lambda k: (Phi, Qd),
        lambda k: (H, R),
        record_every=10,
        include_start=False,
        names=("p", "v", "b"),
    )
    assert isinstance(hist, CovarianceHistory) and hist.names == ("p", "v", "b")
    np.testing.assert_allclose(hist.time, np.arange(1, 11) * 1.0)
    assert hist.index(3.4) == 2 and hist.index(3.6) == 3 and hist.index(99.0) == 9
    np.testing.assert_array_equal(hist.at(3.6), hist.P[3])
    assert hist.at(3.6).shape == (3, 3)
    # without measurements the covariance only grows
    free = covariance_analysis(np.eye(3), 10, 0.1, lambda k: (Phi, Qd))
    assert np.all(np.diff(free.sigma[:, 0]) > 0.0)
    with pytest.raises(ValueError, match="n_steps"):
        covariance_analysis(np.eye(3), 0, 0.1, lambda k: (Phi, Qd))
