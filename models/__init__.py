"""The model library and, in :mod:`cosim.models.blocks`, the model blocks built on it.

This folder is the library every model shares: the block protocol (``block``), the
unit factors and physical constants (``constants``), the attitude conventions
(``conventions``, and ``conventions.h`` for the C kernels), the earth model (``earth``),
frame changes (``frames``), the step paths of exact increments (``step_paths``) and the
compiled kernels' loader (``native``). The subpackage ``blocks/`` holds the model blocks,
one module per block class; :func:`truth_models` finds every concrete
:class:`~cosim.models.block.Block` subclass defined there, and ``make fmus`` packs each
into an FMU.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

from . import blocks
from .block import Block


def find_blocks(package: str, path: list[str]) -> dict[str, type[Block]]:
    """Concrete :class:`Block` subclasses defined in the modules of a package.

    Parameters
    ----------
    package : str
        Dotted package name.
    path : list of str
        The package's ``__path__``.

    Returns
    -------
    dict
        ``{class name: class}``, sorted by name.
    """
    found: dict[str, type[Block]] = {}
    for info in pkgutil.iter_modules(path):
        if info.name.startswith("_") or info.ispkg:
            continue
        module = importlib.import_module(f"{package}.{info.name}")
        for name, obj in inspect.getmembers(module, inspect.isclass):
            if issubclass(obj, Block) and obj is not Block and obj.__module__ == module.__name__:
                found[name] = obj
    return dict(sorted(found.items()))


def truth_models() -> dict[str, type[Block]]:
    """All model blocks of :mod:`cosim.models.blocks`, by class name.

    :mod:`cosim.registry` adds the blocks of installed packages (entry points) to these.

    Returns
    -------
    dict
        ``{class name: class}``, sorted by name.
    """
    return find_blocks(blocks.__name__, list(blocks.__path__))
