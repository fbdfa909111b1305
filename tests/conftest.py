"""Shared fixtures for the physics and simulator tests."""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from pneumafit.simulation import PD, Experiment
from pneumafit.warmup import AUTO_ENV

# The commands' warm-up at first use (pneumafit.warmup.ensure_warm) is off in
# the suite: its commands must print only their own output, and the compiler
# runs where each test needs it, as before. tests/test_warmup.py turns it on
# where it is the subject.
os.environ.setdefault(AUTO_ENV, "0")


@pytest.fixture(scope="session")
def step_experiment() -> Experiment:
    """4-s closed-loop step test at 1 kHz around half stroke (the benchmark's)."""
    t = np.arange(0.0, 4.0005, 1e-3)
    y_ref = np.where(t < 0.2, 0.25, np.where(t < 2.0, 0.35, 0.25))
    return Experiment(
        time=t,
        kind="step",
        y_ref=y_ref,
        controller=PD(kp=60.0, kd=4.0),
        initial={"y": 0.25, "p_P": 4.0e5, "p_N": 4.0e5 * 0.8 / 0.6},
        name="step",
    )


@pytest.fixture(scope="session")
def charge_experiment() -> Experiment:
    """Blocked-piston charge of chamber P: 0.3 s at 8 V, then 2.7 s relaxation."""
    t = np.arange(0.0, 3.0005, 1e-3)
    u = np.where((t > 0.1) & (t < 0.4), 8.0, 0.0)
    return Experiment(
        time=t, kind="charge", chamber="P", u_P=u, initial={"y": 0.2, "p_P": 1.013e5},
        name="charge",
    )  # fmt: skip


@pytest.fixture
def outside_parts() -> Iterator[tuple[Any, Any]]:
    """Yield (``models.parts``, ``models.layout``) for a test that registers
    parts from outside the package; remove them, and the parameters they
    appended, afterwards."""
    from pneumafit.models import layout, parts

    effects, heat = set(parts.EFFECTS), set(parts.HEAT_LAWS)
    friction, valve = set(parts.FRICTION_LAWS), set(parts.VALVE_LAWS)
    n = layout.n_parameters()
    yield parts, layout
    for name in set(parts.VALVE_LAWS) - valve:
        parts.unregister_valve_law(name)
    for name in set(parts.EFFECTS) - effects:
        parts.unregister_effect(name)
    for name in set(parts.HEAT_LAWS) - heat:
        parts.unregister_heat_law(name)
    for name in set(parts.FRICTION_LAWS) - friction:
        parts.unregister_friction_law(name)
    while layout.n_parameters() > n:
        parts.unregister_parameter(layout.PARAMETER_NAMES[-1])
