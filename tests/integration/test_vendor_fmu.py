"""The C vendor IMU (fmus/vendor_example): a binary FMI 2.0 FMU, swapped in for StrapdownImu.

The FMU is compiled from C during the session (conftest ``vendor_imu_fmu``); its
deliberately wrong variant is built here from the same C source with a model
description that drops a variable, changes a causality and declares an incompatible
unit.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

import cosim
from cosim.interop.cbuild import build_c_fmu
from cosim.interop.fmu_check import check_fmu
from cosim.models.constants import DEG, G0
from cosim.scenario import build_master

ROOT = Path(__file__).resolve().parents[2]
VENDOR = ROOT / "fmus" / "vendor_example"

#: The rename map that fits the vendor IMU to the role "imu" (what check-fmu suggests).
RENAME = {
    **{f"true_dtheta_{a}": f"dtheta_b[{i}]" for i, a in enumerate("xyz", 1)},
    **{f"true_dv_{a}": f"dv_b[{i}]" for i, a in enumerate("xyz", 1)},
    **{f"gyro_angle_{a}": f"dtheta_meas_b[{i}]" for i, a in enumerate("xyz", 1)},
    **{f"accel_dv_{a}": f"dv_meas_b[{i}]" for i, a in enumerate("xyz", 1)},
    **{f"gyro_rate_{a}": f"omega_meas_b[{i}]" for i, a in enumerate("xyz", 1)},
    **{f"accel_f_{a}": f"f_meas_b[{i}]" for i, a in enumerate("xyz", 1)},
}


def rename_table(block: str) -> str:
    return f"[blocks.{block}.rename]\n" + "".join(f'"{k}" = "{v}"\n' for k, v in RENAME.items())


def wrong_model_description() -> str:
    """The vendor's model description without accel_dv_z, with true_dtheta_y a parameter
    and gyro_angle_z in m/s (ModelStructure rebuilt, so the FMU still validates)."""
    root = ET.fromstring((VENDOR / "modelDescription.xml").read_text())
    variables = root.find("ModelVariables")
    by_name = {sv.get("name"): sv for sv in variables.findall("ScalarVariable")}
    variables.remove(by_name["accel_dv_z"])
    by_name["true_dtheta_y"].attrib.update(
        causality="parameter", variability="fixed", initial="exact"
    )
    by_name["gyro_angle_z"].find("Real").set("unit", "m/s")
    outputs = root.find("ModelStructure/Outputs")
    for unknown in list(outputs):
        outputs.remove(unknown)
    for index, sv in enumerate(variables.findall("ScalarVariable"), start=1):
        if sv.get("causality") == "output":
            ET.SubElement(outputs, "Unknown", index=str(index), dependencies="")
    return ET.tostring(root, encoding="unicode", xml_declaration=True)


@pytest.fixture(scope="module")
def wrong_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("vendor_wrong") / "VendorImuWrong.fmu"
    return build_c_fmu(VENDOR, out, model_description=wrong_model_description())


def test_vendor_fmu_is_a_valid_binary_fmu(vendor_imu_fmu: Path) -> None:
    assert validate_fmu(str(vendor_imu_fmu)) == []
    with zipfile.ZipFile(vendor_imu_fmu) as zf:
        assert sorted(zf.namelist()) == [
            "binaries/linux64/VendorImu.so",
            "modelDescription.xml",
        ]
        binary = zf.read("binaries/linux64/VendorImu.so")
    assert binary.startswith(b"\x7fELF")
    assert b"libpython" not in binary and b"Py_Initialize" not in binary  # no Python inside


def test_vendor_fmu_runs_standalone_under_fmpy(vendor_imu_fmu: Path) -> None:
    h = 0.01
    start = {
        "true_dtheta_y": 2e-3,
        "true_dv_z": 0.1,
        "gyro_bias_y": 36.0,  # deg/h
        "gyro_sf_y": 500.0,  # ppm
        "accel_bias_z": 1000.0,  # ug
        "gyro_arw": 0.1,
        "noise_on": False,  # the white noise is switched off: deterministic
        "serial_number": "SN-0042",
    }
    result = simulate_fmu(
        str(vendor_imu_fmu),
        stop_time=0.5,
        output_interval=h,
        start_values=start,
        output=["gyro_angle_y", "gyro_rate_y", "accel_dv_z", "accel_f_z"],
    )
    assert len(result) == 51
    angle = (2e-3 + 500e-6 * 2e-3 + 36.0 * DEG / 3600.0 * h) / DEG
    dv = 0.1 + 1000e-6 * G0 * h
    assert result["gyro_angle_y"][0] == 0.0  # no increment at the start time
    np.testing.assert_allclose(result["gyro_angle_y"][1:], angle, rtol=1e-14)
    np.testing.assert_allclose(result["gyro_rate_y"][1:], angle / h, rtol=1e-14)
    np.testing.assert_allclose(result["accel_dv_z"][1:], dv, rtol=1e-14)
    np.testing.assert_allclose(result["accel_f_z"][1:], dv / h / G0, rtol=1e-14)


def test_check_fmu_suggests_the_rename_map(vendor_imu_fmu: Path) -> None:
    report = check_fmu(vendor_imu_fmu, "imu")
    assert report.satisfied, report.problems
    assert report.match.rename == RENAME
    factors = {e.role_name: e.factor for e in report.match.entries if e.fmu is not None}
    assert factors["dtheta_meas_b[2]"] == pytest.approx(DEG, rel=1e-15)
    assert factors["omega_meas_b[3]"] == pytest.approx(DEG, rel=1e-15)  # degps
    assert factors["f_meas_b[1]"] == G0
    assert report.capabilities["reset"] == (True, "fmi2Reset exported")
    assert report.capabilities["get/set state"][0] is False
    assert report.capabilities["variable step"][0] is True
    assert report.display_units["gyro_rate_x"] == "deg/h"


def test_check_fmu_reports_what_is_wrong(wrong_fmu: Path, cli, tmp_path: Path) -> None:
    # a schema-valid FMU: only the role check finds the problems
    assert validate_fmu(str(wrong_fmu)) == []
    expected = [
        "  - dtheta_b[2] <- 'true_dtheta_y': causality is 'parameter', expected 'input'",
        "  - dtheta_meas_b[3] <- 'gyro_angle_z': unit 'm/s' cannot be converted to 'rad' "
        "(dimensions m s^-1 and rad)",
        "  - dv_meas_b[3]: missing (required output, m/s): the FMU has no variable for it",
    ]
    res = cli("check-fmu", wrong_fmu, "--role", "imu", "--block", "imu")
    assert res.code == 1, res.out + res.err
    assert "result: 'VendorImuWrong.fmu' does not fill role 'imu': 3 problem(s)" in res.out
    assert res.out.rstrip().splitlines()[-3:] == expected
    # the same problems through a rename map written by hand (the missing one removed)
    rename = tmp_path / "rename.toml"
    rename.write_text(rename_table("imu").replace('"accel_dv_z" = "dv_meas_b[3]"\n', ""))
    res = cli("check-fmu", wrong_fmu, "--role", "imu", "--rename", rename)
    assert res.code == 1 and res.out.rstrip().splitlines()[-3:] == expected
    assert "[renamed]" in res.out and "[suggested]" not in res.out


SIDE_BY_SIDE = """
connections = [
  "motion.x -> ours.dtheta_b[1]", "motion.x -> ours.dtheta_b[3]",
  "motion.x -> vendor.dtheta_b[1]", "motion.x -> vendor.dtheta_b[3]",
]

