"""The unscented transform and the unscented Kalman filter (additive noise).

Sigma points come from any object with the :class:`SigmaPoints` interface
(:mod:`cosim.estimation.sigma_points`). :func:`ukf_predict` and :func:`ukf_update`
are the batched steps that both the :class:`UnscentedKalmanFilter` (one mean) and the
particle filter (one UKF per particle) run.

Process and measurement functions act on the **last axis**: ``fx(x, dt)`` receives
``x`` of shape ``(..., n)`` and returns ``(..., n)``; ``hx(x)`` returns
``(..., dim_z)``. For a linear model write ``x @ F.T``, not ``F @ x``. Pass
``vectorized=False`` to have them called one point at a time with ``x`` of shape
``(n,)`` instead (slower, simpler to write).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cosim.estimation.checks import (
    ArrayField,
    FloatArray,
    MeanFn,
    ResidualFn,
    ShapeError,
    check_callable,
    check_dim,
    check_measurement,
    check_square,
    measurement_noise,
    set_checked,
)
from cosim.estimation.linalg import float_array, gauss_logpdf, spd_solve, symmetrise
from cosim.estimation.sigma_points import SigmaPoints, SigmaPointSampler

__all__ = [
    "UnscentedKalmanFilter",
    "call_model",
    "check_models",
    "ukf_predict",
    "ukf_update",
    "unscented_transform",
]


def unscented_transform(
    sigmas: ArrayLike,
    Wm: ArrayLike,
    Wc: ArrayLike,
    noise_cov: ArrayLike | None = None,
    mean_fn: MeanFn | None = None,
    residual_fn: ResidualFn | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Mean and covariance of transformed sigma points, batched over leading axes.

    Parameters
    ----------
    sigmas : array_like, shape (..., m, d)
        Transformed sigma points.
    Wm, Wc : array_like, shape (m,)
        Mean and covariance weights.
    noise_cov : array_like, shape (d, d) or (..., d, d), optional
        Additive noise covariance added to the result.
    mean_fn : callable ``mean_fn(sigmas, Wm) -> (..., d)``, optional
        Default ``Wm @ sigmas``; use :func:`angle_mean_fn` for angles.
    residual_fn : callable ``residual_fn(a, b) -> a - b``, optional
        Broadcasting difference; default subtraction; use
        :func:`angle_residual_fn` for angles.

    Returns
    -------
    mean : ndarray, shape (..., d)
    cov : ndarray, shape (..., d, d)
        Symmetrised.
    """
    s = float_array(sigmas, "sigmas")
    if s.ndim < 2:
        raise ShapeError(f"sigmas: expected shape (..., m, d), got {s.shape}")
    m, d = s.shape[-2:]
    Wm = float_array(Wm, "Wm")
    Wc = float_array(Wc, "Wc")
    if Wm.shape != (m,) or Wc.shape != (m,):
        name, w = ("Wm", Wm) if Wm.shape != (m,) else ("Wc", Wc)
        raise ShapeError(f"{name}: expected shape {(m,)}, got {w.shape}")
    mean = Wm @ s if mean_fn is None else np.asarray(mean_fn(s, Wm), dtype=float)
    if mean.shape != s.shape[:-2] + (d,):
        raise ShapeError(f"mean_fn: expected output shape {s.shape[:-2] + (d,)}, got {mean.shape}")
    r = s - mean[..., None, :] if residual_fn is None else residual_fn(s, mean[..., None, :])
    r = np.asarray(r, dtype=float)
    if r.shape != s.shape:
        raise ShapeError(f"residual_fn: expected output shape {s.shape}, got {r.shape}")
    cov = np.swapaxes(r * Wc[:, None], -1, -2) @ r
    if noise_cov is not None:
        nc = float_array(noise_cov, "noise_cov")
        if nc.ndim == 0:
            nc = float(nc) * np.eye(d)
        if nc.shape[-2:] != (d, d):
            raise ShapeError(f"noise_cov: expected shape (..., {d}, {d}), got {nc.shape}")
        cov = cov + nc
    return mean, symmetrise(cov)


