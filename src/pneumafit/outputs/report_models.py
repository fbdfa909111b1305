"""Measurement against the fitted models, residual diagnostics and the air
each model uses: the simulation part of the validation report.

Every recording of the campaign replayed with each fit
(:class:`~pneumafit.comparison.replays.ModelReplay`: saved by the comparison
stage in ``comparison/replays.npz``, which the report reads, or simulated
by :func:`~pneumafit.comparison.replays.replay_model` for a fit it does not
hold): the fit's parameters, structure and fitted initial states, the
reference solver, every sample. The channels compared are :data:`COMPARED`
(a charge/discharge test on its own chamber's pressure, a flow test on its
flow only), plus a measured temperature, which is compared with the
simulated gas temperature seen through the fitted temperature probe (two
lags in series, ``metrics.temperature_probe``).

The report's RMSE is on every sample and keeps each pressure sensor's
offset; fit.json's is on the compared samples.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.comparison.replays import COMPARED, ModelReplay, compared_channels
from pneumafit.comparison.replays import replay_model as replay_fit
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
    "COMPARED",
    "ModelReplay",
    "compared_channels",
    "render_air",
    "render_measurement",
    "render_residuals",
    "replay_fit",
]

#: Points drawn per line at most (strided beyond).
MAX_PLOT_POINTS = 2500
#: Residual figures drawn at most (the recordings furthest from white).
MAX_RESIDUAL_FIGURES = 3
#: Line colour of each model in the overlays (the heat laws' parts, live;
#: the comparison figures' colours too).
MODEL_COLOURS = parts.MODEL_COLOURS


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
        "simulated gas temperature seen through the fitted temperature probe (two lags and "
        "an offset)."
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


def residual_reports(campaign: Any, replay: ModelReplay) -> tuple[list[Any], list[str]]:
    """Residual analysis (``residual_analysis``) of every compared recording of
    one fit's replay; the reports and one line per recording that could not be
    analysed."""
    from pneumafit.discovery import residual_analysis

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
    return reports, problems


def worst_recordings(rows: list[Any]) -> list[str]:
    """The (at most :data:`MAX_RESIDUAL_FIGURES`) recordings furthest from
    white, in the order of ``rows`` (:func:`pneumafit.discovery.summarize`)."""
    worst: list[str] = []
    for r in rows:
        if r.recording not in worst:
            worst.append(r.recording)
        if len(worst) == MAX_RESIDUAL_FIGURES:
            break
    return worst


def render_residual_rows(
    model: str, rows: list[Any], problems: list[str], figures: list[tuple[Path, str]]
) -> tuple[str, str]:
    """The residual section from its rows (``SummaryRow`` or the same fields
    read back from ``comparison/residuals.json``) and figure files (path,
    recording); the HTML and a status."""
    parts = [note(
        f"Residuals of the <strong>{esc(model)}</strong> fit, as MATLAB's "
        "<code>resid</code>: Ljung-Box test of whiteness (LB z = (Q - M)/sqrt(2M), about "
        "N(0, 1) for white residuals), fraction of autocorrelation and input "
        "cross-correlation lags outside the 99 % band, and the test phase where the "
        "residual is largest. Rows furthest from white first."
    )]  # fmt: skip
    for p in problems:
        parts.append(note(esc(p), "warn"))
    if not rows:
        parts.append(note("no recording could be analysed.", "error"))
        return "\n".join(parts), "error"
    parts.append(table(
        ["recording", "channel", "RMS", "mean", "LB z", "p", "acf outside", "ccf outside",
         "largest in", "white"],
        [[esc(r.recording), esc(r.channel), channel_value(r.channel, r.rms),
          channel_value(r.channel, r.mean), fmt(r.violation, "", 3), fmt(r.p_value, "", 2),
          fmt(100 * r.acf_outside, "%", 3), fmt(100 * r.ccf_outside, "%", 3)
          if math.isfinite(r.ccf_outside) else "-", esc(r.concentrated_in), fmt(r.white)]
         for r in rows],
    ))  # fmt: skip
    parts.append(f"<p>Figures for the {len(figures)} recordings furthest from white "
                 "(residual over the test phases, autocorrelation, cross-correlation with "
                 "the inputs).</p>")  # fmt: skip
    for path, name in figures:
        parts.append(embed_png_file(path, f"residuals of {name} ({model} fit)"))
    return "\n".join(parts), "ok" if not problems else "partial"


def render_residuals(campaign: Any, replay: ModelReplay) -> tuple[str, str]:
    """Residual diagnostics of one fit, computed here (``residual_analysis``,
    ``plot_residuals``): for a run folder whose comparison saved none
    (``comparison/residuals.json``, :mod:`pneumafit.services.compare`).

    Returns the HTML and a status.
    """
    from pneumafit.discovery import plot_residuals, summarize

    reports, problems = residual_reports(campaign, replay)
    rows = summarize(reports)
    by_name = {rep.recording: rep for rep in reports}
    with tempfile.TemporaryDirectory(prefix="pneumafit-report-") as tmp:
        figures = [(plot_residuals(by_name[name], Path(tmp) / f"residuals_{i}.png"), name)
                   for i, name in enumerate(worst_recordings(rows))]  # fmt: skip
        return render_residual_rows(replay.model, rows, problems, figures)


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
