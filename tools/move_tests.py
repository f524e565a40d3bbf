"""Move the flat test suite to tests by module (issue 29, item 7).

    python tools/move_tests.py            print the map: old file -> new file, and why
    python tools/move_tests.py --apply    move with ``git mv`` and fix what the move breaks
    python tools/move_tests.py --apply --verify
                                          also count the collected tests before and after
                                          (``pytest --collect-only``, slow ones included)
                                          and fail if the counts differ

Targets:
- ``tests/<package>/test_<module>[_<topic>].py``: the package is the subpackage of
  ``cosim`` the module lives in (``alignment``, ``estimation``, ``interop``, ``models``,
  ``reproduce``, ``sensors``, ``verify``, ...), ``core`` for the modules of ``cosim``
  itself, ``benchmarks`` for ``benchmarks/``. Packages and modules are read from
  pyproject's ``[tool.setuptools]`` (packages and package-dir), so a package added or
  moved by a later change is found without editing this script.
- ``tests/integration/``: files that run whole scenarios or the command line end to end
  and are not named after a module.
- ``tests/acceptance/``: files whose first docstring line names an issue's acceptance
  point and that are not named after a module.

The rule for one file, first match wins:
1. ``OVERRIDES`` (a few hand decisions, each with its reason).
2. Its name: ``test_<name>`` where ``<name>`` or its longest ``_``-prefix is a module's
   name; a name shared by several modules is settled by the file's imports. The file
   keeps its name.
3. Acceptance, then integration, as above. The file keeps its name.
4. Its imports: the project module whose imported names the file uses most. The file is
   renamed ``test_<module>_<old topic>.py`` so that its name starts with the module's.

``--apply`` also fixes what the move breaks:
- ``Path(__file__)`` chains in moved files climb one folder more
  (``.parent`` -> ``.parents[1]``, ``.parents[1]`` -> ``.parents[2]``);
- ``pythonpath`` of pytest's settings gains ``tests`` so that the helper modules that
  stay in ``tests/`` (``testblocks``, ``clockblocks``, ``crashblocks``, ...) import from
  every folder; ``conftest.py`` and ``fixtures/`` stay where they are (a root
  ``conftest.py`` serves every folder below it);
- every mention ``tests/test_<x>.py`` in the repository's text files (tests, code, docs,
  Makefile; CHANGELOG.md is history and is left alone) names the new path.
Test module names stay unique over the whole tree (pytest's default import mode needs
it without ``__init__.py`` files); the script refuses a map with a duplicate.
"""

from __future__ import annotations

import argparse
import ast
import collections
import re
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"

#: Hand decisions: old file name -> (folder, new name or "" to keep it, reason).
OVERRIDES: dict[str, tuple[str, str, str]] = {
    "test_layout.py": ("core", "", "the whole package's layout, kept beside the core"),
    "test_docstrings.py": ("core", "", "docstrings of every package"),
    "test_dependencies.py": ("core", "", "what a plain install brings"),
    "test_install.py": ("integration", "", "the wheel installed in a fresh environment"),
    "test_ci.py": ("integration", "", "the check stage and the demo, run as CI runs them"),
    "test_fmus.py": ("models", "", "every model block as an FMU"),
    "test_fmu_types.py": ("core", "test_blocks_fmu_types.py", "FMU hosts (cosim.blocks)"),
    "test_fmu_host_requirements.py": (
        "interop",
        "test_packaging_host_requirements.py",
        "FMUs we pack",
    ),
    "test_filter_fast_paths.py": (
        "alignment",
        "test_transfer_filter_fast_paths.py",
        "transfer filter",
    ),
    "test_confidence_bounds.py": ("verify", "test_bounds_verdicts.py", "cosim.verify.bounds"),
    "test_sensor_logs.py": ("sensors", "test_logs.py", "cosim.sensors.logs"),
    "test_ship_lookahead.py": ("models", "test_ship_motion_lookahead.py", "ShipMotion"),
}
#: Folders of the tests that are no package.
INTEGRATION = "integration"
ACCEPTANCE = "acceptance"
#: Text files whose mentions of test paths are updated (suffixes), and the one left alone.
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg", ".yml", ".yaml", ""}
HISTORY = {"CHANGELOG.md"}


