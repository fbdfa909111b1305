"""The physics-parts registry (pneumafit.models.parts) and the tables built from it.

Plumbing tests: they check that every older table derived from the parts
registries has exactly the contents it had as a literal before the registry
(references copied from ``git show main:...`` at c174091), and that a part
registered from outside the package reaches the Python-side tables. No
simulation is run; the numbers of the models are not at stake here.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterator

import pytest

from pneumafit import api
from pneumafit.comparison import figures
from pneumafit.discovery import EFFECTS as CATALOG
from pneumafit.discovery import attribution, catalog
from pneumafit.identification.starts import heat_starts
from pneumafit.models import (
    EFFECT_SLOTS,
    MODELS,
    Friction,
    Model,
    ModelStructure,
    Valve,
    layout,
    parts,
    structure,
)
from pneumafit.models.layout import (
    C_AREA_FACTOR,
    C_CHAMBER_LEAK,
    C_EXTERNAL_LEAK,
    C_FORCED_CONV,
    C_FRICTION_ASYM,
    C_HEAT,
    C_SEAL_FRICTION,
    C_SUPPLY_DROP,
    C_VALVE_ORDER,
    C_WALL_MASS,
)
from pneumafit.outputs import report, report_models
from pneumafit.physics.valve_map import MAP_PARAMETER_NAMES
from pneumafit.virtual_rig import EFFECT_DEFAULTS, PRINCIPAL_PARAMETERS

# ----------------------------------------------------------------- references (main, c174091)
OLD_HEAT_LAWS = {"polytropic": 0, "constant-lambda": 1, "convection": 2}
OLD_VALVE_LAWS = {"iso6358": 0, "map": 1}
OLD_FRICTION_LAWS = {"switch": 0, "lugre": 1}

OLD_EFFECT_SLOTS = {
    "chamber_leakage": (
        C_CHAMBER_LEAK,
        ("chamber_leak_conductance",),
        "laminar leakage between the chambers across the piston seal",
    ),
    "external_leakage": (
        C_EXTERNAL_LEAK,
        ("external_leak_conductance", "external_leak_split"),
        "laminar leakage of each chamber to atmosphere, shared 1 + s : 1 - s",
    ),
    "valve_dynamics": (
        C_VALVE_ORDER,
        ("valve_time_constant", "valve_natural_frequency", "valve_damping_ratio"),
        "spool lag: first order (value 1) or second order (value 2)",
    ),
    "wall_thermal_mass": (
        C_WALL_MASS,
        ("wall_heat_capacity", "wall_outer_coefficient"),
        "a wall temperature state per chamber instead of a wall at ambient",
    ),
    "forced_convection": (
        C_FORCED_CONV,
        ("forced_convection_gain",),
        "filling jet raises lambda in proportion to the inflow",
    ),
    "supply_pressure_drop": (
        C_SUPPLY_DROP,
        ("supply_line_resistance",),
        "supply pressure drops with the drawn flow (line resistance)",
    ),
    "seal_friction": (
        C_SEAL_FRICTION,
        ("seal_friction_coefficient",),
        "friction of the seals grows with the chamber pressures",
    ),
    "friction_asymmetry": (
        C_FRICTION_ASYM,
        ("friction_asymmetry",),
        "direction asymmetry of the friction levels",
    ),
    "effective_area": (
        C_AREA_FACTOR,
        ("area_factor",),
        "effective piston area k_A times the nominal bore area",
    ),
}
OLD_HEAT_PARAMETERS = {
    "polytropic": ("k",),
    "constant-lambda": ("lambda",),
    "convection": ("xi", "beta"),
}
OLD_VALVE_PARAMETERS = {
    "iso6358": (
        "valve_C_supply", "valve_b_supply", "valve_C_exhaust", "valve_b_exhaust", "valve_m",
        "valve_x_laminar", "valve_overlap", "valve_u_sat", "valve_C_leak", "valve_leak_width",
        "valve_n_supply", "valve_n_exhaust", "valve_full_supply", "valve_full_exhaust",
        "valve_null_offset", "valve_knee_supply", "valve_knee_exhaust",
    ),
    "map": ("valve_m", "valve_x_laminar", "valve_u_sat", *MAP_PARAMETER_NAMES),
}  # fmt: skip
_SWITCH = ("friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity")
OLD_FRICTION_PARAMETERS = {
    "switch": _SWITCH,
    "lugre": (*_SWITCH, "friction_stiffness", "friction_damping"),
}
OLD_MODELS = {
    "convection": ModelStructure("convection"),
    "constant-lambda": ModelStructure("constant-lambda"),
    "polytropic": ModelStructure("polytropic"),
}
OLD_PRINCIPAL_PARAMETERS = {
    "chamber_leakage": "chamber_leak_conductance",
    "external_leakage": "external_leak_conductance",
    "valve_dynamics": "valve_time_constant",
    "wall_thermal_mass": "wall_heat_capacity",
    "forced_convection": "forced_convection_gain",
    "supply_pressure_drop": "supply_line_resistance",
    "seal_friction": "seal_friction_coefficient",
    "friction_asymmetry": "friction_asymmetry",
    "effective_area": "area_factor",
}
OLD_EFFECT_DEFAULTS = {
    "chamber_leak_conductance": 5.0e-11,
    "external_leak_conductance": 5.0e-11,
    "valve_time_constant": 0.015,
    "wall_heat_capacity": 100.0,
    "forced_convection_gain": 2.0e4,
    "supply_line_resistance": 6.0e6,
    "seal_friction_coefficient": 1.5e-5,
    "friction_asymmetry": 0.2,
    "area_factor": 1.05,
}
OLD_COEFFICIENT_UNIT = {
    "chamber_leakage": "kg/s/Pa",
    "external_leakage": "kg/s/Pa",
    "valve_dynamics": "s",
    "wall_thermal_mass": "m^2 K/J (1/C_w)",
    "forced_convection": "W/m^2/K/(kg/s)",
    "supply_pressure_drop": "Pa/(kg/s)",
    "seal_friction": "N/Pa",
    "friction_asymmetry": "- (a)",
    "effective_area": "- (k_A - 1)",
}
OLD_COLOURS = {"convection": "tab:red", "constant-lambda": "tab:blue", "polytropic": "tab:green"}
OLD_MODEL_LIST = ("convection", "constant-lambda", "polytropic")
OLD_HEAT_STARTS = {
    "convection": [{"xi": 0.59, "beta": 0.25}, {"xi": 0.10, "beta": 1.0 / 3.0},
                   {"xi": 0.25, "beta": 0.29}],
    "constant-lambda": [{"lambda": 5.0}, {"lambda": 15.0}, {"lambda": 40.0}],
    "polytropic": [{"k": 1.05}, {"k": 1.2}, {"k": 1.35}],
}  # fmt: skip

#: The catalog's numbers on main, per effect and parameter: unit, fitting
#: bounds, prior (log-uniform or uniform over the bounds, or a half-normal's
#: scale), typical value, neutral value; its option parameters and phases.
LU, U = "log-uniform", "uniform"
OLD_CATALOG = {
    "chamber_leakage": (
        {"chamber_leak_conductance": ("kg/s/Pa", 1e-13, 1e-9, LU, 5e-11, None)},
        {1: ("chamber_leak_conductance",)},
        ("relaxation", "rest"),
    ),
    "external_leakage": (
        {"external_leak_conductance": ("kg/s/Pa", 1e-13, 1e-9, LU, 5e-11, None),
         "external_leak_split": ("", -1.0, 1.0, U, 0.0, 0.0)},
        {1: ("external_leak_conductance", "external_leak_split")},
        ("relaxation", "rest"),
    ),
    "valve_dynamics": (
        {"valve_time_constant": ("s", 1e-3, 0.1, LU, 0.015, None),
         "valve_natural_frequency": ("rad/s", 30.0, 1e4, LU, 600.0, None),
         "valve_damping_ratio": ("", 0.1, 2.0, LU, 0.7, None)},
        {1: ("valve_time_constant",), 2: ("valve_natural_frequency", "valve_damping_ratio")},
        ("filling", "emptying", "motion"),
    ),
    "wall_thermal_mass": (
        {"wall_heat_capacity": ("J/K/m^2", 10.0, 1e5, LU, 100.0, None),
         "wall_outer_coefficient": ("W/m^2/K", 0.0, 200.0, ("half-normal", 20.0), 10.0, None)},
        {1: ("wall_heat_capacity", "wall_outer_coefficient")},
        ("relaxation",),
    ),
    "forced_convection": (
        {"forced_convection_gain": ("W/m^2/K/(kg/s)", 100.0, 1e6, LU, 2e4, None)},
        {1: ("forced_convection_gain",)},
        ("filling",),
    ),
    "supply_pressure_drop": (
        {"supply_line_resistance": ("Pa/(kg/s)", 1e4, 1e8, LU, 6e6, None)},
        {1: ("supply_line_resistance",)},
        ("filling", "motion"),
    ),
    "seal_friction": (
        {"seal_friction_coefficient": ("N/Pa", 1e-7, 1e-4, LU, 1.5e-5, None)},
        {1: ("seal_friction_coefficient",)},
        ("motion",),
    ),
    "friction_asymmetry": (
        {"friction_asymmetry": ("", -0.5, 0.5, U, 0.2, 0.0)},
        {1: ("friction_asymmetry",)},
        ("motion",),
    ),
    "effective_area": (
        {"area_factor": ("", 0.8, 1.2, U, 1.05, 1.0)},
        {1: ("area_factor",)},
        ("motion", "filling", "emptying"),
    ),
}  # fmt: skip
#: sha256 of the catalog's texts on main (:func:`catalog_text_digest`): every
#: effect's description, law, parameter descriptions and signature terms.
OLD_CATALOG_TEXT_DIGEST = "e3af4d37bcc05f78852079922b927743bc51678e07b1b7686f9a4708e152c6a2"


def _prior(prior: str | tuple[str, float], lower: float, upper: float) -> dict[str, object]:
    """The ``EffectPrior.as_dict()`` that an OLD_CATALOG prior stands for."""
    if isinstance(prior, tuple):
        return {"kind": prior[0], "scale": prior[1]}
    return {"kind": prior, "lower": lower, "upper": upper}


def catalog_text_digest(effects: object) -> str:
    """sha256 over the catalog's text fields, in registry order."""
    texts = [
        [e.name, e.description, e.law, [p.description for p in e.parameters],
         [[t.regressor, t.enters, t.note] for t in e.signature]]
        for e in effects.values()  # type: ignore[attr-defined]
    ]  # fmt: skip
    return hashlib.sha256(json.dumps(texts).encode()).hexdigest()


