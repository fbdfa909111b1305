"""Servo-distributor static flow characteristic (ISO 6358), per 3-way valve.

Each valve has a *supply path* (supply -> chamber) and an *exhaust path*
(chamber -> exhaust). A path is an ISO 6358 restriction of sonic conductance
C (m^3/s/Pa) and critical pressure ratio b:

    q = C rho0 P_up sqrt(T_ref / T_up) phi(x),   x = P_down / P_up

    phi(x) = 1                                    x <= b   (choked)
    phi(x) = [1 - ((x - b) / (1 - b))^2]^m        b < x < x_l
    phi(x) = a (1 - x) + c (1 - x)^2              x_l <= x <= 1 (laminar tail)

The ISO 6358 ellipse has an infinite slope at x -> 1; above x_l (0.995 by
default) the flow becomes linear in the pressure difference as x -> 1, as ISO
6358-1:2013 does, so the right-hand side stays Lipschitz (physics notes). The
tail is quadratic in (1 - x) with a and c chosen so that phi and its slope are
continuous at x_l (with s = 1 - x_l: a = 2 phi(x_l) / s + phi'(x_l),
c = (phi(x_l) - a s) / s^2); a straight line cannot be tangent to the ellipse
and its kink costs the integrator two orders of accuracy. The tail is monotone
for the usual b, m and x_l; its slope at x = 1, a, is the laminar conductance.
Flow reverses (sign and upstream temperature) when P_down > P_up, e.g. when a
chamber exceeds supply pressure.

Command dependence. For a command u (V), with overlap (dead band) u_0 and
full opening at u_sat:

    C_S(u) = C_S,max shape(open_S(u); n_S, k_S) + 2 C_leak sigma(+u / w)
    C_E(u) = C_E,max shape(open_E(-u); n_E, k_E) + 2 C_leak sigma(-u / w)

    shape(o; n, k) = 1 - (1 - o^n)^k             (o^n for k = 1)

    open_S(u) = min(ramp(u - u_0) / (f_S u_sat - u_0), 1)     (open_E likewise, f_E)
    sigma(z) = (1 + z / sqrt(1 + z^2)) / 2       (a smooth step from 0 to 1)

where ramp is max(z, 0) with its corner rounded over |z| < eps = 0.05 V
(:data:`OPENING_SMOOTHING`): ramp = 2 eps (t^3 - t^4 / 2), t = (z + eps) /
(2 eps), the integral of a smoothstep. It is exactly 0 below -eps and exactly
z above +eps, and twice continuously differentiable: a kink in C(u) at the
dead-band edge made the fixed-step error second order (1.2 Pa at 0.5 ms on a
charge test instead of 0.05 Pa) and the likelihood non-smooth in the overlap.
The algebraic sigmoid costs a square root where the logistic would cost an
exponential.

The shape exponents n_S, n_E (1 by default: the linear ramp of ISO 6358
catalogues) let the opening area grow progressively (n > 1: a spool with
round or notched ports, area ~ stroke^n) or regressively (n < 1) with the
spool stroke; they nest the linear law. They are what an independently
written rig needed: flow tests of power-law and tabulated servo-valves left
the linear ramp at 0.47-0.57 g/s RMS on the flow-level means (20-30x the
flow meter noise), the exponents at 0.04-0.13 g/s
(``benchmarks/bench_recovery.py``, docs/identification.md). With n >= 1/3
the slope of open^n stays finite at the rounded dead-band corner (open ~
t^3 there).

The full-opening fractions f_S, f_E (1 by default: both paths open fully at
u_sat) let a path reach its full area before u_sat, as a spool whose port is
wholly uncovered before the end of its travel does; a servo-valve's supply
and exhaust paths saturate at their own commands (7-9.8 V of 10 on the
independently written rigs of ``benchmarks/bench_recovery.py``). Without
them a progressive law must reach its full-opening level at u_sat, which
bends it wrong between the flow test's levels (power-law paths saturating
at 9.1 and 9.6 V, the sparse plan's levels 0.6, 1.5, 4 and 10 V: the fitted
law 6-11 % low at 6-8 V). Above f u_sat the opening is clipped at 1, a
corner in C(u) left sharp, unlike the dead band's: f = 1 must give the
earlier law's values bit for bit, and the corner's fixed-step error is far
below a pressure sensor's noise (a 6-V sine command through a corner at
4 V, RK4 at 1 and 0.5 ms against DP5 at 2 us: 0.031 and 0.020 Pa, 0.001 Pa
without the corner).

The knee exponents k_S, k_E (``valve_knee_supply``, ``valve_knee_exhaust``;
1 by default, the power law o^n) round each path's approach to full
opening: with k > 1 the area grows progressively from the dead band (~ k
o^n) and levels off smoothly at full opening, with zero slope there. That is
the S-shaped area of a round port uncovered by a spool edge (a circular
segment: area ~ stroke^1.5 at first, flattening as the edge passes the
port's centre) and of catalogue servo-valve curves. shape is Kumaraswamy's
distribution function (Kumaraswamy 1980), closed form and monotone in o,
and it nests the power law exactly (k = 1 is computed as o^n, bit for bit).
The power law with a full-opening fraction reaches an S-shaped table only
with a kinked corner and a wrong dead band: on the two catalogue tables of
``pneumafit.virtual_rig.truth`` (PCHIP through 8 knots, 0-10 V) its best
least-squares fit leaves 5.9-6.2 % of C_max at worst and puts the overlap
at 0.61-0.84 V (tables: 0.25-0.3 V), the knee law 0.5-1.1 % with the
overlap at 0.22-0.37 V. k < 1 (a vertical slope at full opening) is not
allowed.

The null offset b (``valve_null_offset``, 0 by default) is the command at
which the spool is centred: the whole characteristic, both paths' edges and
the centre leakage, is that of u - b. A servo-valve's null drifts with its
spool and electronics, and a centred spool with b != 0 is what makes a rig's
supply path open at u_0 + b and its exhaust at -(u_0 - b) (the independently
written rigs' paths open 0.03-0.05 V apart).

The second term is the centre leakage through the overlapped lands: equal to C_leak on
both paths at u = 0, and shifted towards the path that opens as the spool
moves (the land on that side shortens, the other lengthens). It gives the
valve its non-zero pressure gain at the centre, which sets the equilibrium
pressures of the paper's eq. (10) and the gains of eq. (12).

This is the ``iso6358`` valve law (the default). The ``map`` law
(:mod:`pneumafit.physics.valve_map`, selected by ``ModelStructure(valve=
"map")``) keeps the restriction (phi, m, x_l) and replaces C_S(u), C_E(u) by
measured knot tables interpolated monotonically in log C, and b by a
piecewise-linear function of the opening.
"""

