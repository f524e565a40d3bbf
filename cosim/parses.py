"""How many scenario files this process has parsed: the count behind "parse once per process".

:func:`cosim.scenario_parse.parse_scenario` notes every parse here. A campaign parses its
scenario once in its own process and once in each worker process (docs/design.md);
tests check that with :data:`COUNT` in this process, and, for worker processes, with the
log file named by the environment variable :data:`LOG_ENV` (one line ``<pid> <path>`` per
parse, appended; not written when the variable is unset).
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

__all__ = ["COUNT", "LOG_ENV", "note"]

#: Parses by this process, by file name as given.
COUNT: Counter[str] = Counter()
#: The environment variable naming a log file of every process's parses.
LOG_ENV = "INS_COSIM_PARSE_LOG"


def note(path: Path) -> str:
    """Count one parse of ``path`` (and log it when :data:`LOG_ENV` is set).

    Parameters
    ----------
    path : Path
        The scenario file being parsed.

    Returns
    -------
    str
        ``str(path)``, the file's name as the parser reports it.
    """
    name = str(path)
    COUNT[name] += 1
    log = os.environ.get(LOG_ENV)
    if log:
        with open(log, "a", encoding="utf-8") as out:
            out.write(f"{os.getpid()} {name}\n")
    return name
