"""Compiled step kernels of the models: a small C library built with gcc, loaded with ctypes.

The hot loops of :class:`models.blocks.lever_arm.LeverArm`,
:class:`models.blocks.deck_flexure.DeckFlexure`
and :class:`models.blocks.strapdown_imu.StrapdownImu` have a C twin in ``kernels.c`` (the same
formulas in the same order, one call per step, no warm-up). The numpy code stays, as the
fallback and the readable statement of each model; both give the same outputs to rounding
(``tests/test_native.py`` checks 1e-12, in-process and inside an FMU).

Where the library lives. :func:`build` compiles ``kernels.c`` into
``models/native/build/kernels-<sha256 of the source, 16 hex>.so`` (``make setup`` and
``make fmus`` do it; a missing library is also built at first use unless the package is an
FMU's copy). When that folder is not writable (a wheel installed into a read-only
site-packages) the library goes to the user's cache instead, :func:`cache_dir`
(``$XDG_CACHE_HOME/ins-cosim/kernels`` or ``~/.cache/ins-cosim/kernels``). The name carries
the source's hash, so a changed source is never served by a stale library. ``make fmus``
packs the library (not the C sources) with the models package into every FMU's
resources, so an FMU loads it from its own copy (no compiler needed where the FMU runs).
A failed compilation is tried once per process and reported in one short line (the first
compiler error; ``python -m cosim.models.native`` prints the whole log).

Which path runs (:func:`library`, read when a block initialises):

* ``INS_COSIM_NATIVE=0`` in the environment: numpy, always;
* otherwise the compiled kernels when the library loads, else numpy (no compiler, a build
  error, an FMU host on which the library does not load): same numbers to 1e-12, and one
  warning (:class:`NativeFallbackWarning`) per process tree names the reason.

:func:`status` says which, and why; every run's provenance records it
(``software.kernels`` in results.json and in the verification report).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from collections.abc import Callable
from operator import attrgetter, is_
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: Every C source of the library (``kernels.c``: the truth models; ``strapdown.c``: the
#: alignment filters' mechanisation; the other files: further filter kernels) ...
SOURCES = tuple(sorted(HERE.glob("*.c")))
#: ... and the headers they include (``conventions.h``): hashed with them.
HEADERS = tuple(sorted(HERE.glob("*.h")))
BUILD_DIR = HERE / "build"
#: Environment variable that switches the compiled kernels off when set to ``0``.
ENV = "INS_COSIM_NATIVE"
#: Compiler flags: IEEE arithmetic (no -ffast-math, no contraction into FMA).
CFLAGS = ("-O2", "-std=c99", "-shared", "-fPIC", "-ffp-contract=off")

#: Set in the environment once the fall-back warning was given, so that worker processes
#: started afterwards do not repeat it.
WARNED_ENV = "INS_COSIM_NATIVE_WARNED"

_state: dict[str, object] = {}


class NativeFallbackWarning(UserWarning):
    """The compiled kernels are unavailable: the models run their numpy code (slower)."""


def cache_dir() -> Path:
    """The per-user folder for libraries built where the package folder is read-only.

    Returns
    -------
    Path
        ``$XDG_CACHE_HOME/ins-cosim/kernels``, or ``~/.cache/ins-cosim/kernels``.
    """
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "ins-cosim" / "kernels"


def _writable(folder: Path) -> bool:
    """True when ``folder`` (or, missing, the nearest existing parent) is writable."""
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return os.access(folder, os.W_OK)


def library_path() -> Path:
    """Where the library of the current ``kernels.c`` is (or would be) built.

    Returns
    -------
    Path
        ``models/native/build/kernels-<hash>.so``, the hash being the first 16 hex
        digits of the SHA-256 of the C sources and headers (:data:`SOURCES`,
        :data:`HEADERS`: names and contents); the same name in :func:`cache_dir` when it
        is there or the package folder is read-only. A copy without C sources (an FMU's
        resources) has the library it was packed with.
    """
    if not SOURCES:
        packed = sorted(BUILD_DIR.glob("kernels-*.so"))
        return packed[-1] if packed else BUILD_DIR / "kernels-unavailable.so"
    sha = hashlib.sha256()
    for source in SOURCES + HEADERS:
        sha.update(source.name.encode() + b"\0" + source.read_bytes() + b"\0")
    name = f"kernels-{sha.hexdigest()[:16]}.so"
    cached = cache_dir() / name
    if (BUILD_DIR / name).is_file() or (not cached.is_file() and _writable(BUILD_DIR)):
        return BUILD_DIR / name
    return cached


def _short(stderr: str) -> str:
    """The first compiler error of a log, and how many lines followed."""
    lines = [line for line in stderr.strip().splitlines() if line.strip()]
    first = next((line for line in lines if "error" in line), lines[0] if lines else "")
    more = len(lines) - 1
    return first.strip() + (f" (+{more} more lines: python -m cosim.models.native)" if more else "")


def _in_fmu() -> bool:
    """True when this package is the copy inside an unpacked FMU's resources."""
    for resources in HERE.parents:
        if resources.name == "resources" and (resources.parent / "modelDescription.xml").is_file():
            return True
    return False


