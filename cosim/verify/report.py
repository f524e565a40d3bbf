"""Verification reports of a campaign: one self-contained HTML file, JUnit XML and JSON.

Each report carries the same traceability: scenario file and sha256, every block's
source, FMU GUID and sha256, the campaign seed, the seed rule and every run's seeds,
and the software versions.

- ``report.html``: verdict table, then per requirement one figure (error vs time with the
  ensemble and filter +/-3 sigma and the requirement's bounds; Monte Carlo envelope;
  histogram of the per-run metric), then the runs and the traceability. Plots are PNGs
  embedded as base64 ``data:`` URIs; no script, style sheet or link leaves the file.
- ``junit.xml``: one ``<testcase>`` per requirement. Violated -> ``<failure>`` whose
  message holds the measured value and the bound; undecided -> ``<skipped>`` with the
  reason (the exit code, 2, still flags it); provenance as suite ``<properties>``.
- ``report.json``: everything above as data, for tools.
"""

from __future__ import annotations

import html
import io
import json
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from cosim.verify.budget import budget_html, budget_section  # noqa: E402
from cosim.verify.calibration import calibration_html  # noqa: E402
from cosim.verify.campaign import Campaign  # noqa: E402
from cosim.verify.consistency_report import (  # noqa: E402
    consistency_figure,
    consistency_html,
    consistency_overview_html,
    consistency_section,
)
from cosim.verify.estimate_plots import estimate_figure  # noqa: E402
from cosim.verify.figure_parts import (  # noqa: E402  (judged_window: report API)
    VERDICT_COLOURS,
    campaign_histories,
    judged_window,
    png_base64,
    verdict_title,
)
from cosim.verify.records import write_atomic  # noqa: E402
from cosim.verify.requirements import (  # noqa: E402
    SATISFIED,
    UNDECIDED,
    VIOLATED,
    Requirement,
    Verdict,
)

REPORT_SCHEMA = "ins-cosim-verification-report/1"
_COLOURS = VERDICT_COLOURS
_MAX_LINES = 40  # individual runs drawn in the error-vs-time panel


def write_reports(campaign: Campaign, out_dir: str | Path | None = None) -> dict[str, Path]:
    """Write ``report.html``, ``junit.xml`` and ``report.json``.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    out_dir : str or Path, optional
        Folder (default: the campaign's report folder).

    Returns
    -------
    dict
        ``{"html": Path, "junit": Path, "json": Path}``.
    """
    out = Path(out_dir) if out_dir is not None else campaign.out_dir
    out.mkdir(parents=True, exist_ok=True)
    created = datetime.now(UTC).isoformat(timespec="seconds")
    data = report_data(campaign, created)
    js = out / "report.json"
    write_atomic(js, json.dumps(data, indent=2, default=_jsonable) + "\n")
    junit = write_junit(campaign, out / "junit.xml", created)
    page = write_html(campaign, out / "report.html", data)
    return {"html": page, "junit": junit, "json": js}


# ----------------------------------------------------------------------------- JSON
def report_data(campaign: Campaign, created: str) -> dict[str, Any]:
    """The JSON report as a dict (also the data behind the HTML tables).

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    created : str
        ISO 8601 time stamp.

    Returns
    -------
    dict
        ``schema``, ``created``, ``scenario``, ``campaign``, ``summary``,
        ``requirements`` (spec + verdict), ``budgets`` (requirement id -> error budget,
        :func:`cosim.verify.budget.budget_section`), ``runs``, ``provenance``.
    """
    counts = {k: 0 for k in (SATISFIED, VIOLATED, UNDECIDED)}
    for v in campaign.verdicts:
        counts[v.verdict] += 1
    n_failed = len(campaign.failed_runs)
    return {
        "schema": REPORT_SCHEMA,
        "created": created,
        "scenario": campaign.scenario,
        "campaign": {
            "runs": campaign.settings.runs,
            "seed": campaign.settings.seed,
            "completed": len(campaign.records) - n_failed,
            "failed": n_failed,
            **campaign.execution,
        },
        "summary": {**counts, "exit_code": campaign.exit_code},
        "requirements": [
            {**r.to_dict(), "result": v.to_dict()}
            for r, v in zip(campaign.requirements, campaign.verdicts, strict=True)
        ],
        "budgets": budget_section(campaign),
        "consistency": consistency_section(campaign),
        "runs": [r.to_dict() for r in campaign.records],
        "provenance": campaign.provenance,
    }


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


