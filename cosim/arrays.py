"""FMI 3 array variables as the scalars the master exchanges.

An FMI 3 variable with ``<Dimension>`` children is an array (row-major). ins-cosim shows
each element as a scalar :class:`~cosim.variables.Variable` named ``x[i]`` (one
dimension) or ``A[i,j]`` (more), 1-based, in row-major order, so a scenario connects,
sets and records elements (``"a.y[2] -> b.u[1]"``) or the whole array (``"a.y ->
b.u"``, equal shapes) as it does the vectors of FMI 2 FMUs (``name[1]``, ``name[2]``).

FMI 3 gets and sets an array only whole, by the array's value reference. Each element
therefore carries its own *element reference* (a number above :data:`ELEMENT_VR_BASE`,
never an FMI value reference) and an :class:`~cosim.variables.ArrayElement` naming its
array; :class:`ArrayAccess` wraps a host's getters and setters so that element
references read the array once and pick the elements, and setting elements sets the
whole array from a copy that holds the other elements' last values (their start values
at first). Shapes are those the model description gives, a structural parameter's
start value included; structural parameters cannot be changed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from cosim.variables import (  # the element names and variables live there (no circle)
    ELEMENT_VR_BASE,
    ArrayElement,
    Variable,
    element_names,
    element_starts,
    expand_array,
)

__all__ = ["ELEMENT_VR_BASE", "ArrayAccess", "element_names", "element_starts", "expand_array"]


class ArrayAccess:
    """Getters and setters of a host that also take element references.

    Parameters
    ----------
    variables : iterable of Variable
        The host's variables (elements carry :attr:`Variable.element`).
    """

    def __init__(self, variables: Any) -> None:
        self.elements: dict[int, ArrayElement] = {}
        self._start: dict[int, list[Any]] = {}
        for v in variables:
            e = v.element
            if e is None:
                continue
            self.elements[v.vr] = e
            values = self._start.setdefault(e.array_vr, [None] * math.prod(e.shape))
            values[e.index] = v.start if v.start is not None else 0
        self.current: dict[int, list[Any]] = {}
        self.reset()

    def __bool__(self) -> bool:
        return bool(self.elements)

    def reset(self) -> None:
        """Every array's copy back on its start values (after an FMI reset)."""
        self.current = {a: list(values) for a, values in self._start.items()}

    def touches(self, vrs: list[int]) -> bool:
        """Whether any reference of ``vrs`` is an array element.

        Parameters
        ----------
        vrs : list of int
            References.

        Returns
        -------
        bool
        """
        elements = self.elements
        return any(vr in elements for vr in vrs)

    def accessors(
        self, getters: dict[str, Callable[..., Any]], setters: dict[str, Callable[..., Any]]
    ) -> tuple[dict[str, Callable[..., Any]], dict[str, Callable[..., Any]]]:
        """The host's getters and setters by type, taking element references too.

        Parameters
        ----------
        getters, setters : dict
            Type -> fmpy's ``get<Type>(vrs, nValues)`` / ``set<Type>(vrs, values)``.

        Returns
        -------
        (dict, dict)
            The wrapped getters and setters, same keys.
        """
        return (
            {t: self._getter(f) for t, f in getters.items()},
            {t: self._setter(f) for t, f in setters.items()},
        )

    def _getter(self, get: Callable[..., Any]) -> Callable[[list[int]], list[Any]]:
        elements = self.elements

        def get_values(vrs: list[int]) -> list[Any]:
            if not any(vr in elements for vr in vrs):
                return get(vrs)
            plain = [vr for vr in vrs if vr not in elements]
            got = dict(zip(plain, get(plain), strict=True)) if plain else {}
            arrays: dict[int, list[Any]] = {}
            for vr in vrs:
                e = elements.get(vr)
                if e is not None and e.array_vr not in arrays:
                    arrays[e.array_vr] = list(get([e.array_vr], math.prod(e.shape)))
            return [
                got[vr] if vr not in elements else arrays[elements[vr].array_vr][elements[vr].index]
                for vr in vrs
            ]

        return get_values

    def _setter(self, set_: Callable[..., Any]) -> Callable[[list[int], list[Any]], None]:
        elements = self.elements

        def set_values(vrs: list[int], values: list[Any]) -> None:
            if not any(vr in elements for vr in vrs):
                set_(vrs, values)
                return
            plain = [(vr, x) for vr, x in zip(vrs, values, strict=True) if vr not in elements]
            if plain:
                set_([vr for vr, _x in plain], [x for _vr, x in plain])
            touched: dict[int, None] = {}
            for vr, x in zip(vrs, values, strict=True):
                e = elements.get(vr)
                if e is not None:
                    self.current[e.array_vr][e.index] = x
                    touched[e.array_vr] = None
            for a in touched:
                set_([a], self.current[a])

        return set_values


def nested_values(raw: Any, scalars: list[Variable], error: Callable[[str], Exception]) -> Any:
    """A scenario value for a whole FMI 3 array of two or more dimensions, flattened row-major.

    Parameters
    ----------
    raw : Any
        The value as TOML gives it: ``[[1, 0], [0, 1]]`` for a 2 x 2 array.
    scalars : list of Variable
        The scalars the name stands for (:func:`cosim.wiring.expand`).
    error : callable
        Makes the exception to raise from a message (the scenario's, with its key).

    Returns
    -------
    Any
        ``raw`` flattened when it is a nested list for a whole array of that shape; ``raw``
        itself when it holds no list (the caller checks it as before).

    Raises
    ------
    Exception
        From ``error``: nested lists whose shape is not the array's.
    """
    if not (isinstance(raw, list) and any(isinstance(x, list) for x in raw)):
        return raw
    e = scalars[0].element
    shape = e.shape if e is not None and len(scalars) == math.prod(e.shape) else (len(scalars),)
    got, flat = _nested_shape(raw)
    if got != shape:
        name = e.array if e is not None else scalars[0].name
        raise error(
            f"'{name}' is an array of shape {shape}; expected nested lists of that shape "
            f"(row by row), got shape {got if got else 'ragged lists'}"
        )
    return flat


def _nested_shape(raw: Any) -> tuple[tuple[int, ...], list[Any]]:
    """The shape of nested lists (``()`` when ragged) and their leaves, row-major."""
    if not isinstance(raw, list):
        return (), [raw]
    parts = [_nested_shape(x) for x in raw]
    inner = {shape for shape, _leaves in parts}
    ragged = any(isinstance(x, list) and not s for x, (s, _l) in zip(raw, parts, strict=True))
    if len(inner) > 1 or ragged:
        return (), []
    shape = (len(raw), *(inner.pop() if inner else ()))
    return shape, [leaf for _s, leaves in parts for leaf in leaves]
