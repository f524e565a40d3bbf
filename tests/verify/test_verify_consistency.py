"""Consistency verdicts through the real CLI and reports (cosim.verify.consistency).

The scenario is seed 003's (scenarios/sins_north_finding.toml: SinsStaticAlignment,
NIS of 2 dof per zero-velocity update, NEES of 3 angles) with a shortened stop; the
mis-tuned variant states R = (0.0316 m/s)^2 while the measurements carry (0.1 m/s)^2 of
noise: R ten times too small, the innovation sigma sqrt(10) = 3.2 times too small.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import pytest
from scipy import stats

from cosim.errors import ScenarioError
from cosim.verify.consistency import parse_consistency, statistic_kind

ROOT = Path(__file__).resolve().parents[2]
R_TOO_SMALL = 'r_vel = "0.0316228 m/s"'

CONSISTENT_NIS = """
[[requirements]]
id = "NIS"
text = "The fine filter's NIS stays in its chi-square band"
signal = "align.nis"
criterion = "consistent"
false_alarm = 0.01
"""


def sins_scenario(
    tmp_path: Path, name: str, *, stop: str, runs: int = 3, mistuned: bool = False, reqs: str = ""
) -> Path:
    """seed 003's scenario, stopped at ``stop``, its requirements replaced by ``reqs``."""
    text = (ROOT / "scenarios" / "sins_north_finding.toml").read_text().split("[[requirements]]")[0]
    text = text.replace('stop = "300 s"', f'stop = "{stop}"').replace("runs = 50", f"runs = {runs}")
    if mistuned:
        assert 'r_vel = "0.1 m/s"' in text
        text = text.replace('r_vel = "0.1 m/s"', R_TOO_SMALL)
    path = tmp_path / f"{name}.toml"
    path.write_text(text + reqs)
    return path


def test_run_prints_and_records_the_verdicts(cli, tmp_path: Path) -> None:
    """`ins-cosim run` with R ten times too small: the NIS is flagged "sigma too small by
    about 3x" (sqrt(10) = 3.2: window estimates within 2-4.5) over most of the run, in the
    printed summary and in results.json (the tuned filter:
    tests/verify/test_consistency_slow.py)."""
    bad = cli(
        "run",
        sins_scenario(tmp_path, "bad", stop="40 s", mistuned=True),
        "--out",
        "bad",
        "--no-plot",
    )
    assert bad.code == 0, bad.err
    assert "1 % false alarm per run" in bad.out
    line = next(x for x in bad.out.splitlines() if "align.nis" in x)
    assert "align.nis (NIS, 2 dof" in line
    assert "INCONSISTENT: sigma too small by about" in line
    meta = json.loads((tmp_path / "bad" / "results.json").read_text())
    assert meta["consistency"]["consistent"] is False
    nis = next(s for s in meta["consistency"]["signals"] if s["column"] == "align.nis")
    assert nis["consistent"] is False and nis["dof"] == "2"
    assert all(s["sigma"] == "too small" and 2.0 <= s["factor"] <= 4.5 for s in nis["spans"])
    assert sum(s["t_end"] - s["t_start"] for s in nis["spans"]) >= 25.0


def test_verify_flags_the_mistuned_filter_in_every_report(cli, tmp_path: Path) -> None:
    """`ins-cosim verify`, 3 runs with R ten times too small: the consistency requirement
    is violated (Clopper-Pearson: 0 of 3 passing bounds the pass rate below 0.95), the
    reason, the HTML list, JSON and JUnit name where the sigma is too small."""
    path = sins_scenario(tmp_path, "bad", stop="30 s", mistuned=True, reqs=CONSISTENT_NIS)
    res = cli("verify", path, "--report", "rep", "--workers", "1", "--no-progress")
    assert res.code == 1, res.err + res.out
    assert "VIOLATED   NIS" in res.out and "sigma too small by about" in res.out
    data = json.loads((tmp_path / "rep" / "report.json").read_text())
    (req,) = data["requirements"]
    assert req["criterion"] == "consistent" and req["result"]["verdict"] == "violated"
    assert req["result"]["n_pass"] == 0
    notes = [r["metrics"]["NIS"]["note"] for r in data["runs"]]
    assert all("sigma too small by about" in n for n in notes)
    html = (tmp_path / "rep" / "report.html").read_text()
    assert 'class="consistency" data-id="NIS">3 run(s) flagged' in html
    junit = (tmp_path / "rep" / "junit.xml").read_text()
    assert "<failure" in junit and "sigma too small" in junit
    # the automatic check of every NIS/NEES output, with or without a requirement
    auto = data["consistency"]["signals"]["align.nis"]
    assert auto["verdict"] == "inconsistent" and auto["flagged"] == auto["runs"] == 3
    assert "align.nis: INCONSISTENT: flagged in 3 of 3 runs" in res.out
    assert '<h2 id="consistency">Filter consistency</h2>' in html
    assert 'data-column="align.nis" data-verdict="inconsistent"' in html
    # the embedded figures carry no Software chunk (no URL inside the PNG)
    pngs = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", html)
    assert pngs  # the NIS requirement's figure, drawn by consistency_report
    assert not [p for p in pngs if b"Software" in base64.b64decode(p)]


