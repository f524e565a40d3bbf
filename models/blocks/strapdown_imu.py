"""Strapdown IMU: three gyros and three accelerometers delivering increments.

Inputs are the exact true increments over the communication step ``[t, t + h]``
from a motion block (body frame b = FRD of the IMU case), outputs the measured
increments. Per sensor triad (gyro ``g``: angle [rad]; accelerometer ``a``:
velocity [m/s]) and per axis::

    d_meas = Q( (I + E) d_true + int_t^{t+h} b(s) ds + n_w )

    E       = diag(sf + sf_0) + M + M_0           scale factor and misalignment [1, rad]
    b(s)    = b_fix + b_0 + x_gm(s) + x_rw(s)    total bias [rad/s | m/s2]
    x_gm'   = -x_gm / tau + w_1,  E[w_1 w_1] = 2 sigma_gm^2 / tau   (first-order Gauss-Markov)
    x_rw'   = w_2,                E[w_2 w_2] = K^2                  (rate / acceleration RW)
    n_w     ~ N(0, N^2 h)                         white noise: ARW or VRW density N
    Q(.)    quantisation to the LSB with the residual carried to the next step

``sf``, ``M``, ``b_fix`` are the configured fixed values; ``sf_0``, ``M_0`` (off-diagonal
only) and ``b_0`` are turn-on values drawn once per run with the configured sigmas.
``x_gm`` starts from its stationary distribution, ``x_rw`` from zero.

The Gauss-Markov and random-walk states are propagated with the exact joint
discretisation of ``(x(t + h), int x)`` over the step (closed form, see
:func:`integrated_first_order`), so the statistics do not depend on ``h``. The
quantiser keeps the running residual ``r``::

    r_k = r_{k-1} + y_k,   q_k = LSB * round(r_k / LSB),   r_k <- r_k - q_k

hence every output is a whole number of LSB and ``|sum q - sum y| <= LSB / 2`` for
any record length (quantisation noise does not accumulate).

Outputs: the measured increments, the mean measured rate and specific force over the
step (increment / h) and, as truth for verification, the mean total bias over the
step ``gyro_bias_b``, ``accel_bias_b`` (the bias at ``t0`` after initialisation).

Ring laser gyro option (``rlg_mode``): 0 generic gyro, 1 mechanically dithered RLG
(the configured ARW is the dithered random walk coefficient), 2 rate-biased RLG:
the random walk is divided by ``rlg_rw_reduction`` (default 10, seed 003). A
rate-biased IMU sits on a turntable: the turntable rate and the centrifugal and
tangential accelerations reach this block through its inputs and are measured like
any other motion (scale factor and misalignment included); nothing is removed here
(removing them with the encoder angle is the navigation software's job). Mode 1 is
numerically identical to mode 0.

Grades: ``grade`` 0 (custom) gives zero for every statistical parameter left unset,
so a default instance is a perfect IMU; 1 (navigation) and 2 (tactical) fill in the
values of :data:`PRESETS`. A statistical parameter is *unset* when negative (start
value -1); any value >= 0 set by the user wins over the preset. (NaN would be the
natural marker but is not a valid FMI start value.) Fixed values (``*_bias``,
``*_sf``, ``*_misalignment``) are never touched by the grade.
:meth:`StrapdownImu.resolved_parameters` returns the values in force.

Random numbers: ``numpy.random.default_rng(seed)``; at initialisation one (2, 18)
block of standard normals (per triad: turn-on bias 3, scale factor 3, misalignment 9,
initial Gauss-Markov state 3), then one (2, 5, 3) block per step (per triad: white,
Gauss-Markov 2, random walk 2). The draws do not depend on which errors are enabled.
The step blocks are drawn :data:`AHEAD_STEPS` at a time (the same numbers in the same
order) and the input-free terms computed for those steps at once, with the same
arithmetic as step by step. With :func:`models.native.library`, the per-step part (errors
applied to the inputs, quantisation, outputs) is one call of ``strapdown_imu_step``
(``models/blocks/strapdown_imu.c``, the same arithmetic).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.signal import lfilter

from cosim.models import native
from cosim.models.block import Block, input_, output, parameter, same_step
from cosim.models.constants import ARCSEC, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, MICRO_G, PPM

UNSET = -1.0  #: start value of the statistical parameters: "take it from the grade"


def _preset(
    g_bias: float,
    g_arw: float,
    g_bi: float,
    g_tau: float,
    g_sf: float,
    g_mis: float,
    a_bias: float,
    a_vrw: float,
    a_bi: float,
    a_tau: float,
    a_sf: float,
    a_mis: float,
) -> dict[str, float]:
    return {
        "gyro_bias_sigma": g_bias,
        "gyro_arw": g_arw,
        "gyro_bi_sigma": g_bi,
        "gyro_bi_tau": g_tau,
        "gyro_rrw": 0.0,
        "gyro_sf_sigma": g_sf,
        "gyro_misalignment_sigma": g_mis,
        "gyro_lsb": 0.0,
        "accel_bias_sigma": a_bias,
        "accel_vrw": a_vrw,
        "accel_bi_sigma": a_bi,
        "accel_bi_tau": a_tau,
        "accel_rrw": 0.0,
        "accel_sf_sigma": a_sf,
        "accel_misalignment_sigma": a_mis,
        "accel_lsb": 0.0,
    }


#: Grade presets in SI units: 0 custom (all zero), 1 navigation, 2 tactical.
#: Indicative round numbers for the class, not a product data sheet. Rate/acceleration
#: random walk and quantisation are interface specific and left at zero.
PRESETS: dict[int, dict[str, float]] = {
    0: _preset(0.0, 0.0, 0.0, 3600.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3600.0, 0.0, 0.0),
    1: _preset(
        0.01 * DEG_PER_HOUR,  # turn-on gyro bias
        0.002 * DEG_PER_SQRT_HOUR,  # ARW
        0.005 * DEG_PER_HOUR,  # Gauss-Markov bias instability
        3600.0,
        5.0 * PPM,
        5.0 * ARCSEC,
        25.0 * MICRO_G,  # turn-on accelerometer bias
        10.0 * MICRO_G,  # VRW 10 ug/sqrt(Hz)
        10.0 * MICRO_G,
        3600.0,
        20.0 * PPM,
        5.0 * ARCSEC,
    ),
    2: _preset(
        1.0 * DEG_PER_HOUR,
        0.1 * DEG_PER_SQRT_HOUR,
        0.5 * DEG_PER_HOUR,
        300.0,
        150.0 * PPM,
        0.5e-3,
        1000.0 * MICRO_G,
        100.0 * MICRO_G,
        50.0 * MICRO_G,
        300.0,
        300.0 * PPM,
        0.5e-3,
    ),
}


def white_density_from_random(sigma: float, tau_ref: float = 1.0) -> float:
    """White-noise density from a "random drift / random bias" figure of a paper.

    The papers give a white error as a rate (e.g. "random drift 0.01 deg/h").
    Assumption used throughout the project: that figure is the standard deviation of
    the rate averaged over ``tau_ref`` (default 1 s, i.e. a 0.5 Hz Nyquist bandwidth),
    which is also the Allan deviation at ``tau_ref`` and matches a Kalman-filter
    process-noise entry ``q = sigma^2`` per second. Then ``N = sigma sqrt(tau_ref)``.

    Parameters
    ----------
    sigma : float
        The paper's random figure in SI [rad/s or m/s2].
    tau_ref : float, optional
        Averaging time at which ``sigma`` is quoted [s].

    Returns
    -------
    float
        ARW [rad/sqrt(s)] or VRW [m/s/sqrt(s)].
    """
    return float(sigma) * math.sqrt(tau_ref)


def integrated_first_order(beta: float, h: float) -> tuple[float, float, np.ndarray]:
    """Exact discretisation of a first-order process and of its integral over a step.

    For ``x' = -beta x + w`` with unit white-noise intensity (``E[w w] = delta``) and
    ``I = int_0^h x dt``::

        x(h) = phi x(0) + e_1,    I = g x(0) + e_2,    (e_1, e_2) ~ N(0, Q)
        phi = exp(-beta h),       g = (1 - phi) / beta   (g = h for beta = 0)

    Parameters
    ----------
    beta : float
        Inverse correlation time [1/s], >= 0 (0: random walk).
    h : float
        Step [s], > 0.

    Returns
    -------
    phi : float
        Transition of the state.
    g : float
        Gain of the initial state into the integral [s].
    chol : ndarray, shape (2, 2)
        Lower Cholesky factor of ``Q`` (unit intensity; scale by ``sqrt(q)``).
    """
    x = beta * h
    if x == 0.0:
        phi, g = 1.0, h
        q11, q12, q22 = h, h * h / 2.0, h**3 / 3.0
    else:
        e1 = -math.expm1(-x)  # 1 - exp(-x)
        e2 = -math.expm1(-2.0 * x)  # 1 - exp(-2x)
        phi, g = 1.0 - e1, h * e1 / x
        q11 = h * e2 / (2.0 * x)
        q12 = h * h * e1 * e1 / (2.0 * x * x)
        if x < 0.5:
            # (x - 2 e1 + e2 / 2) / x^3 = sum_{n>=3} (-1)^n (2 - 2^(n-1)) x^(n-3) / n!
            s, term = 0.0, 1.0 / 6.0  # term = x^(n-3) / n!
            for n in range(3, 40):
                s += (-1) ** n * (2.0 - 2.0 ** (n - 1)) * term
                term *= x / (n + 1)
            q22 = h**3 * s
        else:
            q22 = h**3 * (x - 2.0 * e1 + e2 / 2.0) / x**3
    l11 = math.sqrt(q11)
    l21 = q12 / l11
    l22 = math.sqrt(max(q22 - l21 * l21, 0.0))
    return phi, g, np.array([[l11, 0.0], [l21, l22]])


def _vec(name: str, value: float, unit: str, description: str, n: int = 3) -> Any:
    return parameter(name, (value,) * n, unit, description)


def _triad_parameters(p: str, q: str, rate: str, inc: str, white: str, white_unit: str) -> tuple:
    """Parameter declarations of one sensor triad (prefix ``p``, quantity ``q``)."""
    return (
        _vec(f"{p}_bias", 0.0, rate, f"fixed {q} bias per axis"),
        parameter(f"{p}_bias_sigma", UNSET, rate, f"turn-on {q} bias sigma (<0: grade)"),
        parameter(white, UNSET, white_unit, f"{q} white-noise density (<0: grade)"),
        parameter(f"{p}_bi_sigma", UNSET, rate, f"{q} Gauss-Markov bias sigma (<0: grade)"),
        parameter(f"{p}_bi_tau", UNSET, "s", f"{q} Gauss-Markov correlation time (<0: grade)"),
        parameter(f"{p}_rrw", UNSET, f"{rate}/sqrt(s)", f"{q} bias random walk (<0: grade)"),
        _vec(f"{p}_sf", 0.0, "1", f"fixed {q} scale-factor error per axis (1e-6 = 1 ppm)"),
        parameter(f"{p}_sf_sigma", UNSET, "1", f"turn-on {q} scale-factor sigma (<0: grade)"),
        _vec(
            f"{p}_misalignment",
            0.0,
            "rad",
            f"fixed {q} misalignment matrix M, row-major (row = sensor axis)",
            9,
        ),
        parameter(
            f"{p}_misalignment_sigma", UNSET, "rad", f"turn-on {q} misalignment sigma (<0: grade)"
        ),
        parameter(f"{p}_lsb", UNSET, inc, f"{q} increment quantum, 0 = none (<0: grade)"),
    )


def resolve_parameters(values: Mapping[str, Any]) -> dict[str, float]:
    """A StrapdownImu's statistical parameters after its grade preset, checked.

    A graded parameter that is negative (unset) takes the preset's value; the
    rate-biased RLG divides the ARW by ``rlg_rw_reduction``.

    Parameters
    ----------
    values : mapping of str to float or int
        The block's ``grade``, ``rlg_mode``, ``rlg_rw_reduction`` and every graded
        parameter (the keys of :data:`PRESETS`), SI units.

    Returns
    -------
    dict
        ``{name: value}`` in SI units for every graded parameter, plus
        ``gyro_arw_effective`` (the ARW after the rate-biased RLG reduction).

    Raises
    ------
    ValueError
        An unknown grade or RLG mode, a reduction <= 0 in mode 2, or a Gauss-Markov
        sigma > 0 with a correlation time <= 0.
    """
    grade = int(values["grade"])
    if grade not in PRESETS:
        raise ValueError(f"StrapdownImu.grade must be 0, 1 or 2, got {grade}")
    out: dict[str, float] = {}
    for name, preset in PRESETS[grade].items():
        value = float(values[name])
        out[name] = value if value >= 0.0 else preset
    mode = int(values["rlg_mode"])
    if mode not in (0, 1, 2):
        raise ValueError(f"StrapdownImu.rlg_mode must be 0, 1 or 2, got {mode}")
    arw = out["gyro_arw"]
    if mode == 2:
        reduction = values["rlg_rw_reduction"]
        if not reduction > 0.0:
            raise ValueError(f"StrapdownImu.rlg_rw_reduction must be > 0, got {reduction}")
        arw /= float(reduction)
    out["gyro_arw_effective"] = arw
    for p in ("gyro", "accel"):
        if out[f"{p}_bi_sigma"] > 0.0 and not out[f"{p}_bi_tau"] > 0.0:
            raise ValueError(
                f"StrapdownImu.{p}_bi_tau must be > 0 when {p}_bi_sigma > 0, "
                f"got {out[f'{p}_bi_tau']}"
            )
    return out


def bias_step_coefficients(
    sigma: float, tau: float, rrw: float, h: float
) -> tuple[tuple[float, float, float, float, float], tuple[float, float, float]]:
    """Per-step coefficients of the Gauss-Markov and random-walk bias of one sensor triad.

    Over a step the Gauss-Markov bias ``x_gm`` (stationary std ``sigma``, correlation
    time ``tau``) and the random walk ``x_rw`` (density ``rrw``) advance as, with
    standard normals ``z1 .. z4`` per axis (:func:`integrated_first_order`)::

        x_gm(t + h) = phi x_gm(t) + l11 z1,   integral of x_gm = g x_gm(t) + l21 z1 + l22 z2
        x_rw(t + h) = x_rw(t) + r11 z3,       integral of x_rw = h x_rw(t) + r21 z3 + r22 z4

    Parameters
    ----------
    sigma : float
        Gauss-Markov stationary std (rad/s or m/s2); ``<= 0``: no Gauss-Markov term.
    tau : float
        Its correlation time [s], > 0 when ``sigma > 0``.
    rrw : float
        Random-walk density (rad/s/sqrt(s) or m/s2/sqrt(s)), >= 0.
    h : float
        Step [s], > 0.

    Returns
    -------
    gm : tuple of 5 float
        ``(phi, g, l11, l21, l22)``; ``(1, h, 0, 0, 0)`` without a Gauss-Markov term.
    rw : tuple of 3 float
        ``(r11, r21, r22)``.
    """
    if sigma > 0.0:
        beta = 1.0 / tau
        phi, g, chol = integrated_first_order(beta, h)
        sq = sigma * math.sqrt(2.0 * beta)
        gm = (phi, g, sq * chol[0, 0], sq * chol[1, 0], sq * chol[1, 1])
    else:
        gm = (1.0, h, 0.0, 0.0, 0.0)
    _, _, chol = integrated_first_order(0.0, h)
    return gm, (rrw * chol[0, 0], rrw * chol[1, 0], rrw * chol[1, 1])


class StrapdownImu(Block):
    """Strapdown IMU (gyro and accelerometer triads) with increment outputs.

    Attributes
    ----------
    noise_batches : int
        Batches of input-free noise terms computed since initialisation: one per
        :data:`AHEAD_STEPS` steps at a constant macro step, more if the step changes.
    compiled : bool
        True when this instance steps through the compiled kernel (set at initialisation,
        :func:`models.native.library`), False on the numpy path.
    """

    variables = (
        parameter(
            "grade",
            0,
            description="preset: 0 custom, a PERFECT IMU (every error zero) unless its error "
            "parameters are set (the default), 1 navigation, 2 tactical",
        ),
        parameter("seed", 0, description="random seed"),
        parameter("rlg_mode", 0, description="ring laser gyro: 0 none, 1 dithered, 2 rate-biased"),
        parameter("rlg_rw_reduction", 10.0, "1", "rate-biased RLG: random walk divided by this"),
        *_triad_parameters("gyro", "gyro", "rad/s", "rad", "gyro_arw", "rad/sqrt(s)"),
        *_triad_parameters("accel", "accelerometer", "m/s2", "m/s", "accel_vrw", "m/s/sqrt(s)"),
        input_(
            "dtheta_b",
            (0.0, 0.0, 0.0),
            "rad",
            "true angle increment over THIS communication step [t, t+h], body (not a rate: "
            "feed rate * h for the h of each doStep, e.g. fmpy's output_interval)",
        ),
        input_(
            "dv_b",
            (0.0, 0.0, 0.0),
            "m/s",
            "true velocity increment (specific force * h) over THIS communication step "
            "[t, t+h], body (not a specific force: feed f * h for the h of each doStep)",
        ),
        output("dtheta_meas_b", (0.0, 0.0, 0.0), "rad", "measured angle increment"),
        output("dv_meas_b", (0.0, 0.0, 0.0), "m/s", "measured velocity increment"),
        output("omega_meas_b", (0.0, 0.0, 0.0), "rad/s", "mean measured rate dtheta_meas_b / h"),
        output("f_meas_b", (0.0, 0.0, 0.0), "m/s2", "mean measured specific force dv_meas_b / h"),
        output("gyro_bias_b", (0.0, 0.0, 0.0), "rad/s", "truth: mean gyro bias over the step"),
        output("accel_bias_b", (0.0, 0.0, 0.0), "m/s2", "truth: mean accel bias over the step"),
    )
    default_step = 0.01
    default_stop = 1.0

    # ------------------------------------------------------------ parameters
    def resolved_parameters(self) -> dict[str, float]:
        """Statistical parameters after applying the grade preset (:func:`resolve_parameters`).

        Returns
        -------
        dict
            ``{name: value}`` in SI units for every graded parameter, plus
            ``gyro_arw_effective`` (the ARW after the rate-biased RLG reduction).
        """
        names = ("grade", "rlg_mode", "rlg_rw_reduction", *PRESETS[0])
        return resolve_parameters({name: getattr(self, name) for name in names})

    # ------------------------------------------------------------ life cycle
    def initialize(self) -> None:
        res = self.resolved_parameters()
        self._res = res
        self._rng = np.random.default_rng(int(self.seed))
        z = self._rng.standard_normal((2, 18))
        prefixes = ("gyro", "accel")
        self._const = np.empty((2, 3))
        self._err = np.empty((2, 3, 3))
        self._gm = np.empty((2, 3))
        self._rw = np.zeros((2, 3))
        self._white = np.array([res["gyro_arw_effective"], res["accel_vrw"]])
        self._lsb = np.array([res["gyro_lsb"], res["accel_lsb"]])
        self._resid = np.zeros((2, 3))
        off = ~np.eye(3, dtype=bool)
        for s, p in enumerate(prefixes):
            self._const[s] = (
                np.asarray(getattr(self, f"{p}_bias"), dtype=float)
                + res[f"{p}_bias_sigma"] * z[s, 0:3]
            )
            sf = (
                np.asarray(getattr(self, f"{p}_sf"), dtype=float) + res[f"{p}_sf_sigma"] * z[s, 3:6]
            )
            m_fix = np.asarray(getattr(self, f"{p}_misalignment"), dtype=float).reshape(3, 3)
            m_turn_on = np.where(
                off, res[f"{p}_misalignment_sigma"] * z[s, 6:15].reshape(3, 3), 0.0
            )
            self._err[s] = np.diag(sf) + m_fix + m_turn_on
            self._gm[s] = res[f"{p}_bi_sigma"] * z[s, 15:18]
        self._coeff_h: float | None = None
        self._z = np.empty((0, 2, 5, 3))  # normals drawn ahead, one (2, 5, 3) block per step
        self._pos = 0  # next unused block of self._z
        self._ahead: dict[str, Any] | None = None
        self.noise_batches = 0  # batches of noise terms computed (one per AHEAD_STEPS steps)
        bias = self._const + self._gm + self._rw
        # outputs written in place: they stay the block's buffer views (models.block)
        self.gyro_bias_b[:] = bias[0]
        self.accel_bias_b[:] = bias[1]
        for name in ("dtheta_meas_b", "dv_meas_b", "omega_meas_b", "f_meas_b"):
            getattr(self, name)[:] = 0.0
        self._lib = native.library()
        self.compiled = self._lib is not None
        if self._lib is not None:
            self._native_step = self._lib.strapdown_imu_step
            self._io = native.Buffers(self, ("dtheta_b", "dv_b"), NATIVE_OUTPUTS)
            self._ptr = tuple(native.pointer(a) for a in (self._err, self._lsb, self._resid))

    def _coefficients(self, h: float) -> None:
        """Cache the per-step noise coefficients (recomputed only when ``h`` changes)."""
        if same_step(h, self._coeff_h):
            return
        self.step_setups += 1
        res = self._res
        gm = np.zeros((2, 5))  # phi, g, l11, l21, l22 (scaled by sqrt(q))
        rw = np.zeros((2, 3))  # l11, l21, l22
        for s, p in enumerate(("gyro", "accel")):
            gm[s], rw[s] = bias_step_coefficients(
                res[f"{p}_bi_sigma"], res[f"{p}_bi_tau"], res[f"{p}_rrw"], h
            )
        self._gm_c = gm
        self._rw_c = rw
        self._white_h = self._white * math.sqrt(h)
        self._coeff_h = h

    def _noise_ahead(self, h: float) -> dict[str, Any]:
        """Bias integrals and white-noise increments of the steps drawn ahead, for step ``h``.

        They do not depend on the inputs, so the per-step recursions (Gauss-Markov,
        random walk) run over :data:`AHEAD_STEPS` steps at once with the same
        arithmetic as one step at a time (``lfilter`` is the recursion
        ``x_{k+1} = phi x_k + a_k``, ``cumsum`` the sequential sum). The random numbers
        are the same: drawing k blocks at once gives the k blocks drawn one by one.
        """
        self.noise_batches += 1
        if self._pos >= len(self._z):
            self._z = self._rng.standard_normal((AHEAD_STEPS, 2, 5, 3))
            self._pos = 0
        z = self._z[self._pos :]
        gm, rw = self._gm_c, self._rw_c
        gm_state = np.empty((len(z), 2, 3))  # state at each step's start
        gm_state[0] = self._gm
        drive = gm[:, 2:3] * z[:, :, 1]
        for s in (0, 1):
            phi = float(gm[s, 0])
            after, _ = lfilter(
                [1.0, 0.0], [1.0, -phi], drive[:, s], axis=0, zi=phi * self._gm[s : s + 1]
            )  # after[k] = phi gm_k + drive_k, the state after step k
            gm_state[1:, s] = after[:-1]
        rw_walk = np.cumsum(
            np.concatenate([self._rw[None], rw[:, 0:1] * z[:, :, 3]]), axis=0
        )  # rw_0, rw_0 + a_0, (rw_0 + a_0) + a_1, ...
        gm_int = gm[:, 1:2] * gm_state + gm[:, 3:4] * z[:, :, 1] + gm[:, 4:5] * z[:, :, 2]
        rw_int = h * rw_walk[:-1] + rw[:, 1:2] * z[:, :, 3] + rw[:, 2:3] * z[:, :, 4]
        ahead = {
            "h": h,
            "start": self._pos,
            "bias_int": np.ascontiguousarray(self._const * h + gm_int + rw_int),
            "white": np.ascontiguousarray(self._white_h[:, None] * z[:, :, 0]),
            "gm_next": gm[:, 0:1] * gm_state + gm[:, 2:3] * z[:, :, 1],
            "rw_next": rw_walk[1:],
        }
        ahead["ptrs"] = (native.pointer(ahead["bias_int"]), native.pointer(ahead["white"]))
        return ahead

    def step(self, t: float, h: float) -> None:
        self._coefficients(h)
        ahead = self._ahead
        if ahead is None or not same_step(h, ahead["h"]) or self._pos >= len(self._z):
            ahead = self._ahead = self._noise_ahead(h)
        k = self._pos - ahead["start"]
        self._pos += 1
        self._gm = ahead["gm_next"][k]
        self._rw = ahead["rw_next"][k]
        if self._lib is not None:
            err, lsb, resid = self._ptr
            bias, white = ahead["ptrs"]
            io = self._io
            d_true = io.input_pointer()
            out = io.output_pointer()
            self._native_step(d_true, err, bias + 48 * k, white + 48 * k, lsb, resid, out, h)
            io.publish()
            return
        bias_int = ahead["bias_int"][k]
        d_true = np.array([self.dtheta_b, self.dv_b], dtype=float)
        y = d_true + np.einsum("sij,sj->si", self._err, d_true) + bias_int + ahead["white"][k]
        for s in (0, 1):
            lsb = self._lsb[s]
            if lsb > 0.0:
                acc = self._resid[s] + y[s]
                y[s] = lsb * np.round(acc / lsb)
                self._resid[s] = acc - y[s]
        self.dtheta_meas_b = y[0].copy()
        self.dv_meas_b = y[1].copy()
        self.omega_meas_b = y[0] / h
        self.f_meas_b = y[1] / h
        self.gyro_bias_b = bias_int[0] / h
        self.accel_bias_b = bias_int[1] / h


#: The compiled step's outputs, in its layout (declaration order).
NATIVE_OUTPUTS = (
    "dtheta_meas_b",
    "dv_meas_b",
    "omega_meas_b",
    "f_meas_b",
    "gyro_bias_b",
    "accel_bias_b",
)

#: Steps of random numbers (and of the input-free bias and noise terms) drawn ahead.
AHEAD_STEPS = 64
