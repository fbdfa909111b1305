"""Body of ``pneumafit discover``: from a base fit to the effects the data ask for.

The work and the files are the service's
(:func:`pneumafit.services.discover.discover_folder`: discovery.json,
discovery.md and the figures, written atomically); this module checks the
options, prints the progress and the summary (:func:`report_discovery`,
also used by the main job) and turns the service's ends into exit statuses.

Exit status: 0 done (whatever was found), 1 the computation failed, 2 bad
input (a message naming the file or key, what was expected and what was
found; never a traceback), 130 interrupted.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    console_log,
    folder_problem,
    int_problem,
    report_problems,
)
from pneumafit.discovery.refit import PRESSURES
from pneumafit.progress import Reporter
from pneumafit.services.discover import (
    DISCOVERY_FORMAT,
    DISCOVERY_VERSION,
    base_fit_seed,
    discover_command_line,
    discover_folder,
    discovery_document,
    format_number,
    load_base_fit,
    write_report,
)

__all__ = [
    "DISCOVERY_FORMAT",
    "DISCOVERY_VERSION",
    "discover_command",
    "discovery_document",
    "load_base_fit",
    "report_discovery",
    "write_report",
]


# ----------------------------------------------------------------- command
def discover_command(
    campaign: Path,
    fit: Path,
    out: Path,
    *,
    seed: int | None = None,
    rounds: int | None = 2,
    per_round: int = 3,
    console: Console,
) -> int:
    """Run discovery on a campaign and its base fit; write the report into ``out``.

    Parameters
    ----------
    campaign : Path
        Campaign folder.
    fit : Path
        fit.json of the base fit, or its folder.
    out : Path
        Report folder (created; its files are replaced).
    seed : int or None
        Seeds the bootstrap and the refits (saved in discovery.json); None:
        the seed the base fit was made with (fit.json ``provenance.seed``),
        0 for a fit that does not record one.
    rounds, per_round : int
        Largest number of rounds (None: 2; on a friction fit 3), and of refits per round.
    console : rich.console.Console

    Returns
    -------
    int
        0 done, 1 failed, 2 bad input, 130 interrupted.
    """
    from pneumafit.campaign import read_campaign
    from pneumafit.cli.friction_discover import friction_discover_command, is_friction_fit

    if is_friction_fit(Path(fit)):  # friction tests: the rod-force residual (frictiontest)
        return friction_discover_command(
            campaign, fit, out, seed=seed, rounds=3 if rounds is None else rounds,
            per_round=per_round, console=console,
        )  # fmt: skip
    rounds = 2 if rounds is None else rounds
    problems = [
        int_problem("--seed", seed, 0),
        int_problem("--rounds", rounds, 1),
        int_problem("--per-round", per_round, 1),
    ]
    out = Path(out)
    problems.append(folder_problem(out))
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    try:
        camp = read_campaign(campaign)
        _base, saved, fit_path = load_base_fit(Path(fit), camp)
    except (PneumafitInputError, ValueError) as exc:
        console.print(Text(str(exc), style="bold red"))
        return EXIT_BAD_INPUT
    seed = base_fit_seed(seed, saved)
    console.print(
        f"discovery on {camp.name}: base model {saved.model} from {fit_path} "
        f"({len(camp.by_role('fit'))} fit, {len(camp.by_role('validate'))} validate recordings)"
    )

    say = console_log(console)

    command = discover_command_line(campaign, fit, out, seed, rounds, per_round)
    try:
        done = discover_folder(
            camp, fit_path, out, seed=seed, rounds=rounds, per_round=per_round,
            command=command, log=say, progress=Reporter(say, console=console),
        )  # fmt: skip
    except KeyboardInterrupt:
        console.print(Text("interrupted: nothing written", "yellow"))
        return EXIT_INTERRUPTED
    except (PneumafitInputError, ValueError) as exc:
        console.print(Text(f"{campaign}: {exc}", style="bold red"))
        return EXIT_BAD_INPUT
    except RuntimeError as exc:
        console.print(Text(f"discovery failed: {exc}", style="bold red"))
        return EXIT_FAILED
    report_discovery(done.document, console)
    console.print("wrote " + ", ".join(os.fspath(p) for p in done.files))
    return EXIT_OK


def report_discovery(doc: Mapping[str, Any], console: Console) -> None:
    """The console summary of a discovery (discovery.json's content): the
    pressure RMSE before and after, the effects selected, the statement."""
    table = Table(title=Text("pressure RMSE (Pa): before -> after"))
    for col in ("role", *PRESSURES):
        table.add_column(col, justify="left" if col == "role" else "right")
    for role in ("fit", "validate"):
        b, a = doc["rmse_before"].get(role) or {}, doc["rmse_after"].get(role) or {}
        if not b:
            continue
        table.add_row(
            role, *(f"{format_number(b.get(c))} -> {format_number(a.get(c))}" for c in PRESSURES)
        )
    console.print(table)
    report_selection(doc, console)


def report_selection(doc: Mapping[str, Any], console: Console) -> None:
    """The end of a discovery's console summary, actuator or friction tests alike:
    the effects selected, their parameters (90 % interval) and the statement."""
    sel = doc["selected"]
    console.print(
        Text("selected: " + (", ".join(sel) if sel else "none"), style="bold green" if sel else "")
    )
    for name, e in doc["effect_parameters"].items():
        iv = e.get("interval_90")
        console.print(
            f"  {name} = {format_number(e['value'])} {e['unit']}"
            + (f", 90 % [{format_number(iv[0])}, {format_number(iv[1])}]" if iv else "")
        )
    console.print(doc["statement"])
