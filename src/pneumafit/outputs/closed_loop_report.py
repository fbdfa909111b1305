"""JSON and figures of the closed-loop comparison (paper Figs. 9-11).

Figures use matplotlib's Agg backend (no display needed); every file is
written atomically.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rich.console import Console

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


def run_closed_loop(
    params: Path,
    out: Path,
    *,
    plant: Path | None = None,
    w0: float | None = None,
    position: float | None = None,
    steps: Sequence[float] = (0.03, 0.0, -0.03, 0.0),
    hold: float = 2.5,
    umax: float = 10.0,
    placement: str = "dominant",
    compensate: bool = True,
    lambda_e: float | None = None,
    console: Console | None = None,
) -> list[ClosedLoopResult]:
    """Design both controllers from a parameter file, run them on the nonlinear
    plant, write ``closed_loop.json`` and the figures, print the table.

    The body of ``pneumafit closed-loop``, and the closed-loop stage of
    ``pneumafit run``.

    Parameters
    ----------
    params : Path
        fit.json, a parameter file or a truth.json: the design parameters.
    out : Path
        Output folder.
    plant : Path, optional
        Parameters of the nonlinear plant (default ``params``); a structure
        other than convection is run as the convection model with its values.
    w0 : float, optional
        ITAE frequency scale (rad/s); default :func:`largest_w0` for the
        largest step.
    position : float, optional
        Operating position (m); default half stroke.
    steps : sequence of float
        Reference offsets from the position (m), one per hold.
    hold : float
        Time at each reference (s).
    umax : float
        Valve command limit (V).
    placement : str
        ``dominant`` or ``itae`` (see :data:`PLACEMENTS`).
    compensate : bool
        Dead-band compensation.
    lambda_e : float, optional
        Nominal heat-transfer coefficient of the linear models (W/m^2/K);
        default the file's lambda for constant-lambda, else 15.
    console : rich.console.Console, optional

    Returns
    -------
    list of ClosedLoopResult
    """
    from rich.table import Table

    from pneumafit.analysis.closed_loop import (
        PLACEMENTS,
        compare_controllers,
        largest_w0,
        read_plant_file,
    )
    from pneumafit.campaign.errors import PneumafitInputError
    from pneumafit.models import parameter_vector
    from pneumafit.models.layout import P
    from pneumafit.models.structure import get_structure

    console = console or Console()
    if placement not in PLACEMENTS:
        raise PneumafitInputError(
            f"option --placement: expected one of {', '.join(PLACEMENTS)}, found {placement!r}"
        )
    if w0 is not None and not w0 > 0:
        raise PneumafitInputError(f"option --w0: expected a positive frequency, found {w0}")
    structure, values = read_plant_file(params)
    design_params = parameter_vector(values)
    nominal = values.get("lambda", 15.0) if structure.heat == "constant-lambda" else 15.0
    if plant is not None:
        plant_structure, plant_values = read_plant_file(plant)
        plant_params = parameter_vector(plant_values)
    else:
        plant_structure, plant_params = structure, design_params
    if plant_structure.heat != "convection":  # the nonlinear model has variable lambda
        console.print(f"plant: the convection model with the {plant_structure.heat} file's values")
        plant_structure = dataclasses.replace(
            get_structure("convection"), valve=plant_structure.valve
        )
    stroke = float(design_params[P["stroke"]])
    y_mid = 0.5 * stroke if position is None else float(position)
    offsets = [float(v) for v in steps]
    kwargs = dict(lambda_e=lambda_e or nominal, compensate=compensate, placement=placement,
                  valve=structure.valve)  # fmt: skip
    if w0 is None:
        biggest = max(abs(v) for v in offsets) or 0.01
        w0 = largest_w0(design_params, y_mid, biggest, umax=umax, **kwargs)
        console.print(f"w0 = {w0:.3g} rad/s: the largest keeping a {biggest * 1e3:g} mm step "
                      f"within 90 % of {umax:g} V")  # fmt: skip
    results = compare_controllers(
        design_params, w0=w0, y_mid=y_mid, steps=offsets, hold=hold, umax=umax,
        plant=plant_structure, plant_parameters=plant_params, **kwargs,
    )  # fmt: skip
    inputs = {"parameters": str(params), "plant": str(plant or params),
              "plant_structure": plant_structure.name or plant_structure.heat, "w0_rad_s": w0,
              "position_m": y_mid, "steps_m": offsets, "hold_s": hold, "umax_V": umax,
              **kwargs}  # fmt: skip
    write_closed_loop(results, out, inputs=inputs)
    table = Table(title=f"closed loop on the nonlinear model, w0 = {w0:.3g} rad/s")
    for column in ("controller", "step", "overshoot", "settling", "final error", "max |u|",
                   "air", "exergy"):  # fmt: skip
        table.add_column(column, justify="right")
    for r in results:
        if not r.ok:
            table.add_row(r.name, "failed", r.message, "", "", "", "", "")
            continue
        for s in r.steps:
            table.add_row(r.name, f"{s.size * 1e3:+.1f} mm", f"{s.overshoot * 1e3:.2f} mm",
                          f"{s.settling_time:.3f} s", f"{s.final_error * 1e3:+.2f} mm",
                          f"{s.max_abs_u:.2f} V", f"{s.air_mass * 1e6:.1f} mg",
                          f"{s.exergy:.1f} J")  # fmt: skip
    console.print(table)
    return list(results)
