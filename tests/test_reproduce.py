"""The reproduction tables and figures of docs/reproductions.md come from code (cosim.reproduce)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cosim.errors import UserError
from cosim.reproduce import DEFAULTS, PAPERS, publish_figures, reproduce, update_readme

ROOT = Path(__file__).resolve().parents[1]


def test_update_readme_replaces_only_between_markers(tmp_path: Path) -> None:
    readme = tmp_path / "README.md"
    readme.write_text("a\n<!-- seed003:begin -->\nold\n<!-- seed003:end -->\nb\n")
    update_readme(readme, "seed003", "| new | table |\n")
    assert (
        readme.read_text()
        == "a\n<!-- seed003:begin -->\n| new | table |\n<!-- seed003:end -->\nb\n"
    )
    with pytest.raises(ValueError, match="seed001:begin"):
        update_readme(readme, "seed001", "x")


def test_publish_figures_copies_and_relinks(tmp_path: Path) -> None:
    (tmp_path / "out" / "r").mkdir(parents=True)
    (tmp_path / "out" / "r" / "fig.png").write_bytes(b"\x89PNG fake")
    block = "text ![fig](out/r/fig.png) and ![gone](out/r/missing.png)"
    out = publish_figures(block, tmp_path, "seed003")
    assert "![fig](docs/figures/seed003/fig.png)" in out
    assert "![gone](out/r/missing.png)" in out  # a missing file is left alone
    assert (tmp_path / "docs" / "figures" / "seed003" / "fig.png").read_bytes() == b"\x89PNG fake"


def test_unknown_paper_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="expected one of seed000"):
        reproduce("seed999", tmp_path, 1, 0)


#: The page the reproduction blocks live on (between their seedNNN markers).
REPRODUCTIONS = ROOT / "docs" / "reproductions.md"


@pytest.mark.parametrize("paper", PAPERS)
def test_figures_of_each_reproduced_paper_are_committed(paper: str) -> None:
    text = REPRODUCTIONS.read_text()
    m = re.search(rf"<!-- {paper}:begin -->\n(.*?)<!-- {paper}:end -->", text, re.S)
    assert m is not None, f"docs/reproductions.md has no {paper} block"
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", m.group(1))
    assert links, f"the {paper} block shows no figure"
    for link in links:  # relative to the page, docs/
        assert link.startswith(f"figures/{paper}/"), link
        assert (REPRODUCTIONS.parent / link).is_file(), link


@pytest.mark.parametrize("paper", PAPERS)
def test_default_runs_and_seed_are_those_of_the_docs_block(paper: str) -> None:
    """`ins-cosim reproduce PAPER` without options regenerates the same block."""
    text = REPRODUCTIONS.read_text()
    m = re.search(rf"<!-- {paper}:begin -->\n(.*?)<!-- {paper}:end -->", text, re.S)
    assert m is not None, f"docs/reproductions.md has no {paper} block"
    runs, seed = DEFAULTS[paper]
    block = m.group(1)
    assert f"{runs} runs" in block or f"runs={runs}" in block
    assert f"seed {seed}" in block or f"seed={seed}" in block


def test_rerun_of_one_run_gives_its_numbers_in_the_whole_reproduction() -> None:
    """``ins-cosim reproduce seed003 --case coarse --run 2``: run 2 of the coarse campaign."""
    from cosim.reproduce import rerun, seed003

    fs, fr = seed003.scenario_facts(seed003.STATIC), seed003.scenario_facts(seed003.ROTATING)
    path, kw = seed003.cases(fs, fr)["coarse"]
    whole = seed003.campaign(path, 3, 2024, workers=2, **kw)
    text = rerun("seed003", "coarse", 2, 3, 2024)
    err = ", ".join(f"{v:.6g}" for v in whole["align.rpy_err"][2, -1])
    assert f"seeds {whole.seeds[2]}" in text and f"rpy_err = [{err}] arcmin" in text
    for paper, case in (("seed000", "large 7 8"), ("seed001", "nope"), ("seed003", "nope")):
        with pytest.raises(UserError, match="has no case"):
            rerun(paper, case, 0, 3, 2024)
