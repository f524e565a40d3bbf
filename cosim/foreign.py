"""Which FMUs of a scenario are foreign: not built by ins-cosim from this installation's models.

An FMU is native code in the simulating process; an ``abort()`` or a segmentation fault
in it ends that process with nothing to catch. ``ins-cosim run`` and ``verify --workers
1`` therefore run a scenario that holds a foreign FMU in a child process
(:mod:`cosim.isolate`, :class:`cosim.verify.pool.WorkerPool`), and scenarios of ours only
in-process (docs/foreign_fmus.md says why).

An FMU is *ours* when ``make fmus`` (``ins-cosim fmus --build``) could have written it
from the models installed here: its model identifier names a truth model
(:func:`cosim.registry.truth_models`) and its GUID is that class's
(:meth:`models.block.Block.model_guid`, derived from the class's source). Any other FMU
is foreign: a vendor's, a C fixture, the Reference-FMUs, the FMUs of an SSP archive
written by another tool, and also one of ours built from other (older) sources. The
test is cheap (the model description is read from the zip, no unpacking) and errs on
the safe side: an FMU taken for foreign only costs the child process's start (about a
second).
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

from cosim import registry
from cosim.archives import check_archive
from cosim.blocks import class_identity
from cosim.errors import FmuError

__all__ = ["foreign_fmus", "is_ours"]


def is_ours(path: str | Path) -> bool:
    """Whether an FMU file is one ``make fmus`` builds from the models installed here.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file.

    Returns
    -------
    bool
        True when its model identifier names a truth model and its GUID is that model's;
        False otherwise, also for a file that cannot be read as an FMU.

    Raises
    ------
    FmuError
        An archive over the unpack limits (:func:`cosim.archives.check_archive`).
    """
    from fmpy import read_model_description

    if not Path(path).is_file():
        return False
    check_archive(path)
    try:
        md = read_model_description(str(path), validate=False)
    except Exception:  # unreadable: not ours (building it will say why)
        return False
    cs = md.coSimulation
    name = cs.modelIdentifier if cs is not None else ""
    cls = registry.truth_models().get(name)
    if cls is None:
        return False
    with contextlib.suppress(Exception):
        return class_identity(cls)[0] == md.guid
    return False


def foreign_fmus(scenario: Any, fmu_dir: str | Path | None = None) -> dict[str, str]:
    """The blocks of a scenario that run a foreign FMU.

    Parameters
    ----------
    scenario : cosim.scenario.Scenario
        The scenario (a ``.toml`` file's or an SSP archive's).
    fmu_dir : str or Path, optional
        Where built-in models run from as FMUs (``--fmu-dir``): ``<fmu_dir>/<Model>.fmu``.

    Returns
    -------
    dict
        Block name -> FMU path, in the scenario's order (empty: every block is in-process
        or one of ours).

    Raises
    ------
    ScenarioError
        An FMU over the unpack limits (:func:`cosim.archives.check_archive`), naming the
        block.
    """
    out: dict[str, str] = {}
    for spec in scenario.blocks.values():
        if spec.kind == "fmu":
            path = Path(spec.source)
        elif spec.kind == "model" and fmu_dir is not None and registry.is_truth_model(spec.source):
            path = (Path(fmu_dir) / f"{spec.source}.fmu").resolve()
        else:
            continue
        try:
            ours = is_ours(path)
        except FmuError as exc:  # over the unpack limits: refused as building it would
            key = f"blocks.{spec.name}.fmu"
            raise scenario.error(f"block '{spec.name}': {exc}", key=key) from None
        if not ours:
            out[spec.name] = str(path)
    return out
