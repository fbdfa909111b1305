"""The committed demo campaigns (data/demo with an undeclared leak, data/demo-clean
without it): complete, small, readable, reproducible."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import read_campaign, validate_campaign
from pneumafit.cli.rig import run_rig
from pneumafit.virtual_rig import (
    DEMO_CLEAN_TRUTH_PRESET,
    DEMO_SEED,
    DEMO_TRUTH,
    DEMO_TRUTH_PRESET,
    TRUTH_FILE,
)
from pneumafit.virtual_rig.truth import PRESETS

DATA = Path(__file__).resolve().parents[2] / "data"
DEMO = DATA / "demo"
DEMO_CLEAN = DATA / "demo-clean"
BOTH = pytest.mark.parametrize(
    ("folder", "preset"), [(DEMO, DEMO_TRUTH_PRESET), (DEMO_CLEAN, DEMO_CLEAN_TRUTH_PRESET)],
    ids=["demo", "demo-clean"],
)  # fmt: skip


@BOTH
def test_demo_is_small(folder: Path, preset: str) -> None:
    total = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    assert total < 10 * 1024 * 1024


@BOTH
def test_demo_reads_cleanly_and_has_the_tests(folder: Path, preset: str) -> None:
    assert validate_campaign(folder) == []
    campaign = read_campaign(folder)
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


@BOTH
def test_demo_truth_and_readme(folder: Path, preset: str) -> None:
    """Both demos are recorded on an independent truth: laws the fitted
    models do not share (power-law valve paths, a Gaussian leak, LuGre
    friction with seal pressure, lagging probes), no round value."""
    truth = json.loads((folder / TRUTH_FILE).read_text())
    assert truth["seed"] == DEMO_SEED and truth["model"]["effects"] == {}
    independent = truth["truth_model"]
    assert independent["config"]["name"] == preset
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
    readme = (folder / "README.md").read_text()
    assert f"independent truth `{preset}`" in readme
    for name in ("bore", "rod", "moving_mass", "supply_pressure"):
        assert f"`{name}`" in readme
    toml = (folder / "campaign.toml").read_text()
    assert TRUTH_FILE not in toml and "leak" not in toml.lower()


def test_only_the_demo_has_the_undeclared_leak() -> None:
    """data/demo = data/demo-clean's rig plus an external leak that
    campaign.toml does not declare and README.md and truth.json do."""
    leak = json.loads((DEMO / TRUTH_FILE).read_text())["truth_model"]["config"]
    clean = json.loads((DEMO_CLEAN / TRUTH_FILE).read_text())["truth_model"]["config"]
    assert leak["external_leak"]["model"] == "orifice" and "external_leak" not in clean
    same = ("valve", "friction", "heat", "probe", "end_stops")
    assert {k: leak[k] for k in same} == {k: clean[k] for k in same}
    assert "undeclared effect" in (DEMO / "README.md").read_text()
    assert "external leak" not in (DEMO_CLEAN / "README.md").read_text()
    # the same protocol, seed and sensors: only the leak differs
    demo, ref = (read_campaign(f) for f in (DEMO, DEMO_CLEAN))
    for a, b in zip(demo.recordings, ref.recordings, strict=True):
        assert (a.file, a.kind, a.role) == (b.file, b.kind, b.role)
        if a.kind == "flow":  # the valve's static characteristic: no leak in it
            np.testing.assert_array_equal(a.channels["qm_" + (a.chamber or "P")],
                                          b.channels["qm_" + (b.chamber or "P")])  # fmt: skip


@pytest.mark.slow
@BOTH
def test_demo_is_what_the_rig_makes_today(
    folder: Path, preset: str, tmp_path: Path, console: Console
) -> None:
    """Regenerate with ``pneumafit rig --out data/demo --seed 2026 --truth demo``
    (``data/demo-clean``, ``--truth demo-clean``) if this fails.

    A change of the independent truth simulator, its ``demo`` or
    ``demo-clean`` preset or the rig's protocol and sensors changes the
    demos; the rig's own numbers must then be reviewed and the demos
    regenerated.
    """
    out = tmp_path / "demo"
    assert run_rig(out, [], seed=DEMO_SEED, console=console, truth=preset) == 0
    assert (out / "campaign.toml").read_text() == (folder / "campaign.toml").read_text()
    fresh, committed = read_campaign(out), read_campaign(folder)
    # The same seed gives the same noise draws; what may differ is the truth
    # simulator's adaptive LSODA (rtol 1e-8), whose step choices follow the
    # platform's last bits (libm, BLAS, CPU): a regeneration on another
    # machine moved the pressures by up to 0.34 Pa (7e-7 relative) and
    # flipped the encoder count of 2 of 4501 samples. Allowed: 1 % of each
    # sensor's noise sigma (truth.json "sensors"), and for the quantised
    # position one count on at most 0.1 % of the samples. A change of the
    # physics, the preset, the protocol or the sensors moves whole records
    # by more than that.
    sensors = json.loads((folder / TRUTH_FILE).read_text())["sensors"]
    sigma = {"p": sensors["pressure_noise"], "T": sensors["temperature_noise"],
             "qm": sensors["flow_noise"]}  # fmt: skip
    count = sensors["position_resolution"]
    for a, b in zip(fresh.recordings, committed.recordings, strict=True):
        assert set(a.channels) == set(b.channels), a.file
        for name in a.channels:
            diff = np.abs(a.channels[name] - b.channels[name])
            where = f"{a.file} {name}"
            if name == "y":
                moved = diff > 1e-9 * count
                assert np.all(diff <= count * (1.0 + 1e-6)), where
                assert moved.sum() <= max(1, int(1e-3 * diff.size)), where
            elif name.split("_")[0] in sigma:
                assert diff.max() <= 0.01 * sigma[name.split("_")[0]], where
            else:  # commands and references: the controller sees the same pressures
                np.testing.assert_allclose(a.channels[name], b.channels[name], rtol=1e-5,
                                           atol=1e-5, err_msg=where)  # fmt: skip
