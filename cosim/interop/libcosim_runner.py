"""Run FMUs in libcosim (the OSP co-simulation library) as an independent cross-check master.

:func:`run_libcosim` loads each FMU as one libcosim slave, sets the given parameters
as initial values, adds the connections, runs libcosim's fixed-step algorithm and
returns the observed variables at every macro step. It talks to ``libcosimc`` (the C
API shipped inside the ``libcosimpy`` wheel) through ``ctypes``, because the
libcosimpy 0.0.6 wrapper cannot set a start time and loses one sample when reading
a time series. Established with libcosim/libcosimc 0.11.2 (libcosimpy 0.0.6):

Time
    libcosim counts time in integer nanoseconds. ``start``, ``step`` and ``stop`` are
    converted exactly from their shortest decimal form (``0.01`` s -> 10 000 000 ns) and
    must be whole numbers of nanoseconds, with ``stop - start`` a whole number of steps
    (:class:`ValueError` otherwise). Step ``n`` calls ``fmi2DoStep`` with
    ``t_n = (start_ns + n * step_ns) / 1e9`` and a step size of ``t_{n+1} - t_n``
    computed in double precision, so the step size an FMU receives can differ from
    ``step`` in the last bits.

Initialisation
    Parameters are set in the instantiated state and again in initialisation mode.
    libcosim then repeats "set inputs, read outputs, transfer connections" once per
    slave *inside initialisation mode* and calls ``fmi2ExitInitializationMode``. A
    block that computes its outputs only when it leaves initialisation mode (every
    ``models.block.Block``) therefore publishes its *start value* to its sinks during
    initialisation: a sink's ``initialize()`` sees the source's start value, not its
    t0 value.

Coupling (Jacobi)
    In each macro step every slave steps (in parallel) with the inputs it was given
    before the step; afterwards every connection copies the source's new output to the
    sink. A sink stepping from ``t_n`` therefore sees its source's output at ``t_n``
    (one macro step of delay on every connection, order irrelevant), and the first
    step sees the outputs after ``fmi2ExitInitializationMode``.

Recording
    A time-series observer records a sample after initialisation (step 0, at
    ``start``) and after every macro step. The returned array has ``n_steps + 1`` rows
    at ``time = (start_ns + k * step_ns) / 1e9``, ``k = 0 .. n_steps``: row 0 holds the
    values after initialisation at t0, row ``k`` the values at the end of step ``k``.
    Real variables are ``float64`` fields, Integer variables ``int32``; Boolean and
    String variables cannot be observed (libcosim's time-series observer records Real
    and Integer only).

Threads and processes
    The fixed-step algorithm calls the FMUs from a worker thread pool
    (``hardware_concurrency - 1`` threads; the C API does not expose the count).
    pythonfmu FMUs take the GIL in each FMI call and ctypes releases it while libcosim
    runs, so they load and step inside a Python process without deadlock. An FMU error
    in ``fmi2DoStep`` comes back as an error (:class:`LibcosimError` naming the block
    and the time). Two failures are not survivable in-process, so each run happens in
    a fresh child Python process (about one second of overhead):

    - an FMU error *during initialisation* escapes libcosim's worker thread and
      ``std::terminate`` aborts the process; the runner turns the abort into a
      :class:`LibcosimError` and names the block by initialising each block alone;
    - after a failed step, freeing the execution can segfault in pythonfmu 0.7's
      ``fmi2Terminate``; the child leaves a failed execution alone and just exits.

    The child imports nothing from ``cosim``, so each pythonfmu FMU runs the ``models``
    code packed in its resources (not this source tree's), and libcosim unpacks the
    FMUs into the child's private temporary directory, removed even after a crash.
    libcosim 0.11 loads FMI 1.0 and 2.0 co-simulation FMUs (not FMI 3.0).

SSP archives
    :func:`run_libcosim_ssp` runs an ``.ssp`` archive (``ins-cosim export-ssp``) through
    libcosim's own SSP loader (``cosim_ssp_fixed_step_execution_create``): libcosim
    reads the components, the connections (with their linear transformations) and the
    parameter values from ``SystemStructure.ssd`` itself; only the step, the start time
    and what to observe come from the caller. Variables are named as in the FMUs.
    Everything else (initialisation, Jacobi coupling, recording) is as above. libcosim's
    loader only *warns* about a parameter value it cannot apply (SSP allows ignoring
    them); the runner turns that warning into a :class:`LibcosimError`, so a misnamed
    parameter cannot pass unnoticed.
"""

