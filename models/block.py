"""FMI-shaped base class shared by every model in ``models/``.

A model says only what it computes: it lists its variables (:func:`parameter`,
:func:`input_`, :func:`output`) and implements :meth:`Block.initialize` and
:meth:`Block.step`. This module owns the FMI side: it registers every variable
with pythonfmu (vectors as scalars ``name[1]`` .. ``name[n]``), writes units and
start values into the model description, and maps the FMI life cycle onto the
two hooks. The same class therefore runs in-process (the master instantiates
it directly) and inside an FMU built by ``make fmus``, with identical
arithmetic.

Life cycle (FMI 2.0 co-simulation)::

    instantiate -> setup_experiment(t0) -> enter_initialization_mode
      -> set parameters / inputs -> exit_initialization_mode  => initialize()
      -> [set inputs -> do_step(t, h)  => step(t, h) -> get outputs] ...
      -> terminate                     (reset = a fresh instance, as pythonfmu does)

Only numpy, scipy and pythonfmu may be imported by models: the FMU carries
``models/`` in its resources and relies on the host interpreter for the rest.
"""

from __future__ import annotations

import hashlib
import inspect
import uuid
from dataclasses import dataclass
from typing import Any, ClassVar
from xml.etree.ElementTree import Element, SubElement

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real