def call_model(
    fn: Callable[..., ArrayLike],
    name: str,
    pts: FloatArray,
    args: tuple[Any, ...],
    kwargs: dict[str, Any],
    dim_out: int,
    vectorized: bool,
) -> FloatArray:
    """Apply a model to points, all at once or one by one, and check the output shape.

    Parameters
    ----------
    fn : callable ``fn(x, *args, **kwargs)``
        Process or measurement model.
    name : str
        Its argument name, for the error message (``"fx"``, ``"hx"``).
    pts : ndarray, shape (..., n)
        Points.
    args : tuple
        Positional arguments after the points (``(dt,)`` for ``fx``).
    kwargs : dict
        Keyword arguments.
    dim_out : int
        Output size.
    vectorized : bool
        Call ``fn`` once on the whole stack (True) or once per point of shape ``(n,)``.

    Returns
    -------
    ndarray, shape (..., dim_out)
    """
    want = pts.shape[:-1] + (dim_out,)
    if vectorized:
        out = np.asarray(fn(pts, *args, **kwargs), dtype=float)
    else:
        flat = pts.reshape(-1, pts.shape[-1])
        rows = [np.asarray(fn(p.copy(), *args, **kwargs), dtype=float) for p in flat]
        out = np.array([np.reshape(r, -1) for r in rows]).reshape(want)
    if out.shape != want:
        hint = " (write the model to act on the last axis, or pass vectorized=False)"
        raise ShapeError(f"{name}: expected output shape {want}, got {out.shape}{hint}")
    return out