from __future__ import annotations

import math

import numpy as np

from pneumafit.numba_stamp import njit
from pneumafit.physics.air import RHO0, T_REF
from pneumafit.physics.friction import FASTMATH

#: Width eps (V) over which the orifice opening rounds off the dead-band edge.
OPENING_SMOOTHING = 0.05


@njit(cache=True, fastmath=FASTMATH)
def _ellipse(x: float, b: float, m: float) -> float:
    s = (x - b) / (1.0 - b)
    base = 1.0 - s * s
    if m == 0.5:
        return math.sqrt(base)
    return base**m


@njit(cache=True, fastmath=FASTMATH)
def laminar_tail(b: float, m: float, x_lam: float) -> tuple[float, float]:
    """Coefficients (a, c) of the laminar tail phi = a (1 - x) + c (1 - x)^2.

    Matches the ISO 6358 ellipse in value and slope at x = x_lam.
    """
    s_l = (x_lam - b) / (1.0 - b)
    base = 1.0 - s_l * s_l
    phi_l = math.sqrt(base) if m == 0.5 else base**m
    dphi_l = -2.0 * m * s_l / (1.0 - b) * phi_l / base  # d phi / dx at x_lam
    s = 1.0 - x_lam
    a = 2.0 * phi_l / s + dphi_l
    c = (phi_l - a * s) / (s * s)
    return a, c


