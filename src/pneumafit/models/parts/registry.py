"""The part types, their registries and the read-only views derived from them.

See :mod:`pneumafit.models.parts` for what a part is and its limits. This
module holds the frozen dataclasses (:class:`HeatLaw`, :class:`ValveLaw`,
:class:`FrictionLaw`, :class:`Effect` with its :class:`FitRange` and
:class:`SignatureTerm`), the four registries, the ``register_*`` /
``unregister_*`` functions that validate a part against the parameter table
(:data:`pneumafit.models.layout.SPECS`) and the configuration layout, and
:class:`RegistryView` / :class:`~pneumafit.models.layout.LiveTuple`, the live read-only tables the
older modules export (``EFFECT_SLOTS``, ``HEAT_LAWS`` codes, ``MODELS``, the
model colours, ...).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Generic, NamedTuple, TypeVar

from pneumafit.errors import PneumafitInputError
from pneumafit.models.layout import (
    C_AIRPROPS,
    C_BLOCKED,
    C_CHAMBER,
    C_FRICTION_LAW,
    C_HEAT,
    C_INPUT,
    C_INPUT_HOLD,
    C_PART_EFFECTS,
    C_STATIC_FLOW,
    C_VALVE_LAW,
    EFFECT_STATE_SLOTS,
    NCFG,
    PART_PARAMETER_GROUPS,
    SPECS,
    STATE_NAMES,
    LiveTuple,
    P,
    ParameterSpec,
    _append_parameter,
    _remove_last_parameter,
)

__all__ = [
    "EFFECTS",
    "FRICTION_LAWS",
    "HEAT_LAWS",
    "KERNEL_FRICTION_CODES",
    "KERNEL_HEAT_CODES",
    "KERNEL_VALVE_CODES",
    "MOVED_RECORDINGS",
    "PRIOR_KINDS",
    "VALVE_LAWS",
    "Effect",
    "FitRange",
    "FrictionLaw",
    "HeatLaw",
    "LiveTuple",
    "RegistryView",
    "SignatureTerm",
    "ValveLaw",
    "add_listener",
    "model_names",
    "register_effect",
    "register_friction_law",
    "register_heat_law",
    "register_parameter",
    "register_valve_law",
    "remove_listener",
    "unregister_effect",
    "unregister_friction_law",
    "unregister_heat_law",
    "unregister_parameter",
    "unregister_valve_law",
]

#: What an effect's parameters can move (:attr:`Effect.moves`): charge/discharge
#: tests with the piston clamped, and tests where the piston moves.
MOVED_RECORDINGS: frozenset[str] = frozenset({"blocked", "motion"})

#: Prior kinds of a :class:`FitRange` (the discovery catalog's ``EffectPrior``).
PRIOR_KINDS: tuple[str, ...] = ("log-uniform", "half-normal", "uniform")

#: Heat-law codes the compiled kernel has a branch for (polytropic, constant
#: lambda, convection); a law with another code brings its ``kernel``.
KERNEL_HEAT_CODES: frozenset[int] = frozenset({0, 1, 2})
#: Valve-law codes the compiled kernel has a branch for (ISO 6358 and the
#: measured map); another code is a law with its own kernel code
#: (``ValveLaw.kernel``), called through ``kernel.part_valve``.
KERNEL_VALVE_CODES: frozenset[int] = frozenset({0, 1})
#: Friction-law codes the compiled kernel has a branch for (the switch model
#: and LuGre); another code is a law with its own kernel code
#: (``FrictionLaw.kernel``), called through ``kernel.part_friction``.
KERNEL_FRICTION_CODES: frozenset[int] = frozenset({0, 1})

#: Configuration slots that are not an effect's: the laws and the experiment.
_RESERVED_SLOTS = {
    C_HEAT: "heat law",
    C_BLOCKED: "blocked piston",
    C_CHAMBER: "chamber under test",
    C_INPUT: "input mode",
    C_AIRPROPS: "air properties",
    C_STATIC_FLOW: "static flow",
    C_VALVE_LAW: "valve law",
    C_FRICTION_LAW: "friction law",
    C_INPUT_HOLD: "input hold",
    C_PART_EFFECTS: "effects with kernel code from outside the package",
}


def _check_parameters(where: str, names: Sequence[str]) -> None:
    """Every name is in the parameter table, once."""
    if len(set(names)) != len(names):
        raise PneumafitInputError(
            f"{where}: parameters: expected distinct names, found {list(names)}"
        )
    unknown = [n for n in names if n not in SPECS]
    if unknown:
        raise PneumafitInputError(
            f"{where}: parameters: expected names in pneumafit.models.PARAMETER_SPECS "
            f"(models/layout.py), found unknown {unknown}"
        )


def _check_values(where: str, values: Mapping[str, float], allowed: Sequence[str]) -> None:
    """Starting values: parameters of the part, inside the table's bounds."""
    for name, value in values.items():
        if name not in allowed:
            raise PneumafitInputError(
                f"{where}: start: expected parameters of the part {list(allowed)}, found {name!r}"
            )
        spec = SPECS[name]
        if not spec.lower <= float(value) <= spec.upper:
            raise PneumafitInputError(
                f"{where}: start {name}: expected a value in [{spec.lower:g}, {spec.upper:g}] "
                f"{spec.unit}, found {value!r}"
            )


