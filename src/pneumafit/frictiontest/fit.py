"""Staged identification of the friction law from friction tests (``--model friction``).

The estimator stack is the one of the other models: the profile
log-likelihood of :class:`~pneumafit.identification.likelihood.LogLikelihood`
(one Gaussian block per recording, sigma profiled), the multi-start
reweighted least squares of :func:`~pneumafit.identification.optimise.fit_least_squares`,
each block tempered by its residuals' correlation time (intervals in
effective samples), Laplace intervals, and optionally emcee
(:func:`~pneumafit.identification.sampling.run_mcmc`). Only the problem,
:class:`FrictionTestProblem`, is new: the force balance of
:mod:`.model` on every fit recording.

Stages:

1. ``sliding``: Coulomb level and viscous coefficient from the steady-sliding
   samples (|v| above 60 % of the median speed), static law.
2. ``law``: three laws fitted to every sample from stage 1, each jointly:
   ``coulomb-viscous`` (no Stribeck drop), ``stribeck`` (+ F_s, v_st) and
   ``lugre`` (+ pre-sliding: bristle stiffness and damping); the law with
   the lowest BIC in effective samples is kept ("pre-sliding where the data
   ask"). The tempering power is set once, at the stage-1 estimate on all
   samples, one power for all samples (:func:`_common_power`), and shared
   by every candidate, so their likelihoods compare.
3. ``effects`` (``effects="auto"``): the optional terms of :data:`.model.EFFECTS`
   added one at a time, greedily, each kept when it lowers BIC (forward
   selection); each step's comparison at the tempering power of the current
   structure's residuals.
   When an effect is kept, the law is chosen again with the effects free
   (``law-with-effects``; its tempering power recomputed at the effects'
   estimate).
4. ``joint``: the chosen structure, its Laplace covariance, then MCMC.

The quality verdict is the same as for the other models: residual RMS over
the load cell's noise per recording (noise from quiet windows of the data,
:func:`~pneumafit.identification.quality.estimate_noise`), estimates at
bounds, chains.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import Campaign
from pneumafit.frictiontest.model import (
    EFFECTS,
    KERNEL_ORDER,
    STATIC_STIFFNESS,
    FrictionTest,
    default_parameters,
    prepare,
)
from pneumafit.identification.likelihood import LogLikelihood, LogPosterior
from pneumafit.identification.noise import Gaussian
from pneumafit.identification.optimise import (
    PointEstimate,
    fit_least_squares,
    laplace_covariance,
    laplace_summary,
)
from pneumafit.identification.parameters import ParameterSet
from pneumafit.identification.quality import (
    FitQuality,
    assess_residuals,
    bound_problems,
    chain_problems,
    estimate_noise,
    interval_problems,
    undetermined_problems,
)
from pneumafit.identification.sampling import run_mcmc
from pneumafit.identification.staged import (
    ADAPT_CHECKS,
    ADAPT_FRACTION,
    MCMC_CHECKS,
    FitResult,
    StageResult,
    campaign_identity,
)
from pneumafit.progress import Reporter

__all__ = ["LAWS", "FrictionStructure", "FrictionTestProblem", "identify_friction"]

#: Friction laws compared in stage 2 -> parameters they free.
LAWS: dict[str, tuple[str, ...]] = {
    "coulomb-viscous": ("friction_coulomb", "friction_viscous"),
    "stribeck": ("friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity"),
    "lugre": (
        "friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity",
        "friction_stiffness", "friction_damping",
    ),
}  # fmt: skip
#: Default MCMC length (steps, adaptation included): the chain stops earlier
#: once converged (``run_mcmc(min_steps=)``) and is extended up to twice
#: this while it is not.
DEFAULT_FRICTION_STEPS = 3000
#: Steady sliding: speed above this fraction of the recording's median speed.
SLIDING_FRACTION = 0.6
#: Stribeck velocity that hides the Stribeck drop (m/s): exp(-(v/v_st)^2) = 0
#: for every sliding speed of the bench (> 1 mm/s).
NO_STRIBECK = 1e-5


@dataclass(frozen=True)
class FrictionStructure:
    """What was fitted: the friction law and the effects (fit.json ``structure``)."""

    friction: str
    effects: Mapping[str, float] = field(default_factory=dict)
    name: str = "friction-test"
    heat: str | None = None
    air_properties: str | None = None
    valve: str | None = None
    inputs: str | None = None


class FrictionTestProblem:
    """The force balance on friction tests, as the likelihood needs a problem.

    Parameters
    ----------
    tests : sequence of FrictionTest
    samples : sequence of index arrays, optional
        The samples compared in each test (default all).
    floors : sequence of float, optional
        Lower bound of each test's profiled sigma [N] (the sensor noise).
    pooled : bool, optional
        One Gaussian block for every test, one sigma (default): the tests
        share one load cell, so one noise level. Per-test blocks
        (``pooled=False``) profile one sigma per test, which weighs each test
        by the inverse square of its own misfit: where model error dominates
        (here 8-100x the load cell's noise) the tests the law fits worst, the
        high pressures, count least, and a pressure dependence fitted that
        way extrapolates worse (Kidney_lc, Coulomb-viscous with area and
        seal friction on 1, 3, 5 bar: 7-bar RMSE 7.64 N per test, 7.13 N
        pooled, the plain least-squares regression's). Per-test blocks serve
        the correlation times of :func:`_common_power`.
    """

    def __init__(
        self,
        tests: Sequence[FrictionTest],
        samples: Sequence[NDArray[np.int64]] | None = None,
        floors: Sequence[float] | None = None,
        pooled: bool = True,
    ) -> None:
        self.tests = list(tests)
        self.samples = list(samples) if samples is not None else [np.arange(t.n) for t in tests]
        self.floors = list(floors) if floors is not None else [0.0] * len(self.tests)
        self.pooled = pooled
        if pooled:
            self.observations = [
                SimpleNamespace(noise=Gaussian(), floor=min(self.floors, default=0.0),
                                weight=None, recording="+".join(t.file for t in self.tests),
                                channel="F", n=int(sum(idx.size for idx in self.samples)))
            ]  # fmt: skip
        else:
            self.observations = [
                SimpleNamespace(noise=Gaussian(), floor=f, weight=None, recording=t.file,
                                channel="F", n=int(idx.size))
                for t, idx, f in zip(self.tests, self.samples, self.floors, strict=True)
            ]  # fmt: skip
        self.tempering = np.ones(len(self.observations))
        self.lag_names: tuple[str, ...] = ()
        self.n_evaluations = 0

    def predict(self, values: Mapping[str, Any], n_sets: int) -> SimpleNamespace:
        """Predicted rod forces of every test for a batch of parameter sets."""
        self.n_evaluations += n_sets
        cols = [np.broadcast_to(np.asarray(values[k], float), (n_sets,)) for k in KERNEL_ORDER]
        params = np.stack(cols, axis=1)
        model = [t.predict(params)[:, idx] for t, idx in zip(self.tests, self.samples, strict=True)]
        ok = np.ones(n_sets, bool)
        for m in model:
            ok &= np.all(np.isfinite(m), axis=1)
        return SimpleNamespace(ok=ok, model=model)

    def residuals(self, prediction: SimpleNamespace) -> list[NDArray[np.float64]]:
        out = [
            t.force[idx][None, :] - m
            for t, idx, m in zip(self.tests, self.samples, prediction.model, strict=True)
        ]
        return [np.concatenate(out, axis=1)] if self.pooled else out

    def log_weight(self, index: int) -> float:
        return 0.0


def _structure_set(base: ParameterSet, law: str, effects: Sequence[str]) -> ParameterSet:
    """``base`` with the law's and the effects' parameters free, the others fixed."""
    free = set(LAWS[law]) | set(effects)
    ps = base
    for p in base:
        ps = ps.replace(p.name, fixed=p.name not in free)
    if law != "lugre":
        ps = ps.replace("friction_stiffness", value=STATIC_STIFFNESS)
        ps = ps.replace("friction_damping", value=0.0)
    if law == "coulomb-viscous":
        ps = ps.replace("stribeck_velocity", value=NO_STRIBECK)
        ps = ps.replace("friction_static", value=ps["friction_coulomb"].value)
    return ps


def _fresh_start(sliding: Mapping[str, float], law: str) -> dict[str, float]:
    """Start values of ``law``'s parameters from the sliding stage, effects neutral."""
    start = {p.name: p.value for p in default_parameters() if p.name in LAWS[law]}
    start.update({k: sliding[k] for k in ("friction_coulomb", "friction_viscous")})
    if "friction_static" in start:
        start["friction_static"] = 1.5 * sliding["friction_coulomb"]
    if law == "lugre":
        start["friction_stiffness"] = 1e5
    return start


def _common_power(like: LogLikelihood, z: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """One tempering power for every sample, 1 / (median correlation time) at ``z``.

    Per-block powers (as :meth:`LogLikelihood.temper` sets) would reweigh the
    recordings against each other by how badly the current model fits each
    (a pressure-independent law fits the 1-bar test best, so its residuals
    are the least correlated and it would dominate). One common power leaves
    the optimum of the untempered likelihood where it is, so the least
    squares run untempered (a likelihood scaled by 1/6000 stops the solver
    at its gradient tolerance) and the power enters BIC, the Laplace
    covariance and MCMC. Returns each block's correlation time and the
    power; the problem is left untempered.
    """
    p = like.problem
    per_test = FrictionTestProblem(p.tests, p.samples, p.floors, pooled=False)
    taus = LogLikelihood(per_test, like.parameters).temper(z)
    p.n_evaluations += per_test.n_evaluations
    return taus, 1.0 / float(np.median(taus))


def _bic(like: LogLikelihood, est: PointEstimate, power: float) -> tuple[float, float]:
    """(BIC, effective samples) at a common power: -2 power log L + k ln(power n)."""
    n_eff = power * float(sum(o.n for o in like.problem.observations))
    return -2.0 * power * est.log_likelihood + like.parameters.n_free * math.log(n_eff), n_eff


def _bics(results: Mapping[str, tuple[Any, Any, float]]) -> str:
    return ", ".join(f"{k} {v[2]:.1f}" for k, v in results.items())


def _compare_laws(
    problem: FrictionTestProblem,
    start: ParameterSet,
    candidates: Sequence[str],
    effects: Sequence[str],
    power: float,
    seed: int,
    say: Callable[[str], None],
) -> dict[str, tuple[LogLikelihood, PointEstimate, float]]:
    """Fit each candidate law (with ``effects`` free) from ``start``; BIC at ``power``."""
    fitted = start.values()
    results: dict[str, tuple[LogLikelihood, PointEstimate, float]] = {}
    for name in candidates:
        ps = _structure_set(start, name, effects)
        starts: list[dict[str, float]] = [{}]
        if name != "coulomb-viscous":
            fc = fitted["friction_coulomb"]
            starts = [{"friction_static": 1.5 * fc + 0.1, "stribeck_velocity": 2e-3}]
        prev = results.get("stribeck")
        if name == "lugre" and prev is not None:
            seeds = prev[1].parameters.values()
            starts = [
                {**{k: seeds[k] for k in (*LAWS["stribeck"], *effects)},
                 "friction_stiffness": k0, "friction_damping": 0.0}
                for k0 in (1e4, 1e5, 1e6)
            ]  # fmt: skip
        like, est = _fit(problem, ps, starts=starts, seed=seed)
        bic, _n_eff = _bic(like, est, power)
        results[name] = (like, est, bic)
        say(f"law {name}: log L {est.log_likelihood:.1f}, BIC {bic:.1f} (effective samples)")
    return results


def _fit(
    problem: FrictionTestProblem,
    ps: ParameterSet,
    starts: Sequence[Mapping[str, float]] | None = None,
    seed: int = 0,
) -> tuple[LogLikelihood, PointEstimate]:
    like = LogLikelihood(problem, ps)
    est = fit_least_squares(like, starts=starts, seed=seed, max_nfev=80, max_reweight=4)
    return like, est


def _stage(name: str, tests: Sequence[FrictionTest], est: PointEstimate, t0: float,
           note: str = "") -> StageResult:  # fmt: skip
    return StageResult(
        name=name, recordings=[t.file for t in tests], free=est.parameters.free_names,
        estimate=est, seconds=time.perf_counter() - t0, note=note,
    )  # fmt: skip


def identify_friction(
    campaign: Campaign,
    *,
    law: str = "auto",
    effects: str = "off",
    mcmc: bool = True,
    walkers: int | None = None,
    steps: int | None = None,
    seed: int = 0,
    chains: str | Path | None = None,
    log: Callable[[str], None] | None = None,
    progress: Reporter | None = None,
) -> FitResult:
    """Fit the friction law to the force balance of a campaign's friction tests.

    Parameters
    ----------
    campaign : Campaign
        With ``friction`` recordings; ``fit`` ones are fitted, ``validate``
        ones only replayed.
    law : {"auto", "coulomb-viscous", "stribeck", "lugre"}
        ``auto``: the lowest BIC (effective samples) of the three.
    effects : {"off", "auto", "on"}
        ``auto``: add the terms of :data:`~pneumafit.frictiontest.model.EFFECTS`
        one at a time while BIC falls; ``on``: all of them.
    mcmc : bool
        Sample the joint posterior with emcee after the least squares.
    walkers, steps : int, optional
        Default 4 n_free (at least 16) and :data:`DEFAULT_FRICTION_STEPS`,
        stopped at the first check (every 1 / ``MCMC_CHECKS`` of it) where
        the chain is >= 50 tau long with every R-hat <= 1.01, extended up
        to twice that while it is not; ``steps`` gives exactly that many.
    seed : int
    chains : path, optional
        emcee HDF5 backend (group ``friction``).
    log : callable, optional
        Receives one line per stage.
    progress : Reporter, optional
        Progress of the MCMC (steps, acceptance, tau); default lines to
        ``log`` at most every :data:`pneumafit.progress.LOG_INTERVAL` s.

    Returns
    -------
    FitResult
        ``model`` ``"friction"``; ``metrics`` has ``rmse`` (role -> F),
        ``rmse_by_recording``, ``noise_F`` (load cell noise per recording),
        ``laws`` (BIC of each candidate), ``effects`` (BIC path), ``aic``,
        ``bic``, ``n_data``, ``n_effective``, ``n_parameters``.

    Raises
    ------
    PneumafitInputError
        No fit recording of kind ``friction``, or an unknown law/effects.
    """
    say = log or (lambda _line: None)
    if law not in ("auto", *LAWS):
        raise PneumafitInputError(f"friction law: expected auto, {', '.join(LAWS)}, found {law!r}")
    if effects not in ("off", "auto", "on"):
        raise PneumafitInputError(f"effects: expected off, auto or on, found {effects!r}")
    started = time.perf_counter()
    recs = [r for r in campaign.by_kind("friction") if r.role == "fit"]
    if not recs:
        raise PneumafitInputError(
            "expected at least one fit recording of kind friction, found none "
            "(a friction fit needs imposed-motion friction tests)"
        )
    tests = prepare(campaign, recs)
    noise = {}
    for rec in campaign.by_kind("friction"):
        sigma, _n = estimate_noise(rec, "F")
        noise[rec.file] = sigma
    floors = [0.5 * (noise[t.file] or 0.0) for t in tests]
    stages: list[StageResult] = []
    warnings: list[str] = []

    # stage 1: steady sliding, static law, Coulomb + viscous
    t0 = time.perf_counter()
    sliding = []
    for t in tests:
        speed = np.abs(t.velocity)
        sliding.append(np.flatnonzero(speed > SLIDING_FRACTION * np.median(speed)))
    base = default_parameters()
    cv = _structure_set(base, "coulomb-viscous", ())
    problem1 = FrictionTestProblem(tests, sliding, floors)
    _, est1 = _fit(problem1, cv, seed=seed)
    stages.append(_stage("sliding", tests, est1, t0, "steady-sliding samples, static law"))
    say(f"sliding: F_c {est1.parameters['friction_coulomb'].value:.3g} N, "
        f"b {est1.parameters['friction_viscous'].value:.3g} N s/m")  # fmt: skip

    # tempering at the stage-1 estimate on every sample, shared by all candidates
    problem = FrictionTestProblem(tests, None, floors)
    like0 = LogLikelihood(problem, est1.parameters)
    taus, power = _common_power(like0, est1.z)
    say("tempering: correlation time " + ", ".join(
        f"{t.file} {tau:.0f}" for t, tau in zip(tests, taus, strict=True))
        + f"; every sample counted at 1 / {1.0 / power:.0f}")  # fmt: skip

    # stage 2: the law
    t0 = time.perf_counter()
    candidates = (law,) if law != "auto" else tuple(LAWS)
    results = _compare_laws(problem, est1.parameters, candidates, (), power, seed, say)
    chosen = min(results, key=lambda k: results[k][2])
    like, est, bic = results[chosen]
    stages.append(_stage("law", tests, est, t0, f"chosen {chosen} by BIC: " + _bics(results)))

    # stage 3: effects, forward selection by BIC
    effect_path: list[dict[str, Any]] = []
    kept: list[str] = []
    if effects == "auto":
        t0 = time.perf_counter()
        remaining = list(EFFECTS)
        # a second start away from the law's optimum without the effect: that
        # optimum bent the law to mimic the effect (a Stribeck curve standing in
        # for pressure-dependent friction), a local minimum once the effect is free
        fresh = _fresh_start(est1.parameters.values(), chosen)
        while remaining:
            # each step compares the current structure with one more effect at
            # the power of the current structure's residuals: a step that fixed
            # the largest misfit shortens the correlation time of the next
            step_power = _common_power(like, est.z)[1] if kept else power
            bic = _bic(like, est, step_power)[0]
            trials = {}
            for eff in remaining:
                ps = _structure_set(est.parameters, chosen, (*kept, eff))
                lk, es = _fit(problem, ps, starts=[{}, fresh], seed=seed)
                trials[eff] = (lk, es, _bic(lk, es, step_power)[0])
            best = min(trials, key=lambda k: trials[k][2])
            effect_path.append({"added": best, "bic": trials[best][2], "bic_before": bic,
                                "power": step_power, "kept": trials[best][2] < bic})  # fmt: skip
            say(
                f"effect {best}: BIC {trials[best][2]:.1f} (was {bic:.1f}; every sample "
                f"counted at 1 / {1.0 / step_power:.0f})"
            )
            if trials[best][2] >= bic:
                break
            like, est, bic = trials[best]
            kept.append(best)
            remaining.remove(best)
        stages.append(_stage("effects", tests, est, t0, "kept: " + (", ".join(kept) or "none")))
    elif effects == "on":
        t0 = time.perf_counter()
        kept = list(EFFECTS)
        fresh = _fresh_start(est1.parameters.values(), chosen)
        like, est = _fit(
            problem, _structure_set(est.parameters, chosen, kept), starts=[{}, fresh], seed=seed
        )
        bic = _bic(like, est, power)[0]
        stages.append(_stage("effects", tests, est, t0, "all effects (--seal-friction on)"))
    if kept and law == "auto":
        # the law again, with the effects: the base law's residuals (one offset
        # per recording) counted each test as a few samples, too few to tell
        # the laws apart; with the effects the correlation time is ~100x shorter
        t0 = time.perf_counter()
        _, power = _common_power(like, est.z)
        say(f"law again with {', '.join(kept)}: every sample counted at 1 / {1.0 / power:.0f}")
        results = _compare_laws(problem, est.parameters, tuple(LAWS), kept, power, seed, say)
        chosen = min(results, key=lambda k: results[k][2])
        like, est, bic = results[chosen]
        stages.append(
            _stage("law-with-effects", tests, est, t0, f"chosen {chosen} by BIC: " + _bics(results))
        )

    # joint: the chosen structure's estimate, tempered at itself, Laplace and MCMC
    final_taus, final_power = _common_power(like, est.z)
    problem.tempering = np.full(len(problem.observations), final_power)
    cov = laplace_covariance(like, est.z)
    est.covariance = cov
    est.parameters = laplace_summary(est.parameters, est.z, cov)
    say(f"joint: every sample counted at 1 / {1.0 / final_power:.0f} (median "
        "correlation time of the residuals at the estimate)")  # fmt: skip
    joint = StageResult(name="joint", recordings=[t.file for t in tests],
                        free=est.parameters.free_names, estimate=est)  # fmt: skip
    stages.append(joint)
    parameters = est.parameters
    runs = []
    if mcmc:
        t0 = time.perf_counter()
        n_free = parameters.n_free
        n_walkers = walkers or max(16, 4 * n_free)
        post = LogPosterior(like)
        # as the chamber fits sample: a DE phase from the Laplace ellipse, then
        # the Student-t proposal fitted to it; without ``steps``, checked
        # every 1/MCMC_CHECKS of the default length and stopped at >= 50 tau
        # with R-hat <= 1.01, extended up to twice the length while short
        n_steps = steps or DEFAULT_FRICTION_STEPS
        check = None if steps else n_steps // MCMC_CHECKS
        with (progress or Reporter(say)).task("mcmc friction") as task:
            run = run_mcmc(
                post, parameters, est.z, est.covariance, n_walkers=n_walkers,
                n_steps=n_steps, seed=seed, backend=chains, name="friction", log=say,
                report=task, adapt=int(ADAPT_FRACTION * n_steps), min_steps=check,
                adapt_check=int(ADAPT_FRACTION * n_steps) // ADAPT_CHECKS if check else 0,
                max_steps=None if steps else 2 * n_steps,
            )  # fmt: skip
        joint.mcmc = run
        joint.propagated = run.parameters
        runs.append(run)
        say(f"mcmc: {run.n_steps} steps x {run.n_walkers} walkers, acceptance "
            f"{run.acceptance:.2f}, {time.perf_counter() - t0:.0f} s")  # fmt: skip
        # the reported estimate and its interval come from the same posterior:
        # the chain's median (the joint optimum stays in stages' joint estimate),
        # as the chamber fits report it; an optimum on a bound (F_c at 0) is
        # otherwise outside its own interval, which cannot hold the bound
        parameters = run.parameters
        for p in run.parameters.free:
            if p.median is not None:
                parameters = parameters.replace(p.name, value=p.median)
        warnings += run.warnings

    # replay every friction test (fit and validate) at the reported estimate
    values = {p.name: p.value for p in parameters}
    all_tests = prepare(campaign)
    residuals = []
    by_rec: dict[str, float] = {}
    sq: dict[str, list[float]] = {"fit": [], "validate": []}
    for t in all_tests:
        pred = t.predict(np.array([[values[k] for k in KERNEL_ORDER]]))[0]
        r = t.force - pred
        residuals.append((t.file, "F", np.arange(t.n), r))
        by_rec[t.file] = float(np.sqrt(np.mean(r * r)))
        sq[t.role].extend((r * r).tolist())
    rmse = {role: {"F": float(np.sqrt(np.mean(v)))} for role, v in sq.items() if v}
    at_bounds = bound_problems(parameters, parameters.free_names)
    quality = FitQuality(
        channels=assess_residuals(campaign, residuals, ["F"]),
        at_bounds=at_bounds,
        outside_interval=interval_problems(parameters),
        unreliable=chain_problems(runs),
        undetermined=undetermined_problems(parameters, parameters.free_names, at_bounds),
        unconverged=[] if est.success else [f"joint: {est.message}"],
    )  # fmt: skip
    n_data = int(sum(o.n for o in problem.observations))
    k = parameters.n_free + len(problem.observations)  # + one sigma per block
    _, n_eff = _bic(like, est, power)
    metrics = {
        "rmse": rmse,
        "rmse_by_recording": by_rec,
        "noise_F": noise,
        "law": chosen,
        "laws": {
            name: {
                "bic": v[2],
                "log_likelihood": v[1].log_likelihood,
                "free": list(v[1].parameters.free_names),
            }
            for name, v in results.items()
        },
        "effects": {"kept": kept, "path": effect_path},
        "log_likelihood": est.log_likelihood,
        "aic": -2.0 * est.log_likelihood + 2 * k,
        "bic": bic,
        "n_data": n_data,
        "n_effective": n_eff,
        "n_parameters": k,
        "tempering_tau": {t.file: float(tau) for t, tau in zip(tests, final_taus, strict=True)},
        "tempering_tau_selection": {t.file: float(tau) for t, tau in zip(tests, taus, strict=True)},
        "tempering_power": final_power,
        "tempering_power_selection": power,
    }
    blocks = [{"recording": o.recording, "channel": "F", "samples": o.n, "noise": "gaussian"}
              for o in problem.observations]  # fmt: skip
    return FitResult(
        model="friction",
        structure=FrictionStructure(  # type: ignore[arg-type]
            friction=chosen, effects={e: values[e] for e in kept}
        ),
        parameters=parameters,
        laplace=est.parameters,
        stages=stages,
        metrics=metrics,
        warnings=warnings,
        seconds=time.perf_counter() - started,
        evaluations=problem.n_evaluations + problem1.n_evaluations,
        blocks=blocks,
        quality=quality,
        seed=seed,
        options={"law": law, "effects": effects, "mcmc": mcmc, "walkers": walkers, "steps": steps},
        campaign=campaign_identity(campaign),
    )
