"""FMI 3.0 co-simulation through FmuHost, with a C FMU compiled during the test run.

The fixture (tests/fixtures/fmi3_ramp) outputs ``y = time + y0`` [s] and ``v = k u``
[ms], with an ``ms`` unit defined by a BaseUnit, so one connection ``a.y -> b.u`` also
exercises FMI 3 unit definitions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy.validation import validate_fmu

import cosim
from cosim.blocks import FmuHost

SCENARIO = """
connections = ["a.y -> b.u"]

[master]
step = "100 ms"
stop = "2 s"
start = "{start}"

[blocks.a]
fmu = "{fmu}"
parameters = {{ y0 = "250 ms" }}

[blocks.b]
fmu = "{fmu}"
parameters = {{ k = 3 }}
"""


@pytest.fixture
def ramp_scenario(tmp_path: Path, fmi3_ramp_fmu: Path):
    def make(start: str = "0 s") -> Path:
        path = tmp_path / "ramp.toml"
        path.write_text(SCENARIO.format(fmu=fmi3_ramp_fmu, start=start))
        return path

    return make


def test_the_fixture_is_a_valid_fmi3_fmu(fmi3_ramp_fmu: Path) -> None:
    assert validate_fmu(str(fmi3_ramp_fmu)) == []


def test_fmu_host_reads_fmi3_variables_and_units(fmi3_ramp_fmu: Path) -> None:
    host = FmuHost("ramp", fmi3_ramp_fmu)
    try:
        assert host.fmi_version == "3.0"
        v = host.variables
        assert (v["y"].type, v["y"].causality, v["y"].unit) == ("Real", "output", "s")
        assert v["steps"].type == "Integer"
        assert v["u"].unit_def is not None and v["u"].unit_def.factor == 0.001
        assert v["time"].causality == "independent"
        assert [x.name for x in host.by_causality("output")] == ["steps", "y", "v"]
    finally:
        host.terminate()


def test_master_runs_fmi3_blocks_gauss_seidel(ramp_scenario) -> None:
    sc = cosim.load_scenario(ramp_scenario("0.5 s"))
    system, meta = sc.build()
    assert [c.factor for c in system.connections] == [1000.0]  # s -> ms
    master = cosim.Master(system, sc.settings, meta)
    try:
        first = master.run()
        master.reset()  # fmi3Reset, then the same run again
        second = master.run()
    finally:
        master.terminate()
    t = first.time
    assert t[0] == 0.5 and t[-1] == 2.0 and len(t) == 16
    # the FMU's time is t_n + h, ours t0 + (n + 1) h: equal to the last bit or two
    np.testing.assert_allclose(first["a.y"], t + 0.25, rtol=1e-15, atol=0)  # y0 = 250 ms
    # b.u = 1000 a.y (ms) and v = k u: under Gauss-Seidel b sees a at the same instant
    np.testing.assert_allclose(first["b.v"], 3.0 * 1000.0 * (t + 0.25), rtol=1e-15, atol=0)
    np.testing.assert_allclose(first["b.y"], t, rtol=1e-15, atol=0)
    for name in first.names:
        np.testing.assert_array_equal(first.data[name], second.data[name])
    assert first.metadata["blocks"]["a"]["fmi_version"] == "3.0"


def test_fmi3_errors_reach_the_host_log(fmi3_ramp_fmu: Path) -> None:
    host = FmuHost("ramp", fmi3_ramp_fmu)
    try:
        host.setup(0.0, {"k": 2.0})
        host.exit_init()
        with pytest.raises(Exception, match="fmi3SetFloat64"):
            host.set_real([host.variables["k"].vr], [5.0])  # a fixed parameter, stepping
        assert "cannot be set now" in host.messages[-1]
    finally:
        host.terminate()