@dataclass(frozen=True)
class Move:
    """Where one test file goes.

    Attributes
    ----------
    old : Path
        The file now (``tests/test_x.py``).
    new : Path
        Its place after the move.
    why : str
        The rule that placed it.
    """

    old: Path
    new: Path
    why: str


def project_modules(root: Path = ROOT) -> dict[str, str]:
    """The project's modules and their test folders.

    Parameters
    ----------
    root : Path
        Repository root.

    Returns
    -------
    dict
        Dotted module name (``cosim.verify.report``, ``cosim.models.native``,
        ``benchmarks.monolithic``) -> test folder (``verify``, ``models``,
        ``benchmarks``; ``core`` for ``cosim.<module>``).
    """
    setup = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]
    package_dir = setup.get("package-dir", {})
    folders: dict[str, Path] = {}
    for package in setup["packages"]:
        mapped = [p for p in package_dir if package == p or package.startswith(p + ".")]
        if mapped:
            base = max(mapped, key=len)
            rest = package[len(base) :].lstrip(".").split(".") if package != base else []
            folders[package] = (
                root / package_dir[base] / Path(*rest) if rest else root / package_dir[base]
            )
        else:
            folders[package] = root / Path(*package.split("."))
    if (root / "benchmarks" / "__init__.py").is_file():
        folders["benchmarks"] = root / "benchmarks"
    modules: dict[str, str] = {}
    for package, folder in folders.items():
        parts = package.split(".")
        home = (
            "benchmarks" if parts[0] == "benchmarks" else ("core" if len(parts) == 1 else parts[1])
        )
        if "package_data" in parts:
            continue
        if len(parts) > 1:
            modules[package] = home
        for path in sorted(folder.glob("*.py")):
            if path.stem != "__init__":
                modules[f"{package}.{path.stem}"] = home
    return modules


def imported_modules(source: str, modules: dict[str, str]) -> collections.Counter[str]:
    """How much a test file uses each project module.

    Parameters
    ----------
    source : str
        The test file's text.
    modules : dict
        As returned by :func:`project_modules`.

    Returns
    -------
    Counter
        Module -> 1 per import statement plus 1 per use of a name bound by it.
    """
    tree = ast.parse(source)
    bound: dict[str, str] = {}
    score: collections.Counter[str] = collections.Counter()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            base = re.sub(r"^models\b", "cosim.models", node.module)
            for alias in node.names:
                target = f"{base}.{alias.name}"
                module = target if target in modules else base
                if module in modules:
                    score[module] += 1
                    bound[alias.asname or alias.name] = module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                name = re.sub(r"^models\b", "cosim.models", alias.name)
                if name in modules:
                    score[name] += 1
                    if alias.asname:
                        bound[alias.asname] = name
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id in bound:
            score[bound[node.id]] += 1
    return score


def first_doc_line(source: str) -> str:
    """The first line of the module docstring ('' without one)."""
    doc = ast.get_docstring(ast.parse(source)) or ""
    return doc.splitlines()[0] if doc else ""


def runs_end_to_end(source: str) -> bool:
    """Whether a test file runs the command line or whole scenario files.

    Parameters
    ----------
    source : str
        The test file's text.

    Returns
    -------
    bool
        It uses the ``cli`` fixture, ``cosim.cli`` or the ``ins-cosim`` command, or
        loads a file of ``scenarios/`` and runs it.
    """
    if re.search(r"def test_\w+\([^)]*\bcli\b", source) or "cosim.cli" in source:
        return True
    if re.search(r"[\"']ins-cosim[\"']", source):
        return True
    return bool(re.search(r"scenarios", source) and re.search(r"\brun_campaign\b|\.run\(", source))


