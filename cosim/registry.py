"""Blocks found by name: what ``model = "<Name>"`` in a scenario means.

Two sources, looked up in this order:

1. **Truth models**: every :class:`models.block.Block` class of the ``models`` package,
   by class name (:func:`truth_models`). These are the models ``ins-cosim fmus --build``
   packs into FMUs and that ``--fmu-dir`` swaps for their FMU.
2. **Entry points** of the group :data:`GROUP` (``ins_cosim.blocks``) of any installed
   distribution: the entry point's name is the scenario's name, its value the class as
   ``"module:Class"``. ins-cosim registers its own alignment filters this way (see
   ``pyproject.toml``); a user's package adds its filters and models the same way,
   without touching this repository (docs/extending.md)::

       [project.entry-points."ins_cosim.blocks"]
       MyFilter = "my_package.filters:MyFilter"

Loading is lazy: an entry point's module is imported only when its name is asked for,
so a broken third-party package breaks only the lookups of its own names, with a
:class:`~cosim.errors.ScenarioError` that names the entry point, its distribution and
the import error. The core never imports the packages above it (alignment, verify,
...): it reaches their blocks through their entry points only.
"""

from __future__ import annotations

import functools
import os
import sys
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from cosim import models, provenance
from cosim.errors import ScenarioError, did_you_mean
from cosim.models.block import Block

#: Entry-point group of block classes (name in a scenario -> ``"module:Class"``).
GROUP = "ins_cosim.blocks"


@dataclass(frozen=True)
class Registration:
    """Where one scenario name comes from, without importing it.

    Attributes
    ----------
    name : str
        The name a scenario writes as ``model = "<name>"``.
    target : str
        ``"module:Class"``.
    distribution : str
        ``"<distribution> <version>"`` that declares it (``"models"`` for a truth model).
    location : str
        Where the distribution is installed (empty for a truth model).
    """

    name: str
    target: str
    distribution: str
    location: str = ""

    def __str__(self) -> str:
        where = f" at {self.location}" if self.location else ""
        return f"'{self.name} = {self.target}' of {self.distribution}{where}"


def truth_models() -> dict[str, type[Block]]:
    """The built-in truth and sensor models (the package ``models``), by class name.

    Returns
    -------
    dict
        ``{class name: class}``, sorted by name: exactly what ``make fmus`` packs (found
        once per process: the package does not change while it runs).
    """
    return dict(_truth_models())


@functools.cache
def _truth_models() -> dict[str, type[Block]]:
    return models.truth_models()


def entry_points() -> dict[str, list[Registration]]:
    """Every entry point of the group :data:`GROUP`, by name; nothing is imported.

    Returns
    -------
    dict
        ``{name: [registration, ...]}``, sorted by name; a list holds more than one
        registration when several distributions claim the same name.
    """
    state = _path_state()
    if _scanned.get("state") != state:
        _scanned.update(state=state, found=_scan())
    return {name: list(regs) for name, regs in _scanned["found"].items()}


#: The last scan of the entry points and the state of ``sys.path`` it was made in.
_scanned: dict[str, Any] = {}


def _path_state() -> tuple[tuple[str, int | None], ...]:
    """Every ``sys.path`` folder with its modification time: a distribution installed or
    removed changes it, so the entry points are scanned again only then."""
    out = []
    for entry in sys.path:
        # absolute: a forkserver started from here has '' where its workers have this
        # folder (Python 3.11 does not pass sys.path to it), the same folder either way
        folder = os.path.abspath(entry or ".")
        try:
            out.append((folder, os.stat(folder).st_mtime_ns))
        except OSError:
            out.append((folder, None))
    return tuple(out)


def _scan() -> dict[str, list[Registration]]:
    found: dict[str, list[Registration]] = {}
    for ep in metadata.entry_points(group=GROUP):
        dist = ep.dist
        if dist is None:
            label, location = "an unknown distribution", ""
        else:
            name, version = provenance.name_and_version(dist)
            label = f"distribution '{name} {version}'"
            location = str(Path(dist.locate_file("")).resolve())
        found.setdefault(ep.name, []).append(Registration(ep.name, ep.value, label, location))
    return dict(sorted(found.items()))


def names() -> list[str]:
    """Every name a scenario can give as ``model = "..."``, truth models first.

    Returns
    -------
    list of str
        The truth models sorted by name, then the entry points' names sorted (a name
        appears once even when it is claimed twice; :func:`find_block` reports that).
        No entry point's module is imported.
    """
    truth = list(truth_models())
    return truth + [n for n in entry_points() if n not in truth]


def is_truth_model(name: str) -> bool:
    """Whether ``name`` is a built-in truth model (one that has an FMU in ``fmus/build``).

    Parameters
    ----------
    name : str
        A scenario's ``model = "..."`` value.

    Returns
    -------
    bool
        True for a class of the ``models`` package; False for an entry point's block
        (alignment filters and users' blocks run in-process only) or an unknown name.
    """
    return name in truth_models()


def find_block(name: str) -> type[Block]:
    """The block class a scenario's ``model = "<name>"`` stands for.

    Parameters
    ----------
    name : str
        A truth model's class name or an entry point's name of the group :data:`GROUP`.

    Returns
    -------
    type
        A :class:`models.block.Block` subclass; only its own module is imported.

    Raises
    ------
    ScenarioError
        Without a file (the caller adds it): an unknown name (with the closest known
        name and the list of known ones), a name claimed by more than one source, or an
        entry point that cannot be loaded (its name, value, distribution and the error).
    """
    truth = truth_models()
    registered = entry_points().get(name, [])
    if name in truth and not registered:
        return truth[name]
    if name in truth or len(registered) > 1:
        claims = ([f"'{truth[name].__module__}:{name}' of models"] if name in truth else []) + [
            str(r) for r in registered
        ]
        raise ScenarioError(
            f"model name '{name}' is claimed more than once: {'; '.join(claims)}; "
            f"rename the entry point of one of them (group '{GROUP}')"
        )
    if not registered:
        known = names()
        tip = did_you_mean(name, known)
        raise ScenarioError(
            f"unknown model '{name}'.{tip} Known models: {', '.join(known)} "
            f"(a package adds its own through the entry-point group '{GROUP}')"
        )
    return _load(registered[0])


def _load(reg: Registration) -> type[Block]:
    """Import one registration's class, or a ScenarioError that says why it cannot be."""
    ep = metadata.EntryPoint(reg.name, reg.target, GROUP)
    try:
        cls = ep.load()
    except Exception as exc:  # a third party's import error of any kind, reported as such
        raise ScenarioError(
            f"model '{reg.name}' cannot be loaded: entry point {reg} failed with "
            f"{type(exc).__name__}: {exc}; fix or reinstall that package"
        ) from exc
    if not (isinstance(cls, type) and issubclass(cls, Block)):
        raise ScenarioError(
            f"model '{reg.name}': entry point {reg} gives {cls!r}, not a subclass of "
            f"cosim.models.block.Block"
        )
    return cls
