"""The compiled kernel for structures that use parts registered outside the package.

The cached kernel (:mod:`pneumafit.models.kernel`) has a fixed branch per
built-in heat law and a configuration slot per built-in effect. A part
registered from outside the package (a notebook, a plug-in module) brings
its own compiled code instead:

- a heat law (``HeatLaw.kernel``): ``lam(p, pres, temp, t_wall) -> float``,
  the heat-transfer coefficient lambda (W/m^2/K) of one chamber from the
  parameter vector p (SI, ``layout.P``), its pressure (Pa), gas temperature
  and wall temperature (K). The chamber balance is the kernel's (paper eqs.
  2-5 with Q = lambda A (T_w - T)): a heat law is a lambda law;
- a valve law (``ValveLaw.kernel``): ``flows(u, pres, temp, p_s, p) ->
  (q_net, h_in, q_supply)``, the flows of one servo-valve from its command
  (V), its chamber's pressure (Pa) and gas temperature (K), the supply
  pressure (Pa, after the supply line's drop when that effect is on) and p
  (the exhaust pressure and ambient temperature are ``p[P["exhaust_pressure"]]``
  and ``p[P["ambient_temperature"]]``): the net mass flow into the chamber
  (kg/s), the enthalpy it carries as sum q_i T_i (kg K/s: inflows at their
  upstream temperature, outflows at the chamber's) and the flow drawn from
  supply (kg/s), as :func:`pneumafit.physics.valve.valve_flows`. The
  chamber's valve gets its own command (the kernel applies the spool
  dynamics, saturation and input hold before);
- a friction law (``FrictionLaw.kernel``): ``force(v, f_s, f_c, x, p) ->
  float``, the friction force (N) against the motion from the piston speed
  (m/s), the static and Coulomb levels (N, the seal and asymmetry effects
  applied), the state and p; a smooth law, without the switch model's
  stuck mode and events (as LuGre). A law with a state of its own (a
  bristle deflection) adds ``FrictionLaw.state_rate``: ``rate(v, f_s, f_c,
  x, p, max_rate) -> float``, the rate of that state, held in the bristle
  slot ``x[layout.X_Z]`` (``max_rate``: the relaxation rate the step can
  follow, 1/s). A law with ``FrictionLaw.stuck`` is instead the sliding
  force of the switch model's modes, ``force(v, s, f_s, f_c, x, p)``, s
  = +-1 the sliding direction (v may be 0 at breakaway): the kernel keeps
  the piston stuck while the drive stays within the static level and
  locates breakaway and rest as for the switch model;
- an effect (``Effect.kernel``): ``eff(x, p) -> (q_P, H_P, q_N, H_N, q_atm,
  F)``, from the state x (``layout.X_*``) and p: mass flows into chambers P
  and N (kg/s), the enthalpy they carry as sum q_i T_i (kg K/s: inflows at
  their upstream temperature, outflows at the chamber's), the mass sent to
  atmosphere (kg/s, for the air consumed) and a force on the piston along
  +y (N). The structure switches it on by its field in the configuration
  slot ``C_PART_EFFECTS`` (:func:`effect_field`). An effect with states of
  its own (``Effect.states``, among the slots ``layout.X_E0`` to ``X_E2``,
  three between all effects) adds ``Effect.state_rate``: ``rate(x, p)``,
  their time derivatives (a float for one state, a tuple for more). An
  effect with options other than the single option 1 (``Effect.options``:
  variants, as the built-in spool order 1 or 2) takes the structure's value
  as a third argument, ``eff(x, p, option)`` and ``rate(x, p, option)``,
  ``option`` an int >= 1 (0, off, never reaches it).

All are numba ``@njit`` functions. They are compiled again here with the
kernel's own flags (``fastmath`` as the kernel, no reference counting): they
may not allocate arrays.

:func:`kernel_for` returns the module a structure runs on: the cached
kernel when it uses built-in parts only, else a copy of the kernel's source
compiled, without numba's disk cache, with its hooks
(``kernel.part_heat``, ``kernel.part_valve``, ``kernel.part_friction``,
``kernel.part_friction_rate``, ``kernel.part_friction_stuck``,
``kernel.part_friction_sliding``, ``kernel.part_effects``,
``kernel.part_effect_rates``)
bound to every outside part
registered at the time. The copy is made once per set of registered parts
(the first simulation compiles it: 20 s on the 2-core machine, measured as
the first test of ``tests/test_part_kernel.py``, once per process) and is
exactly the kernel otherwise: the same integrator, events and health
checks (bit for bit: the tests write built-in laws again as outside parts).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path
from types import FunctionType, ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from pneumafit.errors import PneumafitInputError
from pneumafit.models import kernel, layout, parts
from pneumafit.models.layout import C_FRICTION_LAW, C_HEAT, C_PART_EFFECTS, C_VALVE_LAW
from pneumafit.physics.friction import FASTMATH

_log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from pneumafit.models.structure import ModelStructure

__all__ = [
    "MAX_PART_EFFECTS",
    "effect_field",
    "hooked_effects",
    "hooked_friction_laws",
    "hooked_heat_laws",
    "hooked_valve_laws",
    "kernel_for",
    "kernel_for_config",
    "kernel_for_laws",
    "kernel_for_valve",
    "parts_digest",
    "rebound",
]

#: Bits of the int64 configuration slot ``C_PART_EFFECTS`` that the outside
#: effects with kernel code share: one per effect with the single option 1,
#: ``max(options).bit_length()`` for one with options (:func:`effect_fields`).
MAX_PART_EFFECTS = 62

_BUILT: dict[tuple[object, ...], ModuleType] = {}
_REBOUND: dict[tuple[Any, str], Any] = {}


def hooked_heat_laws() -> list[parts.HeatLaw]:
    """The registered heat laws with kernel code of their own, by code."""
    laws = [h for h in parts.HEAT_LAWS.values() if h.kernel is not None]
    return sorted(laws, key=lambda h: h.code)


def hooked_valve_laws() -> list[parts.ValveLaw]:
    """The registered valve laws with kernel code of their own, by code."""
    laws = [v for v in parts.VALVE_LAWS.values() if v.kernel is not None]
    return sorted(laws, key=lambda v: v.code)


def hooked_friction_laws() -> list[parts.FrictionLaw]:
    """The registered friction laws with kernel code of their own, by code."""
    laws = [f for f in parts.FRICTION_LAWS.values() if f.kernel is not None]
    return sorted(laws, key=lambda f: f.code)


def hooked_effects() -> list[parts.Effect]:
    """The registered effects with kernel code of their own, in registration order."""
    return [e for e in parts.EFFECTS.values() if e.kernel is not None]


def parts_digest() -> str:
    """A fingerprint of the parts registered from outside the package ("" for none).

    sha256 over every registered part that is not built in (a heat, valve or
    friction law with a code outside the kernel's, every effect without a
    configuration slot) and every parameter appended to the table: names,
    codes, parameters, starts, an effect's options (when not the single
    option 1), and the kernel code's bytecode, constants, names, closure
    cells and the numbers it reads from its module's globals (a parameter
    index). Stable across processes for the same source; an
    edited law gives another digest, so that a saved fit of the old law is
    not taken for one of the new (``pipeline.fit_is_reusable``).
    """
    import hashlib

    from pneumafit.models import layout

    items: list[str] = []
    outside = (
        [("heat", h) for h in parts.HEAT_LAWS.values() if h.code not in parts.KERNEL_HEAT_CODES]
        + [("valve", v) for v in parts.VALVE_LAWS.values()
           if v.code not in parts.KERNEL_VALVE_CODES]
        + [("friction", f) for f in parts.FRICTION_LAWS.values()
           if f.code not in parts.KERNEL_FRICTION_CODES]
        + [("effect", e) for e in parts.EFFECTS.values() if e.slot is None]
    )  # fmt: skip
    for kind, part in outside:
        fields = [kind, part.name, str(getattr(part, "code", "")), repr(part.parameters),
                  repr(getattr(part, "starts", ()))]  # fmt: skip
        item = "|".join(fields) + "|" + _code_fingerprint(getattr(part, "kernel", None))
        rate = getattr(part, "state_rate", None)
        if rate is not None:  # appended only when present: older digests unchanged
            item += f"|state_rate|{getattr(part, 'states', '')}|" + _code_fingerprint(rate)
        if getattr(part, "stuck", False):  # likewise
            item += "|stuck"
        if isinstance(part, parts.Effect) and takes_option(part):  # likewise
            item += f"|options|{sorted(part.options.items())!r}"
        items.append(item)
    items += [repr(spec) for spec in layout.PARAMETER_SPECS[layout.NP :]]
    if not items:
        return ""
    return hashlib.sha256("\n".join(items).encode()).hexdigest()


def _code_fingerprint(function: object) -> str:
    """What a kernel function computes, as text: its bytecode, constants,
    names, closure cells and the numeric globals it reads (none: "")."""
    py = getattr(function, "py_func", function)
    code = getattr(py, "__code__", None)
    if code is None:
        return ""
    env = getattr(py, "__globals__", {})
    numbers = {n: env[n] for n in code.co_names if isinstance(env.get(n), (int, float))}
    cells = [repr(c.cell_contents) for c in (py.__closure__ or ()) if _plain(c)]
    return "|".join((code.co_code.hex(), repr(code.co_consts), repr(code.co_names),
                     repr(cells), repr(sorted(numbers.items()))))  # fmt: skip


def _plain(cell: Any) -> bool:
    """A closure cell holding a number or a string (not a function, whose repr
    names its address)."""
    try:
        return isinstance(cell.cell_contents, (int, float, str))
    except ValueError:  # an empty cell
        return False


def takes_option(effect: parts.Effect) -> bool:
    """Whether an outside effect's kernel code takes the option as a third
    argument: it has options other than the single option 1."""
    return set(effect.options) != {1}


def effect_fields() -> dict[str, tuple[int, int]]:
    """Where each outside effect with kernel code sits in ``C_PART_EFFECTS``.

    Returns
    -------
    dict of str to (int, int)
        Effect name -> (shift, width) in bits, in registration order: the
        structure's option value v is stored as ``v << shift`` and read as
        ``(mask >> shift) & (2**width - 1)``. An effect with the single
        option 1 takes one bit (its bit, as before options existed), one
        with options ``max(options).bit_length()`` bits.
    """
    effects = hooked_effects()
    return {e.name: field for e, field in zip(effects, _fields_of(effects), strict=True)}


def effect_field(name: str, value: int) -> int:
    """An outside effect's option value placed in the configuration slot
    ``C_PART_EFFECTS`` (to be or-ed into it; 0 for value 0, off).

    Parameters
    ----------
    name : str
        A registered effect with kernel code (``Effect.kernel``).
    value : int
        0 (off) or one of its options (``Effect.options``).

    Raises
    ------
    PneumafitInputError
        ``name`` is not a registered effect with kernel code, ``value`` not
        one of its options, or the effects registered before it and it take
        more than :data:`MAX_PART_EFFECTS` bits.
    """
    fields = effect_fields()
    if name not in fields:
        raise PneumafitInputError(
            f"effect {name!r}: expected an effect registered with kernel code "
            f"(Effect.kernel), found {'none' if name not in parts.EFFECTS else 'no kernel code'}"
        )
    effect = parts.EFFECTS[name]
    if value != 0 and value not in effect.options:
        raise PneumafitInputError(
            f"effect {name!r}: option: expected one of {list(effect.option_values)}, "
            f"found {value!r}"
        )
    shift, width = fields[name]
    if shift + width > MAX_PART_EFFECTS:
        raise PneumafitInputError(
            f"effect {name!r}: expected the effects with kernel code registered outside the "
            f"package to fit in {MAX_PART_EFFECTS} bits (one per effect, more for one with "
            f"options), found {shift + width} up to this one ({len(fields)} effects)"
        )
    return int(value) << shift


def kernel_for(structure: ModelStructure | None) -> ModuleType:
    """The compiled kernel module a structure runs on.

    Parameters
    ----------
    structure : ModelStructure or None
        None: the cached kernel (built-in parts).

    Returns
    -------
    module
        :mod:`pneumafit.models.kernel`, or its copy with the hooks bound to
        the outside parts registered now (built once per set of parts).

    Raises
    ------
    PneumafitInputError
        A part of the structure that has no kernel code
        (:meth:`ModelStructure.config`).
    """
    return kernel if structure is None else kernel_for_config(structure.config())


def kernel_for_config(cfg: np.ndarray) -> ModuleType:
    """The compiled kernel module for a configuration vector (as :func:`kernel_for`).

    Parameters
    ----------
    cfg : ndarray of int, shape (NCFG,)
        ``ModelStructure.config()``.
    """
    if (
        int(cfg[C_HEAT]) in parts.KERNEL_HEAT_CODES
        and int(cfg[C_VALVE_LAW]) in parts.KERNEL_VALVE_CODES
        and int(cfg[C_FRICTION_LAW]) in parts.KERNEL_FRICTION_CODES
        and int(cfg[C_PART_EFFECTS]) == 0
    ):
        return kernel
    return _copy()


def kernel_for_valve(code: int) -> ModuleType:
    """The compiled kernel module whose valve flows, static flows and rate bound
    (``static_valve_flows``, ``stiffness_bound``) know the valve law ``code``.

    Parameters
    ----------
    code : int
        A valve law's code (``ValveLaw.code``).

    Returns
    -------
    module
        :mod:`pneumafit.models.kernel` for the kernel's own laws, else the
        copy bound to the outside parts registered now.
    """
    return kernel if int(code) in parts.KERNEL_VALVE_CODES else _copy()


def kernel_for_laws(valve: int, friction: int) -> ModuleType:
    """The compiled kernel module whose rate bound (``stiffness_bound``) knows
    the valve law ``valve`` and the friction law ``friction`` (codes).

    Returns
    -------
    module
        :mod:`pneumafit.models.kernel` when both are the kernel's own laws,
        else the copy bound to the outside parts registered now.
    """
    if int(friction) in parts.KERNEL_FRICTION_CODES:
        return kernel_for_valve(valve)
    return _copy()


def rebound(function: Any, module: ModuleType) -> Any:
    """A compiled function of another module that calls ``kernel.*``, bound to ``module``.

    Parameters
    ----------
    function : numba dispatcher
        A function whose code reaches the kernel as the global ``kernel``
        (``kernel.rhs(...)``) or through kernel functions imported by name
        (``rhs(...)``), e.g. discovery's rates along a recording or the
        sampled closed loop's steps.
    module : module
        :func:`kernel_for`'s result.

    Returns
    -------
    numba dispatcher
        ``function`` itself for the cached kernel; else the same code with
        ``kernel`` bound to ``module``, compiled with the same options and no
        disk cache (once per function and module).
    """
    if module is kernel:
        return function
    key = (function, module.__name__)
    bound = _REBOUND.get(key)
    if bound is None:
        from numba import njit

        py = function.py_func
        env = dict(py.__globals__)
        env["kernel"] = module
        if "NX" in env:  # arrays of states sized as the module's (state_size)
            env["NX"] = module.NX
        for name, value in py.__globals__.items():
            inner = getattr(value, "py_func", None)
            if inner is not None and inner.__module__ == kernel.__name__:
                env[name] = getattr(module, name)
        copy = FunctionType(py.__code__, env, py.__name__, py.__defaults__, py.__closure__)
        options = {
            k: v for k, v in function.targetoptions.items() if k not in ("cache", "nopython")
        }
        bound = _REBOUND[key] = njit(cache=False, **options)(copy)
    return bound


def _copy() -> ModuleType:
    """The kernel's copy bound to the outside parts registered now (built once per set)."""
    heat = hooked_heat_laws()
    valve = hooked_valve_laws()
    friction = hooked_friction_laws()
    effects = hooked_effects()
    key = (
        tuple((h.name, h.code, id(h.kernel)) for h in heat),
        tuple((v.name, v.code, id(v.kernel)) for v in valve),
        tuple((f.name, f.code, id(f.kernel), id(f.state_rate), f.stuck) for f in friction),
        tuple(
            (e.name, id(e.kernel), e.states, id(e.state_rate), tuple(sorted(e.options)))
            for e in effects
        ),
    )
    module = _BUILT.get(key)
    if module is None:
        module = _build(heat, valve, friction, effects, len(_BUILT))
        named = [f"heat law {h.name!r}" for h in heat] + [f"valve law {v.name!r}" for v in valve]
        named += [f"friction law {f.name!r}" for f in friction]
        named += [f"effect {e.name!r}" for e in effects]
        # the copy is not in numba's disk cache: each process compiles it at
        # its first simulation, a silent wait on the command line otherwise
        _log.info(
            "the simulator with the parts from outside the package (%s) is compiled at its "
            "first use in this process (about 15-40 s, once)",
            ", ".join(named),
        )
        _compile_hooks(module, (heat, valve, friction, effects), ", ".join(named))
        _BUILT[key] = module
    return module