def by_name(stem: str, modules: dict[str, str], used: collections.Counter[str]) -> str | None:
    """The module a test file is named after, if any.

    Parameters
    ----------
    stem : str
        The name without ``test_`` (``hrg_platform_gyro``).
    modules : dict
        As returned by :func:`project_modules`.
    used : Counter
        As returned by :func:`imported_modules` (settles a name shared by modules).

    Returns
    -------
    str or None
        The longest ``_``-prefix of ``stem`` that names a module (``hrg_platform``).
    """
    words = stem.split("_")
    for n in range(len(words), 0, -1):
        name = "_".join(words[:n])
        found = [m for m in modules if m.rsplit(".", 1)[-1] == name]
        if found:
            return max(found, key=lambda m: (used[m], m.startswith("cosim.")))
    return None


def plan(root: Path = ROOT) -> list[Move]:
    """The map of the flat test files of ``tests/`` to their folders.

    Parameters
    ----------
    root : Path
        Repository root.

    Returns
    -------
    list of Move
        One per ``tests/test_*.py`` at the top of ``tests/``, sorted by old name.

    Raises
    ------
    SystemExit
        When two files would get the same name.
    """
    modules = project_modules(root)
    tests = root / "tests"
    moves = []
    for path in sorted(tests.glob("test_*.py")):
        source = path.read_text()
        used = imported_modules(source, modules)
        stem = path.stem.removeprefix("test_")
        if path.name in OVERRIDES:
            folder, name, why = OVERRIDES[path.name]
            moves.append(Move(path, tests / folder / (name or path.name), f"override: {why}"))
            continue
        named = by_name(stem, modules, used)
        if named is not None:
            why = f"named after {named}"
            moves.append(Move(path, tests / modules[named] / path.name, why))
            continue
        first = first_doc_line(source)
        if re.search(r"\bacceptance\b", first, re.IGNORECASE):
            moves.append(Move(path, tests / ACCEPTANCE / path.name, f"acceptance: {first[:60]}"))
            continue
        if runs_end_to_end(source):
            moves.append(Move(path, tests / INTEGRATION / path.name, "runs the CLI or scenarios"))
            continue
        if used:
            module = max(used, key=lambda m: (used[m], m))
            short = module.rsplit(".", 1)[-1]
            name = f"test_{short}_{stem}.py"
            why = f"uses {module} most ({used[module]})"
            moves.append(Move(path, tests / modules[module] / name, why))
            continue
        moves.append(Move(path, tests / INTEGRATION / path.name, "imports no project module"))
    moves = keep_importers_beside(moves)
    names = collections.Counter(m.new.name for m in moves)
    names.update(p.name for p in tests.rglob("test_*.py") if p.parent != tests)
    twice = sorted(n for n, k in names.items() if k > 1)
    if twice:
        raise SystemExit(f"two test files would share a name: {', '.join(twice)}")
    return moves


def keep_importers_beside(moves: list[Move]) -> list[Move]:
    """A test file that imports another test module goes to that module's folder.

    Parameters
    ----------
    moves : list of Move
        The map so far.

    Returns
    -------
    list of Move
        The same map, importers placed beside what they import (pytest's default import
        mode finds a test module from the folder of the file that imports it).
    """
    where = {m.old.stem: m.new.parent for m in moves}
    out = []
    for m in moves:
        tree = ast.parse(m.old.read_text())
        imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        homes = {where[name] for name in imported if name in where and name != m.old.stem}
        if len(homes) == 1 and m.new.parent not in homes:
            (home,) = homes
            m = Move(m.old, home / m.new.name, f"{m.why}; beside the test module it imports")
        out.append(m)
    return out


def climb_one_more(source: str) -> str:
    """``Path(__file__)`` chains of a file moved one folder down, fixed.

    Parameters
    ----------
    source : str
        The moved file's text.

    Returns
    -------
    str
        ``Path(__file__)[.resolve()].parent`` -> ``.parents[1]``, ``.parent.parent`` and
        ``.parents[1]`` -> ``.parents[2]``, and so on.
    """
    chain = re.compile(
        r"(Path\(__file__\)(?:\.resolve\(\))?)((?:\.parent(?![\w\[]))+|\.parents\[(\d+)\])"
    )

    def fix(m: re.Match[str]) -> str:
        depth = int(m.group(3)) + 1 if m.group(3) is not None else m.group(2).count(".parent")
        return f"{m.group(1)}.parents[{depth}]"

    return chain.sub(fix, source)


