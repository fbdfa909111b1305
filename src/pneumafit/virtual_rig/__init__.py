"""Virtual rig: simulated campaigns from a known truth (docs/virtual-rig.md).

:class:`VirtualRig` simulates a richer model than the fitted structures, at a
finer step, through a sensor model, following a :class:`Protocol`, and writes
a campaign folder plus a ``truth.json`` that campaign.toml never mentions.
``pneumafit rig`` is :func:`pneumafit.cli.rig.run_rig`.
:mod:`pneumafit.virtual_rig.truth` holds an independently written truth
simulator with configurable parts (``VirtualRig(truth=...)``, ``pneumafit rig
--truth``).
"""

from pneumafit.virtual_rig.effects import (
    EFFECT_DEFAULTS,
    PRINCIPAL_PARAMETERS,
    ResolvedEffects,
    parse_effect_options,
    resolve_effects,
)
from pneumafit.virtual_rig.protocol import (
    PROTOCOLS,
    BlockedTest,
    FlowTest,
    Protocol,
    StepTest,
    demo_protocol,
    get_protocol,
    quick_protocol,
    sparse_protocol,
    tutorial_protocol,
)
from pneumafit.virtual_rig.sensors import SensorModel, held_input_lag
from pneumafit.virtual_rig.virtual import (
    DEMO_CLEAN_TRUTH_PRESET,
    DEMO_SEED,
    DEMO_TRUTH,
    DEMO_TRUTH_PRESET,
    RIG_VERSION,
    TRUTH_FILE,
    TRUTH_FORMAT,
    TRUTH_METHOD,
    TRUTH_STEP,
    TRUTH_VERSION,
    RigError,
    RigRun,
    TruthTrace,
    VirtualRig,
    check_output_folder,
    truth_readme,
)

__all__ = [
    "DEMO_CLEAN_TRUTH_PRESET",
    "DEMO_SEED",
    "DEMO_TRUTH",
    "DEMO_TRUTH_PRESET",
    "EFFECT_DEFAULTS",
    "PRINCIPAL_PARAMETERS",
    "PROTOCOLS",
    "RIG_VERSION",
    "TRUTH_FILE",
    "TRUTH_FORMAT",
    "TRUTH_METHOD",
    "TRUTH_STEP",
    "TRUTH_VERSION",
    "BlockedTest",
    "FlowTest",
    "Protocol",
    "ResolvedEffects",
    "RigError",
    "RigRun",
    "SensorModel",
    "StepTest",
    "TruthTrace",
    "VirtualRig",
    "check_output_folder",
    "demo_protocol",
    "get_protocol",
    "held_input_lag",
    "parse_effect_options",
    "quick_protocol",
    "resolve_effects",
    "sparse_protocol",
    "truth_readme",
    "tutorial_protocol",
]
