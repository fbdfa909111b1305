"""fit.json: the contract other tools and scripts read (format ``pneumafit-fit``).

Keys (version 1; keys are only ever added):

- ``format``, ``version``, ``model``; ``structure`` (name, heat law, air
  properties, valve law, friction law, effects; ``friction`` was added with
  the LuGre law, a reader takes its absence as ``"switch"``);
- ``campaign``: ``name``, ``path``, ``sha256`` (file -> hash, as read);
- ``parameters``: every model parameter by canonical name, SI:
  ``value`` (joint least-squares estimate), ``unit``, ``std``,
  ``interval_90`` ([5 %, 95 %] quantiles), ``fixed``, and ``median``,
  ``uncertainty`` (``"mcmc"`` or ``"laplace"``), ``laplace_std``,
  ``laplace_interval_90`` (joint Laplace approximation, which includes the
  other groups' uncertainty), ``lower``, ``upper``, ``scale``, ``group``;
  only model parameters, so :func:`pneumafit.parameters_io.read_parameter_file`
  reads the file as a parameter file;
- ``nuisance``: measurement parameters (sensor lags) and ``initial_states``
  (the fitted initial pressures, temperatures and positions by recording);
- ``correlation``: posterior correlation matrices by stage (``names``,
  ``matrix``), from MCMC or else the joint Laplace approximation;
- ``metrics``: ``rmse`` (``fit``, ``validate``: channel -> SI), ``log_likelihood``,
  ``aic``, ``bic``, ``n_data``, ``n_parameters``, ``temperature_sensor_lag``;
- ``mcmc``: ``walkers``, ``steps`` (largest over the sampled stages),
  ``acceptance`` (mean), ``tau``, ``rhat``, ``ess`` (parameter -> value),
  ``stages`` (per stage: all diagnostics), ``chains`` (file name, group per
  stage); null without MCMC;
- ``noise``: per compared block, the noise model and its estimated sigma;
- ``stages``: what each stage of the staged fit did;
- ``warnings``;
- ``provenance``: ``pneumafit_version``, ``seed``, ``created``, ``command``,
  ``options``, ``seconds``, ``evaluations``.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pneumafit.campaign.model import Campaign
from pneumafit.fileio import write_text_atomic
from pneumafit.identification.staged import FitOptions, FitResult
from pneumafit.models.layout import SPECS

__all__ = ["FIT_FORMAT", "FIT_VERSION", "fit_document", "write_fit_json"]

FIT_FORMAT = "pneumafit-fit"
FIT_VERSION = 1


def _version() -> str:
    try:
        return metadata.version("pneumafit")
    except metadata.PackageNotFoundError:
        return "unknown"


def json_safe(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars and arrays to Python, non-finite floats to None.

    Mappings get string keys; tuples become lists. Used for every JSON
    document pneumafit writes (fit.json, discovery.json).
    """
    if isinstance(obj, Mapping):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, np.bool_ | bool):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        x = float(obj)
        return x if math.isfinite(x) else None
    return obj


