"""A test block that ends its own process, or holds its run at a gate (``crashblocks:Crasher``).

Used by the tests of dead workers, of the report folder's lock and of Ctrl-C. Its
output ``y = t`` is never part of a requirement: adding it to a scenario changes no
metric. ``Sleeper`` sleeps in each step: built into an FMU, its own Python code runs
most of the time.

Settings, from the environment of the process that runs the block, or from class
attributes of a subclass (:func:`crasher_module` writes one into a module beside a
scenario: worker processes forked from an already running forkserver do not see the
test's environment changes):

- ``CRASHERS_GATE=<folder>`` (``GATE``), ``CRASHERS_OPEN`` (``OPEN``): every run takes
  the next slot file ``slot_<n>`` there at its initialisation; slot ``n`` goes on when
  ``n < CRASHERS_OPEN`` or the file ``<folder>/open`` exists, else it waits (until it is
  opened or its process stopped): a campaign that cannot finish before the test lets it.
- ``CRASHERS_ONCE=<folder>`` (``ONCE``): the kill or exit of a seed happens only the
  first time (a marker file per seed): a worker that dies once, not twice.
- ``CRASHERS_PARENT=<pid>`` (``PARENT``): a process other than ``pid`` exits with code 5
  as soon as it builds the block (worker processes that die before they can run).
"""

from __future__ import annotations

import os
import signal
import time
import uuid
from pathlib import Path

from cosim.models.block import Block, output, parameter


def crasher_module(folder: Path, **settings: object) -> str:
    """Write a module with a ``Crasher`` whose settings are class attributes.

    Parameters
    ----------
    folder : Path
        The scenario's folder (a ``class`` module beside the scenario is found).
    **settings
        ``GATE``, ``OPEN``, ``ONCE``, ``PARENT``.

    Returns
    -------
    str
        The module's name (unique: modules are cached by name).
    """
    name = f"crashers_{uuid.uuid4().hex[:12]}"
    lines = ["from crashblocks import Crasher as Base", "", "", "class Crasher(Base):"]
    lines += [f"    {k} = {v!r}" for k, v in settings.items()] or ["    pass"]
    (Path(folder) / f"{name}.py").write_text("\n".join(lines) + "\n")
    return name


def gate(folder: str | None, opened: int) -> None:
    """Take the next slot of the gate ``folder`` and wait while it is closed."""
    if not folder:
        return
    n = 0
    while True:
        try:
            os.close(os.open(Path(folder) / f"slot_{n:04d}", os.O_CREAT | os.O_EXCL))
            break
        except FileExistsError:
            n += 1
    while n >= opened and not (Path(folder) / "open").exists():
        time.sleep(0.02)


class Crasher(Block):
    """Ends its process once ``t + h > at``: SIGKILL when ``seed == kill_seed``,
    ``os._exit(3)`` when ``seed == exit_seed``, ``abort()`` when ``seed == abort_seed``."""

    variables = (
        parameter("seed", 0),
        parameter("kill_seed", -1),
        parameter("exit_seed", -1),
        parameter("abort_seed", -1),
        parameter("at", 0.5, "s"),
        output("y", 0.0, "s"),
    )

    GATE: str | None = None
    OPEN: int | None = None
    ONCE: str | None = None
    PARENT: int | None = None

    @classmethod
    def setting(cls, name: str) -> str | None:
        """A class attribute, else the variable ``CRASHERS_<name>`` of the environment."""
        value = getattr(cls, name)
        return os.environ.get(f"CRASHERS_{name}") if value is None else str(value)

    def __init__(self, **kwargs: object) -> None:
        parent = self.setting("PARENT")
        if parent and os.getpid() != int(parent):
            os._exit(5)
        super().__init__(**kwargs)

    def initialize(self) -> None:
        gate(self.setting("GATE"), int(self.setting("OPEN") or 0))

    def step(self, t: float, h: float) -> None:
        self.y = t + h
        if t + h <= self.at or self.seed not in (self.kill_seed, self.exit_seed, self.abort_seed):
            return
        once = self.setting("ONCE")
        if once:
            try:
                os.close(os.open(Path(once) / f"died_{self.seed}", os.O_CREAT | os.O_EXCL))
            except FileExistsError:
                return
        if self.seed == self.kill_seed:
            os.kill(os.getpid(), signal.SIGKILL)
        if self.seed == self.exit_seed:
            os._exit(3)
        os.abort()


class Sleeper(Block):
    """Sleeps ``nap`` of wall time in each step (an FMU whose own Python code runs most of
    the time); ``y = t``."""

    variables = (parameter("nap", 0.002, "s"), output("y", 0.0, "s"))

    def step(self, t: float, h: float) -> None:
        time.sleep(self.nap)
        self.y = t + h
