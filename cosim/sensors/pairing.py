"""Two logs in one run, checked against each other before the run (``check``, ``run``, ``verify``).

A scenario with two log replays (an :class:`~cosim.sensors.replay.ImuLogReplay` and a
:class:`~cosim.sensors.master_replay.MasterInsLogReplay`, for transfer alignment on
recorded data) pairs the logs **sample by sample from their starts**: each replay starts
with its log's first sample at the run's start ``t0`` and takes ``m = h f_s`` samples per
step of its block (nothing is interpolated). That is right only when the two logs' data
start at the same instant and run at the rates the steps assume. This module finds the
replays of a built scenario with two or more of them, scans their logs (one streaming
pass each, the checks of :mod:`cosim.sensors.logs`) and checks, on the run's common time
base::

    start = t_first - dt - time_offset     (a log of increments: sample k covers
                                            (t_k - dt, t_k], so its data start at
                                            t_first - dt)
    start = t_first - time_offset          (a log of states at their time stamps)
    end   = t_last - time_offset

``time_offset`` [s] is each replay's parameter: by how much the log's time stamps run
ahead of the common time (a clock offset between the two loggers, e.g. a master INS that
stamps its solution 110 ms late). It is a statement about the stamps; the samples are
replayed as they are. The checks, each refused as one line with the numbers and the fix
(:class:`~cosim.errors.ScenarioError`, exit code 3):

* **start**: the two starts differ by more than half the shorter sample interval
  (``0.5 min(dt_a, dt_b)``): the run would pair data that far apart. The fix names the
  ``time_offset`` that makes them agree, or the samples to cut from the earlier log.
* **rate**: a block's step ``h k`` (``master.step`` times the block's ``rate``) must hold
  a whole number of samples of its log (as each replay checks at its first step).
* **end**: the run (``master.stop - master.start``) must end within each log's data
  (``end - start``), so that the two logs cover the whole run together.

A replay that runs from an FMU (its log in the FMU's resources) is not read here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cosim.errors import ScenarioError
from cosim.sensors import logs
from cosim.sensors.replay import RATIO_TOL, LogReplay


@dataclass(frozen=True)
class LogSpan:
    """Where one replay's log lies on the run's common time base.

    Attributes
    ----------
    block : str
        The replay block's name.
    log : str
        Its log file.
    start : float
        Common time at which its data start [s] (see the module docstring).
    end : float
        Common time at which its data end [s].
    dt : float
        Nominal sample interval [s].
    samples : int
        Samples in the log.
    time_offset : float
        The block's ``time_offset`` [s].
    first : float
        Time stamp of the log's first sample [s].
    covers_interval : bool
        True for a log of increments (data start one interval before the first stamp).
    """

    block: str
    log: str
    start: float
    end: float
    dt: float
    samples: int
    time_offset: float
    first: float
    covers_interval: bool

    @property
    def rate(self) -> float:
        """Sample rate [Hz]."""
        return 1.0 / self.dt


def _ms(x: float) -> str:
    """A duration in ms, as the messages give it (rounded to the ns)."""
    return f"{round(1e3 * x, 6) + 0.0:.6g} ms"


def _s(x: float) -> str:
    """A time in s, as the messages give it (rounded to the ns)."""
    return f"{round(x, 9) + 0.0:.9g} s"


def replay_blocks(master: Any) -> dict[str, dict[str, Any]]:
    """The in-process log replays of a built system and their parameters.

    Parameters
    ----------
    master : cosim.master.Master
        Built from the scenario (not run).

    Returns
    -------
    dict
        Block name -> {parameter: value (SI)}: the class's start values, updated with
        the scenario's; ``"__class__"`` holds the block class.
    """
    out: dict[str, dict[str, Any]] = {}
    for name, host in master.system.blocks.items():
        cls = getattr(host, "cls", None)
        if not (isinstance(cls, type) and issubclass(cls, LogReplay)):
            continue
        params = {v.name: v.start for v in host.variables.values() if v.causality == "parameter"}
        params.update(master.system.parameters.get(name, {}))
        params["__class__"] = cls
        out[name] = params
    return out


def log_span(name: str, params: dict[str, Any]) -> LogSpan:
    """Scan one replay's log and place it on the common time base.

    Parameters
    ----------
    name : str
        The block.
    params : dict
        Its parameters (:func:`replay_blocks`).

    Returns
    -------
    LogSpan

    Raises
    ------
    ScenarioError
        An empty ``log``.
    LogError
        The log fails one of its own checks (file, line, time and fix).
    """
    cls = params["__class__"]
    path = str(params.get("log") or "")
    if not path:
        raise ScenarioError(
            f"block '{name}' ({cls.__name__}) has no log: set its parameter log to the file",
            key=f"blocks.{name}.parameters.log",
        )
    rate = float(params.get("sample_rate") or 0.0)
    log = logs.SensorLog(
        path,
        getattr(logs, cls.layout),
        sample_rate=rate if rate > 0.0 else None,
        jitter=float(params.get("jitter", logs.JITTER)),
        duplicates="drop" if params.get("drop_duplicates") else "error",
        chunk_rows=max(1, int(params.get("chunk_rows", logs.CHUNK_ROWS))),
    )
    s = log.scan()
    offset = float(params.get("time_offset", 0.0))
    lead = s.dt if cls.covers_interval else 0.0
    return LogSpan(
        name,
        path,
        s.t_first - lead - offset,
        s.t_last - offset,
        s.dt,
        s.samples,
        offset,
        s.t_first,
        bool(cls.covers_interval),
    )


def check_rate(span: LogSpan, step: float, rate: int, stop: float, start: float) -> None:
    """Refuse a block step that does not hold a whole number of samples, or a short log.

    Parameters
    ----------
    span : LogSpan
        The log.
    step : float
        ``master.step`` [s].
    rate : int
        The block's ``rate`` (it steps every ``rate``-th macro step).
    stop, start : float
        ``master.stop`` and ``master.start`` [s].

    Raises
    ------
    ScenarioError
        Keyed ``master.step`` or ``master.stop``.
    """
    h = step * rate
    ratio = h / span.dt
    m = round(ratio)
    if m < 1 or abs(ratio - m) > RATIO_TOL * max(ratio, 1.0):
        lo, hi = max(1, math.floor(ratio)), max(1, math.ceil(ratio))
        steps = f"{lo * span.dt / rate:.9g} s" + (
            "" if lo == hi else f" or {hi * span.dt / rate:.9g} s"
        )
        raise ScenarioError(
            f"block '{span.block}' steps every {h:.9g} s, which holds {ratio:.9g} samples of "
            f"its log {span.log} at {span.rate:.9g} Hz: a step must hold a whole number of "
            f"samples (nothing is interpolated); use master.step = {steps}",
            key="master.step",
        )
    length = span.end - span.start
    if stop - start > length + 0.5 * span.dt:
        raise ScenarioError(
            f"the run lasts {stop - start:.9g} s, but the log {span.log} of block "
            f"'{span.block}' holds {length:.9g} s of data ({span.samples} samples at "
            f"{span.rate:.9g} Hz); set master.stop <= {start + length:.9g} s",
            key="master.stop",
        )


def check_pair(a: LogSpan, b: LogSpan) -> None:
    """Refuse two logs whose data do not start at the same instant (within half a sample).

    Parameters
    ----------
    a, b : LogSpan
        The two logs.

    Raises
    ------
    ScenarioError
        Keyed ``blocks.<b>.parameters.time_offset``: both starts, their difference, the
        tolerance, and the ``time_offset`` (or the samples to cut) that fixes it.
    """
    tol = 0.5 * min(a.dt, b.dt)
    gap = b.start - a.start
    if abs(gap) <= tol:
        return

    def where(s: LogSpan) -> str:
        what = "first interval starts" if s.covers_interval else "first sample is"
        return (
            f"'{s.block}' ({s.log}, {s.rate:.6g} Hz, time_offset {_ms(s.time_offset)}) "
            f"{what} at {_s(s.start)}"
        )

    earlier = a if gap > 0 else b
    cut = abs(gap) / earlier.dt
    cut_text = (
        f", or cut the first {round(cut)} samples of {earlier.log} if it started earlier"
        if abs(cut - round(cut)) < 0.05 and round(cut) >= 1
        else ""
    )
    raise ScenarioError(
        f"logs out of step: {where(a)}, {where(b)} on the common time base: "
        f"{_ms(abs(gap))} apart, more than half a sample ({_ms(tol)}); the replays pair "
        f"the logs sample by sample from their starts; if the clocks differ set "
        f'[blocks.{b.block}] time_offset = "{_ms(b.time_offset + gap)}"{cut_text}',
        key=f"blocks.{b.block}.parameters.time_offset",
    )


def check_log_pairs(scenario: Any, master: Any) -> list[LogSpan]:
    """Check the log replays of a built scenario with two or more, each against the first.

    Parameters
    ----------
    scenario : cosim.scenario.Scenario
        The loaded scenario (its file, for the messages).
    master : cosim.master.Master
        Built from it (not run).

    Returns
    -------
    list of LogSpan
        One per in-process replay (empty when the scenario has fewer than two: a single
        log is read and checked by its replay when the run starts, as before).

    Raises
    ------
    ScenarioError, LogError
        The first problem, in one line with the numbers and the fix.
    """
    s = master.settings
    spans: list[LogSpan] = []
    replays = replay_blocks(master)
    if len(replays) < 2:  # one log is checked by its replay when the run starts
        return spans
    try:
        for name, params in replays.items():
            span = log_span(name, params)
            check_rate(span, s.step, int(master.system.rates.get(name, 1)), s.stop, s.start)
            spans.append(span)
        for other in spans[1:]:
            check_pair(spans[0], other)
    except ScenarioError as exc:
        if exc.file is not None:
            raise
        raise scenario.error(exc.message, key=exc.key) from None
    return spans