def ukf_predict(
    x: FloatArray,
    P: FloatArray,
    sampler: SigmaPointSampler,
    fx: Callable[..., ArrayLike],
    dt: float,
    Q: FloatArray,
    x_mean_fn: MeanFn | None,
    residual_x: ResidualFn | None,
    fx_kw: dict[str, Any],
    vectorized: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Unscented time update of ``N(x, P)``, batched over leading axes (UKF and UPF).

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Mean(s).
    P : ndarray, shape (..., n, n)
        Covariance(s).
    sampler : SigmaPointSampler
        The filter's sigma points.
    fx : callable ``fx(x, dt, **fx_kw)``
        Process model (see :class:`UnscentedKalmanFilter`).
    dt : float
        Step [s].
    Q : ndarray, shape (n, n)
        Additive process noise over the step.
    x_mean_fn : callable or None
        State mean function, default the weighted sum.
    residual_x : callable or None
        State difference, default subtraction.
    fx_kw : dict
        Keyword arguments for ``fx``.
    vectorized : bool
        Whether ``fx`` takes stacked points.

    Returns
    -------
    sigmas : ndarray, shape (..., m, n)
        Sigma points of the prior ``N(x, P)``.
    sigmas_f : ndarray, shape (..., m, n)
        Their images through ``fx``.
    x_prior : ndarray, shape (..., n)
    P_prior : ndarray, shape (..., n, n)
    """
    sig = sampler(x, P)
    sig_f = call_model(fx, "fx", sig, (dt,), fx_kw, x.shape[-1], vectorized)
    xp, Pp = unscented_transform(sig_f, sampler.Wm, sampler.Wc, Q, x_mean_fn, residual_x)
    return sig, sig_f, xp, Pp


def ukf_update(
    z: FloatArray,
    x: FloatArray,
    P: FloatArray,
    sampler: SigmaPointSampler,
    hx: Callable[..., ArrayLike],
    R: FloatArray,
    residual_x: ResidualFn | None,
    residual_z: ResidualFn | None,
    z_mean_fn: MeanFn | None,
    hx_kw: dict[str, Any],
    vectorized: bool,
) -> dict[str, FloatArray]:
    """Unscented measurement update of the prior ``N(x, P)``, batched (UKF and UPF).

    The sigma points are redrawn from the prior, so they carry the process noise
    ``Q`` added in the time update; reusing the propagated points would leave ``Q``
    out of ``S`` and ``P_xz``, and the UKF would then differ from the KF on linear
    models.

    Parameters
    ----------
    z : ndarray, shape (dz,)
        Measurement.
    x : ndarray, shape (..., n)
        Prior mean(s).
    P : ndarray, shape (..., n, n)
        Prior covariance(s).
    sampler : SigmaPointSampler
        The filter's sigma points.
    hx : callable ``hx(x, **hx_kw)``
        Measurement model.
    R : ndarray, shape (dz, dz)
        Measurement noise.
    residual_x, residual_z : callable or None
        State and measurement differences, default subtraction.
    z_mean_fn : callable or None
        Measurement mean function, default the weighted sum.
    hx_kw : dict
        Keyword arguments for ``hx``.
    vectorized : bool
        Whether ``hx`` takes stacked points.

    Returns
    -------
    dict of ndarray
        ``sigmas`` and ``sigmas_h`` (..., m, .), ``z_pred`` (..., dz), ``S`` and its
        lower Cholesky factor ``chol_S`` (..., dz, dz), gain ``K`` (..., n, dz),
        innovation ``y`` (..., dz), posterior ``x`` (..., n) and ``P`` (..., n, n).
    """
    sig_f = sampler(x, P)
    dz = z.shape[-1]
    sig_h = call_model(hx, "hx", sig_f, (), hx_kw, dz, vectorized)
    zp, S = unscented_transform(sig_h, sampler.Wm, sampler.Wc, R, z_mean_fn, residual_z)
    rx = sig_f - x[..., None, :] if residual_x is None else residual_x(sig_f, x[..., None, :])
    rz = sig_h - zp[..., None, :] if residual_z is None else residual_z(sig_h, zp[..., None, :])
    Pxz = np.swapaxes(rx * sampler.Wc[:, None], -1, -2) @ rz  # (..., n, dz)
    Kt, L = spd_solve(S, np.swapaxes(Pxz, -1, -2), "S")  # S K^T = Pxz^T
    K = np.swapaxes(Kt, -1, -2)
    y = z - zp if residual_z is None else np.asarray(residual_z(z, zp), dtype=float)
    x_post = x + (K @ y[..., None])[..., 0]
    P_post = symmetrise(P - K @ S @ np.swapaxes(K, -1, -2))
    return {
        "sigmas": sig_f,
        "sigmas_h": sig_h,
        "z_pred": zp,
        "S": S,
        "K": K,
        "y": y,
        "x": x_post,
        "P": P_post,
        "chol_S": L,
    }


def check_models(
    dim_x: int,
    fx: Any,
    hx: Any,
    points: Any,
    *,
    robust: bool = False,
    **optional: Any,
) -> SigmaPointSampler:
    """Argument checks shared by the UKF and the UPF; returns the checked sigma points.

    Parameters
    ----------
    dim_x : int
        State dimension n.
    fx, hx : callable
        Process and measurement models.
    points : SigmaPoints
        Sigma-point object (see :class:`~cosim.estimation.sigma_points.SigmaPoints`).
    robust : bool
        Passed to :class:`SigmaPointSampler`.
    **optional : callable or None
        Further callables to check (residual and mean functions), by argument name.

    Returns
    -------
    SigmaPointSampler
    """
    check_callable(fx, "fx")
    check_callable(hx, "hx")
    sampler = SigmaPointSampler(points, dim_x, robust=robust)
    for name, fn in optional.items():
        if fn is not None:
            check_callable(fn, name)
    return sampler


# ----------------------------------------------------------------------------------------
# Unscented Kalman filter
# ----------------------------------------------------------------------------------------
class UnscentedKalmanFilter:
    """Scaled unscented Kalman filter with additive process and measurement noise.

    Parameters
    ----------
    dim_x : int
        State dimension n.
    dim_z : int
        Measurement dimension m of the default ``R``.
    fx : callable ``fx(x, dt, **kw) -> x_next``
        Process model. With ``vectorized=True`` (default) it receives all sigma
        points at once, ``x`` of shape ``(m, n)`` (``m = points.num_sigmas()``), and
        must act row-wise on the last axis (return ``(m, n)``); with
        ``vectorized=False`` it receives one point of shape ``(n,)``.
    hx : callable ``hx(x, **kw) -> z``
        Measurement model, same convention, output ``(..., m)``.
    points : SigmaPoints
        Sigma-point object with ``points.n == dim_x``: :class:`MerweScaledSigmaPoints`,
        :class:`JulierSigmaPoints` or any object with the same interface (see
        :class:`~cosim.estimation.sigma_points.SigmaPoints`).
    residual_x, residual_z : callable ``(a, b) -> a - b``, optional
        Broadcasting differences of states / measurements (angles:
        :func:`angle_residual_fn`).
    x_mean_fn, z_mean_fn : callable ``(sigmas, Wm) -> mean``, optional
        Weighted means (angles: :func:`angle_mean_fn`).
    vectorized : bool
        See ``fx``.

    Notes
    -----
    The state is not wrapped after the update (``x = x_prior + K y``): an angle
    state may leave (-pi, pi] until the next :meth:`predict` wraps it (through
    ``fx`` or ``x_mean_fn``); read it through :func:`models.conventions.wrap_angle`
    if it matters.

    Attributes
    ----------
    x, P, Q, R
        Estimate, covariance, process noise (zero initially), measurement noise
        (identity initially); shape-checked on assignment.
    points : SigmaPoints
        The sigma-point object; assigning another one checks it like the constructor.
    x_prior, P_prior, sigmas_f
        After :meth:`predict` (``sigmas_f`` shape ``(m, n)``).
    x_post, P_post, K, y, S, z_pred, sigmas_h, log_likelihood
        After :meth:`update`.
    """

    x = ArrayField("dim_x")
    P = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    Q = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    R = ArrayField("dim_z", "dim_z", scalar_is_eye=True)

    def __init__(
        self,
        dim_x: int,
        dim_z: int,
        fx: Callable[..., ArrayLike],
        hx: Callable[..., ArrayLike],
        points: SigmaPoints,
        residual_x: ResidualFn | None = None,
        residual_z: ResidualFn | None = None,
        x_mean_fn: MeanFn | None = None,
        z_mean_fn: MeanFn | None = None,
        *,
        vectorized: bool = True,
    ) -> None:
        self.dim_x = check_dim(dim_x, "dim_x")
        self.dim_z = check_dim(dim_z, "dim_z")
        self._sampler = check_models(
            self.dim_x,
            fx,
            hx,
            points,
            residual_x=residual_x,
            residual_z=residual_z,
            x_mean_fn=x_mean_fn,
            z_mean_fn=z_mean_fn,
        )
        self.fx, self.hx = fx, hx
        self.residual_x, self.residual_z = residual_x, residual_z
        self.x_mean_fn, self.z_mean_fn = x_mean_fn, z_mean_fn
        self.vectorized = bool(vectorized)
        n = self.dim_x
        self.x = np.zeros(n)
        self.P = np.eye(n)
        self.Q = np.zeros((n, n))
        self.R = np.eye(self.dim_z)
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
        self.sigmas_f: FloatArray | None = None
        self.sigmas_h: FloatArray | None = None
        self.K: FloatArray | None = None
        self.y: FloatArray | None = None
        self.S: FloatArray | None = None
        self.z_pred: FloatArray | None = None
        self.log_likelihood = None

    @property
    def log_likelihood(self) -> float | None:
        """``log N(y; 0, S)`` of the last update's innovation (None before any update).

        Computed from the update's innovation and the Cholesky factor of ``S`` the first
        time it is read after the update.
        """
        if self._loglik is None and self._loglik_from is not None:
            y, L = self._loglik_from
            self._loglik = float(gauss_logpdf(y, L))
            self._loglik_from = None
        return self._loglik

    @log_likelihood.setter
    def log_likelihood(self, value: float | None) -> None:
        self._loglik = value
        self._loglik_from = None

    @property
    def points(self) -> SigmaPoints:
        """The sigma-point object."""
        return self._sampler.points

    @points.setter
    def points(self, value: SigmaPoints) -> None:
        self._sampler = SigmaPointSampler(value, self.dim_x)

    def predict(
        self,
        dt: float,
        fx: Callable[..., ArrayLike] | None = None,
        Q: ArrayLike | None = None,
        **fx_args: Any,
    ) -> None:
        """Time update through the sigma points.

        Parameters
        ----------
        dt : float
            Step [s], passed to ``fx``.
        fx : callable, optional
            Process model for this call only.
        Q : array_like, shape (n, n) or scalar, optional
            Process noise for this call only.
        **fx_args
            Extra keyword arguments for ``fx`` (e.g. sensor increments).
        """
        fx = self.fx if fx is None else fx
        check_callable(fx, "fx")
        Q = self.Q if Q is None else check_square(Q, "Q", self.dim_x)
        _, self.sigmas_f, x, P = ukf_predict(
            self.x,
            self.P,
            self._sampler,
            fx,
            dt,
            Q,
            self.x_mean_fn,
            self.residual_x,
            fx_args,
            self.vectorized,
        )
        set_checked(self, x=x, P=P)
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()

    def update(
        self,
        z: ArrayLike | None,
        R: ArrayLike | None = None,
        hx: Callable[..., ArrayLike] | None = None,
        **hx_args: Any,
    ) -> None:
        """Measurement update.

        Sigma points are drawn afresh from the current ``(x, P)``, so they include
        the process noise added by :meth:`predict` (with additive noise this makes
        the UKF identical to the KF on linear models) and any earlier update in the
        same step. ``sigmas_h`` holds their images through ``hx``.

        Parameters
        ----------
        z : array_like, shape (m,), or None
            Measurement; ``None`` skips the update.
        R : array_like, shape (m, m) or scalar, optional
            Measurement noise for this call (default ``self.R``).
        hx : callable, optional
            Measurement model for this call (its output size sets ``m``).
        **hx_args
            Extra keyword arguments for ``hx``.
        """
        if z is None:
            self.K = self.y = self.S = self.z_pred = self.sigmas_h = None
            self.log_likelihood = None
            self.x_post = self.x.copy()
            self.P_post = self.P.copy()
            return
        hx = self.hx if hx is None else hx
        check_callable(hx, "hx")
        z = check_measurement(z)
        m = z.size
        R = measurement_noise(R, self.R, self.dim_z, m)
        out = ukf_update(
            z,
            self.x,
            self.P,
            self._sampler,
            hx,
            R,
            self.residual_x,
            self.residual_z,
            self.z_mean_fn,
            hx_args,
            self.vectorized,
        )
        self.sigmas_h = out["sigmas_h"]
        self.z_pred, self.S, self.K, self.y = out["z_pred"], out["S"], out["K"], out["y"]
        self._loglik = None  # computed when read (a filter that never reads it saves it)
        self._loglik_from = (self.y.copy(), out["chol_S"])
        set_checked(self, x=out["x"], P=out["P"])
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
