"""The external leak shared unequally by the chambers (``external_leak_split``).

A real cylinder leaks to the atmosphere where its seals are worn: the rod
seal only on the rod side, a fitting on one side. The catalog's laminar leak
had one conductance for both chambers; the split s shares it as
G_P = G (1 + s), G_N = G (1 - s): s = 0 is the former law bit for bit, s = -1
a leak of chamber N alone. Checked on the kernel's rates (each chamber's leak
term scales by its share, the mass leaving is the sum of the two) and
against the compiled FMU port in tests/test_fmu.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.discovery import get_effect
from pneumafit.models import EFFECT_SLOTS, ModelStructure, kernel, parameter_vector
from pneumafit.models.layout import SPECS, X_ME, X_PN, X_PP, P
from test_seal_effects import CLOSED, _rhs, _state

LEAK = ModelStructure("constant-lambda").with_effects(external_leakage=1)
BASE = ModelStructure("constant-lambda")
G = 4e-11  # kg/s/Pa


def _leak_rates(split: float) -> tuple[float, float, float]:
    """(dP_P/dt, dP_N/dt) due to the leak alone, and the exhausted mass flow."""
    x = _state(0.2, 0.0, 6.0e5, 3.0e5)
    values = {**CLOSED, "external_leak_conductance": G, "external_leak_split": split}
    with_leak, _ = _rhs(LEAK, values, x, 0)
    without, _ = _rhs(BASE, values, x, 0)
    d = with_leak - without
    return d[X_PP], d[X_PN], d[X_ME]


def test_the_split_is_a_registered_effect_parameter() -> None:
    spec = SPECS["external_leak_split"]
    assert (spec.default, spec.lower, spec.upper) == (0.0, -1.0, 1.0)
    assert EFFECT_SLOTS["external_leakage"][1] == ("external_leak_conductance",
                                                   "external_leak_split")  # fmt: skip
    par = get_effect("external_leakage").parameter("external_leak_split")
    assert par.signed and par.neutral == 0.0 and par.typical == 0.0


def test_zero_split_is_the_shared_conductance_bit_for_bit() -> None:
    x = _state(0.2, 0.3, 6.0e5, 3.0e5)
    values = {**CLOSED, "external_leak_conductance": G}
    a, _ = _rhs(LEAK, values, x, 1)
    b, _ = _rhs(LEAK, {**values, "external_leak_split": 0.0}, x, 1)
    assert np.array_equal(a, b)


@pytest.mark.parametrize("split", [-1.0, -0.4, 0.5, 1.0])
def test_each_chamber_leaks_its_share(split: float) -> None:
    dp_p0, dp_n0, qe0 = _leak_rates(0.0)
    dp_p, dp_n, qe = _leak_rates(split)
    assert dp_p == pytest.approx((1.0 + split) * dp_p0, rel=1e-9, abs=1e-9)
    assert dp_n == pytest.approx((1.0 - split) * dp_n0, rel=1e-9, abs=1e-9)
    # the mass leaving is each chamber's G_X (P_X - P_atm): P_P - P_atm = 5 bar and
    # P_N - P_atm = 2 bar weigh the shares 5 : 2
    w_p, w_n = 6.0e5 - CLOSED["exhaust_pressure"], 3.0e5 - CLOSED["exhaust_pressure"]
    assert qe == pytest.approx(
        qe0 * ((1 + split) * w_p + (1 - split) * w_n) / (w_p + w_n), rel=1e-9
    )


def test_a_split_outside_its_range_is_refused() -> None:
    for bad in (-1.01, 1.5):
        with pytest.raises(ValueError, match="external_leak_split"):
            parameter_vector({**CLOSED, "external_leak_split": bad})
        p = parameter_vector(CLOSED)
        p[P["external_leak_split"]] = bad  # past the table's check: the kernel's own
        assert not kernel.check_parameters(p)
