"""Model documentation pages, ``models/docs/<Model>.md``, generated from the models themselves.

Each page has three parts, each written in one place only:

1. the equations and conventions: the model module's docstring, turned from
   reStructuredText into Markdown (``literal`` -> `literal`, ``::`` blocks -> code
   blocks, underlined section titles -> ``###`` headings, Sphinx roles dropped);
2. the variable table, generated from the class's declarations (:attr:`Block.variables
   <models.block.Block.variables>`: name, causality, variability, type, unit, start,
   description);
3. hand-written notes (reference results, test coverage, worked examples), kept from
   the existing page below the line :data:`NOTES_MARKER`.

``python -m cosim.interop.modeldocs`` rewrites every page; ``--check`` only reports the
pages that are out of date (exit code 1), which the test suite runs.
"""

from __future__ import annotations

import inspect
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from cosim import models
from cosim.models.block import Block, Var

DOCS_DIR = Path(models.__file__).resolve().parent / "docs"

#: The line after which a page's hand-written notes start (kept as they are).
NOTES_MARKER = "<!-- notes: hand-written below this line, kept by the generator -->"

_ROLE = re.compile(r":(?:func|class|mod|meth|data|attr|obj|exc):`~?([^`<]+?)(?:\s*<([^>]+)>)?`")


def _start(var: Var) -> str:
    """A start value as the table shows it: ``(0, 0, 0)`` for vectors, ``%.10g`` for reals."""

    def one(x: object) -> str:
        if isinstance(x, bool):
            return "true" if x else "false"
        if isinstance(x, float):
            return f"{x:.10g}"
        return str(x)

    if var.is_vector:
        return "(" + ", ".join(one(x) for x in var.start) + ")"
    return one(var.start)


def variable_table(cls: type[Block]) -> str:
    """The Markdown table of a block's variables, in declaration order.

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass.

    Returns
    -------
    str
        Header, separator and one row per declared variable (vectors as ``name[n]``).
    """
    rows = [
        "| name | causality | variability | type | unit | start | description |",
        "|---|---|---|---|---|---|---|",
    ]
    for v in cls.variables:
        name = f"{v.name}[{v.size}]" if v.is_vector else v.name
        description = v.description.replace("|", "\\|")
        rows.append(
            f"| `{name}` | {v.causality} | {v.variability} | {v.kind} | {v.unit} | "
            f"{_start(v)} | {description} |"
        )
    return "\n".join(rows)


def rst_to_markdown(text: str) -> str:
    """The small reStructuredText subset of the model docstrings, as Markdown.

    Parameters
    ----------
    text : str
        A cleaned docstring (:func:`inspect.cleandoc`).

    Returns
    -------
    str
        ``literal`` -> `literal`; a paragraph ending in ``::`` ends in ``:`` and its
        indented block becomes a fenced code block; ``Title`` over a line of ``-`` or
        ``~`` -> ``### Title``; Sphinx roles (``:func:`x```) -> `x`.
    """
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if line.strip() and re.fullmatch(r"[-~=]{3,}", nxt.strip()) and len(nxt) >= len(line):
            out += [f"### {_inline(line.strip())}", ""]
            i += 2
            continue
        if line.rstrip().endswith("::"):
            head = line.rstrip()[:-2].rstrip()
            if head:
                out.append(_inline(head) + ":")
            i += 1
            block: list[str] = []
            while i < len(lines) and (not lines[i].strip() or lines[i].startswith(" ")):
                block.append(lines[i])
                i += 1
            while block and not block[-1].strip():
                block.pop()
            body = inspect.cleandoc("\n".join(block))
            out += ["", "```", *body.split("\n"), "```", ""]
            continue
        out.append(_inline(line))
        i += 1
    markdown = "\n".join(out)
    return re.sub(r"\n{3,}", "\n\n", markdown).strip() + "\n"


def _inline(line: str) -> str:
    line = _ROLE.sub(lambda m: f"`{m.group(2) or m.group(1)}`", line)
    return line.replace("``", "`")


#: Marks an input whose value is an increment over the communication step (its meaning
#: depends on the step ``h``): the page and ``docs/fmpy_users.md`` then say how to feed it.
STEP_DEPENDENT = "over THIS communication step"


