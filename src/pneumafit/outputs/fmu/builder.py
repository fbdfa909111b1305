"""Build an FMI 2.0 co-simulation FMU of a fitted actuator model.

The FMU holds the model's equations in C (``c/pneumafit_model.c``, a port of
:mod:`pneumafit.models.kernel` with Kutta's third-order method and the switch
model's event location) and the FMI 2.0 co-simulation interface
(``c/pneumafit_fmi2.c``). Two headers are generated per FMU from
:mod:`pneumafit.models.layout`, so that parameter names, units, indices and
values have one source: ``pneumafit_config.h`` (state and parameter indices,
the structure's laws, physical constants) and ``pneumafit_values.h`` (the
fitted values, value references, start values, GUID). The archive holds
``modelDescription.xml``, ``binaries/<platform>/<id>.so`` built with the
system's C compiler and ``sources/`` (a tool with a compiler can rebuild it).
"""

from __future__ import annotations

import datetime
import hashlib
import math
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.models.layout import (
    HEAT_LAWS,
    MAP_B_LOWER,
    MAP_B_UPPER,
    MAP_C_LOWER,
    MAP_C_UPPER,
    PARAMETER_NAMES,
    SPECS,
    STATE_NAMES,
    STATE_UNITS,
    P,
    state_size,
)
from pneumafit.models.part_kernel import hooked_effects
from pneumafit.models.parts import EFFECTS as EFFECT_PARTS
from pneumafit.models.parts import FRICTION_LAWS as FRICTION_LAW_PARTS
from pneumafit.models.parts import HEAT_LAWS as HEAT_LAW_PARTS
from pneumafit.models.parts import VALVE_LAWS as VALVE_LAW_PARTS
from pneumafit.models.parts import Effect, FrictionLaw, HeatLaw, ValveLaw
from pneumafit.models.structure import (
    EFFECT_SLOTS,
    FRICTION_PARAMETERS,
    VALVE_PARAMETERS,
    ModelStructure,
)

__all__ = [
    "FMU_INPUTS",
    "FmuBuildError",
    "FmuVariable",
    "build_fmu",
    "c_code_digest",
    "check_structure",
    "find_compiler",
    "fmu_variables",
    "outside_effects",
    "outside_friction_law",
    "outside_heat_law",
    "outside_valve_law",
    "parts_header",
    "write_fmu",
]

