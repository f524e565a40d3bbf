"""Pack the block classes of ``models/`` into FMI 2.0 co-simulation FMUs with pythonfmu.

Each FMU holds a two-line entry script that imports its class, plus a copy of the
``models`` package in its resources; numpy, scipy and pythonfmu come from the
Python interpreter that loads the FMU.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import models
from models.block import Block

MODELS_DIR = Path(models.__file__).resolve().parent


def build_fmu(cls: type[Block], out_dir: Path) -> Path:
    """Build ``out_dir/<ClassName>.fmu`` from a block class.

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass defined in a module of ``models``.
    out_dir : Path
        Destination folder (created if missing).

    Returns
    -------
    Path
        The FMU file.
    """
    from pythonfmu.builder import FmuBuilder

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ins_cosim_fmu_") as tmp:
        script = Path(tmp) / f"{cls.__name__}_fmu.py"
        script.write_text(f"from {cls.__module__} import {cls.__name__}  # noqa: F401\n")
        return FmuBuilder.build_FMU(
            script, dest=out_dir / f"{cls.__name__}.fmu", project_files=[MODELS_DIR]
        )


def build_all(out_dir: Path) -> list[Path]:
    """Build an FMU for every block class in ``models/``.

    Parameters
    ----------
    out_dir : Path
        Destination folder, normally ``fmus/build``.

    Returns
    -------
    list of Path
        The FMU files, in class-name order.
    """
    return [build_fmu(cls, out_dir) for cls in models.registry().values()]
