"""Parameter files: named model parameters with units, read into SI values.

Format (JSON)::

    {"model": "convection",
     "friction": "lugre",
     "parameters": {"xi": 0.4, "bore": "32 mm", "supply_pressure": "7 bar"}}

or the same keys in TOML, in a file whose name ends in ``.toml``::

    model = "convection"
    friction = "lugre"
    [parameters]
    xi = 0.4
    bore = "32 mm"
    supply_pressure = "7 bar"

``friction`` (optional) is the friction law of the structure, ``"switch"``
(the default when absent) or ``"lugre"``; ``effects`` and ``structure`` are
optional too (see :func:`parse_effects`, :func:`read_valve_law`), and
``description`` is free text. Any other top-level key is an error (a
misspelt ``"paramters"`` would otherwise leave every default in place),
except in documents with a ``format`` key (fit.json, truth.json).

A value is a bare number in the parameter's SI unit (see
:data:`pneumafit.models.PARAMETER_SPECS`) or a string with a unit, converted
by pint. A fit result (``fit.json``, ``{"format": "pneumafit-fit", ...}``)
whose parameters are ``{NAME: {"value": ..., "unit": ...}}`` is read too,
through the one reader of fit.json
(:meth:`pneumafit.identification.fitfile.SavedFit.from_document`): its
structure (valve and friction laws, effects, air properties) is the fitted
one, with that reader's documented fallbacks for missing keys (no
``structure.friction``: ``"switch"``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from pathlib import Path
from typing import Any

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.units import UnitError, parse_quantity
from pneumafit.identification.fitfile import SavedFit, is_fit_document
from pneumafit.models.layout import FRICTION_LAWS, SPECS, VALVE_LAWS
from pneumafit.models.structure import EFFECT_SLOTS, MODELS, ModelStructure

#: Top-level keys of a hand-written parameter file (a document without
#: ``format``; fit.json and truth.json carry more, and are read too).
PARAMETER_FILE_KEYS = ("model", "friction", "effects", "parameters", "structure", "description")


def _to_si(value: Any, name: str, where: str, exhaust_pressure: float | None = None) -> float:
    spec = SPECS.get(name)
    if spec is None:
        raise PneumafitInputError(
            f"{where}: parameters.{name}: expected a model parameter name "
            f"(e.g. xi, beta, bore, friction_static), found unknown name {name!r}"
        )
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise PneumafitInputError(
            f"{where}: parameters.{name}: expected a number or a string with a unit, "
            f"found {value!r}"
        )
    if isinstance(value, int | float):
        number = float(value)
    else:
        try:
            # read as campaigns are ("32mm", "7 barg"); gauge pressures refer
            # to the file's exhaust pressure, else the rig default's
            reference = SPECS["exhaust_pressure"].default if exhaust_pressure is None else (
                exhaust_pressure
            )  # fmt: skip
            number = parse_quantity(value, spec.unit, exhaust_pressure=reference)
        except UnitError as exc:
            raise PneumafitInputError(
                f"{where}: parameters.{name}: expected a value in {spec.unit or 'no unit'} "
                f"(e.g. {spec.default:g}), found {exc.found}"
            ) from None
    if not math.isfinite(number) or not spec.lower <= number <= spec.upper:
        raise PneumafitInputError(
            f"{where}: parameters.{name}: expected a value in [{spec.lower:g}, {spec.upper:g}] "
            f"{spec.unit}, found {number:g}"
        )
    return number


def parse_parameters(document: dict[str, Any], where: str = "parameters") -> tuple[str, dict]:
    """Model name and SI parameter values from a parsed parameter document.

    Parameters
    ----------
    document : dict
        The parsed JSON (see the module docstring).
    where : str
        Name of the source for messages (e.g. the file name).

    Returns
    -------
    model : str
        ``document["model"]`` (default ``"convection"``).
    values : dict of str to float
        Parameter values in SI units.

    Raises
    ------
    PneumafitInputError
        Naming the key, what was expected and what was found.
    """
    if not isinstance(document, dict):
        raise PneumafitInputError(
            f"{where}: expected a JSON object, found {type(document).__name__}"
        )
    if "format" not in document:  # a hand-written parameter file: a misspelt key is an error
        for key in document:
            if key not in PARAMETER_FILE_KEYS:
                raise PneumafitInputError(
                    f"{where}: {key}: expected one of the parameter file's keys "
                    f"({', '.join(PARAMETER_FILE_KEYS)}), found unknown key {key!r}"
                )
    if "format" in document and not isinstance(document["format"], str):
        raise PneumafitInputError(
            f"{where}: format: expected a string such as 'pneumafit-fit', "
            f"found {document['format']!r}"
        )
    structure = document.get("structure")
    if structure is not None and not isinstance(structure, dict):
        raise PneumafitInputError(
            f"{where}: structure: expected an object (valve, friction, effects), "
            f"found {structure!r}"
        )
    if document.get("format") == "pneumafit-fit":  # a fit.json has both, always
        for key in ("model", "parameters"):
            if key not in document:
                raise PneumafitInputError(
                    f"{where}: {key}: expected a key of every fit.json, found it missing"
                )
    model = document.get("model", "convection")
    if not isinstance(model, str) or model not in MODELS:
        raise PneumafitInputError(
            f"{where}: model: expected one of {', '.join(MODELS)}, found {model!r}"
        )
    parse_friction_law(document, where)  # a wrong law is an error wherever the file is read
    parse_effects(document, where)  # so is a wrong effect (not only where effects are used)
    params = document.get("parameters", {})
    if not isinstance(params, dict):
        raise PneumafitInputError(
            f"{where}: parameters: expected an object of name: value, found {params!r}"
        )
    texts: dict[str, Any] = {}
    for name, value in params.items():
        if isinstance(value, dict):  # fit.json entry
            if "value" not in value:
                raise PneumafitInputError(
                    f"{where}: parameters.{name}: expected a 'value' key, found {sorted(value)}"
                )
            unit = value.get("unit")
            value = value["value"] if not unit else f"{value['value']} {unit}"
        texts[name] = value
    # the exhaust pressure first: the reference of gauge pressures ("7 barg")
    exhaust = (
        _to_si(texts["exhaust_pressure"], "exhaust_pressure", where)
        if "exhaust_pressure" in texts else None
    )  # fmt: skip
    values = {name: _to_si(value, name, where, exhaust) for name, value in texts.items()}
    return model, values


def read_parameter_file(path: str | os.PathLike[str]) -> tuple[str, dict[str, float]]:
    """Read a parameter file (JSON or TOML): model name and SI values by name.

    Raises
    ------
    PneumafitInputError
        Missing file, invalid JSON (with line), or a bad entry.
    """
    return parse_parameters(read_document(path), os.fspath(path))


def read_valve_law(path: str | os.PathLike[str]) -> str:
    """Valve law of a fit.json (``structure.valve``) or parameter file.

    The structure's law (``"map"`` for a fit of the measured valve map, or a
    registered law from outside the package), else ``"iso6358"`` (a
    parameter file, or a fit written before the map existed).
    """
    try:
        document = read_document(path)
    except PneumafitInputError:
        return "iso6358"
    if is_fit_document(document):
        return _fitted(document, os.fspath(path)).valve
    structure = document.get("structure") if isinstance(document, dict) else None
    valve = structure.get("valve") if isinstance(structure, dict) else None
    return str(valve) if isinstance(valve, str) and valve in VALVE_LAWS else "iso6358"


def parse_friction_law(document: dict[str, Any], where: str = "parameters") -> str:
    """Friction law of a parsed parameter document or fit.json.

    A parameter file's top-level ``friction`` key, else a fit.json's
    ``structure.friction``; ``"switch"`` when neither is present (files
    written before the LuGre law read unchanged).

    Raises
    ------
    PneumafitInputError
        A value that is not a friction law, naming the key.
    """
    if not isinstance(document, dict):
        return "switch"
    law: Any = "switch"
    key = "friction"
    structure = document.get("structure")
    if isinstance(structure, dict) and "friction" in structure:
        law, key = structure["friction"], "structure.friction"
    if "friction" in document:
        law, key = document["friction"], "friction"
    if not isinstance(law, str) or law not in FRICTION_LAWS:
        raise PneumafitInputError(
            f"{where}: {key}: expected one of {', '.join(FRICTION_LAWS)}, found {law!r}"
        )
    return law


def parse_effects(document: dict[str, Any], where: str = "parameters") -> dict[str, int]:
    """Optional effects of a parsed parameter document or fit.json.

    A parameter file's top-level ``effects`` table, else a fit.json's
    ``structure.effects`` (a fit that kept the pressure-dependent seal
    friction, or a refit of discovery); empty when neither is present.

    Raises
    ------
    PneumafitInputError
        An unknown effect or a value that is not a non-negative integer,
        naming the key.
    """
    if not isinstance(document, dict):
        return {}
    effects: Any = {}
    key = "effects"
    structure = document.get("structure")
    if isinstance(structure, dict) and "effects" in structure:
        effects, key = structure["effects"], "structure.effects"
    if "effects" in document:
        effects, key = document["effects"], "effects"
    if effects is None:  # null: none (an empty list or string is not a table)
        effects = {}
    if not isinstance(effects, dict):
        raise PneumafitInputError(
            f"{where}: {key}: expected a table of effect = option, found {effects!r}"
        )
    out: dict[str, int] = {}
    for name, value in effects.items():
        if name not in EFFECT_SLOTS:
            raise PneumafitInputError(
                f"{where}: {key}.{name}: expected one of {', '.join(EFFECT_SLOTS)}, found {name!r}"
            )
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise PneumafitInputError(
                f"{where}: {key}.{name}: expected a non-negative integer, found {value!r}"
            )
        out[name] = value
    return out


#: Air-property laws of a structure (``ModelStructure.air_properties``).
AIR_PROPERTIES = ("constant", "sutherland")


def parse_structure(
    document: dict[str, Any], model: str, where: str = "parameters"
) -> ModelStructure:
    """The model structure a parsed parameter document or fit.json describes.

    The registered structure of ``model`` with the document's valve law
    (``structure.valve``), friction law (:func:`parse_friction_law`),
    optional effects (:func:`parse_effects`) and air properties (a parameter
    file's top-level ``air_properties``, else a fit.json's
    ``structure.air_properties``: a convection fit is made with Sutherland
    air, and a plant simulated with the registered constant properties
    differs from the fitted model by ~1.5 kPa on a step test). What the
    document does not say stays the registered structure's; for a fit.json,
    what :meth:`~pneumafit.identification.fitfile.SavedFit.from_document`
    reads (the fitted structure, or its laws, air and effects on ``model``
    when that is another model).

    Raises
    ------
    PneumafitInputError
        An unknown model, valve law, friction law, effect or air-property
        law, naming the key.
    """
    if model not in MODELS:
        raise PneumafitInputError(
            f"{where}: model: expected one of {', '.join(MODELS)}, found {model!r}"
        )
    if is_fit_document(document):  # the structure fitted, read as every reader reads it
        fitted = _fitted(document, where)
        if model == document.get("model"):
            return fitted
        # another model (simulate --model): the fit's laws, air and effects on it
        structure = dataclasses.replace(
            MODELS[model], valve=fitted.valve, friction=fitted.friction,
            air_properties=fitted.air_properties,
        )  # fmt: skip
        return structure.with_effects(**fitted.effects) if fitted.effects else structure
    structure = MODELS[model]
    spec = document.get("structure") if isinstance(document, dict) else None
    spec = spec if isinstance(spec, dict) else {}
    changes: dict[str, Any] = {}
    valve = spec.get("valve")
    if valve is not None:
        if valve not in ("iso6358", "map"):
            raise PneumafitInputError(
                f"{where}: structure.valve: expected iso6358 or map, found {valve!r}"
            )
        changes["valve"] = valve
    changes["friction"] = parse_friction_law(document, where)
    air, key = spec.get("air_properties"), "structure.air_properties"
    if isinstance(document, dict) and "air_properties" in document:
        air, key = document["air_properties"], "air_properties"
    if air is not None:
        if air not in AIR_PROPERTIES:
            raise PneumafitInputError(
                f"{where}: {key}: expected one of {', '.join(AIR_PROPERTIES)}, found {air!r}"
            )
        changes["air_properties"] = air
    structure = dataclasses.replace(structure, **changes)
    effects = parse_effects(document, where)
    return structure.with_effects(**effects) if effects else structure


def read_structure(
    path: str | os.PathLike[str], model: str | None = None
) -> tuple[ModelStructure, dict[str, float]]:
    """Structure (:func:`parse_structure`) and SI values of a parameter file or fit.json.

    ``model`` replaces the file's model name (``pneumafit simulate --model``);
    the file's valve law, friction law, effects and air properties are kept.

    Raises
    ------
    PneumafitInputError
        Missing file, invalid JSON or bad entries, naming the file and key.
    """
    document = read_document(path)
    file_model, values = parse_parameters(document, os.fspath(path))
    return parse_structure(document, model or file_model, os.fspath(path)), values


def _fitted(document: dict[str, Any], where: str) -> ModelStructure:
    """The structure of a fit.json document, read by the one reader of the
    format (:meth:`SavedFit.from_document`, with its documented fallbacks);
    a friction-test fit is not a parameter file."""
    structure = SavedFit.from_document(document, where).structure
    if structure is None:
        raise PneumafitInputError(
            f"{where}: model: expected one of {', '.join(MODELS)}, found {document.get('model')!r}"
        )
    return structure


def read_document(path: str | os.PathLike[str]) -> Any:
    """The parsed document of a parameter file (JSON, or TOML when its name
    ends in ``.toml``: the same keys, as the campaign's own file), fit.json
    or truth.json; a fit.json is checked by its reader
    (:meth:`SavedFit.from_document`)."""
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PneumafitInputError(f"{file}: expected a parameter file, found none") from None
    except OSError as exc:
        raise PneumafitInputError(f"{file}: cannot be read: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise PneumafitInputError(f"{file}: expected UTF-8 text, found other bytes") from None
    if file.suffix.lower() == ".toml":
        try:
            document = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:  # the message gives line and column
            raise PneumafitInputError(
                f"{file}: expected valid TOML, found an error: {exc}"
            ) from None
        return document
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PneumafitInputError(
            f"{file}: line {exc.lineno}: expected valid JSON, found an error: {exc.msg}"
        ) from None
    if is_fit_document(document):
        _fitted(document, os.fspath(file))
    return document


def read_friction_law(path: str | os.PathLike[str]) -> str:
    """Friction law of a parameter file or fit.json (see :func:`parse_friction_law`).

    Raises
    ------
    PneumafitInputError
        Missing file, invalid JSON or a wrong friction law.
    """
    document = read_document(path)
    if is_fit_document(document):
        return _fitted(document, os.fspath(path)).friction
    return parse_friction_law(document, os.fspath(path))


def read_effects(path: str | os.PathLike[str]) -> dict[str, int]:
    """Optional effects of a parameter file or fit.json (see :func:`parse_effects`).

    Raises
    ------
    PneumafitInputError
        Missing file, invalid JSON or a wrong effect entry.
    """
    document = read_document(path)
    if is_fit_document(document):
        return dict(_fitted(document, os.fspath(path)).effects)
    return parse_effects(document, os.fspath(path))


def read_parameter_details(path: str | os.PathLike[str]) -> tuple[str, dict[str, dict]]:
    """Model name and, per parameter given in the file, its SI value with the
    uncertainty a fit.json carries (``std``, ``interval_90``; None otherwise).

    Values of a fit.json are SI by its contract; unit strings are honoured.
    """
    document = read_document(path)
    model, values = parse_parameters(document, os.fspath(path))
    entries = document.get("parameters", {})
    details: dict[str, dict] = {}
    for name, value in values.items():
        entry = entries.get(name) if isinstance(entries.get(name), dict) else {}
        interval = entry.get("interval_90")
        details[name] = {
            "value": value,
            "unit": SPECS[name].unit,
            "std": entry.get("std"),
            "interval_90": list(interval) if interval is not None else None,
            "fixed": bool(entry.get("fixed", False)),
        }
    return model, details