#: C sources shipped in the package (``c/``) and copied into ``sources/``.
C_SOURCES = ("pneumafit_model.c", "pneumafit_fmi2.c")
C_HEADERS = ("pneumafit_model.h", "fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
#: Generated per FMU besides them: ``pneumafit_config.h``, ``pneumafit_values.h``
#: and ``pneumafit_parts.h`` (:func:`parts_header`).

#: Value references: inputs, outputs (10 + i), start values (200 + state
#: index), integration step, parameters (1000 + index in layout.PARAMETER_NAMES).
VR_INPUT = {"u_P": 1, "u_N": 2}
VR_OUTPUT_BASE = 10
VR_START_BASE = 200
VR_INTEGRATION_STEP = 300
VR_PARAMETER_BASE = 1000

#: Inputs: the valve commands the simulator's open-loop mode replays.
FMU_INPUTS = (
    ("u_P", "V", "command of the servo-valve of chamber P (positive: to supply)"),
    ("u_N", "V", "command of the servo-valve of chamber N (positive: to supply)"),
)

#: Outputs (name, unit, description); z_f only with the LuGre law, Tw_* with the
#: wall_thermal_mass effect, us_* with valve_dynamics (value reference 10 + index).
_OUTPUTS = (
    ("y", "m", "piston position (0 retracted, chamber P smallest)"),
    ("v", "m/s", "piston velocity"),
    ("p_N", "Pa", "absolute pressure of chamber N (rod side)"),
    ("p_P", "Pa", "absolute pressure of chamber P (bore side)"),
    ("T_N", "K", "gas temperature of chamber N"),
    ("T_P", "K", "gas temperature of chamber P"),
    ("qm_N", "kg/s", "valve mass flow into chamber N"),
    ("qm_P", "kg/s", "valve mass flow into chamber P"),
    ("lambda_N", "W/m^2/K", "gas-to-wall heat-transfer coefficient of chamber N"),
    ("lambda_P", "W/m^2/K", "gas-to-wall heat-transfer coefficient of chamber P"),
    ("m_supply", "kg", "air mass drawn from supply since the start"),
    ("m_exhaust", "kg", "air mass sent to exhaust since the start"),
    ("F_f", "N", "friction force (positive towards smaller y)"),
    ("z_f", "m", "LuGre bristle deflection"),
    ("Tw_N", "K", "wall temperature of chamber N"),
    ("Tw_P", "K", "wall temperature of chamber P"),
    ("us_N", "V", "effective spool command of the valve of chamber N"),
    ("us_P", "V", "effective spool command of the valve of chamber P"),
)

#: States whose start value is a parameter of the FMU (T only with heat states).
_START_STATES = ("y", "v", "p_N", "p_P", "T_N", "T_P")

#: Parameter groups every structure exposes besides its laws' parameters.
_ALWAYS_GROUPS = ("rig", "numerics")

#: Laws and effects the C model implements (check_structure).
SUPPORTED_VALVES = ("iso6358", "map")
SUPPORTED_FRICTION = ("switch", "lugre")
SUPPORTED_HEAT = ("polytropic", "constant-lambda", "convection")
SUPPORTED_AIR = ("constant", "sutherland")
SUPPORTED_EFFECTS = (
    "chamber_leakage", "external_leakage", "valve_dynamics", "wall_thermal_mass",
    "forced_convection", "supply_pressure_drop", "seal_friction", "friction_asymmetry",
    "effective_area",
)  # fmt: skip

#: Integration method of the FMU (the simulator's default).
FMU_METHOD = "kutta3"


class FmuBuildError(PneumafitInputError):
    """The FMU cannot be built: no C compiler, or the compiler failed."""


@dataclass(frozen=True)
class FmuVariable:
    """One scalar variable of the model description.

    Attributes
    ----------
    name : str
    value_reference : int
    causality : {"input", "output", "parameter"}
    unit : str
        pint syntax, "" for dimensionless.
    start : float or None
        Start value (inputs and parameters).
    description : str
    minimum, maximum : float or None
        Bounds of a parameter (layout.SPECS).
    """

    name: str
    value_reference: int
    causality: str
    unit: str
    start: float | None
    description: str
    minimum: float | None = None
    maximum: float | None = None


def _own_code(law: Any) -> Any:
    """``law`` when it brings kernel code of its own (registration keeps such
    a law off the kernel's own codes), else None."""
    return law if law is not None and law.kernel is not None else None


def outside_heat_law(structure: ModelStructure) -> HeatLaw | None:
    """The structure's heat law when it comes from outside the package with
    kernel code, else None."""
    return _own_code(HEAT_LAW_PARTS.get(structure.heat))


def outside_valve_law(structure: ModelStructure) -> ValveLaw | None:
    """The structure's valve law when it comes from outside the package with
    kernel code, else None."""
    return _own_code(VALVE_LAW_PARTS.get(structure.valve))


def outside_friction_law(structure: ModelStructure) -> FrictionLaw | None:
    """The structure's friction law when it comes from outside the package
    with kernel code, else None."""
    return _own_code(FRICTION_LAW_PARTS.get(structure.friction))


def outside_effects(structure: ModelStructure) -> list[Effect]:
    """The structure's effects switched on that come from outside the package
    with kernel code, in the order in which the simulator's hook adds them
    (:func:`pneumafit.models.part_kernel.hooked_effects`)."""
    return [e for e in hooked_effects() if structure.effects.get(e.name)]


def check_structure(structure: ModelStructure, where: str = "model") -> None:
    """Raise :class:`PneumafitInputError` unless the FMU supports ``structure``.

    Supported (the laws the C model was written for; a law or effect added to
    the simulator later is refused until the C model has it): the ISO 6358
    valve law and the measured valve map, the switch and LuGre friction laws,
    the polytropic, constant-lambda and convection heat laws (air properties
    constant or by Sutherland's law) and the optional effects of
    :data:`SUPPORTED_EFFECTS`; and a heat, valve or friction law or effects
    from outside the package that bring their law in C (``HeatLaw.c_code``,
    ``ValveLaw.c_code``, ``FrictionLaw.c_code``, ``Effect.c_code`` and, with
    a state, ``c_state_rate``; :func:`parts_header`).
    """
    problems = []
    laws = (
        ("valve law", structure.valve, SUPPORTED_VALVES, outside_valve_law, "ValveLaw.c_code"),
        ("heat law", structure.heat, SUPPORTED_HEAT, outside_heat_law, "HeatLaw.c_code"),
        ("friction law", structure.friction, SUPPORTED_FRICTION, outside_friction_law,
         "FrictionLaw.c_code and, with a state, c_state_rate"),
    )  # fmt: skip
    for kind, name, supported, outside_law, field in laws:
        if name in supported:
            continue
        law = outside_law(structure)
        if law is None:
            problems.append(f"{kind} {name!r}")
        elif law.c_code is None:
            problems.append(
                f"{kind} {name!r} (from outside the package, without its C code: {field})"
            )
    if structure.air_properties not in SUPPORTED_AIR:
        problems.append(f"air properties {structure.air_properties!r}")
    ported = {e.name for e in outside_effects(structure) if e.c_code is not None}
    unknown = sorted(set(structure.effects) - set(SUPPORTED_EFFECTS) - ported)
    if unknown:
        outside = {e.name for e in outside_effects(structure)}
        problems.append(
            "effects "
            + ", ".join(
                f"{n} (from outside the package, without its C code: Effect.c_code)"
                if n in outside else n
                for n in unknown
            )
        )  # fmt: skip
    if problems:
        raise PneumafitInputError(
            f"{where}: cannot export this structure as an FMU: unsupported "
            + "; ".join(problems)
            + f". Supported: valve {' or '.join(SUPPORTED_VALVES)}, friction "
            f"{' or '.join(SUPPORTED_FRICTION)}, heat {', '.join(SUPPORTED_HEAT)}, effects "
            f"{', '.join(SUPPORTED_EFFECTS)}, and laws or effects from outside the package "
            "that bring their C code"
        )


def c_code_digest() -> str:
    """sha256 of the C code that the registered parts from outside the package
    bring for the FMU ("" when none brings any): the main job's export stage
    runs again when it changes, which the fits' parts digest
    (:func:`pneumafit.models.part_kernel.parts_digest`, kernel code only)
    does not see."""
    items = [
        f"{kind}|{part.name}|{part.c_code}|{getattr(part, 'c_state_rate', None)}"
        for kind, registry in (("heat", HEAT_LAW_PARTS), ("valve", VALVE_LAW_PARTS),
                               ("friction", FRICTION_LAW_PARTS), ("effect", EFFECT_PARTS))
        for part in registry.values()
        if getattr(part, "c_code", None) is not None
    ]  # fmt: skip
    return hashlib.sha256("\n".join(items).encode()).hexdigest() if items else ""


def parts_header(structure: ModelStructure) -> str:
    """``pneumafit_parts.h``: the C code of the structure's parts from outside the package.

    Each function is a part's ``c_code`` (or ``c_state_rate``), called where
    the simulator calls that part's kernel code: ``pf_part_heat`` for a heat
    code above the kernel's own (``kernel.part_heat``), ``pf_part_valve`` in
    the valve function when ``PF_PART_VALVE`` (``kernel.part_valve``),
    ``pf_part_friction`` and ``pf_part_friction_rate`` when
    ``PF_PART_FRICTION`` (``kernel.part_friction``, ``part_friction_rate``),
    or ``pf_part_friction_sliding`` in the switch model's sliding modes
    when ``PF_PART_FRICTION_STUCK`` too (``kernel.part_friction_sliding``,
    a law with ``FrictionLaw.stuck``),
    ``pf_part_effects``, the outside effects' six terms added in
    registration order, and ``pf_part_effect_rates``, the rates of their
    states (each effect's in its slot), when ``PF_PART_EFFECTS`` > 0 (``kernel.part_effects``,
    ``part_effect_rates``). A part the structure does not have gets a
    function that returns zeros and is never called.
    """
    heat = outside_heat_law(structure)
    valve = outside_valve_law(structure)
    friction = outside_friction_law(structure)
    effects = outside_effects(structure)
    stuck = friction is not None and friction.stuck
    smooth = friction if friction is not None and not stuck else None
    lines = [
        "/* Generated by pneumafit.outputs.fmu: the C code of the parts from outside the",
        "   package (the c_code and c_state_rate of HeatLaw, ValveLaw, FrictionLaw and",
        "   Effect), as given. Do not edit. */",
        "#ifndef PNEUMAFIT_PARTS_H",
        "#define PNEUMAFIT_PARTS_H",
        "",
        "#include <math.h>",
        '#include "pneumafit_config.h"',
        "",
        f"#define PF_PART_EFFECTS {len(effects)}",
        f"#define PF_PART_FRICTION {0 if friction is None else 1}",
        f"#define PF_PART_FRICTION_STUCK {1 if stuck else 0}",
        f"#define PF_PART_VALVE {0 if valve is None else 1}",
        "",
        f"/* heat law {heat.name!r} */" if heat is not None else "/* no outside heat law */",
        "static double pf_part_heat(const double *p, double pres, double temp, double t_wall)",
        "{",
        "    (void)p; (void)pres; (void)temp; (void)t_wall;",
        *(_indented(heat.c_code) if heat is not None and heat.c_code else ["    return 0.0;"]),
        "}",
    ]
    lines += [
        "",
        f"/* valve law {valve.name!r}: out = (q_net, h_in, q_supply) */"
        if valve is not None else "/* no outside valve law */",
        "static void pf_part_valve(double u, double pres, double temp, double p_s,",
        "                          const double *p, double *out)",
        "{",
        "    (void)u; (void)pres; (void)temp; (void)p_s; (void)p;",
        *(_indented(valve.c_code or "") if valve is not None
          else ["    out[0] = out[1] = out[2] = 0.0;"]),
        "}",
        "",
        f"/* friction law {smooth.name!r}: the force */"
        if smooth is not None else "/* no smooth outside friction law */",
        "static double pf_part_friction(double v, double f_s, double f_c, const double *x,",
        "                               const double *p)",
        "{",
        "    (void)v; (void)f_s; (void)f_c; (void)x; (void)p;",
        *(_indented(smooth.c_code or "") if smooth is not None else ["    return 0.0;"]),
        "}",
        "",
        "/* ... and the rate of its state (the bristle slot z_f) */",
        "static double pf_part_friction_rate(double v, double f_s, double f_c, const double *x,",
        "                                    const double *p, double max_rate)",
        "{",
        "    (void)v; (void)f_s; (void)f_c; (void)x; (void)p; (void)max_rate;",
        *(_indented(smooth.c_state_rate)
          if smooth is not None and smooth.c_state_rate else ["    return 0.0;"]),
        "}",
        "",
        f"/* friction law {friction.name!r}: the sliding force in direction s (+-1) */"
        if friction is not None and stuck
        else "/* no outside friction law in the switch model's modes */",
        "static double pf_part_friction_sliding(double v, double s, double f_s, double f_c,",
        "                                       const double *x, const double *p)",
        "{",
        "    (void)v; (void)s; (void)f_s; (void)f_c; (void)x; (void)p;",
        *(_indented(friction.c_code or "") if friction is not None and stuck
          else ["    return 0.0;"]),
        "}",
    ]  # fmt: skip
    for i, e in enumerate(effects):
        lines += [
            "",
            f"/* effect {e.name!r}: {e.description} */",
            f"static void pf_part_effect_{i}(const double *x, const double *p, double *out)",
            "{",
            *_option_line(structure, e),
            "    (void)x; (void)p;",
            *_indented(e.c_code or ""),
            "}",
        ]
    lines += [
        "",
        "static void pf_part_effects(const double *x, const double *p, double *sum)",
        "{ /* kernel.part_effects: the outside effects' terms, added */",
        "    int i;",
        "    double out[6];",
        "    (void)x; (void)p; (void)out;",
        "    for (i = 0; i < 6; i++) sum[i] = 0.0;",
    ]
    for i, _ in enumerate(effects):
        lines += [
            "    for (i = 0; i < 6; i++) out[i] = 0.0;",
            f"    pf_part_effect_{i}(x, p, out);",
            "    for (i = 0; i < 6; i++) sum[i] += out[i];",
        ]
    lines += [
        "}",
        "",
    ]  # fmt: skip
    stateful = [(i, e) for i, e in enumerate(effects) if e.states]
    calls = []
    for i, e in stateful:
        names = [STATE_NAMES[slot] for slot in e.states]
        one = len(names) == 1  # one state: its rate returned; more: out[k], in order
        signature = (
            f"static double pf_part_effect_rate_{i}(const double *x, const double *p)"
            if one
            else f"static void pf_part_effect_rate_{i}("
            "const double *x, const double *p, double *out)"
        )
        lines += [
            f"/* the rate of effect {e.name!r}'s state{'' if one else 's'} ({', '.join(names)}) */",
            signature,
            "{",
            *_option_line(structure, e),
            "    (void)x; (void)p;",
            *_indented(e.c_state_rate or ""),
            "}",
            "",
        ]
        if one:
            calls.append(f"    dx[PF_X_{names[0]}] = pf_part_effect_rate_{i}(x, p);")
        else:
            calls += [
                "    {",
                f"        double r[{len(names)}];",
                f"        pf_part_effect_rate_{i}(x, p, r);",
                *(f"        dx[PF_X_{n}] = r[{k}];" for k, n in enumerate(names)),
                "    }",
            ]
    lines += [
        "static void pf_part_effect_rates(const double *x, const double *p, double *dx)",
        "{ /* kernel.part_effect_rates: the outside effects' states (X_E0 to X_E2) */",
        "    int i;",
        "    (void)x; (void)p;",
        "    for (i = PF_X_e_0; i < PF_NX; i++) dx[i] = 0.0;",
        *calls,
        "}",
        "",
        "#endif",
        "",
    ]  # fmt: skip
    return "\n".join(lines)


def _option_line(structure: ModelStructure, effect: Effect) -> list[str]:
    """The C line that gives an outside effect's code the structure's option
    value (``Effect.options``; the numba code gets it as its third argument)."""
    value = int(structure.effects[effect.name])
    return [f"    const int option = {value}; /* the structure's option */", "    (void)option;"]


def _indented(code: str) -> list[str]:
    return ["    " + line if line.strip() else "" for line in code.strip("\n").splitlines()]


def _exposed_parameters(structure: ModelStructure) -> list[str]:
    used = set(VALVE_PARAMETERS[structure.valve])
    used |= set(structure.parameter_names)  # the heat law's and the effects' parameters
    used |= set(FRICTION_PARAMETERS[structure.friction])
    used |= {n for n in PARAMETER_NAMES if SPECS[n].group in _ALWAYS_GROUPS}
    return [n for n in PARAMETER_NAMES if n in used]


def _start_values(structure: ModelStructure, vec: np.ndarray) -> dict[str, float]:
    p_mid = 0.5 * (vec[P["supply_pressure"]] + vec[P["exhaust_pressure"]])
    start = {
        "y": 0.5 * vec[P["stroke"]],
        "v": 0.0,
        "p_N": p_mid,
        "p_P": p_mid,
        "T_N": vec[P["wall_temperature"]],
        "T_P": vec[P["wall_temperature"]],
    }
    if structure.heat == "polytropic":
        del start["T_N"], start["T_P"]
    return start


def fmu_variables(
    structure: ModelStructure, vec: np.ndarray, integration_step: float
) -> list[FmuVariable]:
    """Variables of the model description, in order (index = position + 1)."""
    variables = [
        FmuVariable(name, VR_INPUT[name], "input", unit, 0.0, text)
        for name, unit, text in FMU_INPUTS
    ]
    for i, (name, unit, text) in enumerate(_OUTPUTS):
        if name in structure.state_names or name not in STATE_NAMES[8:]:
            variables.append(FmuVariable(name, VR_OUTPUT_BASE + i, "output", unit, None, text))
    for name, value in _start_values(structure, vec).items():
        index = STATE_NAMES.index(name)
        variables.append(
            FmuVariable(
                name=f"{name}_start",
                value_reference=VR_START_BASE + index,
                causality="parameter",
                unit=STATE_UNITS[index],
                start=float(value),
                description=f"initial value of {name}",
            )
        )
    variables.append(
        FmuVariable(
            name="integration_step",
            value_reference=VR_INTEGRATION_STEP,
            causality="parameter",
            unit="s",
            start=integration_step,
            description="largest Runge-Kutta step (Kutta's third-order method) inside a "
            "communication step",
            minimum=0.0,
        )
    )
    for name in _exposed_parameters(structure):
        spec = SPECS[name]
        variables.append(
            FmuVariable(
                name=name,
                value_reference=VR_PARAMETER_BASE + P[name],
                causality="parameter",
                unit=spec.unit,
                start=float(vec[P[name]]),
                description=spec.description,
                minimum=spec.lower if math.isfinite(spec.lower) else None,
                maximum=spec.upper if math.isfinite(spec.upper) else None,
            )
        )
    return variables


# ----------------------------------------------------------------- units
_BASE_UNITS = {
    "[mass]": "kg", "[length]": "m", "[time]": "s", "[current]": "A",
    "[temperature]": "K", "[substance]": "mol", "[luminosity]": "cd",
}  # fmt: skip


def _base_unit(unit: str) -> dict[str, str]:
    """FMI BaseUnit attributes (SI exponents, factor) of a pint unit string."""
    from pneumafit.campaign.units import ureg

    if unit == "rad":
        return {"rad": "1"}
    quantity = ureg.Quantity(1.0, unit.replace("^", "**")).to_base_units()
    attrs = {}
    for dim, exponent in quantity.dimensionality.items():
        attrs[_BASE_UNITS[dim]] = str(round(exponent))
    if quantity.magnitude != 1.0:
        attrs["factor"] = repr(float(quantity.magnitude))
    return attrs


def _number(value: float) -> str:
    return repr(float(value))


def model_description(
    structure: ModelStructure,
    variables: list[FmuVariable],
    model_identifier: str,
    guid: str,
    source: str,
) -> bytes:
    """The modelDescription.xml document (FMI 2.0, co-simulation)."""
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "2.0",
            "modelName": f"pneumafit {structure.name} actuator",
            "guid": guid,
            "description": (
                f"double-acting pneumatic cylinder, two servo-valves (valve law "
                f"{structure.valve}), heat law "
                f"{structure.heat} (air properties {structure.air_properties}), friction law "
                f"{structure.friction}"
                + (f", effects {', '.join(sorted(structure.effects))}" if structure.effects else "")
                + f"; parameters from {source}"
            ),
            "generationTool": "pneumafit",
            "generationDateAndTime": datetime.datetime.now(datetime.UTC).strftime(
                "%Y-%m-%dT%H:%M:%SZ"
            ),
            "variableNamingConvention": "flat",
            "numberOfEventIndicators": "0",
        },
    )
    cs = ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": model_identifier,
            "needsExecutionTool": "false",
            "canHandleVariableCommunicationStepSize": "true",
            "canInterpolateInputs": "true",
            "maxOutputDerivativeOrder": "0",
            "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canNotUseMemoryManagementFunctions": "true",
            "canGetAndSetFMUstate": "true",
            "canSerializeFMUstate": "true",
            "providesDirectionalDerivative": "false",
        },
    )
    files = ET.SubElement(cs, "SourceFiles")
    for name in C_SOURCES:
        ET.SubElement(files, "File", {"name": name})
    units = ET.SubElement(root, "UnitDefinitions")
    for unit in sorted({v.unit for v in variables if v.unit}):
        element = ET.SubElement(units, "Unit", {"name": unit})
        ET.SubElement(element, "BaseUnit", _base_unit(unit))
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", {"name": "logStatusError",
                                           "description": "errors of the FMU"})  # fmt: skip
    ET.SubElement(
        root, "DefaultExperiment", {"startTime": "0.0", "stopTime": "4.0", "stepSize": "0.001"}
    )
    model_vars = ET.SubElement(root, "ModelVariables")
    for v in variables:
        attrs = {
            "name": v.name,
            "valueReference": str(v.value_reference),
            "description": v.description,
            "causality": v.causality,
        }
        if v.causality == "parameter":
            attrs.update(variability="fixed", initial="exact")
        else:
            attrs["variability"] = "continuous"
        if v.causality == "output":
            attrs["initial"] = "calculated"
        element = ET.SubElement(model_vars, "ScalarVariable", attrs)
        real = {}
        if v.unit:
            real["unit"] = v.unit
        if v.minimum is not None:
            real["min"] = _number(v.minimum)
        if v.maximum is not None:
            real["max"] = _number(v.maximum)
        if v.start is not None:
            real["start"] = _number(v.start)
        ET.SubElement(element, "Real", real)
    structure_el = ET.SubElement(root, "ModelStructure")
    outputs = ET.SubElement(structure_el, "Outputs")
    initial = ET.SubElement(structure_el, "InitialUnknowns")
    for index, v in enumerate(variables, start=1):
        if v.causality == "output":
            ET.SubElement(outputs, "Unknown", {"index": str(index)})
            ET.SubElement(initial, "Unknown", {"index": str(index)})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


