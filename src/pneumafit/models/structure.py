"""Model structures: which heat, valve and friction law, which effects, chosen by configuration.

A :class:`ModelStructure` is turned into the integer configuration vector the
compiled kernel reads. The three structures of the paper are registered in
:data:`MODELS`; optional effects are switched on by name; the valve law
(:data:`VALVE_PARAMETERS`) and the friction law (:data:`FRICTION_PARAMETERS`)
are fields of the structure. The laws and effects themselves, and every table
here, come from :mod:`pneumafit.models.parts` (one object per part).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from pneumafit.errors import PneumafitInputError
from pneumafit.models import parts
from pneumafit.models.layout import (
    C_AIRPROPS,
    C_BLOCKED,
    C_CHAMBER,
    C_FRICTION_LAW,
    C_HEAT,
    C_INPUT,
    C_INPUT_HOLD,
    C_PART_EFFECTS,
    C_STATIC_FLOW,
    C_VALVE_LAW,
    NCFG,
    STATE_NAMES,
)
from pneumafit.models.parts import Effect, FrictionLaw, HeatLaw, RegistryView, ValveLaw

# law name -> its code in C_HEAT, C_VALVE_LAW, C_FRICTION_LAW (= layout.*_LAWS)
HEAT_LAWS = parts.HEAT_LAW_CODES
VALVE_LAWS = parts.VALVE_LAW_CODES
FRICTION_LAWS = parts.FRICTION_LAW_CODES
#: How sampled inputs vary between samples (:attr:`ModelStructure.inputs`).
INPUT_MODES = ("hold", "linear")
#: The default of :attr:`ModelStructure.inputs` (and of every option that sets it).
INPUT_MODE = "hold"

# The tables below are live read-only views of the parts registries
# (pneumafit.models.parts, one object per law or effect): a part registered
# there appears in them at once.

#: Optional effects: configuration slot, parameters, one-line description.
EFFECT_SLOTS: RegistryView[Effect, tuple[int | None, tuple[str, ...], str]] = RegistryView(
    parts.EFFECTS, lambda e: (e.slot, e.parameters, e.description)
)

#: Parameters that each heat law uses.
HEAT_PARAMETERS: RegistryView[HeatLaw, tuple[str, ...]] = RegistryView(
    parts.HEAT_LAWS, lambda h: h.parameters
)

#: Valve parameters that each valve law uses (``valve_m`` and
#: ``valve_x_laminar``, the flow function's shape, are shared).
VALVE_PARAMETERS: RegistryView[ValveLaw, tuple[str, ...]] = RegistryView(
    parts.VALVE_LAWS, lambda v: v.parameters
)

#: Friction parameters that each friction law uses: the switch model of
#: stick-slip (:mod:`pneumafit.physics.friction`) and LuGre, which adds the
#: bristle stiffness sigma0 and damping sigma1 to the same Stribeck curve.
FRICTION_PARAMETERS: RegistryView[FrictionLaw, tuple[str, ...]] = RegistryView(
    parts.FRICTION_LAWS, lambda f: f.parameters
)


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
    inputs : {"hold", "linear"}
        How the sampled inputs replayed from a recording (valve commands,
        the controller's set-point y_ref) vary between samples: held
        (zero-order hold, the default: a digital controller's output and
        set-point) or interpolated linearly (an analog signal; every fit
        saved before 2026-11-28). Like ``valve``, it does not change
        ``name``.
    """

    heat: str
    air_properties: str = "constant"
    effects: Mapping[str, int] = field(default_factory=dict)
    name: str = ""
    valve: str = "iso6358"
    friction: str = "switch"
    inputs: str = INPUT_MODE

    def __post_init__(self) -> None:
        if self.heat not in HEAT_LAWS:
            raise PneumafitInputError(
                f"model structure: heat law: expected one of {sorted(HEAT_LAWS)}, "
                f"found {self.heat!r}"
            )
        if self.air_properties not in ("constant", "sutherland"):
            raise PneumafitInputError(
                "model structure: air_properties: expected 'constant' or 'sutherland', "
                f"found {self.air_properties!r}"
            )
        if self.valve not in VALVE_LAWS:
            raise PneumafitInputError(
                f"model structure: valve: expected one of {sorted(VALVE_LAWS)}, "
                f"found {self.valve!r}"
            )
        if self.friction not in FRICTION_LAWS:
            raise PneumafitInputError(
                f"model structure: friction: expected one of {sorted(FRICTION_LAWS)}, "
                f"found {self.friction!r}"
            )
        if self.inputs not in INPUT_MODES:
            raise PneumafitInputError(
                f"model structure: inputs: expected one of {list(INPUT_MODES)}, "
                f"found {self.inputs!r}"
            )
        for name, value in self.effects.items():
            if name not in EFFECT_SLOTS:
                raise PneumafitInputError(
                    f"model structure: effect: expected one of {sorted(EFFECT_SLOTS)}, "
                    f"found {name!r}"
                )
            allowed = parts.EFFECTS[name].option_values
            if int(value) not in allowed:
                raise PneumafitInputError(
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
        law = parts.FRICTION_LAWS.get(self.friction)
        if self.friction == "lugre" or getattr(law, "state_rate", None) is not None:
            names += ["z_f"]
        for effect, value in self.effects.items():
            states = getattr(parts.EFFECTS.get(effect), "states", ()) if value else ()
            names += [STATE_NAMES[i] for i in states]
        return tuple(names)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Model parameters (besides rig, valve, friction) used by this structure."""
        names = [*HEAT_PARAMETERS[self.heat], *parts.HEAT_LAWS[self.heat].extensions]
        for effect, value in self.effects.items():
            names.extend(parts.EFFECTS[effect].options[value])
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
        cfg[C_INPUT_HOLD] = int(self.inputs == "hold")
        law = parts.HEAT_LAWS[self.heat]
        if law.code not in parts.KERNEL_HEAT_CODES and law.kernel is None:
            raise PneumafitInputError(
                f"model structure {self.name}: heat law {self.heat}: expected a law the compiled "
                "kernel implements (codes 0-2) or one registered with its kernel code "
                "(HeatLaw.kernel), found neither (a part known to the Python side only)"
            )
        valve = parts.VALVE_LAWS[self.valve]
        if valve.code not in parts.KERNEL_VALVE_CODES and valve.kernel is None:
            raise PneumafitInputError(
                f"model structure {self.name}: valve law {valve.name}: expected a law the "
                f"compiled kernel implements (codes {sorted(parts.KERNEL_VALVE_CODES)}) or "
                "one registered with its kernel code (ValveLaw.kernel), found neither (a "
                "part known to the Python side only)"
            )
        friction = parts.FRICTION_LAWS[self.friction]
        if friction.code not in parts.KERNEL_FRICTION_CODES and friction.kernel is None:
            raise PneumafitInputError(
                f"model structure {self.name}: friction law {friction.name}: expected a law the "
                f"compiled kernel implements (codes {sorted(parts.KERNEL_FRICTION_CODES)}) or "
                "one registered with its kernel code (FrictionLaw.kernel), found neither (a "
                "part known to the Python side only)"
            )
        for name, value in self.effects.items():
            slot = EFFECT_SLOTS[name][0]
            if slot is not None:
                cfg[slot] = value
            elif parts.EFFECTS[name].kernel is not None:
                if value:
                    from pneumafit.models.part_kernel import effect_field

                    cfg[C_PART_EFFECTS] |= effect_field(name, value)
            else:
                raise PneumafitInputError(
                    f"model structure {self.name}: effect {name}: expected an effect the compiled "
                    "kernel implements (a configuration slot) or one registered with its kernel "
                    "code (Effect.kernel), found neither (a part known to the Python side only)"
                )
        return cfg


_MODEL_CACHE: dict[str, tuple[HeatLaw, ModelStructure]] = {}


def _model(law: HeatLaw) -> ModelStructure:
    # one structure object per registered heat law (rebuilt if the law is replaced)
    cached = _MODEL_CACHE.get(law.name)
    if cached is None or cached[0] is not law:
        cached = _MODEL_CACHE[law.name] = (law, ModelStructure(law.name))
    return cached[1]


#: The registered structures, one per heat law, named after it, in
#: model-list order (:attr:`pneumafit.models.parts.HeatLaw.order`): the
#: paper's convection, constant-lambda and polytropic structures.
MODELS: RegistryView[HeatLaw, ModelStructure] = RegistryView(
    parts.HEAT_LAWS, _model, order=lambda h: h.order
)


def get_structure(model: str | ModelStructure) -> ModelStructure:
    """Return a registered structure by name, or the structure itself."""
    if isinstance(model, ModelStructure):
        return model
    try:
        return MODELS[model]
    except KeyError:
        raise PneumafitInputError(
            f"model: expected one of {sorted(MODELS)}, found {model!r}"
        ) from None
