"""Units declared by FMUs (UnitDefinitions, BaseUnit, displayUnit) and their conversion.

The unit-level tests build :class:`cosim.units.Unit` objects the way an FMU's model
description defines them; the scenario-level tests load the C vendor IMU (compiled
during the session), whose outputs are in deg, a custom "degps" and g, and whose
parameters are in deg/h, ppm, ug and two units given by name only.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import read_model_description

from cosim.errors import ScenarioError, UnitError
from cosim.models.constants import DEG
from cosim.scenario import load_scenario
from cosim.units import conversion_factor, parse_unit, to_unit, unit_from_fmi
from cosim.variables import fmu_variables

DEG_S = unit_from_fmi("deg/s", {"rad": 1, "s": -1}, factor=DEG)
DEGPS = unit_from_fmi("degps", {"rad": 1, "s": -1}, factor=DEG)
G = unit_from_fmi("g", {"m": 1, "s": -2}, factor=9.80665)
DEG_H = unit_from_fmi("deg/h", {"rad": 1, "s": -1}, factor=DEG / 3600.0)


@pytest.mark.parametrize(
    "unit, target, factor",
    [
        (DEG_S, "rad/s", DEG),
        (DEGPS, "rad/s", DEG),  # a custom name: only the definition gives it meaning
        (G, "m/s2", 9.80665),
        (DEG_H, "rad/s", DEG / 3600.0),
        (DEGPS, "deg/h", 3600.0),
        (unit_from_fmi("ppm", {}, factor=1e-6), "1", 1e-6),
    ],
)
def test_base_unit_definitions_convert(unit, target: str, factor: float) -> None:
    assert conversion_factor(unit, target) == pytest.approx(factor, rel=1e-15)
    assert conversion_factor(target, unit) == pytest.approx(1.0 / factor, rel=1e-15)


def test_the_definition_wins_over_the_name() -> None:
    # a unit *named* "deg/s" but defined as rad/s (factor 1): the definition is what the
    # FMU's values are in, so the name must not be parsed
    mislabelled = unit_from_fmi("deg/s", {"rad": 1, "s": -1}, factor=1.0)
    assert conversion_factor(mislabelled, "rad/s") == 1.0
    assert conversion_factor("deg/s", "rad/s") == pytest.approx(DEG, rel=1e-15)


def test_incompatible_definitions_are_refused_with_both_units() -> None:
    with pytest.raises(UnitError, match=r"'g' cannot be converted to 'rad/s'.*m s\^-2.*rad s\^-1"):
        conversion_factor(G, "rad/s")
    # the angle exponent counts: deg/s is not 1/s
    with pytest.raises(
        UnitError,
        match=r"'degps' \(BaseUnit: 0.01745329252 rad s\^-1\) cannot be converted to '1/s'",
    ):
        conversion_factor(DEGPS, "1/s")


def test_affine_units_convert_only_to_themselves() -> None:
    deg_c = unit_from_fmi("degC", {"K": 1}, factor=1.0, offset=273.15)
    assert conversion_factor(deg_c, deg_c) == 1.0
    with pytest.raises(UnitError, match="offset"):
        conversion_factor(deg_c, "K")
    # parsed names with an offset are recognised as affine as well
    assert parse_unit("degC").offset == pytest.approx(273.15)


def test_bad_definitions_are_refused() -> None:
    with pytest.raises(UnitError, match="expected BaseUnit exponents among.*got 'deg'"):
        unit_from_fmi("x", {"deg": 1})
    with pytest.raises(UnitError, match="expected a BaseUnit factor > 0, got 0"):
        unit_from_fmi("x", {"rad": 1}, factor=0.0)


def test_to_unit_converts_into_a_defined_unit() -> None:
    assert to_unit("0.5 deg/h", DEG_H) == pytest.approx(0.5, rel=1e-15)
    assert to_unit("1e-5 rad/s", DEG_H) == pytest.approx(1e-5 / (DEG / 3600), rel=1e-15)
    assert to_unit(["1 g", "0.5 g"], G) == pytest.approx([1.0, 0.5], rel=1e-15)
    assert to_unit(0.25, G) == 0.25  # a bare number is already in the variable's unit


def test_vendor_fmu_unit_definitions_are_read(vendor_imu_fmu: Path) -> None:
    md = read_model_description(str(vendor_imu_fmu))
    variables = fmu_variables(md)
    rate = variables["gyro_rate_x"]
    assert rate.unit == "degps" and md.modelVariables[26].displayUnit == "deg/h"
    assert rate.unit_def is not None and rate.unit_def.origin == "BaseUnit"
    # displayUnit deg/h (factor 3600) is presentation only: the value is in degps
    assert conversion_factor(rate.conversion_unit, "rad/s") == pytest.approx(DEG, rel=1e-15)
    assert conversion_factor(variables["accel_f_x"].conversion_unit, "m/s2") == 9.80665
    assert conversion_factor(variables["gyro_angle_x"].conversion_unit, "rad") == DEG
    # declared without BaseUnit (FMI exponents are integers): parsed by name
    assert variables["gyro_arw"].unit_def is None
    assert conversion_factor(variables["gyro_arw"].conversion_unit, "rad/sqrt(s)") == (
        pytest.approx(DEG / 60, rel=1e-15)
    )


SCENARIO = """
connections = [{links}]