# ---------------------------------------------------------- C generation
def _c_double(value: float) -> str:
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    return f"{float(value):.17g}"


def config_header(structure: ModelStructure) -> str:
    """``pneumafit_config.h``: indices, the structure's laws and constants."""
    from pneumafit.physics import air, friction, valve, valve_map
    from pneumafit.simulation import simulator

    lines = [
        "/* Generated by pneumafit.outputs.fmu from pneumafit.models.layout: do not edit. */",
        "#ifndef PNEUMAFIT_CONFIG_H",
        "#define PNEUMAFIT_CONFIG_H",
        "",
        "#include <math.h>",
        "#ifndef M_PI",
        "#define M_PI 3.14159265358979323846",
        "#endif",
        "",
        f"#define PF_NP {len(PARAMETER_NAMES)}",
        # the outside effects' states past layout.NX: as the simulator's copy
        f"#define PF_NX {state_size(s for e in outside_effects(structure) for s in e.states)}",
        "",
        "/* structure */",
        f"#define PF_HEAT {HEAT_LAWS[structure.heat]} /* {structure.heat} */",
        f"#define PF_LUGRE {1 if structure.friction == 'lugre' else 0} /* {structure.friction} */",
        f"#define PF_SUTHERLAND {1 if structure.air_properties == 'sutherland' else 0}",
        f"#define PF_VALVE_MAP {1 if structure.valve == 'map' else 0} /* {structure.valve} */",
        *(
            f"#define PF_EFFECT_{name.upper()} {int(structure.effects.get(name, 0))}"
            for name in EFFECT_SLOTS
        ),
        "",
        "/* state indices (layout.STATE_NAMES) */",
    ]
    lines += [f"#define PF_X_{name} {i}" for i, name in enumerate(STATE_NAMES)]
    lines += ["", "/* parameter indices (layout.PARAMETER_NAMES) */"]
    lines += [f"#define PF_P_{name} {i}" for i, name in enumerate(PARAMETER_NAMES)]
    constants = {
        "R_AIR": air.R_AIR, "GAMMA": air.GAMMA, "G0": air.G0, "RHO0": air.RHO0,
        "T_REF": air.T_REF, "MU_REF": air._MU_REF, "MU_T": air._MU_T, "MU_S": air._MU_S,
        "K_REF": air._K_REF, "K_T": air._K_T, "K_S": air._K_S,
        "OPENING_SMOOTHING": valve.OPENING_SMOOTHING,
        "LUGRE_RATE_LIMIT": friction.LUGRE_RATE_LIMIT,
        "LUGRE_MIN_LEVEL": friction.LUGRE_MIN_LEVEL,
        "COMMAND_RESOLUTION": simulator.COMMAND_RESOLUTION,
        "MAP_C_LOWER": MAP_C_LOWER, "MAP_C_UPPER": MAP_C_UPPER,
        "MAP_B_LOWER": MAP_B_LOWER, "MAP_B_UPPER": MAP_B_UPPER,
        "MAP_B1": valve_map.MAP_B_FRACTIONS[1], "MAP_FLOOR": valve_map._FLOOR,
    }  # fmt: skip
    lines += ["", "/* constants (pneumafit.physics, pneumafit.simulation.simulator) */"]
    lines += [f"#define PF_{k} {_c_double(v)}" for k, v in constants.items()]
    knots = ", ".join(_c_double(f) for f in valve_map.MAP_KNOTS)
    lines += [
        "",
        "/* valve-map knots, fractions of valve_u_sat (physics.valve_map.MAP_KNOTS) */",
        f"#define PF_N_MAP_KNOTS {len(valve_map.MAP_KNOTS)}",
        f"#define PF_MAP_CENTRE_KNOT {valve_map.CENTRE_KNOT}",
        f"#define PF_MAP_KNOTS_INIT {{{knots}}}",
    ]
    lines += ["", "#endif", ""]
    return "\n".join(lines)


