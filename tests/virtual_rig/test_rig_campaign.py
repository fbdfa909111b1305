"""The virtual rig's campaigns: valid, deterministic, physical, truth kept apart."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import read_campaign, validate_campaign
from pneumafit.cli.rig import run_rig
from pneumafit.models import EFFECT_SLOTS
from pneumafit.simulation import DEFAULT_STEP, Simulator
from pneumafit.virtual_rig import (
    DEMO_TRUTH,
    TRUTH_FILE,
    TRUTH_FORMAT,
    RigRun,
    SensorModel,
    VirtualRig,
    held_input_lag,
    quick_protocol,
)

#: The effect the shared campaign (conftest.quick_folder) hides from campaign.toml.
HIDDEN_EFFECT = "chamber_leakage"
CAMPAIGN_FILES = ("campaign.toml", *(t.file for t in quick_protocol().tests))


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_campaign_validates_without_problems(quick_folder: Path) -> None:
    assert validate_campaign(quick_folder) == []
    campaign = read_campaign(quick_folder)
    assert [r.file for r in campaign.recordings] == list(CAMPAIGN_FILES[1:])
    assert {r.role for r in campaign.recordings} == {"fit", "validate"}
    # the reader ignores the files campaign.toml does not list
    assert {TRUTH_FILE, "README.md"} <= {p.name for p in quick_folder.iterdir()}


def test_csv_recording_keeps_its_own_columns_and_units(quick_folder: Path) -> None:
    header = next(
        line for line in (quick_folder / "step_1.csv").read_text().splitlines() if line[0] != "#"
    )
    assert "Position [mm]" in header and "Pressure P [bar]" in header
    assert "Temperature P [degC]" in header
    step = read_campaign(quick_folder).recording("step_1.csv")
    assert step.columns["Position"] == "y"
    assert step.units["y"] == "mm" and step.units["p_P"] == "bar"
    # SI inside: a position in m, an absolute pressure in Pa, a temperature in K
    assert 0.0 < step.channels["y"].max() < 0.5
    assert 1e5 < step.channels["p_P"].mean() < 8e5
    assert 270.0 < step.channels["T_P"].mean() < 330.0


def test_same_seed_same_bytes_other_seed_other_noise(
    tmp_path: Path, quick_folder: Path, console: Console
) -> None:
    again = tmp_path / "again"
    assert run_rig(again, [HIDDEN_EFFECT], seed=11, console=console, protocol="quick") == 0
    assert _files(again) == _files(quick_folder)

    other = tmp_path / "other"
    assert run_rig(other, [HIDDEN_EFFECT], seed=12, console=console, protocol="quick") == 0
    a, b = read_campaign(quick_folder), read_campaign(other)
    for rec_a, rec_b in zip(a.recordings, b.recordings, strict=True):
        pressure = next(c for c in rec_a.channels if c.startswith("p_"))
        assert not np.array_equal(rec_a.channels[pressure], rec_b.channels[pressure])
    truth_a = json.loads((quick_folder / TRUTH_FILE).read_text())
    truth_b = json.loads((other / TRUTH_FILE).read_text())
    assert truth_a["parameters"] == truth_b["parameters"]
    assert (truth_a["seed"], truth_b["seed"]) == (11, 12)


def test_effect_in_truth_file_only(quick_folder: Path) -> None:
    truth = json.loads((quick_folder / TRUTH_FILE).read_text())
    assert truth["format"] == TRUTH_FORMAT and truth["version"] == 1
    assert truth["model"]["effects"] == {HIDDEN_EFFECT: 1}
    assert truth["model"]["heat"] == "convection"
    assert truth["model"]["air_properties"] == "sutherland"
    assert truth["parameters"]["chamber_leak_conductance"] > 0.0
    assert truth["seed"] == 11
    assert set(truth["sensors"]["pressure_offsets"]) == {"p_P", "p_N"}
    for name, value in DEMO_TRUTH.items():
        assert truth["parameters"][name] == value

    toml = (quick_folder / "campaign.toml").read_text()
    hidden = [HIDDEN_EFFECT, *EFFECT_SLOTS[HIDDEN_EFFECT][1], "leak", TRUTH_FILE, "truth"]
    assert not [word for word in hidden if word in toml]


def test_hidden_effect_is_visible_in_the_pressures(quick_run: RigRun) -> None:
    leaky = VirtualRig(effects={HIDDEN_EFFECT: None}, seed=5).run("quick")
    p_clean = quick_run.traces["charge_P.h5"].channels["p_P"]
    p_leaky = leaky.traces["charge_P.h5"].channels["p_P"]
    # > 20 kPa: fifty times the pressure noise of the sensors
    assert np.max(np.abs(p_clean - p_leaky)) > 2.0e4


def test_stick_slip_in_step_test(quick_run: RigRun) -> None:
    trace = quick_run.traces["step_1.csv"]
    v, y, y_ref = (trace.channels[c] for c in ("v", "y", "y_ref"))
    stuck = v == 0.0
    # the piston is held exactly (v = 0) for long stretches, off the reference
    edges = np.flatnonzero(np.diff(stuck.astype(int)))
    assert edges.size >= 2
    off_target = stuck & (np.abs(y - y_ref) > 1.0e-3)
    assert off_target.sum() > 100  # > 0.1 s at 1 kHz
    # ... and after it moved: stick-slip, not just a piston that never started
    assert np.ptp(y) > 0.05
    # the recording shows it too: a quantised, flat position
    measured = quick_run.campaign.recording("step_1.csv").channels["y"]
    k = np.flatnonzero(off_target)[-50:]
    assert np.ptp(measured[k]) <= 3e-5  # a few encoder counts of noise


def test_temperature_sensor_lags_the_gas(quick_run: RigRun) -> None:
    sensors = SensorModel()
    rec = quick_run.campaign.recording("charge_P.h5")
    true = quick_run.traces["charge_P.h5"].channels["T_P"]
    measured = rec.channels["T_P"]
    dt = 1.0 / rec.sample_rate
    # slow sensor: its peak comes later and lower than the gas temperature's
    assert rec.time[np.argmax(measured)] > rec.time[np.argmax(true)] + 0.1
    assert measured.max() < true.max() - 5.0
    # and it is the declared first-order lag plus white noise
    residual = measured - held_input_lag(true, dt, sensors.temperature_time_constant)
    assert abs(np.std(residual) - sensors.temperature_noise) < 0.2 * sensors.temperature_noise


def test_sensor_readings(quick_run: RigRun) -> None:
    step = quick_run.campaign.recording("step_1.csv")
    counts = step.channels["y"] / SensorModel().position_resolution
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    offsets = quick_run.truth["sensors"]["pressure_offsets"]
    true = quick_run.traces["step_1.csv"].channels["p_P"]
    error = step.channels["p_P"] - true
    # offset and noise: mean within 4 standard errors, spread within 10 %
    noise = SensorModel().pressure_noise
    assert abs(error.mean() - offsets["p_P"]) < 4 * noise / np.sqrt(error.size)
    assert abs(error.std() - noise) < 0.1 * noise
    # commands are the controller's output, written as commanded
    rec = quick_run.campaign.recording("step_1.csv")
    np.testing.assert_array_equal(rec.channels["u_N"], -rec.channels["u_P"])
    assert np.abs(rec.channels["u_P"]).max() <= 10.0


def test_flow_meter_lags_and_reads_the_static_flow(quick_run: RigRun) -> None:
    rec = quick_run.campaign.recording("flow_P.h5")
    true = quick_run.traces["flow_P.h5"].channels["qm_P"]
    assert rec.sample_rate == pytest.approx(100.0)
    # full opening: several g/s into the chamber, out of it at -10 V
    assert rec.channels["qm_P"].max() > 4e-3 and rec.channels["qm_P"].min() < -4e-3
    # right after a command step the meter has not caught up
    k = np.flatnonzero(np.abs(np.diff(true)) > 1e-3)[0] + 1
    assert abs(rec.channels["qm_P"][k] - true[k]) > 5 * SensorModel().flow_noise


def test_truth_is_finer_than_the_fitting_simulator(quick_run: RigRun) -> None:
    rig = VirtualRig(seed=5)
    assert rig.simulator.step <= DEFAULT_STEP / 10
    assert rig.simulator.tableau.order > Simulator().tableau.order
    assert quick_run.truth["simulator"] == {"method": "dp5", "step": rig.simulator.step}


def test_rewrite_replaces_a_rig_folder_atomically(tmp_path: Path, console: Console) -> None:
    out = tmp_path / "camp"
    assert run_rig(out, [], seed=1, console=console, protocol="quick") == 0
    first = _files(out)
    assert run_rig(out, [], seed=2, console=console, protocol="quick") == 0
    assert _files(out) != first
    assert read_campaign(out).name.endswith("seed-2")
    # nothing left behind next to the campaign
    assert [p.name for p in tmp_path.iterdir()] == ["camp"]


def test_refuses_a_folder_it_did_not_write(tmp_path: Path, console: Console) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert run_rig(out, [], seed=1, console=console, protocol="quick") == 2
    assert "--out" in console.file.getvalue()
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]
