"""The measured valve map in identification: parameter set, knots, fit.json.

Plumbing tests (no fit to convergence; the map's recovery on mismatched
valves is measured by benchmarks/bench_recovery.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pneumafit.campaign import Campaign
from pneumafit.identification import FitOptions, ParameterSet, identify
from pneumafit.identification.staged import (
    MAP_LEAK_PARAMETERS,
    _dead_band_knots,
    _iso_valve,
    _uninformed_knots,
    fit_structure,
)
from pneumafit.models.layout import PARAMETER_SPECS
from pneumafit.physics.valve_map import (
    CENTRE_KNOT,
    MAP_CE_NAMES,
    MAP_CS_NAMES,
    MAP_KNOTS,
    MAP_SMOOTHNESS_SCALE,
    N_KNOTS,
    map_from_iso,
    map_roughness,
)
from pneumafit.virtual_rig import VirtualRig
from pneumafit.virtual_rig.truth import get_truth


def test_a_map_structure_fits_the_map_and_not_the_iso_ramp() -> None:
    st = fit_structure("convection", valve="map")
    assert st.valve == "map" and st.name == "convection"
    ps = ParameterSet.for_model(st, {"bore": 0.032})
    names = set(ps.names)
    assert "valve_C_supply" not in names and "valve_overlap" not in names
    assert "valve_map_CS_14" in ps.free_names and "valve_map_CE_00" in ps.free_names
    # each path's closed side (below its leakage by monotonicity) is held
    assert "valve_map_CS_00" not in ps.free_names and "valve_map_CE_14" not in ps.free_names
    assert set(MAP_LEAK_PARAMETERS) <= set(ps.free_names)
    assert ps["valve_map_CS_14"].scale == "log" and ps["valve_map_bS_1"].scale == "linear"
    iso = ParameterSet.for_model(fit_structure("convection"), {})
    assert not any(n.startswith("valve_map") for n in iso.names)
    assert {s.group for s in PARAMETER_SPECS if s.name.startswith("valve_map")} == {"valve_map"}


def test_knots_without_a_flow_level_are_held_and_the_iso_start_is_sampled(small: tuple) -> None:
    """The small campaign's flow levels (0, +-0.2, +-0.4, +-3, +-10 V) leave
    the knots at +-7 V (levels 3 and 10 V are outside (4, 10)) and +-1 V
    (no level in (0.5, 2)) uninformed; the ISO fit of its flow tests (the
    rig is ISO 6358) sampled at the knots is the map's start."""
    _, campaign, truth = small
    held = _uninformed_knots(campaign, {"valve_u_sat": 10.0})
    u = {round(f * 10.0, 3) for f in MAP_KNOTS}
    assert held == [f"valve_map_{p}_{k:02d}" for k in (1, 4, 10, 13) for p in ("CS", "CE")]
    assert {-7.0, -1.0, 1.0, 7.0} <= u
    flows = [r for r in campaign.by_role("fit") if r.kind == "flow"]
    st = fit_structure("convection", valve="map")
    values = {**truth}
    iso = _iso_valve(campaign, flows, st, values, FitOptions(mcmc=False), seed=0)
    # the flow tests determine the full-opening conductances to a fraction of a percent
    assert np.isclose(iso["valve_C_supply"], truth["valve_C_supply"], rtol=0.01, atol=0.0)
    start = map_from_iso({**values, **iso})
    # full opening: the ISO conductance plus the leakage shifted onto the open path
    full = iso["valve_C_supply"] + 2.0 * iso["valve_C_leak"]
    assert np.isclose(start["valve_map_CS_14"], full, rtol=1e-3, atol=0.0)
    assert np.isclose(start["valve_map_CS_07"], iso["valve_C_leak"], rtol=1e-9, atol=0.0)
    assert replace(st, valve="iso6358").valve == "iso6358"


