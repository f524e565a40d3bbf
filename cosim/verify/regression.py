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

import html
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.verify.seeds import Stratified, stratified_draws

FloatArray = NDArray[np.float64]

#: The formula stated in reports.
SE_FORMULA = (
    "ordinary least squares with an intercept; se(b_j) = sqrt(s^2 [(X^T X)^-1]_jj), "
    "s^2 = sum of squared residuals / (n - p - 1)"
)


@dataclass(frozen=True)
class Regressor:
    """One regressor: a drawn source's value in every run.

    Attributes
    ----------
    name : str
        What it is (``"gyro drift E"``).
    unit : str
        Display unit of its values (``"deg/h"``).
    factor : float
        SI value of one display unit (``x_display = x_SI / factor``).
    values : ndarray, shape (runs,)
        Its value in each run [SI].
    direction : ndarray, shape (n,) or None
        ``d e_0 / d x``: how one SI unit of it enters the filter's initial estimation
        error (None when no linear model knows it).
    """

    name: str
    unit: str
    factor: float
    values: FloatArray
    direction: FloatArray | None = field(default=None, repr=False)


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
        Fewer than ``p + 2`` runs (no residual degree of freedom), or collinear columns.
    """
    y = np.asarray(y, dtype=float)
    X = np.asarray(X, dtype=float).reshape(y.size, -1)
    n, p = X.shape
    if n < p + 2:
        raise ValueError(f"{n} runs for {p} regressors: at least {p + 2} needed")
    A = np.column_stack([np.ones(n), X])
    xtx = A.T @ A
    if np.linalg.cond(xtx) > 1e12:
        raise ValueError("the regressors are collinear (or one does not vary)")
    inv = np.linalg.inv(xtx)
    beta = inv @ (A.T @ y)
    resid = y - A @ beta
    dof = n - p - 1
    s2 = float(resid @ resid) / dof
    se = np.sqrt(np.clip(np.diag(inv) * s2, 0.0, None))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(resid @ resid) / ss_tot if ss_tot > 0 else math.nan
    return Regression(
        tuple(names), tuple(units), beta[1:], se[1:], float(beta[0]), math.sqrt(s2), r2, n
    )


def drawn_parameters(
    stratified: list[Stratified],
    values: dict[str, dict[str, Any]],
    runs: int,
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
    runs : int
        Runs of the campaign (the design's size).
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
            "note": "no drawn parameters: the campaign draws only seeds (see [campaign] stratify)"
        }
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
