"""The compiled transfer-alignment error model (``cosim/alignment/transfer_model.c``).

:func:`cosim.alignment.transfer_native.make_propagate` gives the UKF's process model: the C
twin of :func:`cosim.alignment.transfer_model.propagate`, or the numpy function itself with
``INS_COSIM_NATIVE=0``. Both are compared on sigma points drawn as the filter draws them
(the acquisition bank's stack of 6 x 39 points, the fine UKF's 39, one state) with period
sums accumulated by a real :class:`cosim.alignment.nav.Strapdown` run and with
:meth:`PeriodSums.constant`, in both layouts, and at large angles.

Tolerance: 1e-12 relative, plus an absolute part per state for the values near zero. The
rounding of a result is that of the largest term summed into it, not of the result
itself: ``dV1 = dV0 + (I - Eb^T) S_f + ...`` cancels terms of the size of the period's
velocity increment ``|S_f|`` (about 5 m/s over 0.5 s) into mm/s, so its absolute rounding
is ~eps |S_f|; the Euler angles are atan2 of DCM entries of size 1, so their absolute
rounding is ~eps rad whatever the angle. Hence ``atol = 1e-12 x`` the largest such term,
state by state (:func:`_atol`); biases and drifts are copied, so they must be equal.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest

from cosim.alignment.nav import MOVING_BASE, Strapdown
from cosim.alignment.transfer_filter import StageSettings
from cosim.alignment.transfer_model import (
    PeriodSums,
    StateLayout,
    TransferTuning,
    flexure_matrix,
    propagate,
)
from cosim.alignment.transfer_native import PARAM_SIZE, CompiledPropagate, make_propagate
from cosim.estimation import MerweScaledSigmaPoints, van_loan
from cosim.models import native
from cosim.models.blocks.lever_arm import r0_matrix
from cosim.models.constants import DEG, E2, G0, OMEGA_IE, A
from cosim.models.conventions import euler_rate_to_body_rate, euler_to_dcm, wrap_angle
from cosim.models.earth import R_M

RTOL = 1e-12
LAT = 30.0 * DEG
R0 = np.array([10.0, 10.0, 5.0])  # the scenario's lever arm [m]
H, STEPS = 0.02, 25  # strapdown step and steps per filter period (0.5 s)
LAYOUTS = [StateLayout(True), StateLayout(False)]


def _ship(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Attitude and its rate of a ship rolling, pitching and yawing (the scenario's)."""
    amp = np.array([12.5, 10.0, 5.0]) * DEG
    w = 2.0 * math.pi / np.array([12.0, 6.0, 8.0])
    rpy = amp * np.sin(w * t) + np.array([0.0, 0.0, 0.6])
    return rpy, amp * w * np.cos(w * t)


def _strapdown_periods(layout: StateLayout, periods: int) -> list[PeriodSums]:
    """Period sums of a moving-base strapdown run over ``periods`` filter periods."""
    rpy, rate = _ship(0.0)
    nav = Strapdown(euler_to_dcm(rpy), LAT, 12.0, [5.0, 3.0, 0.0], options=MOVING_BASE)
    phi_flex = None
    if layout.flexure:
        F, G, Qc = TransferTuning().flexure_model()
        phi_flex = van_loan(F, G, Qc, H * STEPS)[0]
    out = []
    m_prev = flexure_matrix(nav.C_s_n, euler_rate_to_body_rate(rpy, rate), r0_matrix(R0))
    k = 0
    for _ in range(periods):
        sums = PeriodSums(lat=nav.lat, height=nav.height)
        for _ in range(STEPS):
            k += 1
            rpy, rate = _ship(k * H)
            c = euler_to_dcm(rpy)
            w_b = euler_rate_to_body_rate(rpy, rate)
            f_b = c.T @ np.array([0.0, 0.0, -G0]) + 0.3 * np.sin(w_b * 40.0)
            nav.step(w_b * H, f_b * H, H)
            sums.add(nav, H)
        if layout.flexure:
            m1 = flexure_matrix(c, w_b, r0_matrix(R0))
            sums.m0, sums.m1, sums.phi_flex = m_prev, m1, phi_flex
            m_prev = m1
        out.append(sums)
        nav.refresh()
    return out