def fmpy_example(cls: type[Block]) -> str:
    """The page's "With plain fmpy" section: host requirements and a runnable example.

    The example simulates the FMU alone for 100 default steps with fmpy's
    ``simulate_fmu`` (inputs at their start values) and prints the last value of its
    first outputs; ``tests/integration/test_install.py`` runs it in a virtual environment holding
    only fmpy, numpy and scipy.

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass.

    Returns
    -------
    str
        Markdown (no trailing newline).
    """
    outputs: list[str] = []
    for var in cls.variables:
        if var.causality == "output" and len(outputs) < 3:
            names = [f"{var.name}[{i + 1}]" for i in range(len(var.start))] if var.is_vector else []
            outputs.extend(names[: 3 - len(outputs)] or [var.name])
    step = f"{cls.default_step:.10g}"
    stepwise = [
        v.name for v in cls.variables if v.causality == "input" and STEP_DEPENDENT in v.description
    ]
    names = {var.name for var in cls.variables}
    starts = ['"seed": 1'] if "seed" in names else []
    starts += ['"grade": 2'] if "grade" in names else []  # tactical: grade 0 is a perfect IMU
    quoted = ", ".join(f'"{o}"' for o in outputs)
    lines = [
        "The FMU needs, in the Python that loads it, numpy and scipy only (pythonfmu's "
        "runtime is packed inside the FMU): `pip install fmpy numpy scipy`. Its "
        "`documentation/index.html` is this page. Example (the file "
        f"`{cls.__name__}.fmu` in the working folder; inputs stay at their start values):",
        "",
        "```python",
        "from fmpy import simulate_fmu",
        "",
        "result = simulate_fmu(",
        f'    "{cls.__name__}.fmu",',
        f"    stop_time={100 * cls.default_step:.10g},",
        f"    output_interval={step},  # the communication step h [s]",
        *([f"    start_values={{{', '.join(starts)}}},"] if starts else []),
        f"    output=[{quoted}],",
        ")",
        'print(result["time"][-1])',
        *(f'print("{o}", result["{o}"][-1])' for o in outputs),
        "```",
    ]
    if stepwise:
        listed = ", ".join(f"`{n}`" for n in stepwise)
        lines += [
            "",
            f"Inputs {listed} are increments over the communication step `[t, t + h]`, not "
            "rates: a host that changes `h` (fmpy's `output_interval`) must feed the "
            "increment over its own `h` (rate times `h`), or the outputs scale with the "
            "ratio of the two steps. See docs/fmpy_users.md of ins-cosim.",
        ]
    return "\n".join(lines)


def render(cls: type[Block], notes: str = "") -> str:
    """The page of one block class.

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass defined in a module of ``models``.
    notes : str
        The hand-written notes to append below :data:`NOTES_MARKER` ("" for none).

    Returns
    -------
    str
        The whole Markdown page, ending with a newline.
    """
    module = sys.modules[cls.__module__]
    path = f"{cls.__module__.removeprefix('cosim.').replace('.', '/')}.py"
    summary = (inspect.getdoc(cls) or cls.__name__).split("\n")[0]
    parts = [
        f"# {cls.__name__}",
        "",
        f"{summary} Module `{path}`; FMU `fmus/build/{cls.__name__}.fmu` (`make fmus`, or "
        "`ins-cosim fmus --build` from an installed wheel); "
        f"reference result `models/reference/{cls.__name__}.csv` (the block alone, default "
        "parameters, the drive of `cosim/interop/references.py`; `tests/models/test_fmus.py` "
        "compares the class and the FMU with it).",
        "",
        f"<!-- generated by `python -m cosim.interop.modeldocs` from {path}: edit the module "
        "docstring and the variable declarations there -->",
        "",
        "## Model",
        "",
        rst_to_markdown(inspect.getdoc(module) or "").rstrip("\n"),
        "",
        "## Variables",
        "",
        variable_table(cls),
        "",
        "## With plain fmpy",
        "",
        fmpy_example(cls),
        "",
        NOTES_MARKER,
    ]
    return page_text(parts, notes)


