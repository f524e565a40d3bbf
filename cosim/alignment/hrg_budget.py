"""The HRG two-position filter's error budget: first order, with the linear KF's model.

The filter of the HRG two-position scenario (:mod:`cosim.alignment.hrg_two_position`) is
a UPF, an EKF or the KF on the paper's linear model (``method`` 2). Only the KF is
linear in its measurements: in each position its linear state ``[p, q]`` (initial tilt
and tilt rate in platform axes) is a linear function of the velocity increments. The
requirements' signals are not linear in that state: the azimuth and the drifts come
from eq. (16)-(21) (two positions combined through ``atan2`` and square roots), the
level errors from the tilt turned back by the two-position ``delta``. The budget is
therefore a **first-order** one, taken at the scenario's own truth:

- the **sensor errors of the truth** (initial level misalignment, the drifts D_E, D_N,
  D_A, the accelerometer bias) by switching each off in a noise-free co-simulation of
  the scenario, its filter set to the KF: a source's contribution is the change of the
  requirement's error at its time (one run with every source, one without each, one
  without any: seven runs); a deterministic error, added in quadrature (each source
  counted with its sign unknown, its value a 1-sigma);
- the **measurement noise** (accelerometer white noise, pulse quantisation: the truth's
  density and pulse weight, as the KF's ``R`` models them) through the KF's own gains
  (exact for the linear state) and the first-order propagation through the polar
  state, position 2's prior and eq. (16)-(21)
  (:func:`cosim.alignment.hrg_filters.kf_noise_budget`);
- what remains with no sensor error and no noise (the KF's prior pull, the model's
  neglected terms) as its own part ("model residual").

The parts' variances add to the total. The first-order assumption is checked in every
entry: ``linearity`` is the error of the run with all sources minus the sum of the
residual and the contributions, relative to the total 1-sigma.

This is the filter's :class:`cosim.estimation.error_model.SignalBudgetModel`: the block's
``budget_model`` returns :class:`HrgBudget` (the verifier asks it per requirement).
"""

from __future__ import annotations

import copy
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from cosim.estimation.error_model import RunFacts

#: Signal of the filter block -> index into :data:`cosim.alignment.hrg_filters.KF_OUTPUTS`
#: and its SI unit.
SIGNALS = {
    "azimuth_err": (0, "rad"),
    "azimuth_est": (0, "rad"),
    "theta_E_err": (1, "rad"),
    "theta_E_est": (1, "rad"),
    "theta_N_err": (2, "rad"),
    "theta_N_est": (2, "rad"),
    "D_N_est": (3, "rad/s"),
    "D_E_est": (4, "rad/s"),
}

#: The campaign's filter by ``method``.
METHOD_NAMES = {0: "the EKF", 1: "the UPF", 2: "the KF"}


