"""Estimators shared by every alignment filter: KF, EKF, scaled UKF and UPF.

Everything here is pure numpy/scipy. Stochastic code never touches global random
state: it takes an explicit :class:`numpy.random.Generator`.

Conventions
-----------
* State vectors are 1-D arrays of shape ``(n,)`` (not column vectors); covariances
  are ``(n, n)``. Units are whatever the caller's model uses (SI in this project:
  rad, rad/s, m/s, m/s2); nothing here converts units.
* Batched code (unscented transform, sigma points, the particle filter) works on
  leading axes: a stack of ``N`` states is ``(N, n)``, a stack of covariances
  ``(N, n, n)``, the sigma points of that stack ``(N, 2n + 1, n)``.
* Process and measurement functions for the UKF/UPF act on the **last axis**:
  ``fx(x, dt)`` receives ``x`` of shape ``(..., n)`` and returns ``(..., n)``;
  ``hx(x)`` returns ``(..., dim_z)``. For a linear model write ``x @ F.T``, not
  ``F @ x``. Pass ``vectorized=False`` to have them called one point at a time
  with ``x`` of shape ``(n,)`` instead (slower, simpler to write).
* Residual functions ``residual(a, b)`` return ``a - b`` and must broadcast over
  leading axes; mean functions ``mean_fn(sigmas, weights)`` take
  ``sigmas (..., m, n)`` and ``weights (m,)`` and return ``(..., n)``.
  :func:`angle_residual_fn` and :func:`angle_mean_fn` build both for states or
  measurements that contain angles (heading), so that they are differenced and
  averaged on the circle.
* Covariance updates of the KF/EKF use the Joseph form; every covariance leaving
  a filter step is symmetrised as ``(P + P.T) / 2``, which is exactly symmetric
  in floating point.

Errors
------
Bad shapes raise :class:`ShapeError` (a ``ValueError``) whose message names the
argument: ``"z: expected shape (2,), got (3,)"``. Non-callables and non-numeric
inputs raise :class:`EstimatorTypeError` (a ``TypeError``). A covariance that is
not positive definite where it has to be raises :class:`CovarianceError` (a
``numpy.linalg.LinAlgError``, hence also a ``ValueError``). A particle filter
whose weights all vanish raises :class:`DegenerateWeightsError`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm
from scipy.special import logsumexp

__all__ = [
    "CovarianceError",
    "DegenerateWeightsError",
    "EstimatorTypeError",
    "ExtendedKalmanFilter",
    "KalmanFilter",
    "MerweScaledSigmaPoints",
    "ShapeError",
    "UnscentedKalmanFilter",
    "UnscentedParticleFilter",
    "anees_bounds",
    "angle_mean",
    "angle_mean_fn",
    "angle_residual",
    "angle_residual_fn",
    "joseph_update",
    "nees",
    "nis",
    "observability_matrix",
    "observability_rank",
    "piecewise_observability_matrix",
    "piecewise_observability_rank",
    "stripped_condition_holds",
    "systematic_resample",
    "unscented_transform",
    "van_loan",
    "wrap_angle",
]

FloatArray = NDArray[np.float64]
ResidualFn = Callable[[FloatArray, FloatArray], FloatArray]
MeanFn = Callable[[FloatArray, FloatArray], FloatArray]

_LOG_2PI = float(np.log(2.0 * np.pi))


# ----------------------------------------------------------------------------------------
# Errors
# ----------------------------------------------------------------------------------------
class ShapeError(ValueError):
    """An array argument has the wrong shape (the message names the argument)."""


class EstimatorTypeError(TypeError):
    """An argument has the wrong type (not callable, not numeric, ...)."""


class CovarianceError(np.linalg.LinAlgError):
    """A covariance that must be symmetric positive definite is not."""


class DegenerateWeightsError(FloatingPointError):
    """All particle weights vanished (every particle is incompatible with the data)."""


# ----------------------------------------------------------------------------------------
# Validation helpers
# ----------------------------------------------------------------------------------------
def _as_float(value: Any, name: str) -> FloatArray:
    """Convert ``value`` to a float array (a copy), or raise EstimatorTypeError."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise EstimatorTypeError(
            f"{name}: expected a real array, got {type(value).__name__}"
        ) from exc


def _check_shape(value: Any, name: str, shape: tuple[int, ...]) -> FloatArray:
    arr = _as_float(value, name)
    if arr.shape != shape:
        raise ShapeError(f"{name}: expected shape {shape}, got {arr.shape}")
    return arr


def _check_square(value: Any, name: str, n: int) -> FloatArray:
    """A ``(n, n)`` matrix; a scalar ``s`` is read as ``s * I``."""
    arr = _as_float(value, name)
    if arr.ndim == 0:
        return float(arr) * np.eye(n)
    if arr.shape != (n, n):
        raise ShapeError(f"{name}: expected shape {(n, n)} or a scalar, got {arr.shape}")
    return arr


def _check_matrix(value: Any, name: str) -> FloatArray:
    arr = _as_float(value, name)
    if arr.ndim != 2:
        raise ShapeError(f"{name}: expected a 2-D array, got shape {arr.shape}")
    return arr


