"""Noise models of the residuals (data - model) of one recorded channel.

A noise model is a small object chosen per channel. It gives

- :meth:`NoiseModel.logpdf`: the log density of residual vectors for given
  noise parameters (``sigma``, and ``phi`` for AR(1));
- :meth:`NoiseModel.estimate`: the maximum-likelihood noise parameters of
  residual vectors;
- :meth:`NoiseModel.loglike`: the *profile* log-likelihood, ``logpdf`` at
  the estimated noise parameters. This is how sigma is "estimated" during a
  fit: it is maximised out at every parameter set, separately for every
  (recording, channel) block, so samplers and optimisers never see it. For
  the Gaussian model the profile equals, up to a constant, the likelihood
  with sigma integrated out under a Jeffreys prior 1/sigma (both are
  -n/2 log(sum r^2)).
- :meth:`NoiseModel.whiten`: residuals scaled so that half their sum of
  squares is -logpdf up to terms that do not depend on the model (for least
  squares with the noise parameters held).

All functions are vectorised over parameter sets: residuals have shape
(n_sets, n_samples) and results (n_sets,).

The AR(1) model is for coloured residuals, which is what a model that is
simpler than the rig leaves (its residuals are smooth, not white): it
counts the information in the data honestly instead of treating thousands
of correlated samples as independent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import prange
from numpy.typing import ArrayLike, NDArray
from scipy.special import gammaln

from pneumafit.errors import PneumafitInputError
from pneumafit.numba_stamp import njit

__all__ = [
    "AR1",
    "Gaussian",
    "NoiseModel",
    "Quantized",
    "StudentT",
    "correlation_time",
    "detect_resolution",
    "noise_model",
    "pool_sigma",
]

_LOG_2PI = math.log(2.0 * math.pi)
#: Largest |phi| of the AR(1) estimate (a unit root has no stationary density).
PHI_MAX = 0.9999


def _as2d(r: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.atleast_2d(np.asarray(r, dtype=float))


class NoiseModel:
    """Base class; see the module docstring for the four methods."""

    name: ClassVar[str] = ""
    #: Noise parameters estimated per block (counted in AIC and BIC).
    n_parameters: ClassVar[int] = 1

    def estimate(
        self, r: NDArray[np.float64], floor: float = 0.0
    ) -> dict[str, NDArray[np.float64]]:
        raise NotImplementedError

    def logpdf(self, r: NDArray[np.float64], **params: NDArray[np.float64]) -> NDArray[np.float64]:
        raise NotImplementedError

    def loglike(self, r: NDArray[np.float64], floor: float = 0.0) -> NDArray[np.float64]:
        """Profile log-likelihood (n_sets,) of residuals (n_sets, n)."""
        r2 = _as2d(r)
        return self.logpdf(r2, **self.estimate(r2, floor))

    def whiten(self, r: NDArray[np.float64], **params: float) -> NDArray[np.float64]:
        raise NotImplementedError

    def whitening_state(self, r: NDArray[np.float64], floor: float = 0.0) -> dict[str, object]:
        """Noise parameters of one residual vector (n,) to hold in :meth:`whiten`."""
        est = self.estimate(np.asarray(r, dtype=float)[None, :], floor)
        return {k: float(v[0]) for k, v in est.items()}

    def describe(self) -> dict[str, object]:
        """Settings for fit.json."""
        return {"name": self.name}


@dataclass(frozen=True)
class Gaussian(NoiseModel):
    """Independent N(0, sigma^2) residuals."""

    name: ClassVar[str] = "gaussian"
    n_parameters: ClassVar[int] = 1

    def estimate(
        self, r: NDArray[np.float64], floor: float = 0.0
    ) -> dict[str, NDArray[np.float64]]:
        r2 = _as2d(r)
        sigma = np.sqrt(np.mean(r2 * r2, axis=1))
        return {"sigma": np.maximum(sigma, max(floor, 1e-300))}

    def logpdf(self, r: NDArray[np.float64], sigma: NDArray[np.float64]) -> NDArray[np.float64]:
        r2 = _as2d(r)
        s = np.asarray(sigma, dtype=float).reshape(-1, 1)
        z = r2 / s
        n = r2.shape[1]
        return -0.5 * np.sum(z * z, axis=1) - n * np.log(s[:, 0]) - 0.5 * n * _LOG_2PI

    def whiten(self, r: NDArray[np.float64], sigma: float) -> NDArray[np.float64]:
        return np.asarray(r, dtype=float) / sigma


@dataclass(frozen=True)
class StudentT(NoiseModel):
    """Independent Student-t residuals of scale sigma and ``nu`` degrees of freedom.

    Heavy tails make outliers (spikes, dropped samples, a badly modelled
    instant) cost little. ``nu`` is held (4 by default); sigma is estimated
    by the EM fixed point sigma^2 = mean(w r^2), w = (nu + 1) / (nu + r^2 / sigma^2).
    """

    nu: float = 4.0
    iterations: int = 60
    name: ClassVar[str] = "student-t"
    n_parameters: ClassVar[int] = 1

    def __post_init__(self) -> None:
        if not self.nu > 0.0:
            raise PneumafitInputError(f"student-t noise: nu: expected a value > 0, found {self.nu}")

    def estimate(
        self, r: NDArray[np.float64], floor: float = 0.0
    ) -> dict[str, NDArray[np.float64]]:
        r2 = _as2d(r)
        sq = r2 * r2
        tiny = max(floor, 1e-300)
        mad = 1.4826 * np.median(np.abs(r2), axis=1)
        var = np.maximum(np.where(mad > 0, mad * mad, np.mean(sq, axis=1)), tiny * tiny)
        nu = self.nu
        for _ in range(self.iterations):
            w = (nu + 1.0) / (nu + sq / var[:, None])
            new = np.maximum(np.mean(w * sq, axis=1), tiny * tiny)
            if np.all(np.abs(new - var) <= 1e-10 * var):
                var = new
                break
            var = new
        return {"sigma": np.sqrt(var)}

    def logpdf(self, r: NDArray[np.float64], sigma: NDArray[np.float64]) -> NDArray[np.float64]:
        r2 = _as2d(r)
        s = np.asarray(sigma, dtype=float).reshape(-1, 1)
        nu = self.nu
        n = r2.shape[1]
        z2 = (r2 / s) ** 2
        const = gammaln((nu + 1.0) / 2.0) - gammaln(nu / 2.0) - 0.5 * math.log(nu * math.pi)
        return (
            n * const - 0.5 * (nu + 1.0) * np.sum(np.log1p(z2 / nu), axis=1) - n * np.log(s[:, 0])
        )

    def whiten(
        self, r: NDArray[np.float64], sigma: float, weights: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Iteratively reweighted least squares: r sqrt(w) / sigma, w held."""
        rr = np.asarray(r, dtype=float)
        if weights is None:
            weights = (self.nu + 1.0) / (self.nu + (rr / sigma) ** 2)
        return rr * np.sqrt(weights) / sigma

    def whitening_state(self, r: NDArray[np.float64], floor: float = 0.0) -> dict[str, object]:
        """sigma and the IRLS weights w at residuals ``r`` (n,)."""
        rr = np.asarray(r, dtype=float)
        sigma = float(self.estimate(rr[None, :], floor)["sigma"][0])
        return {"sigma": sigma, "weights": (self.nu + 1.0) / (self.nu + (rr / sigma) ** 2)}

    def describe(self) -> dict[str, object]:
        return {"name": self.name, "nu": self.nu}


