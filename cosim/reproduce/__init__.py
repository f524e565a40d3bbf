"""Reproductions of the source papers (shared/SEEDS.md): one module per paper.

Each module ``seedNNN`` provides::

    def reproduce(out_dir: Path, runs: int, seed: int) -> str

which runs the paper's cases (campaigns included), writes its plots into ``out_dir``
and returns a Markdown block (tables of the paper's figures next to ours, with the
tolerance written next to each number). ``ins-cosim reproduce SEED --update-readme``
writes that block into README.md between ``<!-- SEED:begin -->`` and ``<!-- SEED:end -->``,
so the README's tables always come from the code.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

PAPERS = ("seed000", "seed001", "seed003")


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


def update_readme(readme: Path, name: str, block: str) -> None:
    """Replace the text between ``<!-- name:begin -->`` and ``<!-- name:end -->``.

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
