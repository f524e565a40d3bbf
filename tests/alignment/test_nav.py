"""The one strapdown integrator (cosim/alignment/nav.py) and its small rotations.

The reference numbers below are the final states of the two integrators the filters had
before they shared this one (``sins_static.Strapdown`` and ``transfer.SlaveStrapdown``),
run on the same fixed increments: the shared integrator with each filter's preset must
reproduce them bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.alignment.nav import (
    MOVING_BASE,
    STATIC_BASE,
    Mechanisation,
    Strapdown,
    dcm_to_rotvec_3,
    euler_rate_matrix,
    euler_rate_matrix_inv,
    rotation_compensation,
    step_mean_dcm,
    table_axis_coning,
)
from cosim.alignment.transfer_model import PeriodSums
from cosim.blocks import InProcessHost
from cosim.master import Connection, Master, MasterSettings, System
from cosim.models.blocks.stationary_base import StationaryBase
from cosim.models.blocks.strapdown_imu import StrapdownImu
from cosim.models.constants import OMEGA_IE
from cosim.models.conventions import dcm_to_rotvec, euler_to_dcm, euler_to_dcm_3, rotvec_to_dcm_3

# sins_static.Strapdown: 200 steps of 0.1 s on a tilted table, one correction after 100
STATIC_C = [
    [-0.4065195513320391, 0.913287620191266, -0.025447537998233266],
    [-0.504851000551121, -0.24775769168827905, -0.8268866871898631],
    [-0.7614901979850623, -0.32329839005888855, 0.5617925145086943],
]
STATIC_V = [4.857521273476834, 162.06653798675757, 0.0]
STATIC_CMEAN = [
    [-0.4839996437893888, 0.8732454752894298, -0.0254873677801027],
    [-0.4806787351552252, -0.29049099974354964, -0.8268972608161349],
    [-0.729488553851775, -0.3879672291011096, 0.5617751450839397],
]
# transfer.SlaveStrapdown: 300 steps of 20 ms with biases, period restarts every 25 steps
SLAVE_C = [
    [0.6965599282369057, -0.7172366314461094, 0.019387647779853124],
    [0.717478971043693, 0.696486484199681, -0.0114238101019479],
    [-0.005309659563290585, 0.021867597924851434, 0.999746775776908],
]
SLAVE_V = [-0.15226631570115803, 0.22657954400972297, 0.07384377647420937]
SLAVE_LAT = 0.5200003086150542
SLAVE_SUMS_LAST = [
    0.5000000000000001,
    -0.13685412879792494,
    0.0729122206163261,
    -4.897793192814598,
    0.3527328321902503,
    -0.35422072084301826,
    0.009701846676328648,
    0.3543424533903616,
    0.3526979184881788,
    -0.0057007428038092466,
    -0.002805058538719841,
    0.01089742599198715,
    0.49987335819438183,
    -0.041754971156907975,
    0.09371507325262342,
    0.037114496600314004,
    3.165585966231009e-05,
    6.5738538907556996e-09,
    -1.8124950194939703e-05,
    6.32970402392529e-05,
    6.5738538907556996e-09,
    -3.624149569975166e-05,
    0.5200003151889081,
    7.0,
]


def _inputs(n: int, h: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Fixed smooth increments: a turn about the sensor z axis plus small wobbles."""
    k = np.arange(n)[:, None]
    dth = np.hstack(
        [1e-5 * np.sin(0.3 * k + 0.1), 2e-5 * np.cos(0.2 * k), rate * h + 1e-6 * np.sin(0.05 * k)]
    )
    dv = np.hstack(
        [1e-3 * np.cos(0.1 * k), 2e-3 * np.sin(0.07 * k), -9.8 * h + 1e-4 * np.cos(0.3 * k)]
    )
    return dth, dv


