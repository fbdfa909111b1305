"""The committed demo campaign (data/demo): complete, small, readable, reproducible."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import read_campaign, validate_campaign
from pneumafit.rig import DEMO_SEED, DEMO_TRUTH, DEMO_TRUTH_PRESET, TRUTH_FILE, run_rig
from pneumafit.rig.truth import PRESETS

DEMO = Path(__file__).resolve().parents[2] / "data" / "demo"


def test_demo_is_small() -> None:
    total = sum(p.stat().st_size for p in DEMO.rglob("*") if p.is_file())
    assert total < 10 * 1024 * 1024


def test_demo_reads_cleanly_and_has_the_tests() -> None:
    assert validate_campaign(DEMO) == []
    campaign = read_campaign(DEMO)
    kinds = [r.kind for r in campaign.recordings]
    assert kinds.count("flow") >= 2
    assert kinds.count("charge") + kinds.count("discharge") >= 4
    assert kinds.count("step") >= 3
    held_out = campaign.by_role("validate")
    assert {r.kind for r in held_out} >= {"step"}
    assert {r.kind for r in held_out} & {"charge", "discharge"}
    assert all(r.controller is not None for r in campaign.by_kind("step"))
    csv = [r for r in campaign.recordings if r.file.endswith(".csv")]
    assert csv and csv[0].columns
    assert {csv[0].units[c] for c in ("y", "p_P", "T_P")} == {"mm", "bar", "degC"}
    rig = campaign.rig
    assert (rig.moving_mass, rig.stroke, rig.supply_pressure) == (17.0, 0.5, 7.0e5)


def test_demo_truth_and_readme() -> None:
    """The demo is recorded on the independent truth ``demo``: laws the fitted
    models do not share (power-law valve paths, a Gaussian leak, LuGre
    friction with seal pressure, lagging probes), no round value."""
    truth = json.loads((DEMO / TRUTH_FILE).read_text())
    assert truth["seed"] == DEMO_SEED and truth["model"]["effects"] == {}
    independent = truth["truth_model"]
    assert independent["config"]["name"] == DEMO_TRUTH_PRESET
    assert independent["config"]["valve"]["supply"] == PRESETS["demo"]["valve"]["supply"]
    assert independent["config"]["friction"]["model"] == "lugre"
    for name in independent["parameters_used"]:
        if name in DEMO_TRUTH:  # the rig's geometry and conditions
            assert truth["parameters"][name] == DEMO_TRUTH[name]
    ref = independent["reference_quantities"]
    for name in ("lambda_reference", "friction_static", "friction_coulomb"):
        assert ref[name] != round(ref[name]), name
    # a heat-transfer coefficient like the paper's constant 15 W/m^2/K
    assert 10.0 < truth["diagnostics"]["lambda_equivalent"] < 20.0
    readme = (DEMO / "README.md").read_text()
    assert f"independent truth `{DEMO_TRUTH_PRESET}`" in readme
    for name in ("bore", "rod", "moving_mass", "supply_pressure"):
        assert f"`{name}`" in readme
    assert TRUTH_FILE not in (DEMO / "campaign.toml").read_text()


@pytest.mark.slow
def test_demo_is_what_the_rig_makes_today(tmp_path: Path, console: Console) -> None:
    """Regenerate with ``pneumafit rig --out data/demo --seed 2026 --truth demo``
    if this fails.

    A change of the independent truth simulator, its ``demo`` preset or the
    rig's protocol and sensors changes the demo; the rig's own numbers must
    then be reviewed and the demo regenerated.
    """
    out = tmp_path / "demo"
    assert run_rig(out, [], seed=DEMO_SEED, console=console, truth=DEMO_TRUTH_PRESET) == 0
    assert (out / "campaign.toml").read_text() == (DEMO / "campaign.toml").read_text()
    fresh, committed = read_campaign(out), read_campaign(DEMO)
    for a, b in zip(fresh.recordings, committed.recordings, strict=True):
        for name in a.channels:
            # 1e-9 relative: file round trip and unit conversion, not physics
            np.testing.assert_allclose(a.channels[name], b.channels[name], rtol=1e-9, err_msg=name)
