"""Cost of the unscented particle filter of seed 000 against the EKF, measured side by side.

Both filters of :mod:`cosim.alignment.hrg_filters` process the same 200
one-second velocity increments of one position (azimuth 100 deg, the paper's drifts,
accelerometer noise 5 ug/sqrt(Hz)); we time the updates only. The judged figure is
the ratio of the time per update, UPF with 200 particles over EKF: vectorising over
the particles must make 200 particles (each a UKF with 9 sigma points) cost less than
200 separate EKF updates. A full two-position scenario run (410 s of simulated time,
every block in-process) is timed for each filter for information.
"""

from __future__ import annotations

import math
import time

import numpy as np

from cosim.alignment.hrg_filters import PositionFilter
from cosim.alignment.hrg_model import apparent_azimuth, dv_coefficients, predict_dv
from cosim.models.constants import ARCMIN, DEG_PER_HOUR
from cosim.models.conventions import rot_z

LAT = math.radians(45.0)
G = 9.7966
N_UPDATES = 200
N_PARTICLES = 200
TARGET = 200.0


def _data(seed: int) -> tuple[list[np.ndarray], float]:
    """Increments of one position and their noise variance."""
    a = math.radians(100.0)
    eps = np.array([0.1, 0.2]) * DEG_PER_HOUR
    d = -(rot_z(a)[:2, :2] @ eps)
    psi, dn = apparent_azimuth(a, d[0], d[1], LAT)
    x = np.array([3 * ARCMIN, 3 * ARCMIN, dn, psi])
    r_var = (5e-6 * 9.80665) ** 2 + 1e-4**2 / 6.0
    rng = np.random.default_rng(seed)
    out = []
    for k in range(N_UPDATES):
        E0, E1 = dv_coefficients(float(k), k + 1.0, LAT)
        out.append(predict_dv(x, E0, E1, LAT, G) + math.sqrt(r_var) * rng.standard_normal(2))
    return out, r_var


def time_per_update(method: int, data: list[np.ndarray], r_var: float, repeat: int = 3) -> float:
    """Best-of-``repeat`` mean time of one filter update [s]."""
    P0 = np.diag([(3 * ARCMIN) ** 2, (3 * ARCMIN) ** 2, (0.2 * DEG_PER_HOUR) ** 2, math.pi**2 / 3])
    best = math.inf
    for r in range(repeat):
        f = PositionFilter(
            method, np.zeros(4), P0, LAT, G, r_var, np.random.default_rng(r), N_PARTICLES
        )
        start = time.perf_counter()
        for k, z in enumerate(data):
            f.update(z, float(k), k + 1.0)
        best = min(best, (time.perf_counter() - start) / len(data))
    return best


def scenario_run_time(method: int) -> float:
    """Wall time of one full two-position scenario run (410 s simulated) [s]."""
    from cosim.reproduce.seed000 import campaign, prepared

    prep = prepared()  # checking the scenario is not part of the run
    start = time.perf_counter()
    campaign(1, 0, methods=(method,), prep=prep)
    return time.perf_counter() - start


def bench() -> list[dict]:
    """Time per update of the UPF (200 particles) and the EKF, and their ratio.

    Returns
    -------
    list of dict
        Rows for ``python -m benchmarks``: ``name``, ``ratio``, ``target``, ``met``,
        ``info`` (absolute times: ``t_upf_ms``, ``t_ekf_ms`` per update, full runs).
    """
    data, r_var = _data(1)
    t_ekf = time_per_update(0, data, r_var)
    t_upf = time_per_update(1, data, r_var)
    t_kf = time_per_update(2, data, r_var)
    ratio = t_upf / t_ekf
    run_upf = scenario_run_time(1)
    run_ekf = scenario_run_time(0)
    return [
        {
            "name": f"seed000 UPF ({N_PARTICLES} particles) / EKF, time per update",
            "ratio": ratio,
            "target": f"<= {TARGET:g}",
            "met": bool(ratio <= TARGET),
            "info": (
                f"UPF {t_upf * 1e3:.3f} ms, EKF {t_ekf * 1e3:.3f} ms, KF {t_kf * 1e3:.3f} ms "
                "per update"
            ),
            "t_upf_ms": t_upf * 1e3,
            "t_ekf_ms": t_ekf * 1e3,
            "t_kf_ms": t_kf * 1e3,
        },
        {
            "name": "seed000 two-position run (410 s simulated), UPF / EKF wall time",
            "ratio": run_upf / run_ekf,
            "target": "",
            "met": None,
            "info": f"UPF {run_upf:.2f} s, EKF {run_ekf:.2f} s per run",
            "run_upf_s": run_upf,
            "run_ekf_s": run_ekf,
        },
    ]


if __name__ == "__main__":  # pragma: no cover
    for row in bench():
        print(row)
