"""The package layout holds: arrows point down, modules stay small, privacy is kept.

Checked by reading the sources (``ast``), not by importing them, except the one test
that runs the demo in a fresh interpreter to see what it actually imports.

- The core (``cosim/__init__``, ``scenario``, ``master``, ``blocks``, ``units``,
  ``results``, ``errors``, ``provenance``, ``registry``) imports nothing from the packages
  above it: it finds their blocks through the registry's entry points.
- No module of ``cosim/``, ``models/`` or ``benchmarks/`` is over 800 lines
  (``benchmarks/monolithic.py``, the hand-written reference, is excepted).
- No module uses a private name (``_x``) of another module of the project: not by
  ``from m import _x``, not as ``m._x``, not as ``obj._x`` on an object whose class
  lives elsewhere (a private attribute is used only in the module that defines it).
- No file of the project names a path outside the repository (a user's clone has only
  the repository).
"""

from __future__ import annotations

import ast
import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: The core's modules (DESIGN: master, hosts, scenario, units, results, errors, ...).
CORE = [
    "cosim/__init__.py",
    "cosim/scenario.py",
    "cosim/scenario_parse.py",
    "cosim/master.py",
    "cosim/blocks.py",
    "cosim/units.py",
    "cosim/results.py",
    "cosim/errors.py",
    "cosim/provenance.py",
    "cosim/registry.py",
    "cosim/observers.py",
    "cosim/recording.py",
    "cosim/runs.py",
    "cosim/parses.py",
]
#: The packages above the core, and the command line on top of everything.
ABOVE = (
    "cosim.estimation",
    "cosim.alignment",
    "cosim.verify",
    "cosim.interop",
    "cosim.reproduce",
    "cosim.cli",
)
MAX_LINES = 800
LONG_ALLOWED = {"benchmarks/monolithic.py"}
#: Top-level packages of the project; the modules of tests/ count too.
PROJECT = ("cosim", "models", "benchmarks")
#: What a clone does not have: generated or installed folders.
NOT_SOURCES = {".git", ".venv", "out", "build", "results", "__pycache__", ".pytest_cache"}
NOT_SOURCES |= {".ruff_cache"}

# Other helpers are still splitting the long modules, making the private names public
# and moving the paper references into the README; the integrator drops these marks.


def python_files(*folders: str) -> list[Path]:
    """The ``.py`` files under the given top-level folders of the repository.

    Parameters
    ----------
    *folders : str
        Folder names relative to the repository root (``"cosim"``, ``"tests"``).

    Returns
    -------
    list of Path
        Sorted, caches excluded.
    """
    return sorted(
        p
        for folder in folders
        for p in (ROOT / folder).rglob("*.py")
        if not NOT_SOURCES.intersection(p.relative_to(ROOT).parts)
    )


def module_name(path: Path) -> str:
    """Dotted module name of a file (a test module is named by its stem, as pytest does).

    Parameters
    ----------
    path : Path
        A ``.py`` file of the repository.

    Returns
    -------
    str
        ``cosim/verify/campaign.py`` -> ``cosim.verify.campaign``; ``cosim/__init__.py``
        -> ``cosim``; ``tests/testblocks.py`` -> ``testblocks`` (a file outside the
        repository is named by its stem too).
    """
    if not path.is_relative_to(ROOT) or path.relative_to(ROOT).parts[0] == "tests":
        return path.stem
    rel = path.relative_to(ROOT)
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    if parts[0] == "models":  # installed as cosim.models (pyproject's package-dir)
        parts.insert(0, "cosim")
    return ".".join(parts)


@dataclass(frozen=True)
class Imported:
    """One name an import statement brings in.

    Attributes
    ----------
    target : str
        The full dotted name (``cosim.blocks`` for ``from cosim import blocks``,
        ``cosim.blocks.REAL`` for ``from cosim.blocks import REAL``).
    bound : str
        The local name it is bound to (empty for a plain ``import a.b``, which binds ``a``).
    line : int
        Line of the statement.
    """

    target: str
    bound: str
    line: int


