"""Stand-ins for recordings: simulated logs written as a logger would write them.

``python -m cosim.sensors.demo OUT.csv [--seed S]`` runs ``scenarios/sins_north_finding.toml``
with the StrapdownImu's seed ``S`` (its turn-on biases and noise drawn from it) and writes
the measured increments of every 100 ms step with :func:`cosim.sensors.logs.write_csv`:
300 s at 10 Hz, the base at the scenario's known attitude (roll 0.3 deg, pitch -0.5 deg,
heading 30 deg, latitude 45 deg N). It lets the README's real-sensor workflow run end to
end without a sensor; with a real unit, record its log instead.

``python -m cosim.sensors.demo --transfer FOLDER [--stop T] [--master-delay D]`` runs
``scenarios/transfer_alignment.toml`` (seed 001's ship, 20 Hz) and writes the two logs of a
transfer alignment on recordings (:func:`write_transfer_logs`): ``slave_imu.csv`` (the
slave IMU's increments) and ``master_ins.csv`` (the master INS's solution, its time stamps
``D`` seconds late, as a second logger's clock would be).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

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


#: The seed 001 transfer-alignment scenario, whose slave IMU and master INS the logs record.
SEED001 = SEED003.parent / "transfer_alignment.toml"
#: Header of the master-INS log :func:`write_transfer_logs` writes (SI units).
MASTER_HEADER = (
    "time [s],v_n [m/s],v_e [m/s],v_d [m/s],roll [rad],pitch [rad],yaw [rad],lat [rad],"
    "lon [rad],h [m]"
)


def transfer_run(stop: str = "100 s") -> Any:
    """The seed 001 transfer-alignment run with what its two logs need, every step recorded.

    Parameters
    ----------
    stop : str, optional
        Length of the run.

    Returns
    -------
    cosim.RunResult
        ``align``, the slave IMU's measured increments and the master INS's outputs.
    """
    import cosim

    sc = cosim.load_scenario(SEED001)
    sc.outputs = ["align", "imu.dtheta_meas_b", "imu.dv_meas_b", "master"]
    return cosim.run(sc, record_every=1, stop=stop)


def write_transfer_logs(
    folder: str | Path, result: Any = None, stop: str = "100 s", master_delay: float = 0.0
) -> tuple[Path, Path]:
    """Write the slave-IMU and master-INS logs of a transfer-alignment run.

    Parameters
    ----------
    folder : str or Path
        Where ``slave_imu.csv`` and ``master_ins.csv`` go (created).
    result : cosim.RunResult, optional
        A run of :func:`transfer_run`; None runs one of length ``stop``.
    stop : str, optional
        Length of the run made when ``result`` is None.
    master_delay : float, optional
        Added to the master log's time stamps [s]: its logger's clock runs that much late.

    Returns
    -------
    (Path, Path)
        The IMU log (increments; row k covers the step ending at its time) and the
        master log (states at their time stamps, the first at the start). Every value
        is written with ``repr``, so both read back exactly.
    """
    from cosim.sensors.logs import write_csv

    r = transfer_run(stop) if result is None else result

    def vec(name: str) -> np.ndarray:
        return np.column_stack([r[f"{name}[{i}]"] for i in (1, 2, 3)])

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    imu = write_csv(
        folder / "slave_imu.csv", r.time[1:], vec("imu.dtheta_meas_b")[1:], vec("imu.dv_meas_b")[1:]
    )
    cols = [r.time + master_delay, vec("master.v_master_n"), vec("master.rpy_master")]
    cols += [r["master.lat_master"], r["master.lon_master"], r["master.h_master"]]
    master = folder / "master_ins.csv"
    with master.open("w") as fh:
        fh.write(MASTER_HEADER + "\n")
        for row in np.column_stack(cols).tolist():
            fh.write(",".join(map(repr, row)) + "\n")
    return imu, master


def main(argv: list[str] | None = None) -> None:
    """Command line of the demo log.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the CSV log to write (--transfer: a folder)")
    parser.add_argument("--seed", type=int, default=7, help="the IMU's seed (default 7)")
    parser.add_argument(
        "--transfer", action="store_true", help="write the two logs of a transfer alignment"
    )
    parser.add_argument("--stop", default="100 s", help="--transfer: length (default 100 s)")
    parser.add_argument(
        "--master-delay", type=float, default=0.0, help="--transfer: master stamps late by [s]"
    )
    args = parser.parse_args(argv)
    if args.transfer:
        paths = write_transfer_logs(args.out, stop=args.stop, master_delay=args.master_delay)
        print(f"wrote {paths[0]} and {paths[1]}")
        return
    print(f"wrote {write_demo_log(args.out, args.seed)}")


if __name__ == "__main__":  # pragma: no cover
    main()
