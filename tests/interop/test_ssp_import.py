"""SSP import (cosim/interop/ssp_import.py) on archives ins-cosim did not write.

The archive is written here by hand, in the shape of the SSP 1.0 standard's examples
(ssd:Units, a DefaultExperiment with the OSP fixed-step annotation libcosim reads,
connectors with their units, a parameter set in an .ssv file of the archive and others
inline, a linear transformation, a connection with unit conversion suppressed), around
C FMUs compiled in the test run (tests/fixtures: Decay, Echo, RateImu) and our ShipMotion
FMU. What it must give is established independently:

- the ship and the IMU against the same system written as a TOML scenario by hand (the
  parameters converted by hand: 45 deg, 0.2 min, 1e-5 rad/s), run by ins-cosim's usual
  path: equal bit for bit;
- the linear transformation against its definition: ``echo.y_real = p_real + 2.5 x``
  with x one macro step late (Jacobi, the archive states no coupling);
- the factors of the connections the master runs: a unit conversion rad/s -> deg/s, and
  with ``suppressUnitConversion`` only the transformation's factor.

What cannot be imported is one line naming the archive, the file inside it and the
element. Round trip: an archive ins-cosim wrote runs, through ``ins-cosim run x.ssp``, to
the same results as the scenario it came from (tests/acceptance/test_three_masters.py does the same
for the transfer-alignment scenario against libcosim and fmpy).
"""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.interop.cbuild import build_c_fmu
from cosim.interop.ssp import export_ssp
from cosim.interop.ssp_import import SspImportError, load_ssp
from cosim.models.constants import DEG, DEG_PER_HOUR, G0
from cosim.scenario import build_master

pytestmark = pytest.mark.filterwarnings("ignore::cosim.wiring.UnconnectedInputWarning")
ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"

SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="DeckSensors"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"
    generationTool="written by hand (test)">
  <ssd:System name="Deck" description="a ship, a rate IMU and an echo chain">
    <ssd:ParameterBindings>
      <ssd:ParameterBinding>
        <ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="system-level">
            <ssv:Parameters>
              <ssv:Parameter name="decay.x0"><ssv:Real value="1.0"/></ssv:Parameter>
            </ssv:Parameters>
          </ssv:ParameterSet>
        </ssd:ParameterValues>
      </ssd:ParameterBinding>
      <ssd:ParameterBinding prefix="echo.">
        <ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="echo-own">
            <ssv:Parameters>
              <ssv:Parameter name="p_real"><ssv:Real value="1.5"/></ssv:Parameter>
              <ssv:Parameter name="u_enum"><ssv:Enumeration value="high"/></ssv:Parameter>
            </ssv:Parameters>
          </ssv:ParameterSet>
        </ssd:ParameterValues>
      </ssd:ParameterBinding>
    </ssd:ParameterBindings>
    <ssd:Elements>
      <ssd:Component name="ship" type="application/x-fmu-sharedlibrary"
          source="resources/ShipMotion.fmu" implementation="CoSimulation">
        <ssd:Connectors>
          <ssd:Connector name="omega_ib_b[1]" kind="output"><ssc:Real unit="rad/s"/></ssd:Connector>
          <ssd:Connector name="omega_ib_b[2]" kind="output"><ssc:Real unit="rad/s"/></ssd:Connector>
          <ssd:Connector name="omega_ib_b[3]" kind="output"><ssc:Real unit="rad/s"/></ssd:Connector>
          <ssd:Connector name="f_b[1]" kind="output"><ssc:Real unit="m/s2"/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="resources/ship.ssv"/>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="imu" source="resources/RateImu.fmu">
        <ssd:Connectors>
          <ssd:Connector name="AngRate_X" kind="input"><ssc:Real unit="deg/s"/></ssd:Connector>
          <ssd:Connector name="AngRate_Y" kind="input"><ssc:Real unit="deg/s"/></ssd:Connector>
          <ssd:Connector name="AngRate_Z" kind="input"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="SpecForce_X" kind="input"><ssc:Real unit="g"/></ssd:Connector>
          <ssd:Connector name="DeltaTheta_X" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="imu-datasheet">
                <ssv:Parameters>
                  <ssv:Parameter name="GyroBias_X">
                    <ssv:Real value="1e-5" unit="rad/s"/></ssv:Parameter>
                  <ssv:Parameter name="NoiseSeed"><ssv:Integer value="11"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="decay" source="resources/Decay.fmu">
        <ssd:Connectors>
          <ssd:Connector name="x" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="decay">
                <ssv:Parameters>
                  <ssv:Parameter name="k"><ssv:Real value="6" unit="1/min"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="echo" source="resources/Echo.fmu">
        <ssd:Connectors>
          <ssd:Connector name="u_real" kind="input"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="y_real" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="ship" startConnector="omega_ib_b[1]"
          endElement="imu" endConnector="AngRate_X"/>
      <ssd:Connection startElement="ship" startConnector="omega_ib_b[2]"
          endElement="imu" endConnector="AngRate_Y" suppressUnitConversion="true">
        <ssc:LinearTransformation factor="2.0" offset="0"/>
      </ssd:Connection>
      <ssd:Connection startElement="ship" startConnector="omega_ib_b[3]"
          endElement="imu" endConnector="AngRate_Z"/>
      <ssd:Connection startElement="ship" startConnector="f_b[1]"
          endElement="imu" endConnector="SpecForce_X"/>
      <ssd:Connection startElement="decay" startConnector="x"
          endElement="echo" endConnector="u_real">
        <ssc:LinearTransformation factor="2.5"/>
      </ssd:Connection>
    </ssd:Connections>
  </ssd:System>
  <ssd:Units>
    <ssc:Unit name="rad/s"><ssc:BaseUnit rad="1" s="-1"/></ssc:Unit>
    <ssc:Unit name="deg/s"><ssc:BaseUnit rad="1" s="-1" factor="0.017453292519943295"/></ssc:Unit>
    <ssc:Unit name="m/s2"><ssc:BaseUnit m="1" s="-2"/></ssc:Unit>
    <ssc:Unit name="g"><ssc:BaseUnit m="1" s="-2" factor="9.80665"/></ssc:Unit>
    <ssc:Unit name="deg"><ssc:BaseUnit rad="1" factor="0.017453292519943295"/></ssc:Unit>
  </ssd:Units>
  <ssd:DefaultExperiment startTime="0" stopTime="2">
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="0.1"/></osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""

SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="1.0" name="mooring"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssv:Parameters>
    <ssv:Parameter name="lat0"><ssv:Real value="45" unit="degree"/></ssv:Parameter>
    <ssv:Parameter name="amp[1]"><ssv:Real value="10" unit="deg"/></ssv:Parameter>
    <ssv:Parameter name="period[1]"><ssv:Real value="0.2" unit="min"/></ssv:Parameter>
  </ssv:Parameters>
  <ssv:Units>
    <ssc:Unit name="degree"><ssc:BaseUnit rad="1" factor="0.017453292519943295"/></ssc:Unit>
  </ssv:Units>
</ssv:ParameterSet>
"""

# The same system (without the suppressed-conversion link and the echo chain, which a
# TOML scenario cannot express) as ins-cosim's own scenario, parameters converted by hand.
TOML = """connections = ["ship.omega_ib_b[1] -> imu.AngRate_X",
  "ship.omega_ib_b[3] -> imu.AngRate_Z", "ship.f_b[1] -> imu.SpecForce_X"]
[master]
step = 0.1
stop = 2.0
coupling = "jacobi"
[blocks.ship]
fmu = "{ship}"
parameters = {{ lat0 = {lat0!r}, "amp[1]" = {amp!r}, "period[1]" = 12.0 }}
[blocks.imu]
fmu = "{imu}"
parameters = {{ GyroBias_X = "1e-5 rad/s", NoiseSeed = 11 }}
"""


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory, fmu_dir: Path) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("c_fmus")
    return {
        "ShipMotion.fmu": fmu_dir / "ShipMotion.fmu",
        "RateImu.fmu": build_c_fmu(FIXTURES / "rate_imu", out / "RateImu.fmu"),
        "Decay.fmu": build_c_fmu(FIXTURES / "decay2", out / "Decay.fmu"),
        "Echo.fmu": build_c_fmu(FIXTURES / "echo2", out / "Echo.fmu"),
    }


def write_archive(path: Path, fmus: dict[str, Path], ssd: str = SSD, ssv: str = SSV) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        zf.writestr("resources/ship.ssv", ssv)
        for name, fmu in fmus.items():
            zf.write(fmu, f"resources/{name}")
    return path


@pytest.fixture(scope="module")
def third_party(tmp_path_factory: pytest.TempPathFactory, fmus) -> Path:
    return write_archive(tmp_path_factory.mktemp("ssp") / "DeckSensors.ssp", fmus)


def test_a_hand_written_archive_reads_as_its_parts(third_party: Path) -> None:
    sc = load_ssp(third_party)
    assert list(sc.blocks) == ["ship", "imu", "decay", "echo"]
    assert sc.settings.step == 0.1 and sc.settings.stop == 2.0
    assert sc.settings.coupling == "jacobi"  # the archive does not say: SSP masters' rule
    ship = sc.blocks["ship"].parameters
    assert ship["lat0"] == 45 * DEG  # ssv:Units of the .ssv
    assert ship["amp[1]"] == 10 * DEG  # ssd:Units
    assert ship["period[1]"] == pytest.approx(12.0, rel=1e-15)  # 'min' parsed by name
    decay = sc.blocks["decay"].parameters
    assert decay["k"] == pytest.approx(0.1, rel=1e-15) and decay["x0"] == 1.0  # system level
    # system level with prefix="echo.": the set's bare names bind to the echo component
    assert sc.blocks["echo"].parameters == {"p_real": 1.5, "u_enum": "high"}
    imu = sc.blocks["imu"].parameters
    assert imu["GyroBias_X"] == pytest.approx(1e-5 / DEG_PER_HOUR, rel=1e-15)  # rad/s -> deg/h
    assert imu["NoiseSeed"] == 11


def test_the_connections_carry_the_ssp_factors(third_party: Path) -> None:
    master = build_master(load_ssp(third_party))
    try:
        factors = {str(c): c.factor for c in master.system.connections}
    finally:
        master.terminate()
    assert factors["ship.omega_ib_b[1] -> imu.AngRate_X"] == pytest.approx(1 / DEG, rel=1e-15)
    assert factors["ship.omega_ib_b[2] -> imu.AngRate_Y"] == 2.0  # suppressed: only the factor
    assert factors["ship.f_b[1] -> imu.SpecForce_X"] == pytest.approx(1 / G0, rel=1e-15)
    assert factors["decay.x -> echo.u_real"] == 2.5


def test_the_archive_runs_as_the_same_system_written_in_toml(
    third_party: Path, fmus, tmp_path: Path
) -> None:
    ours = cosim.run(load_ssp(third_party))
    toml = tmp_path / "deck.toml"
    toml.write_text(
        TOML.format(
            ship=fmus["ShipMotion.fmu"], imu=fmus["RateImu.fmu"], lat0=45 * DEG, amp=10 * DEG
        )
    )
    reference = cosim.run(toml)
    assert len(ours.data) == len(reference.data) == 21
    for name in ("ship.omega_ib_b[1]", "ship.f_b[1]", "imu.DeltaTheta_X", "imu.DeltaTheta_Z"):
        assert ours[name].tolist() == reference[name].tolist(), name  # bit for bit
    assert np.ptp(ours["imu.DeltaTheta_X"]) > 1e-3
    # y = p_real + u_real with u_real = 2.5 x one step late (Jacobi), x(0) its start value
    x, y = ours["decay.x"], ours["echo.y_real"]
    assert y[1:].tolist() == (1.5 + x[:-1] * 2.5).tolist()
    assert x[-1] == pytest.approx(math.exp(-0.1 * 2.0), rel=1e-6)
    assert ours["echo.y_enum"].tolist() == [3.0] * 21  # the item 'high' by name


def bad(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


CASES = [
    (
        "mapping transformation on a connection",
        bad(
            SSD,
            '<ssc:LinearTransformation factor="2.5"/>',
            '<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="2"/>'
            "</ssc:IntegerMappingTransformation>",
        ),
        SSV,
        "key 'Connection decay.x -> echo.u_real/IntegerMappingTransformation': "
        "IntegerMappingTransformation on a connection is not supported",
    ),
    (
        "unknown parameter",
        SSD,
        bad(SSV, 'name="lat0"', 'name="latitude"'),
        "!resources/ship.ssv, key 'Parameter 'latitude' (Component 'ship'/ParameterBinding[1])':"
        " Component 'ship' has no variable 'latitude'",
    ),
    (
        "unknown unit",
        SSD,
        bad(SSV, 'unit="min"', 'unit="fortnightz"'),
        "!resources/ship.ssv, key 'Parameter 'period[1]' (Component 'ship'/ParameterBinding[1])'"
        ": unknown unit 'fortnightz'",
    ),
    (
        "missing resource",
        bad(SSD, "resources/ship.ssv", "resources/nowhere.ssv"),
        SSV,
        "'resources/nowhere.ssv' is not a file inside the archive",
    ),
    (
        "schema",
        bad(SSD, 'endElement="echo" endConnector="u_real"', 'endElement="echo"'),
        SSV,
        "does not validate against the SSP 1.0 schema SystemStructureDescription.xsd",
    ),
    (
        "connector unit",
        bad(SSD, '<ssc:Real unit="g"/>', '<ssc:Real unit="m/s2"/>'),
        SSV,
        "key 'Component 'imu'/Connector 'SpecForce_X'': the connector's unit 'm/s2' is not the "
        "FMU's unit 'g'",
    ),
    (
        "connector type",
        bad(
            SSD,
            '<ssd:Connector name="x" kind="output"><ssc:Real/>',
            '<ssd:Connector name="x" kind="output"><ssc:Integer/>',
        ),
        SSV,
        "key 'Component 'decay'/Connector 'x'': the connector is declared ssc:Integer but the "
        "FMU's variable is Real; declare the FMU's type",
    ),
    (
        "type mismatch",
        bad(
            SSD,
            'startElement="decay" startConnector="x"\n          endElement="echo" '
            'endConnector="u_real"',
            'startElement="decay" startConnector="x" endElement="echo" endConnector="u_int"',
        ),
        SSV,
        "key 'Connection decay.x -> echo.u_int': a Real output (decay.x) to an Integer input "
        "(echo.u_int): FMI connects variables of one type",
    ),
    (
        "transformation on an integer link",
        bad(
            SSD,
            'startElement="decay" startConnector="x"\n          endElement="echo" '
            'endConnector="u_real"',
            'startElement="decay" startConnector="n_int" endElement="echo" endConnector="u_int"',
        ),
        SSV,
        "key 'Connection decay.n_int -> echo.u_int/LinearTransformation': a linear "
        "transformation on an Integer link",
    ),
    (
        "system connector",
        bad(SSD, 'startElement="decay" startConnector="x"', 'startConnector="x"'),
        SSV,
        "key 'Connection (system).x -> echo.u_real': the top-level system's connector has no "
        "source outside the archive",
    ),
    (
        "version",
        bad(SSD, 'version="1.0" name="DeckSensors"', 'version="3.0" name="DeckSensors"'),
        SSV,
        "SSP version '3.0'; ins-cosim imports SSP 1.0 and 2.0",
    ),
]


@pytest.mark.parametrize(("case", "ssd", "ssv", "message"), CASES, ids=[c[0] for c in CASES])
def test_what_cannot_be_imported_is_one_line_naming_file_and_element(
    fmus, tmp_path: Path, case: str, ssd: str, ssv: str, message: str
) -> None:
    path = write_archive(tmp_path / "bad.ssp", fmus, ssd, ssv)
    with pytest.raises(SspImportError) as info:
        load_ssp(path)
    text = str(info.value)
    assert "\n" not in text and text.startswith(f"{path}!"), text
    assert message in text, text


def test_check_and_run_take_an_ssp_archive(cli, third_party: Path, tmp_path: Path) -> None:
    res = cli("check", third_party)
    assert res.code == 0, res.err
    assert "OK - 4 blocks, 5 scalar connections, 20 steps" in res.out
    broken = tmp_path / "broken.ssp"
    broken.write_bytes(b"not a zip")
    res = cli("check", broken)
    assert res.code == 3 and "Traceback" not in res.err
    assert "not an SSP archive" in res.err


def test_round_trip_through_ins_cosim_run(cli, fmu_dir: Path, tmp_path: Path) -> None:
    demo = ROOT / "scenarios" / "demo.toml"
    export = export_ssp(demo, tmp_path / "demo.ssp", fmu_dir)
    res = cli("run", export.path, "--out", tmp_path / "out", "--stop", "2 s", "--no-plot")
    assert res.code == 0, res.err
    sc = cosim.load_scenario(demo)
    sc.use_fmus(fmu_dir)
    sc.settings = sc.master_settings(stop=2.0)
    original = cosim.run(sc)
    imported = np.genfromtxt(tmp_path / "out" / "results.csv", delimiter=",", names=True)
    assert len(imported) == len(original.data) == 201
    for name in original.names[1:]:
        column = name.replace(".", "")  # genfromtxt drops the dots of the header
        diff = float(np.max(np.abs(imported[column] - original[name])))
        assert diff <= 1e-12, f"{name}: {diff}"
    meta = json.loads((tmp_path / "out" / "results.json").read_text())
    assert meta["scenario"]["file"].endswith("demo.ssp")
    assert meta["master"]["coupling"] == "gauss-seidel"  # the scenario's, from the archive
    assert meta["ssp"]["components"] == {
        "flexure": "resources/GaussMarkov2.fmu",
        "sensor": "resources/FirstOrderSensor.fmu",
    }
