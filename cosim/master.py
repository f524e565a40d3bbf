"""The master algorithm: fixed macro step, multi-rate, Gauss-Seidel or Jacobi coupling.

The coupling rule (README, "The coupling rule", has the diagram):

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
- A block error or a non-finite output stops the run with a :class:`SimulationError`
  naming block, variable or call and time; the result recorded so far is attached.

The exchange: each block's Real outputs are one contiguous part of a float64 value table.
At the start of a run every host binds a reader that fills its part and a writer that
takes its inputs from one array (:meth:`BlockHost.real_reader`, :meth:`BlockHost.real_writer`);
per step the master gathers a sink's inputs with one precomputed index array, from the live
table (Gauss-Seidel) or from the ``t_n`` snapshot (Jacobi), scales them by the connections'
unit factors only for a block that has a factor other than 1, and checks each block's
outputs for finiteness right after its step. Links that carry other types (Integer,
Boolean, Enumeration, String, Float32, the FMI 3 integers) follow the same rule through
:class:`cosim.typed_values.TypedExchange`, which extends the writer and reader of the
blocks they touch (docs/coupling.md, "Types and arrays").
"""

from __future__ import annotations

import heapq
import math
import numbers
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.blockchecks import check_blocks
from cosim.blocks import BlockCallError, BlockHost, BlockTerminated
from cosim.clock import CLOCKS, EXACT, Clock
from cosim.errors import ScenarioError, SimulationError
from cosim.results import RunResult
from cosim.typed_values import TypedExchange, is_typed_link
from cosim.variables import REAL, Variable

GAUSS_SEIDEL = "gauss-seidel"
JACOBI = "jacobi"

