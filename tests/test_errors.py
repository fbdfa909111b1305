"""One error family: every error pneumafit raises on purpose is a PneumafitError."""

from __future__ import annotations

from pathlib import Path

import pytest

import pneumafit as pf
from pneumafit.campaign.errors import CampaignError
from pneumafit.campaign.errors import PneumafitInputError as CampaignInputError
from pneumafit.campaign.units import UnitError
from pneumafit.pipeline import StageFailed
from pneumafit.virtual_rig.virtual import RigError


def test_input_and_computation_errors_share_one_base() -> None:
    assert CampaignInputError is pf.PneumafitInputError
    for cls in (CampaignError, UnitError):
        assert issubclass(cls, pf.PneumafitInputError) and issubclass(cls, ValueError)
    for cls in (RigError, StageFailed):
        assert issubclass(cls, pf.PneumafitComputationError) and issubclass(cls, RuntimeError)
    assert issubclass(pf.PneumafitInputError, pf.PneumafitError)
    assert issubclass(pf.PneumafitComputationError, pf.PneumafitError)


def test_a_bad_campaign_is_caught_as_a_pneumafit_error(tmp_path: Path) -> None:
    with pytest.raises(pf.PneumafitError, match=r"campaign\.toml"):
        pf.read_campaign(tmp_path)