def _compiler() -> str | None:
    for candidate in (os.environ.get("CC"), "gcc", "cc"):
        if candidate and shutil.which(candidate):
            return candidate
    return None


def build(force: bool = False) -> Path:
    """Compile the C sources into :func:`library_path` (atomically; old builds removed).

    Parameters
    ----------
    force : bool
        Rebuild even when the library of the current source exists.

    Returns
    -------
    Path
        The shared library.

    Raises
    ------
    RuntimeError
        No C compiler (``$CC``, ``gcc`` or ``cc``), or the compilation failed (its
        messages included).
    """
    target = library_path()
    if target.is_file() and not force:
        return target
    if "build_error" in _state and not force:
        raise RuntimeError(str(_state["build_error"]))
    cc = _compiler()
    if not SOURCES:
        error = f"{target.name} is not in this copy of the models (no C sources to build)"
    elif cc is None:
        error = (
            "no C compiler for the models' kernels: expected $CC, 'gcc' or 'cc' on the "
            "PATH (install gcc); the models run their numpy code meanwhile"
        )
    else:
        error = _compile(cc, target)
    if error:
        _state["build_error"] = error
        raise RuntimeError(error)
    if target.parent == BUILD_DIR:
        for old in BUILD_DIR.glob("kernels-*.so"):
            if old != target:
                old.unlink(missing_ok=True)
    return target


def build_log() -> str:
    """The compiler's whole output of this process's failed build ("" when none failed).

    Returns
    -------
    str
    """
    return str(_state.get("build_log", ""))


def _compile(cc: str, target: Path) -> str:
    """Compile :data:`SOURCES` into ``target`` atomically; "" or the short error."""
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".kernels-", suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        proc = subprocess.run(
            [cc, *CFLAGS, "-o", tmp, *map(str, SOURCES), "-lm"], capture_output=True, text=True
        )
        if proc.returncode != 0:
            _state["build_log"] = proc.stderr
            return f"compiling the models' kernels failed ({cc}): {_short(proc.stderr)}"
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return ""


def _declare(lib: ctypes.CDLL) -> None:
    p, d, i = ctypes.c_void_p, ctypes.c_double, ctypes.c_int
    signatures = {
        "lever_arm_step": ([p, p, p, d, p, d, d], i),
        "lever_arm_publish": ([p, p, d, p], None),
        "deck_flexure_step": ([p, p, p, p, p, p, p, d], None),
        "strapdown_imu_step": ([p, p, p, p, p, p, p, d], None),
        "ship_truth_steps": ([p, p, p, p, ctypes.c_long, ctypes.c_long, p], None),
    }
    for name, (args, res) in signatures.items():
        fn = getattr(lib, name)
        fn.argtypes = args
        fn.restype = res


