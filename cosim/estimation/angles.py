"""Angles inside state and measurement vectors: differences and means on the circle.

A heading in a UKF or UPF state must be differenced and averaged on the circle, or a
sigma-point cloud straddling +-pi averages to the wrong side. :func:`angle_residual_fn`
and :func:`angle_mean_fn` build the ``residual_x/z`` and ``x/z_mean_fn`` callables the
filters take; every wrap is :func:`models.conventions.wrap_angle`, interval (-pi, pi].
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.estimation.checks import (
    EstimatorTypeError,
    FloatArray,
    MeanFn,
    ResidualFn,
    ShapeError,
    as_float,
)
from cosim.models.conventions import wrap_angle

__all__ = ["angle_mean", "angle_mean_fn", "angle_residual", "angle_residual_fn"]


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
    d = np.asarray(np.subtract(as_float(a, "a"), as_float(b, "b")))
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
