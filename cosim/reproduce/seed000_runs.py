"""The seed 000 reproduction's runs: the campaigns, each run's metrics and their statistics.

The reproduction (:mod:`cosim.reproduce.seed000`) of HRG platform two-position
self-alignment, UPF against EKF:

Runs ``scenarios/hrg_two_position.toml`` (truth: :class:`models.blocks.hrg_platform.HrgPlatform`
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
   densities of 1-8 ug/sqrt(Hz), truth and filter model alike (:mod:`.seed000_noise`):
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
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.master import CouplingWarning
from cosim.models.constants import ARCMIN, OMEGA_IE
from cosim.models.constants import DEG_PER_HOUR as DEG_H
from cosim.models.conventions import wrap_angle
from cosim.package_data import scenario_file
from cosim.units import conversion_factor
from cosim.verify.campaign import CampaignError, Prepared, prepare, simulate
from cosim.verify.seeds import run_seeds
from cosim.verify.workers import Job

SCENARIO = scenario_file("hrg_two_position.toml")
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
