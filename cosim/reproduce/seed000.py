"""Reproduction of seed 000: HRG platform two-position self-alignment, UPF against EKF.

Runs ``scenarios/hrg_two_position.toml`` (truth: :class:`models.hrg_platform.HrgPlatform`
with the HRG triad and the pulse accelerometers; filter:
:class:`cosim.alignment.hrg_two_position.HrgTwoPositionAlignment`) as

1. one fixed-seed run per filter (EKF, UPF, and the linear KF reference), plotted;
2. a campaign of ``runs`` runs with the paper's truth (sec. 3.1), every filter on the
   same runs (same sensor noise), giving the paper's figures and Table 1 at the 95th
   percentile;
3. the large-misalignment set: initial azimuth 10, 45, 100, 170, -120 deg,
   ``min(runs, 10)`` runs each, every filter;
4. ``min(runs, 20)`` runs with the truth drawn from the paper's P0 (azimuth uniform);
5. the campaign of 2. again (UPF and KF, the same runs) at accelerometer white-noise
   densities of 1-8 ug/sqrt(Hz), truth and filter model alike (:func:`noise_sensitivity`):
   the paper gives no accelerometer noise and the convergence time depends on it.

Every run goes through the campaign engine of ``ins-cosim verify``
(:mod:`cosim.verify.campaign`), with its seed rule (:func:`cosim.verify.seeds.run_seeds`)
and a fourth stream for the truth after the three seeded blocks::

    child_i = SeedSequence(seed).spawn(runs)[i]      (= SeedSequence(seed, spawn_key=(i,)))
    gyro, accel, filter, truth seeds = child_i.generate_state(4, uint32) >> 1

so run ``i`` has the same sensor noise for every filter and in every table, and the
same as run ``i`` of ``ins-cosim verify scenarios/hrg_two_position.toml --seed S``
(``--only-run I`` reruns it alone; the scenario's filter is the UPF). With
``truth="prior"`` the truth is drawn per run from the truth seed: azimuth uniform,
tilts ``N(0, 3')``, drifts ``N(0, 0.2 deg/h)`` per gyro (the paper's P0).

Metrics of one run (``e`` = estimate minus truth):

- azimuth error: ``filter.azimuth_err`` at the end (two positions, eq. 20) [arcmin];
- convergence time per position: the first time from the position's start after which
  the apparent-azimuth error ``|psi_est - psi_true|`` stays within ``CONV_BAND`` (4')
  to the position's end; ``psi_true = A + atan2(-d_E, Oc - d_N)`` from the recorded
  true azimuth and drift rates (what one position can observe, eq. 15); NaN if never;
- level errors ``theta_E``, ``theta_N`` at the end [arcmin], and the time after which
  both stay within 1' in position 1;
- drift errors of the y ("north") and x ("east") gyros at the end [deg/h];
- failed: final azimuth error above the Table 1 tolerance (15').
"""

from __future__ import annotations

