"""The effect catalog: contents, consistency with the models, registration."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from scipy import integrate

from pneumafit.discovery import (
    EFFECTS,
    PHASES,
    Effect,
    EffectParameter,
    EffectPrior,
    SignatureTerm,
    catalog,
    effects_for_phase,
    get_effect,
    register_effect,
)
from pneumafit.models import EFFECT_SLOTS, PARAMETER_SPECS, ModelStructure
from pneumafit.simulation import Experiment, Simulator
from pneumafit.virtual_rig import EFFECT_DEFAULTS, PRINCIPAL_PARAMETERS

SPECS = {s.name: s for s in PARAMETER_SPECS}
CATALOG = (
    "chamber_leakage",
    "external_leakage",
    "valve_dynamics",
    "wall_thermal_mass",
    "forced_convection",
    "supply_pressure_drop",
    "seal_friction",
    "friction_asymmetry",
    "effective_area",
)
#: Effects that act on the piston only (a blocked test does not see them).
MOTION_ONLY = ("seal_friction", "friction_asymmetry")


@pytest.fixture
def registry() -> Iterator[None]:
    """Restore the registry after a test that registers effects."""
    saved = dict(catalog._EFFECTS)
    yield
    catalog._EFFECTS.clear()
    catalog._EFFECTS.update(saved)


def test_catalog_holds_the_nine_effects() -> None:
    assert tuple(EFFECTS) == CATALOG
    assert set(EFFECTS) == set(EFFECT_SLOTS)  # every kernel effect is a candidate
    with pytest.raises(TypeError):
        EFFECTS["x"] = EFFECTS["chamber_leakage"]  # type: ignore[index]


@pytest.mark.parametrize("name", CATALOG)
def test_effect_agrees_with_the_models(name: str) -> None:
    effect = get_effect(name)
    slot, slot_params, description = EFFECT_SLOTS[name]
    assert effect.description == description
    assert {p.name for p in effect.parameters} == set(slot_params)
    assert effect.law and effect.signature and effect.phases
    assert set(effect.phases) <= set(PHASES)
    for p in effect.parameters:
        spec = SPECS[p.name]
        assert (p.unit, spec.group) == (spec.unit, "effect")
        assert spec.lower <= p.lower <= p.typical <= p.upper <= spec.upper
        assert np.isfinite(p.prior.logpdf(p.typical))
    for option in effect.option_parameters:
        structure = effect.structure("convection", option)
        assert structure.effects == {name: option}
        assert structure.config()[slot] == option
        assert set(effect.parameter_names(option)) <= set(structure.parameter_names)
    # the typical size of the principal parameter is the virtual rig's default
    principal = PRINCIPAL_PARAMETERS[name]
    assert effect.parameter(principal).typical == EFFECT_DEFAULTS[principal]


@pytest.fixture(scope="module")
def charge() -> tuple[Experiment, np.ndarray]:
    t = np.arange(0.0, 2.0005, 1e-3)
    u = np.where((t > 0.1) & (t < 0.3), 8.0, 0.0)
    exp = Experiment(t, "charge", chamber="P", u_P=u, initial={"y": 0.2, "p_P": 1.013e5})
    base = Simulator("convection").simulate({}, exp)
    assert base.ok
    return exp, base["p_P"]


@pytest.mark.parametrize("name", [n for n in CATALOG if n not in MOTION_ONLY])
def test_option_switches_the_law_on_in_the_kernel(
    name: str, charge: tuple[Experiment, np.ndarray]
) -> None:
    # each effect at its typical size changes a charge test by far more than
    # the 400-Pa sensor noise (docs/virtual-rig.md: 20-120 kPa on the demo's)
    exp, p_base = charge
    effect = get_effect(name)
    sim = Simulator(effect.structure("convection")).simulate(effect.typical_values(), exp)
    assert sim.ok, sim.message
    assert np.max(np.abs(sim["p_P"] - p_base)) > 2e3


@pytest.mark.parametrize("name", CATALOG[6:])
def test_seal_effects_change_a_step_test(name: str) -> None:
    """The seal and barrel effects at their typical size change an open-loop
    move of the piston by far more than the 10-um encoder: seal friction
    (~9 N more friction at 6 bar of summed gauge pressure), asymmetry (a
    fifth of the levels), a 5 % larger piston area."""
    t = np.arange(0.0, 1.5005, 1e-3)
    u = np.where(t < 0.5, 0.0, np.where(t < 1.0, 3.0, -3.0))
    exp = Experiment(t, "free", u_P=u, u_N=-u,
                     initial={"y": 0.25, "p_P": 3.0e5, "p_N": 4.0e5})  # fmt: skip
    base = Simulator("convection").simulate({}, exp)
    effect = get_effect(name)
    sim = Simulator(effect.structure("convection")).simulate(effect.typical_values(), exp)
    assert base.ok and sim.ok, sim.message
    assert np.ptp(base["y"]) > 0.05  # the piston moves both ways
    assert np.max(np.abs(sim["y"] - base["y"])) > 1e-3


def test_valve_dynamics_has_two_orders() -> None:
    effect = get_effect("valve_dynamics")
    assert effect.parameter_names() == ("valve_time_constant",)
    assert effect.parameter_names(2) == ("valve_natural_frequency", "valve_damping_ratio")
    assert effect.structure("polytropic", 2).state_names[-2:] == ("dus_N", "dus_P")
    with pytest.raises(ValueError, match="option"):
        effect.parameter_names(3)


def test_effects_for_phase() -> None:
    relaxing = {e.name for e in effects_for_phase("relaxation")}
    assert relaxing == {"chamber_leakage", "external_leakage", "wall_thermal_mass"}
    assert "forced_convection" in {e.name for e in effects_for_phase("filling")}
    with pytest.raises(ValueError, match="phase"):
        effects_for_phase("boiling")


def test_get_effect_unknown_name() -> None:
    with pytest.raises(ValueError, match=r"chamber_leakage.*found 'rod_spring'"):
        get_effect("rod_spring")


@pytest.mark.parametrize("kind", ["log-uniform", "half-normal", "uniform"])
def test_priors_are_normalised_densities(kind: str) -> None:
    prior = (
        EffectPrior(kind, scale=3.0)
        if kind == "half-normal"
        else EffectPrior(kind, lower=0.5, upper=40.0)
    )
    lo, hi = prior.support
    hi = min(hi, 60.0)  # half-normal: 20 scales hold all but 1e-80 of it
    total, _ = integrate.quad(lambda x: np.exp(prior.logpdf(x)), lo, hi, limit=200)
    assert total == pytest.approx(1.0, rel=1e-8)
    assert prior.logpdf(-1.0) == -np.inf
    draws = prior.sample(np.random.default_rng(0), 2000)
    assert np.all(np.isfinite(prior.logpdf(draws)))
    assert set(prior.as_dict()) <= {"kind", "lower", "upper", "scale"}


@pytest.mark.parametrize(
    "args",
    [
        {"kind": "beta"},
        {"kind": "half-normal", "scale": 0.0},
        {"kind": "log-uniform", "lower": 0.0, "upper": 1.0},
        {"kind": "uniform", "lower": 2.0, "upper": 1.0},
    ],
)
def test_bad_priors(args: dict[str, object]) -> None:
    with pytest.raises(ValueError, match="prior"):
        EffectPrior(**args)  # type: ignore[arg-type]


def seal_friction_effect(**changes: object) -> Effect:
    """The rig's seal friction as a catalog entry (it has a kernel slot)."""
    parameter = EffectParameter(
        name="seal_friction_coefficient",
        unit="N/Pa",
        lower=1e-7,
        upper=1e-4,
        prior=EffectPrior("log-uniform", lower=1e-7, upper=1e-4),
        typical=1.5e-5,
        description="growth of the seal friction with the chamber pressures",
    )
    fields: dict[str, object] = {
        "name": "seal_friction",
        "description": EFFECT_SLOTS["seal_friction"][2],
        "law": "F_s, F_c += k_seal (P_P + P_N - 2 P_atm) when positive",
        "parameters": (parameter,),
        "signature": (SignatureTerm("sign(v) (P_P + P_N - 2 P_atm)", "dv/dt"),),
        "phases": ("motion",),
    }
    fields.update(changes)
    return Effect(**fields)  # type: ignore[arg-type]