# ----------------------------------------------------------------- (a) the tables are unchanged
def test_law_codes_are_unchanged() -> None:
    assert dict(layout.HEAT_LAWS) == OLD_HEAT_LAWS
    assert dict(layout.VALVE_LAWS) == OLD_VALVE_LAWS
    assert dict(layout.FRICTION_LAWS) == OLD_FRICTION_LAWS
    # same order too (error messages list them)
    assert list(layout.HEAT_LAWS) == list(OLD_HEAT_LAWS)
    assert structure.HEAT_LAWS is layout.HEAT_LAWS


def test_structure_tables_are_unchanged() -> None:
    assert dict(EFFECT_SLOTS) == OLD_EFFECT_SLOTS
    assert list(EFFECT_SLOTS) == list(OLD_EFFECT_SLOTS)
    assert dict(structure.HEAT_PARAMETERS) == OLD_HEAT_PARAMETERS
    assert dict(structure.VALVE_PARAMETERS) == OLD_VALVE_PARAMETERS
    assert dict(structure.FRICTION_PARAMETERS) == OLD_FRICTION_PARAMETERS
    assert dict(MODELS) == OLD_MODELS
    assert list(MODELS) == list(OLD_MODELS)
    assert MODELS["convection"] is MODELS["convection"]  # one object per law


