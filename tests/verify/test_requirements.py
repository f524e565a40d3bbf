"""Requirements: parsing errors, per-run criteria, campaign statistics and verdicts."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from cosim.errors import ScenarioError
from cosim.models.constants import ARCMIN
from cosim.results import RunResult
from cosim.verify.requirements import (
    SATISFIED,
    UNDECIDED,
    VIOLATED,
    Requirement,
    RunMetric,
    Verdict,
    error_signal,
    evaluate,
    load_requirements,
)
from cosim.verify.statistics import (
    clopper_pearson,
    judge,
    overall_exit_code,
    wilks_lower_rank,
    wilks_min_runs,
    wilks_upper_bound,
    wilks_upper_rank,
)

UNITS = {
    "time": "s",
    "sensor.m": "rad",
    "flexure.x": "rad",
    "flexure.x_dot": "rad/s",
    "filter.att_error[1]": "rad",
    "filter.att_error[2]": "rad",
    "filter.att_error[3]": "rad",
    "filter.heading_sigma": "rad",
    "filter.heading_deg": "deg",
    "filter.ratio": "1",
}
OUTPUTS = [*UNITS, "sensor.y"]  # sensor.y exists but is not recorded


def table(**kw: object) -> dict:
    base = {
        "id": "R1",
        "signal": "sensor.m",
        "minus": "flexure.x",
        "unit": "arcmin",
        "criterion": "bound",
        "bound": "1 arcmin",
    }
    base.update(kw)
    return {k: v for k, v in base.items() if v is not None}


def parse(*tables: dict, on_failure: str = "undecided") -> list[Requirement]:
    return load_requirements(list(tables), UNITS, "s.toml", OUTPUTS, on_failure=on_failure)


def req(**kw: object) -> Requirement:
    return parse(table(**kw))[0]


# ------------------------------------------------------------------------- parsing
def test_parse_converts_bounds_and_times_to_display_units() -> None:
    r = req(bound="0.1 deg", **{"from": "2 min"})
    assert r.limit == pytest.approx(6.0)  # 0.1 deg = 6 arcmin
    assert r.start == pytest.approx(120.0)
    assert r.factors[0] == pytest.approx(1 / ARCMIN) and r.factors[1] == pytest.approx(1 / ARCMIN)
    assert r.statistic == "max" and r.on_failure == "undecided"
    s = req(criterion="settling", bound=None, band="30 arcsec", within="1 min")
    assert s.band == pytest.approx(0.5) and s.limit == pytest.approx(60.0)
    assert s.metric_unit == "s"
    q = req(statistic="p99", confidence=0.9)
    assert (q.statistic, q.probability, q.confidence) == ("quantile", 0.99, 0.9)
    k = req(statistic="mean + 2.5 sigma")
    assert (k.statistic, k.k) == ("mean+ksigma", 2.5)
    p = req(statistic="pass_rate", probability="99 %")
    assert (p.probability, p.confidence) == (0.99, 0.95)
    assert req(signal="filter.att_error[3]", minus=None).minus is None


@pytest.mark.parametrize(
    "changes, key, fragment",
    [
        ({"signal": "sensor.mm"}, "requirements[0].signal", "Did you mean 'sensor.m'"),
        ({"signal": "filter.att_error"}, "requirements[0].signal", "filter.att_error[1]"),
        ({"signal": "sensor.y"}, "requirements[0].signal", "not recorded"),
        ({"minus": "nowhere.x"}, "requirements[0].minus", "unknown signal"),
        ({"unit": "arcmn"}, "requirements[0].unit", "unknown unit"),
        ({"unit": "m/s"}, "requirements[0].unit", "cannot be shown in 'm/s'"),
        ({"minus": "flexure.x_dot"}, "requirements[0].minus", "'rad/s'"),
        ({"bound": "7 m"}, "requirements[0].bound", "'m' cannot be converted to 'arcmin'"),
        ({"bound": [1, 2]}, "requirements[0].bound", "one number"),
        ({"criterion": "bund"}, "requirements[0].criterion", "Did you mean 'bound'"),
        ({"bound": None}, "requirements[0].bound", "needs 'bound'"),
        ({"within": "3 s"}, "requirements[0].within", "does not apply"),
        ({"boundd": "1 arcmin"}, "requirements[0].boundd", "Did you mean 'bound'"),
        ({"statistic": "p950"}, "requirements[0].statistic", "between p0 and p100"),
        ({"statistic": "median"}, "requirements[0].statistic", "unknown statistic"),
        ({"assume": "normal"}, "requirements[0].assume", "goes with 'rms'"),
        ({"statistic": "rms", "assume": "none"}, "requirements[0].assume", "Bahadur"),
        ({"statistic": "mean+3sigma", "assume": "gauss"}, "requirements[0].assume", "'none'"),
        ({"statistic": "p95", "probability": 0.9}, "requirements[0].probability", "'max'"),
        ({"statistic": "rms", "confidence": 0}, "requirements[0].confidence", "between 0 and"),
        ({"statistic": "p95", "confidence": 1.5}, "requirements[0].confidence", "between 0 and"),
        ({"statistic": "pass_rate"}, "requirements[0].probability", "needs 'probability'"),
        ({"on_failure": "ignore"}, "requirements[0].on_failure", "'exclude'"),
        ({"from": "5 s", "until": "2 s"}, "requirements[0].until", "before 'from'"),
        ({"from": "5 deg"}, "requirements[0].from", "cannot be converted to 's'"),
        ({"id": ""}, "requirements[0].id", "non-empty"),
    ],
)
def test_bad_requirement_names_file_and_key(changes: dict, key: str, fragment: str) -> None:
    with pytest.raises(ScenarioError) as info:
        parse(table(**changes))
    message = str(info.value)
    assert message.startswith("s.toml, key '"), message
    assert key in message and fragment in message, message


def test_duplicate_ids_and_non_table_are_refused() -> None:
    with pytest.raises(ScenarioError, match=r"requirements\[1\].id.*used twice"):
        parse(table(), table())
    with pytest.raises(ScenarioError, match=r"\[\[requirements\]\]"):
        load_requirements({"id": "R1"}, UNITS, "s.toml")


def test_wrap_needs_an_angle() -> None:
    with pytest.raises(ScenarioError, match=r"requirements\[0\].wrap.*angle unit"):
        parse(table(wrap=True, unit="1", signal="filter.ratio", minus=None, bound=1.0))


# --------------------------------------------------------------------- error signal
def _result(**cols: np.ndarray) -> RunResult:
    data = np.zeros(len(next(iter(cols.values()))), dtype=[(n, "f8") for n in cols])
    for n, v in cols.items():
        data[n] = v
    return RunResult(data)


def test_error_signal_subtracts_truth_converts_units_and_wraps() -> None:
    t = np.array([0.0, 1.0, 2.0])
    res = _result(
        time=t,
        **{
            "sensor.m": np.array([1.0, 2.0, 3.0]) * ARCMIN,
            "flexure.x": np.array([0.5, 0.5, 0.5]) * ARCMIN,
            "filter.heading_deg": np.array([179.0, -179.0, 10.0]),
        },
    )
    _, e, sigma = error_signal(req(), res)
    np.testing.assert_allclose(e, [0.5, 1.5, 2.5])
    assert sigma is None
    wrapped = req(signal="filter.heading_deg", minus=None, unit="deg", wrap=True, bound=1.0)
    # heading 179 deg and -179 deg stay; wrapping maps into (-180, 180]
    _, e, _ = error_signal(wrapped, res)
    np.testing.assert_allclose(e, [179.0, -179.0, 10.0])
    shifted = _result(time=t, **{"filter.heading_deg": np.array([181.0, -181.0, 540.0])})
    _, e, _ = error_signal(wrapped, shifted)
    np.testing.assert_allclose(e, [-179.0, 179.0, 180.0])


# ------------------------------------------------------------------------ criteria
T = np.linspace(0.0, 10.0, 1001)


def test_bound_criterion_uses_the_window_only() -> None:
    e = np.where(T < 2.0, 5.0, 0.5)
    e[-1] = -0.8
    r = req(**{"from": "2 s"})
    m = evaluate(r, T, e, 0.0, 10.0)
    assert m == RunMetric(0.8, True)  # |-0.8| is the largest in the window
    assert evaluate(req(), T, e, 0.0, 10.0) == RunMetric(5.0, False)
    one_sided = evaluate(req(absolute=False, **{"from": "2 s"}), T, e, 0.0, 10.0)
    assert one_sided.value == 0.5 and one_sided.passed
    late = evaluate(req(**{"from": "20 s"}), T, e, 0.0, 10.0)
    assert late.passed is None and "before the window starts at 20 s" in late.note
    short = evaluate(req(until="12 s"), T, e, 0.0, 10.0)
    assert short.passed is None and "until = 12 s" in short.note


def test_value_criterion_interpolates_and_defaults_to_the_stop_time() -> None:
    e = T.copy()  # e = t
    at = evaluate(req(criterion="value", at="2.345 s", bound="2 arcmin"), T, e, 0.0, 10.0)
    assert at.value == pytest.approx(2.345) and at.passed is False
    end = evaluate(req(criterion="value", bound="20 arcmin"), T, e, 0.0, 10.0)
    assert end == RunMetric(10.0, True)
    stopped_early = evaluate(req(criterion="value", bound="1 arcmin"), T[:500], e[:500], 0, 10)
    assert stopped_early.passed is None


def settling(**kw: object) -> Requirement:
    args = {"criterion": "settling", "bound": None, "band": "1 arcmin", "within": "4 s"}
    return req(**{**args, **kw})


def test_settling_time_is_the_start_of_the_final_stay_in_the_band() -> None:
    e = 10.0 * np.exp(-T)  # |e| <= 1 from t = ln 10 = 2.3026 s on
    m = evaluate(settling(), T, e, 0.0, 10.0)
    assert m.passed and m.value == pytest.approx(2.31)  # first sample inside
    bump = e.copy()
    bump[600] = 3.0  # leaves the band at 6 s: settles at 6.01 s > 4 s
    m = evaluate(settling(), T, bump, 0.0, 10.0)
    assert m.passed is False and m.value == pytest.approx(6.01)
    never = evaluate(settling(), T, np.full_like(T, 2.0), 0.0, 10.0)
    assert never.passed is False and math.isinf(never.value)
    # a run shorter than the allowed settling time cannot tell: undecided
    short = evaluate(settling(), T[:301], e[:301], 0.0, 10.0)
    assert short.passed is None and "too short to settle" in short.note
    # ... unless it already settled too late
    late = evaluate(settling(within="1 s"), T[:301], e[:301], 0.0, 10.0)
    assert late.passed is False


# ---------------------------------------------------------------------- statistics
def test_wilks_59_runs_at_95_95_is_the_sample_maximum() -> None:
    # Theory: P(max of n >= x_p) = 1 - p**n; 1 - 0.95**59 = 0.9515 >= 0.95 > 1 - 0.95**58.
    rng = np.random.default_rng(1)
    x = rng.standard_normal(59)
    assert wilks_upper_rank(59, 0.95, 0.95) == 59
    assert wilks_upper_bound(x, 0.95, 0.95) == x.max()
    assert wilks_upper_rank(58, 0.95, 0.95) is None
    assert wilks_min_runs(0.95, 0.95) == 59
    assert wilks_min_runs(0.95, 0.90) == 45  # ln(0.10) / ln(0.95) = 44.9
    assert wilks_min_runs(0.99, 0.95) == 299  # ln(0.05) / ln(0.99) = 298.1
    # Second and third order (Wilks' classic table): 93 runs -> 2nd largest, 124 -> 3rd.
    assert wilks_upper_rank(93, 0.95, 0.95) == 92 and wilks_upper_rank(92, 0.95, 0.95) == 92
    assert wilks_upper_rank(124, 0.95, 0.95) == 122


def test_wilks_bound_covers_the_quantile_as_often_as_promised() -> None:
    # For U(0, 1) samples x_0.95 = 0.95, and P(max of 59 >= 0.95) = 1 - 0.95**59 = 0.95151.
    # 20000 trials: standard error sqrt(0.9515 * 0.0485 / 20000) = 0.0015; allow 5 of them.
    rng = np.random.default_rng(7)
    samples = rng.random((20000, 59))
    covered = np.mean([wilks_upper_bound(s, 0.95, 0.95) >= 0.95 for s in samples[:2000]])
    assert covered > 0.93  # the function itself, on a subset
    freq = np.mean(samples.max(axis=1) >= 0.95)
    assert abs(freq - (1 - 0.95**59)) < 5 * 0.0015
    # Lower bound: P(X_(r) <= x_p) = P(Binomial(n, p) >= r); at n = 20 the 17th smallest.
    assert wilks_lower_rank(20, 0.95, 0.95) == 17
    assert stats.binom.sf(16, 20, 0.95) >= 0.95 > stats.binom.sf(17, 20, 0.95)


@pytest.mark.parametrize(
    "k, n, conf", [(0, 10, 0.95), (3, 10, 0.95), (7, 20, 0.9), (19, 20, 0.99), (20, 20, 0.9)]
)
def test_clopper_pearson_matches_scipy(k: int, n: int, conf: float) -> None:
    # L = Beta quantile (1 - conf; k, n - k + 1), U = Beta quantile (conf; k + 1, n - k).
    lower, upper = clopper_pearson(k, n, conf)
    expected_lower = stats.beta.ppf(1 - conf, k, n - k + 1) if k > 0 else 0.0
    expected_upper = stats.beta.ppf(conf, k + 1, n - k) if k < n else 1.0
    assert lower == pytest.approx(expected_lower, rel=1e-12, abs=1e-15)
    assert upper == pytest.approx(expected_upper, rel=1e-12, abs=1e-15)
    # scipy's exact binomial test gives the same one-sided bounds by another route.
    lo = stats.binomtest(k, n, alternative="greater").proportion_ci(conf, "exact").low
    hi = stats.binomtest(k, n, alternative="less").proportion_ci(conf, "exact").high
    assert lower == pytest.approx(lo, rel=1e-9, abs=1e-12)
    assert upper == pytest.approx(hi, rel=1e-9, abs=1e-12)
    if k == n:  # closed form with no failure: L = (1 - conf) ** (1 / n)
        assert lower == pytest.approx((1 - conf) ** (1 / n), rel=1e-12)


def passing(n: int, value: float = 0.5) -> list[RunMetric]:
    return [RunMetric(value, True)] * n


def test_percentile_is_undecided_with_too_few_runs_and_decided_with_enough() -> None:
    r = req(statistic="p95", confidence=0.95)
    v = judge(r, passing(20))
    assert v.verdict == UNDECIDED and "needs at least 59 runs, got 20" in v.reason
    rng = np.random.default_rng(3)
    values = rng.uniform(0.0, 0.9, 59)
    v = judge(r, [RunMetric(x, True) for x in values])
    assert v.verdict == SATISFIED and v.value == values.max()
    # Violated: the 95 % lower bound of the p95 (17th of 20) is above the bound.
    bad = [RunMetric(x, x <= 1.0) for x in [0.5] * 10 + [1.5] * 10]
    v = judge(r, bad)
    assert v.verdict == VIOLATED and v.value == 1.5 and v.interval == (1.5, math.inf)
    # Between: enough runs for an upper bound, but it is above the limit while the
    # lower bound is below it.
    mixed = [RunMetric(0.5, True)] * 58 + [RunMetric(1.5, False)]
    v = judge(r, mixed)
    assert v.verdict == UNDECIDED and "contains the bound" in v.reason


def test_pass_rate_uses_clopper_pearson() -> None:
    r = req(statistic="pass_rate", probability=0.9, confidence=0.9)
    # 20/20: L = 0.1 ** (1/20) = 0.891 < 0.9 -> undecided; 22/22: L = 0.9006 -> satisfied.
    assert judge(r, passing(20)).verdict == UNDECIDED
    v = judge(r, passing(22))
    assert v.verdict == SATISFIED and v.interval[0] == pytest.approx(0.1 ** (1 / 22))
    # 14/20: U = Beta(0.9; 15, 6) = 0.84 < 0.9 -> violated.
    runs = passing(14) + [RunMetric(2.0, False)] * 6
    v = judge(r, runs)
    assert v.verdict == VIOLATED and v.value == pytest.approx(0.7) and v.n_pass == 14


def test_point_statistics() -> None:
    runs = [RunMetric(x, x <= 1.0) for x in (0.2, 0.4, 0.6, 0.8)]
    assert judge(req(), runs).value == 0.8
    rms = judge(req(statistic="rms"), runs)
    assert rms.value == pytest.approx(math.sqrt((0.04 + 0.16 + 0.36 + 0.64) / 4))
    ks = judge(req(statistic="mean+3sigma", assume="normal"), runs)
    assert ks.value == pytest.approx(0.5 + 3 * np.std([0.2, 0.4, 0.6, 0.8], ddof=1))
    # 0.5 + 3 * 0.258 = 1.27 > 1, but 4 runs bound mu + 3 sigma only within [0.94, 2.8]
    # (noncentral t, 3 degrees of freedom): not shown either way.
    assert ks.verdict == UNDECIDED and ks.interval[0] < 1.0 < ks.interval[1]
    assert judge(req(statistic="mean+3sigma"), runs[:1]).verdict == UNDECIDED
    # the bootstrap bound needs 10 runs
    few = judge(req(statistic="mean+3sigma"), runs)
    assert few.verdict == UNDECIDED and "at least 10 runs" in few.reason


def test_a_run_too_short_makes_the_verdict_undecided() -> None:
    runs = passing(5) + [RunMetric(math.nan, None, "too short to settle")]
    v = judge(req(), runs)
    assert v.verdict == UNDECIDED and "too short to settle" in v.reason


def test_failed_runs_follow_on_failure() -> None:
    runs: list[RunMetric | None] = passing(9) + [None]
    # 9 passing runs show the 70 % quantile at 1 - 0.7**9 = 96 % >= 95 % confidence
    undecided = judge(req(probability=0.7), runs)
    assert undecided.verdict == UNDECIDED and "run(s) 9" in undecided.reason
    assert undecided.details["judged_on_completed_runs"] == SATISFIED
    assert undecided.claim.startswith("nothing is shown while 1 run(s) failed")
    excluded = judge(req(on_failure="exclude", probability=0.7), runs)
    assert excluded.verdict == SATISFIED and excluded.n_used == 9 and excluded.n_failed == 1
    counted = judge(req(on_failure="fail"), runs)
    assert counted.verdict == VIOLATED and math.isinf(counted.value)
    # A violation stands whatever the failed run would have given.
    bad = [RunMetric(3.0, False)] + passing(8) + [None]
    v = judge(req(), bad)
    assert v.verdict == VIOLATED and "whatever the 1 failed run" in v.reason
    # on_failure from [campaign] is the default of every requirement
    assert parse(table(), on_failure="exclude")[0].on_failure == "exclude"
    assert judge(req(), [None, None]).verdict == UNDECIDED


def test_exit_code_precedence() -> None:
    def v(kind: str) -> Verdict:
        return Verdict("x", kind, 0.0, 1.0, "1", "")

    assert overall_exit_code([v(SATISFIED)]) == 0
    assert overall_exit_code([v(SATISFIED), v(UNDECIDED)]) == 2
    assert overall_exit_code([v(UNDECIDED), v(VIOLATED)]) == 1
