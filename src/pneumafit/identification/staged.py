"""Staged identification, the way a rig engineer works.

a. **valve**: the servo-distributor characteristic q_m(P, u) of both sides,
   dead band and centre leakage, from the flow tests (static);
b. **heat**: the heat-transfer law (xi and beta; lambda; k) from the
   charge/discharge tests, the valve held at (a);
c. **friction**: static, Coulomb, viscous friction and Stribeck velocity
   from the step tests, valve and heat held at (a), (b);
d. **joint**: every ``fit`` recording at once, valve, heat, friction and
   the recordings' initial states free, starting from (a)-(c), refitted
   after the solver's defect correction. When (c) chose LuGre over the
   switch law and the joint bristle stiffness ends at its limit
   (:data:`BRISTLE_LIMIT`), the switch law is solved jointly too and the
   better kept (the same BIC rule): (c) chose on the step tests with valve
   and heat held, and LuGre's joint optimum can then be the poorer one.

Each stage is a :class:`~pneumafit.identification.problem.Problem`, a
:class:`~pneumafit.identification.likelihood.LogLikelihood` and a
multi-start :func:`~pneumafit.identification.optimise.fit_least_squares`.
The joint estimate is the reported value, with its Laplace uncertainty.
With MCMC (:data:`DEFAULT_SAMPLE`), heat is then sampled on the
charge/discharge and step tests and friction on the step tests, the other
groups held at the joint estimate; the uncertainty of the held groups is
added to first order from the joint Laplace covariance
(:func:`~pneumafit.identification.sampling.propagate`). Sampling the groups
separately keeps each chain low-dimensional, which is what makes chains of
50 tau affordable. docs/identification.md gives the reasons and numbers.
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from pneumafit.campaign.consistency import consistency_warnings
from pneumafit.campaign.model import Campaign, Recording
from pneumafit.errors import PneumafitComputationError, PneumafitInputError
from pneumafit.identification.coverage import (
    centre_measured,
    extrapolation_spread,
    full_informed,
    opened_paths,
    shape_informed,
    unbracketed_edges,
    uncovered_commands,
)
from pneumafit.identification.likelihood import LogLikelihood, LogPosterior
from pneumafit.identification.noise import NoiseModel
from pneumafit.identification.optimise import (
    ONE_RECORDING,
    STALL_RULE,
    PointEstimate,
    RobustCovariance,
    fit_least_squares,
    information_stall,
    laplace_covariance,
    laplace_summary,
    recording_robust_covariance,
)
from pneumafit.identification.parameters import (
    CONSTRAINTS,
    DEFAULT_FREE_VALVE,
    Normal,
    Parameter,
    ParameterSet,
)
from pneumafit.identification.problem import (
    MAX_STEP,
    NOISE_POOLING,
    OFFSET_PREFIX,
    OFFSET_SCOPE,
    Problem,
    pressure_offsets,
)
from pneumafit.identification.quality import (
    FitQuality,
    assess_residuals,
    bound_problems,
    chain_problems,
    interval_problems,
    one_recording_caveat,
    rest_offsets,
    undetermined_problems,
)
from pneumafit.identification.reference import (
    REFERENCE_STATE,
    SLIDING_VELOCITY,
    reference_lambda,
    reference_sliding,
)
from pneumafit.identification.replay import Replay, replay, with_recorded_commands
from pneumafit.identification.sampling import MCMCResult, propagate, run_mcmc
from pneumafit.identification.segments import segment_step_tests
from pneumafit.identification.starts import (
    friction_starts,
    heat_starts,
    seal_starts,
    stribeck_candidates,
    valve_starts,
)
from pneumafit.models.layout import FRICTION_LAWS, SPECS
from pneumafit.models.part_kernel import hooked_friction_laws
from pneumafit.models.parts import FRICTION_LAWS as FRICTION_PARTS
from pneumafit.models.parts import HEAT_LAWS, VALVE_LAWS
from pneumafit.models.structure import (
    EFFECT_SLOTS,
    HEAT_PARAMETERS,
    INPUT_MODE,
    MODELS,
    ModelStructure,
)
from pneumafit.models.structure import FRICTION_PARAMETERS as STRUCTURE_FRICTION
from pneumafit.physics.geometry import exchange_areas
from pneumafit.physics.valve_map import (
    CENTRE_KNOT,
    MAP_CE_NAMES,
    MAP_CS_NAMES,
    MAP_KNOTS,
    map_from_iso,
)
from pneumafit.progress import Progress, Reporter

if TYPE_CHECKING:
    from pneumafit.identification.fitfile import SavedFit

__all__ = [
    "DEFAULT_CHANNELS",
    "FRICTION_PARAMETERS",
    "VALVE_PARAMETERS",
    "FitOptions",
    "FitResult",
    "StageResult",
    "fit_structure",
    "identify",
]

#: Valve parameters fitted in stage (a) (the ISO 6358 law's, without the two
#: held ones: :data:`pneumafit.identification.parameters.DEFAULT_FREE_VALVE`).
VALVE_PARAMETERS: tuple[str, ...] = DEFAULT_FREE_VALVE
#: Friction parameters of the switch model (a structure's own list:
#: :attr:`ModelStructure.friction_parameter_names`).
FRICTION_PARAMETERS: tuple[str, ...] = STRUCTURE_FRICTION["switch"]

#: Channels compared by default. Gas temperatures are left out of the
#: likelihood: their sensors' dynamics decide them as much as the gas does
#: (on the virtual rig a half-sample difference in how the 0.4-s sensor lag
#: is discretised moved xi by 1 %, ten times its interval), so they are used
#: for validation (RMSE through a fitted probe, two lags in series) only. Name them in
#: ``FitOptions.channels`` to fit them (with a ``temperature_sensor_lag``
#: nuisance parameter).
DEFAULT_CHANNELS: tuple[str, ...] = ("p_P", "p_N", "y", "qm_P", "qm_N")

#: MCMC steps per sampled stage (walkers: :func:`default_walkers`). With the
#: differential-evolution moves tau is ~10 steps (heat) and ~30 (friction,
#: from a wide start) on the demo, so these are 50 tau plus burn-in.
DEFAULT_STEPS = {"valve": 2500, "heat": 1000, "friction": 2000}
#: With ``FitOptions.early_stop``, a chain is checked every
#: DEFAULT_STEPS / MCMC_CHECKS steps (heat 50, friction 100) after its
#: adaptation phase (:data:`ADAPT_FRACTION`), also while it is extended, and
#: stops at the first check where it is >= 50 tau long with every R-hat
#: <= 1.01. R-hat over the walkers as chains is about sqrt(1 + 2 tau / N) for
#: a well-mixed chain of N kept steps (split chains; Vats and Knudson 2021),
#: so R-hat <= 1.01 asks for ~100 tau, twice the 50 tau: on the demo
#: (2026-11-25, DE moves alone, tau 30-40) the friction chains reached 50 tau
#: at ~2000 steps and R-hat 1.01 at 3200-3800; with the adapted independence
#: proposal (tau ~3) both hold after a few hundred steps.
MCMC_CHECKS = 20
#: Share of a sampled stage's default length run with the DE moves before
#: the independence proposal is fitted to the walkers (``run_mcmc(adapt=)``,
#: module doc of :mod:`pneumafit.identification.sampling`): friction 300
#: steps, heat 150. From the wide start the demo's friction walkers settle
#: in 90-170 steps (DE alone), so the t is fitted to settled walkers.
ADAPT_FRACTION = 0.15
#: With early stopping the adaptation phase is checked every 1/ADAPT_CHECKS of
#: its length (friction every 50 steps, heat every 25) from twice that, and
#: ends once the walkers have settled (``run_mcmc(adapt_check=)``,
#: :func:`pneumafit.identification.sampling._phase_settled`), at its full
#: length at the latest.
ADAPT_CHECKS = 6
#: Stages sampled by default. The valve is not: its eight parameters need
#: long chains on the charge/discharge tests (the flow tests alone leave the
#: centre leakage, which the blocked tests measure, ten times less certain
#: and centred elsewhere), which the 5-minute budget does not allow; its
#: uncertainty comes from the joint Laplace approximation.
DEFAULT_SAMPLE = ("heat", "friction")

#: Centre-leakage parameters, fitted with the heat law in stage (b).
LEAK_PARAMETERS: tuple[str, ...] = ("valve_C_leak",)
#: Choices of :attr:`FitOptions.seal`; ``long``, the default, is ``auto`` for
#: fit step tests fitted in segments and ``off`` otherwise.
SEAL_MODES = ("long", "auto", "on", "off")

#: The seal-friction coefficient (N/Pa) of the ``seal_friction`` effect.
SEAL = EFFECT_SLOTS["seal_friction"][1][0]
#: Starts of the joint stage: stage (b)'s best heat-law optimum and up to
#: ``JOINT_STARTS - 1`` other distinct ones.
JOINT_STARTS = 3
#: Iterations of the short joint solve that screens those starts.
JOINT_SCREEN_NFEV = 20
#: With ``--friction auto`` the switch model is first solved from LuGre's
#: levels; its own starts (:func:`friction_starts`, the Stribeck screen) are
#: solved too unless LuGre's gain over that solve, in effective samples, is
#: above this many times the BIC threshold ln n_eff; when they are, their
#: optimum is compared with LuGre's, as before. The choice would differ from
#: the one against the own starts only if those recovered over 90 % of
#: LuGre's margin over the solve from its levels; on nine campaigns they
#: recovered at most 24 % (2026-11-29; docs/identification.md, "Friction
#: law: the switch model from LuGre's levels").
FRICTION_DECISIVE = 10.0
#: Before a friction chain, a Stribeck drop (friction_static over
#: friction_coulomb) that the joint estimate leaves unresolved is tested
#: (:func:`_stribeck_drop`): static within this share of the Coulomb level
#: (on the kernel's constraint static >= Coulomb) ...
DROP_UNRESOLVED = 0.01
#: ... or the Stribeck velocity within this factor of its lower bound (a
#: drop over before the bristles have deflected).
DROP_VELOCITY_FLOOR = 3.0
#: The law without the drop: friction_static simulated at friction_coulomb
#: (the Stribeck velocity then acts on nothing).
DROP_TIE = {"friction_static": "friction_coulomb"}
#: What the law without the drop holds: the tied static level and the
#: Stribeck velocity, which then acts on nothing.
DROP_HELD = ("friction_static", "stribeck_velocity")
#: The joint stage solves the switch model too when the law kept at stage (c)
#: is LuGre and its joint bristle stiffness ends within this fraction of its
#: log range under the upper bound (1e3-1e8 N/m: above 3.2e7 N/m, a bristle
#: deflection under 2 um at 50 N). Bristles that stiff are not resolved by
#: the recordings; the switch model is their limit, and the fit with them
#: can sit in a poorer optimum (calibration seed 5 on an AMD EPYC host:
#: 9.0e7 N/m, -18457 against the switch model's -16769). Revisiting the law
#: in every fit moved four slow tests' outcomes (docs/identification.md,
#: "Tried and not kept"); this only revisits a law at its limit.
BRISTLE_LIMIT = 0.1
#: Centre leakage tried with every heat start in stage (b), as fractions of
#: the supply path's full-opening conductance (servo-distributors leak
#: 0.1-1 % of their rated flow at the centre; the virtual rigs 0.2-0.4 %), on
#: top of the valve stage's own value. The fractions matter when the valve
#: stage put the leak on its bound: flow levels near the dead band can be
#: followed without a leak when the truth's leak shape is not the model's
#: (a Gaussian bump: 9 of 11 demo-plan fits ended at 1e-15 m^3/s/Pa, and the
#: heat law then absorbed the rest drift, xi 3.5x the truth).
LEAK_FRACTIONS = (1.0e-3, 3.0e-3, 1.0e-2)

#: Starts of a heat law's extension ``heat_area_ends`` besides the law as
#: written (1): the bore wall only (0) and half the heads, faces and rod.
AREA_STARTS = (0.0, 0.5)

#: Confidence of the likelihood-ratio test that frees a heat law's
#: extension (half the chi-square quantile: 11.9 in effective log-likelihood
#: for one parameter). Stricter than the valve's: a free area also stands in
#: for what the chambers lose otherwise. Measured effective gains (gain over
#: the residuals' overcount), flow and chamber tests of the demo plan, seeds
#: 1-3: barrel-only truths 83-356, full-area truths 0.5-6.8; and 5.4 on the
#: discovery tests' full-area rig with an undeclared external leak, where the
#: area kept at the valve's confidence (5.4) went to 0, stood in for the leak,
#: and discovery then rejected the leak (held-out y 13 % worse).
AREA_CONFIDENCE = 1.0 - 1e-6


def _leak_starts(
    heat: Sequence[Mapping[str, float]],
    values: Mapping[str, float],
    names: Sequence[str] = LEAK_PARAMETERS,
    full: float = 1.0e-8,
) -> list[dict[str, float]]:
    """Every heat start with each centre-leakage start.

    The leakage starts are the valve stage's value and :data:`LEAK_FRACTIONS`
    of ``full``, the full-opening supply conductance (m^3/s/Pa), leaving out
    those within a factor 2 of one already kept.
    """
    leaks = [[max(float(values[n]), 1e-14) for n in names]]
    for f in LEAK_FRACTIONS:
        cand = [f * full] * len(names)
        if all(max(abs(math.log(c / k)) for c, k in zip(cand, kept, strict=True)) > math.log(2.0)
               for kept in leaks):  # fmt: skip
            leaks.append(cand)
    return [{**h, **dict(zip(names, leak, strict=True))} for leak in leaks for h in heat]


#: Centre leakage of the valve map: each path's conductance at u = 0.
MAP_LEAK_PARAMETERS: tuple[str, ...] = (
    MAP_CS_NAMES[CENTRE_KNOT],
    MAP_CE_NAMES[CENTRE_KNOT],
)
_VALVE_GROUPS = ("valve", "valve_map")


def _group(name: str) -> str | None:
    """A parameter's group in the (live) table, None for names outside it."""
    spec = SPECS.get(name)
    return None if spec is None else spec.group


#: Sonic conductance of each path: without a fit flow test, the only valve
#: parameters fitted (from the tests that open the path, :func:`coverage.opened_paths`).
CONDUCTANCE_PARAMETERS = {"supply": "valve_C_supply", "exhaust": "valve_C_exhaust"}
#: Critical pressure ratio of each path.
RATIO_PARAMETERS = {"supply": "valve_b_supply", "exhaust": "valve_b_exhaust"}
#: Opening shape exponent of each path (see :func:`coverage.shape_informed`).
SHAPE_PARAMETERS = {"supply": "valve_n_supply", "exhaust": "valve_n_exhaust"}
#: Full-opening fraction of each path (see :func:`coverage.full_informed`).
FULL_PARAMETERS = {"supply": "valve_full_supply", "exhaust": "valve_full_exhaust"}
#: Knee exponent of each path (S-shaped opening, physics.valve), fitted where
#: the full-opening fraction would be (:func:`coverage.full_informed`).
KNEE_PARAMETERS = {"supply": "valve_knee_supply", "exhaust": "valve_knee_exhaust"}
#: Starting knee exponents besides 1 (the power law, whose optimum is at that
#: bound), each with the power law's exponent and with 1.25: an S-shaped
#: catalogue table is followed by n 1.2-1.25 and k 2.7-2.9 (physics.valve),
#: where the power law alone had taken n 0.7 with a 0.6-0.8-V dead band.
KNEE_STARTS = (2.0, 3.0, 5.0)
#: Starting full-opening fractions of the saturating law, besides 1 (the
#: law without them, whose optimum is at that bound).
FULL_STARTS = (0.9, 0.75)
#: A fitted full-opening fraction (knee exponent) this close to 1 is held at
#: 1: the path does not saturate within the flow levels (has no knee), and
#: the bound would be flagged.
FULL_AT_ONE = 1e-3
#: The spool's null offset (V), fitted last in the valve stage.
NULL_PARAMETER = "valve_null_offset"
#: Starting null offsets (V) besides 0 (the law without it): the dead band's
#: edges move by the offset, and from 0 the flow levels near them alone
#: set its sign.
NULL_STARTS = (-0.05, 0.05)
#: Level of the likelihood-ratio test that keeps the shape exponents (the
#: linear ramp is the null hypothesis; chi-square with one degree of freedom
#: per exponent): 0.999, so a linear valve keeps its linear law in all but
#: one fit in a thousand.
SHAPE_CONFIDENCE = 0.999
#: Largest score difference (log-likelihood less the tests' price) between
#: the valve laws of the two orders (knees or full-opening fractions first)
#: at which the one not kept counts as about as good: 3, a likelihood ratio
#: of e^3 ~ 20 (2 ln B = 6, "positive" but not "strong" evidence on Kass
#: and Raftery's scale, JASA 1995). Where the flow tests did not measure,
#: the fit then names how far the two laws' flows differ
#: (:func:`~pneumafit.identification.coverage.extrapolation_spread`). On
#: the bundled demo the two scores are 5.7 apart.
SHAPE_TIE = 3.0
#: Smallest flow difference (relative) between those two laws that is named:
#: 1 %, a flow meter's accuracy class.
SPREAD_NAMED = 0.01
#: Full-opening fractions and knee exponents each path is held at, one at a
#: time, with the rest of the valve refitted to the flow tests, after the
#: valve stage: the laws among them within :data:`SHAPE_TIE` of the kept one
#: fit the flow tests about as well, and where no flow level was measured
#: their flows say how uncertain the kept law's are. Fractions of 0.9 and
#: 0.95: a port uncovered at 9-9.5 V of 10 (the independently written rigs'
#: paths saturate at 9.1-9.8 V); knees of 1.5 and 2.5: a gentle and a
#: marked S (the starts of the knee test go to 5).
VARIANT_FULLS = (0.9, 0.95)
VARIANT_KNEES = (1.5, 2.5)


