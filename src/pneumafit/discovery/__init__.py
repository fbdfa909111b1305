"""Model discovery: the catalog of optional effects and residual analysis.

- :mod:`.catalog`: :class:`Effect` definitions (law, parameters with units,
  bounds and priors, structure option, regression signature) and the
  registry :data:`EFFECTS` (docs/effects.md).
- :mod:`.residuals`: :func:`residual_analysis` of a recording against a
  simulation (autocorrelation, Ljung-Box, cross-correlation with the inputs
  as MATLAB's ``resid``, RMS per phase), :func:`summarize`,
  :func:`plot_residuals`.
- :mod:`.phases`: the phases of a test (filling, emptying, relaxation,
  motion, rest).
- :mod:`.correlation`: the statistics themselves.
- :mod:`.attribution`: which effect the residual asks for (residual rates
  regressed on the effects' signatures, sparse and bootstrapped).
- :mod:`.refit`: the refit loop (:func:`discover`), kept effects must
  improve both BIC and the held-out error.
- ``pneumafit discover`` (discovery.json and the report) is
  :mod:`pneumafit.cli.discover`.
"""

from pneumafit.discovery.attribution import (
    Attribution,
    Candidate,
    Rows,
    attribute,
    build_rows,
    signature_features,
)
from pneumafit.discovery.catalog import (
    EFFECTS,
    PRIOR_KINDS,
    Effect,
    EffectParameter,
    EffectPrior,
    SignatureTerm,
    effects_for_phase,
    get_effect,
    register_effect,
)
from pneumafit.discovery.correlation import (
    LjungBox,
    autocorrelation,
    cross_correlation,
    cross_correlation_band,
    ljung_box,
    whiteness_band,
)
from pneumafit.discovery.phases import PHASES, PhaseRules, label_phases
from pneumafit.discovery.refit import BaseFit, Discovery, discover, refit
from pneumafit.discovery.residuals import (
    DEFAULT_MAX_LAG,
    OUTPUT_CHANNELS,
    ChannelResiduals,
    Correlation,
    PhaseStats,
    ResidualReport,
    SummaryRow,
    format_summary,
    plot_residuals,
    residual_analysis,
    summarize,
)

__all__ = [
    "DEFAULT_MAX_LAG",
    "EFFECTS",
    "OUTPUT_CHANNELS",
    "PHASES",
    "PRIOR_KINDS",
    "Attribution",
    "BaseFit",
    "Candidate",
    "ChannelResiduals",
    "Correlation",
    "Discovery",
    "Effect",
    "EffectParameter",
    "EffectPrior",
    "LjungBox",
    "PhaseRules",
    "PhaseStats",
    "ResidualReport",
    "Rows",
    "SignatureTerm",
    "SummaryRow",
    "attribute",
    "autocorrelation",
    "build_rows",
    "cross_correlation",
    "cross_correlation_band",
    "discover",
    "effects_for_phase",
    "format_summary",
    "get_effect",
    "label_phases",
    "ljung_box",
    "plot_residuals",
    "refit",
    "register_effect",
    "residual_analysis",
    "signature_features",
    "summarize",
    "whiteness_band",
]
