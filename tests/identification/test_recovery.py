"""Recovery of known parameters from virtual-rig campaigns.

The rig's truth is richer than the fitted model (Sutherland air properties
in the rig and in the fitted convection structure, but DP5 at 0.1 ms, sensor
noise, per-sensor pressure offsets, a 10-um position encoder, slow
temperature sensors, gas warmer than the wall at the start of step tests).
The campaigns are the small protocol of conftest.py (2.5-s tests).

Calibration is tested the way it can be honestly tested: over the first six
seeds, the squared Mahalanobis distances of the heat (xi, beta) and friction
estimates from the truth under the reported covariance, summed over seeds,
must stay below the 99th percentile of their chi-square distribution, and no
seed may exceed the 99.9th. Requiring every 90 % interval to contain the
truth for every seed is not a criterion a calibrated method meets: with six
parameters (two strongly correlated pairs) that happens for one seed about
two times in three, for all of six seeds less than one time in ten.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from pneumafit.identification import FitOptions, identify
from pneumafit.identification.optimise import equilibrated_pinv

CHECKED = ("xi", "beta", "friction_static", "friction_coulomb", "friction_viscous",
           "stribeck_velocity")  # fmt: skip


def test_point_estimates_recover_the_truth(small: tuple) -> None:
    """Joint least squares (no MCMC) on the shared campaign (seed 3).

    Tolerances are the accuracy a rig engineer needs, far above the
    estimates' standard deviations (xi 0.6 %, beta 0.15 %, friction 5e-5 to
    5e-4, conductances 1e-4) and far below the errors of the mistakes they
    guard against (air properties at the wall temperature: xi -70 %; the
    valve from the flow tests alone: xi -50 %).
    """
    _, campaign, truth = small
    result = identify(campaign, "convection", options=FitOptions(mcmc=False), seed=0)
    p = result.parameters
    assert p["xi"].value == pytest.approx(truth["xi"], rel=0.05)
    assert p["beta"].value == pytest.approx(truth["beta"], rel=0.02)
    for name in ("friction_static", "friction_coulomb", "friction_viscous"):
        assert p[name].value == pytest.approx(truth[name], rel=1e-3)
    assert p["stribeck_velocity"].value == pytest.approx(truth["stribeck_velocity"], rel=1e-2)
    for name in ("valve_C_supply", "valve_C_exhaust", "valve_C_leak", "valve_overlap"):
        assert p[name].value == pytest.approx(truth[name], rel=1e-2)
    heat = result.stage("joint").estimate
    assert heat is not None and heat.success
    assert p["xi"].uncertainty == "laplace" and p["xi"].interval_90 is not None


@pytest.mark.parametrize(
    "model", ["constant-lambda", pytest.param("polytropic", marks=pytest.mark.slow)]
)
def test_other_structures_converge_on_the_same_data(small: tuple, model: str) -> None:
    """Both simpler structures end with a finite likelihood and every stage's
    least squares, the joint one included, on a termination test.

    The polytropic law cannot follow the thermal relaxation (k ends on its
    adiabatic bound 1.4). Before the initial states had priors
    (``Problem.initial_priors``) its joint stage used them as knobs and
    crawled: it stopped at the 6 x 500-iteration limit (7.5 of the suite's
    14.7 minutes; the test then capped it at 60 iterations and only checked
    that the fit said so). Uncapped, with the priors, it converged in 52 s
    and 3500 simulations (2026-11-25, load ~4). An unconverged joint stage
    is still reported as such (the next test)."""
    _, campaign, truth = small
    result = identify(campaign, model, options=FitOptions(mcmc=False), seed=0)
    for stage in result.stages:
        assert stage.estimate is not None, stage.name
        assert np.isfinite(stage.estimate.log_likelihood)
        assert stage.estimate.success, (stage.name, stage.estimate.message)
    assert not any(u.startswith("joint") for u in result.quality.unconverged)
    if model == "constant-lambda":
        # the rig's lambda varies 0..~27 W/m^2/K; its heat-weighted mean is ~15
        assert 5.0 < result.parameters["lambda"].value < 30.0
    else:
        assert 1.0 < result.parameters["k"].value <= 1.4
    # friction stays near the truth with the simpler heat laws (within 5 %)
    for name in ("friction_static", "friction_coulomb"):
        assert result.parameters[name].value == pytest.approx(truth[name], rel=0.05)


def test_a_joint_stage_stopped_at_its_limit_is_reported(small: tuple) -> None:
    """A joint stage cut at 3 iterations (``joint_iterations``) cannot reach
    a termination test from the staged estimates; the fit must say so and
    not call itself trustworthy. The switch friction law alone: what is
    tested is the joint stage's limit, not the choice of law (29 s -> 11 s
    without the LuGre fit and the comparison, measured 2026-12-01)."""
    _, campaign, _truth = small
    result = identify(
        campaign,
        "constant-lambda",
        options=FitOptions(mcmc=False, joint_iterations=3, friction="switch"),
        seed=0,
    )
    joint = result.stage("joint").estimate
    assert not joint.success
    assert any(u.startswith("joint") for u in result.quality.unconverged)
    assert not result.quality.trustworthy
    assert any("stopped before converging" in p for p in result.quality.problems())
    # what a notebook user sees first: one line, then the verdict's reasons
    assert "\n" not in repr(result) and "constant-lambda" in repr(result)
    assert "stopped before converging" in result.summary()


#: Seeds of the calibration test: the first six, declared before looking.
CALIBRATION_SEEDS = (1, 2, 3, 4, 5, 6)
#: Parameter blocks whose joint calibration is tested.
BLOCKS = {
    "heat": ("xi", "beta"),
    "friction": ("friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity"),
}


@pytest.mark.slow
def test_intervals_are_calibrated_across_seeds(
    campaign_factory: object, tmp_path_factory: pytest.TempPathFactory
) -> None:
    """Joint fits (Laplace covariance, no MCMC: ~20 s each) of six campaigns.

    Measured (2026-11-21): heat 16.3 against a 99th percentile of 26.2,
    friction 32.5 against 43.0. Before the covariance was equilibrated and
    the rest blocks centred, friction was ~2x overconfident and xi/beta
    biased by 1.5 sd, and this test failed. The Stribeck velocity still
    comes out about one sd low on 7 seeds in 8 (docs/identification.md,
    Limitations): small enough to pass here, and not hidden.

    The intervals are claimed for fits that call themselves trustworthy
    (``FitQuality.trustworthy``), so the check is over those seeds; a fit
    that says it failed is left out, and at most one of the six may (a fit's
    end point depends on the CPU's rounding: this test's outcome moved between
    two hosts on the same code, docs/identification.md, Limitations). On an
    AMD EPYC host (2026-12-03; CI's and the development machine's, the same
    numbers) seed 5's joint stage ended in a poor LuGre optimum, the bristle
    stiffness at its limit (position 15x the noise, friction d2 316); since
    the joint stage solves the switch law too in that case
    (``BRISTLE_LIMIT``), seed 5 keeps the switch law and every seed reaches
    the noise there (1.29-1.34x). A fit that calls itself trustworthy and
    misses its interval still fails the test.
    """
    total = dict.fromkeys(BLOCKS, 0.0)
    per_seed: list[dict[str, float]] = []
    left_out: list[tuple[int, str]] = []
    for seed in CALIBRATION_SEEDS:
        folder = tmp_path_factory.mktemp(f"calibration{seed}")
        campaign, truth = campaign_factory(folder, seed)  # type: ignore[operator]
        result = identify(campaign, "convection", options=FitOptions(mcmc=False), seed=0)
        assert result.quality is not None
        if not result.quality.trustworthy:
            left_out.append((seed, result.quality.verdict()))
            continue
        est = result.stage("joint").estimate
        assert est is not None and est.covariance is not None
        names = est.parameters.free_names
        row = {}
        for block, members in BLOCKS.items():
            idx = [names.index(n) for n in members]
            dz = np.array(
                [
                    est.z[i] - est.parameters[n].to_internal(truth[n])
                    for i, n in zip(idx, members, strict=True)
                ]
            )
            d2 = float(dz @ equilibrated_pinv(est.covariance[np.ix_(idx, idx)]) @ dz)
            row[block] = d2
            total[block] += d2
        per_seed.append(row)
    assert len(left_out) <= 1, left_out
    for block, members in BLOCKS.items():
        k = len(members)
        worst = max(r[block] for r in per_seed)
        assert worst < stats.chi2.ppf(0.999, k), (block, per_seed)
        limit = stats.chi2.ppf(0.99, k * len(per_seed))
        assert total[block] < limit, (block, total[block], limit, per_seed)


@pytest.mark.slow  # slow job (59 s)
def test_mcmc_intervals_agree_with_the_laplace_ones(small: tuple) -> None:
    """Default MCMC on the shared campaign (seed 3, ~45 s): the sampled 90 %
    intervals of heat and friction have the width of the calibrated Laplace
    ones (within a factor 1.5: they include the other groups' uncertainty to
    first order and the burn-in), and every estimate is within 3.3 of its
    standard deviations of the truth. An ensemble stuck on one facet of the
    stick-slip likelihood gave intervals 5-70 times too narrow."""
    _, campaign, truth = small
    result = identify(campaign, "convection", options=FitOptions(), seed=0)
    for name in CHECKED:
        p, lap = result.parameters[name], result.laplace[name]
        assert p.uncertainty == "mcmc" and p.interval_90 is not None
        width = p.interval_90[1] - p.interval_90[0]
        lap_width = lap.interval_90[1] - lap.interval_90[0]
        assert 1 / 1.5 < width / lap_width < 1.5, (name, width, lap_width)
        assert abs(p.value - truth[name]) < 3.29 * width / (2 * 1.645), name
