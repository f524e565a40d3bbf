"""Characterise an inertial sensor from a static log: Allan deviation, noise terms, grade.

Allan deviation
    The overlapping Allan deviation of each axis's rate samples at octave-spaced averaging
    times ``tau = m dt``, ``m = 1, 2, 4, ... <= n / 4``, streamed over the log in one pass
    (:class:`cosim.estimation.allan.OctaveAllan`: fully overlapping up to ``m = 1024``,
    the same numbers as allantools ``oadev``; beyond, 1024 start indices per cluster
    length), with the equivalent degrees of freedom of Greenhall (allantools
    ``edf_greenhall``, overlapping Allan variance, noise type of the fitted term that
    dominates at that ``tau``) and the chi-square band from them (68 %: one standard
    error).

Noise terms (IEEE Std 952-1997, Annex C; IEEE Std 1293-2018 for accelerometers)
    The Allan variance of the sum of independent processes is the sum of their variances::

        avar(tau) = 3 Q^2 / tau^2        quantisation, Q the angle (velocity) noise std
                  + N^2 / tau            white rate noise: ARW (VRW) density N, slope -1/2
                  + (2 ln 2 / pi) B^2    flicker rate noise: bias instability B, slope 0
                  + K^2 tau / 3          rate (acceleration) random walk K, slope +1/2

    The readings of the standards (``N = adev(1 s)`` on the -1/2 line, ``B = adev_min /
    0.664`` on the flat part, ``K = adev(3 s)`` on the +1/2 line, ``Q = adev(sqrt(3) s)``
    on the -1 line) are those four lines; here they are fitted at once: the model is linear
    in ``(Q^2, N^2, B^2, K^2)``, solved by non-negative weighted least squares with the
    weights ``edf / (2 avar_model^2)`` (the variance of an Allan variance estimate),
    iterated from the data to the model (:func:`fit_noise`).

Uncertainties
    A parametric bootstrap in the Allan domain (:func:`intervals`): no log is simulated.
    Each Allan variance estimate is distributed as ``avar chi2(edf) / edf`` with Greenhall's
    equivalent degrees of freedom ``edf`` (the chi-square model of NIST SP 1065);
    ``boot`` sets of Allan variances are drawn from the fitted model that way and refitted
    by the fit's weighted least squares, with the fitted model's weights. The interval for
    each parameter ``p`` is ``[p / r_hi, p / r_lo]`` with ``r_lo``, ``r_hi`` the quantiles
    of the ratio ``p* / p`` over the refits (a scale pivot). The estimates of neighbouring
    octaves share data and are correlated (0.5 to 0.9 one octave apart, by noise type):
    the draws are joined by a Gaussian copula with the correlations of
    :data:`OCTAVE_CORRELATION`, so that a term resolved over several octaves does not get
    the narrow interval of independent points. A term fitted is *not resolved* when more
    than ``(1 - level) / 2`` of the refits give it zero: its interval is then ``[0, 2 q]``
    with ``q`` the upper quantile of ``p*`` (an upper bound only, made conservative by the
    factor 2). The level is 95 % by default. The cost is that of ``boot`` least-squares
    fits of some 20 points, whatever the log's length.

Parameters of our IMU model
    ``gyro_arw`` / ``accel_vrw`` = N, ``gyro_rrw`` / ``accel_rrw`` = K, ``*_lsb`` =
    ``sqrt(12) Q`` (the StrapdownImu quantiser keeps its residual, so its angle error is
    uniform over one LSB), and the flicker floor is represented by the model's first-order
    Gauss-Markov bias: correlation time ``tau_min / x_peak`` and sigma ``adev_floor /
    r_peak``, where a Gauss-Markov process peaks at ``tau = x_peak T`` with ``adev = r_peak
    sigma`` (:data:`GM_PEAK`, about 1.89 and 0.62). A first-order Gauss-Markov process
    matches flicker noise only around that peak: the parameter block says so.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import nnls
from scipy.stats import chi2, norm

from cosim.errors import UserError
from cosim.estimation.allan import OctaveAllan
from cosim.models.constants import DEG_PER_HOUR, DEG_PER_SQRT_HOUR, MICRO_G

#: The four noise terms, in the order of the fitted coefficients.
TERMS = ("quantization", "white", "bias_instability", "random_walk")
#: allantools noise exponent alpha (frequency PSD ~ f^alpha) of each term, for the edf.
ALPHA = (2, 0, -1, -2)
#: IEEE Std 952 factor of the flicker floor: avar = FLICKER * B^2.
FLICKER = 2.0 * math.log(2.0) / math.pi
#: Confidence of the adev bands in the plot and csv (one standard error).
BAND = 0.6826894921370859
#: Correlation of the logs of two overlapping Allan variance estimates ``lag`` octaves
#: apart (lag 1, 2, ...; 0 beyond), per term of :data:`TERMS` dominating the estimates:
#: measured here once on 800 records of 2^16 samples of each pure noise
#: (:class:`cosim.estimation.allan.OctaveAllan`, the octaves away from both ends); the
#: correlation does not depend on the octave (the estimators are scale invariant). White
#: phase (quantisation) noise couples every octave through the variance of the angle noise.
OCTAVE_CORRELATION = (
    (0.39, 0.48, 0.48, 0.47, 0.45, 0.45, 0.45, 0.45, 0.45, 0.45, 0.45, 0.45),
    (0.52, 0.18, 0.07, 0.04),
    (0.69, 0.31, 0.12, 0.03),
    (0.88, 0.67, 0.49, 0.36, 0.26, 0.18, 0.13, 0.09),
)


def allantools_module() -> Any:
    """allantools, imported here only (its one place in the package).

    Returns
    -------
    module

    Raises
    ------
    UserError
        Not installed: the message gives the pip command.
    """
    try:
        import allantools
    except ImportError as exc:  # an optional dependency: the `allan` extra
        raise UserError(
            "ins-cosim characterize needs allantools (Greenhall's equivalent degrees of "
            "freedom), an optional dependency (it brings pytest and numpydoc along, so a "
            "plain install leaves it out): pip install 'ins-cosim[allan]'"
        ) from exc
    return allantools


def design(tau: np.ndarray) -> np.ndarray:
    """Columns of the Allan-variance model at ``tau``, one per term of :data:`TERMS`.

    Parameters
    ----------
    tau : ndarray, shape (k,)
        Averaging times [s].

    Returns
    -------
    ndarray, shape (k, 4)
        ``[3 / tau^2, 1 / tau, 2 ln 2 / pi, tau / 3]``: ``avar = design(tau) @ c`` with
        ``c = (Q^2, N^2, B^2, K^2)``.
    """
    tau = np.asarray(tau, dtype=float)
    return np.column_stack(
        [3.0 / tau**2, 1.0 / tau, np.full_like(tau, FLICKER), tau / 3.0]
    )  # fmt: skip


def _gm_peak() -> tuple[float, float]:
    x = np.linspace(0.05, 20.0, 400001)
    inner = 1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x)
    ratio = np.sqrt(2.0 / x * inner)
    k = int(np.argmax(ratio))
    return float(x[k]), float(ratio[k])


#: (x_peak, r_peak): a first-order Gauss-Markov process of std sigma and correlation time T
#: has ``avar(tau) = (2 sigma^2 T / tau) [1 - T (3 - 4 e^(-tau/T) + e^(-2 tau/T)) / (2 tau)]``,
#: largest at ``tau = x_peak T`` where ``adev = r_peak sigma``.
GM_PEAK = _gm_peak()


@functools.lru_cache(maxsize=4096)
def edf(alpha: int, m: int, n_phase: int) -> float:
    """Greenhall's equivalent degrees of freedom of the overlapping Allan variance.

    Parameters
    ----------
    alpha : int
        Noise exponent (frequency PSD ~ f^alpha): 2, 0, -1 or -2 (see :data:`ALPHA`).
    m : int
        Averaging factor (``tau = m dt``).
    n_phase : int
        Number of phase (angle) points, samples + 1.

    Returns
    -------
    float
        allantools ``edf_greenhall(alpha, 2, m, n_phase, overlapping=True)``.
    """
    return float(allantools_module().edf_greenhall(alpha, 2, m, n_phase, overlapping=True))


def octave_factors(n: int) -> np.ndarray:
    """Averaging factors ``1, 2, 4, ... <= n / 4`` for a record of ``n`` rate samples.

    Parameters
    ----------
    n : int
        Rate samples.

    Returns
    -------
    ndarray of int, shape (k,)
    """
    top = max(1, n // 4)
    return 2 ** np.arange(int(math.floor(math.log2(top))) + 1)


def fit_noise(
    tau: np.ndarray, avar: np.ndarray, m: np.ndarray, n: int, iterations: int = 6
) -> tuple[np.ndarray, np.ndarray]:
    """Fit ``(Q^2, N^2, B^2, K^2)`` to Allan variances by non-negative weighted least squares.

    Parameters
    ----------
    tau : ndarray, shape (k,)
        Averaging times [s].
    avar : ndarray, shape (k,)
        Measured Allan variances [unit^2].
    m : ndarray of int, shape (k,)
        Their averaging factors.
    n : int
        Rate samples in the record.
    iterations : int, optional
        Re-weightings: the first weights use the measured variances, the next the model's.

    Returns
    -------
    c : ndarray, shape (4,)
        Coefficients, >= 0 (order of :data:`TERMS`).
    edfs : ndarray, shape (k,)
        The equivalent degrees of freedom used at each ``tau`` (last iteration).
    """
    a = design(tau)
    avar = np.asarray(avar, dtype=float)
    c = np.zeros(4)
    model = avar.copy()
    edfs = np.ones(len(tau))
    for _ in range(iterations):
        parts = a * c if c.any() else np.tile(model[:, None] / 4.0, (1, 4))
        dominant = np.argmax(parts, axis=1)
        edfs = np.array([edf(ALPHA[d], int(mi), n + 1) for d, mi in zip(dominant, m, strict=True)])
        w = np.sqrt(edfs / 2.0) / np.maximum(model, 1e-300)
        scale = np.abs(a * w[:, None]).max(axis=0)
        sol, _ = nnls(a * w[:, None] / scale, avar * w)
        c = sol / scale
        model = a @ c
    return c, edfs


def kasdin_flicker(n: int, rng: np.random.Generator) -> np.ndarray:
    """Flicker (1/f) rate noise of unit bias instability (Kasdin & Walter 1992 filter).

    White normals filtered with ``h_0 = 1``, ``h_k = h_{k-1} (k - 1/2) / k`` (power-law
    exponent 1); its Allan variance tends to ``(2 ln 2 / pi) * 1`` (B = 1).

    Parameters
    ----------
    n : int
        Samples.
    rng : numpy.random.Generator
        Source of the normals.

    Returns
    -------
    ndarray, shape (n,)
    """
    k = np.arange(1, n)
    h = np.concatenate([[1.0], np.cumprod((k - 0.5) / k)])
    w = rng.standard_normal(n)
    size = 2 * n
    return np.fft.irfft(np.fft.rfft(w, size) * np.fft.rfft(h, size), size)[:n]


def simulate(c: np.ndarray, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """Rate samples of a noise model (test and benchmark logs).

    Parameters
    ----------
    c : ndarray, shape (4,)
        ``(Q^2, N^2, B^2, K^2)`` in SI.
    n : int
        Samples.
    dt : float
        Sample interval [s].
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    ndarray, shape (n,)
        Mean rates over each interval [unit].
    """
    q, white, b, k = np.sqrt(np.maximum(c, 0.0))
    y = white / math.sqrt(dt) * rng.standard_normal(n)
    if b > 0.0:
        y += b * kasdin_flicker(n, rng)
    if k > 0.0:
        y += np.cumsum(k * math.sqrt(dt) * rng.standard_normal(n))
    if q > 0.0:
        x = q * rng.standard_normal(n + 1)
        y += np.diff(x) / dt
    return y


@dataclass
class AxisFit:
    """The Allan deviation of one axis and its fitted noise terms.

    Attributes
    ----------
    tau : ndarray, shape (k,)
        Averaging times [s].
    adev : ndarray, shape (k,)
        Overlapping Allan deviation [SI rate unit].
    band : ndarray, shape (k, 2)
        68 % chi-square band of ``adev`` (Greenhall edf).
    edf : ndarray, shape (k,)
        Equivalent degrees of freedom.
    value : ndarray, shape (4,)
        ``(Q, N, B, K)`` [unit s, unit sqrt(s), unit, unit / sqrt(s)] (:data:`TERMS`).
    low, high : ndarray, shape (4,)
        Confidence interval of each (level ``level``).
    level : float
        Confidence level of ``low`` .. ``high``.
    n : int
        Rate samples.
    dt : float
        Sample interval [s].
    boot : ndarray, shape (boot, 4)
        The bootstrap refits of ``value`` (empty without a bootstrap).
    """

    tau: np.ndarray
    adev: np.ndarray
    band: np.ndarray
    edf: np.ndarray
    value: np.ndarray
    low: np.ndarray
    high: np.ndarray
    level: float
    n: int
    dt: float
    boot: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 4)))

    @property
    def resolved(self) -> np.ndarray:
        """``value`` where the term is resolved (its interval excludes 0), else 0; shape (4,)."""
        return np.where(self.low > 0.0, self.value, 0.0)

    def model(self, tau: np.ndarray) -> np.ndarray:
        """Fitted Allan deviation at ``tau``.

        Parameters
        ----------
        tau : ndarray, shape (j,)
            Averaging times [s].

        Returns
        -------
        ndarray, shape (j,)
        """
        return np.sqrt(design(tau) @ self.value**2)

    def gauss_markov(self) -> tuple[float, float]:
        """The flicker floor as the StrapdownImu's first-order Gauss-Markov bias.

        Returns
        -------
        sigma : float
            Stationary std [unit]; 0 when no flicker was resolved.
        tau_c : float
            Correlation time [s]: the ``tau`` of the fitted curve's minimum / ``x_peak``.
        """
        b = self.resolved[2]
        if b <= 0.0:
            return 0.0, 3600.0
        grid = np.geomspace(self.tau[0], self.tau[-1], 400)
        tau_min = float(grid[np.argmin(self.model(grid))])
        x_peak, r_peak = GM_PEAK
        return math.sqrt(FLICKER) * b / r_peak, tau_min / x_peak


def octave_correlation(dominant: np.ndarray) -> np.ndarray:
    """Correlation matrix of the octave Allan variance estimates (for the copula).

    Parameters
    ----------
    dominant : ndarray of int, shape (k,)
        Index in :data:`TERMS` of the term dominating each octave's Allan variance.

    Returns
    -------
    ndarray, shape (k, k)
        ``rho_ij = sqrt(r_i(|i - j|) r_j(|i - j|))`` with ``r`` the row of
        :data:`OCTAVE_CORRELATION` of each octave's term, made positive definite (its
        eigenvalues raised to 1e-6 at least, the diagonal restored to 1).
    """
    k = len(dominant)
    table = np.zeros((4, k))
    for j, row in enumerate(OCTAVE_CORRELATION):
        n = min(len(row), k - 1)
        table[j, 1 : n + 1] = row[:n]
        if j == 0 and k - 1 > n:
            table[j, n + 1 :] = row[-1]
    table[:, 0] = 1.0
    lag = np.abs(np.subtract.outer(np.arange(k), np.arange(k)))
    r = table[np.asarray(dominant)[:, None], lag]
    rho = np.sqrt(r * r.T)
    w, v = np.linalg.eigh(rho)
    rho = (v * np.maximum(w, 1e-6)) @ v.T
    d = np.sqrt(np.diag(rho))
    return rho / np.outer(d, d)


def intervals(
    c: np.ndarray,
    tau: np.ndarray,
    m: np.ndarray,
    n: int,
    edfs: np.ndarray,
    *,
    boot: int,
    level: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Confidence intervals of the fitted terms: a bootstrap of the Allan variances alone.

    ``boot`` sets of Allan variances ``avar_model(tau) chi2(edf) / edf`` (correlated across
    ``tau``, :func:`octave_correlation`) are refitted by the weighted least squares of
    :func:`fit_noise` with the fitted model's weights; see the module docstring for the
    pivot and the unresolved terms.

    Parameters
    ----------
    c : ndarray, shape (4,)
        Fitted ``(Q^2, N^2, B^2, K^2)``.
    tau : ndarray, shape (k,)
        Averaging times [s].
    m : ndarray of int, shape (k,)
        Their averaging factors.
    n : int
        Rate samples in the record.
    edfs : ndarray, shape (k,)
        Equivalent degrees of freedom at each ``tau`` (from the fit).
    boot : int
        Refits (> 0).
    level : float
        Confidence level.
    rng : numpy.random.Generator
        Source of the chi-square draws.

    Returns
    -------
    low, high : ndarray, shape (4,)
        Interval of each of ``(Q, N, B, K)``.
    refits : ndarray, shape (boot, 4)
        The refitted ``(Q, N, B, K)``.
    """
    parts = design(tau) * c
    model = parts.sum(axis=1)
    lower = np.linalg.cholesky(octave_correlation(np.argmax(parts, axis=1)))
    u = norm.cdf(rng.standard_normal((boot, len(tau))) @ lower.T)
    draws = model * chi2.ppf(u, edfs) / edfs
    # each refit is the fit's weighted least squares with the weights of the fitted model
    # (the fit's last iteration): the weights are the same for every draw
    w = np.sqrt(edfs / 2.0) / np.maximum(model, 1e-300)
    weighted = design(tau) * w[:, None]
    scale = np.abs(weighted).max(axis=0)
    refits = np.sqrt(np.array([nnls(weighted / scale, d * w)[0] for d in draws]) / scale)
    value = np.sqrt(c)
    low, high = value.copy(), value.copy()
    a = (1.0 - level) / 2.0
    for j in range(4):
        r = refits[:, j] / value[j] if value[j] > 0.0 else np.zeros(boot)
        r_lo, r_hi = np.quantile(r, [a, 1.0 - a])
        if r_lo > 0.0:
            low[j], high[j] = value[j] / r_hi, value[j] / r_lo
        else:  # not resolved: an upper bound only, conservatively twice the quantile
            low[j], high[j] = 0.0, 2.0 * float(np.quantile(refits[:, j], 1.0 - a))
    return low, high, refits


