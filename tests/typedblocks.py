"""In-process test blocks with Integer and Boolean outputs and inputs (``typedblocks:Counter``,
``typedblocks:Tally``), for the typed links of tests/core/test_typed_values.py."""

from __future__ import annotations

from cosim.models.block import Block, input_, output


class Counter(Block):
    """``n`` (Integer) counts the steps taken; ``odd`` (Boolean) is ``n`` odd."""

    variables = (output("n", 0), output("odd", False))

    def initialize(self) -> None:
        self.n, self.odd = 0, False

    def step(self, t: float, h: float) -> None:
        self.n += 1
        self.odd = self.n % 2 == 1


class Tally(Block):
    """``y = 10 m + (1 if b else 0)`` from an Integer input ``m`` and a Boolean input ``b``;
    ``total`` (Integer) sums ``m`` over the steps."""

    variables = (input_("m", 0), input_("b", False), output("y", 0.0), output("total", 0))

    def initialize(self) -> None:
        self.y, self.total = 10.0 * self.m + self.b, 0

    def step(self, t: float, h: float) -> None:
        self.y = 10.0 * self.m + (1.0 if self.b else 0.0)
        self.total += self.m
