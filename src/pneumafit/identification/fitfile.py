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
  other groups' uncertainty), ``lower``, ``upper``, ``scale``, ``group``,
  and ``interval_widening`` where the misspecification-robust covariance
  widened the Laplace standard deviation by that factor (> 1; the
  Laplace figures above include it; see
  :func:`~pneumafit.identification.optimise.recording_robust_covariance`);
  only model parameters, so :func:`pneumafit.parameters_io.read_parameter_file`
  reads the file as a parameter file;
- ``nuisance``: measurement parameters (sensor lags; since 2026-12-01 the
  pressure sensors' offsets ``offset:p_P`` and ``offset:p_N`` in Pa,
  :func:`~pneumafit.identification.problem.pressure_offsets`, since
  2026-12-04 only where the fit recordings agree on them; every sensor's
  estimate and test in ``metrics.sensor_offsets``) and
  ``initial_states`` (the fitted initial pressures, temperatures and
  positions by recording);
- ``correlation``: posterior correlation matrices by stage (``names``,
  ``matrix``), from MCMC or else the joint Laplace approximation;
- ``metrics``: ``rmse`` (``fit``, ``validate``: channel -> SI), ``log_likelihood``,
  ``aic``, ``bic``, ``n_data``, ``n_parameters``, ``temperature_probe``
  (``time_constant``, ``second_time_constant`` in s, ``offset`` in K; null
  without temperatures; since 2026-11-30, read by
  :meth:`~pneumafit.simulation.sensor.TemperatureProbe.from_metrics`) and
  ``temperature_sensor_lag`` (its total lag, s; the one lag of older files);
- ``mcmc``: ``walkers``, ``steps`` (largest over the sampled stages),
  ``acceptance`` (mean), ``tau``, ``rhat``, ``ess`` (parameter -> value),
  ``stages`` (per stage: all diagnostics), ``chains`` (file name, group per
  stage); null without MCMC;
- ``noise``: per compared block, the noise model and its estimated sigma;
- ``stages``: what each stage of the staged fit did;
- ``warnings``;
- ``provenance``: ``pneumafit_version``, ``seed``, ``created``, ``command``,
  ``options``, ``seconds``, ``evaluations``, ``parts`` (the fingerprint of
  the parts registered from outside the package, "" for none:
  :func:`pneumafit.models.part_kernel.parts_digest`).

