"""An independently written truth for the virtual rig (docs/virtual-rig.md, "Mismatched truths").

The fitted models and the default virtual rig share one compiled kernel and
one set of laws, so fitting the rig's campaigns is an "inverse crime". This
subpackage simulates the truth with its own code and with parts that differ
in structure from the fitted ones, chosen by configuration:

- valve conductance families (:data:`CONDUCTANCE_FAMILIES`: ``iso_linear``,
  ``power``, ``table``), per path, with an ISO 6358 flow function having a
  laminar region, and centre-leak shapes (:data:`LEAK_SHAPES`: ``bump``,
  ``constant``, ``none``, ``sigmoid``);
- friction (:data:`FRICTION_MODELS`: ``lugre``, ``dahl``), optionally growing
  with the chamber pressures, and end stops;
- heat transfer (:data:`HEAT_MODELS`: ``nusselt``) with an exchange-area
  convention (``full`` or ``barrel_only``) and its own wall temperature;
- temperature probes with their own lags and offset (:data:`PROBE_MODELS`);
- optionally, external leaks from the chambers to the atmosphere
  (:data:`EXTERNAL_LEAKS`: ``orifice``, ``none``), an effect the fitted
  models do not declare.

Nothing here imports :mod:`pneumafit.models` kernels, :mod:`pneumafit.physics`
or the fitting simulator.
"""

from pneumafit.virtual_rig.truth.config import (
    PRESETS,
    REFERENCE_STATE,
    TRUTH_FORMAT,
    TruthConfig,
    get_truth,
    reference_quantities,
)
from pneumafit.virtual_rig.truth.friction import (
    FRICTION_MODELS,
    DahlFriction,
    EndStops,
    LuGreFriction,
)
from pneumafit.virtual_rig.truth.heat import AREA_CONVENTIONS, HEAT_MODELS, NusseltConvection
from pneumafit.virtual_rig.truth.leak import EXTERNAL_LEAKS, NoExternalLeak, OrificeLeak
from pneumafit.virtual_rig.truth.probe import PROBE_MODELS, LaggedProbe
from pneumafit.virtual_rig.truth.simulator import CHANNELS, TruthSimulation, TruthSimulator
from pneumafit.virtual_rig.truth.valve import (
    CONDUCTANCE_FAMILIES,
    LEAK_SHAPES,
    BumpLeak,
    ConstantLeak,
    IsoLinearConductance,
    NoLeak,
    PowerConductance,
    ServoValve,
    SigmoidLeak,
    TableConductance,
    flow_function,
    restriction_flow,
)

__all__ = [
    "AREA_CONVENTIONS",
    "CHANNELS",
    "CONDUCTANCE_FAMILIES",
    "EXTERNAL_LEAKS",
    "FRICTION_MODELS",
    "HEAT_MODELS",
    "LEAK_SHAPES",
    "PRESETS",
    "PROBE_MODELS",
    "REFERENCE_STATE",
    "TRUTH_FORMAT",
    "BumpLeak",
    "ConstantLeak",
    "DahlFriction",
    "EndStops",
    "IsoLinearConductance",
    "LaggedProbe",
    "LuGreFriction",
    "NoExternalLeak",
    "NoLeak",
    "NusseltConvection",
    "OrificeLeak",
    "PowerConductance",
    "ServoValve",
    "SigmoidLeak",
    "TableConductance",
    "TruthConfig",
    "TruthSimulation",
    "TruthSimulator",
    "flow_function",
    "get_truth",
    "reference_quantities",
    "restriction_flow",
]