def test_a_bad_key_is_one_line_naming_file_and_key(cli, tmp_path: Path) -> None:
    """`ins-cosim check` refuses an unknown key of a consistency requirement: exit 3, one
    line with the file, the key (its position in the file) and the allowed keys."""
    reqs = CONSISTENT_NIS.replace("false_alarm = 0.01", "windows = 5")
    res = cli("check", sins_scenario(tmp_path, "typo", stop="30 s", reqs=reqs))
    assert res.code == 3
    lines = res.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.err
    assert "typo.toml" in lines[0] and "requirements[0].windows" in lines[0]
    assert "Did you mean 'window'?" in lines[0]


UNITS = {"time": "s", "align.nis": "1", "align.nees": "1", "align.rpy_err[1]": "arcmin"}
DESCRIPTIONS = {
    "align.nis": "NIS of the last zero-velocity update (chi-square, 2 dof)",
    "align.nees": "NEES of the three angles (chi-square, 3 dof)",
}


@pytest.mark.parametrize(
    ("change", "key", "words"),
    [
        ({"false_alarm": 1.5}, "false_alarm", "fraction between 0 and 1"),
        ({"signal": "align.rpy_err[1]"}, "signal", "not a NIS or NEES output"),
        ({"signal": "align.nsi"}, "signal", "Did you mean 'align.nis'?"),
        ({"window": "-2 s"}, "window", "must be > 0 s"),
        ({"dof": 0}, "dof", "whole number of degrees of freedom"),
        ({"probability": 0.995}, "probability", "can never be shown"),
        ({"statistic": "rms"}, "statistic", "takes statistic 'pass_rate'"),
    ],
)
def test_bad_values_are_refused_with_the_fix(change: dict, key: str, words: str) -> None:
    """Each bad value names requirements[2].<key> and says what to write instead."""
    table = {"id": "C", "signal": "align.nis", "criterion": "consistent", **change}
    with pytest.raises(ScenarioError) as info:
        parse_consistency(table, 2, UNITS, "s.toml", DESCRIPTIONS)
    assert info.value.key == f"requirements[2].{key}" and info.value.file == "s.toml"
    assert words in info.value.message


def test_the_dof_come_from_the_description_or_the_key() -> None:
    """A NIS without a stated dof needs `dof`; a stated one is read from its description."""
    table = {"id": "C", "signal": "align.nis", "criterion": "consistent"}
    assert parse_consistency(table, 0, UNITS, "s.toml", DESCRIPTIONS).dof == 2.0
    with pytest.raises(ScenarioError, match="dof = 3"):
        parse_consistency(table, 0, UNITS, "s.toml", {})
    assert parse_consistency({**table, "dof": 6}, 0, UNITS, "s.toml", {}).dof == 6.0
    assert statistic_kind("align.nis_dof") is None and statistic_kind("a.nees_att") == "nees"


def test_pass_rate_verdict_is_reachable_for_a_consistent_filter() -> None:
    """The default probability 0.95 lies below the pass rate of a consistent filter
    (0.99), so enough runs decide it: 300 runs with 3 false alarms give a Clopper-Pearson
    95 % lower bound above 0.95."""
    lower = stats.beta.ppf(0.05, 297, 4)
    assert lower > 0.95


def synthetic_result(unconnected: dict, *, dof_column: bool = False, scale: float = 1.0):  # noqa: ANN201
    """A recording of a filter updating every 2nd step (NIS held in between), seeded."""
    import numpy as np

    from cosim.results import RunResult

    rng = np.random.default_rng(5)
    n = 801
    t = np.arange(n) * 0.1
    upd = stats.chi2.rvs(3, size=n // 2, random_state=rng) * scale
    nis = np.concatenate([[0.0], np.repeat(upd, 2)])
    cols = [("time", t), ("f.nis", nis), ("f.nees", stats.chi2.rvs(3, size=n, random_state=rng))]
    if dof_column:
        cols.append(("f.nis_dof", np.full(n, 3.0)))
    data = np.zeros(n, dtype=[(c, "f8") for c, _ in cols])
    for c, v in cols:
        data[c] = v
    descriptions = {"f.nees": "NEES (chi-square, 3 dof)"}
    if not dof_column:
        descriptions["f.nis"] = "NIS of the last update (chi-square, 3 dof)"
    return RunResult(data, {"descriptions": descriptions, "unconnected": unconnected})


def test_check_run_on_a_log_without_truth_judges_only_the_nis() -> None:
    """A truth input left open: the NEES is not judged (said so), the NIS is, with one
    sample per update (400 updates, not 801 samples), its dof from the description or
    from a recorded nis_dof column; a NIS three times too large in variance is flagged
    "too small by about 1.7x" (sqrt 3)."""
    from cosim.verify.consistency import check_run

    summary = check_run(synthetic_result({"f": {"rpy_true[1]": 0.0}}))
    nees = next(c for c in summary.checks if c.column == "f.nees")
    nis = next(c for c in summary.checks if c.column == "f.nis")
    assert nees.consistent is None and "no truth" in nees.skipped
    assert nis.consistent is True and nis.samples == 400 and nis.dof == "3"
    judged = check_run(synthetic_result({}, dof_column=True, scale=3.0))
    nis = next(c for c in judged.checks if c.column == "f.nis")
    assert nis.dof == "per update (f.nis_dof)"
    assert [s.flag for s in nis.spans] == ["small"]
    assert 1.5 <= nis.spans[0].factor <= 1.9
    nees = next(c for c in judged.checks if c.column == "f.nees")
    assert nees.consistent is True
