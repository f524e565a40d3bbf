"""The master's clock (issue 30, item 5, acceptance 6): correctly rounded step ends.

Under the default rule every time handed to a block is the double nearest the exact
``t0 + n h`` (checked here with :mod:`fractions` against both neighbouring doubles, an
independent definition of "nearest"); ``clock = "fmpy"`` reproduces fmpy's
``t0 + n * h``. The issue's first difference from libcosim: with h = 0.1 ms, step 3
ends at 0.00030000000000000003 s under fmpy's rule and at 0.0003 s under libcosim's.
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from clockblocks import TimeProbe

import cosim
from cosim.clock import Clock, exact_value
from cosim.errors import ScenarioError
from cosim.units import to_unit

#: The steps of acceptance 6, as a user writes them, and the exact step each stands for.
STEPS = [
    ("0.1 ms", Fraction(1, 10_000)),
    ("1 ms", Fraction(1, 1000)),
    ("0.01 s", Fraction(1, 100)),
    ("50 ms", Fraction(1, 20)),
    (1 / 3, Fraction(1, 3)),
]


def wrong_steps(
    step: object, exact: Fraction, ns: range, t0: float = 0.0, rule: str = "exact"
) -> list[int]:
    """The steps ``n`` whose clock time is not the double nearest ``t0 + n * exact``.

    The exact time is ``(A + n P) / Q`` with integers from :mod:`fractions`; a double
    ``x`` is the nearest when the exact time lies between the midpoints to its two
    neighbouring doubles (ties: either), checked in integer arithmetic.
    """
    h = to_unit(step, "s") if isinstance(step, str) else float(step)
    clock = Clock(t0, h, rule)
    start = exact_value(t0)
    q = math.lcm(start.denominator, exact.denominator)
    a, p = int(start * q), int(exact * q)
    wrong = []
    for n in ns:
        x = clock(n)
        if x == 0.0:
            if a + n * p != 0:
                wrong.append(n)
            continue
        (ml, dl), (mx, dx), (mh, dh) = (
            v.as_integer_ratio()
            for v in (math.nextafter(x, -math.inf), x, math.nextafter(x, math.inf))
        )
        d = max(dl, dx, dh)  # powers of two
        lo, mid, hi = ml * (d // dl), mx * (d // dx), mh * (d // dh)
        twice = 2 * (a + n * p) * d
        if not (lo + mid) * q <= twice <= (mid + hi) * q:
            wrong.append(n)
    return wrong


def test_the_step_the_user_meant() -> None:
    for step, exact in STEPS:
        h = to_unit(step, "s") if isinstance(step, str) else step
        assert exact_value(h) == exact, step
    assert to_unit("100 us", "s") != 1e-4  # a unit conversion one ulp off ...
    assert exact_value(to_unit("100 us", "s")) == Fraction(1, 10_000)  # ... read as meant
    assert exact_value(2.5) == Fraction(5, 2) and exact_value(0.0) == 0
    odd = 0.1234567890123456789  # no short decimal, no small denominator: the double
    assert exact_value(odd) == Fraction(odd)


@pytest.mark.parametrize(("step", "exact"), STEPS, ids=[str(s) for s, _ in STEPS])
def test_every_time_is_the_correctly_rounded_exact_time(step: object, exact: Fraction) -> None:
    """The first 10 000 steps and the last 10 000 up to step 10^6 (the slow test below
    checks all 10^6), from t0 = 0 and from t0 = 0.1 s."""
    assert wrong_steps(step, exact, range(10_000)) == []
    assert wrong_steps(step, exact, range(990_000, 1_000_001)) == []
    assert wrong_steps(step, exact, range(2_000), t0=0.1) == []
    # the check can fail: fmpy's rule is off by one ulp at some of these steps
    assert wrong_steps(step, exact, range(10_000), rule="fmpy") != []


@pytest.mark.slow
@pytest.mark.parametrize(("step", "exact"), STEPS, ids=[str(s) for s, _ in STEPS])
def test_every_time_over_a_million_steps(step: object, exact: Fraction) -> None:
    """Acceptance 6 of issue 30, in full: every step n = 0 .. 10^6."""
    assert wrong_steps(step, exact, range(1_000_001)) == []


def test_the_fmpy_rule_is_fmpys() -> None:
    h = 1e-4
    fmpy, ours = Clock(0.0, h, "fmpy"), Clock(0.0, h)
    assert fmpy(3) == 3 * h == 0.00030000000000000003  # the first difference
    assert ours(3) == 0.0003
    late = Clock(0.25, 0.01, "fmpy")
    assert all(late(n) == 0.25 + n * 0.01 for n in range(10_000))
    # the two differ often, by one ulp: the exact rule is not fmpy's rounded differently
    differ = [n for n in range(1000) if fmpy(n) != ours(n)]
    assert differ and all(abs(fmpy(n) - ours(n)) <= math.ulp(ours(n)) for n in differ)


def scenario(tmp_path: Path, step: str, clock: str | None = None, n: int = 3000) -> Path:
    setting = f'clock = "{clock}"\n' if clock else ""
    h = exact_value(to_unit(step, "s"))
    path = tmp_path / "probe.toml"
    path.write_text(
        f'[master]\nstep = "{step}"\nstop = {float(n * h)!r}\n{setting}\n'
        '[blocks.probe]\nclass = "clockblocks:TimeProbe"\n\n'
        '[blocks.slow]\nclass = "clockblocks:TimeProbe"\nrate = 3\n'
    )
    return path


@pytest.mark.parametrize(("step", "exact"), STEPS[:4], ids=[s for s, _ in STEPS[:4]])
def test_the_master_hands_the_blocks_the_clock_times(
    tmp_path: Path, step: str, exact: Fraction
) -> None:
    """End to end: every (t, h) a block of rate 1 and one of rate 3 were given, and the
    recorded time column, under both rules."""
    n = 3000
    for clock in (None, "fmpy"):
        TimeProbe.SEEN.clear()
        result = cosim.run(scenario(tmp_path, step, clock, n))
        assert result.metadata["master"]["clock"] == (clock or "exact")
        h = to_unit(step, "s")
        if clock is None:
            times = [float(k * exact) for k in range(n + 1)]
        else:
            times = [0.0 + k * h for k in range(n + 1)]
        assert list(result.time) == times
        seen = TimeProbe.SEEN
        # order per macro step: probe, then slow every third step (in file order)
        expected = []
        for k in range(n):
            expected.append((times[k], times[k + 1] - times[k]))
            if (k + 1) % 3 == 0:
                expected.append((times[k - 2], times[k + 1] - times[k - 2]))
        assert seen == expected


def test_a_bad_clock_is_refused(tmp_path: Path) -> None:
    path = scenario(tmp_path, "10 ms", "libcosim", n=10)
    with pytest.raises(ScenarioError, match=r"master.clock.*expected one of 'exact', 'fmpy'"):
        cosim.run(path)


def test_an_ssp_of_a_time_sensitive_c_fmu_is_bit_for_bit_with_each_masters_clock(
    tmp_path: Path, cli
) -> None:
    """Acceptance 6 of issue 30, the SSP part: two instances of the C fixture
    ``tests/fixtures/clocked2`` (y = sin(omega (t + h)); x' = lambda x + u, Euler with the
    handed h) at 0.1 ms steps, written by ``export-ssp``, equal libcosim's run of the
    archive bit for bit under the default clock and fmpy's (fmpy's reader and FMU wrapper
    with fmpy's time rule) under ``clock = "fmpy"``; the two clocks give different
    numbers."""
    from cosim.interop.cbuild import build_c_fmu
    from cosim.interop.fmpy_ssp import run_fmpy_ssp
    from cosim.interop.libcosim_runner import run_libcosim_ssp
    from cosim.interop.ssp_import import load_ssp

    fmu = build_c_fmu(Path(__file__).parents[1] / "fixtures" / "clocked2", tmp_path / "Clocked.fmu")
    toml = tmp_path / "clocked.toml"
    toml.write_text(
        'connections = ["a.y -> b.u"]\n\n'
        '[master]\nstep = "0.1 ms"\nstop = "0.1 s"\ncoupling = "jacobi"\n\n'
        f'[blocks.a]\nfmu = "{fmu}"\nparameters = {{ omega = 50.0 }}\nunconnected_ok = ["u"]\n\n'
        f'[blocks.b]\nfmu = "{fmu}"\nparameters = {{ lambda = 20.0 }}\n'
    )
    archive = tmp_path / "clocked.ssp"
    res = cli("export-ssp", toml, archive)
    assert res.code == 0, res.err
    runs = {}
    for clock in ("exact", "fmpy"):
        sc = load_ssp(archive)
        sc.settings = sc.master_settings(clock=clock)
        runs[clock] = cosim.run(sc)
    names = runs["exact"].names
    assert len(runs["exact"].data) == 1001
    observe = [tuple(n.split(".", 1)) for n in names[1:]]
    libcosim = run_libcosim_ssp(archive, step=1e-4, stop=0.1, observe=observe)
    fmpy = run_fmpy_ssp(archive, step=1e-4, stop=0.1, observe=observe)
    for n in names:
        assert np.array_equal(libcosim[n], runs["exact"][n]), n
        assert np.array_equal(fmpy[n], runs["fmpy"][n]), n
    differ = [n for n in names if not np.array_equal(runs["exact"][n], runs["fmpy"][n])]
    assert {"time", "a.y", "b.x"} <= set(differ)
