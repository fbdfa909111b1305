"""The ``pneumafit`` command line. It only parses and calls.

Every command reports bad input as one readable message (file, key, expected,
found) and a non-zero exit status; tracebacks are for bugs only, and shown
with ``PNEUMAFIT_DEBUG=1``. Every command that writes checks its ``--out``
first (:func:`pneumafit.cli.console.check_output`), and every command takes
``--quiet`` and ``--verbose`` (added by :class:`_App`).
"""

from __future__ import annotations

import errno
import functools
import inspect
import logging
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape
from rich.table import Table

from pneumafit import first_use
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    LOGGER,
    check_output,
    configure_output,
    make_console,
    release_output,
)
from pneumafit.errors import PneumafitComputationError
from pneumafit.identification.problem import OFFSET_SCOPE
from pneumafit.models.parts import Friction, Model, Valve
from pneumafit.models.structure import INPUT_MODE

if TYPE_CHECKING:
    import numpy as np

log = logging.getLogger(LOGGER)

#: The exit statuses of every command (the app's --help epilog; README.md).
EXIT_STATUSES = (
    "Exit status: 0 done; 1 the work failed (a fit, a simulation), or check found problems "
    "in the campaign; 2 bad input (an option, a file, an invalid campaign, an output path "
    "that cannot be written, a report whose inputs disagree or are missing); 3 an "
    "untrustworthy result under --strict; 130 interrupted. A bug is an 'internal error' "
    "(exit status 1) with how to report it."
)

# Not a terminal (a log file, a pipe, CI): tables in full (no cut, no
# ellipses) and messages on their own lines, so that logs can be searched.
console = make_console()
err_console = make_console(stderr=True)

QuietOption = Annotated[
    bool,
    typer.Option(
        "--quiet", "-q",
        help="Print nothing but errors (the command's output is shown on standard error "
        "only if it fails); log warnings only.",
    ),
]  # fmt: skip
VerboseOption = Annotated[
    bool,
    typer.Option(
        "--verbose", "-v", help="Also log debug records (options, exit status, time) to stderr."
    ),
]


#: Commands that run the compiled simulator: on an install whose warm-up has
#: not run they run it, with its lines (:func:`pneumafit.warmup.ensure_warm`),
#: just before their first simulation (:mod:`pneumafit.first_use`: their input
#: read and checked first, so a mistyped path costs no compile).
SIMULATING_COMMANDS = frozenset({
    "run", "fit", "fit-many", "compare", "discover", "simulate", "linear", "design",
    "closed-loop", "export",
})  # fmt: skip
#: Commands whose simulations run in other processes (Dask workers): they warm
#: up before their work, in this process, so that the workers load the cache
#: instead of each compiling it.
WORKER_COMMANDS = frozenset({"fit-many"})


def _with_output_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """``func`` with the ``--quiet`` and ``--verbose`` options of every command."""
    signature = inspect.signature(func, eval_str=True)
    extra = [
        inspect.Parameter("quiet", inspect.Parameter.KEYWORD_ONLY, default=False,
                          annotation=QuietOption),
        inspect.Parameter("verbose", inspect.Parameter.KEYWORD_ONLY, default=False,
                          annotation=VerboseOption),
    ]  # fmt: skip

    @functools.wraps(func)
    def command(*args: Any, quiet: bool = False, verbose: bool = False, **kwargs: Any) -> Any:
        configure_output(console, quiet=quiet, verbose=verbose)
        name = func.__name__.replace("_", "-")
        log.debug("pneumafit %s: %s", name, kwargs)
        started = time.perf_counter()
        code: int | None = 0
        try:
            if name in SIMULATING_COMMANDS:
                from pneumafit.warmup import ensure_warm

                def warm() -> None:
                    ensure_warm(lambda line: console.print(f"[dim]{escape(line)}[/dim]"))

                if name in WORKER_COMMANDS:
                    warm()
                else:
                    first_use.defer(warm)
            return func(*args, **kwargs)
        except typer.Exit as exc:
            code = exc.exit_code
            raise
        except KeyboardInterrupt:
            # typer itself turns it into exit status 130 without a word
            code = EXIT_INTERRUPTED
            release_output(console, failed=True)
            err_console.print("interrupted")
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except BaseException:
            code = None
            raise
        finally:
            first_use.cancel()
            release_output(console, failed=code != 0)
            log.debug("pneumafit %s: exit status %s after %.1f s", name,
                      "(exception)" if code is None else code,
                      time.perf_counter() - started)  # fmt: skip

    command.__signature__ = signature.replace(  # type: ignore[attr-defined]
        parameters=[*signature.parameters.values(), *extra]
    )
    command.__annotations__ = {
        **{p.name: p.annotation for p in signature.parameters.values()},
        "quiet": QuietOption,
        "verbose": VerboseOption,
    }
    return command


