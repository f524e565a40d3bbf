"""Issue 16, item 2: Enumeration values by item name, and non-Real links between FMUs.

C FMUs compiled in the test run (tests/fixtures: ``echo2`` / ``echo3``, shaped like the
Reference-FMUs ``Feedthrough``, and ``stair2``, like ``Stair``):

- ``u_enum = "high"`` sets the item's value (3), as fmpy does with the value itself; a
  name that is not an item is refused by ``check`` in one line listing the items;
- an Integer -> Integer or Boolean -> Boolean connection (``Stair.counter ->
  Echo.u_int``) carries its values (issue 30, item 1; until then it was refused); a link
  FMI's type rules forbid (Real -> Integer, Integer -> Boolean) is refused by ``check`` in
  one line naming both variables and their types, exit 3, no traceback.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import simulate_fmu

import cosim
from cosim.interop.cbuild import build_c_fmu

pytestmark = pytest.mark.filterwarnings("ignore::cosim.wiring.UnconnectedInputWarning")
FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"


@pytest.fixture(scope="module")
def echo2(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_c_fmu(FIXTURES / "echo2", tmp_path_factory.mktemp("echo2") / "Echo.fmu")


@pytest.fixture(scope="module")
def echo3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_c_fmu(FIXTURES / "echo3", tmp_path_factory.mktemp("echo3") / "Echo3.fmu")


@pytest.fixture(scope="module")
def stair2(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_c_fmu(FIXTURES / "stair2", tmp_path_factory.mktemp("stair2") / "Steps.fmu")


def scenario(tmp_path: Path, fmu: Path, enum: str) -> Path:
    path = tmp_path / "enum.toml"
    path.write_text(
        f'[master]\nstep = "0.25 s"\nstop = "1 s"\n\n[blocks.e]\nfmu = "{fmu}"\n'
        f"parameters = {{ u_enum = {enum} }}\n"
    )
    return path


@pytest.mark.parametrize("which", ["echo2", "echo3"])
def test_an_enumeration_given_by_item_name_sets_the_items_value(
    which: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    fmu = request.getfixturevalue(which)
    ours = cosim.run(scenario(tmp_path, fmu, '"high"'))
    theirs = simulate_fmu(str(fmu), stop_time=1.0, output_interval=0.25, start_values={"u_enum": 3})
    assert ours["e.y_enum"].astype(int).tolist() == theirs["y_enum"].tolist() == [3] * 5
    # the integer value still works, and gives the same
    again = cosim.run(scenario(tmp_path, fmu, "2"))
    assert again["e.y_enum"].astype(int).tolist() == [2] * 5


def test_a_wrong_item_name_is_one_line_from_check(cli, echo2: Path, tmp_path: Path) -> None:
    res = cli("check", scenario(tmp_path, echo2, '"hihg"'))
    assert res.code == 3 and "Traceback" not in res.err
    line = res.err.strip()
    assert "\n" not in line
    assert "key 'blocks.e.parameters.u_enum'" in line
    assert "'hihg' is not an item of the Enumeration 'u_enum'. Did you mean 'high'?" in line
    assert "Items: 'low' (1), 'mid' (2), 'high' (3)" in line
    # an integer that is no item's value is refused the same way
    res = cli("check", scenario(tmp_path, echo2, "7"))
    assert res.code == 3 and "7 is not an item of the Enumeration 'u_enum'" in res.err


def links_scenario(tmp_path: Path, stair2: Path, echo2: Path, links: list[str]) -> Path:
    path = tmp_path / "links.toml"
    path.write_text(
        f'connections = {links!r}\n[master]\nstep = "0.5 s"\nstop = "2 s"\n\n'
        f'[blocks.s]\nfmu = "{stair2}"\n\n[blocks.e]\nfmu = "{echo2}"\n'
        f"unconnected_ok = ['u_real', 'u_int', 'u_enum', 'u_bool', 'u_str']\n"
    )
    return path


def test_integer_and_boolean_links_carry_their_values(
    echo2: Path, stair2: Path, tmp_path: Path
) -> None:
    """Issue 30, item 1: ``Stair.counter -> Echo.u_int`` (Integer) and ``Stair.odd ->
    Echo.u_bool`` (Boolean) flow like Reals (Gauss-Seidel: the sink sees the source's value
    at the end of the same step); the recording keeps them as integers."""
    path = links_scenario(tmp_path, stair2, echo2, ["s.counter -> e.u_int", "s.odd -> e.u_bool"])
    res = cosim.run(path)
    assert res["e.y_int"].tolist() == res["s.counter"].tolist() == [1, 1, 2, 2, 3]
    assert res["e.y_bool"].tolist() == res["s.odd"].tolist()  # p_bool = false: y = u
    assert res.metadata["types"]["e.y_int"] == "Integer"


@pytest.mark.parametrize(
    ("link", "what"),
    [
        (
            "s.ramp -> e.u_int",
            "'s.ramp' is an output of type Float64 and 'e.u_int' an input "
            "of type Int32: a Float64 value would be rounded to Int32",
        ),
        ("s.counter -> e.u_bool", "FMI has no conversion from Int32 to Boolean"),
        ("s.odd -> e.u_real", "FMI has no conversion from Boolean to Float64"),
    ],
)
def test_a_link_of_the_wrong_type_is_refused_by_check_in_one_line(
    cli, echo2: Path, stair2: Path, tmp_path: Path, link: str, what: str
) -> None:
    res = cli("check", links_scenario(tmp_path, stair2, echo2, [link]))
    assert res.code == 3 and "Traceback" not in res.err
    line = res.err.strip()
    assert "\n" not in line and "key 'connections[0]'" in line
    assert what in line
    assert "give the input a constant value under parameters" in line
