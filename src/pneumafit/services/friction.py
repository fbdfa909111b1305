"""The friction-test services: the friction law fitted, and discovery, each written to a folder.

:func:`friction_fit_folder` is ``pneumafit fit CAMPAIGN --model friction``
without its console (:func:`pneumafit.cli.friction.friction_fit_command`):
``OUT/fit.json`` (format ``pneumafit-fit``, written by the same writer as the
other models) and, with MCMC, ``OUT/chains.h5`` and the ArviZ files.

:func:`friction_discover_folder` is ``pneumafit discover`` on a friction fit
(:func:`pneumafit.cli.friction_discover.friction_discover_command`):
``OUT/discovery.json`` (format ``pneumafit-discovery``, version 1, the same
top-level keys where they mean something here: ``base_model``,
``candidates``, ``rounds``, ``refits``, ``selected``, ``rmse_before`` /
``rmse_after`` (role -> ``{"F": N}``), ``bic_before`` / ``bic_after``,
``effect_parameters``, ``parameters_after``, ``statement``, ...; plus
``rmse_by_recording_before`` / ``_after``), ``OUT/discovery.md`` with the
before/after table, ``OUT/force_residuals.png`` (force residual against the
chamber pressure, before and after).

Both raise the :mod:`pneumafit.errors` family and let ``KeyboardInterrupt``
through; they print nothing.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from pneumafit.campaign.model import Campaign
from pneumafit.errors import PneumafitComputationError, PneumafitInputError
from pneumafit.fileio import write_text_atomic
from pneumafit.frictiontest.discover import (
    FRICTION_EFFECTS,
    FrictionDiscovery,
    discover_friction,
)
from pneumafit.frictiontest.fit import identify_friction
from pneumafit.identification.fitfile import CHAINS_FILE, FIT_FILE, SavedFit, json_safe
from pneumafit.identification.staged import FitResult
from pneumafit.outputs.friction_report import before_after_rows
from pneumafit.services.discover import (
    DiscoveryFolder,
    base_fit_seed,
    discovery_head,
    effect_parameter_lines,
    format_number,
    provenance,
)
from pneumafit.services.fit import PARTIAL_FILE, output_folder, write_inference_data

__all__ = [
    "friction_discover_folder",
    "friction_discovery_document",
    "friction_fit_folder",
    "load_friction_fit",
    "write_discovery_files",
]


def friction_fit_folder(
    campaign: Campaign,
    out: str | os.PathLike[str],
    *,
    law: str = "auto",
    effects: str = "off",
    mcmc: bool = True,
    walkers: int | None = None,
    steps: int | None = None,
    seed: int = 0,
    command: str = "",
    log: Callable[[str], None] | None = None,
) -> FitResult:
    """Fit the friction law to a campaign's friction tests and write the fit folder ``out``.

    Parameters
    ----------
    campaign : Campaign
        A campaign of friction tests.
    out : path
        Output folder (created; its fit.json and chains.h5 are replaced).
    law : {"auto", "stribeck", "lugre"}
        Friction law (``auto``: by BIC among Coulomb-viscous, Stribeck and LuGre).
    effects : {"off", "auto", "on"}
        Optional terms (pressure-dependent friction, direction asymmetry,
        effective area): none, BIC-selected, or all.
    mcmc : bool
        Sample the posterior (the chain is short: always started afresh).
    walkers, steps : int, optional
        MCMC settings (None: the defaults).
    seed : int
        Same seed, same numbers.
    command : str
        The command line, for fit.json's provenance.
    log : callable, optional
        Progress lines.

    Returns
    -------
    FitResult
        As saved in ``out/fit.json``.

    Raises
    ------
    PneumafitInputError
        Bad input (the campaign, the options), or ``out`` cannot be created.
    PneumafitComputationError
        The fit failed, or its files cannot be written.
    """
    out = output_folder(out)
    partial = out / PARTIAL_FILE
    partial.unlink(missing_ok=True)  # the friction chain is short: always afresh
    result = identify_friction(
        campaign, law=law, effects=effects, mcmc=mcmc, walkers=walkers, steps=steps, seed=seed,
        chains=partial if mcmc else None, log=log,
    )  # fmt: skip
    # fit.json through the common writer: the effect parameters are model
    # parameters here (not nuisance), the options the law and effects fitted
    try:
        if mcmc:
            os.replace(partial, out / CHAINS_FILE)
        else:
            (out / CHAINS_FILE).unlink(missing_ok=True)
        result.save(out / FIT_FILE, command=command, chains=CHAINS_FILE if mcmc else None)
    except OSError as exc:
        raise PneumafitComputationError(
            f"{os.fspath(out)}: cannot write the results: {exc}"
        ) from exc
    if mcmc:
        write_inference_data(result, out)
    return result


def load_friction_fit(fit: Path, campaign: Campaign) -> tuple[SavedFit, Path]:
    saved = FitResult.load(fit)  # names the file, key, expected and found
    if saved.campaign_sha256 != dict(campaign.sha256):
        raise PneumafitInputError(
            f"{saved.source}: key 'campaign.sha256': expected the SHA-256 of campaign "
            f"{campaign.name!r}'s files, found a fit of another campaign"
        )
    return saved, saved.path


def friction_discovery_document(
    result: FrictionDiscovery,
    campaign: Campaign,
    fit_path: Path,
    fit_doc: Mapping[str, Any],
    command: str = "",
    options: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The discovery.json content of a friction-test discovery."""

    def roles(rm: Mapping[str, Any]) -> dict[str, Any]:
        return {role: {"F": v} for role, v in rm["role"].items()}

    doc = {
        **discovery_head(fit_doc, campaign, fit_path),
        "roles": {t.file: t.role for t in result.tests},
        "seed": result.seed,
        "candidates": result.rounds[0] if result.rounds else [],
        "rounds": [{"round": i, "candidates": c} for i, c in enumerate(result.rounds, 1)],
        "refits": result.refits,
        "selected": [FRICTION_EFFECTS[p].name for p in result.selected],
        "selected_parameters": list(result.selected),
        "final_structure": {
            "friction": result.final_law,
            "effects": {k: result.values_after[k] for k in result.effect_parameters},
        },
        "rmse_before": roles(result.rmse_before),
        "rmse_after": roles(result.rmse_after),
        "rmse_by_recording_before": result.rmse_before["recording"],
        "rmse_by_recording_after": result.rmse_after["recording"],
        "bic_before": result.bic_before,
        "bic_after": result.bic_after,
        "log_likelihood_before": result.log_likelihood_before,
        "log_likelihood_after": result.log_likelihood_after,
        "effect_parameters": result.effect_parameters,
        "parameters_before": result.values_before,
        "parameters_after": result.values_after,
        "noise_F": result.noise,
        "unexplained": not result.selected,
        "statement": result.statement,
        "provenance": provenance(result.seed, result.seconds, command, options),
    }
    return json_safe(doc)


