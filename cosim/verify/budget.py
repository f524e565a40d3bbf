"""Error budget per requirement: the variance of its signal split by error source.

For a filter with a linear covariance model the estimation error is a sum of
independent contributions, one per source (initial errors, each sensor bias and drift
component, each white noise, the measurement noise, the flexure):
:func:`cosim.estimation.error_model.propagate` propagates each part with the
filter's own gain, so the parts add up to the filter's covariance exactly. A
requirement's signal is a linear function of the error state, ``y = h e`` (``h`` a row
vector, e.g. a heading error ``-M_3 psi`` of the psi angle), so its variance splits as
``h P h^T = sum_s h P_s h^T``.

The time of the budget: a ``value`` requirement at its ``at`` (default the stop time);
a ``bound`` requirement over ``[from, until]`` is reduced to the mean over the window's
times of the analysis (each part averaged the same way); a ``settling`` requirement has
no budget (its metric is a time, not a linear function of the error).

Which filter, which model: none is known here by name. A block class that implements
:class:`cosim.estimation.error_model.BudgetedFilter` (a class method ``budget_model``)
is asked for its model with the run's facts
(:class:`~cosim.estimation.error_model.RunFacts`); it returns a
:class:`~cosim.estimation.error_model.LinearErrorModel` (budgeted here), a
:class:`~cosim.estimation.error_model.SignalBudgetModel` (that budgets each
requirement itself) or None. docs/filter_budget.md shows a user's filter doing it.

Beside it the campaign's evidence (:mod:`cosim.verify.regression`): each run's signed
error at the budget's time regressed on the parameters the campaign drew, with the slope
the linear model predicts (``h T(t) d``, ``T`` the error transfer matrix, ``d`` how the
parameter enters the initial error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.estimation.covariance import CovarianceBudget
from cosim.estimation.error_model import (
    METHOD,
    LinearErrorModel,
    RunFacts,
    SignalBudgetModel,
    propagate,
)
from cosim.verify.regression import (  # noqa: F401  (budget_html, budget_figure: report API)
    NO_MODEL,
    RECORDED_METHOD,
    Regressor,
    budget_figure,
    budget_html,
    drawn_parameters,
    recorded_draws,
    regression_table,
)
from cosim.verify.requirements import Requirement, error_signal
from cosim.verify.seeds import Stratified

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LinearModel:
    """A filter's linear error model with its covariance split by line, ready to budget.

    Attributes
    ----------
    model : LinearErrorModel
        The filter's model (its block, description, rows and regressors).
    budget : CovarianceBudget
        :func:`cosim.estimation.error_model.propagate` of it.
    """

    model: LinearErrorModel
    budget: CovarianceBudget

    @property
    def block(self) -> str:
        """The filter block's name in the scenario."""
        return self.model.block

    @property
    def description(self) -> str:
        """What the model is (for the report)."""
        return self.model.description

    @property
    def t0(self) -> float:
        """Simulation time of the budget's time 0 [s]."""
        return float(self.model.t0)

    def row(self, variable: str, t: float) -> FloatArray | None:
        """The signal ``block.variable`` as a row over the error state at time ``t``, or None.

        Parameters
        ----------
        variable : str
            An output of the filter block (``"rpy_err[3]"``).
        t : float
            Simulation time [s].
        """
        return self.model.signal_row(variable, t)

    def regressors(self, draws: dict[str, FloatArray]) -> list[Regressor]:
        """The drawn parameters (``"block.name"`` -> (runs, size), SI) the model knows.

        Parameters
        ----------
        draws : mapping
            ``"block.name"`` -> ndarray (runs, size) [SI], the campaign's drawn parameters.
        """
        return self.model.regressors(draws)


# ------------------------------------------------------------------ scenario facts
@dataclass(frozen=True)
class BuiltScenario:
    """A scenario built (not run): its parameters and its blocks' classes.

    Attributes
    ----------
    scenario : Scenario
        The parsed file.
    values : dict
        ``{block: {parameter: SI value}}``, the file's values over the defaults.
    classes : dict
        ``{block: class}`` of the in-process blocks (an FMU has none).
    """

    scenario: Any
    values: dict[str, dict[str, Any]]
    classes: dict[str, type]


