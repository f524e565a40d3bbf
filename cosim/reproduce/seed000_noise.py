"""Seed 000: the convergence time's sensitivity to the assumed accelerometer noise.

The paper gives no accelerometer noise; :func:`noise_sensitivity` runs the paper-truth
campaign of :mod:`cosim.reproduce.seed000_runs` at several densities, and
:func:`convergence_bound` gives the Cramer-Rao time no unbiased estimator can beat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.models.constants import ARCMIN, OMEGA_IE
from cosim.reproduce.seed000_runs import (
    CONV_BAND,
    CONV_LIMIT,
    NOISE_DENSITIES,
    UG_SQRT_HZ,
    campaign,
    campaign_stats,
    prepared,
)
from cosim.verify.campaign import Prepared


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
