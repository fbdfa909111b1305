"""The validation report: one self-contained HTML file from a run folder.

:func:`write_report` reads the files the other stages wrote into a run folder
(it never fits, and never imports their code beyond the readers), renders a
section from whatever is there and labels a section whose inputs are
missing "not run" (a file that cannot be read: "error", with the reason).
Figures are embedded as base64 PNG; the page needs no network. What each
section shows and from which file: ``docs/report.md``.

Run folder layout read (all optional)::

    RUN/summary.json                      pneumafit run (campaign path, nominal replay)
    RUN/fits/<model>/fit.json, chains.h5  pneumafit fit, model in MODELS
    RUN/comparison/comparison.json, *.png model comparison
    RUN/comparison/replays.npz            every fit's replay (the report's traces)
    RUN/linear/linear.json, design_4.json, design_6.json, *.png
    RUN/closed_loop/closed_loop.json, *.png
    RUN/discovery/discovery.json, discovery.md, *.png
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import time
from collections.abc import Callable, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

from rich.console import Console

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.units import display_unit
from pneumafit.comparison.result import COMPARISON_FILE
from pneumafit.fileio import check_output, write_text_atomic
from pneumafit.identification.fitfile import widening_label
from pneumafit.identification.quality import parameter_flags, zeros_phrase
from pneumafit.models.parts import MODEL_NAMES
from pneumafit.outputs.report_html import (
    Section,
    channel_value,
    embed_png_file,
    esc,
    fmt,
    note,
    page,
    table,
)
from pneumafit.outputs.rest_figure import REST_FIGURE

__all__ = ["FIT_MODELS", "SECTIONS", "write_report"]

#: Fits looked for, in this order: ``RUN/fits/<model>/fit.json``; one per
#: heat law, in model-list order (:data:`pneumafit.models.parts.MODEL_NAMES`,
#: live: a heat law registered later is looked for too).
FIT_MODELS = MODEL_NAMES

#: Files of a run folder that hold a result (any one of them makes a report).
RESULT_FILES = (
    "summary.json",
    *(f"fits/{m}/fit.json" for m in FIT_MODELS),
    "comparison/comparison.json",
    "linear/linear.json",
    "linear/design_4.json",
    "linear/design_6.json",
    "closed_loop/closed_loop.json",
    "discovery/discovery.json",
)

#: Sections of the report, in order: (anchor, heading).
SECTIONS = (
    ("campaign", "Campaign summary"),
    ("measurement", "Measurement against the three models"),
    ("residuals", "Residual diagnostics"),
    ("parameters", "Parameters with 90 % intervals"),
    ("mcmc", "MCMC: corner plots, traces and diagnostics"),
    ("comparison", "Model comparison"),
    ("linear", "Pole maps and gain schedule"),
    ("discovery", "Discovery: before and after"),
    ("closed-loop", "Closed loop on the nonlinear model"),
    ("air", "Air consumption"),
)

_ROLES = ("fit", "validate")


# --------------------------------------------------------------------- inputs
def _read_json(path: Path) -> tuple[Any, str | None]:
    """(document, None), (None, None) when absent, (None, reason) when unreadable."""
    if not path.is_file():
        return None, None
    try:
        return json.loads(path.read_text(encoding="utf-8")), None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        return None, f"{path}: not readable as JSON ({exc})"


def _not_found(*paths: Path) -> str:
    names = " and ".join(f"<code>{esc(p)}</code>" for p in paths)
    return note(f"not run: {names} not found.", "notrun")


def _pngs(folder: Path, listed: Any = None) -> list[Path]:
    """PNG files of a folder: those a document lists first, then the rest by name."""
    found: list[Path] = []
    if isinstance(listed, list):
        for name in listed:
            p = folder / str(name)
            if p.suffix.lower() == ".png" and p.is_file() and p not in found:
                found.append(p)
    if folder.is_dir():
        found += [p for p in sorted(folder.glob("*.png")) if p not in found]
    return found


def _figures(paths: list[Path]) -> str:
    parts = []
    for p in paths:
        try:
            parts.append(embed_png_file(p))
        except OSError as exc:
            parts.append(note(f"{esc(p)}: not readable ({esc(exc)})", "error"))
    return "\n".join(parts)


#: Display of SI keys by suffix: (suffix, factor, unit).
_KEY_UNITS = (
    ("_rad_s", 1.0, "rad/s"), ("_kg", 1e3, "g"), ("_J", 1.0, "J"), ("_Pa", 1e-3, "kPa"),
    ("_m", 1e3, "mm"), ("_s", 1.0, "s"), ("_V", 1.0, "V"), ("_K", 1.0, "K"),
    ("_fraction", 100.0, "%"),
)  # fmt: skip


def _key_label(key: str) -> str:
    """A column heading for an SI key: ``air_mass_kg`` -> ``air mass [g]``."""
    for suffix, _, unit in _KEY_UNITS:
        if key.endswith(suffix) and len(key) > len(suffix):
            return f"{key[: -len(suffix)].replace('_', ' ')} [{unit}]"
    return key.replace("_", " ")


def _by_key(key: str, value: Any) -> str:
    """A value whose unit its key names (``air_mass_kg``), in a display unit."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        for suffix, factor, unit in _KEY_UNITS:
            if key.endswith(suffix):
                return fmt(float(value) * factor, unit)
        if key in ("p_P", "p_N", "y", "T_P", "T_N", "qm_P", "qm_N"):
            return channel_value(key, value)
        return fmt(value)
    if (
        isinstance(value, list)
        and len(value) <= 8
        and all(isinstance(v, int | float | str | None) for v in value)
    ):
        return ", ".join(_by_key(key, v) for v in value)
    if value is None:
        return "-"
    if (
        isinstance(value, Mapping)
        and 0 < len(value) <= 8
        and all(isinstance(v, int | float | None) for v in value.values())
    ):
        return ", ".join(f"{esc(k)} {fmt(v, '', 3)}" for k, v in value.items())
    if isinstance(value, Mapping | list):
        text = json.dumps(value, default=str)
        return f"<code>{esc(text if len(text) < 300 else text[:300] + ' ...')}</code>"
    return esc(value)


def _kv_table(doc: Mapping[str, Any], caption: str = "", skip: tuple[str, ...] = ()) -> str:
    rows = [[esc(_key_label(str(k))), _by_key(str(k), v)] for k, v in doc.items() if k not in skip]
    return table(["key", "value"], rows, caption=caption)


def _channel_table(
    values: Mapping[str, Any], rows_label: str, caption: str = "", rows: list[str] | None = None
) -> str:
    """{row: {channel: SI}} as a table, channels in display units."""
    keys = rows if rows is not None else [k for k in values if isinstance(values[k], Mapping)]
    channels: list[str] = []
    for k in keys:
        for c in values.get(k) or {}:
            if c not in channels:
                channels.append(c)
    body = [
        [esc(k), *(channel_value(c, (values.get(k) or {}).get(c)) for c in channels)] for k in keys
    ]
    return table([rows_label, *channels], body, caption=caption)


