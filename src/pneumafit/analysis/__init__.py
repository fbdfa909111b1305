"""Analysis layer: the paper's equilibrium set, linearization and design."""

from pneumafit.analysis.linear import (
    ITAE_POLES,
    ITAE_POLYNOMIALS,
    Equilibrium,
    LinearModel,
    closed_loop_poles,
    equilibrium,
    gain_schedule,
    itae_poles,
    linearize,
    numerical_jacobian,
    place,
)

__all__ = [
    "ITAE_POLES",
    "ITAE_POLYNOMIALS",
    "Equilibrium",
    "LinearModel",
    "closed_loop_poles",
    "equilibrium",
    "gain_schedule",
    "itae_poles",
    "linearize",
    "numerical_jacobian",
    "place",
]
