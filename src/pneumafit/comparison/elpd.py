"""Expected log predictive density from posterior draws: WAIC and PSIS-LOO, vectorised.

WAIC (Watanabe 2010, as in Vehtari, Gelman and Gabry 2017) of observation i:
lppd_i - V_s[log p(y_i | theta_s)], with lppd_i = log mean_s p(y_i |
theta_s) and V_s the variance over the draws (no Bessel correction); a
variance above 0.4 marks a point where WAIC may fail.

PSIS-LOO (Vehtari, Gelman and Gabry 2017; Vehtari, Simpson, Gelman, Yao and
Gabry 2024) estimates each observation's leave-one-out predictive density
from posterior draws by importance sampling with the ratios
r_s = 1 / p(y_i | theta_s), whose largest values are replaced by the
expected order statistics of a generalised Pareto distribution fitted to
them. For S draws and relative efficiency r_eff:

1. the tail holds the M = ceil(min(S / 5, 3 sqrt(S / r_eff))) largest log
   ratios, above the cut-off at the (M + 1)-th largest (never below the
   log of the smallest normal float);
2. the generalised Pareto (shape k, scale sigma) is fitted to the tail's
   exceedances exp(log r) - exp(cut-off) by the empirical-Bayes estimate of
   Zhang and Stephens (2009): a posterior mean of theta = -k / sigma over
   m = 30 + floor(sqrt(M)) grid points
   theta_j = 1 / x_(M) + (1 - sqrt(m / (j - 1/2))) / (3 x_(q)), x_(q) the
   first quartile, each weighted by its profile log-likelihood
   l_j = M (log(-theta_j / k_j) - k_j - 1) with k_j = mean(log1p(-theta_j x))
   (weights below 10 machine epsilons dropped); k = mean(log1p(-theta x))
   and sigma = -k / theta at the posterior mean theta; then k is shrunk
   towards 1/2 by a weak prior worth 10 observations,
   k <- (M k + 5) / (M + 10) (sigma kept from before the shrinking);
3. the tail is replaced, in the ratios' own order, by exp(cut-off) plus the
   fitted distribution's quantiles at (i - 1/2) / M, truncated at the
   largest raw ratio; a tail of 4 or fewer points, or a fit with no finite
   k, is left raw (k = inf);
4. the weights are normalised and elpd_i = log sum_s w_s p(y_i | theta_s).

This is the estimator of ArviZ's ``loo`` (``psislw``), which fits one
observation at a time in Python; here every step runs on blocks of
observations at once (the main job's comparison: ~21 600 observations of
60 draws per model). ``tests/comparison/test_elpd.py`` checks both against ArviZ to
rounding on random and heavy-tailed matrices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ElpdResult", "psis_log_weights", "psis_loo", "waic"]

#: Posterior variance of a point's log predictive density above which WAIC
#: may fail (Vehtari, Gelman and Gabry 2017).
WAIC_VARIANCE_LIMIT = 0.4

#: Prior of the shape estimate: weight (observations) and value.
_PRIOR_K_WEIGHT, _PRIOR_K = 10.0, 0.5
#: Scale of the grid of theta around the first quartile (Zhang and Stephens's b = 3).
_PRIOR_B = 3.0
#: Rows per block of the vectorised fit: bounds the (rows, grid, tail) work array.
_BLOCK_ELEMENTS = 4_000_000


@dataclass(frozen=True)
class ElpdResult:
    """WAIC or PSIS-LOO of a pointwise log-likelihood matrix (log scale, higher is better).

    Attributes
    ----------
    elpd : float
        Expected log pointwise predictive density, sum of ``pointwise``.
    se : float
        Its standard error, sqrt(n var(pointwise)).
    p : float
        Effective number of parameters, lppd - elpd.
    pointwise : ndarray, shape (n,)
        Each observation's term.
    n_unreliable : int
        Points where the estimate may fail: WAIC, posterior variance above
        :data:`WAIC_VARIANCE_LIMIT`; PSIS-LOO, Pareto k above ``good_k``.
    pareto_k : ndarray, shape (n,), optional
        PSIS-LOO: shape estimate of each observation's tail (inf where not fitted).
    good_k : float, optional
        PSIS-LOO: largest k with a reliable estimate for this many draws,
        min(1 - 1 / log10(S), 0.7).
    """

    elpd: float
    se: float
    p: float
    pointwise: NDArray[np.float64]
    n_unreliable: int
    pareto_k: NDArray[np.float64] | None = None
    good_k: float | None = None


def _logsumexp(a: NDArray[np.float64], axis: int = -1) -> NDArray[np.float64]:
    top = np.max(a, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    return np.squeeze(top, axis=axis) + np.log(np.sum(np.exp(a - top), axis=axis))


def _gpd_fit(y: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Zhang-Stephens fit of rows of sorted positive exceedances ``y`` (rows, M).

    Returns the shrunk shape k and the scale sigma of each row.
    """
    n = y.shape[1]
    m = 30 + int(np.sqrt(n))
    grid = 1.0 - np.sqrt(m / (np.arange(1, m + 1, dtype=float) - 0.5))  # (m,)
    quartile = y[:, int(n / 4 + 0.5) - 1]
    theta = grid[None, :] / (_PRIOR_B * quartile[:, None]) + 1.0 / y[:, -1:]  # (rows, m)
    k = np.mean(np.log1p(-theta[:, :, None] * y[:, None, :]), axis=2)  # (rows, m)
    profile = n * (np.log(-theta / k) - k - 1.0)
    # weight of grid point j: 1 / sum_i exp(l_i - l_j)
    weight = 1.0 / np.sum(np.exp(profile[:, None, :] - profile[:, :, None]), axis=2)
    weight = np.where(weight >= 10.0 * np.finfo(float).eps, weight, 0.0)
    weight /= np.sum(weight, axis=1, keepdims=True)
    theta_post = np.sum(theta * weight, axis=1)
    k_post = np.mean(np.log1p(-theta_post[:, None] * y), axis=1)
    sigma = -k_post / theta_post
    k_post = (n * k_post + _PRIOR_K_WEIGHT * _PRIOR_K) / (n + _PRIOR_K_WEIGHT)
    return k_post, sigma


