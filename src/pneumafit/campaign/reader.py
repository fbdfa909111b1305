"""Read and validate campaign folders (campaign format version 1).

:func:`inspect_campaign` reads everything it can and collects every problem;
:func:`validate_campaign` returns the problems; :func:`read_campaign` returns a
:class:`~pneumafit.campaign.model.Campaign` or raises
:class:`~pneumafit.campaign.errors.CampaignError`. Files are read once, as
bytes, and never opened for writing; the SHA-256 of those bytes is kept.
"""

from __future__ import annotations

import codecs
import csv
import hashlib
import io
import math
import os
import re
import tomllib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from pneumafit.campaign.consistency import median_interval, recording_findings
from pneumafit.campaign.errors import CampaignError, PneumafitInputError, Problem
from pneumafit.campaign.model import (
    CHAMBERS,
    CHANNELS,
    INPUT_CHANNELS,
    KINDS,
    ROLES,
    Campaign,
    PDController,
    Recording,
    Rig,
    required_channels,
)
from pneumafit.campaign.units import (
    QUANTITY_KINDS,
    UnitError,
    parse_unit,
    parse_value,
    split_header,
    to_si,
)

__all__ = [
    "CAMPAIGN_FILE",
    "CAMPAIGN_FORMAT",
    "CSV_SUFFIXES",
    "FORMAT_VERSION",
    "HDF5_SUFFIXES",
    "RECORDING_FORMAT",
    "CampaignReport",
    "inspect_campaign",
    "read_campaign",
    "read_recording",
    "summarize",
    "validate_campaign",
]

CAMPAIGN_FILE = "campaign.toml"
CAMPAIGN_FORMAT = "pneumatic-campaign"
RECORDING_FORMAT = "pneumatic-recording"
FORMAT_VERSION = 1
HDF5_SUFFIXES = (".h5", ".hdf5")
CSV_SUFFIXES = (".csv",)

_MISSING = "nothing (the key is missing)"
_TOP_KEYS = ("format", "version", "name", "description", "rig", "read", "recording")
_RECORDING_KEYS = (
    "file",
    "kind",
    "role",
    "chamber",
    "piston_position",
    "controller",
    "columns",
    "description",
    "read",
)
#: Sample rate (Hz) above which a recording without ``max_rate`` in ``[read]``
#: gets a warning: a fit's simulations take at least one step per sample
#: (1 ms at most, ``simulation.simulator.DEFAULT_STEP``), so their cost grows
#: with the rate (1.7 ms per 4-s step test at 1 kHz, 21 ms at 10 kHz,
#: 2026-12-04), and the chambers' and the valves' dynamics (tens of Hz) need
#: no more than 1 kHz.
FAST_RATE = 2000.0
#: keys of a ``[read]`` / ``[recording.read]`` table (how to read a file)
_READ_KEYS = (
    "header", "separator", "decimal", "skip_lines", "encoding", "channels", "start", "max_rate",
)  # fmt: skip
#: ``[read]`` keys that only CSV files take (ignored, with a warning, on HDF5)
_CSV_ONLY_KEYS = ("channels", "header", "decimal", "skip_lines", "encoding")
#: decimal marks of CSV numbers ("," as many European benches export them)
_DECIMALS = (".", ",")
#: separators of CSV files; "whitespace" is any run of spaces and tabs
_SEPARATORS = ("whitespace", ",", ";", "\t")
#: keys of one ``[read.channels]`` entry
_CHANNEL_COLUMN_KEYS = ("column", "unit", "gauge", "reversed")
#: channels a sensor may count the other way (``reversed = true``)
_REVERSIBLE = ("y", "y_ref", "v", "F")
#: rig keys still required when every recording is a friction test
_FRICTION_RIG_KEYS = ("bore", "exhaust_pressure", "ambient_temperature")
#: values of rig.acting
_ACTING = ("double", "single")
#: rig key -> (quantity kind, required). exhaust_pressure first: it is the
#: reference of gauge values.
_RIG_FIELDS: dict[str, tuple[str, bool]] = {
    "exhaust_pressure": ("pressure", True),
    "bore": ("length", True),
    "rod": ("length", True),
    "stroke": ("length", True),
    "dead_volume_P": ("volume", True),
    "dead_volume_N": ("volume", True),
    "moving_mass": ("mass", True),
    "supply_pressure": ("pressure", True),
    "ambient_temperature": ("temperature", True),
    "wall_temperature": ("temperature", False),
    "characteristic_length": ("length", False),
    "mounting_angle": ("angle", False),
    "external_force": ("force", False),
}
#: rig key -> (lowest, highest) value of a pneumatic cylinder's rig (SI), and
#: the unit a bare number out of that range was most likely meant in. A bare
#: number is SI: ``bore = 32`` is a 32-m bore, which the fit would take
#: without a word; out of range it is an error naming the unit it may have
#: meant, and a value with a unit out of range only a warning (micro
#: cylinders, long strokes, heavy loads exist).
_RIG_PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "exhaust_pressure": (5.0e4, 1.5e5, "bar"),
    "bore": (0.002, 0.5, "mm"),
    "rod": (0.0, 0.3, "mm"),
    "stroke": (0.001, 10.0, "mm"),
    "dead_volume_P": (1.0e-9, 0.05, "cm^3"),
    "dead_volume_N": (1.0e-9, 0.05, "cm^3"),
    "moving_mass": (1.0e-3, 5.0e3, "g"),
    "supply_pressure": (1.2e5, 4.0e6, "bar"),
    "ambient_temperature": (223.15, 423.15, "degC"),
    "wall_temperature": (223.15, 423.15, "degC"),
    "characteristic_length": (0.001, 1.0, "mm"),
    "mounting_angle": (-2.0 * math.pi, 2.0 * math.pi, "deg"),
}
#: controller key -> (quantity kind, required)
_CONTROLLER_FIELDS: dict[str, tuple[str, bool]] = {
    "kp": ("proportional gain", True),
    "kd": ("derivative gain", True),
    "u0": ("voltage", False),
    "umax": ("voltage", True),
}
_BLOCKED_KINDS = ("charge", "discharge")
_CHAMBER_KINDS = ("charge", "discharge", "flow")
_OPEN_KINDS = ("step", "free")
#: kinds that name no chamber and no blocked piston position
_MOVING_KINDS = ("step", "free", "friction")


def _shown(value: object) -> str:
    """A TOML value as the user wrote it, for messages."""
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return repr(value)


def _bare_number(value: object) -> bool:
    """Whether a TOML value is a number without a unit (a number, or a
    string holding only one), which the campaign reads as SI."""
    if isinstance(value, bool):
        return False
    if isinstance(value, int | float):
        return True
    if isinstance(value, str):
        try:
            float(value.strip())
        except ValueError:
            return False
        return True
    return False


def _found(value: object) -> str:
    """What the user wrote for a key, for messages: the value, or that it is missing."""
    return _MISSING if value is None else _shown(value)


def _unexpected(exc: BaseException) -> str:
    return f"an error while reading it: {type(exc).__name__}: {exc}"


class _Problems:
    """Collects problems in the order they are found."""

    def __init__(self) -> None:
        self.items: list[Problem] = []

    def error(self, file: str, key: str, expected: str, found: str) -> None:
        self.items.append(Problem(file, key, expected, found, "error"))

    def warning(self, file: str, key: str, expected: str, found: str) -> None:
        self.items.append(Problem(file, key, expected, found, "warning"))

    def unknown_keys(
        self, file: str, table: Iterable[str], allowed: Iterable[str], what: str, prefix: str = ""
    ) -> None:
        """A warning for each key of ``table`` not in ``allowed`` (such a key is ignored).

        ``what`` names an allowed key (``"a rig key"``); ``prefix`` is the
        table's key path (none for the top level).
        """
        allowed = tuple(allowed)
        for key in table:
            if key not in allowed:
                self.warning(
                    file,
                    f"{prefix}.{key}" if prefix else key,
                    f"{what} ({', '.join(allowed)})",
                    f'unknown key "{key}" (ignored)',
                )

    @property
    def n_errors(self) -> int:
        return sum(p.is_error for p in self.items)


@dataclass
class CampaignReport:
    """Everything :func:`inspect_campaign` found.

    Parameters
    ----------
    path : pathlib.Path
        The campaign folder.
    campaign : Campaign or None
        The campaign, or None when there is any error.
    recordings : list of Recording
        Recordings that could be read, even if the campaign is invalid.
    problems : list of Problem
        Errors and warnings, in the order found.
    """

    path: Path
    campaign: Campaign | None = None
    recordings: list[Recording] = field(default_factory=list)
    problems: list[Problem] = field(default_factory=list)

    @property
    def errors(self) -> list[Problem]:
        """Problems of severity ``"error"``."""
        return [p for p in self.problems if p.is_error]

    @property
    def warnings(self) -> list[Problem]:
        """Problems of severity ``"warning"``."""
        return [p for p in self.problems if not p.is_error]

    @property
    def ok(self) -> bool:
        """True when there is no error (warnings allowed)."""
        return not self.errors


