"""Parsing a scenario file apart from building it (``cosim.scenario_parse``)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.scenario import Scenario, load_scenario
from cosim.scenario_parse import ScenarioSpec, parse_scenario

ROOT = Path(__file__).resolve().parents[2]

TEXT = """
[master]
step = "10 ms"
stop = "1 s"

[blocks.a]
model = "NoSuchModel"

[blocks.b]
model = "GaussMarkov2"
parameters = {{ {param} = 1.0 }}
"""


def write(tmp_path: Path, param: str = "tau") -> Path:
    path = tmp_path / "s.toml"
    path.write_text(TEXT.format(param=param))
    return path


def test_parsing_instantiates_nothing_and_building_checks_the_blocks(tmp_path: Path) -> None:
    """An unknown model passes the parser (it checks the file, not the registry's
    classes) and is refused by the build with the block's key."""
    spec = parse_scenario(write(tmp_path))
    assert type(spec) is ScenarioSpec and not hasattr(spec, "build")
    assert list(spec.blocks) == ["a", "b"] and spec.blocks["a"].source == "NoSuchModel"
    scenario = load_scenario(write(tmp_path))
    assert isinstance(scenario, Scenario)
    assert {f: getattr(scenario, f) for f in spec.__dataclass_fields__} == vars(spec)
    with pytest.raises(ScenarioError) as err:
        scenario.build()
    assert err.value.key == "blocks.a.model"


def test_a_misspelt_parameter_gets_its_suggestion_when_it_fails(tmp_path: Path) -> None:
    path = write(tmp_path, param="sigmaa")
    path.write_text(path.read_text().replace('model = "NoSuchModel"', 'model = "GaussMarkov2"'))
    with pytest.raises(ScenarioError, match="no variable 'sigmaa'.*Did you mean 'sigma'"):
        load_scenario(path).build()


def test_the_parser_imports_no_host() -> None:
    """The parser's module needs neither hosts nor wiring (checked by reading it)."""
    text = (ROOT / "cosim" / "scenario_parse.py").read_text()
    for name in ("cosim.blocks", "cosim.wiring", "cosim.scenario import"):
        assert name not in text, name
    assert "cosim.scenario_parse" in sys.modules
