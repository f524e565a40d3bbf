"""Master semantics, each against an analytic answer (README, "The coupling rule")."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from testblocks import Clock, Faulty, Pass, Ramp

from cosim.blocks import InProcessHost
from cosim.errors import ScenarioError, SimulationError
from cosim.master import (
    JACOBI,
    Connection,
    CouplingWarning,
    Master,
    MasterSettings,
    System,
    schedule,
)

H = 0.01


def chain(coupling: str, rates: dict[str, int] | None = None, stop: float = 0.2) -> np.ndarray:
    """ramp -> p1 -> p2, declared in reverse order so the master must sort them."""
    blocks = {
        "p2": InProcessHost("p2", Pass),
        "p1": InProcessHost("p1", Pass),
        "ramp": InProcessHost("ramp", Ramp),
    }
    links = [Connection("ramp", "y", "p1", "u"), Connection("p1", "y", "p2", "u")]
    system = System(blocks, links, rates=rates or {})
    master = Master(system, MasterSettings(H, stop, coupling=coupling))
    assert master.order == ["ramp", "p1", "p2"]
    return master.run().data


def test_gauss_seidel_chain_has_no_delay() -> None:
    d = chain("gauss-seidel")
    # every block sees its source's value at the end of the same macro step
    # (Ramp computes t + h itself, hence 1 ulp of tolerance; a delay would be 0.01 s)
    np.testing.assert_allclose(d["p1.y"], d["time"], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(d["p2.y"], d["p1.y"])


def test_jacobi_chain_delays_one_step_per_link() -> None:
    d = chain(JACOBI)
    t = d["time"]
    # p1 sees ramp(t_n) while stepping to t_{n+1}: one step late; p2 two steps late.
    np.testing.assert_allclose(d["p1.y"][1:], t[:-1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(d["p2.y"][2:], t[:-2], rtol=0, atol=1e-15)
    # during the first steps the initial values (t0 = 0) propagate
    assert d["p2.y"][1] == 0.0 and d["p1.y"][0] == 0.0


def test_multirate_slow_sink_holds_its_output() -> None:
    d = chain("gauss-seidel", rates={"p1": 10, "p2": 1}, stop=0.5)
    j = np.arange(len(d))
    # p1 (k=10) steps at the macro steps ending at t_10, t_20, ...; it sees ramp at its
    # step end and holds that value until its next step.
    expected = np.floor(j / 10) * 10 * H
    np.testing.assert_allclose(d["p1.y"], expected, rtol=0, atol=1e-15)
    # the fast sink downstream of the slow block sees the held value with no delay
    np.testing.assert_array_equal(d["p2.y"], d["p1.y"])


def test_multirate_slow_source_fast_sink_under_jacobi() -> None:
    d = chain(JACOBI, rates={"ramp": 10}, stop=0.5)
    j = np.arange(len(d))
    ramp_expected = np.floor(j / 10) * 10 * H
    np.testing.assert_allclose(d["ramp.y"], ramp_expected, rtol=0, atol=1e-15)
    # p1 reads the value held at the start of each macro step (Jacobi)
    np.testing.assert_allclose(d["p1.y"][1:], ramp_expected[:-1], rtol=0, atol=1e-15)


def test_rate_must_divide_the_number_of_steps() -> None:
    system = System({"ramp": InProcessHost("ramp", Ramp)}, [], rates={"ramp": 7})
    with pytest.raises(ScenarioError, match="blocks.ramp.rate"):
        Master(system, MasterSettings(H, 0.2))


def test_million_steps_end_exactly_on_time() -> None:
    system = System({"clock": InProcessHost("clock", Clock)}, [])
    settings = MasterSettings(1e-3, 1000.0, record_every=100_000)
    d = Master(system, settings).run().data
    assert d["time"][-1] == 1000.0
    assert d["clock.t_end"][-1] == 1000.0
    assert d["clock.count"][-1] == 1_000_000
    # every recorded time is exactly t0 + n h, with no accumulated rounding
    np.testing.assert_array_equal(d["time"], np.arange(11) * 100_000 * 1e-3)


def test_feedback_loop_is_delayed_once_with_a_warning() -> None:
    blocks = {
        "a": InProcessHost("a", Pass),
        "b": InProcessHost("b", Pass),
    }
    links = [Connection("a", "y", "b", "u"), Connection("b", "y", "a", "u")]
    system = System(blocks, links, parameters={"a": {"offset": 1.0}})
    master = Master(system, MasterSettings(1.0, 10.0))
    with pytest.warns(CouplingWarning, match=r"a -> b -> a.*b\.y -> a\.u"):
        d = master.run().data
    # a reads b's value at t_n (delayed), b reads a's at t_{n+1}: b.y(t_n) = n + 1
    np.testing.assert_array_equal(d["b.y"], np.arange(11) + 1.0)
    np.testing.assert_array_equal(d["a.y"], d["b.y"])


def test_no_warning_without_loops_and_order_is_topological() -> None:
    names = ["d", "c", "b", "a"]
    links = [Connection("a", "y", "b", "u"), Connection("b", "y", "c", "u")]
    order, delayed, loops = schedule(names, links)
    assert order.index("a") < order.index("b") < order.index("c")
    assert delayed == [] and loops == []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        chain("gauss-seidel")


def test_loop_downstream_block_is_not_delayed() -> None:
    # a <-> b loop feeding c: only the loop's back edge is delayed
    links = [
        Connection("a", "y", "b", "u"),
        Connection("b", "y", "a", "u"),
        Connection("b", "y", "c", "u"),
    ]
    order, delayed, loops = schedule(["c", "a", "b"], links)
    assert order == ["a", "b", "c"]
    assert [str(c) for c in delayed] == ["b.y -> a.u"]
    assert loops == [["a", "b"]]


@pytest.mark.parametrize("mode, message", [(1, "not finite"), (2, "failure")])
def test_fault_stops_run_with_block_variable_time_and_keeps_results(
    mode: int, message: str
) -> None:
    blocks = {"ramp": InProcessHost("ramp", Ramp), "bad": InProcessHost("bad", Faulty)}
    system = System(blocks, [], parameters={"bad": {"fail_time": 0.105, "mode": mode}})
    with pytest.raises(SimulationError, match=message) as info:
        Master(system, MasterSettings(H, 1.0)).run()
    err = info.value
    assert err.block == "bad"
    # a failing call is named as a call, not as a variable
    assert (err.variable, err.call) == (("y", None) if mode == 1 else (None, "do_step"))
    # the step from 0.10 to 0.11 is the first whose end passes 0.105
    expected_time = 0.11 if mode == 1 else 0.1
    assert err.time == pytest.approx(expected_time, abs=1e-12)
    rec = err.result
    assert rec.status == "failed"
    # rows t = 0 .. 0.10 were completed and are kept
    assert len(rec.data) == 11
    np.testing.assert_allclose(rec.data["ramp.y"], np.arange(11) * H, atol=1e-15)


def test_reset_then_run_again_reproduces_the_run_and_takes_new_seeds(fmu_dir) -> None:
    from cosim.blocks import FmuHost
    from cosim.models.blocks.first_order_sensor import FirstOrderSensor

    blocks = {
        "gm": FmuHost("gm", fmu_dir / "GaussMarkov2.fmu"),
        "s": InProcessHost("s", FirstOrderSensor),
    }
    params = {"gm": {"seed": 1}, "s": {"seed": 2, "noise_density": 1e-4}}
    system = System(blocks, [Connection("gm", "x", "s", "u")], parameters=params)
    master = Master(system, MasterSettings(H, 1.0))
    first = master.run().data
    master.reset()
    second = master.run().data
    master.reset()
    params["gm"]["seed"] = 3
    third_result = master.run()
    third = third_result.data
    master.terminate()
    for name in first.dtype.names:
        np.testing.assert_array_equal(first[name], second[name])
    assert not np.array_equal(first["gm.x"], third["gm.x"])
    assert third_result.metadata["seeds"] == {"gm": 3, "s": 2}


def test_jacobi_initialisation_passes_zero_for_outputs_without_start() -> None:
    class NoStart(InProcessHost):
        """A Ramp whose output declares no start value, as vendor FMUs often do."""

        def __init__(self, name: str) -> None:
            super().__init__(name, Ramp)
            self.variables["y"] = dataclasses.replace(self.variables["y"], start=None)

    blocks = {"src": NoStart("src"), "sink": InProcessHost("sink", Pass)}
    system = System(blocks, [Connection("src", "y", "sink", "u")])
    d = Master(system, MasterSettings(H, 1.05, start=1.0, coupling=JACOBI)).run().data
    assert d["sink.y"][0] == 0.0  # no start value: the sink is initialised with 0.0
    np.testing.assert_allclose(d["sink.y"][1:], d["src.y"][:-1], rtol=0, atol=1e-15)


def test_settings_normalise_the_coupling_once_and_overrides_keep_the_checks() -> None:
    s = MasterSettings(0.1, 1.0, coupling="Gauss_Seidel")
    assert s.coupling == "gauss-seidel" and s.n_steps == 10
    assert MasterSettings(0.1, 1.0, coupling="JACOBI").coupling == JACOBI
    # an override is a new object, derived and checked again by the same code
    longer = dataclasses.replace(s, stop=2.0)
    assert longer.n_steps == 20 and s.n_steps == 10 and longer.coupling == "gauss-seidel"
    with pytest.raises(ScenarioError, match="expected 'gauss-seidel' or 'jacobi'") as info:
        MasterSettings(0.1, 1.0, coupling="seidel")
    assert info.value.key == "master.coupling"
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.step = 0.2  # type: ignore[misc]
