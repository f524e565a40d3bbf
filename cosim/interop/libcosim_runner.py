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

import ctypes
import json
import numbers
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["LibcosimError", "run_libcosim", "run_libcosim_ssp"]

#: Macro steps run per call into libcosim; the observer buffers one chunk.
_CHUNK = 10_000
#: Minimum severity libcosim prints (0 trace .. 5 fatal): warnings and errors.
_LOG_WARNING = 3
#: What libcosim's SSP loader logs when it skips a parameter value it cannot apply.
_IGNORED_PARAMETER = "SSP parameter set"
#: Exit code of the child process when libcosim refused something.
_EXIT_REFUSED = 3
_INT32 = (-(2**31), 2**31 - 1)

# libcosimc enumerations (cosim.h).
_REAL, _INTEGER, _STRING, _BOOLEAN = 0, 1, 2, 3
_TYPE_NAMES = {_REAL: "Real", _INTEGER: "Integer", _STRING: "String", _BOOLEAN: "Boolean"}
_CAUSALITY_NAMES = {
    0: "input",
    1: "parameter",
    2: "output",
    3: "calculatedParameter",
    4: "local",
    5: "independent",
}
_SETTABLE = {"parameter", "input"}


class LibcosimError(RuntimeError):
    """libcosim refused the configuration, or an FMU failed during the run.

    Parameters
    ----------
    reason : str
        What happened (libcosim's own message when it has one).
    block : str, optional
        The block (libcosim instance) concerned.
    variable : str, optional
        The variable concerned.
    time : float, optional
        Start of the macro step that failed [s].

    Attributes
    ----------
    reason, block, variable, time
        As given.
    """

    def __init__(
        self,
        reason: str,
        block: str | None = None,
        variable: str | None = None,
        time: float | None = None,
    ) -> None:
        self.reason = reason
        self.block = block
        self.variable = variable
        self.time = time
        where = []
        if block is not None:
            where.append(f"block '{block}'")
        if variable is not None:
            where.append(f"variable '{variable}'")
        if time is not None:
            where.append(f"t = {time:.9g} s")
        context = f"libcosim ({', '.join(where)})" if where else "libcosim"
        super().__init__(f"{context}: {reason}")

    def to_json(self) -> dict[str, Any]:
        """The constructor arguments, for passing the error between processes."""
        return {
            "reason": self.reason,
            "block": self.block,
            "variable": self.variable,
            "time": self.time,
        }


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


def _fmi_value(kind: int, value: Any, block: str, var: str) -> bool | int | float | bytes:
    """Convert a parameter value to the FMI type of its variable, or refuse it."""

    def refuse(why: str) -> LibcosimError:
        return LibcosimError(
            f"{_TYPE_NAMES[kind]} variable cannot take {value!r}: {why}", block=block, variable=var
        )

    if kind == _REAL:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise refuse("a number is needed")
        return float(value)
    if kind == _INTEGER:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise refuse("an integer is needed")
        if isinstance(value, float) and not value.is_integer():
            raise refuse("not an integral value")
        number = int(value)
        if not _INT32[0] <= number <= _INT32[1]:
            raise refuse("outside the 32-bit range of an FMI Integer")
        return number
    if kind == _BOOLEAN:
        if isinstance(value, bool):
            return value
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        raise refuse("true/false (or 0/1) is needed")
    if not isinstance(value, str):
        raise refuse("a string is needed")
    return value.encode()


# ------------------------------------------------------------------ libcosimc binding
class _VariableDescription(ctypes.Structure):
    _fields_ = [
        ("name", ctypes.c_char * 1024),
        ("reference", ctypes.c_uint32),
        ("type", ctypes.c_int),
        ("causality", ctypes.c_int),
        ("variability", ctypes.c_int),
    ]


class _SlaveInfo(ctypes.Structure):
    _fields_ = [("name", ctypes.c_char * 1024), ("index", ctypes.c_int)]


class _ExecutionStatus(ctypes.Structure):
    _fields_ = [
        ("current_time", ctypes.c_int64),
        ("state", ctypes.c_int),
        ("error_code", ctypes.c_int),
        ("total_average_real_time_factor", ctypes.c_double),
        ("rolling_average_real_time_factor", ctypes.c_double),
        ("real_time_factor_target", ctypes.c_double),
        ("is_real_time_simulation", ctypes.c_int),
        ("steps_to_monitor", ctypes.c_int),
    ]