import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.master import CouplingWarning
from cosim.units import conversion_factor
from cosim.verify.campaign import CampaignError, Prepared, prepare, simulate
from cosim.verify.seeds import run_seeds
from cosim.verify.workers import Job
from models.constants import ARCMIN, OMEGA_IE
from models.constants import DEG_PER_HOUR as DEG_H
from models.conventions import wrap_angle

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "hrg_two_position.toml"
#: Convergence band of the apparent azimuth (acceptance: 4') [arcmin].
CONV_BAND = 4.0
#: Level convergence band [arcmin] (Table 1: level error < 1').
LEVEL_BAND = 1.0
#: Table 1 tolerances: azimuth [arcmin], theta_E, theta_N [arcmin], D_N, D_E [deg/h].
TABLE1 = {"azimuth": 15.0, "theta_E": 1.0, "theta_N": 1.0, "D_N": 0.01, "D_E": 0.02}
#: Initial azimuths of the large-misalignment set [deg].
LARGE_AZIMUTHS = (10.0, 45.0, 100.0, 170.0, -120.0)
#: A run whose final azimuth error exceeds this failed: Table 1's tolerance [arcmin].
FAIL_LIMIT = TABLE1["azimuth"]
#: The paper's UPF azimuth convergence time (acceptance 1) [s].
CONV_LIMIT = 70.0
#: 1 ug/sqrt(Hz) in m/s/sqrt(s), the scenario's own conversion (so that 5 ug/sqrt(Hz) here
#: is bit-identical to the file's "5 ug/sqrt(Hz)").
UG_SQRT_HZ = conversion_factor("ug/sqrt(Hz)", "m/s/sqrt(s)")
#: Accelerometer white-noise densities of the sensitivity study [ug/sqrt(Hz)].
NOISE_DENSITIES = (1.0, 2.0, 3.0, 5.0, 8.0)
#: Parameters a run sets itself (seeds, filter method): not allowed as overrides.
RUN_SET = ("seed", "method")
#: The filter block's ``method`` parameter: the filters compared.
METHODS = {0: "EKF", 1: "UPF", 2: "KF"}
#: Streams of a run: the seeded blocks in file order, then the truth's own.
STREAMS = ("gyro", "accel", "filter", "truth")


@dataclass
class RunSummary:
    """Metrics of one run (angles in arcmin, rates in deg/h, times in s).

    Attributes
    ----------
    method : int
        0 EKF, 1 UPF, 2 KF.
    index : int
        Run number in its campaign (its seeds: :data:`STREAMS` of
        :func:`cosim.verify.seeds.run_seeds`).
    azimuth0 : float
        True initial platform azimuth [deg].
    azimuth_err : float
        Two-position azimuth error at the end (eq. 20), estimate minus truth [arcmin].
    azimuth_sigma : float
        The filter's own 1-sigma of it [arcmin].
    t_conv : tuple of float
        Convergence time of position 1 and 2 (apparent azimuth within ``CONV_BAND``
        from then to the position's end) [s]; NaN if never.
    psi_err_end : tuple of float
        Apparent-azimuth error at the end of position 1 and 2 [arcmin].
    t_conv_self : tuple of float
        The filter's self-assessed convergence (3 sigma <= ``conv_band``) per position
        [s]; NaN if never.
    theta_E_err, theta_N_err : float
        Level errors at the end [arcmin].
    t_level : float
        Time after which both level errors stay within ``LEVEL_BAND`` in position 1 [s].
    D_N_err, D_E_err : float
        Drift errors of the y ("north") and x ("east") gyros at the end [deg/h].
    H_E : float
        East-gyro regular drift estimate (eq. 21) [deg/h].
    failed : bool
        Final azimuth error above the Table 1 tolerance (15').
    history : dict or None
        Time histories for the plots (name -> ndarray, shape (m,)), if kept.
    parameters : dict or None
        The run's parameters ``{block: {name: SI value}}``, kept with the histories.
    """

    method: int
    index: int
    azimuth0: float  # deg
    azimuth_err: float
    azimuth_sigma: float
    t_conv: tuple[float, float]
    psi_err_end: tuple[float, float]
    t_conv_self: tuple[float, float]
    theta_E_err: float
    theta_N_err: float
    t_level: float
    D_N_err: float
    D_E_err: float
    H_E: float
    failed: bool
    history: dict[str, np.ndarray] | None = field(default=None, repr=False)
    parameters: dict[str, dict[str, Any]] | None = field(default=None, repr=False)


