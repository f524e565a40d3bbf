"""The transfer-alignment filter's scalar fast paths compute what the array code computed.

Issue 18 item 4 rewrote the hot paths of the filter (strapdown step, master rate,
publishing, the UKF's bookkeeping) with scalar arithmetic around the matrix products.
Every rewrite keeps the operations and their order, so the results are equal **bit for
bit**; the references here are the array formulas the code had before (written out
below) or the batched library functions, on random inputs.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from cosim.alignment.nav import Mechanisation, Strapdown, euler_rate_matrix
from cosim.alignment.transfer_model import (
    PeriodSums,
    StateLayout,
    master_rate,
    propagate,
    relative_rotvecs,
)
from cosim.estimation import MerweScaledSigmaPoints, UnscentedKalmanFilter
from cosim.estimation.checks import EstimatorTypeError
from cosim.estimation.linalg import float_array
from cosim.models.constants import OMEGA_IE
from cosim.models.conventions import (
    cross,
    dcm_to_euler,
    dcm_to_rotvec,
    euler_to_dcm,
    rotvec_to_dcm,
    rotvec_to_dcm_3,
)
from cosim.models.earth import R_M, R_N


# ----------------------------------------------------------------------------- references
def _array_two_sample_step(nav: Strapdown, state: dict, dtheta, dv, h: float) -> None:
    """The two-sample strapdown step as array formulas (the code before the scalar path)."""
    o = nav.options
    dth = np.asarray(dtheta, dtype=float) - state["gyro_bias"] * h
    dvb = np.asarray(dv, dtype=float) - state["accel_bias"] * h
    if state["prev"] is None:
        state["prev"] = (dth, dvb)
    p_th, p_dv = state["prev"]
    state["prev"] = (dth, dvb)
    phi = dth + cross(p_th, dth) / 12.0
    c1 = cross(dth, dvb)
    u = dvb + 0.5 * c1 + cross(dth, c1) / 6.0
    u += (cross(p_th, dvb) + cross(p_dv, dth)) / 12.0
    v = state["v_n"]
    v_ref = 1.5 * v - 0.5 * state["v_prev"] if o.midpoint_velocity else v
    if o.transport_rate:
        rm, rn, tan = state["rm"], state["rn"], state["tan"]
        w_en = np.array([v_ref[1] / rn, -v_ref[0] / rm, -v_ref[1] * tan / rn])
        w_in = nav.w_ie + w_en
        cor = 2.0 * nav.w_ie + w_en
    else:
        w_in, cor = nav.w_ie, 2.0 * nav.w_ie
    zeta = w_in * h
    nav_rot = rotvec_to_dcm_3(-zeta)
    c0 = state["C_s_n"]
    cu = c0 @ u
    dv_n = cu - 0.5 * cross(zeta, cu)
    if o.vertical:
        v_new = v + dv_n + (np.array([0.0, 0.0, nav.g]) - cross(cor, v_ref)) * h
    else:
        k = cor[2] * h
        v_new = np.array([v[0] + dv_n[0] + k * v_ref[1], v[1] + dv_n[1] - k * v_ref[0], 0.0])
    if o.transport_rate:
        state["lat"] += v_ref[0] * h / state["rm"]
    state.update(C_prev=c0, phi=phi, dv_n=dv_n, w_in=w_in, cor=cor, v_prev=v, v_n=v_new)
    state["C_s_n"] = nav_rot @ c0 @ rotvec_to_dcm_3(phi)


# ----------------------------------------------------------------------------- tests
@pytest.mark.parametrize(
    "transport_rate, vertical, midpoint", list(itertools.product([True, False], repeat=3))
)
def test_scalar_two_sample_step_equals_the_array_formulas(
    transport_rate: bool, vertical: bool, midpoint: bool
) -> None:
    opts = Mechanisation(
        coning="two-sample",
        transport_rate=transport_rate,
        vertical=vertical,
        midpoint_velocity=midpoint,
    )
    rng = np.random.default_rng(11)
    c = euler_to_dcm([0.02, -0.01, 0.52])
    nav = Strapdown(c, 0.52, 7.0, [1.0, -0.5, 0.1], options=opts)
    nav.gyro_bias = np.array([1e-7, 2e-7, -1e-7])
    nav.accel_bias = np.array([1e-4, -2e-4, 3e-4])
    ref = {
        "C_s_n": nav.C_s_n.copy(),
        "v_n": nav.v_n.copy(),
        "v_prev": nav.v_prev.copy(),
        "lat": nav.lat,
        "prev": None,
        "gyro_bias": nav.gyro_bias,
        "accel_bias": nav.accel_bias,
        # the latitude constants as Strapdown.refresh makes them (at construction here)
        "rm": float(R_M(0.52)) + 7.0,
        "rn": float(R_N(0.52)) + 7.0,
        "tan": math.tan(0.52),
    }
    h = 0.05
    for _ in range(40):
        dth = rng.normal(0.0, 1e-2, 3)
        dv = np.array([0.0, 0.0, -9.8 * h]) + rng.normal(0.0, 0.05, 3)
        _array_two_sample_step(nav, ref, dth, dv, h)
        nav.step(dth, dv, h)
        for name in ("C_s_n", "v_n", "v_prev", "C_prev", "phi", "dv_n", "w_in", "cor"):
            np.testing.assert_array_equal(getattr(nav, name), ref[name], err_msg=name)
        assert nav.lat == ref["lat"]


def test_relative_rotvecs_equal_the_batched_logarithm() -> None:
    """All four branches of Shepperd's method (large angles pick q1..q3) and tiny angles."""
    rng = np.random.default_rng(7)
    for scale in (1e-14, 1e-9, 1e-4, 0.3, 2.0, 3.1, math.pi):
        v = rng.normal(size=(200, 3))
        v *= scale * rng.uniform(0.2, 1.0, (200, 1)) / np.linalg.norm(v, axis=1, keepdims=True)
        mats = rotvec_to_dcm(v)
        got = np.array(relative_rotvecs(list(mats)))
        np.testing.assert_array_equal(got, dcm_to_rotvec(mats))