#: Starting exponents of the shaped valve law besides the linear ramp's
#: optimum. The ramp's optimum is a poor start for a progressive opening: it
#: fits the curve's convexity with an overlap far past the real dead band
#: (2.34 V for a power law n 1.55 starting at 0.42 V), and from there the
#: exponents stay near 1 (a local optimum at 7x the flow meter's noise).
SHAPE_STARTS = (0.7, 1.5, 2.2)


def _shape_starts(values: Mapping[str, float], shapes: Sequence[str]) -> list[dict[str, float]]:
    """Starts of the shaped valve law, the linear ramp's optimum first.

    Then each exponent of :data:`SHAPE_STARTS` for every free exponent in
    ``shapes``, with the overlap at the generic dead band of
    :func:`valve_starts` (0.5 V) or the ramp's if smaller (V).
    """
    first = dict(values)
    overlap = min(float(values["valve_overlap"]), 0.5)
    return [first] + [
        {**first, "valve_overlap": overlap, **{n: float(e) for n in shapes}} for e in SHAPE_STARTS
    ]


def _full_starts(values: Mapping[str, float], fulls: Sequence[str]) -> list[dict[str, float]]:
    """Starts of the saturating valve law: ``values`` (the law without the
    fractions, at f = 1), then every fraction of :data:`FULL_STARTS` for the
    free full-opening fractions ``fulls``, the rest at ``values``.

    A start whose path would open fully inside the dead band is left out.
    """
    floor = float(values["valve_overlap"]) / float(values["valve_u_sat"])
    return [dict(values)] + [
        {**values, **{n: f for n in fulls}} for f in FULL_STARTS if f > floor + 0.05
    ]


def _knee_starts(values: Mapping[str, float], knees: Sequence[str]) -> list[dict[str, float]]:
    """Starts of the S-shaped law: ``values`` (the power law, at k = 1), then
    every knee of :data:`KNEE_STARTS` for the free knees ``knees``, with the
    paths' exponents as in ``values`` and at 1.25, and the overlap at the
    generic dead band (0.5 V) or the power law's if smaller (V)."""
    overlap = min(float(values["valve_overlap"]), 0.5)
    exps = [SHAPE_PARAMETERS[p] for p, n in KNEE_PARAMETERS.items() if n in knees]
    out = [dict(values)]
    for k in KNEE_STARTS:
        out.append({**values, **{n: k for n in knees}})
        out.append({**values, "valve_overlap": overlap, **{n: k for n in knees},
                    **{n: 1.25 for n in exps}})  # fmt: skip
    return out


def _null_starts(values: Mapping[str, float], null: Sequence[str]) -> list[dict[str, float]]:
    """Starts of the null offset: ``values`` (the law without it, at 0), then
    each of :data:`NULL_STARTS` (V), the rest at ``values``."""
    return [dict(values)] + [{**values, **{n: b for n in null}} for b in NULL_STARTS]


def _at_one(extra: Sequence[str], values: Mapping[str, float]) -> tuple[str, ...]:
    """The full-opening fractions and knee exponents of ``extra`` within
    :data:`FULL_AT_ONE` of 1, the law they extend: held there (a path that
    does not saturate within the commands, a path without a knee)."""
    return tuple(
        n for n in extra
        if (n in FULL_PARAMETERS.values() and values[n] > 1.0 - FULL_AT_ONE)
        or (n in KNEE_PARAMETERS.values() and values[n] < 1.0 + FULL_AT_ONE)
    )  # fmt: skip


def _overcount(problem: Problem, estimate: PointEstimate) -> float:
    """The residuals' overcount at ``estimate`` (:meth:`LogLikelihood.overcount`):
    what a likelihood-ratio test divides its gain by to count effective samples."""
    ps = estimate.parameters
    return LogLikelihood(problem, ps).overcount(ps.to_internal(ps.values()))


def _without_seal(problem: Problem, trial: PointEstimate, before: Mapping[str, float]) -> float:
    """Log-likelihood of the friction without the seal term, to which the seal
    friction's gain is counted (-inf when neither point simulates).

    In the seal trial's own ``problem`` (a likelihood-ratio test compares two
    fits of the same data and the same profiled initial states; the friction
    stage's problem linearises those states elsewhere, and its optimum there
    read 864 higher than the same point here on the mixed truth, sparse-long
    plan: the term's gain of 713 counted as -151), the better
    of the friction stage's optimum (``before``) and the trial's own optimum,
    each with the coefficient at 0. The trial fits the levels again from
    other starts and may find a better optimum of the law without the term:
    on the rig's own laws (sparse-long plan) it ended 1162 above the friction
    stage with the coefficient at 1e-10 N/Pa, and the term was kept for a
    gain that was not its own.
    """
    like = LogLikelihood(problem, trial.parameters)
    fitted = trial.parameters.values()
    return max(like.at_values({**point, SEAL: 0.0}) for point in (before, fitted))


def _ln_n_eff(n_data: int, over: float) -> float:
    """BIC's penalty per parameter in effective samples, ln n_eff (n_eff =
    ``n_data`` / ``over``, at least 2): the residuals of a model that is not
    the rig's are correlated, and ``over`` (:func:`_overcount`) is how many
    times each sample is counted over. NaN when ``over`` is not finite."""
    return math.log(max(n_data / over, 2.0)) if math.isfinite(over) else math.nan


def _lugre_kept(gain: float, over: float, penalty: float) -> bool:
    """The friction-law rule between LuGre and the switch model (LuGre's two
    more parameters): LuGre's log-likelihood ``gain`` in effective samples
    (divided by ``over``) must exceed 2 x ``penalty`` / 2 = ln n_eff."""
    return math.isfinite(gain) and gain / over > penalty


def _passes(gain: float, over: float, n_extra: int, confidence: float) -> bool:
    """The likelihood-ratio test in effective samples: 2 gain / ``over`` above
    the chi-square quantile at ``confidence`` for ``n_extra`` parameters."""
    return math.isfinite(gain) and 2.0 * gain / over > chi2.ppf(confidence, n_extra)


def _flowless_extensions(
    conductances: Sequence[str], names: Sequence[str]
) -> list[tuple[tuple[str, ...], str, Any]]:
    """The valve law's extensions tested without a flow test, in order.

    For the paths whose conductance is fitted (``conductances``): the dead
    band with the opening shape exponents (the steps' commands sweep the
    valve's range, the charge/discharge tests hold a few levels), the knee
    exponents, the full-opening fractions, the critical pressure ratios and
    the null offset (both paths only), each with the starts of stage (a).
    """
    paths = [p for p, n in CONDUCTANCE_PARAMETERS.items() if n in conductances]

    def of(table: Mapping[str, str]) -> tuple[str, ...]:
        return tuple(table[p] for p in paths if table[p] in names)

    def held(values: Mapping[str, float], extra: Sequence[str]) -> list[dict[str, float]]:
        return [dict(values)]

    shapes = of(SHAPE_PARAMETERS)
    out = [
        (("valve_overlap", *shapes), "dead band and opening shape", _shape_starts),
        (of(KNEE_PARAMETERS), "knee exponents", _knee_starts),
        (of(FULL_PARAMETERS), "full-opening fractions", _full_starts),
        (of(RATIO_PARAMETERS), "critical pressure ratios", held),
    ]
    if len(paths) == 2 and NULL_PARAMETER in names:
        out.append(((NULL_PARAMETER,), "null offset", _null_starts))
    return [(extra, what, starts) for extra, what, starts in out if extra]


def _informed_valve(
    campaign: Campaign, values: Mapping[str, float], names: Sequence[str]
) -> tuple[str, ...]:
    """``names`` without the opening shape exponents, knee exponents,
    full-opening fractions and null offset the fit flow tests do not resolve."""
    known = shape_informed(campaign, values)
    drop = {SHAPE_PARAMETERS[path] for path, ok in known.items() if not ok}
    full = full_informed(campaign, values)
    drop |= {FULL_PARAMETERS[p] for p, ok in full.items() if not ok}
    drop |= {KNEE_PARAMETERS[p] for p, ok in full.items() if not ok}
    if not all(known.values()):  # the offset moves both paths' edges: both measured
        drop.add(NULL_PARAMETER)
    return tuple(n for n in names if n not in drop)


def _iso_valve(
    flows_campaign: Campaign,
    flows: Sequence[Recording],
    structure: ModelStructure,
    values: Mapping[str, float],
    options: FitOptions,
    seed: int,
    progress: Progress | None = None,
) -> dict[str, float]:
    """ISO 6358 fit of the flow tests (the valve map's start)."""
    iso = replace(structure, valve="iso6358")
    rig = {n: values[n] for n in values if _group(n) == "rig"}
    informed = _informed_valve(flows_campaign, {**values, **rig}, VALVE_PARAMETERS)
    ps = ParameterSet.for_model(iso, rig).only_free(informed)
    prob = _problem(flows, iso, {**ps.values(), **rig}, options)
    starts = valve_starts(flows, rig)
    prob.linearize({**ps.values(), **starts[0]})
    est = _least_squares(prob, ps, starts, seed, progress=progress)
    return {n: est.parameters[n].value for n in ps.names if _group(n) == "valve"}


def _uninformed_knots(campaign: Campaign, values: Mapping[str, float]) -> list[str]:
    """Map knots with no flow level strictly between their neighbouring knots."""
    u_sat = float(values["valve_u_sat"])
    levels = np.concatenate(
        [np.unique(np.asarray(r.channels[f"u_{r.chamber}"], float))
         for r in campaign.by_role("fit") if r.kind == "flow"] or [np.array([])]
    )  # fmt: skip
    knots = np.asarray(MAP_KNOTS) * u_sat
    held = []
    for k in range(len(knots)):
        lo = knots[k - 1] if k > 0 else -np.inf
        hi = knots[k + 1] if k + 1 < len(knots) else np.inf
        if not np.any((levels > lo) & (levels < hi)):
            held += [MAP_CS_NAMES[k], MAP_CE_NAMES[k]]
    return held


def _dead_band_knots(unmeasured: Sequence[str], free: Sequence[str]) -> tuple[str, ...]:
    """Free map knots in the unmeasured run around the centre, on each side.

    From the centre outwards, every knot in ``unmeasured`` up to the first
    measured one (both paths' parameters, those in ``free``).
    """
    out: list[str] = []
    for step in (-1, 1):
        k = CENTRE_KNOT + step
        while 0 <= k < len(MAP_KNOTS) and MAP_CS_NAMES[k] in unmeasured:
            out += [n for n in (MAP_CS_NAMES[k], MAP_CE_NAMES[k]) if n in free]
            k += step
    return tuple(out)


def _brief_values(values: Mapping[str, float], names: Sequence[str]) -> str:
    return ", ".join(f"{n} {values[n]:.4g}" for n in names if n in values)


def _distinct_optima(
    est: PointEstimate | None, names: Sequence[str], n: int
) -> list[dict[str, float]]:
    """Up to ``n`` start results other than the best, distinct in the heat law.

    Two optima are the same when every heat parameter agrees to 2 %.
    """
    if est is None or n <= 0:
        return []
    ranked = sorted(
        (r for r in est.starts if math.isfinite(r["log_likelihood"])),
        key=lambda r: -r["log_likelihood"],
    )
    kept: list[dict[str, float]] = []
    seen = [{k: est.parameters[k].value for k in names if k in est.parameters}]
    for r in ranked:
        cand = r["estimate"]
        if all(any(abs(cand[k] - s[k]) > 0.02 * max(abs(s[k]), 1e-12) for k in s) for s in seen):
            kept.append(dict(cand))
            seen.append({k: cand[k] for k in seen[0]})
        if len(kept) >= n:
            break
    return kept


#: Iterations per least-squares round of the joint stage. A structure that
#: cannot follow the data converges slowly: the polytropic fit of the small
#: test campaign (k on its adiabatic bound) needs ~2000 iterations in all and
#: was still gaining 330 in log-likelihood when stopped at 200 per round; the
#: demo's fits converge in under 60.
JOINT_NFEV = 500


def _shape_tie_warning(
    campaign: Campaign,
    kept_ll: float,
    kept: Mapping[str, float],
    alternatives: Sequence[tuple[str, float, Mapping[str, float]]],
) -> str:
    """The valve stage's warning when characteristics other than the kept one
    (values ``kept``, log-likelihood ``kept_ll``) fit the flow tests about as
    well (``alternatives``: label, log-likelihood, values; those within
    :data:`SHAPE_TIE` of ``kept_ll`` count) and differ from the kept one by
    :data:`SPREAD_NAMED` or more where no flow level was measured
    (:func:`~pneumafit.identification.coverage.extrapolation_spread`, the
    largest over them per range); empty otherwise."""
    worst: dict[tuple[str, float], tuple[float, float, str, str]] = {}
    for label, ll, values in alternatives:
        if not kept_ll - ll <= SHAPE_TIE:
            continue
        for v, lo, _hi, shown, d, u in extrapolation_spread(campaign, kept, values):
            if d >= SPREAD_NAMED and d > worst.get((v, lo), (0.0,))[0]:
                worst[(v, lo)] = (d, u, shown, label)
    if not worst:
        return ""
    rows = sorted(((d, u, v, shown, label) for (v, _), (d, u, shown, label) in worst.items()),
                  key=lambda row: -row[0])  # fmt: skip
    where = "; ".join(
        f"{100 * d:.1f} % at {u:+.2f} V of valve {v} ({label}), used by {shown}"
        for d, u, v, shown, label in rows[:4]
    )
    return (
        f"valve: other characteristics fit the flow tests about as well as the kept one "
        f"(log-likelihood within {SHAPE_TIE:g} of its {kept_ll:.1f}), and where no flow level "
        f"was measured their flows (into a chamber at mid pressure; near the centre, against "
        f"1 % of the full-opening flow) differ from the kept one's by up to {where}: the flows "
        "there are that uncertain, which no interval shows; a flow level there would tell "
        "them apart"
    )


def _shape_variants(
    knees: Sequence[str], fulls: Sequence[str]
) -> list[tuple[str, tuple[float, ...]]]:
    """Each informed knee and full-opening fraction with the values it is held
    at by the valve stage's profile of the shape (:data:`VARIANT_KNEES`,
    :data:`VARIANT_FULLS`)."""
    return [*((n, VARIANT_FULLS) for n in fulls), *((n, VARIANT_KNEES) for n in knees)]


#: Walkers per sampled parameter, by stage (:func:`default_walkers`).
WALKERS_PER_PARAMETER = {"valve": 3, "heat": 2, "friction": 3}


