"""Whiteness statistics: Ljung-Box, autocorrelation bands, cross-correlation
bands (Ljung, System Identification, sec. 16.6; MATLAB resid)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from discovery_helpers import ar1, white_noise
from scipy import stats

from pneumafit.discovery import (
    autocorrelation,
    cross_correlation,
    cross_correlation_band,
    ljung_box,
    whiteness_band,
)

N_SEEDS = 400


def test_ljung_box_by_hand() -> None:
    # e = 1, -1, 1, -1 (mean 0): c0 = 4/4 = 1, r1 = (-1 - 1 - 1)/4 = -3/4,
    # r2 = (1 + 1)/4 = 1/2; Q = n (n + 2) [r1^2/(n - 1) + r2^2/(n - 2)]
    # = 24 (9/16/3 + 1/4/2) = 24 * 5/16 = 7.5; chi2 with 2 dof: p = exp(-Q/2).
    e = [1.0, -1.0, 1.0, -1.0]
    np.testing.assert_allclose(autocorrelation(e, 2), [1.0, -0.75, 0.5], rtol=0, atol=1e-15)
    lb = ljung_box(e, 2)
    assert lb.statistic == pytest.approx(7.5, rel=1e-14)
    assert lb.p_value == pytest.approx(math.exp(-3.75), rel=1e-12)
    assert (lb.lags, lb.n) == (2, 4)


def test_ljung_box_by_hand_with_a_mean() -> None:
    # e = 2, 4, 3, 7: mean 4, deviations -2, 0, -1, 3, c0 = 14/4;
    # r1 = (0 + 0 - 3)/14 = -3/14, r2 = (2 + 0)/14 = 1/7, r3 = -6/14 = -3/7.
    # Q(3) = 4 * 6 * (9/196/3 + 1/49/2 + 9/49/1)
    e = [2.0, 4.0, 3.0, 7.0]
    np.testing.assert_allclose(autocorrelation(e, 3), [1, -3 / 14, 1 / 7, -3 / 7], atol=1e-15)
    q = 24.0 * (9.0 / 196.0 / 3.0 + 1.0 / 49.0 / 2.0 + 9.0 / 49.0)
    lb = ljung_box(e, 3)
    assert lb.statistic == pytest.approx(q, rel=1e-14)
    assert lb.p_value == pytest.approx(stats.chi2.sf(q, 3), rel=1e-12)


def test_ljung_box_is_calibrated_on_white_noise() -> None:
    # 400 seeded white series, n = 1000, M = 25. Under whiteness Q is close to
    # chi2(25) (Ljung and Box 1978 chose the n(n+2)/(n-k) weights for this),
    # so the p-values are uniform: a KS test must not reject at 0.001, and the
    # rejections at 5 % follow Binomial(400, 0.05) (mean 20, sd 4.4): a
    # two-sided binomial test must not reject at 0.001 either. Seeds are
    # fixed, so this passes or fails deterministically.
    p = np.array([ljung_box(white_noise(seed, 1000), 25).p_value for seed in range(N_SEEDS)])
    assert stats.kstest(p, "uniform").pvalue > 1e-3
    rejected = int(np.sum(p < 0.05))
    assert stats.binomtest(rejected, N_SEEDS, 0.05).pvalue > 1e-3, rejected
    # the standardised statistic is ~N(0, 1) on average
    z = [ljung_box(white_noise(seed, 1000), 25).violation for seed in range(50)]
    assert abs(np.mean(z)) < 4.0 / math.sqrt(50)


def test_ljung_box_rejects_ar1() -> None:
    # AR(1) with phi = 0.3: r1 ~ 0.3, so Q ~ n phi^2 / (1 - phi^2) ~ 100 for
    # n = 1000 against a 99 % critical value of 44 for 25 dof.
    for seed in range(20):
        lb = ljung_box(ar1(seed, 1000, 0.3), 25)
        assert lb.p_value < 1e-6
        assert lb.violation > 5.0


def test_acf_band_as_resid() -> None:
    # resid's 99 % region: +-2.576 / sqrt(N); 95 %: +-1.96 / sqrt(N)
    assert whiteness_band(1000, 0.01) == pytest.approx(2.5758293035489 / math.sqrt(1000))
    assert whiteness_band(400, 0.05) == pytest.approx(1.959963984540054 / 20.0)
    with pytest.raises(ValueError, match="alpha"):
        whiteness_band(100, 1.5)


def test_acf_band_covers_white_noise_at_its_level() -> None:
    # 400 series x 25 lags = 10000 autocorrelations, nearly independent under
    # whiteness, each outside the 99 % band with probability ~0.01 (slightly
    # less: var r_k = (n - k) / (n (n + 2)) < 1/n). The count is checked
    # against Binomial(10000, 0.01) (mean 100, sd 10) at 0.001.
    band = whiteness_band(1000, 0.01)
    outside = 0
    for seed in range(N_SEEDS):
        r = autocorrelation(white_noise(seed, 1000), 25)
        outside += int(np.sum(np.abs(r[1:]) > band))
    assert stats.binomtest(outside, N_SEEDS * 25, 0.01).pvalue > 1e-3, outside


def test_cross_correlation_sign_convention() -> None:
    # residual e(t) = u(t - 3): the input 3 samples earlier drives it, so the
    # peak (value ~1) sits at lag +3, "residual after input", as in resid.
    w = white_noise(1, 2003)
    u = w[3:]  # u(t) = w(t + 3)
    e = w[:-3]  # e(t) = w(t) = u(t - 3)
    r = cross_correlation(e, u, 10)
    assert np.argmax(np.abs(r)) == 10 + 3
    assert r[10 + 3] == pytest.approx(1.0, abs=0.01)
    # and the other way round: the input after the residual, lag -3
    r = cross_correlation(u, e, 10)
    assert np.argmax(np.abs(r)) == 10 - 3


def test_cross_correlation_band_follows_bartlett() -> None:
    # e and u independent AR(1) with phi 0.8 and 0.9: sqrt(n) r_eu(tau) has
    # variance P = (1 + phi_e phi_u) / (1 - phi_e phi_u) = 6.14 (Bartlett).
    # The band from the sample autocorrelations must estimate that (the
    # estimates of r(k) carry ~1/sqrt(n) errors each, 25 of them: 15 %), and
    # it must cover r_eu(0) at about its level: over 400 seeds, at most 12
    # outside at alpha = 0.01 (Binomial(400, 0.01) exceeds 12 with
    # probability 5e-4), while the white-noise band misses ~30 % of them.
    n, m, alpha = 2000, 25, 0.01
    p_true = (1 + 0.72) / (1 - 0.72)
    outside = naive = 0
    ratios = []
    for seed in range(N_SEEDS):
        e = ar1(2 * seed, n, 0.8)
        u = ar1(2 * seed + 1, n, 0.9)
        band = cross_correlation_band(autocorrelation(e, m), autocorrelation(u, m), n, alpha)
        ratios.append((band / whiteness_band(n, alpha)) ** 2)
        r0 = cross_correlation(e, u, m)[m]
        outside += abs(r0) > band
        naive += abs(r0) > whiteness_band(n, alpha)
    assert np.median(ratios) == pytest.approx(p_true, rel=0.15)
    assert outside <= 12
    assert naive / N_SEEDS > 0.2


def test_cross_correlation_band_is_white_band_for_white_residual() -> None:
    # P = sum r_e(k) r_u(k) = 1 for a white residual whatever the input
    # (floored at 1, so a finite sum below 1 never narrows the band)
    r_e = np.array([1.0, 0.0, 0.0])
    r_u = np.array([1.0, 0.99, 0.98])
    assert cross_correlation_band(r_e, r_u, 500) == whiteness_band(500)
    assert cross_correlation_band([1.0, -0.5], [1.0, 0.9], 500) == whiteness_band(500)


def test_constant_series_gives_nan_not_an_error() -> None:
    assert np.all(np.isnan(autocorrelation(np.ones(10), 3)))
    assert math.isnan(ljung_box(np.ones(10), 3).p_value)
    assert np.all(np.isnan(cross_correlation(np.arange(10.0), np.ones(10), 2)))


@pytest.mark.parametrize(
    ("series", "lag", "match"),
    [([1.0], 1, "at least 2"), ([1.0, np.nan, 2.0], 1, "finite"), ([1.0, 2.0, 3.0], 3, "max_lag")],
)
def test_bad_input(series: list[float], lag: int, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        autocorrelation(series, lag)