def fit_axis(
    m: np.ndarray,
    avar: np.ndarray,
    n: int,
    dt: float,
    *,
    boot: int = 1000,
    level: float = 0.95,
    seed: int = 0,
) -> AxisFit:
    """Noise terms and their confidence intervals from one axis's Allan variances.

    Parameters
    ----------
    m : ndarray of int, shape (k,)
        Averaging factors (``tau = m dt``), octave-spaced (:func:`octave_factors`).
    avar : ndarray, shape (k,)
        Overlapping Allan variances [SI rate unit^2].
    n : int
        Rate samples of the record.
    dt : float
        Sample interval [s].
    boot : int, optional
        Bootstrap refits of the Allan variances (0: no intervals, ``low = high = value``).
    level : float, optional
        Confidence level of the intervals.
    seed : int, optional
        Seed of the bootstrap's generator.

    Returns
    -------
    AxisFit
    """
    m = np.asarray(m, dtype=int)
    tau = m * dt
    avar = np.asarray(avar, dtype=float)
    c, edfs = fit_noise(tau, avar, m, n)
    adev = np.sqrt(avar)
    # chi-square band of adev, level BAND (allantools confidence_interval's formula)
    lo_q, hi_q = chi2.ppf([(1.0 + BAND) / 2.0, (1.0 - BAND) / 2.0], edfs[:, None]).T
    band = np.column_stack([adev * np.sqrt(edfs / lo_q), adev * np.sqrt(edfs / hi_q)])
    value = np.sqrt(c)
    low, high, refits = value.copy(), value.copy(), np.zeros((0, 4))
    if boot > 0:
        low, high, refits = intervals(
            c, tau, m, n, edfs, boot=boot, level=level, rng=np.random.default_rng(seed)
        )
    return AxisFit(tau, adev, band, edfs, value, low, high, level, n, dt, refits)


