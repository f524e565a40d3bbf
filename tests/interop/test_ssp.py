"""SSP export (cosim/interop/ssp.py) and its run in libcosim (run_libcosim_ssp).

The archive must validate against the SSP 1.0 schemas (fmpy ships them) and, run by
libcosim's own SSP loader, reproduce our master with Jacobi coupling to 1e-12.
"""

from __future__ import annotations

import hashlib
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.ssp.ssd import read_ssd

import cosim
from cosim.interop.libcosim_exec import LibcosimError
from cosim.interop.libcosim_runner import run_libcosim_ssp
from cosim.interop.ssp import SspError, export_ssp

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "scenarios" / "demo.toml"


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def run_ours_jacobi(scenario: Path, fmu_dir: Path, stop: float) -> cosim.RunResult:
    sc = cosim.load_scenario(scenario)
    sc.use_fmus(fmu_dir)
    sc.settings = sc.master_settings(coupling="jacobi")
    sc.settings = sc.master_settings(stop=stop)
    return cosim.run(sc)


@pytest.fixture(scope="module")
def demo_ssp(tmp_path_factory: pytest.TempPathFactory, fmu_dir: Path):
    return export_ssp(DEMO, tmp_path_factory.mktemp("ssp") / "demo.ssp", fmu_dir)


def test_export_writes_a_valid_ssp_archive(demo_ssp, fmu_dir: Path) -> None:
    path = demo_ssp.path
    with zipfile.ZipFile(path) as zf:
        names = sorted(zf.namelist())
        assert names == [
            "SystemStructure.ssd",
            "resources/FirstOrderSensor.fmu",
            "resources/GaussMarkov2.fmu",
        ]
        for name in names[1:]:  # the FMUs themselves, unchanged
            assert sha256(zf.read(name)) == sha256((fmu_dir / Path(name).name).read_bytes())
        text = zf.read("SystemStructure.ssd").decode()
    assert 'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"' in text
    ssd = read_ssd(str(path))  # validates against SystemStructureDescription.xsd (SSP 1.0)
    assert [c.name for c in ssd.system.elements] == ["flexure", "sensor"]
    assert ssd.system.elements[0].source == "resources/GaussMarkov2.fmu"
    link = ssd.system.connections[0]
    assert (link.startElement, link.startConnector, link.endElement, link.endConnector) == (
        "flexure",
        "x",
        "sensor",
        "u",
    )
    # parameter values: exactly the resolved scenario values (units applied, repr digits)
    system, _ = cosim.load_scenario(DEMO).build()
    for host in system.blocks.values():
        host.terminate()
    values = {}
    for element in ssd.system.elements:
        for binding in element.parameterBindings:
            for parameter_set in binding.parameterValues:
                for p in parameter_set.parameters:
                    values[(element.name, p.name)] = p.value
    expected = {(b, n): v for b, ps in system.parameters.items() for n, v in ps.items()}
    assert {k: float(v) for k, v in values.items()} == {k: float(v) for k, v in expected.items()}
    assert float(values[("flexure", "sigma")]) == pytest.approx(2 * math.pi / 180 / 60, rel=1e-15)
    assert demo_ssp.connections == 1 and demo_ssp.parameters == 7


def test_exported_demo_in_libcosim_equals_our_jacobi_master(demo_ssp, fmu_dir: Path) -> None:
    mine = run_ours_jacobi(DEMO, fmu_dir, stop=5.0)
    observe = [tuple(name.split(".", 1)) for name in mine.names[1:]]
    theirs = run_libcosim_ssp(demo_ssp.path, step=0.01, stop=5.0, observe=observe)
    assert len(theirs) == len(mine.data) == 501
    np.testing.assert_allclose(theirs["time"], mine.time, rtol=0, atol=1e-12)
    for name in mine.names[1:]:
        diff = np.max(np.abs(theirs[name] - mine.data[name]))
        assert diff <= 1e-12, f"{name}: {diff}"
    # the comparison can fail: Gauss-Seidel (the demo's own coupling) differs
    gs = cosim.load_scenario(DEMO)
    gs.settings = gs.master_settings(stop=5.0)
    assert np.max(np.abs(cosim.run(gs)["sensor.y"] - theirs["sensor.y"])) > 1e-9


VENDOR_CHAIN = """
connections = ["flexure.x -> imu.dtheta_b[1]", "imu.dtheta_meas_b[1] -> sensor.u"]

[master]
step = "10 ms"
stop = "2 s"
coupling = "jacobi"

[blocks.flexure]
model = "GaussMarkov2"
parameters = {{ tau = "60 s", sigma = "2 arcmin", seed = 7 }}

[blocks.imu]
fmu = "{fmu}"
parameters = {{ gyro_bias_x = "1 deg/h", gyro_sf_x = "100 ppm", gyro_arw = 0.01, seed = 3 }}
rename = {{ "true_dtheta_x" = "dtheta_b[1]", "gyro_angle_x" = "dtheta_meas_b[1]" }}

[blocks.sensor]
model = "FirstOrderSensor"
parameters = {{ time_constant = "50 ms", seed = 11 }}
"""


