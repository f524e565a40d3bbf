"""Estimators shared by every alignment filter: KF, EKF, UKF and UPF, and their analysis.

Everything here is pure numpy/scipy. Stochastic code never touches global random
state: it takes an explicit :class:`numpy.random.Generator`. Import the public names
from this package; the modules are cut by concern:

========================  ==============================================================
``kalman``                :func:`joseph_update`, :class:`KalmanFilter`,
                          :class:`ExtendedKalmanFilter`
``sigma_points``          the :class:`SigmaPoints` interface, :class:`MerweScaledSigmaPoints`,
                          :class:`JulierSigmaPoints`
``unscented``             :func:`unscented_transform`, :class:`UnscentedKalmanFilter`
``particle``              :func:`systematic_resample`, :class:`UnscentedParticleFilter`
``analysis``              :func:`van_loan`, observability ranks, NEES/NIS, ANEES band
``covariance``            the covariance-analysis loop on :func:`joseph_update` and its
                          history (import from ``cosim.estimation.covariance``)
``angles``                residuals and means with angle components
``checks``, ``linalg``    argument checks, errors, batched linear algebra (internal tools)
``allan``                 Allan variance of sensor records
========================  ==============================================================

Conventions
-----------
* State vectors are 1-D arrays of shape ``(n,)`` (not column vectors); covariances
  are ``(n, n)``. Units are whatever the caller's model uses (SI in this project:
  rad, rad/s, m/s, m/s2); nothing here converts units.
* Batched code (unscented transform, sigma points, the particle filter) works on
  leading axes: a stack of ``N`` states is ``(N, n)``, a stack of covariances
  ``(N, n, n)``, the ``m`` sigma points of that stack ``(N, m, n)`` (``m = 2n + 1``
  for the symmetric sets).
* Process and measurement functions for the UKF/UPF act on the **last axis**:
  ``fx(x, dt)`` receives ``x`` of shape ``(..., n)`` and returns ``(..., n)``;
  ``hx(x)`` returns ``(..., dim_z)``. For a linear model write ``x @ F.T``, not
  ``F @ x``. Pass ``vectorized=False`` to have them called one point at a time
  with ``x`` of shape ``(n,)`` instead (slower, simpler to write).
* Sigma points are duck-typed like filterpy's ``points``: any object with ``n``,
  ``Wm``, ``Wc``, ``num_sigmas()`` and ``sigma_points(x, P)`` plugs into the UKF and
  the UPF (see :class:`SigmaPoints`).
* Residual functions ``residual(a, b)`` return ``a - b`` and must broadcast over
  leading axes; mean functions ``mean_fn(sigmas, weights)`` take
  ``sigmas (..., m, n)`` and ``weights (m,)`` and return ``(..., n)``.
  :func:`angle_residual_fn` and :func:`angle_mean_fn` build both for states or
  measurements that contain angles (heading), so that they are differenced and
  averaged on the circle (wrapped by :func:`models.conventions.wrap_angle`, interval
  (-pi, pi]).
* Covariance updates of the KF/EKF use the Joseph form (:func:`joseph_update`);
  every covariance leaving a filter step is symmetrised as ``(P + P.T) / 2``, which is
  exactly symmetric in floating point.

Errors
------
Bad shapes raise :class:`ShapeError` (a ``ValueError``) whose message names the
argument: ``"z: expected shape (2,), got (3,)"``. Non-callables, non-numeric inputs
and sigma-point objects without the interface raise :class:`EstimatorTypeError` (a
``TypeError``). A covariance that is not positive definite where it has to be raises
:class:`CovarianceError` (a ``numpy.linalg.LinAlgError``, hence also a
``ValueError``). A particle filter whose weights all vanish raises
:class:`DegenerateWeightsError`.
"""

from cosim.estimation.analysis import (
    anees_bounds,
    nees,
    nis,
    observability_matrix,
    observability_rank,
    piecewise_observability_matrix,
    piecewise_observability_rank,
    stripped_condition_holds,
    van_loan,
)
from cosim.estimation.angles import angle_mean, angle_mean_fn, angle_residual, angle_residual_fn
from cosim.estimation.checks import (
    CovarianceError,
    DegenerateWeightsError,
    EstimatorTypeError,
    ShapeError,
)
from cosim.estimation.kalman import ExtendedKalmanFilter, KalmanFilter, joseph_update
from cosim.estimation.particle import UnscentedParticleFilter, systematic_resample
from cosim.estimation.sigma_points import JulierSigmaPoints, MerweScaledSigmaPoints, SigmaPoints
from cosim.estimation.unscented import UnscentedKalmanFilter, unscented_transform

__all__ = [
    "CovarianceError",
    "DegenerateWeightsError",
    "EstimatorTypeError",
    "ExtendedKalmanFilter",
    "JulierSigmaPoints",
    "KalmanFilter",
    "MerweScaledSigmaPoints",
    "ShapeError",
    "SigmaPoints",
    "UnscentedKalmanFilter",
    "UnscentedParticleFilter",
    "anees_bounds",
    "angle_mean",
    "angle_mean_fn",
    "angle_residual",
    "angle_residual_fn",
    "joseph_update",
    "nees",
    "nis",
    "observability_matrix",
    "observability_rank",
    "piecewise_observability_matrix",
    "piecewise_observability_rank",
    "stripped_condition_holds",
    "systematic_resample",
    "unscented_transform",
    "van_loan",
]
