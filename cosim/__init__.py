"""ins-cosim: co-simulation workbench for the initial alignment of inertial navigation systems.

Python API::

    import cosim
    scenario = cosim.load_scenario("scenarios/demo.toml")
    result = cosim.run(scenario)            # RunResult: result.data, result["sensor.m"]
    result.save("out/demo")                 # results.csv + results.json
"""

from __future__ import annotations

from pathlib import Path

from cosim.errors import FmuError, ScenarioError, SimulationError, UnitError, UserError
from cosim.master import Connection, Master, MasterSettings, System
from cosim.results import RunResult
from cosim.runs import make_run
from cosim.scenario import Scenario, build_master, load_scenario

__all__ = [
    "Connection",
    "FmuError",
    "Master",
    "MasterSettings",
    "RunResult",
    "Scenario",
    "ScenarioError",
    "SimulationError",
    "System",
    "UnitError",
    "UserError",
    "build_master",
    "load_scenario",
    "make_run",
    "run",
]


def run(
    scenario: Scenario | str | Path, *, fmu_dir: str | Path | None = None, **overrides: object
) -> RunResult:
    """Run a scenario once (:func:`cosim.runs.make_run`).

    Parameters
    ----------
    scenario : Scenario, str or Path
        A loaded scenario or the path of its TOML file.
    fmu_dir : str or Path, optional
        Run built-in models from the FMUs in this folder.
    **overrides
        Master settings to override (``step``, ``stop``, ``start``, ``coupling``,
        ``record_every``; see :meth:`Scenario.master_settings`).

    Returns
    -------
    RunResult
        The recording, ``time`` first, SI units, with metadata.

    Raises
    ------
    ScenarioError, FmuError
        Before anything runs, when the scenario is inconsistent.
    SimulationError
        When a block fails or outputs a non-finite value; ``error.result`` keeps what
        was recorded up to then.
    TypeError
        An override that is not a master setting.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    return make_run(scenario, fmu_dir=fmu_dir, overrides=overrides)
