"""A requirement's time window against the run, checked before anything runs."""

from __future__ import annotations

from collections.abc import Sequence

from cosim.errors import ScenarioError
from cosim.verify.requirements import Requirement


def check_windows(
    requirements: Sequence[Requirement], start: float, stop: float, file: str
) -> None:
    """Refuse a requirement whose time window lies outside the run, before anything runs.

    Parameters
    ----------
    requirements : sequence of Requirement
        As returned by :func:`cosim.verify.requirements.load_requirements`.
    start, stop : float
        The run's start and stop times [s] (``master.start``, ``master.stop``).
    file : str
        The scenario file (for the message).

    Raises
    ------
    ScenarioError
        A ``from`` or ``at`` after the stop time, or an ``until`` before the start time,
        naming the requirement's key.
    """
    for req in requirements:
        where = f"requirements[{req.index}]"
        for key, t in (("from", req.start), ("at", req.at)):
            if t is not None and t > stop:
                raise ScenarioError(
                    f"requirement '{req.id}': '{key}' = {t:g} s is after the stop time "
                    f"({stop:g} s), so no run can be judged; move it into the run or "
                    f"lengthen master.stop",
                    file=file,
                    key=f"{where}.{key}",
                )
        if req.until is not None and req.until < start:
            raise ScenarioError(
                f"requirement '{req.id}': 'until' = {req.until:g} s is before the start time "
                f"({start:g} s)",
                file=file,
                key=f"{where}.until",
            )
