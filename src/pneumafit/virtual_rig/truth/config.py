"""Truth configurations: which parts the truth is made of, from a dict, TOML or JSON.

A configuration has one table per physical part, each naming its model by a
selector key and giving that model's parameters (SI units, see each part's
docstring)::

    name = "my-truth"
    description = "..."

    [valve]                      # both 3-way valves are of this make
    m = 0.5                      # subsonic index (-)
    x_laminar = 0.999            # onset of the laminar region (-)
    [valve.supply]               # path opened by u > 0
    family = "power"             # iso_linear | power | table
    C_max = 9.4e-9               # m^3/s/Pa
    u0 = 0.42                    # V
    u_sat = 9.1                  # V
    n = 1.55                     # -
    b = 0.34                     # -
    [valve.exhaust]              # path opened by u < 0
    family = "iso_linear"
    C_max = 1.2e-8
    overlap = 0.3
    [valve.leak]
    shape = "bump"               # bump | constant | none | sigmoid
    C0 = 2.6e-11
    width = 0.31

    [friction]
    model = "lugre"              # lugre | dahl
    sigma0 = 2.7e5
    ...
    [heat]
    model = "nusselt"
    xi = 0.36
    beta = 0.28
    area = "full"                # full | barrel_only
    [end_stops]                  # optional
    [probe]                      # optional: the temperature probes' own lag/offset
    model = "lagged"
    time_constant = 0.5
    [external_leak]              # optional: air escaping from the chambers
    model = "orifice"            # orifice | none
    C_P = 1.4e-11                # m^3/s/Pa
    C_N = 2.6e-11
    [barrel]                     # optional: the real bore where it is not the declared one
    bore = 0.0328                # m (campaign.toml keeps the nominal bore)
    [parameters]                 # optional: rig geometry/conditions overriding the rig's

:data:`PRESETS` holds named configurations; :func:`get_truth` resolves a
preset name or a file; :func:`reference_quantities` gives the figures a
recovery test compares fitted parameters with.
"""

from __future__ import annotations

import copy
import json
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

from pneumafit.campaign import PneumafitInputError
from pneumafit.virtual_rig.truth.friction import FRICTION_MODELS, EndStops
from pneumafit.virtual_rig.truth.heat import HEAT_MODELS, exchange_area
from pneumafit.virtual_rig.truth.leak import EXTERNAL_LEAKS
from pneumafit.virtual_rig.truth.probe import PROBE_MODELS
from pneumafit.virtual_rig.truth.valve import CONDUCTANCE_FAMILIES, LEAK_SHAPES, ServoValve

__all__ = [
    "PRESETS",
    "REFERENCE_STATE",
    "TRUTH_FORMAT",
    "TruthConfig",
    "get_truth",
    "reference_quantities",
]

#: ``format`` of a campaign's truth.json (written by the virtual rig);
#: :meth:`TruthConfig.from_file` reads its ``truth_model.config``.
TRUTH_FORMAT = "pneumafit-truth"

_SECTIONS = ("name", "description", "valve", "friction", "heat", "end_stops", "probe", "barrel",
             "external_leak", "parameters")  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class Barrel:
    """The cylinder's real bore, where it is not the declared (nominal) one.

    A barrel honed to a slightly larger diameter, or a catalogue size for a
    slightly smaller bore: campaign.toml keeps the rig's nominal ``bore``
    and the truth simulates the real one everywhere the bore enters (piston
    areas in the force balance and the chamber volumes, exchange areas); the
    rod is the declared one. What a model with the nominal bore sees is an
    effective piston area (bore / nominal)^2 times the nominal one.

    Parameters
    ----------
    bore : float or None
        Real bore diameter (m), > 0; None: the declared bore.
    """

    bore: float | None = None

    def __post_init__(self) -> None:
        if self.bore is not None and not (math.isfinite(self.bore) and self.bore > 0.0):
            raise PneumafitInputError(
                f"barrel: bore: expected a diameter > 0 m, found {self.bore!r}"
            )


def _init_fields(cls: type) -> dict[str, Any]:
    return {f.name: f for f in fields(cls) if f.init}