def default_walkers(n_free: int, stage: str) -> int:
    """Walkers of the sampled stage ``stage`` with ``n_free`` parameters:
    max(6, k n_free), k from :data:`WALKERS_PER_PARAMETER` (heat 2, else 3).

    emcee's ensemble needs at least 2 n_free. With the independence
    proposal the walkers are nearly independent chains, and R-hat over them
    asks for a number of kept steps per walker whatever their count, so a
    walker beyond 2 n_free costs steps without shortening the chain where
    the t fits the posterior. The heat law's posterior is such a case: on
    the demo's convection fit (seeds 1, 2) 2 n_free instead of 3 n_free took
    the heat chain from 4068 evaluations to 1812-2112, >= 50 tau with R-hat
    <= 1.01 and the intervals of xi and beta within 1 % of their widths, and
    no heat chain of the recovery matrix (seed 1, MCMC) was flagged. The
    friction posteriors of sparse plans are not: with 2 n_free walkers
    the friction chains of table-valve-asym and lugre-pressure ended
    unconverged at their limit (R-hat 1.016-1.023), so friction keeps 3
    n_free (docs/identification.md, "Moves and walkers")."""
    return max(6, WALKERS_PER_PARAMETER[stage] * n_free)


def _with_law(
    params: ParameterSet,
    structure: ModelStructure,
    rig: Mapping[str, float],
    nuisance: Sequence[str],
) -> ParameterSet:
    """The fit's parameters for another friction law of ``structure``: those
    of :meth:`ParameterSet.for_model`, plus the initial-state parameters the
    stages already added to ``params``."""
    fresh = ParameterSet.for_model(structure, rig, nuisance=nuisance)
    known = {p.name for p in fresh}
    initial = [p for p in params if p.group == "initial" and p.name not in known]
    return ParameterSet([*fresh, *initial])


def fit_structure(
    model: str | ModelStructure,
    air_properties: str = "sutherland",
    valve: str = "iso6358",
    friction: str = "switch",
    inputs: str = INPUT_MODE,
) -> ModelStructure:
    """The structure fitted for a model name (``inputs``: :class:`ModelStructure`).

    The convection model is fitted with Sutherland air properties (viscosity
    and conductivity of air at the gas temperature in the Grashof number):
    with air properties held at the wall temperature the fit of the virtual
    rig's noise-free charge/discharge traces lands at xi = 0.12, beta = 0.35
    instead of 0.40, 0.27 (the gas in a charge is 60 K hotter than the wall,
    which changes mu^2 by 30 %). The other two structures do not use air
    properties.
    """
    if isinstance(model, ModelStructure):
        return model
    base = replace(MODELS[model], valve=valve, friction=friction, inputs=inputs)
    if base.heat == "convection":
        return replace(base, air_properties=air_properties)
    return base


@dataclass(frozen=True)
class FitOptions:
    """Settings of :func:`identify` (all optional).

    Attributes
    ----------
    mcmc : bool
        Sample the posteriors after the point estimates.
    valve : {"iso6358", "map"}
        Valve law: the parametric ISO 6358 characteristic, or the measured
        map (:mod:`pneumafit.physics.valve_map`), started from the ISO fit of
        the flow tests.
    friction : {"auto", "switch", "lugre"} or a registered law's name
        Friction law of the fitted model (:mod:`pneumafit.physics.friction`):
        the switch model of stick-slip, or LuGre with pre-sliding, whose
        bristle stiffness sigma0 and damping sigma1 are then fitted with the
        other friction parameters in stages (c) and (d), or a law registered
        from outside the package with kernel code (``FrictionLaw.kernel``).
        ``auto`` (default) fits both built-in laws in stage (c) and keeps
        LuGre when its log-likelihood gain on the step tests exceeds ln n
        (BIC for its two extra parameters), then compares each outside law
        with the one kept (BIC in effective samples); a structure passed as
        ``model`` keeps its own law.
    walkers : int or None
        Walkers of every sampled stage (default :func:`default_walkers`).
    steps : int or None
        Steps of every sampled stage (default :data:`DEFAULT_STEPS`).
    sample : tuple of str
        Stages sampled, among ``valve``, ``heat``, ``friction``
        (default :data:`DEFAULT_SAMPLE`).
    channels : tuple of str
        Channels compared (:data:`DEFAULT_CHANNELS`).
    noise : NoiseModel, str or mapping, optional
        Noise model(s), see :class:`Problem` (default Gaussian for
        pressures, temperatures and flows, AR(1) for the position).
    noise_pooling : {"recording", "sensor"}
        ``recording`` (default): one noise level per (recording, channel),
        each profiled on its own residual, so that a recording the model
        cannot follow costs only the log of its own misfit and the
        recordings it follows keep their weight; ``sensor``: one noise level
        per channel, shared by every recording that channel's sensor
        measured, profiled jointly, so that no recording is given up for the
        others (see :class:`Problem`; the trade-off measured on the
        mismatched truths: docs/identification.md, "One noise level per
        sensor").
    inputs : {"hold", "linear"}
        How the commands and set-points replayed from the recordings vary
        between samples (:attr:`ModelStructure.inputs`): ``hold``
        (default: zero-order hold, a digital controller's output) or
        ``linear`` (an analog signal; docs/identification.md, "Held
        inputs").
    air_properties : str
        For the convection structure (see :func:`fit_structure`).
    max_step : float or None
        Largest integration step (s), see :class:`Problem`.
    offsets : tuple of str
        Quantities given a profiled sensor offset.
    offset_scope : {"recording", "sensor"}
        One profiled offset per recording and channel (default), or one per
        sensor, shared by the recordings of a stage
        (:class:`~pneumafit.identification.problem.Problem`,
        :data:`~pneumafit.identification.problem.OFFSET_SCOPE`).
    initial_nuisance : bool
        Profile the initial-state errors (see :meth:`Problem.linearize`).
    random_starts : int
        Random starts added to the data-driven ones in stages b and c.
    correct_solver : bool
        Defect correction of the fixed-step solver at the joint estimate
        (:meth:`Problem.correct_solver`), kept for the MCMC stages.
    progress : bool
        emcee progress bars.
    extend : float
        Chains shorter than 50 tau or with R-hat > 1.01 are extended up to
        this many times their default length (:data:`DEFAULT_STEPS`); with
        ``steps`` given, chains are exactly that long (and flagged when short).
    seal : {"long", "auto", "on", "off"}
        Friction that grows with the chamber pressures (the
        ``seal_friction`` effect: c (P_P + P_N - 2 P_atm) added to the
        friction levels). ``off`` never tries it; ``auto`` fits c in stage
        (c) after the friction law and keeps it when its log-likelihood gain
        on the step tests, counted in effective samples, exceeds
        ln(n_eff) / 2 (BIC for one parameter) and the held-out step tests'
        pressures do not worsen; ``on`` always keeps it. ``long`` (default)
        is ``auto`` where the fit step tests are long enough to be fitted in
        segments (``segments``; rests at several pressure sums tell c from
        the static friction), ``off`` otherwise: on a sparse plan with one
        short fit step test the coefficient trades with the static friction
        (docs/identification.md). A structure passed as ``model`` keeps its
        own effects.
    early_stop : bool
        Stop a chain at the first check (every 1 / :data:`MCMC_CHECKS` of its
        default length, also while extended) where it is at least 50 tau
        long with every R-hat <= 1.01 (ignored with ``steps``, which gives
        chains of exactly that length).
    robust : bool
        Widen the joint Laplace covariance where the profile likelihood's own
        curvature, or the disagreement between recordings (a sandwich with
        the recordings as clusters), says the estimate is less certain
        (:func:`~pneumafit.identification.optimise.recording_robust_covariance`);
        the MCMC draws are widened by what the sandwich adds to the profile
        curvature they sample. Only ever widens. False: the Laplace and MCMC
        spreads as they are.
    temper : bool
        Count each block's residuals as n / tau independent samples in the
        Laplace covariance and the MCMC, tau their correlation time at the
        joint estimate (:meth:`LogLikelihood.temper`): the intervals of a
        model that does not reach the noise widen by ~sqrt(tau); those of
        one that does are unchanged. False: every sample independent.
    joint_iterations : int
        Limit of the joint least squares (function evaluations per start,
        :data:`JOINT_NFEV`); a joint stage stopped by it is reported as
        unconverged (``quality.unconverged``).
    segments : {"auto", "on", "off"}
        Fit long closed-loop step tests in segments between their set-point
        changes, each from its own fitted initial state (multiple shooting,
        :mod:`~pneumafit.identification.segments`): ``auto`` those of at
        least :data:`~pneumafit.identification.segments.AUTO_DURATION`,
        ``on`` every fit step test, ``off`` none. Held-out recordings are
        always replayed whole.
    """

    mcmc: bool = True
    valve: str = "iso6358"
    friction: str = "auto"
    walkers: int | None = None
    steps: int | None = None
    sample: tuple[str, ...] = DEFAULT_SAMPLE
    channels: tuple[str, ...] = DEFAULT_CHANNELS
    noise: NoiseModel | str | Mapping[str, NoiseModel | str] | None = None
    air_properties: str = "sutherland"
    max_step: float | None = MAX_STEP
    offsets: tuple[str, ...] = ("pressure",)
    offset_scope: str = OFFSET_SCOPE
    initial_nuisance: bool = True
    random_starts: int = 0
    correct_solver: bool = True
    progress: bool = False
    extend: float = 2.0
    seal: str = "long"
    temper: bool = True
    early_stop: bool = True
    joint_iterations: int = JOINT_NFEV
    robust: bool = True
    noise_pooling: str = NOISE_POOLING
    inputs: str = INPUT_MODE
    segments: str = "auto"


@dataclass
class StageResult:
    """One stage of :func:`identify`.

    Attributes
    ----------
    name : str
        ``valve``, ``heat``, ``friction`` or ``joint``.
    recordings : list of str
        Recordings compared.
    free : tuple of str
        Parameters estimated.
    estimate : PointEstimate or None
        Least-squares result (None when the stage was skipped).
    mcmc : MCMCResult or None
        The stage's chain and its summaries (conditional on the other
        groups at the joint estimate).
    propagated : ParameterSet or None
        The summaries with the other groups' joint Laplace uncertainty
        propagated (:func:`~pneumafit.identification.sampling.propagate`);
        these are the ones reported.
    seconds : float
        Wall time of the stage (least squares; MCMC separately in ``mcmc``).
    note : str
        Why a stage was skipped, or "".
    """

    name: str
    recordings: list[str]
    free: tuple[str, ...]
    estimate: PointEstimate | None = None
    mcmc: MCMCResult | None = None
    propagated: ParameterSet | None = None
    seconds: float = 0.0
    note: str = ""

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "recordings": self.recordings,
            "free": list(self.free),
            "seconds": self.seconds,
            "note": self.note,
        }
        if self.estimate is not None:
            e = self.estimate
            out.update(
                log_likelihood=_finite(e.log_likelihood), success=e.success, message=e.message,
                evaluations=e.n_evaluations,
                estimate={n: e.parameters[n].value for n in self.free},
                starts=[{"start": s["start"], "log_likelihood": _finite(s["log_likelihood"]),
                         "nfev": s["nfev"]} for s in e.starts],
            )  # fmt: skip
        if self.mcmc is not None:
            out["mcmc"] = self.mcmc.as_dict()
            cond = self.mcmc.parameters
            out["mcmc"]["conditional"] = {
                n: {"std": cond[n].std, "interval_90": list(cond[n].interval_90 or ()),
                    "median": cond[n].median}
                for n in self.mcmc.names
            }  # fmt: skip
        if self.propagated is not None and self.propagated.correlation is not None:
            names, matrix = self.propagated.correlation
            out["correlation"] = {"names": list(names), "matrix": np.asarray(matrix).tolist()}
        return out


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def campaign_identity(campaign: Campaign) -> dict[str, Any]:
    """``name``, ``path`` and ``sha256`` of a campaign, as fit.json records them."""
    return {
        "name": campaign.name,
        "path": os.fspath(campaign.path) if campaign.path is not None else None,
        "sha256": dict(campaign.sha256),
    }


@dataclass
class FitResult:
    """Result of :func:`identify`.

    Attributes
    ----------
    model : str
        Model name (``convection``, ``constant-lambda``, ``polytropic``).
    structure : ModelStructure
        The structure fitted (heat law, air properties, effects).
    parameters : ParameterSet
        Every parameter: the joint estimate as value; for the sampled
        groups the MCMC ``std``, ``interval_90`` and ``median``
        (``uncertainty="mcmc"``), else the joint Laplace ones.
    laplace : ParameterSet or None
        The joint stage's set with its Laplace uncertainties.
    stages : list of StageResult
    metrics : dict
        ``rmse`` (``fit`` and ``validate``: channel -> SI RMSE),
        ``log_likelihood``, ``aic``, ``bic``, ``n_data``, ``n_parameters``
        ``temperature_probe`` (the probe through which the temperatures are
        compared: ``time_constant``, ``second_time_constant`` in s, ``offset``
        in K; :class:`~pneumafit.simulation.sensor.TemperatureProbe`) and
        ``temperature_sensor_lag`` (s, the probe's total lag).
    warnings : list of str
    seconds : float
        Wall time.
    evaluations : int
        Parameter sets simulated, all stages.
    blocks : list of dict
        The joint problem's compared blocks (recording, channel, samples,
        noise model), in the order of the joint estimate's ``noise``.
    quality : FitQuality or None
        Residual over sensor noise per recording, channel and phase, and
        every other reason not to trust the result (:mod:`.quality`).
    seed : int or None
        The seed the fit was made with (``provenance.seed`` of fit.json).
    options : FitOptions or mapping or None
        The settings it was made with (``provenance.options``); a mapping
        for a friction-test fit (law, effects, mcmc, walkers, steps).
    campaign : dict or None
        The campaign fitted as fit.json records it: ``name``, ``path``,
        ``sha256`` (file -> SHA-256).
    widening : dict of str to float
        Free parameter -> factor (> 1) by which the misspecification-robust
        covariance widened its joint Laplace standard deviation
        (:func:`~pneumafit.identification.optimise.recording_robust_covariance`,
        ``FitOptions.robust``); parameters it left alone are absent.

    :func:`identify` fills every field. :meth:`save` writes fit.json;
    :meth:`load` reads one back as a
    :class:`~pneumafit.identification.fitfile.SavedFit`, the file's typed
    view: stages, Laplace set and chains are not in the file, so a read
    fit is not a ``FitResult``.
    """

    model: str
    structure: ModelStructure
    parameters: ParameterSet
    laplace: ParameterSet | None
    stages: list[StageResult]
    metrics: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    evaluations: int = 0
    blocks: list[dict[str, Any]] = field(default_factory=list)
    quality: FitQuality | None = None
    seed: int | None = None
    options: FitOptions | Mapping[str, Any] | None = None
    campaign: dict[str, Any] | None = None
    widening: dict[str, float] = field(default_factory=dict)

    def save(
        self, path: str | os.PathLike[str], *, command: str = "", chains: str | None = None
    ) -> Path:
        """Write fit.json (:func:`~pneumafit.identification.fitfile.fit_document`), atomically.

        Parameters
        ----------
        path : str or path
            The file (``OUT/fit.json``).
        command : str
            The command line, for ``provenance.command``.
        chains : str, optional
            File name of the MCMC chains beside it (``mcmc.chains.file``).

        Raises
        ------
        PneumafitInputError
            A result without :attr:`campaign` or :attr:`seed` (not made by
            :func:`identify`): use ``fit_document(result, campaign, seed=...)``.
        """
        from pneumafit.identification.fitfile import fit_document, write_fit_json

        return write_fit_json(path, fit_document(self, command=command, chains=chains))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> SavedFit:
        """Read a fit.json (or its folder): see :func:`~pneumafit.identification.fitfile.load_fit`.

        Raises
        ------
        PneumafitInputError
            No file, not JSON, or a bad document (naming the file and key).
        """
        from pneumafit.identification.fitfile import load_fit

        return load_fit(path)

    def __repr__(self) -> str:
        verdict = self.quality.verdict() if self.quality is not None else "not assessed"
        return (
            f"FitResult({self.model}, {len(self.parameters.free)} free parameters, "
            f"log-likelihood {self.metrics.get('log_likelihood', float('nan')):.1f}, "
            f"{self.seconds:.0f} s: {verdict})"
        )

    def summary(self) -> str:
        """The verdict, then the free parameters' table (:meth:`ParameterSet.summary`)."""
        lines = [repr(self)]
        if self.quality is not None:
            lines += [f"  - {p}" for p in self.quality.problems()]
        return "\n".join([*lines, self.parameters.summary()])

    def to_dataframe(self) -> Any:
        """Every parameter as a :class:`pandas.DataFrame` (:meth:`ParameterSet.to_dataframe`)."""
        return self.parameters.to_dataframe()

    def _repr_html_(self) -> str:
        import html

        problems = self.quality.problems() if self.quality is not None else []
        items = "".join(f"<li>{html.escape(p)}</li>" for p in problems)
        return (
            f"<p><b>{html.escape(repr(self))}</b></p>"
            + (f"<ul>{items}</ul>" if items else "")
            + self.parameters._repr_html_()
        )

    def stage(self, name: str) -> StageResult:
        for s in self.stages:
            if s.name == name:
                return s
        raise KeyError(f"no stage {name!r}")

    @property
    def mcmc(self) -> list[MCMCResult]:
        return [s.mcmc for s in self.stages if s.mcmc is not None]