# --------------------------------------------------------------------------- smoothness prior
def _line_knots(a: float, b: float) -> dict[str, float]:
    """ln C = a + b |k - centre| on each path's opening side, an arbitrary
    (non-straight) closed side: zero roughness by construction."""
    out = {}
    for k in range(N_KNOTS):
        d = k - CENTRE_KNOT
        out[MAP_CS_NAMES[k]] = float(np.exp(a + b * d)) if d >= 0 else 1e-14 * (1 + k)
        out[MAP_CE_NAMES[k]] = float(np.exp(a + b * -d)) if d <= 0 else 3e-14 * (1 + k)
    return out


def test_roughness_is_the_scaled_second_difference_of_ln_c_on_the_opening_sides() -> None:
    """Zero for a straight line in ln C over the knot index (a power-law
    opening on the nearly geometric knots), whatever the closed side does;
    one knot raised by a factor e gives second differences -2/s and +1/s
    around it; a batch of sets gives one row each."""
    line = _line_knots(-24.0, 0.9)
    assert np.allclose(map_roughness(line), 0.0, atol=1e-12)
    bumped = dict(line)
    k = CENTRE_KNOT + 3
    bumped[MAP_CS_NAMES[k]] *= np.e
    r = map_roughness(bumped)[0] * MAP_SMOOTHNESS_SCALE
    # supply terms are centred on knots centre+1 .. 13: the bump sits at term index 2
    assert np.allclose(r[:6], [0.0, 1.0, -2.0, 1.0, 0.0, 0.0], atol=1e-12)
    assert np.allclose(r[6:], 0.0, atol=1e-12)
    batch = {n: np.array([line[n], bumped[n]]) for n in line}
    assert map_roughness(batch).shape == (2, r.size)


def test_a_map_parameter_set_carries_the_smoothness_prior_and_an_iso_set_does_not() -> None:
    """log_prior and prior_residuals of a map set include the roughness
    (the same terms: log prior = -sum r^2 / 2 up to the per-parameter
    priors and the breakaway prior, flat at these friction defaults); an
    ISO set has no such term."""
    ps = ParameterSet.for_model(fit_structure("convection", valve="map"), {})
    line = _line_knots(-24.0, 0.9)
    bumped = {**line, "valve_map_CE_03": line["valve_map_CE_03"] * 3.0}
    base = ps.with_values(line)
    moved = ps.with_values(bumped)
    z0, z1 = base.to_internal(), moved.to_internal()
    r0, r1 = map_roughness(base.values()), map_roughness(moved.values())
    assert np.allclose(r0, 0.0, atol=1e-12) and np.sum(r1**2) > 1.0
    # every knot has a flat (log-uniform) prior: the difference is the roughness only
    own = sum(
        p.log_prior_internal(np.array([z1[j]]))[0] - p.log_prior_internal(np.array([z0[j]]))[0]
        for j, p in enumerate(ps.free)
    )
    d_lp = float(ps.log_prior(z1)[0] - ps.log_prior(z0)[0])
    assert np.isclose(d_lp, own - 0.5 * np.sum(r1**2), rtol=1e-9, atol=1e-9)
    res = ps.prior_residuals(z1)
    # the laws' joint priors come last, the valve law's before the friction law's
    assert np.allclose(res[-r1.size - 1 : -1], r1[0], rtol=1e-12, atol=1e-12)
    iso = ParameterSet.for_model(fit_structure("convection"), {})
    # no smoothness term: only the friction law's breakaway prior (one term)
    assert iso.prior_residuals(iso.to_internal()).size == 1
    assert res.size == r1.size + 1


