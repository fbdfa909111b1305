"""The residual analysis of every compared fit, saved beside comparison.json.

``comparison/residuals.json`` (format ``pneumafit-residuals``, version 1) and
its figures ``comparison/residuals/<model>_<k>.png`` are written by the
comparison (:func:`pneumafit.services.compare.compare_folder`) from the
replays it saves, and read by the validation report, which then runs no
residual analysis of its own for a fit this file holds. Per model: the
fingerprint of the fit analysed (:func:`~pneumafit.comparison.replays.replay_fingerprint`),
one row per recording and channel (:class:`~pneumafit.discovery.residuals.SummaryRow`,
furthest from white first; non-finite numbers as null), the recordings that
could not be analysed, and (for the fits of :data:`FIGURE_MODELS`, the one
the report shows) the figures of the recordings furthest from white.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from pneumafit.campaign.model import Campaign
from pneumafit.comparison.replays import ModelReplay
from pneumafit.errors import PneumafitInputError
from pneumafit.fileio import write_text_atomic
from pneumafit.identification.fitfile import json_safe

__all__ = [
    "FIGURE_MODELS",
    "RESIDUALS_FILE",
    "RESIDUALS_FORMAT",
    "load_residuals",
    "save_residuals",
]

#: The residual analysis of every fit, beside comparison.json.
RESIDUALS_FILE = "residuals.json"
RESIDUALS_FORMAT = "pneumafit-residuals"
#: The fits whose residual figures are drawn: the one the report shows (the
#: paper's full convection model); every fit gets its rows. Drawing the
#: three recordings furthest from white costs ~0.6 s per figure (demo).
FIGURE_MODELS = ("convection",)


def save_residuals(
    folder: Path,
    campaign: Campaign,
    replays: list[ModelReplay],
    figure_models: tuple[str, ...] | None = FIGURE_MODELS,
) -> Path:
    """Write ``folder/residuals.json`` and its figures: each replayed fit's
    residual analysis (``residual_analysis`` per recording, ranked by
    ``summarize``) and the figures of its recordings furthest from white.

    Parameters
    ----------
    folder : Path
        The comparison folder.
    campaign : Campaign
    replays : list of ModelReplay
        The comparison's replays (:attr:`Comparison.replays`).
    figure_models : tuple of str, optional
        The fits whose figures are drawn (None: every fit).

    Returns
    -------
    Path
        The file written (atomically, after its figures).
    """
    from pneumafit.discovery import plot_residuals, summarize
    from pneumafit.outputs.report_models import residual_reports, worst_recordings

    models: dict[str, Any] = {}
    for replay in replays:
        reports, problems = residual_reports(campaign, replay)
        rows = summarize(reports)
        by_name = {rep.recording: rep for rep in reports}
        figures = []
        drawn = figure_models is None or replay.model in figure_models
        for k, name in enumerate(worst_recordings(rows) if drawn else []):
            rel = Path("residuals") / f"{replay.model}_{k}.png"
            plot_residuals(by_name[name], folder / rel)
            figures.append({"file": rel.as_posix(), "recording": name})
        models[replay.model] = {
            "fingerprint": replay.fingerprint,
            "rows": [asdict(r) for r in rows],
            "problems": problems,
            "figures": figures,
        }
    doc = {
        "format": RESIDUALS_FORMAT,
        "version": 1,
        "campaign": {"name": campaign.name, "sha256": dict(campaign.sha256)},
        "models": models,
    }
    path = folder / RESIDUALS_FILE
    write_text_atomic(path, json.dumps(json_safe(doc), indent=1, allow_nan=False) + "\n")
    return path


def load_residuals(path: Path, sha256: Mapping[str, str]) -> dict[str, dict[str, Any]]:
    """The residual analyses saved in ``path`` for the campaign with these file hashes.

    Returns
    -------
    dict
        Model -> ``fingerprint`` (of the fit analysed), ``rows`` (objects
        with :class:`~pneumafit.discovery.residuals.SummaryRow`'s fields, None
        read back as NaN), ``problems``, ``figures`` (list of (path, recording)).

    Raises
    ------
    PneumafitInputError
        Not a residuals file, or saved for other campaign files.
    """
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PneumafitInputError(f"{path}: cannot be read as JSON: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != RESIDUALS_FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise PneumafitInputError(f"{path}: format: expected {RESIDUALS_FORMAT!r}, found {found!r}")
    saved_for = (doc.get("campaign") or {}).get("sha256")
    if saved_for != dict(sha256):
        raise PneumafitInputError(f"{path}: campaign.sha256: saved for other campaign files")
    out: dict[str, dict[str, Any]] = {}
    for model, entry in (doc.get("models") or {}).items():
        try:
            rows = [
                SimpleNamespace(**{k: (math.nan if v is None else v) for k, v in row.items()})
                for row in entry["rows"]
            ]
            figures = [(Path(path).parent / f["file"], str(f["recording"]))
                       for f in entry.get("figures", [])]  # fmt: skip
            out[str(model)] = {
                "fingerprint": str(entry.get("fingerprint", "")),
                "rows": rows,
                "problems": [str(p) for p in entry.get("problems", [])],
                "figures": figures,
            }
        except (KeyError, TypeError, AttributeError) as exc:
            raise PneumafitInputError(f"{path}: models.{model}: not readable ({exc})") from exc
    return out