def _convert(value: Any) -> Any:
    if isinstance(value, list):
        return tuple(_convert(v) for v in value)
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def _build(registry: Mapping[str, type], selector: str, table: Any, where: str) -> Any:
    """Build one part from its table: ``selector`` names the model, the rest are fields."""
    if not isinstance(table, Mapping):
        raise PneumafitInputError(f"{where}: expected a table, found {table!r}")
    if selector not in table:
        raise PneumafitInputError(
            f"{where}.{selector}: missing; expected one of {', '.join(registry)}"
        )
    choice = table[selector]
    if choice not in registry:
        raise PneumafitInputError(
            f"{where}.{selector}: expected one of {', '.join(registry)}, found {choice!r}"
        )
    cls = registry[choice]
    return _instantiate(cls, {k: v for k, v in table.items() if k != selector}, where)


def _instantiate(cls: type, table: Mapping[str, Any], where: str) -> Any:
    known = _init_fields(cls)
    for key in table:
        if key not in known:
            raise PneumafitInputError(
                f"{where}.{key}: unknown key; expected one of {', '.join(known)}"
            )
    for key, f in known.items():
        if key not in table and f.default is MISSING and f.default_factory is MISSING:
            raise PneumafitInputError(f"{where}.{key}: missing (required)")
    kwargs = {k: _convert(v) for k, v in table.items()}
    for key, value in kwargs.items():
        ok = isinstance(value, (float, str, tuple)) or value is None
        if isinstance(value, float) and not math.isfinite(value):
            ok = False
        if not ok:
            raise PneumafitInputError(f"{where}.{key}: expected a finite number, found {value!r}")
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:
        raise PneumafitInputError(f"{where}: {exc}") from None


def _part_dict(part: Any, selector: str | None) -> dict[str, Any]:
    out: dict[str, Any] = {} if selector is None else {selector: part.name}
    for key in _init_fields(type(part)):
        value = getattr(part, key)
        if value is None:
            continue
        out[key] = list(value) if isinstance(value, tuple) else value
    return out


