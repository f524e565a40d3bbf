"""The transfer-alignment truth and sensor chain as one vectorised numpy program.

Reference for the benchmarks: the chain of ``benchmarks/transfer_chain.toml`` (moored
ship -> deck flexure -> lever arm -> slave strapdown IMU, seed 001) computed over the
whole run at once, with whole-array numpy instead of one call per block per macro
step. It reproduces every output of the co-simulation (Gauss-Seidel, every block at
rate 1) from the same parameters and seeds; ``tests/benchmarks/test_monolithic.py`` checks the
agreement to 1e-9.

How each block becomes whole-array code (``N`` macro steps of ``h``, ``t_n = t0 + n h``,
``m = 2 round(h / dt_truth) + 1`` Simpson nodes per step):

- **ShipMotion** is closed form in time: its truth is evaluated at the ``N m`` node
  times ``t_n + h s_j`` in one call and the Simpson sums are one contraction.
- **DeckFlexure** is the linear recursion ``x_{n+1} = M x_n + R w_n`` per axis
  (``x = [I, theta, theta']``, ``M`` the exact transition with the integral's column
  zeroed since ``I`` restarts at each step). It is solved for all ``n`` with a
  doubling prefix scan (:func:`affine_scan`, ``log2 N`` whole-array passes).
- **LeverArm** rebuilds each step's inputs from step-end values and increments
  (quartic rate path, quadratic specific-force path, cubic Hermite flexure path, as
  :class:`models.step_paths.StepPath` does): every step's nodes are built at once,
  the slave kinematics evaluated on all ``N m`` nodes, the Simpson sums contracted.
- **StrapdownImu**: the Gauss-Markov bias is a first-order recursion (``lfilter``),
  the random walk a cumulative sum, everything else elementwise.

Random numbers: each block owns ``numpy.random.default_rng(seed)`` and draws, as the
blocks do, its initial block of normals and then one block per step; drawing the
``N`` step blocks in one call gives the same numbers in the same order.
Quantisation (``*_lsb > 0``) is not reproduced (it is a sequential residual
recursion); :func:`simulate` refuses it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import lfilter

from cosim.models.blocks.deck_flexure import discretize_flexure, noise_factor
from cosim.models.blocks.lever_arm import r0_matrix, slave_kinematics
from cosim.models.blocks.strapdown_imu import bias_step_coefficients, resolve_parameters
from cosim.models.conventions import cross, dcm_to_euler, euler_to_dcm, wrap_angle
from cosim.models.earth import euler_motion_truth, omega_ie_n
from cosim.models.step_paths import simpson_nodes, substeps

HERE = Path(__file__).resolve().parent
#: The chain's scenario file.
CHAIN_SCENARIO = HERE / "transfer_chain.toml"
#: Block name -> model class name, as in the scenario file.
CHAIN_BLOCKS = {
    "ship": "ShipMotion",
    "flexure": "DeckFlexure",
    "lever": "LeverArm",
    "imu": "StrapdownImu",
}


@dataclass
class ChainParameters:
    """Everything the chain needs, in SI units.

    Attributes
    ----------
    step : float
        Macro step h [s].
    start, stop : float
        Start and stop time [s]; ``stop - start`` is a whole number of steps.
    blocks : dict
        Block name (``ship``, ``flexure``, ``lever``, ``imu``) -> ``{parameter: value}``,
        every parameter of the model (defaults filled in); vectors as float arrays of
        shape (n,).
    """

    step: float
    start: float
    stop: float
    blocks: dict[str, dict[str, Any]]

    @property
    def n_steps(self) -> int:
        """Number of macro steps."""
        return int(round((self.stop - self.start) / self.step))


def chain_parameters(
    scenario: Any = CHAIN_SCENARIO, names: dict[str, str] | None = None
) -> ChainParameters:
    """Read the chain's parameters from its scenario (units converted by the loader).

    Parameters
    ----------
    scenario : str, Path or cosim.Scenario
        A scenario with the blocks of :data:`CHAIN_BLOCKS` (in-process models), or the
        path of its file.
    names : dict, optional
        Chain role (a key of :data:`CHAIN_BLOCKS`) -> the block's name in the scenario,
        for a scenario that names them otherwise (e.g. ``{"flexure": "flex"}``); roles
        not given keep their own name. The scenario's other blocks are returned under
        their own names.

    Returns
    -------
    ChainParameters
        Master step, start, stop and every block parameter (model defaults for the
        ones the file does not set).

    Raises
    ------
    ValueError
        A block is missing, is not the expected model, or steps at a rate other than 1.
    """
    import cosim

    sc = scenario if isinstance(scenario, cosim.Scenario) else cosim.load_scenario(scenario)
    role_of = {(names or {}).get(role, role): role for role in CHAIN_BLOCKS}
    for role, model in CHAIN_BLOCKS.items():
        name = (names or {}).get(role, role)
        spec = sc.blocks.get(name)
        if spec is None or spec.kind != "model" or spec.source != model:
            raise ValueError(f"{sc.path}: expected block '{name}' with model = '{model}'")
        if spec.rate != 1:
            raise ValueError(f"{sc.path}: block '{name}' must step at rate 1, got {spec.rate}")
    if sc.settings.coupling != "gauss-seidel":
        raise ValueError(f"{sc.path}: the monolithic chain reproduces Gauss-Seidel coupling")
    system, _ = sc.build()
    try:
        blocks = {}
        for name, host in system.blocks.items():
            scalars = {v.name: v.start for v in host.by_causality("parameter")}
            scalars.update(system.parameters.get(name, {}))
            blocks[role_of.get(name, name)] = _vectors(scalars)
    finally:
        for host in system.blocks.values():
            host.terminate()
    s = sc.settings
    return ChainParameters(step=s.step, start=s.start, stop=s.stop, blocks=blocks)


def _vectors(scalars: dict[str, Any]) -> dict[str, Any]:
    """FMI scalars ``x[1]``, ``x[2]``, ... gathered into float arrays ``x``."""
    out: dict[str, Any] = {}
    elements: dict[str, dict[int, float]] = {}
    for name, value in scalars.items():
        if name.endswith("]") and "[" in name:
            base, index = name[:-1].split("[")
            elements.setdefault(base, {})[int(index)] = float(value)
        else:
            out[name] = value
    for base, values in elements.items():
        out[base] = np.array([values[i] for i in range(1, len(values) + 1)])
    return out


def affine_scan(m: np.ndarray, c: np.ndarray) -> np.ndarray:
    """All states of ``x_k = M_a x_{k-1} + c_k`` (``x_{-1} = 0``) by a doubling prefix scan.

    ``x_k = sum_{j <= k} M^(k - j) c_j``: after pass ``l`` each entry holds the sum over
    the last ``2^l`` terms, so ``ceil(log2 K)`` whole-array passes give every state.

    Parameters
    ----------
    m : ndarray, shape (a, d, d)
        Transition per channel ``a`` (constant over k).
    c : ndarray, shape (K, a, d)
        Inputs; put the initial state in ``c[0]``.

    Returns
    -------
    ndarray, shape (K, a, d)
        ``x_0 .. x_{K-1}``.
    """
    x = np.array(c, dtype=float)
    power = np.array(m, dtype=float)
    shift = 1
    while shift < len(x):
        x[shift:] = x[shift:] + np.einsum("aij,kaj->kai", power, x[:-shift])
        power = power @ power
        shift *= 2
    return x


# ----------------------------------------------------------------------------- blocks
def _ship_truth(p: dict[str, Any]) -> Any:
    """ShipMotion's closed-form truth as a function of the instants ``tt`` (m,).

    Returns a function giving ``(ImuTruth, rpy (m, 3) [rad], v_n (m, 3) [m/s])``.
    """
    period = np.asarray(p["period"], dtype=float)
    w = np.where(period > 0.0, 2.0 * np.pi / np.where(period > 0.0, period, 1.0), 0.0)
    amp = np.where(period > 0.0, np.asarray(p["amp"], dtype=float), 0.0)
    lper = np.asarray(p["lin_period"], dtype=float)
    wl = np.where(lper > 0.0, 2.0 * np.pi / np.where(lper > 0.0, lper, 1.0), 0.0)
    lamp = np.where(lper > 0.0, np.asarray(p["lin_amp"], dtype=float), 0.0)
    moving = bool(np.any(lamp != 0.0))
    yaw0 = float(p["rpy_mean"][2])
    c_l_n = np.array(
        [[math.cos(yaw0), -math.sin(yaw0), 0.0], [math.sin(yaw0), math.cos(yaw0), 0.0], [0, 0, 1]]
    )
    ref = (float(p["lat0"]), float(p["lon0"]), float(p["h0"]))

    def truth(tt: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray]:
        arg = tt[:, None] * w + np.asarray(p["phase"])
        sa, ca = np.sin(arg), np.cos(arg)
        rpy = np.asarray(p["rpy_mean"]) + amp * sa
        rpy_dot = amp * w * ca
        rpy_ddot = -amp * w**2 * sa
        if not moving:
            tr = euler_motion_truth(rpy, rpy_dot, rpy_ddot, None, None, None, *ref)
            return tr, rpy, np.zeros_like(rpy)
        argl = tt[:, None] * wl + np.asarray(p["lin_phase"])
        sl, cl = np.sin(argl), np.cos(argl)
        d_n = (lamp * sl) @ c_l_n.T
        v_n = (lamp * wl * cl) @ c_l_n.T
        a_n = (-lamp * wl**2 * sl) @ c_l_n.T
        return euler_motion_truth(rpy, rpy_dot, rpy_ddot, d_n, v_n, a_n, *ref), rpy, v_n

    return truth


def _ship(
    p: dict[str, Any], truth: Any, t0: float, h: float, n0: int, n1: int
) -> dict[str, np.ndarray]:
    """ShipMotion outputs at the ends of steps ``n0 .. n1 - 1`` (rows n0 + 1 .. n1).

    With ``n0 == n1`` the outputs at t0 instead (one row, zero increments). Arrays
    (rows, 3) or (rows,).
    """
    s, wts = simpson_nodes(substeps(h, float(p["dt_truth"])))
    m = len(s)
    k = n1 - n0
    if k == 0:
        tt, end = np.array([t0]), np.array([0])
    else:
        t_begin = t0 + np.arange(n0, n1) * h  # the master's t_n = t0 + n h
        tt, end = (t_begin[:, None] + h * s).ravel(), np.arange(1, k + 1) * m - 1
    tr, rpy, v_n = truth(tt)
    out = {
        "rpy": rpy[end],
        "v_n": v_n[end],
        "lat": tr.lat[end],
        "lon": tr.lon[end],
        "h": tr.h[end],
        "omega_ib_b": tr.omega_ib_b[end],
        "omega_dot_b": tr.omega_dot_b[end],
        "f_b": tr.f_b[end],
    }
    yaw = out["rpy"][:, 2]
    turns = np.rint(yaw / (2.0 * math.pi))  # math.remainder(yaw, 2 pi), elementwise
    out["rpy"][:, 2] = np.where(turns == 0.0, yaw, yaw - turns * (2.0 * math.pi))
    for name, src in (("dtheta_b", tr.omega_ib_b), ("dv_b", tr.f_b)):
        if k == 0:
            out[name] = np.zeros((1, 3))
        else:
            out[name] = h * np.einsum("j,njk->nk", wts, src.reshape(k, m, 3))
    return out


def _flexure(p: dict[str, Any], h: float, n_steps: int) -> dict[str, np.ndarray]:
    """DeckFlexure outputs at t0 and every step end, arrays (N + 1, 3)."""
    tau = np.asarray(p["tau"], dtype=float)
    sig = np.asarray(p["sigma"], dtype=float)
    beta = 2.146 / tau
    q = 4.0 * beta**3 * sig**2
    rng = np.random.default_rng(int(p["seed"]))
    z = rng.standard_normal((2, 3))
    noise = rng.standard_normal((n_steps, 3, 3))  # (step, axis, component)
    phis, roots = [], []
    for b, qq in zip(beta, q, strict=True):
        phi, qd = discretize_flexure(float(b), float(qq), h)
        phis.append(phi)
        roots.append(noise_factor(qd))
    trans = np.array(phis)
    trans[:, :, 0] = 0.0  # the integral I restarts at 0 in every step
    c = np.empty((n_steps + 1, 3, 3))
    c[0] = np.stack([np.zeros(3), sig * z[0], beta * sig * z[1]], axis=-1)
    c[1:] = np.einsum("aij,naj->nai", np.array(roots), noise)
    x = affine_scan(trans, c)
    theta, theta_dot = x[:, :, 1], x[:, :, 2]
    d_theta = np.zeros_like(theta)
    d_theta_dot = np.zeros_like(theta)
    d_theta[1:] = theta[1:] - theta[:-1]
    d_theta_dot[1:] = theta_dot[1:] - theta_dot[:-1]
    eta = np.zeros_like(theta)
    eta[1:] = (d_theta_dot[1:] + 2.0 * beta * d_theta[1:] + beta**2 * x[1:, :, 0]) / h
    theta_ddot = -2.0 * beta * theta_dot - beta**2 * theta + eta
    theta_ddot[0] = -2.0 * beta * theta_dot[0] - beta**2 * theta[0]
    return {
        "theta": theta,
        "theta_dot": theta_dot,
        "theta_ddot": theta_ddot,
        "eta": eta,
        "dtheta_flex": d_theta,
        "dtheta_dot_flex": d_theta_dot,
    }


def _norm(x: np.ndarray) -> np.ndarray:
    """Euclidean norms along the last axis."""
    return np.sqrt(np.sum(x * x, axis=-1))


def _lever(
    p: dict[str, Any],
    ship: dict[str, np.ndarray],
    flex: dict[str, np.ndarray],
    h: float,
    n_steps: int,
    rel_tol: float = 1e-2,
) -> dict[str, np.ndarray]:
    """LeverArm outputs from the inputs' rows 0 .. N (N steps), arrays (N + 1, 3).

    Row 0 holds the kinematics at the inputs' first row (its increments are zero: they
    belong to the step before), row n the outputs at the end of step n.
    """
    flexure = int(p["flexure"]) == 1
    r0 = np.asarray(p["r0"], dtype=float)
    r0m = r0_matrix(r0)
    c_s_d = euler_to_dcm(np.asarray(p["mount_rpy"], dtype=float))
    s, wts = simpson_nodes(substeps(h, float(p["dt_truth"])))
    m = len(s)
    u = s[None, :, None]  # (1, m, 1): broadcast over steps and axes

    # Rate: quartic through the previous and current step-end rate and its derivative,
    # integrating to dtheta_b (else the memoryless quadratic).
    x0, x1 = ship["omega_ib_b"][:-1, None, :], ship["omega_ib_b"][1:, None, :]
    m0, m1 = ship["omega_dot_b"][:-1, None, :] * h, ship["omega_dot_b"][1:, None, :] * h
    mean = ship["dtheta_b"][1:, None, :] / h
    mismatch = mean - (0.5 * (x0 + x1) + (m0 - m1) / 12.0)
    ok = _norm(mismatch) <= rel_tol * (_norm(x0) + _norm(x1) + _norm(m0) + _norm(m1)) + 1e-300
    b0, b1 = _hermite(u)
    c30 = 30.0 * mismatch
    bump = u * (1.0 - u)
    w = b0[0] * x0 + b0[1] * m0 + b0[2] * x1 + b0[3] * m1 + c30 * bump**2
    wd = (b1[0] * x0 + b1[1] * m0 + b1[2] * x1 + b1[3] * m1) / h + c30 * (
        2.0 * bump * (1.0 - 2.0 * u)
    ) / h
    if not np.all(ok):  # step_quadratic where the stored start does not fit
        c = 3.0 * (mean - x1 + 0.5 * m1)
        v = u - 1.0
        w = np.where(ok[:, :, None], w, x1 + m1 * v + c * v * v)
        wd = np.where(ok[:, :, None], wd, (m1 + 2.0 * c * v) / h)

    # Specific force: quadratic through the previous and current f_b integrating to dv_b.
    f0, f1 = ship["f_b"][:-1, None, :], ship["f_b"][1:, None, :]
    fmean = ship["dv_b"][1:, None, :] / h
    cf = fmean - 0.5 * (f0 + f1)
    okf = _norm(cf) <= rel_tol * (_norm(f0) + _norm(f1)) + 1e-300
    f = f0 + (f1 - f0) * u + 6.0 * cf * u * (1.0 - u)
    if not np.all(okf):  # step_linear
        f = np.where(okf[:, :, None], f, f1 + 2.0 * (f1 - fmean) * (u - 1.0))

    # Flexure: cubic Hermite through theta, theta' at both ends of the step.
    if flexure:
        th1, thd1 = flex["theta"][1:, None, :], flex["theta_dot"][1:, None, :]
        th0 = th1 - flex["dtheta_flex"][1:, None, :]
        thd0 = thd1 - flex["dtheta_dot_flex"][1:, None, :]
        b2 = np.stack([12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2])
        coef = (th0, thd0 * h, th1, thd1 * h)
        th = sum(b0[i] * coef[i] for i in range(4))
        thd = sum(b1[i] * coef[i] for i in range(4)) / h
        thdd = sum(b2[i] * coef[i] for i in range(4)) / (h * h)
    else:
        th = thd = thdd = np.zeros_like(w)

    k = n_steps * m
    w_s, f_s, _ = slave_kinematics(
        w.reshape(k, 3),
        wd.reshape(k, 3),
        f.reshape(k, 3),
        th.reshape(k, 3),
        thd.reshape(k, 3),
        thdd.reshape(k, 3),
        r0,
        r0m.T,
        c_s_d,
        flexure,
    )
    out = {}
    for name, x in (("dtheta_s", w_s), ("dv_s", f_s)):
        inc = np.zeros((n_steps + 1, 3))
        inc[1:] = h * np.einsum("j,njk->nk", wts, x.reshape(n_steps, m, 3))
        out[name] = inc

    # Step-end outputs (and t0): the kinematics at the inputs' step-end values.
    zero = np.zeros_like(flex["theta"])
    th_e = flex["theta"] if flexure else zero
    thd_e = flex["theta_dot"] if flexure else zero
    thdd_e = flex["theta_ddot"] if flexure else zero
    w_e, f_e, c_d_b = slave_kinematics(
        ship["omega_ib_b"],
        ship["omega_dot_b"],
        ship["f_b"],
        th_e,
        thd_e,
        thdd_e,
        r0,
        r0m.T,
        c_s_d,
        True,
    )
    c_b_n = euler_to_dcm(ship["rpy"])
    r_p = r0 + th_e @ r0m.T
    w_eb = ship["omega_ib_b"] - np.einsum("nji,nj->ni", c_b_n, omega_ie_n(ship["lat"]))
    out["omega_is_s"] = w_e
    out["f_s"] = f_e
    out["rpy_s"] = dcm_to_euler(c_b_n @ c_d_b @ c_s_d)
    out["v_n_s"] = ship["v_n"] + np.einsum("nij,nj->ni", c_b_n, cross(w_eb, r_p) + thd_e @ r0m.T)
    out["r_p"] = r_p
    return out


def _hermite(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite basis (values, first derivatives in u) at ``u``, each (4, *u.shape)."""
    u2, u3 = u * u, u * u * u
    b0 = np.stack([2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2])
    b1 = np.stack([6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u])
    return b0, b1


