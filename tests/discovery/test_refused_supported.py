"""An undeclared leak on a rig whose laws are not the model's.

Not an inverse crime: the campaign is recorded by the independent truth
``benchmarks/truths/novel2.toml`` (its own DP5 solver, sensor noise) with
laws the fitted model does not have: an ISO ramp with a rounded foot on the
supply path and a power law on the exhaust path, a constant centre leak,
LuGre friction with additive seal friction, lagging temperature probes, and
an orifice leak to atmosphere (choked flow proportional to the absolute
pressure, where the catalog's ``external_leakage`` is laminar) that the
campaign does not declare. On the demo plan the mismatched laws make most
of the residual rate and the leak's share of all pressure rows is a few
percent; the supported candidates of the other channels (friction
asymmetry, seal friction) are refused.

Two routes find the leak (docs/effects.md): its evidence on the rest and
relaxation rows alone (the ``quiet`` row set), where it is supported; and,
with that row set switched off, the fallback that refits the next
best-ranked candidates when every supported one is refused ("When the
supported candidates are refused").
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

TRUTH = Path(__file__).resolve().parents[2] / "benchmarks" / "truths" / "novel2.toml"


@pytest.fixture(scope="module")
def novel2(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Any]:
    """The campaign (demo plan, seed 7) and its convection fit, without MCMC."""
    from pneumafit.campaign import read_campaign
    from pneumafit.discovery.refit import BaseFit
    from pneumafit.identification import FitOptions, fit_document, identify, write_fit_json
    from pneumafit.virtual_rig import VirtualRig

    tmp = tmp_path_factory.mktemp("novel2")
    folder = tmp / "campaign"
    VirtualRig(seed=7, truth=str(TRUTH)).write(folder, "demo")
    campaign = read_campaign(folder)
    options = FitOptions(mcmc=False)
    fit = identify(campaign, "convection", options=options, seed=1)
    path = tmp / "fit.json"
    write_fit_json(path, fit_document(fit, campaign, seed=1, options=options))
    return campaign, BaseFit.from_document(json.loads(path.read_text()))


def _check_kept(res: Any, steps: str) -> None:
    # a supported candidate of another channel was refitted (and refused) first
    first = res.steps[0]
    assert first.effect != "external_leakage" and not first.accepted, steps
    assert res.selected == ["external_leakage"], steps
    # the held-out pressures: the rule asks 5 %; the loop tests' convention
    # is half (6419 -> 1875 Pa through the fallback when written, 1853 Pa
    # through the quiet rows)
    before, after = res.base.pressure_rmse("validate"), res.final.pressure_rmse("validate")
    assert after < 0.5 * before, (before, after)
    # the criteria count effective samples: the base fit's residuals, 15-35x
    # the noise, are correlated (24139 samples count as 4423 on the demo plan
    # of seed 7, 2026-12-06); > 2 guards that the overcount is applied at all
    assert res.base.overcount > 2.0 and res.final.overcount == res.base.overcount


@pytest.mark.slow
def test_a_leak_is_supported_on_the_rest_rows(novel2: tuple[Any, Any]) -> None:
    from pneumafit.discovery.refit import discover

    campaign, base = novel2
    res = discover(campaign, base, seed=0, rounds=1)
    steps = "; ".join(f"{s.effect}: {s.reason}" for s in res.steps)
    leak = [c for c in res.attributions[0].candidates if c.effect == "external_leakage"]
    # its evidence is read on the quiet rows (score 0.063 there, 0.006 on all
    # pressure rows when written)
    assert leak and leak[0].supported and leak[0].rows == "quiet", steps
    _check_kept(res, steps)


@pytest.mark.slow
def test_an_unsupported_leak_is_refitted_when_the_supported_candidates_fail(
    novel2: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    from pneumafit.discovery import attribution
    from pneumafit.discovery.refit import discover

    # the fallback alone: no quiet row set, as before it was added
    monkeypatch.setattr(attribution, "MIN_QUIET_BLOCKS", 10**9)
    campaign, base = novel2
    res = discover(campaign, base, seed=0, rounds=1)
    steps = "; ".join(f"{s.effect}: {s.reason}" for s in res.steps)
    leak = [c for c in res.attributions[0].candidates if c.effect == "external_leakage"]
    # the premise: the leak is not supported by the residual rates
    assert leak and not leak[0].supported and leak[0].rows == "pressure", steps
    _check_kept(res, steps)
