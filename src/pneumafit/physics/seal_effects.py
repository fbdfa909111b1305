"""The seal and barrel effects, defined once for every model that uses them.

A real cylinder's seals and barrel show three effects beside the nominal
friction and geometry (issue 14): friction that grows with the chamber
pressure (the seal is pressed harder against the barrel), friction levels
that differ with the direction of motion (a lip seal is not symmetric), and
a piston area different from the nominal one. Each is one physical part of
the actuator; this module holds its definition (name, parameter, SI unit,
neutral value, bounds, typical magnitude, law) for

- the double-acting cylinder model (the compiled kernel's slot, its
  :data:`pneumafit.models.PARAMETER_SPECS` entry and the discovery catalog
  entry, :mod:`pneumafit.discovery.catalog`), and
- the friction-test force balance of measured single-acting seal benches
  (:data:`pneumafit.frictiontest.model.FRICTION_EFFECTS`).

Both read the same :class:`SealEffect`, so the law, the parameter name and
unit, the bounds and the typical value cannot drift apart.

Laws (the friction level g of the Stribeck curve, docs/physics.md eq. 1 and
the LuGre law of :mod:`pneumafit.physics.friction`; v the piston velocity,
sign(0) = 0)::

    seal friction     F_s, F_c  +=  c_p max(P_P + P_N - 2 P_atm, 0)
    asymmetry         g(v)      ->  g(v) (1 + a sign v)     (seal term included)
    effective area    S_bore    ->  k_A pi D^2 / 4          (rod area unchanged)

The asymmetry multiplies the whole level (static, Coulomb and seal parts) by
one factor: the friction-test kernel's definition, and the identifiable
one. Per direction the steady sliding friction is g (1 +- a) + b v; two
independent levels per direction for both F_s and F_c would add three
parameters where a step test, which mostly slides, measures one Coulomb
level per direction (the static level shows only at the few break-aways).
One factor a = (F_c+ - F_c-) / (F_c+ + F_c-) is what the data carry.

The effective area scales the bore's cross-section, i.e. the piston seen as
a real bore D' = D sqrt(k_A): the pressure force, the swept volume and its
rate (V_P = V_0P + k_A S y, dV_P/dt = k_A S dy/dt) and the exchange areas all
follow it, the rod area does not (the annulus is k_A S - S_rod). Why both
force and volume: the axial pressure force on a sealed piston is the
pressure times the projected area of every axial-facing surface of the
moving body up to the seal line, and for a seal that fills the radial gap
that is the bore's cross-section, the same area that sweeps the chamber
volume (the pressure inside the seal's contact band presses radially and
adds to the friction, the seal-friction effect, not to the axial force). A
pressure area different from the nominal one is therefore a bore different
from the nominal one (tolerance, wear, a nominal size for a slightly smaller
bore), which changes force and volume alike; a force-only factor would
break the energy balance (pressure work P dV against the work of the force
on the piston, P S dy). See docs/physics.md, "Seal and barrel effects".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pneumafit.errors import PneumafitInputError

__all__ = ["SEAL_EFFECTS", "SealEffect", "seal_effect"]


@dataclass(frozen=True)
class SealEffect:
    """One seal or barrel effect: the shared definition.

    Attributes
    ----------
    name : str
        Effect name in the cylinder model (``EFFECT_SLOTS``, the discovery
        catalog).
    bench_name : str
        Its name in the friction-test catalog (hyphenated, as written to the
        friction tests' discovery.json).
    parameter : str
        Parameter name, the same in both models.
    unit : str
        SI unit of the parameter (pint syntax, "" for dimensionless).
    neutral : float
        Value at which the effect vanishes (its default: off).
    lower, upper : float
        Physical bounds (the parameter table's; the friction-test fit's).
    fit_lower, fit_upper : float
        Bounds for discovery on the cylinder: what the effect can plausibly be.
    prior : str
        Prior kind over [fit_lower, fit_upper]: ``log-uniform`` (a magnitude
        > 0 known to a few decades) or ``uniform`` (a signed departure from
        the neutral value).
    typical : float
        Typical magnitude (the virtual rig's default size).
    step : float
        Forward-difference step of the friction test's signature (unit).
    description : str
        One line.
    law : str
        The law as the kernels implement it (SI; symbols of docs/physics.md).
    negligible : float
        For a signed effect, the largest departure from the neutral value
        that is not an effect of its own (parameter unit), e.g. a
        manufacturing tolerance; NaN: discovery's generic margin
        (``discovery.refit.VANISHING`` of the half range).
    """

    name: str
    bench_name: str
    parameter: str
    unit: str
    neutral: float
    lower: float
    upper: float
    fit_lower: float
    fit_upper: float
    prior: str
    typical: float
    step: float
    description: str
    law: str
    negligible: float = math.nan

    @property
    def signed(self) -> bool:
        """True when the neutral value lies inside the fitting bounds (either sign acts)."""
        return self.fit_lower < self.neutral < self.fit_upper


#: The three effects, by cylinder name.
SEAL_EFFECTS: dict[str, SealEffect] = {
    e.name: e
    for e in (
        SealEffect(
            name="seal_friction",
            bench_name="seal-friction",
            parameter="seal_friction_coefficient",
            unit="N/Pa",
            neutral=0.0,
            lower=0.0,
            upper=1e-3,
            fit_lower=1e-7,
            fit_upper=1e-4,
            prior="log-uniform",
            typical=1.5e-5,
            step=1e-6,
            description="friction of the seals grows with the chamber pressures",
            law=(
                "F_s, F_c += c_p max(P_P + P_N - 2 P_atm, 0)  [N; c_p in N/Pa]: the seals are\n"
                "pressed harder against the barrel (single-acting bench: P_N = P_atm); with\n"
                "friction_asymmetry the added level is scaled by (1 + a sign v) too."
            ),
        ),
        SealEffect(
            name="friction_asymmetry",
            bench_name="friction-asymmetry",
            parameter="friction_asymmetry",
            unit="",
            neutral=0.0,
            lower=-0.9,
            upper=0.9,
            fit_lower=-0.5,
            fit_upper=0.5,
            prior="uniform",
            typical=0.2,
            step=1e-2,
            description="direction asymmetry of the friction levels",
            law=(
                "g(v) -> g(v) (1 + a sign v): static, Coulomb and seal levels times (1 + a) while\n"
                "extending (v > 0), (1 - a) while retracting; the stuck piston breaks away at\n"
                "F_d > F_s (1 + a) or F_d < -F_s (1 - a); the viscous term b v is unchanged."
            ),
        ),
        SealEffect(
            name="effective_area",
            bench_name="effective-area",
            parameter="area_factor",
            unit="",
            neutral=1.0,
            lower=0.5,
            upper=1.5,
            fit_lower=0.8,
            fit_upper=1.2,
            prior="uniform",
            typical=1.05,
            step=1e-2,
            # ISO 286 IT11 (a honed cylinder tube's H11 bore) is 0.16 mm for
            # 30-50 mm: on a 32 mm bore 0.5 % of D, 1.0 % of its area. A
            # departure within that is the part's tolerance, not an effect; the
            # generic margin (10 % of the 0.2 half range, 2 % of the area)
            # refused a bore 0.8 % wider (k_A 1.018 fitted for 1.016, held-out
            # 3754 -> 1271 Pa, docs/effects.md, "A wider bore called vanished")
            negligible=0.01,
            description="effective piston area k_A times the nominal bore area",
            law=(
                "S_P = k_A pi D^2 / 4, S_N = S_P - pi d^2 / 4 (a bore D sqrt(k_A)): the\n"
                "pressure force S_P P_P - S_N P_N, the volumes V_P = V_0P + S_P y,\n"
                "V_N = V_0N + S_N (L - y), their rates dV/dt = +-S dy/dt and the exchange\n"
                "areas all use it; the rod area is unchanged."
            ),
        ),
    )
}


def seal_effect(name: str) -> SealEffect:
    """The shared definition called ``name`` (cylinder name or bench name)."""
    for e in SEAL_EFFECTS.values():
        if name in (e.name, e.bench_name, e.parameter):
            return e
    raise PneumafitInputError(
        f"seal effect: expected one of {sorted(SEAL_EFFECTS)}, found {name!r}"
    )