# ---------------------------------------------------------------------------- JUnit
def measured_text(v: Verdict) -> str:
    """The report's "measured" cell of a verdict: its statistic with the unit.

    Parameters
    ----------
    v : Verdict
        A campaign verdict.

    Returns
    -------
    str
        A quantile statistic (``p95``) gives the sample quantile and the confidence
        bound the verdict judged as two labelled numbers.
    """
    if isinstance(v.value, float) and math.isnan(v.value):
        return "none"
    if v.statistic == "pass_rate":
        return f"pass rate {100 * v.value:.4g} % ({v.n_pass}/{v.n_used} runs)"
    if v.statistic == "quantile":  # the sample quantile and the bound the verdict used
        return _quantile_measured(v)
    if v.unit == "1":
        return f"{v.value:.4g}"
    if math.isinf(v.value):
        return "not settled" if v.unit == "s" else str(v.value)
    return f"{v.value:.6g} {v.unit}"


def _quantile_measured(v: Verdict) -> str:
    """``"sample p95 540.1 arcmin; 95 % upper bound 576.8 arcmin"`` (the bound judged)."""
    name = v.details.get("statistic_text") or "quantile"
    sample = v.details.get("sample_quantile", math.nan)
    side = "lower" if v.verdict == "violated" else "upper"
    conf = f"{100 * float(v.details.get('confidence', math.nan)):g} %"
    head = "sample " + name + " " + ("none" if math.isnan(sample) else f"{sample:.6g} {v.unit}")
    if math.isinf(v.value):
        return f"{head}; no {conf} {side} bound (too few runs)"
    return f"{head}; {conf} {side} bound {v.value:.6g} {v.unit}"


def _bound(v: Verdict) -> str:
    if v.statistic == "pass_rate":
        return f"pass rate >= {100 * v.limit:.4g} %"
    return f"{v.limit:.4g}" if v.unit == "1" else f"{v.limit:.6g} {v.unit}"


def write_junit(campaign: Campaign, path: Path, created: str = "") -> Path:
    """Write the JUnit XML report: one test case per requirement.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    path : Path
        The XML file.
    created : str
        ISO 8601 time stamp.

    Returns
    -------
    Path
    """
    name = campaign.scenario["name"]
    verdicts = campaign.verdicts
    wall = sum(r.wall_time for r in campaign.records)
    suites = ET.Element("testsuites", name="ins-cosim verify")
    suite = ET.SubElement(
        suites,
        "testsuite",
        name=f"ins-cosim verify {name}",
        tests=str(len(verdicts)),
        failures=str(sum(v.verdict == VIOLATED for v in verdicts)),
        errors="0",
        skipped=str(sum(v.verdict == UNDECIDED for v in verdicts)),
        time=f"{wall:.3f}",
        timestamp=created,
    )
    props = ET.SubElement(suite, "properties")
    for key, value in _trace_items(campaign):
        ET.SubElement(props, "property", name=key, value=str(value))
    for req, v in zip(campaign.requirements, verdicts, strict=True):
        case = ET.SubElement(suite, "testcase", classname=name, name=req.id, time="0")
        detail = (
            f"requirement: {req.text}\n"
            f"signal: {req.signal}" + (f" - {req.minus}" if req.minus else "") + "\n"
            f"criterion (per run): {req.describe()}\n"
            f"statistic: {req.describe_statistic()}\n"
            f"measured: {measured_text(v)}\n"
            f"bound: {_bound(v)}\n"
            f"runs: {v.n_runs} ({v.n_failed} failed, {v.n_used} used, {v.n_pass} met the bound)\n"
            f"verdict: {v.verdict}: {v.reason}\n"
            f"claim: {v.claim}\n"
        )
        if v.verdict == VIOLATED:
            failure = ET.SubElement(
                case,
                "failure",
                message=f"measured {measured_text(v)}, bound {_bound(v)}: {v.reason}. {v.claim}",
                type="violated",
            )
            failure.text = detail
        elif v.verdict == UNDECIDED:
            ET.SubElement(case, "skipped", message=f"undecided: {v.reason}. Shown: {v.claim}")
        ET.SubElement(case, "system-out").text = detail
    ET.indent(suites)
    path = Path(path)
    buffer = io.BytesIO()
    ET.ElementTree(suites).write(buffer, encoding="utf-8", xml_declaration=True)
    write_atomic(path, buffer.getvalue())
    return path


