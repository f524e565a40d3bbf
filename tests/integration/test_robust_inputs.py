"""Bad input answered in one line (issue 14, items 4 to 6): the limit or the key, no traceback.

Each case runs ``ins-cosim`` in this process (click's runner) and checks the exit code 3,
a single ``error:`` line naming the file and key, and what the line says.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

import cosim
from cosim import limits
from cosim.cli import main
from cosim.errors import ScenarioError, UnitError
from cosim.master import MAX_STEPS, Connection, schedule
from cosim.scenario import load_scenario
from cosim.units import MAX_UNIT_CHARS, parse_unit, to_unit

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "scenarios" / "demo.toml"
MASTER = '[master]\nstep = "10 ms"\nstop = "1 s"\n'
GAUSS_MARKOV_BLOCK = '[blocks.gm]\nmodel = "GaussMarkov2"\n'
PAIR = (
    'connections = ["flexure.x -> sensor.u"]\n'
    + MASTER
    + '[blocks.flexure]\nmodel = "GaussMarkov2"\n[blocks.sensor]\nmodel = "FirstOrderSensor"\n'
)


def write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def refused(*args: str, code: int = 3) -> str:
    """Run the CLI; assert it refused in one line without a traceback; return that line."""
    res = CliRunner().invoke(main, [str(a) for a in args])
    assert res.exit_code == code, (res.exit_code, res.output)
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    lines = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, res.output
    assert "Traceback" not in res.output
    return lines[0]


# ------------------------------------------------------------------- item 4: mistakes
def test_a_class_that_is_not_a_block_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, '[blocks.gm]\nclass = "os:path"\n' + MASTER)
    line = refused("check", path)
    assert f"{path}, key 'blocks.gm.class'" in line
    assert "'os:path' is a module, not a block" in line
    assert "models.block.Block" in line


def test_a_nested_list_as_a_parameter_is_refused(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        GAUSS_MARKOV_BLOCK.replace('"\n', '"\nparameters = { tau = [[1, 2]] }\n', 1) + MASTER,
    )
    line = refused("check", path)
    assert "key 'blocks.gm.parameters.tau'" in line
    assert "nested list" in line


def test_an_infinite_stop_is_refused_in_the_file_and_on_the_command_line(tmp_path: Path) -> None:
    path = write(tmp_path, '[master]\nstep = "10 ms"\nstop = inf\n' + GAUSS_MARKOV_BLOCK)
    line = refused("check", path)
    assert f"{path}, key 'master.stop'" in line and "finite" in line
    line = refused("run", DEMO, "--out", tmp_path / "out", "--stop", "1e400")
    assert "key '--stop'" in line and "finite" in line and "master.stop" not in line
    assert not (tmp_path / "out").exists()


def test_a_bad_stop_option_is_named_as_the_option(tmp_path: Path) -> None:
    line = refused("run", DEMO, "--out", tmp_path / "out", "--stop", "1.005 s")
    assert f"{DEMO}, key '--stop'" in line
    assert "whole positive number of steps" in line and "master.stop" not in line
    line = refused("run", DEMO, "--out", tmp_path / "out", "--stop", "ten seconds")
    assert "key '--stop'" in line


def test_step_and_stop_errors_name_the_file(tmp_path: Path) -> None:
    for master, key in (
        ('step = "-1 ms"\nstop = "1 s"', "master.step"),
        ('step = "3 ms"\nstop = "1 s"', "master.stop"),
        ('step = "1 ms"\nstop = "1 m"', "master.stop"),
    ):
        path = write(tmp_path, f"[master]\n{master}\n" + GAUSS_MARKOV_BLOCK)
        assert f"{path}, key '{key}'" in refused("check", path)


def test_too_many_steps_are_refused_by_check_with_the_limit_and_the_value(tmp_path: Path) -> None:
    # 10^15 steps: 'check' used to say OK and 'run' tried to allocate petabytes
    path = write(tmp_path, '[master]\nstep = "1 us"\nstop = "1e9 s"\n' + GAUSS_MARKOV_BLOCK)
    line = refused("check", path)
    assert "key 'master.stop'" in line
    assert "1e+15 macro steps" in line and f"{MAX_STEPS:.0e}" in line


def test_a_recording_that_would_not_fit_in_memory_is_refused_with_its_size(
    tmp_path: Path,
) -> None:
    path = write(tmp_path, '[master]\nstep = "10 us"\nstop = "10000 s"\n' + GAUSS_MARKOV_BLOCK)
    line = refused("check", path)
    assert "key 'output.every'" in line
    assert "1000000001 rows x 3 columns = 22.4 GiB" in line and "limit of 2 GiB" in line
    # recording every 1000th step of the same run fits
    path = write(
        tmp_path,
        '[master]\nstep = "10 us"\nstop = "10000 s"\n[output]\nevery = 1000\n' + GAUSS_MARKOV_BLOCK,
    )
    res = CliRunner().invoke(main, ["check", str(path)])
    assert res.exit_code == 0, res.output


def test_toml_nested_ten_thousand_deep_is_refused_quickly(tmp_path: Path) -> None:
    path = write(
        tmp_path, "x = " + "[" * 10_000 + "]" * 10_000 + "\n" + MASTER + GAUSS_MARKOV_BLOCK
    )
    start = time.perf_counter()
    line = refused("check", path)
    assert time.perf_counter() - start < 5
    assert "nest 10000 levels deep (from line 1)" in line
    assert f"limit of {limits.MAX_DEPTH}" in line
    # inline tables count as well, and brackets inside strings and comments do not
    deep = "x = " + "{a = " * 40 + "1" + "}" * 40 + "\n"
    assert "nest 40 levels deep" in refused(
        "check", write(tmp_path, deep + MASTER + GAUSS_MARKOV_BLOCK)
    )
    text = '[scenario]\ndescription = "' + "[" * 40 + '"  # ' + "{" * 40 + "\n"
    ok = CliRunner().invoke(
        main, ["check", str(write(tmp_path, text + MASTER + GAUSS_MARKOV_BLOCK))]
    )
    assert ok.exit_code == 0, ok.output


def test_tables_nested_by_dotted_keys_are_refused(tmp_path: Path) -> None:
    header = "[" + ".".join(["a"] * 5000) + "]\nx = 1\n"
    line = refused("check", write(tmp_path, MASTER + GAUSS_MARKOV_BLOCK + header))
    assert f"more than the limit of {limits.MAX_DEPTH}" in line


def test_a_hundred_megabyte_file_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "huge.toml"
    with path.open("wb") as f:
        f.truncate(100 * 2**20)  # 100 MiB (sparse: the check reads the size, not the bytes)
    start = time.perf_counter()
    line = refused("check", path)
    assert time.perf_counter() - start < 5
    assert f"the file is {100 * 2**20} bytes" in line
    assert f"limit of {limits.MAX_FILE_BYTES} bytes" in line


def test_an_existing_file_as_out_or_report_is_refused_before_the_run(tmp_path: Path) -> None:
    precious = tmp_path / "results.csv"
    precious.write_text("a result that must not be lost\n")
    res = CliRunner().invoke(main, ["run", str(DEMO), "--out", str(precious)])
    assert res.exit_code == 3
    assert "--out" in res.output and "is an existing file; give a folder" in res.output
    assert "running" not in res.output  # refused before anything ran
    res = CliRunner().invoke(main, ["run", str(DEMO), "--out", str(precious / "sub")])
    assert res.exit_code == 3 and "is under" in res.output
    verify = ROOT / "scenarios" / "demo_verify.toml"
    res = CliRunner().invoke(main, ["verify", str(verify), "--report", str(precious)])
    assert res.exit_code == 3 and "--report" in res.output and "existing file" in res.output
    assert precious.read_text() == "a result that must not be lost\n"


def test_a_parameter_a_block_refuses_at_initialisation_is_bad_input(tmp_path: Path) -> None:
    """A coarse window too short for the fine filter (a ValueError of the block's own
    check) exits 3 with the block, the parameter and the fix, and no empty results file
    (a block failing while it steps exits 4: tests/integration/test_robust_fmus.py)."""
    text = (ROOT / "scenarios" / "sins_north_finding_sway.toml").read_text()
    assert 'coarse_time = "60 s"' in text
    path = tmp_path / "short.toml"
    path.write_text(text.replace('coarse_time = "60 s"', 'coarse_time = "30 s"'))
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["run", str(path), "--out", str(out)])
    assert res.exit_code == 3, res.output
    assert "block 'align'" in res.output and "set coarse_time >= 38 s" in res.output
    assert "results recorded" not in res.output and not (out / "results.csv").exists()
    assert "Traceback" not in res.output


# ------------------------------------------------------------- item 5: large inputs
def _chain(n: int) -> tuple[list[str], list[Connection]]:
    names = [f"b{i}" for i in reversed(range(n))]  # declared last first
    links = [Connection(f"b{i}", "y", f"b{i + 1}", "u") for i in range(n - 1)]
    return names, links


def _schedule_reference(names: list[str], connections: list[Connection]) -> list[str]:
    """The stepping order as the quadratic implementation found it (Kahn, re-sorted)."""
    from cosim.master import strongly_connected

    edges: dict[str, set[str]] = {n: set() for n in names}
    for c in connections:
        edges[c.src_block].add(c.dst_block)
    comps = strongly_connected(names, edges)
    comp_of = {n: i for i, comp in enumerate(comps) for n in comp}
    indeg = {i: 0 for i in range(len(comps))}
    succ: dict[int, set[int]] = {i: set() for i in range(len(comps))}
    for a in names:
        for b in edges[a]:
            ca, cb = comp_of[a], comp_of[b]
            if ca != cb and cb not in succ[ca]:
                succ[ca].add(cb)
                indeg[cb] += 1
    ready = [i for i in indeg if indeg[i] == 0]
    order: list[str] = []
    while ready:
        ready.sort(key=lambda i: names.index(comps[i][0]))
        i = ready.pop(0)
        order.extend(comps[i])
        for j in succ[i]:
            indeg[j] -= 1
            if indeg[j] == 0:
                ready.append(j)
    return order


def test_the_stepping_order_is_the_same_as_before_on_random_systems() -> None:
    import random

    rng = random.Random(14)
    for _ in range(200):
        n = rng.randint(1, 25)
        names = [f"n{i}" for i in rng.sample(range(100), n)]
        links = [
            Connection(rng.choice(names), "y", rng.choice(names), f"u{k}")
            for k in range(rng.randint(0, 2 * n))
        ]
        assert schedule(names, links)[0] == _schedule_reference(names, links)


def test_the_stepping_order_of_ten_thousand_blocks_takes_well_under_a_second() -> None:
    names, links = _chain(10_000)
    start = time.perf_counter()
    order, delayed, loops = schedule(names, links)
    assert time.perf_counter() - start < 2.0  # was minutes: the ready list re-sorted by index
    assert order == [f"b{i}" for i in range(10_000)] and not delayed and not loops
    # one big loop, declared first block first: the delayed connection is the one closing it
    names, links = _chain(10_000)
    links.append(Connection("b9999", "y", "b0", "u"))
    start = time.perf_counter()
    order, delayed, loops = schedule(names[::-1], links)
    assert time.perf_counter() - start < 2.0
    assert len(loops) == 1 and len(loops[0]) == 10_000
    assert [str(c) for c in delayed] == ["b9999.y -> b0.u"]


def test_check_of_ten_thousand_blocks_answers_in_seconds(tmp_path: Path) -> None:
    from benchmarks.bench_check import chain_scenario

    path = write(tmp_path, chain_scenario(10_000))
    start = time.perf_counter()
    res = CliRunner().invoke(main, ["check", str(path)])
    elapsed = time.perf_counter() - start
    assert res.exit_code == 0, res.output[-500:]
    assert "10000 blocks, 9999 scalar connections" in res.output
    assert elapsed < 60, elapsed  # about 5 s on a busy 2-core machine


GC_PROBE = '''
import gc

from cosim.models.block import Block, output

SEEN = []


class Probe(Block):
    """Notes whether the garbage collector runs while it is built."""

    variables = (output("y", 0.0),)

    def __init__(self, **kwargs):
        SEEN.append(gc.isenabled())
        super().__init__(**kwargs)


class Broken(Probe):
    """Fails while it is built."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        raise ValueError("broken on purpose")