# ----------------------------------------------------------------- laws
@dataclass(frozen=True)
class HeatLaw:
    """A heat-transfer law of the chambers (paper eqs. 8, 9, 14).

    Attributes
    ----------
    name : str
        Name; also the model name of the structure with this law
        (:data:`pneumafit.models.MODELS`).
    code : int
        Value of the configuration slot ``C_HEAT`` the compiled kernel
        branches on (:func:`pneumafit.models.kernel.rhs`).
    parameters : tuple of str
        Parameters the law uses, names in
        :data:`pneumafit.models.PARAMETER_SPECS` (unit, bounds and default
        come from there).
    description : str
        One line.
    label : str
        Display label for figures and reports.
    colour : str
        Matplotlib colour of the model in the comparison figures and the
        report (measured data are black).
    order : int
        Position of the model in model lists (comparison, report): lower first.
    starts : tuple of mapping of str to float
        Starting values of the staged fit's heat stage (SI; parameter names
        of ``parameters``), :func:`pneumafit.identification.starts.heat_starts`.
    extensions : tuple of str
        Further parameters the law uses, held at their table default (the law
        as written) unless the heat stage's likelihood-ratio test frees them,
        e.g. ``heat_area_ends``, the exchange area's convention.
    kernel : numba function or None
        The law's compiled code when it is not one of the kernel's own
        (codes outside :data:`KERNEL_HEAT_CODES`): an ``@njit`` function
        ``lam(p, pres, temp, t_wall) -> float``, lambda (W/m^2/K) from the
        parameter vector (SI, ``layout.P``), the chamber pressure (Pa) and
        the gas and wall temperatures (K); it may not allocate arrays
        (:mod:`pneumafit.models.part_kernel`). None: the kernel's branch
        (built-in laws), or a law known to the Python side only, whose
        structure cannot be simulated.
    c_code : str or None
        The same law in C, for the FMU (:mod:`pneumafit.outputs.fmu`): the
        body of ``double law(const double *p, double pres, double temp,
        double t_wall)``, which returns lambda (W/m^2/K) and reads the
        parameters as ``p[PF_P_<name>]`` (``<math.h>`` is included). None:
        an FMU of a structure with this law is refused. Only a law with
        ``kernel`` code takes one.
    """

    name: str
    code: int
    parameters: tuple[str, ...]
    description: str
    label: str
    colour: str
    order: int
    starts: tuple[Mapping[str, float], ...] = ()
    extensions: tuple[str, ...] = ()
    kernel: Callable[..., float] | None = field(default=None, compare=False)
    c_code: str | None = field(default=None, compare=False)


@dataclass(frozen=True)
class _Law:
    """What every law of a configuration slot holds (see the subclasses).

    Attributes
    ----------
    name : str
        Name (the ``ModelStructure`` field's value).
    code : int
        Value of the law's configuration slot (``kernel.*`` codes).
    parameters : tuple of str
        Parameters the law uses, names in ``PARAMETER_SPECS``.
    description : str
        One line.
    """

    name: str
    code: int
    parameters: tuple[str, ...]
    description: str


@dataclass(frozen=True)
class ValveLaw(_Law):
    """A servo-valve law (configuration slot ``C_VALVE_LAW``, ``kernel.VALVE_*``;
    ``ModelStructure.valve``); the attributes of every law, and:

    Attributes
    ----------
    roughness : callable or None
        The law's joint smoothness prior, or None: ``roughness(values)``
        takes the law's parameters by name (floats or arrays of n sets) and
        returns the prior's whitened residuals, shape (n, n_terms); the log
        prior is -sum(r^2) / 2. Parameter sets add it to their priors when
        one of the law's parameters is free
        (:meth:`pneumafit.identification.ParameterSet.log_prior`).
    kernel : numba njit function or None
        The compiled flows of a law registered from outside the package
        (codes outside :data:`KERNEL_VALVE_CODES`): an ``@njit`` function
        ``flows(u, pres, temp, p_s, p) -> (q_net, h_in, q_supply)``, from the
        command u (V), the chamber's pressure (Pa) and gas temperature (K),
        the supply pressure (Pa) and the parameter vector p (SI,
        ``layout.P``): the net mass flow into the chamber (kg/s), the
        enthalpy it carries as sum q_i T_i (kg K/s) and the flow drawn from
        supply (kg/s), as :func:`pneumafit.physics.valve.valve_flows`. It may
        not allocate arrays (:mod:`pneumafit.models.part_kernel`). None: the
        kernel's branch (built-in laws), or a law known to the Python side
        only, whose structure cannot be simulated.
    starts : tuple of mapping
        Starting values of the law's parameters for the valve stage (each a
        mapping name -> SI value; the table's defaults for the rest). The
        valve stage fits every parameter of the group ``"valve"`` the law
        names from its starts (an outside law's own parameters).
    c_code : str or None
        The same flows in C, for the FMU (:mod:`pneumafit.outputs.fmu`): the
        body of ``void flows(double u, double pres, double temp, double p_s,
        const double *p, double *out)``, which sets ``out[0]``, ``out[1]``,
        ``out[2]`` to what ``kernel`` returns (q_net, h_in, q_supply) and
        reads the parameters as ``p[PF_P_<name>]``. None: an FMU of a
        structure with this law is refused. Only a law with ``kernel`` code
        takes one.
    """

    roughness: Callable[[Mapping[str, Any]], Any] | None = None
    kernel: Callable[..., tuple[float, float, float]] | None = field(default=None, compare=False)
    starts: tuple[Mapping[str, float], ...] = ()
    c_code: str | None = field(default=None, compare=False)


