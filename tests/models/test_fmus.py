"""Every block of ``models/``: a valid FMU that runs alone and equals the in-process class.

Parametrised over the model registry, so a new block is covered as soon as it exists.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from cosim import models
from cosim.blocks import FmuHost, InProcessHost
from cosim.interop.references import MAX_STEPS, REFERENCE_DIR, drive, reference_run
from cosim.results import RunResult
from cosim.variables import REAL

BLOCKS = models.truth_models()
NAMES = sorted(BLOCKS)


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validate_reports_no_problem(fmu_dir: Path, name: str) -> None:
    assert validate_fmu(str(fmu_dir / f"{name}.fmu")) == []


@pytest.mark.parametrize("name", NAMES)
def test_units_and_start_values_are_declared(fmu_dir: Path, name: str) -> None:
    md = read_model_description(str(fmu_dir / f"{name}.fmu"))
    declared = {u.name for u in md.unitDefinitions}
    for v in md.modelVariables:
        if v.causality in ("output", "input", "parameter"):
            assert v.start is not None, f"{name}.{v.name} has no start value"
        if v.unit is not None:
            assert v.unit in declared
    assert md.coSimulation.modelIdentifier == name


@pytest.mark.parametrize("name", NAMES)
def test_runs_alone_under_fmpy_simulate(fmu_dir: Path, name: str) -> None:
    fmu = fmu_dir / f"{name}.fmu"
    md = read_model_description(str(fmu))
    result = simulate_fmu(str(fmu))
    n = round(float(md.defaultExperiment.stopTime) / float(md.defaultExperiment.stepSize))
    assert len(result) == n + 1
    outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type == REAL]
    for out in outputs:
        assert np.all(np.isfinite(result[out])), out


def test_fmpy_command_line_simulates_an_fmu_from_any_folder(fmu_dir: Path, tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = tmp_path / "gm.csv"
    proc = subprocess.run(
        [
            str(Path(sys.executable).with_name("fmpy")),
            "simulate",
            str(fmu_dir / "GaussMarkov2.fmu"),
            "--output-file",
            str(out),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().splitlines()[0] == '"time","x","x_dot"'


@pytest.mark.parametrize("name", NAMES)
def test_in_process_equals_fmu(fmu_dir: Path, name: str) -> None:
    cls = BLOCKS[name]
    h = cls.default_step
    n_steps = min(MAX_STEPS, round(cls.default_stop / h))
    a = drive(InProcessHost(name, cls), n_steps, h)
    b = drive(FmuHost(name, fmu_dir / f"{name}.fmu"), n_steps, h)
    assert a.dtype == b.dtype and len(a) == n_steps + 1
    for field in a.dtype.names:
        assert np.max(np.abs(a[field] - b[field])) <= 1e-12, field


@pytest.mark.parametrize("name", NAMES)
def test_matches_its_reference_result(name: str) -> None:
    """The output equals models/reference/<name>.csv (python -m cosim.interop.references)."""
    ref_file = REFERENCE_DIR / f"{name}.csv"
    assert ref_file.exists(), f"no reference for {name}: run `python -m cosim.interop.references`"
    ref = RunResult.load(ref_file).data
    now = reference_run(BLOCKS[name])
    assert ref.dtype.names == now.dtype.names
    for field in ref.dtype.names:
        np.testing.assert_allclose(now[field], ref[field], rtol=1e-12, atol=1e-300, err_msg=field)


def test_reset_reproduces_the_first_run(fmu_dir: Path) -> None:
    host = FmuHost("gm", fmu_dir / "GaussMarkov2.fmu")
    vr = [host.variables["x"].vr]

    def once() -> list[float]:
        host.setup(0.0, {"seed": 5})
        host.exit_init()
        out = []
        for n in range(50):
            host.do_step(n * 0.01, 0.01)
            out += host.get_real(vr)
        return out

    first = once()
    host.reset()
    second = once()
    host.terminate()
    assert first == second


@pytest.mark.parametrize("name", NAMES)
def test_every_model_has_a_readme_with_its_variables(name: str) -> None:
    doc = REFERENCE_DIR.parent / "docs" / f"{name}.md"
    assert doc.exists(), f"models/docs/{name}.md is missing"
    text = doc.read_text()
    for var in BLOCKS[name].variables:
        assert var.name in text, f"{name}.md does not mention {var.name}"
