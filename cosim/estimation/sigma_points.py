"""Sigma points for the unscented filters: the interface, Merwe's and Julier's sets.

The UKF and the UPF take any ``points`` object with filterpy's interface
(:class:`SigmaPoints`): attributes ``n``, ``Wm``, ``Wc``, a method ``num_sigmas()`` and
a method ``sigma_points(x, P)``. :class:`MerweScaledSigmaPoints` (the scaled set,
``alpha``, ``beta``, ``kappa``) and :class:`JulierSigmaPoints` (the original set,
``kappa``) are the two shipped; a user's own set needs no base class. The filters see
a points object through a :class:`SigmaPointSampler`, which checks the interface once
and gives every filter the same batched call.
"""

from __future__ import annotations

import inspect
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from cosim.estimation.checks import (
    EstimatorTypeError,
    FloatArray,
    ShapeError,
    as_float,
    check_dim,
)
from cosim.estimation.linalg import broadcast_batch, cholesky, float_array, sqrt_psd

__all__ = [
    "JulierSigmaPoints",
    "MerweScaledSigmaPoints",
    "SigmaPointSampler",
    "SigmaPoints",
]


class SigmaPoints(Protocol):
    """The interface of a sigma-point set (filterpy's ``points``), for typing and docs.

    Any object with these members plugs into :class:`UnscentedKalmanFilter` and
    :class:`UnscentedParticleFilter`; it does not have to inherit from this class.

    Required:

    * ``n`` (int): the state dimension the set is built for.
    * ``Wm``, ``Wc`` (array_like, shape ``(m,)``): mean and covariance weights,
      ``m = num_sigmas()``; ``Wm`` sums to one.
    * ``num_sigmas()`` -> int: the number of points ``m``.
    * ``sigma_points(x, P)``: the points of ``N(x, P)`` for ``x (n,)`` and
      ``P (n, n)``, an array ``(m, n)`` (one point per row, filterpy's layout).

    Optional:

    * ``batched = True`` (class attribute): ``sigma_points`` also takes stacks
      ``x (..., n)``, ``P (..., n, n)`` and returns ``(..., m, n)``. Without it the
      particle filter calls ``sigma_points`` once per particle.
    * a keyword ``robust`` of ``sigma_points``: the particle filter passes
      ``robust=True`` to ask for a square root that survives a covariance made
      slightly indefinite by round-off (see :meth:`MerweScaledSigmaPoints.sigma_points`).

    If point 0 is the mean (true of the symmetric sets here), the particle filter
    reuses its image through ``fx`` as the transition mean; otherwise it calls ``fx``
    on the particles once more.
    """

    n: int
    Wm: Any
    Wc: Any

    def num_sigmas(self) -> int:
        """Number of sigma points ``m``."""
        ...

    def sigma_points(self, x: ArrayLike, P: ArrayLike) -> Any:
        """Sigma points of ``N(x, P)``.

        Parameters
        ----------
        x : array_like, shape (n,)
            Mean.
        P : array_like, shape (n, n)
            Covariance.

        Returns
        -------
        array_like, shape (m, n)
        """
        ...


_REQUIRED = ("n", "Wm", "Wc", "num_sigmas", "sigma_points")
_METHODS = ("num_sigmas", "sigma_points")


class _SymmetricSigmaPoints:
    """``x`` and ``x +/- columns of sqrt(c P)``: the layout Merwe and Julier share.

    Subclasses set ``n``, the spread ``c`` (``_spread``) and the weights.
    """

    batched = True
    n: int
    _spread: float
    Wm: FloatArray
    Wc: FloatArray

    def num_sigmas(self) -> int:
        """Number of sigma points, ``2n + 1``."""
        return 2 * self.n + 1

    @property
    def spread(self) -> float:
        """The factor ``c`` of ``sqrt(c P)`` (Merwe: ``n + lambda``, computed directly)."""
        return self._spread

    def sigma_points(self, x: ArrayLike, P: ArrayLike, *, robust: bool = False) -> FloatArray:
        """Sigma points of ``N(x, P)``, batched over leading axes.

        Parameters
        ----------
        x : array_like, shape (..., n)
            Mean(s).
        P : array_like, shape (..., n, n)
            Covariance(s), symmetric positive definite.
        robust : bool
            If the Cholesky factorisation fails, fall back to a symmetric square
            root with eigenvalues clipped at ``n eps max(eig)`` instead of raising
            (the particle filter uses this so that one round-off-indefinite
            particle covariance does not stop a long run).

        Returns
        -------
        ndarray, shape (..., 2n + 1, n)
            Row 0 is ``x`` itself, rows ``1..n`` are ``x`` plus the columns of the
            lower Cholesky factor of ``c P``, rows ``n+1..2n`` ``x`` minus them.

        Raises
        ------
        ShapeError
            If ``x`` or ``P`` do not end in ``(n,)`` / ``(n, n)``.
        CovarianceError
            If a ``P`` is not positive definite (and ``robust`` is False).
        """
        n = self.n
        x = float_array(x, "x")
        P = float_array(P, "P")
        if x.ndim == 0 or x.shape[-1] != n:
            raise ShapeError(f"x: expected shape (..., {n}), got {x.shape}")
        if P.ndim < 2 or P.shape[-2:] != (n, n):
            raise ShapeError(f"P: expected shape (..., {n}, {n}), got {P.shape}")
        if robust:
            L, _ = sqrt_psd(self._spread * P)
        else:
            L = cholesky(self._spread * P, "P")
        D = np.swapaxes(L, -1, -2)  # rows = columns of L
        xb = x[..., None, :]
        shape = np.broadcast_shapes(xb.shape, D.shape)
        out = np.empty(shape[:-2] + (2 * n + 1, n))
        out[..., 0, :] = x
        out[..., 1 : n + 1, :] = xb + D
        out[..., n + 1 :, :] = xb - D
        return out


