"""The fine UKF's compiled feedback (``cosim/alignment/transfer_feedback.c``) against numpy.

In stage 2, with the compiled UKF and mechanisation, :class:`TransferFilter` runs the
period and its closed-loop feedback in one call (``transfer_ukf_fed_period``); the numpy
statement is ``TransferFilter._feedback`` and the reset that follows it in ``update``.

- The feedback kernel alone, on the same state as the numpy statement (written out here
  from the same public functions), headings that need the wrap included: mechanisation,
  state after the reset, reset covariance to 1e-12 relative.
- A stage-2 period of two filters on the same state, one with the compiled mechanisation
  (the fed call), one with the numpy mechanisation (the compiled period, then
  ``_feedback``): the same to 1e-12. The two filters are brought to the same state
  without a step of the mechanisation (whose two paths differ by rounding): periods of
  zero length, and the UKF's state written through :attr:`TransferFilter.x_show` and
  :attr:`TransferFilter.P_show`, which are the UKF's own arrays.
- A failure (covariance not positive definite) changes neither the UKF nor the
  mechanisation, and the numpy UKF raises its error.
- A whole 20 s co-simulation with and without the compiled kernels.

Covariances are compared entry by entry with 1e-12 of ``sqrt(P_ii P_jj)`` (the variances
span 1e-17 to 1e-1, drifts in rad/s against velocities in m/s; a covariance entry is
bounded by it), as in ``tests/models/test_native_ukf.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from transfer_run import needs_library, runs_both_ways

from cosim.alignment.nav import MOVING_BASE, Strapdown
from cosim.alignment.nav_compiled import NAV_FIELDS, NAV_SCALARS, CompiledStrapdown, make_strapdown
from cosim.alignment.transfer import TransferAlignment
from cosim.alignment.transfer_filter import StageSettings, TransferFilter
from cosim.alignment.transfer_model import (
    StateLayout,
    TransferTuning,
    flexure_matrix,
    reset_jacobian,
)
from cosim.estimation.checks import CovarianceError
from cosim.models import native
from cosim.models.blocks.lever_arm import r0_matrix
from cosim.models.constants import DEG
from cosim.models.conventions import euler_to_dcm, wrap_angle

LAT = 30.0 * DEG
R0 = np.array([10.0, 10.0, 5.0])
REL = 1e-12
C_B_N = euler_to_dcm([0.02, -0.01, 0.5])
W_EB_B = np.array([0.01, -0.02, 0.005])
V_M = np.array([3.0, 1.0, 0.0])
#: What the feedback corrects; every other field of the mechanisation stays as it is.
CORRECTED = ("C_s_n", "v_n", "v_prev", "lat", "gyro_bias", "accel_bias")
FIELDS = tuple(NAV_FIELDS) + tuple(NAV_SCALARS)
LAYOUTS = pytest.mark.parametrize("flexure", [True, False], ids=["19 states", "13 states"])


def _state(layout: StateLayout, heading: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """An estimate and a full (correlated) covariance of the size of the filter's."""
    rng = np.random.default_rng(seed)
    m = flexure_matrix(C_B_N, W_EB_B, r0_matrix(R0)) if layout.flexure else None
    sigma = np.sqrt(np.diag(TransferTuning().P0(layout, LAT, m)))
    L = np.tril(rng.normal(size=(layout.n, layout.n)) * 0.3) + np.eye(layout.n)
    P = (sigma[:, None] * L) @ (sigma[:, None] * L).T
    x = rng.normal(size=layout.n) * sigma * 0.5
    x[layout.att] = [0.03, -0.02, heading]
    return x, 0.5 * (P + P.T)


