"""Cylinder geometry, following the campaign-format conventions.

Piston position y runs from 0 (fully retracted, chamber P smallest) to the
stroke L. Chamber P is the full-bore side, chamber N the rod side:

    S_P = pi D^2 / 4,  S_N = pi (D^2 - d^2) / 4
    V_P(y) = V_0P + S_P y,  V_N(y) = V_0N + S_N (L - y)

Heat-exchange areas (paper eqs. 6-7 use A(y) without giving it). Each dead
volume is treated as an extra length of bore, l_0 = V_0 / S, so that

    A_P(y) = S_P (head) + S_P (piston face) + pi D (l_0P + y)
    A_N(y) = S_N (head) + S_N (piston face) + pi D (l_0N + L - y)
             + pi d (l_0N + L - y)     (rod surface)

A rig's walls need not exchange heat alike: the heads, piston face and rod
(of another metal, or at another temperature than the barrel) may count for
less. The share c (parameter ``heat_area_ends``, 1 by default; 0 keeps the
bore wall only) multiplies the heads, the piston faces and the rod surface:

    A_P(y) = 2 c S_P + pi D (l_0P + y)
    A_N(y) = 2 c S_N + pi (D + c d) (l_0N + L - y)

All lengths in m, areas in m^2, volumes in m^3.
"""

from __future__ import annotations

import math

from pneumafit.numba_stamp import njit
from pneumafit.physics.friction import FASTMATH


@njit(cache=True, fastmath=FASTMATH)
def piston_areas(bore: float, rod: float) -> tuple[float, float]:
    """Piston areas (S_P, S_N) in m^2 for bore D and rod diameter d (m)."""
    s_p = 0.25 * math.pi * bore * bore
    s_n = 0.25 * math.pi * (bore * bore - rod * rod)
    return s_p, s_n


@njit(cache=True, fastmath=FASTMATH)
def chamber_volumes(
    y: float, stroke: float, s_p: float, s_n: float, v0_p: float, v0_n: float
) -> tuple[float, float]:
    """Chamber volumes (V_P, V_N) in m^3 at piston position y (m)."""
    return v0_p + s_p * y, v0_n + s_n * (stroke - y)


@njit(cache=True, fastmath=FASTMATH)
def exchange_areas(
    y: float,
    stroke: float,
    bore: float,
    rod: float,
    v0_p: float,
    v0_n: float,
    ends: float = 1.0,
) -> tuple[float, float]:
    """Gas-to-wall heat-exchange areas (A_P, A_N) in m^2 at position y (m).

    Heads, piston faces, bore wall (dead volume as extra bore length) and, on
    the N side, the rod surface; heads, faces and rod counted with the share
    ``ends`` (-). See the module docstring.
    """
    s_p = 0.25 * math.pi * bore * bore
    s_n = 0.25 * math.pi * (bore * bore - rod * rod)
    l_p = v0_p / s_p + y
    l_n = v0_n / s_n + (stroke - y)
    a_p = 2.0 * ends * s_p + math.pi * bore * l_p
    a_n = 2.0 * ends * s_n + math.pi * (bore + ends * rod) * l_n
    return a_p, a_n
