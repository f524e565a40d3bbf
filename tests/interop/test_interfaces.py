"""Role interface specs (fmus/interfaces/*.toml) and the role matcher.

Every model a spec names must fill its role under its own names and units, so the
specs and the models cannot drift apart.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim import models
from cosim.blocks import InProcessHost
from cosim.errors import FmuError
from cosim.interop.interfaces import InterfaceError, available_roles, load_role, match_role
from cosim.variables import Variable, apply_rename

ROLES = ["accelerometer", "flexure", "hrg_gyro", "imu", "master_ins", "motion"]
# every spec, including any added later, is checked against the models it names
PAIRS = [(role, model) for role in available_roles() for model in load_role(role).models]


def test_the_six_roles_are_specified() -> None:
    assert set(ROLES) <= set(available_roles())
    for role in available_roles():
        spec = load_role(role)
        assert spec.name == role and spec.models and spec.description
        assert any(v.required for v in spec.variables)


@pytest.mark.parametrize("role, model", PAIRS, ids=[f"{r}-{m}" for r, m in PAIRS])
def test_our_models_fill_their_roles_exactly(role: str, model: str) -> None:
    spec = load_role(role)
    host = InProcessHost(model.lower(), models.truth_models()[model])
    try:
        match = match_role(host.variables, spec, suggest=False)
    finally:
        host.terminate()
    assert match.satisfied, match.problems
    assert not match.needs_rename and not match.warnings
    for entry in match.entries:
        if not match.required(entry) and entry.variable.form:
            assert entry.fmu is None, entry.role_name  # the other input form
            continue
        # every role variable exists in the model under its name, with the same unit
        assert entry.how == "exact", entry.role_name
        assert entry.fmu is not None and entry.fmu.unit == entry.variable.unit
        assert entry.factor in (None, 1.0)


def test_a_model_of_another_kind_does_not_fill_the_role() -> None:
    host = InProcessHost("table", models.truth_models()["Turntable"])
    try:
        match = match_role(host.variables, load_role("motion"))
    finally:
        host.terminate()
    assert not match.satisfied
    assert "lat: missing (required output, rad): the FMU has no variable for it" in match.problems
    assert any(p.startswith("v_n[1]: missing") for p in match.problems)
    # its inputs are named like motion outputs: found by name, refused for causality
    assert "dtheta_b[1] <- 'dtheta_b[1]': causality is 'input', expected 'output'" in (
        match.problems
    )
    assert not [e for e in match.entries if e.how == "suggested"]  # nothing alike to offer


def test_unknown_role_lists_the_known_ones() -> None:
    with pytest.raises(InterfaceError, match=r"unknown role 'imus'\. Did you mean 'imu'\?"):
        load_role("imus")


def test_malformed_spec_names_file_and_key(tmp_path: Path) -> None:
    spec = tmp_path / "bad.toml"
    spec.write_text(
        '[role]\nname = "bad"\n[[variables]]\nname = "x"\ncausality = "inout"\nunit = "rad"\n'
    )
    with pytest.raises(
        InterfaceError,
        match=r"bad\.toml, key 'variables\[0\]\.causality': expected input or output or "
        r"parameter, got 'inout'",
    ):
        load_role(spec)


def var(name: str, causality: str, unit: str, vr: int, vtype: str = "Real") -> Variable:
    return Variable(name, vr, vtype, causality, "continuous", unit)


def test_rename_maps_scalars_and_vector_bases() -> None:
    variables = {
        v.name: v
        for v in [
            var("rate_x", "output", "deg/s", 1),
            var("acc[1]", "output", "g", 2),
            var("acc[2]", "output", "g", 3),
        ]
    }
    out = apply_rename(variables, {"rate_x": "omega_meas_b[1]", "acc": "f_meas_b"}, "fmu")
    assert list(out) == ["omega_meas_b[1]", "f_meas_b[1]", "f_meas_b[2]"]
    assert out["f_meas_b[2]"].fmu_name == "acc[2]" and out["f_meas_b[2]"].vr == 3
    with pytest.raises(FmuError, match=r"expected a variable of the FMU, got 'rate_y'.*rate_x"):
        apply_rename(variables, {"rate_y": "x"}, "fmu")
    with pytest.raises(FmuError, match="'acc\\[1\\]' and 'rate_x' would both be called 'a'"):
        apply_rename(variables, {"rate_x": "a", "acc[1]": "a"}, "fmu")
    with pytest.raises(FmuError, match="expected a new name like"):
        apply_rename(variables, {"rate_x": "omega meas"}, "fmu")


def test_suggestions_group_axes_and_respect_units() -> None:
    # camelCase axes, a second rate-like group (a bias parameter) that must not be taken
    variables = {
        v.name: v
        for v in [
            *(var(f"dAngle{a}", "output", "deg", i) for i, a in enumerate("XYZ")),
            *(var(f"dVel{a}", "output", "m/s", 10 + i) for i, a in enumerate("XYZ")),
            *(var(f"in_dtheta_{i}", "input", "rad", 20 + i) for i in (1, 2, 3)),
            *(var(f"in_dv_{i}", "input", "m/s", 30 + i) for i in (1, 2, 3)),
            *(var(f"gyro_bias_{a}", "parameter", "deg/h", 40 + i) for i, a in enumerate("xyz")),
        ]
    }
    match = match_role(variables, load_role("imu"))
    assert match.satisfied, match.problems
    assert match.rename["dAngleZ"] == "dtheta_meas_b[3]"
    assert match.rename["dVelX"] == "dv_meas_b[1]"
    assert match.rename["in_dtheta_2"] == "dtheta_b[2]"
    assert match.rename["in_dv_3"] == "dv_b[3]"
    assert "gyro_bias_x" not in match.rename  # a parameter is no truth output
    factors = {e.role_name: e.factor for e in match.entries if e.fmu is not None}
    assert factors["dtheta_meas_b[1]"] == pytest.approx(0.017453292519943295, rel=1e-15)
