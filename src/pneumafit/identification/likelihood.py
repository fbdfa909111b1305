"""Log-likelihood and log-posterior of a problem, batched over parameter sets.

Optimisers and samplers only ever call these (PINTS). Both take internal
vectors ``z`` of the free parameters of a :class:`ParameterSet`, shape
(n_sets, n_free) or (n_free,), and return one value per set: emcee's
``vectorize=True`` calls them with the whole ensemble, which the compiled
simulator runs in parallel.

A failed or non-finite simulation, a set outside the bounds, or a non-finite
noise estimate gives -inf; nothing raises for bad parameter values.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.errors import PneumafitInputError
from pneumafit.identification.noise import correlation_time
from pneumafit.identification.parameters import ParameterSet
from pneumafit.identification.problem import Prediction, Problem

__all__ = ["Evaluation", "LogLikelihood", "LogPosterior", "tied"]


def tied(values: Mapping[str, Any], ties: Mapping[str, str]) -> dict[str, Any]:
    """``values`` with each tied parameter at a copy of its partner's value.

    Parameters
    ----------
    values : mapping of str to float or ndarray
        Parameter values by name (SI).
    ties : mapping of str to str
        Tied parameter -> the partner whose value it takes (a friction law
        without its Stribeck drop simulates the static level at the Coulomb
        one: ``MCMCResult.ties``). A tie whose partner is not in ``values``
        is skipped.

    Returns
    -------
    dict
        A new mapping; arrays are copied, not shared with the partner.
    """
    out = dict(values)
    for name, partner in ties.items():
        if partner in out:
            out[name] = copy.copy(out[partner])
    return out


@dataclass
class Evaluation:
    """Everything about a batch of likelihood evaluations.

    Attributes
    ----------
    log_likelihood : ndarray (n_sets,)
        Sum over blocks of the profile log-likelihoods; -inf on failure.
    blocks : ndarray (n_sets, n_blocks)
        Profile log-likelihood of each (recording, channel) block.
    residuals : list of ndarray (n_sets, n_b)
        data - model per block (NaN after a failure).
    noise : list of dict of str to ndarray (n_sets,)
        Estimated noise parameters per block (``sigma``, ``phi``).
    ok : ndarray of bool (n_sets,)
    prediction : Prediction
    """

    log_likelihood: NDArray[np.float64]
    blocks: NDArray[np.float64]
    residuals: list[NDArray[np.float64]]
    noise: list[dict[str, NDArray[np.float64]]]
    ok: NDArray[np.bool_]
    prediction: Prediction


class LogLikelihood:
    """log p(data | parameters), noise parameters profiled per block.

    Parameters
    ----------
    problem : Problem
    parameters : ParameterSet
        Defines the free parameters (internal vector) and the values of the
        fixed ones. Every nuisance parameter the problem uses (sensor lags)
        must be in it.

    Raises
    ------
    PneumafitInputError
        A nuisance parameter of the problem is missing from ``parameters``.
    """

    def __init__(
        self,
        problem: Problem,
        parameters: ParameterSet,
        ties: Mapping[str, str] | None = None,
    ) -> None:
        missing = [n for n in problem.lag_names if n not in parameters]
        if missing:
            raise PneumafitInputError(
                f"likelihood: the problem uses nuisance parameters {missing}, "
                "expected them in the parameter set, found none"
            )
        self.problem = problem
        self.parameters = parameters
        unknown = [n for pair in (ties or {}).items() for n in pair if n not in parameters]
        if unknown:
            raise PneumafitInputError(
                f"likelihood: ties: expected parameters of the set, found {unknown}"
            )
        #: Parameters simulated at another's value (name -> partner), e.g. a
        #: friction law without its Stribeck drop: friction_static at
        #: friction_coulomb (:func:`pneumafit.identification.staged`).
        self.ties = dict(ties or {})
        self._lower, self._upper = parameters.internal_bounds()
        self._unaffected: NDArray[np.bool_] | None = None

    @property
    def n_parameters(self) -> int:
        """Number of free parameters (length of z)."""
        return self.parameters.n_free

    @property
    def names(self) -> tuple[str, ...]:
        return self.parameters.free_names

    @property
    def n_evaluations(self) -> int:
        """Parameter sets simulated so far (all calls)."""
        return self.problem.n_evaluations

    def values(self, z: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Internal vectors -> values by name (all parameters; a tied one at
        its partner's value, :attr:`ties`)."""
        return tied(self.parameters.to_values(z), self.ties)

    def inside(self, z: ArrayLike) -> NDArray[np.bool_]:
        """True where every free coordinate is finite and within its bounds."""
        zz = np.atleast_2d(np.asarray(z, dtype=float))
        return np.all(np.isfinite(zz), axis=1) & np.all(
            (zz >= self._lower) & (zz <= self._upper), axis=1
        )

    def evaluate(
        self,
        z: ArrayLike,
        moved: ArrayLike | None = None,
        prediction: Prediction | None = None,
    ) -> Evaluation:
        """Simulate and score a batch; see :class:`Evaluation`.

        ``moved`` (n_sets,) of int, optional: for a batch whose set i differs
        from set 0 in free parameter ``moved[i]`` alone (-1: in any), e.g. a
        finite-difference Jacobian's, the recordings that parameter cannot
        affect (:meth:`Problem.unaffected`) are not simulated again: they
        take set 0's simulation, which is what simulating them gives.

        ``prediction``, optional: the problem's prediction of this very
        batch, from an earlier evaluation of it (its
        :attr:`Evaluation.prediction`): scored again without simulating,
        under the problem's present weights and tempering. The caller
        vouches that the problem's predictions have not changed since.
        """
        zz = np.atleast_2d(np.asarray(z, dtype=float))
        n = zz.shape[0]
        inside = self.inside(zz)
        if prediction is not None:
            return self._score(prediction, inside, n)
        # simulate only the sets inside the bounds; others stay NaN / -inf
        z_run = np.where(inside[:, None], zz, self.parameters.to_internal()[None, :])
        values = self.values(z_run)
        same = None
        # a problem without the structure's rules (a duck-typed one) simulates all
        if moved is not None and hasattr(self.problem, "unaffected"):
            if self._unaffected is None:
                self._unaffected = self.problem.unaffected(self.names)
            idx = np.asarray(moved, dtype=np.int64)
            same = np.zeros((n, self._unaffected.shape[1]), dtype=bool)
            one = idx >= 0
            same[one] = self._unaffected[idx[one]]
            # a set outside the bounds is simulated at the defaults: not set 0's
            same[~inside] = False
            if not inside[0]:
                same = None  # set 0 is simulated at the defaults: nothing to share
        pred = (
            self.problem.predict(values, n)
            if same is None
            else self.problem.predict(values, n, same_as_first=same)
        )
        return self._score(pred, inside, n)

    def _score(self, pred: Prediction, inside: NDArray[np.bool_], n: int) -> Evaluation:
        """Residuals, noise estimates and log-likelihoods of a batch's prediction."""
        residuals = self.problem.residuals(pred)
        ok = pred.ok & inside
        blocks = np.empty((n, len(residuals)))
        observations = self.problem.observations
        clean = [np.where(ok[:, None], r, 0.0) for r in residuals]
        noise = [o.noise.estimate(r, o.floor) for o, r in zip(observations, clean, strict=True)]
        # one sigma per sensor where the problem pools (duck-typed problems: none)
        if hasattr(self.problem, "pool"):
            noise = self.problem.pool(noise)
        for j, (obs, r_ok) in enumerate(zip(observations, clean, strict=True)):
            blocks[:, j] = self.problem.tempering[j] * (
                obs.noise.logpdf(r_ok, **noise[j]) + self.problem.log_weight(j)
            )
        with np.errstate(invalid="ignore"):
            total = np.sum(blocks, axis=1)
        ok &= np.isfinite(total)
        total = np.where(ok, total, -np.inf)
        blocks[~ok] = -np.inf
        return Evaluation(total, blocks, residuals, noise, ok, pred)

    def correlation_times(
        self, z: ArrayLike, evaluation: Evaluation | None = None
    ) -> NDArray[np.float64]:
        """Correlation time (samples) of each block's whitened residuals at one set.

        See :func:`~pneumafit.identification.noise.correlation_time`; NaN
        for every block when the simulation fails. ``evaluation``: this
        likelihood's :meth:`evaluate` of ``z`` (its first set), when the
        caller has it already; otherwise ``z`` is simulated.
        """
        ev = (
            self.evaluate(np.atleast_2d(np.asarray(z, dtype=float))[:1])
            if evaluation is None
            else evaluation
        )
        out = np.full(len(ev.residuals), np.nan)
        if not ev.ok[0]:
            return out
        for j, (obs, r) in enumerate(zip(self.problem.observations, ev.residuals, strict=True)):
            state = obs.noise.whitening_state(r[0], obs.floor)
            out[j] = correlation_time(obs.noise.whiten(r[0], **state))
        return out

    def overcount(self, z: ArrayLike, evaluation: Evaluation | None = None) -> float:
        """By how much the iid log-likelihood overcounts the data's information.

        sum(n) / sum(n / tau) over the blocks at ``z``, tau the correlation
        time of each block's whitened residuals (:meth:`temper`): 1 for white
        residuals, or when the simulation fails. ``evaluation`` as in
        :meth:`correlation_times`.
        """
        taus = self.correlation_times(z, evaluation)
        if not np.all(np.isfinite(taus)):
            return 1.0
        n = np.array([o.n for o in self.problem.observations], dtype=float)
        return max(float(np.sum(n) / np.sum(n / taus)), 1.0)

    def temper(self, z: ArrayLike) -> NDArray[np.float64]:
        """Count each block's residuals as n / tau independent samples.

        A model simpler than the rig leaves residuals that are smooth, not
        white; the iid likelihood then counts thousands of correlated
        samples as independent and its curvature (Laplace, MCMC) gives
        intervals that are too narrow by ~sqrt(tau). Raising each block's
        likelihood to the power 1 / tau, tau the correlation time of its
        whitened residuals at ``z``, gives the curvature of the sandwich
        (misspecification-robust) covariance when the sensitivities vary
        slowly on the scale of tau, and leaves a block whose residuals are
        white (a model that reaches the noise) as it was. The powers are set
        on the problem (:attr:`Problem.tempering`) and apply to every later
        evaluation, also of other likelihoods of the same problem.

        Returns
        -------
        ndarray (n_blocks,)
            tau of each block (1 where the simulation failed).
        """
        taus = np.nan_to_num(self.correlation_times(z), nan=1.0)
        self.problem.tempering = 1.0 / taus
        return taus

    def __call__(self, z: ArrayLike) -> NDArray[np.float64]:
        """Log-likelihood (n_sets,) of internal vectors (n_sets, n_free); -inf on failure."""
        return self.evaluate(z).log_likelihood

    def at_values(self, values: Mapping[str, float]) -> float:
        """Log-likelihood of one set given by values (free ones looked up by name)."""
        return float(self(self.parameters.to_internal(values))[0])


class LogPosterior:
    """log prior + log-likelihood, in internal coordinates (log-Jacobians included).

    The prior is that of the :class:`ParameterSet` (default flat in the
    internal coordinate within the bounds); sets with zero prior density are
    not simulated.
    """

    def __init__(self, likelihood: LogLikelihood) -> None:
        self.likelihood = likelihood
        self.parameters = likelihood.parameters

    @property
    def n_parameters(self) -> int:
        return self.likelihood.n_parameters

    def __call__(self, z: ArrayLike) -> NDArray[np.float64]:
        zz = np.atleast_2d(np.asarray(z, dtype=float))
        lp = self.parameters.log_prior(zz)
        out = np.full(zz.shape[0], -np.inf)
        live = np.isfinite(lp)
        if live.any():
            out[live] = lp[live] + self.likelihood(zz[live])
        out[~np.isfinite(out)] = -np.inf
        return out
