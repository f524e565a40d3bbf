r"""Filters of the two-position HRG platform alignment (seed 000): one per position.

:class:`PositionFilter` estimates one position's state with the model of
:mod:`cosim.alignment.hrg_model`; :class:`TwoPositionAligner` runs the procedure
(position 1, indexing, position 2, eq. 16-21) without the block layer.

6. Filters (``method``)
-----------------------
- 0 **EKF** on ``x`` (analytic Jacobian, Joseph update).
- 1 **UPF**: :class:`~cosim.estimation.UnscentedParticleFilter`, a UKF per particle,
  ``n_particles`` (200) vectorised, systematic resampling, ``rng`` from ``seed``.
  The states are random constants (Q = 0), for which the exact "full" importance weight
  collapses (see the estimators' notes; sampling with roughening also failed here,
  ending in the mirror solution or collapsing), so we use ``proposal="mean"``: every
  particle moves to its UKF posterior mean and is weighted by the predictive likelihood
  of the innovation (a bank of UKFs, exact Gaussian-sum bookkeeping). The particles are
  drawn from the prior with the azimuth stratified (systematic sampling with the
  ``rng`` offset) over the circle, or over +-4 sigma of a Gaussian azimuth prior, and
  each carries the prior covariance with the azimuth variance narrowed to
  ``(kernel x spacing)^2``. Systematic resampling when the effective sample size falls
  below ``resample`` x N, 0.1 by default: with a deterministic proposal the copies of a
  resampled particle stay identical, so every resampling loses diversity for good; at
  0.5 N (or 0.25 N) one run in 41 kept only components 15-40' off after the first
  20 s and ended 4' off, at 0.1 N none did (the first resampling, at ~3 s, still
  discards the far side of the circle).
- 2 **KF** (reference, not in the paper): the linear platform-frame model (``p``, ``q``
  above, the paper's eq. 13 taken literally) and the exact ``psi = -arg(i q)``,
  ``D_N = Oc - |q|`` afterwards; its prior on ``q`` is isotropic with ``E|q|^2 = Oc^2``.

"""

from __future__ import annotations

import math

import numpy as np

from cosim.alignment.hrg_model import (
    PSI,
    UNIFORM_SIGMA,
    TwoPositionSolution,
    combine_positions,
    dv_coefficients,
    dv_jacobian,
    linear_to_polar,
    numeric_jacobian,
    polar_to_linear,
    position2_prior,
    predict_dv,
    state_steps,
    tilt_jacobian,
)
from cosim.estimation import (
    ExtendedKalmanFilter,
    KalmanFilter,
    MerweScaledSigmaPoints,
    UnscentedParticleFilter,
    angle_mean_fn,
    angle_residual_fn,
)
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR, G0, OMEGA_IE
from cosim.models.conventions import wrap_angle

#: Filter of a position by ``method``.
METHODS = {0: "EKF", 1: "UPF", 2: "KF"}


class AlignmentSequenceError(RuntimeError):
    """The platform status does not follow position 1 -> indexing -> position 2."""