@njit(cache=True, fastmath=FASTMATH)
def flow_function(x: float, b: float, m: float, x_lam: float) -> float:
    """ISO 6358 flow function phi(x) with a C1 laminar tail.

    Parameters
    ----------
    x : float
        Pressure ratio P_down / P_up (-), 0 <= x <= 1.
    b : float
        Critical pressure ratio (-), 0 <= b < x_lam.
    m : float
        Subsonic index (-); 0.5 in ISO 6358:1989.
    x_lam : float
        Ratio above which the tail replaces the ellipse (-).

    Returns
    -------
    float
        phi (-), 1 when choked, 0 at x = 1, continuous with its slope.
    """
    if x <= b:
        return 1.0
    if x < x_lam:
        return _ellipse(x, b, m)
    a, c = laminar_tail(b, m, x_lam)
    z = 1.0 - x
    return a * z + c * z * z


@njit(cache=True, fastmath=FASTMATH)
def restriction_flow(
    conductance: float,
    b: float,
    m: float,
    x_lam: float,
    p_up: float,
    rt_up: float,
    p_down: float,
) -> float:
    """Mass flow through an ISO 6358 restriction, upstream to downstream.

    Parameters
    ----------
    conductance : float
        Sonic conductance C (m^3/s/Pa).
    b, m, x_lam : float
        Critical ratio, subsonic index, laminar onset ratio (-).
    p_up, p_down : float
        Upstream and downstream absolute pressures (Pa), p_up >= p_down.
    rt_up : float
        Temperature factor sqrt(T_ref / T_up) of the upstream gas (-).

    Returns
    -------
    float
        q (kg/s) >= 0.
    """
    x = p_down / p_up
    return conductance * RHO0 * p_up * rt_up * flow_function(x, b, m, x_lam)


@njit(cache=True, fastmath=FASTMATH)
def path_flow(
    conductance: float,
    b: float,
    m: float,
    x_lam: float,
    p_1: float,
    t_1: float,
    rt_1: float,
    p_2: float,
    t_2: float,
    rt_2: float,
) -> tuple[float, float]:
    """Signed mass flow from node 1 to node 2 and the temperature it carries.

    ``rt_i`` is sqrt(T_ref / t_i), passed in because the kernel reuses it.

    Returns
    -------
    q : float
        Mass flow from 1 to 2 (kg/s); negative when the flow reverses.
    t_carried : float
        Temperature of the flowing gas (K): the upstream node's temperature.
    """
    if p_1 >= p_2:
        return restriction_flow(conductance, b, m, x_lam, p_1, rt_1, p_2), t_1
    return -restriction_flow(conductance, b, m, x_lam, p_2, rt_2, p_1), t_2


@njit(cache=True, fastmath=FASTMATH)
def opening(u: float, overlap: float, u_sat: float) -> float:
    """Fraction of the full orifice area opened by command u (V), in [0, 1]."""
    z = u - overlap
    eps = OPENING_SMOOTHING
    if z <= -eps:
        return 0.0
    if z < eps:
        t = (z + eps) / (2.0 * eps)
        ramp = 2.0 * eps * t * t * t * (1.0 - 0.5 * t)
    else:
        ramp = z
    frac = ramp / (u_sat - overlap)
    return frac if frac < 1.0 else 1.0


