"""Identification: parameters, problems, likelihoods, estimators, staged fits.

Layers (docs/identification.md):

- :class:`ParameterSet` / :class:`Parameter`: names, units, bounds, priors,
  scales, fixed or free, posterior summaries; JSON round trip.
- :class:`Problem`: recordings + model structure + compared channels +
  noise models (:class:`Gaussian`, :class:`StudentT`, :class:`AR1`,
  :class:`Quantized`) + sensor lags, initial states and sensor offsets.
- :class:`LogLikelihood`, :class:`LogPosterior`: batched over parameter
  sets, -inf on failed simulations.
- :func:`fit_least_squares` (multi-start, Laplace covariance),
  :func:`run_mcmc` (emcee, seeded, HDF5, resumable, diagnosed).
- :func:`identify`: the staged fit (valve, heat, friction, joint, MCMC);
  :meth:`FitResult.save` / :meth:`FitResult.load` (:class:`SavedFit`): fit.json,
  the only code that writes or reads it (:func:`fit_document`,
  :func:`write_fit_json`, :func:`load_fit`). The body of ``pneumafit fit``
  is :func:`pneumafit.cli.fit.fit_command`.
"""

from pneumafit.identification.fitfile import (
    FIT_FORMAT,
    FIT_VERSION,
    SavedFit,
    fit_document,
    load_fit,
    write_fit_json,
)
from pneumafit.identification.likelihood import Evaluation, LogLikelihood, LogPosterior
from pneumafit.identification.noise import (
    AR1,
    Gaussian,
    NoiseModel,
    Quantized,
    StudentT,
    detect_resolution,
    noise_model,
)
from pneumafit.identification.optimise import PointEstimate, fit_least_squares
from pneumafit.identification.parameters import (
    NUISANCE_SPECS,
    LogNormal,
    LogUniform,
    Normal,
    Parameter,
    ParameterSet,
    Prior,
    Uniform,
)
from pneumafit.identification.problem import (
    COMPARABLE_CHANNELS,
    DEFAULT_NOISE,
    Observation,
    Prediction,
    Problem,
    first_order_lag,
)
from pneumafit.identification.sampling import MCMCResult, default_moves, run_mcmc
from pneumafit.identification.staged import (
    DEFAULT_CHANNELS,
    FRICTION_PARAMETERS,
    VALVE_PARAMETERS,
    FitOptions,
    FitResult,
    StageResult,
    fit_structure,
    identify,
)

__all__ = [
    "AR1",
    "COMPARABLE_CHANNELS",
    "DEFAULT_CHANNELS",
    "DEFAULT_NOISE",
    "FIT_FORMAT",
    "FIT_VERSION",
    "FRICTION_PARAMETERS",
    "NUISANCE_SPECS",
    "VALVE_PARAMETERS",
    "Evaluation",
    "FitOptions",
    "FitResult",
    "Gaussian",
    "LogLikelihood",
    "LogNormal",
    "LogPosterior",
    "LogUniform",
    "MCMCResult",
    "NoiseModel",
    "Normal",
    "Observation",
    "Parameter",
    "ParameterSet",
    "PointEstimate",
    "Prediction",
    "Prior",
    "Problem",
    "Quantized",
    "SavedFit",
    "StageResult",
    "StudentT",
    "Uniform",
    "default_moves",
    "detect_resolution",
    "first_order_lag",
    "fit_document",
    "fit_least_squares",
    "fit_structure",
    "identify",
    "load_fit",
    "noise_model",
    "run_mcmc",
    "write_fit_json",
]
