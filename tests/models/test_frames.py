"""Seed-001 ENU / RFU frames and their conversion to NED / FRD (models.frames)."""

from __future__ import annotations

import math

import numpy as np

from cosim.models import conventions as cv
from cosim.models import frames as fr

RNG = np.random.default_rng(20240611)


def test_enu_ned_conversion() -> None:
    v = RNG.standard_normal(3)
    np.testing.assert_allclose(fr.swap_enu_ned(v), [v[1], v[0], -v[2]])
    np.testing.assert_allclose(fr.swap_enu_ned(fr.swap_enu_ned(v)), v)
    np.testing.assert_allclose(fr.T_NED_ENU @ fr.T_NED_ENU, np.eye(3))
    # Earth rate: ENU [0, W cosL, W sinL] is NED [W cosL, 0, -W sinL].
    lat = 0.5
    np.testing.assert_allclose(
        fr.swap_enu_ned([0.0, math.cos(lat), math.sin(lat)]), [math.cos(lat), 0.0, -math.sin(lat)]
    )


def test_seed001_euler_conversion() -> None:
    # Build the ENU/RFU attitude from its own definition: heading psi about up (ccw),
    # then pitch about the right axis (x_rfu), then roll about the forward axis (y_rfu).
    pitch, roll, psi = 0.1, -0.2, 0.7
    c_rfu_enu = cv.rot_z(psi) @ cv.rot_x(pitch) @ cv.rot_y(roll)
    rpy = fr.enu_euler_to_rpy(pitch, roll, psi)
    np.testing.assert_allclose(fr.swap_enu_ned_dcm(c_rfu_enu), cv.euler_to_dcm(rpy), atol=1e-15)
    np.testing.assert_allclose(fr.swap_enu_ned_dcm(cv.euler_to_dcm(rpy)), c_rfu_enu, atol=1e-15)
    back = fr.rpy_to_enu_euler(rpy)
    np.testing.assert_allclose(back, (pitch, roll, psi))
    # body vectors: RFU forward [0, 1, 0] is FRD [1, 0, 0]
    np.testing.assert_allclose(fr.swap_enu_ned([0.0, 1.0, 0.0]), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(fr.swap_enu_ned([0.0, 0.0, 1.0]), [0.0, 0.0, -1.0])
