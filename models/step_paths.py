"""Step conventions, and the paths of inputs inside a step rebuilt from step-end values.

A block's ``do_step(t, h)`` advances from ``t`` to ``t + h``. Outputs named as
states (``rpy``, ``omega_ib_b``, ``f_b``, ...) are values at ``t + h``; outputs
named ``d...`` (``dtheta_b``, ``dv_b``) are plain integrals over ``[t, t + h]``
(no coning or sculling terms: what an ideal IMU delivers). Inputs follow the
same rule (the master's default Gauss-Seidel order delivers a source's step-end
values and its increments over the same step). Where a block needs an input's
path inside the step it rebuilds it from the step-end value, the step-end
derivative when one is connected, and the increment, with the functions of this
module; fine inner grids use ``n = max(1, round(h / dt_truth))`` sub-steps (an
integer count, never accumulated floating time, :func:`substeps`).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike


def substeps(h: float, dt_truth: float) -> int:
    """Number of inner sub-steps ``n = max(1, round(h / dt_truth))`` (an integer).

    Parameters
    ----------
    h : float
        Communication step [s].
    dt_truth : float
        Wanted inner (truth) step [s]; ``<= 0`` gives one sub-step.

    Returns
    -------
    int
        ``n >= 1``; the sub-step is ``h / n``.
    """
    if not dt_truth > 0.0:
        return 1
    return max(1, int(round(h / dt_truth)))


def simpson_nodes(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Composite Simpson rule on ``[0, 1]`` with ``n`` sub-intervals.

    Parameters
    ----------
    n : int
        Number of sub-steps (>= 1); each gets a mid node.

    Returns
    -------
    s : ndarray, shape (2n + 1,)
        Nodes ``k / (2n)``.
    w : ndarray, shape (2n + 1,)
        Weights summing to 1: multiply by the step ``h`` to integrate over ``[t, t + h]``.
    """
    m = 2 * n
    s = np.arange(m + 1) / m
    w = np.full(m + 1, 2.0)
    w[1::2] = 4.0
    w[0] = w[-1] = 1.0
    return s, w / (3.0 * m)


