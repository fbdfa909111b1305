"""Finite-difference steps stay on the allowed side of a parameter constraint.

The kernel refuses a parameter set whose static friction is below its
Coulomb level (``parameters.CONSTRAINTS``). At an estimate on that
constraint a forward step of the Coulomb level is such a set: its residuals
were the failed set's constant, and the Jacobian column (FAILED_RESIDUAL -
r) / h called the Coulomb level known to ~1e-10 of itself (mixed truth,
sparse plan, seed 1: a Laplace standard deviation of its log of 1.7e-10,
2026-12-06). The covariances now take that step backwards, as at an upper
bound; the least squares keeps its steps (its optima unchanged).

Plumbing with an exact answer: a model linear in the two levels, y = F_s
g1(t) + F_c g2(t), whose "simulation" fails where F_s < F_c as the kernel's
does. Its Jacobian is exact for either step direction, so the Laplace
covariance at a point on the constraint must be the linear least-squares
one, sigma^2 (A^T A)^-1: the ratio of the two standard deviations (the
profiled noise level cancels) to 1e-6, the finite differences' rounding on
a linear model being ~1e-8.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import pneumafit.identification.optimise as optimise
from pneumafit.identification import LogLikelihood, Parameter, ParameterSet
from pneumafit.identification.noise import Gaussian
from pneumafit.identification.problem import Prediction

N = 400
T = np.linspace(0.0, 2.0, N)
G1 = np.exp(-T / 0.3)
G2 = np.sin(3.0 * T) + 0.2


class Levels:
    """y = F_s g1 + F_c g2 with noise, refused where F_s < F_c (what
    LogLikelihood needs of a Problem)."""

    def __init__(self) -> None:
        rng = np.random.default_rng(5)
        self.data = [30.0 * G1 + 30.0 * G2 + 0.5 * rng.standard_normal(N)]
        self.observations = [
            SimpleNamespace(noise=Gaussian(), floor=0.0, weight=None, recording="r0",
                            channel="p_P", n=N)
        ]  # fmt: skip
        self.tempering = np.ones(1)
        self.lag_names: tuple[str, ...] = ()
        self.n_evaluations = 0

    def predict(self, values: dict[str, np.ndarray], n: int) -> Prediction:
        self.n_evaluations += n
        fs, fc = values["friction_static"], values["friction_coulomb"]
        model = fs[:, None] * G1[None, :] + fc[:, None] * G2[None, :]
        return Prediction([model], np.zeros((n, 1), np.int64), fs >= fc)

    def residuals(self, prediction: Prediction) -> list[np.ndarray]:
        return [self.data[0][None, :] - prediction.blocks[0]]

    def log_weight(self, index: int) -> float:
        return 0.0


def test_a_laplace_covariance_on_the_constraint_is_the_linear_one() -> None:
    params = ParameterSet([
        Parameter("friction_static", 30.0, "N", 0.0, 1e3),
        Parameter("friction_coulomb", 30.0, "N", 0.0, 1e3),
    ])  # fmt: skip
    like = LogLikelihood(Levels(), params)
    z = params.to_internal()
    cov = optimise.laplace_covariance(like, z)
    assert cov is not None
    a = np.stack([G1, G2], axis=1)
    exact = np.linalg.inv(a.T @ a)
    ratio = np.sqrt(cov[1, 1] / cov[0, 0])
    assert ratio == pytest.approx(np.sqrt(exact[1, 1] / exact[0, 0]), rel=1e-6)
    corr = cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])
    assert corr == pytest.approx(exact[0, 1] / np.sqrt(exact[0, 0] * exact[1, 1]), rel=1e-6)


def test_the_step_turns_back_only_where_forwards_breaks_the_constraint() -> None:
    """Off the constraint, and for the larger side on it, the steps stay
    forwards (plumbing: the fits that never reach the constraint keep every
    number), and the least squares' Jacobian (``feasible`` False) keeps the
    forward step on it."""
    params = ParameterSet([
        Parameter("friction_static", 35.0, "N", 0.0, 1e3),
        Parameter("friction_coulomb", 30.0, "N", 0.0, 1e3),
    ])  # fmt: skip
    wh = optimise._Whitened(LogLikelihood(Levels(), params))
    h = np.array([1e-3, 1e-3])
    for static, expected in ((35.0, [1.0, 1.0]), (30.0, [1.0, -1.0])):
        sign = np.ones(2)
        turned = wh._inside_constraints(np.array([static, 30.0]), h, sign)
        assert sign.tolist() == expected
        assert turned == (expected[1] < 0)
    z = np.array([30.0, 30.0])
    wh.set_state(z)
    _, forward = wh.fun_and_jac(z)
    _, feasible = wh.fun_and_jac(z, feasible=True)
    assert np.array_equal(forward[:, 0], feasible[:, 0])
    # the forward step's set is refused: its column is the failed set's,
    # FAILED_RESIDUAL / h = 1e3 / (FD_STEP x 30 N) ~ 3e6 (3.3e6 measured),
    # against the honest column's largest |g2| / sigma ~ 2.5; a factor 1e3
    # between them leaves three decades of margin on either side
    assert np.max(np.abs(forward[:, 1])) > 1e3 * np.max(np.abs(feasible[:, 1]))
