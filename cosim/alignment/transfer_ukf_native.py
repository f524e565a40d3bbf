"""The fine-alignment UKF's period (seed 001, stage 2) in one compiled call.

In stage 2 :class:`cosim.alignment.transfer_filter.TransferFilter` runs, once per filter
period, ``ukf.predict`` (sigma points through the error model, the heading-aware mean and
residual, plus ``Q``) and ``ukf.update`` with the velocity match, then the NIS.
:class:`CompiledFinePeriod` does the same in ``transfer_ukf_period``
(``cosim/alignment/transfer_ukf.c``), with the error model of ``transfer_propagate``
(:mod:`cosim.alignment.transfer_native`), and leaves the UKF's attributes as its own two
calls leave them (``x``, ``P``, ``x_prior``, ``P_prior``, ``z_pred``, ``S``, ``K``, ``y``,
``x_post``, ``P_post``). The numpy UKF stays the fallback and the readable statement: the
two agree to rounding (``tests/models/test_native_ukf.py``). Where a Cholesky factorisation
fails, the compiled call writes nothing and the numpy calls run, so the error raised is
the UKF's own.

Given the address of a :class:`~cosim.alignment.nav_compiled.CompiledStrapdown`'s state
(``nav``), the same call (``transfer_ukf_fed_period``, ``cosim/alignment/transfer_feedback.c``)
also does the period's closed-loop feedback, the twin of ``TransferFilter._feedback`` and
of the reset that follows it: the mechanisation corrected in place with the posterior,
``ukf.x`` and ``ukf.P`` the state and covariance after the reset (``x_post``, ``P_post``
stay the posterior). One ctypes call per period, instead of some 40 numpy operations
(``tests/models/test_native_feedback.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from cosim.estimation import UnscentedKalmanFilter
from cosim.models import native

FloatArray = NDArray[np.float64]


class CompiledFinePeriod:
    """Predict + update + NIS (+ feedback) of the fine UKF in one compiled call.

    Parameters
    ----------
    kernel : ctypes function
        ``transfer_ukf_period`` (:func:`make_fine_period`).
    fed_kernel : ctypes function
        ``transfer_ukf_fed_period``: the same and the feedback (:func:`make_fine_period`).
    propagate : CompiledPropagate
        The compiled error model; its parameter block (:meth:`pack`) is the kernel's.
    n : int
        State size (19 or 13).
    flexure : bool
        Whether the layout has the flexure states.
    heading : int
        Index of the heading error in the state.
    """

    def __init__(
        self, kernel: Any, fed_kernel: Any, propagate: Any, n: int, flexure: bool, heading: int
    ) -> None:
        self._kernel, self._fed_kernel = kernel, fed_kernel
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
        self._m1 = np.zeros((3, 6))
        self._fed = np.zeros(n + n * n)  # x after the reset, reset covariance
        self._m1_ptr, self._fed_ptr = native.pointer(self._m1), native.pointer(self._fed)

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
        sums: Any, nav: int | None = None, m1: FloatArray | None = None,
    ) -> float | None:  # fmt: skip
        """One period on ``ukf``: its state becomes the posterior (or the state after the reset).

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
        nav : int, optional
            Address of a :class:`~cosim.alignment.nav_compiled.CompiledStrapdown`'s state
            (``state_pointer``): feed the posterior back into it as
            ``TransferFilter._feedback`` does; ``ukf.x``, ``ukf.P`` become the state and
            covariance after the reset. None: no feedback.
        m1 : ndarray, shape (3, 6), optional
            Flexure matrix at the period's end (with ``nav`` and the flexure states).

        Returns
        -------
        float or None
            The NIS ``y^T S^-1 y``; None when a Cholesky factorisation failed (nothing was
            changed, the mechanisation neither: run the numpy UKF, which raises its own
            error).
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
        args = (*self._ptrs, par, wm_ptr, wc_ptr, spread, n, self._flexure, self._heading)
        if nav is None:
            code = self._kernel(*args, self._out_ptr)
        else:
            if self._flexure:
                self._m1[...] = m1
            code = self._fed_kernel(*args, self._out_ptr, nav, self._m1_ptr, self._fed_ptr)
        if code != 0:
            return None
        o = self._out.copy()  # the attributes are views of this copy, not of the buffer
        ukf.x_prior = o[:n]
        ukf.P_prior = o[n : n + n * n].reshape(n, n)
        i = n + n * n
        ukf.z_pred = o[i : i + 3]
        ukf.S = o[i + 3 : i + 12].reshape(3, 3)
        i += 12
        ukf.K = o[i : i + 3 * n].reshape(n, 3)
        i += 3 * n
        ukf.y = o[i : i + 3]
        nis = float(o[i + 3])
        ukf.x_post, ukf.P_post = self._x.copy(), self._P.copy()
        if nav is None:
            ukf.x, ukf.P = ukf.x_post.copy(), ukf.P_post.copy()
        else:
            fed = self._fed.copy()
            ukf.x, ukf.P = fed[:n], fed[n:].reshape(n, n)
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
    kernel = native.kernel("transfer_ukf_period")
    fed_kernel = native.kernel("transfer_ukf_fed_period")
    if kernel is None or fed_kernel is None:
        return None
    return CompiledFinePeriod(kernel, fed_kernel, propagate, n, flexure, heading)