def test_prior_residuals_of_a_batch_are_its_rows_stacked_in_c_order() -> None:
    """The least-squares batches take the prior residuals of all their sets
    at once: exactly (bit for bit) the rows of one set at a time, and C-ordered
    like them (a Fortran-ordered block, the map's roughness being a transpose,
    changed the solver's summation order and took a map fit to another local
    optimum with the same values)."""
    rng = np.random.default_rng(7)
    for valve in ("map", "iso6358"):
        ps = ParameterSet.for_model(fit_structure("convection", valve=valve), {})
        lo, hi = ps.internal_bounds()
        zz = np.clip(ps.to_internal() + 0.3 * rng.standard_normal((13, ps.n_free)), lo, hi)
        batch = ps.prior_residuals(zz)
        rows = np.array([ps.prior_residuals(z) for z in zz]).reshape(13, -1)
        assert batch.shape == rows.shape and batch.tobytes() == rows.tobytes()
        assert batch.flags["C_CONTIGUOUS"]
        lp = ps.log_prior(zz)
        assert np.array_equal(lp, np.concatenate([ps.log_prior(z[None]) for z in zz]))


def test_a_knot_no_flow_level_informs_follows_its_neighbours() -> None:
    """Recovery on a mismatched truth (the independent simulator's
    ``table-valve-asym`` valve: a catalogue table on the supply path, LSODA,
    flow-meter lag and noise), flow test only, map law. The sparse plan's
    levels (0.6, 1.5, 4, 10 V) leave the supply knot at 7 V uninformed: no
    flow level between 4 and 10 V, and the knot's value changes the
    interpolant only there and, through the PCHIP slope at 4 V, on (2, 4) V,
    where no level is either. It is free (not held at the ISO start) and
    ends where the smoothness prior is flat in it: the data carry no
    gradient for it, so the prior's gradient must vanish at the optimum.
    The tolerance, 0.002 (half the squared roughness per unit of ln C), is
    8x below the gradient at the ISO start (0.017) and 8x above the one
    measured at the fit (0.0003). The informed knots at 4 and 10 V are
    within 2 % of the truth's table (measured: 0.2 % and 0.1 %): a sanity
    check of the fit, not of the change (the ISO start is also within 2 % at
    4 V); 2 % leaves room for other noise draws.
    """
    full = VirtualRig(truth="table-valve-asym", seed=3).campaign("sparse")
    flows = [r for r in full.recordings if r.kind == "flow"]
    campaign = Campaign(path=None, name="flow", description="", rig=full.rig, recordings=flows)
    result = identify(campaign, options=FitOptions(valve="map", mcmc=False), seed=3)
    knot = MAP_CS_NAMES[13]
    assert knot in result.stage("valve").free
    values = {p.name: p.value for p in result.parameters}

    def grad(vals: dict[str, float]) -> float:
        h = 1e-4
        up = {**vals, knot: vals[knot] * np.exp(h)}
        dn = {**vals, knot: vals[knot] * np.exp(-h)}
        return float((np.sum(map_roughness(up) ** 2) - np.sum(map_roughness(dn) ** 2)) / (4 * h))

    assert abs(grad(values)) < 0.002
    table = get_truth("table-valve-asym").valve.supply
    assert np.isclose(values[MAP_CS_NAMES[12]], table.conductance(4.0), rtol=0.02, atol=0.0)
    assert np.isclose(values[MAP_CS_NAMES[14]], table.conductance(10.0), rtol=0.02, atol=0.0)


def test_the_dead_band_knots_are_the_unmeasured_run_around_the_centre() -> None:
    """Sparse-plan levels (+-0.6, 1.5, 4, 10 V, no 0 V) leave the knots at
    0 and +-0.25 V unmeasured (and 7 V, which is not next to the centre):
    the heat stage fits the free ones of +-0.25 V with the centre leakage."""
    unmeasured = [f"valve_map_{p}_{k:02d}" for k in (1, 6, 7, 8, 13) for p in ("CS", "CE")]
    free = [n for n in unmeasured if n not in ("valve_map_CS_01", "valve_map_CE_13")]
    got = _dead_band_knots(unmeasured, free)
    assert set(got) == {"valve_map_CS_06", "valve_map_CE_06", "valve_map_CS_08", "valve_map_CE_08"}
    # a measured knot next to the centre ends the run on that side
    assert _dead_band_knots(["valve_map_CS_07", "valve_map_CE_07"], free) == ()
