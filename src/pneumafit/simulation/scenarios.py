"""Standard test scenarios as experiments: charge, discharge, closed-loop step.

Used by ``pneumafit simulate``; every value in SI units.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from pneumafit.errors import PneumafitComputationError, PneumafitInputError
from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.structure import ModelStructure
from pneumafit.simulation.experiment import PD, Experiment
from pneumafit.simulation.simulator import Simulator


def blocked_test(
    kind: str,
    parameters: Mapping[str, float],
    *,
    chamber: str = "P",
    position: float = 0.25,
    amplitude: float = 10.0,
    start: float = 0.2,
    open_time: float = 0.3,
    duration: float = 4.0,
    rate: float = 1000.0,
) -> Experiment:
    """A charge or discharge test of one chamber, piston blocked.

    The chamber starts at rest at exhaust pressure (charge) or supply pressure
    (discharge), at wall temperature; its valve is driven to +amplitude
    (charge) or -amplitude (discharge) from ``start`` for ``open_time``, then
    returns to 0 V (centre) while the chamber relaxes.

    Parameters
    ----------
    kind : {"charge", "discharge"}
    parameters : mapping
        SI parameter values (for the supply and exhaust pressures).
    chamber : {"P", "N"}
    position : float
        Piston position (m).
    amplitude : float
        Command magnitude during the opening (V).
    start, open_time, duration : float
        Opening instant, opening time and test length (s).
    rate : float
        Sample rate (Hz).
    """
    if kind not in ("charge", "discharge"):
        raise PneumafitInputError(
            f"blocked test: kind: expected 'charge' or 'discharge', found {kind!r}"
        )
    vec = parameter_vector(parameters)
    t = np.arange(0.0, duration + 0.5 / rate, 1.0 / rate)
    sign = 1.0 if kind == "charge" else -1.0
    u = np.where((t >= start) & (t < start + open_time), sign * amplitude, 0.0)
    p0 = vec[P["exhaust_pressure"]] if kind == "charge" else vec[P["supply_pressure"]]
    return Experiment(
        time=t, kind=kind, chamber=chamber, **{f"u_{chamber}": u},
        initial={"y": position, f"p_{chamber}": p0}, name=f"{kind}_{chamber}",
    )  # fmt: skip


def step_test(
    model: str | ModelStructure,
    parameters: Mapping[str, float],
    *,
    y0: float = 0.25,
    y_ref: float = 0.35,
    step_time: float = 0.2,
    duration: float = 4.0,
    kp: float = 60.0,
    kd: float = 4.0,
    u0: float = 0.0,
    umax: float = 10.0,
    rate: float = 1000.0,
    settle: float = 3.0,
) -> Experiment:
    """A closed-loop position step under the campaign format's ``pd`` law.

    The actuator first settles for ``settle`` seconds holding ``y0`` (from
    both chambers at the mean of supply and exhaust pressure); the test
    starts from that state, steps the reference to ``y_ref`` at ``step_time``
    and lasts ``duration`` (s). Positions in m, gains in V/m and V s/m.
    ``model`` is a model name or a structure (the settling uses its laws; with
    LuGre friction the test starts from bristle equilibrium at the settled
    state, the deflection the settled piston holds).

    Raises
    ------
    PneumafitComputationError
        The settling simulation failed.
    """
    vec = parameter_vector(parameters)
    controller = PD(kp=kp, kd=kd, u0=u0, umax=umax)
    p_mid = 0.5 * (vec[P["supply_pressure"]] + vec[P["exhaust_pressure"]])
    initial = {"y": y0, "p_P": p_mid, "p_N": p_mid}
    if settle > 0:
        ts = np.arange(0.0, settle + 0.5 / rate, 1.0 / rate)
        pre = Experiment(time=ts, kind="step", y_ref=np.full(ts.size, y0), controller=controller,
                         initial=initial, name="settling")  # fmt: skip
        sim = Simulator(model, channels=["y", "p_P", "p_N", "T_P", "T_N"])
        r = sim.simulate(vec, pre)
        if not r.ok:
            raise PneumafitComputationError(
                f"step test: settling before the step failed: {r.message}"
            )
        initial = {name: float(r[name][-1]) for name in ("y", "p_P", "p_N", "T_P", "T_N")}
    t = np.arange(0.0, duration + 0.5 / rate, 1.0 / rate)
    ref = np.where(t < step_time, y0, y_ref)
    return Experiment(time=t, kind="step", y_ref=ref, controller=controller, initial=initial,
                      name="step")  # fmt: skip
