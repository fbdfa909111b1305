"""Problems and likelihoods: -inf on failure, batching, grids, nuisances."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pneumafit.campaign import Campaign, Recording
from pneumafit.identification import (
    LogLikelihood,
    LogPosterior,
    ParameterSet,
    Problem,
    first_order_lag,
    fit_structure,
)
from pneumafit.identification.problem import INITIAL_PREFIX
from pneumafit.simulation import Experiment, Simulator
from pneumafit.virtual_rig import held_input_lag

STRUCTURE = fit_structure("convection")


def _setup(
    small: tuple[object, Campaign, dict[str, float]], kinds: tuple[str, ...], **kw: object
) -> tuple[Problem, ParameterSet, dict[str, float]]:
    _, campaign, truth = small
    recs = [r for r in campaign.by_role("fit") if r.kind in kinds]
    prob = Problem(recs, STRUCTURE, truth, **kw)
    ps = ParameterSet.for_model(STRUCTURE, campaign.rig.as_parameters())
    ps = ps.with_values({k: v for k, v in truth.items() if k in ps.names})
    return prob, ps.only_free(("xi", "beta", "friction_static", "friction_coulomb")), truth


def test_failed_simulations_give_minus_infinity_never_an_exception(small: tuple) -> None:
    prob, ps, _ = _setup(small, ("charge", "step"))
    like = LogLikelihood(prob, ps)
    z = np.tile(ps.to_internal(), (4, 1))
    # static friction below Coulomb: the kernel refuses the set (status 3)
    z[1, ps.free_names.index("friction_static")] = np.log(10.0)
    # outside the bounds and non-finite: never simulated
    z[2, 0] = np.log(1e3)
    z[3, 1] = np.nan
    ll = like(z)
    assert np.isfinite(ll[0])
    assert np.all(ll[1:] == -np.inf)
    ev = like.evaluate(z)
    assert ev.ok.tolist() == [True, False, False, False]
    post = LogPosterior(like)
    assert post(z)[1:].tolist() == [-np.inf] * 3


def test_batch_equals_one_by_one(small: tuple) -> None:
    prob, ps, _ = _setup(small, ("charge", "discharge", "step"))
    like = LogLikelihood(prob, ps)
    rng = np.random.default_rng(0)
    z = ps.to_internal() + rng.normal(0.0, 0.01, size=(5, ps.n_free))
    batch = like(z)
    single = np.array([like(row)[0] for row in z])
    # the simulations are bitwise equal; BLAS sums may round differently by batch
    assert batch == pytest.approx(single, rel=1e-12)
    assert like.n_evaluations == 10


def test_thinned_grid_keeps_the_inputs_exactly(small: tuple) -> None:
    """The integration grid keeps both samples around every command jump, so
    the simulator's piecewise-linear inputs are those of the full recording.
    With the solver's defect correction at these parameters, the thinned
    problem predicts a fine reference (DP5 at 0.25 ms on the full grid)
    within 5 Pa, about 1 % of the sensor noise (measured: 2 Pa, set at the
    valve opening, where the two grids resolve the 10-V jump differently);
    without it RK3 at 2.5-4 ms is off by ~40 Pa while the valve is open."""
    _, campaign, truth = small
    rec = campaign.recording("charge_P.h5")
    prob = Problem([rec], STRUCTURE, truth, channels=("p_P",), initial_nuisance=False,
                   offsets=())  # fmt: skip
    exp = prob.experiments[0]
    full = Experiment.from_recording(rec)
    for col in (0, 1):  # u_P, u_N
        resampled = np.interp(full.time, exp.time, exp.inputs()[:, col])
        assert np.array_equal(resampled, full.inputs()[:, col])
    assert exp.time.size < full.time.size / 2
    reference = Simulator(STRUCTURE, step=2.5e-4, method="dp5", channels=["p_P"]).simulate(
        truth, Experiment(full.time, "charge", chamber="P", u_P=full.u_P, initial=exp.initial)
    )
    obs = prob.observations[0]
    dense = obs.weight == 1.0 if obs.weight is not None else np.ones(obs.n, bool)
    ref = np.interp(obs.time, full.time, reference["p_P"])[dense]
    coarse = prob.predict({}, 1).blocks[0][0][dense]
    prob.correct_solver(truth)
    corrected = prob.predict({}, 1).blocks[0][0][dense]
    assert np.max(np.abs(corrected - ref)) < 5.0
    assert np.max(np.abs(coarse - ref)) > 10.0  # the correction matters


def test_rest_blocks_and_flow_levels_are_averaged(small: tuple) -> None:
    _, campaign, truth = small
    prob = Problem(campaign.by_role("fit"), STRUCTURE, truth)
    flow = next(o for o in prob.observations if o.kind == "flow")
    assert flow.n == 27  # 9 commands x 3 pressures, one mean per settled level
    blocked = next(o for o in prob.observations if o.kind == "charge")
    assert blocked.weight is not None and blocked.weight.max() > 1.0
    # a noise model sees weighted residuals: one sigma per block
    ev = LogLikelihood(prob, ParameterSet.for_model(STRUCTURE).only_free(())).evaluate(
        np.zeros((1, 0))
    )
    assert np.all(np.isfinite(ev.blocks))


def test_rest_blocks_are_centred_on_their_compared_sample(small: tuple) -> None:
    """Each rest block's data mean is compared with the model at the block's
    centre sample, so a block holds an odd number of samples around it (an
    even block is centred half a sample off: ~100 Pa on the slope after a
    charge, which biased xi by 1.5 sd). A linear ramp's block means then equal
    the ramp at the compared times."""
    _, campaign, truth = small
    rec = next(r for r in campaign.by_role("fit") if r.kind == "charge")
    prob = Problem([rec], STRUCTURE, truth, channels=(f"p_{rec.chamber}",))
    obs = prob.observations[0]
    assert obs.weight is not None
    counts = np.round(obs.weight**2).astype(int)
    assert np.all(counts % 2 == 1) and counts.max() > 1
    ramp = 1.0e5 + 3.0e5 * rec.time
    ramped = Recording.from_arrays(
        rec.time, {**rec.channels, f"p_{rec.chamber}": ramp}, kind=rec.kind, role=rec.role,
        file=rec.file, chamber=rec.chamber, piston_position=rec.piston_position,
    )  # fmt: skip
    obs2 = Problem([ramped], STRUCTURE, truth, channels=(f"p_{rec.chamber}",)).observations[0]
    np.testing.assert_allclose(obs2.data, 1.0e5 + 3.0e5 * obs2.time, rtol=0, atol=1e-6)


def test_initial_states_are_parameters(small: tuple) -> None:
    prob, _ps, truth = _setup(small, ("step",))
    names = [n for n in prob.initial_parameters if n.endswith(":T_P")]
    assert names and all(n.startswith(INITIAL_PREFIX) for n in names)
    base = prob.predict({}, 1).blocks[0][0]
    warmer = prob.predict({names[0]: np.array([truth["wall_temperature"] + 5.0])}, 1)
    assert not np.allclose(warmer.blocks[0][0], base)


def test_initial_states_have_priors_from_the_sensor_noise(small: tuple) -> None:
    """A measured initial state gets its sensor's noise (with the offset
    tolerance in quadrature when the offset is profiled), an unmeasured gas
    temperature 5 K around the wall; the free parameters carry those priors,
    centred on the data's value even when started elsewhere."""
    from pneumafit.identification.problem import OFFSET_TOLERANCE, UNMEASURED_TEMPERATURE_STD
    from pneumafit.identification.quality import estimate_noise
    from pneumafit.identification.staged import with_initial_states

    prob, ps, truth = _setup(small, ("charge", "step"))
    priors = prob.initial_priors()
    for name, (i, state, default, _unit) in prob.initial_parameters.items():
        rec = prob.recordings[i]
        if state in rec.channels:
            sigma, _n = estimate_noise(rec, state)
            if state.startswith("p"):
                # pressure offsets are profiled by default
                assert priors[name] == pytest.approx(np.hypot(sigma, OFFSET_TOLERANCE["pressure"]))
            else:
                assert priors[name] == pytest.approx(sigma)
        elif state.startswith("T"):
            assert priors[name] == UNMEASURED_TEMPERATURE_STD
            assert default == truth["wall_temperature"]
    # no offsets profiled: the pressure priors are the sensor noise alone
    bare = Problem(prob.recordings, STRUCTURE, truth, offsets=()).initial_priors()
    p_name = next(n for n, v in prob.initial_parameters.items() if v[1] == "p_P")
    assert bare[p_name] < priors[p_name] and bare[p_name] < 1e3
    moved = {p_name: prob.initial_parameters[p_name][2] + 5e4}
    free = with_initial_states(ps, prob, moved, free=True)
    par = free[p_name]
    assert par.value == pytest.approx(moved[p_name])
    assert par.prior.mean == pytest.approx(prob.initial_parameters[p_name][2])
    assert par.prior.std == pytest.approx(priors[p_name])
    fixed = with_initial_states(ps, prob, {}, free=False)
    assert fixed[p_name].prior is None and fixed[p_name].fixed


