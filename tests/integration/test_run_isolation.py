"""``ins-cosim run --isolate``: an FMU that kills its process leaves its partial results
(issue 14, item 2, the isolation mode).

The C fixture ``tests/fixtures/abort2`` (compiled here with :mod:`cosim.interop.cbuild`)
calls ``abort()`` in the step from ``abort_at`` on. Without isolation that takes the
command with it (SIGABRT, exit 134 from a shell, nothing written); with ``--isolate``
the run happens in a child process that streams every recorded row, and the command
writes the rows recorded before the crash with a note naming the block, the time and
the signal, and exits with 4 (a run that stopped). (Without it, the same scenario ends
``ins-cosim run`` with SIGABRT, exit 134 in a shell, and writes nothing.)
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import UserError
from cosim.interop.cbuild import build_c_fmu
from cosim.isolate import IsolatedRunError, run_isolated
from cosim.results import RunResult

TESTS = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bomb_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bomb")
    return build_c_fmu(TESTS / "fixtures" / "abort2", out / "Bomb.fmu")


def scenario(tmp_path: Path, fmu: Path, name: str = "bomb.toml", **bomb: str) -> Path:
    params = ", ".join(f'{k} = "{v}"' for k, v in bomb.items())
    path = tmp_path / name
    path.write_text(
        '[master]\nstep = "10 ms"\nstop = "2 s"\n\n'
        '[blocks.flexure]\nmodel = "GaussMarkov2"\n'
        'parameters = { tau = "60 s", sigma = "2 arcmin", seed = 7 }\n\n'
        f'[blocks.bomb]\nfmu = "{fmu}"\nparameters = {{ {params} }}\n'
    )
    return path


def run_cli(tmp_path: Path, *args: object) -> subprocess.CompletedProcess:
    tmp = tmp_path / "tmp"  # where the FMUs are unpacked (a killed process leaves its own)
    tmp.mkdir(exist_ok=True)
    return subprocess.run(
        [sys.executable, "-m", "cosim.cli", "run", *map(str, args), "--no-plot"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=dict(os.environ, TMPDIR=str(tmp)),
        timeout=300,
    )


def test_an_fmu_that_aborts_leaves_its_partial_results_under_isolate(
    tmp_path: Path, bomb_fmu: Path
) -> None:
    path = scenario(tmp_path, bomb_fmu, abort_at="1.23 s")
    res = run_cli(tmp_path, path, "--out", tmp_path / "out", "--isolate")
    assert res.returncode == 4, (res.stdout, res.stderr)  # README: a run that stopped
    assert "Traceback" not in res.stderr
    error, saved = res.stderr.strip().splitlines()
    assert error.startswith("error: the isolated simulation process")
    for part in ("killed by signal SIGABRT (6)", "block 'bomb' was stepping from t = 1.23 s"):
        assert part in error
    assert "124 row(s) recorded up to t = 1.23 s are kept" in error
    assert saved.startswith("results recorded up to the failure are in")
    assert "running 'bomb': 2 blocks, 200 steps" in res.stdout
    partial = RunResult.load(tmp_path / "out" / "results.csv")
    assert partial.status == "failed" and partial.metadata["isolated"] is True
    assert partial.metadata["crashed"] == {
        "exit_code": -6,
        "how": "killed by signal SIGABRT (6)",
        "block": "bomb",
        "time": 1.23,
    }
    np.testing.assert_allclose(partial.time, np.arange(124) * 0.01, rtol=0, atol=1e-12)
    # every row is the row of an uninterrupted run (the FMU only aborts: same numbers)
    full = cosim.run(scenario(tmp_path, bomb_fmu, "whole.toml"))
    for name in full.names:
        np.testing.assert_array_equal(partial[name], full[name][:124])
    assert json.loads((tmp_path / "out" / "results.json").read_text())["rows"] == 124


def test_an_isolated_run_gives_the_numbers_and_errors_of_a_plain_one(
    tmp_path: Path, bomb_fmu: Path
) -> None:
    path = scenario(tmp_path, bomb_fmu)
    cosim.run(path).save(tmp_path / "here")
    apart = run_cli(tmp_path, path, "--out", tmp_path / "apart", "--isolate")
    assert apart.returncode == 0, apart.stderr
    csv = "results.csv"
    assert (tmp_path / "here" / csv).read_bytes() == (tmp_path / "apart" / csv).read_bytes()
    assert "running 'bomb': 2 blocks, 200 steps of 0.01 s (gauss-seidel)" in apart.stdout
    # an ordinary failure (fmi2Error) is reported as without isolation, its rows kept
    failing = scenario(tmp_path, bomb_fmu, "failing.toml", fail_at="0.5 s")
    apart = run_cli(tmp_path, failing, "--out", tmp_path / "f_apart", "--isolate")
    assert apart.returncode == 4 and "Traceback" not in apart.stderr
    error, saved = apart.stderr.strip().splitlines()
    assert error == (
        "error: block 'bomb', FMI call fmi2DoStep, t = 0.5 s: fmi2DoStep failed with status 3 "
        "(error)."
    )
    assert saved.startswith("results recorded up to the failure are in")
    assert RunResult.load(tmp_path / "f_apart" / csv).time[-1] == pytest.approx(0.5)


def test_run_isolated_from_python_raises_with_the_partial_result(
    tmp_path: Path, bomb_fmu: Path
) -> None:
    seen: list[dict] = []
    with pytest.raises(IsolatedRunError) as info:
        run_isolated(
            scenario(tmp_path, bomb_fmu, abort_at="0.3 s"),
            overrides={"stop": 1.0},
            started=seen.append,
        )
    err = info.value
    assert err.block == "bomb" and err.time == pytest.approx(0.3)
    assert err.crash["exit_code"] == -signal.SIGABRT and err.exit_code == 4
    assert len(err.result.data) == 31 and err.result.time[-1] == pytest.approx(0.3)
    assert seen[0]["n_steps"] == 100 and seen[0]["blocks"] == 2
    # a mistake found while building in the child: its message and exit code (3)
    bad = scenario(tmp_path, bomb_fmu, "bad.toml", nope="1")
    with pytest.raises(UserError, match="nope") as info:
        run_isolated(bad)
    assert info.value.exit_code == 3 and "\n" not in str(info.value)
