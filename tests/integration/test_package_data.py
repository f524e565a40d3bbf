"""Issue 27, item 1: fast checks in the checkout.

The installed wheel: tests/integration/test_install.py.

The files the commands read are found through :mod:`cosim.package_data` (the checkout's
folders here, the package data in a wheel); every result records which kernel path ran;
``ins-cosim fmus`` advises a command that exists without a Makefile.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import cosim
from cosim.interop.interfaces import available_roles
from cosim.models import native
from cosim.package_data import role_dir, scenario_file

ROOT = Path(__file__).resolve().parents[2]


def test_the_checkout_reads_its_own_folders() -> None:
    assert role_dir() == ROOT / "fmus" / "interfaces"
    assert scenario_file("demo.toml") == ROOT / "scenarios" / "demo.toml"
    assert {"imu", "motion", "master_ins"} <= set(available_roles())


@pytest.mark.parametrize("switch", ["1", "0"])
def test_results_json_says_which_kernel_path_ran(
    switch: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(native.ENV, switch)
    result = cosim.run(ROOT / "scenarios" / "demo.toml", stop=1.0)
    result.save(tmp_path)
    meta = json.loads((tmp_path / "results.json").read_text())
    expected = native.status()
    assert meta["software"]["kernels"] == expected
    if switch == "0":
        assert expected == f"numpy ({native.ENV}=0)"
    else:
        assert expected.startswith("compiled kernels (kernels-"), expected


def test_fmus_without_fmus_advises_the_installed_command(cli, tmp_path: Path) -> None:
    """Was: "run `make fmus` first", a command a wheel user does not have."""
    res = cli("fmus", "--dir", tmp_path / "none")
    assert res.code == 3
    first = res.err.strip().splitlines()[0]
    assert f"build ours with `ins-cosim fmus --build --dir {tmp_path / 'none'}`" in first
    assert "Traceback" not in res.err
