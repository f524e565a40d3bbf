"""The sequential rule of ``verify --until-decided`` keeps its error rate (issue 15, acceptance 2).

Simulation, no FMU: synthetic campaigns of per-run metrics from a known distribution,
judged at the planned looks with the statistics of :mod:`cosim.verify.statistics`.
A percentile (Wilks) and a pass rate (Clopper-Pearson) verdict depends on the runs only
through k, the number of runs whose metric meets the limit, so thousands of campaigns
are judged at once from cumulative counts; the vectorised verdicts are checked against
:func:`cosim.verify.sequential.judge_sequentially` (the code ``verify`` runs) on real
:class:`RunMetric` lists first.

Tolerance of a simulated rate (binomial): with m campaigns, an observed wrong-verdict
rate of a rule whose true rate is at most alpha stays below
``alpha + 3 sqrt(alpha (1 - alpha) / m)`` (a 3-sigma bound; with fixed seeds the
numbers are reproducible); naive re-testing is shown to exceed that same bound.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from cosim.verify.requirements import Requirement, RunMetric
from cosim.verify.sequential import (
    Looks,
    first_decisions,
    judge_sequentially,
    plan_looks,
)
from cosim.verify.statistics import wilks_lower_rank, wilks_upper_rank

ALPHA = 0.05
M = 20_000  # synthetic campaigns per case


def tolerance(alpha: float, m: int) -> float:
    """3-sigma binomial tolerance of a rate alpha estimated from m campaigns."""
    return 3.0 * math.sqrt(alpha * (1.0 - alpha) / m)


def quantile_req(limit: float = 1.0, q: float = 0.95, confidence: float = 0.95) -> Requirement:
    return Requirement(
        id="P95", text="", signal="s.y", minus=None, sigma=None, unit="1",
        criterion="bound", limit=limit, statistic="quantile", statistic_text=f"p{100 * q:g}",
        probability=q, confidence=confidence,
    )  # fmt: skip


def pass_rate_req(probability: float, confidence: float = 0.95) -> Requirement:
    return Requirement(
        id="RATE", text="", signal="s.y", minus=None, sigma=None, unit="1",
        criterion="bound", limit=1.0, statistic="pass_rate", statistic_text="pass_rate",
        probability=probability, confidence=confidence,
    )  # fmt: skip


# ------------------------------------------------------------------ vectorised verdicts
def wilks_codes(k: np.ndarray, looks: Looks, confidences: np.ndarray, q: float) -> np.ndarray:
    """Verdict codes of a p<q> requirement at each look from the pass counts k (m, K).

    Satisfied when the Wilks upper bound x_(r_up) <= limit, i.e. k >= r_up; violated when
    the lower bound x_(r_lo) > limit, i.e. k <= r_lo - 1 (statistics.wilks_*_rank).
    """
    out = np.zeros(k.shape, dtype=int)
    for j, (n, c) in enumerate(zip(looks.runs, confidences, strict=True)):
        up, lo = wilks_upper_rank(n, q, c), wilks_lower_rank(n, q, c)
        sat = k[:, j] >= up if up is not None else np.zeros(len(k), bool)
        vio = k[:, j] <= lo - 1 if lo is not None else np.zeros(len(k), bool)
        out[:, j] = np.where(sat, 1, np.where(vio, -1, 0))
    return out


def rate_codes(k: np.ndarray, looks: Looks, confidences: np.ndarray, p: float) -> np.ndarray:
    """Verdict codes of a pass_rate requirement: Clopper-Pearson bounds of k / n."""
    out = np.zeros(k.shape, dtype=int)
    for j, (n, c) in enumerate(zip(looks.runs, confidences, strict=True)):
        kj = k[:, j]
        with np.errstate(invalid="ignore"):
            lower = np.where(kj == 0, 0.0, stats.beta.ppf(1 - c, kj, n - kj + 1))
            upper = np.where(kj == n, 1.0, stats.beta.ppf(c, kj + 1, n - kj))
        out[:, j] = np.where(lower >= p, 1, np.where(upper < p, -1, 0))
    return out


def pass_counts(rng: np.random.Generator, pi: float, looks: Looks, m: int) -> np.ndarray:
    """Cumulative number of passing runs at each look, shape (m, K)."""
    passed = rng.random((m, looks.cap)) < pi
    return np.cumsum(passed, axis=1)[:, np.asarray(looks.runs) - 1]


def wrong_rate(codes: np.ndarray, truth: int) -> tuple[float, np.ndarray]:
    """Fraction of campaigns whose final verdict is the wrong decision, and the looks."""
    final, look = first_decisions(codes)
    return float(np.mean(final == -truth)), look


# ------------------------------------------------------------------------------ looks
def test_looks_double_up_to_the_cap_and_spend_alpha_once() -> None:
    assert plan_looks(20, 320).runs == (20, 40, 80, 160, 320)
    assert plan_looks(20, 300).runs == (20, 40, 80, 160, 300)
    assert plan_looks(20, 200).runs == (20, 40, 80, 200)  # 160 > 200 / 1.5: dropped
    assert plan_looks(20, 20).runs == (20,) and plan_looks(50, 20).runs == (20,)
    looks = plan_looks(20, 320)
    alphas = looks.alphas(ALPHA)
    assert alphas.sum() == pytest.approx(ALPHA, rel=1e-12)
    assert alphas == pytest.approx(ALPHA * np.array([20, 20, 40, 80, 160]) / 320)
    assert looks.confidences(0.95) == pytest.approx(1 - alphas)
    # one look is a fixed campaign at the requirement's own confidence
    assert plan_looks(59, 59).confidences(0.95) == pytest.approx([0.95])
    with pytest.raises(ValueError, match="increasing"):
        Looks((20, 20))


def test_first_decision_is_final() -> None:
    codes = np.array([[0, 1, -1], [0, 0, 0], [-1, 1, 1], [0, 0, 1]])
    final, look = first_decisions(codes)
    assert final.tolist() == [1, 0, -1, 1] and look.tolist() == [1, -1, 0, 2]


# ---------------------------------------------------------- the vectorised = the real
@pytest.mark.parametrize("pi", [0.925, 0.95, 0.97])
def test_vectorised_verdicts_are_those_of_judge_sequentially(pi: float) -> None:
    """On 30 campaigns per case: same final verdict and same deciding look."""
    rng = np.random.default_rng(11)
    looks = plan_looks(20, 320)
    limit_q = stats.norm.ppf(0.5 + pi / 2)  # P(|e| <= limit) = pi
    q_req, r_req = quantile_req(limit_q), pass_rate_req(0.9)
    e = np.abs(rng.standard_normal((30, looks.cap)))
    k = np.cumsum(e <= limit_q, axis=1)[:, np.asarray(looks.runs) - 1]
    for req, codes in (
        (q_req, wilks_codes(k, looks, looks.confidences(0.95), 0.95)),
        (r_req, rate_codes(k, looks, looks.confidences(0.95), 0.9)),
    ):
        final, look = first_decisions(codes)
        for i in range(len(e)):
            metrics = [RunMetric(float(x), bool(x <= limit_q)) for x in e[i]]
            sv = judge_sequentially(req, metrics, looks)
            code = {"satisfied": 1, "violated": -1, "undecided": 0}[sv.verdict.verdict]
            assert (code, -1 if sv.look is None else sv.look) == (final[i], look[i]), (req.id, i)


# ------------------------------------------------------ acceptance 2: the error rate
@pytest.mark.parametrize(
    ("what", "pi", "truth"),
    [
        # |e| with e ~ N(0, 1): p95 = 1.96; limit = p95 / 1.1 (true 10 % above) -> the
        # runs pass with pi = 2 Phi(1.96 / 1.1) - 1 = 0.925, violated is right
        ("p95 10 % above the limit", 2 * stats.norm.cdf(1.959964 / 1.1) - 1, -1),
        ("p95 10 % below the limit", 2 * stats.norm.cdf(1.959964 / 0.9) - 1, 1),
        ("p95 at the limit", 0.95, 1),
        ("p95 30 % below the limit", 2 * stats.norm.cdf(1.959964 / 0.7) - 1, 1),
    ],
)
def test_percentile_wrong_verdict_rate_stays_below_alpha(what: str, pi: float, truth: int) -> None:
    rng = np.random.default_rng(2026)
    looks = plan_looks(20, 320)
    k = pass_counts(rng, pi, looks, M)
    rate, look = wrong_rate(wilks_codes(k, looks, looks.confidences(1 - ALPHA), 0.95), truth)
    assert rate <= ALPHA + tolerance(ALPHA, M), (what, rate)
    if what.startswith("p95 30 %"):  # far below the limit: most campaigns stop early
        assert np.mean((look >= 0) & (look < len(looks.runs) - 1)) > 0.5


@pytest.mark.parametrize(
    ("what", "pi", "truth"),
    [("pass rate 10 % above", 0.88, 1), ("pass rate 10 % below", 0.72, -1), ("at", 0.8, 1)],
)
def test_pass_rate_wrong_verdict_rate_stays_below_alpha(what: str, pi: float, truth: int) -> None:
    """Required pass rate 0.8 at 95 % confidence; true rates 0.88, 0.72 and 0.8."""
    rng = np.random.default_rng(7)
    looks = plan_looks(20, 320)
    k = pass_counts(rng, pi, looks, M)
    rate, _ = wrong_rate(rate_codes(k, looks, looks.confidences(1 - ALPHA), 0.8), truth)
    assert rate <= ALPHA + tolerance(ALPHA, M), (what, rate)


def test_naive_retesting_exceeds_alpha_and_the_rule_does_not() -> None:
    """The same looks, judged at 95 % each time (naive) or by alpha spending (ours).

    True p95 exactly at the limit (satisfied is right): each look alone calls it
    violated with probability <= 5 %, but over 5 looks naive re-testing does so in
    about 11 % of campaigns (30 looks every 10 runs: about 16 %).
    """
    rng = np.random.default_rng(99)
    for looks in (plan_looks(20, 320), Looks(tuple(range(10, 310, 10)))):
        k = pass_counts(rng, 0.95, looks, M)
        naive, _ = wrong_rate(wilks_codes(k, looks, np.full(len(looks.runs), 0.95), 0.95), 1)
        ours, _ = wrong_rate(wilks_codes(k, looks, looks.confidences(0.95), 0.95), 1)
        assert naive > ALPHA + tolerance(ALPHA, M), (looks.runs, naive)
        assert ours <= ALPHA + tolerance(ALPHA, M), (looks.runs, ours)


# ------------------------------------------------------------- rms (chi-square bound)
def rms_req(limit: float = 1.0) -> Requirement:
    return Requirement(
        id="RMS", text="", signal="s.y", minus=None, sigma=None, unit="1",
        criterion="value", limit=limit, statistic="rms", statistic_text="rms",
        confidence=0.95,
    )  # fmt: skip


def rms_codes(m: np.ndarray, looks: Looks, confidences: np.ndarray) -> np.ndarray:
    """Verdict codes of an rms requirement (limit 1) from the metrics m (c, N):
    cosim.verify.bounds.rms_bounds on the first n_j runs, vectorised over campaigns."""
    from cosim.verify.bounds import rms_bounds

    out = np.zeros((m.shape[0], len(looks.runs)), dtype=int)
    for j, (n, c) in enumerate(zip(looks.runs, confidences, strict=True)):
        lower, upper = rms_bounds(m[:, :n], float(c))
        out[:, j] = np.where(upper <= 1.0, 1, np.where(lower > 1.0, -1, 0))
    return out


def test_rms_vectorised_verdicts_are_those_of_judge_sequentially() -> None:
    rng = np.random.default_rng(5)
    looks = plan_looks(20, 160)
    m = np.abs(rng.normal(0.0, 1.05, (25, looks.cap)))
    final, look = first_decisions(rms_codes(m, looks, looks.confidences(0.95)))
    for i in range(len(m)):
        sv = judge_sequentially(
            rms_req(), [RunMetric(float(x), bool(x <= 1.0)) for x in m[i]], looks
        )
        code = {"satisfied": 1, "violated": -1, "undecided": 0}[sv.verdict.verdict]
        assert (code, -1 if sv.look is None else sv.look) == (final[i], look[i]), i


@pytest.mark.parametrize(
    ("what", "sigma", "truth"), [("10 % above", 1.1, -1), ("10 % below", 0.9, 1)]
)
def test_rms_wrong_verdict_rate_stays_below_alpha_and_naive_exceeds_it(
    what: str, sigma: float, truth: int
) -> None:
    """Metrics |e|, e ~ N(0, sigma^2): the true RMS is sigma, the limit 1.

    Looks every 5 runs up to 200 (40 looks): naive re-testing at 95 % calls an RMS 10 %
    above its limit satisfied in about 9 % of campaigns; alpha spending in about 0.3 %.
    """
    rng = np.random.default_rng(31)
    m_campaigns = 10_000
    looks = Looks(tuple(range(5, 205, 5)))
    m = np.abs(rng.normal(0.0, sigma, (m_campaigns, looks.cap)))
    tol = tolerance(ALPHA, m_campaigns)
    ours, _ = wrong_rate(rms_codes(m, looks, looks.confidences(0.95)), truth)
    assert ours <= ALPHA + tol, (what, ours)
    doubling = plan_looks(20, 320)  # the looks of verify --until-decided --runs 20
    mm = np.abs(rng.normal(0.0, sigma, (m_campaigns, doubling.cap)))
    rate, _ = wrong_rate(rms_codes(mm, doubling, doubling.confidences(0.95)), truth)
    assert rate <= ALPHA + tol, (what, doubling.runs, rate)
    if truth == -1:
        naive, _ = wrong_rate(rms_codes(m, looks, np.full(len(looks.runs), 0.95)), truth)
        assert naive > ALPHA + tol, (what, naive)


# ------------------------------------------------------------- stratified designs
def test_a_shipped_stratified_scenario_gets_one_hypercube_per_look_batch() -> None:
    """transfer_alignment.toml (stratified) is no longer refused: the jobs of its looks
    30, 60, 120, 240 start with those of ``verify --runs 30`` (seeds and draws) and the
    second batch is a hypercube of its own (tests/verify/test_sequential_strata.py runs one)."""
    from cosim.verify.campaign import campaign_jobs, prepare
    from cosim.verify.seeds import design_draws

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "transfer_alignment.toml"
    prep = prepare(scenario)
    looks = plan_looks(30, 240)
    jobs = campaign_jobs(prep, 2011, looks.cap, strata=looks.runs)
    assert jobs[:30] == campaign_jobs(prep, 2011, 30)
    z = design_draws(looks.runs, 6, 2011)
    for i in (30, 59, 239):
        (_, _, za), (_, _, zg) = jobs[i].stratified
        assert (*za, *zg) == tuple(z[i])


def test_resume_refuses_other_looks(tmp_path) -> None:
    """The looks are fixed before the first run: --resume with another cap is refused."""
    from cosim.verify.campaign import CampaignError
    from cosim.verify.sequential import SEQUENTIAL_FILE, run_until_decided

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "demo_verify.toml"
    out = tmp_path / "r"
    campaign = run_until_decided(scenario, out, runs=2, max_runs=2, workers=1, progress=False)
    assert len(campaign.records) == 2 and (out / SEQUENTIAL_FILE).is_file()
    assert campaign.execution["sequential"]["looks"] == [2]
    with pytest.raises(CampaignError, match="cannot resume: looks was"):
        run_until_decided(scenario, out, max_runs=8, resume=True, workers=1, progress=False)
    with pytest.raises(CampaignError, match="to resume with --until-decided"):
        run_until_decided(scenario, tmp_path / "none", resume=True, workers=1, progress=False)