class _App(typer.Typer):
    """A typer app whose every command also takes ``--quiet`` and ``--verbose``."""

    def command(self, *args: Any, **kwargs: Any) -> Callable[[Callable[..., Any]], Any]:
        register = super().command(*args, **kwargs)

        def decorator(func: Callable[..., Any]) -> Callable[..., Any]:
            register(_with_output_options(func))
            return func

        return decorator


app = _App(
    name="pneumafit",
    help="Identify and validate models of electropneumatic actuators.",
    epilog=EXIT_STATUSES,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    """``--version``: the installed version, then exit."""
    if value:
        from pneumafit import __version__

        typer.echo(f"pneumafit {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True,
                     help="Print the version and exit."),
    ] = False,
    parts: Annotated[
        list[str] | None,
        typer.Option("--parts", metavar="<file.py|module>",
                     help="A Python file or module that registers heat laws or effects "
                     "(pneumafit.models.parts) before the command runs; repeatable. Also "
                     "PNEUMAFIT_PARTS and the entry points of group pneumafit.parts."),
    ] = None,
) -> None:  # fmt: skip
    """Identify and validate models of electropneumatic actuators."""
    from pneumafit.cli.plugins import load_parts

    load_parts(parts or ())


def _quantity(text: str, unit: str, option: str) -> float:
    """An option value: a bare number in ``unit`` or a string such as '250 mm',
    read as campaigns are (``"250mm"``, ``"6 barg"`` against the standard
    atmosphere)."""
    from pneumafit.campaign.units import UnitError, parse_quantity
    from pneumafit.models.layout import SPECS

    try:
        return parse_quantity(
            text, unit, exhaust_pressure=SPECS["exhaust_pressure"].default
        )  # fmt: skip
    except UnitError as exc:
        raise PneumafitInputError(
            f"option {option}: expected a number in {unit} or a value with a unit "
            f"(e.g. '0.25' or '250 mm'), found {exc.found}"
        ) from None


def _positive(value: float, option: str, text: str) -> float:
    """``value`` if it is positive, else an input error naming the option."""
    if not value > 0:
        raise PneumafitInputError(f"option {option}: expected a positive value, found {text!r}")
    return value


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
    valve: Annotated[
        str,
        typer.Option(
            help=f"Valve law of the three fits, one of {', '.join(Valve)} (see pneumafit fit); "
            "every later stage uses the fits' law.",
        ),
    ] = "iso6358",
    friction: Annotated[
        str,
        typer.Option(
            help=f"Friction law of the three fits: auto or one of {', '.join(Friction)} (or a "
            "law of your own loaded with --parts; see pneumafit fit). auto: the convection "
            "fit chooses, the other two fits use its law.",
        ),
    ] = "auto",
    inputs: Annotated[
        str,
        typer.Option(
            "--inputs",
            help="How the three fits read the recorded commands and set-points between "
            "samples: hold or linear (see pneumafit fit).",
        ),
    ] = INPUT_MODE,
) -> None:
    """The main job: check, fit the three models, compare, discover, design, report, export.

    A campaign of friction tests (every recording of kind friction) runs its
    own job: check, fit --model friction, discover, report
    (docs/measured-data.md). Finished stages in OUT are reused on a re-run
    (see OUT/stages.json). Exit status: 0 ok, 1 a stage failed, 2 bad input,
    3 a fit not trustworthy under --strict, 130 interrupted.
    """
    from pneumafit.pipeline import run as run_pipeline

    check_output(out, "folder")
    code = run_pipeline(campaign, out, console, seed=seed, mcmc=not no_mcmc, walkers=walkers,
                        steps=steps, strict=strict, valve=valve, inputs=inputs,
                        friction=friction)  # fmt: skip
    raise typer.Exit(code)


