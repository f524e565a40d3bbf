"""Filter pages (cosim.interop.filterdocs): generated from the filters' declarations, up to date.

Every parameter of every filter and log replay is documented with name, unit, default and
meaning (issue 26, item 5); a declaration changed without regenerating the pages fails
here: run ``python -m cosim.interop.filterdocs`` and commit.
"""

from __future__ import annotations

from pathlib import Path

from cosim.interop import filterdocs
from cosim.models.block import Block, input_, output, parameter
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR


def test_every_filter_page_is_up_to_date() -> None:
    stale = filterdocs.outdated()
    assert not stale, (
        f"out of date: {sorted(stale)}; run `python -m cosim.interop.filterdocs` and commit"
    )
    assert filterdocs.main(["--check"]) == 0


def test_the_pages_cover_the_filters_and_replays() -> None:
    names = set(filterdocs.filter_blocks())
    assert {
        "SinsStaticAlignment",
        "TransferAlignment",
        "HrgTwoPositionAlignment",
        "ImuLogReplay",
        "MasterInsLogReplay",
    } <= names
    for name, cls in filterdocs.filter_blocks().items():
        page = (filterdocs.DOCS_DIR / f"{name}.md").read_text(encoding="utf-8")
        for v in cls.variables:  # every declared variable has its row
            shown = f"`{v.name}[{v.size}]`" if v.is_vector else f"`{v.name}`"
            assert f"| {shown} | {v.unit} |" in page, (name, v.name)


def test_the_tables_come_from_the_declarations(tmp_path: Path) -> None:
    class Toy(Block):
        """A toy filter."""

        variables = (
            parameter("p0_att", (DEG, DEG, 2 * DEG), "rad", "P0: attitude | sigmas"),
            parameter("drift", 0.02 * DEG_PER_HOUR, "rad/s", "gyro drift"),
            parameter("level", 3 * ARCMIN, "rad", "level"),
            parameter("n", 6, description="hypotheses"),
            input_("rpy_true", (0.0, 0.0, 0.0), "rad", "truth: attitude"),
            output("rpy", (0.0, 0.0, 0.0), "rad", "estimated attitude"),
        )

    page = filterdocs.render(Toy, "Toy", "kept notes")
    assert "| `p0_att[3]` | rad | (0.01745329252, 0.01745329252, 0.03490658504) " in page
    assert "(1 deg, 1 deg, 2 deg) | P0: attitude \\| sigmas |" in page
    assert "| `drift` | rad/s | 9.696273622e-08 (0.02 deg/h) | gyro drift |" in page
    assert "| `level` | rad | 0.000872664626 (3 arcmin) | level |" in page
    assert "| `n` | 1 | 6 | hypotheses |" in page
    assert "**truth**: attitude; leave unconnected on a log" in page
    assert "| `rpy[3]` | rad | estimated attitude |" in page
    assert page.endswith(filterdocs.NOTES_MARKER + "\n\nkept notes\n")
