"""Identification on a truth the fitted model does not share (no inverse crime).

The campaign comes from :mod:`pneumafit.virtual_rig.truth`, a simulator written
independently of the fitted kernel, preset ``mixed``: a tabulated supply path
with an opening-dependent critical ratio, a power-law exhaust path, a Gaussian
leak bump off the centre, LuGre friction with a pressure-dependent seal term,
heat exchanged over the barrel only with a warmer wall, lagging temperature
probes with an offset; solved by LSODA at rtol 1e-8, with sensor noise; the
sparse test plan (one flow test of one valve without a 0-V level, chamber P's
charge/discharge tests only, two short step tests). The convection model
cannot follow it to the noise; what is tested is what must hold anyway:

- the noise the quality check uses is the sensors' (it is estimated from the
  recordings' quiet windows, never from the truth);
- the verdict names every recording whose residual is above 3x the true
  noise, and no recording whose residual is below it (judged against the
  truth's noise, not the estimate);
- what the fit does reach (``benchmarks/bench_recovery.py``, the table in
  docs/identification.md): every fit recording within 3x the noise and the
  Coulomb friction, where the opening shape and knee exponents made the
  difference.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneumafit.campaign import read_campaign
from pneumafit.identification import FitOptions, identify
from pneumafit.virtual_rig import VirtualRig
from pneumafit.virtual_rig.truth import reference_quantities

pytestmark = pytest.mark.slow

#: Seed of the campaign and the fit (not one of the benchmark's seeds 1-3).
SEED = 7


def _record_and_fit(folder: Path, preset: str, seed: int) -> tuple:
    """A sparse-plan campaign of truth ``preset``, fitted as a user would (no MCMC)."""
    rig = VirtualRig(truth=preset, seed=seed)
    rig.write(folder, "sparse")
    campaign = read_campaign(folder)
    result = identify(campaign, "convection", options=FitOptions(mcmc=False), seed=seed)
    truth = reference_quantities(rig.truth, rig.parameters)
    return rig, campaign, result, truth


@pytest.fixture(scope="module")
def mismatched(tmp_path_factory: pytest.TempPathFactory) -> tuple:
    return _record_and_fit(tmp_path_factory.mktemp("mismatched") / "mixed", "mixed", SEED)


def test_the_noise_is_the_sensors(mismatched: tuple) -> None:
    """Every pressure channel's noise estimate within 15 % of the sensor's
    400 Pa: at 15 % the 3x threshold moves by less than 0.5x, the resolution
    the verdict needs (measured on this truth: 0.97-1.07)."""
    rig, _, result, _ = mismatched
    true = rig.sensors.pressure_noise
    pressures = [c for c in result.quality.channels if c.channel.startswith("p_")]
    assert len(pressures) >= 6
    for c in pressures:
        assert c.noise is not None
        assert 0.85 * true <= c.noise <= 1.15 * true, (c.recording, c.channel, c.noise)


def test_the_verdict_names_what_misses_the_true_noise(mismatched: tuple) -> None:
    """Judged with the sensor's true noise: a recording above 3.5x is named,
    one below 2.5x is not (between, the 15 % of the noise estimate decides)."""
    rig, _, result, _ = mismatched
    true = rig.sensors.pressure_noise
    text = "\n".join(result.quality.problems())
    above, below = [], []
    for c in result.quality.channels:
        if not c.channel.startswith("p_"):
            continue
        ratio = c.rms / true
        (above if ratio > 3.5 else below if ratio < 2.5 else []).append(c)
    assert above, "the mismatched truth is not followed to the noise: something must be named"
    assert not result.quality.trustworthy
    for c in above:
        assert f"{c.recording} {c.channel}" in text, (c.recording, c.channel, c.rms / true)
    for c in below:
        assert f"{c.recording} {c.channel}" not in text, (c.recording, c.channel, c.rms / true)


def test_what_the_fit_reaches_on_a_mismatched_truth(mismatched: tuple) -> None:
    """The targets of the robust-identification issue that hold on this truth.

    - every fit recording's pressure within 3x the noise (the issue's
      target; measured on seed 7: charge/discharge 1.04-1.35x, step
      1.35-1.52x; before the valve's knee exponents the catalogue supply
      left the charge/discharge tests at 3.3-3.4x and the steps at 12-17x);
    - Coulomb friction within 25 % of the truth's (the issue's figure;
      measured +0.5 %).
    Not asserted, because they fail (docs/identification.md): the held-out
    recordings (3.2-4.0x the charge/discharge at commands no flow level
    measured, 5.9-15.4x the held-out step), the static friction (-30 %)."""
    rig, _, result, truth = mismatched
    true = rig.sensors.pressure_noise
    fitted = [c for c in result.quality.channels if c.role == "fit" and c.channel.startswith("p_")]
    assert {c.kind for c in fitted} >= {"charge", "discharge", "step"}
    for c in fitted:
        assert c.rms / true <= 3.0, (c.recording, c.channel, c.rms / true)
    f_c = result.parameters["friction_coulomb"].value
    assert f_c == pytest.approx(truth["friction_coulomb"], rel=0.25)
    assert np.isfinite(result.stage("joint").estimate.log_likelihood)


def test_intervals_widen_where_the_recordings_disagree(mismatched: tuple) -> None:
    """The misspecification-robust covariance (FitOptions.robust) on this
    truth, against the same fit without it: the estimates are the same (it
    only changes intervals); every widened parameter's Laplace std is the
    plain one times its recorded factor, and no parameter narrows; the heat
    parameters, informed by the charge/discharge and the step tests that
    the model misses by 1-100x the noise, widen by more than 1.5 (measured
    on seed 7: 3.7). Not asserted: the friction, informed here by the one
    fit step test, widens by 1.004 only; a single recording cannot disagree
    with another, and its profile curvature barely differs from Gauss-Newton
    (docs/identification.md, "Intervals where the recordings disagree").
    Kind: mismatched truth; the bound 1.5 is far above the control's median
    widening 1.01 (test_robust_covariance.py)."""
    _, campaign, result, _ = mismatched
    plain = identify(
        campaign, "convection", options=FitOptions(mcmc=False, robust=False), seed=SEED
    )
    assert plain.widening == {}
    for p in plain.laplace.free:
        if p.group == "initial":
            continue
        q = result.laplace[p.name]
        assert q.value == pytest.approx(p.value, rel=1e-12, abs=1e-300)
        factor = result.widening.get(p.name, 1.0)
        assert q.std == pytest.approx(factor * p.std, rel=1e-6), p.name
    heat = max(result.widening.get(n, 1.0) for n in ("xi", "beta"))
    assert heat > 1.5, heat


# ----------------------------------------------------------------------------
# The friction law chosen by the data (--friction auto)
# ----------------------------------------------------------------------------
#: Seed of the pre-sliding campaign (not one of the benchmark's seeds 1-3).
SEED_LUGRE = 11


@pytest.fixture(scope="module")
def pre_sliding(tmp_path_factory: pytest.TempPathFactory) -> tuple:
    """Truth ``lugre-pressure`` on the sparse plan: LuGre friction whose levels
    grow with the chamber pressures (x (1 + 4.2e-7 Delta)), linear valve ramps
    with a Gaussian centre leak, LSODA, sensor noise. The fitted LuGre law has
    constant levels and the kernel's own valve and leak laws: the structure
    still differs from the truth's."""
    folder = tmp_path_factory.mktemp("pre_sliding") / "lugre"
    rig, _, result, truth = _record_and_fit(folder, "lugre-pressure", SEED_LUGRE)
    return rig, result, truth


