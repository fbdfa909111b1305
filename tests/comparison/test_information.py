"""Pointwise log-likelihood for WAIC/LOO: its terms add up to the identification's
profile log-likelihood (Gaussian and AR(1) noise); no chains, no criteria."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pneumafit.campaign import Campaign
from pneumafit.comparison import fit_values, pointwise_log_likelihood, posterior_criteria
from pneumafit.identification import LogLikelihood, ParameterSet, Problem


@pytest.mark.parametrize("noise", ["gaussian", "ar1"])
def test_pointwise_terms_sum_to_the_likelihood(
    noise: str, blocked_campaign: tuple[Path, Campaign], blocked_fits: dict[str, Path]
) -> None:
    """Row sums equal LogLikelihood's value at two parameter sets (to round-off:
    the same residuals and profiled noise, summed in another order)."""
    _folder, campaign = blocked_campaign
    doc = json.loads((blocked_fits["convection"] / "fit.json").read_text())
    _model, structure, fitted = fit_values(doc, "fit.json")
    # model parameters only: initial states estimated from the data for both sides
    values = {k: v for k, v in fitted.items() if not k.startswith("initial:")}
    recs = list(campaign.by_role("fit"))
    problem = Problem(recs, structure, values, channels=("p_P", "p_N"), noise=noise)
    problem.linearize(values)
    params = ParameterSet.for_model(structure, campaign.rig.as_parameters())
    params = params.with_values(values).only_free(("xi", "beta"))
    like = LogLikelihood(problem, params)
    sets = [dict(values), {**values, "xi": values["xi"] * 1.05}]
    batch = {k: np.array([s[k] for s in sets]) for k in values}
    pointwise = pointwise_log_likelihood(problem, batch, 2)
    assert pointwise.shape == (2, problem.n_data)
    for row, s in zip(pointwise, sets, strict=True):
        assert row.sum() == pytest.approx(like.at_values(s), rel=1e-10, abs=1e-6)
    assert pointwise[0].sum() > pointwise[1].sum()  # the fit beats a 5 % change of xi


def test_no_chains_no_criteria(
    blocked_campaign: tuple[Path, Campaign], blocked_fits: dict[str, Path]
) -> None:
    _folder, campaign = blocked_campaign
    doc = json.loads((blocked_fits["convection"] / "fit.json").read_text())
    out = posterior_criteria(campaign, doc, None)
    assert out == {"available": False, "reason": out["reason"]} and "no MCMC" in out["reason"]
    doc["mcmc"] = {"stages": {}}
    out = posterior_criteria(campaign, doc, blocked_fits["convection"] / "chains.h5")
    assert out["available"] is False and "missing" in out["reason"]
