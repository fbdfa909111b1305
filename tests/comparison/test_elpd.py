"""WAIC and PSIS-LOO, vectorised (``comparison.elpd``), against ArviZ's estimators.

ArviZ (``az.waic``, ``az.loo``) is an independent implementation of the same
estimators, fitting one observation at a time; the vectorised one must give
the same numbers to rounding. Tolerances: 1e-9 relative on sums of ~10^3
terms and 1e-12 absolute pointwise, a few hundred ulps of the values
(different summation order in logsumexp and means, nothing more).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pneumafit.comparison.elpd import psis_loo, waic

az = pytest.importorskip("arviz")


def _matrix(draws: int, points: int, heavy: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ll = rng.normal(size=(draws, 1)) * 0.5 + rng.normal(size=(draws, points)) * 0.3 - 1.0
    # influential points: squared Cauchy log-likelihood drops in a few draws give
    # heavy-tailed ratios (Pareto k above 0.7) and WAIC variances above 0.4
    ll[:, :heavy] -= rng.standard_cauchy(size=(draws, heavy)) ** 2
    return ll


@pytest.mark.parametrize(
    ("draws", "points", "heavy"), [(500, 800, 0), (200, 600, 40), (64, 300, 60)]
)
def test_the_same_numbers_as_arviz(draws: int, points: int, heavy: int) -> None:
    ll = _matrix(draws, points, heavy, seed=draws)
    data = az.from_dict(posterior={"a": np.zeros((1, draws))}, log_likelihood={"y": ll[None, :, :]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref_w = az.waic(data, pointwise=True)
        ref_l = az.loo(data, pointwise=True, reff=1.0)
    w, lo = waic(ll), psis_loo(ll)
    assert w.elpd == pytest.approx(float(ref_w.elpd_waic), rel=1e-9)
    assert w.p == pytest.approx(float(ref_w.p_waic), rel=1e-9)
    assert w.se == pytest.approx(float(ref_w.se), rel=1e-9)
    np.testing.assert_allclose(w.pointwise, np.asarray(ref_w.waic_i).ravel(), rtol=0, atol=1e-12)
    assert lo.elpd == pytest.approx(float(ref_l.elpd_loo), rel=1e-9)
    assert lo.p == pytest.approx(float(ref_l.p_loo), rel=1e-9)
    assert lo.se == pytest.approx(float(ref_l.se), rel=1e-9)
    np.testing.assert_allclose(lo.pointwise, np.asarray(ref_l.loo_i).ravel(), rtol=0, atol=1e-12)
    k_ref = np.asarray(ref_l.pareto_k).ravel()
    assert lo.pareto_k is not None
    np.testing.assert_array_equal(np.isinf(lo.pareto_k), np.isinf(k_ref))
    fin = np.isfinite(k_ref)
    np.testing.assert_allclose(lo.pareto_k[fin], k_ref[fin], rtol=0, atol=1e-12)
    # the heavy cases have unreliable points, counted like ArviZ's warnings
    assert (lo.n_unreliable > 0) == (heavy > 0)
    assert lo.n_unreliable == int(np.sum(k_ref > ref_l.good_k))
    assert w.n_unreliable == int(np.sum(np.var(ll, axis=0) > 0.4))


def test_a_pareto_tail_gives_its_shape() -> None:
    """Ratios 1 + X, X drawn from a generalised Pareto of shape 0.5 (4000
    draws, one row per replicate; exceedances over a high threshold keep the
    shape): the fitted k is near 0.5. The tail
    holds 190 points, so one fit's k has a standard deviation of ~0.1 and
    the mean of 200 rows a standard error of 0.1 / sqrt(200) = 0.007; the
    bound 0.03 is about 4 of them (measured: mean 0.488, sd 0.103; the weak
    prior pulls towards 0.5, which adds no bias at this truth)."""
    from pneumafit.comparison.elpd import psis_log_weights

    rng = np.random.default_rng(5)
    k_true = 0.5
    u = rng.uniform(size=(200, 4000))
    ratios = (u ** (-k_true) - 1.0) / k_true  # GPD(k, sigma=1) quantile transform
    lw, k = psis_log_weights(np.log1p(ratios))
    assert abs(float(np.mean(k)) - k_true) < 0.03
    np.testing.assert_allclose(np.exp(lw).sum(axis=1), 1.0, rtol=1e-12)
    assert np.all(lw <= 0.0)
