"""Every block of ``models/``: a valid FMU that runs alone and equals the in-process class.

Parametrised over the model registry, so a new block is covered as soon as it exists.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

import models
from cosim.blocks import REAL, BlockHost, FmuHost, InProcessHost

BLOCKS = models.registry()
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


def _drive(host: BlockHost, n_steps: int, h: float) -> np.ndarray:
    """Run one block with its default parameters (seed 1234) and deterministic inputs."""
    params = {"seed": 1234} if "seed" in host.variables else {}
    inputs = [v for v in host.by_causality("input") if v.type == REAL]
    outputs = [v for v in host.by_causality("output") if v.type == REAL]
    host.setup(0.0, params)
    host.exit_init()
    rows = [host.get_real([v.vr for v in outputs])]
    for n in range(n_steps):
        t = n * h
        values = [
            (v.start or 0.0) + 1e-3 * math.sin(0.7 * (i + 1) * t + i) for i, v in enumerate(inputs)
        ]
        if inputs:
            host.set_real([v.vr for v in inputs], values)
        host.do_step(t, h)
        rows.append(host.get_real([v.vr for v in outputs]))
    host.terminate()
    return np.array(rows)


@pytest.mark.parametrize("name", NAMES)
def test_in_process_equals_fmu(fmu_dir: Path, name: str) -> None:
    cls = BLOCKS[name]
    h = cls.default_step
    n_steps = min(200, round(cls.default_stop / h))
    a = _drive(InProcessHost(name, cls), n_steps, h)
    b = _drive(FmuHost(name, fmu_dir / f"{name}.fmu"), n_steps, h)
    assert a.shape == b.shape and a.shape[0] == n_steps + 1
    assert np.max(np.abs(a - b), initial=0.0) <= 1e-12


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
