"""The comparison service: fit (or reuse) the three models, compare them, write the folder.

:func:`compare_folder` is ``pneumafit compare`` without its console. It
writes ``OUT``::

    OUT/comparison.json             format pneumafit-comparison (comparison/report.py)
    OUT/replays.npz                 every fit's replay of every recording, for the report
    OUT/residuals.json              every fit's residual analysis (whiteness, phases)
    OUT/residuals/<model>_<k>.png   the convection fit's: the recordings furthest from white
    OUT/figures/<recording>.png     measured vs the models, and residuals
    OUT/fits/<model>/fit.json       the fits made here (and chains.h5 with MCMC)

Every file appears atomically; comparison.json is written last. The report
reads the replays and the residual analysis (``outputs/report.py``); it
computes neither for a fit these files hold.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from pneumafit.campaign.model import Campaign
from pneumafit.comparison.evaluate import fit_values
from pneumafit.comparison.figures import plot_recording
from pneumafit.comparison.information import DEFAULT_DRAWS
from pneumafit.comparison.result import COMPARISON_FILE, Comparison, compare_fits
from pneumafit.errors import PneumafitInputError
from pneumafit.identification.fitfile import FIT_FILE, SavedFit
from pneumafit.identification.staged import FitOptions, FitResult
from pneumafit.models.parts import MODEL_NAMES
from pneumafit.outputs.residual_file import RESIDUALS_FILE, save_residuals
from pneumafit.progress import Reporter
from pneumafit.services.fit import fit_folder, output_folder

__all__ = [
    "COMPARED_MODELS",
    "RESIDUALS_FILE",
    "compare_folder",
    "read_fit",
]

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
    path = Path(path)
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


def compare_folder(
    campaign: Campaign,
    out: str | os.PathLike[str],
    given: Mapping[str, tuple[Path, dict[str, Any]]] | None = None,
    *,
    options: FitOptions | None = None,
    seed: int = 0,
    draws: int = DEFAULT_DRAWS,
    figures: bool = True,
    command: str = "",
    fit_command: Callable[[str, Path], str] | None = None,
    log: Callable[[str], None] | None = None,
    progress: Reporter | None = None,
    on_fit: Callable[[str, FitResult, Path], None] | None = None,
) -> Comparison:
    """Fit the models not given, compare all of them, and write the folder ``out``.

    Parameters
    ----------
    campaign : Campaign
    out : path
        Output folder (created).
    given : mapping, optional
        Model -> (fit.json path, its document) of fits to reuse
        (:func:`read_fit`, checked to be of this campaign by the caller); the
        other models are fitted into ``OUT/fits/<model>``
        (:func:`~pneumafit.services.fit.fit_folder`).
    options : FitOptions, optional
        Options of the fits made here.
    seed : int
        Seed of the fits made here and of the posterior draws.
    draws : int
        Posterior draws for WAIC/LOO per model.
    figures : bool
        Write the per-recording figures.
    command : str
        The command line, for comparison.json's provenance.
    fit_command : callable, optional
        (model, folder) -> the command line recorded in a fit made here.
    log : callable, optional
        Progress lines.
    progress : Reporter, optional
        Progress of the fits' long loops.
    on_fit : callable, optional
        Called with (model, result, folder) after each fit made here (the
        command line prints its summary).

    Returns
    -------
    Comparison
        As saved in ``OUT/comparison.json``.

    Raises
    ------
    PneumafitInputError, PneumafitComputationError
        From a fit made here, or ``out`` cannot be created.
    KeyboardInterrupt
        Interrupted (a fit's MCMC chains are kept in its folder).
    """
    say = log or (lambda _line: None)
    started = time.perf_counter()
    out = output_folder(out)
    given = dict(given or {})
    chosen: dict[str, tuple[Path, dict[str, Any]]] = {}
    sources: dict[str, dict[str, Any]] = {}
    todo = [m for m in COMPARED_MODELS if m not in given]
    for k, model in enumerate(COMPARED_MODELS):
        if model in given:
            file, _document = given[model]
            say(f"[{k + 1}/{len(COMPARED_MODELS)}] {model}: reusing {file}")
            chosen[model] = given[model]
            sources[model] = {"file": os.fspath(file), "given": True}
            continue
        folder = out / "fits" / model
        say(f"[{k + 1}/{len(COMPARED_MODELS)}] {model}: fitting into {folder} "
            f"({todo.index(model) + 1} of {len(todo)} fits to make)")  # fmt: skip
        t0 = time.perf_counter()
        say(f"fitting {model} to {campaign.name} ({len(campaign.by_role('fit'))} fit recordings)")
        result = fit_folder(
            campaign, model, folder, options=options, seed=seed,
            command=fit_command(model, folder) if fit_command else "", log=log,
            progress=progress,
        )  # fmt: skip
        if on_fit is not None:
            on_fit(model, result, folder)
        chosen[model] = read_fit(folder)
        sources[model] = {"file": os.fspath(folder / FIT_FILE), "given": False,
                          "seconds": time.perf_counter() - t0}  # fmt: skip

    comparison = compare_fits(
        campaign, {m: SavedFit.from_document(d, os.fspath(f)) for m, (f, d) in chosen.items()},
        draws=draws, seed=seed, sources=sources, log=say,
    )  # fmt: skip
    written: list[str] = []
    if figures:
        chambers = {r.file: r.chamber for r in campaign.recordings}
        evaluations = comparison.evaluations
        names = [tr.recording for tr in evaluations[0].traces] if evaluations else []
        for name in names:
            traces = {
                ev.model: tr for ev in evaluations for tr in ev.traces if tr.recording == name
            }
            role = next(iter(traces.values())).role
            rel = Path("figures") / f"{Path(name).stem}.png"
            plot_recording(traces, out / rel, chamber=chambers.get(name),
                           title=f"{name} ({role})")  # fmt: skip
            written.append(rel.as_posix())
        say(f"wrote {len(written)} figures in {out / 'figures'}")
    if comparison.replays:
        try:
            save_residuals(out, campaign, comparison.replays)
        except Exception as exc:  # an optional artifact: the report analyses it itself
            (out / RESIDUALS_FILE).unlink(missing_ok=True)
            say(f"residual analysis not saved ({type(exc).__name__}: {exc}); the report "
                "will run it and show what fails")  # fmt: skip
    document = comparison.document
    document["figures"] = written
    document["provenance"].update(command=command, seconds=time.perf_counter() - started)
    comparison.save(out / COMPARISON_FILE)
    return comparison