def test_temperature_lag_needs_its_nuisance_parameter(small: tuple) -> None:
    _, campaign, truth = small
    prob = Problem(
        campaign.by_kind("charge"), STRUCTURE, truth, channels=("p_P", "T_P"),
        sensor_lags={"T_P": "temperature_sensor_lag"},
    )  # fmt: skip
    ps = ParameterSet.for_model(STRUCTURE).only_free(("xi",))
    with pytest.raises(ValueError, match="temperature_sensor_lag"):
        LogLikelihood(prob, ps)


def test_lag_is_exact_for_linear_inputs_and_near_the_rig_sensor() -> None:
    t = np.linspace(0.0, 2.0, 2001)
    x = 3.0 * t
    tau = 0.4
    exact = 3.0 * (t - tau * (1.0 - np.exp(-t / tau)))  # y(0) = x(0) = 0
    assert np.allclose(first_order_lag(x, t, tau), exact, atol=1e-12)
    # the virtual rig's sensor (the truth's side) holds the input over each
    # sample instead: the two differ by about half a sample, no more
    step = np.where(t > 0.5, 1.0, 0.0)
    diff = first_order_lag(step, t, tau) - held_input_lag(step, 1e-3, tau)
    assert 0.0 < np.max(np.abs(diff)) < 2e-3