#: The most macro steps a run may have (refused by :class:`MasterSettings`).
MAX_STEPS = 10**9
#: The largest recording a run may keep in memory [bytes] (refused by :class:`Master`):
#: rows (``n_steps // record_every + 1``) x columns (``time`` and every recorded
#: variable) x 8 bytes.
MAX_RECORDING_BYTES = 2 * 2**30


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
    """Steps a :class:`System` with fixed macro steps.

    Parameters
    ----------
    system : System
        Blocks, connections, parameters, rates, recording.
    settings : MasterSettings
        Step, start, stop, coupling, record interval.
    metadata : dict, optional
        Copied into the result (scenario hash, seeds, ...).
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
        record = sys_.record
        if record is None:
            record = [
                (b, v.name) for b in sys_.blocks for v in sys_.blocks[b].by_causality("output")
            ]
        self.record = record
        # Real columns come from the value table; the other types (Integer, Boolean,
        # Enumeration, FMI 3 integers, String) are read from their block when a row is
        # recorded (they hold between steps like everything else). Columns are 1-based
        # (0 is the time).
        self.types = {f"{b}.{v}": sys_.blocks[b].variables[v].type for b, v in record}
        real = [
            (i + 1, r)
            for i, r in enumerate(record)
            if sys_.blocks[r[0]].variables[r[1]].type == REAL
        ]
        self._real_cols = np.array([i for i, _r in real], dtype=int)
        typed: dict[tuple[str, str], list[tuple[int, int, str]]] = {}
        for i, (b, v) in enumerate(record, start=1):
            var = sys_.blocks[b].variables[v]
            if var.type != REAL:
                typed.setdefault((b, var.type), []).append((i, var.vr, f"{b}.{v}"))
        self._typed = [
            (
                sys_.blocks[b],
                vtype,
                [vr for _i, vr, _n in items],
                [i for i, _vr, _n in items],
                [n for *_x, n in items],
            )
            for (b, vtype), items in typed.items()
        ]
        s = self.settings
        rows, columns = s.n_steps // s.record_every + 1, len(record) + 1
        if rows * columns * 8 > MAX_RECORDING_BYTES:
            raise ScenarioError(
                f"the recording would hold {rows} rows x {columns} columns = "
                f"{rows * columns * 8 / 2**30:.3g} GiB, more than the limit of "
                f"{MAX_RECORDING_BYTES / 2**30:g} GiB; record less often (output.every), "
                f"fewer variables (output.variables) or a shorter run (master.stop)",
                key="output.every",
            )
        self._record_idx = np.array([slots[r] for _i, r in real], dtype=int)

    def warn_loops(self) -> None:
        """Warn (:class:`CouplingWarning`) once per feedback loop broken by a delay.

        :meth:`run` calls it; ``ins-cosim check`` and campaigns call it without running.
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

    def run(self, on_row: Callable[[np.ndarray], None] | None = None) -> RunResult:
        """Initialise every block, step to the stop time, and return the recording.

        Parameters
        ----------
        on_row : callable, optional
            Called with each recorded row as soon as it is written: a float64 view,
            shape (1 + recorded columns,), time [s] first, then the columns in SI units
            (text columns NaN); copy it to keep it (:mod:`cosim.isolate` streams the rows
            of an isolated run to its parent this way).

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
        self.warn_loops()
        s = self.settings
        sys_ = self.system
        h, n_steps = s.step, s.n_steps
        time_of = Clock(s.start, h, s.clock).time  # t_n [s] of macro step n
        t0 = time_of(0)
        n_rows = n_steps // s.record_every + 1
        names = ["time"] + [f"{b}.{v}" for b, v in self.record]
        data = np.zeros(n_rows, dtype=[(n, "f8") for n in names])
        values = self._start_values.copy()
        rates = [sys_.rates.get(name, 1) for name in self.order]
        jacobi = s.coupling == JACOBI
        row = 0

        def result(status: str, error: str = "", ended: dict | None = None) -> RunResult:
            meta = dict(self.metadata)
            meta["types"] = self.types
            if ended is not None:  # a block asked to end the run (not a failure)
                meta["terminated"] = ended
            # the seeds in force for this run (campaigns change them between runs)
            meta["seeds"] = {b: p["seed"] for b, p in sys_.parameters.items() if "seed" in p}
            meta["master"] = {
                "step": h,
                "start": s.start,
                "stop": s.stop,
                "coupling": s.coupling,
                "clock": s.clock,
                "record_every": s.record_every,
                "order": self.order,
                "delayed": [str(c) for c in self.delayed],
                "rates": dict(zip(self.order, rates, strict=True)),
            }
            texts = {n: list(x) for n, x in strings.items()}
            return RunResult(data[:row].copy(), meta, status=status, error=error, strings=texts)

        def fail(
            exc: Exception, name: str, t: float, variable: str | None, call: str | None = None
        ) -> SimulationError:
            err = SimulationError(str(exc), block=name, time=t, variable=variable, call=call)
            err.result = result("failed", str(err))
            return err

        # Per block, in stepping order: name, host, rate, its inputs (source slots, factors
        # or None when every factor is 1: x * 1.0 == x; the host's array writer) and its
        # outputs (the host's reader into the block's part of the value table, that part,
        # its tolist for the finiteness check, the variables). Readers and writers are bound
        # here, for this run (a reset makes new in-process instances).
        plan = []
        links = self._typed_links  # links of other types than Float64 (cosim.typed_values)
        links.restart()
        snap = links.snapshot if jacobi and links.links else None
        for name, k in zip(self.order, rates, strict=True):
            host = sys_.blocks[name]
            in_vrs, in_idx, factor = self._inputs[name]
            out_vrs, part, outs = self._outputs[name]
            unit = bool(np.all(factor == 1.0))
            out = values[part]
            put, read = links.bind(
                name,
                host,
                host.real_writer(in_vrs) if in_vrs else None,
                host.real_reader(out_vrs, out) if out_vrs else None,
                jacobi,
            )
            plan.append(
                (
                    name,
                    host,
                    k,
                    in_idx,
                    None if unit else factor,
                    put,
                    read,
                    out,
                    out.tolist,
                    outs,
                )
            )
        # the recording as a plain (rows, columns) float view of the structured array
        table = data.view(np.float64).reshape(n_rows, len(names))
        record_idx, real_cols, typed = self._record_idx, self._real_cols, self._typed
        # columns and value slots as slices where they are consecutive (the usual case:
        # every output recorded, in order): one slice copy per row
        real_cols_at: slice | np.ndarray = _as_slice(real_cols)
        record_from: np.ndarray | None = None
        record_part = _as_slice(record_idx)
        if isinstance(record_part, slice):
            record_from = values[record_part]
        strings: dict[str, list[str]] = {
            n: [] for _h, vtype, _v, _c, ns in typed if vtype in ("String", "Binary") for n in ns
        }

        def write(row: int, t: float) -> None:
            line = table[row]
            line[0] = t
            line[real_cols_at] = values[record_idx] if record_from is None else record_from
            for host, vtype, vrs, cols, ns in typed:
                got = host.get_values(vtype, vrs)
                if vtype in ("String", "Binary"):  # text columns: NaN here, text in the CSV
                    for n, x in zip(ns, got, strict=True):
                        if isinstance(x, bytes):  # Binary as hex digits; FMI 2 strings as bytes
                            x = x.hex() if vtype == "Binary" else x.decode("utf-8", "replace")
                        strings[n].append(str(x))
                    line[cols] = np.nan
                else:  # Integer, Boolean, Enumeration, FMI 3 numbers: exact up to 2**53
                    line[cols] = [float(x) for x in got]
            if on_row is not None:
                on_row(line)

        def check(name: str, out: np.ndarray, outs: list[Variable], t: float) -> None:
            # called when the sum of out is not finite: an inf or nan in out, or an overflow
            bad = np.flatnonzero(~np.isfinite(out))
            if bad.size:
                i = int(bad[0])
                raise fail(ValueError(f"output is {out[i]} (not finite)"), name, t, outs[i].name)

        # -- initialisation, in stepping order ----------------------------------
        before_init = values.copy()
        for name, host, _k, in_idx, factor, put, read, out, listed, outs in plan:
            try:
                host.setup(t0, sys_.parameters.get(name, {}))
                if put is not None:
                    x = (before_init if jacobi else values)[in_idx]
                    put(x if factor is None else x * factor)
                host.exit_init()
            except BlockCallError as exc:
                raise fail(exc, name, t0, None, exc.call) from exc
            if read is not None:
                read()
                total = sum(listed())
                if total - total != 0.0:  # inf or nan (or a sum that overflowed)
                    check(name, out, outs, t0)
        write(0, t0)
        row = 1

        # -- macro steps ----------------------------------------------------------
        every = s.record_every
        source = values.copy() if jacobi else values  # Jacobi: the t_n snapshot
        steps = [(p, p[1].do_step) for p in plan]  # bound now: after any wrapping
        t_end = t0
        for n in range(n_steps):
            if jacobi:
                source[...] = values
                if snap is not None:
                    snap()
            t_n, t_end = t_end, time_of(n + 1)
            for (name, _host, k, in_idx, factor, put, read, out, listed, outs), do_step in steps:
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
                    # the block asked to end the run: keep its last sample, stop cleanly
                    # (blocks after it in the order have not stepped to this time)
                    if read is not None:
                        read()
                        total = sum(listed())
                        if total - total != 0.0:  # inf or nan (or a sum that overflowed)
                            check(name, out, outs, exc.time)
                    write(row, exc.time)
                    row += 1
                    ended = {"block": name, "time": exc.time, "call": exc.call, "reason": str(exc)}
                    return result("completed", ended=ended)
                except BlockCallError as exc:
                    raise fail(exc, name, t_begin, None, exc.call) from exc
                if read is not None:
                    read()
                    total = sum(listed())
                    if total - total != 0.0:  # inf or nan (or a sum that overflowed)
                        check(name, out, outs, t_end)
            if (n + 1) % every == 0:
                write(row, t_end)
                row += 1
        return result("completed")

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


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice when it is consecutive (a view instead of a copy), else itself."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index