Logger = Callable[[str], None]


def _fit_recordings(campaign: Campaign, kinds: Sequence[str]) -> list[Recording]:
    return [r for r in campaign.by_role("fit") if r.kind in kinds]


def _problem(
    recs: Sequence[Recording],
    structure: ModelStructure,
    values: Mapping[str, float],
    options: FitOptions,
    *,
    initial_nuisance: bool = False,
) -> Problem:
    chans = tuple(options.channels)
    lags = {c: "temperature_sensor_lag" for c in ("T_P", "T_N") if c in chans}
    return Problem(
        recs, structure, values, channels=chans, noise=options.noise, sensor_lags=lags,
        max_step=options.max_step, offsets=options.offsets, offset_scope=options.offset_scope,
        initial_nuisance=initial_nuisance, noise_pooling=options.noise_pooling,
    )  # fmt: skip


def with_initial_states(
    parameters: ParameterSet, problem: Problem, values: Mapping[str, float], free: bool
) -> ParameterSet:
    """Add the problem's initial states as parameters (group ``initial``).

    Bounds: gas temperatures -40/+80 K, position +-2 mm, pressures x0.5..1.5
    around the value in ``values`` (else the problem's data-based default).
    ``free`` makes them free parameters (else fixed at that value), each
    with the Gaussian prior of :meth:`Problem.initial_priors` around the
    data-based default.
    """
    out = parameters
    priors = problem.initial_priors() if free else {}
    for name, (_i, state, default, unit) in problem.initial_parameters.items():
        v = float(values.get(name, default))
        if state.startswith("T"):
            lo, hi = v - 40.0, v + 80.0
        elif state == "y":
            lo, hi = v - 2e-3, v + 2e-3
        else:
            lo, hi = 0.5 * v, 1.5 * v
        # centred on the data's value (or the wall temperature), never on an
        # earlier estimate: a refit from an estimate must not move the prior
        prior = Normal(float(default), priors[name]) if name in priors else None
        par = Parameter(
            name, v, unit, lo, hi, fixed=not free, group="initial", prior=prior,
            description=f"initial {state} of {problem.recordings[_i].file}",
        )  # fmt: skip
        out = (
            out.replace(name, value=v, fixed=not free, prior=prior) if name in out
            else out.add(par)
        )  # fmt: skip
    return out


def _joint_stall(
    problem: Problem, parameters: ParameterSet, start: Mapping[str, float], temper: bool
) -> tuple[int, float]:
    """The joint stage's stall rule at ``start`` (:func:`information_stall`)."""
    like = LogLikelihood(problem, parameters)
    return information_stall(like, parameters.to_internal(dict(start)), scaled=temper)


#: Valve stages of earlier fits in this process, by :func:`_valve_key`
#: (the main job fits three heat laws to one campaign: the flow tests, and so
#: the valve stage, are the same for all three). Oldest dropped first.
_VALVE_STAGES: dict[tuple[Any, ...], tuple[Any, ...]] = {}
#: Largest number of cached valve stages.
VALVE_CACHE_SIZE = 8


def _valve_key(
    campaign: Campaign, structure: ModelStructure, seed: int, opts: FitOptions
) -> tuple[Any, ...] | None:
    """What the valve stage depends on: the campaign's files (hashes), its
    recordings' kinds and roles and rig parameters, the valve law (its fields
    and kernel code), the stage's
    seed and the options the flow problem uses. None for a campaign without
    file hashes (built in memory): such a stage is not cached."""
    if not campaign.sha256:
        return None
    return (
        tuple(sorted(campaign.sha256.items())),
        tuple((r.file, r.kind, r.role) for r in campaign.recordings),
        tuple(sorted(campaign.rig.as_parameters().items())),
        # the law itself, its name, fields and kernel code (whose repr names
        # the function's address): one registered again under its name
        # (replace=True, a notebook's edit) is another law
        repr(VALVE_LAWS[structure.valve]),
        int(seed),
        repr((opts.valve, opts.max_step, opts.noise, opts.channels, opts.offsets,
              opts.initial_nuisance, opts.random_starts, opts.offset_scope)),
    )  # fmt: skip


def _pressure_rms(
    recordings: Sequence[Recording],
    structure: ModelStructure,
    values: Mapping[str, float],
    opts: FitOptions,
) -> float | None:
    """RMS (Pa) of the pressure residuals of ``recordings`` simulated at
    ``values`` (initial states from the data, a sensor offset per recording
    removed); None without recordings or when the simulation fails."""
    if not recordings:
        return None
    try:
        prob = Problem(
            list(recordings), structure, values, channels=("p_P", "p_N"),
            max_step=opts.max_step, initial_nuisance=False, offsets=("pressure",),
            offset_scope="recording",
        )  # fmt: skip
    except ValueError:
        return None
    pred = prob.predict({}, 1)
    if not pred.ok[0]:
        return None
    res = np.concatenate([r[0] for r in prob.residuals(pred)])
    return float(np.sqrt(np.mean(res * res))) if res.size else None


def _stribeck_drop(
    problem: Problem, parameters: ParameterSet, values: Mapping[str, float], seed: int
) -> tuple[ParameterSet, dict[str, str], str]:
    """The friction chain's set with or without the Stribeck drop.

    On a rig whose friction has no drop the recordings' posterior is an L
    (docs/identification.md, "The main job on a campaign none of the presets
    made"): with static on the Coulomb level the Stribeck velocity is free
    over its four decades, and with the velocity under a millimetre a second
    the static level is free up to the actuator's force; no move mixes that.
    Where the joint estimate leaves the drop unresolved
    (:data:`DROP_UNRESOLVED`, :data:`DROP_VELOCITY_FLOOR`), the law with the
    drop and the law without it (friction_static tied to friction_coulomb,
    :data:`DROP_TIE`, the Stribeck velocity held) are both solved on the
    chain's own problem, whose likelihood is tempered (its log-likelihoods
    count effective samples), and the drop is kept when it gains more than
    BIC's penalty for its two parameters, ln n_eff.

    Returns
    -------
    parameters : ParameterSet
        The set to sample (the law without the drop: friction_static and
        stribeck_velocity fixed, at the tied optimum).
    ties : dict
        :data:`DROP_TIE`, or empty when the drop is kept or not tested.
    note : str
        What was tested and decided; empty when nothing was.
    """
    names = ("friction_static", "friction_coulomb", "stribeck_velocity")
    if not set(names) <= set(parameters.free_names):
        return parameters, {}, ""
    f_s, f_c, v_s = (float(values[n]) for n in names)
    floor = float(parameters["stribeck_velocity"].lower)
    if not (f_s <= f_c * (1.0 + DROP_UNRESOLVED) or v_s <= DROP_VELOCITY_FLOOR * floor):
        return parameters, {}, ""
    start = parameters.values()
    full = fit_least_squares(LogLikelihood(problem, parameters), starts=[start], seed=seed)
    tied_set = parameters.with_values({"friction_static": f_c}).with_fixed(list(DROP_HELD))
    tied = fit_least_squares(
        LogLikelihood(problem, tied_set, ties=DROP_TIE), starts=[tied_set.values()], seed=seed
    )
    weights = zip(problem.observations, problem.tempering, strict=True)
    n_eff = float(sum(o.n * w for o, w in weights))
    penalty = math.log(max(n_eff, 2.0))
    gain = full.log_likelihood - tied.log_likelihood
    what = (
        f"the Stribeck drop (friction_static {f_s:.4g} N over friction_coulomb {f_c:.4g} N, "
        f"stribeck_velocity {v_s:.3g} m/s at the joint estimate) tested: the law with it gains "
        f"{gain:.1f} in log-likelihood over the law without it (effective samples) against "
        f"BIC's ln n_eff = {penalty:.1f} for its two parameters"
    )
    if (math.isfinite(gain) and gain > penalty) or not math.isfinite(tied.log_likelihood):
        return parameters, {}, what + ": kept"
    fitted = tied.parameters.values()
    fitted["friction_static"] = fitted["friction_coulomb"]
    return (
        tied_set.with_values(fitted),
        dict(DROP_TIE),
        what + ": not resolved; the chain samples the law without it (friction_static = "
        "friction_coulomb, stribeck_velocity acting on nothing)",
    )


def _least_squares(
    problem: Problem,
    parameters: ParameterSet,
    starts: Sequence[Mapping[str, float]],
    seed: int,
    random_starts: int = 0,
    max_nfev: int = 60,
    stall: tuple[int, float] | None = None,
    progress: Progress | None = None,
    max_reweight: int = 6,
    candidates: Sequence[Mapping[str, float]] = (),
) -> PointEstimate:
    """Multi-start least squares (see :func:`fit_least_squares`)."""
    like = LogLikelihood(problem, parameters)
    return fit_least_squares(
        like, starts=starts, n_random_starts=random_starts, seed=seed, max_nfev=max_nfev,
        stall=stall, progress=progress, max_reweight=max_reweight, candidates=candidates,
    )  # fmt: skip


def _bristles_at_limit(params: ParameterSet, values: dict[str, float], free: Iterable[str]) -> bool:
    """Whether a free LuGre bristle stiffness ends within :data:`BRISTLE_LIMIT`
    of its log range under its upper bound."""
    name = "friction_stiffness"
    if name not in set(free) or name not in values:
        return False
    p = params[name]
    lo, hi, v = p.lower, p.upper, values[name]
    if not (lo > 0 and hi > lo and v > 0):
        return False
    return math.log(hi / v) <= BRISTLE_LIMIT * math.log(hi / lo)


