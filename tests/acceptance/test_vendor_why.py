"""Issue 16, acceptance 3: the bullets of "Why", one test each (no traceback, nothing lost)."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest

from cosim.errors import FmuError
from cosim.interop.cbuild import build_c_fmu
from cosim.interop.fmu_check import check_fmu, format_report

ROOT = Path(__file__).resolve().parents[2]
RATE_IMU = ROOT / "tests" / "fixtures" / "rate_imu"
RAMP = ROOT / "tests" / "fixtures" / "fmi3_ramp"


def test_fmus_lists_every_fmu_past_an_unreadable_one(cli, fmu_dir: Path, tmp_path) -> None:
    (tmp_path / "Broken.fmu").write_text("not a zip archive")
    (tmp_path / "GaussMarkov2.fmu").write_bytes((fmu_dir / "GaussMarkov2.fmu").read_bytes())
    res = cli("fmus", "--dir", tmp_path)
    assert res.code == 1 and "Traceback" not in res.err
    assert re.search(r"^Broken\.fmu\s+unreadable: File is not a zip file", res.out, re.M)
    assert re.search(r"^GaussMarkov2\.fmu\s+2\.0", res.out, re.M)
    # our FMUs say what the host needs
    assert "needs numpy and scipy (pip install numpy scipy)" in res.out
    assert "pythonfmu's runtime is inside each FMU" in res.out


def test_an_fmu_without_a_binary_for_this_machine_does_not_fill_the_role(tmp_path) -> None:
    fmu = build_c_fmu(RATE_IMU, tmp_path / "RateImu.fmu")
    other = tmp_path / "RateImuMac.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(other, "w") as dst:
        for item in src.infolist():
            name = item.filename.replace("binaries/linux64/", "binaries/darwin64/")
            dst.writestr(name.replace(".so", ".dylib"), src.read(item))
    report = check_fmu(other, "imu")
    assert not report.satisfied
    assert "no binary for this machine (linux64) and no C sources" in format_report(report)


def test_a_unit_whose_name_and_definition_disagree_is_flagged(tmp_path) -> None:
    xml = (RATE_IMU / "modelDescription.xml").read_text()
    xml = xml.replace(
        '<Unit name="deg/sqrt(h)"/>',
        '<Unit name="deg/sqrt(h)"><BaseUnit rad="1" s="-1" factor="2.9e-4"/></Unit>',
    )
    fmu = build_c_fmu(RATE_IMU, tmp_path / "RateImu.fmu", model_description=xml)
    text = format_report(check_fmu(fmu, "imu"))
    assert "WARNING unit 'deg/sqrt(h)': its name reads 0.0002908882087 rad s^-0.5" in text
    assert "BaseUnit defines 0.00029 rad s^-1; the definition is used" in text


def test_a_scheduled_execution_fmu_is_named_as_such(tmp_path) -> None:
    xml = (RAMP / "modelDescription.xml").read_text()
    xml = re.sub(r"<CoSimulation[^>]*/>", '<ScheduledExecution modelIdentifier="ramp"/>', xml)
    fmu = build_c_fmu(RAMP, tmp_path / "Ramp.fmu", model_description=xml)
    report = check_fmu(fmu, "imu")
    assert "implements scheduled execution only" in " ".join(report.problems)
    from cosim.blocks import FmuHost

    with pytest.raises(FmuError, match="implements only Scheduled Execution"):
        FmuHost("ramp", fmu)


def test_deleting_the_imu_input_connections_is_refused(cli, tmp_path) -> None:
    text = (ROOT / "scenarios" / "transfer_alignment.toml").read_text()
    text = text.replace('  "lever.dtheta_s -> imu.dtheta_b",\n', "").replace(
        '  "lever.dv_s -> imu.dv_b",\n', ""
    )
    path = tmp_path / "noinputs.toml"
    path.write_text(text)
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err
    assert "block 'imu' fills role 'imu', but its required input(s) dtheta_b[1]" in res.err
    assert "warning: " in res.err and "dtheta_b[1] = 0.0" in res.err
