"""Posterior sampling with emcee: seeded, vectorised, resumable, diagnosed.

:func:`run_mcmc` runs an :class:`emcee.EnsembleSampler` with
``vectorize=True`` (the whole ensemble is one batched simulation) on a
:class:`~pneumafit.identification.likelihood.LogPosterior`, storing every
step in an :class:`emcee.backends.HDFBackend` group (written every
:data:`FLUSH_STEPS` steps, :class:`BufferedHDFBackend`). The backend keeps
the generator state with the steps, so a run that was interrupted resumes
where it stopped and ends with exactly the chain an uninterrupted run gives.

Diagnostics (:class:`MCMCResult`):

- acceptance fraction (mean and per walker);
- integrated autocorrelation time tau per parameter (emcee's estimator),
  with a warning when the kept chain is shorter than 50 tau;
- R-hat and bulk ESS from ArviZ, treating each walker as a chain (walkers of
  an affine-invariant ensemble are not independent chains, so read R-hat as
  a check of mixing between walkers, not as a proof of convergence);
- the posterior correlation matrix of the parameter values.

Burn-in: the first ``discard`` steps, the larger of the transient (until the
walkers' mean log-probability first reaches its second-half median) and
3 tau (estimated on the second half of the chain), but at most half the
chain, are dropped before any summary.

Adaptation (``run_mcmc(adapt=N)``): the first N steps use the
differential-evolution moves from the initial ensemble; a multivariate
Student t (:data:`PROPOSAL_DF` degrees of freedom) is then fitted to the
walkers' positions over the settled part of those steps and frozen, and the
rest of the chain mixes an independence Metropolis-Hastings move with that
t as proposal (:data:`INDEPENDENCE_WEIGHT`) with the DE move. A fixed
proposal leaves the posterior invariant whatever its shape (the t only
decides how often a proposal is accepted), the adaptation steps are never
part of the summaries, and the proposal is rebuilt from the stored chain,
so a resumed run continues with the same proposal and ends with the same
chain. On the demo's friction stage (six LuGre parameters, 18 walkers,
1100 steps, seed 0; ``python benchmarks/bench_moves.py``, 2026-11-26) the
largest tau fell from 24.5 steps (DE alone) to 4.0 and the acceptance rose
from 0.21 to 0.57; every 90 % interval end moved by at most 3 % of the
interval's width; a step cost 1.2x as much (the independent draws reach
stiffer friction parameters), so 50 tau cost 5x less. With
``run_mcmc(adapt_check=)`` the phase is checked as it runs and may end
early; a check that finds the walkers still climbing fits the t to them
there and the phase goes on with it (:func:`_phase_plan`).

The t is fitted again (at most :data:`MAX_READAPT` times) when a check
window after the adaptation accepts fewer than :data:`READAPT_ACCEPTANCE`
of its walker-steps (the phase then ended, at its full length, on walkers
that were still climbing, and the t misses the posterior), or when a walker
held still for :data:`HELD_SHARE` of a window (the t misses a part of the
posterior, where its draws are nearly all refused). The steps since
the last fit are its sample and become burn-in. On the sparse plan of the
fitted laws' own truth (seed 1) the friction chain accepted 0.04 and ended
unconverged at its 4000-step limit (36 tau, R-hat 1.03, 50 s); fitted again
at step 400, it converged at 1000 steps (104 tau, R-hat 1.010, 11 s).
The decision is read from the stored chain, so a resumed run makes it at
the same step. A window that still accepts under
:data:`READAPT_ACCEPTANCE` after those fits drops the t: no t fits that
posterior, and the chain goes on with the adaptation's moves alone
(:data:`FALLBACK`, ``MCMCResult.fallback_after``).
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import emcee
import numpy as np
from numpy.typing import NDArray

from pneumafit.errors import PneumafitComputationError, PneumafitInputError
from pneumafit.identification.optimise import equilibrated_pinv
from pneumafit.identification.parameters import ParameterSet
from pneumafit.progress import Progress

__all__ = [
    "MIN_TAU_MULTIPLE",
    "MCMCResult",
    "StudentTProposal",
    "default_moves",
    "propagate",
    "run_mcmc",
    "summarize_chain",
]

#: Draws of :func:`propagate` shifted outside the bounds are drawn again up
#: to this many times, then put on the bound.
PROPAGATE_REDRAWS = 20
#: A kept chain shorter than this many autocorrelation times gets a warning.
MIN_TAU_MULTIPLE = 50.0
#: Largest R-hat of a converged chain (walkers as chains).
MAX_RHAT = 1.01
#: Standard deviation of the initial ensemble without a covariance, as a
#: fraction of each internal coordinate's range (1.4 % of the value for a
#: log-scale parameter spanning six decades).
INITIAL_SPREAD = 1e-3
#: Degrees of freedom of the independence proposal (heavier tails than the
#: fitted Gaussian, so that the posterior's tails are proposed too).
PROPOSAL_DF = 5.0
#: An adaptation phase checked for its end (``run_mcmc(adapt_check=)``) ends
#: once the walkers' mean log posterior rose by less than this many times
#: sqrt(n_free / 2) (the spread of a d-dimensional posterior's log density,
#: chi-square with d degrees of freedom, over 2) between the last two
#: quarters of the phase so far, its transient over by the middle
#: (:func:`_phase_settled`).
SETTLED_RISE = 0.25
#: Share of the independence move after the adaptation (the rest: DE).
INDEPENDENCE_WEIGHT = 0.9
#: After the adaptation, a check window (``run_mcmc(min_steps=)`` steps) in
#: which fewer than this share of the walker-steps moved says that the
#: fitted t misses the posterior: it was fitted to walkers that had not
#: settled (a phase that ran to its full length while they still climbed),
#: so its draws, 90 % of the moves, are nearly all refused. The t is then
#: fitted again to the steps since the last fit, which become burn-in. A
#: t that fits gives 0.5-0.8 on the demo's stages; 0.15 is far below that
#: and above what the DE share alone accepts (0.1 x its 0.2-0.3).
READAPT_ACCEPTANCE = 0.15
#: A check of the adaptation phase after a t fitted within it
#: (:func:`_phase_plan`) ends the phase only when the walkers moved in at
#: least this share of the walker-steps since that fit: a t fitted to walkers
#: that barely moved is the t they were drawn with. On the demo's friction
#: stages (2026-11-29) the t fitted to the DE walkers at step 100 (still 4-10
#: log units below their level) accepted 0.12-0.32; ended there, the kept t
#: accepted 0.41 on constant-lambda's (0.60 with the phase run to 300 steps)
#: and its chain needed 1150 steps instead of 600. A t that fits accepts
#: 0.5-0.8 there.
PHASE_MIXED = 0.3
#: After the adaptation, a check window in which one walker held its position
#: for at least this share of the window's steps in a row also says that the
#: t misses the posterior, in part: the walker sits where the posterior's
#: density is far above the t's, where nearly every draw is refused (an
#: independence sampler's "sticky" region), while the others move freely.
#: Measured on stored chains (``run_mcmc``'s HDF5 groups): the demo's
#: polytropic friction chain (18 walkers, checks every 100 steps, moved 0.62)
#: held a walker at most 10-17 steps per window, its heat chain (checks every
#: 50) 2-5, NAP310's friction fit (checks every 150, moved 0.40) 19-29; the
#: sparse plan of the ``lugre-pressure`` truth (seed 1, 2026-12-03) held one
#: 50 steps in its first window and walkers still for whole windows in 13 of
#: its 38 after, and ran unconverged to its 4000-step limit (static friction
#: tau 99 steps). There 1 % of its posterior draws were accepted away from
#: with probability below 0.0002 under the t fitted at the phase's end, and
#: 0.014 under one fitted to the 100 steps after it (importance weights of
#: the stored draws).
HELD_SHARE = 0.5
#: Fits of the t after the first, at most. A posterior that no t fits keeps
#: a low acceptance whatever the fit: a check window after the last fit
#: that still accepts fewer than :data:`READAPT_ACCEPTANCE` of its
#: walker-steps drops the t, and the chain goes on with the adaptation's
#: moves alone (differential evolution by default), its steps kept: each
#: kernel leaves the posterior invariant (``MCMCResult.fallback_after``).
#: Found on a truth outside the
#: presets (sparse-long plan, seed 2; docs/identification.md, "A friction
#: chain that mixes slowly"): the friction posterior is smooth but piled
#: against the F_s >= F_c wall, with a funnel in the Stribeck velocity;
#: 27 % of the draws of a Gaussian fitted to the settled walkers fall
#: beyond the wall and the rest lie 5 log units below the walkers' median.
#: The t accepted 0.02-0.05 after each fit (11 tau, R-hat 1.64 at 2000
#: steps); DE alone accepts 0.17 there.
MAX_READAPT = 2
#: Whether a chain whose t still misses after :data:`MAX_READAPT` new fits
#: goes on with the adaptation's moves alone (False: with the last t, as
#: before 2026-12-05; the tests measure the difference with it).
FALLBACK = True
#: A chain past its default length is extended only while it can still
#: converge by its limit: at each check from the default length on, the
#: kept steps it would need (:func:`_steps_needed`: R-hat - 1 falls as
#: 1 / N and the tau multiple grows as N for a chain that mixes) are
#: compared with the kept steps it would have at the limit, and the
#: extension stops, with a warning, when they exceed this many times those.
#: The margin (2) covers the checks' noise: a chain that converges by the
#: limit must not look more than twice as far off at any check. Measured on
#: a truth outside the presets (docs/identification.md, "A chain that
#: cannot converge by its limit"): a polytropic friction chain whose
#: walkers held still (acceptance 0.01, R-hat 2.39 at its 2000-step default
#: length, tau not estimable) had run 2000 more steps to its limit for
#: nothing (R-hat 2.04 there; the fit 189 s, now 107 s); the convection
#: chain of the same campaign (R-hat 1.022 at 2000 steps: about 4400
#: needed, 4000 the limit) is extended as before.
EXTEND_REACH = 2.0
#: Kept steps below which the projection is not made (tau and R-hat of a
#: short chain are too noisy to project; a chain this short at its default
#: length is extended as before).
PROJECTION_MIN_KEPT = 200


def _steps_needed(result: MCMCResult) -> float:
    """Kept steps at which ``result``'s chain would be converged, projected
    from its diagnostics: N max((R-hat - 1) / (MAX_RHAT - 1), MIN_TAU_MULTIPLE
    / tau multiple), N its kept steps (inf when tau or R-hat is not finite).

    For a chain that mixes, split R-hat over walkers is about sqrt(1 + 2 tau
    / N) (module doc, "How long a chain runs"), so R-hat - 1 ~ tau / N falls
    as 1 / N, and the tau multiple N / tau grows as N. A chain whose walkers
    sit in separate places does not follow either law: its projection is
    far beyond any limit, which is what it is meant to say.
    """
    kept = result.n_steps - result.discard
    rhat = max(result.rhat.values(), default=1.0)
    if not (math.isfinite(rhat) and math.isfinite(result.tau_multiple)):
        return math.inf
    if result.tau_multiple <= 0:
        return math.inf
    factor = max((rhat - 1.0) / (MAX_RHAT - 1.0), MIN_TAU_MULTIPLE / result.tau_multiple)
    return kept * factor


@dataclass
class MCMCResult:
    """Result of :func:`run_mcmc`.

    Attributes
    ----------
    name : str
        Backend group name (the stage).
    names : tuple of str
        Sampled (free) parameters, in chain order.
    chain : ndarray (n_steps, n_walkers, n_free)
        Internal coordinates (log for log-scale parameters), every step.
    log_prob : ndarray (n_steps, n_walkers)
    n_walkers, n_steps : int
    discard : int
        Burn-in steps dropped from the summaries.
    acceptance : float
        Mean acceptance fraction; ``acceptance_per_walker`` has all.
    tau : dict of str to float
        Integrated autocorrelation time (steps) of each parameter.
    tau_multiple : float
        Kept chain length over the largest tau.
    rhat, ess : dict of str to float
        ArviZ rank-normalised R-hat and bulk ESS, walkers as chains.
    parameters : ParameterSet
        Input set with ``std``, ``interval_90``, ``median`` and
        ``uncertainty="mcmc"`` for the sampled parameters and the posterior
        correlation attached (values unchanged).
    correlation : ndarray (n_free, n_free)
        Posterior correlation of the parameter values.
    warnings : list of str
    seconds : float
        Wall time of this call (sampling only).
    evaluations : int
        Log-posterior evaluations (parameter sets) in this call.
    resumed_from : int
        Steps found in the backend when the call started (0: a fresh run).
    adapted_after : int
        Steps of the adaptation phase (0: none; ``run_mcmc(adapt_check=)``
        may end it before its ``adapt`` steps).
    readapted_after : list of int
        Steps at which the independence proposal was fitted again
        (:data:`READAPT_ACCEPTANCE`); the summaries start after the last.
    fallback_after : int or None
        Step from which the chain went on without the independence proposal,
        which still missed the posterior after :data:`MAX_READAPT` new fits
        (None: it did not); the steps before it stay in the summaries (the
        burn-in is still the last new fit's).
    phase_fits : list of int
        Checks of the adaptation phase at which the walkers had not settled
        and the t was fitted to them to carry on the phase with
        (``run_mcmc(adapt_check=)``); all burn-in.
    seed : int
    """

    name: str
    names: tuple[str, ...]
    chain: NDArray[np.float64]
    log_prob: NDArray[np.float64]
    n_walkers: int
    n_steps: int
    discard: int
    acceptance: float
    acceptance_per_walker: NDArray[np.float64]
    tau: dict[str, float]
    tau_multiple: float
    rhat: dict[str, float]
    ess: dict[str, float]
    parameters: ParameterSet
    correlation: NDArray[np.float64]
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    evaluations: int = 0
    resumed_from: int = 0
    adapted_after: int = 0
    readapted_after: list[int] = field(default_factory=list)
    fallback_after: int | None = None
    phase_fits: list[int] = field(default_factory=list)
    seed: int = 0
    #: Parameters the chain's likelihood simulated at another's value (name
    #: -> partner; ``LogLikelihood.ties``): a reader of the chain draws them
    #: as their partners. Written to fit.json only when there are any.
    ties: dict[str, str] = field(default_factory=dict)

    def to_inference_data(self) -> Any:
        """The kept chain as an ArviZ ``InferenceData`` (walkers as chains, SI values).

        ``posterior``: one variable per sampled parameter, in its unit
        (dimensions ``chain`` = walker, ``draw`` = step after the discarded
        burn-in); ``sample_stats``: ``lp``, the log posterior. Attributes:
        the stage name, units, seed, discard. For ``az.summary``, ``az.plot_trace``
        and the like; the walkers of one ensemble are not independent chains.
        """
        az = _arviz()
        kept = self.chain[self.discard :]
        posterior = {
            p.name: np.asarray(p.to_value(kept[:, :, j]), dtype=float).T
            for j, p in enumerate(self.parameters.free)
        }
        lp = np.asarray(self.log_prob[self.discard :], dtype=float).T
        idata = az.from_dict(posterior=posterior, sample_stats={"lp": lp})
        attrs = {
            "stage": self.name, "seed": self.seed, "discard": self.discard,
            "units": "; ".join(f"{p.name} [{p.unit or '-'}]" for p in self.parameters.free),
            "creation_library": "pneumafit (emcee ensemble: walkers as chains)",
        }  # fmt: skip
        idata.posterior.attrs.update(attrs)
        return idata

    def as_dict(self) -> dict[str, Any]:
        """The summary written to fit.json (no chains)."""
        ties = {"ties": dict(self.ties)} if self.ties else {}
        return ties | {
            "walkers": self.n_walkers,
            "steps": self.n_steps,
            "discard": self.discard,
            "acceptance": self.acceptance,
            "tau": self.tau,
            "tau_multiple": self.tau_multiple,
            "rhat": self.rhat,
            "ess": self.ess,
            "parameters": list(self.names),
            "correlation": [[float(v) for v in row] for row in self.correlation],
            "seconds": self.seconds,
            "evaluations": self.evaluations,
            "resumed_from": self.resumed_from,
            "adapted_after": self.adapted_after,
            "readapted_after": list(self.readapted_after),
            "fallback_after": self.fallback_after,
            "phase_fits": list(self.phase_fits),
            "seed": self.seed,
            "warnings": list(self.warnings),
        }


def _arviz() -> Any:
    """ArviZ, imported without its 0.23 announcement of the 1.0 refactor.

    ArviZ 0.23 prints a ``FutureWarning`` at import (the refactor to come), in
    the middle of a fit's progress lines; the package pins ``arviz<1`` (the
    refactor moves ``from_dict``), so the announcement says nothing to a user.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=FutureWarning, module="arviz")
        import arviz

    return arviz


