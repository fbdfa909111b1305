"""Model structures: which heat, valve and friction law, which effects, chosen by configuration.

A :class:`ModelStructure` is turned into the integer configuration vector the
compiled kernel reads. The three structures of the paper are registered in
:data:`MODELS`; optional effects are switched on by name; the valve law
(:data:`VALVE_PARAMETERS`) and the friction law (:data:`FRICTION_PARAMETERS`)
are fields of the structure.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

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
    C_SEAL_FRICTION,
    C_STATIC_FLOW,
    C_SUPPLY_DROP,
    C_VALVE_LAW,
    C_VALVE_ORDER,
    C_WALL_MASS,
    FRICTION_LAWS,
    HEAT_LAWS,
    NCFG,
    VALVE_LAWS,
)
from pneumafit.physics.seal_effects import SEAL_EFFECTS
from pneumafit.physics.valve_map import MAP_PARAMETER_NAMES

#: Optional effects: configuration slot, parameters, one-line description.
EFFECT_SLOTS: dict[str, tuple[int, tuple[str, ...], str]] = {
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
        (SEAL_EFFECTS["seal_friction"].parameter,),
        SEAL_EFFECTS["seal_friction"].description,
    ),
    "friction_asymmetry": (
        C_FRICTION_ASYM,
        (SEAL_EFFECTS["friction_asymmetry"].parameter,),
        SEAL_EFFECTS["friction_asymmetry"].description,
    ),
    "effective_area": (
        C_AREA_FACTOR,
        (SEAL_EFFECTS["effective_area"].parameter,),
        SEAL_EFFECTS["effective_area"].description,
    ),
}

#: Parameters that each heat law uses.
HEAT_PARAMETERS: dict[str, tuple[str, ...]] = {
    "polytropic": ("k",),
    "constant-lambda": ("lambda",),
    "convection": ("xi", "beta"),
}

#: Valve parameters that each valve law uses (``valve_m`` and
#: ``valve_x_laminar``, the flow function's shape, are shared).
VALVE_PARAMETERS: dict[str, tuple[str, ...]] = {
    "iso6358": (
        "valve_C_supply", "valve_b_supply", "valve_C_exhaust", "valve_b_exhaust", "valve_m",
        "valve_x_laminar", "valve_overlap", "valve_u_sat", "valve_C_leak", "valve_leak_width",
        "valve_n_supply", "valve_n_exhaust",
    ),
    "map": ("valve_m", "valve_x_laminar", "valve_u_sat", *MAP_PARAMETER_NAMES),
}  # fmt: skip

_SWITCH_FRICTION = ("friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity")

#: Friction parameters that each friction law uses: the switch model of
#: stick-slip (:mod:`pneumafit.physics.friction`) and LuGre, which adds the
#: bristle stiffness sigma0 and damping sigma1 to the same Stribeck curve.
FRICTION_PARAMETERS: dict[str, tuple[str, ...]] = {
    "switch": _SWITCH_FRICTION,
    "lugre": (*_SWITCH_FRICTION, "friction_stiffness", "friction_damping"),
}


@dataclass(frozen=True)
class ModelStructure:
    """Structure of an actuator model.

    Parameters
    ----------
    heat : {"polytropic", "constant-lambda", "convection"}
        Heat-transfer law (paper eqs. 8, 9 and 14).
    air_properties : {"constant", "sutherland"}
        Viscosity and conductivity of air in the Grashof number: constant at
        the wall temperature, or Sutherland's law at the gas temperature.
    effects : mapping of str to int
        Optional effects switched on (value 1; ``valve_dynamics`` takes the
        order 1 or 2). Names in :data:`EFFECT_SLOTS`.
    name : str
        Name used in reports; defaults to the heat law (the valve law does
        not change it: model lists key on it).
    valve : {"iso6358", "map"}
        Servo-valve law: the parametric ISO 6358 law
        (:mod:`pneumafit.physics.valve`) or the measured valve map
        (:mod:`pneumafit.physics.valve_map`).
    friction : {"switch", "lugre"}
        Friction law: the switch model of stick-slip (modes stuck/+1/-1,
        :mod:`pneumafit.physics.friction`) or LuGre (Canudas de Wit et al.
        1995, a bristle state z_f; :func:`pneumafit.physics.friction.lugre_friction`).
        Like ``valve``, it does not change ``name``.
    """

    heat: str
    air_properties: str = "constant"
    effects: Mapping[str, int] = field(default_factory=dict)
    name: str = ""
    valve: str = "iso6358"
    friction: str = "switch"

    def __post_init__(self) -> None:
        if self.heat not in HEAT_LAWS:
            raise ValueError(
                f"model structure: heat law: expected one of {sorted(HEAT_LAWS)}, "
                f"found {self.heat!r}"
            )
        if self.air_properties not in ("constant", "sutherland"):
            raise ValueError(
                "model structure: air_properties: expected 'constant' or 'sutherland', "
                f"found {self.air_properties!r}"
            )
        if self.valve not in VALVE_LAWS:
            raise ValueError(
                f"model structure: valve: expected one of {sorted(VALVE_LAWS)}, "
                f"found {self.valve!r}"
            )
        if self.friction not in FRICTION_LAWS:
            raise ValueError(
                f"model structure: friction: expected one of {sorted(FRICTION_LAWS)}, "
                f"found {self.friction!r}"
            )
        for name, value in self.effects.items():
            if name not in EFFECT_SLOTS:
                raise ValueError(
                    f"model structure: effect: expected one of {sorted(EFFECT_SLOTS)}, "
                    f"found {name!r}"
                )
            allowed = (0, 1, 2) if name == "valve_dynamics" else (0, 1)
            if int(value) not in allowed:
                raise ValueError(
                    f"model structure: effect {name}: expected a value in {allowed}, "
                    f"found {value!r}"
                )
        object.__setattr__(self, "effects", {k: int(v) for k, v in self.effects.items() if v})
        if not self.name:
            object.__setattr__(self, "name", self.heat)

    def with_effects(self, **effects: int) -> ModelStructure:
        """Return a copy with more effects switched on (``name=value``)."""
        merged = {**self.effects, **effects}
        suffix = "+".join(sorted(k for k, v in merged.items() if v))
        return replace(self, effects=merged, name=self.heat + (f"+{suffix}" if suffix else ""))

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the dynamic states of the moving-piston model."""
        names = ["y", "v", "p_N", "p_P"]
        if self.heat != "polytropic":
            names += ["T_N", "T_P"]
        if self.effects.get("wall_thermal_mass"):
            names += ["Tw_N", "Tw_P"]
        order = self.effects.get("valve_dynamics", 0)
        if order >= 1:
            names += ["us_N", "us_P"]
        if order == 2:
            names += ["dus_N", "dus_P"]
        if self.friction == "lugre":
            names += ["z_f"]
        return tuple(names)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Model parameters (besides rig, valve, friction) used by this structure."""
        names = list(HEAT_PARAMETERS[self.heat])
        for effect, value in self.effects.items():
            params = EFFECT_SLOTS[effect][1]
            if effect == "valve_dynamics":
                params = params[:1] if value == 1 else params[1:]
            names.extend(params)
        return tuple(names)

    @property
    def valve_parameter_names(self) -> tuple[str, ...]:
        """Valve parameters used by this structure's valve law."""
        return VALVE_PARAMETERS[self.valve]

    @property
    def friction_parameter_names(self) -> tuple[str, ...]:
        """Friction parameters used by this structure's friction law."""
        return FRICTION_PARAMETERS[self.friction]

    def config(
        self,
        *,
        blocked: bool = False,
        chamber: str | None = None,
        closed_loop: bool | int = False,
        static_flow: bool = False,
    ) -> np.ndarray:
        """Integer configuration vector for the compiled kernel.

        Parameters
        ----------
        blocked : bool
            Piston blocked (charge/discharge tests): only ``chamber`` evolves.
        chamber : {"P", "N"}, optional
            Chamber under test (blocked and static-flow experiments).
        closed_loop : bool or int
            Commands from a controller instead of measured commands: True or
            1 for the ``pd`` law, 2 for state feedback (layout.LAW_*).
        static_flow : bool
            Static valve characteristic only (flow tests).
        """
        cfg = np.zeros(NCFG, dtype=np.int64)
        cfg[C_HEAT] = HEAT_LAWS[self.heat]
        cfg[C_AIRPROPS] = 1 if self.air_properties == "sutherland" else 0
        cfg[C_BLOCKED] = int(blocked)
        cfg[C_CHAMBER] = 1 if chamber == "P" else 0
        cfg[C_INPUT] = int(closed_loop)
        cfg[C_STATIC_FLOW] = int(static_flow)
        cfg[C_VALVE_LAW] = VALVE_LAWS[self.valve]
        cfg[C_FRICTION_LAW] = FRICTION_LAWS[self.friction]
        for name, value in self.effects.items():
            cfg[EFFECT_SLOTS[name][0]] = value
        return cfg


#: The paper's three structures.
MODELS: dict[str, ModelStructure] = {
    "convection": ModelStructure("convection"),
    "constant-lambda": ModelStructure("constant-lambda"),
    "polytropic": ModelStructure("polytropic"),
}


def get_structure(model: str | ModelStructure) -> ModelStructure:
    """Return a registered structure by name, or the structure itself."""
    if isinstance(model, ModelStructure):
        return model
    try:
        return MODELS[model]
    except KeyError:
        raise ValueError(f"model: expected one of {sorted(MODELS)}, found {model!r}") from None
