"""The paper's linear analysis: equilibrium (eq. 10), linearization (eqs.
11-14), ITAE poles and state-feedback placement."""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.analysis import (
    ITAE_POLES,
    closed_loop_poles,
    equilibrium,
    gain_schedule,
    itae_poles,
    linearize,
    numerical_jacobian,
    place,
)
from pneumafit.analysis.linear import _net_flow
from pneumafit.models.parameters import parameter_vector
from pneumafit.physics.geometry import piston_areas

PARAMS = parameter_vector({"rod": 0.02, "dead_volume_P": 2.5e-5, "dead_volume_N": 3e-5})
POSITIONS = (0.05, 0.25, 0.45)

# The paper's table (w0 = 1 rad/s), 4 decimals.
PAPER_TABLE = {
    4: [-0.4240 + 1.2630j, -0.6260 + 0.4141j],
    6: [-0.3099 + 1.2634j, -0.5805 + 0.7828j, -0.7346 + 0.2873j],
}


@pytest.mark.parametrize("order", [4, 6])
def test_itae_poles_match_the_papers_table(order):
    """The ITAE polynomials' roots, rounded to the table's 4 decimals, are the
    table: each component within half a unit of the last digit, so a distance
    below sqrt(2) * 5e-5 = 7.1e-5."""
    for pole in PAPER_TABLE[order]:
        for p in (pole, pole.conjugate()):
            assert np.min(np.abs(ITAE_POLES[order] - p)) < 7.1e-5
    assert ITAE_POLES[order].size == order
    np.testing.assert_allclose(itae_poles(order, 15.0), 15.0 * ITAE_POLES[order])


@pytest.mark.parametrize("y", POSITIONS)
def test_equilibrium_satisfies_eq10(y):
    """Both valves pass no net flow and the forces balance, to the solver's
    tolerance: flows below 1e-12 of the valve's full flow (~8e-3 kg/s), force
    below 1e-6 N (brentq on u with xtol 1e-13 V)."""
    eq = equilibrium(PARAMS, y)
    assert eq.exists, eq.message
    assert abs(_net_flow(PARAMS, eq.u, eq.p_P)) < 1e-12 * 8e-3
    assert abs(_net_flow(PARAMS, -eq.u, eq.p_N)) < 1e-12 * 8e-3
    s_p, s_n = piston_areas(0.032, 0.02)
    f_ext = 1.013e5 * (s_p - s_n)
    assert abs(s_p * eq.p_P - s_n * eq.p_N - f_ext) < 1e-6
    assert 1.013e5 < eq.p_N < 7e5 and 1.013e5 < eq.p_P < 7e5


def test_no_equilibrium_is_said_clearly():
    heavy = parameter_vector({"external_force": 5000.0})  # more than 7 bar on 32 mm can hold
    eq = equilibrium(heavy, 0.25)
    assert not eq.exists
    assert "no equilibrium" in eq.message and "5" in eq.message
    with pytest.raises(ValueError, match="no equilibrium"):
        linearize(heavy, 0.25)


@pytest.mark.parametrize("order", [4, 6])
@pytest.mark.parametrize("y", POSITIONS)
def test_analytic_jacobian_matches_finite_differences(order, y):
    """A and B derived by hand equal central differences of the compiled
    right-hand side. Step 1e-6 relative: truncation ~1e-12, round-off
    ~1e-16 / 1e-6 = 1e-10 relative, so 1e-7 leaves a factor 1000."""
    lin = linearize(PARAMS, y, order=order, lambda_e=15.0)
    a_num, b_num = numerical_jacobian(PARAMS, lin.equilibrium, order=order, lambda_e=15.0)
    nonzero = np.abs(lin.A) > 0
    np.testing.assert_allclose(a_num[nonzero], lin.A[nonzero], rtol=1e-7)
    # structural zeros: below 1e-7 of the largest entry in their row
    row_scale = np.abs(lin.A).max(axis=1, keepdims=True)
    assert np.all(np.abs(a_num[~nonzero]) <= 1e-7 * np.broadcast_to(row_scale, a_num.shape)[
        ~nonzero])  # fmt: skip
    np.testing.assert_allclose(b_num, lin.B, rtol=1e-7, atol=1e-7 * np.abs(lin.B).max())


def test_heat_model_has_two_more_slow_poles():
    """Fig. 5: the 6th-order model keeps the pneumatic pair of the 4th-order
    one (close to it) and adds two real thermal poles."""
    p4 = linearize(PARAMS, 0.25, order=4).poles
    p6 = linearize(PARAMS, 0.25, order=6).poles
    pair4 = p4[np.abs(p4.imag) > 1][0]
    pair6 = p6[np.abs(p6.imag) > 1][0]
    assert abs(pair6 - pair4) / abs(pair4) < 0.15
    assert np.sum(np.abs(p6.imag) < 1e-9) == np.sum(np.abs(p4.imag) < 1e-9) + 2


@pytest.mark.parametrize("order", [4, 6])
@pytest.mark.parametrize("y", POSITIONS)
def test_pole_placement_is_exact(order, y):
    """eig(A - B K) equal the requested ITAE poles within 1e-8 relative, with
    w0 the open-loop natural frequency (the paper's choice), eigenvalues
    computed in extended precision (the closed loop is strongly non-normal)."""
    lin = linearize(PARAMS, y, order=order)
    w0 = float(np.abs(lin.poles[np.abs(lin.poles.imag) > 1]).max())
    target = itae_poles(order, w0)
    gain = place(lin, target)
    got = closed_loop_poles(lin, gain)
    target = target[np.lexsort((target.imag, target.real))]
    assert np.max(np.abs(got - target) / np.abs(target)) < 1e-8


