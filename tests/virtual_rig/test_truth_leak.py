"""The independent truth's external leak (pneumafit.virtual_rig.truth.leak): law, balance, input."""

from __future__ import annotations

import copy
import math
import re

import numpy as np
import pytest

from pneumafit.campaign import PneumafitInputError
from pneumafit.models import parameter_dict, parameter_vector
from pneumafit.simulation import Experiment
from pneumafit.virtual_rig.truth import PRESETS, OrificeLeak, TruthConfig, TruthSimulator
from pneumafit.virtual_rig.truth.constants import R_GAS, RHO_REF, T_REF
from pneumafit.virtual_rig.truth.simulator import _Plant
from pneumafit.virtual_rig.virtual import DEMO_TRUTH

PAR = parameter_dict(parameter_vector(DEMO_TRUTH))


def _config(leak: dict | None) -> TruthConfig:
    data = copy.deepcopy(dict(PRESETS["demo-clean"]))
    data["valve"]["leak"] = {"shape": "none"}
    if leak is not None:
        data["external_leak"] = leak
    return TruthConfig.from_dict(data)


def test_choked_leak_is_proportional_to_the_absolute_pressure() -> None:
    """Above P_atm / b the leak is choked: q = C rho0 P sqrt(T_ref / T), exactly
    (closed form; tolerance: rounding)."""
    leak = OrificeLeak(C_P=1.41e-11, C_N=2.63e-11, b=0.47)
    q, t = leak.flow("N", 6.0e5, 310.0, 1.013e5, 293.15)
    assert t == 310.0
    assert q == pytest.approx(2.63e-11 * RHO_REF * 6.0e5 * math.sqrt(T_REF / 310.0), rel=1e-12)
    # air drawn in below the atmosphere, at the ambient temperature
    q_in, t_in = leak.flow("P", 0.9e5, 280.0, 1.013e5, 293.15)
    assert q_in < 0.0 and t_in == 293.15


def test_leak_leaves_the_chamber_mass_balance() -> None:
    """A closed valve (no centre leak) on a blocked chamber: the mass the
    chamber loses, d(PV / rT)/dt from the simulator's dP/dt and dT/dt, is
    the leak flow (algebra of the balance; 1e-9 relative: rounding)."""
    config = _config({"model": "orifice", "C_P": 1.41e-11, "C_N": 2.63e-11})
    plant = _Plant(config, PAR)
    y, p, t = 0.2, 5.3e5, 301.0
    vol = plant.volume("N", y)
    dp, dt, q_valve = plant.blocked(np.array([p, t, 0.0]), 0.0, "N", y)
    dm = vol / R_GAS * (dp / t - p * dt / t**2)
    q_leak, _ = config.external_leak.flow("N", p, t, plant.p_e, plant.t_amb)
    assert q_valve == 0.0
    assert dm == pytest.approx(-q_leak, rel=1e-9)


def test_leak_empties_a_held_chamber_and_spares_the_flow_tests() -> None:
    """With the valve closed the leaking chamber's pressure falls; without a
    leak it stays (centre leak off); the flow test's valve flow is unchanged."""
    n = 1001
    t = np.arange(n) * 1e-3
    exp = Experiment(t, "charge", chamber="N", u_N=np.zeros(n),
                     initial={"y": 0.2, "p_N": 6.0e5, "T_N": 293.15}, name="hold")  # fmt: skip
    tight = TruthSimulator(_config(None)).simulate(PAR, exp)
    leaky = TruthSimulator(_config({"model": "orifice", "C_P": 0.0, "C_N": 2.63e-11}))
    sim = leaky.simulate(PAR, exp)
    assert tight.ok and sim.ok
    assert abs(tight["p_N"][-1] - 6.0e5) < 1.0
    assert sim["p_N"][-1] < 6.0e5 - 5.0e3
    flow = Experiment(t[:20], "flow", chamber="P", u_P=np.full(20, 5.0),
                      p_chamber=np.full(20, 3.0e5), name="flow")  # fmt: skip
    np.testing.assert_array_equal(
        TruthSimulator(_config(None)).simulate(PAR, flow)["qm_P"], leaky.simulate(PAR, flow)["qm_P"]
    )


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"model": "orifice", "C_P": -1e-12, "C_N": 1e-11}, "external_leak: external leak "
         "'orifice': C_P: expected a conductance in [0, 1e-8)"),
        ({"model": "orifice", "C_P": 1e-11}, "external_leak.C_N: missing"),
        ({"model": "pipe", "C_P": 1e-11, "C_N": 1e-11}, "external_leak.model: expected one of"),
        ({"model": "orifice", "C_P": 1e-11, "C_N": 1e-11, "b": 1.2}, "b: expected a ratio"),
    ],
)  # fmt: skip
def test_bad_leak_input_names_the_key(table: dict, message: str) -> None:
    with pytest.raises(PneumafitInputError, match=re.escape(message)):
        _config(table)


def test_leak_round_trips() -> None:
    config = TruthConfig.from_dict(copy.deepcopy(dict(PRESETS["demo"])))
    again = TruthConfig.from_dict(config.as_dict())
    assert again == config and config.external_leak == OrificeLeak(C_P=1.41e-11, C_N=2.63e-11,
                                                                   b=0.47)  # fmt: skip
