"""The transfer-alignment block's compiled period kernels (``cosim/alignment/transfer_master.c``).

``transfer_master_state`` (the master's attitude, rate w.r.t. the earth and velocity fed
to the filter at every period) and ``transfer_period`` (what changes with the shown
covariance: ``P_att``, its inverse, the flexure, bias and drift outputs) against their
numpy statements :meth:`TransferAlignment.master_state_numpy` and
:meth:`~TransferAlignment.period_numpy`: on the same state at every period of a real
co-simulation of ``scenarios/transfer_alignment.toml`` shortened to 15 s (both stages), on
histories of 1 to 5 attitudes from that run (the 2- and 3-point formulas, the ring's
every rotation), and whole runs with and without the compiled kernels.
"""

from __future__ import annotations

import numpy as np
import pytest
from transfer_run import align_block, needs_library, runs_both_ways, short_master

from cosim.alignment.nav import nav_rates
from cosim.alignment.transfer import HISTORY, PERIOD_OUTPUTS, TransferAlignment
from cosim.alignment.transfer_model import master_rate
from cosim.models import native
from cosim.models.constants import ARCMIN, E2, A
from cosim.models.conventions import euler_to_dcm_3

STOP = 15.0  # the acquisition ends at 5 s at the earliest: both stages run
RTOL = 1e-12
EPS = np.finfo(float).eps
H = 0.02  # the scenario's macro step [s]
#: The rate is a difference quotient: rho_j = rotvec(C_0^T C_j) is made from the products'
#: entries (~1, rounded to ~eps absolute whatever rho's size, and numpy's BLAS sums them
#: in another order), so each rho carries a few eps absolute; the 5-point weights
#: (48 + 36 + 16 + 3) / 12 ~ 9 over h amplify that to ~36 eps / h. Allowed 64 eps / h
#: (1.4e-12 rad/s at h = 0.02 s), absolute: rate components pass through zero.
ATOL_RATE = 64.0 * EPS / H


def _period_values(block: TransferAlignment) -> np.ndarray:
    return np.concatenate([getattr(block, n) for n in PERIOD_OUTPUTS])


@pytest.fixture(scope="module")
def compiled_run() -> dict:
    """A compiled 15 s run: what the filter got at each period and numpy's on that state."""
    needs_library()
    with pytest.MonkeyPatch.context() as mp:
        master = short_master(mp, "1", STOP)
        block = align_block(master)
        rec: dict = {"fed": [], "numpy": [], "stage": [], "inputs": [], "period": [], "P": []}
        step = block.do_step

        def hooked(f_call):  # the estimator's start / update, recording their master state
            def call(*args: object) -> None:
                state = args[:3] if f_call.__name__ == "start" else args[1:4]
                rec["fed"].append([np.array(a) for a in state])
                rec["numpy"].append([np.array(a) for a in block.master_state_numpy()])
                rec["stage"].append(block.estimator.stage)
                f_call(*args)

            return call

        def checked(t: float, h: float) -> bool:
            if "hooked" not in rec:
                rec["hooked"] = True
                block.estimator.start = hooked(block.estimator.start)
                block.estimator.update = hooked(block.estimator.update)
            ok = step(t, h)
            rec["inputs"].append(
                (
                    np.array(block.rpy_master),
                    np.array(block.v_master_n),
                    float(block.lat_master),
                    float(block.h_master),
                )
            )
            p_att, p_inv, values = block.period_numpy()
            rec["period"].append((_period_values(block), values))
            rec["P"].append(np.array(block.estimator.P_show))
            return ok

        block.do_step = checked
        try:
            result = master.run()
            assert block.compiled
        finally:
            master.terminate()
        assert result.status == "completed"
    return rec


def test_filter_gets_numpys_master_state_in_both_stages(compiled_run: dict) -> None:
    """At the start and at every period: attitude and velocity equal, rate to rounding."""
    rec = compiled_run
    # the start (stage 0 -> 1), then 2 periods a second for 15 s, in stages 1 and 2
    assert len(rec["fed"]) == 1 + int(STOP / 0.5)
    assert rec["stage"][0] == 0.0 and {1.0, 2.0} <= set(rec["stage"])
    for (c, w, v), (c_ref, w_ref, v_ref) in zip(rec["fed"], rec["numpy"], strict=True):
        np.testing.assert_array_equal(c, c_ref)
        np.testing.assert_array_equal(v, v_ref)
        np.testing.assert_allclose(w, w_ref, rtol=RTOL, atol=ATOL_RATE)
        assert np.max(np.abs(w)) > 1e3 * ATOL_RATE  # the ship rolls: a rate to compare


def _state_kernel():  # noqa: ANN202 (a ctypes function)
    fn = native.kernel("transfer_master_state")
    assert fn is not None
    return fn


