"""Typed, SI-only objects for a campaign: rig, controller, recordings.

Every value held here is an SI float: m, m^3, kg, Pa (absolute), K, rad, N,
s, V, kg/s. Files and their units are dealt with in :mod:`.reader` and
:mod:`.writer`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.campaign.errors import Problem
from pneumafit.errors import PneumafitInputError

__all__ = [
    "CHAMBERS",
    "CHANNELS",
    "INPUT_CHANNELS",
    "KINDS",
    "ROLES",
    "Campaign",
    "PDController",
    "Recording",
    "Rig",
    "required_channels",
]

#: Recording kinds of the format.
KINDS: tuple[str, ...] = ("charge", "discharge", "flow", "step", "free", "friction")
#: Roles: ``fit`` recordings are fitted, ``validate`` ones are held out.
ROLES: tuple[str, ...] = ("fit", "validate")
#: Chamber names: P is the full-bore side, N the rod side.
CHAMBERS: tuple[str, ...] = ("P", "N")
#: Canonical channels and the kind of quantity each holds.
CHANNELS: dict[str, str] = {
    "u_P": "voltage",
    "u_N": "voltage",
    "p_P": "pressure",
    "p_N": "pressure",
    "p_S": "pressure",
    "T_P": "temperature",
    "T_N": "temperature",
    "y": "length",
    "v": "velocity",
    "qm_P": "mass flow",
    "qm_N": "mass flow",
    "y_ref": "length",
    "F": "force",
}
#: Channels that drive a simulation; they need at least two real samples.
INPUT_CHANNELS: tuple[str, ...] = ("u_P", "u_N", "y_ref")

_SI_UNITS = {
    "voltage": "V",
    "pressure": "Pa",
    "temperature": "K",
    "length": "m",
    "velocity": "m/s",
    "mass flow": "kg/s",
    "force": "N",
}


def required_channels(kind: str, chamber: str | None, has_controller: bool) -> tuple[str, ...]:
    """Channels a recording of ``kind`` must carry.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    chamber : str or None
        ``"P"`` or ``"N"`` for charge, discharge and flow tests.
    has_controller : bool
        Whether the recording declares a controller (step tests).

    Returns
    -------
    tuple of str
        Channel names; empty when ``kind``/``chamber`` is not valid.
    """
    if kind in ("charge", "discharge"):
        return (f"p_{chamber}", f"u_{chamber}") if chamber in CHAMBERS else ()
    if kind == "flow":
        return (f"u_{chamber}", f"p_{chamber}", f"qm_{chamber}") if chamber in CHAMBERS else ()
    if kind == "step" and has_controller:
        return ("y", "y_ref", "p_P", "p_N")
    if kind in ("step", "free"):
        return ("y", "u_P", "u_N")
    if kind == "friction":
        return ("y", "p_P", "F")
    return ()


@dataclass(frozen=True)
class Rig:
    """The actuator and its surroundings, in SI units.

    Parameters
    ----------
    bore : float
        Piston diameter [m]; chamber P area is pi bore^2 / 4.
    rod : float
        Rod diameter [m]; chamber N area is pi (bore^2 - rod^2) / 4.
    stroke : float
        Stroke [m]; the position y runs from 0 (retracted) to stroke.
    dead_volume_P, dead_volume_N : float
        Dead volumes of chambers P and N [m^3].
    moving_mass : float
        Mass of piston, rod and load [kg].
    supply_pressure, exhaust_pressure : float
        Supply and exhaust pressures [Pa absolute].
    ambient_temperature : float
        Ambient (and supply gas) temperature [K].
    wall_temperature : float
        Chamber wall temperature [K]; the reader defaults it to ambient.
    characteristic_length : float
        Length scale of the heat-transfer law [m]; the reader defaults it to
        the bore.
    mounting_angle : float, default 0
        Angle of the rod axis above horizontal [rad].
    external_force : float, default 0
        Constant external force on the rod, positive extending [N].

    Attributes
    ----------
    acting : {"double", "single"}
        ``"single"``: only chamber P is pressurised, the rod side is open to
        the atmosphere (a single-acting cylinder, e.g. a friction-test bench).
        Not a dataclass field (code that rebuilds a rig from its numeric
        fields stays valid): set it with :meth:`with_acting`; default
        ``"double"``.

    Notes
    -----
    In a campaign whose recordings are all friction tests (kind
    ``friction``), only ``bore``, ``exhaust_pressure`` and
    ``ambient_temperature`` are required; a value not given is NaN ("not
    known") and nothing in a friction test uses it.
    """

    bore: float
    rod: float
    stroke: float
    dead_volume_P: float
    dead_volume_N: float
    moving_mass: float
    supply_pressure: float
    exhaust_pressure: float
    ambient_temperature: float
    wall_temperature: float
    characteristic_length: float
    mounting_angle: float = 0.0
    external_force: float = 0.0
    acting: ClassVar[str] = "double"

    def with_acting(self, acting: str) -> Rig:
        """A copy of this rig that is ``"single"`` or ``"double"`` acting."""
        if acting not in ("double", "single"):
            raise PneumafitInputError(f"acting: expected double or single, found {acting!r}")
        out = replace(self)
        object.__setattr__(out, "acting", acting)
        return out

    def as_parameters(self) -> dict[str, float]:
        """All numeric fields as ``{name: SI value}`` (NaN: not given)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True)
