"""The compiled step kernels (``models/native``) against the numpy code they replace.

Every compiled model gives the numbers of its numpy path (relative 1e-12 per value, the
tolerance of the reference files) in-process, over the reference drive and over the
transfer-alignment chain; and an FMU whose host lacks the compiled library (here: the
FMU's copy of ``models/`` without it, run by fmpy in a fresh interpreter, so the FMU
imports its own copy) runs the numpy path with the same numbers as the accelerated
in-process block.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import cosim
from benchmarks.monolithic import CHAIN_SCENARIO
from cosim import models
from cosim.blocks import InProcessHost
from cosim.interop.packaging import build_fmu
from cosim.interop.references import MAX_STEPS, REFERENCE_DIR, SEED, drive
from cosim.models import native
from cosim.results import RunResult
from cosim.scenario import build_master

COMPILED = ("LeverArm", "DeckFlexure", "StrapdownImu", "ShipMotion")
BLOCKS = models.truth_models()
RTOL = 1e-12  # the reference files' tolerance (tests/models/test_fmus.py)


def _reference_drive(name: str) -> np.ndarray:
    cls = BLOCKS[name]
    h = cls.default_step
    return drive(InProcessHost(name, cls), min(MAX_STEPS, round(cls.default_stop / h)), h)


def _assert_same(a: np.ndarray, b: np.ndarray, rtol: float = RTOL) -> None:
    assert a.dtype.names == b.dtype.names
    for field in a.dtype.names:
        np.testing.assert_allclose(a[field], b[field], rtol=rtol, atol=1e-300, err_msg=field)


def test_the_kernels_are_built_and_used() -> None:
    assert native.library_path().is_file()
    assert native.status().startswith("compiled kernels")
    for name in COMPILED:
        block = BLOCKS[name]()
        block.setup_experiment(0.0)
        block.exit_initialization_mode()
        assert block.compiled, name


def test_the_table_is_exactly_what_the_library_exports() -> None:
    """One declaration table: every kernel of ``KERNELS`` is exported by the library, and
    nothing else is (the sources mark kernels with ``KERNEL``, the build hides the rest)."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) is not installed")
    proc = subprocess.run(
        [nm, "-D", "--defined-only", str(native.library_path())],
        capture_output=True,
        text=True,
        check=True,
    )
    exported = {line.split()[-1] for line in proc.stdout.splitlines() if " T " in line}
    assert exported == {k.name for k in native.KERNELS}
    assert len(native.KERNELS) == len({k.name for k in native.KERNELS})


def test_each_kernel_source_sits_in_the_package_it_speeds_up() -> None:
    """The truth models' C beside the blocks, the filters' C beside the alignment code."""
    c_files, h_files = native.sources()
    wanted = {(k.package, k.source) for k in native.KERNELS}
    assert len(c_files) == len(wanted)
    root = Path(cosim.__file__).parent
    for k in native.KERNELS:
        folder = Path(models.__file__).parent if k.package.startswith("cosim.models") else root
        sub = (
            k.package.split(".")[2:]
            if k.package.startswith("cosim.models")
            else k.package.split(".")[1:]
        )
        assert folder.joinpath(*sub, k.source) in c_files, k
        text = folder.joinpath(*sub, k.source).read_text()
        assert f" {k.name}(" in text and "KERNEL" in text, k
    assert {h.name for h in h_files} == {"conventions.h", "kernel.h"}
    with pytest.raises(KeyError, match="no kernel 'nope'"):
        native.kernel("nope")


