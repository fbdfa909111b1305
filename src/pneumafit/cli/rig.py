"""``pneumafit rig --out DIR [--effect NAME=VALUE ...] [--truth NAME_OR_FILE] [--seed N]``.

The command body.

The command line only parses its options and calls :func:`run_rig`, which
prints a short summary and returns the exit status; bad input never escapes
as a traceback.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

from pneumafit.campaign import PneumafitInputError
from pneumafit.cli.console import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK
from pneumafit.models import EFFECT_SLOTS
from pneumafit.virtual_rig.effects import parse_effect_options
from pneumafit.virtual_rig.protocol import Protocol, get_protocol
from pneumafit.virtual_rig.virtual import (
    DEMO_SEED,
    TRUTH_FILE,
    RigError,
    RigRun,
    VirtualRig,
    check_output_folder,
)

__all__ = ["run_rig"]


def _error(console: Console, message: str) -> None:
    line = Text("error: ", style="bold red")
    line.append(message)
    console.print(line)


def run_rig(
    out: str | os.PathLike[str],
    effects: Sequence[str] = (),
    seed: int = DEMO_SEED,
    console: Console | None = None,
    protocol: str | Protocol = "demo",
    truth: str | None = None,
) -> int:
    """Record a virtual-rig campaign into ``out`` and print a summary.

    Parameters
    ----------
    out : str or os.PathLike
        Campaign folder to create (or to replace, if empty or written by the
        virtual rig before). Written atomically.
    effects : sequence of str
        ``--effect`` options, ``NAME=VALUE`` or ``NAME`` (default magnitude):
        NAME an effect (``chamber_leakage``, ``external_leakage``,
        ``valve_dynamics``, ``wall_thermal_mass``, ``forced_convection``,
        ``supply_pressure_drop``, ``seal_friction``) or one of its parameters;
        VALUE in SI units. Written to truth.json, never to campaign.toml.
    seed : int
        Seed of every random draw (>= 0); same seed, same campaign.
    console : rich.console.Console, optional
        Where to print; default standard output.
    protocol : str or Protocol
        ``"demo"`` (default), ``"quick"``, ``"tutorial"``, ``"sparse"``,
        ``"sparse-long"`` or a protocol.
    truth : str or None
        ``--truth``: an independently simulated truth, a preset name of
        :data:`pneumafit.virtual_rig.truth.PRESETS` or a TOML/JSON configuration file
        (docs/virtual-rig.md, "Mismatched truths"); None simulates the truth
        with the fitting kernel.

    Returns
    -------
    int
        0 on success, 2 on bad input (unknown effect, bad value, bad seed,
        unknown truth preset or a bad truth file, ``out`` not writable as a
        campaign), 1 when a simulation or the writing failed.
    """
    console = console if console is not None else Console()
    target = Path(out)
    try:
        parsed = parse_effect_options(effects)
        proto = get_protocol(protocol)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise PneumafitInputError(f"--seed: expected an integer >= 0, found {seed!r}")
        rig = VirtualRig(effects=parsed, seed=seed, truth=truth)
        check_output_folder(target)
    except (PneumafitInputError, ValueError) as exc:
        _error(console, str(exc))
        return EXIT_BAD_INPUT
    try:
        run = rig.write(target, proto)
    except PneumafitInputError as exc:
        _error(console, str(exc))
        return EXIT_BAD_INPUT
    except RigError as exc:
        _error(console, str(exc))
        return EXIT_FAILED
    except Exception as exc:  # the boundary: report, never a traceback
        _error(console, f"could not write {os.fspath(target)!r}: {type(exc).__name__}: {exc}")
        return EXIT_FAILED
    try:
        _summary(console, run, target)
    except Exception as exc:  # printing must not turn a written campaign into a failure
        console.print(Text(f"campaign written to {os.fspath(target)} ({exc})"))
    return EXIT_OK


def _summary(console: Console, run: RigRun, target: Path) -> None:
    truth = run.truth
    table = Table(title=Text(f"Virtual rig: {run.campaign.name}"))
    for column in ("File", "Kind", "Role", "Duration [s]", "Rate [Hz]", "Samples"):
        table.add_column(column, no_wrap=True, justify="right" if "[" in column else "left")
    for rec in run.campaign.recordings:
        table.add_row(
            *(
                Text(cell)
                for cell in (
                    rec.file,
                    rec.kind,
                    rec.role,
                    f"{rec.duration:g}",
                    f"{rec.sample_rate:.0f}",
                    str(rec.n_samples),
                )
            )
        )
    console.print(table)
    effects = truth["model"]["effects"]
    hidden = ", ".join(
        f"{name}={truth['parameters'][p]:g}"
        for name in effects
        for p in truth["model"]["parameter_names"]
        if p not in ("xi", "beta") and _owner(p) == name
    )
    console.print(Text(f"truth: {truth['model']['name']} ({truth['model']['air_properties']} air)"))
    if effects:
        console.print(Text(f"undeclared effects (only in {TRUTH_FILE}): {hidden}"))
    independent = truth.get("truth_model")
    if independent is not None:
        ref = independent["reference_quantities"]
        console.print(
            Text(
                f"independent truth (only in {TRUTH_FILE}): lambda at 5 bar/50 degC "
                f"{ref['lambda_reference']:.1f} W/m^2/K, static friction "
                f"{ref['friction_static']:.1f} N, Coulomb friction {ref['friction_coulomb']:.1f} N"
            )
        )
    lam = truth["diagnostics"].get("lambda_equivalent")
    if lam is not None:
        console.print(Text(f"equivalent lambda over the relaxations: {lam:.1f} W/m^2/K"))
    console.print(
        Text(f"seed {truth['seed']}; campaign written to {os.fspath(target)}", style="bold green")
    )


def _owner(parameter: str) -> str:
    for effect, (_, params, _) in EFFECT_SLOTS.items():
        if parameter in params:
            return effect
    return ""
