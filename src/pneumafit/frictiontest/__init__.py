"""Friction tests (imposed motion, rod force): force balance, friction-law fit, discovery.

``pneumafit fit CAMPAIGN --model friction``, ``pneumafit discover`` on such a
fit, ``pneumafit run`` on such a campaign (``docs/measured-data.md``).
"""

from pneumafit.frictiontest.discover import FrictionDiscovery, discover_friction
from pneumafit.frictiontest.fit import (
    LAWS,
    FrictionStructure,
    FrictionTestProblem,
    identify_friction,
)
from pneumafit.frictiontest.model import (
    EFFECTS,
    FRICTION_EFFECTS,
    FrictionEffect,
    FrictionTest,
    default_parameters,
    estimate_velocity,
    friction_test_force,
    prepare,
)

__all__ = [
    "EFFECTS",
    "FRICTION_EFFECTS",
    "LAWS",
    "FrictionDiscovery",
    "FrictionEffect",
    "FrictionStructure",
    "FrictionTest",
    "FrictionTestProblem",
    "default_parameters",
    "discover_friction",
    "estimate_velocity",
    "friction_test_force",
    "identify_friction",
    "prepare",
]
