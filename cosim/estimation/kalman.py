"""Linear and extended Kalman filters, and the one Joseph-form measurement update.

:func:`joseph_update` is the update of every Kalman-type filter of the project: the
:class:`KalmanFilter` and :class:`ExtendedKalmanFilter` here, and the covariance-only
analyses of the alignment filters. States are ``(n,)`` arrays, covariances ``(n, n)``;
every covariance leaving a step is symmetrised as ``(P + P^T) / 2``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from cosim.estimation.checks import (
    ArrayField,
    FloatArray,
    ResidualFn,
    ShapeError,
    as_float,
    check_callable,
    check_dim,
    check_finite,
    check_measurement,
    check_shape,
    check_square,
    measurement_noise,
    set_checked,
)
from cosim.estimation.linalg import gauss_logpdf, spd_solve, symmetrise

__all__ = ["ExtendedKalmanFilter", "KalmanFilter", "joseph_update"]


def joseph_update(
    x: FloatArray, P: FloatArray, y: FloatArray, H: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float]:
    """Linear(ised) Kalman measurement update, covariance in the Joseph form.

    ``S = H P H^T + R``, ``K = P H^T S^-1``, ``x_post = x + K y`` and
    ``P_post = (I - K H) P (I - K H)^T + K R K^T``; ``S`` and ``P_post`` are
    symmetrised as ``(M + M^T) / 2``. This is the update every filter of the
    package uses; covariance analyses call it with ``y = 0`` to propagate ``P``
    alone. The inputs are used as given (no shape checks, no copies): pass
    float arrays of the shapes below.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Prior state estimate.
    P : ndarray, shape (n, n)
        Prior covariance (symmetric positive semi-definite).
    y : ndarray, shape (m,)
        Innovation ``z - h(x)`` (a residual in the measurement's units).
    H : ndarray, shape (m, n)
        Measurement matrix (or Jacobian at the prior).
    R : ndarray, shape (m, m)
        Measurement noise covariance.

    Returns
    -------
    x_post : ndarray, shape (n,)
        Posterior state estimate.
    P_post : ndarray, shape (n, n)
        Posterior covariance (exactly symmetric).
    K : ndarray, shape (n, m)
        Kalman gain.
    S : ndarray, shape (m, m)
        Innovation covariance (exactly symmetric).
    log_likelihood : float
        ``log N(y; 0, S)`` of the innovation.

    Raises
    ------
    CovarianceError
        If ``S`` is not positive definite.
    """
    PHt = P @ H.T
    S = symmetrise(H @ PHt + R)
    Kt, L = spd_solve(S, PHt.T, "S")  # S K^T = H P
    K = Kt.T
    x_post = x + K @ y
    I_KH = np.eye(x.size) - K @ H
    P_post = symmetrise(I_KH @ P @ I_KH.T + K @ R @ K.T)
    loglik = float(gauss_logpdf(y, L))
    return x_post, P_post, K, S, loglik


class KalmanFilter:
    """Linear Kalman filter, ``x_k = F x_(k-1) + B u + w``, ``z = H x + v``.

    Set ``x``, ``P``, ``F``, ``Q``, ``H``, ``R`` (and ``B``) as attributes; they are
    checked for shape on assignment (square ones also accept a scalar ``s * I``).
    After :meth:`predict`: ``x_prior``, ``P_prior``. After :meth:`update`:
    ``x_post``, ``P_post``, gain ``K``, innovation ``y``, innovation covariance
    ``S`` and ``log_likelihood`` of the measurement.

    Parameters
    ----------
    dim_x : int
        State dimension n.
    dim_z : int
        Measurement dimension m of the default ``H``/``R``.
    dim_u : int
        Control dimension (0: no control input).

    Attributes
    ----------
    x : ndarray, shape (n,)
        State estimate (zeros initially).
    P : ndarray, shape (n, n)
        Covariance (identity initially).
    F : ndarray, shape (n, n)
        Transition matrix (identity initially).
    Q : ndarray, shape (n, n)
        Process noise covariance (zero initially).
    H : ndarray, shape (m, n)
        Measurement matrix (zero initially).
    R : ndarray, shape (m, m)
        Measurement noise covariance (identity initially).
    B : ndarray, shape (n, dim_u)
        Control matrix (zero initially).
    """

    x = ArrayField("dim_x")
    P = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    F = ArrayField("dim_x", "dim_x")
    Q = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    H = ArrayField("dim_z", "dim_x")
    R = ArrayField("dim_z", "dim_z", scalar_is_eye=True)
    B = ArrayField("dim_x", "dim_u")

    def __init__(self, dim_x: int, dim_z: int, dim_u: int = 0) -> None:
        self.dim_x = check_dim(dim_x, "dim_x")
        self.dim_z = check_dim(dim_z, "dim_z")
        self.dim_u = check_dim(dim_u, "dim_u", minimum=0)
        n, m = self.dim_x, self.dim_z
        self.x = np.zeros(n)
        self.P = np.eye(n)
        self.F = np.eye(n)
        self.Q = np.zeros((n, n))
        self.H = np.zeros((m, n))
        self.R = np.eye(m)
        self.B = np.zeros((n, self.dim_u))
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
        self.K: FloatArray | None = None
        self.y: FloatArray | None = None
        self.S: FloatArray | None = None
        self.log_likelihood: float | None = None

    def predict(
        self, u: ArrayLike | None = None, F: ArrayLike | None = None, Q: ArrayLike | None = None
    ) -> None:
        """Time update ``x = F x + B u``, ``P = F P F^T + Q``.

        Parameters
        ----------
        u : array_like, shape (dim_u,), optional
            Control input (requires ``dim_u > 0``).
        F : array_like, shape (n, n), optional
            Transition matrix for this step only (default ``self.F``).
        Q : array_like, shape (n, n) or scalar, optional
            Process noise for this step only (default ``self.Q``).
        """
        n = self.dim_x
        F = self.F if F is None else check_shape(F, "F", (n, n))
        Q = self.Q if Q is None else check_square(Q, "Q", n)
        x = F @ self.x
        if u is not None:
            if self.dim_u == 0:
                raise ValueError("u: expected None for a filter built with dim_u=0, got an input")
            x = x + self.B @ check_shape(u, "u", (self.dim_u,))
        set_checked(self, x=x, P=symmetrise(F @ self.P @ F.T + Q))
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()

    def update(
        self, z: ArrayLike | None, H: ArrayLike | None = None, R: ArrayLike | None = None
    ) -> None:
        """Measurement update (Joseph form).

        Parameters
        ----------
        z : array_like, shape (m,), or None
            Measurement. ``None`` skips the update (``x_post = x``; ``K``, ``y``,
            ``S`` are set to None).
        H : array_like, shape (m, n), optional
            Measurement matrix for this call (default ``self.H``); its row count
            sets ``m``, so measurements of another size can be processed.
        R : array_like, shape (m, m) or scalar, optional
            Measurement noise for this call (default ``self.R``).
        """
        if z is None:
            self._skip_update()
            return
        n = self.dim_x
        if H is None:
            H = self.H
        else:
            H = as_float(H, "H")
            if H.ndim == 1:
                H = H[None, :]
            if H.ndim != 2 or H.shape[1] != n:
                raise ShapeError(f"H: expected shape (m, {n}), got {H.shape}")
        m = H.shape[0]
        z = as_float(z, "z")
        if z.ndim == 0 and m == 1:
            z = z[None]
        if z.shape != (m,):
            raise ShapeError(f"z: expected shape {(m,)}, got {z.shape}")
        check_finite(z, "z")
        R = measurement_noise(R, self.R, self.dim_z, m)
        self.y = z - H @ self.x
        x, P, self.K, self.S, self.log_likelihood = joseph_update(self.x, self.P, self.y, H, R)
        set_checked(self, x=x, P=P)
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()

    def _skip_update(self) -> None:
        self.K = self.y = self.S = None
        self.log_likelihood = None
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()


class ExtendedKalmanFilter:
    """Extended Kalman filter with user-supplied models passed per call.

    ``predict(dt, f, F)`` propagates ``x = f(x, dt)`` and ``P = F P F^T + Q`` with the
    Jacobian ``F`` evaluated at the estimate *before* propagation; ``update(z, h,
    H_jac, ...)`` linearises ``h`` at the prior. Inspectable after each call:
    ``x_prior``, ``P_prior``, ``x_post``, ``P_post``, ``F`` (last transition
    matrix), ``H`` (last measurement Jacobian), ``K``, ``y``, ``S``, ``z_pred``,
    ``log_likelihood``.

    Parameters
    ----------
    dim_x : int
        State dimension n.
    dim_z : int
        Measurement dimension m of the default ``R``.

    Attributes
    ----------
    x, P, Q, R, F
        As in :class:`KalmanFilter` (``Q`` zero, ``R`` identity initially).
    """

    x = ArrayField("dim_x")
    P = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    F = ArrayField("dim_x", "dim_x")
    Q = ArrayField("dim_x", "dim_x", scalar_is_eye=True)
    R = ArrayField("dim_z", "dim_z", scalar_is_eye=True)

    def __init__(self, dim_x: int, dim_z: int) -> None:
        self.dim_x = check_dim(dim_x, "dim_x")
        self.dim_z = check_dim(dim_z, "dim_z")
        n, m = self.dim_x, self.dim_z
        self.x = np.zeros(n)
        self.P = np.eye(n)
        self.F = np.eye(n)
        self.Q = np.zeros((n, n))
        self.R = np.eye(m)
        self.H: FloatArray | None = None
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
        self.K: FloatArray | None = None
        self.y: FloatArray | None = None
        self.S: FloatArray | None = None
        self.z_pred: FloatArray | None = None
        self.log_likelihood: float | None = None

    def predict(
        self,
        dt: float = 1.0,
        f: Callable[[FloatArray, float], ArrayLike] | None = None,
        F: Callable[[FloatArray, float], ArrayLike] | ArrayLike | None = None,
        Q: ArrayLike | None = None,
    ) -> None:
        """Time update.

        Parameters
        ----------
        dt : float
            Step [s], passed to ``f`` and ``F``.
        f : callable ``f(x, dt) -> x_next``, optional
            Nonlinear transition, ``x`` shape (n,). Default: ``x_next = F x``.
        F : callable ``F(x, dt) -> (n, n)`` or array_like (n, n), optional
            Jacobian of ``f`` at the current estimate, or a fixed transition matrix.
            Default: ``self.F``.
        Q : array_like, shape (n, n) or scalar, optional
            Process noise over this step (default ``self.Q``).
        """
        n = self.dim_x
        if F is None:
            Fm = self.F
        elif callable(F):
            Fm = check_shape(F(self.x.copy(), dt), "F(x, dt)", (n, n))
        else:
            Fm = check_shape(F, "F", (n, n))
        Q = self.Q if Q is None else check_square(Q, "Q", n)
        if f is None:
            x = Fm @ self.x
        else:
            check_callable(f, "f")
            x = check_shape(f(self.x.copy(), dt), "f(x, dt)", (n,))
        set_checked(self, F=Fm)
        set_checked(self, x=x, P=symmetrise(Fm @ self.P @ Fm.T + Q))
        self.x_prior = self.x.copy()
        self.P_prior = self.P.copy()

    def update(
        self,
        z: ArrayLike | None,
        h: Callable[[FloatArray], ArrayLike],
        H_jac: Callable[[FloatArray], ArrayLike] | ArrayLike,
        R: ArrayLike | None = None,
        residual: ResidualFn | None = None,
    ) -> None:
        """Measurement update linearised at the prior (Joseph form).

        Parameters
        ----------
        z : array_like, shape (m,), or None
            Measurement; ``None`` skips the update.
        h : callable ``h(x) -> (m,)``
            Measurement function.
        H_jac : callable ``H_jac(x) -> (m, n)`` or array_like (m, n)
            Jacobian of ``h`` at the prior, or a fixed matrix.
        R : array_like, shape (m, m) or scalar, optional
            Measurement noise (default ``self.R``).
        residual : callable ``residual(z, z_pred) -> (m,)``, optional
            Innovation function, e.g. ``angle_residual_fn([2])`` when the
            measurement holds a heading. Default ``z - z_pred``.
        """
        if z is None:
            self.K = self.y = self.S = self.z_pred = None
            self.log_likelihood = None
            self.x_post = self.x.copy()
            self.P_post = self.P.copy()
            return
        check_callable(h, "h")
        n = self.dim_x
        z = check_measurement(z)
        m = z.size
        Hm = H_jac(self.x.copy()) if callable(H_jac) else H_jac
        Hm = check_shape(Hm, "H_jac", (m, n))
        R = measurement_noise(R, self.R, self.dim_z, m)
        zp = check_shape(h(self.x.copy()), "h(x)", (m,))
        if residual is None:
            y = z - zp
        else:
            check_callable(residual, "residual")
            y = check_shape(residual(z, zp), "residual(z, z_pred)", (m,))
        self.H = Hm
        self.z_pred = zp
        self.y = y
        x, P, self.K, self.S, self.log_likelihood = joseph_update(self.x, self.P, y, Hm, R)
        set_checked(self, x=x, P=P)
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
