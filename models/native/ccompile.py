"""The one C build: which compiler, which flags, C sources into one shared library.

Both C products of the project go through :func:`compile_shared`: the models' and
filters' compiled kernels (:mod:`cosim.models.native`) and binary FMUs from C sources
(:mod:`cosim.interop.cbuild`). The compiler is ``$CC`` when set, else ``cc``, else
``gcc``; the flags are :data:`CFLAGS`, then ``-I`` per include folder, ``-D`` per
definition, the sources, and ``-lm``:

* ``-O2 -std=c99 -Wall``: optimised C99, warnings shown in the log;
* ``-shared -fPIC``: a shared library;
* ``-fvisibility=hidden``: only what a source marks for export is exported (the FMI
  functions through the FMI headers' ``FMI2_Export``, the kernels through ``KERNEL`` of
  ``kernel.h``), so two libraries in one process never resolve each other's helpers;
* ``-ffp-contract=off``: IEEE arithmetic, no contraction into FMA (and no
  ``-ffast-math``), so a kernel gives the numbers of its numpy twin to rounding.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

#: The flags of every C build (see the module docstring for why each).
CFLAGS = (
    "-O2",
    "-std=c99",
    "-Wall",
    "-shared",
    "-fPIC",
    "-fvisibility=hidden",
    "-ffp-contract=off",
)
#: Where a C compiler is looked for, in this order (``$CC`` first when set).
COMPILERS = ("cc", "gcc")


class CompileError(RuntimeError):
    """No C compiler was found, or the compilation failed.

    Parameters
    ----------
    message : str
        One line: what failed and the first compiler error.
    log : str
        The compiler's whole output ("" when there was no compiler); kept as ``log``.
    """

    def __init__(self, message: str, log: str = "") -> None:
        super().__init__(message)
        self.log = log


def compiler() -> str | None:
    """The C compiler of every build: ``$CC``, else ``cc``, else ``gcc``.

    Returns
    -------
    str or None
        The command; None when none is on the PATH.
    """
    for candidate in (os.environ.get("CC"), *COMPILERS):
        if candidate and shutil.which(candidate):
            return candidate
    return None


def first_error(log: str) -> str:
    """The first error line of a compiler's log, and how many lines followed.

    Parameters
    ----------
    log : str
        The compiler's output.

    Returns
    -------
    str
        One line.
    """
    lines = [line for line in log.strip().splitlines() if line.strip()]
    first = next((line for line in lines if "error" in line), lines[0] if lines else "")
    more = len(lines) - 1
    return first.strip() + (f" (+{more} more lines)" if more else "")


def compile_shared(
    sources: Sequence[Path],
    target: Path,
    *,
    include_dirs: Sequence[Path] = (),
    defines: Sequence[str] = (),
) -> Path:
    """Compile C sources into the shared library ``target``, atomically.

    The library is written next to ``target`` under a temporary name and renamed when
    the compiler succeeded, so a reader never sees half a library.

    Parameters
    ----------
    sources : sequence of Path
        The ``.c`` files, compiled and linked in this order.
    target : Path
        The ``.so`` to write (its folder is created).
    include_dirs : sequence of Path
        Folders passed as ``-I``, in order.
    defines : sequence of str
        Preprocessor definitions passed as ``-D<define>``.

    Returns
    -------
    Path
        ``target``.

    Raises
    ------
    CompileError
        No compiler (:func:`compiler`), or the compiler failed (its log attached).
    """
    cc = compiler()
    if cc is None:
        raise CompileError("no C compiler: expected $CC, 'cc' or 'gcc' on the PATH (install gcc)")
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}-", suffix=".so", dir=target.parent)
    os.close(fd)
    command = [
        cc,
        *CFLAGS,
        *(f"-I{d}" for d in include_dirs),
        *(f"-D{d}" for d in defines),
        "-o",
        tmp,
        *map(str, sources),
        "-lm",
    ]
    try:
        proc = subprocess.run(command, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            names = ", ".join(Path(s).name for s in sources)
            if len(sources) > 3:
                names = f"{len(sources)} C sources into {target.name}"
            raise CompileError(
                f"compiling {names} failed ({cc}, exit {proc.returncode}): "
                f"{first_error(proc.stderr)}",
                proc.stderr,
            )
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return target
