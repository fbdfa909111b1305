"""Piston friction and end stops.

Two laws, chosen by :attr:`pneumafit.models.structure.ModelStructure.friction`:
the switch model (``"switch"``, the default, below) and LuGre (``"lugre"``,
:func:`lugre_friction`, with a bristle state and no stuck mode).

Law ``"switch"``: the *switch model* of stick-slip (Leine et al., Nonlinear Dynamics 16,
1998) with a Stribeck curve and a viscous term. The piston is in one of three
modes:

- stuck (mode 0): v = 0 exactly, y does not move, and the friction balances
  the driving force F_d (pressures, external load, end stops) as long as
  |F_d| <= F_s. The piston leaves this mode when |F_d| exceeds F_s, in the
  direction of F_d.
- sliding forwards or backwards (mode +1 / -1):

      F_f = mode [F_c + (F_s - F_c) exp(-(v / v_st)^2)] + b v

  The mode, not sign(v), sets the direction, so the right-hand side is smooth
  within a step; the piston leaves the mode when v reaches zero, and then
  sticks if |F_d| <= F_s, otherwise slides the other way.

Why not the alternatives: a smooth law (tanh) creeps under any force below
F_s; Karnopp's velocity band holds the piston but its switching inside
explicit Runge-Kutta stages makes the global error first order in the step
(measured here: 325 Pa at 0.5 ms against 14 Pa without dry friction); LuGre
adds a stiff bristle state. The switch model holds the piston exactly and,
with the mode changes located inside the step (the simulator does it), keeps
the integrator's accuracy.

Law ``"lugre"`` (Canudas de Wit, Olsson, Astrom and Lischinsky, IEEE Trans.
Automatic Control 40(3), 1995, eqs. 1-3 and 6, sigma2 = b): the contact is
held by elastic bristles of mean deflection z, with the same Stribeck curve,

    g(v) = F_c + (F_s - F_c) exp(-(v / v_st)^2)
    dz/dt = v - sigma0 |v| z / g(v)
    F_f = sigma0 z + sigma1 dz/dt + b v

so that a piston under a force below F_s only deflects the bristles
(pre-sliding, |z| <= g(0) / sigma0) and steady sliding gives
F_f = sign(v) g(v) + b v. There is no stuck mode: the piston always obeys
M dv/dt = F_d - F_f. The bristle relaxation rate sigma0 |v| / g(v) is stiff
(thousands of 1/s at 0.3-0.5 m/s); :func:`lugre_friction` limits it to a
multiple of the inverse integration step, see there.
"""

from __future__ import annotations

import math

from pneumafit.numba_stamp import njit

#: LLVM fast-math flags for the compiled physics. Only fused multiply-add:
#: "afn" (approximate sqrt/exp) made two uses of one flow differ by 1e-5 and
#: broke mass conservation; "nnan"/"ninf" would remove the failure checks.
FASTMATH = {"contract"}


@njit(cache=True, fastmath=FASTMATH)
def sliding_friction(
    velocity: float,
    direction: int,
    f_static: float,
    f_coulomb: float,
    f_viscous: float,
    v_stribeck: float,
) -> float:
    """Friction force (N) opposing a sliding piston.

    Parameters
    ----------
    velocity : float
        v (m/s).
    direction : {+1, -1}
        Sliding mode: +1 while the piston slides towards larger y.
    f_static, f_coulomb : float
        Static and Coulomb friction F_s >= F_c (N).
    f_viscous : float
        Viscous coefficient b (N s/m).
    v_stribeck : float
        Stribeck velocity v_st (m/s).

    Returns
    -------
    float
        F_f (N), positive when it acts towards smaller y.
    """
    r = velocity / v_stribeck
    return (
        direction * (f_coulomb + (f_static - f_coulomb) * math.exp(-r * r)) + f_viscous * velocity
    )


#: LuGre bristle relaxation rate limit, as a multiple c of the inverse
#: integration step 1/h (:func:`lugre_friction`). h c = 1 is inside every
#: explicit method's real-axis stability interval (Heun 2, Kutta3 2.51,
#: RK4 2.79, DP5 3.3) and the RK3 amplification at h lambda = -1 is 1/3.
LUGRE_RATE_LIMIT = 1.0