def test_rig_tables_are_unchanged() -> None:
    assert PRINCIPAL_PARAMETERS == OLD_PRINCIPAL_PARAMETERS
    assert EFFECT_DEFAULTS == OLD_EFFECT_DEFAULTS
    assert list(EFFECT_DEFAULTS) == list(OLD_EFFECT_DEFAULTS)


def test_catalog_is_unchanged() -> None:
    assert tuple(CATALOG) == tuple(OLD_CATALOG)
    for name, (params, options, phases) in OLD_CATALOG.items():
        effect = CATALOG[name]
        found = {
            p.name: (p.unit, p.lower, p.upper, p.prior.as_dict(), p.typical, p.neutral)
            for p in effect.parameters
        }
        expected = {
            n: (unit, lo, hi, _prior(prior, lo, hi), typical, neutral)
            for n, (unit, lo, hi, prior, typical, neutral) in params.items()
        }
        assert found == expected, name
        assert list(found) == list(params), name
        assert dict(effect.option_parameters) == options, name
        assert effect.option == 1 and effect.phases == phases, name
    assert catalog_text_digest(CATALOG) == OLD_CATALOG_TEXT_DIGEST


def test_attribution_tables_are_unchanged() -> None:
    assert dict(attribution._COEFFICIENT_UNIT) == OLD_COEFFICIENT_UNIT
    assert attribution.MIN_SPOOL_START == 2.0e-3
    start = attribution.suggested_start
    # the wall: the coefficient is 1 / C_w; the spool: at least 2 ms
    assert start("wall_thermal_mass", 1e-3) == {
        "wall_heat_capacity": 1000.0, "wall_outer_coefficient": 10.0,
    }  # fmt: skip
    assert start("wall_thermal_mass", 0.5) == {
        "wall_heat_capacity": 100.0, "wall_outer_coefficient": 10.0,
    }  # fmt: skip
    assert start("valve_dynamics", 1e-12) == {"valve_time_constant": 0.002}
    assert start("valve_dynamics", 0.05) == {"valve_time_constant": 0.05}
    assert start("valve_dynamics", 0.5) == {"valve_time_constant": 0.015}
    assert start("chamber_leakage", 1e-12) == {"chamber_leak_conductance": 1e-12}
    assert start("chamber_leakage", math.nan) == {"chamber_leak_conductance": 5e-11}
    assert start("effective_area", 0.1) == {"area_factor": 1.1}
    assert start("friction_asymmetry", -1.0) == {"friction_asymmetry": 0.2}


