"""Every command and Python example of the README and of the documentation site runs.

The conventions (docs/contributing.md, "Examples in the docs"):

- a fenced ``console`` block is a shell session: each line starting with ``$ `` is a
  command (a trailing ``\\`` continues it on the next line), the other lines are output and
  are not compared (they hold timings);
- a ``sh``, ``bash`` or ``shell`` block is a script, run as a whole in one shell;
- a ``python`` block is a program, run with the environment's interpreter;
- the blocks of one page run in order in one scratch folder (copies of ``scenarios/``,
  ``benchmarks/`` and ``tests/fixtures/``, links to ``fmus/``, to each built FMU by its
  bare name and to ``.venv``), the environment's ``bin/`` first on ``PATH``;
- every command exits 0 unless ``<!-- exit: 0,2 -->`` right before the fence allows more;
- ``<!-- no-run: reason -->`` right before a fence keeps the block from running; the
  blocks so marked are counted per page in ``NO_RUN`` below, so that a new one is a
  decision this file records, never a silent skip; ``<!-- slow: reason -->`` runs the
  page's other blocks by default and the whole page under ``make test-slow``.

A ``text`` block (or any other language) that holds a ``$ `` line is refused: a command
shown must be a ``console`` block, and so run. The site itself must build with
``mkdocs build --strict``, with every page in its navigation.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

#: The repository root: the folder above this file that holds mkdocs.yml (wherever tests/ nests it).
ROOT = next(p for p in Path(__file__).resolve().parents if (p / "mkdocs.yml").is_file())
BIN = Path(sys.executable).parent

#: Fence languages that are examples to run; every other language is data (toml, text, ...).
SHELL = {"sh", "bash", "shell"}
RUNNABLE = SHELL | {"console", "python"}

#: Pages (relative to the repository root) and how many of their blocks are marked no-run.
#: A block that must not run is a decision: add its page here with the new count.
NO_RUN = {
    "README.md": 1,  # make demo / make test: the repository's own set-up
    "docs/getting_started.md": 1,  # the same two commands
    "docs/install.md": 2,  # a wheel user's session (tests/integration/test_install.py runs it)
    "docs/real_sensor_data.md": 1,  # make docs: rewrites the repository's pages
    "docs/reproductions.md": 3,  # the full reproductions rewrite this page (10-30 minutes)
    "docs/verification.md": 1,  # the synopsis of verify and plan, with placeholders
}


@dataclass(frozen=True)
class Block:
    """One fenced code block of a page.

    Attributes
    ----------
    page : Path
        The page, relative to the repository root.
    line : int
        1-based line of the opening fence.
    lang : str
        The fence's language (``""`` when it has none).
    code : str
        The block's text, dedented by the fence's indentation.
    no_run, slow : str or None
        The reason given by a ``no-run`` or ``slow`` marker right before the fence.
    exit_codes : tuple of int
        The exit codes each command may return (``(0,)`` unless an ``exit`` marker says).
    """

    page: Path
    line: int
    lang: str
    code: str
    no_run: str | None
    slow: str | None
    exit_codes: tuple[int, ...]

    @property
    def where(self) -> str:
        """``page:line`` of the opening fence."""
        return f"{self.page}:{self.line}"


FENCE = re.compile(r"^(?P<indent>\s*)(?P<ticks>```+)(?P<lang>[\w+-]*)\s*$")
MARKER = re.compile(r"^<!--\s*(?P<key>no-run|slow|exit)\s*:\s*(?P<value>.*?)\s*-->$")


def pages() -> list[Path]:
    """The README, every page of docs/ (not the hooks or helpers' notes) and the model pages."""
    found = [ROOT / "README.md"]
    found += sorted(
        p
        for p in (ROOT / "docs").rglob("*.md")
        if not {"hooks", "design"} & set(p.relative_to(ROOT / "docs").parts[:-1])
    )
    found += sorted((ROOT / "models" / "docs").glob("*.md"))
    return [p.relative_to(ROOT) for p in found]


def blocks(page: Path, text: str | None = None) -> list[Block]:
    """The fenced blocks of ``page`` (relative to the root), with their markers.

    Parameters
    ----------
    page : Path
        The page, relative to the repository root.
    text : str, optional
        The page's text (default: read from the file).

    Returns
    -------
    list of Block
        In page order.

    Raises
    ------
    ValueError
        When a fence is not closed or a marker is malformed.
    """
    if text is None:
        text = (ROOT / page).read_text(encoding="utf-8")
    lines = text.splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            i += 1
            continue
        indent, ticks = len(m["indent"]), m["ticks"]
        markers: dict[str, str] = {}
        j = i - 1
        while j >= 0 and (mm := MARKER.match(lines[j].strip())):
            if mm["key"] in markers:
                raise ValueError(f"{page}:{j + 1}: two '{mm['key']}' markers on one block")
            markers[mm["key"]] = mm["value"]
            j -= 1
        end = i + 1
        while end < len(lines) and lines[end].strip() != ticks:
            end += 1
        if end == len(lines):
            raise ValueError(f"{page}:{i + 1}: the fence is never closed")
        body = lines[i + 1 : end]
        code = "\n".join(ln[indent:] if ln[:indent].strip() == "" else ln.lstrip() for ln in body)
        codes = (0,)
        if "exit" in markers:
            codes = tuple(int(c) for c in markers["exit"].split(","))
        for key in ("no-run", "slow"):
            if key in markers and not markers[key]:
                raise ValueError(f"{page}:{i + 1}: a '{key}' marker needs its reason")
        found.append(
            Block(
                page,
                i + 1,
                m["lang"],
                code + "\n",
                markers.get("no-run"),
                markers.get("slow"),
                codes,
            )
        )
        i = end + 1
    return found


def console_script(code: str) -> str:
    """The commands of a console block (lines after ``$ ``, with ``\\`` continuations)."""
    commands, current = [], None
    for ln in code.splitlines():
        if current is not None:
            current.append(ln)
        elif ln.startswith("$ "):
            current = [ln[2:]]
        else:
            continue
        if not ln.rstrip().endswith("\\"):
            commands.append("\n".join(current))
            current = None
    if current is not None:
        commands.append("\n".join(current))
    return "\n".join(commands) + "\n"


def shell_script(code: str, exit_codes: tuple[int, ...]) -> str:
    """A bash script that stops at the first command whose exit code is not allowed."""
    allowed = " ".join(str(c) for c in exit_codes)
    trap = (
        "trap 'rc=$?; case \" "
        + allowed
        + ' " in *" $rc "*) ;; *) echo "exit code $rc: $BASH_COMMAND" >&2; exit $rc;; esac\' ERR\n'
    )
    return "set -o pipefail\n" + trap + code + "exit 0\n"  # the trap let every exit code pass


def scratch(folder: Path) -> dict[str, str]:
    """Make ``folder`` a place where the docs' commands run; return their environment."""
    shutil.copytree(ROOT / "scenarios", folder / "scenarios")
    shutil.copytree(
        ROOT / "benchmarks",
        folder / "benchmarks",
        ignore=shutil.ignore_patterns("__pycache__", "results.json"),
    )
    shutil.copytree(
        ROOT / "tests" / "fixtures",
        folder / "tests" / "fixtures",
        ignore=shutil.ignore_patterns("__pycache__"),
    )
    (folder / "fmus").symlink_to(ROOT / "fmus", target_is_directory=True)
    for fmu in sorted((ROOT / "fmus" / "build").glob("*.fmu")):
        (folder / fmu.name).symlink_to(fmu)
    if (ROOT / ".venv").is_dir():
        (folder / ".venv").symlink_to(ROOT / ".venv", target_is_directory=True)
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    env.pop("PYTHONPATH", None)
    return env


def run_block(block: Block, folder: Path, env: dict[str, str], n: int) -> None:
    """Run one block in ``folder``; fail with its output when a command fails."""
    if block.lang == "python":
        program = folder / f"example_{n}.py"
        program.write_text(block.code, encoding="utf-8")
        argv = [sys.executable, program.name]
        codes = block.exit_codes
    else:
        body = console_script(block.code) if block.lang == "console" else block.code
        argv = ["bash", "-c", shell_script(body, block.exit_codes)]
        codes = (0,)
    res = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True, timeout=3000)
    assert res.returncode in codes, (
        f"{block.where}: the {block.lang} example exits {res.returncode}\n"
        f"--- stdout\n{res.stdout[-3000:]}\n--- stderr\n{res.stderr[-3000:]}"
    )


