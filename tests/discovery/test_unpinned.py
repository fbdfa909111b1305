"""An effect whose size the data do not pin is not kept (refit._unpinned).

Kind: the acceptance rule on constructed refits: the figures of a
tabulated-valve truth's quick plan (a supply drop kept at 2.4e4 Pa/(kg/s)
with the 90 % interval [1e4, 1e8], its whole range) against a pinned one."""

from __future__ import annotations

from types import SimpleNamespace

from pneumafit.discovery.catalog import get_effect
from pneumafit.discovery.refit import _unpinned


def _refit(effect: str, interval: tuple[float, float]) -> SimpleNamespace:
    name = get_effect(effect).parameter_names(None)[0]
    par = SimpleNamespace(interval_90=interval)
    return SimpleNamespace(
        parameters={name: par}, structure=SimpleNamespace(effects={effect: None})
    )


def test_an_interval_over_the_whole_range_is_rejected_a_pinned_one_is_not() -> None:
    eff = get_effect("supply_pressure_drop")
    par = eff.parameter(eff.parameter_names(None)[0])
    whole = _unpinned(_refit("supply_pressure_drop", (par.lower, par.upper)),
                      "supply_pressure_drop")  # fmt: skip
    assert whole is not None and "not pinned" in whole and "spans its whole range" in whole
    mid = (par.lower * par.upper) ** 0.5
    assert _unpinned(_refit("supply_pressure_drop", (0.8 * mid, 1.2 * mid)),
                     "supply_pressure_drop") is None  # fmt: skip
    # reaching one bound only (an effect near vanishing): _vanishing's business
    assert _unpinned(_refit("supply_pressure_drop", (par.lower, mid)),
                     "supply_pressure_drop") is None  # fmt: skip
    signed = get_effect("friction_asymmetry")
    sp = signed.parameter(signed.parameter_names(None)[0])
    assert _unpinned(_refit("friction_asymmetry", (sp.lower, sp.upper)),
                     "friction_asymmetry") is not None  # fmt: skip
    assert _unpinned(_refit("friction_asymmetry", (0.1, 0.2)), "friction_asymmetry") is None
