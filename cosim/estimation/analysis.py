"""Analysis tools around the filters: discretisation, observability, consistency.

* :func:`van_loan` discretises a continuous-time error model exactly.
* :func:`observability_rank` and the piecewise (multi-position) variants count the
  observable directions of a linear model, with the total (TOM) or stripped (SOM)
  observability matrix.
* :func:`nees`, :func:`nis` and :func:`anees_bounds` test a filter's consistency over
  Monte Carlo runs (Bar-Shalom, Li & Kirubarajan, sec. 5.4).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import expm

from cosim.estimation.checks import (
    EstimatorTypeError,
    FloatArray,
    ShapeError,
    as_float,
    check_dim,
    check_matrix,
    check_square,
)
from cosim.estimation.linalg import broadcast_batch, cholesky, symmetrise

__all__ = [
    "Segment",
    "anees_bounds",
    "nees",
    "nis",
    "observability_matrix",
    "observability_rank",
    "piecewise_observability_matrix",
    "piecewise_observability_rank",
    "stripped_condition_holds",
    "van_loan",
]


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
    A = check_matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise ShapeError(f"A: expected a square matrix, got shape {A.shape}")
    G = as_float(G, "G")
    if G.ndim == 1:
        G = G[:, None]
    if G.ndim != 2 or G.shape[0] != n:
        raise ShapeError(f"G: expected shape ({n}, p), got {G.shape}")
    Qc = check_square(Qc, "Qc", G.shape[1])
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
    return Phi, symmetrise(Qd)


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
    A = check_matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise ShapeError(f"A: expected a square matrix, got shape {A.shape}")
    H = as_float(H, "H")
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
        A = check_matrix(seg[0], f"segments[{i}].A")
        if n is None:
            n = A.shape[0]
        if A.shape != (n, n):
            raise ShapeError(f"segments[{i}].A: expected shape {(n, n)}, got {A.shape}")
        H = as_float(seg[1], f"segments[{i}].H")
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
    e = as_float(e, e_name)
    P = as_float(P, P_name)
    if e.ndim == 0:
        e = e[None]
    n = e.shape[-1]
    if P.ndim < 2 or P.shape[-2:] != (n, n):
        raise ShapeError(f"{P_name}: expected shape (..., {n}, {n}), got {P.shape}")
    L = cholesky(P, P_name)
    L, eb = broadcast_batch(L, e)
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
    dim = check_dim(dim, "dim")
    n_runs = check_dim(n_runs, "n_runs")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence: expected a value in (0, 1), got {confidence}")
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    dof = dim * n_runs
    a = 0.5 * (1.0 - confidence)
    return float(chi2.ppf(a, dof) / n_runs), float(chi2.ppf(1.0 - a, dof) / n_runs)
