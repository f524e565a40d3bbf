"""The block exchange as arrays (issue 18, item 2): readers and writers bound per run.

Each test compares the array path with what the block holds or with an analytic answer,
bit for bit: the exchange moves values, it never computes them.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from testblocks import Pass

from cosim import models
from cosim.blocks import FmuHost, InProcessHost
from cosim.interop.packaging import build_fmu
from cosim.master import JACOBI, Connection, Master, MasterSettings, System
from cosim.models.block import Block, input_, output
from cosim.models.blocks.strapdown_imu import StrapdownImu
from cosim.variables import REAL

H = 0.01


def expected_values(block: Block, names: list[str]) -> list[float]:
    """The block's Real values by scalar name (``x`` or ``x[i]``), read from its attributes."""
    values = []
    for name in names:
        base, _, index = name.partition("[")
        value = getattr(block, base)
        values.append(float(value) if not index else float(np.asarray(value)[int(index[:-1]) - 1]))
    return values


def stepped(cls: type, steps: int = 3) -> InProcessHost:
    """A host of ``cls`` initialised with its defaults and stepped ``steps`` times."""
    host = InProcessHost("b", cls)
    host.setup(0.0, {"seed": 3} if "seed" in host.variables else {})
    host.exit_init()
    for n in range(steps):
        host.do_step(n * H, H)
    return host


@pytest.mark.parametrize("name", sorted(models.truth_models()))
def test_reader_gives_every_model_its_attributes_values_bit_for_bit(name: str) -> None:
    host = stepped(models.truth_models()[name])
    outs = [v for v in host.by_causality("output") if v.type == REAL]
    table = np.full(len(outs) + 2, np.nan)  # the block's part of a larger value table
    part = table[1:-1]
    host.real_reader([v.vr for v in outs], part)()
    assert part.tolist() == expected_values(host.instance, [v.name for v in outs])
    assert part.tolist() == host.get_real([v.vr for v in outs])
    assert math.isnan(table[0]) and math.isnan(table[-1])  # nothing written outside


WITH_INPUTS = sorted(
    name
    for name, cls in models.truth_models().items()
    if any(v.causality == "input" and v.kind == "Real" for v in cls.variables)
)


@pytest.mark.parametrize("name", WITH_INPUTS)
def test_writer_sets_every_models_inputs_and_keeps_them_views_of_the_buffer(name: str) -> None:
    host = stepped(models.truth_models()[name], steps=0)
    ins = [v for v in host.by_causality("input") if v.type == REAL]
    block = host.instance
    before = {v.name.partition("[")[0]: getattr(block, v.name.partition("[")[0]) for v in ins}
    x = np.random.default_rng(1).standard_normal(len(ins))
    host.real_writer([v.vr for v in ins])(x)
    assert expected_values(block, [v.name for v in ins]) == x.tolist()
    for attr, value in before.items():
        if isinstance(value, np.ndarray):  # written in place: the same array object
            assert getattr(block, attr) is value
        else:  # scalars are Python floats, as set_real with a list sets them
            assert type(getattr(block, attr)) is float


class InPlace(Block):
    """Vectors written in place around a scalar: a = u, s = 2 u[0], b = -u."""

    variables = (
        input_("u", (0.0, 0.0, 0.0)),
        output("a", (0.0, 0.0, 0.0)),
        output("s", 0.0),
        output("b", (0.0, 0.0, 0.0)),
    )

    def step(self, t: float, h: float) -> None:
        self.a[:] = self.u
        self.s = 2.0 * self.u[0]
        np.negative(self.u, out=self.b)


class Rebinding(InPlace):
    """The same outputs, each step a new array (as the truth models do)."""

    def step(self, t: float, h: float) -> None:
        self.a = self.u.copy()
        self.s = 2.0 * self.u[0]
        self.b = -self.u


class Odd(InPlace):
    """The same values from odd containers: an int array, a float32, a strided view."""

    def step(self, t: float, h: float) -> None:
        self.a = np.rint(self.u).astype(np.int64)  # integers: converted to floats
        self.s = np.float32(2.0 * self.u[0])
        self.b = (-np.repeat(self.u, 2))[::2]  # not contiguous


class Mixed(InPlace):
    """a written in place, b rebound to a strided view (joined bytes refused mid-way)."""

    def step(self, t: float, h: float) -> None:
        self.a[:] = self.u
        self.s = 2.0 * self.u[0]
        self.b = (-np.repeat(self.u, 2))[::2]