def _sigma_points(layout: StateLayout, sums: PeriodSums, ndim: int) -> np.ndarray:
    """Sigma points of the acquisition bank (6 headings over the circle, P0).

    ``ndim`` 3: the bank's whole stack, shape (6, 2n + 1, n); 2: the hypothesis at heading
    pi (its points straddle +-pi), shape (2n + 1, n); 1: one of its points, shape (n,).
    """
    n = layout.n
    s = StageSettings()
    points = MerweScaledSigmaPoints(n, s.ukf_alpha, s.ukf_beta, s.ukf_kappa)
    P = TransferTuning().P0(layout, sums.lat, sums.m0)
    x = np.zeros((6, n))
    x[:, layout.heading] = wrap_angle(2.0 * np.pi * np.arange(6) / 6)
    x[:, layout.dv] = [1e-2, -2e-2, 5e-3]
    x[:, layout.nabla] = np.array([3e-4, -2e-4, 1e-4]) * G0
    sig = points.sigma_points(x, np.broadcast_to(P, (6, n, n)))
    if ndim == 3:
        return sig
    if ndim == 2:
        return sig[3]
    return sig[3, 2 * n - 2]


def _atol(x: np.ndarray, sums: PeriodSums, layout: StateLayout) -> np.ndarray:
    """Absolute tolerance per state: 1e-12 of the largest term summed into it (see above)."""
    x = x.reshape(-1, layout.n)
    dv = np.abs(x[:, layout.dv]).max() + np.abs(sums.dv_f).max()
    xi = 0.0
    if layout.flexure:
        xs = np.abs(x[:, layout.xi]).max()
        dv += 6.0 * xs * max(np.abs(sums.m0).max(), np.abs(sums.m1).max())
        xi = xs * np.abs(sums.phi_flex).sum(axis=1).max()
    atol = np.zeros(layout.n)
    atol[layout.dl] = np.abs(x[:, layout.dl]).max() + sums.T * dv / float(R_M(sums.lat))
    atol[layout.dv] = dv
    atol[layout.att] = 1.0  # [rad]: atan2 of DCM entries of size 1
    if layout.flexure:
        atol[layout.xi] = xi
    return RTOL * atol


def _assert_close(got: np.ndarray, want: np.ndarray, x: np.ndarray, sums: PeriodSums) -> None:
    """``got`` equals ``want`` to 1e-12 relative (+ :func:`_atol`); the heading on the circle.

    A heading of exactly +-pi may come out as +pi on one path and -pi on the other (the
    sign of a DCM entry ~1e-16 decides atan2's branch): the same angle, compared wrapped.
    """
    n = got.shape[-1]
    layout = StateLayout(n == 19)
    assert got.shape == want.shape == x.shape
    err = np.abs(got - want)
    err[..., layout.heading] = np.abs(wrap_angle(got - want)[..., layout.heading])
    bound = RTOL * np.abs(want) + _atol(x, sums, layout)
    worst = np.unravel_index(np.argmax(err - bound), err.shape)
    assert np.all(err <= bound), (worst, got[worst], want[worst], bound[worst])
    np.testing.assert_array_equal(got[..., layout.nabla], want[..., layout.nabla])
    np.testing.assert_array_equal(got[..., layout.eps], want[..., layout.eps])