@njit(cache=True, fastmath=FASTMATH)
def conductances(
    u: float,
    c_supply: float,
    c_exhaust: float,
    overlap: float,
    u_sat: float,
    c_leak: float,
    leak_width: float,
    n_supply: float = 1.0,
    n_exhaust: float = 1.0,
    full_supply: float = 1.0,
    full_exhaust: float = 1.0,
    null_offset: float = 0.0,
    knee_supply: float = 1.0,
    knee_exhaust: float = 1.0,
) -> tuple[float, float]:
    """Sonic conductances (C_S(u), C_E(u)) of the supply and exhaust paths.

    Parameters
    ----------
    u : float
        Valve command (V); positive connects the chamber to supply.
    c_supply, c_exhaust : float
        Full-opening sonic conductances (m^3/s/Pa).
    overlap : float
        Dead band half-width u_0 (V).
    u_sat : float
        Command of full opening (V), > overlap.
    c_leak : float
        Centre leakage conductance of each path at u = 0 (m^3/s/Pa).
    leak_width : float
        Command scale w (V) over which the leakage shifts between paths.
    n_supply, n_exhaust : float
        Opening shape exponents of the two paths (-), > 0; 1 is the linear ramp.
    full_supply, full_exhaust : float
        Fractions of ``u_sat`` at which each path is fully open (-), in
        (overlap / u_sat, 1]; 1 opens both fully at u_sat.
    null_offset : float
        Command at which the spool is centred (V); the law is that of
        u - null_offset.
    knee_supply, knee_exhaust : float
        Knee exponents k of the two paths (-), >= 1; 1 is the power law.

    Returns
    -------
    tuple of float
        (C_S, C_E) in m^3/s/Pa.
    """
    u = u - null_offset
    z = u / leak_width
    sig_s = 0.5 * (1.0 + z / math.sqrt(1.0 + z * z))
    sig_e = 1.0 - sig_s
    o_s = opening(u, overlap, full_supply * u_sat)
    o_e = opening(-u, overlap, full_exhaust * u_sat)
    c_s = c_supply * _shaped(o_s, n_supply, knee_supply) + 2.0 * c_leak * sig_s
    c_e = c_exhaust * _shaped(o_e, n_exhaust, knee_exhaust) + 2.0 * c_leak * sig_e
    return c_s, c_e


@njit(cache=True, fastmath=FASTMATH)
def _shaped(fraction: float, n: float, knee: float = 1.0) -> float:
    # 1 - (1 - open^n)^knee: open^n exactly for knee 1, no pow for the linear law
    if fraction <= 0.0:
        return fraction
    s = fraction if n == 1.0 else fraction**n
    if knee == 1.0:
        return s
    return 1.0 - (1.0 - s) ** knee


# Valve constants, computed once per simulation by valve_constants() so that
# the compiled right-hand side divides by nothing that is constant.
VC_CS, VC_CE, VC_BS, VC_BE, VC_IBS, VC_IBE, VC_M, VC_XLAM = 0, 1, 2, 3, 4, 5, 6, 7
VC_AS, VC_QS, VC_AE, VC_QE, VC_OVER, VC_IRANGE, VC_LEAK2, VC_IW = 8, 9, 10, 11, 12, 13, 14, 15
VC_PE, VC_IPE, VC_TA, VC_RTA = 16, 17, 18, 19
VC_NS, VC_NE, VC_IRANGE_E, VC_NULL = 20, 21, 22, 23  # VC_IRANGE is the supply path's
VC_KS, VC_KE = 24, 25
NVC = 26