def summarise(
    result: Any, params: dict[str, dict[str, Any]], method: int, index: int, history: bool
) -> RunSummary:
    """Metrics of one run's recording (see the module docstring).

    Parameters
    ----------
    result : structured ndarray or mapping
        The master's recording (``time`` and the platform and filter outputs).
    params : dict
        The run's parameters, ``{block: {name: SI value}}``.
    method : int
        0 EKF, 1 UPF, 2 KF.
    index : int
        Run number.
    history : bool
        Keep the time histories needed for the plots.

    Returns
    -------
    RunSummary
    """
    t = result["time"]
    lat = float(params["filter"]["lat"])
    oc = OMEGA_IE * math.cos(lat)
    az_true = result["platform.azimuth"]
    d_e = result["platform.drift_rate_n[1]"]
    d_n = result["platform.drift_rate_n[2]"]
    psi_true = wrap_angle(az_true + np.arctan2(-d_e, oc - d_n))
    psi_err = wrap_angle(result["filter.psi_est"] - psi_true) / ARCMIN
    active = result["filter.position_active"]
    status = result["platform.position"]
    starts = {1: float(t[0])}
    if np.any(status == 2.0):
        starts[2] = float(t[np.argmax(status == 2.0)])
    t_conv, psi_end = [], []
    for pos in (1, 2):
        sel = np.flatnonzero((active == pos) & (status == float(pos)))
        if sel.size == 0 or pos not in starts:
            t_conv.append(math.nan)
            psi_end.append(math.nan)
            continue
        err = np.abs(psi_err[sel])
        bad = np.flatnonzero(err > CONV_BAND)
        if bad.size == 0:
            t_conv.append(float(t[sel[0]] - starts[pos]))
        elif bad[-1] == sel.size - 1:
            t_conv.append(math.nan)
        else:
            t_conv.append(float(t[sel[bad[-1] + 1]] - starts[pos]))
        psi_end.append(float(psi_err[sel[-1]]))
    sel1 = np.flatnonzero((active == 1) & (status == 1.0))
    lev = np.maximum(np.abs(result["filter.theta_E_err"]), np.abs(result["filter.theta_N_err"]))
    bad = np.flatnonzero(lev[sel1] > LEVEL_BAND)
    if sel1.size == 0 or (bad.size and bad[-1] == sel1.size - 1):
        t_level = math.nan
    else:
        t_level = float(t[sel1[bad[-1] + 1 if bad.size else 0]] - starts[1])
    drift = [float(params["gyro"][f"drift[{k}]"]) for k in (1, 2)]
    self_conv = [float(result[f"filter.t_conv_{k}"][-1]) for k in (1, 2)]
    az_err = float(result["filter.azimuth_err"][-1])
    hist = None
    if history:
        names = [
            "azimuth_err",
            "azimuth_sigma",
            "psi_sigma",
            "theta_E_err",
            "theta_N_err",
            "theta_E_sigma",
            "theta_N_sigma",
            "position_active",
            "ess",
        ]
        hist = {n: np.asarray(result[f"filter.{n}"]).copy() for n in names}
        hist["time"] = np.asarray(t).copy()
        hist["psi_err"] = psi_err
        hist["status"] = np.asarray(status).copy()
    return RunSummary(
        method=int(method),
        index=int(index),
        azimuth0=math.degrees(float(params["platform"]["azimuth0"])),
        azimuth_err=az_err,
        azimuth_sigma=float(result["filter.azimuth_sigma"][-1]),
        t_conv=(t_conv[0], t_conv[1]),
        psi_err_end=(psi_end[0], psi_end[1]),
        t_conv_self=(
            self_conv[0] if self_conv[0] >= 0 else math.nan,
            self_conv[1] if self_conv[1] >= 0 else math.nan,
        ),
        theta_E_err=float(result["filter.theta_E_err"][-1]),
        theta_N_err=float(result["filter.theta_N_err"][-1]),
        t_level=t_level,
        D_N_err=(float(result["filter.D_N_est"][-1]) - drift[1]) / DEG_H,
        D_E_err=(float(result["filter.D_E_est"][-1]) - drift[0]) / DEG_H,
        H_E=float(result["filter.H_E"][-1]) / DEG_H,
        failed=not abs(az_err) <= FAIL_LIMIT,
        history=hist,
        parameters=params if history else None,
    )


