"""``ins-cosim check`` at scale: chains of 10^2, 10^3 and 10^4 blocks.

Each chain is a Gauss-Markov source followed by first-order sensors, ``b{i}.m ->
b{i+1}.u``, declared in reverse order (so the stepping order has to be found, not read
off the file). ``check`` is timed as the command runs it (load, build every block, the
stepping order, the loop warnings, the requirements), through click's test runner.

Row (judged): the time per block at 10^4 blocks / the time per block at 10^2 blocks,
target <= 2 (the check is near-linear: a quadratic sort would give ~100). The times
per block at each size are in the info column; each is the best of 3 checks (2 at 10^4
blocks: about 2 s each), after a garbage collection: this row runs after the campaign's
in ``make bench``, and a single 10^4 check there once came out 2.0 where the row alone
gives 1.5-1.6.
"""

from __future__ import annotations

import gc
import tempfile
import time
from pathlib import Path

from click.testing import CliRunner

from cosim.cli import main

SIZES = (100, 1_000, 10_000)


def chain_scenario(n_blocks: int) -> str:
    """A scenario file of a chain of ``n_blocks`` blocks, declared last block first.

    Parameters
    ----------
    n_blocks : int
        Number of blocks (>= 2).

    Returns
    -------
    str
        The TOML text.
    """
    links = ",\n".join(f'  "b{i}.m -> b{i + 1}.u"' for i in range(1, n_blocks - 1))
    lines = [
        f'connections = [\n  "b0.x -> b1.u",\n{links}\n]'
        if n_blocks > 2
        else 'connections = ["b0.x -> b1.u"]',
        '[master]\nstep = "10 ms"\nstop = "1 s"',
        '[output]\nvariables = ["b0"]',
    ]
    for i in reversed(range(1, n_blocks)):
        lines.append(f'[blocks.b{i}]\nmodel = "FirstOrderSensor"')
    lines.append('[blocks.b0]\nmodel = "GaussMarkov2"')
    return "\n".join(lines) + "\n"


def time_check(path: Path, repeats: int = 1) -> float:
    """Best wall time of ``ins-cosim check PATH`` [s] (in this process).

    Parameters
    ----------
    path : Path
        The scenario file.
    repeats : int
        How many times to run it.

    Returns
    -------
    float
        The fastest run [s].
    """
    runner = CliRunner()
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        result = runner.invoke(main, ["check", str(path)])
        best = min(best, time.perf_counter() - start)
        if result.exit_code != 0:
            raise RuntimeError(f"check failed: {result.output[-500:]}")
    return best


def bench() -> list[dict]:
    per_block: dict[int, float] = {}
    with tempfile.TemporaryDirectory(prefix="bench_check_") as tmp:
        for n in SIZES:
            path = Path(tmp) / f"chain_{n}.toml"
            path.write_text(chain_scenario(n))
            gc.collect()  # what the rows before this one left behind is not this row's
            per_block[n] = time_check(path, repeats=3 if n < 10_000 else 2) / n
    ratio = per_block[SIZES[-1]] / per_block[SIZES[0]]
    info = ", ".join(f"{n} blocks: {1e6 * t:.0f} us/block" for n, t in per_block.items())
    return [
        {
            "name": "check: time per block, 10^4 / 10^2 blocks",
            "ratio": ratio,
            "target": "<= 2",
            "met": ratio <= 2.0,
            "info": info,
        }
    ]
