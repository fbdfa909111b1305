"""Discovery on friction tests: the rod-force residual, effect signatures, refits.

``pneumafit discover CAMPAIGN --fit FIT --out OUT`` on a campaign of friction
tests (a fit.json of model ``friction``) runs :func:`discover_friction`, the
friction-test counterpart of :func:`pneumafit.discovery.refit.discover`:

1. The base fit (its law, no effect) is replayed on every friction test;
   the residual is the measured rod force minus the predicted one, r = F - F^.
2. Each effect of :data:`FRICTION_EFFECTS` has a *signature*: the
   sensitivity of the predicted force to its parameter at the neutral value,
   s_e = dF^/d theta_e (a forward difference through the force kernel, so
   the signature is the model's own, LuGre state included). For the steady
   sliding law they are::

       seal friction   dF/dc_p  = -sign(v) (p_P - p_atm)      (N/Pa)
       asymmetry       dF/da    = -g(v)                        (N)
       effective area  dF/dk_A  = (p_P - p_atm) A_nominal      (N)

   Each signature is regressed on the residual of the fit recordings alone
   (least squares through the origin): the share of the residual it explains
   (R^2 alone) ranks the candidates and its coefficient starts the refit.
3. Refits, one round per effect: the top-ranked remaining candidate is
   refitted (its parameter freed, started at the signature's coefficient and
   at a fresh start of the law); it is kept when BIC in effective samples
   falls (each block counted at the common tempering power of the current
   structure's residuals, as ``fit --seal-friction auto`` does) *and* the
   force RMSE on the validate recordings does not rise by more than 2 %.
   Otherwise the next candidate of the ranking is tried. A round that keeps
   nothing ends the search; each later round ranks the remaining candidates
   on the new residual.
4. With an effect kept, the friction law is chosen again by BIC with the
   effects free (the base law's residual is one offset per recording, too
   correlated for BIC to tell the laws apart).

The validate recordings (the held-out pressures) are never fitted; their
RMSE only vetoes a refit that extrapolates worse, so the held-out
improvement reported is that of a model whose parameters never saw them,
chosen with a veto that did.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.campaign.model import Campaign
from pneumafit.frictiontest.fit import (
    LAWS,
    FrictionTestProblem,
    _bic,
    _common_power,
    _compare_laws,
    _fit,
    _fresh_start,
    _structure_set,
)
from pneumafit.frictiontest.model import (
    FRICTION_EFFECTS,
    KERNEL_ORDER,
    FrictionEffect,
    FrictionTest,
    default_parameters,
    prepare,
)
from pneumafit.identification.fitfile import SavedFit
from pneumafit.identification.optimise import laplace_covariance, laplace_summary
from pneumafit.identification.quality import estimate_noise

__all__ = [
    "FRICTION_EFFECTS",
    "Candidate",
    "FrictionDiscovery",
    "FrictionEffect",
    "discover_friction",
    "force_rmse",
    "signature",
]

#: A refit may raise the validate force RMSE by this factor and still be kept
#: (the refit's own optimiser tolerance moves the held-out RMSE by ~1 %).
VALIDATE_TOLERANCE = 1.02


def _matrix(values: Mapping[str, float]) -> NDArray[np.float64]:
    return np.array([[float(values[k]) for k in KERNEL_ORDER]])


def force_rmse(tests: Sequence[FrictionTest], values: Mapping[str, float]) -> dict[str, Any]:
    """Force RMSE (N) by role (``fit``, ``validate``) and by recording at ``values``."""
    sq: dict[str, list[NDArray[np.float64]]] = {}
    by_rec: dict[str, float] = {}
    m = _matrix(values)
    for t in tests:
        r = t.force - t.predict(m)[0]
        sq.setdefault(t.role, []).append(r * r)
        by_rec[t.file] = float(np.sqrt(np.mean(r * r)))
    by_role = {role: float(np.sqrt(np.mean(np.concatenate(v)))) for role, v in sq.items()}
    return {"role": by_role, "recording": by_rec}


def signature(test: FrictionTest, values: Mapping[str, float], effect: FrictionEffect) -> Any:
    """dF^/d theta of ``effect`` at ``values`` on one test (forward difference)."""
    shifted = dict(values)
    shifted[effect.parameter] = float(values[effect.parameter]) + effect.step
    both = test.predict(np.vstack([_matrix(values), _matrix(shifted)]))
    return (both[1] - both[0]) / effect.step


@dataclass
class Candidate:
    """A ranked effect: how much of the residual its signature explains alone."""

    parameter: str
    r2: float
    coefficient: float
    start: float

    def as_dict(self) -> dict[str, Any]:
        eff = FRICTION_EFFECTS[self.parameter]
        return {
            "effect": eff.name, "parameter": self.parameter, "score": self.r2,
            "evidence": {"variance_explained": self.r2, "coefficient": self.coefficient,
                         "coefficient_unit": eff.unit, "start": self.start,
                         "supported": self.r2 > 0.0 and self.start != self.neutral},
        }  # fmt: skip

    @property
    def neutral(self) -> float:
        return float(default_parameters()[self.parameter].value)


def rank(
    tests: Sequence[FrictionTest], values: Mapping[str, float], remaining: Sequence[str]
) -> list[Candidate]:
    """Rank the ``remaining`` effect parameters by the residual share of their signature.

    Only the ``fit`` tests enter. The start of each refit is the parameter's
    current value plus the regression coefficient, clipped to its bounds.
    """
    fit_tests = [t for t in tests if t.role == "fit"]
    m = _matrix(values)
    r = np.concatenate([t.force - t.predict(m)[0] for t in fit_tests])
    ss = float(r @ r)
    base = default_parameters()
    out = []
    for name in remaining:
        eff = FRICTION_EFFECTS[name]
        s = np.concatenate([signature(t, values, eff) for t in fit_tests])
        den = float(s @ s)
        coef = float(s @ r) / den if den > 0 else 0.0
        r2 = (coef * float(s @ r)) / ss if ss > 0 else 0.0
        p = base[name]
        start = min(max(float(values[name]) + coef, p.lower), p.upper)
        out.append(Candidate(name, r2, coef, start))
    return sorted(out, key=lambda c: -c.r2)


@dataclass
class FrictionDiscovery:
    """Result of :func:`discover_friction` (every RMSE in N, force ``F``).

    Attributes
    ----------
    base_law, final_law : str
    selected : list of str
        The kept effect parameters, in the order kept.
    rounds : list of dict
        Each round's ranked candidates (:meth:`Candidate.as_dict`).
    refits : list of dict
        Every refit: round, effect, start, BIC before/after, validate RMSE,
        kept, reason.
    rmse_before, rmse_after : dict
        ``role`` -> RMSE and ``recording`` -> RMSE.
    bic_before, bic_after : float
        At the common tempering power of the base fit's residuals (compare
        the two with that power; each refit's decision used its own).
    values_before, values_after : dict
        Every kernel parameter.
    effect_parameters : dict
        Kept parameter -> value, unit, std, Laplace 90 % interval, effect.
    residuals_before, residuals_after : dict
        file -> (gauge pressure, residual) arrays, for the figures.
    seconds : float
    """

    base_law: str
    final_law: str
    selected: list[str]
    rounds: list[list[dict[str, Any]]]
    refits: list[dict[str, Any]]
    rmse_before: dict[str, Any]
    rmse_after: dict[str, Any]
    bic_before: float
    bic_after: float
    log_likelihood_before: float
    log_likelihood_after: float
    values_before: dict[str, float]
    values_after: dict[str, float]
    effect_parameters: dict[str, Any]
    noise: dict[str, float | None]
    seed: int
    seconds: float
    tests: list[FrictionTest] = field(default_factory=list, repr=False)

    @property
    def statement(self) -> str:
        b = self.rmse_before["role"].get("validate")
        a = self.rmse_after["role"].get("validate")
        if not self.selected:
            return "No effect lowered BIC without worsening the held-out tests: none selected."
        names = ", ".join(FRICTION_EFFECTS[p].name for p in self.selected)
        if b and a:
            return (
                f"Selected {names}; held-out force RMSE {b:.3g} N -> {a:.3g} N "
                f"({100.0 * (a - b) / b:+.0f} %)."
            )
        return f"Selected {names}."

    def __repr__(self) -> str:
        return (
            f"FrictionDiscovery({self.base_law} -> {self.final_law}; selected "
            f"{', '.join(self.selected) or 'none'}; {len(self.refits)} refits, "
            f"{self.seconds:.0f} s)"
        )

    def summary(self) -> str:
        """One line per refit (effect, BIC change, held-out RMSE, decision), then the statement."""
        lines = [repr(self)]
        for r in self.refits:
            lines.append(f"  round {r.get('round')}: {r.get('effect')}: {r.get('reason', '')}")
        return "\n".join([*lines, self.statement])


def base_values(fit_doc: Mapping[str, Any] | SavedFit) -> tuple[str, dict[str, float]]:
    """The law and the kernel parameter values of a friction fit.json
    (:meth:`FitResult.load <pneumafit.identification.staged.FitResult.load>`,
    or its parsed document)."""
    fit = fit_doc if isinstance(fit_doc, SavedFit) else SavedFit.from_document(fit_doc)
    law = (fit.document.get("structure") or {}).get("friction")  # no fallback: a bench law
    if law not in LAWS:
        raise PneumafitInputError(
            f"fit.json key 'structure.friction': expected one of {', '.join(LAWS)}, found {law!r}"
        )
    values = default_parameters().values()
    for name, value in {**fit.values, **fit.nuisance}.items():
        if name in values:
            values[name] = value
    return law, values


def discover_friction(
    campaign: Campaign,
    fit_doc: Mapping[str, Any] | SavedFit,
    *,
    seed: int = 0,
    rounds: int = 3,
    per_round: int = 3,
    law_again: bool = True,
    log: Callable[[str], None] | None = None,
) -> FrictionDiscovery:
    """Discovery on the friction tests of ``campaign`` from a base friction fit.

    Parameters
    ----------
    campaign : Campaign
        Friction tests; ``fit`` ones are refitted, ``validate`` ones held out.
    fit_doc : SavedFit or mapping
        The base fit.json (model ``friction``), as read by
        :meth:`FitResult.load <pneumafit.identification.staged.FitResult.load>`.
        Effects it already holds are kept as they are (not candidates).
    seed : int
        Seed of the refits' multi-start.
    rounds, per_round : int
        Largest number of rounds (one kept effect each), and refits tried per round.
    law_again : bool
        Choose the law again by BIC once an effect is kept.
    log : callable, optional
        Receives one line per step.

    Returns
    -------
    FrictionDiscovery
    """
    say = log or (lambda _line: None)
    started = time.perf_counter()
    fit = fit_doc if isinstance(fit_doc, SavedFit) else SavedFit.from_document(fit_doc)
    law, values = base_values(fit)
    already = [k for k in fit.effects if k in FRICTION_EFFECTS]
    recs = [r for r in campaign.by_kind("friction") if r.role == "fit"]
    if not recs:
        raise PneumafitInputError(
            "expected at least one fit recording of kind friction, found none"
        )
    tests = prepare(campaign, recs)
    all_tests = prepare(campaign)
    noise = {rec.file: estimate_noise(rec, "F")[0] for rec in campaign.by_kind("friction")}
    floors = [0.5 * (noise[t.file] or 0.0) for t in tests]
    problem = FrictionTestProblem(tests, None, floors)

    # the base fit, reconverged from its values (its likelihood and z)
    ps = _structure_set(default_parameters(), law, already)
    for k, v in values.items():
        ps = ps.replace(k, value=min(max(v, ps[k].lower), ps[k].upper))
    like, est = _fit(problem, ps, starts=[{}], seed=seed)
    _, power0 = _common_power(like, est.z)
    bic0 = _bic(like, est, power0)[0]
    base_est_values = est.parameters.values()
    loglike0 = float(est.log_likelihood)
    # "before" is the base fit as written; the refits start from its
    # reconverged estimate (the base fit's solver may have stopped short)
    rmse0 = force_rmse(all_tests, values)
    val_now = force_rmse(all_tests, base_est_values)["role"].get("validate")
    say(
        f"base {law}: force RMSE fit {rmse0['role'].get('fit', math.nan):.3g} N, validate "
        f"{rmse0['role'].get('validate', math.nan):.3g} N; BIC {bic0:.1f} (every sample "
        f"counted at 1 / {1.0 / power0:.0f})"
    )
    kept = list(already)
    remaining = [k for k in FRICTION_EFFECTS if k not in kept]
    history: list[list[dict[str, Any]]] = []
    refits: list[dict[str, Any]] = []
    current_law = law
    for rnd in range(1, rounds + 1):
        if not remaining:
            break
        cur = est.parameters.values()
        ranked = rank(all_tests, cur, remaining)
        history.append([c.as_dict() for c in ranked])
        say(f"round {rnd}: " + ", ".join(
            f"{FRICTION_EFFECTS[c.parameter].name} R^2 {c.r2:.3f}" for c in ranked))  # fmt: skip
        _, step_power = _common_power(like, est.z)
        bic_now = _bic(like, est, step_power)[0]
        added = None
        for cand in ranked[:per_round]:
            eff = FRICTION_EFFECTS[cand.parameter]
            trial = _structure_set(est.parameters, current_law, (*kept, cand.parameter))
            fresh = {**_fresh_start(base_est_values, current_law), cand.parameter: cand.start}
            lk, es = _fit(problem, trial, starts=[{cand.parameter: cand.start}, fresh], seed=seed)
            bic = _bic(lk, es, step_power)[0]
            rm = force_rmse(all_tests, es.parameters.values())
            val = rm["role"].get("validate")
            better_bic = bic < bic_now
            val_ok = val is None or val_now is None or val <= VALIDATE_TOLERANCE * val_now
            ok = better_bic and val_ok
            reason = (
                "kept: BIC lower, held-out RMSE not worse"
                if ok
                else ("rejected: BIC not lower" if not better_bic else "rejected: held-out worse")
            )
            refits.append({
                "round": rnd, "effect": eff.name, "parameter": cand.parameter,
                "start": {cand.parameter: cand.start}, "bic_before": bic_now, "bic": bic,
                "delta_bic": bic - bic_now, "power": step_power,
                "value": es.parameters[cand.parameter].value,
                "rmse": {"fit": {"F": rm["role"].get("fit")},
                         "validate": {"F": val} if val is not None else {}},
                "rmse_by_recording": rm["recording"], "kept": ok, "reason": reason,
            })  # fmt: skip
            say(
                f"  refit + {eff.name}: {cand.parameter} {es.parameters[cand.parameter].value:.4g}"
                f", dBIC {bic - bic_now:+.1f}, validate RMSE "
                + (f"{val:.3g} N" if val is not None else "-")
                + f": {reason}"
            )
            if ok:
                added = cand.parameter
                like, est, val_now = lk, es, val
                break
        if added is None:
            break
        kept.append(added)
        remaining.remove(added)

    if law_again and len(kept) > len(already):
        _, power = _common_power(like, est.z)
        results = _compare_laws(problem, est.parameters, tuple(LAWS), kept, power, seed, say)
        best = min(results, key=lambda k: results[k][2])
        bic_cur = _bic(like, est, power)[0]
        rm = force_rmse(all_tests, results[best][1].parameters.values())
        val = rm["role"].get("validate")
        val_ok = val is None or val_now is None or val <= VALIDATE_TOLERANCE * val_now
        ok = results[best][2] < bic_cur and val_ok
        refits.append({
            "round": len(history) + 1, "effect": f"law {best}", "parameter": None,
            "start": {}, "bic_before": bic_cur, "bic": results[best][2],
            "delta_bic": results[best][2] - bic_cur, "power": power, "value": None,
            "rmse": {"fit": {"F": rm["role"].get("fit")},
                     "validate": {"F": val} if val is not None else {}},
            "rmse_by_recording": rm["recording"], "kept": ok,
            "reason": "kept: BIC lower, held-out RMSE not worse" if ok else (
                "rejected: BIC not lower" if results[best][2] >= bic_cur
                else "rejected: held-out worse"),
        })  # fmt: skip
        if best == current_law:
            say(f"law again with {', '.join(kept)}: {best} still the lowest BIC")
        else:
            say(f"law again with {', '.join(kept)}: {best} " + ("kept" if ok else "not kept"))
        if ok:
            like, est = results[best][0], results[best][1]
            current_law = best

    # final: Laplace intervals at the common power of the final residuals
    _, final_power = _common_power(like, est.z)
    problem.tempering = np.full(len(problem.observations), final_power)
    effect_parameters: dict[str, Any] = {}
    try:
        cov = laplace_covariance(like, est.z)
        summary = laplace_summary(est.parameters, est.z, cov)
    except (ValueError, np.linalg.LinAlgError):
        summary = est.parameters
    problem.tempering = np.ones(len(problem.observations))
    for name in kept:
        p = summary[name]
        effect_parameters[name] = {
            "value": p.value, "unit": p.unit, "std": p.std,
            "interval_90": list(p.interval_90) if p.interval_90 is not None else None,
            "effect": FRICTION_EFFECTS[name].name,
        }  # fmt: skip
    changed = len(kept) > len(already) or current_law != law
    final_values = est.parameters.values() if changed else dict(values)
    bic_after = _bic(like, est, power0)[0] if changed else bic0
    result = FrictionDiscovery(
        base_law=law, final_law=current_law, selected=[k for k in kept if k not in already],
        rounds=history, refits=refits, rmse_before=rmse0,
        rmse_after=force_rmse(all_tests, final_values), bic_before=bic0, bic_after=bic_after,
        log_likelihood_before=loglike0,
        log_likelihood_after=float(est.log_likelihood) if changed else loglike0,
        values_before=dict(values),
        values_after=dict(final_values), effect_parameters=effect_parameters, noise=noise,
        seed=seed, seconds=time.perf_counter() - started, tests=all_tests,
    )  # fmt: skip
    say(result.statement)
    return result