@dataclass(frozen=True)
class TruthConfig:
    """The parts of an independently simulated truth (see the module docstring).

    Parameters
    ----------
    name : str
        Name written to truth.json.
    valve : ServoValve
        Both servo-valves (conductance families per path, leak, m, x_laminar).
    friction : LuGreFriction or DahlFriction
    heat : NusseltConvection
    end_stops : EndStops
    probe : LaggedProbe or None
        Temperature probes; None keeps the rig's :class:`SensorModel`.
    external_leak : OrificeLeak or None
        Air escaping from the chambers to the atmosphere
        (:mod:`pneumafit.virtual_rig.truth.leak`); None: tight chambers.
    barrel : Barrel or None
        The real bore where it differs from the declared one; None: the
        declared bore.
    parameters : dict of str to float
        Rig geometry/conditions (PARAMETER_SPECS names, SI) overriding the
        virtual rig's true parameters.
    description : str
        One line for truth.json and the README.
    """

    name: str
    valve: ServoValve
    friction: Any
    heat: Any
    end_stops: EndStops = field(default_factory=EndStops)
    probe: Any = None
    parameters: Mapping[str, float] = field(default_factory=dict)
    description: str = ""
    external_leak: Any = None
    barrel: Barrel | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "truth") -> TruthConfig:
        """Build a configuration from nested mappings (TOML/JSON layout).

        Raises
        ------
        PneumafitInputError
            A missing or unknown key, an unknown model name or a bad value;
            the message names ``source`` and the key.
        """
        if not isinstance(data, Mapping):
            raise PneumafitInputError(f"{source}: expected a table, found {type(data).__name__}")
        for key in data:
            if key not in _SECTIONS:
                raise PneumafitInputError(
                    f"{source}: {key}: unknown key; expected one of {', '.join(_SECTIONS)}"
                )
        for key in ("valve", "friction", "heat"):
            if key not in data:
                raise PneumafitInputError(f"{source}: {key}: missing (required table)")
        name = data.get("name", Path(source).stem if source != "truth" else "custom")
        if not isinstance(name, str) or not name:
            raise PneumafitInputError(f"{source}: name: expected a text, found {name!r}")
        v = data["valve"]
        if not isinstance(v, Mapping):
            raise PneumafitInputError(f"{source}: valve: expected a table, found {v!r}")
        for key in ("supply", "exhaust"):
            if key not in v:
                raise PneumafitInputError(f"{source}: valve.{key}: missing (required table)")
        for key in v:
            if key not in ("supply", "exhaust", "leak", "m", "x_laminar"):
                raise PneumafitInputError(
                    f"{source}: valve.{key}: unknown key; expected supply, exhaust, leak, m, "
                    "x_laminar"
                )
        supply = _build(CONDUCTANCE_FAMILIES, "family", v["supply"], f"{source}: valve.supply")
        exhaust = _build(CONDUCTANCE_FAMILIES, "family", v["exhaust"], f"{source}: valve.exhaust")
        leak = _build(LEAK_SHAPES, "shape", v.get("leak", {"shape": "none"}),
                      f"{source}: valve.leak")  # fmt: skip
        rest = {k: v[k] for k in ("m", "x_laminar") if k in v}
        for key, value in rest.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise PneumafitInputError(
                    f"{source}: valve.{key}: expected a number, found {value!r}"
                )
        try:
            valve = ServoValve(supply=supply, exhaust=exhaust, leak=leak,
                               **{k: float(x) for k, x in rest.items()})  # fmt: skip
        except ValueError as exc:
            raise PneumafitInputError(f"{source}: {exc}") from None
        friction = _build(FRICTION_MODELS, "model", data["friction"], f"{source}: friction")
        heat = _build(HEAT_MODELS, "model", data["heat"], f"{source}: heat")
        stops = _instantiate(EndStops, data.get("end_stops", {}), f"{source}: end_stops")
        probe = None
        if data.get("probe") is not None:
            probe = _build(PROBE_MODELS, "model", data["probe"], f"{source}: probe")
        external_leak = None
        if data.get("external_leak") is not None:
            external_leak = _build(EXTERNAL_LEAKS, "model", data["external_leak"],
                                   f"{source}: external_leak")  # fmt: skip
        barrel = None
        if data.get("barrel") is not None:
            barrel = _instantiate(Barrel, data["barrel"], f"{source}: barrel")
        params = data.get("parameters", {})
        if not isinstance(params, Mapping):
            raise PneumafitInputError(f"{source}: parameters: expected a table, found {params!r}")
        clean: dict[str, float] = {}
        for key, value in params.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise PneumafitInputError(
                    f"{source}: parameters.{key}: expected a number (SI), found {value!r}"
                )
            clean[str(key)] = float(value)
        description = data.get("description", "")
        if not isinstance(description, str):
            raise PneumafitInputError(f"{source}: description: expected a text")
        return cls(name=name, valve=valve, friction=friction, heat=heat, end_stops=stops,
                   probe=probe, parameters=clean, description=description,
                   external_leak=external_leak, barrel=barrel)  # fmt: skip

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> TruthConfig:
        """Read a configuration from a ``.toml`` or ``.json`` file, or from a
        campaign's ``truth.json`` (its ``truth_model.config``: the truth that
        recorded the campaign).

        Raises
        ------
        PneumafitInputError
            Unreadable file, unknown suffix, a syntax error or a bad key.
        """
        p = Path(path)
        where = os.fspath(p)
        if p.suffix.lower() not in (".toml", ".json"):
            raise PneumafitInputError(
                f"truth file {where!r}: expected a .toml or .json file, found {p.suffix!r}"
            )
        try:
            text = p.read_text(encoding="utf-8")
        except OSError as exc:
            raise PneumafitInputError(f"truth file {where!r}: cannot read it ({exc})") from None
        try:
            data = tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
        except (tomllib.TOMLDecodeError, ValueError) as exc:
            raise PneumafitInputError(
                f"truth file {where!r}: not valid {p.suffix[1:]}: {exc}"
            ) from None
        if isinstance(data, Mapping) and data.get("format") == TRUTH_FORMAT:
            model = data.get("truth_model")
            if not isinstance(model, Mapping) or not isinstance(model.get("config"), Mapping):
                raise PneumafitInputError(
                    f"truth file {where!r}: truth_model.config: expected the independent truth "
                    "that recorded the campaign, found none (the campaign was recorded with the "
                    "fitted models' own laws: record it without --truth)"
                )
            return cls.from_dict(model["config"], source=f"{where}: truth_model.config")
        return cls.from_dict(data, source=where)

    def as_dict(self) -> dict[str, Any]:
        """The configuration as nested plain mappings (for truth.json; from_dict reads it back)."""
        valve = {
            "m": self.valve.m,
            "x_laminar": self.valve.x_laminar,
            "supply": _part_dict(self.valve.supply, "family"),
            "exhaust": _part_dict(self.valve.exhaust, "family"),
            "leak": _part_dict(self.valve.leak, "shape"),
        }
        out: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "valve": valve,
            "friction": _part_dict(self.friction, "model"),
            "heat": _part_dict(self.heat, "model"),
            "end_stops": _part_dict(self.end_stops, None),
        }
        if self.probe is not None:
            out["probe"] = _part_dict(self.probe, "model")
        if self.external_leak is not None:
            out["external_leak"] = _part_dict(self.external_leak, "model")
        if self.barrel is not None:
            out["barrel"] = _part_dict(self.barrel, None)
        if self.parameters:
            out["parameters"] = dict(self.parameters)
        return out


