"""The monolithic numpy chain (benchmarks/monolithic.py) equals the co-simulation to 1e-9.

The benchmark "co-simulation vs monolithic" is only meaningful if both compute the same
thing: every output of every block of benchmarks/transfer_chain.toml, from the same
parameters and seeds (so the same random draws in the same order).
"""

from __future__ import annotations

import numpy as np
import pytest

import cosim
from benchmarks.monolithic import CHAIN_SCENARIO, affine_scan, chain_parameters, simulate

TOL = 1e-9


def worst_mismatch(result: cosim.RunResult, mono: dict[str, np.ndarray]) -> tuple[str, float]:
    """Largest difference over every recorded column, relative to the column's magnitude.

    Returns
    -------
    name : str
        The worst column.
    error : float
        ``max |co-sim - monolithic| / max(|co-sim|)`` for that column (absolute when the
        column is identically zero).
    """
    worst = ("", 0.0)
    for name in result.names:
        base, _, index = name.partition("[")
        assert base in mono, f"the monolithic program does not compute {base}"
        col = mono[base] if not index else mono[base][:, int(index[:-1]) - 1]
        ref = result.data[name]
        assert col.shape == ref.shape, name
        scale = float(np.max(np.abs(ref)))
        err = float(np.max(np.abs(col - ref))) / (scale if scale > 0.0 else 1.0)
        if not err <= worst[1]:
            worst = (name, err)
    return worst


def test_chain_matches_cosimulation() -> None:
    # The benchmark's chain (flexure on, seed 001 slave IMU with its random parts),
    # 20 s of the 120 s the benchmark runs: 2000 macro steps, 42,000 truth nodes.
    sc = cosim.load_scenario(CHAIN_SCENARIO)
    params = chain_parameters(sc)
    result = cosim.run(sc, stop=20.0)
    mono = simulate(params, stop=20.0)
    # time + every output: ship 24 scalars, flexure 18, lever 21, imu 18
    assert len(result.names) == 1 + 24 + 18 + 21 + 18
    name, err = worst_mismatch(result, mono)
    assert err <= TOL, f"{name}: relative difference {err:.3g}"
    # the IMU really sees the flexure: another flexure seed changes its output far
    # beyond the tolerance (so the agreement above is not trivial)
    params.blocks["flexure"]["seed"] = 99
    other = simulate(params, stop=20.0)
    dtheta = result["imu.dtheta_meas_b"]
    assert np.max(np.abs(other["imu.dtheta_meas_b"] - dtheta)) > 1e3 * TOL * np.max(np.abs(dtheta))


def test_other_branches_match_cosimulation() -> None:
    # Moving ship (surge/sway/heave), rigid deck, tactical IMU with Gauss-Markov bias,
    # turn-on errors, bias random walk and a rate-biased RLG: the branches the
    # benchmark's chain does not take.
    sc = cosim.load_scenario(CHAIN_SCENARIO)
    sc.blocks["ship"].parameters.update(
        lin_amp=[1.5, 0.8, 0.4], lin_period=[9.0, 11.0, 7.0], rpy_mean=["2 deg", "-1 deg", "40 deg"]
    )
    sc.blocks["lever"].parameters["flexure"] = 0
    sc.blocks["imu"].parameters.update(
        grade=2, gyro_rrw=1e-7, accel_rrw=1e-5, rlg_mode=2, gyro_bi_tau="5 s", seed=5
    )
    params = chain_parameters(sc)
    result = cosim.run(sc, stop=5.0)
    mono = simulate(params, stop=5.0)
    name, err = worst_mismatch(result, mono)
    assert err <= TOL, f"{name}: relative difference {err:.3g}"
    assert np.ptp(result["ship.v_n"][:, 0]) > 0.1  # the ship did move
    assert np.ptp(result["imu.gyro_bias_b"][:, 0]) > 0.0  # the bias did wander


def test_affine_scan_equals_the_recursion() -> None:
    rng = np.random.default_rng(3)
    m = rng.standard_normal((2, 3, 3)) * 0.5
    c = rng.standard_normal((37, 2, 3))
    x = np.zeros((2, 3))
    expected = []
    for k in range(len(c)):
        x = np.einsum("aij,aj->ai", m, x) + c[k]
        expected.append(x)
    np.testing.assert_allclose(affine_scan(m, c), np.array(expected), rtol=1e-12, atol=1e-12)


def test_quantisation_is_refused() -> None:
    sc = cosim.load_scenario(CHAIN_SCENARIO)
    sc.blocks["imu"].parameters["gyro_lsb"] = 1e-9
    with pytest.raises(ValueError, match="quantisation"):
        simulate(chain_parameters(sc), stop=0.1)
