"""Compiled right-hand side of the actuator models and its integrator.

State (see :mod:`pneumafit.models.layout`): x = [y, v, P_N, P_P, T_N, T_P,
m_supply, m_exhaust, Tw_N, Tw_P, us_N, us_P, dus_N, dus_P, z_f]; a structure
uses a subset (the polytropic model keeps T = T_w, the optional states stay
constant unless their effect is on, z_f unless the friction law is LuGre).

Chamber balance (paper eqs. 2-5 rewritten in P and T; the paper's eq. 9 drops
the gas constant r from the flow terms, restored here). With H = sum q_i T_i
the enthalpy-carrying flow into the chamber (inflows at their upstream
temperature, outflows at T), q = sum q_i the net mass flow, V(y), dV/dt and
Q = lambda A (T_w - T):

    dP/dt = gamma r H / V - gamma P dV/dt / V + (gamma - 1) Q / V
    dT/dt = T [dP/dt / P + dV/dt / V - r T q / (P V)]     (from P V = m r T)

which expands to the paper's dT/dt line of eq. 9. Polytropic model (eq. 14):
dP/dt = k r T_0 q / V - k P dV/dt / V, T = T_0 (T_0 = wall temperature).

Mechanics (eq. 1): M dv/dt = S_P P_P - S_N P_N - F_ext - F_f + F_stop, with
F_ext = P_atm (S_P - S_N) + F_load + M g sin(angle) and one of two friction
laws (configuration slot C_FRICTION_LAW, :mod:`pneumafit.physics.friction`):

- the switch model of stick-slip (0): the piston's mode (stuck, sliding
  forwards, sliding backwards) is a discrete state kept by the integrator,
  which locates the mode changes inside the step;
- LuGre (1): the bristle deflection z_f is a continuous state, the piston
  always obeys M dv/dt = F_d - F_f, and the integrator's mode logic and event
  location are bypassed. The bristle relaxation rate is limited to
  LUGRE_RATE_LIMIT / h for the step h in use (slot D_ZRATE of the derived
  constants, set by :func:`integrate`; unlimited elsewhere, e.g. for the
  scipy reference solver), see :func:`pneumafit.physics.friction.lugre_friction`.

Seal and barrel effects (:mod:`pneumafit.physics.seal_effects`, shared with
the friction-test model): ``seal_friction`` adds c_p max(P_P + P_N - 2 P_atm, 0)
to F_s and F_c; ``friction_asymmetry`` multiplies both levels by 1 + a s,
s the sliding direction (LuGre: sign v; a stuck piston: the sign of F_d, so
it breaks away at F_s (1 + a) forwards and F_s (1 - a) backwards);
``effective_area`` replaces the bore by D sqrt(k_A) everywhere (piston
areas in the force and in V, dV/dt, exchange areas), the rod unchanged.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from pneumafit.models.layout import (
    C_AIRPROPS,
    C_AREA_FACTOR,
    C_BLOCKED,
    C_CHAMBER,
    C_CHAMBER_LEAK,
    C_EXTERNAL_LEAK,
    C_FORCED_CONV,
    C_FRICTION_ASYM,
    C_FRICTION_LAW,
    C_HEAT,
    C_INPUT,
    C_INPUT_HOLD,
    C_PART_EFFECTS,
    C_SEAL_FRICTION,
    C_STATIC_FLOW,
    C_SUPPLY_DROP,
    C_VALVE_LAW,
    C_VALVE_ORDER,
    C_WALL_MASS,
    CTRL_DB_AMPLITUDE,
    CTRL_DB_WIDTH,
    MAP_B_LOWER,
    MAP_B_UPPER,
    MAP_C_LOWER,
    MAP_C_UPPER,
    N_MAP_KNOTS,
    NX,
    P_AENDS,
    P_ANGLE,
    P_AREA,
    P_BE,
    P_BETA,
    P_BORE,
    P_BS,
    P_CE,
    P_CLEAK,
    P_CS,
    P_CSTOP,
    P_FASYM,
    P_FC,
    P_FCG,
    P_FEXT,
    P_FS,
    P_FULLE,
    P_FULLS,
    P_FV,
    P_GCL,
    P_GEL,
    P_GES,
    P_K,
    P_KNEEE,
    P_KNEES,
    P_KSTOP,
    P_LAMBDA,
    P_LEAKW,
    P_LEN,
    P_MAP_BE,
    P_MAP_BS,
    P_MAP_CE,
    P_MAP_CS,
    P_MASS,
    P_NE,
    P_NS,
    P_NULL,
    P_OVERLAP,
    P_PE,
    P_PS,
    P_ROD,
    P_RSUP,
    P_SEAL,
    P_SIG0,
    P_SIG1,
    P_STROKE,
    P_TAMB,
    P_TW,
    P_USAT,
    P_V0N,
    P_V0P,
    P_VM,
    P_VST,
    P_VTAU,
    P_VWN,
    P_VZETA,
    P_WCAP,
    P_WOUT,
    P_XI,
    P_XLAM,
    PARAMETER_SPECS,
    X_DUN,
    X_DUP,
    X_E0,
    X_ME,
    X_MS,
    X_PN,
    X_PP,
    X_TN,
    X_TP,
    X_TWN,
    X_TWP,
    X_UN,
    X_UP,
    X_V,
    X_Y,
    X_Z,
)
from pneumafit.numba_stamp import njit
from pneumafit.physics.air import G0, GAMMA, R_AIR, RHO0, T_REF, conductivity, viscosity
from pneumafit.physics.friction import (
    FASTMATH,
    LUGRE_MIN_LEVEL,
    LUGRE_RATE_LIMIT,
    end_stop_force,
    lugre_friction,
    next_mode,
    sliding_friction,
)
from pneumafit.physics.geometry import chamber_volumes, piston_areas
from pneumafit.physics.heat import convection_coefficient, convection_coefficient_scaled
from pneumafit.physics.valve import (
    NVC,
    VC_KE,
    VC_KS,
    VC_NE,
    VC_NS,
    VC_RTA,
    flows_core,
    laminar_tail,
    valve_constants,
)
from pneumafit.physics.valve_map import (
    NVM,
    VM_BE,
    VM_BS,
    VM_CE_LO,
    VM_CS_HI,
    flows_core_map,
    map_constants,
)

# Derived per-simulation constants (array d), computed once by derive()
D_SP, D_SN, D_FEXT, D_MU, D_KAIR, D_LAMC, D_GRC, D_RTA = 0, 1, 2, 3, 4, 5, 6, 7
D_A0P, D_A0N, D_CAP, D_CAN, D_IPS, D_IM = 8, 9, 10, 11, 12, 13
D_ZRATE = 14  # largest LuGre bristle relaxation rate (1/s): inf, or LUGRE_RATE_LIMIT / h
# geometry of the effective bore D sqrt(area_factor) (effect effective_area):
# piston areas S_P, S_N and exchange-area constants A0P, CAP, A0N, CAN
D_SPK, D_SNK, D_A0PK, D_CAPK, D_A0NK, D_CANK = 15, 16, 17, 18, 19, 20
D_VC = 21  # valve constants (physics.valve.valve_constants), NVC of them
D_VM = D_VC + NVC  # valve-map constants (physics.valve_map.map_constants), NVM of them
ND = D_VM + NVM

# Valve laws (configuration slot C_VALVE_LAW; layout.VALVE_LAWS)
VALVE_ISO6358 = 0
VALVE_MAP = 1

# Friction laws (configuration slot C_FRICTION_LAW; layout.FRICTION_LAWS)
FRICTION_SWITCH = 0
FRICTION_LUGRE = 1

# Auxiliary outputs of one right-hand-side evaluation (array aux)
A_QN, A_QP, A_UN, A_UP, A_LAMN, A_LAMP, A_FF, A_FD, A_FS = 0, 1, 2, 3, 4, 5, 6, 7, 8
NAUX = 9

# Simulation status codes
STATUS_OK = 0
STATUS_NONFINITE = 1
STATUS_NONPHYSICAL = 2
STATUS_BAD_PARAMETERS = 3
STATUS_BAD_INPUT = 4

_FM = FASTMATH
#: 0, 1, True and False as run-time values for the compiled functions' calls
#: to one another. A literal argument (``rhs(x, 0, ...)``) is typed as that
#: constant (``Literal[int](0)``) and numba compiles the callee once more for
#: it, and everything it calls: the warm-up's serial simulation compiled
#: rk_step six times and integrate_from twice. Numpy scalars are typed as
#: int64 and bool, so each function is compiled once per entry point. A
#: variable that starts at a literal and changes later (``k = 0`` before
#: ``k += span``) is typed as the literal first, and its calls compiled for
#: it, before numba's inference widens it: such variables start here too.
_I0 = np.int64(0)
_I1 = np.int64(1)
_TRUE = np.bool_(True)
_FALSE = np.bool_(False)

# The functions called once per stage (rhs, commands, rk_step and what they
# call, down to the valve laws) are compiled with ``_nrt=False``: numba's
# reference counting otherwise increments and decrements, with atomic
# instructions in out-of-line calls, the count of every array argument and
# slice at every call that LLVM does not inline. That was 60 % of the CPU time
# of the benchmark step test (5.0 -> 2.1 ms per simulation, results bit for
# bit). Such functions cannot allocate arrays (numba refuses to compile it);
# the arrays they use are owned by their caller (integrate), which keeps them
# alive. tests/test_simulator.py checks the list.


@njit(cache=True)
def check_parameters(p: np.ndarray) -> bool:
    """Return True when the parameter vector is physically admissible."""
    for i in range(p.shape[0]):
        if not math.isfinite(p[i]):
            return False
    if p[P_BORE] <= 0.0 or p[P_ROD] < 0.0 or p[P_ROD] >= p[P_BORE]:
        return False
    if p[P_STROKE] <= 0.0 or p[P_V0P] <= 0.0 or p[P_V0N] <= 0.0 or p[P_MASS] <= 0.0:
        return False
    if p[P_PS] <= 0.0 or p[P_PE] <= 0.0 or p[P_TAMB] <= 0.0 or p[P_TW] <= 0.0:
        return False
    if p[P_CS] < 0.0 or p[P_CE] < 0.0 or p[P_CLEAK] < 0.0 or p[P_LEAKW] <= 0.0:
        return False
    if p[P_NS] < 1.0 / 3.0 or p[P_NE] < 1.0 / 3.0:
        return False
    if p[P_BS] < 0.0 or p[P_BE] < 0.0 or p[P_BS] >= p[P_XLAM] or p[P_BE] >= p[P_XLAM]:
        return False
    if p[P_XLAM] >= 1.0 or p[P_VM] <= 0.0 or p[P_USAT] <= p[P_OVERLAP] or p[P_OVERLAP] < 0.0:
        return False
    if p[P_FULLS] > 1.0 or p[P_FULLE] > 1.0 or p[P_KNEES] < 1.0 or p[P_KNEEE] < 1.0:
        return False
    if p[P_FULLS] * p[P_USAT] <= p[P_OVERLAP] or p[P_FULLE] * p[P_USAT] <= p[P_OVERLAP]:
        return False
    if p[P_K] < 1.0 or p[P_LAMBDA] < 0.0 or p[P_XI] < 0.0 or p[P_BETA] <= 0.0:
        return False
    if p[P_FS] < p[P_FC] or p[P_FC] < 0.0 or p[P_FV] < 0.0 or p[P_VST] <= 0.0:
        return False
    if p[P_LEN] <= 0.0 or p[P_GCL] < 0.0 or p[P_GEL] < 0.0 or p[P_VTAU] < 0.0:
        return False
    if p[P_WCAP] <= 0.0 or p[P_KSTOP] < 0.0 or p[P_CSTOP] < 0.0:
        return False
    if p[P_SIG0] <= 0.0 or p[P_SIG1] < 0.0:
        return False
    if p[P_SEAL] < 0.0 or not -1.0 < p[P_FASYM] < 1.0:
        return False
    if not -1.0 <= p[P_GES] <= 1.0 or not p[P_AENDS] >= 0.0:
        return False
    # effective area: the bore's area k_A pi D^2 / 4 must exceed the rod's
    if p[P_AREA] <= 0.0 or p[P_AREA] * p[P_BORE] * p[P_BORE] <= p[P_ROD] * p[P_ROD]:
        return False
    # valve map (checked whatever the law: the defaults are admissible)
    for i in range(N_MAP_KNOTS):
        for c in (p[P_MAP_CS + i], p[P_MAP_CE + i]):
            if c < MAP_C_LOWER or c > MAP_C_UPPER:
                return False
    for i in range(3):
        for b in (p[P_MAP_BS + i], p[P_MAP_BE + i]):
            if b < MAP_B_LOWER or b > MAP_B_UPPER or b >= p[P_XLAM]:
                return False
    return True


@njit(cache=True)
def admissible(p: np.ndarray, cfg: np.ndarray) -> bool:
    """:func:`check_parameters`, and what the configuration needs of ``p``: a
    first-order valve (effect valve_dynamics, option 1) a time constant > 0
    (its rate is (u_cmd - u) / tau; tau = 0, the parameter's default, raised
    ZeroDivisionError from the compiled code instead of a failed status)."""
    if not check_parameters(p):
        return False
    return not (cfg[C_VALVE_ORDER] == 1 and p[P_VTAU] <= 0.0)


@njit(cache=True)
def valve_arrays(p: np.ndarray, vc: np.ndarray, vm: np.ndarray) -> None:
    """Fill the ISO 6358 constants vc (NVC) and the valve-map constants vm (NVM).

    Both are filled whatever the configured law (derive() does not see the
    configuration); the map's PCHIP slopes cost ~1 us once per simulation.
    """
    valve_constants(
        p[P_CS], p[P_BS], p[P_CE], p[P_BE], p[P_VM], p[P_XLAM], p[P_OVERLAP], p[P_USAT],
        p[P_CLEAK], p[P_LEAKW], p[P_PE], p[P_TAMB], vc, p[P_NS], p[P_NE], p[P_FULLS],
        p[P_FULLE], p[P_NULL], p[P_KNEES], p[P_KNEEE],
    )  # fmt: skip
    n = N_MAP_KNOTS
    map_constants(p[P_MAP_CS:P_MAP_CS + n], p[P_MAP_CE:P_MAP_CE + n], p[P_MAP_BS:P_MAP_BS + 3],
                  p[P_MAP_BE:P_MAP_BE + 3], p[P_USAT], vm)  # fmt: skip


@njit(cache=True)
def _exchange_constants(
    bore: float, rod: float, s_p: float, s_n: float, v0_p: float, v0_n: float, ends: float
) -> tuple[float, float, float, float]:
    """Exchange areas A_P = A0P + CAP y, A_N = A0N + CAN (L - y) (physics.geometry):
    (A0P, CAP, A0N, CAN) in m^2, m, m^2, m; the dead volumes' walls as cylinders of
    the piston's section; heads, piston faces and rod counted with the share
    ``ends`` (parameter heat_area_ends)."""
    rod_e = ends * rod
    a0_n = 2.0 * ends * s_n + math.pi * (bore + rod_e) * v0_n / s_n if s_n > 0.0 else 0.0
    a0_p = 2.0 * ends * s_p + math.pi * bore * v0_p / s_p
    return a0_p, math.pi * bore, a0_n, math.pi * (bore + rod_e)


@njit(cache=True)
def derive(p: np.ndarray, d: np.ndarray) -> None:
    """Fill the per-simulation constants d (areas, forces, scales) from p."""
    bore = p[P_BORE]
    rod = p[P_ROD]
    s_p, s_n = piston_areas(bore, rod)
    d[D_SP] = s_p
    d[D_SN] = s_n
    # the effective bore of effect effective_area, D' = D sqrt(k_A): same rod,
    # S_P' = k_A S_P, S_N' = S_P' - pi d^2 / 4; P_atm (S_P - S_N) = P_atm S_rod
    # in D_FEXT does not depend on it
    bore_k = bore * math.sqrt(p[P_AREA]) if p[P_AREA] > 0.0 else bore
    d[D_SPK], d[D_SNK] = piston_areas(bore_k, rod)
    d[D_A0PK], d[D_CAPK], d[D_A0NK], d[D_CANK] = _exchange_constants(
        bore_k, rod, d[D_SPK], d[D_SNK], p[P_V0P], p[P_V0N], p[P_AENDS]
    )
    d[D_FEXT] = p[P_PE] * (s_p - s_n) + p[P_FEXT] + p[P_MASS] * G0 * math.sin(p[P_ANGLE])
    mu = viscosity(p[P_TW])
    k_air = conductivity(p[P_TW])
    d[D_MU] = mu
    d[D_KAIR] = k_air
    length = p[P_LEN]
    d[D_LAMC] = p[P_XI] * k_air / length
    d[D_GRC] = G0 * length**3 / (R_AIR * mu) ** 2
    d[D_RTA] = math.sqrt(T_REF / p[P_TAMB])
    d[D_A0P], d[D_CAP], d[D_A0N], d[D_CAN] = _exchange_constants(
        bore, rod, s_p, s_n, p[P_V0P], p[P_V0N], p[P_AENDS]
    )
    d[D_IPS] = 1.0 / p[P_PS]
    d[D_IM] = 1.0 / p[P_MASS]
    d[D_ZRATE] = math.inf  # exact LuGre law unless integrate() limits it to its step
    valve_arrays(p, d[D_VC:D_VM], d[D_VM:])


# ----------------------------------------------------------------- hooks for outside parts
# A heat, valve or friction law or an effect registered from outside the
# package with kernel code (``HeatLaw.kernel``, ``ValveLaw.kernel``,
# ``FrictionLaw.kernel`` and ``state_rate``, ``Effect.kernel``;
# pneumafit.models.part_kernel) is called through these functions. In
# this module, the cached kernel of the built-in parts, they do nothing: a
# structure that uses such a part runs
# on a copy of this module compiled with the hooks bound to its parts
# (``part_kernel.kernel_for``), never on this one.
@njit(cache=True, fastmath=_FM, _nrt=False)
def part_heat(heat: int, p: np.ndarray, pres: float, temp: float, t_wall: float) -> float:
    """lambda (W/m^2/K) of a heat law registered outside the package: none here (NaN)."""
    return math.nan


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_effects(
    mask: int, x: np.ndarray, p: np.ndarray
) -> tuple[float, float, float, float, float, float]:
    """Sum of the outside effects switched on in ``mask``: none here (zeros).

    Returns (q_P, H_P, q_N, H_N, q_atm, F): mass flows into the chambers
    (kg/s), the enthalpy they carry as sum q_i T_i (kg K/s), mass sent to
    atmosphere (kg/s) and force on the piston along +y (N).
    """
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_effect_rates(mask: int, x: np.ndarray, p: np.ndarray, dx: np.ndarray) -> None:
    """Rate of the state of an outside effect switched on in ``mask`` (slot
    X_E0 and above; ``Effect.states``, ``Effect.state_rate``): none here (zero)."""
    for i in range(X_E0, NX):
        dx[i] = 0.0


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_friction(
    law: int, v: float, f_s: float, f_c: float, x: np.ndarray, p: np.ndarray
) -> float:
    """Friction force (N, against the motion) of a friction law registered
    outside the package: none here (NaN)."""
    return math.nan


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_friction_rate(
    law: int, v: float, f_s: float, f_c: float, x: np.ndarray, p: np.ndarray, max_rate: float
) -> float:
    """Rate of the own state (slot X_Z) of a friction law registered outside the
    package (``FrictionLaw.state_rate``): none here (0, the state frozen)."""
    return 0.0


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_friction_stuck(law: int) -> bool:
    """Whether the friction law ``law``, registered outside the package, is a
    sliding force with the switch model's stuck mode and events
    (``FrictionLaw.stuck``): none here (False)."""
    return False


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_friction_sliding(
    law: int, v: float, s: float, f_s: float, f_c: float, x: np.ndarray, p: np.ndarray
) -> float:
    """Sliding friction force (N, against the motion) of an outside law with the
    switch model's modes, sliding in direction ``s`` (+-1, the mode; v may
    be 0 at breakaway): none here (NaN)."""
    return math.nan


@njit(cache=True, _nrt=False)
def friction_modes(cfg: np.ndarray) -> bool:
    """Whether the structure's friction law has the switch model's modes
    (stuck, sliding +-1) and events: the switch model, and a law from
    outside the package with ``FrictionLaw.stuck``; LuGre and the smooth
    outside laws have none."""
    law = cfg[C_FRICTION_LAW]
    return law == FRICTION_SWITCH or part_friction_stuck(law)


@njit(cache=True, fastmath=_FM, _nrt=False)
def part_valve(
    law: int, u: float, pres: float, temp: float, p_s: float, p: np.ndarray
) -> tuple[float, float, float]:
    """Flows of one valve under a valve law registered outside the package: none
    here (NaN).

    Returns (q_net, h_in, q_supply) as :func:`pneumafit.physics.valve.valve_flows`:
    net mass flow into the chamber (kg/s), the enthalpy it carries as
    sum q_i T_i (kg K/s) and the flow drawn from supply (kg/s).
    """
    return math.nan, math.nan, math.nan


@njit(cache=True, fastmath=_FM, _nrt=False)
def heat_coefficient(
    heat: int,
    p: np.ndarray,
    d: np.ndarray,
    sutherland: bool,
    pres: float,
    temp: float,
    t_wall: float,
) -> float:
    """lambda (W/m^2/K) of one chamber for the configured heat law."""
    if heat == 1:
        return p[P_LAMBDA]
    if heat == 2:
        if sutherland:
            return convection_coefficient(
                p[P_XI], p[P_BETA], pres, temp, t_wall, p[P_LEN], viscosity(temp),
                conductivity(temp),
            )  # fmt: skip
        return convection_coefficient_scaled(d[D_LAMC], d[D_GRC], p[P_BETA], pres, temp, t_wall)
    if heat > 2:
        return part_heat(heat, p, pres, temp, t_wall)
    return 0.0


@njit(cache=True, fastmath=_FM, _nrt=False)
def chamber_rates(
    heat: int,
    k_poly: float,
    t_0: float,
    pres: float,
    inv_p: float,
    temp: float,
    vol: float,
    dvol: float,
    q_net: float,
    h_net: float,
    q_wall: float,
) -> tuple[float, float]:
    """(dP/dt, dT/dt) of one chamber (Pa/s, K/s); see the module docstring."""
    inv_v = 1.0 / vol
    if heat == 0:
        return k_poly * (R_AIR * t_0 * q_net - pres * dvol) * inv_v, 0.0
    dp = (GAMMA * R_AIR * h_net - GAMMA * pres * dvol + (GAMMA - 1.0) * q_wall) * inv_v
    dt = temp * (dp * inv_p + (dvol - R_AIR * temp * q_net * inv_p) * inv_v)
    return dp, dt


@njit(cache=True, fastmath=_FM, _nrt=False)
def _valve(
    u: float,
    pres: float,
    inv_p: float,
    temp: float,
    rt: float,
    p_s: float,
    inv_ps: float,
    d: np.ndarray,
    law: int,
):
    # flows of one valve under the configured law (cfg[C_VALVE_LAW]); a law
    # from outside the package (code > VALVE_MAP) is called by the caller
    # (part_valve): a third branch here cost the built-in laws 3-6 % of a
    # simulation
    if law == VALVE_MAP:
        return flows_core_map(u, pres, inv_p, temp, rt, p_s, inv_ps, d[D_VC:D_VM], d[D_VM:])
    if (
        d[D_VC + VC_NS] == 1.0 and d[D_VC + VC_NE] == 1.0
        and d[D_VC + VC_KS] == 1.0 and d[D_VC + VC_KE] == 1.0
    ):  # fmt: skip
        # linear opening (the default): no pow in this path (flows_core's linear)
        return flows_core(u, pres, inv_p, temp, rt, p_s, inv_ps, d[D_VC:], True)
    return flows_core(u, pres, inv_p, temp, rt, p_s, inv_ps, d[D_VC:], False)


#: Parameters a flow test's simulation reads (``C_STATIC_FLOW``: the static
#: characteristic q_m(P, u) at the measured pressure, :func:`integrate`): the
#: valve laws' and the supply, exhaust and ambient conditions. No other
#: parameter moves a flow test (:meth:`pneumafit.identification.Problem.unaffected`).
STATIC_FLOW_PARAMETERS: frozenset[str] = frozenset(
    [s.name for s in PARAMETER_SPECS if s.group in ("valve", "valve_map")]
    + ["supply_pressure", "exhaust_pressure", "ambient_temperature"]
)


@njit(cache=True)
def static_valve_flows(
    p: np.ndarray, valve_law: int, u: float, pres: float, temp: float
) -> tuple[float, float, float]:
    """Flows of one valve at a given chamber state, under either valve law.

    Parameters
    ----------
    p : ndarray, shape (NP,)
        Parameters (SI); the supply and exhaust pressures, ambient
        temperature and the valve parameters of the law are used.
    valve_law : int
        0 ISO 6358, 1 measured map (``layout.VALVE_LAWS``), others a law
        registered outside the package (:func:`part_valve`).
    u : float
        Command (V).
    pres : float
        Chamber pressure (Pa), > 0.
    temp : float
        Chamber temperature (K), > 0.

    Returns
    -------
    q_net, h_in, q_supply : float
        Net mass flow into the chamber (kg/s), enthalpy-carrying flow
        sum(q_i T_i) (kg K/s), flow drawn from supply (kg/s); as
        :func:`pneumafit.physics.valve.valve_flows`.
    """
    vc = np.empty(NVC)
    vm = np.empty(NVM)
    valve_arrays(p, vc, vm)
    p_s = p[P_PS]
    rt = math.sqrt(T_REF / temp)
    if valve_law == VALVE_MAP:
        return flows_core_map(u, pres, 1.0 / pres, temp, rt, p_s, 1.0 / p_s, vc, vm)
    if valve_law > VALVE_MAP:
        return part_valve(valve_law, u, pres, temp, p_s, p)
    return flows_core(u, pres, 1.0 / pres, temp, rt, p_s, 1.0 / p_s, vc)


@njit(cache=True, fastmath=_FM, _nrt=False)
def rhs(
    x: np.ndarray,
    mode: int,
    u_p_cmd: float,
    u_n_cmd: float,
    p: np.ndarray,
    d: np.ndarray,
    cfg: np.ndarray,
    dx: np.ndarray,
    aux: np.ndarray,
) -> None:
    """Right-hand side dx/dt of the configured actuator model (paper eq. 9).

    Parameters
    ----------
    x : ndarray, shape (NX,)
        State (SI units, layout in :mod:`pneumafit.models.layout`).
    mode : {-1, 0, 1}
        Friction mode of the switch model: 0 stuck (v = 0, no motion), +-1
        sliding direction. Not used by the LuGre law.
    u_p_cmd, u_n_cmd : float
        Commands sent to the valves of chambers P and N (V).
    p : ndarray, shape (NP,)
        Parameters (SI).
    d : ndarray, shape (ND,)
        Per-simulation constants from :func:`derive`.
    cfg : ndarray of int64, shape (NCFG,)
        Structure configuration.
    dx : ndarray, shape (NX,)
        Output: time derivative of x.
    aux : ndarray, shape (NAUX,)
        Output: valve flows into the chambers (kg/s), effective commands (V),
        heat-transfer coefficients (W/m^2/K), friction, driving force and
        static friction (N).
    """
    heat = cfg[C_HEAT]
    blocked = cfg[C_BLOCKED] == 1
    y = x[X_Y]
    v = x[X_V]
    p_n = x[X_PN]
    p_p = x[X_PP]
    t_n = x[X_TN]
    t_p = x[X_TP]
    t_amb = p[P_TAMB]
    p_e = p[P_PE]
    # every slot of dx is written below, except the optional states (zeroed
    # here when their effect is off; the outside effects' states are set by
    # their hook when one is on) and the piston states (zeroed when stuck or
    # blocked)
    if cfg[C_WALL_MASS] == 0 and cfg[C_VALVE_ORDER] == 0:
        for i in range(8, NX):
            dx[i] = 0.0
    else:
        for i in range(X_E0, NX):
            dx[i] = 0.0

    # --- valve commands: static, or spool dynamics (effect valve_dynamics)
    order = cfg[C_VALVE_ORDER]
    if order < 2:
        dx[X_DUP] = 0.0
        dx[X_DUN] = 0.0
    if order == 0:
        dx[X_UP] = 0.0
        dx[X_UN] = 0.0
        u_p = u_p_cmd
        u_n = u_n_cmd
    else:
        u_p = x[X_UP]
        u_n = x[X_UN]
        if order == 1:
            tau = p[P_VTAU]
            dx[X_UP] = (u_p_cmd - u_p) / tau
            dx[X_UN] = (u_n_cmd - u_n) / tau
        else:
            wn = p[P_VWN]
            z2 = 2.0 * p[P_VZETA] * wn
            dx[X_UP] = x[X_DUP]
            dx[X_UN] = x[X_DUN]
            dx[X_DUP] = wn * wn * (u_p_cmd - u_p) - z2 * x[X_DUP]
            dx[X_DUN] = wn * wn * (u_n_cmd - u_n) - z2 * x[X_DUN]

    # --- geometry (nominal bore, or the effective one: effect effective_area)
    area = cfg[C_AREA_FACTOR] == 1
    if area:
        s_p = d[D_SPK]
        s_n = d[D_SNK]
    else:
        s_p = d[D_SP]
        s_n = d[D_SN]
    stroke = p[P_STROKE]
    v_p, v_n = chamber_volumes(y, stroke, s_p, s_n, p[P_V0P], p[P_V0N])
    dv_p = s_p * v
    dv_n = -s_n * v

    # --- valve flows (ISO 6358 or measured map), optional supply-line pressure drop
    law = cfg[C_VALVE_LAW]
    inv_pp = 1.0 / p_p
    inv_pn = 1.0 / p_n
    rt_p = math.sqrt(T_REF / t_p)
    rt_n = math.sqrt(T_REF / t_n)
    p_s = p[P_PS]
    inv_ps = d[D_IPS]
    q_p = h_p = qs_p = q_n = h_n = qs_n = 0.0
    for stage in range(2):
        # the flows at P_S; with the supply line's resistance once more at the
        # dropped pressure: one fixed-point iteration of P_S' = P_S - R (q_sP + q_sN)
        if stage == 1:
            q_draw = qs_p + qs_n
            if q_draw < 0.0:
                q_draw = 0.0
            p_s = p_s - p[P_RSUP] * q_draw
            if p_s < p_e:
                p_s = p_e
            inv_ps = 1.0 / p_s
        if law > VALVE_MAP:  # a law from outside the package
            q_p, h_p, qs_p = part_valve(law, u_p, p_p, t_p, p_s, p)
            q_n, h_n, qs_n = part_valve(law, u_n, p_n, t_n, p_s, p)
        else:
            q_p, h_p, qs_p = _valve(u_p, p_p, inv_pp, t_p, rt_p, p_s, inv_ps, d, law)
            q_n, h_n, qs_n = _valve(u_n, p_n, inv_pn, t_n, rt_n, p_s, inv_ps, d, law)
        if cfg[C_SUPPLY_DROP] != 1:
            break
    if blocked:
        if cfg[C_CHAMBER] == 1:
            qs_n = 0.0
            q_n = 0.0
        else:
            qs_p = 0.0
            q_p = 0.0
    qe_total = (qs_p - q_p) + (qs_n - q_n)
    aux[A_QN] = q_n
    aux[A_QP] = q_p
    aux[A_UN] = u_n
    aux[A_UP] = u_p

    # --- leakages (effects)
    if cfg[C_CHAMBER_LEAK] == 1:
        q_l = p[P_GCL] * (p_p - p_n)  # from P to N across the piston seal
        t_l = t_p if q_l > 0.0 else t_n
        q_p -= q_l
        h_p -= q_l * t_l
        q_n += q_l
        h_n += q_l * t_l
    if cfg[C_EXTERNAL_LEAK] == 1:
        # one conductance shared by the chambers as 1 + s : 1 - s (s = 0: equal)
        q_l = p[P_GEL] * (1.0 + p[P_GES]) * (p_p - p_e)
        t_l = t_p if q_l > 0.0 else t_amb
        q_p -= q_l
        h_p -= q_l * t_l
        q_l2 = p[P_GEL] * (1.0 - p[P_GES]) * (p_n - p_e)
        t_l2 = t_n if q_l2 > 0.0 else t_amb
        q_n -= q_l2
        h_n -= q_l2 * t_l2
        qe_total += q_l + q_l2
    f_part = 0.0
    if cfg[C_PART_EFFECTS] != 0:
        # effects registered outside the package (hook part_effects)
        e_qp, e_hp, e_qn, e_hn, e_qa, f_part = part_effects(cfg[C_PART_EFFECTS], x, p)
        q_p += e_qp
        h_p += e_hp
        q_n += e_qn
        h_n += e_hn
        qe_total += e_qa
        part_effect_rates(cfg[C_PART_EFFECTS], x, p, dx)

    # --- wall heat exchange (paper eqs. 6-8)
    wall_mass = cfg[C_WALL_MASS] == 1
    if wall_mass:
        tw_p = x[X_TWP]
        tw_n = x[X_TWN]
    else:
        tw_p = p[P_TW]
        tw_n = p[P_TW]
    sutherland = cfg[C_AIRPROPS] == 1
    lam_p = heat_coefficient(heat, p, d, sutherland, p_p, t_p, tw_p)
    lam_n = heat_coefficient(heat, p, d, sutherland, p_n, t_n, tw_n)
    if cfg[C_FORCED_CONV] == 1 and heat != 0:
        if qs_p > 0.0:
            lam_p += p[P_FCG] * qs_p
        if qs_n > 0.0:
            lam_n += p[P_FCG] * qs_n
    if area:
        a_p = d[D_A0PK] + d[D_CAPK] * y
        a_n = d[D_A0NK] + d[D_CANK] * (stroke - y)
    else:
        a_p = d[D_A0P] + d[D_CAP] * y
        a_n = d[D_A0N] + d[D_CAN] * (stroke - y)
    qw_p = lam_p * a_p * (tw_p - t_p)
    qw_n = lam_n * a_n * (tw_n - t_n)
    aux[A_LAMN] = lam_n
    aux[A_LAMP] = lam_p
    dx[X_TWP] = 0.0
    dx[X_TWN] = 0.0
    if wall_mass:
        c_w = p[P_WCAP]
        h_o = p[P_WOUT]
        dx[X_TWP] = (lam_p * (t_p - tw_p) + h_o * (t_amb - tw_p)) / c_w
        dx[X_TWN] = (lam_n * (t_n - tw_n) + h_o * (t_amb - tw_n)) / c_w

    # --- chambers
    t_0 = p[P_TW]
    k_poly = p[P_K]
    dp_p, dt_p = chamber_rates(heat, k_poly, t_0, p_p, inv_pp, t_p, v_p, dv_p, q_p, h_p, qw_p)
    dp_n, dt_n = chamber_rates(heat, k_poly, t_0, p_n, inv_pn, t_n, v_n, dv_n, q_n, h_n, qw_n)

    if blocked:
        # piston clamped: only the chamber under test evolves
        dx[X_Y] = 0.0
        dx[X_V] = 0.0
        if cfg[C_CHAMBER] == 1:
            dx[X_PP] = dp_p
            dx[X_TP] = dt_p
            dx[X_PN] = 0.0
            dx[X_TN] = 0.0
            dx[X_TWN] = 0.0
        else:
            dx[X_PN] = dp_n
            dx[X_TN] = dt_n
            dx[X_PP] = 0.0
            dx[X_TP] = 0.0
            dx[X_TWP] = 0.0
        dx[X_Z] = 0.0  # bristles frozen with the piston
        aux[A_FF] = 0.0
        aux[A_FD] = 0.0
        aux[A_FS] = 0.0
    else:
        dx[X_PP] = dp_p
        dx[X_TP] = dt_p
        dx[X_PN] = dp_n
        dx[X_TN] = dt_n
        f_stop = end_stop_force(y, v, stroke, p[P_KSTOP], p[P_CSTOP])
        f_drive = s_p * p_p - s_n * p_n - d[D_FEXT] + f_stop + f_part
        f_s = p[P_FS]
        f_c = p[P_FC]
        if cfg[C_SEAL_FRICTION] == 1:
            extra = p[P_SEAL] * (p_p + p_n - 2.0 * p_e)
            if extra > 0.0:
                f_s += extra
                f_c += extra
        # direction asymmetry: levels times (1 + a s), s the sliding direction
        # (LuGre and the laws from outside: sign v; stuck: the direction the
        # drive pushes, for the break-away level)
        asym = cfg[C_FRICTION_ASYM] == 1
        if asym:
            if not friction_modes(cfg):
                s_dir = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
            elif mode == 0:
                s_dir = 1.0 if f_drive > 0.0 else (-1.0 if f_drive < 0.0 else 0.0)
            else:
                s_dir = float(mode)
            scale = 1.0 + p[P_FASYM] * s_dir
            f_s *= scale
            f_c *= scale
        if cfg[C_FRICTION_LAW] == FRICTION_LUGRE:
            # LuGre: no stuck mode, the bristle state carries the pre-sliding
            dz, f_f = lugre_friction(v, x[X_Z], f_s, f_c, p[P_FV], p[P_VST], p[P_SIG0],
                                     p[P_SIG1], d[D_ZRATE])  # fmt: skip
            dx[X_Y] = v
            dx[X_V] = (f_drive - f_f) * d[D_IM]
            dx[X_Z] = dz
        elif not friction_modes(cfg):
            # a smooth law registered outside the package: no stuck mode
            law_f = cfg[C_FRICTION_LAW]
            f_f = part_friction(law_f, v, f_s, f_c, x, p)
            dx[X_Y] = v
            dx[X_V] = (f_drive - f_f) * d[D_IM]
            dx[X_Z] = part_friction_rate(law_f, v, f_s, f_c, x, p, d[D_ZRATE])
        elif mode == 0:
            f_f = f_drive  # stuck: friction balances the drive, v stays 0
            dx[X_Y] = 0.0
            dx[X_V] = 0.0
            dx[X_Z] = 0.0
        else:
            if cfg[C_FRICTION_LAW] == FRICTION_SWITCH:
                f_f = sliding_friction(v, mode, f_s, f_c, p[P_FV], p[P_VST])
            else:  # an outside law's sliding force, in the switch model's modes
                f_f = part_friction_sliding(cfg[C_FRICTION_LAW], v, mode, f_s, f_c, x, p)
            dx[X_Y] = v
            dx[X_V] = (f_drive - f_f) * d[D_IM]
            dx[X_Z] = 0.0
        aux[A_FF] = f_f
        aux[A_FD] = f_drive
        aux[A_FS] = f_s
    dx[X_MS] = qs_p + qs_n
    dx[X_ME] = qe_total


@njit(cache=True, fastmath=_FM, _nrt=False)
def commands(
    x: np.ndarray, inp: np.ndarray, k: int, w: float, cfg: np.ndarray, ctrl: np.ndarray
) -> tuple[float, float]:
    """Valve commands (u_P, u_N) (V) at fraction w of sample interval k.

    Sampled inputs (the measured commands, y_ref) are held between samples
    when ``cfg[C_INPUT_HOLD]`` is 1 (zero-order hold: sample k's value over
    [t_k, t_k+1], as a digital controller's output and set-point are), else
    interpolated linearly. Open loop: the measured commands.
    Closed loop, ``pd`` law: u_P = clip(u0 + kp (y_ref - y) - kd v, -umax,
    umax); state feedback: u_P = clip(c(v), -umax, umax), v = v_e - K (x - x_e)
    over x = [y, v, P_N, P_P, T_N, T_P] with the position of x_e following
    y_ref, and c the dead-band compensation c(v) = v + a tanh(v / w) (a, w in
    the ctrl slots CTRL_DB_AMPLITUDE, CTRL_DB_WIDTH; c(v) = v when w = 0);
    u_N = -u_P.
    """
    k1 = k + 1 if k + 1 < inp.shape[0] else k
    if cfg[C_INPUT_HOLD] == 1:
        w = 0.0
    law = cfg[C_INPUT]
    if law != 0:
        y_ref = (1.0 - w) * inp[k, 2] + w * inp[k1, 2]
        if law == 1:
            u = ctrl[2] + ctrl[0] * (y_ref - x[X_Y]) - ctrl[1] * x[X_V]
        else:
            u = ctrl[2] - ctrl[4] * (x[X_Y] - y_ref)
            for i in range(1, 6):
                u -= ctrl[4 + i] * (x[i] - ctrl[10 + i])
            if ctrl[CTRL_DB_WIDTH] > 0.0:
                u += ctrl[CTRL_DB_AMPLITUDE] * math.tanh(u / ctrl[CTRL_DB_WIDTH])
        umax = ctrl[3]
        if u > umax:
            u = umax
        elif u < -umax:
            u = -umax
        return u, -u
    return (1.0 - w) * inp[k, 0] + w * inp[k1, 0], (1.0 - w) * inp[k, 1] + w * inp[k1, 1]


@njit(cache=True, _nrt=False)
def active_states(cfg: np.ndarray) -> int:
    """Number of leading state slots that can change: 8 (y, v, P, T, air
    accounts) unless an effect adds wall-temperature or spool states, a
    friction law other than the switch model (LuGre, a law from outside the
    package) its state in the bristle slot, or an effect from outside the
    package its state (X_E0 and above: every slot, NX, which a copy of the
    kernel for outside effects sizes to their slots)."""
    if (
        cfg[C_WALL_MASS] == 1
        or cfg[C_VALVE_ORDER] > 0
        or not friction_modes(cfg)
        or cfg[C_PART_EFFECTS] != 0
    ):
        return NX
    return 8


@njit(cache=True, fastmath=_FM, _nrt=False)
def rk_step(
    x: np.ndarray,
    mode: int,
    inp: np.ndarray,
    k: int,
    w0: float,
    dw: float,
    h: float,
    p: np.ndarray,
    d: np.ndarray,
    cfg: np.ndarray,
    ctrl: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    kk: np.ndarray,
    xs: np.ndarray,
    dx: np.ndarray,
    aux: np.ndarray,
    xn: np.ndarray,
    first: bool = True,
) -> None:
    """One explicit Runge-Kutta step of size h (s) in a fixed friction mode.

    The step starts at fraction w0 of sample interval k and spans dw of it;
    xn receives the new state and aux the last stage's auxiliary values (the
    last node is c = 1, the end of the step). With ``first`` False, kk[0]
    already holds the first stage f(x) with the step's inputs (the end
    derivative of a spanning step before it, :func:`_span_samples`) and is
    not evaluated again.
    """
    n_st = tab_b.shape[0]
    nx = active_states(cfg)
    for i in range(nx, NX):
        xs[i] = x[i]
        xn[i] = x[i]
    if n_st == 4 and tab_c[1] == 0.5 and tab_a[2, 0] == 0.0 and tab_a[3, 2] == 1.0:
        # classical RK4, written out
        k1 = kk[0]
        k2 = kk[1]
        k3 = kk[2]
        k4 = kk[3]
        hh = 0.5 * h
        if first:
            u_p, u_n = commands(x, inp, k, w0, cfg, ctrl)
            rhs(x, mode, u_p, u_n, p, d, cfg, k1, aux)
        for i in range(nx):
            xs[i] = x[i] + hh * k1[i]
        u_p, u_n = commands(xs, inp, k, w0 + 0.5 * dw, cfg, ctrl)
        rhs(xs, mode, u_p, u_n, p, d, cfg, k2, aux)
        for i in range(nx):
            xs[i] = x[i] + hh * k2[i]
        u_p, u_n = commands(xs, inp, k, w0 + 0.5 * dw, cfg, ctrl)
        rhs(xs, mode, u_p, u_n, p, d, cfg, k3, aux)
        for i in range(nx):
            xs[i] = x[i] + h * k3[i]
        u_p, u_n = commands(xs, inp, k, w0 + dw, cfg, ctrl)
        rhs(xs, mode, u_p, u_n, p, d, cfg, k4, aux)
        h6 = h / 6.0
        for i in range(nx):
            xn[i] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
        return
    if n_st == 3 and tab_a[2, 0] == -1.0 and tab_a[2, 1] == 2.0 and tab_c[2] == 1.0:
        # Kutta's third-order method, written out: the default of every fit
        k1 = kk[0]
        k2 = kk[1]
        k3 = kk[2]
        if first:
            u_p, u_n = commands(x, inp, k, w0, cfg, ctrl)
            rhs(x, mode, u_p, u_n, p, d, cfg, k1, aux)
        hh = 0.5 * h
        for i in range(nx):
            xs[i] = x[i] + hh * k1[i]
        u_p, u_n = commands(xs, inp, k, w0 + 0.5 * dw, cfg, ctrl)
        rhs(xs, mode, u_p, u_n, p, d, cfg, k2, aux)
        for i in range(nx):
            xs[i] = x[i] + h * (2.0 * k2[i] - k1[i])
        u_p, u_n = commands(xs, inp, k, w0 + dw, cfg, ctrl)
        rhs(xs, mode, u_p, u_n, p, d, cfg, k3, aux)
        h6 = h / 6.0
        for i in range(nx):
            xn[i] = x[i] + h6 * (k1[i] + 4.0 * k2[i] + k3[i])
        return
    for s in range(0 if first else 1, n_st):
        for i in range(nx):
            acc = x[i]
            for r in range(s):
                acc += h * tab_a[s, r] * kk[r, i]
            xs[i] = acc
        u_p, u_n = commands(xs, inp, k, w0 + tab_c[s] * dw, cfg, ctrl)
        rhs(xs, mode, u_p, u_n, p, d, cfg, kk[s], aux)
    for i in range(nx):
        acc = 0.0
        for s in range(n_st):
            acc += tab_b[s] * kk[s, i]
        xn[i] = x[i] + h * acc


@njit(cache=True, fastmath=_FM, _nrt=False)
def _event_function(kind: int, xe: np.ndarray, aux: np.ndarray) -> float:
    # kind 0: sliding piston comes to rest (g = v); kind 1: stuck piston breaks
    # away (g = |F_d| - F_s)
    if kind == 0:
        return xe[X_V]
    return abs(aux[A_FD]) - aux[A_FS]


@njit(cache=True, fastmath=_FM, _nrt=False)
def locate_event(
    kind: int,
    g0: float,
    g1: float,
    x: np.ndarray,
    mode: int,
    inp: np.ndarray,
    k: int,
    w0: float,
    dw: float,
    h: float,
    p: np.ndarray,
    d: np.ndarray,
    cfg: np.ndarray,
    ctrl: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    kk: np.ndarray,
    xs: np.ndarray,
    dx: np.ndarray,
    aux: np.ndarray,
    xe: np.ndarray,
) -> float:
    """Fraction theta of the step at which the event function g changes sign.

    Illinois (modified regula falsi) iterations on g(theta), each g evaluated
    at the state reached by a Runge-Kutta sub-step of size theta h from the
    step's start in the current mode, so the event time is as accurate as the
    method (linear interpolation of g alone made the global error second
    order). On return xe holds the state at theta and aux the values there.
    """
    lo, g_lo = 0.0, g0
    hi, g_hi = 1.0, g1
    side = 0
    first = _TRUE
    theta = g_lo / (g_lo - g_hi) if g_lo != g_hi else 0.0
    for _ in range(8):
        rk_step(x, mode, inp, k, w0, theta * dw, theta * h, p, d, cfg, ctrl, tab_a, tab_b,
                tab_c, kk, xs, dx, aux, xe, first)  # fmt: skip
        u_p, u_n = commands(xe, inp, k, w0 + theta * dw, cfg, ctrl)
        rhs(xe, mode, u_p, u_n, p, d, cfg, dx, aux)
        g = _event_function(kind, xe, aux)
        tol = 1e-12 if kind == 0 else 1e-9  # m/s, N
        if abs(g) <= tol or hi - lo < 1e-12:
            return theta
        if (g > 0.0) == (g_lo > 0.0):
            lo, g_lo = theta, g
            if side == -1:
                g_hi *= 0.5
            side = -1
        else:
            hi, g_hi = theta, g
            if side == 1:
                g_lo *= 0.5
            side = 1
        theta = lo - g_lo * (hi - lo) / (g_hi - g_lo)
    rk_step(x, mode, inp, k, w0, theta * dw, theta * h, p, d, cfg, ctrl, tab_a, tab_b, tab_c,
            kk, xs, dx, aux, xe, first)  # fmt: skip
    u_p, u_n = commands(xe, inp, k, w0 + theta * dw, cfg, ctrl)
    rhs(xe, mode, u_p, u_n, p, d, cfg, dx, aux)
    return theta


@njit(cache=True, _nrt=False)
def _record(out: np.ndarray, row: int, x: np.ndarray, aux: np.ndarray, ch_sel: np.ndarray) -> None:
    # layout.CHANNELS: y v p_N p_P T_N T_P | qm_N qm_P u_N u_P lambda_N lambda_P | m_supply
    # m_exhaust | F_f  ->  states 0-5 | aux 0-5 | state X_MS | state X_ME | aux A_FF
    for j in range(ch_sel.shape[0]):
        c = ch_sel[j]
        if c < 6:
            out[row, j] = x[c]
        elif c < 12:
            out[row, j] = aux[c - 6]
        elif c == 12:
            out[row, j] = x[X_MS]
        elif c == 13:
            out[row, j] = x[X_ME]
        else:
            out[row, j] = aux[A_FF]


@njit(cache=True)
def _initial_state(x0: np.ndarray, p: np.ndarray, cfg: np.ndarray, x: np.ndarray) -> None:
    for i in range(NX):
        x[i] = x0[i]
    t_w = p[P_TW]
    if cfg[C_HEAT] == 0 or not math.isfinite(x[X_TN]):
        x[X_TN] = t_w
    if cfg[C_HEAT] == 0 or not math.isfinite(x[X_TP]):
        x[X_TP] = t_w
    if not math.isfinite(x[X_PN]):
        x[X_PN] = p[P_PE]
    if not math.isfinite(x[X_PP]):
        x[X_PP] = p[P_PE]
    if not math.isfinite(x[X_V]) or cfg[C_BLOCKED] == 1:
        x[X_V] = 0.0
    x[X_MS] = 0.0
    x[X_ME] = 0.0
    x[X_TWN] = t_w
    x[X_TWP] = t_w
    x[X_DUN] = 0.0
    x[X_DUP] = 0.0
    if not math.isfinite(x[X_Z]) and (cfg[C_FRICTION_LAW] != FRICTION_LUGRE or cfg[C_BLOCKED] == 1):
        x[X_Z] = 0.0  # unused (switch model) or frozen (blocked piston)
    for i in range(X_E0, NX):  # the outside effects' states: from 0 unless given
        if not math.isfinite(x[i]):
            x[i] = 0.0


@njit(cache=True, fastmath=_FM)
def _moving_levels(x: np.ndarray, p: np.ndarray, cfg: np.ndarray) -> tuple[float, float]:
    """Static and Coulomb levels (N) at state x with the seal-friction and
    asymmetry effects if on (the asymmetry's direction: sign v, none at rest)."""
    f_s = p[P_FS]
    f_c = p[P_FC]
    if cfg[C_SEAL_FRICTION] == 1:
        extra = p[P_SEAL] * (x[X_PP] + x[X_PN] - 2.0 * p[P_PE])
        if extra > 0.0:
            f_s += extra
            f_c += extra
    v = x[X_V]
    if cfg[C_FRICTION_ASYM] == 1 and v != 0.0:
        scale = 1.0 + p[P_FASYM] * (1.0 if v > 0.0 else -1.0)
        f_s *= scale
        f_c *= scale
    return f_s, f_c


@njit(cache=True, fastmath=_FM)
def steady_friction_state(x: np.ndarray, p: np.ndarray, cfg: np.ndarray) -> float:
    """The friction law's state (slot X_Z) of a piston sliding steadily at x[X_V].

    LuGre: sign(v) g(v) / sigma0 (:func:`initial_deflection`). A law from
    outside the package with a state of its own: the root in z of its rate
    (:func:`part_friction_rate`, unlimited), bracketed by doubling from
    1e-12 in the direction the rate moves z from 0 and refined by 60
    bisections; x[X_Z] itself when the rate vanishes at 0 (no state, or at
    rest) or no root lies within 1e-12 2^60 ~ 1e6 (the state's units). For residual
    attribution, which rebuilds states from measurements that do not give z.
    """
    law = cfg[C_FRICTION_LAW]
    if law == FRICTION_LUGRE:
        return initial_deflection(x, p, cfg, 0.0)
    z0 = x[X_Z]
    if friction_modes(cfg):  # the switch model or a law in its modes: no state
        return z0
    v = x[X_V]
    f_s, f_c = _moving_levels(x, p, cfg)
    x[X_Z] = 0.0
    r0 = part_friction_rate(law, v, f_s, f_c, x, p, math.inf)
    if not r0 != 0.0:  # zero or NaN
        x[X_Z] = z0
        return z0
    s = 1.0 if r0 > 0.0 else -1.0
    lo = 0.0
    hi = s * 1e-12
    found = False
    for _ in range(60):
        x[X_Z] = hi
        if part_friction_rate(law, v, f_s, f_c, x, p, math.inf) * s <= 0.0:
            found = True
            break
        lo = hi
        hi *= 2.0
    if not found:
        x[X_Z] = z0
        return z0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        x[X_Z] = mid
        if part_friction_rate(law, v, f_s, f_c, x, p, math.inf) * s > 0.0:
            lo = mid
        else:
            hi = mid
    x[X_Z] = z0
    return 0.5 * (lo + hi)


@njit(cache=True, fastmath=_FM)
def initial_deflection(x: np.ndarray, p: np.ndarray, cfg: np.ndarray, f_drive: float) -> float:
    """Initial LuGre bristle deflection z_f (m) of a moving-piston test.

    A piston at rest (v = 0) starts in static equilibrium if the bristles can
    hold it, z = clip(F_d / sigma0, -g(0) / sigma0, g(0) / sigma0) (the
    pre-sliding force sigma0 z balances the driving force F_d up to the
    static level g(0) = F_s); a moving one on its steady sliding deflection
    z = sign(v) g(v) / sigma0. Levels with the seal-friction and asymmetry
    effects if on.
    """
    f_s, f_c = _moving_levels(x, p, cfg)
    v = x[X_V]
    r = v / p[P_VST]
    g = max(f_c + (f_s - f_c) * math.exp(-r * r), LUGRE_MIN_LEVEL)
    z_max = g / p[P_SIG0]
    if v > 0.0:
        return z_max
    if v < 0.0:
        return -z_max
    return min(max(f_drive / p[P_SIG0], -z_max), z_max)


@njit(cache=True)
def _fail(out: np.ndarray, row: int, code: int) -> int:
    out[row:, :] = np.nan
    return code


@njit(cache=True, _nrt=False)
def initial_mode(
    x: np.ndarray,
    inp: np.ndarray,
    h0: float,
    p: np.ndarray,
    d: np.ndarray,
    cfg: np.ndarray,
    ctrl: np.ndarray,
    dx: np.ndarray,
    aux: np.ndarray,
) -> tuple[int, float, float]:
    """The first sample of a simulation: spool, LuGre deflection and friction mode.

    Shared by :func:`integrate` and the sampled closed loop
    (:mod:`pneumafit.simulation.sampled`). ``x`` is the initial state (set
    in place: the spool at the first command for a valve with dynamics, the
    bristle deflection in static equilibrium where it is NaN), ``inp`` the
    input table whose row 0 is the first sample, ``h0`` the first interval's
    step (s; LuGre's rate limit). On return ``aux`` holds the auxiliary
    values at the start in the mode returned.

    Returns
    -------
    mode : int
        Friction mode of the switch model (0 stuck, +-1 sliding; 0 for LuGre
        and blocked tests).
    fd_prev, fs_prev : float
        Driving force and static friction at the start (N), for the
        breakaway test of the first step.
    """
    blocked = cfg[C_BLOCKED] == 1
    # LuGre and the smooth laws from outside: no friction modes (the stuck
    # mode and event location are the switch model's)
    lugre = cfg[C_FRICTION_LAW] == FRICTION_LUGRE and not blocked
    smooth = not friction_modes(cfg) and not blocked
    stuck = _I0  # as a run-time int: see _I0
    u_p, u_n = commands(x, inp, stuck, 0.0, cfg, ctrl)
    if cfg[C_VALVE_ORDER] > 0:
        x[X_UP] = u_p
        x[X_UN] = u_n
    # initial friction mode
    mode = 0
    if smooth:
        d[D_ZRATE] = LUGRE_RATE_LIMIT / h0
    if lugre:
        if not math.isfinite(x[X_Z]):
            x[X_Z] = 0.0
            rhs(x, stuck, u_p, u_n, p, d, cfg, dx, aux)
            x[X_Z] = initial_deflection(x, p, cfg, aux[A_FD])
    rhs(x, stuck, u_p, u_n, p, d, cfg, dx, aux)
    if not blocked and not smooth:
        if x[X_V] > 0.0:
            mode = 1
        elif x[X_V] < 0.0:
            mode = -1
        else:
            mode = next_mode(aux[A_FD], aux[A_FS])
    fd_prev = aux[A_FD]
    fs_prev = aux[A_FS]
    if mode != 0:
        rhs(x, mode, u_p, u_n, p, d, cfg, dx, aux)
    return mode, fd_prev, fs_prev


@njit(cache=True)
def integrate_from(
    t: np.ndarray,
    inp: np.ndarray,
    nsub: np.ndarray,
    x: np.ndarray,
    mode: int,
    fd_prev: float,
    fs_prev: float,
    p: np.ndarray,
    d: np.ndarray,
    cfg: np.ndarray,
    ctrl: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    ch_sel: np.ndarray,
    out: np.ndarray,
    need_aux: bool,
    kk: np.ndarray,
    xs: np.ndarray,
    xn: np.ndarray,
    xe: np.ndarray,
    dx: np.ndarray,
    aux: np.ndarray,
) -> tuple[int, int, float, float]:
    """Integrate from sample 0 of ``t`` to its last, recording samples 1 on.

    The loop of :func:`integrate` after its start, and the sampled closed
    loop's step (:mod:`pneumafit.simulation.sampled`: a two-sample table,
    no channels), one code for both. Each sample interval is cut into
    ``nsub`` equal Runge-Kutta steps (:func:`rk_step`); in the switch model
    a sliding piston that stops and a stuck one that breaks away are located
    within their step (:func:`locate_event`) and the step is split there.

    Parameters
    ----------
    t, inp, nsub, p, cfg, ctrl, tab_a, tab_b, tab_c, ch_sel, out
        As :func:`integrate`.
    x : ndarray (NX,)
        State at ``t[0]``, replaced by the state at the last sample reached.
    mode : int
        Friction mode at ``t[0]`` (0 stuck, +-1 sliding).
    fd_prev, fs_prev : float
        Driving force and static friction (N) at ``t[0]``.
    d : ndarray (ND,)
        Derived constants (:func:`derive`).
    need_aux : bool
        Whether a recorded channel needs the auxiliary values (flows, forces).
    kk, xs, xn, xe, dx, aux : ndarray
        Work arrays (:func:`integrate`'s).

    Returns
    -------
    status : int
        STATUS_OK or why it stopped (``out`` NaN from there).
    mode, fd_prev, fs_prev
        The same at the last sample reached.
    """
    n = t.shape[0]
    blocked = cfg[C_BLOCKED] == 1
    # LuGre and the smooth laws from outside: no friction modes (the stuck
    # mode and event location are the switch model's), and a state whose relaxation
    # rate is limited to what the step can follow (D_ZRATE)
    smooth = not friction_modes(cfg) and not blocked
    nx = active_states(cfg)
    # a step that spans several sample intervals (nsub[k] = -m, m >= 2; see
    # simulation.simulator.substeps): its start state and derivative, and its end derivative,
    # for the cubic Hermite interpolant at the samples within it
    herm = np.empty((3, NX))
    fsal = False  # herm[2] holds f at x, with the inputs of sample k
    h_prev = 0.0
    k = _I0
    while k < n - 1:
        span = 1
        if nsub[k] < -1:
            span = min(-nsub[k], n - 1 - k)
        dt = t[k + span] - t[k]
        n_sub = nsub[k] if nsub[k] > 0 else 1
        h = dt / n_sub
        # w counts intervals from t_k: a span's inputs are constant over it
        dw = span / n_sub
        if smooth:
            d[D_ZRATE] = LUGRE_RATE_LIMIT / h
        for j in range(n_sub):
            w0 = j * dw
            # first same as last: a spanning step's end derivative is this
            # step's first stage (the same state, mode and inputs; LuGre's
            # rate limit the same only at the same step)
            first = not (j == 0 and fsal and (h == h_prev or not smooth))
            if not first:
                for i in range(nx):
                    kk[0, i] = herm[2, i]
            rk_step(x, mode, inp, k, w0, dw, h, p, d, cfg, ctrl, tab_a, tab_b, tab_c,
                    kk, xs, dx, aux, xn, first)  # fmt: skip
            if span > 1:
                for i in range(nx):
                    herm[0, i] = x[i]
                    herm[1, i] = kk[0, i]
            if blocked or smooth:
                pass
            elif mode != 0:
                if xn[X_V] * mode <= 0.0:
                    # the sliding piston came to rest within the step
                    theta = 0.0
                    if x[X_V] != 0.0:
                        theta = locate_event(_I0, x[X_V], xn[X_V], x, mode, inp, k, w0, dw, h, p,
                                             d, cfg, ctrl, tab_a, tab_b, tab_c, kk, xs, dx,
                                             aux, xe)  # fmt: skip
                    else:
                        for i in range(NX):
                            xe[i] = x[i]
                        u_p, u_n = commands(xe, inp, k, w0, cfg, ctrl)
                        rhs(xe, _I0, u_p, u_n, p, d, cfg, dx, aux)
                    xe[X_V] = 0.0
                    mode = next_mode(aux[A_FD], aux[A_FS])
                    we = w0 + theta * dw
                    rk_step(xe, mode, inp, k, we, (1.0 - theta) * dw, (1.0 - theta) * h, p, d,
                            cfg, ctrl, tab_a, tab_b, tab_c, kk, xs, dx, aux, xn, _TRUE)  # fmt: skip
                    if mode != 0 and xn[X_V] * mode < 0.0:
                        xn[X_V] = 0.0  # reversal overshoot; the next step re-decides
            elif abs(aux[A_FD]) > aux[A_FS]:
                # the last stage says the stuck piston breaks away: confirm at the
                # step's end, then locate |F_d| = F_s within the step
                u_p, u_n = commands(xn, inp, k, w0 + dw, cfg, ctrl)
                rhs(xn, _I0, u_p, u_n, p, d, cfg, dx, aux)
                e1 = abs(aux[A_FD]) - aux[A_FS]
                if e1 > 0.0:
                    direction = 1 if aux[A_FD] > 0.0 else -1
                    e0 = abs(fd_prev) - fs_prev
                    theta = 0.0
                    if e0 < 0.0:
                        theta = locate_event(_I1, e0, e1, x, _I0, inp, k, w0, dw, h, p, d, cfg,
                                             ctrl, tab_a, tab_b, tab_c, kk, xs, dx, aux,
                                             xe)  # fmt: skip
                    else:
                        for i in range(NX):
                            xe[i] = x[i]
                    mode = direction
                    we = w0 + theta * dw
                    rk_step(xe, mode, inp, k, we, (1.0 - theta) * dw, (1.0 - theta) * h, p, d,
                            cfg, ctrl, tab_a, tab_b, tab_c, kk, xs, dx, aux, xn, _TRUE)  # fmt: skip
            fd_prev = aux[A_FD]
            fs_prev = aux[A_FS]
            for i in range(NX):
                x[i] = xn[i]
        # health check once per sample (per step at the end of a span)
        for i in range(NX):
            if not math.isfinite(x[i]):
                return _fail(out, k + 1, STATUS_NONFINITE), mode, fd_prev, fs_prev
        if x[X_PP] <= 0.0 or x[X_PN] <= 0.0 or x[X_TP] <= 0.0 or x[X_TN] <= 0.0:
            return _fail(out, k + 1, STATUS_NONPHYSICAL), mode, fd_prev, fs_prev
        fsal = span > 1
        h_prev = h
        if span > 1:
            fd_prev, fs_prev = _span_samples(t, k, span, x, mode, inp, p, d, cfg, ctrl, nx,
                                             herm, xe, dx, aux, need_aux, ch_sel, out)  # fmt: skip
        if need_aux:
            u_p, u_n = commands(x, inp, k + span, 0.0, cfg, ctrl)
            rhs(x, mode, u_p, u_n, p, d, cfg, dx, aux)
        _record(out, k + span, x, aux, ch_sel)
        k += span
    return STATUS_OK, mode, fd_prev, fs_prev


@njit(cache=True, fastmath=_FM, _nrt=False)
def _span_samples(
    t: np.ndarray,
    k: int,
    span: int,
    x: np.ndarray,
    mode: int,
    inp: np.ndarray,
    p: np.ndarray,
    d: np.ndarray,
    cfg: np.ndarray,
    ctrl: np.ndarray,
    nx: int,
    herm: np.ndarray,
    xe: np.ndarray,
    dx: np.ndarray,
    aux: np.ndarray,
    need_aux: bool,
    ch_sel: np.ndarray,
    out: np.ndarray,
) -> tuple[float, float]:
    """Record the samples k+1 .. k+span-1 inside one step from t_k to
    t_k+span (dense output).

    Cubic Hermite interpolation between the step's start (state herm[0],
    derivative herm[1], the first stage) and its end (state x, derivative
    f(x) evaluated here into herm[2], with the span's inputs, which are
    constant over it). Its error is O(h^4) locally, below the 3rd-order
    method's own O(h^3) global error. A friction event inside the step
    (the switch model) puts a kink in v within it: there the interpolant is
    only first-order accurate in v, for that step alone.

    Returns
    -------
    fd, fs : float
        Driving force and static friction (N) at the step's end.
    """
    h = t[k + span] - t[k]
    # the inputs at t_k+span, equal to the span's (and exactly the next
    # step's first stage: integrate_from reuses herm[2])
    u_p, u_n = commands(x, inp, k + span, 0.0, cfg, ctrl)
    rhs(x, mode, u_p, u_n, p, d, cfg, dx, aux)
    for i in range(nx):
        herm[2, i] = dx[i]
    fd = aux[A_FD]
    fs = aux[A_FS]
    for j in range(1, span):
        s = (t[k + j] - t[k]) / h
        s2 = s * s
        s3 = s2 * s
        c00 = 2.0 * s3 - 3.0 * s2 + 1.0
        c10 = (s3 - 2.0 * s2 + s) * h
        c01 = -2.0 * s3 + 3.0 * s2
        c11 = (s3 - s2) * h
        for i in range(nx):
            xe[i] = c00 * herm[0, i] + c10 * herm[1, i] + c01 * x[i] + c11 * herm[2, i]
        for i in range(nx, NX):
            xe[i] = x[i]
        if need_aux:
            u_p, u_n = commands(xe, inp, k + j, 0.0, cfg, ctrl)
            rhs(xe, mode, u_p, u_n, p, d, cfg, dx, aux)
        _record(out, k + j, xe, aux, ch_sel)
    return fd, fs


@njit(cache=True)
def integrate(
    t: np.ndarray,
    inp: np.ndarray,
    nsub: np.ndarray,
    x0: np.ndarray,
    p: np.ndarray,
    cfg: np.ndarray,
    ctrl: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    ch_sel: np.ndarray,
    out: np.ndarray,
) -> int:
    """Integrate one recording with a fixed-step explicit Runge-Kutta method.

    Each sample interval [t_k, t_k+1] is split into nsub[k] equal steps
    (chosen from the largest step and from how fast the inputs change, see
    :func:`pneumafit.simulation.simulator.substeps`), so uneven sampling is
    followed exactly and the steps never depend on the parameters (a smooth
    log-likelihood; physics notes).
    Friction mode changes of the switch model (stick, slip, reversal) are
    located inside the step by :func:`locate_event` (v = 0 while sliding,
    |F_d| = F_s while stuck) and the step is split there. The LuGre law has
    no modes: its steps are plain Runge-Kutta steps, with the bristle
    relaxation rate limited to LUGRE_RATE_LIMIT / h (h the step of the
    sample interval), and a NaN initial z_f is replaced by
    :func:`initial_deflection`. Nor has a friction law registered from
    outside the package (:func:`part_friction`): plain steps too.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), strictly increasing.
    inp : ndarray, shape (n, 4)
        Inputs at the samples: u_P (V), u_N (V), y_ref (m), p_chamber (Pa).
    x0 : ndarray, shape (NX,)
        Initial state; NaN temperatures/pressures take the wall temperature /
        exhaust pressure.
    p, cfg, ctrl : ndarray
        Parameters, configuration, controller gains [kp, kd, u0, umax].
    nsub : ndarray of int64, shape (n,)
        Number of steps in each sample interval (last entry unused).
    tab_a, tab_b, tab_c : ndarray
        Butcher tableau of the explicit method (s stages, last node c = 1).
    ch_sel : ndarray of int64
        Indices (into layout.CHANNELS) of the channels to record.
    out : ndarray, shape (n, len(ch_sel))
        Output, filled with NaN after a failure.

    Returns
    -------
    int
        Status code (0 ok; see the STATUS_* constants).
    """
    n = t.shape[0]
    n_st = tab_b.shape[0]
    d = np.empty(ND)
    x = np.empty(NX)
    xs = np.empty(NX)
    xn = np.empty(NX)
    xe = np.empty(NX)
    kk = np.empty((n_st, NX))
    aux = np.zeros(NAUX)
    dx = np.empty(NX)
    if not admissible(p, cfg):
        return _fail(out, 0, STATUS_BAD_PARAMETERS)
    derive(p, d)
    _initial_state(x0, p, cfg, x)
    need_aux = _FALSE
    for j in range(ch_sel.shape[0]):
        if 6 <= ch_sel[j] < 12 or ch_sel[j] == 14:
            need_aux = True

    if cfg[C_STATIC_FLOW] == 1:
        # flow test: static characteristic q_m(P, u) at the measured chamber
        # pressure (inp column 3) and command, gas at ambient temperature
        on_p = cfg[C_CHAMBER] == 1
        x[X_TP] = p[P_TAMB]
        x[X_TN] = p[P_TAMB]
        for k in range(n):
            pres = inp[k, 3]
            u = inp[k, 0] if on_p else inp[k, 1]
            if not pres > 0.0:
                return _fail(out, k, STATUS_BAD_INPUT)
            rt_a = d[D_VC + VC_RTA]  # gas at ambient temperature
            if cfg[C_VALVE_LAW] > VALVE_MAP:
                q, _, _ = part_valve(cfg[C_VALVE_LAW], u, pres, p[P_TAMB], p[P_PS], p)
            else:
                q, _, _ = _valve(u, pres, 1.0 / pres, p[P_TAMB], rt_a, p[P_PS], d[D_IPS], d,
                                 cfg[C_VALVE_LAW])  # fmt: skip
            x[X_PP if on_p else X_PN] = pres
            aux[A_QP if on_p else A_QN] = q
            aux[A_UP if on_p else A_UN] = u
            _record(out, k, x, aux, ch_sel)
        return STATUS_OK

    # LuGre's rate limit needs the first interval's step
    h0 = 1.0
    if n > 1:
        h0 = (t[1] - t[0]) / nsub[0] if nsub[0] > 0 else t[min(max(-nsub[0], 1), n - 1)] - t[0]
    mode, fd_prev, fs_prev = initial_mode(x, inp, h0, p, d, cfg, ctrl, dx, aux)
    _record(out, _I0, x, aux, ch_sel)
    status, _, _, _ = integrate_from(
        t, inp, nsub, x, mode, fd_prev, fs_prev, p, d, cfg, ctrl, tab_a, tab_b, tab_c,
        ch_sel, out, need_aux, kk, xs, xn, xe, dx, aux,
    )  # fmt: skip
    return status


@njit(cache=True)
def _run_job(
    job: int,
    params: np.ndarray,
    cfgs: np.ndarray,
    ctrls: np.ndarray,
    x0s: np.ndarray,
    t_all: np.ndarray,
    inp_all: np.ndarray,
    nsub_all: np.ndarray,
    offsets: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    ch_sel: np.ndarray,
    out: np.ndarray,
    status: np.ndarray,
) -> None:
    n_rec = cfgs.shape[0]
    i = job // n_rec
    r = job - i * n_rec
    a = offsets[r]
    b = offsets[r + 1]
    status[i, r] = integrate(
        t_all[a:b], inp_all[a:b], nsub_all[a:b], x0s[i, r], params[i], cfgs[r], ctrls[r],
        tab_a, tab_b, tab_c, ch_sel, out[i, a:b],
    )  # fmt: skip


@njit(cache=True, parallel=True)
def integrate_many(
    params: np.ndarray,
    cfgs: np.ndarray,
    ctrls: np.ndarray,
    x0s: np.ndarray,
    t_all: np.ndarray,
    inp_all: np.ndarray,
    nsub_all: np.ndarray,
    offsets: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    ch_sel: np.ndarray,
    out: np.ndarray,
    status: np.ndarray,
) -> None:
    """Simulate every (parameter set, recording) pair, in parallel threads.

    Recordings are concatenated: recording r spans rows offsets[r]:offsets[r+1]
    of ``t_all``, ``inp_all`` and ``out[i]``.

    Parameters
    ----------
    params : ndarray, shape (n_sets, NP)
    cfgs, ctrls : per-recording configuration and controller.
    x0s : initial states, shape (n_sets, n_recordings, NX): one per pair, so
        that initial states can be parameters.
    nsub_all : steps per sample interval, rows as ``t_all``.
    out : ndarray, shape (n_sets, n_rows, n_channels)
    status : ndarray of int64, shape (n_sets, n_recordings)
    """
    for job in prange(params.shape[0] * cfgs.shape[0]):
        # prange's index is unsigned: as int64, the serial twin's _run_job
        _run_job(np.int64(job), params, cfgs, ctrls, x0s, t_all, inp_all, nsub_all, offsets,
                 tab_a, tab_b, tab_c, ch_sel, out, status)  # fmt: skip


@njit(cache=True, parallel=True)
def integrate_jobs(
    jobs: np.ndarray,
    params: np.ndarray,
    cfgs: np.ndarray,
    ctrls: np.ndarray,
    x0s: np.ndarray,
    t_all: np.ndarray,
    inp_all: np.ndarray,
    nsub_all: np.ndarray,
    offsets: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    ch_sel: np.ndarray,
    out: np.ndarray,
    status: np.ndarray,
) -> None:
    """:func:`integrate_many` for the listed (parameter set, recording) pairs
    only, job = set * n_recordings + recording; every other pair's rows of
    ``out`` and entry of ``status`` are left as they are.

    The threads take equal runs of ``jobs`` (numba's static schedule), so a
    caller orders it to balance their work."""
    for k in prange(jobs.size):
        _run_job(jobs[k], params, cfgs, ctrls, x0s, t_all, inp_all, nsub_all, offsets,
                 tab_a, tab_b, tab_c, ch_sel, out, status)  # fmt: skip


@njit(cache=True)
def integrate_many_serial(
    params: np.ndarray,
    cfgs: np.ndarray,
    ctrls: np.ndarray,
    x0s: np.ndarray,
    t_all: np.ndarray,
    inp_all: np.ndarray,
    nsub_all: np.ndarray,
    offsets: np.ndarray,
    tab_a: np.ndarray,
    tab_b: np.ndarray,
    tab_c: np.ndarray,
    ch_sel: np.ndarray,
    out: np.ndarray,
    status: np.ndarray,
) -> None:
    """Serial twin of :func:`integrate_many` (no thread start-up for one job)."""
    for job in range(params.shape[0] * cfgs.shape[0]):
        _run_job(job, params, cfgs, ctrls, x0s, t_all, inp_all, nsub_all, offsets,
                 tab_a, tab_b, tab_c, ch_sel, out, status)  # fmt: skip


@njit(cache=True)
def _part_valve_slope(p: np.ndarray, law: int) -> float:
    """Largest |dq_net/dP| (kg/s/Pa) of an outside valve law (:func:`part_valve`),
    by central differences on a grid: 9 commands over [-u_sat, u_sat] and 65
    chamber pressures from P_e to P_s, packed towards both ends, where a flow
    function with a laminar tail is steepest (its pressure ratio near 1); gas
    at ambient temperature, the densest a valve passes."""
    p_e = p[P_PE]
    p_s = p[P_PS]
    span = p_s - p_e
    delta = 1e-4 * span
    temp = p[P_TAMB]
    slope = 0.0
    for i in range(9):
        u = p[P_USAT] * (i / 4.0 - 1.0)
        for j in range(65):
            s = 0.5 - 0.5 * math.cos(math.pi * j / 64.0)  # Chebyshev points: denser at the ends
            pres = p_e + span * s
            pres = min(max(pres, p_e + delta), p_s - delta)
            q_hi, _, _ = part_valve(law, u, pres + delta, temp, p_s, p)
            q_lo, _, _ = part_valve(law, u, pres - delta, temp, p_s, p)
            slope = max(slope, abs(q_hi - q_lo) / (2.0 * delta))
    return slope


@njit(cache=True)
def _part_friction_mode(p: np.ndarray, law: int) -> float:
    """Rate bound (1/s) of the piston's friction mode under an outside friction law.

    The law's force F(v, z) (:func:`part_friction`) and its state's rate
    r(v, z) (:func:`part_friction_rate`, 0 without a state) linearised at
    rest (v = 0, z = 0, mid-stroke, both chambers at the mean of supply and
    exhaust, gas at ambient temperature) by central differences give the
    Jacobian of (v, z), J = [[-F_v / M, -F_z / M], [r_v, r_z]], trace T and
    determinant D. Its eigenvalues are bounded by |T| + 1.5 sqrt(|D|): the
    LuGre bound of :func:`stiffness_bound` for the LuGre law ((sigma1 + b) /
    M + 1.5 sqrt(sigma0 / M)), and F_v / M, a smooth law's damping at rest,
    without a state. The relaxation of a state in sliding is the law's to
    limit (``max_rate``, here unbounded: at rest it does not act).
    """
    x = np.zeros(NX)
    x[X_Y] = 0.5 * p[P_STROKE]
    x[X_PN] = 0.5 * (p[P_PS] + p[P_PE])
    x[X_PP] = x[X_PN]
    x[X_TN] = p[P_TAMB]
    x[X_TP] = p[P_TAMB]
    f_s = p[P_FS]
    f_c = p[P_FC]
    dv = 1e-7
    dz = 1e-10
    if part_friction_stuck(law):
        # a sliding force in the switch model's modes: no state, and its
        # slope one-sided (v -> 0+, sliding forwards: the levels jump at 0)
        f_1 = part_friction_sliding(law, dv, _I1, f_s, f_c, x, p)
        f_2 = part_friction_sliding(law, 2.0 * dv, _I1, f_s, f_c, x, p)
        bound = abs(f_2 - f_1) / dv / p[P_MASS]
        return bound if math.isfinite(bound) else 0.0
    f_hi = part_friction(law, dv, f_s, f_c, x, p)
    r_hi = part_friction_rate(law, dv, f_s, f_c, x, p, math.inf)
    f_lo = part_friction(law, -dv, f_s, f_c, x, p)
    r_lo = part_friction_rate(law, -dv, f_s, f_c, x, p, math.inf)
    f_v = (f_hi - f_lo) / (2.0 * dv)
    r_v = (r_hi - r_lo) / (2.0 * dv)
    x[X_Z] = dz
    f_hi = part_friction(law, 0.0, f_s, f_c, x, p)
    r_hi = part_friction_rate(law, 0.0, f_s, f_c, x, p, math.inf)
    x[X_Z] = -dz
    f_lo = part_friction(law, 0.0, f_s, f_c, x, p)
    r_lo = part_friction_rate(law, 0.0, f_s, f_c, x, p, math.inf)
    f_z = (f_hi - f_lo) / (2.0 * dz)
    r_z = (r_hi - r_lo) / (2.0 * dz)
    m = p[P_MASS]
    trace = -f_v / m + r_z
    det = -f_v / m * r_z + f_z / m * r_v
    bound = abs(trace) + 1.5 * math.sqrt(abs(det))
    return bound if math.isfinite(bound) else 0.0


@njit(cache=True)
def stiffness_bound(
    p: np.ndarray, y_min: float, y_max: float, valve_law: int = 0, friction_law: int = 0
) -> float:
    """Upper bound of the fastest rate of the model (1/s) over [y_min, y_max].

    The fastest pressure mode is a fully open valve near pressure equality,
    where the ISO 6358 laminar tail gives dq/dP = C rho0 sqrt(T_ref/T)
    phi(x_l) / (1 - x_l); with dP/dt = gamma r T q / V this is a rate
    gamma r T dq/dP / V at the smallest chamber volume. The piston modes
    (end-stop contact, viscous friction) are bounded by their own rates.
    ``valve_law`` 1 (measured map) takes the largest map conductance (at
    +-u_sat: the map is monotone and does not overshoot its knots) and the
    steepest tail over the map's critical ratios; 0 (default) the ISO law;
    a law registered outside the package its largest |dq/dP| on a grid
    (:func:`_part_valve_slope`).
    ``friction_law`` 1 (LuGre) adds the bristle mode of a piston in
    pre-sliding, M z'' = -sigma0 z - (sigma1 + b) z': its damping rate
    (sigma1 + b) / M plus 1.5 times its natural frequency sqrt(sigma0 / M)
    (1.5: an explicit method's stability interval on the imaginary axis is
    shorter than on the real one, sqrt(3) against 2.51 for Kutta's RK3). The
    bristle relaxation rate sigma0 |v| / g(v) is not bounded here: the
    kernel limits it to LUGRE_RATE_LIMIT / h, inside every method's interval.
    A law from outside the package adds the same bound taken from its
    force and state rate by central differences at rest
    (:func:`_part_friction_mode`).
    """
    d = np.empty(ND)
    derive(p, d)
    s_p = d[D_SP]
    s_n = d[D_SN]
    v_p, _ = chamber_volumes(y_min, p[P_STROKE], s_p, s_n, p[P_V0P], p[P_V0N])
    _, v_n = chamber_volumes(y_max, p[P_STROKE], s_p, s_n, p[P_V0P], p[P_V0N])
    v_min = min(v_p, v_n)
    c_max = 0.0
    slope = 0.0
    if valve_law == VALVE_MAP:
        c_max = max(d[D_VM + VM_CS_HI], d[D_VM + VM_CE_LO])
        # the tail slope a(b) over the range of b the map spans (b is linear
        # between its knots): sampled on a grid, ends included
        b_lo = 1.0
        b_hi = 0.0
        for i in range(3):
            for b in (d[D_VM + VM_BS + i], d[D_VM + VM_BE + i]):
                b_lo = min(b_lo, b)
                b_hi = max(b_hi, b)
        slope = 0.0
        for j in range(17):
            a, _ = laminar_tail(b_lo + (b_hi - b_lo) * j / 16.0, p[P_VM], p[P_XLAM])
            slope = max(slope, a)
    elif valve_law == VALVE_ISO6358:
        c_max = max(p[P_CS], p[P_CE]) + 2.0 * p[P_CLEAK]
        slope_s, _ = laminar_tail(p[P_BS], p[P_VM], p[P_XLAM])
        slope_e, _ = laminar_tail(p[P_BE], p[P_VM], p[P_XLAM])
        slope = max(slope_s, slope_e)
    t_hot = GAMMA * p[P_TAMB]  # hottest gas of a filling from supply at T_amb
    if valve_law > VALVE_MAP:
        dq_dp = _part_valve_slope(p, valve_law)
    else:
        # largest |d phi / dx| is the tail's slope at x = 1, a
        dq_dp = c_max * RHO0 * math.sqrt(T_REF / p[P_TAMB]) * slope
    rate_p = GAMMA * R_AIR * t_hot * dq_dp / v_min
    m = p[P_MASS]
    rate_stop = p[P_CSTOP] / m + math.sqrt(p[P_KSTOP] / m)
    rate_visc = p[P_FV] / m
    rate = max(rate_p, rate_stop, rate_visc)
    if friction_law == FRICTION_LUGRE:
        rate = max(rate, (p[P_SIG1] + p[P_FV]) / m + 1.5 * math.sqrt(p[P_SIG0] / m))
    elif friction_law > FRICTION_LUGRE:
        rate = max(rate, _part_friction_mode(p, friction_law))
    return rate