def test_the_switch_turns_them_off(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(native.ENV, "0")
    assert native.library() is None
    assert native.status() == f"numpy ({native.ENV}=0)"
    block = BLOCKS["LeverArm"]()
    block.setup_experiment(0.0)
    block.exit_initialization_mode()
    assert not block.compiled


@pytest.mark.parametrize("name", COMPILED)
def test_compiled_equals_numpy_on_the_reference_drive(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(native.ENV, "1")
    fast = _reference_drive(name)
    monkeypatch.setenv(native.ENV, "0")
    slow = _reference_drive(name)
    _assert_same(fast, slow)


@pytest.mark.parametrize("name", COMPILED)
def test_the_numpy_path_equals_the_reference_file(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """tests/models/test_fmus.py checks the default (compiled) path against the same file."""
    monkeypatch.setenv(native.ENV, "0")
    _assert_same(_reference_drive(name), RunResult.load(REFERENCE_DIR / f"{name}.csv").data)


def test_compiled_equals_numpy_over_the_transfer_chain(monkeypatch: pytest.MonkeyPatch) -> None:
    """20 s of the benchmark chain (2000 steps, flexure, IMU noise), every output."""
    runs = {}
    for mode in ("1", "0"):
        monkeypatch.setenv(native.ENV, mode)
        master = build_master(cosim.load_scenario(CHAIN_SCENARIO), stop=20.0)
        try:
            runs[mode] = master.run().data
        finally:
            master.terminate()
    assert len(runs["1"]) == 2001
    _assert_same(runs["1"], runs["0"])


# The child process: fmpy runs one FMU with the reference drive (cosim.interop.references),
# importing nothing of this repository itself, and prints its outputs and which path ran.
CHILD = """
import json, math, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

fmu, n_steps, h, seed = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
md = read_model_description(fmu)
unzipped = extract(fmu)
slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="child")
slave.instantiate()
slave.setupExperiment(startTime=0.0)
slave.enterInitializationMode()
for v in md.modelVariables:
    if v.name == "seed":
        slave.setInteger([v.valueReference], [seed])
slave.exitInitializationMode()
inputs = [v for v in md.modelVariables if v.causality == "input" and v.type == "Real"]
outputs = [v for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
out_vrs = [v.valueReference for v in outputs]
rows = [slave.getReal(out_vrs)]
for n in range(n_steps):
    t = n * h
    if inputs:
        values = [float(v.start or 0.0) + 1e-3 * math.sin(0.7 * (i + 1) * t + i)
                  for i, v in enumerate(inputs)]
        slave.setReal([v.valueReference for v in inputs], values)
    slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
    rows.append(slave.getReal(out_vrs))
path = sys.modules["cosim.models.native"]
print(json.dumps({"names": [v.name for v in outputs], "rows": rows,
                  "models": sys.modules["cosim.models"].__file__, "status": path.status()}))
slave.terminate()
"""


@pytest.fixture(scope="module")
def fmus_without_kernels(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The compiled models' FMUs, built as ``make fmus`` does, minus the compiled library."""
    out = tmp_path_factory.mktemp("native_fmus")
    stripped = {}
    for name in COMPILED:
        fmu = build_fmu(BLOCKS[name], out)
        with zipfile.ZipFile(fmu) as src:
            packed = [i.filename for i in src.infolist()]
            assert any(p.startswith("resources/cosim/models/native/build/kernels-") for p in packed)
            target = out / f"stripped_{name}.fmu"
            with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as dst:
                for item in src.infolist():
                    if not item.filename.startswith("resources/cosim/models/native/build/"):
                        dst.writestr(item, src.read(item))
        stripped[name] = target
    return stripped


@pytest.mark.parametrize("name", COMPILED)
def test_an_fmu_without_the_kernels_gives_the_compiled_numbers(
    name: str, fmus_without_kernels: dict[str, Path], tmp_path: Path
) -> None:
    cls = BLOCKS[name]
    h = cls.default_step
    n_steps = min(MAX_STEPS, round(cls.default_stop / h))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", native.ENV)}
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(fmus_without_kernels[name]), str(n_steps), str(h)]
        + [str(SEED)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    child = json.loads(proc.stdout.strip().splitlines()[-1])
    # the FMU ran its own copy of models/, on the numpy path, because the library is missing
    assert "resources" in Path(child["models"]).parts
    assert child["status"].startswith("numpy (compiled kernels unavailable"), child["status"]
    accelerated = _reference_drive(name)  # in-process, compiled (checked above)
    rows = np.array(child["rows"])
    assert rows.shape == (n_steps + 1, len(child["names"]))
    for j, field in enumerate(child["names"]):
        np.testing.assert_allclose(rows[:, j], accelerated[field], rtol=RTOL, atol=1e-300)


def test_without_a_compiler_the_models_run_numpy(tmp_path: Path) -> None:
    """A copy of the package with no library, in a process that finds no C compiler."""
    skip = shutil.ignore_patterns("build", "__pycache__")
    shutil.copytree(Path(cosim.__file__).parent, tmp_path / "cosim", ignore=skip)
    shutil.copytree(Path(models.__file__).parent, tmp_path / "cosim" / "models", ignore=skip)
    script = (
        "import sys; sys.path.insert(0, sys.argv[1])\n"
        "import cosim.models as models, cosim.models.native as n\n"
        "from cosim.models.blocks.lever_arm import LeverArm\n"
        "b = LeverArm(); b.setup_experiment(0.0); b.exit_initialization_mode()\n"
        "b.step(0.0, 0.01)\n"
        "print(models.__file__); print(b.compiled); print(n.status())\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("CC", "PYTHONPATH", native.ENV)}
    env["PATH"] = str(tmp_path / "no-compiler-here")
    proc = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    where, compiled, status = proc.stdout.strip().splitlines()[-3:]
    assert Path(where).parent == tmp_path / "cosim" / "models"
    assert compiled == "False"
    assert status.startswith("numpy (compiled kernels unavailable: no C compiler"), status
    assert not list(tmp_path.rglob("kernels-*.so"))
