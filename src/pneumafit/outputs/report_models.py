"""Measurement against the fitted models, residual diagnostics and the air
each model uses: the simulation part of the validation report.

Every recording of the campaign is replayed with each fit by
:func:`pneumafit.identification.replay.replay`, the replay that gives
fit.json's metrics and the comparison's traces: the fit's parameters,
structure and fitted initial states, the reference solver, every sample.
The channels compared are :data:`COMPARED` (a charge/discharge test on its
own chamber's pressure, a flow test on its flow only), plus a measured
temperature, which is compared with the simulated gas temperature seen
through the fitted first-order sensor lag (``metrics.temperature_sensor_lag``).

The report's RMSE is on every sample and keeps each pressure sensor's
offset; fit.json's is on the compared samples.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.models import parts
from pneumafit.outputs.report_html import (
    CHANNEL_DISPLAY,
    channel_value,
    embed_figure,
    embed_png_file,
    esc,
    fmt,
    note,
    table,
)

__all__ = [
    "ModelReplay",
    "compared_channels",
    "render_air",
    "render_measurement",
    "render_residuals",
    "replay_fit",
]

#: Measured channels compared with a simulation (those of the main job's first
#: version; a charge/discharge test is compared on its own chamber only).
COMPARED = ("p_P", "p_N", "y", "qm_P", "qm_N")
#: Simulated channels the report asks for.
SIMULATED = ("y", "p_P", "p_N", "qm_P", "qm_N", "T_P", "T_N", "m_supply", "m_exhaust")
#: Points drawn per line at most (strided beyond).
MAX_PLOT_POINTS = 2500
#: Residual figures drawn at most (the recordings furthest from white).
MAX_RESIDUAL_FIGURES = 3
#: Line colour of each model in the overlays (the heat laws' parts, live;
#: the comparison figures' colours too).
MODEL_COLOURS = parts.MODEL_COLOURS


def compared_channels(recording: Any) -> list[str]:
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
        sample times (SI; temperatures through the sensor lag). Missing for a
        failed simulation.
    failed : dict of str to str
        Recording file -> the simulator's message.
    air : dict of str to tuple of float
        Recording file -> (mass supplied kg, mass exhausted kg, exergy J).
    sensor_lag : float
        Temperature sensor time constant applied (s; 0: none).
    """

    model: str
    structure: str
    channels: dict[str, dict[str, NDArray[np.float64]]] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    air: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    sensor_lag: float = 0.0


def replay_fit(campaign: Any, fit: Mapping[str, Any], fit_path: Path, model: str) -> ModelReplay:
    """Simulate every recording of ``campaign`` with one fit (see the module doc).

    Parameters
    ----------
    campaign : Campaign
    fit : mapping
        The parsed fit.json.
    fit_path : Path
        The fit.json file (read again as a parameter file).
    model : str
        Name shown in the report.

    Returns
    -------
    ModelReplay

    Raises
    ------
    PneumafitInputError, ValueError
        A fit.json whose parameters or structure cannot be used.
    """
    from pneumafit.comparison.evaluate import fit_values
    from pneumafit.identification.replay import replay as replay_campaign
    from pneumafit.models import parameter_vector
    from pneumafit.simulation.sensor import first_order_lag
    from pneumafit.simulation.simulator import STATUS_MESSAGES, AirConsumption

    _name, structure, values = fit_values(fit, str(fit_path))  # the one fit.json reader
    lag = (fit.get("metrics") or {}).get("temperature_sensor_lag")
    lag = float(lag) if isinstance(lag, int | float) and math.isfinite(lag) and lag > 0 else 0.0
    params = parameter_vector({k: v for k, v in values.items() if ":" not in k})
    # the one replay: the comparison's and the fit metrics' traces, every sample
    rep = replay_campaign(
        campaign, structure, values, trace_channels=SIMULATED, lag=lag or None,
        estimate_lag=False,
    )  # fmt: skip
    replay = ModelReplay(model=model, structure=structure.name, sensor_lag=lag)
    for rec in rep.recordings:
        if not rec.ok:
            replay.failed[rec.file] = STATUS_MESSAGES.get(rec.status, f"status {rec.status}")
            continue
        chans = dict(rec.simulated)
        if lag > 0:
            for t_name in ("T_P", "T_N"):
                if np.all(np.isfinite(chans[t_name])):
                    chans[t_name] = first_order_lag(chans[t_name], rec.time, lag)
        replay.channels[rec.file] = chans
        air = AirConsumption.from_mass(chans["m_supply"][-1], chans["m_exhaust"][-1], params)
        replay.air[rec.file] = (air.mass_supplied, air.mass_exhausted, air.exergy)
    return replay


