"""Shared fixtures: FMUs built fresh for the session, and a CLI runner."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent

# A shell that starts the suite in the background (`make test &`, nohup, some CI runners)
# starts it with SIGINT ignored, and an ignored signal stays ignored in every child: the
# tests of Ctrl-C would then send a signal nobody receives. Python's own handler is put
# back here; children started from a process that handles SIGINT get the default again.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Every model of ``models/`` built into FMUs by the same code as ``make fmus``."""
    from cosim.interop.packaging import build_all

    out = tmp_path_factory.mktemp("fmus")
    build_all(out)
    return out


@pytest.fixture(scope="session")
def faulty_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The ``testblocks.Faulty`` block as an FMU (fails on purpose)."""
    from testblocks import Faulty

    from cosim.interop.packaging import build_fmu

    out = tmp_path_factory.mktemp("faulty")
    return build_fmu(Faulty, out, extra_files=(TESTS / "testblocks.py",))


@pytest.fixture(scope="session")
def vendor_imu_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The C vendor IMU of ``fmus/vendor_example`` compiled into a binary FMU 2.0."""
    from cosim.interop.cbuild import build_c_fmu

    out = tmp_path_factory.mktemp("vendor_imu")
    return build_c_fmu(ROOT / "fmus" / "vendor_example", out / "VendorImu.fmu")


@pytest.fixture(scope="session")
def fmi3_ramp_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The FMI 3.0 co-simulation fixture ``tests/fixtures/fmi3_ramp`` compiled from C."""
    from cosim.interop.cbuild import build_c_fmu

    out = tmp_path_factory.mktemp("fmi3_ramp")
    return build_c_fmu(TESTS / "fixtures" / "fmi3_ramp", out / "Ramp.fmu")


@dataclass
class CliResult:
    code: int
    out: str
    err: str


@pytest.fixture
def cli(tmp_path: Path):
    """Run ``ins-cosim`` in a subprocess, as a user would (tests/ on the path for fixtures)."""

    def run(*args: str) -> CliResult:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(TESTS), env.get("PYTHONPATH", "")])
        proc = subprocess.run(
            [sys.executable, "-m", "cosim.cli", *map(str, args)],
            capture_output=True,
            text=True,
            cwd=tmp_path,
            env=env,
            timeout=300,
        )
        return CliResult(proc.returncode, proc.stdout, proc.stderr)

    return run


#: Timeout of a slow test that states none [s]. The global 600 s (pyproject) guards the
#: default suite against a hang; the slow acceptance campaigns (50-100 runs of 100-600 s)
#: take 5-40 minutes on an idle 2-core machine and several times that on a shared one.
SLOW_TIMEOUT = 4 * 3600


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Give every ``slow`` test without a ``timeout`` marker :data:`SLOW_TIMEOUT`."""
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT))