def test_auto_friction_chooses_pre_sliding_where_the_rig_has_it(pre_sliding: tuple) -> None:
    """On a pre-sliding rig ``auto`` keeps LuGre, and says so.

    Tolerances are from the benchmark's seeds 1-3 on this truth (docs/
    identification.md), with room for another seed: fit recordings' pressures
    1.7-1.8x the noise (asserted <= 3x, the issue's target), lambda -2 %
    and the Coulomb friction +0 % (asserted within 10 %; the switch model got
    within 2 % too, so this guards the choice, not the law). The static
    friction is not asserted: its levels grow with pressure in the truth
    (+32..+35 % against the 4-bar reference), which no fitted law has.
    """
    rig, result, truth = pre_sliding
    assert result.structure.friction == "lugre"
    friction = next(s for s in result.stages if s.name == "friction")
    assert "friction law lugre" in friction.note
    true = rig.sensors.pressure_noise
    fit_p = [c for c in result.quality.channels if c.role == "fit" and c.channel.startswith("p_")]
    assert fit_p
    for c in fit_p:
        assert c.rms / true <= 3.0, (c.recording, c.channel, c.rms / true)
    lam = result.metrics["lambda_reference"]["full_area_equivalent"]["value"]
    assert lam == pytest.approx(truth["lambda_full_area_equivalent"], rel=0.10)
    f_c = result.parameters["friction_coulomb"].value
    assert f_c == pytest.approx(truth["friction_coulomb"], rel=0.10)


