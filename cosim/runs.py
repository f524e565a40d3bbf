"""How a run is made: scenario -> master -> results, in one function every caller uses.

:func:`make_run` makes every run: ``cosim.run`` (the Python API), ``ins-cosim run`` in
this process and in an isolated child (:mod:`cosim.isolate`), and every run of a
campaign (:func:`cosim.verify.workers.run_one`, in this process, a local worker process
or a Dask worker). It takes a parsed scenario, or an :class:`Assembly` built from one
earlier by :func:`assemble`, and returns the :class:`~cosim.results.RunResult`:

- given a :class:`~cosim.scenario.Scenario`, it assembles it (:func:`assemble`), runs
  it once and terminates its blocks;
- given an :class:`Assembly`, it resets the blocks if they ran before, sets the run's
  parameters over the built ones and runs, keeping the blocks for the next run (a
  campaign worker builds once and runs many times).

The run itself is the master stepping with observers watching
(:func:`cosim.recording.record_run`): the finiteness check, the recorder, then the
caller's (the crash step board of isolated runs and workers, Ctrl-C checks, progress,
early stops). Parsing a scenario file is the caller's business and happens once per
process (:func:`cosim.scenario.load_scenario`); docs/design.md says why.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.master import Master
from cosim.recording import Recorder, record_run
from cosim.results import RunResult
from cosim.scenario import Scenario, build_master

__all__ = ["Assembly", "assemble", "make_run"]


@dataclass
class Assembly:
    """A scenario built into a master, kept for runs (:func:`make_run`).

    Attributes
    ----------
    scenario : Scenario
        The scenario it was built from (a copy: the caller's is not changed).
    master : Master
        Its master; ``master.system.parameters`` are set per run.
    parameters : dict
        The built parameters, ``{block: {scalar name: SI value}}``, that every run
        starts from.
    recorder : Recorder
        The run's recorder: column names and types known before any run; its size
        checked at assembly.
    used : bool
        Whether the blocks ran since they were built or reset.
    """

    scenario: Scenario
    master: Master
    parameters: dict[str, dict[str, Any]]
    recorder: Recorder
    used: bool = False

    def close(self) -> None:
        """Terminate the blocks (frees FMU instances)."""
        self.master.terminate()


def assemble(
    scenario: Scenario,
    *,
    fmu_dir: str | Path | None = None,
    outputs: Sequence[str] | None = None,
    on_row: Callable[[np.ndarray], None] | None = None,
    **overrides: Any,
) -> Assembly:
    """Build a parsed scenario's blocks and master, ready for :func:`make_run`.

    Parameters
    ----------
    scenario : Scenario
        Parsed (:func:`cosim.scenario.load_scenario`); not changed (a copy is built).
    fmu_dir : str or Path, optional
        Run built-in models from ``<fmu_dir>/<Model>.fmu``.
    outputs : sequence of str, optional
        What to record (``output.variables`` syntax) instead of the scenario's.
    on_row : callable, optional
        Called with each recorded row (:class:`cosim.recording.Recorder`).
    **overrides
        Master settings replacing the scenario's (``stop``, ``record_every``, ...; None
        keeps the scenario's).

    Returns
    -------
    Assembly
        The caller closes it (:meth:`Assembly.close`) when done.

    Raises
    ------
    ScenarioError, FmuError
        Before anything runs, with the file and key of the problem (a recording too
        large to keep included).
    """
    # a copy of what building may change (block sources for fmu_dir, the outputs); the
    # parsed document is shared, read only
    blocks = {name: dataclasses.replace(spec) for name, spec in scenario.blocks.items()}
    own = dataclasses.replace(scenario, blocks=blocks)
    if outputs is not None:
        own.outputs = list(outputs)
    master = build_master(own, fmu_dir=fmu_dir, **overrides)
    try:
        recorder = Recorder(master, on_row)
    except BaseException:
        master.terminate()
        raise
    return Assembly(own, master, copy.deepcopy(master.system.parameters), recorder)


def make_run(
    source: Scenario | Assembly,
    *,
    fmu_dir: str | Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    parameters: Mapping[str, Mapping[str, Any]] | None = None,
    observers: Sequence[Any] = (),
    on_row: Callable[[np.ndarray], None] | None = None,
    before: Callable[[Assembly], None] | None = None,
) -> RunResult:
    """Make one run: scenario -> master -> results (the module docstring says who calls).

    Parameters
    ----------
    source : Scenario or Assembly
        A parsed scenario (assembled, run once, closed), or an assembly kept between
        runs (reset when it ran before; never closed here).
    fmu_dir : str or Path, optional
        With a scenario: run built-in models from these FMUs.
    overrides : dict, optional
        With a scenario: master settings replacing its own (``stop`` [s], ...).
    parameters : dict, optional
        This run's parameters, ``{block: {scalar name: value}}``, over the built ones
        (seeds, a campaign's draws); the run's ``system.parameters`` hold the result.
    observers : sequence, optional
        What else watches the run (:mod:`cosim.observers`), after the finiteness check
        and the recorder.
    on_row : callable, optional
        With a scenario: called with each recorded row as it is written.
    before : callable, optional
        Called with the assembly before the run (checks that refuse it, the line that
        announces it); an exception closes a new assembly and goes through.

    Returns
    -------
    RunResult
        The recording and its metadata.

    Raises
    ------
    ScenarioError, FmuError
        With a scenario: it cannot be built.
    SimulationError
        A block failed, or an output was not finite; ``error.result`` holds the rows
        recorded before.
    """
    if isinstance(source, Assembly):
        assembly, own = source, False
    else:
        assembly = assemble(source, fmu_dir=fmu_dir, on_row=on_row, **dict(overrides or {}))
        own = True
    try:
        if before is not None:
            before(assembly)
        master = assembly.master
        if assembly.used:
            master.reset()
        params = copy.deepcopy(assembly.parameters)
        for block, values in (parameters or {}).items():
            params.setdefault(block, {}).update(values)
        master.system.parameters = params
        assembly.used = True
        return record_run(master, observers=observers, recorder=assembly.recorder)
    finally:
        if own:
            assembly.close()
