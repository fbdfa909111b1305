"""Figures of the comparison: measured against every model, and residuals.

One PNG per recording: a row per quantity (pressures, position for step
tests, flows for flow tests, temperature), measured values and each model's
simulation on the left, residuals (measured - simulated, as the sensor reads)
on the right. The temperature row shows each model's predicted gas
temperature in every chamber (no sensor lag, thin lines) beside the
measurement and the lagged prediction it is compared with. matplotlib is
imported here only (Agg backend); files are written atomically.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from pneumafit.campaign.units import display_unit
from pneumafit.comparison.evaluate import RecordingTrace
from pneumafit.fileio import atomic_path
from pneumafit.models.parts import MODEL_COLOURS

__all__ = ["plot_recording"]

#: Quantities plotted, one axis each (display units: campaign.units.display_unit).
QUANTITIES = ("pressure", "position", "temperature", "flow")
QUANTITY = {"p_P": "pressure", "p_N": "pressure", "y": "position", "T_P": "temperature",
            "T_N": "temperature", "qm_P": "flow", "qm_N": "flow"}  # fmt: skip
#: One colour per model, measured data in black (the heat laws' parts, live).
COLOURS = MODEL_COLOURS
LINESTYLES = {"P": "-", "N": "--"}


def _chambers(trace: RecordingTrace, chamber: str | None) -> tuple[str, ...]:
    if trace.kind == "flow":
        return ()
    if trace.kind in ("charge", "discharge") and chamber in ("P", "N"):
        return (chamber,)
    return ("P", "N")


def plot_recording(
    traces: Mapping[str, RecordingTrace],
    path: str | Path,
    *,
    chamber: str | None = None,
    title: str = "",
) -> Path:
    """Measured vs simulated channels of one recording for every model, and residuals.

    Parameters
    ----------
    traces : mapping of str to RecordingTrace
        Model name -> the recording simulated with that model.
    path : path
        PNG file to write (atomically).
    chamber : {"P", "N"} or None
        The chamber under test of a charge/discharge test.
    title : str

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = next(iter(traces.values()))
    channels = list(dict.fromkeys(c for tr in traces.values() for c in tr.compared))
    quantities = [q for q in QUANTITIES if any(QUANTITY[c] == q for c in channels)]
    chambers = _chambers(first, chamber)
    if "temperature" not in quantities and chambers:
        quantities.append("temperature")  # predicted gas temperature, nothing measured
    n = max(1, len(quantities))
    fig, axes = plt.subplots(n, 2, figsize=(12, 2.8 * n), squeeze=False, sharex="col")
    for row, q in enumerate(quantities):
        scale, unit = display_unit(q)
        ax, axr = axes[row]
        measured_done: set[str] = set()
        for model, tr in traces.items():
            colour = COLOURS.get(model, None)
            for c, (t, d, pred) in tr.compared.items():
                if QUANTITY[c] != q:
                    continue
                style = LINESTYLES.get(c[-1], "-") if q != "position" else "-"
                if c not in measured_done:
                    ax.plot(t, d * scale, color="black", lw=0.6, ls=style, zorder=3,
                            label=f"measured {c}")  # fmt: skip
                    measured_done.add(c)
                lag = " (sensor)" if q == "temperature" else ""
                ax.plot(t, pred * scale, color=colour, lw=1.0, ls=style,
                        label=f"{model} {c}{lag}")  # fmt: skip
                axr.plot(t, (d - pred) * scale, color=colour, lw=0.8, ls=style,
                         label=f"{model} {c}")  # fmt: skip
            if q == "temperature":
                for ch in chambers:
                    gas = tr.simulated.get(f"T_{ch}")
                    if gas is not None and np.any(np.isfinite(gas)):
                        ax.plot(tr.time, gas * scale, color=colour, lw=0.6, alpha=0.6,
                                ls=LINESTYLES[ch], label=f"{model} gas T_{ch}")  # fmt: skip
        ax.set_ylabel(f"{q} ({unit})")
        axr.set_ylabel(f"residual ({unit})")
        axr.axhline(0.0, color="0.6", lw=0.5)
        ax.legend(fontsize=6, ncol=2, loc="upper right")
        if axr.lines[1:]:
            axr.legend(fontsize=6, ncol=2, loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    axes[-1, 1].set_xlabel("time (s)")
    axes[0, 0].set_title(title or first.recording)
    axes[0, 1].set_title("measured - simulated")
    # fixed margins: tight_layout and legend loc="best" cost a redraw each
    height = 2.8 * n  # inches: margins of 0.45 in (axis labels) and 0.35 in (titles)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.45 / height, top=1 - 0.35 / height,
                        wspace=0.2, hspace=0.08)  # fmt: skip
    target = Path(path)
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return target
