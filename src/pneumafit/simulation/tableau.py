"""Butcher tableaus of the fixed-step explicit Runge-Kutta methods."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Stability radii already computed, by (method's coefficients, angle).
_RADII: dict[tuple[bytes, bytes, float], float] = {}


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

    def amplification(self, z: complex) -> complex:
        """R(z) = 1 + z b^T (I - z A)^-1 1: one step's factor on y' = lambda y, z = h lambda."""
        n = self.b.size
        k = np.linalg.solve(np.eye(n) - z * self.a, np.ones(n, dtype=complex))
        return complex(1.0 + z * (self.b @ k))

    def stability_radius(self, angle: float) -> float:
        """Largest r with |R(rho e^(i angle))| <= 1 for every rho in (0, r].

        The stable h |lambda| of a mode lambda = |lambda| e^(i angle): on the
        negative real axis (angle pi) the method's real-axis limit
        (:attr:`stability`, to its three digits), on the imaginary axis
        (pi / 2, an undamped oscillation) sqrt(3) for Kutta's RK3, 2 sqrt(2)
        for RK4 and 0 for Heun's method. Found on a 1e-3 grid up to 8, then
        by bisection to 1e-10.

        Parameters
        ----------
        angle : float
            Direction of the mode in the complex plane (rad), in [pi / 2, pi].
            At pi (a decaying real mode, e.g. a first-order spool lag) the
            radius is :attr:`stability` by definition, so that every real
            mode is held to the same limit as the model's own rate bound.
        """
        if abs(angle - math.pi) < 1e-12:
            return self.stability
        # keyed by the coefficients, not the name: a user's tableau may reuse one
        key = (self.a.tobytes(), self.b.tobytes(), round(float(angle), 12))
        if key in _RADII:
            return _RADII[key]
        ray = complex(math.cos(angle), math.sin(angle))

        def stable(rho: float) -> bool:
            return abs(self.amplification(rho * ray)) <= 1.0 + 1e-12

        lo = 0.0
        hi = math.nan
        for rho in np.arange(1e-3, 8.0, 1e-3):
            if not stable(float(rho)):
                hi = float(rho)
                break
            lo = float(rho)
        if math.isnan(hi):
            _RADII[key] = lo
            return lo
        while hi - lo > 1e-10:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if stable(mid) else (lo, mid)
        _RADII[key] = lo
        return lo


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
