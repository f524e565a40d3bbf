"""A cheap block with turn-on errors a campaign can stratify (``[campaign] stratify``)."""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, output, parameter


class TurnOnError(Block):
    """An error made of a turn-on bias (a 2-vector) and a gain error, plus white noise.

    ``error = bias[1] + 0.5 bias[2] + gain t + noise w``, ``w ~ N(0, 1)`` per step from
    ``seed``. With ``bias_sigma > 0`` the block draws ``bias`` from its seed as
    ``bias + bias_sigma N(0, I)`` (likewise ``gain`` with ``gain_sigma``), which is what a
    stratified campaign replaces by its own draw (and sets the sigma to 0). ``sigma`` is
    the matching 1-sigma; ``drawn_bias`` and ``drawn_gain`` are the values the run used.
    """

    variables = (
        parameter("bias", (0.0, 0.0), "rad"),
        parameter("bias_sigma", 0.0, "rad"),
        parameter("gain", 0.0, "rad/s"),
        parameter("gain_sigma", 0.0, "rad/s"),
        parameter("noise", 1.0e-5, "rad"),
        parameter("seed", 0),
        output("error", 0.0, "rad"),
        output("sigma", 0.0, "rad"),
        output("drawn_bias", (0.0, 0.0), "rad"),
        output("drawn_gain", 0.0, "rad/s"),
    )

    def initialize(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        turn_on = self._rng.standard_normal(3)
        self._bias = np.asarray(self.bias, dtype=float) + self.bias_sigma * turn_on[:2]
        self._gain = float(self.gain) + self.gain_sigma * float(turn_on[2])
        self.drawn_bias = (float(self._bias[0]), float(self._bias[1]))
        self.drawn_gain = self._gain
        self._update(self.start_time)

    def _update(self, t: float) -> None:
        dt = t - self.start_time
        w = float(self._rng.standard_normal())
        self.error = float(self._bias[0] + 0.5 * self._bias[1] + self._gain * dt) + self.noise * w
        self.sigma = math.sqrt(
            1.25 * self.bias_sigma**2 + (self.gain_sigma * dt) ** 2 + self.noise**2
        )

    def step(self, t: float, h: float) -> None:
        self._update(t + h)