def page_text(parts: Sequence[str], notes: str) -> str:
    """A generated page: its lines, then the hand-written notes kept from the old page.

    Parameters
    ----------
    parts : sequence of str
        The generated lines, the last :data:`NOTES_MARKER`.
    notes : str
        The notes (from :func:`notes_of`; blank lines around them are dropped).

    Returns
    -------
    str
        The Markdown page, ending with a newline.
    """
    text = "\n".join(parts) + "\n"
    notes = notes.strip("\n")
    return text + ("\n" + notes + "\n" if notes else "")


def notes_of(page: Path) -> str:
    """The hand-written notes of an existing page (what follows :data:`NOTES_MARKER`).

    Parameters
    ----------
    page : Path
        A ``models/docs/<Model>.md`` file; a missing file has no notes.

    Returns
    -------
    str
        The notes ("" when the file or the marker is missing).
    """
    if not page.is_file():
        return ""
    text = page.read_text(encoding="utf-8")
    _, found, notes = text.partition(NOTES_MARKER)
    return notes if found else ""


def outdated(docs_dir: Path = DOCS_DIR) -> dict[str, str]:
    """Pages whose text differs from what :func:`render` makes of their model now.

    Parameters
    ----------
    docs_dir : Path
        Folder of the pages.

    Returns
    -------
    dict of str to str
        Model name -> its up-to-date page text, for every page that is missing or stale.
    """
    return stale_pages(models.truth_models(), docs_dir, lambda name, cls, notes: render(cls, notes))


def stale_pages(
    blocks: Mapping[str, type[Block]],
    docs_dir: Path,
    render_page: Callable[[str, type[Block], str], str],
) -> dict[str, str]:
    """The pages ``<docs_dir>/<name>.md`` that are missing or differ from their block's.

    Parameters
    ----------
    blocks : mapping of str to Block subclass
        Page name -> its block class.
    docs_dir : Path
        Folder of the pages.
    render_page : callable ``render_page(name, cls, notes) -> str``
        The page of one block, with the notes kept from its old page.

    Returns
    -------
    dict of str to str
        Name -> its up-to-date page text, for every missing or stale page.
    """
    stale = {}
    for name, cls in blocks.items():
        page = docs_dir / f"{name}.md"
        text = render_page(name, cls, notes_of(page))
        if not page.is_file() or page.read_text(encoding="utf-8") != text:
            stale[name] = text
    return stale


def main(argv: Sequence[str] | None = None) -> int:
    """Rewrite the stale pages, or with ``--check`` list them.

    Parameters
    ----------
    argv : sequence of str, optional
        Command-line arguments (``--check``); None for ``sys.argv[1:]``.

    Returns
    -------
    int
        0 when every page is up to date (or was rewritten), 1 for ``--check`` with stale
        pages.
    """
    return write_or_check(argv, outdated(), DOCS_DIR, "models/docs", "cosim.interop.modeldocs")


def write_or_check(
    argv: Sequence[str] | None, stale: Mapping[str, str], docs_dir: Path, shown: str, module: str
) -> int:
    """Write the stale pages, or with ``--check`` in ``argv`` name them (the generators' main).

    Parameters
    ----------
    argv : sequence of str, optional
        Command-line arguments (``--check``); None for ``sys.argv[1:]``.
    stale : mapping of str to str
        Page name -> its up-to-date text (from :func:`stale_pages`).
    docs_dir : Path
        Folder of the pages (made when missing).
    shown : str
        The folder as the messages name it (``models/docs``).
    module : str
        The generator, for ``python -m <module>`` in the messages.

    Returns
    -------
    int
        0 when every page is up to date (or was rewritten), 1 for ``--check`` with stale
        pages.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if "--check" in args:
        for name in stale:
            print(f"{shown}/{name}.md is out of date: python -m {module}")
        return 1 if stale else 0
    docs_dir.mkdir(parents=True, exist_ok=True)
    for name, text in stale.items():
        (docs_dir / f"{name}.md").write_text(text, encoding="utf-8")
        print(f"wrote {shown}/{name}.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
