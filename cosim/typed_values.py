"""Links between blocks that carry other values than Float64: FMI's type rules and the exchange.

The master moves Real (Float64) values through its float64 value table
(:mod:`cosim.master`). Every other link — Integer, Boolean, Enumeration, String, the
FMI 3 integer types ``Int8`` .. ``UInt64`` and ``Float32`` — goes through a
:class:`TypedExchange`: after a source block steps (or leaves initialisation) its typed
outputs are read into a list of Python values; before a sink steps they are converted
and set, under the same coupling rule as Reals (Gauss-Seidel: the value the source
holds at that moment; Jacobi: the snapshot taken at the start of the macro step).

Type rules (docs/coupling.md, "Types and arrays"): a link joins an output and an input
of the same type (Enumerations: the same items, names and values), or widens without
losing any value:

- an integer type into a wider one whose range holds every value of the source
  (``Int8`` -> ``Int16``, ``UInt16`` -> ``Int32``, ``Integer`` -> ``Int64``, ...);
- an integer type into ``Float32`` (at most 16 bits) or ``Float64`` (at most 32 bits),
  where every value is exact;
- ``Float32`` into ``Float64``.

Everything else (``Float64`` -> an integer, a narrowing, Boolean <-> numbers,
Enumeration <-> integers, Binary and Clock links) is refused with the reason.
FMI 2 ``Real`` is ``Float64`` and FMI 2 ``Integer`` is ``Int32``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from cosim.variables import REAL, Variable

if TYPE_CHECKING:
    from cosim.blocks import BlockHost
    from cosim.master import Connection

__all__ = [
    "TypedExchange",
    "canonical_type",
    "is_typed_link",
    "link_converter",
    "link_refusal",
    "shape_refusal",
]

#: FMI 2 type names as the FMI 3 types they are.
_FMI2_AS_FMI3 = {"Real": "Float64", "Integer": "Int32"}
#: Value range of every FMI integer type [lo, hi].
INTEGER_TYPES: dict[str, tuple[int, int]] = {
    **{f"Int{n}": (-(2 ** (n - 1)), 2 ** (n - 1) - 1) for n in (8, 16, 32, 64)},
    **{f"UInt{n}": (0, 2**n - 1) for n in (8, 16, 32, 64)},
}
#: The integers a float type holds exactly: |x| <= 2**(mantissa bits).
_EXACT_INTEGERS = {"Float32": 2**24, "Float64": 2**53}
#: The value a typed output holds before its block first publishes one.
_ZERO = {"Boolean": False, "String": ""}


def canonical_type(vtype: str) -> str:
    """The FMI 3 name of a type: ``"Real"`` -> ``"Float64"``, ``"Integer"`` -> ``"Int32"``.

    Parameters
    ----------
    vtype : str
        A :attr:`cosim.variables.Variable.type`.

    Returns
    -------
    str
        The FMI 3 type name; other names unchanged.
    """
    return _FMI2_AS_FMI3.get(vtype, vtype)


def link_refusal(src: Variable, dst: Variable) -> str | None:
    """Why an output may not feed an input, or None when FMI's type rules allow the link.

    Parameters
    ----------
    src, dst : Variable
        The output and the input.

    Returns
    -------
    str or None
        The reason in a few words (the caller names the link and the variables).
    """
    a, b = canonical_type(src.type), canonical_type(dst.type)
    for t in (a, b):
        if t in ("Binary", "Clock"):
            return f"{t} variables are not linked between blocks"
    if a == b:
        if a == "Enumeration" and sorted(src.items) != sorted(dst.items):
            return (
                f"the two Enumerations have different items "
                f"({_items(src.items)} and {_items(dst.items)})"
            )
        return None
    if a in INTEGER_TYPES and b in INTEGER_TYPES:
        (lo, hi), (dlo, dhi) = INTEGER_TYPES[a], INTEGER_TYPES[b]
        if dlo <= lo and hi <= dhi:
            return None
        return f"{a} values outside [{dlo}, {dhi}] do not fit into {b}"
    if a in INTEGER_TYPES and b in _EXACT_INTEGERS:
        lo, hi = INTEGER_TYPES[a]
        if max(-lo, hi) <= _EXACT_INTEGERS[b]:
            return None
        return f"{a} values beyond 2**{_EXACT_INTEGERS[b].bit_length() - 1} are not exact in {b}"
    if a == "Float32" and b == "Float64":
        return None
    if a in _EXACT_INTEGERS and (b in INTEGER_TYPES or b == "Enumeration"):
        return f"a {a} value would be rounded to {b}"
    if a == "Float64" and b == "Float32":
        return "a Float64 value would be rounded to Float32"
    return f"FMI has no conversion from {a} to {b}"


def link_converter(src: Variable, dst: Variable, factor: float = 1.0) -> Callable[[Any], Any]:
    """The function that turns a value of ``src`` into one for ``dst`` (an allowed link).

    Parameters
    ----------
    src, dst : Variable
        The output and the input (:func:`link_refusal` returned None).
    factor : float
        The unit factor of the link (float types only; 1 for the others).

    Returns
    -------
    callable
        Value as the source's host returns it -> value as the sink's host takes it
        (int, float, bool or str).
    """
    b = canonical_type(dst.type)
    if b in _EXACT_INTEGERS:
        if factor != 1.0:
            return lambda x: float(x) * factor
        return float
    if b == "Boolean":
        return bool
    if b == "String":
        return lambda x: x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x)
    return int  # the integer types and Enumeration


def is_typed_link(blocks: Mapping[str, BlockHost], c: Connection) -> bool:
    """Whether a link carries other than Float64 on either side (then it is exchanged here).

    Parameters
    ----------
    blocks : mapping of str to BlockHost
        The system's blocks.
    c : Connection
        A resolved link.

    Returns
    -------
    bool
    """
    src = blocks[c.src_block].variables[c.src_var]
    dst = blocks[c.dst_block].variables[c.dst_var]
    return src.type != REAL or dst.type != REAL


def shape_refusal(src: list[Variable], dst: list[Variable]) -> str | None:
    """Why two sides of a connection do not match in shape, or None (FMI 3 arrays only).

    Parameters
    ----------
    src, dst : list of Variable
        The scalars each side of a connection stands for (:func:`cosim.wiring.expand`).

    Returns
    -------
    str or None
        ``"have shapes (2, 3) and (3, 2); ..."`` when either side is a whole FMI 3 array
        and the shapes differ; None otherwise (lengths are checked by the caller).
    """
    if not any(v.element for v in src + dst):
        return None
    a, b = _shape(src), _shape(dst)
    if a == b:
        return None
    return (
        f"have shapes {a} and {b}; connect arrays of equal shape, or elements one by one "
        f"(e.g. '...y[1] -> ...u[1]')"
    )


def _shape(side: list[Variable]) -> tuple[int, ...]:
    """A whole array's shape, else the number of scalars as a 1-D shape."""
    e = side[0].element
    if e is not None and all(v.element and v.element.array_vr == e.array_vr for v in side):
        indices = {v.element.index for v in side if v.element is not None}
        if len(side) == len(indices) and len(side) == _size(e.shape):
            return e.shape
    return (len(side),)


