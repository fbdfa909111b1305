"""Butcher tableaus of the fixed-step explicit Runge-Kutta methods."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Tableau:
    """An explicit Runge-Kutta method.

    Attributes: stage matrix a, weights b, nodes c, order, and the stability
    limit on the negative real axis (largest h |lambda| of a decaying mode).
    """

    name: str
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    order: int
    stability: float


RK4 = Tableau(
    "rk4",
    np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]], dtype=float),
    np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    np.array([0.0, 0.5, 0.5, 1.0]),
    4,
    2.785,
)

# Dormand-Prince 5(4), used here as a fixed-step 5th-order method (the 7th,
# FSAL stage has weight 0 in the 5th-order solution and is dropped).
DP5 = Tableau(
    "dp5",
    np.array(
        [
            [0, 0, 0, 0, 0, 0],
            [1 / 5, 0, 0, 0, 0, 0],
            [3 / 40, 9 / 40, 0, 0, 0, 0],
            [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
            [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
            [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
        ],
        dtype=float,
    ),
    np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]),
    np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1]),
    5,
    3.3,
)

# Kutta's third-order method: 3 stages, last node at the step's end (c = 1),
# which the event detection needs.
KUTTA3 = Tableau(
    "kutta3",
    np.array([[0, 0, 0], [0.5, 0, 0], [-1.0, 2.0, 0]], dtype=float),
    np.array([1 / 6, 2 / 3, 1 / 6]),
    np.array([0.0, 0.5, 1.0]),
    3,
    2.513,
)

# Heun's method, second order: for convergence-order tests.
HEUN = Tableau(
    "heun",
    np.array([[0, 0], [1, 0]], dtype=float),
    np.array([0.5, 0.5]),
    np.array([0.0, 1.0]),
    2,
    2.0,
)

TABLEAUS = {t.name: t for t in (RK4, DP5, KUTTA3, HEUN)}
