"""Reproductions found by name: what ``ins-cosim reproduce NAME`` runs (entry points).

A reproduction is a module registered under the entry-point group :data:`GROUP`
(``ins_cosim.reproductions``) of any installed distribution: the entry point's name is
the command's ``NAME``, its value the module. ins-cosim registers its own reproductions
of the source papers this way (``pyproject.toml``); the engine never imports them. A
module is a reproduction when it offers :class:`Reproduction`. Nothing is imported
until a name is asked for (:func:`find`).

``ins-cosim reproduce NAME --update-docs`` writes the returned Markdown block into the
reproductions page (:data:`DOCS_PAGE`) between ``<!-- NAME:begin -->`` and
``<!-- NAME:end -->`` (:func:`update_docs`), after copying the figures it links to
beside the page (:func:`publish_figures`), so the published tables always come from
the code.
"""

from __future__ import annotations

import os
import re
import shutil
from importlib import metadata
from pathlib import Path
from types import ModuleType
from typing import Protocol, cast

from cosim.errors import UserError, did_you_mean

#: Entry-point group of reproductions (``NAME = "package.module"``).
GROUP = "ins_cosim.reproductions"

#: The page ``--update-docs`` writes into, relative to the working folder.
DOCS_PAGE = Path("docs") / "reproductions.md"


class ReproductionError(UserError):
    """An unknown or broken reproduction, or a page without its markers."""


class Reproduction(Protocol):
    """What a reproduction module offers.

    Attributes
    ----------
    DEFAULT_RUNS : int
        Monte Carlo runs of the published block.
    DEFAULT_SEED : int
        Campaign seed of the published block.
    DEFAULT_CASE : str
        The case ``--run I`` reruns without ``--case``.
    """

    DEFAULT_RUNS: int
    DEFAULT_SEED: int
    DEFAULT_CASE: str

    def reproduce(self, out_dir: Path, runs: int, seed: int) -> str:
        """Run every case, write the plots into ``out_dir``, return the Markdown block.

        Parameters
        ----------
        out_dir : Path
            Folder for the plots (exists).
        runs : int
            Monte Carlo runs.
        seed : int
            Campaign seed.

        Returns
        -------
        str
            Markdown: tables of the paper's figures beside ours, image links to the plots
            (relative to the working folder, or absolute).
        """
        ...

    def rerun(self, case: str, index: int, runs: int, seed: int) -> str:
        """Run ``index`` of one case alone, with the numbers it has in the whole reproduction.

        Parameters
        ----------
        case : str
            A case of the reproduction.
        index : int
            Run number within the case.
        runs : int
            Runs of the reproduction (as for :meth:`reproduce`).
        seed : int
            Campaign seed (as for :meth:`reproduce`).

        Returns
        -------
        str
            A few lines: the case, the run, its figures.
        """
        ...


def names() -> dict[str, str]:
    """Every registered reproduction, nothing imported.

    Returns
    -------
    dict
        ``{name: "module"}``, sorted by name (the first registration of a name).
    """
    found: dict[str, str] = {}
    for ep in metadata.entry_points(group=GROUP):
        found.setdefault(ep.name, ep.value)
    return dict(sorted(found.items()))


def find(name: str) -> Reproduction:
    """The reproduction registered as ``name``.

    Parameters
    ----------
    name : str
        An entry point's name of the group :data:`GROUP`.

    Returns
    -------
    Reproduction
        Its module (imported now).

    Raises
    ------
    ReproductionError
        An unknown name (with the known ones), or a module that fails to import or does
        not offer :class:`Reproduction`.
    """
    known = names()
    if name not in known:
        listed = ", ".join(known) or "none"
        raise ReproductionError(
            f"unknown reproduction '{name}'.{did_you_mean(name, list(known))} Known: {listed} "
            f"(a package adds its own through the entry-point group '{GROUP}')"
        )
    ep = metadata.EntryPoint(name, known[name], GROUP)
    try:
        module = ep.load()
    except Exception as exc:  # a third party's import error of any kind, reported as such
        raise ReproductionError(
            f"reproduction '{name}' cannot be loaded: entry point '{name} = {ep.value}' "
            f"failed with {type(exc).__name__}: {exc}; fix or reinstall that package"
        ) from exc
    missing = [
        a
        for a in ("reproduce", "rerun", "DEFAULT_RUNS", "DEFAULT_SEED", "DEFAULT_CASE")
        if not hasattr(module, a)
    ]
    if not isinstance(module, ModuleType) or missing:
        raise ReproductionError(
            f"reproduction '{name}': entry point '{name} = {ep.value}' lacks "
            f"{', '.join(missing) or 'a module'} (see cosim.reproductions.Reproduction)"
        )
    return cast(Reproduction, module)