class _Run:
    """What was found in a run folder (each input read once)."""

    def __init__(self, run_dir: Path, campaign: Path | None) -> None:
        from pneumafit.identification.fitfile import load_fit

        self.dir = run_dir
        self.summary, self.summary_error = _read_json(run_dir / "summary.json")
        self.fits: dict[str, tuple[dict[str, Any], Path]] = {}
        self.fit_errors: dict[str, str] = {}
        for model in FIT_MODELS:
            path = run_dir / "fits" / model / "fit.json"
            if not path.is_file():
                continue
            try:  # the one reader of fit.json: format, parameters, structure, ...
                doc = dict(load_fit(path).document)
                if not isinstance(doc.get("parameters"), dict):
                    self.fit_errors[model] = f"{path}: parameters: expected an object"
                else:
                    self.fits[model] = (doc, path)
            except PneumafitInputError as exc:
                detail = str(exc).removeprefix(f"{path}: ")
                if detail.startswith(("line ", "cannot be read")):
                    self.fit_errors[model] = f"{path}: not readable as JSON ({detail})"
                else:
                    self.fit_errors[model] = str(exc)
        self.campaign_path, self.campaign_origin = self._campaign_path(campaign)
        self.campaign: Any = None
        self.campaign_error: str | None = None
        self.replays: list[Any] = []
        self.replay_errors: dict[str, str] = {}
        #: model -> "saved" (read from comparison/replays.npz) or "simulated"
        self.replay_sources: dict[str, str] = {}
        #: Why saved replays were not used (shown in the measurement section).
        self.replay_notes: list[str] = []
        #: What makes the report untrue to its inputs (:meth:`disagreements`).
        self.problems: list[str] = []

    def _campaign_path(self, given: Path | None) -> tuple[Path | None, str]:
        if given is not None:
            return given, "given"
        sources: list[tuple[Any, str]] = [
            (doc.get("campaign"), f"fits/{model}/fit.json") for model, (doc, _) in self.fits.items()
        ]
        comparison, _ = _read_json(self.dir / "comparison" / COMPARISON_FILE)
        if isinstance(comparison, dict):
            sources.append((comparison.get("campaign"), "comparison/comparison.json"))
        if isinstance(self.summary, dict):
            sources.append((self.summary.get("campaign"), "summary.json"))
        for entry, origin in sources:
            if isinstance(entry, Mapping) and isinstance(entry.get("path"), str):
                path = Path(entry["path"])
                if not path.is_absolute():
                    # relative to where the stage ran: here, or above the run folder
                    bases = [Path.cwd(), self.dir, *self.dir.resolve().parents]
                    path = next((b / path for b in bases if (b / path).exists()), path)
                return path, origin
        return None, ""

    def has_results(self) -> bool:
        """Whether the folder holds any result file (:data:`RESULT_FILES`)."""
        return any((self.dir / name).is_file() for name in RESULT_FILES)

    def disagreements(self, given: bool) -> list[str]:
        """What makes this run's report untrue: a fit.json cannot be read, the
        campaign cannot be read (when it was given, or fits need it), or a fit,
        the comparison or the main job's summary records other campaign files
        than the campaign's
        (``campaign.sha256``: file -> SHA-256). Call after :meth:`load_campaign`."""
        # a fit.json that cannot be read makes a report of that model untrue too
        unread = [f"fits/{m}/fit.json cannot be read ({e})" for m, e in self.fit_errors.items()]
        needed = given or bool(self.fits) or bool(self.fit_errors)
        if self.campaign is None:
            if not needed:
                return unread
            if self.campaign_path is None:
                return [
                    *unread, "no campaign folder was given (--campaign) or recorded in the fits"
                ]  # fmt: skip
            return [*unread, f"campaign {self.campaign_error}"]
        ours = dict(self.campaign.sha256)
        recorded: list[tuple[str, Any]] = [
            (f"fits/{m}/fit.json", doc.get("campaign")) for m, (doc, _) in self.fits.items()
        ]
        comparison, _ = _read_json(self.dir / "comparison" / COMPARISON_FILE)
        if isinstance(comparison, Mapping):
            recorded.append(("comparison/comparison.json", comparison.get("campaign")))
        if isinstance(self.summary, Mapping):
            recorded.append(("summary.json", self.summary.get("campaign")))
        problems = unread
        for origin, entry in recorded:
            theirs = entry.get("sha256") if isinstance(entry, Mapping) else None
            if not isinstance(theirs, Mapping) or dict(theirs) == ours:
                continue  # nothing recorded to compare (older files), or the same files
            differ = sorted(k for k in set(theirs) | set(ours) if theirs.get(k) != ours.get(k))
            shown = ", ".join(differ[:4]) + (" ..." if len(differ) > 4 else "")
            problems.append(
                f"{origin} was made from campaign {entry.get('name')!r} at {entry.get('path')}, "
                f"not from campaign {self.campaign.name!r} at {self.campaign_path} as it is now "
                f"(files that differ: {shown})"
            )
        return problems

    def load_campaign(self) -> None:
        from pneumafit.campaign import read_campaign

        if self.campaign_path is None:
            return
        try:
            self.campaign = read_campaign(self.campaign_path)
        except Exception as exc:  # a campaign error is a section, never a crash
            self.campaign_error = f"{self.campaign_path}: {exc}"

    def replay(self, console: Console | None) -> None:
        """The fits' replays: read from ``comparison/replays.npz`` (written by
        the comparison stage) where it holds this fit of this campaign;
        simulated here only for a fit it does not hold (a folder without a
        comparison, or one made before the replays were saved)."""
        from pneumafit.comparison.replays import (
            REPLAYS_FILE,
            load_replays,
            replay_fingerprint,
            replay_model,
        )

        if self.campaign is None:
            return
        saved: dict[str, Any] = {}
        path = self.dir / "comparison" / REPLAYS_FILE
        if path.is_file():
            try:
                replays, identity = load_replays(path)
            except PneumafitInputError as exc:
                self.replay_notes.append(f"{exc}; the fits were simulated here instead")
            else:
                if dict(identity.get("sha256") or {}) == dict(self.campaign.sha256):
                    saved = {r.model: r for r in replays}
                else:
                    self.replay_notes.append(
                        f"{path} was saved for other campaign files; the fits were "
                        "simulated here instead"
                    )
        for model, (doc, fit_path) in self.fits.items():
            found = saved.get(model)
            if found is not None and found.fingerprint == replay_fingerprint(doc):
                self.replays.append(found)
                self.replay_sources[model] = "saved"
                continue
            started = time.perf_counter()
            try:
                self.replays.append(replay_model(self.campaign, doc, str(fit_path), model))
                self.replay_sources[model] = "simulated"
            except Exception as exc:  # a bad fit.json is reported in its section
                self.replay_errors[model] = f"{fit_path}: {exc}"
            if console is not None:
                console.print(
                    f"report: simulated the campaign with the {model} fit "
                    f"({time.perf_counter() - started:.1f} s; no saved replay of this fit "
                    f"in comparison/{REPLAYS_FILE})"
                )

    def replay_source(self, what: str) -> str:
        """Where the section's simulated traces come from, for its source line."""
        kinds = set(self.replay_sources.values())
        if kinds == {"saved"}:
            return f"<code>comparison/replays.npz</code> ({what}, saved by the comparison)"
        if kinds == {"simulated"} or not kinds:
            return f"{what}, simulated here (no saved replay of these fits)"
        saved = ", ".join(m for m, k in self.replay_sources.items() if k == "saved")
        return (f"<code>comparison/replays.npz</code> for {esc(saved)}; the other fits "
                f"simulated here ({what})")  # fmt: skip