def characterize_axis(
    rate: np.ndarray, dt: float, *, boot: int = 1000, level: float = 0.95, seed: int = 0
) -> AxisFit:
    """Allan deviation, fitted noise terms and their confidence intervals of one record.

    Parameters
    ----------
    rate : ndarray, shape (n,)
        Mean rates over each sample interval [SI rate unit: rad/s or m/s2].
    dt : float
        Sample interval [s].
    boot : int, optional
        Bootstrap refits (0: no intervals, ``low = high = value``).
    level : float, optional
        Confidence level of the intervals.
    seed : int, optional
        Seed of the bootstrap's generator.

    Returns
    -------
    AxisFit
    """
    y = np.asarray(rate, dtype=float)
    n = len(y)
    if n < 16:
        raise ValueError(f"need at least 16 samples for an Allan analysis, got {n}")
    acc = OctaveAllan(1)
    acc.update(y[:, None] * dt)
    m, avar = acc.avar(dt)
    return fit_axis(m, avar[:, 0], n, dt, boot=boot, level=level, seed=seed)


# ----------------------------------------------------------------------------- grades
@dataclass(frozen=True)
class Grade:
    """Indicative error figures of a class of IMU (decade centres of the cited ranges).

    Attributes
    ----------
    name : str
        Class name.
    gyro_bi : float
        Gyro bias instability [rad/s].
    gyro_arw : float
        Angle random walk [rad/sqrt(s)].
    accel_bi : float
        Accelerometer bias instability [m/s2].
    accel_vrw : float
        Velocity random walk [m/s/sqrt(s)].
    source : str
        Where the figures come from.
    """

    name: str
    gyro_bi: float
    gyro_arw: float
    accel_bi: float
    accel_vrw: float
    source: str


