"""Reports of a real campaign with one satisfied, one violated and one undecided requirement."""

from __future__ import annotations

import base64
import hashlib
import json
import struct
from html.parser import HTMLParser

import pytest

from cosim.verify.campaign import run_campaign
from cosim.verify.report import write_reports
from cosim.verify.requirements import SATISFIED, UNDECIDED, VIOLATED
from cosim.verify.seeds import run_seeds

SCENARIO = """
[master]
step = "10 ms"
stop = "3 s"

[blocks.filter]
class = "testblocks:Converging"

[blocks.filter.parameters]
sigma0 = "10 arcmin"
tau = "0.5 s"
noise = "0.05 arcmin"
fail_seed = {fail_seed}
fail_time = "2 s"

[campaign]
runs = 12
seed = 5
on_failure = "exclude"

[[requirements]]
id = "REQ-S"
text = "The error settles within 1 arcmin in 2.5 s"
signal = "filter.error"
sigma = "filter.sigma"
unit = "arcmin"
criterion = "settling"
band = "1 arcmin"
within = "2.5 s"
probability = 0.75  # 11 passing runs show the 75 % quantile at 1 - 0.75^11 = 96 % confidence

[[requirements]]
id = "REQ-V"
text = "The error stays within 0.01 arcmin from 2 s on"
signal = "filter.error"
sigma = "filter.sigma"
unit = "arcmin"
criterion = "bound"
bound = "0.01 arcmin"
from = "2 s"

[[requirements]]
id = "REQ-U"
text = "The 95th percentile of the error from 2 s on is below 1 arcmin (95 % confidence)"
signal = "filter.error"
unit = "arcmin"
criterion = "bound"
bound = "1 arcmin"
from = "2 s"
statistic = "p95"
confidence = 0.95
"""
EXPECTED = {"REQ-S": SATISFIED, "REQ-V": VIOLATED, "REQ-U": UNDECIDED}


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory):
    tmp = tmp_path_factory.mktemp("report")
    scenario = tmp / "mixed.toml"
    scenario.write_text(SCENARIO.format(fail_seed=run_seeds(5, 2, ["filter"])["filter"]))
    campaign = run_campaign(scenario, tmp / "out", workers=1, progress=False)
    return campaign, write_reports(campaign), scenario


def test_the_campaign_behind_the_reports(reports) -> None:
    campaign, _, _ = reports
    assert {v.id: v.verdict for v in campaign.verdicts} == EXPECTED
    assert [r.index for r in campaign.failed_runs] == [2]


class Page(HTMLParser):
    """Collects tags, attributes and the text of table cells."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str]]] = []
        self.rows: dict[str, dict[str, str]] = {}
        self.cells: list[str] = []
        self._row: dict[str, str] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        self.tags.append((tag, a))
        if tag == "tr" and "requirement-row" in a.get("class", ""):
            self._row = a
            self.rows[a["data-id"]] = {"data-verdict": a["data-verdict"], "cells": []}
        if tag == "td":
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self._cell is not None:
            text = "".join(self._cell).strip()
            self.cells.append(text)
            if self._row is not None:
                self.rows[self._row["data-id"]]["cells"].append(text)
            self._cell = None
        if tag == "tr":
            self._row = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


def test_html_is_one_offline_file_with_every_plot_embedded(reports) -> None:
    campaign, paths, _ = reports
    text = paths["html"].read_text(encoding="utf-8")
    for external in ("http://", "https://", "url(", "@import", "file:"):
        assert external not in text
    page = Page()
    page.feed(text)
    names = [t for t, _ in page.tags]
    assert names.count("html") == 1 and names.count("title") == 1
    assert not {"script", "link", "iframe", "object", "embed"} & set(names)
    for _tag, attrs in page.tags:
        for key in ("src", "href"):
            if key in attrs:
                assert attrs[key].startswith("data:image/png;base64," if key == "src" else "#")
    images = [a for t, a in page.tags if t == "img"]
    calibration = [a for a in images if a["alt"].endswith("sigma calibration over time")]
    judged = [c for c in data_calibration(paths) if c["consistent"] is not None]
    # one figure per requirement, one more per requirement whose sigma was calibrated
    assert len(images) == len(campaign.requirements) + len(judged)
    assert len(calibration) == len(judged) >= 1
    for attrs in images:
        png = base64.b64decode(attrs["src"].split(",", 1)[1], validate=True)
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = struct.unpack(">II", png[16:24])
        assert width >= 800 and height >= (250 if attrs in calibration else 500)


def data_calibration(paths: dict) -> list[dict]:
    """The report's ``consistency.calibration`` (cosim.verify.calibration)."""
    return json.loads(paths["json"].read_text())["consistency"]["calibration"]


