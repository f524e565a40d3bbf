"""The campaign's own evidence for an error budget: regression of each run's error on its draws.

A campaign draws some parameters itself (``[campaign] stratify``; :mod:`cosim.verify.seeds`),
so it knows, run by run, the value each of them took. Regressing each run's signed
error at the requirement's time on those values by ordinary least squares measures the
sensitivity of the error to each drawn source directly from the simulations, beside the
linear model's prediction (:mod:`cosim.verify.budget`)::

    y_i = b_0 + sum_j b_j x_ij + r_i                  (i = 1 .. n runs, p regressors)
    b   = (X^T X)^-1 X^T y,      X = [1, x_1 .. x_p]   (n x (p + 1))
    s^2 = sum_i r_i^2 / (n - p - 1)                   residual variance
    se(b_j) = sqrt(s^2 [(X^T X)^-1]_jj)               standard error of each slope

The standard errors assume residuals independent with a common variance (the runs are
independent; the sources not regressed on, e.g. the white noises, make up the
residual). With a linear filter and Gaussian sources the slope is unbiased and
``(b_j - beta_j) / se(b_j)`` is Student-t with ``n - p - 1`` degrees of freedom.

:func:`regression_html` renders the table for the HTML report (with :func:`html_table`
and :func:`fmt`, which the budget section uses too).
"""

from __future__ import annotations

import base64
import html
import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.estimation.error_model import Regressor
from cosim.verify.seeds import Stratified, stratified_draws

FloatArray = NDArray[np.float64]

#: The note of a requirement whose filter has no linear error model here.
NO_MODEL = "no linear error model for this filter"

#: Largest condition number of the standardised regressors' correlation matrix (with the
#: intercept) before they are called collinear.
COLLINEAR = 1e10

#: The formula stated in reports.
SE_FORMULA = (
    "ordinary least squares with an intercept; se(b_j) = sqrt(s^2 [(X^T X)^-1]_jj), "
    "s^2 = sum of squared residuals / (n - p - 1)"
)


