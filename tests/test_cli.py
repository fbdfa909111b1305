"""The command line as a user runs it: exit status, messages, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneumafit.campaign import read_recording

DEMO = Path(__file__).resolve().parents[1] / "data" / "demo"


def cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pneumafit.cli", *args],
        capture_output=True, text=True, cwd=cwd, timeout=600,
    )  # fmt: skip


@pytest.fixture
def params_file(tmp_path: Path) -> Path:
    path = tmp_path / "params.json"
    path.write_text(json.dumps({"model": "convection", "parameters": {
        "bore": "32 mm", "rod": "20 mm", "supply_pressure": "7 bar", "xi": 0.4}}))  # fmt: skip
    return path


def test_simulate_charge_writes_a_campaign_recording(tmp_path, params_file):
    out = tmp_path / "charge.h5"
    res = cli("simulate", str(params_file), "--kind", "charge", "--chamber", "N",
              "--position", "100 mm", "--duration", "2 s", "--out", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "exergy" in res.stdout and "mass drawn from supply" in res.stdout
    rec = read_recording(out, kind="charge", chamber="N", piston_position=0.1)
    assert rec.n_samples == 2001
    assert rec.channels["p_N"][0] == pytest.approx(1.013e5)
    assert rec.channels["p_N"].max() > 6e5  # filled towards the 7 bar supply
    assert np.all(rec.channels["y"] == pytest.approx(0.1))


def test_simulate_step(tmp_path, params_file):
    out = tmp_path / "step.h5"
    res = cli("simulate", str(params_file), "--kind", "step", "--y-ref", "300 mm",
              "--duration", "2 s", "--out", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    rec = read_recording(out, kind="step")
    assert abs(rec.channels["y"][-1] - 0.30) < 0.01  # reached the reference


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--kind", "jump"], "--kind"),
        (["--kind", "step", "--y-ref", "3 bar"], "--y-ref"),
        (["--kind", "charge", "--chamber", "Q"], "--chamber"),
    ],
)
def test_simulate_bad_options_are_messages(tmp_path, params_file, args, needle):
    res = cli("simulate", str(params_file), "--out", str(tmp_path / "x.h5"), *args)
    assert res.returncode == 2
    assert needle in res.stderr and "Traceback" not in res.stderr + res.stdout
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("{not json", "line 1"),
        ('{"parameters": {"bore": "6 bar"}}', "parameters.bore"),
        ('{"parameters": {"bogus": 1}}', "bogus"),
        ('{"model": "isothermal"}', "model"),
    ],
)
def test_bad_parameter_files_are_messages(tmp_path, content, needle):
    path = tmp_path / "p.json"
    path.write_text(content)
    res = cli("simulate", str(path), "--kind", "charge", "--out", str(tmp_path / "x.h5"))
    assert res.returncode == 2
    assert needle in res.stderr and "p.json" in res.stderr
    assert "Traceback" not in res.stderr + res.stdout


def test_check_demo_is_clean_and_bad_campaign_fails(tmp_path):
    res = cli("check", str(DEMO))
    assert res.returncode == 0, res.stdout
    assert "valid campaign: 0 errors" in res.stdout
    res = cli("check", str(tmp_path))
    assert res.returncode == 1
    assert "campaign.toml" in res.stdout + res.stderr
    assert "Traceback" not in res.stdout + res.stderr


def test_rig_quick_campaign_and_bad_effect(tmp_path):
    out = tmp_path / "camp"
    res = cli("rig", "--out", str(out), "--protocol", "quick", "--seed", "5")
    assert res.returncode == 0, res.stdout + res.stderr
    assert (out / "campaign.toml").exists() and (out / "truth.json").exists()
    assert cli("check", str(out)).returncode == 0
    res = cli("rig", "--out", str(tmp_path / "b"), "--protocol", "quick", "--effect", "warp=1")
    assert res.returncode == 2
    assert "warp" in res.stdout + res.stderr and "Traceback" not in res.stdout + res.stderr


def test_run_on_a_missing_campaign_is_a_message(tmp_path):
    """The main job end to end is tests/test_pipeline.py (the demo with MCMC
    takes minutes); here only its command-line contract."""
    res = cli("run", str(tmp_path / "nowhere"), "--out", str(tmp_path / "run"))
    assert res.returncode != 0
    assert "nowhere" in res.stdout + res.stderr
    assert "Traceback" not in res.stdout + res.stderr
    assert not (tmp_path / "run" / "fits").exists()


def test_linear_and_export_use_a_fitted_valve_map(tmp_path):
    """A fit of the measured valve map (fit.json ``structure.valve = "map"``)
    is analysed and exported with its map: here a map whose supply knots are
    three times those of the ISO valve it was sampled from, so that the map's
    equilibrium differs from the ISO parameters' (by 12 % in P_P)."""
    from pneumafit.analysis import equilibrium
    from pneumafit.models.parameters import parameter_dict, parameter_vector
    from pneumafit.physics.valve_map import MAP_CS_NAMES, map_from_iso

    base = parameter_dict(parameter_vector({}))
    knots = map_from_iso(base)
    knots.update({k: 3.0 * knots[k] for k in MAP_CS_NAMES[7:]})
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps({"model": "convection", "structure": {"valve": "map"},
                               "parameters": knots}))  # fmt: skip
    out = tmp_path / "lin"
    res = cli("linear", str(fit), "--positions", "250 mm", "--out", str(out))
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "linear.json").read_text())
    expected = equilibrium(parameter_vector(knots), 0.25, valve="map")
    assert doc["valve"] == "map"
    assert doc["positions"][0]["equilibrium"]["p_P"] == pytest.approx(expected.p_P, rel=1e-9)
    assert expected.p_P > 1.05 * equilibrium(parameter_vector({}), 0.25).p_P
    res = cli("export", str(fit), "--format", "json", "--out", str(tmp_path / "x.json"))
    assert res.returncode == 0, res.stderr
    exported = json.loads((tmp_path / "x.json").read_text())
    assert exported["source"]["valve"] == "map"
    assert exported["parameters"][MAP_CS_NAMES[10]]["value"] == pytest.approx(
        knots[MAP_CS_NAMES[10]]
    )


@pytest.mark.parametrize("args", [[], ["bogus"], ["simulate"], ["rig"]])
def test_usage_errors_have_no_traceback(args):
    res = cli(*args)
    assert res.returncode == 2
    assert "Traceback" not in res.stdout + res.stderr


def test_linear_and_design_commands(tmp_path, params_file):
    out = tmp_path / "lin"
    res = cli("linear", str(params_file), "--positions", "50,250,450 mm", "--out", str(out))
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "linear.json").read_text())
    assert [round(e["y"], 3) for e in doc["positions"]] == [0.05, 0.25, 0.45]
    assert len(doc["positions"][1]["order_6"]["A"]) == 6
    assert (out / "open_loop_poles.png").stat().st_size > 10_000
    res = cli("design", str(params_file), "--order", "4", "--w0", "15", "--out", str(out))
    assert res.returncode == 0, res.stderr
    design = json.loads((out / "design_4.json").read_text())
    assert len(design["schedule"]) == 25 and all(e["K"] for e in design["schedule"])
    res = cli("design", str(params_file), "--order", "5", "--out", str(out))
    assert res.returncode == 2 and "--order" in res.stderr
    res = cli("linear", str(params_file), "--positions", "0.9", "--out", str(out))
    assert res.returncode == 2 and "--positions" in res.stderr