@dataclass(frozen=True)
class FrictionLaw(_Law):
    """A friction law of the piston (configuration slot ``C_FRICTION_LAW``,
    ``kernel.FRICTION_*``; ``ModelStructure.friction``); the attributes of
    every law, and:

    Attributes
    ----------
    joint_prior : callable or None
        A prior over several of the law's parameters, or None: called as a
        valve law's ``roughness`` (the whitened residuals, shape (n, n_terms);
        the log prior is -sum(r^2) / 2), and added by parameter sets when one
        of the law's parameters is free, e.g. the breakaway prior on
        F_s / F_c (:mod:`pneumafit.physics.friction_prior`).
    kernel : numba njit function or None
        The compiled friction force of a law registered from outside the
        package (codes outside :data:`KERNEL_FRICTION_CODES`): an ``@njit``
        function ``force(v, f_s, f_c, x, p) -> float``, the friction force
        (N) against the motion, along +y, from the piston speed v (m/s), the
        static and Coulomb levels f_s and f_c (N, with the seal-friction and
        direction-asymmetry effects applied when they are on), the state x
        (``layout.X_*``) and the parameter vector p (SI, ``layout.P``). It
        must be a smooth function of v (no stuck mode, no events: the piston
        then obeys M dv/dt = F_d - F), and may not allocate arrays
        (:mod:`pneumafit.models.part_kernel`). None: the kernel's branch
        (built-in laws), or a law known to the Python side only, whose
        structure cannot be simulated.
    starts : tuple of mapping
        Starting values of the law's own parameters for the friction stage
        (each a mapping name -> SI value; the switch model's levels seed the
        rest).
    state_rate : numba njit function or None
        A law with a state of its own (pre-sliding: a bristle deflection, a
        Dahl or elasto-plastic state): an ``@njit`` function ``rate(v, f_s,
        f_c, x, p, max_rate) -> float``, the state's time derivative, with
        the arguments of ``kernel`` and the largest relaxation rate (1/s)
        the fixed step can follow (``LUGRE_RATE_LIMIT / h``: a law whose
        state relaxes faster, as LuGre's bristles at high speed, limits its
        rate there as :func:`pneumafit.physics.friction.lugre_friction`
        does). The state is the bristle slot ``x[layout.X_Z]``, which
        ``kernel`` reads too; it starts at 0 (or at the experiment's initial
        ``z_f``) and is frozen in blocked tests. The integration step bounds
        the state's mode by central differences of ``kernel`` and
        ``rate`` at rest (:func:`pneumafit.models.kernel.stiffness_bound`).
        None: no state (only with ``kernel``).
    c_code : str or None
        The same force in C, for the FMU (:mod:`pneumafit.outputs.fmu`): the
        body of ``double force(double v, double f_s, double f_c, const double
        *x, const double *p)``, reading the state as ``x[PF_X_<name>]`` (the
        law's own, the bristle slot, ``x[PF_X_z_f]``) and the parameters as
        ``p[PF_P_<name>]`` (a law with ``stuck``: ``double force(double v,
        double s, double f_s, double f_c, const double *x, const double
        *p)``, s the sliding direction). None: an FMU of a structure with
        this law is refused. Only a law with ``kernel`` code takes one.
    c_state_rate : str or None
        With ``state_rate`` and ``c_code``: the body of ``double rate(double
        v, double f_s, double f_c, const double *x, const double *p, double
        max_rate)``, ``state_rate`` in C.
    stuck : bool
        With ``kernel``: the law is the sliding force of the switch model's
        modes instead of a smooth law. The piston sticks at rest while the
        driving force stays within the static level f_s, breaks away above
        it and comes to rest where v crosses 0 with the drive within f_s,
        and the integrator locates both events, as for the switch model;
        ``kernel`` is then ``force(v, s, f_s, f_c, x, p) -> float``, called
        only while sliding, s = +1 or -1 the sliding direction (v may be 0,
        at breakaway, or of the other sign within a step before the event).
        A Coulomb-type law that jumps at v = 0 belongs here. No state of its
        own (``state_rate``); its ``c_code`` is then the body of ``double
        force(double v, double s, double f_s, double f_c, const double *x,
        const double *p)``, which the FMU's C model calls in the same modes.
    """

    joint_prior: Callable[[Mapping[str, Any]], Any] | None = None
    kernel: Callable[..., float] | None = field(default=None, compare=False)
    starts: tuple[Mapping[str, float], ...] = ()
    state_rate: Callable[..., float] | None = field(default=None, compare=False)
    c_code: str | None = field(default=None, compare=False)
    c_state_rate: str | None = field(default=None, compare=False)
    stuck: bool = False

    @property
    def modes(self) -> bool:
        """Whether the law has the switch model's stuck mode and events (the
        switch model itself, or ``stuck``); the kernel's ``friction_modes``."""
        return self.stuck or self.code == 0  # 0: the switch model (kernel.FRICTION_SWITCH)


