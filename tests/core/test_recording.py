"""The recording observer (cosim.recording): the rows and columns asked, at their periods,
and the rows recorded before a failure or an early end."""

from __future__ import annotations

import numpy as np
import pytest
from testblocks import Clock, Faulty, Pass, Ramp

from cosim.blocks import InProcessHost
from cosim.errors import ScenarioError, SimulationError
from cosim.master import Connection, Master, MasterSettings, System
from cosim.observers import FinitenessCheck, Observer
from cosim.recording import MAX_RECORDING_BYTES, Recorder, record_run

H = 0.01


def ramp_clock(record: list[tuple[str, str]] | None = None, every: int = 1, stop: float = 1.0):
    blocks = {
        "ramp": InProcessHost("ramp", Ramp),
        "p": InProcessHost("p", Pass),
        "clock": InProcessHost("clock", Clock),
    }
    system = System(blocks, [Connection("ramp", "y", "p", "u")], record=record)
    return Master(system, MasterSettings(H, stop, record_every=every))


def test_records_exactly_the_variables_asked_in_the_order_asked() -> None:
    master = ramp_clock(record=[("clock", "count"), ("ramp", "y")])
    result = record_run(master)
    assert result.names == ["time", "clock.count", "ramp.y"]
    np.testing.assert_array_equal(result["clock.count"], np.arange(101.0))
    np.testing.assert_allclose(result["ramp.y"], result.time, rtol=0, atol=1e-15)
    assert result.metadata["types"] == {"clock.count": "Real", "ramp.y": "Real"}


def test_without_a_list_every_output_is_recorded_in_declaration_order() -> None:
    result = record_run(ramp_clock())
    assert result.names == ["time", "ramp.y", "p.y", "clock.t_end", "clock.count"]


@pytest.mark.parametrize("every", [1, 3, 7, 100])
def test_rows_at_t0_and_every_kth_macro_step(every: int) -> None:
    result = record_run(ramp_clock(every=every))
    # 100 steps: t0, then after steps every, 2 every, ... (not the stop time unless on it)
    expected_steps = np.arange(0, 101, every)
    assert len(result.data) == len(expected_steps) == 100 // every + 1
    np.testing.assert_array_equal(result["clock.count"], expected_steps.astype(float))
    np.testing.assert_allclose(result.time, expected_steps * H, rtol=0, atol=1e-15)


def test_rows_before_a_failure_are_kept_and_the_error_names_block_variable_time() -> None:
    blocks = {"ramp": InProcessHost("ramp", Ramp), "bad": InProcessHost("bad", Faulty)}
    system = System(blocks, [], parameters={"bad": {"fail_time": 0.305, "mode": 1}})
    master = Master(system, MasterSettings(H, 1.0, record_every=2))
    with pytest.raises(SimulationError, match="not finite") as info:
        record_run(master)
    err = info.value
    assert (err.block, err.variable) == ("bad", "y")
    assert err.time == pytest.approx(0.31, abs=1e-12)  # the first step ending past 0.305
    rec = err.result
    assert rec.status == "failed" and "bad" in rec.error
    # rows at 0, 0.02, ..., 0.30 (the failing step 0.30 -> 0.31 wrote none)
    np.testing.assert_allclose(rec.time, np.arange(16) * 2 * H, rtol=0, atol=1e-15)
    assert np.all(np.isfinite(rec["bad.y"]))


def test_a_block_call_failure_keeps_the_rows_and_names_the_call() -> None:
    blocks = {"ramp": InProcessHost("ramp", Ramp), "bad": InProcessHost("bad", Faulty)}
    system = System(blocks, [], parameters={"bad": {"fail_time": 0.105, "mode": 2}})
    with pytest.raises(SimulationError, match="failure") as info:
        record_run(Master(system, MasterSettings(H, 1.0)))
    assert (info.value.block, info.value.call, info.value.variable) == ("bad", "do_step", None)
    assert len(info.value.result.data) == 11  # t = 0 .. 0.10


def test_on_row_sees_every_row_as_it_is_written() -> None:
    rows: list[np.ndarray] = []
    result = record_run(ramp_clock(every=10), on_row=lambda row: rows.append(row.copy()))
    assert len(rows) == len(result.data) == 11
    np.testing.assert_array_equal(np.array(rows), result.data.view(np.float64).reshape(11, -1))


class StopAt(Observer):
    """Asks the run to end after the macro step that ends at ``t_stop`` or later."""

    def __init__(self, t_stop: float) -> None:
        self.t_stop = t_stop

    def after_step(self, n: int, t: float) -> object:
        return f"reached {t:g} s" if t >= self.t_stop - 1e-12 else None


def test_an_early_stop_records_the_last_values_once() -> None:
    # off the recording grid: the values at the stop are added as the last row
    result = record_run(ramp_clock(every=10), observers=[StopAt(0.25)])
    np.testing.assert_allclose(result.time, [0.0, 0.1, 0.2, 0.25], rtol=0, atol=1e-15)
    assert result["clock.count"][-1] == 25.0
    assert result.status == "completed"
    assert result.metadata["stopped"] == {"time": pytest.approx(0.25), "reason": "reached 0.25 s"}
    # on the grid: no second row at the same time
    on_grid = record_run(ramp_clock(every=10), observers=[StopAt(0.3)])
    np.testing.assert_allclose(on_grid.time, [0.0, 0.1, 0.2, 0.3], rtol=0, atol=1e-15)


def test_a_recording_too_large_is_refused_before_the_run_with_its_size() -> None:
    # 2**28 rows x 3 columns x 8 bytes = 6 GiB
    master = ramp_clock(record=[("ramp", "y"), ("p", "y")], stop=H * 2**28)
    with pytest.raises(ScenarioError, match=r"rows x 3 columns = 6 GiB") as info:
        Recorder(master)
    assert info.value.key == "output.every"
    assert MAX_RECORDING_BYTES == 2 * 2**30


def test_the_recorder_runs_again_after_a_reset_with_the_same_rows() -> None:
    master = ramp_clock(every=5)
    recorder = Recorder(master)
    first = record_run(master, recorder=recorder)
    master.reset()
    second = record_run(master, recorder=recorder)
    np.testing.assert_array_equal(first.data, second.data)
    assert first.data is not second.data


def test_without_the_finiteness_check_a_nan_is_recorded_not_refused() -> None:
    # the check is an observer like the others: the master itself does not look at values
    blocks = {"bad": InProcessHost("bad", Faulty)}
    master = Master(
        System(blocks, [], parameters={"bad": {"fail_time": 0.05}}), MasterSettings(H, 0.1)
    )
    recorder = Recorder(master)
    master.execute([recorder])
    data = recorder.result().data
    assert np.isnan(data["bad.y"][-1]) and len(data) == 11
    with pytest.raises(SimulationError):
        master.reset()
        master.execute([FinitenessCheck(), Recorder(master)])