def _prototypes() -> dict[str, tuple[Any, list[Any]]]:
    ptr, i32, u32, i64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_uint32, ctypes.c_int64
    connect = (i32, [ptr, i32, u32, i32, u32])
    return {
        "cosim_last_error_message": (ctypes.c_char_p, []),
        "cosim_log_set_output_level": (None, [i32]),
        "cosim_fixed_step_algorithm_create": (ptr, [i64]),
        "cosim_algorithm_destroy": (i32, [ptr]),
        "cosim_execution_create_with_algorithm": (ptr, [i64, ptr]),
        "cosim_execution_destroy": (i32, [ptr]),
        "cosim_execution_get_status": (i32, [ptr, ctypes.POINTER(_ExecutionStatus)]),
        "cosim_local_slave_create": (ptr, [ctypes.c_char_p, ctypes.c_char_p]),
        "cosim_local_slave_destroy": (i32, [ptr]),
        "cosim_execution_add_slave": (i32, [ptr, ptr]),
        "cosim_slave_get_num_variables": (i32, [ptr, i32]),
        "cosim_slave_get_variables": (
            i32,
            [ptr, i32, ctypes.POINTER(_VariableDescription), ctypes.c_size_t],
        ),
        "cosim_execution_set_real_initial_value": (i32, [ptr, i32, u32, ctypes.c_double]),
        "cosim_execution_set_integer_initial_value": (i32, [ptr, i32, u32, i32]),
        "cosim_execution_set_boolean_initial_value": (i32, [ptr, i32, u32, ctypes.c_bool]),
        "cosim_execution_set_string_initial_value": (i32, [ptr, i32, u32, ctypes.c_char_p]),
        "cosim_execution_connect_real_variables": connect,
        "cosim_execution_connect_integer_variables": connect,
        "cosim_execution_connect_boolean_variables": connect,
        "cosim_execution_connect_string_variables": connect,
        "cosim_buffered_time_series_observer_create": (ptr, [ctypes.c_size_t]),
        "cosim_observer_destroy": (i32, [ptr]),
        "cosim_execution_add_observer": (i32, [ptr, ptr]),
        "cosim_observer_start_observing": (i32, [ptr, i32, i32, u32]),
        "cosim_observer_slave_get_real_samples": (
            i64,
            [ptr, i32, u32, i64, ctypes.c_size_t, ptr, ptr, ptr],
        ),
        "cosim_observer_slave_get_integer_samples": (
            i64,
            [ptr, i32, u32, i64, ctypes.c_size_t, ptr, ptr, ptr],
        ),
        "cosim_execution_step": (i32, [ptr, ctypes.c_size_t]),
        "cosim_ssp_fixed_step_execution_create": (
            ptr,
            [ctypes.c_char_p, ctypes.c_bool, i64, i64],
        ),
        "cosim_execution_get_num_slaves": (i32, [ptr]),
        "cosim_execution_get_slave_infos": (
            i32,
            [ptr, ctypes.POINTER(_SlaveInfo), ctypes.c_size_t],
        ),
    }


_LIBRARY: ctypes.CDLL | None = None


def _library() -> ctypes.CDLL:
    """libcosimc from the libcosimpy wheel, with our own prototypes (libcosimpy's untouched)."""
    global _LIBRARY
    if _LIBRARY is None:
        try:
            import libcosimpy
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError(
                "run_libcosim needs libcosimpy (pip install 'ins-cosim[test]')"
            ) from exc
        folder = Path(libcosimpy.__file__).resolve().parent / "libcosimc"
        name = "cosimc.dll" if os.name == "nt" else "libcosimc.so"
        lib = ctypes.CDLL(str(folder / name))
        for func, (restype, argtypes) in _prototypes().items():
            getattr(lib, func).restype = restype
            getattr(lib, func).argtypes = argtypes
        _LIBRARY = lib
    return _LIBRARY


def _last_error(lib: ctypes.CDLL) -> str:
    message = lib.cosim_last_error_message()
    return message.decode(errors="replace").strip() if message else "no message from libcosim"