class MerweScaledSigmaPoints(_SymmetricSigmaPoints):
    """Scaled symmetric sigma points (van der Merwe, 2004), ``2n + 1`` of them.

    ``lambda = alpha^2 (n + kappa) - n``; the points are ``x`` and
    ``x +/- columns of sqrt((n + lambda) P)`` (lower Cholesky factor). Weights:
    ``Wm[0] = lambda / (n + lambda)``, ``Wc[0] = Wm[0] + 1 - alpha^2 + beta``,
    ``Wm[i] = Wc[i] = 1 / (2 (n + lambda))``.

    Parameters
    ----------
    n : int
        State dimension.
    alpha : float
        Spread, ``0 < alpha <= 1`` typically. Small values (1e-3) give central
        weights of order ``-1/alpha^2`` and lose digits to cancellation; 0.1 - 1 is
        usually accurate enough.
    beta : float
        Prior-knowledge parameter (2 is optimal for Gaussian priors).
    kappa : float
        Secondary scaling (0 or ``3 - n``); ``n + kappa`` must be positive.

    Attributes
    ----------
    Wm, Wc : ndarray, shape (2n + 1,)
        Mean and covariance weights.
    lambda_ : float
        ``alpha^2 (n + kappa) - n``.
    """

    def __init__(self, n: int, alpha: float, beta: float = 2.0, kappa: float = 0.0) -> None:
        self.n = check_dim(n, "n")
        self.alpha = float(alpha)
        self.beta = float(beta)
        self.kappa = float(kappa)
        if not self.alpha > 0.0:
            raise ValueError(f"alpha: expected a positive value, got {alpha}")
        if not self.n + self.kappa > 0.0:
            raise ValueError(f"kappa: expected n + kappa > 0, got n={self.n}, kappa={kappa}")
        # n + lambda computed directly: forming lambda first and adding n back loses
        # ~n eps / (alpha^2 (n + kappa)) relative accuracy for small alpha
        c = self.alpha**2 * (self.n + self.kappa)
        self._spread = c
        self.lambda_ = c - self.n
        self.Wm = np.full(2 * self.n + 1, 0.5 / c)
        self.Wc = self.Wm.copy()
        self.Wm[0] = self.lambda_ / c
        self.Wc[0] = self.lambda_ / c + 1.0 - self.alpha**2 + self.beta


class JulierSigmaPoints(_SymmetricSigmaPoints):
    """The original symmetric sigma points (Julier & Uhlmann, 1997), ``2n + 1`` of them.

    The points are ``x`` and ``x +/- columns of sqrt((n + kappa) P)`` (lower
    Cholesky factor), with the same weights for mean and covariance:
    ``W[0] = kappa / (n + kappa)``, ``W[i] = 1 / (2 (n + kappa))``. ``kappa = 3 - n``
    matches the fourth moments of a Gaussian; ``kappa = 0`` puts no weight on the
    mean. This is :class:`MerweScaledSigmaPoints` with ``alpha = 1``, ``beta = 0``.

    Parameters
    ----------
    n : int
        State dimension.
    kappa : float
        Scaling; ``n + kappa`` must be positive (a negative ``kappa`` gives a
        negative central weight, and the covariance is then not guaranteed
        positive semi-definite).

    Attributes
    ----------
    Wm, Wc : ndarray, shape (2n + 1,)
        Mean and covariance weights (equal arrays, not the same object).
    """

    def __init__(self, n: int, kappa: float = 0.0) -> None:
        self.n = check_dim(n, "n")
        self.kappa = float(kappa)
        if not self.n + self.kappa > 0.0:
            raise ValueError(f"kappa: expected n + kappa > 0, got n={self.n}, kappa={kappa}")
        c = self.n + self.kappa
        self._spread = c
        self.Wm = np.full(2 * self.n + 1, 0.5 / c)
        self.Wm[0] = self.kappa / c
        self.Wc = self.Wm.copy()