def _load() -> ctypes.CDLL | None:
    """Load (building first when allowed) the library once per process; None when it fails."""
    if "lib" in _state:
        return _state["lib"]  # type: ignore[return-value]
    lib = None
    try:
        path = library_path()
        if not path.is_file():
            if _in_fmu():
                raise RuntimeError(f"{path.name} is not in this FMU's copy of models/")
            path = build()
        lib = ctypes.CDLL(str(path))
        _declare(lib)
        _state["why"] = f"compiled kernels ({path.name})"
    except (OSError, RuntimeError, AttributeError) as exc:
        lib = None
        _state["why"] = f"numpy (compiled kernels unavailable: {exc})"
        if os.environ.get(WARNED_ENV) != "1":
            os.environ[WARNED_ENV] = "1"
            message = f"the models run their numpy code, slower: {exc}"
            warnings.warn(message, NativeFallbackWarning, stacklevel=2)
    _state["lib"] = lib
    return lib


def library() -> ctypes.CDLL | None:
    """The compiled kernels for a block being initialised, or None for the numpy path.

    Returns
    -------
    ctypes.CDLL or None
        None when ``INS_COSIM_NATIVE=0`` or the library is unavailable (see :func:`status`).
    """
    if os.environ.get(ENV, "1").strip() == "0":
        return None
    return _load()


def declare(name: str, argtypes: list, restype: object = None) -> Callable | None:
    """A kernel of the library with its C signature, for a block being initialised.

    The truth models' kernels are declared when the library loads; the filters' own
    kernels (``strapdown.c`` and the others) are declared by the module that calls them.

    Parameters
    ----------
    name : str
        The C function.
    argtypes : list
        Its ctypes argument types (``ctypes.c_void_p`` for ``double *``, ...).
    restype : ctypes type or None
        Its result type (None: ``void``).

    Returns
    -------
    callable or None
        The function; None when :func:`library` is None (numpy path) or the library has no
        such function.
    """
    lib = library()
    fn = None if lib is None else getattr(lib, name, None)
    if fn is None:
        return None
    fn.argtypes = argtypes
    fn.restype = restype
    return fn


def status() -> str:
    """Which path the blocks initialised now take, and why.

    Returns
    -------
    str
        ``"compiled kernels (kernels-<hash>.so)"``, or ``"numpy (...)"`` with the reason.
    """
    if os.environ.get(ENV, "1").strip() == "0":
        return f"numpy ({ENV}=0)"
    _load()
    return str(_state["why"])


def pointer(array: object) -> int:
    """Address of a numpy array's data, for the kernels' ``double *`` arguments.

    Parameters
    ----------
    array : ndarray
        A C-contiguous float64 array that outlives the calls using the address.

    Returns
    -------
    int
        The address of its first element.
    """
    return array.ctypes.data  # type: ignore[attr-defined]