def draw_truth(seed: int) -> dict[str, float]:
    """A truth drawn from the paper's P0 (azimuth uniform), SI, for ``truth="prior"``.

    Parameters
    ----------
    seed : int
        The run's truth seed (the ``truth`` stream of :data:`STREAMS`).

    Returns
    -------
    dict
        ``azimuth0``, ``theta_E0``, ``theta_N0`` [rad] and ``drift[1..3]`` [rad/s].
    """
    rng = np.random.default_rng(seed)
    return {
        "azimuth0": float(rng.uniform(-math.pi, math.pi)),
        "theta_E0": float(rng.normal(0.0, 3.0 * ARCMIN)),
        "theta_N0": float(rng.normal(0.0, 3.0 * ARCMIN)),
        **{f"drift[{k}]": float(rng.normal(0.0, 0.2 * DEG_H)) for k in (1, 2, 3)},
    }


def prepared() -> Prepared:
    """The seed 000 scenario, checked once (:func:`cosim.verify.campaign.prepare`).

    Returns
    -------
    Prepared
        Its seeded blocks are ``gyro``, ``accel``, ``filter`` (the first three of
        :data:`STREAMS`) and ``parameters`` its parameters in SI.

    Raises
    ------
    CampaignError
        The scenario's seeded blocks are not those of :data:`STREAMS`.
    """
    with warnings.catch_warnings():
        # the platform <- gyro servo loop is intended (see the scenario file)
        warnings.simplefilter("ignore", CouplingWarning)
        prep = prepare(SCENARIO, requirements=False)
    if tuple(prep.seeded) != STREAMS[:3]:
        raise CampaignError(f"{SCENARIO}: expected seeded blocks {STREAMS[:3]}, got {prep.seeded}")
    return prep


def campaign(
    runs: int,
    seed: int,
    methods: tuple[int, ...] = (0, 1, 2),
    azimuth0_deg: float | None = None,
    truth: str = "paper",
    stop: float | None = None,
    history_runs: int = 0,
    overrides: dict[str, dict[str, float]] | None = None,
    *,
    platform: dict[str, float] | None = None,
    indices: list[int] | None = None,
    workers: int = 1,
    prep: Prepared | None = None,
) -> dict[int, list[RunSummary]]:
    """Run ``runs`` runs per method on the same per-run seeds, through the campaign engine.

    Parameters
    ----------
    runs : int
        Runs per method.
    seed : int
        Campaign seed (:data:`STREAMS` of :func:`cosim.verify.seeds.run_seeds`).
    methods : tuple of int
        Filters to run (0 EKF, 1 UPF, 2 KF).
    azimuth0_deg : float, optional
        True initial azimuth for every run [deg] (default: the scenario's 100 deg).
    truth : {"paper", "prior"}
        The paper's fixed truth, or one drawn per run from P0.
    stop : float, optional
        Stop time [s] (default: the scenario's).
    history_runs : int
        Keep histories (and parameters) for the runs with an index below this.
    overrides : dict, optional
        Block -> {parameter: SI value} for every run, e.g.
        ``{"accel": {"noise_density": 2e-5}}``; the seeds of the runs do not depend on
        them. Seeds and the filter method are set per run and cannot be overridden.
    platform : dict, optional
        Platform parameters (SI) for every run (the same as
        ``overrides={"platform": platform}``, applied before them).
    indices : list of int, optional
        Only these runs of the campaign (default ``0 .. runs - 1``): run ``i`` alone
        equals run ``i`` of the whole campaign.
    workers : int
        Processes (1: this process).
    prep : Prepared, optional
        The scenario from :func:`prepared` (checked again otherwise).

    Returns
    -------
    dict
        method -> list of :class:`RunSummary`, in run order.

    Raises
    ------
    ValueError
        ``truth`` not ``"paper"`` or ``"prior"``.
    CampaignError
        An override of an unknown block or parameter, or of a seed or the method; a
        failed run.
    """
    if truth not in ("paper", "prior"):
        raise ValueError(f"truth: expected 'paper' or 'prior', got {truth!r}")
    prep = prep or prepared()
    common: dict[str, dict[str, Any]] = {"platform": dict(platform or {})}
    for block, values in (overrides or {}).items():
        for name in values:
            if name in RUN_SET:
                raise CampaignError(f"overrides: {block}.{name} is set by each run")
        common.setdefault(block, {}).update(values)
    prep.check_parameters(common, "overrides")
    jobs = []
    for i in range(int(runs)) if indices is None else indices:
        if not 0 <= i < int(runs):
            raise CampaignError(f"run {i} is outside 0 .. {int(runs) - 1}")
        streams = run_seeds(seed, i, STREAMS)
        this = draw_truth(streams["truth"]) if truth == "prior" else {}
        if azimuth0_deg is not None:
            this["azimuth0"] = math.radians(azimuth0_deg)
        params = {b: dict(v) for b, v in common.items()}
        for key, value in this.items():
            params.setdefault("gyro" if key.startswith("drift") else "platform", {})[key] = value
        seeds = {b: streams[b] for b in STREAMS[:3]}
        for m in methods:
            run_params = {**params, "filter": {**params.get("filter", {}), "method": int(m)}}
            jobs.append(Job(int(i), seeds, run_params, tag=str(m)))
    records = simulate(prep, jobs, stop=stop, workers=max(1, min(int(workers), len(jobs))))
    out: dict[int, list[RunSummary]] = {m: [] for m in methods}
    for rec in records:
        if rec.failed:
            raise CampaignError(f"run {rec.index}, method {rec.tag}: {rec.error}")
        m = int(rec.tag)
        keep = rec.index < history_runs
        out[m].append(summarise(rec.columns, rec.parameters, m, rec.index, keep))
    return out