@app.command()
def fit(
    campaign: Annotated[Path, typer.Argument(help="Campaign folder (with campaign.toml).")],
    out: Annotated[Path, typer.Option("--out", help="Folder for fit.json and chains.h5.")],
    model: Annotated[
        str,
        typer.Option(
            help=f"{', '.join(Model)}; or friction (a campaign of "
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
            help=f"Valve law, one of {', '.join(Valve)}: iso6358 (parametric) or map (measured "
            "conductance and critical ratio tables over the command, started from the ISO fit).",
        ),
    ] = "iso6358",
    friction: Annotated[
        str,
        typer.Option(
            help=f"Friction law: auto or one of {', '.join(Friction)}. auto (both fitted to the "
            "step tests, LuGre kept when BIC "
            "prefers it), switch (stick-slip, the piston sticks exactly) or lugre (pre-sliding "
            "bristles; their stiffness and damping are fitted too).",
        ),
    ] = "auto",
    seal_friction: Annotated[
        str,
        typer.Option(
            "--seal-friction",
            help="Friction that grows with the chamber pressures (seal preload): long "
            "(default: auto where the fit step tests are fitted in segments, off otherwise), "
            "auto (fitted after the friction law, kept when BIC in effective samples prefers it "
            "and the held-out step tests do not worsen), on or off. With --model friction, long "
            "is off.",
        ),
    ] = "long",
    noise_pooling: Annotated[
        str,
        typer.Option(
            "--noise-pooling",
            help="recording (one noise level per recording and channel, profiled on its own "
            "residual) or sensor (one per channel, shared by the recordings: no recording "
            "is given up for the others).",
        ),
    ] = "recording",
    inputs: Annotated[
        str,
        typer.Option(
            "--inputs",
            help="How the recorded commands and set-points vary between samples: hold (held "
            "until the next sample, as a digital controller outputs them) or linear "
            "(interpolated, an analog signal).",
        ),
    ] = INPUT_MODE,
    segments: Annotated[
        str,
        typer.Option(
            "--segments",
            help="Fit long closed-loop step tests in segments between their set-point "
            "changes, each from its own initial state (multiple shooting): auto (tests of "
            "6 s or more), on (every fit step test) or off. Held-out tests are replayed whole.",
        ),
    ] = "auto",
    offset_scope: Annotated[
        str,
        typer.Option(
            "--offset-scope",
            help="recording (one profiled pressure offset per recording and sensor, the "
            "default) or sensor (one per sensor, shared by the recordings: a model whose "
            "levels are wrong at rest is not excused recording by recording).",
        ),
    ] = OFFSET_SCOPE,
) -> None:
    """Staged identification (valve, heat transfer, friction, joint) with MCMC.

    Exit status: 0 ok (also for an untrustworthy fit, which is said at the top
    of the summary and in fit.json's quality), 1 the fit failed, 2 bad input,
    3 untrustworthy result under --strict, 130 interrupted.
    """
    from pneumafit.cli.fit import fit_command

    code = fit_command(
        campaign, model, out, walkers, steps, seed, not no_mcmc, console, strict, valve,
        friction, seal_friction, noise_pooling, inputs, segments, offset_scope,
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
    from pneumafit.cli.compare import compare_command

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
    valve: Annotated[
        str, typer.Option(help=f"Valve law, one of {', '.join(Valve)} (see pneumafit fit).")
    ] = "iso6358",
    friction: Annotated[
        str, typer.Option(help="Friction law: auto, switch or lugre (see pneumafit fit).")
    ] = "auto",
) -> None:
    """Fit one model to many campaigns on Dask distributed: OUT/<campaign name>/fit.json."""
    from pneumafit.distributed import fit_many_command

    code = fit_many_command(
        campaigns, model, out, scheduler=scheduler, workers=workers, seed=seed,
        mcmc=not no_mcmc, walkers=walkers, steps=steps, console=console, valve=valve,
        friction=friction,
    )  # fmt: skip
    raise typer.Exit(code)


