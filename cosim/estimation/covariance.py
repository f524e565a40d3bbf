"""Linear covariance analysis: the one loop every filter's analysis runs, and its history.

A covariance analysis propagates the covariance of a linear(ised) filter without
simulating anything: every step ``k`` (length ``dt``) ::

    P <- Phi_k P Phi_k^T + Qd_k
    P <- Joseph update with (H_k, R_k)          when step k ends with a measurement

The update is the estimators' own :func:`cosim.estimation.joseph_update` (with a zero
innovation: only ``P`` matters), so an analysis and a filter built on the same model
give the same covariance. The filters supply ``Phi_k, Qd_k`` (e.g. Van Loan of their
error model at mid-step) and ``H_k, R_k``; see
:func:`cosim.alignment.static_model.static_covariance` and
:func:`cosim.alignment.transfer_analysis.transfer_covariance`.

There is one loop: :func:`covariance_budget` runs it with the noise split by error
source, :func:`covariance_analysis` runs the same loop with one source and keeps the
total only (its sums then add a zero matrix to ``P0``, ``Qd`` and ``R``, which is
exact, so the total is the budget's total to the bit).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.estimation import joseph_update

FloatArray = NDArray[np.float64]

#: ``transition(k) -> (Phi, Qd)``: the discrete model of step ``k``, shapes (n, n).
Transition = Callable[[int], tuple[FloatArray, FloatArray]]
#: ``measurement(k) -> (H, R)`` after step ``k``, shapes (m, n) and (m, m), or None.
Measurement = Callable[[int], tuple[FloatArray, FloatArray] | None]


class _Recorded:
    """What a covariance history and a budget share: the recorded times and their rows."""

    time: FloatArray

    def index(self, t: float) -> int:
        """Row of the recorded time nearest to ``t``.

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        int
            Index into :attr:`time` (and the first axis of the recorded arrays).
        """
        return int(np.argmin(np.abs(self.time - t)))


@dataclass(frozen=True)
class CovarianceHistory(_Recorded):
    """A filter's covariance over time, as recorded by :func:`covariance_analysis`.

    ``at(t)`` is the covariance matrix and ``index(t)`` its row, both at the recorded
    time nearest to ``t``.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Recorded times [s] (from the start of the analysis).
    P : ndarray, shape (m, n, n)
        Covariance at each time (posterior where a measurement ended the step), in the
        states' units squared.
    names : tuple of str
        State names, in order (empty when not given).
    """

    time: FloatArray
    P: FloatArray
    names: tuple[str, ...] = ()

    @property
    def sigma(self) -> FloatArray:
        """1-sigma of every state at every recorded time, shape (m, n) (states' units)."""
        return np.sqrt(np.diagonal(self.P, axis1=1, axis2=2))

    def at(self, t: float) -> FloatArray:
        """Covariance matrix at the recorded time nearest to ``t``.

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        ndarray, shape (n, n)
            ``P[index(t)]``.
        """
        return self.P[self.index(t)]


def covariance_analysis(
    P0: ArrayLike,
    n_steps: int,
    dt: float,
    transition: Transition,
    measurement: Measurement | None = None,
    *,
    record_every: int = 1,
    include_start: bool = True,
    names: tuple[str, ...] = (),
) -> CovarianceHistory:
    """Propagate and update a covariance over ``n_steps`` steps of ``dt`` (module docstring).

    Parameters
    ----------
    P0 : array_like, shape (n, n)
        Initial covariance.
    n_steps : int
        Number of steps.
    dt : float
        Step length [s] (sets the recorded times ``(k + 1) dt``).
    transition : callable
        ``transition(k) -> (Phi, Qd)`` of step ``k``, shapes (n, n).
    measurement : callable, optional
        ``measurement(k) -> (H, R)`` of the update at the end of step ``k``, or None
        for no update (default: no updates at all).
    record_every : int
        Record after every ``record_every``-th step.
    include_start : bool
        Also record ``P0`` at time 0.
    names : tuple of str
        State names for the history.

    Returns
    -------
    CovarianceHistory

    Raises
    ------
    ValueError
        When ``n_steps < 1`` or ``record_every < 1``.
    """

    def split_transition(k: int) -> tuple[FloatArray, dict[str, FloatArray]]:
        Phi, Qd = transition(k)
        return Phi, {"": Qd}

    def split_measurement(k: int) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        upd = None if measurement is None else measurement(k)
        return None if upd is None else (upd[0], {"": upd[1]})

    # One source: the loop's sums add a zero matrix to P0, Qd and R, which is exact.
    times, total, _, _ = _covariance_loop(
        {"": P0},
        n_steps,
        dt,
        split_transition,
        split_measurement,
        record_every,
        include_start,
        split=False,
    )
    return CovarianceHistory(times, total, tuple(names))


# ----------------------------------------------------------------------- error budgets
#: ``budget_transition(k) -> (Phi, {source: Qd})``: step ``k``'s model, noise split by source.
BudgetTransition = Callable[[int], tuple[FloatArray, dict[str, FloatArray]]]
#: ``budget_measurement(k) -> (H, {source: R})`` after step ``k``, or None.
BudgetMeasurement = Callable[[int], tuple[FloatArray, dict[str, FloatArray]] | None]


@dataclass(frozen=True)
class CovarianceBudget(_Recorded):
    """A covariance analysis split by error source (:func:`covariance_budget`).

    The filter is linear, so its estimation error is a sum of independent
    contributions, one per source: ``P(t) = sum_s P_s(t)`` exactly.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Recorded times [s].
    total : ndarray, shape (m, n, n)
        The filter's covariance (the same as :func:`covariance_analysis` gives).
    parts : dict
        Source name -> its part of the covariance, shape (m, n, n), in the insertion
        order of the sources.
    transfer : ndarray, shape (m, n, n)
        ``T(t)``: the estimation error at ``t`` caused by an initial estimation error
        ``e_0`` is ``T(t) e_0`` (the deterministic part of the error dynamics; a random
        constant such as a sensor bias is an initial error of its state).
    names : tuple of str
        State names, in order.
    """

    time: FloatArray
    total: FloatArray
    parts: dict[str, FloatArray]
    transfer: FloatArray
    names: tuple[str, ...] = ()

    def variances(self, h: ArrayLike) -> tuple[FloatArray, dict[str, FloatArray]]:
        """Variance of a linear function ``y = h e`` of the error, total and per source.

        Parameters
        ----------
        h : array_like, shape (n,)
            Row vector mapping the error state to the signal (signal unit per state unit).

        Returns
        -------
        total : ndarray, shape (m,)
            ``h P(t) h^T`` at every recorded time [signal unit^2].
        parts : dict
            Source -> ``h P_s(t) h^T``, shape (m,).
        """
        row = np.asarray(h, dtype=float)
        total = np.einsum("i,mij,j->m", row, self.total, row)
        return total, {s: np.einsum("i,mij,j->m", row, P, row) for s, P in self.parts.items()}


def covariance_budget(
    P0_parts: Mapping[str, ArrayLike],
    n_steps: int,
    dt: float,
    transition: BudgetTransition,
    measurement: BudgetMeasurement | None = None,
    *,
    record_every: int = 1,
    include_start: bool = True,
    names: tuple[str, ...] = (),
) -> CovarianceBudget:
    """Covariance analysis with every error source propagated on its own.

    The filter's gain ``K`` comes from the total covariance, as in the filter. Each
    source's part then obeys the same linear recursion with only its own input::

        P_s <- Phi P_s Phi^T + Qd_s                     (propagation)
        P_s <- (I - K H) P_s (I - K H)^T + K R_s K^T    (update, Joseph form)

    with ``P_s(0)`` its block of ``P0``. Summed over the sources this is the total
    recursion term by term, so the parts add up to the total to rounding. The transfer
    matrix ``T`` obeys ``T <- Phi T`` and ``T <- (I - K H) T`` from ``T(0) = I``.

    Parameters
    ----------
    P0_parts : dict
        Source -> its part of the initial covariance, shape (n, n); they sum to ``P0``.
    n_steps : int
        Number of steps.
    dt : float
        Step length [s].
    transition : callable
        ``transition(k) -> (Phi, {source: Qd_s})``, shapes (n, n); the ``Qd_s`` sum to
        the step's ``Qd`` (Van Loan's ``Qd`` is linear in ``Qc``).
    measurement : callable, optional
        ``measurement(k) -> (H, {source: R_s})`` of the update after step ``k`` (shapes
        (m, n), (m, m); the ``R_s`` sum to ``R``), or None for no update.
    record_every : int
        Record after every ``record_every``-th step.
    include_start : bool
        Also record time 0.
    names : tuple of str
        State names.

    Returns
    -------
    CovarianceBudget

    Raises
    ------
    ValueError
        When ``n_steps < 1`` or ``record_every < 1``.
    """
    times, total, parts, transfer = _covariance_loop(
        P0_parts, n_steps, dt, transition, measurement, record_every, include_start, split=True
    )
    return CovarianceBudget(times, total, parts, transfer, tuple(names))


def _covariance_loop(
    P0_parts: Mapping[str, ArrayLike],
    n_steps: int,
    dt: float,
    transition: BudgetTransition,
    measurement: BudgetMeasurement | None,
    record_every: int,
    include_start: bool,
    *,
    split: bool,
) -> tuple[FloatArray, FloatArray, dict[str, FloatArray], FloatArray]:
    """The one covariance loop (:func:`covariance_budget`'s recursion).

    Returns the recorded times, totals, parts and transfer matrices; with
    ``split=False`` only the total is propagated (parts empty, transfer matrices
    not computed: an empty array).
    """
    if n_steps < 1 or record_every < 1:
        raise ValueError(
            f"n_steps and record_every: expected >= 1, got {n_steps} and {record_every}"
        )
    parts = {s: np.array(P, dtype=float) for s, P in P0_parts.items()}
    P = sum(parts.values(), np.zeros_like(next(iter(parts.values()))))
    n = P.shape[0]
    if not split:
        parts = {}
    T = np.eye(n)
    zero = np.zeros(n)

    def add(source: str) -> None:
        if split and source not in parts:  # a source that starts with no initial part
            parts[source] = np.zeros((n, n))
            rec_parts[source] = [np.zeros((n, n))] * len(rec_total)

    rec_total: list[FloatArray] = []
    rec_parts: dict[str, list[FloatArray]] = {s: [] for s in parts}
    rec_T: list[FloatArray] = []
    times: list[float] = []

    def record(t: float) -> None:
        times.append(t)
        rec_total.append(P.copy())
        if split:
            rec_T.append(T.copy())
        for s, Ps in parts.items():
            rec_parts[s].append(Ps.copy())

    if include_start:
        record(0.0)
    for k in range(n_steps):
        Phi, Qd = transition(k)
        for s in Qd:
            add(s)
        P = Phi @ P @ Phi.T + sum(Qd.values(), np.zeros((n, n)))
        if split:
            T = Phi @ T
        for s, Ps in parts.items():
            parts[s] = Phi @ Ps @ Phi.T + Qd.get(s, 0.0)
        upd = None if measurement is None else measurement(k)
        if upd is not None:
            H, Rs = upd
            for s in Rs:
                add(s)
            R = sum(Rs.values(), np.zeros((H.shape[0], H.shape[0])))
            _, P, K, _, _ = joseph_update(zero, P, np.zeros(H.shape[0]), H, R)
            if split:
                A = np.eye(n) - K @ H
                T = A @ T
            for s, Ps in parts.items():
                Pn = A @ Ps @ A.T
                if s in Rs:
                    Pn = Pn + K @ Rs[s] @ K.T
                parts[s] = 0.5 * (Pn + Pn.T)
        if (k + 1) % record_every == 0:
            record((k + 1) * dt)
    return (
        np.array(times),
        np.array(rec_total),
        {s: np.array(v) for s, v in rec_parts.items()},
        np.array(rec_T),
    )
