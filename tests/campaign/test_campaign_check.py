"""``check_campaign`` exit status and robustness; reading never modifies files."""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rich.console import Console

from pneumafit.campaign import (
    CampaignError,
    check_campaign,
    inspect_campaign,
    read_campaign,
    validate_campaign,
)
from pneumafit.campaign import reader as reader_module


def run_check(path: Path) -> tuple[int, str]:
    out = io.StringIO()
    status = check_campaign(path, console=Console(file=out, width=200))
    return status, " ".join(out.getvalue().split())


def snapshot(folder: Path) -> dict[str, tuple[str, int]]:
    """Every file's SHA-256 and modification time, and nothing else there."""
    return {
        str(p.relative_to(folder)): (
            hashlib.sha256(p.read_bytes()).hexdigest(),
            p.stat().st_mtime_ns,
        )
        for p in sorted(folder.rglob("*"))
    }


def test_check_valid_campaign(campaign_dir: Path) -> None:
    status, text = run_check(campaign_dir)
    assert status == 0
    assert "Campaign test-rig" in text
    for fragment in (
        "charge_P_1.h5",
        "p_N [bar (gauge)]",
        "y [mm]",
        "u_N [derived: -u_P]",
        "chamber P, piston at 250 mm",
        "kp=60 V/m",
        "valid campaign: 0 errors",
    ):
        assert fragment in text


def test_check_warnings_only_is_valid(campaign_dir: Path) -> None:
    toml = campaign_dir / "campaign.toml"
    toml.write_text(toml.read_text().replace("version = 1", 'version = 1\nauthor = "me"'))
    status, text = run_check(campaign_dir)
    assert status == 0
    assert "warning: campaign.toml: author: expected a top-level key" in text
    assert "valid campaign: 0 errors, 1 warning" in text


def test_check_invalid_campaign(campaign_dir: Path) -> None:
    (campaign_dir / "flow_N_1.csv").write_text("time [s],u_N [V]\n0,1\n")
    status, text = run_check(campaign_dir)
    assert status == 1
    assert "error: flow_N_1.csv: time: expected at least 2 samples" in text
    assert "invalid campaign" in text
    assert "step_1.csv" in text  # the readable recordings are still listed


def test_check_prints_to_stdout_by_default(campaign_dir: Path, capsys) -> None:
    assert check_campaign(campaign_dir) == 0
    assert "valid campaign" in capsys.readouterr().out


def test_check_missing_folder(tmp_path: Path) -> None:
    status, text = run_check(tmp_path / "nope")
    assert status == 1
    assert "no such folder" in text


def test_unexpected_exception_becomes_a_problem(campaign_dir: Path, monkeypatch) -> None:
    def broken(*args, **kwargs):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(reader_module, "_read_csv", broken)
    status, text = run_check(campaign_dir)
    assert status == 1
    assert "error: step_1.csv: expected a readable recording" in text
    assert "RuntimeError: disk on fire" in text
    problems = validate_campaign(campaign_dir)
    assert {p.file for p in problems} == {"flow_N_1.csv", "step_1.csv", "free_1.csv"}


def test_check_never_raises_even_if_inspection_fails(campaign_dir: Path, monkeypatch) -> None:
    def broken(path):
        raise MemoryError("out of memory")

    monkeypatch.setattr("pneumafit.campaign.check.inspect_campaign", broken)
    status, text = run_check(campaign_dir)
    assert status == 1
    assert "MemoryError: out of memory" in text


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    toml_text=st.one_of(
        st.text(max_size=200),
        st.sampled_from(
            [
                "",
                "format = 1",
                "rig = 3\nrecording = 4",
                "[rig]\nbore = []\nrod = {a = 1}",
                "[[recording]]\nfile = 3\nkind = [1]\nrole = {}\nchamber = 2.5",
                '[[recording]]\nfile = "x.csv"\ncontroller = 1\ncolumns = {a = [1], b = {}}',
                '[[recording]]\nfile = "../../etc"\npiston_position = "1 furlong/s"',
            ]
        ),
    ),
    junk=st.binary(max_size=300),
    target=st.sampled_from(["campaign.toml", "charge_P_1.h5", "step_1.csv"]),
)
def test_check_never_raises_on_garbage(
    tmp_path_factory, build_campaign, toml_text: str, junk: bytes, target: str
) -> None:
    folder = build_campaign(tmp_path_factory.mktemp("fuzz"))
    if target == "campaign.toml":
        (folder / target).write_text(toml_text)
    else:
        (folder / target).write_bytes(junk)
    status, _ = run_check(folder)
    assert status == 1  # garbage is never a valid campaign, and never a crash


def test_reading_never_modifies_files(campaign_dir: Path) -> None:
    before = snapshot(campaign_dir)
    read_campaign(campaign_dir)
    validate_campaign(campaign_dir)
    inspect_campaign(campaign_dir)
    run_check(campaign_dir)
    assert snapshot(campaign_dir) == before


@pytest.mark.parametrize("broken", ["campaign.toml", "charge_P_1.h5", "step_1.csv"])
def test_reading_an_invalid_campaign_never_modifies_files(campaign_dir: Path, broken: str) -> None:
    path = campaign_dir / broken
    path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])
    before = snapshot(campaign_dir)
    with pytest.raises(CampaignError):
        read_campaign(campaign_dir)
    run_check(campaign_dir)
    assert snapshot(campaign_dir) == before