def _compile_hooks(module: ModuleType, hooked: tuple[list[Any], ...], named: str) -> None:
    """Compile the copy's hooks, and so the parts' code, by calling each once
    on the probe operating point (``parts.registry.probe_point``), so that
    code numba cannot compile is named as the parts' fault (an input error
    with numba's own lines) before a simulation starts, not reported by the
    command line as an internal error. The kernel's own functions compile
    later, at their first use, on the hooks compiled here. ``hooked``: the
    heat, valve and friction laws and the effects the copy binds."""
    from numba.core.errors import NumbaError

    from pneumafit.models.parts.registry import probe_point

    heat, valve, friction, effects = hooked
    pt = probe_point()
    x, p, v, f_s, f_c = pt.x[: module.NX], pt.p, pt.v, pt.f_s, pt.f_c
    dx = np.zeros(module.NX)
    mask = 0
    for effect, (shift, _width) in zip(effects, _fields_of(effects), strict=True):
        mask |= min(effect.options) << shift
    try:
        for h in heat:
            module.part_heat(int(h.code), p, pt.pres, pt.temp, pt.t_wall)
        for law in valve:
            module.part_valve(int(law.code), pt.u, pt.pres, pt.temp, pt.p_s, p)
        for f in friction:
            module.part_friction(int(f.code), v, f_s, f_c, x, p)
            module.part_friction_rate(int(f.code), v, f_s, f_c, x, p, 1.0e4)
            module.part_friction_sliding(int(f.code), v, 1.0, f_s, f_c, x, p)
        if effects:
            module.part_effects(mask, x, p)
            module.part_effect_rates(mask, x, p, dx)
    except NumbaError as exc:
        lines = [
            line for line in str(exc).splitlines()
            if line.strip() and not line.startswith(("Failed in nopython", "During:", "File "))
            and "source missing" not in line
        ]  # fmt: skip
        raise PneumafitInputError(
            f"the compiled code of the parts from outside the package ({named}) does not "
            f"compile with numba: {' | '.join(lines[:4]) or type(exc).__name__}"
        ) from exc


