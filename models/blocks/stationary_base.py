"""Stationary base: fixed attitude and position, optional sway and random angular jitter.

Equations (``rpy = [roll, pitch, yaw]``, Z-Y-X Euler angles of ``C_b_n``)::

    rpy(t) = rpy0 + sway_amp * sin(2 pi t / sway_period + sway_phase) + j(t)
    d_n(t) = lin_amp * sin(2 pi t / lin_period + lin_phase)          (NED, metres)

    omega_ib_b = omega_nb_b + C_n_b (omega_ie_n + omega_en_n)
    f_b        = C_n_b (d_n'' + (2 omega_ie_n + omega_en_n) x d_n' - g_n)

With no disturbance (the default) the readings are the perfect static ones::

    f_b = C_n_b [0, 0, -g(L, h)],      omega_ib_b = C_n_b [Omega cos L, 0, -Omega sin L]

Random jitter ``j`` (per axis, stationary std ``jitter_sigma``, seeded by ``seed``)
is sampled exactly at the inner grid ``delta = h / n``, ``n = round(h / dt_truth)``:

- ``jitter_order = 1``: first-order Markov ``j' = -j / tau + w``,
  ``j(k+1) = e^(-delta/tau) j(k) + sigma sqrt(1 - e^(-2 delta/tau)) N(0, 1)``;
  the path is linear between samples (its rate, the difference quotient, has a
  variance ~ 2 sigma^2 / (tau delta): a first-order process has no derivative,
  so the jitter rate depends on ``dt_truth``).
- ``jitter_order = 2``: second-order Markov ``j'' + 2 beta j' + beta^2 j = w``,
  ``beta = 2.146 / tau``, exact transition of ``[j, j']`` (matrix exponential,
  Van Loan noise); the path is the cubic Hermite interpolant of the samples
  (continuous rate; ``omega_dot_b`` is its one-sided second derivative).

Increments ``dtheta_b = integral omega_ib_b dt`` and ``dv_b = integral f_b dt``
over the step are plain integrals (no coning/sculling terms) by Simpson's rule on
each inner interval; without sway they are exactly ``omega_ib_b h`` and ``f_b h``.
A period <= 0 switches that axis off.
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, parameter
from cosim.models.blocks.gauss_markov import discretize_gm2
from cosim.models.constants import DEG
from cosim.models.earth import MOTION_OUTPUTS, ImuTruth, euler_motion_truth
from cosim.models.step_paths import substeps


def _omega(period: np.ndarray) -> np.ndarray:
    """Angular frequency ``2 pi / period`` [rad/s], 0 where ``period <= 0``."""
    period = np.asarray(period, dtype=float)
    return np.where(period > 0.0, 2.0 * np.pi / np.where(period > 0.0, period, 1.0), 0.0)


class StationaryBase(Block):
    """Stationary base at a fixed attitude and position, with optional sway and jitter."""

    variables = (
        parameter("rpy0", (0.0, 0.0, 0.0), "rad", "mean roll, pitch, yaw"),
        parameter("lat0", 45.0 * DEG, "rad", "latitude"),
        parameter("lon0", 0.0, "rad", "longitude"),
        parameter("h0", 0.0, "m", "height above the ellipsoid"),
        parameter("sway_amp", (0.0, 0.0, 0.0), "rad", "angular sway amplitude (roll, pitch, yaw)"),
        parameter("sway_period", (10.0, 10.0, 10.0), "s", "angular sway period (<= 0: off)"),
        parameter("sway_phase", (0.0, 0.0, 0.0), "rad", "angular sway phase"),
        parameter("lin_amp", (0.0, 0.0, 0.0), "m", "linear sway amplitude (N, E, D)"),
        parameter("lin_period", (5.0, 5.0, 5.0), "s", "linear sway period (<= 0: off)"),
        parameter("lin_phase", (0.0, 0.0, 0.0), "rad", "linear sway phase"),
        parameter("jitter_sigma", (0.0, 0.0, 0.0), "rad", "random jitter std (roll, pitch, yaw)"),
        parameter("jitter_tau", (1.0, 1.0, 1.0), "s", "random jitter correlation time"),
        parameter("jitter_order", 2, description="Gauss-Markov order of the jitter (1 or 2)"),
        parameter("seed", 0, description="random seed of the jitter"),
        parameter("dt_truth", 1.0e-3, "s", "inner integration step"),
        *MOTION_OUTPUTS,
    )
    default_stop = 2.0
    shared_values = {"lat0": "latitude", "h0": "height"}

    def initialize(self) -> None:
        if self.jitter_order not in (1, 2):
            raise ValueError(f"StationaryBase.jitter_order must be 1 or 2, got {self.jitter_order}")
        self._rng = np.random.default_rng(self.seed)
        self._w = _omega(self.sway_period)
        self._amp = np.where(self._w > 0.0, np.asarray(self.sway_amp, dtype=float), 0.0)
        self._wl = _omega(self.lin_period)
        self._lamp = np.where(self._wl > 0.0, np.asarray(self.lin_amp, dtype=float), 0.0)
        self._sigma = np.asarray(self.jitter_sigma, dtype=float).copy()
        self._tau = np.asarray(self.jitter_tau, dtype=float).copy()
        self._jitter = bool(np.any(self._sigma > 0.0))
        self._static = not (self._jitter or np.any(self._amp) or np.any(self._lamp))
        self._cache: dict[tuple[int, float], tuple] = {}
        # Jitter state [j, j'] per axis, drawn from the stationary distribution.
        self._j = np.zeros(3)
        self._jd = np.zeros(3)
        if self._jitter:
            self._j = self._sigma * self._rng.standard_normal(3)
            if self.jitter_order == 2:
                beta = 2.146 / self._tau
                self._jd = beta * self._sigma * self._rng.standard_normal(3)
        t0 = np.array([self.start_time])
        zero = np.zeros((1, 3))
        truth = self._truth(t0, self._j[None, :], self._jd[None, :], zero)
        self._publish(truth)
        self.dtheta_b = np.zeros(3)
        self.dv_b = np.zeros(3)

    # ------------------------------------------------------------ trajectory
    def _truth(self, tt: np.ndarray, j: np.ndarray, jd: np.ndarray, jdd: np.ndarray) -> ImuTruth:
        """Inertial truth at instants ``tt`` (m,) given the jitter path (m, 3) there."""
        arg = tt[:, None] * self._w + np.asarray(self.sway_phase)
        sa = np.sin(arg)
        rpy = np.asarray(self.rpy0) + self._amp * sa + j
        rpy_dot = self._amp * self._w * np.cos(arg) + jd
        rpy_ddot = -self._amp * self._w**2 * sa + jdd
        self._rpy_end = rpy[-1]
        ref = (float(self.lat0), float(self.lon0), float(self.h0))
        if not np.any(self._lamp):
            self._v_end = np.zeros(3)
            return euler_motion_truth(rpy, rpy_dot, rpy_ddot, None, None, None, *ref)
        argl = tt[:, None] * self._wl + np.asarray(self.lin_phase)
        sl = np.sin(argl)
        d_n = self._lamp * sl
        v_n = self._lamp * self._wl * np.cos(argl)
        a_n = -self._lamp * self._wl**2 * sl
        self._v_end = v_n[-1]
        return euler_motion_truth(rpy, rpy_dot, rpy_ddot, d_n, v_n, a_n, *ref)

    def _publish(self, truth: ImuTruth) -> None:
        self.rpy = np.array(self._rpy_end)
        self.rpy[2] = math.remainder(self.rpy[2], 2.0 * math.pi)
        self.v_n = np.array(self._v_end)
        self.lat = float(truth.lat[-1])
        self.lon = float(truth.lon[-1])
        self.h = float(truth.h[-1])
        self.omega_ib_b = truth.omega_ib_b[-1].copy()
        self.omega_dot_b = truth.omega_dot_b[-1].copy()
        self.f_b = truth.f_b[-1].copy()

    def _jitter_model(self, n: int, delta: float) -> tuple:
        """Cached exact transition for one inner step: per-axis (phi, chol(Qd))."""
        key = (n, delta)
        if key not in self._cache:
            if self.jitter_order == 1:
                a = np.exp(-delta / self._tau)
                self._cache[key] = (a, self._sigma * np.sqrt(1.0 - a * a))
            else:
                phis, chols = [], []
                for sig, tau in zip(self._sigma, self._tau, strict=True):
                    beta = 2.146 / tau
                    phi, qd = discretize_gm2(beta, 4.0 * beta**3 * sig**2, delta)
                    phis.append(phi)
                    chols.append(_psd_sqrt(qd))
                self._cache[key] = (np.array(phis), np.array(chols))
        return self._cache[key]

    def _jitter_path(self, n: int, delta: float) -> tuple[np.ndarray, ...]:
        """Sample the jitter at the n inner nodes; values at the 3n Simpson nodes."""
        noise = self._rng.standard_normal((n, 2, 3))
        j = np.empty((n + 1, 3))
        jd = np.empty((n + 1, 3))
        j[0], jd[0] = self._j, self._jd
        if self.jitter_order == 1:
            a, b = self._jitter_model(n, delta)
            for k in range(n):
                j[k + 1] = a * j[k] + b * noise[k, 0]
            rate = np.diff(j, axis=0) / delta  # (n, 3), constant on each interval
            mid = 0.5 * (j[:-1] + j[1:])
            path = np.stack([j[:-1], mid, j[1:]], axis=1).reshape(3 * n, 3)
            path_d = np.repeat(rate, 3, axis=0)
            path_dd = np.zeros((3 * n, 3))
            self._j = j[-1].copy()
        else:
            phi, chol = self._jitter_model(n, delta)
            s = np.stack([self._j, self._jd], axis=-1)  # (3 axes, 2)
            for k in range(n):
                s = np.einsum("aij,aj->ai", phi, s) + np.einsum("aij,aj->ai", chol, noise[k].T)
                j[k + 1], jd[k + 1] = s[:, 0], s[:, 1]
            x0, m0, x1, m1 = j[:-1], jd[:-1] * delta, j[1:], jd[1:] * delta
            mid = 0.5 * (x0 + x1) + 0.125 * (m0 - m1)
            mid_d = (1.5 * (x1 - x0) - 0.25 * (m0 + m1)) / delta
            acc0 = (6.0 * (x1 - x0) - 4.0 * m0 - 2.0 * m1) / delta**2
            acc_mid = (m1 - m0) / delta**2
            acc1 = (6.0 * (x0 - x1) + 2.0 * m0 + 4.0 * m1) / delta**2
            path = np.stack([x0, mid, x1], axis=1).reshape(3 * n, 3)
            path_d = np.stack([jd[:-1], mid_d, jd[1:]], axis=1).reshape(3 * n, 3)
            path_dd = np.stack([acc0, acc_mid, acc1], axis=1).reshape(3 * n, 3)
            self._j, self._jd = s[:, 0].copy(), s[:, 1].copy()
        return path, path_d, path_dd

    # ------------------------------------------------------------ stepping
    def step(self, t: float, h: float) -> None:
        if self._static:
            self.dtheta_b = self.omega_ib_b * h
            self.dv_b = self.f_b * h
            return
        n = substeps(h, self.dt_truth)
        delta = h / n
        # Simpson's rule on each inner interval: nodes (k, k + 1/2, k + 1) / n.
        s = (np.arange(n)[:, None] + np.array([0.0, 0.5, 1.0])).reshape(-1) / n
        w = np.tile(np.array([1.0, 4.0, 1.0]) / (6.0 * n), n)
        if self._jitter:
            j, jd, jdd = self._jitter_path(n, delta)
        else:
            j = jd = jdd = np.zeros((3 * n, 3))
        truth = self._truth(t + h * s, j, jd, jdd)
        self.dtheta_b = h * (w @ truth.omega_ib_b)
        self.dv_b = h * (w @ truth.f_b)
        self._publish(truth)


def _psd_sqrt(q: np.ndarray) -> np.ndarray:
    """A square root ``L`` with ``L @ L.T = q`` for a (possibly singular) PSD 2x2 matrix."""
    vals, vecs = np.linalg.eigh(0.5 * (q + q.T))
    return vecs * np.sqrt(np.clip(vals, 0.0, None))
