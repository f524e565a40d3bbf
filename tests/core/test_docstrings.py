"""Every public argument of ``cosim`` and ``models`` is documented (numpy style).

One test case per module found by :func:`pkgutil.walk_packages`, so a failure names
the module; its message lists every offender as ``module.qualname: missing a, b``.

What is checked
---------------
* public functions of the module (``inspect.isfunction`` after :func:`inspect.unwrap`,
  so ``functools.lru_cache``/``wraps`` decorated functions count);
* public classes: the parameters of their constructor, documented in the "Parameters"
  section of the class docstring or of ``__init__``'s;
* public methods defined in a public class (its own ``__dict__``), including
  ``staticmethod``/``classmethod`` and ``__call__``.

Only objects whose ``__module__`` is the module being walked are checked (a name
imported from elsewhere is checked where it is defined); private modules, classes,
functions and methods (leading ``_``) are skipped. Every parameter of
:func:`inspect.signature` except ``self``/``cls``, ``*args`` and ``**kwargs`` must be
an entry of the "Parameters" or "Other Parameters" section: a line ``name : type`` or
``name1, name2 : type`` at the section's indentation (a type is required, as our
standard asks for shapes, units and frames).

Special cases
-------------
* Docstrings are read with :func:`inspect.getdoc`, so an override without a docstring
  inherits its base's (e.g. ``step`` of the blocks inherits ``Block.step``'s). A
  public callable with parameters and no docstring at all fails.
* Dunder methods other than ``__init__`` and ``__call__`` are skipped: their
  arguments are fixed by the Python data model.
* Properties (and ``cached_property``) are skipped: they take no argument, and a
  setter's value is what the property's docstring describes.
* A constructor is checked only in the class that defines it; a subclass that
  inherits ``__init__`` is covered by its base.
* Dataclass-generated ``__init__`` and ``NamedTuple`` fields: the fields must be
  entries of the class docstring's "Attributes" or "Parameters" section (either).
* :class:`enum.Enum` subclasses: the constructor is Enum machinery and is skipped
  (their own methods are still checked).
* Exceptions: only an ``__init__`` the exception defines itself is checked
  (``BaseException.__init__`` takes ``*args``).
* Block subclasses in ``models/`` (and ``cosim.alignment``) declare their FMI variables
  with ``parameter()``/``input_()``/``output()`` and take pythonfmu's ``**kwargs`` in
  ``__init__``: there is nothing to check there (the variables carry their own
  description and unit). Their FMI hooks (``do_step``, ...) are checked like any
  method.
* click commands of ``cosim.cli`` are ``click.Command`` objects, not functions (their
  options are documented by their ``help=`` strings, shown by ``--help``): skipped.
* Nested classes are not walked.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import importlib
import inspect
import pkgutil
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

import cosim
from cosim import models

PACKAGES = (cosim, models)


_HEADER = re.compile(r"^\s*-{3,}\s*$")
_ENTRY = re.compile(r"^(?P<names>\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)*)\s*:(?:\s|$)")
_SKIPPED_KINDS = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)


def documented_names(doc: str | None, sections: tuple[str, ...] = ("Parameters",)) -> set[str]:
    """Names documented in the given numpy sections of a docstring.

    Parameters
    ----------
    doc : str or None
        Docstring, already dedented (as :func:`inspect.getdoc` returns it).
    sections : tuple of str
        Section titles to read ("Other Parameters" is always read with "Parameters").

    Returns
    -------
    set of str
        The entry names, stars stripped (``*args`` gives ``args``).
    """
    if not doc:
        return set()
    wanted = {s.lower() for s in sections}
    if "parameters" in wanted:
        wanted.add("other parameters")
    lines = doc.expandtabs().splitlines()
    names: set[str] = set()
    current: str | None = None
    indent: int | None = None
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and line.strip() and _HEADER.match(lines[i + 1]):
            current, indent = line.strip().lower(), None
            continue
        if _HEADER.match(line) or not line.strip() or current not in wanted:
            continue
        width = len(line) - len(line.lstrip())
        if indent is None:
            indent = width
        if width != indent:
            continue  # an entry's description
        match = _ENTRY.match(line.strip())
        if match:
            names.update(n.strip().lstrip("*") for n in match["names"].split(","))
    return names


def missing_parameters(
    func: Callable[..., object], doc: str | None, sections: tuple[str, ...] = ("Parameters",)
) -> list[str]:
    """Parameters of ``func`` that the sections of ``doc`` do not document.

    Parameters
    ----------
    func : callable
        Function, method or class (a class gives its constructor's signature).
    doc : str or None
        The docstring(s) that should document them.
    sections : tuple of str
        Numpy section titles in which an entry counts.

    Returns
    -------
    list of str
        In signature order; ``self``/``cls``, ``*args`` and ``**kwargs`` are not asked for.
    """
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):  # a builtin without a signature
        return []
    documented = documented_names(doc, sections)
    return [
        p.name
        for i, p in enumerate(signature.parameters.values())
        if p.kind not in _SKIPPED_KINDS
        and not (i == 0 and p.name in ("self", "cls"))
        and p.name not in documented
    ]


def _is_generated_init(cls: type) -> bool:
    """Whether ``cls.__init__`` was written by ``dataclasses`` (not in the class's file)."""
    init = cls.__dict__.get("__init__")
    code = getattr(init, "__code__", None)
    module_file = getattr(sys.modules[cls.__module__], "__file__", None)
    return code is not None and code.co_filename != module_file


def _is_namedtuple(cls: type) -> bool:
    return issubclass(cls, tuple) and hasattr(cls, "_fields")


def _class_offenders(cls: type) -> Iterator[tuple[str, list[str]]]:
    """``(qualname, missing)`` for the constructor and the methods of one class."""
    class_doc = inspect.getdoc(cls)
    if issubclass(cls, enum.Enum):
        pass
    elif (dataclasses.is_dataclass(cls) and _is_generated_init(cls)) or _is_namedtuple(cls):
        missing = missing_parameters(cls, class_doc, ("Parameters", "Attributes"))
        yield cls.__qualname__, missing
    elif "__init__" in cls.__dict__:
        init_doc = cls.__dict__["__init__"].__doc__ or ""
        doc = (class_doc or "") + "\n\n" + inspect.cleandoc(init_doc)
        yield cls.__qualname__, missing_parameters(cls.__dict__["__init__"], doc)
    for name, raw in vars(cls).items():
        if name.startswith("_") and name != "__call__":
            continue
        if isinstance(raw, (property, functools.cached_property)):
            continue
        if isinstance(raw, (staticmethod, classmethod)):
            raw = raw.__func__
        if not inspect.isfunction(inspect.unwrap(raw)):
            continue
        method = getattr(cls, name)
        yield f"{cls.__qualname__}.{name}", missing_parameters(method, inspect.getdoc(method))


def offenders(module_name: str) -> list[str]:
    """Undocumented public arguments of one module.

    Parameters
    ----------
    module_name : str
        Dotted module name, imported here.

    Returns
    -------
    list of str
        One ``module.qualname: missing a, b`` line per offending callable.
    """
    module = importlib.import_module(module_name)
    found: list[tuple[str, list[str]]] = []
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module_name:
            continue
        if inspect.isclass(obj):
            found.extend(_class_offenders(obj))
        elif inspect.isfunction(inspect.unwrap(obj)):
            found.append((obj.__qualname__, missing_parameters(obj, inspect.getdoc(obj))))
    return [f"{module_name}.{q}: missing {', '.join(m)}" for q, m in found if m]


def public_modules() -> list[str]:
    """Every public module of the packages, packages included, sorted."""
    names = [p.__name__ for p in PACKAGES]
    for package in PACKAGES:
        for info in pkgutil.walk_packages(package.__path__, prefix=package.__name__ + "."):
            if not any(part.startswith("_") for part in info.name.split(".")):
                names.append(info.name)
    return sorted(names)


@pytest.mark.parametrize("module_name", public_modules())
def test_public_arguments_are_documented(module_name: str) -> None:
    found = offenders(module_name)
    assert not found, "undocumented arguments:\n" + "\n".join(found)


# ------------------------------------------------------------- the checker itself


def _documented(gain: float, bias: float) -> float:
    """Scale and offset.

    Parameters
    ----------
    gain : float
        Scale factor [1].
    bias : float
        Offset [m/s2], added after scaling.

    Returns
    -------
    float
        Not an entry: ``gain`` here does not count.
    """
    return gain + bias


def _undocumented(gain: float, bias: float, *args: float, **kwargs: float) -> float:  # noqa: D417
    """Scale and offset.

    Parameters
    ----------
    gain : float
        The word bias in a description does not document ``bias``:
    bias
        (an entry without a type does not count either)

    Returns
    -------
    bias : float
        A Returns entry does not count.
    """
    return gain + bias


def _grouped(x: float, y: float, z: float, *, frame: str = "ned") -> None:  # noqa: D417
    """Position.

    Parameters
    ----------
    x, y, z : float
        Coordinates [m].

    Other Parameters
    ----------------
    frame : {"ned", "enu"}
        Navigation frame.
    """


def _no_docstring(x: float) -> None:
    pass


class _Method:
    def scale(self, gain: float) -> None:
        pass


def test_checker_reports_undocumented_arguments() -> None:
    assert missing_parameters(_documented, inspect.getdoc(_documented)) == []
    assert missing_parameters(_undocumented, inspect.getdoc(_undocumented)) == ["bias"]
    assert missing_parameters(_grouped, inspect.getdoc(_grouped)) == []
    assert missing_parameters(_no_docstring, inspect.getdoc(_no_docstring)) == ["x"]
    method = _Method().scale
    assert missing_parameters(method, inspect.getdoc(method)) == ["gain"]


def test_checker_walks_every_module() -> None:
    modules = public_modules()
    assert {"cosim", "cosim.master", "cosim.alignment.transfer", "cosim.models.block"} <= set(
        modules
    )
    assert not any(part.startswith("_") for m in modules for part in m.split("."))


def summary_line_problem(source: str) -> str:
    """What is wrong with a module's summary line ("" when nothing is).

    The first line of a module's docstring says its one concern: a sentence of its own
    (ending with a full stop), followed by a blank line or the end of the docstring.

    Parameters
    ----------
    source : str
        The module's source.

    Returns
    -------
    str
        ``"no docstring"``, ``"the first line is not a sentence of its own"``, or "".
    """
    import ast

    doc = ast.get_docstring(ast.parse(source))
    if not doc or not doc.strip():
        return "no docstring"
    lines = doc.strip().splitlines()
    if not lines[0].rstrip().endswith(".") or (len(lines) > 1 and lines[1].strip()):
        return "the first line is not a sentence of its own"
    return ""


def test_the_summary_line_checker() -> None:
    assert summary_line_problem('"""One concern."""\n') == ""
    assert summary_line_problem('"""One concern.\n\nDetails.\n"""\n') == ""
    assert summary_line_problem('"""One concern and\nanother.\n"""\n') != ""
    assert summary_line_problem("x = 1\n") == "no docstring"


def test_every_module_says_its_concern_in_its_first_line() -> None:
    root = Path(cosim.__file__).resolve().parent
    files = sorted(root.rglob("*.py")) + sorted(
        Path(models.__file__).resolve().parent.rglob("*.py")
    )
    bad = [
        f"{path}: {problem}"
        for path in files
        if "__pycache__" not in path.parts
        and (problem := summary_line_problem(path.read_text(encoding="utf-8")))
    ]
    assert not bad, "\n".join(bad)
