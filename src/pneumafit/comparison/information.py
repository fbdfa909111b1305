"""WAIC and PSIS-LOO of a fit from its posterior draws (ArviZ).

A fit made with MCMC (``pneumafit fit`` without ``--no-mcmc``) stores one
emcee chain per sampled group (``heat``, ``friction``) in ``chains.h5``,
each conditional on the other groups at the joint estimate
(docs/identification.md). :func:`posterior_criteria`:

1. takes ``n_draws`` draws of each group from the second half of its chain
   and never before the fit's own burn-in (seeded, without replacement; a
   burn-in of 3 tau alone was too short after the wide initial ensemble: in
   demo fits made with it, walkers were still hundreds to thousands of
   log-units below the mode at steps 55 (heat) and 232 (friction) against
   discards of 24 and 55; the second half is safe whatever the fit's rule),
   and pairs the k-th draws of
   the groups into one parameter set (the groups taken as independent a
   posteriori; the unsampled groups, e.g. the valve, at the joint estimate);
2. evaluates them on the likelihood of the fit's MCMC stages (every ``fit``
   recording, the fit's channels, sensor offsets and initial-state errors
   profiled, the solver's defect correction), in one batched call, with the
   integration steps (hence the compared samples) chosen at the parameter
   defaults, the same for every model;
3. splits each block's profile log-likelihood into pointwise terms (Gaussian:
   one term per sample; AR(1): the innovations, the first sample from the
   stationary distribution; the sqrt(n) weights of averaged samples as
   log-Jacobians), with the noise scale profiled per draw;
4. computes WAIC and PSIS-LOO of the pointwise matrix
   (:mod:`pneumafit.comparison.elpd`: ArviZ's ``waic`` and ``loo`` estimators,
   vectorised over the points; the same numbers to rounding).

The values are on the deviance scale too (-2 elpd), comparable with AIC.
The profiled noise scale and the projection of the nuisances make the
pointwise terms an approximation: read differences of many units, not of
one. A fit without chains gets ``{"available": false, "reason": ...}``,
never a made-up number.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Campaign
from pneumafit.comparison.elpd import WAIC_VARIANCE_LIMIT, psis_loo, waic
from pneumafit.comparison.evaluate import fit_values
from pneumafit.errors import PneumafitInputError
from pneumafit.identification.fitfile import noise_pooling_of, offset_scope_of
from pneumafit.identification.likelihood import tied
from pneumafit.identification.noise import AR1, Gaussian
from pneumafit.identification.problem import MAX_STEP, Problem
from pneumafit.identification.staged import DEFAULT_CHANNELS

__all__ = ["DEFAULT_DRAWS", "differences", "pointwise_log_likelihood", "posterior_criteria"]

#: Posterior draws per fit: enough for WAIC/LOO to settle to a few tenths of
#: a unit of elpd on the demo, cheap (one batched simulation).
DEFAULT_DRAWS = 60
_LOG_2PI = math.log(2.0 * math.pi)


def _unavailable(reason: str) -> dict[str, Any]:
    return {"available": False, "reason": reason}


def _draws(
    chains: Path, document: Mapping[str, Any], n_draws: int, seed: int
) -> tuple[dict[str, NDArray[np.float64]], list[str], int]:
    """Paired posterior draws by parameter name (values, SI), groups, draws."""
    import emcee

    stages = (document.get("mcmc") or {}).get("stages") or {}
    scales = {
        name: entry.get("scale", "linear")
        for source in (document.get("parameters") or {}, document.get("nuisance") or {})
        for name, entry in source.items()
        if isinstance(entry, Mapping)
    }
    rng = np.random.default_rng(seed)
    flats: dict[str, tuple[list[str], NDArray[np.float64]]] = {}
    ties: dict[str, str] = {}
    for group, stage in stages.items():
        stage_ties = stage.get("ties")
        ties.update(stage_ties if isinstance(stage_ties, Mapping) else {})
        backend = emcee.backends.HDFBackend(os.fspath(chains), name=group, read_only=True)
        chain = backend.get_chain()
        start = max(int(stage.get("discard", 0)), chain.shape[0] // 2)
        flat = chain[start:].reshape(-1, chain.shape[2])
        flats[group] = (list(stage["parameters"]), flat)
    n = min([n_draws, *(f.shape[0] for _, f in flats.values())])
    out: dict[str, NDArray[np.float64]] = {}
    for names, flat in flats.values():
        pick = rng.choice(flat.shape[0], size=n, replace=False)
        for j, name in enumerate(names):
            z = flat[pick, j]
            out[name] = np.exp(z) if scales.get(name) == "log" else z
    # a parameter the chain simulated at another's value (a friction law
    # without its Stribeck drop: MCMCResult.ties) is drawn as its partner
    return tied(out, ties), list(flats), n


def pointwise_log_likelihood(
    problem: Problem, values: Mapping[str, NDArray[np.float64]], n_sets: int
) -> NDArray[np.float64]:
    """Pointwise profile log-likelihood (n_sets, n_points) of a batch of sets.

    Parameters
    ----------
    problem : Problem
        Linearised (offsets and initial-state errors profiled) as for a fit.
    values : mapping of str to ndarray (n_sets,)
        Parameter values by name; the rest keep the problem's ``base``.
    n_sets : int

    Returns
    -------
    ndarray
        Rows sum to each set's profile log-likelihood (-inf rows for a
        failed simulation).

    Raises
    ------
    PneumafitInputError
        A block's noise model has no pointwise form here (only Gaussian and
        AR(1) do).
    """
    pred = problem.predict(values, n_sets)
    residuals = problem.residuals(pred)
    columns: list[NDArray[np.float64]] = []
    clean = [np.where(pred.ok[:, None], r, 0.0) for r in residuals]
    estimates = [
        o.noise.estimate(r, o.floor) for o, r in zip(problem.observations, clean, strict=True)
    ]
    # the fit's noise levels: one per sensor where it pooled them
    if hasattr(problem, "pool"):  # (a duck-typed problem: none)
        estimates = problem.pool(estimates)
    for obs, r, est in zip(problem.observations, clean, estimates, strict=True):
        sigma = np.asarray(est["sigma"], dtype=float).reshape(-1)[:, None]
        if isinstance(obs.noise, AR1):
            phi = est["phi"][:, None]
            e = np.concatenate([np.sqrt(1.0 - phi * phi) * r[:, :1], r[:, 1:] - phi * r[:, :-1]], 1)
            ll = -0.5 * (e / sigma) ** 2 - np.log(sigma) - 0.5 * _LOG_2PI
            ll[:, 0] += 0.5 * np.log1p(-(phi[:, 0] ** 2))
        elif isinstance(obs.noise, Gaussian):
            ll = -0.5 * (r / sigma) ** 2 - np.log(sigma) - 0.5 * _LOG_2PI
        else:
            raise PneumafitInputError(
                f"pointwise log-likelihood: {obs.recording} {obs.channel}: expected a Gaussian "
                f"or AR(1) noise model, found {obs.noise.name}"
            )
        if obs.weight is not None:
            ll = ll + np.log(obs.weight)[None, :]
        columns.append(ll * problem.tempering[len(columns)])
    out = np.concatenate(columns, axis=1)
    out[~pred.ok] = -np.inf
    return out


def posterior_criteria(
    campaign: Campaign,
    document: Mapping[str, Any],
    chains: str | os.PathLike[str] | None,
    *,
    n_draws: int = DEFAULT_DRAWS,
    seed: int = 0,
    where: str = "fit.json",
) -> dict[str, Any]:
    """WAIC and PSIS-LOO of a fit from its chains (module doc).

    Parameters
    ----------
    campaign : Campaign
        The campaign the fit was made on.
    document : mapping
        The parsed fit.json.
    chains : path or None
        Its chains.h5 (None or missing: not available).
    n_draws : int
        Posterior draws per group.
    seed : int
        Seeds the choice of draws.
    where : str
        The fit file, for messages.

    Returns
    -------
    dict
        ``available``; then ``waic`` and ``loo`` (``elpd``, ``se``, ``p``,
        ``deviance`` = -2 elpd; LOO also ``pareto_k_above_0.7``), ``n_draws``,
        ``n_points``, ``groups``, ``note``, and ``_pointwise`` (the pointwise
        elpd arrays, which :func:`differences` uses and removes); or
        ``reason`` when not available.
    """
    if not document.get("mcmc"):
        return _unavailable("the fit has no MCMC (made with --no-mcmc): no posterior draws")
    if chains is None or not Path(chains).is_file():
        return _unavailable(f"the fit has MCMC summaries but its chains file {chains} is missing")
    model, structure, values = fit_values(document, where)
    try:
        draws, groups, n = _draws(Path(chains), document, n_draws, seed)
    except (OSError, KeyError, ValueError) as exc:
        return _unavailable(f"{chains}: cannot read the chains: {exc}")
    if n < 4:
        return _unavailable(f"{chains}: expected at least 4 posterior draws, found {n}")
    options = (document.get("provenance") or {}).get("options") or {}
    channels = tuple(options.get("channels") or DEFAULT_CHANNELS)
    lags = {c: "temperature_sensor_lag" for c in ("T_P", "T_N") if c in channels}
    noise = options.get("noise")
    if not (noise is None or isinstance(noise, str)):
        noise = None  # a described noise model: the defaults (the fit's own defaults too)
    fit_recs = list(campaign.by_role("fit"))
    # every model's problem compares the same samples (Problem's fixed
    # COMPARE_SPACING), whatever values it is built at: WAIC/LOO score the
    # same points; the step follows this model's values
    try:
        problem = Problem(
            fit_recs, structure, values, channels=channels, noise=noise,
            sensor_lags=lags, max_step=options.get("max_step", MAX_STEP),
            offsets=tuple(options.get("offsets") or ("pressure",)), initial_nuisance=True,
            offset_scope=offset_scope_of(options), noise_pooling=noise_pooling_of(options),
        )  # fmt: skip
    except ValueError as exc:
        return _unavailable(f"cannot set up the likelihood of the fit recordings: {exc}")
    # the fit's posterior counted each block's residuals as n / tau samples
    # (LogLikelihood.temper): its pointwise terms carry the same power, or
    # WAIC's effective parameter count grows by ~tau
    taus = {
        (b.get("recording"), b.get("channel")): float(b.get("correlation_time") or 1.0)
        for b in document.get("noise") or [] if isinstance(b, dict)
    }  # fmt: skip
    problem.tempering = np.array(
        [1.0 / max(taus.get((o.recording, o.channel), 1.0), 1.0) for o in problem.observations]
    )
    point = dict(values)
    problem.linearize(point)
    problem.correct_solver(point)
    batch = {k: np.full(n, v) for k, v in values.items()}
    batch.update(draws)
    try:
        ll = pointwise_log_likelihood(problem, batch, n)
    except ValueError as exc:
        return _unavailable(str(exc))
    good = np.all(np.isfinite(ll), axis=1)
    if good.sum() < 4:
        return _unavailable("fewer than 4 posterior draws simulated successfully")
    ll = ll[good]
    waic_ = waic(ll)
    loo = psis_loo(ll, reff=1.0)  # thinned draws: nearly independent
    assert loo.pareto_k is not None and loo.good_k is not None
    k_high = int(np.sum(loo.pareto_k > 0.7))
    notes = []
    if waic_.n_unreliable:
        notes.append(
            f"WAIC: the posterior variance of the log predictive density exceeds "
            f"{WAIC_VARIANCE_LIMIT} at {waic_.n_unreliable} of {ll.shape[1]} points, where WAIC "
            "may fail (Vehtari, Gelman and Gabry 2017)"
        )
    if loo.n_unreliable:
        notes.append(
            f"PSIS-LOO: Pareto k above {loo.good_k:.2f} at {loo.n_unreliable} of {ll.shape[1]} "
            "points, where the importance-sampling estimate is unreliable"
        )
    return {
        "available": True,
        "model": model,
        "waic": {
            "elpd": waic_.elpd, "se": waic_.se, "p": waic_.p, "deviance": -2.0 * waic_.elpd,
        },
        "loo": {
            "elpd": loo.elpd, "se": loo.se, "p": loo.p, "deviance": -2.0 * loo.elpd,
            "pareto_k_above_0.7": k_high,
        },
        "n_draws": int(good.sum()),
        # pointwise elpd (not written to JSON): for the standard error of differences
        "_pointwise": {
            "waic": waic_.pointwise,
            "loo": loo.pointwise,
        },
        "n_points": int(ll.shape[1]),
        "groups": groups,
        "seed": int(seed),
        "warnings": notes,
        "note": (
            "pointwise profile log-likelihood on the fit recordings; draws of the sampled "
            "groups paired across groups, other groups at the joint estimate"
        ),
    }  # fmt: skip


def differences(posteriors: Mapping[str, dict[str, Any]]) -> None:
    """Add each model's elpd difference to the best, with its standard error.

    For ``waic`` and ``loo`` of every available result, in place:
    ``elpd_diff`` (best minus this model, >= 0) and ``se_diff``
    (sqrt(n) times the standard deviation of the pointwise differences, as
    ``arviz.compare``), when every model scored the same data points. Removes
    the pointwise arrays (``_pointwise``), which are not written to JSON.

    Parameters
    ----------
    posteriors : mapping of str to dict
        Model -> :func:`posterior_criteria` result.
    """
    ready = {m: p for m, p in posteriors.items() if p.get("available") and "_pointwise" in p}
    sizes = {p["n_points"] for p in ready.values()}
    if len(ready) >= 2 and len(sizes) == 1:
        for crit in ("waic", "loo"):
            best = max(ready, key=lambda m: ready[m][crit]["elpd"])
            ref = ready[best]["_pointwise"][crit]
            for p in ready.values():
                diff = ref - p["_pointwise"][crit]
                p[crit]["best"] = best
                p[crit]["elpd_diff"] = float(np.sum(diff))
                p[crit]["se_diff"] = float(math.sqrt(diff.size) * np.std(diff))
    for p in posteriors.values():
        p.pop("_pointwise", None)