from __future__ import annotations

import json
import numbers
import os
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any

import numpy as np

from cosim.interop import libcosim_exec
from cosim.interop.libcosim_exec import EXIT_REFUSED, LibcosimError

__all__ = ["run_libcosim", "run_libcosim_ssp"]

#: What libcosim's SSP loader logs when it skips a parameter value it cannot apply.
_IGNORED_PARAMETER = "SSP parameter set"


def run_libcosim(
    fmus: Mapping[str, Path | str],
    parameters: Mapping[str, Mapping[str, float | int | bool]],
    connections: Sequence[tuple[str, str, str, str]],
    step: float,
    stop: float,
    observe: Sequence[tuple[str, str]],
    start: float = 0.0,
) -> np.ndarray:
    """Run FMUs in libcosim's fixed-step (Jacobi) algorithm and record variables at every step.

    Parameters
    ----------
    fmus : mapping of str to Path
        FMU file of each block; the key is the libcosim instance name.
    parameters : mapping
        ``{block: {variable: value}}`` set before initialisation (parameters or inputs).
        Each value is converted to the variable's FMI type: an Integer variable (such as
        ``seed``) gets an ``int`` (``7`` or ``7.0``; ``7.5`` is refused), a Boolean a
        ``bool``.
    connections : sequence of (str, str, str, str)
        ``(source block, source variable, sink block, sink variable)``, output to input
        of the same type.
    step : float
        Macro step [s], a whole number of nanoseconds.
    stop : float
        Stop time [s]; ``stop - start`` must be a whole number of steps.
    observe : sequence of (str, str)
        ``(block, variable)`` pairs to record (Real or Integer variables).
    start : float, optional
        Start time [s], default 0.

    Returns
    -------
    numpy.ndarray
        Structured array of ``n_steps + 1`` rows: field ``time`` [s] first, then one
        field ``"block.variable"`` per observed variable, in the order of ``observe``.
        Row 0 holds the values after initialisation at ``start``; row ``k`` the values at
        the end of macro step ``k``, ``time = (start_ns + k * step_ns) / 1e9``.

    Raises
    ------
    ValueError
        The time grid is not representable in libcosim's nanosecond time, or an observed
        variable is listed twice.
    LibcosimError
        An unknown block or variable, a value of the wrong type, a connection or value
        libcosim refuses, or an FMU failure during the run (the message names the block
        and variable, and the time for failures during a step).
    RuntimeError
        The child process running libcosim failed for another reason (its stderr is in
        the message).
    """
    start_ns, step_ns, n_steps = _grid(start, step, stop)
    pairs = _observed(observe)
    spec = {
        "fmus": {},
        "parameters": {},
        "connections": [[str(x) for x in c] for c in connections],
        "observe": [list(p) for p in pairs],
        "start_ns": start_ns,
        "step_ns": step_ns,
        "n_steps": n_steps,
    }
    for name, path in fmus.items():
        if not isinstance(name, str) or not name:
            raise LibcosimError(f"block names must be non-empty strings, got {name!r}")
        fmu = Path(path)
        if not fmu.is_file():
            raise LibcosimError(f"FMU file not found: {fmu}", block=name)
        spec["fmus"][name] = str(fmu.resolve())
    for block, values in parameters.items():
        spec["parameters"][str(block)] = {
            str(var): _plain(value, str(block), str(var)) for var, value in values.items()
        }
    return _run_isolated(spec)