def update_docs(page: Path, name: str, block: str) -> None:
    """Replace the text between ``<!-- name:begin -->`` and ``<!-- name:end -->`` of a page.

    Parameters
    ----------
    page : Path
        The Markdown page, rewritten in place.
    name : str
        Marker name, the reproduction's.
    block : str
        Markdown to put between the markers (trailing whitespace stripped, one newline
        added).

    Raises
    ------
    ReproductionError
        When the page or its markers are missing.
    """
    page = Path(page)
    pattern = check_page(name, page)
    text = page.read_text(encoding="utf-8")
    page.write_text(
        pattern.sub(lambda m: m.group(1) + block.rstrip() + "\n" + m.group(2), text),
        encoding="utf-8",
    )


def check_page(name: str, page: Path = DOCS_PAGE) -> re.Pattern[str]:
    """Check that a page has the markers of a reproduction's block.

    Parameters
    ----------
    name : str
        The reproduction's name.
    page : Path
        The page (default :data:`DOCS_PAGE`, relative to the working folder).

    Returns
    -------
    re.Pattern
        The pattern of the markers and the text between them.

    Raises
    ------
    ReproductionError
        When the page or its markers are missing.
    """
    page = Path(page)
    if not page.is_file():
        raise ReproductionError(
            f"{page}: no such page; run from the repository's root (where {DOCS_PAGE} is)"
        )
    begin, end = re.escape(f"<!-- {name}:begin -->"), re.escape(f"<!-- {name}:end -->")
    pattern = re.compile(rf"({begin}\n).*?({end})", re.S)
    if not pattern.search(page.read_text(encoding="utf-8")):
        raise ReproductionError(
            f"{page}: markers <!-- {name}:begin --> / <!-- {name}:end --> missing; add them "
            "where the block goes"
        )
    return pattern


_IMAGE = re.compile(r"(!\[[^\]]*\]\()([^)]+\.png)(\))")


def publish_figures(block: str, root: Path, page: Path, name: str) -> str:
    """Copy the PNGs a block links to beside the page, ``figures/<name>/``, and relink them.

    A reproduction writes its plots under ``out/`` (not in git); the page must show
    figures that are committed, so ``--update-docs`` publishes them first.

    Parameters
    ----------
    block : str
        Markdown with image links relative to ``root`` (or absolute).
    root : Path
        The folder the links are relative to (the working folder).
    page : Path
        The page the block goes into (relative to ``root``, or absolute).
    name : str
        The reproduction's name.

    Returns
    -------
    str
        The block with links relative to the page's folder (``figures/<name>/<file>.png``
        for a page in ``docs/``); a link to a missing file is left alone.
    """
    root = Path(root)
    page = page if Path(page).is_absolute() else root / page
    target = page.parent / "figures" / name
    target.mkdir(parents=True, exist_ok=True)

    def relink(m: re.Match[str]) -> str:
        src = Path(m.group(2))
        src = src if src.is_absolute() else root / src
        if not src.is_file():
            return m.group(0)
        shutil.copyfile(src, target / src.name)
        link = os.path.relpath(target / src.name, page.parent)
        return f"{m.group(1)}{Path(link).as_posix()}{m.group(3)}"

    return _IMAGE.sub(relink, block)


def publish(block: str, name: str, page: Path = DOCS_PAGE, root: Path | None = None) -> Path:
    """``--update-docs``: publish the block's figures and write it into the page.

    Parameters
    ----------
    block : str
        The reproduction's Markdown block (links relative to ``root``).
    name : str
        The reproduction's name (its markers).
    page : Path
        The page (default :data:`DOCS_PAGE`), relative to ``root`` or absolute.
    root : Path, optional
        The folder the block's links and the page are relative to (default: the
        working folder).

    Returns
    -------
    Path
        The page written.

    Raises
    ------
    ReproductionError
        The page or its markers are missing, or a file cannot be written.
    """
    root = Path.cwd() if root is None else Path(root)
    target = page if Path(page).is_absolute() else root / page
    check_page(name, target)  # before copying any figure
    try:
        update_docs(target, name, publish_figures(block, root, target, name))
    except OSError as exc:
        raise ReproductionError(f"{target}: {exc}") from exc
    return target
