"""Friction tests (imposed motion, rod force): force balance and friction-law fit.

``pneumafit fit CAMPAIGN --model friction`` (``docs/measured-data.md``).
"""

from pneumafit.frictiontest.fit import (
    LAWS,
    FrictionStructure,
    FrictionTestProblem,
    identify_friction,
)
from pneumafit.frictiontest.model import (
    EFFECTS,
    FrictionTest,
    default_parameters,
    estimate_velocity,
    friction_test_force,
    prepare,
)

__all__ = [
    "EFFECTS",
    "LAWS",
    "FrictionStructure",
    "FrictionTest",
    "FrictionTestProblem",
    "default_parameters",
    "estimate_velocity",
    "friction_test_force",
    "identify_friction",
    "prepare",
]
