"""The master loop's own cost per macro step: the transfer chain with blocks of zero work.

The chain of ``benchmarks/transfer_chain.toml`` (ship motion -> deck flexure -> lever arm
-> slave IMU: 81 Real outputs, 43 connected inputs, every output recorded) is rebuilt
from blocks that declare exactly the chain models' variables (the same classes'
``variables``, so the same vectors, scalars and value references) and do no work: each
step publishes precomputed outputs the way the models do (every output attribute
rebound to a new value), so what is timed is the master and the block exchange alone.

Variants, interleaved in one process (best CPU time of :data:`REPEATS` rounds each, 10 ms
steps; the best wall time of ``full`` is printed too):

- ``full``: every connection, every output recorded: the master's cost per macro step;
- ``no recording``: the same without recording (``output.variables`` empty);
- ``bare``: the same four blocks with no connection and no output read (blocks that
  declare no variables): the loop itself (time grid, rates, one ``do_step`` per block);
- ``in place``: ``full`` with blocks that write their vector outputs into the arrays
  they hold (views of the block's output buffer) instead of rebinding them.

The blocks' own work (``publish``: their ``step`` called alone, rebinding the outputs)
is timed too and left out. The row prints the master's cost per macro step (``full -
publish``) and the exchange's share (``no recording - bare - publish``: outputs read,
checked and stored, inputs gathered and written).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from benchmarks.timing import load_note
from cosim.blocks import InProcessHost
from cosim.master import Connection, Master, MasterSettings, System
from cosim.models.block import Block
from cosim.models.blocks.deck_flexure import DeckFlexure
from cosim.models.blocks.lever_arm import LeverArm
from cosim.models.blocks.ship_motion import ShipMotion
from cosim.models.blocks.strapdown_imu import StrapdownImu

#: Macro steps per timed run (10 ms steps: 60 s simulated).
STEPS = 6000
STEP = 0.01
REPEATS = 5

#: The chain's connections (``benchmarks/transfer_chain.toml``), vector by vector.
LINKS = [
    ("ship", "omega_ib_b", "lever", "omega_ib_b"),
    ("ship", "omega_dot_b", "lever", "omega_dot_b"),
    ("ship", "f_b", "lever", "f_b"),
    ("ship", "dtheta_b", "lever", "dtheta_b"),
    ("ship", "dv_b", "lever", "dv_b"),
    ("ship", "rpy", "lever", "rpy"),
    ("ship", "v_n", "lever", "v_n"),
    ("ship", "lat", "lever", "lat"),
    ("flexure", "theta", "lever", "theta"),
    ("flexure", "theta_dot", "lever", "theta_dot"),
    ("flexure", "theta_ddot", "lever", "theta_ddot"),
    ("flexure", "dtheta_flex", "lever", "dtheta_flex"),
    ("flexure", "dtheta_dot_flex", "lever", "dtheta_dot_flex"),
    ("lever", "dtheta_s", "imu", "dtheta_b"),
    ("lever", "dv_s", "imu", "dv_b"),
]
MODELS = {"ship": ShipMotion, "flexure": DeckFlexure, "lever": LeverArm, "imu": StrapdownImu}


def zero_work(model: type, keep_variables: bool = True, in_place: bool = False) -> type:
    """A block class with ``model``'s variables whose step only republishes its outputs.

    Parameters
    ----------
    model : type
        A :class:`models.block.Block` subclass (its ``variables`` are copied).
    keep_variables : bool
        False for a block that declares no variable at all (the ``bare`` variant).
    in_place : bool
        Publish vector outputs by writing into the output arrays (``self.y[:] = ...``)
        instead of rebinding them.

    Returns
    -------
    type
        The class: ``initialize`` prepares one new value per output (a float or a
        float64 array of the declared length), ``step`` rebinds every output to it.
    """
    variables = model.variables if keep_variables else ()
    outs = [v for v in variables if v.causality == "output" and v.kind == "Real"]

    def initialize(self: Block) -> None:
        self._next = [(v.name, np.full(v.size, 0.5) if v.is_vector else 0.5) for v in outs]

    def step(self: Block, t: float, h: float) -> None:
        for name, value in self._next:
            setattr(self, name, value)

    def step_in_place(self: Block, t: float, h: float) -> None:
        for name, value in self._next:
            if type(value) is float:
                setattr(self, name, value)
            else:
                getattr(self, name)[:] = value

    return type(
        f"ZeroWork{model.__name__}",
        (Block,),
        {
            "__doc__": f"{model.__name__}'s variables, no work.",
            "__module__": __name__,
            "variables": variables,
            "initialize": initialize,
            "step": step_in_place if in_place else step,
        },
    )


def chain_master(
    connect: bool = True, record: bool = True, variables: bool = True, in_place: bool = False
) -> Master:
    """The zero-work chain's master.

    Parameters
    ----------
    connect : bool
        Make the chain's 43 scalar connections.
    record : bool
        Record every output (else nothing but the time).
    variables : bool
        Blocks with the chain models' variables (else blocks with none).
    in_place : bool
        Blocks that write their vector outputs in place (see :func:`zero_work`).

    Returns
    -------
    Master
        Gauss-Seidel, :data:`STEPS` macro steps of :data:`STEP`.
    """
    blocks = {n: InProcessHost(n, zero_work(cls, variables, in_place)) for n, cls in MODELS.items()}
    links: list[Connection] = []
    if connect and variables:
        for src, out, dst, inp in LINKS:
            size = next(v.size for v in MODELS[src].variables if v.name == out)
            if size == 1:
                links.append(Connection(src, out, dst, inp))
            else:
                links += [
                    Connection(src, f"{out}[{i}]", dst, f"{inp}[{i}]") for i in range(1, size + 1)
                ]
    system = System(blocks, links, record=None if record else [])
    return Master(system, MasterSettings(STEP, STEP * STEPS))


def best_times(
    tasks: dict[str, Callable[[], Any]], repeats: int
) -> tuple[dict[str, float], dict[str, float]]:
    """Best wall time and best CPU time of each task over interleaved rounds.

    Parameters
    ----------
    tasks : dict
        Name -> function of no argument.
    repeats : int
        Rounds; each runs every task once, in order.

    Returns
    -------
    wall, cpu : dict
        Name -> smallest ``time.perf_counter`` / ``time.process_time`` difference [s]
        (CPU time is what a loaded machine disturbs least).
    """
    wall = {name: float("inf") for name in tasks}
    cpu = dict(wall)
    for _ in range(repeats):
        for name, task in tasks.items():
            w, c = time.perf_counter(), time.process_time()
            task()
            wall[name] = min(wall[name], time.perf_counter() - w)
            cpu[name] = min(cpu[name], time.process_time() - c)
    return wall, cpu


def bench() -> list[dict[str, Any]]:
    """Row: the master's own cost per macro step, and the exchange's share."""
    note = load_note()
    masters = {
        "full": chain_master(),
        "no recording": chain_master(record=False),
        "bare": chain_master(connect=False, record=False, variables=False),
        "in place": chain_master(in_place=True),
    }

    def runner(master: Master) -> Any:
        state = {"ran": False}

        def go() -> None:
            if state["ran"]:
                master.reset()
            master.run()
            state["ran"] = True

        return go

    def publisher(master: Master) -> Any:
        blocks = [h.instance for h in master.system.blocks.values()]

        def publish() -> None:  # the blocks' own work: publishing their outputs
            for _ in range(STEPS):
                for block in blocks:
                    block.step(0.0, STEP)

        return publish

    tasks = {k: runner(m) for k, m in masters.items()}
    tasks["publish"] = publisher(masters["full"])
    tasks["publish in place"] = publisher(masters["in place"])
    start = time.perf_counter()
    best_wall, best_cpu = best_times(tasks, REPEATS)
    wall = time.perf_counter() - start
    us = {k: 1e6 * v / STEPS for k, v in best_cpu.items()}
    wall_full = 1e6 * (best_wall["full"] - best_wall["publish"]) / STEPS
    own = us["full"] - us["publish"]  # the master's own cost
    own_in_place = us["in place"] - us["publish in place"]
    exchange = us["no recording"] - us["bare"] - us["publish"]
    recording = us["full"] - us["no recording"]
    return [
        {
            "name": "master loop, zero-work transfer chain (4 blocks): us per macro step",
            "ratio": own,
            "target": "report",
            "met": None,
            "info": (
                f"{own:.1f} us of CPU per macro step (wall {wall_full:.1f} us): exchange "
                f"(81 outputs read and checked, 43 inputs written) {exchange:.1f} us "
                f"({100 * exchange / own:.0f}%), "
                f"recording 81 columns {recording:.1f} us, loop and do_step calls "
                f"{us['bare']:.1f} us (the blocks' own rebinding of their outputs, "
                f"{us['publish']:.1f} us, left out); best of {REPEATS} interleaved runs of "
                f"{STEPS} steps ({wall:.1f} s); with blocks that write their vector "
                f"outputs in place {own_in_place:.1f} us; {note}"
            ),
        }
    ]