class SigmaPointSampler:
    """A checked sigma-point object, called the same way by every unscented filter.

    The constructor checks the :class:`SigmaPoints` interface and the dimension once;
    calling the sampler returns the points of one mean or of a stack, whatever the
    object supports (a set without ``batched = True`` is called once per mean), with
    ``robust=True`` passed through where the object accepts it.

    Parameters
    ----------
    points : SigmaPoints
        The user's sigma-point object.
    n : int
        State dimension it must have been built for.
    robust : bool
        Ask for the round-off-tolerant square root (when ``points.sigma_points`` has
        a ``robust`` keyword).

    Attributes
    ----------
    points : SigmaPoints
        The object itself.
    m : int
        ``points.num_sigmas()``.

    Raises
    ------
    EstimatorTypeError
        If a member of the interface is missing or a method is not callable (the
        message names them).
    ShapeError
        If ``points.n`` differs from ``n`` or the weights are not ``(m,)``.
    """

    def __init__(self, points: Any, n: int, *, robust: bool = False) -> None:
        missing = [name for name in _REQUIRED if not hasattr(points, name)]
        missing += [
            f"{name}() (not callable)"
            for name in _METHODS
            if hasattr(points, name) and not callable(getattr(points, name))
        ]
        if missing:
            what = (
                f"class {points.__name__} (pass an instance)"
                if isinstance(points, type)
                else type(points).__name__
            )
            raise EstimatorTypeError(
                "points: expected a sigma-point object with n, Wm, Wc, num_sigmas() and "
                f"sigma_points(x, P), got {what} without {', '.join(missing)}"
            )
        if points.n != n:
            raise ShapeError(f"points: expected sigma points for n={n}, got n={points.n}")
        m = points.num_sigmas()
        if isinstance(m, bool) or not isinstance(m, int | np.integer) or m < 1:
            raise EstimatorTypeError(f"points.num_sigmas(): expected an int >= 1, got {m!r}")
        for name in ("Wm", "Wc"):
            w = as_float(getattr(points, name), f"points.{name}")
            if w.shape != (m,):
                raise ShapeError(
                    f"points.{name}: expected shape ({m},) for num_sigmas() = {m}, got {w.shape}"
                )
        self.points = points
        self.n = int(n)
        self.m = int(m)
        self._batched = bool(getattr(points, "batched", False))
        takes_robust = _has_keyword(points.sigma_points, "robust")
        self._kw: dict[str, Any] = {"robust": True} if robust and takes_robust else {}

    @property
    def Wm(self) -> Any:
        """The object's mean weights, shape (m,)."""
        return np.asarray(self.points.Wm, dtype=float)

    @property
    def Wc(self) -> Any:
        """The object's covariance weights, shape (m,)."""
        return np.asarray(self.points.Wc, dtype=float)

    def __call__(self, x: FloatArray, P: FloatArray) -> FloatArray:
        """Sigma points of ``N(x, P)``, batched over leading axes.

        Parameters
        ----------
        x : ndarray, shape (..., n)
            Mean(s).
        P : ndarray, shape (..., n, n)
            Covariance(s).

        Returns
        -------
        ndarray, shape (..., m, n)
        """
        fn = self.points.sigma_points
        if self._batched or (x.ndim == 1 and P.ndim == 2):
            sig = np.asarray(fn(x, P, **self._kw), dtype=float)
            lead = x.shape[:-1]
            if P.shape[:-2] != lead:  # np.broadcast_shapes costs more than the points
                lead = np.broadcast_shapes(lead, P.shape[:-2])
            want = lead + (self.m, self.n)
            if sig.shape != want:
                raise ShapeError(
                    f"points.sigma_points: expected output shape {want}, got {sig.shape}"
                )
            return sig
        Pb, xb = broadcast_batch(P, x)
        sig = np.empty(xb.shape[:-1] + (self.m, self.n))
        for i in np.ndindex(xb.shape[:-1]):
            row = np.asarray(fn(xb[i].copy(), Pb[i].copy(), **self._kw), dtype=float)
            if row.shape != (self.m, self.n):
                raise ShapeError(
                    f"points.sigma_points: expected output shape {(self.m, self.n)}, "
                    f"got {row.shape}"
                )
            sig[i] = row
        return sig


def _has_keyword(fn: Any, name: str) -> bool:
    """Whether callable ``fn`` accepts the keyword argument ``name``."""
    try:
        params = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())
