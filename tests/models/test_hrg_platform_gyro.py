"""HrgPlatformGyro against an independent evaluation of seed 000 eq. (1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.estimation.allan import allan_deviation
from cosim.models.blocks.hrg_platform_gyro import HrgPlatformGyro
from cosim.models.constants import OMEGA_IE

DEG_H = math.pi / 180.0 / 3600.0


def make(**params: object) -> HrgPlatformGyro:
    gyro = HrgPlatformGyro()
    for name, value in params.items():
        if isinstance(value, (tuple, list, np.ndarray)):
            value = np.asarray(value, dtype=float)
        setattr(gyro, name, value)
    gyro.setup_experiment(0.0)
    gyro.exit_initialization_mode()
    return gyro


def eq1(
    lat: float, a: float, k: np.ndarray, eta: dict, d0: np.ndarray, h: np.ndarray
) -> np.ndarray:
    """Seed 000 eq. (1) written out term by term, as printed in the paper: U per axis."""
    w = OMEGA_IE
    cl, sl, sa, ca = math.cos(lat), math.sin(lat), math.sin(a), math.cos(a)
    ux = k[0] * (w * cl * sa + eta["yx"] * w * cl * ca + eta["zx"] * w * sl + d0[0] + h[0])
    uy = k[1] * (w * cl * ca + eta["xy"] * w * cl * sa + eta["zy"] * w * sl + d0[1] + h[1])
    uz = k[2] * (w * sl + eta["xz"] * w * cl * sa + eta["yz"] * w * cl * ca + d0[2] + h[2])
    return np.array([ux, uy, uz])


def test_output_voltage_matches_equation_1() -> None:
    rng = np.random.default_rng(0)
    k = np.array([2.5, 1.7, 3.1])  # V/(rad/s)
    eta = {
        name: float(v)
        for name, v in zip(
            ("yx", "zx", "xy", "zy", "xz", "yz"), rng.normal(0, 1e-3, 6), strict=True
        )
    }
    d0 = np.array([0.2, 0.1, 0.2]) * DEG_H  # seed 000: D_N, D_E, D_A
    coeff = {c: rng.normal(0.0, 0.05, 3) * DEG_H for c in ("a1", "b1", "a2", "b2")}
    gyro = make(
        k=k,
        drift=d0,
        heading_a1=coeff["a1"],
        heading_b1=coeff["b1"],
        heading_a2=coeff["a2"],
        heading_b2=coeff["b2"],
        **{f"eta_{n}": v for n, v in eta.items()},
    )
    h = 0.01
    n = 0
    for lat in np.radians([0.0, 30.0, 45.0, -60.0]):
        for a in np.radians([0.0, 37.0, 90.0, 100.0, 190.0, 271.0]):
            # Level platform at rest: inertial rate = earth rate in platform axes
            # (x, y level, z up; azimuth A counter-clockwise from east/north/up).
            gyro.omega_ip_p = OMEGA_IE * np.array(
                [math.cos(lat) * math.sin(a), math.cos(lat) * math.cos(a), math.sin(lat)]
            )
            gyro.azimuth = float(a)
            gyro.do_step(n * h, h)
            n += 1
            h_a = (
                coeff["a1"] * math.sin(a)
                + coeff["b1"] * math.cos(a)
                + coeff["a2"] * math.sin(2 * a)
                + coeff["b2"] * math.cos(2 * a)
            )
            expected = eq1(lat, a, k, eta, d0, h_a)
            np.testing.assert_allclose(gyro.U, expected, rtol=1e-13, atol=1e-22)
            np.testing.assert_allclose(gyro.omega_meas_p, expected / k, rtol=1e-13, atol=1e-22)
            np.testing.assert_allclose(
                gyro.omega_err_p, expected / k - gyro.omega_ip_p, rtol=1e-9, atol=1e-20
            )


def test_rotation_by_90_deg_swaps_the_level_gyros() -> None:
    # Seed 000, sec. 1.4: turning the platform 90 deg counter-clockwise points the
    # former east gyro (x) north: its earth-rate reading becomes Omega cos L.
    lat = math.radians(45.0)
    gyro = make()
    for k, a in enumerate((0.0, math.pi / 2)):
        gyro.omega_ip_p = OMEGA_IE * np.array(
            [math.cos(lat) * math.sin(a), math.cos(lat) * math.cos(a), math.sin(lat)]
        )
        gyro.azimuth = a
        gyro.do_step(k * 0.01, 0.01)
        if a == 0.0:
            assert gyro.U[0] == pytest.approx(0.0, abs=1e-20)
        else:
            assert gyro.U[0] == pytest.approx(OMEGA_IE * math.cos(lat), rel=1e-14)


def test_white_noise_density() -> None:
    # Mean-over-step white noise: std N / sqrt(h); sample std over n = 40000 steps has
    # a relative error 1/sqrt(2n) = 0.35 %, and adev(1 s) = N within ~0.9 % (m = 10);
    # both are checked at 5 %.
    density = 0.01 * DEG_H  # a "random 0.01 deg/h" figure read as adev(1 s)
    h, n = 0.1, 40_000
    gyro = make(noise_density=density, seed=4, k=[2.0, 2.0, 2.0])
    out = np.empty((n, 3))
    for i in range(n):
        gyro.do_step(i * h, h)
        out[i] = gyro.omega_meas_p
    np.testing.assert_allclose(out.std(axis=0), density / math.sqrt(h), rtol=0.05)
    _, adev = allan_deviation(out, h, 10)
    np.testing.assert_allclose(adev[0], density, rtol=0.05)


def test_seed_reproducibility_and_bad_parameters() -> None:
    def record(seed: int) -> np.ndarray:
        gyro = make(noise_density=1e-6, seed=seed)
        rows = []
        for i in range(50):
            gyro.do_step(i * 0.01, 0.01)
            rows.append(gyro.U.copy())
        return np.array(rows)

    np.testing.assert_array_equal(record(3), record(3))
    assert not np.array_equal(record(3), record(4))
    with pytest.raises(ValueError):
        make(k=[1.0, 0.0, 1.0])