_SOURCE_CLASSES = (
    "class names and order of magnitude: Groves, Principles of GNSS, Inertial, and "
    "Multisensor Integrated Navigation Systems, 2nd ed., Artech House 2013, section 4.4; "
    "El-Sheimy & Youssef, Inertial sensors technologies for navigation applications, "
    "Satellite Navigation 1:2 (2020); figures: decade centres chosen here"
)
_SOURCE_PRESETS = (
    "models/blocks/strapdown_imu.PRESETS (the project's grade presets); " + _SOURCE_CLASSES
)

#: The grade presets, best last. Indicative figures of a class, not of any product.
GRADES = (
    Grade(
        "consumer MEMS",
        30.0 * DEG_PER_HOUR,
        0.5 * DEG_PER_SQRT_HOUR,
        1000.0 * MICRO_G,
        300.0 * MICRO_G,
        _SOURCE_CLASSES,
    ),
    Grade(
        "industrial",
        3.0 * DEG_PER_HOUR,
        0.2 * DEG_PER_SQRT_HOUR,
        200.0 * MICRO_G,
        150.0 * MICRO_G,
        _SOURCE_CLASSES,
    ),
    Grade(
        "tactical",
        0.5 * DEG_PER_HOUR,
        0.1 * DEG_PER_SQRT_HOUR,
        50.0 * MICRO_G,
        100.0 * MICRO_G,
        _SOURCE_PRESETS,
    ),
    Grade(
        "navigation",
        0.005 * DEG_PER_HOUR,
        0.002 * DEG_PER_SQRT_HOUR,
        10.0 * MICRO_G,
        10.0 * MICRO_G,
        _SOURCE_PRESETS,
    ),
    Grade(
        "strategic",
        0.0005 * DEG_PER_HOUR,
        0.0002 * DEG_PER_SQRT_HOUR,
        1.0 * MICRO_G,
        1.0 * MICRO_G,
        _SOURCE_CLASSES,
    ),
)