ALL = {page: blocks(page) for page in pages()}


#: The model pages are generated from one template (``cosim.interop.modeldocs``): the
#: default suite runs the example of the first one, ``make test-slow`` every one (each
#: loads its FMU in a new interpreter, about 1.5 s).
MODEL_PAGES = [page for page in ALL if page.parts[:2] == ("models", "docs")]


#: A slow page may hold a campaign of hundreds of runs (campaigns.md: 400).
SLOW = [pytest.mark.slow, pytest.mark.timeout(3600)]


def cases() -> list:
    """One default case per page with runnable blocks, and a slow one when it has slow ones."""
    out = []
    for page, found in ALL.items():
        runnable = [b for b in found if b.lang in RUNNABLE and b.no_run is None]
        if not runnable:
            continue
        if page in MODEL_PAGES[1:]:
            out.append(pytest.param(page, True, id=f"{page}-all", marks=SLOW))
            continue
        if any(b.slow is None for b in runnable):
            out.append(pytest.param(page, False, id=f"{page}"))
        if any(b.slow is not None for b in runnable):
            out.append(pytest.param(page, True, id=f"{page}-all", marks=SLOW))
    return out


@pytest.mark.parametrize(("page", "with_slow"), cases())
def test_examples_of_the_page_run(page: Path, with_slow: bool, tmp_path: Path) -> None:
    """Each runnable block of ``page`` exits with an allowed code, in page order."""
    if not (ROOT / "fmus" / "build").is_dir():
        pytest.fail("fmus/build is missing: run `make fmus` first")
    env = scratch(tmp_path)
    ran = 0
    for n, block in enumerate(ALL[page]):
        if block.lang not in RUNNABLE or block.no_run is not None:
            continue
        if block.slow is not None and not with_slow:
            continue
        run_block(block, tmp_path, env, n)
        ran += 1
    assert ran > 0