def test_static_base_preset_reproduces_the_old_static_integrator() -> None:
    dth, dv = _inputs(200, 0.1, 1.7453292519943295)
    c_s_t = euler_to_dcm_3(np.array([45.0, -35.264, 0.0]) * math.pi / 180)  # as recorded
    c0 = euler_to_dcm_3([0.01, -0.02, 0.5]) @ c_s_t
    nav = Strapdown(c0, 0.7, 12.0, options=STATIC_BASE, table_axis=c_s_t[2, :])
    for k in range(200):
        nav.step(dth[k], dv[k], 0.1)
        if k == 99:
            nav.correct(
                rotation=rotvec_to_dcm_3(np.array([1e-4, -2e-4, 3e-4])),
                d_v=np.array([1e-3, -2e-3, 0.0]),
            )
    np.testing.assert_array_equal(nav.C_s_n, STATIC_C)
    np.testing.assert_array_equal(nav.v_n, STATIC_V)
    np.testing.assert_array_equal(nav.mean_attitude(), STATIC_CMEAN)


def test_moving_base_preset_reproduces_the_old_slave_integrator() -> None:
    dth, dv = _inputs(300, 0.02, 0.05)
    nav = Strapdown(euler_to_dcm([0.02, 0.01, 0.52]), 0.52, 7.0, [1.0, -0.5, 0.1])
    assert nav.options is MOVING_BASE
    nav.accel_bias = np.array([1e-4, -2e-4, 3e-4])
    nav.gyro_bias = np.array([1e-7, 2e-7, -1e-7])
    sums = PeriodSums(lat=nav.lat, height=nav.height)
    last = None
    for k in range(300):
        nav.step(dth[k], dv[k], 0.02)
        sums.add(nav, 0.02)
        if (k + 1) % 25 == 0:
            last = [sums.T, *sums.dv_f, *sums.c_int.ravel(), *sums.v_int, *sums.w_in, *sums.cor]
            last += [sums.lat, sums.height]
            if k == 149:
                nav.correct(
                    rotation=euler_to_dcm([1e-3, -1e-3, 2e-2]).T,
                    d_v=np.array([1e-3, 2e-3, -1e-3]),
                    d_lat=1e-7,
                )
            nav.refresh()
            sums = PeriodSums(lat=nav.lat, height=nav.height)
    np.testing.assert_array_equal(nav.C_s_n, SLAVE_C)
    np.testing.assert_array_equal(nav.v_n, SLAVE_V)
    assert nav.lat == SLAVE_LAT
    np.testing.assert_array_equal(last, SLAVE_SUMS_LAST)


def test_the_presets_differ_only_in_their_options() -> None:
    """On a perfect static IMU both presets hold the attitude; options are validated."""
    lat, h = 0.6, 0.1
    c = euler_to_dcm_3([0.01, -0.02, 1.0])
    w_ie = np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])
    for opts in (STATIC_BASE, MOVING_BASE):
        nav = Strapdown(c, lat, 0.0, options=opts)
        f_s = c.T @ np.array([0.0, 0.0, -nav.g])
        for _ in range(600):
            nav.step(c.T @ w_ie * h, f_s * h, h)
        assert np.max(np.abs(dcm_to_rotvec_3(nav.C_s_n @ c.T))) < 1e-12
        assert np.max(np.abs(nav.v_n)) < 1e-7  # 0.1 um/s after 60 s (second-order terms)
    with pytest.raises(ValueError, match="coning"):
        Mechanisation(coning="one-sample")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="orthonormalise_every"):
        Mechanisation(orthonormalise_every=-1)


def test_small_rotation_helpers() -> None:
    rng = np.random.default_rng(5)
    phi = rng.normal(0.0, 0.3, 3)
    c = rotvec_to_dcm_3(phi)
    np.testing.assert_allclose(dcm_to_rotvec_3(c), phi, atol=1e-15)
    np.testing.assert_allclose(dcm_to_rotvec_3(c), dcm_to_rotvec(c), atol=1e-14)
    # J(phi) is the mean of exp([s phi x]) over s in [0, 1] (Simpson, 201 nodes)
    s = np.linspace(0.0, 1.0, 201)
    w = np.full(201, 2.0)
    w[1:-1:2] = 4.0
    w[0] = w[-1] = 1.0
    mean = sum(wi * rotvec_to_dcm_3(si * phi) for si, wi in zip(s, w, strict=True)) / (3 * 200)
    np.testing.assert_allclose(step_mean_dcm(phi), mean, atol=1e-10)
    np.testing.assert_allclose(
        rotation_compensation(phi) @ step_mean_dcm(-phi), np.eye(3), atol=1e-14
    )
    # a pure table turn: the rotation vector is the increment itself
    axis = np.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose(table_axis_coning(0.2 * axis, axis), 0.2 * axis, atol=1e-16)
    rpy = np.array([0.2, -0.3, 2.5])
    np.testing.assert_allclose(
        euler_rate_matrix_inv(rpy) @ euler_rate_matrix(rpy), np.eye(3), atol=1e-14
    )


