"""Equilibrium set, linearized models and state-feedback design (paper eqs. 10-14).

Equilibrium (eq. 10). With v = 0 and T_N = T_P = T_0 (wall = supply air
temperature), the unknowns (P_P, P_N, u_e) solve

    q_P(P_P, u_e) = 0,   q_N(P_N, -u_e) = 0,   S_P P_P - S_N P_N - F_ext = 0

where q_X is the valve's net mass flow into chamber X. For a given u each
valve's zero-flow pressure P_X*(u) is unique (the net flow falls strictly with
the chamber pressure), and the force S_P P_P*(u) - S_N P_N*(-u) rises with u,
so u_e is a root of one monotone function: it exists iff F_ext lies within the
force range the valves can hold. The equilibrium does not depend on y_e (the
static valves set the pressures); the matrices do.

Linearization (eqs. 11-14), derived here because the printed matrices are
garbled. At the equilibrium each valve passes the same leakage q_bar through
its supply and exhaust paths. With q'_P = dq/dP and q'_u = dq/du (the valve's
gains of eq. 12, from the valve law by central differences), lambda_e the
nominal heat-transfer coefficient (the convection law gives 0 at T = T_0, so
the paper freezes lambda; physics notes) and viscous friction b, chamber P:

    d(dP/dt)/dv = -gamma P S / V           d(dT/dt)/dv = -(gamma-1) T0 S / V
    d(dP/dt)/dP = gamma r T0 q'_P / V      d(dT/dt)/dP = (gamma-1) r T0^2 q'_P / (P V)
    d(dP/dt)/dT = -(gamma r q_bar / 2 + (gamma-1) lambda_e A) / V
    d(dT/dt)/dT = -T0 ((gamma+1) r q_bar / 2 + (gamma-1) lambda_e A) / (P V)
    d(dP/dt)/du = gamma r T0 q'_u / V      d(dT/dt)/du = (gamma-1) r T0^2 q'_u / (P V)

(the q_bar terms come from the outflow's sqrt(T_ref / T) dependence: the
paper omits them; they vanish without centre leakage). Chamber N: S -> -S_N
(its volume shrinks as y grows) and u -> -u (u_N = -u_P). Mechanics:
d(dv/dt)/dP_P = S_P / M, d(dv/dt)/dP_N = -S_N / M, d(dv/dt)/dv = -b / M.
Polytropic model (4 states): d(dP/dt)/dv = -k P S / V (the paper prints + for
chamber P), d(dP/dt)/dP = k r T0 q'_P / V, d(dP/dt)/du = k r T0 q'_u / V.

State order (paper): [y, v, P_N, P_P, T_N, T_P]; input u = u_P = -u_N.

Dead-band compensation. With the controller output v passed through
u = c(v) = v + a tanh(v / w) before the valve (a the overlap), the plant seen
by the controller is f(x, c(v)); its equilibrium is the same (c(v_e) = u_e)
and its input column is B c'(v_e), c'(v) = 1 + (a / w) sech^2(v / w). The
width w is chosen so that this local gain equals the valve's gain just
outside the dead band (:func:`deadband_compensation`; docs/physics.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from pneumafit import first_use
from pneumafit.errors import PneumafitInputError
from pneumafit.models import kernel
from pneumafit.models.layout import (
    C_INPUT,
    CTRL_DB_AMPLITUDE,
    CTRL_DB_WIDTH,
    LAW_STATE_FEEDBACK,
    NCTRL,
    VALVE_LAWS,
    X_PN,
    X_PP,
    X_TN,
    X_TP,
    X_V,
    X_Y,
    P,
)
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.part_kernel import kernel_for, kernel_for_valve
from pneumafit.models.structure import ModelStructure
from pneumafit.physics.air import GAMMA, R_AIR
from pneumafit.physics.geometry import chamber_volumes, exchange_areas, piston_areas
from pneumafit.physics.valve import NVC
from pneumafit.physics.valve_map import NVM, map_conductances

#: ITAE step-response prototype polynomials for w0 = 1 rad/s (Graham and
#: Lathrop, 1953), coefficients from s^n down to s^0.
ITAE_POLYNOMIALS: dict[int, tuple[float, ...]] = {
    4: (1.0, 2.1, 3.4, 2.7, 1.0),
    6: (1.0, 3.25, 6.60, 8.60, 7.45, 3.95, 1.0),
}

#: ITAE prototype poles (w0 = 1 rad/s), the roots of those polynomials: the
#: paper's table to its 4 decimals.
ITAE_POLES: dict[int, np.ndarray] = {
    order: np.sort_complex(np.roots(coeffs)) for order, coeffs in ITAE_POLYNOMIALS.items()
}

#: Digits of the extended-precision arithmetic used for pole placement.
PLACEMENT_DIGITS = 60

#: Paper state order and the kernel's slots for it.
STATES_6 = ("y", "v", "p_N", "p_P", "T_N", "T_P")
SLOTS_6 = (X_Y, X_V, X_PN, X_PP, X_TN, X_TP)


def _vec(parameters: Mapping[str, float] | np.ndarray) -> np.ndarray:
    if isinstance(parameters, np.ndarray):
        return np.asarray(parameters, dtype=float)
    return parameter_vector(parameters)


def valve_law(valve: str) -> int:
    """Kernel code of a valve law name (``"iso6358"``, ``"map"`` or a law
    registered from outside the package).

    Raises
    ------
    PneumafitInputError
        An unknown name (a ValueError).
    """
    if valve not in VALVE_LAWS:
        raise PneumafitInputError(
            f"valve: expected one of {', '.join(VALVE_LAWS)}, found {valve!r}"
        )
    return VALVE_LAWS[valve]


def _flows(p: np.ndarray, u: float, pres: float, law: int) -> tuple[float, float, float]:
    """Valve flows (net, enthalpy, from supply) into a chamber at pressure pres
    (Pa), gas at T_0, under the valve law ``law`` (the fitted one: ISO 6358,
    the measured map or a law from outside the package)."""
    first_use.due()
    module = kernel_for_valve(law)
    return module.static_valve_flows(p, law, u, pres, p[P["wall_temperature"]])


def _net_flow(p: np.ndarray, u: float, pres: float, law: int = 0) -> float:
    """Net valve flow into a chamber at pressure pres (Pa), gas at T_0 (kg/s)."""
    return _flows(p, u, pres, law)[0]


def _zero_flow_pressure(p: np.ndarray, u: float, law: int = 0) -> float:
    """Chamber pressure (Pa) at which a valve at command u passes no net flow."""
    lo, hi = p[P["exhaust_pressure"]], p[P["supply_pressure"]]
    f_lo = _net_flow(p, u, lo * (1 + 1e-12), law)
    f_hi = _net_flow(p, u, hi * (1 - 1e-12), law)
    if f_lo <= 0.0:
        return lo
    if f_hi >= 0.0:
        return hi
    return brentq(lambda x: _net_flow(p, u, x, law), lo * (1 + 1e-12), hi * (1 - 1e-12),
                  xtol=1e-9, rtol=1e-14)  # fmt: skip


@dataclass(frozen=True)
class Equilibrium:
    """An equilibrium of eq. 10.

    Attributes
    ----------
    exists : bool
        False when the valves cannot hold the load (then the other fields
        describe the closest approach and ``message`` says why).
    y, p_P, p_N, T, u : float
        Position (m), pressures (Pa), temperature (K), command (V).
    leakage_P, leakage_N : float
        Flow through each valve's supply and exhaust paths (kg/s).
    force_residual : float
        S_P P_P - S_N P_N - F_ext at the solution (N).
    message : str
    """

    exists: bool
    y: float
    p_P: float
    p_N: float
    T: float
    u: float
    leakage_P: float
    leakage_N: float
    force_residual: float
    message: str

    def state(self) -> np.ndarray:
        """[y, v, P_N, P_P, T_N, T_P] at the equilibrium (SI)."""
        return np.array([self.y, 0.0, self.p_N, self.p_P, self.T, self.T])


def _external_force(p: np.ndarray) -> tuple[float, float, float]:
    s_p, s_n = piston_areas(p[P["bore"]], p[P["rod"]])
    f_ext = (
        p[P["exhaust_pressure"]] * (s_p - s_n)
        + p[P["external_force"]]
        + p[P["moving_mass"]] * 9.80665 * math.sin(p[P["mounting_angle"]])
    )
    return s_p, s_n, f_ext


def equilibrium(
    parameters: Mapping[str, float] | np.ndarray, y: float, *, valve: str = "iso6358"
) -> Equilibrium:
    """Solve eq. 10 at piston position y (m).

    Parameters
    ----------
    parameters : mapping or ndarray
        SI parameter values (the fitted valve characteristic matters most).
    y : float
        Equilibrium position (m), within the stroke.
    valve : {"iso6358", "map"}
        Valve law of the parameters (a fit's ``structure.valve``).

    Returns
    -------
    Equilibrium
        ``exists`` False, with a message, when no command holds the load.
    """
    p = _vec(parameters)
    law = valve_law(valve)
    stroke = p[P["stroke"]]
    if not 0.0 <= y <= stroke:
        raise PneumafitInputError(
            f"equilibrium: y: expected a position in [0, {stroke}] m, found {y}"
        )
    s_p, s_n, f_ext = _external_force(p)
    t0 = p[P["wall_temperature"]]
    u_sat = p[P["valve_u_sat"]]

    def force(u: float) -> float:
        return s_p * _zero_flow_pressure(p, u, law) - s_n * _zero_flow_pressure(p, -u, law) - f_ext

    f_lo, f_hi = force(-u_sat), force(u_sat)
    if f_lo > 0.0 or f_hi < 0.0:
        u_e = -u_sat if f_lo > 0.0 else u_sat
        p_p, p_n = _zero_flow_pressure(p, u_e, law), _zero_flow_pressure(p, -u_e, law)
        return Equilibrium(
            False, y, p_p, p_n, t0, u_e, float("nan"), float("nan"), force(u_e),
            f"no equilibrium at y = {y:g} m: the valves hold forces from {f_lo + f_ext:.1f} to "
            f"{f_hi + f_ext:.1f} N, the load needs {f_ext:.1f} N",
        )  # fmt: skip
    u_e = brentq(force, -u_sat, u_sat, xtol=1e-13, rtol=1e-15)
    p_p, p_n = _zero_flow_pressure(p, u_e, law), _zero_flow_pressure(p, -u_e, law)
    leak_p = _flows(p, u_e, p_p, law)[2]
    leak_n = _flows(p, -u_e, p_n, law)[2]
    return Equilibrium(True, y, p_p, p_n, t0, u_e, leak_p, leak_n, force(u_e), "ok")


def _existing_equilibrium(
    parameters: Mapping[str, float] | np.ndarray, y: float, valve: str
) -> tuple[np.ndarray, int, Equilibrium]:
    """The parameter vector, the valve law's kernel code and the equilibrium at y (m).

    Raises
    ------
    PneumafitInputError
        When no equilibrium exists at y (its message), or the valve law is unknown.
    """
    p = _vec(parameters)
    law = valve_law(valve)
    eq = equilibrium(p, y, valve=valve)
    if not eq.exists:
        raise PneumafitInputError(eq.message)
    return p, law, eq


def _gains(p: np.ndarray, u: float, pres: float, law: int = 0) -> tuple[float, float]:
    """Valve gains (dq/dP (kg/s/Pa), dq/du (kg/s/V)) by central differences."""
    dp = 1e-6 * pres
    du = 1e-6 * max(1.0, abs(u))
    q_p = (_net_flow(p, u, pres + dp, law) - _net_flow(p, u, pres - dp, law)) / (2 * dp)
    q_u = (_net_flow(p, u + du, pres, law) - _net_flow(p, u - du, pres, law)) / (2 * du)
    return q_p, q_u


#: Fractions of a path's rise from its centre conductance to full opening
#: between which a measured map's opening is extrapolated to its dead-band
#: edge (see :func:`overlap`).
MAP_EDGE_FRACTIONS = (0.1, 0.3)


def overlap(p: np.ndarray, valve: str = "iso6358") -> float:
    """Dead-band half-width u_0 of the valve (V).

    ISO 6358 law: the ``valve_overlap`` parameter. Measured map: per path,
    the straight line through the commands where the conductance has risen
    by 10 % and 30 % of its rise from the centre value to full opening,
    extrapolated to zero rise (the ISO ramp's u_0 exactly, for a map
    sampled from a linear ramp, up to the knot interpolation; knots at
    0.25 and 0.5 V cannot place the edge more finely by themselves); the mean
    over the supply (u > 0) and exhaust (u < 0) paths, on a 1-mV grid,
    clipped to [0, u_sat / 2]. A law from outside the package: the same
    rule on its flows, the supply path's drawn into a chamber at the exhaust
    pressure and the exhaust path's out of one at the supply pressure
    (each path's conductance times a constant, for an orifice law).
    """
    law = valve_law(valve)
    if law == VALVE_LAWS["iso6358"]:
        return float(p[P["valve_overlap"]])
    u_sat = float(p[P["valve_u_sat"]])
    grid = np.arange(0.0, u_sat + 5e-4, 1e-3)
    if law == VALVE_LAWS["map"]:
        vc, vm = np.empty(NVC), np.empty(NVM)
        kernel.valve_arrays(p, vc, vm)
        paths = [
            np.array([map_conductances(u, vm)[0] for u in grid]),
            np.array([map_conductances(-u, vm)[1] for u in grid]),
        ]
    else:
        p_e, p_s = float(p[P["exhaust_pressure"]]), float(p[P["supply_pressure"]])
        paths = [
            np.array([_flows(p, u, p_e * (1.0 + 1e-9), law)[2] for u in grid]),
            np.array([-_flows(p, -u, p_s * (1.0 - 1e-9), law)[0] for u in grid]),
        ]
    edges = []
    for c in paths:  # supply path at +u, exhaust at -u
        rise = c - c[0]
        if not rise[-1] > 0.0:
            edges.append(0.0)
            continue
        lo, hi = (float(np.interp(f * rise[-1], np.maximum.accumulate(rise), grid))
                  for f in MAP_EDGE_FRACTIONS)  # fmt: skip
        f_lo, f_hi = MAP_EDGE_FRACTIONS
        edges.append(lo - f_lo * (hi - lo) / (f_hi - f_lo))
    return float(np.clip(0.5 * (edges[0] + edges[1]), 0.0, 0.5 * u_sat))


@dataclass(frozen=True)
class DeadbandCompensation:
    """Smoothed inverse of the valve's dead band, u = c(v) = v + a tanh(v / w).

    The state-feedback law's output v goes through c before the valve
    (kernel ``commands``), so the orifice opens as soon as |v| exceeds a few w.

    Attributes
    ----------
    amplitude : float
        a, the dead-band half-width compensated (V): the valve overlap.
    width : float
        w, the width of the transition through the band (V), > 0.
    """

    amplitude: float
    width: float

    def __post_init__(self) -> None:
        if not (self.amplitude >= 0.0 and self.width > 0.0):
            raise PneumafitInputError(
                f"dead-band compensation: expected a >= 0 V and w > 0 V, found "
                f"a = {self.amplitude} and w = {self.width}"
            )

    def __call__(self, v: float) -> float:
        """Valve command u (V) for a controller output v (V)."""
        return float(v + self.amplitude * math.tanh(v / self.width))

    def slope(self, v: float) -> float:
        """du/dv (-) at controller output v (V)."""
        return float(1.0 + self.amplitude / self.width / math.cosh(v / self.width) ** 2)

    def inverse(self, u: float) -> float:
        """Controller output v (V) with c(v) = u (c rises strictly, so v is unique)."""
        span = abs(u) + self.amplitude + 1.0
        return float(brentq(lambda v: self(v) - u, -span, span, xtol=1e-15, rtol=1e-15))


def _force_gain(p: np.ndarray, u: float, p_p: float, p_n: float, y: float, law: int = 0) -> float:
    """Rate of piston force per volt through both valves at command u (N/s/V):
    sum over chambers of S r T0 |dq/du| / V (the force-producing part of B)."""
    s_p, s_n = piston_areas(p[P["bore"]], p[P["rod"]])
    v_p, v_n = chamber_volumes(y, p[P["stroke"]], s_p, s_n, p[P["dead_volume_P"]],
                               p[P["dead_volume_N"]])  # fmt: skip
    g_p = _gains(p, u, p_p, law)[1]
    g_n = _gains(p, -u, p_n, law)[1]
    return R_AIR * p[P["wall_temperature"]] * (s_p * g_p / v_p + s_n * g_n / v_n)


def deadband_compensation(
    parameters: Mapping[str, float] | np.ndarray,
    y: float,
    *,
    margin: float = 2.0,
    valve: str = "iso6358",
) -> DeadbandCompensation | None:
    """Dead-band compensation whose gain at the equilibrium matches the open valve.

    Amplitude a = the valve overlap u_0. The width w solves

        c'(v_e) G(u_e) = [G(u_0 + m eps) + G(-u_0 - m eps)] / 2,   c(v_e) = u_e,

    where G(u) = sum_X S_X r T_0 |dq_X/du| / V_X is the rate of piston force
    per volt through both valves at the equilibrium pressures of eq. 10 (the
    force-producing combination of the B column of eqs. 13-14), eps the width
    over which the orifice edge is rounded (0.05 V) and m = ``margin``: the
    right side is the gain of the valve just outside its dead band, averaged
    over opening to supply and to exhaust. The compensated plant's linear
    model then has the open valve's flow gain, instead of the centre
    leakage's.

    Parameters
    ----------
    parameters : mapping or ndarray
        SI parameter values.
    y : float
        Equilibrium position (m).
    margin : float
        Multiple of the rounding width past the overlap where the open gain
        is taken (-).
    valve : {"iso6358", "map"}
        Valve law of the parameters; the overlap of a map is :func:`overlap`.

    Returns
    -------
    DeadbandCompensation or None
        None when the valve has no overlap or its centre gain already matches
        the open one (nothing to compensate).

    Raises
    ------
    PneumafitInputError
        When no equilibrium exists at y (a ValueError).
    """
    from pneumafit.physics.valve import OPENING_SMOOTHING

    p, law, eq = _existing_equilibrium(parameters, y, valve)
    a = overlap(p, valve)
    if a <= 0.0:
        return None
    u_open = a + margin * OPENING_SMOOTHING
    g_open = 0.5 * (_force_gain(p, u_open, eq.p_P, eq.p_N, y, law)
                    + _force_gain(p, -u_open, eq.p_P, eq.p_N, y, law))  # fmt: skip
    ratio = g_open / _force_gain(p, eq.u, eq.p_P, eq.p_N, y, law)
    if not ratio > 1.0 or abs(eq.u) >= a:
        return None

    def excess(log_w: float) -> float:
        comp = DeadbandCompensation(a, math.exp(log_w))
        return comp.slope(comp.inverse(eq.u)) - ratio

    # c'(v_e) falls from infinity (w -> 0) to 1 (w -> infinity)
    log_w = brentq(excess, math.log(1e-6 * a), math.log(1e3 * a), xtol=1e-12)
    return DeadbandCompensation(a, math.exp(log_w))


@dataclass(frozen=True)
class LinearModel:
    """dx/dt = A x + B u around an equilibrium (paper eqs. 13-14).

    Attributes: A (n, n), B (n, 1), state names, the equilibrium, lambda_e
    (W/m^2/K, None for the polytropic model) and the model kind (order).
    """

    A: np.ndarray
    B: np.ndarray
    states: tuple[str, ...]
    equilibrium: Equilibrium
    lambda_e: float | None
    compensation: DeadbandCompensation | None = None

    @property
    def v_e(self) -> float:
        """Controller-side equilibrium command (V): c^-1(u_e), or u_e uncompensated."""
        if self.compensation is None:
            return float(self.equilibrium.u)
        return self.compensation.inverse(self.equilibrium.u)

    @property
    def poles(self) -> np.ndarray:
        """Open-loop poles (1/s), sorted by real part."""
        ev = np.linalg.eigvals(self.A)
        return ev[np.argsort(ev.real)]

    @property
    def input_name(self) -> str:
        """``"v"`` (controller output, before the compensation) or ``"u"`` (valve command)."""
        return "u" if self.compensation is None else "v"

    def output_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """C (n, n) = identity and D (n, 1) = 0: every state is an output (the
        state feedback measures them all, in the state order ``states``)."""
        n = self.A.shape[0]
        return np.eye(n), np.zeros((n, 1))

    def to_ss(self):
        """The model as ``scipy.signal.StateSpace(A, B, C, D)`` (continuous time).

        Deviations from the equilibrium: x - x_e (SI, order ``states``), input
        ``input_name`` minus its equilibrium value (V), outputs the states.
        """
        from scipy.signal import StateSpace

        c, d = self.output_matrices()
        return StateSpace(self.A, self.B, c, d)

    def to_control(self):
        """The model as a python-control ``StateSpace`` with named signals.

        Raises
        ------
        ImportError
            When python-control is not installed (``pip install control``).
        """
        try:
            import control
        except ImportError:
            raise ImportError(
                "LinearModel.to_control needs python-control, which is not installed: "
                "pip install control (or use LinearModel.to_ss for scipy)"
            ) from None
        c, d = self.output_matrices()
        return control.ss(self.A, self.B, c, d, inputs=[self.input_name],
                          outputs=list(self.states), states=list(self.states))  # fmt: skip


def linearize(
    parameters: Mapping[str, float] | np.ndarray,
    y: float,
    *,
    order: int = 6,
    lambda_e: float = 15.0,
    k: float | None = None,
    compensation: DeadbandCompensation | None = None,
    valve: str = "iso6358",
) -> LinearModel:
    """Analytic linear model around the equilibrium at y (see module docstring).

    Parameters
    ----------
    parameters : mapping or ndarray
        SI parameter values.
    y : float
        Equilibrium position (m).
    order : {6, 4}
        6: heat model [y, v, P_N, P_P, T_N, T_P] with lambda frozen at
        ``lambda_e``; 4: polytropic [y, v, P_N, P_P] with index ``k``.
    lambda_e : float
        Nominal heat-transfer coefficient (W/m^2/K): the fitted constant-lambda
        value where there is one; the paper's 15 by default.
    k : float, optional
        Polytropic index; default the parameter set's ``k``.
    compensation : DeadbandCompensation, optional
        Model the plant seen through u = c(v): B is multiplied by c'(v_e),
        the input is v (V).
    valve : {"iso6358", "map"}
        Valve law of the parameters (equilibrium and the gains of eq. 12).

    Raises
    ------
    PneumafitInputError
        When no equilibrium exists at y (a ValueError).
    """
    p, law, eq = _existing_equilibrium(parameters, y, valve)
    bore, rod, stroke = p[P["bore"]], p[P["rod"]], p[P["stroke"]]
    s_p, s_n = piston_areas(bore, rod)
    v_p, v_n = chamber_volumes(y, stroke, s_p, s_n, p[P["dead_volume_P"]], p[P["dead_volume_N"]])
    a_p, a_n = exchange_areas(
        y, stroke, bore, rod, p[P["dead_volume_P"]], p[P["dead_volume_N"]], p[P["heat_area_ends"]]
    )
    mass, b = p[P["moving_mass"]], p[P["friction_viscous"]]
    t0, r, g = eq.T, R_AIR, GAMMA
    qp_p, qu_p = _gains(p, eq.u, eq.p_P, law)
    qp_n, qu_n = _gains(p, -eq.u, eq.p_N, law)
    qu_n = -qu_n  # u_N = -u
    n = 6 if order == 6 else 4
    if order not in (4, 6):
        raise PneumafitInputError(f"linearize: order: expected 4 or 6, found {order}")
    A = np.zeros((n, n))
    B = np.zeros((n, 1))
    A[0, 1] = 1.0
    A[1, 1] = -b / mass
    A[1, 2] = -s_n / mass
    A[1, 3] = s_p / mass
    # chamber N (index 2, T at 4) and P (index 3, T at 5): (S signed, V, P, q'_P, q'_u, leak, A)
    chambers = ((2, 4, -s_n, v_n, eq.p_N, qp_n, qu_n, eq.leakage_N, a_n),
                (3, 5, s_p, v_p, eq.p_P, qp_p, qu_p, eq.leakage_P, a_p))  # fmt: skip
    if order == 4:
        kk = p[P["k"]] if k is None else k
        for ip, _, s, vol, pres, qp, qu, _, _ in chambers:
            A[ip, 1] = -kk * pres * s / vol
            A[ip, ip] = kk * r * t0 * qp / vol
            B[ip, 0] = kk * r * t0 * qu / vol
        if compensation is not None:
            B *= compensation.slope(compensation.inverse(eq.u))
        return LinearModel(A, B, STATES_6[:4], eq, None, compensation)
    for ip, it, s, vol, pres, qp, qu, leak, area in chambers:
        A[ip, 1] = -g * pres * s / vol
        A[ip, ip] = g * r * t0 * qp / vol
        A[ip, it] = -(g * r * leak / 2 + (g - 1) * lambda_e * area) / vol
        A[it, 1] = -(g - 1) * t0 * s / vol
        A[it, ip] = (g - 1) * r * t0**2 * qp / (pres * vol)
        A[it, it] = -t0 * ((g + 1) * r * leak / 2 + (g - 1) * lambda_e * area) / (pres * vol)
        B[ip, 0] = g * r * t0 * qu / vol
        B[it, 0] = (g - 1) * r * t0**2 * qu / (pres * vol)
    if compensation is not None:
        B *= compensation.slope(compensation.inverse(eq.u))
    return LinearModel(A, B, STATES_6, eq, lambda_e, compensation)


def numerical_jacobian(
    parameters: Mapping[str, float] | np.ndarray,
    eq: Equilibrium,
    *,
    order: int = 6,
    lambda_e: float = 15.0,
    rel_step: float = 1e-6,
    compensation: DeadbandCompensation | None = None,
    valve: str = "iso6358",
) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) by central differences of the compiled right-hand side.

    The model evaluated is the one the analytic linearization describes: the
    constant-lambda structure at lambda_e (order 6) or the polytropic one
    (order 4), with friction reduced to its viscous term (the linear model's
    friction), sliding mode so that F_f = b v. With ``compensation`` the input
    is the controller output v, mapped to the valve command by the compiled
    state-feedback law (kernel ``commands``, zero gain) around v_e = c^-1(u_e).
    ``valve`` is the valve law of the parameters.
    """
    p = _vec(parameters).copy()
    p[P["friction_static"]] = 0.0
    p[P["friction_coulomb"]] = 0.0
    p[P["lambda"]] = lambda_e
    structure = ModelStructure("constant-lambda" if order == 6 else "polytropic", valve=valve)
    cfg = structure.config()
    module = kernel_for(structure)  # a valve law from outside the package runs on its copy
    d = np.empty(kernel.ND)
    module.derive(p, d)
    slots = SLOTS_6[:order]
    x0 = np.zeros(module.NX)
    x0[list(SLOTS_6)] = eq.state()
    x0[kernel.X_TWN] = x0[kernel.X_TWP] = p[P["wall_temperature"]]
    dx = np.empty(module.NX)
    aux = np.empty(kernel.NAUX)
    scale = np.array([p[P["stroke"]], 1.0, eq.p_N, eq.p_P, eq.T, eq.T])

    ctrl = np.zeros(NCTRL)
    ctrl[3] = np.inf  # no command limit
    law_cfg = cfg.copy()
    law_cfg[C_INPUT] = LAW_STATE_FEEDBACK
    inp = np.zeros((2, 4))
    if compensation is not None:
        ctrl[CTRL_DB_AMPLITUDE] = compensation.amplitude
        ctrl[CTRL_DB_WIDTH] = compensation.width
        u_e = compensation.inverse(eq.u)
    else:
        u_e = eq.u

    def f(x: np.ndarray, u: float) -> np.ndarray:
        ctrl[2] = u  # zero gains: the law returns c(u) (or u)
        u_valve = module.commands(x, inp, 0, 0.0, law_cfg, ctrl)[0]
        module.rhs(x, 1, u_valve, -u_valve, p, d, cfg, dx, aux)
        return dx[list(slots)].copy()

    A = np.zeros((order, order))
    for j, slot in enumerate(slots):
        h = rel_step * scale[j]
        xp, xm = x0.copy(), x0.copy()
        xp[slot] += h
        xm[slot] -= h
        A[:, j] = (f(xp, u_e) - f(xm, u_e)) / (2 * h)
    hu = rel_step * max(1.0, abs(u_e))
    if compensation is not None:
        hu = rel_step * compensation.width
    B = ((f(x0, u_e + hu) - f(x0, u_e - hu)) / (2 * hu))[:, None]
    return A, B


def itae_poles(order: int, w0: float) -> np.ndarray:
    """ITAE prototype poles (1/s) of order 4 or 6 scaled by w0 (rad/s): s -> s / w0."""
    if order not in ITAE_POLES:
        raise PneumafitInputError(f"itae_poles: order: expected 4 or 6, found {order}")
    if not w0 > 0:
        raise PneumafitInputError(
            f"itae_poles: w0: expected a positive frequency in rad/s, found {w0}"
        )
    return ITAE_POLES[order] * w0


def _scaling(model: LinearModel) -> np.ndarray:
    eq = model.equilibrium
    return np.array([0.1, 0.1, eq.p_N, eq.p_P, eq.T, eq.T])[: model.A.shape[0]]


def place(model: LinearModel, poles: Sequence[complex]) -> np.ndarray:
    """State-feedback gain K (delta u = -K delta x) with eig(A - B K) = poles.

    Single input, so K is unique; it is computed by Ackermann's formula,
    K = e_n^T C^-1 phi(A), in 60-digit arithmetic (mpmath) on the system with
    its states scaled to comparable magnitudes, then rounded to double. Why
    not ``scipy.signal.place_poles``: the 6-state model is nearly
    uncontrollable in double precision (its scaled controllability matrix has
    a condition number ~1e11: one input drives both chambers, so combinations
    of their temperatures barely respond), and the double-precision algorithm
    misplaced poles by up to 60 % where the exact K places them to 1e-11.

    Returns
    -------
    ndarray, shape (1, n)
        K in SI units (V per state unit).
    """
    import mpmath as mp

    poles = np.asarray(poles, dtype=complex)
    n = model.A.shape[0]
    if poles.size != n:
        raise PneumafitInputError(f"place: poles: expected {n} poles, found {poles.size}")
    scale = _scaling(model)
    a_z = model.A / scale[:, None] * scale[None, :]
    b_z = model.B / scale[:, None]
    with mp.workdps(PLACEMENT_DIGITS):
        a_m = mp.matrix(a_z.tolist())
        ctrb = mp.matrix(n, n)
        col = mp.matrix(b_z.tolist())
        for i in range(n):
            for r in range(n):
                ctrb[r, i] = col[r]
            col = a_m * col
        coeffs = [mp.mpc(1)]
        for root in poles:
            root = mp.mpc(complex(root))
            coeffs = [c - root * prev for c, prev in zip([*coeffs, 0], [0, *coeffs], strict=True)]
        phi = mp.zeros(n, n)
        power = mp.eye(n)
        for c in reversed(coeffs):
            phi += mp.re(c) * power
            power = power * a_m
        last = mp.zeros(1, n)
        last[0, n - 1] = 1
        k_m = last * mp.inverse(ctrb) * phi
        k_z = np.array([[float(k_m[0, i]) for i in range(n)]])
    return k_z / scale[None, :]


def closed_loop_poles(model: LinearModel, gain: np.ndarray) -> np.ndarray:
    """Eigenvalues of A - B K (1/s), computed in 60-digit arithmetic.

    The closed loop of the 6-state model is strongly non-normal; LAPACK's
    double-precision eigenvalues of it can be off by tens of percent while the
    exact ones sit on the requested poles, so the check is made exactly.
    """
    import mpmath as mp

    scale = _scaling(model)
    a_z = model.A / scale[:, None] * scale[None, :]
    b_z = model.B / scale[:, None]
    k_z = np.asarray(gain, dtype=float).reshape(1, -1) * scale[None, :]
    with mp.workdps(PLACEMENT_DIGITS):
        closed = mp.matrix(a_z.tolist()) - mp.matrix(b_z.tolist()) * mp.matrix(k_z.tolist())
        values = mp.eig(closed, left=False, right=False)
        ev = np.array([complex(v) for v in values])
    return ev[np.lexsort((ev.imag, ev.real))]


def gain_schedule(
    parameters: Mapping[str, float] | np.ndarray,
    positions: Sequence[float],
    *,
    order: int,
    w0: float,
    lambda_e: float = 15.0,
    valve: str = "iso6358",
) -> dict[str, np.ndarray]:
    """K(y), open- and closed-loop poles over a grid of positions.

    ``valve`` is the valve law of the parameters.

    Returns a dict with ``positions`` (m), ``K`` (n_positions, order),
    ``open_loop`` and ``closed_loop`` poles (n_positions, order); positions
    without an equilibrium get NaN rows.
    """
    ys = np.asarray(positions, dtype=float)
    poles = itae_poles(order, w0)
    K = np.full((ys.size, order), np.nan)
    ol = np.full((ys.size, order), np.nan, dtype=complex)
    cl = np.full((ys.size, order), np.nan, dtype=complex)
    for i, y in enumerate(ys):
        try:
            lin = linearize(parameters, float(y), order=order, lambda_e=lambda_e, valve=valve)
        except ValueError:
            continue
        K[i] = place(lin, poles)[0]
        ol[i] = lin.poles
        cl[i] = closed_loop_poles(lin, K[i : i + 1])
    return {"positions": ys, "K": K, "open_loop": ol, "closed_loop": cl}
