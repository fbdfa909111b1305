"""Optional effects of the virtual rig's truth, switched on by name and value.

An effect is named either by its slot in
:data:`pneumafit.models.EFFECT_SLOTS` (the value then sets its *principal*
parameter) or by one of its parameters directly (which switches the effect
on). ``NAME`` alone takes the default magnitude of :data:`EFFECT_DEFAULTS`,
chosen so that the effect is clearly visible in the pressures of the demo
protocol (docs/virtual-rig.md lists what each one does to a charge test and
a step test).

>>> resolve_effects(parse_effect_options(["chamber_leakage=5e-11"]))
ResolvedEffects(structure={'chamber_leakage': 1}, parameters={'chamber_leak_conductance': 5e-11})
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.models import EFFECT_SLOTS
from pneumafit.models.layout import SPECS
from pneumafit.models.parts import EFFECTS, RegistryView

__all__ = [
    "EFFECT_DEFAULTS",
    "PRINCIPAL_PARAMETERS",
    "ResolvedEffects",
    "parse_effect_options",
    "resolve_effects",
]


#: Parameter set by ``--effect NAME=VALUE`` when NAME is an effect slot
#: (:attr:`pneumafit.models.parts.Effect.principal`).
PRINCIPAL_PARAMETERS: Mapping[str, str] = RegistryView(EFFECTS, lambda e: e.principal)


class _Live(Mapping[str, Any]):
    """A read-only table recomputed from the effects registry at each use."""

    def __init__(self, build: Callable[[], dict[str, Any]]) -> None:
        self._build = build

    def __getitem__(self, key: str) -> Any:
        return self._build()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._build())

    def __len__(self) -> int:
        return len(self._build())

    def __repr__(self) -> str:
        return repr(self._build())


#: Default magnitude of each effect's principal parameter (SI), used when an
#: effect is named without a value (:attr:`pneumafit.models.parts.Effect.rig_default`;
#: chosen so that the effect is clearly visible in the demo protocol, see
#: :mod:`pneumafit.models.parts.effects`). The seal and barrel effects take
#: their shared typical sizes (:mod:`pneumafit.physics.seal_effects`).
EFFECT_DEFAULTS: Mapping[str, float] = _Live(
    lambda: {e.principal: e.rig_default for e in EFFECTS.values()}
)

#: Second-order spool parameters: naming one selects valve_dynamics order 2.
_SECOND_ORDER = ("valve_natural_frequency", "valve_damping_ratio")


def _effect_of_parameter() -> dict[str, str]:
    owner: dict[str, str] = {}
    for effect, (_, params, _) in EFFECT_SLOTS.items():
        for name in params:
            owner[name] = effect
    return owner


_OWNER: Mapping[str, str] = _Live(_effect_of_parameter)


@dataclass(frozen=True)
class ResolvedEffects:
    """Effects ready for the truth model.

    Attributes
    ----------
    structure : dict of str to int
        ``ModelStructure.effects``: effect name -> 1 (``valve_dynamics``: the
        spool order, 1 or 2).
    parameters : dict of str to float
        Effect parameters (SI) to set in the true parameter set.
    """

    structure: dict[str, int] = field(default_factory=dict)
    parameters: dict[str, float] = field(default_factory=dict)


def _names_help() -> str:
    return f"an effect ({', '.join(EFFECT_SLOTS)}) or one of its parameters ({', '.join(_OWNER)})"


def parse_effect_options(options: Iterable[str]) -> dict[str, float | None]:
    """Parse ``--effect`` options, ``NAME=VALUE`` or ``NAME``.

    Parameters
    ----------
    options : iterable of str
        E.g. ``["chamber_leakage=5e-11", "valve_time_constant=0.02",
        "wall_thermal_mass"]``. VALUE is a plain number in the SI unit of the
        parameter it sets.

    Returns
    -------
    dict of str to float or None
        Name -> value, None where no value was given (default magnitude).

    Raises
    ------
    PneumafitInputError
        Unknown name, a value that is not a finite number or lies outside
        the parameter's bounds, or a name given twice; the message names the
        option.
    """
    parsed: dict[str, float | None] = {}
    for option in options:
        text = str(option).strip()
        name, sep, raw = text.partition("=")
        name = name.strip()
        where = f"--effect {text!r}"
        if name not in EFFECT_SLOTS and name not in _OWNER:
            raise PneumafitInputError(
                f"{where}: expected NAME=VALUE with NAME {_names_help()}, found {name!r}"
            )
        value: float | None = None
        if sep:
            try:
                value = float(raw)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise PneumafitInputError(
                    f"{where}: expected a finite number (SI units) after '=', found {raw.strip()!r}"
                )
            param = PRINCIPAL_PARAMETERS.get(name, name)
            _check_value(param, value, where)
        if name in parsed:
            raise PneumafitInputError(f"{where}: expected each name once, found {name!r} twice")
        parsed[name] = value
    return parsed


def _check_value(name: str, value: float, where: str) -> float:
    spec = SPECS[name]
    # a principal parameter of 0 would switch the effect on with no effect,
    # and a zero valve time constant divides by zero: ask for > 0
    positive = name in EFFECT_DEFAULTS or name in _SECOND_ORDER
    low_ok = value > spec.lower if positive else value >= spec.lower
    if not (low_ok and value <= spec.upper):
        bound = ">" if positive else ">="
        raise PneumafitInputError(
            f"{where}: expected {name} {bound} {spec.lower:g} and <= {spec.upper:g} "
            f"{spec.unit}, found {value:g}"
        )
    return float(value)


def resolve_effects(effects: Mapping[str, float | None]) -> ResolvedEffects:
    """Turn effect names and values into a structure and parameter values.

    Parameters
    ----------
    effects : mapping of str to float or None
        Effect slot or effect parameter name -> SI value (None: default
        magnitude of :data:`EFFECT_DEFAULTS`; for a non-principal parameter
        None keeps its model default). Naming ``valve_natural_frequency`` or
        ``valve_damping_ratio`` selects a second-order spool.

    Returns
    -------
    ResolvedEffects

    Raises
    ------
    PneumafitInputError
        Unknown name, value out of the parameter's bounds, or first- and
        second-order valve parameters together.
    """
    structure: dict[str, int] = {}
    parameters: dict[str, float] = {}
    for name, value in effects.items():
        where = f"effect {name!r}" + ("" if value is None else f" = {value:g}")
        if name in EFFECT_SLOTS:
            effect, param = name, PRINCIPAL_PARAMETERS[name]
        elif name in _OWNER:
            effect, param = _OWNER[name], name
        else:
            raise PneumafitInputError(f"{where}: expected {_names_help()}, found {name!r}")
        if value is None:
            value = EFFECT_DEFAULTS.get(param, SPECS[param].default)
        parameters[param] = _check_value(param, float(value), where)
        order = 2 if param in _SECOND_ORDER else 1
        structure[effect] = max(structure.get(effect, 0), order)
    if structure.get("valve_dynamics") == 2 and "valve_time_constant" in parameters:
        raise PneumafitInputError(
            "effect valve_dynamics: expected either valve_time_constant (first-order spool) "
            "or valve_natural_frequency / valve_damping_ratio (second order), found both"
        )
    # an effect named only by a secondary parameter still needs its principal one
    for effect, order in structure.items():
        principal = PRINCIPAL_PARAMETERS[effect]
        if effect == "valve_dynamics" and order == 2:
            continue
        parameters.setdefault(principal, EFFECT_DEFAULTS[principal])
    return ResolvedEffects(structure=structure, parameters=parameters)
