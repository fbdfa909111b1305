"""Replay a campaign through one fitted model: traces and error metrics.

A fit (the content of a ``fit.json``) gives the model parameters, the
structure (heat law, air properties) and the fitted initial states of the
``fit`` recordings. :func:`evaluate_fit` replays every recording of the
campaign with them through :func:`pneumafit.identification.replay.replay`,
the same replay that gives ``fit.json: metrics.rmse`` (compared samples,
initial states, reference solver and temperature probe are described there), and
scores every compared channel (RMSE, normalised fit, largest error).

Unlike the identification's metrics, the temperature is compared for the
polytropic model too: it predicts the gas at the wall temperature
throughout, and the size of that error is the point of the comparison
(paper, section 2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import Campaign
from pneumafit.comparison.replays import temperature_probe
from pneumafit.identification.fitfile import SavedFit
from pneumafit.identification.problem import (
    INITIAL_PREFIX,
    MAX_STEP,
    OFFSET_PREFIX,
    QUANTITIES,
)
from pneumafit.identification.replay import replay
from pneumafit.models.structure import MODELS, ModelStructure
from pneumafit.parameters_io import parse_parameters
from pneumafit.simulation.sensor import TemperatureProbe

__all__ = [
    "TRACE_CHANNELS",
    "ChannelError",
    "ModelEvaluation",
    "RecordingTrace",
    "channel_error",
    "evaluate_fit",
    "fit_values",
]

#: Channels kept in the simulated traces (for figures and the JSON).
TRACE_CHANNELS: tuple[str, ...] = ("y", "p_P", "p_N", "T_P", "T_N", "qm_P", "qm_N", "u_P", "u_N")


@dataclass(frozen=True)
class ChannelError:
    """Errors of one simulated channel against its measurement.

    Attributes
    ----------
    n : int
        Samples compared.
    rmse : float
        Root-mean-square error (SI: Pa, m, K, kg/s).
    fit_percent : float
        Normalised fit (%), as MATLAB ``compare``:
        100 (1 - ||y - yhat|| / ||y - mean(y)||); 100 is a perfect fit,
        0 is no better than the mean, negative is worse. NaN for a constant
        measurement.
    max_abs_error : float
        Largest absolute error (SI).
    sum_squares : float
        sum (y - yhat)^2, for pooling over recordings.
    """

    n: int
    rmse: float
    fit_percent: float
    max_abs_error: float
    sum_squares: float

    def as_dict(self) -> dict[str, float | int]:
        return {
            "n": self.n,
            "rmse": self.rmse,
            "fit_percent": self.fit_percent,
            "max_abs_error": self.max_abs_error,
        }


def channel_error(measured: NDArray[np.float64], simulated: NDArray[np.float64]) -> ChannelError:
    """RMSE, normalised fit (%) and largest absolute error of a simulated channel.

    Parameters
    ----------
    measured, simulated : ndarray, shape (n,)
        Same samples, same SI unit.

    Returns
    -------
    ChannelError
    """
    y = np.asarray(measured, dtype=float)
    r = y - np.asarray(simulated, dtype=float)
    ss = float(np.sum(r * r))
    spread = float(np.linalg.norm(y - np.mean(y)))
    fit = 100.0 * (1.0 - math.sqrt(ss) / spread) if spread > 0.0 else math.nan
    return ChannelError(
        n=int(y.size),
        rmse=math.sqrt(ss / y.size) if y.size else math.nan,
        fit_percent=fit,
        max_abs_error=float(np.max(np.abs(r))) if y.size else math.nan,
        sum_squares=ss,
    )


@dataclass
class RecordingTrace:
    """One recording simulated with one model.

    Attributes
    ----------
    recording, kind, role : str
    time : ndarray
        Every sample time of the recording (s).
    simulated : dict of str to ndarray
        :data:`TRACE_CHANNELS` (SI), the gas temperatures without sensor lag.
    compared : dict of str to (ndarray, ndarray, ndarray)
        Per compared channel: times (s), measured values and simulated
        values as the sensor reads them (temperatures after the lag).
    errors : dict of str to ChannelError
    ok : bool
        The simulation succeeded.
    """

    recording: str
    kind: str
    role: str
    time: NDArray[np.float64]
    simulated: dict[str, NDArray[np.float64]]
    compared: dict[str, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]
    errors: dict[str, ChannelError]
    ok: bool = True


@dataclass
class ModelEvaluation:
    """A campaign replayed through one fitted model.

    Attributes
    ----------
    model : str
    structure : ModelStructure
    traces : list of RecordingTrace
        One per simulated recording, campaign order.
    temperature_probe : TemperatureProbe or None
        The probe through which temperatures are compared (two lags in series).
    lag_source : str
        ``"fit"`` (from fit.json) or ``"estimated"`` (fitted here).
    warnings : list of str
    """

    model: str
    structure: ModelStructure
    traces: list[RecordingTrace]
    temperature_probe: TemperatureProbe | None
    lag_source: str
    warnings: list[str] = field(default_factory=list)

    @property
    def temperature_sensor_lag(self) -> float | None:
        """The probe's total lag (s), None without a probe."""
        probe = self.temperature_probe
        return probe.total_lag if probe is not None else None

    def pooled(self, role: str, by: str = "channel") -> dict[str, ChannelError]:
        """Errors pooled over the ``role`` recordings, per channel or per quantity.

        Parameters
        ----------
        role : {"fit", "validate"}
        by : {"channel", "quantity"}
            Pool per channel (``p_P``, ...) or per quantity (``pressure``:
            ``p_P`` and ``p_N`` together, ...).

        Returns
        -------
        dict of str to ChannelError
            ``fit_percent`` is NaN (it is defined per recording).
        """
        acc: dict[str, list[float]] = {}
        for tr in self.traces:
            if tr.role != role:
                continue
            for c, e in tr.errors.items():
                key = c if by == "channel" else QUANTITIES[c]
                a = acc.setdefault(key, [0.0, 0.0, 0.0])
                a[0] += e.sum_squares
                a[1] += e.n
                a[2] = max(a[2], e.max_abs_error)
        return {
            k: ChannelError(int(n), math.sqrt(ss / n), math.nan, mx, ss)
            for k, (ss, n, mx) in acc.items()
            if n > 0
        }


