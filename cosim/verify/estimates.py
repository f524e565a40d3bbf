"""Requirements on a filter's estimates, for runs without truth (real sensor logs).

A run on recorded logs has no truth: the filter's error outputs (``*_err``, estimate minus
the truth input) would compare its estimate with the truth inputs' start values. Two kinds
of requirement need no truth:

* **against a reference value** given in the scenario (a survey, an established toolbox's
  result on the same log)::

      [[requirements]]
      id = "HDG-REF"
      signal = "align.rpy[3]"        # the estimate (yaw, rad)
      reference = "90.60 deg"        # e = estimate - reference
      sigma = "align.rpy_sigma[3]"   # optional: the report's +/-3 sigma band
      unit = "arcmin"
      criterion = "value"
      at = "300 s"
      bound = "6 arcmin"

  The error is ``e = signal - reference`` in the display ``unit``; for an angle unit it is
  wrapped to (-180 deg, 180 deg] unless ``wrap = false`` (a heading of -179.9 deg is
  0.2 deg from a reference of 179.9 deg). ``reference`` and ``minus`` exclude each other.
  The report draws the **estimate** (in the reference's own unit) with the filter's
  +/-3 sigma band, the reference and the reference +/- the bound, not the error.
* **against the filter's own sigma**: the signal is a 1-sigma output
  (``signal = "align.rpy_sigma[3]"``, ``criterion = "value"``, ``bound = "3 arcmin"``):
  "the filter claims heading within 3' (1 sigma) at 300 s". This says nothing about
  whether the claim is true: that needs truth, or the consistency verdicts.

Which inputs are truth: by the project's naming rule, a filter's inputs whose names end
in ``_true`` (``rpy_true``, ``rpy_s_true``, ``azimuth_true``) feed only its error outputs,
whose names end in ``_err``, and its ``nees``. :func:`check_truth` refuses a requirement
on an error output while any truth input of its block is left unconnected (``check`` and
``verify`` stop with the requirement, the inputs and the fix, exit code 3). The NEES is
left to the consistency verdicts, which judge it only when the truth is connected.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cosim.errors import ScenarioError, UnitError
from cosim.units import conversion_factor, to_unit

#: Suffix of a truth input's name, and of an output that is estimate minus truth.
TRUTH_SUFFIX = "_true"
ERROR_SUFFIX = "_err"


@dataclass(frozen=True)
class Reference:
    """A requirement's reference value.

    Attributes
    ----------
    value : float
        The reference in the requirement's display unit (subtracted from the signal).
    text : str
        As written in the scenario (``"90.60 deg"``).
    unit : str
        The unit it was written in (``"deg"``); the report draws the estimate in it.
    to_unit : float
        Factor from the display unit to :attr:`unit`.
    angle : bool
        Whether the display unit is an angle (the error is then wrapped by default).
    """

    value: float
    text: str
    unit: str
    to_unit: float
    angle: bool

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the JSON report."""
        return {"value": self.value, "text": self.text, "unit": self.unit}


def parse_reference(table: Mapping[str, Any], unit: str, err: Any) -> Reference | None:
    """The ``reference`` key of a requirement table, in its display unit.

    Parameters
    ----------
    table : mapping
        The ``[[requirements]]`` table.
    unit : str
        The requirement's display unit (checked already).
    err : callable
        ``err(message, key) -> ScenarioError`` of the requirement (file and key).

    Returns
    -------
    Reference or None
        None when the table has no ``reference``.

    Raises
    ------
    ScenarioError
        Not one number with a unit of the display unit's kind, or given with ``minus``.
    """
    if "reference" not in table:
        return None
    raw = table["reference"]
    if "minus" in table:
        raise err(
            "'reference' (a value) and 'minus' (a truth signal) both say what the signal is "
            "compared with; keep one",
            "reference",
        )
    try:
        value = to_unit(raw, unit)
    except UnitError as exc:
        message = f"{exc.message} (the reference must be of the kind of '{unit}')"
        raise err(message, "reference") from exc
    if isinstance(value, (bool, list)) or not math.isfinite(float(value)):
        raise err(f"expected one number with a unit, e.g. '90.60 deg', got {raw!r}", "reference")
    written = raw.split(None, 1)[1].strip() if isinstance(raw, str) and " " in raw.strip() else unit
    try:
        factor = conversion_factor(unit, written)
    except UnitError:
        written, factor = unit, 1.0
    try:
        conversion_factor(unit, "rad")
        angle = True
    except UnitError:
        angle = False
    return Reference(float(value), str(raw), written, factor, angle)


def truth_outputs(block: str, host: Any) -> list[str]:
    """The error outputs of a block, estimate minus its truth inputs (``*_err``).

    Parameters
    ----------
    block : str
        The block's name.
    host : BlockHost
        Its host (variables).

    Returns
    -------
    list of str
        Scalar output names, ``"<block>.<name>"``.
    """
    out = []
    for v in host.by_causality("output"):
        base = v.name.split("[", 1)[0]
        if base.endswith(ERROR_SUFFIX):
            out.append(f"{block}.{v.name}")
    return out


def check_truth(
    requirements: Sequence[Any],
    system: Any,
    unconnected: Mapping[str, Mapping[str, Any]],
    file: str,
) -> None:
    """Refuse a requirement on an error output whose block has its truth left unconnected.

    Parameters
    ----------
    requirements : sequence of Requirement
        The parsed requirements.
    system : cosim.master.System
        The built system (hosts).
    unconnected : mapping
        Block -> {input: start value} of the inputs left unconnected (build metadata).
    file : str
        The scenario file.

    Raises
    ------
    ScenarioError
        Keyed ``requirements[i].<key>``: the column, the truth inputs and two ways out.
    """
    for req in requirements:
        for key in ("signal", "minus", "sigma"):
            column = getattr(req, key, None)
            if not column:
                continue
            block, _, name = column.partition(".")
            host = system.blocks.get(block)
            if host is None or column not in truth_outputs(block, host):
                continue
            left = sorted(
                {
                    n.split("[", 1)[0]
                    for n in unconnected.get(block, {})
                    if n.split("[", 1)[0].endswith(TRUTH_SUFFIX)
                }
            )
            if not left:
                continue
            base, _, index = name.partition("[")
            estimate = base[: -len(ERROR_SUFFIX)] if base.endswith(ERROR_SUFFIX) else ""
            names = {v.name for v in host.by_causality("output")}
            idx = f"[{index}" if index else ""
            ways = "connect the truth"
            if estimate and f"{estimate}{idx}" in names:
                ways += (
                    f", or state it against a reference value (signal = "
                    f"'{block}.{estimate}{idx}', reference = '<value> <unit>')"
                )
            if f"{estimate}_sigma{idx}" in names:
                ways += f" or against the filter's sigma (signal = '{block}.{estimate}_sigma{idx}')"
            raise ScenarioError(
                f"requirement '{req.id}': '{column}' is estimate minus truth, but the truth "
                f"input(s) {', '.join(left)} of block '{block}' are not connected (a log has "
                f"no truth), so it would compare the estimate with their start values; "
                f"{ways}",
                file=file,
                key=f"requirements[{req.index}].{key}",
            )
