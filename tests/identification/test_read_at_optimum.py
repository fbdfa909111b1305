"""The friction laws' log-likelihoods are read where they are compared: at the
optimum, with the profiled initial states linearised there
(``staged._read_at_optimum``), whatever start the stage linearised them at."""

from __future__ import annotations

import pytest

from pneumafit.campaign import Campaign
from pneumafit.identification import LogLikelihood, ParameterSet, Problem, fit_structure
from pneumafit.identification.optimise import fit_least_squares
from pneumafit.identification.staged import _read_at_optimum, with_initial_states

FRICTION = ("friction_static", "friction_coulomb", "friction_viscous")


def _problem(campaign: Campaign, truth: dict[str, float]) -> tuple[Problem, ParameterSet]:
    structure = fit_structure("convection", friction="switch")
    steps = [r for r in campaign.by_role("fit") if r.kind == "step"]
    prob = Problem(steps, structure, truth, channels=("p_P", "p_N", "y"), initial_nuisance=True)
    ps = ParameterSet.for_model(structure, campaign.rig.as_parameters())
    ps = ps.with_values({k: v for k, v in truth.items() if k in ps.names}).only_free(FRICTION)
    return prob, with_initial_states(ps, prob, truth, free=False)


def test_the_reading_does_not_depend_on_the_stages_start(
    small: tuple[object, Campaign, dict[str, float]],
) -> None:
    """Two problems of the same step tests, linearised at two starts (the
    truth's friction, and its levels 30 % high and the viscous 30 % low), give
    the same optimum two readings: the offset of their starts' making (it
    exists: 648 measured, asserted above 1). Read at the optimum, both give the same value
    (to round-off: the same simulations, 1e-9 relative), and it is the
    reading of a problem linearised at the optimum from the start.

    Kind: a property of the likelihood's bookkeeping on the rig's own laws
    (the switch model of the small campaign); no recovery is claimed."""
    _, campaign, truth = small
    truth = dict(truth)
    moved = {**truth, "friction_static": truth["friction_static"] * 1.3,
             "friction_coulomb": truth["friction_coulomb"] * 1.3,
             "friction_viscous": truth["friction_viscous"] * 0.7}  # fmt: skip
    a, ps = _problem(campaign, truth)
    b, _ = _problem(campaign, truth)
    a.linearize({**ps.values(), **truth})
    b.linearize({**ps.values(), **moved})
    est = fit_least_squares(LogLikelihood(a, ps), starts=[moved], max_nfev=6)
    point = {**truth, **est.parameters.values()}
    read_a = LogLikelihood(a, est.parameters).at_values(point)
    read_b = LogLikelihood(b, est.parameters).at_values(point)
    assert abs(read_a - read_b) > 1.0
    at_a = _read_at_optimum(a, est, truth)
    at_b = _read_at_optimum(b, est, truth)
    assert at_a == pytest.approx(at_b, rel=1e-9)
    c, _ = _problem(campaign, truth)
    c.linearize(point)
    assert LogLikelihood(c, est.parameters).at_values(point) == pytest.approx(at_a, rel=1e-9)
    assert _read_at_optimum(a, None, truth) == float("-inf")