@dataclass(frozen=True)
class Regression:
    """An ordinary least-squares fit (module docstring).

    Attributes
    ----------
    names : tuple of str
        Regressor names (without the intercept).
    units : tuple of str
        Their display units.
    slope : ndarray, shape (p,)
        Coefficients [response unit per regressor unit].
    se : ndarray, shape (p,)
        Their standard errors.
    intercept : float
        ``b_0`` [response unit].
    residual_sigma : float
        ``s`` [response unit].
    r2 : float
        Coefficient of determination.
    n : int
        Runs used.
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    slope: FloatArray
    se: FloatArray
    intercept: float
    residual_sigma: float
    r2: float
    n: int


def ols(y: FloatArray, X: FloatArray, names: tuple[str, ...], units: tuple[str, ...]) -> Regression:
    """Ordinary least squares of ``y`` on the columns of ``X`` plus an intercept.

    Parameters
    ----------
    y : ndarray, shape (n,)
        Response (finite).
    X : ndarray, shape (n, p)
        Regressors (finite), in their display units.
    names, units : tuple of str
        Names and units of the ``p`` columns.

    Returns
    -------
    Regression

    Raises
    ------
    ValueError
        Fewer than ``p + 2`` runs (no residual degree of freedom), a column that does
        not vary, or columns collinear after standardising (condition number of their
        correlation matrix over :data:`COLLINEAR`).
    """
    y = np.asarray(y, dtype=float)
    X = np.asarray(X, dtype=float).reshape(y.size, -1)
    n, p = X.shape
    if n < p + 2:
        raise ValueError(f"{n} runs for {p} regressors: at least {p + 2} needed")
    # Standardise the columns (centre, unit spread): the fit does not change, but the
    # condition number then measures collinearity, not the columns' units (raw SI draws
    # of 1e-7 rad/s beside 1e-3 rad give 1e15 for independent columns).
    center, scale = X.mean(axis=0), X.std(axis=0)
    flat = [names[j] for j in range(p) if not scale[j] > 1e-12 * abs(center[j])]
    if flat:
        raise ValueError(f"{', '.join(flat)} does not vary over the runs")
    Z = (X - center) / scale
    A = np.column_stack([np.ones(n), Z])
    xtx = A.T @ A
    cond = float(np.linalg.cond(xtx / n))
    if cond > COLLINEAR:
        raise ValueError(
            f"the regressors are collinear (condition number {cond:.3g} of their "
            f"standardised correlation, over {COLLINEAR:g})"
        )
    inv = np.linalg.inv(xtx)
    gamma = inv @ (A.T @ y)
    resid = y - A @ gamma
    dof = n - p - 1
    s2 = float(resid @ resid) / dof
    se_z = np.sqrt(np.clip(np.diag(inv) * s2, 0.0, None))
    slope, se = gamma[1:] / scale, se_z[1:] / scale  # back to the columns' own units
    intercept = float(gamma[0] - slope @ center)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(resid @ resid) / ss_tot if ss_tot > 0 else math.nan
    return Regression(tuple(names), tuple(units), slope, se, intercept, math.sqrt(s2), r2, n)


def drawn_parameters(
    stratified: list[Stratified],
    values: dict[str, dict[str, Any]],
    runs: int | tuple[int, ...],
    seed: int,
    indices: list[int],
) -> dict[str, FloatArray]:
    """The values the campaign drew for its stratified parameters, run by run.

    Run ``i`` uses ``name = value in the file + name_sigma * z_i``
    (:func:`cosim.verify.seeds.stratified_draws`), so the draws follow from the campaign
    seed, its run count and the file's values alone.

    Parameters
    ----------
    stratified : list of Stratified
        ``[campaign] stratify``, resolved.
    values : dict
        The scenario's parameters with defaults, ``{block: {name: SI value}}``.
    runs : int or tuple of int
        The campaign's stratified design (``Campaign.settings.design``: its run count,
        or the look batches of ``--until-decided``).
    seed : int
        Campaign seed.
    indices : list of int
        The runs wanted, in order.

    Returns
    -------
    dict
        ``"block.name"`` -> ndarray, shape (len(indices), size) [SI].
    """
    out: dict[str, FloatArray] = {}
    for s in stratified:
        p = values[s.block]
        base = np.array([float(p[c]) for c in s.components])
        sigma = float(p[s.sigma])
        out[f"{s.block}.{s.name}"] = np.zeros((len(indices), s.size))
        for row, i in enumerate(indices):
            for block, name, z in stratified_draws(stratified, runs, seed, i):
                if (block, name) == (s.block, s.name):
                    out[f"{s.block}.{s.name}"][row] = base + sigma * np.asarray(z)
    return out


#: Sensor blocks whose truth outputs carry a run's own draw (blocks drawing from their own
#: seed): model class -> ((output, draw key), ...); the draw key is the parameter the
#: ``[campaign] stratify`` draw of the same quantity would have (``"gyro_bias"``), so a
#: linear model's regressors read both alike.
TRUTH_OUTPUTS: dict[str, tuple[tuple[str, str], ...]] = {
    "StrapdownImu": (("gyro_bias_b", "gyro_bias"), ("accel_bias_b", "accel_bias")),
}

#: How :func:`recorded_draws` obtains its regressors (stated in reports).
RECORDED_METHOD = (
    "from the run's recorded seeds: the sensor block re-initialised with the run's seed "
    "and parameters (no simulation), its truth output at the start time, i.e. the "
    "turn-on draw of that run (plus the initial Gauss-Markov state) that the run's own "
    "block output at t0"
)


def recorded_draws(
    path: Any,
    records: list[Any],
    skip: set[str],
    stratified: list[Stratified] | None = None,
    runs: int | tuple[int, ...] = 0,
    seed: int = 0,
) -> dict[str, FloatArray]:
    """Each run's own draw of the sensor errors, read from the sensor blocks' truth outputs.

    A block that draws its turn-on errors from its own seed (``StrapdownImu``: gyro and
    accelerometer biases) outputs them as truth (``gyro_bias_b``, ``accel_bias_b``
    [rad/s, m/s^2]). The campaign records each run's seeds; the block is set up with the
    run's seed, its parameters and the run's stratified draws (if any), and initialised,
    which draws exactly what the run drew, and its truth output at the start is read. No
    simulation runs and nothing a run records changes: the metrics cannot move.

    Parameters
    ----------
    path : str or Scenario
        The campaign's scenario file, or the scenario as the campaign parsed it.
    records : list of RunRecord
        The runs (their ``seeds``), in order.
    skip : set of str
        Draw keys (``"block.name"``) known otherwise (stratified): left out.
    stratified : list of Stratified, optional
        The campaign's stratified parameters (applied to the block as in the run).
    runs : int or tuple of int
        The campaign's stratified design (its run count, or its look batches).
    seed : int
        The campaign seed (for the stratified draws).

    Returns
    -------
    dict
        ``"block.name"`` -> ndarray, shape (len(records), 3), sensor axes [SI]; nan for
        a run without a recorded seed of the block.
    """
    import warnings

    from cosim.scenario import Scenario, load_scenario
    from cosim.verify.seeds import stratified_draws

    scenario = path if isinstance(path, Scenario) else load_scenario(path)
    blocks = {
        name: TRUTH_OUTPUTS[spec.source]
        for name, spec in scenario.blocks.items()
        if spec.kind == "model" and spec.source in TRUTH_OUTPUTS
    }
    wanted = {b: [(o, k) for o, k in outs if f"{b}.{k}" not in skip] for b, outs in blocks.items()}
    wanted = {b: v for b, v in wanted.items() if v}
    if not wanted or not records:
        return {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        system, _ = scenario.build()
    out: dict[str, FloatArray] = {}
    try:
        start = float(scenario.settings.start)
        for block, outs in wanted.items():
            host = system.blocks[block]
            base = dict(system.parameters.get(block, {}))
            vrs = {o: [host.variables[f"{o}[{i}]"].vr for i in (1, 2, 3)] for o, _ in outs}
            vals = {k: np.full((len(records), 3), math.nan) for _, k in outs}
            for row, rec in enumerate(records):
                if block not in rec.seeds:
                    continue
                params = dict(base, seed=int(rec.seeds[block]))
                if stratified:
                    for b, name, z in stratified_draws(stratified, runs, seed, rec.index):
                        if b != block:
                            continue
                        sigma = float(
                            params.get(f"{name}_sigma", host.variables[f"{name}_sigma"].start)
                        )
                        names = (
                            [name]
                            if name in host.variables
                            else [f"{name}[{i + 1}]" for i in range(len(z))]
                        )
                        for n, zk in zip(names, z, strict=True):
                            params[n] = float(params.get(n, host.variables[n].start)) + sigma * zk
                        params[f"{name}_sigma"] = 0.0
                host.reset()
                host.setup(start, params)
                host.exit_init()
                for o, k in outs:
                    vals[k][row] = host.get_real(vrs[o])
            for _, k in outs:
                out[f"{block}.{k}"] = vals[k]
    finally:
        for host in system.blocks.values():
            host.terminate()
    return out


def regression_table(
    y: FloatArray, regressors: list[Regressor], predicted: list[float | None], unit: str
) -> dict[str, Any]:
    """The regression of ``y`` on the regressors as report data.

    Parameters
    ----------
    y : ndarray, shape (runs,)
        Response per run [``unit``] (nan: run left out).
    regressors : list of Regressor
        The drawn sources.
    predicted : list of float or None
        The linear model's slope for each regressor [``unit`` per regressor unit].
    unit : str
        Unit of the response.

    Returns
    -------
    dict
        ``n``, ``formula``, ``intercept``, ``residual_sigma``, ``r2`` and ``rows`` (one
        per regressor: ``name``, ``unit``, ``slope``, ``se``, ``predicted``, ``z`` =
        (slope - predicted) / se), or ``note`` when no fit is possible.
    """
    ok = np.isfinite(y)
    for r in regressors:
        ok &= np.isfinite(r.values)
    if not regressors:
        return {
            "note": "no drawn parameters: the runs differ only in seeds, and no sensor block "
            "outputs its draw (see [campaign] stratify)"
        }
    if not np.any(ok):
        return {"note": "no regression: no completed run has the metric and every drawn value"}
    X = np.column_stack([r.values[ok] / r.factor for r in regressors])
    try:
        fit = ols(y[ok], X, tuple(r.name for r in regressors), tuple(r.unit for r in regressors))
    except ValueError as exc:
        return {"note": f"no regression: {exc}"}
    rows = []
    for j, r in enumerate(regressors):
        pred = predicted[j]
        se = float(fit.se[j])
        z = (float(fit.slope[j]) - pred) / se if pred is not None and se > 0 else None
        rows.append(
            {
                "name": r.name,
                "unit": f"{unit}/({r.unit})",
                "regressor_unit": r.unit,
                "slope": float(fit.slope[j]),
                "se": se,
                "predicted": pred,
                "z": z,
            }
        )
    return {
        "n": fit.n,
        "response_unit": unit,
        "formula": SE_FORMULA,
        "intercept": fit.intercept,
        "residual_sigma": fit.residual_sigma,
        "r2": fit.r2,
        "rows": rows,
    }


# ------------------------------------------------------------------ report rendering
def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def fmt(x: Any, digits: int = 4) -> str:
    """A number with ``digits`` significant digits, "—" for None or a non-finite one.

    Parameters
    ----------
    x : float or None
        The number.
    digits : int
        Significant digits.

    Returns
    -------
    str
    """
    return (
        "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{digits}g}"
    )


def html_table(header: list[str], rows: list[list[Any]], cls: str) -> str:
    """An HTML table (cells escaped).

    Parameters
    ----------
    header : list of str
        Column titles.
    rows : list of list
        Cells, row by row (any value; shown with ``str``).
    cls : str
        The table's class.

    Returns
    -------
    str
    """
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def regression_html(reg: dict[str, Any]) -> str:
    """The regression table of a budget as HTML.

    Parameters
    ----------
    reg : dict
        ``regression`` of a budget entry.

    Returns
    -------
    str
    """
    if "rows" not in reg:
        what = _e(reg.get("response", ""))
        return f"<p>Regression of the runs ({what}): {_e(reg.get('note', ''))}.</p>"
    rows = [
        [r["name"], r["unit"], fmt(r["slope"]), fmt(r["se"]), fmt(r["predicted"]), fmt(r["z"], 3)]
        for r in reg["rows"]
    ]
    return (
        f"<p>Regression of each run's {_e(reg['response'])} on the parameters the campaign "
        f"drew ({reg['n']} runs; residual 1σ {fmt(reg['residual_sigma'])} "
        f"{_e(reg['response_unit'])}, R² {fmt(reg['r2'], 3)}; {_e(reg['formula'])}). "
        "A slope within about two standard errors of the model's prediction "
        "(|z| < 2) agrees with it.</p>"
        + "".join(
            f"<p>Regressor {_e(k)}: {_e(v)}.</p>" for k, v in reg.get("regressors_from", {}).items()
        )
        + html_table(
            [
                "regressor",
                "unit",
                "slope",
                "standard error",
                "linear model",
                "z = (slope − model) / se",
            ],
            rows,
            "regression",
        )
    )


# ------------------------------------------------------------------ report rendering
def budget_figure(entry: dict[str, Any]) -> str:
    """Bar chart of a requirement's budget: each source's share of the variance.

    Parameters
    ----------
    entry : dict
        One budget (:func:`requirement_budget`) with ``parts``.

    Returns
    -------
    str
        Base64 of the PNG.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parts = sorted(entry["parts"], key=lambda p: p["variance"])
    unit = entry["unit"]
    fig, ax = plt.subplots(figsize=(9.0, 0.9 + 0.32 * len(parts)))
    share = [100.0 * p["share"] for p in parts]
    ax.barh([p["source"] for p in parts], share, color="#0969da")
    for y, (p, v) in enumerate(zip(parts, share, strict=True)):
        ax.text(v + 0.5, y, f"{v:.1f} %  (1σ {p['sigma']:.3g} {unit})", va="center", fontsize=7)
    ax.set_xlim(0.0, max(110.0, max(share) * 1.25))
    ax.set_xlabel("share of the variance [%] (the shares add to 100 %)")
    ax.set_title(
        f"{entry['id']}: error budget {_when(entry)}\n"
        f"total 1σ {entry['total']['sigma']:.3g} {unit}",
        fontsize=9,
    )
    ax.tick_params(axis="y", labelsize=8)
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _when(entry: dict[str, Any]) -> str:
    a, b = entry["window"]
    return f"at {b:g} s" if a == b else f"over [{a:g} s, {b:g} s] (mean variance)"


