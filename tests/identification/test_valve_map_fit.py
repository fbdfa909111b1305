"""The measured valve map in identification: parameter set, knots, fit.json.

Plumbing tests (no fit to convergence; the map's recovery on mismatched
valves is measured by benchmarks/bench_recovery.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pneumafit.identification import FitOptions, ParameterSet
from pneumafit.identification.staged import (
    MAP_LEAK_PARAMETERS,
    _iso_valve,
    _uninformed_knots,
    fit_structure,
)
from pneumafit.models.layout import PARAMETER_SPECS
from pneumafit.physics.valve_map import MAP_KNOTS, map_from_iso


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
