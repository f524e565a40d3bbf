"""The transfer-alignment block's compiled outputs (``cosim/alignment/transfer_publish.c``).

Over a real co-simulation of ``scenarios/transfer_alignment.toml`` shortened to 12 s
(waiting for the master, stage 1 acquisition, stage 2 from about 5 s): at every step the
compiled outputs equal the numpy statement :meth:`TransferAlignment.attitude_numpy` on
the same filter state to 1e-12 relative; whole runs with and without the compiled
kernels agree to the filter's amplified rounding; the vector outputs stay the block's
output-buffer views (the master's one-slice read); and a block whose inputs and outputs
are rebound from outside (the fallback) gives the same numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
from transfer_run import align_block, needs_library, runs_both_ways, short_master

from cosim.alignment.transfer import PUBLISH_INPUTS, PUBLISH_OUTPUTS, TransferAlignment
from cosim.models import native
from cosim.models.constants import ARCMIN
from cosim.models.conventions import euler_to_dcm_3

STOP = 12.0  # the acquisition ends at 5 s at the earliest: both stages run
RTOL = 1e-12
#: rpy_err is a difference of two angles of up to pi: their rounding (ulp(pi) = 4.4e-16
#: rad) is absolute, 1e-14 rad, whatever the size of the difference; rel_rpy likewise
#: (it is ~1e-17 rad before the filter starts). rpy_sigma: relative only.
ATOL = np.array([1e-14 / ARCMIN] * 3 + [0.0] * 3 + [1e-14] * 3)
VECTORS = [v.name for v in TransferAlignment.variables if v.causality == "output" and v.is_vector]
INPUTS = [v.name for v in TransferAlignment.variables if v.causality == "input"]


def _published(block: TransferAlignment) -> np.ndarray:
    return np.concatenate([getattr(block, n) for n in PUBLISH_OUTPUTS])


def _mode(block: TransferAlignment) -> int:
    f = block.estimator
    return 0 if f.nav is None else int(f.stage)


def _views_intact(block: TransferAlignment) -> bool:
    """Every vector output is still a view of one buffer, back to back in declared order."""
    return native.span(block, tuple(VECTORS)) is not None


def test_compiled_equals_numpy_at_every_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """Compiled outputs vs the numpy statement on the same state, step by step."""
    needs_library()
    master = short_master(monkeypatch, "1", STOP)
    block = align_block(master)
    step = block.do_step
    steps = {0: 0, 1: 0, 2: 0}
    rows: list[np.ndarray] = []  # per step: t, compiled outputs and nees, numpy's
    same_attitude: list[bool] = []
    intact: list[bool] = []

    def checked(t: float, h: float) -> bool:
        ok = step(t, h)
        assert block.compiled
        ref, nees = block.attitude_numpy()
        rows.append(np.concatenate([[t], _published(block), [block.nees], ref, [nees]]))
        # the master attitude of the step, by the kernel or numpy: the same arithmetic
        same_attitude.append(np.array_equal(block.master_dcm, euler_to_dcm_3(block.rpy_master)))
        intact.append(_views_intact(block))
        steps[_mode(block)] += 1
        return ok

    block.do_step = checked  # the master calls the host, the host the instance's do_step
    try:
        result = master.run()
    finally:
        master.terminate()
    assert result.status == "completed"
    # before the filter starts (5 master attitudes), the acquisition, the fine alignment
    assert steps[0] == 3 and steps[1] >= 50 and steps[2] >= 50, steps
    assert result.data["align.stage"][-1] == 2.0
    table = np.array(rows)
    got, ref = table[:, 1:11], table[:, 11:21]
    atol = np.append(ATOL, 0.0)
    excess = np.abs(got - ref) - (atol + RTOL * np.abs(ref))
    i, j = np.unravel_index(np.argmax(excess), excess.shape)
    assert excess[i, j] <= 0.0, (table[i, 0], j, got[i, j], ref[i, j])
    assert all(same_attitude) and all(intact)


def test_numpy_and_compiled_runs_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    """Whole runs, every kernel off (INS_COSIM_NATIVE=0) vs on: the same alignment."""
    needs_library()

    def check(block: TransferAlignment, compiled: bool) -> None:
        assert block.compiled == compiled
        assert _views_intact(block)  # in place on the numpy path too

    a, b = runs_both_ways(monkeypatch, STOP, check)
    assert set(a["align.stage"]) == {0.0, 1.0, 2.0}
    # The filter's own kernels (mechanisation, error model) switch too: their 3x3
    # products differ from numpy's (BLAS) by rounding, which the filter amplifies (its
    # update divides by small innovation covariances): ~6e-10 arcmin on alignment errors
    # of up to 2200 arcmin here, against 1e-12 per step on the same state (test above).
    for name, rtol, atol in (
        ("rpy_err", 1e-9, 5e-9),
        ("rpy_sigma", 1e-9, 5e-9),
        ("rel_rpy", 1e-9, 1e-12),
    ):
        for i in (1, 2, 3):
            col = f"align.{name}[{i}]"
            np.testing.assert_allclose(b[col], a[col], rtol=rtol, atol=atol, err_msg=col)
    np.testing.assert_allclose(b["align.nees"], a["align.nees"], rtol=1e-9, atol=1e-12)
    # before the filter starts the outputs depend on the inputs only (the same truth)
    first = a["time"] < 0.2
    assert np.count_nonzero(first) == 4
    for i in (1, 2, 3):
        col = f"align.rpy_err[{i}]"
        np.testing.assert_allclose(b[col][first], a[col][first], rtol=RTOL, atol=ATOL[0])


def _record_inputs(monkeypatch: pytest.MonkeyPatch) -> tuple[list, dict]:
    """The align block's inputs at initialisation and before every step of a run."""
    master = short_master(monkeypatch, "1", stop=8.0)
    block = align_block(master)
    step = block.do_step
    init = block.exit_initialization_mode
    feed: list = []
    params = {}

    def values() -> dict:
        return {n: np.array(getattr(block, n)) for n in INPUTS}

    def initialised() -> None:
        for v in block.variables:
            if v.causality == "parameter":
                value = getattr(block, v.name)
                params[v.name] = value.copy() if isinstance(value, np.ndarray) else value
        feed.append((None, None, values()))
        init()

    def recorded(t: float, h: float) -> bool:
        feed.append((t, h, values()))
        return step(t, h)

    block.exit_initialization_mode = initialised
    block.do_step = recorded
    try:
        assert master.run().status == "completed"
    finally:
        master.terminate()
    return feed, params