def test_solver_correction_moves_predictions_to_the_reference(small: tuple) -> None:
    prob, ps, _truth = _setup(small, ("step",))
    before = prob.predict({}, 1).blocks[0][0].copy()
    prob.correct_solver(ps.values())
    after = prob.predict({}, 1).blocks[0][0]
    delta = after - before
    # the coarse solver is already good to a few Pa; the correction is that
    assert 0.0 < np.max(np.abs(delta)) < 100.0


def test_compared_samples_do_not_depend_on_the_values_a_problem_is_built_at(
    small: tuple,
) -> None:
    """Two problems of one fit built at different values or friction laws (a
    stage and its extension after the joint solve stiffened a LuGre bristle;
    the switch and LuGre laws' BIC) compare the same samples, so that their
    log-likelihoods can be compared. Before, the compared samples were the
    stability step's grid: here 2.58 ms (every 2nd sample) against 1.64 ms
    (every one), and the log-likelihood of one and the same parameter set was
    -15299 on one problem and -28883 on the other. Now both compare every 2
    ms (``COMPARE_SPACING``) and integrate a shorter step as substeps; what
    is left is the two steps' truncation error (measured: 1.5 in
    log-likelihood; bound 5, about three times that and 2700 times below the
    13583 of the defect)."""
    _, campaign, truth = small
    lugre = dataclasses.replace(STRUCTURE, friction="lugre")
    rec = [r for r in campaign.by_role("fit") if r.kind == "step"][:1]
    ps = ParameterSet.for_model(lugre, campaign.rig.as_parameters())
    base = {**ps.values(), **{k: v for k, v in truth.items() if k in ps.names}}
    ps = ps.with_values(base).only_free(("friction_static", "friction_coulomb"))
    probs = [
        Problem(rec, lugre, {**base, "friction_damping": d}, initial_nuisance=False)
        for d in (1.0e3, 2.0e4)
    ]
    # the precondition: the stiffer bristle asks for a shorter step
    assert probs[1].steps[0] < 0.75 * probs[0].steps[0]
    switch = Problem(rec, STRUCTURE, truth, initial_nuisance=False)
    for other in (probs[1], switch):
        for a, b in zip(probs[0].observations, other.observations, strict=True):
            np.testing.assert_array_equal(a.time, b.time)
    ll = [LogLikelihood(p, ps)(ps.to_internal()[None, :])[0] for p in probs]
    assert np.all(np.isfinite(ll))
    assert abs(ll[0] - ll[1]) < 5.0, ll


