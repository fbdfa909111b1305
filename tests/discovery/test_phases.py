"""Phase labelling of a test: filling, emptying, relaxation, motion, rest."""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.campaign import Recording
from pneumafit.discovery import PHASES, PhaseRules, label_phases
from pneumafit.discovery.phases import phase_interior
from pneumafit.simulation import Experiment, Simulator

T = np.arange(0.0, 3.0005, 1e-3)


def between(a: float, b: float) -> np.ndarray:
    return (T >= a) & (T <= b)


@pytest.fixture(scope="module")
def charge() -> Recording:
    """Charge of P at 8 V from 0.5 s to 0.8 s, with 400-Pa sensor noise.

    The default valve fills the blocked chamber to supply by ~0.72 s: from
    then to 0.8 s the valve is open on a saturated chamber (rest).
    """
    u = np.where((T >= 0.5) & (T < 0.8), 8.0, 0.0)
    exp = Experiment(T, "charge", chamber="P", u_P=u, initial={"y": 0.2, "p_P": 1.013e5})
    sim = Simulator("convection").simulate({}, exp)
    assert sim.ok
    p = sim["p_P"] + np.random.default_rng(3).normal(0.0, 400.0, T.size)
    return Recording.from_arrays(
        T, {"u_P": u, "p_P": p}, kind="charge", chamber="P", piston_position=0.2, file="c.h5"
    )


def test_charge_phases(charge: Recording) -> None:
    labels = label_phases(charge)
    assert set(labels) <= set(PHASES)
    # away from the transitions by the 50-ms fit window
    assert np.all(labels[between(0.0, 0.47)] == "rest")
    assert np.all(labels[between(0.505, 0.68)] == "filling")
    assert np.all(labels[between(0.74, 0.795)] == "rest")  # open, saturated
    assert np.all(labels[between(0.8, 3.0)] == "relaxation")
    assert not np.any(np.isin(labels, ["motion", "emptying"]))  # blocked piston


def test_relaxation_time_ends_relaxation(charge: Recording) -> None:
    labels = label_phases(charge, PhaseRules(relaxation_time=1.0))
    # the valve was last open at 0.799 s
    assert np.all(labels[between(0.8, 1.79)] == "relaxation")
    assert np.all(labels[between(1.81, 3.0)] == "rest")


def test_discharge_phases() -> None:
    u = np.where((T >= 0.5) & (T < 0.8), -8.0, 0.0)
    exp = Experiment(T, "discharge", chamber="N", u_N=u, initial={"y": 0.2, "p_N": 7e5})
    sim = Simulator("convection").simulate({}, exp)
    rec = Recording.from_arrays(
        T, {"u_N": u, "p_N": sim["p_N"]}, kind="discharge", chamber="N", piston_position=0.2
    )
    labels = label_phases(rec)
    assert np.all(labels[between(0.0, 0.47)] == "rest")
    assert np.all(labels[between(0.505, 0.6)] == "emptying")
    assert np.all(labels[between(0.8, 3.0)] == "relaxation")


def test_step_phases() -> None:
    """A synthetic step: the valve opens at 0.3 s on a stuck piston, P fills and
    N empties until the piston breaks away at 0.4 s, moves at 0.2 m/s to 0.9 s,
    stops with the valve still open (pressures steady) until 1.0 s, then the
    valve returns to the centre."""
    u_p = np.where((T >= 0.3) & (T < 1.0), 4.0, 0.1)
    build = np.clip(T - 0.3, 0.0, 0.1)  # s of pressure build-up
    p_p = 3.0e5 + 1.0e6 * build
    p_n = 4.0e5 - 1.0e6 * build
    y = 0.2 + 0.2 * np.clip(T - 0.4, 0.0, 0.5)
    rec = Recording.from_arrays(
        T, {"u_P": u_p, "u_N": -u_p, "p_P": p_p, "p_N": p_n, "y": y}, kind="step"
    )
    labels = label_phases(rec)
    assert np.all(labels[between(0.0, 0.29)] == "rest")
    assert np.all(labels[between(0.33, 0.37)] == "filling")  # before emptying (N)
    assert np.all(labels[between(0.42, 0.88)] == "motion")
    assert np.all(labels[between(0.93, 0.99)] == "rest")  # open, steady, at rest
    assert np.all(labels[between(1.03, 3.0)] == "relaxation")

    # a recorded velocity takes precedence over the position's rate
    v = np.where(between(0.4, 0.9), 0.2, 0.0)
    rec_v = Recording.from_arrays(T, {**rec.channels, "v": v}, kind="step")
    labels_v = label_phases(rec_v)
    assert np.all(labels_v[between(0.4, 0.9)] == "motion")
    assert not np.any(labels_v[~between(0.4, 0.9)] == "motion")


def test_flow_test_phases() -> None:
    t = np.arange(0.0, 3.0, 0.01)
    u = np.repeat([-10.0, -0.2, 0.0, 0.2, 10.0, 5.0], 50)
    p = np.full(t.size, 4e5)  # held by the regulator
    rec = Recording.from_arrays(t, {"u_P": u, "p_P": p, "qm_P": u * 1e-4}, kind="flow", chamber="P")
    labels = label_phases(rec)
    expected = np.repeat(["emptying", "rest", "rest", "rest", "filling", "filling"], 50)
    np.testing.assert_array_equal(labels, expected)


def test_phase_interior() -> None:
    labels = np.array(["rest"] * 5 + ["filling"] * 6 + ["rest"] * 5)
    inside = phase_interior(labels, 2)
    expected = [1, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 1]  # 5 rest, 6 filling, 5 rest
    np.testing.assert_array_equal(inside, np.array(expected, dtype=bool))


@pytest.mark.parametrize(
    "rules",
    [
        {"open_command": 0.0},
        {"speed": -1.0},
        {"pressure_rate": float("nan")},
        {"smoothing": 0.0},
        {"relaxation_time": 0.0},
    ],
)
def test_bad_rules(rules: dict[str, float]) -> None:
    with pytest.raises(ValueError, match="phase rules"):
        PhaseRules(**rules)