# ----------------------------------------------------------------------------------------
# One position
# ----------------------------------------------------------------------------------------
class PositionFilter:
    """One position's filter on the polar state ``[theta_N0, theta_E0, D_N, psi]``.

    Parameters
    ----------
    method : int
        0 EKF, 1 UPF, 2 KF (linear platform-frame model); see the module docstring and
        :mod:`cosim.alignment.hrg_model`.
    x0 : ndarray, shape (4,)
        Prior mean.
    P0 : ndarray, shape (4, 4)
        Prior covariance (for a uniform azimuth: ``P0[3, 3] >= (pi / sqrt 3)^2``).
    lat, g : float
        Latitude [rad], gravity [m/s^2].
    r_var : float
        Measurement noise variance per axis [(m/s)^2].
    rng : numpy.random.Generator
        Randomness of the UPF (stratification offset and resampling).
    n_particles : int
        UPF particles.
    kernel : float
        UPF: component azimuth std as a multiple of the particle spacing.
    alpha : float
        UKF sigma-point spread (Merwe ``alpha``; ``kappa = 0``, ``beta = 2``).
    resample : float
        UPF: resample when the effective sample size falls below ``resample`` x N.

    Attributes
    ----------
    x : ndarray, shape (4,)
        Estimate (azimuth wrapped to (-pi, pi]).
    P : ndarray, shape (4, 4)
        Covariance (UPF: mixture covariance; KF: linearised from the linear state).
    ess : float
        UPF effective sample size (1 for the Kalman filters).
    n_resamples : int
        UPF resampling steps so far (0 for the Kalman filters).
    nis : float
        NIS of the last update (2 dof; 0 before the first and for the UPF, whose
        predictive density is a mixture, not a Gaussian).
    """

    def __init__(
        self,
        method: int,
        x0: np.ndarray,
        P0: np.ndarray,
        lat: float,
        g: float,
        r_var: float,
        rng: np.random.Generator,
        n_particles: int = 200,
        kernel: float = 1.0,
        alpha: float = 1.0,
        resample: float = 0.1,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"method: expected one of {sorted(METHODS)}, got {method}")
        self.method = int(method)
        self.lat, self.g = float(lat), float(g)
        self.R = np.eye(2) * float(r_var)
        x0 = np.asarray(x0, dtype=float).copy()
        P0 = np.asarray(P0, dtype=float).copy()
        uniform = P0[PSI, PSI] >= UNIFORM_SIGMA**2 * (1.0 - 1e-9)
        self.n_updates = 0
        self.nis = 0.0
        if self.method == 0:
            self._f = ExtendedKalmanFilter(4, 2)
            self._f.x = x0
            self._f.P = P0
            self._f.R = self.R
        elif self.method == 2:
            self._f = KalmanFilter(4, 2)
            self._f.R = self.R
            oc = OMEGA_IE * math.cos(self.lat)
            if uniform:
                # Unknown direction: p and q isotropic, moment-matched (E|q|^2 = |b|^2).
                self._f.x = np.zeros(4)
                tilt_var = 0.5 * (P0[0, 0] + P0[1, 1]) + 0.5 * (x0[0] ** 2 + x0[1] ** 2)
                rate_var = 0.5 * ((oc - x0[2]) ** 2 + P0[2, 2])
                self._f.P = np.diag([tilt_var, tilt_var, rate_var, rate_var])
            else:
                J = numeric_jacobian(lambda v: polar_to_linear(v, self.lat), x0, state_steps(P0))
                self._f.x = polar_to_linear(x0, self.lat)
                self._f.P = J @ P0 @ J.T
        else:
            pts = MerweScaledSigmaPoints(4, alpha=alpha, beta=2.0, kappa=0.0)
            self._f = UnscentedParticleFilter(
                4,
                2,
                _identity,
                self._hx,
                pts,
                rng=rng,
                n_particles=int(n_particles),
                resample_threshold=float(resample) * int(n_particles),
                proposal="mean",
                residual_x=angle_residual_fn([PSI]),
                x_mean_fn=angle_mean_fn([PSI]),
            )
            self._f.R = self.R
            parts, cov, weights = azimuth_grid(x0, P0, int(n_particles), rng, uniform, kernel)
            self._f.set_particles(parts, cov, weights)
        self._refresh()

    def _hx(self, x: np.ndarray, E0: complex, E1: complex) -> np.ndarray:
        return predict_dv(x, E0, E1, self.lat, self.g)

    def update(self, dv: np.ndarray, t0: float, t1: float) -> None:
        """Process one velocity increment.

        Parameters
        ----------
        dv : ndarray, shape (2,)
            Velocity increment along the platform x, y axes over ``[t0, t1]`` [m/s].
        t0, t1 : float
            Window, seconds from the start of the position.
        """
        E0, E1 = dv_coefficients(t0, t1, self.lat)
        z = np.asarray(dv, dtype=float)
        if self.method == 0:
            f = self._f
            f.update(
                z,
                lambda x: predict_dv(x, E0, E1, self.lat, self.g),
                lambda x: dv_jacobian(x, E0, E1, self.lat, self.g),
            )
            x = f.x.copy()
            x[PSI] = wrap_angle(x[PSI])
            f.x = x
        elif self.method == 2:
            cols = (E0, 1j * E0, E1, 1j * E1)
            H = np.array([[-self.g * c.imag for c in cols], [self.g * c.real for c in cols]])
            self._f.update(z, H=H)
        else:
            self._f.step(z, t1 - t0, hx_args={"E0": E0, "E1": E1})
        self.n_updates += 1
        if self.method != 1:  # the Kalman filters' innovation, chi-square with 2 dof
            y, S = self._f.y, self._f.S
            self.nis = float(y @ np.linalg.solve(S, y))
        self._refresh()

    def _refresh(self) -> None:
        if self.method == 2:
            y, Py = self._f.x, self._f.P
            self.x = linear_to_polar(y, self.lat)
            steps = np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(Py), 0.0)), 1e-13)
            J = numeric_jacobian(lambda v: linear_to_polar(v, self.lat), y, steps, (PSI,))
            self.P = J @ Py @ J.T
            self.ess = 1.0
        elif self.method == 0:
            self.x, self.P, self.ess = self._f.x.copy(), self._f.P.copy(), 1.0
        else:
            self.x = self._f.x.copy()
            self.x[PSI] = wrap_angle(self.x[PSI])
            self.P = self._f.P
            self.ess = self._f.ess
        self.n_resamples = self._f.n_resamples if self.method == 1 else 0