# ------------------------------------------------------------------------ the run
def _simulate(spec: dict[str, Any]) -> np.ndarray:
    """Build the libcosim execution described by ``spec``, run it, return the samples.

    Runs in the child process. ``spec`` holds either ``fmus``, ``parameters`` and
    ``connections`` (built here) or ``ssp`` (an archive libcosim loads itself). After a
    failed step the execution is left alone (the child exits): freeing pythonfmu
    instances after an FMU error can crash.
    """
    lib = _library()
    lib.cosim_log_set_output_level(_LOG_WARNING)
    start_ns, step_ns = spec["start_ns"], spec["step_ns"]
    if "ssp" in spec:
        execution = lib.cosim_ssp_fixed_step_execution_create(
            spec["ssp"].encode(), True, start_ns, step_ns
        )
        if not execution:
            raise LibcosimError(f"cannot load the SSP archive {spec['ssp']}: {_last_error(lib)}")
    else:
        algorithm = lib.cosim_fixed_step_algorithm_create(step_ns)
        if not algorithm:
            raise LibcosimError(f"cannot create the fixed-step algorithm: {_last_error(lib)}")
        execution = lib.cosim_execution_create_with_algorithm(start_ns, algorithm)
        lib.cosim_algorithm_destroy(algorithm)  # the execution holds its own reference
        if not execution:
            raise LibcosimError(f"cannot create the execution: {_last_error(lib)}")
    run = _Run()
    try:
        if "ssp" in spec:
            index, variables = _ssp_slaves(lib, execution)
        else:
            index, variables = _add_slaves(lib, execution, spec["fmus"])
            _set_initial_values(lib, execution, index, variables, spec["parameters"])
            _connect(lib, execution, index, variables, spec["connections"])
        data = _record(lib, execution, index, variables, spec, run)
    except BaseException:
        if not run.stepped:
            _destroy(lib, execution, run.observer)
        raise
    _destroy(lib, execution, run.observer)
    return data


class _Run:
    """What the clean-up of :func:`_simulate` needs to know: the observer, and whether
    a step was attempted."""

    def __init__(self) -> None:
        self.observer: int | None = None
        self.stepped = False


def _record(
    lib: ctypes.CDLL,
    execution: int,
    index: Mapping[str, int],
    variables: Mapping[str, Mapping[str, tuple[int, int, str]]],
    spec: dict[str, Any],
    run: _Run,
) -> np.ndarray:
    """Observe ``spec["observe"]``, step ``spec["n_steps"]`` times, return the samples."""
    start_ns, step_ns, n_steps = spec["start_ns"], spec["step_ns"], spec["n_steps"]
    chunk = max(1, min(_CHUNK, n_steps))
    run.observer = lib.cosim_buffered_time_series_observer_create(chunk + 1)
    if not run.observer or lib.cosim_execution_add_observer(execution, run.observer) != 0:
        raise LibcosimError(f"cannot add a time-series observer: {_last_error(lib)}")
    observed = _start_observing(lib, run.observer, index, variables, spec["observe"])
    data = np.zeros(
        n_steps + 1,
        dtype=[("time", np.float64)] + [(name, dtype) for name, _, _, dtype in observed],
    )
    data["time"] = (start_ns + np.arange(n_steps + 1, dtype=np.int64) * step_ns) / 1e9
    done = 0
    while done < n_steps:
        count = min(chunk, n_steps - done)
        run.stepped = True
        if lib.cosim_execution_step(execution, count) != 0:
            raise _step_failure(lib, execution, list(index))
        first = 0 if done == 0 else done + 1
        _fetch(lib, run.observer, observed, data, first, done + count, start_ns, step_ns)
        done += count
    return data


def _destroy(lib: ctypes.CDLL, execution: int, observer: int | None) -> None:
    lib.cosim_execution_destroy(execution)  # terminates and frees the FMU instances
    if observer:
        lib.cosim_observer_destroy(observer)


def _add_slaves(
    lib: ctypes.CDLL, execution: int, fmus: Mapping[str, str]
) -> tuple[dict[str, int], dict[str, dict[str, tuple[int, int, str]]]]:
    """Load each FMU as a slave.

    Returns
    -------
    tuple
        Slave index of each block, and ``{block: {variable: (vr, type, causality)}}``.
    """
    index: dict[str, int] = {}
    variables: dict[str, dict[str, tuple[int, int, str]]] = {}
    for name, path in fmus.items():
        slave = lib.cosim_local_slave_create(path.encode(), name.encode())
        if not slave:
            raise LibcosimError(f"cannot load FMU {path}: {_last_error(lib)}", block=name)
        slave_index = lib.cosim_execution_add_slave(execution, slave)
        reason = _last_error(lib) if slave_index < 0 else ""
        lib.cosim_local_slave_destroy(slave)  # the execution keeps the instance
        if slave_index < 0:
            raise LibcosimError(f"cannot add the slave: {reason}", block=name)
        index[name] = slave_index
        variables[name] = _slave_variables(lib, execution, slave_index, name)
    return index, variables


