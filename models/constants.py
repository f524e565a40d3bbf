"""Physical constants and unit factors, the one place every model and filter takes them from.

Unit factors convert a value in the named unit to SI: ``2 * ARCMIN`` is 2 arcmin in rad.
``G0`` is standard gravity (the papers' "g" in sensor figures, also the ``g``, ``mg`` and
``ug`` of scenario files), not the local gravity of :mod:`models.earth`.

The WGS-84 ellipsoid and its normal gravity follow NIMA TR8350.2 (3rd ed., 2000).
"""

from __future__ import annotations

import math

# ------------------------------------------------------------------ angle and rate units
#: 1 deg [rad].
DEG = math.pi / 180.0
#: 1 arcmin [rad].
ARCMIN = math.pi / 180.0 / 60.0
#: 1 arcsec [rad].
ARCSEC = math.pi / 180.0 / 3600.0
#: 1 deg/h [rad/s].
DEG_PER_HOUR = math.pi / 180.0 / 3600.0
#: 1 deg/sqrt(h) [rad/sqrt(s)] (angle random walk).
DEG_PER_SQRT_HOUR = math.pi / 180.0 / 60.0

# ------------------------------------------------------------------ acceleration units
#: Standard gravity [m/s2].
G0 = 9.80665
#: 1 ug [m/s2] (also 1 ug/sqrt(Hz) in m/s/sqrt(s)).
MICRO_G = 9.80665e-6
#: 1 ppm [-].
PPM = 1.0e-6

# ------------------------------------------------------------------ WGS-84
#: Semi-major axis [m].
A = 6378137.0
#: Flattening [-].
F = 1.0 / 298.257223563
#: Semi-minor axis [m].
B = A * (1.0 - F)
#: First eccentricity squared [-].
E2 = F * (2.0 - F)
#: Earth's gravitational constant GM (with atmosphere) [m^3/s^2].
GM = 3.986004418e14
#: Earth rotation rate [rad/s].
OMEGA_IE = 7.292115e-5
#: Normal gravity at the equator [m/s^2].
GAMMA_E = 9.7803253359
#: Normal gravity at the poles [m/s^2].
GAMMA_P = 9.8321849378
#: Somigliana's constant k = b gamma_p / (a gamma_e) - 1 [-].
K_SOMIGLIANA = B * GAMMA_P / (A * GAMMA_E) - 1.0
#: m = Omega^2 a^2 b / GM [-].
M_RATIO = OMEGA_IE**2 * A**2 * B / GM