def test_kernel_on_histories_of_one_to_five_attitudes(compiled_run: dict) -> None:
    """The ring as the block keeps it, every rotation, 1..5 attitudes (zero, 2-, 3-, 5-point)."""
    fn = _state_kernel()
    ring = np.zeros((HISTORY, 3, 3))
    earth = np.array([A, E2])
    out = np.zeros(12)
    v = np.zeros(3)
    worst = 0.0
    seen_k = set()
    for n, (rpy, v_m, lat, height) in enumerate(compiled_run["inputs"][:200]):
        ring[n % HISTORY] = euler_to_dcm_3(rpy)
        hist = [ring[(n - j) % HISTORY] for j in range(min(n + 1, HISTORY))]
        v[...] = v_m
        for k in range(1, len(hist) + 1):
            fn(*map(native.pointer, (ring,)), n % HISTORY, k, H, native.pointer(v), lat, height,
               native.pointer(earth), native.pointer(out))  # fmt: skip
            _, w_en = nav_rates(v, lat, height)
            ref = master_rate(hist[:k], H) + hist[0].T @ w_en
            np.testing.assert_array_equal(out[:9].reshape(3, 3), hist[0])
            np.testing.assert_allclose(out[9:], ref, rtol=RTOL, atol=ATOL_RATE, err_msg=f"k={k}")
            if k == 1:  # no rate from one attitude: the transport rate alone
                np.testing.assert_allclose(out[9:], hist[0].T @ w_en, rtol=RTOL, atol=1e-20)
            worst = max(worst, float(np.max(np.abs(out[9:] - ref))))
            seen_k.add(k)
    assert seen_k == {1, 2, 3, 4, 5}
    assert worst < ATOL_RATE
    # a master at rest: C_0^T C_j = I, |q_v| = 0 (the rotation vector's small-angle branch)
    ring[...] = euler_to_dcm_3(compiled_run["inputs"][0][0])
    fn(native.pointer(ring), 2, HISTORY, H, native.pointer(v), lat, height,
       native.pointer(earth), native.pointer(out))  # fmt: skip
    _, w_en = nav_rates(v, lat, height)
    ref = master_rate(list(ring), H) + ring[0].T @ w_en
    assert np.all(np.isfinite(out[9:]))
    np.testing.assert_allclose(out[9:], ref, rtol=RTOL, atol=1e-20)


def test_period_outputs_equal_numpys(compiled_run: dict) -> None:
    """flex, bias, drift and their sigmas at every step: the same operations, equal."""
    got = np.array([g for g, _ in compiled_run["period"]])
    ref = np.array([r for _, r in compiled_run["period"]])
    np.testing.assert_allclose(got, ref, rtol=RTOL, atol=0.0)
    assert np.all(np.abs(got[-1]) > 0.0)  # every output estimated by the end


def test_period_kernel_inverse_to_rounding(compiled_run: dict) -> None:
    """P_att and its inverse from the shown P of every step, and the singular case."""
    fn = native.kernel("transfer_period")
    assert fn is not None
    idx = np.array([4, 13, 16, 7], dtype=np.intc)
    bias = np.zeros(6)
    per = np.zeros(28)
    out = np.zeros(18)
    ptrs = [native.pointer(a) for a in (idx, bias)]
    x = np.zeros(19)
    conds = []
    for P in compiled_run["P"][::10]:
        assert fn(native.pointer(P), 19, native.pointer(x), *ptrs, ARCMIN, native.pointer(per),
                  native.pointer(out)) == 0  # fmt: skip
        p_att = P[4:7, 4:7]
        np.testing.assert_array_equal(per[9:18].reshape(3, 3), p_att)
        inv = np.linalg.inv(p_att)
        cond = np.linalg.cond(p_att)
        conds.append(cond)
        # LU in another order (LAPACK's blocked kernels): normwise cond * eps apart
        err = np.max(np.abs(per[18:27].reshape(3, 3) - inv)) / np.max(np.abs(inv))
        assert err <= 16.0 * cond * EPS, (err, cond)
        np.testing.assert_allclose(per[18:27].reshape(3, 3) @ p_att, np.eye(3), atol=1e-9)
    assert max(conds) > 10.0  # a spread of conditionings, not only near-isotropic P
    P = np.zeros((19, 19))
    per[18:27] = 7.0
    assert fn(native.pointer(P), 19, native.pointer(x), *ptrs, ARCMIN, native.pointer(per),
              native.pointer(out)) == 1  # fmt: skip
    assert np.all(per[18:27] == 7.0)  # untouched: the block falls back to numpy (raises)


def test_numpy_and_compiled_runs_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    """Whole runs, every kernel off (INS_COSIM_NATIVE=0) vs on: the same alignment."""
    needs_library()

    def check(block: TransferAlignment, compiled: bool) -> None:
        assert block.compiled == compiled

    a, b = runs_both_ways(monkeypatch, STOP, check)
    assert set(a["align.stage"]) == {0.0, 1.0, 2.0}
    # Every kernel switches (mechanisation, error model, UKF, outputs): their sums differ
    # from numpy's (BLAS) by rounding, which the filter's updates amplify (they divide by
    # small innovation covariances): ~1e-9 arcmin on errors of up to 2200 arcmin here.
    for name, atol in (("rpy_err", 1e-8), ("flex", 1e-8), ("accel_bias", 1e-12)):
        for i in (1, 2, 3):
            col = f"align.{name}[{i}]"
            np.testing.assert_allclose(b[col], a[col], rtol=1e-9, atol=atol, err_msg=col)
    for i in (1, 2, 3):
        col = f"align.gyro_drift[{i}]"
        np.testing.assert_allclose(b[col], a[col], rtol=1e-9, atol=1e-15, err_msg=col)
