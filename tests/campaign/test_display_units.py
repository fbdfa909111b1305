"""The one display-unit table: its factors are the units' own (checked by pint)."""

from __future__ import annotations

import pytest

from pneumafit.campaign.model import _SI_UNITS, CHANNELS
from pneumafit.campaign.units import DISPLAY_UNITS, display_unit, ureg


@pytest.mark.parametrize("kind", sorted(DISPLAY_UNITS))
def test_factor_is_the_conversion_from_si(kind: str) -> None:
    factor, unit = DISPLAY_UNITS[kind]
    assert ureg.Quantity(1.0, _SI_UNITS[kind]).to(unit).magnitude == pytest.approx(factor)


def test_every_channel_and_comparison_quantity_has_a_display_unit() -> None:
    for name in [*CHANNELS, "pressure", "position", "temperature", "flow"]:
        assert display_unit(name)[1], name
    assert display_unit("qm_P") == display_unit("flow") == (1e3, "g/s")
    assert display_unit("no such channel") == (1.0, "")
