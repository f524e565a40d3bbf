"""The compiled kernels: one table of C functions, built into one library, loaded with ctypes.

Some hot loops have a C twin that lives beside the Python module it speeds up (the same
formulas in the same order, one call per step or per filter period): the model blocks'
steps in ``models/blocks/*.c`` (:class:`cosim.models.blocks.lever_arm.LeverArm`,
:class:`~cosim.models.blocks.deck_flexure.DeckFlexure`,
:class:`~cosim.models.blocks.strapdown_imu.StrapdownImu`,
:class:`~cosim.models.blocks.ship_motion.ShipMotion`), the alignment filters' strapdown
step and transfer-alignment kernels in ``cosim/alignment/*.c``. :data:`KERNELS` is the
one table of them: each kernel's C function, the source that defines it and its ctypes
signature. The numpy code stays, as the fallback and the readable statement of each
model; both give the same outputs to rounding (``tests/test_native*.py``).

Where the library lives. :func:`build` compiles every source of the table, with the one
C build of the project (:func:`cosim.models.native.ccompile.compile_shared`: one
compiler choice, one flag set), into ``models/native/build/kernels-<sha256 of the sources
and headers, 16 hex>.so`` (``make setup`` and ``make fmus`` do it; a missing library is
also built at first use unless the package is an FMU's copy). When that folder is not
writable (a wheel installed into a read-only site-packages) the library goes to the
user's cache instead, :func:`cache_dir` (``$XDG_CACHE_HOME/ins-cosim/kernels`` or
``~/.cache/ins-cosim/kernels``). The name carries the sources' hash, so a changed source
is never served by a stale library. ``make fmus`` packs the library (not the C sources)
with the models package into every FMU's resources, so an FMU loads it from its own copy
(no compiler needed where the FMU runs). A failed compilation is tried once per process
and reported in one short line (the first compiler error; ``python -m
cosim.models.native`` prints the whole log).

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
import importlib.util
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter, is_
from pathlib import Path

import numpy as np

from cosim.models.native.ccompile import CompileError, compile_shared, compiler

HERE = Path(__file__).resolve().parent
BUILD_DIR = HERE / "build"
#: Environment variable that switches the compiled kernels off when set to ``0``.
ENV = "INS_COSIM_NATIVE"

#: Set in the environment once the fall-back warning was given, so that worker processes
#: started afterwards do not repeat it.
WARNED_ENV = "INS_COSIM_NATIVE_WARNED"

_state: dict[str, object] = {}

_P, _D, _I, _L = ctypes.c_void_p, ctypes.c_double, ctypes.c_int, ctypes.c_long


@dataclass(frozen=True)
class Kernel:
    """One compiled kernel: a C function, where it is defined, its ctypes signature.

    Attributes
    ----------
    name : str
        The C function (exported with ``KERNEL``, ``models/native/kernel.h``).
    package : str
        The package whose folder holds the source, beside the module it speeds up.
    source : str
        The ``.c`` file in that folder.
    argtypes : tuple
        ctypes argument types (``c_void_p`` for ``double *``).
    restype : ctypes type or None
        Result type (None: ``void``).
    """

    name: str
    package: str
    source: str
    argtypes: tuple
    restype: object = None


_BLOCKS, _ALIGNMENT = "cosim.models.blocks", "cosim.alignment"
_UKF_PERIOD = (_P, _P, _P, _P, _P, _P, _P, _P, _D, _I, _I, _I, _P)

#: Every compiled kernel of the project, the one place a C signature is declared.
KERNELS = (
    Kernel("lever_arm_step", _BLOCKS, "lever_arm.c", (_P, _P, _P, _D, _P, _D, _D), _I),
    Kernel("lever_arm_publish", _BLOCKS, "lever_arm.c", (_P, _P, _D, _P)),
    Kernel("deck_flexure_step", _BLOCKS, "deck_flexure.c", (_P, _P, _P, _P, _P, _P, _P, _D)),
    Kernel("strapdown_imu_step", _BLOCKS, "strapdown_imu.c", (_P, _P, _P, _P, _P, _P, _P, _D)),
    Kernel("ship_truth_steps", _BLOCKS, "ship_motion.c", (_P, _P, _P, _P, _L, _L, _P)),
    Kernel("strapdown_two_sample_step", _ALIGNMENT, "strapdown.c", (_P, _P, _P, _P, _D, _I, _L)),
    Kernel("strapdown_refresh", _ALIGNMENT, "strapdown.c", (_P, _P)),
    Kernel("transfer_propagate", _ALIGNMENT, "transfer_model.c", (_P, _P, _P, _L, _I, _I)),
    Kernel("transfer_ukf_period", _ALIGNMENT, "transfer_ukf.c", _UKF_PERIOD, _I),
    Kernel(
        "transfer_ukf_fed_period", _ALIGNMENT, "transfer_feedback.c", (*_UKF_PERIOD, _P, _P, _P), _I
    ),
    Kernel(
        "transfer_feedback", _ALIGNMENT, "transfer_feedback.c", (_P, _P, _P, _P, _I, _I, _I, _P)
    ),
    Kernel("transfer_publish", _ALIGNMENT, "transfer_publish.c", (_P, _P, _I, _P, _P, _P), _D),
    Kernel(
        "transfer_period", _ALIGNMENT, "transfer_master.c", (_P, _I, _P, _P, _P, _D, _P, _P), _I
    ),
    Kernel(
        "transfer_master_state",
        _ALIGNMENT,
        "transfer_master.c",
        (_P, _I, _I, _D, _P, _D, _D, _P, _P),
    ),
)
#: The headers the sources include (``#include "..."``), by package: hashed with them,
#: their folders passed as include folders.
HEADERS = (("cosim.models", "conventions.h"), ("cosim.models.native", "kernel.h"))


class NativeFallbackWarning(UserWarning):
    """The compiled kernels are unavailable: the models run their numpy code (slower)."""


def _folder(package: str) -> Path | None:
    """The folder of a package, found without importing it; None when it is not here."""
    try:
        spec = importlib.util.find_spec(package)
    except ImportError:
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


def sources() -> tuple[list[Path], list[Path]]:
    """The C sources of :data:`KERNELS` and the headers they include, as files.

    Returns
    -------
    sources, headers : list of Path
        In table order, each once; files missing from this copy of the package (an FMU
        carries only the library) are left out.
    """
    found: dict[str, list[Path]] = {"c": [], "h": []}
    pairs = [(k.package, k.source) for k in KERNELS] + list(HEADERS)
    for package, name in pairs:
        folder = _folder(package)
        file = None if folder is None else folder / name
        kind = "h" if name.endswith(".h") else "c"
        if file is not None and file.is_file() and file not in found[kind]:
            found[kind].append(file)
    return found["c"], found["h"]


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


def _complete() -> bool:
    """True when every source and header of the table is in this copy of the package."""
    c_files, h_files = sources()
    wanted = {(k.package, k.source) for k in KERNELS} | set(HEADERS)
    return len(c_files) + len(h_files) == len(wanted)


def library_path() -> Path:
    """Where the library of the current sources is (or would be) built.

    Returns
    -------
    Path
        ``models/native/build/kernels-<hash>.so``, the hash being the first 16 hex
        digits of the SHA-256 of the C sources and headers (:func:`sources`: names and
        contents); the same name in :func:`cache_dir` when it is there or the package
        folder is read-only. A copy without all the C sources (an FMU's resources) has
        the library it was packed with.
    """
    if not _complete():
        packed = sorted(BUILD_DIR.glob("kernels-*.so"))
        return packed[-1] if packed else BUILD_DIR / "kernels-unavailable.so"
    sha = hashlib.sha256()
    c_files, h_files = sources()
    for source in c_files + h_files:
        sha.update(source.name.encode() + b"\0" + source.read_bytes() + b"\0")
    name = f"kernels-{sha.hexdigest()[:16]}.so"
    cached = cache_dir() / name
    if (BUILD_DIR / name).is_file() or (not cached.is_file() and _writable(BUILD_DIR)):
        return BUILD_DIR / name
    return cached


def _in_fmu() -> bool:
    """True when this package is the copy inside an unpacked FMU's resources."""
    for resources in HERE.parents:
        if resources.name == "resources" and (resources.parent / "modelDescription.xml").is_file():
            return True
    return False


def build(force: bool = False) -> Path:
    """Compile the sources of :data:`KERNELS` into :func:`library_path` (old builds removed).

    Parameters
    ----------
    force : bool
        Rebuild even when the library of the current sources exists.

    Returns
    -------
    Path
        The shared library.

    Raises
    ------
    RuntimeError
        No C compiler (:func:`cosim.models.native.ccompile.compiler`), a source missing,
        or the compilation failed (the first error in the message, the whole log in
        :func:`build_log`).
    """
    target = library_path()
    if target.is_file() and not force:
        return target
    if "build_error" in _state and not force:
        raise RuntimeError(str(_state["build_error"]))
    c_files, h_files = sources()
    error = ""
    if not _complete():
        error = f"{target.name} is not in this copy of the models (no C sources to build)"
    elif compiler() is None:
        error = (
            "no C compiler for the compiled kernels: expected $CC, 'cc' or 'gcc' on the "
            "PATH (install gcc); the models run their numpy code meanwhile"
        )
    else:
        includes = list(dict.fromkeys(h.parent for h in h_files))
        try:
            compile_shared(c_files, target, include_dirs=includes)
        except CompileError as exc:
            _state["build_log"] = exc.log
            error = f"{exc}; the whole log: python -m cosim.models.native"
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


def _declare(lib: ctypes.CDLL) -> None:
    """Give every kernel of :data:`KERNELS` its signature (a missing one: AttributeError)."""
    for kernel in KERNELS:
        fn = getattr(lib, kernel.name)
        fn.argtypes = list(kernel.argtypes)
        fn.restype = kernel.restype


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
        None when ``INS_COSIM_NATIVE=0`` or the library is unavailable (see :func:`status`);
        every kernel of :data:`KERNELS` is an attribute, with its signature.
    """
    if os.environ.get(ENV, "1").strip() == "0":
        return None
    return _load()


def kernel(name: str) -> Callable | None:
    """A kernel of :data:`KERNELS`, for a block or filter being initialised.

    Parameters
    ----------
    name : str
        The C function, as in the table.

    Returns
    -------
    callable or None
        The function, its signature set from the table; None when :func:`library` is
        None (numpy path).

    Raises
    ------
    KeyError
        ``name`` is not in the table.
    """
    if name not in {k.name for k in KERNELS}:
        known = ", ".join(k.name for k in KERNELS)
        raise KeyError(f"no kernel {name!r} in models/native KERNELS; known: {known}")
    lib = library()
    return None if lib is None else getattr(lib, name)


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
