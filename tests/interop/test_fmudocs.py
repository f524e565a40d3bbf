"""Issue 27, item 2: our FMUs for plain fmpy users (fast checks; the plain-fmpy virtual
environment is in ``tests/integration/test_install.py``, slow).

Each FMU carries its own model page as its FMI ``documentation/index.html`` and nothing
it does not run; step-dependent inputs and the perfect default IMU are said where an
fmpy user reads (the modelDescription and the page), and the statements are true: the
rule the description gives makes the outputs independent of the step, and the default
instance outputs its inputs unchanged.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from cosim.interop.fmudocs import markdown_to_html
from cosim.interop.modeldocs import STEP_DEPENDENT
from cosim.interop.packaging import needed_modules
from cosim.models import truth_models

ROOT = Path(__file__).resolve().parents[2]
NAMES = sorted(truth_models())


def test_the_renderer_keeps_headings_tables_code_and_escapes_the_rest() -> None:
    page = markdown_to_html(
        "# Model\n\nA `x < y` **rule**.\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n"
        "```python\nif a < b:\n    pass\n```\n\n- one\n- two\n",
        "Model",
    )
    assert "<h1>Model</h1>" in page
    assert "<p>A <code>x &lt; y</code> <strong>rule</strong>.</p>" in page
    assert "<table><tr><th>a</th><th>b</th></tr><tr><td>1</td><td>2</td></tr></table>" in page
    assert '<pre><code class="language-python">if a &lt; b:\n    pass</code></pre>' in page
    assert "<ul><li>one</li><li>two</li></ul>" in page


@pytest.mark.parametrize("name", NAMES)
def test_each_fmu_carries_its_own_page_and_only_what_it_runs(name: str, fmu_dir: Path) -> None:
    """Was: no documentation folder, and every 1.6 MB FMU carried all twelve pages, the
    reference results and the filter's C sources."""
    fmu = fmu_dir / f"{name}.fmu"
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
        page = z.read("documentation/index.html").decode()
    assert f"<h1>{name}</h1>" in page and "With plain fmpy" in page
    others = [n for n in NAMES if n != name and f"<h1>{n}</h1>" in page]
    assert not others
    assert not [n for n in names if n.endswith((".c", ".h", ".md", ".csv"))]
    assert not [n for n in names if "/docs/" in n or "/reference/" in n]
    needed = needed_modules(Path(sys.modules[truth_models()[name].__module__].__file__))
    packed = {
        n.removeprefix("resources/cosim/models/").removesuffix(".py")
        for n in names
        if n.startswith("resources/cosim/models/") and n.endswith(".py")
    }
    assert packed == needed  # e.g. no strapdown_imu.py in FirstOrderSensor.fmu
    kernels = [n for n in names if n.startswith("resources/cosim/models/native/build/kernels-")]
    assert len(kernels) == ("native/__init__" in needed)  # the compiled library, not its sources
    assert fmu.stat().st_size < 1_000_000  # was 1.6 MB


def test_step_dependent_inputs_are_said_so_and_the_rule_given_holds(fmu_dir: Path) -> None:
    """Was: with another output_interval the specific force came out 10 times too small
    without a word. Fed as the descriptions say (increment = rate * h of each step), a
    perfect IMU measures the same specific force at h = 10 ms and h = 1 ms."""
    fmu = fmu_dir / "StrapdownImu.fmu"
    md = read_model_description(str(fmu))
    described = {v.name: v.description or "" for v in md.modelVariables}
    for name in ("dtheta_b[1]", "dv_b[3]"):
        assert STEP_DEPENDENT in described[name] and "not a" in described[name]
    assert "dtheta_b" in (ROOT / "docs" / "fmpy_users.md").read_text()
    f_z = -9.80665  # m/s2, a level IMU at rest (down axis)
    measured = {}
    for h in (0.01, 0.001):
        signal = np.array(
            [(0.0, f_z * h), (1.0, f_z * h)], dtype=[("time", float), ("dv_b[3]", float)]
        )
        out = simulate_fmu(
            str(fmu), stop_time=0.1, output_interval=h, input=signal, output=["f_meas_b[3]"]
        )
        measured[h] = out["f_meas_b[3]"][-1]
    assert measured[0.01] == pytest.approx(f_z, rel=1e-12)
    assert measured[0.001] == pytest.approx(f_z, rel=1e-12)


def test_the_default_grade_is_described_as_a_perfect_imu_and_is_one(fmu_dir: Path) -> None:
    """Was: ``grade = 0`` made a perfect IMU without saying so. The description says it;
    the default instance outputs its inputs unchanged, grade 2 (tactical) does not."""
    fmu = fmu_dir / "StrapdownImu.fmu"
    md = read_model_description(str(fmu))
    (grade,) = [v for v in md.modelVariables if v.name == "grade"]
    assert grade.start in ("0", 0) and "PERFECT" in grade.description
    h, dv = 0.01, 0.123
    signal = np.array([(0.0, dv), (1.0, dv)], dtype=[("time", float), ("dv_b[1]", float)])
    outputs = {}
    for g in (0, 2):
        out = simulate_fmu(
            str(fmu),
            stop_time=0.5,
            output_interval=h,
            input=signal,
            start_values={"grade": g, "seed": 5},
            output=["dv_meas_b[1]"],
        )
        outputs[g] = out["dv_meas_b[1]"][1:]
    assert np.all(outputs[0] == dv)
    assert np.all(outputs[2] != dv)


def test_every_package_folder_is_listed_in_pyproject() -> None:
    """The wheel lists its packages (models/ installs as cosim.models): a new folder of
    cosim/ or models/ must be listed too, or the wheel would lack it."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    mapped = config["package-dir"]
    found = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for p in (ROOT / "cosim").rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    found |= {
        ".".join(("cosim", *p.parent.relative_to(ROOT).parts))
        for p in (ROOT / "models").rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    assert found <= listed, sorted(found - listed)
    assert not [p for p in listed if p.split(".")[0] != "cosim"]
    assert mapped["cosim.models"] == "models"
    assert (ROOT / mapped["cosim.package_data.interfaces"] / "imu.toml").is_file()
    assert (ROOT / mapped["cosim.package_data.scenarios"] / "sins_north_finding.toml").is_file()


TOGETHER = r"""
import json, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

slaves = []
for path in sys.argv[1:]:
    md = read_model_description(path)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(path),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=md.modelName)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    slaves.append(slave)
for n in range(10):
    for slave in slaves:
        slave.doStep(currentCommunicationPoint=n * 0.01, communicationStepSize=0.01)
print(json.dumps(sorted(m for m in sys.modules if m.startswith("cosim"))))
"""


def test_fmus_that_carry_different_modules_run_together_in_one_plain_process(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """Each FMU carries only its model's modules; several alive in one Python (as in an
    fmpy script or libcosim) find each other's modules, none of ins-cosim imported."""
    names = ("GaussMarkov2", "FirstOrderSensor", "StrapdownImu")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    proc = subprocess.run(
        [sys.executable, "-c", TOGETHER, *(str(fmu_dir / f"{n}.fmu") for n in names)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    assert {"cosim.models.blocks.first_order_sensor", "cosim.models.blocks.strapdown_imu"} <= set(
        loaded
    )
    assert "cosim.scenario" not in loaded  # the FMUs' stub, not the installed package
