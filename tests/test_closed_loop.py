"""State feedback in the compiled simulator (paper's "Simulation" section)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from pneumafit.analysis import closed_loop_poles, equilibrium, itae_poles, linearize, place
from pneumafit.analysis.closed_loop import compare_controllers, design_controller, read_plant_file
from pneumafit.analysis.linear import deadband_compensation, numerical_jacobian
from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.simulation import Experiment, Simulator, StateFeedback
from pneumafit.virtual_rig import DEMO_TRUTH


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pneumafit", *args], capture_output=True,
                          text=True, timeout=600)  # fmt: skip


# friction reduced to its viscous part, as in the linear model
PARAMS = parameter_vector({"rod": 0.02, "dead_volume_P": 2.5e-5, "dead_volume_N": 3e-5,
                           "friction_static": 0.0, "friction_coulomb": 0.0})  # fmt: skip


@pytest.mark.parametrize(("order", "plant"), [(4, "polytropic"), (6, "constant-lambda")])
def test_small_perturbation_follows_the_linear_closed_loop(order, plant):
    """From a 10 nm offset, the nonlinear model under u = u_e - K (x - x_e)
    follows exp((A - B K) t) dx0, the designed linear closed loop.

    Tolerance 1 % of each state's largest linear excursion over 0.2 s: the
    valve law's curvature over the 2e-4 V command change is ~0.02 % (the
    leakage sigmoid's sigma''/sigma' times the change), the integration error
    at 0.1 ms is smaller still, and a wrong sign or slot in the controller
    would be off by 100 %.
    """
    lin = linearize(PARAMS, 0.25, order=order, lambda_e=15.0)
    gain = place(lin, itae_poles(order, 3.0))
    eq = lin.equilibrium
    controller = StateFeedback(gain=gain[0], x_e=eq.state(), u_e=eq.u)
    t = np.arange(0.0, 0.2, 1e-3)
    dy0 = 1e-8
    exp = Experiment(time=t, kind="step", y_ref=np.full(t.size, 0.25), controller=controller,
                     initial={"y": 0.25 + dy0, "p_P": eq.p_P, "p_N": eq.p_N, "T_P": eq.T,
                              "T_N": eq.T})  # fmt: skip
    names = ["y", "v", "p_N", "p_P", "T_N", "T_P"][:order]
    r = Simulator(plant, step=1e-4, channels=names).simulate(PARAMS, exp)
    assert r.ok
    a_cl = lin.A - lin.B @ gain
    dx0 = np.zeros(order)
    dx0[0] = dy0
    linear = np.array([expm(a_cl * ti) @ dx0 for ti in t])
    for j, name in enumerate(names):
        nonlinear = r[name] - eq.state()[j]
        scale = np.abs(linear[:, j]).max()
        assert np.abs(nonlinear - linear[:, j]).max() < 0.01 * scale, name


def test_state_feedback_law_is_applied_as_declared():
    """u = clip(u_e - K (x - x_e), -umax, umax) with the position following y_ref."""
    controller = StateFeedback(gain=[100.0, 0, 0, 0], x_e=[0.25, 0, 4e5, 4e5, 293.15, 293.15],
                               u_e=0.5, umax=2.0)  # fmt: skip
    t = np.arange(0.0, 0.01, 1e-3)
    exp = Experiment(time=t, kind="step", y_ref=np.full(t.size, 0.26), controller=controller,
                     initial={"y": 0.25, "p_P": 4e5, "p_N": 4e5})  # fmt: skip
    r = Simulator("polytropic", channels=["u_P", "u_N"]).simulate(
        {"friction_static": 1e9, "friction_coulomb": 0.0}, exp
    )
    # y - y_ref = -0.01 m: u = 0.5 + 100 * 0.01 = 1.5 V (within the 2 V limit)
    np.testing.assert_allclose(r["u_P"], 1.5, rtol=1e-12)
    np.testing.assert_allclose(r["u_N"], -1.5, rtol=1e-12)
    with pytest.raises(ValueError, match="gains"):
        StateFeedback(gain=[1.0, 2.0], x_e=[0.0] * 6, u_e=0.0)


# --------------------------------------------------------------------------
# Designs on the demo rig's valve (overlap 0.3 V, centre leakage), run on the
# rig's nonlinear truth (variable lambda, Sutherland air, stiction)
# --------------------------------------------------------------------------

DEMO = Path(__file__).resolve().parents[1] / "data" / "demo"
W0 = 20.0  # rad/s: ~ the largest keeping a 30-mm step within 9 V (largest_w0 gives 19.8)
STEPS = (0.03, 0.0, -0.03, 0.0)  # offsets from half stroke (m)


@pytest.fixture(scope="module")
def demo_plant(tmp_path_factory) -> Path:
    """A rig truth of the fitted models' laws on the demo rig (DEMO_TRUTH,
    Sutherland air), as the virtual rig writes it without ``--truth``. The
    committed demo's truth.json is an independent truth, which the compiled
    model cannot run as a plant."""
    path = tmp_path_factory.mktemp("plant") / "truth.json"
    doc = {"format": "pneumafit-truth", "version": 1,
           "model": {"heat": "convection", "air_properties": "sutherland", "effects": {}},
           "parameters": dict(DEMO_TRUTH)}  # fmt: skip
    path.write_text(json.dumps(doc))
    return path


@pytest.fixture(scope="module")
def demo_truth(demo_plant):
    structure, values = read_plant_file(demo_plant)
    return structure, parameter_vector(values)


@pytest.fixture(scope="module")
def demo_runs(demo_truth):
    structure, p = demo_truth
    return compare_controllers(p, w0=W0, steps=STEPS, hold=1.5, plant=structure)


@pytest.mark.parametrize("placement", ["dominant", "itae"])
@pytest.mark.parametrize("order", [4, 6])
def test_compensated_design_places_the_requested_poles(demo_truth, order, placement):
    """eig(A - B K) of the compensated linear model are the requested poles.

    Relative error 1e-8: K and the eigenvalues are computed in 60-digit
    arithmetic and K is rounded to double (relative 1e-16 per entry); the
    non-normal 6-state closed loop amplifies that rounding to ~1e-11 at most.
    """
    _, p = demo_truth
    design = design_controller(p, 0.25, order=order, w0=W0, placement=placement)
    assert design.compensation is not None
    placed = closed_loop_poles(design.model, design.gain[None, :])
    for pole in design.poles:
        assert np.min(np.abs(placed - pole)) / abs(pole) < 1e-8


@pytest.mark.parametrize("order", [4, 6])
def test_linear_input_column_matches_the_compiled_rhs(demo_truth, order):
    """B of the uncompensated and of the compensated plant against central
    differences of the compiled right-hand side, the compensation applied by
    the compiled state-feedback law (kernel ``commands``). Tolerance 1e-6 of
    max |B|: the analytic valve gains are central differences at 1e-6 V
    (truncation ~(1e-6 / w)^2 ~ 1e-9 with w = 0.036 V), the Jacobian's step
    1e-6 w has a rounding error ~1e-16 |f| / (1e-6 w |B|) < 1e-8."""
    _, p = demo_truth
    comp = deadband_compensation(p, 0.25)
    for c in (None, comp):
        lin = linearize(p, 0.25, order=order, compensation=c)
        _, b_num = numerical_jacobian(p, lin.equilibrium, order=order, compensation=c)
        scale = np.abs(lin.B).max()
        assert np.abs(b_num - lin.B).max() < 1e-6 * scale
    # the compensation multiplies the input column by c'(v_e) ~ 10: the open
    # valve's gain / the centre leakage's
    plain = linearize(p, 0.25, order=order).B
    ratio = linearize(p, 0.25, order=order, compensation=comp).B[3, 0] / plain[3, 0]
    assert ratio == pytest.approx(comp.slope(comp.inverse(equilibrium(p, 0.25).u)), rel=1e-12)
    assert 5.0 < ratio < 20.0


def test_compensation_matches_the_open_valve_gain(demo_truth):
    """c'(v_e) G(u_e) equals the mean open-valve force gain just outside the
    dead band (the definition of the width), and c(v_e) = u_e."""
    from pneumafit.analysis.linear import _force_gain
    from pneumafit.physics.valve import OPENING_SMOOTHING

    _, p = demo_truth
    eq = equilibrium(p, 0.25)
    comp = deadband_compensation(p, 0.25)
    v_e = comp.inverse(eq.u)
    assert comp(v_e) == pytest.approx(eq.u, abs=1e-13)
    u_open = comp.amplitude + 2 * OPENING_SMOOTHING
    target = 0.5 * (_force_gain(p, u_open, eq.p_P, eq.p_N, 0.25)
                    + _force_gain(p, -u_open, eq.p_P, eq.p_N, 0.25))  # fmt: skip
    got = comp.slope(v_e) * _force_gain(p, eq.u, eq.p_P, eq.p_N, 0.25)
    assert got == pytest.approx(target, rel=1e-9)


def test_nonlinear_closed_loop_tracks_steps_within_the_stiction_band(demo_runs):
    """Both designs move the piston towards each target, stop within the
    stiction band (the largest error at which the loop can hold the piston
    stuck, derived in ``stiction_band``), without divergence or saturation.

    Stiction (50 N) with proportional state feedback leaves a residual error:
    on the demo rig 3-13 mm for 30-mm steps, against bands of 16 and 23 mm.
    """
    for r in demo_runs:
        assert r.ok, r.message
        assert r.max_abs_u < 10.0 and r.saturation == 0.0
        assert np.all(np.abs(r.channels["y"] - 0.25) < 0.045)  # no run to an end stop
        for s in r.steps:
            assert abs(s.final_error) <= r.stiction_band, (r.name, s)
            assert abs(s.final_error) < 0.6 * abs(s.size), (r.name, s)  # it moved
            assert s.settling_time < 1.0  # the motion stops well within the hold
            assert s.overshoot < 0.1 * abs(s.size)


def test_uncompensated_design_is_held_by_stiction(demo_truth):
    """Without compensation the band (47 mm) exceeds the 30-mm step: the
    piston never breaks away, as stiction_band predicts."""
    structure, p = demo_truth
    (r,) = compare_controllers(p, w0=W0 / 2, steps=(0.03,), hold=1.0, plant=structure,
                               orders=(4,), compensate=False)  # fmt: skip
    assert r.ok and r.stiction_band > 0.03
    assert np.all(r.channels["y"] == 0.25)


def test_air_mass_is_positive_and_conserved(demo_runs, demo_truth):
    """Air drawn from supply minus air exhausted equals the air gained by the
    chambers, m = P V / (r T), at every sample: the accounts integrate the
    same valve flows as the pressures and temperatures, so they differ only by
    the method's error on the nonlinear invariant P V / T (measured 1e-7 of
    the chambers' mass with RK3 at 1 ms; a lost or doubled flow term would be
    ~1e-2). The rest before the first step and the
    per-step masses add up to the total."""
    from pneumafit.physics.air import R_AIR
    from pneumafit.physics.geometry import chamber_volumes, piston_areas

    _, p = demo_truth
    s_p, s_n = piston_areas(p[P["bore"]], p[P["rod"]])
    for r in demo_runs:
        ch = r.channels
        v_p, v_n = chamber_volumes(ch["y"], p[P["stroke"]], s_p, s_n, p[P["dead_volume_P"]],
                                   p[P["dead_volume_N"]])  # fmt: skip
        mass = ch["p_P"] * v_p / (R_AIR * ch["T_P"]) + ch["p_N"] * v_n / (R_AIR * ch["T_N"])
        balance = ch["m_supply"] - ch["m_exhaust"] - (mass - mass[0])
        assert np.abs(balance).max() < 1e-6 * mass[0]
        assert r.air_mass > 0 and all(s.air_mass > s.leakage_mass > 0 for s in r.steps)
        rest = ch["m_supply"][np.searchsorted(r.time, r.steps[0].start - 1e-9) - 1]
        assert rest + sum(s.air_mass for s in r.steps) == pytest.approx(r.air_mass, rel=1e-9)
        assert r.exergy == pytest.approx(
            r.air_mass * R_AIR * 293.15 * np.log(7e5 / 1.013e5), rel=1e-12
        )


def test_closed_loop_command_reports_air_per_controller(tmp_path, demo_plant):
    """The command on the demo rig's truth writes closed_loop.json with the air
    mass and exergy per controller and step, and the figures; bad input is a
    message with exit status 2."""
    out = tmp_path / "cl"
    run = cli("closed-loop", str(demo_plant), "--out", str(out), "--w0", "20",
              "--steps", "30,-30 mm", "--hold", "1.5 s")  # fmt: skip
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "closed_loop.json").read_text())
    assert [c["name"] for c in doc["controllers"]] == ["order 4", "order 6"]
    for c in doc["controllers"]:
        assert c["ok"] and c["air_mass_kg"] > 0 and c["exergy_J"] > 0
        assert len(c["steps"]) == 2 and all(s["air_mass_kg"] > 0 for s in c["steps"])
    for name in doc["figures"]:
        assert (out / name).stat().st_size > 0
    bad = cli("closed-loop", str(demo_plant), "--out", str(out), "--steps", "300 mm")
    assert bad.returncode == 2 and "inside the stroke" in bad.stderr
    # the demo's independent truth is not a plant the compiled model can run
    bad = cli("closed-loop", str(DEMO / "truth.json"), "--out", str(out))
    assert bad.returncode == 2 and "independent truth ('demo'" in bad.stderr
    assert "Traceback" not in bad.stderr
    assert "Traceback" not in bad.stderr
    bad = cli("closed-loop", str(tmp_path / "none.json"), "--out", str(out))
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