def run_libcosim_ssp(
    ssp_path: Path | str,
    step: float,
    stop: float,
    observe: Sequence[tuple[str, str]],
    start: float = 0.0,
) -> np.ndarray:
    """Run an SSP archive in libcosim's fixed-step (Jacobi) algorithm.

    Parameters
    ----------
    ssp_path : Path or str
        The ``.ssp`` archive (``SystemStructure.ssd`` and ``resources/*.fmu``).
    step : float
        Macro step [s], a whole number of nanoseconds (overrides the archive's).
    stop : float
        Stop time [s]; ``stop - start`` must be a whole number of steps.
    observe : sequence of (str, str)
        ``(component, variable)`` pairs to record, with the FMU's variable names.
    start : float, optional
        Start time [s], default 0 (overrides the archive's).

    Returns
    -------
    numpy.ndarray
        As :func:`run_libcosim`: ``n_steps + 1`` rows, ``time`` then one field
        ``"component.variable"`` per observed variable.

    Raises
    ------
    ValueError
        A time grid libcosim cannot represent, or a variable observed twice.
    LibcosimError
        libcosim cannot load the archive, ignores one of its parameter values, or an FMU
        fails during the run.
    RuntimeError
        The child process failed for another reason.
    """
    path = Path(ssp_path)
    if not path.is_file():
        raise LibcosimError(f"SSP archive not found: {path}")
    start_ns, step_ns, n_steps = _grid(start, step, stop)
    spec = {
        "ssp": str(path.resolve()),
        "observe": [list(p) for p in _observed(observe)],
        "start_ns": start_ns,
        "step_ns": step_ns,
        "n_steps": n_steps,
    }
    return _run_isolated(spec)


# --------------------------------------------------------------------------- helpers
def _grid(start: float, step: float, stop: float) -> tuple[int, int, int]:
    """``(start_ns, step_ns, n_steps)`` of a time grid, or ValueError."""
    start_ns = _to_ns(start, "start")
    step_ns = _to_ns(step, "step")
    stop_ns = _to_ns(stop, "stop")
    if step_ns <= 0:
        raise ValueError(f"step must be positive, got {step!r} s")
    if stop_ns <= start_ns:
        raise ValueError(f"stop ({stop!r} s) must be after start ({start!r} s)")
    n_steps, rest = divmod(stop_ns - start_ns, step_ns)
    if rest:
        raise ValueError(
            f"stop - start = {(stop_ns - start_ns) / 1e9!r} s is not a whole number of "
            f"steps of {step!r} s"
        )
    return start_ns, step_ns, n_steps


def _observed(observe: Sequence[tuple[str, str]]) -> list[tuple[str, str]]:
    """The observed pairs as strings, or ValueError for a pair listed twice."""
    pairs = [(str(b), str(v)) for b, v in observe]
    seen: set[tuple[str, str]] = set()
    for pair in pairs:
        if pair in seen:
            raise ValueError(f"'{pair[0]}.{pair[1]}' is observed twice")
        seen.add(pair)
    return pairs


def _to_ns(seconds: float, what: str) -> int:
    """Exact integer nanoseconds of a time given in seconds (its shortest decimal form)."""
    try:
        exact = Decimal(repr(float(seconds))) * 1_000_000_000
    except (TypeError, ValueError, InvalidOperation) as exc:
        raise ValueError(f"{what} must be a finite number of seconds, got {seconds!r}") from exc
    if not exact.is_finite() or exact != exact.to_integral_value():
        raise ValueError(
            f"{what} = {seconds!r} s is not a whole number of nanoseconds "
            "(libcosim's time resolution)"
        )
    return int(exact)


