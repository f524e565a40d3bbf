"""Two-position HRG alignment filter: measurement model, filters, eq. (16)-(21), block logic.

The UPF itself (one particle = UKF, unscented transform exact for linear maps,
resampling keeps the weighted mean) is tested in tests/estimation/test_particle.py and
tests/estimation/test_unscented.py (test_upf_with_one_particle_equals_the_ukf,
test_unscented_transform_is_exact_for_linear_maps,
test_systematic_resample_is_unbiased_for_the_weighted_mean).
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.integrate import quad

from cosim.alignment.hrg_filters import (
    AlignmentSequenceError,
    PositionFilter,
    TwoPositionAligner,
    azimuth_grid,
)
from cosim.alignment.hrg_model import (
    UNIFORM_SIGMA,
    apparent_azimuth,
    combine_positions,
    dv_coefficients,
    dv_jacobian,
    position2_prior,
    predict_dv,
    tilt_jacobian,
)
from cosim.alignment.hrg_two_position import HrgTwoPositionAlignment
from cosim.models.blocks.hrg_platform import HrgPlatform
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR, G0, OMEGA_IE
from cosim.models.conventions import rot_z, wrap_angle

LAT = math.radians(45.0)
G = 9.7966
OC = OMEGA_IE * math.cos(LAT)
OS = OMEGA_IE * math.sin(LAT)
UNIFORM = UNIFORM_SIGMA
P0 = np.diag([(3 * ARCMIN) ** 2, (3 * ARCMIN) ** 2, (0.2 * DEG_PER_HOUR) ** 2, UNIFORM**2])
N_ACC = 5e-6 * G0  # accelerometer white noise [m/s/sqrt(s)]
R_VAR = N_ACC**2 * 1.0 + 1e-4**2 / 6.0  # per 1 s increment, as the block computes it


def geo_drift(a: float, eps: np.ndarray) -> np.ndarray:
    """d = -Rz(A) eps (east, north) [rad/s]."""
    return -(rot_z(a)[:2, :2] @ eps[:2])


def apparent_state(a: float, eps: np.ndarray, theta0: tuple[float, float]) -> np.ndarray:
    """The polar state one position observes, from a truth (tilts turned into the model frame)."""
    d = geo_drift(a, eps)
    psi, dn = apparent_azimuth(a, d[0], d[1], LAT)
    u = complex(theta0[0], theta0[1]) * cmath.exp(1j * (psi - a))
    return np.array([u.imag, u.real, dn, psi])


# ----------------------------------------------------------------------- measurement
@pytest.mark.parametrize("t0, t1", [(0.0, 1.0), (199.0, 200.0), (37.5, 41.0), (5.0e4, 5.0e4 + 2.0)])
def test_dv_coefficients_equal_quadrature(t0: float, t1: float) -> None:
    def e1(s: float) -> complex:
        # (1 - exp(-i w s)) / (i w) without cancellation: sin(w s) / w - 2i sin^2(w s / 2) / w
        return complex(math.sin(OS * s), -2.0 * math.sin(0.5 * OS * s) ** 2) / OS

    def cquad(f: Callable[[float], complex]) -> complex:
        re = quad(lambda s: f(s).real, t0, t1, epsabs=0, epsrel=1e-12, limit=200)[0]
        im = quad(lambda s: f(s).imag, t0, t1, epsabs=0, epsrel=1e-12, limit=200)[0]
        return complex(re, im)

    E0, E1 = dv_coefficients(t0, t1, LAT)
    ref0, ref1 = cquad(lambda s: cmath.exp(-1j * OS * s)), cquad(e1)
    assert abs(E0 - ref0) <= 1e-12 * abs(E0)
    assert abs(E1 - ref1) <= 1e-12 * abs(E1)
    # the small imaginary parts carry the Os coupling: check them on their own scale
    assert E0.imag == pytest.approx(ref0.imag, rel=1e-9)
    assert E1.imag == pytest.approx(ref1.imag, rel=1e-9)


def test_predict_dv_matches_the_exact_platform() -> None:
    # Truth: HrgPlatform at 100 deg with x, y drifts (no azimuth drift: the filter's
    # azimuth is constant), increments integrated with the trapezoid rule on 10 ms.
    a0 = 100 * DEG
    eps = np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR
    p = HrgPlatform()
    p.azimuth0, p.index_time, p.omega_err_p, p.g = a0, -1.0, eps, G
    p.setup_experiment(0.0)
    p.exit_initialization_mode()
    x = apparent_state(a0, eps, (p.theta_E0, p.theta_N0))
    h, f_prev, worst = 0.01, p.f_p[:2].copy(), 0.0
    for k in range(200):
        dv = np.zeros(2)
        for j in range(100):
            p.do_step(k + j * h, h)
            dv += 0.5 * h * (f_prev + p.f_p[:2])
            f_prev = p.f_p[:2].copy()
        E0, E1 = dv_coefficients(float(k), k + 1.0, LAT)
        worst = max(worst, float(np.max(np.abs(predict_dv(x, E0, E1, LAT, G) - dv))))
    # Neglected: g theta^3 / 6 (1.8e-6 m/s per second at 35') and the second-order
    # azimuth creep (1/2) theta_E Oc t times f (~5e-7 m/s): 5e-6 m/s, against a signal
    # of 0.09 m/s per second where any first-order slip shows at 1e-4 or more.
    assert worst <= 5e-6


def test_dv_jacobian_matches_finite_differences() -> None:
    x = np.array([2 * ARCMIN, -1 * ARCMIN, 0.1 * DEG_PER_HOUR, 1.7])
    E0, E1 = dv_coefficients(120.0, 121.0, LAT)
    J = dv_jacobian(x, E0, E1, LAT, G)
    steps = np.array([1e-7, 1e-7, 1e-11, 1e-7])
    for k in range(4):
        dx = np.zeros(4)
        dx[k] = steps[k]
        fd = (predict_dv(x + dx, E0, E1, LAT, G) - predict_dv(x - dx, E0, E1, LAT, G)) / (
            2 * steps[k]
        )
        assert np.allclose(J[:, k], fd, rtol=1e-6, atol=0.0), k


def test_east_drift_and_azimuth_cannot_be_separated_in_one_position() -> None:
    # Eq. (15): (A, d) and (A + delta, d turned by delta) give the same increments.
    eps = np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR
    for a in (10 * DEG, 100 * DEG, -120 * DEG):
        x = apparent_state(a, eps, (3 * ARCMIN, 3 * ARCMIN))
        d = geo_drift(a, eps)
        # a truth with no east drift at the apparent azimuth has the same polar state
        psi2, dn2 = apparent_azimuth(x[3], 0.0, OC - math.hypot(d[0], OC - d[1]), LAT)
        assert psi2 == pytest.approx(x[3], abs=1e-15)
        assert dn2 == pytest.approx(x[2], abs=1e-20)
        # and the apparent azimuth is off the true one by about -d_E / (Oc - d_N)
        # (32' per 0.1 deg/h; the atan's cubic term is delta^2 / 3 ~ 1e-4 relative)
        assert float(wrap_angle(x[3] - a)) == pytest.approx(-d[0] / (OC - d[1]), rel=1e-3)


def test_mirror_solution_predicts_the_same_increments() -> None:
    # psi + pi, D_N -> 2 Oc - D_N, tilts -> -tilts: only the drift prior tells them apart.
    x = np.array([2 * ARCMIN, 3 * ARCMIN, 0.15 * DEG_PER_HOUR, 1.745])
    mirror = np.array([-x[0], -x[1], 2 * OC - x[2], float(wrap_angle(x[3] + math.pi))])
    for t0 in (0.0, 100.0, 399.0):
        E0, E1 = dv_coefficients(t0, t0 + 1.0, LAT)
        assert np.allclose(
            predict_dv(x, E0, E1, LAT, G), predict_dv(mirror, E0, E1, LAT, G), rtol=1e-12, atol=0
        )


def test_tilt_jacobian_is_the_exact_linear_map() -> None:
    x = np.array([2 * ARCMIN, -1 * ARCMIN, 0.1 * DEG_PER_HOUR, 0.3])
    u, J = tilt_jacobian(x, 150.0, 0.02, LAT)
    dx = np.array([1e-4, -2e-4, 3e-8])
    u2, _ = tilt_jacobian(x + np.append(dx, 0.0), 150.0, 0.02, LAT)
    assert np.allclose([u2.real - u.real, u2.imag - u.imag], J @ dx, rtol=1e-9, atol=1e-18)


# ----------------------------------------------------------------------- filters
def synthetic(x: np.ndarray, seed: int, n: int = 200, noise: bool = True) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        E0, E1 = dv_coefficients(float(k), k + 1.0, LAT)
        z = predict_dv(x, E0, E1, LAT, G)
        out.append(z + (math.sqrt(R_VAR) * rng.standard_normal(2) if noise else 0.0))
    return out


def run_filter(method: int, data: list[np.ndarray], seed: int = 0, n: int = 200) -> PositionFilter:
    f = PositionFilter(method, np.zeros(4), P0, LAT, G, R_VAR, np.random.default_rng(seed), n)
    for k, z in enumerate(data):
        f.update(z, float(k), k + 1.0)
    return f


@pytest.mark.parametrize("a_deg", [10.0, 100.0, 170.0, -120.0])
def test_kf_on_the_linear_model_recovers_noise_free_data_exactly(a_deg: float) -> None:
    x = apparent_state(
        a_deg * DEG, np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR, (3 * ARCMIN, -2 * ARCMIN)
    )
    f = run_filter(2, synthetic(x, 0, noise=False))
    # noise-free data of a linear model: only the (weak) prior pulls, at the level
    # sigma_post^2 / sigma_prior^2 ~ 1e-5 of the prior mean offset
    assert float(wrap_angle(f.x[3] - x[3])) == pytest.approx(0.0, abs=1e-3 * ARCMIN)
    assert f.x[2] == pytest.approx(x[2], abs=1e-5 * DEG_PER_HOUR)
    assert f.x[:2] == pytest.approx(x[:2], abs=1e-3 * ARCMIN)


def test_upf_converges_for_every_initial_azimuth_and_the_ekf_falls_into_the_mirror() -> None:
    eps = np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR
    for i, a_deg in enumerate((10.0, 45.0, 100.0, 170.0, -120.0)):
        x = apparent_state(a_deg * DEG, eps, (3 * ARCMIN, 3 * ARCMIN))
        data = synthetic(x, 100 + i)
        kf = run_filter(2, data)
        upf = run_filter(1, data, seed=i)
        sig = math.sqrt(kf.P[3, 3])  # the linear model's exact posterior: 0.53'
        assert 0.3 * ARCMIN < sig < 1.0 * ARCMIN
        # a consistent filter is within 4 sigma (P = 6e-5 per case) of the truth
        err = float(wrap_angle(upf.x[3] - x[3]))
        assert abs(err) <= 4.0 * sig, (a_deg, err / ARCMIN)
        assert math.sqrt(upf.P[3, 3]) == pytest.approx(sig, rel=0.2)
        # the first measurements rule out most of the circle: systematic resampling ran
        assert upf.n_resamples >= 1
        assert abs(upf.x[2] - x[2]) <= 4.0 * math.sqrt(kf.P[2, 2])
        if a_deg in (170.0, -120.0):
            ekf = run_filter(0, data)
            # the EKF ends on the mirror solution and claims sub-arcminute accuracy
            assert abs(float(wrap_angle(ekf.x[3] - x[3]))) > 170 * DEG
            assert ekf.x[2] == pytest.approx(2 * OC - x[2], rel=0.01)
            assert math.sqrt(ekf.P[3, 3]) < 1.0 * ARCMIN


def test_azimuth_grid_represents_the_prior() -> None:
    rng = np.random.default_rng(1)
    parts, cov, w = azimuth_grid(np.zeros(4), P0, 200, rng, True, 1.0)
    assert w == pytest.approx(np.full(200, 1 / 200))
    spacing = np.diff(np.unwrap(parts[:, 3]))
    assert spacing == pytest.approx(np.full(199, 2 * math.pi / 200), rel=1e-12)
    assert np.all(cov[:, 3, 3] == pytest.approx((2 * math.pi / 200) ** 2))
    assert np.all(cov[:, :3, :3] == P0[:3, :3])
    # Gaussian prior with correlations: the mixture keeps its mean and covariance
    m = np.array([1e-3, -2e-3, 1e-7, 0.5])
    a = np.array(
        [[1.0, 0.0, 0.0, 0.0], [0.3, 1.0, 0.0, 0.0], [0.0, 0.2, 1.0, 0.0], [0.5, 0.1, 0.0, 1.0]]
    )
    s = np.diag([3 * ARCMIN, 3 * ARCMIN, 0.2 * DEG_PER_HOUR, 2 * DEG])
    P = s @ a @ a.T @ s
    parts, cov, w = azimuth_grid(m, P, 400, rng, False, 1.0)
    mean = w @ parts
    r = parts - mean
    mix = (r * w[:, None]).T @ r + np.tensordot(w, cov, axes=1)
    assert mean == pytest.approx(m, abs=1e-3 * np.sqrt(np.diag(P)).max())
    # +-4 sigma grid: truncation removes 0.1 % of the variance; spacing^2 kernel adds 0.03 %
    assert np.allclose(mix, P, rtol=0, atol=5e-3 * np.sqrt(np.outer(np.diag(P), np.diag(P))))


# ----------------------------------------------------------------------- two positions
def exact_pair(a1: float, eps1: np.ndarray, eps2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x1 = apparent_state(a1, eps1, (0.0, 0.0))
    x2 = apparent_state(a1 + math.pi / 2, eps2, (0.0, 0.0))
    return x1, x2


@pytest.mark.parametrize("a_deg", [100.0, -120.0, 10.0])
def test_combine_positions_recovers_azimuth_and_gyro_drifts(a_deg: float) -> None:
    eps = np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR
    x1, x2 = exact_pair(a_deg * DEG, eps, eps)
    P = np.diag([1e-12, 1e-12, 1e-20, 1e-12])
    s = combine_positions(x1, P, x2, P, math.pi / 2, LAT)
    # before the correction each position is off by ~ d_E / Oc (tens of arcmin)
    assert abs(float(wrap_angle(x1[3] - a_deg * DEG))) > 5 * ARCMIN
    assert float(wrap_angle(s.azimuth_avg - a_deg * DEG)) == pytest.approx(0.0, abs=1e-12)
    assert float(wrap_angle(s.azimuth_1 - a_deg * DEG)) == pytest.approx(0.0, abs=1e-12)
    assert float(wrap_angle(s.azimuth_2 - a_deg * DEG)) == pytest.approx(0.0, abs=1e-12)
    assert s.D_E == pytest.approx(eps[0], abs=1e-18)
    assert s.D_N == pytest.approx(eps[1], abs=1e-18)
    assert s.H_E == pytest.approx(0.0, abs=1e-18)


def test_regular_drift_shows_in_h_e() -> None:
    # eq. (21): a drift that differs between the positions by delta along the direction
    # east at position 1 appears in H_E, halved: eq. (20) averages two azimuths of which
    # one is corrected with the changed drift, so the average moves by delta / (2 Oc)
    # and (D_E)_1 = -rho_1 sin(psi_1 - avg) with it by delta / 2.
    a1 = 100 * DEG
    eps = np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR
    east_p = rot_z(a1)[:2, :2].T @ np.array([1.0, 0.0])  # east at position 1, in p axes
    delta = 0.01 * DEG_PER_HOUR
    x1, x2 = exact_pair(a1, eps, eps + np.append(delta * east_p, 0.0))
    P = np.diag([1e-12, 1e-12, 1e-20, 1e-12])
    s = combine_positions(x1, P, x2, P, math.pi / 2, LAT)
    # second-order terms (|d| / Oc ~ 2 %) aside
    assert s.H_E == pytest.approx(0.5 * delta, rel=0.05)
    truth = exact_pair(a1, eps, eps)
    s0 = combine_positions(*[truth[0], P, truth[1], P], math.pi / 2, LAT)
    assert float(wrap_angle(s.azimuth_avg - s0.azimuth_avg)) == pytest.approx(
        -0.5 * delta / OC, rel=0.05
    )


def test_combined_sigma_matches_monte_carlo() -> None:
    x1, x2 = exact_pair(
        100 * DEG,
        np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR,
        np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR,
    )
    P1 = np.diag([1e-8, 1e-8, (0.002 * DEG_PER_HOUR) ** 2, (0.6 * ARCMIN) ** 2])
    P2 = np.diag([1e-8, 1e-8, (0.0015 * DEG_PER_HOUR) ** 2, (0.5 * ARCMIN) ** 2])
    s = combine_positions(x1, P1, x2, P2, math.pi / 2, LAT)
    rng = np.random.default_rng(5)
    n = 2000
    avg, dn = [], []
    for _ in range(n):
        y1 = x1 + rng.standard_normal(4) * np.sqrt(np.diag(P1))
        y2 = x2 + rng.standard_normal(4) * np.sqrt(np.diag(P2))
        r = combine_positions(y1, P1, y2, P2, math.pi / 2, LAT)
        avg.append(float(wrap_angle(r.azimuth_avg - s.azimuth_avg)))
        dn.append(r.D_N)
    # sample std of 2000 normal draws: relative error 1.6 %, so 5 % is a 3-sigma bound
    assert np.std(avg) == pytest.approx(s.sigma_avg, rel=0.05)
    assert np.std(dn) == pytest.approx(s.sigma_D_N, rel=0.05)


def test_position2_prior_covers_the_truth() -> None:
    a1 = 100 * DEG
    eps = np.array([0.1, 0.2, 0.0]) * DEG_PER_HOUR
    x1 = apparent_state(a1, eps, (3 * ARCMIN, 3 * ARCMIN))
    P1 = np.diag(
        [
            (0.01 * ARCMIN) ** 2,
            (0.01 * ARCMIN) ** 2,
            (0.002 * DEG_PER_HOUR) ** 2,
            (0.5 * ARCMIN) ** 2,
        ]
    )
    gap = 210.0
    x2, P2 = position2_prior(
        x1, P1, gap, math.pi / 2, LAT, 0.2 * DEG_PER_HOUR, 6 * ARCMIN, 3 * ARCMIN
    )
    # truth at position 2: tilts after 210 s of eq. (10) with the true drifts, model frame 2
    d1 = geo_drift(a1, eps)
    u_geo = cmath.exp(-1j * OS * gap) * complex(3 * ARCMIN, 3 * ARCMIN) + complex(
        d1[0], d1[1] - OC
    ) * (1 - cmath.exp(-1j * OS * gap)) / (1j * OS)
    truth = apparent_state(a1 + math.pi / 2, eps, (u_geo.real, u_geo.imag))
    sd = np.sqrt(np.diag(P2))
    z = np.abs([x2[0] - truth[0], x2[1] - truth[1], float(wrap_angle(x2[3] - truth[3]))])
    assert np.all(z <= 3.0 * sd[[0, 1, 3]]), z / sd[[0, 1, 3]]
    # the apparent azimuth moves by (d_N1 + d_E1) / Oc; the prior knows d_N1 only
    assert 0.9 * DEG < sd[3] < 1.3 * DEG  # sigma_drift / Oc = 1.08 deg dominates
    assert sd[2] == pytest.approx(0.2 * DEG_PER_HOUR)


# ----------------------------------------------------------------------- aligner and block
def test_aligner_rejects_position_2_first_and_bad_settings() -> None:
    al = TwoPositionAligner(method=2)
    al.start(0.0, 2.0)
    with pytest.raises(AlignmentSequenceError, match="expected position 1"):
        al.step(0.0, 0.1, np.zeros(3), 2.0)
    with pytest.raises(ValueError, match="method"):
        TwoPositionAligner(method=3)
    with pytest.raises(ValueError, match="period"):
        TwoPositionAligner(period=0.0)
    with pytest.raises(ValueError, match="method"):
        PositionFilter(7, np.zeros(4), P0, LAT, G, R_VAR, np.random.default_rng(0))


def test_aligner_uses_only_steps_at_rest_in_one_position() -> None:
    x1 = apparent_state(100 * DEG, np.zeros(3), (0.0, 0.0))
    al = TwoPositionAligner(method=2, accel_noise=N_ACC)
    al.start(0.0, 1.0)
    h = 0.1
    for k in range(100):
        E0, E1 = dv_coefficients(k * h, (k + 1) * h, LAT)
        assert al.step(k * h, h, predict_dv(x1, E0, E1, LAT, G), 1.0) == ((k + 1) % 10 == 0)
    n1 = al.filters[1].n_updates
    # moving, and the step that leaves position 1, carry nonsense: they must be dropped
    assert not al.step(10.0, h, np.array([5.0, 5.0, 5.0]), 0.0)
    for k in range(101, 150):
        assert not al.step(k * h, h, np.array([5.0, 5.0, 5.0]), 0.0)
    assert not al.step(15.0, h, np.array([5.0, 5.0, 5.0]), 2.0)  # status 0 -> 2 inside
    assert al.filters[1].n_updates == n1 and al.active == 1
    assert not al.step(15.1, h, np.zeros(3), 2.0)
    assert al.active == 2 and al.starts[2] == pytest.approx(15.1)
    assert al.final[1][0] == pytest.approx(al.filters[1].x)


def test_block_outputs_at_start_are_the_prior() -> None:
    b = HrgTwoPositionAlignment()
    b.setup_experiment(0.0)
    b.exit_initialization_mode()
    assert b.azimuth_sigma == pytest.approx(UNIFORM / ARCMIN)
    assert b.theta_E_sigma == pytest.approx(3.0)
    assert b.D_N_sigma == pytest.approx(0.2)
    assert b.t_conv_1 == -1.0 and b.converged == 0.0 and b.position_active == 0.0
    for v in b.variables:
        if v.causality == "output":
            assert np.all(np.isfinite(getattr(b, v.name))), v.name