@app.command()
def discover(
    campaign: Annotated[Path, typer.Argument(help="Campaign folder (with campaign.toml).")],
    fit: Annotated[Path, typer.Option("--fit", help="Base fit: fit.json or its folder.")],
    out: Annotated[Path, typer.Option("--out", help="Folder for discovery.json and the report.")],
    seed: Annotated[
        int | None,
        typer.Option(help="Seed of the bootstrap and the refits (default: the base fit's)."),
    ] = None,
    rounds: Annotated[
        int | None,
        typer.Option(
            help="Largest number of rounds (default 2; friction tests 3, one per effect)."
        ),
    ] = None,
    per_round: Annotated[int, typer.Option("--per-round", help="Refits per round.")] = 3,
) -> None:
    """Find the effect a fit's residual asks for, refit with it, report before/after."""
    from pneumafit.cli.discover import discover_command

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
def parts() -> None:
    """List the heat, valve and friction laws and the effects this command knows.

    The built-in parts and those of one's own that --parts, PNEUMAFIT_PARTS
    or an installed plug-in registered (docs/architecture.md, "Adding a part").
    """
    from pneumafit.cli.plugins import parts_tables

    for table in parts_tables():
        console.print(table)


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
    allow_partial: Annotated[
        bool,
        typer.Option(
            "--allow-partial",
            help="Write the report even when the run folder holds no result, its fits were "
            "made from another campaign than --campaign (or than each other), or the campaign "
            "cannot be read; without it these exit with status 2 and nothing is written.",
        ),
    ] = False,
) -> None:
    """Validation report: one self-contained HTML file from a run folder.

    Exit status: 0 written, 2 bad input (no run folder, an --out that cannot be
    written, or inputs that are missing or disagree, unless --allow-partial).
    """
    from pneumafit.outputs.friction_report import (
        is_friction_run,
        write_friction_report_of_folder,
    )
    from pneumafit.outputs.report import FIT_MODELS, write_report

    target = out or Path(run_dir) / "report.html"
    chamber = any((Path(run_dir) / "fits" / m / "fit.json").is_file() for m in FIT_MODELS)
    if is_friction_run(run_dir) and not chamber:
        check_output(target, "file")
        written = write_friction_report_of_folder(Path(run_dir), target, campaign)
        console.print(f"wrote {written} (friction-test report)")
        raise typer.Exit(0)
    write_report(run_dir, target, campaign=campaign, console=console,
                 allow_partial=allow_partial)  # fmt: skip
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
        str, typer.Option(help="Test protocol: demo, quick, tutorial, sparse or sparse-long.")
    ] = "demo",
    truth: Annotated[
        str | None,
        typer.Option(
            "--truth",
            help="Independent truth: a preset (demo, demo-clean, power-valve, "
            "table-valve-asym, lugre-pressure, dahl-bump-leak, mixed, fit-laws) or a TOML/JSON "
            "file.",
        ),
    ] = None,
) -> None:
    """Record a campaign on the virtual rig (deterministic for a seed)."""
    from pneumafit.cli.rig import run_rig

    check_output(out, "folder")
    raise typer.Exit(
        run_rig(out, effect or [], seed=seed, console=console, protocol=protocol, truth=truth)
    )