def values_header(
    structure: ModelStructure,
    vec: np.ndarray,
    variables: list[FmuVariable],
    guid: str,
    integration_step: float,
) -> str:
    """``pneumafit_values.h``: fitted values, value references, start values, GUID."""
    starts = {v.name[: -len("_start")]: v.start for v in variables if v.name.endswith("_start")}
    lines = [
        "/* Generated by pneumafit.outputs.fmu: the fitted parameter values and the",
        " * value references of modelDescription.xml. Do not edit. */",
        "#ifndef PNEUMAFIT_VALUES_H",
        "#define PNEUMAFIT_VALUES_H",
        "",
        f'#define PF_GUID "{guid}"',
        f"#define PF_INTEGRATION_STEP {_c_double(integration_step)}",
        f"#define PF_VR_PARAMETER_BASE {VR_PARAMETER_BASE}u",
        f"#define PF_VR_START_BASE {VR_START_BASE}u",
        f"#define PF_VR_INTEGRATION_STEP {VR_INTEGRATION_STEP}u",
    ]
    lines += [f"#define PF_VR_{name} {vr}u" for name, vr in VR_INPUT.items()]
    for i, (name, _, _) in enumerate(_OUTPUTS):
        # every output has a define; the ones the description leaves out are never asked for
        lines.append(f"#define PF_VR_{name} {VR_OUTPUT_BASE + i}u")
    lines += ["", "/* parameter values (SI), layout.PARAMETER_NAMES order */"]
    lines.append("static const double PF_PARAMETER_VALUES[PF_NP] = {")
    for name, value in zip(PARAMETER_NAMES, vec, strict=True):
        lines.append(f"    {_c_double(value)}, /* {name} [{SPECS[name].unit}] */")
    lines += ["};", ""]
    lines.append("static void pf_start_defaults(double *x0)\n{")
    for name, value in starts.items():
        lines.append(f"    x0[PF_X_{name}] = {_c_double(value)};")
    lines += ["}", ""]
    indices = " || ".join(f"i == PF_X_{name}" for name in starts)
    lines.append(f"static int pf_is_start_variable(int i) {{ return {indices}; }}")
    lines += ["", "#endif", ""]
    return "\n".join(lines)


