"""JSON and figures of the closed-loop comparison (paper Figs. 9-11).

Figures use matplotlib's Agg backend (no display needed); every file is
written atomically.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pneumafit.analysis.closed_loop import ClosedLoopResult, result_document
from pneumafit.fileio import atomic_path, write_text_atomic

#: Figures written by :func:`write_closed_loop`, by file name: (channels, label, scale).
FIGURES = {
    "closed_loop_position.png": ((("y", "y"),), "position (mm)", 1e3),  # Fig. 9
    "closed_loop_pressures.png": ((("p_P", "P_P"), ("p_N", "P_N")), "pressure (bar)", 1e-5),
    "closed_loop_temperatures.png": ((("T_P", "T_P"), ("T_N", "T_N")), "temperature (K)", 1.0),
    "closed_loop_lambda.png": (
        (("lambda_P", "lambda_P"), ("lambda_N", "lambda_N")),
        "lambda (W/m^2/K)",
        1.0,
    ),
    "closed_loop_command.png": ((("u_P", "u_P"),), "valve command (V)", 1.0),
}


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")


def write_closed_loop(
    results: Sequence[ClosedLoopResult], out: Path, *, inputs: dict | None = None
) -> dict:
    """Write ``closed_loop.json`` and the figures of a controller comparison.

    Parameters
    ----------
    results : sequence of ClosedLoopResult
        From :func:`pneumafit.analysis.closed_loop.compare_controllers`.
    out : Path
        Folder (created).
    inputs : dict, optional
        What was run (parameter file, plant, w0, steps...), stored as is.

    Returns
    -------
    dict
        The JSON document: ``inputs``, ``controllers`` (per controller: design,
        gains, totals and per-step metrics in SI units) and ``figures``.

    Figures: position (Fig. 9), pressures (Fig. 10), temperatures (Fig. 11),
    heat-transfer coefficients (the paper's second Fig. 11), valve command,
    and a bar chart of the air mass and exergy per step and controller.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    ok = [r for r in results if r.ok]
    written = []
    for name, (channels, label, scale) in FIGURES.items():
        fig, ax = plt.subplots(figsize=(8, 4))
        for i, r in enumerate(ok):
            for j, (ch, tag) in enumerate(channels):
                ax.plot(r.time, r.channels[ch] * scale, color=f"C{i}",
                        linestyle=("-", "--")[j], label=f"{r.name}: {tag}")  # fmt: skip
        if name == "closed_loop_position.png" and ok:
            ax.plot(ok[0].time, ok[0].y_ref * scale, color="k", linestyle=":", label="y_ref")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if ok:
            ax.legend(fontsize=8)
        _save(fig, out / name)
        plt.close(fig)
        written.append(name)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    width = 0.8 / max(len(ok), 1)
    for i, r in enumerate(ok):
        k = np.arange(len(r.steps)) + (i - 0.5 * (len(ok) - 1)) * width
        axes[0].bar(k, [s.air_mass * 1e6 for s in r.steps], width, label=r.name, color=f"C{i}")
        axes[1].bar(k, [s.exergy for s in r.steps], width, label=r.name, color=f"C{i}")
    if ok:
        leak = [s.leakage_mass * 1e6 for s in ok[0].steps]
        axes[0].plot(np.arange(len(leak)), leak, "k_", markersize=20, label="centre leakage")
        labels = [f"{s.size * 1e3:+.0f} mm" for s in ok[0].steps]
        for ax in axes:
            ax.set_xticks(np.arange(len(labels)), labels)
            ax.legend(fontsize=8)
    axes[0].set_ylabel("air drawn from supply per step (mg)")
    axes[1].set_ylabel("exergy per step (J)")
    for ax in axes:
        ax.set_xlabel("step (target minus position at the step)")
        ax.grid(True, axis="y", alpha=0.3)
    _save(fig, out / "closed_loop_air.png")
    plt.close(fig)
    written.append("closed_loop_air.png")
    doc = {
        "format": "pneumafit-closed-loop",
        "version": 1,
        "units": "SI (m, s, V, kg, J); poles as [real, imag] in 1/s",
        "inputs": inputs or {},
        "controllers": [result_document(r) for r in results],
        "figures": written,
    }
    write_text_atomic(out / "closed_loop.json", json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return doc