def _imu(
    p: dict[str, Any], d_theta: np.ndarray, d_v: np.ndarray, h: float, n_steps: int
) -> dict[str, np.ndarray]:
    """StrapdownImu outputs at t0 and every step end from the true increments (N + 1, 3)."""
    res = resolve_parameters(p)
    if res["gyro_lsb"] > 0.0 or res["accel_lsb"] > 0.0:
        raise ValueError("the monolithic reference does not model quantisation (*_lsb > 0)")
    rng = np.random.default_rng(int(p["seed"]))
    z0 = rng.standard_normal((2, 18))
    z = rng.standard_normal((n_steps, 2, 5, 3))  # (step, triad, white/gm/gm/rw/rw, axis)
    off = ~np.eye(3, dtype=bool)
    const = np.empty((2, 3))
    err = np.empty((2, 3, 3))
    gm0 = np.empty((2, 3))
    for s, pre in enumerate(("gyro", "accel")):
        const[s] = np.asarray(p[f"{pre}_bias"]) + res[f"{pre}_bias_sigma"] * z0[s, 0:3]
        sf = np.asarray(p[f"{pre}_sf"]) + res[f"{pre}_sf_sigma"] * z0[s, 3:6]
        m_fix = np.asarray(p[f"{pre}_misalignment"]).reshape(3, 3)
        m_on = np.where(off, res[f"{pre}_misalignment_sigma"] * z0[s, 6:15].reshape(3, 3), 0.0)
        err[s] = np.diag(sf) + m_fix + m_on
        gm0[s] = res[f"{pre}_bi_sigma"] * z0[s, 15:18]

    bias_int = np.empty((n_steps, 2, 3))
    for s, pre in enumerate(("gyro", "accel")):
        (phi, g, l11, l21, l22), (r11, r21, r22) = bias_step_coefficients(
            res[f"{pre}_bi_sigma"], res[f"{pre}_bi_tau"], res[f"{pre}_rrw"], h
        )
        zs = z[:, s]
        # Gauss-Markov state at each step start: gm_{n+1} = phi gm_n + l11 z1_n
        after = lfilter([1.0], [1.0, -phi], l11 * zs[:, 1], axis=0, zi=(phi * gm0[s])[None, :])[0]
        gm = np.concatenate([gm0[s][None, :], after[:-1]])
        rw_after = np.cumsum(r11 * zs[:, 3], axis=0)  # rw_0 = 0
        rw = np.concatenate([np.zeros((1, 3)), rw_after[:-1]])
        gm_int = g * gm + l21 * zs[:, 1] + l22 * zs[:, 2]
        rw_int = h * rw + r21 * zs[:, 3] + r22 * zs[:, 4]
        bias_int[:, s] = const[s] * h + gm_int + rw_int

    white_h = np.array([res["gyro_arw_effective"], res["accel_vrw"]]) * math.sqrt(h)
    d_true = np.stack([d_theta[1:], d_v[1:]], axis=1)  # (N, 2, 3)
    y = d_true + np.einsum("sij,nsj->nsi", err, d_true) + bias_int + white_h[:, None] * z[:, :, 0]
    out = {}
    for name, values in (
        ("dtheta_meas_b", y[:, 0]),
        ("dv_meas_b", y[:, 1]),
        ("omega_meas_b", y[:, 0] / h),
        ("f_meas_b", y[:, 1] / h),
        ("gyro_bias_b", bias_int[:, 0] / h),
        ("accel_bias_b", bias_int[:, 1] / h),
    ):
        arr = np.zeros((n_steps + 1, 3))
        arr[1:] = values
        out[name] = arr
    out["gyro_bias_b"][0] = const[0] + gm0[0]
    out["accel_bias_b"][0] = const[1] + gm0[1]
    return out


