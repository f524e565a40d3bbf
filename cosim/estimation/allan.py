"""Overlapping Allan variance of inertial-sensor records (numpy-vectorised).

Definitions
-----------
A record of ``n`` rate samples ``y_k`` [unit], each the mean rate over an interval
``dt`` [s] (``y_k = d_k / dt`` when the sensor delivers increments ``d_k``), is
integrated into the angle (or velocity) series

    theta_0 = 0,    theta_j = dt * sum_{k < j} y_k,       j = 0 .. n

and, for a cluster of ``m`` samples (averaging time ``tau = m dt``), the
overlapping Allan variance is

    avar(tau) = sum_{j=0}^{n-2m} (theta_{j+2m} - 2 theta_{j+m} + theta_j)^2
                / (2 tau^2 (n - 2m + 1))

(every start index is used, hence "overlapping"). The Allan deviation is
``adev = sqrt(avar)``.

Reference values for the noise terms of an inertial sensor (IEEE Std 952)::

    white rate noise, density N           avar = N^2 / tau
    rate random walk, density K           avar = K^2 tau / 3
    increment quantisation, LSB q         avar = 3 Q^2 / tau^2,  Q = q / sqrt(12)
    (residual carried, Q = angle error std)

so that ``N = adev(tau = 1 s)`` on the white-noise slope. For a rate random walk
sampled at the interval ends (``y_k = y_{k-1} + K sqrt(dt) w_k``) the exact
discrete value is ``avar = K^2 (tau / 3 + dt^2 / (6 tau))``.

The statistical uncertainty of the estimate is summarised by its equivalent
degrees of freedom (:func:`edf_overlapping`): ``avar_hat / avar ~ chi2(edf) / edf``,
so the relative standard error of ``adev_hat`` is about ``1 / sqrt(2 edf)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "allan_deviation",
    "allan_variance",
    "cluster_sizes",
    "edf_overlapping",
    "relative_error",
]


def cluster_sizes(n: int, per_decade: int = 10, m_max: int | None = None) -> np.ndarray:
    """Log-spaced cluster sizes ``m`` for a record of ``n`` samples.

    Parameters
    ----------
    n : int
        Number of rate samples (or increments) in the record.
    per_decade : int, optional
        Approximate number of cluster sizes per decade of ``tau``.
    m_max : int, optional
        Largest cluster size; default ``(n - 1) // 2`` (at least two overlapping terms).

    Returns
    -------
    ndarray of int, shape (k,)
        Sorted unique cluster sizes, starting at 1.
    """
    top = (n - 1) // 2 if m_max is None else min(int(m_max), (n - 1) // 2)
    if top < 1:
        return np.zeros(0, dtype=int)
    count = max(2, int(np.ceil(np.log10(top) * per_decade)) + 1)
    return np.unique(np.round(np.logspace(0.0, np.log10(top), count)).astype(int))


def allan_variance(
    data: np.ndarray,
    dt: float,
    m: int | Sequence[int] | np.ndarray | None = None,
    *,
    increments: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan variance of rate samples or increments.

    Parameters
    ----------
    data : array_like, shape (n,) or (n, k)
        Rate samples ``y`` [unit] (mean over each interval), or increments ``d = y dt``
        [unit s] when ``increments`` is true. Time runs along axis 0; further columns
        (e.g. the three axes of a sensor) are processed together.
    dt : float
        Sample interval [s].
    m : int or sequence of int, optional
        Cluster sizes (``tau = m dt``); default :func:`cluster_sizes` of ``n``. Each must
        satisfy ``1 <= m <= n // 2``.
    increments : bool, optional
        Interpret ``data`` as increments instead of rates.

    Returns
    -------
    tau : ndarray, shape (len(m),)
        Averaging times [s].
    avar : ndarray, shape (len(m),) or (len(m), k)
        Allan variance [unit^2].
    """
    x = np.asarray(data, dtype=float)
    if x.ndim not in (1, 2):
        raise ValueError(f"data must have shape (n,) or (n, k), got {x.shape}")
    if dt <= 0.0:
        raise ValueError(f"dt must be positive, got {dt}")
    n = x.shape[0]
    sizes = cluster_sizes(n) if m is None else np.atleast_1d(np.asarray(m, dtype=int))
    if sizes.size and (sizes.min() < 1 or 2 * sizes.max() > n):
        raise ValueError(f"cluster sizes must lie in [1, {n // 2}] for {n} samples")
    d = x if increments else x * dt
    # The Allan variance ignores a constant rate: removing the mean keeps the
    # cumulative sum small, so the second differences lose no precision.
    d = d - d.mean(axis=0)
    theta = np.concatenate([np.zeros((1,) + d.shape[1:]), np.cumsum(d, axis=0)], axis=0)
    tau = sizes * float(dt)
    out = np.empty((sizes.size,) + d.shape[1:])
    for i, mi in enumerate(sizes):
        second = theta[2 * mi :] - 2.0 * theta[mi:-mi] + theta[: -2 * mi]
        out[i] = np.mean(second**2, axis=0) / (2.0 * tau[i] ** 2)
    return tau, out


