"""A signed effect vanishes within its negligible departure, not within 10 %
of its range.

The refit loop refuses an effect whose principal parameter ends where the
effect vanishes ("the gain came from the other parameters"). For a signed
parameter that zone was 10 % of the half range on its side of the neutral
value: an area factor within 2 % of 1. A bore 0.8 % wider than declared
(area +1.6 %, 0.26 mm on 32 mm) was then refused although the refit found it
to 0.3 % and every channel improved. The area factor's zone is now a bore's
H11 tolerance, 1 % of the area (``SealEffect.negligible``); the friction
asymmetry keeps the generic margin.

The slow cases are only partly free of inverse crime: the independent
truth's ``fit-laws`` preset shares the model's valve and heat law families;
what differs is its own barrel code (a bore the campaign does not declare),
its LuGre bristle friction and its DP5 solver with sensor noise. Discovery
protocol of the loop tests, convection fitted without MCMC. The case that
found the defect had every part different (docs/effects.md, "A wider bore
called vanished"), but its demo-plan run takes 12 minutes.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from discovery_helpers import TRUTH_CASES, _fit_laws_truth, run_case

from pneumafit.discovery import EFFECTS
from pneumafit.discovery.refit import _vanishing


def _model(name: str, value: float) -> object:
    return SimpleNamespace(structure=SimpleNamespace(effects={}), values={name: value})


@pytest.mark.parametrize(
    ("effect", "value", "vanished"),
    [
        ("effective_area", 1.009, True),  # inside the 1 % tolerance
        ("effective_area", 0.991, True),
        ("effective_area", 1.011, False),  # the old 2 % margin called this vanished
        ("effective_area", 1.018, False),
        ("friction_asymmetry", 0.049, True),  # generic: 10 % of the 0.5 half range
        ("friction_asymmetry", -0.051, False),
    ],
)
def test_a_signed_effect_vanishes_within_its_negligible_departure(
    effect: str, value: float, vanished: bool
) -> None:
    name = EFFECTS[effect].parameter_names()[0]
    assert (_vanishing(_model(name, value), effect) is not None) is vanished  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("bore", "kept"),
    [
        # k_A 1.01632: refused as vanished before, kept now; measured
        # 2026-11-29: k_A 1.01627, held-out 2300 -> 605 Pa
        (0.03226, True),
        # k_A 1.0050, inside the tolerance: nothing is kept (measured: the
        # residual is at the noise, nothing refitted)
        (0.03208, False),
    ],
)
def test_a_bore_beyond_its_tolerance_is_found_and_one_within_it_is_not(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    bore: float,
    kept: bool,
) -> None:
    name = f"truth:bore_{bore * 1e5:.0f}"
    monkeypatch.setitem(TRUTH_CASES, name, _fit_laws_truth(barrel={"bore": bore}))
    res = run_case(tmp_path_factory.mktemp("bore"), name).result
    steps = "; ".join(f"{s.effect}: {s.reason}" for s in res.steps)
    if not kept:
        assert "effective_area" not in res.selected, steps
        return
    assert res.selected[:1] == ["effective_area"], steps
    truth = (bore / 0.032) ** 2
    # the departure from 1 within 10 % (measured 0.3 %: 0.01627 for 0.01632;
    # the loop tests allow 20 % for the independent truth's effects, whose
    # size the model's other laws can bend; here only the bristles differ)
    assert res.final.values["area_factor"] - 1.0 == pytest.approx(truth - 1.0, rel=0.1)
    # at least halved, as the loop tests ask of a found effect
    assert res.final.pressure_rmse("validate") < 0.5 * res.base.pressure_rmse("validate")
