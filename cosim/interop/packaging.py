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

# The FMU's entry module. pythonfmu imports it, then executes it once more per instance
# with separate globals and locals (so: no comprehensions here, they would not see the
# local names), and releases one reference to the module namespace that it never took
# (pythonfmu 0.7 findClass): each execution keeps one reference to balance that, or the
# namespace is freed under the module and the interpreter crashes later.
# A `models` package imported earlier in the same process from another FMU's resources
# may point to a folder deleted when that FMU was unloaded: forget it, so that this FMU
# imports its own copy.
# pythonfmu 0.7's binary also has a use-after-free at process exit: a C++ static
# shared_ptr is destroyed by the exit handlers, then the library's ELF destructor
# (finalizePythonInterpreter) decrements the freed control block again, which corrupts
# the heap ("corrupted double-linked list", SIGABRT) at random. In a Python host the
# entry script therefore pins the library and, from Python's atexit (before the C exit
# handlers), calls finalizePythonInterpreter itself: the shared_ptr is empty by the time
# the two faulty finalisers run, and both do nothing. Hosts where the FMU started Python
# (no sys.orig_argv) are left as pythonfmu made them. pythonfmu puts the instance's
# resources folder first on sys.path just before it runs this script, which is how the
# script finds its own binary (a second copy of the same FMU finds the module cached,
# but the per-instance execution still runs).
ENTRY_SCRIPT = """\
import atexit
import ctypes
import os
import sys

_kept = sys.__dict__.setdefault("_ins_cosim_fmu_namespaces", [])
_kept.append(globals())

_pinned = sys.__dict__.setdefault("_ins_cosim_fmu_libraries", {{}})
if sys.platform.startswith("linux") and getattr(sys, "orig_argv", None) and sys.path:
    _binary = os.path.join(
        os.path.dirname(os.path.abspath(sys.path[0])), "binaries", "linux64", "{name}.so"
    )
    if _binary not in _pinned and os.path.isfile(_binary):
        try:
            _library = ctypes.CDLL(_binary, mode=os.RTLD_NOLOAD | os.RTLD_NOW)
            _release = _library.finalizePythonInterpreter
        except (OSError, AttributeError):
            _release = None
        if _release is not None:
            _pinned[_binary] = _library
            atexit.register(_release)

_previous = sys.modules.get("models")
if _previous is not None:
    _stale = False
    for _folder in _previous.__path__:
        if not os.path.isdir(_folder):
            _stale = True
    if _stale:
        for _key in list(sys.modules):
            if _key == "models" or _key.startswith("models."):
                del sys.modules[_key]

from {module} import {name}  # noqa: E402,F401
"""


def build_fmu(cls: type[Block], out_dir: Path, extra_files: tuple[Path, ...] = ()) -> Path:
    """Build ``out_dir/<ClassName>.fmu`` from a block class.

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass defined in a module of ``models``.
    out_dir : Path
        Destination folder (created if missing).
    extra_files : tuple of Path
        Further modules to ship in the resources (for classes defined outside ``models``).

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
        script.write_text(ENTRY_SCRIPT.format(module=cls.__module__, name=cls.__name__))
        return FmuBuilder.build_FMU(
            script,
            dest=out_dir / f"{cls.__name__}.fmu",
            project_files=[MODELS_DIR, *map(Path, extra_files)],
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
    return [build_fmu(cls, out_dir) for cls in models.truth_models().values()]