def scenario_facts(path: Any) -> BuiltScenario:
    """The scenario, every block's parameters (file values over the defaults, SI), classes.

    Parameters
    ----------
    path : str, Path or Scenario
        Scenario file, or the scenario as parsed (built, not run).

    Returns
    -------
    BuiltScenario
    """
    import warnings

    from cosim.scenario import Scenario, load_scenario

    scenario = path if isinstance(path, Scenario) else load_scenario(path)
    with warnings.catch_warnings():  # the campaign has shown them (feedback loops, ...)
        warnings.simplefilter("ignore")
        system, _ = scenario.build()
    try:
        values = {}
        classes = {}
        for name, host in system.blocks.items():
            defaults = {v.name: v.start for v in host.variables.values()}
            values[name] = {**defaults, **system.parameters.get(name, {})}
            cls = getattr(host, "cls", None)
            if isinstance(cls, type):
                classes[name] = cls
    finally:
        for host in system.blocks.values():
            host.terminate()
    return BuiltScenario(scenario, values, classes)


def scenario_values(path: Any) -> tuple[Any, dict[str, dict[str, Any]]]:
    """The scenario and every block's parameters (:func:`scenario_facts` without classes).

    Parameters
    ----------
    path : str, Path or Scenario
        Scenario file, or the scenario as parsed (built, not run).

    Returns
    -------
    scenario : Scenario
    values : dict
        ``{block: {parameter: SI value}}``.
    """
    facts = scenario_facts(path)
    return facts.scenario, facts.values


def run_facts(
    path: str | Path, facts: BuiltScenario, block: str, requirements: list[Requirement]
) -> RunFacts:
    """What the filter block ``block`` is told of the run (:class:`RunFacts`).

    Parameters
    ----------
    path : str or Path
        Scenario file.
    facts : BuiltScenario
        :func:`scenario_facts` of it.
    block : str
        The filter block.
    requirements : list of Requirement
        The requirements to budget.

    Returns
    -------
    RunFacts
    """
    sc = facts.scenario
    return RunFacts(
        block=block,
        models={n: (s.source if s.kind == "model" else "") for n, s in sc.blocks.items()},
        values=facts.values,
        start=float(sc.settings.start),
        stop=float(sc.settings.stop),
        step=float(sc.settings.step),
        rate=int(sc.blocks[block].rate),
        path=Path(path),
        requirements=tuple(requirements),
        error_signal=error_signal,
        scenario=sc,
    )


def linear_model(
    path: str | Path,
    facts: BuiltScenario | None = None,
    requirements: list[Requirement] | None = None,
) -> LinearModel | SignalBudgetModel | None:
    """The error model of the scenario's filter, from the first block that offers one.

    A block offers one when its class implements
    :class:`cosim.estimation.error_model.BudgetedFilter`; a
    :class:`~cosim.estimation.error_model.LinearErrorModel` is propagated here.

    Parameters
    ----------
    path : str or Path
        Scenario file.
    facts : BuiltScenario, optional
        :func:`scenario_facts` of it, if already read.
    requirements : list of Requirement, optional
        The requirements to budget (a model that simulates them needs them).

    Returns
    -------
    LinearModel, SignalBudgetModel or None
        None when no block of the scenario offers a model.
    """
    facts = facts if facts is not None else scenario_facts(path)
    for block, cls in facts.classes.items():
        offer = getattr(cls, METHOD, None)
        if not callable(offer):
            continue
        model = offer(run_facts(path, facts, block, list(requirements or [])))
        if isinstance(model, SignalBudgetModel) and not isinstance(model, LinearErrorModel):
            return model
        if model is not None:
            return LinearModel(model, propagate(model))
    return None


# ------------------------------------------------------------------ per requirement
def _stratified(campaign: Any, values: dict[str, dict[str, Any]]) -> list[Stratified]:
    out = []
    for item in campaign.provenance.get("stratified", []):
        block, name = item.split(".", 1)
        p = values.get(block, {})
        size = 0
        while f"{name}[{size + 1}]" in p:
            size += 1
        out.append(Stratified(block, name, max(size, 1), size > 0))
    return out