def _numpy_feedback(
    nav: Strapdown, x: np.ndarray, P: np.ndarray, m1: np.ndarray | None, layout: StateLayout
) -> tuple[np.ndarray, np.ndarray]:
    """TransferFilter._feedback and the reset of its update, from the same functions."""
    x = x.copy()
    x[layout.heading] = wrap_angle(x[layout.heading])
    mxi = m1 @ x[layout.xi] if layout.flexure else 0.0
    nav.correct(rotation=euler_to_dcm(x[layout.att]).T, d_v=x[layout.dv] - mxi, d_lat=float(x[0]))
    nav.accel_bias = nav.accel_bias + x[layout.nabla]
    nav.gyro_bias = nav.gyro_bias + x[layout.eps]
    J = reset_jacobian(x, layout)
    P = J @ P @ J.T
    x_new = np.zeros(layout.n)
    if layout.flexure:
        x_new[layout.xi] = x[layout.xi]
        x_new[layout.dv] = mxi
    return x_new, 0.5 * (P + P.T)


def _fields(nav: Strapdown) -> dict[str, np.ndarray]:
    return {name: np.array(getattr(nav, name), dtype=float) for name in FIELDS}


def _close_nav(want: Strapdown, got: Strapdown) -> None:
    a, b = _fields(want), _fields(got)
    for name in FIELDS:
        scale = np.abs(a[name]).max()
        np.testing.assert_allclose(b[name], a[name], rtol=REL, atol=REL * scale, err_msg=name)


def _close_cov(want: np.ndarray, got: np.ndarray, name: str) -> None:
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    np.testing.assert_array_less(np.abs(got - want), REL * scale + 1e-300, err_msg=name)


def _navs() -> tuple[Strapdown, Strapdown]:
    """A compiled and a numpy mechanisation in the same state (nonzero biases, v_prev)."""
    c = euler_to_dcm([0.1, -0.2, 2.0])
    pair = (make_strapdown(c, LAT, 5.0, V_M, options=MOVING_BASE), Strapdown(c, LAT, 5.0, V_M))
    for nav in pair:
        nav.v_prev = V_M + [0.1, -0.05, 0.02]
        nav.gyro_bias = np.array([1e-6, -2e-6, 3e-7])
        nav.accel_bias = np.array([1e-3, 2e-3, -5e-4])
    assert isinstance(pair[0], CompiledStrapdown) and not isinstance(pair[1], CompiledStrapdown)
    return pair


@LAYOUTS
@pytest.mark.parametrize("heading", [0.3, 3.6, -3.5], ids=["0.3", "3.6 wraps", "-3.5 wraps"])
def test_the_kernel_feeds_back_as_numpy(flexure: bool, heading: float) -> None:
    needs_library()
    layout = StateLayout(flexure)
    kernel = native.kernel("transfer_feedback")
    x, P = _state(layout, heading, seed=1)
    m1 = flexure_matrix(C_B_N, W_EB_B, r0_matrix(R0))
    compiled, ref = _navs()
    x_in, P_in = x.copy(), P.copy()
    fed = np.zeros(layout.n + layout.n**2)
    args = (native.pointer(x), native.pointer(P), native.pointer(m1), layout.n, int(flexure))
    kernel(compiled.state_pointer, *args, layout.heading, native.pointer(fed))
    want_x, want_P = _numpy_feedback(ref, x, P, m1 if flexure else None, layout)
    assert np.array_equal(x, x_in) and np.array_equal(P, P_in)  # the posterior is read only
    _close_nav(ref, compiled)
    got_P = fed[layout.n :].reshape(layout.n, layout.n)
    _close_cov(want_P, got_P, "P")
    assert np.array_equal(got_P, got_P.T)
    np.testing.assert_allclose(fed[: layout.n], want_x, rtol=REL, atol=1e-300)
    # the attitude correction is euler_to_dcm of the wrapped angles, bit for bit (the same
    # libm calls; products with the identity are exact in both)
    for nav in (compiled, ref):
        nav.C_s_n = np.eye(3)
    kernel(compiled.state_pointer, *args, layout.heading, native.pointer(fed))
    _numpy_feedback(ref, x, P, m1 if flexure else None, layout)
    assert np.array_equal(compiled.C_s_n, ref.C_s_n)
    # the feedback did something to every field it corrects
    before = _fields(_navs()[1])
    assert all(not np.array_equal(before[n], _fields(ref)[n]) for n in CORRECTED)