def text_files(root: Path) -> list[Path]:
    """The repository's tracked text files that may mention test paths."""
    out = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True, check=True)
    files = []
    for line in out.stdout.splitlines():
        path = root / line
        if path.name in HISTORY or path.suffix not in TEXT_SUFFIXES or not path.is_file():
            continue
        if path.suffix == "" and path.name not in ("Makefile", "run", "check"):
            continue
        files.append(path)
    return files


def add_tests_to_pythonpath(pyproject: Path) -> None:
    """Add ``tests`` to pytest's ``pythonpath`` (the helper modules stay there)."""
    text = pyproject.read_text()
    m = re.search(r"^pythonpath = \[([^\]]*)\].*$", text, re.MULTILINE)
    if m is None:
        raise SystemExit(f"{pyproject}: no pythonpath in [tool.pytest.ini_options]")
    if '"tests"' in m.group(1):
        return
    entries = m.group(1).strip()
    new = f'pythonpath = [{entries}, "tests"]' if entries else 'pythonpath = ["tests"]'
    new += "  # the root (benchmarks/) and tests/ (its helper modules)"
    pyproject.write_text(text[: m.start()] + new + text[m.end() :])


def collected(root: Path) -> int:
    """The number of tests pytest collects, slow ones included."""
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "--collect-only",
            "-q",
            "-m",
            "",
            "-p",
            "no:cacheprovider",
        ],
        cwd=root,
        capture_output=True,
        text=True,
    )
    m = re.search(r"(\d+) tests? collected", proc.stdout)
    if proc.returncode != 0 or m is None:
        raise SystemExit(
            f"pytest --collect-only failed:\n{proc.stdout[-3000:]}{proc.stderr[-2000:]}"
        )
    return int(m.group(1))


def apply(moves: list[Move], root: Path = ROOT) -> None:
    """Move the files with ``git mv`` and fix paths, mentions and pytest's settings.

    Parameters
    ----------
    moves : list of Move
        As returned by :func:`plan`.
    root : Path
        Repository root (a git work tree).
    """
    for move in moves:
        move.new.parent.mkdir(exist_ok=True)
        subprocess.run(["git", "mv", str(move.old), str(move.new)], cwd=root, check=True)
        move.new.write_text(climb_one_more(move.new.read_text()))
    renames = {f"tests/{m.old.name}": m.new.relative_to(root).as_posix() for m in moves}
    mention = re.compile(r"tests/test_\w+\.py\b")
    for path in text_files(root):
        text = path.read_text()
        new = mention.sub(lambda m: renames.get(m.group(0), m.group(0)), text)
        if new != text:
            path.write_text(new)
    add_tests_to_pythonpath(root / "pyproject.toml")


def main(argv: list[str] | None = None) -> int:
    """Print the map; with ``--apply`` move; with ``--verify`` compare the counts.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0, or 1 when ``--verify`` finds another number of tests after the move.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--apply", action="store_true", help="git mv the files and fix them")
    parser.add_argument("--verify", action="store_true", help="compare collected test counts")
    args = parser.parse_args(argv)
    moves = plan()
    width = max(len(m.old.name) for m in moves)
    for m in moves:
        print(f"{m.old.name:<{width}}  ->  {m.new.relative_to(ROOT).as_posix():<55}  {m.why}")
    folders = collections.Counter(m.new.parent.name for m in moves)
    print(f"{len(moves)} files: " + ", ".join(f"{k} {v}" for k, v in sorted(folders.items())))
    if not args.apply:
        return 0
    before = collected(ROOT) if args.verify else None
    if before is not None:
        print(f"collected before the move: {before}")
    apply(moves)
    if before is not None:
        after = collected(ROOT)
        print(f"collected before the move: {before}, after: {after}")
        if after != before:
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