def _hook_source(
    heat: list[parts.HeatLaw],
    valve: list[parts.ValveLaw],
    friction: list[parts.FrictionLaw],
    effects: list[parts.Effect],
) -> str:
    """Source of the hooks, dispatching on the heat, valve and friction
    codes and the effect bits."""
    lines = [
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_heat(heat, p, pres, temp, t_wall):",
    ]
    for h in heat:
        lines += [
            f"    if heat == {int(h.code)}:",
            f"        return _heat_{int(h.code)}(p, pres, temp, t_wall)",
        ]
    lines += [
        "    return math.nan",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_valve(law, u, pres, temp, p_s, p):",
    ]
    for v in valve:
        lines += [
            f"    if law == {int(v.code)}:",
            f"        return _valve_{int(v.code)}(u, pres, temp, p_s, p)",
        ]
    lines += [
        "    return math.nan, math.nan, math.nan",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_friction(law, v, f_s, f_c, x, p):",
    ]
    smooth = [f for f in friction if not f.stuck]
    stuck = [f for f in friction if f.stuck]
    for f in smooth:
        lines += [
            f"    if law == {int(f.code)}:",
            f"        return _friction_{int(f.code)}(v, f_s, f_c, x, p)",
        ]
    lines += [
        "    return math.nan",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_friction_stuck(law):",
        *[f"    if law == {int(f.code)}:\n        return True" for f in stuck],
        "    return False",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_friction_sliding(law, v, s, f_s, f_c, x, p):",
        *[f"    if law == {int(f.code)}:\n"
          f"        return _friction_{int(f.code)}(v, s, f_s, f_c, x, p)" for f in stuck],
        "    return math.nan",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_friction_rate(law, v, f_s, f_c, x, p, max_rate):",
    ]  # fmt: skip
    for f in friction:
        if f.state_rate is not None:
            lines += [
                f"    if law == {int(f.code)}:",
                f"        return _friction_rate_{int(f.code)}(v, f_s, f_c, x, p, max_rate)",
            ]
    lines += [
        "    return 0.0",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_effects(mask, x, p):",
        "    q_p = 0.0",
        "    h_p = 0.0",
        "    q_n = 0.0",
        "    h_n = 0.0",
        "    q_a = 0.0",
        "    f = 0.0",
    ]
    for i, (effect, field) in enumerate(zip(effects, _fields_of(effects), strict=True)):
        guard, arguments = _switched_on(i, effect, field)
        lines += [
            *guard,
            f"        a0, a1, a2, a3, a4, a5 = _effect_{i}({arguments})",
            "        q_p += a0",
            "        h_p += a1",
            "        q_n += a2",
            "        h_n += a3",
            "        q_a += a4",
            "        f += a5",
        ]
    lines += [
        "    return q_p, h_p, q_n, h_n, q_a, f",
        "",
        "",
        "@njit(cache=False, fastmath=_FM, _nrt=False)",
        "def part_effect_rates(mask, x, p, dx):",
        "    for i in range(X_E0, NX):",
        "        dx[i] = 0.0",
    ]
    for i, (effect, field) in enumerate(zip(effects, _fields_of(effects), strict=True)):
        if not effect.states:
            continue
        guard, arguments = _switched_on(i, effect, field)
        if len(effect.states) == 1:  # the rate is a number
            slot = int(effect.states[0])
            lines += [*guard, f"        dx[{slot}] = _effect_rate_{i}({arguments})"]
            continue
        # a tuple, one rate per state in the order of the effect's states
        names = [f"r{i}_{k}" for k in range(len(effect.states))]
        lines += [*guard, f"        {', '.join(names)} = _effect_rate_{i}({arguments})"]
        lines += [f"        dx[{int(s)}] = {r}" for s, r in zip(effect.states, names, strict=True)]
    lines += ["    return", ""]
    return "\n".join(lines)


