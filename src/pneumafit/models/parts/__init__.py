"""One object per swappable physics part: heat, valve and friction laws, optional effects.

A *part* is one physical law the actuator model can switch: a heat-transfer
law (:class:`HeatLaw`), a servo-valve law (:class:`ValveLaw`), a friction law
(:class:`FrictionLaw`) or an optional effect (:class:`Effect`). Each is one
frozen dataclass holding everything the Python side knows about it: its name,
the kernel code or configuration slot it switches (``layout.C_*``), its
parameters (names into :data:`pneumafit.models.PARAMETER_SPECS`, which keeps
their unit, bounds, scale and default), its starting values, its description;
a heat law also its display label, colour and position in model lists; an
effect also its option values, principal parameter, virtual-rig default,
discovery facts (law, fitting ranges and priors, signature, phases),
attribution's coefficient unit and refit-start rule.

The registries :data:`HEAT_LAWS`, :data:`VALVE_LAWS`, :data:`FRICTION_LAWS`
and :data:`EFFECTS` (read-only, name -> part) hold the built-in parts
(:mod:`.laws`, :mod:`.effects`) and whatever :func:`register_heat_law`,
:func:`register_valve_law`, :func:`register_friction_law` and
:func:`register_effect` add; each checks names, codes/slots and parameter
names and raises ``ValueError`` saying what is wrong. Every older table is a
live view of them: ``layout.HEAT_LAWS`` (name -> code), ``structure``'s
``EFFECT_SLOTS``, ``HEAT_PARAMETERS``, ``VALVE_PARAMETERS``,
``FRICTION_PARAMETERS`` and ``MODELS``, the rig's ``PRINCIPAL_PARAMETERS`` and
``EFFECT_DEFAULTS``, the discovery catalog, attribution's units and starts,
the comparison and report colours and model lists.

Limit: the compiled kernel (:mod:`pneumafit.models.kernel`) has fixed codes
and slots for the built-in parts. A heat, valve or friction law or an
effect registered from outside the package brings its compiled law
(``HeatLaw.kernel``, ``ValveLaw.kernel``, ``FrictionLaw.kernel``,
``Effect.kernel``): its structures run on a copy of the kernel whose hooks
call it (:mod:`pneumafit.models.part_kernel`). Without one it is known to
the Python side only (structures, parameter lists, the catalog, model lists
and colours) and ``ModelStructure.config`` refuses it. Every part names
parameters of ``models/layout.py``'s table (parameters of its own are
appended to it by :func:`register_parameter`). docs/architecture.md, "Adding a part", and
docs/effects.md, "Adding an effect" and "An effect from outside the
package".

>>> HEAT_LAWS["convection"].parameters
('xi', 'beta')
>>> EFFECTS["chamber_leakage"].principal
'chamber_leak_conductance'
>>> Model.CONSTANT_LAMBDA.value
'constant-lambda'
"""

from __future__ import annotations

from enum import StrEnum

from pneumafit.models.parts import effects as _effects
from pneumafit.models.parts import laws as _laws
from pneumafit.models.parts.registry import (
    EFFECTS,
    FRICTION_LAWS,
    HEAT_LAWS,
    KERNEL_FRICTION_CODES,
    KERNEL_HEAT_CODES,
    KERNEL_VALVE_CODES,
    PRIOR_KINDS,
    VALVE_LAWS,
    Effect,
    FitRange,
    FrictionLaw,
    HeatLaw,
    LiveTuple,
    RegistryView,
    SignatureTerm,
    ValveLaw,
    add_listener,
    model_names,
    register_effect,
    register_friction_law,
    register_heat_law,
    register_parameter,
    register_valve_law,
    remove_listener,
    unregister_effect,
    unregister_friction_law,
    unregister_heat_law,
    unregister_parameter,
    unregister_valve_law,
)

__all__ = [
    "EFFECTS",
    "FRICTION_LAWS",
    "FRICTION_LAW_CODES",
    "HEAT_LAWS",
    "HEAT_LAW_CODES",
    "KERNEL_FRICTION_CODES",
    "KERNEL_HEAT_CODES",
    "KERNEL_VALVE_CODES",
    "MODEL_COLOURS",
    "MODEL_NAMES",
    "PRIOR_KINDS",
    "VALVE_LAWS",
    "VALVE_LAW_CODES",
    "Effect",
    "FitRange",
    "Friction",
    "FrictionLaw",
    "HeatLaw",
    "LiveTuple",
    "Model",
    "RegistryView",
    "SignatureTerm",
    "Valve",
    "ValveLaw",
    "add_listener",
    "model_names",
    "register_effect",
    "register_friction_law",
    "register_heat_law",
    "register_parameter",
    "register_valve_law",
    "remove_listener",
    "unregister_effect",
    "unregister_friction_law",
    "unregister_heat_law",
    "unregister_parameter",
    "unregister_valve_law",
]

del _effects, _laws  # imported to register the built-in parts

#: Heat law -> its code in the configuration slot ``C_HEAT`` (``layout.HEAT_LAWS``).
HEAT_LAW_CODES: RegistryView[HeatLaw, int] = RegistryView(HEAT_LAWS, lambda h: h.code)
#: Valve law -> its code in ``C_VALVE_LAW`` (``layout.VALVE_LAWS``).
VALVE_LAW_CODES: RegistryView[ValveLaw, int] = RegistryView(VALVE_LAWS, lambda v: v.code)
#: Friction law -> its code in ``C_FRICTION_LAW`` (``layout.FRICTION_LAWS``).
FRICTION_LAW_CODES: RegistryView[FrictionLaw, int] = RegistryView(FRICTION_LAWS, lambda f: f.code)
#: The model names (one per heat law) in model-list order: comparison, report.
MODEL_NAMES = LiveTuple(model_names)
#: Model name -> its colour in figures (measured data black), model-list order.
MODEL_COLOURS: RegistryView[HeatLaw, str] = RegistryView(
    HEAT_LAWS, lambda h: h.colour, order=lambda h: h.order
)


def _enum_member(name: str) -> str:
    return name.upper().replace("-", "_")


# Choices for command lines and APIs: the built-in parts at import (a part
# registered later is in the registries, not in these enums).
#: The model names (heat laws), in model-list order: ``Model.CONVECTION`` ...
Model = StrEnum("Model", [(_enum_member(n), n) for n in model_names()])  # type: ignore[misc]
#: The valve laws: ``Valve.ISO6358``, ``Valve.MAP``.
Valve = StrEnum("Valve", [(_enum_member(n), n) for n in VALVE_LAWS])  # type: ignore[misc]
#: The friction laws: ``Friction.SWITCH``, ``Friction.LUGRE``.
Friction = StrEnum("Friction", [(_enum_member(n), n) for n in FRICTION_LAWS])  # type: ignore[misc]
Model.__doc__ = "Model names (one per heat law), in model-list order."
Valve.__doc__ = "Valve law names."
Friction.__doc__ = "Friction law names."