@app.command()
def simulate(
    params: Annotated[Path, typer.Argument(help="Parameter file (JSON or TOML) or a fit.json.")],
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
    ``effects`` (a fit.json's ``structure.effects``) switch optional effects on;
    a fit.json's valve law and air properties are kept.
    """
    from pneumafit.campaign import Recording, write_recording_h5
    from pneumafit.models.structure import MODELS
    from pneumafit.parameters_io import read_structure
    from pneumafit.simulation import Simulator
    from pneumafit.simulation.scenarios import blocked_test, step_test

    check_output(out, "file")
    if model is not None and model not in MODELS:
        raise PneumafitInputError(
            f"option --model: expected one of {', '.join(MODELS)}, found {model!r}"
        )
    # the fitted structure: valve and friction laws, effects, air properties
    structure, values = read_structure(params, model)
    model = model or structure.name  # the file's model when not overridden
    if kind not in ("charge", "discharge", "step"):
        raise PneumafitInputError(
            f"option --kind: expected charge, discharge or step, found {kind!r}"
        )
    if chamber not in ("P", "N"):
        raise PneumafitInputError(f"option --chamber: expected P or N, found {chamber!r}")
    fs = _positive(_quantity(rate, "Hz", "--rate"), "--rate", rate)
    length = _positive(_quantity(duration, "s", "--duration"), "--duration", duration)
    if kind == "step":
        exp = step_test(
            structure, values, y0=_quantity(y0, "m", "--y0"),
            y_ref=_quantity(y_ref, "m", "--y-ref"),
            step_time=_quantity(step_time, "s", "--step-time"), duration=length,
            kp=_quantity(kp, "V/m", "--kp"), kd=_quantity(kd, "V*s/m", "--kd"),
            umax=_quantity(umax, "V", "--umax"), rate=fs,
        )  # fmt: skip
    else:
        from pneumafit.models import parameter_vector
        from pneumafit.models.layout import P

        stroke = float(parameter_vector(values)[P["stroke"]])
        blocked_at = _quantity(position, "m", "--position")
        if not 0.0 <= blocked_at <= stroke:
            raise PneumafitInputError(
                f"option --position: expected a position within the stroke [0, {stroke:g}] m, "
                f"found {position!r}"
            )
        exp = blocked_test(
            kind, values, chamber=chamber, position=blocked_at,
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


def _lambda_e(value: float | None) -> float | None:
    """``--lambda-e`` when given: a positive finite heat-transfer coefficient."""
    if value is not None and not (math.isfinite(value) and value > 0):
        raise PneumafitInputError(
            f"option --lambda-e: expected a positive heat-transfer coefficient in W/m^2/K, "
            f"found {value!r}"
        )
    return value


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
    lambda_e = _lambda_e(lambda_e)
    check_output(out, "folder")
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
    lambda_e = _lambda_e(lambda_e)
    check_output(out, "folder")
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
    lambda_e = _lambda_e(lambda_e)
    check_output(out, "folder")
    from pneumafit.outputs.closed_loop_report import run_closed_loop

    numbers, _, unit = steps.strip().partition(" ")
    y_op = None
    if position is not None:
        from pneumafit.analysis.closed_loop import read_plant_file
        from pneumafit.models.layout import P
        from pneumafit.models.parameters import parameter_vector

        y_op = _quantity(position, "m", "--position")
        stroke = float(parameter_vector(read_plant_file(params)[1])[P["stroke"]])
        if not 0.0 <= y_op <= stroke:
            raise PneumafitInputError(
                f"option --position: expected a position within the stroke [0, {stroke:g}] m, "
                f"found {position!r}"
            )
    _positive(_quantity(umax, "V", "--umax"), "--umax", umax)
    results = run_closed_loop(
        params, out, plant=plant, w0=w0, position=y_op,
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
    format: Annotated[str, typer.Option("--format", help="json, yaml, c, mat, csv or fmu.")],
    out: Annotated[Path, typer.Option("--out", help="File to write (c: the header, .h).")],
    order: Annotated[int, typer.Option(help="Design model: 4 or 6.")] = 6,
    placement: Annotated[
        str | None, typer.Option(help="dominant (validated default) or itae.")
    ] = None,
    w0: Annotated[
        float | None,
        typer.Option(help="ITAE frequency scale (rad/s); default closed-loop's (largest_w0)."),
    ] = None,
    compensate: Annotated[
        bool | None,
        typer.Option("--compensate/--no-compensate", help="Dead-band compensation (default on)."),
    ] = None,
    closed_loop: Annotated[
        Path | None,
        typer.Option("--closed-loop", help="closed_loop.json whose design to export."),
    ] = None,
    positions: PositionsOption = None,
    lambda_e: LambdaOption = None,
    sil: Annotated[
        bool,
        typer.Option("--sil", help="c: compile controller.c and run it in the loop (sil.json)."),
    ] = False,
) -> None:
    """Export the validated controller: parameters, linear models, gain schedule, C code."""
    lambda_e = _lambda_e(lambda_e)
    check_output(out, "file")
    from pneumafit.models.layout import P
    from pneumafit.outputs.export import FORMATS, export_document, write_export

    if format == "fmu":
        try:
            from pneumafit.outputs.fmu import build_fmu
        except ImportError as exc:
            err_console.print(
                f"[bold red]error:[/bold red] --format fmu: the FMU exporter "
                f"(pneumafit.outputs.fmu) is not available in this installation ({exc})"
            )
            raise typer.Exit(2) from None
        written = build_fmu(fit, out)
        console.print(f"wrote {written}")
        return
    if format not in FORMATS:
        raise PneumafitInputError(
            f"option --format: expected one of {', '.join((*FORMATS, 'fmu'))}, found {format!r}"
        )
    params, _, _, _ = _fit_parameters(fit)
    ys = None if positions is None else _positions(positions, params[P["stroke"]])
    doc = export_document(fit, order=order, placement=placement, w0=w0, compensate=compensate,
                          positions=ys, lambda_e=lambda_e, closed_loop=closed_loop)  # fmt: skip
    write_export(doc, out, format)
    extra = " and " + str(out.with_suffix(".c")) if format == "c" else ""
    console.print(
        f"wrote {out}{extra}: {doc['design']['description']}; "
        f"{len(doc['grid']['positions'])} breakpoints"
        + (f" ({len(doc['skipped'])} positions left out)" if doc["skipped"] else "")
    )
    if not sil:
        return
    if format != "c":
        raise PneumafitInputError("option --sil: runs the C controller; use it with --format c")
    import json

    from pneumafit.fileio import write_text_atomic
    from pneumafit.outputs.c_controller import sil_for_fit

    try:
        result = sil_for_fit(doc, out, fit, closed_loop=closed_loop)
    except RuntimeError as exc:  # no compiler, or the code does not compile
        err_console.print(f"[bold red]error:[/bold red] --sil: {exc}")
        raise typer.Exit(1) from None
    write_text_atomic(out.with_name("sil.json"), json.dumps(result, indent=2) + "\n")
    table = Table(title="software in the loop: Python law / compiled controller.c")
    for column in ("step", "overshoot", "settling", "final error", "air"):
        table.add_column(column, justify="right")

    def pair(p: dict, c: dict, key: str, scale: float, spec: str, unit: str) -> str:
        both = [("-" if r.get(key) is None else f"{r[key] * scale:{spec}}") for r in (p, c)]
        return f"{both[0]} / {both[1]} {unit}"

    for p, c in zip(result["python"]["steps"], result["c"]["steps"], strict=True):
        table.add_row(
            f"{p['size_m'] * 1e3:+.1f} mm", pair(p, c, "overshoot_m", 1e3, ".2f", "mm"),
            pair(p, c, "settling_time_s", 1.0, ".3f", "s"),
            pair(p, c, "final_error_m", 1e3, "+.3f", "mm"),
            pair(p, c, "air_mass_kg", 1e6, ".1f", "mg"),
        )  # fmt: skip
    console.print(table)
    console.print(
        f"largest command difference {result['max_command_difference_V']} V over "
        f"{result['samples']} samples; figures identical: {result['identical_figures']}; "
        f"wrote {out.with_name('sil.json')}"
    )
    if not result["identical_figures"]:
        raise typer.Exit(1)


#: What the environment refuses (permissions, a read-only or full disk): a
#: message about the path and exit status 2, not a bug.
_ENVIRONMENT_ERRNOS = frozenset({errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC,
                                 errno.EDQUOT})  # fmt: skip

_REPORT_BUG = (
    "This is a bug in pneumafit; please report it with the traceback that the same command "
    "prints with PNEUMAFIT_DEBUG=1."
)


def main() -> None:
    """Entry point: run the app; turn input errors into messages, not tracebacks.

    Typer (standalone mode) handles usage errors, ``--help`` and exit codes
    itself and leaves by ``SystemExit``; what reaches the handlers below is
    bad input found while working (one message, exit status 2), a path the
    system refuses to read or write (permission, read-only or full disk: one
    message, 2), an interrupt (130) or a bug ("internal error", exit status
    1, with how to report it; traceback with ``PNEUMAFIT_DEBUG=1``).
    """
    debug = os.environ.get("PNEUMAFIT_DEBUG") == "1"
    try:
        app()
    except PneumafitInputError as exc:
        if debug:
            raise
        err_console.print(f"[bold red]error:[/bold red] {escape(str(exc))}")
        sys.exit(EXIT_BAD_INPUT)
    except PneumafitComputationError as exc:  # the work failed on valid input: not a bug
        if debug:
            raise
        err_console.print(f"[bold red]failed:[/bold red] {escape(str(exc))}")
        sys.exit(EXIT_FAILED)
    except OSError as exc:
        if debug or exc.errno not in _ENVIRONMENT_ERRNOS:
            _internal_error(exc, debug)
        where = exc.filename if exc.filename is not None else "a file"
        err_console.print(
            f"[bold red]error:[/bold red] cannot write or read {escape(str(where))}: "
            f"{escape(str(exc.strerror))}; "
            "check the path, its permissions and the free space"
        )
        sys.exit(EXIT_BAD_INPUT)
    except KeyboardInterrupt:
        err_console.print("interrupted")
        sys.exit(EXIT_INTERRUPTED)
    except Exception as exc:
        _internal_error(exc, debug)


def _internal_error(exc: BaseException, debug: bool) -> None:
    """Re-raise under ``PNEUMAFIT_DEBUG=1``, else one line and exit status 1."""
    if debug:
        raise exc
    err_console.print(
        f"[bold red]internal error:[/bold red] {type(exc).__name__}: {escape(str(exc))}\n"
        f"{_REPORT_BUG}"
    )
    sys.exit(EXIT_FAILED)