def test_a_spool_lag_at_its_fitting_floor_is_simulated(small: tuple) -> None:
    """With a first-order spool lag the problem's steps (also the blocked
    tests' rest steps) are stable down to the lag's fitting floor, not only at
    the nominal lag it was built with: a fit that moves tau there still
    simulates (before, a 2-ms start failed in every simulation: the 4-ms step
    and the rest steps were stable for the 15-ms nominal lag only)."""
    from pneumafit.discovery.catalog import get_effect
    from pneumafit.identification.problem import valve_lag_floor

    _, campaign, truth = small
    lagged = get_effect("valve_dynamics").structure(STRUCTURE)
    nominal = {**truth, "valve_time_constant": 0.015}
    prob = Problem(campaign.by_role("fit"), lagged, nominal)
    floor = valve_lag_floor(lagged, prob.base)
    assert floor == 1e-3
    pred = prob.predict({"valve_time_constant": np.array([floor, 2e-3, 0.015])}, 3)
    assert np.all(pred.status == 0) and pred.ok.all()
    assert {"charge", "discharge", "step"} <= {e.kind for e in prob.experiments}
    # the cap applies only with the lag
    assert valve_lag_floor(STRUCTURE, prob.base) is None
    assert max(Problem(campaign.by_role("fit"), STRUCTURE, truth).steps) > max(prob.steps)


def test_noise_pooled_per_sensor_shares_one_sigma(small: tuple) -> None:
    """With ``noise_pooling="sensor"`` the blocks of one channel (one sensor
    across the recordings) share the sigma of their joint profile, the
    likelihood is the blocks' log densities at that sigma, and the shared
    sigma is counted once among the profiled parameters; "recording" keeps
    a sigma per block (the default, unchanged)."""
    from pneumafit.identification.noise import Gaussian

    own, ps, _ = _setup(small, ("charge", "discharge", "step"))
    pooled, _, _ = _setup(small, ("charge", "discharge", "step"), noise_pooling="sensor")
    assert own.noise_groups is None and pooled.noise_groups is not None
    z = np.tile(ps.to_internal(), (2, 1))
    z[1, 0] += 0.05  # another xi: another residual, another pooled sigma
    ev_own = LogLikelihood(own, ps).evaluate(z)
    ev = LogLikelihood(pooled, ps).evaluate(z)
    p_blocks = [j for j, o in enumerate(pooled.observations) if o.channel == "p_P"]
    assert len(p_blocks) >= 3
    sizes = np.array([pooled.observations[j].n for j in p_blocks], dtype=float)
    own_sigma = np.array([ev_own.noise[j]["sigma"] for j in p_blocks])  # (blocks, sets)
    expected = np.sqrt(np.sum(sizes[:, None] * own_sigma**2, axis=0) / sizes.sum())
    for j in p_blocks:
        np.testing.assert_allclose(ev.noise[j]["sigma"], expected, rtol=1e-12)
        obs = pooled.observations[j]
        r = np.nan_to_num(ev.residuals[j])
        direct = Gaussian().logpdf(r, expected) + pooled.log_weight(j)
        np.testing.assert_allclose(ev.blocks[:, j], direct, rtol=1e-12)
        assert obs.noise == Gaussian()
    # one sigma per channel instead of one per block: each channel with k
    # Gaussian or AR(1) blocks has k - 1 fewer profiled parameters
    per_channel: dict[str, int] = {}
    for o in pooled.observations:
        per_channel[o.channel] = per_channel.get(o.channel, 0) + 1
    shared = sum(k - 1 for k in per_channel.values())
    assert shared >= len(p_blocks) - 1
    assert pooled.n_noise_parameters == own.n_noise_parameters - shared
    # the pooled profile never beats the blocks' own profiles (fewer noise parameters)
    assert np.all(ev.log_likelihood <= ev_own.log_likelihood + 1e-6)
    with pytest.raises(ValueError, match="noise_pooling"):
        _setup(small, ("charge",), noise_pooling="channel")


@pytest.mark.parametrize("option", ["noise_pooling", "offset_scope"])
def test_the_option_goes_with_the_fit(option: str) -> None:
    """fit.json records FitOptions.noise_pooling and .offset_scope (both
    "recording" by default); discovery's refits read them (a fit.json
    written before the option existed was "recording": a noise level, a
    pressure offset per recording), and the fit's command line says them
    when they are not the default."""
    import json
    from types import SimpleNamespace

    from pneumafit.discovery.refit import BaseFit
    from pneumafit.identification import FitOptions
    from pneumafit.identification.fitfile import fit_document
    from pneumafit.identification.staged import FitResult
    from pneumafit.services.fit import fit_command_line

    assert getattr(FitOptions(), option) == "recording"
    result = FitResult(
        model="convection", structure=STRUCTURE, parameters=ParameterSet.for_model(STRUCTURE),
        laplace=None, stages=[], metrics={}, options=FitOptions(**{option: "sensor"}),
    )  # fmt: skip
    camp = SimpleNamespace(name="test", path=None, sha256={})
    doc = json.loads(json.dumps(fit_document(result, camp, seed=0)))
    assert doc["provenance"]["options"][option] == "sensor"
    assert getattr(BaseFit.from_document(doc), option) == "sensor"
    del doc["provenance"]["options"][option]
    assert getattr(BaseFit.from_document(doc), option) == "recording"
    flag = "--" + option.replace("_", "-")
    line = fit_command_line("c", "convection", "o", None, None, 0, False, **{option: "sensor"})
    assert line.endswith(f"{flag} sensor")
    assert flag not in fit_command_line("c", "convection", "o", None, None, 0, False)