# ------------------------------------------------------------------- sections
def _stages_table(run: _Run) -> str:
    """Times of the main job's stages (stages.json, summary.json ``seconds``)."""
    seconds: dict[str, Any] = {}
    stages, _ = _read_json(run.dir / "stages.json")
    if isinstance(stages, Mapping) and isinstance(stages.get("stages"), Mapping):
        for name, entry in stages["stages"].items():
            if isinstance(entry, Mapping):
                seconds[str(name)] = entry.get("seconds")
    summary = run.summary if isinstance(run.summary, Mapping) else {}
    if isinstance(summary.get("seconds"), Mapping):
        for name, value in summary["seconds"].items():
            seconds.setdefault(str(name), value)
    if not seconds:
        return ""
    rows = [[esc(k), fmt(v, "s", 3)] for k, v in seconds.items()]
    if summary.get("total_seconds") is not None:
        rows.append(["<strong>total</strong>", fmt(summary.get("total_seconds"), "s", 3)])
    html_text = table(["stage", "wall time"], rows, caption="Stages of pneumafit run")
    if summary.get("failed_stage"):
        html_text += note(f"failed stage: {esc(summary['failed_stage'])}", "error")
    return html_text


def _campaign_section(run: _Run) -> tuple[str, str, str]:
    parts = []
    inventory = [
        ("pneumafit run", "summary.json"),
        *((f"fit {m}", f"fits/{m}/fit.json") for m in FIT_MODELS),
        *((f"chains {m}", f"fits/{m}/chains.h5") for m in FIT_MODELS),
        ("comparison", "comparison/comparison.json"),
        ("linear analysis", "linear/linear.json"),
        ("designs", "linear/design_4.json, linear/design_6.json"),
        ("closed loop", "closed_loop/closed_loop.json"),
        ("discovery", "discovery/discovery.json"),
        ("export", "export/controller.json"),
        ("stages of pneumafit run", "stages.json"),
    ]
    rows = []
    for stage, files in inventory:
        found = all((run.dir / f.strip()).is_file() for f in files.split(","))
        rows.append([esc(stage), f"<code>{esc(files)}</code>", "found" if found else
                     "<em>not found</em>"])  # fmt: skip
    parts.append("<h3>Run folder</h3>")
    parts.append(table(["stage", "file", "status"], rows,
                       caption=f"What {run.dir} holds"))  # fmt: skip
    parts.append(_stages_table(run))
    for model, error in run.fit_errors.items():
        parts.append(note(f"fit {esc(model)}: {esc(error)}", "error"))
    for problem in run.problems:
        parts.append(note(f"inputs disagree: {esc(problem)}", "error"))
    if run.summary_error:
        parts.append(note(esc(run.summary_error), "error"))
    source = f"campaign folder ({esc(run.campaign_origin) or 'not recorded'})"
    if run.campaign_path is None:
        parts.append(
            note(
                "not run: no campaign folder was given (<code>--campaign</code>) or recorded "
                "(fit.json <code>campaign.path</code>, comparison.json, summary.json).",
                "notrun",
            )
        )
        return "\n".join(parts), "not run", source
    if run.campaign is None:
        parts.append(note(f"campaign not readable: {esc(run.campaign_error)} (give the "
                          "folder with <code>--campaign</code>)", "error"))  # fmt: skip
        return "\n".join(parts), "error", source
    c = run.campaign
    parts.append("<h3>Campaign</h3>")
    parts.append(table(
        ["name", "folder", "recordings", "fit", "validate", "description"],
        [[esc(c.name), f"<code>{esc(c.path)}</code>", fmt(len(c.recordings)),
          fmt(len(c.by_role("fit"))), fmt(len(c.by_role("validate"))), esc(c.description)]],
    ))  # fmt: skip
    rig = c.rig.as_parameters()
    from pneumafit.models.layout import SPECS

    parts.append(table(
        ["rig parameter", "value"],
        [[esc(k), fmt(v, SPECS[k].unit if k in SPECS else "")] for k, v in rig.items()],
        caption="Rig (from campaign.toml, SI units)",
    ))  # fmt: skip
    rec_rows = []
    for r in c.recordings:
        chans = ", ".join(f"{n} [{r.units.get(n, '?')}]" for n in r.channels)
        where = f"chamber {r.chamber}" if r.chamber else ""
        if r.piston_position is not None:
            where += f", piston at {r.piston_position * 1e3:.0f} mm"
        if r.controller is not None:
            where += f"; {r.controller}"
        rec_rows.append([
            f"<code>{esc(r.file)}</code>", esc(r.kind), esc(r.role), fmt(r.duration, "s"),
            esc(chans), fmt(r.sample_rate, "Hz"), esc(where.strip(";, ")),
        ])  # fmt: skip
    parts.append(table(
        ["file", "kind", "role", "duration", "channels [file units]", "sample rate", "setup"],
        rec_rows, caption="Recordings",
    ))  # fmt: skip
    if c.warnings:
        parts.append(note("campaign warnings: " + "; ".join(esc(w) for w in c.warnings), "warn"))
    summary = run.summary
    if isinstance(summary, dict) and isinstance(summary.get("models"), Mapping):
        parts.append("<h3>Nominal replay (<code>pneumafit run</code>, untuned models)</h3>")
        parts.append(note(esc(summary.get("parameters", ""))))
        rows = []
        channels: list[str] = []
        for res in summary["models"].values():
            for role in _ROLES:
                for ch in ((res or {}).get("rmse") or {}).get(role) or {}:
                    if ch not in channels:
                        channels.append(ch)
        for model, res in summary["models"].items():
            for role in _ROLES:
                row = ((res or {}).get("rmse") or {}).get(role) or {}
                rows.append([esc(model), esc(role), *(channel_value(ch, row.get(ch))
                                                      for ch in channels)])  # fmt: skip
        parts.append(table(["model", "role", *(f"RMSE {ch}" for ch in channels)], rows))
    return "\n".join(parts), "ok", source


def _need_fits(run: _Run) -> str | None:
    if run.fits:
        return None
    paths = [run.dir / "fits" / m / "fit.json" for m in FIT_MODELS]
    return _not_found(*paths)


def _measurement_section(run: _Run) -> tuple[str, str, str]:
    from pneumafit.outputs.report_models import render_measurement

    source = "the campaign and " + run.replay_source("<code>fits/&lt;model&gt;/fit.json</code>")
    missing = _need_fits(run)
    if missing:
        return missing, "not run", source
    if run.campaign is None:
        return note("not run: the campaign could not be read (see the campaign summary).",
                    "notrun"), "not run", source  # fmt: skip
    parts = [note(f"{esc(m)}: could not simulate: {esc(e)}", "error")
             for m, e in run.replay_errors.items()]  # fmt: skip
    parts += [note(esc(n), "warn") for n in run.replay_notes]
    absent = [m for m in FIT_MODELS if m not in run.fits]
    if absent:
        parts.append(note("not run for " + ", ".join(esc(m) for m in absent)
                          + ": no fit.json.", "notrun"))  # fmt: skip
    if not run.replays:
        return "\n".join(parts), "error", source
    parts.append(render_measurement(run.campaign, run.replays))
    status = "ok" if not absent and not run.replay_errors else "partial"
    return "\n".join(parts), status, source


def _residual_section(run: _Run) -> tuple[str, str, str]:
    from pneumafit.outputs.report_models import render_residual_rows, render_residuals

    replay = next((r for r in run.replays if r.model == "convection"), None)
    if replay is None:
        source = run.replay_source("<code>fits/convection/fit.json</code>")
        if "convection" not in run.fits:
            return _not_found(run.dir / "fits" / "convection" / "fit.json"), "not run", source
        return note("not run: the convection fit could not be simulated (see above).",
                    "notrun"), "not run", source  # fmt: skip
    saved, why = _saved_residuals(run, replay)
    if saved is not None:
        source = ("<code>comparison/residuals.json</code> (the convection fit's residual "
                  "analysis, saved by the comparison)")  # fmt: skip
        body, status = render_residual_rows(
            replay.model, saved["rows"], saved["problems"], saved["figures"]
        )
        return body, status, source
    source = run.replay_source("<code>fits/convection/fit.json</code>")
    source += f"; <code>pneumafit.discovery.residual_analysis</code>, run here ({esc(why)})"
    body, status = render_residuals(run.campaign, replay)
    return body, status, source


