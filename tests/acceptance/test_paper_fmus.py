"""Issue 16, acceptance 0: the paper scenarios with every truth and sensor model from its FMU.

``--fmu-dir`` swaps the blocks whose model has an FMU (the truth models of ``models/``,
what ``make fmus`` builds) and keeps the alignment filters in-process: a filter is the
thing under test, not a model to exchange, and keeping it in Python keeps its history
outputs and its speed. The results equal the in-process ones at the same seeds.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cosim import registry
from cosim.scenario import build_master, load_scenario

ROOT = Path(__file__).resolve().parents[2]
PAPER = ["sins_north_finding.toml", "hrg_two_position.toml", "transfer_alignment.toml"]


def run(path: Path, fmu_dir: Path | None, stop: str | None):
    master = build_master(path, fmu_dir=fmu_dir, stop=stop)
    try:
        return master.run()
    finally:
        master.terminate()


def assert_same(a, b) -> None:
    assert a.names == b.names
    for name in b.names:
        scale = max(1.0, float(np.max(np.abs(b[name]))))
        np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-12 * scale, err_msg=name)


@pytest.mark.parametrize("file", PAPER)
def test_paper_scenario_from_fmus_gives_the_in_process_numbers(file: str, fmu_dir: Path) -> None:
    path = ROOT / "scenarios" / file
    ours = run(path, None, "20 s")
    fmus = run(path, fmu_dir, "20 s")
    assert fmus.status == "completed"
    for name, spec in load_scenario(path).blocks.items():
        block = fmus.metadata["blocks"][name]
        if registry.is_truth_model(spec.source):
            assert block["kind"] == "fmu", name
            assert block["source"] == str((fmu_dir / f"{spec.source}.fmu").resolve())
        else:
            assert block["kind"] == "model", name
    assert_same(fmus, ours)


def test_run_and_check_say_where_each_block_runs_from(cli, fmu_dir: Path, tmp_path: Path) -> None:
    path = ROOT / "scenarios" / "transfer_alignment.toml"
    res = cli("run", path, "--fmu-dir", fmu_dir, "--stop", "1 s", "--out", tmp_path / "o")
    assert res.code == 0, res.err
    lines = {line.split()[0]: line.split(None, 1)[1] for line in res.out.splitlines()[1:7]}
    assert lines["ship"] == f"FMU {(fmu_dir / 'ShipMotion.fmu').resolve()}"
    assert lines["imu"] == f"FMU {(fmu_dir / 'StrapdownImu.fmu').resolve()}"
    assert lines["align"] == "in-process TransferAlignment"
    res = cli("check", path)
    assert res.code == 0, res.err
    assert "  ship    in-process ShipMotion" in res.out


def test_a_missing_fmu_names_the_block_and_the_folder(cli, tmp_path: Path) -> None:
    res = cli("check", ROOT / "scenarios" / "sins_north_finding.toml", "--fmu-dir", tmp_path)
    assert res.code == 3
    assert "StationaryBase.fmu" in res.err and "Traceback" not in res.err
    assert "SinsStaticAlignment" not in res.err  # the filter is not looked for


def verdicts(cli, path: Path, out: Path, *extra: str) -> dict:
    res = cli("verify", path, "--report", out, "--workers", "1", "--no-progress", *extra)
    assert res.code in (0, 1, 2), res.out + res.err
    data = json.loads((out / "report.json").read_text())
    return {r["id"]: r["result"]["value"] for r in data["requirements"]}


# Two Monte Carlo campaigns, from FMUs and in-process (~20 s); the default suite keeps
# test_verify_cli::test_fmus_in_workers_give_the_in_process_metrics.
@pytest.mark.slow
def test_verify_from_fmus_gives_the_in_process_metrics(cli, fmu_dir: Path, tmp_path) -> None:
    path = ROOT / "scenarios" / "sins_north_finding.toml"
    ours = verdicts(cli, path, tmp_path / "ours", "--runs", "1")
    theirs = verdicts(cli, path, tmp_path / "fmus", "--runs", "1", "--fmu-dir", fmu_dir)
    assert theirs.keys() == ours.keys()
    for key, value in ours.items():
        assert theirs[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key


@pytest.mark.slow
@pytest.mark.timeout(3600)
@pytest.mark.parametrize("file", PAPER)
def test_paper_scenario_full_length_from_fmus(file: str, fmu_dir: Path, cli, tmp_path) -> None:
    path = ROOT / "scenarios" / file
    assert_same(run(path, fmu_dir, None), run(path, None, None))
    ours = verdicts(cli, path, tmp_path / "ours", "--runs", "2")
    theirs = verdicts(cli, path, tmp_path / "fmus", "--runs", "2", "--fmu-dir", fmu_dir)
    assert theirs.keys() == ours.keys()
    for key, value in ours.items():
        if isinstance(value, str):  # a statistic that is not a number (e.g. no settling)
            assert theirs[key] == value, key
        else:
            assert theirs[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key
