"""The block protocol the master uses for everything, and its two hosts.

A *block* is anything with FMI co-simulation semantics: variables with
causality, variability, unit and start value; a life cycle
``instantiate -> setup(t0, parameters) -> [set inputs] -> exit_init -> do_step(t, h)* ->
terminate``; and ``reset``. Two hosts implement it:

- :class:`InProcessHost` runs a :class:`models.block.Block` class directly (fast path);
  it makes exactly the calls an FMU wrapper makes, so results are identical.
- :class:`FmuHost` runs an FMU file through fmpy (FMI 2.0 co-simulation; FMI 3.0
  co-simulation where fmpy supports it), ours or a vendor's.

Values cross the protocol addressed by value reference: as lists of scalars
(:meth:`BlockHost.get_real`, :meth:`BlockHost.set_real`), and, for the master's
per-step exchange, as float64 arrays bound once per run
(:meth:`BlockHost.real_reader`, :meth:`BlockHost.real_writer`): an in-process block
fills its part of the master's value table and takes its inputs from one array
without lists; an FMU gets one ``fmi2GetReal`` / ``fmi2SetReal`` call per block and
step with value-reference and value arrays made once.
"""

from __future__ import annotations

import abc
import ctypes
import functools
import hashlib
import importlib
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cosim import models  # noqa: F401  (imported before any FMU, so FMUs of ours reuse this copy)
from cosim.archives import check_archive
from cosim.arrays import ArrayAccess
from cosim.errors import FmuError
from cosim.units import name_disagreement
from cosim.unpacked import drop_repeated_path_entries, unpacked_folders
from cosim.variables import FMI3_NUMERIC_TYPES, UnitWarning, Variable, apply_rename, fmu_variables