@dataclass(frozen=True)
class _ChannelColumn:
    """Where one channel of a headerless file is: column (from 1), unit, gauge."""

    column: int
    unit: str
    gauge: bool = False
    reversed: bool = False


@dataclass
class _ReadSpec:
    """How to read a recording file (``[read]`` merged with ``[recording.read]``).

    ``keys`` maps each given key to where it was written (``read.header`` or
    ``recording[2].read.header``), for messages. ``ok`` is False when the
    table had an error: the file is then not read (the error is reported).
    """

    header: bool = True
    separator: str = ","
    decimal: str = "."
    skip_lines: int = 0
    encoding: str = "utf-8"
    channels: dict[str, _ChannelColumn] = field(default_factory=dict)
    start: float | None = None
    start_text: str = ""
    max_rate: float | None = None
    keys: dict[str, str] = field(default_factory=dict)
    ok: bool = True


@dataclass
class _Meta:
    """One ``[[recording]]`` entry of campaign.toml, values already in SI."""

    index: int
    file: str
    kind: str | None
    role: str = "fit"
    chamber: str | None = None
    piston_position: float | None = None
    controller: PDController | None = None
    controller_declared: bool = False
    columns: dict[str, str] = field(default_factory=dict)
    description: str | None = None
    columns_file: str = CAMPAIGN_FILE
    columns_key: str = "columns"
    exhaust_reported: bool = False  # campaign.toml already reports a bad exhaust pressure
    read: _ReadSpec = field(default_factory=_ReadSpec)


@dataclass
class _Column:
    """One channel as found in a file, values in the file's unit."""

    channel: str
    unit_text: str
    values: NDArray[np.float64]
    mask: NDArray[np.bool_]
    gauge_attr: bool = False
    ok: bool = True


@dataclass
class _Raw:
    """A recording file as found, before unit conversion and checks."""

    time: NDArray[np.float64]
    time_unit: str
    columns: list[_Column]
    present: set[str]
    locate: Callable[[int], str]
    description: str | None = None
    kind: str | None = None


# --------------------------------------------------------------------------- campaign.toml


def _read_toml(path: Path, probs: _Problems, sha: dict[str, str]) -> dict[str, Any] | None:
    name = path.name
    data = path.read_bytes()
    sha[name] = hashlib.sha256(data).hexdigest()
    if not data.strip():
        probs.error(
            name,
            "",
            "a campaign description (format, version, [rig], [[recording]])",
            "an empty file" if data else "an empty file (0 bytes)",
        )
        return None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        probs.error(name, f"byte {exc.start}", "UTF-8 text", "a byte that is not UTF-8")
        return None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        line = re.search(r"line (\d+)", message)
        probs.error(name, f"line {line[1]}" if line else "", "valid TOML", message)
        return None


def _parse_header(
    doc: dict[str, Any], default_name: str, file: str, probs: _Problems
) -> tuple[str, str]:
    probs.unknown_keys(file, doc, _TOP_KEYS, "a top-level key")
    fmt = doc.get("format")
    if fmt != CAMPAIGN_FORMAT:
        probs.error(file, "format", f'"{CAMPAIGN_FORMAT}"', _found(fmt))
    version = doc.get("version")
    if version is None:
        probs.error(file, "version", str(FORMAT_VERSION), _MISSING)
    elif type(version) is not int or version != FORMAT_VERSION:
        newer = type(version) is int and version > FORMAT_VERSION
        probs.error(
            file,
            "version",
            str(FORMAT_VERSION),
            _shown(version) + (" (a newer format than this pneumafit reads)" if newer else ""),
        )
    texts = []
    for key, default in (("name", default_name), ("description", "")):
        value = doc.get(key, default)
        if not isinstance(value, str):
            probs.error(file, key, "a string", _shown(value))
            value = default
        texts.append(value)
    return texts[0], texts[1]


def _friction_only(doc: dict[str, Any]) -> bool:
    """True when campaign.toml lists recordings and every one is a friction test."""
    entries = doc.get("recording")
    entries = [entries] if isinstance(entries, dict) else entries
    return (
        isinstance(entries, list)
        and bool(entries)
        and all(isinstance(e, dict) and e.get("kind") == "friction" for e in entries)
    )


def _parse_rig(
    doc: dict[str, Any], file: str, probs: _Problems, friction_only: bool = False
) -> tuple[Rig | None, dict[str, float]]:
    """The rig (None on any error) and the rig values that are valid on their own.

    The valid values (e.g. a good exhaust pressure next to a bad bore) still
    serve to check the recordings, so that one mistake is reported once.
    With ``friction_only`` (every recording a friction test) only
    :data:`_FRICTION_RIG_KEYS` are required; the others default to NaN.
    """
    table = doc.get("rig")
    if not isinstance(table, dict):
        found = "no [rig] table" if table is None else _shown(table)
        probs.error(file, "rig", "a [rig] table (bore, rod, stroke, ...)", found)
        return None, {}
    probs.unknown_keys(file, table, (*_RIG_FIELDS, "acting"), "a rig key", "rig")
    n_errors = probs.n_errors
    acting = table.get("acting", "double")
    if acting not in _ACTING:
        probs.error(
            file,
            "rig.acting",
            '"double" (both chambers pressurised) or "single" (rod side open to the air)',
            _shown(acting),
        )
    values: dict[str, float] = {}
    for key, (kind, required) in _RIG_FIELDS.items():
        if friction_only and key not in _FRICTION_RIG_KEYS:
            required = False
        if key not in table:
            if required:
                probs.error(file, f"rig.{key}", QUANTITY_KINDS[kind].expected, _MISSING)
            continue
        try:
            values[key] = parse_value(
                table[key], kind, exhaust_pressure=values.get("exhaust_pressure")
            )
        except UnitError as exc:
            expected = exc.expected
            if key == "exhaust_pressure" and "gauge" in exc.found:
                expected = "an absolute pressure (it is the reference of gauge values)"
            probs.error(file, f"rig.{key}", expected, exc.found)

    rejected: set[str] = set()

    def bad(key: str, expected: str) -> None:
        rejected.add(key)
        unit = QUANTITY_KINDS[_RIG_FIELDS[key][0]].si_unit
        found = f"{_shown(table[key])} (= {values[key]:.6g} {unit})"
        if _bare_number(table[key]) and key in _RIG_PLAUSIBLE:
            meant = _RIG_PLAUSIBLE[key][2]
            found += (
                f": a bare number is in SI units ({unit}); if {table[key]} was meant in "
                f'another, write it, e.g. "{table[key]} {meant}"'
            )
        probs.error(file, f"rig.{key}", expected, found)

    for key in (
        "bore",
        "stroke",
        "dead_volume_P",
        "dead_volume_N",
        "moving_mass",
        "characteristic_length",
        "exhaust_pressure",
    ):
        if key in values and not values[key] > 0.0:
            bad(key, f"a positive {_RIG_FIELDS[key][0]}")
    for key in ("ambient_temperature", "wall_temperature"):
        if key in values and not values[key] > 0.0:
            bad(key, "a temperature above absolute zero")
    if "rod" in values:
        if values["rod"] < 0.0:
            bad("rod", "a rod diameter >= 0")
        elif values.get("bore", math.inf) <= values["rod"]:
            bad("rod", f"a rod diameter smaller than the bore ({values['bore']:.6g} m)")
    exhaust = values.get("exhaust_pressure", 0.0)
    if "supply_pressure" in values and values["supply_pressure"] <= exhaust:
        bad("supply_pressure", f"a pressure above the exhaust pressure ({exhaust:.6g} Pa)")
    for key, (low, high, _meant) in _RIG_PLAUSIBLE.items():
        if key not in values or key in rejected or low <= values[key] <= high:
            continue
        kind = _RIG_FIELDS[key][0]
        unit = QUANTITY_KINDS[kind].si_unit
        name = key.replace("_", " ")
        span = f"{'an' if name[0] in 'aeiou' else 'a'} {name} of {low:.6g} to {high:.6g} {unit}"
        if _bare_number(table[key]):
            bad(key, span)
        else:
            probs.warning(
                file, f"rig.{key}", f"{span} (pneumatic cylinders; the value is used as written)",
                f"{_shown(table[key])} (= {values[key]:.6g} {unit})",
            )  # fmt: skip
    valid = {key: value for key, value in values.items() if key not in rejected}
    if probs.n_errors > n_errors:
        return None, valid
    values.setdefault("wall_temperature", values["ambient_temperature"])
    values.setdefault("characteristic_length", values["bore"])
    for key, (_kind, required) in _RIG_FIELDS.items():
        if required:  # only friction-only campaigns get here without one
            values.setdefault(key, math.nan)
    return Rig(**values).with_acting(acting), valid


