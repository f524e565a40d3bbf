"""Seed 003 campaigns (issue 9, acceptance 1-4) and the reproduction module.

Statistics used by the fast (default) tests, for a consistent filter whose error at a
given time is N(0, sigma^2) with sigma its own 1-sigma:

* RMS of N independent runs: ``N RMS^2 / sigma^2 ~ chi-square(N)``, so
  ``RMS / sigma`` lies in ``[sqrt(chi2_N(a/2) / N), sqrt(chi2_N(1 - a/2) / N)]`` with
  probability ``1 - a``. The fast tests use ``a = 1 %``: for N = 10 that is
  [0.46, 1.62], for N = 8 [0.40, 1.66], for 2N = 20 (two level axes pooled) [0.60, 1.42].
  Wide, but a filter whose sigma is off by a factor of two, or a heading stuck at the
  single-position limit, fails them.
* ANEES of N runs (3 angles): ``N * ANEES ~ chi-square(3 N)``
  (:func:`cosim.estimation.anees_bounds`, 99 % here).

The seeds are fixed, so each test is deterministic; the bands say how unlikely a
failure of a correct filter would be. The slow tests (50 runs, ``-m slow``) check the
issue's acceptance numbers directly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.estimation import anees_bounds
from cosim.models.constants import ARCMIN
from cosim.reproduce import seed003
from cosim.verify.campaign import CampaignError, prepare
from cosim.verify.seeds import run_seeds

SEED = 2024
N_STATIC = 10
N_ROTATING = 8
N_COARSE = 20
CONF = 0.99


def _workers() -> int:
    import os

    return max(1, min(2, os.cpu_count() or 1))


@pytest.fixture(scope="module")
def static_fast() -> object:
    return seed003.campaign(
        seed003.STATIC, N_STATIC, SEED, columns=list(seed003.COLUMNS), record_every=10,
        workers=_workers(),
    )  # fmt: skip


@pytest.fixture(scope="module")
def rotating_fast() -> object:
    return seed003.campaign(
        seed003.ROTATING, N_ROTATING, SEED, columns=list(seed003.COLUMNS), record_every=10,
        workers=_workers(),
    )  # fmt: skip


@pytest.fixture(scope="module")
def facts() -> tuple:
    return seed003.scenario_facts(seed003.STATIC), seed003.scenario_facts(seed003.ROTATING)


@pytest.fixture(scope="module")
def analyses(facts: tuple) -> dict:
    return seed003.analyses(*facts)


def _ratio_ok(rms: float, sigma: float, n: int) -> bool:
    lo, hi = seed003.rms_band(n, CONF)
    return lo <= rms / sigma <= hi


# ------------------------------------------------------------------ seeds
def test_campaign_seeds_follow_the_documented_mapping() -> None:
    names = ["base", "imu", "align"]
    five = [run_seeds(7, i, names) for i in range(5)]
    words = np.random.SeedSequence(7).spawn(5)[4].generate_state(3, dtype=np.uint32)
    assert five[4] == {n: int(w >> 1) for n, w in zip(names, words, strict=True)}
    assert all(0 <= s < 2**31 for run in five for s in run.values())
    assert len({run["imu"] for run in five}) == 5
    assert prepare(seed003.ROTATING, requirements=False).seeded == names  # the table has none
    with pytest.raises(CampaignError, match="runs"):
        seed003.campaign(seed003.STATIC, 0, 1)
    # the campaign's runs carry the seeds of `ins-cosim verify` (one rule), run by run
    camp = seed003.campaign(seed003.STATIC, 3, 7, columns=["align.rpy_err"], stop=1.0)
    assert camp.seeds == five[:3]


def test_a_run_alone_equals_that_run_of_the_campaign() -> None:
    kw = {"columns": ["align.rpy_err", "align.phase"], "stop": 5.0, "workers": 2}
    whole = seed003.campaign(seed003.STATIC, 4, SEED, **kw)
    alone = seed003.campaign(seed003.STATIC, 4, SEED, indices=[2], **kw)
    assert alone.seeds == whole.seeds[2:3]
    for name, column in whole.columns.items():
        np.testing.assert_array_equal(alone.columns[name][0], column[2])


# ------------------------------------------------------------------ acceptance 1
def test_coarse_alignment_with_the_seed003_imu_is_within_the_theory(facts: tuple) -> None:
    """Residual misalignment of the 5 s analytic alignment: a few to tens of arcmin.

    Theory (first order): heading = -eps_E / (W cos L) + tan L nabla_E / g, level
    nabla / g; sigma from the turn-on sigmas and the white noise averaged over 5 s.
    """
    camp = seed003.campaign(
        seed003.STATIC, N_COARSE, SEED, columns=["align.rpy_err", "align.phase"],
        parameters={"align": {"init_mode": 0}}, stop=5.0, workers=1,
    )  # fmt: skip
    assert np.all(camp["align.phase"][:, -1] == 1.0)
    err = camp["align.rpy_err"][:, -1, :]
    th, tl = seed003.coarse_theory_sigma(facts[0])
    assert 5.0 < th / ARCMIN < 10.0  # ~6.6': "a few to tens of arcmin"
    assert _ratio_ok(float(seed003.rms(err[:, 2])), th / ARCMIN, N_COARSE)
    assert _ratio_ok(float(seed003.rms(err[:, :2].ravel())), tl / ARCMIN, 2 * N_COARSE)
    assert np.all(np.abs(err[:, 2]) < 60.0)


# ------------------------------------------------------------------ acceptance 2, fast
# slow: 10 static runs of 300 s (~12 s), shared with the tables test
@pytest.mark.slow
def test_static_campaign_is_consistent_with_its_covariance(
    static_fast: object, analyses: dict
) -> None:
    camp = static_fast
    e, sig = camp["align.rpy_err"], camp["align.rpy_sigma"]
    i60, i300 = camp.index(60.0), camp.index(300.0)
    # the filter's sigma is the independent covariance analysis (Taylor vs Van Loan). It
    # differs a little from run to run: F uses the estimated attitude, and while the
    # heading is still off by up to a few degrees the information on the north drift is
    # gathered along a slightly wrong axis (up to ~1 % at 300 s)
    ca = analyses["static"]
    np.testing.assert_allclose(sig[:, i300, 2], ca.sigma[ca.index(300.0), 4] / ARCMIN, rtol=3e-2)
    assert abs(np.median(sig[:, i300, 2]) / (ca.sigma[ca.index(300.0), 4] / ARCMIN) - 1.0) < 3e-3
    assert sig[0, i60, :2].max() < seed003.LEVEL_LIMIT  # the model says: level < 0.5' at 60 s
    # heading at 300 s and the two level axes at 60 s, against the filter's own sigma
    assert _ratio_ok(float(seed003.rms(e[:, i300, 2])), float(sig[:, i300, 2].mean()), N_STATIC)
    lvl = e[:, i60, :2].ravel()
    assert _ratio_ok(float(seed003.rms(lvl)), float(sig[:, i60, :2].mean()), 2 * N_STATIC)
    lo, hi = anees_bounds(3, N_STATIC, CONF)
    for t in (60.0, 150.0, 300.0):
        assert lo <= camp["align.nees"][:, camp.index(t)].mean() <= hi, t


# ------------------------------------------------------------------ acceptance 3, fast
# slow: the 8 rotating runs of 600 s (~25 s), shared with the tables test below
@pytest.mark.slow
def test_rotating_campaign_beats_the_static_limit_consistently(
    rotating_fast: object, analyses: dict, facts: tuple
) -> None:
    camp = rotating_fast
    e, sig = camp["align.rpy_err"], camp["align.rpy_sigma"]
    ca = analyses["rotating"]
    limit = seed003.heading_limit(facts[1].tuning.p0_gyro_drift, facts[1].lat) / ARCMIN
    for t in (300.0, 600.0):
        i = camp.index(t)
        np.testing.assert_allclose(sig[:, i, 2], ca.sigma[ca.index(t), 4] / ARCMIN, rtol=3e-2)
        assert _ratio_ok(float(seed003.rms(e[:, i, 2])), float(sig[:, i, 2].mean()), N_ROTATING)
    i600 = camp.index(600.0)
    # the model predicts 1.3' at 600 s; even at the top of the 99 % band (x1.66) the
    # single-position limit is beaten by more than 2x
    assert sig[0, i600, 2] < 1.5
    assert seed003.rms(e[:, i600, 2]) < limit / 2.0
    lo, hi = anees_bounds(3, N_ROTATING, CONF)
    for t in (300.0, 600.0):
        assert lo <= camp["align.nees"][:, camp.index(t)].mean() <= hi, t


# ------------------------------------------------------------------ acceptance 4
@pytest.mark.slow  # the rotating campaign above
def test_reproduction_tables_and_plots(
    tmp_path, static_fast: object, rotating_fast: object, analyses: dict, facts: tuple
) -> None:
    """The Markdown and the figures from the fast campaigns (no extra simulation)."""
    coarse = seed003.campaign(
        seed003.STATIC, 3, SEED, columns=["align.rpy_err", "align.phase"],
        parameters={"align": {"init_mode": 0}}, stop=5.0,
    )  # fmt: skip
    res = seed003.Seed003Run(
        static=static_fast,
        rotating=rotating_fast,
        coarse=coarse,
        coarse_perfect=np.zeros(3),
        facts_static=facts[0],
        facts_rotating=facts[1],
        cov=analyses,
        runs=N_ROTATING,
        seed=SEED,
        elapsed=0.0,
    )
    res.static.seeds = res.static.seeds[:N_ROTATING]
    res.static.columns = {k: v[:N_ROTATING] for k, v in res.static.columns.items()}
    files = seed003.plots(res, tmp_path)
    assert files == ["seed003_static.png", "seed003_rotating.png", "seed003_comparison.png"]
    for f in files:
        assert (tmp_path / f).stat().st_size > 20_000
    md = seed003.markdown(res, files)
    s = seed003.summary(res)
    assert "| heading error at 300 s, one position | ~6' |" in md
    assert f"{s['static_heading_rms_300']:.2f}'" in md
    assert "6.46'" in md and "![seed003_comparison.png](seed003_comparison.png)" in md
    # the covariance-analysis table reproduces the issue's six figures
    assert md.count("| yes |") >= 6
    for (case, r, t), want in seed003.ISSUE_CA.items():
        assert abs(s[f"ca_{case}_{r}_{t:.0f}"] - want) <= 0.05 + 1e-9


# ------------------------------------------------------------------ slow: the issue's numbers
@pytest.mark.slow
def test_static_campaign_50_runs_meets_acceptance_2() -> None:
    n = 50
    camp = seed003.campaign(
        seed003.STATIC, n, SEED, columns=list(seed003.COLUMNS), record_every=10, workers=2
    )
    e = camp["align.rpy_err"]
    t = camp.time
    level_rms = seed003.rms(e[:, :, :2], axis=0).max(axis=1)
    assert level_rms[t >= 60.0 - 1e-9].max() < 0.5
    heading = float(seed003.rms(e[:, camp.index(300.0), 2]))
    assert 5.5 <= heading <= 9.0
    lo, hi = anees_bounds(3, n)
    for tt in (60.0, 300.0):
        assert lo <= camp["align.nees"][:, camp.index(tt)].mean() <= hi


@pytest.mark.slow
def test_rotating_campaign_50_runs_meets_acceptance_3() -> None:
    n = 50
    camp = seed003.campaign(
        seed003.ROTATING, n, SEED, columns=list(seed003.COLUMNS), record_every=10, workers=2
    )
    e, sig = camp["align.rpy_err"], camp["align.rpy_sigma"]
    i600 = camp.index(600.0)
    assert seed003.rms(e[:, i600, 2]) <= 1.5
    for tt in (300.0, 600.0):
        i = camp.index(tt)
        ratio = seed003.rms(e[:, i, 2]) / sig[:, i, 2].mean()
        assert math.isclose(ratio, 1.0, abs_tol=0.25), (tt, ratio)