class BlockHost(abc.ABC):
    """What the master needs from a block. Subclasses wrap one simulation unit.

    Parameters
    ----------
    name : str
        Instance name (the block's name in the scenario).
    """

    #: "model" (in-process class) or "fmu".
    kind: str = ""

    def __init__(self, name: str) -> None:
        self.name = name
        self.variables: dict[str, Variable] = {}
        self.guid: str = ""
        self.sha256: str = ""
        self.source: str = ""
        self.fmi_version: str = "2.0"

    # -- metadata ---------------------------------------------------------
    def by_causality(self, causality: str) -> list[Variable]:
        """Variables with the given causality, in declaration order.

        Parameters
        ----------
        causality : str
            FMI causality: ``"parameter"``, ``"input"``, ``"output"``, ``"local"``, ...

        Returns
        -------
        list of Variable
            Scalars (vector elements ``x[i]`` one by one).
        """
        return [v for v in self.variables.values() if v.causality == causality]

    def rename(self, mapping: Mapping[str, str]) -> None:
        """Expose variables under other names (a scenario's ``rename`` map).

        Value references are unchanged, so the master and the FMU are unaffected; only
        the names that connections, parameters and outputs use change.

        Parameters
        ----------
        mapping : mapping of str to str
            The block's own variable name -> the name to use (see :func:`apply_rename`).

        Raises
        ------
        FmuError
            An unknown variable, an invalid new name, or two variables with one name.
        """
        self.variables = apply_rename(self.variables, mapping, f"block '{self.name}'")

    # -- life cycle ---------------------------------------------------------
    @abc.abstractmethod
    def setup(self, start_time: float, parameters: dict[str, Any]) -> None:
        """Start the experiment at ``start_time`` and enter initialisation with ``parameters``.

        Parameters
        ----------
        start_time : float
            t0 [s].
        parameters : dict
            Scalar variable name -> value, in the variable's declared unit.
        """

    @abc.abstractmethod
    def exit_init(self) -> None:
        """Leave initialisation mode; outputs are valid at t0 afterwards."""

    @abc.abstractmethod
    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` to ``t + h``; raise :class:`BlockCallError` when the block fails.

        Parameters
        ----------
        t : float
            Communication point at the start of the step [s].
        h : float
            Communication step size [s], > 0.
        """

    @abc.abstractmethod
    def get_real(self, vrs: list[int]) -> list[float]:
        """Current values of Real variables.

        Parameters
        ----------
        vrs : list of int
            Value references (:attr:`Variable.vr`).

        Returns
        -------
        list of float
            One value per reference, in order, in each variable's declared unit.
        """

    @abc.abstractmethod
    def set_real(self, vrs: list[int], values: list[float]) -> None:
        """Set Real variables (inputs, or parameters during setup).

        Parameters
        ----------
        vrs : list of int
            Value references (:attr:`Variable.vr`).
        values : list of float
            One value per reference, in each variable's declared unit.
        """

    def real_reader(self, vrs: list[int], out: np.ndarray) -> Callable[[], None]:
        """A function that writes the current values of ``vrs`` into ``out`` (per step).

        Parameters
        ----------
        vrs : list of int
            Value references of Real variables.
        out : ndarray
            float64, shape (len(vrs),), C-contiguous: where the values go (in each
            variable's declared unit), kept by the returned function.

        Returns
        -------
        callable
            ``read()``; valid until :meth:`reset` (the master binds it at every run).
            This default reads :meth:`get_real`; the hosts read arrays directly.
        """
        get = self.get_real

        def read() -> None:
            out[:] = get(vrs)

        return read

    def real_writer(self, vrs: list[int]) -> Callable[[np.ndarray], None]:
        """A function that sets ``vrs`` from a float64 array (per step).

        Parameters
        ----------
        vrs : list of int
            Value references of Real variables.

        Returns
        -------
        callable
            ``write(x)``, ``x`` float64 of shape (len(vrs),) in each variable's declared
            unit; valid until :meth:`reset`. This default calls :meth:`set_real`.
        """
        set_ = self.set_real
        return lambda x: set_(vrs, x.tolist())

    def get_values(self, vtype: str, vrs: list[int]) -> list[Any]:
        """Current values of variables of one type (what the recorder reads).

        Parameters
        ----------
        vtype : str
            The :attr:`Variable.type` (``"Real"``, ``"Integer"``, ``"Boolean"``,
            ``"String"``, ``"Enumeration"``, or an FMI 3 type such as ``"UInt8"``).
        vrs : list of int
            Value references.

        Returns
        -------
        list
            One value per reference (float, int, bool or str).
        """
        return list(self._getters[vtype](vrs))

    def set_values(self, vtype: str, vrs: list[int], values: list[Any]) -> None:
        """Set variables of one type (what typed links write, :mod:`cosim.typed_values`).

        Parameters
        ----------
        vtype : str
            The :attr:`Variable.type`, as in :meth:`get_values`.
        vrs : list of int
            Value references.
        values : list
            One value per reference (float, int, bool or str).
        """
        self._setters[vtype](vrs, values)

    @abc.abstractmethod
    def reset(self) -> None:
        """Return to the state after instantiation (FMI reset)."""

    @abc.abstractmethod
    def terminate(self) -> None:
        """End the experiment and free resources."""

    def _apply_parameters(self, parameters: dict[str, Any], setters: dict[str, Any]) -> None:
        for name, value in parameters.items():
            var = self.variables[name]
            setters[var.type]([var.vr], [value])


class BlockCallError(Exception):
    """A block reported failure in a call; ``call`` names the call, message the reason.

    Parameters
    ----------
    call : str
        The protocol or FMI call that failed (``"do_step"``, ``"fmi3DoStep"``, ...).
    message : str
        The reason (the exception or the FMU's log).
    """

    def __init__(self, call: str, message: str) -> None:
        self.call = call
        super().__init__(message)


class BlockParametersRefused(BlockCallError):  # noqa: N818  (named for what the block did)
    """An in-process block's own check refused a parameter while it initialised."""


class BlockTerminated(BlockCallError):  # noqa: N818  (a request, not an error)
    """A block asked to end the simulation (FMI 2 ``fmi2Discard`` with ``fmi2Terminated``,
    FMI 3 ``terminateSimulation``): not a failure; the run ends cleanly at :attr:`time`.

    Parameters
    ----------
    call : str
        The FMI call that returned the request (``"fmi2DoStep"``, ``"fmi3DoStep"``).
    message : str
        What the block said (its last log message, if any).
    time : float
        The last time the block's outputs are valid at [s] (FMI 2
        ``fmi2LastSuccessfulTime``; FMI 3 the step end, or the early-return time).
    """

    def __init__(self, call: str, message: str, time: float) -> None:
        self.time = time
        super().__init__(call, message)


class InProcessHost(BlockHost):
    """Runs a :class:`models.block.Block` subclass in this process.

    Parameters
    ----------
    name : str
        Instance name.
    cls : type
        The block class.
    """

    kind = "model"

    def __init__(self, name: str, cls: type) -> None:
        super().__init__(name)
        self.cls = cls
        self.source = f"{cls.__module__}.{cls.__qualname__}"
        self.guid, self.sha256 = class_identity(cls)
        self._new_instance()
        for sv in self.instance.vars.values():
            kind = type(sv).__name__
            kind = "Real" if kind == "_UnitReal" else kind
            start = sv.getter()
            self.variables[sv.name] = Variable(
                name=sv.name,
                vr=sv.value_reference,
                type=kind,
                causality=sv.causality.name,
                variability=sv.variability.name if sv.variability else "continuous",
                unit=getattr(sv, "unit", "1"),
                start=start,
                description=sv.description or "",
            )

    def _new_instance(self) -> None:
        self.instance = self.cls(instance_name=self.name)
        inst = self.instance
        self._setters = {
            "Real": inst.set_real,
            "Integer": inst.set_integer,
            "Boolean": inst.set_boolean,
            "String": inst.set_string,
        }
        self._getters = {
            "Real": inst.get_real,
            "Integer": inst.get_integer,
            "Boolean": inst.get_boolean,
            "String": inst.get_string,
        }

    def setup(self, start_time: float, parameters: dict[str, Any]) -> None:
        self.instance.setup_experiment(start_time, None, None)
        self._apply_parameters(parameters, self._setters)
        self.instance.enter_initialization_mode()

    def exit_init(self) -> None:
        try:
            self.instance.exit_initialization_mode()
        except ValueError as exc:  # the model's own parameter check refused a value
            raise BlockParametersRefused(
                "exit_initialization_mode", f"{type(exc).__name__}: {exc}"
            ) from exc
        except Exception as exc:  # the model's own error, reported with block and time
            raise BlockCallError(
                "exit_initialization_mode", f"{type(exc).__name__}: {exc}"
            ) from exc

    def do_step(self, t: float, h: float) -> None:
        try:
            ok = self.instance.do_step(t, h)
        except Exception as exc:
            raise BlockCallError("do_step", f"{type(exc).__name__}: {exc}") from exc
        if not ok:
            raise BlockCallError("do_step", "the block returned failure")

    def get_real(self, vrs: list[int]) -> list[float]:
        return self.instance.get_real(vrs)

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self.instance.set_real(vrs, values)

    def real_reader(self, vrs: list[int], out: np.ndarray) -> Callable[[], None]:
        return self.instance.real_reader(vrs, out)

    def real_writer(self, vrs: list[int]) -> Callable[[np.ndarray], None]:
        return self.instance.real_writer(vrs)

    def reset(self) -> None:
        self._new_instance()

    def terminate(self) -> None:
        self.instance.terminate()


def _checked(fmu: Any, function: str, args: tuple[Any, ...]) -> Callable[[], Any]:
    """``fmu.<function>(*args)`` as fmpy calls it (status above warning raises fmpy's
    ``FMICallException``), straight to the C function that fmpy set up in ``fmu.dll`` when
    no FMI call logger is set (fmpy's two Python wrappers cost a microsecond per call)."""
    c_function = getattr(getattr(fmu, "dll", None), function, None)
    if c_function is None or getattr(fmu, "fmiCallLogger", None) is not None:
        return functools.partial(getattr(fmu, function), *args)

    def call() -> int:
        status = c_function(*args)
        if status > 1:  # fmi2Warning / fmi3Warning
            raise _fmi_call_exception()(function=function, status=status)
        return status

    return call


def _stepper(fmu: Any) -> Callable[[float, float], Any]:
    """``fmu.doStep(t, h)`` of an FMI 2 slave, straight to ``fmi2DoStep`` as :func:`_checked`
    calls its functions."""
    c_function = getattr(getattr(fmu, "dll", None), "fmi2DoStep", None)
    if c_function is None or getattr(fmu, "fmiCallLogger", None) is not None:
        return fmu.doStep
    component = fmu.component

    def step(t: float, h: float) -> int:
        status = c_function(component, t, h, 1)  # noSetFMUStatePriorToCurrentPoint = fmi2True
        if status > 1:
            raise _fmi_call_exception()(function="fmi2DoStep", status=status)
        return status

    return step


@functools.cache
def _fmi_call_exception() -> type:
    """fmpy's ``FMICallException`` (imported when a step first fails: an import statement
    per step cost about 2 µs)."""
    from fmpy.fmi1 import FMICallException

    return FMICallException


@functools.cache
def class_identity(cls: type) -> tuple[str, str]:
    """A block class's GUID and the SHA-256 of its source file, worked out once per process
    (reading the source for every instance made checking 10^4 blocks slow).

    Parameters
    ----------
    cls : type
        A :class:`models.block.Block` subclass.

    Returns
    -------
    guid : str
        ``cls.model_guid()`` (empty when the class has none).
    sha256 : str
        Of the module's file (empty when it has none).
    """
    guid = cls.model_guid() if hasattr(cls, "model_guid") else ""
    source_file = importlib.import_module(cls.__module__).__file__
    return guid, file_sha256(Path(source_file)) if source_file else ""


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes: the hash results and reports give for FMUs and sources.

    Parameters
    ----------
    path : str or Path
        The file (an FMU, a model's source file).

    Returns
    -------
    str
        64 lower-case hex digits.
    """
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


class FmuHost(BlockHost):
    """Runs an FMU file through fmpy.

    Parameters
    ----------
    name : str
        Instance name.
    path : Path
        The ``.fmu`` file (FMI 2.0 or 3.0, co-simulation).

    Attributes
    ----------
    unzip_dir : str
        The folder the FMU is unpacked into, shared by every instance of the same FMU in
        this process and removed with the last (:mod:`cosim.unpacked`).

    Raises
    ------
    FmuError
        Missing file, unreadable model description, or no co-simulation interface.
    """

    kind = "fmu"

    def __init__(self, name: str, path: Path) -> None:
        from fmpy import read_model_description

        super().__init__(name)
        path = Path(path)
        self.path = path
        self.source = str(path)
        if not path.is_file():
            raise FmuError(f"block '{name}': FMU file '{path}' does not exist (run `make fmus`?)")
        try:
            check_archive(path)  # its unpacked size, before any member is read
        except FmuError as exc:
            raise FmuError(f"block '{name}': {exc}") from None
        try:
            md = read_model_description(str(path), validate=False)
        except Exception as exc:
            raise FmuError(f"block '{name}': cannot read FMU '{path}': {exc}") from exc
        if md.coSimulation is None:
            has = [
                label
                for label, part in (
                    ("Model Exchange", md.modelExchange),
                    ("Scheduled Execution", getattr(md, "scheduledExecution", None)),
                )
                if part is not None
            ]
            interfaces = " and ".join(has) or "no interface"
            raise FmuError(
                f"block '{name}': FMU '{path}' implements only {interfaces}; ins-cosim steps "
                f"blocks as Co-Simulation units. Export it with the "
                f"Co-Simulation interface (or ask its vendor for a Co-Simulation FMU)."
            )
        if md.fmiVersion not in ("2.0", "3.0"):
            raise FmuError(
                f"block '{name}': FMU '{path}' is FMI {md.fmiVersion}; expected FMI 2.0 or 3.0"
            )
        self.model_description = md
        self._pythonfmu = (md.generationTool or "").lower().startswith("pythonfmu")
        self.fmi_version = md.fmiVersion
        self.guid = md.guid
        self.sha256 = file_sha256(path)
        self.messages: list[str] = []
        try:
            self.variables = fmu_variables(md)
        except FmuError as exc:
            raise FmuError(f"block '{name}': FMU '{path}': {exc}") from exc
        self.arrays = ArrayAccess(self.variables.values())  # FMI 3 array elements
        notes = {name_disagreement(v.unit_def) for v in self.variables.values() if v.unit_def}
        for note in sorted(n for n in notes if n):
            warnings.warn(f"block '{name}': FMU '{path.name}': {note}", UnitWarning, stacklevel=2)
        self._state = "none"
        self.unzip_dir = unpacked_folders.acquire(path, self.sha256)
        try:
            self._instantiate()
            drop_repeated_path_entries()
        except Exception as exc:
            unpacked_folders.release(self.unzip_dir)
            if isinstance(exc, FmuError):
                raise
            log = (
                f" (FMU log: {' | '.join(m.strip() for m in self.messages[-3:])})"
                if self.messages
                else ""
            )
            raise FmuError(f"block '{name}': cannot instantiate FMU '{path}': {exc}{log}") from exc

    def _logger(
        self, component: Any, instance: bytes, status: int, category: bytes, msg: bytes
    ) -> None:
        self._log_text(msg)

    def _logger3(self, environment: Any, status: int, category: bytes, msg: bytes) -> None:
        self._log_text(msg)

    def _log_text(self, msg: Any) -> None:
        text = msg.decode("utf-8", "replace") if isinstance(msg, bytes) else str(msg)
        self.messages.append(text)
        del self.messages[:-20]

    def _instantiate(self) -> None:
        md = self.model_description
        ident = md.coSimulation.modelIdentifier
        if md.fmiVersion == "2.0":
            from fmpy import calloc, free
            from fmpy.fmi2 import (
                FMU2Slave,
                fmi2CallbackAllocateMemoryTYPE,
                fmi2CallbackFreeMemoryTYPE,
                fmi2CallbackFunctions,
                fmi2CallbackLoggerTYPE,
            )

            fmu = FMU2Slave(
                guid=md.guid,
                unzipDirectory=self.unzip_dir,
                modelIdentifier=ident,
                instanceName=self.name,
            )
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(self._logger)
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            try:
                from fmpy.logging import addLoggerProxy
            except ImportError:  # pragma: no cover - older fmpy: messages unformatted
                pass
            else:
                addLoggerProxy(ctypes.byref(cb))
            self._callbacks = cb
            fmu.instantiate(callbacks=cb, loggingOn=True)
            self._step = _stepper(fmu)
            self._get = {
                "Real": fmu.getReal,
                "Integer": fmu.getInteger,
                "Boolean": fmu.getBoolean,
                "String": fmu.getString,
                "Enumeration": fmu.getInteger,
            }
            self._set = {
                "Real": fmu.setReal,
                "Integer": fmu.setInteger,
                "Boolean": fmu.setBoolean,
                "String": fmu.setString,
                "Enumeration": fmu.setInteger,
            }
        else:
            from fmpy.fmi3 import FMU3Slave

            fmu = FMU3Slave(
                guid=md.guid,
                unzipDirectory=self.unzip_dir,
                modelIdentifier=ident,
                instanceName=self.name,
            )
            # our own log callback: fmpy's default prints every FMU message to stdout
            fmu.instantiate(loggingOn=True, logMessage=self._logger3)
            self._get = {
                "Real": fmu.getFloat64,
                "Integer": fmu.getInt32,
                "Boolean": fmu.getBoolean,
                "String": fmu.getString,
                "Enumeration": fmu.getInt64,
                "Binary": fmu.getBinary,
            }
            self._set = {
                "Real": fmu.setFloat64,
                "Integer": fmu.setInt32,
                "Boolean": fmu.setBoolean,
                "String": fmu.setString,
                "Enumeration": fmu.setInt64,
                "Binary": fmu.setBinary,
            }
            # the other FMI 3 types keep their type names (fmu_variables)
            for vtype in FMI3_NUMERIC_TYPES:
                self._set[vtype] = getattr(fmu, f"set{vtype}")
                self._get[vtype] = getattr(fmu, f"get{vtype}")
        if self.arrays:  # element references read and write whole arrays
            self._get, self._set = self.arrays.accessors(self._get, self._set)
        self._getters, self._setters = self._get, self._set
        self.fmu = fmu
        self._state = "instantiated"

    def _call(self, call: str, fn: Any, *args: Any) -> Any:
        try:
            return fn(*args)
        except Exception as exc:
            detail = f" (FMU log: {self.messages[-1].strip()})" if self.messages else ""
            raise BlockCallError(call, f"{exc}{detail}") from exc

    def setup(self, start_time: float, parameters: dict[str, Any]) -> None:
        if self.fmi_version == "2.0":
            self._call("fmi2SetupExperiment", self.fmu.setupExperiment, None, start_time)
            self._apply_parameters(parameters, self._set)
            self._call("fmi2EnterInitializationMode", self.fmu.enterInitializationMode)
        else:
            # FMI 3: parameters and inputs are set in the Instantiated state; the start
            # time is an argument of fmi3EnterInitializationMode
            self._apply_parameters(parameters, self._set)
            self._call(
                "fmi3EnterInitializationMode",
                self.fmu.enterInitializationMode,
                None,
                start_time,
            )
        self._state = "initialization"

    def exit_init(self) -> None:
        prefix = "fmi2" if self.fmi_version == "2.0" else "fmi3"
        self._call(f"{prefix}ExitInitializationMode", self.fmu.exitInitializationMode)
        # FMI 3 co-simulation without event mode goes straight to Step Mode
        self._state = "stepping"

    def _said(self) -> str:
        return f" (FMU log: {self.messages[-1].strip()})" if self.messages else ""

    def do_step(self, t: float, h: float) -> None:
        if self.fmi_version == "2.0":
            try:
                self._step(t, h)
            except _fmi_call_exception() as exc:
                from fmpy.fmi2 import fmi2Discard, fmi2LastSuccessfulTime, fmi2Terminated

                # PythonFMU reports every failed step as fmi2Discard + fmi2Terminated: for
                # its FMUs (ours) that is a failure, for others a request to end the run
                if exc.status == fmi2Discard and not self._pythonfmu:
                    ask = self._call(
                        "fmi2GetBooleanStatus", self.fmu.getBooleanStatus, fmi2Terminated
                    )
                    if ask:
                        last = self._call(
                            "fmi2GetRealStatus", self.fmu.getRealStatus, fmi2LastSuccessfulTime
                        )
                        raise BlockTerminated(
                            "fmi2DoStep",
                            f"the FMU asked to end the simulation (fmi2Discard, fmi2Terminated) "
                            f"at t = {last:.9g} s{self._said()}",
                            last,
                        ) from exc
                raise BlockCallError("fmi2DoStep", f"{exc}{self._said()}") from exc
            return
        _event, terminate, early, last = self._call("fmi3DoStep", self.fmu.doStep, t, h)
        if terminate:
            end = last if early else t + h
            raise BlockTerminated(
                "fmi3DoStep",
                f"the FMU asked to end the simulation (terminateSimulation) at t = {end:.9g} s"
                f"{self._said()}",
                end,
            )
        if early:  # pragma: no cover - early return is not allowed at instantiation
            raise BlockCallError(
                "fmi3DoStep", f"expected a complete step to {t + h!r} s, got one to {last!r} s"
            )

    def get_real(self, vrs: list[int]) -> list[float]:
        return list(self._get["Real"](vrs))

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self._set["Real"](vrs, values)

    def _real_call(self, name: str, vrs: list[int], values: np.ndarray) -> Callable[[], Any]:
        """fmpy's checked ``fmi2GetReal``/``fmi2SetReal`` (FMI 3: ``Float64``) on arrays made
        once: the value references as a C array, the values aliasing ``values``."""
        fmu = self.fmu
        n = len(vrs)
        refs = (ctypes.c_uint32 * n)(*vrs)
        buffer = (ctypes.c_double * n).from_buffer(values) if n else (ctypes.c_double * 0)()
        if self.fmi_version == "2.0":
            function, args = f"fmi2{name}Real", (fmu.component, refs, n, buffer)
        else:
            function, args = f"fmi3{name}Float64", (fmu.component, refs, n, buffer, n)
        return _checked(fmu, function, args)

    def real_reader(self, vrs: list[int], out: np.ndarray) -> Callable[[], None]:
        if not out.flags.c_contiguous or out.dtype != np.float64 or self.arrays.touches(vrs):
            return super().real_reader(vrs, out)
        return self._real_call("Get", vrs, out)

    def real_writer(self, vrs: list[int]) -> Callable[[np.ndarray], None]:
        if self.arrays.touches(vrs):
            return super().real_writer(vrs)
        values = np.zeros(len(vrs))
        call = self._real_call("Set", vrs, values)

        def write(x: np.ndarray) -> None:
            values[...] = x
            call()

        return write

    def reset(self) -> None:
        self._call("fmi2Reset" if self.fmi_version == "2.0" else "fmi3Reset", self.fmu.reset)
        self.arrays.reset()
        self._state = "instantiated"

    def terminate(self) -> None:
        if self._state == "freed":  # a second terminate (cleanup after a failure) is a no-op
            return
        try:
            # fmi2Terminate / fmi3Terminate are legal only after initialisation; an FMU
            # that was never set up (or failed in initialisation) is just freed
            if self._state == "stepping":
                self.fmu.terminate()
        finally:
            self._state = "freed"
            try:
                self.fmu.freeInstance()  # fmpy: fmi2FreeInstance, then the library unloaded
            finally:
                unpacked_folders.release(self.unzip_dir)