def test_vendor_fmu_with_rename_and_unit_conversion_in_libcosim(
    tmp_path: Path, fmu_dir: Path, vendor_imu_fmu: Path
) -> None:
    scenario = tmp_path / "chain.toml"
    scenario.write_text(VENDOR_CHAIN.format(fmu=vendor_imu_fmu))
    export = export_ssp(scenario, tmp_path / "chain.ssp", fmu_dir)
    assert export.fmu_names["imu"]["dtheta_meas_b[1]"] == "gyro_angle_x"
    with zipfile.ZipFile(export.path) as zf:
        ssd = zf.read("SystemStructure.ssd").decode()
    # deg -> rad on the way to the sensor, and SSP tools told not to convert again
    assert 'suppressUnitConversion="true"' in ssd
    assert f'<ssc:LinearTransformation factor="{math.pi / 180!r}" offset="0"' in ssd
    assert '<ssv:Parameter name="gyro_bias_x">' in ssd  # the FMU's own names
    mine = run_ours_jacobi(scenario, fmu_dir, stop=2.0)
    names = {"imu.dtheta_meas_b[1]": ("imu", "gyro_angle_x")}
    observe = [names.get(n, tuple(n.split(".", 1))) for n in mine.names[1:]]
    observed = [f"{b}.{v}" for b, v in observe]
    theirs = run_libcosim_ssp(export.path, step=0.01, stop=2.0, observe=observe)
    assert np.max(np.abs(mine["sensor.y"])) > 1e-5
    for ours, their in zip(mine.names[1:], observed, strict=True):
        diff = np.max(np.abs(theirs[their] - mine.data[ours]))
        assert diff <= 1e-12, f"{ours}: {diff}"


def test_libcosim_refuses_an_ignored_parameter(demo_ssp, tmp_path: Path) -> None:
    bad = tmp_path / "bad.ssp"
    with zipfile.ZipFile(demo_ssp.path) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "SystemStructure.ssd":
                data = data.replace(b'name="tau"', b'name="tau_typo"')
            dst.writestr(item, data)
    with pytest.raises(LibcosimError, match="ignored parameter value.*tau_typo"):
        run_libcosim_ssp(bad, step=0.01, stop=0.1, observe=[("flexure", "x")])


def test_export_needs_the_built_fmus(cli, tmp_path: Path, fmu_dir: Path) -> None:
    res = cli("export-ssp", DEMO, tmp_path / "x.ssp", "--fmu-dir", tmp_path / "nowhere")
    assert res.code == 3 and "Traceback" not in res.err
    assert "block 'flexure' uses the built-in model 'GaussMarkov2'" in res.err
    assert "run `make fmus`" in res.err and not (tmp_path / "x.ssp").exists()
    res = cli("export-ssp", DEMO, tmp_path / "demo.ssp", "--fmu-dir", fmu_dir)
    assert res.code == 0, res.err
    assert "2 components, 1 scalar connections, 7 parameter values" in res.out
    assert zipfile.is_zipfile(tmp_path / "demo.ssp")


def test_python_class_blocks_cannot_be_exported(tmp_path: Path, fmu_dir: Path) -> None:
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        '[master]\nstep = "10 ms"\nstop = "1 s"\n[blocks.bad]\nclass = "testblocks:Faulty"\n'
    )
    with pytest.raises(SspError, match=r"block\(s\) bad \(testblocks:Faulty\) run in Python"):
        export_ssp(scenario, tmp_path / "s.ssp", fmu_dir)


TRANSFER = Path(__file__).resolve().parents[2] / "scenarios" / "transfer_alignment.toml"


def test_a_filter_block_is_named_and_excluded_with_its_cut_connections(
    cli, tmp_path: Path, fmu_dir: Path
) -> None:
    res = cli("export-ssp", TRANSFER, tmp_path / "t.ssp", "--fmu-dir", fmu_dir)
    assert res.code == 3 and "Traceback" not in res.err
    assert "align (TransferAlignment) run in Python and have no FMU" in res.err
    assert "--exclude align" in res.err and "make fmus" not in res.err
    export = export_ssp(TRANSFER, tmp_path / "t.ssp", fmu_dir, exclude=["align"])
    assert set(export.components) == {"ship", "flex", "lever", "imu", "master"}
    assert export.cut[0] == "imu.dtheta_meas_b -> align.dtheta_s" and len(export.cut) == 8
    ssd = read_ssd(str(tmp_path / "t.ssp"))  # validates against the SSP 1.0 schemas
    assert {u.name for u in ssd.units} >= {"rad", "m/s", "rad/s"}
    with zipfile.ZipFile(tmp_path / "t.ssp") as zf:
        text = zf.read("SystemStructure.ssd").decode()
    flat = "".join(line.strip() for line in text.splitlines())
    assert '<ssc:Unit name="m/s2"><ssc:BaseUnit m="1" s="-2" /></ssc:Unit>' in flat
    assert '<ssd:Connector name="f_s[1]" kind="output"><ssc:Real unit="m/s2" />' in flat
    res = cli(
        "export-ssp", TRANSFER, tmp_path / "t2.ssp", "--fmu-dir", fmu_dir, "--exclude", "align"
    )
    assert res.code == 0, res.err
    assert "left out: block align (8 connection(s) cut" in res.out