# ----------------------------------------------------------------------------
# The friction stage's starts (screened Stribeck bumps)
# ----------------------------------------------------------------------------
#: Seed of the power-law-valve campaign: benchmark seed 1, where the usual
#: starts alone ended with the static level on the Coulomb level (-35 %).
SEED_BUMP = 1


def _joint_log_likelihood(campaign: object, extra_start: dict[str, float] | None) -> float:
    """The joint stage's log-likelihood of a fit whose friction stage also
    starts at ``extra_start`` (the usual starts when None)."""
    from pneumafit.identification import staged

    plain = staged.friction_starts

    def starts(steps, rig, law="switch"):  # type: ignore[no-untyped-def]
        out = plain(steps, rig, law)
        return [*out, {**out[0], **extra_start}] if extra_start and law == "lugre" else out

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(staged, "friction_starts", starts)
        result = identify(campaign, "convection", options=FitOptions(mcmc=False), seed=SEED_BUMP)
    return float(result.stage("joint").estimate.log_likelihood)


def test_a_start_at_the_truth_does_not_beat_the_usual_starts(tmp_path: Path) -> None:
    """Truth ``power-valve`` (power-law valve paths, Gaussian leak, LuGre with
    a Stribeck bump F_s = 1.6 F_c), sparse plan, LSODA, sensor noise.

    A fit whose friction stage also starts at the truth's own friction
    (levels, Stribeck velocity, bristle stiffness and damping) reaches no
    higher joint log-likelihood than the fit from the usual starts, which
    now include the screened Stribeck bumps (starts.stribeck_candidates):
    an optimisation check on a truth the model does not share, not a
    recovery claim. Measured on this seed: both -7565.7; without the
    screened bumps (``stribeck_candidates`` returning none) the usual starts
    ended with F_s = F_c at -12571.6, and this test failed. The margin,
    20, is above the joint stage's stall gain (14.3 here: a solve stopped
    by that rule may lie that far below its basin's top)."""
    rig = VirtualRig(truth="power-valve", seed=SEED_BUMP)
    rig.write(tmp_path / "pv", "sparse")
    campaign = read_campaign(tmp_path / "pv")
    fr = rig.truth.friction
    truth_start = {
        "friction_static": fr.F_s, "friction_coulomb": fr.F_c, "stribeck_velocity": fr.v_s,
        "friction_viscous": fr.sigma2, "friction_stiffness": fr.sigma0,
        "friction_damping": fr.sigma1,
    }  # fmt: skip
    usual = _joint_log_likelihood(campaign, None)
    from_truth = _joint_log_likelihood(campaign, truth_start)
    assert usual >= from_truth - 20.0, (usual, from_truth)
