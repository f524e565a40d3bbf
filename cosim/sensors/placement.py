"""Place a real run in a simulated campaign: its percentile per requirement.

The workflow (docs/sensor_logs.md, "Verify around the real sensor"): the filter runs once on a real
log (``ImuLogReplay``) and a campaign runs the simulated IMU with the sensor's
characterised parameters, both through ``ins-cosim verify`` with the same requirements.
For every requirement, the real run's metric (the per-run value the verdict is built
from: the error at ``at``, the largest error in the window, the settling time) is placed
in the distribution of the campaign's per-run metrics::

    percentile = 100 * (#{campaign metrics < real} + #{== real} / 2) / #{campaign metrics}

(the mid-rank: 50 is the campaign's median). A real metric outside the campaign's range
is reported as a *finding*: the sensor, its mounting or the base differs from what the
campaign simulated (an unmodelled error, a wrong parameter, a base that was not still).
It is a statement about the data, not a failure of the tool; the exit code stays 0.

Only the two ``report.json`` files are read (schema of :mod:`cosim.verify.report`), so
the placement can be redone at any time from the reports alone.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from cosim.errors import UserError


class PlacementError(UserError, ValueError):
    """A report is missing or unreadable, or the two reports do not share a requirement."""


@dataclass(frozen=True)
class Placement:
    """Where the real run's metric of one requirement falls in the campaign's.

    Attributes
    ----------
    id : str
        Requirement id.
    text : str
        The requirement as written.
    unit : str
        Unit of the metric.
    limit : float
        The per-run limit.
    real : float
        The real run's metric (nan when the run could not decide it).
    real_passed : bool or None
        Whether the real run meets the per-run limit.
    percentile : float
        Mid-rank percentile of ``real`` among the campaign's metrics [0, 100] (nan when
        either side has no value).
    runs : int
        Campaign runs with a metric.
    low, median, high : float
        The campaign's smallest, median and largest metric.
    finding : str
        Empty, or the sentence the report states (outside the range, in a 5 % tail).
    """

    id: str
    text: str
    unit: str
    limit: float
    real: float
    real_passed: bool | None
    percentile: float
    runs: int
    low: float
    median: float
    high: float
    finding: str


def read_report(path: str | Path) -> dict[str, Any]:
    """A campaign's ``report.json``.

    Parameters
    ----------
    path : str or Path
        The report folder (``ins-cosim verify --report DIR``) or the json file.

    Returns
    -------
    dict

    Raises
    ------
    PlacementError
        Missing or not a report.
    """
    p = Path(path)
    js = p / "report.json" if p.is_dir() else p
    try:
        data = json.loads(js.read_text())
    except (OSError, ValueError) as exc:
        raise PlacementError(
            f"{js}: cannot read a campaign report ({exc}); run ins-cosim verify SCENARIO "
            f"--report {p} first"
        ) from exc
    if not isinstance(data, dict) or "requirements" not in data or "runs" not in data:
        raise PlacementError(f"{js}: not an ins-cosim verify report (no requirements or runs)")
    return data


def _value(x: Any) -> float:
    return float(x) if x is not None else math.nan


def _metrics(report: dict[str, Any], req_id: str) -> list[float]:
    out = []
    for run in report["runs"]:
        m = (run.get("metrics") or {}).get(req_id)
        if run.get("status") == "completed" and m is not None:
            v = _value(m["value"])
            if not math.isnan(v):
                out.append(v)
    return out


def place(real: dict[str, Any], campaign: dict[str, Any]) -> list[Placement]:
    """Place the real report's run in the campaign's distribution, per requirement.

    Parameters
    ----------
    real : dict
        :func:`read_report` of the real run (its first completed run is placed).
    campaign : dict
        :func:`read_report` of the simulated campaign.

    Returns
    -------
    list of Placement
        In the campaign's requirement order, for the ids both reports have.

    Raises
    ------
    PlacementError
        The real report has no completed run, or the reports share no requirement.
    """
    runs = [r for r in real["runs"] if r.get("status") == "completed"]
    if not runs:
        raise PlacementError("the real run's report has no completed run: see its report.html")
    ours = runs[0].get("metrics") or {}
    shared = [r for r in campaign["requirements"] if r["id"] in ours]
    if not shared:
        raise PlacementError(
            f"the reports share no requirement (real: {', '.join(sorted(ours)) or 'none'}; "
            f"campaign: {', '.join(r['id'] for r in campaign['requirements']) or 'none'}): "
            "give both scenarios the same [[requirements]]"
        )
    out = []
    for req in shared:
        m = ours[req["id"]]
        value = math.nan if m is None else _value(m["value"])
        passed = None if m is None else m.get("passed")
        sim = sorted(_metrics(campaign, req["id"]))
        n = len(sim)
        unit = req.get("limit_unit") or req.get("unit", "")
        if n == 0 or math.isnan(value):
            pct, low, med, high = math.nan, math.nan, math.nan, math.nan
            finding = "not placed: " + (
                "no campaign run decided it"
                if n == 0
                else f"the real run did not decide it ({m and m['note']})"
            )
        else:
            below = sum(v < value for v in sim)
            equal = sum(v == value for v in sim)
            pct = 100.0 * (below + 0.5 * equal) / n
            low, high = sim[0], sim[-1]
            med = sim[n // 2] if n % 2 else 0.5 * (sim[n // 2 - 1] + sim[n // 2])
            finding = ""
            if value > high or value < low:
                side = "above the largest" if value > high else "below the smallest"
                finding = (
                    f"outside the simulated distribution: {value:.4g} {unit} is {side} of "
                    f"the {n} simulated runs ({low:.4g} .. {high:.4g} {unit}); the sensor, "
                    "its mounting or the base differs from the simulated model"
                )
            elif pct >= 95.0 or pct <= 5.0:
                finding = f"in the {'upper' if pct >= 95.0 else 'lower'} 5 % tail of the campaign"
        out.append(
            Placement(
                req["id"], req.get("text", ""), unit, float(req["limit"]), value, passed, pct,
                n, low, med, high, finding,
            )
        )  # fmt: skip
    return out


def format_placement(placements: list[Placement], real: str, campaign: str) -> str:
    """The placement as a Markdown report.

    Parameters
    ----------
    placements : list of Placement
        From :func:`place`.
    real, campaign : str
        Names of the two reports (their folders).

    Returns
    -------
    str
    """
    lines = [
        f"# Real run {real} in campaign {campaign}",
        "",
        "| requirement | real run | per-run limit | percentile in the campaign | campaign "
        "min / median / max | runs | finding |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in placements:
        verdict = {True: "meets", False: "exceeds", None: "undecided"}[p.real_passed]
        lines.append(
            f"| {p.id} | {p.real:.4g} {p.unit} ({verdict}) | {p.limit:.4g} {p.unit} | "
            f"{p.percentile:.1f} | {p.low:.4g} / {p.median:.4g} / {p.high:.4g} | {p.runs} | "
            f"{p.finding or '-'} |"
        )
    outside = [p.id for p in placements if p.finding.startswith("outside")]
    lines += [
        "",
        "Percentile: mid-rank of the real run's metric among the campaign's per-run metrics "
        "(50 = the campaign's median). "
        + (
            f"Finding: the real run lies outside the simulated distribution for "
            f"{', '.join(outside)}; this is a statement about the sensor or the model, not a "
            "failure of the tool."
            if outside
            else "The real run lies within the simulated distribution for every requirement."
        ),
    ]
    return "\n".join(lines) + "\n"


def write_placement(
    placements: list[Placement], out_dir: str | Path, real: str, campaign: str
) -> dict[str, Path]:
    """Write ``placement.md`` and ``placement.json``.

    Parameters
    ----------
    placements : list of Placement
        From :func:`place`.
    out_dir : str or Path
        Destination folder (created).
    real, campaign : str
        Names of the two reports.

    Returns
    -------
    dict of str to Path
        ``{"md", "json"}`` -> file.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = out / "placement.md"
    md.write_text(format_placement(placements, real, campaign))
    js = out / "placement.json"
    rows = [
        {k: (str(v) if isinstance(v, float) and not math.isfinite(v) else v)
         for k, v in asdict(p).items()}
        for p in placements
    ]  # fmt: skip
    js.write_text(json.dumps({"real": real, "campaign": campaign, "placements": rows}, indent=2))
    return {"md": md, "json": js}