# The example of docs/extending.md ("Writing an alignment filter"), verbatim after its path comment.
TOY_LEVELLING = '''
import numpy as np

from cosim.alignment.nav import STATIC_BASE, Strapdown
from cosim.estimation import KalmanFilter
from cosim.models.block import Block, input_, output, parameter
from cosim.models.conventions import dcm_to_euler_3, rotvec_to_dcm_3


# ---- error model: x = [dv_N, dv_E, psi_N, psi_E], dv_N' = g psi_E, dv_E' = -g psi_N
def transition(g: float, h: float) -> np.ndarray:
    A = np.zeros((4, 4))
    A[0, 3], A[1, 2] = g * h, -g * h
    return np.eye(4) + A + 0.5 * A @ A


H = np.hstack([np.eye(2), np.zeros((2, 2))])  # the zero-velocity update sees dv_N, dv_E


# ---- block: FMI variables, strapdown, filter, closed-loop feedback
class ToyLevelling(Block):
    """Levels a stationary IMU with zero-velocity updates (roll and pitch only)."""

    variables = (
        parameter("lat", 0.785, "rad", "latitude"),
        parameter("r_vel", 0.01, "m/s", "zero-velocity measurement sigma"),
        input_("dtheta_s", (0.0, 0.0, 0.0), "rad", "angle increment, sensor axes"),
        input_("dv_s", (0.0, 0.0, 0.0), "m/s", "velocity increment, sensor axes"),
        output("level", (0.0, 0.0), "rad", "estimated roll and pitch"),
    )
    default_step = 0.1

    def initialize(self) -> None:
        self._nav = Strapdown(np.eye(3), float(self.lat), options=STATIC_BASE)
        self._kf = KalmanFilter(4, 2)
        self._kf.P = np.diag([0.1**2, 0.1**2, 0.02**2, 0.02**2])
        self._kf.H, self._kf.R = H, float(self.r_vel) ** 2

    def step(self, t: float, h: float) -> None:
        nav, kf = self._nav, self._kf
        nav.step(np.asarray(self.dtheta_s), np.asarray(self.dv_s), h)
        kf.predict(F=transition(nav.g, h))
        kf.update(nav.v_n[:2])
        x = kf.x
        nav.correct(rotation=rotvec_to_dcm_3([x[2], x[3], 0.0]), d_v=np.array([*x[:2], 0.0]))
        kf.x = np.zeros(4)
        self.level = dcm_to_euler_3(nav.C_s_n)[:2]
'''


def test_the_readme_example_filter_levels_a_tilted_imu(tmp_path, monkeypatch) -> None:
    """The example filter runs on the navigation core and returns the base's tilts."""
    (tmp_path / "toy_level.py").write_text(TOY_LEVELLING)
    monkeypatch.syspath_prepend(str(tmp_path))
    from toy_level import ToyLevelling

    def vec(src: str, out: str, dst: str, inp: str) -> list[Connection]:
        return [Connection(src, f"{out}[{i}]", dst, f"{inp}[{i}]") for i in (1, 2, 3)]

    blocks = {
        "base": InProcessHost("base", StationaryBase),
        "imu": InProcessHost("imu", StrapdownImu),
        "align": InProcessHost("align", ToyLevelling),
    }
    links = vec("base", "dtheta_b", "imu", "dtheta_b") + vec("base", "dv_b", "imu", "dv_b")
    links += vec("imu", "dtheta_meas_b", "align", "dtheta_s")
    links += vec("imu", "dv_meas_b", "align", "dv_s")
    params = {"base": {"lat0": 0.785, "rpy0[1]": 0.01, "rpy0[2]": -0.005}, "imu": {}, "align": {}}
    record = [("align", "level[1]"), ("align", "level[2]")]
    system = System(blocks, links, parameters=params, record=record)
    d = Master(system, MasterSettings(0.1, 60.0)).run().data
    assert abs(d["align.level[1]"][-1] - 0.01) < 1e-6
    assert abs(d["align.level[2]"][-1] + 0.005) < 1e-6