'''


def generations(*hosts: object) -> set[int]:
    """The garbage collector's generations that hold the hosts and what they refer to."""
    import gc

    ids = {id(o) for h in hosts for o in (h, *vars(h).values()) if gc.is_tracked(o)}
    assert len(ids) > len(hosts)
    return {g for g in range(3) for o in gc.get_objects(generation=g) if id(o) in ids}


def test_the_garbage_collector_pauses_while_blocks_are_built_and_comes_back(
    tmp_path: Path,
) -> None:
    import gc

    from benchmarks.bench_check import chain_scenario

    (tmp_path / "robust_gc_probe.py").write_text(GC_PROBE)
    text = MASTER + '[blocks.a]\nclass = "robust_gc_probe:Probe"\n'
    path = write(tmp_path, text + '[blocks.b]\nclass = "robust_gc_probe:Probe"\n')
    try:
        assert gc.isenabled()
        gc.collect()
        system, _ = load_scenario(path).build()
        probe = sys.modules["robust_gc_probe"]
        assert probe.SEEN == [False, False]  # paused for every block
        assert gc.isenabled()  # and back once they are built
        # a small build is left to the collector: its objects are young
        assert 2 not in generations(system.blocks["a"])
        # a large one goes to the oldest generation, unwalked; nothing stays frozen
        big = write(tmp_path, chain_scenario(600), "big.toml")
        system, _ = load_scenario(big).build()
        assert generations(system.blocks["b0"], system.blocks["b599"]) == {2}
        assert gc.get_freeze_count() == 0
        # back after a block that fails, too
        bad = write(tmp_path, text + '[blocks.b]\nclass = "robust_gc_probe:Broken"\n', "b.toml")
        with pytest.raises(Exception, match="broken on purpose"):
            load_scenario(bad).build()
        assert gc.isenabled() and probe.SEEN == [False] * 4
        # a caller that turned it off keeps it off
        gc.disable()
        try:
            load_scenario(path).build()
            assert not gc.isenabled()
        finally:
            gc.enable()
        # and what a caller froze stays frozen (a pool worker freezes its blocks)
        gc.freeze()
        try:
            frozen = gc.get_freeze_count()
            system, _ = load_scenario(path).build()
            # not thawed (0), nothing of the build frozen (more); objects that died since
            # left the frozen set, as they do
            assert 0 < gc.get_freeze_count() <= frozen and gc.isenabled()
        finally:
            gc.unfreeze()
    finally:
        sys.modules.pop("robust_gc_probe", None)


def test_unit_parsing_is_linear_and_a_long_unit_is_shown_cut() -> None:
    for text in ("x" * 100_000, "deg*" * 25_000, "1 x" + " " * 100_000 + "y"):
        start = time.perf_counter()
        with pytest.raises(UnitError) as info:
            to_unit(f"1 {text}", "rad")
        assert time.perf_counter() - start < 0.5  # was 63 s for 100 kB
        message = str(info.value)
        assert len(message) < 300
        assert "characters)" in message and f"limit of {MAX_UNIT_CHARS}" in message
    # nested square roots in one pass, and the same factors as before
    assert parse_unit("sqrt(sqrt(Hz))").dimension == parse_unit("Hz**0.25").dimension
    assert to_unit("1 deg/sqrt(h)", "rad/sqrt(s)") == pytest.approx(2.908882086657216e-4)
    start = time.perf_counter()
    with pytest.raises(UnitError):
        parse_unit("sqrt(" * 39 + "s" + ")" * 39)  # within the length limit, deeply nested
    assert time.perf_counter() - start < 1.0


@pytest.mark.parametrize(
    ("limit", "value", "text", "expected"),
    [
        (
            "MAX_BLOCKS",
            3,
            MASTER + "".join(f"[blocks.b{i}]\nmodel = 'Ramp'\n" for i in range(4)),
            "4 blocks, more than the limit of 3",
        ),
        (
            "MAX_CONNECTIONS",
            1,
            PAIR.replace('"]', '", "flexure.x -> sensor.u"]'),
            "2 connections, more than the limit of 1",
        ),
        (
            "MAX_STRING_CHARS",
            50,
            "[scenario]\nname = '" + "n" * 51 + "'\n" + MASTER + GAUSS_MARKOV_BLOCK,
            "string '" + "n" * 51 + "' is longer than the limit of 50",
        ),
        (
            "MAX_DEPTH",
            4,
            MASTER
            + GAUSS_MARKOV_BLOCK.replace(
                '"\n', '"\nparameters = { tau = { value = [1], unit = "s" } }\n', 1
            ),
            "nest at least 5 levels deep, more than the limit of 4",
        ),
    ],
)
def test_each_limit_is_refused_with_the_limit_and_the_value(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    limit: str,
    value: int,
    text: str,
    expected: str,
) -> None:
    monkeypatch.setattr(limits, limit, value)
    with pytest.raises(ScenarioError) as info:
        cosim.load_scenario(write(tmp_path, text))
    assert expected in str(info.value)
    assert str(info.value).startswith(str(tmp_path))


def test_a_long_string_is_shown_cut_with_its_length(tmp_path: Path) -> None:
    path = write(
        tmp_path, MASTER + GAUSS_MARKOV_BLOCK + f"[output]\nvariables = ['{'v' * 20_000}']\n"
    )
    line = refused("check", path)
    assert "(20000 characters) is longer than the limit of 10000 characters" in line
    assert len(line) < 400


# ------------------------------------------------------------------ item 6: the traps
def test_an_unknown_key_under_scenario_is_refused_with_a_suggestion(tmp_path: Path) -> None:
    path = write(tmp_path, '[scenario]\nnmae = "demo"\n' + MASTER + GAUSS_MARKOV_BLOCK)
    line = refused("check", path)
    assert "key 'scenario.nmae'" in line and "Did you mean 'name'?" in line


def test_a_parameter_for_a_connected_input_is_refused(tmp_path: Path) -> None:
    text = PAIR.replace(
        'model = "FirstOrderSensor"', 'model = "FirstOrderSensor"\nparameters = { u = 0.1 }'
    )
    line = refused("check", write(tmp_path, text))
    assert "key 'blocks.sensor.parameters.u'" in line
    assert "input 'sensor.u' is connected (flexure.x -> sensor.u)" in line


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_a_non_finite_parameter_is_refused_at_check_naming_it(tmp_path: Path, value: str) -> None:
    text = PAIR.replace(
        'model = "FirstOrderSensor"',
        f'model = "FirstOrderSensor"\nparameters = {{ bias = {value} }}',
    )
    line = refused("check", write(tmp_path, text))
    assert "key 'blocks.sensor.parameters.bias'" in line
    assert f"parameter 'bias' is {float(value)}; expected a finite number" in line


REQUIREMENT = """
[[requirements]]
id = "REQ-1"
signal = "sensor.m"
minus = "flexure.x"
unit = "arcmin"
criterion = "bound"
bound = "{bound}"
{window}
"""


def test_check_checks_the_requirements(tmp_path: Path) -> None:
    ok = write(tmp_path, PAIR + REQUIREMENT.format(bound="1 arcmin", window='from = "0.5 s"'))
    res = CliRunner().invoke(main, ["check", str(ok)])
    assert res.exit_code == 0 and "1 requirement(s)" in res.output, res.output
    bad = write(
        tmp_path,
        PAIR + REQUIREMENT.format(bound="1 arcmin", window="").replace("sensor.m", "sensor.mm"),
    )
    assert "key 'requirements[0].signal'" in refused("check", bad)


def test_a_requirement_window_after_the_stop_time_is_refused_by_check(tmp_path: Path) -> None:
    path = write(tmp_path, PAIR + REQUIREMENT.format(bound="1 arcmin", window='from = "2 s"'))
    line = refused("check", path)
    assert "key 'requirements[0].from'" in line
    assert "'from' = 2 s is after the stop time (1 s)" in line
    path = write(
        tmp_path,
        PAIR
        + REQUIREMENT.format(bound="1 arcmin", window='at = "5 s"').replace('"bound"', '"value"'),
    )
    assert "key 'requirements[0].at'" in refused("check", path)


def test_a_negative_bound_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, PAIR + REQUIREMENT.format(bound="-1 arcmin", window=""))
    line = refused("check", path)
    assert "key 'requirements[0].bound'" in line and "must be >= 0" in line
    # a signed bound (e <= -1 arcmin) is a real requirement
    signed = write(
        tmp_path, PAIR + REQUIREMENT.format(bound="-1 arcmin", window="absolute = false")
    )
    assert CliRunner().invoke(main, ["check", str(signed)]).exit_code == 0


BESIDE = '''
from cosim.models.block import Block, input_, output


class Doubler(Block):
    """y = 2 u."""

    variables = (input_("u", 0.0, "rad"), output("y", 0.0, "rad"))

    def step(self, t, h):
        self.y = 2.0 * self.u
'''


def test_a_class_module_beside_the_scenario_is_found(tmp_path: Path) -> None:
    folder = tmp_path / "project"
    folder.mkdir()
    (folder / "robust_beside_block.py").write_text(BESIDE)
    text = (
        'connections = ["flexure.x -> twice.u"]\n'
        + MASTER
        + '[blocks.flexure]\nmodel = "GaussMarkov2"\n'
        + '[blocks.twice]\nclass = "robust_beside_block:Doubler"\n'
    )
    path = write(folder, text)
    before = list(sys.path)
    try:
        result = cosim.run(path)
        assert list(result["twice.y"][1:]) == list(2.0 * result["flexure.x"][1:])
    finally:
        sys.modules.pop("robust_beside_block", None)
    assert sys.path == before  # the folder was on the path for the lookup only
    # a module that is nowhere gets the message that says where it may be
    line = refused("check", write(folder, text.replace("robust_beside_block", "nowhere_block")))
    assert "a file nowhere_block.py beside the scenario" in line and str(folder) in line
