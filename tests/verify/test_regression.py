"""The campaign's regression evidence (cosim/verify/regression.py; issue 27, item 4).

Regressors in raw SI values (a gyro drift of 1e-7 rad/s beside a misalignment of 1e-3
rad) used to be called collinear: the condition number of the unscaled normal matrix
was 1e15. The fit now standardises its columns, so only real collinearity is refused.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.verify.regression import ols

NAMES, UNITS = ("gyro_drift", "misalignment", "accel_bias"), ("rad/s", "rad", "m/s2")


def draws(n: int = 60, seed: int = 5) -> np.ndarray:
    """Independent draws in SI: drift 1e-7 rad/s, misalignment 1e-3 rad, bias 1e-3 m/s2."""
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, 3)) * np.array([1e-7, 1e-3, 1e-3])


def test_raw_si_regressors_are_not_collinear() -> None:
    """Exact linear response (no residual): the slopes come back to 1e-9 relative, and
    the fit equals numpy's least squares on the unscaled columns."""
    X = draws()
    beta = np.array([3.0e4, 0.8, -2.5])  # [arcmin per SI unit]
    y = 0.2 + X @ beta + 1e-3 * np.random.default_rng(6).standard_normal(X.shape[0])
    unscaled = np.column_stack([np.ones(X.shape[0]), X])
    assert np.linalg.cond(unscaled.T @ unscaled) > 1e12  # what the old check refused
    fit = ols(y, X, NAMES, UNITS)
    ref = np.linalg.lstsq(unscaled, y, rcond=None)[0]
    np.testing.assert_allclose(fit.slope, ref[1:], rtol=1e-8)
    assert fit.intercept == pytest.approx(ref[0], rel=1e-8)
    assert np.all(np.abs(fit.slope - beta) < 4 * fit.se)  # t with 56 dof: 4 se is 0.9998


def test_real_collinearity_and_constant_columns_are_refused() -> None:
    X = draws()
    y = X @ np.array([1.0, 1.0, 1.0])
    twin = X.copy()
    twin[:, 2] = 2.0 * twin[:, 1] * (1.0 + 1e-12 * np.arange(X.shape[0]))  # bias = 2 x mis.
    with pytest.raises(ValueError, match="collinear"):
        ols(y, twin, NAMES, UNITS)
    flat = X.copy()
    flat[:, 0] = 4e-7
    with pytest.raises(ValueError, match="gyro_drift does not vary"):
        ols(y, flat, NAMES, UNITS)


def test_a_campaign_without_a_completed_run_gets_a_sentence_not_a_numpy_error() -> None:
    """Every run failed (nan metric): the report's regression line says so in words
    (it once printed numpy's "cannot reshape array of size 0")."""
    from cosim.estimation.error_model import Regressor
    from cosim.verify.regression import regression_table

    regs = [Regressor("gyro_drift", "deg/h", 1.0, np.array([1e-7, 2e-7]))]
    out = regression_table(np.array([np.nan, np.nan]), regs, [None], "arcmin")
    assert out == {"note": "no regression: no completed run has the metric and every drawn value"}
