"""Acceptance 6 of issue 26 on a real filter (slow): false-alarm and detection rates.

seed 003's SinsStaticAlignment (scenarios/sins_north_finding.toml, stopped at 30 s: 300
zero-velocity updates, 30 recorded), judged by two ``criterion = "consistent"``
requirements (NIS, 2 dof; NEES, 3 dof; each at 1 % false alarm per run) over campaigns
run through :func:`cosim.verify.campaign.run_campaign`, the engine of ``ins-cosim
verify``. Bounds: a correctly tuned filter is flagged in a Binomial(n, <= 0.01) number of
runs, so the count must not exceed its 99.9 % quantile.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from scipy import stats
from test_verify_consistency import sins_scenario

from cosim.verify.campaign import run_campaign

pytestmark = pytest.mark.slow

BOTH = """
[[requirements]]
id = "NIS"
signal = "align.nis"
criterion = "consistent"
false_alarm = 0.01

[[requirements]]
id = "NEES"
signal = "align.nees"
criterion = "consistent"
false_alarm = 0.01
"""


def flagged(campaign, rid: str) -> tuple[int, int]:  # noqa: ANN001
    """(flagged runs, completed runs) of one requirement."""
    metrics = [r.metrics[rid] for r in campaign.records if not r.failed]
    return sum(m.passed is False for m in metrics), len(metrics)


def test_tuned_filter_false_alarms_over_500_runs(tmp_path: Path) -> None:
    """500 runs of the tuned filter: each requirement flags at most the binomial 99.9 %
    quantile of 1 % of the runs (measured: NIS 7 of 500, NEES 0 of 500 at campaign seed
    2024), and the pass-rate verdict is satisfied."""
    path = sins_scenario(tmp_path, "ok", stop="30 s", runs=500, reqs=BOTH)
    campaign = run_campaign(path, tmp_path / "rep", workers=2, progress=False)
    limit = stats.binom.ppf(0.999, 500, 0.01)
    for rid in ("NIS", "NEES"):
        count, n = flagged(campaign, rid)
        print(f"{rid}: {count} of {n} tuned runs flagged (limit {limit:g})")
        assert n == 500 and count <= limit
    assert all(v.verdict == "satisfied" for v in campaign.verdicts)


def test_r_ten_times_too_small_is_detected(tmp_path: Path) -> None:
    """100 runs with R ten times too small: the NIS flags at least 95 % of them
    (measured 100 %); the NEES, whose band holds under any dependence, flags fewer
    (measured 39 of 100)."""
    path = sins_scenario(tmp_path, "bad", stop="30 s", runs=100, mistuned=True, reqs=BOTH)
    campaign = run_campaign(path, tmp_path / "rep", workers=2, progress=False)
    nis, n = flagged(campaign, "NIS")
    nees, _ = flagged(campaign, "NEES")
    print(f"R/10: NIS flags {nis} of {n}, NEES {nees} of {n}")
    assert n == 100 and nis >= 95 and nees >= 30
    assert campaign.verdicts[0].verdict == "violated"


def test_run_of_the_tuned_filter_says_consistent(cli, tmp_path: Path) -> None:
    """`ins-cosim run` of the tuned filter (seed 003's seeds, 40 s): both statistics
    consistent, nothing flagged, in the printout and results.json."""
    ok = cli("run", sins_scenario(tmp_path, "ok", stop="40 s"), "--out", "ok", "--no-plot")
    assert ok.code == 0, ok.err
    assert "align.nis (NIS, 2 dof" in ok.out and "INCONSISTENT" not in ok.out
    assert "align.nees (NEES, 3 dof" in ok.out


def test_transfer_alignment_with_r_ten_times_too_small(cli, tmp_path: Path) -> None:
    """seed 001's transfer alignment (UKF, velocity matching, NIS of 3 dof) with R ten
    times too small, 60 s: `ins-cosim run` flags the NIS as sigma too small; as shipped,
    the same 60 s are consistent."""
    root = Path(__file__).resolve().parents[2] / "scenarios" / "transfer_alignment.toml"
    text = root.read_text()
    assert 'r_vel = "0.01 m/s"' in text
    bad = tmp_path / "ta_bad.toml"
    bad.write_text(text.replace('r_vel = "0.01 m/s"', 'r_vel = "0.00316228 m/s"'))
    res = cli("run", bad, "--out", "bad", "--stop", "60 s", "--no-plot")
    assert res.code == 0, res.err
    line = next(x for x in res.out.splitlines() if "align.nis" in x)
    assert "INCONSISTENT: sigma too small by about" in line
    ok = cli("run", root, "--out", "ok", "--stop", "60 s", "--no-plot")
    line = next(x for x in ok.out.splitlines() if "align.nis" in x)
    assert line.endswith(": consistent"), line


@pytest.mark.parametrize(("method", "verdict"), [(2, ": consistent"), (0, "sigma too small")])
def test_hrg_two_position_kf_is_consistent_and_ekf_is_not(cli, tmp_path: Path, method, verdict):  # noqa: ANN001
    """seed 000 (scenarios/hrg_two_position.toml, 410 s) with the linear KF (method 2):
    the NIS (2 dof) is consistent; with the EKF (method 0), whose linearisation cannot
    take the uniform azimuth prior (the paper's reason for the UPF), the azimuth error
    runs to ~170 deg against a 65' sigma and the NIS says "sigma too small" (by ~90x)."""
    root = Path(__file__).resolve().parents[2] / "scenarios" / "hrg_two_position.toml"
    text = root.read_text()
    assert "parameters = { method = 1," in text
    path = tmp_path / "hrg.toml"
    path.write_text(
        text.replace("parameters = { method = 1,", f"parameters = {{ method = {method},")
    )
    res = cli("run", path, "--out", "out", "--no-plot")
    assert res.code == 0, res.err
    line = next(x for x in res.out.splitlines() if "filter.nis" in x)
    assert "(NIS, 2 dof, 400 samples" in line and verdict in line, line
