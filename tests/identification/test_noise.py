"""Noise models: log densities against scipy, estimators on synthetic noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.integrate import quad

from pneumafit.identification import AR1, Gaussian, Quantized, StudentT, detect_resolution
from pneumafit.identification.noise import noise_model

RNG = np.random.default_rng(20261121)


def test_gaussian_logpdf_matches_scipy() -> None:
    r = RNG.normal(0.0, 3.0, size=(3, 50))
    sigma = np.array([2.0, 3.0, 4.5])
    expected = [stats.norm(0.0, s).logpdf(row).sum() for row, s in zip(r, sigma, strict=True)]
    assert Gaussian().logpdf(r, sigma) == pytest.approx(expected, rel=1e-12)


def test_student_t_logpdf_matches_scipy() -> None:
    r = RNG.standard_t(3.0, size=(2, 40)) * 2.0
    sigma = np.array([1.5, 2.5])
    model = StudentT(nu=3.0)
    expected = [stats.t(df=3.0, scale=s).logpdf(row).sum() for row, s in zip(r, sigma, strict=True)]
    assert model.logpdf(r, sigma) == pytest.approx(expected, rel=1e-12)


def test_ar1_logpdf_matches_the_multivariate_normal() -> None:
    n = 30
    r = RNG.normal(size=(2, n))
    sigma = np.array([0.7, 1.3])
    phi = np.array([0.6, -0.3])
    lags = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    expected = []
    for row, s, p in zip(r, sigma, phi, strict=True):
        cov = s**2 / (1.0 - p**2) * p**lags
        expected.append(stats.multivariate_normal(np.zeros(n), cov).logpdf(row))
    assert AR1().logpdf(r, sigma, phi) == pytest.approx(expected, rel=1e-10)


def test_estimators_recover_the_noise_parameters() -> None:
    # tolerances: a few standard errors of each estimator at n = 20000
    n = 20000
    g = RNG.normal(0.0, 2.0, size=(1, n))
    assert Gaussian().estimate(g)["sigma"][0] == pytest.approx(2.0, rel=0.02)
    t = RNG.standard_t(4.0, size=(1, n)) * 3.0
    assert StudentT(nu=4.0).estimate(t)["sigma"][0] == pytest.approx(3.0, rel=0.03)
    e = RNG.normal(0.0, 0.5, size=n)
    x = np.empty(n)
    x[0] = e[0] / np.sqrt(1 - 0.9**2)
    for k in range(1, n):
        x[k] = 0.9 * x[k - 1] + e[k]
    est = AR1().estimate(x[None, :])
    assert est["phi"][0] == pytest.approx(0.9, abs=0.01)
    assert est["sigma"][0] == pytest.approx(0.5, rel=0.02)


@pytest.mark.parametrize("model", [Gaussian(), AR1(), Quantized(1.0)])
def test_whitened_squares_are_minus_the_logpdf_up_to_a_constant(model: object) -> None:
    # with the noise parameters held, 0.5 sum(w^2) + logpdf does not depend on r
    r1 = RNG.normal(0.0, 1.0, size=200)
    r2 = RNG.normal(0.0, 1.0, size=200) * 1.5
    state = model.whitening_state(r1)
    params = dict(state)
    c1 = 0.5 * np.sum(model.whiten(r1, **state) ** 2) + model.logpdf(r1[None], **params)[0]
    c2 = 0.5 * np.sum(model.whiten(r2, **state) ** 2) + model.logpdf(r2[None], **params)[0]
    assert c1 == pytest.approx(c2, rel=1e-9, abs=1e-9)


def test_student_t_irls_weights_give_the_gradient() -> None:
    # at the residuals they come from, IRLS weights reproduce d logpdf / dr
    r = RNG.standard_t(4.0, size=50)
    model = StudentT(nu=4.0)
    state = model.whitening_state(r)
    w = model.whiten(r, **state)
    grad_ls = -w * np.sqrt(state["weights"]) / state["sigma"]
    h = 1e-6
    grad = np.array(
        [
            (model.logpdf((r + h * np.eye(50)[k])[None], state["sigma"])[0]
             - model.logpdf((r - h * np.eye(50)[k])[None], state["sigma"])[0]) / (2 * h)
            for k in range(5)
        ]
    )  # fmt: skip
    assert grad == pytest.approx(grad_ls[:5], rel=1e-5)


def test_quantized_cell_probability_matches_integration() -> None:
    q, sigma = 1.0, 0.3
    r = np.array([[0.0, 0.2, 0.49, 0.7, 2.5]])
    expected = sum(
        np.log(quad(lambda e, x=x: stats.norm(0, sigma).pdf(e), x - q / 2, x + q / 2)[0])
        for x in r[0]
    )
    assert Quantized(q).logpdf(r, np.array([sigma]))[0] == pytest.approx(expected, rel=1e-8)


def test_detect_resolution_finds_an_encoder_grid() -> None:
    # a slow piston read 500 times by a 10-um encoder: repeated counts
    y = np.round(RNG.uniform(0.1, 0.1005, 500) / 1e-5) * 1e-5
    assert detect_resolution(y) == pytest.approx(1e-5, rel=1e-6)
    assert detect_resolution(RNG.uniform(0.1, 0.2, 500)) is None


def test_noise_model_by_name() -> None:
    assert isinstance(noise_model("ar1"), AR1)
    with pytest.raises(ValueError, match="expected one of"):
        noise_model("laplace")


def test_pooled_sigma_maximises_the_joint_tempered_likelihood() -> None:
    """pool_sigma gives the sigma that maximises sum_b t_b logpdf_b(sigma) over
    a group (Gaussian and AR(1) blocks, phi held per block), found here by a
    bounded scalar search; a block in group -1 keeps its own sigma."""
    from scipy.optimize import minimize_scalar

    from pneumafit.identification.noise import pool_sigma

    blocks = [RNG.normal(0.0, 1.0, size=(1, 40)), RNG.normal(0.0, 3.0, size=(1, 90))]
    ar = RNG.normal(0.0, 2.0, size=(1, 60)).cumsum(axis=1) * 0.1
    models = [Gaussian(), Gaussian(), AR1()]
    data = [*blocks, ar]
    powers = np.array([1.0, 0.4, 0.7])
    own = [m.estimate(r) for m, r in zip(models, data, strict=True)]
    pooled = pool_sigma(own, np.array([0, 0, 0]), np.array([40.0, 90.0, 60.0]), powers)

    def minus(log_s: float) -> float:
        s = np.array([np.exp(log_s)])
        total = 0.0
        for m, r, t, e in zip(models, data, powers, own, strict=True):
            extra = {"phi": e["phi"]} if "phi" in e else {}
            total += t * float(m.logpdf(r, s, **extra)[0])
        return -total

    best = minimize_scalar(minus, bounds=(-5.0, 5.0), method="bounded", options={"xatol": 1e-10})
    for e in pooled:
        assert float(e["sigma"][0]) == pytest.approx(np.exp(best.x), rel=1e-6)
    assert pooled[2]["phi"] is own[2]["phi"]
    alone = pool_sigma(own, np.array([0, -1, 0]), np.array([40.0, 90.0, 60.0]), powers)
    assert alone[1]["sigma"] is own[1]["sigma"]
    assert float(alone[0]["sigma"][0]) != pytest.approx(float(pooled[0]["sigma"][0]))
