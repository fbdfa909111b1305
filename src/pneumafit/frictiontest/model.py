"""Force balance of an imposed-motion friction test (kind ``friction``).

An external drive moves the piston; the chamber pressure is held by a
regulator; a load cell measures the rod force F (positive outwards, the
extending direction). With the rod side at ambient (single-acting)::

    F = (p_P - p_atm) A_eff - F_f(v, history) [- (p_N - p_atm) A_N]      (1)

(the moving mass times the acceleration is left out: at 5-15 mm/s and
reversals of ~0.2 s it is ~0.01 N for 0.1 kg, far below the load cell's
noise). The friction F_f is positive against positive (extending) velocity.

Friction law: LuGre (Canudas de Wit et al., IEEE TAC 40(3), 1995, eqs. 1-3,
6) along the *measured* velocity (the motion is imposed, so no equation of
motion is solved)::

    g(v, p) = [F_c + c_p (p_P - p_atm) + (F_s - F_c) exp(-(v / v_st)^2)] (1 + a sign v)
    dz/dt   = v - sigma0 |v| z / g
    F_f     = sigma0 z + sigma1 dz/dt + b v

Steady sliding gives F_f = sign(v) g + b v; at a reversal the bristles
deflect (pre-sliding) over g / sigma0 before sliding resumes. Holding v and
p over each sampling interval, the bristle equation is linear in z and is
integrated exactly, ``z(t + h) = z_ss + (z - z_ss) exp(-sigma0 |v| h / g)``,
stable for any stiffness (no step-size limit, unlike the simulator's
explicit stages). A very stiff sigma0 (pre-sliding over less than a
micrometre) gives the static law sign(v) g(v) + b v with a continuous
crossing of v = 0: the "no pre-sliding" variant.

Effects for later discovery are parameters of the same kernel, neutral by
default (fixed): ``seal_friction_coefficient`` c_p (static and Coulomb
friction grow by c_p times the chamber gauge pressure: the seal is pressed
harder), ``friction_asymmetry`` a (direction asymmetry) and ``area_factor``
k_A (an effective bore area k_A pi bore^2 / 4; on a double-acting bench the
annulus is k_A pi bore^2 / 4 - pi rod^2 / 4, the rod unchanged). They are the
cylinder model's effects ``seal_friction``, ``friction_asymmetry`` and
``effective_area``: one definition each (law, parameter, unit, bounds,
typical size) in :mod:`pneumafit.physics.seal_effects`, read by both. Adding
one is freeing its parameter; nothing is restructured.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import savgol_filter

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.identification.parameters import Parameter, ParameterSet
from pneumafit.numba_stamp import njit
from pneumafit.physics.seal_effects import SEAL_EFFECTS, SealEffect

__all__ = [
    "EFFECTS",
    "FRICTION_EFFECTS",
    "KERNEL_ORDER",
    "STATIC_STIFFNESS",
    "FrictionEffect",
    "FrictionTest",
    "default_parameters",
    "estimate_velocity",
    "friction_test_force",
    "prepare",
]

#: sigma0 of the "no pre-sliding" law (N/m): 10 N of friction deflects
#: 1 um, a hundredth of one sample's travel at 10 mm/s and 100 Hz.
STATIC_STIFFNESS = 1.0e7
#: Savitzky-Golay window (s) of the velocity estimate: 11 samples at 100 Hz,
#: a reversal of the bench takes ~0.2 s.
VELOCITY_WINDOW = 0.11

#: Kernel parameter order (columns of the parameter matrix).
KERNEL_ORDER: tuple[str, ...] = (
    "friction_static",
    "friction_coulomb",
    "friction_viscous",
    "stribeck_velocity",
    "friction_stiffness",
    "friction_damping",
    "seal_friction_coefficient",
    "friction_asymmetry",
    "area_factor",
)


@dataclass(frozen=True)
class FrictionEffect:
    """One catalog effect of the friction-test model.

    Attributes
    ----------
    name : str
        Catalog name (``seal-friction``, ...).
    parameter : str
        The kernel parameter it frees (:data:`pneumafit.frictiontest.model.KERNEL_ORDER`).
    unit : str
        Unit of the parameter.
    step : float
        Step of the forward difference of the signature (in the parameter's unit).
    description : str
    """

    name: str
    parameter: str
    unit: str
    step: float
    description: str


def _bench_effect(e: SealEffect) -> FrictionEffect:
    return FrictionEffect(e.bench_name, e.parameter, e.unit, e.step, e.description)


#: The optional effects, neutral and fixed by default: one registry, shared by
#: ``fit --seal-friction`` (:data:`EFFECTS`) and ``discover`` (signatures),
#: built from the shared definitions (:data:`pneumafit.physics.seal_effects.SEAL_EFFECTS`).
FRICTION_EFFECTS: dict[str, FrictionEffect] = {
    e.parameter: _bench_effect(e) for e in SEAL_EFFECTS.values()
}

#: Optional effects (parameter -> what it adds), from :data:`FRICTION_EFFECTS`.
EFFECTS: dict[str, str] = {k: e.description for k, e in FRICTION_EFFECTS.items()}


def default_parameters() -> ParameterSet:
    """The friction-test parameters with starts, bounds and SI units."""
    return ParameterSet(
        [
            Parameter("friction_static", 6.0, "N", 0.0, 500.0, group="friction",
                      description="static friction F_s (at ambient chamber pressure)"),
            Parameter("friction_coulomb", 4.0, "N", 0.0, 500.0, group="friction",
                      description="Coulomb friction F_c"),
            Parameter("friction_viscous", 10.0, "N s/m", 0.0, 1e5, group="friction",
                      description="viscous coefficient b"),
            Parameter("stribeck_velocity", 2e-3, "m/s", 1e-5, 0.1, "log", group="friction",
                      description="Stribeck velocity v_st"),
            Parameter("friction_stiffness", STATIC_STIFFNESS, "N/m", 1e2, 1e8, "log",
                      group="friction", description="bristle stiffness sigma0 (pre-sliding)"),
            Parameter("friction_damping", 0.0, "N s/m", 0.0, 1e4, group="friction",
                      description="bristle damping sigma1 (pre-sliding)"),
            *(_effect_parameter(e) for e in SEAL_EFFECTS.values()),
        ]
    )  # fmt: skip


def _effect_parameter(e: SealEffect) -> Parameter:
    # neutral (the effect off) and fixed; the physical bounds of the shared definition
    return Parameter(e.parameter, e.neutral, e.unit, e.lower, e.upper, fixed=True,
                     group="effect", description=e.description)  # fmt: skip


def estimate_velocity(time: ArrayLike, position: ArrayLike) -> NDArray[np.float64]:
    """Velocity (m/s) from a position record by a Savitzky-Golay derivative.

    The record is resampled on a uniform grid at its median step (the bench
    drops samples: gaps of up to 0.3 s), differentiated by a quadratic
    Savitzky-Golay filter over :data:`VELOCITY_WINDOW`, and interpolated back
    to the sample times.
    """
    t = np.asarray(time, float)
    y = np.asarray(position, float)
    h = float(np.median(np.diff(t)))
    grid = np.arange(t[0], t[-1] + 0.5 * h, h)
    yy = np.interp(grid, t, y)
    window = max(5, round(VELOCITY_WINDOW / h) | 1)
    if grid.size <= window:
        return np.gradient(y, t)
    vv = savgol_filter(yy, window, 2, deriv=1, delta=h)
    return np.interp(t, grid, vv)


@njit(cache=True)
def _kernel(
    dt: NDArray[np.float64],
    v: NDArray[np.float64],
    dp: NDArray[np.float64],
    push: NDArray[np.float64],
    rod_push: NDArray[np.float64],
    params: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    n_sets = params.shape[0]
    n = v.size
    for s in range(n_sets):
        fs, fc, b, vst, sig0, sig1, cp, asym, af = params[s]
        z = 0.0
        for i in range(n):
            vi = v[i]
            sv = 1.0 if vi > 0.0 else (-1.0 if vi < 0.0 else 0.0)
            r = vi / vst
            g = (fc + cp * dp[i] + (fs - fc) * math.exp(-r * r)) * (1.0 + asym * sv)
            if g < 1e-6:
                g = 1e-6
            zss = sv * g / sig0
            rate = sig0 * abs(vi) / g
            if i == 0:
                z = zss
            else:
                z = zss + (z - zss) * math.exp(-rate * dt[i])
            zdot = vi - rate * z
            # k_A scales the bore's area, not the rod's: k_A push + (1 - k_A) rod_push
            out[s, i] = af * push[i] + (1.0 - af) * rod_push[i] - (sig0 * z + sig1 * zdot + b * vi)


@dataclass
class FrictionTest:
    """One friction-test recording, ready for the force balance (1).

    Attributes
    ----------
    file, role : str
    time : ndarray
        Sample times [s].
    velocity : ndarray
        Estimated velocity [m/s], positive extending.
    gauge_pressure : ndarray
        p_P - p_atm [Pa].
    push : ndarray
        (p_P - p_atm) A_P - (p_N - p_atm) A_N [N] with the nominal areas.
    force : ndarray
        Measured rod force F [N].
    rod_push : ndarray, optional
        (p_N - p_atm) A_rod [N] (double-acting bench; zeros when single-acting
        or None): with an area factor k_A the annulus is k_A A_P - A_rod, so
        the predicted push is k_A push + (1 - k_A) rod_push.
    """

    file: str
    role: str
    time: NDArray[np.float64]
    velocity: NDArray[np.float64]
    gauge_pressure: NDArray[np.float64]
    push: NDArray[np.float64]
    force: NDArray[np.float64]
    rod_push: NDArray[np.float64] | None = None

    @property
    def n(self) -> int:
        return int(self.time.size)

    def predict(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        """Predicted F (n_sets, n) for a kernel parameter matrix (n_sets, 9)."""
        p = np.ascontiguousarray(np.atleast_2d(params), dtype=np.float64)
        out = np.empty((p.shape[0], self.n))
        dt = np.concatenate([[0.0], np.diff(self.time)])
        rod = self.rod_push if self.rod_push is not None else np.zeros(self.n)
        _kernel(dt, self.velocity, self.gauge_pressure, self.push, rod, p, out)
        return out


def prepare(
    campaign: Campaign, recordings: Sequence[Recording] | None = None
) -> list[FrictionTest]:
    """The friction tests of a campaign (or the given recordings) with velocities."""
    rig = campaign.rig
    atm = rig.exhaust_pressure
    area_p = math.pi * rig.bore**2 / 4.0
    rod = rig.rod if math.isfinite(rig.rod) else 0.0
    area_n = math.pi * (rig.bore**2 - rod**2) / 4.0
    out = []
    for rec in recordings if recordings is not None else campaign.by_kind("friction"):
        dp = np.asarray(rec.channels["p_P"], float) - atm
        push = dp * area_p
        rod_push = np.zeros(dp.size)
        if "p_N" in rec.channels and rig.acting != "single":
            dp_n = np.asarray(rec.channels["p_N"], float) - atm
            push = push - dp_n * area_n
            rod_push = dp_n * (area_p - area_n)
        out.append(
            FrictionTest(
                file=rec.file,
                role=rec.role,
                time=np.asarray(rec.time, float),
                velocity=estimate_velocity(rec.time, rec.channels["y"]),
                gauge_pressure=dp,
                push=push,
                force=np.asarray(rec.channels["F"], float),
                rod_push=rod_push,
            )
        )
    return out


def friction_test_force(
    test: FrictionTest, values: Mapping[str, ArrayLike], n_sets: int = 1
) -> NDArray[np.float64]:
    """Predicted rod force (n_sets, n) from parameter values by name."""
    cols = [np.broadcast_to(np.asarray(values[k], float), (n_sets,)) for k in KERNEL_ORDER]
    return test.predict(np.stack(cols, axis=1))
