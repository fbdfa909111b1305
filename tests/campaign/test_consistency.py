"""The declared rig against the recordings (campaign/consistency.py): a
measured supply pressure p_S, the chambers of the tests whose piston is
held, the position against the stroke and the commands against the
declared controller.

The models simulate the rig's declared ``supply_pressure``; a recording's
``p_S`` is kept but is no input, and a chamber the piston does not compress
stays between the exhaust and the supply pressure. These tests check that
a recording that contradicts the declaration is named (by ``pneumafit
check``'s reader and in a fit's warnings) and that one that agrees is not.
The tolerances are 1 % of the gauge supply for p_S, 2 % for the chambers
and 2 % of the stroke for the position (module doc). They are unit tests
of a consistency check on hand-made signals, not recoveries; that the
virtual rig's campaigns raise none of these warnings was measured over 129
campaigns (every preset and protocol, seeds 1-3; the largest excess over
the supply 0.19 % of the gauge supply, below the exhaust 0.32 %, positions
from 0.20 to 0.95 of the stroke: docs/campaign-format.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneumafit.campaign import inspect_campaign, read_campaign
from pneumafit.campaign.consistency import (
    TOLERANCE,
    chamber_beyond_bounds,
    consistency_warnings,
    controller_mismatch,
    moved_chamber_out_of_range,
    position_beyond_stroke,
    sampled_too_slowly,
    supply_mismatch,
    temperature_out_of_range,
)
from pneumafit.campaign.model import PDController, Recording

SUPPLY = 7.0e5  # the conftest campaign's "7 bar"
EXHAUST = 1.013e5


def _with_supply_channel(folder: Path, p_s_bar: list[float]) -> None:
    """Add a p_S column (bar absolute) to the conftest campaign's step test."""
    path = folder / "step_1.csv"
    lines = path.read_text().splitlines()
    rows = [i for i, line in enumerate(lines) if not line.startswith("#")]
    lines[rows[0]] += ",p_S [bar]"
    for i, value in zip(rows[1:], p_s_bar, strict=True):
        lines[i] += f",{value}"
    path.write_text("\n".join(lines) + "\n")


def test_a_supply_within_the_tolerance_is_not_reported() -> None:
    rng = np.random.default_rng(1)
    span = SUPPLY - EXHAUST
    # off by 0.8 % of the gauge supply, with 400 Pa of sensor noise
    p_s = SUPPLY + 0.8 * TOLERANCE * span + rng.normal(0.0, 400.0, 2000)
    assert supply_mismatch(p_s, SUPPLY, EXHAUST) is None


def test_an_offset_supply_is_reported_with_its_median() -> None:
    rng = np.random.default_rng(2)
    p_s = SUPPLY - 2.0e4 + rng.normal(0.0, 400.0, 2000)  # 20 kPa low: 3.4 % of 5.99 bar
    expected, found = supply_mismatch(p_s, SUPPLY, EXHAUST)
    assert "declared supply_pressure 700.0 kPa absolute" in expected
    assert "median 680.0 kPa" in found
    assert "-20.0 kPa from the declared value" in found
    assert "gauge reading" not in found  # not the gauge confusion: 8.013 bar is far
    assert "sags" not in found  # the noise alone spans 1.3 kPa


def test_a_gauge_supply_declared_as_absolute_is_named() -> None:
    p_s = np.full(100, SUPPLY + EXHAUST)  # the regulator at 7 bar gauge
    _, found = supply_mismatch(p_s, SUPPLY, EXHAUST)
    assert "a gauge reading declared as absolute?" in found


def test_a_sagging_supply_is_reported_as_such() -> None:
    t = np.linspace(0.0, 2.0, 2001)
    p_s = SUPPLY - 3.0e4 * ((t > 0.5) & (t < 1.0))  # 0.3 bar of droop for a quarter of it
    _, found = supply_mismatch(p_s, SUPPLY, EXHAUST)
    assert "central 90 % 670.0 kPa to 700.0 kPa" in found
    assert "supply_pressure_drop" in found
    assert "from the declared value" not in found  # the median is the declared value