def _gpd_quantiles(
    p: NDArray[np.float64], k: NDArray[np.float64], sigma: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Quantiles at probabilities ``p`` (M,) of rows of generalised Paretos (rows, M)."""
    lp = np.log1p(-p)[None, :]
    tiny = np.abs(k) < np.finfo(float).eps
    safe = np.where(tiny, 1.0, k)[:, None]
    q = np.where(tiny[:, None], -lp, np.expm1(-safe * lp) / safe)
    q = q * sigma[:, None]
    return np.where((sigma > 0)[:, None], q, np.nan)


def psis_log_weights(
    log_ratios: NDArray[np.float64], reff: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pareto-smoothed, normalised log importance weights of each row.

    Parameters
    ----------
    log_ratios : ndarray, shape (n, S)
        Log importance ratios of each of n observations (for LOO, minus the
        pointwise log-likelihood), S draws per row.
    reff : float
        Relative efficiency of the draws, ESS / S (1 for independent draws).

    Returns
    -------
    log_weights : ndarray, shape (n, S)
        Smoothed, truncated log weights, each row normalised to sum 1.
    k : ndarray, shape (n,)
        Fitted Pareto shape of each row's tail (inf where not fitted).
    """
    x = np.array(log_ratios, dtype=float, ndmin=2, copy=True)
    n_obs, s = x.shape
    x -= np.max(x, axis=1, keepdims=True)
    m_tail = int(np.ceil(min(s / 5.0, 3.0 * np.sqrt(s / reff))))
    # the M + 1 largest of each row, ascending (a partition, then a sort of those only)
    top = np.argpartition(x, s - m_tail - 1, axis=1)[:, s - m_tail - 1 :]
    order = np.take_along_axis(top, np.argsort(np.take_along_axis(x, top, axis=1), axis=1), axis=1)
    xs = np.take_along_axis(x, order, axis=1)  # (n, M + 1)
    cut = np.maximum(xs[:, 0], np.log(np.finfo(float).tiny))
    tail_len = np.sum(xs > cut[:, None], axis=1)
    k = np.full(n_obs, np.inf)
    for length in np.unique(tail_len):
        if length <= 4:
            continue
        rows_all = np.flatnonzero(tail_len == length)
        grid = 30 + int(np.sqrt(length))
        block = max(1, _BLOCK_ELEMENTS // (grid * max(grid, length)))
        p = np.arange(0.5, length) / length
        for start in range(0, rows_all.size, block):
            rows = rows_all[start : start + block]
            ecut = np.exp(cut[rows])
            # the tail: the row's `length` largest entries (all above the cut), ascending
            y = np.exp(xs[rows, m_tail + 1 - length :]) - ecut[:, None]
            k_rows, sigma = _gpd_fit(y)
            fitted = np.isfinite(k_rows)
            k[rows] = k_rows
            if not np.any(fitted):
                continue
            rows, ecut = rows[fitted], ecut[fitted]
            smooth = np.log(_gpd_quantiles(p, k_rows[fitted], sigma[fitted]) + ecut[:, None])
            cols = order[rows, m_tail + 1 - length :]
            x[rows[:, None], cols] = np.minimum(smooth, 0.0)
    x -= _logsumexp(x, axis=1)[:, None]
    return x, k


def _lppd(ll: NDArray[np.float64]) -> NDArray[np.float64]:
    return _logsumexp(ll, axis=1) - np.log(ll.shape[1])


def waic(log_likelihood: NDArray[np.float64]) -> ElpdResult:
    """WAIC of a pointwise log-likelihood matrix.

    Parameters
    ----------
    log_likelihood : ndarray, shape (S, n)
        log p(y_i | theta_s) of each of n observations under each of S draws.

    Returns
    -------
    ElpdResult
    """
    ll = np.asarray(log_likelihood, dtype=float).T  # (n, S)
    variance = np.var(ll, axis=1)
    pointwise = _lppd(ll) - variance
    return ElpdResult(
        elpd=float(np.sum(pointwise)),
        se=float(np.sqrt(ll.shape[0] * np.var(pointwise))),
        p=float(np.sum(variance)),
        pointwise=pointwise,
        n_unreliable=int(np.sum(variance > WAIC_VARIANCE_LIMIT)),
    )


def psis_loo(log_likelihood: NDArray[np.float64], reff: float = 1.0) -> ElpdResult:
    """PSIS-LOO of a pointwise log-likelihood matrix.

    Parameters
    ----------
    log_likelihood : ndarray, shape (S, n)
        log p(y_i | theta_s) of each of n observations under each of S draws.
    reff : float
        Relative efficiency of the draws, ESS / S (1: independent, e.g. thinned).

    Returns
    -------
    ElpdResult
    """
    ll = np.asarray(log_likelihood, dtype=float).T  # (n, S)
    n_obs, s = ll.shape
    lw, k = psis_log_weights(-ll, reff)
    pointwise = _logsumexp(lw + ll, axis=1)
    elpd = float(np.sum(pointwise))
    good_k = float(min(1.0 - 1.0 / np.log10(s), 0.7))
    return ElpdResult(
        elpd=elpd,
        se=float(np.sqrt(n_obs * np.var(pointwise))),
        p=float(np.sum(_lppd(ll)) - elpd),
        pointwise=pointwise,
        n_unreliable=int(np.sum(k > good_k)),
        pareto_k=k,
        good_k=good_k,
    )
