"""Moored ship: sinusoidal roll/pitch/yaw and optional surge/sway/heave (truth motion).

Equations (per axis ``k``; ``rpy = [roll, pitch, yaw]``, Z-Y-X Euler angles of
``C_b_n``, see :mod:`models.conventions`)::

    rpy_k(t)  = rpy_mean_k + amp_k sin(w_k t + phase_k),     w_k = 2 pi / period_k
    rpy_k'    = amp_k w_k cos(w_k t + phase_k)
    rpy_k''   = -amp_k w_k^2 sin(w_k t + phase_k)

    d_l(t)    = lin_amp sin(wl t + lin_phase)     (surge, sway, heave) in the level frame
                                                 of the mean heading (x along it, z down)
    d_n       = Rz(yaw_mean) d_l,   v_n = d_n',   a_n = d_n''

    omega_nb_b from the Euler rates (exact, conventions.euler_rate_to_body_rate)
    omega_ib_b = omega_nb_b + C_n_b (omega_ie_n + omega_en_n)
    f_b        = C_n_b (a_n + (2 omega_ie_n + omega_en_n) x v_n - g_n(L, h))
    omega_dot_b = d(omega_ib_b)/dt in body axes (analytic)

Position: ``L = L0 + d_N / (R_M + h0)``, ``lon = lon0 + d_E / ((R_N + h0) cos L0)``,
``h = h0 - d_D`` (first order in the metre-sized displacement). Everything at an
instant is closed form; the increments over a step are the plain integrals

    dtheta_b = integral omega_ib_b dt,    dv_b = integral f_b dt      (over [t, t + h])

by composite Simpson on ``n = round(h / dt_truth)`` sub-steps (error ~ dt^4 |f''''|,
below 1e-15 of the increment at the defaults). They contain no coning or sculling
correction: they are what an ideal strapdown IMU measures; the navigation
algorithm applies the compensations. A period <= 0 switches that axis off.

With :func:`models.native.library` and no linear motion, the look-ahead (truth at every
node, Simpson sums, step-end outputs) is one call of ``ship_truth_steps``
(``models/blocks/ship_motion.c``, the same arithmetic in the same order: bit-identical here).

Defaults follow seed 001: latitude 30 deg, roll 12.5 deg / 12 s, pitch 10 deg / 6 s,
yaw 5 deg / 8 s about a mean heading of 0, no linear motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.models import native
from cosim.models.block import STEP_RTOL, Block, parameter, same_step
from cosim.models.constants import DEG, OMEGA_IE
from cosim.models.earth import MOTION_OUTPUTS, ImuTruth, euler_motion_truth, gravity
from cosim.models.step_paths import simpson_nodes, substeps


class ShipMotion(Block):
    """Moored ship motion: sinusoidal attitude and linear motion, exact rates and specific force.

    Attributes
    ----------
    truth_evaluations : int
        Vectorised truth evaluations since initialisation (each covers up to
        :data:`AHEAD_STEPS` steps): about ``n / AHEAD_STEPS`` for ``n`` steps on the
        master's grid, one per step if the steps are irregular.
    compiled : bool
        True when this instance evaluates its look-ahead through the compiled kernel (a
        moored ship with :func:`models.native.library`), False on the numpy path.
    """

    variables = (
        parameter("lat0", 30.0 * DEG, "rad", "latitude of the mooring"),
        parameter("lon0", 0.0, "rad", "longitude of the mooring"),
        parameter("h0", 0.0, "m", "height of the master IMU above the ellipsoid"),
        parameter("rpy_mean", (0.0, 0.0, 0.0), "rad", "mean roll, pitch, heading"),
        parameter("amp", (12.5 * DEG, 10.0 * DEG, 5.0 * DEG), "rad", "roll/pitch/yaw amplitude"),
        parameter("period", (12.0, 6.0, 8.0), "s", "roll/pitch/yaw period (<= 0: axis off)"),
        parameter("phase", (0.0, 0.0, 0.0), "rad", "roll/pitch/yaw phase"),
        parameter("lin_amp", (0.0, 0.0, 0.0), "m", "surge/sway/heave amplitude"),
        parameter("lin_period", (10.0, 10.0, 10.0), "s", "surge/sway/heave period (<= 0: off)"),
        parameter("lin_phase", (0.0, 0.0, 0.0), "rad", "surge/sway/heave phase"),
        parameter("dt_truth", 1.0e-3, "s", "inner integration step for the increments"),
        *MOTION_OUTPUTS,
    )
    default_stop = 2.0
    shared_values = {"lat0": "latitude", "h0": "height"}

    def initialize(self) -> None:
        per = np.asarray(self.period, dtype=float)
        self._w = np.where(per > 0.0, 2.0 * np.pi / np.where(per > 0.0, per, 1.0), 0.0)
        self._amp = np.where(per > 0.0, np.asarray(self.amp, dtype=float), 0.0)
        lper = np.asarray(self.lin_period, dtype=float)
        self._wl = np.where(lper > 0.0, 2.0 * np.pi / np.where(lper > 0.0, lper, 1.0), 0.0)
        self._lamp = np.where(lper > 0.0, np.asarray(self.lin_amp, dtype=float), 0.0)
        self._moving = bool(np.any(self._lamp != 0.0))
        cy, sy = math.cos(self.rpy_mean[2]), math.sin(self.rpy_mean[2])
        self._c_l_n = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        self._nodes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._ahead: _Ahead | None = None
        self._ahead_size = 1
        self.truth_evaluations = 0
        truth, rpy, v_n = self._truth(np.array([self.start_time]))
        self._publish(truth, rpy, v_n, 0)
        self.dtheta_b[:] = 0.0
        self.dv_b[:] = 0.0
        self._io = native.Buffers(self, (), ROW_OUTPUTS)
        lib = native.library()
        self._native: tuple | None = None
        if lib is not None and not self._moving:
            lat0 = float(self.lat0)
            par = np.concatenate(
                [
                    self._w,
                    self._amp,
                    np.asarray(self.phase, dtype=float),
                    np.asarray(self.rpy_mean, dtype=float),
                    [
                        OMEGA_IE * np.cos(lat0),
                        OMEGA_IE * np.sin(lat0),
                        float(gravity(lat0, float(self.h0))),
                    ],
                ]
            )
            self._native = (lib, par)
        self.compiled = self._native is not None

    def _truth(self, tt: np.ndarray) -> tuple[ImuTruth, np.ndarray, np.ndarray]:
        """Closed-form trajectory and inertial truth at the instants ``tt`` (shape (m,)).

        Returns
        -------
        truth : ImuTruth
            Inertial quantities at ``tt``.
        rpy, v_n : ndarray, shape (m, 3)
            Euler angles [rad] and NED velocity [m/s].
        """
        arg = tt[:, None] * self._w + np.asarray(self.phase)
        sa, ca = np.sin(arg), np.cos(arg)
        rpy = np.asarray(self.rpy_mean) + self._amp * sa
        rpy_dot = self._amp * self._w * ca
        rpy_ddot = -self._amp * self._w**2 * sa
        if not self._moving:
            truth = euler_motion_truth(rpy, rpy_dot, rpy_ddot, None, None, None, *self._ref())
            return truth, rpy, np.zeros_like(rpy)
        argl = tt[:, None] * self._wl + np.asarray(self.lin_phase)
        sl, cl = np.sin(argl), np.cos(argl)
        c = self._c_l_n.T  # row vectors: x_n = x_l @ C_l_n.T
        d_n = (self._lamp * sl) @ c
        v_n = (self._lamp * self._wl * cl) @ c
        a_n = (-self._lamp * self._wl**2 * sl) @ c
        return euler_motion_truth(rpy, rpy_dot, rpy_ddot, d_n, v_n, a_n, *self._ref()), rpy, v_n

    def _ref(self) -> tuple[float, float, float]:
        return float(self.lat0), float(self.lon0), float(self.h0)

    def _publish(self, truth: ImuTruth, rpy: np.ndarray, v_n: np.ndarray, i: int) -> None:
        """Set the state outputs from row ``i`` of the evaluated truth."""
        # written in place: the vectors stay the block's buffer views (models.block)
        self.rpy[:] = rpy[i]
        self.rpy[2] = math.remainder(self.rpy[2], 2.0 * math.pi)
        self.v_n[:] = v_n[i]
        self.lat = float(truth.lat[i])
        self.lon = float(truth.lon[i])
        self.h = float(truth.h[i])
        self.omega_ib_b[:] = truth.omega_ib_b[i]
        self.omega_dot_b[:] = truth.omega_dot_b[i]
        self.f_b[:] = truth.f_b[i]

    def step(self, t: float, h: float) -> None:
        ahead = self._ahead
        if ahead is None or not ahead.serves(t, h):
            ahead = self._look_ahead(t, h)
        k = ahead.pos
        ahead.pos += 1
        row = ahead.rows[k]  # this step's outputs, packed once per look-ahead (see _Ahead)
        self.lat, self.lon, self.h = ahead.position[k]
        out = self._io.output_array()
        if out is not None:  # the outputs are one buffer in this order: one copy
            np.copyto(out, row)
            return
        self.rpy = row[0:3]
        self.v_n = row[3:6]
        self.omega_ib_b = row[6:9]
        self.omega_dot_b = row[9:12]
        self.f_b = row[12:15]
        self.dtheta_b = row[15:18]
        self.dv_b = row[18:21]

    def _look_ahead(self, t: float, h: float) -> _Ahead:
        """Evaluate the steps from ``t`` on, predicting the master's next step starts.

        The truth is closed form in time, so several steps cost one vectorised call.
        Each step uses the master's ``t_n = t0 + n h`` and ``h_n = t_{n+1} - t_n``
        as predicted from this call's ``h`` (:meth:`_Ahead.serves` compares them with
        the step actually taken, to the rounding of the time grid);
        the number of steps evaluated ahead doubles while the predictions hold (up to
        :data:`AHEAD_STEPS`) and drops to one when one fails.
        """
        previous = self._ahead
        if previous is not None and previous.pos < len(previous.starts):
            self._ahead_size = 1  # mispredicted: irregular steps, evaluate one at a time
        elif previous is not None:
            self._ahead_size = min(AHEAD_STEPS, 2 * self._ahead_size)
        size = self._ahead_size
        self.truth_evaluations += 1
        n = substeps(h, self.dt_truth)
        if n not in self._nodes:
            self._nodes[n] = simpson_nodes(n)
        s, w = self._nodes[n]
        k0 = round((t - self.start_time) / h)
        grid = self.start_time + (k0 + np.arange(size + 1)) * h
        if grid[0] != t:
            grid = t + np.arange(size + 1) * h
        starts = grid[:-1]
        steps = (grid[1:] - starts)[:, None]  # h_n = t_{n+1} - t_n, as the master passes it
        tt = (starts[:, None] + steps * s).ravel()
        m = len(s)
        if self._native is not None:  # the moored ship, compiled: the same rows
            rows = np.empty((size, 21))
            lib, par = self._native
            lengths = np.ascontiguousarray(steps[:, 0])  # kept alive over the call
            lib.ship_truth_steps(
                native.pointer(par),
                native.pointer(tt),
                native.pointer(w),
                native.pointer(lengths),
                size,
                m,
                native.pointer(rows),
            )
            self._ahead = _Ahead(
                steps=steps[:, 0].tolist(),
                starts=starts.tolist(),
                rows=rows,
                position=[(float(self.lat0), float(self.lon0), float(self.h0))] * size,
            )
            return self._ahead
        truth, rpy, v_n = self._truth(tt)
        ends = np.arange(1, size + 1) * m - 1  # the node at each step's end
        rows = np.concatenate(
            [
                rpy[ends],
                v_n[ends],
                truth.omega_ib_b[ends],
                truth.omega_dot_b[ends],
                truth.f_b[ends],
                steps * _simpson(w, truth.omega_ib_b.reshape(size, m, 3)),
                steps * _simpson(w, truth.f_b.reshape(size, m, 3)),
            ],
            axis=1,
        )
        rows[:, 2] = [math.remainder(y, 2.0 * math.pi) for y in rows[:, 2].tolist()]
        position = np.stack([truth.lat[ends], truth.lon[ends], truth.h[ends]], axis=1).tolist()
        self._ahead = _Ahead(
            steps=steps[:, 0].tolist(),
            starts=starts.tolist(),
            rows=rows,
            position=[tuple(p) for p in position],
        )
        return self._ahead


def _simpson(w: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``sum_j w_j x[:, j]`` in node order (cumsum is sequential, as the compiled step).

    ``w`` (m,) weights, ``x`` (size, m, 3) values at the nodes of each step -> (size, 3).
    """
    return np.cumsum(w[None, :, None] * x, axis=1)[:, -1]


