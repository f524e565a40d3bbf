"""Interoperability: the demo chain's FMUs in libcosim, an independent master.

With Jacobi coupling our master and libcosim must give the same outputs (1e-12). The
libcosim run uses the C library shipped in the libcosimpy wheel (see
cosim/interop/libcosim_runner.py for why it is driven through ctypes and in a child process).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.interop.libcosim_exec import LibcosimError
from cosim.interop.libcosim_runner import run_libcosim
from cosim.scenario import build_master

ROOT = Path(__file__).resolve().parents[2]


def test_demo_chain_matches_libcosim_under_jacobi(fmu_dir: Path) -> None:
    sc = cosim.load_scenario(ROOT / "scenarios" / "demo.toml")
    sc.use_fmus(fmu_dir)
    sc.settings = sc.master_settings(coupling="jacobi", stop=5.0)
    ours = build_master(sc)
    system = ours.system
    try:
        mine = ours.run()
    finally:
        ours.terminate()
    observe = [tuple(name.split(".", 1)) for name in mine.names[1:]]
    theirs = run_libcosim(
        fmus={n: Path(s.source) for n, s in sc.blocks.items()},
        parameters=system.parameters,
        connections=[(c.src_block, c.src_var, c.dst_block, c.dst_var) for c in system.connections],
        step=sc.settings.step,
        stop=sc.settings.stop,
        observe=observe,
    )
    assert len(theirs) == len(mine.data) == 501
    # libcosim counts integer nanoseconds; its times equal ours to an ulp
    np.testing.assert_allclose(theirs["time"], mine.time, rtol=0, atol=1e-12)
    for name in mine.names[1:]:
        diff = np.max(np.abs(theirs[name] - mine.data[name]))
        assert diff <= 1e-12, f"{name}: {diff}"
    # the comparison can fail: under Gauss-Seidel the sensor sees x one step earlier
    sc.settings = sc.master_settings(coupling="gauss-seidel")
    gs = cosim.run(sc)
    assert np.max(np.abs(gs["sensor.y"] - theirs["sensor.y"])) > 1e-9


def test_libcosim_names_the_failing_block(fmu_dir: Path) -> None:
    with pytest.raises(LibcosimError, match="sensor"):
        run_libcosim(
            fmus={"sensor": fmu_dir / "FirstOrderSensor.fmu"},
            parameters={"sensor": {"time_constant": 0.0}},
            connections=[],
            step=0.01,
            stop=0.1,
            observe=[("sensor", "y")],
        )
