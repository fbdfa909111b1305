"""The comparison as an object: replay fits on a campaign, score them, keep the result.

:func:`compare_fits` is the service under ``pneumafit compare`` (which adds the
fits it makes, the figures and the console table) and :func:`pneumafit.compare`:
each fit replayed on every recording (:func:`~.evaluate.evaluate_fit`), WAIC and
PSIS-LOO from its chains where it has them (:func:`~.information.posterior_criteria`),
and the comparison.json document (:func:`~.report.comparison_document`).
"""

from __future__ import annotations

import io
import json
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console

from pneumafit.campaign.model import Campaign
from pneumafit.comparison.evaluate import ModelEvaluation, evaluate_fit
from pneumafit.comparison.information import DEFAULT_DRAWS, differences, posterior_criteria
from pneumafit.comparison.replays import REPLAYS_FILE, ModelReplay, replay_model, save_replays
from pneumafit.comparison.report import comparison_document, print_table
from pneumafit.errors import PneumafitError
from pneumafit.fileio import write_text_atomic
from pneumafit.identification.fitfile import SavedFit

__all__ = ["COMPARISON_FILE", "Comparison", "compare_fits"]

#: The comparison's file in its folder (``RUN/comparison/comparison.json``).
COMPARISON_FILE = "comparison.json"


@dataclass
class Comparison:
    """Fits replayed on one campaign and scored (comparison.json, module docstring of
    :mod:`pneumafit.comparison.report`).

    Attributes
    ----------
    document : dict
        The comparison.json content: per model RMSE by role and channel, criteria
        (AIC, BIC, WAIC, LOO), per-recording errors, the best model per line.
    evaluations : list of ModelEvaluation
        Per model, the simulated traces of every recording (for figures).
    replays : list of ModelReplay
        Per model, every recording simulated for the validation report
        (:mod:`pneumafit.comparison.replays`), saved beside comparison.json.
    campaign : dict
        The campaign's identity (name, path, file hashes) the replays belong to.
    """

    document: dict[str, Any]
    evaluations: list[ModelEvaluation] = field(default_factory=list, repr=False)
    replays: list[ModelReplay] = field(default_factory=list, repr=False)
    campaign: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def models(self) -> list[str]:
        return list(self.document["models"])

    def __repr__(self) -> str:
        best = self.document["best"].get("validate", {})
        held = ", ".join(f"{c}: {m}" for c, m in best.items() if c in ("p_P", "p_N", "y") and m)
        return (
            f"Comparison({self.document['campaign']['name']}: {', '.join(self.models)}; "
            f"best held out {held or 'none'})"
        )

    def summary(self) -> str:
        """The RMSE and criteria table, as ``pneumafit compare`` prints it."""
        console = Console(file=io.StringIO(), width=140, color_system=None)
        print_table(self.document, console)
        return str(console.file.getvalue())  # type: ignore[attr-defined]

    def to_dataframe(self) -> Any:
        """One row per model, recording and channel: RMSE and the other errors (SI)."""
        import pandas as pd

        return pd.DataFrame(self.document["table"])

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write comparison.json atomically, after the replays beside it
        (:data:`~pneumafit.comparison.replays.REPLAYS_FILE`; for a comparison
        made by :func:`compare_fits`, also when no fit could be replayed)."""
        if self.replays or self.campaign:
            save_replays(Path(path).parent / REPLAYS_FILE, self.replays, self.campaign)
        text = json.dumps(self.document, indent=2, allow_nan=False) + "\n"
        write_text_atomic(Path(path), text)
        return Path(path)


def compare_fits(
    campaign: Campaign,
    fits: Mapping[str, SavedFit],
    *,
    draws: int = DEFAULT_DRAWS,
    seed: int = 0,
    sources: Mapping[str, Mapping[str, Any]] | None = None,
    log: Callable[[str], None] | None = None,
) -> Comparison:
    """Replay each fit on every recording of ``campaign`` and score them.

    Parameters
    ----------
    campaign : Campaign
        The campaign the fits were made on.
    fits : mapping of str to SavedFit
        Model name -> its fit (:meth:`FitResult.load
        <pneumafit.identification.staged.FitResult.load>`), in table order. A
        fit read from a file uses the chains beside it for WAIC/LOO.
    draws : int
        Posterior draws per model for WAIC/LOO.
    seed : int
        Seeds the draws.
    sources : mapping, optional
        Model -> where its fit came from (``file``, ``given``), recorded.
    log : callable, optional
        One line per model replayed.

    Returns
    -------
    Comparison
    """
    from pneumafit.identification.staged import campaign_identity

    say = log or (lambda _line: None)
    started = time.perf_counter()
    evaluations: list[ModelEvaluation] = []
    replays: list[ModelReplay] = []
    posteriors: dict[str, dict[str, Any]] = {}
    for model, fit in fits.items():
        where = fit.source
        t0 = time.perf_counter()
        ev = evaluate_fit(campaign, fit.document, where=where)
        evaluations.append(ev)
        say(f"{model}: simulated {len(ev.traces)} recordings ({time.perf_counter() - t0:.1f} s)")
        t0 = time.perf_counter()
        try:
            # the report's traces, every sample, saved so that it simulates nothing
            replays.append(replay_model(campaign, fit.document, where, model))
            say(f"{model}: replayed for the report ({time.perf_counter() - t0:.1f} s)")
        except PneumafitError as exc:  # the report says what is missing
            say(f"{model}: not replayed for the report: {exc}")
        t0 = time.perf_counter()
        posteriors[model] = posterior_criteria(
            campaign, fit.document, fit.chains_path, n_draws=draws, seed=seed, where=where
        )
        if posteriors[model].get("available"):
            say(f"{model}: WAIC/LOO from {posteriors[model]['n_draws']} posterior draws "
                f"({time.perf_counter() - t0:.1f} s)")  # fmt: skip
    differences(posteriors)
    document = comparison_document(
        campaign, evaluations, {m: f.document for m, f in fits.items()}, posteriors,
        sources=sources, seconds=time.perf_counter() - started,
    )  # fmt: skip
    return Comparison(document, evaluations, replays, campaign_identity(campaign))