def _trace_items(campaign: Campaign) -> list[tuple[str, Any]]:
    prov = campaign.provenance
    items: list[tuple[str, Any]] = [
        ("scenario.file", campaign.scenario["file"]),
        ("scenario.sha256", campaign.scenario["sha256"]),
        ("campaign.runs", campaign.settings.runs),
        ("campaign.seed", campaign.settings.seed),
        ("campaign.seed_rule", prov["seed_rule"]),
        ("campaign.randomized_blocks", ",".join(prov["randomized_blocks"])),
    ]
    for b, info in prov["blocks"].items():
        items += [
            (f"block.{b}.kind", info["kind"]),
            (f"block.{b}.source", info["source"]),
            (f"block.{b}.guid", info["guid"]),
            (f"block.{b}.sha256", info["sha256"]),
        ]
    items += [(f"software.{k}", v) for k, v in prov["software"].items()]
    items += [(f"run.{r.index}.seeds", _seeds(r.seeds)) for r in campaign.records]
    return items


# ----------------------------------------------------------------------------- plots
def window_curves(
    t: np.ndarray, e: np.ndarray, s: np.ndarray, window: tuple[float, float]
) -> dict[str, np.ndarray]:
    """The curves of the window panel, restricted to the window.

    Parameters
    ----------
    t : ndarray, shape (m,)
        Times [s].
    e : ndarray, shape (n, m)
        Errors of the completed runs [req.unit].
    s : ndarray, shape (n, m) or (0, m)
        Filter 1-sigma of the runs [req.unit].
    window : (float, float)
        From :func:`judged_window` [s].

    Returns
    -------
    dict
        ``time`` (k,), ``runs`` (n, k), and when available ``ensemble_lo``/``ensemble_hi``
        (mean -/+ 3 std over the runs, (k,)) and ``filter_3sigma`` (3 x RMS over the runs
        of the filter sigma, (k,)); at least the samples next to the window's ends.
    """
    a, b = window
    inside = (t >= a) & (t <= b)
    if inside.sum() < 2:  # a window shorter than the history's spacing: the nearest samples
        inside = np.zeros_like(inside)
        inside[max(0, np.searchsorted(t, a) - 1) : np.searchsorted(t, b) + 1] = True
    out = {"time": t[inside], "runs": e[:, inside]}
    if e.shape[0] >= 2:
        mean, std = e[:, inside].mean(axis=0), e[:, inside].std(axis=0, ddof=1)
        out["ensemble_lo"], out["ensemble_hi"] = mean - 3 * std, mean + 3 * std
    if s.shape[0]:
        out["filter_3sigma"] = 3 * np.sqrt(np.mean(s[:, inside] ** 2, axis=0))
    return out


def window_ylim(req: Requirement, curves: dict[str, np.ndarray]) -> tuple[float, float]:
    """y-range of the window panel: the window's data and the bound, 8 % margin.

    Parameters
    ----------
    req : Requirement
        The requirement (its bound, or band for settling).
    curves : dict
        From :func:`window_curves`.

    Returns
    -------
    (float, float)
        [req.unit].
    """
    bound = req.band if req.criterion == "settling" else req.limit
    parts = [np.array([bound, -bound if (req.absolute or req.criterion == "settling") else 0.0])]
    parts += [np.ravel(curves[k]) for k in ("runs", "ensemble_lo", "ensemble_hi") if k in curves]
    if "filter_3sigma" in curves:
        parts += [curves["filter_3sigma"], -curves["filter_3sigma"]]
    values = np.concatenate(parts)
    values = values[np.isfinite(values)]
    lo, hi = float(values.min()), float(values.max())
    pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.1
    return lo - pad, hi + pad