def closest_grade(
    gyro_bi: float | None = None,
    gyro_arw: float | None = None,
    accel_bi: float | None = None,
    accel_vrw: float | None = None,
) -> tuple[Grade, float]:
    """The grade preset nearest to a sensor's figures, in decades.

    Parameters
    ----------
    gyro_bi : float, optional
        Gyro bias instability [rad/s].
    gyro_arw : float, optional
        Angle random walk [rad/sqrt(s)].
    accel_bi : float, optional
        Accelerometer bias instability [m/s2].
    accel_vrw : float, optional
        Velocity random walk [m/s/sqrt(s)].

    Returns
    -------
    grade : Grade
        The preset with the smallest RMS of ``log10(figure / preset)`` over the figures
        given (those > 0).
    distance : float
        That RMS [decades].
    """
    given = [
        (value, attr)
        for value, attr in (
            (gyro_bi, "gyro_bi"),
            (gyro_arw, "gyro_arw"),
            (accel_bi, "accel_bi"),
            (accel_vrw, "accel_vrw"),
        )
        if value is not None and value > 0.0
    ]
    if not given:
        raise ValueError("no figure > 0 to compare with the grade presets")
    best: tuple[Grade, float] | None = None
    for grade in GRADES:
        d = math.sqrt(
            sum(math.log10(v / getattr(grade, a)) ** 2 for v, a in given) / len(given)
        )  # fmt: skip
        if best is None or d < best[1]:
            best = (grade, d)
    assert best is not None
    return best
