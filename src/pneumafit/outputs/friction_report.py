"""The report of a friction-test run: one self-contained HTML file.

Read from a run folder written by ``pneumafit run`` on a friction-test
campaign (:mod:`pneumafit.friction_pipeline`); every input optional, a
missing one labelled "not run"::

    RUN/fits/friction/fit.json          the base fit (pneumafit fit --model friction)
    RUN/discovery/discovery.json, *.png pneumafit discover on it
    RUN/stages.json                     stage times

Sections: the campaign (recordings, pressures, load-cell noise), the fit
(law, parameters with intervals, quality verdict, force RMSE per recording),
force measured against the model per recording (base fit and, when
discovery kept an effect, the model after discovery), the discovery
(candidates, refits, before/after table, effect parameters, figure). The
report replays the force balance at the fitted values; it never fits.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import Campaign
from pneumafit.fileio import write_text_atomic
from pneumafit.frictiontest.model import KERNEL_ORDER, default_parameters, prepare
from pneumafit.identification.staged import FitResult
from pneumafit.outputs.report_html import (
    Section,
    embed_figure,
    embed_png_file,
    esc,
    fmt,
    note,
    page,
    table,
)

__all__ = [
    "before_after_rows",
    "is_friction_run",
    "write_friction_report",
    "write_friction_report_of_folder",
]


def _short(x: Any, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


def _change_percent(b: Any, a: Any) -> str:
    if not b or a is None:
        return "-"
    return f"{100.0 * (a - b) / b:+.0f} %"


def before_after_rows(doc: Mapping[str, Any]) -> list[tuple[str, str, str, str, str]]:
    """(recording or role, role, before N, after N, change) rows of the before/after table."""
    rows = []
    roles = dict(doc.get("roles") or {})
    for f, b in doc["rmse_by_recording_before"].items():
        a = doc["rmse_by_recording_after"].get(f)
        rows.append((f, roles.get(f, ""), _short(b), _short(a), _change_percent(b, a)))
    for role in ("fit", "validate"):
        b = (doc["rmse_before"].get(role) or {}).get("F")
        a = (doc["rmse_after"].get(role) or {}).get("F")
        if b is not None:
            rows.append((f"all {role}", role, _short(b), _short(a), _change_percent(b, a)))
    return rows


def _read(path: Path) -> tuple[Any, str | None]:
    if not path.exists():
        return None, None
    try:
        return json.loads(path.read_text(encoding="utf-8")), None
    except (OSError, ValueError) as exc:
        return None, f"{path}: cannot be read: {exc}"


def _read_fit(path: Path) -> tuple[dict[str, Any] | None, str | None]:
    """The base fit through the one reader of fit.json (:meth:`FitResult.load`)."""
    if not path.exists():
        return None, None
    try:
        return dict(FitResult.load(path).document), None
    except PneumafitInputError as exc:
        return None, str(exc)


def _values(doc: Mapping[str, Any]) -> dict[str, float]:
    values = default_parameters().values()
    for section in ("parameters", "nuisance"):
        for k, e in (doc.get(section) or {}).items():
            if k in values and isinstance(e, dict) and "value" in e:
                values[k] = float(e["value"])
    return values


def _campaign_section(campaign: Campaign, fit: Any) -> Section:
    noise = ((fit or {}).get("metrics") or {}).get("noise_F") or {}
    rows = []
    for rec in campaign.by_kind("friction"):
        t = np.asarray(rec.time, float)
        p = np.asarray(rec.channels["p_P"], float) - campaign.rig.exhaust_pressure
        rows.append(
            [
                esc(rec.file),
                esc(rec.role),
                str(t.size),
                fmt(float(t[-1] - t[0]), "s"),
                fmt(float(np.median(p)) / 1e5, "bar"),
                fmt(noise.get(rec.file), "N"),
            ]
        )
    body = (
        f"<p>{esc(campaign.description)}</p>"
        + f"<p>Bore {fmt(campaign.rig.bore * 1e3, 'mm')}, {esc(campaign.rig.acting)}-acting; "
        "the drive imposes the motion, the load cell measures the rod force F "
        "(docs/measured-data.md).</p>"
        + table(
            [
                "recording",
                "role",
                "samples",
                "duration",
                "median gauge pressure",
                "load-cell noise",
            ],
            rows,
        )
    )
    return Section("campaign", f"Campaign {campaign.name}", "ok", body, "campaign.toml")


def _fit_section(fit: Any, error: str | None) -> Section:
    src = "fits/friction/fit.json"
    if error:
        return Section("fit", "Friction fit", "error", note(esc(error), "error"), src)
    if fit is None:
        return Section("fit", "Friction fit", "not run", note("no fit.json", "notrun"), src)
    q = fit.get("quality") or {}
    m = fit.get("metrics") or {}
    rows = []
    params = {**(fit.get("parameters") or {}), **(fit.get("nuisance") or {})}
    for name in KERNEL_ORDER:
        e = params.get(name)
        if not isinstance(e, dict):
            continue
        iv = e.get("interval_90") or e.get("laplace_interval_90")
        rows.append(
            [
                esc(name),
                fmt(e.get("value"), e.get("unit") or ""),
                f"[{fmt(iv[0])}, {fmt(iv[1])}]" if iv else "fixed" if e.get("fixed") else "-",
                esc(e.get("group") or ""),
            ]
        )
    verdict = q.get("verdict", "no quality verdict")
    kind = "note" if q.get("trustworthy") else "warn"
    problems = "".join(f"<li>{esc(p)}</li>" for p in q.get("problems") or [])
    rm = m.get("rmse_by_recording") or {}
    body = (
        note(f"<b>{esc(verdict)}</b>" + (f"<ul>{problems}</ul>" if problems else ""), kind)
        + f"<p>Law <code>{esc(m.get('law'))}</code>; effects kept by the fit: "
        + esc(", ".join((m.get("effects") or {}).get("kept") or []) or "none")
        + f"; command <code>{esc((fit.get('provenance') or {}).get('command', ''))}</code>.</p>"
        + table(["parameter", "value", "90 % interval", "group"], rows)
        + table(["recording", "force RMSE"], [[esc(k), fmt(v, "N")] for k, v in rm.items()])
    )
    return Section("fit", "Friction fit", "ok", body, src)


def _force_section(campaign: Campaign, fit: Any, disc: Any) -> Section:
    if fit is None:
        return Section("force", "Force: measured and model", "not run", note("no fit", "notrun"))
    import matplotlib.pyplot as plt

    tests = prepare(campaign)
    models = [("base fit", _values(fit))]
    if disc and disc.get("selected"):
        models.append(("after discovery", dict(disc["parameters_after"])))
    fig, axes = plt.subplots(len(tests), 1, figsize=(9, 2.2 * len(tests)), squeeze=False)
    for ax, t in zip(axes[:, 0], tests, strict=True):
        ax.plot(t.time, t.force, "k", lw=0.6, label="measured")
        for label, values in models:
            pred = t.predict(np.array([[values[k] for k in KERNEL_ORDER]]))[0]
            rms = float(np.sqrt(np.mean((t.force - pred) ** 2)))
            ax.plot(t.time, pred, lw=0.8, label=f"{label} (RMSE {rms:.3g} N)")
        ax.set_title(f"{t.file} ({t.role})", fontsize=8)
        ax.set_ylabel("F (N)")
        ax.legend(fontsize=6, loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    return Section(
        "force",
        "Force: measured and model",
        "ok",
        embed_figure(fig, "force measured and model"),
        "fit.json, discovery.json, the recordings",
    )


def _discovery_section(folder: Path, disc: Any, error: str | None) -> Section:
    src = "discovery/discovery.json"
    if error:
        return Section("discovery", "Discovery", "error", note(esc(error), "error"), src)
    if disc is None:
        return Section(
            "discovery", "Discovery", "not run", note("no discovery.json", "notrun"), src
        )
    cands = [
        [
            esc(c["effect"]),
            fmt(c["evidence"]["variance_explained"]),
            fmt(c["evidence"]["coefficient"], c["evidence"]["coefficient_unit"]),
        ]
        for c in disc.get("candidates") or []
    ]
    refits = [
        [
            str(s["round"]),
            esc(s["effect"]),
            fmt(s.get("delta_bic")),
            fmt(((s.get("rmse") or {}).get("validate") or {}).get("F"), "N"),
            esc(s["reason"]),
        ]
        for s in disc.get("refits") or []
    ]
    effects = []
    for name, e in (disc.get("effect_parameters") or {}).items():
        iv = e.get("interval_90")
        effects.append(
            [
                esc(name),
                fmt(e.get("value"), e.get("unit") or ""),
                f"[{fmt(iv[0])}, {fmt(iv[1])}]" if iv else "-",
            ]
        )
    body = (
        note(f"<b>{esc(disc.get('statement'))}</b>")
        + table(["candidate (round 1)", "R^2 alone", "coefficient"], cands)
        + table(["round", "refit", "dBIC", "validate RMSE", "decision"], refits)
        + table(
            ["recording", "role", "before (N)", "after (N)", "change"],
            [[esc(c) for c in row] for row in before_after_rows(disc)],
            caption="force RMSE before and after discovery",
        )
        + table(["effect parameter", "value", "90 % interval (Laplace)"], effects)
        + table(
            ["parameter", "base fit", "after discovery"],
            [
                [
                    esc(k),
                    fmt((disc.get("parameters_before") or {}).get(k)),
                    fmt((disc.get("parameters_after") or {}).get(k)),
                ]
                for k in KERNEL_ORDER
            ],
            caption=f"every parameter; law {(disc.get('final_structure') or {}).get('friction')} "
            "after discovery",
        )
    )
    for name in disc.get("figures") or []:
        if (folder / name).exists():
            body += embed_png_file(folder / name)
    return Section("discovery", "Discovery", "ok", body, src)


def write_friction_report(run_dir: Path, campaign: Campaign, out_html: Path) -> Path:
    """Write the report of a friction-test run folder (module docstring) to ``out_html``."""
    import matplotlib

    matplotlib.use("Agg")
    run_dir = Path(run_dir)
    fit, fit_error = _read_fit(run_dir / "fits" / "friction" / "fit.json")
    disc, disc_error = _read(run_dir / "discovery" / "discovery.json")
    sections = [
        _campaign_section(campaign, fit),
        _fit_section(fit, fit_error),
        _force_section(campaign, fit, disc),
        _discovery_section(run_dir / "discovery", disc, disc_error),
    ]
    created = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    html = page(
        f"pneumafit friction-test report: {campaign.name}",
        "friction law and discovered effects on imposed-motion friction tests",
        sections,
        f"written {created}",
    )
    write_text_atomic(Path(out_html), html)
    return Path(out_html)


def is_friction_run(run_dir: Path) -> bool:
    """Whether ``run_dir`` is a friction-test run folder (``fits/friction/fit.json``)."""
    return (Path(run_dir) / "fits" / "friction" / "fit.json").is_file()


def write_friction_report_of_folder(
    run_dir: Path, out_html: Path, campaign: Path | None = None
) -> Path:
    """The report of a friction-test run folder, its campaign found as ``pneumafit report`` does.

    Parameters
    ----------
    run_dir : path
        Folder written by ``pneumafit run`` on friction tests.
    out_html : path
        The HTML file (written atomically).
    campaign : path, optional
        Campaign folder; default the one the fit recorded (``campaign.path``).

    Raises
    ------
    PneumafitInputError
        The fit cannot be read, or the campaign is neither given nor recorded,
        or cannot be read.
    """
    from pneumafit.campaign import read_campaign
    from pneumafit.campaign.errors import PneumafitInputError

    fit_file = Path(run_dir) / "fits" / "friction" / "fit.json"
    fit, error = _read_fit(fit_file)
    if error is not None or not isinstance(fit, dict):
        raise PneumafitInputError(
            f"report: {fit_file}: expected a fit.json, " + (error or "found no JSON object")
        )
    path = campaign
    if path is None:
        recorded = (fit.get("campaign") or {}).get("path")
        if not recorded:
            raise PneumafitInputError(
                f"report: {fit_file}: key campaign.path: expected the campaign folder the fit "
                "was made from, found none; give it with --campaign"
            )
        path = Path(recorded)
    if not Path(path).exists():
        raise PneumafitInputError(
            f"report: campaign {path}: expected a campaign folder, found nothing at that path"
            + ("" if campaign is not None else f" (recorded in {fit_file}; give --campaign)")
        )
    return write_friction_report(Path(run_dir), read_campaign(path), Path(out_html))