class HrgBudget:
    """The first-order budget of every requirement of a seed 000 scenario (module docstring).

    Parameters
    ----------
    run : RunFacts
        The run: its scenario file (an HrgPlatform, HrgPlatformGyro and
        PlatformAccelerometer beside this filter block), the parameters with their
        defaults, the requirements to budget and the verifier's ``error_signal``.

    Attributes
    ----------
    block : str
        The filter block.
    description : str
        The model, for the report.
    which : str
        Which filter's model budgets the campaign's (stated first in the method text).
    result : RunResult or None
        The noise-free KF run with every sensor error (after the first :meth:`entry`).
    aligner : TwoPositionAligner
        The KF fed with that run's increments (its position starts, priors).
    windows : list of tuple
        Its filter windows (:func:`cosim.alignment.hrg_filters.kf_windows`).
    """

    def __init__(self, run: RunFacts) -> None:
        from cosim.scenario import load_scenario

        if run.path is None or run.error_signal is None:
            raise ValueError(
                "the HRG budget simulates the scenario: give its file and error_signal"
            )
        self.path = Path(run.path)
        scenario = copy.deepcopy(run.scenario) if run.scenario is not None else None
        scenario = scenario if scenario is not None else load_scenario(self.path)
        self.scenario = scenario
        self.values = run.values
        self.error_signal = run.error_signal
        self.block = run.block
        self.platform = run.find("HrgPlatform") or ""
        self.gyro = run.find("HrgPlatformGyro") or ""
        self.accel = run.find("PlatformAccelerometer") or ""
        method = int(run.values[self.block]["method"])
        self.which = (
            "the linear KF's model"
            if method == 2
            else f"the linear KF's model, the campaign's filter is "
            f"{METHOD_NAMES.get(method, 'another filter')}"
        )
        self.description = (
            "HRG two-position alignment with the linear KF's model (method 2: a KF on "
            "the paper's linear platform-frame model in each position), first-order "
            "through eq. (16)-(21)"
            + ("" if method == 2 else f"; the campaign's filter is {METHOD_NAMES.get(method)}")
        )
        self.requirements = list(run.requirements)
        self.sources: list[tuple[str, str, tuple[str, ...]]] = [
            (
                "initial level misalignment (theta_E0, theta_N0)",
                self.platform,
                ("theta_E0", "theta_N0"),
            ),
            ("drift D_E (x gyro)", self.gyro, ("drift[1]",)),
            ("drift D_N (y gyro)", self.gyro, ("drift[2]",)),
            ("drift D_A (z gyro: azimuth)", self.gyro, ("drift[3]",)),
            ("accelerometer bias (x, y)", self.accel, ("K0[1]", "K0[2]")),
        ]
        self._errors: dict[str, dict[str, float]] | None = None
        self._noise: tuple[np.ndarray, dict[str, np.ndarray], np.ndarray] | None = None
        self.result: Any = None
        self.aligner: Any = None
        self.windows: list[Any] = []

    # ------------------------------------------------------------------ simulations
    def _simulate(self, off: tuple[tuple[str, str], ...]) -> Any:
        from cosim.runs import make_run

        sc = self.scenario
        cols = {self.block, f"{self.accel}.dv_meas_p", f"{self.platform}"}
        for r in self.requirements:
            for c in (r.signal, r.minus, r.sigma):
                if c and c.split(".", 1)[0] not in (self.block, self.platform):
                    cols.add(c.split("[", 1)[0])
        sc.outputs = sorted(cols)
        params: dict[str, dict[str, Any]] = {
            self.block: {"method": 2},
            self.accel: {"noise_density": 0.0, **{f"K1[{k}]": 1e8 for k in (1, 2, 3)}},
            self.gyro: {"noise_density": 0.0},
        }  # the linear KF, no noise, no quantisation
        for block, name in off:
            params.setdefault(block, {})[name] = 0.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the feedback loop (shown by the campaign)
            return make_run(sc, overrides={"record_every": 1}, parameters=params)

    def _error_at(self, result: Any, req: Any, t: float) -> float:
        tt, e, *_ = self.error_signal(req, result)
        return float(np.interp(t, tt, e))

    def _compute(self) -> None:
        from cosim.alignment.hrg_filters import TwoPositionAligner, kf_windows

        stop = float(self.scenario.settings.stop)
        cases: dict[str, tuple[tuple[str, str], ...]] = {"all": ()}
        for label, block, names in self.sources:
            cases[label] = tuple((block, n) for n in names)
        cases["none"] = tuple(pair for v in list(cases.values()) for pair in v)
        self._errors = {}
        for case, off in cases.items():
            result = self._simulate(off)
            if case == "all":
                self.result = result
            self._errors[case] = {
                r.id: self._error_at(result, r, stop if r.at is None else r.at)
                for r in self.requirements
                if r.criterion == "value"
            }
        f = self.values[self.block]
        res = self.result
        aligner = TwoPositionAligner(
            method=2,
            lat=f["lat"],
            g=f["g"],
            period=f["period"],
            accel_noise=f["accel_noise"],
            dv_quantum=f["dv_quantum"],
            sigma_theta0=f["sigma_theta0"],
            sigma_drift=f["sigma_drift"],
            sigma_azimuth=f["sigma_azimuth"],
            azimuth0=f["azimuth0"],
            index_angle=f["index_angle"],
            sigma_index=f["sigma_index"],
        )
        dv = np.column_stack([res.data[f"{self.accel}.dv_meas_p[{k}]"] for k in (1, 2)])
        self.windows = kf_windows(
            aligner, np.asarray(res.time), dv, np.asarray(res.data[f"{self.platform}.position"])
        )
        self.aligner = aligner

    def noise(self, t: float) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """The measurement-noise parts at time ``t`` (see the module docstring).

        Parameters
        ----------
        t : float
            Time [s], in position 2.

        Returns
        -------
        tuple
            :func:`cosim.alignment.hrg_filters.kf_noise_budget`: estimate, parts, total
            (SI).
        """
        from cosim.alignment.hrg_filters import kf_noise_budget

        if self._errors is None:
            self._compute()
        a = self.values[self.accel]
        f = self.values[self.block]
        quantum = 1.0 / float(a["K1[1]"])
        noise = {
            "accelerometer white noise": float(a["noise_density"]) ** 2 * float(f["period"]),
            "pulse quantisation": quantum**2 / 6.0,
        }
        aligner = self.aligner
        aligner.r_var = sum(noise.values())  # the truth's noise, in the KF's R form
        return kf_noise_budget(aligner, self.windows, t, noise)

    # ------------------------------------------------------------------ per requirement
    def entry(self, req: Any, stop: float) -> dict[str, Any] | str:
        """One requirement's budget, or the reason there is none.

        Parameters
        ----------
        req : Requirement
            A requirement of the scenario (:class:`cosim.verify.requirements.Requirement`).
        stop : float
            The run's stop time [s] (the default ``at``).

        Returns
        -------
        dict or str
            The entry (:func:`cosim.verify.budget.requirement_budget`'s keys, plus per
            part ``signed``, the signed first-order error [unit], and ``linearity``), or
            a note.
        """
        from cosim.units import conversion_factor

        block, _, variable = req.signal.partition(".")
        if block != self.block or variable not in SIGNALS:
            return "no linear error model for this signal"
        if req.criterion != "value":
            return (
                "the two-position budget is taken at a requirement's time (a value criterion); "
                "this one is a window or a settling time"
            )
        at = stop if req.at is None else req.at
        if self._errors is None:
            self._compute()
        assert self._errors is not None
        if at <= self.aligner.starts.get(2, math.inf):
            return "the two-position budget needs the two-position solution (a time in position 2)"
        errors = self._errors
        signed = {
            label: errors["all"][req.id] - errors[label][req.id] for label, _, _ in self.sources
        }
        residual = errors["none"][req.id]
        k, si = SIGNALS[variable]
        factor = conversion_factor(si, req.unit)
        _, noise_parts, noise_total = self.noise(at)
        parts = [("model residual (no sensor error, no noise)", residual)]
        parts += list(signed.items())
        items: list[dict[str, Any]] = [
            {"source": s, "variance": v * v, "signed": v} for s, v in parts
        ]
        items += [
            {"source": s, "variance": float(p[k]) * factor**2, "signed": None}
            for s, p in noise_parts.items()
        ]
        var = residual**2 + sum(v * v for v in signed.values()) + float(noise_total[k]) * factor**2
        for it in items:
            it["sigma"] = math.sqrt(max(it["variance"], 0.0))
            it["share"] = it["variance"] / var if var > 0 else math.nan
        lin = errors["all"][req.id] - residual - sum(signed.values())
        return {
            "model": self.description,
            "method": (
                f"{self.which}: first-order propagation (a linearisation) through the two-position "
                "combination, eq. (16)-(21): each truth sensor error switched off in a "
                "noise-free co-simulation with the linear KF (its contribution the change "
                "of the error at the time; values added in quadrature, the sign taken as "
                "unknown); the measurement noises through the linear KF's gains, the "
                "polar state and position 2's prior (Jacobians at the noise-free run); "
                "the campaign's randomness is only the noise"
            ),
            "time": float(at),
            "window": [float(at), float(at)],
            "reduction": f"at {at:g} s",
            "total": {"variance": var, "sigma": math.sqrt(max(var, 0.0))},
            "parts": items,
            "sum_check": sum(it["variance"] for it in items) / var - 1.0 if var > 0 else 0.0,
            "linearity": lin / math.sqrt(var) if var > 0 else 0.0,
        }