@dataclass(frozen=True)
class AR1(NoiseModel):
    """Stationary Gaussian AR(1) residuals: r_t = phi r_(t-1) + e_t, e_t ~ N(0, sigma^2).

    ``sigma`` is the innovation standard deviation; the marginal one is
    sigma / sqrt(1 - phi^2). The exact likelihood (r_0 from the stationary
    distribution) is used. phi is estimated by conditional least squares,
    sum r_t r_(t-1) / sum r_(t-1)^2 (clipped to |phi| <= 0.9999), and sigma
    exactly for that phi. Samples are taken as equally spaced (the
    likelihood compares models on a uniform grid per recording).
    """

    name: ClassVar[str] = "ar1"
    n_parameters: ClassVar[int] = 2

    def estimate(
        self, r: NDArray[np.float64], floor: float = 0.0
    ) -> dict[str, NDArray[np.float64]]:
        r2 = _as2d(r)
        num = np.sum(r2[:, 1:] * r2[:, :-1], axis=1)
        den = np.sum(r2[:, :-1] * r2[:, :-1], axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            phi = np.where(den > 0, num / den, 0.0)
        phi = np.clip(np.nan_to_num(phi), -PHI_MAX, PHI_MAX)
        e = r2[:, 1:] - phi[:, None] * r2[:, :-1]
        ss = (1.0 - phi * phi) * r2[:, 0] ** 2 + np.sum(e * e, axis=1)
        sigma = np.sqrt(ss / r2.shape[1])
        return {"sigma": np.maximum(sigma, max(floor, 1e-300)), "phi": phi}

    def logpdf(
        self, r: NDArray[np.float64], sigma: NDArray[np.float64], phi: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        r2 = _as2d(r)
        n = r2.shape[1]
        s = np.asarray(sigma, dtype=float).reshape(-1)
        ph = np.broadcast_to(np.asarray(phi, dtype=float).reshape(-1), s.shape)
        e = r2[:, 1:] - ph[:, None] * r2[:, :-1]
        ss = (1.0 - ph * ph) * r2[:, 0] ** 2 + np.sum(e * e, axis=1)
        return -0.5 * n * _LOG_2PI - n * np.log(s) + 0.5 * np.log1p(-ph * ph) - 0.5 * ss / (s * s)

    def whiten(self, r: NDArray[np.float64], sigma: float, phi: float) -> NDArray[np.float64]:
        """Innovations over sigma: [sqrt(1 - phi^2) r_0, r_t - phi r_(t-1)] / sigma.

        Works on the last axis, so a batch (n_sets, n) is whitened row by row.
        """
        rr = np.asarray(r, dtype=float)
        first = math.sqrt(1.0 - phi * phi) * rr[..., :1]
        rest = rr[..., 1:] - phi * rr[..., :-1]
        return np.concatenate([first, rest], axis=-1) / sigma


_SQRT2 = math.sqrt(2.0)
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@njit(cache=True)
def _log_cell(r: float, half: float, sigma: float) -> float:
    """log P(|e - r| < half), e ~ N(0, sigma^2): one quantised reading."""
    a = (abs(r) - half) / sigma
    b = (abs(r) + half) / sigma
    if a < 8.0:
        p = 0.5 * (math.erfc(a / _SQRT2) - math.erfc(b / _SQRT2))
        if p > 1e-300:
            return math.log(p)
    # far tail: 0.5 erfc(a / sqrt 2) ~ phi(a) / a, the b term negligible
    return -0.5 * a * a - math.log(a) - _LOG_SQRT_2PI


@njit(cache=True, parallel=True)
def _quantized_logpdf(r: np.ndarray, half: float, sigma: np.ndarray, out: np.ndarray) -> None:
    for i in prange(r.shape[0]):
        total = 0.0
        for k in range(r.shape[1]):
            total += _log_cell(r[i, k], half, sigma[i])
        out[i] = total


@njit(cache=True)
def _quantized_whiten(r: np.ndarray, half: float, sigma: float, out: np.ndarray) -> None:
    top = _log_cell(0.0, half, sigma)
    for k in range(r.shape[0]):
        d = 2.0 * (top - _log_cell(r[k], half, sigma))
        out[k] = math.copysign(math.sqrt(max(d, 0.0)), r[k])


@dataclass(frozen=True)
class Quantized(NoiseModel):
    """Gaussian noise, then rounding to a grid of step ``resolution`` (an encoder).

    A reading y_q of a true value y has probability
    Phi((y_q - y + q/2) / sigma) - Phi((y_q - y - q/2) / sigma): a residual
    inside the cell costs almost nothing when sigma < q, so a stuck piston
    read a thousand times is not located to a thousandth of a count (which
    a Gaussian model of the readings claims, and which biased the friction of
    the virtual rig by ten times its interval). sigma is estimated with
    Sheppard's correction, sigma^2 = mean(r^2) - q^2 / 12 (at least
    (q / 10)^2), closed form at every parameter set.

    Parameters
    ----------
    resolution : float
        Grid step q of the readings (SI), e.g. from :func:`detect_resolution`.
    """

    resolution: float = 1e-5
    name: ClassVar[str] = "quantized"
    n_parameters: ClassVar[int] = 1

    def __post_init__(self) -> None:
        if not self.resolution > 0.0:
            raise PneumafitInputError(
                f"quantized noise: resolution: expected a value > 0, found {self.resolution}"
            )

    def estimate(
        self, r: NDArray[np.float64], floor: float = 0.0
    ) -> dict[str, NDArray[np.float64]]:
        r2 = _as2d(r)
        q = self.resolution
        var = np.mean(r2 * r2, axis=1) - q * q / 12.0
        return {"sigma": np.sqrt(np.maximum(var, max((0.1 * q) ** 2, floor * floor)))}

    def logpdf(self, r: NDArray[np.float64], sigma: NDArray[np.float64]) -> NDArray[np.float64]:
        r2 = np.ascontiguousarray(_as2d(r))
        s = np.broadcast_to(np.asarray(sigma, dtype=float).reshape(-1), (r2.shape[0],)).copy()
        out = np.empty(r2.shape[0])
        _quantized_logpdf(r2, 0.5 * self.resolution, s, out)
        return out

    def whiten(self, r: NDArray[np.float64], sigma: float) -> NDArray[np.float64]:
        """sign(r) sqrt(2 (l(0) - l(r))): half the sum of squares is -logpdf + const."""
        rr = np.asarray(r, dtype=float)
        flat = np.ascontiguousarray(rr.reshape(-1))
        out = np.empty_like(flat)
        _quantized_whiten(flat, 0.5 * self.resolution, float(sigma), out)
        return out.reshape(rr.shape)

    def describe(self) -> dict[str, object]:
        return {"name": self.name, "resolution": self.resolution}


def detect_resolution(values: NDArray[np.float64], tolerance: float = 1e-6) -> float | None:
    """Grid step of quantised readings, or None when they are not on a grid.

    The step is the smallest difference between distinct values; the
    readings are on the grid when at least 99 % of them are within
    ``tolerance`` steps of a multiple of it and there are fewer distinct
    values than half the readings.
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 10:
        return None
    u = np.unique(v)
    if u.size < 2 or u.size > v.size // 2:
        return None
    d = np.diff(u)
    scale = max(float(np.max(np.abs(u))), 1e-300)
    d = d[d > 1e-9 * scale]
    if d.size == 0:
        return None
    q = float(np.min(d))
    k = v / q
    on_grid = np.abs(k - np.round(k)) <= tolerance + 1e-9 * np.abs(k)
    if np.mean(on_grid) < 0.99:
        return None
    return q


#: Window factor of :func:`correlation_time` (Sokal's c): the sum of the
#: autocorrelation stops at the first lag M >= c tau(M). 5 is Sokal's and
#: emcee's choice: long enough for a sum that has converged when the
#: correlation decays exponentially, short enough to keep its noise low.
CORRELATION_WINDOW = 5.0


def correlation_time(r: ArrayLike, window: float = CORRELATION_WINDOW) -> float:
    """Integrated correlation time (samples) of a whitened residual series.

    tau = 1 + 2 sum_(k=1..M) rho(k), with rho(k) = sum_t r_t r_(t+k) /
    sum_t r_t^2 taken *about zero*, not about the mean (a constant misfit is
    one piece of information, not n), and M the first lag with
    M >= ``window`` tau(M) (Sokal's automatic window; the whole series when
    none). The result is clipped to [1, n].

    White residuals give tau ~ 1; AR(1) residuals (1 + phi) / (1 - phi); a
    residual that is one slow curve ~ n. n / tau is the number of
    effectively independent samples, and for parameter sensitivities that
    vary slowly on the scale of tau, the sandwich covariance of a least-
    squares estimate under such correlated errors is tau times the iid one
    (the long-run variance of the score is tau times its variance).

    Parameters
    ----------
    r : array_like, shape (n,)
        Residuals (any unit, whitened by the block's noise model).
    window : float
        Sokal's window factor.

    Returns
    -------
    float
        tau in samples, in [1, n]; 1.0 for fewer than 3 samples or an
        all-zero series.
    """
    x = np.asarray(r, dtype=float).ravel()
    x = x[np.isfinite(x)]
    n = x.size
    if n < 3:
        return 1.0
    size = 1 << int(2 * n - 1).bit_length()
    f = np.fft.rfft(x, size)
    acov = np.fft.irfft(f * np.conj(f), size)[:n]
    if not acov[0] > 0.0:
        return 1.0
    rho = acov / acov[0]
    taus = 2.0 * np.cumsum(rho) - 1.0
    lags = np.arange(n)
    ok = lags >= window * taus
    m = int(np.argmax(ok)) if ok.any() else n - 1
    return float(np.clip(taus[m], 1.0, n))


#: Noise models whose sigma, for its other parameters held, is the root mean
#: square of a block's whitened innovations: the joint profile of one sigma
#: over several blocks is then exact (:func:`pool_sigma`).
POOLABLE: tuple[type[NoiseModel], ...] = (Gaussian, AR1)


def pool_sigma(
    estimates: list[dict[str, NDArray[np.float64]]],
    groups: NDArray[np.int64],
    sizes: NDArray[np.float64],
    powers: NDArray[np.float64],
) -> list[dict[str, NDArray[np.float64]]]:
    """One sigma per group of blocks: the joint profile of a shared noise level.

    For a Gaussian or AR(1) block b with n_b samples, its likelihood raised
    to the power t_b (tempering), the profile over one sigma shared by the
    blocks of a group (their other noise parameters, AR(1) phi, held per
    block) maximises sum_b t_b (-n_b log sigma - S_b / (2 sigma^2)), S_b
    the block's sum of squared innovations = n_b sigma_b^2, so

        sigma^2 = sum_b t_b n_b sigma_b^2 / sum_b t_b n_b.

    Parameters
    ----------
    estimates : list of dict
        Per block, its own profile estimates (``sigma`` (n_sets,) and, for
        AR(1), ``phi``), e.g. from :meth:`NoiseModel.estimate`.
    groups : ndarray of int (n_blocks,)
        Group of each block; -1 keeps the block's own sigma.
    sizes : ndarray (n_blocks,)
        Samples per block.
    powers : ndarray (n_blocks,)
        Tempering power of each block (1: none).

    Returns
    -------
    list of dict
        The estimates with ``sigma`` replaced by its group's (new dicts; the
        other entries shared).
    """
    out = [dict(e) for e in estimates]
    for g in np.unique(groups[groups >= 0]):
        members = np.flatnonzero(groups == g)
        if members.size < 2:
            continue
        w = powers[members] * sizes[members]
        var = sum(
            w[i] * np.asarray(estimates[b]["sigma"], dtype=float) ** 2
            for i, b in enumerate(members)
        ) / float(np.sum(w))
        sigma = np.sqrt(var)
        for b in members:
            out[b]["sigma"] = sigma if np.ndim(estimates[b]["sigma"]) else float(sigma)
    return out


_BY_NAME: dict[str, type[NoiseModel]] = {
    "gaussian": Gaussian, "student-t": StudentT, "ar1": AR1, "quantized": Quantized,
}  # fmt: skip


def noise_model(spec: str | NoiseModel) -> NoiseModel:
    """A noise model from its name (``gaussian``, ``student-t``, ``ar1``) or itself.

    Raises
    ------
    PneumafitInputError
        Unknown name.
    """
    if isinstance(spec, NoiseModel):
        return spec
    try:
        return _BY_NAME[spec]()
    except KeyError:
        raise PneumafitInputError(
            f"noise model: expected one of {', '.join(_BY_NAME)}, found {spec!r}"
        ) from None
