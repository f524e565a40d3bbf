"""The fine UKF's compiled period (``cosim/alignment/transfer_ukf.c``) against the numpy UKF.

:class:`cosim.alignment.transfer_ukf_native.CompiledFinePeriod` must leave the UKF as its
``predict`` and ``update`` leave it, with the same NIS. The arithmetic is the same; the
sums of products run in another order than BLAS's, and the C code solves with Cholesky
factors where numpy uses LAPACK's LU and blocked Cholesky. A period's result therefore
agrees to rounding amplified by the conditioning of ``P`` (its variances span 1e-17 to
1e-1: drifts in rad/s against velocities in m/s), so each entry is compared with a
tolerance of 1e-9 of the scale of its row and column, ``sqrt(P_ii P_jj)`` (a covariance
entry is bounded by it), and states with 1e-9 of their sigma.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.alignment.transfer_filter import StageSettings, TransferFilter
from cosim.alignment.transfer_model import (
    PeriodSums,
    StateLayout,
    TransferTuning,
    flexure_matrix,
    measurement,
)
from cosim.alignment.transfer_native import make_propagate
from cosim.alignment.transfer_ukf_native import CompiledFinePeriod, make_fine_period
from cosim.estimation import (
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
    angle_mean_fn,
    angle_residual_fn,
    van_loan,
)
from cosim.estimation.checks import CovarianceError
from cosim.models.blocks.lever_arm import r0_matrix
from cosim.models.constants import DEG
from cosim.models.conventions import euler_to_dcm

LAT = 30.0 * DEG
R0 = np.array([10.0, 10.0, 5.0])
REL = 1e-9


def _setup(layout: StateLayout, heading: float) -> tuple[TransferFilter, PeriodSums, dict]:
    tuning = TransferTuning()
    filt = TransferFilter(layout, tuning, R0, StageSettings(), LAT)
    c = euler_to_dcm([0.2, -0.1, 0.5])
    m = flexure_matrix(c, np.array([0.01, -0.02, 0.005]), r0_matrix(R0))
    phi = van_loan(*tuning.flexure_model(), 0.5)[0] if layout.flexure else None
    sums = PeriodSums.constant(
        0.5, [0.1, -0.2, -9.79], c, [3.0, 1.0, 0.0], LAT, 5.0,
        m if layout.flexure else None, phi,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    P = tuning.P0(layout, LAT, m if layout.flexure else None)
    x = rng.normal(size=layout.n) * np.sqrt(np.diag(P)) * 0.3
    x[layout.heading] = heading
    args = {
        "x": x,
        "P": P,
        "Q": filt.process_noise(0.5, m if layout.flexure else None),
        "R": 1e-4 * np.eye(3),
        "z": np.array([0.02, -0.01, 0.005]),
    }
    return filt, sums, args


def _ukf(
    filt: TransferFilter, layout: StateLayout, x: np.ndarray, P: np.ndarray
) -> UnscentedKalmanFilter:
    s = StageSettings()
    ukf = UnscentedKalmanFilter(
        layout.n,
        3,
        lambda x, dt, sums: filt.propagate(x, sums),
        lambda pts: measurement(pts, layout),
        MerweScaledSigmaPoints(layout.n, s.ukf_alpha, s.ukf_beta, s.ukf_kappa),
        residual_x=angle_residual_fn([layout.heading]),
        x_mean_fn=angle_mean_fn([layout.heading]),
    )  # fmt: skip
    ukf.x, ukf.P = x.copy(), P.copy()
    return ukf


def _close_cov(want: np.ndarray, got: np.ndarray, name: str) -> None:
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    np.testing.assert_array_less(np.abs(got - want), REL * scale + 1e-300, err_msg=name)


def _crossing(layout: StateLayout) -> float:
    """A heading whose predicted mean crosses +-pi (wrapped by the mean, not the model)."""
    near = np.pi - 1e-6
    filt, sums, a = _setup(layout, near)
    ukf = _ukf(filt, layout, a["x"], a["P"])
    ukf.predict(0.5, Q=a["Q"], sums=sums)
    shift = float(ukf.x[layout.heading] - near)  # the heading's change over the period
    assert abs(shift) > 1e-9
    return float(np.sign(shift) * (np.pi - 0.5 * abs(shift)))


@pytest.mark.parametrize("flexure", [True, False], ids=["19 states", "13 states"])
@pytest.mark.parametrize("heading", [0.3, "crossing"], ids=["heading 0.3", "mean crosses pi"])
def test_compiled_period_leaves_the_ukf_as_predict_and_update(
    flexure: bool, heading: float | str
) -> None:
    layout = StateLayout(flexure)
    if heading == "crossing":
        heading = _crossing(layout)
    filt, sums, a = _setup(layout, float(heading))
    fine = make_fine_period(filt.propagate, layout.n, layout.flexure, layout.heading)
    assert isinstance(fine, CompiledFinePeriod)
    ref = _ukf(filt, layout, a["x"], a["P"])
    ref.predict(0.5, Q=a["Q"], sums=sums)
    ref.update(a["z"], R=a["R"])
    ref_nis = float(ref.y @ np.linalg.solve(ref.S, ref.y))
    got = _ukf(filt, layout, a["x"], a["P"])
    nis = fine(got, 0.5, a["Q"], a["R"], a["z"], sums)
    assert nis == pytest.approx(ref_nis, rel=1e-9)
    for name in ("P_prior", "P", "P_post"):
        _close_cov(getattr(ref, name), getattr(got, name), name)
    for name, cov in (("x_prior", ref.P_prior), ("x", ref.P_prior), ("x_post", ref.P_prior)):
        sigma = np.sqrt(np.diag(cov))
        np.testing.assert_array_less(
            np.abs(getattr(got, name) - getattr(ref, name)), REL * sigma, err_msg=name
        )
    s = np.sqrt(np.diag(ref.S))
    np.testing.assert_array_less(np.abs(got.S - ref.S), REL * np.outer(s, s), err_msg="S")
    np.testing.assert_allclose(got.z_pred, ref.z_pred, rtol=0, atol=REL * s.max())
    np.testing.assert_allclose(got.y, ref.y, rtol=0, atol=REL * s.max())
    np.testing.assert_allclose(got.K, ref.K, rtol=REL, atol=REL * np.abs(ref.K).max())


def test_a_covariance_that_is_not_positive_definite_changes_nothing_and_numpy_raises() -> None:
    layout = StateLayout(True)
    filt, sums, a = _setup(layout, 0.3)
    fine = make_fine_period(filt.propagate, layout.n, layout.flexure, layout.heading)
    P = a["P"].copy()
    P[5, 5] = -1e-6
    ukf = _ukf(filt, layout, a["x"], P)
    assert fine(ukf, 0.5, a["Q"], a["R"], a["z"], sums) is None
    assert np.array_equal(ukf.P, P) and np.array_equal(ukf.x, a["x"])
    with pytest.raises(CovarianceError, match="P"):
        ukf.predict(0.5, Q=a["Q"], sums=sums)


def test_numpy_with_the_switch_off(monkeypatch: pytest.MonkeyPatch) -> None:
    layout = StateLayout(True)
    monkeypatch.setenv("INS_COSIM_NATIVE", "0")
    prop = make_propagate(layout)
    assert make_fine_period(prop, layout.n, True, layout.heading) is None
    monkeypatch.delenv("INS_COSIM_NATIVE")
    assert make_fine_period(make_propagate(layout), layout.n, True, layout.heading) is not None
