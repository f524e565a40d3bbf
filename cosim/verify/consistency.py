"""Consistency verdicts of the filters in a run: which outputs, their dof, the summary.

The statistics and their bands are :mod:`cosim.estimation.consistency`; this module finds
them in a recording, judges every one, words the result, and parses the requirement
``criterion = "consistent"`` (docs/consistency.md).

Declaration (what a filter block, in-process or an FMU, states)
---------------------------------------------------------------
* A Real output named ``nis`` or ``nees`` (or starting with ``nis_`` / ``nees_``) is a
  consistency statistic: the NIS of the last measurement update (held between updates,
  0 before the first) or the NEES of the current estimate.
* Its degrees of freedom: a recorded output ``<name>_dof`` of the same block (per update,
  for a filter whose measurement size changes with its mode), else ``"N dof"`` in the
  output's description (``"NIS of the last velocity update (chi-square, 3 dof)"``), else a
  requirement's ``dof`` key. A statistic without any is reported as not judged.
* Update instants: the samples where the NIS changes value (a recording at the update
  rate or finer sees every update; a coarser one sees a subset, still a valid sample).
* The NEES needs the truth: it is judged only when none of the block's inputs whose name
  contains ``true`` (``rpy_true``, ``rpy_s_true``, ...) runs unconnected.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.errors import ScenarioError
from cosim.estimation.consistency import (
    ConsistencyWindow,
    InconsistentSpan,
    inconsistent_spans,
    update_instants,
    window_edges,
    window_test,
)
from cosim.results import RunResult
from cosim.units import to_unit
from cosim.verify.requirements import DEFAULT_CONFIDENCE, Requirement, RunMetric
from cosim.verify.table_keys import TableError, check_keys, fraction, table_error

DEFAULT_FALSE_ALARM = 0.01
"""Per-run false-alarm rate of the automatic check (all signals and windows together)."""
DEFAULT_WINDOWS = 10
"""Windows a signal's span is cut into when no window length is given ..."""
MIN_SAMPLES = 10
"""... fewer when the span has fewer than this many samples per window (at least one)."""
MAX_SPANS_SHOWN = 3
DEFAULT_PASS_PROBABILITY = 0.95
"""Pass rate a campaign must show for a ``consistent`` requirement (statistic pass_rate)."""
KINDS = ("nis", "nees")
_DOF = re.compile(r"(\d+)\s*dof\b", re.IGNORECASE)

CONSISTENT_KEYS = {
    "id",
    "text",
    "signal",
    "criterion",
    "dof",
    "false_alarm",
    "window",
    "from",
    "until",
    "statistic",
    "probability",
    "confidence",
    "on_failure",
}


def statistic_kind(column: str) -> str | None:
    """``"nis"``, ``"nees"`` or None for a column ``block.var`` (see the module docstring).

    Parameters
    ----------
    column : str
        A recorded column name.

    Returns
    -------
    str or None
    """
    var = column.rsplit(".", 1)[-1]
    if var.endswith("_dof") or "[" in var:
        return None
    for kind in KINDS:
        if var == kind or var.startswith(f"{kind}_"):
            return kind
    return None


def declared_dof(description: str) -> int | None:
    """The ``"N dof"`` of an output's description, or None.

    Parameters
    ----------
    description : str
        The output's description (``"NIS of the last update (chi-square, 3 dof)"``).

    Returns
    -------
    int or None
    """
    m = _DOF.search(description or "")
    return int(m.group(1)) if m else None


def truth_connected(metadata: Mapping[str, Any], block: str) -> bool:
    """False when an input of ``block`` named ``*true*`` runs unconnected.

    Parameters
    ----------
    metadata : mapping
        A run's metadata (its ``unconnected``: block -> {input: start value}).
    block : str
        The filter block.

    Returns
    -------
    bool
    """
    left = (metadata.get("unconnected") or {}).get(block) or {}
    return not any("true" in name for name in left)