def test_one_offset_per_pressure_sensor_is_the_joint_least_squares(small: tuple) -> None:
    """Exact, on the linear algebra: with ``offset_scope="sensor"`` the
    residuals are those of the joint weighted least squares over one
    constant per channel, shared by its blocks, and each block's own
    initial-state sensitivities (weights: the blocks' tempering powers),
    computed here by brute force on the stacked blocks; a constant added to
    every reading of one sensor leaves them unchanged, and
    :meth:`Problem.sensor_offsets` gives it back. ``"recording"`` keeps one
    constant per block (its residuals each sum to zero)."""
    prob, _ps, truth = _setup(small, ("charge", "discharge", "step"), offset_scope="sensor")
    assert prob.offset_scope == "sensor"
    prob.linearize(truth)
    rng = np.random.default_rng(3)
    prob.tempering = rng.uniform(0.05, 1.0, len(prob.observations))
    off = {**truth, "xi": truth["xi"] * 1.3, "friction_static": truth["friction_static"] * 0.8}
    pred = prob.predict({k: np.array([v]) for k, v in off.items()}, 1)
    got = prob.residuals(pred)
    raw = prob.raw_residuals(pred)
    members = [j for j, o in enumerate(prob.observations) if o.channel == "p_P"]
    assert len(members) >= 3
    assert any(prob.bases[j] is not None for j in members)
    # brute force: columns [Q_1 .. Q_k (block-diagonal), ones], rows scaled by sqrt(t_b)
    sizes = [prob.observations[j].n for j in members]
    starts = np.cumsum([0, *sizes])
    ncol = sum(0 if prob.bases[j] is None else prob.bases[j].shape[1] for j in members) + 1
    mat = np.zeros((starts[-1], ncol))
    rhs = np.zeros(starts[-1])
    col = 0
    for b, j in enumerate(members):
        o, q = prob.observations[j], prob.bases[j]
        rows = slice(starts[b], starts[b + 1])
        w = np.ones(o.n) if o.weight is None else o.weight
        s = np.sqrt(prob.tempering[j])
        rhs[rows] = s * raw[j][0] * w
        mat[rows, -1] = s * w
        if q is not None:
            mat[rows, col : col + q.shape[1]] = s * q
            col += q.shape[1]
    # tolerances: float rounding of two solutions of one linear least
    # squares (QR here, normal equations per block there), ~1e-12 relative
    coef, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
    brute = rhs - mat @ coef
    for b, j in enumerate(members):
        s = np.sqrt(prob.tempering[j])
        np.testing.assert_allclose(
            got[j][0], brute[starts[b] : starts[b + 1]] / s, atol=1e-9 * np.abs(rhs).max()
        )
    np.testing.assert_allclose(prob.sensor_offsets(pred)["p_P"][0], coef[-1], rtol=1e-9)
    # a shared sensor zero is taken off whole
    shifted = [
        dataclasses.replace(o, data=o.data + 750.0) if o.channel == "p_P" else o
        for o in prob.observations
    ]
    plain = prob.observations
    prob.observations = shifted
    again = prob.residuals(pred)
    np.testing.assert_allclose(prob.sensor_offsets(pred)["p_P"][0], coef[-1] + 750.0, rtol=1e-9)
    prob.observations = plain
    for j in members:
        np.testing.assert_allclose(again[j], got[j], atol=1e-6)
    # one per recording: each block's weighted residual sums to zero
    own, _, _ = _setup(small, ("charge", "discharge", "step"))
    assert own.offset_scope == "recording"  # the default
    own.linearize(truth)
    for j, r in enumerate(own.residuals(pred)):
        o = own.observations[j]
        if o.channel == "p_P":
            w = np.ones(o.n) if o.weight is None else o.weight
            assert abs(float(r[0] @ w)) < 1e-6 * float(np.abs(r[0]).sum())
    assert own.sensor_offsets(pred) == {}
    assert own.n_nuisance > prob.n_nuisance
    with pytest.raises(ValueError, match="offset_scope"):
        _setup(small, ("charge",), offset_scope="campaign")
