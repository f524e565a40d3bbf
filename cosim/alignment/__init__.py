"""Alignment filters: Python blocks in the same protocol as the truth models.

They derive from :class:`models.block.Block` and run in-process (scenario key
``model = "<ClassName>"``, found through the ``ins_cosim.blocks`` entry points as
``cosim.alignment:<ClassName>``). They are not packed into FMUs by ``make fmus``: they
are the system under test, not truth models.

Every filter is its error model plus its block, on one navigation core:

- :mod:`cosim.alignment.nav`: the one strapdown integrator and the small rotation
  helpers every filter shares;
- :mod:`cosim.alignment.coarse`: analytic (TRIAD) coarse alignment;
- :mod:`cosim.alignment.static_model` + :mod:`cosim.alignment.sins_static`: the
  stationary 10-state KF (seed 003);
- :mod:`cosim.alignment.transfer_model` (+ ``transfer_filter``, the two-stage
  estimator, and ``transfer_analysis``, its covariance analysis) +
  :mod:`cosim.alignment.transfer`: shipboard transfer alignment, 19-state scaled UKF
  (seed 001);
- :mod:`cosim.alignment.hrg_model` (+ ``hrg_filters``) +
  :mod:`cosim.alignment.hrg_two_position`: the two-position HRG platform alignment,
  EKF / UPF / KF (seed 000);
- :func:`cosim.estimation.covariance.covariance_analysis`: the one covariance loop the
  filters' linear analyses run on.

The block classes are attributes of this package, imported on first use (a filter's
module, and what it imports, loads only when its block is asked for).
"""

from __future__ import annotations

import importlib
from typing import Any

#: Block class name -> the module of this package that defines it.
BLOCKS = {
    "HrgTwoPositionAlignment": "hrg_two_position",
    "SinsStaticAlignment": "sins_static",
    "TransferAlignment": "transfer",
}

__all__ = [*BLOCKS, "BLOCKS"]


def __getattr__(name: str) -> Any:
    """``cosim.alignment.<BlockName>``: import the block's module on first use."""
    if name in BLOCKS:
        cls = getattr(importlib.import_module(f"{__name__}.{BLOCKS[name]}"), name)
        globals()[name] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
