"""Every recording of a campaign simulated with each fit, saved for the report.

The comparison stage (:func:`~pneumafit.comparison.result.compare_fits`)
replays each fit on every recording with :func:`replay_model` and
:meth:`Comparison.save <pneumafit.comparison.result.Comparison.save>` writes
the traces to ``replays.npz`` beside comparison.json; the validation report
reads them (:func:`load_replays`) and simulates nothing
(``docs/report.md``). Each model's entry carries a fingerprint of the fit
it was simulated with (:func:`replay_fingerprint`: structure, parameters,
initial states, temperature probe) and the campaign's file hashes, so that a
report never shows the traces of another fit or campaign as this one's.

The replay is :func:`pneumafit.identification.replay.replay`, the one that
gives fit.json's metrics and the comparison's traces: the fit's parameters,
structure and fitted initial states, the reference solver, every sample.
Saved per recording: the channels the report compares
(:func:`compared_channels`, SI, every sample, temperatures through the
fit's temperature probe) and the air the test draws (mass supplied and exhausted,
kg; exergy, J).

File layout (NumPy ``.npz``, no pickled objects): ``meta`` holds a JSON
string (format ``pneumafit-replays``, version, campaign identity, per model
its name, structure, fingerprint, the probe's total lag, failed recordings with the
simulator's message, air per recording, and the array key of each
recording's channels); the arrays are named ``m<i>/<k>/<channel>``.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.errors import PneumafitInputError
from pneumafit.fileio import atomic_path
from pneumafit.simulation.sensor import TemperatureProbe

__all__ = [
    "COMPARED",
    "REPLAYS_FILE",
    "ModelReplay",
    "compared_channels",
    "load_replays",
    "replay_fingerprint",
    "replay_model",
    "save_replays",
    "sensor_lag",
    "temperature_probe",
]

#: The replays' file beside comparison.json.
REPLAYS_FILE = "replays.npz"
#: ``format`` of the file's metadata.
REPLAYS_FORMAT = "pneumafit-replays"
#: Version of that format.
REPLAYS_VERSION = 1
#: Measured channels compared with a simulation (a charge/discharge test is
#: compared on its own chamber only).
COMPARED = ("p_P", "p_N", "y", "qm_P", "qm_N")
#: Simulated channels a replay asks for (the masses give the air drawn).
SIMULATED = ("y", "p_P", "p_N", "qm_P", "qm_N", "T_P", "T_N", "m_supply", "m_exhaust")


def compared_channels(recording: Recording) -> list[str]:
    """Channels of a recording compared with the simulation.

    :data:`COMPARED` (a charge/discharge test only on its chamber's
    pressure) plus a measured gas temperature, less the imposed chamber
    pressure of a flow test.
    """
    names = []
    for name in (*COMPARED, "T_P", "T_N"):
        if name not in recording.channels:
            continue
        if recording.kind in ("charge", "discharge") and name in ("p_P", "p_N"):
            if name != "p_" + str(recording.chamber):
                continue
        if recording.kind == "flow" and name == "p_" + str(recording.chamber):
            continue  # the imposed chamber pressure of a flow test is an input
        names.append(name)
    return names


@dataclass
class ModelReplay:
    """Every recording of a campaign simulated with one fit.

    Attributes
    ----------
    model : str
        The fit's model name (its folder under ``fits/``).
    structure : str
        Structure name (heat law and effects).
    channels : dict of str to dict of str to ndarray
        Recording file -> channel -> simulated values at the recording's
        sample times (SI; temperatures through the fit's probe), for the
        channels the report compares. Missing for a failed simulation.
    failed : dict of str to str
        Recording file -> the simulator's message.
    air : dict of str to tuple of float
        Recording file -> (mass supplied kg, mass exhausted kg, exergy J).
    sensor_lag : float
        Total lag of the temperature probe applied (s; 0: none).
    fingerprint : str
        :func:`replay_fingerprint` of the fit simulated.
    """

    model: str
    structure: str
    channels: dict[str, dict[str, NDArray[np.float64]]] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    air: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    sensor_lag: float = 0.0
    fingerprint: str = ""


def temperature_probe(document: Mapping[str, Any]) -> TemperatureProbe | None:
    """The fit's temperature probe (``metrics.temperature_probe``, else the one
    lag ``metrics.temperature_sensor_lag``), None if it names none."""
    return TemperatureProbe.from_metrics(document.get("metrics"))


def sensor_lag(document: Mapping[str, Any]) -> float:
    """The fit's temperature probe's total lag (s; :func:`temperature_probe`), 0 if none."""
    probe = temperature_probe(document)
    return probe.total_lag if probe is not None else 0.0


def replay_fingerprint(document: Mapping[str, Any]) -> str:
    """SHA-256 of what a replay of this fit depends on.

    The structure, the parameters' values, the nuisance block (initial
    states, offsets) and the temperature probe of a parsed fit.json:
    the same fit written again (other formatting, another run folder) has
    the same fingerprint; a refit has another.
    """
    params = document.get("parameters") or {}
    probe = temperature_probe(document)
    values = {
        k: (v.get("value") if isinstance(v, Mapping) else v) for k, v in sorted(params.items())
    }
    key = {
        "structure": document.get("structure"),
        "parameters": values,
        "nuisance": document.get("nuisance"),
        "probe": probe.as_dict() if probe is not None else None,
    }
    text = json.dumps(key, sort_keys=True, default=str, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def replay_model(
    campaign: Campaign, document: Mapping[str, Any], where: str, model: str
) -> ModelReplay:
    """Simulate every recording of ``campaign`` with one fit (module doc).

    Parameters
    ----------
    campaign : Campaign
    document : mapping
        The parsed fit.json.
    where : str
        The fit's file, for messages.
    model : str
        Name shown in the report.

    Returns
    -------
    ModelReplay

    Raises
    ------
    PneumafitInputError
        A fit.json whose parameters or structure cannot be used.
    """
    from pneumafit.comparison.evaluate import fit_values
    from pneumafit.identification.replay import replay as replay_campaign
    from pneumafit.models import parameter_vector
    from pneumafit.simulation.simulator import STATUS_MESSAGES, AirConsumption

    _name, structure, values = fit_values(document, where)  # the one fit.json reader
    probe = temperature_probe(document)
    params = parameter_vector({k: v for k, v in values.items() if ":" not in k})
    # the one replay: the comparison's and the fit metrics' traces, every sample
    rep = replay_campaign(
        campaign, structure, values, trace_channels=SIMULATED, lag=probe,
        estimate_lag=False,
    )  # fmt: skip
    out = ModelReplay(
        model=model, structure=structure.name, sensor_lag=rep.lag or 0.0,
        fingerprint=replay_fingerprint(document),
    )  # fmt: skip
    by_file = {r.file: r for r in campaign.recordings}
    for rec in rep.recordings:
        if not rec.ok:
            out.failed[rec.file] = STATUS_MESSAGES.get(rec.status, f"status {rec.status}")
            continue
        chans = dict(rec.simulated)
        if probe is not None:
            for t_name in ("T_P", "T_N"):
                if np.all(np.isfinite(chans[t_name])):
                    chans[t_name] = probe.read(chans[t_name], rec.time)
        names = compared_channels(by_file[rec.file])
        out.channels[rec.file] = {n: np.asarray(chans[n], dtype=float) for n in names}
        air = AirConsumption.from_mass(chans["m_supply"][-1], chans["m_exhaust"][-1], params)
        out.air[rec.file] = (air.mass_supplied, air.mass_exhausted, air.exergy)
    return out


def save_replays(
    path: str | os.PathLike[str], replays: Sequence[ModelReplay], campaign: Mapping[str, Any]
) -> Path:
    """Write ``replays`` to ``path`` (``.npz``) atomically.

    Parameters
    ----------
    path : path
        The file (:data:`REPLAYS_FILE` beside comparison.json).
    replays : sequence of ModelReplay
    campaign : mapping
        The campaign's identity (``name``, ``path``, ``sha256``:
        :func:`~pneumafit.identification.staged.campaign_identity`).

    Returns
    -------
    Path
    """
    arrays: dict[str, NDArray[np.float64]] = {}
    models = []
    for i, rp in enumerate(replays):
        keys = {}
        for k, (file, chans) in enumerate(rp.channels.items()):
            keys[file] = f"m{i}/{k}"
            for name, values in chans.items():
                arrays[f"m{i}/{k}/{name}"] = np.asarray(values, dtype=float)
        models.append({
            "model": rp.model, "structure": rp.structure, "fingerprint": rp.fingerprint,
            "sensor_lag": rp.sensor_lag, "failed": dict(rp.failed),
            "air": {f: list(a) for f, a in rp.air.items()}, "arrays": keys,
        })  # fmt: skip
    meta = {
        "format": REPLAYS_FORMAT, "version": REPLAYS_VERSION,
        "campaign": {k: campaign.get(k) for k in ("name", "path", "sha256")},
        "models": models,
    }  # fmt: skip
    target = Path(path)
    with atomic_path(target) as tmp:
        with open(tmp, "wb") as stream:
            np.savez_compressed(stream, meta=np.array(json.dumps(meta)), **arrays)
            stream.flush()
            os.fsync(stream.fileno())
    return target


def load_replays(path: str | os.PathLike[str]) -> tuple[list[ModelReplay], dict[str, Any]]:
    """Read a file of :func:`save_replays`.

    Returns
    -------
    replays : list of ModelReplay
    campaign : dict
        The campaign identity recorded (``name``, ``path``, ``sha256``).

    Raises
    ------
    PneumafitInputError
        Not readable, not that format, or an array it names is missing.
    """
    file = Path(path)
    try:
        with np.load(file, allow_pickle=False) as data:
            if "meta" not in data.files:
                raise PneumafitInputError(f"{file}: expected a 'meta' entry, found none")
            meta = json.loads(str(data["meta"]))
            if not isinstance(meta, dict) or meta.get("format") != REPLAYS_FORMAT:
                found = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
                raise PneumafitInputError(
                    f"{file}: format: expected {REPLAYS_FORMAT!r}, found {found!r}"
                )
            if meta.get("version") != REPLAYS_VERSION:
                raise PneumafitInputError(
                    f"{file}: version: expected {REPLAYS_VERSION}, found {meta.get('version')!r}"
                )
            replays = []
            for i, m in enumerate(meta["models"]):
                rp = ModelReplay(
                    model=str(m["model"]), structure=str(m["structure"]),
                    failed={str(k): str(v) for k, v in m["failed"].items()},
                    air={str(k): (float(a[0]), float(a[1]), float(a[2]))
                         for k, a in m["air"].items()},
                    sensor_lag=float(m["sensor_lag"]), fingerprint=str(m["fingerprint"]),
                )  # fmt: skip
                for rec_file, prefix in m["arrays"].items():
                    names = [n for n in data.files if n.startswith(prefix + "/")]
                    rp.channels[str(rec_file)] = {
                        n.rsplit("/", 1)[1]: np.asarray(data[n], dtype=float) for n in names
                    }
                if len(rp.channels) != len(m["arrays"]):
                    raise PneumafitInputError(f"{file}: model {i}: arrays missing")
                replays.append(rp)
    except PneumafitInputError:
        raise
    except (OSError, EOFError, ValueError, KeyError, TypeError, IndexError,
            zipfile.BadZipFile) as exc:  # fmt: skip
        raise PneumafitInputError(
            f"{file}: expected a {REPLAYS_FORMAT} file (.npz), found one that cannot be read: {exc}"
        ) from exc
    return replays, dict(meta.get("campaign") or {})
