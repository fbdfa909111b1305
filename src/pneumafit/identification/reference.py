"""Quantities that can be compared across heat laws: lambda at a reference state.

xi and beta of the Nusselt law are correlated at -0.999 over the narrow
Grashof range of a campaign, and the constant-lambda and polytropic models
have neither; what a fit determines, and what can be compared with a truth
or between models, is the heat-transfer coefficient over the states the
campaign visits. :func:`reference_lambda` evaluates it at one such state,
:data:`REFERENCE_STATE` (5 bar, gas at 50 degC, wall at 20 degC: a charged
chamber just after filling), with the fitted air properties.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from pneumafit.physics.air import conductivity, viscosity
from pneumafit.physics.heat import convection_coefficient

__all__ = ["REFERENCE_STATE", "reference_lambda"]

#: Reference state: pressure (Pa), gas and wall temperatures (K).
REFERENCE_STATE = {"pressure": 5.0e5, "gas_temperature": 323.15, "wall_temperature": 293.15}


def reference_lambda(
    values: Mapping[str, float | NDArray[np.float64]],
    heat: str = "convection",
    air_properties: str = "sutherland",
) -> NDArray[np.float64] | float | None:
    """Heat-transfer coefficient (W/m^2/K) at :data:`REFERENCE_STATE`.

    Parameters
    ----------
    values : mapping
        ``xi``, ``beta``, ``characteristic_length`` (m) for the convection law
        (arrays of draws allowed), ``lambda`` for the constant-lambda law.
    heat : str
        Heat law; the polytropic law has no coefficient (None).
    air_properties : {"sutherland", "constant"}
        Viscosity and conductivity at the gas (Sutherland) or wall temperature.

    Returns
    -------
    float or ndarray or None
    """
    if heat == "constant-lambda":
        return values["lambda"]
    if heat != "convection":
        return None
    s = REFERENCE_STATE
    t_air = s["gas_temperature"] if air_properties == "sutherland" else s["wall_temperature"]
    mu, k_air = viscosity(t_air), conductivity(t_air)
    xi = np.atleast_1d(np.asarray(values["xi"], float))
    beta = np.atleast_1d(np.asarray(values["beta"], float))
    length = float(values.get("characteristic_length", values.get("bore", 0.032)))
    out = np.array(
        [
            convection_coefficient(
                x, b, s["pressure"], s["gas_temperature"], s["wall_temperature"], length, mu,
                k_air,
            )
            for x, b in np.broadcast(xi, beta)
        ]
    )  # fmt: skip
    return float(out[0]) if out.size == 1 and np.ndim(values["xi"]) == 0 else out
