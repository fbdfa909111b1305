"""Body of ``pneumafit discover`` on friction tests (a base fit of model ``friction``).

The work and the files are the service's
(:func:`pneumafit.services.friction.friction_discover_folder`). Same contract
as the cylinder discovery (:mod:`pneumafit.cli.discover`):
``OUT/discovery.json`` (format ``pneumafit-discovery``, version 1, the same
top-level keys where they mean something here: ``base_model``,
``candidates``, ``rounds``, ``refits``, ``selected``, ``rmse_before`` /
``rmse_after`` (role -> ``{"F": N}``), ``bic_before`` / ``bic_after``,
``effect_parameters``, ``parameters_after``, ``statement``, ...; plus
``rmse_by_recording_before`` / ``_after``), ``OUT/discovery.md`` with the
before/after table, ``OUT/force_residuals.png`` (force residual against the
chamber pressure, before and after). Exit 0 done, 1 failed, 2 bad input,
130 interrupted.
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
    EXIT_OK,
    console_log,
    folder_problem,
    int_problem,
    report_problems,
    run_guarded,
)
from pneumafit.cli.discover import report_selection
from pneumafit.identification.staged import FitResult
from pneumafit.outputs.friction_report import before_after_rows
from pneumafit.services.discover import base_fit_seed, discover_command_line
from pneumafit.services.friction import (
    friction_discover_folder,
    friction_discovery_document,
    load_friction_fit,
)

__all__ = [
    "friction_discover_command",
    "friction_discovery_document",
    "is_friction_fit",
    "report_friction_discovery",
]


def is_friction_fit(fit: Path) -> bool:
    """True when ``fit`` (a fit.json or its folder) is a fit of model ``friction``."""
    try:
        return FitResult.load(fit).model == "friction"
    except PneumafitInputError:
        return False  # not a readable fit: the actuator discovery says why


def summary_table(doc: Mapping[str, Any]) -> Table:
    """The before/after force RMSE table of a friction discovery."""
    table = Table(title=Text("force RMSE (N): before -> after discovery"))
    for col in ("recording", "role", "before", "after", "change"):
        table.add_column(col, justify="left" if col in ("recording", "role") else "right")
    for row in before_after_rows(doc):
        table.add_row(*row)
    return table


def friction_discover_command(
    campaign: Path,
    fit: Path,
    out: Path,
    *,
    seed: int | None = None,
    rounds: int = 3,
    per_round: int = 3,
    console: Console,
) -> int:
    """Discovery on a friction-test campaign; see the module docstring.

    ``seed`` None: the seed the base fit was made with (0 if it records none).
    """
    from pneumafit.campaign import read_campaign

    out = Path(out)
    problems = [
        int_problem("--seed", seed, 0),
        int_problem("--rounds", rounds, 1),
        int_problem("--per-round", per_round, 1),
        folder_problem(out),
    ]
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    try:
        camp = read_campaign(campaign)
        saved, fit_path = load_friction_fit(Path(fit), camp)
    except (PneumafitInputError, ValueError) as exc:
        console.print(Text(str(exc), style="bold red"))
        return EXIT_BAD_INPUT
    seed = base_fit_seed(seed, saved)
    recs = camp.by_kind("friction")
    console.print(
        f"discovery on {camp.name}: base model friction "
        f"({saved.friction}) from {fit_path} "
        f"({sum(r.role == 'fit' for r in recs)} fit, "
        f"{sum(r.role == 'validate' for r in recs)} validate friction tests)"
    )
    command = discover_command_line(campaign, fit, out, seed, rounds, per_round)
    done, status = run_guarded(
        console,
        lambda: friction_discover_folder(
            camp, fit_path, out, seed=seed, rounds=rounds, per_round=per_round,
            command=command, log=console_log(console),
        ),
        campaign=campaign, failed="discovery failed", interrupted="interrupted: nothing written",
    )  # fmt: skip
    if status is not None or done is None:
        return status if status is not None else EXIT_FAILED
    report_friction_discovery(done.document, console)
    console.print("wrote " + ", ".join(os.fspath(p) for p in done.files))
    return EXIT_OK


def report_friction_discovery(doc: Mapping[str, Any], console: Console) -> None:
    """The console summary of a friction discovery (discovery.json's content)."""
    console.print(summary_table(doc))
    report_selection(doc, console)
