"""Body of ``pneumafit discover`` on friction tests (a base fit of model ``friction``).

Same contract as the cylinder discovery (:mod:`pneumafit.cli.discover`):
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

import datetime as _dt
import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import Campaign
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    folder_problem,
    int_problem,
    report_problems,
    run_guarded,
)
from pneumafit.fileio import write_text_atomic
from pneumafit.frictiontest.discover import (
    FRICTION_EFFECTS,
    FrictionDiscovery,
    discover_friction,
)
from pneumafit.identification.fitfile import SavedFit, json_safe
from pneumafit.identification.staged import FitResult
from pneumafit.outputs.friction_report import before_after_rows

__all__ = ["friction_discover_command", "friction_discovery_document", "is_friction_fit"]


def is_friction_fit(fit: Path) -> bool:
    """True when ``fit`` (a fit.json or its folder) is a fit of model ``friction``."""
    try:
        return FitResult.load(fit).model == "friction"
    except PneumafitInputError:
        return False  # not a readable fit: the actuator discovery says why


def _load(fit: Path, campaign: Campaign) -> tuple[SavedFit, Path]:
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
    from pneumafit.identification.fitfile import _version

    def roles(rm: Mapping[str, Any]) -> dict[str, Any]:
        return {role: {"F": v} for role, v in rm["role"].items()}

    doc = {
        "format": "pneumafit-discovery",
        "version": 1,
        "base_model": fit_doc.get("model"),
        "base_structure": fit_doc.get("structure"),
        "campaign": {
            "name": campaign.name,
            "path": os.fspath(campaign.path) if campaign.path is not None else None,
            "sha256": dict(campaign.sha256),
        },
        "fit": os.fspath(fit_path),
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
        "provenance": {
            "pneumafit_version": _version(),
            "seed": result.seed,
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "command": command,
            "options": dict(options or {}),
            "seconds": result.seconds,
        },
    }
    return json_safe(doc)


def _f(x: Any, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


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
    if doc["effect_parameters"]:
        lines += ["| parameter | effect | value | unit | 90 % interval (Laplace) |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for name, e in doc["effect_parameters"].items():
            iv = e.get("interval_90")
            iv_s = f"[{_f(iv[0], 4)}, {_f(iv[1], 4)}]" if iv else "-"
            lines.append(
                f"| `{name}` | `{e['effect']}` | {_f(e['value'], 4)} | {e['unit']} | {iv_s} |"
            )
    else:
        lines.append("None.")
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
        saved, fit_path = _load(Path(fit), camp)
    except (PneumafitInputError, ValueError) as exc:
        console.print(Text(str(exc), style="bold red"))
        return EXIT_BAD_INPUT
    fit_doc = saved.document
    if seed is None:  # the base fit's own
        seed = saved.seed if saved.seed is not None else 0
    recs = camp.by_kind("friction")
    console.print(
        f"discovery on {camp.name}: base model friction "
        f"({saved.friction}) from {fit_path} "
        f"({sum(r.role == 'fit' for r in recs)} fit, "
        f"{sum(r.role == 'validate' for r in recs)} validate friction tests)"
    )
    result, status = run_guarded(
        console,
        lambda: discover_friction(
            camp, saved, seed=seed, rounds=rounds, per_round=per_round,
            log=lambda line: console.print(Text(line)),
        ),
        campaign=campaign, failed="discovery failed", interrupted="interrupted: nothing written",
    )  # fmt: skip
    if status is not None:
        return status
    command = (
        f"pneumafit discover {os.fspath(campaign)} --fit {os.fspath(fit)} --out {os.fspath(out)}"
        f" --seed {seed} --rounds {rounds} --per-round {per_round}"
    )
    doc = friction_discovery_document(
        result, camp, fit_path, fit_doc, command=command,
        options={"seed": seed, "rounds": rounds, "per_round": per_round},
    )  # fmt: skip
    try:
        written = write_discovery_files(out, doc, result)
    except OSError as exc:
        console.print(Text(f"{os.fspath(out)}: cannot write the report: {exc}", "bold red"))
        return EXIT_FAILED
    console.print(summary_table(doc))
    sel = doc["selected"]
    console.print(
        Text("selected: " + (", ".join(sel) if sel else "none"), style="bold green" if sel else "")
    )
    for name, e in doc["effect_parameters"].items():
        iv = e.get("interval_90")
        console.print(
            f"  {name} = {_f(e['value'], 4)} {e['unit']}"
            + (f", 90 % [{_f(iv[0], 4)}, {_f(iv[1], 4)}]" if iv else "")
        )
    console.print(doc["statement"])
    console.print("wrote " + ", ".join(os.fspath(p) for p in written))
    return EXIT_OK