def _parse_controller(table: object, key: str, file: str, probs: _Problems) -> PDController | None:
    if not isinstance(table, dict):
        probs.error(file, key, "a [recording.controller] table", _shown(table))
        return None
    probs.unknown_keys(file, table, ("law", *_CONTROLLER_FIELDS), "a controller key", key)
    n_errors = probs.n_errors
    law = table.get("law", "pd")
    if law != "pd":
        probs.error(file, f"{key}.law", '"pd" (the only law of format version 1)', _shown(law))
    gains: dict[str, float] = {"u0": 0.0}
    for name, (kind, required) in _CONTROLLER_FIELDS.items():
        if name not in table:
            if required:
                probs.error(file, f"{key}.{name}", QUANTITY_KINDS[kind].expected, _MISSING)
            continue
        try:
            gains[name] = parse_value(table[name], kind)
        except UnitError as exc:
            probs.error(file, f"{key}.{name}", exc.expected, exc.found)
    if "umax" in gains and not gains["umax"] > 0.0:
        probs.error(
            file,
            f"{key}.umax",
            "a positive saturation voltage",
            f"{_shown(table['umax'])} (= {gains['umax']:.6g} V)",
        )
    if probs.n_errors > n_errors:
        return None
    return PDController(kp=gains["kp"], kd=gains["kd"], u0=gains["u0"], umax=gains["umax"], law=law)


def _parse_entry(
    entry: object,
    index: int,
    stroke: float | None,
    seen: dict[str, int],
    file: str,
    probs: _Problems,
) -> _Meta | None:
    prefix = f"recording[{index}]"
    if not isinstance(entry, dict):
        probs.error(file, prefix, "a [[recording]] table", _shown(entry))
        return None
    probs.unknown_keys(file, entry, _RECORDING_KEYS, "a recording key", prefix)

    name = entry.get("file")
    if not isinstance(name, str) or not name.strip():
        probs.error(
            file,
            f"{prefix}.file",
            'a file name (e.g. "step_1.csv")',
            _found(name),
        )
        name = None
    elif name in seen:
        probs.error(
            file,
            f"{prefix}.file",
            "each file listed once",
            f'"{name}" already listed as recording[{seen[name]}]',
        )
        name = None
    else:
        seen[name] = index

    kind = entry.get("kind")
    if kind not in KINDS:
        probs.error(
            file,
            f"{prefix}.kind",
            f"one of {', '.join(KINDS)}",
            _found(kind),
        )
        kind = None

    role = entry.get("role", "fit")
    if role not in ROLES:
        probs.error(file, f"{prefix}.role", "fit or validate", _shown(role))
        role = "fit"

    chamber = entry.get("chamber")
    if chamber is not None and chamber not in CHAMBERS:
        probs.error(
            file, f"{prefix}.chamber", '"P" (full-bore side) or "N" (rod side)', _shown(chamber)
        )
        chamber = None
    elif chamber is None and kind in _CHAMBER_KINDS:
        probs.error(
            file, f"{prefix}.chamber", f'"P" or "N" (a {kind} test names its chamber)', _MISSING
        )
    elif chamber is not None and kind in _MOVING_KINDS:
        probs.warning(
            file,
            f"{prefix}.chamber",
            f"no chamber on a {kind} test",
            f'chamber = "{chamber}" (ignored)',
        )
        chamber = None

    position = None
    if "piston_position" in entry:
        raw = entry["piston_position"]
        try:
            position = parse_value(raw, "length")
        except UnitError as exc:
            probs.error(file, f"{prefix}.piston_position", exc.expected, exc.found)
        if position is not None and kind in _MOVING_KINDS:
            probs.warning(
                file,
                f"{prefix}.piston_position",
                f"no piston position on a {kind} test",
                f"{_shown(raw)} (ignored)",
            )
            position = None
        if position is not None and not 0.0 <= position <= (stroke or math.inf):
            limit = f"the stroke ({stroke:.6g} m)" if stroke is not None else "the stroke"
            probs.error(
                file,
                f"{prefix}.piston_position",
                f"a position between 0 and {limit}",
                f"{_shown(raw)} (= {position:.6g} m)",
            )
            position = None
    elif kind in _BLOCKED_KINDS:
        probs.error(
            file,
            f"{prefix}.piston_position",
            f'a length (e.g. "250 mm"): a {kind} test is made with the piston blocked',
            _MISSING,
        )

    controller = None
    declared = "controller" in entry
    if declared:
        controller = _parse_controller(entry["controller"], f"{prefix}.controller", file, probs)
        if kind is not None and kind != "step":
            probs.warning(
                file,
                f"{prefix}.controller",
                "a controller on step tests only",
                f"a controller on a {kind} test (ignored)",
            )
            controller, declared = None, False

    columns: dict[str, str] = {}
    table = entry.get("columns", {})
    if not isinstance(table, dict):
        probs.error(file, f"{prefix}.columns", 'a table "file column" = "channel"', _shown(table))
        table = {}
    for column, target in table.items():
        if isinstance(target, str) and target in CHANNELS:
            columns[column] = target
        else:
            probs.error(
                file,
                f'{prefix}.columns."{column}"',
                f"a channel name ({', '.join(CHANNELS)})",
                _shown(target),
            )

    description = entry.get("description")
    if description is not None and not isinstance(description, str):
        probs.error(file, f"{prefix}.description", "a string", _shown(description))
        description = None

    if name is None:
        return None
    return _Meta(
        index=index,
        file=name,
        kind=kind,
        role=role,
        chamber=chamber,
        piston_position=position,
        controller=controller,
        controller_declared=declared,
        columns=columns,
        description=description,
        columns_file=file,
        columns_key=f"{prefix}.columns",
    )


def _parse_read(table: object, prefix: str, file: str, probs: _Problems) -> dict[str, Any]:
    """Check one ``[read]`` table; return its valid values (``ok`` False on an error).

    ``prefix`` is the table's key path (``read`` or ``recording[2].read``).
    """
    out: dict[str, Any] = {"ok": True, "keys": {}}
    if table is None:
        return out
    if not isinstance(table, dict):
        probs.error(file, prefix, f"a table ({', '.join(_READ_KEYS)})", _shown(table))
        out["ok"] = False
        return out
    n_errors = probs.n_errors
    probs.unknown_keys(file, table, _READ_KEYS, "a read key", prefix)
    out["keys"] = {key: f"{prefix}.{key}" for key in table if key in _READ_KEYS}
    if "header" in table:
        if isinstance(table["header"], bool):
            out["header"] = table["header"]
        else:
            probs.error(
                file,
                f"{prefix}.header",
                "true (the first row names the columns) or false (no header row)",
                _shown(table["header"]),
            )
    if "separator" in table:
        sep = table["separator"]
        if sep in _SEPARATORS:
            out["separator"] = sep
        else:
            shown = '"whitespace", ",", ";", "\\t"'
            probs.error(file, f"{prefix}.separator", f"one of {shown}", _shown(sep))
    if "decimal" in table:
        if table["decimal"] in _DECIMALS:
            out["decimal"] = table["decimal"]
        else:
            probs.error(
                file, f"{prefix}.decimal", '"." or "," (the decimal mark)', _shown(table["decimal"])
            )
    if "skip_lines" in table:
        skip = table["skip_lines"]
        if type(skip) is int and skip >= 0:
            out["skip_lines"] = skip
        else:
            probs.error(
                file,
                f"{prefix}.skip_lines",
                "a number of lines (an integer, 0 or more) to leave out at the top of the file",
                _shown(skip),
            )
    if "encoding" in table:
        name = table["encoding"]
        try:
            if not isinstance(name, str):
                raise LookupError(name)
            out["encoding"] = codecs.lookup(name).name
        except LookupError:
            probs.error(
                file,
                f"{prefix}.encoding",
                'a text encoding (e.g. "utf-8", the default, "cp1252" or "latin-1")',
                _shown(name),
            )
    if "start" in table:
        try:
            out["start"] = parse_value(table["start"], "time")
            out["start_text"] = _shown(table["start"])
        except UnitError as exc:
            probs.error(file, f"{prefix}.start", exc.expected, exc.found)
    if "max_rate" in table:
        try:
            rate = parse_value(table["max_rate"], "frequency")
        except UnitError as exc:
            probs.error(file, f"{prefix}.max_rate", exc.expected, exc.found)
        else:
            if rate > 0.0:
                out["max_rate"] = rate
            else:
                probs.error(
                    file, f"{prefix}.max_rate", 'a positive frequency (e.g. "1 kHz")',
                    _shown(table["max_rate"]),
                )  # fmt: skip
    if "channels" in table:
        out["channels"] = _parse_read_channels(table["channels"], f"{prefix}.channels", file, probs)
    out["ok"] = probs.n_errors == n_errors
    return out


