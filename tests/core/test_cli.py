"""The command line: good runs, and bad input that gets one clear message and no traceback."""

from __future__ import annotations

import re
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from cosim.results import RunResult

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "scenarios" / "demo.toml"

PAIR = "[blocks.flexure]\nmodel = 'GaussMarkov2'\n[blocks.sensor]\nmodel = 'FirstOrderSensor'\n"
HEAD = """
[master]
step = "10 ms"
stop = "1 s"
"""


def write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def assert_user_error(res, *fragments: str, code: int = 3) -> None:
    assert res.code == code, (res.code, res.out, res.err)
    assert "Traceback" not in res.err
    assert res.err.startswith("error: ")
    for f in fragments:
        assert f in res.err, f"{f!r} not in {res.err!r}"


def test_run_demo_writes_results_and_metadata(cli, tmp_path: Path) -> None:
    res = cli("run", DEMO, "--out", tmp_path / "out", "--stop", "2 s")
    assert res.code == 0, res.err
    result = RunResult.load(tmp_path / "out" / "results.csv")
    assert result.names[0] == "time"
    assert len(result.data) == 201 and result.time[-1] == 2.0
    meta = result.metadata
    assert re.fullmatch(r"[0-9a-f]{64}", meta["scenario"]["sha256"])
    assert meta["seeds"] == {"flexure": 7, "sensor": 11}
    assert meta["units"]["flexure.x"] == "rad"
    assert meta["software"]["ins-cosim"]
    assert (tmp_path / "out" / "results.png").stat().st_size > 10_000


def test_run_demo_from_fmus_gives_the_same_numbers(cli, tmp_path: Path, fmu_dir: Path) -> None:
    a = cli("run", DEMO, "--out", tmp_path / "a", "--stop", "2 s", "--no-plot")
    b = cli(
        "run", DEMO, "--out", tmp_path / "b", "--stop", "2 s", "--no-plot", "--fmu-dir", fmu_dir
    )
    assert a.code == 0 and b.code == 0, (a.err, b.err)
    ra, rb = RunResult.load(tmp_path / "a/results.csv"), RunResult.load(tmp_path / "b/results.csv")
    for name in ra.names:
        np.testing.assert_array_equal(ra.data[name], rb.data[name])
    assert rb.metadata["blocks"]["flexure"]["kind"] == "fmu"
    assert re.fullmatch(r"[0-9a-f]{64}", rb.metadata["blocks"]["flexure"]["sha256"])


def test_check_reports_order(cli) -> None:
    res = cli("check", DEMO)
    assert res.code == 0, res.err
    assert "flexure -> sensor" in res.out


def test_fmus_lists_and_validates(cli, fmu_dir: Path) -> None:
    res = cli("fmus", "--dir", fmu_dir)
    assert res.code == 0, res.out + res.err
    assert "GaussMarkov2.fmu" in res.out
    assert re.search(r"GaussMarkov2\.fmu\s+2\.0\s+[0-9a-f-]{36}\s+[0-9a-f]{12}\s+0", res.out)


def test_missing_scenario_file(cli, tmp_path: Path) -> None:
    assert_user_error(cli("check", tmp_path / "nope.toml"), "nope.toml", "file not found")


def test_malformed_toml(cli, tmp_path: Path) -> None:
    path = write(tmp_path, HEAD + "[blocks.a\nmodel = 'Ramp'\n")
    assert_user_error(cli("check", path), "s.toml", "not valid TOML", "line 5")


def test_duplicate_block_names(cli, tmp_path: Path) -> None:
    text = HEAD + "[blocks.gm]\nmodel = 'GaussMarkov2'\n[blocks.gm]\nmodel = 'GaussMarkov2'\n"
    assert_user_error(cli("check", write(tmp_path, text)), "s.toml", "block 'gm' is defined twice")


def test_missing_fmu_file(cli, tmp_path: Path) -> None:
    text = HEAD + "[blocks.imu]\nfmu = 'vendor/Imu.fmu'\n"
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "s.toml", "blocks.imu.fmu", "Imu.fmu", "does not exist")


def test_model_exchange_only_fmu(cli, tmp_path: Path, fmu_dir: Path) -> None:
    me = tmp_path / "MeOnly.fmu"
    with zipfile.ZipFile(fmu_dir / "GaussMarkov2.fmu") as src, zipfile.ZipFile(me, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(b"<CoSimulation", b"<ModelExchange")
            dst.writestr(item, data)
    text = HEAD + "[blocks.gm]\nfmu = 'MeOnly.fmu'\n"
    assert_user_error(cli("check", write(tmp_path, text)), "blocks.gm.fmu", "Model Exchange")


def test_unknown_block_in_connection(cli, tmp_path: Path) -> None:
    text = "connections = ['flexur.x -> sensor.u']\n" + HEAD + PAIR
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "connections[0]", "unknown block 'flexur'", "Did you mean 'flexure'")


