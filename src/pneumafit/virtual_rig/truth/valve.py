"""Servo-valve parts of the truth: flow function, conductance families, centre leaks.

Each 3-way servo-valve connects its chamber to supply through a *supply path*
and to exhaust through an *exhaust path*. A path is an ISO 6358 restriction
(ISO 6358-1:2013 form with a laminar region):

    q = C rho0 P_up sqrt(T_ref / T_up) phi(x),   x = P_down / P_up

    phi(x) = 1                                           x <= b   (choked)
    phi(x) = [1 - ((x - b) / (1 - b))^2]^m               b < x <= x_l
    phi(x) = phi(x_l) (1 - x) / (1 - x_l)                x_l < x <= 1 (laminar)

In the laminar region q = C rho0 sqrt(T_ref / T_up) phi(x_l) (P_up - P_down)
/ (1 - x_l) is linear in the pressure difference (ISO 6358-1:2013 uses
x_l = 0.999); phi is continuous there, its slope is not (the fitted law of
:mod:`pneumafit.physics.valve` uses a C1 quadratic tail instead). When the
downstream pressure exceeds the upstream one the flow reverses and carries
the temperature of the new upstream side.

The sonic conductance of a path depends on the command s that opens it
(s = u for the supply path, s = -u for the exhaust path), through one of the
conductance families (:data:`CONDUCTANCE_FAMILIES`), plus a centre leak
through the overlapped lands (:data:`LEAK_SHAPES`), a function of u. The
critical ratio b may depend on the opening: b(f) = b_small + (b - b_small) f
with f = C_open / C_max in [0, 1] (``b_small`` None: b constant).

Units: C in m^3/s/Pa, commands in V, pressures in Pa (absolute),
temperatures in K, mass flows in kg/s.
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from scipy.interpolate import PchipInterpolator

from pneumafit.errors import PneumafitInputError
from pneumafit.virtual_rig.truth.constants import RHO_REF, T_REF

__all__ = [
    "CONDUCTANCE_FAMILIES",
    "LEAK_SHAPES",
    "BumpLeak",
    "ConstantLeak",
    "IsoLinearConductance",
    "NoLeak",
    "PowerConductance",
    "ServoValve",
    "SigmoidLeak",
    "TableConductance",
    "flow_function",
    "restriction_flow",
]


def flow_function(x: float, b: float, m: float, x_laminar: float) -> float:
    """ISO 6358 flow function phi(x) with a laminar region (-).

    Parameters
    ----------
    x : float
        Pressure ratio P_down / P_up (-), in [0, 1].
    b : float
        Critical pressure ratio (-), below ``x_laminar``.
    m : float
        Subsonic index (-), 0.5 in ISO 6358:1989.
    x_laminar : float
        Ratio above which the flow is linear in the pressure difference (-).

    Returns
    -------
    float
        phi in [0, 1]: 1 when choked, 0 at x = 1.
    """
    if x <= b:
        return 1.0
    if x <= x_laminar:
        s = (x - b) / (1.0 - b)
        return (1.0 - s * s) ** m
    s_l = (x_laminar - b) / (1.0 - b)
    return (1.0 - s_l * s_l) ** m * (1.0 - x) / (1.0 - x_laminar)


def restriction_flow(
    conductance: float,
    b: float,
    m: float,
    x_laminar: float,
    p_1: float,
    t_1: float,
    p_2: float,
    t_2: float,
) -> tuple[float, float]:
    """Signed mass flow from node 1 to node 2 through a restriction.

    Parameters
    ----------
    conductance : float
        Sonic conductance C (m^3/s/Pa), >= 0.
    b, m, x_laminar : float
        Critical ratio, subsonic index, laminar onset ratio (-).
    p_1, p_2 : float
        Absolute pressures of the nodes (Pa), > 0.
    t_1, t_2 : float
        Gas temperatures of the nodes (K), > 0.

    Returns
    -------
    q : float
        Mass flow from 1 to 2 (kg/s), negative when it reverses.
    t_up : float
        Temperature carried by the flow (K): that of the upstream node.
    """
    if p_1 >= p_2:
        q = conductance * RHO_REF * p_1 * math.sqrt(T_REF / t_1)
        return q * flow_function(p_2 / p_1, b, m, x_laminar), t_1
    q = conductance * RHO_REF * p_2 * math.sqrt(T_REF / t_2)
    return -q * flow_function(p_1 / p_2, b, m, x_laminar), t_2


def _need(where: str, ok: bool, what: str, found: object) -> None:
    if not ok:
        raise PneumafitInputError(f"{where}: expected {what}, found {found!r}")


# ----------------------------------------------------------------------------
# Conductance families (one path, command s that opens it)
# ----------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class _Path:
    """Critical ratio of a path, shared by every family.

    Parameters
    ----------
    b : float
        Critical pressure ratio at full opening (-), in (0, 0.95).
    b_small : float or None
        Critical ratio as the opening tends to 0 (-); b varies linearly with
        the open fraction in between. None: b at every opening.
    """

    name: ClassVar[str] = ""
    b: float = 0.3
    b_small: float | None = None

    def __post_init__(self) -> None:
        where = f"conductance family {self.name!r}"
        _need(f"{where}: b", 0.0 < self.b < 0.95, "a ratio in (0, 0.95)", self.b)
        if self.b_small is not None:
            _need(f"{where}: b_small", 0.0 < self.b_small < 0.95, "a ratio in (0, 0.95)",
                  self.b_small)  # fmt: skip

    @property
    def c_max(self) -> float:  # pragma: no cover - overridden
        raise NotImplementedError

    def conductance(self, s: float) -> float:  # pragma: no cover - overridden
        """Sonic conductance (m^3/s/Pa) at opening command s (V)."""
        raise NotImplementedError

    def critical_ratio(self, s: float) -> float:
        """Critical ratio b (-) at opening command s (V)."""
        if self.b_small is None:
            return self.b
        f = self.conductance(s) / self.c_max if self.c_max > 0.0 else 0.0
        return self.b_small + (self.b - self.b_small) * min(max(f, 0.0), 1.0)


@dataclass(frozen=True, kw_only=True)
class IsoLinearConductance(_Path):
    """Linear ramp past an overlap: C = C_max clip((s - u0) / (u_sat - u0), 0, 1).

    Parameters
    ----------
    C_max : float
        Full-opening sonic conductance (m^3/s/Pa).
    overlap : float
        Dead-band half-width u0 (V).
    u_sat : float
        Command of full opening (V), > overlap.
    corner : float
        Half-width e (V) of the rounding of the ramp's foot; 0 for the sharp
        corner.
    corner_shape : {"quadratic", "smoothstep"}
        How the foot rounds over |z| < e, z = s - overlap: ``quadratic``
        (C1), ramp = (z + e)^2 / (4 e); ``smoothstep`` (C2), the integral
        of the smoothstep 3 t^2 - 2 t^3 with t = (z + e) / (2 e), ramp =
        2 e (t^3 - t^4 / 2), which is how the fitted ISO law rounds its
        dead-band edge (``physics.valve``, 0.05 V there): the ``fit-laws``
        control takes it, so that the control's valve is the fit's. Both
        are 0 at z = -e and equal z, with slope 1, at z = +e.
    b, b_small : float
        See :class:`_Path`.
    """

    name: ClassVar[str] = "iso_linear"
    C_max: float
    overlap: float = 0.3
    u_sat: float = 10.0
    corner: float = 0.0
    corner_shape: str = "quadratic"

    def __post_init__(self) -> None:
        super().__post_init__()
        w = f"conductance family {self.name!r}"
        _need(f"{w}: C_max", self.C_max >= 0.0, "a conductance >= 0 m^3/s/Pa", self.C_max)
        _need(f"{w}: overlap", self.overlap >= 0.0, "a command >= 0 V", self.overlap)
        _need(f"{w}: u_sat", self.u_sat > self.overlap + self.corner,
              "a command > overlap + corner (V)", self.u_sat)  # fmt: skip
        _need(f"{w}: corner", self.corner >= 0.0, "a width >= 0 V", self.corner)
        _need(f"{w}: corner_shape", self.corner_shape in ("quadratic", "smoothstep"),
              '"quadratic" or "smoothstep"', self.corner_shape)  # fmt: skip

    @property
    def c_max(self) -> float:
        return self.C_max

    def conductance(self, s: float) -> float:
        z = s - self.overlap
        e = self.corner
        if z <= -e:
            return 0.0
        if z >= e:
            ramp = z
        elif self.corner_shape == "smoothstep":
            t = (z + e) / (2.0 * e)
            ramp = 2.0 * e * t**3 * (1.0 - 0.5 * t)
        else:
            ramp = (z + e) ** 2 / (4.0 * e)
        return self.C_max * min(ramp / (self.u_sat - self.overlap), 1.0)


@dataclass(frozen=True, kw_only=True)
class PowerConductance(_Path):
    """Power law past an overlap: C = C_max clip((s - u0) / (u_sat - u0), 0, 1)^n.

    Parameters
    ----------
    C_max : float
        Full-opening sonic conductance (m^3/s/Pa).
    u0 : float
        Command where the path starts to open (V).
    u_sat : float
        Command of full opening (V), > u0.
    n : float
        Exponent (-), >= 1 (n > 1: C1 at u0; a round port opening gives ~1.5).
    b, b_small : float
        See :class:`_Path`.
    """

    name: ClassVar[str] = "power"
    C_max: float
    u0: float = 0.3
    u_sat: float = 10.0
    n: float = 1.6

    def __post_init__(self) -> None:
        super().__post_init__()
        w = f"conductance family {self.name!r}"
        _need(f"{w}: C_max", self.C_max >= 0.0, "a conductance >= 0 m^3/s/Pa", self.C_max)
        _need(f"{w}: u_sat", self.u_sat > self.u0, "a command > u0 (V)", self.u_sat)
        _need(f"{w}: n", 1.0 <= self.n <= 5.0, "an exponent in [1, 5]", self.n)

    @property
    def c_max(self) -> float:
        return self.C_max

    def conductance(self, s: float) -> float:
        f = (s - self.u0) / (self.u_sat - self.u0)
        if f <= 0.0:
            return 0.0
        return self.C_max * (min(f, 1.0) ** self.n)


@dataclass(frozen=True, kw_only=True)
class TableConductance(_Path):
    """Catalogue-style tabulated C(s), monotone cubic (PCHIP) between knots.

    Below the first knot C is the first value, above the last the last.

    Parameters
    ----------
    commands : tuple of float
        Knot commands (V), strictly increasing, at least 3.
    conductances : tuple of float
        Sonic conductance at each knot (m^3/s/Pa), non-decreasing, >= 0.
    b, b_small : float
        See :class:`_Path`.
    """

    name: ClassVar[str] = "table"
    commands: tuple[float, ...]
    conductances: tuple[float, ...]
    _slopes: tuple[float, ...] = field(init=False, repr=False, compare=False, default=())

    def __post_init__(self) -> None:
        super().__post_init__()
        w = f"conductance family {self.name!r}"
        u = tuple(float(v) for v in self.commands)
        c = tuple(float(v) for v in self.conductances)
        object.__setattr__(self, "commands", u)
        object.__setattr__(self, "conductances", c)
        _need(f"{w}: commands", len(u) >= 3 and all(b > a for a, b in itertools.pairwise(u)),
              "at least 3 strictly increasing commands (V)", u)  # fmt: skip
        _need(f"{w}: conductances", len(c) == len(u), f"{len(u)} values like commands", c)
        _need(f"{w}: conductances", all(v >= 0.0 for v in c) and all(b >= a for a, b in
              itertools.pairwise(c)), "non-decreasing values >= 0 (m^3/s/Pa)", c)  # fmt: skip
        pchip = PchipInterpolator(np.array(u), np.array(c), extrapolate=False)
        slopes = tuple(float(v) for v in pchip.derivative()(np.array(u)))
        object.__setattr__(self, "_slopes", slopes)

    @property
    def c_max(self) -> float:
        return self.conductances[-1]

    def conductance(self, s: float) -> float:
        u, c, d = self.commands, self.conductances, self._slopes
        if s <= u[0]:
            return c[0]
        if s >= u[-1]:
            return c[-1]
        k = bisect.bisect_right(u, s) - 1
        h = u[k + 1] - u[k]
        t = (s - u[k]) / h
        t2, t3 = t * t, t * t * t
        return (
            (2 * t3 - 3 * t2 + 1) * c[k]
            + (t3 - 2 * t2 + t) * h * d[k]
            + (-2 * t3 + 3 * t2) * c[k + 1]
            + (t3 - t2) * h * d[k + 1]
        )


#: Conductance families by name.
CONDUCTANCE_FAMILIES: dict[str, type[_Path]] = {
    cls.name: cls for cls in (IsoLinearConductance, PowerConductance, TableConductance)
}


# ----------------------------------------------------------------------------
# Centre-leak shapes (functions of the command u, both paths)
# ----------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class NoLeak:
    """No centre leak (a lapped, perfectly sealing spool)."""

    name: ClassVar[str] = "none"

    def leak(self, u: float) -> tuple[float, float]:
        """Leak conductances (supply path, exhaust path) (m^3/s/Pa) at command u (V)."""
        return 0.0, 0.0


@dataclass(frozen=True, kw_only=True)
class ConstantLeak:
    """The same leak conductance on both paths at every command.

    Parameters
    ----------
    C0 : float
        Leak conductance of each path (m^3/s/Pa).
    """

    name: ClassVar[str] = "constant"
    C0: float

    def __post_init__(self) -> None:
        _need("leak 'constant': C0", self.C0 >= 0.0, "a conductance >= 0 m^3/s/Pa", self.C0)

    def leak(self, u: float) -> tuple[float, float]:
        return self.C0, self.C0


@dataclass(frozen=True, kw_only=True)
class BumpLeak:
    """A Gaussian bump of leak through the dead band.

    C_leak,S = C0 exp(-((u - shift) / width)^2), C_leak,E = C0 exp(-((u + shift) / width)^2):
    largest near the centre, gone once a path is well open (the lands no
    longer overlap).

    Parameters
    ----------
    C0 : float
        Peak leak conductance of each path (m^3/s/Pa).
    width : float
        Command width of the bump (V), > 0.
    shift : float
        Offset of each path's peak towards its opening side (V).
    """

    name: ClassVar[str] = "bump"
    C0: float
    width: float = 0.3
    shift: float = 0.0

    def __post_init__(self) -> None:
        _need("leak 'bump': C0", self.C0 >= 0.0, "a conductance >= 0 m^3/s/Pa", self.C0)
        _need("leak 'bump': width", self.width > 0.0, "a width > 0 V", self.width)

    def leak(self, u: float) -> tuple[float, float]:
        zs = (u - self.shift) / self.width
        ze = (u + self.shift) / self.width
        return self.C0 * math.exp(-zs * zs), self.C0 * math.exp(-ze * ze)


@dataclass(frozen=True, kw_only=True)
class SigmoidLeak:
    """The fitted law's leak shape (for cross-checks): C0 on both paths at u = 0,
    moving to the opening path as |u| grows.

    C_leak,S = 2 C0 sigma(u / width), C_leak,E = 2 C0 sigma(-u / width),
    sigma(z) = (1 + z / sqrt(1 + z^2)) / 2.

    Parameters
    ----------
    C0 : float
        Leak conductance of each path at u = 0 (m^3/s/Pa).
    width : float
        Command scale of the shift (V), > 0.
    """

    name: ClassVar[str] = "sigmoid"
    C0: float
    width: float = 0.3

    def __post_init__(self) -> None:
        _need("leak 'sigmoid': C0", self.C0 >= 0.0, "a conductance >= 0 m^3/s/Pa", self.C0)
        _need("leak 'sigmoid': width", self.width > 0.0, "a width > 0 V", self.width)

    def leak(self, u: float) -> tuple[float, float]:
        z = u / self.width
        s = 0.5 * (1.0 + z / math.sqrt(1.0 + z * z))
        return 2.0 * self.C0 * s, 2.0 * self.C0 * (1.0 - s)


#: Centre-leak shapes by name.
LEAK_SHAPES: dict[str, type[Any]] = {
    cls.name: cls for cls in (BumpLeak, ConstantLeak, NoLeak, SigmoidLeak)
}


@dataclass(frozen=True, kw_only=True)
class ServoValve:
    """One 3-way servo-valve (both valves of the rig are of this make).

    Parameters
    ----------
    supply, exhaust : conductance family
        Supply path (opened by u > 0) and exhaust path (opened by u < 0);
        families and parameters may differ.
    leak : leak shape
        Centre leak of both paths.
    m : float
        Subsonic index of both paths (-), in [0.2, 1].
    x_laminar : float
        Pressure ratio where the laminar region starts (-), in [0.99, 0.99999).
    """

    supply: Any
    exhaust: Any
    leak: Any
    m: float = 0.5
    x_laminar: float = 0.999

    def __post_init__(self) -> None:
        _need("valve: m", 0.2 <= self.m <= 1.0, "an index in [0.2, 1]", self.m)
        _need("valve: x_laminar", 0.99 <= self.x_laminar < 0.99999,
              "a ratio in [0.99, 0.99999)", self.x_laminar)  # fmt: skip

    def conductances(self, u: float) -> tuple[float, float, float, float]:
        """(C_S, b_S, C_E, b_E) at command u (V): conductances (m^3/s/Pa), ratios (-)."""
        l_s, l_e = self.leak.leak(u)
        c_s = self.supply.conductance(u) + l_s
        c_e = self.exhaust.conductance(-u) + l_e
        return c_s, self.supply.critical_ratio(u), c_e, self.exhaust.critical_ratio(-u)

    def flows(
        self,
        u: float,
        pressure: float,
        temperature: float,
        p_supply: float,
        p_exhaust: float,
        t_source: float,
    ) -> tuple[float, float, float, float]:
        """Flows of the valve into its chamber.

        Parameters
        ----------
        u : float
            Command (V).
        pressure, temperature : float
            Chamber pressure (Pa) and gas temperature (K).
        p_supply, p_exhaust : float
            Supply and exhaust pressures (Pa, absolute).
        t_source : float
            Temperature of the supply and of the atmosphere (K).

        Returns
        -------
        q_supply : float
            Mass flow supply -> chamber (kg/s), negative when reversed.
        t_supply : float
            Temperature carried by it (K).
        q_exhaust : float
            Mass flow chamber -> exhaust (kg/s), negative when reversed.
        t_exhaust : float
            Temperature carried by it (K).
        """
        c_s, b_s, c_e, b_e = self.conductances(u)
        q_s, t_s = restriction_flow(c_s, b_s, self.m, self.x_laminar, p_supply, t_source,
                                    pressure, temperature)  # fmt: skip
        q_e, t_e = restriction_flow(c_e, b_e, self.m, self.x_laminar, pressure, temperature,
                                    p_exhaust, t_source)  # fmt: skip
        return q_s, t_s, q_e, t_e

    def net_flow(
        self, u: float, pressure: float, temperature: float, p_supply: float, p_exhaust: float,
        t_source: float,
    ) -> float:  # fmt: skip
        """Net mass flow into the chamber, q_S - q_E (kg/s); see :meth:`flows`."""
        q_s, _, q_e, _ = self.flows(u, pressure, temperature, p_supply, p_exhaust, t_source)
        return q_s - q_e
