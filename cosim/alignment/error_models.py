"""The static and transfer filters' error models for the budget, read from a run's facts.

Each function here is one filter block's ``budget_model``
(:class:`cosim.estimation.error_model.BudgetedFilter`): it reads the run
(:class:`~cosim.estimation.error_model.RunFacts`: the block's parameters, the base,
turntable, ship, lever arm and IMU blocks of the scenario) and returns a
:class:`~cosim.estimation.error_model.LinearErrorModel` made of the filter's budget
lines (:class:`cosim.alignment.static_model.StaticLines`,
:class:`cosim.alignment.transfer_analysis.TransferLines`) and the scenario's half:
the requirement signals' rows and the drawn parameters' directions.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from cosim.estimation.error_model import Regressor, RunFacts, StepGrid

FloatArray = NDArray[np.float64]


class BudgetLines(Protocol):
    """The numerical half of a linear error model (see :class:`ScenarioErrorModel`)."""

    @property
    def names(self) -> tuple[str, ...]:
        """State names, in order."""
        ...

    @property
    def grid(self) -> StepGrid:
        """Its steps."""
        ...

    def initial_covariance(self) -> dict[str, FloatArray]:
        """P0 by line."""
        ...

    def dynamics(self, k: int) -> tuple[FloatArray, FloatArray, dict[str, FloatArray]]:
        """F, G and Qc by line at step ``k``.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        ...

    def step_key(self, k: int) -> Hashable:
        """Cache key of step ``k``.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        ...

    def measurement(self, k: int) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """H and R by line after step ``k``.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        ...