def _parse_read_channels(
    table: object, prefix: str, file: str, probs: _Problems
) -> dict[str, _ChannelColumn]:
    """``[read.channels]``: channel -> {column, unit, gauge} of a headerless file."""
    if not isinstance(table, dict):
        probs.error(file, prefix, '{column = 1, unit = "ms"} tables by channel', _shown(table))
        return {}
    names = ("time", *CHANNELS)
    out: dict[str, _ChannelColumn] = {}
    used: dict[int, str] = {}
    for name, entry in table.items():
        key = f"{prefix}.{name}"
        if name not in names:
            probs.error(file, key, f"a channel name ({', '.join(names)})", f'"{name}"')
            continue
        if not isinstance(entry, dict):
            probs.error(
                file, key, '{column = N, unit = "..."} (column counted from 1)', _shown(entry)
            )
            continue
        probs.unknown_keys(file, entry, _CHANNEL_COLUMN_KEYS, "a channel column key", key)
        kind = "time" if name == "time" else CHANNELS[name]
        ok = True
        column = entry.get("column")
        if type(column) is not int or column < 1:
            probs.error(
                file,
                f"{key}.column",
                "a column number counted from 1 (an integer)",
                _found(column),
            )
            ok = False
        elif column in used:
            probs.error(
                file,
                f"{key}.column",
                "each column read as one channel only",
                f"column {column}, already read as {used[column]}",
            )
            ok = False
        unit = entry.get("unit")
        expected_unit = f'a unit of {QUANTITY_KINDS[kind].name} (e.g. "{_example_unit(kind)}")'
        if not isinstance(unit, str):
            probs.error(file, f"{key}.unit", expected_unit, _found(unit))
            ok = False
        else:
            try:
                parsed = parse_unit(unit, kind)
            except UnitError as exc:
                probs.error(file, f"{key}.unit", exc.expected, exc.found)
                ok = False
            else:
                if parsed.gauge and entry.get("gauge") is False:
                    probs.error(file, f"{key}.gauge", f'true, as the unit "{unit}" says', "false")
                    ok = False
        gauge = entry.get("gauge", False)
        if not isinstance(gauge, bool):
            probs.error(file, f"{key}.gauge", "true or false", _shown(gauge))
            ok = False
        elif gauge and kind != "pressure":
            probs.error(file, f"{key}.gauge", f"no gauge on a {kind} channel", "gauge = true")
            ok = False
        flip = entry.get("reversed", False)
        if not isinstance(flip, bool):
            probs.error(file, f"{key}.reversed", "true or false", _shown(flip))
            ok = False
        elif flip and name not in _REVERSIBLE:
            probs.error(
                file,
                f"{key}.reversed",
                f"reversed only on {', '.join(_REVERSIBLE)} (a sensor counting the other way)",
                f"reversed = true on {name}",
            )
            ok = False
        if ok:
            out[name] = _ChannelColumn(column, unit, gauge, flip)
            used[column] = name
    return out


def _example_unit(kind: str) -> str:
    """The unit part of a quantity kind's example (``"32 mm"`` -> ``"mm"``)."""
    return QUANTITY_KINDS[kind].example.split(" ", 1)[-1]


def _merge_read(top: dict[str, Any], own: dict[str, Any], file: str, probs: _Problems) -> _ReadSpec:
    """A recording's read spec: its own keys override the campaign's ``[read]``."""
    spec = _ReadSpec()
    keys = {**top["keys"], **own["keys"]}
    for part in (top, own):
        for name in (*_READ_KEYS, "start_text"):
            if name in part:
                setattr(spec, name, part[name])
    spec.keys = keys
    spec.ok = top["ok"] and own["ok"]
    if not spec.ok:
        return spec

    def combination(key: str, expected: str, found: str) -> None:
        problem = Problem(file, key, expected, found, "error")
        if problem not in probs.items:  # a campaign-wide [read] problem is said once
            probs.items.append(problem)
        spec.ok = False

    if not spec.header and not spec.channels:
        combination(
            keys.get("header", "read.header"),
            "read.channels too (a file without a header row names its columns in "
            'campaign.toml, e.g. time = {column = 1, unit = "ms"})',
            "header = false and no channels",
        )
    elif not spec.header and "time" not in spec.channels:
        combination(
            keys["channels"], 'a time column (e.g. time = {column = 1, unit = "ms"})', "none"
        )
    if spec.header and spec.channels:
        combination(
            keys["channels"],
            "channels by column number only in a file without a header row (header = false); "
            "with a header use [recording.columns]",
            "header = true",
        )
    if spec.decimal == "," and spec.separator == ",":
        combination(
            keys.get("decimal", "read.decimal"),
            'another separator with a decimal comma (e.g. separator = ";")',
            'decimal = "," and separator ","',
        )
    if spec.header and spec.separator == "whitespace":
        combination(
            keys["separator"],
            'a one-character separator with a header row (whitespace would split "time [s]")',
            '"whitespace"',
        )
    return spec


def _parse_entries(
    doc: dict[str, Any], stroke: float | None, file: str, probs: _Problems
) -> list[_Meta]:
    entries = doc.get("recording")
    if isinstance(entries, dict):
        probs.error(
            file,
            "recording",
            "[[recording]] tables (double brackets)",
            "a single [recording] table",
        )
        entries = [entries]
    if not isinstance(entries, list) or not entries:
        probs.error(
            file,
            "recording",
            "at least one [[recording]] table",
            "none" if not entries else _shown(entries),
        )
        return []
    seen: dict[str, int] = {}
    top = _parse_read(doc.get("read"), "read", file, probs)
    metas = []
    for i, entry in enumerate(entries, start=1):
        meta = _parse_entry(entry, i, stroke, seen, file, probs)
        if meta is None:
            continue
        own = _parse_read(entry.get("read"), f"recording[{i}].read", file, probs)
        meta.read = _merge_read(top, own, file, probs)
        metas.append(meta)
    return metas


# --------------------------------------------------------------------------- recording files


def _apply_columns(
    meta: _Meta, names: dict[int, tuple[str, str]], time_names: Iterable[str], probs: _Problems
) -> dict[int, str]:
    """Channel name of each column after the ``[recording.columns]`` mapping.

    ``names`` maps a column index to (full header or dataset name, name part);
    a mapping key may be either.
    """
    channel = {j: name for j, (_, name) in names.items()}
    for key, target in meta.columns.items():
        wanted = key.strip()
        hits = [j for j, (full, name) in names.items() if wanted in (full, name)]
        where = f'{meta.columns_key}."{key}"'
        if hits:
            channel.update(dict.fromkeys(hits, target))
        elif wanted in time_names:
            probs.error(
                meta.columns_file,
                where,
                "a channel column (the first column is time)",
                f'the time column "{key}"',
            )
        else:
            listed = ", ".join(f'"{full}"' for full, _ in names.values()) or "none"
            probs.error(
                meta.columns_file,
                where,
                f"a column of {meta.file}",
                f'no column "{key}" (columns: {listed})',
            )
    return channel


def _drop_duplicates(
    channel: dict[int, str], label: dict[int, str], file: str, probs: _Problems
) -> dict[int, str]:
    """Report channels given by more than one column; keep only the first column."""
    first: dict[str, int] = {}
    for j, name in channel.items():
        if name in first:
            probs.error(
                file,
                name,
                "each channel in one column only",
                f'"{label[first[name]]}" and "{label[j]}" both give {name}',
            )
        else:
            first[name] = j
    return {j: name for name, j in first.items()}


def _csv_numbers(
    series: pd.Series,
    file: str,
    key: str,
    locate: Callable[[int], str],
    probs: _Problems,
    decimal: str = ".",
) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | None:
    """Numbers of one CSV column; an empty cell is NaN and mask False.

    With ``decimal`` "," a cell's comma is its decimal mark, and a cell with
    a point is refused: "1.234" may be a thousands-grouped 1234 or 1.234, and
    the reader does not guess.
    """
    if decimal == ",":
        return _comma_numbers(series, file, key, locate, probs)
    if series.dtype.kind in "fiu":
        values = series.to_numpy(dtype=np.float64)
        return values, ~np.isnan(values)
    values = np.full(len(series), np.nan)
    bad: list[tuple[int, str]] = []
    for i, cell in enumerate(series.tolist()):
        if pd.isna(cell) or not str(cell).strip():
            continue
        try:
            values[i] = float(cell)
        except (TypeError, ValueError):
            bad.append((i, str(cell)))
            continue
        if not math.isfinite(values[i]):
            bad.append((i, str(cell)))
    if bad:
        i, cell = bad[0]
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        try:
            float(cell)
            expected, what = "finite numbers", " (a NaN or infinite sample)"
        except ValueError:
            expected, what = "numbers", ""
            hint = _comma_hint([c for _, c in bad])
            if hint:
                expected = f"numbers ({hint})"
        probs.error(file, key, expected, f'"{cell}" at {locate(i)}{what}{more}')
        return None
    return values, ~np.isnan(values)


#: A number that may be grouped in thousands with commas ("1,250", "-12,500,000").
_GROUPED = re.compile(r"[+-]?[1-9]\d{0,2}(,\d{3})+")


