"""Deck flexure: second-order Markov angle per axis (seed 001, eq. 1), exact discretisation.

Equations (per axis ``i = x, y, z`` of the master body frame)::

    theta_i'' + 2 beta_i theta_i' + beta_i^2 theta_i = eta_i,     eta_i white, PSD q_i
    beta_i = 2.146 / tau_i,       q_i = 4 beta_i^3 sigma_i^2

so that ``theta_i`` is stationary with std ``sigma_i`` (and ``theta_i'`` with std
``beta_i sigma_i``); the initial state is drawn from that distribution. The PSD of
``theta_i`` is ``q_i |H(j w)|^2`` with ``H(s) = 1 / (s^2 + 2 beta_i s + beta_i^2)``.

Exact discretisation over any step ``h``: the state ``[I, theta, theta']`` with
``I' = theta`` (``I`` restarted at 0 at each step, so ``I(h) = integral of theta``
over the step) is propagated with ``Phi = expm(A h)`` and the Van Loan noise
covariance ``Qd = integral_0^h expm(A s) G q G^T expm(A s)^T ds``, computed on
the time-scaled state ``[I / h^2, theta / h, theta']`` (all entries keep full
relative precision for small steps) and, for ``beta h > 1``, on ``h / 2^k`` followed
by ``k`` exact doublings ``Qd(2s) = Qd(s) + Phi(s) Qd(s) Phi(s)^T`` (Van Loan's
``expm(-A h)`` would overflow): valid for any step.

The white noise over a step. ``eta`` has no value at an instant; what the
physics needs is its integral, and that follows exactly from the sampled state::

    integral_t^(t+h) eta dt = dtheta_dot + 2 beta dtheta + beta^2 I

The block outputs the step mean ``eta = (that integral) / h`` (variance exactly
``q / h``: a sampled white noise). The flexure acceleration at the step end is
represented as ``theta_ddot = -2 beta theta' - beta^2 theta + eta``
(instantaneous damping terms, step-mean noise). The lever-arm term ``R_0 eta``
of seed 001 eq. (11) thus appears as ``R_0 theta_ddot`` in the slave's specific
force at the step end, and its integral over the step is exactly
``R_0 (theta'(t+h) - theta'(t)) = R_0 dtheta_dot_flex`` (see :mod:`models.blocks.lever_arm`).

Compiled step: with :func:`models.native.library`, the per-step update below is one call
of ``deck_flexure_step`` (``models/blocks/deck_flexure.c``, the same arithmetic; the normals are
still drawn by numpy, :data:`AHEAD_STEPS` steps at a time).

Outputs at the step end: ``theta`` [rad], ``theta_dot`` [rad/s], ``theta_ddot``
[rad/s2], ``eta`` [rad/s2] (step mean); increments over the step:
``dtheta_flex = theta(t+h) - theta(t)`` [rad] (the integral of ``theta_dot``) and
``dtheta_dot_flex = theta_dot(t+h) - theta_dot(t)`` [rad/s] (the integral of
``theta_ddot``).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.linalg import expm

from cosim.models import native
from cosim.models.block import Block, output, parameter, same_step
from cosim.models.constants import ARCMIN


def discretize_flexure(beta: float, q: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact transition and noise covariance of ``[I, theta, theta']`` over a step.

    Parameters
    ----------
    beta : float
        Damping parameter [1/s].
    q : float
        Two-sided PSD of the driving white noise [rad^2/s^3].
    h : float
        Step [s], > 0.

    Returns
    -------
    phi : ndarray, shape (3, 3)
        Transition of ``[I, theta, theta']`` (``I`` = integral of theta since the step start).
    qd : ndarray, shape (3, 3)
        Covariance of the accumulated noise.
    """
    # Van Loan on a sub-step h0 = h / 2^k with beta h0 <= 1 (the Van Loan matrix holds
    # expm(-A h0), which overflows for large beta h), then doubling:
    # Phi(2s) = Phi(s)^2,  Qd(2s) = Qd(s) + Phi(s) Qd(s) Phi(s)^T.
    k = max(0, math.ceil(math.log2(beta * h))) if beta * h > 1.0 else 0
    h0 = h / 2.0**k
    # Scaled state z = S x, S = diag(1/h0^2, 1/h0, 1), time in units of h0:
    # dz/du = As z + Gs w with As = h0 S A S^-1.
    a_s = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -((beta * h0) ** 2), -2.0 * beta * h0]])
    m = np.zeros((6, 6))
    m[:3, :3] = -a_s
    m[2, 5] = q * h0  # Gs q Gs^T with Gs = [0, 0, 1] and d(time) = h0 du
    m[3:, 3:] = a_s.T
    e = expm(m)
    phi_s = e[3:, 3:].T
    q_s = phi_s @ e[:3, 3:]
    q_s = 0.5 * (q_s + q_s.T)
    scale = np.array([h0 * h0, h0, 1.0])
    phi = phi_s * scale[:, None] / scale[None, :]
    qd = q_s * scale[:, None] * scale[None, :]
    for _ in range(k):
        qd = qd + phi @ qd @ phi.T
        phi = phi @ phi
    return phi, 0.5 * (qd + qd.T)