def _switched_on(i: int, effect: parts.Effect, field: tuple[int, int]) -> tuple[list[str], str]:
    """The hook's lines that test whether the ``i``-th outside effect is on in
    ``mask`` (its ``field``, (shift, width)), and the arguments of its calls:
    ``x, p`` for the single option 1 (its bit, the code before options
    existed), ``x, p, o_i`` with the option read from its field otherwise."""
    shift, width = field
    if not takes_option(effect):
        return [f"    if mask & {1 << shift}:"], "x, p"
    return [f"    o_{i} = (mask >> {shift}) & {(1 << width) - 1}", f"    if o_{i} != 0:"], (
        f"x, p, o_{i}"
    )


def _fields_of(effects: list[parts.Effect]) -> list[tuple[int, int]]:
    """(shift, width) of each effect in ``C_PART_EFFECTS``, in this order
    (:func:`effect_fields` for the registered ones)."""
    fields, shift = [], 0
    for effect in effects:
        width = max(effect.options).bit_length()
        fields.append((shift, width))
        shift += width
    return fields


def _recompiled(function: object, where: str) -> object:
    """A part's njit function compiled again with the kernel's flags."""
    py_func = getattr(function, "py_func", None)
    if py_func is None:
        raise PneumafitInputError(
            f"{where}: kernel: expected a numba @njit function, found {type(function).__name__}"
        )
    from numba import njit

    return njit(cache=False, fastmath=FASTMATH, _nrt=False)(py_func)


