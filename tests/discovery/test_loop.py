"""The discovery loop on virtual-rig campaigns with one hidden effect.

Each campaign (``discovery_protocol``: four fit and three held-out tests,
recorded by the virtual rig with its fine DP5 truth and sensor noise) hides
one effect the base convection model does not declare. The base model is
fitted with the identification (no MCMC), then :func:`discover` must select
that effect and the held-out pressure RMSE must at least halve. Without a
hidden effect nothing is selected; with a valve law no catalog effect
describes (``truth:outside``, a power-law supply path recorded by the
independent truth) the residual must be reported unexplained or partly
explained.

The seal and barrel effects are recorded twice: by the virtual rig's kernel
truth (the loop cases above) and by the *independent* truth
(:mod:`pneumafit.virtual_rig.truth`, the ``fit-laws`` preset with LuGre bristle
friction, plus one effect: ``truth:<effect>`` cases); there the effect must
be selected with its size, and nothing of the kind on the preset alone
(``truth:clean``).
"""

from __future__ import annotations

import math

import pytest
from discovery_helpers import LOOP_EFFECTS, TRUTH_CASES

from pneumafit.discovery import EFFECTS

pytestmark = pytest.mark.slow


def test_every_catalog_effect_has_a_loop_case() -> None:
    assert set(LOOP_EFFECTS) == set(EFFECTS)


# effective_area was an expected failure until the inputs were held between
# samples (2026-11-28): the base fit was poor (LuGre, F_s = F_c = 29 N,
# position RMSE 2.5 mm) and the refit ended with a worse BIC. Held, it is
# kept, held-out p_P / p_N 7847 / 9942 -> 3408 / 5120 Pa (docs/effects.md).
@pytest.mark.parametrize("effect", sorted(LOOP_EFFECTS))
def test_hidden_effect_is_found_and_halves_the_validation_error(
    discovery_cases: object, effect: str
) -> None:
    case = discovery_cases(effect)  # type: ignore[operator]
    res = case.result
    ranked = [c.effect for c in res.attributions[0].candidates]
    assert res.selected and res.selected[0] == effect, (
        f"selected {res.selected}, ranking {ranked}; steps "
        + "; ".join(f"{s.effect}: {s.reason}" for s in res.steps)
    )
    before = res.base.pressure_rmse("validate")
    after = res.final.pressure_rmse("validate")
    assert math.isfinite(before) and math.isfinite(after)
    assert after <= 0.5 * before, f"validate pressure RMSE {before:.0f} -> {after:.0f} Pa"
    for ch in ("p_P", "p_N"):
        assert res.final.rmse["validate"][ch] < res.base.rmse["validate"][ch]
    # the refit's parameter is where the rig put it, within a factor of 3
    # (a signed effect: its departure from the neutral value)
    principal = EFFECTS[effect].parameter_names()[0]
    truth = case.truth["parameters"][principal]
    assert _within_factor(effect, res.final.values[principal], truth, 3.0)


def _within_factor(effect: str, value: float, truth: float, factor: float) -> bool:
    par = EFFECTS[effect].parameter(EFFECTS[effect].parameter_names()[0])
    neutral = par.neutral if par.neutral is not None else 0.0
    ratio = (value - neutral) / (truth - neutral)
    return 1.0 / factor < ratio < factor


#: Independent-truth cases: effect expected, its true size (the truth's own
#: parameters: additive c_p, asymmetry a, bore 32.8 mm for 32 declared).
TRUTH_EXPECTED: dict[str, tuple[str, float]] = {
    "truth:seal_friction": ("seal_friction", 1.5e-5),
    "truth:friction_asymmetry": ("friction_asymmetry", 0.2),
    "truth:effective_area": ("effective_area", (0.0328 / 0.032) ** 2),
}


def test_truth_cases_are_defined() -> None:
    assert set(TRUTH_EXPECTED) | {"truth:clean", "truth:outside"} == set(TRUTH_CASES)