def test_html_lists_every_requirement_with_its_verdict(reports) -> None:
    campaign, paths, _ = reports
    page = Page()
    page.feed(paths["html"].read_text(encoding="utf-8"))
    assert set(page.rows) == set(EXPECTED)
    for rid, verdict in EXPECTED.items():
        row = page.rows[rid]
        assert row["data-verdict"] == verdict
        assert row["cells"][0] == rid and row["cells"][6] == verdict
    sections = {a["id"]: a["data-verdict"] for t, a in page.tags if t == "section"}
    assert sections == {f"req-{k}": v for k, v in EXPECTED.items()}
    # the failed run, with its message; traceability of the scenario and the block
    failed = campaign.failed_runs[0]
    assert "2" in page.cells and failed.error in page.cells
    assert campaign.scenario["sha256"] in page.cells
    assert campaign.provenance["blocks"]["filter"]["guid"] in page.cells
    overall = [a for t, a in page.tags if a.get("id") == "overall"]
    assert overall[0]["data-verdict"] == VIOLATED


def test_junit_has_one_case_per_requirement(reports) -> None:
    junitparser = pytest.importorskip("junitparser")
    campaign, paths, scenario = reports
    xml = junitparser.JUnitXml.fromfile(str(paths["junit"]))
    suites = list(xml)
    assert len(suites) == 1
    suite = suites[0]
    cases = {case.name: case for case in suite}
    assert set(cases) == set(EXPECTED)
    assert (suite.tests, suite.failures, suite.skipped, suite.errors) == (3, 1, 1, 0)
    assert cases["REQ-S"].is_passed
    (failure,) = cases["REQ-V"].result
    assert isinstance(failure, junitparser.Failure)
    v = next(v for v in campaign.verdicts if v.id == "REQ-V")
    assert f"measured {v.value:.6g} arcmin" in failure.message
    assert "bound 0.01 arcmin" in failure.message
    (skipped,) = cases["REQ-U"].result
    assert isinstance(skipped, junitparser.Skipped)
    assert "undecided" in skipped.message and "59 runs" in skipped.message
    props = {p.name: p.value for p in suite.properties()}
    assert props["scenario.sha256"] == hashlib.sha256(scenario.read_bytes()).hexdigest()
    assert props["campaign.seed"] == "5"
    assert props["block.filter.guid"] == campaign.provenance["blocks"]["filter"]["guid"]
    assert props["software.numpy"]
    assert props["run.3.seeds"] == f"filter={run_seeds(5, 3, ['filter'])['filter']}"


def test_json_traces_scenario_blocks_seeds_and_versions(reports) -> None:
    campaign, paths, scenario = reports
    data = json.loads(paths["json"].read_text())
    assert data["schema"] == "ins-cosim-verification-report/1"
    assert data["scenario"]["sha256"] == hashlib.sha256(scenario.read_bytes()).hexdigest()
    block = data["provenance"]["blocks"]["filter"]
    assert block["guid"] and len(block["sha256"]) == 64
    assert [r["seeds"]["filter"] for r in data["runs"]] == [
        run_seeds(5, i, ["filter"])["filter"] for i in range(12)
    ]
    assert data["runs"][2]["status"] == "failed" and "do_step" in data["runs"][2]["error"]
    software = data["provenance"]["software"]
    assert {"python", "ins-cosim", "numpy", "scipy", "fmpy", "dask", "matplotlib"} <= set(software)
    assert data["summary"] == {SATISFIED: 1, VIOLATED: 1, UNDECIDED: 1, "exit_code": 1}
    results = {r["id"]: r["result"] for r in data["requirements"]}
    assert {k: r["verdict"] for k, r in results.items()} == EXPECTED
    assert results["REQ-V"]["n_used"] == 11 and results["REQ-V"]["n_failed"] == 1
    assert data["campaign"]["seed"] == 5 and data["campaign"]["failed"] == 1
