"""Gas-to-wall heat-transfer laws (paper eqs. 6-8).

Wall heat flow into the gas: Q = lambda A (T_w - T) (W).

- polytropic: no wall exchange; the chamber balance is replaced by the
  polytropic law of index k (paper eq. 14);
- constant lambda: lambda fixed (W/m^2/K);
- full convection (paper eq. 8), Nusselt law with Pr folded into xi:

      lambda = xi (k_air / D) Gr^beta,
      Gr = g D^3 |T_w - T| P^2 / (r^2 mu^2 T^3)

  The absolute value makes the law valid for heating and cooling; at
  T = T_w, lambda = 0 and Q is C^1 in T.
"""

from __future__ import annotations

import math

from pneumafit.numba_stamp import njit
from pneumafit.physics.air import G0, R_AIR
from pneumafit.physics.friction import FASTMATH

HEAT_POLYTROPIC = 0
HEAT_CONSTANT = 1
HEAT_CONVECTION = 2


@njit(cache=True, fastmath=FASTMATH)
def grashof(
    pressure: float, temperature: float, wall_temperature: float, length: float, mu: float
) -> float:
    """Grashof number of the chamber gas (paper eq. 8).

    Parameters
    ----------
    pressure : float
        P (Pa).
    temperature, wall_temperature : float
        Gas and wall temperatures (K).
    length : float
        Characteristic length D (m).
    mu : float
        Dynamic viscosity (Pa s).

    Returns
    -------
    float
        Gr (-) >= 0.
    """
    return (
        G0
        * length**3
        * abs(wall_temperature - temperature)
        * pressure**2
        / (R_AIR**2 * mu**2 * temperature**3)
    )


@njit(cache=True, fastmath=FASTMATH)
def convection_coefficient(
    xi: float,
    beta: float,
    pressure: float,
    temperature: float,
    wall_temperature: float,
    length: float,
    mu: float,
    k_air: float,
) -> float:
    """Free-convection heat-transfer coefficient lambda = xi (k/D) Gr^beta (W/m^2/K)."""
    gr = grashof(pressure, temperature, wall_temperature, length, mu)
    if gr <= 0.0:
        return 0.0
    return xi * k_air / length * math.exp(beta * math.log(gr))


@njit(cache=True, fastmath=FASTMATH)
def wall_heat_flow(coefficient: float, area: float, temperature: float, wall_temperature: float):
    """Heat flow from wall to gas, Q = lambda A (T_w - T) (W) (paper eqs. 6-7)."""
    return coefficient * area * (wall_temperature - temperature)


@njit(cache=True, fastmath=FASTMATH)
def convection_coefficient_scaled(
    lambda_scale: float,
    grashof_scale: float,
    beta: float,
    pressure: float,
    temperature: float,
    wall_temperature: float,
) -> float:
    """Eq. 8 with its constant factors precomputed (for the compiled kernel).

    lambda = lambda_scale * (grashof_scale |T_w - T| P^2 / T^3)^beta with
    lambda_scale = xi k_air / D (W/m^2/K) and grashof_scale = g D^3 / (r mu)^2
    (1/(Pa^2 K^2)); equal to :func:`convection_coefficient` with air
    properties held constant.
    """
    gr = (
        grashof_scale
        * abs(wall_temperature - temperature)
        * pressure
        * pressure
        / (temperature * temperature * temperature)
    )
    if gr <= 0.0:
        return 0.0
    return lambda_scale * math.exp(beta * math.log(gr))