def identify(
    campaign: Campaign,
    model: str | ModelStructure = "convection",
    *,
    options: FitOptions | None = None,
    seed: int = 0,
    chains: str | Path | None = None,
    log: Logger | None = None,
    progress: Reporter | None = None,
) -> FitResult:
    """Identify a model structure from a campaign, stage by stage.

    Parameters
    ----------
    campaign : Campaign
        A valid campaign (:func:`pneumafit.campaign.read_campaign`).
    model : str or ModelStructure
        ``"convection"``, ``"constant-lambda"``, ``"polytropic"`` or a structure.
    options : FitOptions, optional
    seed : int
        Seeds every random choice (random starts, MCMC); same seed, same numbers.
    chains : path, optional
        HDF5 file for the MCMC chains (one group per stage); an interrupted
        run resumes from it.
    log : callable, optional
        Receives one line per step of progress.
    progress : Reporter, optional
        Progress inside each least-squares solve and MCMC chain
        (:mod:`pneumafit.progress`): the stage, the points and simulations so
        far, the log-likelihood, the elapsed time; MCMC steps, acceptance and
        tau. Default: lines to ``log`` at most every
        :data:`~pneumafit.progress.LOG_INTERVAL` seconds. Reporting changes
        no number of the fit.

    Returns
    -------
    FitResult

    Raises
    ------
    PneumafitInputError
        The campaign has no ``fit`` recording.
    PneumafitComputationError
        Every simulation failed at the staged estimates.
    """
    opts = options or FitOptions()
    say = log or (lambda _msg: None)
    reporter = progress if progress is not None else Reporter(say)
    t_start = time.perf_counter()
    name = model if isinstance(model, str) else model.name
    if opts.friction not in (*FRICTION_LAWS, "auto"):
        raise PneumafitInputError(
            f"friction: expected one of {', '.join((*FRICTION_LAWS, 'auto'))}, "
            f"found {opts.friction!r}"
        )
    if opts.seal not in SEAL_MODES:
        raise PneumafitInputError(
            f"seal: expected one of {', '.join(SEAL_MODES)}, found {opts.seal!r}"
        )
    law = "switch" if opts.friction == "auto" else opts.friction
    structure = fit_structure(model, opts.air_properties, opts.valve, law, opts.inputs)
    # long closed-loop step tests in segments (multiple shooting); the fit's
    # campaign identity stays the campaign's as read
    identity = campaign_identity(campaign)
    campaign, segment_lines = segment_step_tests(campaign, opts.segments)
    for line in segment_lines:
        say(line)
    heat_names = tuple(HEAT_PARAMETERS[structure.heat])
    friction_names = tuple(structure.friction_parameter_names)
    rig = campaign.rig.as_parameters()
    nuisance = ["temperature_sensor_lag"] if {"T_P", "T_N"} & set(opts.channels) else []
    params = ParameterSet.for_model(structure, rig, nuisance=nuisance)
    seeds = [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(seed).spawn(8)]
    warns: list[str] = []
    unidentified: list[str] = []  # parameter groups no fit recording informs
    stages: list[StageResult] = []
    evaluations = 0

    flows = _fit_recordings(campaign, ("flow",))
    blocked = _fit_recordings(campaign, ("charge", "discharge"))
    steps = _fit_recordings(campaign, ("step", "free"))
    if not (flows or blocked or steps):
        raise PneumafitInputError(
            f"campaign {campaign.name!r}: expected recordings with role 'fit', found none"
        )
    values = params.values()
    # judged again, not read from campaign.warnings: a Campaign built in
    # Python (a rig's, a test's) was never read, and the checks take ~5 ms
    for line in [*consistency_warnings(campaign), *uncovered_commands(campaign, values)]:
        warns.append(line)
        say(f"warning: {line}")

    joint_stall = STALL_RULE

    def run_stage(
        stage: StageResult,
        recs: list[Recording],
        free: tuple[str, ...],
        starts: list[dict[str, float]],
        stage_seed: int,
        random_starts: int = 0,
        explicit_initial: bool = False,
        label: str | None = None,
        candidates: Sequence[Mapping[str, float]] = (),
    ) -> Problem:
        # stages a-c profile the initial-state errors (cheap, linearised at the
        # first start); the joint stage fits the initial states as parameters
        nonlocal params, evaluations, joint_stall
        t0 = time.perf_counter()
        prob = _problem(recs, structure, values, opts, initial_nuisance=not explicit_initial)
        params = with_initial_states(params, prob, values, free=False)
        ps = with_initial_states(
            params.with_values(values).only_free(free), prob, values, free=explicit_initial
        )
        if not explicit_initial:
            prob.linearize({**ps.values(), **(starts[0] if starts else {})})
        stall = None
        if explicit_initial:
            joint_stall = _joint_stall(prob, ps, starts[0] if starts else {}, opts.temper)
            if joint_stall[1] > STALL_RULE[1]:
                say(
                    f"{stage.name}: residuals correlated at the start; a round stops when it "
                    f"gains less than {joint_stall[1]:.3g} in {joint_stall[0]} points"
                )
            stall = joint_stall
        with reporter.task(label or stage.name) as task:
            est = _least_squares(
                prob,
                ps,
                starts,
                stage_seed,
                random_starts,
                opts.joint_iterations if explicit_initial else 60,
                stall,
                task,
                candidates=candidates,
            )
        stage.estimate, stage.seconds = est, time.perf_counter() - t0
        evaluations += est.n_evaluations
        if math.isfinite(est.log_likelihood):
            values.update(est.parameters.values())
        return prob

    # ------------------------------------------------------------ (a) valve
    valve_free = _informed_valve(
        campaign, values,
        [n for n in params.free_names if _group(n) in _VALVE_GROUPS],
    )  # fmt: skip
    # the centre leakage's parameters: a valve law from outside the package
    # has none the heat stage knows (its own are fitted with the rest of it)
    leak_names = (
        LEAK_PARAMETERS if structure.valve == "iso6358"
        else MAP_LEAK_PARAMETERS if structure.valve == "map" else ()
    )  # fmt: skip
    valve_key = _valve_key(campaign, structure, seeds[0], opts)
    cached = _VALVE_STAGES.get(valve_key) if valve_key is not None and flows else None
    valve_before, warns_before = dict(values), len(warns)
    if structure.valve == "map" and flows and cached is None:
        # the map starts from the ISO 6358 fit of the same flow tests, sampled
        # at its knots; knots no flow level informs stay at that start
        with reporter.task("valve (ISO 6358 start)") as task:
            iso = _iso_valve(campaign, flows, structure, values, opts, seeds[0], task)
        values.update(map_from_iso({**values, **iso}))
        values["valve_m"] = iso["valve_m"]
        # a knot no flow level informs follows the smoothness prior through its
        # neighbours here (physics.valve_map.map_roughness), and in the joint
        # stage also the charge/discharge and step tests whose commands reach
        # it; the centre knots (the paths' leakages) are the heat stage's when
        # no flow level is near 0 V
        unmeasured = _uninformed_knots(campaign, values)
        held = [n for n in unmeasured if n in MAP_LEAK_PARAMETERS]
        shown = [n for n in unmeasured if n not in held and n in valve_free]
        if shown:
            warns.append(
                "valve map: knots without a flow level between their neighbours, left to the "
                "smoothness prior and to the charge/discharge and step tests whose commands "
                "reach them: " + ", ".join(shown)
            )
        valve_free = tuple(n for n in valve_free if n not in held)
        say(f"valve: ISO 6358 start {_brief_values(iso, VALVE_PARAMETERS)}")
    stage = StageResult("valve", [r.file for r in flows], valve_free)
    if cached is not None:
        # the flow tests see the valve only: the stage of an earlier fit of the
        # same campaign, valve law, seed and options is this one
        stage, delta, valve_free, new_warns = copy.deepcopy(cached)
        # counted as the fit's own: the same seed gives the same fit.json
        evaluations += stage.estimate.n_evaluations if stage.estimate is not None else 0
        values.update(delta)
        warns.extend(new_warns)
        say(
            f"valve: the stage of an earlier fit of this campaign reused (same flow tests, "
            f"valve law, seed and options; it took {stage.seconds:.1f} s)"
        )
    elif flows:
        starts = (
            valve_starts(flows, rig) if structure.valve == "iso6358"
            else [dict(s) for s in VALVE_LAWS[structure.valve].starts] or [{}]
        )  # fmt: skip
        values.update(starts[0])
        shapes = tuple(n for n in valve_free if n in SHAPE_PARAMETERS.values())
        knees = tuple(n for n in valve_free if n in KNEE_PARAMETERS.values())
        fulls = tuple(n for n in valve_free if n in FULL_PARAMETERS.values())
        null = tuple(n for n in valve_free if n == NULL_PARAMETER)
        linear = tuple(n for n in valve_free if n not in (*shapes, *knees, *fulls, *null))
        run_stage(stage, flows, linear, starts, seeds[0])
        valve_free, notes = linear, []

        def extended(extra: tuple[str, ...], make_starts: Any) -> float:
            # the law with ``extra`` free from ``make_starts``; its gain
            before_seconds = stage.seconds
            ll = stage.estimate.log_likelihood
            run_stage(stage, flows, (*valve_free, *extra), make_starts(values, extra), seeds[0])
            stage.seconds += before_seconds
            return stage.estimate.log_likelihood - ll

        # the linear ramp nests the shaped law, and the shaped law the knee
        # and saturating ones: each is kept only when the flow tests ask for
        # it (likelihood-ratio tests), so a valve that is a linear ramp keeps
        # the linear law and its fewer parameters
        def test_extra(extra: tuple[str, ...], what: str, make_starts: Any) -> int:
            # the likelihood-ratio test of ``extra`` on the current law: kept
            # (the parameters freed) or not (the law as it was); how many kept
            nonlocal valve_free
            if not extra:
                return 0
            before, before_values = stage.estimate, dict(values)
            gain = extended(extra, make_starts)
            needed = 2.0 * gain > chi2.ppf(SHAPE_CONFIDENCE, len(extra))
            notes.append(
                f"{what} {'kept' if needed else 'not needed'}: log-likelihood gain {gain:.1f} "
                f"({', '.join(extra)})"
            )
            if not needed:
                stage.estimate = before
                values.update(before_values)
                values.update({n: float(SPECS[n].default) for n in extra})
                return 0
            # a path that does not saturate within the flow levels ends at its
            # bound 1, a path without a knee at its bound 1: held there
            at_one = _at_one(extra, values)
            values.update({n: 1.0 for n in at_one})
            valve_free = (*valve_free, *(n for n in extra if n not in at_one))
            return len(extra) - len(at_one)

        test_extra(shapes, "opening shape exponents", _shape_starts)
        # a smooth knee (an S-shaped port) and a corner at full opening (a
        # port uncovered before the end of its stroke) answer one question:
        # both orders are tried (each extra tested on top of the other, then
        # the null offset), and the better law is kept, by log-likelihood
        # less the test's price per kept parameter (half its chi-square
        # quantile); on the bundled demo the two extras' gains on the shaped
        # law tie (252.0 and 250.7), and the order decides the law
        orders = [
            [(knees, "knee exponents", _knee_starts), (fulls, "full-opening fractions",
                                                        _full_starts)],
        ]  # fmt: skip
        if knees and fulls:
            orders.append(orders[0][::-1])
        price = 0.5 * chi2.ppf(SHAPE_CONFIDENCE, 1)
        start_state = (stage.estimate, dict(values), valve_free, list(notes))
        ends = []
        for order in orders:
            stage.estimate, valve_free = start_state[0], start_state[2]
            values.clear()
            values.update(start_state[1])
            notes[:] = start_state[3]
            kept = sum(test_extra(*item) for item in (*order, (null, "null offset",
                                                                _null_starts)))  # fmt: skip
            score = stage.estimate.log_likelihood - price * kept
            ends.append((score, stage.estimate, dict(values), valve_free, list(notes)))
        best = max(ends, key=lambda e: e[0])
        _, stage.estimate, best_values, valve_free, best_notes = best
        values.clear()
        values.update(best_values)
        notes[:] = best_notes
        if len(ends) > 1:
            notes.append(
                "knees and fractions tried in both orders: log-likelihood "
                + " and ".join(
                    f"{e[1].log_likelihood:.1f} ({o[0][1]} first)"
                    for e, o in zip(ends, orders, strict=True)
                )
                + f", the {'first' if best is ends[0] else 'second'} kept"
            )
        for line in notes:
            say(f"valve: {line}")
        # characteristics the flow tests fit about as well: the other order's
        # law, and each path's corner and knee held at a few values (a
        # profile of the shape the flow levels leave open), refitted
        kept_ll = stage.estimate.log_likelihood
        kept_state = (stage.estimate, dict(values), stage.seconds)

        def shape_profile() -> list[tuple[str, float, Mapping[str, float]]]:
            # in a scope of its own: its loop names cannot shadow identify's
            out: list[tuple[str, float, Mapping[str, float]]] = []
            if len(ends) > 1:
                k = 1 if best is ends[0] else 0
                out.append(
                    (f"the law with the {orders[k][0][1]} tested first",
                     ends[k][1].log_likelihood, ends[k][2])
                )  # fmt: skip
            t_variants = time.perf_counter()
            for held, grid in _shape_variants(knees, fulls):
                for value in grid:
                    if abs(float(kept_state[1][held]) - value) < 1e-9:
                        continue
                    values.clear()
                    values.update(kept_state[1])
                    values[held] = value
                    free = tuple(n for n in valve_free if n != held)
                    run_stage(stage, flows, free, [dict(values)], seeds[0])
                    ll = stage.estimate.log_likelihood
                    if math.isfinite(ll):
                        out.append((f"{held} = {value:g}", ll, dict(values)))
            stage.estimate = kept_state[0]
            values.clear()
            values.update(kept_state[1])
            stage.seconds = kept_state[2] + time.perf_counter() - t_variants
            return out

        line = _shape_tie_warning(campaign, kept_ll, kept_state[1], shape_profile())
        if line:
            warns.append(line)
            say(f"warning: {line}")
        stage.free = valve_free
        if notes:
            stage.note = "; ".join(notes)
        say(f"valve: {stage.seconds:.1f} s, log-likelihood {stage.estimate.log_likelihood:.1f}")
        if valve_key is not None:
            delta = {k: v for k, v in values.items() if valve_before.get(k) != v}
            _VALVE_STAGES[valve_key] = copy.deepcopy(
                (stage, delta, valve_free, warns[warns_before:])
            )
            while len(_VALVE_STAGES) > VALVE_CACHE_SIZE:
                _VALVE_STAGES.pop(next(iter(_VALVE_STAGES)))
    else:
        stage.note = "no fit flow test: valve parameters held at their defaults"
        valve_free = ()
        if structure.valve == "iso6358":
            # the charge/discharge and step tests measure the conductances of
            # the paths they open (a rig without a flow meter): fitted with the
            # heat law in stage (b) and in the joint stage
            opened = opened_paths(blocked + steps, values)
            valve_free = tuple(
                CONDUCTANCE_PARAMETERS[p] for p in ("supply", "exhaust") if opened[p]
            )
            if valve_free:
                stage.note = (
                    "no fit flow test: the valve's sonic conductances ("
                    + ", ".join(valve_free)
                    + ") are fitted from the charge/discharge and step tests that open its "
                    "paths, its shape only where the joint stage's likelihood-ratio tests "
                    "ask for it; its flows at commands those tests do not use are extrapolated"
                )
        warns.append(f"valve: {stage.note}")
        stage.free = valve_free
    stages.append(stage)
    if structure.valve == "map" and flows and any(n not in valve_free for n in leak_names):
        # the knots between a held centre and the first measured knot on
        # either side follow it through the smoothness prior: they are fitted
        # with it in stage (b), or the ISO start's centre leakage (25-35x the
        # leak of a table valve whose ISO fit rounds the dead band) stays in
        # the dead band where the rest phases and the closed loops sit
        leak_names = (
            *MAP_LEAK_PARAMETERS, *_dead_band_knots(_uninformed_knots(campaign, values), valve_free)
        )  # fmt: skip

    # -------------------------------------------------------------- (b) heat
    # the centre leakage is fitted here too: the charge/discharge tests' rest
    # phases measure it (the valve rests at 0 V for seconds, at the chamber's
    # own pressures), also where a flow level at 0 V did; a leak held wrong
    # makes the heat law absorb the pressure drift (beta on its bound on an
    # independently written rig; xi 3.5x the truth on a Gaussian-bump leak).
    # Not for the polytropic law with a 0-V flow level: it cannot follow the
    # thermal relaxation, and a free leak would stand in for it
    leak_here = bool(blocked) and (
        structure.heat != "polytropic" or not (flows and centre_measured(campaign, values))
    )
    # without a flow test, the conductances of the paths the charge/discharge
    # tests open are fitted here too (their fillings set them)
    blocked_valve = () if flows else tuple(
        CONDUCTANCE_PARAMETERS[p] for p, ok in opened_paths(blocked, values).items()
        if ok and CONDUCTANCE_PARAMETERS[p] in valve_free
    )  # fmt: skip
    free_heat = heat_names + tuple(nuisance) + (leak_names if leak_here else ()) + blocked_valve
    stage = StageResult("heat", [r.file for r in blocked], free_heat)
    heat_alternatives: list[dict[str, float]] = []
    if blocked:
        starts = heat_starts(structure.heat)
        if leak_here and leak_names:
            full = (
                float(values["valve_C_supply"]) if structure.valve == "iso6358"
                else max(float(values[n]) for n in MAP_CS_NAMES)
            )  # fmt: skip
            starts = _leak_starts(starts, values, leak_names, full)
            stage.note = "the centre leakage is fitted with the heat law (rest phases at 0 V)"
        run_stage(stage, blocked, free_heat, starts, seeds[1], opts.random_starts)
        if len(heat_names) > 1:  # the xi-beta ridge: one-parameter laws have one optimum
            heat_alternatives = _distinct_optima(stage.estimate, heat_names, JOINT_STARTS - 1)
        say(
            f"heat: {stage.seconds:.1f} s, "
            + _brief(stage.estimate, heat_names + leak_names + blocked_valve)
        )
        extensions = tuple(
            n for n in HEAT_LAWS[structure.heat].extensions if n in params.names
        )  # fmt: skip
        both = {r.chamber for r in blocked} >= {"P", "N"}
        if extensions and stage.estimate is not None and not both:
            line = (
                "exchange area's convention held (heat_area_ends 1): the fit charge/discharge "
                "tests cover one chamber"
            )
            say(f"heat: {line}")
            stage.note = "; ".join(x for x in (stage.note, line) if x)
        if extensions and stage.estimate is not None and both:
            # the law's extensions (the exchange area's convention): freed
            # when the charge/discharge tests ask for them (likelihood-ratio
            # test, the gain divided by the residuals' overcount as for the
            # seal friction). Only with both chambers' tests: the rod side's
            # area differs from the bore side's by the rod and the faces,
            # which is what resolves it; one chamber's tests leave it to
            # trade with the heat law (table-valve-asym, sparse plan, seed
            # 2: kept for a gain of 99 effective, at 0.69 after the heat
            # stage and 1.19 in [0, 3] after the joint, every recording
            # worse: fit 10.6x -> 20.3x, held-out 16.8x -> 45.4x)
            before, before_values = stage.estimate, dict(values)
            ll = before.log_likelihood
            t_ext = stage.seconds
            ext_starts = [dict(values)] + [
                {**values, **{n: v for n in extensions}} for v in AREA_STARTS
            ]
            prob = run_stage(stage, blocked, (*free_heat, *extensions), ext_starts, seeds[1],
                             label="heat (area convention)")  # fmt: skip
            stage.seconds += t_ext
            gain = stage.estimate.log_likelihood - ll
            over = _overcount(prob, stage.estimate)
            kept = _passes(gain, over, len(extensions), AREA_CONFIDENCE)
            line = (
                f"exchange area's convention {'kept' if kept else 'not needed'}: log-likelihood "
                f"gain {gain:.1f} / {over:.3g} (residual correlation), "
                + _brief(stage.estimate, extensions)
            )
            say(f"heat: {line}")
            stage.note = "; ".join(x for x in (stage.note, line) if x)
            if kept:
                heat_names = (*heat_names, *extensions)
                stage.free = (*free_heat, *extensions)
                heat_alternatives = [
                    {**alt, **{n: values[n] for n in extensions}} for alt in heat_alternatives
                ]
            else:
                stage.estimate = before
                values.clear()
                values.update(before_values)
    else:
        stage.note = (
            "no fit charge/discharge test: heat parameters from the step tests only"
            if steps
            else "no fit charge/discharge or step test: heat parameters held at their defaults"
        )
        warns.append(f"heat: {stage.note}")
        if not steps and heat_names:
            unidentified.append(
                f"heat law ({', '.join(heat_names)}; no fit charge/discharge or step test)"
            )
    stages.append(stage)

    # ---------------------------------------------------------- (c) friction
    stage = StageResult("friction", [r.file for r in steps], friction_names)
    # the switch law's estimates at this stage, kept when LuGre was chosen:
    # when LuGre's joint bristles end at their limit (_bristles_at_limit), the
    # joint stage solves the switch law from them
    runner_up: dict[str, float] | None = None
    if steps and opts.friction == "auto" and not isinstance(model, ModelStructure):
        # both laws on the step tests, the better by BIC (the chamber tests do
        # not see friction): LuGre's two bristle parameters must buy more than
        # ln(n) in log-likelihood
        before, tried = dict(values), {}
        over = penalty = math.nan
        seconds = 0.0

        # LuGre first: the switch model is then solved from LuGre's levels
        # (its four parameters are LuGre's less the bristles'), and from its
        # own starts only when that solve leaves the choice open
        # (FRICTION_DECISIVE)
        def solve(
            names: tuple[str, ...],
            starts: list[dict[str, float]],
            label: str,
            random_starts: int = 0,
            candidates: Sequence[Mapping[str, float]] = (),
        ) -> tuple[StageResult, dict[str, float], Problem]:
            # one law's solve; the values are put back for the next one
            nonlocal seconds
            trial = StageResult("friction", [r.file for r in steps], names)
            prob = run_stage(trial, steps, names, starts, seeds[2], random_starts, label=label,
                             candidates=candidates)  # fmt: skip
            solved = dict(values)
            values.clear()
            values.update(before)
            seconds += trial.seconds
            return trial, solved, prob

        # the kernel's own laws first; the laws registered from outside with
        # kernel code are compared with the better of the two after
        for cand in ("lugre", "switch"):
            structure = replace(structure, friction=cand)
            params = _with_law(params, structure, rig, nuisance)
            names = tuple(structure.friction_parameter_names)
            starts = friction_starts(steps, rig, cand)
            at_start = seconds
            run = screen = None
            if cand == "switch" and "lugre" in tried:
                levels = {n: tried["lugre"][1][n] for n in names}
                screen = solve(names, [levels], "friction (switch, from LuGre's levels)")
                gain = tried["lugre"][0].estimate.log_likelihood - screen[0].estimate.log_likelihood
                if math.isfinite(gain) and gain / over > FRICTION_DECISIVE * penalty:
                    run = screen
                    say(
                        f"friction (switch): from LuGre's levels, LuGre's gain {gain / over:.1f} "
                        f"effective is over {FRICTION_DECISIVE:g}x the BIC threshold "
                        f"{penalty:.1f}: the switch model's own starts are not solved"
                    )
            if run is None:
                # the solve from LuGre's levels only screens: when the choice
                # is open, the switch model's own optimum decides it, as
                # before (the better of the two flipped a case to the switch
                # model; see FRICTION_DECISIVE)
                run = solve(names, starts, f"friction ({cand})", opts.random_starts,
                            stribeck_candidates(starts[0]))  # fmt: skip
                if screen is not None:
                    say(
                        f"friction ({cand}): log-likelihood "
                        f"{screen[0].estimate.log_likelihood:.1f} from LuGre's levels, "
                        f"{run[0].estimate.log_likelihood:.1f} from its own starts"
                    )
            trial, chosen, prob = run
            tried[cand] = (trial, chosen, prob.n_data, prob)
            say(
                f"friction ({cand}): {seconds - at_start:.1f} s, "
                f"log-likelihood {trial.estimate.log_likelihood:.1f}, "
                + _brief(trial.estimate, names)
            )
            if cand == "lugre":
                # BIC in effective samples, as for the seal friction and the
                # area convention: the gain and n divided by the residuals'
                # overcount at the LuGre optimum (correlated residuals of a
                # model that is not the rig's count each sample many times over)
                over = _overcount(prob, trial.estimate)
                penalty = _ln_n_eff(prob.n_data, over)
        lls = {k: t[0].estimate.log_likelihood for k, t in tried.items()}
        gain = lls["lugre"] - lls["switch"]
        law = "lugre" if _lugre_kept(gain, over, penalty) else "switch"
        stage, chosen, _, _ = tried[law]
        if law == "lugre" and math.isfinite(lls["switch"]):
            runner_up = dict(tried["switch"][1])
        stage.seconds = seconds
        stage.note = (
            f"friction law {law}: LuGre log-likelihood gain {gain:.1f} / {over:.3g} (residual "
            f"correlation) = {gain / over:.1f} over the switch model (BIC threshold "
            f"ln n_eff = {penalty:.1f})"
        )
        say(f"friction: {stage.note}")
        # the laws registered from outside with kernel code, each against the
        # law kept so far
        outside = [f.name for f in hooked_friction_laws()]
        for cand in outside if math.isfinite(over) and math.isfinite(penalty) else ():
            structure = replace(structure, friction=cand)
            params = _with_law(params, structure, rig, nuisance)
            names = tuple(structure.friction_parameter_names)
            trial, solved, _ = solve(names, friction_starts(steps, rig, cand),
                                     f"friction ({cand})", opts.random_starts)  # fmt: skip
            law, stage, chosen = _lower_bic(
                (law, stage, chosen), (cand, trial, solved), over, penalty, say
            )
        if law not in ("lugre", "switch"):
            runner_up = None
        stage.seconds = seconds
        values.update(chosen)
        structure = replace(structure, friction=law)
        params = _with_law(params, structure, rig, nuisance)
        friction_names = tuple(structure.friction_parameter_names)
    elif steps:
        starts = friction_starts(steps, rig, structure.friction)
        run_stage(stage, steps, friction_names, starts, seeds[2], opts.random_starts,
                  candidates=stribeck_candidates(starts[0]))  # fmt: skip
        say(f"friction: {stage.seconds:.1f} s, " + _brief(stage.estimate, friction_names))
    else:
        stage.note = "no fit step test: friction parameters held at their defaults"
        warns.append(f"friction: {stage.note}")
        unidentified.append(f"friction ({', '.join(friction_names)}; no fit step test)")
    # segment_lines: one per fit step test cut into segments (none: none cut)
    if (
        steps and (opts.seal in ("auto", "on") or (opts.seal == "long" and segment_lines))
        and stage.estimate is not None and not isinstance(model, ModelStructure)
    ):  # fmt: skip
        # friction that grows with the chamber pressures (seal preload):
        # kept when its one parameter buys more than ln(n) / 2 (BIC) in the
        # data's effective information (gain and n divided by the residuals'
        # overcount) and does not worsen the held-out step tests (on a sparse
        # plan whose one fit step test could not tell it from the static
        # friction, BIC kept it and the held-out step went from 3.6x to 27x
        # the noise)
        before, plain = dict(values), (structure, params, friction_names)
        structure = structure.with_effects(seal_friction=1)
        params = _with_law(params, structure, rig, nuisance)
        names = (*friction_names, SEAL)
        trial = StageResult("friction", [r.file for r in steps], names)
        starts = seal_starts(steps, rig, values, SEAL)
        prob = run_stage(trial, steps, names, starts, seeds[2], label="friction (seal)")
        base = _without_seal(prob, trial.estimate, before)
        gain = trial.estimate.log_likelihood - base
        over = _overcount(prob, trial.estimate)
        penalty = 0.5 * _ln_n_eff(prob.n_data, over)
        held = [r for r in campaign.by_role("validate") if r.kind in ("step", "free")]
        rms_without = _pressure_rms(held, plain[0], before, opts)
        rms_with = _pressure_rms(held, structure, values, opts)
        validated = rms_with is None or rms_without is None or rms_with <= rms_without
        keep = opts.seal == "on" or (math.isfinite(gain) and gain / over > penalty and validated)
        line = (
            f"pressure-dependent seal friction {'kept' if keep else 'not kept'}: "
            f"log-likelihood gain {gain:.1f} / {over:.3g} (residual correlation) = "
            f"{gain / over:.1f} against BIC's ln(n_eff)/2 = {penalty:.1f}"
            + (
                f", held-out steps' pressure RMS {rms_without:.0f} -> {rms_with:.0f} Pa"
                if rms_with is not None and rms_without is not None else ""
            )
            + f", {SEAL} {trial.estimate.parameters[SEAL].value:.3g} N/Pa"
        )  # fmt: skip
        say(f"friction: {line}")
        if keep:
            trial.seconds += stage.seconds
            trial.note = "; ".join(x for x in (stage.note, line) if x)
            stage, friction_names = trial, names
        else:
            stage.note = "; ".join(x for x in (stage.note, line) if x)
            stage.seconds += trial.seconds
            structure, params, friction_names = plain
            values.clear()
            values.update(before)
    stages.append(stage)

    # ------------------------------------------------------------- (d) joint
    # each fit recording's residual here, fitted by its own stage, is what
    # the quality compares the joint optimum's with (FitQuality.staged)
    staged_values = dict(values)
    # the map's centre knots, held out of stage (a) for want of a 0-V flow
    # level and fitted in stage (b), are free again with everything else
    map_leak = (
        tuple(n for n in MAP_LEAK_PARAMETERS if n not in valve_free)
        if structure.valve == "map" and flows and leak_here else ()
    )  # fmt: skip
    joint_free = tuple(
        [*valve_free, *map_leak, *(heat_names if (blocked or steps) else ()),
         *(friction_names if steps else ()), *nuisance]
    )  # fmt: skip
    all_fit = flows + blocked + steps
    stage = StageResult("joint", [r.file for r in all_fit], joint_free)
    joint_starts = [dict(values)] + [{**values, **alt} for alt in heat_alternatives]
    if len(joint_starts) > 1:
        # several heat-law optima of stage (b): a short joint solve from each,
        # then the best one to convergence (the stages' order cannot lock the
        # fit into the heat law a wrong valve or friction stage suggested)
        t0 = time.perf_counter()
        screen_prob = _problem(all_fit, structure, values, opts)
        ps = with_initial_states(
            params.with_values(values).only_free(joint_free), screen_prob, values, free=True
        )
        with reporter.task("joint (screening the heat-law starts)") as task:
            # one round of JOINT_SCREEN_NFEV iterations per start (the noise
            # weights of the start held): a screen, not a solve
            screen = _least_squares(
                screen_prob, ps, joint_starts, seeds[3], 0, JOINT_SCREEN_NFEV, progress=task,
                max_reweight=1,
            )  # fmt: skip
        evaluations += screen.n_evaluations
        ranked = sorted(
            (r for r in screen.starts if math.isfinite(r["log_likelihood"])),
            key=lambda r: -r["log_likelihood"],
        )
        if ranked:
            best = ranked[0]
            say(
                f"joint: {len(joint_starts)} heat-law starts screened in "
                f"{time.perf_counter() - t0:.1f} s; best " + ", ".join(
                    f"{n} {best['estimate'][n]:.4g}" for n in heat_names if n in best["estimate"]
                )
            )  # fmt: skip
            values.update(best["estimate"])
            stage.note = (
                f"{len(joint_starts)} starts screened ({JOINT_SCREEN_NFEV} iterations each): "
                + "; ".join(f"log-likelihood {r['log_likelihood']:.1f}" for r in ranked)
            )
    joint_problem = run_stage(
        stage, all_fit, joint_free, [dict(values)], seeds[3], explicit_initial=True
    )
    if (
        runner_up is not None
        and stage.estimate is not None
        and _bristles_at_limit(params, values, joint_free)
    ):
        # the friction law of stage (c) was chosen on the step tests with the
        # valve and heat held: LuGre's joint optimum with the bristle
        # stiffness at its limit can be poorer than the switch model's (seed 5
        # of the calibration campaigns: LuGre at -18457, the switch law at
        # -16768). The switch model is solved jointly from its stage-(c)
        # estimates and the better kept by the same BIC rule
        law, solved = "switch", runner_up
        stiffness = values["friction_stiffness"]
        kept_state = (structure, params, joint_free, friction_names, dict(values), joint_stall)
        kept_est, kept_seconds = stage.estimate, stage.seconds
        own = tuple(structure.friction_parameter_names)  # the kept law's (no seal term)
        structure = replace(structure, friction=law)
        params = _with_law(params, structure, rig, nuisance)
        law_names = tuple(structure.friction_parameter_names)
        # the seal friction, when stage (c) kept it, stays with either law
        names = law_names + tuple(n for n in friction_names if n not in own)
        free = tuple(n for n in joint_free if n not in own) + law_names
        start = {**values, **{n: solved[n] for n in law_names if n in solved}}
        start = {k: v for k, v in start.items() if k in law_names or k not in own}
        values.clear()
        values.update(start)
        trial = StageResult("joint", [r.file for r in all_fit], free)
        prob = run_stage(trial, all_fit, free, [start], seeds[3], explicit_initial=True,
                         label=f"joint ({law} friction)")  # fmt: skip
        lugre_est, switch_est = kept_est, trial.estimate
        gain = lugre_est.log_likelihood - switch_est.log_likelihood
        over = _overcount(joint_problem, lugre_est) if math.isfinite(gain) else math.nan
        penalty = _ln_n_eff(joint_problem.n_data, over)
        keep_lugre = not math.isfinite(gain) or _lugre_kept(gain, over, penalty)
        better = "lugre" if keep_lugre else "switch"
        if not math.isfinite(switch_est.log_likelihood):
            better = "lugre"
        if not math.isfinite(lugre_est.log_likelihood):
            better = "switch"
        line = (
            f"friction law {better} kept jointly (LuGre's bristle stiffness {stiffness:.3g} "
            f"N/m, at its limit): LuGre log-likelihood "
            f"{lugre_est.log_likelihood:.1f}, the switch model's {switch_est.log_likelihood:.1f} "
            f"(gain / residual correlation {gain / over:.1f} against ln n_eff = {penalty:.1f})"
        )
        say(f"joint: {line}")
        if better == law:
            # the switch law: its joint optimum is the fit's
            trial.seconds += kept_seconds
            trial.note = "; ".join(x for x in (stage.note, line) if x)
            stage, joint_free, friction_names, joint_problem = trial, free, names, prob
            stages[-1].note = "; ".join(
                x for x in (stages[-1].note, f"replaced in the joint stage: {line}") if x
            )
        else:
            structure, params, joint_free, friction_names, before, joint_stall = kept_state
            values.clear()
            values.update(before)
            stage.seconds = kept_seconds + trial.seconds
            stage.note = "; ".join(x for x in (stage.note, line) if x)
    if not flows and structure.valve == "iso6358" and valve_free:
        # without a flow test the valve law's shape comes from the tests that
        # open its paths: the extensions of stage (a), each kept by a
        # likelihood-ratio test on the joint problem
        extended = _flowless_extensions(valve_free, params.names)
        for extra, what, make_starts in extended:
            before, before_values, before_seconds = stage.estimate, dict(values), stage.seconds
            if before is None or not math.isfinite(before.log_likelihood):
                break
            prob = run_stage(stage, all_fit, (*joint_free, *extra), make_starts(values, extra),
                             seeds[3], explicit_initial=True, label=f"joint ({what})")  # fmt: skip
            stage.seconds += before_seconds
            gain = stage.estimate.log_likelihood - before.log_likelihood
            over = _overcount(prob, stage.estimate)
            kept = _passes(gain, over, len(extra), SHAPE_CONFIDENCE)
            line = (
                f"valve {what} (no flow test) {'kept' if kept else 'not needed'}: "
                f"log-likelihood gain {gain:.1f} / {over:.3g} (residual correlation)"
                + (", " + _brief(stage.estimate, extra) if kept else "")
            )
            say(f"joint: {line}")
            stage.note = "; ".join(x for x in (stage.note, line) if x)
            if kept:
                # a path that opens fully at u_sat, or has no knee, is held there
                # (at the bound 1), as in stage (a)
                at_one = _at_one(extra, values)
                values.update({n: 1.0 for n in at_one})
                extra = tuple(n for n in extra if n not in at_one)
                joint_free, valve_free = (*joint_free, *extra), (*valve_free, *extra)
                joint_problem = prob
                stage.free = joint_free
            else:
                stage.estimate = before
                values.clear()
                values.update(before_values)
    stages.append(stage)
    est = stage.estimate
    if est is not None and math.isfinite(est.log_likelihood) and opts.correct_solver:
        # defect correction of the fixed-step solver, then refit from the estimate
        t0 = time.perf_counter()
        # a fine reference solve of every fit recording (11 s on the demo at
        # load 5): said first, so that a log is not silent meanwhile
        say("joint: correcting the fixed-step solver against a fine reference solution")
        worst = joint_problem.correct_solver(values)
        ps = with_initial_states(
            params.with_values(values).only_free(joint_free), joint_problem, values, True
        )
        with reporter.task("joint (corrected)") as task:
            est2 = _least_squares(joint_problem, ps, [dict(values)], seeds[3], 0,
                                  opts.joint_iterations, joint_stall, task)  # fmt: skip
        evaluations += est2.n_evaluations
        if math.isfinite(est2.log_likelihood):
            est2.starts = est.starts + est2.starts
            est2.n_evaluations += est.n_evaluations
            est = stage.estimate = est2
            values.update(est.parameters.values())
        stage.seconds += time.perf_counter() - t0
        say(f"joint: solver correction up to {worst:.2g} residual sigma")
    if est is None or not math.isfinite(est.log_likelihood):
        raise PneumafitComputationError(
            "joint refinement: every simulation failed at the staged estimates; "
            "check the campaign's rig parameters"
        )
    say(f"joint: {stage.seconds:.1f} s, log-likelihood {est.log_likelihood:.1f}")
    if structure.valve == "iso6358":  # the map's knots are its measured levels
        for line in unbracketed_edges(campaign, est.parameters.values()):
            warns.append(line)
            say(f"warning: {line}")
    like = LogLikelihood(joint_problem, est.parameters)
    if opts.temper:
        # intervals from the data's effective information: each block's
        # likelihood counts its correlated residuals as n / tau samples
        taus = like.temper(est.z)
        say(f"joint: {_tempering_line(joint_problem, taus)}")
    # the robust covariance's Laplace part is the (tempered) Laplace
    # covariance at est.z: one Jacobian gives both
    robust = recording_robust_covariance(like, est.z) if opts.robust else None
    inflation: dict[str, float] = {}
    widening: dict[str, float] = {}
    one_recording: dict[str, str] = {}
    cov = laplace_covariance(like, est.z) if opts.temper and robust is None else None
    if robust is not None:
        cov = robust.covariance
        names = est.parameters.free_names
        # the chains sample the profile likelihood: what the sandwich adds
        inflation = dict(zip(names, robust.beyond_profile.tolist(), strict=True))
        widening = {n: float(f) for n, f in zip(names, robust.inflation, strict=True)
                    if f > 1.0 and est.parameters[n].group != "initial"}  # fmt: skip
        line = _robust_line(widening, robust.clusters)
        say(f"joint: {line}")
        stage.note = "; ".join(x for x in (stage.note, line) if x)
        one_recording = _one_recording(robust, est.parameters)
        if one_recording:
            line = one_recording_caveat(one_recording)
            say(f"joint: {line}")
            stage.note = "; ".join(x for x in (stage.note, line) if x)
    if cov is not None:
        est.covariance = cov
        est.parameters = laplace_summary(est.parameters, est.z, cov)
    laplace = est.parameters
    final = laplace.with_fixed([p.name for p in laplace if p.group == "initial"], fixed=True)
    final.correlation = laplace.correlation

    # -------------------------------------------------------------- MCMC
    heat_draws: dict[str, NDArray[np.float64]] | None = None
    friction_draws: dict[str, NDArray[np.float64]] | None = None
    # the static friction's upper bound when the chain sampled the law without
    # its Stribeck drop (_stribeck_drop); None otherwise
    unresolved_drop: float | None = None
    if opts.mcmc:
        groups = {
            "valve": (flows + blocked, valve_free),
            "heat": (blocked + steps, heat_names + tuple(nuisance)),
            "friction": (steps, friction_names),
        }
        for k, stage_name in enumerate(("valve", "heat", "friction")):
            recs, free = groups[stage_name]
            if stage_name not in opts.sample or not recs:
                continue
            prob = _problem(recs, structure, values, opts, initial_nuisance=opts.initial_nuisance)
            prob.linearize(values)
            if opts.correct_solver:
                prob.correct_solver(values)
            held = laplace.with_values(values).only_free(free)
            ps = with_initial_states(held, prob, values, False)
            like = LogLikelihood(prob, ps)
            if opts.temper:
                like.temper(ps.to_internal())
            ties: dict[str, str] = {}
            if stage_name == "friction":
                ps, ties, drop = _stribeck_drop(prob, ps, values, seeds[4 + k])
                if drop:
                    say(f"mcmc friction: {drop}")
                    stage_obj = next(s for s in stages if s.name == stage_name)
                    stage_obj.note = "; ".join(x for x in (stage_obj.note, drop) if x)
                if ties:
                    like = LogLikelihood(prob, ps, ties=ties)
                    values.update(ps.values())
            post = LogPosterior(like)
            # a wide initial ensemble, not the Laplace ellipse (see run_mcmc)
            cov = None
            n_walkers = opts.walkers or default_walkers(ps.n_free, stage_name)
            n_steps = opts.steps or DEFAULT_STEPS[stage_name]
            check = None if opts.steps or not opts.early_stop else n_steps // MCMC_CHECKS
            say(
                f"mcmc {stage_name}: {n_walkers} walkers x "
                + (f"up to {n_steps} steps, stopped when converged (checked every {check})"
                   if check else f"{n_steps} steps")
            )  # fmt: skip
            # emcee's own bar on a terminal when asked for (opts.progress), and
            # then no live line beside it; the reporter's lines otherwise
            bar = opts.progress and reporter.live
            with nullcontext() if bar else reporter.task(f"mcmc {stage_name}") as task:
                res = run_mcmc(
                    post, ps, ps.to_internal(), cov, n_walkers=n_walkers, n_steps=n_steps,
                    seed=seeds[4 + k], backend=chains, name=stage_name, progress=opts.progress,
                    max_steps=None if opts.steps else int(opts.extend * n_steps), log=say,
                    min_steps=check, report=task, adapt=int(ADAPT_FRACTION * n_steps),
                    adapt_check=int(ADAPT_FRACTION * n_steps) // ADAPT_CHECKS if check else 0,
                )  # fmt: skip
            evaluations += res.evaluations
            res.ties = dict(ties)
            stage_obj = next(s for s in stages if s.name == stage_name)
            stage_obj.mcmc = res
            warns.extend(res.warnings)
            # the groups held fixed: their joint Laplace uncertainty, propagated
            summary, draws = propagate(
                res, laplace, est.covariance, seed=seeds[4 + k], inflation=inflation
            )
            stage_obj.propagated = summary
            if stage_name == "heat":
                heat_draws = {n: v for n, v in res.parameters.to_values(draws).items()}
            if stage_name == "friction":
                friction_draws = {n: v for n, v in res.parameters.to_values(draws).items()}
            point, line = _reported_point(post, ps, res, summary)
            if line:
                say(f"mcmc {stage_name}: {line}")
                warns.append(f"mcmc {stage_name}: {line}")
                stage_obj.note = "; ".join(x for x in (stage_obj.note, line) if x)
            for p in summary.free:
                # the reported estimate and its interval come from the same
                # posterior: the median of the propagated draws, or the most
                # probable draw inside every interval when the medians
                # together are not a typical point (_reported_point); the
                # joint optimum stays in fit.json's stages.joint.estimate
                value = point.get(p.name, p.median if p.median is not None else p.value)
                final = final.replace(
                    p.name, value=value, std=p.std, interval_90=p.interval_90,
                    median=p.median, uncertainty="mcmc",
                )  # fmt: skip
                values[p.name] = value
            for tied, partner in ties.items():
                # a tied parameter is its partner's value and draws (not
                # `name`: the model's name, read after the loop); its interval
                # runs from the partner's lower end to its own upper bound: no
                # drop was resolved, and one the recordings cannot resolve
                # (the velocity under a millimetre a second) can be as high
                # as the bound, as the chain with the drop free showed
                twin = final[partner]
                top = float(final[tied].upper)
                span = (twin.interval_90[0], top) if twin.interval_90 is not None else None
                final = final.replace(
                    tied, value=twin.value, std=None, interval_90=span,
                    median=twin.median, uncertainty="mcmc",
                )  # fmt: skip
                values[tied] = values[partner]
                if friction_draws is not None:
                    friction_draws[tied] = np.array(friction_draws[partner], copy=True)
                unresolved_drop = top
            if ties:
                # without a drop the Stribeck velocity acts on nothing: it
                # is anywhere in its range
                void = final["stribeck_velocity"]
                final = final.replace(
                    "stribeck_velocity", std=None, interval_90=(void.lower, void.upper)
                )
            say(
                f"mcmc {stage_name}: {res.seconds:.1f} s, acceptance {res.acceptance:.2f}, "
                f"chain {res.tau_multiple:.0f} tau"
            )

    # ------------------------------------------- the pressure sensors' offsets
    # from the fit recordings' fitted initial pressures; a held-out recording
    # starts from its readings less them (problem.pressure_offsets)
    offsets = pressure_offsets(
        joint_problem, values,
        {p.name: p.std for p in laplace if p.group == "initial"},
    )  # fmt: skip
    for channel, off in offsets.items():
        if not off.applies:
            continue
        values[f"{OFFSET_PREFIX}{channel}"] = off.value
        final = final.add(
            Parameter(
                f"{OFFSET_PREFIX}{channel}", off.value, "Pa", fixed=True, group="sensor",
                description=f"{channel} sensor's offset: weighted mean over {off.n} fit "
                "recordings of the initial reading less the fitted initial pressure",
            )
        )  # fmt: skip
    if offsets:
        say(
            "pressure sensors' offsets (initial readings less the fitted initial pressures "
            "of the fit recordings started at rest, their weighted mean; taken off the "
            "held-out recordings' initial readings where the recordings agree on it and "
            "pin it down): " + "; ".join(o.describe() for o in offsets.values())
        )

    # ------------------------------------------------------------ metrics
    say("replaying the fit on every recording")
    metrics, rep = _metrics(campaign, structure, values, joint_problem, est, opts)
    if offsets:
        metrics["sensor_offsets"] = {
            c: {
                "value": o.value, "unit": "Pa", "estimates": list(o.estimates),
                "chi_square": o.chi_square, "p_value": o.p_value,
                "standard_error": o.standard_error, "applied": o.applies,
            }
            for c, o in offsets.items()
        }  # fmt: skip
    if blocked or steps:
        # as the friction figures below need a step test: without a test that
        # informs the heat law, lambda is the rig's default, not a figure of
        # this rig (its interval would be one point; quality.not_identified)
        metrics["lambda_reference"] = _lambda_reference(
            structure, values, laplace, est, heat_draws, seeds[7]
        )
    if steps:
        metrics["friction_reference"] = _friction_reference(
            structure, values, rig, laplace, est, friction_draws, seeds[7]
        )
        static = metrics["friction_reference"].get("static")
        if unresolved_drop is not None and static and static.get("interval_90"):
            # no drop resolved: the static figure's interval up to the
            # bound, as the parameter's (the seal term's share as at the value)
            extra = static["value"] - float(values["friction_static"])
            static["interval_90"] = [static["interval_90"][0], unresolved_drop + extra]
    runs = [s.mcmc for s in stages if s.mcmc is not None]
    # the verdict judges every recording's pressures less one zero per sensor:
    # its offset where the fit recordings agree on one (what the held-out
    # recordings' starts take off), else the fit recordings' mean residual
    zeros = rep.verdict_zeros({c: o.value for c, o in offsets.items() if o.applies})
    quality = assess(campaign, rep, final, joint_free, runs, opts.channels,
                     one_recording=one_recording, values=values,
                     max_step=opts.max_step, staged_values=staged_values,
                     fit_recordings=all_fit, zeros=zeros)  # fmt: skip
    quality.unconverged = [
        f"{s.name} ({s.estimate.message})"
        for s in stages
        if s.estimate is not None and not s.estimate.success and s.name == "joint"
    ]
    quality.not_identified = unidentified
    quality.refused_offsets = [o.describe() for o in offsets.values() if not o.applies]
    quality.zeros_applied = sorted(c for c, o in offsets.items() if o.applies)
    say(f"quality: {quality.verdict()}")
    return FitResult(
        model=name, structure=structure, parameters=final, laplace=laplace, stages=stages,
        metrics=metrics, warnings=warns, seconds=time.perf_counter() - t_start,
        evaluations=evaluations, blocks=joint_problem.describe(), quality=quality,
        seed=seed, options=opts, campaign=identity,
        widening=widening,
    )  # fmt: skip


