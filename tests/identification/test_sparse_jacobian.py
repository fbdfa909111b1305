"""The finite-difference Jacobian skips the simulations a parameter cannot change.

``Problem.unaffected`` states, from the model's structure, which recordings'
simulations cannot depend on a parameter; a Jacobian batch then takes them
from its first set (``same_as_first``). These tests check each rule against
full simulations (bit for bit, and that the rules are not vacuous: the
parameter does move the recordings it is not excused from), and that the
Jacobian and a whole least-squares solve are unchanged by the shortcut.
They are exactness tests of the code, not recovery claims.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pneumafit.campaign import Campaign
from pneumafit.errors import PneumafitInputError
from pneumafit.identification import LogLikelihood, ParameterSet, Problem, fit_structure
from pneumafit.identification.optimise import _fd_steps, _Whitened, fit_least_squares
from pneumafit.identification.staged import with_initial_states
from pneumafit.simulation import counter

HEAT = ("xi", "beta")
FRICTION = (
    "friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity",
    "friction_stiffness", "friction_damping",
)  # fmt: skip
VALVE = ("valve_C_supply", "valve_overlap")


#: Effects switched on in the effects test, and a value of each parameter
#: away from its default (SI): friction-like terms that declare
#: ``moves={"motion"}`` and chamber effects that move blocked tests too.
EFFECT_VALUES = {
    "seal_friction": {"seal_friction_coefficient": 1.5e-5},
    "friction_asymmetry": {"friction_asymmetry": 0.1},
    "effective_area": {"area_factor": 1.02},
    "external_leakage": {"external_leak_conductance": 1e-11},
}


def _likelihood(
    small: tuple[object, Campaign, dict[str, float]],
    lag: bool = False,
    effects: bool = False,
) -> tuple[LogLikelihood, ParameterSet]:
    _, campaign, truth = small
    structure = fit_structure("convection", friction="lugre")
    extra: dict[str, float] = {}
    if effects:
        structure = dataclasses.replace(structure, effects=dict.fromkeys(EFFECT_VALUES, 1))
        extra = {k: v for d in EFFECT_VALUES.values() for k, v in d.items()}
        truth = {**truth, **extra}
    channels = ("p_P", "p_N", "y", "qm_P", "qm_N") + (("T_P",) if lag else ())
    kw = {"sensor_lags": {"T_P": "temperature_sensor_lag"}} if lag else {}
    prob = Problem(campaign.by_role("fit"), structure, truth, channels=channels, **kw)
    ps = ParameterSet.for_model(
        structure, campaign.rig.as_parameters(), nuisance=("temperature_sensor_lag",) if lag else ()
    )
    ps = ps.with_values({k: v for k, v in truth.items() if k in ps.names})
    free = HEAT + FRICTION + VALVE + (("temperature_sensor_lag",) if lag else ()) + tuple(extra)
    ps = with_initial_states(ps.only_free(free), prob, {}, free=True)
    return LogLikelihood(prob, ps), ps


def _rules_against_full_simulations(
    like: LogLikelihood, ps: ParameterSet
) -> tuple[dict[str, np.ndarray], list[str], np.ndarray]:
    """Each rule of ``unaffected`` checked bit for bit against a full batch.

    Returns the rules by name, the recordings' kinds and which recordings
    some parameter not excused from them did move.
    """
    prob = like.problem
    names = ps.free_names
    rules = prob.unaffected(names)
    kinds = [e.kind for e in prob.experiments]
    assert {"flow", "charge", "step"} <= set(kinds)
    z0 = ps.to_internal()
    # every parameter moved by a few per cent of its internal range, all at once
    lo, hi = ps.internal_bounds()
    step = 0.02 * np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    zz = np.repeat(z0[None], len(names) + 1, axis=0)
    zz[1:] += np.diag(step)
    values = ps.to_values(zz)
    full_out, full_status = prob.simulator.simulate_batch(
        prob.model_vectors(values, zz.shape[0]), prob.packed,
        initial_states=prob.initial_states(values, zz.shape[0]),
    )  # fmt: skip
    assert np.all(full_status == 0)
    off = prob.packed.offsets
    moved_any = np.zeros(len(kinds), dtype=bool)
    for j, name in enumerate(names):
        for r in range(len(kinds)):
            same = np.array_equal(
                full_out[j + 1, off[r] : off[r + 1]], full_out[0, off[r] : off[r + 1]]
            )
            if rules[j, r]:
                assert same, f"{name} is said not to affect {kinds[r]} {r}, but does"
            else:
                moved_any[r] |= not same
    return dict(zip(names, rules, strict=True)), kinds, moved_any


def test_each_rule_holds_in_full_simulations(small: tuple) -> None:
    like, ps = _likelihood(small, lag=True)
    by_name, kinds, moved_any = _rules_against_full_simulations(like, ps)
    names = ps.free_names
    # the rules are not vacuous: friction excused from flow and blocked tests,
    # heat from flow tests, an initial state from every other recording, the lag
    # (it acts after the simulation) from all
    blocked_or_flow = np.array([k != "step" for k in kinds])
    assert np.array_equal(by_name["friction_damping"], blocked_or_flow)
    assert np.array_equal(by_name["xi"], np.array([k == "flow" for k in kinds]))
    assert not by_name["valve_C_supply"].any()
    assert by_name["temperature_sensor_lag"].all()
    initial = [n for n in names if n.startswith("initial:")]
    assert initial and all(by_name[n].sum() == len(kinds) - 1 for n in initial)
    # and each recording is moved by some parameter the rules leave to it
    assert moved_any.all()


def test_effects_declare_what_they_move(small: tuple) -> None:
    """Effects on: a friction-like effect (``moves={"motion"}``) is excused
    from blocked tests as well as flow tests, a chamber effect only from flow
    tests (the static characteristic reads the valve laws alone); each rule
    holds bit for bit in full simulations."""
    like, ps = _likelihood(small, effects=True)
    by_name, kinds, moved_any = _rules_against_full_simulations(like, ps)
    flow = np.array([k == "flow" for k in kinds])
    not_step = np.array([k != "step" for k in kinds])
    assert np.array_equal(by_name["seal_friction_coefficient"], not_step)
    assert np.array_equal(by_name["friction_asymmetry"], not_step)
    assert np.array_equal(by_name["area_factor"], flow)
    assert np.array_equal(by_name["external_leak_conductance"], flow)
    assert moved_any.all()


def test_the_jacobian_and_a_solve_are_unchanged_bit_for_bit(small: tuple) -> None:
    like, ps = _likelihood(small)
    wh = _Whitened(like)
    z = ps.to_internal()
    wh.set_state(z)
    n0 = like.problem.n_evaluations
    sims0 = counter.simulations()
    r_sparse, j_sparse = wh.fun_and_jac(z)
    simulated = counter.simulations() - sims0
    # the same batch without the shortcut
    h_batch = np.repeat(z[None], z.size + 1, axis=0)

    h = _fd_steps(ps, z)
    sign = np.where(z + h > wh.upper, -1.0, 1.0)
    h_batch[1:] += np.diag(sign * h)
    full = wh.batch(h_batch)
    j_full = (full[1:] - full[0]).T / (sign * h)
    assert r_sparse.tobytes() == full[0].tobytes()
    assert j_sparse.tobytes() == j_full.tobytes()
    assert like.problem.n_evaluations - n0 == 2 * (z.size + 1)
    # the shortcut was taken: the (set, recording) pairs the rules excuse were
    # not simulated (the full batch simulates every pair)
    n_rec = len(like.problem.experiments)
    excused = int(like.problem.unaffected(ps.free_names).sum())
    assert excused > 0 and simulated == (z.size + 1) * n_rec - excused
    # a short solve from a moved start: the same estimate either way
    start = {"xi": 0.5, "friction_coulomb": 25.0}
    a = fit_least_squares(like, starts=[start], max_reweight=1, max_nfev=4)
    original = _Whitened.fun_and_jac

    def full_jacobian(
        self: _Whitened, z: np.ndarray, *, feasible: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        hh = _fd_steps(self.like.parameters, z)
        sg = np.where(z + hh > self.upper, -1.0, 1.0)
        if feasible:  # the covariance's steps, as _Whitened.fun_and_jac takes them
            self._inside_constraints(z, hh, sg)
        pts = np.repeat(z[None, :], z.size + 1, axis=0)
        pts[1:] += np.diag(sg * hh)
        res = self.batch(pts)
        return res[0], (res[1:] - res[0]).T / (sg * hh)

    try:
        _Whitened.fun_and_jac = full_jacobian  # type: ignore[method-assign]
        b = fit_least_squares(like, starts=[start], max_reweight=1, max_nfev=4)
    finally:
        _Whitened.fun_and_jac = original  # type: ignore[method-assign]
    assert a.z.tobytes() == b.z.tobytes()


def test_simulate_batch_checks_the_shape_of_same_as_first(small: tuple) -> None:
    like, ps = _likelihood(small)
    prob = like.problem
    vec = prob.model_vectors(ps.to_values(ps.to_internal()), 1)
    with pytest.raises(PneumafitInputError, match="same_as_first: expected shape"):
        prob.simulator.simulate_batch(
            np.repeat(vec, 2, axis=0), prob.packed, same_as_first=np.zeros((2, 1), dtype=bool)
        )