def test_register_an_effect_with_a_kernel_slot(registry: None) -> None:
    catalog._EFFECTS.pop("seal_friction")  # registered again below
    effect = register_effect(seal_friction_effect())
    assert get_effect("seal_friction") is effect
    assert effect in effects_for_phase("motion")
    assert effect.structure("convection").effects == {"seal_friction": 1}
    with pytest.raises(ValueError, match="replace=True"):
        register_effect(seal_friction_effect())
    assert register_effect(seal_friction_effect(phases=()), replace=True).phases == ()


def test_register_checks_against_the_models(registry: None) -> None:
    catalog._EFFECTS.pop("seal_friction")  # each failed registration must not add it
    prior = EffectPrior("log-uniform", lower=1e-7, upper=1e-4)

    def with_parameter(name: str, unit: str, upper: float) -> Effect:
        return seal_friction_effect(
            parameters=(EffectParameter(name, unit, 1e-7, upper, prior, 1e-5),)
        )

    with pytest.raises(ValueError, match=r"EFFECT_SLOTS.*models/kernel\.rhs"):
        register_effect(seal_friction_effect(name="rod_spring"))
    with pytest.raises(ValueError, match="expected unit 'N/Pa'"):
        register_effect(with_parameter("seal_friction_coefficient", "N/bar", 1e-4))
    with pytest.raises(ValueError, match="within the physical bounds"):
        register_effect(with_parameter("seal_friction_coefficient", "N/Pa", 1.0))
    with pytest.raises(ValueError, match="PARAMETER_SPECS"):
        register_effect(with_parameter("seal_stiffness", "N/Pa", 1e-4))
    with pytest.raises(ValueError, match="option 2"):
        register_effect(
            seal_friction_effect(option_parameters={1: ("seal_friction_coefficient",), 2: ()})
        )
    assert "seal_friction" not in EFFECTS


def test_effect_validation() -> None:
    with pytest.raises(ValueError, match="identifier"):
        seal_friction_effect(name="seal friction")
    with pytest.raises(ValueError, match="phases"):
        seal_friction_effect(phases=("sliding",))
    with pytest.raises(ValueError, match="option"):
        seal_friction_effect(option=0)
    with pytest.raises(ValueError, match="typical"):
        EffectParameter("x", "", 1.0, 2.0, EffectPrior("uniform", lower=1.0, upper=2.0), 3.0)


def test_structure_switches_on_what_the_catalog_lists() -> None:
    # every catalog parameter is switched on by some option of its effect
    for effect in EFFECTS.values():
        used = set()
        for option in effect.option_parameters:
            used |= set(effect.structure(ModelStructure("convection"), option).parameter_names)
        assert {p.name for p in effect.parameters} <= used