Friction-test fits (model ``friction``, :mod:`pneumafit.frictiontest`) use
the same format: ``structure`` holds ``friction`` (the bench's law) and
``effects`` (effect -> fitted value), ``heat``, ``air_properties`` and
``valve`` are null, and the effect parameters are model parameters
(``parameters``), not nuisance.

Reading and writing. This module is the only code that touches fit.json:
:meth:`FitResult.save <pneumafit.identification.staged.FitResult.save>`
(:func:`fit_document` + :func:`write_fit_json`) writes it, and
:meth:`FitResult.load <pneumafit.identification.staged.FitResult.load>`
(:func:`load_fit`) reads it into a :class:`SavedFit`, the typed view every
reader uses; a document already parsed by a generic reader (a parameter
file that may be a fit.json) goes through :meth:`SavedFit.from_document`.
A bad file raises :class:`~pneumafit.campaign.errors.PneumafitInputError`
naming the file, the key, what was expected and what was found.

Keys a reader may find missing, with the one fallback of each (what the
version-1 writer wrote; every version-1 writer wrote ``structure`` in full
except ``friction``, which came with the LuGre law):

- ``version`` absent: 1; a version above :data:`FIT_VERSION` is refused;
- ``structure`` absent, or any key of it: the registered structure of
  ``model`` (:data:`pneumafit.models.structure.MODELS`) as
  :func:`~pneumafit.identification.staged.fit_structure` makes it, i.e.
  ``heat`` the model's heat law, ``air_properties`` ``"sutherland"`` for the
  convection law and ``"constant"`` for the others (what every version-1
  writer wrote: the convection structure has been fitted with Sutherland
  air since the first fit.json, git e932d63), ``valve`` ``"iso6358"``,
  ``friction`` ``"switch"``, ``inputs`` ``"linear"`` (every fit written
  before the held inputs interpolated the sampled inputs), ``effects`` none,
  ``name`` the heat law (with the effects, as
  :meth:`ModelStructure.with_effects` names them);
- ``parameters`` (present in every fit written; a reader that needs
  values, such as a parameter-file reader, refuses a file without them),
  ``nuisance``, ``metrics``, ``stages``, ``provenance``, ``campaign``:
  empty; ``mcmc``, ``quality``: null; ``warnings``: none;
- ``provenance.options.noise_pooling`` absent: ``"recording"`` (every fit
  written before the option profiled a noise level per recording and
  channel; :func:`noise_pooling_of`);
- ``provenance.options.offset_scope`` absent: ``"recording"`` (every fit
  written before the option profiled a pressure offset per recording and
  channel; :func:`offset_scope_of`);
- ``provenance.parts`` absent: "" (written before 2026-11-30, seventeenth
  session; a run reuses such a fit only without outside parts).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pneumafit.campaign.model import Campaign
from pneumafit.errors import PneumafitInputError
from pneumafit.fileio import write_text_atomic
from pneumafit.identification.parameters import Parameter, ParameterSet
from pneumafit.identification.staged import (
    FitOptions,
    FitResult,
    campaign_identity,
    fit_structure,
)
from pneumafit.models.layout import FRICTION_LAWS, SPECS, VALVE_LAWS
from pneumafit.models.part_kernel import parts_digest
from pneumafit.models.structure import EFFECT_SLOTS, INPUT_MODES, MODELS, ModelStructure

__all__ = [
    "CHAINS_FILE",
    "FIT_FILE",
    "FIT_FORMAT",
    "FIT_VERSION",
    "SavedFit",
    "fit_document",
    "is_fit_document",
    "load_fit",
    "noise_pooling_of",
    "offset_scope_of",
    "write_fit_json",
]

FIT_FORMAT = "pneumafit-fit"
FIT_VERSION = 1
#: Name of the file in a fit folder (``pneumafit fit --out FOLDER``).
FIT_FILE = "fit.json"
#: The emcee chains beside fit.json, when ``mcmc.chains.file`` names none.
CHAINS_FILE = "chains.h5"


def offset_scope_of(options: Mapping[str, Any] | None) -> str:
    """How widely a fit shared its profiled sensor offsets, from its
    ``provenance.options`` (``FitOptions.offset_scope``); ``"recording"``
    when absent (the module doc's fallback)."""
    scope = (options or {}).get("offset_scope")
    return str(scope) if scope else "recording"


def noise_pooling_of(options: Mapping[str, Any] | None) -> str:
    """How a fit profiled its noise levels, from its ``provenance.options``
    (``FitOptions.noise_pooling``); ``"recording"`` when absent (the module
    doc's fallback)."""
    pooling = (options or {}).get("noise_pooling")
    return str(pooling) if pooling else "recording"


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


#: Default of :func:`fit_document`'s ``options``: the result's own.
_RESULT_OPTIONS: Any = object()


def fit_document(
    result: FitResult,
    campaign: Campaign | None = None,
    *,
    seed: int | None = None,
    command: str = "",
    options: FitOptions | Mapping[str, Any] | None = _RESULT_OPTIONS,
    chains: str | None = None,
) -> dict[str, Any]:
    """The fit.json content of a result (see the module docstring).

    Parameters
    ----------
    result : FitResult
    campaign : Campaign, optional
        The campaign fitted (its name, path and file hashes are recorded);
        default the result's own (:attr:`FitResult.campaign`).
    seed : int, optional
        Default the result's own (:attr:`FitResult.seed`).
    command : str
        The command line, for provenance.
    options : FitOptions or mapping or None, optional
        Recorded as ``provenance.options``; default the result's own
        (:attr:`FitResult.options`); None records null.
    chains : str, optional
        File name of the MCMC chains beside fit.json.

    Raises
    ------
    PneumafitInputError
        No campaign or seed given and none in the result.
    """
    if campaign is not None:
        identity: Mapping[str, Any] = campaign_identity(campaign)
    elif result.campaign is not None:
        identity = result.campaign
    else:
        raise PneumafitInputError(
            "fit document: expected a campaign (the result does not record one), found none"
        )
    seed = result.seed if seed is None else seed
    if seed is None:
        raise PneumafitInputError(
            "fit document: expected a seed (the result does not record one), found none"
        )
    if options is _RESULT_OPTIONS:
        options = result.options
    friction_test = result.model == "friction"
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
        widening = getattr(result, "widening", {}).get(p.name, 1.0)
        if widening > 1.0:
            entry["interval_widening"] = float(widening)
        if p.name in SPECS or (friction_test and p.group == "effect"):
            params[p.name] = entry  # a friction test's effects are its model's parameters
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
            "inputs": result.structure.inputs,
            "effects": dict(result.structure.effects),
        },
        "campaign": {
            "name": identity["name"],
            "path": identity["path"],
            "sha256": dict(identity["sha256"]),
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
            # the parts from outside the package registered when the fit was
            # saved ("" for none): a run reuses the fit only with the same
            "parts": parts_digest(),
        },
    }
    return json_safe(doc)