@pytest.mark.parametrize("name", sorted(TRUTH_EXPECTED))
def test_effect_recorded_by_the_independent_truth_is_proposed(
    discovery_cases: object, name: str
) -> None:
    """Recorded by the independent truth (LuGre bristles, its own seal,
    asymmetry and bore code): attribution ranks the effect first, supported,
    with the truth's size within 20 % (measured 2026-11-25: seal 1.496e-5
    for 1.5e-5 N/Pa, a = 0.198 for 0.2, k_A - 1 = 0.0475 for 0.0506)."""
    effect, truth = TRUTH_EXPECTED[name]
    res = discovery_cases(name).result  # type: ignore[operator]
    best = res.attributions[0].candidates[0]
    assert best.effect == effect and best.supported, [
        c.effect for c in res.attributions[0].candidates
    ]
    par = EFFECTS[effect].parameter(EFFECTS[effect].parameter_names()[0])
    neutral = par.neutral if par.neutral is not None else 0.0
    assert best.suggested[par.name] - neutral == pytest.approx(truth - neutral, rel=0.2)


# The asymmetry and the area on the independent truth were expected failures
# until the inputs were held between samples (2026-11-28): the channel rule
# (discovery/refit.py) rejected refits that were large gains, because the base
# fit's valve, bent by the half-sample timing error of interpolated commands,
# fitted the flow tests better than the true one. Held, both are kept
# (held-out p_P / p_N: asymmetry 4405 / 4185 -> 610 / 552 Pa, area 5464 /
# 8209 -> 646 / 572 Pa; docs/effects.md).
@pytest.mark.parametrize(
    "name", ["truth:seal_friction", "truth:friction_asymmetry", "truth:effective_area"]
)
def test_effect_recorded_by_the_independent_truth_is_kept(
    discovery_cases: object, name: str
) -> None:
    """... and keeps it, with its fitted size within 20 % of the truth's and
    a lower held-out error (seal friction, measured: 1.488e-5 N/Pa, held-out
    p_N 1719 -> 788 Pa)."""
    effect, truth = TRUTH_EXPECTED[name]
    res = discovery_cases(name).result  # type: ignore[operator]
    assert effect in res.selected, f"selected {res.selected}; steps " + "; ".join(
        f"{s.effect}: {s.reason}" for s in res.steps
    )
    assert _within_factor(effect, res.final.values[EFFECTS[effect].parameter_names()[0]], truth,
                          1.2)  # fmt: skip
    assert res.final.pressure_rmse("validate") < res.base.pressure_rmse("validate")


def test_independent_truth_without_effects_keeps_no_seal_effect(discovery_cases: object) -> None:
    """The preset alone (measured: nothing selected, "nothing to explain";
    the asymmetry ranked first at a = -0.009, not supported)."""
    res = discovery_cases("truth:clean").result  # type: ignore[operator]
    seal = {"seal_friction", "friction_asymmetry", "effective_area"}
    assert not seal & set(res.selected), res.statement


def test_clean_campaign_selects_nothing(discovery_cases: object) -> None:
    res = discovery_cases(None).result  # type: ignore[operator]
    assert res.selected == []
    assert not res.unexplained, res.statement
    assert res.final is res.base


def test_the_statement_judges_the_held_out_recordings_as_the_fit_does(
    discovery_cases: object,
) -> None:
    """The held-out figures discovery's statement reads (refit.judged_held_out)
    are the fit's own verdict's (fit.json ``quality.recordings``: the held-out
    pressures started from the chambers' pressures, less one zero per sensor),
    computed by another path; the tolerance is rounding (both are the same
    replay's residuals, summed in another order). Before 2026-12-05 the
    statement read them from the sensors' readings with their offsets kept."""
    import json

    case = discovery_cases(None)  # type: ignore[operator]
    fit = json.loads(case.fit_path.read_text())  # type: ignore[attr-defined]
    verdict = {
        f"{r['recording']} {r['channel']}": r["rms"]
        for r in fit["quality"]["recordings"]
        if r["role"] == "validate" and r["channel"] in ("p_P", "p_N")
    }
    judged = case.result.base.held_out  # type: ignore[attr-defined]
    assert verdict and set(judged) == set(verdict)
    for key, rms in verdict.items():
        assert judged[key] == pytest.approx(rms, rel=1e-9), key


def test_effect_outside_the_catalog_is_not_claimed(discovery_cases: object) -> None:
    """A power-law supply path (no catalog effect describes a valve law,
    recorded by the independent truth): whatever is kept had to pass BIC and
    the held-out error, and the residual is reported unexplained or partly
    explained, never as explained by a catalog effect."""
    res = discovery_cases("truth:outside").result  # type: ignore[operator]
    assert res.unexplained, res.statement
    assert ("partly explained" in res.statement) == bool(res.selected)
    assert "unexplained" in res.statement or "partly explained" in res.statement
    for step in res.steps:
        if step.accepted:
            assert step.model is not None
            assert step.model.bic < res.base.bic