def _saved_residuals(run: _Run, replay: Any) -> tuple[dict[str, Any] | None, str]:
    """The convection fit's residual analysis saved by the comparison
    (``comparison/residuals.json``) when it is of this campaign, this fit and
    has its figures; else None and why not."""
    from pneumafit.outputs.residual_file import RESIDUALS_FILE, load_residuals

    path = run.dir / "comparison" / RESIDUALS_FILE
    if not path.is_file() or run.campaign is None:
        return None, f"no comparison/{RESIDUALS_FILE}"
    try:
        saved = load_residuals(path, run.campaign.sha256).get(replay.model)
    except PneumafitInputError as exc:
        return None, str(exc)
    if saved is None:
        return None, f"comparison/{RESIDUALS_FILE} holds no {replay.model} fit"
    if not replay.fingerprint or saved["fingerprint"] != replay.fingerprint:
        return None, f"comparison/{RESIDUALS_FILE} was saved for another {replay.model} fit"
    missing = [p for p, _ in saved["figures"] if not p.is_file()]
    if missing:
        return None, f"{missing[0]} is missing"
    return saved, ""


def _interval(entry: Mapping[str, Any], key: str, unit: str) -> str:
    iv = entry.get(key)
    if isinstance(iv, list) and len(iv) == 2:
        return f"[{fmt(iv[0])}, {fmt(iv[1])}]" + (f"&nbsp;{esc(unit)}" if unit else "")
    return "-"


def _quality_html(doc: Mapping[str, Any]) -> str:
    """A fit's verdict and its residual-over-noise table (fit.json ``quality``)."""
    quality = doc.get("quality")
    if not isinstance(quality, Mapping):
        return note("fit quality: not in this fit.json (written before pneumafit checked it)",
                    "notrun")  # fmt: skip
    kind = "note" if quality.get("trustworthy") else "warn"
    items = "".join(f"<li>{esc(p)}</li>" for p in quality.get("problems") or [])
    parts = [note(f"<strong>{esc(quality.get('verdict', ''))}</strong>"
                  + (f"<ul>{items}</ul>" if items else ""), kind)]  # fmt: skip
    parts += [note(esc(c), "warn") for c in quality.get("caveats") or []]
    rows = []
    for r in quality.get("recordings") or []:
        scale, unit = display_unit(str(r.get("channel", "")))
        ratio = r.get("ratio")
        over = [
            f"{p} {v['ratio']:.1f}x"
            for p, v in (r.get("phases") or {}).items()
            if isinstance(v, Mapping) and (v.get("ratio") or 0) > quality.get("threshold", 3)
        ]
        cell = fmt(ratio, "", 3)
        if not r.get("reaches_noise", True):
            cell = f"<strong>{cell}</strong>"
        rows.append([
            esc(r.get("recording")), esc(r.get("role")),
            esc(r.get("channel")) + ("" if r.get("fitted") else " (not fitted)"),
            fmt(r["rms"] * scale if r.get("rms") is not None else None, unit, 3),
            fmt(r["noise"] * scale if r.get("noise") is not None else None, unit, 3),
            cell, esc(", ".join(over)),
        ])  # fmt: skip
    if rows:
        # a fit.json written before 2026-12-04 has no zeros: no phrase
        zeros = (
            zeros_phrase(
                quality["sensor_zeros"], quality.get("zeros_applied") or (),
                (str(r.get("channel", "")) for r in quality.get("recordings") or []),
            )
            if "sensor_zeros" in quality
            else ""
        )  # fmt: skip
        parts.append(table(
            ["recording", "role", "channel", "RMS residual", "sensor noise", "RMS / noise",
             "phases above the threshold"], rows,
            caption="Residual over sensor noise (noise from each recording's quiet windows; "
            f"above {quality.get('threshold', 3):g}x the fit does not reach the noise"
            + (f"; {zeros}" if zeros else "") + ")",
        ))  # fmt: skip
    return "\n".join(parts)


def _quality_headline(run: _Run) -> str:
    """One line per fit for the top of the report."""
    lines = []
    for model in FIT_MODELS:
        if model in run.fits:
            q = run.fits[model][0].get("quality")
            if isinstance(q, Mapping):
                lines.append(f"{esc(model)}: {esc(q.get('verdict', ''))}")
    return "<br>".join(lines)


def _parameter_section(run: _Run) -> tuple[str, str, str]:
    source = "<code>fits/&lt;model&gt;/fit.json</code> <code>parameters</code>"
    missing = _need_fits(run)
    if missing:
        return missing, "not run", source
    parts = [note(
        "value: the posterior median (<em>mcmc</em>) or the joint least-squares estimate "
        "(<em>laplace</em>); 90 % interval: the 5 and 95 % quantiles of the same posterior; "
        "widened: the factor by which the disagreement between recordings and the profile "
        "likelihood's curvature widened it (docs/identification.md, \"Intervals where the "
        "recordings disagree\"); flag: at bound, outside interval, not determined (a 90 % "
        "interval over a factor 10 or reaching 0), chain short or not mixed, as in the fit's "
        "verdict. Rig parameters are fixed from the campaign."
    )]  # fmt: skip
    fixed_rows: dict[str, list[str]] = {}
    for model in FIT_MODELS:
        if model not in run.fits:
            parts.append(f"<h3>{esc(model)}</h3>" + note("not run: no fit.json.", "notrun"))
            continue
        doc, path = run.fits[model]
        structure = doc.get("structure") or {}
        parts.append(
            f"<h3>{esc(model)} <small>({esc(structure.get('name', ''))}, air "
            f"properties {esc(structure.get('air_properties', '?'))})</small></h3>"
        )
        parts.append(_quality_html(doc))
        rest = Path(path).parent / REST_FIGURE
        if rest.is_file():
            parts.append(_figures([rest]))
        rows = []
        quality = doc.get("quality")
        flags = parameter_flags(quality) if isinstance(quality, Mapping) else {}
        for name, e in doc["parameters"].items():
            if not isinstance(e, Mapping):
                continue
            unit = str(e.get("unit") or "")
            if e.get("fixed"):
                fixed_rows.setdefault(name, [esc(name)]).append(fmt(e.get("value"), unit))
                continue
            rows.append([
                esc(name), esc(e.get("group", "")), fmt(e.get("value"), unit),
                fmt(e.get("std"), unit, 3), _interval(e, "interval_90", unit),
                esc(e.get("uncertainty") or "-"), _interval(e, "laplace_interval_90", unit),
                widening_label(e.get("interval_widening")),
                f"<strong>{esc(flags[name])}</strong>" if name in flags else "",
            ])  # fmt: skip
        parts.append(
            table(
                [
                    "parameter",
                    "group",
                    "value",
                    "std",
                    "90 % interval",
                    "from",
                    "Laplace 90 % interval",
                    "widened",
                    "flag",
                ],
                rows,
                caption=f"Estimated parameters ({path})",
            )
        )
        warnings = doc.get("warnings") or []
        if warnings:
            parts.append("<details><summary>" + f"{len(warnings)} warning(s) of this fit"
                         + "</summary>" + "".join(note(esc(w), "warn") for w in warnings)
                         + "</details>")  # fmt: skip
    if fixed_rows:
        models = [m for m in FIT_MODELS if m in run.fits]
        parts.append("<details><summary>Fixed parameters (rig and defaults)</summary>"
                     + table(["parameter", *models],
                             [r + ["-"] * (len(models) + 1 - len(r)) for r in fixed_rows.values()])
                     + "</details>")  # fmt: skip
    return "\n".join(parts), "ok" if len(run.fits) == len(FIT_MODELS) else "partial", source