def _identity(x: np.ndarray, dt: float) -> np.ndarray:
    """Random-constant states: the process model is the identity."""
    return x


def azimuth_grid(
    x0: np.ndarray,
    P0: np.ndarray,
    n: int,
    rng: np.random.Generator,
    uniform: bool,
    kernel: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian-sum prior for the UPF: azimuth stratified, the rest conditional Gaussian.

    Parameters
    ----------
    x0 : ndarray, shape (4,)
        Prior mean (azimuth last).
    P0 : ndarray, shape (4, 4)
        Prior covariance.
    n : int
        Number of particles.
    rng : numpy.random.Generator
        Draws the common stratification offset ``u ~ U(0, 1)``.
    uniform : bool
        Azimuth uniform on the circle (equal weights); else Gaussian, the grid spanning
        +-4 sigma with weights proportional to the prior density.
    kernel : float
        Component azimuth std = ``kernel`` x grid spacing.

    Returns
    -------
    particles : ndarray, shape (n, 4)
    cov : ndarray, shape (n, 4, 4)
    weights : ndarray, shape (n,)
    """
    u = rng.uniform()
    rest = slice(0, PSI)
    if uniform:
        spacing = 2.0 * math.pi / n
        psi = x0[PSI] - math.pi + (np.arange(n) + u) * spacing
        weights = np.full(n, 1.0 / n)
        sig = 0.0
    else:
        sig = math.sqrt(P0[PSI, PSI])
        spacing = 8.0 * sig / n
        dev = -4.0 * sig + (np.arange(n) + u) * spacing
        psi = x0[PSI] + dev
        weights = np.exp(-0.5 * (dev / sig) ** 2)
        weights /= weights.sum()
    parts = np.tile(x0, (n, 1))
    cov = np.empty((n, 4, 4))
    c_rest = P0[rest, rest].copy()
    if not uniform and sig > 0.0:
        gain = P0[rest, PSI] / P0[PSI, PSI]
        parts[:, rest] += np.outer(psi - x0[PSI], gain)
        c_rest = c_rest - np.outer(gain, P0[PSI, rest])
    parts[:, PSI] = wrap_angle(psi)
    cov[:] = 0.0
    cov[:, rest, rest] = c_rest
    cov[:, PSI, PSI] = (kernel * spacing) ** 2
    return parts, cov, weights


class TwoPositionAligner:
    """The alignment procedure without the block layer: positions, priors, eq. (16)-(21).

    Feed it the accelerometer's velocity increments and the platform status with
    :meth:`step`; read the results from its attributes.

    Parameters
    ----------
    method : int
        0 EKF, 1 UPF, 2 KF.
    lat, g : float
        Latitude [rad], gravity [m/s^2].
    period : float
        Filter period: increments are summed over this long [s].
    accel_noise : float
        Accelerometer white-noise density ``N`` [m/s/sqrt(s)].
    dv_quantum : float
        Velocity per pulse ``q`` [m/s] (0: no quantisation term).
    sigma_theta0, sigma_drift, sigma_azimuth : float
        Prior stds (3', 0.2 deg/h, unknown azimuth ``pi / sqrt 3``) [rad, rad/s, rad].
    azimuth0 : float
        Prior azimuth estimate [rad].
    index_angle, sigma_index : float
        Nominal indexing angle and its accuracy [rad].
    n_particles : int
        UPF particles.
    seed : int
        UPF random seed.
    kernel, alpha : float
        UPF component width (grid spacings) and sigma-point spread.
    resample : float
        UPF resampling threshold as a fraction of the particles.
    """

    def __init__(
        self,
        method: int = 1,
        lat: float = 45.0 * DEG,
        g: float = 9.7966,
        period: float = 1.0,
        accel_noise: float = 5e-6 * G0,
        dv_quantum: float = 1e-4,
        sigma_theta0: float = 3.0 * ARCMIN,
        sigma_drift: float = 0.2 * DEG_PER_HOUR,
        sigma_azimuth: float = UNIFORM_SIGMA,
        azimuth0: float = 0.0,
        index_angle: float = math.pi / 2.0,
        sigma_index: float = 6.0 * ARCMIN,
        n_particles: int = 200,
        seed: int = 0,
        kernel: float = 1.0,
        alpha: float = 1.0,
        resample: float = 0.1,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"method: expected 0 (EKF), 1 (UPF) or 2 (KF), got {method}")
        if not period > 0.0:
            raise ValueError(f"period: expected a positive filter period, got {period}")
        if not (accel_noise > 0.0 or dv_quantum > 0.0):
            raise ValueError("accel_noise and dv_quantum: expected at least one > 0, got both 0")
        if int(n_particles) < 1:
            raise ValueError(f"n_particles: expected >= 1, got {n_particles}")
        self.method, self.lat, self.g = int(method), float(lat), float(g)
        self.period = float(period)
        self.r_var = accel_noise**2 * self.period + dv_quantum**2 / 6.0
        self.sigma_drift = float(sigma_drift)
        self.index_angle, self.sigma_index = float(index_angle), float(sigma_index)
        self.n_particles, self.kernel, self.alpha = int(n_particles), float(kernel), float(alpha)
        self.resample = float(resample)
        self.rng = np.random.default_rng(int(seed))
        self.x0 = np.array([0.0, 0.0, 0.0, float(azimuth0)])
        self.P0 = np.diag(
            [
                sigma_theta0**2,
                sigma_theta0**2,
                sigma_drift**2,
                min(sigma_azimuth, UNIFORM_SIGMA) ** 2,
            ]
        )
        self.filters: dict[int, PositionFilter] = {}
        self.starts: dict[int, float] = {}
        self.final: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.active = 0
        self.solution: TwoPositionSolution | None = None
        self._prev_status: float | None = None
        self._acc = np.zeros(2)
        self._acc_t0: float | None = None
        self._last_t = 0.0

    # ------------------------------------------------------------------ feeding
    def start(self, t: float, status: float) -> None:
        """Record the platform status at the start time ``t`` [s].

        Parameters
        ----------
        t : float
            Start time of the run [s].
        status : float
            Platform status at ``t``: 1 position 1, 0 indexing, 2 position 2.
        """
        self._prev_status = float(status)
        self._last_t = float(t)

    def step(self, t: float, h: float, dv_p: np.ndarray, status: float) -> bool:
        """Take the increment of one step ``[t, t + h]``.

        Parameters
        ----------
        t, h : float
            Step start and length [s].
        dv_p : ndarray, shape (2,) or (3,)
            Accelerometer velocity increment over the step, platform axes [m/s]
            (x, y used).
        status : float
            Platform status at ``t + h`` (1, 0, 2).

        Returns
        -------
        bool
            Whether a filter update happened in this step.

        Raises
        ------
        AlignmentSequenceError
            When position 2 data arrive before any position 1 data.
        """
        prev = self._prev_status if self._prev_status is not None else float(status)
        self._prev_status = float(status)
        self._last_t = t + h
        if not (prev == status and status in (1.0, 2.0)):
            self._acc[:] = 0.0
            self._acc_t0 = None
            return False
        pos = int(status)
        if pos != self.active:
            self._begin(pos, t)
        if self._acc_t0 is None:
            self._acc_t0 = t
            self._acc[:] = 0.0
        self._acc += np.asarray(dv_p, dtype=float)[:2]
        if t + h - self._acc_t0 < self.period - 1e-9 * self.period:
            return False
        t0 = self._acc_t0 - self.starts[pos]
        t1 = t + h - self.starts[pos]
        self.filters[pos].update(self._acc.copy(), t0, t1)
        self._acc[:] = 0.0
        self._acc_t0 = None
        if pos == 2:
            self._combine()
        return True

    def _begin(self, pos: int, t: float) -> None:
        if pos == 1 and self.active == 0:
            x0, P0 = self.x0, self.P0
        elif pos == 2 and self.active == 1:
            f1 = self.filters[1]
            self.final[1] = (f1.x.copy(), f1.P.copy())
            x0, P0 = position2_prior(
                f1.x,
                f1.P,
                t - self.starts[1],
                self.index_angle,
                self.lat,
                self.sigma_drift,
                self.sigma_index,
                math.sqrt(self.P0[0, 0]),
            )
        else:
            raise AlignmentSequenceError(
                f"platform status: expected position 1, indexing, then position 2, got "
                f"position {pos} after position {self.active} at t = {t:g} s"
            )
        self.active = pos
        self.starts[pos] = t
        self._acc_t0 = None
        self.filters[pos] = PositionFilter(
            self.method,
            x0,
            P0,
            self.lat,
            self.g,
            self.r_var,
            self.rng,
            self.n_particles,
            self.kernel,
            self.alpha,
            self.resample,
        )

    def _combine(self) -> None:
        x1, P1 = self.final[1]
        f2 = self.filters[2]
        self.solution = combine_positions(x1, P1, f2.x, f2.P, self.index_angle, self.lat)

    # ------------------------------------------------------------------ results
    @property
    def oc(self) -> float:
        """Horizontal earth rate ``Omega cos L`` [rad/s]."""
        return OMEGA_IE * math.cos(self.lat)

    def azimuth(self) -> tuple[float, float]:
        """Current platform azimuth estimate and 1-sigma [rad].

        Position 1: ``psi_1`` (the east drift is unknown: sigma includes
        ``sigma_drift / Oc``); position 2: eq. (20) plus the indexing angle.
        """
        if self.active == 2 and self.solution is not None:
            s = self.solution
            return float(wrap_angle(s.azimuth_avg + self.index_angle)), s.sigma_avg
        if self.active == 0:
            return float(self.x0[PSI]), math.sqrt(self.P0[PSI, PSI])
        f = self.filters[self.active]
        sig = math.sqrt(f.P[PSI, PSI] + (self.sigma_drift / self.oc) ** 2)
        return float(f.x[PSI]), sig

    def tilts(self, t: float) -> tuple[float, float, float, float]:
        """Current level misalignments ``theta_E``, ``theta_N`` and their 1-sigma [rad].

        The model frame of a position is geographic turned by ``delta``; it is turned
        back with the two-position ``delta`` when known (position 2), else with 0 and
        the unknown ``delta`` (``sigma_drift / Oc``) added to the sigma.

        Parameters
        ----------
        t : float
            Time at which to evaluate the tilts [s] (the active position's filter state is
            propagated from its position start to ``t``).

        Returns
        -------
        theta_E, theta_N, sigma_E, sigma_N : float
            Geographic level misalignments about east and north and their 1-sigma [rad].
        """
        if self.active == 0:
            s = math.sqrt(self.P0[0, 0])
            return 0.0, 0.0, s, s
        f = self.filters[self.active]
        dt = t - self.starts[self.active]
        if self.active == 2 and self.solution is not None:
            delta, sig_delta = self.solution.delta_2, 0.0
        else:
            delta, sig_delta = 0.0, self.sigma_drift / self.oc

        x = f.x
        u, J = tilt_jacobian(x, dt, delta, self.lat)
        C = J @ f.P[:3, :3] @ J.T
        # an unknown turn of the frame moves the tilt across itself: i u = (-u_N, u_E)
        var_e = C[0, 0] + (u.imag * sig_delta) ** 2
        var_n = C[1, 1] + (u.real * sig_delta) ** 2
        return u.real, u.imag, math.sqrt(var_e), math.sqrt(var_n)


# ----------------------------------------------------------------------------------------
# Error budget of the linear KF (method 2): the measurement-noise parts
# ----------------------------------------------------------------------------------------
#: The estimates :func:`kf_noise_budget` differentiates, in order (SI: rad, rad/s).
KF_OUTPUTS = ("azimuth", "theta_E", "theta_N", "D_N", "D_E")


def kf_windows(
    aligner: TwoPositionAligner, times: np.ndarray, dv_p: np.ndarray, status: np.ndarray
) -> list[tuple[int, float, float, np.ndarray]]:
    """Feed a recorded run to an aligner and return the filter windows it used.

    Parameters
    ----------
    aligner : TwoPositionAligner
        A fresh aligner (any method; the budget uses 2, the KF).
    times : ndarray, shape (n,)
        Recorded times, one per macro step [s].
    dv_p : ndarray, shape (n, 2)
        Accelerometer velocity increments along platform x, y [m/s]; row ``k + 1`` is
        the increment the filter block reads for the step from ``times[k]``.
    status : ndarray, shape (n,)
        Platform status (1, 0, 2), aligned as ``dv_p``.

    Returns
    -------
    list of tuple
        ``(position, t0, t1, dv)`` per filter update: window in seconds from the start
        of its position and the summed increment, shape (2,) [m/s].
    """
    aligner.start(float(times[0]), float(status[0]))
    out: list[tuple[int, float, float, np.ndarray]] = []
    prev = float(status[0])
    acc: list | None = None
    for k in range(len(times) - 1):
        t, h = float(times[k]), float(times[k + 1] - times[k])
        z, s = np.asarray(dv_p[k + 1], dtype=float)[:2], float(status[k + 1])
        run = prev == s and s in (1.0, 2.0)
        prev = s
        if not run:
            acc = None
        elif acc is None:
            acc = [t, z.copy()]
        else:
            acc[1] = acc[1] + z
        if aligner.step(t, h, z, s) and acc is not None:
            pos = int(s)
            start = aligner.starts[pos]
            out.append((pos, acc[0] - start, t + h - start, acc[1]))
            acc = None
    return out


def kf_noise_budget(
    aligner: TwoPositionAligner,
    windows: list[tuple[int, float, float, np.ndarray]],
    t: float,
    noise: dict[str, float],
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """Variance of the KF's two-position estimates from each measurement-noise source.

    The KF (``method`` 2) is linear in each position's measurements, so the noise part
    of its linear state's covariance is exact (:func:`cosim.estimation.covariance.
    covariance_budget` with the filter's own gains, ``P_0`` its prior); the estimates
    are then propagated to first order: through ``linear_to_polar``, through position
    2's prior (a position-1 error moves position 2's prior mean: the derivative is taken
    by rerunning position 2 on the same data) and through eq. (16)-(21)
    (:func:`combine_positions`) and the tilt propagation. The two positions' noises are
    independent, so their parts add.

    Parameters
    ----------
    aligner : TwoPositionAligner
        The aligner (method 2) that processed ``windows`` (its ``starts``, priors, ``lat``,
        ``g``, ``r_var``, indexing and drift parameters are used).
    windows : list of tuple
        :func:`kf_windows` of the run (noise-free data: the point of linearisation).
    t : float
        Time of the estimates [s], in position 2.
    noise : dict
        Source -> its measurement variance per axis and window [(m/s)^2]; they sum to
        ``aligner.r_var``.

    Returns
    -------
    estimate : ndarray, shape (5,)
        :data:`KF_OUTPUTS` at ``t`` [rad, rad, rad, rad/s, rad/s] (azimuth wrapped).
    parts : dict
        Source -> variance of each output, shape (5,) [SI^2].
    total : ndarray, shape (5,)
        The same from the covariance's total (all noises together) [SI^2].
    """
    from cosim.estimation.covariance import covariance_budget

    lat, g, r_var = aligner.lat, aligner.g, aligner.r_var
    rng = np.random.default_rng(0)  # unused by the KF
    wins = {p: [w for w in windows if w[0] == p] for p in (1, 2)}
    gap = aligner.starts[2] - aligner.starts[1]

    def run(pos: int, x0: np.ndarray, P0: np.ndarray) -> PositionFilter:
        f = PositionFilter(2, x0, P0, lat, g, r_var, rng)
        for _, t0, t1, dv in wins[pos]:
            f.update(dv, t0, t1)
        return f

    def prior2(x1: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return position2_prior(
            x1,
            P1,
            gap,
            aligner.index_angle,
            lat,
            aligner.sigma_drift,
            aligner.sigma_index,
            math.sqrt(aligner.P0[0, 0]),
        )

    def outputs(x1: np.ndarray, P1: np.ndarray, x2: np.ndarray, P2: np.ndarray) -> np.ndarray:
        s = combine_positions(x1, P1, x2, P2, aligner.index_angle, lat)
        u, _ = tilt_jacobian(x2, t - aligner.starts[2], s.delta_2, lat)
        az = float(wrap_angle(s.azimuth_avg + aligner.index_angle))
        return np.array([az, u.real, u.imag, s.D_N, s.D_E])

    f1 = run(1, aligner.x0, aligner.P0)
    x1, P1 = f1.x.copy(), f1.P.copy()
    x20, P20 = prior2(x1, P1)
    f2 = run(2, x20, P20)
    x2, P2 = f2.x.copy(), f2.P.copy()
    estimate = outputs(x1, P1, x2, P2)

    def through_2(v: np.ndarray) -> np.ndarray:
        f = run(2, *prior2(v, P1))
        return outputs(v, P1, f.x, P2)

    a1 = numeric_jacobian(through_2, x1, state_steps(P1), (0,))
    a2 = numeric_jacobian(lambda v: outputs(x1, P1, v, P2), x2, state_steps(P2), (0,))

    def noise_parts(pos: int, x0: np.ndarray, P0: np.ndarray, x_end: np.ndarray) -> dict:
        Py0 = kf_prior_covariance(x0, P0, lat)
        Hs = []
        for _, t0, t1, _ in wins[pos]:
            E0, E1 = dv_coefficients(t0, t1, lat)
            cols = (E0, 1j * E0, E1, 1j * E1)
            Hs.append(np.array([[-g * c.imag for c in cols], [g * c.real for c in cols]]))
        n = len(Hs)
        bud = covariance_budget(
            {"prior": Py0},
            n,
            1.0,
            lambda k: (np.eye(4), {}),
            lambda k: (Hs[k], {s: v * np.eye(2) for s, v in noise.items()}),
            record_every=n,
            include_start=False,
        )
        y = polar_to_linear(x_end, lat)
        steps = np.maximum(1e-3 * np.sqrt(np.maximum(np.diag(bud.total[-1]), 0.0)), 1e-13)
        J = numeric_jacobian(lambda v: linear_to_polar(v, lat), y, steps, (PSI,))
        out = {s: J @ bud.parts[s][-1] @ J.T for s in noise}
        out["_all"] = J @ (bud.total[-1] - bud.parts["prior"][-1]) @ J.T
        return out

    n1 = noise_parts(1, aligner.x0, aligner.P0, x1)
    n2 = noise_parts(2, x20, P20, x2)

    def var(C1: np.ndarray, C2: np.ndarray) -> np.ndarray:
        return np.einsum("ij,jk,ik->i", a1, C1, a1) + np.einsum("ij,jk,ik->i", a2, C2, a2)

    parts = {s: var(n1[s], n2[s]) for s in noise}
    return estimate, parts, var(n1["_all"], n2["_all"])


def kf_prior_covariance(x0: np.ndarray, P0: np.ndarray, lat: float) -> np.ndarray:
    """The KF's prior covariance of its linear state ``[Re p, Im p, Re q, Im q]``.

    As :class:`PositionFilter` with ``method`` 2 sets it: for an unknown azimuth
    isotropic and moment-matched, else ``J P0 J^T`` of :func:`polar_to_linear`.

    Parameters
    ----------
    x0 : ndarray, shape (4,)
        Polar prior mean [rad, rad, rad/s, rad].
    P0 : ndarray, shape (4, 4)
        Polar prior covariance.
    lat : float
        Latitude [rad].

    Returns
    -------
    ndarray, shape (4, 4)
        [rad^2, (rad/s)^2].
    """
    oc = OMEGA_IE * math.cos(lat)
    if P0[PSI, PSI] >= UNIFORM_SIGMA**2 * (1.0 - 1e-9):
        tilt_var = 0.5 * (P0[0, 0] + P0[1, 1]) + 0.5 * (x0[0] ** 2 + x0[1] ** 2)
        rate_var = 0.5 * ((oc - x0[2]) ** 2 + P0[2, 2])
        return np.diag([tilt_var, tilt_var, rate_var, rate_var])
    J = numeric_jacobian(lambda v: polar_to_linear(v, lat), x0, state_steps(P0))
    return J @ P0 @ J.T