@pytest.mark.parametrize(
    ("p_s", "warned"),
    [([7.0, 7.0, 7.01, 6.99, 7.0], False), ([8.01, 8.02, 8.01, 8.0, 8.01], True)],
)
def test_the_reader_and_the_fit_warnings_name_the_recording(
    campaign_dir: Path, p_s: list[float], warned: bool
) -> None:
    _with_supply_channel(campaign_dir, p_s)
    report = inspect_campaign(campaign_dir)
    mine = [p for p in report.problems if p.key == "p_S"]
    assert not any(p.is_error for p in report.problems)
    campaign = read_campaign(campaign_dir)
    lines = consistency_warnings(campaign)
    if not warned:
        assert mine == [] and lines == []
        return
    assert [(p.file, p.is_error) for p in mine] == [("step_1.csv", False)]
    assert "median 801.0 kPa" in mine[0].found
    assert lines == [f"step_1.csv: p_S: expected {mine[0].expected}; found {mine[0].found}"]


# --- chambers the piston does not compress (charge, discharge, flow tests)


def test_a_held_chamber_within_the_bounds_is_not_reported() -> None:
    t = np.linspace(0.0, 2.0, 2001)
    # a charge to the supply less 1.5 % of the gauge supply (a sensor offset
    # below the 2 % tolerance), with 400 Pa of noise
    rise = 1.0 - np.exp(-t / 0.1)
    p = (
        EXHAUST
        + (SUPPLY - EXHAUST) * (1.015 * rise)
        + np.random.default_rng(3).normal(0, 400, t.size)
    )
    assert chamber_beyond_bounds(p, SUPPLY, EXHAUST) is None


def test_a_chamber_above_a_supply_declared_in_gauge_is_named() -> None:
    supply = 6.0e5  # "6 bar" written for a regulator at 6 bar gauge
    t = np.linspace(0.0, 2.0, 2001)
    p = EXHAUST + 6.0e5 * (1.0 - np.exp(-t / 0.1))  # the charge plateaus at 7.013 bar
    expected, found = chamber_beyond_bounds(p, supply, EXHAUST)
    assert "supply_pressure 600.0 kPa absolute" in expected
    assert "99th percentile 701.3 kPa, 101.3 kPa above the supply" in found
    assert "a gauge setting declared as absolute?" in found


def test_a_chamber_in_gauge_declared_absolute_is_named() -> None:
    p = np.linspace(0.0, 5.0e5, 500)  # gauge readings, 0 at atmosphere
    _, found = chamber_beyond_bounds(p, SUPPLY, EXHAUST)
    assert "below the exhaust" in found and "gauge pressure declared as absolute?" in found
    assert "above the supply" not in found


def test_the_reader_judges_held_chambers_only(campaign_dir: Path) -> None:
    """The conftest's charge reaches 6.01 bar: above a supply declared as
    "5 bar" (5 bar gauge is 6.013 bar absolute), so it is named; its flow
    test (held at 3-4 bar absolute) is within the bounds, and its step and
    free tests, whose piston moves, are judged only by the looser bounds of
    a moved chamber, which they meet."""
    toml = campaign_dir / "campaign.toml"
    toml.write_text(
        toml.read_text().replace('supply_pressure = "7 bar"', 'supply_pressure = "5 bar"')
    )
    report = inspect_campaign(campaign_dir)
    mine = [(p.file, p.key) for p in report.problems if "piston does not compress" in p.expected]
    assert mine == [("charge_P_1.h5", "p_P")]
    assert not any(p.is_error for p in report.problems)
    found = next(p.found for p in report.problems if p.key == "p_P")
    assert "a gauge setting declared as absolute?" in found
    lines = consistency_warnings(read_campaign(campaign_dir))
    assert len(lines) == 1 and lines[0].startswith("charge_P_1.h5: p_P: expected a chamber")


# --- the moved chambers and the temperatures against a rig's ranges


def test_a_moved_chamber_compressed_past_the_supply_is_not_reported() -> None:
    """A piston compresses its chamber past the supply and expands it below
    the exhaust for a moment: up to 2 supplies and down to 0.3 exhausts
    (absolute) pass."""
    p = np.linspace(0.5 * EXHAUST, 1.5 * SUPPLY, 200)
    assert moved_chamber_out_of_range(p, SUPPLY, EXHAUST) is None
    # a friction-only campaign has no supply: the lower bound alone
    assert moved_chamber_out_of_range(p * 10.0, float("nan"), EXHAUST) is None


