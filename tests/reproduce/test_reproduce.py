"""The reproductions: a plug-in area found through entry points (cosim.reproductions).

The published tables and figures come from code: ``ins-cosim reproduce NAME
--update-docs`` writes them between markers of the reproductions page; these tests use a
page of their own in ``tmp_path``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cosim import reproductions
from cosim.errors import UserError
from cosim.reproductions import (
    ReproductionError,
    find,
    names,
    publish,
    publish_figures,
    update_docs,
)

ROOT = Path(__file__).resolve().parents[2]
#: The reproductions this distribution registers (pyproject.toml).
SHIPPED = ("seed000", "seed001", "seed003")


def published_page() -> Path:
    """The page that holds the published blocks: the docs page once it has the markers."""
    page = ROOT / reproductions.DOCS_PAGE
    assert "<!-- seed003:begin -->" in page.read_text(encoding="utf-8"), page
    return page


def test_update_docs_replaces_only_between_markers(tmp_path: Path) -> None:
    page = tmp_path / "reproductions.md"
    page.write_text("a\n<!-- seed003:begin -->\nold\n<!-- seed003:end -->\nb\n")
    update_docs(page, "seed003", "| new | table |\n")
    assert (
        page.read_text() == "a\n<!-- seed003:begin -->\n| new | table |\n<!-- seed003:end -->\nb\n"
    )
    with pytest.raises(ReproductionError, match="seed001:begin"):
        update_docs(page, "seed001", "x")
    with pytest.raises(ReproductionError, match="no such page"):
        update_docs(tmp_path / "nowhere.md", "seed003", "x")


def test_publish_figures_copies_beside_the_page_and_relinks(tmp_path: Path) -> None:
    (tmp_path / "out" / "r").mkdir(parents=True)
    (tmp_path / "out" / "r" / "fig.png").write_bytes(b"\x89PNG fake")
    block = "text ![fig](out/r/fig.png) and ![gone](out/r/missing.png)"
    out = publish_figures(block, tmp_path, Path("docs") / "reproductions.md", "seed003")
    assert "![fig](figures/seed003/fig.png)" in out  # relative to docs/
    assert "![gone](out/r/missing.png)" in out  # a missing file is left alone
    assert (tmp_path / "docs" / "figures" / "seed003" / "fig.png").read_bytes() == b"\x89PNG fake"
    # a page at the root links into its own figures folder
    out = publish_figures(block, tmp_path, tmp_path / "page.md", "seed003")
    assert "![fig](figures/seed003/fig.png)" in out and (tmp_path / "figures" / "seed003").is_dir()


def test_publish_writes_the_block_into_a_page_of_markers(tmp_path: Path) -> None:
    """``--update-docs``: the figures beside the page, the block between its markers."""
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "p.png").write_bytes(b"png")
    (tmp_path / "docs").mkdir()
    page = tmp_path / "docs" / "reproductions.md"
    page.write_text("# R\n<!-- seed000:begin -->\n<!-- seed000:end -->\n")
    assert publish("| x |\n![p](out/p.png)\n", "seed000", root=tmp_path) == page
    assert page.read_text() == (
        "# R\n<!-- seed000:begin -->\n| x |\n![p](figures/seed000/p.png)\n<!-- seed000:end -->\n"
    )
    with pytest.raises(ReproductionError, match="no such page"):
        publish("x", "seed000", root=tmp_path / "elsewhere")


def test_the_shipped_reproductions_are_registered_and_offer_the_protocol() -> None:
    assert set(SHIPPED) <= set(names())
    for name in SHIPPED:
        module = find(name)
        assert callable(module.reproduce) and callable(module.rerun)
        assert module.DEFAULT_RUNS > 0 and isinstance(module.DEFAULT_CASE, str)


def test_unknown_reproduction_is_refused_with_the_known_names() -> None:
    with pytest.raises(ReproductionError, match="unknown reproduction 'seed999'.*seed000") as info:
        find("seed999")
    assert isinstance(info.value, UserError) and info.value.exit_code == 3


def test_the_cli_lists_and_refuses_by_the_registry(cli) -> None:  # noqa: ANN001
    res = cli("reproduce")
    assert res.code == 0, res.err
    assert [line.split()[0] for line in res.out.splitlines()] == list(names())
    res = cli("reproduce", "seed999")
    assert res.code == 3 and "unknown reproduction 'seed999'" in res.err
    assert "Traceback" not in res.err


@pytest.mark.parametrize("flag", ["--update-docs", "--update-readme"])
def test_update_docs_is_refused_before_running_without_the_page(cli, flag: str) -> None:  # noqa: ANN001
    """In a folder without docs/reproductions.md: exit 3 at once, nothing run; the
    deprecated --update-readme writes to the same page and says it is deprecated."""
    res = cli("reproduce", "seed003", flag, "--runs", "1")
    assert res.code == 3, (res.code, res.err)
    assert "docs/reproductions.md: no such page" in res.err and "Traceback" not in res.err
    assert ("deprecated" in res.err) == (flag == "--update-readme")
    assert not res.out  # no reproduction ran


@pytest.mark.parametrize("paper", SHIPPED)
def test_published_figures_of_each_reproduction_are_committed(paper: str) -> None:
    page = published_page()
    text = page.read_text(encoding="utf-8")
    m = re.search(rf"<!-- {paper}:begin -->\n(.*?)<!-- {paper}:end -->", text, re.S)
    if m is None:
        pytest.skip(f"{paper} has no published block yet")
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", m.group(1)):
        assert "figures/" + paper + "/" in link, link
        assert (page.parent / link).is_file(), link


@pytest.mark.parametrize("paper", SHIPPED)
def test_default_runs_and_seed_are_those_of_the_published_block(paper: str) -> None:
    """`ins-cosim reproduce NAME --update-docs` without options regenerates the same block."""
    text = published_page().read_text(encoding="utf-8")
    m = re.search(rf"<!-- {paper}:begin -->\n(.*?)<!-- {paper}:end -->", text, re.S)
    assert m is not None, f"no {paper} block"
    module = find(paper)
    runs, seed = module.DEFAULT_RUNS, module.DEFAULT_SEED
    block = m.group(1)
    assert f"{runs} runs" in block or f"runs={runs}" in block
    assert f"seed {seed}" in block or f"seed={seed}" in block


def test_rerun_of_one_run_gives_its_numbers_in_the_whole_reproduction() -> None:
    """``ins-cosim reproduce seed003 --case coarse --run 2``: run 2 of the coarse campaign."""
    from cosim.reproduce import seed003

    fs, fr = seed003.scenario_facts(seed003.STATIC), seed003.scenario_facts(seed003.ROTATING)
    path, kw = seed003.cases(fs, fr)["coarse"]
    whole = seed003.campaign(path, 3, 2024, workers=2, **kw)
    text = find("seed003").rerun("coarse", 2, 3, 2024)
    err = ", ".join(f"{v:.6g}" for v in whole["align.rpy_err"][2, -1])
    assert f"seeds {whole.seeds[2]}" in text and f"rpy_err = [{err}] arcmin" in text
    for paper, case in (("seed000", "large 7 8"), ("seed001", "nope"), ("seed003", "nope")):
        with pytest.raises(UserError, match="has no case"):
            find(paper).rerun(case, 0, 3, 2024)