def _mcmc_section(run: _Run) -> tuple[str, str, str]:
    from pneumafit.outputs.report_mcmc import render_chains

    source = ("<code>fits/&lt;model&gt;/fit.json</code> <code>mcmc</code> and "
              "<code>fits/&lt;model&gt;/chains.h5</code>")  # fmt: skip
    missing = _need_fits(run)
    if missing:
        return missing, "not run", source
    parts = []
    statuses = []
    for model in FIT_MODELS:
        parts.append(f"<h3>{esc(model)}</h3>")
        if model not in run.fits:
            parts.append(note("not run: no fit.json.", "notrun"))
            statuses.append("not run")
            continue
        doc, path = run.fits[model]
        try:
            body, status = render_chains(doc, path.parent)
        except Exception as exc:  # a broken chains file is reported, not raised
            body, status = note(f"{esc(path.parent)}: {esc(exc)}", "error"), "error"
        parts.append(body)
        statuses.append(status)
    if all(s == "ok" for s in statuses):
        status = "ok"
    elif all(s == "not run" for s in statuses):
        status = "not run"
    else:
        status = "partial"
    return "\n".join(parts), status, source


def _deviance(entry: Any) -> str:
    """WAIC or PSIS-LOO on the deviance scale (-2 elpd) with its standard error."""
    if isinstance(entry, int | float) and not isinstance(entry, bool):
        return fmt(entry)
    if not isinstance(entry, Mapping):
        return "-"
    value = entry.get("deviance")
    if value is None and isinstance(entry.get("elpd"), int | float):
        value = -2.0 * entry["elpd"]
    se = entry.get("se")
    text = fmt(value)
    if isinstance(se, int | float) and value is not None:
        text += f" &plusmn; {fmt(2.0 * se, '', 2)}"
    return text


def _criteria_rows(models: list[str], entries: Mapping[str, Any]) -> list[list[str]]:
    rows = []
    for m in models:
        e = entries.get(m) or {}
        post = e.get("posterior") if isinstance(e.get("posterior"), Mapping) else {}
        rows.append([
            esc(m), fmt(e.get("log_likelihood")), fmt(e.get("aic")), fmt(e.get("bic")),
            fmt(e.get("n_data")), fmt(e.get("n_parameters")),
            _deviance(post.get("waic")), _deviance(post.get("loo")),
        ])  # fmt: skip
    return rows


_CRITERIA_HEADER = ["model", "log-likelihood", "AIC", "BIC", "data points", "parameters",
                    "WAIC (deviance)", "PSIS-LOO (deviance)"]  # fmt: skip


def _recording_table(rows: Any, models: list[str]) -> str:
    """comparison.json ``table`` (long form) as recording x channel rows, models as columns."""
    if not isinstance(rows, list) or not models:
        return ""
    cells: dict[tuple[str, str, str], dict[str, Mapping[str, Any]]] = {}
    for r in rows:
        if isinstance(r, Mapping) and r.get("model") in models:
            key = (str(r.get("recording")), str(r.get("role", "")), str(r.get("channel")))
            cells.setdefault(key, {})[str(r["model"])] = r
    if not cells:
        return ""
    header = ["recording", "role", "channel"]
    for m in models:
        header += [f"{m}: RMSE", f"{m}: fit %"]
    body = []
    for (rec, role, ch), by_model in cells.items():
        line = [esc(rec), esc(role), esc(ch)]
        for m in models:
            e = by_model.get(m) or {}
            line += [channel_value(ch, e.get("rmse")), fmt(e.get("fit_percent"), "%", 3)]
        body.append(line)
    return table(header, body, caption="Per recording and channel (comparison.json table)")


def _comparison_section(run: _Run) -> tuple[str, str, str]:
    folder = run.dir / "comparison"
    path = folder / COMPARISON_FILE
    source = f"<code>{esc(path)}</code> and its figures"
    doc, error = _read_json(path)
    parts = []
    status = "ok"
    if error:
        parts.append(note(esc(error), "error"))
        status = "error"
    elif doc is None:
        parts.append(_not_found(path))
        status = "not run"
    elif not isinstance(doc, dict):
        parts.append(note(f"{esc(path)}: expected a JSON object, found "
                          f"{esc(type(doc).__name__)}", "error"))  # fmt: skip
        status = "error"
    else:
        if doc.get("format") not in (None, "pneumafit-comparison"):
            parts.append(
                note(
                    f"{esc(path)}: format {esc(doc.get('format'))!s}, expected "
                    "pneumafit-comparison; shown as far as it can be read.",
                    "warn",
                )
            )
        models = doc.get("models")
        if not isinstance(models, list):
            models = [m for m in FIT_MODELS if isinstance(doc.get(m), Mapping)]
        models = [str(m) for m in models if isinstance(doc.get(str(m)), Mapping)]
        if not models:
            parts.append(note(f"{esc(path)}: no model entries found.", "warn"))
            status = "partial"
        for role in _ROLES:
            for key, label in (("rmse", "RMSE"), ("rmse_by_quantity", "RMSE by quantity"),
                               ("max_abs_error", "largest absolute error")):  # fmt: skip
                values = {m: ((doc[m].get(key) or {}).get(role) or {}) for m in models
                          if isinstance(doc[m].get(key), Mapping)}  # fmt: skip
                if any(values.values()):
                    parts.append(_channel_table(values, "model", f"{label}, {role} recordings"))
        if models:
            parts.append(table(_CRITERIA_HEADER, _criteria_rows(models, doc),
                               caption="Information criteria (lower is better)"))  # fmt: skip
        parts.append(_recording_table(doc.get("table"), models))
        for m in models:
            post = doc[m].get("posterior")
            if isinstance(post, Mapping) and post.get("available") is False:
                parts.append(note(f"{esc(m)}: no WAIC/PSIS-LOO: {esc(post.get('reason', ''))}"))
        best = doc.get("best")
        if isinstance(best, Mapping) and best:
            parts.append(_kv_table(best, caption="Best model per channel and criterion"))
        for m in models:
            for w in doc[m].get("warnings") or []:
                parts.append(note(f"{esc(m)}: {esc(w)}", "warn"))
        parts.append(_figures(_pngs(folder, doc.get("figures"))))
    if run.fits:
        models = [m for m in FIT_MODELS if m in run.fits]
        parts.append("<h3>From the fits' own fit.json metrics</h3>")
        rmse = {m: ((run.fits[m][0].get("metrics") or {}).get("rmse") or {}) for m in models}
        for role in _ROLES:
            parts.append(
                _channel_table(
                    {m: rmse[m].get(role) or {} for m in models},
                    "model",
                    f"RMSE reported by the fit, {role} recordings",
                )
            )
        metrics = {m: run.fits[m][0].get("metrics") or {} for m in models}
        parts.append(table(_CRITERIA_HEADER[:6], [r[:6] for r in _criteria_rows(models, metrics)],
                           caption="Criteria reported by each fit"))  # fmt: skip
    return "\n".join(parts), status, source


