"""Reproduction of seed 000: HRG platform two-position self-alignment, UPF against EKF.

The entry point ``seed000`` of the group ``ins_cosim.reproductions``: runs the cases of
:mod:`cosim.reproduce.seed000_runs` (where the cases, the seeds and the metrics are
described), the accelerometer-noise study (:mod:`.seed000_noise`) and writes the plots
and the Markdown block (:mod:`.seed000_report`).
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

from cosim.reproduce.seed000_noise import noise_sensitivity
from cosim.reproduce.seed000_report import markdown, plots, sensitivity_plot
from cosim.reproduce.seed000_runs import (
    LARGE_AZIMUTHS,
    METHODS,
    SCENARIO,
    UG_SQRT_HZ,
    campaign,
    campaign_stats,
    prepared,
)
from cosim.verify.campaign import CampaignError

#: Runs and campaign seed of the published block (``ins-cosim reproduce`` defaults).
DEFAULT_RUNS = 30
DEFAULT_SEED = 2024
#: The case ``--run I`` reruns when no ``--case`` is given.
DEFAULT_CASE = "main"


def rerun(case: str, index: int, runs: int, seed: int) -> str:
    """Run ``index`` of one campaign of the reproduction alone (every filter), with its numbers.

    Parameters
    ----------
    case : str
        ``"main"``, ``"large <azimuth deg>"`` (e.g. ``"large 170"``), ``"prior"`` or
        ``"noise <ug/sqrt(Hz)>"`` (e.g. ``"noise 2"``): the campaigns of :func:`reproduce`.
    index : int
        Run number within that campaign.
    runs : int
        Runs of the reproduction's main campaign.
    seed : int
        Campaign seed of the reproduction.

    Returns
    -------
    str
        The run's :class:`RunSummary` per filter.

    Raises
    ------
    CampaignError
        An unknown case, or a run outside its campaign.
    """
    name, _, arg = case.partition(" ")
    try:
        value = float(arg) if arg else math.nan
    except ValueError:
        value, name = math.nan, ""
    kw: dict[str, Any] = {}
    if name == "main" and not arg:
        n, s, methods = runs, seed, (0, 1, 2)
    elif name == "large" and arg:
        n, s, methods, kw = min(runs, 10), seed + 1, (0, 1, 2), {"azimuth0_deg": value}
    elif name == "prior" and not arg:
        n, s, methods, kw = min(runs, 20), seed + 2, (0, 1, 2), {"truth": "prior"}
    elif name == "noise" and arg:
        d = value * UG_SQRT_HZ
        n, s, methods = runs, seed, (1, 2)
        kw = {"overrides": {"accel": {"noise_density": d}, "filter": {"accel_noise": d}}}
    else:
        raise CampaignError(f"seed000 has no case '{case}' (main, large AZ, prior, noise D)")
    res = campaign(n, s, methods, indices=[index], **kw)
    lines = [f"seed000 '{case}', run {index} of {n}, campaign seed {s}:"]
    lines += [f"  {METHODS[m]}: {res[m][0]}" for m in methods]
    return "\n".join(lines)


def reproduce(out_dir: Path, runs: int, seed: int, workers: int | None = None) -> str:
    """Run the seed 000 cases, write plots into ``out_dir``, return the Markdown block.

    Parameters
    ----------
    out_dir : Path
        Folder for the plots.
    runs : int
        Runs of the main campaign (the large-misalignment set uses ``min(runs, 10)``
        per azimuth).
    seed : int
        Campaign seed.
    workers : int, optional
        Processes (default: the number of CPUs).

    Returns
    -------
    str
        Markdown: the paper's figures next to ours, Table 1 at the 95th percentile, the
        large-misalignment table, the sensitivity to the accelerometer noise
        (:mod:`.seed000_noise`, ``runs`` runs of the campaign seed per density).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    kw: dict[str, Any] = {"workers": workers or os.cpu_count() or 1, "prep": prepared()}
    main = campaign(runs, seed, (0, 1, 2), history_runs=1, **kw)
    large = {
        az: campaign(min(runs, 10), seed + 1, (0, 1, 2), azimuth0_deg=az, **kw)
        for az in LARGE_AZIMUTHS
    }
    prior = campaign(min(runs, 20), seed + 2, (0, 1, 2), truth="prior", **kw)
    sens = noise_sensitivity(runs, seed, **kw)
    elapsed = time.perf_counter() - start
    files = [*plots(out_dir, {m: main[m][0] for m in (0, 1)}), sensitivity_plot(out_dir, sens)]
    root = SCENARIO.parents[1]
    try:  # link the plots relative to the README when they are inside the repository
        where = out_dir.resolve().relative_to(root).as_posix()
    except ValueError:
        where = out_dir.resolve().as_posix()
    files = [f"{where}/{p}" for p in files]
    st = {m: campaign_stats(main[m]) for m in (0, 1, 2)}
    fixed = {m: main[m][0] for m in (0, 1, 2)}
    return markdown(st, fixed, large, prior, runs, seed, files, elapsed, sens)
