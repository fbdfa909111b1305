"""Effect options: names, values, defaults, and errors in the user's words."""

from __future__ import annotations

from pathlib import Path

import pytest
from rich.console import Console

from pneumafit.campaign import PneumafitInputError
from pneumafit.cli.rig import run_rig
from pneumafit.models import EFFECT_SLOTS
from pneumafit.virtual_rig import (
    EFFECT_DEFAULTS,
    PRINCIPAL_PARAMETERS,
    VirtualRig,
    parse_effect_options,
    resolve_effects,
)


def test_every_effect_has_a_principal_parameter_and_a_default() -> None:
    assert set(PRINCIPAL_PARAMETERS) == set(EFFECT_SLOTS)
    for effect, param in PRINCIPAL_PARAMETERS.items():
        assert param in EFFECT_SLOTS[effect][1]
        assert EFFECT_DEFAULTS[param] > 0.0


def test_name_value_and_name_alone() -> None:
    parsed = parse_effect_options(["valve_dynamics=0.02", "seal_friction"])
    assert parsed == {"valve_dynamics": 0.02, "seal_friction": None}
    resolved = resolve_effects(parsed)
    assert resolved.structure == {"valve_dynamics": 1, "seal_friction": 1}
    assert resolved.parameters == {
        "valve_time_constant": 0.02,
        "seal_friction_coefficient": EFFECT_DEFAULTS["seal_friction_coefficient"],
    }


def test_parameter_name_switches_its_effect_on() -> None:
    resolved = resolve_effects(parse_effect_options(["wall_outer_coefficient=20"]))
    assert resolved.structure == {"wall_thermal_mass": 1}
    assert resolved.parameters["wall_outer_coefficient"] == 20.0
    assert resolved.parameters["wall_heat_capacity"] == EFFECT_DEFAULTS["wall_heat_capacity"]
    second = resolve_effects({"valve_natural_frequency": 300.0})
    assert second.structure == {"valve_dynamics": 2}


@pytest.mark.parametrize(
    ("option", "words"),
    [
        ("bogus=1", ["--effect 'bogus=1'", "found 'bogus'", "chamber_leakage"]),
        ("chamber_leakage=abc", ["--effect 'chamber_leakage=abc'", "finite number", "'abc'"]),
        ("chamber_leakage=nan", ["finite number", "'nan'"]),
        ("valve_dynamics=-0.01", ["valve_time_constant > 0", "found -0.01"]),
        ("chamber_leak_conductance=1", ["<= 1e-06 kg/s/Pa", "found 1"]),
    ],
)
def test_bad_option_names_the_option(option: str, words: list[str]) -> None:
    with pytest.raises(PneumafitInputError) as info:
        parse_effect_options([option])
    for word in words:
        assert word in str(info.value)


def test_twice_and_conflicting_orders() -> None:
    with pytest.raises(PneumafitInputError, match="twice"):
        parse_effect_options(["seal_friction", "seal_friction=1e-5"])
    with pytest.raises(PneumafitInputError, match="found both"):
        resolve_effects({"valve_time_constant": 0.01, "valve_damping_ratio": 0.5})


def test_rig_rejects_unknown_truth_parameter() -> None:
    with pytest.raises(PneumafitInputError, match="bore_size"):
        VirtualRig({"bore_size": 0.04})


def test_cli_bad_effect_returns_2_and_writes_nothing(tmp_path: Path, console: Console) -> None:
    out = tmp_path / "never"
    assert run_rig(out, ["cheese=3"], seed=1, console=console, protocol="quick") == 2
    text = console.file.getvalue()
    assert "cheese" in text and "--effect" in text and "Traceback" not in text
    assert not out.exists()


def test_cli_bad_seed_and_protocol_return_2(tmp_path: Path, console: Console) -> None:
    assert run_rig(tmp_path / "a", [], seed=-1, console=console, protocol="quick") == 2
    assert "--seed" in console.file.getvalue()
    assert run_rig(tmp_path / "b", [], seed=1, console=console, protocol="nope") == 2
    assert "protocol" in console.file.getvalue()
    assert list(tmp_path.iterdir()) == []