def test_model_lists_and_colours_are_unchanged() -> None:
    assert dict(figures.COLOURS) == OLD_COLOURS
    assert dict(report_models.MODEL_COLOURS) == OLD_COLOURS
    assert list(figures.COLOURS) == list(OLD_MODEL_LIST)
    assert tuple(report.FIT_MODELS) == OLD_MODEL_LIST
    assert report.FIT_MODELS == OLD_MODEL_LIST
    assert tuple(api.MODELS) == (*OLD_MODEL_LIST, "friction")
    assert {h: heat_starts(h) for h in OLD_HEAT_STARTS} == OLD_HEAT_STARTS


def test_enums_match_the_registries() -> None:
    assert [m.value for m in Model] == list(OLD_MODEL_LIST)
    assert [v.value for v in Valve] == list(OLD_VALVE_LAWS)
    assert [f.value for f in Friction] == list(OLD_FRICTION_LAWS)
    assert Model.CONSTANT_LAMBDA == "constant-lambda"
    assert ModelStructure(Model.CONVECTION, valve=Valve.MAP, friction=Friction.LUGRE).name == (
        "convection"
    )


# ----------------------------------------------------------------- (b) parts from outside
def toy_effect(**changes: object) -> parts.Effect:
    """A Python-only effect: no kernel slot, an existing table parameter."""
    fields: dict[str, object] = {
        "name": "toy_leak",
        "slot": None,
        "parameters": ("chamber_leak_conductance",),
        "description": "a toy leak (plumbing test)",
        "law": "q = G (P_P - P_N)",
        "principal": "chamber_leak_conductance",
        "rig_default": 1e-11,
        "fit": (parts.FitRange("chamber_leak_conductance", 1e-13, 1e-9, "log-uniform"),),
        "coefficient_unit": "kg/s/Pa",
        "signature": (parts.SignatureTerm("P_P - P_N", "dP_P/dt"),),
        "phases": ("rest",),
    }
    fields.update(changes)
    return parts.Effect(**fields)  # type: ignore[arg-type]


def toy_heat_law(**changes: object) -> parts.HeatLaw:
    """A Python-only heat law with code 3 (the kernel branches on 0-2 only)."""
    fields: dict[str, object] = {
        "name": "toy-heat",
        "code": 3,
        "parameters": ("lambda",),
        "description": "a toy heat law (plumbing test)",
        "label": "toy",
        "colour": "tab:purple",
        "order": 5,
        "starts": ({"lambda": 7.0},),
    }
    fields.update(changes)
    return parts.HeatLaw(**fields)  # type: ignore[arg-type]


@pytest.fixture
def clean_registry() -> Iterator[None]:
    """Remove whatever toy parts a test registered, so other tests see the built-ins only."""
    effects, heat = set(parts.EFFECTS), set(parts.HEAT_LAWS)
    yield
    for name in set(parts.EFFECTS) - effects:
        parts.unregister_effect(name)
    for name in set(parts.HEAT_LAWS) - heat:
        parts.unregister_heat_law(name)
    assert dict(EFFECT_SLOTS) == OLD_EFFECT_SLOTS
    assert tuple(CATALOG) == tuple(OLD_CATALOG)
    assert dict(MODELS) == OLD_MODELS