def _comma_hint(cells: list[str]) -> str:
    """What the commas of a column's unreadable cells say, for the error: a
    decimal comma (some cell cannot be a thousands-grouped number, "0,25"),
    thousands separators (a cell with both marks or two groups, "1,234.5",
    "1,234,567"), either (every
    comma cell reads both ways, "1,250"), or nothing ("" without commas)."""
    texts = [c.strip() for c in cells]
    # grouped beyond doubt: a point after the groups, or two groups or more
    if any(
        _GROUPED.fullmatch(t.split(".")[0]) and (t.count(".") == 1 or t.count(",") > 1)
        for t in texts
        if "," in t and t.count(".") <= 1
    ):
        return "thousands separators are not read: export the numbers without grouping"
    commas = [t for t in texts if _comma_decimal(t)]
    if not commas:
        return ""
    if all(_GROUPED.fullmatch(t) for t in commas):
        return (
            f'"{commas[0]}" is a decimal comma, which needs decimal = "," in [read], or '
            "thousands grouping, which is not read: export the numbers without it"
        )
    proof = next(t for t in commas if not _GROUPED.fullmatch(t))
    if proof == texts[0]:
        return 'a decimal comma as in this cell needs decimal = "," in [read]'
    return f'a decimal comma as in "{proof}" needs decimal = "," in [read]'


def _decodes(data: bytes, encoding: str) -> bool:
    """Whether ``data`` is text in ``encoding``."""
    try:
        data.decode(encoding)
    except UnicodeDecodeError:
        return False
    return True


def _comma_decimal(cell: str) -> bool:
    """Whether a cell is a number written with a decimal comma ("0,25")."""
    text = cell.strip()
    if text.count(",") != 1 or "." in text:
        return False
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def _comma_numbers(
    series: pd.Series, file: str, key: str, locate: Callable[[int], str], probs: _Problems
) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | None:
    """:func:`_csv_numbers` of a column written with decimal commas ("1,25")."""
    cells = [None if pd.isna(c) else str(c).strip() for c in series.tolist()]
    dotted = [i for i, c in enumerate(cells) if c and "." in c]
    if dotted:
        i = dotted[0]
        more = f" (and {len(dotted) - 1} more)" if len(dotted) > 1 else ""
        probs.error(
            file,
            key,
            'numbers with a decimal comma (decimal = ","), no points',
            f'"{cells[i]}" at {locate(i)}{more}',
        )
        return None
    converted = pd.Series([c.replace(",", ".") if c else c for c in cells], dtype=object)
    return _csv_numbers(converted, file, key, locate, probs)


def _csv_time(
    series: pd.Series,
    file: str,
    locate: Callable[[int], str],
    probs: _Problems,
    decimal: str = ".",
) -> NDArray[np.float64] | None:
    """The time column of a CSV file, in its own unit: a number in every row.

    None when a cell is not a number or is empty (the problem is reported).
    """
    time = _csv_numbers(series, file, "time", locate, probs, decimal)
    if time is None:
        return None
    if not time[1].all():
        i = int(np.flatnonzero(~time[1])[0])
        probs.error(file, "time", "a time in every row", f"an empty cell at {locate(i)}")
        return None
    return time[0]


def _read_csv(data: bytes, meta: _Meta, probs: _Problems) -> _Raw | None:
    file = meta.file
    encoding = meta.read.encoding
    try:
        # UTF-8 with or without a byte-order mark
        text = data.decode("utf-8-sig" if encoding == "utf-8" else encoding)
    except UnicodeDecodeError as exc:
        where = f"byte {exc.start}"
        if encoding == "utf-8":
            line = data[: exc.start].count(b"\n") + 1
            if data[:2] in (b"\xff\xfe", b"\xfe\xff"):  # a UTF-16 byte-order mark
                hint = ' (a UTF-16 file: encoding = "utf-16" in [read] reads it)'
            elif _decodes(data, "cp1252"):
                hint = ' (a Windows export? encoding = "cp1252" in [read] reads it)'
            else:
                hint = ""
            probs.error(file, f"line {line}, {where}", "UTF-8 text" + hint,
                        f"a byte that is not UTF-8 (0x{data[exc.start]:02x})")  # fmt: skip
        else:
            probs.error(file, where, f"{encoding} text (read.encoding)",
                        f"a byte that is not {encoding} (0x{data[exc.start]:02x})")  # fmt: skip
        return None
    lines = text.splitlines()
    comments: list[str] = []
    skip = meta.read.skip_lines
    if skip and skip >= len(lines):
        probs.error(
            file,
            meta.read.keys.get("skip_lines", "read.skip_lines"),
            f"more than the {skip} lines that read.skip_lines leaves out",
            f"{len(lines)} line{'s' * (len(lines) != 1)}",
        )
        return None
    for line in lines[skip:]:
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            break
        comment = stripped[1:]
        comments.append(comment[1:] if comment.startswith(" ") else comment)
        skip += 1
    if not meta.read.header:
        return _read_positional(lines, skip, comments, meta, probs)
    if skip == len(lines):
        probs.error(file, "", 'a header row "time [s],name [unit],..."', "no header row")
        return None
    sep = meta.read.separator
    cells = [c.strip() for c in next(csv.reader([lines[skip]], delimiter=sep))]
    body = "\n".join(lines[skip:])
    try:
        frame = pd.read_csv(
            io.StringIO(body),
            sep=sep,
            header=None,
            skiprows=1,
            names=list(range(len(cells))),
            index_col=False,
            keep_default_na=False,
            na_values=[""],
            skip_blank_lines=True,
            # decimal commas: cells kept as text, read by _csv_numbers
            dtype=object if meta.read.decimal == "," else None,
        )
    except pd.errors.EmptyDataError:
        frame = pd.DataFrame(columns=list(range(len(cells))))
    except pd.errors.ParserError as exc:
        fields = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if fields:
            probs.error(
                file,
                f"line {int(fields[2]) + skip}",
                f"{fields[1]} {_separator_name(meta.read.separator)}-separated fields, "
                "like the header",
                f"{fields[3]} fields",
            )
        else:
            probs.error(
                file,
                "",
                f"{_separator_name(meta.read.separator)}-separated rows",
                str(exc).strip(),
            )
        return None
    if frame.empty:
        probs.error(file, "", "at least 2 samples", "a header and no data rows")
        return None
    row_lines = [skip + 1 + j for j, line in enumerate(lines[skip:]) if j > 0 and line.strip()]

    def locate(i: int) -> str:
        return f"line {row_lines[i]}" if len(row_lines) == len(frame) else f"data row {i + 1}"

    time_header = split_header(cells[0])
    if time_header is None:
        probs.error(
            file,
            cells[0] or "column 1",
            'a time header "name [unit]" (e.g. "time [s]")',
            f'"{cells[0]}"',
        )
        return None
    time = _csv_time(frame[0], file, locate, probs, meta.read.decimal)
    if time is None:
        return None

    headers: dict[int, tuple[str, str]] = {}
    for j, cell in enumerate(cells[1:], start=1):
        if not cell and frame[j].isna().all():
            # no name and no value: a separator at the end of every line (as
            # LabVIEW and many loggers write them) or two in a row; nothing to read
            continue
        parsed = split_header(cell)
        if parsed is None:
            probs.error(
                file,
                cell or f"column {j + 1}",
                'a header cell "name [unit]" (e.g. "p_P [bar]")',
                f'"{cell}"' if cell else "an empty header cell",
            )
        else:
            headers[j] = parsed
    names = {j: (cells[j], name) for j, (name, _) in headers.items()}
    channel = _apply_columns(meta, names, (cells[0], time_header[0]), probs)
    present = set(channel.values())
    channel = _drop_duplicates(channel, cells, file, probs)

    columns = []
    for j, name in channel.items():
        numbers = _csv_numbers(frame[j], file, name, locate, probs, meta.read.decimal)
        if numbers is None:
            columns.append(_Column(name, headers[j][1], np.empty(0), np.empty(0, bool), ok=False))
        else:
            columns.append(_Column(name, headers[j][1], numbers[0], numbers[1]))
    description = "\n".join(comments).strip("\n") or None
    return _Raw(time, time_header[1], columns, present, locate, description)


def _separator_name(separator: str) -> str:
    return {",": "comma", ";": "semicolon", "\t": "tab", "whitespace": "whitespace"}.get(
        separator, repr(separator)
    )


def _split_row(line: str, separator: str) -> list[str]:
    if separator == "whitespace":
        return line.split()
    return [cell.strip() for cell in line.split(separator)]