class Ramp3(Block):
    """u(t) = (t, 10 t, -t) at the end of each step, degrees; a rebound array."""

    variables = (output("y", (0.0, 0.0, 0.0), "deg"),)

    def step(self, t: float, h: float) -> None:
        self.y = np.array([t + h, 10.0 * (t + h), -(t + h)])


def run_pair(sink: type, coupling: str = "gauss-seidel") -> np.ndarray:
    blocks = {"sink": InProcessHost("sink", sink), "src": InProcessHost("src", Ramp3)}
    # declared backwards (u[3] first) and with a unit factor: the master sorts by value
    # reference and applies the factor to the whole vector
    deg = math.pi / 180.0
    links = [Connection("src", f"y[{i}]", "sink", f"u[{i}]", deg) for i in (3, 2, 1)]
    master = Master(System(blocks, links), MasterSettings(H, 0.1, coupling=coupling))
    return master.run().data


@pytest.mark.parametrize("coupling", ["gauss-seidel", JACOBI])
def test_in_place_rebinding_and_odd_outputs_give_the_same_bits(coupling: str) -> None:
    runs = [run_pair(cls, coupling) for cls in (InPlace, Rebinding, Mixed, Odd)]
    t = runs[0]["time"]
    src_t = t if coupling == "gauss-seidel" else np.concatenate([[0.0], t[:-1]])
    deg = math.pi / 180.0
    first = runs[0]
    # Gauss-Seidel: the sink sees the source's value at the end of the same step;
    # Jacobi: at the step's start. Factor applied once: y * (pi / 180).
    np.testing.assert_array_equal(first["sink.a[2]"][1:], (10.0 * src_t * deg)[1:])
    np.testing.assert_array_equal(first["sink.b[1]"][1:], -(src_t * deg)[1:])
    np.testing.assert_array_equal(first["sink.s"][1:], (2.0 * (src_t * deg))[1:])
    for other in runs[1:3]:
        assert other.tobytes() == first.tobytes()
    odd = runs[3]  # the same values through the conversions (a rounded to integers)
    np.testing.assert_array_equal(odd["sink.b[3]"], first["sink.b[3]"])
    np.testing.assert_array_equal(odd["sink.a[2]"], np.rint(first["sink.a[2]"]))
    np.testing.assert_array_equal(odd["sink.s"], first["sink.s"].astype(np.float32))


def test_an_input_connected_twice_takes_the_last_connection_as_before() -> None:
    blocks = {
        "a": InProcessHost("a", Pass),
        "b": InProcessHost("b", Pass),
        "sink": InProcessHost("sink", Pass),
    }
    links = [Connection("a", "y", "sink", "u"), Connection("b", "y", "sink", "u")]
    params = {"a": {"offset": 1.0}, "b": {"offset": 2.0}}
    data = Master(System(blocks, links, params), MasterSettings(H, 0.05)).run().data
    np.testing.assert_array_equal(data["sink.y"][1:], 2.0)  # b's value, set last


def test_a_rebound_input_is_still_written_into_the_models_array() -> None:
    class Holds(Pass):
        """Replaces its input array by its own (the buffer's view is then unused)."""

        variables = (input_("v", (0.0, 0.0)), output("w", (0.0, 0.0)))

        def initialize(self) -> None:
            self.v = np.array([7.0, 8.0])
            self.w = self.v.copy()

        def step(self, t: float, h: float) -> None:
            self.w = self.v.copy()

    host = InProcessHost("h", Holds)
    host.setup(0.0, {})
    host.exit_init()
    own = host.instance.v
    write = host.real_writer([host.variables["v[1]"].vr, host.variables["v[2]"].vr])
    write(np.array([1.5, -2.5]))
    assert host.instance.v is own and own.tolist() == [1.5, -2.5]


def test_outputs_held_in_lists_or_scalar_arrays_are_read_as_get_real_converts_them() -> None:
    host = stepped(Rebinding, steps=1)
    block = host.instance
    block.a = [1, 2, 3]  # a list of ints
    block.s = 4  # an int for a Real scalar
    vrs = [v.vr for v in host.by_causality("output")]
    out = np.zeros(len(vrs))
    host.real_reader(vrs, out)()
    assert out.tolist() == [1.0, 2.0, 3.0, 4.0] + block.b.tolist()
    assert out.tolist() == host.get_real(vrs)