@njit(cache=True, fastmath=FASTMATH)
def valve_constants(
    c_supply: float,
    b_supply: float,
    c_exhaust: float,
    b_exhaust: float,
    m: float,
    x_lam: float,
    overlap: float,
    u_sat: float,
    c_leak: float,
    leak_width: float,
    p_exhaust: float,
    t_ambient: float,
    vc: np.ndarray,
    n_supply: float = 1.0,
    n_exhaust: float = 1.0,
    full_supply: float = 1.0,
    full_exhaust: float = 1.0,
    null_offset: float = 0.0,
    knee_supply: float = 1.0,
    knee_exhaust: float = 1.0,
) -> None:
    """Fill ``vc`` (length NVC) with the constants of :func:`flows_core`.

    Parameters are those of :func:`valve_flows` (SI); supply and exhaust air
    are at ``t_ambient``.
    """
    vc[VC_NS] = n_supply
    vc[VC_NE] = n_exhaust
    vc[VC_KS] = knee_supply
    vc[VC_KE] = knee_exhaust
    vc[VC_CS] = c_supply
    vc[VC_CE] = c_exhaust
    vc[VC_BS] = b_supply
    vc[VC_BE] = b_exhaust
    vc[VC_IBS] = 1.0 / (1.0 - b_supply)
    vc[VC_IBE] = 1.0 / (1.0 - b_exhaust)
    vc[VC_M] = m
    vc[VC_XLAM] = x_lam
    vc[VC_AS], vc[VC_QS] = laminar_tail(b_supply, m, x_lam)
    vc[VC_AE], vc[VC_QE] = laminar_tail(b_exhaust, m, x_lam)
    vc[VC_OVER] = overlap
    vc[VC_IRANGE] = 1.0 / (full_supply * u_sat - overlap)
    vc[VC_IRANGE_E] = 1.0 / (full_exhaust * u_sat - overlap)
    vc[VC_NULL] = null_offset
    vc[VC_LEAK2] = 2.0 * c_leak
    vc[VC_IW] = 1.0 / leak_width
    vc[VC_PE] = p_exhaust
    vc[VC_IPE] = 1.0 / p_exhaust
    vc[VC_TA] = t_ambient
    vc[VC_RTA] = math.sqrt(T_REF / t_ambient)


@njit(cache=True, fastmath=FASTMATH)
def _phi(x: float, b: float, inv_1mb: float, m: float, x_lam: float, a: float, c: float):
    # flow_function with 1 / (1 - b) and the tail coefficients precomputed
    if x <= b:
        return 1.0
    if x < x_lam:
        s = (x - b) * inv_1mb
        base = 1.0 - s * s
        return math.sqrt(base) if m == 0.5 else base**m
    z = 1.0 - x
    return a * z + c * z * z


