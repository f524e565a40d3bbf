"""Sigma calibration over a campaign: each stated sigma against the spread of its error.

A requirement that names the filter's 1-sigma of its error (``sigma = "align.rpy_sigma[3]"``)
can be judged for more than its bound: over ``n`` independent runs, at each recorded
instant ``t_i``, the normalised squared error averaged across the runs,

    ``A_i = (1 / n) sum_r (e_r(t_i) / s_r(t_i))^2``,

estimates ``k^2``, the ratio of the actual error variance to the one the filter states.
If the filter is consistent (its error is Gaussian with the variance it states) each
``(e / s)^2`` is chi-square with 1 degree of freedom and, runs being independent,
``n A_i`` is chi-square with ``n`` degrees of freedom. Successive instants of one run are
strongly correlated (a heading error drifts slowly), so the window means of ``A_i`` are
judged with the band that holds for any dependence in time
(:func:`cosim.estimation.consistency.any_dependence_band` with ``n`` degrees of freedom:
the window mean is smaller than ``chi2(n) / n`` in the convex order), each of the windows
at ``false_alarm / windows`` (Bonferroni), so a consistent filter is flagged in at most
``false_alarm`` of campaigns.

This is the sharp test a single run cannot give: over 50 runs a window shows a sigma about
1.4 times too small (the band's upper end 1.87 at 0.1 %), where one run's NEES shows only
gross errors (2.6 times). It needs the truth (the error ``e``), so it runs on simulation
campaigns and on logs with a stated reference. docs/consistency.md, "Over a campaign".
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cosim.estimation.consistency import (
    inconsistent_spans,
    window_edges,
    window_test,
)
from cosim.verify.figure_parts import campaign_histories

__all__ = ["CALIBRATION_FALSE_ALARM", "calibration_lines", "sigma_calibration"]

CALIBRATION_FALSE_ALARM = 0.01
"""Probability that a consistent filter's requirement is flagged in one campaign."""
WINDOWS = 10
"""The judged span is cut into this many equal windows."""
MIN_RUNS = 2
"""Fewer completed runs are not judged (one run is the NEES's business)."""