def _check_dim(value: Any, name: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise EstimatorTypeError(f"{name}: expected an int, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name}: expected an int >= {minimum}, got {value}")
    return int(value)


def _check_callable(value: Any, name: str) -> None:
    if not callable(value):
        raise EstimatorTypeError(f"{name}: expected a callable, got {type(value).__name__}")


def _check_finite(arr: FloatArray, name: str) -> None:
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected finite values, got {arr!r}")


def _meas_noise(R: Any, default: FloatArray, dim_z: int, m: int) -> FloatArray:
    """The measurement noise of one update: ``R`` if given, else the filter's own."""
    if R is not None:
        return _check_square(R, "R", m)
    if m != dim_z:
        raise ShapeError(
            f"R: expected an explicit ({m}, {m}) noise covariance for a measurement of "
            f"size {m} (the filter's R is {dim_z}x{dim_z}), got None"
        )
    return default


def _symmetrise(P: FloatArray) -> FloatArray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def _cholesky(P: FloatArray, name: str) -> FloatArray:
    """Lower Cholesky factor (batched); CovarianceError naming ``name`` on failure."""
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError as exc:
        raise CovarianceError(
            f"{name}: expected a symmetric positive definite matrix, "
            "got one whose Cholesky factorisation failed"
        ) from exc


def _spd_solve(S: FloatArray, B: FloatArray, name: str) -> tuple[FloatArray, FloatArray]:
    """Solve ``S X = B`` for SPD ``S`` (batched over leading axes).

    Returns ``X`` and the lower Cholesky factor of ``S`` (which also certifies that
    ``S`` is positive definite). numpy's gufuncs are used rather than
    ``scipy.linalg.solve_triangular``, whose batching loops in Python.
    """
    L = _cholesky(S, name)
    return np.linalg.solve(S, B), L


def _mahalanobis2(r: FloatArray, L: FloatArray) -> FloatArray:
    """Squared Mahalanobis norms ``r^T (L L^T)^-1 r`` of ``r (..., d)``, L lower ``(..., d, d)``."""
    if L.ndim > 2 or r.ndim > 1:
        L, r = _broadcast_batch(L, r)
    u = np.linalg.solve(L, r[..., None])[..., 0]
    return np.sum(u * u, axis=-1)


def _gauss_logpdf(r: FloatArray, L: FloatArray, m2: FloatArray | None = None) -> FloatArray:
    """Log density of residuals ``r (..., d)`` under N(0, L L^T), L lower ``(..., d, d)``.

    ``m2``: their :func:`_mahalanobis2` when the caller has it already.
    """
    if m2 is None:
        m2 = _mahalanobis2(r, L)
    d = r.shape[-1]
    half_logdet = np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
    return -0.5 * m2 - half_logdet - 0.5 * d * _LOG_2PI


def _broadcast_batch(M: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Broadcast the leading axes of matrices ``(..., d, d)`` and vectors ``(..., d)``."""
    d = v.shape[-1]
    batch = np.broadcast_shapes(M.shape[:-2], v.shape[:-1])
    return np.broadcast_to(M, batch + (d, d)), np.broadcast_to(v, batch + (d,))


class _ArrayField:
    """Data descriptor for filter matrices: converts on assignment and checks shape.

    ``shape_of(instance)`` gives the expected shape; square fields accept a scalar
    ``s`` meaning ``s * I``. Values are copied on assignment, so a filter never
    aliases the caller's arrays.
    """

    def __init__(
        self, shape_of: Callable[[Any], tuple[int, ...]], *, scalar_is_eye: bool = False
    ) -> None:
        self.shape_of = shape_of
        self.scalar_is_eye = scalar_is_eye
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        return obj.__dict__[self.name]

    def __set__(self, obj: Any, value: Any) -> None:
        shape = self.shape_of(obj)
        if self.scalar_is_eye:
            arr = _check_square(value, self.name, shape[0])
        else:
            arr = _check_shape(value, self.name, shape)
        obj.__dict__[self.name] = arr


def _store(obj: Any, **arrays: FloatArray) -> None:
    """Internal fast path past :class:`_ArrayField`: results are already checked."""
    obj.__dict__.update(arrays)


def _vec(obj: Any) -> tuple[int, ...]:
    return (obj.dim_x,)


def _sq_x(obj: Any) -> tuple[int, ...]:
    return (obj.dim_x, obj.dim_x)


def _sq_z(obj: Any) -> tuple[int, ...]:
    return (obj.dim_z, obj.dim_z)


def _hz(obj: Any) -> tuple[int, ...]:
    return (obj.dim_z, obj.dim_x)


def _bu(obj: Any) -> tuple[int, ...]:
    return (obj.dim_x, obj.dim_u)


# ----------------------------------------------------------------------------------------
# Discretisation and observability
# ----------------------------------------------------------------------------------------
def van_loan(A: ArrayLike, G: ArrayLike, Qc: ArrayLike, dt: float) -> tuple[FloatArray, FloatArray]:
    """Exact discretisation of ``x' = A x + G w``, ``E[w(t) w(s)^T] = Qc delta(t - s)``.

    Van Loan (1978): with ``M = [[-A, G Qc G^T], [0, A^T]] dt`` and
    ``expm(M) = [[., E12], [0, E22]]``, ``Phi = E22^T`` and ``Qd = Phi E12``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Continuous-time system matrix [1/s].
    G : array_like, shape (n, p)
        Noise input matrix.
    Qc : array_like, shape (p, p), or scalar when p == 1
        Two-sided power spectral density of ``w`` [unit(w)^2 * s].
    dt : float
        Step [s], ``dt >= 0``.

    Returns
    -------
    Phi : ndarray, shape (n, n)
        Transition matrix ``expm(A dt)``.
    Qd : ndarray, shape (n, n)
        Covariance of the noise accumulated over ``dt``,
        ``int_0^dt expm(A s) G Qc G^T expm(A^T s) ds`` (symmetrised).

    Raises
    ------
    ShapeError
        If the shapes of ``A``, ``G``, ``Qc`` do not agree.
    """
    A = _check_matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise ShapeError(f"A: expected a square matrix, got shape {A.shape}")
    G = _as_float(G, "G")
    if G.ndim == 1:
        G = G[:, None]
    if G.ndim != 2 or G.shape[0] != n:
        raise ShapeError(f"G: expected shape ({n}, p), got {G.shape}")
    Qc = _check_square(Qc, "Qc", G.shape[1])
    dt = float(dt)
    if not np.isfinite(dt) or dt < 0.0:
        raise ValueError(f"dt: expected a finite step >= 0, got {dt}")
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = G @ Qc @ G.T
    M[n:, n:] = A.T
    E = expm(M * dt)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    return Phi, _symmetrise(Qd)


def observability_matrix(A: ArrayLike, H: ArrayLike) -> FloatArray:
    """Observability matrix ``[H; H A; ...; H A^(n-1)]`` (``control.obsv``).

    Parameters
    ----------
    A : array_like, shape (n, n)
        System matrix (continuous or discrete time).
    H : array_like, shape (m, n)
        Measurement matrix.

    Returns
    -------
    ndarray, shape (m * n, n)
    """
    A = _check_matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise ShapeError(f"A: expected a square matrix, got shape {A.shape}")
    H = _as_float(H, "H")
    if H.ndim == 1:
        H = H[None, :]
    if H.ndim != 2 or H.shape[1] != n:
        raise ShapeError(f"H: expected shape (m, {n}), got {H.shape}")
    import control  # lazy: python-control takes ~1.5 s to import; filters do not need it

    return np.asarray(control.obsv(A, H), dtype=float)


def _numerical_rank(O: FloatArray, tol: float | None, normalize: bool) -> int:
    if normalize:
        norms = np.linalg.norm(O, axis=0)
        O = O / np.where(norms > 0.0, norms, 1.0)
    return int(np.linalg.matrix_rank(O, tol=tol))


def observability_rank(
    A: ArrayLike, H: ArrayLike, *, tol: float | None = None, normalize: bool = True
) -> int:
    """Numerical rank of the observability matrix of ``(A, H)``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        System matrix.
    H : array_like, shape (m, n)
        Measurement matrix.
    tol : float, optional
        Singular-value threshold passed to :func:`numpy.linalg.matrix_rank`
        (default: numpy's, relative to the largest singular value).
    normalize : bool
        Scale every column of the observability matrix to unit norm first. This is a
        change of state units, so it does not change the rank in exact arithmetic,
        but it keeps states of very different magnitudes (rad vs m/s vs rad/s of
        gyro drift) from hiding behind the SVD threshold. Default True.

    Returns
    -------
    int
        Number of observable directions (``n`` means fully observable).
    """
    return _numerical_rank(observability_matrix(A, H), tol, normalize)


Segment = tuple[ArrayLike, ArrayLike, float]


def _check_segments(segments: Sequence[Segment]) -> list[tuple[FloatArray, FloatArray, float]]:
    if isinstance(segments, np.ndarray) or not isinstance(segments, Sequence):
        raise EstimatorTypeError(
            f"segments: expected a sequence of (A, H, dt) tuples, got {type(segments).__name__}"
        )
    if len(segments) == 0:
        raise ValueError("segments: expected at least one (A, H, dt) segment, got none")
    out = []
    n = None
    for i, seg in enumerate(segments):
        if len(seg) != 3:
            raise ShapeError(f"segments[{i}]: expected an (A, H, dt) triple, got {len(seg)} items")
        A = _check_matrix(seg[0], f"segments[{i}].A")
        if n is None:
            n = A.shape[0]
        if A.shape != (n, n):
            raise ShapeError(f"segments[{i}].A: expected shape {(n, n)}, got {A.shape}")
        H = _as_float(seg[1], f"segments[{i}].H")
        if H.ndim == 1:
            H = H[None, :]
        if H.ndim != 2 or H.shape[1] != n:
            raise ShapeError(f"segments[{i}].H: expected shape (m, {n}), got {H.shape}")
        out.append((A, H, float(seg[2])))
    return out


def piecewise_observability_matrix(
    segments: Sequence[Segment], *, method: Literal["total", "stripped"] = "total"
) -> FloatArray:
    """Observability matrix of a piecewise-constant system (multi-position alignment).

    Segment ``j`` runs the continuous-time model ``(A_j, H_j)`` for ``dt_j`` seconds
    (e.g. one platform position), and ``O_j`` is its observability matrix.

    * ``"total"`` (TOM, exact): ``[O_1; O_2 Phi_1; O_3 Phi_2 Phi_1; ...]`` with
      ``Phi_j = expm(A_j dt_j)``, i.e. every segment's information is referred to
      the initial state.
    * ``"stripped"`` (SOM, Goshen-Meskin & Bar-Itzhack 1992): ``[O_1; O_2; ...]``.
      Its rank equals the TOM's when ``null(O_j)`` is contained in ``null(A_j)``
      for every segment (check with :func:`stripped_condition_holds`); the
      ``dt_j`` are ignored.

    Parameters
    ----------
    segments : sequence of (A, H, dt)
        ``A`` shape (n, n) [1/s], ``H`` shape (m_j, n), ``dt`` duration [s].
    method : {"total", "stripped"}
        Which matrix to build.

    Returns
    -------
    ndarray, shape (sum_j m_j * n, n)
    """
    segs = _check_segments(segments)
    if method not in ("total", "stripped"):
        raise ValueError(f"method: expected 'total' or 'stripped', got {method!r}")
    blocks = []
    Phi = np.eye(segs[0][0].shape[0])
    for A, H, dt in segs:
        O = observability_matrix(A, H)
        blocks.append(O @ Phi if method == "total" else O)
        if method == "total":
            Phi = expm(A * dt) @ Phi
    return np.vstack(blocks)


def piecewise_observability_rank(
    segments: Sequence[Segment],
    *,
    method: Literal["total", "stripped"] = "total",
    tol: float | None = None,
    normalize: bool = True,
) -> int:
    """Numerical rank of :func:`piecewise_observability_matrix`.

    Parameters
    ----------
    segments : sequence of (A, H, dt)
        See :func:`piecewise_observability_matrix`.
    method : {"total", "stripped"}
        TOM (exact) or SOM.
    tol : float, optional
        Singular-value threshold, as in :func:`observability_rank` (default numpy's).
    normalize : bool
        Scale every column to unit norm before the SVD, as in :func:`observability_rank`
        (default True).

    Returns
    -------
    int
        Number of observable directions of the initial state over all segments.
    """
    return _numerical_rank(piecewise_observability_matrix(segments, method=method), tol, normalize)


def stripped_condition_holds(segments: Sequence[Segment], *, tol: float | None = None) -> bool:
    """Whether ``null(O_j)`` lies in ``null(A_j)`` for every segment (then SOM rank = TOM rank).

    Tested as ``rank([O_j; A_j]) == rank(O_j)`` (the null space of the stacked matrix
    is the intersection of both null spaces), with column-normalised numerical
    ranks as in :func:`observability_rank`.

    Parameters
    ----------
    segments : sequence of (A, H, dt)
        See :func:`piecewise_observability_matrix`.
    tol : float, optional
        SVD threshold, as in :func:`observability_rank`.

    Returns
    -------
    bool
    """
    for A, H, _ in _check_segments(segments):
        O = observability_matrix(A, H)
        if _numerical_rank(np.vstack([O, A]), tol, True) != _numerical_rank(O, tol, True):
            return False
    return True


# ----------------------------------------------------------------------------------------
# Consistency statistics
# ----------------------------------------------------------------------------------------
def _normalised_square(e: Any, P: Any, e_name: str, P_name: str) -> FloatArray | float:
    e = _as_float(e, e_name)
    P = _as_float(P, P_name)
    if e.ndim == 0:
        e = e[None]
    n = e.shape[-1]
    if P.ndim < 2 or P.shape[-2:] != (n, n):
        raise ShapeError(f"{P_name}: expected shape (..., {n}, {n}), got {P.shape}")
    L = _cholesky(P, P_name)
    L, eb = _broadcast_batch(L, e)
    u = np.linalg.solve(L, eb[..., None])
    out = np.sum(u[..., 0] ** 2, axis=-1)
    return float(out) if out.ndim == 0 else out


def nees(x_err: ArrayLike, P: ArrayLike) -> FloatArray | float:
    """Normalised estimation error squared ``e^T P^-1 e``.

    Parameters
    ----------
    x_err : array_like, shape (..., n)
        Estimation error(s) ``x_hat - x_true`` (angles already wrapped).
    P : array_like, shape (..., n, n)
        Filter covariance(s); leading axes broadcast against ``x_err``.

    Returns
    -------
    float or ndarray, shape (...)
        Chi-square distributed with ``n`` degrees of freedom for a consistent filter.
    """
    return _normalised_square(x_err, P, "x_err", "P")


def nis(y: ArrayLike, S: ArrayLike) -> FloatArray | float:
    """Normalised innovation squared ``y^T S^-1 y``.

    Parameters
    ----------
    y : array_like, shape (..., m)
        Innovation(s) (the filter's ``y``).
    S : array_like, shape (..., m, m)
        Innovation covariance(s) (the filter's ``S``).

    Returns
    -------
    float or ndarray, shape (...)
        Chi-square with ``m`` degrees of freedom for a consistent filter.
    """
    return _normalised_square(y, S, "y", "S")


def anees_bounds(dim: int, n_runs: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided acceptance band of the average NEES over independent Monte Carlo runs.

    If the filter is consistent, ``n_runs * ANEES`` is chi-square with
    ``n_runs * dim`` degrees of freedom, so ANEES lies in the returned band with
    probability ``confidence`` (Bar-Shalom, Li & Kirubarajan, sec. 5.4).

    Parameters
    ----------
    dim : int
        State (or measurement, for NIS) dimension.
    n_runs : int
        Number of independent runs averaged.
    confidence : float
        Two-sided probability, e.g. 0.95.

    Returns
    -------
    (low, high) : tuple of float
    """
    dim = _check_dim(dim, "dim")
    n_runs = _check_dim(n_runs, "n_runs")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence: expected a value in (0, 1), got {confidence}")
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    dof = dim * n_runs
    a = 0.5 * (1.0 - confidence)
    return float(chi2.ppf(a, dof) / n_runs), float(chi2.ppf(1.0 - a, dof) / n_runs)


# ----------------------------------------------------------------------------------------
# Angles
# ----------------------------------------------------------------------------------------
def wrap_angle(a: ArrayLike) -> FloatArray:
    """Wrap angles [rad] to the interval (-pi, pi].

    Parameters
    ----------
    a : array_like, any shape
        Angles [rad].

    Returns
    -------
    ndarray, same shape as ``a``
        ``a`` plus multiples of ``2 pi``, in (-pi, pi] [rad].
    """
    a = np.asarray(a, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def _check_indices(angle_indices: Any, n: int | None = None) -> NDArray[np.intp]:
    idx = np.atleast_1d(np.asarray(angle_indices))
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise EstimatorTypeError(f"angle_indices: expected integer indices, got dtype {idx.dtype}")
    idx = idx.astype(np.intp)
    if idx.ndim != 1:
        raise ShapeError(f"angle_indices: expected a 1-D sequence, got shape {idx.shape}")
    if n is not None and idx.size and (idx.max() >= n or idx.min() < -n):
        raise ValueError(f"angle_indices: expected indices in [-{n}, {n}), got {idx.tolist()}")
    return idx


def angle_residual(a: ArrayLike, b: ArrayLike, angle_indices: Sequence[int]) -> FloatArray:
    """``a - b`` with the components ``angle_indices`` wrapped to (-pi, pi].

    Parameters
    ----------
    a, b : array_like, shape (..., n), broadcastable
        Vectors whose components ``angle_indices`` are angles [rad].
    angle_indices : sequence of int
        Positions of the angles along the last axis.

    Returns
    -------
    ndarray, shape (..., n)
    """
    d = np.asarray(np.subtract(_as_float(a, "a"), _as_float(b, "b")))
    if d.ndim == 0:
        raise ShapeError(f"a: expected vectors of shape (..., n), got shape {d.shape}")
    idx = _check_indices(angle_indices, d.shape[-1])
    if idx.size:
        d[..., idx] = wrap_angle(d[..., idx])
    return d


def angle_mean(sigmas: ArrayLike, weights: ArrayLike, angle_indices: Sequence[int]) -> FloatArray:
    """Weighted mean with the components ``angle_indices`` averaged on the circle.

    For an angle column, a reference ``r`` is taken as the direction of
    ``sum |w_i| exp(j theta_i)``; the mean is ``r + sum w_i wrap(theta_i - r)``,
    wrapped to (-pi, pi]. Unlike ``atan2(sum w sin, sum w cos)`` it does not
    depend on the sign of the weights (Merwe's central weight is negative for
    ``alpha^2 (n + kappa) < n``) and it equals the ordinary weighted mean whenever
    all points lie within pi of the reference and that mean lies in (-pi, pi].
    It assumes the points span less than pi around the reference, which holds for
    any sensible sigma-point or particle cloud.

    Parameters
    ----------
    sigmas : array_like, shape (..., m, n)
        Points to average.
    weights : array_like, shape (m,)
        Weights summing to one (may be negative, e.g. Merwe ``Wm[0]``).
    angle_indices : sequence of int
        Angle components [rad] along the last axis.

    Returns
    -------
    ndarray, shape (..., n)
    """
    s = np.asarray(sigmas, dtype=float)
    w = np.asarray(weights, dtype=float)
    if s.ndim < 2 or w.shape != s.shape[-2:-1]:
        raise ShapeError(
            f"weights: expected shape {s.shape[-2:-1]} to match sigmas {s.shape}, got {w.shape}"
        )
    mean = w @ s
    idx = _check_indices(angle_indices, s.shape[-1])
    if idx.size:
        th = s[..., idx]  # (..., m, k)
        aw = np.abs(w)[:, None]
        ref = np.arctan2(np.sum(aw * np.sin(th), axis=-2), np.sum(aw * np.cos(th), axis=-2))
        dev = wrap_angle(th - ref[..., None, :])
        mean[..., idx] = wrap_angle(ref + w @ dev)
    return mean


def angle_residual_fn(angle_indices: Sequence[int]) -> ResidualFn:
    """Residual function ``(a, b) -> a - b`` with angles wrapped, for the UKF/UPF.

    Parameters
    ----------
    angle_indices : sequence of int
        Angle components [rad] of the vectors it will receive.

    Returns
    -------
    callable
    """
    idx = _check_indices(angle_indices)

    def residual(a: FloatArray, b: FloatArray) -> FloatArray:
        return angle_residual(a, b, idx)

    return residual


def angle_mean_fn(angle_indices: Sequence[int]) -> MeanFn:
    """Mean function ``(sigmas, weights) -> mean`` averaging angles on the circle.

    Parameters
    ----------
    angle_indices : sequence of int
        Angle components [rad].

    Returns
    -------
    callable
        See :func:`angle_mean`.
    """
    idx = _check_indices(angle_indices)

    def mean(sigmas: FloatArray, weights: FloatArray) -> FloatArray:
        return angle_mean(sigmas, weights, idx)

    return mean


# ----------------------------------------------------------------------------------------
# Linear Kalman filter
# ----------------------------------------------------------------------------------------
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
    S = _symmetrise(H @ PHt + R)
    Kt, L = _spd_solve(S, PHt.T, "S")  # S K^T = H P
    K = Kt.T
    x_post = x + K @ y
    I_KH = np.eye(x.size) - K @ H
    P_post = _symmetrise(I_KH @ P @ I_KH.T + K @ R @ K.T)
    loglik = float(_gauss_logpdf(y, L))
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

    x = _ArrayField(_vec)
    P = _ArrayField(_sq_x, scalar_is_eye=True)
    F = _ArrayField(_sq_x)
    Q = _ArrayField(_sq_x, scalar_is_eye=True)
    H = _ArrayField(_hz)
    R = _ArrayField(_sq_z, scalar_is_eye=True)
    B = _ArrayField(_bu)

    def __init__(self, dim_x: int, dim_z: int, dim_u: int = 0) -> None:
        self.dim_x = _check_dim(dim_x, "dim_x")
        self.dim_z = _check_dim(dim_z, "dim_z")
        self.dim_u = _check_dim(dim_u, "dim_u", minimum=0)
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
        F = self.F if F is None else _check_shape(F, "F", (n, n))
        Q = self.Q if Q is None else _check_square(Q, "Q", n)
        x = F @ self.x
        if u is not None:
            if self.dim_u == 0:
                raise ValueError("u: expected None for a filter built with dim_u=0, got an input")
            x = x + self.B @ _check_shape(u, "u", (self.dim_u,))
        _store(self, x=x, P=_symmetrise(F @ self.P @ F.T + Q))
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
            H = _as_float(H, "H")
            if H.ndim == 1:
                H = H[None, :]
            if H.ndim != 2 or H.shape[1] != n:
                raise ShapeError(f"H: expected shape (m, {n}), got {H.shape}")
        m = H.shape[0]
        z = _as_float(z, "z")
        if z.ndim == 0 and m == 1:
            z = z[None]
        if z.shape != (m,):
            raise ShapeError(f"z: expected shape {(m,)}, got {z.shape}")
        _check_finite(z, "z")
        R = _meas_noise(R, self.R, self.dim_z, m)
        self.y = z - H @ self.x
        x, P, self.K, self.S, self.log_likelihood = joseph_update(self.x, self.P, self.y, H, R)
        _store(self, x=x, P=P)
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()

    def _skip_update(self) -> None:
        self.K = self.y = self.S = None
        self.log_likelihood = None
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()


# ----------------------------------------------------------------------------------------
# Extended Kalman filter
# ----------------------------------------------------------------------------------------
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

    x = _ArrayField(_vec)
    P = _ArrayField(_sq_x, scalar_is_eye=True)
    F = _ArrayField(_sq_x)
    Q = _ArrayField(_sq_x, scalar_is_eye=True)
    R = _ArrayField(_sq_z, scalar_is_eye=True)

    def __init__(self, dim_x: int, dim_z: int) -> None:
        self.dim_x = _check_dim(dim_x, "dim_x")
        self.dim_z = _check_dim(dim_z, "dim_z")
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
            Fm = _check_shape(F(self.x.copy(), dt), "F(x, dt)", (n, n))
        else:
            Fm = _check_shape(F, "F", (n, n))
        Q = self.Q if Q is None else _check_square(Q, "Q", n)
        if f is None:
            x = Fm @ self.x
        else:
            _check_callable(f, "f")
            x = _check_shape(f(self.x.copy(), dt), "f(x, dt)", (n,))
        _store(self, F=Fm)
        _store(self, x=x, P=_symmetrise(Fm @ self.P @ Fm.T + Q))
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
        _check_callable(h, "h")
        n = self.dim_x
        z = _as_float(z, "z")
        if z.ndim == 0:
            z = z[None]
        if z.ndim != 1:
            raise ShapeError(f"z: expected a 1-D measurement, got shape {z.shape}")
        _check_finite(z, "z")
        m = z.size
        Hm = H_jac(self.x.copy()) if callable(H_jac) else H_jac
        Hm = _check_shape(Hm, "H_jac", (m, n))
        R = _meas_noise(R, self.R, self.dim_z, m)
        zp = _check_shape(h(self.x.copy()), "h(x)", (m,))
        if residual is None:
            y = z - zp
        else:
            _check_callable(residual, "residual")
            y = _check_shape(residual(z, zp), "residual(z, z_pred)", (m,))
        self.H = Hm
        self.z_pred = zp
        self.y = y
        x, P, self.K, self.S, self.log_likelihood = joseph_update(self.x, self.P, y, Hm, R)
        _store(self, x=x, P=P)
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()


# ----------------------------------------------------------------------------------------
# Sigma points and the unscented transform
# ----------------------------------------------------------------------------------------
class MerweScaledSigmaPoints:
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
    """

    def __init__(self, n: int, alpha: float, beta: float = 2.0, kappa: float = 0.0) -> None:
        self.n = _check_dim(n, "n")
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

    @property
    def num_sigmas(self) -> int:
        """Number of sigma points, ``2n + 1``."""
        return 2 * self.n + 1

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
            Row 0 is ``x`` itself.

        Raises
        ------
        ShapeError
            If ``x`` or ``P`` do not end in ``(n,)`` / ``(n, n)``.
        CovarianceError
            If a ``P`` is not positive definite (and ``robust`` is False).
        """
        n = self.n
        x = _as_float(x, "x")
        P = _as_float(P, "P")
        if x.ndim == 0 or x.shape[-1] != n:
            raise ShapeError(f"x: expected shape (..., {n}), got {x.shape}")
        if P.ndim < 2 or P.shape[-2:] != (n, n):
            raise ShapeError(f"P: expected shape (..., {n}, {n}), got {P.shape}")
        if robust:
            L, _ = _sqrt_psd(self._spread * P)
        else:
            L = _cholesky(self._spread * P, "P")
        D = np.swapaxes(L, -1, -2)  # rows = columns of L
        xb = x[..., None, :]
        shape = np.broadcast_shapes(xb.shape, D.shape)
        out = np.empty(shape[:-2] + (2 * n + 1, n))
        out[..., 0, :] = x
        out[..., 1 : n + 1, :] = xb + D
        out[..., n + 1 :, :] = xb - D
        return out


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
    s = _as_float(sigmas, "sigmas")
    if s.ndim < 2:
        raise ShapeError(f"sigmas: expected shape (..., m, d), got {s.shape}")
    m, d = s.shape[-2:]
    Wm = _check_shape(Wm, "Wm", (m,))
    Wc = _check_shape(Wc, "Wc", (m,))
    mean = Wm @ s if mean_fn is None else np.asarray(mean_fn(s, Wm), dtype=float)
    if mean.shape != s.shape[:-2] + (d,):
        raise ShapeError(f"mean_fn: expected output shape {s.shape[:-2] + (d,)}, got {mean.shape}")
    r = s - mean[..., None, :] if residual_fn is None else residual_fn(s, mean[..., None, :])
    r = np.asarray(r, dtype=float)
    if r.shape != s.shape:
        raise ShapeError(f"residual_fn: expected output shape {s.shape}, got {r.shape}")
    cov = np.swapaxes(r * Wc[:, None], -1, -2) @ r
    if noise_cov is not None:
        nc = _as_float(noise_cov, "noise_cov")
        if nc.ndim == 0:
            nc = float(nc) * np.eye(d)
        if nc.shape[-2:] != (d, d):
            raise ShapeError(f"noise_cov: expected shape (..., {d}, {d}), got {nc.shape}")
        cov = cov + nc
    return mean, _symmetrise(cov)


def _call_model(
    fn: Callable[..., ArrayLike],
    name: str,
    pts: FloatArray,
    args: tuple[Any, ...],
    kwargs: dict[str, Any],
    dim_out: int,
    vectorized: bool,
) -> FloatArray:
    """Apply ``fn`` to points ``(..., n)``; returns ``(..., dim_out)``, shape-checked."""
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


def _ukf_predict(
    x: FloatArray,
    P: FloatArray,
    points: MerweScaledSigmaPoints,
    fx: Callable[..., ArrayLike],
    dt: float,
    Q: FloatArray,
    x_mean_fn: MeanFn | None,
    residual_x: ResidualFn | None,
    fx_kw: dict[str, Any],
    vectorized: bool,
    robust: bool = False,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Batched UKF time update; returns ``sigmas_f, x_prior, P_prior``."""
    sig = points.sigma_points(x, P, robust=robust)
    sig_f = _call_model(fx, "fx", sig, (dt,), fx_kw, x.shape[-1], vectorized)
    xp, Pp = unscented_transform(sig_f, points.Wm, points.Wc, Q, x_mean_fn, residual_x)
    return sig_f, xp, Pp


def _ukf_update(
    z: FloatArray,
    x: FloatArray,
    P: FloatArray,
    points: MerweScaledSigmaPoints,
    hx: Callable[..., ArrayLike],
    R: FloatArray,
    residual_x: ResidualFn | None,
    residual_z: ResidualFn | None,
    z_mean_fn: MeanFn | None,
    hx_kw: dict[str, Any],
    vectorized: bool,
    robust: bool = False,
) -> dict[str, FloatArray]:
    """Batched UKF measurement update of the prior ``N(x, P)``.

    The sigma points are redrawn from the prior, so they carry the process noise
    ``Q`` added in the time update; reusing the propagated points would leave ``Q``
    out of ``S`` and ``P_xz``, and the UKF would then differ from the KF on linear
    models.
    """
    sig_f = points.sigma_points(x, P, robust=robust)
    dz = z.shape[-1]
    sig_h = _call_model(hx, "hx", sig_f, (), hx_kw, dz, vectorized)
    zp, S = unscented_transform(sig_h, points.Wm, points.Wc, R, z_mean_fn, residual_z)
    rx = sig_f - x[..., None, :] if residual_x is None else residual_x(sig_f, x[..., None, :])
    rz = sig_h - zp[..., None, :] if residual_z is None else residual_z(sig_h, zp[..., None, :])
    Pxz = np.swapaxes(rx * points.Wc[:, None], -1, -2) @ rz  # (..., n, dz)
    Kt, L = _spd_solve(S, np.swapaxes(Pxz, -1, -2), "S")  # S K^T = Pxz^T
    K = np.swapaxes(Kt, -1, -2)
    y = z - zp if residual_z is None else np.asarray(residual_z(z, zp), dtype=float)
    x_post = x + (K @ y[..., None])[..., 0]
    P_post = _symmetrise(P - K @ S @ np.swapaxes(K, -1, -2))
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


def _check_models(
    dim_x: int,
    fx: Any,
    hx: Any,
    points: Any,
    **optional: Any,
) -> None:
    """Argument checks shared by the UKF and the UPF."""
    _check_callable(fx, "fx")
    _check_callable(hx, "hx")
    if not isinstance(points, MerweScaledSigmaPoints):
        raise EstimatorTypeError(
            f"points: expected MerweScaledSigmaPoints, got {type(points).__name__}"
        )
    if points.n != dim_x:
        raise ShapeError(f"points: expected sigma points for n={dim_x}, got n={points.n}")
    for name, fn in optional.items():
        if fn is not None:
            _check_callable(fn, name)


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
        points at once, ``x`` of shape ``(2n + 1, n)``, and must act row-wise on the
        last axis (return ``(2n + 1, n)``); with ``vectorized=False`` it receives
        one point of shape ``(n,)``.
    hx : callable ``hx(x, **kw) -> z``
        Measurement model, same convention, output ``(..., m)``.
    points : MerweScaledSigmaPoints
        Sigma-point generator with ``points.n == dim_x``.
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
    ``fx`` or ``x_mean_fn``); read it through :func:`wrap_angle` if it matters.

    Attributes
    ----------
    x, P, Q, R
        Estimate, covariance, process noise (zero initially), measurement noise
        (identity initially); shape-checked on assignment.
    x_prior, P_prior, sigmas_f
        After :meth:`predict` (``sigmas_f`` shape ``(2n + 1, n)``).
    x_post, P_post, K, y, S, z_pred, sigmas_h, log_likelihood
        After :meth:`update`.
    """

    x = _ArrayField(_vec)
    P = _ArrayField(_sq_x, scalar_is_eye=True)
    Q = _ArrayField(_sq_x, scalar_is_eye=True)
    R = _ArrayField(_sq_z, scalar_is_eye=True)

    def __init__(
        self,
        dim_x: int,
        dim_z: int,
        fx: Callable[..., ArrayLike],
        hx: Callable[..., ArrayLike],
        points: MerweScaledSigmaPoints,
        residual_x: ResidualFn | None = None,
        residual_z: ResidualFn | None = None,
        x_mean_fn: MeanFn | None = None,
        z_mean_fn: MeanFn | None = None,
        *,
        vectorized: bool = True,
    ) -> None:
        self.dim_x = _check_dim(dim_x, "dim_x")
        self.dim_z = _check_dim(dim_z, "dim_z")
        _check_models(
            self.dim_x,
            fx,
            hx,
            points,
            residual_x=residual_x,
            residual_z=residual_z,
            x_mean_fn=x_mean_fn,
            z_mean_fn=z_mean_fn,
        )
        self.fx, self.hx, self.points = fx, hx, points
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
        self.log_likelihood: float | None = None

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
        _check_callable(fx, "fx")
        Q = self.Q if Q is None else _check_square(Q, "Q", self.dim_x)
        self.sigmas_f, x, P = _ukf_predict(
            self.x,
            self.P,
            self.points,
            fx,
            dt,
            Q,
            self.x_mean_fn,
            self.residual_x,
            fx_args,
            self.vectorized,
        )
        _store(self, x=x, P=P)
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
        _check_callable(hx, "hx")
        z = _as_float(z, "z")
        if z.ndim == 0:
            z = z[None]
        if z.ndim != 1:
            raise ShapeError(f"z: expected a 1-D measurement, got shape {z.shape}")
        _check_finite(z, "z")
        m = z.size
        R = _meas_noise(R, self.R, self.dim_z, m)
        out = _ukf_update(
            z,
            self.x,
            self.P,
            self.points,
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
        self.log_likelihood = float(_gauss_logpdf(self.y, out["chol_S"]))
        _store(self, x=out["x"], P=out["P"])
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()


# ----------------------------------------------------------------------------------------
# Resampling and the unscented particle filter
# ----------------------------------------------------------------------------------------
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
    w = _as_float(weights, "weights")
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


def _sqrt_psd(P: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Square roots ``A A^T = P`` (batched) and ``0.5 log det P``.

    Cholesky when every matrix allows it; otherwise an eigen-decomposition with
    eigenvalues clipped at ``n eps max(eig)`` (symmetric square root), which keeps a
    long particle run alive when round-off makes one covariance semi-definite.
    """
    try:
        L = np.linalg.cholesky(P)
        return L, np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(_symmetrise(P))
        floor = P.shape[-1] * np.finfo(float).eps * np.max(np.abs(w), axis=-1, keepdims=True)
        w = np.maximum(w, np.maximum(floor, np.finfo(float).tiny))
        return V * np.sqrt(w)[..., None, :], 0.5 * np.sum(np.log(w), axis=-1)


class UnscentedParticleFilter:
    """Unscented particle filter (van der Merwe, Doucet, de Freitas & Wan, 2000).

    Every particle ``i`` carries a state ``x^i`` and a covariance ``P^i``. One
    :meth:`step` runs, for all particles at once (arrays ``(N, 2n + 1, n)``), a UKF
    predict + update from ``(x^i_(k-1), P^i_(k-1))`` with the measurement ``z_k``,
    giving ``N(m^i_k, P^i_k)``; then

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

    ``fx`` and ``hx`` act on the last axis (``x`` of shape ``(N, 2n + 1, n)`` or
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
    points : MerweScaledSigmaPoints
        Sigma-point generator for ``dim_x``.
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

    Q = _ArrayField(_sq_x, scalar_is_eye=True)
    R = _ArrayField(_sq_z, scalar_is_eye=True)

    def __init__(
        self,
        dim_x: int,
        dim_z: int,
        fx: Callable[..., ArrayLike],
        hx: Callable[..., ArrayLike],
        points: MerweScaledSigmaPoints,
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
        _check_models(
            _check_dim(dim_x, "dim_x"),
            fx,
            hx,
            points,
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
        self.dim_x, self.dim_z = int(dim_x), _check_dim(dim_z, "dim_z")
        self.N = _check_dim(n_particles, "n_particles")
        self.resample_threshold = (
            self.N / 2.0 if resample_threshold is None else float(resample_threshold)
        )
        self.fx, self.hx, self.points, self.rng = fx, hx, points, rng
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
        x0 = _check_shape(x0, "x0", (n,))
        P0 = _check_square(P0, "P0", n)
        if spread:
            L = _cholesky(P0, "P0")
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
        parts = _check_shape(particles, "particles", (N, n))
        Pa = _as_float(P, "P")
        if Pa.shape == (n, n):
            Pa = np.broadcast_to(Pa, (N, n, n)).copy()
        if Pa.shape != (N, n, n):
            raise ShapeError(f"P: expected shape {(N, n, n)} or {(n, n)}, got {Pa.shape}")
        if weights is None:
            w = np.full(N, 1.0 / N)
        else:
            w = _check_shape(weights, "weights", (N,))
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
        return _symmetrise(cov)

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
        Q = self.Q if Q is None else _check_square(Q, "Q", n)
        fx_kw = {} if fx_args is None else dict(fx_args)
        hx_kw = {} if hx_args is None else dict(hx_args)
        rx, rz = self.residual_x, self.residual_z

        sig_f, xp, Pp = _ukf_predict(
            self.particles,
            self.particle_P,
            self.points,
            self.fx,
            dt,
            Q,
            self.x_mean_fn,
            rx,
            fx_kw,
            self.vectorized,
            robust=True,
        )
        with np.errstate(divide="ignore"):  # a weight that underflowed to 0 -> -inf
            log_w = np.log(self.weights)
        if z is not None:
            z = _as_float(z, "z")
            if z.ndim == 0:
                z = z[None]
            if z.ndim != 1:
                raise ShapeError(f"z: expected a 1-D measurement, got shape {z.shape}")
            _check_finite(z, "z")
            m = z.size
            R = _meas_noise(R, self.R, self.dim_z, m)
            out = _ukf_update(
                z, xp, Pp, self.points, self.hx, R, rx, rz, self.z_mean_fn, hx_kw,
                self.vectorized, robust=True,
            )  # fmt: skip
            mean, cov = out["x"], out["P"]
            particle_nis = _mahalanobis2(out["y"], out["chol_S"])
        else:
            mean, cov = xp, Pp
            particle_nis = np.full(N, np.nan)

        if self.proposal == "mean":
            if z is not None:
                log_w = log_w + _gauss_logpdf(out["y"], out["chol_S"], particle_nis)
            new = mean
        else:
            A, half_logdet = _sqrt_psd(cov)
            eps = self.rng.standard_normal((N, n))
            new = mean + (A @ eps[..., None])[..., 0]
            log_q = -0.5 * np.sum(eps * eps, axis=-1) - half_logdet - 0.5 * n * _LOG_2PI
            if self.weight_rule == "full":
                LQ = _cholesky(Q, "Q (the 'full' UPF weight needs a positive definite Q)")
                f_prev = sig_f[:, 0, :]  # sigma point 0 is the particle itself
                d = new - f_prev if rx is None else np.asarray(rx(new, f_prev), dtype=float)
                log_w = log_w + _gauss_logpdf(d, LQ) - log_q
            if z is not None:
                LR = _cholesky(R, "R")
                zh = _call_model(self.hx, "hx", new, (), hx_kw, z.size, self.vectorized)
                r = z - zh if rz is None else np.asarray(rz(z, zh), dtype=float)
                log_w = log_w + _gauss_logpdf(r, LR)

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
