"""Unit parsing and conversion (cosim.units), against hand-computed factors and the
project's constants (models.constants): a scenario's "2 arcmin" is the models' 2 * ARCMIN."""

from __future__ import annotations

import pytest

from cosim.errors import UnitError
from cosim.models.constants import ARCMIN, ARCSEC, DEG, DEG_PER_HOUR, DEG_PER_SQRT_HOUR, G0, PPM
from cosim.units import conversion_factor, parse_unit, to_unit


@pytest.mark.parametrize(
    "unit, si_unit, factor",
    [
        ("deg", "rad", DEG),
        ("arcmin", "rad", DEG / 60),
        ("arcmin", "rad", ARCMIN),
        ("arcsec", "rad", DEG / 3600),
        ("arcsec", "rad", ARCSEC),
        ("deg/h", "rad/s", DEG / 3600),
        ("deg/h", "rad/s", DEG_PER_HOUR),
        ("deg/sqrt(h)", "rad/sqrt(s)", DEG / 60),
        ("deg/sqrt(h)", "rad/sqrt(s)", DEG_PER_SQRT_HOUR),
        ("g", "m/s2", G0),
        ("ppm", "1", PPM),
        ("ug", "m/s2", 9.80665e-6),
        ("mg", "m/s2", 9.80665e-3),
        ("g", "m/s2", 9.80665),
        ("µg", "m/s2", 9.80665e-6),
        ("ug/sqrt(Hz)", "m/s2/sqrt(Hz)", 9.80665e-6),
        ("ms", "s", 1e-3),
        ("min", "s", 60.0),
        ("h", "s", 3600.0),
        ("km", "m", 1e3),
        ("ppm", "1", 1e-6),
        ("deg/s", "rad/s", DEG),
    ],
)
def test_factors(unit: str, si_unit: str, factor: float) -> None:
    assert conversion_factor(unit, si_unit) == pytest.approx(factor, rel=1e-14)


def test_random_walk_units_relate_as_expected() -> None:
    # 1 deg/h/sqrt(Hz) of rate noise density is 1/60 deg/sqrt(h) of angle random walk
    assert conversion_factor("deg/h/sqrt(Hz)", "deg/sqrt(h)") == pytest.approx(1 / 60, rel=1e-14)


@pytest.mark.parametrize("a, b", [("deg", "1"), ("rad/s", "1/s"), ("rad", "m/s"), ("ug", "m/s")])
def test_incompatible_units_are_refused(a: str, b: str) -> None:
    with pytest.raises(UnitError, match=f"'{a}' cannot be converted to '{b}'"):
        conversion_factor(a, b)


def test_unknown_unit_names_itself_and_gives_examples() -> None:
    with pytest.raises(UnitError, match=r"unknown unit 'furlongz'.*deg/h"):
        parse_unit("furlongz")


def test_to_unit_forms() -> None:
    assert to_unit(0.5, "rad") == 0.5
    assert to_unit(3, "1") == 3
    assert to_unit("12.5 deg", "rad") == pytest.approx(12.5 * DEG, rel=1e-15)
    assert to_unit("-1e-4 g", "m/s2") == pytest.approx(-9.80665e-4, rel=1e-15)
    assert to_unit(["1 deg", 2.0], "rad") == pytest.approx([DEG, 2.0], rel=1e-15)
    assert to_unit({"value": [10, 10, 5], "unit": "cm"}, "m") == pytest.approx([0.1, 0.1, 0.05])
    with pytest.raises(UnitError, match="expected a number with a unit"):
        to_unit("fast", "m/s")
    with pytest.raises(UnitError, match="keys 'value' and 'unit'"):
        to_unit({"val": 1}, "m")
