"""Step conventions and step paths (models.step_paths): sub-steps, Simpson nodes, paths."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.models import step_paths as sp

RNG = np.random.default_rng(20240611)


def test_substeps_and_simpson() -> None:
    assert sp.substeps(0.01, 1e-3) == 10
    assert sp.substeps(0.0105, 1e-3) == 10  # round, not floor/ceil of accumulated time
    assert sp.substeps(1e-4, 1e-3) == 1
    s, w = sp.simpson_nodes(5)
    assert s.shape == (11,) and s[0] == 0.0 and s[-1] == 1.0
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    # exact for cubics
    assert w @ (s**3) == pytest.approx(0.25, abs=1e-15)


def test_step_paths_are_exact_for_their_degree() -> None:
    h = 0.02
    s = np.linspace(0.0, 1.0, 7)
    tt = h * s
    a, b, c = RNG.standard_normal((3, 3))
    # quadratic x = a + b t + c t^2 on [0, h]
    x = a + b * tt[:, None] + c * tt[:, None] ** 2
    inc = a * h + b * h**2 / 2 + c * h**3 / 3
    xq, xqd = sp.step_quadratic(x[-1], b + 2 * c * h, inc, h, s)
    np.testing.assert_allclose(xq, x, atol=1e-13)
    np.testing.assert_allclose(xqd, b + 2 * c * tt[:, None], atol=1e-11)
    # linear
    xl = a + b * tt[:, None]
    yl, yld = sp.step_linear(xl[-1], a * h + b * h**2 / 2, h, s)
    np.testing.assert_allclose(yl, xl, atol=1e-14)
    np.testing.assert_allclose(yld, np.tile(b, (7, 1)), atol=1e-11)
    # Hermite: exact for cubics; derivative integrals exact
    d = RNG.standard_normal(3)
    xc = a + b * tt[:, None] + c * tt[:, None] ** 2 + d * tt[:, None] ** 3
    xcd = b + 2 * c * tt[:, None] + 3 * d * tt[:, None] ** 2
    xh, xhd, xhdd = sp.step_hermite(xc[0], xcd[0], xc[-1], xcd[-1], h, s)
    np.testing.assert_allclose(xh, xc, atol=1e-14)
    np.testing.assert_allclose(xhd, xcd, atol=1e-12)
    np.testing.assert_allclose(xhdd, 2 * c + 6 * d * tt[:, None], atol=1e-9)


def test_step_path_memory_quartic_and_fallback() -> None:
    h = 0.05
    s = np.linspace(0.0, 1.0, 5)
    coef = RNG.standard_normal((5, 3))  # quartic x(t) = sum coef_k t^k

    def x(t: float) -> np.ndarray:
        return sum(coef[k] * t**k for k in range(5))

    def xd(t: float) -> np.ndarray:
        return sum(k * coef[k] * t ** (k - 1) for k in range(1, 5))

    def integral(t0: float, t1: float) -> np.ndarray:
        return sum(coef[k] * (t1 ** (k + 1) - t0 ** (k + 1)) / (k + 1) for k in range(5))

    path = sp.StepPath()
    path.reset(0.0, x(0.0), xd(0.0))
    t = 0.0
    vals, ders = path.nodes(t, h, x(h), integral(0.0, h), s, xd(h))
    np.testing.assert_allclose(vals, np.array([x(h * u) for u in s]), atol=1e-13)
    np.testing.assert_allclose(ders, np.array([xd(h * u) for u in s]), atol=1e-11)
    # A start value inconsistent with the increment (not forwarded: zero) -> memoryless quadratic,
    # which matches the end value, end rate and the increment.
    bad = sp.StepPath()
    bad.reset(0.0, np.zeros(3) + 100.0, np.zeros(3))
    vals, ders = bad.nodes(0.0, h, x(h), integral(0.0, h), s, xd(h))
    np.testing.assert_allclose(vals[-1], x(h), atol=1e-14)
    np.testing.assert_allclose(ders[-1], xd(h), atol=1e-12)
    w = np.array([1, 4, 2, 4, 1]) / 12.0
    np.testing.assert_allclose(h * (w @ vals), integral(0.0, h), atol=1e-14)