# ----------------------------------------------------------------------------------------
# Statistics and report
# ----------------------------------------------------------------------------------------
def p95(values: list[float]) -> float:
    """Empirical 95th percentile of ``|values|`` (NaN counts as infinite).

    Parameters
    ----------
    values : list of float
        One metric per run (NaN: never converged).

    Returns
    -------
    float
        The ``higher`` 95th percentile; NaN for no values.
    """
    a = np.abs(np.asarray(values, dtype=float))
    a = np.where(np.isnan(a), np.inf, a)
    return float(np.percentile(a, 95.0, method="higher")) if a.size else math.nan


def median(values: list[float]) -> float:
    """Median of ``values`` (NaN counts as infinite: a run that never converged).

    Parameters
    ----------
    values : list of float
        One metric per run.

    Returns
    -------
    float
        NaN for no values.
    """
    a = np.asarray(values, dtype=float)
    a = np.where(np.isnan(a), np.inf, a)
    return float(np.median(a)) if a.size else math.nan


def campaign_stats(summaries: list[RunSummary]) -> dict[str, float]:
    """Campaign statistics of one filter's runs (what the README tables print).

    Parameters
    ----------
    summaries : list of RunSummary
        The runs of one method.

    Returns
    -------
    dict
        ``n``, ``failed``, ``t1``, ``t2`` (median convergence [s]), ``t1_p95``,
        ``t2_p95`` [s], azimuth, level and drift statistics (arcmin, deg/h).
    """
    ok = [s for s in summaries if not s.failed]
    az = np.array([abs(s.azimuth_err) for s in summaries])
    return {
        "n": len(summaries),
        "failed": len(summaries) - len(ok),
        "t1": median([s.t_conv[0] for s in summaries]),
        "t2": median([s.t_conv[1] for s in summaries]),
        "t1_p95": p95([s.t_conv[0] for s in summaries]),
        "t2_p95": p95([s.t_conv[1] for s in summaries]),
        "az_mean": float(np.mean(az)) if az.size else math.nan,
        "az_rms": float(np.sqrt(np.mean(az**2))) if az.size else math.nan,
        "az_p95": p95([s.azimuth_err for s in summaries]),
        "az_sigma": float(np.median([s.azimuth_sigma for s in summaries])),
        "thE_p95": p95([s.theta_E_err for s in summaries]),
        "thN_p95": p95([s.theta_N_err for s in summaries]),
        "t_level": median([s.t_level for s in summaries]),
        "DN_p95": p95([s.D_N_err for s in summaries]),
        "DE_p95": p95([s.D_E_err for s in summaries]),
        "HE_p95": p95([s.H_E for s in summaries]),
        "self1": median([s.t_conv_self[0] for s in summaries]),
    }