#: Truth nodes per whole-array call of the kinematics (arrays of ~250 kB each: they stay
#: in the processor's cache).
BLOCK_NODES = 10500


def simulate(
    params: ChainParameters, stop: float | None = None, block_steps: int | None = None
) -> dict[str, np.ndarray]:
    """Run the whole chain at once.

    Parameters
    ----------
    params : ChainParameters
        From :func:`chain_parameters`.
    stop : float, optional
        Stop time [s] instead of ``params.stop`` (a whole number of steps after start).
    block_steps : int, optional
        The ship and lever-arm kinematics are evaluated ``block_steps`` macro steps at a
        time (whole-array code on arrays that stay in the processor's cache; one array
        per run is up to three times slower). Default: about :data:`BLOCK_NODES` truth
        nodes per call (500 steps of 21 nodes at 10 ms, 104 of 101 nodes at 50 ms).

    Returns
    -------
    dict
        ``"time"`` (N + 1,) [s], then ``"block.output"`` for every output of the four
        blocks, as the co-simulation records them: row 0 at t0, row n at ``t0 + n h``;
        vectors (N + 1, 3), scalars (N + 1,). SI units, frames as in the models
        (``ship.*`` master body / NED, ``lever.*_s`` slave axes, ``imu.*`` IMU axes).
    """
    h, t0 = params.step, params.start
    n_steps = int(round(((params.stop if stop is None else stop) - t0) / h))
    b = params.blocks
    if block_steps is None:
        nodes = 2 * substeps(h, float(b["ship"]["dt_truth"])) + 1
        block_steps = max(1, BLOCK_NODES // nodes)
    flex = _flexure(b["flexure"], h, n_steps)
    truth = _ship_truth(b["ship"])
    first = _ship(b["ship"], truth, t0, h, 0, 0)
    ship = {k: np.empty((n_steps + 1,) + v.shape[1:]) for k, v in first.items()}
    lever: dict[str, np.ndarray] = {}
    for k, v in first.items():
        ship[k][0] = v[0]
    for n0 in range(0, n_steps, block_steps):
        n1 = min(n0 + block_steps, n_steps)
        for k, v in _ship(b["ship"], truth, t0, h, n0, n1).items():
            ship[k][n0 + 1 : n1 + 1] = v
        part = _lever(
            b["lever"],
            {k: v[n0 : n1 + 1] for k, v in ship.items()},
            {k: v[n0 : n1 + 1] for k, v in flex.items()},
            h,
            n1 - n0,
        )
        skip = 0 if n0 == 0 else 1  # row n0 (increments included) came with the block before
        for k, v in part.items():
            if k not in lever:
                lever[k] = np.empty((n_steps + 1,) + v.shape[1:])
            lever[k][n0 + skip : n1 + 1] = v[skip:]
    imu = _imu(b["imu"], lever["dtheta_s"], lever["dv_s"], h, n_steps)
    out = {"time": t0 + np.arange(n_steps + 1) * h}
    for block, values in (("ship", ship), ("flexure", flex), ("lever", lever), ("imu", imu)):
        for name, arr in values.items():
            out[f"{block}.{name}"] = arr
    return out


def master_ins(p: dict[str, Any], ship: dict[str, np.ndarray], h: float) -> dict[str, np.ndarray]:
    """MasterIns outputs at t0 and every step end from the ship's true outputs.

    The same draws in the same order as :class:`models.blocks.master_ins.MasterIns` (6 normals
    at initialisation, 6 per step, drawn here in one call); zero latency only (the
    delay line is a sequential buffer).

    Parameters
    ----------
    p : dict
        The MasterIns block's parameters (SI).
    ship : dict
        ``"ship.v_n"`` (N + 1, 3) [m/s, NED], ``"ship.rpy"`` (N + 1, 3) [rad],
        ``"ship.lat"``, ``"ship.lon"`` [rad], ``"ship.h"`` [m] (N + 1,), as
        :func:`simulate` returns them.
    h : float
        Macro step [s].

    Returns
    -------
    dict
        ``v_master_n``, ``rpy_master`` (N + 1, 3); ``lat_master``, ``lon_master``,
        ``h_master`` (N + 1,).

    Raises
    ------
    ValueError
        A latency other than zero.
    """
    if float(p["latency"]) != 0.0:
        raise ValueError("the monolithic reference models MasterIns without latency only")
    v_n, rpy = ship["ship.v_n"], ship["ship.rpy"]
    n_steps = len(v_n) - 1
    rng = np.random.default_rng(int(p["seed"]))
    z0 = rng.standard_normal(6)
    z = rng.standard_normal((n_steps, 6))
    delta = np.asarray(p["attitude_error"], float) + float(p["attitude_error_sigma"]) * z0[:3]
    sigma_gm = float(p["velocity_gm_sigma"])
    gm = np.empty((n_steps + 1, 3))
    gm[0] = sigma_gm * z0[3:]
    if sigma_gm > 0.0:
        x_h = h / float(p["velocity_gm_tau"])
        gain = sigma_gm * math.sqrt(-math.expm1(-2.0 * x_h))
        for n in range(n_steps):  # gm_{n+1} = a gm_n + gain z_n (the block's order)
            gm[n + 1] = math.exp(-x_h) * gm[n] + gain * z[n, :3]
    else:
        gm[1:] = gm[0]
    white = np.zeros((n_steps + 1, 3))
    white[1:] = float(p["velocity_noise_std"]) * z[:, 3:]
    rpy_m = rpy + delta
    rpy_m[:, 0] = wrap_angle(rpy_m[:, 0])
    rpy_m[:, 2] = wrap_angle(rpy_m[:, 2])
    return {
        "v_master_n": v_n + gm + white,
        "rpy_master": rpy_m,
        "lat_master": np.asarray(ship["ship.lat"], float),
        "lon_master": np.asarray(wrap_angle(ship["ship.lon"]), float),
        "h_master": np.asarray(ship["ship.h"], float),
    }
