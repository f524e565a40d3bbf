"""Shared by the tests of the transfer filter's kernels: a short transfer-alignment run.

Not a test module: ``tests/test_native_publish.py`` and ``tests/test_native_master.py``
build the seed 001 scenario, shortened, with the compiled kernels on or off, and reach its
``TransferAlignment`` block.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import cosim
from cosim.alignment.transfer import TransferAlignment
from cosim.master import Master
from cosim.scenario import build_master
from models import native

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
