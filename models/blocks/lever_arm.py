"""Slave-IMU kinematics from the master's motion: lever arm, deck flexure, mounting (seed 001).

Frames: master body ``b`` (the motion block's body frame, origin at the master
IMU), flexed deck frame ``d`` at the slave, slave body ``s``::

    C_d_b = exp([theta x])           (flexure angle theta, master axes; J_r its right Jacobian)
    C_s_d = euler_to_dcm(mount_rpy)  (fixed mounting misalignment, seed 001: 1, 1, 30 deg)
    C_s_b = C_d_b C_s_d,             C_s_n = C_b_n(rpy) C_s_b

Lever arm (seed 001 eq. 9-10, resolved in master body axes)::

    r_p = r_0 + R_0 theta,   r_p' = R_0 theta',   r_p'' = R_0 theta''
    R_0 = [[0, z0, 0], [0, 0, x0], [y0, 0, 0]]    for r_0 = [x0, y0, z0]

Slave rate and specific force (``omega = omega_ib_b``, ``omega'`` its derivative
in body axes; uniform gravity over the arm, as in eq. 2)::

    omega_is_s = C_s_d^T (C_d_b^T omega + J_r(theta) theta')
    f_p = f_b + omega x (omega x r_0) + omega' x r_0
              + ([omega x]^2 + [omega' x]) R_0 theta + 2 [omega x] R_0 theta' + R_0 theta''
    f_s = C_s_b^T f_p

With ``theta'' = -2 beta theta' - beta^2 theta + eta`` the flexure terms are
exactly eq. (11): ``(...) R_0 theta - R_2 theta + (2 [omega x] R_0 - R_1) theta' + R_0 eta``.
``theta''`` at the step end is the DeckFlexure's ``theta_ddot`` (white noise as
its step mean, see :mod:`models.blocks.deck_flexure`); over a step the integral of
``R_0 theta''`` is exactly ``R_0 dtheta_dot_flex``.

Increments (plain integrals over ``[t, t + h]``, no coning/sculling terms)::

    dtheta_s = integral omega_is_s dt,       dv_s = integral f_s dt

by composite Simpson on ``n = round(h / dt_truth)`` sub-steps. Inside the step
the inputs are rebuilt (:class:`models.step_paths.StepPath`): ``omega`` is the
quartic through the previous and current step-end ``omega_ib_b`` and
``omega_dot_b`` whose integral is ``dtheta_b`` (connect ShipMotion's
``omega_dot_b``); ``f_b`` the quadratic through the previous and current ``f_b``
with integral ``dv_b``; ``theta`` the cubic Hermite through ``theta, theta_dot``
at both ends (start = end minus ``dtheta_flex``, ``dtheta_dot_flex``). So the
angular acceleration is the master's analytic ``omega_dot_b`` (no finite
differences), ``integral omega' dt`` is exactly the change of ``omega_ib_b``,
and ``integral R_0 theta'' dt = R_0 dtheta_dot_flex``; with flexure off,
``dtheta_s = C_s_d^T dtheta_b`` exactly. The first step (or one after a time
jump, or with start values not forwarded at initialisation) uses the
memoryless quadratic / linear paths. Inputs must come from blocks stepping at
the same rate (the increments are per step).

Approximations: uniform gravity over the arm (eq. 2): ``f_s`` omits the
gravitation gradient, ~``3 GM/R^3 |r|`` <= 3e-5 m/s2 (3 ug) for the default 15 m arm,
so a navigator fed with ``f_s`` must use the master's gravity to reproduce
``v_n_s``; ``rpy_s`` and ``v_n_s`` are resolved in the master's NED frame (the
slave's own local level differs by ``|r|/R`` ~ 2e-6 rad).

Slave velocity (w.r.t. earth, master NED axes; ``omega_eb_b = omega - C_n_b omega_ie_n``)::

    v_n_s = v_n + C_b_n (omega_eb_b x r_p + r_p')

Compiled step: when :func:`models.native.library` gives the compiled kernels, a step is
one call of ``lever_arm_step`` (``models/blocks/lever_arm.c``: the paths, the node loop and
the step end above, node by node); otherwise the numpy code below. Both give the same
outputs to rounding (1e-12, ``tests/models/test_native.py``).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from cosim.models import native
from cosim.models.block import Block, input_, output, parameter
from cosim.models.constants import DEG, OMEGA_IE
from cosim.models.conventions import (
    cross,
    dcm_to_euler_3,
    euler_to_dcm,
    euler_to_dcm_3,
    rotvec_to_dcm_and_jacobian,
)
from cosim.models.earth import motion_inputs
from cosim.models.step_paths import (
    StepPath,
    hermite_basis,
    path_basis,
    simpson_nodes,
    step_linear,
    step_quadratic,
    substeps,
)


def r0_matrix(r0: np.ndarray) -> np.ndarray:
    """Seed 001's ``R_0 = [[0, z0, 0], [0, 0, x0], [y0, 0, 0]]`` for ``r0 = [x0, y0, z0]``.

    Parameters
    ----------
    r0 : ndarray, shape (3,)
        Undeformed lever arm master -> slave, master body axes [m].

    Returns
    -------
    ndarray, shape (3, 3)
        ``R_0`` [m/rad]: the lever-arm change ``R_0 theta`` for a flexure angle ``theta``.
    """
    x0, y0, z0 = (float(v) for v in r0)
    return np.array([[0.0, z0, 0.0], [0.0, 0.0, x0], [y0, 0.0, 0.0]])


def slave_kinematics(
    w: np.ndarray,
    wd: np.ndarray,
    f: np.ndarray,
    th: np.ndarray,
    thd: np.ndarray,
    thdd: np.ndarray,
    r0: np.ndarray,
    r0_t: np.ndarray,
    c_s_d: np.ndarray,
    flexure: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Slave rate and specific force (slave axes) and ``C_d_b`` at ``m`` instants at once.

    The kinematics of the module docstring: ``r = r0 + R_0 theta``,
    ``f_p = f + omega' x r + omega x (omega x r) [+ 2 omega x R_0 theta' + R_0 theta'']``,
    resolved through ``C_d_b = exp([theta x])`` and the mounting ``C_s_d``.

    Parameters
    ----------
    w, wd, f : ndarray, shape (m, 3)
        Master rate [rad/s], angular acceleration [rad/s2] and specific force [m/s2],
        master body axes.
    th, thd, thdd : ndarray, shape (m, 3)
        Flexure angle [rad] and its first [rad/s] and second [rad/s2] derivatives.
    r0 : ndarray, shape (3,)
        Lever arm master -> slave, master body axes [m].
    r0_t : ndarray, shape (3, 3)
        ``R_0.T`` (:func:`r0_matrix` transposed) [m/rad].
    c_s_d : ndarray, shape (3, 3)
        Slave mounting ``C_s_d``.
    flexure : bool
        False for a rigid deck: the flexure terms (and ``C_d_b``) are left out.

    Returns
    -------
    w_s, f_s : ndarray, shape (m, 3)
        Slave rate w.r.t. inertial [rad/s] and specific force [m/s2], slave axes.
    c_d_b : ndarray, shape (m, 3, 3), or None for a rigid deck
    """
    r = r0 + th @ r0_t
    # omega x (omega x r) = omega (omega . r) - r |omega|^2
    wr = (w * r).sum(axis=-1, keepdims=True)
    ww = (w * w).sum(axis=-1, keepdims=True)
    f_p = f + cross(wd, r) + w * wr - r * ww
    if not flexure:
        return w @ c_s_d, f_p @ c_s_d, None
    f_p = f_p + 2.0 * cross(w, thd @ r0_t) + thdd @ r0_t
    c_d_b, j_r = rotvec_to_dcm_and_jacobian(th)
    # [w, f_p] @ C_d_b in one batched product: rows (m, 2, 3)
    wf = np.stack([w, f_p], axis=1) @ c_d_b
    w_d = wf[:, 0, :] + (j_r @ thd[:, :, None])[:, :, 0]
    return w_d @ c_s_d, wf[:, 1, :] @ c_s_d, c_d_b


