"""Whiteness and independence tests of a residual (Ljung, *System
Identification*, 2nd ed., sec. 16.6; MATLAB's ``resid``).

All correlations use the biased estimator of the covariance,
R(k) = (1/n) sum_t x(t) x(t+k) of the mean-removed series, normalised by
R(0) (as ``resid`` and the Ljung-Box statistic do), and lags count samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from pneumafit.errors import PneumafitInputError

__all__ = [
    "LjungBox",
    "autocorrelation",
    "cross_correlation",
    "cross_correlation_band",
    "ljung_box",
    "whiteness_band",
]


def _series(x: ArrayLike, what: str) -> NDArray[np.float64]:
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 1 or arr.size < 2:
        raise PneumafitInputError(
            f"{what}: expected a 1-D series of at least 2 samples, found {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise PneumafitInputError(f"{what}: expected finite values, found NaN or infinity")
    return arr - arr.mean()


def _check_lag(max_lag: int, n: int) -> int:
    if isinstance(max_lag, bool) or int(max_lag) != max_lag or not 1 <= max_lag < n:
        raise PneumafitInputError(
            f"max_lag: expected an integer in [1, {n - 1}], found {max_lag!r}"
        )
    return int(max_lag)


def autocorrelation(x: ArrayLike, max_lag: int) -> NDArray[np.float64]:
    """Normalised autocorrelation r(k) = R(k) / R(0), k = 0..max_lag.

    Parameters
    ----------
    x : array_like, shape (n,)
        Series (any unit); its mean is removed.
    max_lag : int
        Largest lag (samples), 1 <= max_lag < n.

    Returns
    -------
    ndarray, shape (max_lag + 1,)
        r(0) = 1, ..., r(max_lag); NaN for a constant series.
    """
    e = _series(x, "autocorrelation")
    m = _check_lag(max_lag, e.size)
    c0 = float(e @ e)
    if c0 == 0.0:
        return np.full(m + 1, np.nan)
    n = e.size
    return np.array([float(e[: n - k] @ e[k:]) / c0 for k in range(m + 1)])


def cross_correlation(residual: ArrayLike, inputs: ArrayLike, max_lag: int) -> NDArray[np.float64]:
    """Normalised cross-correlation r_eu(tau), tau = -max_lag..max_lag.

    r_eu(tau) = R_eu(tau) / sqrt(R_e(0) R_u(0)), R_eu(tau) = (1/n) sum_t
    e(t) u(t - tau): a positive lag pairs the residual with an *earlier*
    input (the causal side, as in ``resid``).

    Parameters
    ----------
    residual, inputs : array_like, shape (n,)
        Residual e and input u on the same samples; means are removed.
    max_lag : int
        Largest lag (samples), 1 <= max_lag < n.

    Returns
    -------
    ndarray, shape (2 max_lag + 1,)
        Values at lags -max_lag..max_lag; NaN when either series is constant.
    """
    e = _series(residual, "cross-correlation: residual")
    u = _series(inputs, "cross-correlation: input")
    if e.size != u.size:
        raise PneumafitInputError(
            f"cross-correlation: expected residual and input of equal length, found "
            f"{e.size} and {u.size}"
        )
    m = _check_lag(max_lag, e.size)
    scale = math.sqrt(float(e @ e) * float(u @ u))
    if scale == 0.0:
        return np.full(2 * m + 1, np.nan)
    n = e.size
    out = np.empty(2 * m + 1)
    for i, tau in enumerate(range(-m, m + 1)):
        out[i] = float(e[tau:] @ u[: n - tau]) if tau >= 0 else float(e[: n + tau] @ u[-tau:])
    return out / scale


def whiteness_band(n: int, alpha: float = 0.01) -> float:
    """Half-width of the white-noise band of a normalised correlation.

    z_{1 - alpha/2} / sqrt(n): under whiteness each r(k), k >= 1, is
    asymptotically N(0, 1/n) (Ljung sec. 16.6; ``resid``'s confidence region,
    99 % by default).

    Parameters
    ----------
    n : int
        Number of samples.
    alpha : float
        Two-sided significance level, 0 < alpha < 1.
    """
    if not 0.0 < alpha < 1.0:
        raise PneumafitInputError(f"alpha: expected a level in (0, 1), found {alpha!r}")
    return float(stats.norm.ppf(1.0 - alpha / 2.0) / math.sqrt(n))


def cross_correlation_band(
    residual_acf: ArrayLike, input_acf: ArrayLike, n: int, alpha: float = 0.01
) -> float:
    """Half-width of the independence band of a residual-input cross-correlation.

    If e and u are independent, sqrt(n) r_eu(tau) is asymptotically
    N(0, P) with P = sum_k r_e(k) r_u(k) over all lags (Ljung sec. 16.6;
    ``resid``), summed here over |k| <= max_lag. For a white residual P = 1
    whatever the input's colour. P is floored at 1 (the white value), so a
    finite sum that comes out smaller never narrows the band.

    Parameters
    ----------
    residual_acf, input_acf : array_like, shape (max_lag + 1,)
        Normalised autocorrelations r(0..max_lag) of e and u.
    n : int
        Number of samples.
    alpha : float
        Two-sided significance level.
    """
    re = np.asarray(residual_acf, dtype=float)
    ru = np.asarray(input_acf, dtype=float)
    p = 1.0 + 2.0 * float(np.sum(re[1:] * ru[1:]))
    return whiteness_band(n, alpha) * math.sqrt(max(p, 1.0))


@dataclass(frozen=True)
class LjungBox:
    """Ljung-Box portmanteau test of whiteness.

    Attributes
    ----------
    statistic : float
        Q = n (n + 2) sum_{k=1..lags} r(k)^2 / (n - k) (dimensionless).
    p_value : float
        P(chi2_lags >= Q): small values reject whiteness.
    lags : int
        Number of autocorrelations summed (the chi-square's degrees of freedom).
    n : int
        Number of samples.
    """

    statistic: float
    p_value: float
    lags: int
    n: int

    @property
    def violation(self) -> float:
        """Standardised statistic (Q - lags) / sqrt(2 lags): ~N(0, 1) for white
        noise, comparable across lag counts; large means far from white."""
        return (self.statistic - self.lags) / math.sqrt(2.0 * self.lags)


def ljung_box(x: ArrayLike, lags: int) -> LjungBox:
    """Ljung-Box test of a series (Ljung and Box, Biometrika 65, 1978).

    Parameters
    ----------
    x : array_like, shape (n,)
        Series; its mean is removed (no model parameters are subtracted from
        the degrees of freedom: the residual of a simulation, not of a fitted
        ARMA model).
    lags : int
        Number of autocorrelations m, 1 <= m < n.

    Returns
    -------
    LjungBox
        Q and its p-value from the chi-square distribution with m degrees of
        freedom; NaN for a constant series.
    """
    r = autocorrelation(x, lags)
    n = int(np.asarray(x).size)
    k = np.arange(1, lags + 1)
    q = float(n * (n + 2) * np.sum(r[1:] ** 2 / (n - k)))
    p = float(stats.chi2.sf(q, lags)) if math.isfinite(q) else math.nan
    return LjungBox(statistic=q, p_value=p, lags=int(lags), n=n)
