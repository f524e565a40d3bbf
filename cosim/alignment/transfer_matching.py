"""Attitude matching and lag estimation for transfer alignment (rapid transfer alignment).

:class:`MatchingFilter` is the estimator of
:class:`cosim.alignment.transfer.TransferAlignment` when ``matching`` is not velocity
alone or ``estimate_lag = 1``. It extends the 19-state (13 without flexure) model of
:mod:`cosim.alignment.transfer_model` with

* ``rho`` (3, with attitude matching): the noise-free attitude residual, a rotation
  vector in the navigation frame, ``exp([rho x]) = E(phi) exp([C_b_n theta x]) E(nu)^T``
  (below). It carries the mounting: the true slave-to-master rotation is
  ``C_s_b = exp([theta x]) exp([mu x]) C_nom`` (``C_nom = euler_to_dcm(mount_rpy)``, the
  nominal mounting; ``mu`` master axes; ``theta`` the deck flexure; as
  :class:`models.blocks.lever_arm.LeverArm`: ``C_s_d = exp([mu x]) C_nom``), seen in the
  navigation frame as ``E(nu) = C_b_n exp(-[mu x]) C_b_n^T`` (``nu ~ -C_b_n mu``), so
  ``E(nu) = exp(-[rho x]) E(phi) exp([C_b_n theta x])``;
* ``tau`` (1, with ``estimate_lag = 1``): the lag of the master's data behind the
  slave's [s] (positive: the master's values arrive ``tau`` late), a random constant.

``mu`` and ``tau`` are random constants (no process noise); ``E(nu)`` follows the master's
attitude exactly over a period, ``E(nu1) = dC E(nu0) dC^T`` with ``dC = C_b_n(t1)
C_b_n(t0)^T``, so that ``rho`` moves with the attitude error and the flexure:
``exp([rho1 x]) = E(phi1) F1 dC F0^T E(phi0)^T exp([rho0 x]) dC^T`` (``F =
exp([C_b_n theta x])``). Neither is fed back into the mechanisation; the feedback of
``phi^`` (``C^ <- E(phi^)^T C^``) turns the residual: ``exp([rho x]) <- E(phi^)^T
exp([rho x])``.

Measurements (every filter period, at a fresh master sample)
------------------------------------------------------------
Velocity (as the velocity path, :func:`cosim.alignment.transfer_model.measurement`)::

    z_v = v^ - v_master - C_b_n (omega_eb_b x r_0) = dV + tau a_n + noise,  R = r_vel^2 I

with ``a_n`` the vehicle's acceleration, taken from the slave mechanisation's velocity
over the last filter period (``v_master(t - tau) = v_master(t) - tau a_n``). The
vehicle's rate, for the lever arm ``omega_eb_b`` and the lag term ``C_b_n omega_nb_b``,
comes from the slave mechanisation's attitude over its last two steps
(:meth:`MatchingFilter.body_rate_n`): the master's attitude differenced at its own rate
(10 Hz, 0.3 arcmin of noise) gives the rate with 0.3 deg/s of noise, and a regressor that
noisy biases the lag estimate towards zero (20 ms came out as 6 ms).

Attitude (Kain and Cloutier 1989: the master's attitude through the mounting and
flexure model), the small-angle residual (a rotation vector, navigation frame)::

    Z   = C^_s_n C_nom^T C_b_n^T          (slave mechanisation vs master x nominal mounting)
        = E(phi) exp([C_b_n theta x]) E(nu)^T exp([tau C_b_n omega_nb_b x])
        = exp([rho x]) exp([tau C_b_n omega_nb_b x])
    z_a = rotvec(Z) + noise,                                     R = r_att^2 I

exact in the attitude error ``E`` (large heading allowed), ``theta`` and the mounting
(without a lag ``z_a = rho + noise``, linear); the lag to first order (a master
attitude ``tau`` old is ``C_b_n exp(-tau [omega_nb_b x])``, ``omega_nb_b`` the master's
rate from its attitude history,
:func:`~cosim.alignment.transfer_model.master_rate`). ``velocity+attitude`` stacks both
(6 values, ``R = diag(r_vel^2 I, r_att^2 I)``); the NIS then has 6 degrees of freedom,
else 3 (``dim_z``).

Why ``rho`` and not the mounting in the state: the attitude residual pins only the
combination ``E(phi) F E(nu)^T``; a heading error of the slave with the mounting's yaw
turned with it leaves it unchanged (the heading is seen through the velocity and the
vehicle's turns, not through ``Z``). With ``rho`` that unobserved direction is a
coordinate axis (``phi_D`` with ``rho`` fixed) and the measurement is linear. With the
mounting as a state (``mu``, or ``nu`` as navigation-frame Euler angles) it is curved: a
change of ``phi_D`` must turn ``nu``'s degree-sized level angles with it, the curvature
(heading error times mounting tilt: 3 deg x 1 deg = 3 arcmin) exceeds ``r_att``, and the
UKF took it for heading information. On the land-vehicle scenario that gave a heading
sigma 5 times too small in the first 5 s and 2 times until 15 s (heading 5 sigma off at
2-5 s with ``mu``; roll 7 sigma off at 100 s with a linear model). The process noise that
turns ``phi`` over a period turns ``rho`` with it (``Q`` maps the base noise of ``phi``,
and of ``theta``, into ``rho``); without that, roll ran 10 sigma off.

Start: the prior of the mounting is ``diag(p0_level^2, p0_level^2, p0_heading^2)`` in
master roll, pitch, yaw axes (``nu`` gets ``C_b_n`` of it), the master's attitude noise
``e0`` has ``r_att^2``; the mechanisation starts on the master's attitude times ``C_nom``,
so ``phi = e0 + nu - C_b_n theta`` and ``rho = e0``. No acquisition bank runs: the
mounting must be known to a few degrees (``p0_heading <=`` :data:`MAX_HEADING_PRIOR`).
Everything runs in numpy (the compiled kernels cover the velocity path only).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from cosim.alignment.nav import euler_rate_matrix_inv
from cosim.alignment.transfer_filter import StageSettings, TransferFilter
from cosim.alignment.transfer_model import (
    PeriodSums,
    StateLayout,
    TransferTuning,
    reset_jacobian,
)
from cosim.estimation import (
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
    angle_mean_fn,
    angle_residual_fn,
)
from cosim.models.constants import ARCMIN, DEG
from cosim.models.conventions import (
    cross,
    dcm_to_euler,
    dcm_to_rotvec,
    euler_to_dcm,
    rotvec_to_dcm,
    so3_right_jacobian,
)

FloatArray = NDArray[np.float64]

#: Matching modes of the ``matching`` parameter, by value.
MATCHING_MODES = {0: "velocity", 1: "attitude", 2: "velocity+attitude"}
#: Largest heading prior [rad] without the acquisition bank (attitude matching, lag).
MAX_HEADING_PRIOR = 10.0 * DEG


class MatchingFilter(TransferFilter):
    """Transfer alignment with attitude matching and/or lag estimation (numpy, one UKF).

    Parameters
    ----------
    layout : StateLayout
        The base layout (19 or 13 states); ``rho`` and ``tau`` are appended after it.
    tuning : TransferTuning
        Filter statistics (``p0_level``, ``p0_heading``: the mounting's prior).
    r0 : array_like, shape (3,)
        Nominal lever arm master -> slave, master axes [m].
    settings : StageSettings
        Sigma-point settings (the acquisition settings are not used).
    lat : float
        Latitude for the covariance shown before the start [rad].
    matching : int
        0 velocity, 1 attitude, 2 velocity+attitude (:data:`MATCHING_MODES`).
    estimate_lag : bool
        Whether the lag ``tau`` is a state.
    r_att : float
        Attitude-matching noise sigma per axis [rad].
    p0_lag : float
        Prior sigma of the lag [s].
    c_nom : ndarray, shape (3, 3)
        Nominal mounting ``C_nom`` (slave to master axes).
    accel_steps : int
        Steps over which the vehicle's acceleration (lag term) is differenced (>= 1).

    Attributes
    ----------
    n : int
        State dimension (base + 3 with attitude + 1 with the lag).
    rho : slice or None
        Where the attitude residual (rotation vector, navigation frame) sits in the state.
    tau : int or None
        Where the lag sits in the state.
    dim_z : int
        Measurement dimension (3 or 6): the NIS's degrees of freedom.
    """

    def __init__(
        self,
        layout: StateLayout,
        tuning: TransferTuning,
        r0: FloatArray,
        settings: StageSettings,
        lat: float,
        matching: int,
        estimate_lag: bool,
        r_att: float,
        p0_lag: float,
        c_nom: FloatArray,
        accel_steps: int = 1,
    ) -> None:
        super().__init__(layout, tuning, r0, settings, lat)
        self.matching = int(matching)
        self.use_velocity = self.matching in (0, 2)
        self.use_attitude = self.matching in (1, 2)
        self.estimate_lag = bool(estimate_lag)
        self.r_att, self.p0_lag = float(r_att), float(p0_lag)
        self.c_nom = np.asarray(c_nom, dtype=float).copy()
        n0 = layout.n
        self.rho = slice(n0, n0 + 3) if self.use_attitude else None
        n = n0 + (3 if self.use_attitude else 0)
        self.tau = n if self.estimate_lag else None
        self.n = n + (1 if self.estimate_lag else 0)
        self.dim_z = 3 * (int(self.use_velocity) + int(self.use_attitude))
        self._v_hist: deque[FloatArray] = deque(maxlen=max(int(accel_steps), 1) + 1)
        self._h = 0.0
        self._c_hist: deque[FloatArray] = deque(maxlen=3)
        self._c_prev = np.eye(3)
        self._dC = np.eye(3)
        self._c0 = np.eye(3)
        self.P_show = self.prior(lat, np.eye(3), None)
        self.x_show = np.zeros(self.n)

    # ------------------------------------------------------------------ models
    def prior(self, lat: float, c_b_n: FloatArray, m0: FloatArray | None) -> FloatArray:
        """Initial covariance of the extended state, shape (n, n).

        Parameters
        ----------
        lat : float
            Latitude [rad].
        c_b_n : ndarray, shape (3, 3)
            Master attitude at the start.
        m0 : ndarray, shape (3, 6), or None
            Flexure matrix at the start (None without flexure states).

        Returns
        -------
        ndarray, shape (n, n)
        """
        lay, tu = self.layout, self.tuning
        n0 = lay.n
        P = np.zeros((self.n, self.n))
        P[:n0, :n0] = tu.P0(lay, lat, m0)
        if self.tau is not None:
            P[self.tau, self.tau] = self.p0_lag**2
        if self.rho is None:
            return P
        # independent sources: rho = e0 (the master's attitude noise), nu ~ -C_b_n mu
        # (three extra rows, dropped at the end), theta; then phi := e0 + nu - C_b_n theta
        m = self.n
        Pa = np.zeros((m + 3, m + 3))
        Pa[:m, :m] = P
        Pa[lay.att, :] = 0.0
        Pa[:, lay.att] = 0.0
        Pa[self.rho, self.rho] = self.r_att**2 * np.eye(3)
        mount = np.diag([tu.p0_level**2, tu.p0_level**2, tu.p0_heading**2])
        Pa[m:, m:] = c_b_n @ mount @ c_b_n.T
        T = np.eye(m + 3)
        T[lay.att, self.rho] = np.eye(3)
        T[lay.att, m:] = np.eye(3)
        if lay.flexure:
            T[lay.att, 7:10] = -c_b_n
        P = (T @ Pa @ T.T)[:m, :m]
        return 0.5 * (P + P.T)

    def transition(self, x: FloatArray, dt: float, sums: PeriodSums) -> FloatArray:
        """``f(x)``: the extended error state over one filter period (the UKF's ``fx``).

        Parameters
        ----------
        x : ndarray, shape (..., n)
            Error states (sigma points along the first axes).
        dt : float
            Period [s].
        sums : PeriodSums
            The mechanisation's sums over the period (:meth:`close_period`).

        Returns
        -------
        ndarray, shape (..., n)
            The base states by the seed 001 model, ``rho`` as the module docstring says
            (the master's turn over the period is :meth:`turn_master`'s), ``tau`` kept.
        """
        n0 = self.layout.n
        out = np.array(x, dtype=float, copy=True)
        out[..., :n0] = self.propagate(np.ascontiguousarray(out[..., :n0]), sums)
        if self.rho is not None:  # module docstring: E(nu) turns with dC = C1 C0^T
            lay, dC = self.layout, self._dC
            e0 = euler_to_dcm(x[..., lay.att])
            turn = euler_to_dcm(out[..., lay.att])
            if lay.flexure:
                turn = turn @ rotvec_to_dcm(out[..., 7:10] @ self._c_prev.T)
                e0 = e0 @ rotvec_to_dcm(x[..., 7:10] @ self._c0.T)
            r1 = turn @ dC @ np.swapaxes(e0, -1, -2) @ rotvec_to_dcm(x[..., self.rho]) @ dC.T
            out[..., self.rho] = dcm_to_rotvec(r1)
        return out

    def measurement_model(
        self, x: FloatArray, c_b_n: FloatArray, w_nb_n: FloatArray, a_n: FloatArray
    ) -> FloatArray:
        """``h(x)``: the stacked measurement predicted from error states (the UKF's ``hx``).

        Parameters
        ----------
        x : ndarray, shape (..., n)
            Error states (sigma points along the first axes).
        c_b_n : ndarray, shape (3, 3)
            Master attitude as received.
        w_nb_n : ndarray, shape (3,)
            Vehicle rate w.r.t. the navigation frame, NED [rad/s] (the lag term).
        a_n : ndarray, shape (3,)
            Vehicle acceleration, NED [m/s2] (the lag term).

        Returns
        -------
        ndarray, shape (..., dim_z)
            Velocity [m/s] then attitude [rad] residuals (module docstring).
        """
        x = np.asarray(x, dtype=float)
        lay = self.layout
        parts = []
        tau = x[..., self.tau, None] if self.tau is not None else None
        if self.use_velocity:
            zv = x[..., lay.dv]
            parts.append(zv if tau is None else zv + tau * a_n)
        if self.use_attitude:
            if tau is None:
                parts.append(x[..., self.rho])
            else:
                Z = rotvec_to_dcm(x[..., self.rho]) @ rotvec_to_dcm(tau * w_nb_n)
                parts.append(dcm_to_rotvec(Z))
        return np.concatenate(parts, axis=-1)

    def turn_master(self, c_b_n: FloatArray) -> None:
        """Take the master's attitude at the end of the period about to be predicted.

        Parameters
        ----------
        c_b_n : ndarray, shape (3, 3)
            Master attitude as received; its turn since the last call, ``dC = C1 C0^T``,
            turns the mounting in :meth:`transition`.
        """
        self._dC = c_b_n @ self._c_prev.T
        self._c0 = self._c_prev
        self._c_prev = np.array(c_b_n, dtype=float)

    def measurement_noise(self) -> FloatArray:
        """``R`` of the stacked measurement, shape (dim_z, dim_z)."""
        sig = []
        if self.use_velocity:
            sig += [self.tuning.r_vel] * 3
        if self.use_attitude:
            sig += [self.r_att] * 3
        return np.diag(np.square(sig))

    # ------------------------------------------------------------------ stepping
    def start(
        self, c_b_n: FloatArray, w_eb_b: FloatArray, v_m: FloatArray, lat: float, height: float
    ) -> None:
        """Start the mechanisation on the master's attitude times the nominal mounting.

        Parameters
        ----------
        c_b_n : ndarray, shape (3, 3)
            Master attitude.
        w_eb_b : ndarray, shape (3,)
            Master rate w.r.t. the earth, master axes [rad/s].
        v_m : ndarray, shape (3,)
            Master velocity, NED [m/s].
        lat, height : float
            Master latitude [rad] and height [m].
        """
        lay = self.layout
        m0 = self._start_nav(c_b_n, w_eb_b, v_m, lat, height)
        ukf = UnscentedKalmanFilter(
            self.n,
            self.dim_z,
            self.transition,
            self.measurement_model,
            self._make_points_ext(),
            residual_x=angle_residual_fn([lay.heading]),
            x_mean_fn=angle_mean_fn([lay.heading]),
        )
        ukf.x = np.zeros(self.n)
        ukf.P = self.prior(lat, c_b_n, m0)
        self._ukf = ukf
        self._c_prev = c_b_n.copy()
        self._c_hist.clear()
        self._v_hist.clear()
        self._v_hist.append(np.array(self.nav.v_n, dtype=float))
        self.x_show, self.P_show = ukf.x, ukf.P
        self._bias0 = (np.array(self.nav.accel_bias), np.array(self.nav.gyro_bias))
        self.stage = 1.0

    def _make_points_ext(self) -> MerweScaledSigmaPoints:
        s = self.settings
        return MerweScaledSigmaPoints(self.n, s.ukf_alpha, s.ukf_beta, s.ukf_kappa)

    def step(self, dtheta: FloatArray, dv: FloatArray, h: float) -> None:
        """Mechanise one pair of slave increments (see :meth:`TransferFilter.step`).

        Parameters
        ----------
        dtheta, dv : ndarray, shape (3,)
            Slave angle [rad] and velocity [m/s] increments, slave axes.
        h : float
            Step [s].
        """
        super().step(dtheta, dv, h)
        self._h = h
        self._v_hist.append(np.array(self.nav.v_n, dtype=float))
        self._c_hist.append(np.array(self.nav.C_s_n, dtype=float))

    def body_rate_n(self) -> FloatArray:
        """The vehicle's rate w.r.t. the navigation frame, NED [rad/s], from the slave
        mechanisation's attitude over its last two steps (its gyros, bias-compensated):
        ``rotvec(C^(t) C^(t - 2h)^T) / 2h``, 0 before two steps. A rigid mount turns with
        the master, so this is the master's ``C_b_n omega_nb_b`` (to the flexure rate)."""
        if len(self._c_hist) < 3 or self._h <= 0.0:
            return np.zeros(3)
        return dcm_to_rotvec(self._c_hist[-1] @ self._c_hist[0].T) / (2.0 * self._h)

    def set_accel_steps(self, k: int) -> None:
        """Difference the vehicle's acceleration (lag term) over ``k`` steps.

        Parameters
        ----------
        k : int
            Steps (>= 1; the block passes the filter period's).
        """
        self._v_hist = deque(self._v_hist, maxlen=max(int(k), 1) + 1)

    def acceleration(self) -> FloatArray:
        """The vehicle's acceleration from the mechanisation's recent velocities, NED [m/s2]."""
        k = len(self._v_hist) - 1
        if k < 1 or self._h <= 0.0:
            return np.zeros(3)
        return (self._v_hist[-1] - self._v_hist[0]) / (k * self._h)

    def measured(self, c_b_n: FloatArray, w_eb_b: FloatArray, v_m: FloatArray) -> FloatArray:
        """The stacked measurement ``z`` (velocity [m/s] then attitude [rad], NED).

        Parameters
        ----------
        c_b_n : ndarray, shape (3, 3)
            Master attitude (as received).
        w_eb_b : ndarray, shape (3,)
            Master rate w.r.t. the earth, master axes [rad/s].
        v_m : ndarray, shape (3,)
            Master velocity, NED [m/s].

        Returns
        -------
        ndarray, shape (dim_z,)
        """
        sd = self.nav
        parts = []
        if self.use_velocity:
            parts.append(sd.v_n - v_m - c_b_n @ cross(w_eb_b, self._r0))
        if self.use_attitude:
            parts.append(dcm_to_rotvec(sd.C_s_n @ self.c_nom.T @ c_b_n.T))
        return np.concatenate(parts)

    def update(self, t: float, c_b_n: FloatArray, w_eb_b: FloatArray, v_m: FloatArray) -> None:
        """One filter period: predict, stacked update, feedback of the mechanisation errors.

        Parameters
        ----------
        t : float
            Time since the block's start [s] (not used: no acquisition stage).
        c_b_n : ndarray, shape (3, 3)
            Master attitude at the period's end.
        w_eb_b : ndarray, shape (3,)
            Master rate w.r.t. the earth, master axes [rad/s].
        v_m : ndarray, shape (3,)
            Master velocity, NED [m/s].
        """
        lay = self.layout
        w_nb_n = self.body_rate_n()
        if len(self._c_hist) == 3:  # the master's rate from the slave's gyros (docstring)
            w_eb_b = c_b_n.T @ w_nb_n
        sums, T, m1 = self.close_period(c_b_n, w_eb_b)
        n0 = lay.n
        Q = np.zeros((self.n, self.n))
        Q[:n0, :n0] = self.process_noise(T, m1)
        if self.rho is not None:  # the noise that turns phi (and theta) turns rho with it
            G = np.zeros((self.n, n0))
            G[:n0, :n0] = np.eye(n0)
            G[self.rho, lay.att] = np.eye(3)
            if lay.flexure:
                G[self.rho, 7:10] = c_b_n
            Q = G @ Q[:n0, :n0] @ G.T
        ukf = self._ukf
        self.turn_master(c_b_n)
        ukf.predict(T, Q=Q, sums=sums)
        z = self.measured(c_b_n, w_eb_b, v_m)
        ukf.update(
            z,
            R=self.measurement_noise(),
            c_b_n=c_b_n,
            w_nb_n=w_nb_n,
            a_n=self.acceleration(),
        )
        self.nis = float(ukf.y @ np.linalg.solve(ukf.S, ukf.y))
        x = ukf.x.copy()
        d_v = self._correct_nav(x, m1)
        for v in self._v_hist:
            v -= d_v
        turn = euler_to_dcm(x[lay.att]).T
        for c in self._c_hist:
            c[...] = turn @ c
        J = np.eye(self.n)
        J[:n0, :n0] = reset_jacobian(x[:n0], lay)
        x_new = np.zeros(self.n)
        if lay.flexure:
            x_new[lay.xi] = x[lay.xi]
            x_new[lay.dv] = m1 @ x[lay.xi]
        x_new[n0:] = x[n0:]
        if self.rho is not None:  # the feedback turns the residual: E(phi^)^T exp([rho x])
            x_new[self.rho], J[self.rho, self.rho] = turned_residual(turn, x[self.rho])
        P = J @ ukf.P @ J.T
        ukf.x = x_new
        ukf.P = 0.5 * (P + P.T)
        if self.stage == 1.0 and t >= self.settings.min_time - 1e-9:
            self._restart()
        self.x_show, self.P_show = ukf.x, ukf.P
        self._new_period()

    def _restart(self) -> None:
        """End the first stage (degree-sized level errors) and start the fine stage.

        With attitude matching nothing is forgotten: the stage only changes the ``phase``
        output. The first stage is consistent there (docs/transfer_alignment.md,
        "Consistency"), and forgetting its heading cost accuracy (land vehicle, 16 runs:
        heading RMS 4.0' against 3.1' at 30 s, 2.1' against 1.8' at 100 s).

        With velocity matching alone (``estimate_lag = 1``) the products of degree-sized
        level errors and the heading error in the model give the UKF heading and
        accelerometer-bias information that is not there. At ``acquire_min_time``
        (levels now arcminutes) the accelerometer-bias estimate is discarded (the
        mechanisation's bias back to its start, the states to their prior, uncorrelated)
        and ``relevel_sigma^2`` (level) and ``p0_heading^2`` (heading) are added to the
        attitude error: what the first stage learned about the absolute attitude is
        forgotten. The gyro-bias estimate is kept.
        """
        self.stage = 2.0
        if self.rho is not None:
            return
        lay, ukf, sd = self.layout, self._ukf, self.nav
        P = self._forget(ukf.P.copy(), self._m_prev, [lay.nabla])
        sd.accel_bias = np.array(self._bias0[0])
        add = [self.settings.relevel_sigma] * 2 + [self.tuning.p0_heading]
        for k, sigma in enumerate(add):
            P[lay.att.start + k, lay.att.start + k] += sigma**2
        ukf.P = 0.5 * (P + P.T)


def turned_residual(turn: FloatArray, rho: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The attitude residual after the feedback of ``phi^``, and its Jacobian.

    Parameters
    ----------
    turn : ndarray, shape (3, 3)
        The correction ``E(phi^)^T`` applied to the mechanisation (navigation frame).
    rho : ndarray, shape (3,)
        Residual before the feedback, rotation vector [rad].

    Returns
    -------
    rho_new : ndarray, shape (3,)
        ``rotvec(turn exp([rho x]))`` [rad].
    jac : ndarray, shape (3, 3)
        ``d rho_new / d rho = J_r(rho_new)^-1 J_r(rho)`` (``J_r`` the right Jacobian of
        SO(3): ``exp([(rho + d) x]) = exp([rho x]) exp([J_r(rho) d x])`` to first order).
    """
    rho = np.asarray(rho, dtype=float)
    new = dcm_to_rotvec(turn @ rotvec_to_dcm(rho))
    return new, np.linalg.solve(so3_right_jacobian(new), so3_right_jacobian(rho))


def estimates(
    c_est: FloatArray,
    c_b_n: FloatArray,
    x: FloatArray,
    P: FloatArray,
    layout: StateLayout,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Relative attitude and mounting with their 1-sigma, from the master's reported attitude.

    No truth is used. The slave's estimated relative attitude ``C^_s_b = C_b_n^T C^_s_n``
    (``rel_rpy``) errs by ``C_n_b phi`` (master axes, ``phi`` the mechanisation's attitude
    error, navigation axes); the rigid mounting ``C^_s_d = exp(-[theta^ x]) C^_s_b``
    (``mount``) by ``C_n_b phi - dtheta``. Each small-angle error ``e`` (master axes,
    ``C -> exp([e x]) C``) maps to roll, pitch, yaw through
    :func:`~cosim.alignment.nav.euler_rate_matrix_inv` at the estimate.

    Parameters
    ----------
    c_est : ndarray, shape (3, 3)
        Shown slave attitude ``C^_s_n`` (the error estimate applied).
    c_b_n : ndarray, shape (3, 3)
        Master attitude as reported.
    x, P : ndarray, shapes (n,), (n, n)
        Shown error state and covariance (the base layout's states first).
    layout : StateLayout
        Base layout.

    Returns
    -------
    rel_sigma : ndarray, shape (3,)
        1-sigma of ``rel_rpy`` (roll, pitch, yaw of ``C^_s_b``) [arcmin].
    mount : ndarray, shape (3,)
        Roll, pitch, yaw of ``C^_s_d`` [rad].
    mount_sigma : ndarray, shape (3,)
        Its 1-sigma [arcmin].
    """
    c_n_b = c_b_n.T
    rel = c_n_b @ c_est
    n = P.shape[0]
    G = np.zeros((3, n))
    G[:, layout.att] = c_n_b
    B = euler_rate_matrix_inv(dcm_to_euler(rel)) @ G
    rel_sigma = np.sqrt(np.maximum((B @ P @ B.T).diagonal(), 0.0)) / ARCMIN
    if layout.flexure:
        rel = rotvec_to_dcm(x[7:10]).T @ rel
        G[:, 7:10] = -np.eye(3)
    mount = dcm_to_euler(rel)
    B = euler_rate_matrix_inv(mount) @ G
    mount_sigma = np.sqrt(np.maximum((B @ P @ B.T).diagonal(), 0.0)) / ARCMIN
    return rel_sigma, mount, mount_sigma