# ----------------------------------------------------------------- effects
@dataclass(frozen=True)
class FitRange:
    """What discovery assumes about one effect parameter (the catalog's facts).

    Attributes
    ----------
    parameter : str
        Parameter name (``PARAMETER_SPECS``).
    lower, upper : float
        Fitting bounds (parameter unit): what the effect can plausibly be,
        inside the table's physical bounds and usually tighter.
    prior : {"log-uniform", "half-normal", "uniform"}
        Prior kind; log-uniform and uniform priors span [lower, upper].
    scale : float
        Scale of a half-normal prior (parameter unit); NaN otherwise.
    description : str
        One line on the parameter's role in the effect.
    signed : bool
        The effect acts on either side of its neutral value (the
        parameter's default, strictly inside [lower, upper]): a friction
        asymmetry around 0, an area factor around 1.
    negligible : float
        For a signed parameter, the largest departure from its neutral value
        that discovery counts as no effect (parameter unit); NaN: its
        generic margin.
    vanishes_at_upper : bool
        For a one-sided parameter, the effect vanishes at the upper bound
        (the wall's heat capacity: an infinite one holds the wall at its
        temperature); False: at the lower bound.
    """

    parameter: str
    lower: float
    upper: float
    prior: str = "log-uniform"
    scale: float = math.nan
    description: str = ""
    signed: bool = False
    negligible: float = math.nan
    vanishes_at_upper: bool = False


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
    """An optional effect of the actuator model, switched on by a configuration slot.

    Attributes
    ----------
    name : str
        Name (``ModelStructure.effects``, the discovery catalog, ``--effect``).
    slot : int or None
        Configuration slot (``layout.C_*``) the compiled kernel reads; the
        structure writes the option value there. None: the kernel has no
        slot for the effect (a part defined outside the package): it brings
        its ``kernel``, or it is known to the Python side only and a
        structure with it switched on cannot make a configuration vector.
    parameters : tuple of str
        All its parameters over all options (``PARAMETER_SPECS`` names).
    description : str
        One line.
    law : str
        The law as the kernel implements it (SI; symbols of docs/physics.md).
    principal : str
        The parameter that ``--effect NAME=VALUE`` sets, whose regression
        coefficient attribution reports, and whose departure from its
        default switches the effect's contribution on.
    rig_default : float
        The virtual rig's magnitude of ``principal`` (SI) when the effect is
        named without a value; also the catalog's typical value.
    fit : tuple of FitRange
        Discovery's fitting range and prior, one per parameter.
    coefficient_unit : str
        Unit of attribution's regression coefficient (the principal
        parameter's, or what the coefficient is when it is not the
        parameter itself).
    options : mapping of int to tuple of str
        Option value -> the parameters that variant uses. Empty (the
        default): the single option 1 with every parameter.
    signature : tuple of SignatureTerm
        Regressors for discovery's sparse regression.
    phases : tuple of str
        Phases of a test (``pneumafit.discovery.phases.PHASES``) where a
        missing effect shows most in the residuals.
    inverse_coefficient : bool
        Attribution's coefficient is 1 / principal (the wall's capacity).
    start_floor : float
        Smallest refit start of the principal parameter taken from a
        coefficient (SI; 0: none).
    moves : frozenset of str
        Recordings whose simulation its parameters can change, among
        :data:`MOVED_RECORDINGS`: ``"blocked"`` (charge/discharge tests,
        piston clamped) and ``"motion"`` (step tests). Flow tests are never
        moved by an effect: the kernel evaluates their static
        characteristic from the valve law alone. Default: both; an effect
        that acts only on the piston's force balance (a friction term)
        declares ``{"motion"}``, so a finite-difference Jacobian does not
        re-simulate the blocked tests for it
        (:meth:`pneumafit.identification.Problem.unaffected`).
    kernel : numba function or None
        The effect's compiled code when it has no slot (``slot=None``): an
        ``@njit`` function ``eff(x, p) -> (q_P, H_P, q_N, H_N, q_atm, F)``
        of the state (``layout.X_*``) and the parameters (SI): mass flows
        into chambers P and N (kg/s), the enthalpy they carry as sum q_i T_i
        (kg K/s), mass sent to atmosphere (kg/s) and a force on the piston
        along +y (N); it may not allocate arrays
        (:mod:`pneumafit.models.part_kernel`). With ``options`` other than
        the single option 1 it takes the structure's option value as a third
        argument, ``eff(x, p, option)`` (an int >= 1), and so does its
        ``state_rate``.
    states : tuple of int
        The state slots the effect claims, among
        ``layout.EFFECT_STATE_SLOTS`` (X_E0, X_E1, X_E2), for states of its
        own that its ``kernel`` reads from ``x`` (a wall temperature, a
        spool's position and speed, a leak that opens over time); none by
        default. No two registered effects claim the same slot, so the
        effects with states run together while they claim three slots or
        fewer between them.
    state_rate : numba njit function or None
        With ``states``: an ``@njit`` function ``rate(x, p)``, the states'
        time derivatives (their units per second): a float for one state, a
        tuple of as many floats as ``states``, in their order, for more.
        The states start at 0 (from the experiment's initial state when it
        gives them) and evolve in every test, blocked or not.
    c_code : str or None
        The same effect in C, for the FMU (:mod:`pneumafit.outputs.fmu`):
        the body of ``void eff(const double *x, const double *p, double
        *out)``, which sets ``out[0]`` ... ``out[5]`` to what ``kernel``
        returns, in its order, and reads the state as ``x[PF_X_<name>]``
        (``layout.STATE_NAMES``; the effect's own state is ``x[PF_X_e_0]``
        for slot X_E0, ``x[PF_X_e_1]`` for X_E1, ...),
        the parameters as ``p[PF_P_<name>]`` and the structure's option value
        as the ``const int option`` the function declares before it. None: an FMU of a
        structure with this effect switched on is refused. Only an effect
        with ``kernel`` code takes one.
    c_state_rate : str or None
        With ``states`` and ``c_code``: ``state_rate`` in C, the body of
        ``double rate(const double *x, const double *p)`` for one state, of
        ``void rate(const double *x, const double *p, double *out)``
        setting ``out[0]``, ``out[1]``, ... in the order of ``states`` for
        more.
    """

    name: str
    slot: int | None
    parameters: tuple[str, ...]
    description: str
    law: str
    principal: str
    rig_default: float
    fit: tuple[FitRange, ...]
    coefficient_unit: str
    options: Mapping[int, tuple[str, ...]] = field(default_factory=dict, hash=False)
    signature: tuple[SignatureTerm, ...] = ()
    phases: tuple[str, ...] = ()
    inverse_coefficient: bool = False
    start_floor: float = 0.0
    moves: frozenset[str] = frozenset({"blocked", "motion"})
    kernel: Callable[..., tuple[float, ...]] | None = field(default=None, compare=False)
    states: tuple[int, ...] = ()
    state_rate: Callable[..., Any] | None = field(default=None, compare=False)
    c_code: str | None = field(default=None, compare=False)
    c_state_rate: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        options = {int(k): tuple(v) for k, v in self.options.items()} or {1: self.parameters}
        object.__setattr__(self, "options", MappingProxyType(options))

    @property
    def option_values(self) -> tuple[int, ...]:
        """Values ``ModelStructure.effects`` accepts for the effect (0 = off)."""
        return (0, *sorted(self.options))

    def typical(self, name: str) -> float:
        """Typical value of a parameter: ``rig_default`` for the principal, else its default."""
        return self.rig_default if name == self.principal else SPECS[name].default

    def fit_range(self, name: str) -> FitRange:
        """The :class:`FitRange` of the parameter ``name``."""
        for r in self.fit:
            if r.parameter == name:
                return r
        raise PneumafitInputError(f"effect {self.name!r}: fit range: expected one of "
                         f"{list(self.parameters)}, found {name!r}")  # fmt: skip


# ----------------------------------------------------------------- registries
_Part = TypeVar("_Part")
_V = TypeVar("_V")

_HEAT: dict[str, HeatLaw] = {}
_VALVE: dict[str, ValveLaw] = {}
_FRICTION: dict[str, FrictionLaw] = {}
_EFFECTS: dict[str, Effect] = {}

#: Registered heat laws by name, in registration order (read-only).
HEAT_LAWS: Mapping[str, HeatLaw] = MappingProxyType(_HEAT)
#: Registered valve laws by name (read-only).
VALVE_LAWS: Mapping[str, ValveLaw] = MappingProxyType(_VALVE)
#: Registered friction laws by name (read-only).
FRICTION_LAWS: Mapping[str, FrictionLaw] = MappingProxyType(_FRICTION)
#: Registered effects by name (read-only).
EFFECTS: Mapping[str, Effect] = MappingProxyType(_EFFECTS)

