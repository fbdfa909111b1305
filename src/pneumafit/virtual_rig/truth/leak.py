"""External leaks of the truth: air escaping from a chamber to the atmosphere.

A worn rod seal, a loose push-in fitting or a porous port thread lets air out
of a chamber through a small, fixed opening. The truth models each chamber's
leak as an ISO 6358 restriction to the atmosphere (its own flow function,
:func:`pneumafit.virtual_rig.truth.valve.restriction_flow`): choked, so proportional
to the *absolute* chamber pressure, above the critical ratio, subsonic
below it, and linear in the pressure difference only very near P_atm. The
fitted models' catalog effect ``external_leakage`` is a laminar law instead,
q = G (P - P_atm): the same effect in a different structure, as a real leak
would be.

Air that leaves carries the chamber's temperature; air drawn in (a chamber
below the atmosphere) the ambient temperature. The leak is not seen by the
flow meter (it sits between the valve and the chamber) and not by the flow
tests (the valve's static characteristic at a held pressure).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from pneumafit.errors import PneumafitInputError
from pneumafit.virtual_rig.truth.valve import restriction_flow

__all__ = ["EXTERNAL_LEAKS", "NoExternalLeak", "OrificeLeak"]


@dataclass(frozen=True, kw_only=True)
class NoExternalLeak:
    """Tight chambers (no external leak)."""

    name: ClassVar[str] = "none"

    def flow(self, chamber: str, pressure: float, temperature: float, p_atm: float,
             t_atm: float) -> tuple[float, float]:  # fmt: skip
        """(mass flow out of the chamber (kg/s), temperature it carries (K)): none."""
        return 0.0, temperature


@dataclass(frozen=True, kw_only=True)
class OrificeLeak:
    """One small orifice from each chamber to the atmosphere (ISO 6358 law).

    Parameters
    ----------
    C_P, C_N : float
        Sonic conductance of the leak of chamber P and of chamber N
        (m^3/s/Pa), >= 0. Choked, the leak is C P (ANR volume flow): 1 l/min
        (ANR) out of a chamber at 7 bar absolute is C = 1.667e-5 / 7e5 =
        2.4e-11 m^3/s/Pa. A sharp orifice of diameter d and discharge
        coefficient C_d has C = C_d (pi d^2 / 4) sqrt(gamma / (r T)) (2 /
        (gamma + 1))^3 / rho0 = 1.6e-9 C_d (d / 1 mm)^2 m^3/s/Pa at 20 degC,
        so that leak is a hole of about 0.14 mm (C_d 0.8).
    b : float
        Critical pressure ratio (-), in [0, 1): 0.5 to 0.53 for a sharp
        orifice.
    m : float
        Subsonic index (-), in [0.2, 1].
    """

    name: ClassVar[str] = "orifice"
    C_P: float
    C_N: float
    b: float = 0.5
    m: float = 0.5

    def __post_init__(self) -> None:
        for key in ("C_P", "C_N"):
            value = getattr(self, key)
            if not (math.isfinite(value) and 0.0 <= value < 1e-8):
                raise PneumafitInputError(
                    f"external leak 'orifice': {key}: expected a conductance in [0, 1e-8) "
                    f"m^3/s/Pa (1e-8 is a fully open valve, not a leak), found {value!r}"
                )
        if not (math.isfinite(self.b) and 0.0 <= self.b < 1.0):
            raise PneumafitInputError(f"external leak 'orifice': b: expected a ratio in [0, 1), "
                             f"found {self.b!r}")  # fmt: skip
        if not (math.isfinite(self.m) and 0.2 <= self.m <= 1.0):
            raise PneumafitInputError(f"external leak 'orifice': m: expected an index in [0.2, 1], "
                             f"found {self.m!r}")  # fmt: skip

    def flow(self, chamber: str, pressure: float, temperature: float, p_atm: float,
             t_atm: float) -> tuple[float, float]:  # fmt: skip
        """Leak of one chamber.

        Parameters
        ----------
        chamber : {"P", "N"}
        pressure, temperature : float
            Chamber pressure (Pa, absolute) and gas temperature (K).
        p_atm, t_atm : float
            Atmospheric pressure (Pa) and temperature (K).

        Returns
        -------
        q : float
            Mass flow out of the chamber (kg/s), negative when air is drawn in.
        t : float
            Temperature the flow carries (K): the upstream side's.
        """
        c = self.C_P if chamber == "P" else self.C_N
        if c == 0.0:
            return 0.0, temperature
        # laminar onset as the valve's default: linear only within 0.1 % of P_atm
        return restriction_flow(c, self.b, self.m, 0.999, pressure, temperature, p_atm, t_atm)


#: External-leak models by name.
EXTERNAL_LEAKS: dict[str, type[Any]] = {cls.name: cls for cls in (NoExternalLeak, OrificeLeak)}
