"""The transfer-alignment filter block: a slave strapdown matched to the master by a UKF.

The block :class:`TransferAlignment` aligns a slave strapdown IMU on a ship's deck to
the ship's master INS by **velocity matching** (``matching = 0``, the default and seed
001's case; attitude and velocity-plus-attitude matching, ``matching = 1, 2``, and the
lag state, ``estimate_lag = 1``, run :class:`cosim.alignment.transfer_matching.MatchingFilter`
in numpy instead, with ``master_period`` for a master slower than the block's step; user
documentation: ``docs/transfer_alignment.md``): it runs its own strapdown mechanisation
from the slave's angle and velocity increments (every increment it receives), starts it
with the master's attitude (so the slave's initial attitude error is the unknown mounting,
seed 001: roll 1 deg, pitch 1 deg, heading 30 deg, plus the deck flexure), and corrects it
with a scaled unscented Kalman filter whose process model is the nonlinear error model of
seed 001, eq. (12)-(30), rewritten in our frames (NED, FRD) in
:mod:`cosim.alignment.transfer_model`. The estimator itself (mechanisation, period sums,
the two stages below) is :class:`cosim.alignment.transfer_filter.TransferFilter`; the
block validates its parameters, feeds it and publishes.


Filter: two stages, both scaled UKFs (Merwe sigma points ``ukf_alpha``, ``ukf_beta``,
``ukf_kappa``; heading-aware mean and residual, :func:`cosim.estimation.angle_mean_fn`
and :func:`~cosim.estimation.angle_residual_fn` on ``phi_D``). Seed 001 augments the state
with the noises; with additive noise the augmented and the plain UKF give the same first
two moments, so we do not augment.

* **Stage 1, acquisition** (``stage = 1``): a Gaussian-sum bank of ``acquire_hypotheses``
  UKFs (:class:`cosim.estimation.UnscentedParticleFilter` with ``proposal="mean"``: each
  particle is a UKF, weighted by its innovations' likelihood), whose prior headings are
  spread evenly over the circle with sigma ``p0_heading`` each (6 x 30 deg by default), so
  any initial heading error, up to 180 deg, is within about one sigma of a hypothesis.
  The mechanisation runs open loop (the model is exact for large errors). One UKF with a
  60 deg prior and a 30 deg error converged, but its Gaussian posterior became
  overconfident within the first seconds (a level error of 1 deg is then "explained" by a
  heading swing of 15-25 deg) and from 90 deg on it locked onto wrong headings.
* The acquisition ends (at ``acquire_min_time`` at the earliest) when the hypotheses on
  the best heading hold ``acquire_weight`` of the weight and that hypothesis' heading
  sigma is below ``acquire_sigma``. Its estimate is fed back; its accelerometer bias,
  gyro drift and flexure estimates are discarded (back to their priors, uncorrelated)
  and ``relevel_sigma^2`` is added to the level variances: in the large-error transient
  the Gaussian approximation leaves wrong, overconfident values in the weakly observable
  direction "level tilt vs bias / g", which no later data would correct (a noise-free
  run kept a 1.4 arcmin level error and a 1000 ug bias estimate without this restart).
* **Stage 2, fine alignment** (``stage = 2``): one UKF with the same model, closed loop.
  After each update the estimate is fed back, ``C^ <- E(phi^)^T C^``,
  ``v^ <- v^ - (dV^ - M xi^)``, ``L^ <- L^ - dL^``, ``nabla^ += nabla_x``,
  ``eps^ += eps_x``, and those states are reset to zero; the covariance is carried
  through the reset with its Jacobian (``phi_new = A(phi^) dphi``, the Euler-rate matrix
  of ``phi^``; identity for everything else). The flexure states are not fed back (they
  are not mechanisation errors).


Mechanisation (slave axes, every IMU increment ``dtheta, dv`` over ``h``)
----------------------------------------------------------------------------
:class:`cosim.alignment.nav.Strapdown` with :data:`~cosim.alignment.nav.MOVING_BASE`:
two-sample coning and sculling with the previous increment::

    a = dtheta + dtheta_prev x dtheta / 12
    u = dv + dtheta x dv / 2 + dtheta x (dtheta x dv) / 6
          + (dtheta_prev x dv + dv_prev x dtheta) / 12
    C^ <- exp(-[zeta x]) C^ exp([a x]),   zeta = w^_in h
    v^ <- v^ + (I - [zeta x] / 2) C^ u + (g(L^, h_m) - (2 w^_ie + w^_en) x v^_mid) h
    L^ <- L^ + v^_N,mid h / (R_M + h_m)

``v^_mid`` extrapolated from the last two velocities; the height is the master's (the
vertical position is not mechanised, so there is no height state, as in the paper). The
latitude-dependent constants are refreshed once per filter period, when the period
sums (:class:`~cosim.alignment.transfer_model.PeriodSums`) restart.

Outputs ("alignment accuracy")
------------------------------
What is compared: the slave's estimated attitude ``C^_s_n`` against its true attitude
``C_s_n`` (from :class:`models.blocks.lever_arm.LeverArm`'s ``rpy_s``), both referred to the
master's true attitude, i.e. the **relative attitude** (misalignment) of the slave in
master axes, ``C_s_b = C_b_n^T C_s_n``, which is the mounting plus the current flexure
(seed 001's "true misalignment" of Table 1: 1.055706 deg, 1.015315 deg, 29.98939 deg).
``rpy_err = euler(C_b_n^T C^_s_n) - euler(C_b_n^T C_s_n)`` [arcmin], Z-Y-X angles of the
relative attitude: roll, pitch, heading of the slave relative to the master. Its 1-sigma
``rpy_sigma`` maps ``P_phi`` through ``C_n_b`` and the inverse Euler-rate matrix of the
relative attitude, both from the **truth** input ``rpy_m_true`` (left unconnected, that
input is zero and ``rpy_sigma`` is then the sigma of the slave's absolute roll, pitch, yaw
in NED). Without truth use ``rel_rpy_sigma``: the same mapping from the master's reported
attitude, the 1-sigma of ``rel_rpy``; ``mount``, ``mount_sigma`` are the rigid mounting
(relative attitude without the flexure estimate, master axes) and its 1-sigma
(:func:`cosim.alignment.transfer_matching.estimates`; these four are refreshed once per
filter period). The rigid mounting estimate is the relative attitude minus the flexure
estimate ``flex`` (master axes, with its own sigma). In stage 1 the outputs are those of
the most probable hypothesis (``nis`` too: its own UKF's innovation). Also: ``rel_rpy``
(the estimated relative attitude, from the master's reported attitude), bias and drift
estimates with their sigmas, ``nees`` (attitude error against ``P``, 3 degrees of
freedom), ``nis`` (0 before the first update) and ``stage``.

Compiled outputs: when :func:`cosim.models.native.kernel` gives ``transfer_publish``
(``cosim/alignment/transfer_publish.c``), the per-step outputs (``rpy_err``,
``rpy_sigma``, ``rel_rpy``, ``nees``) and the step's master attitude ``C_b_n`` are one
call; :meth:`TransferAlignment.attitude_numpy` stays as the fallback and the readable
statement (``INS_COSIM_NATIVE=0``, no library), equal to rounding
(``tests/models/test_native_publish.py``). Either way the vector outputs are written in place
into the block's output buffer while they are its views, so the master reads them as one
slice (:meth:`models.block.Block.real_reader`); an output rebound from outside is
assigned a new array instead. Once per filter period, ``cosim/alignment/transfer_master.c``
gives the master's state fed to the filter (``transfer_master_state``: attitude, rate
w.r.t. the earth from the attitude ring, velocity; :meth:`TransferAlignment.master_state_numpy`)
and what changes with the shown covariance (``transfer_period``: ``P_att``, its inverse,
flexure, bias and drift outputs; :meth:`TransferAlignment.period_numpy`), one call each,
equal to rounding (``tests/models/test_native_master.py``).

Limits: the block must step every macro step (rate 1) with a constant step that divides
``period``: its strapdown needs every increment; it starts once it has five master
attitudes (for the rate), i.e. four steps after the start. Without a lever arm the
heading is observable only by gyrocompassing (tens of minutes), which the acquisition
stage is not designed for (seed 001; docs/reproductions.md).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import NDArray

from cosim.alignment.nav import euler_rate_matrix_inv, nav_rates
from cosim.alignment.transfer_filter import StageSettings, TransferFilter
from cosim.alignment.transfer_matching import (
    MATCHING_MODES,
    MAX_HEADING_PRIOR,
    MatchingFilter,
    estimates,
)
from cosim.alignment.transfer_model import (
    StateLayout,
    TransferConfigError,
    TransferRuntimeError,
    TransferTuning,
    master_rate,
)
from cosim.estimation.error_model import LinearErrorModel, RunFacts
from cosim.models import native
from cosim.models.block import Block, input_, output, parameter
from cosim.models.constants import ARCMIN, DEG, E2, A
from cosim.models.conventions import dcm_to_euler_3, euler_to_dcm, euler_to_dcm_3, wrap_angle

FloatArray = NDArray[np.float64]

_ZERO3 = (0.0, 0.0, 0.0)
#: Inputs of the per-step outputs, in the kernel's order (back to back in the input buffer).
PUBLISH_INPUTS = ("rpy_master", "rpy_s_true", "rpy_m_true")
#: The per-step vector outputs, in the kernel's order (back to back in the output buffer).
PUBLISH_OUTPUTS = ("rpy_err", "rpy_sigma", "rel_rpy")
#: The outputs that change with the shown covariance, in the kernel's order (back to back).
PERIOD_OUTPUTS = (
    "flex",
    "flex_sigma",
    "accel_bias",
    "accel_bias_sigma",
    "gyro_drift",
    "gyro_drift_sigma",
)
#: The master attitudes kept for the rate (:func:`~cosim.alignment.transfer_model.master_rate`).
HISTORY = 5


# ----------------------------------------------------------------------------- the block
class TransferAlignment(Block):
    """Transfer alignment by velocity and/or attitude matching: slave strapdown + scaled UKF."""

    variables = (
        parameter("r0", (10.0, 10.0, 5.0), "m", "nominal lever arm master -> slave, master axes"),
        parameter("flexure_states", 1, description="1: 19 states with flexure, 0: 13 (ignored)"),
        parameter("period", 0.5, "s", "filter period (a whole number of macro steps)"),
        parameter("p0_pos", TransferTuning.p0_pos, "m", "P0: position error behind dL"),
        parameter("p0_vel", TransferTuning.p0_vel, "m/s", "P0: velocity difference sigma"),
        parameter("p0_level", TransferTuning.p0_level, "rad", "P0: level error sigma"),
        parameter("p0_heading", TransferTuning.p0_heading, "rad", "P0: heading error sigma"),
        parameter(
            "p0_accel_bias", TransferTuning.p0_accel_bias, "m/s2", "P0: accelerometer bias sigma"
        ),
        parameter("p0_gyro_drift", TransferTuning.p0_gyro_drift, "rad/s", "P0: gyro drift sigma"),
        parameter("q_accel", TransferTuning.q_accel, "m/s/sqrt(s)", "Q: accelerometer noise"),
        parameter("q_gyro", TransferTuning.q_gyro, "rad/sqrt(s)", "Q: gyro noise density"),
        parameter("r_vel", TransferTuning.r_vel, "m/s", "R: velocity-matching noise sigma"),
        parameter("flexure_tau", TransferTuning.flex_tau, "s", "flexure model: tau per axis"),
        parameter(
            "flexure_sigma", TransferTuning.flex_sigma, "rad", "flexure model: sigma per axis"
        ),
        parameter("acquire_hypotheses", 6, description="stage 1: headings in the UKF bank"),
        parameter(
            "acquire_sigma", 1.0 * DEG, "rad", "stage 1 ends when the heading sigma is below this"
        ),
        parameter(
            "acquire_weight", 0.99, "1", "... and the hypotheses on the best heading this weight"
        ),
        parameter("acquire_min_time", 5.0, "s", "shortest stage 1 (acquisition)"),
        parameter(
            "relevel_sigma",
            10.0 * ARCMIN,
            "rad",
            "level sigma added at the stage-2 restart (not with attitude matching)",
        ),
        parameter("ukf_alpha", 0.1, "1", "UKF sigma-point spread alpha"),
        parameter("ukf_beta", 2.0, "1", "UKF beta (2: Gaussian prior)"),
        parameter("ukf_kappa", 0.0, "1", "UKF kappa"),
        parameter("matching", 0, description="0 velocity, 1 attitude, 2 velocity+attitude"),
        parameter("estimate_lag", 0, description="1: estimate the master's data lag (a state)"),
        parameter("r_att", 1.0 * ARCMIN, "rad", "R: attitude-matching noise sigma per axis"),
        parameter("p0_lag", 0.05, "s", "P0: lag sigma (estimate_lag = 1)"),
        parameter("mount_rpy", _ZERO3, "rad", "nominal mounting C_nom (slave to master axes)"),
        parameter("master_period", 0.0, "s", "master data interval (0: every step)"),
        input_("dtheta_s", _ZERO3, "rad", "slave angle increment over the step, slave axes"),
        input_("dv_s", _ZERO3, "m/s", "slave velocity increment over the step, slave axes"),
        input_("v_master_n", _ZERO3, "m/s", "master velocity, NED"),
        input_("rpy_master", _ZERO3, "rad", "master attitude (roll, pitch, yaw)"),
        input_("lat_master", 30.0 * DEG, "rad", "master latitude"),
        input_("h_master", 0.0, "m", "master height"),
        input_("rpy_s_true", _ZERO3, "rad", "truth: slave attitude (LeverArm.rpy_s)"),
        input_("rpy_m_true", _ZERO3, "rad", "truth: master attitude (ShipMotion.rpy)"),
        output("rpy_err", _ZERO3, "arcmin", "relative attitude error: roll, pitch, heading"),
        output("rpy_sigma", _ZERO3, "arcmin", "1-sigma of rpy_err (via rpy_m_true: truth)"),
        output("rel_rpy", _ZERO3, "rad", "estimated slave attitude in master axes (misalignment)"),
        output("flex", _ZERO3, "arcmin", "estimated flexure angle, master axes"),
        output("flex_sigma", _ZERO3, "arcmin", "1-sigma of flex"),
        output("accel_bias", _ZERO3, "m/s2", "estimated accelerometer bias, slave axes"),
        output("accel_bias_sigma", _ZERO3, "m/s2", "1-sigma of accel_bias"),
        output("gyro_drift", _ZERO3, "rad/s", "estimated gyro drift, slave axes"),
        output("gyro_drift_sigma", _ZERO3, "rad/s", "1-sigma of gyro_drift"),
        output("nees", 0.0, "1", "NEES of the attitude error (chi-square, 3 dof)"),
        output("nis", 0.0, "1", "NIS of the last update (chi-square, nis_dof dof)"),
        output("stage", 0.0, "1", "0 waiting for the master, 1 acquisition, 2 fine alignment"),
        output("nis_dof", 3.0, "1", "degrees of freedom of nis: the measurement dimension"),
        output("rel_rpy_sigma", _ZERO3, "arcmin", "1-sigma of rel_rpy (master axes, per period)"),
        output("mount", _ZERO3, "rad", "estimated rigid mounting C_s_d: rel_rpy minus flexure"),
        output("mount_sigma", _ZERO3, "arcmin", "1-sigma of mount (per period)"),
        output("lag", 0.0, "s", "estimated lag of the master's data (estimate_lag = 1)"),
        output("lag_sigma", 0.0, "s", "1-sigma of lag"),
        output("kernel_path", 0.0, "1", "1: compiled velocity-path kernels ran, 0: numpy"),
    )
    default_step = 0.02
    default_stop = 10.0
    step_multiples = ("period",)

    # ------------------------------------------------------------------ set-up
    @property
    def compiled(self) -> bool:
        """True when the per-step outputs are computed by ``transfer_publish`` (set by
        :meth:`initialize`, :func:`cosim.models.native.kernel`), False on the numpy path."""
        return getattr(self, "_native_publish", None) is not None

    @property
    def estimator(self) -> TransferFilter:
        """The two-stage estimator the block feeds (mechanisation, stages, shown state)."""
        return self._filter

    @property
    def master_dcm(self) -> FloatArray:
        """The master's attitude ``C_b_n`` of the newest step, shape (3, 3) (kept, not a copy)."""
        return self._hist[0]

    def tuning(self) -> TransferTuning:
        """The filter statistics from the parameters."""
        return TransferTuning(
            p0_pos=float(self.p0_pos),
            p0_vel=float(self.p0_vel),
            p0_level=float(self.p0_level),
            p0_heading=float(self.p0_heading),
            p0_accel_bias=float(self.p0_accel_bias),
            p0_gyro_drift=float(self.p0_gyro_drift),
            q_accel=float(self.q_accel),
            q_gyro=float(self.q_gyro),
            r_vel=float(self.r_vel),
            flex_tau=tuple(float(v) for v in self.flexure_tau),
            flex_sigma=tuple(float(v) for v in self.flexure_sigma),
        )

    @property
    def extended(self) -> bool:
        """True when the block runs the numpy path of :mod:`cosim.alignment.transfer_matching`
        or samples the master every ``master_period`` (attitude matching, lag or a slower
        master): the compiled kernels cover velocity matching on every step only."""
        return bool(self.matching != 0 or self.estimate_lag or self.master_period > 0.0)

    def _check(self) -> None:
        if self.matching not in MATCHING_MODES:
            raise TransferConfigError(
                f"TransferAlignment.matching must be 0 (velocity), 1 (attitude) or 2 "
                f"(velocity+attitude), got {self.matching}"
            )
        if self.estimate_lag not in (0, 1):
            raise TransferConfigError(
                f"TransferAlignment.estimate_lag must be 0 or 1, got {self.estimate_lag}"
            )
        for name in ("r_att", "p0_lag"):
            if not getattr(self, name) > 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be > 0, got {getattr(self, name)}"
                )
        if self.master_period < 0.0:
            raise TransferConfigError(
                f"TransferAlignment.master_period must be >= 0 s, got {self.master_period}"
            )
        if (self.matching or self.estimate_lag) and self.p0_heading > MAX_HEADING_PRIOR:
            raise TransferConfigError(
                f"TransferAlignment.p0_heading ({self.p0_heading / DEG:.3g} deg) must be at most "
                f"{MAX_HEADING_PRIOR / DEG:.0f} deg with matching = {self.matching} or "
                "estimate_lag = 1 (no acquisition bank runs): give mount_rpy within a few "
                "degrees of the mounting, or use matching = 0 without the lag"
            )
        if self.flexure_states not in (0, 1):
            raise TransferConfigError(
                f"TransferAlignment.flexure_states must be 0 or 1, got {self.flexure_states}"
            )
        if not self.period > 0.0:
            raise TransferConfigError(f"TransferAlignment.period must be > 0 s, got {self.period}")
        positive = ("p0_pos", "p0_vel", "p0_level", "p0_heading", "r_vel")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be > 0, got {getattr(self, name)}"
                )
        for name in ("p0_accel_bias", "p0_gyro_drift", "q_accel", "q_gyro"):
            if getattr(self, name) < 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be >= 0, got {getattr(self, name)}"
                )
        if self.flexure_states and not (
            np.all(np.asarray(self.flexure_tau) > 0.0)
            and np.all(np.asarray(self.flexure_sigma) > 0.0)
        ):
            raise TransferConfigError(
                "TransferAlignment.flexure_tau and flexure_sigma must be > 0 on every axis "
                "when flexure_states = 1"
            )
        for name in ("acquire_sigma", "relevel_sigma"):
            if not getattr(self, name) > 0.0:
                raise TransferConfigError(
                    f"TransferAlignment.{name} must be > 0, got {getattr(self, name)}"
                )
        if int(self.acquire_hypotheses) < 1:
            raise TransferConfigError(
                f"TransferAlignment.acquire_hypotheses must be >= 1, got {self.acquire_hypotheses}"
            )
        if not 0.0 < self.acquire_weight <= 1.0:
            raise TransferConfigError(
                f"TransferAlignment.acquire_weight must be in (0, 1], got {self.acquire_weight}"
            )
        if self.acquire_min_time < 0.0:
            raise TransferConfigError(
                f"TransferAlignment.acquire_min_time must be >= 0 s, got {self.acquire_min_time}"
            )
        if not self.ukf_alpha > 0.0:
            raise TransferConfigError(
                f"TransferAlignment.ukf_alpha must be > 0, got {self.ukf_alpha}"
            )

    @classmethod
    def budget_model(cls, run: RunFacts) -> LinearErrorModel | None:
        """The small-error model along the ship's motion, for the budget.

        Parameters
        ----------
        run : RunFacts
            The run's facts (:class:`cosim.estimation.error_model.BudgetedFilter`).

        Returns
        -------
        LinearErrorModel
            :func:`cosim.alignment.error_models.transfer_error_model`.
        """
        from cosim.alignment.error_models import transfer_error_model

        return transfer_error_model(run)

    def initialize(self) -> None:
        self._check()
        self._layout = StateLayout(bool(self.flexure_states))
        settings = StageSettings(
            hypotheses=int(self.acquire_hypotheses),
            sigma=float(self.acquire_sigma),
            weight=float(self.acquire_weight),
            min_time=float(self.acquire_min_time),
            relevel_sigma=float(self.relevel_sigma),
            ukf_alpha=float(self.ukf_alpha),
            ukf_beta=float(self.ukf_beta),
            ukf_kappa=float(self.ukf_kappa),
        )
        self._c_nom = (
            None
            if not np.any(np.asarray(self.mount_rpy))
            else euler_to_dcm(np.asarray(self.mount_rpy, dtype=float))
        )
        if self.matching or self.estimate_lag:
            self._filter: TransferFilter = MatchingFilter(
                self._layout,
                self.tuning(),
                self.r0,
                settings,
                float(self.lat_master),
                matching=int(self.matching),
                estimate_lag=bool(self.estimate_lag),
                r_att=float(self.r_att),
                p0_lag=float(self.p0_lag),
                c_nom=np.eye(3) if self._c_nom is None else self._c_nom,
            )
        else:
            self._filter = TransferFilter(
                self._layout, self.tuning(), self.r0, settings, float(self.lat_master)
            )
            self._filter.c_nom = self._c_nom
        self._km = 1
        self._extras_P: FloatArray | None = None
        # the master attitudes, newest first: views of a ring of HISTORY matrices (the
        # oldest one's storage takes the newest)
        self._ring = np.zeros((HISTORY, 3, 3))
        self._hist: deque[FloatArray] = deque(maxlen=HISTORY)
        self._ring[0] = euler_to_dcm(np.asarray(self.rpy_master, dtype=float))
        self._hist.appendleft(self._ring[0])
        self._h: float | None = None
        self._k = 0
        self._n = 0
        self._P_cached: FloatArray | None = None
        self._att_T: FloatArray | None = None
        # what changes with P (per filter period): att_T, P_att, P_att^-1, ARCMIN
        self._per = np.zeros(28)
        self._per[27] = ARCMIN
        self._P_att = self._per[9:18].reshape(3, 3)
        self._P_att_inv = self._per[18:27].reshape(3, 3)
        self._per_ptr = native.pointer(self._per)
        # the vector outputs back to the output buffer's views (a re-initialised block)
        for name, view in self._out_views.items():
            setattr(self, name, view)
        self._io = native.Buffers(self, PUBLISH_INPUTS, PUBLISH_OUTPUTS)
        self._period_io = native.Buffers(self, (), PERIOD_OUTPUTS)
        self._native_publish = native.kernel("transfer_publish")
        if self._native_publish is not None:
            self._c_nav = np.zeros((3, 3))
            self._c_nav_ptr = native.pointer(self._c_nav)
            self._ring_ptrs = [native.pointer(c) for c in self._ring]
        self._native_period = native.kernel("transfer_period")
        if self._native_period is not None:
            lay = self._layout
            starts = [lay.att.start, lay.nabla.start, lay.eps.start, 7 if lay.flexure else -1]
            self._period_idx = np.array(starts, dtype=np.intc)
            self._period_idx_ptr = native.pointer(self._period_idx)
            self._bias = np.zeros(6)
            self._bias_ptr = native.pointer(self._bias)
        self._native_master = native.kernel("transfer_master_state")
        if self._native_master is not None:
            self._ring_ptr = native.pointer(self._ring)
            self._v_io = native.Buffers(self, ("v_master_n",), ())
            self._earth = np.array([A, E2])
            self._earth_ptr = native.pointer(self._earth)
            self._ms_out = np.zeros(12)
            self._ms_ptr = native.pointer(self._ms_out)
        if self.extended:  # the numpy path (module docstring of transfer_matching)
            self._native_publish = self._native_period = self._native_master = None
        self.nis = 0.0
        self.stage = 0.0
        self.nis_dof = float(getattr(self._filter, "dim_z", 3))
        self.kernel_path = 1.0 if self.compiled else 0.0
        self._publish()

    def _check_step(self, h: float) -> None:
        if self._h is None:
            k = int(round(self.period / h))
            if k < 1 or abs(k * h - self.period) > 1e-9 * self.period:
                raise TransferRuntimeError(
                    f"TransferAlignment.period ({self.period:.9g} s) must be a whole number of "
                    f"steps; the block steps by {h:.9g} s (run it at rate 1, every macro step)"
                )
            self._h, self._k = h, k
            if isinstance(self._filter, MatchingFilter):
                self._filter.set_accel_steps(k)
            if self.master_period > 0.0:
                km = int(round(self.master_period / h))
                if km < 1 or abs(km * h - self.master_period) > 1e-9 * self.master_period:
                    raise TransferRuntimeError(
                        f"TransferAlignment.master_period ({self.master_period} s) must be a "
                        f"whole number of steps ({h} s)"
                    )
                if k % km:
                    raise TransferRuntimeError(
                        f"TransferAlignment.period ({self.period} s) must be a whole number "
                        f"of master_period ({self.master_period} s)"
                    )
                self._km = km
        elif abs(h - self._h) > 1e-9 * self._h:
            raise TransferRuntimeError(
                f"TransferAlignment needs a constant step; got {h} s after {self._h} s"
            )

    def _master_state(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`master_state_numpy`, in one call of ``transfer_master_state`` when compiled."""
        fn = self._native_master
        if fn is None:
            return self.master_state_numpy()
        v_m = np.asarray(self.v_master_n, dtype=float)
        fn(
            self._ring_ptr,
            self._n % HISTORY,
            len(self._hist),
            self._h,
            self._v_io.input_pointer(),
            float(self.lat_master),
            float(self.h_master),
            self._earth_ptr,
            self._ms_ptr,
        )
        out = self._ms_out.copy()  # the filter gets arrays of its own, as from numpy
        return out[:9].reshape(3, 3), out[9:], v_m

    def master_state_numpy(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The master's state for the filter, in numpy (the statement of ``transfer_master``).

        Returns
        -------
        c_b_n : ndarray, shape (3, 3)
            The newest master attitude (a copy).
        w_eb_b : ndarray, shape (3,)
            Master rate w.r.t. the earth, master axes [rad/s]: the rate from the attitude
            history (:func:`~cosim.alignment.transfer_model.master_rate`) plus
            ``C_b_n^T omega_en_n`` (:func:`~cosim.alignment.nav.nav_rates`).
        v_m : ndarray, shape (3,)
            Master velocity, NED [m/s] (the input).
        """
        c = self._hist[0].copy()
        v_m = np.asarray(self.v_master_n, dtype=float)
        _, w_en = nav_rates(v_m, float(self.lat_master), float(self.h_master))
        w_eb = master_rate(list(self._hist), self._h * self._km) + c.T @ w_en
        return c, w_eb, v_m

    # ------------------------------------------------------------------ stepping
    def step(self, t: float, h: float) -> None:
        self._check_step(h)
        self._n += 1
        f = self._filter
        if self.extended:
            self._step_numpy(h)
            return
        c_m = self._ring[self._n % HISTORY]
        self._hist.appendleft(c_m)
        # the step's master attitude; the compiled publish computes it too (the same
        # arithmetic), so it is needed here only when the filter uses it
        if self._native_publish is None or f.nav is None or self._n % self._k == 0:
            c_m[...] = euler_to_dcm_3(self.rpy_master)
        if f.nav is None:
            if len(self._hist) == self._hist.maxlen:
                f.start(*self._master_state(), float(self.lat_master), float(self.h_master))
        else:
            f.step(np.asarray(self.dtheta_s, dtype=float), np.asarray(self.dv_s, dtype=float), h)
            if self._n % self._k == 0:
                f.update(self._n * self._h, *self._master_state())
                self.nis = f.nis
        self.stage = f.stage
        self._publish()

    def _step_numpy(self, h: float) -> None:
        """:meth:`step` of the numpy path: the master is sampled every ``master_period``."""
        f = self._filter
        fresh = self._n % self._km == 0
        if fresh:
            self._hist.appendleft(euler_to_dcm_3(self.rpy_master).copy())
        if f.nav is None:
            if fresh and len(self._hist) == self._hist.maxlen:
                f.start(*self.master_state_numpy(), float(self.lat_master), float(self.h_master))
        else:
            f.step(np.asarray(self.dtheta_s, dtype=float), np.asarray(self.dv_s, dtype=float), h)
            if self._n % self._k == 0:
                f.update(self._n * self._h, *self.master_state_numpy())
                self.nis = f.nis
        self.stage = f.stage
        self._publish()

    def _publish_period(self) -> None:
        """The outputs and constants that change with the shown covariance ``P``: one call
        of ``transfer_period`` when compiled, else :meth:`period_numpy`."""
        f = self._filter
        P, x = f.P_show, f.x_show
        self._P_cached = P
        self._att_T = None  # the shown attitude error's E^T, made when stage 1 needs it
        fn = self._native_period
        if fn is not None:
            sd = f.nav
            if sd is not None:
                self._bias[0:3] = sd.accel_bias
                self._bias[3:6] = sd.gyro_bias
            P_c = np.ascontiguousarray(P, dtype=float)  # (no copy: the filter's are)
            x_c = np.ascontiguousarray(x, dtype=float)
            ok = fn(
                native.pointer(P_c),
                P_c.shape[0],
                native.pointer(x_c),
                self._period_idx_ptr,
                self._bias_ptr,
                ARCMIN,
                self._per_ptr,
                self._period_io.output_pointer(),
            )
            if ok == 0:
                self._period_io.publish()
                return
        p_att, p_att_inv, values = self.period_numpy()  # (raises when P_att is singular)
        self._P_att[...] = p_att
        self._P_att_inv[...] = p_att_inv
        out = self._period_io.output_array()
        if out is not None:  # in place: the master reads the buffer as one slice
            out[...] = values
        else:
            for i, name in enumerate(PERIOD_OUTPUTS):
                setattr(self, name, values[3 * i : 3 * i + 3])

    def period_numpy(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """What changes with the shown covariance, in numpy (the statement of
        ``transfer_period``).

        Returns
        -------
        P_att, P_att_inv : ndarray, shape (3, 3)
            The attitude error's covariance [rad^2] and its inverse [rad^-2].
        values : ndarray, shape (18,)
            The outputs :data:`PERIOD_OUTPUTS` in this order: ``flex``, ``flex_sigma``
            [arcmin], ``accel_bias``, ``accel_bias_sigma`` [m/s2], ``gyro_drift``,
            ``gyro_drift_sigma`` [rad/s] (the biases: the mechanisation's plus the shown
            estimate's).
        """
        lay, f = self._layout, self._filter
        x_show = f.x_show
        P = f.P_show
        p_att = P[lay.att, lay.att].copy()
        if lay.flexure:
            flex = x_show[7:10] / ARCMIN
            flex_sigma = np.sqrt(P[7:10, 7:10].diagonal()) / ARCMIN
        else:
            flex = flex_sigma = np.zeros(3)
        sd = f.nav
        values = np.concatenate(
            [
                flex,
                flex_sigma,
                (sd.accel_bias if sd is not None else 0.0) + x_show[lay.nabla],
                np.sqrt(P[lay.nabla, lay.nabla].diagonal()),
                (sd.gyro_bias if sd is not None else 0.0) + x_show[lay.eps],
                np.sqrt(P[lay.eps, lay.eps].diagonal()),
            ]
        )
        return p_att, np.linalg.inv(p_att), values

    def _publish(self) -> None:
        """Set every output from the filter's shown estimate and the step's inputs."""
        f = self._filter
        if f.P_show is not self._P_cached:
            self._publish_period()
        if self._att_T is None and f.nav is not None and f.stage == 1.0:
            self._att_T = self._per[0:9].reshape(3, 3)
            self._att_T[...] = euler_to_dcm_3(f.x_show[self._layout.att]).T
        if f.P_show is not self._extras_P:
            self._publish_estimates()
        io = self._io
        if self._native_publish is not None:
            if f.nav is None:
                mode = 0
            else:
                self._c_nav[...] = f.nav.C_s_n
                mode = 1 if f.stage == 1.0 else 2
            self.nees = self._native_publish(
                io.input_pointer(),
                self._c_nav_ptr,
                mode,
                self._per_ptr,
                self._ring_ptrs[self._n % HISTORY],
                io.output_pointer(),
            )
            io.publish()
            return
        values, self.nees = self.attitude_numpy()
        out = io.output_array()
        if out is not None:
            out[...] = values
        else:
            self.rpy_err, self.rpy_sigma, self.rel_rpy = values[0:3], values[3:6], values[6:9]

    def _publish_estimates(self) -> None:
        """The outputs that need no truth: ``rel_rpy_sigma``, ``mount``, ``mount_sigma``,
        ``lag``, ``lag_sigma`` (:func:`cosim.alignment.transfer_matching.estimates`)."""
        f = self._filter
        self._extras_P = f.P_show
        if f.nav is None:
            c_est = self._hist[0] if self._c_nom is None else self._hist[0] @ self._c_nom
        else:
            c_est = f.nav.C_s_n if f.stage != 1.0 else self._att_T @ f.nav.C_s_n
        rel_sigma, mount, mount_sigma = estimates(
            c_est, self._hist[0], f.x_show, f.P_show, self._layout
        )
        self.rel_rpy_sigma[:] = rel_sigma
        self.mount[:] = mount
        self.mount_sigma[:] = mount_sigma
        tau = getattr(f, "tau", None)
        if tau is not None:
            self.lag = float(f.x_show[tau])
            self.lag_sigma = float(np.sqrt(max(f.P_show[tau, tau], 0.0)))

    def attitude_numpy(self) -> tuple[FloatArray, float]:
        """The per-step outputs in numpy (the statement of ``transfer_publish``).

        Returns
        -------
        values : ndarray, shape (9,)
            ``rpy_err`` [arcmin], ``rpy_sigma`` [arcmin], ``rel_rpy`` [rad], in this order.
        nees : float
            NEES of the attitude error (3 degrees of freedom).
        """
        f = self._filter
        if f.nav is None:
            c_est = self._hist[0]
        else:  # stage 1 runs open loop: apply the best hypothesis' attitude error
            c_est = f.nav.C_s_n
            if f.stage == 1.0:
                c_est = self._att_T @ c_est
        c_m_t = euler_to_dcm_3(self.rpy_m_true).T
        c_s = euler_to_dcm_3(self.rpy_s_true)
        rel_est = dcm_to_euler_3(c_m_t @ c_est)
        e0, e1, e2 = rel_est.tolist()
        r0, r1, r2 = dcm_to_euler_3(c_m_t @ c_s).tolist()
        B = euler_rate_matrix_inv(rel_est) @ c_m_t
        s0, s1, s2 = (B @ self._P_att @ B.T).diagonal().tolist()
        rel_rpy = dcm_to_euler_3(self._hist[0].T @ c_est)
        values = np.array(
            [
                wrap_angle(e0 - r0) / ARCMIN,
                wrap_angle(e1 - r1) / ARCMIN,
                wrap_angle(e2 - r2) / ARCMIN,
                math.sqrt(max(s0, 0.0)) / ARCMIN,
                math.sqrt(max(s1, 0.0)) / ARCMIN,
                math.sqrt(max(s2, 0.0)) / ARCMIN,
                *rel_rpy.tolist(),
            ]
        )
        # small-angle rotation vector of the error (exact for NEES use)
        (_, d01, d02), (d10, _, d12), (d20, d21, _) = (c_est @ c_s.T).tolist()
        e_n = np.array([0.5 * (d21 - d12), 0.5 * (d02 - d20), 0.5 * (d10 - d01)])
        return values, float(e_n @ self._P_att_inv @ e_n)