def _draw_limits(ax: plt.Axes, req: Requirement, t0: float, t1: float) -> None:
    style: dict[str, Any] = {"color": "#cf222e", "lw": 1.6}
    if req.criterion == "bound":
        a = t0 if req.start is None else req.start
        b = t1 if req.until is None else req.until
        ax.hlines(req.limit, a, b, label=f"bound {req.limit:g} {req.unit}", **style)
        if req.absolute:
            ax.hlines(-req.limit, a, b, **style)
    elif req.criterion == "value":
        at = t1 if req.at is None else req.at
        lo = -req.limit if req.absolute else ax.get_ylim()[0]
        ax.vlines(at, lo, req.limit, label=f"|e| <= {req.limit:g} {req.unit} at {at:g} s", **style)
        ax.plot([at, at], [lo, req.limit], "_", ms=14, color=style["color"])
    else:
        ax.hlines(
            [req.band, -req.band],
            t0 + req.limit,
            t1,
            label=f"band +/-{req.band:g} {req.unit} from {req.limit:g} s",
            **style,
        )
        ax.axvline(t0 + req.limit, color=style["color"], ls=":", lw=1.0)


def _draw_ensemble(ax: plt.Axes, t: np.ndarray, curves: dict[str, np.ndarray]) -> None:
    """Runs (grey), ensemble mean +/-3 sigma (dashed black), filter +/-3 sigma (blue)."""
    for i, row in enumerate(curves["runs"][:_MAX_LINES]):
        ax.plot(t, row, lw=0.6, alpha=0.45, color="#57606a", label="runs" if i == 0 else None)
    if "ensemble_hi" in curves:
        ax.plot(t, curves["ensemble_hi"], "k--", lw=1.1, label="ensemble mean ±3σ")
        ax.plot(t, curves["ensemble_lo"], "k--", lw=1.1)
    if "filter_3sigma" in curves:
        f = curves["filter_3sigma"]
        ax.plot(t, f, color="#0969da", lw=1.3, label="filter ±3σ (RMS over runs)")
        ax.plot(t, -f, color="#0969da", lw=1.3)


def build_requirement_figure(campaign: Campaign, req: Requirement, verdict: Verdict) -> plt.Figure:
    """The requirement's figure (see :func:`requirement_figure`) as a matplotlib Figure.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : Requirement
        The requirement.
    verdict : Verdict
        Its verdict.

    Returns
    -------
    matplotlib.figure.Figure
        Axes labelled ``"error"``, ``"window"``, ``"envelope"``, ``"histogram"``.
    """
    if req.reference is not None:  # an estimate, drawn with its +/-3 sigma band
        return estimate_figure(campaign, req, verdict, _histogram)
    k = campaign.requirements.index(req)
    t, e, s = campaign_histories(campaign, k)
    master = campaign.provenance["master"]
    t0, t1 = master["start"], master["stop"]
    fig = plt.figure(figsize=(10.5, 10.0))
    grid = fig.add_gridspec(3, 2, height_ratios=[1.0, 1.0, 1.0])
    ax1 = fig.add_subplot(grid[0, :], label="error")
    axw = fig.add_subplot(grid[1, :], label="window")
    ax2 = fig.add_subplot(grid[2, 0], sharex=ax1, label="envelope")
    ax3 = fig.add_subplot(grid[2, 1], label="histogram")
    verdict_title(fig, req, verdict)
    label = f"error [{req.unit}]"
    window = judged_window(req, t0, t1)
    if t is not None and e.shape[0]:
        _draw_ensemble(ax1, t, window_curves(t, e, s, (t[0], t[-1])))
        curves = window_curves(t, e, s, window)
        _draw_ensemble(axw, curves["time"], curves)
        axw.set_ylim(*window_ylim(req, curves))
        span = curves["time"][-1] - curves["time"][0]
        axw.set_xlim(curves["time"][0] - 0.02 * span, curves["time"][-1] + 0.02 * span)
        ax2.fill_between(t, e.min(axis=0), e.max(axis=0), color="#8c959f", alpha=0.35, lw=0)
        ax2.fill_between(
            t,
            np.percentile(e, 5, axis=0),
            np.percentile(e, 95, axis=0),
            color="#57606a",
            alpha=0.45,
            lw=0,
            label="5–95 %",
        )
        ax2.plot(t, np.median(e, axis=0), color="k", lw=0.9, label="median")
        ax2.fill_between([], [], [], color="#8c959f", alpha=0.35, label="min–max")
    for rec in campaign.failed_runs:
        h = rec.history
        if f"e_{k}" in h:
            ax1.plot(
                h["time"], h[f"e_{k}"], lw=0.9, color="#bc4c00", label=f"run {rec.index} failed"
            )
    for ax in (ax1, axw, ax2):
        ylim = ax.get_ylim() if ax is axw else None
        _draw_limits(ax, req, t0, t1)
        if ylim is not None:  # the bound lines keep the window's range
            ax.set_ylim(*ylim)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel(label)
        ax.legend(loc="upper right", fontsize=7)
    ax1.set_title("error vs time", fontsize=9)
    axw.set_title(
        f"judged window {window[0]:g} – {window[1]:g} s (y-range: the window's data and the bound)",
        fontsize=9,
    )
    axw.set_xlabel("time [s]")
    ax2.set_title(f"Monte Carlo envelope ({e.shape[0]} completed runs)", fontsize=9)
    ax2.set_xlabel("time [s]")
    _histogram(ax3, campaign, req, verdict)
    fig.tight_layout()
    return fig


