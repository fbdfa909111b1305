"""Physics checks of the independent truth simulator (pneumafit.virtual_rig.truth).

Analytic limits and conservation laws, each with a tolerance derived from
the integrator's settings (solve_ivp LSODA, rtol 1e-8 unless stated).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from pneumafit.models import parameter_dict, parameter_vector
from pneumafit.simulation import PD, Experiment
from pneumafit.virtual_rig.truth import (
    PRESETS,
    LuGreFriction,
    PowerConductance,
    TableConductance,
    TruthConfig,
    TruthSimulator,
    flow_function,
    get_truth,
    restriction_flow,
)
from pneumafit.virtual_rig.truth.constants import GAMMA, R_GAS
from pneumafit.virtual_rig.virtual import DEMO_TRUTH

PAR = parameter_dict(parameter_vector(DEMO_TRUTH))
S_P = 0.25 * math.pi * PAR["bore"] ** 2
S_N = 0.25 * math.pi * (PAR["bore"] ** 2 - PAR["rod"] ** 2)


def _config(**changes: dict) -> TruthConfig:
    data = copy.deepcopy(dict(PRESETS["power-valve"]))
    for section, values in changes.items():
        if section == "leak":
            data["valve"]["leak"] = values
        else:
            data[section].update(values)
    return TruthConfig.from_dict(data)


def _charge(y: float = 0.15, n: int = 1501) -> Experiment:
    t = np.arange(n) * 1e-3
    u = np.zeros(n)
    u[50:300] = 10.0
    return Experiment(t, "charge", chamber="P", u_P=u, initial={"y": y}, name="charge")


# ----------------------------------------------------------------------------
# steady flow
# ----------------------------------------------------------------------------
def test_flow_function_hand_values() -> None:
    """ISO 6358 flow function and restriction flow against values worked by hand.

    Closed-form values (phi(0.6) = sqrt(1 - (0.3 / 0.7)^2) = 0.9035079...),
    so the tolerance is floating-point rounding (1e-12 relative).
    """
    b, m, x_l = 0.3, 0.5, 0.999
    assert flow_function(0.2, b, m, x_l) == 1.0
    assert flow_function(b, b, m, x_l) == 1.0
    assert flow_function(0.6, b, m, x_l) == pytest.approx(0.9035079029052513, rel=1e-12)
    assert flow_function(1.0, b, m, x_l) == 0.0
    phi_l = math.sqrt(1.0 - ((x_l - b) / (1.0 - b)) ** 2)
    # laminar region: continuous at x_l, linear in (1 - x) above it
    assert flow_function(x_l, b, m, x_l) == pytest.approx(phi_l, rel=1e-12)
    assert flow_function(0.9995, b, m, x_l) == pytest.approx(0.5 * phi_l, rel=1e-12)
    # choked flow: q = C rho0 P_up sqrt(T_ref / T_up)
    q, t_up = restriction_flow(1e-8, b, m, x_l, 6e5, 293.15, 1.2e5, 300.0)
    assert q == pytest.approx(1e-8 * 1.185 * 6e5, rel=1e-12)
    assert t_up == 293.15
    q_hot, _ = restriction_flow(1e-8, b, m, x_l, 6e5, 323.15, 1.2e5, 300.0)
    assert q_hot == pytest.approx(q * math.sqrt(293.15 / 323.15), rel=1e-12)
    # subsonic, and reversed: the sign flips and the new upstream's temperature is carried
    q_sub, _ = restriction_flow(1e-8, b, m, x_l, 5e5, 293.15, 3e5, 310.0)
    assert q_sub == pytest.approx(1e-8 * 1.185 * 5e5 * 0.9035079029052513, rel=1e-12)
    q_rev, t_rev = restriction_flow(1e-8, b, m, x_l, 3e5, 310.0, 5e5, 293.15)
    assert q_rev == pytest.approx(-q_sub, rel=1e-12)
    assert t_rev == 293.15
    # laminar region: linear in the pressure difference at a fixed upstream pressure
    q_1, _ = restriction_flow(1e-8, b, m, x_l, 5e5, 293.15, 5e5 - 100.0, 293.15)
    q_2, _ = restriction_flow(1e-8, b, m, x_l, 5e5, 293.15, 5e5 - 200.0, 293.15)
    assert q_2 == pytest.approx(2.0 * q_1, rel=1e-12)


def test_conductance_families_hand_values() -> None:
    """Power law and table at points computed by hand (rounding only, 1e-12)."""
    power = PowerConductance(C_max=1e-8, u0=0.4, u_sat=9.4, n=1.5, b=0.3)
    assert power.conductance(0.3) == 0.0
    assert power.conductance(4.9) == pytest.approx(1e-8 * 0.5**1.5, rel=1e-12)
    assert power.conductance(12.0) == 1e-8
    table = TableConductance(commands=(0.3, 1.0, 4.0, 9.0), conductances=(0.0, 1e-9, 6e-9, 1e-8))
    for u, c in zip(table.commands, table.conductances, strict=True):
        assert table.conductance(u) == pytest.approx(c, rel=1e-12, abs=1e-24)
    grid = np.linspace(0.0, 10.0, 401)
    values = np.array([table.conductance(u) for u in grid])
    assert np.all(np.diff(values) >= -1e-24)  # monotone (PCHIP)
    # an opening-dependent critical ratio moves linearly with the open fraction
    path = PowerConductance(C_max=1e-8, u0=0.4, u_sat=9.4, n=1.0, b=0.3, b_small=0.45)
    assert path.critical_ratio(4.9) == pytest.approx(0.375, rel=1e-12)


def test_flow_test_is_the_static_characteristic() -> None:
    """A flow test returns q_m(P_held, u) of the valve, gas at ambient temperature (exact)."""
    cfg = get_truth("mixed")
    n = 6
    held = np.array([2e5, 2e5, 4e5, 4e5, 6e5, 6e5])
    u = np.array([-10.0, 3.0, -1.5, 1.5, -0.6, 10.0])
    exp = Experiment(np.arange(n) * 0.01, "flow", chamber="P", p_chamber=held, u_P=u, name="f")
    sim = TruthSimulator(cfg).simulate(PAR, exp)
    assert sim.ok
    t_a = PAR["ambient_temperature"]
    for k in range(n):
        expected = cfg.valve.net_flow(u[k], held[k], t_a, PAR["supply_pressure"],
                                      PAR["exhaust_pressure"], t_a)  # fmt: skip
        assert sim["qm_P"][k] == expected
    assert sim["qm_P"][1] > 0.0 > sim["qm_P"][0]


# ----------------------------------------------------------------------------
# chamber balance
# ----------------------------------------------------------------------------
def test_mass_conservation_on_a_blocked_charge() -> None:
    """Mass let in by the valve (integrated net flow) equals the change of P V / (r T).

    The ODE integrates P and T, not the mass, so this checks the dT/dt line
    of the balance against dP/dt. Both sides carry the integrator's relative
    error (rtol 1e-8 per step, accumulating over ~1e3 steps); 1e-6 of the
    mass change (~7e-4 kg) leaves that margin and is 1000 times smaller than
    a wrong factor in any flow term would give.
    """
    sim = TruthSimulator(get_truth("power-valve")).simulate(PAR, _charge())
    assert sim.ok, sim.message
    vol = PAR["dead_volume_P"] + S_P * 0.15
    mass = sim["p_P"] * vol / (R_GAS * sim["T_P"])
    change = mass - mass[0]
    assert change[-1] > 5e-4
    assert np.max(np.abs(sim["m_P"] - change)) < 1e-6 * change[-1]
    # heat flows: the gas cooled after the valve closed
    assert sim["T_P"][-1] < sim["T_P"][300]


def test_adiabatic_charge_end_temperature() -> None:
    """With xi = 0 and no leak the end state of a charge is the adiabatic filling's.

    Energy balance of a rigid chamber filled from a reservoir at T_s:
    c_v (m T)_end = c_v (m T)_0 + c_p T_s dm, with m = P V / (r T), gives
    T_end = P_end / (P_0 / T_0 + (P_end - P_0) / (gamma T_s)). The two sides
    agree to the integrator's relative error (1e-8 per step); 1e-3 K is a
    hundred times above it and far below the ~100 K heating being checked.
    """
    cfg = _config(heat={"xi": 0.0}, leak={"shape": "none"})
    sim = TruthSimulator(cfg).simulate(PAR, _charge())
    assert sim.ok, sim.message
    p_0, t_0 = sim["p_P"][0], sim["T_P"][0]
    p_end = sim["p_P"][-1]
    t_s = PAR["ambient_temperature"]
    expected = p_end / (p_0 / t_0 + (p_end - p_0) / (GAMMA * t_s))
    assert sim["T_P"][-1] == pytest.approx(expected, abs=1e-3)
    assert expected > t_0 + 80.0
    # closed, adiabatic and rigid: the state stays put after the valve closed
    assert np.ptp(sim["p_P"][400:]) < 1e-2


# ----------------------------------------------------------------------------
# friction
# ----------------------------------------------------------------------------
def _hold(config: TruthConfig, force_ratio: float) -> tuple[np.ndarray, float]:
    """Piston from rest under a constant net pressure force, valves shut (no leak).

    The bristles start loaded to half the force, as after a slow load ramp
    that a sudden release then completes.
    """
    friction: LuGreFriction = config.friction
    p_n = 4.0e5
    p_e = PAR["exhaust_pressure"]
    delta = 0.0  # pressure excess of the seals, filled below
    p_p = p_n
    for _ in range(3):  # the static level depends on the pressures through the seals
        delta = p_p + p_n - 2.0 * p_e
        drive = force_ratio * friction.breakaway(delta)
        p_p = (drive + S_N * p_n + p_e * (S_P - S_N)) / S_P
    t = np.arange(1001) * 1e-3
    zero = np.zeros(t.size)
    z_0 = 0.5 * drive / friction.sigma0
    exp = Experiment(t, "free", u_P=zero, u_N=zero, name="hold",
                     initial={"y": 0.25, "p_P": p_p, "p_N": p_n, "z": z_0})  # fmt: skip
    sim = TruthSimulator(config).simulate(PAR, exp)
    assert sim.ok, sim.message
    return sim["y"], friction.breakaway(delta)


def test_lugre_holds_below_breakaway() -> None:
    """LuGre holds the piston at 70 % of the breakaway force, and lets it go at 115 %.

    Below breakaway the piston moves only by pre-sliding, which in LuGre
    grows like (F_s / sigma0) ln(1 / (1 - F / F_s)) and overshoots with the
    lightly damped bristles: 0.3 mm here, bounded by 2 F_s / sigma0 = 0.4 mm;
    then it stays, < 1 um over the last half second (LuGre's residual drift
    is ~0.2 um), against centimetres if it slid. Above, it slides by
    centimetres within the second. (A load applied at once can break away
    below F_s, the dynamic load factor of a step: 85 % already slips here.)
    """
    cfg = _config(leak={"shape": "none"}, friction={"seal": "multiplicative", "k_p": 4e-7})
    y, f_s = _hold(cfg, 0.70)
    assert abs(y[-1] - y[0]) < 2.0 * f_s / cfg.friction.sigma0
    assert abs(y[-1] - y[500]) < 1e-6
    y, _ = _hold(cfg, 1.15)
    assert y[-1] - y[0] > 0.01


def test_step_test_converges_across_methods() -> None:
    """A closed-loop step test: LSODA at rtol 1e-8 agrees with Radau at rtol 1e-10.

    Two different integrators (Adams/BDF switching vs implicit Runge-Kutta)
    at tolerances 100 times apart: their difference estimates the truth's
    own integration error. Measured 0.06 Pa and 1e-8 m on this test; the
    bounds (1 Pa, 1e-7 m) are ten times that and 400 times below the rig's
    pressure-sensor noise (400 Pa).
    """
    s_p, s_n = S_P, S_N
    p_e = PAR["exhaust_pressure"]
    p_n = 0.5 * (PAR["supply_pressure"] + p_e)
    p_p = (p_n * s_n + p_e * (s_p - s_n)) / s_p
    n_pre, n = 500, 1501
    y_ref = np.full(n_pre + n, 0.25)
    y_ref[n_pre + 200 :] = 0.34
    y_ref[n_pre + 900 :] = 0.2
    exp = Experiment(np.arange(n_pre + n) * 1e-3, "step", y_ref=y_ref, controller=PD(60.0, 4.0),
                     initial={"y": 0.25, "p_P": p_p, "p_N": p_n}, name="step")  # fmt: skip
    cfg = get_truth("mixed")
    fast = TruthSimulator(cfg, rtol=1e-8).simulate(PAR, exp)
    fine = TruthSimulator(cfg, rtol=1e-10, method="Radau").simulate(PAR, exp)
    assert fast.ok and fine.ok
    for name in ("p_P", "p_N"):
        assert np.max(np.abs(fast[name] - fine[name])) < 1.0
    assert np.max(np.abs(fast["y"] - fine["y"])) < 1e-7
    assert np.ptp(fast["y"]) > 0.1  # the piston did travel