# ----------------------------------------------------------------------------
# Presets
# ----------------------------------------------------------------------------
_LUGRE = {
    "model": "lugre", "sigma0": 2.7e5, "sigma1": 1.3e3, "sigma2": 57.0, "F_c": 28.5,
    "F_s": 46.0, "v_s": 0.017,
}  # fmt: skip

_PRESET_DATA: dict[str, dict[str, Any]] = {
    "power-valve": {
        "description": "power-law valve paths (supply and exhaust differ), Gaussian centre "
        "leak, LuGre friction, full-area Nusselt heat",
        "valve": {
            "m": 0.5, "x_laminar": 0.999,
            "supply": {"family": "power", "C_max": 9.4e-9, "u0": 0.42, "u_sat": 9.1,
                       "n": 1.55, "b": 0.34},
            "exhaust": {"family": "power", "C_max": 1.17e-8, "u0": 0.37, "u_sat": 9.6,
                        "n": 1.7, "b": 0.27},
            "leak": {"shape": "bump", "C0": 2.6e-11, "width": 0.31},
        },
        "friction": dict(_LUGRE),
        "heat": {"model": "nusselt", "xi": 0.36, "beta": 0.28, "area": "full"},
    },
    "table-valve-asym": {
        "description": "catalogue-table supply path with opening-dependent b, rounded linear "
        "exhaust path, constant leak, LuGre friction, barrel-only heat area",
        "valve": {
            "m": 0.5, "x_laminar": 0.999,
            "supply": {
                "family": "table",
                "commands": [0.25, 0.5, 1.0, 2.0, 3.5, 5.0, 7.0, 9.5],
                "conductances": [0.0, 4.1e-10, 1.3e-9, 3.2e-9, 5.9e-9, 7.8e-9, 9.3e-9, 9.8e-9],
                "b": 0.41, "b_small": 0.48,
            },
            "exhaust": {"family": "iso_linear", "C_max": 1.26e-8, "overlap": 0.22,
                        "u_sat": 8.4, "corner": 0.04, "b": 0.23, "b_small": 0.31},
            "leak": {"shape": "constant", "C0": 1.4e-11},
        },
        "friction": {**_LUGRE, "F_c": 33.5, "F_s": 52.0, "v_s": 0.024, "sigma2": 48.0},
        "heat": {"model": "nusselt", "xi": 0.43, "beta": 0.26, "area": "barrel_only"},
    },
    "lugre-pressure": {
        "description": "linear valve paths like the fit's, LuGre friction growing with the "
        "chamber pressures (x(1 + k_p Delta)), full-area heat",
        "valve": {
            "m": 0.5, "x_laminar": 0.999,
            "supply": {"family": "iso_linear", "C_max": 1.02e-8, "overlap": 0.33,
                       "u_sat": 10.0, "corner": 0.03, "b": 0.31},
            "exhaust": {"family": "iso_linear", "C_max": 1.13e-8, "overlap": 0.33,
                        "u_sat": 10.0, "corner": 0.03, "b": 0.29},
            "leak": {"shape": "bump", "C0": 2.2e-11, "width": 0.35},
        },
        "friction": {**_LUGRE, "F_c": 24.0, "F_s": 39.5, "v_s": 0.021, "seal":
                     "multiplicative", "k_p": 4.2e-7},
        "heat": {"model": "nusselt", "xi": 0.40, "beta": 0.27, "area": "full"},
    },
    "dahl-bump-leak": {
        "description": "power-law valve paths, shifted Gaussian leak, Dahl friction with an "
        "additive seal term, lagging temperature probes with an offset",
        "valve": {
            "m": 0.47, "x_laminar": 0.999,
            "supply": {"family": "power", "C_max": 1.04e-8, "u0": 0.28, "u_sat": 9.8,
                       "n": 1.35, "b": 0.32},
            "exhaust": {"family": "power", "C_max": 1.09e-8, "u0": 0.31, "u_sat": 9.3,
                        "n": 1.45, "b": 0.29},
            "leak": {"shape": "bump", "C0": 4.3e-11, "width": 0.42, "shift": 0.08},
        },
        "friction": {"model": "dahl", "sigma0": 1.6e5, "F_c": 31.0, "alpha": 1.5,
                     "sigma1": 900.0, "sigma2": 68.0, "seal": "additive", "c_p": 1.1e-5},
        "heat": {"model": "nusselt", "xi": 0.38, "beta": 0.29, "area": "full"},
        "probe": {"model": "lagged", "time_constant": 0.55, "second_time_constant": 0.12,
                  "offset": 0.6, "noise": 0.05},
    },
    "mixed": {
        "description": "every part different from the fit: table supply, power exhaust, "
        "Gaussian leak, LuGre with additive seal friction, barrel-only heat, warm wall, "
        "two-lag probes",
        "valve": {
            "m": 0.52, "x_laminar": 0.999,
            "supply": {
                "family": "table",
                "commands": [0.3, 0.6, 1.2, 2.5, 4.0, 6.0, 8.0, 10.0],
                "conductances": [0.0, 3.3e-10, 1.1e-9, 3.4e-9, 5.8e-9, 8.1e-9, 9.2e-9, 9.6e-9],
                "b": 0.37, "b_small": 0.44,
            },
            "exhaust": {"family": "power", "C_max": 1.21e-8, "u0": 0.26, "u_sat": 9.4,
                        "n": 1.6, "b": 0.26},
            "leak": {"shape": "bump", "C0": 3.4e-11, "width": 0.37, "shift": 0.05},
        },
        "friction": {**_LUGRE, "F_c": 26.5, "F_s": 43.0, "v_s": 0.019, "seal": "additive",
                     "c_p": 8.5e-6},
        "heat": {"model": "nusselt", "xi": 0.47, "beta": 0.25, "area": "barrel_only",
                 "wall_temperature": 295.2},
        "probe": {"model": "lagged", "time_constant": 0.38, "second_time_constant": 0.09,
                  "offset": -0.45, "noise": 0.05},
    },
    "demo-clean": {
        "description": "the clean demo's rig (data/demo-clean): power-law valve paths that differ "
        "(their own overlaps and full-scale commands), a slightly shifted Gaussian centre "
        "leak, LuGre friction with a small additive seal term, full-area Nusselt heat, "
        "lagging temperature probes with an offset; no value round",
        "valve": {
            "m": 0.49, "x_laminar": 0.999,
            "supply": {"family": "power", "C_max": 9.73e-9, "u0": 0.34, "u_sat": 9.62,
                       "n": 1.27, "b": 0.326},
            "exhaust": {"family": "power", "C_max": 1.137e-8, "u0": 0.305, "u_sat": 9.81,
                        "n": 1.34, "b": 0.283},
            "leak": {"shape": "bump", "C0": 2.37e-11, "width": 0.328, "shift": 0.031},
        },
        "friction": {**_LUGRE, "sigma0": 2.31e5, "sigma1": 1.08e3, "sigma2": 63.4,
                     "F_c": 31.7, "F_s": 47.3, "v_s": 0.0186, "seal": "additive",
                     "c_p": 3.1e-6},
        "heat": {"model": "nusselt", "xi": 0.414, "beta": 0.263, "area": "full"},
        "probe": {"model": "lagged", "time_constant": 0.29, "second_time_constant": 0.065,
                  "offset": 0.35, "noise": 0.05},
    },
    "demo": {
        "description": "the bundled demo's rig (data/demo): the clean demo's rig (preset "
        "demo-clean) "
        "with leaking chambers, an undeclared effect: air escapes to the atmosphere through "
        "a worn rod seal and fittings, about 1.1 l/min (ANR) out of chamber N and 0.6 l/min "
        "out of chamber P at 7 bar, orifice law",
        "external_leak": {"model": "orifice", "C_P": 1.41e-11, "C_N": 2.63e-11, "b": 0.47},
    },
    "fit-laws": {
        "description": "the fitted laws where the truth can express them (linear ramps with "
        "the fit's rounded dead-band edge, the fit's leak shape, full area); a control, not a "
        "mismatch",
        "valve": {
            "m": 0.5, "x_laminar": 0.995,
            "supply": {"family": "iso_linear", "C_max": 1.0e-8, "overlap": 0.3, "u_sat": 10.0,
                       "b": 0.3, "corner": 0.05, "corner_shape": "smoothstep"},
            "exhaust": {"family": "iso_linear", "C_max": 1.1e-8, "overlap": 0.3,
                        "u_sat": 10.0, "b": 0.3, "corner": 0.05, "corner_shape": "smoothstep"},
            "leak": {"shape": "sigmoid", "C0": 2.0e-11, "width": 0.3},
        },
        "friction": {**_LUGRE, "F_c": 30.0, "F_s": 50.0, "v_s": 0.02, "sigma2": 60.0},
        "heat": {"model": "nusselt", "xi": 0.4, "beta": 0.27, "area": "full"},
    },
}  # fmt: skip
# demo is demo-clean's rig (every part) plus its own description and external leak
_PRESET_DATA["demo"] = {**copy.deepcopy(_PRESET_DATA["demo-clean"]), **_PRESET_DATA["demo"]}