def span(block: object, names: tuple[str, ...]) -> np.ndarray | None:
    """The float64 array whose consecutive parts the attributes ``names`` are, in order.

    :class:`models.block.Block` keeps its vector inputs (and outputs) as views of one
    buffer; when the named attributes are such views, back to back in the given order, a
    kernel can read (write) them all through one pointer.

    Parameters
    ----------
    block : object
        The model instance.
    names : tuple of str
        Attribute names of 1-D float64 vectors.

    Returns
    -------
    ndarray or None
        A view spanning exactly those attributes; None when they are not one span.
    """
    arrays = [getattr(block, n) for n in names]
    for a in arrays:
        if type(a) is not np.ndarray or a.dtype != np.float64 or a.ndim != 1:
            return None
        if not a.flags.c_contiguous or a.base is None or a.base is not arrays[0].base:
            return None
    base = arrays[0].base
    if type(base) is not np.ndarray or base.dtype != np.float64 or base.ndim != 1:
        return None
    if not base.flags.c_contiguous:
        return None
    start = arrays[0].ctypes.data
    pos = start
    for a in arrays:
        if a.ctypes.data != pos:
            return None
        pos += a.nbytes
    first = (start - base.ctypes.data) // base.itemsize
    return base[first : first + (pos - start) // base.itemsize]


def _getter(names: tuple[str, ...]) -> Callable[[object], tuple] | None:
    """``obj -> tuple of the attributes`` (a tuple also for one name); None for none."""
    if not names:
        return None
    if len(names) == 1:
        one = attrgetter(names[0])
        return lambda obj: (one(obj),)
    return attrgetter(*names)


class Buffers:
    """Where a compiled step reads its vector inputs and writes its vector outputs.

    Straight from the block's own buffers when the inputs (outputs) are one span of
    views (:func:`span`) and still the same objects; otherwise through buffers of its
    own: the inputs gathered before the step, the outputs assigned as fresh arrays
    after it (:meth:`publish`). The values are the same either way.

    Parameters
    ----------
    block : object
        The model instance (its attributes are read at each step).
    inputs, outputs : tuple of str
        Vector attributes in the kernel's layout order (may be empty).
    """

    def __init__(self, block: object, inputs: tuple[str, ...], outputs: tuple[str, ...]) -> None:
        self.block = block
        self.inputs = inputs
        self.outputs = outputs
        self._in_get = _getter(inputs)
        self._out_get = _getter(outputs)
        in_sizes = [len(getattr(block, n)) for n in inputs]
        out_sizes = [len(getattr(block, n)) for n in outputs]
        self._in_own = np.zeros(sum(in_sizes))
        self._out_own = np.zeros(sum(out_sizes))
        self._in_own_ptr = pointer(self._in_own)
        self._out_own_ptr = pointer(self._out_own)
        edges = np.cumsum([0, *out_sizes]).tolist()
        self._out_slices = list(zip(outputs, edges[:-1], edges[1:], strict=True))
        self._in_views = self._in_get(block) if self._in_get else ()
        self._out_views = self._out_get(block) if self._out_get else ()
        in_span = span(block, inputs) if self._in_get else None
        out_span = span(block, outputs) if self._out_get else None
        self._in_ptr = None if in_span is None else pointer(in_span)
        self._out_ptr = None if out_span is None else pointer(out_span)
        self._out_span = out_span
        self._own_out = True

    def output_array(self) -> np.ndarray | None:
        """The block's output span (:func:`span`) while its views are in place, else None.

        Returns
        -------
        ndarray or None
            Write a step's outputs into it in place (numpy code without a kernel); None:
            assign the attributes instead.
        """
        if self._out_span is not None and all(map(is_, self._out_get(self.block), self._out_views)):
            return self._out_span
        return None

    def input_pointer(self) -> int:
        """Address of this step's inputs (the block's buffer, or gathered into our own).

        Returns
        -------
        int
        """
        vals = self._in_get(self.block)
        if self._in_ptr is not None and all(map(is_, vals, self._in_views)):
            return self._in_ptr
        np.concatenate(vals, out=self._in_own)
        return self._in_own_ptr

    def output_pointer(self) -> int:
        """Address where this step's outputs go; call :meth:`publish` after the kernel.

        Returns
        -------
        int
        """
        if self._out_ptr is not None and all(map(is_, self._out_get(self.block), self._out_views)):
            self._own_out = False
            return self._out_ptr
        self._own_out = True
        return self._out_own_ptr

    def publish(self) -> None:
        """Set the output attributes when the kernel wrote into our own buffer."""
        if self._own_out:
            out = self._out_own.copy()
            block = self.block
            for name, lo, hi in self._out_slices:
                setattr(block, name, out[lo:hi])