def _complex(values: Any) -> str:
    if not isinstance(values, list):
        return "-"
    out = []
    for v in values:
        if isinstance(v, list) and len(v) == 2 and all(isinstance(x, int | float) for x in v):
            re_, im = float(v[0]), float(v[1])
            out.append(f"{re_:.3g}" + (f" {'+' if im >= 0 else '-'} {abs(im):.3g}j" if im else ""))
    return ", ".join(out) + " 1/s" if out else "-"


def _linear_section(run: _Run) -> tuple[str, str, str]:
    folder = run.dir / "linear"
    source = f"<code>{esc(folder)}</code>: linear.json, design_4.json, design_6.json, figures"
    lin, lin_error = _read_json(folder / "linear.json")
    designs = {o: _read_json(folder / f"design_{o}.json") for o in (4, 6)}
    if lin is None and lin_error is None and all(d is None and e is None
                                                  for d, e in designs.values()):  # fmt: skip
        return _not_found(folder / "linear.json", folder / "design_4.json"), "not run", source
    parts = []
    status = "ok"
    if lin_error:
        parts.append(note(esc(lin_error), "error"))
        status = "partial"
    elif not isinstance(lin, dict):
        parts.append(_not_found(folder / "linear.json"))
        status = "partial"
    else:
        positions = [p for p in lin.get("positions") or [] if isinstance(p, Mapping)]
        bad = [p for p in positions if "error" in p]
        parts.append(f"<h3>Linear models (eqs. 10-14), lambda_e = "
                     f"{fmt(lin.get('lambda_e'), 'W/m^2/K')}</h3>")  # fmt: skip
        if bad:
            parts.append(note(f"{len(bad)} of {len(positions)} positions have no equilibrium: "
                              + "; ".join(f"{fmt(p.get('y', 0) * 1e3, 'mm')}: {esc(p['error'])}"
                                          for p in bad[:5]), "warn"))  # fmt: skip
        good = [p for p in positions if "error" not in p]
        pick = good[:: max(1, math.ceil(len(good) / 7))]
        rows = []
        for p in pick:
            eq = p.get("equilibrium") or {}
            rows.append([
                fmt(float(p.get("y", math.nan)) * 1e3, "mm"), channel_value("p_P", eq.get("p_P")),
                channel_value("p_N", eq.get("p_N")), fmt(eq.get("u"), "V"),
                _complex((p.get("order_4") or {}).get("poles")),
                _complex((p.get("order_6") or {}).get("poles")),
            ])  # fmt: skip
        parts.append(
            table(
                [
                    "position",
                    "p_P",
                    "p_N",
                    "u_e",
                    "poles, 4th order (polytropic)",
                    "poles, 6th order (heat)",
                ],
                rows,
                caption=f"Equilibria and open-loop poles ({len(good)} positions; "
                f"every {max(1, math.ceil(len(good) / 7))}th shown)",
            )
        )
    for order, (doc, error) in designs.items():
        if error:
            parts.append(note(esc(error), "error"))
            status = "partial"
            continue
        if not isinstance(doc, dict):
            parts.append(_not_found(folder / f"design_{order}.json"))
            status = "partial"
            continue
        parts.append(f"<h3>State-feedback design, order {order}</h3>")
        parts.append(table(
            ["w0", "lambda_e", "law", "target poles"],
            [[fmt(doc.get("w0"), "rad/s"), fmt(doc.get("lambda_e"), "W/m^2/K"),
              esc(doc.get("law", "")), _complex(doc.get("target_poles"))]],
        ))  # fmt: skip
        states = [str(s) for s in doc.get("states") or []]
        units = [str(u) for u in doc.get("gain_units") or []]
        sched = [s for s in doc.get("schedule") or [] if isinstance(s, Mapping)]
        pick = sched[:: max(1, math.ceil(len(sched) / 7))]
        rows = []
        for s in pick:
            k = s.get("K")
            cells = [fmt(float(s.get("y", math.nan)) * 1e3, "mm")]
            for i in range(len(states)):
                ok = isinstance(k, list) and i < len(k)
                cells.append(fmt(k[i], units[i] if i < len(units) else "") if ok else "-")
            rows.append(cells)
        parts.append(
            table(
                ["position", *(f"K[{s}]" for s in states)],
                rows,
                caption=f"Gain schedule ({len(sched)} positions; a selection)",
            )
        )
    figs = _pngs(folder, ["open_loop_poles.png", "closed_loop_poles_4.png",
                          "closed_loop_poles_6.png", "gain_schedule_4.png",
                          "gain_schedule_6.png"])  # fmt: skip
    parts.append(_figures(figs))
    if (folder / "controller.json").is_file():
        parts.append(note(f"controller export: <code>{esc(folder / 'controller.json')}</code> "
                          "(docs/export.md)."))  # fmt: skip
    return "\n".join(parts), status, source


def _evidence(value: Any) -> str:
    if isinstance(value, Mapping):
        items = []
        for k, v in list(value.items())[:8]:
            items.append(f"{esc(k)}: {fmt(v) if isinstance(v, int | float) else _by_key(k, v)}")
        return "<br>".join(items)
    return _by_key("", value)