def _build(
    heat: list[parts.HeatLaw],
    valve: list[parts.ValveLaw],
    friction: list[parts.FrictionLaw],
    effects: list[parts.Effect],
    serial: int,
) -> ModuleType:
    """Compile-ready copy of the kernel module with its hooks bound to ``heat``,
    ``valve``, ``friction`` and ``effects``."""
    source = Path(kernel.__file__).read_text(encoding="utf-8")
    # the copy must not read or write numba's disk cache: its hooks are not
    # in the kernel file the cache is keyed on
    source = source.replace("cache=True", "cache=False")
    name = f"pneumafit.models._part_kernel_{serial}"
    module = ModuleType(name)
    module.__file__ = kernel.__file__
    sys.modules[name] = module  # numba resolves a function's globals through its module
    code = compile(source, f"<pneumafit kernel copy {serial}>", "exec")
    exec(code, module.__dict__)
    namespace = module.__dict__
    # the state vector: the cached kernel's, or longer for effect states in
    # the slots past it (numba reads the global at compilation, after this)
    namespace["NX"] = layout.state_size(s for e in effects for s in e.states)
    for law in heat:
        namespace[f"_heat_{int(law.code)}"] = _recompiled(law.kernel, f"heat law {law.name!r}")
    for law in valve:
        namespace[f"_valve_{int(law.code)}"] = _recompiled(law.kernel, f"valve law {law.name!r}")
    for law in friction:
        namespace[f"_friction_{int(law.code)}"] = _recompiled(
            law.kernel, f"friction law {law.name!r}"
        )
        if law.state_rate is not None:
            namespace[f"_friction_rate_{int(law.code)}"] = _recompiled(
                law.state_rate, f"friction law {law.name!r}: state_rate"
            )
    for i, effect in enumerate(effects):
        namespace[f"_effect_{i}"] = _recompiled(effect.kernel, f"effect {effect.name!r}")
        if effect.state_rate is not None:
            namespace[f"_effect_rate_{i}"] = _recompiled(
                effect.state_rate, f"effect {effect.name!r}: state_rate"
            )
    exec(compile(_hook_source(heat, valve, friction, effects), f"<pneumafit part hooks {serial}>",
                 "exec"), namespace)  # fmt: skip
    return module
