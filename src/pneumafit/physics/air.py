"""Air properties (perfect gas) and constants.

Units: SI throughout (Pa, K, kg, m, s, J).
"""

from __future__ import annotations

import math

from pneumafit.numba_stamp import njit

#: Specific gas constant of dry air, r (J/kg/K).
R_AIR = 287.058
#: Adiabatic index of air, gamma (-).
GAMMA = 1.4
#: Specific heat at constant volume, c_v = r / (gamma - 1) (J/kg/K).
CV = R_AIR / (GAMMA - 1.0)
#: Specific heat at constant pressure, c_p = gamma c_v (J/kg/K).
CP = GAMMA * CV
#: Standard gravity (m/s^2).
G0 = 9.80665
#: ISO 6358 reference density (kg/m^3) and temperature (K) of the sonic conductance.
RHO0 = 1.185
T_REF = 293.15

# Sutherland constants for air (White, Viscous Fluid Flow, Table 1-2/1-3).
_MU_REF, _MU_T, _MU_S = 1.716e-5, 273.15, 110.4
_K_REF, _K_T, _K_S = 0.02414, 273.15, 194.0


@njit(cache=True)
def viscosity(temperature: float) -> float:
    """Dynamic viscosity of air by Sutherland's law.

    Parameters
    ----------
    temperature : float
        Gas temperature T (K).

    Returns
    -------
    float
        mu (Pa s); 1.81e-5 Pa s at 293 K.
    """
    tr = temperature / _MU_T
    return _MU_REF * tr * math.sqrt(tr) * (_MU_T + _MU_S) / (temperature + _MU_S)


@njit(cache=True)
def conductivity(temperature: float) -> float:
    """Thermal conductivity of air by Sutherland's law.

    Parameters
    ----------
    temperature : float
        Gas temperature T (K).

    Returns
    -------
    float
        k_air (W/m/K); 0.0257 W/m/K at 293 K.
    """
    tr = temperature / _K_T
    return _K_REF * tr * math.sqrt(tr) * (_K_T + _K_S) / (temperature + _K_S)


@njit(cache=True)
def density(pressure: float, temperature: float) -> float:
    """Perfect-gas density rho = P / (r T) (kg/m^3)."""
    return pressure / (R_AIR * temperature)


def prandtl(temperature: float) -> float:
    """Prandtl number Pr = c_p mu / k_air (-), about 0.71 for air."""
    return CP * viscosity(temperature) / conductivity(temperature)
