"""Body of ``pneumafit compare``: fit (or reuse) the three models and compare them.

``compare_command`` checks every input before any work and reports bad input
as one message per problem naming the option or file, what was expected and
what was found (exit status 2, no traceback). The fits it makes are those of
``pneumafit fit`` (:func:`~pneumafit.cli.fit.fit_command`),
written to ``OUT/fits/<model>/``; a model given with ``--fits`` is not
refitted.

Output folder ``OUT``::

    OUT/comparison.json           format pneumafit-comparison (report.py)
    OUT/replays.npz               every fit's replay of every recording, for the report
    OUT/residuals.json            every fit's residual analysis, for the report
    OUT/residuals/<model>_<k>.png its figures (the convection fit's)
    OUT/figures/<recording>.png   measured vs the models, and residuals
    OUT/fits/<model>/fit.json     the fits made here (and chains.h5 with MCMC)

Every file appears atomically; comparison.json is written last.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.text import Text

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    EXIT_FAILED,
    console_log,
    folder_problem,
    int_problem,
    report_problems,
    run_guarded,
)
from pneumafit.cli.fit import (
    EXIT_BAD_INPUT,
    EXIT_OK,
    MAX_SAMPLED,
    report_fit,
)
from pneumafit.comparison.information import DEFAULT_DRAWS
from pneumafit.comparison.report import print_table
from pneumafit.comparison.result import COMPARISON_FILE
from pneumafit.identification.staged import FitOptions, FitResult
from pneumafit.models.structure import MODELS
from pneumafit.progress import Reporter
from pneumafit.services.compare import COMPARED_MODELS, compare_folder, read_fit
from pneumafit.services.fit import fit_command_line, interrupted_message, partial_path

__all__ = ["COMPARED_MODELS", "COMPARISON_FILE", "compare_command", "read_fit"]


def _same_campaign(file: Path, document: dict[str, Any], sha256: dict[str, str], name: str) -> str:
    """'' when the fit was made on this campaign (same file hashes), else the problem."""
    campaign = document.get("campaign")
    if not isinstance(campaign, dict):
        return f"{file}: campaign: expected an object, found {type(campaign).__name__}"
    theirs = campaign.get("sha256")
    if theirs == sha256:
        return ""
    if not isinstance(theirs, dict):
        return (f"{file}: campaign.sha256: expected the file hashes of campaign {name!r}, "
                f"found {theirs!r}")  # fmt: skip
    differ = sorted(k for k in set(theirs) | set(sha256) if theirs.get(k) != sha256.get(k))
    other = campaign.get("name")
    return (
        f"{file}: campaign.sha256: expected the file hashes of campaign {name!r} (the CAMPAIGN "
        f"argument), found those of campaign {other!r}, which differ for "
        f"{', '.join(differ[:5])}{' ...' if len(differ) > 5 else ''}"
    )


def compare_command(
    campaign: Path,
    out: Path,
    fits: Sequence[Path] = (),
    walkers: int | None = None,
    steps: int | None = None,
    seed: int = 0,
    mcmc: bool = True,
    console: Console | None = None,
    *,
    draws: int = DEFAULT_DRAWS,
    figures: bool = True,
) -> int:
    """Fit or reuse the three models, replay the campaign, write ``OUT/comparison.json``.

    Parameters
    ----------
    campaign : Path
        Campaign folder (or its campaign.toml).
    out : Path
        Output folder (created).
    fits : sequence of Path
        Fit folders (``pneumafit fit --out``) to reuse, at most one per model;
        the models without one are fitted into ``OUT/fits/<model>``.
    walkers, steps, seed, mcmc
        Passed to the fits made here (see ``pneumafit fit``).
    console : rich.console.Console, optional
    draws : int
        Posterior draws for WAIC/LOO per model.
    figures : bool
        Write the per-recording figures.

    Returns
    -------
    int
        0 ok, 1 a fit failed, 2 bad input, 130 interrupted.
    """
    from pneumafit.campaign import read_campaign

    console = console or Console()
    out = Path(out)
    problems = [
        int_problem("--walkers", walkers, 2 * MAX_SAMPLED),
        int_problem("--steps", steps, 1),
        int_problem("--seed", seed, 0),
        int_problem("draws", draws, 4),
    ]
    problems.append(folder_problem(out))
    camp = None
    try:
        camp = read_campaign(campaign)
    except PneumafitInputError as exc:
        problems.append(str(exc))
    given: dict[str, tuple[Path, dict[str, Any]]] = {}
    for path in fits:
        try:
            file, document = read_fit(Path(path))
        except PneumafitInputError as exc:
            problems.append(str(exc))
            continue
        model = document["model"]
        if model in given:
            problems.append(
                f"option --fits: expected at most one fit per model, found two {model} fits: "
                f"{given[model][0]} and {file}"
            )
            continue
        if model not in COMPARED_MODELS:
            problems.append(f"{file}: model: expected one of {', '.join(MODELS)}, found {model!r}")
            continue
        if camp is not None:
            mismatch = _same_campaign(file, document, dict(camp.sha256), camp.name)
            if mismatch:
                problems.append(mismatch)
                continue
        given[model] = (file, document)
    if report_problems(console, problems) or camp is None:
        return EXIT_BAD_INPUT
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        message = f"option --out {os.fspath(out)!r}: cannot be created: {exc}"
        console.print(Text(message, "bold red"))
        return EXIT_BAD_INPUT

    command = (
        f"pneumafit compare {os.fspath(campaign)} --out {os.fspath(out)}"
        + "".join(f" --fits {os.fspath(p)}" for p in fits)
        + (f" --walkers {walkers}" if walkers is not None else "")
        + (f" --steps {steps}" if steps is not None else "")
        + f" --seed {seed}"
        + ("" if mcmc else " --no-mcmc")
    )
    options = FitOptions(mcmc=mcmc, walkers=walkers, steps=steps, progress=console.is_terminal)
    campaign_path = camp.path or Path(campaign)

    say = console_log(console)

    def stopped(model_folder: Path) -> str:
        return interrupted_message(partial_path(model_folder) if mcmc else None)

    current: list[Path] = []

    def fitted(model: str, result: FitResult, folder: Path) -> None:
        report_fit(result, folder, console)

    def fit_line(model: str, folder: Path) -> str:
        current[:] = [folder]
        return fit_command_line(campaign_path, model, folder, walkers, steps, seed, mcmc)

    comparison, status = run_guarded(
        console,
        lambda: compare_folder(
            camp, out, given, options=options, seed=seed, draws=draws, figures=figures,
            command=command, fit_command=fit_line, log=say,
            progress=Reporter(say, console=console), on_fit=fitted,
        ),
        campaign=campaign, failed="comparison failed",
        interrupted=lambda: stopped(current[0]) if current else "interrupted: nothing written",
    )  # fmt: skip
    if status is not None or comparison is None:
        return status if status is not None else EXIT_FAILED
    print_table(comparison.document, console)
    console.print(f"wrote {out / COMPARISON_FILE}")
    return EXIT_OK
