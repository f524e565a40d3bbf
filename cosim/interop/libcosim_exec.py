"""One libcosim execution in this process: the libcosimc binding behind the libcosim runner.

The runner starts a fresh Python process per run and loads this file there as a
stand-alone module (:func:`child_main`), so it imports nothing from ``cosim``: each
pythonfmu FMU then runs the ``models`` code packed in its own resources. The
behaviour (time grid, initialisation, Jacobi coupling, recording, failures) is
described in :mod:`cosim.interop.libcosim_runner`.
"""

from __future__ import annotations

import ctypes
import json
import os
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: Macro steps run per call into libcosim; the observer buffers one chunk.
_CHUNK = 10_000
#: Minimum severity libcosim prints (0 trace .. 5 fatal): warnings and errors.
_LOG_WARNING = 3
#: Exit code of the child process when libcosim refused something (``error.json`` written).
EXIT_REFUSED = 3
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

    Raised by :func:`cosim.interop.libcosim_runner.run_libcosim` and
    :func:`~cosim.interop.libcosim_runner.run_libcosim_ssp`.

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


def _per_type(lib: ctypes.CDLL, pattern: str) -> dict[int, Any]:
    """The libcosimc function of each FMI type: ``pattern`` with ``{}`` -> real, integer, ..."""
    return {kind: getattr(lib, pattern.format(name.lower())) for kind, name in _TYPE_NAMES.items()}


def _last_error(lib: ctypes.CDLL) -> str:
    message = lib.cosim_last_error_message()
    return message.decode(errors="replace").strip() if message else "no message from libcosim"


# ------------------------------------------------------------------------ the run
def simulate(spec: dict[str, Any]) -> np.ndarray:
    """Build the libcosim execution described by ``spec``, run it, return the samples.

    Runs in the child process. After a failed step the execution is left alone (the
    child exits): freeing pythonfmu instances after an FMU error can crash.

    Parameters
    ----------
    spec : dict
        ``start_ns``, ``step_ns``, ``n_steps`` (int, the time grid in ns), ``observe``
        (list of ``[block, variable]``), and either ``fmus`` (``{block: FMU path}``),
        ``parameters`` (``{block: {variable: value}}``) and ``connections`` (lists
        ``[source, output, sink, input]``), or ``ssp`` (the archive's path, which
        libcosim loads itself).

    Returns
    -------
    numpy.ndarray
        Structured array of ``n_steps + 1`` rows, ``time`` [s] then one field per
        observed variable (see :func:`cosim.interop.libcosim_runner.run_libcosim`).

    Raises
    ------
    LibcosimError
        libcosim refused the configuration, or an FMU failed during a step.
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
    """What the clean-up of :func:`simulate` needs to know: the observer, and whether
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
    setters = _per_type(lib, "cosim_execution_set_{}_initial_value")
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
    connectors = _per_type(lib, "cosim_execution_connect_{}_variables")
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


def child_main(workdir: str) -> None:
    """Child process: run ``workdir/spec.json``, write ``result.npy`` or ``error.json``, exit.

    Parameters
    ----------
    workdir : str
        The run's private folder, holding ``spec.json`` (what :func:`simulate` takes).
        On success ``result.npy`` (the samples) is written; on a refusal ``error.json``
        (the :class:`LibcosimError` arguments) and the process exits with
        :data:`EXIT_REFUSED`. The process ends with ``os._exit`` either way.
    """
    work = Path(workdir)
    spec = json.loads((work / "spec.json").read_text())
    try:
        data = simulate(spec)
    except LibcosimError as exc:
        (work / "error.json").write_text(json.dumps(exc.to_json()))
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(EXIT_REFUSED)  # no teardown: freeing a failed pythonfmu instance can crash
    np.save(work / "partial.npy", data, allow_pickle=False)
    os.replace(work / "partial.npy", work / "result.npy")
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)  # the execution is already destroyed; skip the interpreter's teardown