@pytest.mark.parametrize(
    ("factor", "offset", "why"),
    [
        (1e-5, 0.0, "another unit than its header says (bar labelled Pa?)"),
        (1e5, 0.0, "another unit than its header says (Pa labelled bar?)"),
        (1.0, -EXHAUST, "gauge pressure declared as absolute?"),
    ],
)
def test_a_moved_chamber_in_another_unit_is_named(factor: float, offset: float, why: str) -> None:
    """Bar read as Pa, Pa read as bar, gauge read as absolute (a chamber
    vented to the exhaust then reads ~0): named with the likely cause."""
    p = np.linspace(EXHAUST, SUPPLY, 200) * factor + offset
    found = moved_chamber_out_of_range(p, SUPPLY, EXHAUST)
    assert found is not None and why in found[1], found


@pytest.mark.parametrize(
    ("offset", "why"), [(-273.15, "degC labelled K?"), (273.15, "K labelled degC?")]
)
def test_a_temperature_in_another_unit_is_named(offset: float, why: str) -> None:
    t = np.linspace(290.0, 330.0, 100)
    assert temperature_out_of_range(t) is None
    found = temperature_out_of_range(t + offset)
    assert found is not None and why in found[1], found


def test_a_dynamic_test_sampled_in_another_time_unit_is_named() -> None:
    """A 4-s step test at 1 kHz passes; the same samples under a "[s]"
    header that held milliseconds (one sample per second, 4000 s) are named;
    a flow test holding its levels is not judged."""
    t = np.arange(0.0, 4.0005, 1e-3)
    assert sampled_too_slowly(t, "step") is None
    found = sampled_too_slowly(t * 1e3, "step")
    assert found is not None and "ms under [s]?" in found[1] and "4000 s in all" in found[1]
    assert sampled_too_slowly(t * 1e3, "flow") is None


def test_the_reader_names_a_step_test_pressure_in_another_unit(campaign_dir: Path) -> None:
    """From the file: the step test's p_P written in bar under a "[Pa]"
    header is a warning of ``pneumafit check`` naming file and channel (it
    read 1e5 times too low, and the fit would take it)."""
    path = campaign_dir / "step_1.csv"
    text = path.read_text()
    assert "p_P [bar]" in text
    path.write_text(text.replace("p_P [bar]", "p_P [Pa]", 1))
    report = inspect_campaign(campaign_dir)
    mine = [p for p in report.problems if p.file == "step_1.csv" and p.key == "p_P"]
    assert len(mine) == 1 and not mine[0].is_error, report.problems
    assert "bar labelled Pa?" in mine[0].found


# --- the position against the stroke


def test_a_position_within_the_stroke_is_not_reported() -> None:
    # the end stops' compliance and an encoder zeroed 1 % off the stop
    y = np.r_[-0.005, np.linspace(0.0, 0.5, 100), 0.505]
    assert position_beyond_stroke(y, 0.5) is None


@pytest.mark.parametrize(
    ("y", "shown"),
    [
        (np.linspace(100.0, 400.0, 50), "from 100000 to 400000 mm"),  # mm written as m
        (-np.linspace(0.1, 0.4, 50), "from -400 to -100 mm"),  # a sensor counting backwards
    ],
)
def test_a_position_beyond_the_stroke_is_named(y: np.ndarray, shown: str) -> None:
    expected, found = position_beyond_stroke(y, 0.5)
    assert "the declared stroke 500 mm" in expected
    assert shown in found


def test_the_reader_and_the_fit_name_a_position_beyond_the_stroke(campaign_dir: Path) -> None:
    """The conftest's step test, its position header in cm instead of mm:
    1000 to 1050 mm on a 500-mm stroke."""
    step = campaign_dir / "step_1.csv"
    step.write_text(step.read_text().replace("Pos [mm]", "Pos [cm]"))
    toml = campaign_dir / "campaign.toml"
    toml.write_text(toml.read_text().replace('"Pos [mm]" = "y"', '"Pos [cm]" = "y"'))
    report = inspect_campaign(campaign_dir)
    mine = [(p.file, p.key, p.found) for p in report.problems if p.key == "y"]
    assert [m[:2] for m in mine] == [("step_1.csv", "y")]
    assert "positions from 1000 to 1050 mm" in mine[0][2]
    assert not any(p.is_error for p in report.problems)
    lines = consistency_warnings(read_campaign(campaign_dir))
    assert any(line.startswith("step_1.csv: y: expected a piston position") for line in lines)


