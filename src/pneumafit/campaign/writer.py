"""Write recordings and campaigns in campaign format version 1.

Every file is written atomically: to a temporary file in the target folder,
then moved over the target with :func:`os.replace`, so a reader never sees a
half-written file. Floats are written with ``repr`` precision (shortest text
that reads back to the same float64), so CSV files round-trip exactly up to
the unit conversion.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path, PurePosixPath
from typing import Literal

import h5py
import numpy as np

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import CHANNELS, Campaign, Recording
from pneumafit.campaign.reader import (
    CAMPAIGN_FILE,
    CAMPAIGN_FORMAT,
    CSV_SUFFIXES,
    FORMAT_VERSION,
    HDF5_SUFFIXES,
    RECORDING_FORMAT,
)
from pneumafit.campaign.units import (
    QUANTITY_KINDS,
    ParsedUnit,
    UnitError,
    format_value,
    from_si,
    parse_unit,
    split_header,
)
from pneumafit.fileio import atomic_path, write_text_atomic

__all__ = ["write_campaign", "write_recording_csv", "write_recording_h5"]

_RIG_KINDS = {
    "bore": "length",
    "rod": "length",
    "stroke": "length",
    "dead_volume_P": "volume",
    "dead_volume_N": "volume",
    "moving_mass": "mass",
    "supply_pressure": "pressure",
    "exhaust_pressure": "pressure",
    "ambient_temperature": "temperature",
    "wall_temperature": "temperature",
    "characteristic_length": "length",
    "mounting_angle": "angle",
    "external_force": "force",
}


def _unit_for(name: str, text: str | None) -> ParsedUnit:
    """The unit to write channel ``name`` in (SI when ``text`` is None)."""
    kind = "time" if name == "time" else CHANNELS.get(name)
    if text is None:
        text = QUANTITY_KINDS[kind].si_unit if kind is not None else ""
    try:
        return parse_unit(text, kind)
    except UnitError as exc:
        raise PneumafitInputError(f"units[{name!r}]: {exc}") from None


def _channels_to_write(recording: Recording) -> list[str]:
    return [name for name in recording.channels if name not in recording.derived]


def write_recording_h5(
    path: str | os.PathLike[str],
    recording: Recording,
    units: Mapping[str, str] | None = None,
    *,
    exhaust_pressure: float | None = None,
) -> Path:
    """Write one recording as HDF5 (format ``pneumatic-recording`` version 1).

    HDF5 has no notion of "not sampled": every channel is written at every
    time, with interpolated values where ``recording.mask`` is False.

    Parameters
    ----------
    path : str or os.PathLike
        Target file (``.h5``); replaced atomically.
    recording : Recording
        Values in SI units.
    units : mapping of str to str, optional
        Channel (or ``"time"``) -> unit to write, e.g. ``{"p_P": "bar",
        "time": "ms"}``. A gauge unit (``"barg"``) is written as the plain unit
        with attribute ``reference = "gauge"``. Default SI.
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute]; required for gauge units.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    target = Path(path)
    units = dict(units or {})
    time_unit = _unit_for("time", units.get("time"))
    with atomic_path(target) as tmp, h5py.File(tmp, "w") as handle:
        handle.attrs["format"] = RECORDING_FORMAT
        handle.attrs["version"] = FORMAT_VERSION
        handle.attrs["kind"] = recording.kind
        handle.attrs["description"] = recording.description
        dataset = handle.create_dataset("time", data=from_si(recording.time, time_unit))
        dataset.attrs["unit"] = time_unit.plain_text
        group = handle.create_group("channels")
        for name in _channels_to_write(recording):
            unit = _unit_for(name, units.get(name))
            values = from_si(recording.channels[name], unit, exhaust_pressure=exhaust_pressure)
            dataset = group.create_dataset(name, data=values)
            dataset.attrs["unit"] = unit.plain_text
            if unit.gauge:
                dataset.attrs["reference"] = "gauge"
    return target