def _read_positional(
    lines: list[str], skip: int, comments: list[str], meta: _Meta, probs: _Problems
) -> _Raw | None:
    """A CSV file without a header row: channels by column number (``[read.channels]``)."""
    file = meta.file
    spec = meta.read
    where = spec.keys.get("channels", "read.channels")
    rows: list[list[str]] = []
    row_lines: list[int] = []
    for number, line in enumerate(lines[skip:], start=skip + 1):
        if line.strip():
            rows.append(_split_row(line, spec.separator))
            row_lines.append(number)
    if len(rows) < 2:
        probs.error(file, "", "at least 2 samples", f"{len(rows)} data row{'s' * (len(rows) != 1)}")
        return None
    name = _separator_name(spec.separator)
    widest = max(spec.channels.items(), key=lambda item: item[1].column)
    n_fields = len(rows[0])
    if n_fields < widest[1].column:
        probs.error(
            file,
            f"line {row_lines[0]}",
            f"at least {widest[1].column} {name}-separated fields ({where}.{widest[0]} is "
            f"column {widest[1].column})",
            f"{n_fields} field{'s' * (n_fields != 1)}",
        )
        return None
    uneven = [i for i, row in enumerate(rows) if len(row) != n_fields]
    if uneven:
        i = uneven[0]
        more = f" (and {len(uneven) - 1} more lines)" if len(uneven) > 1 else ""
        probs.error(
            file,
            f"line {row_lines[i]}",
            f"{n_fields} {name}-separated fields, like line {row_lines[0]}",
            f"{len(rows[i])} field{'s' * (len(rows[i]) != 1)}{more}",
        )
        return None

    def locate(i: int) -> str:
        return f"line {row_lines[i]}"

    def cells(column: int) -> pd.Series:
        return pd.Series([row[column - 1] for row in rows], dtype=object)

    time_spec = spec.channels["time"]
    time = _csv_time(cells(time_spec.column), file, locate, probs, spec.decimal)
    if time is None:
        return None
    columns = []
    for channel, col in spec.channels.items():
        if channel == "time":
            continue
        numbers = _csv_numbers(cells(col.column), file, channel, locate, probs, spec.decimal)
        if numbers is None:
            columns.append(_Column(channel, col.unit, np.empty(0), np.empty(0, bool), ok=False))
        else:
            values = -numbers[0] if col.reversed else numbers[0]
            columns.append(_Column(channel, col.unit, values, numbers[1], col.gauge))
    present = {c for c in spec.channels if c != "time"}
    description = "\n".join(comments).strip("\n") or None
    return _Raw(time, time_spec.unit, columns, present, locate, description)


def _attr_text(value: object) -> str | None:
    """An HDF5 attribute as text (h5py gives str, bytes or numpy values)."""
    if value is None:
        return None
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(-1)[0]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return str(value)


def _is_version(text: str | None) -> bool:
    """True for version 1 written as an integer or a float (MATLAB writes doubles)."""
    try:
        return text is not None and float(text) == FORMAT_VERSION
    except ValueError:
        return False


def _h5_vector(obj: object, file: str, key: str, probs: _Problems) -> NDArray[np.float64] | None:
    if not isinstance(obj, h5py.Dataset) or obj.ndim != 1 or obj.dtype.kind not in "fiu":
        found = (
            f"a dataset of shape {obj.shape} and type {obj.dtype}"
            if isinstance(obj, h5py.Dataset)
            else "a group"
        )
        probs.error(file, key, "a 1-D dataset of numbers", found)
        return None
    return np.asarray(obj[()], dtype=np.float64)


def _read_hdf5(data: bytes, meta: _Meta, probs: _Problems) -> _Raw | None:
    file = meta.file
    try:
        handle = h5py.File(io.BytesIO(data), "r")
    except OSError as exc:
        probs.error(file, "", "an HDF5 file", f"a file HDF5 cannot open ({exc})")
        return None
    with handle:
        fmt = _attr_text(handle.attrs.get("format"))
        if fmt != RECORDING_FORMAT:
            probs.error(
                file,
                "format",
                f'root attribute format = "{RECORDING_FORMAT}"',
                "no format attribute" if fmt is None else f'"{fmt}"',
            )
        version = _attr_text(handle.attrs.get("version"))
        if not _is_version(version):
            probs.error(
                file,
                "version",
                f"root attribute version = {FORMAT_VERSION}",
                "no version attribute" if version is None else version,
            )
        time = None
        time_unit = ""
        time_obj = handle.get("time")
        if time_obj is None:
            probs.error(file, "/time", "a /time dataset of sample times", "no /time dataset")
        else:
            time = _h5_vector(time_obj, file, "/time", probs)
            unit = _attr_text(time_obj.attrs.get("unit"))
            if unit is None:
                probs.error(file, "/time", 'a "unit" attribute (e.g. "s" or "ms")', "none")
                time = None
            time_unit = unit or ""
        group = handle.get("channels")
        if not isinstance(group, h5py.Group):
            probs.error(
                file,
                "/channels",
                "a /channels group with one dataset per channel",
                "no /channels group" if group is None else "a dataset",
            )
            group = None
        if time is None or group is None:
            return None

        dataset_names = list(group.keys())
        names = {j: (name, name) for j, name in enumerate(dataset_names)}
        channel = _apply_columns(meta, names, ("time", "/time"), probs)
        present = set(channel.values())
        channel = _drop_duplicates(channel, dataset_names, file, probs)
        columns = []
        for j, name in channel.items():
            obj = group[dataset_names[j]]
            values = _h5_vector(obj, file, name, probs)
            unit = _attr_text(obj.attrs.get("unit"))
            reference = _attr_text(obj.attrs.get("reference"))
            ok = values is not None
            if unit is None:
                probs.error(file, name, 'a "unit" attribute (e.g. "bar")', "none")
                ok = False
            if reference not in (None, "gauge", "absolute"):
                probs.error(
                    file,
                    name,
                    'attribute reference = "gauge" or "absolute"',
                    f'reference = "{reference}"',
                )
                ok = False
            array = values if values is not None else np.empty(0)
            columns.append(
                _Column(
                    name,
                    unit or "",
                    array,
                    np.ones(array.size, bool),
                    gauge_attr=reference == "gauge",
                    ok=ok,
                )
            )

        kind = _attr_text(handle.attrs.get("kind"))
        description = _attr_text(handle.attrs.get("description"))

    def locate(i: int) -> str:
        return f"sample {i} (time = {time[i]:.9g} {time_unit})"

    return _Raw(time, time_unit, columns, present, locate, description, kind)


def _needed_why(meta: _Meta) -> str:
    why = f"needed by a {meta.kind} test"
    if meta.chamber is not None:
        why += f" of chamber {meta.chamber}"
    if meta.kind == "step":
        why += " with a controller" if meta.controller_declared else " without a controller"
    return why


def _drop_before(
    raw: _Raw, time: NDArray[np.float64], meta: _Meta, probs: _Problems
) -> _Raw | None:
    """The samples at and after ``[read] start`` (a start-up transient left out)."""
    first = int(np.searchsorted(time, meta.read.start, side="left"))
    if time.size - first < 2:
        probs.error(
            meta.columns_file,
            meta.read.keys.get("start", "read.start"),
            f"a start time that leaves at least 2 samples of {meta.file}",
            f"{meta.read.start_text} (the file ends at {raw.time[-1]!r} {raw.time_unit})",
        )
        return None
    columns = [
        _Column(
            c.channel,
            c.unit_text,
            c.values[first:] if c.values.size == time.size else c.values,
            c.mask[first:] if c.mask.size == time.size else c.mask,
            c.gauge_attr,
            c.ok,
        )
        for c in raw.columns
    ]
    locate = raw.locate

    def shifted(i: int) -> str:
        return locate(i + first)

    return _Raw(
        raw.time[first:], raw.time_unit, columns, raw.present, shifted, raw.description, raw.kind
    )


def _thinning(rate: float, max_rate: float) -> int:
    """Samples per kept one of a recording at ``rate`` read at most at
    ``max_rate`` (Hz): ceil(rate / max_rate), a rate equal to the limit
    within rounding kept whole."""
    return math.ceil(rate / max_rate * (1.0 - 1e-9))


def _thinned(
    raw: _Raw, time: NDArray[np.float64], max_rate: float
) -> tuple[_Raw, NDArray[np.float64]]:
    """Every k-th sample of a recording sampled faster than ``max_rate`` (Hz).

    k = ceil(rate / max_rate), the rate from the median sample interval; the
    first sample is kept. The kept samples are the file's own (no averaging:
    a held command stays a held command, only its changes may move by up to
    k - 1 file samples); a channel with empty cells ("not sampled") is
    sampled at a kept row when it has a real sample among the k rows from
    it, its value there interpolated between its real samples as everywhere
    else. Messages keep the file's line numbers.
    """
    dt = median_interval(time)
    k = _thinning(1.0 / dt, max_rate) if dt else 1
    if k <= 1:
        return raw, time
    starts = np.arange(0, time.size, k)

    def kept(column: _Column) -> _Column:
        values, real = column.values, column.mask
        if values.size != time.size or real.size != time.size:
            return column  # reported as a length mismatch by the caller
        if real.all() or not real.any():
            return replace(column, values=values[starts], mask=real[starts])
        # a real sample among the k rows from a kept row samples it there
        filled = values.copy()
        filled[~real] = np.interp(time[~real], time[real], values[real])
        sampled = np.add.reduceat(real.astype(np.int64), starts) > 0
        return replace(column, values=np.where(sampled, filled[starts], np.nan), mask=sampled)

    locate = raw.locate

    def thinned(i: int) -> str:
        return locate(i * k)

    columns = [kept(c) for c in raw.columns]
    return replace(raw, time=raw.time[starts], columns=columns, locate=thinned), time[starts]