def allan_deviation(
    data: np.ndarray,
    dt: float,
    m: int | Sequence[int] | np.ndarray | None = None,
    *,
    increments: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of rate samples or increments.

    Parameters
    ----------
    data : array_like, shape (n,) or (n, k)
        Rate samples [unit] or, with ``increments``, increments [unit s]; time along axis 0.
    dt : float
        Sample interval [s].
    m : int or sequence of int, optional
        Cluster sizes; default log-spaced (:func:`cluster_sizes`).
    increments : bool, optional
        Interpret ``data`` as increments.

    Returns
    -------
    tau : ndarray, shape (len(m),)
        Averaging times [s].
    adev : ndarray, shape (len(m),) or (len(m), k)
        Allan deviation [unit].
    """
    tau, avar = allan_variance(data, dt, m, increments=increments)
    return tau, np.sqrt(avar)


def edf_overlapping(n: int, m: int, noise: str = "white") -> float:
    """Equivalent degrees of freedom of the overlapping Allan variance.

    Approximations of NIST Special Publication 1065 (Riley 2008, table 5), in terms
    of the number of integrated points ``n + 1``.

    Parameters
    ----------
    n : int
        Number of rate samples in the record.
    m : int
        Cluster size.
    noise : {"white", "rrw"}
        Dominant noise: white rate noise (ARW / VRW; white FM in clock terms) or
        rate random walk (random-walk FM).

    Returns
    -------
    float
        Equivalent chi-square degrees of freedom.
    """
    big_n = float(n + 1)  # number of phase (angle) points
    mf = float(m)
    if noise == "white":
        return (3.0 * (big_n - 1.0) / (2.0 * mf) - 2.0 * (big_n - 2.0) / big_n) * (
            4.0 * mf**2 / (4.0 * mf**2 + 5.0)
        )
    if noise == "rrw":
        return (
            (big_n - 2.0)
            / (mf * (big_n - 3.0) ** 2)
            * ((big_n - 1.0) ** 2 - 3.0 * mf * (big_n - 1.0) + 4.0 * mf**2)
        )
    raise ValueError(f"noise must be 'white' or 'rrw', got {noise!r}")


def relative_error(n: int, m: int, noise: str = "white") -> float:
    """Approximate relative standard error of the Allan *deviation* estimate.

    Parameters
    ----------
    n : int
        Number of rate samples.
    m : int
        Cluster size.
    noise : {"white", "rrw"}
        Dominant noise type (see :func:`edf_overlapping`).

    Returns
    -------
    float
        ``1 / sqrt(2 edf)``.
    """
    return 1.0 / np.sqrt(2.0 * edf_overlapping(n, m, noise))
