"""What watches a run of the master: the observer interface, and the finiteness check.

The master (:mod:`cosim.master`) only steps: it initialises the blocks, exchanges their
values and steps them. Everything else that happens during a run watches it through
:class:`Observer`, as libcosim's observers watch its algorithm: the recording
(:mod:`cosim.recording`), the finiteness check (:class:`FinitenessCheck`), progress
(:class:`Progress`), the crash step board of isolated runs and campaign workers
(:class:`cosim.isolate.BoardObserver`) and early stops.

An observer overrides the hooks it needs; the master calls only those, through lists
made once at the start of a run (a hook left as the base class's costs nothing per
step). The hooks other than ``on_start`` are looked up after it, so that an observer
may bind them for the run there. Blocks are named by their index in
:attr:`cosim.master.Master.order` (stepping order). The hooks, in the order of a run:

- ``on_start(master, t0)``: before the first block is initialised; ``master.values``
  is the run's live value table (every Real output, float64, each block's outputs one
  part of it: ``master.output_parts``).
- ``before_block(i, t, initialising)``: before block ``i`` is initialised at ``t0``
  (``initialising`` True) or stepped from ``t``.
- ``after_block(i, t)``: after block ``i`` was initialised or stepped and its outputs
  read into the value table; ``t`` is the time they are valid at.
- ``after_step(n, t)``: after macro step ``n`` (``t = t_{n+1}``); ``n = -1`` after the
  initialisation (``t = t0``). A truthy return value asks the run to end after this
  step (every observer sees the step first); the value, as text, is the reason kept in
  the result's ``metadata["stopped"]``.
- ``on_stop(ending)``: once, when the run ends (:class:`Ending`), also when it fails.

A hook that raises :class:`cosim.errors.SimulationError` fails the run (the master then
calls every ``on_stop`` with the failure and raises it); any other exception (e.g. a
``KeyboardInterrupt``) goes through unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.errors import SimulationError

__all__ = ["Ending", "FinitenessCheck", "Hooks", "Observer", "Progress", "hooks_of"]

HOOKS = ("on_start", "before_block", "after_block", "after_step", "on_stop")


class Observer:
    """Watches a run; every hook does nothing here (override the ones you need).

    See the module docstring for when each hook is called.
    """

    def on_start(self, master: Any, t0: float) -> None:
        """Before the first block is initialised.

        Parameters
        ----------
        master : cosim.master.Master
            The master; ``master.values`` is this run's live value table.
        t0 : float
            Start time [s].
        """

    def before_block(self, i: int, t: float, initialising: bool) -> None:
        """Before a block is initialised or stepped.

        Parameters
        ----------
        i : int
            The block's index in ``master.order``.
        t : float
            The start time (initialising) or the step's start [s].
        initialising : bool
            Whether the block is being initialised (else stepped).
        """

    def after_block(self, i: int, t: float) -> None:
        """After a block was initialised or stepped and its outputs read.

        Parameters
        ----------
        i : int
            The block's index in ``master.order``.
        t : float
            The time its outputs are valid at [s].
        """

    def after_step(self, n: int, t: float) -> object:
        """After a macro step.

        Parameters
        ----------
        n : int
            The macro step (-1: the initialisation).
        t : float
            ``t_{n+1}`` [s], the time every block's outputs are valid at.

        Returns
        -------
        object
            Truthy to end the run after this step (its text is the reason).
        """
        return None

    def on_stop(self, ending: Ending) -> None:
        """Once, when the run ends, completed, ended early or failed.

        Parameters
        ----------
        ending : Ending
            How it ended.
        """


@dataclass
class Ending:
    """How a run ended.

    Attributes
    ----------
    status : str
        ``"completed"`` or ``"failed"``.
    time : float
        The last time [s] the blocks' outputs are valid at (a failure: its time).
    terminated : dict or None
        A block asked to end the run (``block``, ``time``, ``call``, ``reason``).
    stopped : dict or None
        An observer asked to end the run (``time`` [s], ``reason``).
    error : SimulationError or None
        The failure.
    """

    status: str
    time: float
    terminated: dict[str, Any] | None = None
    stopped: dict[str, Any] | None = None
    error: SimulationError | None = None

    @property
    def early(self) -> bool:
        """Whether the run ended before its stop time without failing."""
        return self.terminated is not None or self.stopped is not None


@dataclass
class Hooks:
    """The overridden hooks of a run's observers, one list per hook (in observer order).

    Attributes
    ----------
    on_start, before_block, after_block, after_step, on_stop : list of callable
        The observers' bound methods of that hook.
    """

    on_start: list[Callable[..., Any]] = field(default_factory=list)
    before_block: list[Callable[..., Any]] = field(default_factory=list)
    after_block: list[Callable[..., Any]] = field(default_factory=list)
    after_step: list[Callable[..., Any]] = field(default_factory=list)
    on_stop: list[Callable[..., Any]] = field(default_factory=list)


def hooks_of(observers: Sequence[Any]) -> Hooks:
    """The hooks the observers override, bound, one list per hook.

    An :class:`Observer` subclass contributes the hooks it overrides; any other object
    (duck-typed) the hooks it has.

    Parameters
    ----------
    observers : sequence
        The run's observers, in the order their hooks are called.

    Returns
    -------
    Hooks
    """
    out = Hooks()
    for obs in observers:
        for name in HOOKS:
            own = getattr(type(obs), name, None)
            if own is None or (isinstance(obs, Observer) and own is getattr(Observer, name)):
                continue
            getattr(out, name).append(getattr(obs, name))
    return out


class FinitenessCheck(Observer):
    """Fails the run when a block publishes a non-finite output (NaN or Inf).

    Checked right after each block's step, before the blocks it feeds step: the
    :class:`~cosim.errors.SimulationError` names the block, the first non-finite
    variable and the time its outputs are valid at. The check costs one sum of the
    block's outputs (a sum that overflows is looked at too, and passes when every value
    is finite).
    """

    def on_start(self, master: Any, t0: float) -> None:
        values = master.values
        self.order = master.order
        self.parts = [
            (values[part], values[part].tolist, outs) for _n, part, outs in master.output_parts
        ]

    def after_block(self, i: int, t: float) -> None:
        out, listed, outs = self.parts[i]
        total = sum(listed())
        if total - total != 0.0:  # inf or nan (or a sum that overflowed)
            bad = np.flatnonzero(~np.isfinite(out))
            if bad.size:
                k = int(bad[0])
                raise SimulationError(
                    f"output is {out[k]} (not finite)",
                    block=self.order[i],
                    time=t,
                    variable=outs[k].name,
                )


class Progress(Observer):
    """Reports the fraction of the run done, at most ``updates`` times per run.

    Parameters
    ----------
    report : callable
        ``report(fraction, t)``: fraction of the macro steps done (0 to 1), simulated
        time [s].
    updates : int
        How many reports a whole run gives (evenly spaced in macro steps), >= 1.
    """

    def __init__(self, report: Callable[[float, float], None], updates: int = 100) -> None:
        if updates < 1:
            raise ValueError(f"updates must be >= 1, got {updates}")
        self.report, self.updates = report, updates

    def on_start(self, master: Any, t0: float) -> None:
        self.n_steps = master.settings.n_steps
        self.every = max(1, self.n_steps // self.updates)

    def after_step(self, n: int, t: float) -> object:
        done = n + 1  # 0 after the initialisation: nothing to report yet
        if done and (done % self.every == 0 or done == self.n_steps):
            self.report(done / self.n_steps, t)
        return None