def normalised_sum(t: np.ndarray, e: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``n A_i``, the sum over the ``n`` runs of ``(e / s)^2``, at the instants it is judged.

    Parameters
    ----------
    t : ndarray, shape (m,)
        Common sample times of the runs [s].
    e, s : ndarray, shape (n, m)
        Errors and the filter's 1-sigma of them, same unit.

    Returns
    -------
    times : ndarray, shape (k,)
        The instants where every run's sigma is positive and finite and its error finite.
    total : ndarray, shape (k,)
        ``n A_i`` there (dimensionless; chi-square with ``n`` dof if consistent).
    """
    ok = np.all(np.isfinite(s) & (s > 0.0) & np.isfinite(e), axis=0)
    return t[ok], ((e[:, ok] / s[:, ok]) ** 2).sum(axis=0)


def calibrate(
    t: np.ndarray,
    e: np.ndarray,
    s: np.ndarray,
    *,
    false_alarm: float = CALIBRATION_FALSE_ALARM,
    windows: int = WINDOWS,
) -> dict[str, Any]:
    """Judge ``e / s`` of independent runs against the unit variance, window by window.

    Parameters
    ----------
    t : ndarray, shape (m,)
        Common sample times of the runs [s].
    e : ndarray, shape (n, m)
        Errors of ``n`` runs (any unit).
    s : ndarray, shape (n, m)
        The filter's 1-sigma of those errors, same unit; instants where any run's sigma
        is not positive and finite (before the first update) are not judged.
    false_alarm : float
        Probability of flagging a consistent filter (whole span).
    windows : int
        Number of equal windows of the judged span.

    Returns
    -------
    dict
        ``runs``, ``samples``, ``t_start``, ``t_end``, ``false_alarm``,
        ``windows`` (:meth:`ConsistencyWindow.to_dict` each: ``mean`` is the window mean of
        ``A_i``), ``spans`` (merged flagged windows: ``t_start``, ``t_end``, ``sigma``
        "too small"/"too large", ``factor``, ``mean``), ``peak`` (the largest
        ``A_i`` and its time), ``consistent`` (bool, or None when not judged) and
        ``message``.
    """
    t = np.asarray(t, dtype=float)
    e = np.atleast_2d(np.asarray(e, dtype=float))
    s = np.atleast_2d(np.asarray(s, dtype=float))
    n = e.shape[0]
    out: dict[str, Any] = {"runs": n, "false_alarm": false_alarm, "windows": [], "spans": []}
    if n < MIN_RUNS or s.shape != e.shape:
        why = f"{n} run(s) with a recorded sigma" if s.shape == e.shape else "no sigma recorded"
        out.update(consistent=None, samples=0, message=f"not judged: {why}")
        return out
    ts, total = normalised_sum(t, e, s)
    if ts.size == 0:
        out.update(consistent=None, samples=0, message="not judged: no instant with a sigma")
        return out
    edges = window_edges(float(ts[0]), float(ts[-1]), None, windows)
    found = window_test(ts, total, n, edges, false_alarm / (edges.size - 1), white=False)
    spans = inconsistent_spans(found)
    peak = int(np.argmax(total))
    out.update(
        samples=int(ts.size),
        t_start=float(ts[0]),
        t_end=float(ts[-1]),
        windows=[w.to_dict() for w in found],
        spans=[
            {
                "t_start": sp.t_start,
                "t_end": sp.t_end,
                "sigma": f"too {sp.flag}",
                "factor": sp.factor,
                "mean": sp.mean,
            }
            for sp in spans
        ],
        peak={"time": float(ts[peak]), "mean": float(total[peak] / n)},
        consistent=not spans,
    )
    if spans:
        out["message"] = "INCONSISTENT: " + "; ".join(sp.message() for sp in spans)
    else:
        lo, hi = (found[0].lower, found[0].upper) if found else (np.nan, np.nan)
        out["message"] = f"consistent: every window's mean (e/sigma)^2 within [{lo:.2f}, {hi:.2f}]"
    return out


def sigma_calibration(campaign: Any) -> list[dict[str, Any]]:
    """:func:`calibrate` for every requirement of a campaign that names a sigma.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign (its runs' histories of ``e_k`` and ``s_k``).

    Returns
    -------
    list of dict
        Per requirement with a ``sigma``: ``id``, ``signal``, ``sigma`` (the columns) and
        the keys of :func:`calibrate`, its ``message`` prefixed by the runs judged.
    """
    out = []
    for k, req in enumerate(campaign.requirements):
        if getattr(req, "sigma", None) is None:
            continue
        t, e, s = campaign_histories(campaign, k)
        if t is None:
            res: dict[str, Any] = {"runs": 0, "consistent": None, "windows": [], "spans": []}
            res["message"] = "not judged: no completed run"
        else:
            res = calibrate(t, e, s)
        if res["consistent"] is not None:
            res["message"] = f"over {res['runs']} runs, {res['message']}"
        out.append({"id": req.id, "signal": req.signal, "sigma": req.sigma, **res})
    return out


def calibration_lines(entries: list[dict[str, Any]]) -> list[str]:
    """The lines ``ins-cosim verify`` prints for :func:`sigma_calibration`.

    Parameters
    ----------
    entries : list of dict
        From :func:`sigma_calibration`.

    Returns
    -------
    list of str
        Empty when no requirement names a sigma.
    """
    if not entries:
        return []
    rate = f"{100 * CALIBRATION_FALSE_ALARM:g} % false alarm"
    return [
        f"sigma calibration over the campaign, error / stated sigma ({rate}; docs/consistency.md):"
    ] + [f"  {c['id']} ({c['sigma']}): {c['message']}" for c in entries]


def calibration_figure(campaign: Any, k: int, entry: dict[str, Any]) -> str:
    """Mean ``(e / sigma)^2`` across the runs over time, with its band: base64 PNG.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    k : int
        The requirement's position in ``campaign.requirements``.
    entry : dict
        Its item of :func:`sigma_calibration` (judged: ``consistent`` not None).

    Returns
    -------
    str
        The figure as base64 PNG text (:func:`~cosim.verify.figure_parts.png_base64`).
    """
    import matplotlib.pyplot as plt

    from cosim.verify.figure_parts import png_base64

    t, e, s = campaign_histories(campaign, k)
    assert t is not None
    times, total = normalised_sum(t, e, s)
    a_i = total / e.shape[0]
    fig, ax = plt.subplots(figsize=(9.0, 3.2), layout="constrained")
    ax.semilogy(times, a_i, "k", lw=1.0, label=f"mean over {entry['runs']} runs")
    for w in entry["windows"]:
        colour = "#cf222e" if w["flag"] else "#1a7f37"
        ax.plot([w["t_start"], w["t_end"]], [w["mean"]] * 2, color=colour, lw=3, alpha=0.8)
        ax.fill_between(
            [w["t_start"], w["t_end"]], w["lower"], w["upper"], color="#1a7f37", alpha=0.12
        )
    ax.axhline(1.0, color="0.4", lw=0.8, ls="--")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("(error / stated sigma)$^2$")
    ax.set_title(
        f"{entry['id']}: window means (bars; red = flagged) against the band of a "
        "consistent filter (green)",
        fontsize=9,
    )
    ax.legend(loc="upper right", fontsize=8)
    return png_base64(fig)


def calibration_html(campaign: Any, k: int, entry: dict[str, Any]) -> str:
    """The requirement section's paragraph (and figure) for its sigma calibration.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    k : int
        The requirement's position in ``campaign.requirements``.
    entry : dict
        Its item of :func:`sigma_calibration`.

    Returns
    -------
    str
        HTML.
    """
    from html import escape

    verdict = {True: "consistent", False: "inconsistent", None: "not judged"}
    state = verdict[entry["consistent"]]
    head = (
        f'<p class="calibration" data-id="{escape(entry["id"])}" data-verdict="{state}">'
        f"Sigma calibration (is <code>{escape(entry['sigma'])}</code> the spread of the "
        f"error? mean (error / sigma)<sup>2</sup> across the runs, judged in windows at "
        f"{100 * CALIBRATION_FALSE_ALARM:g} % false alarm; docs/consistency.md): "
        f"{escape(entry['message'])}.</p>"
    )
    if entry["consistent"] is None:
        return head
    img = calibration_figure(campaign, k, entry)
    return (
        head + f'<figure><img alt="{escape(entry["id"])}: sigma calibration over time" '
        f'src="data:image/png;base64,{img}"></figure>'
    )