_LISTENERS: list[Callable[[str, object], None]] = []


def add_listener(listener: Callable[[str, object], None]) -> None:
    """Call ``listener(event, part)`` on every later registration change.

    ``event`` is ``"register"`` or ``"unregister"``. A listener that raises
    on ``"register"`` refuses the part: the registration is undone and the
    error propagates (the discovery catalog checks an effect's phases this
    way).
    """
    _LISTENERS.append(listener)


def remove_listener(listener: Callable[[str, object], None]) -> None:
    """Stop calling ``listener``."""
    _LISTENERS.remove(listener)


def _commit(registry: dict[str, Any], part: Any, replace: bool) -> Any:
    old = registry.get(part.name)
    registry[part.name] = part
    try:
        for listener in list(_LISTENERS):
            listener("register", part)
    except Exception:
        if old is None:
            del registry[part.name]
        else:
            registry[part.name] = old
            for listener in list(_LISTENERS):
                listener("register", old)
        raise
    return part


def _remove(registry: dict[str, Any], kind: str, name: str) -> Any:
    try:
        part = registry.pop(name)
    except KeyError:
        raise PneumafitInputError(f"unregister {kind}: expected one of {sorted(registry)}, "
                         f"found {name!r}") from None  # fmt: skip
    for listener in list(_LISTENERS):
        listener("unregister", part)
    return part


def _check_law(registry: Mapping[str, Any], part: Any, kind: str, replace: bool) -> str:
    where = f"register {kind} {part.name!r}"
    if not part.name or not isinstance(part.name, str):
        raise PneumafitInputError(
            f"register {kind}: name: expected a non-empty str, found {part.name!r}"
        )
    if part.name in registry and not replace:
        raise PneumafitInputError(
            f"{where}: a {kind} of this name is registered; pass replace=True"
        )
    if not isinstance(part.code, int) or part.code < 0:
        raise PneumafitInputError(f"{where}: code: expected an int >= 0, found {part.code!r}")
    taken = {p.code: p.name for p in registry.values() if p.name != part.name}
    if part.code in taken:
        raise PneumafitInputError(
            f"{where}: code {part.code}: expected a code no other {kind} has, found it "
            f"taken by {taken[part.code]!r}"
        )
    _check_parameters(where, part.parameters)
    return where


def _check_own_code(where: str, law: Any, codes: frozenset[int]) -> None:
    """A law's kernel code is an njit function, and a law with one takes a
    code outside ``codes`` (the kernel's own branches)."""
    _check_kernel(where, law.kernel)
    rate = getattr(law, "state_rate", None)
    _check_kernel(where, rate, "state_rate")
    if rate is not None and law.kernel is None:
        raise PneumafitInputError(
            f"{where}: state_rate: expected it only with kernel code (the force that "
            "reads the state), found no kernel"
        )
    if law.kernel is not None and law.code in codes:
        raise PneumafitInputError(
            f"{where}: kernel: expected a code outside {sorted(codes)} (the "
            f"kernel's own branches), found {law.code}"
        )
    _check_law_returns(where, law)


def _check_effect_states(where: str, effect: Effect) -> None:
    """An effect's states: distinct slots among ``EFFECT_STATE_SLOTS``, no
    other registered effect's, and a compiled rate exactly when it has some
    (and kernel code that reads them); what the rate returns is checked by
    :func:`_check_effect_returns`."""
    _check_kernel(where, effect.state_rate, "state_rate")
    states = tuple(effect.states)
    if not states:
        if effect.state_rate is not None:
            raise PneumafitInputError(
                f"{where}: state_rate: expected it only with states, found no states"
            )
        return
    if effect.kernel is None or effect.state_rate is None:
        missing = "kernel" if effect.kernel is None else "state_rate"
        raise PneumafitInputError(
            f"{where}: states: expected kernel code and a state_rate with them, found no {missing}"
        )
    if len(set(states)) != len(states) or not set(states) <= set(EFFECT_STATE_SLOTS):
        raise PneumafitInputError(
            f"{where}: states: expected distinct slots among {list(EFFECT_STATE_SLOTS)} "
            f"(layout.X_E0 to X_E2), found {list(states)}"
        )
    taken = {s: e.name for e in _EFFECTS.values() if e.name != effect.name for s in e.states}
    clash = sorted(set(states) & set(taken))
    if clash:
        raise PneumafitInputError(
            f"{where}: states: expected slots no other effect has, found {clash[0]} taken by "
            f"{taken[clash[0]]!r}"
        )


class ProbePoint(NamedTuple):
    """A plausible operating point on which registration calls a part's
    Python function once (:func:`_check_returns`) and
    :mod:`pneumafit.models.part_kernel` its compiled hooks: mid-stroke,
    moving at 50 mm/s, 3 bar and 20 degC in both chambers and at the walls,
    2 V of command, 7 bar of supply, the friction levels 50 and 40 N; every
    other state 0, the parameters at their table defaults."""

    x: Any  #: state vector, every slot (the effects' included)
    p: Any  #: parameter vector (SI, layout.P)
    v: float = 0.05  #: piston speed (m/s)
    f_s: float = 50.0  #: static friction level (N)
    f_c: float = 40.0  #: Coulomb friction level (N)
    u: float = 2.0  #: valve command (V)
    pres: float = 3.0e5  #: chamber pressure (Pa)
    temp: float = 293.15  #: gas temperature (K)
    t_wall: float = 293.15  #: wall temperature (K)
    p_s: float = 7.0e5  #: supply pressure (Pa)


def probe_point() -> ProbePoint:
    """The :class:`ProbePoint`, its vectors built from the layout now (the
    parameters registered so far)."""
    import numpy as np

    pt = ProbePoint(np.zeros(len(STATE_NAMES)), np.empty(len(P)))
    state = {"y": 0.1, "v": pt.v, "p_N": pt.pres, "p_P": pt.pres, "T_N": pt.temp,
             "T_P": pt.temp, "Tw_N": pt.t_wall, "Tw_P": pt.t_wall}  # fmt: skip
    for name, value in state.items():
        pt.x[STATE_NAMES.index(name)] = value
    for name, index in P.items():
        pt.p[index] = SPECS[name].default
    return pt