class PDController:
    """Position controller that produced the commands of a step test.

    ``u_P = clip(u0 + kp (y_ref - y) - kd v, -umax, umax)`` and ``u_N = -u_P``.

    Parameters
    ----------
    kp : float
        Proportional gain [V/m].
    kd : float
        Derivative gain [V s/m].
    u0 : float
        Command offset [V].
    umax : float
        Command saturation [V], positive.
    law : str, default "pd"
        Control law name; only ``"pd"`` exists in format version 1.
    """

    kp: float
    kd: float
    u0: float
    umax: float
    law: str = "pd"

    def __str__(self) -> str:
        return (
            f"{self.law}: kp={self.kp:g} V/m, kd={self.kd:g} V s/m, "
            f"u0={self.u0:g} V, umax={self.umax:g} V"
        )


def _float_array(values: ArrayLike, what: str) -> NDArray[np.float64]:
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise PneumafitInputError(f"{what}: expected numbers, found {exc}") from None
    if array.ndim != 1:
        raise PneumafitInputError(f"{what}: expected a 1-D array, found shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise PneumafitInputError(f"{what}: expected finite values, found NaN or infinity")
    return array


@dataclass(eq=False)
class Recording:
    """One test: time, channels in SI units, and how the test was run.

    Parameters
    ----------
    file : str
        File name as written in campaign.toml (relative to the campaign).
    path : pathlib.Path or None
        Resolved path of the file; None for a recording made in memory.
    kind : str
        ``charge``, ``discharge``, ``flow``, ``step``, ``free`` or ``friction``
        (imposed-motion friction test: ``y``, ``p_P`` and the rod force ``F``).
    role : str
        ``fit`` or ``validate`` (held out from fitting).
    chamber : str or None
        ``"P"`` or ``"N"`` for charge, discharge and flow tests.
    piston_position : float or None
        Blocked piston position [m] for charge and discharge tests.
    controller : PDController or None
        Controller of a closed-loop step test.
    time : numpy.ndarray
        Sample times [s], float64, strictly increasing.
    channels : dict of str to numpy.ndarray
        Canonical channel name -> float64 SI values, each as long as ``time``.
        Where a channel was not sampled (``mask`` False) the value is linearly
        interpolated between real samples and held at the ends.
    mask : dict of str to numpy.ndarray
        Channel -> bool array, True where the channel was really sampled.
    units : dict of str to str
        Channel -> unit string as found in the file (e.g. ``"bar"``,
        ``"barg"``, ``"bar (gauge)"``), for reporting and for writing back.
    unknown_channels : list of str
        Channels not in the format's table; kept in ``channels``.
    description : str, default ""
        Free text.
    time_unit : str, default "s"
        Unit of the time column as found in the file.
    columns : dict of str to str
        The ``[recording.columns]`` mapping: file column -> channel name.
    derived : list of str
        Channels computed rather than read (``u_N = -u_P`` on a single-input
        rig); writers leave them out.
    """

    file: str
    path: Path | None
    kind: str
    role: str
    chamber: str | None
    piston_position: float | None
    controller: PDController | None
    time: NDArray[np.float64]
    channels: dict[str, NDArray[np.float64]]
    mask: dict[str, NDArray[np.bool_]]
    units: dict[str, str]
    unknown_channels: list[str]
    description: str = ""
    time_unit: str = "s"
    columns: dict[str, str] = field(default_factory=dict)
    derived: list[str] = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    @property
    def duration(self) -> float:
        """Time from first to last sample [s]."""
        return float(self.time[-1] - self.time[0]) if self.time.size else 0.0

    @property
    def sample_rate(self) -> float:
        """Median of 1/dt over the recording [Hz]; NaN with fewer than 2 samples."""
        if self.time.size < 2:
            return float("nan")
        return float(np.median(1.0 / np.diff(self.time)))

    @classmethod
    def from_arrays(
        cls,
        time: ArrayLike,
        channels: Mapping[str, ArrayLike],
        *,
        kind: str,
        role: str = "fit",
        file: str = "",
        chamber: str | None = None,
        piston_position: float | None = None,
        controller: PDController | None = None,
        mask: Mapping[str, ArrayLike] | None = None,
        units: Mapping[str, str] | None = None,
        columns: Mapping[str, str] | None = None,
        description: str = "",
    ) -> Recording:
        """Build a recording from SI arrays, e.g. in a virtual rig.

        Parameters
        ----------
        time : array_like
            Sample times [s], strictly increasing, at least 2.
        channels : mapping of str to array_like
            Channel name -> SI values (Pa absolute, K, m, V, m/s, kg/s), each
            as long as ``time``.
        kind, role, file, chamber, piston_position, controller, description
            As the attributes of :class:`Recording`; ``piston_position`` in m.
        mask : mapping of str to array_like, optional
            Channel -> bool array, True where really sampled. Values where the
            mask is False are replaced by interpolation. Default all True.
        units : mapping of str to str, optional
            Channel -> preferred file unit (used when writing a campaign).
            Default: SI units.
        columns : mapping of str to str, optional
            The file's own column name -> channel name, written to CSV headers
            and to ``[recording.columns]`` in campaign.toml.

        Returns
        -------
        Recording
            With ``path`` None.

        Raises
        ------
        PneumafitInputError
            Unknown kind, role or chamber, arrays of unequal length, NaN,
            time not strictly increasing, or a channel never sampled.
        """
        for value, allowed, what in ((kind, KINDS, "kind"), (role, ROLES, "role")):
            if value not in allowed:
                raise PneumafitInputError(
                    f"{what}: expected one of {', '.join(allowed)}, found {value!r}"
                )
        if chamber is not None and chamber not in CHAMBERS:
            raise PneumafitInputError(f"chamber: expected P or N, found {chamber!r}")
        t = _float_array(time, "time")
        if t.size < 2:
            raise PneumafitInputError(f"time: expected at least 2 samples, found {t.size}")
        if np.any(np.diff(t) <= 0.0):
            i = int(np.argmax(np.diff(t) <= 0.0))
            raise PneumafitInputError(
                f"time: expected strictly increasing values, found {t[i]:g} s followed by "
                f"{t[i + 1]:g} s (samples {i} and {i + 1})"
            )
        values: dict[str, NDArray[np.float64]] = {}
        masks: dict[str, NDArray[np.bool_]] = {}
        for name, data in channels.items():
            array = np.asarray(data, dtype=np.float64)
            m = np.ones(t.size, dtype=bool)
            if mask is not None and name in mask:
                m = np.asarray(mask[name], dtype=bool)
            if array.shape != t.shape or m.shape != t.shape:
                raise PneumafitInputError(
                    f"{name}: expected {t.size} samples like time, found shape "
                    f"{array.shape} (mask {m.shape})"
                )
            if not m.any():
                raise PneumafitInputError(f"{name}: expected at least one sample, found none")
            real = _float_array(array[m], name)
            values[name] = real if m.all() else np.interp(t, t[m], real)
            masks[name] = m
        file_units = {name: _SI_UNITS.get(CHANNELS.get(name, ""), "") for name in values}
        file_units.update({k: v for k, v in (units or {}).items() if k in values})
        return cls(
            file=file,
            path=None,
            kind=kind,
            role=role,
            chamber=chamber,
            piston_position=piston_position,
            controller=controller,
            time=t,
            channels=values,
            mask=masks,
            units=file_units,
            unknown_channels=[n for n in values if n not in CHANNELS],
            description=description,
            time_unit=(units or {}).get("time", "s"),
            columns=dict(columns or {}),
        )


@dataclass(eq=False)
class Campaign:
    """A rig and its recordings.

    Parameters
    ----------
    path : pathlib.Path or None
        Campaign folder; None for a campaign built in memory.
    name : str
        Campaign name.
    description : str
        Free text.
    rig : Rig
        The actuator.
    recordings : list of Recording
        In campaign.toml order.
    sha256 : dict of str to str
        File name (``campaign.toml`` and each recording, as written in
        campaign.toml) -> hex SHA-256 digest of the bytes that were read.
    warnings : list of Problem
        Warnings found while reading (unknown keys, unknown channels, ...).
    """

    path: Path | None
    name: str
    description: str
    rig: Rig
    recordings: list[Recording]
    sha256: dict[str, str] = field(default_factory=dict)
    warnings: list[Problem] = field(default_factory=list)

    def by_role(self, role: str) -> list[Recording]:
        """Recordings with ``role`` (``"fit"`` or ``"validate"``)."""
        return [r for r in self.recordings if r.role == role]

    def by_kind(self, kind: str) -> list[Recording]:
        """Recordings of ``kind`` (``"charge"``, ``"step"``, ...)."""
        return [r for r in self.recordings if r.kind == kind]

    def recording(self, file: str) -> Recording:
        """The recording stored in ``file`` (name as in campaign.toml).

        Raises
        ------
        KeyError
            No recording has that file name.
        """
        for rec in self.recordings:
            if rec.file == file:
                return rec
        names = ", ".join(r.file for r in self.recordings)
        raise KeyError(f"no recording {file!r} in campaign {self.name!r} (files: {names})")
