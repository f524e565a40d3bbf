"""Two-position self-alignment of a gimballed HRG platform with a large azimuth error (seed 000).

The block :class:`HrgTwoPositionAlignment` feeds the accelerometer's velocity increments
and the platform status to :class:`cosim.alignment.hrg_filters.TwoPositionAligner` (the
filters: EKF, UPF or KF per position) and publishes its estimates; the equations are in
:mod:`cosim.alignment.hrg_model`.
"""

from __future__ import annotations

import math

from cosim.alignment.hrg_filters import TwoPositionAligner
from cosim.alignment.hrg_model import PSI, UNIFORM_SIGMA
from cosim.estimation.error_model import RunFacts, SignalBudgetModel
from cosim.models.block import Block, input_, output, parameter
from cosim.models.constants import ARCMIN, DEG, DEG_PER_HOUR, G0
from cosim.models.conventions import wrap_angle


class HrgTwoPositionAlignment(Block):
    """Two-position HRG platform self-alignment (seed 000): EKF, UPF or KF per position."""

    variables = (
        parameter("method", 1, description="0 EKF, 1 UPF, 2 KF (linear platform-frame model)"),
        parameter("n_particles", 200, description="UPF particles"),
        parameter("seed", 0, description="UPF random seed"),
        parameter("lat", 45.0 * DEG, "rad", "latitude"),
        parameter("g", 9.7966, "m/s2", "gravity"),
        parameter("period", 1.0, "s", "filter period (increments summed)"),
        parameter("accel_noise", 5e-6 * G0, "m/s/sqrt(s)", "accelerometer VRW density N"),
        parameter("dv_quantum", 1e-4, "m/s", "velocity per accelerometer pulse (1/K1)"),
        parameter("sigma_theta0", 3.0 * ARCMIN, "rad", "prior std of the level misalignments"),
        parameter("sigma_drift", 0.2 * DEG_PER_HOUR, "rad/s", "prior std of a drift rate"),
        parameter(
            "sigma_azimuth", UNIFORM_SIGMA, "rad", "prior azimuth std (>= pi/sqrt3: unknown)"
        ),
        parameter("azimuth0", 0.0, "rad", "prior azimuth estimate (theta_C)"),
        parameter("index_angle", 90.0 * DEG, "rad", "nominal indexing angle"),
        parameter("sigma_index", 6.0 * ARCMIN, "rad", "indexing accuracy (1 sigma)"),
        parameter("kernel", 1.0, "1", "UPF component azimuth std in grid spacings"),
        parameter("alpha", 1.0, "1", "UKF sigma-point spread"),
        parameter("resample", 0.1, "1", "UPF: resample when ESS < resample x n_particles"),
        parameter("conv_band", 4.0 * ARCMIN, "rad", "converged when 3 sigma(psi) <= conv_band"),
        input_("dv_p", (0.0, 0.0, 0.0), "m/s", "accelerometer velocity increments, p axes"),
        input_("position", 1.0, "1", "platform status: 1, 0 (indexing), 2"),
        input_("azimuth_true", 0.0, "rad", "true platform azimuth (error signals only)"),
        input_("theta_E_true", 0.0, "rad", "true level misalignment about east (errors only)"),
        input_("theta_N_true", 0.0, "rad", "true level misalignment about north (errors only)"),
        output("azimuth_est", 0.0, "rad", "current platform azimuth estimate"),
        output("azimuth_sigma", 0.0, "arcmin", "1-sigma of azimuth_est"),
        output("azimuth_err", 0.0, "arcmin", "azimuth_est - azimuth_true, wrapped"),
        output("psi_est", 0.0, "rad", "apparent azimuth of the current position (state)"),
        output("psi_sigma", 0.0, "arcmin", "1-sigma of psi_est"),
        output("azimuth_1", 0.0, "rad", "(theta_AP)_1, eq. (19)"),
        output("azimuth_2", 0.0, "rad", "(theta_AP)_2 referred to position 1, eq. (17)"),
        output("azimuth_avg", 0.0, "rad", "(theta_AP) two-position mean, eq. (20)"),
        output("azimuth_avg_sigma", 0.0, "arcmin", "1-sigma of azimuth_avg"),
        output("theta_E_est", 0.0, "rad", "current level misalignment about east"),
        output("theta_N_est", 0.0, "rad", "current level misalignment about north"),
        output("theta_E_sigma", 0.0, "arcmin", "1-sigma of theta_E_est"),
        output("theta_N_sigma", 0.0, "arcmin", "1-sigma of theta_N_est"),
        output("theta_E_err", 0.0, "arcmin", "theta_E_est - theta_E_true"),
        output("theta_N_err", 0.0, "arcmin", "theta_N_est - theta_N_true"),
        output("theta_N0_est", 0.0, "rad", "initial tilt about north of this position (state)"),
        output("theta_E0_est", 0.0, "rad", "initial tilt about east of this position (state)"),
        output(
            "drift_north_est", 0.0, "rad/s", "apparent north drift D_N of this position (state)"
        ),
        output("drift_north_sigma", 0.0, "deg/h", "1-sigma of drift_north_est"),
        output("D_N_est", 0.0, "rad/s", "drift of the y ('north') gyro, after position 2 starts"),
        output("D_E_est", 0.0, "rad/s", "drift of the x ('east') gyro, after position 2 starts"),
        output("D_N_sigma", 0.0, "deg/h", "1-sigma of D_N_est"),
        output("D_E_sigma", 0.0, "deg/h", "1-sigma of D_E_est"),
        output("H_E", 0.0, "rad/s", "east-gyro regular drift, eq. (21)"),
        output("converged", 0.0, "1", "1 when 3 sigma(psi) <= conv_band in this position"),
        output("t_conv_1", -1.0, "s", "position 1: time from its start to convergence (-1: not)"),
        output("t_conv_2", -1.0, "s", "position 2: time from its start to convergence (-1: not)"),
        output("position_active", 0.0, "1", "position being filtered (0 before the first)"),
        output("ess", 1.0, "1", "UPF effective sample size (1 for the Kalman filters)"),
        output("nis", 0.0, "1", "NIS of the last update (chi-square, 2 dof; 0 for the UPF)"),
    )
    default_step = 0.1
    default_stop = 2.0
    step_multiples = ("period",)
    shared_values = {"lat": "latitude", "g": "gravity"}

    @classmethod
    def budget_model(cls, run: RunFacts) -> SignalBudgetModel | None:
        """The first-order budget with the linear KF's model (it simulates the run).

        Parameters
        ----------
        run : RunFacts
            The run's facts (:class:`cosim.estimation.error_model.BudgetedFilter`).

        Returns
        -------
        HrgBudget or None
            :class:`cosim.alignment.hrg_budget.HrgBudget`; None without requirements.
        """
        from cosim.alignment.hrg_budget import HrgBudget

        return HrgBudget(run) if run.requirements else None

    def initialize(self) -> None:
        self._core = TwoPositionAligner(
            method=int(self.method),
            lat=float(self.lat),
            g=float(self.g),
            period=float(self.period),
            accel_noise=float(self.accel_noise),
            dv_quantum=float(self.dv_quantum),
            sigma_theta0=float(self.sigma_theta0),
            sigma_drift=float(self.sigma_drift),
            sigma_azimuth=float(self.sigma_azimuth),
            azimuth0=float(self.azimuth0),
            index_angle=float(self.index_angle),
            sigma_index=float(self.sigma_index),
            n_particles=int(self.n_particles),
            seed=int(self.seed),
            kernel=float(self.kernel),
            alpha=float(self.alpha),
            resample=float(self.resample),
        )
        self._core.start(self.start_time, float(self.position))
        self._publish(self.start_time)

    def step(self, t: float, h: float) -> None:
        updated = self._core.step(t, h, self.dv_p, float(self.position))
        if updated:
            self._publish(t + h)
        elif self._core.active:
            self._publish_tilts(t + h)

    # ------------------------------------------------------------------ outputs
    def _publish(self, t: float) -> None:
        core = self._core
        az, az_sig = core.azimuth()
        self.azimuth_est = az
        self.azimuth_sigma = az_sig / ARCMIN
        self.azimuth_err = float(wrap_angle(az - float(self.azimuth_true))) / ARCMIN
        self.position_active = float(core.active)
        if core.active:
            f = core.filters[core.active]
            self.psi_est = float(f.x[PSI])
            self.psi_sigma = math.sqrt(f.P[PSI, PSI]) / ARCMIN
            self.theta_N0_est, self.theta_E0_est = float(f.x[0]), float(f.x[1])
            self.drift_north_est = float(f.x[2])
            self.drift_north_sigma = math.sqrt(f.P[2, 2]) / DEG_PER_HOUR
            self.ess = float(f.ess)
            self.nis = float(f.nis)
            conv = 3.0 * math.sqrt(f.P[PSI, PSI]) <= float(self.conv_band)
            name = f"t_conv_{core.active}"
            if conv and getattr(self, name) < 0.0:
                setattr(self, name, t - core.starts[core.active])
            elif not conv:
                setattr(self, name, -1.0)
            self.converged = 1.0 if conv else 0.0
        else:
            self.psi_est = float(core.x0[PSI])
            self.psi_sigma = math.sqrt(core.P0[PSI, PSI]) / ARCMIN
            self.drift_north_sigma = math.sqrt(core.P0[2, 2]) / DEG_PER_HOUR
        s = core.solution
        if s is not None:
            self.azimuth_1, self.azimuth_2, self.azimuth_avg = (
                s.azimuth_1,
                s.azimuth_2,
                s.azimuth_avg,
            )
            self.azimuth_avg_sigma = s.sigma_avg / ARCMIN
            self.D_N_est, self.D_E_est = s.D_N, s.D_E
            self.D_N_sigma, self.D_E_sigma = s.sigma_D_N / DEG_PER_HOUR, s.sigma_D_E / DEG_PER_HOUR
            self.H_E = s.H_E
        else:
            if core.active:
                self.azimuth_1 = self.azimuth_avg = self.psi_est
            self.azimuth_avg_sigma = az_sig / ARCMIN
            self.D_N_sigma = self.D_E_sigma = core.sigma_drift / DEG_PER_HOUR
        self._publish_tilts(t)

    def _publish_tilts(self, t: float) -> None:
        e, n, se, sn = self._core.tilts(t)
        self.theta_E_est, self.theta_N_est = e, n
        self.theta_E_sigma, self.theta_N_sigma = se / ARCMIN, sn / ARCMIN
        self.theta_E_err = (e - float(self.theta_E_true)) / ARCMIN
        self.theta_N_err = (n - float(self.theta_N_true)) / ARCMIN
