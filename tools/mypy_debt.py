"""Rewrite the type-checking debt table of pyproject.toml from a mypy run.

The table silences, module by module, the error codes mypy reported when the checker came
in (numpy arrays held in attributes typed ``ndarray | None`` until a block's setup, numpy's
overloads, ``**kwargs`` dictionaries). It only ever shrinks: fix a module's errors, run

    .venv/bin/python tools/mypy_debt.py

and the module leaves the table. After a merge that moved or split modules, the same
command gives the moved modules their entries again (say so in the commit). Modules are
grouped by the set of codes they silence; each group's comment lists its error counts.

Run from the repository root; it calls ``mypy`` with the table emptied, so it sees every
error, and writes the new table between the two marker lines.
"""

from __future__ import annotations

import collections
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = ROOT / "pyproject.toml"
BEGIN = "# --- type-checking debt (tools/mypy_debt.py writes this table) ---"
END = "# --- end of the type-checking debt ---"
ERROR = re.compile(r"^(?P<path>[\w/]+)\.py:\d+: error: .*\[(?P<code>[a-z-]+)\]$")


def module_of(path: str) -> str:
    """Dotted module name of a checked file, as mypy names it (``models`` stays top-level).

    Parameters
    ----------
    path : str
        Path relative to the root, without ``.py`` (``cosim/verify/plan``).

    Returns
    -------
    str
        ``cosim.verify.plan``; ``cosim/__init__`` -> ``cosim``.
    """
    return path.replace("/", ".").removesuffix(".__init__")


def collect(output: str) -> dict[str, collections.Counter[str]]:
    """Error codes per module in mypy's output.

    Parameters
    ----------
    output : str
        mypy's standard output.

    Returns
    -------
    dict
        Module name -> counter of error codes.
    """
    found: dict[str, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    for line in output.splitlines():
        m = ERROR.match(line.strip())
        if m:
            found[module_of(m["path"])][m["code"]] += 1
    return found


def table(found: dict[str, collections.Counter[str]]) -> str:
    """The TOML of the debt table (between the markers, markers excluded).

    Parameters
    ----------
    found : dict
        As returned by :func:`collect`.

    Returns
    -------
    str
        ``[[tool.mypy.overrides]]`` sections, one per set of codes.
    """
    groups: dict[tuple[str, ...], list[str]] = collections.defaultdict(list)
    for module, codes in found.items():
        groups[tuple(sorted(codes))].append(module)
    total = sum(sum(c.values()) for c in found.values())
    lines = [f"# {total} errors in {len(found)} modules."]
    for codes, modules in sorted(groups.items(), key=lambda g: sorted(g[1])[0]):
        lines.append("[[tool.mypy.overrides]]")
        lines.append("module = [")
        for module in sorted(modules):
            lines.append(f'    "{module}",  # {sum(found[module].values())}')
        lines.append("]")
        lines.append("disable_error_code = [" + ", ".join(f'"{c}"' for c in codes) + "]")
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    """Run mypy without the table, write the new table, print the total.

    Returns
    -------
    int
        0 (mypy's own failure to run is raised).
    """
    text = PYPROJECT.read_text()
    head, begin, rest = text.partition(BEGIN + "\n")
    old, end, tail = rest.partition(END)
    if not begin or not end:
        raise SystemExit(f"{PYPROJECT}: the debt markers are missing ({BEGIN!r} ... {END!r})")
    PYPROJECT.write_text(head + begin + end + tail)
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True
        )
    finally:
        PYPROJECT.write_text(text)
    if proc.returncode not in (0, 1):
        raise SystemExit(proc.stdout + proc.stderr)
    found = collect(proc.stdout)
    PYPROJECT.write_text(head + begin + table(found) + "\n" + end + tail)
    print(f"type-checking debt: {sum(sum(c.values()) for c in found.values())} errors "
          f"in {len(found)} modules")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