def _check_returns(where: str, key: str, function: Any, args: tuple[Any, ...], n: int,
                   what: str = "") -> None:  # fmt: skip
    """A part's compiled function returns one number (``n`` = 1) or a tuple
    of ``n``: checked by calling its Python function once on ``args`` (the
    probe operating point), so that a wrong return is named at registration
    rather than as a typing error of the compiled simulator. A call that
    fails in Python (a law that divides by a state that is 0 there, say) is
    left to the compiler, which types the same return. ``what`` names the
    tuple's terms in the message."""
    import numpy as np

    try:
        with np.errstate(all="ignore"):
            out = function.py_func(*args)
    except Exception:  # the compiler reports the law's own errors
        return
    found = len(out) if isinstance(out, tuple) else None
    if (n == 1) != (found is None) or (n > 1 and found != n):
        expected = "one number" if n == 1 else f"a tuple of {n} numbers"
        raise PneumafitInputError(
            f"{where}: {key}: expected {expected}{f' ({what})' if what else ''}, found "
            + ("a number" if found is None else f"a tuple of {found}")
        )


def _check_law_returns(where: str, law: Any) -> None:
    """What a heat, valve or friction law's kernel code (and a friction law's
    state rate) returns, on the probe operating point (:func:`_check_returns`)."""
    if law.kernel is None:
        return
    pt = probe_point()
    x, p, v, f_s, f_c = pt.x, pt.p, pt.v, pt.f_s, pt.f_c
    if isinstance(law, HeatLaw):
        args = (p, pt.pres, pt.temp, pt.t_wall)
        _check_returns(where, "kernel", law.kernel, args, 1, "lambda")
    elif isinstance(law, ValveLaw):
        args = (pt.u, pt.pres, pt.temp, pt.p_s, p)
        _check_returns(where, "kernel", law.kernel, args, 3, "q_net, h_in, q_supply")
    elif isinstance(law, FrictionLaw):
        args = (v, 1.0, f_s, f_c, x, p) if law.stuck else (v, f_s, f_c, x, p)
        _check_returns(where, "kernel", law.kernel, args, 1, "the friction force")
        if law.state_rate is not None:
            _check_returns(where, "state_rate", law.state_rate, (v, f_s, f_c, x, p, 1.0e4), 1)


def _check_effect_returns(where: str, effect: Effect) -> None:
    """What an effect's kernel code and state rate return, on the probe
    operating point (:func:`_check_returns`)."""
    pt = probe_point()
    args = (pt.x, pt.p) if set(effect.options) == {1} else (pt.x, pt.p, min(effect.options))
    if effect.kernel is not None:
        _check_returns(where, "kernel", effect.kernel, args, 6, "q_P, H_P, q_N, H_N, q_atm, F")
    if effect.state_rate is not None and effect.states:
        n = len(effect.states)
        _check_returns(where, "state_rate", effect.state_rate, args, n,
                       "one per state, in the order of states" if n > 1 else "")  # fmt: skip


def _check_c_code(where: str, part: Any) -> None:
    """A part's C code for the FMU (``c_code`` and, for an effect or a friction
    law with a state of its own, ``c_state_rate``): a non-empty string, only
    beside kernel code; a state rate exactly when the part has a state and
    ``c_code``."""
    for key in ("c_code", "c_state_rate"):
        code = getattr(part, key, None)
        if code is None:
            continue
        if not isinstance(code, str) or not code.strip():
            raise PneumafitInputError(
                f"{where}: {key}: expected the body of a C function as a non-empty string "
                f"or None, found {code!r}"
            )
        if part.kernel is None:
            raise PneumafitInputError(
                f"{where}: {key}: expected it only with kernel code (the C code is the "
                "kernel code's port), found no kernel"
            )
    # an effect's state is its states; a friction law's, its state_rate
    stateful = bool(getattr(part, "states", ())) or (
        isinstance(part, FrictionLaw) and part.state_rate is not None
    )
    if getattr(part, "c_state_rate", None) is not None and (not stateful or part.c_code is None):
        raise PneumafitInputError(
            f"{where}: c_state_rate: expected it only with a state of its own and c_code, "
            f"found {'a state' if stateful else 'no state'} and c_code "
            f"{'set' if part.c_code else 'None'}"
        )
    if stateful and part.c_code is not None and part.c_state_rate is None:
        raise PneumafitInputError(
            f"{where}: c_code: expected a c_state_rate with it for the part's state, found none"
        )


def _check_kernel(where: str, function: object, key: str = "kernel") -> None:
    """A part's kernel code (its field ``key``) is a numba njit function (or None)."""
    if function is not None and not (
        callable(function) and callable(getattr(function, "py_func", None))
    ):
        raise PneumafitInputError(
            f"{where}: {key}: expected a numba @njit function or None, "
            f"found {type(function).__name__}"
        )