# ------------------------------------------------------------------------ one signal
@dataclass
class SignalCheck:
    """The verdict of one statistic of one run.

    Attributes
    ----------
    column : str
        The recorded column (``"align.nis"``).
    kind : str
        ``"nis"`` or ``"nees"``.
    dof : str
        The degrees of freedom as stated (``"3"``, or ``"per update (align.nis_dof)"``).
    samples : int
        Samples judged (update instants for NIS).
    alpha : float
        False-alarm rate of each window.
    windows : list of ConsistencyWindow
        The judged windows.
    spans : list of InconsistentSpan
        Merged flagged windows (empty: consistent).
    skipped : str
        Why the signal is not judged (else empty).
    """

    column: str
    kind: str
    dof: str = ""
    samples: int = 0
    alpha: float = math.nan
    windows: list[ConsistencyWindow] = field(default_factory=list)
    spans: list[InconsistentSpan] = field(default_factory=list)
    skipped: str = ""

    @property
    def consistent(self) -> bool | None:
        """True / False when judged, None when skipped."""
        return None if self.skipped else not self.spans

    def message(self) -> str:
        """One line: the verdict with the spans, e.g. ``"align.nis: INCONSISTENT: ..."``."""
        what = f"{self.column} ({self.kind.upper()}, {self.dof} dof"
        if self.skipped:
            return f"{self.column}: not judged: {self.skipped}"
        what += f", {self.samples} samples, {len(self.windows)} windows)"
        if not self.spans:
            return f"{what}: consistent"
        shown = "; ".join(s.message() for s in self.spans[:MAX_SPANS_SHOWN])
        more = len(self.spans) - MAX_SPANS_SHOWN
        return f"{what}: INCONSISTENT: {shown}" + (f" (and {more} more spans)" if more > 0 else "")

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "column": self.column,
            "kind": self.kind,
            "dof": self.dof,
            "samples": self.samples,
            "window_false_alarm": self.alpha,
            "consistent": self.consistent,
            "skipped": self.skipped,
            "message": self.message(),
            "spans": [
                {
                    "t_start": s.t_start,
                    "t_end": s.t_end,
                    "sigma": f"too {s.flag}",
                    "factor": s.factor,
                    "mean": s.mean,
                }
                for s in self.spans
            ],
            "windows": [w.to_dict() for w in self.windows],
        }


@dataclass(frozen=True)
class _Prepared:
    column: str
    kind: str
    t: np.ndarray
    values: np.ndarray
    dof: np.ndarray
    dof_text: str
    edges: np.ndarray


