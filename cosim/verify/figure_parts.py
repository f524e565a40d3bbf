"""What the report's requirement figures share: verdict colours, histories, the judged span.

Used by :mod:`cosim.verify.report`, :mod:`cosim.verify.estimate_plots` and
:mod:`cosim.verify.consistency_report`: the verdict's colour and title, the completed
runs' recorded histories, and the judged time span.
"""

from __future__ import annotations

import base64
import io
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from cosim.verify.requirements import (  # noqa: E402
    SATISFIED,
    UNDECIDED,
    VIOLATED,
    Requirement,
    Verdict,
)

#: Verdict -> its colour in the figures and the HTML report.
VERDICT_COLOURS = {SATISFIED: "#1a7f37", VIOLATED: "#cf222e", UNDECIDED: "#9a6700"}


def png_base64(fig: plt.Figure) -> str:
    """A figure as base64 PNG text for an HTML ``img``, and the figure closed.

    No "Software" text chunk is written: the file then holds no URL, not even inside
    the PNG.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure (closed on return).

    Returns
    -------
    str
        The PNG bytes (90 dpi), base64-encoded.
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def verdict_title(fig: plt.Figure, req: Requirement, verdict: Verdict) -> None:
    """Title ``fig`` with the requirement's id and its verdict, in the verdict's colour.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The requirement's figure.
    req : Requirement
        The requirement.
    verdict : Verdict
        Its verdict.
    """
    fig.suptitle(
        f"{req.id} — {verdict.verdict.upper()}",
        color=VERDICT_COLOURS[verdict.verdict],
        weight="bold",
    )


def campaign_histories(campaign: Any, k: int) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """The recorded ``e_k`` and ``s_k`` of the completed runs on the first run's times.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    k : int
        The requirement's position in ``campaign.requirements``.

    Returns
    -------
    t : ndarray, shape (m,), or None
        Times [s] (None when no completed run recorded ``e_k``).
    e : ndarray, shape (n, m)
        Errors [the requirement's SI unit], one row per completed run on those times.
    s : ndarray, shape (n_s, m)
        Sigmas, one row per such run that recorded ``s_k`` (``n_s = 0`` without).
    """
    t = None
    errors, sigmas = [], []
    for rec in campaign.records:
        if rec.failed or f"e_{k}" not in rec.history:
            continue
        if t is None:
            t = rec.history["time"]
        if rec.history["time"].shape != t.shape:
            continue
        errors.append(rec.history[f"e_{k}"])
        if f"s_{k}" in rec.history:
            sigmas.append(rec.history[f"s_{k}"])
    m = 0 if t is None else t.size
    e = np.array(errors) if errors else np.zeros((0, m))
    s = np.array(sigmas) if sigmas else np.zeros((0, m))
    return t, e, s


def judged_window(req: Requirement, t0: float, t1: float) -> tuple[float, float]:
    """The time span a requirement judges, for its window panel.

    Parameters
    ----------
    req : Requirement
        The requirement.
    t0, t1 : float
        The run's start and stop times [s].

    Returns
    -------
    (float, float)
        [s]: ``from``..``until`` of a bound; ``at`` +/- 5 % of the run (at least the
        span shown, clipped to the run) for a value; the settling deadline to the end for
        a settling criterion.
    """
    if req.criterion == "bound":
        return (t0 if req.start is None else req.start), (t1 if req.until is None else req.until)
    if req.criterion == "value":
        at = t1 if req.at is None else req.at
        half = 0.05 * (t1 - t0)
        return max(t0, at - half), min(t1, at + half)
    return min(t1, t0 + req.limit), t1
