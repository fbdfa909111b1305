"""The discovery service: from a base fit to the effects the data ask for, written to a folder.

:func:`discover_folder` is ``pneumafit discover`` without its console
(:func:`pneumafit.cli.discover.discover_command`). It reads the campaign's
base fit (``FIT/fit.json``, written by ``pneumafit fit``), checks that the
fit was made on this campaign (the SHA-256 of every file, as fit.json
records them) with a known model, runs
:func:`~pneumafit.discovery.refit.discover` and writes, atomically:

- ``OUT/discovery.json`` (format ``pneumafit-discovery``, version 1; keys are
  only ever added): ``base_model``, ``candidates`` (first round, ranked:
  ``effect``, ``score``, ``evidence``), ``rounds`` (every round's candidates
  and attribution summary), ``refits`` (every refit tried, why kept or
  rejected), ``selected``, ``rmse_before`` / ``rmse_after`` (``fit`` and
  ``validate``: channel -> SI), ``held_out_pressure_before`` / ``_after``
  (``"FILE CHANNEL"`` -> RMSE in Pa of each held-out pressure less the
  sensor's zero: the statement's figure), ``aic_before`` / ``aic_after``,
  ``bic_before`` / ``bic_after``, ``log_likelihood_before`` / ``_after``,
  ``effect_parameters`` (name -> ``value``, ``unit``, ``std``,
  ``interval_90`` (Laplace), ``effect``), ``parameters_after`` (every
  model parameter, SI), ``unexplained`` and ``statement``,
  ``noise_pressure``, ``campaign``, ``fit``, ``seed``, ``provenance``,
  ``figures`` (file names of the figures beside it);
- ``OUT/discovery.md``: the report section (tables and figures);
- ``OUT/residuals_before.png``, ``OUT/residuals_after.png``: pressure
  residuals of every charge, discharge and step recording against the base
  and the final model; ``OUT/candidates.png``: the ranked candidates.

It raises :class:`~pneumafit.errors.PneumafitInputError` for bad input
(naming the file or key, what was expected and what was found),
:class:`~pneumafit.errors.PneumafitComputationError` when the computation or
the writing fails, and lets ``KeyboardInterrupt`` through (nothing written).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import Campaign
from pneumafit.discovery.attribution import simulate_recording
from pneumafit.discovery.catalog import get_effect
from pneumafit.discovery.refit import PRESSURES, BaseFit, Discovery, Model, discover
from pneumafit.fileio import atomic_path, write_text_atomic
from pneumafit.frictiontest.discover import FrictionDiscovery
from pneumafit.identification.fitfile import SavedFit, _version, json_safe
from pneumafit.identification.staged import FitResult, campaign_identity
from pneumafit.models.layout import SPECS
from pneumafit.models.structure import MODELS
from pneumafit.progress import Reporter

__all__ = [
    "DISCOVERY_FORMAT",
    "DISCOVERY_VERSION",
    "DiscoveryFolder",
    "base_fit_seed",
    "discover_command_line",
    "discover_folder",
    "discovery_document",
    "discovery_head",
    "effect_parameter_lines",
    "format_number",
    "load_base_fit",
    "provenance",
    "write_report",
]

DISCOVERY_FORMAT = "pneumafit-discovery"
DISCOVERY_VERSION = 1
FIT_FILE = "fit.json"


# ----------------------------------------------------------------- input
def base_fit_seed(seed: int | None, saved: SavedFit) -> int:
    """The seed of a discovery: ``seed`` as given, or the base fit's own.

    Parameters
    ----------
    seed : int or None
        The seed asked for; None: the seed the base fit was made with
        (fit.json ``provenance.seed``).
    saved : SavedFit
        The base fit as read.

    Returns
    -------
    int
        ``seed``, else the base fit's seed, else 0 (a fit that records none).
    """
    if seed is not None:
        return seed
    return saved.seed if saved.seed is not None else 0


def discover_command_line(
    campaign: str | os.PathLike[str],
    fit: str | os.PathLike[str],
    out: str | os.PathLike[str],
    seed: int,
    rounds: int,
    per_round: int,
) -> str:
    """The ``pneumafit discover`` command line of these options (discovery.json's
    ``provenance.command``), for the actuator and the friction-test discovery alike."""
    return (
        f"pneumafit discover {os.fspath(campaign)} --fit {os.fspath(fit)} --out {os.fspath(out)}"
        f" --seed {seed} --rounds {rounds} --per-round {per_round}"
    )


def load_base_fit(fit: Path, campaign: Campaign) -> tuple[BaseFit, SavedFit, Path]:
    """Read and check ``fit`` (a fit.json or the folder holding one).

    The file is read by :meth:`FitResult.load
    <pneumafit.identification.staged.FitResult.load>`; the base fit is
    :meth:`BaseFit.from_document` of what it read (with the channels,
    offsets, step and solver correction the fit was made with).

    Returns
    -------
    base : BaseFit
    fit : SavedFit
        The fit.json read (its seed: ``fit.seed``).
    path : Path
        The fit.json file.

    Raises
    ------
    PneumafitInputError
        No fit.json, not JSON, not a ``pneumafit-fit`` document, an unknown
        model, or a fit of another campaign (SHA-256 of the files differ).
    """
    path = Path(fit)
    if path.is_dir():
        path = path / FIT_FILE
    if not path.is_file():
        raise PneumafitInputError(
            f"option --fit {os.fspath(fit)!r}: expected a fit.json (from pneumafit fit) or a "
            f"folder holding one, found no file {os.fspath(path)!r}"
        )
    try:
        saved = FitResult.load(path)
    except PneumafitInputError as exc:
        detail = str(exc).removeprefix(f"{path}: ")
        if detail.startswith(("line ", "cannot be read")):  # not JSON at all
            raise PneumafitInputError(
                f"{path}: expected a JSON fit document, found: {detail}"
            ) from None
        raise
    doc = saved.document
    model = saved.model
    if model not in MODELS:
        raise PneumafitInputError(
            f"{path}: key 'model': expected one of {', '.join(MODELS)}, found {model!r}"
        )
    for key in ("campaign", "parameters", "structure", "nuisance"):
        if not isinstance(doc.get(key), dict):
            raise PneumafitInputError(
                f"{path}: key {key!r}: expected an object, found {type(doc.get(key)).__name__}"
            )
    recorded = saved.campaign_sha256
    actual = dict(campaign.sha256)
    if recorded != actual:
        differ = sorted(k for k in set(recorded) | set(actual) if recorded.get(k) != actual.get(k))
        shown = ", ".join(differ[:4]) + (" ..." if len(differ) > 4 else "")
        raise PneumafitInputError(
            f"{path}: key 'campaign.sha256': expected the SHA-256 of campaign "
            f"{campaign.name!r}'s files, found a fit of another campaign "
            f"({saved.campaign.get('name')!r}; files differing: {shown})"
        )
    try:
        base = BaseFit.from_document(saved)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise PneumafitInputError(
            f"{path}: expected a complete pneumafit-fit document, found a problem: {exc}"
        ) from None
    return base, saved, path


# ----------------------------------------------------------------- document
def _effect_parameters(model: Model) -> dict[str, Any]:
    out: dict[str, Any] = {}
    ps = model.parameters
    for effect in model.effects:
        eff = get_effect(effect)
        for name in eff.parameter_names(model.structure.effects.get(effect)):
            entry: dict[str, Any] = {
                "effect": effect,
                "value": model.values.get(name),
                "unit": SPECS[name].unit,
                "std": None,
                "interval_90": None,
                "uncertainty": "laplace",
            }
            if ps is not None and name in ps:
                p = ps[name]
                entry["std"] = p.std
                entry["interval_90"] = list(p.interval_90) if p.interval_90 else None
            out[name] = entry
    return out


def discovery_head(
    fit_doc: Mapping[str, Any], campaign: Campaign, fit_path: Path
) -> dict[str, Any]:
    """The first keys of discovery.json, actuator and friction-test discovery alike.

    Parameters
    ----------
    fit_doc : mapping
        The base fit's document (fit.json).
    campaign : Campaign
    fit_path : Path
        The base fit's file.

    Returns
    -------
    dict
        ``format``, ``version``, ``base_model``, ``base_structure``,
        ``campaign`` (name, path, SHA-256 of its files) and ``fit``, in that order.
    """
    return {
        "format": DISCOVERY_FORMAT,
        "version": DISCOVERY_VERSION,
        "base_model": fit_doc.get("model"),
        "base_structure": fit_doc.get("structure"),
        "campaign": campaign_identity(campaign),
        "fit": os.fspath(fit_path),
    }


def discovery_document(
    result: Discovery,
    campaign: Campaign,
    fit_path: Path,
    fit_doc: Mapping[str, Any],
    *,
    command: str = "",
    options: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The discovery.json content (see the module docstring)."""

    base, final = result.base, result.final
    rounds = []
    for i, att in enumerate(result.attributions, start=1):
        rounds.append(
            {
                "round": i,
                "attribution": att.as_dict(),
                "candidates": [
                    {
                        "effect": c.effect,
                        "score": c.score,
                        "evidence": c.evidence(),
                        # the same effect read on its other row sets (the
                        # ranked evidence is the one above)
                        "other_rows": [
                            {"score": o.score, "evidence": o.evidence()}
                            for o in att.other_evidence(c.effect)
                        ],
                    }
                    for c in att.candidates
                ],
            }
        )
    history = result.rounds_history
    refits = []
    for step in result.steps:
        current = history[0]
        for m in history:
            if len(m.effects) == step.round - 1:
                current = m
        refits.append(step.as_dict(current))
    model_names = [k for k in final.values if k in SPECS]
    doc = {
        **discovery_head(fit_doc, campaign, fit_path),
        "seed": result.seed,
        "candidates": rounds[0]["candidates"] if rounds else [],
        "rounds": rounds,
        "refits": refits,
        "selected": list(result.selected),
        "final_structure": {
            "heat": final.structure.heat,
            "air_properties": final.structure.air_properties,
            "effects": dict(final.structure.effects),
        },
        "rmse_before": base.rmse,
        "rmse_after": final.rmse,
        "pressure_rmse_before": {r: base.pressure_rmse(r) for r in ("fit", "validate")},
        "pressure_rmse_after": {r: final.pressure_rmse(r) for r in ("fit", "validate")},
        # the held-out pressures as the fit's verdict judges them (the statement's)
        "held_out_pressure_before": base.held_out,
        "held_out_pressure_after": final.held_out,
        "aic_before": base.aic,
        "aic_after": final.aic,
        "bic_before": base.bic,
        "bic_after": final.bic,
        "log_likelihood_before": base.log_likelihood,
        "log_likelihood_after": final.log_likelihood,
        "n_parameters_before": base.n_parameters,
        "n_parameters_after": final.n_parameters,
        "n_data": base.n_data,
        # the criteria count effective samples: n_data over the base model's
        # overcount (discovery.refit, module doc)
        "n_effective": base.n_effective,
        "overcount": base.overcount,
        "effect_parameters": _effect_parameters(final),
        "parameters_after": {k: final.values[k] for k in model_names},
        "noise_pressure": result.noise,
        "unexplained": bool(result.unexplained),
        "statement": result.statement,
        "provenance": provenance(result.seed, result.seconds, command, options),
    }
    return json_safe(doc)