def _discovery_section(run: _Run) -> tuple[str, str, str]:
    folder = run.dir / "discovery"
    path = folder / "discovery.json"
    source = f"<code>{esc(path)}</code>, discovery.md and figures"
    doc, error = _read_json(path)
    if error:
        return note(esc(error), "error"), "error", source
    if doc is None:
        return _not_found(path), "not run", source
    if not isinstance(doc, dict):
        return note(f"{esc(path)}: expected a JSON object, found {esc(type(doc).__name__)}",
                    "error"), "error", source  # fmt: skip
    parts = []
    if doc.get("statement"):
        parts.append(note(f"<strong>{esc(doc['statement'])}</strong>"))
    selected = doc.get("selected")
    sel = selected if isinstance(selected, list) else [selected] if selected else []
    parts.append(f"<p>Selected effect(s): <strong>{esc(', '.join(map(str, sel)) or 'none')}"
                 "</strong></p>")  # fmt: skip
    candidates = [c for c in doc.get("candidates") or [] if isinstance(c, Mapping)]
    if candidates:
        parts.append(table(
            ["effect", "score", "selected", "evidence"],
            [[esc(c.get("effect")), fmt(c.get("score"), "", 3), fmt(c.get("effect") in sel),
              _evidence(c.get("evidence"))] for c in candidates],
            caption="Candidate effects, from the residuals of the base model",
        ))  # fmt: skip
    before, after = doc.get("rmse_before"), doc.get("rmse_after")
    if isinstance(before, Mapping) and isinstance(after, Mapping):
        rows = []
        for role in [r for r in _ROLES if r in before or r in after] + [
            r for r in before if r not in _ROLES
        ]:
            b, a = before.get(role) or {}, after.get(role) or {}
            for ch in list(b) + [c for c in a if c not in b]:
                vb, va = b.get(ch), a.get(ch)
                change = (fmt(100.0 * (va - vb) / vb, "%", 3)
                          if isinstance(va, int | float) and isinstance(vb, int | float) and vb
                          else "-")  # fmt: skip
                rows.append([esc(role), esc(ch), channel_value(ch, vb), channel_value(ch, va),
                             change])  # fmt: skip
        parts.append(
            table(
                ["role", "channel", "RMSE before", "RMSE after", "change"],
                rows,
                caption="Before and after adding the selected effect(s)",
            )
        )
    elif before is not None or after is not None:
        parts.append(note("rmse_before/rmse_after: only one of them, or not objects.", "warn"))
    p_before, p_after = doc.get("pressure_rmse_before"), doc.get("pressure_rmse_after")
    if isinstance(p_before, Mapping) and isinstance(p_after, Mapping):
        parts.append(table(
            ["role", "pressure RMSE before", "pressure RMSE after"],
            [[esc(r), channel_value("pressure", p_before.get(r)),
              channel_value("pressure", p_after.get(r))]
             for r in dict.fromkeys([*p_before, *p_after])],
            caption="Pressure RMSE (both chambers pooled)",
        ))  # fmt: skip
    refits = [r for r in doc.get("refits") or [] if isinstance(r, Mapping)]
    if refits:
        keys = [k for k in dict.fromkeys(k for r in refits for k in r)
                if all(not isinstance(r.get(k), Mapping | list) for r in refits)]  # fmt: skip
        parts.append(
            table([_key_label(k) for k in keys], [[_by_key(k, r.get(k)) for k in keys]
                                                  for r in refits],
                  caption="Refits tried (scalar fields)")
        )  # fmt: skip
    # since 2026-12-06 discovery's criteria count effective samples
    # (discovery.json's n_effective); an older file's count every sample
    counted = " (effective samples)" if doc.get("n_effective") is not None else ""
    aic = [("AIC" + counted, doc.get("aic_before"), doc.get("aic_after")),
           ("BIC" + counted, doc.get("bic_before"), doc.get("bic_after"))]  # fmt: skip
    aic_rows = [[k, fmt(b), fmt(a), fmt(a - b) if isinstance(a, int | float)
                 and isinstance(b, int | float) else "-"]
                for k, b, a in aic if b is not None or a is not None]  # fmt: skip
    if aic_rows:
        parts.append(table(["criterion", "before", "after", "change"], aic_rows))
    eff = doc.get("effect_parameters")
    if isinstance(eff, Mapping) and eff:
        rows = []
        for name, v in eff.items():
            if isinstance(v, Mapping):
                unit = str(v.get("unit") or "")
                rows.append([esc(name), fmt(v.get("value"), unit), fmt(v.get("std"), unit, 3),
                             _interval(v, "interval_90", unit)])  # fmt: skip
            else:
                rows.append([esc(name), _by_key(str(name), v), "-", "-"])
        parts.append(
            table(
                ["parameter", "value", "std", "90 % interval"],
                rows,
                caption="Parameters of the selected effect(s)",
            )
        )
    skip = ("format", "version", "candidates", "selected", "rmse_before", "rmse_after",
            "aic_before", "aic_after", "bic_before", "bic_after", "effect_parameters",
            "figures", "statement", "pressure_rmse_before", "pressure_rmse_after", "rounds",
            "refits")  # fmt: skip
    rest = {k: v for k, v in doc.items() if k not in skip}
    if rest:
        parts.append("<details><summary>Other keys of discovery.json</summary>"
                     + _kv_table(rest) + "</details>")  # fmt: skip
    parts.append(_figures(_pngs(folder, doc.get("figures"))))
    md = folder / "discovery.md"
    if md.is_file():
        try:
            parts.append("<h3>discovery.md</h3><pre>" + esc(md.read_text(encoding="utf-8"))
                         + "</pre>")  # fmt: skip
        except (OSError, UnicodeDecodeError) as exc:
            parts.append(note(f"{esc(md)}: not readable ({esc(exc)})", "error"))
    return "\n".join(parts), "ok", source


def _sil_html(path: Path) -> str:
    """The exported controller run in the loop (export/sil.json), as HTML."""
    doc, error = _read_json(path)
    head = "<h3>The exported controller in the loop</h3>"
    if error:
        return head + note(esc(error), "error")
    if not isinstance(doc, dict):
        return head + _not_found(path)
    if not doc.get("run"):
        return head + note(f"software in the loop not run: {esc(doc.get('reason'))}", "warn")
    runs = {k: doc.get(k) if isinstance(doc.get(k), Mapping) else {} for k in ("python", "c")}
    diff = doc.get("max_command_difference_V")
    same = doc.get("identical_figures") is True
    text = (
        f"The exported controller ({esc(doc.get('design'))}): its gain schedule with the "
        f"dead-band compensation, sampled every {fmt(doc.get('period_s'), 's')} with the "
        f"command held, on the plant <code>{esc(doc.get('plant'))}</code>, same steps. "
        f"The exported C code (<code>export/controller.c</code>, compiled with "
        f"<code>{esc(doc.get('compiler'))} {esc(doc.get('flags'))}</code>) was run in the "
        f"loop through ctypes beside the Python law: largest command difference "
        f"{esc(diff)} V over {esc(doc.get('samples'))} samples; "
        + ("every figure below is identical." if same else "the figures differ.")
    )
    rows = []
    keys = ("overshoot_m", "settling_time_s", "final_error_m", "air_mass_kg", "max_abs_u_V")
    c_steps = runs["c"].get("steps") or []
    for i, s in enumerate(runs["python"].get("steps") or []):
        c = c_steps[i] if i < len(c_steps) else {}
        pairs = [f"{_by_key(k, s.get(k))} / {_by_key(k, c.get(k))}" for k in keys]
        rows.append([_by_key("size_m", s.get("size_m")), *pairs])
    rows.append(["whole test", "", "", "",
                 f"{_by_key('air_mass_kg', runs['python'].get('air_mass_kg'))} / "
                 f"{_by_key('air_mass_kg', runs['c'].get('air_mass_kg'))}", ""])  # fmt: skip
    return head + note(text, "note" if same else "error") + table(
        ["step", *(f"{_key_label(k)} (Python / C)" for k in keys)], rows,
        caption="Exported controller, sampled: Python law / compiled C code",
    )  # fmt: skip


def _closed_loop_section(run: _Run) -> tuple[str, str, str]:
    """The controllers run on the nonlinear model (closed_loop.json): its
    status is that of the closed-loop test alone."""
    folder = run.dir / "closed_loop"
    path = folder / "closed_loop.json"
    source = f"<code>{esc(path)}</code> and figures; <code>export/sil.json</code>"
    doc, error = _read_json(path)
    parts = []
    status_cl = "ok"
    if error:
        parts.append(note(esc(error), "error"))
        status_cl = "error"
    elif doc is None:
        parts.append(_not_found(path))
        status_cl = "not run"
    elif not isinstance(doc, dict):
        parts.append(note(f"{esc(path)}: expected a JSON object", "error"))
        status_cl = "error"
    else:
        if doc.get("units"):
            parts.append(note(f"units in the file: {esc(doc['units'])}"))
        inputs = doc.get("inputs")
        if isinstance(inputs, Mapping) and inputs:
            parts.append(_kv_table(inputs, caption="What was run"))
        controllers = [c for c in doc.get("controllers") or [] if isinstance(c, Mapping)]
        if controllers:
            parts.append(table(
                ["controller", "order", "ok", "air mass", "exergy", "max |u|",
                 "saturated", "stiction band", "message"],
                [[esc(c.get("name")), fmt(c.get("order")), fmt(c.get("ok")),
                  _by_key("air_mass_kg", c.get("air_mass_kg")),
                  _by_key("exergy_J", c.get("exergy_J")),
                  _by_key("max_abs_u_V", c.get("max_abs_u_V")),
                  _by_key("saturation_fraction", c.get("saturation_fraction")),
                  _by_key("stiction_band_m", c.get("stiction_band_m")),
                  esc(c.get("message") or "")] for c in controllers],
                caption="Per controller: totals over the test",
            ))  # fmt: skip
            for c in controllers:
                steps = [s for s in c.get("steps") or [] if isinstance(s, Mapping)]
                if not steps:
                    continue
                keys = list(dict.fromkeys(k for s in steps for k in s))
                parts.append(
                    table(
                        [_key_label(k) for k in keys],
                        [[_by_key(k, s.get(k)) for k in keys] for s in steps],
                        caption=f"{c.get('name')}: per step (air mass and exergy of each step)",
                    )
                )
        else:
            parts.append(note("closed_loop.json lists no controllers.", "warn"))
            status_cl = "partial"
        parts.append(_figures(_pngs(folder, doc.get("figures"))))
        parts.append(_sil_html(run.dir / "export" / "sil.json"))
    return "\n".join(parts), status_cl, source


