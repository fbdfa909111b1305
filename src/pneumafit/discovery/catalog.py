"""Catalog of optional effects that plug into the models of the physics core.

Each :class:`Effect` states its physical law (as the compiled kernel
implements it, :func:`pneumafit.models.kernel.rhs`), its parameters with SI
units, fitting bounds, a prior and a typical magnitude, the option value that
switches it on in a :class:`~pneumafit.models.ModelStructure`, the phases of
a test where a missing effect shows in the residuals (:mod:`.phases`), and
its *signature*: the regressors that a sparse regression on residual rates
would need to detect it.

The registry :data:`EFFECTS` holds the nine effects of the catalog: six of
the chambers, valves and supply, and the three seal and barrel effects
(``seal_friction``, ``friction_asymmetry``, ``effective_area``) whose
definitions (law, parameter, unit, bounds, typical size) are shared with the
friction-test model (:mod:`pneumafit.physics.seal_effects`).

Adding an effect (docs/effects.md): its law needs a configuration slot and
parameters in ``models/layout.py``, an entry in
``models/structure.EFFECT_SLOTS`` and a few lines in ``models/kernel.rhs``;
then one small module defines an :class:`Effect` and calls
:func:`register_effect`, which checks it against the structure and the
parameter table.

>>> effect = get_effect("chamber_leakage")
>>> effect.structure("convection").effects
{'chamber_leakage': 1}
>>> effect.parameter_names()
('chamber_leak_conductance',)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.discovery.phases import PHASES
from pneumafit.models.layout import SPECS
from pneumafit.models.structure import EFFECT_SLOTS, ModelStructure, get_structure
from pneumafit.physics.seal_effects import SEAL_EFFECTS, SealEffect

__all__ = [
    "EFFECTS",
    "PRIOR_KINDS",
    "Effect",
    "EffectParameter",
    "EffectPrior",
    "SignatureTerm",
    "effects_for_phase",
    "get_effect",
    "register_effect",
]

#: Kinds of :class:`EffectPrior`.
PRIOR_KINDS: tuple[str, ...] = ("log-uniform", "half-normal", "uniform")


@dataclass(frozen=True)
class EffectPrior:
    """Prior density of an effect parameter's value.

    Parameters
    ----------
    kind : {"log-uniform", "half-normal", "uniform"}
        ``log-uniform``: density ~ 1/value on [lower, upper], 0 < lower
        (scale-free: for magnitudes unknown to a decade). ``half-normal``:
        density ~ exp(-value^2 / (2 scale^2)) on value >= 0 (a quantity
        expected near 0, at most a few ``scale``). ``uniform``: flat on
        [lower, upper].
    lower, upper : float
        Support of log-uniform and uniform priors (parameter unit).
    scale : float
        Scale of a half-normal prior (parameter unit).
    """

    kind: str
    lower: float = math.nan
    upper: float = math.nan
    scale: float = math.nan

    def __post_init__(self) -> None:
        where = f"effect prior {self.kind!r}"
        if self.kind not in PRIOR_KINDS:
            raise ValueError(
                f"effect prior: kind: expected one of {PRIOR_KINDS}, found {self.kind!r}"
            )
        if self.kind == "half-normal":
            if not (math.isfinite(self.scale) and self.scale > 0.0):
                raise ValueError(
                    f"{where}: scale: expected a finite number > 0, found {self.scale}"
                )
            return
        low_ok = self.lower > 0.0 if self.kind == "log-uniform" else math.isfinite(self.lower)
        if not (low_ok and math.isfinite(self.upper) and self.upper > self.lower):
            need = "0 < lower < upper" if self.kind == "log-uniform" else "lower < upper"
            raise ValueError(
                f"{where}: expected finite bounds with {need}, found [{self.lower}, {self.upper}]"
            )

    @property
    def support(self) -> tuple[float, float]:
        """(lower, upper) of the density's support (parameter unit)."""
        if self.kind == "half-normal":
            return 0.0, math.inf
        return self.lower, self.upper

    def logpdf(self, value: ArrayLike) -> NDArray[np.float64]:
        """Log density at ``value`` (normalised; -inf outside the support)."""
        v = np.asarray(value, dtype=float)
        lo, hi = self.support
        inside = (v >= lo) & (v <= hi)
        if self.kind == "half-normal":
            z = v / self.scale
            out = -0.5 * z * z + math.log(math.sqrt(2.0 / math.pi) / self.scale)
        elif self.kind == "log-uniform":
            with np.errstate(divide="ignore", invalid="ignore"):
                out = -np.log(np.where(inside, v, 1.0)) - math.log(math.log(hi / lo))
        else:
            out = np.full(v.shape, -math.log(hi - lo))
        return np.where(inside, out, -np.inf)

    def sample(self, rng: np.random.Generator, size: int | None = None) -> NDArray[np.float64]:
        """Draw values from the prior with the generator ``rng``."""
        if self.kind == "half-normal":
            return np.abs(rng.normal(0.0, self.scale, size))
        if self.kind == "log-uniform":
            return np.exp(rng.uniform(math.log(self.lower), math.log(self.upper), size))
        return rng.uniform(self.lower, self.upper, size)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form (``kind`` plus ``lower``/``upper`` or ``scale``)."""
        if self.kind == "half-normal":
            return {"kind": self.kind, "scale": self.scale}
        return {"kind": self.kind, "lower": self.lower, "upper": self.upper}


def _log_uniform(lower: float, upper: float) -> EffectPrior:
    """Log-uniform prior on [lower, upper]."""
    return EffectPrior("log-uniform", lower=lower, upper=upper)


def _half_normal(scale: float) -> EffectPrior:
    """Half-normal prior of scale ``scale``."""
    return EffectPrior("half-normal", scale=scale)


@dataclass(frozen=True)
class EffectParameter:
    """One parameter of an effect.

    Parameters
    ----------
    name : str
        Canonical name in :data:`pneumafit.models.PARAMETER_SPECS`.
    unit : str
        SI unit (must equal the parameter table's).
    lower, upper : float
        Bounds for fitting (parameter unit), inside the table's physical
        bounds and usually tighter: what the effect can plausibly be.
    prior : EffectPrior
        Prior of the value.
    typical : float
        A typical magnitude (start value, or the size the virtual rig uses).
    description : str
        One line.
    neutral : float, optional
        Value at which the effect vanishes when it lies strictly inside the
        bounds (a *signed* parameter: either sign of the departure acts, e.g.
        a friction asymmetry around 0, an area factor around 1). None (the
        default): the effect vanishes at the lower bound (at the upper one
        for the wall's heat capacity), every departure is one-sided.
    """

    name: str
    unit: str
    lower: float
    upper: float
    prior: EffectPrior
    typical: float
    description: str = ""
    neutral: float | None = None

    @property
    def signed(self) -> bool:
        """True when the effect acts on either side of a neutral value inside the bounds."""
        return self.neutral is not None

    def __post_init__(self) -> None:
        where = f"effect parameter {self.name!r}"
        if self.neutral is not None and not self.lower < self.neutral < self.upper:
            raise ValueError(
                f"{where}: neutral: expected a value strictly inside [{self.lower:g}, "
                f"{self.upper:g}], found {self.neutral:g}"
            )
        if not self.lower <= self.typical <= self.upper:
            raise ValueError(
                f"{where}: expected lower <= typical <= upper, found "
                f"{self.lower:g} <= {self.typical:g} <= {self.upper:g}"
            )
        if not np.isfinite(self.prior.logpdf(self.typical)):
            raise ValueError(
                f"{where}: typical value {self.typical:g} {self.unit} lies outside its prior's "
                f"support {self.prior.support}"
            )


@dataclass(frozen=True)
class SignatureTerm:
    """A regressor through which an effect enters the model equations.

    Parameters
    ----------
    regressor : str
        The term, in words and symbols, e.g. ``"P_P - P_N"``.
    enters : str
        The rates it appears in, e.g. ``"dP_P/dt, dP_N/dt"``.
    note : str
        Its coefficient or how to form it from measured/simulated signals.
    """

    regressor: str
    enters: str
    note: str = ""


@dataclass(frozen=True)
class Effect:
    """An optional effect of the catalog.

    Parameters
    ----------
    name : str
        Name; also its key in :data:`pneumafit.models.EFFECT_SLOTS`.
    description : str
        One line.
    law : str
        The physical law as the kernel implements it (SI; symbols of
        docs/physics.md).
    parameters : tuple of EffectParameter
        All parameters of the effect, over all its options.
    option : int
        Value that switches it on in ``ModelStructure.effects`` (default
        variant; ``valve_dynamics`` takes 1 or 2, the spool order).
    option_parameters : mapping of int to tuple of str, optional
        Option value -> the parameters that variant uses; default: every
        parameter for ``option``.
    signature : tuple of SignatureTerm
        Regressors for a later sparse regression.
    phases : tuple of str
        Phases of a test (:data:`pneumafit.discovery.phases.PHASES`) where a
        missing effect shows most in the residuals.
    """

    name: str
    description: str
    law: str
    parameters: tuple[EffectParameter, ...]
    option: int = 1
    option_parameters: Mapping[int, tuple[str, ...]] = field(default_factory=dict, hash=False)
    signature: tuple[SignatureTerm, ...] = ()
    phases: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = f"effect {self.name!r}"
        if not self.name.isidentifier():
            raise ValueError(f"effect: name: expected an identifier, found {self.name!r}")
        if not self.parameters:
            raise ValueError(f"{where}: parameters: expected at least one, found none")
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"{where}: parameters: expected distinct names, found {names}")
        options = dict(self.option_parameters) or {self.option: tuple(names)}
        if self.option not in options or any(v < 1 for v in options):
            raise ValueError(
                f"{where}: option: expected {self.option} >= 1 among the option values "
                f"{sorted(options)}"
            )
        for value, used in options.items():
            extra = sorted(set(used) - set(names))
            if extra:
                raise ValueError(
                    f"{where}: option {value}: expected parameters of the effect, found {extra}"
                )
        object.__setattr__(self, "option_parameters", MappingProxyType(options))
        bad = [p for p in self.phases if p not in PHASES]
        if bad:
            raise ValueError(f"{where}: phases: expected some of {PHASES}, found {bad}")

    def parameter(self, name: str) -> EffectParameter:
        """The parameter called ``name``."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise ValueError(
            f"effect {self.name!r}: parameter: expected one of "
            f"{[p.name for p in self.parameters]}, found {name!r}"
        )

    def _option(self, option: int | None) -> int:
        value = self.option if option is None else int(option)
        if value not in self.option_parameters:
            raise ValueError(
                f"effect {self.name!r}: option: expected one of {sorted(self.option_parameters)}, "
                f"found {option!r}"
            )
        return value

    def parameter_names(self, option: int | None = None) -> tuple[str, ...]:
        """Parameters the effect uses with ``option`` (default :attr:`option`)."""
        return tuple(self.option_parameters[self._option(option)])

    def typical_values(self, option: int | None = None) -> dict[str, float]:
        """Typical magnitude of each parameter used with ``option`` (SI)."""
        return {n: self.parameter(n).typical for n in self.parameter_names(option)}

    def structure(self, base: str | ModelStructure, option: int | None = None) -> ModelStructure:
        """``base`` (a structure or a registered structure name) with this effect on."""
        return get_structure(base).with_effects(**{self.name: self._option(option)})


# ----------------------------------------------------------------- registry
_EFFECTS: dict[str, Effect] = {}
#: The registered effects by name (read-only view; add with :func:`register_effect`).
EFFECTS: Mapping[str, Effect] = MappingProxyType(_EFFECTS)


def register_effect(effect: Effect, *, replace: bool = False) -> Effect:
    """Add an effect to :data:`EFFECTS` after checking it against the models.

    Checks: the name has a configuration slot (an entry of
    :data:`pneumafit.models.EFFECT_SLOTS`, i.e. the kernel implements the
    law); every option value is accepted by
    :class:`~pneumafit.models.ModelStructure` and switches on exactly the
    parameters the effect lists for it; each parameter exists in
    :data:`pneumafit.models.PARAMETER_SPECS` with the same unit, and its
    fitting bounds and prior support lie within the table's physical bounds.

    Parameters
    ----------
    effect : Effect
    replace : bool
        Allow replacing an effect registered under the same name.

    Returns
    -------
    Effect
        ``effect`` (so a module can write ``MY_EFFECT = register_effect(Effect(...))``).

    Raises
    ------
    ValueError
        Any failed check; the message says what to add where (docs/effects.md).
    """
    where = f"register_effect({effect.name!r})"
    if effect.name in _EFFECTS and not replace:
        raise ValueError(f"{where}: an effect of this name is registered; pass replace=True")
    if effect.name not in EFFECT_SLOTS:
        raise ValueError(
            f"{where}: expected a configuration slot in pneumafit.models.EFFECT_SLOTS, found "
            "none: the law needs a slot and parameters in models/layout.py, an EFFECT_SLOTS "
            "entry in models/structure.py and its lines in models/kernel.rhs (docs/effects.md)"
        )
    for p in effect.parameters:
        spec = SPECS.get(p.name)
        if spec is None:
            raise ValueError(
                f"{where}: parameter {p.name!r}: expected a ParameterSpec in "
                "models/layout.PARAMETER_SPECS, found none"
            )
        if spec.unit != p.unit:
            raise ValueError(
                f"{where}: parameter {p.name!r}: expected unit {spec.unit!r} (the parameter "
                f"table's), found {p.unit!r}"
            )
        lo, hi = p.prior.support
        if not (spec.lower <= p.lower and p.upper <= spec.upper and spec.lower <= lo):
            raise ValueError(
                f"{where}: parameter {p.name!r}: expected bounds [{p.lower:g}, {p.upper:g}] and "
                f"prior support [{lo:g}, {hi:g}] within the physical bounds "
                f"[{spec.lower:g}, {spec.upper:g}] {spec.unit}"
            )
    for value, used in effect.option_parameters.items():
        try:
            structure = ModelStructure("constant-lambda", effects={effect.name: value})
        except ValueError as exc:
            raise ValueError(f"{where}: option {value}: {exc}") from None
        switched = set(structure.parameter_names) - set(
            ModelStructure("constant-lambda").parameter_names
        )
        if switched != set(used):
            raise ValueError(
                f"{where}: option {value}: expected the parameters the structure switches on, "
                f"{sorted(switched)}, found {sorted(used)}"
            )
    _EFFECTS[effect.name] = effect
    return effect


def get_effect(name: str) -> Effect:
    """The registered effect called ``name``.

    Raises
    ------
    ValueError
        Unknown name (the message lists the registered ones).
    """
    try:
        return _EFFECTS[name]
    except KeyError:
        raise ValueError(f"effect: expected one of {sorted(_EFFECTS)}, found {name!r}") from None


def effects_for_phase(phase: str) -> tuple[Effect, ...]:
    """Registered effects whose missing term shows most in ``phase``."""
    if phase not in PHASES:
        raise ValueError(f"phase: expected one of {PHASES}, found {phase!r}")
    return tuple(e for e in _EFFECTS.values() if phase in e.phases)


# ----------------------------------------------------------------- the catalog
# Typical magnitudes: the virtual rig's defaults (pneumafit.rig.EFFECT_DEFAULTS,
# chosen to be clearly visible on the demo protocol) for the principal
# parameters, the parameter table's defaults for the others.

register_effect(
    Effect(
        name="chamber_leakage",
        description=EFFECT_SLOTS["chamber_leakage"][2],
        law=(
            "q_l = G_cl (P_P - P_N)  [kg/s, from P to N across the piston seal];\n"
            "m_P loses q_l and m_N gains it; the enthalpy flow q_l T_up leaves P and enters N,\n"
            "T_up = T_P if q_l > 0 else T_N (laminar: linear in the pressure difference)."
        ),
        parameters=(
            EffectParameter(
                name="chamber_leak_conductance",
                unit="kg/s/Pa",
                lower=1e-13,
                upper=1e-9,
                prior=_log_uniform(1e-13, 1e-9),
                typical=5e-11,
                description="laminar conductance G_cl of the piston seal",
            ),
        ),
        signature=(
            SignatureTerm(
                regressor="P_P - P_N",
                enters="dP_P/dt, dP_N/dt",
                note="coefficient -gamma r T_up G_cl / V_P in dP_P/dt and +gamma r T_up G_cl / "
                "V_N in dP_N/dt: opposite signs, volume-weighted (what sets it apart from "
                "external leakage)",
            ),
        ),
        phases=("relaxation", "rest"),
    )
)

register_effect(
    Effect(
        name="external_leakage",
        description=EFFECT_SLOTS["external_leakage"][2],
        law=(
            "q_P = G_el (1 + s) (P_P - P_atm), q_N = G_el (1 - s) (P_N - P_atm)  [kg/s, out of\n"
            "each chamber to atmosphere; s = 0: the same conductance, s = -1: only N leaks];\n"
            "an outflow carries T_X, an inflow (P_X < P_atm) T_atm; both count as exhausted air."
        ),
        parameters=(
            EffectParameter(
                name="external_leak_conductance",
                unit="kg/s/Pa",
                lower=1e-13,
                upper=1e-9,
                prior=_log_uniform(1e-13, 1e-9),
                typical=5e-11,
                description="laminar conductance G_el of each chamber to atmosphere (mean)",
            ),
            EffectParameter(
                name="external_leak_split",
                unit="",
                lower=-1.0,
                upper=1.0,
                prior=EffectPrior("uniform", lower=-1.0, upper=1.0),
                typical=0.0,
                description="how the chambers share it: G_P = G_el (1 + s), G_N = G_el (1 - s)",
                neutral=0.0,
            ),
        ),
        signature=(
            SignatureTerm("P_P - P_atm", "dP_P/dt", "coefficient -gamma r T_P G_el (1 + s) / V_P"),
            SignatureTerm("P_N - P_atm", "dP_N/dt", "coefficient -gamma r T_N G_el (1 - s) / V_N"),
        ),
        phases=("relaxation", "rest"),
    )
)

register_effect(
    Effect(
        name="valve_dynamics",
        description=EFFECT_SLOTS["valve_dynamics"][2],
        law=(
            "The valve flows see a spool position u_s instead of the command u, per valve:\n"
            "order 1: tau du_s/dt = u - u_s;\n"
            "order 2: d2u_s/dt2 = w_n^2 (u - u_s) - 2 zeta w_n du_s/dt;\n"
            "u_s starts at the first command, at rest."
        ),
        parameters=(
            EffectParameter(
                name="valve_time_constant",
                unit="s",
                lower=1e-4,
                upper=0.1,
                prior=_log_uniform(1e-4, 0.1),
                typical=0.015,
                description="first-order spool time constant tau",
            ),
            EffectParameter(
                name="valve_natural_frequency",
                unit="rad/s",
                lower=30.0,
                upper=1e4,
                prior=_log_uniform(30.0, 1e4),
                typical=600.0,
                description="second-order spool natural frequency w_n",
            ),
            EffectParameter(
                name="valve_damping_ratio",
                unit="",
                lower=0.1,
                upper=2.0,
                prior=_log_uniform(0.1, 2.0),
                typical=0.7,
                description="second-order spool damping ratio zeta",
            ),
        ),
        option=1,
        option_parameters={
            1: ("valve_time_constant",),
            2: ("valve_natural_frequency", "valve_damping_ratio"),
        },
        signature=(
            SignatureTerm(
                regressor="d/dt [gamma r T_up q_valve(u, P) / V]",
                enters="dP_P/dt, dP_N/dt",
                note="to first order in tau, q(u_s) = q(u) - tau dq/dt: the rate of the static "
                "valve-flow term, coefficient -tau (order 2: tau = 2 zeta / w_n)",
            ),
        ),
        phases=("filling", "emptying", "motion"),
    )
)

register_effect(
    Effect(
        name="wall_thermal_mass",
        description=EFFECT_SLOTS["wall_thermal_mass"][2],
        law=(
            "Per chamber a wall temperature state T_w,X (starting at the wall temperature):\n"
            "C_w dT_w,X/dt = lambda_X (T_X - T_w,X) + h_o (T_atm - T_w,X)  [per unit area];\n"
            "the gas exchanges Q_X = lambda_X A_X (T_w,X - T_X) with it instead of the fixed\n"
            "wall. No effect in the polytropic structure (no wall exchange)."
        ),
        parameters=(
            EffectParameter(
                name="wall_heat_capacity",
                unit="J/K/m^2",
                lower=10.0,
                upper=1e5,
                prior=_log_uniform(10.0, 1e5),
                typical=100.0,
                description="heat capacity C_w of the wall per unit exchange area",
            ),
            EffectParameter(
                name="wall_outer_coefficient",
                unit="W/m^2/K",
                lower=0.0,
                upper=200.0,
                prior=_half_normal(20.0),
                typical=10.0,
                description="wall-to-ambient heat-transfer coefficient h_o",
            ),
        ),
        signature=(
            SignatureTerm(
                regressor="lambda A (T_wf - T_w0)",
                enters="dP_X/dt, dT_X/dt",
                note="T_wf: the gas temperature low-pass filtered with time constant "
                "C_w / lambda (the wall warming up), T_w0 the fixed wall; coefficient "
                "(gamma - 1) / V_X in dP_X/dt",
            ),
        ),
        phases=("relaxation",),
    )
)

register_effect(
    Effect(
        name="forced_convection",
        description=EFFECT_SLOTS["forced_convection"][2],
        law=(
            "lambda_X = lambda_law + K_fc q_s,X while q_s,X > 0, q_s,X the mass flow through\n"
            "the supply path of valve X into chamber X (the filling jet, centre leakage\n"
            "included; kg/s); not in the polytropic structure (no wall exchange)."
        ),
        parameters=(
            EffectParameter(
                name="forced_convection_gain",
                unit="W/m^2/K/(kg/s)",
                lower=100.0,
                upper=1e6,
                prior=_log_uniform(100.0, 1e6),
                typical=2e4,
                description="increase K_fc of lambda per unit supply inflow",
            ),
        ),
        signature=(
            SignatureTerm(
                regressor="max(q_s,X, 0) A_X (T_w - T_X)",
                enters="dP_X/dt, dT_X/dt",
                note="coefficient (gamma - 1) K_fc / V_X in dP_X/dt; non-zero only while filling",
            ),
        ),
        phases=("filling",),
    )
)

register_effect(
    Effect(
        name="supply_pressure_drop",
        description=EFFECT_SLOTS["supply_pressure_drop"][2],
        law=(
            "P_S' = max(P_S - R (q_s,P + q_s,N)^+, P_atm): the valves see the supply pressure\n"
            "behind a line resistance R, q_s the supply-path flows first evaluated at P_S\n"
            "(one fixed-point iteration); not applied in flow tests (static characteristic)."
        ),
        parameters=(
            EffectParameter(
                name="supply_line_resistance",
                unit="Pa/(kg/s)",
                lower=1e4,
                upper=1e8,
                prior=_log_uniform(1e4, 1e8),
                typical=6e6,
                description="supply pressure drop R per unit drawn flow",
            ),
        ),
        signature=(
            SignatureTerm(
                regressor="q_s dq_valve/dP_S",
                enters="dP_P/dt, dP_N/dt",
                note="drawn flow times the valve flow's sensitivity to supply pressure (sonic: "
                "q_valve / P_S), coefficient -R gamma r T_atm / V_X; only with a supply path open",
            ),
        ),
        phases=("filling", "motion"),
    )
)


# ----------------------------------------------------------------- seal and barrel
# The definitions are shared with the friction-test model
# (pneumafit.physics.seal_effects); only what discovery on the cylinder adds
# (signature terms, phases) is written here.


def _seal_parameter(e: SealEffect) -> EffectParameter:
    if e.prior == "log-uniform":
        prior = _log_uniform(e.fit_lower, e.fit_upper)
    else:
        prior = EffectPrior("uniform", lower=e.fit_lower, upper=e.fit_upper)
    return EffectParameter(
        name=e.parameter,
        unit=e.unit,
        lower=e.fit_lower,
        upper=e.fit_upper,
        prior=prior,
        typical=e.typical,
        description=e.description,
        neutral=e.neutral if e.signed else None,
    )


def _seal_entry(name: str, signature: tuple[SignatureTerm, ...], phases: tuple[str, ...]) -> None:
    e = SEAL_EFFECTS[name]
    register_effect(
        Effect(
            name=e.name,
            description=EFFECT_SLOTS[e.name][2],
            law=e.law,
            parameters=(_seal_parameter(e),),
            signature=signature,
            phases=phases,
        )
    )


_seal_entry(
    "seal_friction",
    (
        SignatureTerm(
            regressor="-sign(v) max(P_P + P_N - 2 P_atm, 0) / M",
            enters="dv/dt",
            note="coefficient c_p; only while sliding (a stuck piston's friction balances the "
            "drive); the chambers' rates do not see it at the measured state",
        ),
    ),
    ("motion",),
)
_seal_entry(
    "friction_asymmetry",
    (
        SignatureTerm(
            regressor="-g(v) / M, g the friction level (static, Coulomb, seal)",
            enters="dv/dt",
            note="coefficient a (either sign); F_f = sign(v) g (1 + a sign v) + b v, so "
            "dF_f/da = g in both directions: an offset of the sliding force that a constant "
            "load cannot mimic while the piston is stuck (break-away at F_s (1 +- a))",
        ),
    ),
    ("motion",),
)
_seal_entry(
    "effective_area",
    (
        SignatureTerm(
            regressor="S_bore (P_P - P_N) / M (the force k_A S_bore (P_P - P_N) + S_rod P_N)",
            enters="dv/dt",
            note="coefficient k_A - 1 (either sign): the pressure force on the bore's area",
        ),
        SignatureTerm(
            regressor="d(dP_X/dt)/dk_A: -+gamma P_X S_bore v / V_X and the volume change "
            "S_bore y (resp. L - y) in 1/V_X",
            enters="dP_P/dt, dP_N/dt",
            note="coefficient k_A - 1; the kernel's own derivative at the measured state "
            "(central difference), blocked tests included (the chamber volume changes)",
        ),
    ),
    ("motion", "filling", "emptying"),
)
