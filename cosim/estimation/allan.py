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
    "OctaveAllan",
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


class OctaveAllan:
    """Overlapping Allan variance at octave cluster sizes, streamed chunk by chunk.

    The log is read once, in chunks; the memory does not grow with its length. Each
    octave ``m = 2^j`` keeps the angle (velocity) series ``theta`` on a grid of stride
    ``d = max(1, m / span)`` samples, and of that grid only the last ``2 m / d + 1``
    points: a second difference ``theta_{i+2m} - 2 theta_{i+m} + theta_i`` is summed as
    soon as its last point ``i + 2m`` has been read. Up to ``m = span`` every start
    index ``i`` is used (the fully overlapping estimator, the same numbers as allantools
    ``oadev``); beyond, the start indices are the multiples of ``d`` (``2 span + 1``
    points kept per octave, whatever the log's length). A second difference with
    stride-``d`` starts is still an exact term of the overlapping sum, so the estimate
    is unbiased; it averages ``(n - 2m) / d + 1`` of them, where the overlapping one
    averages ``n - 2m + 1`` terms that are correlated over a lag of about ``m``:
    with ``span`` of several hundred, ``m / d = span`` start indices per cluster
    length, its variance is that of the fully overlapping estimate to within a few
    parts per thousand (the module's tests measure it), so Greenhall's equivalent
    degrees of freedom of the overlapping estimator apply.

    Memory: ``(2 span + 1)`` points per octave and channel, about 40 octaves at most;
    time: one pass over each chunk per octave up to ``span``, a geometrically shrinking
    share beyond.

    Parameters
    ----------
    channels : int
        Columns of the chunks (e.g. 6: three gyros and three accelerometers).
    span : int, optional
        Start indices per cluster length beyond full overlap (a power of two).
    octaves : int, optional
        Octaves followed, ``m = 1 .. 2^(octaves - 1)`` (40: 5.5e11 samples).
    """

    def __init__(self, channels: int, span: int = 1024, octaves: int = 40) -> None:
        if span < 1 or span & (span - 1):
            raise ValueError(f"span must be a power of two, got {span}")
        self.channels = int(channels)
        self.span = int(span)
        self.m = 2 ** np.arange(int(octaves))
        self.stride = np.maximum(1, self.m // self.span)
        self.lag = self.m // self.stride
        #: Per octave beyond ``span``: the kept grid points (newest last), shape
        #: (channels, <= 2 span + 1); the octaves up to ``span`` share :attr:`fine`.
        self.ring = [np.zeros((self.channels, 1)) for _ in self.m]
        #: The last ``2 span`` values of theta at every sample (all of them while fewer).
        self.fine = np.zeros((self.channels, 1))
        self.sumsq = np.zeros((len(self.m), self.channels))
        self.terms = np.zeros(len(self.m), dtype=np.int64)
        self.count = 0
        self.theta = np.zeros(self.channels)
        self.offset: np.ndarray | None = None

    def update(self, increments: np.ndarray) -> None:
        """Add the next samples.

        Parameters
        ----------
        increments : ndarray, shape (c, channels)
            Increments over each sample interval [unit s] (angle or velocity), i.e.
            ``rate * dt``; time along axis 0.
        """
        d = np.asarray(increments, dtype=float)
        if d.ndim != 2 or d.shape[1] != self.channels:
            raise ValueError(f"increments must have shape (c, {self.channels}), got {d.shape}")
        c = d.shape[0]
        if c == 0:
            return
        if self.offset is None:
            # a constant rate does not enter the Allan variance: removing the first chunk's
            # mean keeps theta small, so the second differences keep their precision
            self.offset = d.mean(axis=0)
        # theta at indices count+1 .. count+c, one contiguous row per channel
        theta = np.ascontiguousarray((d - self.offset).T)
        np.cumsum(theta, axis=1, out=theta)
        theta += self.theta[:, None]
        ext = np.concatenate([self.fine, theta], axis=1)
        width, old = ext.shape[1], self.fine.shape[1]
        first = self.count + 1
        for j, (stride, lag) in enumerate(zip(self.stride, self.lag, strict=True)):
            if stride == 1:  # every start index: second differences ending at a new sample
                lo = max(old, 2 * lag)
                if lo >= width:
                    continue
                second = ext[:, lo:] + ext[:, lo - 2 * lag : width - 2 * lag]
                second -= ext[:, lo - lag : width - lag]
                second -= ext[:, lo - lag : width - lag]
                self.sumsq[j] += np.einsum("ij,ij->i", second, second)
                self.terms[j] += width - lo
                continue
            start = (-first) % stride  # first sample whose global index is a multiple
            if start >= c:
                continue
            pts = np.concatenate([self.ring[j], theta[:, start::stride]], axis=1)
            if pts.shape[1] > 2 * lag:
                second = pts[:, 2 * lag :] - 2.0 * pts[:, lag:-lag] + pts[:, : -2 * lag]
                self.sumsq[j] += np.einsum("ij,ij->i", second, second)
                self.terms[j] += second.shape[1]
            self.ring[j] = pts[:, -2 * lag :].copy()
        self.fine = ext[:, -2 * self.span :].copy()
        self.theta = theta[:, -1].copy()
        self.count += c

    def avar(self, dt: float, m_max: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Allan variances of the samples added so far.

        Parameters
        ----------
        dt : float
            Sample interval [s].
        m_max : int, optional
            Largest cluster size reported; default ``count // 4`` (at least 2m + 1 start
            indices for the overlapping estimator, as :func:`cosim.sensors.characterize.\
octave_factors` chooses them).

        Returns
        -------
        m : ndarray of int, shape (k,)
            Cluster sizes ``1, 2, 4, ...`` (``tau = m dt``).
        avar : ndarray, shape (k, channels)
            Allan variance [unit^2].
        """
        top = max(1, self.count // 4) if m_max is None else int(m_max)
        keep = (self.m <= top) & (self.terms > 0)
        m = self.m[keep]
        tau = m * float(dt)
        return m, self.sumsq[keep] / self.terms[keep, None] / (2.0 * tau[:, None] ** 2)