@pytest.mark.parametrize("k", [1, 2, 3, 5])
def test_master_rate_equals_the_array_difference(k: int) -> None:
    rng = np.random.default_rng(k)
    hist = [rotvec_to_dcm(rng.normal(0.0, 0.2, 3)) for _ in range(k)]
    h = 0.05
    got = master_rate(hist, h)
    if k < 2:
        np.testing.assert_array_equal(got, np.zeros(3))
        return
    rho = dcm_to_rotvec(np.array([hist[0].T @ c for c in hist[1:5]]))
    if k >= 5:
        want = (-48.0 * rho[0] + 36.0 * rho[1] - 16.0 * rho[2] + 3.0 * rho[3]) / (12.0 * h)
    elif k >= 3:
        want = (-4.0 * rho[0] + rho[1]) / (2.0 * h)
    else:
        want = -rho[0] / h
    np.testing.assert_array_equal(got, want)


def _array_propagate(x, sums, layout):
    """The error model over one period as it was written before (stacks, broadcast crosses)."""
    x = np.asarray(x, dtype=float)
    T = sums.T
    out = np.empty_like(x)
    dl, dV, att = x[..., layout.dl], x[..., layout.dv], x[..., layout.att]
    nab, eps = x[..., layout.nabla], x[..., layout.eps]
    if layout.flexure:
        xi = x[..., layout.xi]
        dv0 = dV - xi @ sums.m0.T
    else:
        dv0 = dV
    lat_h = sums.lat
    rm = float(R_M(lat_h)) + sums.height
    rn = float(R_N(lat_h)) + sums.height
    cl, sl, tl = math.cos(lat_h), math.sin(lat_h), math.tan(lat_h)
    lat_t = lat_h - dl
    zero = np.zeros_like(dl)
    d_wie = OMEGA_IE * np.stack([cl - np.cos(lat_t), zero, -(sl - np.sin(lat_t))], axis=-1)
    v_mean_e = sums.v_int[1] / T
    d_wen = np.stack(
        [
            dv0[..., 1] / rn,
            -dv0[..., 0] / rm,
            -dv0[..., 1] * tl / rn - v_mean_e * dl / (rn * cl * cl),
        ],
        axis=-1,
    )
    d_win = d_wie + d_wen
    E0 = euler_to_dcm(att)
    rot = (
        eps @ sums.c_int.T + (E0 @ sums.w_in) - sums.w_in - (E0 @ (d_win[..., :, None] * T))[..., 0]
    )
    E1 = rotvec_to_dcm(rot) @ E0
    EbT = 0.5 * np.swapaxes(E0 + E1, -1, -2)
    dv1 = (
        dv0
        + sums.dv_f
        - EbT @ sums.dv_f
        + (EbT @ (nab @ sums.c_int.T)[..., :, None])[..., 0]
        - cross(np.broadcast_to(sums.cor, dv0.shape), dv0)
        - cross(2.0 * d_wie + d_wen, np.broadcast_to(sums.v_int, dv0.shape))
    )
    out[..., layout.dl] = dl + 0.5 * (dv0[..., 0] + dv1[..., 0]) * T / rm
    out[..., layout.att] = dcm_to_euler(E1)
    out[..., layout.nabla] = nab
    out[..., layout.eps] = eps
    if layout.flexure:
        xi1 = xi @ sums.phi_flex.T
        out[..., layout.xi] = xi1
        out[..., layout.dv] = dv1 + xi1 @ sums.m1.T
    else:
        out[..., layout.dv] = dv1
    return out


