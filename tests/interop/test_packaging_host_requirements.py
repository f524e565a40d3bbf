"""Issue 16, item 6: our FMUs say what they need from the host.

An FMU made by ``cosim.interop.packaging`` runs its model in the Python interpreter that
loads it, which needs numpy and scipy (pythonfmu's runtime is packed inside the FMU:
issue 27 found the old "needs pythonfmu" untrue, and a test below shows it). A host
without one of them used to get "Failed to instantiate model" and nothing else
(pythonfmu 0.7 logs only with debug logging on). Now ``fmi2Instantiate`` sends one
error-level message through the host's logger callback, with debug logging *off*,
naming the package and the install command, and fails.

Tested for real, without a fresh virtual environment: the FMU is loaded by fmpy in a
child Python whose import system refuses the package (a ``sys.meta_path`` finder raising
``ModuleNotFoundError``, exactly what a missing package raises), with fmpy's own
``FMU2Slave`` and a logger callback of ours. The same child without the finder
instantiates the FMU and logs nothing, so the message comes from the missing package.
(numpy cannot be refused this way: fmpy itself imports it; the FMU takes the same path
for any missing package.)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.interop.packaging import REQUIREMENTS, build_fmu
from cosim.models.blocks.gauss_markov import GaussMarkov2

CHILD = r"""
import importlib.abc, json, sys

import importlib.machinery

blocked = sys.argv[2]
# "pythonfmu:installed" refuses only the installed pythonfmu (site-packages): an FMU's own
# copy in its resources stays importable, as on a host that never installed pythonfmu.
blocked, _, scope = blocked.partition(":")


class Refuse(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if blocked and (name == blocked or name.startswith(blocked + ".")):
            if scope == "installed" and name == blocked:
                outside = [p for p in sys.path if "site-packages" not in p]
                spec = importlib.machinery.PathFinder.find_spec(name, outside)
                if spec is not None:
                    return spec
            elif scope == "installed":
                return None
            raise ModuleNotFoundError(f"No module named '{name}'", name=name)
        return None


sys.meta_path.insert(0, Refuse())
from fmpy import extract, read_model_description
from fmpy.fmi2 import (FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)

messages = []


def logger(component, instance, status, category, message):
    messages.append([status, (category or b"").decode(), message.decode()])


callbacks = fmi2CallbackFunctions()
callbacks.logger = fmi2CallbackLoggerTYPE(logger)
callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
md = read_model_description(sys.argv[1])
fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(sys.argv[1]),
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="flexure")
try:
    fmu.instantiate(callbacks=callbacks, loggingOn=False)
    instantiated = True
except Exception:
    instantiated = False
out = {"instantiated": instantiated, "messages": messages}
if instantiated and scope:
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
    out["stepped"] = True
    out["pythonfmu"] = sys.modules["pythonfmu"].__file__
print(json.dumps(out))
sys.stdout.flush()
"""


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_fmu(GaussMarkov2, tmp_path_factory.mktemp("host"))


def load_without(fmu: Path, package: str, tmp_path: Path) -> dict:
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.run(
        [sys.executable, str(script), str(fmu), package],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("package", ["scipy"])
def test_a_missing_package_is_an_error_level_message_from_instantiate(
    fmu: Path, package: str, tmp_path: Path
) -> None:
    got = load_without(fmu, package, tmp_path)
    assert got["instantiated"] is False
    assert len(got["messages"]) == 1, got["messages"]  # debug logging is off
    status, category, message = got["messages"][0]
    assert status == 3 and category == "logStatusError"  # fmi2Error
    assert f"GaussMarkov2.fmu needs the Python package '{package}'" in message
    assert f"{sys.executable} -m pip install {package}" in message
    assert "(this FMU needs numpy, scipy)" in message


def test_with_every_package_the_fmu_instantiates_and_says_nothing(
    fmu: Path, tmp_path: Path
) -> None:
    got = load_without(fmu, "", tmp_path)
    assert got == {"instantiated": True, "messages": []}


def test_a_host_without_pythonfmu_runs_the_fmu_on_the_copy_inside_it(
    fmu: Path, tmp_path: Path
) -> None:
    """Issue 27: the message said pythonfmu was needed on the host; it is not."""
    got = load_without(fmu, "pythonfmu:installed", tmp_path)
    assert got["instantiated"] is True and got["messages"] == []
    assert got["stepped"] is True
    assert "resources" in Path(got["pythonfmu"]).parts  # the FMU's own pythonfmu
    assert "pythonfmu" not in REQUIREMENTS


def test_ins_cosim_fmus_states_the_host_requirements(cli, fmu: Path) -> None:
    res = cli("fmus", "--dir", fmu.parent)
    assert res.code == 0, res.err
    assert "GaussMarkov2.fmu" in res.out
    assert "needs numpy and scipy (pip install numpy scipy)" in res.out
    assert "pythonfmu's runtime is inside each FMU" in res.out
    assert f"pip install {' '.join(REQUIREMENTS)}" in res.out
