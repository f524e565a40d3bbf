"""Requirements: parsing ``[[requirements]]`` and per-run criteria (see also statistics.py).

A requirement names a recorded **signal** (optionally ``minus`` a truth signal), a
display **unit**, a **criterion** that turns one run's signal into one number (its
*metric*) and a limit, and a campaign **statistic** that turns the metrics of all runs
into a three-valued verdict: ``satisfied``, ``violated`` or ``undecided``.

Criteria (``e(t)`` is the error in the display unit, ``t0`` the run's start time)::

    bound      metric = max |e(t)| over from <= t <= until      pass: metric <= bound
    value      metric = |e(at)| (linear interpolation)          pass: metric <= bound
    settling   metric = first time after which |e| <= band      pass: metric <= within
               until the end of the run, minus t0 [s]

Statistics over the runs, bounded at ``confidence`` (docs/verification.md;
:mod:`cosim.verify.statistics`)::

    max            every run meets the limit: one run over it violates; all n passing
                   with 1 - p^n >= confidence satisfies (`probability` p, default 0.95)
    rms            sqrt(mean(metric^2)), chi-square bounds (`assume = "normal"`)
    mean+<k>sigma  mean + k * std, bootstrap (`assume = "none"`) or noncentral-t bounds
    p<q>           Wilks order-statistic bounds of the q-th percentile
    pass_rate      Clopper-Pearson bounds of P(metric <= limit) against `probability`
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.errors import ScenarioError, UnitError
from cosim.results import RunResult
from cosim.units import conversion_factor, parse_unit, to_unit
from cosim.verify.estimates import Reference, parse_reference
from cosim.verify.table_keys import TableError, check_keys, fraction, table_error

SATISFIED = "satisfied"
VIOLATED = "violated"
UNDECIDED = "undecided"
VERDICTS = (SATISFIED, VIOLATED, UNDECIDED)

CRITERIA = ("bound", "value", "settling")
ON_FAILURE = ("undecided", "exclude", "fail")

REQUIREMENT_KEYS = {
    "id",
    "text",
    "signal",
    "minus",
    "reference",
    "sigma",
    "unit",
    "wrap",
    "absolute",
    "criterion",
    "bound",
    "from",
    "until",
    "at",
    "band",
    "within",
    "statistic",
    "probability",
    "confidence",
    "assume",
    "on_failure",
}
# Keys each criterion needs (beyond the common ones) and may use.
_CRITERION_KEYS = {
    "bound": ({"bound"}, {"bound", "from", "until", "absolute"}),
    "value": ({"bound"}, {"bound", "at", "absolute"}),
    "settling": ({"band", "within"}, {"band", "within"}),
}
_QUANTILE = re.compile(r"^p(\d+(?:\.\d+)?)$")
_MEAN_K_SIGMA = re.compile(r"^mean\s*\+\s*(\d+(?:\.\d+)?)\s*\*?\s*sigma$")
DEFAULT_CONFIDENCE = 0.95
DEFAULT_MAX_PROBABILITY = 0.95  # the quantile level a `max` shows
ASSUMPTIONS = ("normal", "none")
DEFAULT_ASSUME = {"rms": "normal", "mean+ksigma": "none"}


@dataclass(frozen=True)
class Requirement:
    """One ``[[requirements]]`` table, resolved against the recorded columns.

    Attributes
    ----------
    id : str
        Unique identifier (``"REQ-HDG-01"``).
    text : str
        The requirement as written for people.
    signal : str
        Recorded column (``"sensor.m"``, ``"filter.att_error[3]"``).
    minus : str or None
        Column subtracted from ``signal`` (a truth signal), or None.
    reference : Reference or None
        Value subtracted from ``signal`` (:mod:`cosim.verify.estimates`), or None.
    sigma : str or None
        Column holding the filter's 1-sigma of the error (for the +/-3 sigma plot), or None.
    unit : str
        Display unit of the error, of ``bound`` and ``band``.
    criterion : str
        ``"bound"``, ``"value"`` or ``"settling"``.
    limit : float
        ``bound`` [unit] for bound/value, ``within`` [s] for settling.
    band : float or None
        Settling band [unit].
    start : float or None
        ``from``: beginning of the bound window [s] (None: the run's start).
    until : float or None
        End of the bound window [s] (None: the run's end).
    at : float or None
        Time of the value criterion [s] (None: the run's end).
    absolute : bool
        Bound ``|e|`` (True) or ``e`` from above (False).
    wrap : bool
        Wrap the error to (-180 deg, 180 deg] (angles only).
    statistic : str
        ``"max"``, ``"rms"``, ``"mean+ksigma"``, ``"quantile"`` or ``"pass_rate"``.
    statistic_text : str
        The statistic as written (``"p95"``, ``"mean+3sigma"``).
    k : float or None
        Factor of ``mean+ksigma``.
    probability : float or None
        Quantile level p (``p95`` -> 0.95), the required pass rate, or for ``max`` the
        quantile level its sample maximum must bound (default 0.95).
    confidence : float or None
        One-sided confidence of the statistic's bounds (default 0.95).
    assume : str or None
        ``"normal"`` or ``"none"``: the distribution assumed by the ``rms`` and
        ``mean+ksigma`` bounds (None for the other statistics, which assume none).
    on_failure : str
        How failed runs count: ``"undecided"``, ``"exclude"`` or ``"fail"``.
    factors : tuple of float
        SI-to-display factors of (signal, minus, sigma) columns (1.0 when absent).
    index : int
        Position in the file (``requirements[index]``).
    """

    id: str
    text: str
    signal: str
    minus: str | None
    sigma: str | None
    unit: str
    criterion: str
    limit: float
    band: float | None = None
    start: float | None = None
    until: float | None = None
    at: float | None = None
    absolute: bool = True
    wrap: bool = False
    statistic: str = "max"
    statistic_text: str = "max"
    k: float | None = None
    probability: float | None = None
    confidence: float | None = None
    assume: str | None = None
    on_failure: str = "undecided"
    factors: tuple[float, float, float] = (1.0, 1.0, 1.0)
    index: int = 0
    reference: Reference | None = None

    @property
    def metric_unit(self) -> str:
        """Unit of the per-run metric: ``"s"`` for settling, else the display unit."""
        return "s" if self.criterion == "settling" else self.unit

    def describe(self) -> str:
        """The per-run criterion in words, e.g. ``"|e| <= 1.2 arcmin for t >= 10 s"``."""
        e = "|e|" if self.absolute else "e"
        if self.criterion == "bound":
            lo = f"t >= {self.start:g} s" if self.start is not None else ""
            hi = f"t <= {self.until:g} s" if self.until is not None else ""
            when = " and ".join(x for x in (lo, hi) if x) or "the whole run"
            return f"{e} <= {self.limit:g} {self.unit} for {when}"
        if self.criterion == "value":
            at = f"t = {self.at:g} s" if self.at is not None else "the end of the run"
            return f"{e} <= {self.limit:g} {self.unit} at {at}"
        return f"|e| settles within {self.band:g} {self.unit} in <= {self.limit:g} s"

    def describe_statistic(self) -> str:
        """The campaign statistic in words, e.g. ``"p95, Wilks bound at 95 % confidence"``."""
        conf = f"{100 * (self.confidence or DEFAULT_CONFIDENCE):g} % confidence"
        if self.statistic == "quantile":
            return f"{self.statistic_text}, Wilks bound at {conf}"
        if self.statistic == "pass_rate":
            return f"pass rate >= {100 * self.probability:g} % (Clopper-Pearson, {conf})"
        if self.statistic == "max":
            p = self.probability or DEFAULT_MAX_PROBABILITY
            return f"max (every run; shows {100 * p:g} % of runs at {conf})"
        assume = self.assume or DEFAULT_ASSUME[self.statistic]
        method = {"rms": "chi-square bound, normal errors", "none": "bootstrap bound"}.get(
            self.statistic if assume == "normal" else assume, "noncentral-t bound, normal metric"
        )
        return f"{self.statistic_text} ({method}, {conf})"

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view for JSON reports."""
        return {
            "id": self.id,
            "text": self.text,
            "signal": self.signal,
            "minus": self.minus,
            "reference": None if self.reference is None else self.reference.to_dict(),
            "sigma": self.sigma,
            "unit": self.unit,
            "criterion": self.criterion,
            "criterion_text": self.describe(),
            "limit": self.limit,
            "limit_unit": self.metric_unit,
            "band": self.band,
            "from": self.start,
            "until": self.until,
            "at": self.at,
            "absolute": self.absolute,
            "wrap": self.wrap,
            "statistic": self.statistic_text,
            "statistic_text": self.describe_statistic(),
            "probability": self.probability,
            "confidence": self.confidence,
            "assume": self.assume,
            "on_failure": self.on_failure,
        }


@dataclass(frozen=True)
class RunMetric:
    """One run's result for one requirement.

    Attributes
    ----------
    value : float
        The metric (display unit, or s for settling); ``inf`` when never settled,
        ``nan`` when undecided.
    passed : bool or None
        ``value <= limit``; None when the run cannot decide (too short).
    note : str
        Why the run is undecided or failed, else empty.
    """

    value: float
    passed: bool | None
    note: str = ""


@dataclass
class Verdict:
    """A requirement's campaign verdict.

    Attributes
    ----------
    id : str
        Requirement id.
    verdict : str
        ``"satisfied"``, ``"violated"`` or ``"undecided"``.
    value : float
        The campaign's statistic (nan when none could be computed): the sample max,
        RMS or mean + k sigma, the bound of a percentile, or for ``pass_rate`` the
        observed pass fraction.
    limit : float
        The limit the statistic is compared with (``probability`` for pass_rate).
    unit : str
        Unit of ``value`` and ``limit`` (``"1"`` for pass_rate).
    reason : str
        One sentence: the numbers behind the verdict.
    claim : str
        One sentence in words: the claim about the population of runs (all runs the
        campaign samples) the verdict supports, with its confidence and assumption.
    n_runs, n_used, n_failed, n_pass : int
        Runs in the campaign, runs the verdict is based on, failed runs, runs whose
        metric met the limit.
    interval : tuple of float or None
        (lower, upper): one-sided confidence bounds of the population value, each at the
        requirement's confidence (for ``max``: of its p-quantile); None when no run
        could be judged.
    details : dict
        Further numbers (sample quantile, order-statistic ranks, runs needed, ...).
    statistic : str
        The requirement's statistic (``"max"``, ..., ``"pass_rate"``).
    """

    id: str
    verdict: str
    value: float
    limit: float
    unit: str
    reason: str
    n_runs: int = 0
    n_used: int = 0
    n_failed: int = 0
    n_pass: int = 0
    interval: tuple[float, float] | None = None
    details: dict[str, Any] = field(default_factory=dict)
    statistic: str = ""
    claim: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view for JSON reports (non-finite numbers as strings)."""
        return {
            "id": self.id,
            "verdict": self.verdict,
            "value": _finite_or_text(self.value),
            "limit": self.limit,
            "unit": self.unit,
            "reason": self.reason,
            "claim": self.claim,
            "n_runs": self.n_runs,
            "n_used": self.n_used,
            "n_failed": self.n_failed,
            "n_pass": self.n_pass,
            "interval": None
            if self.interval is None
            else [_finite_or_text(x) for x in self.interval],
            "details": {k: _finite_or_text(v) for k, v in self.details.items()},
            "statistic": self.statistic,
        }


def _finite_or_text(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


# --------------------------------------------------------------------------- parsing
def load_requirements(
    tables: Any,
    units: Mapping[str, Any],
    file: str,
    outputs: Sequence[str] = (),
    on_failure: str = "undecided",
) -> list[Requirement]:
    """Parse and check the ``[[requirements]]`` tables of a scenario.

    Parameters
    ----------
    tables : list of dict
        ``scenario.raw.get("requirements", [])``.
    units : mapping
        Recorded column -> its unit: a unit string (``metadata["units"]`` of a built
        scenario) or a resolved unit object (an FMU's own unit definition).
    file : str
        The scenario file (for error messages).
    outputs : sequence of str
        Every Real output of the system (recorded or not), to tell "not recorded"
        from "unknown".
    on_failure : str
        Default for requirements without ``on_failure`` (from ``[campaign]``).

    Returns
    -------
    list of Requirement
        In file order.

    Raises
    ------
    ScenarioError
        Naming the file and the key (``requirements[i].key``) and how to fix it.
    """
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise ScenarioError(
            "expected an array of tables: write each requirement under its own "
            "[[requirements]] header",
            file=file,
            key="requirements",
        )
    out: list[Requirement] = []
    seen: dict[str, int] = {}
    for i, table in enumerate(tables):
        req = _parse_one(table, i, units, file, outputs, on_failure)
        if req.id in seen:
            raise ScenarioError(
                f"requirement id '{req.id}' is used twice (requirements[{seen[req.id]}] and "
                f"requirements[{i}]); ids must be unique",
                file=file,
                key=f"requirements[{i}].id",
            )
        seen[req.id] = i
        out.append(req)
    return out


def _parse_one(
    table: dict[str, Any],
    i: int,
    units: Mapping[str, Any],
    file: str,
    outputs: Sequence[str],
    default_on_failure: str,
) -> Requirement:
    err = table_error(table, i, file)
    rid, text = check_keys(table, REQUIREMENT_KEYS, ("id", "signal", "criterion"), err)

    criterion = table["criterion"]
    if criterion not in CRITERIA:
        hint = difflib.get_close_matches(str(criterion), CRITERIA, n=1)
        tip = f" Did you mean '{hint[0]}'?" if hint else ""
        raise err(
            f"unknown criterion {criterion!r}.{tip} Use 'bound' (|e| <= bound from a time on), "
            f"'settling' (settles within a band in a time) or 'value' (|e| <= bound at a time)",
            "criterion",
        )
    needed, allowed = _CRITERION_KEYS[criterion]
    for k in needed:
        if k not in table:
            raise err(f"criterion '{criterion}' needs '{k}'", k)
    for k in set(_CRITERION_KEYS["bound"][1] | _CRITERION_KEYS["value"][1] | {"band", "within"}):
        if k in table and k not in allowed:
            raise err(
                f"'{k}' does not apply to criterion '{criterion}' (it takes: "
                f"{', '.join(sorted(allowed))})",
                k,
            )

    # -- signals --------------------------------------------------------------
    signal = _column(table, "signal", units, outputs, err)
    minus = _column(table, "minus", units, outputs, err) if "minus" in table else None
    sigma = _column(table, "sigma", units, outputs, err) if "sigma" in table else None
    unit = table.get("unit", _unit_text(units[signal]))
    if not isinstance(unit, str):
        raise err(f"expected a unit string such as 'arcmin', got {unit!r}", "unit")
    try:
        parse_unit(unit)
    except UnitError as exc:
        raise err(str(exc), "unit") from exc

    def factor(column: str | None, key: str) -> float:
        if column is None:
            return 1.0
        try:
            return conversion_factor(units[column], unit)
        except UnitError as exc:
            raise err(
                f"'{column}' is in '{_unit_text(units[column])}', which cannot be shown in "
                f"'{unit}'; "
                f"give a unit of the same kind",
                "unit" if key == "signal" else key,
            ) from exc

    factors = (factor(signal, "signal"), factor(minus, "minus"), factor(sigma, "sigma"))
    reference = parse_reference(table, unit, err)
    wrap = _bool(table, "wrap", reference is not None and reference.angle, err)
    if wrap:
        try:
            conversion_factor(unit, "rad")
        except UnitError as exc:
            raise err(f"wrap = true needs an angle unit, not '{unit}'", "wrap") from exc

    # -- criterion values -----------------------------------------------------
    def quantity(key: str, target: str) -> float:
        raw = table[key]
        try:
            value = to_unit(raw, target)
        except UnitError as exc:
            raise err(f"{exc}", key) from exc
        if isinstance(value, (bool, list)) or not math.isfinite(float(value)):
            raise err(f"expected one number with a unit, e.g. '5 {target}', got {raw!r}", key)
        return float(value)

    def time(key: str) -> float | None:
        return quantity(key, "s") if key in table else None

    band = None
    if criterion == "settling":
        band = quantity("band", unit)
        limit = quantity("within", "s")
        if band <= 0:
            raise err(f"the band must be > 0, got {table['band']!r}", "band")
        if limit < 0:
            raise err(f"expected a duration >= 0 s, got {table['within']!r}", "within")
    else:
        limit = quantity("bound", unit)
    start, until, at = time("from"), time("until"), time("at")
    if start is not None and until is not None and until < start:
        raise err(f"'until' ({until:g} s) is before 'from' ({start:g} s)", "until")
    absolute = _bool(table, "absolute", True, err)
    if criterion != "settling" and absolute and limit < 0:
        raise err(
            f"a bound on |e| must be >= 0, got {table['bound']!r} (|e| <= a negative bound is "
            f"violated by every run); for a signed bound on e write absolute = false",
            "bound",
        )

    # -- statistic ------------------------------------------------------------
    stat_text = table.get("statistic", "max")
    if not isinstance(stat_text, str):
        raise err(f"expected a string such as 'max' or 'p95', got {stat_text!r}", "statistic")
    stat = stat_text.strip().lower().replace(" ", "")
    k = probability = confidence = assume = None
    if stat in ("max", "rms"):
        statistic = stat
    elif m := _MEAN_K_SIGMA.match(stat):
        statistic, k = "mean+ksigma", float(m.group(1))
    elif m := _QUANTILE.match(stat):
        statistic, probability = "quantile", float(m.group(1)) / 100.0
        if not 0.0 < probability < 1.0:
            raise err(f"a percentile must be between p0 and p100, got {stat_text!r}", "statistic")
    elif stat in ("pass_rate", "passrate", "pass-rate"):
        statistic = "pass_rate"
        if "probability" not in table:
            raise err("statistic 'pass_rate' needs 'probability' (e.g. 0.99)", "probability")
    else:
        raise err(
            f"unknown statistic {stat_text!r}; use 'max', 'rms', 'mean+3sigma' (any k), "
            f"'p95' (any percentile, Wilks) or 'pass_rate' (Clopper-Pearson)",
            "statistic",
        )
    if "probability" in table:
        if statistic not in ("pass_rate", "max"):
            raise err(
                "'probability' goes with statistic = 'pass_rate' (the pass rate to show) or "
                "'max' (the quantile level the largest run shows, default 0.95)",
                "probability",
            )
        probability = _fraction(table, "probability", err)
    elif statistic == "max":
        probability = DEFAULT_MAX_PROBABILITY
    confidence = (
        _fraction(table, "confidence", err) if "confidence" in table else DEFAULT_CONFIDENCE
    )
    assume = _assume(table, statistic, stat_text, err)
    on_failure = table.get("on_failure", default_on_failure)
    if on_failure not in ON_FAILURE:
        raise err(
            f"expected one of {', '.join(repr(x) for x in ON_FAILURE)}, got {on_failure!r}",
            "on_failure",
        )
    return Requirement(
        id=rid,
        text=text,
        signal=signal,
        minus=minus,
        sigma=sigma,
        unit=unit,
        criterion=criterion,
        limit=limit,
        band=band,
        start=start,
        until=until,
        at=at,
        absolute=absolute,
        wrap=wrap,
        statistic=statistic,
        statistic_text=stat_text.strip(),
        k=k,
        probability=probability,
        confidence=confidence,
        assume=assume,
        on_failure=on_failure,
        factors=factors,
        index=i,
        reference=reference,
    )


def _column(
    table: dict[str, Any],
    key: str,
    units: Mapping[str, Any],
    outputs: Sequence[str],
    err: TableError,
) -> str:
    name = table[key]
    if not isinstance(name, str):
        raise err(f"expected a recorded variable such as 'sensor.m', got {name!r}", key)
    name = name.strip()
    if name in units and name != "time":
        return name
    elements = sorted(c for c in units if c.startswith(f"{name}["))
    if elements:
        raise err(
            f"'{name}' is a vector; name one element, e.g. '{elements[0]}'",
            key,
        )
    if name in outputs or any(o.startswith(f"{name}[") for o in outputs):
        raise err(
            f"'{name}' is not recorded; add it (or its block) to output.variables",
            key,
        )
    recorded = [c for c in units if c != "time"]
    hint = difflib.get_close_matches(name, recorded, n=1)
    tip = f" Did you mean '{hint[0]}'?" if hint else ""
    raise err(
        f"unknown signal '{name}'.{tip} Recorded: {', '.join(recorded) or 'none'}",
        key,
    )


def _assume(table: dict[str, Any], statistic: str, stat_text: str, err: TableError) -> str | None:
    """The ``assume`` key: the distribution the rms / mean+ksigma bounds rest on."""
    if statistic not in DEFAULT_ASSUME:
        if "assume" in table:
            raise err(
                f"'assume' goes with 'rms' or 'mean+<k>sigma'; '{stat_text}' is bounded "
                f"without assuming a distribution",
                "assume",
            )
        return None
    value = table.get("assume", DEFAULT_ASSUME[statistic])
    if value not in ASSUMPTIONS:
        raise err(f"expected 'normal' or 'none', got {value!r}", "assume")
    if statistic == "rms" and value == "none":
        raise err(
            "an RMS has no confidence bound without a distribution assumption (one rare, "
            "huge run can move a mean square anywhere: Bahadur & Savage 1956); keep "
            "assume = 'normal' (chi-square bound, valid for metrics no heavier-tailed than "
            "|e| of a normal e) or bound a percentile ('p95') or a 'pass_rate', which "
            "assume no distribution",
            "assume",
        )
    return str(value)


def _unit_text(unit: Any) -> str:
    """A unit's text: ``units`` values are unit strings or resolved unit objects."""
    return str(getattr(unit, "text", unit))


def _bool(table: dict[str, Any], key: str, default: bool, err: TableError) -> bool:
    value = table.get(key, default)
    if not isinstance(value, bool):
        raise err(f"expected true or false, got {value!r}", key)
    return value


def _fraction(table: dict[str, Any], key: str, err: TableError) -> float:
    return fraction(table[key], key, err, "0.95 or '95 %'")


# --------------------------------------------------------------------------- one run
def error_signal(
    req: Requirement, result: RunResult
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The requirement's error and 1-sigma over time, in the display unit.

    Parameters
    ----------
    req : Requirement
        The requirement.
    result : RunResult
        A run's recording (SI columns).

    Returns
    -------
    t : ndarray, shape (n,)
        Recorded times [s].
    e : ndarray, shape (n,)
        ``signal - minus`` or ``signal - reference`` [req.unit], wrapped to
        (-180 deg, 180 deg] if asked.
    sigma : ndarray, shape (n,), or None
        The ``sigma`` column [req.unit], or None when the requirement has none.
    """
    f_sig, f_minus, f_sigma = req.factors
    e = np.asarray(result.data[req.signal], dtype=float) * f_sig
    if req.minus is not None:
        e = e - np.asarray(result.data[req.minus], dtype=float) * f_minus
    if req.reference is not None:
        e = e - req.reference.value
    if req.wrap:
        half = math.pi * conversion_factor("rad", req.unit)
        e = half - np.mod(half - e, 2.0 * half)
    sigma = None
    if req.sigma is not None:
        sigma = np.asarray(result.data[req.sigma], dtype=float) * f_sigma
    return np.asarray(result.time, dtype=float), e, sigma


def evaluate(
    req: Requirement, t: np.ndarray, e: np.ndarray, t_start: float, t_stop: float
) -> RunMetric:
    """One run's metric and pass/fail for one requirement.

    Parameters
    ----------
    req : Requirement
        The requirement.
    t : ndarray, shape (n,)
        Recorded times [s], increasing.
    e : ndarray, shape (n,)
        Error [req.unit].
    t_start : float
        The run's start time t0 [s] (settling times are counted from it).
    t_stop : float
        The scenario's stop time [s] (the default ``at`` of a value criterion).

    Returns
    -------
    RunMetric
        ``passed`` is None (undecided) when the run is too short to judge.
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if t.size == 0:
        return RunMetric(math.nan, None, "nothing was recorded")
    t_end = float(t[-1])
    tol = 1e-9 * max(1.0, abs(t_end))
    x = np.abs(e) if req.absolute else e
    if req.criterion == "bound":
        lo = t_start if req.start is None else req.start
        if req.until is not None and t_end < req.until - tol:
            return RunMetric(
                math.nan, None, f"the run ends at {t_end:g} s, before until = {req.until:g} s"
            )
        hi = t_end if req.until is None else req.until
        window = (t >= lo - tol) & (t <= hi + tol)
        if not np.any(window):
            return RunMetric(
                math.nan,
                None,
                f"the run ends at {t_end:g} s, before the window starts at {lo:g} s",
            )
        value = float(np.max(x[window]))
        return RunMetric(value, value <= req.limit)
    if req.criterion == "value":
        at = t_stop if req.at is None else req.at
        if t_end < at - tol or at < t[0] - tol:
            return RunMetric(
                math.nan, None, f"no recording at t = {at:g} s (run: up to {t_end:g} s)"
            )
        value = float(np.interp(at, t, e))
        value = abs(value) if req.absolute else value
        return RunMetric(value, value <= req.limit)
    # settling
    duration = t_end - t_start
    outside = np.flatnonzero(np.abs(e) > req.band)
    if outside.size == 0:
        settle = float(t[0] - t_start)
    elif outside[-1] == t.size - 1:
        settle = math.inf
    else:
        settle = float(t[outside[-1] + 1] - t_start)
    if settle > req.limit and math.isfinite(settle):
        return RunMetric(settle, False)
    if duration < req.limit - tol:
        return RunMetric(
            math.nan,
            None,
            f"the run lasts {duration:g} s, less than the settling time allowed "
            f"({req.limit:g} s): too short to settle",
        )
    if math.isinf(settle):
        return RunMetric(settle, False, "still outside the band at the end of the run")
    return RunMetric(settle, True)