#: Smallest level g (N) the LuGre law divides by (F_s = F_c = 0 would divide
#: by zero; 1 uN is far below any seal's friction).
LUGRE_MIN_LEVEL = 1.0e-6


@njit(cache=True, fastmath=FASTMATH)
def lugre_friction(
    velocity: float,
    z: float,
    f_static: float,
    f_coulomb: float,
    f_viscous: float,
    v_stribeck: float,
    stiffness: float,
    damping: float,
    max_rate: float,
) -> tuple[float, float]:
    """Bristle rate and friction force of the LuGre law (Canudas de Wit et al. 1995).

    With g(v) = F_c + (F_s - F_c) exp(-(v / v_st)^2) (eq. 6) and the bristle
    relaxation rate a = sigma0 |v| / g(v):

        dz/dt = v - a z = a (z_ss - z),  z_ss = sign(v) g(v) / sigma0   (eq. 2)
        F_f = sigma0 z + sigma1 dz/dt + b v                          (eq. 3)

    Stiffness device. ``a`` exceeds 1/h (h = 1 ms, the fitting step) above
    |v| = g / (sigma0 h), 0.1 m/s at the defaults (g = 30 N, sigma0 =
    3e5 N/m), and an explicit Runge-Kutta step is unstable beyond
    h a ~ 2.5. The rate is therefore limited: a_eff = min(a, max_rate),
    max_rate = c / h (``LUGRE_RATE_LIMIT`` c = 1), in the relaxation form
    dz/dt = a_eff (z_ss - z). The steady state z_ss, hence the steady
    sliding force sign(v) g(v) + b v, is unchanged; only a relaxation that
    is already faster than the step is slowed to a time constant h / c.
    Where the limit acts, z lags z_ss by about (dz_ss/dt) h / c, so the
    friction error is about |dg/dt| h / c (plus sigma1 times the change of
    dz/dt): small, because the limit acts only at |v| >> v_st where g is
    flat (at the defaults exp(-25) of F_s - F_c is left of the Stribeck
    drop at 0.1 m/s). The device is consistent: as h -> 0 the limit
    disappears (docs/physics.md gives the measured errors).

    Parameters
    ----------
    velocity : float
        v (m/s).
    z : float
        Bristle deflection (m).
    f_static, f_coulomb : float
        Static and Coulomb levels F_s >= F_c (N), seal effect included.
    f_viscous : float
        Viscous coefficient b (N s/m), sigma2 of the paper.
    v_stribeck : float
        Stribeck velocity v_st (m/s).
    stiffness : float
        Bristle stiffness sigma0 (N/m), > 0.
    damping : float
        Bristle damping sigma1 (N s/m).
    max_rate : float
        Largest relaxation rate a (1/s); ``inf`` for the exact law.

    Returns
    -------
    dz_dt : float
        Bristle rate (m/s).
    force : float
        F_f (N), positive when it acts towards smaller y.
    """
    r = velocity / v_stribeck
    g = f_coulomb + (f_static - f_coulomb) * math.exp(-r * r)
    if g < LUGRE_MIN_LEVEL:
        g = LUGRE_MIN_LEVEL
    s_v = stiffness * abs(velocity)
    if s_v <= max_rate * g:
        dz = velocity - s_v * z / g
    else:
        z_ss = g / stiffness if velocity > 0.0 else -g / stiffness
        dz = max_rate * (z_ss - z)
    return dz, stiffness * z + damping * dz + f_viscous * velocity


@njit(cache=True, fastmath=FASTMATH)
def next_mode(drive_force: float, f_static: float) -> int:
    """Mode of a piston at rest under the driving force F_d (N): 0 if it sticks."""
    if drive_force > f_static:
        return 1
    if drive_force < -f_static:
        return -1
    return 0


@njit(cache=True, fastmath=FASTMATH)
def end_stop_force(
    position: float, velocity: float, stroke: float, stiffness: float, damping: float
) -> float:
    """Contact force of the end stops (N), a one-sided spring-damper.

    Positive pushes towards larger y. Zero inside [0, stroke]; the damping part
    never pulls the piston into the stop.
    """
    if position < 0.0:
        f = -stiffness * position - damping * velocity
        return f if f > 0.0 else 0.0
    if position > stroke:
        f = -stiffness * (position - stroke) - damping * velocity
        return f if f < 0.0 else 0.0
    return 0.0
