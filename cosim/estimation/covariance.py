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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.estimation import joseph_update

FloatArray = NDArray[np.float64]

#: ``transition(k) -> (Phi, Qd)``: the discrete model of step ``k``, shapes (n, n).
Transition = Callable[[int], tuple[FloatArray, FloatArray]]
#: ``measurement(k) -> (H, R)`` after step ``k``, shapes (m, n) and (m, m), or None.
Measurement = Callable[[int], tuple[FloatArray, FloatArray] | None]


@dataclass(frozen=True)
class CovarianceHistory:
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

    def index(self, t: float) -> int:
        """Row of the recorded time nearest to ``t``.

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        int
            Index into :attr:`time` (and the first axis of :attr:`P`, :attr:`sigma`).
        """
        return int(np.argmin(np.abs(self.time - t)))

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
    if n_steps < 1 or record_every < 1:
        raise ValueError(
            f"n_steps and record_every: expected >= 1, got {n_steps} and {record_every}"
        )
    P = np.array(P0, dtype=float)
    zero = np.zeros(P.shape[0])
    times, Ps = ([0.0], [P.copy()]) if include_start else ([], [])
    for k in range(n_steps):
        Phi, Qd = transition(k)
        P = Phi @ P @ Phi.T + Qd
        upd = None if measurement is None else measurement(k)
        if upd is not None:
            H, R = upd
            _, P, _, _, _ = joseph_update(zero, P, np.zeros(H.shape[0]), H, R)
        if (k + 1) % record_every == 0:
            times.append((k + 1) * dt)
            Ps.append(P.copy())
    return CovarianceHistory(np.array(times), np.array(Ps), tuple(names))
