"""Shared by the tests of the transfer filter's kernels: a short transfer-alignment run.

Not a test module: ``tests/models/test_native_publish.py``, ``test_native_master.py`` and
``test_native_feedback.py`` build the seed 001 scenario, shortened, with the compiled
kernels on or off, and reach its ``TransferAlignment`` block.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.alignment.transfer import TransferAlignment
from cosim.master import Master
from cosim.models import native
from cosim.scenario import build_master

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "transfer_alignment.toml"


def needs_library() -> None:
    """Skip the calling test when the compiled kernels do not load here."""
    if native.library() is None:
        pytest.skip(f"no compiled kernels: {native.status()}")


def short_master(mp: pytest.MonkeyPatch, env: str, stop: float, **overrides: object) -> Master:
    """The transfer-alignment scenario stopped at ``stop`` [s], kernels on (``env="1"``) or
    off (``"0"``: ``INS_COSIM_NATIVE`` is read when the blocks initialise)."""
    mp.setenv(native.ENV, env)
    return build_master(cosim.load_scenario(SCENARIO), **{"stop": stop, **overrides})


def align_block(master: Master) -> TransferAlignment:
    """The scenario's filter block (``align``), in-process."""
    block = master.system.blocks["align"].instance
    assert isinstance(block, TransferAlignment)
    return block


def runs_both_ways(
    mp: pytest.MonkeyPatch, stop: float, check: Callable[[TransferAlignment, bool], None]
) -> tuple[np.ndarray, np.ndarray]:
    """The short run with every kernel off (``INS_COSIM_NATIVE=0``), then on.

    Parameters
    ----------
    mp : pytest.MonkeyPatch
        Sets the switch.
    stop : float
        Stop time [s] (every step recorded).
    check : callable ``check(block, compiled)``
        Asserts on the filter block after each run (``compiled``: the kernels were on).

    Returns
    -------
    numpy, compiled : structured ndarray
        The two recordings.
    """
    runs = {}
    for env in ("0", "1"):
        master = short_master(mp, env, stop, record_every=1)
        try:
            result = master.run()
            check(align_block(master), env == "1")
        finally:
            master.terminate()
        assert result.status == "completed"
        runs[env] = result.data
    return runs["0"], runs["1"]
