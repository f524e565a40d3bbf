"""Truth and sensor models: one module per block class (see ``models/block.py``).

:func:`registry` finds every concrete :class:`~models.block.Block` subclass
defined in a module of this package; ``make fmus`` packs each into an FMU.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

from .block import Block

_NOT_BLOCKS = {"block", "constants", "conventions", "earth", "frames", "step_paths"}


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
        if info.name.startswith("_") or info.name in _NOT_BLOCKS:
            continue
        module = importlib.import_module(f"{package}.{info.name}")
        for name, obj in inspect.getmembers(module, inspect.isclass):
            if issubclass(obj, Block) and obj is not Block and obj.__module__ == module.__name__:
                found[name] = obj
    return dict(sorted(found.items()))


def truth_models() -> dict[str, type[Block]]:
    """All truth-model classes in ``models/``, by class name.

    :mod:`cosim.registry` adds the blocks of installed packages (entry points) to these.

    Returns
    -------
    dict
        ``{class name: class}``, sorted by name.
    """
    return find_blocks(__name__, __path__)