def _air_section(run: _Run) -> tuple[str, str, str]:
    """The air each fitted model draws on the recorded tests, and the nominal
    replay's (summary.json); the closed-loop test's air is in its section."""
    from pneumafit.outputs.report_models import render_air

    source = run.replay_source("the fits") + "; summary.json"
    parts = []
    have = False
    air_html = render_air(run.campaign, run.replays) if run.replays else ""
    if air_html:
        have = True
        parts.append(air_html)
    summary = run.summary
    if isinstance(summary, dict) and isinstance(summary.get("models"), Mapping):
        rows = [[esc(m), _by_key("air_supplied_kg", (r or {}).get("air_supplied_kg"))]
                for m, r in summary["models"].items()]  # fmt: skip
        if any(r[1] != "-" for r in rows):
            have = True
            parts.append(table(["model", "air supplied"], rows,
                               caption="Nominal replay of the whole campaign (summary.json, "
                                       "untuned models)"))  # fmt: skip
    if not have:
        parts.append(note("not run: no fit could be simulated on the campaign and "
                          "summary.json holds no nominal replay.", "notrun"))  # fmt: skip
        return "\n".join(parts), "not run", source
    return "\n".join(parts), "ok", source


_BUILDERS: dict[str, Callable[[_Run], tuple[str, str, str]]] = {
    "campaign": _campaign_section,
    "measurement": _measurement_section,
    "residuals": _residual_section,
    "parameters": _parameter_section,
    "mcmc": _mcmc_section,
    "comparison": _comparison_section,
    "linear": _linear_section,
    "discovery": _discovery_section,
    "closed-loop": _closed_loop_section,
    "air": _air_section,
}


def _version() -> str:
    try:
        return metadata.version("pneumafit")
    except metadata.PackageNotFoundError:
        return "unknown"


def write_report(
    run_dir: str | os.PathLike[str],
    out_html: str | os.PathLike[str],
    *,
    campaign: str | os.PathLike[str] | None = None,
    console: Console | None = None,
    allow_partial: bool = True,
) -> Path:
    """Write the validation report of a run folder as one HTML file.

    Parameters
    ----------
    run_dir : path
        Run folder (layout in the module docstring). Every input is optional:
        a section whose files are missing says "not run", one whose file
        cannot be read says why.
    out_html : path
        The HTML file, written atomically (folders created).
    campaign : path, optional
        Campaign folder; default the one recorded in a fit.json
        (``campaign.path``), comparison.json or summary.json.
    console : rich Console, optional
        Progress messages.
    allow_partial : bool
        Write the report whatever the folder holds (the default). False (the
        command line without ``--allow-partial``): raise instead, before
        anything is simulated or written, when the folder holds no result
        (:data:`RESULT_FILES`), or when the campaign cannot be read (given,
        or needed by the fits) or differs from the one the fits, comparison
        or summary were made from (``campaign.sha256``).

    Returns
    -------
    pathlib.Path
        ``out_html``.

    Raises
    ------
    PneumafitInputError
        ``run_dir`` is not an existing folder, ``campaign`` was given and does
        not exist, ``out_html`` cannot be written
        (:func:`pneumafit.fileio.output_problem`), or, unless
        ``allow_partial``, the inputs are missing or disagree (above).
    """
    import matplotlib

    matplotlib.use("Agg")
    started = time.perf_counter()
    folder = Path(run_dir)
    target = Path(out_html)
    if not folder.exists():
        raise PneumafitInputError(
            f"report: run folder {folder}: expected a folder written by pneumafit run/fit, "
            "found nothing at that path"
        )
    if not folder.is_dir():
        raise PneumafitInputError(f"report: run folder {folder}: expected a folder, found a file")
    if campaign is not None and not Path(campaign).exists():
        raise PneumafitInputError(
            f"report: option --campaign {campaign}: expected a campaign folder, found nothing "
            "at that path"
        )
    check_output(target, "file")
    run = _Run(folder, Path(campaign) if campaign is not None else None)
    if not allow_partial and not run.has_results():
        hint = ""
        if (folder / "fit.json").is_file():
            hint = (" (it holds a fit.json: the report reads a run folder whose fits are in "
                    "fits/<model>/fit.json, as pneumafit run writes them)")  # fmt: skip
        raise PneumafitInputError(
            f"report: run folder {folder}: expected the results of pneumafit run, fit, compare, "
            f"linear, closed-loop or discover, found none of {', '.join(RESULT_FILES)}{hint}; "
            "give a run folder, or --allow-partial for a report of empty sections"
        )
    run.load_campaign()
    run.problems = problems = run.disagreements(given=campaign is not None)
    if problems and not allow_partial:
        raise PneumafitInputError(
            f"report: the inputs of run folder {folder} disagree or are missing: "
            + "; ".join(problems)
            + ". Give the campaign the fits were made from with --campaign, or "
            "--allow-partial to write the report anyway"
        )
    run.replay(console)
    sections = []
    for anchor, title in SECTIONS:
        t0 = time.perf_counter()
        try:
            body, status, source = _BUILDERS[anchor](run)
        except Exception as exc:  # one broken input never takes the report down
            body = note(f"this section could not be rendered: {esc(type(exc).__name__)}: "
                        f"{esc(exc)}", "error")  # fmt: skip
            status, source = "error", ""
        sections.append(Section(anchor, title, status, body, source))
        if console is not None:
            console.print(f"report: {title}: {status} ({time.perf_counter() - t0:.1f} s)")
    name = run.campaign.name if run.campaign is not None else folder.name
    created = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    subtitle = (f"run folder <code>{esc(folder.resolve())}</code>; written {esc(created)} by "
                f"pneumafit {esc(_version())}")  # fmt: skip
    if run.problems:
        subtitle += ("<br><strong>Inputs disagree</strong> (the report was written anyway): "
                     + "; ".join(esc(p) for p in run.problems))  # fmt: skip
    headline = _quality_headline(run)
    if headline:
        subtitle += f"<br><strong>Fit quality</strong>: {headline}"
    footer = (f"pneumafit {esc(_version())}, {esc(created)}; built in "
              f"{time.perf_counter() - started:.1f} s from the files of the run folder. "
              "Self-contained: no network resource is used.")  # fmt: skip
    html_text = page(f"pneumafit validation report: {name}", subtitle, sections, footer)
    write_text_atomic(target, html_text)
    if console is not None:
        console.print(f"wrote {target} ({len(html_text) / 1e6:.1f} MB, "
                      f"{time.perf_counter() - started:.1f} s)")  # fmt: skip
    return target
