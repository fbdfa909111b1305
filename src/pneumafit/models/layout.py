"""Fixed layouts shared by the Python side and the compiled kernels.

The compiled right-hand side reads a flat float64 parameter vector, an int64
configuration vector and a float64 state vector. Their layouts are defined
here once; everything else refers to the names.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from pneumafit.physics.seal_effects import SEAL_EFFECTS
from pneumafit.physics.valve_map import (
    MAP_B_FRACTIONS,
    MAP_BE_NAMES,
    MAP_BS_NAMES,
    MAP_C_BOUNDS,
    MAP_CE_NAMES,
    MAP_CS_NAMES,
    MAP_KNOTS,
    sample_iso,
)

# ----------------------------------------------------------------------------
# State vector (fixed maximal layout; a structure uses a subset)
# ----------------------------------------------------------------------------
X_Y, X_V, X_PN, X_PP, X_TN, X_TP = 0, 1, 2, 3, 4, 5
X_MS, X_ME = 6, 7  # accumulated mass drawn from supply / sent to exhaust (kg)
X_TWN, X_TWP = 8, 9  # wall temperatures (effect wall_thermal_mass)
X_UN, X_UP = 10, 11  # effective spool commands (effect valve_dynamics)
X_DUN, X_DUP = 12, 13  # their rates (second-order valve dynamics)
X_Z = 14  # bristle deflection z (m) of the LuGre friction law
# the states of effects registered from outside the package (Effect.states:
# each slot claimed by one effect; its unit is the effect's). The cached
# kernel has the first (NX = 16): two slots more cost the built-in
# structures 3.5 % of the compiled code's instructions, so the copy of the
# kernel that runs outside parts (part_kernel) is compiled with the slots
# its effects claim (state_size; docs/effects.md)
X_E0, X_E1, X_E2 = 15, 16, 17
EFFECT_STATE_SLOTS = (X_E0, X_E1, X_E2)
NX = 16
STATE_NAMES = (  # every slot: the cached kernel's NX and the effects' beyond
    "y", "v", "p_N", "p_P", "T_N", "T_P", "m_supply", "m_exhaust",
    "Tw_N", "Tw_P", "us_N", "us_P", "dus_N", "dus_P", "z_f", "e_0", "e_1", "e_2",
)  # fmt: skip
STATE_UNITS = (
    "m", "m/s", "Pa", "Pa", "K", "K", "kg", "kg", "K", "K", "V", "V", "V/s", "V/s", "m",
    "", "", "",
)  # fmt: skip


def state_size(slots: Iterable[int] = ()) -> int:
    """Length of the state vector of a kernel that runs the effect states in
    ``slots`` (``Effect.states``): the cached kernel's ``NX``, or one past
    the highest slot claimed."""
    return max([NX, *(int(s) + 1 for s in slots)])


# ----------------------------------------------------------------------------
# Output channels (simulated, at the recording's sample times)
# ----------------------------------------------------------------------------
CHANNELS = (
    "y", "v", "p_N", "p_P", "T_N", "T_P", "qm_N", "qm_P",
    "u_N", "u_P", "lambda_N", "lambda_P", "m_supply", "m_exhaust", "F_f",
)  # fmt: skip
CHANNEL_UNITS = (
    "m", "m/s", "Pa", "Pa", "K", "K", "kg/s", "kg/s",
    "V", "V", "W/m^2/K", "W/m^2/K", "kg", "kg", "N",
)  # fmt: skip
NCH = len(CHANNELS)
CH = {name: i for i, name in enumerate(CHANNELS)}

# ----------------------------------------------------------------------------
# Configuration vector (int64)
# ----------------------------------------------------------------------------
C_HEAT = 0  # 0 polytropic, 1 constant lambda, 2 convection
C_BLOCKED = 1  # 0 moving piston, 1 piston blocked (charge/discharge tests)
C_CHAMBER = 2  # chamber under test when blocked: 0 = N, 1 = P
C_INPUT = 3  # 0 commands replayed open loop, 1 pd law, 2 state feedback (closed loop)
C_AIRPROPS = 4  # 0 mu, k_air at the wall temperature; 1 Sutherland at gas T
C_CHAMBER_LEAK = 5  # effect chamber_leakage on/off
C_EXTERNAL_LEAK = 6  # effect external_leakage on/off
C_VALVE_ORDER = 7  # effect valve_dynamics: 0 static, 1 first order, 2 second
C_WALL_MASS = 8  # effect wall_thermal_mass on/off
C_FORCED_CONV = 9  # effect forced_convection on/off
C_SUPPLY_DROP = 10  # effect supply_pressure_drop on/off
C_STATIC_FLOW = 11  # 1: no ODE, static valve flow at measured p, u (flow tests)
C_SEAL_FRICTION = 12  # effect pressure-dependent seal friction on/off
C_VALVE_LAW = 13  # servo-valve law: 0 ISO 6358 (parametric), 1 measured map
C_FRICTION_LAW = 14  # friction law: 0 switch model (stick-slip modes), 1 LuGre (bristle z)
C_FRICTION_ASYM = 15  # effect friction_asymmetry on/off
C_AREA_FACTOR = 16  # effect effective_area on/off
C_INPUT_HOLD = 17  # sampled inputs (commands, y_ref): 1 held between samples, 0 linear
C_PART_EFFECTS = 18  # bit mask of the effects registered with kernel code outside the package
NCFG = 19

# HEAT_LAWS, VALVE_LAWS, FRICTION_LAWS (law name -> its code in C_HEAT,
# C_VALVE_LAW, C_FRICTION_LAW) are live views of the parts registries
# (models/parts: one object per law); see __getattr__ at the end.

# ----------------------------------------------------------------------------
# Controller vector (float64): pd law [kp, kd, u0, umax, 0...]; state feedback
# [a, w, v_e, umax, K (6: y, v, p_N, p_P, T_N, T_P), x_e (6, same order)], with
# a, w the dead-band compensation u = v + a tanh(v / w) (off when w = 0)
# ----------------------------------------------------------------------------
NCTRL = 16
CTRL_DB_AMPLITUDE = 0  # state feedback: compensated dead-band half-width a (V)
CTRL_DB_WIDTH = 1  # state feedback: width w of its tanh (V); 0 = no compensation
LAW_PD = 1
LAW_STATE_FEEDBACK = 2


# ----------------------------------------------------------------------------
# Parameter vector
# ----------------------------------------------------------------------------
@dataclass(frozen=True)
class ParameterSpec:
    """Definition of one named model parameter.

    Attributes
    ----------
    name : str
        Canonical name.
    unit : str
        SI unit of the value (pint syntax).
    default : float
        Default value in ``unit``.
    lower, upper : float
        Physical bounds (inclusive) used to validate values and as fit bounds.
    group : str
        ``rig``, ``valve``, ``heat``, ``friction``, ``effect``, ``numerics``
        or ``valve_map`` (the measured valve map, used by the ``map`` law).
    description : str
        One line for tables and reports.
    """

    name: str
    unit: str
    default: float
    lower: float
    upper: float
    group: str
    description: str


_INF = float("inf")
_T = TypeVar("_T")


def _seal_spec(name: str) -> ParameterSpec:
    # the seal and barrel effects' parameters, from their shared definitions
    e = SEAL_EFFECTS[name]
    return ParameterSpec(e.parameter, e.unit, e.neutral, e.lower, e.upper, "effect",
                         e.description)  # fmt: skip


_BASE_SPECS: tuple[ParameterSpec, ...] = (
    # --- rig (from campaign.toml) ---
    ParameterSpec("bore", "m", 0.032, 1e-3, 1.0, "rig", "cylinder bore D"),
    ParameterSpec("rod", "m", 0.016, 0.0, 1.0, "rig", "rod diameter d"),
    ParameterSpec("stroke", "m", 0.5, 1e-3, 10.0, "rig", "stroke L"),
    ParameterSpec("dead_volume_P", "m^3", 2.0e-5, 1e-9, 1.0, "rig", "dead volume of chamber P"),
    ParameterSpec("dead_volume_N", "m^3", 2.0e-5, 1e-9, 1.0, "rig", "dead volume of chamber N"),
    ParameterSpec("moving_mass", "kg", 17.0, 1e-3, 1e4, "rig", "moving load M"),
    ParameterSpec("supply_pressure", "Pa", 7.0e5, 1e3, 1e8, "rig", "supply pressure P_S (abs)"),
    ParameterSpec("exhaust_pressure", "Pa", 1.013e5, 1e2, 1e8, "rig", "exhaust/atmosphere (abs)"),
    ParameterSpec("ambient_temperature", "K", 293.15, 150.0, 600.0, "rig", "ambient T_atm"),
    ParameterSpec("wall_temperature", "K", 293.15, 150.0, 600.0, "rig", "cylinder wall T_w"),
    ParameterSpec("characteristic_length", "m", 0.032, 1e-4, 10.0, "rig", "convection length"),
    ParameterSpec("mounting_angle", "rad", 0.0, -1.5708, 1.5708, "rig", "rod axis above horizon"),
    ParameterSpec("external_force", "N", 0.0, -_INF, _INF, "rig", "external load opposing +y"),
    # --- servo-distributor (ISO 6358, both valves alike) ---
    ParameterSpec("valve_C_supply", "m^3/s/Pa", 1.0e-8, 0.0, 1e-5, "valve",
                  "sonic conductance of the supply path, full opening"),
    ParameterSpec("valve_b_supply", "", 0.30, 0.01, 0.95, "valve", "critical ratio, supply path"),
    ParameterSpec("valve_C_exhaust", "m^3/s/Pa", 1.1e-8, 0.0, 1e-5, "valve",
                  "sonic conductance of the exhaust path, full opening"),
    ParameterSpec("valve_b_exhaust", "", 0.30, 0.01, 0.95, "valve", "critical ratio, exhaust"),
    ParameterSpec("valve_m", "", 0.5, 0.2, 1.0, "valve", "subsonic index m"),
    ParameterSpec("valve_x_laminar", "", 0.995, 0.96, 0.9999, "valve",
                  "pressure ratio where the laminar (linear) tail starts"),
    ParameterSpec("valve_overlap", "V", 0.3, 0.0, 5.0, "valve", "dead band half-width u_0"),
    ParameterSpec("valve_u_sat", "V", 10.0, 0.1, 100.0, "valve", "command of full opening"),
    ParameterSpec("valve_C_leak", "m^3/s/Pa", 2.0e-11, 0.0, 1e-7, "valve",
                  "centre leakage conductance of each path at u = 0"),
    ParameterSpec("valve_leak_width", "V", 0.3, 1e-3, 10.0, "valve",
                  "command scale of the leakage shift between paths"),
    ParameterSpec("valve_n_supply", "", 1.0, 0.34, 4.0, "valve",
                  "opening shape exponent of the supply path (1: linear ramp)"),
    ParameterSpec("valve_n_exhaust", "", 1.0, 0.34, 4.0, "valve",
                  "opening shape exponent of the exhaust path (1: linear ramp)"),
    ParameterSpec("valve_full_supply", "", 1.0, 0.2, 1.0, "valve",
                  "fraction of u_sat at which the supply path is fully open"),
    ParameterSpec("valve_full_exhaust", "", 1.0, 0.2, 1.0, "valve",
                  "fraction of u_sat at which the exhaust path is fully open"),
    ParameterSpec("valve_null_offset", "V", 0.0, -5.0, 5.0, "valve",
                  "command at which the spool is centred (null offset)"),
    ParameterSpec("valve_knee_supply", "", 1.0, 1.0, 20.0, "valve",
                  "knee exponent of the supply path (1: power law; > 1: S-shaped)"),
    ParameterSpec("valve_knee_exhaust", "", 1.0, 1.0, 20.0, "valve",
                  "knee exponent of the exhaust path (1: power law; > 1: S-shaped)"),
    # --- heat transfer ---
    ParameterSpec("k", "", 1.2, 1.0, 1.4, "heat", "polytropic index"),
    ParameterSpec("lambda", "W/m^2/K", 15.0, 0.0, 1e6, "heat", "constant heat-transfer coeff."),
    ParameterSpec("xi", "", 0.4, 1e-4, 100.0, "heat", "Nusselt coefficient xi (Pr folded in)"),
    ParameterSpec("beta", "", 0.27, 0.05, 0.6, "heat", "Grashof exponent beta"),
    # --- friction ---
    ParameterSpec("friction_static", "N", 50.0, 0.0, 1e10, "friction", "static friction F_s"),
    ParameterSpec("friction_coulomb", "N", 30.0, 0.0, 1e5, "friction", "Coulomb friction F_c"),
    ParameterSpec("friction_viscous", "N s/m", 60.0, 0.0, 1e6, "friction", "viscous coeff. b"),
    ParameterSpec("stribeck_velocity", "m/s", 0.02, 1e-4, 10.0, "friction", "Stribeck velocity"),
    # --- optional effects (used when the structure switches them on) ---
    ParameterSpec("chamber_leak_conductance", "kg/s/Pa", 0.0, 0.0, 1e-6, "effect",
                  "laminar leak across the piston seal, q = G (P_P - P_N)"),
    ParameterSpec("external_leak_conductance", "kg/s/Pa", 0.0, 0.0, 1e-6, "effect",
                  "laminar leak of each chamber to atmosphere, q = G (P - P_atm)"),
    ParameterSpec("valve_time_constant", "s", 0.0, 0.0, 1.0, "effect",
                  "first-order spool lag"),
    ParameterSpec("valve_natural_frequency", "rad/s", 600.0, 1.0, 1e5, "effect",
                  "second-order spool natural frequency"),
    ParameterSpec("valve_damping_ratio", "", 0.7, 0.05, 5.0, "effect",
                  "second-order spool damping"),
    ParameterSpec("wall_heat_capacity", "J/K/m^2", 4000.0, 1.0, 1e7, "effect",
                  "heat capacity of the wall per unit exchange area"),
    ParameterSpec("wall_outer_coefficient", "W/m^2/K", 10.0, 0.0, 1e5, "effect",
                  "wall-to-ambient heat-transfer coefficient"),
    ParameterSpec("forced_convection_gain", "W/m^2/K/(kg/s)", 0.0, 0.0, 1e7, "effect",
                  "increase of lambda per unit inflow during filling"),
    ParameterSpec("supply_line_resistance", "Pa/(kg/s)", 0.0, 0.0, 1e10, "effect",
                  "supply pressure drop per unit supply flow"),
    _seal_spec("seal_friction"),
    # --- numerics (end stops) ---
    ParameterSpec("stop_stiffness", "N/m", 1.0e6, 1.0, 1e10, "numerics", "end-stop stiffness"),
    ParameterSpec("stop_damping", "N s/m", 6.0e3, 0.0, 1e8, "numerics", "end-stop damping"),
    # --- friction, LuGre law only (appended: the indices before them did not move)
    ParameterSpec("friction_stiffness", "N/m", 3.0e5, 1e3, 1e8, "friction",
                  "bristle stiffness sigma0 (LuGre)"),
    ParameterSpec("friction_damping", "N s/m", 1.0e3, 0.0, 1e5, "friction",
                  "bristle damping sigma1 (LuGre)"),
)  # fmt: skip


# appended after the LuGre parameters (the indices before them did not move)
_BASE_SPECS = (*_BASE_SPECS, _seal_spec("friction_asymmetry"), _seal_spec("effective_area"))

# appended after the seal effects: how the external leak is shared by the chambers
_BASE_SPECS = (
    *_BASE_SPECS,
    ParameterSpec("external_leak_split", "", 0.0, -1.0, 1.0, "effect",
                  "share of the external leak by chamber: G_P = G (1 + s), G_N = G (1 - s)"),
)  # fmt: skip

# appended after the external leak's split: the heat-exchange area's convention
_BASE_SPECS = (
    *_BASE_SPECS,
    ParameterSpec("heat_area_ends", "", 1.0, 0.0, 5.0, "heat",
                  "share of heads, piston faces and rod in the exchange area (0: bore wall only)"),
)  # fmt: skip


def _map_specs(base: tuple[ParameterSpec, ...]) -> tuple[ParameterSpec, ...]:
    # measured valve map (physics.valve_map): knot values of the default ISO valve
    by_name = {s.name: s for s in base}
    iso = {name: s.default for name, s in by_name.items()}
    c_s, c_e = sample_iso(
        iso["valve_C_supply"], iso["valve_b_supply"], iso["valve_C_exhaust"],
        iso["valve_b_exhaust"], iso["valve_overlap"], iso["valve_u_sat"], iso["valve_C_leak"],
        iso["valve_leak_width"],
    )  # fmt: skip
    lo, hi = MAP_C_BOUNDS
    specs = []
    for path, names, values in (("supply", MAP_CS_NAMES, c_s), ("exhaust", MAP_CE_NAMES, c_e)):
        for name, value, f in zip(names, values, MAP_KNOTS, strict=True):
            specs.append(ParameterSpec(
                name, "m^3/s/Pa", value, lo, hi, "valve_map",
                f"sonic conductance of the {path} path at u = {f:+g} u_sat",
            ))  # fmt: skip
    for path, names, key in (("supply", MAP_BS_NAMES, "valve_b_supply"),
                             ("exhaust", MAP_BE_NAMES, "valve_b_exhaust")):  # fmt: skip
        side = "u" if path == "supply" else "-u"
        for name, f in zip(names, MAP_B_FRACTIONS, strict=True):
            specs.append(ParameterSpec(
                name, "", iso[key], by_name[key].lower, by_name[key].upper, "valve_map",
                f"critical ratio of the {path} path at {side} = {f:g} u_sat",
            ))  # fmt: skip
    return tuple(specs)


class LiveTuple(Sequence[_T]):
    """A live read-only tuple: the items ``items()`` returns, read on each use.

    Compares equal to a tuple or list of the same items. The parameter
    table below is one (a list this module appends to), and so are the
    parts registries' name lists (:data:`pneumafit.models.parts.MODEL_NAMES`).
    """

    def __init__(self, items: Callable[[], Sequence[_T]]) -> None:
        self._items = items

    def __getitem__(self, index: Any) -> Any:
        item = self._items()[index]
        return tuple(item) if isinstance(index, slice) else item

    def __len__(self) -> int:
        return len(self._items())

    def __iter__(self) -> Iterator[_T]:
        return iter(tuple(self._items()))

    def __contains__(self, item: object) -> bool:
        return item in self._items()

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (tuple, list, LiveTuple)):
            return tuple(self) == tuple(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return repr(tuple(self._items()))


_SPEC_LIST: list[ParameterSpec] = list(_BASE_SPECS + _map_specs(_BASE_SPECS))
_NAME_LIST: list[str] = [s.name for s in _SPEC_LIST]

#: Every model parameter. The valve-map parameters come after the base block;
#: every index is taken by name (P, P_* below, and the map's contiguous blocks
#: P_MAP_*), so appending to the base block only shifts the map block.
#: Parameters of parts from outside the package
#: (:func:`pneumafit.models.parts.register_parameter`) come last, in
#: registration order: this table, :data:`PARAMETER_NAMES`, :data:`P` and
#: :data:`SPECS` are live (the vector grows; no built-in index moves).
PARAMETER_SPECS: Sequence[ParameterSpec] = LiveTuple(lambda: _SPEC_LIST)
#: The parameter names, in vector order (live, as :data:`PARAMETER_SPECS`).
PARAMETER_NAMES: Sequence[str] = LiveTuple(lambda: _NAME_LIST)
#: Number of built-in parameters (the package's own vector length); with
#: parameters registered from outside, :func:`n_parameters` is the length.
NP = len(_SPEC_LIST)
P = {name: i for i, name in enumerate(_NAME_LIST)}
SPECS = {s.name: s for s in _SPEC_LIST}

#: Groups a parameter registered from outside the package may have: its
#: part's (a heat, valve or friction law's, or an effect's).
PART_PARAMETER_GROUPS = ("heat", "valve", "friction", "effect")


def n_parameters() -> int:
    """Length of the parameter vector: the built-in parameters and any registered since."""
    return len(_SPEC_LIST)


def _append_parameter(spec: ParameterSpec) -> int:
    """Append a parameter to the table (``parts.register_parameter`` checks it first)."""
    _SPEC_LIST.append(spec)
    _NAME_LIST.append(spec.name)
    P[spec.name] = len(_SPEC_LIST) - 1
    SPECS[spec.name] = spec
    return P[spec.name]


def _remove_last_parameter(name: str) -> None:
    """Remove the last parameter, which must be ``name`` and registered from outside."""
    if len(_SPEC_LIST) <= NP or _NAME_LIST[-1] != name:
        raise ValueError(f"parameter {name!r}: only the last one registered can be removed")
    _SPEC_LIST.pop()
    _NAME_LIST.pop()
    del P[name], SPECS[name]


# Integer indices for the kernels (numba treats module globals as constants).
P_BORE = P["bore"]
P_ROD = P["rod"]
P_STROKE = P["stroke"]
P_V0P = P["dead_volume_P"]
P_V0N = P["dead_volume_N"]
P_MASS = P["moving_mass"]
P_PS = P["supply_pressure"]
P_PE = P["exhaust_pressure"]
P_TAMB = P["ambient_temperature"]
P_TW = P["wall_temperature"]
P_LEN = P["characteristic_length"]
P_ANGLE = P["mounting_angle"]
P_FEXT = P["external_force"]
P_CS = P["valve_C_supply"]
P_BS = P["valve_b_supply"]
P_CE = P["valve_C_exhaust"]
P_BE = P["valve_b_exhaust"]
P_VM = P["valve_m"]
P_XLAM = P["valve_x_laminar"]
P_OVERLAP = P["valve_overlap"]
P_USAT = P["valve_u_sat"]
P_CLEAK = P["valve_C_leak"]
P_LEAKW = P["valve_leak_width"]
P_NS = P["valve_n_supply"]
P_NE = P["valve_n_exhaust"]
P_FULLS = P["valve_full_supply"]
P_FULLE = P["valve_full_exhaust"]
P_NULL = P["valve_null_offset"]
P_KNEES = P["valve_knee_supply"]
P_KNEEE = P["valve_knee_exhaust"]
P_K = P["k"]
P_LAMBDA = P["lambda"]
P_XI = P["xi"]
P_BETA = P["beta"]
P_FS = P["friction_static"]
P_FC = P["friction_coulomb"]
P_FV = P["friction_viscous"]
P_VST = P["stribeck_velocity"]
P_GCL = P["chamber_leak_conductance"]
P_GEL = P["external_leak_conductance"]
P_GES = P["external_leak_split"]
P_VTAU = P["valve_time_constant"]
P_VWN = P["valve_natural_frequency"]
P_VZETA = P["valve_damping_ratio"]
P_WCAP = P["wall_heat_capacity"]
P_WOUT = P["wall_outer_coefficient"]
P_FCG = P["forced_convection_gain"]
P_RSUP = P["supply_line_resistance"]
P_SEAL = P["seal_friction_coefficient"]
P_KSTOP = P["stop_stiffness"]
P_CSTOP = P["stop_damping"]
P_SIG0 = P["friction_stiffness"]
P_SIG1 = P["friction_damping"]
P_FASYM = P["friction_asymmetry"]
P_AREA = P["area_factor"]
P_AENDS = P["heat_area_ends"]
# valve map: contiguous blocks (physics.valve_map.map_constants reads slices)
N_MAP_KNOTS = len(MAP_KNOTS)
P_MAP_CS = P[MAP_CS_NAMES[0]]
P_MAP_CE = P[MAP_CE_NAMES[0]]
P_MAP_BS = P[MAP_BS_NAMES[0]]
P_MAP_BE = P[MAP_BE_NAMES[0]]
MAP_C_LOWER, MAP_C_UPPER = MAP_C_BOUNDS
MAP_B_LOWER, MAP_B_UPPER = SPECS[MAP_BS_NAMES[0]].lower, SPECS[MAP_BS_NAMES[0]].upper


_LAW_CODES = {
    "HEAT_LAWS": "HEAT_LAW_CODES",
    "VALVE_LAWS": "VALVE_LAW_CODES",
    "FRICTION_LAWS": "FRICTION_LAW_CODES",
}


def __getattr__(name: str) -> object:
    # the law codes come from the parts registries (pneumafit.models.parts),
    # which import this module: looked up on first use, not at import
    if name in _LAW_CODES:
        from pneumafit.models import parts

        return getattr(parts, _LAW_CODES[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