@dataclass(frozen=True)
class ScenarioErrorModel:
    """A :class:`~cosim.estimation.error_model.LinearErrorModel` from budget lines and a
    scenario: the lines' numbers, the signals' rows and the drawn parameters.

    Attributes
    ----------
    block : str
        The filter block.
    description : str
        What the model is (for the report).
    t0 : float
        Simulation time of the lines' time 0 [s].
    lines : BudgetLines
        :class:`~cosim.alignment.static_model.StaticLines` or
        :class:`~cosim.alignment.transfer_analysis.TransferLines`.
    row : callable
        ``row(variable, t) -> h`` (n,) or None (:meth:`signal_row`).
    drawn : callable
        ``drawn(draws) -> list of Regressor`` (:meth:`regressors`).
    """

    block: str
    description: str
    t0: float
    lines: BudgetLines
    row: Callable[[str, float], FloatArray | None]
    drawn: Callable[[Mapping[str, FloatArray]], list[Regressor]]

    @property
    def names(self) -> tuple[str, ...]:
        """State names."""
        return tuple(self.lines.names)

    @property
    def grid(self) -> StepGrid:
        """The lines' steps."""
        return self.lines.grid

    def initial_covariance(self) -> dict[str, FloatArray]:
        """P0 by line, each (n, n) [SI^2]."""
        return self.lines.initial_covariance()

    def dynamics(self, k: int) -> tuple[FloatArray, FloatArray, dict[str, FloatArray]]:
        """``F`` (n, n), ``G`` (n, q), ``{line: Qc}`` at step ``k``'s midpoint.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return self.lines.dynamics(k)

    def step_key(self, k: int) -> Hashable:
        """Steps of equal key have equal dynamics.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return self.lines.step_key(k)

    def measurement(self, k: int) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """``H`` and ``{line: R}`` after step ``k``, or None.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return self.lines.measurement(k)

    def signal_row(self, variable: str, t: float) -> FloatArray | None:
        """The signal's row over the error state at simulation time ``t`` (n,), or None.

        Parameters
        ----------
        variable : str
            An output of the filter block (``"rpy_err[3]"``).
        t : float
            Simulation time [s].
        """
        return self.row(variable, t)

    def regressors(self, draws: Mapping[str, FloatArray]) -> list[Regressor]:
        """The drawn parameters the model knows, with their directions.

        Parameters
        ----------
        draws : mapping
            ``"block.name"`` -> ndarray (runs, size) [SI], the campaign's drawn parameters.
        """
        return self.drawn(draws)


def _step(period: float) -> float:
    """0.1 s if it divides the update period, else the period itself."""
    k = period / 0.1
    return 0.1 if k >= 1 and abs(k - round(k)) < 1e-9 else period


def static_error_model(run: RunFacts) -> ScenarioErrorModel | None:
    """The 10-state psi-angle KF's model in a run (the SinsStaticAlignment block).

    The sensor errors split along north, east and down on a fixed base, along the
    table axes on a turntable (:func:`cosim.alignment.static_model.static_sources`);
    time 0 is the start of fine alignment.

    The swaying-base self-alignment (``init_mode = 2``) starts its fine filter from the
    inertial coarse theory's correlated covariance, on a specific force that sways and
    with the lever arm in the update: this model is not that filter's, so it has none
    (the report says so rather than give a budget that is not the filter's).

    Parameters
    ----------
    run : RunFacts
        The run (a ``StationaryBase``, optionally a ``Turntable`` and a ``StrapdownImu``).

    Returns
    -------
    ScenarioErrorModel or None
        None for ``init_mode = 2``.
    """
    from cosim.alignment.nav import euler_rate_matrix_inv
    from cosim.alignment.static_model import FilterTuning, static_lines, table_dcm
    from cosim.models.blocks.turntable import Turntable
    from cosim.models.constants import DEG_PER_HOUR, MICRO_G
    from cosim.models.conventions import euler_to_dcm_3

    a = run.parameters
    if int(a["init_mode"]) == 2:
        return None
    tuning = FilterTuning.from_parameters(a)
    base = run.find("StationaryBase")
    base_rpy = run.vector(base, "rpy0") if base else np.zeros(3)
    t0 = float(a["coarse_time"]) if int(a["init_mode"]) == 0 else 0.0
    t0 += float(run.start)
    table = run.find("Turntable")
    angle = None
    if table is not None:
        tp = run.values[table]
        profile = Turntable(instance_name="budget")
        for name in ("mode", "angle0", "rate", "reversal_period", "rotation_start"):
            setattr(profile, name, tp[name])
        profile.accel_limit = tp["accel_limit"]

        def angle(t: FloatArray, p: Turntable = profile) -> FloatArray:
            return p.profile(np.asarray(t, dtype=float) + t0)[0]

    kf = float(a["kf_period"])
    t_end = round((float(run.stop) - t0) / kf) * kf
    lines = static_lines(
        t_end,
        tuning=tuning,
        lat=float(a["lat"]),
        h=float(a["h"]),
        dt=kf,
        kf_period=kf,
        angle=angle,
        base_rpy=base_rpy,
        coriolis=True,
        record_every=max(1, int(round(1.0 / kf))),
    )
    c_b_n = euler_to_dcm_3(base_rpy)
    c_s_t = euler_to_dcm_3(run.vector(run.block, "mount_rpy"))
    gamma0 = 0.0 if angle is None else float(angle(np.zeros(1))[0])
    c_t_n = c_b_n @ table_dcm(gamma0)
    m_rpy = euler_rate_matrix_inv(base_rpy)

    def row(variable: str, t: float) -> FloatArray | None:
        h = np.zeros(10)
        for name, m in (("rpy_err", m_rpy), ("phi_err", np.eye(3))):
            for k in range(3):
                if variable == f"{name}[{k + 1}]":
                    h[2:5] = -m[k]  # estimate minus truth = -psi (residual)
                    return h
        return None

    imu = run.find("StrapdownImu")

    def drawn(draws: Mapping[str, FloatArray]) -> list[Regressor]:
        out: list[Regressor] = []
        for key, (state, label, unit, factor, axes) in {
            f"{imu}.gyro_bias": (slice(7, 10), "gyro drift", "deg/h", DEG_PER_HOUR, "NED"),
            f"{imu}.accel_bias": (slice(5, 7), "accelerometer bias", "ug", MICRO_G, "NE"),
        }.items():
            if key not in draws:
                continue
            x_s = draws[key]  # sensor axes, SI
            if angle is None:  # fixed base: along north, east, down
                x_n = x_s @ (c_t_n @ c_s_t).T
                for k, ax in enumerate(axes):
                    d = np.zeros(10)
                    d[state] = c_t_n.T[: state.stop - state.start, k]
                    out.append(Regressor(f"{label} {ax}", unit, factor, x_n[:, k], d))
            else:  # turntable: table axes
                x_t = x_s @ c_s_t.T
                for k, ax in enumerate("xyz"[: state.stop - state.start]):
                    d = np.zeros(10)
                    d[state.start + k] = 1.0
                    out.append(Regressor(f"{label} {ax} (table)", unit, factor, x_t[:, k], d))
        return out

    where = "a turntable" if angle is not None else "a fixed base"
    return ScenarioErrorModel(
        run.block,
        "seed 003 10-state psi-angle KF on " + where + " (cosim.alignment.static_model."
        "static_budget: Van Loan every kf_period, Joseph updates, the block's P0, Q, R)",
        t0,
        lines,
        row,
        drawn,
    )


def transfer_error_model(run: RunFacts) -> ScenarioErrorModel | None:
    """The transfer filter's small-error model in a run (the TransferAlignment block).

    The model along the ship's closed-form motion (an ideal linear filter on the same
    data, not the block's two-stage bookkeeping); sensor errors per slave axis.

    With attitude matching or lag estimation (``matching`` > 0, ``estimate_lag = 1``) the
    block runs :class:`cosim.alignment.transfer_matching.MatchingFilter`, whose states
    and measurements this velocity-matching model lacks: then there is none.

    Parameters
    ----------
    run : RunFacts
        The run (a ``ShipMotion``, optionally a ``LeverArm``, a ``StrapdownImu``).

    Returns
    -------
    ScenarioErrorModel or None
        None with attitude matching or lag estimation.
    """
    from cosim.alignment.nav import euler_rate_matrix_inv
    from cosim.alignment.transfer_analysis import ship_truth, transfer_lines
    from cosim.alignment.transfer_model import StateLayout, TransferTuning
    from cosim.models.constants import DEG_PER_HOUR, MICRO_G

    a = run.parameters
    if int(a["matching"]) != 0 or int(a["estimate_lag"]) != 0:
        return None
    tuning = TransferTuning(
        p0_pos=float(a["p0_pos"]),
        p0_vel=float(a["p0_vel"]),
        p0_level=float(a["p0_level"]),
        p0_heading=float(a["p0_heading"]),
        p0_accel_bias=float(a["p0_accel_bias"]),
        p0_gyro_drift=float(a["p0_gyro_drift"]),
        q_accel=float(a["q_accel"]),
        q_gyro=float(a["q_gyro"]),
        r_vel=float(a["r_vel"]),
        flex_tau=tuple(run.vector(run.block, "flexure_tau")),
        flex_sigma=tuple(run.vector(run.block, "flexure_sigma")),
    )
    ship_block = run.find("ShipMotion") or ""
    lever = run.find("LeverArm")
    mount = run.vector(lever, "mount_rpy") if lever else np.zeros(3)
    flexure = bool(int(a["flexure_states"]))
    layout = StateLayout(flexure)
    lat = float(run.values[ship_block]["lat0"])
    kw: dict[str, Any] = {
        "lat": lat,
        "amp": run.vector(ship_block, "amp"),
        "period": run.vector(ship_block, "period"),
    }
    t0 = float(run.start)
    period = float(a["period"])
    lines = transfer_lines(
        float(run.stop) - t0,
        r0=run.vector(run.block, "r0"),
        mount_rpy=mount,
        tuning=tuning,
        flexure=flexure,
        update_period=period,
        dt=_step(period),
        **kw,
    )
    m_rel = euler_rate_matrix_inv(mount)

    def row(variable: str, t: float) -> FloatArray | None:
        c_b_n = ship_truth([t - t0], **kw)["C_b_n"][0]
        for k in range(3):
            if variable == f"rpy_err[{k + 1}]":
                h = np.zeros(layout.n)
                h[layout.att] = (m_rel @ c_b_n.T)[k]
                return h
        return None

    imu = run.find("StrapdownImu")

    def drawn(draws: Mapping[str, FloatArray]) -> list[Regressor]:
        out: list[Regressor] = []
        for key, (state, label, unit, factor) in {
            f"{imu}.accel_bias": (layout.nabla, "accelerometer bias", "ug", MICRO_G),
            f"{imu}.gyro_bias": (layout.eps, "gyro drift", "deg/h", DEG_PER_HOUR),
        }.items():
            if key in draws:
                for k, ax in enumerate("xyz"):
                    d = np.zeros(layout.n)
                    d[state.start + k] = 1.0
                    out.append(Regressor(f"{label} {ax}", unit, factor, draws[key][:, k], d))
        return out

    return ScenarioErrorModel(
        run.block,
        "seed 001 small-error model along the ship's closed-form motion "
        f"({'with' if flexure else 'without'} flexure states; cosim.alignment."
        "transfer_analysis.transfer_budget: an ideal linear filter on the same data, "
        "Van Loan steps, velocity matching every period)",
        t0,
        lines,
        row,
        drawn,
    )