#: The posterior medians, taken together, are a typical point of a stage's
#: posterior when their log posterior is at least this quantile of the kept
#: draws' (a point less probable than 95 % of the draws is not typical).
TYPICAL_QUANTILE = 0.05


def _reported_point(
    post: LogPosterior, ps: ParameterSet, res: MCMCResult, summary: ParameterSet
) -> tuple[dict[str, float], str]:
    """The stage's reported values when its medians are not a typical point.

    Each parameter's posterior median lies inside its 90 % interval, but
    the medians together need not be a point of the posterior: on a ridge
    (the Stribeck velocity against the static friction on a sparse plan)
    the vector of medians sat far off it, and its replay missed a step test
    by 56 mm where the joint optimum fitted it. When the log posterior at
    the medians is below :data:`TYPICAL_QUANTILE` of the kept draws', the
    reported point is the most probable kept draw whose every parameter is
    inside its (propagated) 90 % interval: a point of the same posterior,
    inside every interval. Returns the values to report by name (empty:
    the medians) and a line saying what was done (empty: nothing).
    """
    medians = {p.name: float(p.median) for p in summary.free if p.median is not None}
    if not medians or res.chain.size == 0:
        return {}, ""
    lp_med = float(post(ps.to_internal({**ps.values(), **medians})[None, :])[0])
    kept = res.chain[res.discard :].reshape(-1, len(res.names))
    lp = np.asarray(res.log_prob[res.discard :], dtype=float).reshape(-1)
    ok_lp = np.isfinite(lp)
    if not ok_lp.any():
        return {}, ""
    floor = float(np.quantile(lp[ok_lp], TYPICAL_QUANTILE))
    if math.isfinite(lp_med) and lp_med >= floor:
        return {}, ""
    values = res.parameters.to_values(kept)
    inside = ok_lp.copy()
    for p in summary.free:
        iv = p.interval_90
        if iv is not None and p.name in values:
            v = np.asarray(values[p.name], dtype=float)
            inside &= (v >= iv[0]) & (v <= iv[1])
    if not inside.any():
        return {}, (
            f"the posterior medians together are not a typical point (log posterior "
            f"{lp_med:.1f} below the draws' {TYPICAL_QUANTILE:.0%} quantile {floor:.1f}) and "
            "no draw lies inside every 90 % interval: the medians are reported"
        )
    best = int(np.flatnonzero(inside)[np.argmax(lp[inside])])
    point = {n: float(np.asarray(values[n])[best]) for n in res.names}
    return point, (
        f"the posterior medians together are not a typical point (log posterior {lp_med:.1f} "
        f"below the draws' {TYPICAL_QUANTILE:.0%} quantile {floor:.1f}): the reported "
        f"estimate is the most probable draw inside every 90 % interval (log posterior "
        f"{lp[best]:.1f})"
    )


