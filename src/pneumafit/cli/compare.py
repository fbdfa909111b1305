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
    OUT/figures/<recording>.png   measured vs the models, and residuals
    OUT/fits/<model>/fit.json     the fits made here (and chains.h5 with MCMC)

Every file appears atomically; comparison.json is written last.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.text import Text

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import folder_problem, int_problem, report_problems
from pneumafit.cli.fit import (
    EXIT_BAD_INPUT,
    EXIT_OK,
    FIT_FILE,
    MAX_SAMPLED,
    fit_command,
)
from pneumafit.comparison.evaluate import fit_values
from pneumafit.comparison.figures import plot_recording
from pneumafit.comparison.information import DEFAULT_DRAWS
from pneumafit.comparison.report import print_table
from pneumafit.comparison.result import COMPARISON_FILE, compare_fits
from pneumafit.identification.fitfile import SavedFit
from pneumafit.identification.staged import FitResult
from pneumafit.models.parts import MODEL_NAMES
from pneumafit.models.structure import MODELS

__all__ = ["COMPARED_MODELS", "COMPARISON_FILE", "compare_command", "read_fit"]

#: The models compared, in table order.
COMPARED_MODELS = MODEL_NAMES  # the heat laws, model-list order (models.parts, live)


def read_fit(path: Path, option: str = "--fits") -> tuple[Path, dict[str, Any]]:
    """The fit.json of a fit folder (or the file itself), parsed.

    Parameters
    ----------
    path : Path
        A folder holding fit.json (written by ``pneumafit fit``) or a fit.json.
    option : str
        The option it was given with, for messages.

    Returns
    -------
    file : Path
    document : dict

    Raises
    ------
    PneumafitInputError
        No fit.json, unreadable, invalid JSON or not a fit document.
    """
    file = path / FIT_FILE if path.is_dir() else path
    if not path.exists():
        raise PneumafitInputError(
            f"option {option} {os.fspath(path)!r}: expected a fit folder holding {FIT_FILE} "
            "(written by pneumafit fit), found nothing at that path"
        )
    if not file.is_file():
        raise PneumafitInputError(
            f"option {option} {os.fspath(path)!r}: expected a fit folder holding {FIT_FILE} "
            f"(written by pneumafit fit), found a folder without {FIT_FILE}"
        )
    document = dict(FitResult.load(file).document)  # the one reader of fit.json
    fit_values(document, os.fspath(file))  # format, model and parameters
    return file, document


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
    t_start = time.perf_counter()
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

    # ------------------------------------------------------------------ fits
    chosen: dict[str, tuple[Path, dict[str, Any]]] = {}
    sources: dict[str, dict[str, Any]] = {}
    todo = [m for m in COMPARED_MODELS if m not in given]
    for k, model in enumerate(COMPARED_MODELS):
        if model in given:
            file, document = given[model]
            console.print(f"[{k + 1}/{len(COMPARED_MODELS)}] {model}: reusing {file}")
            chosen[model] = given[model]
            sources[model] = {"file": os.fspath(file), "given": True}
            continue
        folder = out / "fits" / model
        console.print(f"[{k + 1}/{len(COMPARED_MODELS)}] {model}: fitting into {folder} "
                      f"({todo.index(model) + 1} of {len(todo)} fits to make)")  # fmt: skip
        t0 = time.perf_counter()
        code = fit_command(camp.path or Path(campaign), model, folder, walkers, steps, seed,
                           mcmc, console)  # fmt: skip
        if code != EXIT_OK:
            console.print(Text(f"{model}: the fit stopped (exit status {code})", "bold red"))
            return code
        chosen[model] = read_fit(folder)
        sources[model] = {"file": os.fspath(folder / FIT_FILE), "given": False,
                          "seconds": time.perf_counter() - t0}  # fmt: skip

    # ------------------------------------------------------------- evaluate
    comparison = compare_fits(
        camp, {m: SavedFit.from_document(d, os.fspath(f)) for m, (f, d) in chosen.items()},
        draws=draws, seed=seed, sources=sources, log=console.print,
    )  # fmt: skip
    evaluations = comparison.evaluations

    # -------------------------------------------------------------- figures
    written: list[str] = []
    if figures:
        chambers = {r.file: r.chamber for r in camp.recordings}
        names = [tr.recording for tr in evaluations[0].traces]
        for name in names:
            traces = {
                ev.model: tr for ev in evaluations for tr in ev.traces if tr.recording == name
            }
            role = next(iter(traces.values())).role
            rel = Path("figures") / f"{Path(name).stem}.png"
            plot_recording(traces, out / rel, chamber=chambers.get(name),
                           title=f"{name} ({role})")  # fmt: skip
            written.append(rel.as_posix())
        console.print(f"wrote {len(written)} figures in {out / 'figures'}")

    command = (
        f"pneumafit compare {os.fspath(campaign)} --out {os.fspath(out)}"
        + "".join(f" --fits {os.fspath(p)}" for p in fits)
        + (f" --walkers {walkers}" if walkers is not None else "")
        + (f" --steps {steps}" if steps is not None else "")
        + f" --seed {seed}"
        + ("" if mcmc else " --no-mcmc")
    )
    document = comparison.document
    document["figures"] = written
    document["provenance"].update(command=command, seconds=time.perf_counter() - t_start)
    comparison.save(out / COMPARISON_FILE)
    print_table(document, console)
    console.print(f"wrote {out / COMPARISON_FILE}")
    return EXIT_OK
