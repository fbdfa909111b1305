"""Unit parsing: pint notations, kinds, gauge and offset units."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneumafit.campaign import parse_unit, parse_value
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.units import UnitError, from_si, split_header, to_si

EXHAUST = 101_325.0


@pytest.mark.parametrize(
    ("value", "kind", "si"),
    [
        ("32 mm", "length", 0.032),
        ("6 bar", "pressure", 6e5),
        ("20 degC", "temperature", 293.15),
        ("68 degF", "temperature", 293.15),
        ("20 cm^3", "volume", 20e-6),
        ("60 V/m", "proportional gain", 60.0),
        ("4 V s/m", "derivative gain", 4.0),
        ("90 deg", "angle", math.pi / 2),
        ("10 ms", "time", 0.01),
        ("5 g/s", "mass flow", 0.005),
        ("1e5", "pressure", 1e5),  # bare number in a string: SI
        (0.032, "length", 0.032),  # bare TOML number: SI
        (17, "mass", 17.0),
        ("6 barg", "pressure", 6e5 + EXHAUST),
        ("6 bar (gauge)", "pressure", 6e5 + EXHAUST),
        ("10 psig", "pressure", 10 * 6894.757293168361 + EXHAUST),
        ("-50 kPag", "pressure", -5e4 + EXHAUST),
        ("6 bara", "pressure", 6e5),
        ("6 bar (absolute)", "pressure", 6e5),
        # data-sheet and logger notations of the reference (since 2026-12-04)
        ("6 bar(g)", "pressure", 6e5 + EXHAUST),
        ("6 bar (g)", "pressure", 6e5 + EXHAUST),
        ("600 kPa(g)", "pressure", 6e5 + EXHAUST),
        ("6 bar gauge", "pressure", 6e5 + EXHAUST),
        ("6 bar(a)", "pressure", 6e5),
        ("20 °C", "temperature", 293.15),
    ],
)
def test_parse_value(value: object, kind: str, si: float) -> None:
    assert parse_value(value, kind, exhaust_pressure=EXHAUST) == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize(
    ("value", "kind", "found"),
    [
        ("6 bar", "length", '"6 bar" (a pressure)'),
        ("32 furlongz", "length", '"32 furlongz" ("furlongz" is not a known unit)'),
        ("mm", "length", '"mm" (no number in front)'),
        ("6 kgg", "mass", '"6 kgg" ("kgg" is not a known unit)'),
        ("3 mmg", "length", '"3 mmg" ("mmg" is not a known unit)'),
        (True, "length", "True (a bool)"),
        (float("nan"), "length", "nan (not a finite number)"),
        ([1, 2], "length", "[1, 2] (a list)"),
        # pint reads "C" as the coulomb (before 2026-12-04 said without the hint)
        (
            "20 C",
            "temperature",
            '"20 C" (unit "C" (a quantity of dimension [current] * [time]); "C" is the coulomb: '
            'degrees Celsius are "degC" or "°C")',
        ),
        ("3 mm(g)", "length", '"3 mm(g)" (gauge applies to pressures only)'),
    ],
)
def test_parse_value_errors(value: object, kind: str, found: str) -> None:
    with pytest.raises(UnitError) as info:
        parse_value(value, kind, exhaust_pressure=EXHAUST)
    assert info.value.found == found


def test_gauge_needs_exhaust() -> None:
    with pytest.raises(UnitError, match="exhaust_pressure"):
        parse_value("6 barg", "pressure")


def test_gauge_marker_only_on_pressures() -> None:
    with pytest.raises(UnitError, match="applies to pressures only"):
        parse_unit("mm (gauge)", "length")


def test_kg_is_not_a_gauge_unit() -> None:
    unit = parse_unit("kg", "mass")
    assert not unit.gauge and unit.plain_text == "kg"
    assert parse_unit("psig").plain_text == "psi"


def test_array_conversion_with_offsets() -> None:
    kelvin = to_si(np.array([-40.0, 0.0, 100.0]), parse_unit("degC"))
    np.testing.assert_allclose(kelvin, [233.15, 273.15, 373.15])
    np.testing.assert_allclose(from_si(kelvin, parse_unit("degF")), [-40.0, 32.0, 212.0])
    barg = parse_unit("barg")
    absolute = to_si([0.0, 1.0], barg, exhaust_pressure=EXHAUST)
    np.testing.assert_allclose(absolute, [EXHAUST, EXHAUST + 1e5])
    np.testing.assert_allclose(from_si(absolute, barg, exhaust_pressure=EXHAUST), [0.0, 1.0])


@pytest.mark.parametrize(
    ("cell", "parts"),
    [
        ("p_P [bar]", ("p_P", "bar")),
        ("  Pos [mm] ", ("Pos", "mm")),
        ("u [V s/m]", ("u", "V s/m")),
        ("p [bar (gauge)]", ("p", "bar (gauge)")),
        ("x []", ("x", "")),
        ("p_P", None),
        ("p_P [bar", None),
        ("[bar]", None),
        ("a [b] [c]", None),
    ],
)
def test_split_header(cell: str, parts: tuple[str, str] | None) -> None:
    assert split_header(cell) == parts


def test_parameter_files_and_options_read_units_as_campaigns_do() -> None:
    """ "32mm" and "7 barg" are accepted in a parameter file (and an option)
    exactly as in a campaign; a unit of another dimension is named."""
    from pneumafit.campaign.units import UnitError, parse_quantity, parse_value
    from pneumafit.parameters_io import parse_parameters

    _, values = parse_parameters(
        {"parameters": {"bore": "32mm", "supply_pressure": "6 barg", "exhaust_pressure": "1 bar",
                        "lambda": "15 W/m^2/K"}}
    )  # fmt: skip
    assert values["bore"] == pytest.approx(parse_value("32 mm", "length"))
    assert values["supply_pressure"] == pytest.approx(7.0e5)  # gauge over the file's 1 bar
    assert values["lambda"] == pytest.approx(15.0)
    assert parse_quantity("1 kHz", "Hz") == pytest.approx(1e3)
    assert parse_quantity("4 V s/m", "V*s/m") == pytest.approx(4.0)
    with pytest.raises(UnitError, match="a pressure, not m"):
        parse_quantity("6 bar", "m")
    with pytest.raises(PneumafitInputError, match=r"parameters\.bore.*no number in front"):
        parse_parameters({"parameters": {"bore": "mm 32"}})
