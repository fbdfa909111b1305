"""A step test whose piston rests elsewhere than the rig's, as a picture.

The fit's verdict names the step test whose model piston comes to rest
furthest from the measured one where the pressures miss the noise at rest
(:meth:`pneumafit.identification.quality.FitQuality.stops_elsewhere`). This
figure shows that test: the measured pressures against the model's closed loop
(the fit's replay) and, for a closed loop recorded with its commands, the
model driven by the recorded commands instead of its controller; below,
the model's position and valve-P command minus the measured ones. The rest
phase named is shaded. Written beside fit.json (:data:`REST_FIGURE`),
embedded by the report.

Figures use matplotlib's Agg backend; the file is written atomically.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Recording
from pneumafit.fileio import atomic_path
from pneumafit.identification.quality import RestOffset

__all__ = ["REST_FIGURE", "rest_position_figure"]

#: File name of the figure in a fit folder.
REST_FIGURE = "rest_position.png"

#: (channel, axis label, scale from SI, difference) of the panels, top to
#: bottom: the pressures as measured and simulated, the position and the
#: command as the model's minus the measured (millimetres and tenths of a
#: volt, which the full strokes and +-10 V would hide).
_PANELS = (
    ("p_P", "p_P (kPa)", 1e-3, False),
    ("p_N", "p_N (kPa)", 1e-3, False),
    ("y", "y, model - measured (mm)", 1e3, True),
    ("u_P", "u_P, model - recorded (V)", 1.0, True),
)


def rest_position_figure(
    recording: Recording,
    closed: Mapping[str, NDArray[np.float64]],
    opened: Mapping[str, NDArray[np.float64]] | None,
    stop: RestOffset,
    path: str | os.PathLike[str],
) -> Path:
    """Draw a step test with the model's closed loop and its replay on the recorded commands.

    Parameters
    ----------
    recording : Recording
        The step test (SI channels).
    closed : mapping of str to ndarray
        The fit's replay of it on every sample (SI; ``RecordingReplay.simulated``).
    opened : mapping of str to ndarray or None
        The replay with the recorded commands instead of the controller, or
        None (an open-loop test, or a closed loop recorded without commands).
    stop : RestOffset
        The rest phase named (shaded).
    path : path
        PNG file to write (atomically).

    Returns
    -------
    Path
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(recording.time, float)
    panels = [p for p in _PANELS if p[0] in recording.channels and p[0] in closed]
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.0 * len(panels) + 0.6), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, (channel, label, scale, difference) in zip(axes, panels, strict=True):
        measured = np.asarray(recording.channels[channel], float)
        base = measured if difference else 0.0
        if not difference:
            ax.plot(t, measured * scale, color="k", lw=0.8, label="measured")
        else:
            ax.axhline(0.0, color="k", lw=0.8)
        ax.plot(t, (np.asarray(closed[channel], float) - base) * scale, color="C3", lw=1.0,
                label="model, its closed loop")  # fmt: skip
        if opened is not None and channel in opened:
            ax.plot(t, (np.asarray(opened[channel], float) - base) * scale, color="C0", lw=1.0,
                    linestyle="--", label="model, the recorded commands")  # fmt: skip
        ax.axvspan(stop.start, stop.end, color="0.85", zorder=0)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("time (s)")
    command = f", command {stop.command:+.2f} V" if stop.command is not None else ""
    axes[0].set_title(
        f"{recording.file}: the model's piston rests {stop.offset * 1e3:+.2f} mm from the "
        f"rig's at {stop.start:.1f}-{stop.end:.1f} s (shaded){command}",
        fontsize=9,
    )
    fig.tight_layout()
    target = Path(path)
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)
    return target
