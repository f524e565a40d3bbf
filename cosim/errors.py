"""Typed exceptions of ins-cosim.

Every error a user can cause is a :class:`UserError`: the CLI prints its message
(which names the file, key, block or variable and how to fix it) and exits with a
non-zero code, without a traceback. Everything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from typing import Any


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """The hint every "unknown name" message ends with: the closest known name, if any.

    Parameters
    ----------
    name : str
        What the user wrote.
    known : iterable of str
        The names that would have been accepted.

    Returns
    -------
    str
        ``" Did you mean 'x'?"`` (leading space included), or ``""`` when nothing is close
        (:func:`difflib.get_close_matches`, its default cutoff 0.6).
    """
    hint = difflib.get_close_matches(name, list(known), n=1)
    return f" Did you mean '{hint[0]}'?" if hint else ""


def shorten(value: Any, limit: int = 60) -> str:
    """A user's value for a message, cut when long (with its length).

    Parameters
    ----------
    value : Any
        What the user wrote: a string (quoted) or another value (its ``repr``).
    limit : int
        Most characters shown.

    Returns
    -------
    str
        ``"'deg/h'"``, ``"[1, 2]"``, or ``"'deg*deg*de...' (100000 characters)"`` when
        longer than ``limit``.
    """
    text = value if isinstance(value, str) else repr(value)
    q = "'" if isinstance(value, str) else ""
    if len(text) <= limit:
        return f"{q}{text}{q}"
    return f"{q}{text[:limit]}...{q} ({len(text)} characters)"


class UserError(Exception):
    """Base of every error caused by the user's input (scenario, FMU, command line)."""

    exit_code = 3


class ScenarioError(UserError, ValueError):
    """A scenario file is malformed or inconsistent.

    Parameters
    ----------
    message : str
        What is wrong and how to fix it.
    file : str, optional
        The scenario file.
    key : str, optional
        The TOML key (dotted path) where the problem is.
    """

    def __init__(self, message: str, file: str | None = None, key: str | None = None) -> None:
        self.file = file
        self.key = key
        self.message = message
        where = ", ".join(x for x in (file, f"key '{key}'" if key else None) if x)
        super().__init__(f"{where}: {message}" if where else message)


class UnitError(ScenarioError):
    """A unit is unknown, or two units do not have the same dimension."""


class FmuError(UserError, ValueError):
    """An FMU file is missing, unreadable, or not usable for co-simulation."""


class SimulationError(UserError, RuntimeError):
    """A run stopped: a block failed or produced a non-finite output.

    Parameters
    ----------
    message : str
        What happened.
    block : str
        The block that failed.
    time : float
        Simulated time of the failure [s].
    variable : str, optional
        The variable concerned.
    result : Any, optional
        The :class:`cosim.results.RunResult` recorded up to the failure.
    call : str, optional
        The FMI call (``fmi2DoStep``) or block call (``do_step``) that failed.
    """

    exit_code = 4

    def __init__(
        self,
        message: str,
        block: str,
        time: float,
        variable: str | None = None,
        result: Any = None,
        call: str | None = None,
    ) -> None:
        self.block = block
        self.time = time
        self.variable = variable
        self.result = result
        self.call = call
        what = f"block '{block}'" + (f", variable '{variable}'" if variable else "")
        if call:
            what += f", {'FMI call' if call.startswith('fmi') else 'call'} {call}"
        super().__init__(f"{what}, t = {time:.6g} s: {message}")


class ParameterRefusedError(SimulationError):
    """A block refused its parameters when it initialised (a ``ValueError`` of the model).

    A user's mistake, not a failure of the run: exit code 3 as for any bad input; the
    message names the block and, from the model, the parameter and its fix. Campaigns
    record each run as failed with that message, as for any :class:`SimulationError`.
    """

    exit_code = 3
