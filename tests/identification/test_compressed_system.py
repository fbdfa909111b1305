"""The least-squares system handed to scipy in n + 1 rows (``optimise._compressed``).

Unit tests, no simulation: the compressed system has the full one's cost,
gradient and Gauss-Newton matrix on both of its paths (the equilibrated
Cholesky factor of the Gram, the QR factor where that is ill-conditioned),
and scipy's trust-region reflective solver, given the compressed residual
and Jacobian of a nonlinear problem with bounds, takes the full system's
steps to the same end point.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from pneumafit.identification.optimise import COMPRESS_COND, _compressed


def _check_same(f: np.ndarray, jac: np.ndarray, ft: np.ndarray, jt: np.ndarray) -> None:
    n = jac.shape[1]
    assert ft.shape == (n + 1,) and jt.shape == (n + 1, n)
    # rounding of a product of 10^4-row matrices: 1e-12 relative
    assert ft @ ft == pytest.approx(f @ f, rel=1e-12)
    np.testing.assert_allclose(jt.T @ ft, jac.T @ f, rtol=1e-9, atol=1e-9 * np.abs(jac.T @ f).max())
    gram = jac.T @ jac
    np.testing.assert_allclose(jt.T @ jt, gram, rtol=1e-9, atol=1e-12 * np.abs(gram).max())
    # the column norms, x_scale="jac"
    np.testing.assert_allclose(np.linalg.norm(jt, axis=0), np.linalg.norm(jac, axis=0), rtol=1e-10)


def test_the_cholesky_path_keeps_cost_gradient_and_gauss_newton_matrix() -> None:
    rng = np.random.default_rng(1)
    # columns of very different sizes (pascals, logarithms), as the fits' are
    jac = rng.standard_normal((10000, 12)) * np.logspace(-6, 6, 12)
    f = rng.standard_normal(10000)
    ft, jt = _compressed(f, jac)
    _check_same(f, jac, ft, jt)


def test_an_ill_conditioned_system_takes_the_qr_path() -> None:
    rng = np.random.default_rng(2)
    jac = rng.standard_normal((5000, 6))
    # two columns equal to 1e-9: the Gram's factor would keep nothing of
    # their difference; the QR factor keeps it
    jac[:, 5] = jac[:, 4] + 1e-9 * rng.standard_normal(5000)
    f = rng.standard_normal(5000)
    a = np.column_stack([jac, f])
    s = np.linalg.norm(a, axis=0)
    assert np.linalg.cond(a / s) ** 1 > COMPRESS_COND  # the guard's case
    ft, jt = _compressed(f, jac)
    r = np.linalg.qr(a, mode="r")
    np.testing.assert_array_equal(jt, r[:, :6])
    _check_same(f, jac, ft, jt)


def test_short_and_non_finite_systems() -> None:
    jac, f = np.ones((8, 4)), np.ones(8)
    ft, jt = _compressed(f, jac)
    assert ft is f and jt is jac  # m <= 2 (n + 1): as it is
    big = np.ones((100, 3))
    big[5, 1] = np.nan
    ft, jt = _compressed(np.ones(100), big)
    assert ft.shape == (4,) and not np.isfinite(ft).any() and not np.isfinite(jt).any()


def test_trf_reaches_the_same_end_point_on_the_compressed_system() -> None:
    """A three-parameter exponential relaxation sampled at 4000 points with
    noise, bounds and x_scale="jac", solved by scipy's trf on the full
    system and on the compressed one (the same steps in exact arithmetic:
    the end points agree to rounding, far inside the solve's xtol)."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 4.0, 4000)
    y = 3.0 * np.exp(-t / 0.7) + 0.5 + 0.01 * rng.standard_normal(t.size)

    def fun(x: np.ndarray) -> np.ndarray:
        return x[0] * np.exp(-t / x[1]) + x[2] - y

    def jac(x: np.ndarray) -> np.ndarray:
        e = np.exp(-t / x[1])
        return np.column_stack([e, x[0] * e * t / x[1] ** 2, np.ones_like(t)])

    x0, bounds = np.array([1.0, 2.0, 0.0]), ([0.0, 0.05, -1.0], [10.0, 10.0, 1.0])
    full = least_squares(fun, x0, jac=jac, bounds=bounds, method="trf", x_scale="jac",
                         ftol=1e-12, xtol=1e-12, gtol=1e-12)  # fmt: skip
    comp = least_squares(
        lambda x: _compressed(fun(x), jac(x))[0], x0, jac=lambda x: _compressed(fun(x), jac(x))[1],
        bounds=bounds, method="trf", x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12,
    )  # fmt: skip
    assert full.success and comp.success
    # the same accepted steps (one Jacobian each); the trial steps after the
    # last differ only in the cost's rounding against ftol 1e-12
    assert comp.njev == full.njev
    np.testing.assert_allclose(comp.x, full.x, rtol=1e-9)
    assert 2 * comp.cost == pytest.approx(2 * full.cost, rel=1e-10)
