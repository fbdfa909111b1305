"""Constants and air properties of the truth simulator (its own, SI units).

Written independently of :mod:`pneumafit.physics`, on purpose: the truth must
not share code with the models it is used to test.
"""

from __future__ import annotations

__all__ = [
    "CP",
    "CV",
    "GAMMA",
    "GRAVITY",
    "RHO_REF",
    "R_GAS",
    "T_REF",
    "air_conductivity",
    "air_viscosity",
]

#: Specific gas constant of dry air, r (J/kg/K).
R_GAS = 287.058
#: Ratio of specific heats of air, gamma (-).
GAMMA = 1.4
#: Specific heat at constant volume, c_v = r / (gamma - 1) (J/kg/K).
CV = R_GAS / (GAMMA - 1.0)
#: Specific heat at constant pressure, c_p = gamma c_v (J/kg/K).
CP = GAMMA * CV
#: ISO 6358 reference density (kg/m^3) and temperature (K) of the sonic conductance.
RHO_REF = 1.185
T_REF = 293.15
#: Standard gravity (m/s^2).
GRAVITY = 9.80665

# Sutherland's law, mu = mu0 (T / T0)^1.5 (T0 + S) / (T + S): reference values
# for air (F. M. White, Viscous Fluid Flow, 3rd ed., tables 1-2 and 1-3).
_MU0, _T_MU, _S_MU = 1.716e-5, 273.15, 110.4
_K0, _T_K, _S_K = 0.02414, 273.15, 194.0


def air_viscosity(temperature: float) -> float:
    """Dynamic viscosity of air mu (Pa s) at ``temperature`` (K), Sutherland's law."""
    return _MU0 * (temperature / _T_MU) ** 1.5 * (_T_MU + _S_MU) / (temperature + _S_MU)


def air_conductivity(temperature: float) -> float:
    """Thermal conductivity of air k (W/m/K) at ``temperature`` (K), Sutherland's law."""
    return _K0 * (temperature / _T_K) ** 1.5 * (_T_K + _S_K) / (temperature + _S_K)