def _one_recording(robust: RobustCovariance, parameters: ParameterSet) -> dict[str, str]:
    """Free model parameters whose information comes from one recording
    (:attr:`RobustCovariance.informing` below :data:`ONE_RECORDING`), each
    with that recording's name. Initial states and sensor parameters, which
    belong to one recording by construction, are left out."""
    out = {}
    for j, p in enumerate(parameters.free):
        if p.group in ("initial", "sensor"):
            continue
        if 0.0 < robust.informing[j] < ONE_RECORDING:
            out[p.name] = robust.recordings[int(robust.dominant[j])]
    return out


def _robust_line(widening: Mapping[str, float], clusters: int) -> str:
    """One line on the widened intervals (:func:`recording_robust_covariance`)."""
    if not widening:
        return f"intervals: the {clusters} recordings agree within their noise"
    wide = sorted(widening.items(), key=lambda item: item[1], reverse=True)
    top = ", ".join(f"{n} x{f:.1f}" for n, f in wide[:4])
    return (
        f"intervals widened by the profile curvature and the disagreement between the "
        f"{clusters} recordings (sandwich over recordings): {top}"
        + (f" and {len(wide) - 4} more" if len(wide) > 4 else "")
    )


def _tempering_line(problem: Problem, taus: NDArray[np.float64]) -> str:
    """One console line on the residuals' correlation times (see LogLikelihood.temper)."""
    n = np.array([o.n for o in problem.observations], dtype=float)
    worst = int(np.argmax(taus))
    o = problem.observations[worst]
    return (
        f"residuals correlated over {np.median(taus):.3g} samples (median of "
        f"{taus.size} blocks; longest {taus[worst]:.3g} in {o.recording} {o.channel}): "
        f"the intervals count {np.sum(n / taus):.0f} effective samples of {np.sum(n):.0f}"
    )


