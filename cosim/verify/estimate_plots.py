"""The report's figure of a requirement on an estimate against a reference value.

A requirement with ``reference`` (:mod:`cosim.verify.estimates`) is judged on
``e = estimate - reference``, but a run on a real log has no truth, and what a reviewer
needs to see is the **estimate** with the filter's own **+/-3 sigma** band next to the
reference and the allowed band around it, not an error curve. Everything is drawn in the
unit the reference was written in (``"90.60 deg"`` -> deg)::

    estimate(t) = reference + e(t)            (e wrapped: the estimate is drawn around the
                                               reference, never 360 deg away)
    band(t)     = estimate(t) +/- 3 sigma(t)  (the requirement's ``sigma`` column)
    allowed     = reference +/- bound         (over the judged window)

Panels: the estimates over the whole run (runs in grey, the first runs' +/-3 sigma bands
in blue, the reference dashed, the allowed band in red); the same on the judged window;
the filter's 3 sigma against time; the histogram of the per-run metric (the report's).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from cosim.verify.figure_parts import (  # noqa: E402
    campaign_histories,
    judged_window,
    verdict_title,
)
from cosim.verify.requirements import Requirement, Verdict  # noqa: E402

#: Runs drawn as lines, and runs whose +/-3 sigma band is filled.
MAX_LINES = 40
MAX_BANDS = 5


def estimate_histories(
    campaign: Any, req: Requirement
) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """Time, estimates and 3 sigma of the completed runs, in the reference's unit.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign whose requirement ``req`` has a reference.
    req : Requirement
        The requirement.

    Returns
    -------
    t : ndarray, shape (m,), or None
        Times [s] (None when no run completed).
    estimate : ndarray, shape (n, m)
        ``reference + e`` [reference unit].
    three_sigma : ndarray, shape (n, m) or (0, m)
        3 x the ``sigma`` column [reference unit] (none without ``sigma``).
    """
    assert req.reference is not None
    k = campaign.requirements.index(req)
    ref, f = req.reference.value, req.reference.to_unit
    t, e, s = campaign_histories(campaign, k)
    return t, (e + ref) * f, 3.0 * s * f


def _allowed(ax: plt.Axes, req: Requirement, t0: float, t1: float) -> None:
    """The reference (dashed) and reference +/- bound over the judged window (red)."""
    assert req.reference is not None
    r = req.reference
    ref = r.value * r.to_unit
    ax.axhline(ref, color="#1a7f37", ls="--", lw=1.1, label=f"reference {r.text}")
    half = (req.band if req.criterion == "settling" else req.limit) * r.to_unit
    style: dict[str, Any] = {"color": "#cf222e", "lw": 1.6}
    if req.criterion == "value":
        at = t1 if req.at is None else req.at
        ax.vlines(at, ref - half, ref + half, label=f"allowed ±{req.limit:g} {req.unit}", **style)
        ax.plot([at, at], [ref - half, ref + half], "_", ms=14, color=style["color"])
        return
    a, b = judged_window(req, t0, t1)
    ax.hlines([ref - half, ref + half], a, b, label=f"allowed ±{half:.4g} {r.unit}", **style)


def _estimates(ax: plt.Axes, t: np.ndarray, est: np.ndarray, s3: np.ndarray) -> None:
    """Runs in grey, the first runs' +/-3 sigma bands in blue."""
    for i, row in enumerate(est[:MAX_LINES]):
        ax.plot(t, row, lw=0.8, color="#57606a", alpha=0.7, label="estimate" if i == 0 else None)
    for i in range(min(MAX_BANDS, s3.shape[0], est.shape[0])):
        ax.fill_between(
            t,
            est[i] - s3[i],
            est[i] + s3[i],
            color="#0969da",
            alpha=0.18,
            lw=0,
            label="estimate ±3σ (filter)" if i == 0 else None,
        )


def estimate_figure(
    campaign: Any,
    req: Requirement,
    verdict: Verdict,
    histogram: Callable[[plt.Axes, Any, Requirement, Verdict], None],
) -> plt.Figure:
    """The figure of a requirement with a reference value.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : Requirement
        The requirement (``req.reference`` is set).
    verdict : Verdict
        Its verdict.
    histogram : callable
        Draws the per-run metric histogram on an axis (the report's).

    Returns
    -------
    matplotlib.figure.Figure
        Axes labelled ``"estimate"``, ``"window"``, ``"sigma"``, ``"histogram"``.
    """
    assert req.reference is not None
    unit = req.reference.unit
    t, est, s3 = estimate_histories(campaign, req)
    master = campaign.provenance["master"]
    t0, t1 = master["start"], master["stop"]
    fig = plt.figure(figsize=(10.5, 10.0))
    grid = fig.add_gridspec(3, 2)
    ax1 = fig.add_subplot(grid[0, :], label="estimate")
    axw = fig.add_subplot(grid[1, :], label="window")
    ax2 = fig.add_subplot(grid[2, 0], sharex=ax1, label="sigma")
    ax3 = fig.add_subplot(grid[2, 1], label="histogram")
    verdict_title(fig, req, verdict)
    a, b = judged_window(req, t0, t1)
    if t is not None and est.shape[0]:
        _estimates(ax1, t, est, s3)
        inside = (t >= a) & (t <= b)
        if inside.sum() < 2:
            inside[max(0, np.searchsorted(t, a) - 1) : np.searchsorted(t, b) + 1] = True
        _estimates(axw, t[inside], est[:, inside], s3[:, inside])
        ref = req.reference.value * req.reference.to_unit
        half = (req.band if req.criterion == "settling" else req.limit) * req.reference.to_unit
        parts = [est[:, inside].ravel(), [ref - half, ref + half]]
        if s3.shape[0]:
            parts += [(est[: s3.shape[0], inside] + s3[:, inside]).ravel()]
            parts += [(est[: s3.shape[0], inside] - s3[:, inside]).ravel()]
            for i, row in enumerate(s3[:MAX_LINES]):
                ax2.plot(t, row, lw=0.8, color="#0969da", label="filter 3σ" if i == 0 else None)
        values = np.concatenate([np.ravel(p) for p in parts])
        values = values[np.isfinite(values)]
        lo, hi = float(values.min()), float(values.max())
        pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.1
        span = t[inside][-1] - t[inside][0]
        axw.set_xlim(t[inside][0] - 0.02 * span, t[inside][-1] + 0.02 * span)
        axw.set_ylim(lo - pad, hi + pad)
    for ax in (ax1, axw):
        ylim = ax.get_ylim() if ax is axw else None
        _allowed(ax, req, t0, t1)
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.set_ylabel(f"{req.signal} [{unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    ax1.set_title(
        f"estimate vs time (no truth: e = estimate − reference {req.reference.text})", fontsize=9
    )
    axw.set_title(f"judged window {a:g} – {b:g} s", fontsize=9)
    axw.set_xlabel("time [s]")
    ax2.set_title("filter 3σ of the estimate", fontsize=9)
    ax2.set_ylabel(f"3σ [{unit}]")
    ax2.set_xlabel("time [s]")
    ax2.grid(True, alpha=0.3)
    if s3.shape[0]:
        ax2.set_yscale("log")
        ax2.legend(loc="upper right", fontsize=7)
    histogram(ax3, campaign, req, verdict)
    fig.tight_layout()
    return fig