# SI exponents of the units models may declare, in FMI <BaseUnit> terms.
# Units whose exponents are not integers (rad/sqrt(s), ...) are declared by name only.
UNIT_BASE: dict[str, dict[str, int]] = {
    "1": {},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "s": {"s": 1},
    "1/s": {"s": -1},
    "Hz": {"s": -1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
}

_NAMESPACE = uuid.UUID("6f0d8a52-3c41-4e0b-9a53-8f7f3e1c2b10")


#: Relative tolerance within which two macro steps are the same step for a model's caches.
#: The master passes ``h_n = t_{n+1} - t_n`` so that a step ends exactly on its grid point;
#: these differ from the nominal step by a rounding of ``t`` (``ulp(t) / h``: 3e-13 at
#: t = 120 s, h = 0.05 s), so a cache keyed on the exact ``h`` would miss on every step.
STEP_RTOL = 1e-9


def same_step(h: float, h_ref: float | None) -> bool:
    """Whether step ``h`` may reuse what a model computed for step ``h_ref``.

    Parameters
    ----------
    h : float
        The step being taken [s].
    h_ref : float or None
        The step the cached values were computed for [s]; None when nothing is cached.

    Returns
    -------
    bool
        ``abs(h - h_ref) <= STEP_RTOL * h_ref``: the same macro step up to the rounding
        of the time grid. Cached values then differ from those of ``h`` by the relative
        step difference, a rounding of ``t`` (not ``STEP_RTOL``); a step that really
        changes (a last, shorter step) is recomputed.
    """
    return h_ref is not None and abs(h - h_ref) <= STEP_RTOL * h_ref


@dataclass(frozen=True)
class Var:
    """Declaration of one (scalar or vector) model variable.

    Attributes
    ----------
    name : str
        Attribute name on the model; FMI scalars are ``name`` or ``name[i]``, i = 1..size.
    causality : str
        ``"parameter"``, ``"input"``, ``"output"`` or ``"local"``.
    start : float, int, bool or tuple
        Start value; a tuple makes a vector of that length.
    unit : str
        SI unit (a key of :data:`UNIT_BASE` or any other name); ``"1"`` when dimensionless.
    description : str
        One line for the model description.
    """

    name: str
    causality: str
    start: Any = 0.0
    unit: str = "1"
    description: str = ""

    @property
    def size(self) -> int:
        """Number of scalar elements (1 for scalars)."""
        return len(self.start) if isinstance(self.start, (tuple, list)) else 1

    @property
    def is_vector(self) -> bool:
        """True when the variable is exposed as ``name[1]`` .. ``name[n]``."""
        return isinstance(self.start, (tuple, list))

    @property
    def variability(self) -> str:
        """FMI variability: ``"fixed"`` for a parameter, else ``"discrete"`` (Integer, Boolean)
        or ``"continuous"`` (Real)."""
        if self.causality == "parameter":
            return "fixed"
        return "continuous" if self.kind == "Real" else "discrete"

    @property
    def kind(self) -> str:
        """FMI type: ``"Real"``, ``"Integer"`` or ``"Boolean"``."""
        first = self.start[0] if self.is_vector else self.start
        if isinstance(first, bool):
            return "Boolean"
        if isinstance(first, (int, np.integer)):
            return "Integer"
        return "Real"


def parameter(name: str, start: Any, unit: str = "1", description: str = "") -> Var:
    """Declare a fixed parameter (set before initialisation, constant afterwards).

    Parameters
    ----------
    name : str
        Attribute name on the model (a Python identifier); vectors become the FMI
        scalars ``name[1]`` .. ``name[n]``.
    start : float, int, bool or tuple
        Start value, the default a scenario may override. Its type sets the FMI type
        (Real, Integer, Boolean); a tuple makes a vector of that length.
    unit : str
        SI unit (a key of :data:`UNIT_BASE` or any other name), ``"1"`` when
        dimensionless.
    description : str
        One line for the model description.

    Returns
    -------
    Var
    """
    return Var(name, "parameter", start, unit, description)


def input_(name: str, start: Any = 0.0, unit: str = "1", description: str = "") -> Var:
    """Declare a continuous input (set by the master before each step).

    Parameters
    ----------
    name, start, unit, description : str, float or tuple
        As for :func:`parameter`; ``start`` holds until a connection sets the input.

    Returns
    -------
    Var
    """
    return Var(name, "input", start, unit, description)


def output(name: str, start: Any = 0.0, unit: str = "1", description: str = "") -> Var:
    """Declare an output (valid at the end of each step, and at t0 after initialisation).

    Parameters
    ----------
    name, start, unit, description : str, float or tuple
        As for :func:`parameter`; ``start`` holds until :meth:`Block.initialize` sets
        the output.

    Returns
    -------
    Var
    """
    return Var(name, "output", start, unit, description)


class _UnitReal(Real):
    """pythonfmu Real that also writes the ``unit`` attribute."""

    def __init__(self, name: str, unit: str, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self) -> Element:
        node = super().to_xml()
        if self.unit != "1":
            node.find("Real").set("unit", self.unit)
        return node


_CAUSALITY = {
    "parameter": Fmi2Causality.parameter,
    "input": Fmi2Causality.input,
    "output": Fmi2Causality.output,
    "local": Fmi2Causality.local,
}


class Block(Fmi2Slave):
    """Base class of every model block.

    Subclasses set :attr:`variables` and implement :meth:`initialize` and
    :meth:`step`. Each declared variable becomes an attribute: a Python scalar
    for scalars, a float ndarray of shape (n,) for vectors (update it in place
    or assign a new array of the same shape).

    Attributes
    ----------
    step_setups : int
        How many times the model computed its step-dependent coefficients (transition
        matrices, noise factors); a model that caches them by step (:func:`same_step`)
        counts each computation, so a run at a constant macro step counts 1 (reset at
        each initialisation).
    """

    #: The model's variables, in the order they appear in the model description.
    variables: ClassVar[tuple[Var, ...]] = ()
    #: Default communication step for the model description's DefaultExperiment [s].
    default_step: ClassVar[float] = 0.01
    #: Default stop time for the DefaultExperiment (used by a standalone ``fmpy simulate``) [s].
    default_stop: ClassVar[float] = 1.0

    author = "ins-cosim"
    license = "MIT"

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("instance_name", type(self).__name__)
        super().__init__(**kwargs)
        doc = inspect.getdoc(type(self)) or type(self).__name__
        self.description = doc.splitlines()[0]
        self.start_time = 0.0
        self.step_setups = 0
        # Real value reference -> (attribute, element index or -1 for a scalar), and the
        # access plans built from it (see get_real / set_real)
        self._real_slots: dict[int, tuple[str, int]] = {}
        self._plans: dict[tuple[int, ...], list[tuple[str, int, int]]] = {}
        for var in self.variables:
            self._declare(var)

    # ----------------------------------------------------------------- hooks
    def initialize(self) -> None:
        """Compute derived quantities and the outputs at the start time from the parameters."""

    def step(self, t: float, h: float) -> None:
        """Advance the model from ``t`` to ``t + h`` and set the outputs at ``t + h``.

        Parameters
        ----------
        t : float
            Time at the start of the step [s].
        h : float
            Step size [s], > 0.
        """
        raise NotImplementedError

    # ------------------------------------------------------------ FMI side
    @classmethod
    def model_guid(cls) -> str:
        """A GUID derived from the model's source, so equal sources give equal GUIDs."""
        try:
            text = inspect.getsource(cls) + inspect.getsource(Block)
        except OSError:  # source not on disk (e.g. a model loaded from an unloaded FMU)
            text = f"{cls.__module__}.{cls.__qualname__}"
        return str(uuid.uuid5(_NAMESPACE, hashlib.sha256(text.encode()).hexdigest()))

    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        """FMI ``setupExperiment``: store the start time for :meth:`initialize`.

        Parameters
        ----------
        start_time : float
            Start time t0 of the experiment [s].
        stop_time : float, optional
            Stop time [s]; not used.
        tolerance : float, optional
            Relative tolerance; not used.
        """
        self.start_time = float(start_time)

    def exit_initialization_mode(self) -> None:
        self.step_setups = 0
        self.initialize()

    def do_step(self, current_time: float, step_size: float) -> bool:
        """FMI ``doStep``: :meth:`step` from ``current_time`` to ``current_time + step_size``.

        Parameters
        ----------
        current_time : float
            Communication point at the start of the step [s].
        step_size : float
            Communication step size [s], > 0.

        Returns
        -------
        bool
            Always True (a failing :meth:`step` raises instead).
        """
        self.step(current_time, step_size)
        return True

    def reset(self) -> None:
        """Return every variable to its start value (FMI reset)."""
        for var in self.variables:
            setattr(self, var.name, self._start_value(var))

    @staticmethod
    def _start_value(var: Var) -> Any:
        if var.is_vector:
            dtype = {"Real": float, "Integer": int, "Boolean": bool}[var.kind]
            return np.array(var.start, dtype=dtype)
        return var.start

    def _declare(self, var: Var) -> None:
        if var.causality not in _CAUSALITY:
            raise ValueError(
                f"{type(self).__name__}.{var.name}: causality must be one of "
                f"{sorted(_CAUSALITY)}, got {var.causality!r}"
            )
        setattr(self, var.name, self._start_value(var))
        causality = _CAUSALITY[var.causality]
        variability = getattr(Fmi2Variability, var.variability)
        # inputs carry a start value but no initial attribute
        initial = None if var.causality == "input" else Fmi2Initial.exact
        names = (
            [var.name] if not var.is_vector else [f"{var.name}[{i + 1}]" for i in range(var.size)]
        )
        for i, scalar_name in enumerate(names):
            getter, setter = self._accessors(var, i)
            kwargs = dict(
                causality=causality,
                variability=variability,
                initial=initial,
                description=var.description or None,
                getter=getter,
                setter=setter,
            )
            if var.kind == "Real":
                real = _UnitReal(scalar_name, var.unit, **kwargs)
                self.register_variable(real, nested=False)
                self._real_slots[real.value_reference] = (var.name, i if var.is_vector else -1)
            elif var.kind == "Integer":
                self.register_variable(Integer(scalar_name, **kwargs), nested=False)
            else:
                self.register_variable(Boolean(scalar_name, **kwargs), nested=False)

    # ------------------------------------------------------ Real access (fast path)
    def _plan(self, vrs: Any) -> list[tuple[str, int, int]]:
        """Segments ``(attribute, start, stop)`` covering ``vrs`` in order (cached).

        Consecutive elements of one vector become one slice; a scalar is
        ``(attribute, -1, -1)``. Raises like pythonfmu: KeyError for an unknown value
        reference, TypeError for a variable that is not Real.
        """
        key = tuple(vrs)
        plan = self._plans.get(key)
        if plan is not None:
            return plan
        plan = []
        for vr in key:
            slot = self._real_slots.get(vr)
            if slot is None:
                self.vars[vr]  # KeyError for an unknown value reference
                raise TypeError(f"Variable with valueReference={vr} is not of type Real!")
            name, index = slot
            last = plan[-1] if plan else None
            if index >= 0 and last is not None and last[0] == name and last[2] == index:
                plan[-1] = (name, last[1], index + 1)
            else:
                plan.append((name, index, index + 1) if index >= 0 else (name, -1, -1))
        if len(self._plans) >= 64:  # callers use a few fixed lists; bound the cache anyway
            self._plans.clear()
        self._plans[key] = plan
        return plan

    def get_real(self, vrs: Any) -> list[float]:
        """Values of Real variables (pythonfmu's per-scalar getters, one slice per vector).

        Parameters
        ----------
        vrs : sequence of int
            Value references.

        Returns
        -------
        list of float
            In the order of ``vrs``.
        """
        out: list[float] = []
        for name, lo, hi in self._plan(vrs):
            value = getattr(self, name)
            if lo < 0:
                out.append(float(value))
            elif (
                lo == 0
                and type(value) is np.ndarray
                and value.shape == (hi,)
                and (value.dtype == np.float64)
            ):
                out += value.tolist()  # the whole vector, already floats
            else:
                out.extend(np.asarray(value, dtype=float)[lo:hi].tolist())
        return out

    def set_real(self, vrs: Any, values: Any) -> None:
        """Set Real variables; vector elements are written into the attribute's array.

        Parameters
        ----------
        vrs : sequence of int
            Value references.
        values : sequence of float
            One value per reference.
        """
        pos = 0
        array = None
        for name, lo, hi in self._plan(vrs):
            if lo < 0:
                setattr(self, name, values[pos])
                pos += 1
            else:
                if array is None:  # one conversion for every vector element
                    array = np.asarray(values, dtype=float)
                getattr(self, name)[lo:hi] = array[pos : pos + hi - lo]
                pos += hi - lo

    def _accessors(self, var: Var, index: int) -> tuple[Any, Any]:
        name = var.name
        if not var.is_vector:
            return (lambda: getattr(self, name)), (lambda v: setattr(self, name, v))

        def get() -> Any:
            return getattr(self, name)[index]

        def set_(value: Any) -> None:
            getattr(self, name)[index] = value

        return get, set_

    def to_xml(self, model_options: dict[str, str] | None = None) -> Element:
        """Model description: pythonfmu's, plus unit definitions and a default experiment.

        Parameters
        ----------
        model_options : dict of str to str, optional
            pythonfmu's FMU model options (capability flags such as
            ``canHandleVariableCommunicationStepSize``); None for pythonfmu's defaults.

        Returns
        -------
        xml.etree.ElementTree.Element
            The ``fmiModelDescription`` root, with ``UnitDefinitions`` after
            ``CoSimulation`` when a Real variable has a unit other than ``"1"``.
        """
        from pythonfmu.default_experiment import DefaultExperiment

        self.default_experiment = DefaultExperiment(
            start_time=0.0, stop_time=self.default_stop, step_size=self.default_step
        )
        self.guid = self.model_guid()
        root = super().to_xml(model_options or {})
        units = sorted({v.unit for v in self.variables if v.kind == "Real" and v.unit != "1"})
        if units:
            node = Element("UnitDefinitions")
            for unit in units:
                u = SubElement(node, "Unit", {"name": unit})
                exps = UNIT_BASE.get(unit)
                if exps is not None:
                    SubElement(u, "BaseUnit", {k: str(e) for k, e in exps.items()})
            position = list(root).index(root.find("CoSimulation")) + 1
            root.insert(position, node)
        return root
