"""The master algorithm: fixed macro step, multi-rate, Gauss-Seidel or Jacobi coupling.

The coupling rule (docs/concepts.md, "The coupling rule", has the diagram):

- Time ``t_n`` comes from an integer counter ``n``; nothing accumulates. By default
  ``t_n`` is the double nearest the exact ``t0 + n h`` (one rounding, as libcosim's
  integer clock); ``clock = "fmpy"`` computes ``t0 + n * h`` in floating point, as fmpy
  does (:mod:`cosim.clock`, docs/coupling.md).
- A block of rate ``k`` steps once every ``k`` macro steps, in the macro steps ``n`` with
  ``(n + 1) % k == 0``, from ``t_{n+1-k}`` to ``t_{n+1}`` (step size ``k h``): its step *ends*
  on the macro step's end, so what it publishes is valid at the same instant as everyone
  else's. Its inputs are set just before it steps and held over its step; its outputs
  hold their last value until its next step. With ``k = 1`` this is the plain rule.
- **Gauss-Seidel** (default): blocks step in the topological order of the connections.
  A block reads each input from the value its source holds *at that moment*: a source
  earlier in the order has already stepped in this macro step, so the sink sees the
  source's value at ``t_{n+1}`` (no delay). A connection that closes a feedback loop runs
  against the order: its sink sees the value at ``t_n`` (one macro step of delay), and
  the run warns with the loop's blocks and the delayed connection.
- **Jacobi**: every block reads its inputs from the values all sources held at ``t_n``,
  before anyone stepped (one macro step of delay on every connection; order irrelevant).
- Initialisation follows the same rule. Gauss-Seidel: in stepping order, each block is
  initialised with inputs taken from the t0 outputs of its already-initialised sources
  (start values for delayed connections). Jacobi: every block is initialised with its
  sources' start values (the snapshot before anyone initialised), as libcosim does.
- A block error stops the run with a :class:`SimulationError` naming block, call and
  time. Everything else watches the stepping (:mod:`cosim.observers`): the recording
  (:mod:`cosim.recording`, which keeps the rows recorded before a failure), the
  finiteness check (a non-finite output stops the run naming block, variable, time),
  progress, the crash step board, early stops.

The exchange: each block's Real outputs are one contiguous part of a float64 value table.
At the start of a run every host binds a reader that fills its part and a writer that
takes its inputs from one array (:meth:`BlockHost.real_reader`, :meth:`BlockHost.real_writer`);
per step the master gathers a sink's inputs with one precomputed index array, from the live
table (Gauss-Seidel) or from the ``t_n`` snapshot (Jacobi), scales them by the connections'
unit factors only for a block that has a factor other than 1; the observers see each
block's outputs right after its step. Links that carry other types (Integer, Boolean,
Enumeration, String, Float32, the FMI 3 integers) follow the same rule through
:class:`cosim.typed_values.TypedExchange`, which extends the writer and reader of the
blocks they touch (docs/coupling.md, "Types and arrays").
"""

from __future__ import annotations

import heapq
import math
import numbers
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.blockchecks import check_blocks
from cosim.blocks import BlockCallError, BlockHost, BlockParametersRefused, BlockTerminated
from cosim.clock import CLOCKS, EXACT, Clock
from cosim.errors import ParameterRefusedError, ScenarioError, SimulationError
from cosim.observers import Ending, hooks_of
from cosim.recording import MAX_RECORDING_BYTES, record_run  # noqa: F401 (the docs' name)
from cosim.results import RunResult
from cosim.typed_values import TypedExchange, is_typed_link
from cosim.variables import REAL, Variable

GAUSS_SEIDEL = "gauss-seidel"
JACOBI = "jacobi"

#: The most macro steps a run may have (refused by :class:`MasterSettings`).
MAX_STEPS = 10**9


class CouplingWarning(UserWarning):
    """A feedback loop was broken with a one-step delay."""


@dataclass(frozen=True)
class Connection:
    """A scalar link from an output to an input.

    Attributes
    ----------
    src_block, src_var : str
        Source block and its output (scalar name).
    dst_block, dst_var : str
        Sink block and its input (scalar name).
    factor : float
        Unit conversion applied to the value (source unit -> sink unit).
    """

    src_block: str
    src_var: str
    dst_block: str
    dst_var: str
    factor: float = 1.0

    def __str__(self) -> str:
        return f"{self.src_block}.{self.src_var} -> {self.dst_block}.{self.dst_var}"


