"""Discovery's closing statement (refit._statement): what it claims from the
fit and held-out residuals. Kind: the wording rule on constructed residuals
(the figures of a tabulated-valve truth's quick plan, where the statement
said "falls from 444 to 460 Pa ... explained" with the held-out error at
164x the noise)."""

from __future__ import annotations

from types import SimpleNamespace

from pneumafit.discovery.refit import HELD_OUT_FACTOR, _statement

NOISE = 407.0


def _model(misfit: float, held: float) -> SimpleNamespace:
    return SimpleNamespace(misfit=misfit, pressure_rmse=lambda role: held)


def test_held_out_far_above_the_noise_is_never_explained() -> None:
    far = 164.0 * NOISE
    unexplained, text = _statement(_model(444.0, far), _model(460.0, 0.82 * far),
                                   ["supply_pressure_drop"], NOISE, [])  # fmt: skip
    assert unexplained and "partly explained" in text
    assert "goes from 444 to 460" in text and "falls" not in text
    assert "held-out recordings are not" in text
    unexplained, text = _statement(_model(444.0, far), _model(444.0, far), [], NOISE, [])
    assert unexplained and "nothing to explain" not in text and "held-out" in text


def test_a_clean_fit_keeps_its_statements() -> None:
    near = 1.5 * NOISE  # clean virtual-rig campaigns: 1.4-2.1x held out
    assert near < HELD_OUT_FACTOR * NOISE
    unexplained, text = _statement(_model(400.0, near), _model(400.0, near), [], NOISE, [])
    assert not unexplained and "nothing to explain" in text
    unexplained, text = _statement(_model(900.0, 3 * NOISE), _model(420.0, near), ["x"], NOISE,
                                   [])  # fmt: skip
    assert not unexplained and "falls from 900 to 420" in text and text.endswith("explained.")
