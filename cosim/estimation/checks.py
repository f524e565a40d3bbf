"""Argument checks shared by the estimators: errors, shape checks, checked filter fields.

Every check names the argument it rejects, in the form ``"name: expected ..., got ..."``,
so that an error raised deep inside a filter still says which input was wrong. The
filters' matrices (``x``, ``P``, ``Q``, ``R``, ...) are :class:`ArrayField` descriptors:
assigning to one converts, copies and shape-checks the value.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ArrayField",
    "CovarianceError",
    "DegenerateWeightsError",
    "EstimatorTypeError",
    "FloatArray",
    "MeanFn",
    "ResidualFn",
    "ShapeError",
    "as_float",
    "check_callable",
    "check_dim",
    "check_finite",
    "check_matrix",
    "check_measurement",
    "check_shape",
    "check_square",
    "measurement_noise",
    "set_checked",
]

FloatArray = NDArray[np.float64]
"""A float64 array (states ``(n,)``, covariances ``(n, n)``, stacks of them)."""

ResidualFn = Callable[[FloatArray, FloatArray], FloatArray]
"""``residual(a, b) -> a - b``, broadcasting over leading axes."""

MeanFn = Callable[[FloatArray, FloatArray], FloatArray]
"""``mean_fn(sigmas (..., m, d), weights (m,)) -> (..., d)``."""


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
# Checks
# ----------------------------------------------------------------------------------------
def as_float(value: Any, name: str) -> FloatArray:
    """A float copy of ``value``, or :class:`EstimatorTypeError` naming ``name``.

    Parameters
    ----------
    value : array_like
        Anything :func:`numpy.array` converts to floats.
    name : str
        Argument name used in the error message.

    Returns
    -------
    ndarray
        A new float64 array, same shape as ``value``.
    """
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise EstimatorTypeError(
            f"{name}: expected a real array, got {type(value).__name__}"
        ) from exc


def check_shape(value: Any, name: str, shape: tuple[int, ...]) -> FloatArray:
    """A float copy of ``value`` that must have exactly ``shape``.

    Parameters
    ----------
    value : array_like
        The argument.
    name : str
        Argument name used in the error message.
    shape : tuple of int
        Required shape.

    Returns
    -------
    ndarray, shape ``shape``

    Raises
    ------
    ShapeError
        If the shape differs.
    """
    arr = as_float(value, name)
    if arr.shape != shape:
        raise ShapeError(f"{name}: expected shape {shape}, got {arr.shape}")
    return arr


def check_square(value: Any, name: str, n: int) -> FloatArray:
    """A ``(n, n)`` matrix; a scalar ``s`` is read as ``s * I``.

    Parameters
    ----------
    value : array_like, shape (n, n), or scalar
        The argument.
    name : str
        Argument name used in the error message.
    n : int
        Matrix size.

    Returns
    -------
    ndarray, shape (n, n)
    """
    arr = as_float(value, name)
    if arr.ndim == 0:
        return float(arr) * np.eye(n)
    if arr.shape != (n, n):
        raise ShapeError(f"{name}: expected shape {(n, n)} or a scalar, got {arr.shape}")
    return arr


def check_matrix(value: Any, name: str) -> FloatArray:
    """A float copy of ``value`` that must be 2-D.

    Parameters
    ----------
    value : array_like, shape (r, c)
        The argument.
    name : str
        Argument name used in the error message.

    Returns
    -------
    ndarray, shape (r, c)
    """
    arr = as_float(value, name)
    if arr.ndim != 2:
        raise ShapeError(f"{name}: expected a 2-D array, got shape {arr.shape}")
    return arr


def check_dim(value: Any, name: str, minimum: int = 1) -> int:
    """An integer dimension ``>= minimum`` (``bool`` is refused).

    Parameters
    ----------
    value : int
        The argument.
    name : str
        Argument name used in the error message.
    minimum : int
        Smallest accepted value (default 1).

    Returns
    -------
    int
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise EstimatorTypeError(f"{name}: expected an int, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name}: expected an int >= {minimum}, got {value}")
    return int(value)


def check_callable(value: Any, name: str) -> None:
    """Raise :class:`EstimatorTypeError` unless ``value`` is callable.

    Parameters
    ----------
    value : object
        The argument.
    name : str
        Argument name used in the error message.
    """
    if not callable(value):
        raise EstimatorTypeError(f"{name}: expected a callable, got {type(value).__name__}")


def check_finite(arr: FloatArray, name: str) -> None:
    """Raise ``ValueError`` unless every element of ``arr`` is finite.

    Parameters
    ----------
    arr : ndarray, any shape
        Values to test.
    name : str
        Argument name used in the error message.
    """
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected finite values, got {arr!r}")


def check_measurement(z: ArrayLike) -> FloatArray:
    """A finite 1-D measurement vector (a scalar becomes shape ``(1,)``).

    Parameters
    ----------
    z : array_like, shape (m,), or scalar
        Measurement.

    Returns
    -------
    ndarray, shape (m,)
    """
    arr = as_float(z, "z")
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1:
        raise ShapeError(f"z: expected a 1-D measurement, got shape {arr.shape}")
    check_finite(arr, "z")
    return arr


def measurement_noise(R: Any, default: FloatArray, dim_z: int, m: int) -> FloatArray:
    """The measurement noise of one update: ``R`` if given, else the filter's own.

    Parameters
    ----------
    R : array_like, shape (m, m), scalar, or None
        Noise given for this update.
    default : ndarray, shape (dim_z, dim_z)
        The filter's ``R``.
    dim_z : int
        The filter's measurement size.
    m : int
        Size of this measurement; the default is usable only when ``m == dim_z``.

    Returns
    -------
    ndarray, shape (m, m)
    """
    if R is not None:
        return check_square(R, "R", m)
    if m != dim_z:
        raise ShapeError(
            f"R: expected an explicit ({m}, {m}) noise covariance for a measurement of "
            f"size {m} (the filter's R is {dim_z}x{dim_z}), got None"
        )
    return default


# ----------------------------------------------------------------------------------------
# Checked filter fields
# ----------------------------------------------------------------------------------------
class ArrayField:
    """Data descriptor for a filter matrix: converts and shape-checks on assignment.

    The expected shape is read from the instance: ``ArrayField("dim_x", "dim_x")`` is a
    ``(dim_x, dim_x)`` matrix. Values are copied on assignment, so a filter never
    aliases the caller's arrays.

    Parameters
    ----------
    *dims : str
        Names of the instance's integer attributes that give the shape, in order.
    scalar_is_eye : bool
        Accept a scalar ``s`` for a square field and store ``s * I``.
    """

    def __init__(self, *dims: str, scalar_is_eye: bool = False) -> None:
        self.dims = dims
        self.scalar_is_eye = scalar_is_eye
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        return obj.__dict__[self.name]

    def __set__(self, obj: Any, value: Any) -> None:
        shape = tuple(getattr(obj, d) for d in self.dims)
        if self.scalar_is_eye:
            arr = check_square(value, self.name, shape[0])
        else:
            arr = check_shape(value, self.name, shape)
        obj.__dict__[self.name] = arr


def set_checked(obj: Any, **arrays: FloatArray) -> None:
    """Store arrays in :class:`ArrayField` slots without the check (already checked).

    Parameters
    ----------
    obj : object
        The filter.
    **arrays : ndarray
        Field name to value; the caller guarantees type and shape.
    """
    obj.__dict__.update(arrays)
