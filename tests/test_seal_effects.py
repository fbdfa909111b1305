"""The seal and barrel effects (issue 14): seal friction, direction asymmetry,
effective piston area.

One definition each (:mod:`pneumafit.physics.seal_effects`) read by the
parameter table, the kernel's effect slots, the discovery catalog, the
friction-test registry and the virtual rig; the kernel's terms checked
against their laws (forces, volumes, conservation), the neutral values
against the model without the effect bit for bit, and the cylinder against
the friction-test bench's force balance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneumafit.discovery import EFFECTS, get_effect
from pneumafit.frictiontest.model import (
    FRICTION_EFFECTS,
    STATIC_STIFFNESS,
    FrictionTest,
    default_parameters,
    friction_test_force,
)
from pneumafit.models import EFFECT_SLOTS, ModelStructure, kernel, parameter_vector
from pneumafit.models.layout import NX, SPECS, X_PN, X_PP, X_TN, X_TP, X_V, X_Y, X_Z
from pneumafit.physics.seal_effects import SEAL_EFFECTS, seal_effect
from pneumafit.simulation import Experiment, Simulator
from pneumafit.virtual_rig import EFFECT_DEFAULTS, PRINCIPAL_PARAMETERS

P_ATM = 1.013e5


# ------------------------------------------------------------- one definition
@pytest.mark.parametrize("name", list(SEAL_EFFECTS))
def test_every_model_reads_the_shared_definition(name: str) -> None:
    e = SEAL_EFFECTS[name]
    spec = SPECS[e.parameter]
    assert (spec.unit, spec.lower, spec.upper, spec.default) == (
        e.unit,
        e.lower,
        e.upper,
        e.neutral,
    )
    assert EFFECT_SLOTS[name][1:] == ((e.parameter,), e.description)
    cat = get_effect(name)
    par = cat.parameter(e.parameter)
    assert (cat.law, par.unit, par.lower, par.upper, par.typical) == (
        e.law, e.unit, e.fit_lower, e.fit_upper, e.typical,
    )  # fmt: skip
    assert par.signed == e.signed and (par.neutral is None) != e.signed
    bench = FRICTION_EFFECTS[e.parameter]
    assert (bench.name, bench.unit, bench.step) == (e.bench_name, e.unit, e.step)
    start = default_parameters()[e.parameter]
    assert (start.value, start.lower, start.upper, start.fixed) == (
        e.neutral, e.lower, e.upper, True,
    )  # fmt: skip
    assert PRINCIPAL_PARAMETERS[name] == e.parameter
    assert EFFECT_DEFAULTS[e.parameter] == e.typical
    assert seal_effect(e.bench_name) is e and seal_effect(e.parameter) is e
    assert name in EFFECTS


# ------------------------------------------------------------- kernel terms
def _rhs(
    structure: ModelStructure, values: dict[str, float], x: np.ndarray, mode: int, u: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    p = parameter_vector(values)
    assert kernel.check_parameters(p)
    d = np.empty(kernel.ND)
    kernel.derive(p, d)
    dx = np.empty(NX)
    aux = np.zeros(kernel.NAUX)
    kernel.rhs(x, mode, u, -u, p, d, structure.config(), dx, aux)
    return dx, aux


def _state(y: float, v: float, p_p: float, p_n: float, temp: float = 293.15) -> np.ndarray:
    x = np.zeros(NX)
    x[X_Y], x[X_V], x[X_PP], x[X_PN], x[X_TP], x[X_TN] = y, v, p_p, p_n, temp, temp
    return x


AREA = ModelStructure("constant-lambda").with_effects(effective_area=1)
#: no wall exchange, no valve flow (u = 0 inside the overlap, no centre leak)
CLOSED = {"lambda": 0.0, "valve_C_leak": 0.0, "exhaust_pressure": P_ATM}


@pytest.mark.parametrize("k", [0.9, 1.05, 1.2])
def test_area_factor_scales_the_pressure_force(k: float) -> None:
    """At rest with the rod side at the atmosphere the pressure force is
    k_A times the nominal one; in general it changes by
    (k_A - 1) S_bore (P_P - P_N) (the rod's area is not scaled)."""
    s_bore = 0.25 * math.pi * 0.032**2
    for p_n in (P_ATM, 4.0e5):
        x = _state(0.2, 0.0, 5.0e5, p_n)
        _, nominal = _rhs(AREA, {**CLOSED, "area_factor": 1.0}, x, 0)
        _, scaled = _rhs(AREA, {**CLOSED, "area_factor": k}, x, 0)
        f_nom, f_k = nominal[kernel.A_FD], scaled[kernel.A_FD]
        assert f_k - f_nom == pytest.approx((k - 1.0) * s_bore * (5.0e5 - p_n), rel=1e-10)
        if p_n == P_ATM:
            assert f_k == pytest.approx(k * f_nom, rel=1e-12)


@pytest.mark.parametrize("k", [0.9, 1.2])
def test_area_factor_enters_the_volumes_and_their_rates(k: float) -> None:
    """Closed chambers, no heat exchange, a moving piston: dP/dt = -gamma P
    dV/dt / V with V = V_0 + k_A S y and dV/dt = k_A S v (the swept volume
    follows the area), and the kernel's rates conserve mass (d(PV/T) = 0)
    and energy (d(PV)/dt = -(gamma - 1) P dV/dt)."""
    values = {**CLOSED, "area_factor": k}
    y, v, p_p, p_n = 0.2, 0.3, 5.0e5, 3.0e5
    dx, _ = _rhs(AREA, values, _state(y, v, p_p, p_n), 1)
    s_p = k * 0.25 * math.pi * 0.032**2
    s_n = s_p - 0.25 * math.pi * 0.016**2
    stroke = SPECS["stroke"].default
    v_p = SPECS["dead_volume_P"].default + s_p * y
    v_n = SPECS["dead_volume_N"].default + s_n * (stroke - y)
    for pres, vol, dvol, dp, dt in (
        (p_p, v_p, s_p * v, dx[X_PP], dx[X_TP]),
        (p_n, v_n, -s_n * v, dx[X_PN], dx[X_TN]),
    ):
        assert dp == pytest.approx(-1.4 * pres * dvol / vol, rel=1e-12)
        mass_rate = (dp * vol + pres * dvol) / 293.15 - pres * vol * dt / 293.15**2
        assert abs(mass_rate) < 1e-10 * abs(pres * dvol / 293.15)
        assert dp * vol + pres * dvol == pytest.approx(-0.4 * pres * dvol, rel=1e-10)


@pytest.mark.parametrize("a", [-0.3, 0.25])
def test_asymmetry_scales_the_levels_by_direction(a: float) -> None:
    """Sliding: F_f = s (1 + a s) (F_c + (F_s - F_c) exp(-(v/v_st)^2)) + b v,
    seal term included; stuck: the piston breaks away at F_s (1 + a s), s
    the direction the drive pushes."""
    structure = ModelStructure("constant-lambda").with_effects(friction_asymmetry=1,
                                                              seal_friction=1)  # fmt: skip
    c_p = 2e-5
    values = {**CLOSED, "friction_asymmetry": a, "seal_friction_coefficient": c_p}
    f_s, f_c, b, v_st = (SPECS[n].default for n in
                         ("friction_static", "friction_coulomb", "friction_viscous",
                          "stribeck_velocity"))  # fmt: skip
    p_p, p_n = 5.0e5, 3.0e5
    extra = c_p * (p_p + p_n - 2.0 * P_ATM)
    for s in (1, -1):
        v = 0.03 * s
        _, aux = _rhs(structure, values, _state(0.2, v, p_p, p_n), s)
        level = (f_c + extra + (f_s - f_c) * math.exp(-((v / v_st) ** 2))) * (1.0 + a * s)
        assert aux[kernel.A_FF] == pytest.approx(s * level + b * v, rel=1e-12)
    for p_p_stuck, s in ((6.5e5, 1), (1.2e5, -1)):
        _, aux = _rhs(structure, values, _state(0.2, 0.0, p_p_stuck, p_n), 0)
        assert np.sign(aux[kernel.A_FD]) == s
        extra = c_p * (p_p_stuck + p_n - 2.0 * P_ATM)
        assert aux[kernel.A_FS] == pytest.approx((f_s + extra) * (1.0 + a * s), rel=1e-12)


@pytest.fixture(scope="module")
def moving() -> Experiment:
    t = np.arange(0.0, 1.5005, 1e-3)
    u = np.where(t < 0.4, 0.0, np.where(t < 0.9, 3.0, -3.0))
    return Experiment(t, "free", u_P=u, u_N=-u,
                      initial={"y": 0.25, "p_P": 3.0e5, "p_N": 4.0e5})  # fmt: skip


@pytest.mark.parametrize("friction", ["switch", "lugre"])
@pytest.mark.parametrize(
    ("name", "neutral"),
    [("seal_friction", 0.0), ("friction_asymmetry", 0.0), ("effective_area", 1.0)],
)
def test_neutral_value_is_the_old_model_bit_for_bit(
    moving: Experiment, friction: str, name: str, neutral: float
) -> None:
    base = ModelStructure("convection", friction=friction)
    old = Simulator(base).simulate({}, moving)
    new = Simulator(base.with_effects(**{name: 1})).simulate(
        {SEAL_EFFECTS[name].parameter: neutral}, moving
    )
    assert old.ok and new.ok
    assert np.ptp(old["y"]) > 0.05
    for ch in ("y", "v", "p_P", "p_N", "T_P", "T_N", "F_f"):
        np.testing.assert_array_equal(new[ch], old[ch], err_msg=ch)


def test_bad_effect_parameters_are_refused() -> None:
    """The kernel's own check (values outside the parameter table's bounds
    are refused earlier, by parameter_vector)."""
    from pneumafit.models.layout import P

    for name, bad in (("friction_asymmetry", 1.0), ("friction_asymmetry", -1.0),
                      ("area_factor", 0.0), ("area_factor", 0.2)):  # fmt: skip
        # 0.2 pi D^2 / 4 is below the 16-mm rod's area (0.25 of the 32-mm bore's)
        p = parameter_vector({})
        assert kernel.check_parameters(p)
        p[P[name]] = bad
        assert not kernel.check_parameters(p), (name, bad)


# ------------------------------------------------------- cylinder vs bench
@pytest.mark.parametrize("v", [0.012, -0.008])
def test_cylinder_and_bench_give_the_same_rod_force(v: float) -> None:
    """A single-acting bench (rod side at the atmosphere) sliding steadily:
    the cylinder kernel's driving force minus its LuGre friction at the
    steady bristle deflection equals the friction-test force balance
    F = k_A (p_P - p_atm) A - F_f with the same seal, asymmetry and area
    parameters: one law in two kernels."""
    values = {
        "friction_static": 9.0, "friction_coulomb": 6.0, "friction_viscous": 40.0,
        "stribeck_velocity": 3e-3, "friction_stiffness": STATIC_STIFFNESS,
        "friction_damping": 0.0, "seal_friction_coefficient": 1.2e-5,
        "friction_asymmetry": 0.15, "area_factor": 1.04,
    }  # fmt: skip
    p_p = 4.0e5
    bore, rod = 0.025, 0.01
    n = 400
    t = np.arange(n) * 0.01
    dp = np.full(n, p_p - P_ATM)
    area = 0.25 * math.pi * bore**2
    test = FrictionTest("t", "fit", t, np.full(n, v), dp, dp * area, np.zeros(n))
    bench = friction_test_force(test, values)[0, -1]
    structure = ModelStructure("constant-lambda", friction="lugre").with_effects(
        seal_friction=1, friction_asymmetry=1, effective_area=1
    )
    cyl = {**values, **CLOSED, "bore": bore, "rod": rod, "mounting_angle": 0.0}
    x = _state(0.2, v, p_p, P_ATM)
    g = (6.0 + 1.2e-5 * (p_p - P_ATM) + 3.0 * math.exp(-((v / 3e-3) ** 2))) * (
        1.0 + 0.15 * np.sign(v)
    )
    x[X_Z] = np.sign(v) * g / STATIC_STIFFNESS
    dx, aux = _rhs(structure, cyl, x, 0)
    assert abs(dx[X_Z]) < 1e-9 * abs(v)  # the steady deflection
    assert aux[kernel.A_FD] - aux[kernel.A_FF] == pytest.approx(bench, rel=1e-9)


def test_double_acting_bench_scales_the_bore_not_the_rod() -> None:
    """With p_N recorded (double-acting bench) the area factor scales the
    bore's area: push = k_A A_P dp_P - (k_A A_P - A_rod) dp_N."""
    n = 50
    t = np.arange(n) * 0.01
    a_p, a_rod = 4.9e-4, 0.8e-4
    dp_p, dp_n = np.full(n, 3e5), np.full(n, 1e5)
    push = dp_p * a_p - dp_n * (a_p - a_rod)
    test = FrictionTest("t", "fit", t, np.zeros(n), dp_p, push, np.zeros(n),
                        rod_push=dp_n * a_rod)  # fmt: skip
    values = {p.name: p.value for p in default_parameters()}
    values.update(friction_static=0.0, friction_coulomb=0.0, friction_viscous=0.0,
                  area_factor=1.1)  # fmt: skip
    force = friction_test_force(test, values)[0]
    expected = 1.1 * a_p * dp_p - (1.1 * a_p - a_rod) * dp_n
    np.testing.assert_allclose(force, expected, rtol=1e-12)


# ------------------------------------------------------------- independent truth
def test_truth_asymmetry_and_barrel() -> None:
    from pneumafit.virtual_rig.truth import PRESETS, TruthConfig
    from pneumafit.virtual_rig.truth.friction import LuGreFriction
    from pneumafit.virtual_rig.truth.simulator import _Plant

    lugre = LuGreFriction(sigma0=1e5, sigma1=0.0, sigma2=0.0, F_c=20.0, F_s=30.0, v_s=0.01,
                          asymmetry=0.2)  # fmt: skip
    assert lugre.stribeck(0.5, 0.0) == pytest.approx(1.2 * 20.0)
    assert lugre.stribeck(-0.5, 0.0) == pytest.approx(0.8 * 20.0)
    assert lugre.sliding(0.5, 0.0) == pytest.approx(20.0)  # the mean of both directions
    with pytest.raises(ValueError, match="asymmetry"):
        LuGreFriction(sigma0=1e5, sigma1=0.0, sigma2=0.0, F_c=20.0, F_s=30.0, v_s=0.01,
                      asymmetry=1.0)  # fmt: skip
    data = {**PRESETS["fit-laws"], "barrel": {"bore": 0.0328}}
    config = TruthConfig.from_dict(data)
    assert TruthConfig.from_dict(config.as_dict()) == config
    par = {name: spec.default for name, spec in SPECS.items()}
    plant = _Plant(config, {**par, "bore": 0.032})
    assert plant.s_p == pytest.approx(0.25 * math.pi * 0.0328**2)
    assert plant.volume("P", 0.1) == pytest.approx(par["dead_volume_P"] + plant.s_p * 0.1)