# ----------------------------------------------------------------------------------------
# Sensitivity to the accelerometer noise (the paper gives none)
# ----------------------------------------------------------------------------------------
def largest_density_within(
    densities: tuple[float, ...] | list[float],
    times: tuple[float, ...] | list[float],
    limit: float = CONV_LIMIT,
) -> float:
    """Largest noise density whose time stays within ``limit``, log-log interpolated.

    The times at the swept densities are joined by straight lines in log-log (a power
    law between neighbours, as ``t ~ N^(2/3)`` of the module docstring); the result is
    where the line leaving the last swept density with ``time <= limit`` crosses
    ``limit``.

    Parameters
    ----------
    densities : sequence of float
        Swept densities (> 0, distinct; any order).
    times : sequence of float
        Time at each density (> 0; NaN or inf: never converged).
    limit : float
        The bound on the time (> 0).

    Returns
    -------
    float
        The crossing density; the largest swept density when every time is within
        ``limit`` (a lower bound then); NaN when none is. A crossing towards a
        never-converged neighbour is put at the last density within ``limit``.

    Raises
    ------
    ValueError
        Lengths differ, a density or time <= 0, repeated densities, or ``limit`` <= 0.
    """
    d = np.asarray(densities, dtype=float)
    t = np.asarray(times, dtype=float)
    if d.shape != t.shape or d.ndim != 1 or d.size == 0:
        raise ValueError(
            f"densities and times: expected equal 1-D lengths, got {d.shape} and {t.shape}"
        )
    if not (limit > 0.0 and np.all(d > 0.0) and np.all((t > 0.0) | np.isnan(t))):
        raise ValueError("densities, times and limit: expected > 0 (times may be NaN)")
    order = np.argsort(d)
    d, t = d[order], np.where(np.isnan(t), np.inf, t[order])
    if np.any(np.diff(d) == 0.0):
        raise ValueError(f"densities: expected distinct values, got {sorted(d.tolist())}")
    within = np.flatnonzero(t <= limit)
    if within.size == 0:
        return math.nan
    k = int(within[-1])
    if k == d.size - 1:
        return float(d[k])
    if math.isinf(t[k + 1]):
        return float(d[k])
    frac = math.log(limit / t[k]) / math.log(t[k + 1] / t[k])
    return float(d[k] * (d[k + 1] / d[k]) ** frac)


