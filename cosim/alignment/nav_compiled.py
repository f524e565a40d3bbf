"""The strapdown integrator with its step compiled (``cosim/alignment/strapdown.c``).

:class:`CompiledStrapdown` is a :class:`cosim.alignment.nav.Strapdown` whose state lives in
one float64 buffer that the C step reads and writes in place; its attributes (``C_s_n``,
``v_n``, ``lat``, ...) are properties over that buffer, so every method of the base class
(:meth:`~cosim.alignment.nav.Strapdown.correct`, :meth:`~cosim.alignment.nav.Strapdown.refresh`,
:meth:`~cosim.alignment.nav.Strapdown.mean_attitude`) works on it unchanged. A read gives a
copy (as the base class, whose step binds new arrays, never changes an array it gave out).
Only two-sample increments are compiled; :func:`make_strapdown` returns the numpy class
for table-axis increments, for ``INS_COSIM_NATIVE=0`` and where the library does not load.

The step can also add itself to period sums kept in a second buffer
(:meth:`CompiledStrapdown.step_summed`, :meth:`CompiledStrapdown.sums_into`): the twin of
``nav.step(...)`` followed by :meth:`cosim.alignment.transfer_model.PeriodSums.add`, in one
call. The two paths agree to rounding: the C code sums the three matrix products of a step
in the order k = 0, 1, 2, numpy's may go through BLAS (``tests/alignment/test_nav_compiled.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cosim.alignment.nav import MOVING_BASE, Mechanisation, Strapdown
from cosim.models import native
from cosim.models.constants import E2, GAMMA_E, K_SOMIGLIANA, M_RATIO, OMEGA_IE, A, F

FloatArray = NDArray[np.float64]

#: Buffer layout of ``strapdown.c`` (:attr:`CompiledStrapdown.state_pointer`): vector
#: attribute -> (offset, shape) in doubles; :data:`NAV_SCALARS`: scalar -> offset.
NAV_FIELDS: dict[str, tuple[int, tuple[int, ...]]] = {
    "C_s_n": (0, (3, 3)),
    "v_n": (9, (3,)),
    "v_prev": (12, (3,)),
    "gyro_bias": (17, (3,)),
    "accel_bias": (20, (3,)),
    "C_prev": (23, (3, 3)),
    "phi": (32, (3,)),
    "dv_n": (35, (3,)),
    "w_in": (38, (3,)),
    "cor": (41, (3,)),
    "w_ie": (51, (3,)),
    "_cor_ie": (54, (3,)),
}
NAV_SCALARS = {"lat": 15, "height": 16, "_rm": 57, "_rn": 58, "_tan": 59, "g": 60}
#: Doubles in the state buffer (the previous increments, the step count and the cached
#: navigation-frame rotation follow the fields above: ``strapdown.c``'s header).
NAV_SIZE = 72
#: Period-sum buffer: T, dv_f, c_int (3x3), v_int, w_in T, cor T.
SUMS_SIZE = 22


def _vector(offset: int, shape: tuple[int, ...]) -> property:
    size = int(np.prod(shape))

    def get(self: CompiledStrapdown) -> FloatArray:
        return self._nav[offset : offset + size].copy().reshape(shape)

    def put(self: CompiledStrapdown, value: ArrayLike) -> None:
        self._nav[offset : offset + size] = np.reshape(value, size)

    return property(get, put)


def _scalar(offset: int) -> property:
    def get(self: CompiledStrapdown) -> float:
        return float(self._nav[offset])

    def put(self: CompiledStrapdown, value: float) -> None:
        self._nav[offset] = value

    return property(get, put)


class CompiledStrapdown(Strapdown):
    """:class:`~cosim.alignment.nav.Strapdown` (two-sample increments) stepped in C.

    Parameters
    ----------
    step : ctypes function
        ``strapdown_two_sample_step`` of the compiled library (:func:`make_strapdown`).
    refresh : ctypes function
        ``strapdown_refresh`` (the latitude-dependent constants).
    *args, **kwargs
        Those of :class:`~cosim.alignment.nav.Strapdown`.
    """

    def __init__(self, step: Any, refresh: Any, *args: Any, **kwargs: Any) -> None:
        self._nav = np.zeros(NAV_SIZE)
        self._sums = np.zeros(SUMS_SIZE)
        self._inc = np.zeros(6)
        self._kernel = step
        self._refresh = refresh
        self._earth = np.array([A, E2, OMEGA_IE, GAMMA_E, K_SOMIGLIANA, F, M_RATIO])
        self._earth_ptr = native.pointer(self._earth)
        self._nav_ptr = native.pointer(self._nav)
        self._sums_ptr = native.pointer(self._sums)
        self._dth_ptr = native.pointer(self._inc)
        self._dv_ptr = self._dth_ptr + 3 * self._inc.itemsize
        super().__init__(*args, **kwargs)
        o = self.options
        if o.coning != "two-sample":
            raise ValueError("CompiledStrapdown: only two-sample increments are compiled")
        self._flags = int(o.transport_rate) | 2 * int(o.vertical) | 4 * int(o.midpoint_velocity)
        self._every = int(o.orthonormalise_every)

    @property
    def state_pointer(self) -> int:
        """Address of the state buffer (float64, :data:`NAV_SIZE`; layout :data:`NAV_FIELDS`,
        :data:`NAV_SCALARS`), for kernels that correct the mechanisation in place."""
        return self._nav_ptr

    def refresh(self) -> None:
        """Re-evaluate the latitude-dependent constants (radii, earth rate, gravity) in C.

        ``strapdown_refresh`` repeats the base class's :meth:`~Strapdown.refresh` (with
        :func:`models.earth.R_M`, ``R_N``, ``gravity`` and
        :func:`cosim.alignment.nav.earth_rate`) into the buffer.
        """
        self._refresh(self._nav_ptr, self._earth_ptr)

    def _run(self, dtheta: ArrayLike, dv: ArrayLike, h: float, sums: int | None) -> None:
        inc = self._inc
        inc[:3] = dtheta
        inc[3:] = dv
        self._kernel(self._nav_ptr, sums, self._dth_ptr, self._dv_ptr, h, self._flags, self._every)

    def step(self, dtheta: ArrayLike, dv: ArrayLike, h: float) -> None:  # (the base's doc)
        self._run(dtheta, dv, h, None)

    def step_summed(self, dtheta: ArrayLike, dv: ArrayLike, h: float) -> None:
        """:meth:`step` and add it to this integrator's period sums (:meth:`sums_into`).

        Parameters
        ----------
        dtheta : array_like, shape (3,)
            Angle increment over the step, sensor axes [rad].
        dv : array_like, shape (3,)
            Velocity increment, sensor axes [m/s].
        h : float
            Step [s].
        """
        self._run(dtheta, dv, h, self._sums_ptr)

    def sums_into(self, sums: Any) -> Any:
        """Copy the period sums into a :class:`~cosim.alignment.transfer_model.PeriodSums`.

        Parameters
        ----------
        sums : PeriodSums
            Its ``T``, ``dv_f``, ``c_int``, ``v_int``, ``w_in``, ``cor`` are set (fresh arrays).

        Returns
        -------
        PeriodSums
            ``sums``.
        """
        s = self._sums.copy()
        sums.T = float(s[0])
        sums.dv_f, sums.c_int, sums.v_int = s[1:4], s[4:13].reshape(3, 3), s[13:16]
        sums.w_in, sums.cor = s[16:19], s[19:22]
        return sums

    def clear_sums(self) -> None:
        """Start new period sums (all zero)."""
        self._sums[:] = 0.0


for _name, (_offset, _shape) in NAV_FIELDS.items():
    setattr(CompiledStrapdown, _name, _vector(_offset, _shape))
for _name, _offset in NAV_SCALARS.items():
    setattr(CompiledStrapdown, _name, _scalar(_offset))


def make_strapdown(
    C_s_n: ArrayLike,
    lat: float,
    height: float = 0.0,
    v_n: ArrayLike | None = None,
    *,
    options: Mechanisation = MOVING_BASE,
) -> Strapdown:
    """The compiled integrator where it can run, else the numpy one (same numbers).

    Parameters
    ----------
    C_s_n : array_like, shape (3, 3)
        Initial attitude, sensor to NED.
    lat : float
        Latitude [rad].
    height : float
        Height [m].
    v_n : array_like, shape (3,), optional
        Initial velocity, NED [m/s] (zero).
    options : Mechanisation
        What the integrator does; only ``coning="two-sample"`` is compiled.

    Returns
    -------
    Strapdown
        A :class:`CompiledStrapdown` when ``options.coning == "two-sample"`` and
        :func:`cosim.models.native.kernel` finds the kernel (not with ``INS_COSIM_NATIVE=0``),
        else a :class:`~cosim.alignment.nav.Strapdown`.
    """
    step = refresh = None
    if options.coning == "two-sample":
        step = native.kernel("strapdown_two_sample_step")
        refresh = native.kernel("strapdown_refresh")
    if step is None or refresh is None:
        return Strapdown(C_s_n, lat, height, v_n, options=options)
    return CompiledStrapdown(step, refresh, C_s_n, lat, height, v_n, options=options)
