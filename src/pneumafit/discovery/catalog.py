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

Every entry is built from the effect's part
(:class:`pneumafit.models.parts.Effect`: law, description, options, fitting
ranges and priors, signature, phases; the typical values are the rig's
defaults and the table's) by :func:`catalog_entry`; an effect registered
with :func:`pneumafit.models.parts.register_effect` later, from outside the
package too, enters the catalog at once, and leaves it when unregistered.

Adding an effect (docs/effects.md): its law needs a configuration slot and
parameters in ``models/layout.py`` and a few lines in ``models/kernel.rhs``;
its part in ``models/parts/effects.py`` holds everything else.
:func:`register_effect` (here) still takes a hand-written catalog entry for
an effect whose part is registered, and checks it against the structure and
the parameter table.

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
from pneumafit.errors import PneumafitInputError
from pneumafit.models import parts
from pneumafit.models.layout import SPECS
from pneumafit.models.parts import SignatureTerm
from pneumafit.models.structure import EFFECT_SLOTS, ModelStructure, get_structure

__all__ = [
    "EFFECTS",
    "PRIOR_KINDS",
    "Effect",
    "EffectParameter",
    "EffectPrior",
    "SignatureTerm",
    "catalog_entry",
    "effects_for_phase",
    "get_effect",
    "register_effect",
]

#: Kinds of :class:`EffectPrior`.
PRIOR_KINDS: tuple[str, ...] = parts.PRIOR_KINDS


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
            raise PneumafitInputError(
                f"effect prior: kind: expected one of {PRIOR_KINDS}, found {self.kind!r}"
            )
        if self.kind == "half-normal":
            if not (math.isfinite(self.scale) and self.scale > 0.0):
                raise PneumafitInputError(
                    f"{where}: scale: expected a finite number > 0, found {self.scale}"
                )
            return
        low_ok = self.lower > 0.0 if self.kind == "log-uniform" else math.isfinite(self.lower)
        if not (low_ok and math.isfinite(self.upper) and self.upper > self.lower):
            need = "0 < lower < upper" if self.kind == "log-uniform" else "lower < upper"
            raise PneumafitInputError(
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
    negligible : float
        For a signed parameter, the largest departure from ``neutral`` that
        is not an effect of its own (a manufacturing tolerance); NaN: the
        refit loop's generic margin (:data:`pneumafit.discovery.refit.VANISHING`
        of the half range).
    vanishes_at_upper : bool
        For a one-sided parameter (``neutral`` None), the effect vanishes at
        the upper bound instead of the lower one (the wall's heat capacity).
    """

    name: str
    unit: str
    lower: float
    upper: float
    prior: EffectPrior
    typical: float
    description: str = ""
    neutral: float | None = None
    negligible: float = math.nan
    vanishes_at_upper: bool = False

    @property
    def signed(self) -> bool:
        """True when the effect acts on either side of a neutral value inside the bounds."""
        return self.neutral is not None

    def __post_init__(self) -> None:
        where = f"effect parameter {self.name!r}"
        if self.neutral is not None and not self.lower < self.neutral < self.upper:
            raise PneumafitInputError(
                f"{where}: neutral: expected a value strictly inside [{self.lower:g}, "
                f"{self.upper:g}], found {self.neutral:g}"
            )
        if not self.lower <= self.typical <= self.upper:
            raise PneumafitInputError(
                f"{where}: expected lower <= typical <= upper, found "
                f"{self.lower:g} <= {self.typical:g} <= {self.upper:g}"
            )
        if not np.isfinite(self.prior.logpdf(self.typical)):
            raise PneumafitInputError(
                f"{where}: typical value {self.typical:g} {self.unit} lies outside its prior's "
                f"support {self.prior.support}"
            )


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
            raise PneumafitInputError(f"effect: name: expected an identifier, found {self.name!r}")
        if not self.parameters:
            raise PneumafitInputError(f"{where}: parameters: expected at least one, found none")
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise PneumafitInputError(
                f"{where}: parameters: expected distinct names, found {names}"
            )
        options = dict(self.option_parameters) or {self.option: tuple(names)}
        if self.option not in options or any(v < 1 for v in options):
            raise PneumafitInputError(
                f"{where}: option: expected {self.option} >= 1 among the option values "
                f"{sorted(options)}"
            )
        for value, used in options.items():
            extra = sorted(set(used) - set(names))
            if extra:
                raise PneumafitInputError(
                    f"{where}: option {value}: expected parameters of the effect, found {extra}"
                )
        object.__setattr__(self, "option_parameters", MappingProxyType(options))
        bad = [p for p in self.phases if p not in PHASES]
        if bad:
            raise PneumafitInputError(f"{where}: phases: expected some of {PHASES}, found {bad}")

    def parameter(self, name: str) -> EffectParameter:
        """The parameter called ``name``."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise PneumafitInputError(
            f"effect {self.name!r}: parameter: expected one of "
            f"{[p.name for p in self.parameters]}, found {name!r}"
        )

    def _option(self, option: int | None) -> int:
        value = self.option if option is None else int(option)
        if value not in self.option_parameters:
            raise PneumafitInputError(
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
        raise PneumafitInputError(
            f"{where}: an effect of this name is registered; pass replace=True"
        )
    if effect.name not in EFFECT_SLOTS:
        raise PneumafitInputError(
            f"{where}: expected an effect in pneumafit.models.EFFECT_SLOTS, found none: "
            "register its part first (pneumafit.models.parts.register_effect; a law the "
            "kernel simulates needs a slot and parameters in models/layout.py and its lines "
            "in models/kernel.rhs, docs/effects.md)"
        )
    for p in effect.parameters:
        spec = SPECS.get(p.name)
        if spec is None:
            raise PneumafitInputError(
                f"{where}: parameter {p.name!r}: expected a ParameterSpec in "
                "models/layout.PARAMETER_SPECS, found none"
            )
        if spec.unit != p.unit:
            raise PneumafitInputError(
                f"{where}: parameter {p.name!r}: expected unit {spec.unit!r} (the parameter "
                f"table's), found {p.unit!r}"
            )
        lo, hi = p.prior.support
        if not (spec.lower <= p.lower and p.upper <= spec.upper and spec.lower <= lo):
            raise PneumafitInputError(
                f"{where}: parameter {p.name!r}: expected bounds [{p.lower:g}, {p.upper:g}] and "
                f"prior support [{lo:g}, {hi:g}] within the physical bounds "
                f"[{spec.lower:g}, {spec.upper:g}] {spec.unit}"
            )
    for value, used in effect.option_parameters.items():
        try:
            structure = ModelStructure("constant-lambda", effects={effect.name: value})
        except ValueError as exc:
            raise PneumafitInputError(f"{where}: option {value}: {exc}") from None
        switched = set(structure.parameter_names) - set(
            ModelStructure("constant-lambda").parameter_names
        )
        if switched != set(used):
            raise PneumafitInputError(
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
        raise PneumafitInputError(
            f"effect: expected one of {sorted(_EFFECTS)}, found {name!r}"
        ) from None


def effects_for_phase(phase: str) -> tuple[Effect, ...]:
    """Registered effects whose missing term shows most in ``phase``."""
    if phase not in PHASES:
        raise PneumafitInputError(f"phase: expected one of {PHASES}, found {phase!r}")
    return tuple(e for e in _EFFECTS.values() if phase in e.phases)


# ----------------------------------------------------------------- the catalog
def catalog_entry(part: parts.Effect) -> Effect:
    """The catalog's record of an effect part: nothing in it is written twice.

    Parameters: the part's fitting range and prior per parameter, its unit
    from the parameter table, the typical value the rig's default for the
    principal parameter and the table's default for the others, the table's
    default as the neutral value of a signed parameter.
    """
    params = []
    for name in part.parameters:
        r = part.fit_range(name)
        spec = SPECS[name]
        if r.prior == "half-normal":
            prior = _half_normal(r.scale)
        else:
            prior = EffectPrior(r.prior, lower=r.lower, upper=r.upper)
        params.append(
            EffectParameter(
                name=name,
                unit=spec.unit,
                lower=r.lower,
                upper=r.upper,
                prior=prior,
                typical=part.typical(name),
                description=r.description,
                neutral=spec.default if r.signed else None,
                negligible=r.negligible,
                vanishes_at_upper=r.vanishes_at_upper,
            )
        )
    return Effect(
        name=part.name,
        description=part.description,
        law=part.law,
        parameters=tuple(params),
        option=min(part.options),
        option_parameters=dict(part.options),
        signature=part.signature,
        phases=part.phases,
    )


def _follow_parts(event: str, part: object) -> None:
    # keep the catalog in step with the effect parts registered later
    if not isinstance(part, parts.Effect):
        return
    if event == "register":
        register_effect(catalog_entry(part), replace=True)
    else:
        _EFFECTS.pop(part.name, None)


for _part in parts.EFFECTS.values():
    register_effect(catalog_entry(_part))
parts.add_listener(_follow_parts)
