"""The least squares re-scores the batches it kept instead of simulating them again.

``optimise._Whitened`` keeps the finite-difference batch of each round's
best point; the reweighting, the next round and the final covariance
evaluate that point again, and take its prediction instead of a new
simulation. Plumbing, exact: a small nonlinear problem of two blocks whose
noise levels the rounds re-estimate (so that several rounds run) is solved
with and without kept batches; every number is the same to the bit and
fewer predictions are made. (On the demo's convection fit without MCMC,
2026-12-06: 90870 -> 86340 simulations, fit.json's values and intervals
the same to the bit.)
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import pneumafit.identification.optimise as optimise
from pneumafit.identification import LogLikelihood, Parameter, ParameterSet
from pneumafit.identification.noise import Gaussian
from pneumafit.identification.problem import Prediction

N = 1500
T = np.linspace(0.0, 3.0, N)


class DecayProblem:
    """y = a exp(-t / b) + c seen by two sensors (noise 0.01 and 0.05) whose
    data disagree slightly, so that each round's noise weights move the
    estimate: what LogLikelihood needs of a Problem, with real Predictions."""

    def __init__(self) -> None:
        rng = np.random.default_rng(11)
        true = 2.0 * np.exp(-T / 0.6) + 0.3
        self.data = [true + 0.01 * rng.standard_normal(N),
                     true * 1.03 + 0.05 * rng.standard_normal(N)]  # fmt: skip
        self.observations = [
            SimpleNamespace(noise=Gaussian(), floor=0.0, weight=None, recording=f"r{j}",
                            channel="p_P", n=N)
            for j in range(2)
        ]  # fmt: skip
        self.tempering = np.ones(2)
        self.lag_names: tuple[str, ...] = ()
        self.n_evaluations = 0

    def predict(self, values: dict[str, np.ndarray], n: int) -> Prediction:
        self.n_evaluations += n
        model = values["a"][:, None] * np.exp(-T[None, :] / values["b"][:, None])
        model = model + values["c"][:, None]
        return Prediction([model, model.copy()], np.zeros((n, 2), np.int64), np.ones(n, bool))

    def residuals(self, prediction: Prediction) -> list[np.ndarray]:
        return [d[None, :] - b for d, b in zip(self.data, prediction.blocks, strict=True)]

    def log_weight(self, index: int) -> float:
        return 0.0


def _solve() -> tuple[optimise.PointEstimate, int]:
    params = ParameterSet([Parameter("a", 1.0, "", 0.0, 10.0), Parameter("b", 2.0, "", 0.05, 10.0),
                           Parameter("c", 0.0, "", -2.0, 2.0)])  # fmt: skip
    problem = DecayProblem()
    est = optimise.fit_least_squares(LogLikelihood(problem, params), max_reweight=6)
    return est, problem.n_evaluations


def test_kept_batches_change_no_number_and_save_predictions(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    kept, n_kept = _solve()
    monkeypatch.setattr(optimise, "KEPT_BATCHES", 0)
    fresh, n_fresh = _solve()
    assert len(kept.starts) == 1 and kept.starts[0]["nfev"] > 1
    np.testing.assert_array_equal(kept.z, fresh.z)
    assert kept.log_likelihood == fresh.log_likelihood
    np.testing.assert_array_equal(kept.covariance, fresh.covariance)
    assert kept.noise == fresh.noise
    # the reweighting and the final evaluation take the kept first set, the
    # next rounds and the covariance the kept batch (4 sets each)
    assert n_kept < n_fresh