def test_no_run_blocks_are_the_recorded_ones() -> None:
    """The no-run blocks per page are exactly those counted in ``NO_RUN`` (each with a reason)."""
    found: dict[str, list[str]] = {}
    for page, page_blocks in ALL.items():
        for b in page_blocks:
            if b.no_run is not None:
                found.setdefault(str(page), []).append(f"{b.where} ({b.lang}): {b.no_run}")
    counts = {page: len(v) for page, v in found.items()}
    listing = "\n".join(line for v in found.values() for line in v)
    assert counts == NO_RUN, f"no-run blocks changed; update NO_RUN:\n{listing}"


def test_commands_are_shown_in_runnable_blocks() -> None:
    """No ``$ `` command hides in a text block; markers sit only on blocks that can run."""
    problems = []
    for page_blocks in ALL.values():
        for b in page_blocks:
            has_prompt = any(ln.startswith("$ ") for ln in b.code.splitlines())
            if b.lang not in RUNNABLE and has_prompt:
                problems.append(f"{b.where}: a '$ ' command in a '{b.lang}' block: use console")
            if b.lang not in RUNNABLE and (b.no_run or b.slow or b.exit_codes != (0,)):
                problems.append(f"{b.where}: a run marker on a '{b.lang}' block")
            if b.lang == "console" and not has_prompt:
                problems.append(f"{b.where}: a console block without a '$ ' command")
    assert not problems, "\n".join(problems)


