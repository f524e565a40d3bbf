"""The transfer-alignment error model with its period step compiled (``transfer_model.c``).

:func:`make_propagate` returns the UKF's process model for one state layout: the C twin
``transfer_propagate`` of :func:`cosim.alignment.transfer_model.propagate` (one call on
the whole stack of sigma points, the period sums and constants packed into one buffer),
or, with ``INS_COSIM_NATIVE=0`` or where the library does not load, the numpy function
itself. The two agree to rounding (numpy's matrix products may go through BLAS, the C code
sums in index order; ``tests/models/test_native_propagate.py``). The numpy function stays the
readable statement of the model; the C code repeats it formula by formula.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.transfer_model import PeriodSums, StateLayout, propagate
from cosim.models import native
from cosim.models.constants import E2, OMEGA_IE, A

FloatArray = NDArray[np.float64]

#: Offsets in the kernel's parameter block (``cosim/alignment/transfer_model.c``): ``T``,
#: ``lat``, ``height``, then the constants ``OMEGA_IE, A, E2``.
PARAM_T, PARAM_LAT, PARAM_HEIGHT, PARAM_CONSTANTS = 0, 1, 2, 3
#: Where the arrays of :class:`PeriodSums` start, back to back in this order (the last
#: three for the flexure layout only).
PARAM_SUMS = 6
_PARAM_ARRAYS = (
    ("dv_f", (3,)),
    ("c_int", (3, 3)),
    ("v_int", (3,)),
    ("w_in", (3,)),
    ("cor", (3,)),
    ("m0", (3, 6)),
    ("m1", (3, 6)),
    ("phi_flex", (6, 6)),
)
PARAM_SIZE = 99


class CompiledPropagate:
    """``propagate(x, sums, layout)`` of one layout, computed by ``transfer_propagate``.

    Parameters
    ----------
    kernel : ctypes function
        ``transfer_propagate`` of the compiled library (:func:`make_propagate`).
    layout : StateLayout
        19- or 13-state layout.

    Notes
    -----
    The buffers are allocated once: the parameter block (refilled at every call, through
    views shaped like the sums) and, per stack shape, an input and an output stack (the
    points are copied in, which also makes them C-contiguous float64). Each call returns
    a copy of the output: the UKF keeps its propagated sigma points (``sigmas_f``), which
    the next period would otherwise overwrite.
    """

    #: Stack shapes whose buffers are kept (the bank's, the fine UKF's, single points).
    MAX_SHAPES = 8

    def __init__(self, kernel: Any, layout: StateLayout) -> None:
        self.layout = layout
        self._kernel = kernel
        self._n = layout.n
        self._flexure = int(layout.flexure)
        self._par = par = np.zeros(PARAM_SIZE)
        par[PARAM_CONSTANTS : PARAM_CONSTANTS + 3] = (OMEGA_IE, A, E2)
        self._par_ptr = native.pointer(par)
        edges = np.cumsum([PARAM_SUMS, *(int(np.prod(s)) for _, s in _PARAM_ARRAYS)]).tolist()
        views = [
            par[lo:hi].reshape(shape)
            for (_, shape), lo, hi in zip(_PARAM_ARRAYS, edges[:-1], edges[1:], strict=True)
        ]
        self._sum_views = tuple(zip((name for name, _ in _PARAM_ARRAYS), views, strict=True))
        if not layout.flexure:
            self._sum_views = self._sum_views[:5]
        self._stacks: dict[tuple[int, ...], tuple[FloatArray, FloatArray, int, int, int]] = {}

    def _stack(self, shape: tuple[int, ...]) -> tuple[FloatArray, FloatArray, int, int, int]:
        """Input and output buffers (and their addresses, point count) for ``shape``."""
        n = self._n
        if not shape or shape[-1] != n:
            raise ValueError(
                f"propagate: expected states of size {n} on the last axis, got {shape}"
            )
        if len(self._stacks) >= self.MAX_SHAPES:
            self._stacks.clear()
        x_buf, out = np.zeros(shape), np.zeros(shape)
        entry = (x_buf, out, native.pointer(x_buf), native.pointer(out), x_buf.size // n)
        self._stacks[shape] = entry
        return entry

    def pack(self, sums: PeriodSums) -> int:
        """Fill the kernel's parameter block with the period's sums; return its address.

        Also for other kernels that call ``transfer_propagate`` themselves (the fine UKF's
        period, :mod:`cosim.alignment.transfer_ukf_native`).

        Parameters
        ----------
        sums : PeriodSums
            The period's sums (with ``m0``, ``m1`` and ``phi_flex`` for the flexure layout).

        Returns
        -------
        int
            Address of the block (:data:`PARAM_SIZE` doubles, the layout of
            ``cosim/alignment/transfer_model.c``), valid while this object lives.

        Raises
        ------
        ValueError
            The flexure layout's ``m0``, ``m1`` or ``phi_flex`` is None.
        """
        par = self._par
        par[PARAM_T] = sums.T
        par[PARAM_LAT] = sums.lat
        par[PARAM_HEIGHT] = sums.height
        for name, view in self._sum_views:
            value = getattr(sums, name)
            if value is None:  # numpy would assign NaN
                raise ValueError(f"propagate: the flexure layout needs sums.{name}, got None")
            view[...] = value
        return self._par_ptr

    def __call__(self, x: ArrayLike, sums: PeriodSums) -> FloatArray:
        """The error state(s) at the end of the period (see :func:`propagate`).

        Parameters
        ----------
        x : array_like, shape (..., n)
            Error state(s) at the start of the period.
        sums : PeriodSums
            The mechanisation's integrals over the period (with ``m0``, ``m1`` and
            ``phi_flex`` for the flexure layout).

        Returns
        -------
        ndarray, shape (..., n)
            A new array.

        Raises
        ------
        ValueError
            The last axis of ``x`` is not the layout's state size, or the flexure
            layout's ``m0``, ``m1`` or ``phi_flex`` is None.
        """
        if type(x) is not np.ndarray:
            x = np.asarray(x, dtype=np.float64)
        stack = self._stacks.get(x.shape)
        if stack is None:
            stack = self._stack(x.shape)
        x_buf, out, x_ptr, out_ptr, m = stack
        np.copyto(x_buf, x)
        self._kernel(x_ptr, out_ptr, self.pack(sums), m, self._n, self._flexure)
        return out.copy()


def make_propagate(layout: StateLayout) -> Callable[[ArrayLike, PeriodSums], FloatArray]:
    """The UKF's process model for ``layout``: compiled where it can run, else numpy.

    Call it where the filter is built (not at import): :func:`cosim.models.native.kernel`
    reads ``INS_COSIM_NATIVE`` then.

    Parameters
    ----------
    layout : StateLayout
        19- or 13-state layout.

    Returns
    -------
    callable ``f(x, sums) -> ndarray``
        ``x`` of shape (..., n), :class:`PeriodSums` of the period; the result has the
        shape of ``x``. A :class:`CompiledPropagate` when the library has
        ``transfer_propagate``, else ``propagate(x, sums, layout)`` (same numbers to
        rounding).
    """
    kernel = native.kernel("transfer_propagate")
    if kernel is None:

        def numpy_propagate(x: ArrayLike, sums: PeriodSums) -> FloatArray:
            return propagate(x, sums, layout)

        return numpy_propagate
    return CompiledPropagate(kernel, layout)
