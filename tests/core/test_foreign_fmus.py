"""No run lost to a foreign FMU (issue 30, item 3, acceptance 3).

A foreign FMU (not built by ins-cosim from the models installed here: :mod:`cosim.foreign`)
runs in a child process by default, under a plain ``ins-cosim run`` and under ``verify
--workers 1``. The C fixture ``tests/fixtures/abort2`` (compiled here) calls ``abort()``
in the step from ``abort_at`` on, in the runs whose ``seed`` is ``abort_seed``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.foreign import foreign_fmus, is_ours
from cosim.interop.cbuild import build_c_fmu
from cosim.results import RunResult
from cosim.scenario import load_scenario
from cosim.verify.campaign import run_campaign
from cosim.verify.seeds import run_seeds

TESTS = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bomb_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bomb")
    return build_c_fmu(TESTS / "fixtures" / "abort2", out / "Bomb.fmu")


def scenario(
    tmp_path: Path, fmu: Path, name: str = "bomb.toml", campaign: str = "", **bomb: object
) -> Path:
    params = ", ".join(f"{k} = {v!r}".replace("'", '"') for k, v in bomb.items())
    path = tmp_path / name
    path.write_text(
        '[master]\nstep = "10 ms"\nstop = "2 s"\n\n'
        '[blocks.flexure]\nmodel = "GaussMarkov2"\n'
        'parameters = { tau = "60 s", sigma = "2 arcmin", seed = 7 }\n\n'
        f'[blocks.bomb]\nfmu = "{fmu}"\nparameters = {{ {params} }}\n' + campaign
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


def test_ours_and_foreign(tmp_path: Path, bomb_fmu: Path, fmu_dir: Path) -> None:
    assert is_ours(fmu_dir / "GaussMarkov2.fmu")
    assert not is_ours(bomb_fmu)
    assert not is_ours(tmp_path / "missing.fmu")
    # the model identifier and GUID inside decide, not the file's name or place
    renamed = tmp_path / "Vendor.fmu"
    renamed.write_bytes((fmu_dir / "GaussMarkov2.fmu").read_bytes())
    assert is_ours(renamed)
    sc = load_scenario(scenario(tmp_path, bomb_fmu))
    assert foreign_fmus(sc) == {"bomb": str(bomb_fmu)}
    assert foreign_fmus(sc, fmu_dir) == {"bomb": str(bomb_fmu)}  # GaussMarkov2.fmu: ours


def test_a_plain_run_keeps_the_rows_of_an_fmu_that_aborts(tmp_path: Path, bomb_fmu: Path) -> None:
    """Acceptance 3 of issue 30: plain ``run``, exit 4, SIGABRT, block, time, rows kept."""
    path = scenario(tmp_path, bomb_fmu, abort_at="1.23 s")
    res = run_cli(tmp_path, path, "--out", tmp_path / "out")
    assert res.returncode == 4, (res.stdout, res.stderr)
    assert "Traceback" not in res.stderr
    error, saved = res.stderr.strip().splitlines()
    for part in ("killed by signal SIGABRT (6)", "block 'bomb' was stepping from t = 1.23 s"):
        assert part in error
    assert saved.startswith("results recorded up to the failure are in")
    assert "in a child process: FMU(s) not built by ins-cosim (bomb)" in res.stdout
    partial = RunResult.load(tmp_path / "out" / "results.csv")
    assert partial.status == "failed"
    assert partial.metadata["crashed"]["block"] == "bomb"
    assert len(partial.data) == 124 and partial.time[-1] == 1.23
    full = cosim.run(scenario(tmp_path, bomb_fmu, "whole.toml"))
    for name in full.names:
        np.testing.assert_array_equal(partial[name], full[name][:124])
    # --no-isolate runs in this process: the abort takes the command along, nothing written
    res = run_cli(tmp_path, path, "--out", tmp_path / "here", "--no-isolate")
    assert res.returncode == -6
    assert not (tmp_path / "here" / "results.csv").exists()


def test_a_campaign_on_one_worker_records_a_crashed_run_and_goes_on(
    tmp_path: Path, bomb_fmu: Path
) -> None:
    """Acceptance 3 of issue 30, ``--workers 1``: the run whose seed aborts is crashed."""
    victim = run_seeds(11, 1, ["flexure", "bomb"])["bomb"]  # seeded blocks, file order
    campaign = (
        '\n[campaign]\nruns = 3\nseed = 11\nrandomize = ["bomb"]\n\n'
        '[[requirements]]\nid = "R1"\ntext = "y stays below 10 s"\nsignal = "bomb.y"\n'
        'unit = "s"\ncriterion = "bound"\nbound = "10 s"\nstatistic = "max"\n'
        "probability = 0.5\n"
    )
    path = scenario(
        tmp_path, bomb_fmu, campaign=campaign, abort_at="1.23 s", abort_seed=victim, seed=0
    )
    result = run_campaign(path, tmp_path / "report", workers=1, progress=False)
    status = [r.status for r in result.records]
    assert status == ["completed", "crashed", "completed"]
    crashed = result.records[1]
    assert "killed by signal SIGABRT (6)" in crashed.error
    assert "block 'bomb' was stepping from t = 1.23 s" in crashed.error
    assert crashed.t_end == 1.23


def test_an_ssp_archive_with_a_foreign_fmu_runs_isolated(tmp_path: Path, bomb_fmu: Path) -> None:
    """The FMUs of an .ssp archive are foreign too: its plain ``run`` keeps the rows."""
    toml = tmp_path / "alone.toml"
    toml.write_text(
        '[master]\nstep = "10 ms"\nstop = "2 s"\n\n'
        f'[blocks.bomb]\nfmu = "{bomb_fmu}"\nparameters = {{ abort_at = "0.5 s" }}\n'
    )
    archive = tmp_path / "alone.ssp"
    res = subprocess.run(
        [sys.executable, "-m", "cosim.cli", "export-ssp", str(toml), str(archive)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    res = run_cli(tmp_path, archive, "--out", tmp_path / "out")
    assert res.returncode == 4, (res.stdout, res.stderr)
    error = res.stderr.strip().splitlines()[0]
    assert "killed by signal SIGABRT (6)" in error and "block 'bomb'" in error
    partial = RunResult.load(tmp_path / "out" / "results.csv")
    assert len(partial.data) == 51 and partial.time[-1] == 0.5
