"""WGS-84 earth model: gravity, radii, earth and transport rates, kinematics helper."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.models import constants, earth
from cosim.models import conventions as cv


def test_gravity_equator_and_pole_wgs84() -> None:
    # NIMA TR8350.2 table 3.4: normal gravity at the equator and at the poles.
    assert earth.gravity(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.gravity(math.pi / 2) == pytest.approx(9.8321849378, abs=1e-10)
    assert earth.gravity(-math.pi / 2) == pytest.approx(9.8321849378, abs=1e-10)
    # Somigliana's k and m (TR8350.2 table 3.4: k = 0.00193185265241, m = 0.00344978650684);
    # k derived from the rounded published constants agrees to ~3e-9 relative.
    assert constants.K_SOMIGLIANA == pytest.approx(0.00193185265241, rel=1e-8)
    assert constants.M_RATIO == pytest.approx(0.00344978650684, rel=1e-10)
    assert constants.E2 == pytest.approx(0.00669437999013, rel=1e-11)


def test_gravity_mid_latitude_and_height() -> None:
    # Somigliana's closed formula with the published constants (independent of the module's)
    for lat_deg in (10.0, 30.0, 45.0, 60.0, 89.0):
        s2 = math.sin(math.radians(lat_deg)) ** 2
        ref = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2)
        assert earth.gravity(math.radians(lat_deg)) == pytest.approx(ref, abs=1e-10)
    # Free-air gradient ~ -3.086e-6 /s2 per metre at the equator (2 g / a (1 + f + m))
    dg = earth.gravity(0.0, 1000.0) - earth.gravity(0.0, 0.0)
    assert dg == pytest.approx(-3.0877e-3, rel=1e-3)
    np.testing.assert_allclose(earth.g_n(0.3, 10.0), [0.0, 0.0, earth.gravity(0.3, 10.0)])


def test_radii() -> None:
    a, e2 = constants.A, constants.E2
    assert earth.R_M(0.0) == pytest.approx(a * (1 - e2), abs=1e-6)  # 6335439.327 m
    assert earth.R_M(0.0) == pytest.approx(6335439.327, abs=1e-3)
    assert earth.R_N(0.0) == pytest.approx(a, abs=1e-9)
    polar = a * a / constants.B  # radius of curvature at the pole, 6399593.626 m
    assert earth.R_M(math.pi / 2) == pytest.approx(polar, abs=1e-6)
    assert earth.R_N(math.pi / 2) == pytest.approx(polar, abs=1e-6)
    assert polar == pytest.approx(6399593.626, abs=1e-3)
    # R_M < R_N except at the poles
    lat = np.radians([10.0, 30.0, 60.0])
    assert np.all(earth.R_M(lat) < earth.R_N(lat))


def test_earth_and_transport_rate() -> None:
    lat = math.radians(30.0)
    w = earth.omega_ie_n(lat)
    np.testing.assert_allclose(w, [7.292115e-5 * math.cos(lat), 0.0, -7.292115e-5 * math.sin(lat)])
    v = np.array([10.0, 5.0, -1.0])
    h = 100.0
    wen = earth.omega_en_n(v, lat, h)
    lat_dot, lon_dot, h_dot = earth.position_rate(v, lat, h)
    # omega_en_n = [lon' cos L, -lat', -lon' sin L]
    np.testing.assert_allclose(
        wen, [lon_dot * math.cos(lat), -lat_dot, -lon_dot * math.sin(lat)], rtol=1e-14
    )
    assert h_dot == 1.0


def test_euler_motion_truth_static_equals_general_path() -> None:
    # The fixed-position fast path and the general path agree (zero displacement).
    rng = np.random.default_rng(3)
    m = 4
    rpy, rd, rdd = rng.standard_normal((3, m, 3)) * 0.3
    zero = np.zeros((m, 3))
    fast = earth.euler_motion_truth(rpy, rd, rdd, None, None, None, 0.7, 0.1, 50.0)
    full = earth.euler_motion_truth(rpy, rd, rdd, zero, zero, zero, 0.7, 0.1, 50.0)
    for a, b in zip(fast, full, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-18)
    # at rest: f_b = C_n_b [0, 0, -g], omega_ib_b = omega_nb_b + C_n_b omega_ie_n
    c = cv.euler_to_dcm(rpy)
    np.testing.assert_allclose(
        fast.f_b, np.einsum("mji,j->mi", c, [0, 0, -earth.gravity(0.7, 50.0)]), atol=1e-14
    )
    w_nb = cv.euler_rate_to_body_rate(rpy, rd)
    np.testing.assert_allclose(
        fast.omega_ib_b, w_nb + np.einsum("mji,j->mi", c, earth.omega_ie_n(0.7)), atol=1e-17
    )