def fit_values(document: Mapping[str, Any], where: str) -> tuple[str, ModelStructure, dict]:
    """Model name, fitted structure and values (model parameters and initial states).

    Parameters
    ----------
    document : mapping
        A parsed fit.json (format ``pneumafit-fit``).
    where : str
        The file, for messages.

    Returns
    -------
    model : str
    structure : ModelStructure
    values : dict of str to float
        SI values by canonical name, plus ``initial:<file>:<state>`` for the
        fitted initial states and ``offset:<channel>`` for the pressure
        sensors' offsets (Pa).

    Raises
    ------
    PneumafitInputError
        Not a fit document, or an unknown model.
    """
    # format, structure (valve and friction laws, effects, air properties, with
    # the documented fallbacks) and initial states: the one reader of fit.json
    fit = SavedFit.from_document(document, where)
    model, values = parse_parameters(dict(document), where)  # unit-checked SI values
    if model not in MODELS or fit.structure is None:
        raise PneumafitInputError(
            f"{where}: model: expected one of {', '.join(MODELS)}, found {model!r}"
        )
    for key, value in fit.initial_states.items():
        values[f"{INITIAL_PREFIX}{key}"] = value
    # the pressure sensors' offsets, which held-out recordings start without
    values.update({k: v for k, v in fit.nuisance.items() if k.startswith(OFFSET_PREFIX)})
    return model, fit.structure, values


def evaluate_fit(
    campaign: Campaign,
    document: Mapping[str, Any],
    *,
    where: str = "fit.json",
    max_step: float | None = MAX_STEP,
) -> ModelEvaluation:
    """Simulate every recording of a campaign with a fit and compare (module doc).

    Parameters
    ----------
    campaign : Campaign
    document : mapping
        The parsed fit.json.
    where : str
        The file, for messages.
    max_step : float or None
        Largest integration step (s) of the comparison grid (as the fit).

    Returns
    -------
    ModelEvaluation

    Raises
    ------
    PneumafitInputError
        Not a fit document.
    """
    model, structure, values = fit_values(document, where)
    probe = temperature_probe(document)  # the one reading of the fitted probe
    # the one replay (fit metrics, discovery and the report read the same)
    rep = replay(
        campaign, structure, values, trace_channels=TRACE_CHANNELS, lag=probe,
        gas_temperatures=True, max_step=max_step,
    )  # fmt: skip
    warnings: list[str] = []
    traces: list[RecordingTrace] = []
    for r in rep.recordings:
        if not r.ok:
            warnings.append(f"{model}: {r.file}: the simulation failed (status {r.status})")
        trace = RecordingTrace(
            recording=r.file, kind=r.kind, role=r.role, time=r.time, simulated=r.simulated,
            compared={}, errors={}, ok=r.ok,
        )  # fmt: skip
        for c, cmp in r.compared.items():
            trace.compared[c] = (cmp.time, cmp.measured, cmp.predicted)
            if r.ok and np.all(np.isfinite(cmp.predicted)):
                trace.errors[c] = channel_error(cmp.measured, cmp.predicted)
        traces.append(trace)
    return ModelEvaluation(model, structure, traces, rep.probe, rep.lag_source, warnings)