def imports(path: Path) -> list[Imported]:
    """Every import of a module, at any depth (functions' lazy imports included).

    Parameters
    ----------
    path : Path
        The module's file.

    Returns
    -------
    list of Imported
        Relative imports resolved against the module's package; a constant
        ``importlib.import_module("a.b")`` call counts as an import of ``a.b``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    me = module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found: list[Imported] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.append(Imported(alias.name, alias.asname or "", node.lineno))
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([module] if module else []))
            for alias in node.names:
                bound = alias.asname or alias.name
                found.append(Imported(f"{module}.{alias.name}", bound, node.lineno))
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            found.append(Imported(node.args[0].value, "", node.lineno))
    return found


def _within(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def test_core_imports_nothing_above_it() -> None:
    offenders = [
        f"{rel}:{imp.line}: {imp.target}"
        for rel in CORE
        for imp in imports(ROOT / rel)
        if any(_within(imp.target, above) for above in ABOVE)
    ]
    assert not offenders, "the core imports packages above it:\n" + "\n".join(offenders)


def test_the_core_imports_only_itself_and_the_models_at_run_time() -> None:
    """Loading and running the demo in a fresh interpreter imports no package above the core."""
    code = (
        "import json, sys, cosim\n"
        "cosim.run('scenarios/demo.toml', stop=0.1)\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.startswith('cosim'))))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    loaded = json.loads(proc.stdout.splitlines()[-1])
    above = [m for m in loaded if any(_within(m, a) for a in ABOVE)]
    assert not above, f"running a truth-model scenario imported {above}"
    assert "cosim.registry" in loaded


def test_the_checker_resolves_imports() -> None:
    folder = ROOT / "cosim"
    targets = {i.target for i in imports(folder / "scenario.py")}
    assert {"cosim.registry", "cosim.master.Master", "cosim.scenario_parse.BlockSpec"} <= targets
    assert "tomllib" in {i.target for i in imports(folder / "scenario_parse.py")}
    assert module_name(folder / "__init__.py") == "cosim"
    assert module_name(ROOT / "tests" / "testblocks.py") == "testblocks"


def test_no_module_is_over_800_lines() -> None:
    too_long = []
    for path in python_files("cosim", "models", "benchmarks"):
        rel = path.relative_to(ROOT).as_posix()
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_LINES and rel not in LONG_ALLOWED:
            too_long.append(f"{rel}: {n} lines")
    assert not too_long, f"modules over {MAX_LINES} lines:\n" + "\n".join(too_long)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _project_modules() -> set[str]:
    return {module_name(p) for p in python_files(*PROJECT, "tests")}


def _is_project(name: str, modules: set[str]) -> bool:
    return name.split(".")[0] in PROJECT or name.split(".")[0] in modules


def _own_private_names(tree: ast.AST) -> set[str]:
    """Private names a module defines: functions, classes, attributes it assigns."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
    return {n for n in names if _is_private(n)}


def private_uses(path: Path, modules: set[str]) -> list[str]:
    """Where a module uses a private name that another module of the project defines.

    Parameters
    ----------
    path : Path
        The module's file.
    modules : set of str
        Names of the project's modules (the test modules by stem).

    Returns
    -------
    list of str
        ``file:line: what`` per offence: ``from m import _x``; ``m._x`` on a module (or an
        object imported from one) of the project; ``obj._x`` on a local object when the
        module itself defines no ``_x`` (the attribute belongs to a class elsewhere).
    """
    me = module_name(path)
    rel = path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else path.name
    tree = ast.parse(path.read_text(encoding="utf-8"))
    bound: dict[str, str] = {}
    found: list[str] = []
    for imp in imports(path):
        module, _, last = imp.target.rpartition(".")
        if imp.bound and _is_private(last) and _is_project(module, modules) and module != me:
            found.append(f"{rel}:{imp.line}: from {module} import {last}")
        if imp.bound:
            bound[imp.bound] = imp.target
        else:
            bound[imp.target.split(".")[0]] = imp.target.split(".")[0]
    own = _own_private_names(tree)
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _is_private(node.attr)):
            continue
        chain: list[str] = []
        value = node.value
        while isinstance(value, ast.Attribute):
            chain.append(value.attr)
            value = value.value
        if not isinstance(value, ast.Name) or value.id in ("self", "cls"):
            continue
        if value.id in bound:
            full = ".".join([bound[value.id], *reversed(chain)])
            if _is_project(full, modules) and not _within(full, me):
                found.append(f"{rel}:{node.lineno}: {full}.{node.attr}")
        elif node.attr not in own:
            found.append(f"{rel}:{node.lineno}: {value.id}.{node.attr} (defined elsewhere)")
    return found