@pytest.mark.parametrize("env", ["1", "0"])
def test_rebound_inputs_and_outputs_give_the_same_numbers(
    env: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The fallback: inputs set as new arrays (gathered), outputs rebound (assigned)."""
    if env == "1":
        needs_library()
    feed, params = _record_inputs(monkeypatch)
    monkeypatch.setenv(native.ENV, env)
    blocks = [TransferAlignment(), TransferAlignment()]
    for block in blocks:
        for name, value in params.items():
            setattr(block, name, value)
        block.setup_experiment(0.0)
    inplace, rebound = blocks
    for n, (t, h, inputs) in enumerate(feed):
        for name, value in inputs.items():
            if value.ndim:
                getattr(inplace, name)[...] = value  # into its input views
                setattr(rebound, name, value.copy())  # new arrays: gathered
            else:
                setattr(inplace, name, float(value))
                setattr(rebound, name, float(value))
        if n == 0:
            inplace.exit_initialization_mode()
            rebound.exit_initialization_mode()
            assert inplace.compiled == rebound.compiled == (env == "1")
            for name in VECTORS:  # rebound from outside: the block assigns them from now on
                setattr(rebound, name, np.array(getattr(rebound, name)))
        else:
            inplace.do_step(t, h)
            rebound.do_step(t, h)
        assert _views_intact(inplace)
        assert native.span(inplace, PUBLISH_INPUTS) is not None
        assert not _views_intact(rebound)
        for name in [*VECTORS, "nees", "nis", "stage"]:
            np.testing.assert_array_equal(getattr(rebound, name), getattr(inplace, name), name)
    assert inplace.stage == 2.0
