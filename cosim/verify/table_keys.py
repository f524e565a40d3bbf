"""Checks every ``[[requirements]]`` table goes through, whatever its criterion.

:mod:`cosim.verify.requirements` (bound, settling, value) and
:mod:`cosim.verify.consistency` (``criterion = "consistent"``) parse their own keys; the
error's wording and key, the allowed and required keys, ``id``, ``text`` and the
fractions (``probability``, ``confidence``, ``false_alarm``) are checked here once.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Collection, Iterable
from typing import Any

from cosim.errors import ScenarioError

#: ``err(message, key=None)``: the error for ``requirements[i]`` (or one of its keys).
TableError = Callable[..., ScenarioError]


def table_error(table: dict[str, Any], i: int, file: str) -> TableError:
    """The error maker of one requirement table.

    Parameters
    ----------
    table : dict
        ``requirements[i]``.
    i : int
        Its position.
    file : str
        The scenario file.

    Returns
    -------
    callable ``err(message, key=None) -> ScenarioError``
        The message is prefixed with ``requirement '<id>': `` where the table has a string
        id; the key is ``requirements[i]`` or ``requirements[i].<key>``.
    """
    where = f"requirements[{i}]"

    def err(message: str, key: str | None = None) -> ScenarioError:
        rid = table.get("id")
        label = f"requirement '{rid}': " if isinstance(rid, str) else ""
        return ScenarioError(label + message, file=file, key=f"{where}.{key}" if key else where)

    return err


def check_keys(
    table: dict[str, Any],
    allowed: Collection[str],
    required: Iterable[str],
    err: TableError,
    what: str = "",
) -> tuple[str, str]:
    """Refuse unknown and missing keys; check ``id`` and ``text``.

    Parameters
    ----------
    table : dict
        ``requirements[i]``.
    allowed : collection of str
        The keys the table may have (an unknown one is named with the closest allowed).
    required : iterable of str
        The keys it must have (``id`` among them).
    err : callable
        From :func:`table_error`.
    what : str
        Said after ``unknown key '<k>'`` (e.g. `` for criterion 'consistent'``).

    Returns
    -------
    (str, str)
        The id (stripped) and the text (``""`` when not given).

    Raises
    ------
    ScenarioError
        Naming the key and the fix.
    """
    for k in table:
        if k not in allowed:
            hint = difflib.get_close_matches(k, allowed, n=1)
            tip = f" Did you mean '{hint[0]}'?" if hint else ""
            raise err(
                f"unknown key '{k}'{what}.{tip} Allowed: {', '.join(sorted(allowed))}",
                k,
            )
    for k in required:
        if k not in table:
            raise err(f"missing '{k}'", k)
    rid = table["id"]
    if not isinstance(rid, str) or not rid.strip():
        raise err(f"expected a non-empty string, got {rid!r}", "id")
    text = table.get("text", "")
    if not isinstance(text, str):
        raise err(f"expected a string, got {text!r}", "text")
    return rid.strip(), text


def fraction(value: Any, key: str, err: TableError, example: str) -> float:
    """A fraction strictly between 0 and 1, given as a number or a percentage string.

    Parameters
    ----------
    value : object
        The key's value (``0.95``, ``"95 %"``).
    key : str
        The key (for the error).
    err : callable
        From :func:`table_error`.
    example : str
        Shown in the error, e.g. ``"0.95 or '95 %'"``.

    Returns
    -------
    float
        The fraction [-].

    Raises
    ------
    ScenarioError
        When the value is not a fraction in (0, 1).
    """
    if isinstance(value, str) and value.strip().endswith("%"):
        try:
            value = float(value.strip()[:-1]) / 100.0
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1:
        raise err(f"expected a fraction between 0 and 1 (e.g. {example}), got {value!r}", key)
    return float(value)