def _lower_bic(
    kept: tuple[str, StageResult, dict[str, float]],
    other: tuple[str, StageResult, dict[str, float]],
    over: float,
    penalty: float,
    say: Callable[[str], None],
) -> tuple[str, StageResult, dict[str, float]]:
    """``--friction auto``: a friction law registered from outside the package
    against the law kept so far, each given as (name, stage, estimates).

    The one with the lower BIC in effective samples, -2 ll / over + k ln
    n_eff (``over`` the residuals' overcount at the LuGre optimum, ``penalty``
    = ln n_eff), is kept; between LuGre and the switch model the rule above
    is this one for their pair (two more parameters against a gain).
    """

    def bic(name: str, trial: StageResult) -> float:
        ll = trial.estimate.log_likelihood if trial.estimate is not None else -math.inf
        return -2.0 * ll / over + len(FRICTION_PARTS[name].parameters) * penalty

    best, score = bic(kept[0], kept[1]), bic(other[0], other[1])
    better = math.isfinite(score) and score < best
    say(
        f"friction ({other[0]}): BIC in effective samples {score:.1f} against {best:.1f} "
        f"({kept[0]}): " + ("kept" if better else "not kept")
    )
    if not better:
        return kept
    other[1].note = (
        f"friction law {other[0]}: BIC in effective samples {score:.1f} against {best:.1f} "
        f"for {kept[0]} ({kept[1].note})"
    )
    return other


def _brief(est: PointEstimate, names: Sequence[str]) -> str:
    return ", ".join(f"{n} {est.parameters[n].value:.4g}" for n in names if n in est.parameters)


#: Channels of the RMSE metrics (every sample of every recording).
RMSE_CHANNELS = ("p_P", "p_N", "y", "T_P", "T_N", "qm_P", "qm_N")


def _metrics(
    campaign: Campaign,
    structure: ModelStructure,
    values: Mapping[str, float],
    joint_problem: Problem,
    est: PointEstimate,
    options: FitOptions,
) -> tuple[dict[str, Any], Replay]:
    """RMSE per role and channel, log-likelihood, AIC, BIC (see FitResult), and the replay."""
    n_data = joint_problem.n_data
    k = est.parameters.n_free + joint_problem.n_noise_parameters
    ll = est.log_likelihood
    rep = replay(campaign, structure, values, channels=RMSE_CHANNELS, max_step=options.max_step)
    metrics = {
        "rmse": rep.rmse(),
        "log_likelihood": _finite(ll),
        "aic": _finite(2 * k - 2 * ll),
        "bic": _finite(k * math.log(max(n_data, 1)) - 2 * ll),
        "n_data": n_data,
        "n_parameters": k,
        "temperature_sensor_lag": rep.lag,
        "temperature_probe": rep.probe.as_dict() if rep.probe is not None else None,
    }
    return metrics, rep


def _lambda_reference(
    structure: ModelStructure,
    values: Mapping[str, float],
    laplace: ParameterSet,
    est: PointEstimate,
    draws: Mapping[str, NDArray[np.float64]] | None,
    seed: int,
) -> dict[str, Any] | None:
    """lambda at the reference state with its 90 % interval (metrics.lambda_reference).

    From the heat stage's propagated MCMC draws when sampled, else from 4000
    draws of the joint Laplace approximation; the value is the draws' median,
    so that it lies inside its own interval. ``full_area_equivalent`` is
    lambda A_P / A_P,full, chamber P's exchange at mid-stroke on the area that
    counts every wall (heat_area_ends 1): the figure that compares fits, and
    rigs, whose area conventions differ.
    """
    if structure.heat == "polytropic":
        return None
    names = (*HEAT_PARAMETERS[structure.heat], *HEAT_LAWS[structure.heat].extensions)
    if draws is None:
        draws = _laplace_draws(laplace, est, seed)

    def figures(sample: Mapping[str, Any]) -> tuple[Any, Any]:
        lam = np.asarray(reference_lambda(sample, structure.heat, structure.air_properties))
        return lam, lam * _full_area_share(sample)

    point, point_full = (float(x) for x in figures(values))
    out: dict[str, Any] = {
        "state": dict(REFERENCE_STATE), "value": point, "interval_90": None,
        "full_area_equivalent": {"value": point_full, "interval_90": None},
    }  # fmt: skip
    if draws is not None and all(n in draws for n in HEAT_PARAMETERS[structure.heat]):
        sample = {**values, **{n: np.asarray(draws[n]) for n in names if n in draws}}
        lam, full = figures(sample)
        lam, full = np.broadcast_arrays(lam, full)
        ok = np.isfinite(lam) & np.isfinite(full)
        _summarise(out, lam[ok])
        _summarise(out["full_area_equivalent"], full[ok])
    return out


def _full_area_share(values: Mapping[str, Any]) -> Any:
    """A_P / A_P,full of chamber P at mid-stroke (physics.geometry; SI values;
    ``heat_area_ends`` may be an array of draws)."""
    geo = [float(values[n]) for n in ("stroke", "bore", "rod", "dead_volume_P", "dead_volume_N")]
    y = 0.5 * geo[0]
    ends = np.asarray(values.get("heat_area_ends", 1.0), dtype=float)
    area = exchange_areas.py_func(y, *geo, ends)[0]
    return area / exchange_areas.py_func(y, *geo, 1.0)[0]


def _laplace_draws(
    laplace: ParameterSet, est: PointEstimate, seed: int, n: int = 4000
) -> dict[str, NDArray[np.float64]] | None:
    """``n`` draws (values by name) of the joint Laplace approximation; None
    without one.

    Each draw is held to the parameter sets the model accepts: its internal
    coordinates clipped to the bounds, and projected onto every
    :data:`~.parameters.CONSTRAINTS` inequality (:func:`_feasible_draws`:
    the static friction at least the Coulomb level), which the kernel
    enforces by refusing the set. Until 2026-12-06 the draws that broke it
    were kept: on a sparse campaign of step tests alone, whose estimate sits
    on the constraint, the summary quoted a static friction at mid pressure
    of 31.91 N against a Coulomb level of 31.98 N, the static interval's
    lower end 0.7 N below the Coulomb one's, a friction the model cannot
    have."""
    if est.covariance is None:
        return None
    rng = np.random.default_rng(seed)
    cov = 0.5 * (est.covariance + est.covariance.T)
    # drawn in equilibrated coordinates (unit variances), then scaled: the
    # internal coordinates' variances span ~20 decades (initial pressures in
    # Pa^2 against a seal coefficient's 1e-18 (N/Pa)^2), and an
    # eigendecomposition of the raw matrix leaks rounding of the largest
    # eigenvalues into the smallest directions (a seal coefficient of std
    # 1.4e-9 N/Pa was drawn with a spread of ~1e-5 N/Pa, and the friction at
    # mid pressure got a 90 % interval of +-7.4 N instead of +-0.2 N)
    s = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    unit = np.where(s > 0.0, s, 1.0)
    corr = cov / np.outer(unit, unit)
    # a pseudo-inverse of J^T J: positive semi-definite up to rounding, whose
    # tiny negative eigenvalues numpy would report as a warning on the console
    u = rng.multivariate_normal(np.zeros(s.size), corr, size=n, method="eigh", check_valid="ignore")
    z = est.z + u * s
    lo, hi = laplace.internal_bounds()
    return _feasible_draws(laplace.to_values(np.clip(z, lo, hi)))


def _feasible_draws(draws: Mapping[str, NDArray[np.float64]]) -> dict[str, NDArray[np.float64]]:
    """``draws`` (name -> values, one per draw) projected onto the
    :data:`~.parameters.CONSTRAINTS` inequalities: where a draw has the
    larger side below the smaller (a set the kernel refuses), the larger is
    set to the smaller (the static friction to the Coulomb level: the law
    without a Stribeck drop).

    This is what the draws' clipping to the bounds does at a bound, and for
    an estimate on a constraint it is the estimate's own distribution: the
    Gaussian projected onto the allowed side, a share of it on the boundary
    itself (Self and Liang, JASA 82, 1987, after Chernoff 1954). Dropped
    instead of projected (a truncated Gaussian), the draws of an estimate
    whose static level sat on the Coulomb one undetermined (Dahl truth,
    sparse plan, seed 1, 2026-12-06: a standard deviation of 18 in its log,
    the Coulomb level's 0.009) kept only the static levels above the Coulomb
    one, nearly all clipped at the force ceiling: "563 N [112, 563]" for an
    estimate of 37.0 N; projected, 37.8 N [36.6, 563]. A constraint whose
    two sides are not both drawn changes nothing."""
    out = {k: np.asarray(v, dtype=float) for k, v in draws.items()}
    for larger, smaller, _ in CONSTRAINTS:
        if larger in out and smaller in out:
            out[larger] = np.maximum(out[larger], out[smaller])
    return out


def _friction_reference(
    structure: ModelStructure,
    values: Mapping[str, float],
    rig: Mapping[str, float],
    laplace: ParameterSet,
    est: PointEstimate,
    draws: Mapping[str, NDArray[np.float64]] | None,
    seed: int,
) -> dict[str, Any]:
    """Static and Coulomb friction with both chambers at mid pressure (metrics.friction_reference).

    With the ``seal_friction`` effect the levels grow by c (P_P + P_N -
    2 P_atm); at P_P = P_N = (P_S + P_atm) / 2 that is c (P_S - P_atm),
    the state at which a rig's friction is usually quoted. Without it the
    levels are the parameters themselves. ``sliding`` is the steady sliding
    friction at 50 mm/s less its viscous part at the same pressures
    (:func:`~pneumafit.identification.reference.reference_sliding`): the
    Coulomb level plus what remains of the Stribeck drop there. Values are
    the medians of the friction stage's propagated MCMC draws when sampled,
    else of 4000 draws of the joint Laplace approximation, with their 90 %
    intervals. A friction law that does not name a level (a law from outside
    the package, e.g. Dahl's, without a static level) has no entry for it,
    and ``sliding`` needs all three of F_s, F_c and v_s.
    """
    delta = float(rig["supply_pressure"] - rig["exhaust_pressure"])
    seal = SEAL if structure.effects.get("seal_friction") else None
    out: dict[str, Any] = {"pressure_sum": delta, "seal_friction": seal is not None}
    if draws is None or not all(n in draws for n in ("friction_static", "friction_coulomb")):
        draws = _laplace_draws(laplace, est, seed)
    for key, name in (("static", "friction_static"), ("coulomb", "friction_coulomb")):
        if name not in values:
            continue
        c = float(values.get(seal, 0.0)) if seal else 0.0
        entry: dict[str, Any] = {"value": float(values[name]) + c * delta, "interval_90": None}
        if draws is not None and name in draws:
            level = np.asarray(draws[name], dtype=float)
            if seal:
                level = level + np.asarray(draws.get(seal, c), dtype=float) * delta
            _summarise(entry, level)
        out[key] = entry
    c = float(values.get(seal, 0.0)) if seal else 0.0
    names = ("friction_static", "friction_coulomb", "stribeck_velocity")
    if not all(n in values for n in names):
        return out
    sliding: dict[str, Any] = {
        "velocity": SLIDING_VELOCITY,
        "value": float(reference_sliding(values, c * delta)),
        "interval_90": None,
    }
    if draws is not None and all(n in draws for n in names):
        extra = np.asarray(draws.get(seal, c), dtype=float) * delta if seal else 0.0
        _summarise(sliding, reference_sliding({n: draws[n] for n in names}, extra))
    out["sliding"] = sliding
    return out


def _summarise(entry: dict[str, Any], draws: Any) -> None:
    """Set ``entry``'s ``value`` and ``interval_90`` to the median and the 5 and
    95 % quantiles of the finite ``draws`` (unchanged when none is finite)."""
    x = np.asarray(draws, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if x.size:
        entry["value"] = float(np.median(x))
        entry["interval_90"] = [float(np.quantile(x, 0.05)), float(np.quantile(x, 0.95))]


def assess(
    campaign: Campaign,
    rep: Replay,
    parameters: ParameterSet,
    free: Sequence[str],
    runs: Sequence[MCMCResult],
    channels: Sequence[str],
    *,
    one_recording: Mapping[str, str] | None = None,
    values: Mapping[str, float] | None = None,
    max_step: float | None = MAX_STEP,
    staged_values: Mapping[str, float] | None = None,
    fit_recordings: Sequence[Recording] = (),
    zeros: Mapping[str, float] | None = None,
) -> FitQuality:
    """Everything that says whether a fit can be trusted (:mod:`.quality`);
    ``one_recording``: parameter -> the one recording its interval rests on
    (:func:`_one_recording`); ``values`` (the replay's, with the fitted
    initial states) and ``max_step``: replay the closed-loop step tests whose
    piston rests elsewhere with the recorded commands too
    (:attr:`FitQuality.recorded_commands`; not without ``values``);
    ``staged_values`` (the estimate before the joint refinement): replay
    ``fit_recordings`` with it (:attr:`FitQuality.staged`); ``zeros``
    (pressure channel -> Pa): taken off every recording's pressure residual,
    and from the staged and recorded-command replays' too (a channel without
    one is judged as read); default :meth:`Replay.sensor_zeros` of ``rep``."""
    recs = {r.file: r for r in campaign.recordings}
    rest = [
        offset
        for r in rep.recordings
        if r.ok and r.file in recs
        for offset in rest_offsets(recs[r.file], r.simulated)
    ]
    # one zero per pressure sensor: nothing fitted to a held-out recording
    # enters its figure
    zeros = rep.sensor_zeros() if zeros is None else dict(zeros)
    at_bounds = bound_problems(parameters, free)
    quality = FitQuality(
        channels=assess_residuals(campaign, rep.sensor_offset_free(zeros), channels),
        at_bounds=at_bounds,
        outside_interval=interval_problems(parameters),
        unreliable=chain_problems(runs),
        undetermined=undetermined_problems(parameters, free, at_bounds),
        one_recording=dict(one_recording or {}),
        rest_positions=rest,
        sensor_zeros=zeros,
    )
    if staged_values is not None and fit_recordings:
        quality.staged = _staged_ratios(
            campaign, fit_recordings, rep.structure, staged_values, channels, max_step, zeros
        )
    if values is not None:
        named = [recs[r.recording] for r in quality.stops_elsewhere()]
        quality.recorded_commands = _recorded_commands(
            campaign, named, rep.structure, values, max_step, zeros
        )
    return quality


def _staged_ratios(
    campaign: Campaign,
    recordings: Sequence[Recording],
    structure: ModelStructure,
    values: Mapping[str, float],
    channels: Sequence[str],
    max_step: float | None,
    zeros: Mapping[str, float],
) -> dict[str, float]:
    """Largest RMS over noise of the fitted ``channels`` of each of
    ``recordings`` replayed with ``values`` (:attr:`FitQuality.staged`), the
    pressures less ``zeros`` as the verdict's; no entry for a recording
    whose replay fails."""
    rep = replay(list(recordings), structure, values, channels=tuple(channels),
                 estimate_lag=False, max_step=max_step)  # fmt: skip
    ok = {r.file for r in rep.recordings if r.ok}
    worst = FitQuality(
        assess_residuals(campaign, rep.sensor_offset_free(zeros), channels)
    ).worst_fitted()
    return {f: v for f, v in worst.items() if f in ok}


def _recorded_commands(
    campaign: Campaign,
    recordings: Sequence[Recording],
    structure: ModelStructure,
    values: Mapping[str, float],
    max_step: float | None,
    zeros: Mapping[str, float] | None = None,
) -> dict[str, float | None]:
    """Largest pressure RMS over noise of each closed-loop step test of
    ``recordings`` replayed with the recorded commands instead of the model's
    controller (:func:`~pneumafit.identification.replay.with_recorded_commands`;
    :attr:`FitQuality.recorded_commands`), less the pressure sensors'
    ``zeros`` (Pa, :meth:`Replay.sensor_zeros` of the fit's replay; default:
    those of each test's own replay when it is a fit recording, none for a
    held-out one); None where that replay fails, no entry for a test that
    cannot be driven so."""
    out: dict[str, float | None] = {}
    for rec in recordings:
        opened = with_recorded_commands(rec)
        if opened is None:
            continue
        rep = replay([opened], structure, values, channels=("p_P", "p_N"), max_step=max_step)
        ratios = [
            c.ratio
            for c in assess_residuals(campaign, rep.sensor_offset_free(zeros), ())
            if c.ratio is not None
        ]
        out[rec.file] = max(ratios) if ratios and rep.recordings[0].ok else None
    return out
