"""Pack the model blocks (``models/blocks/``) into FMI 2.0 co-simulation FMUs with pythonfmu.

Each FMU holds a short entry script that imports its class, plus in its resources a
``cosim`` stub package holding a copy of ``cosim.models`` (the repository's ``models/``)
without what the FMU does not run: no model pages, reference results or C sources, only
the compiled kernels' library (:func:`models_copy`); pythonfmu packs its own Python runtime
beside it. The FMU's model page is its FMI ``documentation/index.html``
(:mod:`cosim.interop.fmudocs`). numpy and scipy (:data:`REQUIREMENTS`) come from the
Python interpreter that loads the FMU; pythonfmu need not be installed there. In a host
that has imported ins-cosim already, the FMU reuses that ``cosim.models``. When one of
the requirements is missing there,
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

import ast
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

from cosim import models
from cosim.interop.fmudocs import write_documentation
from cosim.models import native
from cosim.models.block import Block

MODELS_DIR = Path(models.__file__).resolve().parent
#: The ``cosim/__init__.py`` an FMU carries: a marker, nothing imported.
STUB_INIT = '''"""The part of ins-cosim an FMU carries (its models; no commands)."""

_ins_cosim_fmu_stub = True
'''

# The FMU's entry module. pythonfmu imports it, then executes it once more per instance
# with separate globals and locals (so: no comprehensions here, they would not see the
# local names), and releases one reference to the module namespace that it never took
# (pythonfmu 0.7 findClass): each execution keeps one reference to balance that, or the
# namespace is freed under the module and the interpreter crashes later.
# A `cosim` stub package imported earlier in the same process from another FMU's resources
# may point to a folder deleted when that FMU was unloaded: forget it, so that this FMU
# imports its own copy; a live stub of another FMU gets this FMU's folders on its paths
# (each FMU carries only the modules its model imports, and a log replay FMU carries
# cosim.sensors). A real ins-cosim imported by the host is left alone: the FMU uses its
# cosim.models.
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

_previous = sys.modules.get("cosim")
if _previous is not None and getattr(_previous, "_ins_cosim_fmu_stub", False):
    _stale = False
    for _folder in _previous.__path__:
        if not os.path.isdir(_folder):
            _stale = True
    if _stale:
        for _key in list(sys.modules):
            if _key == "cosim" or _key.startswith("cosim."):
                del sys.modules[_key]
    elif sys.path:
        _own = os.path.join(os.path.abspath(sys.path[0]), "cosim")
        if os.path.isdir(_own) and _own not in _previous.__path__:
            _previous.__path__.append(_own)
        for _sub in ("models", "models.blocks"):
            _package = sys.modules.get("cosim." + _sub)
            _own_sub = os.path.join(_own, *_sub.split("."))
            if _package is not None and os.path.isdir(_own_sub):
                if _own_sub not in _package.__path__:
                    _package.__path__.append(_own_sub)

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

#: What every FMU built here needs in the Python interpreter that loads it (pythonfmu's
#: runtime travels inside the FMU: pythonfmu's builder packs it into the resources).
REQUIREMENTS = ("numpy", "scipy")
#: pythonfmu versions whose logger layout the entry script reads (see ENTRY_SCRIPT).
LOGGER_LAYOUT_VERSIONS = ("0.7.",)


def entry_script(module: str, name: str) -> str:
    """The entry script of the FMU of class ``module.name`` (see :data:`ENTRY_SCRIPT`).

    Parameters
    ----------
    module : str
        The class's module (``models.blocks.gauss_markov``).
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


