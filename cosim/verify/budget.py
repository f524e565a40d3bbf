"""Error budget per requirement: the variance of its signal split by error source.

For a filter with a linear covariance model the estimation error is a sum of
independent contributions, one per source (initial errors, each sensor bias and drift
component, each white noise, the measurement noise, the flexure):
:func:`cosim.estimation.covariance.covariance_budget` propagates each part with the
filter's own gain, so the parts add up to the filter's covariance exactly. A
requirement's signal is a linear function of the error state, ``y = h e`` (``h`` a row
vector, e.g. a heading error ``-M_3 psi`` of the psi angle), so its variance splits as
``h P h^T = sum_s h P_s h^T``.

The time of the budget: a ``value`` requirement at its ``at`` (default the stop time);
a ``bound`` requirement over ``[from, until]`` is reduced to the time in the window
where the model's total variance is largest (the parts at that time); a ``settling``
requirement has no budget (its metric is a time, not a linear function of the error).

Models known here (the block's class in the scenario, its parameters from the file):

- ``SinsStaticAlignment`` (seed 003, static and turntable):
  :func:`cosim.alignment.static_model.static_budget`; the sensor errors split along
  north/east/down on a fixed base, along the table axes on a turntable;
- ``TransferAlignment`` (seed 001): :func:`cosim.alignment.transfer_analysis.transfer_budget`,
  the small-error model along the ship's closed-form motion (an ideal filter on the same
  data, not the block's two-stage bookkeeping); sensor errors per slave axis.

Beside it the campaign's evidence (:mod:`cosim.verify.regression`): each run's signed
error at the budget's time regressed on the parameters the campaign drew, with the slope
the linear model predicts (``h T(t) d``, ``T`` the error transfer matrix, ``d`` how the
parameter enters the initial error).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.estimation.covariance import CovarianceBudget
from cosim.verify.budget_hrg import HrgBudget
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
from cosim.verify.requirements import Requirement
from cosim.verify.seeds import Stratified

FloatArray = NDArray[np.float64]


@dataclass
class LinearModel:
    """A filter's linear error model, ready to budget requirements.

    Attributes
    ----------
    block : str
        The filter block's name in the scenario.
    description : str
        What the model is (for the report).
    budget : CovarianceBudget
        The covariance split by source.
    t0 : float
        Simulation time of the budget's time 0 [s].
    row : callable
        ``row(variable, t) -> h``: the signal ``block.variable`` as a row vector over the
        error state [rad per state SI unit] at simulation time ``t``, or None.
    regressors : callable
        ``regressors(draws) -> list of Regressor`` from the drawn parameters
        (``"block.name"`` -> ndarray (runs, size), SI).
    """

    block: str
    description: str
    budget: CovarianceBudget
    t0: float
    row: Callable[[str, float], FloatArray | None]
    regressors: Callable[[dict[str, FloatArray]], list[Regressor]]


# ------------------------------------------------------------------ scenario facts
def scenario_values(path: Any) -> tuple[Any, dict[str, dict[str, Any]]]:
    """The scenario and every block's parameters (file values over the defaults, SI).

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
    import warnings

    from cosim.scenario import Scenario, load_scenario

    scenario = path if isinstance(path, Scenario) else load_scenario(path)
    with warnings.catch_warnings():  # the campaign has shown them (feedback loops, ...)
        warnings.simplefilter("ignore")
        system, _ = scenario.build()
    try:
        values = {}
        for name, host in system.blocks.items():
            defaults = {v.name: v.start for v in host.variables.values()}
            values[name] = {**defaults, **system.parameters.get(name, {})}
    finally:
        for host in system.blocks.values():
            host.terminate()
    return scenario, values


def _vec(p: dict[str, Any], name: str) -> FloatArray:
    return np.array([float(p[f"{name}[{i}]"]) for i in (1, 2, 3)])


def _step(period: float) -> float:
    """0.1 s if it divides the update period, else the period itself."""
    k = period / 0.1
    return 0.1 if k >= 1 and abs(k - round(k)) < 1e-9 else period


def _of_source(scenario: Any, source: str) -> str | None:
    for name, spec in scenario.blocks.items():
        if spec.kind == "model" and spec.source == source:
            return name
    return None


