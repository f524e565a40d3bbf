"""Limits on a scenario file: what ``load_scenario`` (so ``ins-cosim check``) refuses unread.

Each limit is refused with the limit and the value found, in one line, before anything
slow happens: the file's size is read before its bytes, the nesting of arrays and inline
tables is measured before the TOML parser recurses into it, and the parsed document is
walked once, without recursion, for nesting by dotted keys and for long strings. The
number of macro steps and the size of the recording are limited by
:class:`cosim.master.MasterSettings` (:data:`cosim.master.MAX_STEPS`) and
:class:`cosim.recording.Recorder` (:data:`cosim.recording.MAX_RECORDING_BYTES`); the length of a
unit string by :data:`cosim.units.MAX_UNIT_CHARS`.
"""

from __future__ import annotations

import re
from typing import Any

from cosim.errors import ScenarioError, shorten

#: The largest scenario file [bytes].
MAX_FILE_BYTES = 16 * 2**20
#: How deep tables, arrays and inline tables may nest.
MAX_DEPTH = 32
#: The most blocks, and the most connection strings, of a scenario.
MAX_BLOCKS = 100_000
MAX_CONNECTIONS = 1_000_000
#: The longest key or string value [characters].
MAX_STRING_CHARS = 10_000
_NESTING = re.compile(r"[\"'#\[\]{}]")
_STRINGS = {
    '"""': re.compile(r'"""(?:[^\\"]|\\.|"(?!""))*"""', re.S),
    "'''": re.compile(r"'''(?:[^']|'(?!''))*'''", re.S),
    '"': re.compile(r'"(?:[^"\\\n]|\\.)*"'),
    "'": re.compile(r"'[^'\n]*'"),
}


def nesting_depth(text: str) -> tuple[int, int]:
    """How deep arrays and inline tables nest in TOML text, found without parsing it.

    One pass over the text, skipping strings and comments, so that a document nested
    thousands of levels deep is refused before the parser recurses into it.

    Parameters
    ----------
    text : str
        The TOML document.

    Returns
    -------
    depth : int
        The deepest nesting of ``[`` and ``{`` (a table header counts 1, ``[[x]]`` 2).
    line : int
        The line (1-based) where that depth is first reached.
    """
    depth = deepest = 0
    at = i = 0
    n = len(text)
    while i < n:
        m = _NESTING.search(text, i)
        if m is None:
            break
        c, i = m.group(), m.end()
        if c == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif c in "[{":
            depth += 1
            if depth > deepest:
                deepest, at = depth, m.start()
        elif c in "]}":
            depth = max(0, depth - 1)
        else:
            quote = c * 3 if text.startswith(c * 3, m.start()) else c
            string = _STRINGS[quote].match(text, m.start())
            if string is not None:  # an unterminated string is the parser's to report
                i = string.end()
    return deepest, text.count("\n", 0, at) + 1


def check_document(doc: dict[str, Any], file: str) -> None:
    """Refuse a parsed document that nests too deep or holds too long a string.

    Walks the document without recursion (a table nested by dotted keys is as deep as
    its header is long).

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    file : str
        The file it was read from (for the message).

    Raises
    ------
    ScenarioError
        Nesting deeper than :data:`MAX_DEPTH`, or a key or string longer than
        :data:`MAX_STRING_CHARS`, with the key where it is.
    """
    stack: list[tuple[Any, int, str]] = [(doc, 1, "")]
    while stack:
        node, depth, where = stack.pop()
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for k, v in items:
            if isinstance(node, dict):
                key = f"{where}.{k}" if where else str(k)
            else:
                key = f"{where}[{k}]"
            for text, what in ((k, "key"), (v, "string")):
                if isinstance(text, str) and len(text) > MAX_STRING_CHARS:
                    raise ScenarioError(
                        f"{what} {shorten(text)} is longer than the limit of "
                        f"{MAX_STRING_CHARS} characters",
                        file=file,
                        key=key if len(key) <= 80 else f"{key[:80]}...",
                    )
            if isinstance(v, (dict, list)):
                if depth + 1 > MAX_DEPTH:
                    raise ScenarioError(
                        f"tables and arrays nest at least {depth + 1} levels deep, more than the "
                        f"limit of {MAX_DEPTH}",
                        file=file,
                        key=key if len(key) <= 80 else f"{key[:80]}...",
                    )
                stack.append((v, depth + 1, key))
