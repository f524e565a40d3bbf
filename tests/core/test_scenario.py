"""Scenario loading through the Python API: units applied once, vectors expanded."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import ScenarioError
from cosim.models.constants import ARCMIN, DEG

ROOT = Path(__file__).resolve().parents[2]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def test_demo_parameters_are_converted_to_si_once() -> None:
    sc = cosim.load_scenario(ROOT / "scenarios" / "demo.toml")
    system, meta = sc.build()
    try:
        p = system.parameters
        assert p["flexure"]["tau"] == 60.0
        assert p["flexure"]["sigma"] == pytest.approx(2 * ARCMIN, rel=1e-15)
        assert p["sensor"]["time_constant"] == pytest.approx(0.05, rel=1e-15)
        assert p["flexure"]["seed"] == 7 and isinstance(p["flexure"]["seed"], int)
        assert sc.settings.step == pytest.approx(0.01, rel=1e-15)
        assert sc.settings.n_steps == 12000
        assert meta["scenario"]["sha256"] == sc.sha256
    finally:
        for host in system.blocks.values():
            host.terminate()


VEC = """
connections = ["a.y -> b.u", "b.y[2] -> c.u[1]"]
[master]
step = 1.0
stop = 3.0
[blocks.a]
class = "testblocks:Vec"
parameters = { u = ["1 deg", "2 deg", "3 deg"], gain = 2.0 }
[blocks.b]
class = "testblocks:Vec"
[blocks.c]
class = "testblocks:Vec"
"""


def test_vector_connections_expand_element_by_element(tmp_path: Path) -> None:
    result = cosim.run(write(tmp_path, VEC))
    np.testing.assert_allclose(result["a.y"][-1], [2 * DEG, 4 * DEG, 6 * DEG], rtol=1e-15)
    np.testing.assert_allclose(result["b.y"][-1], result["a.y"][-1], rtol=0)
    # a single element wired explicitly: c.u[1] <- b.y[2]; the others keep their start
    np.testing.assert_allclose(result["c.y"][-1], [4 * DEG, 0.0, 0.0], rtol=1e-15)
    assert result["a.y"].shape == (4, 3)


def test_vector_length_mismatch_is_explained(tmp_path: Path) -> None:
    text = VEC.replace('"b.y[2] -> c.u[1]"', '"b.y -> c.u[1]"')
    with pytest.raises(ScenarioError, match=r"has 3 element\(s\) but 'c.u\[1\]' has 1"):
        cosim.load_scenario(write(tmp_path, text)).build()


def test_connection_between_compatible_units_converts(tmp_path: Path) -> None:
    text = """
connections = ["src.y -> v.u[1]"]
[master]
step = 1.0
stop = 2.0
[blocks.src]
class = "testblocks:DegSource"
[blocks.v]
class = "testblocks:Vec"
"""
    result = cosim.run(write(tmp_path, text))
    # 90 deg arrives as pi/2 rad
    assert result["v.y[1]"][-1] == pytest.approx(math.pi / 2, rel=1e-15)


def test_step_must_divide_the_run(tmp_path: Path) -> None:
    text = VEC.replace("stop = 3.0", "stop = 3.5")
    with pytest.raises(ScenarioError, match="not a whole positive number of steps"):
        cosim.run(write(tmp_path, text))


def test_record_selection_and_interval(tmp_path: Path) -> None:
    text = VEC + '[output]\nvariables = ["a.y[1]", "c"]\nevery = 3\n'
    result = cosim.run(write(tmp_path, text))
    assert result.names == ["time", "a.y[1]", "c.y[1]", "c.y[2]", "c.y[3]"]
    np.testing.assert_array_equal(result.time, [0.0, 3.0])


def test_unknown_top_level_key(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="unknown key 'mastre'.*Did you mean 'master'"):
        cosim.load_scenario(write(tmp_path, VEC + "[mastre]\nstep = 1\n"))


def test_run_refuses_an_override_that_is_not_a_master_setting() -> None:
    with pytest.raises(TypeError, match="unknown master setting 'stpo'"):
        cosim.run(ROOT / "scenarios" / "demo.toml", stpo="1 s")


def test_overrides_are_parsed_like_the_file_and_leave_the_scenario_alone() -> None:
    sc = cosim.load_scenario(ROOT / "scenarios" / "demo.toml")
    settings = sc.master_settings(stop="2 min", coupling="Jacobi", step=None)
    assert (settings.stop, settings.step, settings.coupling) == (120.0, 0.01, "jacobi")
    assert settings.n_steps == 12000 and sc.settings.coupling == "gauss-seidel"
    assert sc.master_settings() is sc.settings
    with pytest.raises(ScenarioError, match="not a whole positive number") as info:
        sc.master_settings(stop="1.005 s")
    assert info.value.file == str(sc.path) and info.value.key == "master.stop"