[master]
step = "10 ms"
stop = "{stop}"

[blocks.motion]
model = "GaussMarkov2"
parameters = {{ tau = "2 s", sigma = "{sigma}", seed = 5 }}

[blocks.ours]
model = "StrapdownImu"
parameters = {{ {ours} }}
unconnected_ok = ["dtheta_b", "dv_b"]   # only dtheta_b[1], [3] are driven

[blocks.vendor]
fmu = "{fmu}"
parameters = {{ {vendor} }}
unconnected_ok = ["dtheta_b", "dv_b"]   # only dtheta_b[1], [3] are driven

{rename}
"""

INPUTS = '"dtheta_b[2]" = "0.1 deg", dv_b = [0.01, -0.02, 0.0980665]'


def side_by_side(tmp_path: Path, fmu: Path, stop: str, sigma: str, ours: str, vendor: str):
    path = tmp_path / "side_by_side.toml"
    text = SIDE_BY_SIDE.format(
        stop=stop, sigma=sigma, ours=ours, vendor=vendor, fmu=fmu, rename=rename_table("vendor")
    )
    path.write_text(text)
    return path


def test_swap_in_reproduces_the_deterministic_errors_exactly(
    tmp_path: Path, vendor_imu_fmu: Path
) -> None:
    errors = {
        "gyro_bias": ["1 deg/h", "-2 deg/h", "0.5 deg/h"],
        "gyro_sf": ["100 ppm", "-50 ppm", "20 ppm"],
        "accel_bias": ["100 ug", "-200 ug", "50 ug"],
        "accel_sf": ["30 ppm", "0 ppm", "-70 ppm"],
    }
    ours = ", ".join(f"{k} = {v!r}".replace("'", '"') for k, v in errors.items())
    vendor = ", ".join(
        f'{k}_{a} = "{v[i]}"' for k, v in errors.items() for i, a in enumerate("xyz")
    )
    # the vendor's noise is set but switched off (Boolean parameter noise_on)
    vendor += ', gyro_arw = "0.05 deg/sqrt(h)", accel_vrw = "30 ug/sqrt(Hz)", noise_on = false'
    path = side_by_side(
        tmp_path, vendor_imu_fmu, "2 s", "0.5 deg", f"{ours}, {INPUTS}", f"{vendor}, {INPUTS}"
    )
    result = cosim.run(path)
    units = result.metadata["units"]
    assert units["vendor.dtheta_meas_b[1]"] == "deg" and units["vendor.f_meas_b[1]"] == "g"
    assert result.metadata["blocks"]["vendor"]["rename"] == RENAME
    to_si = {"dtheta_meas_b": DEG, "omega_meas_b": DEG, "dv_meas_b": 1.0, "f_meas_b": G0}
    for name, factor in to_si.items():
        mine, theirs = result[f"ours.{name}"], result[f"vendor.{name}"] * factor
        assert np.all(np.abs(mine[1:]) > 0)
        np.testing.assert_allclose(theirs, mine, rtol=1e-13, atol=0, err_msg=name)


def test_noise_statistics_match_strapdown_imu(tmp_path: Path, vendor_imu_fmu: Path) -> None:
    arw, vrw = "0.05 deg/sqrt(h)", "30 ug/sqrt(Hz)"
    path = side_by_side(
        tmp_path,
        vendor_imu_fmu,
        "20 s",
        "1e-9 arcsec",  # no motion to speak of: the outputs are the noise
        f'gyro_arw = "{arw}", accel_vrw = "{vrw}", seed = 1',
        f'gyro_arw = "{arw}", accel_vrw = "{vrw}", seed = 2',
    )
    result = cosim.run(path)
    h = 0.01
    expected = {"dtheta_meas_b": 0.05 * DEG / 60 * h**0.5, "dv_meas_b": 30e-6 * G0 * h**0.5}
    factor = {"dtheta_meas_b": DEG, "dv_meas_b": 1.0}
    for name, sigma in expected.items():
        mine = result[f"ours.{name}"][1:]
        theirs = result[f"vendor.{name}"][1:] * factor[name]
        n = theirs.size  # 6000 samples: the std is known to about 1 %
        for sample in (mine, theirs):
            assert abs(sample.std() / sigma - 1.0) < 0.05, name
            assert abs(sample.mean()) < 5 * sigma / math.sqrt(n), name
        assert abs(theirs.std() / mine.std() - 1.0) < 0.07, name


def test_seed_reset_and_variable_steps(tmp_path: Path, vendor_imu_fmu: Path) -> None:
    path = side_by_side(
        tmp_path,
        vendor_imu_fmu,
        "0.5 s",
        "1 deg",
        "",
        'gyro_arw = "0.05 deg/sqrt(h)", accel_vrw = "30 ug/sqrt(Hz)", seed = 9',
    )
    sc = cosim.load_scenario(path)
    master = build_master(sc)
    system = master.system
    try:
        first = master.run()
        master.reset()  # fmi2Reset: the generator restarts from the seed
        again = master.run()
        master.reset()
        system.parameters["vendor"]["seed"] = 10
        other = master.run()
    finally:
        master.terminate()
    key = "vendor.dtheta_meas_b[2]"
    np.testing.assert_array_equal(first[key], again[key])
    assert np.all(first[key][1:] != other[key][1:])


def test_swapped_scenario_checks_and_a_rename_typo_is_one_line(
    tmp_path: Path, vendor_imu_fmu: Path, cli
) -> None:
    path = side_by_side(tmp_path, vendor_imu_fmu, "1 s", "1 deg", "", "")
    res = cli("check", path)
    assert res.code == 0, res.err
    assert "motion -> ours -> vendor" in res.out
    path.write_text(path.read_text().replace('"gyro_angle_x"', '"gyro_angel_x"'))
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err
    assert "key 'blocks.vendor.rename'" in res.err
    assert "expected a variable of the FMU, got 'gyro_angel_x'. Closest names: gyro_angle_x" in (
        res.err
    )