def _options(options: FitOptions | Mapping[str, Any] | None) -> dict[str, Any] | None:
    if options is None:
        return None
    if not isinstance(options, FitOptions):  # a friction-test fit's (law, effects, ...)
        return dict(options)
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


# ------------------------------------------------------------------ reading
def is_fit_document(document: Any) -> bool:
    """True for a parsed JSON document of format ``pneumafit-fit``."""
    return isinstance(document, Mapping) and document.get("format") == FIT_FORMAT


def _problem(where: str, key: str, expected: str, found: Any) -> PneumafitInputError:
    return PneumafitInputError(f"{where}: {key}: expected {expected}, found {found}")


def _section(doc: Mapping[str, Any], key: str, where: str, default: Any) -> Any:
    """``doc[key]``, an object or null (-> ``default``)."""
    value = doc.get(key)
    if value is None:
        return default
    if not isinstance(value, Mapping):
        raise _problem(where, key, "an object", f"{type(value).__name__} {value!r:.60}")
    return value


def _number(entry: Any, key: str, where: str) -> float:
    """The finite ``value`` of a parameter entry (an object with ``value``, or a number)."""
    value = entry.get("value") if isinstance(entry, Mapping) else entry
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _problem(where, f"{key}.value", "a finite number", repr(value))
    return float(value)


