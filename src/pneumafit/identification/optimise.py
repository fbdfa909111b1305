"""Point estimates by ``scipy.optimize.least_squares``, multi-start.

The profile likelihood of :mod:`.likelihood` is maximised by iteratively
reweighted least squares: the noise parameters of every block (sigma, the
AR(1) phi, the Student-t weights) are held at their estimates at the current
point, the whitened residuals are minimised with the trust-region reflective
method inside the bounds, and the noise parameters are re-estimated, until
the profile log-likelihood stops improving. At a fixed point the gradient of
the profile log-likelihood vanishes (for the Gaussian model,
d/dtheta sum_b n_b log SSR_b = sum_b dSSR_b / sigma_b^2).

The Jacobian is a forward difference computed in one batched simulation of
all perturbed sets (parallel over sets and recordings), not column by column.
At the estimate, the Laplace approximation (J^T J)^-1 of the whitened
problem gives a covariance of the internal coordinates; it provides the
uncertainty when no MCMC is run, and the spread of the MCMC walkers' start.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from pneumafit.identification.likelihood import Evaluation, LogLikelihood
from pneumafit.identification.parameters import CONSTRAINTS, ParameterSet
from pneumafit.identification.problem import Prediction
from pneumafit.identification.segments import source_recording
from pneumafit.progress import Progress

__all__ = [
    "ONE_RECORDING",
    "STALL_RULE",
    "PointEstimate",
    "RobustCovariance",
    "fit_least_squares",
    "information_stall",
    "laplace_covariance",
    "laplace_summary",
    "recording_robust_covariance",
]

#: Whitened residual given to every sample of a failed simulation: large, so
#: that the trust region retreats, finite, so that least_squares carries on.
FAILED_RESIDUAL = 1.0e3
#: Relative forward-difference step in the internal coordinates.
FD_STEP = 1.0e-5
#: Quantile of the standard normal for a central 90 % interval.
Z90 = 1.6448536269514722


@dataclass
class PointEstimate:
    """Result of :func:`fit_least_squares`.

    Attributes
    ----------
    parameters : ParameterSet
        The set with the estimate as values; free parameters carry the
        Laplace ``std`` and ``interval_90`` (``uncertainty="laplace"``).
    z : ndarray (n_free,)
        Internal coordinates of the estimate.
    log_likelihood : float
        Profile log-likelihood at the estimate.
    log_posterior : float
        log_likelihood + log prior (internal coordinates).
    covariance : ndarray (n_free, n_free) or None
        Laplace covariance of the internal coordinates (pseudo-inverse of
        J^T J of the whitened residuals and Gaussian priors).
    success : bool
        The best start converged (scipy's status > 0) to a finite likelihood.
    message : str
        scipy's message for the best start.
    n_evaluations : int
        Parameter sets simulated (Jacobian columns included), all starts.
    starts : list of dict
        Per start: ``start`` (values), ``log_likelihood``, ``nfev``,
        ``message``, ``estimate`` (values).
    noise : list of dict
        Per block of the problem: estimated noise parameters at the estimate.
    """

    parameters: ParameterSet
    z: NDArray[np.float64]
    log_likelihood: float
    log_posterior: float
    covariance: NDArray[np.float64] | None
    success: bool
    message: str
    n_evaluations: int
    starts: list[dict[str, Any]] = field(default_factory=list)
    noise: list[dict[str, float]] = field(default_factory=list)


def _fd_steps(ps: ParameterSet, z: NDArray[np.float64]) -> NDArray[np.float64]:
    h = np.empty(z.size)
    for j, p in enumerate(ps.free):
        h[j] = FD_STEP if p.scale == "log" else FD_STEP * max(abs(z[j]), 1e-2)
    return h


#: Finite-difference batches a :class:`_Whitened` keeps for the points it
#: may be asked about again (the best points of the latest rounds).
KEPT_BATCHES = 3


class _Whitened:
    """Whitened residuals with the noise state held.

    It keeps the predictions of the finite-difference batches at a few
    points (:meth:`keep`: the best point of each round, which the next
    round, the reweighting and the final covariance evaluate again): a
    point's batch is then scored anew under the present noise weights
    without simulating it again, and a single evaluation at the point
    takes the batch's first set. The numbers are those of simulating
    again (the same prediction, scored by the same code); only the
    simulations are saved (one single evaluation and one batch per
    reweighting round).
    """

    def __init__(self, like: LogLikelihood) -> None:
        self.like = like
        self.states: list[dict[str, Any]] = []
        self.lower, self.upper = like.parameters.internal_bounds()
        # (point, prediction) of the last finite-difference batch, and the
        # kept ones by point (the batch's points follow from its point)
        self._last: tuple[bytes, Any] | None = None
        self._kept: dict[bytes, Any] = {}

    def keep(self, z: NDArray[np.float64]) -> None:
        """Keep the last batch's prediction when it was made at ``z``."""
        if self._last is not None and self._last[0] == z.tobytes():
            key, pred = self._last
            self._kept.pop(key, None)
            self._kept[key] = pred
            while len(self._kept) > KEPT_BATCHES:
                del self._kept[next(iter(self._kept))]

    def _first_set(self, z: NDArray[np.float64]) -> Prediction | None:
        """The first set of a kept batch made at ``z`` (a Prediction of one set)."""
        pred = self._kept.get(z.tobytes())
        if not isinstance(pred, Prediction):
            return None  # none kept, or a duck-typed problem's: simulated again
        return Prediction([b[:1] for b in pred.blocks], pred.status[:1], pred.ok[:1])

    def set_state(self, z: NDArray[np.float64]) -> float:
        ev = self.like.evaluate(z[None, :], prediction=self._first_set(z))
        states = []
        for o, r in zip(self.like.problem.observations, ev.residuals, strict=True):
            rr = np.nan_to_num(r[0], nan=0.0)
            states.append(o.noise.whitening_state(rr, o.floor))
        # a sigma shared by a sensor's blocks: the evaluation's pooled one
        groups = getattr(self.like.problem, "noise_groups", None)
        if groups is not None:
            for j in np.flatnonzero(groups >= 0):
                states[j]["sigma"] = float(np.asarray(ev.noise[j]["sigma"]).reshape(-1)[0])
        self.states = states
        return float(ev.log_likelihood[0])

    def batch(
        self, zz: NDArray[np.float64], moved: NDArray[np.int64] | None = None
    ) -> NDArray[np.float64]:
        """Whitened residual vectors (n_sets, n_res) of a batch (``moved``:
        see :meth:`LogLikelihood.evaluate`)."""
        return self._whitened(self.like.evaluate(zz, moved=moved), zz)

    def _whitened(self, ev: Evaluation, zz: NDArray[np.float64]) -> NDArray[np.float64]:
        """Whitened residual vectors (n_sets, n_res) of an evaluation of ``zz``."""
        parts = []
        power = np.sqrt(self.like.problem.tempering)
        for j, (o, r, st) in enumerate(
            zip(self.like.problem.observations, ev.residuals, self.states, strict=True)
        ):
            w = o.noise.whiten(np.nan_to_num(r, nan=0.0), **st)
            parts.append(w * power[j])
        res = np.concatenate(parts, axis=1)
        res[~ev.ok] = FAILED_RESIDUAL
        prior = self.like.parameters.prior_residuals(zz)
        if prior.shape[1]:
            res = np.concatenate([res, prior], axis=1)
        return res

    def _inside_constraints(
        self, z: NDArray[np.float64], h: NDArray[np.float64], sign: NDArray[np.float64]
    ) -> bool:
        """Turn ``sign`` (+-1 per coordinate, in place) backwards for the smaller
        side of a :data:`~.parameters.CONSTRAINTS` inequality whose forward
        step would break it (the Coulomb level above the static one); True
        when it turned one. The values are the tied ones
        (:meth:`LogLikelihood.values`: a level tied to its partner moves with
        it and breaks nothing)."""
        like = self.like
        names = like.names
        turned = False
        for larger, smaller, _ in CONSTRAINTS:
            if smaller not in names:
                continue
            j = names.index(smaller)
            if sign[j] < 0.0:
                continue
            moved = z.copy()
            moved[j] += h[j]
            values = like.values(moved)
            if larger in values and values[smaller][0] > values[larger][0]:
                sign[j] = -1.0
                turned = True
        return turned

    def fun_and_jac(
        self, z: NDArray[np.float64], *, feasible: bool = False
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Whitened residuals at ``z`` and their forward-difference Jacobian
        (backward where forward would leave the bounds).

        ``feasible``: also backward where forward would break a
        :data:`~.parameters.CONSTRAINTS` inequality (:meth:`_inside_constraints`),
        as the covariances take it. The kernel refuses such a set, so its
        residuals are the failed set's constant and the column
        (FAILED_RESIDUAL - r) / h calls the parameter known to ~1e-10 of
        itself: on a fit whose static friction ends on the Coulomb level
        (mixed truth, sparse plan, seed 1, 2026-12-06) the Laplace standard
        deviation of the Coulomb level's log was 1.7e-10 and its interval of
        zero width. The least squares keeps the forward step (False): with
        that column the trust region does not move the smaller side across
        the constraint; with the backward one, 4 of the recovery matrix's
        30 fits ended elsewhere, one 2750 log-likelihood units better, one
        3145 worse and two within 1.1 (docs/identification.md, "The friction
        constraint in the covariances and the reference draws"). A batch
        whose step was turned is not kept (:meth:`keep`: a kept batch's
        points follow from its point with the least squares' steps).
        """
        h = _fd_steps(self.like.parameters, z)
        # step backwards where forwards would leave the bounds
        sign = np.where(z + h > self.upper, -1.0, 1.0)
        turned = feasible and self._inside_constraints(z, h, sign)
        pts = np.repeat(z[None, :], z.size + 1, axis=0)
        pts[1:] += np.diag(sign * h)
        key = z.tobytes()
        # set j + 1 moves coordinate j alone: the recordings it cannot affect
        # keep set 0's simulation (exactly what simulating them again gives)
        kept = None if turned else self._kept.get(key)
        ev = self.like.evaluate(pts, moved=np.arange(-1, z.size), prediction=kept)
        self._last = None if turned else (key, ev.prediction)
        res = self._whitened(ev, pts)
        jac = (res[1:] - res[0]).T / (sign * h)
        return res[0], jac


#: Stall rule of a solve over many recordings (``fit_least_squares(stall=)``;
#: the joint stage, discovery's refits): stop a round when its
#: log-likelihood gained less than 0.5 over the last 10 evaluated points,
#: the gain scaled by the residuals' correlation (:func:`information_stall`).
#: 0.5 is the gain of a one-sigma move of one parameter; a model that cannot
#: follow its data creeps at such gains for hundreds of points: on a
#: demo-plan campaign of an independently written rig (LuGre friction
#: against the switch model) the joint stage took 1066 s and 78790
#: simulations, most of them gaining less than that.
STALL_RULE = (10, 0.5)


def information_stall(
    likelihood: LogLikelihood, z: NDArray[np.float64], scaled: bool = True
) -> tuple[int, float]:
    """:data:`STALL_RULE` in units of the data's effective information at ``z``.

    Its gain is a one-sigma move of one parameter when every sample is
    independent. With residuals correlated over tau samples (a model that
    does not follow its data) the log-likelihood overcounts the information
    by ~tau (:meth:`LogLikelihood.overcount`) and the same move gains ~tau
    times more, so the gain is scaled by it (unscaled when ``scaled`` is
    False, or the residuals are white).
    """
    if not scaled:
        return STALL_RULE
    return STALL_RULE[0], STALL_RULE[1] * likelihood.overcount(z)


#: Status given to a solve stopped by the stall rule (scipy's are -1..4).
STALLED = 5

#: Largest condition number of the equilibrated Cholesky factor of
#: [J f]^T [J f] for the compressed system (:func:`_compressed`); beyond it
#: the factor comes from a QR of [J f] instead. The Gram squares the
#: condition number: at 1e4 (1e8 for the Gram) its factor keeps about 8
#: significant digits in its weakest direction. Equilibrated, the fits'
#: J^T J have condition numbers ~1e3 (:func:`equilibrated_pinv`).
COMPRESS_COND = 1.0e4


def _compressed(
    f: NDArray[np.float64], jac: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The least-squares system (f, J), m x n, as n + 1 rows with the same
    cost, gradient and Gauss-Newton matrix.

    With R the (n + 1) x (n + 1) triangular factor of A = [J f] (R^T R =
    A^T A), f~ = R[:, n] and J~ = R[:, :n] give |f~|^2 = |f|^2, J~^T f~ =
    J^T f and J~^T J~ = J^T J, so scipy's trust-region reflective solver,
    which sees the system only through these (its subproblem is the SVD
    of the scaled J, its scaling J's column norms, its acceptance the
    cost), takes the same steps on it in exact arithmetic, at the cost of
    an SVD of n + 1 rows instead of m (7 s of the demo's 56-s convection
    fit without MCMC went into those SVDs; 2026-12-06). R is the Cholesky
    factor of A^T A (a matrix product: 5-10x cheaper than the SVD on tall
    matrices), equilibrated, or, where that factor's condition number
    exceeds :data:`COMPRESS_COND`, the QR factor of A (as costly as the
    SVD, and as accurate). A system with non-finite entries stays
    non-finite (the solver shrinks its step); one with m <= 2 (n + 1) rows
    is returned as it is.
    """
    m, n = jac.shape
    if m <= 2 * (n + 1):
        return f, jac
    a = np.empty((m, n + 1))
    a[:, :n] = jac
    a[:, n] = f
    if not np.all(np.isfinite(a)):
        return np.full(n + 1, np.nan), np.full((n + 1, n), np.nan)
    gram = a.T @ a
    scale = np.sqrt(np.diag(gram))
    scale = np.where(scale > 0.0, scale, 1.0)
    r: NDArray[np.float64] | None = None
    try:
        lower = np.linalg.cholesky(gram / np.outer(scale, scale))
        if np.linalg.cond(lower) < COMPRESS_COND:
            r = lower.T * scale
    except np.linalg.LinAlgError:
        r = None
    if r is None:
        r = np.linalg.qr(a, mode="r")
    return np.ascontiguousarray(r[:, n]), np.ascontiguousarray(r[:, :n])


class _Stalled(Exception):
    """Raised inside least_squares when the cost stopped falling (stall rule)."""


class _Cached:
    """fun and jac of least_squares from one batched simulation per point,
    compressed to n + 1 rows (:func:`_compressed`).

    Also keeps the best point seen and applies the stall rule: with
    ``stall`` = (window, gain), the solve is stopped when the cost (half the
    sum of squared whitened residuals, a log-likelihood difference at the
    held noise state) has fallen by less than ``gain`` over the last
    ``window`` evaluated points. ``progress`` is updated at every evaluated
    point (it says a line when one is due, :mod:`pneumafit.progress`).
    """

    def __init__(
        self,
        whitened: _Whitened,
        stall: tuple[int, float] | None = None,
        progress: Progress | None = None,
        where: str = "",
        log_likelihood: float = math.nan,
    ) -> None:
        self.whitened = whitened
        self.key: bytes | None = None
        self.value: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self.stall = stall
        self.best: tuple[float, NDArray[np.float64]] | None = None
        self.history: list[float] = []
        self.progress = progress
        self.where = where
        self.log_likelihood = log_likelihood
        self.cost0: float | None = None

    def status(self) -> str:
        """Points so far and the best log-likelihood (noise held) of this round."""
        assert self.best is not None and self.cost0 is not None
        gain = self.cost0 - self.best[0]
        sims = self.whitened.like.n_evaluations
        return (
            f"{self.where}{len(self.history)} points ({sims} simulations), log-likelihood "
            f"{self.log_likelihood + gain:.1f} ({gain:+.1f} this round)"
        )

    def _get(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        key = x.tobytes()
        if key != self.key or self.value is None:
            f, jac = self.whitened.fun_and_jac(x)
            self.key, self.value = key, _compressed(f, jac)
            self._observe(x, 0.5 * float(np.dot(f, f)))
        return self.value

    def _observe(self, x: NDArray[np.float64], cost: float) -> None:
        if self.cost0 is None:
            self.cost0 = cost
        if self.best is None or cost < self.best[0]:
            self.best = (cost, x.copy())
            # the next round, the reweighting and the covariance start here
            self.whitened.keep(x)
        assert self.best is not None
        self.history.append(self.best[0])
        if self.progress is not None:
            self.progress.update(self.status)
        if self.stall is not None:
            window, gain = self.stall
            if len(self.history) > window and self.history[-window - 1] - self.best[0] < gain:
                raise _Stalled

    def fun(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._get(x)[0]

    def jac(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._get(x)[1]


def fit_least_squares(
    likelihood: LogLikelihood,
    *,
    starts: Sequence[Mapping[str, float]] | None = None,
    n_random_starts: int = 0,
    seed: int | np.random.Generator = 0,
    max_reweight: int = 6,
    max_nfev: int = 60,
    tol: float = 1e-8,
    stall: tuple[int, float] | None = None,
    progress: Progress | Callable[[str], None] | None = None,
    candidates: Sequence[Mapping[str, float]] = (),
    n_screened: int = 1,
    screen_nfev: int = 8,
) -> PointEstimate:
    """Maximise the profile log-likelihood from one or more starts.

    Parameters
    ----------
    likelihood : LogLikelihood
    starts : sequence of mapping, optional
        Start values by name (free parameters not named start at the set's
        values). Default: the set's values.
    n_random_starts : int
        Extra starts drawn uniformly in the internal coordinates within the
        bounds (multimodal problems), from ``seed``.
    seed : int or numpy.random.Generator
    max_reweight : int
        Largest number of reweighting rounds per start.
    max_nfev : int
        Iterations of each inner least-squares solve.
    tol : float
        ftol, xtol and gtol of the inner solves.
    stall : (int, float), optional
        Stall rule (window, gain): an inner solve also stops when its
        log-likelihood has gained less than ``gain`` over the last
        ``window`` evaluated points (the best point is kept; status
        :data:`STALLED`, counted as converged). A model that cannot follow
        its data creeps for thousands of iterations with such gains, which
        move no estimate by a fraction of its uncertainty. The reweighting
        rounds stop by the same rule: after a round that gained less than
        ``gain`` in all.
    progress : Progress or callable, optional
        Updated at every evaluated point with the start, the round, the
        points and simulations so far and the round's best log-likelihood
        (noise parameters held at the round's start); it says a line at most
        every few seconds (:class:`pneumafit.progress.Progress`). A callable
        receives those lines (wrapped in a ``Progress`` labelled
        ``least squares``). Reporting changes no number of the fit.
    candidates : sequence of mapping, optional
        Further starts that are only screened: a short solve from each
        (``screen_nfev`` iterations, one round), and the ``n_screened`` best
        ends are solved in full after ``starts``. For a basin that the usual
        starts miss (the friction law's Stribeck bump: from a bump no larger
        than the Coulomb level it collapses onto it, and the Stribeck
        velocity then has no gradient) at less than a full solve per
        candidate.
    n_screened : int
        How many of the screened candidates become starts.
    screen_nfev : int
        Iterations of each screening solve.

    Returns
    -------
    PointEstimate
        The best start's estimate (by log posterior).
    """
    if progress is not None and not isinstance(progress, Progress):
        progress = Progress("least squares", progress)
    ps = likelihood.parameters
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    lo, hi = ps.internal_bounds()
    z_starts = [ps.to_internal(dict(s)) for s in (starts or [{}])]
    for _ in range(n_random_starts):
        a = np.where(np.isfinite(lo), lo, -10.0)
        b = np.where(np.isfinite(hi), hi, 10.0)
        z_starts.append(rng.uniform(a, b))
    n0 = likelihood.n_evaluations
    if candidates and n_screened > 0:
        # a short solve from each (one round of screen_nfev iterations, the
        # noise weights of its start held): the likelihood at a candidate
        # itself ranks bumps by how far the other parameters are from
        # fitting them, not by the basin they lead to
        screen = fit_least_squares(
            likelihood, starts=candidates, max_nfev=screen_nfev, max_reweight=1, tol=tol,
            stall=stall, progress=progress,
        )  # fmt: skip
        ranked = sorted(
            (r for r in screen.starts if math.isfinite(r["log_likelihood"])),
            key=lambda r: -r["log_likelihood"],
        )
        z_starts.extend(ps.to_internal(r["estimate"]) for r in ranked[:n_screened])
    best: tuple[float, NDArray[np.float64], dict[str, Any]] | None = None
    records: list[dict[str, Any]] = []
    width = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    margin = 1e-9 * width
    wh = _Whitened(likelihood)
    for i_start, z0 in enumerate(z_starts):
        z = np.clip(np.asarray(z0, float), lo + margin, hi - margin)
        ll = wh.set_state(z)
        nfev = 0
        message = "start is not finite" if not math.isfinite(ll) else ""
        status = 0
        if math.isfinite(ll):
            for i_round in range(max_reweight):
                where = f"start {i_start + 1}/{len(z_starts)}, " if len(z_starts) > 1 else ""
                where += f"round {i_round + 1}: "
                fj = _Cached(wh, stall, progress, where, ll)
                try:
                    sol = least_squares(
                        fj.fun, z, jac=fj.jac, bounds=(lo, hi),
                        method="trf", x_scale="jac", ftol=tol, xtol=tol, gtol=tol,
                        max_nfev=max_nfev,
                    )  # fmt: skip
                    x_end = sol.x
                    nfev += int(sol.nfev)
                    status, message = int(sol.status), str(sol.message)
                except _Stalled:
                    assert fj.best is not None and stall is not None
                    x_end = fj.best[1]
                    nfev += len(fj.history)
                    status = STALLED
                    message = (
                        f"stalled: the log-likelihood gained less than {stall[1]:g} over the "
                        f"last {stall[0]} points"
                    )
                ll_new = wh.set_state(x_end)
                improved = ll_new > ll + 1e-6 * max(1.0, abs(ll))
                # the stall rule between rounds too: a whole round (noise
                # weights re-estimated, >= 1 point) that gained less than
                # the rule's gain moved no estimate by a fraction of its
                # uncertainty, and neither would the next
                settled = stall is not None and ll_new - ll < stall[1]
                if ll_new >= ll or not math.isfinite(ll):
                    z, ll = x_end, ll_new
                if not improved:
                    break
                if settled:
                    message += (
                        f"; reweighting stopped: round {i_round + 1} gained less than {stall[1]:g}"
                    )
                    break
            wh.set_state(z)
        lp = ll + float(ps.log_prior(z)[0])
        start_values, end_values = ps.to_values(z0), ps.to_values(z)
        records.append(
            {
                "start": {n: float(start_values[n][0]) for n in ps.free_names},
                "log_likelihood": ll,
                "nfev": nfev,
                "message": message,
                "estimate": {n: float(end_values[n][0]) for n in ps.free_names},
            }
        )
        if math.isfinite(lp) and (best is None or lp > best[0]):
            best = (lp, z.copy(), {"ll": ll, "status": status, "message": message})
    if best is None:
        return PointEstimate(
            parameters=ps, z=ps.to_internal(), log_likelihood=-math.inf,
            log_posterior=-math.inf, covariance=None, success=False,
            message="no start gave a finite likelihood (every simulation failed)",
            n_evaluations=likelihood.n_evaluations - n0, starts=records,
        )  # fmt: skip
    lp, z, info = best
    wh.set_state(z)
    _, jac = wh.fun_and_jac(z, feasible=True)
    cov = _laplace(jac)
    values = {n: float(v[0]) for n, v in ps.to_values(z).items()}
    fitted = laplace_summary(ps.with_values(values), z, cov)
    ev = likelihood.evaluate(z[None, :], prediction=wh._first_set(z))
    noise = [{k: float(v[0]) for k, v in est.items()} for est in ev.noise]
    return PointEstimate(
        parameters=fitted, z=z, log_likelihood=float(info["ll"]), log_posterior=float(lp),
        covariance=cov, success=info["status"] > 0, message=info["message"],
        n_evaluations=likelihood.n_evaluations - n0, starts=records, noise=noise,
    )  # fmt: skip


def equilibrated_pinv(matrix: NDArray[np.float64], rcond: float = 1e-12) -> NDArray[np.float64]:
    """Pseudo-inverse of a symmetric positive semi-definite matrix, equilibrated.

    ``D pinv(D M D) D`` with ``D = diag(M)^-1/2`` (zero where the diagonal
    is zero). The internal coordinates mix pascals, kelvins and logarithms,
    so the diagonal of J^T J spans ~14 decades: a plain ``pinv`` with a
    relative cut-off then discards the directions of the small-diagonal
    coordinates (the initial pressures) as if they were exactly known, and
    every parameter correlated with them gets too narrow an interval
    (friction on the test campaigns: 1.3-1.8 times too narrow). Scaled to a
    unit diagonal the same matrix has a condition number ~1e3.
    """
    m = 0.5 * (matrix + matrix.T)
    diag = np.diag(m)
    d = np.where(diag > 0.0, 1.0 / np.sqrt(np.where(diag > 0.0, diag, 1.0)), 0.0)
    inner = np.linalg.pinv(d[:, None] * m * d[None, :], rcond=rcond, hermitian=True)
    return d[:, None] * inner * d[None, :]


def laplace_covariance(
    likelihood: LogLikelihood, z: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """Laplace covariance of the internal coordinates at ``z``.

    The pseudo-inverse of J^T J of the whitened residuals (noise state held
    at ``z``, priors included), as :func:`fit_least_squares` gives at its
    estimate; None when the Jacobian is not finite.
    """
    wh = _Whitened(likelihood)
    zz = np.asarray(z, dtype=float)
    wh.set_state(zz)
    _, jac = wh.fun_and_jac(zz, feasible=True)
    return _laplace(jac)


@dataclass
class RobustCovariance:
    """Laplace covariance and its misspecification-robust widening at one point.

    Attributes
    ----------
    laplace : ndarray (n_free, n_free)
        (J^T J)^+ of the whitened residuals and priors (:func:`laplace_covariance`).
    profile : ndarray (n_free, n_free) or None
        H^+, H the curvature of the profile log-likelihood (Gauss-Newton
        less each noise level's share, see
        :func:`recording_robust_covariance`); None where H is not positive
        definite.
    sandwich : ndarray (n_free, n_free) or None
        H^+ M H^+, M = G / (G - 1) sum_c s_c s_c^T over the G recordings c,
        s_c the gradient of recording c's profile log-likelihood.
    inflation : ndarray (n_free,)
        max(1, sqrt(profile_jj / laplace_jj), sqrt(sandwich_jj / laplace_jj))
        per free parameter.
    covariance : ndarray (n_free, n_free)
        The Laplace covariance with its standard deviations scaled by
        ``inflation`` (correlations kept): D laplace D, D = diag(inflation).
    clusters : int
        Recordings G in the sandwich.
    beyond_profile : ndarray (n_free,)
        max(1, sqrt(sandwich_jj / profile_jj)): the widening still due
        where the spread already follows the profile likelihood (an MCMC
        chain samples it); ``inflation`` where ``profile`` is None.
    informing : ndarray (n_free,)
        How many recordings inform each parameter: the participation ratio
        (sum_c I_c)^2 / sum_c I_c^2 of the recordings' Gauss-Newton
        information I_c = (J_c^T J_c)_jj on its diagonal. 1 when one recording
        holds all of it: that recording's score is then the total one, zero at
        the optimum, so the sandwich cannot widen the interval whatever the
        model's error (:data:`ONE_RECORDING`).
    recordings : tuple of str
        The clusters' recording names, in order of first appearance.
    dominant : ndarray of int (n_free,)
        Index in ``recordings`` of the recording with the most information
        on each parameter.
    """

    laplace: NDArray[np.float64]
    profile: NDArray[np.float64] | None
    sandwich: NDArray[np.float64] | None
    inflation: NDArray[np.float64]
    covariance: NDArray[np.float64]
    clusters: int
    beyond_profile: NDArray[np.float64]
    informing: NDArray[np.float64]
    recordings: tuple[str, ...]
    dominant: NDArray[np.int64]


#: Fewer informing recordings (:attr:`RobustCovariance.informing`) than this
#: and a parameter's interval rests on one recording: 1.5 is where the
#: largest recording's share of the information exceeds ~80 % with the
#: rest spread thin (two recordings sharing 80/20 give 1.47), so no second
#: recording holds enough of it to disagree.
ONE_RECORDING = 1.5


#: Smallest eigenvalue, relative to the largest, of the equilibrated profile
#: curvature for it to count as positive definite.
PROFILE_PD = 1.0e-10


def recording_robust_covariance(
    likelihood: LogLikelihood, z: NDArray[np.float64]
) -> RobustCovariance | None:
    """Misspecification-robust covariance, recordings as independent clusters.

    Two corrections to the Laplace covariance (J^T J)^-1 of the whitened
    residuals, which is the sampling covariance of the estimate only when the
    model is the rig's.

    **The profile curvature.** Each block's noise level is profiled, so its
    log-likelihood is -(n w / 2) log S(theta), S the sum of squares, w the
    block's tempering power (:meth:`LogLikelihood.temper`). Its Hessian is
    the Gauss-Newton J^T J *less* (2 / (n w)) g g^T, g = J^T r the block's
    gradient (whitened): a block that the model misses by more than its noise
    lets its noise level absorb part of any move, so it pins the parameters
    less than J^T J says. At a model that reaches the noise g is ~ sqrt(n)
    and the correction is negligible; at one 10x off it is not. This is the
    curvature that the MCMC, which samples the profile likelihood itself,
    sees.

    **The sandwich over recordings.** A model whose laws are not the rig's
    leaves recordings that disagree: each test, refitted alone, would move the
    parameters further than its noise allows. The cluster-robust (Godambe)
    covariance H^-1 M H^-1, with M the outer products of the recordings'
    scores at the estimate, measures that disagreement whatever the
    residuals' correlation inside a recording (Liang and Zeger 1986; Cameron
    and Miller 2015, small-sample factor G / (G - 1)). To first order,
    H^-1 s_c is how far dropping recording c would move the estimate, so
    this is the jackknife over recordings without G refits: one Jacobian,
    n_free + 1 simulations.

    Neither can see a bias that every recording shares, and with few
    recordings informing a parameter (two step tests) the sandwich has few
    degrees of freedom, so they only ever widen: the reported covariance is
    the Laplace one with each standard deviation scaled by the largest of 1
    and the two ratios.

    Returns None when the Jacobian is not finite or fewer than two
    recordings are compared.
    """
    wh = _Whitened(likelihood)
    zz = np.asarray(z, dtype=float)
    wh.set_state(zz)
    res, jac = wh.fun_and_jac(zz, feasible=True)
    if not (np.all(np.isfinite(jac)) and np.all(np.isfinite(res))):
        return None
    problem = likelihood.problem
    observations = problem.observations
    sizes = [np.asarray(o.data).size for o in observations]
    n_prior = likelihood.parameters.prior_residuals(zz[None, :]).shape[1]
    if sum(sizes) + n_prior != res.size:
        return None  # rows that cannot be told apart: no recording's score
    power = np.asarray(problem.tempering, dtype=float)
    groups = getattr(problem, "noise_groups", None)
    names: dict[str, int] = {}
    block_grad = np.zeros((len(observations), zz.size))
    block_info = np.zeros((len(observations), zz.size))
    cluster = np.empty(len(observations), dtype=np.int64)
    start = 0
    for j, (o, size) in enumerate(zip(observations, sizes, strict=True)):
        rows = slice(start, start + size)
        block_grad[j] = jac[rows].T @ res[rows]
        block_info[j] = np.einsum("ij,ij->j", jac[rows], jac[rows])
        # a long step test's segments are one cluster: one test (segments)
        cluster[j] = names.setdefault(source_recording(o.recording), len(names))
        start += size
    g = len(names)
    if g < 2:
        return None
    info = np.zeros((g, zz.size))
    np.add.at(info, cluster, block_info)
    total = info.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        informing = np.where(total > 0.0, total**2 / np.sum(info**2, axis=0), 0.0)
    dominant = np.argmax(info, axis=0).astype(np.int64)
    gauss_newton = jac.T @ jac
    laplace = equilibrated_pinv(gauss_newton)
    # each profiled noise level's share of the curvature: (2 / (n w)) g g^T,
    # per block, or per sensor where blocks share one sigma
    level = np.arange(len(observations)) if groups is None else np.where(
        groups >= 0, groups + len(observations), np.arange(len(observations))
    )  # fmt: skip
    share = np.zeros_like(gauss_newton)
    for lv in np.unique(level):
        members = np.flatnonzero(level == lv)
        n_w = float(sum(sizes[m] * power[m] for m in members))
        if n_w > 0.0:
            gg = block_grad[members].sum(axis=0)
            share += (2.0 / n_w) * np.outer(gg, gg)
    hessian = gauss_newton - share
    diag = np.diag(hessian)
    profile: NDArray[np.float64] | None = None
    if np.all(diag > 0.0):
        d = 1.0 / np.sqrt(diag)
        eig = np.linalg.eigvalsh(d[:, None] * hessian * d[None, :])
        if eig[0] > PROFILE_PD * eig[-1]:
            profile = equilibrated_pinv(hessian)
    h_inv = profile if profile is not None else laplace
    scores = np.zeros((g, zz.size))
    np.add.at(scores, cluster, block_grad)
    meat = g / (g - 1.0) * (scores.T @ scores)
    sandwich = h_inv @ meat @ h_inv
    sandwich = 0.5 * (sandwich + sandwich.T)
    lap_var = np.diag(laplace)
    ratio = np.ones(zz.size)
    for cov in (profile, sandwich):
        if cov is None:
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where(lap_var > 0.0, np.diag(cov) / lap_var, 1.0)
        ratio = np.maximum(ratio, np.nan_to_num(r, nan=1.0, posinf=1.0))
    inflation = np.sqrt(ratio)
    widened = inflation[:, None] * laplace * inflation[None, :]
    beyond = inflation
    if profile is not None:
        pro_var = np.diag(profile)
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where(pro_var > 0.0, np.diag(sandwich) / pro_var, 1.0)
        beyond = np.sqrt(np.maximum(np.nan_to_num(r, nan=1.0, posinf=1.0), 1.0))
    return RobustCovariance(
        laplace, profile, sandwich, inflation, widened, g, beyond,
        informing, tuple(names), dominant,
    )  # fmt: skip


def _laplace(jac: NDArray[np.float64]) -> NDArray[np.float64] | None:
    if not np.all(np.isfinite(jac)):
        return None
    return equilibrated_pinv(jac.T @ jac)


def laplace_summary(
    parameters: ParameterSet, z: NDArray[np.float64], covariance: NDArray[np.float64] | None
) -> ParameterSet:
    """Attach Laplace ``std`` and ``interval_90`` to the free parameters.

    The interval is z +- 1.645 s in the internal coordinate, mapped to
    values (asymmetric for log scale); ``std`` is s in linear scale and
    value * s (delta method) in log scale. The correlation of the internal
    coordinates is attached to the set.
    """
    if covariance is None:
        return parameters
    s = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    out = parameters.copy()
    for j, p in enumerate(parameters.free):
        lo = float(p.to_value(z[j] - Z90 * s[j]))
        hi = float(p.to_value(z[j] + Z90 * s[j]))
        lo, hi = max(lo, p.lower), min(hi, p.upper)
        std = float(s[j] * (p.value if p.scale == "log" else 1.0))
        out = out.replace(p.name, std=std, interval_90=(lo, hi), uncertainty="laplace")
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = covariance / np.outer(s, s)
    out.correlation = (parameters.free_names, np.nan_to_num(corr))
    return out