def _slave_variables(
    lib: ctypes.CDLL, execution: int, slave_index: int, name: str
) -> dict[str, tuple[int, int, str]]:
    """``{variable: (vr, type, causality)}`` of one slave."""
    count = lib.cosim_slave_get_num_variables(execution, slave_index)
    table = (_VariableDescription * max(count, 1))()
    if count < 0 or lib.cosim_slave_get_variables(execution, slave_index, table, count) < 0:
        raise LibcosimError(f"cannot read the variables: {_last_error(lib)}", block=name)
    return {
        d.name.decode(): (d.reference, d.type, _CAUSALITY_NAMES.get(d.causality, "?"))
        for d in table[:count]
    }


def _ssp_slaves(
    lib: ctypes.CDLL, execution: int
) -> tuple[dict[str, int], dict[str, dict[str, tuple[int, int, str]]]]:
    """Slave index and variables of every component libcosim loaded from an SSP archive."""
    count = lib.cosim_execution_get_num_slaves(execution)
    infos = (_SlaveInfo * max(count, 1))()
    if count < 0 or lib.cosim_execution_get_slave_infos(execution, infos, count) < 0:
        raise LibcosimError(f"cannot list the SSP components: {_last_error(lib)}")
    index = {info.name.decode(): info.index for info in infos[:count]}
    variables = {
        name: _slave_variables(lib, execution, slave_index, name)
        for name, slave_index in index.items()
    }
    return index, variables


def _lookup(
    variables: Mapping[str, Mapping[str, tuple[int, int, str]]], block: str, var: str, role: str
) -> tuple[int, int, str]:
    if block not in variables:
        raise LibcosimError(
            f"unknown block in {role} (blocks: {', '.join(variables)})", block=block, variable=var
        )
    if var not in variables[block]:
        raise LibcosimError(
            f"the FMU has no variable of this name ({role}; it has: {', '.join(variables[block])})",
            block=block,
            variable=var,
        )
    return variables[block][var]


def _set_initial_values(
    lib: ctypes.CDLL,
    execution: int,
    index: Mapping[str, int],
    variables: Mapping[str, Mapping[str, tuple[int, int, str]]],
    parameters: Mapping[str, Mapping[str, Any]],
) -> None:
    setters = {
        _REAL: lib.cosim_execution_set_real_initial_value,
        _INTEGER: lib.cosim_execution_set_integer_initial_value,
        _BOOLEAN: lib.cosim_execution_set_boolean_initial_value,
        _STRING: lib.cosim_execution_set_string_initial_value,
    }
    for block, values in parameters.items():
        for var, value in values.items():
            vr, kind, causality = _lookup(variables, block, var, "parameters")
            if causality not in _SETTABLE:
                raise LibcosimError(
                    f"only parameters and inputs can be set before initialisation, this "
                    f"variable is a(n) {causality}",
                    block=block,
                    variable=var,
                )
            converted = _fmi_value(kind, value, block, var)
            if setters[kind](execution, index[block], vr, converted) != 0:
                raise LibcosimError(
                    f"libcosim refused the value {value!r}: {_last_error(lib)}",
                    block=block,
                    variable=var,
                )


def _connect(
    lib: ctypes.CDLL,
    execution: int,
    index: Mapping[str, int],
    variables: Mapping[str, Mapping[str, tuple[int, int, str]]],
    connections: Sequence[Sequence[str]],
) -> None:
    connectors = {
        _REAL: lib.cosim_execution_connect_real_variables,
        _INTEGER: lib.cosim_execution_connect_integer_variables,
        _BOOLEAN: lib.cosim_execution_connect_boolean_variables,
        _STRING: lib.cosim_execution_connect_string_variables,
    }
    for connection in connections:
        if len(connection) != 4:
            raise LibcosimError(
                f"a connection is (source block, source variable, sink block, sink variable), "
                f"got {tuple(connection)!r}"
            )
        src_block, src_var, dst_block, dst_var = connection
        link = f"connection {src_block}.{src_var} -> {dst_block}.{dst_var}"
        src_vr, src_kind, _ = _lookup(variables, src_block, src_var, link)
        dst_vr, dst_kind, _ = _lookup(variables, dst_block, dst_var, link)
        if src_kind != dst_kind:
            raise LibcosimError(
                f"{link}: the source is {_TYPE_NAMES[src_kind]}, the sink "
                f"{_TYPE_NAMES[dst_kind]}; libcosim connects variables of one type only",
                block=dst_block,
                variable=dst_var,
            )
        status = connectors[src_kind](execution, index[src_block], src_vr, index[dst_block], dst_vr)
        if status != 0:
            raise LibcosimError(
                f"libcosim refused the {link}: {_last_error(lib)}",
                block=dst_block,
                variable=dst_var,
            )