def convergence_bound(
    density_ug: float | np.ndarray,
    g: float,
    lat: float,
    probability: float = 0.95,
    band: float = CONV_BAND,
) -> float | np.ndarray:
    """Earliest time by which ``probability`` of any unbiased estimator's runs are in the band.

    One position sees its apparent azimuth ``psi`` through the east tilt rate
    ``Oc psi`` (``Oc = Omega cos L``): the measured specific force is
    ``-g theta_E - g Oc psi t`` plus white noise of density ``N``. Fitting the slope over
    ``[0, t]`` (continuous least squares, the Fisher information of that model) gives
    the Cramer-Rao bound::

        sigma_psi(t) = sqrt(12) N / (g Oc t^(3/2))

    and a Gaussian error is inside ``+-band`` with ``probability`` once
    ``z sigma_psi(t) <= band``, ``z = Phi^-1((1 + probability) / 2)``::

        t = (z sqrt(12) N / (g Oc band))^(2/3)

    A lower bound on the convergence time of the module docstring (which asks the error
    to *stay* in the band, and whose data also carry the pulse quantisation, the other
    states and the cubic drift term, which only remove information): the
    ``probability``-quantile of that time over many runs cannot be earlier. The prior
    (0.2 deg/h drift, about 1 deg of apparent azimuth) adds nothing at the arcmin level.

    Parameters
    ----------
    density_ug : float or ndarray
        Accelerometer white-noise density [ug/sqrt(Hz)] (> 0), any shape.
    g : float
        Gravity [m/s^2].
    lat : float
        Latitude [rad].
    probability : float
        Fraction of runs inside the band (0 < p < 1; 0.5: the median run).
    band : float
        Half-width of the band [arcmin].

    Returns
    -------
    float or ndarray
        Time from the position's start [s], the shape of ``density_ug``.

    Raises
    ------
    ValueError
        A density, ``g`` or ``band`` not > 0, ``probability`` outside (0, 1) or a pole.
    """
    from scipy.stats import norm

    n = np.asarray(density_ug, dtype=float)
    oc = OMEGA_IE * math.cos(lat)
    if not (np.all(n > 0.0) and g > 0.0 and band > 0.0 and 0.0 < probability < 1.0 and oc > 0):
        raise ValueError(
            "convergence_bound: expected density_ug, g, band > 0, 0 < probability < 1 and "
            f"|lat| < 90 deg, got {density_ug!r}, {g!r}, {band!r}, {probability!r}, {lat!r}"
        )
    z = float(norm.ppf(0.5 * (1.0 + probability)))
    t = (z * math.sqrt(12.0) * n * UG_SQRT_HZ / (g * oc * band * ARCMIN)) ** (2.0 / 3.0)
    return float(t) if t.ndim == 0 else t


@dataclass
class NoiseSensitivity:
    """The paper-truth campaign at several accelerometer noise densities.

    Attributes
    ----------
    densities : tuple of float
        Swept white-noise densities [ug/sqrt(Hz)], truth and filter model alike.
    stats : dict
        density -> method -> :func:`campaign_stats` of its runs: ``t1``, ``t2`` (median
        convergence time of position 1, 2 [s]), ``t1_p95``, ``t2_p95`` (95th
        percentile [s]), ``az_p95`` (|azimuth error| [arcmin]), ``failed``, ``n``, ...
    crossing : dict
        method -> largest density [ug/sqrt(Hz)] at which the 95th percentile of the
        convergence time of both positions is within :data:`CONV_LIMIT`
        (:func:`largest_density_within`).
    scenario_density : float
        The scenario's own ``accel.noise_density`` [ug/sqrt(Hz)].
    quantum_density : float
        The filter's model of the pulse quantisation as a white-noise density,
        ``sqrt(dv_quantum^2 / (6 period))`` [ug/sqrt(Hz)].
    runs, seed : int
        Runs per density and method; campaign seed (the same runs at every density).
    g, lat : float
        The filter's gravity [m/s^2] and latitude [rad], for :func:`convergence_bound`.
    """

    densities: tuple[float, ...]
    stats: dict[float, dict[int, dict[str, float]]]
    crossing: dict[int, float]
    scenario_density: float
    quantum_density: float
    runs: int
    seed: int
    g: float
    lat: float