def test_the_private_name_checker_finds_each_kind(tmp_path: Path) -> None:
    sample = tmp_path / "layout_sample.py"
    sample.write_text(
        "import cosim.blocks\n"
        "from cosim.blocks import _hidden\n"
        "from cosim import master as m\n"
        "def f(upf, obj):\n"
        "    obj._mine = 1\n"
        "    return cosim.blocks._a, m._b, upf._f, obj._mine\n"
    )
    found = [f.split(": ", 1)[1] for f in private_uses(sample, {"layout_sample"})]
    assert found == [
        "from cosim.blocks import _hidden",
        "cosim.blocks._a",
        "cosim.master._b",
        "upf._f (defined elsewhere)",
    ]


def test_no_private_name_crosses_modules() -> None:
    modules = _project_modules()
    offenders = [
        offence
        for path in python_files(*PROJECT, "tests")
        for offence in private_uses(path, modules)
    ]
    assert not offenders, "private names used across modules:\n" + "\n".join(offenders)


#: A path a clone does not have: the project's planning folder, or an absolute path of
#: the machine it was written on.
OUTSIDE = re.compile(r"\bshared/[A-Z]\w*\.md\b|(?<![\w.~-])/(?:work|tmp|home|root|Users)/\w")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg", ".ini", ".yml", ".yaml", ".c", ".h"}
TEXT_NAMES = {"Makefile", "run"}


def project_text_files() -> list[Path]:
    """The repository's text files (sources, docs, scenarios, build files).

    Returns
    -------
    list of Path
        Sorted; generated and installed folders are left out.
    """
    found = []
    for folder, subfolders, files in os.walk(ROOT):
        subfolders[:] = [
            d for d in subfolders if d not in NOT_SOURCES and not d.endswith(".egg-info")
        ]
        found += [
            Path(folder) / f for f in files if Path(f).suffix in TEXT_SUFFIXES or f in TEXT_NAMES
        ]
    return sorted(found)


def test_the_outside_path_pattern() -> None:
    assert OUTSIDE.search("see shared/" + "SEEDS.md for the papers")
    assert OUTSIDE.search("written to /" + "tmp/coord/notes.md")
    assert not OUTSIDE.search("fmus/build/GaussMarkov2.fmu and ../fmus/build")
    assert not OUTSIDE.search("tests/fixtures/fmi3_ramp and out/demo/results.csv")


def test_no_file_names_a_path_outside_the_repository() -> None:
    offenders = []
    for path in project_text_files():
        for i, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines()):
            match = OUTSIDE.search(line)
            if match:
                offenders.append(f"{path.relative_to(ROOT)}:{i + 1}: {match.group(0)}")
    assert not offenders, "paths outside the repository:\n" + "\n".join(offenders)


# ------------------------------------------------------------ one of each (acceptance 2)

#: Where the "one of each" rules apply: the library and the benchmarks (the monolithic
#: reference is written by hand on purpose; tests keep their own independent oracles).
LIBRARY = ("cosim", "models", "benchmarks")


def library_files() -> list[Path]:
    """The library's modules and the benchmarks, the monolithic reference excepted.

    Returns
    -------
    list of Path
        Sorted.
    """
    return [p for p in python_files(*LIBRARY) if p.relative_to(ROOT).as_posix() not in LONG_ALLOWED]


def definitions(pattern: str, kinds: tuple[type, ...]) -> list[str]:
    """Every class or function of the library whose name matches a pattern.

    Parameters
    ----------
    pattern : str
        Regular expression matched against the whole name (``re.fullmatch``).
    kinds : tuple of type
        ``ast.ClassDef`` and/or ``ast.FunctionDef``.

    Returns
    -------
    list of str
        ``module:name``, methods included (``module:Class.name``).
    """
    found = []
    for path in library_files():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        scopes: list[tuple[str, ast.AST]] = [("", tree)]
        while scopes:
            prefix, scope = scopes.pop()
            for node in ast.iter_child_nodes(scope):
                if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                    if isinstance(node, kinds) and re.fullmatch(pattern, node.name):
                        found.append(f"{module_name(path)}:{prefix}{node.name}")
                    if isinstance(node, ast.ClassDef):
                        scopes.append((f"{prefix}{node.name}.", node))
    return sorted(found)


FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)


@pytest.mark.parametrize(
    "what, pattern, kinds, expected",
    [
        ("covariance history", r"\w*CovarianceHistory", (ast.ClassDef,), 1),
        ("campaign error", r"\w*CampaignError", (ast.ClassDef,), 1),
        ("angle wrap", r"_?wrap\w*", FUNCTIONS, 1),
        ("cross product", r"_?cross\d?", FUNCTIONS, 1),
        ("skew matrix", r"_?skew\w*", FUNCTIONS, 1),
    ],
)
def test_one_of_each(what: str, pattern: str, kinds: tuple[type, ...], expected: int) -> None:
    found = definitions(pattern, kinds)
    assert len(found) == expected, f"{len(found)} definitions of the {what}: {found}"


def test_one_strapdown_integrator() -> None:
    found = definitions(r"\w*Strapdown", (ast.ClassDef,))
    # the compiled twin is the same integrator: a subclass that only moves its step to C
    twin = ROOT / "cosim" / "alignment" / "nav_compiled.py"
    bases = [
        [b.id for b in node.bases if isinstance(b, ast.Name)]
        for node in ast.walk(ast.parse(twin.read_text(encoding="utf-8")))
        if isinstance(node, ast.ClassDef) and node.name == "CompiledStrapdown"
    ]
    assert bases == [["Strapdown"]], bases
    assert found == [
        "cosim.alignment.nav:Strapdown",
        "cosim.alignment.nav_compiled:CompiledStrapdown",
    ], f"strapdown integrators: {found}"