@pytest.mark.parametrize("flexure", [True, False])
def test_propagate_equals_the_stacked_formulas(flexure: bool) -> None:
    rng = np.random.default_rng(3)
    layout = StateLayout(flexure)
    c = euler_to_dcm([0.1, -0.05, 0.7])
    m = rng.normal(0.0, 1.0, (3, 6))
    sums = PeriodSums.constant(
        0.5, [0.3, -0.2, -9.8], c, [1.0, 2.0, 0.1], 0.52, 3.0, m, np.eye(6) * 0.999
    )
    sums.m1 = m + 0.01  # the two ends of the period differ
    for shape in [(layout.n,), (39, layout.n), (6, 39, layout.n)]:
        x = rng.normal(0.0, 1e-3, shape)
        x[..., layout.heading] = rng.uniform(-math.pi, math.pi, shape[:-1])
        np.testing.assert_array_equal(propagate(x, sums, layout), _array_propagate(x, sums, layout))


def test_single_euler_rate_matrix_equals_the_batched_one() -> None:
    rpy = np.random.default_rng(4).normal(0.0, 2.0, (500, 3))
    batched = euler_rate_matrix(rpy)
    for i in range(len(rpy)):
        np.testing.assert_array_equal(euler_rate_matrix(rpy[i]), batched[i])


def test_float_array_copies_only_what_it_must() -> None:
    a = np.arange(12.0).reshape(3, 4)
    assert float_array(a, "a") is a
    view = a[:, 1:3]  # strided: copied, C-contiguous, as as_float does
    got = float_array(view, "view")
    assert got is not view and got.flags.c_contiguous
    np.testing.assert_array_equal(got, view)
    assert float_array([1, 2], "b").dtype == np.float64
    with pytest.raises(EstimatorTypeError, match="c: expected a real array"):
        float_array("x", "c")


def test_lazy_log_likelihood_is_the_update_density() -> None:
    ukf = UnscentedKalmanFilter(
        2, 1, lambda x, dt: x, lambda x: x[..., :1], MerweScaledSigmaPoints(2, 0.5)
    )
    assert ukf.log_likelihood is None
    ukf.P = np.diag([2.0, 1.0])
    ukf.update(np.array([0.7]), R=np.array([[0.5]]))
    s = 2.0 + 0.5  # S = P_00 + R for a linear h: the KF value
    want = -0.5 * 0.7**2 / s - 0.5 * math.log(2.0 * math.pi * s)
    assert ukf.log_likelihood == pytest.approx(want, rel=1e-12)
    ukf.update(None)
    assert ukf.log_likelihood is None
