"""Issue 30, item 2: FMI 3 array variables as scalars (cosim.arrays).

C fixtures compiled in the test run: ``statespace3`` (shaped like the Reference-FMUs'
StateSpace: ``A``, ``B``, ``C``, ``D``, ``x0`` two- and one-dimensional parameter arrays
whose sizes are structural parameters, ``u``, ``y``, ``x`` arrays; one explicit Euler
step per communication step) and ``vec3`` (Float64, Float32 and Int32 arrays fed
through). Shown here: array parameters set from TOML lists (nested for two dimensions),
the closed-form result of the state-space system, whole-array and element connections,
recordings by element, and one-line refusals of shape mismatches.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.arrays import element_names, element_starts, nested_values
from cosim.interop.cbuild import build_c_fmu

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
H, STOP = 0.125, 2.0
A = np.array([[-1.0, 0.5, 0.0], [0.0, -2.0, 0.0], [0.25, 0.0, -0.5]])  # the fixture's start
B = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])


@pytest.fixture(scope="module")
def ss3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ss3") / "StateSpace3.fmu"
    return build_c_fmu(FIXTURES / "statespace3", out)


@pytest.fixture(scope="module")
def vec3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_c_fmu(FIXTURES / "vec3", tmp_path_factory.mktemp("vec3") / "Vec3.fmu")


def closed_form(x0: np.ndarray, u: np.ndarray, D: np.ndarray, k: int) -> tuple:
    """x_k = M^k x0 + sum_{j<k} M^j h B u with M = I + hA (explicit Euler, constant u)."""
    M = np.eye(3) + H * A
    x = np.linalg.matrix_power(M, k) @ x0
    x += sum(np.linalg.matrix_power(M, j) for j in range(k)) @ (H * B @ u) if k else 0.0
    return x, C @ x + D @ u


def test_the_state_space_fmu_equals_the_closed_form(ss3: Path, tmp_path: Path) -> None:
    path = tmp_path / "ss.toml"
    path.write_text(
        f'[master]\nstep = {H}\nstop = {STOP}\n[blocks.ss]\nfmu = "{ss3}"\n'
        "parameters = { u = [1.0, -0.5], D = [[1, 0], [0, 2]], x0 = [0.5, -1, 2] }\n"
    )
    res = cosim.run(path)
    assert res.names == ["time", "ss.y[1]", "ss.y[2]", "ss.x[1]", "ss.x[2]", "ss.x[3]"]
    assert res["ss.x"].shape == (round(STOP / H) + 1, 3)
    u, D, x0 = np.array([1.0, -0.5]), np.diag([1.0, 2.0]), np.array([0.5, -1.0, 2.0])
    for k in range(len(res.data)):
        x, y = closed_form(x0, u, D, k)
        np.testing.assert_allclose(res["ss.x"][k], x, rtol=0, atol=1e-13)
        np.testing.assert_allclose(res["ss.y"][k], y, rtol=0, atol=1e-13)
    assert res["ss.x"][-1, 2] != res["ss.x"][0, 2]  # it moved


def test_the_state_space_fmu_equals_fmpys_simulate_fmu(ss3: Path, tmp_path: Path) -> None:
    """fmpy sets the same arrays itself (start values as flat lists, row-major) and steps
    the FMU alone: every element of ``x`` and ``y`` agrees bit for bit (clock = "fmpy")."""
    from fmpy import simulate_fmu

    path = tmp_path / "ss.toml"
    path.write_text(
        f'[master]\nstep = {H}\nstop = {STOP}\nclock = "fmpy"\n[blocks.ss]\nfmu = "{ss3}"\n'
        "parameters = { u = [1.0, -0.5], D = [[1, 0], [0, 2]], x0 = [0.5, -1, 2] }\n"
    )
    ours = cosim.run(path)
    start = {"u": [1.0, -0.5], "D": [1.0, 0.0, 0.0, 2.0], "x0": [0.5, -1.0, 2.0]}
    theirs = simulate_fmu(str(ss3), stop_time=STOP, output_interval=H, start_values=start)
    assert ours["ss.x"].tobytes() == np.ascontiguousarray(theirs["x"]).tobytes()
    assert ours["ss.y"].tobytes() == np.ascontiguousarray(theirs["y"]).tobytes()


def test_a_renamed_two_dimensional_array_is_set_under_its_new_name(
    ss3: Path, tmp_path: Path
) -> None:
    path = tmp_path / "renamed.toml"
    path.write_text(
        f'[master]\nstep = {H}\nstop = {H}\n[blocks.ss]\nfmu = "{ss3}"\n'
        'rename = { C = "C_y_x" }\nparameters = { C_y_x = [[2, 0, 0], [0, 0, 0]] }\n'
        'unconnected_ok = ["u"]\n'
    )
    res = cosim.run(path)
    assert res["ss.y[1]"][0] == 2.0 and res["ss.y[2]"][0] == 0.0  # C x0 with x0 = (1, 0, 0)


def test_a_two_dimensional_parameter_in_the_wrong_shape_is_one_line(
    cli, ss3: Path, tmp_path: Path
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(
        f'[master]\nstep = {H}\nstop = {STOP}\n[blocks.ss]\nfmu = "{ss3}"\n'
        "parameters = { B = [[1, 0, 0], [0, 1, 1]] }\n"
    )
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err
    line = res.err.strip()
    assert "\n" not in line and "key 'blocks.ss.parameters.B'" in line
    assert "'B' is an array of shape (3, 2); expected nested lists of that shape" in line
    assert "got shape (2, 3)" in line


def test_elements_and_whole_arrays_connect_and_record(
    vec3: Path, ss3: Path, tmp_path: Path
) -> None:
    """``v.y[3] -> ss.u[1]`` (one element; ``ss.u[2]`` set on its own) and ``v.z -> v2.u[1..2]``
    style whole links: the state-space block sees the constant ``k3 u3`` and its closed
    form holds; the element columns are recorded under their names."""
    path = tmp_path / "links.toml"
    path.write_text(
        'connections = ["v.y[3] -> ss.u[1]"]\n'
        f"[master]\nstep = {H}\nstop = {STOP}\n"
        f'[blocks.v]\nfmu = "{vec3}"\nparameters = {{ k = [1, 1, 1.5], u = [0, 0, 2] }}\n'
        "unconnected_ok = ['f', 'n']\n"
        f'[blocks.ss]\nfmu = "{ss3}"\nparameters = {{ "u[2]" = -0.5 }}\n'
        '[output]\nvariables = ["v.y[3]", "ss.x", "ss.y[2]"]\n'
    )
    res = cosim.run(path)
    assert res.names == ["time", "v.y[3]", "ss.x[1]", "ss.x[2]", "ss.x[3]", "ss.y[2]"]
    assert set(res["v.y[3]"]) == {3.0}
    u, D, x0 = np.array([3.0, -0.5]), np.zeros((2, 2)), np.array([1.0, 0.0, 0.0])
    for k in range(len(res.data)):
        x, y = closed_form(x0, u, D, k)
        np.testing.assert_allclose(res["ss.x"][k], x, rtol=0, atol=1e-13)
        np.testing.assert_allclose(res["ss.y[2]"][k], y[1], rtol=0, atol=1e-13)


def test_a_whole_array_link_of_another_shape_is_one_line(
    cli, vec3: Path, ss3: Path, tmp_path: Path
) -> None:
    path = tmp_path / "shape.toml"
    path.write_text(
        'connections = ["v.y -> ss.u"]\n'
        f'[master]\nstep = {H}\nstop = {STOP}\n[blocks.v]\nfmu = "{vec3}"\n'
        f'[blocks.ss]\nfmu = "{ss3}"\n'
    )
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err
    line = res.err.strip()
    assert "\n" not in line and "key 'connections[0]'" in line
    assert "'v.y' and 'ss.u' have shapes (3,) and (2,)" in line
    assert "connect arrays of equal shape, or elements one by one" in line


def test_reset_puts_the_array_inputs_back_on_their_start_values(vec3: Path, tmp_path: Path) -> None:
    """An element set in one run does not leak into the next (campaigns reset blocks)."""
    from cosim.scenario import build_master

    path = tmp_path / "reset.toml"
    path.write_text(
        f'[master]\nstep = {H}\nstop = 0.5\n[blocks.v]\nfmu = "{vec3}"\n'
        'parameters = { "u[1]" = 4.0 }\nunconnected_ok = ["u", "f", "n"]\n'
    )
    master = build_master(path)
    try:
        first = master.run()
        master.system.parameters["v"] = {}
        master.reset()
        second = master.run()
    finally:
        master.terminate()
    assert set(first["v.y[1]"]) == {4.0}
    assert set(second["v.y[1]"]) == {0.0}  # the start value again


def test_element_names_starts_and_nested_values() -> None:
    assert list(element_names("x", (3,))) == ["x[1]", "x[2]", "x[3]"]
    assert list(element_names("A", (2, 2))) == ["A[1,1]", "A[1,2]", "A[2,1]", "A[2,2]"]
    assert element_starts("1 0 0.5", "Float64", 3) == [1.0, 0.0, 0.5]
    assert element_starts("2", "Int32", 3) == [2, 2, 2]
    assert element_starts("true false", "Boolean", 2) == [True, False]
    assert element_starts(None, "Float64", 2) == [None, None]

    def error(message: str) -> Exception:
        return ValueError(message)

    class Element:
        def __init__(self, shape: tuple[int, ...]) -> None:
            from cosim.variables import ArrayElement

            self.element = ArrayElement("A", 4, 0, shape)
            self.name = "A[1,1]"

    scalars = [Element((2, 3))] * 6
    assert nested_values([[1, 2, 3], [4, 5, 6]], scalars, error) == [1, 2, 3, 4, 5, 6]
    assert nested_values(7.0, scalars, error) == 7.0  # not a nested list: left as it is
    with pytest.raises(ValueError, match=r"shape \(2, 3\).*got shape ragged lists"):
        nested_values([[1, 2, 3], [4, 5]], scalars, error)
    with pytest.raises(ValueError, match=r"got shape \(3, 2\)"):
        nested_values([[1, 2], [3, 4], [5, 6]], scalars, error)
