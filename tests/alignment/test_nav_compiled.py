"""The compiled strapdown step (``cosim/alignment/strapdown.c``) against the numpy integrator.

:class:`cosim.alignment.nav_compiled.CompiledStrapdown` must give the numbers of
:class:`cosim.alignment.nav.Strapdown` (two-sample increments) to rounding: the scalar
arithmetic is the same, the three matrix products of a step are summed in another order
than BLAS may use. Over 2000 steps the relative difference stays below 1e-12 (1e-16 per
step, growing at most linearly through the attitude and velocity integrals). Its period
sums equal :meth:`cosim.alignment.transfer_model.PeriodSums.add` to the same tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.alignment.nav import MOVING_BASE, STATIC_BASE, Mechanisation, Strapdown
from cosim.alignment.nav_compiled import CompiledStrapdown, make_strapdown
from cosim.alignment.transfer_model import PeriodSums
from cosim.models.conventions import euler_to_dcm

RTOL = 1e-12
OPTIONS = {
    "moving base": MOVING_BASE,
    "no transport rate": Mechanisation(transport_rate=False),
    "level, no mid-point, orthonormalised": Mechanisation(
        vertical=False, midpoint_velocity=False, orthonormalise_every=7
    ),
}
ATTRS = ("C_s_n", "v_n", "v_prev", "C_prev", "phi", "dv_n", "w_in", "cor", "lat")


def _pair(opts: Mechanisation) -> tuple[Strapdown, Strapdown]:
    c = euler_to_dcm([0.3, -0.2, 2.9])
    args = (c, 0.52, 7.0, [1.0, -0.5, 0.1])
    return Strapdown(*args, options=opts), make_strapdown(*args, options=opts)


def _close(a: object, b: object, scale: float = 1.0) -> None:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    np.testing.assert_allclose(b, a, rtol=RTOL, atol=RTOL * scale)


@pytest.mark.parametrize("opts", OPTIONS.values(), ids=OPTIONS.keys())
def test_compiled_steps_and_sums_equal_the_numpy_integrator(opts: Mechanisation) -> None:
    ref, fast = _pair(opts)
    assert isinstance(fast, CompiledStrapdown)
    rng = np.random.default_rng(7)
    sums = PeriodSums(lat=ref.lat, height=ref.height)
    for nav in (ref, fast):
        nav.gyro_bias = np.array([1e-6, 2e-6, -1e-6])
        nav.accel_bias = np.array([1e-3, -2e-3, 5e-4])
    h = 0.05
    for k in range(2000):
        dth = rng.normal(0.0, 2e-3, 3)
        dv = rng.normal(0.0, 1e-2, 3) + [0.0, 0.0, -9.79 * h]
        ref.step(dth, dv, h)
        sums.add(ref, h)
        fast.step_summed(dth, dv, h)
        if k % 10 == 9:  # a filter period: feedback, new constants, new sums
            _close(sums.T, fast.sums_into(PeriodSums()).T)
            got = fast.sums_into(PeriodSums())
            for name in ("dv_f", "c_int", "v_int", "w_in", "cor"):
                _close(getattr(sums, name), getattr(got, name), np.abs(getattr(sums, name)).max())
            for nav in (ref, fast):
                nav.correct(rotation=euler_to_dcm([1e-4, -2e-4, 3e-4]), d_v=[0.01, 0, 0])
                nav.refresh()
            sums = PeriodSums(lat=ref.lat, height=ref.height)
            fast.clear_sums()
    for name in ATTRS:
        want = getattr(ref, name)
        _close(want, getattr(fast, name), np.abs(want).max())
    assert fast.g == ref.g and fast.w_ie.tolist() == ref.w_ie.tolist()


def test_the_first_step_has_no_previous_increment() -> None:
    ref, fast = _pair(MOVING_BASE)
    first, second = [1e-3, 2e-3, -1e-3], [2e-3, -1e-3, 5e-4]
    for nav in (ref, fast):
        nav.step(first, [0.0, 0.0, -0.49], 0.05)
        assert nav.phi.tolist() == first  # no coning term without a previous increment
    for nav in (ref, fast):
        nav.step(second, [0.0, 0.0, -0.49], 0.05)
        assert nav.phi.tolist() != second  # the coning term with the first increment
    assert fast.phi.tolist() == ref.phi.tolist()


def test_attributes_are_copies_and_settable() -> None:
    _, fast = _pair(MOVING_BASE)
    c = fast.C_s_n
    c[0, 0] = 99.0  # a copy: the integrator is not changed through it
    assert fast.C_s_n[0, 0] != 99.0
    fast.v_n = [1.0, 2.0, 3.0]
    assert fast.v_n.tolist() == [1.0, 2.0, 3.0]
    fast.lat -= 0.01
    assert fast.lat == pytest.approx(0.51, abs=1e-15)
    ref = Strapdown(fast.C_s_n, fast.lat, fast.height, fast.v_n)
    _close(ref.mean_attitude(), fast.mean_attitude())


def test_numpy_where_nothing_is_compiled(monkeypatch: pytest.MonkeyPatch) -> None:
    c = np.eye(3)
    assert type(make_strapdown(c, 0.3, options=STATIC_BASE)) is Strapdown  # table-axis
    monkeypatch.setenv("INS_COSIM_NATIVE", "0")
    assert type(make_strapdown(c, 0.3, options=MOVING_BASE)) is Strapdown
    monkeypatch.delenv("INS_COSIM_NATIVE")
    assert type(make_strapdown(c, 0.3, options=MOVING_BASE)) is CompiledStrapdown


@pytest.mark.parametrize("lat", [-1.2, -0.3, 0.0, 0.52, 1.45])
@pytest.mark.parametrize("height", [0.0, 12.0, 3000.0])
def test_compiled_refresh_gives_the_constants_of_the_numpy_one(lat: float, height: float) -> None:
    ref, fast = _pair(MOVING_BASE)
    for nav in (ref, fast):
        nav.lat, nav.height = lat, height
        nav.refresh()
    _close(ref.g, fast.g, ref.g)
    _close(ref.w_ie, fast.w_ie, 1e-4)
    for nav in (ref, fast):  # the radii and tan(lat) act through the transport rate
        nav.step([1e-3, -2e-3, 5e-4], [0.1, 0.2, -0.49], 0.05)
    for name in ("v_n", "lat", "w_in", "cor", "C_s_n"):
        want = getattr(ref, name)
        _close(want, getattr(fast, name), np.abs(want).max())