@pytest.fixture(autouse=True)
def _compiled(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(native.ENV, "1")


@pytest.mark.parametrize("layout", LAYOUTS, ids=["19", "13"])
def test_make_propagate_takes_the_kernel_and_the_switch_takes_numpy(
    layout: StateLayout, monkeypatch: pytest.MonkeyPatch
) -> None:
    sums = _strapdown_periods(layout, 1)[0]
    x = _sigma_points(layout, sums, 2)
    fast = make_propagate(layout)
    assert isinstance(fast, CompiledPropagate)
    monkeypatch.setenv(native.ENV, "0")
    slow = make_propagate(layout)
    assert not isinstance(slow, CompiledPropagate)
    np.testing.assert_array_equal(slow(x, sums), propagate(x, sums, layout))
    _assert_close(fast(x, sums), slow(x, sums), x, sums)


@pytest.mark.parametrize("ndim", [3, 2, 1], ids=["bank", "ukf", "one"])
@pytest.mark.parametrize("layout", LAYOUTS, ids=["19", "13"])
def test_compiled_equals_numpy_on_sigma_points_over_strapdown_periods(
    layout: StateLayout, ndim: int
) -> None:
    """Four periods of a rolling ship, one compiled model (its buffer refilled each time)."""
    fast = make_propagate(layout)
    for sums in _strapdown_periods(layout, 4):
        assert abs(sums.T - 0.5) < 1e-12 and np.abs(sums.dv_f).max() > 4.0
        x = _sigma_points(layout, sums, ndim)
        assert x.ndim == ndim
        _assert_close(fast(x, sums), propagate(x, sums, layout), x, sums)


@pytest.mark.parametrize("layout", LAYOUTS, ids=["19", "13"])
def test_compiled_equals_numpy_at_large_angles_with_constant_sums(layout: StateLayout) -> None:
    """Headings at and next to +-pi, level errors of 30 deg, random stacks of every depth,
    and a stack of large errors (1 km, 1 m/s), in which every term counts."""
    rng = np.random.default_rng(18)
    m = rng.normal(0.0, 5.0, (3, 6))
    F, G, Qc = TransferTuning().flexure_model()
    sums = PeriodSums.constant(
        1.0, [0.3, -0.2, -9.8], euler_to_dcm([0.2, -0.1, 2.5]), [6.0, -3.0, 0.2], 0.9, 40.0,
        m if layout.flexure else None, van_loan(F, G, Qc, 1.0)[0] if layout.flexure else None,
    )  # fmt: skip
    if layout.flexure:
        sums.m1 = m + rng.normal(0.0, 0.1, (3, 6))
    fast = make_propagate(layout)
    scale = np.full(layout.n, 1e-3)
    scale[layout.dl] = 1e-6
    big = scale * 1e3  # errors of km and m/s: every term of the model above the tolerance
    big[layout.nabla] = big[layout.eps] = 1e-3
    shapes = [(layout.n,), (39, layout.n), (6, 39, layout.n), (2, 3, 39, layout.n)]
    for shape, s in [*((shape, scale) for shape in shapes), ((39, layout.n), big)]:
        x = rng.normal(0.0, 1.0, shape) * s
        x[..., layout.heading] = rng.uniform(-math.pi, math.pi, shape[:-1])
        x[..., 4:6] = rng.uniform(-30.0 * DEG, 30.0 * DEG, shape[:-1] + (2,))
        _assert_close(fast(x, sums), propagate(x, sums, layout), x, sums)
    edge = np.zeros((8, layout.n))
    edge[:, layout.heading] = [math.pi, -math.pi, math.pi - 1e-12, -math.pi + 1e-12,
                               math.pi - 1e-6, 3.0, -3.0, 0.0]  # fmt: skip
    edge[:, 4] = [30.0 * DEG, -30.0 * DEG, 0.0, 0.0, 30.0 * DEG, -30.0 * DEG, 30.0 * DEG, 0.0]
    edge[:, 5] = [30.0 * DEG, 30.0 * DEG, -30.0 * DEG, 0.0, 0.0, -30.0 * DEG, 0.0, 30.0 * DEG]
    edge[:, layout.eps] = 2e-4  # with a 1 s period: rotations of 3.5e-4 rad, past the series
    got, want = fast(edge, sums), propagate(edge, sums, layout)
    _assert_close(got, want, edge, sums)
    assert np.all(np.abs(want[:5, layout.heading]) > 3.14)  # still next to +-pi after the period
    for i in range(len(edge)):  # one state: the numpy scalar paths (euler_to_dcm_3, ...)
        _assert_close(fast(edge[i], sums), propagate(edge[i], sums, layout), edge[i], sums)


@pytest.mark.parametrize("layout", LAYOUTS, ids=["19", "13"])
def test_both_branches_of_the_rotation_vector(layout: StateLayout) -> None:
    """Period rotations from 1e-7 to 1e-2 rad, across rotvec_to_dcm's series at 1e-4 rad.

    With zero attitude, position and velocity errors the rotation is ``S_C eps`` exactly,
    so ``eps = S_C^-1 r`` sets it; the attitude error after the period is then ``r`` to
    first order (checked, so that the points do sweep the threshold).
    """
    sums = PeriodSums.constant(0.5, [0.0, 0.0, -9.8], euler_to_dcm([0.1, 0.2, 0.3]),
                               np.zeros(3), LAT, 0.0, np.zeros((3, 6)), np.eye(6))  # fmt: skip
    r = np.geomspace(1e-7, 1e-2, 200)[:, None] * np.array([0.6, -0.48, 0.64])
    x = np.zeros((200, layout.n))
    x[:, layout.eps] = np.linalg.solve(sums.c_int, r.T).T
    got, want = make_propagate(layout)(x, sums), propagate(x, sums, layout)
    _assert_close(got, want, x, sums)
    np.testing.assert_allclose(want[:, layout.att], r, rtol=1e-2)


@pytest.mark.parametrize("layout", LAYOUTS, ids=["19", "13"])
def test_a_stack_is_its_points_and_any_input_array_is_taken(layout: StateLayout) -> None:
    """Each point of a stack gives what it gives alone (bit for bit), also when the stack
    is a strided view or a list, or one of more shapes than the buffers kept; the result
    is a new array each call."""
    sums = _strapdown_periods(layout, 1)[0]
    fast = make_propagate(layout)
    sig = _sigma_points(layout, sums, 3)
    got = fast(sig, sums)
    for k in (0, 3, 5):
        for j in (0, layout.n - 2, 2 * layout.n):
            np.testing.assert_array_equal(fast(sig[k, j], sums), got[k, j])
    strided = np.swapaxes(np.ascontiguousarray(np.swapaxes(sig, 0, 1)), 0, 1)
    assert not strided.flags.c_contiguous
    np.testing.assert_array_equal(fast(strided, sums), got)
    np.testing.assert_array_equal(fast(sig[3].tolist(), sums), got[3])
    again = fast(sig, sums)
    assert again is not got
    np.testing.assert_array_equal(again, got)
    flat = sig.reshape(-1, layout.n)
    for m in range(1, 2 * CompiledPropagate.MAX_SHAPES):  # more shapes than buffers kept
        np.testing.assert_array_equal(fast(flat[:m], sums), got.reshape(-1, layout.n)[:m])


def test_a_state_of_the_wrong_size_or_missing_flexure_sums_are_refused() -> None:
    layout = StateLayout(False)
    sums = _strapdown_periods(layout, 1)[0]
    with pytest.raises(ValueError, match="size 13"):
        make_propagate(layout)(np.zeros((39, 19)), sums)
    with pytest.raises(ValueError, match="needs sums.m0"):  # not NaN
        make_propagate(StateLayout(True))(np.zeros((39, 19)), sums)


@pytest.mark.parametrize("layout", LAYOUTS, ids=["19", "13"])
def test_pack_lays_the_sums_out_as_the_kernel_reads_them(layout: StateLayout) -> None:
    """The parameter block (also read by the fine UKF's kernel): T, lat, height, the
    constants, then the sums' arrays back to back (the flexure ones only with flexure)."""
    sums = _strapdown_periods(layout, 2)[1]
    fast = make_propagate(layout)
    address = fast.pack(sums)
    block = ctypes.cast(address, ctypes.POINTER(ctypes.c_double))
    par = np.ctypeslib.as_array(block, (PARAM_SIZE,))
    np.testing.assert_array_equal(par[:6], [sums.T, sums.lat, sums.height, OMEGA_IE, A, E2])
    arrays = [sums.dv_f, sums.c_int, sums.v_int, sums.w_in, sums.cor]
    if layout.flexure:
        arrays += [sums.m0, sums.m1, sums.phi_flex]
    packed = np.concatenate([a.ravel() for a in arrays])
    np.testing.assert_array_equal(par[6 : 6 + packed.size], packed)
    assert (6 + packed.size == PARAM_SIZE) == layout.flexure
    assert fast.pack(sums) == address  # one block, refilled