def _size(shape: tuple[int, ...]) -> int:
    n = 1
    for k in shape:
        n *= k
    return n


def _items(items: tuple[tuple[str, int], ...]) -> str:
    return ", ".join(f"{name}={value}" for name, value in items) or "none declared"


class TypedExchange:
    """The typed links of a system: source values after each step, set into sinks before theirs.

    Parameters
    ----------
    blocks : mapping of str to BlockHost
        The system's blocks.
    links : list of Connection
        The links for which :func:`is_typed_link` holds (their types are allowed).

    Attributes
    ----------
    links : list of Connection
        As given.
    """

    def __init__(self, blocks: Mapping[str, BlockHost], links: list[Connection]) -> None:
        self.links = links
        slots: dict[tuple[str, str], int] = {}
        self._start: list[Any] = []
        # block -> type -> ([vr], [slot]) of its typed outputs that feed somebody
        self._reads: dict[str, dict[str, tuple[list[int], list[int]]]] = {}
        # block -> type -> ([vr], [slot], [converter]) of its typed inputs
        self._writes: dict[str, dict[str, tuple[list[int], list[int], list[Callable]]]] = {}
        for c in links:
            src = blocks[c.src_block].variables[c.src_var]
            dst = blocks[c.dst_block].variables[c.dst_var]
            key = (c.src_block, c.src_var)
            if key not in slots:
                slots[key] = len(self._start)
                start = src.start if src.start is not None else _ZERO.get(src.type, 0)
                self._start.append(start)
                vrs, where = self._reads.setdefault(c.src_block, {}).setdefault(src.type, ([], []))
                vrs.append(src.vr)
                where.append(slots[key])
            vrs, where, convert = self._writes.setdefault(c.dst_block, {}).setdefault(
                dst.type, ([], [], [])
            )
            vrs.append(dst.vr)
            where.append(slots[key])
            convert.append(link_converter(src, dst, c.factor))
        self.live: list[Any] = list(self._start)
        self.snapshot_values: list[Any] = list(self._start)

    def restart(self) -> None:
        """Every source back on its start value (at the start of a run)."""
        self.live[:] = self._start
        self.snapshot_values[:] = self._start

    def snapshot(self) -> None:
        """Keep the values all sources hold now (Jacobi: at ``t_n``, before anyone steps)."""
        self.snapshot_values[:] = self.live

    def bind(
        self,
        name: str,
        host: BlockHost,
        put: Callable[[Any], None] | None,
        read: Callable[[], None] | None,
        jacobi: bool,
    ) -> tuple[Callable[[Any], None] | None, Callable[[], None] | None]:
        """A block's input writer and output reader, extended by its typed links.

        Parameters
        ----------
        name : str
            The block.
        host : BlockHost
            Its host.
        put : callable or None
            The master's writer of its Real inputs (``put(x)``, x float64 array).
        read : callable or None
            The master's reader of its Real outputs (``read()``).
        jacobi : bool
            Whether sinks read the snapshot (Jacobi) or the live values (Gauss-Seidel).

        Returns
        -------
        (put, read)
            Unchanged when the block has no typed link; else functions that also set its
            typed inputs / read its typed outputs.
        """
        writes, reads = self._writes.get(name), self._reads.get(name)
        if writes:
            table = self.snapshot_values if jacobi else self.live
            groups = [(t, vrs, where, conv) for t, (vrs, where, conv) in writes.items()]
            set_values = host.set_values

            def put_typed(x: Any, real: Callable[[Any], None] | None = put) -> None:
                if real is not None:
                    real(x)
                for vtype, vrs, where, convert in groups:
                    pairs = zip(convert, where, strict=True)
                    set_values(vtype, vrs, [f(table[i]) for f, i in pairs])

            put = put_typed
        if reads:
            live = self.live
            out_groups = [(t, vrs, where) for t, (vrs, where) in reads.items()]
            get_values = host.get_values

            def read_typed(real: Callable[[], None] | None = read) -> None:
                if real is not None:
                    real()
                for vtype, vrs, where in out_groups:
                    for i, value in zip(where, get_values(vtype, vrs), strict=True):
                        live[i] = value

            read = read_typed
        return put, read