def _mask(rec: Any, name: str) -> NDArray[np.bool_]:
    mask = rec.mask.get(name)
    return np.ones(rec.n_samples, bool) if mask is None else np.asarray(mask, bool)


def _rmse(rec: Any, name: str, simulated: NDArray[np.float64]) -> float:
    m = _mask(rec, name)
    err = simulated[m] - rec.channels[name][m]
    return float(np.sqrt(np.mean(err**2))) if err.size else math.nan


def _stride(n: int) -> int:
    return max(1, math.ceil(n / MAX_PLOT_POINTS))


def _overlay(rec: Any, names: list[str], replays: list[ModelReplay]) -> Any:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(names), 1, figsize=(11.0, 1.9 * len(names) + 0.7),
                             sharex=True, squeeze=False)  # fmt: skip
    for ax, name in zip(axes[:, 0], names, strict=True):
        factor, unit = CHANNEL_DISPLAY.get(name, (1.0, ""))
        m = _mask(rec, name)
        t = rec.time[m]
        s = _stride(t.size)
        ax.plot(t[::s], rec.channels[name][m][::s] * factor, color="k", lw=1.4,
                label="measured")  # fmt: skip
        for rp in replays:
            chans = rp.channels.get(rec.file)
            if chans is None or name not in chans:
                continue
            ax.plot(rec.time[::_stride(rec.n_samples)],
                    chans[name][::_stride(rec.n_samples)] * factor,
                    color=MODEL_COLOURS.get(rp.model, None), lw=0.9, ls="--",
                    label=rp.model)  # fmt: skip
        ax.set_ylabel(f"{name} [{unit}]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="best", ncol=4)
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(f"{rec.file} ({rec.kind}, {rec.role})", fontsize=10)
    fig.tight_layout()
    return fig


def render_measurement(campaign: Any, replays: list[ModelReplay]) -> str:
    """Per recording: the measurement against every fitted model, with RMSE."""
    parts = [note(
        "Each recording is simulated from its measured initial state with each fit's "
        "parameters (the fits used fitted initial states and sensor offsets, so their own "
        "RMSE in fit.json is a little smaller). Measured temperatures are compared with the "
        "simulated gas temperature seen through the fitted sensor lag."
    )]  # fmt: skip
    for rp in replays:
        if rp.failed:
            parts.append(
                note(
                    f"{esc(rp.model)}: the simulation failed on "
                    + ", ".join(f"{esc(f)} ({esc(m)})" for f, m in rp.failed.items()),
                    "warn",
                )
            )
    for rec in campaign.recordings:
        names = compared_channels(rec)
        parts.append(f"<h3>{esc(rec.file)} <small>({esc(rec.kind)}, {esc(rec.role)})</small></h3>")
        if not names:
            parts.append(note("no channel of this recording is compared.", "notrun"))
            continue
        rows = []
        for rp in replays:
            chans = rp.channels.get(rec.file)
            cells = [esc(rp.model)]
            for name in names:
                cells.append("failed" if chans is None else
                             channel_value(name, _rmse(rec, name, chans[name])))  # fmt: skip
            rows.append(cells)
        parts.append(table(["model", *(f"RMSE {n}" for n in names)], rows))
        parts.append(embed_figure(_overlay(rec, names, replays),
                                  f"measurement vs models {rec.file}"))  # fmt: skip
    return "\n".join(parts)


def render_residuals(campaign: Any, replay: ModelReplay) -> tuple[str, str]:
    """Residual diagnostics of one fit (``residual_analysis``, ``plot_residuals``).

    Returns the HTML and a status.
    """
    from pneumafit.discovery import plot_residuals, residual_analysis, summarize

    reports = []
    problems = []
    for rec in campaign.recordings:
        chans = replay.channels.get(rec.file)
        if chans is None:
            problems.append(f"{rec.file}: simulation failed")
            continue
        names = compared_channels(rec)
        if not names:
            continue
        try:
            reports.append(residual_analysis(rec, chans, channels=names))
        except ValueError as exc:
            problems.append(f"{rec.file}: {exc}")
    parts = [note(
        f"Residuals of the <strong>{esc(replay.model)}</strong> fit, as MATLAB's "
        "<code>resid</code>: Ljung-Box test of whiteness (LB z = (Q - M)/sqrt(2M), about "
        "N(0, 1) for white residuals), fraction of autocorrelation and input "
        "cross-correlation lags outside the 99 % band, and the test phase where the "
        "residual is largest. Rows furthest from white first."
    )]  # fmt: skip
    for p in problems:
        parts.append(note(esc(p), "warn"))
    if not reports:
        parts.append(note("no recording could be analysed.", "error"))
        return "\n".join(parts), "error"
    rows = summarize(reports)
    parts.append(table(
        ["recording", "channel", "RMS", "mean", "LB z", "p", "acf outside", "ccf outside",
         "largest in", "white"],
        [[esc(r.recording), esc(r.channel), channel_value(r.channel, r.rms),
          channel_value(r.channel, r.mean), fmt(r.violation, "", 3), fmt(r.p_value, "", 2),
          fmt(100 * r.acf_outside, "%", 3), fmt(100 * r.ccf_outside, "%", 3)
          if math.isfinite(r.ccf_outside) else "-", esc(r.concentrated_in), fmt(r.white)]
         for r in rows],
    ))  # fmt: skip
    worst: list[str] = []
    for r in rows:
        if r.recording not in worst:
            worst.append(r.recording)
        if len(worst) == MAX_RESIDUAL_FIGURES:
            break
    by_name = {rep.recording: rep for rep in reports}
    parts.append(f"<p>Figures for the {len(worst)} recordings furthest from white "
                 "(residual over the test phases, autocorrelation, cross-correlation with "
                 "the inputs).</p>")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="pneumafit-report-") as tmp:
        for i, name in enumerate(worst):
            path = plot_residuals(by_name[name], Path(tmp) / f"residuals_{i}.png")
            parts.append(embed_png_file(path, f"residuals of {name} ({replay.model} fit)"))
    return "\n".join(parts), "ok" if not problems else "partial"


def render_air(campaign: Any, replays: list[ModelReplay]) -> str:
    """Air supplied per recording and model (simulated), with its exergy."""
    if not replays:
        return ""
    rows = []
    for rec in campaign.recordings:
        if rec.kind == "flow":
            continue
        cells = [esc(rec.file), esc(rec.kind)]
        for rp in replays:
            air = rp.air.get(rec.file)
            cells += ["failed", "-"] if air is None else [fmt(air[0] * 1e3, "g"),
                                                           fmt(air[2], "J")]  # fmt: skip
        rows.append(cells)
    header = ["recording", "kind"]
    for rp in replays:
        header += [f"{rp.model}: air supplied", f"{rp.model}: exergy"]
    return (
        "<h3>Air used by each fitted model on the recorded tests</h3>"
        + note("Net air mass drawn from the supply over each test, simulated with each fit "
               "(flow tests left out: their chamber pressure is imposed), and its exergy "
               "m r T_atm ln(P_S / P_atm) (isothermal compression work from atmosphere).")
        + table(header, rows)
    )  # fmt: skip
