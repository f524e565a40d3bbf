"""Second-order Gauss-Markov process (demo block of the co-simulation core).

Equations (per axis, continuous time)::

    x'' + 2 beta x' + beta^2 x = w,      w white, two-sided PSD q
    beta = 2.146 / tau,                  q = 4 beta^3 sigma^2

so that the stationary standard deviation of x is ``sigma``. The state
``s = [x, x']`` is propagated with the exact discretisation over the step
``h`` (matrix exponential of ``A h``, Van Loan integral for the driving
noise), so the statistics do not depend on the step size.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from cosim.models.block import Block, output, parameter, same_step


def discretize_gm2(beta: float, q: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discrete transition and noise covariance of the second-order Markov model.

    Parameters
    ----------
    beta : float
        Damping parameter [1/s].
    q : float
        Two-sided PSD of the driving white noise [unit^2 / s^3].
    h : float
        Step [s].

    Returns
    -------
    phi : ndarray, shape (2, 2)
        State transition over ``h`` for ``[x, x']``.
    qd : ndarray, shape (2, 2)
        Covariance of the noise accumulated over ``h`` (Van Loan).
    """
    a = np.array([[0.0, 1.0], [-(beta**2), -2.0 * beta]])
    g = np.array([[0.0], [1.0]])
    m = np.zeros((4, 4))
    m[:2, :2] = -a
    m[:2, 2:] = g @ g.T * q
    m[2:, 2:] = a.T
    e = expm(m * h)
    phi = e[2:, 2:].T
    qd = phi @ e[:2, 2:]
    return phi, 0.5 * (qd + qd.T)


class GaussMarkov2(Block):
    """Second-order Gauss-Markov process, exact discretisation, one axis."""

    variables = (
        parameter("tau", 100.0, "s", "correlation time (beta = 2.146 / tau)"),
        parameter("sigma", 1.0e-3, "rad", "stationary standard deviation"),
        parameter("seed", 0, description="random seed"),
        output("x", 0.0, "rad", "process value"),
        output("x_dot", 0.0, "rad/s", "process rate"),
    )
    default_stop = 10.0

    def initialize(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._beta = 2.146 / self.tau
        self._q = 4.0 * self._beta**3 * self.sigma**2
        p = np.diag([self.sigma**2, (self._beta * self.sigma) ** 2])
        self._s = np.linalg.cholesky(p) @ self._rng.standard_normal(2)
        self._cache: tuple[float, np.ndarray, np.ndarray] | None = None
        self.x, self.x_dot = float(self._s[0]), float(self._s[1])

    def step(self, t: float, h: float) -> None:
        if self._cache is None or not same_step(h, self._cache[0]):
            self.step_setups += 1
            phi, qd = discretize_gm2(self._beta, self._q, h)
            self._cache = (h, phi, np.linalg.cholesky(qd + 1e-300 * np.eye(2)))
        _, phi, lq = self._cache
        self._s = phi @ self._s + lq @ self._rng.standard_normal(2)
        self.x, self.x_dot = float(self._s[0]), float(self._s[1])