def slave_kinematics_ordered(
    w: np.ndarray,
    wd: np.ndarray,
    f: np.ndarray,
    th: np.ndarray,
    thd: np.ndarray,
    thdd: np.ndarray,
    r0: np.ndarray,
    r0_t: np.ndarray,
    c_s_d: np.ndarray,
    flexure: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`slave_kinematics` summed in a fixed order: the compiled step's twin.

    The same equations with every sum of products written in index order (:func:`vecmat`,
    :func:`matvec`, :func:`dot`: no BLAS, no FMA), the order of ``models/blocks/lever_arm.c``,
    so that the block's numpy path and its compiled step agree bit for bit. Meant for one
    step's nodes (the block); :func:`slave_kinematics` is the faster form for long stacks.

    The kinematics of the module docstring: ``r = r0 + R_0 theta``,
    ``f_p = f + omega' x r + omega x (omega x r) [+ 2 omega x R_0 theta' + R_0 theta'']``,
    resolved through ``C_d_b = exp([theta x])`` and the mounting ``C_s_d``.

    Parameters
    ----------
    w, wd, f : ndarray, shape (m, 3)
        Master rate [rad/s], angular acceleration [rad/s2] and specific force [m/s2],
        master body axes.
    th, thd, thdd : ndarray, shape (m, 3)
        Flexure angle [rad] and its first [rad/s] and second [rad/s2] derivatives.
    r0 : ndarray, shape (3,)
        Lever arm master -> slave, master body axes [m].
    r0_t : ndarray, shape (3, 3)
        ``R_0.T`` (:func:`r0_matrix` transposed) [m/rad].
    c_s_d : ndarray, shape (3, 3)
        Slave mounting ``C_s_d``.
    flexure : bool
        False for a rigid deck: the flexure terms (and ``C_d_b``) are left out.

    Returns
    -------
    w_s, f_s : ndarray, shape (m, 3)
        Slave rate w.r.t. inertial [rad/s] and specific force [m/s2], slave axes.
    c_d_b : ndarray, shape (m, 3, 3), or None for a rigid deck
    """
    r = r0 + vecmat(th, r0_t)
    # omega x (omega x r) = omega (omega . r) - r |omega|^2
    wr = dot(w, r)[..., None]
    ww = dot(w, w)[..., None]
    f_p = f + cross(wd, r) + w * wr - r * ww
    if not flexure:
        return vecmat(w, c_s_d), vecmat(f_p, c_s_d), None
    f_p = f_p + 2.0 * cross(w, vecmat(thd, r0_t)) + vecmat(thdd, r0_t)
    c_d_b, j_r = rotvec_to_dcm_and_jacobian(th)
    w_d = vecmat(w, c_d_b) + matvec(j_r, thd)
    return vecmat(w_d, c_s_d), vecmat(vecmat(f_p, c_d_b), c_s_d), c_d_b


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a . b`` along the last axis, summed in component order (``a0 b0 + a1 b1 + a2 b2``).

    Parameters
    ----------
    a, b : ndarray, shape (..., 3)
        Vectors in one frame.

    Returns
    -------
    ndarray, shape (...)
    """
    return _accumulate(a * b, axis=-1)[..., -1]  # sequential: ((p0 + p1) + p2)


