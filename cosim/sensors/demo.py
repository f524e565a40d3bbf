"""A stand-in for a lab recording: the seed 003 IMU, simulated, written as a static log.

``python -m cosim.sensors.demo OUT.csv [--seed S]`` runs ``scenarios/sins_north_finding.toml``
with the StrapdownImu's seed ``S`` (its turn-on biases and noise drawn from it) and writes
the measured increments of every 100 ms step with :func:`cosim.sensors.logs.write_csv`:
300 s at 10 Hz, the base at the scenario's known attitude (roll 0.3 deg, pitch -0.5 deg,
heading 30 deg, latitude 45 deg N). It lets the README's real-sensor workflow run end to
end without a sensor; with a real unit, record its log instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from cosim.package_data import scenario_file

#: The seed 003 scenario, whose IMU the demo log records.
SEED003 = scenario_file("sins_north_finding.toml")


def write_demo_log(path: str | Path, seed: int = 7, stop: str = "300 s") -> Path:
    """Simulate the seed 003 IMU and write its increments as a CSV log.

    Parameters
    ----------
    path : str or Path
        The log to write.
    seed : int, optional
        The StrapdownImu's seed (a different unit of the same type per seed).
    stop : str, optional
        Length of the recording.

    Returns
    -------
    Path
    """
    import cosim
    from cosim.sensors.logs import write_csv

    sc = cosim.load_scenario(SEED003)
    sc.blocks["imu"].parameters["seed"] = int(seed)
    sc.outputs = ["imu.dtheta_meas_b", "imu.dv_meas_b"]
    result = cosim.run(sc, record_every=1, stop=stop)
    dtheta = np.column_stack([result[f"imu.dtheta_meas_b[{i}]"] for i in (1, 2, 3)])
    dv = np.column_stack([result[f"imu.dv_meas_b[{i}]"] for i in (1, 2, 3)])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_csv(path, result.time[1:], dtheta[1:], dv[1:])


def main(argv: list[str] | None = None) -> None:
    """Command line of the demo log.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the CSV log to write")
    parser.add_argument("--seed", type=int, default=7, help="the IMU's seed (default 7)")
    args = parser.parse_args(argv)
    print(f"wrote {write_demo_log(args.out, args.seed)}")


if __name__ == "__main__":  # pragma: no cover
    main()
