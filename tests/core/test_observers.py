"""The observer interface of the master (cosim.observers): which hooks are called, when,
and how an observer ends or fails a run."""

from __future__ import annotations

import pytest
from testblocks import Faulty, Pass, Ramp

from cosim.blocks import InProcessHost
from cosim.errors import SimulationError
from cosim.master import Connection, Master, MasterSettings, System
from cosim.observers import Ending, Observer, Progress, hooks_of

H = 0.1


def chain(stop: float = 0.5, rates: dict[str, int] | None = None) -> Master:
    blocks = {"p": InProcessHost("p", Pass), "ramp": InProcessHost("ramp", Ramp)}
    system = System(blocks, [Connection("ramp", "y", "p", "u")], rates=rates or {})
    return Master(system, MasterSettings(H, stop))


class Log(Observer):
    """Notes every hook call."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def on_start(self, master: Master, t0: float) -> None:
        self.calls.append(("start", t0, master.values is not None))

    def before_block(self, i: int, t: float, initialising: bool) -> None:
        self.calls.append(("before", i, round(t, 9), initialising))

    def after_block(self, i: int, t: float) -> None:
        self.calls.append(("after", i, round(t, 9)))

    def after_step(self, n: int, t: float) -> object:
        self.calls.append(("step", n, round(t, 9)))
        return None

    def on_stop(self, ending: Ending) -> None:
        self.calls.append(("stop", ending.status, round(ending.time, 9)))


def test_the_hooks_come_in_the_order_of_the_run_blocks_in_stepping_order() -> None:
    master = chain(stop=0.2)
    log = Log()
    ending = master.execute([log])
    assert master.order == ["ramp", "p"]
    assert ending.status == "completed" and ending.time == pytest.approx(0.2)
    assert log.calls == [
        ("start", 0.0, True),
        ("before", 0, 0.0, True), ("after", 0, 0.0),
        ("before", 1, 0.0, True), ("after", 1, 0.0),
        ("step", -1, 0.0),
        ("before", 0, 0.0, False), ("after", 0, 0.1),
        ("before", 1, 0.0, False), ("after", 1, 0.1),
        ("step", 0, 0.1),
        ("before", 0, 0.1, False), ("after", 0, 0.2),
        ("before", 1, 0.1, False), ("after", 1, 0.2),
        ("step", 1, 0.2),
        ("stop", "completed", 0.2),
    ]  # fmt: skip


def test_a_slow_block_is_seen_only_when_it_steps() -> None:
    log = Log()
    chain(stop=0.4, rates={"p": 2}).execute([log])
    p_steps = [c for c in log.calls if c[:2] == ("before", 1) and not c[3]]
    # p (rate 2) steps from t_{n-1} to t_{n+1} in macro steps 1 and 3
    assert p_steps == [("before", 1, 0.0, False), ("before", 1, 0.2, False)]


def test_only_the_overridden_hooks_are_called() -> None:
    class OnlySteps(Observer):
        def after_step(self, n: int, t: float) -> object:
            return None

    hooks = hooks_of([OnlySteps(), Observer()])
    assert [len(getattr(hooks, h)) for h in ("on_start", "before_block", "after_block")] == [0] * 3
    assert len(hooks.after_step) == 1 and hooks.on_stop == []


def test_an_observer_ends_the_run_after_every_observer_saw_the_step() -> None:
    class StopAfter(Observer):
        def after_step(self, n: int, t: float) -> object:
            return n == 1 and "enough"

    first, second = StopAfter(), Log()
    ending = chain(stop=10.0).execute([first, second])
    assert ending.stopped == {"time": pytest.approx(0.2), "reason": "enough"}
    assert ending.early and ending.status == "completed"
    assert [c for c in second.calls if c[0] == "step"][-1] == ("step", 1, 0.2)
    assert second.calls[-1] == ("stop", "completed", 0.2)


def test_an_observer_that_fails_the_run_is_reported_with_every_on_stop_told() -> None:
    class Refuse(Observer):
        def after_block(self, i: int, t: float) -> None:
            if t > 0.25:
                raise SimulationError("too late", block="p", time=t)

    log = Log()
    with pytest.raises(SimulationError, match="too late"):
        chain(stop=1.0).execute([Refuse(), log])
    assert log.calls[-1] == ("stop", "failed", 0.3)


def test_a_block_failure_reaches_on_stop_with_the_error() -> None:
    endings: list[Ending] = []

    class Keep(Observer):
        def on_stop(self, ending: Ending) -> None:
            endings.append(ending)

    blocks = {"bad": InProcessHost("bad", Faulty)}
    master = Master(System(blocks, [], parameters={"bad": {"mode": 2, "fail_time": 0.25}}),
                    MasterSettings(H, 1.0))  # fmt: skip
    with pytest.raises(SimulationError) as info:
        master.execute([Keep()])
    assert len(endings) == 1 and endings[0].status == "failed"
    assert endings[0].error is info.value and info.value.call == "do_step"


def test_progress_reports_evenly_and_ends_at_one() -> None:
    seen: list[tuple[float, float]] = []
    chain(stop=2.0).execute([Progress(lambda f, t: seen.append((f, round(t, 9))), updates=4)])
    assert seen == [(0.25, 0.5), (0.5, 1.0), (0.75, 1.5), (1.0, 2.0)]
    with pytest.raises(ValueError):
        Progress(print, updates=0)
