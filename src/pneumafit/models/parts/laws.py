"""The built-in heat, valve and friction laws (their kernel codes are fixed).

Each law's code is the value the compiled kernel branches on
(``kernel.rhs``: ``heat == 0/1/2``; ``kernel.VALVE_*``, ``kernel.FRICTION_*``);
the parameters' units, bounds and defaults are the table's
(:data:`pneumafit.models.PARAMETER_SPECS`).
"""

from __future__ import annotations

from pneumafit.models.parts.registry import (
    FrictionLaw,
    HeatLaw,
    ValveLaw,
    register_friction_law,
    register_heat_law,
    register_valve_law,
)
from pneumafit.physics.friction_prior import breakaway_prior
from pneumafit.physics.valve_map import MAP_PARAMETER_NAMES, map_roughness

__all__ = ["CONSTANT_LAMBDA", "CONVECTION", "ISO6358", "LUGRE", "MAP", "POLYTROPIC", "SWITCH"]

# ----------------------------------------------------------------- heat (slot C_HEAT)
# Starts of the heat stage (physics notes): polytropic k = 1.05, 1.2, 1.35;
# constant lambda 5, 15 and 40 W/m^2/K; convection laminar (xi 0.59, beta
# 1/4) and turbulent (0.10, 1/3) free convection and one in between.
POLYTROPIC = register_heat_law(
    HeatLaw(
        name="polytropic",
        code=0,
        parameters=("k",),
        description="polytropic change of state P V^k = const, no gas temperature state (eq. 8)",
        label="polytropic",
        colour="tab:green",
        order=2,
        starts=({"k": 1.05}, {"k": 1.2}, {"k": 1.35}),
    )
)
CONSTANT_LAMBDA = register_heat_law(
    HeatLaw(
        name="constant-lambda",
        code=1,
        parameters=("lambda",),
        description="wall heat exchange with a constant coefficient lambda (eq. 9)",
        label="constant lambda",
        colour="tab:blue",
        order=1,
        starts=({"lambda": 5.0}, {"lambda": 15.0}, {"lambda": 40.0}),
        extensions=("heat_area_ends",),
    )
)
CONVECTION = register_heat_law(
    HeatLaw(
        name="convection",
        code=2,
        parameters=("xi", "beta"),
        description="free convection, lambda from a Nusselt law Nu = xi Gr^beta (eq. 14)",
        label="convection (Nusselt)",
        colour="tab:red",
        order=0,
        starts=(
            {"xi": 0.59, "beta": 0.25},
            {"xi": 0.10, "beta": 1.0 / 3.0},
            {"xi": 0.25, "beta": 0.29},
        ),
        extensions=("heat_area_ends",),
    )
)

# ----------------------------------------------------------------- valve (slot C_VALVE_LAW)
# valve_m and valve_x_laminar, the flow function's shape, are shared.
ISO6358 = register_valve_law(
    ValveLaw(
        name="iso6358",
        code=0,
        parameters=(
            "valve_C_supply",
            "valve_b_supply",
            "valve_C_exhaust",
            "valve_b_exhaust",
            "valve_m",
            "valve_x_laminar",
            "valve_overlap",
            "valve_u_sat",
            "valve_C_leak",
            "valve_leak_width",
            "valve_n_supply",
            "valve_n_exhaust",
            "valve_full_supply",
            "valve_full_exhaust",
            "valve_null_offset",
            "valve_knee_supply",
            "valve_knee_exhaust",
        ),
        description="parametric ISO 6358 law (pneumafit.physics.valve)",
    )
)
MAP = register_valve_law(
    ValveLaw(
        name="map",
        code=1,
        parameters=("valve_m", "valve_x_laminar", "valve_u_sat", *MAP_PARAMETER_NAMES),
        description="measured valve map: conductances and critical ratios at knots of u "
        "(pneumafit.physics.valve_map)",
        roughness=map_roughness,
    )
)

# ----------------------------------------------------------------- friction (slot C_FRICTION_LAW)
_SWITCH_FRICTION = ("friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity")

SWITCH = register_friction_law(
    FrictionLaw(
        name="switch",
        code=0,
        parameters=_SWITCH_FRICTION,
        description="switch model of stick-slip, modes stuck/+1/-1 (pneumafit.physics.friction)",
        joint_prior=breakaway_prior,
    )
)
LUGRE = register_friction_law(
    FrictionLaw(
        name="lugre",
        code=1,
        parameters=(*_SWITCH_FRICTION, "friction_stiffness", "friction_damping"),
        description="LuGre (Canudas de Wit et al. 1995): a bristle state z_f, stiffness sigma0 "
        "and damping sigma1 on the same Stribeck curve",
        joint_prior=breakaway_prior,
    )
)
