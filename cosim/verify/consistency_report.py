"""The report's pieces for a ``criterion = "consistent"`` requirement: figure and run list.

The figure shows the statistic over time (each run's recorded NIS or NEES divided by its
dof, their mean over the runs, and the one-sample 95 % chi-square band for reference), and
the flagged windows per run against what the false-alarm rate explains. The HTML list
names every flagged run with the spans where its filter is off (docs/consistency.md).
"""

from __future__ import annotations

import html
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

from cosim.verify.calibration import calibration_lines, sigma_calibration  # noqa: E402
from cosim.verify.consistency import (  # noqa: E402
    DEFAULT_FALSE_ALARM,
    ConsistencyRequirement,
)
from cosim.verify.figure_parts import campaign_histories, png_base64, verdict_title  # noqa: E402
from cosim.verify.requirements import Requirement, Verdict  # noqa: E402

_MAX_LINES = 40
_MAX_LISTED = 20


def build_consistency_figure(campaign: Any, req: Requirement, verdict: Verdict) -> plt.Figure:
    """The figure of a consistency requirement.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : ConsistencyRequirement
        The requirement.
    verdict : Verdict
        Its verdict.

    Returns
    -------
    matplotlib.figure.Figure
        Axes labelled ``"statistic"`` and ``"flags"``.
    """
    assert isinstance(req, ConsistencyRequirement)
    k = campaign.requirements.index(req)
    t, e, _ = campaign_histories(campaign, k)
    fig = plt.figure(figsize=(10.5, 6.5))
    grid = fig.add_gridspec(2, 2, height_ratios=[1.2, 1.0])
    ax1 = fig.add_subplot(grid[0, :], label="statistic")
    ax2 = fig.add_subplot(grid[1, 0], label="flags")
    verdict_title(fig, req, verdict)
    dof = req.dof or 1.0
    what = f"{req.kind.upper()} / dof" if req.dof else f"{req.kind.upper()}"
    if t is not None and e.shape[0]:
        for i, row in enumerate(e[:_MAX_LINES]):
            ax1.plot(t, row / dof, lw=0.6, alpha=0.45, color="#57606a",
                     label="runs (held between updates)" if i == 0 else None)  # fmt: skip
        ax1.plot(t, e.mean(axis=0) / dof, "k", lw=1.2, label="mean over runs")
    if req.dof:
        d = int(req.dof)
        lo, hi = stats.chi2.ppf([0.025, 0.975], d) / d
        ax1.axhspan(lo, hi, color="#0969da", alpha=0.12, label="one sample's 95 % band")
        ax1.axhline(1.0, color="#0969da", lw=1.0)
    if req.start is not None:
        ax1.axvline(req.start, color="#cf222e", ls=":", lw=1.0)
    if req.until is not None:
        ax1.axvline(req.until, color="#cf222e", ls=":", lw=1.0)
    ax1.set_yscale("log")
    ax1.set_ylabel(what)
    ax1.set_xlabel("time [s]")
    ax1.set_title(
        "statistic vs time (the verdict judges window means against their own, narrower, band)",
        fontsize=9,
    )
    ax1.grid(True, alpha=0.3)
    ax1.legend(loc="upper right", fontsize=7)
    values = campaign.metric_values(req)
    values = values[np.isfinite(values)]
    n = values.size
    flagged = int(np.sum(values > 0))
    ax2.bar(["flagged runs", "expected if consistent"], [flagged, req.false_alarm * n],
            color=["#cf222e", "#8c959f"])  # fmt: skip
    ax2.set_title(f"{flagged} of {n} runs flagged ({100 * req.false_alarm:g} % false alarm)",
                  fontsize=9)  # fmt: skip
    ax2.set_ylabel("runs")
    ax2.grid(True, alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def consistency_figure(campaign: Any, req: Requirement, verdict: Verdict) -> str:
    """:func:`build_consistency_figure` as base64 PNG.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : ConsistencyRequirement
        The requirement.
    verdict : Verdict
        Its verdict.

    Returns
    -------
    str
    """
    return png_base64(build_consistency_figure(campaign, req, verdict))


def consistency_html(campaign: Any, req: Requirement) -> str:
    """The flagged runs of a consistency requirement as an HTML list ("" for others).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : Requirement
        Any requirement.

    Returns
    -------
    str
    """
    if not isinstance(req, ConsistencyRequirement):
        return ""
    rows = []
    for rec in campaign.records:
        m = rec.metrics.get(req.id)
        if m is not None and m.passed is False:
            rows.append(f"<li>run {rec.index}: {html.escape(m.note)}</li>")
    if not rows:
        return f'<p class="consistency" data-id="{html.escape(req.id)}">No run flagged.</p>'
    more = len(rows) - _MAX_LISTED
    tail = f"<li>... and {more} more</li>" if more > 0 else ""
    return (
        f'<p class="consistency" data-id="{html.escape(req.id)}">{len(rows)} run(s) flagged '
        f"(what to do: docs/consistency.md):</p><ul>{''.join(rows[:_MAX_LISTED])}{tail}</ul>"
    )


# ------------------------------------------------------------------ automatic check
EVIDENCE = 0.01
"""A filter is called inconsistent over a campaign when its flagged runs are more than
the false-alarm rate explains at this significance (binomial tail)."""


def consistency_section(campaign: Any) -> dict[str, Any]:
    """The automatic consistency check over a campaign's runs, per NIS/NEES output.

    Each completed run was judged at :data:`~cosim.verify.consistency.DEFAULT_FALSE_ALARM`
    per run (all its signals together), so a consistent filter's output is flagged in a
    number of runs no larger than Binomial(n, 0.01); ``p_value`` is that tail at the
    observed count, and below :data:`EVIDENCE` the filter is called inconsistent. A
    campaign of one run (a recorded log) is judged as that run: a flag is the verdict,
    ``"inconsistent"`` with the run's window and factor, since no count of runs can
    explain it away.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.

    Returns
    -------
    dict
        ``false_alarm_per_run`` and ``signals``: column -> ``runs`` (judged),
        ``flagged``, ``p_value``, ``verdict`` (``"inconsistent"``, ``"no evidence"`` or
        ``"not judged"``), ``text`` (one sentence) and ``examples`` (run, message);
        ``calibration``: :func:`cosim.verify.calibration.sigma_calibration` (the
        requirements' error / sigma across the runs).
    """
    per: dict[str, dict[str, Any]] = {}
    for rec in campaign.records:
        for column, c in (getattr(rec, "consistency", None) or {}).items():
            entry = per.setdefault(column, {"runs": 0, "flagged": 0, "examples": [], "why": ""})
            if c["consistent"] is None:
                entry["why"] = c["message"]
                continue
            entry["runs"] += 1
            if c["consistent"] is False:
                entry["flagged"] += 1
                if len(entry["examples"]) < 5:
                    entry["examples"].append([rec.index, c["message"]])
    a = DEFAULT_FALSE_ALARM
    for e in per.values():
        n, f = e["runs"], e["flagged"]
        if n == 0:
            e.update(p_value=None, verdict="not judged", text=e["why"] or "not judged")
            continue
        p = float(stats.binom.sf(f - 1, n, a)) if f else 1.0
        e["p_value"] = p
        if f and n == 1:  # one run is judged as one run: its flag is the verdict
            e["verdict"] = "inconsistent"
            run, message = e["examples"][0]
            e["text"] = (
                f"INCONSISTENT in its one run (run {run}): "
                + message.split(": INCONSISTENT: ", 1)[-1]
                + f" (a consistent filter is flagged in {100 * a:g} % of runs)"
            )
        elif p < EVIDENCE:
            e["verdict"] = "inconsistent"
            e["text"] = (
                f"INCONSISTENT: flagged in {f} of {n} runs, more than the {100 * a:g} % "
                f"false-alarm rate explains (p = {p:.2g}); e.g. run {e['examples'][0][0]}: "
                + e["examples"][0][1].split(": INCONSISTENT: ", 1)[-1]
            )
        else:
            e["verdict"] = "no evidence"
            e["text"] = (
                f"no evidence of inconsistency: flagged in {f} of {n} runs"
                + (f" (p = {p:.2g})" if f else "")
                + f", within what the {100 * a:g} % false-alarm rate explains"
            )
    for e in per.values():
        e.pop("why", None)
    return {"false_alarm_per_run": a, "signals": per, "calibration": sigma_calibration(campaign)}


def consistency_lines(section: dict[str, Any]) -> list[str]:
    """The lines ``ins-cosim verify`` prints for :func:`consistency_section`.

    Parameters
    ----------
    section : dict
        From :func:`consistency_section`.

    Returns
    -------
    list of str
        Empty when no NIS/NEES output is recorded.
    """
    lines = calibration_lines(section.get("calibration", []))
    if not section["signals"]:
        return lines
    return (
        ["filter consistency (docs/consistency.md):"]
        + [f"  {column}: {e['text']}" for column, e in section["signals"].items()]
        + lines
    )


def consistency_overview_html(section: dict[str, Any]) -> str:
    """The report's "Filter consistency" section for :func:`consistency_section`.

    Parameters
    ----------
    section : dict
        From :func:`consistency_section`.

    Returns
    -------
    str
        HTML ("" when no NIS/NEES output is recorded).
    """
    if not section["signals"]:
        return ""
    rows = []
    for column, e in section["signals"].items():
        examples = "; ".join(f"run {i}: {m}" for i, m in e["examples"])
        rows.append(
            f'<tr class="consistency-row" data-column="{html.escape(column)}" '
            f'data-verdict="{html.escape(e["verdict"])}"><td><code>{html.escape(column)}</code>'
            f"</td><td>{e['runs']}</td><td>{e['flagged']}</td>"
            f"<td>{html.escape(e['text'])}</td><td>{html.escape(examples)}</td></tr>"
        )
    a = section["false_alarm_per_run"]
    return (
        '<h2 id="consistency">Filter consistency</h2>'
        f"<p>Every run's NIS and NEES outputs judged over windows against their chi-square "
        f"bands at {100 * a:g} % false alarm per run (docs/consistency.md). A filter flagged "
        f"in more runs than that rate explains has a wrong sigma: retune R, Q or P0, or "
        f"model what the filter misses.</p>"
        '<table class="consistency"><thead><tr><th>output</th><th>runs judged</th>'
        "<th>runs flagged</th><th>verdict</th><th>where (first runs)</th></tr></thead>"
        f"<tbody>{''.join(rows)}</tbody></table>"
    )
