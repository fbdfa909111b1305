"""The main job, ``pneumafit run``: from a campaign to a summary.

Today it validates the campaign, replays every recording through the three
model structures at *nominal* parameters (the campaign's rig, default valve,
heat and friction values), reporting the error of each model on each channel
and the air each test consumed, then writes the linear analysis (eqs. 10-14),
both state-feedback designs and a controller export at those parameters.
Identification (fitted parameters with uncertainty) plugs in here when it
lands; until then the numbers describe untuned models, and the summary says so.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from pneumafit.campaign import Campaign, check_campaign, read_campaign
from pneumafit.fileio import write_text_atomic
from pneumafit.models import MODELS, parameter_vector
from pneumafit.simulation import Experiment, Simulator

#: The bundled demo campaign (a virtual-rig recording of a rig like the paper's).
DEMO = Path(__file__).resolve().parents[2] / "data" / "demo"

#: Measured channels compared with the simulation, per kind.
COMPARED = ("p_P", "p_N", "y", "qm_P", "qm_N")


def nominal_parameters(campaign: Campaign) -> np.ndarray:
    """Parameter vector: the campaign's rig, defaults for everything else."""
    return parameter_vector(campaign.rig.as_parameters())


def replay(campaign: Campaign, model: str, params: np.ndarray) -> dict:
    """Simulate every recording with one structure; RMSE per role and channel (SI)."""
    sim = Simulator(model, channels=["y", "p_P", "p_N", "qm_P", "qm_N", "m_supply"])
    exps = [Experiment.from_recording(r) for r in campaign.recordings]
    packed = sim.pack(exps)
    out, status = sim.simulate_batch(params, packed)
    sq: dict[str, dict[str, list[float]]] = {"fit": {}, "validate": {}}
    failed = []
    air = 0.0
    for r, (rec, sl) in enumerate(zip(campaign.recordings, packed.slices(), strict=True)):
        if status[0, r] != 0:
            failed.append(rec.file)
            continue
        rows = out[0, sl]
        air += float(rows[-1, sim.channels.index("m_supply")])
        for name in COMPARED:
            if name not in rec.channels or name not in sim.channels:
                continue
            if rec.kind in ("charge", "discharge") and name != "p_" + rec.chamber:
                continue
            mask = rec.mask.get(name, np.ones(rec.n_samples, bool))
            err = rows[mask, sim.channels.index(name)] - rec.channels[name][mask]
            sq[rec.role].setdefault(name, []).extend((err**2).tolist())
    rmse = {
        role: {name: float(np.sqrt(np.mean(v))) for name, v in chans.items()}
        for role, chans in sq.items()
    }
    return {"rmse": rmse, "failed": failed, "air_supplied_kg": air}


def linear_outputs(params: np.ndarray, out: Path, console: Console) -> dict:
    """Linear analysis, both designs and a JSON export at ``params``.

    w0 is the open-loop natural frequency at half stroke (the paper's
    choice); lambda_e the paper's 15 W/m^2/K.
    """
    from pneumafit.analysis import linearize
    from pneumafit.models.layout import P
    from pneumafit.models.parameters import parameter_dict
    from pneumafit.outputs.export import build_export, write_export
    from pneumafit.outputs.linear_report import write_design, write_linear

    stroke = params[P["stroke"]]
    ys = np.linspace(0.02, 0.98, 25) * stroke
    mid = linearize(params, 0.5 * stroke, order=4).poles
    w0 = float(np.abs(mid[np.abs(mid.imag) > 0]).max())
    write_linear(params, ys, out, lambda_e=15.0)
    for order in (4, 6):
        write_design(params, ys, out, order=order, w0=w0, lambda_e=15.0)
    details = {name: {"value": value} for name, value in parameter_dict(params).items()}
    doc = build_export(details, model="convection", source="nominal parameters", positions=ys,
                       order=6, w0=w0, lambda_e=15.0)  # fmt: skip
    write_export(doc, out / "controller.json", "json")
    console.print(f"linear analysis, designs (w0 = {w0:.1f} rad/s) and export in {out}")
    return {"w0": w0, "folder": str(out)}


def run(campaign_path: Path | None, out: Path, console: Console) -> int:
    """Run the main job; returns the exit status."""
    started = time.perf_counter()
    path = Path(campaign_path) if campaign_path is not None else DEMO
    console.rule(f"[bold]pneumafit run[/bold]: {path}")
    status = check_campaign(path, console=console)
    if status != 0:
        console.print("[red]the campaign is not valid; nothing was simulated[/red]")
        return status
    campaign = read_campaign(path)
    params = nominal_parameters(campaign)
    results = {}
    with console.status("replaying every recording through the three models ..."):
        for model in MODELS:
            results[model] = replay(campaign, model, params)
    table = Table(
        title="RMSE of each model at nominal (unfitted) parameters\n"
        "pressures in kPa, position in mm, flow in g/s"
    )
    table.add_column("model")
    table.add_column("role")
    for name in ("p_P", "p_N", "y", "qm_P"):
        table.add_column(name, justify="right")
    scale = {"p_P": 1e-3, "p_N": 1e-3, "y": 1e3, "qm_P": 1e3}
    for model, res in results.items():
        for role in ("fit", "validate"):
            row = res["rmse"][role]
            table.add_row(
                model, role,
                *(f"{row[c] * scale[c]:.3g}" if c in row else "-" for c in scale),
            )  # fmt: skip
    console.print(table)
    summary = {
        "format": "pneumafit-run",
        "version": 1,
        "campaign": {"name": campaign.name, "path": str(path), "sha256": campaign.sha256},
        "parameters": "nominal (campaign rig + defaults); identification is not yet available",
        "models": results,
    }
    out.mkdir(parents=True, exist_ok=True)
    with console.status("linear analysis, state-feedback design and export ..."):
        summary["linear"] = linear_outputs(params, out / "linear", console)
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    console.print(
        "[yellow]note:[/yellow] these are untuned models: the identification stage "
        "(fitted xi, beta, friction with uncertainty) is not part of this version yet."
    )
    console.print(f"wrote {out / 'summary.json'}; total time {time.perf_counter() - started:.1f} s")
    return 0
