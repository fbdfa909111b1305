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
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.parts import HEAT_LAWS
from pneumafit.physics.air import conductivity, viscosity
from pneumafit.physics.heat import convection_coefficient

__all__ = ["REFERENCE_STATE", "SLIDING_VELOCITY", "reference_lambda", "reference_sliding"]

#: Reference state: pressure (Pa), gas and wall temperatures (K).
REFERENCE_STATE = {"pressure": 5.0e5, "gas_temperature": 323.15, "wall_temperature": 293.15}

#: Sliding velocity (m/s) at which the sliding friction level is quoted
#: (:func:`reference_sliding`): past the Stribeck drop of pneumatic seals
#: (v_s 5-30 mm/s), below the speeds of a full stroke.
SLIDING_VELOCITY = 0.05


def reference_sliding(
    values: Mapping[str, float | NDArray[np.float64]], extra: float | NDArray[np.float64] = 0.0
) -> float | NDArray[np.float64]:
    """Steady sliding friction at :data:`SLIDING_VELOCITY` less its viscous part (N).

    F_c + (F_s - F_c) exp(-(v / v_s)^2) (the Stribeck curve of both friction
    laws, :func:`pneumafit.physics.friction.sliding_friction`) plus ``extra``
    (N, e.g. the seal friction at the quoted pressures), which adds to both
    levels. This is the level a friction test reads once the piston slides,
    and it compares laws whose Coulomb parameters mean different things (a
    truth without a Stribeck drop, or with another drop shape).

    Parameters
    ----------
    values : mapping
        ``friction_static``, ``friction_coulomb`` (N), ``stribeck_velocity``
        (m/s); arrays of draws allowed.
    extra : float or ndarray
        Added to both levels (N).
    """
    f_s = np.asarray(values["friction_static"], float) + extra
    f_c = np.asarray(values["friction_coulomb"], float) + extra
    r = SLIDING_VELOCITY / np.asarray(values["stribeck_velocity"], float)
    out = f_c + (f_s - f_c) * np.exp(-r * r)
    return float(out) if np.ndim(out) == 0 else out


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
        Heat law; the polytropic law has no coefficient (None); a law
        registered with its kernel code (``HeatLaw.kernel``) is evaluated
        by it, with the gas and wall temperatures of the state.
    air_properties : {"sutherland", "constant"}
        Viscosity and conductivity at the gas (Sutherland) or wall temperature.

    Returns
    -------
    float or ndarray or None
    """
    if heat == "constant-lambda":
        return values["lambda"]
    law = HEAT_LAWS.get(heat)
    if law is not None and law.kernel is not None:
        return _part_lambda(law.kernel, values)
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


def _part_lambda(
    law: Any, values: Mapping[str, float | NDArray[np.float64]]
) -> float | NDArray[np.float64]:
    """lambda at :data:`REFERENCE_STATE` from a heat law's own kernel code.

    Parameters given as arrays of draws are evaluated draw by draw; others
    keep their value (table defaults for the ones not given).
    """
    s = REFERENCE_STATE
    scalars = {n: float(v) for n, v in values.items() if n in P and np.ndim(v) == 0}
    arrays = {n: np.asarray(v, float).ravel() for n, v in values.items() if n in P and np.ndim(v)}
    vec = parameter_vector(scalars)
    state = (s["pressure"], s["gas_temperature"], s["wall_temperature"])
    if not arrays:
        return float(law(vec, *state))
    n = max(a.size for a in arrays.values())
    out = np.empty(n)
    for i in range(n):
        for name, a in arrays.items():
            vec[P[name]] = a[i if a.size == n else 0]
        out[i] = law(vec, *state)
    return out
