"""Pack the block classes of ``models/`` into FMI 2.0 co-simulation FMUs with pythonfmu.

Each FMU holds a short entry script that imports its class, plus a copy of the
``models`` package in its resources; numpy, scipy and pythonfmu (:data:`REQUIREMENTS`)
come from the Python interpreter that loads the FMU. When one of them is missing there,
the entry script stands in for the class: ``fmi2Instantiate`` sends one error-level
message (``fmi2Error``, category ``logStatusError``) through the host's logger callback,
naming the package and the install command, also with debug logging off, and fails.
pythonfmu 0.7 itself forwards no message unless debug logging is on, so the stand-in
calls the host's logger directly: it reads the callback from pythonfmu's logger object
(passed to the class as ``kwargs['logger']``), whose layout it checks against the
instance name before use, and only for the pythonfmu versions in
:data:`LOGGER_LAYOUT_VERSIONS` (the binary is packed into the FMU at build time, so the
version that builds is the version that runs). Otherwise the message still ends the
instantiation, visible with debug logging.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import models
from models import native
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

try:
    from {module} import {name}  # noqa: E402,F401
except ImportError as _error:
    # A package the model needs is missing from the Python that loads this FMU. Stand in
    # for the class so that instantiation reaches Python: the stand-in reports through
    # the host's logger (error level) and fails the instantiation.
    _package = (getattr(_error, "name", None) or "").split(".")[0] or str(_error)
    sys.__dict__.setdefault("_ins_cosim_fmu_missing", {{}})["{name}"] = (_package, str(_error))
    try:
        from pythonfmu import Fmi2Slave
    except ImportError:  # pythonfmu's binary finds the class by its base's name

        class Fmi2Slave:
            pass

    class {name}(Fmi2Slave):
        def __init__(self, **kwargs):
            import sys

            package, error = sys._ins_cosim_fmu_missing["{name}"]
            install = sys.executable + " -m pip install " + package
            message = (
                "{name}.fmu needs the Python package '" + package + "' in the Python that "
                "loads it (" + sys.executable + "): " + error + ". Install it with: " + install
                + " (this FMU needs {requirements})"
            )
            if {layout_known}:
                self._ins_cosim_log(kwargs, message)
            raise ImportError(message)

        def do_step(self, current_time, step_size):  # never reached: __init__ raises
            return False

        @staticmethod
        def _ins_cosim_log(kwargs, message):
            # pythonfmu {pythonfmu_version}'s logger object (kwargs['logger']): a vtable, a
            # flag, the instance name (std::string), the categories (std::vector), and the
            # host's fmi2CallbackFunctions; checked by the instance name before use.
            import ctypes

            address = kwargs.get("logger")
            name = str(kwargs.get("instance_name", "")).encode()
            if not address:
                return
            words = ctypes.cast(address, ctypes.POINTER(ctypes.c_void_p))
            if words[3] != len(name) or not words[2]:
                return
            if ctypes.string_at(words[2], words[3]) != name or not words[9]:
                return
            functions = ctypes.cast(words[9], ctypes.POINTER(ctypes.c_void_p))
            if not functions[0]:
                return
            logger = ctypes.CFUNCTYPE(
                None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                ctypes.c_char_p,
            )(functions[0])
            text = message.replace("%", "%%").encode()
            logger(functions[4], name, 3, b"logStatusError", text)
"""

#: What every FMU built here needs in the Python interpreter that loads it.
REQUIREMENTS = ("numpy", "scipy", "pythonfmu")
#: pythonfmu versions whose logger layout the entry script reads (see ENTRY_SCRIPT).
LOGGER_LAYOUT_VERSIONS = ("0.7.",)


def entry_script(module: str, name: str) -> str:
    """The entry script of the FMU of class ``module.name`` (see :data:`ENTRY_SCRIPT`).

    Parameters
    ----------
    module : str
        The class's module (``models.gauss_markov``).
    name : str
        The class name, also the FMU's model identifier.

    Returns
    -------
    str
        Python source.
    """
    import pythonfmu

    version = pythonfmu.__version__
    return ENTRY_SCRIPT.format(
        module=module,
        name=name,
        requirements=", ".join(REQUIREMENTS),
        pythonfmu_version=version,
        layout_known=version.startswith(LOGGER_LAYOUT_VERSIONS),
    )


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

    try:  # the compiled kernels travel in the FMU's copy of models/ (models/native/build)
        native.build()
    except RuntimeError as exc:
        message = f"{cls.__name__}.fmu without compiled kernels (runs numpy): {exc}"
        warnings.warn(message, stacklevel=2)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ins_cosim_fmu_") as tmp:
        script = Path(tmp) / f"{cls.__name__}_fmu.py"
        script.write_text(entry_script(cls.__module__, cls.__name__))
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
