"""Controllers designed on the linear models, run on the nonlinear model.

The paper's section "Simulation": state-feedback gains computed at half
stroke on the 4th-order (polytropic) and 6th-order (heat) linear models drive
the full nonlinear model (variable lambda, stiction with Stribeck, the valve
characteristic); step responses around that position are compared in
position, pressures, temperatures, heat-transfer coefficient, and in the air
each controller consumes (mass and exergy per step) - the paper's aim,
minimum-energy actuation, made measurable.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pneumafit.analysis.linear import itae_poles, linearize, place
from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.structure import ModelStructure
from pneumafit.simulation import Experiment, Simulator, StateFeedback

CHANNELS = ("y", "v", "p_P", "p_N", "T_P", "T_N", "lambda_P", "lambda_N", "u_P", "m_supply",
            "m_exhaust")  # fmt: skip


@dataclass(frozen=True)
class ClosedLoopResult:
    """One controller's step responses on the nonlinear model.

    Attributes
    ----------
    name : str
        Controller name (e.g. ``"order 6"``).
    gain : ndarray
        K (6,) in V per SI state unit (zeros on temperatures for order 4).
    time : ndarray
        s.
    channels : dict of str to ndarray
        Simulated channels (SI).
    ok : bool
        The simulation succeeded.
    air_mass : float
        Mass drawn from supply over the test (kg).
    exergy : float
        Its exergy (J).
    metrics : dict
        Per step: overshoot (m), 2 %-settling time (s), final error (m).
    """

    name: str
    gain: np.ndarray
    time: np.ndarray
    channels: dict[str, np.ndarray]
    ok: bool
    air_mass: float
    exergy: float
    metrics: list[dict[str, float]]


def _step_metrics(t: np.ndarray, y: np.ndarray, y_ref: np.ndarray, switch: list[float]) -> list:
    out = []
    bounds = [*switch, t[-1] + 1e-9]
    for a, b in itertools.pairwise(bounds):
        m = (t >= a) & (t < b)
        target = y_ref[m][-1]
        start = y[m][0]
        span = target - start
        err = y[m] - target
        overshoot = max(0.0, float(np.max(np.sign(span) * err))) if span != 0 else 0.0
        outside = np.flatnonzero(np.abs(err) > 0.02 * max(abs(span), 1e-9))
        settle = float(t[m][outside[-1]] - a) if outside.size else 0.0
        out.append({"overshoot_m": overshoot, "settling_time_s": settle,
                    "final_error_m": float(err[-1])})  # fmt: skip
    return out


def compare_controllers(
    parameters: Mapping[str, float] | np.ndarray,
    *,
    w0: float,
    y_mid: float | None = None,
    step: float = 0.02,
    duration: float = 4.0,
    lambda_e: float = 15.0,
    umax: float = 10.0,
    plant: ModelStructure | str = "convection",
    orders: tuple[int, ...] = (4, 6),
) -> list[ClosedLoopResult]:
    """Step responses of the order-4 and order-6 designs on the nonlinear plant.

    Parameters
    ----------
    parameters : mapping or ndarray
        SI parameter values of the plant (fitted values, or a rig's truth).
    w0 : float
        ITAE frequency scale of both designs (rad/s).
    y_mid : float, optional
        Design and operating position (m); default half stroke.
    step : float
        Reference step (m): up at 0.2 s, back down at half the duration.
    duration : float
        Test length (s).
    lambda_e : float
        Nominal lambda of the order-6 design (W/m^2/K).
    umax : float
        Command limit (V).
    plant : ModelStructure or str
        The nonlinear model the controllers drive (``"convection"``: variable
        lambda, stiction; a rig's richer truth structure where there is one).
    orders : tuple of int
        Designs to compare.
    """
    p = parameters if isinstance(parameters, np.ndarray) else parameter_vector(parameters)
    stroke = float(p[P["stroke"]])
    y_mid = 0.5 * stroke if y_mid is None else y_mid
    t = np.arange(0.0, duration + 5e-4, 1e-3)
    switch = [0.2, 0.5 * duration]
    y_ref = np.where((t >= switch[0]) & (t < switch[1]), y_mid + step, y_mid)
    sim = Simulator(plant, channels=CHANNELS)
    results = []
    for order in orders:
        lin = linearize(p, y_mid, order=order, lambda_e=lambda_e)
        gain = place(lin, itae_poles(order, w0))[0]
        eq = lin.equilibrium
        controller = StateFeedback(gain=gain, x_e=eq.state(), u_e=eq.u, umax=umax)
        exp = Experiment(time=t, kind="step", y_ref=y_ref, controller=controller,
                         initial={"y": y_mid, "p_P": eq.p_P, "p_N": eq.p_N, "T_P": eq.T,
                                  "T_N": eq.T}, name=f"order {order}")  # fmt: skip
        r = sim.simulate(p, exp)
        metrics = _step_metrics(t, r["y"], y_ref, switch) if r.ok else []
        results.append(
            ClosedLoopResult(
                name=f"order {order}",
                gain=np.pad(gain, (0, 6 - gain.size)),
                time=t,
                channels=r.channels,
                ok=r.ok,
                air_mass=r.air.mass_supplied if r.air else float("nan"),
                exergy=r.air.exergy if r.air else float("nan"),
                metrics=metrics,
            )
        )
    return results