def _f(x: Any, digits: int = 3) -> str:
    return format_number(x, digits)


def _markdown(doc: Mapping[str, Any], figures: list[str]) -> str:
    lines = [
        f"# Model discovery: {doc['campaign']['name']} (friction tests)",
        "",
        f"Base model `friction`, law `{(doc['base_structure'] or {}).get('friction')}` "
        f"(fit `{doc['fit']}`), seed {doc['seed']}.",
        "",
        f"**{doc['statement']}**",
        "",
        "## Candidates (signatures on the force residual of the fit tests)",
        "",
    ]
    for rnd in doc["rounds"]:
        lines += [f"Round {rnd['round']}:", "",
                  "| effect | parameter | R^2 alone | coefficient | unit | refit start |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        for c in rnd["candidates"]:
            ev = c["evidence"]
            lines.append(
                f"| `{c['effect']}` | `{c['parameter']}` | {_f(ev['variance_explained'])} | "
                f"{_f(ev['coefficient'])} | {ev['coefficient_unit']} | {_f(ev['start'], 4)} |"
            )
        lines.append("")
    lines += ["## Refits", ""]
    if doc["refits"]:
        lines += ["| round | effect | dBIC | validate F RMSE (N) | decision |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for s in doc["refits"]:
            val = (s["rmse"].get("validate") or {}).get("F")
            lines.append(
                f"| {s['round']} | `{s['effect']}` | {_f(s['delta_bic'], 4)} | {_f(val)} | "
                f"{s['reason']} |"
            )
    else:
        lines.append("No refit.")
    lines += ["", "## Force RMSE before and after (N)", ""]
    lines += ["| recording | role | before | after | change |", "|---|---|---|---|---|"]
    for row in before_after_rows(doc):
        lines.append("| " + " | ".join(row) + " |")
    lines += [
        "",
        f"BIC (effective samples, at the base fit's tempering) {_f(doc['bic_before'], 6)} -> "
        f"{_f(doc['bic_after'], 6)}; log-likelihood {_f(doc['log_likelihood_before'], 8)} -> "
        f"{_f(doc['log_likelihood_after'], 8)}. Final law "
        f"`{doc['final_structure']['friction']}`.",
        "",
        "## Effect parameters",
        "",
    ]
    lines += effect_parameter_lines(doc["effect_parameters"])
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def _plot(result: FrictionDiscovery, path: Path) -> Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    from pneumafit.frictiontest.discover import _matrix

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, values, title in (
        (axes[0], result.values_before, "base fit"),
        (axes[1], result.values_after, "after discovery: "
         + (", ".join(FRICTION_EFFECTS[p].name for p in result.selected) or "nothing added")),
    ):  # fmt: skip
        m = _matrix(values)
        for t in result.tests:
            r = t.force - t.predict(m)[0]
            step = max(1, t.n // 1500)
            ax.scatter(t.gauge_pressure[::step] / 1e5, r[::step], s=2,
                       marker="o" if t.role == "fit" else "x",
                       label=f"{t.file} ({t.role})")  # fmt: skip
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel("chamber gauge pressure (bar)")
        ax.set_title(title, fontsize=9)
    axes[0].set_ylabel("force residual F - F_model (N)")
    axes[1].legend(fontsize=6, markerscale=3)
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def write_discovery_files(out: Path, doc: dict[str, Any], result: FrictionDiscovery) -> list[Path]:
    """Write discovery.json, force_residuals.png and discovery.md into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    fig = _plot(result, out / "force_residuals.png")
    figs = [fig.name] if fig is not None else []
    doc["figures"] = figs
    write_text_atomic(out / "discovery.md", _markdown(doc, figs))
    write_text_atomic(out / "discovery.json", json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return [out / "discovery.json", out / "discovery.md", *([fig] if fig else [])]


def friction_discover_folder(
    campaign: Campaign,
    fit: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    seed: int | None = None,
    rounds: int = 3,
    per_round: int = 3,
    command: str = "",
    log: Callable[[str], None] | None = None,
) -> DiscoveryFolder:
    """Discovery on a friction-test campaign from its friction fit; write the folder ``out``.

    Parameters
    ----------
    campaign : Campaign
    fit : path
        The base fit (model ``friction``): its fit.json or folder.
    out : path
        Report folder (created; its files are replaced).
    seed : int or None
        None: the seed the base fit was made with (0 if it records none).
    rounds, per_round : int
        Largest number of rounds, and of refits per round.
    command : str
        The command line, for discovery.json's provenance.
    log : callable, optional
        Progress lines.

    Returns
    -------
    DiscoveryFolder

    Raises
    ------
    PneumafitInputError
        The fit is not of this campaign, or not readable.
    PneumafitComputationError
        The discovery failed, or its files cannot be written.
    """
    saved, fit_path = load_friction_fit(Path(fit), campaign)
    seed = base_fit_seed(seed, saved)
    result = discover_friction(campaign, saved, seed=seed, rounds=rounds, per_round=per_round,
                               log=log)  # fmt: skip
    doc = friction_discovery_document(
        result, campaign, fit_path, saved.document, command=command,
        options={"seed": seed, "rounds": rounds, "per_round": per_round},
    )  # fmt: skip
    try:
        written = write_discovery_files(Path(out), doc, result)
    except OSError as exc:
        raise PneumafitComputationError(
            f"{os.fspath(out)}: cannot write the report: {exc}"
        ) from exc
    return DiscoveryFolder(doc, result, written)
