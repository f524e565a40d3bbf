"""Stationary SINS self north-finding (seed 003): coarse alignment, then a 10-state KF.

The block :class:`SinsStaticAlignment` reads the measured increments of a strapdown
IMU (optionally on a turntable), aligns analytically (:mod:`cosim.alignment.coarse`),
runs the strapdown integrator :class:`cosim.alignment.nav.Strapdown` with the
:data:`~cosim.alignment.nav.STATIC_BASE` mechanisation and the 10-state error-state
Kalman filter of :mod:`cosim.alignment.static_model` with zero-velocity measurements,
and feeds every estimate back (closed loop). With the IMU on a turntable turning with
reversals it removes the table rotation with the encoder angle, and the modulation of
the sensor errors makes the east gyro drift observable. The simulated base is
perfectly still; ``zupt_noise`` adds white noise of that sigma to each measurement
(the disturbance of a quasi-static base that seed 003's R stands for; the block's
``seed`` draws it).

Swaying bases (``init_mode = 2``, issue 26; docs/self_alignment.md): the coarse stage
is the inertial-frame alignment of :mod:`cosim.alignment.coarse_inertial`; the fine
filter starts from it with the P0 of :func:`cosim.alignment.self_align.coarse_p0`
(the coarse error theory, cross-covariances with the biases included), integrates with
:data:`SWAYING_BASE` (two-sample coning and sculling), couples the misalignment through
the measured specific force ``f_n`` (not ``[0, 0, -g]``) and, with ``lever_s``, updates
the velocity of the point at rest: ``z = mean(v^_NE) - ((C_k - C_k-1) l / h)_NE``,
``H_psi = -[u x]_NE``. A coarse window whose theoretical heading sigma exceeds
``coarse_sigma_max`` is refused at start-up. During the window the outputs carry the
running coarse estimate and the theory's sigma (from 1 s on). Modes 0 and 1 are as
before.

Mechanisation (sensor frame, every step)
----------------------------------------
The increments are corrected with the bias estimates (the integrator's
``gyro_bias = C_s_t^T eps^``, ``accel_bias = C_s_t^T [nabla^_x, nabla^_y, 0]``). Then::

    phi    = theta a + k(theta) (dth - theta a),   theta = a . dth,
             k = (theta / 2)^2 / sin^2(theta / 2)                  (table-axis coning)
    C_s_n <- exp(-[zeta x]) C_s_n exp([phi x]),    zeta = w_ie h
    v_n   <- v_n + (I - [zeta x] / 2) C_s_n J(-phi)^-1 dv + (-2 w_ie x v_n) h,  v_D = 0

``a = C_s_t^T e_z`` is the table axis in sensor axes. For a table turning at a
constant rate on a stationary base, the part of the increment perpendicular to the
axis is the earth rate averaged over a turning frame; ``k`` turns it into the exact
rotation vector (to first order in the earth rate). The usual two-sample coning
correction agrees with ``k = 1 + theta^2 / 12 + ...`` to second order but leaves a
residual ``theta^3 / 24`` of the earth rate turned by 90 deg: at 10 deg per step an
east drift of 0.002 deg/h (flipping sign with each reversal). ``J(x) = I +
(1 - cos a) / a^2 [x x] + (a - sin a) / a^3 [x x]^2`` is the mean of ``exp([x s x])``
over ``s in [0, 1]``; ``J(-phi)^-1 dv`` is the exact rotation compensation when the
specific force is constant in inertial space over the step (a stationary base, any
tilt). Both reduce to the classical first-order terms for small steps. During the
table's acceleration ramps (200 deg/s2 at the reversals) the constant-rate
assumption leaves velocity glitches of about 0.1 mm/s, far below the measurement
noise. A lever arm between the axis and the sensors (centrifugal acceleration) is
not compensated: the sensors sit on the axis.

Closed loop: after each measurement update ``C^_s_n <- exp([psi^ x]) C^_s_n``,
``v^ <- v^ - dv^``, ``nabla^ += x_nabla``, ``eps^ += x_eps`` and ``x <- 0``; ``P``
is kept.

Outputs (estimate minus truth, the truth from the motion block's ``rpy``):
``phi_err`` is the rotation from the true to the estimated base attitude,
``C^_b_n = exp([phi_err x]) C_b_n`` (``= -psi``; for a level base ``phi_err_D``
is the heading error), ``rpy_err`` the Euler-angle errors, their 1-sigma from
``P`` and the NEES ``phi_err^T P_psi^-1 phi_err`` of the three angles.
``phi_hat = log(C^_b_n(t_f) C^_b_n(t)^T)`` estimates ``phi_err`` at the start of the
fine alignment ``t_f`` (what the paper adds to the coarse heading); on a stationary
base its own error is about ``-phi_err(t)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from cosim.alignment.coarse import coarse_alignment
from cosim.alignment.coarse_inertial import InertialCoarse
from cosim.alignment.nav import (
    STATIC_BASE,
    AlignmentConfigError,
    AlignmentError,
    Mechanisation,
    Strapdown,
    dcm_to_rotvec_3,
    euler_rate_matrix_inv,
)
from cosim.alignment.self_align import coarse_p0, coarse_theory_cached, required_coarse_time
from cosim.alignment.static_model import (
    N_STATES,
    SEED003,
    FilterTuning,
    discretize_taylor,
    error_model,
    measurement_matrix,
    noise_input,
    quad_form_inv3,
    table_dcm,
)
from cosim.estimation import KalmanFilter
from cosim.estimation.error_model import LinearErrorModel, RunFacts
from cosim.models.block import Block, input_, output, parameter
from cosim.models.constants import ARCMIN, DEG
from cosim.models.conventions import (
    dcm_to_euler_3,
    euler_to_dcm_3,
    rotvec_to_dcm_3,
    skew,
    wrap_angle,
)

FloatArray = NDArray[np.float64]

_I3 = np.eye(3)
#: init_mode 2's integrator: seed 003's level channel with two-sample coning and sculling
#: (a swaying base turns about any axis, not about a table axis).
SWAYING_BASE = Mechanisation(
    coning="two-sample",
    transport_rate=False,
    vertical=False,
    midpoint_velocity=False,
    orthonormalise_every=64,
)


# ------------------------------------------------------------------ the block
_ZERO3 = (0.0, 0.0, 0.0)


class SinsStaticAlignment(Block):
    """Stationary SINS self north-finding: coarse alignment, 10-state KF, optional turntable."""

    variables = (
        parameter("lat", 45.0 * DEG, "rad", "latitude"),
        parameter("h", 0.0, "m", "height"),
        parameter(
            "init_mode",
            0,
            description=(
                "0: analytic coarse alignment first (still base); 1: truth + init_offset "
                "(simulation studies); 2: inertial-frame coarse alignment first (sway-robust, "
                "P0 from its error theory; docs/self_alignment.md)"
            ),
        ),
        parameter("coarse_time", 5.0, "s", "coarse alignment window (init_mode 0 and 2)"),
        parameter(
            "coarse_sigma_max",
            DEG,
            "rad",
            "init_mode 2: largest heading 1-sigma of the coarse result (error theory) the "
            "fine filter accepts; a longer one stops the run naming the coarse_time needed",
        ),
        parameter(
            "lever_s",
            _ZERO3,
            "m",
            "init_mode 2: IMU position from the sway centre (the point at rest), sensor axes",
        ),
        parameter(
            "init_offset",
            (DEG, DEG, DEG),
            "rad",
            "init_mode 1: initial attitude error, estimate minus truth (NED rotation vector)",
        ),
        parameter(
            "init_offset_random",
            False,
            description="init_mode 1: draw the offset per axis from N(0, init_offset^2)",
        ),
        parameter("kf_period", 0.1, "s", "zero-velocity update period (a multiple of the step)"),
        parameter("p0_vel", SEED003.p0_vel, "m/s", "P0: velocity error sigma"),
        parameter("p0_att", SEED003.p0_att, "rad", "P0: misalignment sigmas N, E, D"),
        parameter("p0_accel_bias", SEED003.p0_accel_bias, "m/s2", "P0: accelerometer bias sigma"),
        parameter("p0_gyro_drift", SEED003.p0_gyro_drift, "rad/s", "P0: gyro drift sigma"),
        parameter("q_accel", SEED003.q_accel, "m/s/sqrt(s)", "Q: accelerometer noise density"),
        parameter("q_gyro", SEED003.q_gyro, "rad/sqrt(s)", "Q: gyro noise density"),
        parameter("r_vel", SEED003.r_vel, "m/s", "R: zero-velocity measurement sigma"),
        parameter(
            "zupt_noise",
            0.0,
            "m/s",
            "sigma of white noise added to each zero-velocity measurement (base disturbance)",
        ),
        parameter("mount_rpy", _ZERO3, "rad", "sensor mounting on the table, C_s_t (as Turntable)"),
        parameter("seed", 0, description="random seed (offset draw, measurement noise)"),
        input_("dtheta_s", _ZERO3, "rad", "measured angle increment over the step, sensor axes"),
        input_("dv_s", _ZERO3, "m/s", "measured velocity increment over the step, sensor axes"),
        input_("rpy_true", _ZERO3, "rad", "truth: base attitude (for the error outputs)"),
        input_("angle", 0.0, "rad", "turntable encoder angle (0 without a table)"),
        output("phase", 0.0, "1", "0 coarse alignment, 1 fine alignment"),
        output("rpy", _ZERO3, "rad", "estimated base attitude: roll, pitch, yaw"),
        output("v_n", _ZERO3, "m/s", "estimated velocity, NED (v_D = 0)"),
        output(
            "phi_hat",
            _ZERO3,
            "arcmin",
            "estimated misalignment of the fine-start attitude (stationary base), NED",
        ),
        output("phi_err", _ZERO3, "arcmin", "attitude error, estimate minus truth, NED"),
        output("phi_sigma", _ZERO3, "arcmin", "1-sigma of phi_err from P"),
        output("rpy_err", _ZERO3, "arcmin", "roll, pitch, heading error, estimate minus truth"),
        output("rpy_sigma", _ZERO3, "arcmin", "1-sigma of rpy_err from P"),
        output(
            "nees",
            0.0,
            "1",
            "NEES of the three angles phi_err with their covariance (chi-square, 3 dof; "
            "needs rpy_true)",
        ),
        output(
            "nis",
            0.0,
            "1",
            "NIS of the last zero-velocity update (chi-square, 2 dof; 0 before the first)",
        ),
        output(
            "coarse_sigma",
            _ZERO3,
            "arcmin",
            "init_mode 2: error theory's 1-sigma of the coarse attitude N, E, D at its end",
        ),
        output("accel_bias", (0.0, 0.0), "m/s2", "estimated accelerometer bias, table x, y"),
        output("gyro_drift", _ZERO3, "rad/s", "estimated gyro drift, table x, y, z"),
        output("accel_bias_sigma", (0.0, 0.0), "m/s2", "1-sigma of accel_bias"),
        output("gyro_drift_sigma", _ZERO3, "rad/s", "1-sigma of gyro_drift"),
    )
    default_step = 0.1
    default_stop = 300.0
    step_multiples = ("kf_period",)
    shared_values = {"lat": "latitude", "h": "height"}

    # ------------------------------------------------------------ set-up
    def tuning(self) -> FilterTuning:
        """The filter tuning given by the parameters."""
        return FilterTuning(
            p0_vel=float(self.p0_vel),
            p0_att=tuple(float(a) for a in self.p0_att),
            p0_accel_bias=float(self.p0_accel_bias),
            p0_gyro_drift=float(self.p0_gyro_drift),
            q_accel=float(self.q_accel),
            q_gyro=float(self.q_gyro),
            r_vel=float(self.r_vel),
        )

    def _check(self) -> None:
        if self.init_mode not in (0, 1, 2):
            raise AlignmentConfigError(
                f"SinsStaticAlignment.init_mode must be 0 (analytic coarse), 1 (truth + "
                f"offset) or 2 (inertial-frame coarse), got {self.init_mode}"
            )
        if self.init_mode in (0, 2) and not self.coarse_time > 0.0:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.coarse_time must be > 0 s, got {self.coarse_time}"
            )
        if not self.kf_period > 0.0:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.kf_period must be > 0 s, got {self.kf_period}"
            )
        if not abs(self.lat) < 89.0 * DEG:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.lat must be within +-89 deg (heading is undefined at "
                f"the poles), got {self.lat / DEG:g} deg"
            )
        tun = self.tuning()
        sig = [tun.p0_vel, *tun.p0_att, tun.p0_accel_bias, tun.p0_gyro_drift, tun.r_vel]
        if not all(s > 0.0 for s in sig):
            raise AlignmentConfigError(
                "SinsStaticAlignment: p0_vel, p0_att, p0_accel_bias, p0_gyro_drift and r_vel "
                "must be > 0"
            )
        if tun.q_accel < 0.0 or tun.q_gyro < 0.0 or self.zupt_noise < 0.0:
            raise AlignmentConfigError(
                "SinsStaticAlignment: q_accel, q_gyro and zupt_noise must be >= 0"
            )
        if self.init_mode == 2:
            self._check_coarse_window(tun)

    def _check_coarse_window(self, tun: FilterTuning) -> None:
        """Refuse a coarse window whose theoretical heading sigma exceeds coarse_sigma_max."""
        smax = float(self.coarse_sigma_max)
        if not smax > 0.0:
            raise AlignmentConfigError(
                f"SinsStaticAlignment.coarse_sigma_max must be > 0, got {smax}"
            )
        T = float(self.coarse_time)
        dt = min(0.1, T / 10.0)
        th = coarse_theory_cached(T, float(self.lat), float(self.h), dt, tun)
        sig = float(np.sqrt(th.P_phi[2, 2]))
        if sig > smax:
            need = required_coarse_time(float(self.lat), float(self.h), dt, tun, smax)
            fix = (
                f"set coarse_time >= {need:.0f} s"
                if need is not None
                else "no window reaches it with this IMU (gyro bias limit): raise "
                "coarse_sigma_max or use a better IMU"
            )
            raise AlignmentConfigError(
                f"SinsStaticAlignment: init_mode 2 with coarse_time = {T:g} s leaves a "
                f"coarse heading 1-sigma of {sig / ARCMIN:.1f} arcmin (error theory for "
                f"q_gyro, q_accel, p0_gyro_drift, p0_accel_bias) above coarse_sigma_max = "
                f"{smax / ARCMIN:.1f} arcmin, beyond the fine filter's linear model: {fix}"
            )

    @classmethod
    def budget_model(cls, run: RunFacts) -> LinearErrorModel | None:
        """The filter's linear error model for the budget (its P0, Q, R; the base's axes).

        Parameters
        ----------
        run : RunFacts
            The run's facts (:class:`cosim.estimation.error_model.BudgetedFilter`).

        Returns
        -------
        LinearErrorModel
            :func:`cosim.alignment.error_models.static_error_model`.
        """
        from typing import cast

        from cosim.alignment.error_models import static_error_model

        # a ScenarioErrorModel offers the protocol's members (mypy cannot match the
        # dataclass's fields against the protocol's read-only properties here)
        return cast("LinearErrorModel | None", static_error_model(run))

    def initialize(self) -> None:
        self._check()
        self._rng = np.random.default_rng(int(self.seed))
        z = self._rng.standard_normal(3)  # always drawn: the stream does not depend on options
        self._C_s_t = euler_to_dcm_3(self.mount_rpy)
        self._axis = self._C_s_t[2, :].copy()
        tun = self.tuning()
        self._tun = tun
        self._Gq = noise_input() @ tun.Qc() @ noise_input().T
        self._F = error_model(_I3, float(self.lat), float(self.h))
        self._kf = KalmanFilter(N_STATES, 2)
        self._kf.H = measurement_matrix()
        self._kf.R = tun.R()
        self._nav: Strapdown | None = None
        self._bias_a = np.zeros(2)
        self._bias_g = np.zeros(3)
        self._sum_dth = np.zeros(3)
        self._sum_dv = np.zeros(3)
        self._elapsed = 0.0
        self._angle0 = float(self.angle)
        self._k_upd: int | None = None
        self._n_fine = 0
        self._C0_b_n = _I3.copy()
        self._ic: InertialCoarse | None = None
        self._coarse_P = np.zeros((3, 3))
        self._lever = np.asarray(self.lever_s, dtype=float).copy()
        self._has_lever = bool(np.any(self._lever))
        if self.init_mode == 2:
            self._ic = InertialCoarse(float(self.lat), float(self.h), lever_b=self._lever)
        self.phase = 0.0
        if self.init_mode == 1:
            offset = np.asarray(self.init_offset, dtype=float)
            if self.init_offset_random:
                offset = offset * z
            c_s_n = self._sensor_dcm(euler_to_dcm_3(self.rpy_true))
            self._start_fine(rotvec_to_dcm_3(offset) @ c_s_n)
        self._publish()

    def _publish_attitude(self, c_b_n: FloatArray, p_att: FloatArray) -> None:
        """Attitude outputs from an estimated ``C_b_n`` and its (3, 3) covariance [rad^2]."""
        rpy_hat = dcm_to_euler_3(c_b_n)
        rpy_true = np.asarray(self.rpy_true, dtype=float)
        e = dcm_to_rotvec_3(c_b_n @ euler_to_dcm_3(rpy_true).T)
        m = euler_rate_matrix_inv(rpy_hat)
        d = (rpy_hat - rpy_true).tolist()
        self.rpy = rpy_hat
        self.phi_err = e / ARCMIN
        self.phi_sigma = np.sqrt(np.diag(p_att)) / ARCMIN
        self.rpy_err = np.array([wrap_angle(d[0]), d[1], wrap_angle(d[2])]) / ARCMIN
        self.rpy_sigma = np.sqrt(np.diag(m @ p_att @ m.T)) / ARCMIN
        if p_att[0, 0] > 0.0:
            self.nees = quad_form_inv3(e, p_att)

    def _sensor_dcm(self, c_b_n: FloatArray) -> FloatArray:
        """``C_s_n`` from a base attitude and the current encoder angle."""
        return c_b_n @ table_dcm(float(self.angle)) @ self._C_s_t

    def _base_dcm(self) -> FloatArray:
        """Estimated ``C_b_n`` from the sensor attitude, the encoder angle and the mount."""
        assert self._nav is not None
        return self._nav.C_s_n @ self._C_s_t.T @ table_dcm(float(self.angle)).T

    def _start_fine(self, c_s_n: FloatArray, P0: FloatArray | None = None) -> None:
        mech = SWAYING_BASE if self.init_mode == 2 else STATIC_BASE
        self._nav = Strapdown(
            c_s_n, float(self.lat), float(self.h), options=mech, table_axis=self._axis
        )
        self._kf.x = np.zeros(N_STATES)
        self._kf.P = self._tun.P0() if P0 is None else P0
        self._C0_b_n = self._base_dcm()
        self._n_fine = 0
        self.phase = 1.0

    # ------------------------------------------------------------ stepping
    def step(self, t: float, h: float) -> None:
        dth = np.asarray(self.dtheta_s, dtype=float)
        dv = np.asarray(self.dv_s, dtype=float)
        if self._nav is None:
            self._coarse_step(dth, dv, h)
        else:
            self._fine_step(dth, dv, h)
        self._publish()

    def _coarse_step(self, dth: FloatArray, dv: FloatArray, h: float) -> None:
        if abs(float(self.angle) - self._angle0) > 1e-9:
            raise AlignmentError(
                "the turntable moved during coarse alignment; hold it (Turntable "
                "rotation_start >= coarse_time) or use init_mode = 1"
            )
        self._elapsed += h
        if self._ic is not None:
            self._inertial_coarse_step(dth, dv, h)
            return
        self._sum_dth += dth
        self._sum_dv += dv
        if self._elapsed >= float(self.coarse_time) - 1e-9 * max(1.0, float(self.coarse_time)):
            T = self._elapsed
            self._start_fine(
                coarse_alignment(
                    self._sum_dv / T, self._sum_dth / T, float(self.lat), float(self.h)
                )
            )

    def _inertial_coarse_step(self, dth: FloatArray, dv: FloatArray, h: float) -> None:
        ic = self._ic
        assert ic is not None
        ic.step(dth, dv, h)
        done = self._elapsed >= float(self.coarse_time) - 1e-9 * max(1.0, float(self.coarse_time))
        if not done and ic.elapsed < 1.0 - 0.5 * h:
            return  # no running estimate in the first second (too few pairs)
        c_s_n = ic.attitude()
        c_t_n = c_s_n @ self._C_s_t.T
        if done:
            th = coarse_theory_cached(ic.elapsed, float(self.lat), float(self.h), h, self._tun)
            self._coarse_P = th.P_phi
            self.coarse_sigma = np.sqrt(np.diag(th.P_phi)) / ARCMIN
            self._ic = None
            self._start_fine(c_s_n, coarse_p0(th, c_t_n, self._tun))
            return
        # running estimate during the window, 1-sigma from the theory at whole seconds
        sec = int(ic.elapsed + 0.5 * h)
        if sec >= 1 and abs(ic.elapsed - sec) < 0.5 * h:
            th = coarse_theory_cached(float(sec), float(self.lat), float(self.h), h, self._tun)
            self._coarse_P = th.P_phi
        self._publish_attitude(c_s_n @ self._C_s_t.T, self._coarse_P)

    def _fine_step(self, dth: FloatArray, dv: FloatArray, h: float) -> None:
        if self._k_upd is None:
            k = int(round(float(self.kf_period) / h))
            if k < 1 or abs(k * h - float(self.kf_period)) > 1e-9 * float(self.kf_period):
                raise AlignmentConfigError(
                    f"SinsStaticAlignment.kf_period = {self.kf_period:.9g} s must be a whole "
                    f"multiple of the block's step {h:.9g} s"
                )
            self._k_upd = k
        nav = self._nav
        assert nav is not None
        cst_t = self._C_s_t.T
        nav.step(dth, dv, h)
        F = self._F
        c_t_n = nav.mean_attitude() @ cst_t
        F[0:2, 5:7] = c_t_n[0:2, 0:2]
        F[2:5, 7:10] = -c_t_n
        if self.init_mode == 2:  # the specific force of a swaying base, not just -g
            F[0:2, 2:5] = skew(nav.dv_n / h)[0:2, :]
        Phi, Qd = discretize_taylor(F, self._Gq, h)
        kf = self._kf
        kf.predict(F=Phi, Q=Qd)
        self._n_fine += 1
        if self._n_fine % self._k_upd == 0:
            noise = self._rng.standard_normal(2) * float(self.zupt_noise)
            z = nav.v_n[0:2] + noise
            if self._has_lever:  # the IMU moves about the sway centre at rest
                # the step's mean velocity against the exact mean of d(C_s_n l)/dt
                u_n = (nav.C_s_n - nav.C_prev) @ self._lever / h
                z = 0.5 * (nav.v_prev[0:2] + nav.v_n[0:2]) + noise - u_n[0:2]
                kf.H = measurement_matrix()
                kf.H[:, 2:5] = -skew(u_n)[0:2, :]
            kf.update(z)
            x = kf.x
            nav.correct(rotation=rotvec_to_dcm_3(x[2:5]), d_v=np.array([x[0], x[1], 0.0]))
            self._bias_a += x[5:7]
            self._bias_g += x[7:10]
            nav.gyro_bias = cst_t @ self._bias_g
            nav.accel_bias = cst_t @ np.array([self._bias_a[0], self._bias_a[1], 0.0])
            kf.x = np.zeros(N_STATES)
            (y1, y2), ((s11, s12), (_, s22)) = kf.y.tolist(), kf.S.tolist()
            self.nis = (s22 * y1 * y1 - 2.0 * s12 * y1 * y2 + s11 * y2 * y2) / (
                s11 * s22 - s12 * s12
            )

    # ------------------------------------------------------------ outputs
    def _publish(self) -> None:
        if self._nav is None:
            return
        c_b_n = self._base_dcm()
        P = self._kf.P
        self._publish_attitude(c_b_n, P[2:5, 2:5])
        sd = np.sqrt(np.diag(P))
        self.v_n = self._nav.v_n.copy()
        self.phi_hat = dcm_to_rotvec_3(self._C0_b_n @ c_b_n.T) / ARCMIN
        self.accel_bias = self._bias_a.copy()
        self.gyro_drift = self._bias_g.copy()
        self.accel_bias_sigma = sd[5:7]
        self.gyro_drift_sigma = sd[7:10]