def noise_sensitivity(
    runs: int,
    seed: int,
    densities_ug: tuple[float, ...] = NOISE_DENSITIES,
    methods: tuple[int, ...] = (1, 2),
    *,
    stop: float | None = None,
    platform: dict[str, float] | None = None,
    workers: int = 1,
    prep: Prepared | None = None,
) -> NoiseSensitivity:
    """The paper-truth campaign at each accelerometer white-noise density.

    The paper gives no accelerometer noise; the scenario assumes 5 ug/sqrt(Hz), and the
    convergence time depends on it. At each density the truth's ``accel.noise_density``
    and the filter's model ``filter.accel_noise`` are set to the same value (the filter
    stays consistent with the truth); the runs have the same seeds at every density
    (the same normal draws, scaled). The pulse quantisation (``K1`` = 1e4 pulses per
    m/s, ``filter.dv_quantum`` = 1e-4 m/s) is unchanged.

    Theory: the azimuth comes from the ``t^2`` coefficient of the integrated
    accelerometer output (eq. 12-13: the platform tilts about east at ``Oc sin(delta_psi)``),
    i.e. from the slope ``-g Oc delta_psi`` of the measured specific force, fitted over
    ``t`` seconds of white noise of density ``N``::

        sigma_psi(t) = sqrt(12) N / (g Oc t^(3/2))

    so the error enters a fixed band (4') at a time ``t ~ N^(2/3)``, for the median run
    and the 95th percentile alike (8 / 2 ug/sqrt(Hz): x 2.52). Quantisation: the
    accumulated pulses are off the true velocity by less than one pulse (1e-4 m/s), an
    error that does not grow with time, and the filter models each period's increment as
    off by white noise of variance ``dv_quantum^2 / 6`` (4.2 ug/sqrt(Hz) equivalent at
    ``period`` = 1 s), so its own sigma goes as ``sqrt(N^2 + (4.2 ug/sqrt(Hz))^2)``. At low
    noise the pulse quantisation takes over and the ``N^(2/3)`` scaling flattens.

    Parameters
    ----------
    runs : int
        Runs per density and method.
    seed : int
        Campaign seed (:func:`run_seeds`; the same runs at every density).
    densities_ug : tuple of float
        White-noise densities [ug/sqrt(Hz)] (> 0).
    methods : tuple of int
        Filters (default UPF and KF; the EKF falls into the mirror solution anyway).
    stop : float, optional
        Stop time [s] (default: the scenario's).
    platform : dict, optional
        Platform parameters (SI) for every run (:func:`campaign`).
    workers : int
        Processes (1: this process).
    prep : Prepared, optional
        The scenario from :func:`prepared`.

    Returns
    -------
    NoiseSensitivity
    """
    if not densities_ug or not all(d > 0.0 for d in densities_ug):
        raise ValueError(f"densities_ug: expected values > 0, got {densities_ug!r}")
    prep = prep or prepared()
    base = prep.parameters or {}
    stats: dict[float, dict[int, dict[str, float]]] = {}
    scenario = float(base["accel"]["noise_density"]) / UG_SQRT_HZ
    filt = base["filter"]
    quantum = math.sqrt(float(filt["dv_quantum"]) ** 2 / (6.0 * float(filt["period"])))
    g, lat = float(filt["g"]), float(filt["lat"])
    for d in densities_ug:
        density = float(d) * UG_SQRT_HZ  # m/s/sqrt(s)
        over = {"accel": {"noise_density": density}, "filter": {"accel_noise": density}}
        res = campaign(
            runs, seed, methods, stop=stop, overrides=over, platform=platform,
            workers=workers, prep=prep,
        )  # fmt: skip
        stats[float(d)] = {m: campaign_stats(res[m]) for m in methods}
    dens = tuple(float(d) for d in densities_ug)
    crossing = {
        m: largest_density_within(
            dens, [float(np.max([stats[d][m]["t1_p95"], stats[d][m]["t2_p95"]])) for d in dens]
        )
        for m in methods
    }
    return NoiseSensitivity(
        dens, stats, crossing, scenario, quantum / UG_SQRT_HZ, int(runs), int(seed), g, lat
    )


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
        (:func:`noise_sensitivity`, ``runs`` runs of the campaign seed per density).
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
    # the report module imports this one (its constants and statistics)
    from cosim.reproduce.seed000_report import markdown, plots, sensitivity_plot

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