def _histogram(ax: plt.Axes, campaign: Campaign, req: Requirement, verdict: Verdict) -> None:
    """Per-run metrics with the limit, the statistic and its confidence bounds."""
    values = campaign.metric_values(req)
    finite = values[np.isfinite(values)]
    n_inf = int(np.sum(np.isinf(values)))
    if finite.size:
        ax.hist(finite, bins=min(30, max(5, finite.size // 3)), color="#8c959f", edgecolor="k")
    ax.axvline(req.limit, color="#cf222e", lw=1.6, label=f"limit {req.limit:g} {req.metric_unit}")
    if req.statistic != "pass_rate" and math.isfinite(verdict.value):
        ax.axvline(
            verdict.value,
            color="k",
            ls="--",
            lw=1.2,
            label=f"{req.statistic_text} {verdict.value:.4g}",
        )
    conf = verdict.details.get("confidence", req.confidence)
    if req.statistic != "pass_rate" and verdict.interval is not None and conf is not None:
        lo, hi = verdict.interval
        what = f"{100 * req.probability:g} % quantile" if req.statistic == "max" else ""
        for x, side, ls in ((hi, "upper", "-."), (lo, "lower", ":")):
            if math.isfinite(x):
                ax.axvline(
                    x,
                    color="#8250df",
                    ls=ls,
                    lw=1.4,
                    label=f"{100 * conf:g} % {side} bound {what} {x:.4g}".replace("  ", " "),
                )
    if n_inf:
        ax.text(0.02, 0.92, f"{n_inf} run(s) never settled", transform=ax.transAxes, fontsize=8)
    ax.set_title("per-run metric", fontsize=9)
    ax.set_xlabel(f"metric [{req.metric_unit}]")
    ax.set_ylabel("runs")
    ax.legend(loc="upper right", fontsize=7)
    ax.grid(True, alpha=0.3)


def requirement_figure(campaign: Campaign, req: Requirement, verdict: Verdict) -> str:
    """The requirement's figure as base64 PNG.

    Panels: error vs time over the whole run (runs, ensemble mean +/-3 sigma, filter
    +/-3 sigma, bounds); the same on the judged window only (:func:`judged_window`), its
    y-range set by the window's data and the bound (:func:`window_ylim`), not by the
    transient; Monte Carlo envelope (min-max and 5-95 % bands, median, bounds); histogram
    of the per-run metric with the limit, the statistic and its confidence bounds.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    req : Requirement
        The requirement.
    verdict : Verdict
        Its verdict.

    Returns
    -------
    str
        Base64 of the PNG.
    """
    if req.criterion == "consistent":
        return consistency_figure(campaign, req, verdict)
    return png_base64(build_requirement_figure(campaign, req, verdict))


# ------------------------------------------------------------------------------ HTML
_CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 2em auto;
       max-width: 1100px; color: #1f2328; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; border-bottom: 1px solid #d0d7de; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #d0d7de; padding: 4px 8px; text-align: left; vertical-align: top; }
th { background: #f6f8fa; }
td.verdict { font-weight: bold; color: white; text-transform: uppercase; }
td.satisfied { background: #1a7f37; } td.violated { background: #cf222e; }
td.undecided { background: #9a6700; }
.banner { padding: 0.6em 1em; color: white; font-weight: bold; border-radius: 6px; }
code, .mono { font-family: ui-monospace, Menlo, Consolas, monospace; font-size: 0.9em; }
img { max-width: 100%; }
"""


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _table(header: list[str], rows: list[list[Any]], cls: str = "") -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def write_html(campaign: Campaign, path: Path, data: dict[str, Any] | None = None) -> Path:
    """Write the self-contained HTML report.

    Parameters
    ----------
    campaign : Campaign
        A finished campaign.
    path : Path
        The HTML file.
    data : dict, optional
        :func:`report_data` (computed if not given).

    Returns
    -------
    Path
    """
    data = data or report_data(campaign, datetime.now(UTC).isoformat(timespec="seconds"))
    name = campaign.scenario["name"]
    code = campaign.exit_code
    overall = {0: SATISFIED, 1: VIOLATED, 2: UNDECIDED}[code]
    summary = data["summary"]
    n_runs = campaign.settings.runs
    n_failed = len(campaign.failed_runs)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>Verification report: {_e(name)}</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>Verification report: {_e(name)}</h1>",
        f'<p class="banner" id="overall" data-verdict="{overall}" '
        f'style="background:{_COLOURS[overall]}">'
        f"{summary[SATISFIED]} satisfied, {summary[VIOLATED]} violated, "
        f"{summary[UNDECIDED]} undecided — exit code {code}</p>",
        f"<p>Scenario <code>{_e(campaign.scenario['file'])}</code> "
        f"(sha256 <code>{_e(campaign.scenario['sha256'])}</code>); {n_runs} run(s), "
        f"{n_runs - n_failed} completed, {n_failed} failed; campaign seed "
        f"{campaign.settings.seed}; created {_e(data['created'])}.</p>",
        '<h2 id="verdicts">Verdicts</h2>',
        '<table class="verdicts"><thead><tr><th>id</th><th>requirement</th>'
        "<th>criterion (per run)</th><th>statistic</th><th>measured</th><th>bound</th>"
        "<th>verdict</th><th>why</th><th>what it shows about all runs</th></tr></thead><tbody>",
    ]
    for req, v in zip(campaign.requirements, campaign.verdicts, strict=True):
        parts.append(
            f'<tr class="requirement-row" data-id="{_e(req.id)}" data-verdict="{v.verdict}">'
            f'<td><a href="#req-{_e(req.id)}">{_e(req.id)}</a></td><td>{_e(req.text)}</td>'
            f"<td>{_e(req.describe())}</td><td>{_e(req.describe_statistic())}</td>"
            f"<td>{_e(measured_text(v))}</td><td>{_e(_bound(v))}</td>"
            f'<td class="verdict {v.verdict}">{v.verdict}</td><td>{_e(v.reason)}</td>'
            f'<td class="claim">{_e(v.claim)}</td></tr>'
        )
    parts.append("</tbody></table>")
    parts.append(consistency_overview_html(data["consistency"]))
    calibrated = {c["id"]: c for c in data["consistency"].get("calibration", [])}

    for k, (req, v) in enumerate(zip(campaign.requirements, campaign.verdicts, strict=True)):
        signal = req.signal + (f" − {req.minus}" if req.minus else "")
        signal += f" − reference {req.reference.text}" if req.reference else ""
        interval = ""
        if v.interval is not None and f"{v.interval[0]:.4g} " not in v.reason:
            lo, hi = v.interval
            conf = v.details.get("confidence", req.confidence)
            what = f"{conf * 100:g} % " if conf else ""
            interval = f"; {what}confidence bounds [{lo:.4g}, {hi:.4g}] {v.unit}"
        parts += [
            f'<section class="requirement" id="req-{_e(req.id)}" data-verdict="{v.verdict}">',
            f"<h2>{_e(req.id)}: {_e(req.text)}</h2>",
            f'<p>Verdict: <strong style="color:{_COLOURS[v.verdict]}">{v.verdict}</strong>. '
            f"{_e(v.reason)}{_e(interval)}.</p>",
            f'<p class="claim" data-id="{_e(req.id)}">Shown: {_e(v.claim)}.</p>',
            f"<p>Signal <code>{_e(signal)}</code> in {_e(req.unit)}"
            + (f", filter 1σ <code>{_e(req.sigma)}</code>" if req.sigma else "")
            + f"; per run: {_e(req.describe())}; over the runs: "
            f"{_e(req.describe_statistic())}; failed runs: {_e(req.on_failure)}.</p>",
            f'<figure><img alt="{_e(req.id)}: error vs time, Monte Carlo envelope and '
            f'histogram" src="data:image/png;base64,{requirement_figure(campaign, req, v)}">'
            "</figure>",
            consistency_html(campaign, req),
            calibration_html(campaign, k, calibrated[req.id]) if req.id in calibrated else "",
            budget_html(data.get("budgets", {}).get(req.id)),
            "</section>",
        ]

    # runs
    parts.append('<h2 id="runs">Runs</h2>')
    if n_failed:
        parts.append(f"<p>{n_failed} run(s) failed:</p>")
        parts.append(
            _table(
                ["run", "seeds", "error"],
                [
                    [r.index, _seeds(r.seeds), r.error or "(no message)"]
                    for r in campaign.failed_runs
                ],
                "failed-runs",
            )
        )
    else:
        parts.append("<p>Every run completed.</p>")
    header = ["run", "status", "seeds"] + [
        f"{r.id} [{r.metric_unit}]" for r in campaign.requirements
    ]
    rows = []
    for rec in campaign.records:
        row: list[Any] = [rec.index, rec.status, _seeds(rec.seeds)]
        for r in campaign.requirements:
            m = rec.metrics.get(r.id)
            row.append("—" if m is None else (f"{m.value:.5g}" + ("" if m.passed else " ✗")))
        rows.append(row)
    parts.append(
        f"<details><summary>All {len(rows)} runs (metric per requirement; ✗ = over the "
        f"limit or undecided)</summary>{_table(header, rows, 'runs')}</details>"
    )

    # traceability
    prov = campaign.provenance
    parts += [
        '<h2 id="traceability">Traceability</h2>',
        _table(
            ["item", "value"],
            [
                ["scenario file", campaign.scenario["file"]],
                ["scenario sha256", campaign.scenario["sha256"]],
                ["campaign seed", campaign.settings.seed],
                ["runs", n_runs],
                ["seed rule", prov["seed_rule"]],
                ["randomized blocks", ", ".join(prov["randomized_blocks"]) or "none"],
                ["seeds from the file", _seeds({k: v for k, v in prov["file_seeds"].items()})],
                ["master", ", ".join(f"{k} = {v}" for k, v in prov["master"].items())],
                [
                    "execution",
                    ", ".join(f"{k} = {v}" for k, v in campaign.execution.items()),
                ],
            ],
            "trace",
        ),
        "<h3>Blocks</h3>",
        _table(
            ["block", "kind", "source", "GUID", "sha256"],
            [
                [b, i["kind"], i["source"], i["guid"], i["sha256"]]
                for b, i in prov["blocks"].items()
            ],
            "blocks",
        ),
        "<h3>Software</h3>",
        _table(["package", "version"], [[k, v] for k, v in prov["software"].items()], "software"),
        "</body></html>",
    ]
    path = Path(path)
    write_atomic(path, "\n".join(parts))
    return path


def _seeds(seeds: dict[str, Any]) -> str:
    return ", ".join(f"{b}={s}" for b, s in seeds.items()) or "—"