def _stage2(flexure: bool, compiled: bool, monkeypatch: pytest.MonkeyPatch) -> TransferFilter:
    """A filter in stage 2 after two periods of zero length (no mechanisation step)."""
    layout = StateLayout(flexure)
    settings = StageSettings(min_time=0.0, sigma=10.0, weight=0.0)  # stage 1 ends at once
    filt = TransferFilter(layout, TransferTuning(), R0, settings, LAT)
    monkeypatch.setenv(native.ENV, "1" if compiled else "0")  # the mechanisation's path
    filt.start(C_B_N, W_EB_B, V_M, LAT, 5.0)
    monkeypatch.delenv(native.ENV)  # the UKF's period compiled in both
    assert isinstance(filt.nav, CompiledStrapdown) == compiled
    filt.update(0.0, C_B_N, W_EB_B, V_M)
    filt.update(0.0, C_B_N, W_EB_B, V_M + 0.01)
    assert filt.stage == 2.0
    return filt


@LAYOUTS
def test_a_fed_period_equals_the_period_and_the_numpy_feedback(
    flexure: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    needs_library()
    layout = StateLayout(flexure)
    fed, ref = (_stage2(flexure, compiled, monkeypatch) for compiled in (True, False))
    x, P = _state(layout, 0.2, seed=2)
    for filt in (fed, ref):  # the UKF's own arrays (see the module docstring)
        filt.x_show[:] = x
        filt.P_show[...] = P
    _close_nav(ref.nav, fed.nav)
    att = fed.nav.C_s_n
    for filt in (fed, ref):
        filt.update(0.0, C_B_N, W_EB_B, V_M + [0.2, -0.1, 0.05])
    assert np.abs(fed.nav.C_s_n - att).max() > 1e-3  # the attitude was fed back
    assert fed.nis == pytest.approx(ref.nis, rel=REL)
    _close_nav(ref.nav, fed.nav)
    _close_cov(ref.P_show, fed.P_show, "P")
    scale = np.sqrt(np.diag(ref.P_show))
    np.testing.assert_array_less(np.abs(fed.x_show - ref.x_show), REL * scale + 1e-300)
    assert np.any(fed.x_show != 0.0) == flexure  # dV = M xi, xi kept


def test_a_failed_fed_period_changes_nothing_and_numpy_raises(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    needs_library()
    filt = _stage2(True, True, monkeypatch)
    filt.x_show[:] = _state(StateLayout(True), 0.2, seed=3)[0]  # an estimate to feed back
    filt.P_show[5, 5] = -1e-6  # the UKF's covariance, no longer positive definite
    x, P, nav = filt.x_show.copy(), filt.P_show.copy(), _fields(filt.nav)
    with pytest.raises(CovarianceError, match="P"):
        filt.update(0.0, C_B_N, W_EB_B, V_M + 0.1)
    after = _fields(filt.nav)
    assert all(np.array_equal(after[name], nav[name]) for name in FIELDS)
    assert np.array_equal(filt.x_show, x) and np.array_equal(filt.P_show, P)


def test_compiled_and_numpy_runs_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    """20 s of the scenario, every kernel on vs off: the same alignment."""
    needs_library()

    def check(block: TransferAlignment, compiled: bool) -> None:
        assert isinstance(block.estimator.nav, CompiledStrapdown) == compiled

    a, b = runs_both_ways(monkeypatch, 20.0, check)
    assert np.count_nonzero(a["align.stage"] == 2.0) > 100  # 15 s of fine alignment
    # rounding of the kernels' sums against BLAS's, amplified by the filter's updates (its
    # innovation covariances are small): at most 1.3e-9 arcmin, in the acquisition, on
    # errors of up to 2200 arcmin (1e-11 in the fine alignment)
    for i in (1, 2, 3):
        col = f"align.rpy_err[{i}]"
        np.testing.assert_allclose(b[col], a[col], rtol=0.0, atol=1e-8, err_msg=col)
    np.testing.assert_allclose(b["align.nees"], a["align.nees"], rtol=1e-9, atol=1e-12)
    assert np.abs(a["align.rpy_err[3]"][-1]) < 60.0  # a converged heading [arcmin]