# --- the commands against the declared controller


def _pd_step(kp: float, kd: float, declared: PDController) -> Recording:
    """A closed-loop step whose commands a PD law with gains kp, kd produced,
    on a made-up motion (an underdamped approach to a 100-mm step, 20 %
    overshoot, read by a 10-um encoder), declared with ``declared``."""
    t = np.arange(0.0, 2.0, 0.001)
    y_ref = np.where(t < 0.2, 0.2, 0.3)
    tau = np.clip(t - 0.2, 0.0, None)
    w, zeta = 15.0, 0.45
    wd = w * np.sqrt(1.0 - zeta**2)
    y = 0.3 - 0.1 * np.exp(-zeta * w * tau) * (np.cos(wd * tau) + zeta * w / wd * np.sin(wd * tau))
    y = np.where(t < 0.2, 0.2, y)
    y_read = np.round(y / 1e-5) * 1e-5
    v = np.gradient(y, t)
    u = np.clip(kp * (y_ref - y) - kd * v, -10.0, 10.0)
    return Recording.from_arrays(
        t, {"y": y_read, "y_ref": y_ref, "u_P": u, "u_N": -u}, kind="step",
        file="step.csv", controller=declared,
    )  # fmt: skip


def test_commands_that_follow_the_declared_law_are_not_reported() -> None:
    declared = PDController(kp=60.0, kd=4.0, u0=0.0, umax=10.0)
    assert controller_mismatch(_pd_step(60.0, 4.0, declared)) is None


def test_gains_a_first_order_motion_cannot_split_are_judged_by_the_law() -> None:
    """Along a first-order approach y_ref - y and v are proportional: the
    commands of kp 40 and kd 4 (13.3 (y_ref - y) with v = (y_ref - y) /
    0.15 s) are those of kp 60 and kd 7 there, so the gains are not judged
    one by one, and the declared law (60, 7) is not reported."""
    t = np.arange(0.0, 2.0, 0.001)
    y = 0.3 - 0.1 * np.exp(-t / 0.15)
    y_ref = np.full_like(t, 0.3)
    v = np.gradient(y, t)
    u = 40.0 * (y_ref - y) - 4.0 * v
    rec = Recording.from_arrays(
        t, {"y": y, "y_ref": y_ref, "u_P": u}, kind="step", file="s.csv",
        controller=PDController(kp=60.0, kd=7.0, u0=0.0, umax=10.0),
    )  # fmt: skip
    assert controller_mismatch(rec) is None


@pytest.mark.parametrize(
    ("kp", "kd", "shown"),
    [(40.0, 4.0, "follow kp 40"), (60.0, 12.0, "kd 12")],
)
def test_commands_of_other_gains_are_named_with_the_gains_they_follow(
    kp: float, kd: float, shown: str
) -> None:
    declared = PDController(kp=60.0, kd=4.0, u0=0.0, umax=10.0)
    expected, found = controller_mismatch(_pd_step(kp, kd, declared))
    assert "kp 60 V/m, kd 4 V s/m" in expected
    assert shown in found


def test_a_gain_in_v_per_mm_is_named_by_the_reader(campaign_dir: Path) -> None:
    """The conftest's campaign with a 2-s step test whose commands follow
    60 V/m, declared as 60 V/mm."""
    rec = _pd_step(60.0, 4.0, PDController(kp=60.0, kd=4.0, u0=0.0, umax=10.0))
    lines = ["time [s],Pos [mm],y_ref [mm],u_P [V]"] + [
        f"{t:.4f},{1e3 * y:.3f},{1e3 * r:.1f},{u:.6f}"
        for t, y, r, u in zip(
            rec.time, rec.channels["y"], rec.channels["y_ref"], rec.channels["u_P"], strict=True
        )
    ]
    (campaign_dir / "step_1.csv").write_text("\n".join(lines) + "\n")
    toml = campaign_dir / "campaign.toml"
    toml.write_text(toml.read_text().replace('kp = "60 V/m"', 'kp = "60 V/mm"'))
    report = inspect_campaign(campaign_dir)
    mine = [p for p in report.problems if p.file == "step_1.csv" and p.key == "u_P"]
    assert len(mine) == 1 and not mine[0].is_error
    assert "kp 6e+04 V/m" in mine[0].expected and "follow kp 60" in mine[0].found
