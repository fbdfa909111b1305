"""The friction-test force balance against analytic limits (model.py).

The bristle state is integrated exactly for a velocity held over each
interval, so at constant velocity it must match the closed-form LuGre
solution to round-off, whatever the step: tolerances are 1e-9 relative.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneumafit.frictiontest.model import (
    KERNEL_ORDER,
    FrictionTest,
    estimate_velocity,
    friction_test_force,
)

AREA = math.pi * 0.025**2 / 4.0
VALUES = {
    "friction_static": 6.0,
    "friction_coulomb": 4.0,
    "friction_viscous": 30.0,
    "stribeck_velocity": 2e-3,
    "friction_stiffness": 1e5,
    "friction_damping": 0.0,
    "seal_friction_coefficient": 0.0,
    "friction_asymmetry": 0.0,
    "area_factor": 1.0,
}


def make_test(time: np.ndarray, velocity: np.ndarray, gauge: float = 3e5) -> FrictionTest:
    dp = np.full(time.size, gauge)
    return FrictionTest("t", "fit", time, velocity, dp, dp * AREA, np.zeros(time.size))


def test_steady_sliding_is_the_stribeck_curve() -> None:
    t = np.arange(0.0, 1.0, 0.01)
    for v in (-0.012, -0.002, 0.0005, 0.01):
        pred = friction_test_force(make_test(t, np.full(t.size, v)), VALUES)[0]
        g = 4.0 + 2.0 * math.exp(-((v / 2e-3) ** 2))
        expected = 3e5 * AREA - (math.copysign(g, v) + 30.0 * v)
        np.testing.assert_allclose(pred, expected, rtol=1e-9)


def test_pre_sliding_follows_the_closed_form() -> None:
    # from steady backward sliding (z = -g / sigma0), move forward at 1 mm/s:
    # dz/dx = 1 - sigma0 z / g, so z(x) = g/s0 + (z0 - g/s0) exp(-s0 x / g)
    values = {**VALUES, "friction_static": 4.0, "friction_viscous": 0.0}  # g = 4 N flat
    t = np.arange(0.0, 0.2, 0.003)  # coarse step: exact integration must not care
    v = np.where(t < 0.05, -1e-3, 1e-3)
    pred = friction_test_force(make_test(t, v), values)[0]
    friction = 3e5 * AREA - pred
    s0, g = 1e5, 4.0
    after = t >= 0.05
    x = (t[after] - t[after][0] + 0.003) * 1e-3  # forward travel at each sample
    z = g / s0 + (-g / s0 - g / s0) * np.exp(-s0 * x / g)
    np.testing.assert_allclose(friction[after], s0 * z, rtol=1e-9)
    # the initial stiffness of a reversal is 2 sigma0 (LuGre, from the
    # opposite steady state); over the first step's 3 um it is the secant
    step = 0.003e-3
    secant = 2 * s0 * (1 - math.exp(-s0 * step / g)) / (s0 * step / g)
    assert (friction[after][0] - friction[~after][-1]) / step == pytest.approx(secant, rel=1e-9)


@pytest.mark.parametrize(
    ("name", "value", "check"),
    [
        ("area_factor", 0.9, lambda base, new, v: new - base == pytest.approx(-0.1 * 3e5 * AREA)),
        ("seal_friction_coefficient", 1e-5,
         lambda base, new, v: base - new == pytest.approx(np.sign(v) * 3.0)),
        ("friction_asymmetry", 0.2,
         lambda base, new, v: base - new == pytest.approx(0.2 * 4.0)),
    ],
)  # fmt: skip
def test_effects(name: str, value: float, check) -> None:
    t = np.arange(0.0, 0.5, 0.01)
    for v in (-0.01, 0.01):
        test = make_test(t, np.full(t.size, v))
        base = friction_test_force(test, VALUES)[0][-1]
        new = friction_test_force(test, {**VALUES, name: value})[0][-1]
        assert check(base, new, v)


def test_kernel_order_names_every_value() -> None:
    assert set(KERNEL_ORDER) == set(VALUES)


def test_velocity_of_a_quadratic_is_exact() -> None:
    t = np.arange(0.0, 3.0, 0.01)
    y = 0.002 + 0.01 * t - 0.003 * t**2
    v = estimate_velocity(t, y)
    np.testing.assert_allclose(v[10:-10], 0.01 - 0.006 * t[10:-10], rtol=1e-6, atol=1e-9)