def test_a_non_finite_output_stops_the_run_naming_the_element() -> None:
    class Bad(Block):
        """y[2] becomes inf at t >= 0.03 s."""

        variables = (output("y", (0.0, 0.0, 0.0)), output("z", 0.0))

        def step(self, t: float, h: float) -> None:
            self.y = np.array([1.0, math.inf if t + h > 0.025 else 2.0, 3.0])

    master = Master(System({"bad": InProcessHost("bad", Bad)}, []), MasterSettings(H, 0.1))
    with pytest.raises(Exception, match="not finite") as info:
        master.run()
    assert info.value.block == "bad" and info.value.variable == "y[2]"
    assert info.value.time == pytest.approx(0.03)
    assert len(info.value.result.data) == 3  # t0, 0.01, 0.02 recorded


def test_bench_master_chain_has_the_transfer_chains_variables() -> None:
    from benchmarks.bench_master import chain_master

    master = chain_master()
    hosts = master.system.blocks.values()
    outs = sum(len([v for v in h.by_causality("output") if v.type == REAL]) for h in hosts)
    assert outs == 81 and len(master.system.connections) == 43
    short = chain_master(record=False)
    short.settings = MasterSettings(H, 0.05)
    assert len(short.run().data) == 6


CHILD = r"""
import json, sys
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

md = read_model_description(sys.argv[1])
vr = {v.name: v.valueReference for v in md.modelVariables}
fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(sys.argv[1]),
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="imu")
fmu.instantiate()
fmu.setupExperiment(startTime=0.0)
fmu.enterInitializationMode()
fmu.setInteger([vr["seed"]], [3])
fmu.exitInitializationMode()
ins = json.loads(sys.argv[2])
outs = json.loads(sys.argv[3])
rows = []
for n, x in enumerate(ins):
    fmu.setReal([vr[k] for k in x], list(x.values()))
    fmu.doStep(n * 0.01, 0.01)
    rows.append(fmu.getReal([vr[k] for k in outs]))
fmu.terminate()
fmu.freeInstance()
from cosim import models
print(json.dumps({"rows": rows, "models": models.__file__}))
"""


def test_the_model_inside_its_fmu_in_another_interpreter_equals_in_process(
    tmp_path: Path,
) -> None:
    """pythonfmu calls get_real/set_real by value references inside the FMU, with the
    FMU's own copy of ``models`` (a child interpreter): same bits as the array path."""
    fmu = build_fmu(StrapdownImu, tmp_path)
    host = InProcessHost("imu", StrapdownImu)
    ins = [v for v in host.by_causality("input") if v.type == REAL]
    outs = [v for v in host.by_causality("output") if v.type == REAL]
    rng = np.random.default_rng(7)
    names, out_names = [v.name for v in ins], [v.name for v in outs]
    drive = [dict(zip(names, 1e-4 * rng.standard_normal(len(ins)), strict=True)) for _ in range(5)]
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            CHILD,
            str(fmu),
            json.dumps(drive),
            json.dumps(out_names),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        env={"PATH": "/usr/bin:/bin"},
    )
    assert proc.returncode == 0, proc.stderr
    child = json.loads(proc.stdout.splitlines()[-1])
    assert "resources" in child["models"]  # the FMU's own copy of the package
    host.setup(0.0, {"seed": 3})
    host.exit_init()
    write = host.real_writer([v.vr for v in ins])
    out = np.zeros(len(outs))
    read = host.real_reader([v.vr for v in outs], out)
    for n, x in enumerate(drive):
        write(np.array(list(x.values())))
        host.do_step(n * H, H)
        read()
        assert out.tolist() == child["rows"][n]


def test_fmu_host_reads_and_writes_whole_arrays_like_get_and_set(tmp_path: Path) -> None:
    fmu = build_fmu(StrapdownImu, tmp_path)
    a, b = FmuHost("a", fmu), FmuHost("b", fmu)
    ins = [v.vr for v in a.by_causality("input") if v.type == REAL]
    outs = [v.vr for v in a.by_causality("output") if v.type == REAL]
    values = np.zeros(len(outs) + 1)
    out = values[1:]
    write, read = b.real_writer(ins), b.real_reader(outs, out)
    x = 1e-4 * np.random.default_rng(2).standard_normal((4, len(ins)))
    try:
        for host in (a, b):
            host.setup(0.0, {"seed": 5})
            host.exit_init()
        for n in range(4):
            a.set_real(ins, x[n].tolist())
            write(x[n])
            a.do_step(n * H, H)
            b.do_step(n * H, H)
            read()
            assert out.tolist() == a.get_real(outs) and values[0] == 0.0
    finally:
        a.terminate()
        b.terminate()
