"""A test block that notes every time and step size the master hands it
(``clockblocks:TimeProbe``, for tests/core/test_clock.py)."""

from __future__ import annotations

from typing import ClassVar

from cosim.models.block import Block, output


class TimeProbe(Block):
    """Appends ``(t, h)`` of every step to :attr:`SEEN`; ``y = t + h``."""

    variables = (output("y", 0.0, "s"),)
    SEEN: ClassVar[list[tuple[float, float]]] = []

    def step(self, t: float, h: float) -> None:
        TimeProbe.SEEN.append((t, h))
        self.y = t + h