[master]
step = "10 ms"
stop = "100 ms"

[blocks.imu]
fmu = "{fmu}"
parameters = {{ {params} }}
rename = {{ "gyro_rate_x" = "omega_meas_b[1]", "accel_f_x" = "f_meas_b[1]" }}

[blocks.gyro]
model = "HrgPlatformGyro"

[blocks.acc]
model = "PlatformAccelerometer"
"""


def scenario(tmp_path: Path, fmu: Path, links: str, params: str = "") -> Path:
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.format(fmu=fmu, links=links, params=params))
    return path


def test_connections_convert_vendor_units(tmp_path: Path, vendor_imu_fmu: Path) -> None:
    links = '"imu.omega_meas_b[1] -> gyro.omega_ip_p[1]", "imu.f_meas_b[1] -> acc.f_p[3]"'
    params = (
        'gyro_bias_x = "1e-5 rad/s", gyro_sf_y = "250 ppm", accel_bias_z = "0.002 m/s2", '
        'accel_vrw = "5e-5 m/s/sqrt(s)", gyro_arw = 0.02'
    )
    system, _ = load_scenario(scenario(tmp_path, vendor_imu_fmu, links, params)).build()
    try:
        factors = {(c.src_var, c.dst_var): c.factor for c in system.connections}
        assert factors[("omega_meas_b[1]", "omega_ip_p[1]")] == pytest.approx(DEG, rel=1e-15)
        assert factors[("f_meas_b[1]", "f_p[3]")] == pytest.approx(9.80665, rel=1e-15)
        p = system.parameters["imu"]
        assert p["gyro_bias_x"] == pytest.approx(1e-5 / (DEG / 3600), rel=1e-14)  # deg/h
        assert p["gyro_sf_y"] == pytest.approx(250.0, rel=1e-14)  # ppm
        assert p["accel_bias_z"] == pytest.approx(0.002 / 9.80665e-6, rel=1e-14)  # ug
        assert p["accel_vrw"] == pytest.approx(5e-5 / 9.80665e-6, rel=1e-14)  # by name
        assert p["gyro_arw"] == 0.02  # a bare number is in the FMU's unit
    finally:
        for host in system.blocks.values():
            host.terminate()


def test_incompatible_connection_names_variable_and_both_units(
    tmp_path: Path, vendor_imu_fmu: Path
) -> None:
    path = scenario(tmp_path, vendor_imu_fmu, '"imu.f_meas_b[1] -> gyro.omega_ip_p[2]"')
    with pytest.raises(ScenarioError) as err:
        load_scenario(path).build()
    msg = str(err.value)
    assert "key 'connections[0]'" in msg
    assert "'imu.f_meas_b[1]' (FMU variable 'accel_f_x') is in 'g'" in msg
    assert "'gyro.omega_ip_p[2]' expects 'rad/s'" in msg
    assert "dimensions m s^-2 and rad s^-1" in msg


def test_incompatible_parameter_names_variable_and_both_units(
    tmp_path: Path, vendor_imu_fmu: Path
) -> None:
    path = scenario(tmp_path, vendor_imu_fmu, "", 'gyro_bias_y = "3 m/s"')
    with pytest.raises(ScenarioError) as err:
        load_scenario(path).build()
    msg = str(err.value)
    assert "key 'blocks.imu.parameters.gyro_bias_y'" in msg
    assert "'m/s' cannot be converted to 'deg/h'" in msg and "'imu.gyro_bias_y'" in msg


def test_a_name_that_disagrees_with_its_definition_is_reported_with_both() -> None:
    from cosim.units import name_disagreement

    # a vendor's deg/sqrt(h) given integer exponents (rad/s) by mistake
    wrong = unit_from_fmi("deg/sqrt(h)", {"rad": 1, "s": -1}, 2.9e-4)
    note = name_disagreement(wrong)
    assert "its name reads 0.0002908882087 rad s^-0.5" in note
    assert "BaseUnit defines 0.00029 rad s^-1; the definition is used" in note
    assert "factor 0.00029 to SI" in note
    with pytest.raises(UnitError) as info:
        conversion_factor("0.5 deg/sqrt(h)".split()[1], wrong)
    message = info.value.message
    assert "cannot be converted to 'deg/sqrt(h)' (BaseUnit: 0.00029 rad s^-1)" in message
    assert "its name reads" in message
    # a name pint does not know, or one that agrees, is no disagreement
    assert (
        name_disagreement(unit_from_fmi("degps", {"rad": 1, "s": -1}, 0.017453292519943295)) == ""
    )
    assert (
        name_disagreement(unit_from_fmi("deg/s", {"rad": 1, "s": -1}, 0.017453292519943295)) == ""
    )
    # deg/h defined with the factor of deg/s: converts, with the definition's factor
    fast = unit_from_fmi("deg/h", {"rad": 1, "s": -1}, 0.017453292519943295)
    assert "its name reads 4.848136811e-06 rad s^-1" in name_disagreement(fast)
    assert conversion_factor(fast, "rad/s") == 0.017453292519943295
