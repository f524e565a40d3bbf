"""First-order sensor with constant bias and white noise (demo block of the core).

Equations::

    tau y' = -y + u                (exact: y+ = a y + (1 - a) u,  a = exp(-h / tau))
    m = y + b + n,                 n ~ N(0, N^2 / h)

``N`` is the white-noise density [unit * sqrt(s)], so the sample standard
deviation scales with the step as a real sensor's does. The input is held
constant over the step (the master's zero-order hold).
"""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, input_, output, parameter


class FirstOrderSensor(Block):
    """First-order lag sensor with bias and white noise."""

    variables = (
        parameter("time_constant", 0.1, "s", "first-order lag time constant"),
        parameter("bias", 0.0, "rad", "constant bias"),
        parameter("noise_density", 0.0, "rad/sqrt(Hz)", "white-noise density N"),
        parameter("seed", 0, description="random seed"),
        input_("u", 0.0, "rad", "measured quantity"),
        output("y", 0.0, "rad", "noise-free lagged quantity"),
        output("m", 0.0, "rad", "measurement: y + bias + noise"),
    )
    default_stop = 10.0

    def initialize(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self.y = float(self.u)
        self.m = self.y + self.bias

    def step(self, t: float, h: float) -> None:
        a = math.exp(-h / self.time_constant)
        self.y = a * self.y + (1.0 - a) * self.u
        noise = self.noise_density / math.sqrt(h) * float(self._rng.standard_normal())
        self.m = self.y + self.bias + noise