def _start_observing(
    lib: ctypes.CDLL,
    observer: int,
    index: Mapping[str, int],
    variables: Mapping[str, Mapping[str, tuple[int, int, str]]],
    observe: Sequence[Sequence[str]],
) -> list[tuple[str, tuple[int, int], int, Any]]:
    """Start the time series; return ``(field, (slave, vr), type, dtype)`` per variable."""
    observed = []
    for block, var in observe:
        vr, kind, _ = _lookup(variables, block, var, "observe")
        if kind not in (_REAL, _INTEGER):
            raise LibcosimError(
                f"libcosim's time-series observer records Real and Integer variables only, "
                f"this one is {_TYPE_NAMES[kind]}",
                block=block,
                variable=var,
            )
        if lib.cosim_observer_start_observing(observer, index[block], kind, vr) != 0:
            raise LibcosimError(
                f"libcosim cannot observe it: {_last_error(lib)}", block=block, variable=var
            )
        dtype = np.float64 if kind == _REAL else np.int32
        observed.append((f"{block}.{var}", (index[block], vr), kind, dtype))
    return observed


def _fetch(
    lib: ctypes.CDLL,
    observer: int,
    observed: Sequence[tuple[str, tuple[int, int], int, Any]],
    data: np.ndarray,
    first: int,
    last: int,
    start_ns: int,
    step_ns: int,
) -> None:
    """Copy the samples of steps ``first .. last`` into rows ``first .. last`` of ``data``."""
    count = last - first + 1
    expected_steps = np.arange(first, last + 1, dtype=np.int64)
    for field, (slave, vr), kind, dtype in observed:
        values = np.zeros(count, dtype=np.float64 if kind == _REAL else np.intc)
        steps = np.zeros(count, dtype=np.int64)
        times = np.zeros(count, dtype=np.int64)
        reader = (
            lib.cosim_observer_slave_get_real_samples
            if kind == _REAL
            else lib.cosim_observer_slave_get_integer_samples
        )
        got = reader(
            observer,
            slave,
            vr,
            first,
            count,
            values.ctypes.data,
            steps.ctypes.data,
            times.ctypes.data,
        )
        if (
            got != count
            or not np.array_equal(steps, expected_steps)
            or not np.array_equal(times, start_ns + expected_steps * step_ns)
        ):
            raise RuntimeError(
                f"libcosim returned {got} samples of '{field}' for steps {first}..{last} "
                f"(expected {count} on the time grid): internal error of run_libcosim"
            )
        data[field][first : last + 1] = values.astype(dtype, copy=False)


def _step_failure(lib: ctypes.CDLL, execution: int, blocks: Sequence[str]) -> LibcosimError:
    """The error of a failed ``cosim_execution_step``, naming the block from libcosim's message."""
    reason = _last_error(lib)
    status = _ExecutionStatus()
    lib.cosim_execution_get_status(execution, ctypes.byref(status))
    block = None
    for name in sorted(blocks, key=len, reverse=True):
        if re.match(rf"(Simulation error: )?{re.escape(name)}: ", reason):
            block = name
            break
    return LibcosimError(reason, block=block, time=status.current_time / 1e9)


# ------------------------------------------------------------------ child process
# The child loads this file as a stand-alone module (it imports nothing from ``cosim``),
# from a neutral working directory, so that each pythonfmu FMU imports the ``models``
# package packed in its own resources rather than the one of this source tree.
_CHILD_CODE = (
    "import importlib.util, sys; "
    "spec = importlib.util.spec_from_file_location('ins_cosim_libcosim_child', sys.argv[1]); "
    "module = importlib.util.module_from_spec(spec); sys.modules[spec.name] = module; "
    "spec.loader.exec_module(module); module._child_main(sys.argv[2])"
)


def _run_isolated(spec: dict[str, Any]) -> np.ndarray:
    """Run :func:`_simulate` in a child process; turn its failures into exceptions."""
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
            [sys.executable, "-c", _CHILD_CODE, str(Path(__file__).resolve()), tmp],
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
        if proc.returncode == _EXIT_REFUSED and (work / "error.json").is_file():
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


def _child_main(workdir: str) -> None:
    """Child process: run ``spec.json`` and write ``result.npy`` or ``error.json``."""
    work = Path(workdir)
    spec = json.loads((work / "spec.json").read_text())
    try:
        data = _simulate(spec)
    except LibcosimError as exc:
        (work / "error.json").write_text(json.dumps(exc.to_json()))
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT_REFUSED)  # no teardown: freeing a failed pythonfmu instance can crash
    np.save(work / "partial.npy", data, allow_pickle=False)
    os.replace(work / "partial.npy", work / "result.npy")
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)  # the execution is already destroyed; skip the interpreter's teardown
