"""Shared by the land-vehicle transfer-alignment tests: one run of the scenario, its figures.

Not a test module: ``tests/alignment/test_transfer_matching.py`` (fast and slow tests) and the
acceptance campaign of docs/transfer_alignment.md run
``scenarios/transfer_alignment_vehicle.toml`` through :func:`vehicle_run`. Run ``i`` takes
the IMU seed ``1000 + i`` and the master seed ``2000 + i`` (the scenario's own seeds are
run -1's: 2 and 3 are not used here).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

import cosim
from cosim.models.constants import ARCMIN
from cosim.scenario import build_master

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "transfer_alignment_vehicle.toml"
#: The slave's true mounting in the scenario (LeverArm.mount_rpy) [deg].
MOUNT_DEG = (0.5, -0.8, 1.5)


def vehicle_run(
    i: int, stop: float = 100.0, truth: bool = True, latency: float = 0.0, **align: Any
) -> np.ndarray:
    """Run ``i`` of the land-vehicle scenario to ``stop`` [s].

    Parameters
    ----------
    i : int
        Run index (seeds ``1000 + i``, ``2000 + i``).
    stop : float
        Stop time [s].
    truth : bool
        False leaves the two truth inputs of the filter unconnected (``unconnected_ok``).
    latency : float
        The master's data latency [s] (MasterIns.latency).
    **align
        Filter parameters replacing the scenario's (SI values or unit strings).

    Returns
    -------
    structured ndarray
        The recording (every 0.1 s).
    """
    sc = cosim.load_scenario(SCENARIO)
    sc.blocks["align"].parameters.update(align)
    sc.blocks["imu"].parameters["seed"] = 1000 + i
    sc.blocks["master"].parameters["seed"] = 2000 + i
    sc.blocks["master"].parameters["latency"] = latency
    if not truth:
        sc.connections = [c for c in sc.connections if "_true" not in c]
        sc.blocks["align"].unconnected_ok = ["rpy_s_true", "rpy_m_true"]
    master = build_master(sc, stop=stop)
    try:
        result = master.run()
    finally:
        master.terminate()
    assert result.status == "completed"
    return result.data


def final_figures(data: np.ndarray) -> dict[str, Any]:
    """Errors and sigmas at the last recorded instant.

    Returns
    -------
    dict
        ``rpy_err``, ``rpy_sigma`` [arcmin] (relative attitude), ``accel_err``,
        ``accel_sigma`` [m/s2], ``gyro_err``, ``gyro_sigma`` [rad/s] (estimate minus the
        IMU's true bias), ``mount_err`` (``mount`` minus the true mounting), ``mount_sigma``
        [arcmin], ``lag``, ``lag_sigma`` [s], ``nis_mean`` (after 10 s), ``nis_dof``.
    """
    row = data[-1]

    def vec(name: str) -> np.ndarray:
        return np.array([float(row[f"{name}[{k}]"]) for k in (1, 2, 3)])

    late = data["time"] > 10.0
    return {
        "rpy_err": vec("align.rpy_err"),
        "rpy_sigma": vec("align.rpy_sigma"),
        "accel_err": vec("align.accel_bias") - vec("imu.accel_bias_b"),
        "accel_sigma": vec("align.accel_bias_sigma"),
        "gyro_err": vec("align.gyro_drift") - vec("imu.gyro_bias_b"),
        "gyro_sigma": vec("align.gyro_drift_sigma"),
        "mount_err": (vec("align.mount") - np.radians(MOUNT_DEG)) / ARCMIN,
        "mount_sigma": vec("align.mount_sigma"),
        "lag": float(row["align.lag"]),
        "lag_sigma": float(row["align.lag_sigma"]),
        "nis_mean": float(np.mean(data["align.nis"][late])),
        "nis_dof": float(row["align.nis_dof"]),
    }