def default_moves() -> list[tuple[Any, float]]:
    """Differential-evolution moves: 80 % DE, 20 % DE snooker (emcee's moves).

    On the heat posterior of the demo (xi, beta; correlation -0.999) they
    gave tau = 8-10 steps against 24-39 for the default stretch move, and
    14-20 against 25-32 on the four friction parameters, for the same cost
    per step.
    """
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


class StudentTProposal(emcee.moves.MHMove):
    """Independence Metropolis-Hastings move with a fixed multivariate Student t.

    Every walker proposes a fresh draw x' ~ t_nu(mean, scale) regardless of
    where it is, accepted with probability
    min(1, p(x') q(x) / (p(x) q(x'))): the proposal ratio enters through
    emcee's ``factors`` (ln q(x) - ln q(x')). Any fixed proposal that covers
    the posterior's support leaves it invariant; the closer the t is to the
    posterior, the more draws are accepted and the shorter the
    autocorrelation time.

    Parameters
    ----------
    mean : ndarray (n,)
        Location (internal coordinates).
    covariance : ndarray (n, n)
        Scale matrix (the fitted covariance of the walkers; made positive
        definite by flooring its eigenvalues at 1e-12 of the largest).
    df : float
        Degrees of freedom (:data:`PROPOSAL_DF`).
    """

    def __init__(
        self, mean: NDArray[np.float64], covariance: NDArray[np.float64], df: float = PROPOSAL_DF
    ) -> None:
        self.mean = np.asarray(mean, dtype=float)
        self.df = float(df)
        cov = 0.5 * (np.asarray(covariance, float) + np.asarray(covariance, float).T)
        w, v = np.linalg.eigh(cov)
        w = np.clip(w, 1e-12 * max(float(w.max()), 1e-300), None)
        self._root = v * np.sqrt(w)  # scale = root root^T
        self._inverse_root = (v / np.sqrt(w)).T  # whitening: u = inverse_root (x - mean)
        super().__init__(self._propose, ndim=self.mean.size)

    def log_density(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Unnormalised log density of the proposal at rows of ``x``."""
        u = (np.atleast_2d(x) - self.mean) @ self._inverse_root.T
        return -0.5 * (self.df + self.mean.size) * np.log1p(np.sum(u * u, axis=1) / self.df)

    def _propose(
        self, coords: NDArray[np.float64], random: np.random.RandomState
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        n, d = coords.shape
        g = random.standard_normal((n, d))
        w = random.chisquare(self.df, n) / self.df
        x = self.mean + (g / np.sqrt(w)[:, None]) @ self._root.T
        return x, self.log_density(coords) - self.log_density(x)


def _adapted_moves(
    chain: NDArray[np.float64], log_prob: NDArray[np.float64], after_fit: bool = False
) -> list[Any]:
    """The moves after an adaptation phase of ``chain`` (steps, walkers, n).

    The t is fitted to every walker over the settled part of the phase (from
    the later of its middle and the end of its transient, :func:`_settled`,
    keeping at least its last quarter): a function of the stored steps only.
    ``after_fit``: the steps followed a t fitted within the phase, whose
    draws reach the posterior within a few steps, so the sample starts at
    the end of the transient, not at the middle (still keeping the last
    quarter).
    """
    n_adapt = chain.shape[0]
    settled = _settled(log_prob) if after_fit else max(n_adapt // 2, _settled(log_prob))
    first = min(settled, n_adapt - max(n_adapt // 4, 1))
    sample = chain[first:].reshape(-1, chain.shape[2])
    mean = sample.mean(axis=0)
    cov = np.atleast_2d(np.cov(sample, rowvar=False))
    return [
        (StudentTProposal(mean, cov), INDEPENDENCE_WEIGHT),
        (emcee.moves.DEMove(), 1.0 - INDEPENDENCE_WEIGHT),
    ]


def _initial_walkers(
    log_prob: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    z0: NDArray[np.float64],
    covariance: NDArray[np.float64] | None,
    n_walkers: int,
    rng: np.random.Generator,
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Walkers drawn around z0 from the Laplace covariance, all with finite log_prob.

    A draw beyond a bound is reflected back inside it, not clipped onto it:
    with the estimate at a bound (a viscous friction at 0, beta at its lower
    bound) clipping put about half the walkers on the bound itself, all with
    the same coordinate, so the ensemble started in a lower-dimensional
    subspace that the differential-evolution and stretch moves, which move
    walkers along differences of walkers, leave only slowly.
    """
    n = z0.size
    if covariance is None or not np.all(np.isfinite(covariance)):
        width = np.where(np.isfinite(upper - lower), upper - lower, 1.0)
        covariance = np.diag((INITIAL_SPREAD * width) ** 2)
    cov = 0.5 * (covariance + covariance.T)
    w, v = np.linalg.eigh(cov)
    scale = np.sqrt(np.clip(w, 1e-24 * max(float(w.max()), 1e-300), None))
    walkers = np.empty((n_walkers, n))
    filled = 0
    shrink = 1.0
    for _ in range(50):
        need = n_walkers - filled
        cand = z0 + shrink * (rng.standard_normal((need, n)) * scale) @ v.T
        cand = np.where(cand < lower, 2.0 * lower - cand, cand)
        cand = np.where(cand > upper, 2.0 * upper - cand, cand)
        cand = np.clip(cand, lower, upper)  # a draw wider than the whole interval
        good = np.isfinite(log_prob(cand))
        take = cand[good]
        walkers[filled : filled + take.shape[0]] = take
        filled += take.shape[0]
        if filled >= n_walkers:
            return walkers
        shrink *= 0.5
    raise PneumafitComputationError(
        "mcmc: could not place the walkers: the log posterior is -inf around the point estimate"
    )


#: Steps a chain file's backend holds in memory before it writes them
#: (:class:`BufferedHDFBackend`). emcee's HDFBackend opens the file at every
#: step, 2.3-2.5 ms each (measured 2026-12-05 in two runs: 2.44 and 2.70 ms
#: a step against 0.17 ms in memory and 0.23 ms buffered, 32 walkers, 8
#: parameters, a trivial log-probability): about 2 s of the demo's
#: convection fit (775 sampled steps), 5 s of a 2100-step chain (the clean
#: demo's friction chain with --offset-scope sensor). Fifty steps are under a
#: second of sampling: what an interruption that skips the final write (a
#: killed process) can lose; Ctrl-C writes them (:func:`run_mcmc`).
FLUSH_STEPS = 50


class BufferedHDFBackend(emcee.backends.HDFBackend):
    """emcee's HDF5 backend, written every :data:`FLUSH_STEPS` steps.

    Steps are kept in memory and written together, with the generator state
    of the last of them, so the file always holds a prefix of the chain and
    the state to continue it from: a run resumed from it ends with exactly
    the chain of an uninterrupted one. Every read of the file (the
    iteration count, the chain, the convergence checks) and every resize
    writes the pending steps first, so readers never see a stale chain.
    """

    def __init__(self, filename: str, name: str = "mcmc", every: int = FLUSH_STEPS) -> None:
        super().__init__(filename, name=name)
        self.every = max(int(every), 1)
        self._pending: list[tuple[Any, ...]] = []

    def open(self, mode: str = "r") -> Any:
        """emcee's file opening, after the pending steps are written."""
        self.flush()
        return super().open(mode)

    def save_step(self, state: emcee.State, accepted: NDArray[np.bool_]) -> None:
        """Keep one step; write the pending ones every :attr:`every` steps."""
        self._pending.append(
            (
                np.array(state.coords, dtype=float),
                np.array(state.log_prob, dtype=float),
                None if state.blobs is None else np.array(state.blobs),
                np.asarray(accepted, dtype=int),
                state.random_state,
            )
        )
        if len(self._pending) >= self.every:
            self.flush()

    def flush(self) -> None:
        """Write the pending steps (none: nothing is opened)."""
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        with super().open("a") as f:
            g = f[self.name]
            start = int(g.attrs["iteration"])
            stop = start + len(pending)
            g["chain"][start:stop, :, :] = np.stack([p[0] for p in pending])
            g["log_prob"][start:stop, :] = np.stack([p[1] for p in pending])
            if pending[-1][2] is not None:
                g["blobs"][start:stop, :] = np.stack([p[2] for p in pending])
            g["accepted"][:] += np.sum([p[3] for p in pending], axis=0)
            if pending[-1][4] is not None:
                for i, v in enumerate(pending[-1][4]):
                    g.attrs[f"random_state_{i}"] = v
            g.attrs["iteration"] = stop


def _backend(path: Path | None, name: str) -> emcee.backends.Backend:
    if path is None:
        return emcee.backends.Backend()
    return BufferedHDFBackend(os.fspath(path), name=name)


def _flush(store: emcee.backends.Backend) -> None:
    if isinstance(store, BufferedHDFBackend):
        store.flush()


def run_mcmc(
    log_prob: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    parameters: ParameterSet,
    start: NDArray[np.float64],
    covariance: NDArray[np.float64] | None = None,
    *,
    n_walkers: int = 32,
    n_steps: int = 2000,
    seed: int = 0,
    backend: str | os.PathLike[str] | None = None,
    name: str = "mcmc",
    progress: bool | str = False,
    moves: Any = None,
    max_steps: int | None = None,
    log: Callable[[str], None] | None = None,
    min_steps: int | None = None,
    report: Progress | None = None,
    adapt: int = 0,
    adapt_check: int = 0,
) -> MCMCResult:
    """Sample a log posterior with emcee; resume a stored run when possible.

    Parameters
    ----------
    log_prob : callable
        Vectorised log posterior: (n_walkers, n_free) -> (n_walkers,).
    parameters : ParameterSet
        Its free parameters are sampled (internal coordinates).
    start : ndarray (n_free,)
        Centre of the initial ensemble (e.g. the point estimate's ``z``).
    covariance : ndarray, optional
        Spread of the initial ensemble. Default: :data:`INITIAL_SPREAD` of
        each coordinate's range, deliberately wider than the posterior: the
        stick-slip likelihood is rugged, and an ensemble started inside the
        Laplace ellipse of one local facet stays there (on the test campaigns
        its friction intervals were 5-70 times too narrow and missed the
        truth); started wide, the walkers settle over the whole envelope and
        the burn-in is discarded.
    n_walkers, n_steps : int
        Ensemble size (at least 2 n_free) and chain length (steps stored).
    seed : int
        Seeds the initial ensemble and emcee's generator; same seed, same chain.
    backend : path, optional
        HDF5 file holding the chain in group ``name``. A group with the same
        shape and fewer steps is resumed; one with ``n_steps`` or more is
        read back without sampling; a different shape is started afresh.
    progress : bool or str
        emcee's tqdm progress bar (a terminal; ``report`` for a log).
    moves : optional
        emcee moves (default :func:`default_moves`).
    max_steps : int, optional
        Extend the chain, in rounds of half ``n_steps``, while it is shorter
        than :data:`MIN_TAU_MULTIPLE` tau or an R-hat exceeds
        :data:`MAX_RHAT`, up to ``max_steps`` steps in all (None: exactly
        ``n_steps``). The decisions depend on the stored chain only, so an
        interrupted extension resumes to the same chain.
    log : callable, optional
        Receives one line per extension.
    min_steps : int, optional
        Stop early: the chain is first run to ``min_steps`` and checked
        there and every ``min_steps`` steps after, also past ``n_steps`` up
        to ``max_steps``; it stops at the first check where it is at least
        :data:`MIN_TAU_MULTIPLE` tau long and every R-hat is at most
        :data:`MAX_RHAT`, else at ``n_steps`` (or ``max_steps``). None: no
        check before ``n_steps``, extensions in rounds of half ``n_steps``.
        The checks see the stored chain only, so an interrupted run resumes
        to the same chain and the same stop.
    report : Progress, optional
        Updated after every step with the steps done and aimed at, the
        acceptance so far and the largest autocorrelation time of the chain
        so far (computed only when a line is due,
        :class:`pneumafit.progress.Progress`). The chain is the same with
        and without it: the steps are emcee's ``sample`` iterator, which
        ``EnsembleSampler.run_mcmc`` iterates too.
    adapt : int
        Steps of the adaptation phase (0: none; module doc). They are
        burn-in: the summaries start after them, the convergence checks
        start ``min_steps`` steps after them, and ``n_steps`` and
        ``max_steps`` count them. ``moves`` applies to the adaptation phase.
        With ``min_steps``, a check whose window accepted fewer than
        :data:`READAPT_ACCEPTANCE` of its steps, or in which one walker held
        still for :data:`HELD_SHARE` of its steps, fits the proposal again
        (module doc; ``MCMCResult.readapted_after``).
    adapt_check : int
        With ``adapt``, end the adaptation phase early: checked every
        ``adapt_check`` steps from ``2 adapt_check``, it ends at the first
        check where the walkers have settled, at ``adapt`` steps at the
        latest; a check that finds them still climbing fits the t to them
        and the phase goes on with it (:func:`_phase_plan`). 0: exactly
        ``adapt`` steps of the given moves. The decisions depend on the
        stored chain only (a resumed run makes them at the same steps);
        ``MCMCResult.adapted_after`` and ``phase_fits`` give them.

    Returns
    -------
    MCMCResult

    Raises
    ------
    PneumafitInputError
        Too few walkers or steps.
    PneumafitComputationError
        The walkers cannot be placed (the log posterior is -inf around the
        point estimate).
    """
    n_free = parameters.n_free
    if n_walkers < 2 * n_free or n_walkers < 4:
        raise PneumafitInputError(
            f"mcmc {name}: walkers: expected at least {max(2 * n_free, 4)} walkers "
            f"for {n_free} parameters, found {n_walkers}"
        )
    if n_steps < 1:
        raise PneumafitInputError(f"mcmc {name}: steps: expected at least 1, found {n_steps}")
    path = Path(backend) if backend is not None else None
    store = _backend(path, name)
    done = 0
    if path is not None and path.exists():
        try:
            if store.initialized and store.shape == (n_walkers, n_free):
                done = int(store.iteration)
            else:
                done = -1
        except (OSError, KeyError):
            done = -1
    if done < 0 or (done == 0 and path is not None):
        store.reset(n_walkers, n_free)
        done = 0
    t0 = time.perf_counter()
    evaluations = 0

    def counted(z: NDArray[np.float64]) -> NDArray[np.float64]:
        nonlocal evaluations
        evaluations += z.shape[0]
        return log_prob(z)

    def sampler_with(chosen: Any) -> emcee.EnsembleSampler:
        # on a stored chain emcee resumes from its last step and random state
        return emcee.EnsembleSampler(
            n_walkers, n_free, counted, vectorize=True, backend=store, moves=chosen
        )

    adapt = max(int(adapt), 0)
    # the adaptation phase's moves, and a fallback's (no state of their own:
    # emcee draws from the sampler's random state)
    phase_moves = default_moves() if moves is None else moves
    sampler = sampler_with(phase_moves)
    adapted = False
    last: emcee.State | None = None
    check = int(min_steps) if min_steps else 0
    target = limit = 0

    def status() -> str:
        have = int(store.iteration)
        chain = store.get_chain()
        tau = _tau(chain) if have >= 2 else np.array([math.nan])
        taus = tau[np.isfinite(tau)]
        accepted = float(np.mean(np.asarray(store.accepted, dtype=float))) / max(have, 1)
        aim = f"{target}" + (f" (limit {limit})" if limit > target else "")
        return (
            f"step {have} of {aim}, acceptance {accepted:.2f}, tau "
            + (f"{taus.max():.1f} steps (largest, chain so far)" if taus.size else "not yet known")
            + f", {evaluations} evaluations"
        )

    def first_state() -> emcee.State:
        lower, upper = parameters.internal_bounds()
        rng = np.random.default_rng(seed)
        walkers = _initial_walkers(
            counted, np.asarray(start, float), covariance, n_walkers, rng, lower, upper
        )
        return emcee.State(walkers, random_state=np.random.RandomState(seed % 2**32).get_state())

    adapt_check = max(int(adapt_check), 0)
    phase_fits: list[int] = []
    if adapt and adapt_check and 2 * adapt_check < adapt:
        # the phase, run (or resumed) check by check until it is decided; a
        # check that finds the walkers still climbing fits the t to them and
        # the phase goes on with it (_phase_plan): a function of the stored
        # steps, so a resumed run samples on with the same moves
        moves_from = 0
        while True:
            have = int(store.iteration) if store.initialized else 0
            stored = store.get_log_prob() if have else np.empty((0, n_walkers))
            positions = store.get_chain() if have else np.empty((0, n_walkers, n_free))
            end, phase_fits = _phase_plan(stored, positions, adapt, adapt_check, n_free)
            if end is not None:
                adapt = end
                break
            if phase_fits and phase_fits[-1] != moves_from:
                since = phase_fits[-2] if len(phase_fits) > 1 else 0
                fit_at = phase_fits[-1]
                sampler = sampler_with(
                    _adapted_moves(
                        positions[since:fit_at], stored[since:fit_at], after_fit=since > 0
                    )
                )
                moves_from = fit_at
            target = min(adapt, max(2 * adapt_check, (have // adapt_check + 1) * adapt_check))
            try:
                for result_state in sampler.sample(
                    first_state() if have == 0 else sampler.get_last_sample(),
                    iterations=target - have,
                    progress=progress,
                ):
                    last = result_state
                    if report is not None:
                        report.update(status)
            finally:  # an interrupted run keeps every step it made
                _flush(store)
    burn = adapt
    readapted: list[int] = []
    fallback: int | None = None
    target = min(check, n_steps) if check > 0 else n_steps
    if adapt:
        n_steps = max(n_steps, adapt + 2)
        target = min(adapt + check, n_steps) if check > 0 else n_steps
    limit = max(n_steps, int(max_steps or n_steps))

    def advance(state: emcee.State | None, n: int) -> emcee.State | None:
        # as EnsembleSampler.run_mcmc(state, n): None resumes from the last
        # step (the backend's, for a sampler made on a stored chain)
        nonlocal sampler, adapted
        have = int(store.iteration) if store.initialized else 0
        if adapt and not adapted and have < adapt < have + n:
            state = advance(state, adapt - have)
            return advance(None, have + n - adapt)
        if adapt and not adapted and have >= adapt:
            since = phase_fits[-1] if phase_fits else 0
            sampler = sampler_with(
                _adapted_moves(
                    store.get_chain()[since:adapt],
                    store.get_log_prob()[since:adapt],
                    after_fit=since > 0,
                )
            )
            adapted = True
            state = None
        first = sampler.get_last_sample() if state is None else state
        try:
            for result in sampler.sample(first, iterations=n, progress=progress):
                state = result
                if report is not None:
                    report.update(status)
        finally:  # an interrupted run keeps every step it made
            _flush(store)
        return state

    while True:
        have = int(store.iteration) if store.initialized else 0
        remaining = target - have
        if remaining > 0:
            last = advance(first_state() if have == 0 else last, remaining)
        chain = store.get_chain()[:target]
        lp = store.get_log_prob()[:target]
        # acceptance over the steps kept (emcee counts every step stored)
        accepted = np.asarray(store.accepted, dtype=float)
        iterations = max(int(store.iteration), 1)
        result = summarize_chain(
            chain, lp, parameters, accepted / iterations, name=name, seed=seed, burn=burn
        )
        converged = result.tau_multiple >= MIN_TAU_MULTIPLE and all(
            math.isfinite(r) and r <= MAX_RHAT for r in result.rhat.values()
        )
        if converged or target >= limit:
            break
        # read only after an adaptation, at checks (a window of ``check`` steps)
        watched = bool(adapt and check)
        moved = _moved_fraction(chain, target - check) if watched else math.nan
        held = _longest_hold(chain, target - check) if watched else 0
        missed = watched and (moved < READAPT_ACCEPTANCE or held >= HELD_SHARE * check)
        if missed and len(readapted) < MAX_READAPT and target - check >= burn:
            # the t misses the posterior (everywhere: few moves; in part: a
            # walker held): fitted again to the steps since the last fit, a
            # function of the stored chain (a resumed run decides the same
            # here and samples on with the same proposal)
            sampler = sampler_with(_adapted_moves(chain[burn:], lp[burn:]))
            adapted = True
            last = None
            if log is not None:
                why = (f"acceptance {moved:.2f}" if moved < READAPT_ACCEPTANCE
                       else f"a walker held still for {held} steps in a row")  # fmt: skip
                log(
                    f"mcmc {name}: {why} over steps {target - check}-{target}: "
                    f"the proposal misses the posterior; fitted again to steps {burn}-{target}"
                )
            readapted.append(target)
            burn = target
            target = min(limit, target + check)
            continue
        if (FALLBACK and moved < READAPT_ACCEPTANCE and fallback is None
                and len(readapted) >= MAX_READAPT > 0 and target - check >= burn):  # fmt: skip
            # no t fits this posterior (MAX_READAPT new fits and it still
            # refuses nearly every draw): the adaptation's moves alone from
            # here, a function of the stored chain as above
            sampler = sampler_with(phase_moves)
            adapted = True
            last = None
            fallback = target
            if log is not None:
                log(
                    f"mcmc {name}: acceptance {moved:.2f} over steps {target - check}-{target} "
                    f"after {len(readapted)} new fits of the proposal: no t fits this "
                    "posterior; differential evolution alone from here"
                )
            target = min(limit, target + check)
            continue
        # past the default length, extended only while it can converge by the
        # limit (EXTEND_REACH): a projection from the stored chain, so a
        # resumed run stops at the same step
        kept = result.n_steps - result.discard
        if target >= n_steps and kept >= PROJECTION_MIN_KEPT:
            need = _steps_needed(result)
            reach = kept + (limit - target)
            if need > EXTEND_REACH * reach:
                where, why = (
                    (f"it would need about {math.ceil(need + result.discard)} steps to "
                     "converge", "it mixes too slowly for its limit")
                    if math.isfinite(need)
                    else ("its convergence cannot be projected (tau not estimable)",
                          "the walkers do not mix")
                )  # fmt: skip
                note = (
                    f"{name}: not extended past {target} steps: at {result.tau_multiple:.0f} "
                    f"tau and R-hat up to {max(result.rhat.values()):.3f} {where}, and its "
                    f"limit is {limit}: {why}, the intervals are not reliable"
                )
                result.warnings.append(note)
                if log is not None:
                    log(f"mcmc {note}")
                break
        # with checks, every ``check`` steps up to the limit (a chain that needs
        # 1.1x its default length stops there, not at 1.5x); without, the
        # extension rounds of half the default length
        previous = target
        target = min(limit, target + (check if check > 0 else max(n_steps // 2, 1)))
        if log is not None and target > n_steps:
            log(
                f"mcmc {name}: {previous} steps, {result.tau_multiple:.0f} tau, R-hat up to "
                f"{max(result.rhat.values()):.3f}: extending to {target} steps (limit {limit})"
            )
    seconds = time.perf_counter() - t0
    result.seconds = seconds
    result.evaluations = evaluations
    result.resumed_from = done
    result.adapted_after = adapt
    result.readapted_after = readapted
    result.fallback_after = fallback
    result.phase_fits = phase_fits
    return result


def _moved(chain: NDArray[np.float64], start: int) -> NDArray[np.bool_]:
    """Whether each walker moved at each step from ``start`` to the end of
    ``chain`` (steps, walkers, n): (steps - start, walkers). The acceptance
    read from the stored chain (a refused proposal repeats the position
    exactly; emcee's own counts start at step 0)."""
    return np.any(np.diff(chain[max(start - 1, 0) :], axis=0) != 0.0, axis=2)


def _longest_hold(chain: NDArray[np.float64], start: int) -> int:
    """The most steps in a row, from step ``start`` on, that one walker of
    ``chain`` (steps, walkers, n) spent without moving (:func:`_moved`); 0
    without a step."""
    moved = _moved(chain, start)
    longest = 0
    for column in moved.T:
        # lengths of the runs of refusals: gaps between the moves
        at = np.flatnonzero(np.concatenate([[True], column, [True]]))
        longest = max(longest, int(np.max(np.diff(at))) - 1)
    return longest


def _moved_fraction(chain: NDArray[np.float64], start: int) -> float:
    """Share of the walker-steps from step ``start`` on in which the walker
    moved (:func:`_moved`); NaN without a step."""
    moved = _moved(chain, start)
    return float(moved.mean()) if moved.size else math.nan


def _settled(log_prob: NDArray[np.float64]) -> int:
    """First step at which the walkers' mean log-probability reaches its
    median over the second half of the chain: the end of the transient from
    a wide start, which 3 tau (estimated in equilibrium) can undercount."""
    lp = np.asarray(log_prob, dtype=float)
    if lp.ndim != 2 or lp.shape[0] < 4:
        return 0
    with np.errstate(invalid="ignore"):
        mean = np.nanmean(np.where(np.isfinite(lp), lp, np.nan), axis=1)
    level = np.nanmedian(mean[lp.shape[0] // 2 :])
    reached = np.flatnonzero(mean >= level)
    return int(reached[0]) if reached.size else lp.shape[0] // 2


def _phase_settled(log_prob: NDArray[np.float64], n_free: int) -> bool:
    """True when an adaptation phase whose log posteriors are ``log_prob``
    (steps, walkers) can end: the walkers' mean log posterior first reaches its
    second-half median in the first half (:func:`_settled`), and it rose by
    less than :data:`SETTLED_RISE` sqrt(n_free / 2) between the last two
    quarters. A function of the stored steps only."""
    lp = np.asarray(log_prob, dtype=float)
    if lp.ndim != 2 or lp.shape[0] < 8:
        return False
    n = lp.shape[0]
    if _settled(lp) > n // 2:
        return False
    with np.errstate(invalid="ignore"):
        mean = np.nanmean(np.where(np.isfinite(lp), lp, np.nan), axis=1)
    q = n // 4
    rise = float(np.nanmean(mean[n - q :]) - np.nanmean(mean[n - 2 * q : n - q]))
    return math.isfinite(rise) and rise < SETTLED_RISE * math.sqrt(max(n_free, 1) / 2.0)


def _phase_plan(
    log_prob: NDArray[np.float64],
    chain: NDArray[np.float64],
    adapt: int,
    adapt_check: int,
    n_free: int,
) -> tuple[int | None, list[int]]:
    """The course of an adaptation phase of at most ``adapt`` steps, checked
    every ``adapt_check`` steps from ``2 adapt_check``, as far as the stored
    ``log_prob`` (steps, walkers) and ``chain`` (steps, walkers, n) decide it.

    Returns the step at which the phase ends (None while undecided) and the
    checks at which it did not end, where the t is fitted to the walkers
    and the phase goes on with it. A check ends the phase when the steps
    since the last such fit (from step 0 before the first) have settled
    (:func:`_phase_settled`), or the whole phase so far has, and, after a
    fit, the walkers moved in at least :data:`PHASE_MIXED` of the steps
    since.

    The whole phase is judged too because a window of one check is short:
    on the demo's heat stage (6 walkers, checks every 25 steps; convection,
    seed 2) the walkers had settled by step 50, but two 25-step windows in
    a row failed the rule by chance (a rise of 0.44 against 0.31 between
    quarters of 6 steps), and the phase ran to 125 steps where, judged
    from step 0, it ends at 100.

    Why: from the wide start the DE moves climb the last few log units
    slowly. On the demo's friction stages (2026-11-29, seed 0) the walkers'
    mean log posterior was 3-5 units below its level at step 100 and crept
    up to it by steps 130-170, so the phase, judged from step 0, ran its
    full 300 steps in all three fits. A t fitted to the walkers at step 100
    is close enough to draw from the posterior at once; the phase ends at
    the next check that finds the walkers settled since, and the t kept is
    fitted to those settled steps.
    """
    have = log_prob.shape[0]
    fits: list[int] = []
    for end in range(2 * adapt_check, adapt, adapt_check):
        if end > have:
            return None, fits
        since = fits[-1] if fits else 0
        mixed = since == 0 or _moved_fraction(chain[:end], since) >= PHASE_MIXED
        if mixed and (
            _phase_settled(log_prob[since:end], n_free)
            or (since > 0 and _phase_settled(log_prob[:end], n_free))
        ):
            return end, fits
        fits.append(end)
    return (adapt if have >= adapt else None), fits


def summarize_chain(
    chain: NDArray[np.float64],
    log_prob: NDArray[np.float64],
    parameters: ParameterSet,
    acceptance_per_walker: NDArray[np.float64],
    *,
    name: str = "mcmc",
    seed: int = 0,
    burn: int = 0,
) -> MCMCResult:
    """Diagnostics and posterior summaries of a stored chain (see module doc).

    ``burn`` steps (an adaptation phase) are dropped before the burn-in rule
    applies to the rest; the acceptance is then that of the kept steps, read
    from the chain (a walker that moved accepted), since emcee's counts
    include the adaptation.
    """
    az = _arviz()
    n_steps, n_walkers, n_free = chain.shape
    burn = min(max(int(burn), 0), max(n_steps - 2, 0))
    names = parameters.free_names
    notes: list[str] = []
    rest = n_steps - burn
    half = chain[burn + rest // 2 :]
    tau_half = _tau(half)
    finite = tau_half[np.isfinite(tau_half)]
    transient = math.ceil(3.0 * finite.max()) if finite.size else 0
    discard = burn + int(min(rest // 2, max(transient, _settled(log_prob[burn:]))))
    kept = chain[discard:]
    if burn:
        moved = _moved(chain, discard)
        acceptance_per_walker = moved.mean(axis=0) if moved.size else acceptance_per_walker
    tau = _tau(kept)
    tau_max = float(np.max(tau)) if n_free and np.all(np.isfinite(tau)) else math.nan
    multiple = kept.shape[0] / tau_max if tau_max > 0 else (0.0 if n_free else math.inf)
    if not math.isfinite(tau_max) and n_free:
        notes.append(
            f"{name}: the autocorrelation time could not be estimated from "
            f"{kept.shape[0]} steps: the chain is far too short"
        )
    elif multiple < MIN_TAU_MULTIPLE:
        notes.append(
            f"{name}: the kept chain ({kept.shape[0]} steps) is {multiple:.1f} tau long, "
            f"shorter than {MIN_TAU_MULTIPLE:g} tau (largest tau {tau_max:.1f} steps): "
            f"the uncertainty is not reliable; run at least "
            f"{math.ceil(MIN_TAU_MULTIPLE * tau_max + discard)} steps"
        )
    # values, walkers as chains: (n_walkers, n_draws)
    values = np.empty_like(kept)
    for j, p in enumerate(parameters.free):
        values[:, :, j] = p.to_value(kept[:, :, j])
    rhat: dict[str, float] = {}
    ess: dict[str, float] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for j, n in enumerate(names):
            draws = kept[:, :, j].T
            rhat[n] = float(az.rhat(draws)) if kept.shape[0] >= 4 else math.nan
            ess[n] = float(az.ess(draws)) if kept.shape[0] >= 4 else math.nan
    flat = values.reshape(-1, n_free)
    out = parameters.copy()
    for j, p in enumerate(parameters.free):
        col = flat[:, j]
        lo, med, hi = np.quantile(col, [0.05, 0.5, 0.95])
        out = out.replace(
            p.name, std=float(np.std(col)), interval_90=(float(lo), float(hi)),
            median=float(med), uncertainty="mcmc",
        )  # fmt: skip
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.atleast_2d(np.corrcoef(flat, rowvar=False)) if n_free > 1 else np.ones((1, 1))
    corr = np.nan_to_num(corr)
    out.correlation = (names, corr)
    accept = float(np.mean(acceptance_per_walker))
    if accept < 0.1:
        notes.append(f"{name}: low acceptance fraction {accept:.2f} (expected 0.2-0.5)")
    return MCMCResult(
        name=name, names=names, chain=chain, log_prob=log_prob, n_walkers=n_walkers,
        n_steps=n_steps, discard=discard, acceptance=accept,
        acceptance_per_walker=np.asarray(acceptance_per_walker, float),
        tau={n: float(t) for n, t in zip(names, tau, strict=True)}, tau_multiple=float(multiple),
        rhat=rhat, ess=ess, parameters=out, correlation=corr, warnings=notes, seed=seed,
    )  # fmt: skip


def _tau(chain: NDArray[np.float64]) -> NDArray[np.float64]:
    """emcee's integrated autocorrelation time per parameter, without raising."""
    if chain.shape[0] < 2:
        return np.full(chain.shape[2], np.nan)
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore")
        tau = emcee.autocorr.integrated_time(chain, c=5, tol=0, quiet=True)
    return np.asarray(tau, dtype=float)


def summarize_samples(
    z: NDArray[np.float64], parameters: ParameterSet, uncertainty: str = "mcmc"
) -> ParameterSet:
    """Median, std, 90 % interval and correlation of internal samples (n, n_free)."""
    out = parameters.copy()
    values = np.empty_like(z)
    for j, p in enumerate(parameters.free):
        values[:, j] = p.to_value(z[:, j])
        lo, med, hi = np.quantile(values[:, j], [0.05, 0.5, 0.95])
        out = out.replace(
            p.name, std=float(np.std(values[:, j])), interval_90=(float(lo), float(hi)),
            median=float(med), uncertainty=uncertainty,
        )  # fmt: skip
    n_free = z.shape[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.atleast_2d(np.corrcoef(values, rowvar=False)) if n_free > 1 else np.ones((1, 1))
    out.correlation = (parameters.free_names, np.nan_to_num(corr))
    return out


def propagate(
    result: MCMCResult,
    joint: ParameterSet,
    covariance: NDArray[np.float64] | None,
    *,
    exclude_groups: tuple[str, ...] = ("initial",),
    seed: int = 0,
    inflation: Mapping[str, float] | None = None,
) -> tuple[ParameterSet, NDArray[np.float64]]:
    """Add the uncertainty of the parameters a stage held fixed, to first order.

    A stage samples its parameters h with the others v held at the joint
    estimate: a conditional posterior. For a Gaussian joint posterior of
    covariance S the marginal of h is the conditional one shifted by
    A (z_v - mu_v), A = S_hv S_vv^-1, z_v ~ N(mu_v, S_vv): each kept MCMC
    draw gets such a shift, drawn from the joint Laplace covariance
    ``covariance`` (internal coordinates of ``joint.free_names``). Parameters
    of ``exclude_groups`` (the initial states, whose errors the stage's
    likelihood profiles already) are not propagated.

    ``inflation`` (name -> factor >= 1) widens the sampled parameters the
    way the joint covariance was widened
    (:func:`~pneumafit.identification.optimise.recording_robust_covariance`,
    ``covariance`` then being D L D with L the Laplace covariance): each
    draw's deviation from the chain mean is scaled by its factor before the
    shift. For a Gaussian posterior the conditional spread D_h L_cond D_h
    plus the shift's A C_vv A^T is then exactly C_hh, the widened marginal,
    so the reported median and interval come from one (widened) posterior.

    Returns
    -------
    ParameterSet
        ``result.parameters`` with the propagated summaries.
    ndarray (n_draws, n_h)
        The shifted internal draws.
    """
    kept = result.chain[result.discard :].reshape(-1, len(result.names))
    lo, hi = result.parameters.internal_bounds()
    widened = False
    if inflation:
        factor = np.array([max(float(inflation.get(n, 1.0)), 1.0) for n in result.names])
        if np.any(factor > 1.0):
            centre = kept.mean(axis=0)
            kept = np.clip(centre + (kept - centre) * factor, lo, hi)
            widened = True

    def unshifted() -> tuple[ParameterSet, NDArray[np.float64]]:
        if widened:
            return summarize_samples(kept, result.parameters), kept
        return result.parameters, kept

    if covariance is None:
        return unshifted()
    free = joint.free_names
    try:
        h = [free.index(n) for n in result.names]
    except ValueError:
        return unshifted()
    v = [i for i, n in enumerate(free) if n not in result.names
         and joint[n].group not in exclude_groups]  # fmt: skip
    if not v:
        return unshifted()
    s_hv = covariance[np.ix_(h, v)]
    s_vv = covariance[np.ix_(v, v)]
    a = s_hv @ equilibrated_pinv(s_vv)
    extra = a @ s_vv @ a.T
    w, vecs = np.linalg.eigh(0.5 * (extra + extra.T))
    root = vecs * np.sqrt(np.clip(w, 0.0, None))
    rng = np.random.default_rng(seed)
    z = kept + rng.standard_normal(kept.shape) @ root.T
    # the posterior has no mass outside the parameters' bounds, the Gaussian
    # shift does: a draw shifted outside is drawn again (the Gaussian
    # truncated to the support), and one still outside after that is put on
    # the bound. Without this, a parameter the joint stage leaves nearly
    # unidentified (a huge Laplace variance; the Stribeck velocity of a
    # polytropic fit on an independently written rig) got draws of exp(800)
    # and a NaN interval. Draws that stay inside are the same as before.
    for _ in range(PROPAGATE_REDRAWS):
        out = np.any((z < lo) | (z > hi), axis=1)
        if not out.any():
            break
        z[out] = kept[out] + rng.standard_normal((int(out.sum()), kept.shape[1])) @ root.T
    z = np.clip(z, lo, hi)
    return summarize_samples(z, result.parameters), z