# -------------------------------------------------------------- compiler
def find_compiler() -> list[str] | None:
    """The C compiler command: ``$CC`` if set, else the first of cc, gcc, clang."""
    env = os.environ.get("CC", "").strip()
    if env:
        command = shlex.split(env)
        if shutil.which(command[0]):
            return command
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return [path]
    return None


def _platform() -> tuple[str, str]:
    if sys.platform.startswith("linux"):
        return ("linux64" if sys.maxsize > 2**32 else "linux32"), ".so"
    if sys.platform == "darwin":
        return "darwin64", ".dylib"
    raise FmuBuildError(
        f"cannot build the FMU: platform {sys.platform!r} is not supported by the builder "
        "(linux and darwin are); the sources are portable C99"
    )


def _compile(compiler: list[str], sources: Path, library: Path) -> None:
    command = [
        *compiler, "-shared", "-fPIC", "-O2", "-fvisibility=hidden",
        "-I", str(sources), "-o", str(library),
        *(str(sources / name) for name in C_SOURCES), "-lm",
    ]  # fmt: skip
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise FmuBuildError(f"cannot build the FMU: the C compiler failed to run: {exc}") from None
    if run.returncode != 0:
        raise FmuBuildError(
            f"cannot build the FMU: the C compiler failed ({shlex.join(command)}):\n"
            + (run.stderr or run.stdout).strip()[-4000:]
        )