def test_unknown_variable_in_connection(cli, tmp_path: Path) -> None:
    text = "connections = ['flexure.xx -> sensor.u']\n" + HEAD + PAIR
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "connections[0]", "no variable 'xx'", "Did you mean 'x'")


def test_output_on_the_right_side(cli, tmp_path: Path) -> None:
    text = "connections = ['flexure.x -> sensor.y']\n" + HEAD + PAIR
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "'sensor.y' is an output", "right side")


def test_incompatible_units_on_a_connection(cli, tmp_path: Path) -> None:
    # flexure.x_dot is rad/s, sensor.u expects rad
    text = "connections = ['flexure.x_dot -> sensor.u']\n" + HEAD + PAIR
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "incompatible units", "'rad/s'", "'rad'", "flexure.x_dot")


def test_parameter_with_wrong_unit(cli, tmp_path: Path) -> None:
    text = HEAD + "[blocks.gm]\nmodel = 'GaussMarkov2'\nparameters = { tau = '3 deg' }\n"
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "blocks.gm.parameters.tau", "'deg' cannot be converted to 's'")


def test_unconnected_input_without_start(cli, tmp_path: Path, fmu_dir: Path) -> None:
    fmu = tmp_path / "NoStart.fmu"
    with zipfile.ZipFile(fmu_dir / "FirstOrderSensor.fmu") as src, zipfile.ZipFile(fmu, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                # drop the start value of the input u
                text = re.sub(r'(name="u".*?<Real[^>]*?)\sstart="[^"]*"', r"\1", text, flags=re.S)
                data = text.encode()
            dst.writestr(item, data)
    text = HEAD + "[blocks.sensor]\nfmu = 'NoStart.fmu'\n"
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "input 'sensor.u' is not connected and has no start value")


def test_top_level_key_under_a_table_is_explained(cli, tmp_path: Path) -> None:
    text = HEAD + "[blocks.gm]\nmodel = 'GaussMarkov2'\nconnections = []\n"
    res = cli("check", write(tmp_path, text))
    assert_user_error(res, "blocks.gm.connections", "top-level key")


def test_fmu_do_step_error_stops_with_block_call_time(cli, tmp_path: Path, faulty_fmu) -> None:
    shutil.copy(faulty_fmu, tmp_path / "Faulty.fmu")
    text = HEAD + (
        "[blocks.bad]\nfmu = 'Faulty.fmu'\nparameters = { fail_time = '0.5 s', mode = 2 }\n"
    )
    res = cli("run", write(tmp_path, text), "--out", tmp_path / "out")
    assert_user_error(res, "block 'bad', FMI call fmi2DoStep", "t = 0.5 s", code=4)
    partial = RunResult.load(tmp_path / "out" / "results.csv")
    assert partial.status == "failed" and "fmi2DoStep" in partial.error
    assert len(partial.data) == 51 and partial.time[-1] == 0.5


def test_nan_output_stops_with_block_variable_time(cli, tmp_path: Path) -> None:
    text = HEAD + (
        "[blocks.bad]\nclass = 'testblocks:Faulty'\n"
        "parameters = { fail_time = '0.25 s', mode = 1 }\n"
    )
    res = cli("run", write(tmp_path, text), "--out", tmp_path / "out")
    assert_user_error(res, "block 'bad', variable 'y'", "t = 0.26 s", "not finite", code=4)
    partial = RunResult.load(tmp_path / "out" / "results.csv")
    assert len(partial.data) == 26
    assert np.all(np.isfinite(partial.data["bad.y"]))


@pytest.mark.parametrize(
    "snippet, fragment",
    [
        ("[blocks.gm]\nmodel = 'GaussMarkov3'\n", "Did you mean 'GaussMarkov2'"),
        ("[blocks.gm]\nmodel = 'GaussMarkov2'\nrate = 0\n", "blocks.gm.rate"),
        ("[blocks.gm]\nmodel = 'GaussMarkov2'\nparameters = { seed = 1.5 }\n", "integer"),
        ("[blocks.gm]\nmodel = 'GaussMarkov2'\nparameters = { sigmma = 1 }\n", "'sigma'"),
        ("[blocks.gm]\nclass = 'nowhere:Nothing'\n", "package.module:ClassName"),
    ],
)
def test_block_table_errors(cli, tmp_path: Path, snippet: str, fragment: str) -> None:
    assert_user_error(cli("check", write(tmp_path, HEAD + snippet)), fragment)


@pytest.mark.parametrize(
    "args",
    [("run",), ("check",), ("fmus", "--bogus"), ("reproduce", "seed999"), ("run", "x.toml")],
)
def test_usage_errors_exit_3_without_traceback(cli, args: tuple[str, ...]) -> None:
    res = cli(*args)
    assert res.code == 3, (res.code, res.err)
    assert "Traceback" not in res.err