def vecmat(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Row vectors times matrices, ``v @ m``, summed in index order (no BLAS, no FMA).

    The elementwise order is the compiled kernels' (``models/blocks/lever_arm.c``), so the
    numpy and compiled lever arms give the same numbers bit for bit.

    Parameters
    ----------
    v : ndarray, shape (..., 3)
        Row vectors.
    m : ndarray, shape (3, 3) or (..., 3, 3)
        Matrices (one for all vectors, or one per vector).

    Returns
    -------
    ndarray, shape (..., 3)
        ``sum_i v_i m_ij``; with ``v`` of shape (3, 3) and ``m`` (3, 3), the product of
        two matrices.
    """
    return _accumulate(v[..., :, None] * m, axis=-2)[..., -1, :]  # sequential over i


def matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrices times column vectors, ``m @ v``, summed in index order (see :func:`vecmat`).

    Parameters
    ----------
    m : ndarray, shape (3, 3) or (..., 3, 3)
        Matrices.
    v : ndarray, shape (..., 3)
        Vectors.

    Returns
    -------
    ndarray, shape (..., 3)
        ``sum_j m_ij v_j``.
    """
    return _accumulate(m * v[..., None, :], axis=-1)[..., -1]  # sequential over j


def combine(basis: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``basis @ rows`` summed column by column in order (see :func:`vecmat`).

    Parameters
    ----------
    basis : ndarray, shape (m, k)
        Basis functions at the nodes.
    rows : ndarray, shape (k, 3)
        Coefficient rows.

    Returns
    -------
    ndarray, shape (m, 3)
    """
    return _accumulate(basis[:, :, None] * rows[None, :, :], axis=1)[:, -1]  # sequential


class LeverArm(Block):
    """Slave IMU on a lever arm with deck flexure and mounting misalignment (seed 001).

    Attributes
    ----------
    compiled : bool
        True when this instance steps through the compiled kernel (set at initialisation,
        :func:`models.native.library`), False on the numpy path.
    """

    variables = (
        parameter("r0", (10.0, 10.0, 5.0), "m", "lever arm master -> slave, master body axes"),
        parameter("mount_rpy", (1.0 * DEG, 1.0 * DEG, 30.0 * DEG), "rad", "slave mounting C_s_d"),
        parameter("flexure", 1, description="1: use the flexure inputs, 0: rigid deck"),
        parameter("dt_truth", 1.0e-3, "s", "inner integration step"),
        *motion_inputs(
            ("omega_ib_b", "omega_dot_b", "f_b", "dtheta_b", "dv_b", "rpy", "v_n", "lat"), "master"
        ),
        input_("theta", (0.0, 0.0, 0.0), "rad", "flexure angle"),
        input_("theta_dot", (0.0, 0.0, 0.0), "rad/s", "flexure rate"),
        input_("theta_ddot", (0.0, 0.0, 0.0), "rad/s2", "flexure acceleration (step-mean noise)"),
        input_(
            "dtheta_flex",
            (0.0, 0.0, 0.0),
            "rad",
            "flexure angle change over THIS communication step [t, t+h] (depends on h)",
        ),
        input_(
            "dtheta_dot_flex",
            (0.0, 0.0, 0.0),
            "rad/s",
            "flexure rate change over THIS communication step [t, t+h] (depends on h)",
        ),
        output("omega_is_s", (0.0, 0.0, 0.0), "rad/s", "slave rate w.r.t. inertial, slave axes"),
        output("f_s", (0.0, 0.0, 0.0), "m/s2", "slave specific force, slave axes"),
        output("dtheta_s", (0.0, 0.0, 0.0), "rad", "integral of omega_is_s over the step"),
        output("dv_s", (0.0, 0.0, 0.0), "m/s", "integral of f_s over the step"),
        output("rpy_s", (0.0, 0.0, 0.0), "rad", "slave attitude (roll, pitch, yaw of C_s_n)"),
        output("v_n_s", (0.0, 0.0, 0.0), "m/s", "slave velocity, master NED axes"),
        output("r_p", (0.0, 0.0, 0.0), "m", "current lever arm r0 + R0 theta, master axes"),
    )
    default_stop = 2.0

    def initialize(self) -> None:
        if self.flexure not in (0, 1):
            raise ValueError(f"LeverArm.flexure must be 0 or 1, got {self.flexure}")
        self._r0 = np.asarray(self.r0, dtype=float).copy()
        self._R0 = r0_matrix(self._r0)
        self._R0T = self._R0.T.copy()
        self._c_s_d = euler_to_dcm(np.asarray(self.mount_rpy, dtype=float))
        # the slave kinematics of this block: (w, wd, f, th, thd, thdd) -> (w_s, f_s, C_d_b)
        self._slave = functools.partial(
            slave_kinematics_ordered,
            r0=self._r0,
            r0_t=self._R0T,
            c_s_d=self._c_s_d,
            flexure=bool(self.flexure),
        )
        self._nodes: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, int]] = {}
        self._lib = native.library()
        self.compiled = self._lib is not None
        if self._lib is not None:
            self._initialize_native()
            return
        self._w_path = StepPath()
        self._w_path.reset(self.start_time, self.omega_ib_b, self.omega_dot_b)
        self._f_path = StepPath()
        self._f_path.reset(self.start_time, self.f_b)
        self._publish_end()
        self.dtheta_s = np.zeros(3)
        self.dv_s = np.zeros(3)

    def _initialize_native(self) -> None:
        """Buffers and parameters of the compiled step (layouts: ``models/blocks/lever_arm.c``)."""
        self._par = np.concatenate(
            [
                self._r0,
                self._R0.ravel(),
                self._c_s_d.ravel(),
                [float(self.flexure), StepPath().rel_tol, OMEGA_IE, float(self.dt_truth)],
            ]
        )
        self._st = np.zeros(14)  # both paths start at the start time from the inputs
        self._st[0:2] = (1.0, self.start_time)
        self._st[2:5] = np.asarray(self.omega_ib_b, dtype=float)
        self._st[5] = 1.0
        self._st[6:9] = np.asarray(self.omega_dot_b, dtype=float)
        self._st[9:11] = (1.0, self.start_time)
        self._st[11:14] = np.asarray(self.f_b, dtype=float)
        self._io = native.Buffers(self, NATIVE_INPUTS, NATIVE_OUTPUTS)
        self._par_ptr = native.pointer(self._par)
        self._st_ptr = native.pointer(self._st)
        self._native_step = self._lib.lever_arm_step
        io = self._io
        self._lib.lever_arm_publish(
            self._par_ptr, io.input_pointer(), float(self.lat), io.output_pointer()
        )
        io.publish()

    def _flex_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.flexure:
            return np.zeros(3), np.zeros(3), np.zeros(3)
        return (
            np.asarray(self.theta, dtype=float),
            np.asarray(self.theta_dot, dtype=float),
            np.asarray(self.theta_ddot, dtype=float),
        )

    def _publish_end(self) -> None:
        """Outputs at the time of the current inputs (used at initialisation)."""
        th, thd, thdd = self._flex_inputs()
        w_s, f_s, c_d_b = self._slave(
            np.asarray(self.omega_ib_b, dtype=float)[None, :],
            np.asarray(self.omega_dot_b, dtype=float)[None, :],
            np.asarray(self.f_b, dtype=float)[None, :],
            th[None, :],
            thd[None, :],
            thdd[None, :],
        )
        self._finish(w_s[0], f_s[0], th, thd, None if c_d_b is None else c_d_b[0])

    def _finish(
        self,
        w_s: np.ndarray,
        f_s: np.ndarray,
        th: np.ndarray,
        thd: np.ndarray,
        c_d_b: np.ndarray | None,
    ) -> None:
        """Set the step-end outputs from the slave rate and force and the flexure state."""
        self.omega_is_s = w_s.copy()
        self.f_s = f_s.copy()
        c_b_n = euler_to_dcm_3(self.rpy)
        c_s_b = self._c_s_d if c_d_b is None else vecmat(c_d_b, self._c_s_d)
        self.rpy_s = dcm_to_euler_3(vecmat(c_b_n, c_s_b))
        self.r_p = self._r0 + matvec(self._R0, th)
        lat = float(self.lat)
        w_ie = np.array([OMEGA_IE * math.cos(lat), 0.0, -OMEGA_IE * math.sin(lat)])
        w_eb = np.asarray(self.omega_ib_b, dtype=float) - vecmat(w_ie, c_b_n)
        self.v_n_s = np.asarray(self.v_n, dtype=float) + matvec(
            c_b_n, cross(w_eb, self.r_p) + matvec(self._R0, thd)
        )

    def _step_basis(self, h: float) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """Simpson nodes and weights of the step, and the paths' bases at the nodes (cached).

        Returns
        -------
        s, wts : ndarray, shape (m,)
            Nodes in [0, 1] and weights (sum 1).
        bases : tuple of ndarray
            ``quartic, quartic_d`` (m, 5), ``quadratic`` (m, 3) and the Hermite ``b0, b1,
            b2`` (m, 4) (:func:`models.step_paths.path_basis`, :func:`hermite_basis`).
        """
        n = substeps(h, self.dt_truth)
        entry = self._nodes.get(n)
        if entry is None:
            s, wts = simpson_nodes(n)
            quartic, quartic_d, quadratic, _ = path_basis(s)
            entry = self._nodes[n] = (s, wts, (quartic, quartic_d, quadratic, *hermite_basis(s)))
        return entry

    def step(self, t: float, h: float) -> None:
        if self._lib is not None:
            io = self._io
            self._native_step(
                self._par_ptr,
                self._st_ptr,
                io.input_pointer(),
                float(self.lat),
                io.output_pointer(),
                t,
                h,
            )
            io.publish()
            return
        s, wts, (quartic, quartic_d, quadratic, b0, b1, b2) = self._step_basis(h)
        cw = self._w_path.coefficients(t, h, self.omega_ib_b, self.dtheta_b, self.omega_dot_b)
        cf = self._f_path.coefficients(t, h, self.f_b, self.dv_b)
        if cw is None:  # no valid start: memoryless quadratic
            w, wd = step_quadratic(self.omega_ib_b, self.omega_dot_b, self.dtheta_b, h, s)
        else:
            w, wd = combine(quartic, cw), combine(quartic_d, cw) / h
        if cf is None:
            f, _ = step_linear(self.f_b, self.dv_b, h, s)
        else:
            f = combine(quadratic, cf)
        if self.flexure:
            th1 = np.asarray(self.theta, dtype=float)
            thd1 = np.asarray(self.theta_dot, dtype=float)
            th0 = th1 - np.asarray(self.dtheta_flex, dtype=float)
            thd0 = thd1 - np.asarray(self.dtheta_dot_flex, dtype=float)
            cth = np.array([th0, thd0 * h, th1, thd1 * h])
            th = combine(b0, cth)
            thd = combine(b1, cth) / h
            thdd = combine(b2, cth) / (h * h)
        else:
            th = thd = thdd = np.zeros_like(w)
        w_s, f_s, c_d_b = self._slave(w, wd, f, th, thd, thdd)
        # Simpson sums in node order (cumsum is sequential, as the compiled step)
        sums = h * _accumulate(wts[:, None] * np.hstack([w_s, f_s]), axis=0)[-1]
        self.dtheta_s = sums[0:3]
        self.dv_s = sums[3:6]
        # Step end: the path's end node equals the inputs except theta'', which is the
        # DeckFlexure's theta_ddot (step-mean noise) rather than the Hermite end slope.
        f_end = f_s[-1]
        if c_d_b is None:
            self._finish(w_s[-1], f_end, np.zeros(3), np.zeros(3), None)
            return
        d_acc = np.asarray(self.theta_ddot, dtype=float) - thdd[-1]
        f_end = f_end + vecmat(vecmat(matvec(self._R0, d_acc), c_d_b[-1]), self._c_s_d)
        self._finish(w_s[-1], f_end, th1, thd1, c_d_b[-1])


#: Running sums in element order (``np.cumsum`` without its wrapper): the fixed summation
#: order that the compiled kernels repeat.
_accumulate = np.add.accumulate

#: The compiled step's vector inputs and outputs, in its layout (declaration order).
NATIVE_INPUTS = (
    "omega_ib_b",
    "omega_dot_b",
    "f_b",
    "dtheta_b",
    "dv_b",
    "rpy",
    "v_n",
    "theta",
    "theta_dot",
    "theta_ddot",
    "dtheta_flex",
    "dtheta_dot_flex",
)
NATIVE_OUTPUTS = ("omega_is_s", "f_s", "dtheta_s", "dv_s", "rpy_s", "v_n_s", "r_p")