def test_a_toy_effect_reaches_the_python_tables(clean_registry: None) -> None:
    part = parts.register_effect(toy_effect())
    assert EFFECT_SLOTS["toy_leak"] == (None, ("chamber_leak_conductance",), part.description)
    assert list(EFFECT_SLOTS)[-1] == "toy_leak"
    entry = catalog.get_effect("toy_leak")
    assert entry.law == part.law and entry.phases == ("rest",)
    assert entry.parameter("chamber_leak_conductance").typical == 1e-11
    structure_ = entry.structure("convection")
    assert structure_.effects == {"toy_leak": 1}
    assert "chamber_leak_conductance" in structure_.parameter_names
    with pytest.raises(ValueError, match="found neither"):
        structure_.config()  # no kernel slot and no kernel code of its own
    parts.unregister_effect("toy_leak")
    assert "toy_leak" not in EFFECT_SLOTS and "toy_leak" not in CATALOG


def test_a_toy_heat_law_reaches_the_model_lists(clean_registry: None) -> None:
    parts.register_heat_law(toy_heat_law())
    assert layout.HEAT_LAWS["toy-heat"] == 3
    assert structure.HEAT_PARAMETERS["toy-heat"] == ("lambda",)
    assert list(MODELS)[-1] == "toy-heat"
    assert MODELS["toy-heat"].heat == "toy-heat"
    assert figures.COLOURS["toy-heat"] == report_models.MODEL_COLOURS["toy-heat"] == "tab:purple"
    assert "toy-heat" in report.FIT_MODELS and "toy-heat" in api.MODELS
    assert heat_starts("toy-heat") == [{"lambda": 7.0}]
    with pytest.raises(ValueError, match="found neither"):
        ModelStructure("toy-heat").config()  # no kernel branch and no kernel code of its own


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"name": "chamber_leakage"}, "registered; pass replace=True"),
        ({"name": "toy leak"}, "identifier"),
        ({"parameters": ("toy_conductance",)}, r"unknown \['toy_conductance'\]"),
        ({"slot": C_CHAMBER_LEAK}, "taken by 'chamber_leakage'"),
        ({"slot": C_HEAT}, "heat law's"),
        ({"slot": 99}, "configuration slot"),
        ({"principal": "area_factor"}, "principal"),
        ({"rig_default": 1.0}, "rig_default"),
        ({"fit": ()}, "one FitRange per parameter"),
        ({"fit": (parts.FitRange("chamber_leak_conductance", 1e-13, 1.0),)}, "physical bounds"),
        ({"options": {0: ("chamber_leak_conductance",)}}, "option 0"),
        ({"phases": ("boiling",)}, "phases"),  # the catalog refuses it
        ({"moves": frozenset({"flow"})}, "moves"),  # the kernel's flow tests read no effect
        ({"moves": frozenset()}, "moves"),
        ({"moves": {"motion"}}, "moves"),  # a set, not a frozenset: parts are frozen
    ],
)
def test_bad_effects_are_refused(
    clean_registry: None, changes: dict[str, object], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        parts.register_effect(toy_effect(**changes))
    assert "toy_leak" not in parts.EFFECTS and "toy_leak" not in CATALOG
    assert parts.EFFECTS["chamber_leakage"].slot == C_CHAMBER_LEAK


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"name": "convection"}, "registered; pass replace=True"),
        ({"code": 2}, "taken by 'convection'"),
        ({"parameters": ("lambda", "toy_h")}, r"unknown \['toy_h'\]"),
        ({"starts": ({"k": 1.2},)}, "start"),
        ({"starts": ({"lambda": -1.0},)}, "start lambda"),
    ],
)
def test_bad_heat_laws_are_refused(
    clean_registry: None, changes: dict[str, object], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        parts.register_heat_law(toy_heat_law(**changes))
    assert "toy-heat" not in parts.HEAT_LAWS


def test_registries_are_read_only() -> None:
    with pytest.raises(TypeError):
        parts.EFFECTS["x"] = parts.EFFECTS["chamber_leakage"]  # type: ignore[index]
    with pytest.raises(TypeError):
        EFFECT_SLOTS["x"] = EFFECT_SLOTS["chamber_leakage"]  # type: ignore[index]
    with pytest.raises(ValueError, match="unregister effect"):
        parts.unregister_effect("toy_leak")
