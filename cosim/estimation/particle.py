"""Particle filtering: systematic resampling and the unscented particle filter.

The unscented particle filter runs one UKF per particle (the batched
:func:`~cosim.estimation.unscented.ukf_predict` / ``ukf_update``) to build its
proposal. Stochastic code never touches global random state: it takes an explicit
:class:`numpy.random.Generator`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import logsumexp

from cosim.estimation.checks import (
    ArrayField,
    DegenerateWeightsError,
    EstimatorTypeError,
    FloatArray,
    MeanFn,
    ResidualFn,
    ShapeError,
    as_float,
    check_dim,
    check_measurement,
    check_shape,
    check_square,
    measurement_noise,
)
from cosim.estimation.linalg import (
    LOG_2PI,
    cholesky,
    gauss_logpdf,
    mahalanobis2,
    sqrt_psd,
    symmetrise,
)
from cosim.estimation.sigma_points import SigmaPoints, SigmaPointSampler
from cosim.estimation.unscented import call_model, check_models, ukf_predict, ukf_update

__all__ = ["UnscentedParticleFilter", "systematic_resample"]


def systematic_resample(weights: ArrayLike, rng: np.random.Generator) -> NDArray[np.intp]:
    """Systematic resampling: one uniform draw, ``N`` evenly spaced pointers.

    Particle ``i`` is selected ``floor(N w_i)`` or ``ceil(N w_i)`` times, and
    ``N w_i`` times on average.

    Parameters
    ----------
    weights : array_like, shape (N,)
        Non-negative weights (normalised internally).
    rng : numpy.random.Generator
        Source of the single uniform draw.

    Returns
    -------
    ndarray of intp, shape (N,)
        Indices of the selected particles, in non-decreasing order.
    """
    if not isinstance(rng, np.random.Generator):
        raise EstimatorTypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
    w = as_float(weights, "weights")
    if w.ndim != 1 or w.size == 0:
        raise ShapeError(f"weights: expected shape (N,) with N >= 1, got {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0.0):
        raise ValueError("weights: expected finite non-negative values, got negative or non-finite")
    total = w.sum()
    if not total > 0.0:
        raise DegenerateWeightsError("weights: expected a positive sum, got 0")
    N = w.size
    cum = np.cumsum(w / total)
    cum[-1] = 1.0  # guard against round-off leaving the last pointer unmatched
    pointers = (rng.random() + np.arange(N)) / N
    return np.searchsorted(cum, pointers, side="right").astype(np.intp)


class UnscentedParticleFilter:
    """Unscented particle filter (van der Merwe, Doucet, de Freitas & Wan, 2000).

    Every particle ``i`` carries a state ``x^i`` and a covariance ``P^i``. One
    :meth:`step` runs, for all particles at once (arrays ``(N, s, n)`` for ``s``
    sigma points per particle), a UKF predict + update from ``(x^i_(k-1), P^i_(k-1))``
    with the measurement ``z_k``, giving ``N(m^i_k, P^i_k)``; then

    * ``proposal="sample"`` (the UPF): draw ``x^i_k ~ N(m^i_k, P^i_k)`` and set
      ``w^i <- w^i p(z_k | x^i_k) p(x^i_k | x^i_(k-1)) / q(x^i_k)`` with
      ``p(z|x) = N(z; hx(x), R)``, ``p(x_k|x_(k-1)) = N(x_k; fx(x_(k-1)), Q)``,
      ``q = N(m^i_k, P^i_k)``. The filter covariance ``P`` is the weighted
      covariance of the particles.
    * ``proposal="mean"`` (deterministic, a Gaussian-sum bank of UKFs): set
      ``x^i_k = m^i_k`` and ``w^i <- w^i N(y^i; 0, S^i)`` (predictive likelihood
      of the innovation). ``P`` is then the mixture covariance
      ``sum w_i (P^i + (x^i - x)(x^i - x)^T)``. With one particle this is exactly
      the UKF, which is how the tests tie the two together.

    Systematic resampling (particles and their covariances) happens when the
    effective sample size ``1 / sum w_i^2`` falls below ``resample_threshold``.

    ``fx`` and ``hx`` act on the last axis (``x`` of shape ``(N, s, n)`` or
    ``(N, n)``); with ``vectorized=False`` they are called per point with ``(n,)``
    (slow: for prototyping only).

    Weight rules and their limits (see the tests for numbers):

    * ``"full"`` is the exact importance weight: with many particles the weighted
      cloud reproduces the exact posterior. It needs a positive definite ``Q``,
      and because every proposal is as wide as the whole posterior (``P^i``)
      while the transition density is only as wide as ``Q``, the weights
      degenerate (ESS near 1 every step, the cloud collapses) when ``Q`` is much
      smaller than ``P``. Random-constant states (``Q`` singular, e.g. drifts and
      initial misalignments in a static alignment) are the extreme case.
    * ``"likelihood"`` keeps only ``p(z | x)`` (proposal-to-prior ratio taken as
      one), a heuristic found in applied papers. It does not need ``Q`` and keeps
      a healthy ESS, but it counts ``z`` twice (the proposal already used it), so
      it is overconfident: on a linear-Gaussian step its variance comes out
      around half the true one.
    * For random-constant states prefer ``proposal="mean"`` (a bank of UKFs with
      Gaussian-sum weights, exact bookkeeping, no sampling noise), or add a small
      artificial process noise ("roughening") and keep ``"full"``.

    Parameters
    ----------
    dim_x, dim_z : int
        State and measurement dimensions.
    fx, hx : callable
        ``fx(x, dt, **kw)`` and ``hx(x, **kw)``, see above.
    points : SigmaPoints
        Sigma-point object for ``dim_x``, as in :class:`UnscentedKalmanFilter`. Where
        its ``sigma_points`` takes a ``robust`` keyword (the sets shipped here do),
        the filter passes ``robust=True``: a particle covariance that round-off made
        slightly indefinite then gets a clipped square root instead of an error.
    rng : numpy.random.Generator
        The only source of randomness (sampling and resampling).
    n_particles : int
        Number of particles N (default 200).
    resample_threshold : float, optional
        Resample when ``ess < resample_threshold`` (default ``N / 2``; 0 never).
    proposal : {"sample", "mean"}
        See above.
    weight_rule : {"full", "likelihood"}
        See above (only for ``proposal="sample"``).
    residual_x, residual_z : callable ``(a, b) -> a - b``, optional
        Broadcasting differences of states / measurements, as in
        :class:`UnscentedKalmanFilter` (angles: :func:`angle_residual_fn`).
    x_mean_fn, z_mean_fn : callable ``(sigmas, Wm) -> mean``, optional
        Weighted means, as in :class:`UnscentedKalmanFilter` (angles:
        :func:`angle_mean_fn`); ``x_mean_fn`` also forms the weighted particle mean.
    vectorized : bool
        Whether ``fx`` and ``hx`` take stacked points (default True); False calls them
        per point with shape ``(n,)``.

    Attributes
    ----------
    particles : ndarray, shape (N, n)
    particle_P : ndarray, shape (N, n, n)
    weights : ndarray, shape (N,)
        Normalised.
    proposal_mean : ndarray, shape (N, n)
        UKF posterior means ``m^i`` of the last step.
    particle_nis : ndarray, shape (N,)
        Normalised innovation squared ``y_i^T S_i^-1 y_i`` of each particle's UKF update
        in the last step (chi-square with ``dim_z`` degrees of freedom for a consistent
        particle); NaN before the first update and after a step without ``z``.
    Q : ndarray, shape (n, n)
    R : ndarray, shape (m, m)
    resampled : bool
        Whether the last step resampled; ``n_resamples`` counts them.
    last_ess : float
        Effective sample size of the last step's weights before any resampling
        (``ess`` is the current one, ``N`` right after resampling).
    """

    Q = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    R = ArrayField("dim_z", "dim_z", scalar_is_eye=True)

    def __init__(
        self,
        dim_x: int,
        dim_z: int,
        fx: Callable[..., ArrayLike],
        hx: Callable[..., ArrayLike],
        points: SigmaPoints,
        *,
        rng: np.random.Generator,
        n_particles: int = 200,
        resample_threshold: float | None = None,
        proposal: Literal["sample", "mean"] = "sample",
        weight_rule: Literal["full", "likelihood"] = "full",
        residual_x: ResidualFn | None = None,
        residual_z: ResidualFn | None = None,
        x_mean_fn: MeanFn | None = None,
        z_mean_fn: MeanFn | None = None,
        vectorized: bool = True,
    ) -> None:
        sampler = check_models(
            check_dim(dim_x, "dim_x"),
            fx,
            hx,
            points,
            robust=True,
            residual_x=residual_x,
            residual_z=residual_z,
            x_mean_fn=x_mean_fn,
            z_mean_fn=z_mean_fn,
        )
        if not isinstance(rng, np.random.Generator):
            raise EstimatorTypeError(
                f"rng: expected numpy.random.Generator, got {type(rng).__name__}"
            )
        if proposal not in ("sample", "mean"):
            raise ValueError(f"proposal: expected 'sample' or 'mean', got {proposal!r}")
        if weight_rule not in ("full", "likelihood"):
            raise ValueError(f"weight_rule: expected 'full' or 'likelihood', got {weight_rule!r}")
        self.dim_x, self.dim_z = int(dim_x), check_dim(dim_z, "dim_z")
        self.N = check_dim(n_particles, "n_particles")
        self.resample_threshold = (
            self.N / 2.0 if resample_threshold is None else float(resample_threshold)
        )
        self.fx, self.hx, self.rng = fx, hx, rng
        self._sampler = sampler
        self.proposal, self.weight_rule = proposal, weight_rule
        self.residual_x, self.residual_z = residual_x, residual_z
        self.x_mean_fn, self.z_mean_fn = x_mean_fn, z_mean_fn
        self.vectorized = bool(vectorized)
        n = self.dim_x
        self.Q = np.zeros((n, n))
        self.R = np.eye(self.dim_z)
        self.particles = np.zeros((self.N, n))
        self.particle_P = np.broadcast_to(np.eye(n), (self.N, n, n)).copy()
        self.weights = np.full(self.N, 1.0 / self.N)
        self.proposal_mean = self.particles.copy()
        self.particle_nis = np.full(self.N, np.nan)
        self.resampled = False
        self.n_resamples = 0
        self.last_ess = float(self.N)

    @property
    def points(self) -> SigmaPoints:
        """The sigma-point object."""
        return self._sampler.points

    @points.setter
    def points(self, value: SigmaPoints) -> None:
        self._sampler = SigmaPointSampler(value, self.dim_x, robust=True)

    # -- set-up -----------------------------------------------------------------------------
    def initialize(self, x0: ArrayLike, P0: ArrayLike, *, spread: bool = True) -> None:
        """Start from the prior ``N(x0, P0)``.

        Parameters
        ----------
        x0 : array_like, shape (n,)
            Prior mean.
        P0 : array_like, shape (n, n) or scalar
            Prior covariance; every particle carries it as its own ``P^i``.
        spread : bool
            Draw the particles from ``N(x0, P0)`` (default, the UPF). False puts
            them all at ``x0`` (useful with ``proposal="mean"`` and one particle).
        """
        n = self.dim_x
        x0 = check_shape(x0, "x0", (n,))
        P0 = check_square(P0, "P0", n)
        if spread:
            L = cholesky(P0, "P0")
            parts = x0 + self.rng.standard_normal((self.N, n)) @ L.T
        else:
            parts = np.broadcast_to(x0, (self.N, n)).copy()
        self.set_particles(parts, np.broadcast_to(P0, (self.N, n, n)))

    def set_particles(
        self, particles: ArrayLike, P: ArrayLike, weights: ArrayLike | None = None
    ) -> None:
        """Set particles, their covariances and (optionally) weights directly.

        Parameters
        ----------
        particles : array_like, shape (N, n)
            Particle states.
        P : array_like, shape (N, n, n) or (n, n)
            Their covariances (one shared matrix is broadcast).
        weights : array_like, shape (N,), optional
            Non-negative; normalised here. Default uniform.
        """
        n, N = self.dim_x, self.N
        parts = check_shape(particles, "particles", (N, n))
        Pa = as_float(P, "P")
        if Pa.shape == (n, n):
            Pa = np.broadcast_to(Pa, (N, n, n)).copy()
        if Pa.shape != (N, n, n):
            raise ShapeError(f"P: expected shape {(N, n, n)} or {(n, n)}, got {Pa.shape}")
        if weights is None:
            w = np.full(N, 1.0 / N)
        else:
            w = check_shape(weights, "weights", (N,))
            if np.any(w < 0.0) or not w.sum() > 0.0:
                raise ValueError("weights: expected non-negative values with a positive sum")
            w = w / w.sum()
        self.particles = parts
        self.particle_P = Pa
        self.weights = w
        self.proposal_mean = parts.copy()
        self.particle_nis = np.full(N, np.nan)

    # -- estimates --------------------------------------------------------------------------
    @property
    def ess(self) -> float:
        """Effective sample size ``1 / sum w_i^2`` (between 1 and N)."""
        return float(1.0 / np.sum(self.weights**2))

    @property
    def x(self) -> FloatArray:
        """Weighted mean of the particles, shape (n,)."""
        if self.x_mean_fn is None:
            return self.weights @ self.particles
        return np.asarray(self.x_mean_fn(self.particles, self.weights), dtype=float)

    @property
    def P(self) -> FloatArray:
        """Posterior covariance, shape (n, n).

        Weighted particle covariance for ``proposal="sample"``; mixture covariance
        (including every ``P^i``) for ``proposal="mean"``.
        """
        x = self.x
        r = (
            self.particles - x
            if self.residual_x is None
            else np.asarray(self.residual_x(self.particles, x), dtype=float)
        )
        cov = (r * self.weights[:, None]).T @ r
        if self.proposal == "mean":
            cov = cov + np.tensordot(self.weights, self.particle_P, axes=1)
        return symmetrise(cov)

    # -- filtering --------------------------------------------------------------------------
    def step(
        self,
        z: ArrayLike | None,
        dt: float,
        *,
        Q: ArrayLike | None = None,
        R: ArrayLike | None = None,
        fx_args: dict[str, Any] | None = None,
        hx_args: dict[str, Any] | None = None,
    ) -> None:
        """One filter cycle: per-particle UKF proposal, weighting, optional resampling.

        Parameters
        ----------
        z : array_like, shape (m,), or None
            Measurement at the end of the step; ``None`` propagates only (the
            proposal is then the UKF prediction and the weights change only by
            the transition/proposal ratio).
        dt : float
            Step [s].
        Q : array_like, shape (n, n) or scalar, optional
            Process noise over the step (default ``self.Q``).
        R : array_like, shape (m, m) or scalar, optional
            Measurement noise (default ``self.R``).
        fx_args, hx_args : dict, optional
            Extra keyword arguments for ``fx`` / ``hx``.
        """
        n, N = self.dim_x, self.N
        Q = self.Q if Q is None else check_square(Q, "Q", n)
        fx_kw = {} if fx_args is None else dict(fx_args)
        hx_kw = {} if hx_args is None else dict(hx_args)
        rx, rz = self.residual_x, self.residual_z

        sig, sig_f, xp, Pp = ukf_predict(
            self.particles,
            self.particle_P,
            self._sampler,
            self.fx,
            dt,
            Q,
            self.x_mean_fn,
            rx,
            fx_kw,
            self.vectorized,
        )
        with np.errstate(divide="ignore"):  # a weight that underflowed to 0 -> -inf
            log_w = np.log(self.weights)
        if z is not None:
            z = check_measurement(z)
            m = z.size
            R = measurement_noise(R, self.R, self.dim_z, m)
            out = ukf_update(
                z, xp, Pp, self._sampler, self.hx, R, rx, rz, self.z_mean_fn, hx_kw,
                self.vectorized,
            )  # fmt: skip
            mean, cov = out["x"], out["P"]
            particle_nis = mahalanobis2(out["y"], out["chol_S"])
        else:
            mean, cov = xp, Pp
            particle_nis = np.full(N, np.nan)

        if self.proposal == "mean":
            if z is not None:
                log_w = log_w + gauss_logpdf(out["y"], out["chol_S"], particle_nis)
            new = mean
        else:
            A, half_logdet = sqrt_psd(cov)
            eps = self.rng.standard_normal((N, n))
            new = mean + (A @ eps[..., None])[..., 0]
            log_q = -0.5 * np.sum(eps * eps, axis=-1) - half_logdet - 0.5 * n * LOG_2PI
            if self.weight_rule == "full":
                LQ = cholesky(Q, "Q (the 'full' UPF weight needs a positive definite Q)")
                if np.array_equal(sig[:, 0, :], self.particles):
                    f_prev = sig_f[:, 0, :]  # sigma point 0 is the particle itself
                else:
                    f_prev = call_model(
                        self.fx, "fx", self.particles, (dt,), fx_kw, n, self.vectorized
                    )
                d = new - f_prev if rx is None else np.asarray(rx(new, f_prev), dtype=float)
                log_w = log_w + gauss_logpdf(d, LQ) - log_q
            if z is not None:
                LR = cholesky(R, "R")
                zh = call_model(self.hx, "hx", new, (), hx_kw, z.size, self.vectorized)
                r = z - zh if rz is None else np.asarray(rz(z, zh), dtype=float)
                log_w = log_w + gauss_logpdf(r, LR)

        total = logsumexp(log_w)
        if not np.isfinite(total):
            raise DegenerateWeightsError(
                "weights: expected at least one particle compatible with the data, got all "
                "weights zero or non-finite (check R, Q and the measurement)"
            )
        self.weights = np.exp(log_w - total)
        self.particles = new
        self.particle_P = cov
        self.proposal_mean = mean
        self.particle_nis = particle_nis
        self.resampled = False
        self.last_ess = self.ess
        if self.last_ess < self.resample_threshold:
            idx = systematic_resample(self.weights, self.rng)
            self.particles = self.particles[idx]
            self.particle_P = self.particle_P[idx]
            self.proposal_mean = self.proposal_mean[idx]
            self.particle_nis = self.particle_nis[idx]
            self.weights = np.full(N, 1.0 / N)
            self.resampled = True
            self.n_resamples += 1
