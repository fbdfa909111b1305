"""Discovery's closing statement (refit._statement): what it claims from the
fit and held-out residuals. Kind: the wording rule on constructed residuals
(the figures of a tabulated-valve truth's quick plan, where the statement
said "falls from 444 to 460 Pa ... explained" with the held-out error at
164x the noise, and of the power-law valve truth's sparse plan, seed 1,
where it said "nothing to explain" with a held-out recording at 4x the noise
while the fit's own verdict said "does not reach the noise")."""

from __future__ import annotations

import math
from types import SimpleNamespace

from pneumafit.discovery.refit import HELD_OUT_FACTOR, Model, _statement
from pneumafit.identification.quality import THRESHOLD

NOISE = 407.0


def _model(misfit: float, held: float) -> SimpleNamespace:
    worst = ("step_2.h5 p_N", held)
    return SimpleNamespace(misfit=misfit, worst_held_out=lambda: worst)


def test_the_held_out_threshold_is_the_verdicts() -> None:
    assert HELD_OUT_FACTOR == THRESHOLD == 3.0


def test_held_out_far_above_the_noise_is_never_explained() -> None:
    far = 164.0 * NOISE
    unexplained, text = _statement(_model(444.0, far), _model(460.0, 0.82 * far),
                                   ["supply_pressure_drop"], NOISE, [])  # fmt: skip
    assert unexplained and "partly explained" in text
    assert "goes from 444 to 460" in text and "falls" not in text
    assert "held-out recordings are not: step_2.h5 p_N" in text
    unexplained, text = _statement(_model(444.0, far), _model(444.0, far), [], NOISE, [])
    assert unexplained and "nothing to explain" not in text and "held-out" in text


def test_held_out_above_the_verdicts_threshold_is_not_nothing_to_explain() -> None:
    """4x the noise on a held-out recording (the power-law valve's sparse
    plan): the fit's verdict says "does not reach the noise", and so must
    discovery; just under 3x it is at the noise."""
    unexplained, text = _statement(_model(414.0, 4.0 * NOISE), _model(414.0, 4.0 * NOISE), [],
                                   NOISE, [])  # fmt: skip
    assert unexplained and "nothing to explain" not in text
    assert "4.0x the noise" in text and "step_2.h5 p_N" in text
    under = 0.99 * HELD_OUT_FACTOR * NOISE
    unexplained, text = _statement(_model(414.0, under), _model(414.0, under), [], NOISE, [])
    assert not unexplained and "nothing to explain" in text and "step_2.h5 p_N" in text


def test_a_clean_fit_keeps_its_statements() -> None:
    near = 1.5 * NOISE
    unexplained, text = _statement(_model(400.0, near), _model(400.0, near), [], NOISE, [])
    assert not unexplained and "nothing to explain" in text
    unexplained, text = _statement(_model(900.0, 3 * NOISE), _model(420.0, near), ["x"], NOISE,
                                   [])  # fmt: skip
    assert not unexplained and "falls from 900 to 420" in text and text.endswith("explained.")


def test_the_worst_held_out_channel() -> None:
    held = {"a.h5 p_P": 900.0, "b.h5 p_N": 1200.0, "c.h5 p_P": float("nan")}
    common = dict(effects=(), structure=None, values={}, parameters=None, log_likelihood=0.0,
                  n_parameters=0, n_data=0, rmse={})  # fmt: skip
    assert Model(**common, held_out=held).worst_held_out() == ("b.h5 p_N", 1200.0)  # type: ignore[arg-type]
    where, worst = Model(**common).worst_held_out()  # type: ignore[arg-type]
    assert where == "" and math.isnan(worst)


def test_a_residual_above_the_noise_names_the_worst_held_out_recording() -> None:
    """Where the fit recordings are above the noise the statement was already
    "unexplained" or "partly explained"; it now also gives the held-out
    figure the fit's verdict gives (mixed truth, demo plan, seed 1: 6210 Pa
    on step_4.csv p_N with seal_friction kept)."""
    unexplained, text = _statement(_model(809.0, 6210.0), _model(784.0, 6210.0),
                                   ["seal_friction"], 401.0, [])  # fmt: skip
    assert unexplained and "partly explained" in text
    assert text.endswith("step_2.h5 p_N 6210 Pa RMS (15.5x the noise, less the sensor's zero).")
    unexplained, text = _statement(_model(812.0, 6095.0), _model(812.0, 6095.0), [], 407.0, [])
    assert unexplained and "stays unexplained" in text and "(15.0x the noise" in text
