"""Linear covariance analysis of transfer alignment along a moored ship's motion (seed 001).

Independent of the simulation and of the filter's bookkeeping: the ship's motion in
closed form (:func:`ship_truth`), the slave's kinematics from it, the small-error model
of :func:`cosim.alignment.transfer_model.linear_error_model` discretised with Van Loan,
on the one covariance loop :func:`cosim.estimation.covariance.covariance_analysis`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.transfer_model import (
    StateLayout,
    TransferConfigError,
    TransferTuning,
    flexure_matrix,
    linear_error_model,
)
from cosim.estimation import van_loan
from cosim.estimation.covariance import (
    CovarianceBudget,
    CovarianceHistory,
    covariance_analysis,
)
from cosim.estimation.error_model import StepGrid, propagate
from cosim.models.blocks.lever_arm import r0_matrix
from cosim.models.constants import DEG, OMEGA_IE
from cosim.models.conventions import cross, euler_to_dcm
from cosim.models.earth import euler_motion_truth

FloatArray = NDArray[np.float64]

_I3 = np.eye(3)
_ZERO3 = (0.0, 0.0, 0.0)


def ship_truth(
    t: ArrayLike,
    *,
    lat: float = 30.0 * DEG,
    amp: ArrayLike = (12.5 * DEG, 10.0 * DEG, 5.0 * DEG),
    period: ArrayLike = (12.0, 6.0, 8.0),
    phase: ArrayLike = _ZERO3,
    rpy_mean: ArrayLike = _ZERO3,
) -> dict[str, FloatArray]:
    """Closed-form moored-ship motion (the equations of :mod:`models.blocks.ship_motion`).

    Parameters
    ----------
    t : array_like, shape (m,)
        Times [s].
    lat : float
        Latitude [rad].
    amp, period, phase, rpy_mean : array_like, shape (3,)
        Roll/pitch/yaw amplitude [rad], period [s], phase [rad], mean [rad].

    Returns
    -------
    dict
        ``rpy, rpy_dot`` (m, 3); ``C_b_n`` (m, 3, 3); ``omega_ib_b, omega_dot_b, f_b``
        (m, 3) in master axes; ``omega_nb_b`` (m, 3).
    """
    tt = np.atleast_1d(np.asarray(t, dtype=float))
    per = np.asarray(period, dtype=float)
    w = np.where(per > 0.0, 2.0 * np.pi / np.where(per > 0.0, per, 1.0), 0.0)
    a = np.where(per > 0.0, np.asarray(amp, dtype=float), 0.0)
    arg = tt[:, None] * w + np.asarray(phase, dtype=float)
    rpy = np.asarray(rpy_mean, dtype=float) + a * np.sin(arg)
    rpy_dot = a * w * np.cos(arg)
    rpy_ddot = -a * w**2 * np.sin(arg)
    truth = euler_motion_truth(rpy, rpy_dot, rpy_ddot, None, None, None, lat, 0.0, 0.0)
    w_ie_b = np.einsum(
        "mji,j->mi",
        truth.C_b_n,
        np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)]),
    )
    return {
        "rpy": rpy,
        "rpy_dot": rpy_dot,
        "C_b_n": truth.C_b_n,
        "omega_ib_b": truth.omega_ib_b,
        "omega_dot_b": truth.omega_dot_b,
        "omega_eb_b": truth.omega_ib_b - w_ie_b,
        "f_b": truth.f_b,
    }


def _repeat_steps(period: ArrayLike, dt: float) -> int:
    """Steps after which the ship's motion repeats (0 if not a whole number of steps).

    The least common multiple of the active periods, on a 1 microsecond grid.
    """
    us = [int(round(p * 1e6)) for p in np.asarray(period, dtype=float) if p > 0.0]
    if not us or any(
        abs(u - p * 1e6) > 1e-3
        for u, p in zip(us, [p for p in np.asarray(period, dtype=float) if p > 0.0], strict=True)
    ):
        return 0
    lcm = math.lcm(*us) * 1e-6
    n = lcm / dt
    return int(round(n)) if abs(n - round(n)) < 1e-9 * max(1.0, n) and n >= 1 else 0


@dataclasses.dataclass(frozen=True)
class _ShipModel:
    """The small-error model along the ship's motion, shared by the analysis and budget.

    The slave's kinematics at the step midpoints (specific force ``f_mid``, lever-arm
    velocity ``v_mid``, slave attitude ``cs_mid``, navigation frame, shape (n_steps, 3)
    or (n_steps, 3, 3)), the noise input ``G`` (n, 9), the continuous noise by source
    (9, 9 each, disjoint blocks), the velocity-matching noise ``R`` (3, 3) [m^2/s^2]
    and the ship's truth at the update times for the flexure measurement.
    """

    tuning: TransferTuning
    layout: StateLayout
    lat: float
    dt: float
    k_up: int
    n_steps: int
    t_up: FloatArray
    f_mid: FloatArray
    v_mid: FloatArray
    cs_mid: FloatArray
    up: dict[str, FloatArray]
    R0: FloatArray
    G: FloatArray
    Qc: dict[str, FloatArray]
    R: FloatArray
    n_rep: int

    def key(self, k: int) -> int:
        """Cache key of step ``k``: the motion repeats every ``n_rep`` steps."""
        return k % self.n_rep if self.n_rep else k

    def A(self, k: int) -> FloatArray:
        """Error dynamics of step ``k`` at its midpoint, shape (n, n)."""
        return linear_error_model(
            self.f_mid[k],
            self.cs_mid[k],
            self.v_mid[k],
            self.lat,
            0.0,
            self.layout,
            tuning=self.tuning,
        )

    def H(self, k: int) -> FloatArray | None:
        """Measurement matrix of the update after step ``k`` (3, n), or None."""
        if (k + 1) % self.k_up:
            return None
        layout = self.layout
        H = np.zeros((3, layout.n))
        H[:, layout.dv] = _I3
        if layout.flexure:
            j = (k + 1) // self.k_up - 1
            H[:, layout.xi] = flexure_matrix(self.up["C_b_n"][j], self.up["omega_eb_b"][j], self.R0)
        return H


def _ship_model(
    t_end: float,
    r0: ArrayLike,
    mount_rpy: ArrayLike,
    lat: float,
    amp: ArrayLike,
    period: ArrayLike,
    tuning: TransferTuning | None,
    flexure: bool,
    update_period: float,
    dt: float,
) -> _ShipModel:
    """Build :class:`_ShipModel` (arguments of :func:`transfer_covariance`)."""
    tuning = tuning or TransferTuning()
    layout = StateLayout(flexure)
    n = layout.n
    k_up = int(round(update_period / dt))
    if k_up < 1 or abs(k_up * dt - update_period) > 1e-9:
        raise TransferConfigError(f"dt ({dt}) must divide update_period ({update_period})")
    n_steps = int(round(t_end / dt))
    r0 = np.asarray(r0, dtype=float)
    c_s_b = euler_to_dcm(np.asarray(mount_rpy, dtype=float))
    t_mid = (np.arange(n_steps) + 0.5) * dt
    t_up = np.arange(1, n_steps // k_up + 1) * update_period
    mid = ship_truth(t_mid, lat=lat, amp=amp, period=period)
    up = ship_truth(t_up, lat=lat, amp=amp, period=period)
    w, wd = mid["omega_ib_b"], mid["omega_dot_b"]
    wr = np.sum(w * r0, axis=-1, keepdims=True)
    f_p = mid["f_b"] + cross(wd, r0) + w * wr - r0 * np.sum(w * w, axis=-1, keepdims=True)
    G = np.zeros((n, 9))
    G[layout.dv, 0:3] = _I3
    G[layout.att, 3:6] = _I3
    Qc = {
        "accelerometer white noise": np.zeros((9, 9)),
        "gyro white noise": np.zeros((9, 9)),
    }
    Qc["accelerometer white noise"][0:3, 0:3] = tuning.q_accel**2 * _I3
    Qc["gyro white noise"][3:6, 3:6] = tuning.q_gyro**2 * _I3
    if flexure:
        _, Gf, Qf = tuning.flexure_model()
        G[layout.xi, 6:9] = Gf
        Qc["flexure noise"] = np.zeros((9, 9))
        Qc["flexure noise"][6:9, 6:9] = Qf
    return _ShipModel(
        tuning=tuning,
        layout=layout,
        lat=lat,
        dt=dt,
        k_up=k_up,
        n_steps=n_steps,
        t_up=t_up,
        f_mid=np.einsum("mij,mj->mi", mid["C_b_n"], f_p),
        v_mid=np.einsum("mij,mj->mi", mid["C_b_n"], cross(mid["omega_eb_b"], r0)),
        cs_mid=mid["C_b_n"] @ c_s_b,
        up=up,
        R0=r0_matrix(r0),
        G=G,
        Qc=Qc,
        R=tuning.r_vel**2 * _I3,
        # The motion repeats with the least common multiple of the periods (24 s for
        # seed 001): the discretised model of step k equals that of step k - n_rep.
        n_rep=_repeat_steps(period, dt),
    )


def transfer_covariance(
    t_end: float = 120.0,
    *,
    r0: ArrayLike = (10.0, 10.0, 5.0),
    mount_rpy: ArrayLike = (1.0 * DEG, 1.0 * DEG, 30.0 * DEG),
    lat: float = 30.0 * DEG,
    amp: ArrayLike = (12.5 * DEG, 10.0 * DEG, 5.0 * DEG),
    period: ArrayLike = (12.0, 6.0, 8.0),
    tuning: TransferTuning | None = None,
    flexure: bool = False,
    update_period: float = 0.5,
    dt: float = 0.1,
) -> CovarianceHistory:
    """Linear covariance analysis of velocity-matching transfer alignment along the ship's motion.

    The ship's motion is evaluated in closed form (:func:`ship_truth`), the slave's
    kinematics from it (rigid lever arm ``r_0``, mounting ``mount_rpy``), and the
    small-error model is used in its **slave-velocity form** ``y = [dL, dv, phi, (xi),
    nabla, eps]`` (the filter uses ``dV = dv + M xi``), where the flexure enters only
    the measurement::

        z = dv + M(t) xi + n,   E[n n^T] = r_vel^2 I    every update_period

    The model (:func:`~cosim.alignment.transfer_model.linear_error_model` without the
    transformation) is held constant over ``dt`` at the interval's midpoint and
    discretised exactly with :func:`cosim.estimation.van_loan` (noise: accelerometer
    ``q_accel`` on ``dv``, gyro ``q_gyro`` on ``phi``, flexure ``eta``). Updates are
    the estimators' Joseph update.

    Parameters
    ----------
    t_end : float
        Duration [s].
    r0 : array_like, shape (3,)
        Lever arm, master axes [m].
    mount_rpy : array_like, shape (3,)
        Slave mounting [rad].
    lat : float
        Latitude [rad].
    amp, period : array_like, shape (3,)
        Ship roll/pitch/yaw amplitude [rad] and period [s].
    tuning : TransferTuning, optional
        P0, noises (default seed 001's).
    flexure : bool
        Include the flexure states (and the flexure part of the measurement).
    update_period : float
        Velocity-matching period [s].
    dt : float
        Propagation step [s]; must divide ``update_period``.

    Returns
    -------
    CovarianceHistory
        Posterior covariance after each update (times ``j update_period``, SI), state
        ``[dL, dv, phi, (xi), nabla, eps]`` (names of :class:`StateLayout`).

    Raises
    ------
    TransferConfigError
        When ``dt`` does not divide ``update_period``.
    """
    m = _ship_model(t_end, r0, mount_rpy, lat, amp, period, tuning, flexure, update_period, dt)
    # the sources' blocks are disjoint: their sum is the total Qc exactly
    Qc = sum(m.Qc.values(), np.zeros((9, 9)))
    cache: dict[int, tuple[FloatArray, FloatArray]] = {}

    def transition(k: int) -> tuple[FloatArray, FloatArray]:
        key = m.key(k)
        if key not in cache:
            cache[key] = van_loan(m.A(k), m.G, Qc, dt)
        return cache[key]

    def measurement(k: int) -> tuple[FloatArray, FloatArray] | None:
        H = m.H(k)
        return None if H is None else (H, m.R)

    # slave-velocity form: dv_0 independent of xi_0
    hist = covariance_analysis(
        m.tuning.P0(m.layout, lat),
        m.n_steps,
        dt,
        transition,
        measurement,
        record_every=m.k_up,
        include_start=False,
        names=m.layout.names,
    )
    return dataclasses.replace(hist, time=m.t_up)


def transfer_budget(
    t_end: float = 120.0,
    *,
    r0: ArrayLike = (10.0, 10.0, 5.0),
    mount_rpy: ArrayLike = (1.0 * DEG, 1.0 * DEG, 30.0 * DEG),
    lat: float = 30.0 * DEG,
    amp: ArrayLike = (12.5 * DEG, 10.0 * DEG, 5.0 * DEG),
    period: ArrayLike = (12.0, 6.0, 8.0),
    tuning: TransferTuning | None = None,
    flexure: bool = False,
    update_period: float = 0.5,
    dt: float = 0.1,
) -> CovarianceBudget:
    """:func:`transfer_covariance` split by error source (the same total, to rounding).

    Sources: the initial position (``dL``), velocity, level and heading errors, the
    initial flexure (with ``flexure``), the accelerometer bias and the gyro drift per
    slave axis (x, y, z), the accelerometer and gyro white noise, the flexure noise
    ``eta`` and the velocity-matching noise. The same model, steps and updates as
    :func:`transfer_covariance`.

    Parameters
    ----------
    t_end : float
        Duration [s].
    r0 : array_like, shape (3,)
        Lever arm, master axes [m].
    mount_rpy : array_like, shape (3,)
        Slave mounting [rad].
    lat : float
        Latitude [rad].
    amp, period : array_like, shape (3,)
        Ship roll/pitch/yaw amplitude [rad] and period [s].
    tuning : TransferTuning, optional
        P0, noises (default seed 001's).
    flexure : bool
        Include the flexure states (and the flexure part of the measurement).
    update_period : float
        Velocity-matching period [s].
    dt : float
        Propagation step [s]; must divide ``update_period``.

    Returns
    -------
    CovarianceBudget
        After each update (times ``j update_period``), states of :class:`StateLayout`.

    Raises
    ------
    TransferConfigError
        When ``dt`` does not divide ``update_period``.
    """
    m = _ship_model(t_end, r0, mount_rpy, lat, amp, period, tuning, flexure, update_period, dt)
    return propagate(TransferLines(m))


@dataclasses.dataclass(frozen=True)
class TransferLines:
    """The small-error model along the ship split into budget lines (:func:`transfer_budget`).

    The numerical half of :class:`cosim.estimation.error_model.LinearErrorModel`
    (``grid``, ``names``, ``initial_covariance``, ``dynamics``, ``step_key``,
    ``measurement``); :mod:`cosim.alignment.error_models` adds the scenario's half.

    Attributes
    ----------
    model : object
        Steps, kinematics and noises (this module's ship model).
    """

    model: _ShipModel

    @property
    def names(self) -> tuple[str, ...]:
        """State names of :class:`StateLayout`."""
        return self.model.layout.names

    @property
    def grid(self) -> StepGrid:
        """Steps of ``dt``; a row after each update, at ``j update_period``."""
        m = self.model
        return StepGrid(m.dt, m.n_steps, m.k_up, False, m.t_up)

    def initial_covariance(self) -> dict[str, FloatArray]:
        """P0 by line: initial position, velocity, level, heading (flexure), and the
        accelerometer bias and gyro drift per slave axis, each (n, n) [SI^2]."""
        m = self.model
        layout, n = m.layout, m.layout.n
        P0 = m.tuning.P0(layout, m.lat)
        P0_parts: dict[str, FloatArray] = {}

        def piece(idx: list[int]) -> FloatArray:
            part = np.zeros_like(P0)
            part[np.ix_(idx, idx)] = P0[np.ix_(idx, idx)]
            return part

        att = list(range(n))[layout.att]
        P0_parts["initial position error"] = piece([layout.dl])
        P0_parts["initial velocity error"] = piece(list(range(n))[layout.dv])
        P0_parts["initial level misalignment"] = piece(att[0:2])
        P0_parts["initial heading misalignment"] = piece(att[2:3])
        if layout.flexure:
            P0_parts["initial flexure"] = piece(list(range(n))[layout.xi])
        for name, sl in (("accelerometer bias", layout.nabla), ("gyro drift", layout.eps)):
            for axis, i in zip("xyz", list(range(n))[sl], strict=True):
                P0_parts[f"{name} {axis}"] = piece([i])
        return P0_parts

    def dynamics(self, k: int) -> tuple[FloatArray, FloatArray, dict[str, FloatArray]]:
        """``F`` at step ``k``'s midpoint (n, n), ``G`` (n, 9), ``Qc`` by line (9, 9).

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        m = self.model
        return m.A(k), m.G, m.Qc

    def step_key(self, k: int) -> int:
        """Step ``k`` within the ship's period (the motion's repeat).

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        return self.model.key(k)

    def measurement(self, k: int) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """Velocity matching after every ``update_period``: ``H`` (3, n), its noise.

        Parameters
        ----------
        k : int
            Step index (step ``k`` ends at ``(k + 1) dt``).
        """
        H = self.model.H(k)
        return None if H is None else (H, {"measurement noise (velocity matching)": self.model.R})


def transfer_lines(
    t_end: float = 120.0,
    *,
    r0: ArrayLike = (10.0, 10.0, 5.0),
    mount_rpy: ArrayLike = (1.0 * DEG, 1.0 * DEG, 30.0 * DEG),
    lat: float = 30.0 * DEG,
    amp: ArrayLike = (12.5 * DEG, 10.0 * DEG, 5.0 * DEG),
    period: ArrayLike = (12.0, 6.0, 8.0),
    tuning: TransferTuning | None = None,
    flexure: bool = False,
    update_period: float = 0.5,
    dt: float = 0.1,
) -> TransferLines:
    """The budget lines of :func:`transfer_budget` (same arguments), not yet propagated.

    Parameters
    ----------
    t_end : float
        Duration [s].
    r0 : array_like, shape (3,)
        Lever arm, master axes [m].
    mount_rpy : array_like, shape (3,)
        Slave mounting [rad].
    lat : float
        Latitude [rad].
    amp, period : array_like, shape (3,)
        Ship roll/pitch/yaw amplitude [rad] and period [s].
    tuning : TransferTuning, optional
        P0, noises (default seed 001's).
    flexure : bool
        Include the flexure states.
    update_period : float
        Velocity-matching period [s].
    dt : float
        Propagation step [s]; must divide ``update_period``.

    Returns
    -------
    TransferLines
    """
    return TransferLines(
        _ship_model(t_end, r0, mount_rpy, lat, amp, period, tuning, flexure, update_period, dt)
    )