def linear_model(
    path: str | Path,
    facts: tuple[Any, dict[str, dict[str, Any]]] | None = None,
    requirements: list[Requirement] | None = None,
) -> LinearModel | HrgBudget | None:
    """The linear error model of the scenario's alignment filter, if it has one.

    Parameters
    ----------
    path : str or Path
        Scenario file.
    facts : tuple, optional
        :func:`scenario_values` of it, if already read.
    requirements : list of Requirement, optional
        The requirements to budget: the seed 000 model (:class:`HrgBudget`, the linear
        KF's first-order budget) simulates their errors and needs them; without them a
        seed 000 scenario has no model.

    Returns
    -------
    LinearModel, HrgBudget or None
        None when no block of the scenario has a linear covariance model here.
    """
    scenario, values = facts if facts is not None else scenario_values(path)
    block = _of_source(scenario, "HrgTwoPositionAlignment")
    if block is not None:
        return None if requirements is None else HrgBudget(path, requirements, values, scenario)
    block = _of_source(scenario, "SinsStaticAlignment")
    if block is not None:
        return _static_model(scenario, values, block)
    block = _of_source(scenario, "TransferAlignment")
    if block is not None:
        return _transfer_model(scenario, values, block)
    return None


def _static_model(scenario: Any, values: dict[str, dict[str, Any]], block: str) -> LinearModel:
    from cosim.alignment.nav import euler_rate_matrix_inv
    from cosim.alignment.static_model import FilterTuning, static_budget, table_dcm
    from cosim.models.constants import DEG_PER_HOUR, MICRO_G
    from cosim.models.conventions import euler_to_dcm_3
    from cosim.models.turntable import Turntable

    a = values[block]
    tuning = FilterTuning.from_parameters(a)
    base = _of_source(scenario, "StationaryBase")
    base_rpy = _vec(values[base], "rpy0") if base else np.zeros(3)
    t0 = float(a["coarse_time"]) if int(a["init_mode"]) == 0 else 0.0
    t0 += float(scenario.settings.start)
    table = _of_source(scenario, "Turntable")
    angle = None
    if table is not None:
        tp = values[table]
        profile = Turntable(instance_name="budget")
        for name in ("mode", "angle0", "rate", "reversal_period", "rotation_start"):
            setattr(profile, name, tp[name])
        profile.accel_limit = tp["accel_limit"]

        def angle(t: FloatArray, _p: Turntable = profile) -> FloatArray:
            return _p.profile(np.asarray(t, dtype=float) + t0)[0]

    kf = float(a["kf_period"])
    t_end = round((float(scenario.settings.stop) - t0) / kf) * kf
    budget = static_budget(
        t_end,
        tuning=tuning,
        lat=float(a["lat"]),
        h=float(a["h"]),
        dt=kf,
        kf_period=kf,
        angle=angle,
        base_rpy=base_rpy,
        coriolis=True,
        record_every=max(1, int(round(1.0 / kf))),
    )
    c_b_n = euler_to_dcm_3(base_rpy)
    c_s_t = euler_to_dcm_3(_vec(a, "mount_rpy"))
    gamma0 = 0.0 if angle is None else float(angle(np.zeros(1))[0])
    c_t_n = c_b_n @ table_dcm(gamma0)
    m_rpy = euler_rate_matrix_inv(base_rpy)

    def row(variable: str, t: float) -> FloatArray | None:
        h = np.zeros(10)
        for name, m in (("rpy_err", m_rpy), ("phi_err", np.eye(3))):
            for k in range(3):
                if variable == f"{name}[{k + 1}]":
                    h[2:5] = -m[k]  # estimate minus truth = -psi (residual)
                    return h
        return None

    imu = _of_source(scenario, "StrapdownImu")

    def regressors(draws: dict[str, FloatArray]) -> list[Regressor]:
        out: list[Regressor] = []
        for key, (state, label, unit, factor, axes) in {
            f"{imu}.gyro_bias": (slice(7, 10), "gyro drift", "deg/h", DEG_PER_HOUR, "NED"),
            f"{imu}.accel_bias": (slice(5, 7), "accelerometer bias", "ug", MICRO_G, "NE"),
        }.items():
            if key not in draws:
                continue
            x_s = draws[key]  # sensor axes, SI
            if angle is None:  # fixed base: along north, east, down
                x_n = x_s @ (c_t_n @ c_s_t).T
                for k, ax in enumerate(axes):
                    d = np.zeros(10)
                    d[state] = c_t_n.T[: state.stop - state.start, k]
                    out.append(Regressor(f"{label} {ax}", unit, factor, x_n[:, k], d))
            else:  # turntable: table axes
                x_t = x_s @ c_s_t.T
                for k, ax in enumerate("xyz"[: state.stop - state.start]):
                    d = np.zeros(10)
                    d[state.start + k] = 1.0
                    out.append(Regressor(f"{label} {ax} (table)", unit, factor, x_t[:, k], d))
        return out

    where = "a turntable" if angle is not None else "a fixed base"
    return LinearModel(
        block,
        "seed 003 10-state psi-angle KF on " + where + " (cosim.alignment.static_model."
        "static_budget: Van Loan every kf_period, Joseph updates, the block's P0, Q, R)",
        budget,
        t0,
        row,
        regressors,
    )


