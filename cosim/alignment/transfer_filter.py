"""The two-stage estimator of transfer alignment (seed 001), without the block layer.

:class:`TransferFilter` owns the slave mechanisation (:class:`cosim.alignment.nav.Strapdown`,
:func:`~cosim.alignment.nav_compiled.make_strapdown`: stepped in C where it can be,
:data:`~cosim.alignment.nav.MOVING_BASE`), its period sums and the filters of the two
stages (module docstring of :mod:`cosim.alignment.transfer`): stage 1, a Gaussian-sum
bank of UKFs over the heading circle (open loop); stage 2, one UKF, closed loop. The
block :class:`cosim.alignment.transfer.TransferAlignment` feeds it the increments and
the master's state and publishes what it shows (:attr:`TransferFilter.x_show`,
:attr:`TransferFilter.P_show`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.alignment.nav import MOVING_BASE, Strapdown
from cosim.alignment.nav_compiled import CompiledStrapdown, make_strapdown
from cosim.alignment.transfer_model import (
    PeriodSums,
    StateLayout,
    TransferTuning,
    flexure_matrix,
    measurement,
    reset_jacobian,
)
from cosim.alignment.transfer_native import make_propagate
from cosim.alignment.transfer_ukf_native import make_fine_period
from cosim.estimation import (
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
    UnscentedParticleFilter,
    angle_mean_fn,
    angle_residual_fn,
    van_loan,
)
from cosim.models.blocks.lever_arm import r0_matrix
from cosim.models.constants import ARCMIN, DEG
from cosim.models.conventions import cross, euler_to_dcm, wrap_angle

FloatArray = NDArray[np.float64]

_I3 = np.eye(3)


@dataclass(frozen=True)
class StageSettings:
    """When the acquisition ends, how stage 2 restarts, and the UKFs' sigma points.

    Attributes
    ----------
    hypotheses : int
        Stage 1: headings in the UKF bank, spread evenly over the circle.
    sigma : float
        Stage 1 ends when the best hypothesis' heading sigma is below this [rad] ...
    weight : float
        ... and the hypotheses within ``sigma`` of its heading hold this weight [-] ...
    min_time : float
        ... and at least this long after the start [s].
    relevel_sigma : float
        Level sigma added at the stage-2 restart [rad].
    ukf_alpha, ukf_beta, ukf_kappa : float
        Merwe scaled sigma points.
    """

    hypotheses: int = 6
    sigma: float = 1.0 * DEG
    weight: float = 0.99
    min_time: float = 5.0
    relevel_sigma: float = 10.0 * ARCMIN
    ukf_alpha: float = 0.1
    ukf_beta: float = 2.0
    ukf_kappa: float = 0.0


class TransferFilter:
    """Slave mechanisation + acquisition bank (stage 1) + fine-alignment UKF (stage 2).

    Parameters
    ----------
    layout : StateLayout
        19- or 13-state layout.
    tuning : TransferTuning
        Filter statistics.
    r0 : array_like, shape (3,)
        Nominal lever arm master -> slave, master axes [m].
    settings : StageSettings
        Stage switches and sigma points.
    lat : float
        Latitude for the initial covariance shown before the start [rad].

    Attributes
    ----------
    nav : Strapdown or None
        The slave mechanisation (None before :meth:`start`).
    stage : float
        0 not started, 1 acquisition, 2 fine alignment.
    nis : float
        NIS of the last update (stage 1: the most probable hypothesis' own UKF).
    x_show, P_show : ndarray, shapes (n,), (n, n)
        What the block publishes: the fine UKF's state, or the best hypothesis'.
    """

    def __init__(
        self,
        layout: StateLayout,
        tuning: TransferTuning,
        r0: FloatArray,
        settings: StageSettings,
        lat: float,
    ) -> None:
        self.layout, self.tuning, self.settings = layout, tuning, settings
        self._r0 = np.asarray(r0, dtype=float).copy()
        self._R0 = r0_matrix(self._r0)
        self.nav: Strapdown | None = None
        #: Nominal mounting ``C_nom`` (slave to master axes): the mechanisation starts on
        #: ``C_b_n C_nom``; None starts it on the master's attitude (no product).
        self.c_nom: FloatArray | None = None
        self._sums = PeriodSums()
        self._ukf: UnscentedKalmanFilter | None = None
        self._bank: UnscentedParticleFilter | None = None
        self._best = 0
        self._m_prev: FloatArray | None = None
        self._compiled = False
        #: The error model over a period, ``propagate(x, sums)``: compiled where it can
        #: run, else numpy (:func:`cosim.alignment.transfer_native.make_propagate`).
        self.propagate = make_propagate(layout)
        self._fine: Any = None  # stage 2's compiled period (make_fine_period), or None
        self._flex_cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        self._q_cache: dict[float, FloatArray] = {}
        self.P_show = tuning.P0(layout, lat)
        self.x_show = np.zeros(layout.n)
        self.nis = 0.0
        self.stage = 0.0

    # ------------------------------------------------------------------ models
    def _flex(self, T: float) -> tuple[FloatArray, FloatArray]:
        key = round(T, 12)
        if key not in self._flex_cache:
            F, G, Qc = self.tuning.flexure_model()
            self._flex_cache[key] = van_loan(F, G, Qc, T)
        return self._flex_cache[key]

    def _make_points(self) -> MerweScaledSigmaPoints:
        s = self.settings
        return MerweScaledSigmaPoints(self.layout.n, s.ukf_alpha, s.ukf_beta, s.ukf_kappa)

    def _fx(self, x: FloatArray, dt: float, sums: PeriodSums) -> FloatArray:
        return self.propagate(x, sums)

    def _hx(self, x: FloatArray) -> FloatArray:
        return measurement(x, self.layout)

    def process_noise(self, T: float, m1: FloatArray | None) -> FloatArray:
        """The process noise over a period of ``T`` [s], shape (n, n).

        Parameters
        ----------
        T : float
            Period [s].
        m1 : ndarray, shape (3, 6), or None
            Flexure matrix at the period's end (None without the flexure states).

        Returns
        -------
        ndarray, shape (n, n)
            Symmetric.
        """
        lay, tu = self.layout, self.tuning
        base = self._q_cache.get(T)  # keyed on T exactly: Q's terms in T are T's own
        if base is None:  # the parts that depend on T only
            if len(self._q_cache) >= 16:  # a few roundings of one period; bound it anyway
                self._q_cache.clear()
            base = np.zeros((lay.n, lay.n))
            base[lay.dv, lay.dv] = tu.q_accel**2 * T * _I3
            base[lay.att, lay.att] = tu.q_gyro**2 * T * _I3
            if lay.flexure:
                base[lay.xi, lay.xi] = self._flex(T)[1]
            self._q_cache[T] = base
        Q = base.copy()
        if lay.flexure:
            mq = m1 @ self._flex(T)[1]
            Q[lay.dv, lay.dv] += mq @ m1.T
            Q[lay.dv, lay.xi] = mq
            Q[lay.xi, lay.dv] = mq.T
        return 0.5 * (Q + Q.T)

    # ------------------------------------------------------------------ stepping
    def start(
        self, c_b_n: FloatArray, w_eb_b: FloatArray, v_m: FloatArray, lat: float, height: float
    ) -> None:
        """Start the mechanisation on the master's attitude, and the acquisition bank.

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
        k = int(self.settings.hypotheses)
        bank = UnscentedParticleFilter(
            lay.n,
            3,
            self._fx,
            self._hx,
            self._make_points(),
            rng=np.random.default_rng(0),  # never used: deterministic proposal, no resampling
            n_particles=k,
            resample_threshold=0.0,
            proposal="mean",
            residual_x=angle_residual_fn([lay.heading]),
            x_mean_fn=angle_mean_fn([lay.heading]),
        )
        parts = np.zeros((k, lay.n))
        parts[:, lay.heading] = wrap_angle(2.0 * np.pi * np.arange(k) / k)
        bank.set_particles(parts, self.tuning.P0(lay, lat, m0))
        self._bank = bank
        self._best = 0
        self._show_bank()
        self.stage = 1.0

    def _start_nav(
        self, c_b_n: FloatArray, w_eb_b: FloatArray, v_m: FloatArray, lat: float, height: float
    ) -> FloatArray | None:
        """Start the mechanisation on ``C_b_n`` (times ``C_nom`` if set) and the period sums;
        return the flexure matrix at the start, shape (3, 6) (None without flexure)."""
        v_lr = c_b_n @ cross(w_eb_b, self._r0)
        c_start = c_b_n if self.c_nom is None else c_b_n @ self.c_nom
        self.nav = make_strapdown(c_start, lat, height, v_m + v_lr, options=MOVING_BASE)
        self._compiled = isinstance(self.nav, CompiledStrapdown)
        self._sums = PeriodSums(lat=lat, height=self.nav.height)
        m0 = flexure_matrix(c_b_n, w_eb_b, self._R0) if self.layout.flexure else None
        self._m_prev = m0
        return m0

    def step(self, dtheta: FloatArray, dv: FloatArray, h: float) -> None:
        """Mechanise one pair of slave increments and add them to the period sums.

        Parameters
        ----------
        dtheta, dv : ndarray, shape (3,)
            Slave angle [rad] and velocity [m/s] increments, slave axes.
        h : float
            Step [s].
        """
        if self._compiled:  # the step and the sums in one call (nav.sums_into reads them)
            self.nav.step_summed(dtheta, dv, h)
        else:
            self.nav.step(dtheta, dv, h)
            self._sums.add(self.nav, h)

    def _show_bank(self) -> None:
        bank = self._bank
        self._best = int(np.argmax(bank.weights))
        self.x_show = bank.particles[self._best]
        self.P_show = bank.particle_P[self._best]

    def update(self, t: float, c_b_n: FloatArray, w_eb_b: FloatArray, v_m: FloatArray) -> None:
        """One filter period: predict with the period sums, velocity update, feedback.

        Parameters
        ----------
        t : float
            Time since the block's start [s] (for the acquisition's ``min_time``).
        c_b_n : ndarray, shape (3, 3)
            Master attitude at the period's end.
        w_eb_b : ndarray, shape (3,)
            Master rate w.r.t. the earth, master axes [rad/s].
        v_m : ndarray, shape (3,)
            Master velocity, NED [m/s].
        """
        sd, lay, st = self.nav, self.layout, self.settings
        sums, T, m1 = self.close_period(c_b_n, w_eb_b)
        Q = self.process_noise(T, m1)
        R = self.tuning.r_vel**2 * _I3
        z = sd.v_n - v_m - c_b_n @ cross(w_eb_b, self._r0)
        if self.stage == 1.0:
            self._bank.step(z, T, Q=Q, R=R, fx_args={"sums": sums})
            self._show_bank()
            bank = self._bank
            self.nis = float(bank.particle_nis[self._best])
            sig_best = math.sqrt(bank.particle_P[self._best][lay.heading, lay.heading])
            # hypotheses that converged onto the best one's heading count with it
            gap = np.abs(wrap_angle(bank.particles[:, lay.heading] - self.x_show[lay.heading]))
            weight = float(np.sum(bank.weights[gap < st.sigma]))
            done = t >= st.min_time - 1e-9 and weight >= st.weight and sig_best < st.sigma
            if done:
                self._restart_fine(m1)
            self._new_period()
            return
        ukf = self._ukf
        # compiled UKF and mechanisation: the period and its feedback in one call
        nav = sd.state_pointer if self._compiled else None
        nis = None if self._fine is None else self._fine(ukf, T, Q, R, z, sums, nav, m1)
        if nis is None or nav is None:
            if nis is None:  # numpy (also where the compiled call found P not pos. definite)
                ukf.predict(T, Q=Q, sums=sums)
                ukf.update(z, R=R)
                nis = float(ukf.y @ np.linalg.solve(ukf.S, ukf.y))
            x = ukf.x.copy()
            P = self._feedback(x, ukf.P, m1)
            x_new = np.zeros(lay.n)
            if lay.flexure:
                x_new[lay.xi] = x[lay.xi]
                x_new[lay.dv] = m1 @ x[lay.xi]
            ukf.x = x_new
            ukf.P = P
        self.nis = nis
        self.x_show = ukf.x
        self.P_show = ukf.P
        self._new_period()

    def close_period(
        self, c_b_n: FloatArray, w_eb_b: FloatArray
    ) -> tuple[PeriodSums, float, FloatArray | None]:
        """Close the period's sums (with the flexure matrices at its ends).

        Parameters
        ----------
        c_b_n : ndarray, shape (3, 3)
            Master attitude at the period's end.
        w_eb_b : ndarray, shape (3,)
            Master rate w.r.t. the earth, master axes [rad/s] (the flexure matrix).

        Returns
        -------
        sums : PeriodSums
            The period's sums.
        T : float
            The period [s].
        m1 : ndarray, shape (3, 6), or None
            Flexure matrix at the period's end (None without flexure).
        """
        sums = self._sums
        if self._compiled:
            self.nav.sums_into(sums)
        T = sums.T
        m1 = None
        if self.layout.flexure:
            m1 = flexure_matrix(c_b_n, w_eb_b, self._R0)
            sums.m0, sums.m1 = self._m_prev, m1
            sums.phi_flex = self._flex(T)[0]
            self._m_prev = m1
        return sums, T, m1

    def _new_period(self) -> None:
        """Refresh the mechanisation's constants and restart the period sums."""
        sd = self.nav
        sd.refresh()
        self._sums = PeriodSums(lat=sd.lat, height=sd.height)
        if self._compiled:
            sd.clear_sums()

    def _feedback(self, x: FloatArray, P: FloatArray, m1: FloatArray | None) -> FloatArray:
        """Correct the mechanisation with the estimate ``x``; return the reset covariance.

        In stage 2 with the compiled UKF and mechanisation, ``transfer_ukf_fed_period``
        (:mod:`cosim.alignment.transfer_ukf_native`) does this and the reset of
        :meth:`update` in the period's own call; this stays the numpy path and the
        readable statement.
        """
        self._correct_nav(x, m1)
        J = reset_jacobian(x, self.layout)
        P = J @ P @ J.T
        return 0.5 * (P + P.T)

    def _correct_nav(self, x: FloatArray, m1: FloatArray | None) -> FloatArray:
        """Wrap the heading of ``x`` (in place) and correct the mechanisation with it.

        Parameters
        ----------
        x : ndarray, shape (n,)
            Error state (the base layout's states first).
        m1 : ndarray, shape (3, 6), or None
            Flexure matrix at the period's end (None without flexure).

        Returns
        -------
        ndarray, shape (3,)
            The velocity correction applied, NED [m/s].
        """
        lay, sd = self.layout, self.nav
        x[lay.heading] = wrap_angle(x[lay.heading])
        d_v = x[lay.dv] - (m1 @ x[lay.xi] if lay.flexure else 0.0)
        sd.correct(rotation=euler_to_dcm(x[lay.att]).T, d_v=d_v, d_lat=float(x[lay.dl]))
        sd.accel_bias = sd.accel_bias + x[lay.nabla]
        sd.gyro_bias = sd.gyro_bias + x[lay.eps]
        return d_v

    def _forget(self, P: FloatArray, m1: FloatArray | None, blocks: list[slice]) -> FloatArray:
        """Reset ``blocks`` of ``P`` to their prior, uncorrelated with the rest.

        The reset is made in the slave-velocity form ``dv = dV - M xi`` (the flexure
        states' prior is stated in it), then ``P`` is turned back.

        Parameters
        ----------
        P : ndarray, shape (m, m)
            Covariance, the base layout's states first (``m >= n``).
        m1 : ndarray, shape (3, 6), or None
            Flexure matrix at the period's end (None without flexure).
        blocks : list of slice
            The base layout's blocks to reset.

        Returns
        -------
        ndarray, shape (m, m)
        """
        lay = self.layout
        m = P.shape[0]
        S_inv = np.eye(m)
        if lay.flexure:
            S_inv[lay.dv, lay.xi] = -m1
        P = S_inv @ P @ S_inv.T
        P0 = self.tuning.P0(lay, float(self.nav.lat))
        for blk in blocks:
            P[blk, :] = 0.0
            P[:, blk] = 0.0
            P[blk, blk] = P0[blk, blk]
        if lay.flexure:
            S = np.eye(m)
            S[lay.dv, lay.xi] = m1
            P = S @ P @ S.T
        return P

    def _restart_fine(self, m1: FloatArray | None) -> None:
        """End the acquisition (stage 1) and start the fine alignment (stage 2).

        The most probable hypothesis of the bank is fed back into the mechanisation
        (attitude, velocity, latitude). In stage 1 the heading error is large and the
        Gaussian approximation is poor; what it leaves in the weakly observable
        directions (accelerometer bias against level tilt, flexure, gyro drift) is not
        trustworthy. So those estimates are discarded (back to their priors,
        uncorrelated, in the slave-velocity form ``dv = dV - M xi``) and the level
        variance is increased by ``relevel_sigma^2``: stage 2, quasi-linear, splits
        tilt and bias afresh. Stage 2 is a single UKF with the same model.
        """
        lay = self.layout
        n = lay.n
        x = self._bank.particles[self._best].copy()
        x[lay.nabla] = 0.0  # discarded: not fed back
        x[lay.eps] = 0.0
        P = self._feedback(x, self._bank.particle_P[self._best], m1)
        blocks = [lay.nabla, lay.eps] + ([lay.xi] if lay.flexure else [])
        P = self._forget(P, m1, blocks)
        # level rows and columns: the velocity form's transform does not touch them
        P[4, 4] += self.settings.relevel_sigma**2
        P[5, 5] += self.settings.relevel_sigma**2
        ukf = UnscentedKalmanFilter(
            n,
            3,
            self._fx,
            self._hx,
            self._make_points(),
            residual_x=angle_residual_fn([lay.heading]),
            x_mean_fn=angle_mean_fn([lay.heading]),
        )
        ukf.x = np.zeros(n)
        ukf.P = 0.5 * (P + P.T)
        self._ukf = ukf
        self._fine = make_fine_period(self.propagate, n, lay.flexure, lay.heading)
        self._bank = None
        self.x_show = ukf.x
        self.P_show = ukf.P
        self.stage = 2.0
