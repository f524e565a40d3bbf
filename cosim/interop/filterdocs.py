"""Filter documentation pages, ``docs/filters/<Filter>.md``, generated from the filter blocks.

The blocks a scenario names besides the truth models (the project's own entry points of
``ins_cosim.blocks`` in ``pyproject.toml``: the alignment filters and the log replays) get
one page each, written as the model pages are (:mod:`cosim.interop.modeldocs`):

1. the parameters, inputs and outputs as tables generated from the class's declarations
   (name, unit, default, meaning), a default also shown in the engineering unit a
   scenario would write (``0.01745329252 rad`` -> ``1 deg``); an input whose name ends
   in ``_true`` is marked as truth (leave it unconnected on a log:
   :mod:`cosim.verify.estimates`);
2. the method: the filter module's docstring, turned into Markdown;
3. hand-written notes, kept from the existing page below
   :data:`~cosim.interop.modeldocs.NOTES_MARKER`.

``python -m cosim.interop.filterdocs`` rewrites every stale page (run it after changing a
filter's declarations or docstring); ``--check`` lists them and exits 1, which the test
suite runs.
"""

from __future__ import annotations

import importlib
import inspect
import math
import sys
import tomllib
from collections.abc import Sequence
from pathlib import Path

from cosim.interop.modeldocs import (
    NOTES_MARKER,
    page_text,
    rst_to_markdown,
    stale_pages,
    write_or_check,
)
from cosim.models.block import Block, Var
from cosim.units import conversion_factor

ROOT = Path(__file__).resolve().parents[2]
DOCS_DIR = ROOT / "docs" / "filters"
PYPROJECT = ROOT / "pyproject.toml"
GROUP = "ins_cosim.blocks"
#: SI unit -> the engineering units a default is also shown in (the first that gives a
#: number between 0.1 and 1e5, else the last).
ENGINEERING = {
    "rad": ("deg", "arcmin", "arcsec"),
    "rad/s": ("deg/s", "deg/h"),
    "m/s2": ("mg", "ug"),
    "rad/sqrt(s)": ("deg/sqrt(h)", "deg/h/sqrt(Hz)"),
    "m/s/sqrt(s)": ("ug/sqrt(Hz)",),
}


def filter_blocks(pyproject: Path = PYPROJECT) -> dict[str, type[Block]]:
    """The project's own filter and replay blocks, by scenario name.

    Parameters
    ----------
    pyproject : Path
        The project's ``pyproject.toml`` (its ``ins_cosim.blocks`` entry points).

    Returns
    -------
    dict
        Name -> class, sorted by name, for every entry point of a ``cosim.`` module.
    """
    data = tomllib.loads(pyproject.read_text(encoding="utf-8"))
    points = data.get("project", {}).get("entry-points", {}).get(GROUP, {})
    out = {}
    for name, target in sorted(points.items()):
        module, _, attr = target.partition(":")
        if module.split(".")[0] == "cosim":
            out[name] = getattr(importlib.import_module(module), attr)
    return out


def _number(x: object) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        return f"{x:.10g}"
    return str(x)


def _engineering(x: float, unit: str) -> str:
    """``x`` [unit] in the first engineering unit that reads well, or ""."""
    options = ENGINEERING.get(unit, ())
    if not options or x == 0.0 or not math.isfinite(x):
        return ""
    for target in options:
        y = x * conversion_factor(unit, target)
        if 0.1 <= abs(y) < 1e5:
            break
    return f"{y:.6g} {target}"


def default_text(var: Var) -> str:
    """A declared default as the page shows it: SI value, then the engineering one.

    Parameters
    ----------
    var : Var
        A declared variable.

    Returns
    -------
    str
        ``"0.01745329252 (1 deg)"``; vectors as ``(a, b, c)``.
    """
    values = list(var.start) if var.is_vector else [var.start]
    si = ", ".join(_number(v) for v in values)
    si = f"({si})" if var.is_vector else si
    if var.kind != "Real":
        return si
    eng = [_engineering(float(v), var.unit) for v in values]
    if not any(eng):
        return si
    same = len(set(eng)) == 1 and var.is_vector
    shown = eng[0] if same else ", ".join(e or "0" for e in eng)
    return f"{si} ({shown}{' each' if same else ''})"


def _rows(cls: type[Block], causality: str) -> list[str]:
    rows = []
    for v in cls.variables:
        if v.causality != causality:
            continue
        name = f"{v.name}[{v.size}]" if v.is_vector else v.name
        meaning = v.description.replace("|", "\\|")
        if causality == "input" and v.name.endswith("_true"):
            meaning = meaning.removeprefix("truth: ")
            meaning = f"**truth**: {meaning}; leave unconnected on a log"
        if causality == "output":
            rows.append(f"| `{name}` | {v.unit} | {meaning} |")
        else:
            rows.append(f"| `{name}` | {v.unit} | {default_text(v)} | {meaning} |")
    return rows


def render(cls: type[Block], name: str, notes: str = "") -> str:
    """The page of one filter block.

    Parameters
    ----------
    cls : type
        The block class.
    name : str
        Its scenario name (``model = "<name>"``).
    notes : str
        Hand-written notes to keep below the marker ("" for none).

    Returns
    -------
    str
        The Markdown page, ending with a newline.
    """
    module = sys.modules[cls.__module__]
    path = Path(inspect.getfile(cls)).resolve().relative_to(ROOT).as_posix()
    summary = (inspect.getdoc(cls) or name).split("\n")[0]
    head = ["| name | unit | default | meaning |", "|---|---|---|---|"]
    parts = [
        f"# {name}",
        "",
        f'{summary} Module `{path}`; in a scenario `model = "{name}"`. Parameters are '
        'given in any unit of their kind (`"1 deg"`, `"0.02 deg/h"`); the tables show '
        "the declared SI unit, the default in it and in an engineering unit.",
        "",
        f"<!-- generated by `python -m cosim.interop.filterdocs` from {path}: edit the "
        "declarations and the module docstring there -->",
        "",
        "## Parameters",
        "",
        *head,
        *_rows(cls, "parameter"),
        "",
        "## Inputs",
        "",
        "| name | unit | start | meaning |",
        "|---|---|---|---|",
        *_rows(cls, "input"),
        "",
        "## Outputs",
        "",
        "| name | unit | meaning |",
        "|---|---|---|",
        *_rows(cls, "output"),
        "",
        "## Method",
        "",
        rst_to_markdown(inspect.getdoc(module) or "").rstrip("\n"),
        "",
        NOTES_MARKER,
    ]
    return page_text(parts, notes)


def outdated(docs_dir: Path = DOCS_DIR) -> dict[str, str]:
    """Pages whose text differs from what :func:`render` makes of their filter now.

    Parameters
    ----------
    docs_dir : Path
        Folder of the pages.

    Returns
    -------
    dict of str to str
        Filter name -> its up-to-date page text, for every missing or stale page.
    """
    return stale_pages(filter_blocks(), docs_dir, lambda name, cls, notes: render(cls, name, notes))


def main(argv: Sequence[str] | None = None) -> int:
    """Rewrite the stale pages, or with ``--check`` list them.

    Parameters
    ----------
    argv : sequence of str, optional
        ``["--check"]`` or nothing; None for ``sys.argv[1:]``.

    Returns
    -------
    int
        0 when every page is up to date (or was rewritten); 1 for ``--check`` with stale
        pages.
    """
    return write_or_check(argv, outdated(), DOCS_DIR, "docs/filters", "cosim.interop.filterdocs")


if __name__ == "__main__":
    sys.exit(main())
