"""Friction and end-stop parts of the truth: LuGre and Dahl bristle models.

Both are smooth ODEs in a bristle state z (m): the piston is held by the
bristle stiffness below breakaway, without any stick/slip switch (the fitted
models use a Karnopp-like switch, :mod:`pneumafit.physics.friction`).

Seal friction may grow with the chamber pressures, through
Delta = max(P_P + P_N - 2 P_atm, 0) (Pa):

- ``seal = "multiplicative"``: F_c and F_s scaled by (1 + k_p Delta);
- ``seal = "additive"``: c_p Delta added to F_c and F_s;
- ``seal = "none"``: constant levels.

The levels may also differ with the direction of sliding (a lip seal is not
symmetric): ``asymmetry`` a scales every level by (1 + a) while the piston
extends (v > 0) and by (1 - a) while it retracts (v < 0); at v = 0 (the
bristle law's pre-sliding) the level is the symmetric one.

Forces in N, velocities in m/s, pressures in Pa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from pneumafit.errors import PneumafitInputError

__all__ = ["FRICTION_MODELS", "DahlFriction", "EndStops", "LuGreFriction"]

_SEAL_MODES = ("none", "multiplicative", "additive")


def _need(where: str, ok: bool, what: str, found: object) -> None:
    if not ok:
        raise PneumafitInputError(f"{where}: expected {what}, found {found!r}")


@dataclass(frozen=True, kw_only=True)
class _Seal:
    """Pressure dependence of the friction levels (see the module docstring).

    Parameters
    ----------
    seal : {"none", "multiplicative", "additive"}
    k_p : float
        Relative growth of the levels per Pa of Delta (1/Pa), multiplicative mode.
    c_p : float
        Growth of the levels per Pa of Delta (N/Pa), additive mode.
    asymmetry : float
        Direction asymmetry a (-), |a| < 1: levels times 1 + a extending,
        1 - a retracting.
    """

    name: ClassVar[str] = ""
    seal: str = "none"
    k_p: float = 0.0
    c_p: float = 0.0
    asymmetry: float = 0.0

    def _check_seal(self) -> None:
        w = f"friction {self.name!r}"
        _need(f"{w}: seal", self.seal in _SEAL_MODES, f"one of {_SEAL_MODES}", self.seal)
        _need(f"{w}: k_p", self.k_p >= 0.0, "a growth >= 0 1/Pa", self.k_p)
        _need(f"{w}: c_p", self.c_p >= 0.0, "a growth >= 0 N/Pa", self.c_p)
        _need(f"{w}: asymmetry", -1.0 < self.asymmetry < 1.0, "a value in (-1, 1)",
              self.asymmetry)  # fmt: skip

    def direction(self, v: float) -> float:
        """Factor (-) of the levels for sliding at velocity v (m/s): 1 + a, 1 - a or 1."""
        if v > 0.0:
            return 1.0 + self.asymmetry
        if v < 0.0:
            return 1.0 - self.asymmetry
        return 1.0

    def level(self, force: float, delta: float) -> float:
        """A friction level (N) at pressure excess ``delta`` (Pa)."""
        d = delta if delta > 0.0 else 0.0
        if self.seal == "multiplicative":
            return force * (1.0 + self.k_p * d)
        if self.seal == "additive":
            return force + self.c_p * d
        return force


@dataclass(frozen=True, kw_only=True)
class LuGreFriction(_Seal):
    """LuGre friction (Canudas de Wit et al., 1995) with a Stribeck curve.

    g(v) = F_c + (F_s - F_c) exp(-|v / v_s|^delta_s)
    dz/dt = v - sigma0 |v| z / g(v)
    F = sigma0 z + sigma1 dz/dt + sigma2 v

    Parameters
    ----------
    sigma0 : float
        Bristle stiffness (N/m).
    sigma1 : float
        Bristle damping (N s/m).
    sigma2 : float
        Viscous coefficient (N s/m).
    F_c, F_s : float
        Coulomb and static friction levels (N), F_s >= F_c > 0.
    v_s : float
        Stribeck velocity (m/s).
    stribeck_exponent : float
        delta_s (-), 2 for the Gaussian Stribeck curve.
    seal, k_p, c_p
        Pressure dependence, see :class:`_Seal`.
    """

    name: ClassVar[str] = "lugre"
    sigma0: float
    sigma1: float
    sigma2: float
    F_c: float
    F_s: float
    v_s: float
    stribeck_exponent: float = 2.0

    def __post_init__(self) -> None:
        self._check_seal()
        w = "friction 'lugre'"
        for key in ("sigma0", "F_c", "v_s", "stribeck_exponent"):
            _need(f"{w}: {key}", getattr(self, key) > 0.0, "a value > 0", getattr(self, key))
        for key in ("sigma1", "sigma2"):
            _need(f"{w}: {key}", getattr(self, key) >= 0.0, "a value >= 0", getattr(self, key))
        _need(f"{w}: F_s", self.F_s >= self.F_c, f"a level >= F_c = {self.F_c:g} N", self.F_s)

    def stribeck(self, v: float, delta: float) -> float:
        """g(v) (N) at pressure excess ``delta`` (Pa)."""
        f_c = self.level(self.F_c, delta)
        f_s = self.level(self.F_s, delta)
        g = f_c + (f_s - f_c) * math.exp(-(abs(v / self.v_s) ** self.stribeck_exponent))
        return g * self.direction(v)

    def rates(self, v: float, z: float, delta: float) -> tuple[float, float]:
        """(dz/dt (m/s), friction force F (N)) at velocity v and bristle state z."""
        dz = v - self.sigma0 * abs(v) * z / self.stribeck(v, delta)
        return dz, self.sigma0 * z + self.sigma1 * dz + self.sigma2 * v

    def breakaway(self, delta: float) -> float:
        """Steady friction as v -> 0+ (N): the static level F_s at ``delta``
        (the mean of the two directions with an asymmetry)."""
        return self.stribeck(0.0, delta)

    def sliding(self, v: float, delta: float) -> float:
        """Steady sliding friction at velocity v > 0 minus its viscous part (N)
        (the mean of the two directions with an asymmetry)."""
        return self.stribeck(abs(v), delta) / self.direction(abs(v))

    def viscous(self) -> float:
        """Viscous coefficient (N s/m)."""
        return self.sigma2


@dataclass(frozen=True, kw_only=True)
class DahlFriction(_Seal):
    """Dahl friction (1968) with a pre-sliding damper and a viscous term.

    dz/dt = v sign(r) |r|^alpha,  r = 1 - sigma0 z sign(v) / F_c
    F = sigma0 z + sigma1 dz/dt + sigma2 v

    No Stribeck effect: breakaway and sliding levels are both F_c.

    Parameters
    ----------
    sigma0 : float
        Rest stiffness (N/m).
    F_c : float
        Coulomb level (N), > 0.
    alpha : float
        Shape exponent (-), in [1, 3].
    sigma1 : float
        Pre-sliding damping (N s/m).
    sigma2 : float
        Viscous coefficient (N s/m).
    seal, k_p, c_p
        Pressure dependence, see :class:`_Seal`.
    """

    name: ClassVar[str] = "dahl"
    sigma0: float
    F_c: float
    alpha: float = 1.0
    sigma1: float = 0.0
    sigma2: float = 0.0

    def __post_init__(self) -> None:
        self._check_seal()
        w = "friction 'dahl'"
        _need(f"{w}: sigma0", self.sigma0 > 0.0, "a stiffness > 0 N/m", self.sigma0)
        _need(f"{w}: F_c", self.F_c > 0.0, "a level > 0 N", self.F_c)
        _need(f"{w}: alpha", 1.0 <= self.alpha <= 3.0, "an exponent in [1, 3]", self.alpha)
        for key in ("sigma1", "sigma2"):
            _need(f"{w}: {key}", getattr(self, key) >= 0.0, "a value >= 0", getattr(self, key))

    def rates(self, v: float, z: float, delta: float) -> tuple[float, float]:
        """(dz/dt (m/s), friction force F (N)) at velocity v and bristle state z."""
        f_c = self.level(self.F_c, delta) * self.direction(v)
        r = 1.0 - self.sigma0 * z * (1.0 if v >= 0.0 else -1.0) / f_c
        dz = v * math.copysign(abs(r) ** self.alpha, r)
        return dz, self.sigma0 * z + self.sigma1 * dz + self.sigma2 * v

    def breakaway(self, delta: float) -> float:
        """Largest friction the bristles hold (N): F_c at ``delta``."""
        return self.level(self.F_c, delta)

    def sliding(self, v: float, delta: float) -> float:
        """Steady sliding friction minus its viscous part (N): F_c at ``delta``."""
        return self.level(self.F_c, delta)

    def viscous(self) -> float:
        """Viscous coefficient (N s/m)."""
        return self.sigma2


#: Friction models by name.
FRICTION_MODELS: dict[str, type[Any]] = {cls.name: cls for cls in (LuGreFriction, DahlFriction)}


@dataclass(frozen=True, kw_only=True)
class EndStops:
    """Stiff spring-dampers at y = 0 and y = stroke (push only).

    Parameters
    ----------
    stiffness : float
        Contact stiffness (N/m).
    damping : float
        Contact damping (N s/m).
    """

    stiffness: float = 2.0e6
    damping: float = 5.0e3

    def __post_init__(self) -> None:
        _need("end_stops: stiffness", self.stiffness > 0.0, "a stiffness > 0 N/m", self.stiffness)
        _need("end_stops: damping", self.damping >= 0.0, "a damping >= 0 N s/m", self.damping)

    def force(self, y: float, v: float, stroke: float) -> float:
        """Force of the stops on the piston (N), + towards +y."""
        if y < 0.0:
            return max(-self.stiffness * y - self.damping * v, 0.0)
        if y > stroke:
            return min(-self.stiffness * (y - stroke) - self.damping * v, 0.0)
        return 0.0
