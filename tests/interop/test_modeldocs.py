"""Model pages: generated from each model's docstring and declarations, and up to date."""

from __future__ import annotations

from pathlib import Path

from cosim import models
from cosim.interop import modeldocs
from cosim.models.block import Block, input_, output, parameter


def test_every_model_page_is_up_to_date() -> None:
    stale = modeldocs.outdated()
    assert not stale, (
        f"out of date: {sorted(stale)}; run `python -m cosim.interop.modeldocs` and commit"
    )
    assert modeldocs.main(["--check"]) == 0


def test_the_table_comes_from_the_declarations() -> None:
    class Toy(Block):
        """A toy block."""

        variables = (
            parameter("k", 2.5, "1/s", "rate constant"),
            parameter("seed", 0, description="random seed"),
            input_("u", (0.0, 1.0), "m", "drive | two axes"),
            output("y", 0.0, "m", "state"),
        )

    table = modeldocs.variable_table(Toy).splitlines()
    assert table[2] == "| `k` | parameter | fixed | Real | 1/s | 2.5 | rate constant |"
    assert table[3] == "| `seed` | parameter | fixed | Integer | 1 | 0 | random seed |"
    assert table[4] == "| `u[2]` | input | continuous | Real | m | (0, 1) | drive \\| two axes |"
    assert table[5] == "| `y` | output | continuous | Real | m | 0 | state |"


def test_a_changed_declaration_makes_the_page_stale(tmp_path: Path) -> None:
    cls = models.truth_models()["GaussMarkov2"]
    page = tmp_path / "GaussMarkov2.md"
    page.write_text(modeldocs.render(cls, "## Notes\n\nkept\n"), encoding="utf-8")
    assert "GaussMarkov2" not in modeldocs.outdated(tmp_path)
    assert modeldocs.notes_of(page).strip() == "## Notes\n\nkept"
    page.write_text(page.read_text().replace("| 100 |", "| 99 |"), encoding="utf-8")
    assert "GaussMarkov2" in modeldocs.outdated(tmp_path)


def test_rst_literal_blocks_and_roles_become_markdown() -> None:
    text = "Title\n-----\nSee :func:`models.conventions.cross` and ``x``::\n\n    x' = -x\n\nEnd."
    md = modeldocs.rst_to_markdown(text)
    assert md == (
        "### Title\n\nSee `models.conventions.cross` and `x`:\n\n```\nx' = -x\n```\n\nEnd.\n"
    )