#: Named truth configurations (name -> nested dict, as a TOML file would hold).
PRESETS: Mapping[str, Mapping[str, Any]] = {
    name: {"name": name, **data} for name, data in _PRESET_DATA.items()
}


def get_truth(truth: TruthConfig | str | os.PathLike[str] | Mapping[str, Any]) -> TruthConfig:
    """Resolve a truth: a configuration, a preset name, a TOML/JSON file or a dict.

    Raises
    ------
    PneumafitInputError
        Neither a preset nor a readable configuration file, or a bad key.
    """
    if isinstance(truth, TruthConfig):
        return truth
    if isinstance(truth, Mapping):
        return TruthConfig.from_dict(truth)
    text = os.fspath(truth)
    if text in PRESETS:
        return TruthConfig.from_dict(copy.deepcopy(dict(PRESETS[text])), source=f"preset {text}")
    path = Path(text)
    if path.suffix.lower() in (".toml", ".json") or path.exists():
        if not path.is_file():
            raise PneumafitInputError(f"--truth {text!r}: no such file")
        return TruthConfig.from_file(path)
    raise PneumafitInputError(
        f"--truth: expected a preset ({', '.join(PRESETS)}) or a .toml/.json file, found {text!r}"
    )


#: Reference state of :func:`reference_quantities`: chamber pressure (Pa), gas
#: and wall temperatures (K), sliding speed (m/s).
REFERENCE_STATE = {"pressure": 5.0e5, "gas_temperature": 323.15, "wall_temperature": 293.15,
                   "sliding_velocity": 0.05}  # fmt: skip