def _build_recording(
    raw: _Raw, meta: _Meta, path: Path, exhaust: float | None, probs: _Problems
) -> Recording | None:
    """Convert a raw recording to SI, check it, and derive u_N = -u_P where allowed."""
    file = meta.file
    if raw.kind is not None and meta.kind is not None and raw.kind != meta.kind:
        probs.error(file, "kind", f'kind "{meta.kind}", as in campaign.toml', f'"{raw.kind}"')
    try:
        time_unit = parse_unit(raw.time_unit, "time")
    except UnitError as exc:
        probs.error(file, "time", exc.expected, exc.found)
        return None
    t_file = raw.time
    if t_file.size < 2:
        probs.error(
            file,
            "time",
            "at least 2 samples",
            "no samples" if t_file.size == 0 else "a single sample",
        )
        return None
    bad = np.flatnonzero(~np.isfinite(t_file))
    if bad.size:
        probs.error(
            file, "time", "finite times", f"{float(t_file[bad[0]])!r} at {raw.locate(int(bad[0]))}"
        )
        return None
    back = np.flatnonzero(np.diff(t_file) <= 0.0)
    if back.size:
        i = int(back[0])
        probs.error(
            file,
            "time",
            "strictly increasing times",
            f"{float(t_file[i])!r} {raw.time_unit} then {float(t_file[i + 1])!r} {raw.time_unit} "
            f"at {raw.locate(i + 1)}",
        )
        return None
    time = to_si(t_file, time_unit)
    if meta.read.start is not None:
        raw = _drop_before(raw, time, meta, probs)
        if raw is None:
            return None
        time = time[time >= meta.read.start]
    if meta.read.max_rate is not None:
        raw, time = _thinned(raw, time, meta.read.max_rate)
    elif (dt := median_interval(time)) is not None and 1.0 / dt > FAST_RATE:
        rate = 1.0 / dt
        probs.warning(
            file, "time",
            f"a rate of at most {FAST_RATE / 1e3:g} kHz for the fits, or max_rate in [read] "
            "(a fit's simulations step through every sample: their cost grows with the rate, "
            "and the models' dynamics need no more)",
            f"{rate:.4g} Hz, {rate / 1e3:.3g} times a 1-kHz recording's cost; "
            f'max_rate = "1 kHz" keeps one sample in {_thinning(rate, 1e3)}',
        )  # fmt: skip

    channels: dict[str, NDArray[np.float64]] = {}
    masks: dict[str, NDArray[np.bool_]] = {}
    units: dict[str, str] = {}
    unknown: list[str] = []
    for col in raw.columns:
        name = col.channel
        kind = CHANNELS.get(name)
        if kind is None:
            unknown.append(name)
            probs.warning(
                file,
                name,
                f"a channel of the format ({', '.join(CHANNELS)})",
                f'unknown channel "{name}" (kept, not used)',
            )
        if not col.ok:
            continue
        if col.values.size != time.size:
            probs.error(
                file, name, f"{time.size} samples, like /time", f"{col.values.size} samples"
            )
            continue
        try:
            unit = parse_unit(col.unit_text, kind)
            if col.gauge_attr and not unit.gauge:
                unit = parse_unit(f"{col.unit_text} (gauge)", kind)
        except UnitError as exc:
            probs.error(file, name, exc.expected, exc.found)
            continue
        real = col.mask
        bad = np.flatnonzero(real & ~np.isfinite(col.values))
        if bad.size:
            more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
            probs.error(
                file,
                name,
                "finite numbers",
                f"{float(col.values[bad[0]])!r} at {raw.locate(int(bad[0]))}{more}",
            )
            continue
        n_real = int(real.sum())
        if n_real == 0:
            probs.error(file, name, "at least one sample", "only empty cells")
            continue
        if name in INPUT_CHANNELS and n_real < 2:
            probs.error(
                file,
                name,
                "at least 2 samples (an input is interpolated between samples)",
                "a single sample",
            )
            continue
        if unit.gauge and exhaust is None and meta.exhaust_reported:
            continue  # converting needs the exhaust pressure, already reported as wrong
        try:
            si = to_si(col.values[real], unit, exhaust_pressure=exhaust)
        except UnitError as exc:
            probs.error(file, name, exc.expected, exc.found)
            continue
        low = int(np.argmin(si))
        where = raw.locate(int(np.flatnonzero(real)[low]))
        shown = f"{float(col.values[real][low])!r} {unit.text}"
        if QUANTITY_KINDS["pressure"].matches(unit.unit) and si[low] < 0.0:
            probs.error(
                file,
                name,
                "a pressure >= 0 Pa absolute",
                f"{shown} (= {si[low]:.6g} Pa absolute) at {where}",
            )
            continue
        if QUANTITY_KINDS["temperature"].matches(unit.unit) and si[low] <= 0.0:
            probs.error(
                file,
                name,
                "a temperature above absolute zero",
                f"{shown} (= {si[low]:.6g} K) at {where}",
            )
            continue
        channels[name] = si if real.all() else np.interp(time, time[real], si)
        masks[name] = real.copy()
        units[name] = unit.text

    derived: list[str] = []
    if meta.kind in _OPEN_KINDS:
        for source, target in (("u_P", "u_N"), ("u_N", "u_P")):
            if source in channels and target not in raw.present:
                channels[target] = -channels[source]
                masks[target] = masks[source].copy()
                units[target] = units[source]
                derived.append(target)
    if meta.kind is not None:
        available = raw.present | set(derived)
        listed = ", ".join(sorted(raw.present)) or "none"
        for name in required_channels(meta.kind, meta.chamber, meta.controller_declared):
            if name not in available:
                probs.error(
                    file,
                    name,
                    f"a channel {name} ({_needed_why(meta)})",
                    f"no such channel (channels: {listed})",
                )
    return Recording(
        file=meta.file,
        path=path,
        kind=meta.kind or "",
        role=meta.role,
        chamber=meta.chamber,
        piston_position=meta.piston_position,
        controller=meta.controller,
        time=time,
        channels=channels,
        mask=masks,
        units=units,
        unknown_channels=unknown,
        description=meta.description if meta.description is not None else raw.description or "",
        time_unit=time_unit.text,
        columns=dict(meta.columns),
        derived=derived,
    )


def _load_recording(
    folder: Path, meta: _Meta, exhaust: float | None, probs: _Problems, sha: dict[str, str]
) -> Recording | None:
    path = folder / meta.file
    if not path.is_file():
        probs.error(
            meta.file,
            "",
            f"the recording listed as recording[{meta.index}] in {meta.columns_file}",
            f"no such file in {folder}",
        )
        return None
    suffix = path.suffix.lower()
    if suffix not in HDF5_SUFFIXES + CSV_SUFFIXES:
        probs.error(
            meta.file, "", "an HDF5 (.h5, .hdf5) or CSV (.csv) recording", f'a "{path.suffix}" file'
        )
        return None
    data = path.read_bytes()
    sha[meta.file] = hashlib.sha256(data).hexdigest()
    if not data:
        probs.error(meta.file, "", "a recording with samples", "an empty file (0 bytes)")
        return None
    default = _ReadSpec()
    set_keys = [k for k in _CSV_ONLY_KEYS if getattr(meta.read, k) != getattr(default, k)]
    if suffix in HDF5_SUFFIXES and set_keys:
        probs.warning(
            meta.columns_file,
            next((meta.read.keys[k] for k in _CSV_ONLY_KEYS if k in meta.read.keys), "read"),
            f"{', '.join(_CSV_ONLY_KEYS)} for CSV files only "
            "(HDF5 names its datasets and stores numbers)",
            f"a read table for {meta.file} (ignored)",
        )
        for key in set_keys:
            setattr(meta.read, key, getattr(default, key))
    if not meta.read.ok:
        return None  # its read table has an error, already reported
    reader = _read_hdf5 if suffix in HDF5_SUFFIXES else _read_csv
    raw = reader(data, meta, probs)
    if raw is None:
        return None
    return _build_recording(raw, meta, path, exhaust, probs)


# --------------------------------------------------------------------------- public API


