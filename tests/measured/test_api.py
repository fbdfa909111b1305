"""The workbench from Python (pneumafit.api): fit, save, load, discover in a few lines.

Recovery-kind data, not an inverse crime: the synthetic bench of
test_friction_fit (a tanh friction law growing with pressure, which the fitted
laws only approximate, on a finer grid, with sensor noise); here only the
plumbing is judged: that the objects pass from one step to the next and that
a fit in memory, a loaded one and a path give the same discovery.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from test_friction_fit import synthetic_campaign

import pneumafit as pf
from pneumafit.campaign.errors import PneumafitInputError


def test_fit_save_load_discover(tmp_path: Path) -> None:
    campaign = synthetic_campaign()
    fit = pf.fit(campaign, "friction", mcmc=False, seed=4)
    assert isinstance(fit, pf.FitResult) and fit.seed == 4
    fit.save(tmp_path / "fit.json")
    saved = pf.load_fit(tmp_path)
    assert isinstance(saved, pf.SavedFit) and saved.seed == 4
    assert saved.values["friction_coulomb"] == pytest.approx(
        fit.parameters["friction_coulomb"].value, rel=1e-12
    )
    in_memory = pf.discover(campaign, fit)
    from_file = pf.discover(campaign, tmp_path / "fit.json")
    # the synthetic friction grows with pressure (1.5e-5 N/Pa): discovery must say so
    assert "seal_friction_coefficient" in in_memory.effect_parameters
    assert in_memory.selected == from_file.selected
    assert in_memory.rmse_after == from_file.rmse_after
    # results read in a notebook: short reprs, summaries, tables
    for obj in (fit, saved, in_memory):
        assert len(repr(obj)) < 300, repr(obj)
        assert repr(obj).split("(")[0] in obj.summary()
    assert in_memory.statement in in_memory.summary()
    frame = fit.to_dataframe()
    assert frame.loc["friction_coulomb", "value"] == fit.parameters["friction_coulomb"].value
    assert {"unit", "interval_lower", "interval_upper", "fixed"} <= set(frame.columns)
    assert saved.to_dataframe().loc["friction_coulomb", "unit"] == "N"
    assert "<table" in fit._repr_html_() and "<table" in saved._repr_html_()


def test_bad_model_and_options_are_named() -> None:
    campaign = synthetic_campaign()
    with pytest.raises(PneumafitInputError, match="model: expected one of"):
        pf.fit(campaign, "isothermal")
    with pytest.raises(PneumafitInputError, match="law: expected no such option"):
        pf.fit(campaign, "convection", law="lugre")


def test_friction_mcmc_shows_progress_and_reports_its_median() -> None:
    """A friction-test MCMC says where it is (it was silent for minutes on the seals)."""
    from pneumafit.progress import Reporter

    lines: list[str] = []
    fit = pf.fit(synthetic_campaign(), "friction", mcmc=True, steps=60, walkers=16,
                 progress=Reporter(lines.append, interval=0.0))  # fmt: skip
    assert any(line.startswith("mcmc friction") for line in lines), lines
    # estimate and interval from the same posterior: the chain's median, as the chamber
    # fits report it (the joint optimum of Kidney_lc's F_c sat on its bound 0, outside
    # the chain's own 90 % interval [0.07, 2.45] N)
    for p in fit.parameters.free:
        assert p.uncertainty == "mcmc" and p.value == p.median, p
    assert not fit.quality.outside_interval
