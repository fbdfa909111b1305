"""The ``pneumafit`` command line. It only parses and calls.

Every command reports bad input as one readable message (file, key, expected,
found) and a non-zero exit status; tracebacks are for bugs only, and shown
with ``PNEUMAFIT_DEBUG=1``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.table import Table

from pneumafit.campaign.errors import PneumafitInputError

if TYPE_CHECKING:
    import numpy as np

app = typer.Typer(
    name="pneumafit",
    help="Identify and validate models of electropneumatic actuators.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
# Not a terminal (a log file, a pipe, CI): no 80-column cut, so that tables
# of parameter names and values stay readable in logs.
console = Console() if sys.stdout.isatty() else Console(width=200)
# messages to a log or a pipe are not wrapped: a path cut at 80 columns
# cannot be searched for (soft_wrap keeps each message on its own lines)
err_console = Console(stderr=True) if sys.stderr.isatty() else Console(stderr=True, soft_wrap=True)

EXIT_INVALID_INPUT = 2


def _quantity(text: str, unit: str, option: str) -> float:
    """An option value: a bare number in ``unit`` or a string such as '250 mm'."""
    from pneumafit.campaign.units import ureg

    magnitude, _, unit_text = text.strip().partition(" ")
    try:
        value = float(magnitude)
        if not unit_text:
            return value
        return float(ureg.Quantity(value, unit_text.strip()).to(unit).magnitude)
    except Exception as exc:  # pint or float: say what was expected
        raise PneumafitInputError(
            f"option {option}: expected a number in {unit} or a value with a unit "
            f"(e.g. '0.25' or '250 mm'), found {text!r} ({exc})"
        ) from None


@app.command()
def run(
    campaign: Annotated[
        Path | None, typer.Argument(help="Campaign folder (default: the bundled demo).")
    ] = None,
    out: Annotated[Path, typer.Option("--out", help="Folder for the results.")] = Path("out/run"),
    seed: Annotated[int, typer.Option(help="Seed of every random draw.")] = 0,
    no_mcmc: Annotated[
        bool, typer.Option("--no-mcmc", help="Point estimates with Laplace intervals only.")
    ] = False,
    walkers: Annotated[int | None, typer.Option(help="MCMC walkers of every fit.")] = None,
    steps: Annotated[int | None, typer.Option(help="MCMC steps of every fit.")] = None,
    strict: Annotated[
        bool,
        typer.Option("--strict", help="Exit 3 when a fit is not trustworthy (see pneumafit fit)."),
    ] = False,
) -> None:
    """The main job: check, fit the three models, compare, discover, design, report, export.

    Finished stages in OUT are reused on a re-run (see OUT/stages.json). Exit
    status: 0 ok, 1 a stage failed, 2 bad input, 3 a fit not trustworthy under
    --strict, 130 interrupted.
    """
    from pneumafit.pipeline import run as run_pipeline

    code = run_pipeline(campaign, out, console, seed=seed, mcmc=not no_mcmc, walkers=walkers,
                        steps=steps, strict=strict)  # fmt: skip
    raise typer.Exit(code)


@app.command()
def fit(
    campaign: Annotated[Path, typer.Argument(help="Campaign folder (with campaign.toml).")],
    out: Annotated[Path, typer.Option("--out", help="Folder for fit.json and chains.h5.")],
    model: Annotated[
        str,
        typer.Option(
            help="convection, constant-lambda or polytropic; or friction (a campaign of "
            "friction tests: the friction law on the rod-force balance)."
        ),
    ] = "convection",
    walkers: Annotated[int | None, typer.Option(help="MCMC walkers.")] = None,
    steps: Annotated[int | None, typer.Option(help="MCMC steps.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random draw.")] = 0,
    no_mcmc: Annotated[
        bool, typer.Option("--no-mcmc", help="Point estimates with Laplace intervals only.")
    ] = False,
    strict: Annotated[
        bool,
        typer.Option(
            "--strict",
            help="Exit 3 when the result is not trustworthy (residual above 3x the sensor "
            "noise, an estimate at a bound or outside its interval, chains too short).",
        ),
    ] = False,
    valve: Annotated[
        str,
        typer.Option(
            help="Valve law: iso6358 (parametric) or map (measured conductance and critical "
            "ratio tables over the command, started from the ISO fit).",
        ),
    ] = "iso6358",
    friction: Annotated[
        str,
        typer.Option(
            help="Friction law: auto (both fitted to the step tests, LuGre kept when BIC "
            "prefers it), switch (stick-slip, the piston sticks exactly) or lugre (pre-sliding "
            "bristles; their stiffness and damping are fitted too).",
        ),
    ] = "auto",
    seal_friction: Annotated[
        str,
        typer.Option(
            "--seal-friction",
            help="Friction that grows with the chamber pressures (seal preload): off, auto "
            "(fitted after the friction law, kept when BIC in effective samples prefers it) or "
            "on.",
        ),
    ] = "off",
) -> None:
    """Staged identification (valve, heat transfer, friction, joint) with MCMC.

    Exit status: 0 ok (also for an untrustworthy fit, which is said at the top
    of the summary and in fit.json's quality), 1 the fit failed, 2 bad input,
    3 untrustworthy result under --strict, 130 interrupted.
    """
    from pneumafit.identification.command import fit_command

    code = fit_command(
        campaign, model, out, walkers, steps, seed, not no_mcmc, console, strict, valve,
        friction, seal_friction,
    )  # fmt: skip
    raise typer.Exit(code)


@app.command()
def compare(
    campaign: Annotated[Path, typer.Argument(help="Campaign folder (with campaign.toml).")],
    out: Annotated[Path, typer.Option("--out", help="Folder for comparison.json and figures.")],
    fits: Annotated[
        list[Path] | None,
        typer.Option("--fits", help="Fit folder (holding fit.json) to reuse; repeatable."),
    ] = None,
    walkers: Annotated[int | None, typer.Option(help="MCMC walkers of the fits made.")] = None,
    steps: Annotated[int | None, typer.Option(help="MCMC steps of the fits made.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random draw.")] = 0,
    no_mcmc: Annotated[
        bool, typer.Option("--no-mcmc", help="Fits made here: Laplace intervals only.")
    ] = False,
) -> None:
    """Fit (or reuse) the convection, constant-lambda and polytropic models and compare them."""
    from pneumafit.comparison import compare_command

    code = compare_command(campaign, out, fits or [], walkers, steps, seed, not no_mcmc, console)
    raise typer.Exit(code)


@app.command(name="fit-many")
def fit_many(
    campaigns: Annotated[list[Path], typer.Argument(help="Campaign folders (with campaign.toml).")],
    out: Annotated[Path, typer.Option("--out", help="Folder for one fit folder per campaign.")],
    model: Annotated[str, typer.Option(help="convection, constant-lambda or polytropic.")] = (
        "convection"
    ),
    scheduler: Annotated[
        str | None,
        typer.Option(help="Address of a running Dask scheduler (default: a local cluster)."),
    ] = None,
    workers: Annotated[int | None, typer.Option(help="Workers of the local cluster.")] = None,
    walkers: Annotated[int | None, typer.Option(help="MCMC walkers.")] = None,
    steps: Annotated[int | None, typer.Option(help="MCMC steps.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of every campaign's fit.")] = 0,
    no_mcmc: Annotated[
        bool, typer.Option("--no-mcmc", help="Point estimates with Laplace intervals only.")
    ] = False,
) -> None:
    """Fit one model to many campaigns on Dask distributed: OUT/<campaign name>/fit.json."""
    from pneumafit.distributed import fit_many_command

    code = fit_many_command(
        campaigns, model, out, scheduler=scheduler, workers=workers, seed=seed,
        mcmc=not no_mcmc, walkers=walkers, steps=steps, console=console,
    )  # fmt: skip
    raise typer.Exit(code)


@app.command()
def discover(
    campaign: Annotated[Path, typer.Argument(help="Campaign folder (with campaign.toml).")],
    fit: Annotated[Path, typer.Option("--fit", help="Base fit: fit.json or its folder.")],
    out: Annotated[Path, typer.Option("--out", help="Folder for discovery.json and the report.")],
    seed: Annotated[int, typer.Option(help="Seed of the bootstrap and the refits.")] = 0,
    rounds: Annotated[int, typer.Option(help="Largest number of rounds.")] = 2,
    per_round: Annotated[int, typer.Option("--per-round", help="Refits per round.")] = 3,
) -> None:
    """Find the effect a fit's residual asks for, refit with it, report before/after."""
    from pneumafit.discovery.command import discover_command

    code = discover_command(
        campaign, fit, out, seed=seed, rounds=rounds, per_round=per_round, console=console
    )
    raise typer.Exit(code)


@app.command()
def check(
    campaign: Annotated[Path, typer.Argument(help="Campaign folder (with campaign.toml).")],
) -> None:
    """Validate a campaign and print its recordings and every problem found."""
    from pneumafit.campaign import check_campaign

    raise typer.Exit(check_campaign(campaign, console=console))


@app.command()
def report(
    run_dir: Annotated[Path, typer.Argument(help="Run folder (pneumafit run/fit outputs).")],
    out: Annotated[
        Path | None, typer.Option("--out", help="HTML file (default RUN_DIR/report.html).")
    ] = None,
    campaign: Annotated[
        Path | None,
        typer.Option("--campaign", help="Campaign folder (default: the one the fits recorded)."),
    ] = None,
) -> None:
    """Validation report: one self-contained HTML file from a run folder."""
    from pneumafit.outputs.report import write_report

    write_report(run_dir, out or Path(run_dir) / "report.html", campaign=campaign, console=console)
    raise typer.Exit(0)


@app.command()
def rig(
    out: Annotated[Path, typer.Option("--out", help="Folder to write the campaign into.")],
    effect: Annotated[
        list[str] | None,
        typer.Option("--effect", help="Undeclared extra effect NAME[=VALUE]; repeatable."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random draw (sensor noise).")] = 2026,
    protocol: Annotated[
        str, typer.Option(help="Test protocol: demo, quick, tutorial or sparse.")
    ] = "demo",
    truth: Annotated[
        str | None,
        typer.Option(
            "--truth",
            help="Independent truth: a preset (demo, power-valve, table-valve-asym, "
            "lugre-pressure, dahl-bump-leak, mixed, fit-laws) or a TOML/JSON file.",
        ),
    ] = None,
) -> None:
    """Record a campaign on the virtual rig (deterministic for a seed)."""
    from pneumafit.rig import run_rig

    raise typer.Exit(
        run_rig(out, effect or [], seed=seed, console=console, protocol=protocol, truth=truth)
    )


@app.command()
def simulate(
    params: Annotated[Path, typer.Argument(help="Parameter file (JSON) or a fit.json.")],
    kind: Annotated[str, typer.Option(help="charge, discharge or step.")],
    out: Annotated[Path, typer.Option("--out", help="HDF5 recording to write.")],
    model: Annotated[str | None, typer.Option(help="Override the file's model structure.")] = None,
    chamber: Annotated[str, typer.Option(help="Chamber under test (charge/discharge).")] = "P",
    position: Annotated[str, typer.Option(help="Blocked piston position.")] = "250 mm",
    amplitude: Annotated[str, typer.Option(help="Valve command while open.")] = "10 V",
    start: Annotated[str, typer.Option(help="Valve opening instant.")] = "0.2 s",
    open_time: Annotated[str, typer.Option(help="Valve opening time.")] = "0.3 s",
    duration: Annotated[str, typer.Option(help="Test length.")] = "4 s",
    rate: Annotated[str, typer.Option(help="Sample rate of the output.")] = "1000 Hz",
    y0: Annotated[str, typer.Option(help="Initial position (step).")] = "250 mm",
    y_ref: Annotated[str, typer.Option(help="Reference after the step (step).")] = "350 mm",
    step_time: Annotated[str, typer.Option(help="Reference step instant (step).")] = "0.2 s",
    kp: Annotated[str, typer.Option(help="pd proportional gain (step).")] = "60 V/m",
    kd: Annotated[str, typer.Option(help="pd derivative gain (step).")] = "4 V*s/m",
    umax: Annotated[str, typer.Option(help="pd command limit (step).")] = "10 V",
) -> None:
    """Simulate a test and write it as a campaign-format HDF5 recording.

    The parameter file's ``friction`` key (a fit.json's ``structure.friction``)
    chooses the friction law: ``switch`` (default) or ``lugre``; its
    ``effects`` (a fit.json's ``structure.effects``) switch optional effects on.
    """
    import dataclasses

    from pneumafit.campaign import Recording, write_recording_h5
    from pneumafit.models import get_structure
    from pneumafit.parameters_io import read_effects, read_friction_law, read_parameter_file
    from pneumafit.simulation import Simulator
    from pneumafit.simulation.scenarios import blocked_test, step_test

    file_model, values = read_parameter_file(params)
    model = model or file_model
    structure = dataclasses.replace(get_structure(model), friction=read_friction_law(params))
    effects = read_effects(params)
    if effects:  # a fit that kept an effect (seal friction, discovery's refits)
        structure = structure.with_effects(**effects)
    if kind not in ("charge", "discharge", "step"):
        raise PneumafitInputError(
            f"option --kind: expected charge, discharge or step, found {kind!r}"
        )
    if chamber not in ("P", "N"):
        raise PneumafitInputError(f"option --chamber: expected P or N, found {chamber!r}")
    fs = _quantity(rate, "Hz", "--rate")
    length = _quantity(duration, "s", "--duration")
    if kind == "step":
        exp = step_test(
            structure, values, y0=_quantity(y0, "m", "--y0"),
            y_ref=_quantity(y_ref, "m", "--y-ref"),
            step_time=_quantity(step_time, "s", "--step-time"), duration=length,
            kp=_quantity(kp, "V/m", "--kp"), kd=_quantity(kd, "V*s/m", "--kd"),
            umax=_quantity(umax, "V", "--umax"), rate=fs,
        )  # fmt: skip
    else:
        exp = blocked_test(
            kind, values, chamber=chamber, position=_quantity(position, "m", "--position"),
            amplitude=_quantity(amplitude, "V", "--amplitude"),
            start=_quantity(start, "s", "--start"),
            open_time=_quantity(open_time, "s", "--open-time"), duration=length, rate=fs,
        )  # fmt: skip
    law = ", LuGre friction" if structure.friction == "lugre" else ""
    t0 = time.perf_counter()
    result = Simulator(structure).simulate(values, exp)
    elapsed = time.perf_counter() - t0
    if not result.ok:
        err_console.print(f"[red]simulation failed:[/red] {result.message}")
        raise typer.Exit(1)
    names = ["y", "v", "p_P", "p_N", "T_P", "T_N", "u_P", "u_N", "qm_P", "qm_N"]
    channels = {name: result[name] for name in names}
    if exp.y_ref is not None:
        channels["y_ref"] = exp.y_ref
    recording = Recording.from_arrays(
        exp.time, channels, kind=kind, chamber=None if kind == "step" else chamber,
        piston_position=None if kind == "step" else exp.initial["y"],
        description=f"simulated by pneumafit ({model} model{law}) from {params.name}",
    )  # fmt: skip
    write_recording_h5(out, recording)
    air = result.air
    table = Table(
        title=f"{kind} test, {model} model{law}, {exp.time[-1]:.2f} s ({elapsed * 1e3:.1f} ms)"
    )
    table.add_column("air consumption")
    table.add_column("value", justify="right")
    table.add_row("mass drawn from supply", f"{air.mass_supplied * 1e3:.4f} g")
    table.add_row("mass sent to exhaust", f"{air.mass_exhausted * 1e3:.4f} g")
    table.add_row("exergy of the supplied air", f"{air.exergy:.1f} J")
    console.print(table)
    console.print(f"wrote {out}")


#: Options shared by the linear-analysis commands.
PositionsOption = Annotated[
    str | None, typer.Option(help="Positions, e.g. '50,250,450 mm' (default: 25).")
]
LambdaOption = Annotated[
    float | None,
    typer.Option(help="Nominal lambda (W/m^2/K); default the fitted constant one, else 15."),
]


def _positions(text: str | None, stroke: float) -> np.ndarray:
    """Comma-separated positions, one optional unit for all ('50,250,450 mm')."""
    import numpy as np

    if text is None:
        return np.linspace(0.02, 0.98, 25) * stroke
    numbers, _, unit = text.strip().partition(" ")
    values = [_quantity(f"{v} {unit}".strip(), "m", "--positions") for v in numbers.split(",")]
    if not values or any(not 0.0 <= v <= stroke for v in values):
        raise PneumafitInputError(
            f"option --positions: expected positions within the stroke [0, {stroke:g}] m, "
            f"found {text!r}"
        )
    return np.array(values)


def _fit_parameters(fit: Path) -> tuple[np.ndarray, float, str, str]:
    """Parameter vector, nominal lambda_e, model and valve law of a fit or parameter file."""
    from pneumafit.models import parameter_vector
    from pneumafit.parameters_io import read_parameter_file, read_valve_law

    model, values = read_parameter_file(fit)
    lambda_e = values["lambda"] if model == "constant-lambda" and "lambda" in values else 15.0
    return parameter_vector(values), lambda_e, model, read_valve_law(fit)


@app.command()
def linear(
    fit: Annotated[Path, typer.Argument(help="fit.json or a parameter file.")],
    out: Annotated[Path, typer.Option("--out", help="Folder for JSON and figures.")] = Path(
        "out/linear"
    ),
    positions: PositionsOption = None,
    lambda_e: LambdaOption = None,
) -> None:
    """Equilibria, linear models and open-loop poles over the stroke (eqs. 10-14)."""
    from pneumafit.models.layout import P
    from pneumafit.outputs.linear_report import write_linear

    params, nominal, _, valve = _fit_parameters(fit)
    ys = _positions(positions, params[P["stroke"]])
    doc = write_linear(params, ys, out, lambda_e=lambda_e or nominal, valve=valve)
    bad = [e for e in doc["positions"] if "error" in e]
    for entry in bad:
        console.print(f"[yellow]{entry['error']}[/yellow]")
    console.print(f"wrote {out / 'linear.json'} and {out / 'open_loop_poles.png'}")


@app.command()
def design(
    fit: Annotated[Path, typer.Argument(help="fit.json or a parameter file.")],
    order: Annotated[int, typer.Option(help="4 (polytropic) or 6 (heat model).")] = 6,
    w0: Annotated[float, typer.Option(help="ITAE frequency scale (rad/s).")] = 15.0,
    out: Annotated[Path, typer.Option("--out", help="Folder for JSON and figures.")] = Path(
        "out/design"
    ),
    positions: PositionsOption = None,
    lambda_e: LambdaOption = None,
) -> None:
    """State-feedback gain schedule placing the ITAE poles (paper Figs. 6-7)."""
    from pneumafit.models.layout import P
    from pneumafit.outputs.linear_report import write_design

    if order not in (4, 6):
        raise PneumafitInputError(f"option --order: expected 4 or 6, found {order}")
    if not w0 > 0:
        raise PneumafitInputError(f"option --w0: expected a positive frequency, found {w0}")
    params, nominal, _, valve = _fit_parameters(fit)
    ys = _positions(positions, params[P["stroke"]])
    doc = write_design(params, ys, out, order=order, w0=w0, lambda_e=lambda_e or nominal,
                       valve=valve)  # fmt: skip
    mid = doc["schedule"][len(doc["schedule"]) // 2]
    if mid["K"] is not None:
        gains = ", ".join(f"{s}: {k:.4g}" for s, k in zip(doc["states"], mid["K"], strict=True))
        console.print(f"K at y = {mid['y']:.3f} m: {gains} ({', '.join(doc['gain_units'])})")
    console.print(f"wrote {out / f'design_{order}.json'} and figures")


@app.command(name="closed-loop")
def closed_loop(
    params: Annotated[Path, typer.Argument(help="fit.json, a parameter file or a truth.json.")],
    out: Annotated[Path, typer.Option("--out", help="Folder for JSON and figures.")] = Path(
        "out/closed_loop"
    ),
    w0: Annotated[
        float | None,
        typer.Option(help="ITAE frequency scale (rad/s); default the largest within the limit."),
    ] = None,
    position: Annotated[
        str | None, typer.Option(help="Operating position (default half stroke).")
    ] = None,
    steps: Annotated[
        str, typer.Option(help="Reference offsets from the position, one per hold.")
    ] = "30,0,-30,0 mm",
    hold: Annotated[str, typer.Option(help="Time at each reference.")] = "2.5 s",
    plant: Annotated[
        Path | None,
        typer.Option(help="Parameters of the nonlinear plant (e.g. a rig's truth.json)."),
    ] = None,
    umax: Annotated[str, typer.Option(help="Valve command limit.")] = "10 V",
    placement: Annotated[str, typer.Option(help="dominant or itae (the paper's, order n).")] = (
        "dominant"
    ),
    no_compensation: Annotated[
        bool, typer.Option("--no-compensation", help="No dead-band compensation.")
    ] = False,
    lambda_e: LambdaOption = None,
) -> None:
    """Both state-feedback designs run on the nonlinear model: steps and air (Figs. 9-11)."""
    from pneumafit.outputs.closed_loop_report import run_closed_loop

    numbers, _, unit = steps.strip().partition(" ")
    results = run_closed_loop(
        params, out, plant=plant, w0=w0,
        position=None if position is None else _quantity(position, "m", "--position"),
        steps=[_quantity(f"{v} {unit}".strip(), "m", "--steps") for v in numbers.split(",")],
        hold=_quantity(hold, "s", "--hold"), umax=_quantity(umax, "V", "--umax"),
        placement=placement, compensate=not no_compensation, lambda_e=lambda_e, console=console,
    )  # fmt: skip
    console.print(f"wrote {out / 'closed_loop.json'} and figures")
    if not all(r.ok for r in results):
        raise typer.Exit(1)


@app.command()
def export(
    fit: Annotated[Path, typer.Argument(help="fit.json or a parameter file.")],
    format: Annotated[str, typer.Option("--format", help="json, yaml, c or mat.")],
    out: Annotated[Path, typer.Option("--out", help="File to write.")],
    order: Annotated[int, typer.Option(help="Design model: 4 or 6.")] = 6,
    w0: Annotated[float, typer.Option(help="ITAE frequency scale (rad/s).")] = 15.0,
    positions: PositionsOption = None,
    lambda_e: LambdaOption = None,
) -> None:
    """Export parameters, linear models and the gain schedule for a controller."""
    from pneumafit.models.layout import P
    from pneumafit.outputs.export import FORMATS, build_export, write_export
    from pneumafit.parameters_io import read_parameter_details

    if format not in FORMATS:
        raise PneumafitInputError(
            f"option --format: expected one of {', '.join(FORMATS)}, found {format!r}"
        )
    if order not in (4, 6):
        raise PneumafitInputError(f"option --order: expected 4 or 6, found {order}")
    params, nominal, model, valve = _fit_parameters(fit)
    _, details = read_parameter_details(fit)
    ys = _positions(positions, params[P["stroke"]])
    doc = build_export(details, model=model, source=fit.name, positions=ys, order=order, w0=w0,
                       lambda_e=lambda_e or nominal, valve=valve)  # fmt: skip
    write_export(doc, out, format)
    console.print(
        f"wrote {out}: {len(doc['grid']['positions'])} positions, order {order}"
        + (f" ({len(doc['skipped'])} positions without equilibrium)" if doc["skipped"] else "")
    )


def main() -> None:
    """Entry point: run the app; turn input errors into messages, not tracebacks.

    Typer (standalone mode) handles usage errors, ``--help`` and exit codes
    itself and leaves by ``SystemExit``; what reaches the handlers below is
    bad input found while working (one message, exit status 2), an interrupt
    (130) or a bug (one line, exit status 1; traceback with
    ``PNEUMAFIT_DEBUG=1``).
    """
    debug = os.environ.get("PNEUMAFIT_DEBUG") == "1"
    try:
        app()
    except (PneumafitInputError, ValueError) as exc:
        if debug:
            raise
        err_console.print(f"[bold red]error:[/bold red] {exc}")
        sys.exit(EXIT_INVALID_INPUT)
    except KeyboardInterrupt:
        err_console.print("interrupted")
        sys.exit(130)
    except Exception as exc:
        if debug:
            raise
        err_console.print(
            f"[bold red]internal error:[/bold red] {type(exc).__name__}: {exc}\n"
            "This is a bug in pneumafit; run again with PNEUMAFIT_DEBUG=1 for the traceback."
        )
        sys.exit(1)


if __name__ == "__main__":
    main()