def budget_html(entry: dict[str, Any] | None) -> str:
    """A requirement's budget section of the HTML report: bar chart and tables.

    Parameters
    ----------
    entry : dict or None
        Its budget (:func:`requirement_budget`), or None.

    Returns
    -------
    str
        A ``<div class="budget">``.
    """
    if entry is None:
        return ""
    out = [f'<div class="budget" data-id="{_e(entry["id"])}"><h3>Error budget</h3>']
    if "parts" not in entry:
        out.append(f'<p class="no-budget">{_e(entry.get("note", NO_MODEL))}.</p>')
    else:
        unit = entry["unit"]
        out.append(
            f"<p>Linear model: {_e(entry['model'])}. Time: {_e(entry['reduction'])}. "
            f"Method: {_e(entry['method'])}. Total 1σ {fmt(entry['total']['sigma'])} {_e(unit)}; "
            f"the parts' sum differs from the total by {fmt(entry['sum_check'], 2)} (relative). "
            "Assumes the sources independent and the filter linear: the budget is the "
            "filter model's prediction; the regression below is the campaign's evidence.</p>"
        )
        out.append(
            f'<figure><img alt="{_e(entry["id"])}: error budget" '
            f'src="data:image/png;base64,{budget_figure(entry)}"></figure>'
        )
        signed = any("signed" in p for p in entry["parts"])
        if "linearity" in entry:
            out.append(
                "<p>First-order check: the error of the run with every source minus the "
                "sum of the signed parts is "
                f"{fmt(entry['linearity'], 2)} of the total 1σ.</p>"
            )
        rows = [
            [p["source"], fmt(p["sigma"]), fmt(p["variance"]), f"{100 * p['share']:.2f} %"]
            + ([fmt(p.get("signed"))] if signed else [])
            for p in sorted(entry["parts"], key=lambda p: -p["variance"])
        ]
        rows.append(
            ["total", fmt(entry["total"]["sigma"]), fmt(entry["total"]["variance"]), "100 %"]
            + ([""] if signed else [])
        )
        out.append(
            html_table(
                ["source", f"1σ part [{unit}]", f"variance [{unit}²]", "share"]
                + ([f"signed error [{unit}]"] if signed else []),
                rows,
                "budget-parts",
            )
        )
    if "regression" in entry:
        out.append(regression_html(entry["regression"]))
    out.append("</div>")
    return "\n".join(out)