@njit(cache=True, fastmath=FASTMATH)
def _open(u: float, overlap: float, inv_range: float) -> float:
    # opening() with 1 / (u_sat - overlap) precomputed
    z = u - overlap
    eps = OPENING_SMOOTHING
    if z <= -eps:
        return 0.0
    if z < eps:
        t = (z + eps) / (2.0 * eps)
        z = 2.0 * eps * t * t * t * (1.0 - 0.5 * t)
    frac = z * inv_range
    return frac if frac < 1.0 else 1.0


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def flows_core(
    u: float,
    pres: float,
    inv_pres: float,
    temp: float,
    rt: float,
    p_supply: float,
    inv_p_supply: float,
    vc: np.ndarray,
    linear: bool = False,
) -> tuple[float, float, float]:
    """Flows of one 3-way valve into its chamber (see :func:`valve_flows`).

    Parameters
    ----------
    u : float
        Command (V).
    pres, inv_pres : float
        Chamber pressure (Pa) and its inverse (1/Pa).
    temp, rt : float
        Chamber temperature (K) and sqrt(T_ref / temp) (-).
    p_supply, inv_p_supply : float
        Supply pressure (Pa) and its inverse (1/Pa).
    vc : ndarray
        Constants from :func:`valve_constants`.
    linear : bool
        True only when both shape and knee exponents are 1 (the caller checked): the
        same results without the shaping code. LLVM turns _shaped's branch
        into a select and so calls pow at every evaluation even for n = 1
        (8 % of a simulation's CPU time); the kernel passes a constant here,
        which removes the shaping from the linear law's code.

    Returns
    -------
    q_net, h_in, q_supply : float
        As :func:`valve_flows`.
    """
    u = u - vc[VC_NULL]
    z = u * vc[VC_IW]
    sig_s = 0.5 * (1.0 + z / math.sqrt(1.0 + z * z))
    o_s = _open(u, vc[VC_OVER], vc[VC_IRANGE])
    o_e = _open(-u, vc[VC_OVER], vc[VC_IRANGE_E])
    if not linear:
        o_s = _shaped(o_s, vc[VC_NS], vc[VC_KS])
        o_e = _shaped(o_e, vc[VC_NE], vc[VC_KE])
    c_s = vc[VC_CS] * o_s + vc[VC_LEAK2] * sig_s
    c_e = vc[VC_CE] * o_e + vc[VC_LEAK2] * (1.0 - sig_s)
    k = RHO0
    # supply path, supply -> chamber
    if p_supply >= pres:
        phi = _phi(pres * inv_p_supply, vc[VC_BS], vc[VC_IBS], vc[VC_M], vc[VC_XLAM],
                   vc[VC_AS], vc[VC_QS])  # fmt: skip
        q_s = c_s * k * p_supply * vc[VC_RTA] * phi
        t_s = vc[VC_TA]
    else:
        phi = _phi(p_supply * inv_pres, vc[VC_BS], vc[VC_IBS], vc[VC_M], vc[VC_XLAM],
                   vc[VC_AS], vc[VC_QS])  # fmt: skip
        q_s = -c_s * k * pres * rt * phi
        t_s = temp
    # exhaust path, chamber -> exhaust
    p_e = vc[VC_PE]
    if pres >= p_e:
        phi = _phi(p_e * inv_pres, vc[VC_BE], vc[VC_IBE], vc[VC_M], vc[VC_XLAM],
                   vc[VC_AE], vc[VC_QE])  # fmt: skip
        q_e = c_e * k * pres * rt * phi
        t_e = temp
    else:
        phi = _phi(pres * vc[VC_IPE], vc[VC_BE], vc[VC_IBE], vc[VC_M], vc[VC_XLAM],
                   vc[VC_AE], vc[VC_QE])  # fmt: skip
        q_e = -c_e * k * p_e * vc[VC_RTA] * phi
        t_e = vc[VC_TA]
    return q_s - q_e, q_s * t_s - q_e * t_e, q_s


@njit(cache=True, fastmath=FASTMATH)
def valve_flows(
    u: float,
    p: float,
    t: float,
    p_supply: float,
    t_ambient: float,
    p_exhaust: float,
    c_supply: float,
    b_supply: float,
    c_exhaust: float,
    b_exhaust: float,
    m: float,
    x_lam: float,
    overlap: float,
    u_sat: float,
    c_leak: float,
    leak_width: float,
    n_supply: float = 1.0,
    n_exhaust: float = 1.0,
    full_supply: float = 1.0,
    full_exhaust: float = 1.0,
    null_offset: float = 0.0,
    knee_supply: float = 1.0,
    knee_exhaust: float = 1.0,
) -> tuple[float, float, float]:
    """Flows of one 3-way servo-distributor into its chamber.

    Supply and exhaust air are at ambient temperature ``t_ambient`` (K).
    Pressures in Pa, temperatures in K, conductances in m^3/s/Pa, commands
    in V; see the module docstring for the law.

    Returns
    -------
    q_net : float
        Net mass flow into the chamber, q_S - q_E (kg/s).
    h_in : float
        Net enthalpy-carrying flow sum(q_i T_i) into the chamber (kg K/s):
        inflows carry their upstream temperature, outflows the chamber's.
    q_supply : float
        Mass flow drawn from the supply through this valve (kg/s, signed).
    """
    vc = np.empty(NVC)
    valve_constants(c_supply, b_supply, c_exhaust, b_exhaust, m, x_lam, overlap, u_sat,
                    c_leak, leak_width, p_exhaust, t_ambient, vc, n_supply,
                    n_exhaust, full_supply, full_exhaust, null_offset, knee_supply,
                    knee_exhaust)  # fmt: skip
    return flows_core(u, p, 1.0 / p, t, math.sqrt(T_REF / t), p_supply, 1.0 / p_supply, vc)
