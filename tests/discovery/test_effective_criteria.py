"""Discovery's information criteria count effective samples (unit tests, no fit).

A model that does not reach the noise leaves residuals correlated over tau
samples; its iid log-likelihood counts each independent piece of
information about tau times, so a refit's gain looks tau times more
decisive than it is. ``Model.aic`` and ``Model.bic`` divide the
log-likelihood by the base model's overcount sum(n) / sum(n / tau) and take
ln of n / overcount (discovery.refit, module doc). Mechanism tests with
hand-made models; the overcount of a real misfit is checked in the slow
``test_refused_supported.py`` (novel2, 5.5).
"""

from __future__ import annotations

import math

import pytest

from pneumafit.discovery.refit import Model, _accept
from pneumafit.models.structure import ModelStructure

N = 3721  # compared samples of a sparse plan's fit recordings
#: The overcount of the mixed truth's sparse plan (seed 3, 2026-12-06): its
#: 3721 samples count as 404.
OVER = 3721 / 404


def _model(ll: float, k: int, p_rmse: float, effects: tuple[str, ...] = (),
           over: float = OVER) -> Model:  # fmt: skip
    rmse = {"fit": {"p_P": p_rmse, "p_N": p_rmse}, "validate": {"p_P": p_rmse, "p_N": p_rmse}}
    structure = (
        ModelStructure("convection", effects={"seal_friction": 1})
        if effects
        else ModelStructure("convection")
    )
    values = {"seal_friction_coefficient": 5e-6} if effects else {}
    return Model(effects=effects, structure=structure, values=values, parameters=None,
                 log_likelihood=ll, n_parameters=k, n_data=N, rmse=rmse,
                 overcount=over)  # fmt: skip


def test_the_criteria_in_effective_samples() -> None:
    m = _model(-10018.9, 30, 788.0)
    n_eff = N / OVER
    assert m.n_effective == pytest.approx(n_eff)
    assert m.bic == pytest.approx(30 * math.log(n_eff) + 2 * 10018.9 / OVER)
    assert m.aic == pytest.approx(60 + 2 * 10018.9 / OVER)
    # an overcount of 1 (white residuals, or a fit that counts every sample)
    # is the usual criteria
    white = _model(-10018.9, 30, 788.0, over=1.0)
    assert white.bic == pytest.approx(30 * math.log(N) + 2 * 10018.9)


def test_a_gain_the_correlated_residuals_inflate_is_not_enough() -> None:
    """One parameter gaining 20 log-likelihood units: BIC -31.8 when every
    sample counts (ln 3721 = 8.2 against 40), +1.7 in effective samples
    (ln 404 = 6.0 against 40 / 9.2 = 4.3). The held-out error falls by 10 %
    and no channel is worse, so the criterion alone decides."""
    base = _model(-10018.9, 30, 1000.0)
    refit = _model(-10018.9 + 20.0, 31, 900.0, ("seal_friction",))
    ok, reason = _accept(refit, base)
    assert not ok and "the information criterion does not improve" in reason, reason
    iid_base, iid_refit = (
        _model(-10018.9, 30, 1000.0, over=1.0),
        _model(-10018.9 + 20.0, 31, 900.0, ("seal_friction",), over=1.0),
    )
    ok, reason = _accept(iid_refit, iid_base)
    assert ok, reason
    # a gain of 200 (21.7 effective) is decisive either way
    ok, reason = _accept(_model(-10018.9 + 200.0, 31, 900.0, ("seal_friction",)), base)
    assert ok, reason