#: The vector outputs in the order of a row of :class:`_Ahead` (their declaration order).
ROW_OUTPUTS = ("rpy", "v_n", "omega_ib_b", "omega_dot_b", "f_b", "dtheta_b", "dv_b")

#: Most steps of a moored ship evaluated in one vectorised call.
AHEAD_STEPS = 64


@dataclass
class _Ahead:
    """Outputs of the next steps, evaluated at once: step ``k`` runs from ``starts[k]`` for
    ``steps[k]``; ``rows[k]`` holds its step-end ``rpy`` (yaw wrapped), ``v_n``,
    ``omega_ib_b``, ``omega_dot_b``, ``f_b`` and its ``dtheta_b``, ``dv_b`` (21 values),
    ``position[k]`` its ``(lat, lon, h)``."""

    steps: list[float]
    starts: list[float]
    rows: np.ndarray
    position: list[tuple[float, float, float]]
    pos: int = 0

    def serves(self, t: float, h: float) -> bool:
        """True when the next evaluated step is the step from ``t`` of size ``h``.

        Bit for bit when the master's grid is the predicted one (``t0 + n h`` with the
        step of the first call); otherwise within the rounding of the time grid
        (:data:`models.block.STEP_RTOL` of ``h``), which moves the outputs by the
        relative time difference (~1e-16), far below the models' 1e-12.
        """
        k = self.pos
        if k >= len(self.starts):
            return False
        h_k = self.steps[k]
        return abs(self.starts[k] - t) <= STEP_RTOL * h_k and same_step(h, h_k)