def signed_errors(campaign: Any, req: Requirement, t: float) -> FloatArray:
    """Each run's signed error at simulation time ``t`` (linear interpolation).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign (its runs' decimated histories).
    req : Requirement
        One of its requirements.
    t : float
        Time [s].

    Returns
    -------
    ndarray, shape (runs,)
        In the requirement's unit; nan for a failed run or one that ended before ``t``.
    """
    k = campaign.requirements.index(req)
    out = np.full(len(campaign.records), math.nan)
    for i, rec in enumerate(campaign.records):
        h = rec.history
        if rec.failed or f"e_{k}" not in h or not h["time"].size:
            continue
        if h["time"][0] - 1e-9 <= t <= h["time"][-1] + 1e-9:
            out[i] = float(np.interp(t, h["time"], h[f"e_{k}"]))
    return out


def _budget_times(req: Requirement, model: LinearModel, stop: float) -> tuple[FloatArray, str]:
    """Indices of the budget's times for a requirement, and how the window is reduced."""
    times = model.budget.time + model.t0
    if req.criterion == "value":
        at = stop if req.at is None else req.at
        return np.array([int(np.argmin(np.abs(times - at)))]), f"at {at:g} s"
    lo = -math.inf if req.start is None else req.start
    hi = math.inf if req.until is None else req.until
    inside = np.flatnonzero((times >= lo - 1e-9) & (times <= hi + 1e-9))
    if not inside.size:
        raise ValueError(f"{req.id}: its window has no time of the linear model's analysis")
    window = f"[{times[inside[0]]:g} s, {times[inside[-1]]:g} s]"
    return inside, (
        f"window {window}: the variance averaged over the window's times (the mean-square "
        "error over the window; each part averaged the same way, so they still add)"
    )


def requirement_budget(
    campaign: Any,
    req: Requirement,
    model: LinearModel | SignalBudgetModel | None,
    draws: dict[str, FloatArray],
) -> dict[str, Any]:
    """The error budget of one requirement and the campaign's regression (report data).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : Requirement
        One of its requirements.
    model : LinearModel, SignalBudgetModel or None
        The scenario's model (:func:`linear_model`).
    draws : dict
        The campaign's drawn parameters, ``"block.name"`` -> ndarray (runs, size) [SI].

    Returns
    -------
    dict
        ``id``, ``unit``, ``note`` (set when there is no budget), ``model``, ``method``,
        ``time``, ``reduction``, ``total`` (``variance``, ``sigma``), ``parts`` (per
        source ``source``, ``variance``, ``sigma``, ``share``), ``sum_check`` (relative
        difference of the parts' sum from the total) and ``regression``
        (:func:`cosim.verify.regression.regression_table`).
    """
    stop = float(campaign.provenance["master"]["stop"])
    out: dict[str, Any] = {"id": req.id, "unit": req.unit}
    block, _, variable = req.signal.partition(".")
    if isinstance(model, SignalBudgetModel) and not isinstance(model, LinearModel):
        return _direct_budget(campaign, req, model, draws, stop)
    h = None
    if model is not None and block == model.block and not req.minus and req.criterion != "settling":
        h = model.row(variable, stop)
    if h is None:
        out["note"] = (
            NO_MODEL
            if req.criterion != "settling"
            else (
                "no budget for a settling criterion (its metric is a time, not linear in the error)"
            )
        )
        out["regression"] = _regression_without_model(campaign, req, draws, stop)
        return out
    entry, rows, idx = signal_budget(model, req, stop)
    regs = model.regressors(draws)
    T = model.budget.transfer[idx]
    predicted = [
        None
        if r.direction is None
        else float(np.mean(np.einsum("ki,kij,j->k", rows, T, r.direction))) * r.factor
        for r in regs
    ]
    times = model.budget.time[idx] + model.t0
    if idx.size == 1:
        y, what = signed_errors(campaign, req, float(times[0])), f"signed error at {times[0]:g} s"
    else:
        y = window_mean_errors(campaign, req, float(times[0]), float(times[-1]))
        what = f"mean signed error over [{times[0]:g} s, {times[-1]:g} s]"
    out.update(entry)
    out["regression"] = {"response": what, **regression_table(y, regs, predicted, req.unit)}
    return out


