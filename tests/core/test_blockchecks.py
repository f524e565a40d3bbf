"""Checks across blocks before a run (cosim/blockchecks.py; issue 27, item 3).

"Writing a new scenario from the README", a tactical IMU at 60 deg N: each mistake the
issue met is now one line at ``check`` (exit 3) naming the block and key, with the fix:

- ``lat`` on the base (an output there) -> "Did you mean 'lat0'?";
- a base at 60 deg with the filter told 45 deg (or left on its 45 deg default) -> refused;
- ``kf_period = "15 ms"`` on a 10 ms step -> refused at ``check``, times rounded as
  written (10 ms, not 0.009999999999999787 s), instead of exit 4 at t = 5 s in ``run``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.scenario import build_master, load_scenario

ROOT = Path(__file__).resolve().parents[2]
BASE = 'parameters = { lat0 = "45 deg", h0 = 0.0,'
FILTER = 'parameters = { lat = "45 deg", init_mode = 1,'


def scenario(tmp_path: Path, *, base: str = BASE, filt: str = FILTER, period: str = "100 ms",
             step: str = "100 ms") -> Path:  # fmt: skip
    """seed 003's scenario, 6 s, with the base, filter, kf_period and step changed."""
    text = (ROOT / "scenarios" / "sins_north_finding.toml").read_text()
    changes = [
        (BASE, base),
        (FILTER, filt),
        ('kf_period = "100 ms"', f'kf_period = "{period}"'),
        ('step = "100 ms"', f'step = "{step}"'),
        ('stop = "300 s"', 'stop = "6 s"'),
    ]
    for old, new in changes:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "tactical_60n.toml"
    path.write_text(text.split("[[requirements]]")[0])
    return path


def refusal(path: Path) -> str:
    with pytest.raises(ScenarioError) as info:
        build_master(load_scenario(path)).terminate()
    return str(info.value)


def test_lat_on_the_base_suggests_lat0(tmp_path: Path) -> None:
    text = refusal(scenario(tmp_path, base='parameters = { lat = "60 deg", h0 = 0.0,'))
    assert "'base.lat' is an output" in text and "Did you mean 'lat0'?" in text
    assert "blocks.base.parameters.lat" in text


def test_base_and_filter_latitudes_must_agree(tmp_path: Path) -> None:
    base60 = 'parameters = { lat0 = "60 deg", h0 = 0.0,'
    text = refusal(scenario(tmp_path, base=base60))
    assert "blocks.align.parameters.lat = 45 deg disagrees with blocks.base.parameters.lat0" in text
    assert "= 60 deg: both state the latitude; give both the same value" in text
    # the filter's latitude left on its default is the same mistake, said so
    text = refusal(scenario(tmp_path, base=base60, filt="parameters = { init_mode = 1,"))
    assert "lat = 45 deg (its default) disagrees" in text
    # agreeing: built
    ok = scenario(tmp_path, base=base60, filt='parameters = { lat = "60 deg", init_mode = 1,')
    build_master(load_scenario(ok)).terminate()


def test_kf_period_off_the_step_is_caught_by_check_with_rounded_times(tmp_path: Path, cli) -> None:
    path = scenario(tmp_path, period="15 ms", step="10 ms")
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err, res.err
    assert (
        "blocks.align.parameters.kf_period = 15 ms is not a whole multiple of the block's "
        "step 10 ms (master step 10 ms): use 10 ms or 20 ms"
    ) in res.err, res.err
    assert "0.0099999" not in res.err and len(res.err.strip().splitlines()) == 1
    # a block stepping every 2nd macro step: its step is 20 ms
    text = path.read_text().replace(
        'model = "SinsStaticAlignment"', 'model = "SinsStaticAlignment"\nrate = 2'
    )
    path.write_text(text.replace('kf_period = "15 ms"', 'kf_period = "30 ms"'))
    assert "step 20 ms (master step 10 ms x rate 2): use 20 ms or 40 ms" in refusal(path)
