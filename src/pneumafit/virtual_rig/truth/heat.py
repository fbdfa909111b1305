"""Heat-transfer part of the truth: Nusselt free convection with an area convention.

lambda = xi (k_air / D) Gr^beta,  Gr = g D^3 |T_w - T| P^2 / (r^2 mu^2 T^3)

(physics notes, paper eq. 8 with Pr folded into xi), air properties mu,
k_air by Sutherland's law at the gas temperature (``air = "sutherland"``) or
at the wall temperature (``air = "constant"``). Wall heat flow into the gas
Q = lambda A (T_w - T) (W) with the exchange area A(y) of a convention:

- ``full``: head and piston face (2 S) plus the barrel wall over the chamber
  length, the dead volume counted as extra length l_0 = V_0 / S, and on the
  rod side the rod surface: A_P = 2 S_P + pi D (l_0P + y),
  A_N = 2 S_N + pi (D + d) (l_0N + L - y) (the fitted models' convention);
- ``barrel_only``: only the lateral barrel wall, A_P = pi D (l_0P + y),
  A_N = pi D (l_0N + L - y).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from pneumafit.errors import PneumafitInputError
from pneumafit.virtual_rig.truth.constants import GRAVITY, R_GAS, air_conductivity, air_viscosity

__all__ = ["AREA_CONVENTIONS", "HEAT_MODELS", "NusseltConvection", "exchange_area"]

AREA_CONVENTIONS = ("full", "barrel_only")


def exchange_area(
    convention: str, chamber: str, y: float, bore: float, rod: float, stroke: float,
    dead_volume: float,
) -> float:  # fmt: skip
    """Gas-to-wall exchange area (m^2) of chamber ``chamber`` at position y (m).

    See the module docstring for the conventions; lengths in m, volume in m^3.
    """
    if chamber == "P":
        s = 0.25 * math.pi * bore * bore
        length = dead_volume / s + y
        lateral = math.pi * bore * length
        extra = 2.0 * s
    else:
        s = 0.25 * math.pi * (bore * bore - rod * rod)
        length = dead_volume / s + (stroke - y)
        lateral = math.pi * bore * length
        extra = 2.0 * s + math.pi * rod * length
    return lateral + extra if convention == "full" else lateral


@dataclass(frozen=True, kw_only=True)
class NusseltConvection:
    """Free-convection heat transfer (see the module docstring).

    Parameters
    ----------
    xi : float
        Nusselt coefficient (-), >= 0 (0: adiabatic chambers).
    beta : float
        Grashof exponent (-), in [0.05, 0.6].
    area : {"full", "barrel_only"}
        Exchange-area convention.
    air : {"sutherland", "constant"}
        Air properties at the gas temperature, or constant at the wall's.
    wall_temperature : float or None
        Wall temperature T_w (K); None takes the parameter set's
        ``wall_temperature``.
    length : float or None
        Characteristic length D of the Nusselt and Grashof numbers (m); None
        takes the parameter set's ``characteristic_length``.
    """

    name: ClassVar[str] = "nusselt"
    xi: float
    beta: float
    area: str = "full"
    air: str = "sutherland"
    wall_temperature: float | None = None
    length: float | None = None

    def __post_init__(self) -> None:
        w = "heat 'nusselt'"
        if not (math.isfinite(self.xi) and self.xi >= 0.0):
            raise PneumafitInputError(f"{w}: xi: expected a value >= 0, found {self.xi!r}")
        if not 0.05 <= self.beta <= 0.6:
            raise PneumafitInputError(
                f"{w}: beta: expected an exponent in [0.05, 0.6], found {self.beta!r}"
            )
        if self.area not in AREA_CONVENTIONS:
            raise PneumafitInputError(
                f"{w}: area: expected one of {AREA_CONVENTIONS}, found {self.area!r}"
            )
        if self.air not in ("sutherland", "constant"):
            raise PneumafitInputError(
                f"{w}: air: expected 'sutherland' or 'constant', found {self.air!r}"
            )
        if self.wall_temperature is not None and not 150.0 <= self.wall_temperature <= 600.0:
            raise PneumafitInputError(
                f"{w}: wall_temperature: expected a temperature in [150, 600] K, found "
                f"{self.wall_temperature!r}"
            )
        if self.length is not None and not self.length > 0.0:
            raise PneumafitInputError(
                f"{w}: length: expected a length > 0 m, found {self.length!r}"
            )

    def coefficient(self, pressure: float, temperature: float, wall: float, length: float) -> float:
        """lambda (W/m^2/K) at P (Pa), gas T (K), wall T_w (K), length D (m)."""
        if self.xi == 0.0 or temperature == wall:
            return 0.0
        t_air = temperature if self.air == "sutherland" else wall
        mu = air_viscosity(t_air)
        k_air = air_conductivity(t_air)
        gr = (
            GRAVITY * length**3 * abs(wall - temperature) * pressure**2
            / (R_GAS**2 * mu**2 * temperature**3)
        )  # fmt: skip
        return self.xi * k_air / length * gr**self.beta


#: Heat-transfer models by name.
HEAT_MODELS: dict[str, type[Any]] = {NusseltConvection.name: NusseltConvection}