def provenance(
    seed: int, seconds: float, command: str, options: Mapping[str, Any] | None
) -> dict[str, Any]:
    """discovery.json's ``provenance``: version, seed, time made, command, options, seconds."""
    return {
        "pneumafit_version": _version(),
        "seed": seed,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "command": command,
        "options": dict(options or {}),
        "seconds": seconds,
    }


# ----------------------------------------------------------------- report
def effect_parameter_lines(parameters: Mapping[str, Any]) -> list[str]:
    """discovery.md's table of the effect parameters (``effect_parameters``)."""
    if not parameters:
        return ["None."]
    lines = ["| parameter | effect | value | unit | 90 % interval (Laplace) |",
             "|---|---|---|---|---|"]  # fmt: skip
    for name, e in parameters.items():
        iv = e.get("interval_90")
        iv_s = f"[{_fmt(iv[0])}, {_fmt(iv[1])}]" if iv else "-"
        lines.append(f"| `{name}` | `{e['effect']}` | {_fmt(e['value'])} | {e['unit']} | {iv_s} |")
    return lines


def format_number(x: Any, digits: int = 4) -> str:
    """A number in ``digits`` significant digits; '-' for None or non-finite."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, float | int):
        return f"{x:.{digits}g}"
    return str(x)


_fmt = format_number


def _save_png(fig: Any, path: Path) -> None:
    """Lay a figure out and write it to ``path`` as PNG (100 dpi), atomically."""
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def _plot_pressure_residuals(
    campaign: Campaign, model: Model, path: Path, title: str
) -> Path | None:
    """Pressure residual (kPa) over time of every charge, discharge and step recording."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recs = [r for r in campaign.recordings if r.kind in ("charge", "discharge", "step")]
    if not recs:
        return None
    cols = 2
    rows = math.ceil(len(recs) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(12, 2.6 * rows), squeeze=False)
    try:
        for ax, rec in zip(axes.flat, recs, strict=False):
            sim = simulate_recording(rec, model.structure, model.values)
            for ch in PRESSURES:
                if sim is None or ch not in rec.channels:
                    continue
                res = (np.asarray(rec.channels[ch], float) - sim[ch]) / 1e3
                ax.plot(rec.time, res, lw=0.7, label=ch)
            ax.axhline(0.0, color="k", lw=0.5)
            ax.set_title(f"{rec.file} ({rec.kind}, {rec.role})", fontsize=9)
            ax.set_ylabel("kPa")
            ax.legend(fontsize=7, loc="best")
        for ax in list(axes.flat)[len(recs) :]:
            ax.axis("off")
        for ax in axes[-1]:
            ax.set_xlabel("time (s)")
        fig.suptitle(title)
        _save_png(fig, path)
    finally:
        plt.close(fig)
    return path


