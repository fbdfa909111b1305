"""Model comparison: the three heat-transfer models on one campaign.

``pneumafit compare`` (:func:`pneumafit.cli.compare.compare_command`) fits
(or reuses) the convection, constant-lambda and polytropic models, replays
every recording with each (:func:`evaluate_fit`), scores them per role and
channel (RMSE, normalised fit, largest error), by information criteria (AIC,
BIC from the fits; WAIC and PSIS-LOO from the posterior draws,
:func:`posterior_criteria`), and writes ``comparison.json``
(:func:`comparison_document`) and one figure per recording
(:func:`plot_recording`). docs/comparison.md describes the schema.
"""

from pneumafit.comparison.evaluate import (
    ChannelError,
    ModelEvaluation,
    RecordingTrace,
    channel_error,
    evaluate_fit,
    fit_values,
)
from pneumafit.comparison.figures import plot_recording
from pneumafit.comparison.information import pointwise_log_likelihood, posterior_criteria
from pneumafit.comparison.report import (
    COMPARISON_FORMAT,
    COMPARISON_VERSION,
    comparison_document,
    print_table,
)

__all__ = [
    "COMPARISON_FORMAT",
    "COMPARISON_VERSION",
    "ChannelError",
    "ModelEvaluation",
    "RecordingTrace",
    "channel_error",
    "comparison_document",
    "evaluate_fit",
    "fit_values",
    "plot_recording",
    "pointwise_log_likelihood",
    "posterior_criteria",
    "print_table",
]
