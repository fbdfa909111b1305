"""State feedback in the compiled simulator (paper's "Simulation" section)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from pneumafit.analysis import itae_poles, linearize, place
from pneumafit.models.parameters import parameter_vector
from pneumafit.simulation import Experiment, Simulator, StateFeedback

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
