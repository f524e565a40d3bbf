"""Batched linear algebra of the estimators: square roots, solves, Gaussian log densities.

Everything broadcasts over leading axes (a stack of ``N`` covariances is ``(N, n, n)``)
and uses numpy's gufuncs rather than ``scipy.linalg.solve_triangular``, whose batching
loops in Python.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cosim.estimation.checks import CovarianceError, FloatArray, as_float

__all__ = [
    "LOG_2PI",
    "broadcast_batch",
    "cholesky",
    "float_array",
    "gauss_logpdf",
    "mahalanobis2",
    "spd_solve",
    "sqrt_psd",
    "symmetrise",
]

LOG_2PI = float(np.log(2.0 * np.pi))
"""``log(2 pi)``, the constant of every Gaussian log density."""


def float_array(value: Any, name: str) -> FloatArray:
    """``value`` itself if it is a C-contiguous float64 ndarray, else :func:`as_float`'s copy.

    For the filters' own hot paths, which read their inputs and never write into them:
    the copy :func:`~cosim.estimation.checks.as_float` makes is then only a cost. Other
    arrays are copied as before, so every later product sees the memory layout it saw
    with the copy (a strided operand can take another summation order in a matrix
    product, and the filters' outputs would move by rounding).

    Parameters
    ----------
    value : array_like
        Anything :func:`numpy.array` converts to floats.
    name : str
        Argument name used in the error message.

    Returns
    -------
    ndarray
        float64, C-contiguous, same shape as ``value`` (``value`` itself when it
        already is one).
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.flags.c_contiguous:
        return value  # a view with other strides is copied: the products see the same layout
    return as_float(value, name)


def symmetrise(P: FloatArray) -> FloatArray:
    """``(P + P^T) / 2`` over the last two axes (exactly symmetric in floating point).

    Parameters
    ----------
    P : ndarray, shape (..., n, n)
        Matrices.

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def cholesky(P: FloatArray, name: str) -> FloatArray:
    """Lower Cholesky factor (batched); :class:`CovarianceError` naming ``name`` on failure.

    Parameters
    ----------
    P : ndarray, shape (..., n, n)
        Symmetric positive definite matrices.
    name : str
        Argument name used in the error message.

    Returns
    -------
    ndarray, shape (..., n, n)
        ``L`` with ``L L^T = P``.
    """
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError as exc:
        raise CovarianceError(
            f"{name}: expected a symmetric positive definite matrix, "
            "got one whose Cholesky factorisation failed"
        ) from exc


def spd_solve(S: FloatArray, B: FloatArray, name: str) -> tuple[FloatArray, FloatArray]:
    """Solve ``S X = B`` for symmetric positive definite ``S`` (batched).

    Parameters
    ----------
    S : ndarray, shape (..., d, d)
        Symmetric positive definite matrices (innovation covariances).
    B : ndarray, shape (..., d, k)
        Right-hand sides.
    name : str
        Name of ``S`` in the error message.

    Returns
    -------
    X : ndarray, shape (..., d, k)
    L : ndarray, shape (..., d, d)
        Lower Cholesky factor of ``S`` (it also certifies that ``S`` is positive
        definite).
    """
    L = cholesky(S, name)
    return np.linalg.solve(S, B), L


def broadcast_batch(M: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Broadcast the leading axes of matrices and vectors against each other.

    Parameters
    ----------
    M : ndarray, shape (..., d, d)
        Matrices.
    v : ndarray, shape (..., d)
        Vectors.

    Returns
    -------
    M, v : ndarray, shapes (B..., d, d) and (B..., d)
        Read-only broadcast views over the common leading shape ``B``.
    """
    d = v.shape[-1]
    batch = np.broadcast_shapes(M.shape[:-2], v.shape[:-1])
    return np.broadcast_to(M, batch + (d, d)), np.broadcast_to(v, batch + (d,))


def mahalanobis2(r: FloatArray, L: FloatArray) -> FloatArray:
    """Squared Mahalanobis norms ``r^T (L L^T)^-1 r``.

    Parameters
    ----------
    r : ndarray, shape (..., d)
        Residuals.
    L : ndarray, shape (..., d, d)
        Lower Cholesky factors of their covariances.

    Returns
    -------
    ndarray, shape (...)
    """
    if L.ndim > 2 or r.ndim > 1:
        L, r = broadcast_batch(L, r)
    u = np.linalg.solve(L, r[..., None])[..., 0]
    return np.sum(u * u, axis=-1)


def gauss_logpdf(r: FloatArray, L: FloatArray, m2: FloatArray | None = None) -> FloatArray:
    """Log density of residuals under ``N(0, L L^T)``.

    Parameters
    ----------
    r : ndarray, shape (..., d)
        Residuals.
    L : ndarray, shape (..., d, d)
        Lower Cholesky factors of the covariances.
    m2 : ndarray, shape (...), optional
        Their :func:`mahalanobis2`, when the caller has it already.

    Returns
    -------
    ndarray, shape (...)
    """
    if m2 is None:
        m2 = mahalanobis2(r, L)
    d = r.shape[-1]
    half_logdet = np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
    return -0.5 * m2 - half_logdet - 0.5 * d * LOG_2PI


def sqrt_psd(P: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Square roots ``A A^T = P`` (batched) that survive round-off indefiniteness.

    Cholesky when every matrix allows it; otherwise an eigen-decomposition with
    eigenvalues clipped at ``n eps max(eig)`` (a symmetric square root), which keeps a
    long particle run alive when round-off makes one covariance semi-definite.

    Parameters
    ----------
    P : ndarray, shape (..., n, n)
        Symmetric positive semi-definite matrices.

    Returns
    -------
    A : ndarray, shape (..., n, n)
        Square roots (lower triangular on the Cholesky path).
    half_logdet : ndarray, shape (...)
        ``0.5 log det P`` (of the clipped matrix on the eigen path).
    """
    try:
        L = np.linalg.cholesky(P)
        return L, np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(symmetrise(P))
        floor = P.shape[-1] * np.finfo(float).eps * np.max(np.abs(w), axis=-1, keepdims=True)
        w = np.maximum(w, np.maximum(floor, np.finfo(float).tiny))
        return V * np.sqrt(w)[..., None, :], 0.5 * np.sum(np.log(w), axis=-1)
