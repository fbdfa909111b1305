"""Recovery of known parameters from virtual-rig campaigns.

The rig's truth is richer than the fitted model (Sutherland air properties
in the rig and in the fitted convection structure, but DP5 at 0.1 ms, sensor
noise, per-sensor pressure offsets, a 10-um position encoder, slow
temperature sensors, gas warmer than the wall at the start of step tests).
The campaigns are the small protocol of conftest.py (2.5-s tests).

Not tested here, because it does not hold yet: that the 90 % intervals
contain the truth for each seed. Measured over seeds 1, 2, 4-7 (MCMC):
friction_static 6/6, friction_viscous 5/6, friction_coulomb 4/6, xi, beta
and stribeck_velocity 3/6 (docs/identification.md, Limitations).
"""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.identification import FitOptions, identify

CHECKED = ("xi", "beta", "friction_static", "friction_coulomb", "friction_viscous",
           "stribeck_velocity")  # fmt: skip


def test_point_estimates_recover_the_truth(small: tuple) -> None:
    """Joint least squares (no MCMC) on the shared campaign (seed 3).

    Tolerances are the accuracy a rig engineer needs, far above the
    estimates' standard deviations (xi 0.6 %, beta 0.15 %, friction 5e-5 to
    5e-4, conductances 1e-4) and far below the errors of the mistakes they
    guard against (air properties at the wall temperature: xi -70 %; the
    valve from the flow tests alone: xi -50 %).
    """
    _, campaign, truth = small
    result = identify(campaign, "convection", options=FitOptions(mcmc=False), seed=0)
    p = result.parameters
    assert p["xi"].value == pytest.approx(truth["xi"], rel=0.05)
    assert p["beta"].value == pytest.approx(truth["beta"], rel=0.02)
    for name in ("friction_static", "friction_coulomb", "friction_viscous"):
        assert p[name].value == pytest.approx(truth[name], rel=1e-3)
    assert p["stribeck_velocity"].value == pytest.approx(truth["stribeck_velocity"], rel=1e-2)
    for name in ("valve_C_supply", "valve_C_exhaust", "valve_C_leak", "valve_overlap"):
        assert p[name].value == pytest.approx(truth[name], rel=1e-2)
    heat = result.stage("joint").estimate
    assert heat is not None and heat.success
    assert p["xi"].uncertainty == "laplace" and p["xi"].interval_90 is not None


@pytest.mark.parametrize(
    "model", ["constant-lambda", pytest.param("polytropic", marks=pytest.mark.slow)]
)
def test_other_structures_converge_on_the_same_data(small: tuple, model: str) -> None:
    """Both simpler structures converge (every stage's least squares ends on a
    termination test, finite likelihood). The polytropic joint fit takes
    ~1000 iterations (~3 min): it cannot follow the thermal relaxation, and
    k ends on its adiabatic bound 1.4 (the fast phases are adiabatic)."""
    _, campaign, truth = small
    result = identify(campaign, model, options=FitOptions(mcmc=False), seed=0)
    for stage in result.stages:
        assert stage.estimate is not None and stage.estimate.success, stage.name
        assert np.isfinite(stage.estimate.log_likelihood)
    if model == "constant-lambda":
        # the rig's lambda varies 0..~27 W/m^2/K; its heat-weighted mean is ~15
        assert 5.0 < result.parameters["lambda"].value < 30.0
    else:
        assert 1.0 < result.parameters["k"].value <= 1.4
    # friction stays near the truth with the simpler heat laws (within 5 %)
    for name in ("friction_static", "friction_coulomb"):
        assert result.parameters[name].value == pytest.approx(truth[name], rel=0.05)