def test_the_conventions_are_those_parsed() -> None:
    """The parser reads markers, indented fences, prompts and continuations as documented."""
    text = (
        "intro\n\n<!-- slow: minutes -->\n<!-- exit: 0,2 -->\n   ```console\n"
        "   $ echo a \\\n   >   b\n   a b\n   $ true\n   ```\n\n```toml\nx = 1\n```\n"
    )
    (b, data) = blocks(Path("example.md"), text)
    assert (b.lang, b.line, b.slow, b.exit_codes, b.no_run) == (
        "console",
        5,
        "minutes",
        (0, 2),
        None,
    )
    assert console_script(b.code) == "echo a \\\n>   b\ntrue\n"
    assert data.lang == "toml" and data.code == "x = 1\n"
    allowed = shell_script("bash -c 'exit 2'\necho after\n", (0, 2))
    res = subprocess.run(["bash", "-c", allowed], capture_output=True, text=True)
    assert (res.returncode, res.stdout) == (0, "after\n")
    last = shell_script("echo before\nbash -c 'exit 2'\n", (0, 2))
    assert subprocess.run(["bash", "-c", last], capture_output=True).returncode == 0
    refused = shell_script("bash -c 'exit 3'\necho after\n", (0, 2))
    res = subprocess.run(["bash", "-c", refused], capture_output=True, text=True)
    assert (res.returncode, res.stdout) == (3, "")
    assert "exit code 3" in res.stderr


DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b|\b(?:morning|afternoon)\b|\bthis session\b")


def test_no_dated_measurement_outside_the_changelog() -> None:
    """Dates and session notes belong to CHANGELOG.md, not to the README or the site's pages.

    The one date allowed is the start time inside the example message of a campaign lock.
    """
    hits = []
    for page in pages():
        for n, line in enumerate((ROOT / page).read_text(encoding="utf-8").splitlines(), 1):
            if DATE.search(line) and "in use by another campaign" not in line:
                hits.append(f"{page}:{n}: {line.strip()[:100]}")
    assert not hits, "\n".join(hits)


def test_readme_links_resolve_from_the_repository_root() -> None:
    """Every relative link of the README names a file or folder of the repository (GitHub)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [link for link in links if "://" not in link]
    assert local, "the README links no page"
    missing = [link for link in local if not (ROOT / link).exists()]
    assert not missing, missing


def nav_pages(nav: list) -> set[str]:
    """Every page path named in an mkdocs ``nav`` (nested lists and ``title: path`` maps)."""
    out: set[str] = set()
    for item in nav:
        values = item.values() if isinstance(item, dict) else [item]
        for v in values:
            if isinstance(v, list):
                out |= nav_pages(v)
            elif isinstance(v, str) and not v.startswith(("http://", "https://")):
                out.add(v)
    return out


def test_every_page_is_in_the_navigation() -> None:
    """A page of docs/ or models/docs/ missing from mkdocs.yml's nav is unreachable: refuse it."""
    yaml = pytest.importorskip("yaml", reason="PyYAML comes with mkdocs (the docs extra)")

    class Loader(yaml.SafeLoader):
        """Reads mkdocs.yml's python tags as plain strings (only the nav is needed)."""

    Loader.add_multi_constructor("tag:yaml.org,2002:python/", lambda *a: None)
    config = yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=Loader)
    in_nav = nav_pages(config["nav"])
    site = {str(p.relative_to("docs")) for p in pages() if p.parts[0] == "docs"}
    site |= {f"models/{p.name}" for p in pages() if p.parts[:2] == ("models", "docs")}
    site.add("changelog.md")
    assert sorted(site - in_nav) == [], "pages not in mkdocs.yml's nav"
    assert sorted(in_nav - site) == [], "nav entries without a page"


def test_the_site_builds_strictly(tmp_path: Path) -> None:
    """``mkdocs build --strict``: every page renders and every relative link resolves."""
    pytest.importorskip("mkdocs", reason="mkdocs is not installed (pip install -e '.[docs]')")
    pytest.importorskip("material", reason="mkdocs-material is not installed (the docs extra)")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    res = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr[-4000:]
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "models" / "StrapdownImu.html").is_file()
    assert (tmp_path / "site" / "changelog.html").is_file()