def test_gain_schedule_over_the_stroke():
    ys = np.linspace(0.02, 0.48, 7)
    sched = gain_schedule(PARAMS, ys, order=4, w0=15.0)
    assert sched["K"].shape == (7, 4) and np.all(np.isfinite(sched["K"]))
    np.testing.assert_allclose(
        np.sort_complex(sched["closed_loop"][3]), np.sort_complex(itae_poles(4, 15.0)), rtol=1e-8
    )
    # the chambers' stiffness changes along the stroke, so does the gain
    assert np.ptp(sched["K"][:, 0]) > 0.05 * np.abs(sched["K"][:, 0]).mean()


# --------------------------------------------------------------------------
# The measured valve map in the linear analysis (a fit with --valve map)
# --------------------------------------------------------------------------
def _map_of_params() -> np.ndarray:
    """PARAMS with a valve map sampled from its own ISO 6358 valve."""
    from pneumafit.models.parameters import parameter_dict
    from pneumafit.physics.valve_map import map_from_iso

    return parameter_vector({**parameter_dict(PARAMS), **map_from_iso(parameter_dict(PARAMS))})


@pytest.mark.parametrize("y", POSITIONS)
def test_map_sampled_from_the_iso_valve_gives_its_equilibrium(y):
    """The map law reproduces the ISO valve it samples: equilibrium pressures
    within 0.05 % (measured 0.007 %: the centre leak interpolated in log C
    between knots 0.25 V apart), the pneumatic pair of poles within 0.1 %
    (measured 0.01 %), the real poles within 5 % (measured 3 % on the slowest:
    it is set by dq/dP of the centre leakage, the part the knots interpolate),
    and eq. 10 holds under the map's own flows."""
    mp = _map_of_params()
    a, b = equilibrium(PARAMS, y), equilibrium(mp, y, valve="map")
    assert b.exists, b.message
    np.testing.assert_allclose([b.p_P, b.p_N], [a.p_P, a.p_N], rtol=5e-4)
    assert abs(_net_flow(mp, b.u, b.p_P, 1)) < 1e-12 * 8e-3
    poles_a = np.sort_complex(linearize(PARAMS, y, order=6).poles)
    poles_b = np.sort_complex(linearize(mp, y, order=6, valve="map").poles)
    pair = np.abs(poles_a.imag) > 0
    np.testing.assert_allclose(poles_b[pair], poles_a[pair], rtol=1e-3)
    np.testing.assert_allclose(poles_b[~pair], poles_a[~pair], rtol=0.05, atol=1e-9)


def test_map_law_is_the_one_used():
    """Tripling the supply path's knots from the centre up moves the map's
    equilibrium (P_P up by 12 %) and leaves the ISO one, which does not read
    the knots, unchanged: the linear analysis follows the fitted map."""
    from pneumafit.models.parameters import parameter_dict
    from pneumafit.physics.valve_map import MAP_CS_NAMES

    values = parameter_dict(_map_of_params())
    scaled = parameter_vector(
        {k: v * (3.0 if k in MAP_CS_NAMES[7:] else 1.0) for k, v in values.items()}
    )
    base = equilibrium(_map_of_params(), 0.25, valve="map")
    moved = equilibrium(scaled, 0.25, valve="map")
    assert moved.p_P > 1.05 * base.p_P
    assert equilibrium(scaled, 0.25).p_P == equilibrium(PARAMS, 0.25).p_P
    with pytest.raises(ValueError, match="valve: expected one of"):
        equilibrium(PARAMS, 0.25, valve="table")


@pytest.mark.parametrize("order", [4, 6])
def test_map_jacobian_matches_finite_differences(order):
    """The analytic (A, B) with the map's gains equal central differences of
    the compiled right-hand side under the map law (tolerances as the ISO
    test above: measured 7e-11)."""
    mp = _map_of_params()
    lin = linearize(mp, 0.25, order=order, lambda_e=15.0, valve="map")
    a_num, b_num = numerical_jacobian(mp, lin.equilibrium, order=order, lambda_e=15.0,
                                      valve="map")  # fmt: skip
    nonzero = np.abs(lin.A) > 0
    np.testing.assert_allclose(a_num[nonzero], lin.A[nonzero], rtol=1e-7)
    np.testing.assert_allclose(b_num, lin.B, rtol=1e-7, atol=1e-7 * np.abs(lin.B).max())


def test_map_overlap_is_the_ramps_edge():
    """The dead-band edge read off a map sampled from a linear ramp with
    overlap 0.3 V is 0.3 V to within 0.05 V (measured 0.283 V: the knots at
    0.5, 1 and 2 V carry the opening, interpolated in log C)."""
    from pneumafit.analysis.linear import deadband_compensation, overlap

    assert overlap(PARAMS) == pytest.approx(0.3)
    assert overlap(_map_of_params(), "map") == pytest.approx(0.3, abs=0.05)
    comp = deadband_compensation(_map_of_params(), 0.25, valve="map")
    assert comp is not None and comp.amplitude == pytest.approx(0.3, abs=0.05)