def inspect_campaign(path: str | os.PathLike[str]) -> CampaignReport:
    """Read a campaign, collecting every problem instead of stopping at the first.

    Never raises on bad input: an unexpected exception while reading a file
    becomes a problem naming that file. Files are only read.

    Parameters
    ----------
    path : str or os.PathLike
        Campaign folder, or its campaign.toml.

    Returns
    -------
    CampaignReport
        The campaign (None when there is any error), the recordings that could
        be read and every problem found.
    """
    probs = _Problems()
    given = Path(path)
    folder, toml_path = (given.parent, given) if given.is_file() else (given, given / CAMPAIGN_FILE)
    report = CampaignReport(path=folder, problems=probs.items)
    if not folder.is_dir():
        probs.error(
            str(given), "", f"a campaign folder containing {CAMPAIGN_FILE}", "no such folder"
        )
        return report
    if given.is_file() and given.suffix.lower() != ".toml":
        # a recording given where its campaign is expected: say what to write
        probs.error(
            str(given), "", f"a campaign folder or its {CAMPAIGN_FILE} (a recording is read "
            f"through the {CAMPAIGN_FILE} that names it; docs/campaign-format.md)",
            f"a {given.suffix or 'data'} file",
        )  # fmt: skip
        return report
    if not toml_path.is_file():
        data = sorted(
            f.name
            for f in folder.iterdir()
            if f.is_file() and f.suffix.lower() in HDF5_SUFFIXES + CSV_SUFFIXES
        )
        found = "no such file"
        if data:
            shown = ", ".join(data[:3]) + (f" and {len(data) - 3} more" if len(data) > 3 else "")
            found += (
                f", but {len(data)} data file{'s' if len(data) > 1 else ''} ({shown}): write a "
                f"{CAMPAIGN_FILE} that names them, their kind, role and rig "
                "(docs/campaign-format.md; data/measured/NAP310/campaign.toml is one for "
                "a bench's CSV exports)"
            )
        probs.error(CAMPAIGN_FILE, "", f"a {CAMPAIGN_FILE} in {folder}", found)
        return report
    toml_name = toml_path.name
    sha: dict[str, str] = {}
    try:
        doc = _read_toml(toml_path, probs, sha)
        if doc is None:
            return report
        name, description = _parse_header(doc, folder.name, toml_name, probs)
        rig, rig_values = _parse_rig(doc, toml_name, probs, _friction_only(doc))
        metas = _parse_entries(doc, rig_values.get("stroke"), toml_name, probs)
    except Exception as exc:  # the boundary: report, never raise
        probs.error(toml_name, "", "a readable campaign description", _unexpected(exc))
        return report
    exhaust = rig_values.get("exhaust_pressure")
    for meta in metas:
        meta.columns_file = toml_name
        meta.exhaust_reported = exhaust is None
        try:
            recording = _load_recording(folder, meta, exhaust, probs, sha)
        except Exception as exc:  # the boundary: report, never raise
            probs.error(meta.file, "", "a readable recording", _unexpected(exc))
            continue
        if recording is not None:
            report.recordings.append(recording)
            _check_consistency(recording, rig_values, probs)
    if rig is not None and probs.n_errors == 0:
        report.campaign = Campaign(
            path=folder,
            name=name,
            description=description,
            rig=rig,
            recordings=list(report.recordings),
            sha256=sha,
            warnings=report.warnings,
        )
    return report


def _check_consistency(recording: Recording, rig_values: dict[str, Any], probs: _Problems) -> None:
    """Warnings when the recording disagrees with the declared rig or
    controller: its measured supply pressure, a chamber the piston does not
    compress, its position, its commands
    (:func:`pneumafit.campaign.consistency.recording_findings`)."""
    supply, exhaust = rig_values.get("supply_pressure"), rig_values.get("exhaust_pressure")
    if supply is None or exhaust is None:
        return
    stroke = rig_values.get("stroke")
    found = recording_findings(
        recording, float(supply), float(exhaust), None if stroke is None else float(stroke)
    )
    for name, expected, text in found:
        probs.warning(recording.file, name, expected, text)


def validate_campaign(path: str | os.PathLike[str]) -> list[Problem]:
    """Every problem (errors and warnings) of a campaign; empty when all is well.

    Parameters
    ----------
    path : str or os.PathLike
        Campaign folder, or its campaign.toml.

    Returns
    -------
    list of Problem
        In the order found: campaign.toml first, then each recording.
    """
    return inspect_campaign(path).problems


def read_campaign(path: str | os.PathLike[str]) -> Campaign:
    """Read and validate a campaign.

    Parameters
    ----------
    path : str or os.PathLike
        Campaign folder, or its campaign.toml.

    Returns
    -------
    Campaign
        All values in SI units; warnings in ``Campaign.warnings``.

    Raises
    ------
    CampaignError
        The campaign has at least one error; ``.problems`` lists them all.
    """
    report = inspect_campaign(path)
    if report.campaign is None:
        raise CampaignError(str(path), report.problems)
    return report.campaign


def read_recording(
    path: str | os.PathLike[str],
    *,
    kind: str,
    role: str = "fit",
    chamber: str | None = None,
    piston_position: float | None = None,
    controller: PDController | None = None,
    columns: dict[str, str] | None = None,
    exhaust_pressure: float | None = None,
    description: str | None = None,
) -> Recording:
    """Read one recording file outside a campaign.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.h5``/``.hdf5`` or ``.csv`` recording.
    kind : str
        ``charge``, ``discharge``, ``flow``, ``step`` or ``free``; decides the
        channels required.
    role : str, default "fit"
        ``fit`` or ``validate``.
    chamber : str, optional
        ``"P"`` or ``"N"``, for charge, discharge and flow tests.
    piston_position : float, optional
        Blocked piston position [m].
    controller : PDController, optional
        Controller of a step test.
    columns : dict of str to str, optional
        File column -> channel name, as ``[recording.columns]``.
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute]; needed only for gauge channels.
    description : str, optional
        Overrides the file's own description.

    Returns
    -------
    Recording
        Values in SI units.

    Raises
    ------
    PneumafitInputError
        Bad arguments.
    CampaignError
        The file has at least one error.
    """
    if kind not in KINDS:
        raise PneumafitInputError(f"kind: expected one of {', '.join(KINDS)}, found {kind!r}")
    if role not in ROLES:
        raise PneumafitInputError(f"role: expected fit or validate, found {role!r}")
    if chamber is not None and chamber not in CHAMBERS:
        raise PneumafitInputError(f"chamber: expected P or N, found {chamber!r}")
    given = Path(path)
    unknown_targets = sorted(set((columns or {}).values()) - set(CHANNELS))
    if unknown_targets:
        raise PneumafitInputError(
            f"columns: expected channel names ({', '.join(CHANNELS)}), found {unknown_targets}"
        )
    meta = _Meta(
        index=1,
        file=given.name,
        kind=kind,
        role=role,
        chamber=chamber,
        piston_position=piston_position,
        controller=controller,
        controller_declared=controller is not None,
        columns=dict(columns or {}),
        description=description,
        columns_file=given.name,
        columns_key="columns",
    )
    probs = _Problems()
    try:
        recording = _load_recording(given.parent, meta, exhaust_pressure, probs, {})
    except Exception as exc:  # the boundary: report in the user's words
        probs.error(given.name, "", "a readable recording", _unexpected(exc))
        recording = None
    if recording is None or probs.n_errors:
        raise CampaignError(str(given), probs.items)
    return recording


def _setup_text(recording: Recording) -> str:
    if recording.kind in _CHAMBER_KINDS:
        text = f"chamber {recording.chamber}"
        if recording.piston_position is not None:
            text += f", piston at {recording.piston_position * 1e3:.6g} mm"
        return text
    if recording.controller is not None:
        return str(recording.controller)
    if recording.kind == "friction":
        return "imposed motion (friction test)"
    return "open loop (measured commands)"


def summarize(campaign: Campaign | Iterable[Recording]) -> list[dict[str, Any]]:
    """One row per recording, for the ``check`` command.

    Parameters
    ----------
    campaign : Campaign or iterable of Recording
        A campaign, or recordings (e.g. ``CampaignReport.recordings``).

    Returns
    -------
    list of dict
        Keys: ``file``, ``kind``, ``role``, ``duration_s`` [s],
        ``sample_rate_Hz`` [Hz], ``n_samples``, ``channels`` (channel -> unit
        as found in the file, or ``"derived: -u_P"``), ``setup`` (chamber and
        piston position, or controller, or ``"open loop"``).
    """
    recordings = campaign.recordings if isinstance(campaign, Campaign) else list(campaign)
    rows = []
    for rec in recordings:
        channels = {}
        for name in rec.channels:
            if name in rec.derived:
                source = "u_N" if name == "u_P" else "u_P"
                channels[name] = f"derived: -{source}"
            else:
                channels[name] = rec.units.get(name, "")
        rows.append(
            {
                "file": rec.file,
                "kind": rec.kind,
                "role": rec.role,
                "duration_s": rec.duration,
                "sample_rate_Hz": rec.sample_rate,
                "n_samples": rec.n_samples,
                "channels": channels,
                "setup": _setup_text(rec),
            }
        )
    return rows
