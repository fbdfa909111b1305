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


@pytest.mark.parametrize(
    ("error", "code", "shown", "hidden"),
    [
        (pf.PneumafitComputationError("the reference solve failed"), 1, "failed:", "internal"),
        (pf.PneumafitInputError("campaign.toml: rig.bore: expected ..."), 2, "error:", "internal"),
        (ZeroDivisionError("a bug"), 1, "internal error", "failed:"),
    ],
)
def test_the_command_line_tells_failed_work_from_bad_input_and_bugs(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    error: Exception, code: int, shown: str, hidden: str,
) -> None:  # fmt: skip
    """Plumbing: a computation error is the work failing (exit 1, no bug hint),
    an input error is bad input (exit 2), anything else is a bug (exit 1)."""
    import importlib

    cli_app = importlib.import_module("pneumafit.cli.app")  # the module, not the typer app

    def boom() -> None:
        raise error

    monkeypatch.setattr(cli_app, "app", boom)
    monkeypatch.delenv("PNEUMAFIT_DEBUG", raising=False)
    with pytest.raises(SystemExit) as exit_info:
        cli_app.main()
    err = capsys.readouterr().err
    assert exit_info.value.code == code
    assert shown in err and hidden not in err
