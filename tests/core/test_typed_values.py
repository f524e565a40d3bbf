"""Issue 30, item 1 and acceptance 1: typed links between blocks (cosim.typed_values).

C fixtures compiled in the test run, shaped like the Reference-FMUs' Feedthrough:
``stair2`` (FMI 2: a Real ramp, an Integer counter, a Boolean), ``echo2`` (FMI 2: every
FMI 2 type), ``vec3`` (FMI 3: Float64, Float32 and Int32 arrays, an Int8 counter, an
Enumeration and a Boolean that change at every step) and ``echo3`` (FMI 3: every FMI 3
type), ``statespace3`` (FMI 3: a state-space system with array variables). The chain

    stair2 -> echo2 -> vec3 -> echo3 -> echo3,   vec3.z -> statespace3.u  (whole array)

carries Real, Integer, Boolean, Enumeration, String, Float32, Int8, UInt8 and array
links, and the widenings Integer -> Float64, Integer -> Int64, Int8 -> Int16, Int16 ->
Int32, UInt16 -> UInt32, UInt32 -> UInt64, Float32 -> Float64.
It runs under Gauss-Seidel and Jacobi and equals, bit for bit in every recorded column,

- fmpy's FMU wrappers driven by the same coupling rule (``tests/fmpychain.py``, FMI 2
  and 3: the whole chain);
- libcosim (``run_libcosim``; FMI 2 only: libcosim 0.11 loads no FMI 3 FMU, steps
  Jacobi only, observes Real and Integer variables only and skips Enumeration
  variables): the FMI 2 part ``stair2 -> echo2 -> echo2`` with Integer, Boolean, String
  and Real links.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpychain import run_chain

import cosim
from cosim.interop.cbuild import build_c_fmu
from cosim.typed_values import link_refusal
from cosim.variables import Variable

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
STEP, STOP = 0.125, 2.0  # binary fractions: every clock gives the same times


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("typed")
    names = {"stair2": "Steps", "echo2": "Echo", "vec3": "Vec3", "echo3": "Echo3"}
    names["statespace3"] = "StateSpace3"
    return {k: build_c_fmu(FIXTURES / k, out / f"{v}.fmu") for k, v in names.items()}


#: The chain's links (scenario text), scalar by scalar except the whole-array one.
LINKS = [
    "s.counter -> a.u_int",
    "s.odd -> a.u_bool",
    "a.y_real -> v.u[1]",
    "s.counter -> v.u[2]",  # Integer -> Float64
    "a.y_int -> v.u[3]",  # Integer -> Float64
    "a.y_int -> v.n[1]",
    "s.counter -> v.n[2]",
    "v.level -> e.u_enum",  # Enumeration, the same items
    "v.g[1] -> e.u_float32",
    "v.g[2] -> e.u_float64",  # Float32 -> Float64
    "v.count8 -> e.u_int8",
    "v.count8 -> e.u_int16",  # Int8 -> Int16
    "a.y_int -> e.u_int32",  # FMI 2 Integer is Int32
    "a.y_int -> e.u_int64",  # Int32 -> Int64
    "a.y_bool -> e.u_boolean",
    "a.y_str -> e.u_string",
    "v.z -> ss.u",  # whole arrays of shape (2,)
    "e.y_uint8 -> e2.u_uint8",
    "e.y_uint16 -> e2.u_uint32",  # UInt16 -> UInt32
    "e.y_uint32 -> e2.u_uint64",  # UInt32 -> UInt64
    "e.y_int16 -> e2.u_int32",  # Int16 -> Int32
    "e.y_float32 -> e2.u_float32",
]
PARAMETERS = {
    "a": {"u_enum": 2, "p_int": 10, "p_str": "A", "u_real": 0.25},
    "v": {"k": [1.0, 2.0, 3.0], "M": [[1.0, 1.0, 1.0], [0.0, 0.0, 2.0]], "f": [1.0, 3.0]},
    "e": {"p_uint8": 200, "p_uint16": 60000, "p_uint32": 4000000000},
}
BLOCKS = {"s": "stair2", "a": "echo2", "v": "vec3", "e": "echo3", "ss": "statespace3"}
BLOCKS["e2"] = "echo3"


def chain_scenario(tmp_path: Path, fmus: dict[str, Path], coupling: str) -> Path:
    text = f"connections = {LINKS!r}\n[master]\nstep = {STEP}\nstop = {STOP}\n"
    text += f'coupling = "{coupling}"\n'
    for name, fixture in BLOCKS.items():
        text += f'\n[blocks.{name}]\nfmu = "{fmus[fixture]}"\n'
        if name in PARAMETERS:
            inner = ", ".join(f"{k} = {v!r}" for k, v in PARAMETERS[name].items())
            text += f"parameters = {{ {inner} }}\n"
        if name == "a":
            text += "unconnected_ok = ['u_str']\n"
        if name == "e":
            text += "unconnected_ok = ['u_uint8', 'u_uint16', 'u_uint32', 'u_uint64', 'u_binary']\n"
        if name == "e2":
            text += "unconnected_ok = ['u_float64', 'u_int8', 'u_int16', 'u_int64', 'u_uint16',"
            text += " 'u_uint32', 'u_boolean', 'u_string', 'u_binary', 'u_enum']\n"
    path = tmp_path / f"chain_{coupling}.toml"
    path.write_text(text.replace("'", '"'))
    return path


def fmpy_links() -> list[tuple[str, str, str, str]]:
    out = []
    for text in LINKS:
        left, right = (x.strip() for x in text.split("->"))
        (sb, sv), (db, dv) = left.split(".", 1), right.split(".", 1)
        if sv == "z":  # the whole-array link, element by element
            out += [(sb, f"z[{i}]", db, f"u[{i}]") for i in (1, 2)]
        else:
            out.append((sb, sv, db, dv))
    return out


def fmpy_parameters() -> dict[str, dict[str, object]]:
    v = PARAMETERS["v"]
    flat = {f"k[{i + 1}]": x for i, x in enumerate(v["k"])}
    flat.update({f"M[{i // 3 + 1},{i % 3 + 1}]": x for i, x in enumerate(sum(v["M"], []))})
    flat.update({f"f[{i + 1}]": x for i, x in enumerate(v["f"])})
    return {"a": PARAMETERS["a"], "v": flat, "e": PARAMETERS["e"]}


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_the_typed_chain_equals_fmpy_bit_for_bit(
    fmus: dict[str, Path], tmp_path: Path, coupling: str
) -> None:
    ours = cosim.run(chain_scenario(tmp_path, fmus, coupling))
    assert ours.status == "completed"
    types = ours.metadata["types"]
    numeric = [n for n in ours.names[1:] if types[n] not in ("String", "Binary")]
    record = [tuple(n.split(".", 1)) for n in numeric + ["e.y_string"]]
    theirs = run_chain(
        {b: fmus[f] for b, f in BLOCKS.items()},
        fmpy_parameters(),
        fmpy_links(),
        record,
        STEP,
        STOP,
        coupling,
    )
    assert len(ours.data) == round(STOP / STEP) + 1
    for n in numeric:
        assert ours[n].tobytes() == theirs[n].tobytes(), n  # bit for bit
    assert ours.strings["e.y_string"] == list(theirs["e.y_string"])
    # the links carry what they should: the Enumeration cycles, the counter widens
    # (Jacobi initialises e with v.level's start value: none declared, so 0, as for Reals)
    assert set(ours["e.y_enum"][1:]) == {1.0, 2.0, 3.0}
    assert ours["e.y_int16"].max() > 0 and ours["e.y_int64"].max() >= 10 + 2
    assert ours["e2.y_uint8"][-1] == 200 and ours["e2.y_uint32"][-1] == 60000
    assert ours["e2.y_uint64"][-1] == 4000000000 and ours["e2.y_float32"][-1] > 0
    assert {types[n] for n in ("e.y_float32", "v.g[1]", "e.y_int8", "e.y_enum")} == {
        "Float32",
        "Int8",
        "Enumeration",
    }
    gs = coupling == "gauss-seidel"
    # Gauss-Seidel: the Int8 counter reaches echo3 in the same step; Jacobi: one step later
    delay = 0 if gs else 1
    count = ours["v.count8"]
    assert ours["e.y_int8"][delay:].tolist() == count[: len(count) - delay].tolist()


def test_the_fmi2_chain_equals_libcosim_bit_for_bit(fmus: dict[str, Path], tmp_path: Path) -> None:
    """libcosim steps Jacobi and observes Real and Integer variables (Booleans and Strings
    reach ``b`` through ``a`` and show in nothing libcosim can record except through
    ``b``'s Integer and Real outputs, which the Boolean does not change: compared where
    observable)."""
    from cosim.interop.libcosim_runner import run_libcosim

    links = [
        ("s", "counter", "a", "u_int"),
        ("s", "odd", "a", "u_bool"),
        ("a", "y_int", "b", "u_int"),
        ("a", "y_bool", "b", "u_bool"),
        ("a", "y_real", "b", "u_real"),
        ("a", "y_str", "b", "u_str"),
    ]
    text = f"connections = {[f'{a}.{b} -> {c}.{d}' for a, b, c, d in links]!r}\n"
    text += f'[master]\nstep = {STEP}\nstop = {STOP}\ncoupling = "jacobi"\n'
    text += f'[blocks.s]\nfmu = "{fmus["stair2"]}"\n'
    text += f'[blocks.a]\nfmu = "{fmus["echo2"]}"\nparameters = {{ p_int = 10, u_real = 0.25 }}\n'
    text += 'unconnected_ok = ["u_str", "u_enum"]\n'
    text += f'[blocks.b]\nfmu = "{fmus["echo2"]}"\nparameters = {{ p_int = -1 }}\n'
    text += 'unconnected_ok = ["u_enum"]\n'
    path = tmp_path / "fmi2.toml"
    path.write_text(text.replace("'", '"'))
    ours = cosim.run(path)
    observe = [
        ("s", "ramp"),
        ("s", "counter"),
        ("a", "y_int"),
        ("b", "y_int"),
        ("b", "y_real"),
    ]
    theirs = run_libcosim(
        {"s": fmus["stair2"], "a": fmus["echo2"], "b": fmus["echo2"]},
        {"a": {"p_int": 10, "u_real": 0.25}, "b": {"p_int": -1}},
        links,
        STEP,
        STOP,
        observe,
    )
    assert len(theirs) == len(ours.data)
    for b, v in observe:
        name = f"{b}.{v}"
        mine = ours[name]
        assert mine.tobytes() == theirs[name].astype(np.float64).tobytes(), name
    assert ours["b.y_int"].max() == 10 + 2 - 1  # the Integer went s -> a -> b
    assert ours.strings["b.y_str"][-1] == "p/p/u"


@pytest.mark.parametrize(
    ("src", "dst", "allowed"),
    [
        ("Integer", "Integer", True),
        ("Integer", "Int64", True),
        ("Int8", "Int16", True),
        ("UInt16", "Int32", True),
        ("UInt8", "Float32", True),
        ("Integer", "Real", True),
        ("Float32", "Real", True),
        ("Int16", "UInt16", False),  # negative values
        ("Int32", "Int16", False),
        ("Int64", "Real", False),  # beyond 2**53
        ("Int32", "Float32", False),  # beyond 2**24
        ("Real", "Float32", False),
        ("Real", "Integer", False),
        ("Boolean", "Integer", False),
        ("Enumeration", "Integer", False),
        ("Binary", "Binary", False),
    ],
)
def test_fmis_type_rules(src: str, dst: str, allowed: bool) -> None:
    a = Variable("a", 1, src, "output", "discrete")
    b = Variable("b", 2, dst, "input", "discrete")
    assert (link_refusal(a, b) is None) == allowed


def test_enumerations_with_other_items_are_refused() -> None:
    a = Variable("a", 1, "Enumeration", "output", "discrete", items=(("low", 1), ("high", 2)))
    b = Variable("b", 2, "Enumeration", "input", "discrete", items=(("low", 1), ("high", 3)))
    assert "different items (low=1, high=2 and low=1, high=3)" in link_refusal(a, b)
    assert link_refusal(a, a) is None
    reordered = Variable("c", 3, "Enumeration", "input", "discrete", items=a.items[::-1])
    assert link_refusal(a, reordered) is None  # the items, not their order


def test_a_narrowing_link_is_one_line_from_check(cli, fmus: dict[str, Path], tmp_path: Path):
    path = tmp_path / "narrow.toml"
    path.write_text(
        'connections = ["v.c[1] -> e.u_int16"]\n[master]\nstep = 0.5\nstop = 1\n'
        f'[blocks.v]\nfmu = "{fmus["vec3"]}"\n[blocks.e]\nfmu = "{fmus["echo3"]}"\n'
    )
    res = cli("check", path)
    assert res.code == 3 and "Traceback" not in res.err
    line = res.err.strip()
    assert "\n" not in line and "key 'connections[0]'" in line
    assert "'v.c[1]' is an output of type Int32 and 'e.u_int16' an input of type Int16" in line
    assert "Int32 values outside [-32768, 32767] do not fit into Int16" in line


def test_results_csv_writes_integers_and_booleans_as_integers(
    fmus: dict[str, Path], tmp_path: Path
) -> None:
    """Integers, Enumerations and Booleans (0/1) as whole numbers, Float32 values as the
    double they are (17 digits), the types in results.json; loading gives them back."""
    res = cosim.run(chain_scenario(tmp_path, fmus, "gauss-seidel"))
    csv, js = res.save(tmp_path / "out")
    header, first, *_ = csv.read_text().splitlines()
    row = dict(zip(header.split(","), first.split(","), strict=True))
    assert row["v.count8"] == "0" and row["v.flag"] == "0" and row["v.level"] == "1"
    assert row["e.y_string"] == "p/A/u"  # a.y_str at t0 reached e in initialisation
    assert float(row["v.g[1]"]) == float(np.float32(1.0 / 3.0))
    import json

    types = json.loads(js.read_text())["types"]
    assert types["v.flag"] == "Boolean" and types["v.g[1]"] == "Float32"
    again = cosim.RunResult.load(csv)
    for n in ("v.g[1]", "e.y_int64", "v.flag", "ss.y[2]"):
        assert again[n].tobytes() == res[n].tobytes()


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_in_process_blocks_link_integers_and_booleans(tmp_path: Path, coupling: str) -> None:
    """In-process blocks (no FMI layer) exchange Integer and Boolean values by the same
    rule: Gauss-Seidel sees the counter of the same step, Jacobi the one before."""
    path = tmp_path / "inproc.toml"
    path.write_text(
        'connections = ["c.n -> t.m", "c.odd -> t.b"]\n'
        f'[master]\nstep = 0.5\nstop = 3\ncoupling = "{coupling}"\n'
        '[blocks.c]\nclass = "typedblocks:Counter"\n[blocks.t]\nclass = "typedblocks:Tally"\n'
    )
    res = cosim.run(path)
    n = res["c.n"]
    assert n.tolist() == [0, 1, 2, 3, 4, 5, 6]
    seen = n if coupling == "gauss-seidel" else np.concatenate([[0], n[:-1]])
    assert res["t.y"].tolist() == (10 * seen + seen % 2).tolist()
    assert res["t.total"].tolist() == np.concatenate([[0], np.cumsum(seen[1:])]).tolist()
    assert res.metadata["types"]["t.total"] == "Integer"


def test_a_block_without_typed_links_keeps_the_masters_own_functions() -> None:
    """The Float64 path is not wrapped where no typed link is (Real-only scenarios run the
    same per-step code as before typed links existed)."""
    from cosim.typed_values import TypedExchange

    def put(x: object) -> None: ...

    def read() -> None: ...

    exchange = TypedExchange({}, [])
    assert exchange.bind("b", None, put, read, jacobi=True) == (put, read)  # type: ignore[arg-type]
    assert exchange.bind("b", None, None, None, jacobi=False) == (None, None)  # type: ignore[arg-type]