def _prepare(
    result: RunResult,
    column: str,
    kind: str,
    dof: float | None,
    start: float | None,
    until: float | None,
    window: float | None,
) -> _Prepared | str:
    """The samples and windows of one statistic, or why it cannot be judged."""
    names = result.names
    block, var = column.rsplit(".", 1)
    dof_col = f"{block}.{var}_dof"
    values = np.asarray(result.data[column], dtype=float)
    idx = update_instants(values, held=kind == "nis")
    if dof_col in names:
        d = np.asarray(result.data[dof_col], dtype=float)[idx]
        dof_text = f"per update ({dof_col})"
    elif dof is not None:
        d = np.full(idx.size, float(dof))
        dof_text = f"{dof:g}"
    else:
        return (
            "its degrees of freedom are not stated: write '(chi-square, N dof)' in the "
            f"output's description, record '{dof_col}', or give a requirement's 'dof'"
        )
    t = np.asarray(result.time, dtype=float)[idx]
    v = values[idx]
    keep = np.isfinite(d) & (d > 0)
    if start is not None:
        keep &= t >= start - 1e-9
    if until is not None:
        keep &= t <= until + 1e-9
    t, v, d = t[keep], v[keep], d[keep]
    if t.size == 0:
        return (
            "no sample: the output stayed 0 in the judged span (the filter never updated, "
            "or publishes no NIS, as a particle filter may)"
        )
    windows = max(1, min(DEFAULT_WINDOWS, t.size // MIN_SAMPLES))
    edges = window_edges(float(t[0]), float(t[-1]), window, windows)
    return _Prepared(column, kind, t, v, d, dof_text, edges)


def _judge(p: _Prepared, alpha: float) -> SignalCheck:
    windows = window_test(p.t, p.values, p.dof, p.edges, alpha, white=p.kind == "nis")
    return SignalCheck(
        p.column, p.kind, p.dof_text, int(p.t.size), alpha, windows, inconsistent_spans(windows)
    )


def _n_windows(p: _Prepared) -> int:
    which = np.clip(np.searchsorted(p.edges, p.t, side="right") - 1, 0, p.edges.size - 2)
    return int(np.unique(which).size)


# ------------------------------------------------------------------------ one run
@dataclass
class RunConsistency:
    """Every statistic of one run, judged together at a per-run false-alarm rate.

    Attributes
    ----------
    false_alarm : float
        Probability that a consistent filter has any window flagged in this run
        (Bonferroni over every judged window of every signal).
    checks : list of SignalCheck
        One per statistic found (judged or skipped).
    """

    false_alarm: float
    checks: list[SignalCheck]

    @property
    def inconsistent(self) -> list[SignalCheck]:
        """The judged signals with a flagged window."""
        return [c for c in self.checks if c.consistent is False]

    def lines(self) -> list[str]:
        """The summary printed after a run, one line per statistic."""
        if not self.checks:
            return []
        head = (
            f"consistency (chi-square bands, {100 * self.false_alarm:g} % false alarm per run, "
            "docs/consistency.md):"
        )
        return [head] + [f"  {c.message()}" for c in self.checks]

    def to_dict(self) -> dict[str, Any]:
        """Plain data for results.json."""
        return {
            "false_alarm_per_run": self.false_alarm,
            "consistent": not self.inconsistent,
            "signals": [c.to_dict() for c in self.checks],
        }


def check_run(
    result: RunResult,
    *,
    false_alarm: float = DEFAULT_FALSE_ALARM,
    window: float | None = None,
    start: float | None = None,
) -> RunConsistency:
    """Judge every NIS and NEES output recorded in a run (the automatic check).

    Parameters
    ----------
    result : RunResult
        The run; its metadata's ``descriptions`` give the dof, ``unconnected`` tells
        whether the NEES has its truth.
    false_alarm : float
        Per-run false-alarm rate, split equally over all judged windows.
    window : float, optional
        Window length [s] (default: each span cut into 10 windows, fewer below 10 samples
        per window).
    start : float, optional
        Judge from this time on [s].

    Returns
    -------
    RunConsistency
    """
    descriptions = result.metadata.get("descriptions") or {}
    prepared: list[_Prepared] = []
    checks: list[SignalCheck] = []
    for column in result.names[1:]:
        kind = statistic_kind(column)
        if kind is None:
            continue
        block = column.rsplit(".", 1)[0]
        if kind == "nees" and not truth_connected(result.metadata, block):
            checks.append(SignalCheck(column, kind, skipped="no truth (a truth input is open)"))
            continue
        p = _prepare(result, column, kind, declared_dof(descriptions.get(column, "")), start, None,
                     window)  # fmt: skip
        if isinstance(p, str):
            checks.append(SignalCheck(column, kind, skipped=p))
        else:
            prepared.append(p)
            checks.append(SignalCheck(column, kind))
    n_tests = sum(_n_windows(p) for p in prepared)
    judged = {p.column: _judge(p, false_alarm / n_tests) for p in prepared}
    return RunConsistency(false_alarm, [judged.get(c.column, c) for c in checks])


def record_consistency(result: RunResult) -> dict[str, dict[str, Any]]:
    """What a campaign keeps of the automatic check of one run (:func:`check_run`).

    Parameters
    ----------
    result : RunResult
        A completed run.

    Returns
    -------
    dict
        Column -> ``{"consistent": bool or None, "message": str}`` (None: not judged).
    """
    return {
        c.column: {"consistent": c.consistent, "message": c.message()}
        for c in check_run(result).checks
    }


# ------------------------------------------------------------------------ requirement
@dataclass(frozen=True)
class ConsistencyRequirement(Requirement):
    """A ``[[requirements]]`` table with ``criterion = "consistent"``.

    Per run: the signal's windows are judged at ``false_alarm / windows`` each; the
    metric is the number of flagged windows, the run passes with none. Over a campaign
    the pass rate is bounded (Clopper-Pearson) against ``probability`` (default 0.95),
    or ``statistic = "max"`` asks every run to pass.

    Attributes
    ----------
    id, text, signal, minus, sigma, unit, criterion, limit, band, start, until, at : object
        As in :class:`~cosim.verify.requirements.Requirement` (``criterion`` is
        ``"consistent"``, ``unit`` ``"1"``, ``limit`` 0 flagged windows).
    absolute, wrap, statistic, statistic_text, k, probability, confidence : object
        As in :class:`~cosim.verify.requirements.Requirement` (``statistic`` is
        ``"pass_rate"`` or ``"max"``).
    assume, on_failure, factors, index, reference : object
        As in :class:`~cosim.verify.requirements.Requirement` (``reference`` is unused).
    kind : str
        ``"nis"`` (white samples) or ``"nees"`` (any dependence).
    dof : float or None
        Degrees of freedom of one sample; None when a ``<signal>_dof`` column gives them.
    false_alarm : float
        Probability that a consistent filter fails one run.
    window : float or None
        Window length [s]; None: the span cut into 10 windows (fewer below 10 samples each).
    """

    kind: str = "nis"
    dof: float | None = None
    false_alarm: float = DEFAULT_FALSE_ALARM
    window: float | None = None

    @property
    def metric_unit(self) -> str:
        """The per-run metric counts flagged windows."""
        return "windows"

    def describe(self) -> str:
        """The per-run criterion in words."""
        span = f"{self.window:g} s windows" if self.window else f"up to {DEFAULT_WINDOWS} windows"
        lo = f" from {self.start:g} s" if self.start is not None else ""
        hi = f" until {self.until:g} s" if self.until is not None else ""
        return (
            f"{self.kind.upper()} in its chi-square band in every window ({span}{lo}{hi}; "
            f"{100 * self.false_alarm:g} % false alarm per run)"
        )

    def judge(self, result: RunResult) -> tuple[RunMetric, SignalCheck]:
        """One run's metric (flagged windows, 0 passes) and the signal's check.

        Parameters
        ----------
        result : RunResult
            The run.

        Returns
        -------
        (RunMetric, SignalCheck)
            The note of a failing run is the check's message.
        """
        p = _prepare(result, self.signal, self.kind, self.dof, self.start, self.until,
                     self.window)  # fmt: skip
        if isinstance(p, str):
            return RunMetric(math.nan, None, p), SignalCheck(self.signal, self.kind, skipped=p)
        check = _judge(p, self.false_alarm / _n_windows(p))
        flagged = sum(1 for w in check.windows if w.flag)
        note = "; ".join(s.message() for s in check.spans)
        return RunMetric(float(flagged), flagged == 0, note), check

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view for JSON reports."""
        return dict(
            super().to_dict(),
            kind=self.kind,
            dof=self.dof,
            false_alarm=self.false_alarm,
            window=self.window,
        )


def is_consistency_table(table: Any) -> bool:
    """True for a ``[[requirements]]`` table with ``criterion = "consistent"``.

    Parameters
    ----------
    table : object
        One item of ``scenario.raw["requirements"]``.

    Returns
    -------
    bool
    """
    return isinstance(table, dict) and table.get("criterion") == "consistent"


def parse_consistency(
    table: dict[str, Any],
    i: int,
    units: Mapping[str, Any],
    file: str,
    descriptions: Mapping[str, str],
    on_failure: str = "undecided",
) -> ConsistencyRequirement:
    """Parse and check one ``criterion = "consistent"`` requirement.

    Parameters
    ----------
    table : dict
        ``requirements[i]``.
    i : int
        Its position (for the key in messages).
    units : mapping
        Recorded column -> unit (only the names are used).
    file : str
        The scenario file.
    descriptions : mapping
        Recorded column -> its description (the declared dof).
    on_failure : str
        Default ``on_failure`` (from ``[campaign]``).

    Returns
    -------
    ConsistencyRequirement

    Raises
    ------
    ScenarioError
        Naming the file and ``requirements[i].<key>``, and the fix.
    """

    err = table_error(table, i, file)
    rid, text = check_keys(
        table, CONSISTENT_KEYS, ("id", "signal"), err, " for criterion 'consistent'"
    )
    signal = table["signal"]
    if not isinstance(signal, str) or signal.strip() not in units:
        recorded = [c for c in units if statistic_kind(c)]
        hint = difflib.get_close_matches(str(signal), recorded, n=1)
        tip = f" Did you mean '{hint[0]}'?" if hint else ""
        raise err(
            f"'{signal}' is not a recorded column.{tip} Recorded NIS/NEES outputs: "
            f"{', '.join(recorded) or 'none'} (add the filter's nis/nees to output.variables)",
            "signal",
        )
    signal = signal.strip()
    kind = statistic_kind(signal)
    if kind is None:
        raise err(
            f"'{signal}' is not a NIS or NEES output (a block output named 'nis', 'nees', "
            "'nis_*' or 'nees_*'); consistency is judged on those",
            "signal",
        )
    dof: float | None = None
    if "dof" in table:
        raw = table["dof"]
        if isinstance(raw, bool) or not isinstance(raw, int) or raw < 1:
            raise err(f"expected a whole number of degrees of freedom >= 1, got {raw!r}", "dof")
        dof = float(raw)
    else:
        dof_col = f"{signal}_dof"
        stated = declared_dof(descriptions.get(signal, ""))
        if dof_col not in units and stated is None:
            raise err(
                f"the degrees of freedom of '{signal}' are not stated by its block; give "
                f"them, e.g. dof = 3 (the measurement size of one update for a NIS, the "
                f"state block's size for a NEES), or record '{dof_col}'",
                "dof",
            )
        dof = None if dof_col in units else float(stated)  # type: ignore[arg-type]
    if kind == "nees" and dof is None:
        raise err("a NEES needs one dof for all samples: give dof = 3 (say)", "dof")
    false_alarm = _fraction(table, "false_alarm", DEFAULT_FALSE_ALARM, err)

    def seconds(key: str) -> float | None:
        if key not in table:
            return None
        try:
            value = float(to_unit(table[key], "s"))  # type: ignore[arg-type]
        except (ScenarioError, TypeError, ValueError) as exc:
            raise err(f"expected a time such as '20 s', got {table[key]!r}", key) from exc
        if not math.isfinite(value):
            raise err(f"expected a finite time, got {table[key]!r}", key)
        return value

    window = seconds("window")
    if window is not None and window <= 0:
        raise err(f"the window must be > 0 s, got {table['window']!r}", "window")
    start, until = seconds("from"), seconds("until")
    if start is not None and until is not None and until <= start:
        raise err(f"'until' ({until:g} s) is not after 'from' ({start:g} s)", "until")
    stat = str(table.get("statistic", "pass_rate")).strip().lower()
    if stat not in ("pass_rate", "max"):
        raise err(
            f"criterion 'consistent' takes statistic 'pass_rate' (the share of runs without "
            f"a flagged window, Clopper-Pearson) or 'max' (every run), got "
            f"{table['statistic']!r}",
            "statistic",
        )
    if "probability" in table and stat != "pass_rate":
        raise err("'probability' goes with statistic = 'pass_rate'", "probability")
    probability = _fraction(table, "probability", DEFAULT_PASS_PROBABILITY, err)
    if stat == "pass_rate" and probability > 1.0 - false_alarm:
        raise err(
            f"a consistent filter passes a run with probability {1 - false_alarm:g} "
            f"(false_alarm = {false_alarm:g}), so a pass rate of {probability:g} can never be "
            f"shown; ask for probability <= {1 - false_alarm:g} or lower false_alarm",
            "probability",
        )
    confidence = _fraction(table, "confidence", DEFAULT_CONFIDENCE, err)
    failure = table.get("on_failure", on_failure)
    if failure not in ("undecided", "exclude", "fail"):
        raise err(f"expected 'undecided', 'exclude' or 'fail', got {failure!r}", "on_failure")
    return ConsistencyRequirement(
        id=rid,
        text=text,
        signal=signal,
        minus=None,
        sigma=None,
        unit="1",
        criterion="consistent",
        limit=0.0,
        start=start,
        until=until,
        statistic=stat,
        statistic_text=stat,
        probability=probability if stat == "pass_rate" else 1.0 - false_alarm,
        confidence=confidence,
        on_failure=failure,
        index=i,
        kind=kind,
        dof=dof,
        false_alarm=false_alarm,
        window=window,
    )


def _fraction(table: dict[str, Any], key: str, default: float, err: TableError) -> float:
    return fraction(table.get(key, default), key, err, "0.01 or '1 %'")


def split_tables(tables: Any) -> tuple[list[Any], list[tuple[int, dict[str, Any]]]]:
    """Separate ``criterion = "consistent"`` tables from the others (keeping positions).

    Parameters
    ----------
    tables : list
        ``scenario.raw["requirements"]``.

    Returns
    -------
    (list, list of (int, dict))
        The other tables in order, and the consistency tables with their index.
    """
    if not isinstance(tables, list):
        return tables, []
    others = [t for t in tables if not is_consistency_table(t)]
    mine = [(i, t) for i, t in enumerate(tables) if is_consistency_table(t)]
    return others, mine


def load_all(
    tables: Any,
    units: Mapping[str, Any],
    file: str,
    outputs: Sequence[str],
    descriptions: Mapping[str, str],
    on_failure: str = "undecided",
) -> list[Requirement]:
    """Every ``[[requirements]]`` table: the consistency ones here, the others as before.

    Parameters
    ----------
    tables : list of dict
        ``scenario.raw["requirements"]``.
    units : mapping
        Recorded column -> its unit.
    file : str
        The scenario file.
    outputs : sequence of str
        Every Real output of the system.
    on_failure : str
        Default ``on_failure`` (from ``[campaign]``).
    descriptions : mapping
        Recorded column -> its description (the declared dof).

    Returns
    -------
    list of Requirement
        In file order.

    Raises
    ------
    ScenarioError
        Naming the file and the key ``requirements[i].<key>`` (``i`` the file position).
    """
    from cosim.verify.requirements import load_requirements

    others, mine = split_tables(tables)
    positions = [i for i in range(len(tables) if isinstance(tables, list) else 0)
                 if i not in {j for j, _ in mine}]  # fmt: skip
    try:
        parsed = load_requirements(others, units, file, outputs, on_failure=on_failure)
    except ScenarioError as exc:
        key = exc.key or ""
        m = re.match(r"requirements\[(\d+)\](.*)", key)
        if not m or not mine:
            raise
        where = f"requirements[{positions[int(m.group(1))]}]{m.group(2)}"
        message = re.sub(
            r"requirements\[(\d+)\]", lambda g: f"requirements[{positions[int(g.group(1))]}]",
            exc.message,
        )  # fmt: skip
        raise ScenarioError(message, file=exc.file, key=where) from None
    consistency = [parse_consistency(t, i, units, file, descriptions, on_failure) for i, t in mine]
    return merge_requirements(parsed, consistency, file)


def merge_requirements(
    others: Sequence[Requirement], mine: Sequence[ConsistencyRequirement], file: str
) -> list[Requirement]:
    """All requirements in file order, ids unique across both kinds.

    Parameters
    ----------
    others : sequence of Requirement
        Parsed by :func:`cosim.verify.requirements.load_requirements` (their ``index``
        counts the other tables only).
    mine : sequence of ConsistencyRequirement
        Parsed by :func:`parse_consistency` (``index`` = the file position).
    file : str
        The scenario file (for the message).

    Returns
    -------
    list of Requirement
    """
    taken = sorted(r.index for r in mine)
    out: list[Requirement] = list(mine)
    free = (i for i in range(len(others) + len(mine)) if i not in taken)
    for r, pos in zip(others, free, strict=False):
        out.append(r if r.index == pos else _reindexed(r, pos))
    out.sort(key=lambda r: r.index)
    seen: dict[str, int] = {}
    for r in out:
        if r.id in seen:
            raise ScenarioError(
                f"requirement id '{r.id}' is used twice (requirements[{seen[r.id]}] and "
                f"requirements[{r.index}]); ids must be unique",
                file=file,
                key=f"requirements[{r.index}].id",
            )
        seen[r.id] = r.index
    return out


def _reindexed(req: Requirement, index: int) -> Requirement:
    from dataclasses import replace

    return replace(req, index=index)