def _plot_candidates(result: Discovery, path: Path) -> Path | None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not result.attributions:
        return None
    cands = result.attributions[0].candidates
    names = [c.effect for c in cands]
    y = np.arange(len(names))
    fig, axes = plt.subplots(1, 3, figsize=(12, 0.5 * len(names) + 1.5), sharey=True)
    try:
        for ax, key, label in zip(
            axes,
            ("inclusion_probability", "variance_explained", "phase_match"),
            ("inclusion probability", "variance explained (R^2)", "phase match"),
            strict=True,
        ):
            vals = [getattr(c, key) for c in cands]
            colors = ["tab:green" if c.effect in result.selected else "tab:gray" for c in cands]
            ax.barh(y, vals, color=colors)
            ax.set_xlim(0, 1)
            ax.set_xlabel(label)
        axes[0].set_yticks(y, names)
        axes[0].invert_yaxis()
        fig.suptitle("Candidates of round 1, best score first (green: selected)")
        _save_png(fig, path)
    finally:
        plt.close(fig)
    return path


def _markdown(doc: Mapping[str, Any], figures: Sequence[str]) -> str:
    lines = [
        f"# Model discovery: {doc['campaign']['name']}",
        "",
        f"Base model `{doc['base_model']}` (fit `{doc['fit']}`), seed {doc['seed']}.",
        "",
        f"**{doc['statement']}**",
        "",
        "Selected effects: "
        + (", ".join(f"`{e}`" for e in doc["selected"]) if doc["selected"] else "none")
        + f"; unexplained: {str(doc['unexplained']).lower()}.",
        "",
        "## Candidates",
        "",
    ]
    for rnd in doc["rounds"]:
        att = rnd["attribution"]
        lines += [
            f"Round {rnd['round']}: {att['n_rows']} rows, residual-rate R^2 of the sparse model "
            f"{_fmt(att['explained'], 3)}, {att['n_bootstrap']} bootstrap fits.",
            "",
            "| effect | score | inclusion | R^2 alone | phase match | coefficient | unit "
            "| rows | supported |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for c in rnd["candidates"]:
            ev = c["evidence"]
            lines.append(
                f"| `{c['effect']}` | {_fmt(c['score'], 3)} | "
                f"{_fmt(ev['inclusion_probability'], 2)} | {_fmt(ev['variance_explained'], 3)} | "
                f"{_fmt(ev['phase_match'], 2)} | {_fmt(ev['coefficient'], 3)} | "
                f"{ev['coefficient_unit']} | {ev.get('rows', 'pressure')} | "
                f"{'yes' if ev['supported'] else 'no'} |"
            )
        # an effect also judged on the quiet rows: its evidence on the set
        # that does not rank it (the two routes to support, side by side)
        also = [
            f"`{c['effect']}` on the {o['evidence']['rows']} rows: score "
            f"{_fmt(o['score'], 3)}, R^2 alone {_fmt(o['evidence']['variance_explained'], 3)}, "
            + ("supported" if o["evidence"]["supported"] else "not supported")
            for c in rnd["candidates"]
            for o in c.get("other_rows", [])
            if "quiet" in (o["evidence"].get("rows"), c["evidence"].get("rows"))
            and ((o["score"] or 0.0) > 0.0 or o["evidence"]["supported"])
        ]
        if also:
            lines += ["", "Also read on another row set: " + "; ".join(also) + "."]
        lines.append("")
    lines += ["## Refits", ""]
    if doc["refits"]:
        lines += [
            "| round | effect | start | dBIC | dAIC | validate p RMSE (Pa) | decision |",
            "|---|---|---|---|---|---|---|",
        ]
        for s in doc["refits"]:
            start = ", ".join(f"{k} {_fmt(v, 3)}" for k, v in s["start"].items())
            val = s.get("rmse", {}).get("validate", {})
            pv = ", ".join(f"{c} {_fmt(val.get(c), 4)}" for c in PRESSURES if c in val)
            lines.append(
                f"| {s['round']} | `{s['effect']}` | {start} | {_fmt(s.get('delta_bic'), 4)} | "
                f"{_fmt(s.get('delta_aic'), 4)} | {pv or '-'} | {s['reason']} |"
            )
    else:
        lines.append("No candidate was supported enough to be refitted.")
    lines += ["", "## Errors before and after", ""]
    lines += [
        "RMSE of each role's recordings as replayed, nothing taken off (the statement "
        "above takes each fit recording's mean pressure residual off first).",
        "",
    ]
    lines += ["| role | channel | before | after | unit |", "|---|---|---|---|---|"]
    units = {"p_P": "Pa", "p_N": "Pa", "y": "m", "T_P": "K", "T_N": "K", "qm_P": "kg/s",
             "qm_N": "kg/s"}  # fmt: skip
    for role in ("fit", "validate"):
        before = doc["rmse_before"].get(role) or {}
        after = doc["rmse_after"].get(role) or {}
        for ch in before:
            lines.append(
                f"| {role} | {ch} | {_fmt(before.get(ch))} | {_fmt(after.get(ch))} | "
                f"{units.get(ch, '')} |"
            )
    lines += [
        "",
        f"Log-likelihood {_fmt(doc['log_likelihood_before'], 8)} -> "
        f"{_fmt(doc['log_likelihood_after'], 8)}; AIC {_fmt(doc['aic_before'], 8)} -> "
        f"{_fmt(doc['aic_after'], 8)}; BIC {_fmt(doc['bic_before'], 8)} -> "
        f"{_fmt(doc['bic_after'], 8)} (in effective samples: "
        f"{_fmt(doc.get('n_effective'), 4)} of {doc['n_data']} compared samples; "
        'docs/effects.md, "Effective samples").',
        "",
        "## Effect parameters",
        "",
    ]
    lines += effect_parameter_lines(doc["effect_parameters"])
    lines += ["", "## Figures", ""]
    lines += [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def write_report(
    out: Path, doc: Mapping[str, Any], result: Discovery, campaign: Campaign
) -> list[Path]:
    """Write discovery.json, the figures and discovery.md into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    figs: list[str] = []
    for path in (
        _plot_pressure_residuals(
            campaign, result.base, out / "residuals_before.png",
            f"Pressure residuals, base model ({doc['base_model']})",
        ),
        _plot_pressure_residuals(
            campaign, result.final, out / "residuals_after.png",
            "Pressure residuals, with "
            + (", ".join(result.selected) if result.selected else "no effect added"),
        ),
        _plot_candidates(result, out / "candidates.png"),
    ):  # fmt: skip
        if path is not None:
            written.append(path)
            figs.append(path.name)
    doc = {**doc, "figures": figs}
    md = out / "discovery.md"
    write_text_atomic(md, _markdown(doc, figs))
    js = out / "discovery.json"
    write_text_atomic(js, json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return [js, md, *written]


# ----------------------------------------------------------------- service
@dataclass
class DiscoveryFolder:
    """What :func:`discover_folder` wrote.

    Attributes
    ----------
    document : dict
        discovery.json's content.
    discovery : Discovery or FrictionDiscovery
        The discovery itself (rounds, refits, selected effects, final model;
        a :class:`~pneumafit.frictiontest.discover.FrictionDiscovery` from
        :func:`pneumafit.services.friction.friction_discover_folder`).
    files : list of Path
        The files written (discovery.json, discovery.md, the figures).
    """

    document: dict[str, Any]
    discovery: Discovery | FrictionDiscovery
    files: list[Path] = field(default_factory=list)


def discover_folder(
    campaign: Campaign,
    fit: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    seed: int | None = None,
    rounds: int = 2,
    per_round: int = 3,
    command: str = "",
    log: Callable[[str], None] | None = None,
    progress: Reporter | None = None,
) -> DiscoveryFolder:
    """Run discovery on a campaign and its base fit; write the folder ``out``.

    Parameters
    ----------
    campaign : Campaign
    fit : path
        fit.json of the base fit, or its folder (:func:`load_base_fit`).
    out : path
        Report folder (created; its files are replaced).
    seed : int or None
        Seeds the bootstrap and the refits (saved in discovery.json); None:
        the seed the base fit was made with (fit.json ``provenance.seed``),
        0 for a fit that does not record one.
    rounds, per_round : int
        Largest number of rounds, and of refits per round.
    command : str
        The command line, for discovery.json's provenance.
    log : callable, optional
        Progress lines.
    progress : Reporter, optional
        Progress of the refits' long loops.

    Returns
    -------
    DiscoveryFolder

    Raises
    ------
    PneumafitInputError
        The fit is not of this campaign, or not readable.
    PneumafitComputationError
        The discovery failed, or its files cannot be written.
    KeyboardInterrupt
        Interrupted: nothing is written.
    """
    from pneumafit.errors import PneumafitComputationError

    base, saved, fit_path = load_base_fit(Path(fit), campaign)
    seed = base_fit_seed(seed, saved)
    result = discover(campaign, base, seed=seed, rounds=rounds, per_round=per_round, log=log,
                      progress=progress)  # fmt: skip
    doc = discovery_document(
        result, campaign, fit_path, saved.document, command=command,
        options={"seed": seed, "rounds": rounds, "per_round": per_round},
    )  # fmt: skip
    try:
        written = write_report(Path(out), doc, result, campaign)
    except OSError as exc:
        raise PneumafitComputationError(
            f"{os.fspath(out)}: cannot write the report: {exc}"
        ) from exc
    return DiscoveryFolder(doc, result, written)