def reference_quantities(config: TruthConfig, parameters: Mapping[str, float]) -> dict[str, float]:
    """Figures of the truth a recovery test compares fitted parameters with.

    Parameters
    ----------
    config : TruthConfig
    parameters : mapping of str to float
        The rig's true parameters (SI, PARAMETER_SPECS names).

    Returns
    -------
    dict of str to float
        ``lambda_reference`` (W/m^2/K): lambda at P = 5 bar, gas 50 degC,
        wall 20 degC; ``lambda_full_area_equivalent`` (W/m^2/K): the same
        scaled by A_truth / A_full of chamber P at mid-stroke (what a model
        with the full-area convention should find); ``friction_static`` (N):
        steady friction at breakaway (v -> 0+), ``friction_coulomb`` (N):
        steady sliding friction at 0.05 m/s minus its viscous part,
        ``friction_viscous`` (N s/m), all with both chambers at mid
        pressure (P_S + P_atm) / 2; ``valve_C_supply_max``,
        ``valve_C_exhaust_max`` (m^3/s/Pa): full-opening conductances;
        ``valve_C_leak_centre`` (m^3/s/Pa): leak of each path at u = 0
        (mean of both).
    """
    par = dict(parameters)
    par.update(config.parameters)
    ref = REFERENCE_STATE
    heat = config.heat
    length = par["characteristic_length"] if heat.length is None else heat.length
    lam = heat.coefficient(ref["pressure"], ref["gas_temperature"], ref["wall_temperature"],
                           length)  # fmt: skip
    y_mid = 0.5 * par["stroke"]
    geo = (y_mid, par["bore"], par["rod"], par["stroke"], par["dead_volume_P"])
    ratio = exchange_area(heat.area, "P", *geo) / exchange_area("full", "P", *geo)
    delta = par["supply_pressure"] - par["exhaust_pressure"]
    fr = config.friction
    c_s, _, c_e, _ = config.valve.conductances(0.0)
    return {
        "lambda_reference": lam,
        "lambda_full_area_equivalent": lam * ratio,
        "friction_static": fr.breakaway(delta),
        "friction_coulomb": fr.sliding(ref["sliding_velocity"], delta),
        "friction_viscous": fr.viscous(),
        "valve_C_supply_max": config.valve.supply.c_max,
        "valve_C_exhaust_max": config.valve.exhaust.c_max,
        "valve_C_leak_centre": 0.5 * (c_s + c_e),
    }