def _plain(value: Any, block: str, var: str) -> bool | int | float | str:
    """A parameter value as a plain JSON-able Python scalar (numpy scalars unwrapped)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    if isinstance(value, str):
        return value
    raise LibcosimError(
        f"unsupported value {value!r} of type {type(value).__name__}", block=block, variable=var
    )


# ------------------------------------------------------------------ child process
# The child loads libcosim_exec.py as a stand-alone module (it imports nothing from ``cosim``),
# from a neutral working directory, so that each pythonfmu FMU imports the ``models``
# package packed in its own resources rather than the one of this source tree.
_CHILD_CODE = (
    "import importlib.util, sys; "
    "spec = importlib.util.spec_from_file_location('ins_cosim_libcosim_child', sys.argv[1]); "
    "module = importlib.util.module_from_spec(spec); sys.modules[spec.name] = module; "
    "spec.loader.exec_module(module); module.child_main(sys.argv[2])"
)


def _run_isolated(spec: dict[str, Any]) -> np.ndarray:
    """Run :func:`cosim.interop.libcosim_exec.simulate` in a child process; raise its failures."""
    outcome, payload, stderr = _run_child(spec)
    if outcome == "ok":
        ignored = [line.strip() for line in stderr.splitlines() if _IGNORED_PARAMETER in line]
        if "ssp" in spec and ignored:
            raise LibcosimError(
                f"libcosim ignored parameter value(s) of the SSP archive: {' | '.join(ignored)}"
            )
        if stderr.strip():
            sys.stderr.write(stderr)
        return payload
    if outcome == "refused":
        raise LibcosimError(**payload)
    if outcome == "failed":
        raise RuntimeError(f"the libcosim child process failed ({payload}): {_summary(stderr)}")
    if "ssp" in spec:
        block = None
    elif len(spec["fmus"]) > 1:
        block = _culprit(spec)
    else:
        block = next(iter(spec["fmus"]), None)
    raise LibcosimError(
        f"libcosim aborted the process ({payload}), which it does when an FMU fails during "
        f"initialisation: {_summary(stderr)}",
        block=block,
    )


def _run_child(spec: dict[str, Any]) -> tuple[str, Any, str]:
    """Run one spec in a child process.

    Returns
    -------
    tuple
        ``(outcome, payload, stderr)``: ``("ok", data, ...)``, ``("refused", error
        arguments, ...)``, ``("aborted", signal, ...)`` or ``("failed", exit code, ...)``.
        For an SSP run that succeeded, the last item is the child's stdout (where
        libcosim logs its warnings) followed by its stderr.
    """
    with tempfile.TemporaryDirectory(prefix="ins_cosim_libcosim_") as tmp:
        work = Path(tmp)
        (work / "spec.json").write_text(json.dumps(spec))
        # libcosim unpacks the FMUs under the temporary directory: removed with `work`,
        # even when the child dies.
        env = dict(os.environ, TMPDIR=tmp, TMP=tmp, TEMP=tmp)
        proc = subprocess.run(
            [sys.executable, "-c", _CHILD_CODE, str(Path(libcosim_exec.__file__).resolve()), tmp],
            env=env,
            cwd=tmp,
            capture_output=True,
            text=True,
            errors="replace",
            check=False,
        )
        if (work / "result.npy").is_file():
            # libcosim's console log (its warnings) goes to stdout: the SSP loader's
            # skipped parameter values are only visible there
            log = proc.stdout + proc.stderr if "ssp" in spec else proc.stderr
            return "ok", np.load(work / "result.npy", allow_pickle=False), log
        if proc.returncode == EXIT_REFUSED and (work / "error.json").is_file():
            return "refused", json.loads((work / "error.json").read_text()), proc.stderr
    if proc.returncode < 0:
        return "aborted", f"signal {-proc.returncode}", proc.stderr
    return "failed", f"exit code {proc.returncode}", proc.stderr


def _summary(stderr: str) -> str:
    """The useful lines of a failed child's stderr (the C++ exception, else the tail)."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    for i, line in enumerate(lines):
        if line.startswith("what():"):
            return " ".join([line[len("what():") :].strip(), *lines[i + 1 : i + 4]])
    return " | ".join(lines[-5:]) if lines else "no output"


def _culprit(spec: dict[str, Any]) -> str | None:
    """The first block whose initialisation alone (with its parameters) crashes libcosim."""
    for name, path in spec["fmus"].items():
        alone = {
            **spec,
            "fmus": {name: path},
            "parameters": {name: spec["parameters"].get(name, {})},
            "connections": [],
            "observe": [],
            "n_steps": 1,
        }
        if _run_child(alone)[0] == "aborted":
            return name
    return None
