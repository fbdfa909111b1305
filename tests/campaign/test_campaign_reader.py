"""Reading the example campaign: SI values, defaults, derived channels, hashes."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import pytest

from pneumafit.campaign import (
    CampaignError,
    PDController,
    inspect_campaign,
    read_campaign,
    read_recording,
    summarize,
    validate_campaign,
)

BAR = 1e5  # Pa; pint's bar is exactly 1e5 Pa (conversions agree to rounding)


def test_valid_campaign_has_no_problem(campaign_dir: Path) -> None:
    assert validate_campaign(campaign_dir) == []
    report = inspect_campaign(campaign_dir)
    assert report.ok and report.campaign is not None


def test_campaign_toml_path_is_accepted(campaign_dir: Path) -> None:
    assert read_campaign(campaign_dir / "campaign.toml").name == "test-rig"


def test_rig_in_si_with_defaults(campaign_dir: Path) -> None:
    rig = read_campaign(campaign_dir).rig
    expected = {
        "bore": 0.032,
        "rod": 0.016,
        "stroke": 0.5,
        "dead_volume_P": 20e-6,
        "dead_volume_N": 20e-6,
        "moving_mass": 17.0,
        "supply_pressure": 7 * BAR,
        "exhaust_pressure": 1.013 * BAR,
        "ambient_temperature": 293.15,
        "wall_temperature": 293.15,  # default: ambient
        "characteristic_length": 0.032,  # default: bore
        "mounting_angle": 0.0,
        "external_force": 0.0,
    }
    params = rig.as_parameters()
    assert params.keys() == expected.keys()
    for key, value in expected.items():
        assert params[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key


def test_optional_rig_values(campaign_dir: Path) -> None:
    toml = campaign_dir / "campaign.toml"
    toml.write_text(
        toml.read_text().replace(
            'rod = "16 mm"',
            'rod = "16 mm"\nwall_temperature = "30 degC"\nmounting_angle = "90 deg"\n'
            'external_force = -20\ncharacteristic_length = "1 cm"\nsupply_pressure_note = 1',
        )
    )
    campaign = read_campaign(campaign_dir)
    rig = campaign.rig
    assert rig.wall_temperature == pytest.approx(303.15)
    assert rig.mounting_angle == pytest.approx(math.pi / 2)
    assert rig.external_force == -20.0
    assert rig.characteristic_length == pytest.approx(0.01)
    assert [p.key for p in campaign.warnings] == ["rig.supply_pressure_note"]


def test_gauge_and_units_conversion(campaign_dir: Path) -> None:
    campaign = read_campaign(campaign_dir)
    exhaust = campaign.rig.exhaust_pressure
    charge = campaign.recording("charge_P_1.h5")
    np.testing.assert_allclose(charge.channels["p_N"], exhaust)  # 0 bar with reference=gauge
    assert charge.channels["p_P"][0] == pytest.approx(1.013 * BAR)  # absolute bar
    assert charge.channels["T_P"][0] == pytest.approx(293.15)  # degC -> K
    assert charge.units == {"u_P": "V", "p_P": "bar", "p_N": "bar (gauge)", "T_P": "degC"}
    assert charge.piston_position == pytest.approx(0.25)
    assert charge.description == "charge of chamber P"

    flow = campaign.recording("flow_N_1.csv")
    np.testing.assert_allclose(flow.time, [0.0, 0.01, 0.02, 0.03])  # ms -> s
    np.testing.assert_allclose(flow.channels["p_N"], [2 * BAR + exhaust] * 3 + [3 * BAR + exhaust])
    np.testing.assert_allclose(flow.channels["qm_N"], [0.5e-3, 0.51e-3, 1.1e-3, 0.9e-3])
    assert flow.description == "flow test, chamber N"


def test_mapping_uneven_sampling_and_derived_command(campaign_dir: Path) -> None:
    step = read_campaign(campaign_dir).recording("step_1.csv")
    assert step.controller == PDController(kp=60.0, kd=4.0, u0=0.0, umax=10.0)
    assert step.role == "validate"
    np.testing.assert_allclose(step.channels["y"][:3], [0.1, 0.1, 0.1005])  # "Pos [mm]" -> y
    np.testing.assert_array_equal(step.mask["y_ref"], [True, False, True, False, True])
    np.testing.assert_allclose(step.channels["y_ref"], [0.1, 0.15, 0.2, 0.2, 0.2])
    assert step.derived == ["u_N"]
    np.testing.assert_array_equal(step.channels["u_N"], -step.channels["u_P"])
    assert step.columns == {"Pos [mm]": "y"}
    assert step.description == "step test under PD control\nsecond comment line"


def test_unknown_channel_is_kept(campaign_dir: Path) -> None:
    path = campaign_dir / "free_1.csv"
    lines = path.read_text().splitlines()
    lines[0] += ",valve_T [degC]"
    lines[1:] = [line + ",25" for line in lines[1:]]
    path.write_text("\n".join(lines) + "\n")
    free = read_campaign(campaign_dir).recording("free_1.csv")
    assert free.unknown_channels == ["valve_T"]
    np.testing.assert_allclose(free.channels["valve_T"], 298.15)  # kept, in SI


def test_mapping_without_unit_bracket(campaign_dir: Path) -> None:
    toml = campaign_dir / "campaign.toml"
    toml.write_text(toml.read_text().replace('"Pos [mm]" = "y"', 'Pos = "y"'))
    step = read_campaign(campaign_dir).recording("step_1.csv")
    np.testing.assert_allclose(step.channels["y"][0], 0.1)


def test_sha256_of_every_file(campaign_dir: Path) -> None:
    campaign = read_campaign(campaign_dir)
    assert set(campaign.sha256) == {
        "campaign.toml",
        "charge_P_1.h5",
        "flow_N_1.csv",
        "step_1.csv",
        "free_1.csv",
    }
    for name, digest in campaign.sha256.items():
        assert digest == hashlib.sha256((campaign_dir / name).read_bytes()).hexdigest()


def test_summarize(campaign_dir: Path) -> None:
    rows = summarize(read_campaign(campaign_dir))
    assert [r["file"] for r in rows] == [
        "charge_P_1.h5",
        "flow_N_1.csv",
        "step_1.csv",
        "free_1.csv",
    ]
    charge, flow, step, free = rows
    assert charge["n_samples"] == 101
    assert charge["duration_s"] == pytest.approx(1.0)
    assert charge["sample_rate_Hz"] == pytest.approx(100.0)
    assert charge["setup"] == "chamber P, piston at 250 mm"
    assert flow["channels"] == {"u_N": "V", "p_N": "barg", "qm_N": "g/s"}
    assert step["setup"].startswith("pd: kp=60 V/m")
    assert step["channels"]["u_N"] == "derived: -u_P"
    assert free["setup"].startswith("open loop")


def test_read_recording_alone(campaign_dir: Path) -> None:
    rec = read_recording(
        campaign_dir / "flow_N_1.csv", kind="flow", chamber="N", exhaust_pressure=1e5
    )
    assert rec.channels["p_N"][0] == pytest.approx(3e5)
    with pytest.raises(CampaignError, match="p_N: expected an absolute pressure"):
        read_recording(campaign_dir / "flow_N_1.csv", kind="flow", chamber="N")
    with pytest.raises(CampaignError, match="needed by a flow test of chamber P"):
        read_recording(
            campaign_dir / "flow_N_1.csv", kind="flow", chamber="P", exhaust_pressure=1e5
        )
