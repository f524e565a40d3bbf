"""Reference results: each model run alone, written to ``models/reference/<Model>.csv``.

Every block of ``models/`` is run with its default parameters (``seed = 1234`` where
it has a seed), at its ``default_step`` for ``min(200, default_stop / default_step)``
steps, with each Real input held at its start value plus a small deterministic
sinusoid (``1e-3 sin(0.7 (i+1) t + i)`` in the input's SI unit, i = input index).
The same drive serves the FMU-equivalence test. ``python -m cosim.interop.references``
rewrites the files after a deliberate change of a model; the test suite compares
every model with its file (relative 1e-12), as modelica/Reference-FMUs does.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from cosim import models
from cosim.blocks import BlockHost, InProcessHost
from cosim.results import RunResult
from cosim.variables import REAL

REFERENCE_DIR = Path(models.__file__).resolve().parent / "reference"
SEED = 1234
MAX_STEPS = 200


def drive(host: BlockHost, n_steps: int, h: float) -> np.ndarray:
    """Run one block alone with the reference drive.

    Parameters
    ----------
    host : BlockHost
        The block (in-process or FMU), freshly instantiated; it is terminated at the end.
    n_steps : int
        Number of steps.
    h : float
        Step [s].

    Returns
    -------
    numpy structured array, shape (n_steps + 1,)
        ``time`` [s], then every Real output (SI units) after initialisation and after
        each step.
    """
    params = {"seed": SEED} if "seed" in host.variables else {}
    inputs = [v for v in host.by_causality("input") if v.type == REAL]
    outputs = [v for v in host.by_causality("output") if v.type == REAL]
    out_vrs = [v.vr for v in outputs]
    data = np.zeros(n_steps + 1, dtype=[("time", "f8")] + [(v.name, "f8") for v in outputs])
    host.setup(0.0, params)
    host.exit_init()
    data[0] = (0.0, *host.get_real(out_vrs))
    for n in range(n_steps):
        t = n * h
        if inputs:
            values = [
                (v.start or 0.0) + 1e-3 * math.sin(0.7 * (i + 1) * t + i)
                for i, v in enumerate(inputs)
            ]
            host.set_real([v.vr for v in inputs], values)
        host.do_step(t, h)
        data[n + 1] = ((n + 1) * h, *host.get_real(out_vrs))
    host.terminate()
    return data


def reference_run(cls: type) -> np.ndarray:
    """The reference drive of a model class, in-process."""
    h = cls.default_step
    n_steps = min(MAX_STEPS, round(cls.default_stop / h))
    return drive(InProcessHost(cls.__name__, cls), n_steps, h)


def write_all(out_dir: Path = REFERENCE_DIR) -> list[Path]:
    """Rewrite the reference file of every model.

    Parameters
    ----------
    out_dir : Path
        Folder for the ``<Model>.csv`` files (created if missing); default
        ``models/reference``.

    Returns
    -------
    list of Path
        The CSV files written.
    """

    written = []
    for name, cls in models.truth_models().items():
        data = reference_run(cls)
        meta = {"model": name, "seed": SEED, "step": cls.default_step}
        csv, js = RunResult(data, meta).save(out_dir, stem=name)
        js.unlink()
        written.append(csv)
    return written


if __name__ == "__main__":  # pragma: no cover
    for path in write_all(Path(sys.argv[1]) if len(sys.argv) > 1 else REFERENCE_DIR):
        print(f"wrote {path}")