_BAD_COLUMN = re.compile(r'[\[\],"\r\n]')


def write_recording_csv(
    path: str | os.PathLike[str],
    recording: Recording,
    units: Mapping[str, str] | None = None,
    columns: Mapping[str, str] | None = None,
    comments: str | Sequence[str] | None = None,
    *,
    exhaust_pressure: float | None = None,
) -> Path:
    """Write one recording as CSV: ``# comments``, a ``name [unit]`` header, rows.

    Where ``recording.mask`` is False the cell is left empty (not sampled).
    Numbers are written with ``repr`` precision.

    Parameters
    ----------
    path : str or os.PathLike
        Target file (``.csv``); replaced atomically.
    recording : Recording
        Values in SI units.
    units : mapping of str to str, optional
        Channel (or ``"time"``) -> unit to write, e.g. ``{"y": "mm", "p_P":
        "barg", "T_P": "degC", "time": "ms"}``. Default SI.
    columns : mapping of str to str, optional
        Channel -> the file's own column name, e.g. ``{"y": "Pos"}`` gives
        the header ``Pos [mm]``. Reading it back needs the reverse mapping in
        ``[recording.columns]``.
    comments : str or sequence of str, optional
        Leading comment lines (without ``#``); default the recording's
        description.
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute]; required for gauge units.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    target = Path(path)
    units = dict(units or {})
    columns = dict(columns or {})
    if comments is None:
        comments = recording.description
    lines = comments.splitlines() if isinstance(comments, str) else list(comments)
    out = [f"# {line}".rstrip() + "\n" for line in lines]

    time_unit = _unit_for("time", units.get("time"))
    header = [f"time [{time_unit.text}]"]
    cells = [[repr(x) for x in from_si(recording.time, time_unit).tolist()]]
    for name in _channels_to_write(recording):
        column = columns.get(name, name)
        if not column.strip() or _BAD_COLUMN.search(column):
            raise PneumafitInputError(
                f"columns[{name!r}]: expected a name without brackets, commas, quotes or "
                f"line breaks, found {column!r}"
            )
        unit = _unit_for(name, units.get(name))
        values = from_si(recording.channels[name], unit, exhaust_pressure=exhaust_pressure)
        text = [repr(x) for x in values.tolist()]
        for i in np.flatnonzero(~recording.mask.get(name, np.ones(len(text), bool))):
            text[i] = ""
        header.append(f"{column} [{unit.text}]")
        cells.append(text)
    out.append(",".join(header) + "\n")
    out.extend(",".join(row) + "\n" for row in zip(*cells, strict=True))
    write_text_atomic(target, "".join(out))
    return target


def _toml_string(text: str) -> str:
    """A TOML basic string (escapes quotes, backslashes and control characters)."""
    escaped = []
    for char in text:
        if char in '"\\':
            escaped.append("\\" + char)
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            escaped.append({"\n": "\\n", "\t": "\\t", "\r": "\\r"}.get(char, f"\\u{ord(char):04X}"))
        else:
            escaped.append(char)
    return '"' + "".join(escaped) + '"'


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _toml_string(key)


def _campaign_toml(campaign: Campaign, files: list[str], csv_columns: list[dict[str, str]]) -> str:
    out = [
        f"format = {_toml_string(CAMPAIGN_FORMAT)}",
        f"version = {FORMAT_VERSION}",
        f"name = {_toml_string(campaign.name)}",
        f"description = {_toml_string(campaign.description)}",
        "",
        "[rig]",
    ]
    if campaign.rig.acting != "double":
        out.append(f"acting = {_toml_string(campaign.rig.acting)}")
    for key, value in campaign.rig.as_parameters().items():
        if math.isnan(value):  # not given (a friction-only campaign)
            continue
        out.append(f"{key} = {_toml_string(format_value(value, _RIG_KINDS[key]))}")
    for rec, file, columns in zip(campaign.recordings, files, csv_columns, strict=True):
        out += ["", "[[recording]]", f"file = {_toml_string(file)}"]
        out += [f"kind = {_toml_string(rec.kind)}", f"role = {_toml_string(rec.role)}"]
        if rec.chamber is not None:
            out.append(f"chamber = {_toml_string(rec.chamber)}")
        if rec.piston_position is not None:
            out.append(
                f"piston_position = {_toml_string(format_value(rec.piston_position, 'length'))}"
            )
        if rec.description:
            out.append(f"description = {_toml_string(rec.description)}")
        if rec.controller is not None:
            c = rec.controller
            out += ["[recording.controller]", f"law = {_toml_string(c.law)}"]
            out += [
                f'kp = "{c.kp!r} V/m"',
                f'kd = "{c.kd!r} V s/m"',
                f'u0 = "{c.u0!r} V"',
                f'umax = "{c.umax!r} V"',
            ]
        if columns:
            out.append("[recording.columns]")
            out += [f"{_toml_key(k)} = {_toml_string(v)}" for k, v in columns.items()]
    return "\n".join(out) + "\n"


def write_campaign(
    path: str | os.PathLike[str],
    campaign: Campaign,
    formats: Literal["h5", "csv"] | None = None,
) -> Path:
    """Write a campaign folder: every recording, then campaign.toml.

    Rig values are written as exact SI strings (``"0.032 m"``). Each recording
    is written in the units of ``Recording.units`` (its file units when it was
    read, SI when built with :meth:`Recording.from_arrays` without units);
    CSV files keep their own column names (``Recording.columns``).

    Parameters
    ----------
    path : str or os.PathLike
        Campaign folder; created if needed. Existing files of the same names
        are replaced atomically; other files are left alone.
    campaign : Campaign
        The campaign to write.
    formats : {"h5", "csv"}, optional
        Write every recording in this format (changing the file suffix).
        Default: keep each recording's suffix; a recording with no file name
        is written as ``<kind>_<n>.h5``.

    Returns
    -------
    pathlib.Path
        The campaign.toml written.

    Raises
    ------
    PneumafitInputError
        Two recordings with the same file name, an unknown suffix or format,
        or a unit that does not fit its channel.
    """
    if formats not in (None, "h5", "csv"):
        raise PneumafitInputError(f"formats: expected 'h5', 'csv' or None, found {formats!r}")
    folder = Path(path)
    folder.mkdir(parents=True, exist_ok=True)
    exhaust = campaign.rig.exhaust_pressure
    files: list[str] = []
    csv_columns: list[dict[str, str]] = []
    for index, rec in enumerate(campaign.recordings, start=1):
        file = rec.file or f"{rec.kind}_{index}.h5"
        if formats is not None:
            file = str(PurePosixPath(file).with_suffix(f".{formats}"))
        if file in files:
            raise PneumafitInputError(f"recording {index}: file name {file!r} is used twice")
        files.append(file)
        units = {**rec.units, "time": rec.time_unit}
        suffix = PurePosixPath(file).suffix.lower()
        if suffix in CSV_SUFFIXES:
            names = {}
            for column, channel in rec.columns.items():
                parsed = split_header(column)
                names[channel] = parsed[0] if parsed else column.strip()
            names = {ch: col for ch, col in names.items() if ch in rec.channels}
            write_recording_csv(folder / file, rec, units, names, exhaust_pressure=exhaust)
            csv_columns.append({col: ch for ch, col in names.items()})
        elif suffix in HDF5_SUFFIXES:
            write_recording_h5(folder / file, rec, units, exhaust_pressure=exhaust)
            csv_columns.append({})
        else:
            raise PneumafitInputError(
                f"recording {index}: expected a .h5, .hdf5 or .csv file name, found {file!r}"
            )
    target = folder / CAMPAIGN_FILE
    write_text_atomic(target, _campaign_toml(campaign, files, csv_columns))
    return target
