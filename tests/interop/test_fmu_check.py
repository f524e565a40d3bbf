"""The check-fmu report (cosim.interop.fmu_check): rename files, our own FMU, bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.interop.fmu_check import check_fmu, read_rename_file
from cosim.interop.interfaces import InterfaceError


def test_rename_file_forms(tmp_path: Path) -> None:
    a = tmp_path / "a.toml"
    a.write_text('[rename]\n"gyro_x" = "dtheta_meas_b[1]"\n')
    b = tmp_path / "b.toml"
    b.write_text('[blocks.imu]\nfmu = "x.fmu"\n[blocks.imu.rename]\n"gyro_x" = "d[1]"\n')
    assert read_rename_file(a) == {"gyro_x": "dtheta_meas_b[1]"}
    assert read_rename_file(b) == {"gyro_x": "d[1]"}
    c = tmp_path / "c.toml"
    c.write_text("[rename]\nx = 1\n")
    with pytest.raises(InterfaceError, match="expected a table of"):
        read_rename_file(c)


def test_check_fmu_on_our_own_imu_fmu(fmu_dir: Path, cli) -> None:
    report = check_fmu(fmu_dir / "StrapdownImu.fmu", "imu")
    assert report.satisfied and not report.match.needs_rename
    assert report.fmi_version == "2.0" and "linux64" in report.platforms
    assert report.capabilities["co-simulation"][0] is True
    assert report.capabilities["reset"] == (True, "fmi2Reset exported")
    res = cli("check-fmu", fmu_dir / "StrapdownImu.fmu", "--role", "imu")
    assert res.code == 0, res.out + res.err
    assert "result: 'StrapdownImu.fmu' fills role 'imu'\n" in res.out
    assert "rename map" not in res.out


def test_check_fmu_bad_input_is_one_line(cli, tmp_path: Path) -> None:
    res = cli("check-fmu", tmp_path / "none.fmu", "--role", "imu")
    assert res.code == 3 and "Traceback" not in res.err
    assert res.err.startswith("error: FMU file") and "does not exist" in res.err
