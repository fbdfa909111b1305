"""The exchange area's convention: a heat law's extension ``heat_area_ends``.

The paper leaves the area A(y) of eqs. 6-7 unwritten; the kernel counts the
heads, the piston faces and the rod with the share c (1: every wall, 0: the
bore wall only, physics.geometry). Tests of two kinds:

- geometry against the independently written truth simulator's own area
  conventions (virtual_rig.truth.heat.exchange_area): c = 1 is its ``full``
  and c = 0 its ``barrel_only``, at every position;
- recovery without an inverse crime: charge/discharge tests of both
  chambers recorded by the truth simulator (LSODA at rtol 1e-8, sensor noise,
  its own valve, leak, probe and heat-area laws), fitted with flow tests on
  the demo plan. A barrel-only truth must make the heat stage free c and land
  near 0; a full-area truth must leave c at 1 or near it.
"""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.campaign.model import Campaign
from pneumafit.errors import PneumafitInputError
from pneumafit.identification import FitOptions, ParameterSet, identify
from pneumafit.models.parts import HeatLaw, register_heat_law
from pneumafit.models.structure import ModelStructure
from pneumafit.physics.geometry import exchange_areas
from pneumafit.virtual_rig import VirtualRig
from pneumafit.virtual_rig.truth import reference_quantities
from pneumafit.virtual_rig.truth.heat import exchange_area

AREA = "heat_area_ends"


@pytest.mark.parametrize(("ends", "convention"), [(1.0, "full"), (0.0, "barrel_only")])
def test_the_two_conventions_are_the_truth_simulators(ends: float, convention: str) -> None:
    """Exact to rounding (rel 1e-12): the same formulas written twice."""
    bore, rod, stroke, v0p, v0n = 0.032, 0.012, 0.16, 1.9e-5, 2.3e-5
    for y in np.linspace(0.0, stroke, 7):
        a_p, a_n = exchange_areas(y, stroke, bore, rod, v0p, v0n, ends)
        assert a_p == pytest.approx(
            exchange_area(convention, "P", y, bore, rod, stroke, v0p), rel=1e-12
        )
        assert a_n == pytest.approx(
            exchange_area(convention, "N", y, bore, rod, stroke, v0n), rel=1e-12
        )


def test_the_area_is_an_extension_held_at_one() -> None:
    """Used by the laws with a wall exchange, fixed at 1 until a test frees it."""
    for model in ("convection", "constant-lambda"):
        assert AREA in ModelStructure(model).parameter_names
        ps = ParameterSet.for_model(model)
        assert ps[AREA].value == 1.0 and ps[AREA].fixed
    assert AREA not in ModelStructure("polytropic").parameter_names


def test_an_extension_outside_the_table_is_refused() -> None:
    law = HeatLaw(name="toy-area", code=97, parameters=("lambda",), description="toy",
                  label="toy", colour="k", order=9, extensions=("no_such_parameter",))  # fmt: skip
    with pytest.raises(PneumafitInputError, match="no_such_parameter"):
        register_heat_law(law)


def _chamber_tests(preset: str, seed: int, plan: str = "demo") -> tuple[Campaign, float]:
    """The flow and charge/discharge tests of truth ``preset`` on test plan
    ``plan``, and the truth's full-area equivalent lambda at the reference
    state (W/m^2/K)."""
    rig = VirtualRig(truth=preset, seed=seed)
    full = rig.campaign(plan)
    kept = [r for r in full.recordings if r.kind in ("flow", "charge", "discharge")]
    truth = reference_quantities(rig.truth, rig.parameters)["lambda_full_area_equivalent"]
    camp = Campaign(path=None, name=preset, description="", rig=full.rig, recordings=kept)
    return camp, float(truth)


def _full_area_lambda(result: object) -> float:
    return float(result.metrics["lambda_reference"]["full_area_equivalent"]["value"])


# slow job (44 s); its twin on a full-area rig stays in the default suite
@pytest.mark.slow
def test_a_bore_wall_only_rig_gets_its_area() -> None:
    """Truth ``mixed``: heat over the bore wall only (c = 0). The heat stage
    keeps the extension and c ends below 0.15 (measured 0.000-0.000 on seeds
    1-3 after the joint stage, 0.003-0.019 after the heat stage; 0.15 is 15 %
    of the heads, faces and rod, where a rod-side residual of 11x came from
    the whole of them), and chamber N's charge test, 11.5x the noise with c
    held at 1 on the whole demo plan, is within 3x (the issue's target;
    measured 1.59-1.63x), and lambda A_P at the reference state is the
    truth's within the issue's 25 % (measured +0.7 to +0.9 %; -17 % with c
    held at 1)."""
    campaign, lam = _chamber_tests("mixed", 2)
    result = identify(campaign, options=FitOptions(mcmc=False), seed=2)
    heat = result.stage("heat")
    assert "convention kept" in heat.note
    assert result.parameters[AREA].value < 0.15
    ratios = {
        (c.recording, c.channel): c.ratio for c in result.quality.channels if c.fitted
    }  # fmt: skip
    assert ratios[("charge_N_1.h5", "p_N")] < 3.0
    # lambda A as the truth's, within the 25 %
    assert _full_area_lambda(result) == pytest.approx(lam, rel=0.25)


def test_a_full_area_rig_keeps_its_area() -> None:
    """Truth ``demo-clean``: every wall exchanges heat (c = 1). c stays at 1
    (not needed) or within 0.25 of it (the issue's 25 % for its figures;
    measured on seeds 1-3 of demo-clean and power-valve: not needed, with
    effective gains 0.5-6.8 against the test's 11.96; at the valve's
    confidence, 5.4, demo-clean seed 1 kept it at 0.999); lambda A_P within
    25 % (measured -0.1 to 0.0 %)."""
    campaign, lam = _chamber_tests("demo-clean", 2)
    result = identify(campaign, options=FitOptions(mcmc=False), seed=2)
    assert abs(result.parameters[AREA].value - 1.0) <= 0.25
    assert _full_area_lambda(result) == pytest.approx(lam, rel=0.25)


def test_one_chambers_tests_hold_the_area() -> None:
    """The sparse plan tests chamber P only: the area's convention is held at
    1 and the note says why. Freed there, it traded with the heat law
    (table-valve-asym seed 2: kept at 0.69, then 1.19 in [0, 3], the fit
    recordings' worst from 10.6x to 20.3x the noise)."""
    campaign, _ = _chamber_tests("mixed", 2, "sparse")
    assert {r.chamber for r in campaign.recordings if r.kind != "flow"} == {"P"}
    result = identify(campaign, options=FitOptions(mcmc=False), seed=2)
    assert "cover one chamber" in result.stage("heat").note
    assert result.parameters[AREA].value == 1.0 and result.parameters[AREA].fixed
