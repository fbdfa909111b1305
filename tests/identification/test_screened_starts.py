"""Screened starts of the multi-start least squares (``fit_least_squares(candidates=)``).

The frequency of a sinusoid fitted by least squares is the textbook
multimodal problem: from a start more than about half a period's worth of
frequency away the solver ends in a side lobe. The problem is a small
stand-in for :class:`~pneumafit.identification.problem.Problem` (the
interface :class:`~pneumafit.identification.LogLikelihood` needs), so the
real screening and solving code runs. The friction stage uses the same
mechanism for the Stribeck bump (:func:`pneumafit.identification.starts.stribeck_candidates`);
its recovery on an independently written rig is in ``test_mismatched.py``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from test_tempering import LineProblem, N, T  # the stand-in Problem, same folder

from pneumafit.identification import LogLikelihood, Parameter, ParameterSet
from pneumafit.identification.optimise import fit_least_squares

#: True amplitude and frequency (Hz); the start's frequency is far below.
A, F = 1.0, 7.3


class SineProblem(LineProblem):
    """y = a sin(2 pi f t), one Gaussian block (the line's stand-in otherwise)."""

    def predict(self, values: dict[str, np.ndarray], n: int) -> SimpleNamespace:
        self.n_evaluations += n
        model = values["a"][:, None] * np.sin(2.0 * np.pi * values["f"][:, None] * T[None, :])
        return SimpleNamespace(ok=np.ones(n, bool), model=model)


def _likelihood() -> LogLikelihood:
    rng = np.random.default_rng(11)
    y = A * np.sin(2.0 * np.pi * F * T) + rng.normal(0.0, 0.05, N)
    ps = ParameterSet([Parameter("a", 0.5, "", -5.0, 5.0), Parameter("f", 2.0, "Hz", 0.5, 20.0)])
    return LogLikelihood(SineProblem(y), ps)


def test_a_far_start_ends_in_a_side_lobe() -> None:
    """The control: without candidates the solve from f = 2 Hz does not
    reach 7.3 Hz (if it did, the next test would prove nothing)."""
    est = fit_least_squares(_likelihood(), max_nfev=40)
    assert abs(est.parameters["f"].value - F) > 1.0


def test_screened_candidates_reach_the_main_lobe() -> None:
    """Candidates every 1 Hz: a short solve from each, the best one solved
    in full. The main lobe reaches 0.5 Hz either side (the cross-correlation
    of two sines over the 1-s record has its first zero there, its first
    side lobe at 0.72 Hz), so one candidate (7 Hz) lies in it. The estimate
    then lies within 0.025 Hz of the truth: a bound that tells the main lobe
    from a side lobe (>= 0.7 Hz off), wide against the estimate's standard
    error (0.0004 Hz at this noise). The likelihood is above the plain
    solve's."""
    like = _likelihood()
    plain = fit_least_squares(like, max_nfev=40)
    cands = [{"a": 0.5, "f": float(f)} for f in np.arange(2.0, 20.0, 1.0)]
    est = fit_least_squares(like, max_nfev=40, candidates=cands, n_screened=1, screen_nfev=4)
    assert abs(est.parameters["f"].value - F) < 0.025  # side lobes are >= 0.7 Hz off
    assert est.log_likelihood > plain.log_likelihood + 100.0
    # the screened candidate is the last start recorded
    assert len(est.starts) == 2


def test_no_candidates_changes_nothing() -> None:
    """candidates=() (the default) is the plain solve, number for number."""
    a = fit_least_squares(_likelihood(), max_nfev=40)
    b = fit_least_squares(_likelihood(), max_nfev=40, candidates=(), n_screened=3)
    assert a.log_likelihood == b.log_likelihood
    assert np.array_equal(a.z, b.z)