def noise_factor(qd: np.ndarray) -> np.ndarray:
    """A square root ``L`` of a noise covariance, ``L @ L.T = qd``, that tolerates tiny steps.

    The eigen-decomposition of the correlation matrix, rescaled by the standard
    deviations: the entries of ``qd`` of :func:`discretize_flexure` span many decades
    for small steps, the correlation matrix does not.

    Parameters
    ----------
    qd : ndarray, shape (n, n)
        Symmetric positive semi-definite covariance (units of the state squared).

    Returns
    -------
    ndarray, shape (n, n)
        ``L`` (units of the state); all zeros when a diagonal entry of ``qd`` is not > 0.
    """
    d = np.sqrt(np.clip(np.diag(qd), 0.0, None))
    if not np.all(d > 0.0):
        return np.zeros_like(qd)
    corr = qd / d[:, None] / d[None, :]
    vals, vecs = np.linalg.eigh(corr)
    root = vecs * np.sqrt(np.clip(vals, 0.0, None))
    return d[:, None] * root


@functools.lru_cache(maxsize=64)
def axis_model(beta: float, q: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`discretize_flexure` and its :func:`noise_factor`, cached for the process.

    A campaign's runs (and the master's resets) share the same ``(beta, q, h)``; the
    matrix exponentials are computed once (read-only arrays, the same numbers).

    Parameters
    ----------
    beta : float
        Damping parameter [1/s].
    q : float
        Two-sided PSD of the driving white noise [rad^2/s^3].
    h : float
        Step [s], > 0.

    Returns
    -------
    phi : ndarray, shape (3, 3)
        Transition of ``[I, theta, theta']``.
    root : ndarray, shape (3, 3)
        ``L`` with ``L L^T = Qd``.
    """
    phi, qd = discretize_flexure(beta, q, h)
    root = noise_factor(qd)
    for a in (phi, root):
        a.setflags(write=False)
    return phi, root


class DeckFlexure(Block):
    """Deck flexure angles: second-order Gauss-Markov per axis with exact discretisation.

    Attributes
    ----------
    compiled : bool
        True when this instance steps through the compiled kernel (set at initialisation,
        :func:`models.native.library`), False on the numpy path.
    """

    variables = (
        parameter(
            "tau", (600.0, 600.0, 600.0), "s", "correlation time per axis (beta = 2.146/tau)"
        ),
        parameter("sigma", (2.0 * ARCMIN,) * 3, "rad", "stationary std per axis"),
        parameter("seed", 0, description="random seed"),
        output("theta", (0.0, 0.0, 0.0), "rad", "flexure angle, master body axes"),
        output("theta_dot", (0.0, 0.0, 0.0), "rad/s", "flexure rate"),
        output("theta_ddot", (0.0, 0.0, 0.0), "rad/s2", "-2 beta theta' - beta^2 theta + eta"),
        output("eta", (0.0, 0.0, 0.0), "rad/s2", "driving white noise, mean over the step"),
        output("dtheta_flex", (0.0, 0.0, 0.0), "rad", "theta(t+h) - theta(t)"),
        output("dtheta_dot_flex", (0.0, 0.0, 0.0), "rad/s", "theta_dot(t+h) - theta_dot(t)"),
    )
    default_stop = 2.0

    def initialize(self) -> None:
        tau = np.asarray(self.tau, dtype=float)
        if np.any(tau <= 0.0):
            raise ValueError("DeckFlexure.tau must be > 0 on every axis")
        self._rng = np.random.default_rng(self.seed)
        self._beta = 2.146 / tau
        sig = np.asarray(self.sigma, dtype=float)
        self._q = 4.0 * self._beta**3 * sig**2
        self._cache: tuple[float, np.ndarray, np.ndarray] | None = None
        self._two_beta = 2.0 * self._beta
        self._beta2 = self._beta**2
        self._noise = np.empty((0, 3, 3))  # normals drawn ahead, one (3, 3) block per step
        self._pos = 0
        self._x0 = np.zeros((3, 3))  # [0, theta, theta'] per axis (the integral restarts)
        z = self._rng.standard_normal((2, 3))
        # outputs written in place: they stay the block's buffer views (models.block)
        self.theta[:] = sig * z[0]
        self.theta_dot[:] = self._beta * sig * z[1]
        self.eta[:] = 0.0
        self.theta_ddot[:] = -2.0 * self._beta * self.theta_dot - self._beta**2 * self.theta
        self.dtheta_flex[:] = 0.0
        self.dtheta_dot_flex[:] = 0.0
        self._lib = native.library()
        self.compiled = self._lib is not None
        if self._lib is not None:
            self._st = np.concatenate([self.theta, self.theta_dot])  # the state the step needs
            self._fixed = np.concatenate([self._two_beta, self._beta2])
            self._native_step = self._lib.deck_flexure_step
            self._io = native.Buffers(self, (), NATIVE_OUTPUTS)
            self._st_ptr = native.pointer(self._st)
            self._fixed_ptr = native.pointer(self._fixed)

    def _model(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        if self._cache is None or not same_step(h, self._cache[0]):
            self.step_setups += 1
            phis, roots = [], []
            for beta, q in zip(self._beta, self._q, strict=True):
                phi, root = axis_model(float(beta), float(q), float(h))
                phis.append(phi)
                roots.append(root)
            self._cache = (h, np.array(phis), np.array(roots))
            self._cache_ptrs = (native.pointer(self._cache[1]), native.pointer(self._cache[2]))
        return self._cache[1], self._cache[2]

    def step(self, t: float, h: float) -> None:
        phi, root = self._model(h)
        if self._lib is not None:
            if self._pos >= len(self._noise):
                self._noise = self._rng.standard_normal((AHEAD_STEPS, 3, 3))
                self._pos = 0
                self._noise_ptr = native.pointer(self._noise)
            fixed = self._fixed_ptr
            io = self._io
            self._native_step(
                *self._cache_ptrs,
                self._noise_ptr + 72 * self._pos,  # 9 doubles per step
                fixed,
                fixed + 24,  # beta^2 after 2 beta
                self._st_ptr,
                io.output_pointer(),
                h,
            )
            self._pos += 1
            io.publish()
            return
        x0 = self._x0  # (axis, 3): column 0 stays 0
        x0[:, 1] = self.theta
        x0[:, 2] = self.theta_dot
        if self._pos >= len(self._noise):
            # the same numbers as one (3, 3) draw per step, in the same order
            self._noise = self._rng.standard_normal((AHEAD_STEPS, 3, 3))
            self._pos = 0
        noise = self._noise[self._pos]  # (axis, component)
        self._pos += 1
        # Phi x0 + L z per axis, summed in index order (the compiled step's order)
        x1 = (phi[:, :, 0] * x0[:, 0:1] + phi[:, :, 1] * x0[:, 1:2] + phi[:, :, 2] * x0[:, 2:3]) + (
            root[:, :, 0] * noise[:, 0:1]
            + root[:, :, 1] * noise[:, 1:2]
            + root[:, :, 2] * noise[:, 2:3]
        )
        integral, theta, theta_dot = x1[:, 0], x1[:, 1], x1[:, 2]
        d_theta = theta - self.theta
        d_theta_dot = theta_dot - self.theta_dot
        beta2 = self._beta2
        self.eta = (d_theta_dot + self._two_beta * d_theta + beta2 * integral) / h
        self.theta = theta
        self.theta_dot = theta_dot
        self.theta_ddot = -self._two_beta * theta_dot - beta2 * theta + self.eta
        self.dtheta_flex = d_theta
        self.dtheta_dot_flex = d_theta_dot


#: The compiled step's outputs, in its layout (declaration order).
NATIVE_OUTPUTS = ("theta", "theta_dot", "theta_ddot", "eta", "dtheta_flex", "dtheta_dot_flex")

#: Steps of random numbers drawn ahead (one call instead of one per step).
AHEAD_STEPS = 64
