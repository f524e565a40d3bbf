"""The error-model protocol: what a filter block offers to get an error budget.

A filter block class gets an error budget in every verification report by one class
method, :meth:`BudgetedFilter.budget_model`: given the run's facts (:class:`RunFacts`:
its own parameters, the other blocks' models and parameters, the master's times) it
returns its linear error model (:class:`LinearErrorModel`), a model that budgets
signals itself (:class:`SignalBudgetModel`), or None. The verifier
(:mod:`cosim.verify.budget`) knows no filter by name: it finds the scenario's blocks
whose class has ``budget_model`` and asks them.

A :class:`LinearErrorModel` is the filter's error state ``e`` (estimate minus truth,
``n`` states in SI units) with, per step ``k`` of length ``dt`` (step ``k`` covers
``[t0 + k dt, t0 + (k + 1) dt]``)::

    de/dt = F_k e + G_k w,     E[w w^T] = sum_s Qc_s delta(t)      (continuous, mid-step)
    z_k = H_k e + v,           E[v v^T] = sum_s R_s                 (after step k, or none)
    E[e_0 e_0^T] = sum_s P0_s

where ``s`` runs over the model's **budget lines** (its independent error sources:
"gyro drift E", "measurement noise (zero velocity)", ...): the split of ``P0``,
``Qc`` and ``R`` into lines is the model's statement of how its sources divide.
:func:`propagate` discretises each step exactly (:func:`cosim.estimation.van_loan`),
runs the one covariance loop (:func:`cosim.estimation.covariance.covariance_budget`)
with the filter's gain from the total and every line on its own, and returns the
parts, which add up to the total covariance. A requirement's signal ``block.variable``
is a linear function ``h e`` of the error (:meth:`LinearErrorModel.signal_row`), so
its variance splits as ``h P h^T = sum_s h P_s h^T``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from cosim.estimation.analysis import van_loan
from cosim.estimation.covariance import CovarianceBudget, covariance_budget

FloatArray = NDArray[np.float64]

#: The method a filter block class implements (:class:`BudgetedFilter`).
METHOD = "budget_model"


@dataclass(frozen=True)
class Regressor:
    """One regressor: a drawn source's value in every run.

    Attributes
    ----------
    name : str
        What it is (``"gyro drift E"``).
    unit : str
        Display unit of its values (``"deg/h"``).
    factor : float
        SI value of one display unit (``x_display = x_SI / factor``).
    values : ndarray, shape (runs,)
        Its value in each run [SI].
    direction : ndarray, shape (n,) or None
        ``d e_0 / d x``: how one SI unit of it enters the filter's initial estimation
        error (None when no linear model knows it).
    """

    name: str
    unit: str
    factor: float
    values: FloatArray
    direction: FloatArray | None = field(default=None, repr=False)


@dataclass(frozen=True)
class RunFacts:
    """What a filter's error model may read of the run (the scenario, built, not run).

    Attributes
    ----------
    block : str
        The filter block's name in the scenario.
    models : dict
        Every block's ``model = "..."`` name (empty for an FMU or a ``class`` block),
        ``{block: name}``, in file order.
    values : dict
        Every block's parameters, the file's values over the defaults, SI units
        (vectors as ``name[1]``, ``name[2]``, ...): ``{block: {parameter: value}}``.
    start, stop : float
        The run's start and stop time [s].
    step : float
        The master's macro step [s]; the block steps every ``rate`` macro steps.
    rate : int
        The filter block's rate (its step is ``rate * step``).
    path : Path
        The scenario file (a model that budgets by simulating reads it).
    requirements : sequence
        The requirements to budget (objects with ``id``, ``signal``, ``minus``,
        ``criterion``, ``at``, ``unit``); empty when unknown.
    error_signal : callable or None
        ``error_signal(requirement, result) -> (time, error, ...)``: a requirement's
        error over a run [its unit] (the verifier's definition), for a
        :class:`SignalBudgetModel`.
    scenario : Scenario or None
        The scenario as the caller parsed it (a model that simulates copies it rather
        than reading ``path`` again); None: read ``path``.
    """

    block: str
    models: Mapping[str, str]
    values: Mapping[str, Mapping[str, Any]]
    start: float
    stop: float
    step: float
    rate: int = 1
    path: Path | None = None
    requirements: Sequence[Any] = ()
    error_signal: Callable[..., tuple[Any, ...]] | None = None
    scenario: Any = None

    @property
    def parameters(self) -> Mapping[str, Any]:
        """The filter block's own parameters (SI, defaults filled)."""
        return self.values[self.block]

    def find(self, model: str) -> str | None:
        """The first block (file order) whose ``model = "..."`` is ``model``, or None.

        Parameters
        ----------
        model : str
            A model name (``"StationaryBase"``).

        Returns
        -------
        str or None
            The block's name.
        """
        return next((b for b, m in self.models.items() if m == model), None)

    def vector(self, block: str, name: str) -> FloatArray:
        """A 3-vector parameter ``name[1..3]`` of a block, shape (3,) [SI].

        Parameters
        ----------
        block : str
            Block name.
        name : str
            Parameter name without the index.

        Returns
        -------
        ndarray, shape (3,)
        """
        p = self.values[block]
        return np.array([float(p[f"{name}[{i}]"]) for i in (1, 2, 3)])


@dataclass(frozen=True)
class StepGrid:
    """The steps of a covariance analysis and the rows it keeps.

    Attributes
    ----------
    dt : float
        Step length [s].
    n_steps : int
        Number of steps.
    record_every : int
        Keep the covariance after every ``record_every``-th step.
    include_start : bool
        Also keep time 0.
    times : ndarray or None
        The kept rows' times [s after ``t0``], shape (m,); None: the loop's own,
        ``k dt`` after step ``k`` (:meth:`recorded_times`).
    """

    dt: float
    n_steps: int
    record_every: int = 1
    include_start: bool = True
    times: FloatArray | None = None

    def recorded_times(self) -> FloatArray:
        """The kept rows' times [s after ``t0``], shape (m,)."""
        if self.times is not None:
            return np.asarray(self.times, dtype=float)
        ks = range(self.record_every, self.n_steps + 1, self.record_every)
        return np.array(([0.0] if self.include_start else []) + [k * self.dt for k in ks])


@runtime_checkable
class LinearErrorModel(Protocol):
    """A filter's linear error model over one run (module docstring for the equations).

    Attributes
    ----------
    block : str
        The filter block's name.
    description : str
        What the model is, one sentence for the report.
    names : tuple of str
        State names, in order (``n`` of them).
    t0 : float
        Simulation time of the analysis' time 0 [s].
    grid : StepGrid
        Its steps and the rows it keeps.
    """

    block: str
    description: str
    t0: float

    @property
    def names(self) -> tuple[str, ...]:
        """State names, in order (read-only)."""
        ...

    @property
    def grid(self) -> StepGrid:
        """Its steps and the rows it keeps (read-only)."""
        ...

    def initial_covariance(self) -> dict[str, FloatArray]:
        """``P0`` split into budget lines.

        Returns
        -------
        dict
            ``{line: P0_s}``, each (n, n) [state SI units^2]; they add up to ``P0``.
        """
        ...

    def dynamics(self, k: int) -> tuple[FloatArray, FloatArray, dict[str, FloatArray]]:
        """The continuous error model at step ``k``'s midpoint.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) grid.dt`` after ``t0``).

        Returns
        -------
        F : ndarray, shape (n, n)
            ``de/dt = F e + G w`` [1/s in SI state units].
        G : ndarray, shape (n, q)
            Noise input.
        Qc : dict
            ``{line: Qc_s}``, each (q, q): the white-noise density of the line's part
            of ``w`` [input SI unit^2 * s]; a line may be absent (no noise of its own).
        """
        ...

    def step_key(self, k: int) -> Hashable:
        """A key of step ``k``: steps with equal keys have equal dynamics.

        Parameters
        ----------
        k : int
            Step index.

        Returns
        -------
        hashable
            :func:`propagate` discretises once per key (``k`` itself: no reuse).
        """
        ...

    def measurement(self, k: int) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """The filter's update after step ``k``, if it has one there.

        Parameters
        ----------
        k : int
            Step index.

        Returns
        -------
        tuple or None
            ``(H, {line: R_s})``: ``H`` (m, n), each ``R_s`` (m, m) [measurement SI
            unit^2], adding up to the filter's ``R``; None: no update after step ``k``.
        """
        ...

    def signal_row(self, variable: str, t: float) -> FloatArray | None:
        """The error of one of the block's outputs as a linear function of the error state.

        Parameters
        ----------
        variable : str
            An output of the filter block (``"rpy_err[3]"``).
        t : float
            Simulation time [s].

        Returns
        -------
        ndarray, shape (n,) or None
            ``h`` with ``error of block.variable = h e`` [output SI unit (rad) per state
            SI unit]; None when the output is not linear in the error state.
        """
        ...

    def regressors(self, draws: Mapping[str, FloatArray]) -> list[Regressor]:
        """The campaign's drawn parameters the model knows, with how they enter the error.

        Parameters
        ----------
        draws : mapping
            ``"block.name"`` -> ndarray (runs, size) [SI], the campaign's drawn parameters.

        Returns
        -------
        list of Regressor
            One per budget line the draws give (``[]`` if none).
        """
        ...


@runtime_checkable
class SignalBudgetModel(Protocol):
    """A filter's budget that it computes itself per requirement (e.g. first order, by
    simulating with each source switched off) when its estimates are not linear.

    Attributes
    ----------
    block : str
        The filter block's name.
    description : str
        What the model is, for the report.
    """

    block: str
    description: str

    def entry(self, requirement: Any, stop: float) -> dict[str, Any] | str:
        """One requirement's budget, or why there is none.

        Parameters
        ----------
        requirement : Requirement
            A requirement of the scenario (``id``, ``signal``, ``criterion``, ``at``,
            ``unit``).
        stop : float
            The run's stop time [s] (the default ``at``).

        Returns
        -------
        dict or str
            The entry (``model``, ``method``, ``time``, ``window``, ``reduction``,
            ``total``, ``parts``, ``sum_check``: see
            :func:`cosim.verify.budget.signal_budget`), or a one-line note.
        """
        ...


class BudgetedFilter(Protocol):
    """A filter block class that offers an error model (the method :data:`METHOD`)."""

    @classmethod
    def budget_model(cls, run: RunFacts) -> LinearErrorModel | SignalBudgetModel | None:
        """The block's error model for this run, or None when it has none here.

        Parameters
        ----------
        run : RunFacts
            The run's facts, ``run.block`` the block of this class.

        Returns
        -------
        LinearErrorModel, SignalBudgetModel or None
        """
        ...


def propagate(model: LinearErrorModel) -> CovarianceBudget:
    """The covariance of a linear error model split by budget line.

    Each step is discretised exactly (:func:`cosim.estimation.van_loan` of ``F, G`` and
    each line's ``Qc``; once per :meth:`LinearErrorModel.step_key`), then
    :func:`cosim.estimation.covariance.covariance_budget` runs the filter's loop with
    every line on its own.

    Parameters
    ----------
    model : LinearErrorModel
        The filter's model.

    Returns
    -------
    CovarianceBudget
        Times of :meth:`StepGrid.recorded_times` [s after ``model.t0``], states
        ``model.names``; the parts add up to the total.
    """
    grid = model.grid
    cache: dict[Hashable, tuple[FloatArray, dict[str, FloatArray]]] = {}

    def transition(k: int) -> tuple[FloatArray, dict[str, FloatArray]]:
        key = model.step_key(k)
        if key not in cache:
            F, G, Qc = model.dynamics(k)
            Qd: dict[str, FloatArray] = {}
            if not Qc:  # no process noise: Van Loan's Phi of a zero density
                Phi, _ = van_loan(F, G, np.zeros((G.shape[1], G.shape[1])), grid.dt)
            for s, q in Qc.items():
                Phi, Qd[s] = van_loan(F, G, q, grid.dt)  # the same Phi for every line
            cache[key] = (Phi, Qd)
        return cache[key]

    budget = covariance_budget(
        model.initial_covariance(),
        grid.n_steps,
        grid.dt,
        transition,
        model.measurement,
        record_every=grid.record_every,
        include_start=grid.include_start,
        names=tuple(model.names),
    )
    if grid.times is None:
        return budget
    return dataclasses.replace(budget, time=grid.recorded_times())