def register_parameter(spec: ParameterSpec) -> ParameterSpec:
    """Add a parameter of a part from outside the package to the parameter table.

    The table (``layout.PARAMETER_SPECS``, ``PARAMETER_NAMES``, ``P``,
    ``SPECS``) grows by one at its end; no built-in index moves. Register
    the parameter before the part that names it; the part's kernel code
    reads it at ``layout.P[name]`` (a constant once compiled).

    Checks: an identifier as name that no parameter has; a group of
    :data:`~pneumafit.models.layout.PART_PARAMETER_GROUPS` (``"heat"``,
    ``"valve"``, ``"friction"`` or ``"effect"``: its part's); an SI unit in pint's syntax (``""``:
    dimensionless); finite bounds (a fit's box) with the default inside.

    Returns
    -------
    ParameterSpec
        ``spec``.

    Raises
    ------
    PneumafitInputError
        A failed check; nothing is registered.
    """
    where = f"register parameter {getattr(spec, 'name', spec)!r}"
    if not isinstance(spec, ParameterSpec):
        raise PneumafitInputError(
            f"register parameter: expected a ParameterSpec, found {type(spec).__name__}"
        )
    if not spec.name.isidentifier():
        raise PneumafitInputError(f"{where}: name: expected an identifier, found {spec.name!r}")
    if spec.name in SPECS:
        raise PneumafitInputError(f"{where}: expected a new name, found one the table has")
    if spec.group not in PART_PARAMETER_GROUPS:
        raise PneumafitInputError(
            f"{where}: group: expected one of {list(PART_PARAMETER_GROUPS)}, found {spec.group!r}"
        )
    from pneumafit.campaign.units import UnitError, parse_unit, ureg

    try:
        unit = parse_unit(spec.unit).unit
    except UnitError as exc:
        raise PneumafitInputError(
            f"{where}: unit: expected {exc.expected}, found {exc.found}"
        ) from None
    factor = float(ureg.Quantity(1.0, unit).to_base_units().magnitude)
    if not math.isclose(factor, 1.0, rel_tol=1e-12):
        raise PneumafitInputError(
            f"{where}: unit: expected an SI unit (the kernel computes in SI), found "
            f"{spec.unit!r} ({factor:g} of its SI unit)"
        )
    bounds = (spec.lower, spec.default, spec.upper)
    if not all(math.isfinite(v) for v in bounds) or not spec.lower <= spec.default <= spec.upper \
            or not spec.lower < spec.upper:  # fmt: skip
        raise PneumafitInputError(
            f"{where}: expected finite bounds lower < upper with the default inside, found "
            f"[{spec.lower:g}, {spec.upper:g}] and default {spec.default:g}"
        )
    _append_parameter(spec)
    return spec


def unregister_parameter(name: str) -> ParameterSpec:
    """Remove the last parameter registered from outside (for tests and notebooks).

    Raises
    ------
    PneumafitInputError
        ``name`` is not the last one registered, or a registered part uses it.
    """
    users = [
        part.name
        for registry in (_HEAT, _VALVE, _FRICTION, _EFFECTS)
        for part in registry.values()
        if name in part.parameters or name in getattr(part, "extensions", ())
    ]
    if users:
        raise PneumafitInputError(
            f"unregister parameter {name!r}: expected a parameter no registered part uses, "
            f"found it used by {users}"
        )
    spec = SPECS.get(name)
    try:
        _remove_last_parameter(name)
    except ValueError as exc:
        raise PneumafitInputError(f"unregister parameter: {exc}") from None
    assert spec is not None
    return spec


def register_heat_law(law: HeatLaw, *, replace: bool = False) -> HeatLaw:
    """Add a heat law to :data:`HEAT_LAWS` after checking it.

    Checks: a new name (unless ``replace``), a code no other heat law has,
    parameters in the parameter table, starts naming only its parameters
    within their physical bounds.

    Returns
    -------
    HeatLaw
        ``law``.

    Raises
    ------
    ValueError
        A failed check; nothing is registered.
    """
    where = _check_law(_HEAT, law, "heat law", replace)
    _check_own_code(where, law, KERNEL_HEAT_CODES)
    _check_c_code(where, law)
    if law.extensions:
        _check_parameters(f"{where}: extensions", (*law.parameters, *law.extensions))
    for start in law.starts:
        _check_values(where, start, law.parameters)
    return _commit(_HEAT, law, replace)


def register_valve_law(law: ValveLaw, *, replace: bool = False) -> ValveLaw:
    """Add a valve law to :data:`VALVE_LAWS` (checks as :func:`register_heat_law`).

    A law with ``kernel`` code takes a code outside
    :data:`KERNEL_VALVE_CODES`, and its ``starts`` name only its parameters.
    """
    return _register_slot_law(_VALVE, law, "valve law", KERNEL_VALVE_CODES, replace)


def register_friction_law(law: FrictionLaw, *, replace: bool = False) -> FrictionLaw:
    """Add a friction law to :data:`FRICTION_LAWS` (checks as :func:`register_heat_law`).

    A law with ``kernel`` code takes a code outside
    :data:`KERNEL_FRICTION_CODES`, and its ``starts`` name only its parameters;
    a law with ``stuck`` has kernel code and no ``state_rate``.
    """
    if law.stuck is not False:
        where = f"register friction law {law.name!r}"
        if law.stuck is not True:
            raise PneumafitInputError(
                f"{where}: stuck: expected True or False, found {law.stuck!r}"
            )
        found = [n for n, bad in (("no kernel", law.kernel is None),
                                  ("a state_rate", law.state_rate is not None)) if bad]  # fmt: skip
        if found:
            raise PneumafitInputError(
                f"{where}: stuck: expected kernel code, a sliding force(v, s, f_s, f_c, x, p) "
                f"without a state of its own (state_rate), found {', '.join(found)}"
            )
    return _register_slot_law(_FRICTION, law, "friction law", KERNEL_FRICTION_CODES, replace)


def _register_slot_law(
    registry: dict[str, Any], law: Any, kind: str, codes: frozenset[int], replace: bool
) -> Any:
    """Check a valve or friction law (name, code, parameters, kernel code
    outside ``codes``, starts) and commit it to ``registry``."""
    where = _check_law(registry, law, kind, replace)
    _check_own_code(where, law, codes)
    _check_c_code(where, law)
    for start in law.starts:
        _check_values(where, start, law.parameters)
    return _commit(registry, law, replace)