def signal_budget(
    model: LinearModel, req: Requirement, stop: float
) -> tuple[dict[str, Any], FloatArray, int]:
    """The budget of a requirement's signal from a linear model (no campaign needed).

    Parameters
    ----------
    model : LinearModel
        The scenario's model; the requirement's signal must be one of its block's
        (:attr:`LinearModel.row` knows it).
    req : Requirement
        The requirement (``value`` or ``bound``).
    stop : float
        The run's stop time [s] (the default ``at`` and ``until``).

    Returns
    -------
    entry : dict
        ``model``, ``method``, ``time`` [s] (a window's end), ``window`` ([from, until]
        [s], equal for a ``value``), ``reduction``, ``total``, ``parts``, ``sum_check``
        (see :func:`requirement_budget`), in the requirement's unit.
    rows : ndarray, shape (k, n)
        The signal's row at each of the budget's times [requirement unit per state SI
        unit].
    index : ndarray of int, shape (k,)
        The budget's times as indices into ``model.budget.time``.

    Raises
    ------
    ValueError
        When the model does not know the signal.
    """
    from cosim.units import conversion_factor

    block, _, variable = req.signal.partition(".")
    if block != model.block or model.row(variable, stop) is None:
        raise ValueError(f"{req.id}: the linear model does not know the signal {req.signal}")
    to_unit = conversion_factor("rad", req.unit)
    bud = model.budget
    idx, reduction = _budget_times(req, model, stop)
    rows = np.array([model.row(variable, float(bud.time[i]) + model.t0) * to_unit for i in idx])

    def mean_var(P: FloatArray) -> float:
        return float(np.mean(np.einsum("ki,kij,kj->k", rows, P[idx], rows)))

    var = mean_var(bud.total)
    items = []
    for s, P in bud.parts.items():
        v = mean_var(P)
        share = v / var if var > 0 else math.nan
        items.append({"source": s, "variance": v, "sigma": math.sqrt(max(v, 0.0)), "share": share})
    times = bud.time[idx] + model.t0
    entry = {
        "model": model.description,
        "method": (
            "each source propagated alone with the filter's gain (linear filter, "
            "independent sources: the parts add); variance = h P_s h^T of the "
            "signal's row h over the error state"
        ),
        "time": float(times[-1]),
        "window": [float(times[0]), float(times[-1])],
        "reduction": reduction,
        "total": {"variance": var, "sigma": math.sqrt(max(var, 0.0))},
        "parts": items,
        "sum_check": sum(r["variance"] for r in items) / var - 1.0 if var > 0 else 0.0,
    }
    return entry, rows, idx


def window_mean_errors(campaign: Any, req: Requirement, t0: float, t1: float) -> FloatArray:
    """Each run's signed error averaged over its recorded samples in ``[t0, t1]``.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign (its runs' decimated histories).
    req : Requirement
        One of its requirements.
    t0, t1 : float
        The window [s].

    Returns
    -------
    ndarray, shape (runs,)
        In the requirement's unit; nan for a failed run or one without samples there.
    """
    k = campaign.requirements.index(req)
    out = np.full(len(campaign.records), math.nan)
    for i, rec in enumerate(campaign.records):
        h = rec.history
        if rec.failed or f"e_{k}" not in h:
            continue
        m = (h["time"] >= t0 - 1e-9) & (h["time"] <= t1 + 1e-9)
        if np.any(m) and h["time"][-1] >= t1 - 1e-9:
            out[i] = float(np.mean(h[f"e_{k}"][m]))
    return out


def _direct_budget(
    campaign: Any,
    req: Requirement,
    model: SignalBudgetModel,
    draws: dict[str, FloatArray],
    stop: float,
) -> dict[str, Any]:
    """A requirement's budget from a model that budgets signals itself."""
    out: dict[str, Any] = {"id": req.id, "unit": req.unit}
    entry = model.entry(req, stop)
    if isinstance(entry, str):
        out["note"] = entry
    else:
        out.update(entry)
    out["regression"] = _regression_without_model(campaign, req, draws, stop)
    return out


