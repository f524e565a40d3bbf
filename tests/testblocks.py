"""Small blocks with analytic behaviour, for tests of the master and of error handling."""

from __future__ import annotations

import math

import numpy as np

from cosim.models.block import Block, input_, output, parameter


class Ramp(Block):
    """Outputs the time at the end of its last step: y = t + h (t0 after initialisation)."""

    variables = (output("y", 0.0, "s"),)

    def initialize(self) -> None:
        self.y = self.start_time

    def step(self, t: float, h: float) -> None:
        self.y = t + h


class Pass(Block):
    """Direct feedthrough with an offset: y = u + offset, valid at the end of the step."""

    variables = (
        parameter("offset", 0.0, "s"),
        input_("u", 0.0, "s"),
        output("y", 0.0, "s"),
    )

    def initialize(self) -> None:
        self.y = self.u + self.offset

    def step(self, t: float, h: float) -> None:
        self.y = self.u + self.offset


class Clock(Block):
    """Reports the t and h it was called with: t_end = t + h, plus the count of steps."""

    variables = (output("t_end", 0.0, "s"), output("count", 0.0))

    def initialize(self) -> None:
        self.t_end = self.start_time

    def step(self, t: float, h: float) -> None:
        self.t_end = t + h
        self.count += 1.0


class Faulty(Block):
    """Fails on purpose from ``fail_time`` on: mode 1 outputs NaN, mode 2 reports failure."""

    variables = (
        parameter("fail_time", 0.5, "s"),
        parameter("mode", 1),
        output("y", 0.0),
    )

    def step(self, t: float, h: float) -> None:
        self.y = t + h
        if t + h > self.fail_time and self.mode == 1:
            self.y = math.nan

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.step(current_time, step_size)
        return not (self.mode == 2 and current_time + step_size > self.fail_time)


class Vec(Block):
    """A 3-vector source and a 3-vector sink in one block: y = u * gain."""

    variables = (
        parameter("gain", 1.0),
        input_("u", (0.0, 0.0, 0.0), "rad"),
        output("y", (1.0, 2.0, 3.0), "rad"),
    )

    def initialize(self) -> None:
        self.y = self.gain * self.u

    def step(self, t: float, h: float) -> None:
        self.y = self.gain * self.u


class DegSource(Block):
    """A vendor-style source that speaks degrees: y = 90 deg."""

    variables = (output("y", 90.0, "deg"),)

    def step(self, t: float, h: float) -> None:
        self.y = 90.0


class Converging(Block):
    """Stand-in for an alignment filter: an error that decays from a random start.

    ``error = e0 exp(-(t - t0) / tau) + noise w``, ``e0 ~ N(0, sigma0^2)`` and ``w ~ N(0, 1)``
    drawn from ``seed``; ``sigma`` is the matching 1-sigma,
    ``sqrt(sigma0^2 exp(-2 (t - t0) / tau) + noise^2)``. When ``seed == fail_seed`` the
    block reports failure from ``fail_time`` on (for campaign tests).
    """

    variables = (
        parameter("sigma0", 0.01, "rad"),
        parameter("tau", 2.0, "s"),
        parameter("noise", 1.0e-4, "rad"),
        parameter("seed", 0),
        parameter("fail_seed", -1),
        parameter("fail_time", 1.0, "s"),
        output("error", 0.0, "rad"),
        output("sigma", 0.0, "rad"),
    )

    def initialize(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._e0 = self.sigma0 * float(self._rng.standard_normal())
        self._update(self.start_time)

    def _update(self, t: float) -> None:
        decay = math.exp(-(t - self.start_time) / self.tau)
        self.error = self._e0 * decay + self.noise * float(self._rng.standard_normal())
        self.sigma = math.sqrt((self.sigma0 * decay) ** 2 + self.noise**2)

    def step(self, t: float, h: float) -> None:
        self._update(t + h)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.step(current_time, step_size)
        failing = self.seed == self.fail_seed and current_time + step_size > self.fail_time
        return not failing


class StepLog(Block):
    """Keeps every (t, h) it is stepped with (the master's step ends), in ``steps``."""

    variables = (output("n", 0.0, "1"),)

    def initialize(self) -> None:
        self.steps: list[tuple[float, float]] = []

    def step(self, t: float, h: float) -> None:
        self.steps.append((t, h))
        self.n = float(len(self.steps))
