"""tools/move_tests.py: the map of the flat suite to tests by module, and its path fixes.

The move itself is checked on a scratch copy (``--apply --verify``: the same number of
tests collected before and after); these tests pin the rules on the current tree.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("move_tests", ROOT / "tools" / "move_tests.py")
assert spec is not None and spec.loader is not None
move_tests = importlib.util.module_from_spec(spec)
sys.modules["move_tests"] = move_tests
spec.loader.exec_module(move_tests)


#: Test files put back flat in a scratch tree, to be placed again by the rules.
FLAT = (
    "test_master.py",
    "test_kalman.py",
    "test_hrg_platform_gyro.py",
    "test_campaign_lock.py",
    "test_report.py",
    "test_seed003.py",
)


def scratch_tree(root: Path) -> Path:
    """A tree with this repository's packages and pyproject, and an empty ``tests/``."""
    (root / "tests").mkdir()
    (root / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text())
    for package in ("cosim", "models"):
        (root / package).symlink_to(ROOT / package)
    return root


@pytest.fixture(scope="module")
def moves(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The map of :data:`FLAT`, copied back flat into a scratch tree, by old file name."""
    root = scratch_tree(tmp_path_factory.mktemp("flat"))
    for name in FLAT:
        (found,) = (ROOT / "tests").rglob(name)
        (root / "tests" / name).write_text(found.read_text())
    return {m.old.name: m for m in move_tests.plan(root)}


def test_the_suite_sits_by_module_and_every_flat_file_gets_one_place(moves: dict) -> None:
    """No test file is left flat in ``tests/``; flat ones map below it, no name twice."""
    assert not sorted(p.name for p in (ROOT / "tests").glob("test_*.py"))
    assert sorted(moves) == sorted(FLAT)
    new = [m.new for m in moves.values()]
    assert len({p.name for p in new}) == len(new)
    assert all(p.parent.parent.name == "tests" for p in new)
    assert all(p.name.startswith("test_") for p in new)


def test_files_named_after_a_module_go_to_its_package(moves: dict) -> None:
    """The name rule, the longest-prefix rule and a name two packages share."""
    where = {name: f"{m.new.parent.name}/{m.new.name}" for name, m in moves.items()}
    assert where["test_master.py"] == "core/test_master.py"
    assert where["test_kalman.py"] == "estimation/test_kalman.py"
    assert where["test_hrg_platform_gyro.py"] == "models/test_hrg_platform_gyro.py"
    assert where["test_campaign_lock.py"] == "verify/test_campaign_lock.py"
    # report.py is in cosim.verify and cosim.sensors: the file's imports settle it
    assert where["test_report.py"] == "verify/test_report.py"
    assert where["test_seed003.py"] == "reproduce/test_seed003.py"


def test_a_new_file_is_placed_by_rule(tmp_path: Path) -> None:
    """A file the script has never seen: named after nothing, it goes by its imports and
    is renamed after the module it uses most; one naming an acceptance point goes there."""
    (tmp_path / "tests").mkdir()
    for name in ("pyproject.toml",):
        (tmp_path / name).write_text((ROOT / name).read_text())
    for package in ("cosim", "models"):
        (tmp_path / package).symlink_to(ROOT / package)
    (tmp_path / "tests" / "test_brand_new.py").write_text(
        '"""Something new."""\n\nfrom cosim.verify.bounds import rms_bounds\n\n\n'
        "def test_x() -> None:\n    assert rms_bounds([1.0], 0.9)\n"
    )
    (tmp_path / "tests" / "test_issue99.py").write_text(
        '"""Issue 99, acceptance 2: something the user asked for."""\n'
    )
    found = {m.old.name: m.new.relative_to(tmp_path).as_posix() for m in move_tests.plan(tmp_path)}
    assert found == {
        "test_brand_new.py": "tests/verify/test_bounds_brand_new.py",
        "test_issue99.py": "tests/acceptance/test_issue99.py",
    }


@pytest.mark.parametrize(
    ("before", "after"),
    [
        ("Path(__file__).resolve().parents[1]", "Path(__file__).resolve().parents[2]"),
        ("Path(__file__).resolve().parents[2]", "Path(__file__).resolve().parents[3]"),
        ("Path(__file__).resolve().parents[2]", "Path(__file__).resolve().parents[3]"),
        ('Path(__file__).parents[1] / "fixtures"', 'Path(__file__).parents[2] / "fixtures"'),
        ("Path(__file__).resolve().parents[1].name", "Path(__file__).resolve().parents[2].name"),
    ],
)
def test_path_chains_climb_one_folder_more(before: str, after: str) -> None:
    """A file moved one folder down reaches the same folders as before."""
    assert move_tests.climb_one_more(before) == after