@dataclass(frozen=True)
class MasterSettings:
    """Master settings, checked once when made; frozen (an override makes a new object).

    Attributes
    ----------
    step : float
        Macro step h [s], > 0.
    stop : float
        Stop time [s]; ``stop - start`` must be a whole positive number of steps.
    start : float
        Start time t0 [s].
    coupling : str
        ``"gauss-seidel"`` or ``"jacobi"`` (case and ``_`` for ``-`` do not matter; the
        attribute holds the lower-case, hyphenated form).
    record_every : int
        Record every k-th macro step (t0 is always recorded), >= 1.
    clock : str
        How the time of macro step n is computed (:mod:`cosim.clock`): ``"exact"``
        (default: the double nearest the exact ``t0 + n h``) or ``"fmpy"`` (``t0 + n * h``
        in floating point, as fmpy's ``simulate_fmu``).
    n_steps : int
        Number of macro steps, derived from the above (not an argument).

    Raises
    ------
    ScenarioError
        With the ``master.*`` key of the inconsistent setting.
    """

    step: float
    stop: float
    start: float = 0.0
    coupling: str = GAUSS_SEIDEL
    record_every: int = 1
    clock: str = EXACT
    n_steps: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for key in ("step", "stop", "start"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ScenarioError(f"expected a time in s, got {value!r}", key=f"master.{key}")
            if not math.isfinite(value):
                raise ScenarioError(
                    f"master.{key} must be a finite time, got {value}", key=f"master.{key}"
                )
        if not self.step > 0:
            raise ScenarioError(f"master.step must be > 0 s, got {self.step}", key="master.step")
        n = (self.stop - self.start) / self.step
        if n < 1 or not math.isclose(n, round(n), rel_tol=0, abs_tol=1e-9 * max(1.0, n)):
            raise ScenarioError(
                f"stop - start = {self.stop - self.start} s is not a whole positive number of "
                f"steps of {self.step} s; change master.stop or master.step",
                key="master.stop",
            )
        if round(n) > MAX_STEPS:
            raise ScenarioError(
                f"{n:.6g} macro steps ((stop - start) / step), more than the limit of "
                f"{MAX_STEPS:.0e}; use a larger master.step or a shorter run",
                key="master.stop",
            )
        coupling = str(self.coupling).lower().replace("_", "-")
        if coupling not in (GAUSS_SEIDEL, JACOBI):
            raise ScenarioError(
                f"expected 'gauss-seidel' or 'jacobi', got '{self.coupling}'",
                key="master.coupling",
            )
        object.__setattr__(self, "coupling", coupling)
        if self.clock not in CLOCKS:
            raise ScenarioError(
                f"expected one of {', '.join(repr(c) for c in CLOCKS)}, got {self.clock!r}",
                key="master.clock",
            )
        every = self.record_every
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise ScenarioError(f"expected a positive integer, got {every!r}", key="output.every")
        object.__setattr__(self, "n_steps", int(round(n)))


@dataclass
class System:
    """Blocks, their parameters and rates, connections and what to record.

    Attributes
    ----------
    blocks : dict
        Block name -> host, in declaration order.
    connections : list of Connection
        Scalar links.
    parameters : dict
        Block name -> {scalar variable name: value}.
    rates : dict
        Block name -> k (steps every k-th macro step); default 1.
    record : list of (str, str)
        (block, scalar output) pairs to record; None records every Real output.
    """

    blocks: dict[str, BlockHost]
    connections: list[Connection]
    parameters: dict[str, dict[str, object]] = field(default_factory=dict)
    rates: dict[str, int] = field(default_factory=dict)
    record: list[tuple[str, str]] | None = None


def strongly_connected(nodes: list[str], edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of the block graph (Tarjan's algorithm, iterative).

    Parameters
    ----------
    nodes : list of str
        Block names in declaration order.
    edges : dict
        Block name -> names of the blocks it feeds.

    Returns
    -------
    list of list of str
        The components in no particular order, each in declaration order;
        O(nodes + edges log edges).
    """
    position = {n: i for i, n in enumerate(nodes)}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    comps: list[list[str]] = []
    counter = 0
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root], key=position.__getitem__)))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges[child], key=position.__getitem__))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == node:
                        break
                comps.append(sorted(comp, key=position.__getitem__))
    return comps


def schedule(
    names: list[str], connections: list[Connection]
) -> tuple[list[str], list[Connection], list[list[str]]]:
    """Gauss-Seidel order of the blocks and the connections delayed to break loops.

    Blocks are ordered topologically; ties and the order inside a feedback loop follow
    the declaration order. Inside a loop, a connection whose sink comes before (or is)
    its source is delayed by one macro step. Near-linear: O((blocks + connections) log
    blocks).

    Parameters
    ----------
    names : list of str
        Block names in declaration order.
    connections : list of Connection
        Scalar links.

    Returns
    -------
    order : list of str
        Stepping order.
    delayed : list of Connection
        Connections that run against the order (one macro step of delay).
    loops : list of list of str
        The blocks of each feedback loop, in stepping order.
    """
    edges: dict[str, set[str]] = {n: set() for n in names}
    for c in connections:
        edges[c.src_block].add(c.dst_block)
    comps = strongly_connected(names, edges)
    comp_of = {n: i for i, comp in enumerate(comps) for n in comp}
    indeg = {i: 0 for i in range(len(comps))}
    succ: dict[int, set[int]] = {i: set() for i in range(len(comps))}
    for a in names:
        for b in edges[a]:
            ca, cb = comp_of[a], comp_of[b]
            if ca != cb and cb not in succ[ca]:
                succ[ca].add(cb)
                indeg[cb] += 1
    # Kahn's algorithm; among the ready components the one declared first goes first
    declared = {n: i for i, n in enumerate(names)}
    first = [declared[comp[0]] for comp in comps]
    ready = [(first[i], i) for i in indeg if indeg[i] == 0]
    heapq.heapify(ready)
    order: list[str] = []
    while ready:
        _, i = heapq.heappop(ready)
        order.extend(comps[i])
        for j in succ[i]:
            indeg[j] -= 1
            if indeg[j] == 0:
                heapq.heappush(ready, (first[j], j))
    position = {n: i for i, n in enumerate(order)}
    delayed = [c for c in connections if position[c.dst_block] <= position[c.src_block]]
    loops = [comp for comp in comps if len(comp) > 1 or comp[0] in edges[comp[0]]]
    loops = [sorted(comp, key=position.__getitem__) for comp in loops]
    return order, delayed, loops


class Master:
    """Steps a :class:`System` with fixed macro steps; observers watch (:mod:`cosim.observers`).

    Parameters
    ----------
    system : System
        Blocks, connections, parameters, rates, recording.
    settings : MasterSettings
        Step, start, stop, coupling, record interval.
    metadata : dict, optional
        Copied into the result (scenario hash, seeds, ...).

    Attributes
    ----------
    order : list of str
        Stepping order (blocks are indexed by their position in it).
    output_parts : list of (str, slice, list of Variable)
        Per block in stepping order: its name, its part of the value table, its Real
        outputs.
    slots : dict
        ``(block, output)`` -> index of its Real output in the value table.
    values : ndarray or None
        The live value table of the run in progress (float64, every Real output).
    """

    def __init__(
        self, system: System, settings: MasterSettings, metadata: dict | None = None
    ) -> None:
        self.system = system
        self.settings = settings
        self.metadata = dict(metadata or {})
        s = settings
        for name, k in system.rates.items():
            if not isinstance(k, int) or k < 1 or s.n_steps % k:
                raise ScenarioError(
                    f"rate must be a positive integer dividing the number of macro steps "
                    f"({s.n_steps}), got {k!r}",
                    key=f"blocks.{name}.rate",
                )
        check_blocks(system, s.step)
        names = list(system.blocks)
        self.order, self.delayed, self.loops = schedule(names, system.connections)
        if s.coupling == JACOBI:
            self.delayed = list(system.connections)
        self.values: np.ndarray | None = None
        self._build_tables()

    def _build_tables(self) -> None:
        sys_ = self.system
        slots: dict[tuple[str, str], int] = {}
        self._outputs: dict[str, tuple[list[int], slice, list[Variable]]] = {}
        start_values: list[float] = []
        for name in self.order:
            host = sys_.blocks[name]
            outs = [v for v in host.by_causality("output") if v.type == REAL]
            first = len(start_values)
            for v in outs:
                slots[(name, v.name)] = len(start_values)
                # An output without a start value (FMI initial="calculated") has no value
                # before initialisation; where one is read then (Jacobi initialisation, a
                # delayed loop connection) the master passes 0.0.
                start_values.append(float(v.start) if v.start is not None else 0.0)
            # each block's outputs are one contiguous part of the value table
            self._outputs[name] = ([v.vr for v in outs], slice(first, len(start_values)), outs)
        self.slots = slots
        self.output_parts = [(n, self._outputs[n][1], self._outputs[n][2]) for n in self.order]
        self._start_values = np.array(start_values)
        self._inputs: dict[str, tuple[list[int], np.ndarray, np.ndarray]] = {}
        into: dict[str, list[Connection]] = {name: [] for name in self.order}
        typed = [c for c in sys_.connections if is_typed_link(sys_.blocks, c)]
        self._typed_links = TypedExchange(sys_.blocks, typed)  # not Float64: typed_values
        typed_set = set(typed)
        for c in sys_.connections:
            if c not in typed_set:
                into[c.dst_block].append(c)
        for name in self.order:
            host = sys_.blocks[name]
            # in value-reference order (vector elements in order: few slice copies); the
            # sort is stable, so an input connected twice keeps its connections' order
            conns = sorted(into[name], key=lambda c: host.variables[c.dst_var].vr)
            self._inputs[name] = (
                [host.variables[c.dst_var].vr for c in conns],
                np.array([slots[(c.src_block, c.src_var)] for c in conns], dtype=int),
                np.array([c.factor for c in conns]),
            )

    def warn_loops(self) -> None:
        """Warn (:class:`CouplingWarning`) once per feedback loop broken by a delay.

        :meth:`execute` calls it; ``ins-cosim check`` and campaigns call it without running.
        """
        if self.settings.coupling != GAUSS_SEIDEL:
            return
        for loop in self.loops:
            links = [str(c) for c in self.delayed if c.dst_block in loop and c.src_block in loop]
            chain = " -> ".join(loop + [loop[0]])
            warnings.warn(
                f"feedback loop {chain}: connection(s) {', '.join(links)} "
                f"delayed by one macro step",
                CouplingWarning,
                stacklevel=3,
            )

    @property
    def rates(self) -> list[int]:
        """Rate k of each block, in stepping order."""
        return [self.system.rates.get(name, 1) for name in self.order]

    def run(
        self,
        on_row: Callable[[np.ndarray], None] | None = None,
        observers: Sequence[Any] = (),
    ) -> RunResult:
        """Step to the stop time with the recording and the finiteness check watching.

        The same as :func:`cosim.recording.record_run` (``record_run(self, ...)``).

        Parameters
        ----------
        on_row : callable, optional
            Called with each recorded row as soon as it is written
            (:class:`cosim.recording.Recorder`).
        observers : sequence, optional
            More observers (:class:`cosim.observers.Observer`), after those two.

        Returns
        -------
        RunResult
            Recording (structured array, ``time`` first) and metadata.

        Raises
        ------
        SimulationError
            A block failed or produced a non-finite output; ``error.result`` holds the
            recording up to the last completed macro step.
        """
        return record_run(self, on_row=on_row, observers=observers)

    def execute(self, observers: Sequence[Any] = ()) -> Ending:
        """Initialise every block and step to the stop time, the observers watching.

        Parameters
        ----------
        observers : sequence of Observer
            What watches the run (:mod:`cosim.observers`); their hooks are called in
            this order.

        Returns
        -------
        Ending
            Completed at the stop time, or early: a block ended the run
            (``terminated``) or an observer asked to (``stopped``).

        Raises
        ------
        SimulationError
            A block failed, or an observer failed the run (after every ``on_stop`` saw
            the failure).
        """
        self.warn_loops()
        s = self.settings
        sys_ = self.system
        n_steps = s.n_steps
        time_of = Clock(s.start, s.step, s.clock).time  # t_n [s] of macro step n
        t0 = time_of(0)
        values = self._start_values.copy()
        self.values = values
        jacobi = s.coupling == JACOBI
        for f in hooks_of(observers).on_start:
            f(self, t0)
        hooks = hooks_of(observers)  # looked up after on_start: it may bind them for this run
        before_block, after_block = hooks.before_block, hooks.after_block
        after_step = hooks.after_step

        def stop(ending: Ending) -> Ending:
            for f in hooks.on_stop:
                f(ending)
            return ending

        # Per block, in stepping order: index, name, host, rate, its inputs (source
        # slots, factors or None when every factor is 1: x * 1.0 == x; the host's array
        # writer), its reader into the block's part of the value table, and its do_step
        # (noting the observers' before_block first, when there are any). Readers and
        # writers are bound here, for this run (a reset makes new in-process instances).
        plan = []
        links = self._typed_links  # links of other types than Float64 (cosim.typed_values)
        links.restart()
        snap = links.snapshot if jacobi and links.links else None
        for i, (name, k) in enumerate(zip(self.order, self.rates, strict=True)):
            host = sys_.blocks[name]
            in_vrs, in_idx, factor = self._inputs[name]
            out_vrs, part, _outs = self._outputs[name]
            unit = bool(np.all(factor == 1.0))
            put, read = links.bind(
                name,
                host,
                host.real_writer(in_vrs) if in_vrs else None,
                host.real_reader(out_vrs, values[part]) if out_vrs else None,
                jacobi,
            )
            do_step = host.do_step
            if before_block:
                do_step = _noted(do_step, before_block, i)
            plan.append(
                (
                    i,
                    name,
                    host,
                    k,
                    in_idx,
                    None if unit else factor,
                    put,
                    read,
                    do_step,
                )
            )
        try:
            # -- initialisation, in stepping order ----------------------------------
            before_init = values.copy()
            for i, name, host, _k, in_idx, factor, put, read, _step in plan:
                for f in before_block:
                    f(i, t0, True)
                try:
                    host.setup(t0, sys_.parameters.get(name, {}))
                    if put is not None:
                        x = (before_init if jacobi else values)[in_idx]
                        put(x if factor is None else x * factor)
                    host.exit_init()
                except BlockCallError as exc:
                    raise _failure(exc, name, t0) from exc
                if read is not None:
                    read()
                for f in after_block:
                    f(i, t0)
            reason = _asked(after_step, -1, t0)
            if reason is not None:
                return stop(Ending("completed", t0, stopped={"time": t0, "reason": reason}))

            # -- macro steps ----------------------------------------------------------
            source = values.copy() if jacobi else values  # Jacobi: the t_n snapshot
            t_end = t0
            for n in range(n_steps):
                if jacobi:
                    source[...] = values
                    if snap is not None:
                        snap()
                t_n, t_end = t_end, time_of(n + 1)
                for i, name, _host, k, in_idx, factor, put, read, do_step in plan:
                    if k == 1:
                        t_begin = t_n  # time_of(n + 1 - k) with k = 1
                    elif (n + 1) % k:
                        continue
                    else:
                        t_begin = time_of(n + 1 - k)
                    if put is not None:
                        x = source[in_idx]
                        put(x if factor is None else x * factor)
                    # the step ends exactly on t_{n+1} as computed here: h_n = t_{n+1} - t_begin
                    try:
                        do_step(t_begin, t_end - t_begin)
                    except BlockTerminated as exc:
                        # the block asked to end the run: keep its last sample, stop
                        # cleanly (blocks after it in the order have not stepped to this time)
                        if read is not None:
                            read()
                        for f in after_block:
                            f(i, exc.time)
                        ended = {
                            "block": name,
                            "time": exc.time,
                            "call": exc.call,
                            "reason": str(exc),
                        }
                        return stop(Ending("completed", exc.time, terminated=ended))
                    except BlockCallError as exc:
                        raise _failure(exc, name, t_begin) from exc
                    if read is not None:
                        read()
                    for f in after_block:
                        f(i, t_end)
                asked = None
                for f in after_step:  # every observer sees the step, then the run may end
                    why = f(n, t_end)
                    if why:
                        asked = [why] if asked is None else [*asked, why]
                if asked is not None:
                    stopped = {"time": t_end, "reason": _reason(asked)}
                    return stop(Ending("completed", t_end, stopped=stopped))
            return stop(Ending("completed", t_end))
        except SimulationError as err:
            stop(Ending("failed", err.time, error=err))
            raise

    def reset(self) -> None:
        """Reset every block (FMI reset) so that :meth:`run` can run again.

        Campaigns instantiate the blocks once per worker and call ``reset()`` between
        runs; change ``system.parameters`` (e.g. seeds) before the next :meth:`run`.
        """
        for host in self.system.blocks.values():
            host.reset()

    def terminate(self) -> None:
        """Terminate every block (frees FMU instances)."""
        for host in self.system.blocks.values():
            try:
                host.terminate()
            except Exception as exc:  # terminating after a failure may fail again
                warnings.warn(f"block '{host.name}': terminate failed: {exc}", stacklevel=2)


def _failure(exc: BlockCallError, name: str, t: float) -> SimulationError:
    kind = ParameterRefusedError if isinstance(exc, BlockParametersRefused) else SimulationError
    return kind(str(exc), block=name, time=t, variable=None, call=exc.call)


def _noted(
    do_step: Callable[[float, float], None], notes: list[Callable[..., Any]], i: int
) -> Callable[[float, float], None]:
    """``do_step`` that calls the observers' ``before_block(i, t, False)`` first."""

    def step(t: float, h: float) -> None:
        for f in notes:
            f(i, t, False)
        do_step(t, h)

    return step


def _asked(after_step: list[Callable[[int, float], object]], n: int, t: float) -> str | None:
    """Show step ``n`` to every ``after_step``; the reason they give to end the run, or None."""
    asked = [why for why in [f(n, t) for f in after_step] if why]
    return _reason(asked) if asked else None


def _reason(asked: list[object]) -> str:
    """The reasons observers gave to end a run, as one text."""
    return "; ".join("an observer asked" if why is True else str(why) for why in asked)