@dataclass(frozen=True, eq=False)
class SavedFit:
    """A fit read back from fit.json (:func:`load_fit`, :meth:`FitResult.load`).

    What a fit.json holds, typed, with the documented fallbacks for keys a
    file lacks (module docstring). The objects of the fit itself (stages,
    chains, Laplace set) are not in the file: a :class:`SavedFit` is not a
    :class:`~pneumafit.identification.staged.FitResult`; keys it does not
    model are in :attr:`document`, the parsed file as it is.

    Attributes
    ----------
    document : dict
        The parsed document, unchanged (:meth:`save` writes it back).
    source : str
        The file read, for messages (``"fit.json"`` when not known).
    model : str
        ``convection``, ``constant-lambda``, ``polytropic`` or ``friction``.
    version : int
        Format version (1 when absent).
    structure : ModelStructure or None
        The structure fitted, with the fallbacks; None for a friction-test
        fit (model ``friction``) and for a model without a registered
        structure that the file does not describe (no ``structure.heat``).
    friction : str
        ``structure.friction`` (``"switch"`` when absent); for a
        friction-test fit the bench's law (``lugre``, ``stribeck``, ...).
    effects : dict of str to float
        ``structure.effects``: option by effect (actuator), fitted value by
        effect (friction test).
    values : dict of str to float
        ``value`` of every model parameter (``parameters``), SI.
    nuisance : dict of str to float
        ``value`` of every measurement parameter (``nuisance`` but its
        ``initial_states``), SI.
    initial_states : dict of str to float
        Fitted initial states by ``<recording>:<state>``, SI.
    campaign : dict
        ``name``, ``path``, ``sha256`` (file -> SHA-256) as recorded.
    metrics : dict
    quality : dict or None
    mcmc : dict or None
    stages : dict
    warnings : list of str
    provenance : dict
    """

    document: Mapping[str, Any]
    source: str
    model: str
    version: int
    structure: ModelStructure | None
    friction: str
    effects: dict[str, float]
    values: dict[str, float]
    nuisance: dict[str, float]
    initial_states: dict[str, float]
    campaign: Mapping[str, Any] = field(default_factory=dict)
    metrics: Mapping[str, Any] = field(default_factory=dict)
    quality: Mapping[str, Any] | None = None
    mcmc: Mapping[str, Any] | None = None
    stages: Mapping[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    provenance: Mapping[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return f"SavedFit({self.model}, {len(self.values)} parameters, from {self.source})"

    def summary(self) -> str:
        """The saved verdict, then the free parameters' table."""
        verdict = (self.quality or {}).get("verdict") or "no verdict saved"
        return f"{self!r}: {verdict}\n{self.parameters.summary()}"

    def to_dataframe(self) -> Any:
        """Every saved parameter as a :class:`pandas.DataFrame` (SI units)."""
        return self.parameters.to_dataframe()

    def _repr_html_(self) -> str:
        import html

        return f"<p><b>{html.escape(repr(self))}</b></p>" + self.parameters._repr_html_()

    # ------------------------------------------------------------ typed views
    @property
    def path(self) -> Path:
        """The file read (:attr:`source`)."""
        return Path(self.source)

    @property
    def seed(self) -> int | None:
        """``provenance.seed``: the seed the fit was made with."""
        seed = self.provenance.get("seed")
        return int(seed) if isinstance(seed, int) and not isinstance(seed, bool) else None

    @property
    def options(self) -> dict[str, Any] | None:
        """``provenance.options``: the settings the fit was made with (JSON form)."""
        options = self.provenance.get("options")
        return dict(options) if isinstance(options, Mapping) else None

    @property
    def offset_scope(self) -> str:
        """``provenance.options.offset_scope`` (:func:`offset_scope_of`)."""
        return offset_scope_of(self.options)

    @property
    def noise_pooling(self) -> str:
        """``provenance.options.noise_pooling`` (:func:`noise_pooling_of`)."""
        return noise_pooling_of(self.options)

    @property
    def chains_path(self) -> Path | None:
        """The emcee chains beside the fit.json read (``mcmc.chains.file``,
        default :data:`CHAINS_FILE`); None without MCMC or for a fit not read
        from a file."""
        if not self.mcmc or not self.path.is_file():
            return None
        return self.path.parent / ((self.mcmc.get("chains") or {}).get("file") or CHAINS_FILE)

    @property
    def campaign_sha256(self) -> dict[str, str]:
        """``campaign.sha256``: file -> SHA-256 of the campaign fitted."""
        return dict(self.campaign.get("sha256") or {})

    @property
    def all_values(self) -> dict[str, float]:
        """Model and measurement parameters, and the initial states as
        ``initial:<recording>:<state>``: what a simulation of the fit needs."""
        return {
            **self.values,
            **self.nuisance,
            **{f"initial:{k}": v for k, v in self.initial_states.items()},
        }

    @cached_property
    def parameters(self) -> ParameterSet:
        """The model parameters as a :class:`ParameterSet` (value, unit,
        bounds, scale, group, fixed and the posterior summaries as written),
        with the joint Laplace correlation when the file has one.

        Raises
        ------
        PneumafitInputError
            An entry the set cannot take (naming the file and key).
        """
        where = f"{self.source}: "
        entries = self.document.get("parameters") or {}
        plist = [Parameter.from_dict(str(n), _entry(e), where) for n, e in entries.items()]
        correlation = None
        joint = (self.document.get("correlation") or {}).get("joint")
        if isinstance(joint, Mapping) and joint.get("names"):
            names = tuple(str(n) for n in joint["names"])
            if set(names) <= {p.name for p in plist}:
                try:
                    correlation = (names, np.asarray(joint.get("matrix"), dtype=float))
                except (TypeError, ValueError):
                    raise _problem(self.source, "correlation.joint.matrix",
                                   "a matrix of numbers", repr(joint.get("matrix"))[:80],
                                   ) from None  # fmt: skip
        try:
            return ParameterSet(plist, correlation)
        except ValueError as exc:
            raise PneumafitInputError(f"{where}parameters: {exc}") from None

    # ------------------------------------------------------------------- I/O
    @classmethod
    def from_document(cls, document: Any, where: str | os.PathLike[str] = "fit.json") -> SavedFit:
        """Read a parsed fit.json document: the one parser of the format.

        Parameters
        ----------
        document : dict
            The parsed JSON.
        where : str or path
            The file, for messages (:attr:`source`).

        Raises
        ------
        PneumafitInputError
            Not a ``pneumafit-fit`` document, a newer version, or a key of
            the wrong type or value; the message names the file and the key.
        """
        name = os.fspath(where)
        if not isinstance(document, Mapping):
            raise _problem(name, "format", f"a JSON object of format {FIT_FORMAT!r}",
                           f"a {type(document).__name__}")  # fmt: skip
        if document.get("format") != FIT_FORMAT:
            raise _problem(name, "format", repr(FIT_FORMAT), repr(document.get("format")))
        version = document.get("version", 1)
        if isinstance(version, bool) or not isinstance(version, int) or version > FIT_VERSION:
            raise _problem(name, "version", f"an integer up to {FIT_VERSION}", repr(version))
        model = document.get("model")
        if not isinstance(model, str):
            raise _problem(name, "model", f"one of {', '.join(MODELS)}, friction", repr(model))
        parameters = document.get("parameters", {})
        if not isinstance(parameters, Mapping):
            raise _problem(name, "parameters", "an object of name: {value, unit, ...}",
                           repr(parameters))  # fmt: skip
        values = {str(k): _number(e, f"parameters.{k}", name) for k, e in parameters.items()}
        nuisance_doc = _section(document, "nuisance", name, {})
        nuisance = {
            str(k): _number(e, f"nuisance.{k}", name)
            for k, e in nuisance_doc.items()
            if k != "initial_states" and isinstance(e, Mapping) and "value" in e
        }
        initial_doc = nuisance_doc.get("initial_states") or {}
        if not isinstance(initial_doc, Mapping):
            raise _problem(name, "nuisance.initial_states", "an object",
                           type(initial_doc).__name__)  # fmt: skip
        initial = {
            str(k): float(v)
            for k, e in initial_doc.items()
            if isinstance(v := (e.get("value") if isinstance(e, Mapping) else e), int | float)
            and not isinstance(v, bool)
            and math.isfinite(v)
        }
        spec = _section(document, "structure", name, {})
        friction = spec.get("friction")
        friction = "switch" if friction is None else friction
        effects = spec.get("effects")
        effects = {} if effects is None else effects
        if not isinstance(effects, Mapping):
            raise _problem(name, "structure.effects", "a table of effect = option",
                           repr(effects))  # fmt: skip
        structure = None
        if model != "friction":
            structure = _structure(model, spec, name)
        warnings = document.get("warnings") or []
        campaign = _section(document, "campaign", name, {})
        sha = campaign.get("sha256")
        if sha is not None and not isinstance(sha, Mapping):
            raise _problem(name, "campaign.sha256", "an object of file: SHA-256",
                           type(sha).__name__)  # fmt: skip
        return cls(
            document=document,
            source=name,
            model=model,
            version=int(version),
            structure=structure,
            friction=str(friction),
            effects=dict(effects),
            values=values,
            nuisance=nuisance,
            initial_states=initial,
            campaign=campaign,
            metrics=_section(document, "metrics", name, {}),
            quality=_section(document, "quality", name, None),
            mcmc=_section(document, "mcmc", name, None),
            stages=_section(document, "stages", name, {}),
            warnings=tuple(str(w) for w in warnings),
            provenance=_section(document, "provenance", name, {}),
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write :attr:`document` back (atomically): the file as it was read."""
        return write_fit_json(path, self.document)


def _entry(entry: Any) -> Any:
    """A fit.json parameter entry as :meth:`Parameter.from_dict` reads it."""
    if not isinstance(entry, Mapping):
        return entry
    return {k: v for k, v in entry.items() if not k.startswith("laplace_")}


#: Said after a heat, valve or friction law or an effect the registries do not know.
_OWN_PART = (
    " (a part of one's own? register it first: import its module, or "
    "pneumafit --parts FILE.py COMMAND ...)"
)


def _structure(model: str, spec: Mapping[str, Any], where: str) -> ModelStructure | None:
    """The fitted structure of ``structure`` with the fallbacks (module docstring)."""
    heat = spec.get("heat")
    if heat is None and model not in MODELS:
        return None
    if heat is not None and heat not in MODELS:
        raise _problem(where, "structure.heat", f"one of {', '.join(MODELS)}",
                       f"{heat!r}{_OWN_PART}")  # fmt: skip
    base = fit_structure(model if heat is None else str(heat))
    checks = (
        ("valve", tuple(VALVE_LAWS), base.valve),
        ("friction", tuple(FRICTION_LAWS), base.friction),
        ("air_properties", ("constant", "sutherland"), base.air_properties),
        # fits written before the held inputs interpolated them
        ("inputs", INPUT_MODES, "linear"),
    )
    chosen: dict[str, str] = {}
    for key, allowed, default in checks:
        value = spec.get(key)
        if value is None:
            value = default
        if value not in allowed:
            # a valve or friction law may be one's own, registered by --parts
            own = _OWN_PART if key in ("valve", "friction") else ""
            raise _problem(where, f"structure.{key}", f"one of {', '.join(allowed)}",
                           f"{value!r}{own}")  # fmt: skip
        chosen[key] = value
    effects: dict[str, int] = {}
    for effect, option in (spec.get("effects") or {}).items():
        if effect not in EFFECT_SLOTS:
            raise _problem(where, f"structure.effects.{effect}",
                           f"one of {', '.join(EFFECT_SLOTS)}",
                           f"{effect!r}{_OWN_PART}")  # fmt: skip
        if isinstance(option, bool) or not isinstance(option, int) or option < 0:
            raise _problem(where, f"structure.effects.{effect}", "a non-negative integer",
                           repr(option))  # fmt: skip
        effects[str(effect)] = option
    name = spec.get("name")
    try:
        structure = ModelStructure(base.heat, effects=effects, **chosen)
        if effects:
            structure = structure.with_effects()
        if isinstance(name, str) and name:
            structure = replace(structure, name=name)
    except ValueError as exc:
        raise PneumafitInputError(f"{where}: structure: {exc}") from None
    return structure


#: Smallest ``interval_widening`` that the console and the report show: a
#: fit whose model is the rig's has factors of 1.00-1.03 (sampling noise of
#: the sandwich; the control case of tests/identification/
#: test_robust_covariance.py has a median of 1.01), which a reader should
#: not take for a warning.
WIDENING_SHOWN = 1.05


def widening_label(factor: Any) -> str:
    """How an interval's ``interval_widening`` is shown: "x3.5", or "-" below
    :data:`WIDENING_SHOWN`, when it was not widened, or when the value is not
    a number (a hand-edited fit.json: the report shows what it can)."""
    if (
        isinstance(factor, bool) or not isinstance(factor, (int, float))
        or not math.isfinite(factor) or factor < WIDENING_SHOWN
    ):  # fmt: skip
        return "-"
    return f"x{factor:.2g}" if factor < 10 else f"x{factor:.0f}"


def load_fit(path: str | os.PathLike[str]) -> SavedFit:
    """Read a fit.json (or the fit folder holding one): the one reader of the file.

    Parameters
    ----------
    path : str or path
        ``fit.json`` or a folder holding it.

    Returns
    -------
    SavedFit

    Raises
    ------
    PneumafitInputError
        No such file, unreadable, not JSON, or a bad document
        (:meth:`SavedFit.from_document`); the message names the file.
    """
    file = Path(path)
    if file.is_dir():
        file = file / FIT_FILE
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PneumafitInputError(
            f"{file}: expected a fit.json (written by pneumafit fit), found no such file"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PneumafitInputError(f"{file}: cannot be read: {exc}") from None
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PneumafitInputError(
            f"{file}: line {exc.lineno}: expected valid JSON, found an error: {exc.msg}"
        ) from None
    return SavedFit.from_document(document, file)
