"""Reproductions of the source papers (README, "References"): one module per paper.

Each module ``seedNNN`` provides::

    def reproduce(out_dir: Path, runs: int, seed: int) -> str

which runs the paper's cases (campaigns included), writes its plots into ``out_dir``
and returns a Markdown block (tables of the paper's figures next to ours, with the
tolerance written next to each number). ``ins-cosim reproduce SEED --update-readme``
writes that block into README.md between ``<!-- SEED:begin -->`` and ``<!-- SEED:end -->``,
so the README's tables always come from the code. Each module also provides
``rerun(case, index, runs, seed) -> str``: one run of one case alone, with the numbers
it has in the whole reproduction (``ins-cosim reproduce SEED --case CASE --run I``).
"""

from __future__ import annotations

import importlib
import re
import shutil
from pathlib import Path

PAPERS = ("seed000", "seed001", "seed003")

#: Runs and campaign seed that produced each README block (``ins-cosim reproduce`` defaults).
DEFAULTS: dict[str, tuple[int, int]] = {
    "seed000": (30, 2024),
    "seed001": (30, 2011),
    "seed003": (50, 2024),
}


def reproduce(name: str, out_dir: Path, runs: int, seed: int) -> str:
    """Run one paper's reproduction and return its Markdown block.

    Parameters
    ----------
    name : str
        ``"seed000"``, ``"seed001"`` or ``"seed003"``.
    out_dir : Path
        Folder for plots and tables.
    runs : int
        Monte Carlo runs per campaign.
    seed : int
        Campaign seed.

    Returns
    -------
    str
        Markdown.
    """
    if name not in PAPERS:
        raise ValueError(f"expected one of {', '.join(PAPERS)}, got {name!r}")
    module = importlib.import_module(f"{__name__}.{name}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return module.reproduce(out_dir, runs, seed)


#: The case ``ins-cosim reproduce PAPER --run I`` reruns when no ``--case`` is given.
DEFAULT_CASES = {"seed000": "main", "seed001": "campaign modelled", "seed003": "static"}


def rerun(name: str, case: str | None, index: int, runs: int, seed: int) -> str:
    """Rerun one run of one case of a reproduction alone and describe its numbers.

    Every reproduction runs through the campaign engine, whose runs depend only on the
    campaign seed, the run's index and its case: the run alone gives the numbers it has
    in the whole reproduction.

    Parameters
    ----------
    name : str
        ``"seed000"``, ``"seed001"`` or ``"seed003"``.
    case : str or None
        The case (the module's ``rerun`` lists them); None: :data:`DEFAULT_CASES`.
    index : int
        Run number within the case.
    runs : int
        Runs of the reproduction (as for :func:`reproduce`).
    seed : int
        Campaign seed (as for :func:`reproduce`).

    Returns
    -------
    str
        A few lines: the case, the run, its per-run figures.
    """
    if name not in PAPERS:
        raise ValueError(f"expected one of {', '.join(PAPERS)}, got {name!r}")
    module = importlib.import_module(f"{__name__}.{name}")
    return module.rerun(case or DEFAULT_CASES[name], int(index), int(runs), int(seed))


def update_readme(readme: Path, name: str, block: str) -> None:
    """Replace the text between ``<!-- name:begin -->`` and ``<!-- name:end -->``.

    Parameters
    ----------
    readme : Path
        The README file, rewritten in place.
    name : str
        Marker name, the paper (``"seed000"``, ``"seed001"`` or ``"seed003"``).
    block : str
        Markdown to put between the markers (trailing whitespace stripped, one newline
        added).

    Raises
    ------
    ValueError
        When the markers are missing from the README.
    """
    text = Path(readme).read_text()
    pattern = re.compile(rf"(<!-- {name}:begin -->\n).*?(<!-- {name}:end -->)", re.S)
    if not pattern.search(text):
        raise ValueError(f"{readme}: markers <!-- {name}:begin --> / <!-- {name}:end --> missing")
    Path(readme).write_text(
        pattern.sub(lambda m: m.group(1) + block.rstrip() + "\n" + m.group(2), text)
    )


_IMAGE = re.compile(r"(!\[[^\]]*\]\()([^)]+\.png)(\))")


def publish_figures(block: str, root: Path, paper: str) -> str:
    """Copy the PNGs a block links to into ``docs/figures/<paper>/`` and relink them.

    The reproduction writes its plots under ``out/`` (not in git); the README must show
    figures that are committed, so ``--update-readme`` publishes them first.

    Parameters
    ----------
    block : str
        Markdown with image links relative to ``root`` (or absolute).
    root : Path
        The repository root (where README.md is).
    paper : str
        ``"seed000"``, ``"seed001"`` or ``"seed003"``.

    Returns
    -------
    str
        The block with links to ``docs/figures/<paper>/<name>.png``.
    """
    target = Path(root) / "docs" / "figures" / paper
    target.mkdir(parents=True, exist_ok=True)

    def relink(m: re.Match[str]) -> str:
        src = Path(m.group(2))
        src = src if src.is_absolute() else Path(root) / src
        if not src.is_file():
            return m.group(0)
        shutil.copyfile(src, target / src.name)
        return f"{m.group(1)}docs/figures/{paper}/{src.name}{m.group(3)}"

    return _IMAGE.sub(relink, block)