def _transfer_model(scenario: Any, values: dict[str, dict[str, Any]], block: str) -> LinearModel:
    from cosim.alignment.nav import euler_rate_matrix_inv
    from cosim.alignment.transfer_analysis import ship_truth, transfer_budget
    from cosim.alignment.transfer_model import StateLayout, TransferTuning
    from cosim.models.constants import DEG_PER_HOUR, MICRO_G

    a = values[block]
    tuning = TransferTuning(
        p0_pos=float(a["p0_pos"]),
        p0_vel=float(a["p0_vel"]),
        p0_level=float(a["p0_level"]),
        p0_heading=float(a["p0_heading"]),
        p0_accel_bias=float(a["p0_accel_bias"]),
        p0_gyro_drift=float(a["p0_gyro_drift"]),
        q_accel=float(a["q_accel"]),
        q_gyro=float(a["q_gyro"]),
        r_vel=float(a["r_vel"]),
        flex_tau=tuple(_vec(a, "flexure_tau")),
        flex_sigma=tuple(_vec(a, "flexure_sigma")),
    )
    ship = values[_of_source(scenario, "ShipMotion") or ""]
    lever = _of_source(scenario, "LeverArm")
    mount = _vec(values[lever], "mount_rpy") if lever else np.zeros(3)
    flexure = bool(int(a["flexure_states"]))
    layout = StateLayout(flexure)
    lat = float(ship["lat0"])
    kw = {"lat": lat, "amp": _vec(ship, "amp"), "period": _vec(ship, "period")}
    t0 = float(scenario.settings.start)
    budget = transfer_budget(
        float(scenario.settings.stop) - t0,
        r0=_vec(a, "r0"),
        mount_rpy=mount,
        tuning=tuning,
        flexure=flexure,
        update_period=float(a["period"]),
        dt=_step(float(a["period"])),
        **kw,
    )
    m_rel = euler_rate_matrix_inv(mount)

    def row(variable: str, t: float) -> FloatArray | None:
        c_b_n = ship_truth([t - t0], **kw)["C_b_n"][0]
        for k in range(3):
            if variable == f"rpy_err[{k + 1}]":
                h = np.zeros(layout.n)
                h[layout.att] = (m_rel @ c_b_n.T)[k]
                return h
        return None

    imu = _of_source(scenario, "StrapdownImu")

    def regressors(draws: dict[str, FloatArray]) -> list[Regressor]:
        out: list[Regressor] = []
        for key, (state, label, unit, factor) in {
            f"{imu}.accel_bias": (layout.nabla, "accelerometer bias", "ug", MICRO_G),
            f"{imu}.gyro_bias": (layout.eps, "gyro drift", "deg/h", DEG_PER_HOUR),
        }.items():
            if key in draws:
                for k, ax in enumerate("xyz"):
                    d = np.zeros(layout.n)
                    d[state.start + k] = 1.0
                    out.append(Regressor(f"{label} {ax}", unit, factor, draws[key][:, k], d))
        return out

    return LinearModel(
        block,
        "seed 001 small-error model along the ship's closed-form motion "
        f"({'with' if flexure else 'without'} flexure states; cosim.alignment."
        "transfer_analysis.transfer_budget: an ideal linear filter on the same data, "
        "Van Loan steps, velocity matching every period)",
        budget,
        t0,
        row,
        regressors,
    )


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
    model: LinearModel | None,
    draws: dict[str, FloatArray],
) -> dict[str, Any]:
    """The error budget of one requirement and the campaign's regression (report data).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : Requirement
        One of its requirements.
    model : LinearModel, HrgBudget or None
        The scenario's linear model (:func:`linear_model`).
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
    if isinstance(model, HrgBudget):
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
    model: HrgBudget,
    draws: dict[str, FloatArray],
    stop: float,
) -> dict[str, Any]:
    """A requirement's budget from a model that budgets signals itself (seed 000)."""
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
    facts = scenario_values(campaign.source or path)  # as the campaign parsed it
    values = facts[1]
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
