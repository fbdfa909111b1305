"""``pneumafit discover`` as a user runs it: files, schema, bad input."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from pneumafit.cli.discover import discover_command, discovery_document, write_report

pytestmark = pytest.mark.slow

KEYS = (
    "format", "version", "base_model", "candidates", "selected", "rmse_before", "rmse_after",
    "aic_before", "aic_after", "effect_parameters", "unexplained", "statement", "seed",
)  # fmt: skip


def _console() -> Console:
    return Console(file=io.StringIO(), width=200, color_system=None)


def test_report_of_a_found_effect(discovery_cases: object, tmp_path: Path) -> None:
    """discovery.json keeps the schema and the report names the effect with its interval."""
    case = discovery_cases("chamber_leakage")  # type: ignore[operator]
    fit_doc = json.loads(case.fit_path.read_text())
    doc = discovery_document(case.result, case.campaign, case.fit_path, fit_doc)
    written = write_report(tmp_path, doc, case.result, case.campaign)
    names = {p.name for p in written}
    assert {"discovery.json", "discovery.md", "residuals_before.png", "residuals_after.png",
            "candidates.png"} <= names  # fmt: skip
    saved = json.loads((tmp_path / "discovery.json").read_text())
    for key in KEYS:
        assert key in saved, key
    assert saved["format"] == "pneumafit-discovery" and saved["version"] == 1
    assert saved["base_model"] == "convection"
    assert saved["selected"][0] == "chamber_leakage"
    assert saved["candidates"][0]["effect"] == "chamber_leakage"
    for c in saved["candidates"]:
        assert {"inclusion_probability", "variance_explained", "phase_match"} <= set(c["evidence"])
    par = saved["effect_parameters"]["chamber_leak_conductance"]
    lo, hi = par["interval_90"]
    assert lo < par["value"] < hi
    assert saved["aic_after"] < saved["aic_before"]
    for role in ("fit", "validate"):
        assert set(saved["rmse_before"][role]) >= {"p_P", "p_N"}
    text = (tmp_path / "discovery.md").read_text()
    assert "chamber_leakage" in text and "90 % interval" in text


def test_command_on_the_clean_campaign(discovery_cases: object, tmp_path: Path) -> None:
    """The whole command (subprocess): exit 0, nothing selected, files written."""
    case = discovery_cases(None)  # type: ignore[operator]
    out = tmp_path / "rep"
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "discover", str(case.folder), "--fit",
         str(case.fit_path.parent), "--out", str(out), "--seed", "3"],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert res.returncode == 0, res.stdout + res.stderr
    assert "Traceback" not in res.stderr
    doc = json.loads((out / "discovery.json").read_text())
    assert doc["selected"] == [] and doc["unexplained"] is False
    assert doc["seed"] == 3 and doc["effect_parameters"] == {}
    assert (out / "discovery.md").is_file() and (out / "residuals_before.png").is_file()
    assert "round 1" in res.stdout  # progress lines


def _bad(case: object, fit: Path, tmp_path: Path) -> str:
    console = _console()
    code = discover_command(case.folder, fit, tmp_path / "rep", console=console)  # type: ignore[attr-defined]
    assert code == 2
    assert not (tmp_path / "rep" / "discovery.json").exists()
    return console.file.getvalue()  # type: ignore[attr-defined]


def test_missing_fit_file(discovery_cases: object, tmp_path: Path) -> None:
    case = discovery_cases(None)  # type: ignore[operator]
    empty = tmp_path / "nothing"
    empty.mkdir()
    msg = _bad(case, empty, tmp_path)
    assert "--fit" in msg and "fit.json" in msg and "found no file" in msg


def test_fit_of_another_campaign(discovery_cases: object, tmp_path: Path) -> None:
    case = discovery_cases(None)  # type: ignore[operator]
    doc = json.loads(case.fit_path.read_text())
    first = sorted(doc["campaign"]["sha256"])[0]
    doc["campaign"]["sha256"][first] = "0" * 64
    doc["campaign"]["name"] = "another"
    other = tmp_path / "fit.json"
    other.write_text(json.dumps(doc))
    msg = _bad(case, other, tmp_path)
    assert "campaign.sha256" in msg and "another" in msg and first in msg


def test_unknown_model(discovery_cases: object, tmp_path: Path) -> None:
    case = discovery_cases(None)  # type: ignore[operator]
    doc = json.loads(case.fit_path.read_text())
    doc["model"] = "magic"
    other = tmp_path / "fit.json"
    other.write_text(json.dumps(doc))
    msg = _bad(case, other, tmp_path)
    assert "'model'" in msg and "convection" in msg and "'magic'" in msg


def test_not_a_fit_document(discovery_cases: object, tmp_path: Path) -> None:
    case = discovery_cases(None)  # type: ignore[operator]
    other = tmp_path / "fit.json"
    other.write_text("{not json")
    msg = _bad(case, other, tmp_path)
    assert "expected a JSON fit document" in msg
