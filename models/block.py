"""The FMI-shaped base class of every model block (``models/blocks/``).

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

import functools
import hashlib
import inspect
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter, is_
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

    The vector Real inputs start as views into one contiguous float64 buffer, and so
    do the vector Real outputs (another buffer): the master writes the inputs of a
    step into their buffer in a few slice copies, and reads outputs that a model
    wrote in place (``self.y[:] = ...``, a kernel's ``out=``) as one slice. A model
    that assigns a new array is read element by element instead, with the same
    values (:meth:`real_reader`, :meth:`real_writer`).

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
        self._readers: dict[tuple[int, ...], tuple[np.ndarray, Callable[[], None]]] = {}
        self._writers: dict[tuple[int, ...], Callable[..., None]] = {}
        for var in self.variables:
            self._declare(var)
        # per causality: the buffer, attribute -> its view, attribute -> where it starts
        self._in_buffer, self._in_views, self._in_offsets = self._buffer("input")
        self._out_buffer, self._out_views, self._out_offsets = self._buffer("output")

    def _buffer(self, causality: str) -> tuple[np.ndarray, dict[str, Any], dict[str, int]]:
        """One float64 buffer for the vector Real variables of a causality; each attribute
        becomes a view of its part (start values copied in)."""
        vectors = [
            v
            for v in self.variables
            if v.causality == causality and v.kind == "Real" and v.is_vector
        ]
        buffer = np.zeros(sum(v.size for v in vectors))
        views: dict[str, np.ndarray] = {}
        offsets: dict[str, int] = {}
        for v in vectors:
            offsets[v.name] = pos = sum(w.size for w in views.values())
            views[v.name] = view = buffer[pos : pos + v.size]
            view[:] = getattr(self, v.name)
            setattr(self, v.name, view)
        return buffer, views, offsets

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
        views = {**self._in_views, **self._out_views}
        for var in self.variables:
            view = views.get(var.name)
            if view is None:
                setattr(self, var.name, self._start_value(var))
            else:  # buffer-backed vectors stay views of their buffer
                view[:] = self._start_value(var)
                setattr(self, var.name, view)

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
        """Values of Real variables (what pythonfmu's ``fmi2GetReal`` calls): the array
        reader of :meth:`real_reader`, cached per list of value references.

        Parameters
        ----------
        vrs : sequence of int
            Value references.

        Returns
        -------
        list of float
            In the order of ``vrs``.
        """
        key = tuple(vrs)
        entry = self._readers.get(key)
        if entry is None:
            out = np.zeros(len(key))
            entry = (out, self.real_reader(key, out))
            if len(self._readers) >= 64:  # callers use a few fixed lists; bound the cache
                self._readers.clear()
            self._readers[key] = entry
        entry[1]()
        return entry[0].tolist()

    def set_real(self, vrs: Any, values: Any) -> None:
        """Set Real variables; vector elements are written into the attribute's array
        (a few slice copies when the vectors are views of the input buffer).

        Parameters
        ----------
        vrs : sequence of int
            Value references.
        values : sequence of float
            One value per reference; scalars are set to these objects as given.
        """
        key = tuple(vrs)
        write = self._writers.get(key)
        if write is None:
            write = self._writer(key)[1]
            if len(self._writers) >= 64:
                self._writers.clear()
            self._writers[key] = write
        write(values)

    def _get_each(self, vrs: Any) -> list[float]:
        """The values of ``vrs`` one segment after the other (for parts of vectors)."""
        out: list[float] = []
        for name, lo, hi in self._plan(vrs):
            value = getattr(self, name)
            if lo < 0:
                out.append(float(value))
            else:
                out.extend(np.asarray(value, dtype=float)[lo:hi].tolist())
        return out

    def _set_each(self, vrs: Any, values: Any) -> None:
        """:meth:`set_real` one segment after the other (a reference given twice: the last
        value wins, as in order)."""
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

    # ------------------------------------------- Real access (arrays, for the master)
    def real_reader(self, vrs: Any, out: np.ndarray) -> Callable[[], None]:
        """A function of no argument that writes the current values of ``vrs`` into ``out``.

        What the in-process host gives the master: one call per step fills the block's
        part of the master's value table. Each run of whole vectors between scalars is
        one copy: a slice of the output buffer when the model wrote them in place
        (``self.y[:] = ...``), else the bytes of the arrays the model assigned (float64,
        the declared length; anything else is converted as :meth:`get_real` converts
        it). Scalars are read with one attribute look-up. The values are those
        :meth:`get_real` returns, bit for bit.

        Parameters
        ----------
        vrs : sequence of int
            Value references of Real variables.
        out : ndarray
            float64, shape (len(vrs),), C-contiguous: where the values go, in the order
            of ``vrs``; kept by the returned function (bind it once, call it every step).

        Returns
        -------
        callable
            ``read()``, valid for this instance.
        """
        vrs = list(vrs)
        if out.shape != (len(vrs),) or out.dtype != np.float64 or not out.flags.c_contiguous:
            raise ValueError(
                f"out must be C-contiguous float64 of shape ({len(vrs)},), got "
                f"{out.dtype} {out.shape}"
            )
        sizes = {v.name: v.size for v in self.variables}
        groups: list[list[tuple[str, int]]] = []  # runs of whole vectors (name, size)
        starts: list[int] = []
        scalars: list[tuple[str, int]] = []
        pos = 0
        for name, lo, hi in self._plan(vrs):
            if lo < 0:
                scalars.append((name, pos))
                pos += 1
                continue
            if lo != 0 or hi != sizes[name]:  # part of a vector: the general path
                return functools.partial(_read_any, self._get_each, vrs, out)
            if not groups or starts[-1] + sum(n for _v, n in groups[-1]) != pos:
                groups.append([])
                starts.append(pos)
            groups[-1].append((name, hi))
            pos += hi
        targets = [out[p : p + sum(n for _v, n in g)] for g, p in zip(groups, starts, strict=True)]
        vectors = _vectors_reader(self, groups, targets) if groups else None
        sc_out: Any = _positions(out, [p for _n, p in scalars])
        sc_get = _getter([n for n, _p in scalars])

        def read() -> None:
            if vectors is not None:
                vectors(self)
            if sc_get is not None:
                vals = sc_get(self)
                try:
                    sc_out[...] = vals
                except (TypeError, ValueError):  # e.g. a one-element array
                    sc_out[...] = [float(v) for v in vals]

        return read

    def real_writer(self, vrs: Any) -> Callable[[np.ndarray], None]:
        """A function that sets ``vrs`` from a float64 array: what the master calls per step.

        Vector inputs that are still views of the input buffer are written as a few slice
        copies; a vector the model rebound is written into the model's array, scalars
        are set to Python floats (as :meth:`set_real` with ``x.tolist()``).

        Parameters
        ----------
        vrs : sequence of int
            Value references of Real variables (inputs, or parameters during setup).

        Returns
        -------
        callable
            ``write(x)`` with ``x`` float64 of shape (len(vrs),), one value per
            reference in the order of ``vrs``; valid for this instance.
        """
        return self._writer(tuple(vrs))[0]

    def _writer(self, key: tuple[int, ...]) -> tuple[Callable[..., None], Callable[..., None]]:
        """``(write(x), write_raw(values))``: :meth:`real_writer` (scalars as Python floats
        from the float64 array ``x``) and :meth:`set_real` (scalars set to the objects in
        ``values``, vectors from ``values`` as float64)."""
        if len(set(key)) != len(key):  # a reference given twice: in order
            set_each = self._set_each
            return (lambda x: set_each(key, x.tolist())), (lambda raw: set_each(key, raw))
        vectors: list[tuple[str, int, int, int]] = []  # (attribute, lo, hi, position in x)
        scalars: list[tuple[str, int]] = []
        pos = 0
        for name, lo, hi in self._plan(key):
            if lo < 0:
                scalars.append((name, pos))
                pos += 1
            else:
                vectors.append((name, lo, hi, pos))
                pos += hi - lo
        views = self._in_views
        # copies (buffer slice, x start, x stop) of consecutive runs, when every vector is
        # a view of the input buffer
        runs: list[list[int]] = []
        whole = None  # the buffer slice that takes all of x (vectors only, one run)
        if all(name in views for name, *_r in vectors):
            offset = self._in_offsets
            for name, lo, hi, p in vectors:
                b = offset[name] + lo
                if runs and runs[-1][1] == b and runs[-1][3] == p:
                    runs[-1][1] += hi - lo
                    runs[-1][3] += hi - lo
                else:
                    runs.append([b, b + hi - lo, p, p + hi - lo])
            copies = [(self._in_buffer[b0:b1], x0, x1) for b0, b1, x0, x1 in runs]
            if len(copies) == 1 and not scalars:
                whole = copies[0][0]
            names = sorted({name for name, *_r in vectors})
            vec_get = _getter(names)
            vec_views = tuple(views[n] for n in names)
        else:
            copies, vec_get, vec_views = [], None, ()

        def put_vectors(x: np.ndarray) -> None:
            if vec_get is not None and all(map(is_, vec_get(self), vec_views)):
                if whole is not None:
                    whole[...] = x
                else:
                    for dst, x0, x1 in copies:
                        dst[...] = x[x0:x1]
            else:  # a rebound input (or not an input): into the model's own array
                for name, lo, hi, p in vectors:
                    getattr(self, name)[lo:hi] = x[p : p + hi - lo]

        def write(x: np.ndarray) -> None:
            if vectors:
                put_vectors(x)
            for name, i in scalars:
                setattr(self, name, x.item(i))

        def write_raw(raw: Any) -> None:
            if vectors:
                put_vectors(np.asarray(raw, dtype=float))
            for name, i in scalars:
                setattr(self, name, raw[i])

        return write, write_raw

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


def _read_any(get: Callable[[list[int]], list[float]], vrs: list[int], out: np.ndarray) -> None:
    """``out[:] = get(vrs)``: :meth:`Block.real_reader` for parts of vectors."""
    out[:] = get(vrs)


def _getter(names: list[str]) -> Callable[[Any], tuple[Any, ...]] | None:
    """``obj -> tuple of attributes`` (always a tuple), None for no names."""
    if not names:
        return None
    if len(names) == 1:
        one = attrgetter(names[0])
        return lambda obj: (one(obj),)
    return attrgetter(*names)


def _positions(out: np.ndarray, positions: list[int]) -> Any:
    """A view of ``out`` for contiguous positions (writes go straight through), else an
    object whose ``[...] =`` writes those positions."""
    if not positions:
        return None
    if positions == list(range(positions[0], positions[-1] + 1)):
        return out[positions[0] : positions[-1] + 1]
    return _Scatter(out, np.array(positions, dtype=np.intp))


class _Scatter:
    """``s[...] = values`` writes ``values`` at fixed positions of an array."""

    __slots__ = ("index", "out")

    def __init__(self, out: np.ndarray, index: np.ndarray) -> None:
        self.out, self.index = out, index

    def __setitem__(self, key: Any, values: Any) -> None:
        self.out[self.index] = values


def _vectors_reader(
    block: Block, groups: list[list[tuple[str, int]]], targets: list[np.ndarray]
) -> Callable[[Block], None]:
    """For :meth:`Block.real_reader`: a function of the block that copies its whole vectors,
    group by group (consecutive in ``out``), into the targets (contiguous parts of ``out``,
    one per group). One attribute look-up and one type check for all of them."""
    names = [n for g in groups for n, _s in g]
    sizes = tuple(s for g in groups for _n, s in g)
    get = _getter(names)
    dtypes = (np.dtype(np.float64),) * len(names)
    views = tuple(block._out_views.get(n) for n in names)
    bounds, i = [], 0
    for g in groups:
        bounds.append((i, i + len(g)))
        i += len(g)
    # in place: the buffer slice of each group, when every vector is a view of the buffer
    # and each group's views are back to back in it
    segments: list[np.ndarray] | None = None
    if all(v is not None for v in views):
        offset = block._out_offsets
        segments = []
        for i0, i1 in bounds:
            first = [offset[n] for n in names[i0:i1]]
            ends = [a + s for a, s in zip(first, sizes[i0:i1], strict=True)]
            if any(e != b for e, b in zip(ends, first[1:], strict=False)):
                segments = None
                break
            segments.append(block._out_buffer[first[0] : ends[-1]])
    pairs = list(zip(targets, segments, strict=True)) if segments is not None else []
    byte_runs = [
        (memoryview(t).cast("B"), i0, i1) for t, (i0, i1) in zip(targets, bounds, strict=True)
    ]
    single = byte_runs[0][0] if len(byte_runs) == 1 else None
    join = b"".join

    def read(obj: Block) -> None:
        vals = get(obj)
        if pairs and all(map(is_, vals, views)):
            for target, segment in pairs:  # written in place: one slice per group
                target[...] = segment
            return
        try:  # float64 arrays of the declared lengths: their bytes, joined
            if tuple(map(_DTYPE, vals)) == dtypes and tuple(map(len, vals)) == sizes:
                if single is not None:
                    single[:] = join(vals)
                else:
                    for target_bytes, i0, i1 in byte_runs:
                        target_bytes[:] = join(vals[i0:i1])
                return
        except (AttributeError, TypeError):  # not arrays, or not C-contiguous
            pass
        for target, (i0, i1) in zip(targets, bounds, strict=True):
            target[:] = [
                x
                for size, v in zip(sizes[i0:i1], vals[i0:i1], strict=True)
                for x in np.asarray(v, dtype=float)[0:size].tolist()
            ]

    return read


_DTYPE = attrgetter("dtype")