def _module_file(dotted: str) -> Path | None:
    """The file of a module of the models package (``cosim.models.x.y``), or None."""
    parts = dotted.split(".")
    if parts[:2] != ["cosim", "models"]:
        return None
    base = MODELS_DIR.joinpath(*parts[2:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if parts[2:] and candidate.is_file():
            return candidate
    return MODELS_DIR / "__init__.py" if not parts[2:] else None


def _dotted(path: Path) -> str:
    """``cosim.models...`` name of a file of the models package."""
    rel = path.relative_to(MODELS_DIR).with_suffix("").parts
    return ".".join(("cosim", "models", *(p for p in rel if p != "__init__")))


def needed_modules(source: Path) -> set[str]:
    """The modules of the models package that the code in ``source`` imports, transitively.

    Read from the import statements (relative and absolute ones), functions' lazy imports
    included; a package's ``__init__`` comes with each of its modules.

    Parameters
    ----------
    source : Path
        A Python file: a model's module, or a block's module outside the package.

    Returns
    -------
    set of str
        The files' paths inside the package, without ``.py`` (``"__init__"``, ``"block"``,
        ``"native/__init__"``, ``"blocks/lever_arm"``, ...), ``source``'s own included
        when it is in the package.
    """
    found: set[Path] = set()
    todo = [source.resolve(), MODELS_DIR / "__init__.py"]
    while todo:
        path = todo.pop()
        inside = path.is_relative_to(MODELS_DIR)
        if path in found:
            continue
        if inside:
            found.add(path)
            package = path.parent
            while package != MODELS_DIR:  # a package's __init__ runs before its modules
                todo.append(package / "__init__.py")
                package = package.parent
        me = _dotted(path) if inside else ""
        here = me if path.name == "__init__.py" else me.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom):
                continue
            module = node.module or ""
            if node.level:
                if not inside:
                    continue
                base = here.split(".")[: len(here.split(".")) - node.level + 1]
                module = ".".join(base + ([module] if module else []))
            for name in (module, *(f"{module}.{a.name}" for a in node.names)):
                file = _module_file(name)
                if file is not None:
                    todo.append(file)
    return {p.relative_to(MODELS_DIR).with_suffix("").as_posix() for p in found}


def models_copy(dest: Path, source: Path | None = None) -> Path:
    """Copy the models package as an FMU runs it into ``dest/cosim/models``.

    Left out: the modules ``source`` does not need (:func:`needed_modules`), the model
    pages (``docs/``; the FMU's own page is its documentation folder), the reference
    results (``reference/``), the C sources and headers, caches, and every compiled
    library but the current one (:func:`cosim.models.native.library_path`, copied when it
    was built).

    Parameters
    ----------
    dest : Path
        The folder that becomes the FMU's resources.
    source : Path, optional
        The file of the block's module; None copies every module.

    Returns
    -------
    Path
        The ``cosim`` folder made (with :data:`STUB_INIT` as its ``__init__.py``).
    """
    library = native.library_path()
    keep = None if source is None else needed_modules(source)

    def ignore(folder: str, names: list[str]) -> set[str]:
        skip = {n for n in names if n in ("docs", "reference", "__pycache__", "build")}
        if keep is not None:
            rel = Path(folder).resolve().relative_to(MODELS_DIR).as_posix()
            prefix = "" if rel == "." else rel + "/"
            for n in names:
                if n.endswith(".py") and prefix + n.removesuffix(".py") not in keep:
                    skip.add(n)
                elif (Path(folder) / n).is_dir() and not any(
                    k.startswith(prefix + n + "/") for k in keep
                ):
                    skip.add(n)
        return skip | {n for n in names if n.endswith((".c", ".h", ".md", ".pyc", ".so"))}

    package = dest / "cosim"
    shutil.copytree(MODELS_DIR, package / "models", ignore=ignore, dirs_exist_ok=True)
    if library.is_file() and (keep is None or "native/__init__" in keep):
        build = package / "models" / "native" / "build"
        build.mkdir(parents=True, exist_ok=True)
        shutil.copy2(library, build / library.name)
    (package / "__init__.py").write_text(STUB_INIT)
    return package


def build_fmu(cls: type[Block], out_dir: Path, extra_files: tuple[Path, ...] = ()) -> Path:
    """Build ``out_dir/<ClassName>.fmu`` from a block class.

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass defined in a module of ``models``.
    out_dir : Path
        Destination folder (created if missing).
    extra_files : tuple of Path
        Further files and folders to ship in the resources (for classes defined outside
        ``models``); a folder named ``cosim`` is merged into the FMU's ``cosim`` package.

    Returns
    -------
    Path
        The FMU file.
    """
    from pythonfmu.builder import FmuBuilder

    from cosim.interop.modeldocs import DOCS_DIR, notes_of, render

    try:  # the compiled kernels travel in the FMU's copy of the models
        native.build()
    except RuntimeError as exc:
        message = f"FMUs built without compiled kernels (they run numpy): {exc}"
        warnings.warn(message, stacklevel=2)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ins_cosim_fmu_") as tmp:
        script = Path(tmp) / f"{cls.__name__}_fmu.py"
        script.write_text(entry_script(cls.__module__, cls.__name__))
        resources = Path(tmp) / "resources"
        package = models_copy(resources, Path(sys.modules[cls.__module__].__file__))
        others = []
        for extra in map(Path, extra_files):
            if extra.is_dir() and extra.name == "cosim":
                shutil.copytree(extra, package, dirs_exist_ok=True)
                (package / "__init__.py").write_text(STUB_INIT)
            else:
                others.append(extra)
        page = DOCS_DIR / f"{cls.__name__}.md"
        if not page.is_file():  # a block outside models/: its page made from the class
            page = Path(tmp) / f"{cls.__name__}.md"
            page.write_text(render(cls, notes_of(page)), encoding="utf-8")
        documentation = write_documentation(page, Path(tmp) / "documentation", cls.__name__)
        return FmuBuilder.build_FMU(
            script,
            dest=out_dir / f"{cls.__name__}.fmu",
            project_files=[package, *others],
            documentation_folder=documentation.parent,
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
