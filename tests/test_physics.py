"""Physics layer: analytic limits and consistency of the pure laws."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneumafit.models import kernel
from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.physics import air, friction, geometry, heat, valve


def test_air_properties_match_tables():
    # Incropera Table A.4, air at 300 K: mu = 1.846e-5 Pa s, k = 0.0263 W/m/K,
    # Pr = 0.707. Sutherland's law is good to ~1 % there.
    assert air.viscosity(300.0) == pytest.approx(1.846e-5, rel=0.01)
    assert air.conductivity(300.0) == pytest.approx(0.0263, rel=0.02)
    assert air.prandtl(300.0) == pytest.approx(0.707, rel=0.02)
    assert air.CP - air.CV == pytest.approx(air.R_AIR)


@pytest.mark.parametrize("b", [0.2, 0.3, 0.5])
def test_flow_function_limits_and_continuity(b):
    m, x_lam = 0.5, 0.995
    assert valve.flow_function(0.0, b, m, x_lam) == 1.0
    assert valve.flow_function(b, b, m, x_lam) == 1.0
    assert valve.flow_function(1.0, b, m, x_lam) == 0.0
    eps = 1e-9  # continuity at both regime boundaries (value jump << eps^0.5)
    for x0 in (b, x_lam):
        lo = valve.flow_function(x0 - eps, b, m, x_lam)
        hi = valve.flow_function(x0 + eps, b, m, x_lam)
        assert abs(lo - hi) < 1e-6
    xs = np.linspace(0, 1, 2001)
    phi = np.array([valve.flow_function(x, b, m, x_lam) for x in xs])
    assert np.all(np.diff(phi) <= 1e-15)  # non-increasing
    # slope continuous at x_lam (C1), by central differences on each side
    h = 1e-7
    left = (
        valve.flow_function(x_lam - h, b, m, x_lam)
        - valve.flow_function(x_lam - 2 * h, b, m, x_lam)
    ) / h
    right = (
        valve.flow_function(x_lam + 2 * h, b, m, x_lam)
        - valve.flow_function(x_lam + h, b, m, x_lam)
    ) / h
    assert left == pytest.approx(right, rel=1e-3)
    # laminar near x = 1: linear in the pressure difference with slope a
    a, _ = valve.laminar_tail(b, m, x_lam)
    z = 1e-7
    assert valve.flow_function(1 - z, b, m, x_lam) / z == pytest.approx(a, rel=1e-4)


def test_opening_is_a_rounded_ramp():
    eps = valve.OPENING_SMOOTHING
    assert valve.opening(0.3 - 1.01 * eps, 0.3, 10.0) == 0.0  # exactly closed below the band
    assert valve.opening(-10.0, 0.3, 10.0) == 0.0
    assert valve.opening(5.3, 0.3, 10.0) == pytest.approx(5.0 / 9.7, rel=1e-14)
    assert valve.opening(10.0, 0.3, 10.0) == 1.0
    us = np.linspace(0.3 - 2 * eps, 0.3 + 2 * eps, 401)
    op = np.array([valve.opening(u, 0.3, 10.0) for u in us])
    slope = np.diff(op) / np.diff(us)
    assert np.all(np.diff(op) >= 0)
    # a corner would change the slope by its full value in one grid step; the
    # rounded ramp changes it by at most 1.5 du / (2 eps) = 0.0075 of it here
    assert np.abs(np.diff(slope)).max() < 0.05 * slope.max()


def test_iso6358_choked_flow_value():
    # q = C rho0 P_up sqrt(T_ref / T_up) when choked (ISO 6358 definition of C)
    q = valve.restriction_flow(1e-8, 0.3, 0.5, 0.995, 7e5, 1.0, 1e5)
    assert q == pytest.approx(1e-8 * air.RHO0 * 7e5, rel=1e-12)


def test_path_flow_reverses_with_upstream_temperature():
    rt1, rt2 = math.sqrt(air.T_REF / 300), math.sqrt(air.T_REF / 350)
    q, t = valve.path_flow(1e-8, 0.3, 0.5, 0.995, 7e5, 300.0, rt1, 5e5, 350.0, rt2)
    assert q > 0 and t == 300.0
    q2, t2 = valve.path_flow(1e-8, 0.3, 0.5, 0.995, 5e5, 350.0, rt2, 7e5, 300.0, rt1)
    assert q2 == pytest.approx(-q * rt1 / rt1) and t2 == 300.0


def test_valve_centre_leakage_and_monotonicity():
    p = dict(
        p_supply=7e5, t_ambient=293.15, p_exhaust=1.013e5,
        c_supply=1e-8, b_supply=0.3, c_exhaust=1.1e-8, b_exhaust=0.3, m=0.5, x_lam=0.995,
        overlap=0.3, u_sat=10.0, c_leak=2e-11, leak_width=0.3,
    )  # fmt: skip
    args = list(p.values())
    q0, _, qs0 = valve.valve_flows(0.0, 4e5, 293.15, *args)
    assert qs0 > 0  # centre leakage from supply
    assert abs(q0) < 1e-5  # net flow at the centre is leakage only (<< 8e-3 kg/s full flow)
    us = np.linspace(-10, 10, 401)
    q = np.array([valve.valve_flows(u, 4e5, 293.15, *args)[0] for u in us])
    assert np.all(np.diff(q) > 0)  # strictly increasing in the command
    # an equilibrium pressure exists at u = 0 (eq. 10): net flow changes sign in P
    pres = np.linspace(1.2e5, 6.9e5, 200)
    qp = np.array([valve.valve_flows(0.0, x, 293.15, *args)[0] for x in pres])
    assert qp[0] > 0 > qp[-1]


def test_opening_shape_exponents_nest_the_linear_ramp():
    """C = C_max open(u)^n + leak: n = 1 is the linear law bit for bit (the
    demo's valve), n = 2 squares the opening by hand, and the compiled flow
    (valve_flows through valve_constants and flows_core) uses the same law
    as conductances(); each path has its own exponent."""
    base = (1e-8, 1.1e-8, 0.3, 10.0, 2e-11, 0.3)
    for u in (-10.0, -4.0, -0.2, 0.0, 0.31, 2.0, 6.5, 10.0):
        assert valve.conductances(u, *base) == valve.conductances(u, *base, 1.0, 1.0)
        o_s, o_e = valve.opening(u, 0.3, 10.0), valve.opening(-u, 0.3, 10.0)
        c_s, c_e = valve.conductances(u, *base, 2.0, 0.5)
        leak_s, leak_e = valve.conductances(u, 0.0, 0.0, 0.3, 10.0, 2e-11, 0.3)
        assert c_s == pytest.approx(1e-8 * o_s**2 + leak_s, rel=1e-14, abs=1e-30)
        assert c_e == pytest.approx(1.1e-8 * o_e**0.5 + leak_e, rel=1e-14, abs=1e-30)
    # the compiled flow at a choked pressure ratio is C rho0 P_S (ISO 6358's C)
    args = (7e5, 293.15, 1.013e5, 1e-8, 0.3, 1.1e-8, 0.3, 0.5, 0.995, 0.3, 10.0, 0.0, 0.3)
    for n in (0.6, 1.0, 1.7):
        q = valve.valve_flows(5.15, 1.5e5, 293.15, *args, n, 1.0)[2]
        c_s, _ = valve.conductances(5.15, 1e-8, 1.1e-8, 0.3, 10.0, 0.0, 0.3, n, 1.0)
        assert q == pytest.approx(c_s * air.RHO0 * 7e5, rel=1e-12)
    assert valve.opening(5.15, 0.3, 10.0) == pytest.approx(0.5, rel=1e-12)
    q_lin = valve.valve_flows(5.15, 1.5e5, 293.15, *args)[2]
    q_pow = valve.valve_flows(5.15, 1.5e5, 293.15, *args, 2.0, 1.0)[2]
    assert q_pow == pytest.approx(0.5 * q_lin, rel=1e-12)  # half open, squared
    # the kernel rejects exponents below 1/3 (infinite slope at the dead-band corner)
    vec = parameter_vector({"valve_n_supply": 0.5})
    assert kernel.check_parameters(vec)
    vec[P["valve_n_exhaust"]] = 0.3
    assert not kernel.check_parameters(vec)


def test_full_opening_fractions_saturate_each_path_at_its_own_command():
    """C_S = C_max min(ramp(u - u_0) / (f_S u_sat - u_0), 1)^n_S: f = 1 is the
    earlier law bit for bit; with f_S = 0.8 the supply path is fully open from
    8 V and its opening at 4.15 V is half, by hand; the exhaust path keeps
    its own fraction; the compiled flow (valve_constants, flows_core) uses
    the same law as conductances(); the kernel rejects f > 1 and a full
    opening inside the dead band."""
    base = (1e-8, 1.1e-8, 0.3, 10.0, 2e-11, 0.3, 1.5, 1.0)
    for u in (-10.0, -6.0, -0.2, 0.0, 0.31, 2.0, 8.0, 10.0):
        assert valve.conductances(u, *base) == valve.conductances(u, *base, 1.0, 1.0)
    leak = valve.conductances(4.15, 0.0, 0.0, 0.3, 10.0, 2e-11, 0.3)
    c_s, c_e = valve.conductances(4.15, *base, 0.8, 0.6)
    assert c_s == pytest.approx(1e-8 * 0.5**1.5 + leak[0], rel=1e-14)
    for u in (8.0, 9.0, 10.0):  # saturated: the full-opening conductance
        c_s, _ = valve.conductances(u, *base, 0.8, 1.0)
        assert c_s == pytest.approx(1e-8 + valve.conductances(u, 0.0, 0.0, 0.3, 10.0, 2e-11,
                                                               0.3)[0], rel=1e-14)  # fmt: skip
    _, c_e = valve.conductances(-3.15, *base, 1.0, 0.6)  # exhaust: (3.15 - 0.3) / (6 - 0.3)
    leak_e = valve.conductances(-3.15, 0.0, 0.0, 0.3, 10.0, 2e-11, 0.3)[1]
    assert c_e == pytest.approx(1.1e-8 * 0.5 + leak_e, rel=1e-14)
    args = (7e5, 293.15, 1.013e5, 1e-8, 0.3, 1.1e-8, 0.3, 0.5, 0.995, 0.3, 10.0, 0.0, 0.3)
    for u in (2.0, 4.15, 7.9, 9.5):
        q = valve.valve_flows(u, 1.5e5, 293.15, *args, 1.5, 1.0, 0.8, 1.0)[2]
        c_s, _ = valve.conductances(u, 1e-8, 1.1e-8, 0.3, 10.0, 0.0, 0.3, 1.5, 1.0, 0.8, 1.0)
        assert q == pytest.approx(c_s * air.RHO0 * 7e5, rel=1e-12)
    vec = parameter_vector({"valve_full_supply": 0.5, "valve_full_exhaust": 0.2})
    assert kernel.check_parameters(vec)  # 2 V > the 0.3-V overlap
    vec[P["valve_full_exhaust"]] = 0.02  # 0.2 V: inside the dead band
    assert not kernel.check_parameters(vec)
    vec[P["valve_full_exhaust"]] = 1.01
    assert not kernel.check_parameters(vec)


def test_knee_exponents_give_an_s_shaped_opening_that_nests_the_power_law():
    """C = C_max (1 - (1 - open^n)^k) + leak: k = 1 is the power law bit for
    bit; k = 3 by hand; the shape rises monotonically from the dead band to
    full opening, where its slope is zero (finite differences); the compiled
    flow (valve_constants, flows_core) uses the same law as conductances();
    the kernel rejects k < 1."""
    base = (1e-8, 1.1e-8, 0.3, 10.0, 2e-11, 0.3, 1.2, 1.6, 1.0, 0.9, 0.0)
    for u in (-10.0, -6.0, -0.2, 0.0, 0.31, 2.0, 8.0, 10.0):
        assert valve.conductances(u, *base) == valve.conductances(u, *base, 1.0, 1.0)
    for u in (0.5, 2.0, 5.15, 9.0):
        o = valve.opening(u, 0.3, 10.0)
        leak = valve.conductances(u, 0.0, 0.0, 0.3, 10.0, 2e-11, 0.3)[0]
        c_s, _ = valve.conductances(u, *base, 3.0, 1.0)
        assert c_s == pytest.approx(1e-8 * (1.0 - (1.0 - o**1.2) ** 3) + leak, rel=1e-13)
    grid = np.linspace(0.0, 10.0, 2001)
    shape = np.array([valve.conductances(u, 1.0, 1.0, 0.3, 10.0, 0.0, 0.3, 1.2, 1.6, 1.0, 1.0,
                                         0.0, 3.0, 2.0)[0] for u in grid])  # fmt: skip
    assert np.all(np.diff(shape) >= 0.0) and shape[-1] == pytest.approx(1.0, rel=1e-14)
    h = 1e-4
    top = [valve.conductances(u, 1.0, 1.0, 0.3, 10.0, 0.0, 0.3, 1.2, 1.6, 1.0, 1.0, 0.0,
                              3.0, 2.0)[0] for u in (10.0 - 2 * h, 10.0 - h)]  # fmt: skip
    assert (top[1] - top[0]) / h < 1e-5  # zero slope at full opening (k > 1)
    args = (7e5, 293.15, 1.013e5, 1e-8, 0.3, 1.1e-8, 0.3, 0.5, 0.995, 0.3, 10.0, 0.0, 0.3)
    for u in (0.6, 3.0, 7.5):
        q = valve.valve_flows(u, 1.5e5, 293.15, *args, 1.2, 1.6, 1.0, 0.9, 0.0, 3.0, 2.0)[2]
        c_s, _ = valve.conductances(u, 1e-8, 1.1e-8, 0.3, 10.0, 0.0, 0.3, 1.2, 1.6, 1.0, 0.9,
                                    0.0, 3.0, 2.0)  # fmt: skip
        assert q == pytest.approx(c_s * air.RHO0 * 7e5, rel=1e-12)
    vec = parameter_vector({"valve_knee_supply": 3.0})
    assert kernel.check_parameters(vec)
    vec[P["valve_knee_exhaust"]] = 0.9
    assert not kernel.check_parameters(vec)


def test_null_offset_shifts_the_whole_characteristic():
    """C(u; b) = C(u - b; 0) for both paths, the centre leakage included:
    b = 0 is the earlier law bit for bit, and the compiled flow
    (valve_constants, flows_core) shifts likewise."""
    base = (1e-8, 1.1e-8, 0.3, 10.0, 2e-11, 0.3, 1.5, 0.8, 0.9, 1.0)
    for u in (-10.0, -4.0, -0.35, -0.1, 0.0, 0.12, 0.4, 3.0, 9.5):
        assert valve.conductances(u, *base) == valve.conductances(u, *base, 0.0)
        for b in (-0.2, 0.07):
            assert valve.conductances(u, *base, b) == pytest.approx(
                valve.conductances(u - b, *base, 0.0), rel=1e-13, abs=1e-30
            )
    args = (7e5, 293.15, 1.013e5, 1e-8, 0.3, 1.1e-8, 0.3, 0.5, 0.995, 0.3, 10.0, 2e-11, 0.3)
    for u in (-3.0, -0.2, 0.0, 0.45, 2.0):
        for pres in (1.5e5, 4e5, 6.9e5):
            q = valve.valve_flows(u, pres, 293.15, *args, 1.5, 0.8, 0.9, 1.0, 0.07)
            ref = valve.valve_flows(u - 0.07, pres, 293.15, *args, 1.5, 0.8, 0.9, 1.0, 0.0)
            assert q == pytest.approx(ref, rel=1e-12, abs=1e-18)


def test_convection_law_zero_at_wall_temperature_and_scaled_form():
    mu, k = air.viscosity(293.15), air.conductivity(293.15)
    assert heat.convection_coefficient(0.4, 0.27, 5e5, 293.15, 293.15, 0.032, mu, k) == 0.0
    lam = heat.convection_coefficient(0.4, 0.27, 5e5, 330.0, 293.15, 0.032, mu, k)
    gr = heat.grashof(5e5, 330.0, 293.15, 0.032, mu)
    assert lam == pytest.approx(0.4 * k / 0.032 * gr**0.27, rel=1e-12)
    # heating and cooling by the same |T_w - T| at the same T^3 are symmetric in Gr
    p = parameter_vector({"xi": 0.4, "beta": 0.27})
    d = np.empty(kernel.ND)
    kernel.derive(p, d)
    scaled = heat.convection_coefficient_scaled(d[kernel.D_LAMC], d[kernel.D_GRC], 0.27, 5e5,
                                                330.0, 293.15)  # fmt: skip
    assert scaled == pytest.approx(lam, rel=1e-12)
    assert 5.0 < lam < 40.0  # the paper's range (physics notes: 5..30 W/m^2/K)


@pytest.mark.parametrize("ends", [1.0, 0.0, 0.4])
def test_exchange_areas_of_kernel_match_geometry(ends):
    p = parameter_vector({"heat_area_ends": ends})
    d = np.empty(kernel.ND)
    kernel.derive(p, d)
    for y in (0.0, 0.13, 0.5):
        a_p, a_n = geometry.exchange_areas(y, 0.5, 0.032, 0.016, 2e-5, 2e-5, ends)
        assert d[kernel.D_A0P] + d[kernel.D_CAP] * y == pytest.approx(a_p, rel=1e-12)
        assert d[kernel.D_A0N] + d[kernel.D_CAN] * (0.5 - y) == pytest.approx(a_n, rel=1e-12)
    # the two conventions by hand: all walls (1), the bore wall only (0)
    s_p, s_n = 0.25 * np.pi * 0.032**2, 0.25 * np.pi * (0.032**2 - 0.016**2)
    l_p, l_n = 2e-5 / s_p + 0.13, 2e-5 / s_n + 0.37
    a_p, a_n = geometry.exchange_areas(0.13, 0.5, 0.032, 0.016, 2e-5, 2e-5, ends)
    bore_p, bore_n = np.pi * 0.032 * l_p, np.pi * 0.032 * l_n
    assert a_p == pytest.approx(bore_p + ends * 2 * s_p, rel=1e-12)
    assert a_n == pytest.approx(bore_n + ends * (2 * s_n + np.pi * 0.016 * l_n), rel=1e-12)
    s_p, s_n = geometry.piston_areas(0.032, 0.016)
    v_p, v_n = geometry.chamber_volumes(0.1, 0.5, s_p, s_n, 2e-5, 2e-5)
    assert v_p == pytest.approx(2e-5 + s_p * 0.1) and v_n == pytest.approx(2e-5 + s_n * 0.4)


def test_friction_switch_model():
    # sliding friction tends to +-F_s at rest and to Coulomb + viscous when fast
    assert friction.sliding_friction(0.0, 1, 50, 30, 60, 0.02) == pytest.approx(50)
    assert friction.sliding_friction(0.0, -1, 50, 30, 60, 0.02) == pytest.approx(-50)
    assert friction.sliding_friction(1.0, 1, 50, 30, 60, 0.02) == pytest.approx(30 + 60)
    assert friction.next_mode(49.9, 50.0) == 0
    assert friction.next_mode(50.1, 50.0) == 1
    assert friction.next_mode(-50.1, 50.0) == -1
    # end stops push back, never pull
    assert friction.end_stop_force(-1e-3, -0.1, 0.5, 1e6, 6e3) > 0
    assert friction.end_stop_force(-1e-3, 10.0, 0.5, 1e6, 6e3) == 0.0
    assert friction.end_stop_force(0.25, 0.0, 0.5, 1e6, 6e3) == 0.0