def _regression_without_model(
    campaign: Any, req: Requirement, draws: dict[str, FloatArray], stop: float
) -> dict[str, Any]:
    """The runs' regression on their own draws, with no predicted slopes.

    The response is the signed error at the requirement's time for a ``value``
    criterion, else the per-run metric.
    """
    regs = _generic_regressors(draws)
    if req.criterion == "value":
        at = stop if req.at is None else req.at
        y, what = signed_errors(campaign, req, at), f"signed error at {at:g} s"
    else:
        y, what = campaign.metric_values(req), "the per-run metric"
    return {
        "response": what,
        **regression_table(y, regs, [None] * len(regs), req.metric_unit),
    }


def _generic_regressors(draws: dict[str, FloatArray]) -> list[Regressor]:
    out = []
    for key, x in draws.items():
        for k in range(x.shape[1]):
            name = key if x.shape[1] == 1 else f"{key}[{k + 1}]"
            out.append(Regressor(name, "SI", 1.0, x[:, k]))
    return out


def campaign_budgets(campaign: Any) -> list[dict[str, Any]]:
    """The error budget of every requirement of a campaign (see :func:`requirement_budget`).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign; its scenario file is read again (built, not run).

    Returns
    -------
    list of dict
        One per requirement, in order.
    """
    path = campaign.scenario["file"]
    facts = scenario_facts(campaign.source or path)  # as the campaign parsed it
    values = facts.values
    model = linear_model(path, facts, list(campaign.requirements))
    draws, origin = campaign_draws(campaign, values)
    out = []
    for req in campaign.requirements:
        try:
            entry = requirement_budget(campaign, req, model, draws)
        except ValueError as exc:
            entry = {"id": req.id, "unit": req.unit, "note": f"no budget: {exc}"}
        if "regression" in entry and origin:
            entry["regression"]["regressors_from"] = origin
        out.append(entry)
    return out


def campaign_draws(
    campaign: Any, values: dict[str, dict[str, Any]]
) -> tuple[dict[str, FloatArray], dict[str, str]]:
    """Each run's drawn parameters, from the stratified design and the runs' own draws.

    ``[campaign] stratify`` parameters follow from the campaign seed and its design (the
    run count of a fixed campaign, one hypercube per look batch of ``--until-decided``;
    :func:`cosim.verify.regression.drawn_parameters`); a sensor block that draws from
    its own seed gives its draw as a truth output at the start
    (:func:`cosim.verify.regression.recorded_draws`, from each run's recorded seed).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    values : dict
        The scenario's parameters with defaults, ``{block: {name: SI value}}``.

    Returns
    -------
    draws : dict
        ``"block.name"`` -> ndarray (runs, size) [SI], the runs in record order.
    origin : dict
        ``"block.name"`` -> where its values came from (stated in the report).
    """
    stratified = _stratified(campaign, values)
    indices = [r.index for r in campaign.records]
    runs, seed = campaign.settings.design, campaign.settings.seed  # the stratified design
    draws = drawn_parameters(stratified, values, runs, seed, indices)
    origin = {
        k: "[campaign] stratify: the design's draw (campaign seed and design batches)"
        for k in draws
    }
    recorded = recorded_draws(
        campaign.source or campaign.scenario["file"],
        list(campaign.records),
        set(draws),
        stratified,
        runs,
        seed,
    )
    draws.update(recorded)
    origin.update({k: RECORDED_METHOD for k in recorded})
    return draws, origin


def budget_section(campaign: Any) -> dict[str, dict[str, Any]]:
    """:func:`campaign_budgets` keyed by requirement id, never raising (report data).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.

    Returns
    -------
    dict
        Requirement id -> its budget; when the budget cannot be computed (e.g. the
        scenario file is gone), an entry with only ``note`` saying why.
    """
    try:
        return {b["id"]: _finite(b) for b in campaign_budgets(campaign)}
    except Exception as exc:  # the report must be written whatever the budget does
        note = f"budget not computed: {type(exc).__name__}: {exc}"
        return {r.id: {"id": r.id, "unit": r.unit, "note": note} for r in campaign.requirements}


def _finite(x: Any) -> Any:
    """Non-finite floats as None (strict JSON), recursively."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(x) else None
    return x
