"""The fine-alignment UKF's period (seed 001, stage 2) in one compiled call.

In stage 2 :class:`cosim.alignment.transfer_filter.TransferFilter` runs, once per filter
period, ``ukf.predict`` (sigma points through the error model, the heading-aware mean and
residual, plus ``Q``) and ``ukf.update`` with the velocity match, then the NIS.
:class:`CompiledFinePeriod` does the same in ``transfer_ukf_period``
(``models/native/transfer_ukf.c``), with the error model of ``transfer_propagate``
(:mod:`cosim.alignment.transfer_native`), and leaves the UKF's attributes as its own two
calls leave them (``x``, ``P``, ``x_prior``, ``P_prior``, ``z_pred``, ``S``, ``K``, ``y``,
``x_post``, ``P_post``). The numpy UKF stays the fallback and the readable statement: the
two agree to rounding (``tests/test_native_ukf.py``). Where a Cholesky factorisation
fails, the compiled call writes nothing and the numpy calls run, so the error raised is
the UKF's own.
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.estimation import UnscentedKalmanFilter
from models import native

FloatArray = NDArray[np.float64]

_P, _D, _I = ctypes.c_void_p, ctypes.c_double, ctypes.c_int
_ARGTYPES = [_P, _P, _P, _P, _P, _P, _P, _P, _D, _I, _I, _I, _P]


class CompiledFinePeriod:
    """Predict + update + NIS of the fine UKF in one call of ``transfer_ukf_period``.

    Parameters
    ----------
    kernel : ctypes function
        ``transfer_ukf_period`` (:func:`make_fine_period`).
    propagate : CompiledPropagate
        The compiled error model; its parameter block (:meth:`pack`) is the kernel's.
    n : int
        State size (19 or 13).
    flexure : bool
        Whether the layout has the flexure states.
    heading : int
        Index of the heading error in the state.
    """

    def __init__(self, kernel: Any, propagate: Any, n: int, flexure: bool, heading: int) -> None:
        self._kernel = kernel
        self._model = propagate
        self.n, self._flexure, self._heading = n, int(flexure), int(heading)
        self._x = np.zeros(n)
        self._P = np.zeros((n, n))
        self._Q = np.zeros((n, n))
        self._R = np.zeros((3, 3))
        self._z = np.zeros(3)
        self._out = np.zeros(n + n * n + 3 + 9 + 3 * n + 3 + 1)
        self._weights: tuple[Any, ...] | None = None
        self._ptrs = [native.pointer(a) for a in (self._x, self._P, self._Q, self._R, self._z)]
        self._out_ptr = native.pointer(self._out)

    def _bind(self, ukf: UnscentedKalmanFilter) -> tuple[Any, ...]:
        points = ukf.points
        key = (id(points), points.alpha, points.beta, points.kappa)
        if self._weights is None or self._weights[0] != key:
            Wm = np.ascontiguousarray(points.Wm, dtype=np.float64)
            Wc = np.ascontiguousarray(points.Wc, dtype=np.float64)
            self._weights = (key, Wm, Wc, native.pointer(Wm), native.pointer(Wc))
        return self._weights

    def __call__(
        self, ukf: UnscentedKalmanFilter, T: float, Q: FloatArray, R: FloatArray, z: FloatArray,
        sums: Any,
    ) -> float | None:  # fmt: skip
        """One period on ``ukf``: its state becomes the posterior.

        Parameters
        ----------
        ukf : UnscentedKalmanFilter
            The fine UKF (Merwe sigma points, the transfer filter's models).
        T : float
            Period [s] (the sums' own).
        Q : ndarray, shape (n, n)
            Process noise over the period.
        R : ndarray, shape (3, 3)
            Velocity-match noise [(m/s)^2].
        z : ndarray, shape (3,)
            Velocity match, slave minus master, NED [m/s].
        sums : PeriodSums
            The period's mechanisation sums (with the flexure matrices where used).

        Returns
        -------
        float or None
            The NIS ``y^T S^-1 y``; None when a Cholesky factorisation failed (nothing was
            changed: run the numpy UKF, which raises its own error).
        """
        n = self.n
        _, Wm, Wc, wm_ptr, wc_ptr = self._bind(ukf)
        self._x[:] = ukf.x
        self._P[...] = ukf.P
        self._Q[...] = Q
        self._R[...] = R
        self._z[:] = z
        par = self._model.pack(sums)
        spread = float(ukf.points.spread)
        code = self._kernel(
            *self._ptrs[:5], par, wm_ptr, wc_ptr, spread, n, self._flexure, self._heading,
            self._out_ptr,
        )  # fmt: skip
        if code != 0:
            return None
        o = self._out.copy()
        i = 0
        x_prior = o[i : i + n]
        i += n
        P_prior = o[i : i + n * n].reshape(n, n)
        i += n * n
        ukf.z_pred = o[i : i + 3]
        ukf.S = o[i + 3 : i + 12].reshape(3, 3)
        i += 12
        ukf.K = o[i : i + 3 * n].reshape(n, 3)
        i += 3 * n
        ukf.y = o[i : i + 3]
        nis = float(o[i + 3])
        ukf.x_prior, ukf.P_prior = x_prior.copy(), P_prior.copy()
        ukf.x = self._x.copy()
        ukf.P = self._P.copy()
        ukf.x_post, ukf.P_post = ukf.x.copy(), ukf.P.copy()
        return nis


def make_fine_period(propagate: Any, n: int, flexure: bool, heading: int) -> Any:
    """The compiled fine-UKF period, or None where the numpy UKF must run.

    Parameters
    ----------
    propagate : callable
        The filter's error model from :func:`cosim.alignment.transfer_native.make_propagate`
        (compiled only when it is a ``CompiledPropagate``, whose parameter block the
        kernel reads).
    n : int
        State size.
    flexure : bool
        Whether the layout has the flexure states.
    heading : int
        Index of the heading error.

    Returns
    -------
    CompiledFinePeriod or None
        None with ``INS_COSIM_NATIVE=0``, without the library, or when ``propagate`` is
        the numpy one.
    """
    if not hasattr(propagate, "pack"):
        return None
    kernel = native.declare("transfer_ukf_period", _ARGTYPES, ctypes.c_int)
    if kernel is None:
        return None
    return CompiledFinePeriod(kernel, propagate, n, flexure, heading)
