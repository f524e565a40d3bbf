"""Dependencies of a plain install (issue 27, item 4).

allantools (every release since 2024) requires pytest and numpydoc, and numpydoc sphinx:
as a core dependency it pulled test and documentation tooling into a user's install. It
is the ``allan`` extra (and in ``test``); ``characterize`` says how to get it.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TOOLING = {"pytest", "numpydoc", "sphinx", "allantools"}


def name(requirement: str) -> str:
    """The distribution name of a requirement string (``"numpy>=1.26"`` -> ``"numpy"``)."""
    return re.match(r"[A-Za-z0-9_.-]+", requirement).group().lower()


def test_allantools_is_an_extra_not_a_core_dependency() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {name(r) for r in project["dependencies"]}
    assert not core & TOOLING, core & TOOLING
    extras = project["optional-dependencies"]
    assert any(r.startswith("allantools") for r in extras["allan"])
    assert any(r.startswith("allantools") for r in extras["test"])  # the checkout's tests


def test_characterize_without_allantools_says_how_to_get_it(tmp_path: Path) -> None:
    """allantools made absent (None in sys.modules): one line, exit 3, no traceback."""
    code = (
        "import sys; sys.modules['allantools'] = None; from cosim.cli import main; "
        "main(['characterize', 'log.csv', '--out', 'out'])"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120
    )
    assert res.returncode == 3, res.stderr
    assert "Traceback" not in res.stderr
    assert "pip install 'ins-cosim[allan]'" in res.stderr and len(res.stderr.splitlines()) == 1


@pytest.mark.slow
def test_a_plain_install_resolves_without_test_or_doc_tooling(tmp_path: Path) -> None:
    """pip resolves the project's dependencies from nothing (--ignore-installed, dry run):
    no pytest, numpydoc, sphinx or allantools among what it would install."""
    report = tmp_path / "report.json"
    res = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--dry-run", "--ignore-installed", "--quiet",
         "--report", str(report), str(ROOT)],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    names = {item["metadata"]["name"].lower() for item in json.loads(report.read_text())["install"]}
    assert "ins-cosim" in names and "numpy" in names
    assert not names & TOOLING, names & TOOLING