def step_quadratic(
    end: ArrayLike, end_rate: ArrayLike, increment: ArrayLike, h: float, s: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic path over a step from its end value, end derivative and integral.

    ``x(s h) = x1 + x1' h (s - 1) + c (s - 1)^2`` with ``c`` chosen so that
    ``integral_0^h x dt = increment``; exact when ``x`` is quadratic in time.

    Parameters
    ----------
    end : array_like, shape (3,)
        ``x(t + h)``.
    end_rate : array_like, shape (3,)
        ``x'(t + h)`` (per second).
    increment : array_like, shape (3,)
        ``integral of x over [t, t + h]``.
    h : float
        Step [s].
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    x : ndarray, shape (m, 3)
        Values at the nodes.
    x_dot : ndarray, shape (m, 3)
        Time derivatives at the nodes (per second).
    """
    x1 = np.asarray(end, dtype=float)
    d1 = np.asarray(end_rate, dtype=float) * h
    c = 3.0 * (np.asarray(increment, dtype=float) / h - x1 + 0.5 * d1)
    u = (np.asarray(s, dtype=float) - 1.0)[:, None]
    return x1 + d1 * u + c * u * u, (d1 + 2.0 * c * u) / h


def step_linear(
    end: ArrayLike, increment: ArrayLike, h: float, s: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Linear path over a step from its end value and integral (exact for linear ``x``).

    ``x(s h) = x1 + b (s - 1)`` with ``b = 2 (x1 - increment / h)``.

    Parameters
    ----------
    end : array_like, shape (3,)
        ``x(t + h)``.
    increment : array_like, shape (3,)
        ``integral of x over [t, t + h]``.
    h : float
        Step [s].
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    x : ndarray, shape (m, 3)
        Values at the nodes.
    x_dot : ndarray, shape (m, 3)
        The (constant) slope, per second.
    """
    x1 = np.asarray(end, dtype=float)
    b = 2.0 * (x1 - np.asarray(increment, dtype=float) / h)
    u = (np.asarray(s, dtype=float) - 1.0)[:, None]
    return x1 + b * u, np.broadcast_to(b / h, (u.shape[0], x1.shape[-1])).copy()


def step_hermite(
    x0: ArrayLike, xd0: ArrayLike, x1: ArrayLike, xd1: ArrayLike, h: float, s: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite path over a step from end values and end derivatives.

    Parameters
    ----------
    x0, xd0 : array_like, shape (3,)
        Value and time derivative at ``t``.
    x1, xd1 : array_like, shape (3,)
        Value and time derivative at ``t + h``.
    h : float
        Step [s].
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    x, x_dot, x_ddot : ndarray, shape (m, 3)
        Value and first and second time derivatives at the nodes. ``x_dot``
        integrates to ``x1 - x0`` and ``x_ddot`` to ``xd1 - xd0`` exactly.
    """
    s = np.ascontiguousarray(s, dtype=float)
    b0, b1, b2 = _hermite_basis(s.tobytes())
    p = np.array([x0, np.asarray(xd0, dtype=float) * h, x1, np.asarray(xd1, dtype=float) * h])
    return b0 @ p, (b1 @ p) / h, (b2 @ p) / (h * h)


def hermite_basis(s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite basis at the nodes ``s`` (cached per ``s``).

    Parameters
    ----------
    s : array_like, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    b0, b1, b2 : ndarray, shape (m, 4)
        Value, first and second derivative (in ``s``) of the path from the rows
        ``[x0, h x0', x1, h x1']``; :func:`step_hermite` is ``b0 @ p``, ``b1 @ p / h``,
        ``b2 @ p / h^2``.
    """
    return _hermite_basis(np.ascontiguousarray(s, dtype=float).tobytes())


@functools.lru_cache(maxsize=64)
def _hermite_basis(key: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite basis (value, first and second derivative) at the nodes, each (m, 4)."""
    u = np.frombuffer(key, dtype=float)[:, None]
    u2, u3 = u * u, u * u * u
    b0 = np.hstack([2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2])
    b1 = np.hstack([6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u])
    b2 = np.hstack([12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2])
    for b in (b0, b1, b2):
        b.setflags(write=False)
    return b0, b1, b2


@functools.lru_cache(maxsize=64)
def _path_basis(key: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bases of :class:`StepPath`'s paths at the nodes ``u`` (``key``: their bytes).

    Returns
    -------
    quartic, quartic_d : ndarray, shape (m, 5)
        Value and ``h`` times the time derivative of the quartic from the rows
        ``[x0, h x0', x1, h x1', c]``: the cubic Hermite basis plus ``u^2 (1 - u)^2``.
    quadratic, quadratic_d : ndarray, shape (m, 3)
        The same for the quadratic from ``[x0, x1, c]``: ``x0 (1 - u) + x1 u + c u (1 - u)``.
    """
    u = np.frombuffer(key, dtype=float)[:, None]
    b0, b1, _ = _hermite_basis(key)
    bump = u * (1.0 - u)
    quartic = np.hstack([b0, bump * bump])
    quartic_d = np.hstack([b1, 2.0 * bump * (1.0 - 2.0 * u)])
    quadratic = np.hstack([1.0 - u, u, bump])
    quadratic_d = np.hstack([-np.ones_like(u), np.ones_like(u), 1.0 - 2.0 * u])
    out = (quartic, quartic_d, quadratic, quadratic_d)
    for b in out:
        b.setflags(write=False)
    return out


def path_basis(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bases that turn :meth:`StepPath.coefficients` into node values (cached per ``s``).

    Parameters
    ----------
    s : ndarray, shape (m,)
        Normalised times in [0, 1].

    Returns
    -------
    quartic, quartic_d : ndarray, shape (m, 5)
        ``x = quartic @ coef``, ``x' = quartic_d @ coef / h`` for a path with a derivative.
    quadratic, quadratic_d : ndarray, shape (m, 3)
        The same for a path without one.
    """
    return _path_basis(np.ascontiguousarray(s, dtype=float).tobytes())


class StepPath:
    """Path of a 3-vector input inside each step, rebuilt from step-end values and increments.

    Keeps the previous step-end value (and derivative, when one is connected) so
    that the start of the step is known exactly. With a derivative the path is
    the quartic ``x0, x0', x1, x1'`` Hermite cubic plus ``c u^2 (1 - u)^2``
    (``u = (tau - t) / h``) with ``c`` matching the increment; without, the
    quadratic through ``x0, x1`` matching the increment. Both are exact for
    polynomials of that degree. Without a valid start (first step after a
    time jump, or a start value inconsistent with the increment by more than
    ``rel_tol`` of the path's size, e.g. an input not forwarded at
    initialisation), the memoryless :func:`step_quadratic` / :func:`step_linear`
    is used for that step.

    Parameters
    ----------
    rel_tol : float
        Largest accepted mismatch between the increment and the path through
        the stored start, relative to ``|x0| + |x1| + h (|x0'| + |x1'|)``.
    """

    def __init__(self, rel_tol: float = 1e-2) -> None:
        self.rel_tol = rel_tol
        self._t: float | None = None
        self._x = np.zeros(3)
        self._xd: np.ndarray | None = None

    def reset(self, t: float, x: ArrayLike, xd: ArrayLike | None = None) -> None:
        """Store the value (and derivative) at time ``t`` as the start of the next step.

        Parameters
        ----------
        t : float
            Time of the value, the start of the next step [s].
        x : array_like, shape (3,)
            Value of the input at ``t`` (its unit and frame).
        xd : array_like, shape (3,), optional
            Its time derivative at ``t`` (unit per second); None when no derivative is
            connected (the next step then uses the quadratic path).
        """
        self._t = float(t)
        self._x = np.array(x, dtype=float)
        self._xd = None if xd is None else np.array(xd, dtype=float)

    def coefficients(
        self,
        t: float,
        h: float,
        end: ArrayLike,
        increment: ArrayLike,
        end_rate: ArrayLike | None = None,
    ) -> np.ndarray | None:
        """This step's path as coefficient rows for :func:`path_basis`, and advance.

        Parameters
        ----------
        t, h : float
            Step start and size [s].
        end : array_like, shape (3,)
            Value at ``t + h``.
        increment : array_like, shape (3,)
            Integral over the step.
        end_rate : array_like, shape (3,), optional
            Derivative at ``t + h`` (per second).

        Returns
        -------
        ndarray or None
            With ``end_rate``: shape (5, 3), rows ``[x0, h x0', x1, h x1', c]`` of the
            quartic; without: shape (3, 3), rows ``[x0, x1, c]`` of the quadratic. None
            when the stored start is not valid for this step: use the memoryless
            :func:`step_quadratic` / :func:`step_linear` (what :meth:`nodes` does).
        """
        x1 = np.asarray(end, dtype=float)
        mean = np.asarray(increment, dtype=float) / h
        valid = self._t is not None and abs(t - self._t) <= 1e-6 * h
        out = None
        if end_rate is None:
            if valid:
                x0 = self._x
                c = mean - 0.5 * (x0 + x1)
                out = np.array([x0, x1, 6.0 * c])
                norms = np.sqrt((out * out).sum(axis=1))  # |x0|, |x1|, 6 |c|
                if not norms[2] <= 6.0 * (self.rel_tol * (norms[0] + norms[1]) + 1e-300):
                    out = None
            self.reset(t + h, x1)
            return out
        xd1 = np.asarray(end_rate, dtype=float)
        if valid and self._xd is not None:
            x0, m0, m1 = self._x, self._xd * h, xd1 * h
            mismatch = mean - (0.5 * (x0 + x1) + (m0 - m1) / 12.0)
            out = np.array([x0, m0, x1, m1, 30.0 * mismatch])
            norms = np.sqrt((out * out).sum(axis=1))  # |x0|, |m0|, |x1|, |m1|, 30 |mismatch|
            scale = norms[0] + norms[2] + norms[1] + norms[3]
            if not norms[4] <= 30.0 * (self.rel_tol * scale + 1e-300):
                out = None
        self.reset(t + h, x1, xd1)
        return out

    def nodes(
        self,
        t: float,
        h: float,
        end: ArrayLike,
        increment: ArrayLike,
        s: np.ndarray,
        end_rate: ArrayLike | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Values and time derivatives (m, 3) at normalised times ``s`` of ``[t, t + h]``.

        Parameters
        ----------
        t, h : float
            Step start and size [s].
        end : array_like, shape (3,)
            Value at ``t + h``.
        increment : array_like, shape (3,)
            Integral over the step.
        s : ndarray, shape (m,)
            Normalised times in [0, 1].
        end_rate : array_like, shape (3,), optional
            Derivative at ``t + h`` (per second).

        Returns
        -------
        x, x_dot : ndarray, shape (m, 3)
        """
        coef = self.coefficients(t, h, end, increment, end_rate)
        if coef is None:
            if end_rate is None:
                return step_linear(end, increment, h, s)
            return step_quadratic(end, end_rate, increment, h, s)
        quartic, quartic_d, quadratic, quadratic_d = path_basis(s)
        if end_rate is None:
            return quadratic @ coef, (quadratic_d @ coef) / h
        return quartic @ coef, (quartic_d @ coef) / h