# ----------------------------------------------------------------- build
def _model_identifier(structure: ModelStructure) -> str:
    safe = "".join(c if c.isalnum() else "_" for c in structure.heat)
    return f"pneumafit_{safe}_{structure.friction}"


def write_fmu(
    structure: ModelStructure,
    values: Mapping[str, float] | np.ndarray,
    out: str | os.PathLike[str],
    *,
    integration_step: float | None = None,
    source: str = "parameters",
) -> Path:
    """Write the co-simulation FMU of a model structure and parameter set.

    Parameters
    ----------
    structure : ModelStructure
        Supported: ISO 6358 valves or the measured valve map, switch or LuGre
        friction, any of the three heat laws, the optional effects
        (:func:`check_structure`).
    values : mapping of str to float, or ndarray (NP,)
        SI parameter values by name (defaults for the rest), or a full vector.
    out : path
        The .fmu file to write.
    integration_step : float, optional
        Largest Runge-Kutta step inside a communication step (s); default
        :func:`pneumafit.simulation.choose_step` for the parameters (the
        simulator's 1 ms unless stability needs less). A parameter of the FMU.
    source : str
        Where the parameters came from (the model description says it).

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    PneumafitInputError
        Unsupported structure or inadmissible parameters.
    FmuBuildError
        No C compiler, or the compilation failed.
    """
    from pneumafit.models import kernel
    from pneumafit.models.parameters import parameter_vector
    from pneumafit.simulation import choose_step, spool_mode

    check_structure(structure, source)
    try:
        vec = (
            np.asarray(values, dtype=float).copy()
            if isinstance(values, np.ndarray)
            else parameter_vector(values)
        )
    except ValueError as exc:
        raise PneumafitInputError(f"{source}: {exc}") from None
    if vec.shape != (len(PARAMETER_NAMES),) or not kernel.admissible(vec, structure.config()):
        raise PneumafitInputError(
            f"{source}: the parameters are not physically admissible (e.g. rod >= bore, "
            "Coulomb friction above static friction, overlap >= u_sat, a first-order valve "
            "with valve_time_constant 0); cannot export an FMU"
        )
    if integration_step is None:
        integration_step = choose_step(
            vec, valve=structure.valve, friction=structure.friction,
            spool=spool_mode(structure, vec),
        )  # fmt: skip
    if not integration_step > 0:
        raise PneumafitInputError(
            f"integration step: expected a positive step in s, found {integration_step}"
        )
    compiler = find_compiler()
    if compiler is None:
        raise FmuBuildError(
            "cannot build the FMU: no C compiler found (looked for $CC, cc, gcc and clang on "
            "PATH; install one, e.g. apt-get install gcc, or set CC); the other exports are "
            "not affected"
        )
    platform, suffix = _platform()
    identifier = _model_identifier(structure)
    variables = fmu_variables(structure, vec, float(integration_step))
    digest = hashlib.sha256()
    digest.update(f"{structure!r}".encode())
    digest.update(np.ascontiguousarray(vec).tobytes())
    digest.update(repr(float(integration_step)).encode())
    guid = "{" + str(uuid.UUID(bytes=digest.digest()[:16])) + "}"
    out_path = Path(out)
    with tempfile.TemporaryDirectory(prefix="pneumafit-fmu-") as tmp:
        root = Path(tmp)
        sources = root / "sources"
        sources.mkdir()
        package = resources.files("pneumafit.outputs.fmu") / "c"
        for name in (*C_SOURCES, *C_HEADERS):
            (sources / name).write_bytes((package / name).read_bytes())
        (sources / "pneumafit_config.h").write_text(config_header(structure), encoding="utf-8")
        (sources / "pneumafit_parts.h").write_text(parts_header(structure), encoding="utf-8")
        (sources / "pneumafit_values.h").write_text(
            values_header(structure, vec, variables, guid, float(integration_step)),
            encoding="utf-8",
        )
        binaries = root / "binaries" / platform
        binaries.mkdir(parents=True)
        try:
            _compile(compiler, sources, binaries / f"{identifier}{suffix}")
        except FmuBuildError as exc:
            ported = [f"heat law {h.name!r}" for h in [outside_heat_law(structure)] if h]
            ported += [f"valve law {v.name!r}" for v in [outside_valve_law(structure)] if v]
            ported += [f"friction law {f.name!r}" for f in [outside_friction_law(structure)] if f]
            ported += [f"effect {e.name!r}" for e in outside_effects(structure)]
            if not ported:
                raise
            raise FmuBuildError(
                f"{exc}\n(pneumafit_parts.h holds the C code of the parts from outside the "
                f"package, as given: {', '.join(ported)}; check their c_code)"
            ) from None
        (root / "modelDescription.xml").write_bytes(
            model_description(structure, variables, identifier, guid, source)
        )
        out_path.parent.mkdir(parents=True, exist_ok=True)
        partial = out_path.with_name(out_path.name + ".partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(root).as_posix())
        partial.replace(out_path)
    return out_path


def build_fmu(fit_path: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Export a fitted plant (fit.json or parameter file) as an FMI 2.0 co-simulation FMU.

    The structure (heat, valve and friction laws, effects) and the parameter
    values are read as ``pneumafit closed-loop`` reads a plant
    (:func:`pneumafit.analysis.closed_loop.read_plant_file`).

    Parameters
    ----------
    fit_path : path
        ``fit.json`` or a parameter file.
    out : path
        The .fmu file to write.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    PneumafitInputError
        Unreadable file, bad entries, or a structure the FMU does not support
        (:func:`check_structure`).
    FmuBuildError
        "cannot build the FMU: no C compiler found (...)", or the compiler failed.
    """
    from pneumafit.analysis.closed_loop import read_plant_file

    # the fit's own structure, Sutherland air of a convection fit included
    structure, values = read_plant_file(fit_path)
    return write_fmu(structure, values, out, source=str(fit_path))
