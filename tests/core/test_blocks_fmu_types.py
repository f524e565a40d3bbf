"""Issue 16, items 2, 3 and 7: every output type recorded, FMUs that end the run early,
step ends on the master's time grid.

The fixture tests/fixtures/stair2 (C, FMI 2.0, compiled by the test run) is shaped like
the Reference-FMUs' Stair: an Integer counter, a Boolean and a String output, and a
request to end the simulation at ``stop_at`` (fmi2Discard + fmi2Terminated).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fmpy import simulate_fmu

import cosim
from cosim.interop.cbuild import build_c_fmu
from cosim.results import RunResult

ROOT = Path(__file__).resolve().parents[2]

SCENARIO = """
[master]
step = "0.5 s"
stop = "12 s"

[blocks.steps]
fmu = "{fmu}"
parameters = {{ stop_at = "{stop_at}" }}
"""


@pytest.fixture(scope="module")
def steps_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("steps") / "Steps.fmu"
    return build_c_fmu(ROOT / "tests" / "fixtures" / "stair2", out)


def scenario(tmp_path: Path, fmu: Path, stop_at: str = "10 s") -> Path:
    path = tmp_path / "steps.toml"
    path.write_text(SCENARIO.format(fmu=fmu, stop_at=stop_at))
    return path


def test_an_fmu_that_asks_to_stop_ends_the_run_cleanly(cli, steps_fmu, tmp_path) -> None:
    res = cli("run", scenario(tmp_path, steps_fmu), "--out", tmp_path / "o", "--no-plot")
    assert res.code == 0, res.err
    assert "Traceback" not in res.err
    result = RunResult.load(tmp_path / "o" / "results.csv")
    assert result.status == "completed"
    assert result.time[-1] == 10.0 and len(result.time) == 21  # the last sample is kept
    note = result.metadata["terminated"]
    assert note["block"] == "steps" and note["time"] == 10.0 and note["call"] == "fmi2DoStep"
    assert "fmi2Discard, fmi2Terminated" in note["reason"]


def test_integer_boolean_and_string_outputs_are_recorded(cli, steps_fmu, tmp_path) -> None:
    res = cli("run", scenario(tmp_path, steps_fmu), "--out", tmp_path / "o", "--no-plot")
    assert res.code == 0, res.err
    meta = json.loads((tmp_path / "o" / "results.json").read_text())
    assert meta["types"] == {
        "steps.ramp": "Real",
        "steps.counter": "Integer",
        "steps.odd": "Boolean",
        "steps.label": "String",
    }
    lines = (tmp_path / "o" / "results.csv").read_text().splitlines()
    assert lines[0] == "time,steps.ramp,steps.counter,steps.odd,steps.label"
    assert lines[3] == "1,1,2,0,step 2"
    assert lines[-1] == "10,10,11,1,step 11"
    result = RunResult.load(tmp_path / "o" / "results.csv")
    assert result.strings["steps.label"][-1] == "step 11"
    assert result["steps.counter"][-1] == 11


def test_agrees_with_fmpy_at_the_same_output_times(steps_fmu, tmp_path) -> None:
    ours = cosim.run(scenario(tmp_path, steps_fmu, "7.25 s"))
    theirs = simulate_fmu(
        str(steps_fmu),
        stop_time=12.0,
        output_interval=0.5,
        start_values={"stop_at": 7.25},
        output=["ramp", "counter", "odd"],
    )
    assert ours.time.tolist() == theirs["time"].tolist()  # both end at 7.25 s
    assert ours["steps.ramp"].tolist() == theirs["ramp"].tolist()  # Real: bit for bit
    assert ours["steps.counter"].astype(int).tolist() == theirs["counter"].tolist()
    assert ours["steps.odd"].astype(bool).tolist() == theirs["odd"].tolist()


def test_step_sizes_end_on_the_master_grid() -> None:
    from testblocks import StepLog

    from cosim.blocks import InProcessHost
    from cosim.master import Master, MasterSettings, System

    def steps(clock: str) -> list[tuple[float, float]]:
        host = InProcessHost("log", StepLog)
        settings = MasterSettings(0.1, 10.0, start=0.3, clock=clock)
        master = Master(System({"log": host}, []), settings)
        try:
            master.run()
            return host.instance.steps
        finally:
            master.terminate()

    for n, (t, h) in enumerate(steps("fmpy")):
        assert t == 0.3 + n * 0.1
        assert t + h == 0.3 + (n + 1) * 0.1, n  # not t + 0.1: one rounding less
    for n, (t, h) in enumerate(steps("exact")):  # the default: t_n nearest 3/10 + n/10
        assert t == (3 + n) / 10
        assert t + h == (4 + n) / 10, n


def test_an_fmi3_fmu_that_asks_to_stop_agrees_with_fmpy(fmi3_ramp_fmu: Path, tmp_path) -> None:
    path = tmp_path / "ramp.toml"
    path.write_text(
        f'[master]\nstep = "0.1 s"\nstop = "2 s"\nclock = "fmpy"\n\n'
        f'[blocks.ramp]\nfmu = "{fmi3_ramp_fmu}"\n'
        f'parameters = {{ stop_at = "0.75 s" }}\nunconnected_ok = ["u"]\n'
    )  # fmpy's clock (docs/coupling.md): bit for bit with fmpy
    ours = cosim.run(path)
    assert ours.status == "completed"
    assert ours.metadata["terminated"]["call"] == "fmi3DoStep"
    assert "terminateSimulation" in ours.metadata["terminated"]["reason"]
    theirs = simulate_fmu(
        str(fmi3_ramp_fmu),
        stop_time=2.0,
        output_interval=0.1,
        start_values={"stop_at": 0.75},
        output=["y", "steps"],
    )
    assert ours.time.tolist() == theirs["time"].tolist()  # the last sample (0.8 s) kept
    assert ours["ramp.y"].tolist() == theirs["y"].tolist()  # bit for bit
    assert ours["ramp.steps"].astype(int).tolist() == theirs["steps"].tolist()
    assert ours.metadata["types"]["ramp.steps"] == "Integer"


@pytest.fixture(scope="module")
def decay_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("decay") / "Decay.fmu"
    return build_c_fmu(ROOT / "tests" / "fixtures" / "decay2", out)


@pytest.fixture(scope="module")
def echo_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("echo") / "Echo.fmu"
    return build_c_fmu(ROOT / "tests" / "fixtures" / "echo2", out)


def test_internal_steps_up_to_the_step_end_agree_with_fmpy(decay_fmu: Path, tmp_path) -> None:
    # like Reference-FMUs Roberts: a step end one rounding off would cost an extra step
    path = tmp_path / "decay.toml"
    text = (
        f'[master]\nstep = "0.1 s"\nstop = "3 s"\n\n[blocks.d]\nfmu = "{decay_fmu}"\n'
        f'parameters = {{ k = 0.7, dt_int = "30 ms" }}\n'
    )
    path.write_text(text)
    exact = cosim.run(path)  # the default clock: t_n nearest n/10, no extra step either
    assert exact.time.tolist() == [k / 10 for k in range(31)]
    assert int(exact["d.n_int"][-1]) == 120
    # fmpy's clock (docs/coupling.md): the same times, steps and outputs as fmpy
    path.write_text(text.replace('stop = "3 s"', 'stop = "3 s"\nclock = "fmpy"'))
    ours = cosim.run(path)
    theirs = simulate_fmu(
        str(decay_fmu),
        stop_time=3.0,
        output_interval=0.1,
        start_values={"k": 0.7, "dt_int": 0.03},
        output=["x", "n_int"],
    )
    assert ours.time.tolist() == theirs["time"].tolist()
    assert ours["d.x"].tolist() == theirs["x"].tolist()  # bit for bit
    assert ours["d.n_int"].astype(int).tolist() == theirs["n_int"].tolist()
    assert int(ours["d.n_int"][-1]) == 120  # 4 internal steps per 0.1 s, none extra


def test_every_fmi2_type_is_set_and_echoed(echo_fmu: Path, tmp_path) -> None:
    values = {
        "p_real": 1.5,
        "u_real": 0.25,
        "p_int": 3,
        "u_int": -7,
        "u_enum": 3,
        "p_bool": True,
        "u_bool": False,
        "p_str": "abc",
        "u_str": "xyz",
    }
    table = ", ".join(
        f"{k} = {str(v).lower() if isinstance(v, bool) else repr(v).replace(chr(39), chr(34))}"
        for k, v in values.items()
    )
    path = tmp_path / "echo.toml"
    path.write_text(
        f'[master]\nstep = "0.25 s"\nstop = "1 s"\n\n[blocks.e]\nfmu = "{echo_fmu}"\n'
        f"parameters = {{ {table} }}\n"
    )
    ours = cosim.run(path)
    theirs = simulate_fmu(
        str(echo_fmu),
        stop_time=1.0,
        output_interval=0.25,
        start_values=values,
        output=["y_real", "y_int", "y_enum", "y_bool"],
    )
    assert ours.time.tolist() == theirs["time"].tolist()
    assert ours["e.y_real"].tolist() == theirs["y_real"].tolist()
    for name in ("y_int", "y_enum"):
        assert ours[f"e.{name}"].astype(int).tolist() == theirs[name].tolist()
    assert ours["e.y_bool"].astype(bool).tolist() == theirs["y_bool"].tolist()
    assert ours.strings["e.y_str"] == ["abc/xyz"] * 5
    assert ours.metadata["types"]["e.y_enum"] == "Enumeration"


def test_a_value_that_does_not_fit_its_type_is_one_line(cli, echo_fmu: Path, tmp_path) -> None:
    for value, message in [
        ("3.5", "expected an integer in [-2147483648, 2147483647] for 'p_int' (Integer)"),
        ('"x"', "expected an integer in [-2147483648, 2147483647] for 'p_int' (Integer)"),
    ]:
        path = tmp_path / "bad.toml"
        path.write_text(
            f'[master]\nstep = "0.25 s"\nstop = "1 s"\n\n[blocks.e]\nfmu = "{echo_fmu}"\n'
            f"parameters = {{ p_int = {value} }}\nunconnected_ok = "
            f'["u_real", "u_int", "u_enum", "u_bool", "u_str"]\n'
        )
        res = cli("check", path)
        assert res.code == 3 and "Traceback" not in res.err, res.err
        assert message in res.err and len(res.err.strip().splitlines()) == 1, res.err


@pytest.fixture(scope="module")
def echo3_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("echo3") / "Echo3.fmu"
    return build_c_fmu(ROOT / "tests" / "fixtures" / "echo3", out)


def test_every_fmi3_type_is_set_and_echoed(echo3_fmu: Path, tmp_path) -> None:
    numbers = {
        "p_float64": 1.5,
        "u_float64": 0.25,
        "p_float32": 0.1,
        "u_float32": 0.2,
        "p_int8": -100,
        "u_int8": -20,
        "p_uint8": 200,
        "u_uint8": 50,
        "p_int16": 30000,
        "u_int16": 1000,
        "p_uint16": 60000,
        "u_uint16": 5000,
        "p_int32": -(2**30),
        "u_int32": 12,
        "p_uint32": 2**31,
        "u_uint32": 9,
        "p_int64": -(2**40),
        "u_int64": 7,
        "p_uint64": 2**50,
        "u_uint64": 5,
        "u_enum": 3,
        "p_boolean": True,
        "u_boolean": False,
    }
    table = ", ".join(f"{k} = {str(v).lower()}" for k, v in numbers.items())
    table += ', p_string = "abc", u_string = "xyz", p_binary = "0a0b", u_binary = "ff"'
    path = tmp_path / "echo3.toml"
    path.write_text(
        f'[master]\nstep = "0.25 s"\nstop = "1 s"\n\n[blocks.e]\nfmu = "{echo3_fmu}"\n'
        f"parameters = {{ {table} }}\n"
    )
    ours = cosim.run(path)
    outputs = [f"y_{k[2:]}" for k in numbers if k.startswith("u_")]
    theirs = simulate_fmu(
        str(echo3_fmu), stop_time=1.0, output_interval=0.25, start_values=numbers, output=outputs
    )
    assert ours.time.tolist() == theirs["time"].tolist()
    for name in outputs:
        mine = ours[f"e.{name}"]
        want = theirs[name].astype(float)  # ins-cosim records numbers as float64
        assert mine.tolist() == want.tolist(), name  # Float64 and Float32: bit for bit
    assert ours["e.y_int8"][-1] == -120 and ours["e.y_uint64"][-1] == 2**50 + 5
    assert ours.strings["e.y_string"][-1] == "abc/xyz"
    assert ours.strings["e.y_binary"][-1] == "0a0bff"
    types = ours.metadata["types"]
    assert (types["e.y_float32"], types["e.y_uint64"], types["e.y_enum"]) == (
        "Float32",
        "UInt64",
        "Enumeration",
    )


def test_a_binary_parameter_is_written_as_hex_by_run(cli, echo3_fmu, tmp_path) -> None:
    """Issue 30, item 2: a Binary parameter ended ``run`` in a traceback while writing
    results.json (bytes are not JSON); it is written as hex digits, as in the CSV."""
    path = tmp_path / "binary.toml"
    path.write_text(
        f'[master]\nstep = "0.25 s"\nstop = "1 s"\n\n[blocks.e]\nfmu = "{echo3_fmu}"\n'
        f'parameters = {{ p_binary = "0a0b", u_binary = "ff" }}\n'
    )
    res = cli("run", path, "--out", tmp_path / "o", "--no-plot")
    assert res.code == 0 and "Traceback" not in res.err, res.err
    meta = json.loads((tmp_path / "o" / "results.json").read_text())
    assert meta["parameters"]["e"]["p_binary"] == "0a0b"
    assert meta["types"]["e.y_binary"] == "Binary"
    result = RunResult.load(tmp_path / "o" / "results.csv")
    assert result.strings["e.y_binary"] == ["0a0bff"] * 5


def test_an_out_of_range_fmi3_integer_is_refused_by_check(cli, echo3_fmu, tmp_path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(
        f'[master]\nstep = "0.25 s"\nstop = "1 s"\n\n[blocks.e]\nfmu = "{echo3_fmu}"\n'
        f"parameters = {{ p_uint8 = 256 }}\n"
    )
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err
    assert "expected an integer in [0, 255] for 'p_uint8' (UInt8), got 256" in res.err


def test_fmi3_internal_steps_up_to_the_step_end_agree_with_fmpy(tmp_path: Path) -> None:
    fmu = build_c_fmu(ROOT / "tests" / "fixtures" / "decay3", tmp_path / "Decay3.fmu")
    path = tmp_path / "decay3.toml"
    path.write_text(
        f'[master]\nstep = "0.1 s"\nstop = "3 s"\nclock = "fmpy"\n\n[blocks.d]\nfmu = "{fmu}"\n'
        f'parameters = {{ k = 0.7, y0 = "1 s" }}\nunconnected_ok = ["u"]\n'
    )  # fmpy's clock (docs/coupling.md): bit for bit with fmpy
    ours = cosim.run(path)
    theirs = simulate_fmu(
        str(fmu),
        stop_time=3.0,
        output_interval=0.1,
        start_values={"k": 0.7, "y0": 1.0},
        output=["y", "steps"],
    )
    assert ours.time.tolist() == theirs["time"].tolist()
    assert ours["d.y"].tolist() == theirs["y"].tolist()  # bit for bit
    assert ours["d.steps"].astype(int).tolist() == theirs["steps"].tolist()
    assert int(ours["d.steps"][-1]) == 120
