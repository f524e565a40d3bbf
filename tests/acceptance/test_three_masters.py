"""Issue 16, acceptance 4: one SSP archive, three masters, the same truth outputs.

``ins-cosim export-ssp scenarios/transfer_alignment.toml --exclude align`` (the filter is
a Python block) writes an SSP 1.0 archive that validates against the schemas fmpy ships,
with units. The archive is then run by

- ins-cosim, re-imported (``cosim.interop.ssp_import.load_ssp``), Jacobi coupling;
- libcosim, through its own SSP loader (``run_libcosim_ssp``; libcosim steps Jacobi);
- fmpy, with fmpy's SSP reader and FMU wrapper driven by the Jacobi rule
  (``cosim.interop.fmpy_ssp.run_fmpy_ssp``; why fmpy's ``simulate_ssp`` itself cannot
  be used is shown below),

and every recorded output of every block agrees to 1e-12 over a short horizon, and bit
for bit with the master whose clock ins-cosim uses (issue 30, item 5: libcosim's under
the default ``clock``, fmpy's under ``clock = "fmpy"``). The
re-imported run also equals the original scenario (without the filter) run from the
same FMUs: the round trip loses nothing.
"""

from __future__ import annotations

import copy
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.ssp.ssd import read_ssd

import cosim
from cosim.interop.fmpy_ssp import run_fmpy_ssp
from cosim.interop.libcosim_runner import run_libcosim_ssp
from cosim.interop.ssp_import import load_ssp

ROOT = Path(__file__).resolve().parents[2]
TRANSFER = ROOT / "scenarios" / "transfer_alignment.toml"
STEP, STOP = 0.05, 1.0  # 20 macro steps of the scenario's own 50 ms step
TOL = 1e-12


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory, fmu_dir: Path) -> Path:
    from click.testing import CliRunner

    from cosim.cli import main

    out = tmp_path_factory.mktemp("three") / "transfer.ssp"
    res = CliRunner().invoke(
        main,
        ["export-ssp", str(TRANSFER), str(out), "--fmu-dir", str(fmu_dir), "--exclude", "align"],
    )
    assert res.exit_code == 0, res.output
    assert "left out: block align" in res.output
    return out


@pytest.fixture(scope="module")
def ours(archive: Path) -> cosim.RunResult:
    return cosim.run(load_ssp(archive, stop=STOP, coupling="jacobi"))


def test_the_archive_validates_against_the_ssp_schemas_with_units(archive: Path) -> None:
    ssd = read_ssd(str(archive))  # raises unless SystemStructure.ssd validates (SSP 1.0)
    assert {c.name for c in ssd.system.elements} == {"ship", "flex", "lever", "imu", "master"}
    units = {u.name: u for u in ssd.units}
    assert units["rad/s"].rad == 1 and units["rad/s"].s == -1
    assert units["m/s2"].m == 1 and units["m/s2"].s == -2
    with zipfile.ZipFile(archive) as zf:
        text = zf.read("SystemStructure.ssd").decode()
    assert '<ssd:Connector name="omega_ib_b[1]" kind="output">' in text
    assert text.count('<ssc:Real unit="') > 50  # the connectors carry their units


def test_three_masters_give_the_same_truth_outputs(archive: Path, ours) -> None:
    names = ours.names[1:]
    observe = [tuple(n.split(".", 1)) for n in names]
    assert {n.split(".")[0] for n in names} == {"ship", "flex", "lever", "imu", "master"}
    assert len(ours.data) == round(STOP / STEP) + 1
    libcosim = run_libcosim_ssp(archive, step=STEP, stop=STOP, observe=observe)
    fmpy = run_fmpy_ssp(archive, step=STEP, stop=STOP, observe=observe)
    for other, label in ((libcosim, "libcosim"), (fmpy, "fmpy")):
        assert len(other) == len(ours.data), label
        np.testing.assert_allclose(other["time"], ours.time, rtol=0, atol=1e-15)
        for n in names:
            diff = float(np.max(np.abs(other[n] - ours.data[n])))
            assert diff <= TOL, f"{label} {n}: {diff}"
    # bit for bit under each master's own clock (docs/coupling.md): the default is
    # libcosim's integer clock, clock = "fmpy" is fmpy's t0 + n h; the two differ
    assert all(np.array_equal(libcosim[n], ours.data[n]) for n in ["time", *names])
    sc = load_ssp(archive, stop=STOP, coupling="jacobi")
    sc.settings = sc.master_settings(clock="fmpy")
    as_fmpy = cosim.run(sc)
    assert all(np.array_equal(fmpy[n], as_fmpy.data[n]) for n in ["time", *names])
    assert not np.array_equal(as_fmpy.time, ours.time)
    assert sum(not np.array_equal(as_fmpy[n], ours[n]) for n in names) > 10
    # the outputs move (the comparison is not of constants): the IMU sees the ship's motion
    assert np.ptp(ours["imu.dtheta_meas_b[1]"]) > 1e-4 and np.ptp(ours["lever.v_n_s[3]"]) > 0.1


def test_round_trip_equals_the_original_scenario_without_the_filter(ours, fmu_dir: Path) -> None:
    sc = copy.deepcopy(cosim.load_scenario(TRANSFER))
    del sc.blocks["align"]
    sc.connections = [c for c in sc.connections if "align." not in c]
    sc.outputs = None  # every output, as the import records
    sc.use_fmus(fmu_dir)
    sc.settings = sc.master_settings(stop=STOP, coupling="jacobi", record_every=1)
    original = cosim.run(sc)
    assert original.names == ours.names
    for n in ours.names[1:]:
        diff = float(np.max(np.abs(original[n] - ours[n])))
        assert diff <= TOL, f"{n}: {diff}"
    # and the coupling matters: the scenario's own Gauss-Seidel run differs
    sc.settings = sc.master_settings(coupling="gauss-seidel")
    gs = cosim.run(sc)
    assert np.max(np.abs(gs["imu.dv_meas_b[3]"] - ours["imu.dv_meas_b[3]"])) > 1e-6


def test_fmpy_simulate_ssp_as_shipped_feeds_zero_inputs_first(archive: Path, ours) -> None:
    """Why run_fmpy_ssp drives fmpy's pieces itself: ``simulate_ssp`` agrees on the ship
    (no inputs) but feeds 0.0 to every input in its first step, so the lever arm, whose
    inputs are the ship's motion, starts from nothing."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import ParameterSet

    ssd = read_ssd(str(archive))
    pset = ParameterSet(name="all")
    for comp in ssd.system.elements:
        for binding in comp.parameterBindings:
            for values in binding.parameterValues:
                for p in values.parameters:
                    p.name = f"{comp.name}.{p.name}"
                    pset.parameters.append(p)
    shipped = simulate_ssp(str(archive), stop_time=STOP, step_size=STEP, parameter_set=pset)
    # its row k holds the values at the end of step k + 1 (labelled with the step's start)
    n = round(STOP / STEP)
    ship = float(np.max(np.abs(shipped["ship.rpy[1]"][:n] - ours["ship.rpy[1]"][1 : n + 1])))
    assert ship <= TOL
    lever = np.abs(shipped["lever.v_n_s[3]"][:n] - ours["lever.v_n_s[3]"][1 : n + 1])
    assert float(np.max(lever)) > 1e-3