def _calls(path: Path, name: str) -> list[int]:
    """Lines of the calls ``name(...)`` or ``x.name(...)`` in a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and (
            (isinstance(node.func, ast.Name) and node.func.id == name)
            or (isinstance(node.func, ast.Attribute) and node.func.attr == name)
        )
    ]


def test_one_place_builds_a_master() -> None:
    places = [
        f"{path.relative_to(ROOT)}:{line}"
        for path in python_files("cosim")
        for line in _calls(path, "Master")
    ]
    assert len(places) == 1 and places[0].startswith("cosim/scenario.py:"), places


def test_one_seed_rule() -> None:
    places = sorted(
        {
            path.relative_to(ROOT).as_posix()
            for path in python_files("cosim")
            if _calls(path, "SeedSequence")
        }
    )
    assert places == ["cosim/verify/seeds.py"], f"modules that derive seeds: {places}"


#: The unit factors and physical constants of models/constants.py.
CONSTANTS = {"DEG", "ARCMIN", "ARCSEC", "DEG_PER_HOUR", "DEG_PER_SQRT_HOUR", "G0", "MICRO_G"}
CONSTANTS |= {"PPM", "OMEGA_IE", "GM", "E2", "GAMMA_E", "GAMMA_P", "K_SOMIGLIANA", "M_RATIO"}


def test_constants_come_from_models_constants_only() -> None:
    offenders = []
    for path in python_files(*PROJECT, "tests"):
        rel = path.relative_to(ROOT).as_posix()
        if rel == "models/constants.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in tree.body:  # module-level copies: DEG = math.pi / 180, _ARCMIN = ...
            targets = node.targets if isinstance(node, ast.Assign) else []
            for target in targets:
                if isinstance(target, ast.Name) and target.id.lstrip("_").upper() in CONSTANTS:
                    offenders.append(f"{rel}:{node.lineno}: {target.id} = ...")
        for imp in imports(path):  # a constant taken from a filter or a reproduction
            module, _, name = imp.target.rpartition(".")
            if name.lstrip("_") in CONSTANTS and module != "cosim.models.constants":
                if _is_project(module, {"testblocks"}):
                    offenders.append(f"{rel}:{imp.line}: {name} from {module}")
    assert not offenders, "constants defined or taken outside models.constants:\n" + "\n".join(
        offenders
    )


#: Besides Scenario.build: the model references drive one model alone, with no scenario.
HOSTS_ALSO_MADE_IN = {"cosim/interop/references.py"}


def test_scenario_build_is_where_blocks_are_instantiated() -> None:
    places = {
        path.relative_to(ROOT).as_posix()
        for path in python_files("cosim")
        if _calls(path, "InProcessHost") or _calls(path, "FmuHost")
    }
    assert places - HOSTS_ALSO_MADE_IN == {"cosim/scenario.py"}, sorted(places)


def test_one_c_build() -> None:
    """The kernels and the C FMUs are compiled by one function with one flag set."""
    places = [
        path.relative_to(ROOT).as_posix()
        for path in python_files(*LIBRARY)
        if '"-shared"' in path.read_text(encoding="utf-8")
    ]
    assert places == ["models/native/ccompile.py"], places


# ------------------------------------------------------------------ no import circles

#: Import circles allowed (none: split modules by concern instead).
KNOWN_CIRCLES: list[list[str]] = []


def _type_checking_only(node: ast.AST) -> bool:
    """True for ``if TYPE_CHECKING:`` (its imports never run)."""
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")
    )


def import_graph(paths: list[Path]) -> dict[str, set[str]]:
    """Which project modules each module imports.

    Every import statement counts, at module level and inside functions alike: a lazy
    import only moves the circle from import time to call time, and the two modules
    still cannot be read, tested or moved one without the other. Imports under
    ``if TYPE_CHECKING:`` do not count (they never run: annotations only).
    ``from package import name`` is an import of ``package.name`` when that is a module
    of the project, else of ``package``; ``import a.b.c`` of the longest project module
    it names. A package's ``__init__`` is not implied by importing one of its modules.

    Parameters
    ----------
    paths : list of Path
        The modules' files.

    Returns
    -------
    dict
        ``{module: {imported project module, ...}}`` (no self-imports).
    """
    files = {module_name(p): p for p in paths}
    graph: dict[str, set[str]] = {}
    for me, path in files.items():
        package = me if path.name == "__init__.py" else me.rpartition(".")[0]
        found: set[str] = set()
        todo: list[ast.AST] = [ast.parse(path.read_text(encoding="utf-8"))]
        while todo:
            node = todo.pop()
            if _type_checking_only(node):
                todo.extend(node.orelse)  # type: ignore[attr-defined]
                continue
            if isinstance(node, ast.Import):
                for alias in node.names:
                    name = alias.name
                    while name and name not in files:
                        name = name.rpartition(".")[0]
                    found.add(name)
            elif isinstance(node, ast.ImportFrom):
                module = node.module or ""
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    module = ".".join(base + ([module] if module else []))
                for alias in node.names:
                    found.add(
                        f"{module}.{alias.name}" if f"{module}.{alias.name}" in files else module
                    )
            todo.extend(ast.iter_child_nodes(node))
        graph[me] = {m for m in found if m in files and m != me}
    return graph


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The circles of an import graph: its strongly connected parts of two or more modules.

    Parameters
    ----------
    graph : dict
        ``{module: {imported module, ...}}``.

    Returns
    -------
    list of list of str
        Each circle's modules, sorted; the circles sorted.
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []
    for root in sorted(graph):  # Tarjan's algorithm, iterative
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        while work:
            v, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in stack:
                    low[v] = min(low[v], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                part = []
                while True:
                    w = stack.pop()
                    part.append(w)
                    if w == v:
                        break
                if len(part) > 1:
                    circles.append(sorted(part))
    return sorted(circles)


def test_the_circle_finder_finds_lazy_and_indirect_circles(tmp_path: Path) -> None:
    """Files outside the repository are named by their stem (:func:`module_name`)."""
    files = {
        "a.py": "import b\n",
        "b.py": "def f():\n    from c import g\n",  # lazy: counts
        "c.py": "import a.x\n",  # the longest module it names: a
        "d.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import e\n",
        "e.py": "from d import thing\n",  # d imports e for annotations only: no circle
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    graph = import_graph(sorted(tmp_path.glob("*.py")))
    assert graph == {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set(), "e": {"d"}}
    assert import_circles(graph) == [["a", "b", "c"]]
    assert import_circles({"f": {"g"}, "g": {"f", "h"}, "h": {"h"}}) == [["f", "g"]]


def test_no_import_circles() -> None:
    graph = import_graph(python_files("cosim", "models"))
    assert "cosim.verify.dispatch" in graph["cosim.verify.campaign"]  # the graph is read
    circles = import_circles(graph)
    new = [c for c in circles if c not in KNOWN_CIRCLES]
    assert not new, "modules that import each other (split by concern):\n" + "\n".join(
        " -> ".join(c) for c in new
    )
