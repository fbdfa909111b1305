"""comparison.json (format ``pneumafit-comparison``) and the console table.

Keys (version 1; keys are only ever added):

- ``format``, ``version``, ``campaign`` (``name``, ``path``, ``sha256``),
  ``models`` (the model names compared, in order);
- one top-level key per model (``convection``, ``constant-lambda``,
  ``polytropic``), holding:

  - ``rmse``: ``{role: {channel: SI}}`` over every ``fit`` / ``validate``
    recording (samples pooled); ``max_abs_error`` the same shape;
    ``rmse_by_quantity``: ``{role: {pressure|position|temperature|flow: SI}}``
    (``p_P`` and ``p_N`` pooled, ...);
  - ``log_likelihood``, ``aic``, ``bic``, ``n_data``, ``n_parameters``: the
    fit's joint profile log-likelihood on the ``fit`` recordings and its
    criteria (from fit.json ``metrics``);
  - ``posterior``: WAIC and PSIS-LOO from the chains
    (:func:`~pneumafit.comparison.information.posterior_criteria`) or
    ``{"available": false, "reason": ...}``; with every model scored on the
    same points, ``waic``/``loo`` also hold ``best``, ``elpd_diff`` (best
    minus this model) and ``se_diff`` (its standard error);
  - ``temperature``: ``sensor_lag`` (s, the probe's total lag), ``probe``
    (two lags in s; its offset, K, 0 as fitted) and ``lag_source``, ``rmse`` /
    ``max_abs_error`` (``{role: K}``) where a temperature is measured, and
    ``predicted`` (``{recording: {T_P|T_N: {initial, min, max, final}}}``,
    K, the gas temperature without sensor lag in every chamber);
  - ``recordings``: ``{file: {kind, role, ok, channels: {channel: {n, rmse,
    fit_percent, max_abs_error}}}}``;
  - ``fit``: where the fit came from (``file``, ``given`` or fitted here,
    ``mcmc``) and ``fit_json_rmse`` (fit.json's own RMSE, for a cross-check);
  - ``warnings``;
- ``table``: the same per-recording numbers in long form, one row per
  (model, recording, channel);
- ``best``: per role and channel (and quantity) the model with the lowest
  RMSE; per criterion (``aic``, ``bic``, ``waic``, ``loo``) the model with the
  lowest value (deviance scale); ``comparable_criteria`` says whether the
  fits' data counts agree;
- ``figures``: PNG files, relative to the output folder;
- ``provenance``: ``pneumafit_version``, ``created``, ``command``, ``seconds``.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table
from rich.text import Text

from pneumafit.campaign.model import Campaign
from pneumafit.campaign.units import display_unit
from pneumafit.comparison.evaluate import ModelEvaluation
from pneumafit.identification.fitfile import _version, json_safe
from pneumafit.identification.staged import campaign_identity

__all__ = ["COMPARISON_FORMAT", "COMPARISON_VERSION", "comparison_document", "print_table"]

COMPARISON_FORMAT = "pneumafit-comparison"
COMPARISON_VERSION = 1
ROLES = ("fit", "validate")
CHANNEL_ORDER = ("p_P", "p_N", "y", "T_P", "T_N", "qm_P", "qm_N")
QUANTITY_ORDER = ("pressure", "position", "temperature", "flow")


def _temperature_summary(ev: ModelEvaluation) -> dict[str, Any]:
    predicted: dict[str, dict[str, dict[str, float]]] = {}
    for tr in ev.traces:
        if tr.kind == "flow":
            continue
        chambers = ("P", "N")
        out: dict[str, dict[str, float]] = {}
        for ch in chambers:
            gas = tr.simulated[f"T_{ch}"]
            if gas.size and np.all(np.isfinite(gas)):
                out[f"T_{ch}"] = {
                    "initial": float(gas[0]), "min": float(gas.min()),
                    "max": float(gas.max()), "final": float(gas[-1]),
                }  # fmt: skip
        predicted[tr.recording] = out
    rmse: dict[str, float] = {}
    worst: dict[str, float] = {}
    for role in ROLES:
        pooled = ev.pooled(role, by="quantity").get("temperature")
        if pooled is not None:
            rmse[role] = pooled.rmse
            worst[role] = pooled.max_abs_error
    return {
        "sensor_lag": ev.temperature_sensor_lag,
        "probe": ev.temperature_probe.as_dict() if ev.temperature_probe else None,
        "lag_source": ev.lag_source,
        "rmse": rmse,
        "max_abs_error": worst,
        "predicted": predicted,
    }


def _best(values: Mapping[str, float | None]) -> str | None:
    finite = {m: v for m, v in values.items() if v is not None and math.isfinite(v)}
    return min(finite, key=finite.__getitem__) if finite else None


def comparison_document(
    campaign: Campaign,
    evaluations: Sequence[ModelEvaluation],
    fits: Mapping[str, Mapping[str, Any]],
    posteriors: Mapping[str, Mapping[str, Any]],
    *,
    sources: Mapping[str, Mapping[str, Any]] | None = None,
    figures: Sequence[str] = (),
    command: str = "",
    seconds: float = 0.0,
) -> dict[str, Any]:
    """The comparison.json content (module docstring).

    Parameters
    ----------
    campaign : Campaign
    evaluations : sequence of ModelEvaluation
        One per model, in the order listed.
    fits : mapping of str to mapping
        Model -> its parsed fit.json.
    posteriors : mapping of str to mapping
        Model -> :func:`~pneumafit.comparison.information.posterior_criteria`.
    sources : mapping of str to mapping, optional
        Model -> where its fit came from (``file``, ``given``).
    figures : sequence of str
    command : str
    seconds : float
        Wall time (s) of the whole comparison.
    """
    models = [ev.model for ev in evaluations]
    doc: dict[str, Any] = {
        "format": COMPARISON_FORMAT,
        "version": COMPARISON_VERSION,
        "campaign": campaign_identity(campaign),
        "models": models,
    }
    table: list[dict[str, Any]] = []
    for ev in evaluations:
        fit = fits[ev.model]
        metrics = fit.get("metrics") or {}
        entry: dict[str, Any] = {
            "rmse": {r: {c: e.rmse for c, e in _ordered(ev.pooled(r))} for r in ROLES},
            "max_abs_error": {
                r: {c: e.max_abs_error for c, e in _ordered(ev.pooled(r))} for r in ROLES
            },
            "rmse_by_quantity": {
                r: {q: e.rmse for q, e in _ordered(ev.pooled(r, "quantity"), QUANTITY_ORDER)}
                for r in ROLES
            },
            "log_likelihood": metrics.get("log_likelihood"),
            "aic": metrics.get("aic"),
            "bic": metrics.get("bic"),
            "n_data": metrics.get("n_data"),
            "n_parameters": metrics.get("n_parameters"),
            "posterior": dict(posteriors.get(ev.model) or {"available": False,
                                                           "reason": "not computed"}),
            "temperature": _temperature_summary(ev),
            "recordings": {},
            "fit": {
                **dict((sources or {}).get(ev.model) or {}),
                "mcmc": bool(fit.get("mcmc")),
                "fit_json_rmse": metrics.get("rmse"),
                "structure": fit.get("structure"),
            },
            "warnings": list(ev.warnings),
        }  # fmt: skip
        for tr in ev.traces:
            entry["recordings"][tr.recording] = {
                "kind": tr.kind,
                "role": tr.role,
                "ok": tr.ok,
                "channels": {c: e.as_dict() for c, e in _ordered(tr.errors)},
            }
            for c, e in _ordered(tr.errors):
                table.append({"model": ev.model, "recording": tr.recording, "kind": tr.kind,
                              "role": tr.role, "channel": c, **e.as_dict()})  # fmt: skip
        doc[ev.model] = entry
    best: dict[str, Any] = {}
    for r in ROLES:
        keys = {k for m in models for k in doc[m]["rmse"][r]}
        best[r] = {
            c: _best({m: doc[m]["rmse"][r].get(c) for m in models})
            for c in CHANNEL_ORDER if c in keys
        }  # fmt: skip
        qkeys = {k for m in models for k in doc[m]["rmse_by_quantity"][r]}
        best[r].update({
            q: _best({m: doc[m]["rmse_by_quantity"][r].get(q) for m in models})
            for q in QUANTITY_ORDER if q in qkeys
        })  # fmt: skip
    for crit in ("aic", "bic"):
        best[crit] = _best({m: doc[m][crit] for m in models})
    for crit in ("waic", "loo"):
        vals = {
            m: doc[m]["posterior"][crit]["deviance"]
            for m in models
            if doc[m]["posterior"].get("available")
        }
        best[crit] = _best(vals) if len(vals) == len(models) else None
    n_data = {doc[m]["n_data"] for m in models}
    best["comparable_criteria"] = len(n_data) == 1
    doc["best"] = best
    doc["table"] = table
    doc["figures"] = list(figures)
    doc["provenance"] = {
        "pneumafit_version": _version(),
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "command": command,
        "seconds": seconds,
    }
    return json_safe(doc)


def _ordered(
    mapping: Mapping[str, Any], order: Sequence[str] = CHANNEL_ORDER
) -> list[tuple[str, Any]]:
    return sorted(mapping.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else 99)


def _fmt(x: float | None, scale: float = 1.0, digits: int = 4) -> str:
    if x is None or not math.isfinite(x):
        return "-"
    return f"{x * scale:.{digits}g}"


def print_table(document: Mapping[str, Any], console: Console) -> None:
    """Three models x role x channel RMSE, criteria, best model marked (bold, *)."""
    models = list(document["models"])
    best = document["best"]
    table = Table(title=Text(f"{document['campaign']['name']}: RMSE by role and channel "
                             "(* best; temperatures through each fit's probe)"))  # fmt: skip
    table.add_column("role", no_wrap=True)
    table.add_column("channel", no_wrap=True)
    table.add_column("unit", no_wrap=True)
    for m in models:
        table.add_column(m, justify="right")
    for role in ROLES:
        keys = [k for k in (*CHANNEL_ORDER, *QUANTITY_ORDER) if k in best.get(role, {})]
        for k in keys:
            source = "rmse" if k in CHANNEL_ORDER else "rmse_by_quantity"
            scale, unit = display_unit(k)
            cells = []
            for m in models:
                v = document[m][source][role].get(k)
                text = _fmt(v, scale)
                cells.append(Text(text + " *", style="bold") if best[role][k] == m else text)
            label = k if k in CHANNEL_ORDER else f"all {k}"
            table.add_row(role, label, unit, *cells)
        table.add_section()
    for crit in ("log_likelihood", "aic", "bic"):
        cells = []
        for m in models:
            text = _fmt(document[m][crit], digits=8)
            if best.get(crit) == m:
                cells.append(Text(text + " *", style="bold"))
            else:
                cells.append(text)
        table.add_row("fit", crit.replace("_", "-"), "", *cells)
    for crit in ("waic", "loo"):
        cells, diffs = [], []
        for m in models:
            post = document[m]["posterior"]
            if not post.get("available"):
                cells.append("n/a")
                diffs.append("")
                continue
            c = post[crit]
            text = f"{c['deviance']:.8g}"
            cells.append(Text(text + " *", style="bold") if best.get(crit) == m else text)
            diffs.append(
                f"{0.0 - c['elpd_diff'] + 0.0:.6g} ± {c['se_diff']:.3g}" if "elpd_diff" in c else ""
            )
        table.add_row("fit", f"{crit} (deviance)", "", *cells)
        if any(diffs):
            table.add_row("fit", f"{crit} elpd - best", "", *diffs)
    console.print(table)
    if not best.get("comparable_criteria", True):
        console.print(Text("warning: the fits compared different numbers of data points: "
                           "AIC/BIC are not comparable", "yellow"))  # fmt: skip
    for m in models:
        post = document[m]["posterior"]
        if not post.get("available"):
            console.print(f"{m}: no WAIC/LOO: {post.get('reason')}")