def fit_document(
    result: FitResult,
    campaign: Campaign,
    *,
    seed: int,
    command: str = "",
    options: FitOptions | None = None,
    chains: str | None = None,
) -> dict[str, Any]:
    """The fit.json content of a result (see the module docstring)."""
    params: dict[str, Any] = {}
    nuisance: dict[str, Any] = {}
    initial: dict[str, Any] = {}
    laplace = result.laplace
    for p in result.parameters:
        entry = {
            "value": p.value,
            "unit": p.unit,
            "std": p.std,
            "interval_90": list(p.interval_90) if p.interval_90 is not None else None,
            "fixed": bool(p.fixed and p.std is None),
            "median": p.median,
            "uncertainty": p.uncertainty,
            "lower": p.lower,
            "upper": p.upper,
            "scale": p.scale,
            "group": p.group,
        }
        if laplace is not None and p.name in laplace and laplace[p.name].std is not None:
            lp = laplace[p.name]
            entry["laplace_std"] = lp.std
            entry["laplace_interval_90"] = list(lp.interval_90) if lp.interval_90 else None
        if p.name in SPECS:
            params[p.name] = entry
        elif p.group == "initial":
            initial[p.name.split(":", 1)[1]] = {
                "value": p.value, "unit": p.unit, "std": entry.get("laplace_std"),
            }  # fmt: skip
        else:
            nuisance[p.name] = entry
    correlation: dict[str, Any] = {}
    for stage in result.stages:
        if stage.propagated is not None and stage.propagated.correlation is not None:
            names, matrix = stage.propagated.correlation
            correlation[stage.name] = {"source": "mcmc", "names": list(names), "matrix": matrix}
    if laplace is not None and laplace.correlation is not None:
        names, matrix = laplace.correlation
        keep = [i for i, n in enumerate(names) if n in SPECS]
        correlation["joint"] = {
            "source": "laplace",
            "names": [names[i] for i in keep],
            "matrix": np.asarray(matrix)[np.ix_(keep, keep)],
        }
    mcmc: dict[str, Any] | None = None
    runs = result.mcmc
    if runs:
        mcmc = {
            "walkers": max(r.n_walkers for r in runs),
            "steps": max(r.n_steps for r in runs),
            "acceptance": float(np.mean([r.acceptance for r in runs])),
            "tau": {k: v for r in runs for k, v in r.tau.items()},
            "tau_multiple": {r.name: r.tau_multiple for r in runs},
            "rhat": {k: v for r in runs for k, v in r.rhat.items()},
            "ess": {k: v for r in runs for k, v in r.ess.items()},
            "stages": {r.name: r.as_dict() for r in runs},
            "chains": {"file": chains, "groups": [r.name for r in runs]} if chains else None,
            "walker_chains_note": (
                "R-hat and ESS treat each walker as a chain (ArviZ); "
                "posteriors are conditional on the other groups at the joint estimate"
            ),
        }
    joint = next((s for s in result.stages if s.name == "joint"), None)
    noise: list[dict[str, Any]] = []
    if joint is not None and joint.estimate is not None:
        for block, est in zip(result.blocks, joint.estimate.noise, strict=False):
            noise.append({**block, "estimate": est})
    doc = {
        "format": FIT_FORMAT,
        "version": FIT_VERSION,
        "model": result.model,
        "structure": {
            "name": result.structure.name,
            "heat": result.structure.heat,
            "air_properties": result.structure.air_properties,
            "valve": result.structure.valve,
            "friction": result.structure.friction,
            "effects": dict(result.structure.effects),
        },
        "campaign": {
            "name": campaign.name,
            "path": os.fspath(campaign.path) if campaign.path is not None else None,
            "sha256": dict(campaign.sha256),
        },
        "parameters": params,
        "nuisance": {**nuisance, "initial_states": initial},
        "correlation": correlation,
        "metrics": result.metrics,
        "quality": result.quality.as_dict() if result.quality is not None else None,
        "mcmc": mcmc,
        "noise": noise,
        "stages": {s.name: s.as_dict() for s in result.stages},
        "warnings": list(result.warnings),
        "provenance": {
            "pneumafit_version": _version(),
            "seed": int(seed),
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "command": command,
            "options": _options(options),
            "seconds": result.seconds,
            "evaluations": result.evaluations,
        },
    }
    return json_safe(doc)


def _options(options: FitOptions | None) -> dict[str, Any] | None:
    if options is None:
        return None
    out = asdict(options)
    noise = options.noise
    if noise is not None and not isinstance(noise, str):
        if isinstance(noise, Mapping):
            out["noise"] = {
                k: (v if isinstance(v, str) else v.describe()) for k, v in noise.items()
            }
        else:
            out["noise"] = noise.describe()
    return out


def write_fit_json(path: str | os.PathLike[str], document: Mapping[str, Any]) -> Path:
    """Write a fit document as JSON, atomically (never a half-written file)."""
    target = Path(path)
    write_text_atomic(target, json.dumps(document, indent=2, allow_nan=False) + "\n")
    return target