def register_effect(effect: Effect, *, replace: bool = False) -> Effect:
    """Add an effect to :data:`EFFECTS` after checking it.

    Checks: an identifier as name, new unless ``replace``; a configuration
    slot inside the layout, not a law's or the experiment's, not another
    effect's (or None: no slot, with or without kernel code of its own);
    parameters in the parameter table;
    options >= 1 using only its parameters and together all of them; the
    principal parameter among them with its rig default inside its
    physical bounds; one fit range per parameter, inside the physical
    bounds, with a known prior kind.

    Returns
    -------
    Effect
        ``effect`` (``MY_EFFECT = register_effect(Effect(...))``).

    Raises
    ------
    ValueError
        A failed check, or a listener refusing the effect; nothing is
        registered.
    """
    where = f"register effect {effect.name!r}"
    if not (
        isinstance(effect.moves, frozenset) and effect.moves and effect.moves <= MOVED_RECORDINGS
    ):
        raise PneumafitInputError(
            f"{where}: moves: expected a non-empty frozenset of {sorted(MOVED_RECORDINGS)}, "
            f"found {effect.moves!r}"
        )
    if not effect.name.isidentifier():
        raise PneumafitInputError(
            f"register effect: name: expected an identifier, found {effect.name!r}"
        )
    if effect.name in _EFFECTS and not replace:
        raise PneumafitInputError(
            f"{where}: an effect of this name is registered; pass replace=True"
        )
    _check_kernel(where, effect.kernel)
    if effect.kernel is not None:
        if effect.slot is not None:
            raise PneumafitInputError(
                f"{where}: kernel: expected slot=None for an effect with kernel code of its "
                f"own, found slot {effect.slot!r}"
            )
    _check_effect_states(where, effect)
    _check_effect_returns(where, effect)
    _check_c_code(where, effect)
    if effect.slot is not None:
        if not isinstance(effect.slot, int) or not 0 <= effect.slot < NCFG:
            raise PneumafitInputError(
                f"{where}: slot: expected a configuration slot in [0, {NCFG}) (models/layout.py "
                f"C_*) or None, found {effect.slot!r}"
            )
        if effect.slot in _RESERVED_SLOTS:
            raise PneumafitInputError(
                f"{where}: slot {effect.slot}: expected an effect's slot, found the "
                f"{_RESERVED_SLOTS[effect.slot]}'s"
            )
        taken = {e.slot: e.name for e in _EFFECTS.values() if e.name != effect.name}
        if effect.slot in taken:
            raise PneumafitInputError(
                f"{where}: slot {effect.slot}: expected a slot no other effect has, found it "
                f"taken by {taken[effect.slot]!r}"
            )
    if not effect.parameters:
        raise PneumafitInputError(f"{where}: parameters: expected at least one, found none")
    _check_parameters(where, effect.parameters)
    used: set[str] = set()
    for value, names in effect.options.items():
        extra = sorted(set(names) - set(effect.parameters))
        if value < 1 or extra:
            raise PneumafitInputError(
                f"{where}: option {value}: expected a value >= 1 using parameters of the effect, "
                f"found {'value < 1' if value < 1 else extra}"
            )
        used |= set(names)
    if used != set(effect.parameters):
        raise PneumafitInputError(
            f"{where}: options: expected every parameter used by some option, found "
            f"{sorted(set(effect.parameters) - used)} unused"
        )
    if effect.principal not in effect.parameters:
        raise PneumafitInputError(
            f"{where}: principal: expected one of {list(effect.parameters)}, "
            f"found {effect.principal!r}"
        )
    spec = SPECS[effect.principal]
    if not spec.lower <= effect.rig_default <= spec.upper:
        raise PneumafitInputError(
            f"{where}: rig_default: expected a value in [{spec.lower:g}, {spec.upper:g}] "
            f"{spec.unit}, found {effect.rig_default!r}"
        )
    ranges = [r.parameter for r in effect.fit]
    if sorted(ranges) != sorted(effect.parameters):
        raise PneumafitInputError(
            f"{where}: fit: expected one FitRange per parameter {list(effect.parameters)}, "
            f"found {ranges}"
        )
    for r in effect.fit:
        spec = SPECS[r.parameter]
        if r.prior not in PRIOR_KINDS:
            raise PneumafitInputError(
                f"{where}: fit {r.parameter}: prior: expected one of {PRIOR_KINDS}, "
                f"found {r.prior!r}"
            )
        if not spec.lower <= r.lower < r.upper <= spec.upper:
            raise PneumafitInputError(
                f"{where}: fit {r.parameter}: expected bounds [{r.lower:g}, {r.upper:g}] within "
                f"the physical bounds [{spec.lower:g}, {spec.upper:g}] {spec.unit}"
            )
    return _commit(_EFFECTS, effect, replace)


def unregister_heat_law(name: str) -> HeatLaw:
    """Remove a heat law (for tests and notebooks); returns it."""
    return _remove(_HEAT, "heat law", name)


def unregister_valve_law(name: str) -> ValveLaw:
    """Remove a valve law; returns it."""
    return _remove(_VALVE, "valve law", name)


def unregister_friction_law(name: str) -> FrictionLaw:
    """Remove a friction law; returns it."""
    return _remove(_FRICTION, "friction law", name)


def unregister_effect(name: str) -> Effect:
    """Remove an effect; returns it."""
    return _remove(_EFFECTS, "effect", name)


# ----------------------------------------------------------------- derived tables
class RegistryView(Mapping[str, _V], Generic[_Part, _V]):
    """A live read-only table derived from a registry: name -> ``value(part)``.

    Parameters
    ----------
    source : mapping of str to part
        A registry (:data:`HEAT_LAWS`, :data:`EFFECTS`, ...).
    value : callable
        Part -> the table's value.
    order : callable, optional
        Part -> sort key of the iteration order; default the registry's
        (registration) order.

    A part registered later appears at once. Compares equal to a dict of
    the same items.
    """

    def __init__(
        self,
        source: Mapping[str, _Part],
        value: Callable[[_Part], _V],
        order: Callable[[_Part], Any] | None = None,
    ) -> None:
        self._source = source
        self._value = value
        self._order = order

    def _parts(self) -> list[_Part]:
        parts = list(self._source.values())
        if self._order is not None:
            parts.sort(key=self._order)
        return parts

    def __getitem__(self, key: str) -> _V:
        return self._value(self._source[key])

    def __iter__(self) -> Iterator[str]:
        return iter([p.name for p in self._parts()])  # type: ignore[attr-defined]

    def __len__(self) -> int:
        return len(self._source)

    def __contains__(self, key: object) -> bool:
        return key in self._source

    def __repr__(self) -> str:
        return repr(dict(self.items()))


def model_names() -> tuple[str, ...]:
    """The heat laws' names in model-list order (:attr:`HeatLaw.order`)."""
    return tuple(h.name for h in sorted(_HEAT.values(), key=lambda h: h.order))
