"""The exported controller: a gain schedule over position, sampled and held.

The closed-loop stage (:mod:`pneumafit.analysis.closed_loop`) validates one
design at the operating position. What a user takes to the rig is that
design repeated over a grid of positions (same order, placement, w0 and
dead-band compensation at every grid point) and run by a digital
controller. Its law, at every sampling instant, is

    i, f      grid interval of the measured position y and the fraction
              within it (clamped to the end points: f = 0 below the first,
              f = 1 in the last interval above the last)
    g(y)      = g[i] + f (g[i+1] - g[i]) for every scheduled quantity g:
              K_j, v_e, p_N_e, p_P_e, T_e and the compensation width w
    v         = v_e - K_0 (y - y_ref) - sum_{j >= 1} K_j (x_j - x_e,j),
              x = [y, v, p_N, p_P, T_N, T_P], x_e = [y_ref, 0, p_N_e, p_P_e,
              T_e, T_e] (the first n = order states)
    u         = v + a tanh(v / w)     (dead-band compensation; u = v when w = 0)
    u_P       = clip(u, -umax, umax),  u_N = -u_P

held until the next sample. With a grid of one position it is exactly the
closed-loop stage's state feedback (:class:`pneumafit.simulation.StateFeedback`),
sampled. :meth:`ScheduledController.command` evaluates it in plain double
arithmetic in the order of the C code the export writes
(:mod:`pneumafit.outputs.export`), so the two agree to the last bit on the
same inputs.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from pneumafit.analysis.closed_loop import (
    SAMPLE_INTERVAL,
    ControllerDesign,
    StepMetrics,
    _step_metrics,
    design_controller,
    step_reference,
)
from pneumafit.errors import PneumafitInputError
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.structure import ModelStructure, get_structure


@dataclass(frozen=True)
class ScheduledController:
    """The exported state-feedback law (module docstring), ready to run.

    Attributes
    ----------
    positions : tuple of float
        Grid (m), strictly increasing, n >= 1.
    gain : tuple of tuple of float
        K at each grid point (V per SI state unit), n rows of ``order``.
    v_e, p_N_e, p_P_e, T_e : tuple of float
        Controller-side equilibrium command (V), equilibrium pressures (Pa)
        and temperature (K) at each grid point.
    deadband : float
        Compensation amplitude a (V), 0 without compensation.
    deadband_width : tuple of float
        Compensation width w (V) at each grid point, 0 without.
    umax : float
        Command limit (V).
    period : float
        Sampling period the law is meant for (s).
    """

    positions: tuple[float, ...]
    gain: tuple[tuple[float, ...], ...]
    v_e: tuple[float, ...]
    p_N_e: tuple[float, ...]
    p_P_e: tuple[float, ...]
    T_e: tuple[float, ...]
    deadband: float = 0.0
    deadband_width: tuple[float, ...] = field(default_factory=tuple)
    umax: float = 10.0
    period: float = SAMPLE_INTERVAL

    def __post_init__(self) -> None:
        n = len(self.positions)
        pos = tuple(float(v) for v in self.positions)
        if n < 1 or any(b <= a for a, b in itertools.pairwise(pos)):
            raise PneumafitInputError(
                "scheduled controller: positions: expected one or more strictly increasing "
                f"positions (m), found {list(pos)}"
            )
        gain = tuple(tuple(float(k) for k in row) for row in self.gain)
        order = len(gain[0]) if gain else 0
        if len(gain) != n or order not in (4, 6) or any(len(r) != order for r in gain):
            raise PneumafitInputError(
                f"scheduled controller: gain: expected {n} rows of 4 or 6 gains, "
                f"found {[len(r) for r in gain]}"
            )
        width = tuple(float(v) for v in self.deadband_width) or (0.0,) * n
        for name, values in (("v_e", self.v_e), ("p_N_e", self.p_N_e), ("p_P_e", self.p_P_e),
                             ("T_e", self.T_e), ("deadband_width", width)):  # fmt: skip
            if len(values) != n:
                raise PneumafitInputError(
                    f"scheduled controller: {name}: expected {n} values (one per position), "
                    f"found {len(values)}"
                )
            object.__setattr__(self, name, tuple(float(v) for v in values))
        if not (self.deadband >= 0.0 and all(w >= 0.0 for w in width)):
            raise PneumafitInputError(
                "scheduled controller: dead-band compensation: expected a >= 0 and w >= 0 V, "
                f"found a = {self.deadband}, w = {width}"
            )
        if not (self.umax > 0.0 and self.period > 0.0):
            raise PneumafitInputError(
                "scheduled controller: expected umax > 0 V and period > 0 s, "
                f"found {self.umax} and {self.period}"
            )
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "gain", gain)
        object.__setattr__(self, "deadband", float(self.deadband))
        object.__setattr__(self, "umax", float(self.umax))
        object.__setattr__(self, "period", float(self.period))

    @property
    def order(self) -> int:
        return len(self.gain[0])

    @classmethod
    def from_export(cls, document: Mapping) -> ScheduledController:
        """The law of an export document (version 2, :func:`build_export`)."""
        version = document.get("version")
        if version != 2 or "controller" not in document:
            raise PneumafitInputError(
                "export: expected a version-2 document with a controller section "
                f"(the validated controller), found version {version}"
            )
        grid, ctrl = document["grid"], document["controller"]
        return cls(
            positions=grid["positions"], gain=grid["K"], v_e=grid["v_e"], p_N_e=grid["p_N_e"],
            p_P_e=grid["p_P_e"], T_e=grid["T_e"], deadband=ctrl["deadband_amplitude"] or 0.0,
            deadband_width=grid["deadband_width"], umax=ctrl["umax"], period=ctrl["period"],
        )  # fmt: skip

    def command(self, state: Sequence[float], y_ref: float) -> tuple[float, float, bool]:
        """(u_P, v, saturated) for the measured state [y, v, p_N, p_P, T_N, T_P] (SI).

        Plain double arithmetic in the C code's order (module docstring)."""
        pos = self.positions
        n = len(pos)
        y = float(state[0])
        if n == 1 or y <= pos[0]:
            i, f = 0, 0.0
        elif y >= pos[n - 1]:
            i, f = n - 2, 1.0
        else:
            i = 0
            while y >= pos[i + 1]:
                i += 1
            f = (y - pos[i]) / (pos[i + 1] - pos[i])
        j = i + 1 if n > 1 else i

        def lerp(table: Sequence[float]) -> float:
            return table[i] + f * (table[j] - table[i])

        gi, gj = self.gain[i], self.gain[j]
        t_e = lerp(self.T_e)
        x_e = (float(y_ref), 0.0, lerp(self.p_N_e), lerp(self.p_P_e), t_e, t_e)
        v = lerp(self.v_e) - (gi[0] + f * (gj[0] - gi[0])) * (y - x_e[0])
        for s in range(1, self.order):
            v -= (gi[s] + f * (gj[s] - gi[s])) * (float(state[s]) - x_e[s])
        u = v
        width = lerp(self.deadband_width)
        if self.deadband > 0.0 and width > 0.0:
            u = v + self.deadband * math.tanh(v / width)
        saturated = False
        if u > self.umax:
            u, saturated = self.umax, True
        elif u < -self.umax:
            u, saturated = -self.umax, True
        return u, v, saturated

    def __call__(self, state: Sequence[float], y_ref: float) -> float:
        """u_P (V): the callable :func:`pneumafit.simulation.sampled.simulate_sampled` takes."""
        return self.command(state, y_ref)[0]


def design_schedule(
    parameters: Mapping[str, float] | np.ndarray,
    positions: Sequence[float],
    *,
    order: int,
    w0: float,
    placement: str = "dominant",
    compensate: bool = True,
    lambda_e: float = 15.0,
    valve: str = "iso6358",
    umax: float = 10.0,
    period: float = SAMPLE_INTERVAL,
) -> tuple[ScheduledController, list[ControllerDesign], list[dict]]:
    """The closed-loop stage's design repeated over a grid of positions.

    Every grid point gets :func:`design_controller` with the same order, w0,
    placement and compensation. Positions without an equilibrium, or where
    the compensation is off while it is on elsewhere, are left out.

    Returns
    -------
    controller : ScheduledController
    designs : list of ControllerDesign
        One per kept position.
    skipped : list of dict
        ``{"y": position (m), "reason": text}`` per position left out.

    Raises
    ------
    PneumafitInputError
        When no position has a design.
    """
    p = parameters if isinstance(parameters, np.ndarray) else parameter_vector(parameters)
    designs, skipped = [], []
    for y in sorted(float(v) for v in positions):
        try:
            d = design_controller(p, y, order=order, w0=w0, lambda_e=lambda_e,
                                  compensate=compensate, placement=placement,
                                  valve=valve)  # fmt: skip
        except ValueError as exc:
            skipped.append({"y": y, "reason": str(exc)})
            continue
        designs.append(d)
    if compensate and any(d.compensation is not None for d in designs):
        for d in [d for d in designs if d.compensation is None]:
            skipped.append({"y": d.model.equilibrium.y, "reason": "no dead-band compensation "
                            "here (the centre gain matches the open valve's)"})  # fmt: skip
        designs = [d for d in designs if d.compensation is not None]
    if not designs:
        raise PneumafitInputError(
            "design schedule: no position of the grid has a design: "
            + "; ".join(s["reason"] for s in skipped[:3])
        )
    amplitude = designs[0].compensation.amplitude if designs[0].compensation else 0.0
    controller = ScheduledController(
        positions=[d.model.equilibrium.y for d in designs],
        gain=[d.gain for d in designs],
        v_e=[d.model.v_e for d in designs],
        p_N_e=[d.model.equilibrium.p_N for d in designs],
        p_P_e=[d.model.equilibrium.p_P for d in designs],
        T_e=[d.model.equilibrium.T for d in designs],
        deadband=amplitude,
        deadband_width=[d.compensation.width if d.compensation else 0.0 for d in designs],
        umax=umax, period=period,
    )  # fmt: skip
    return controller, designs, sorted(skipped, key=lambda s: s["y"])


@dataclass(frozen=True)
class SampledRun:
    """A sampled controller's step test on the nonlinear plant.

    Attributes
    ----------
    time, y_ref : ndarray
        Samples (s) and reference (m).
    channels : dict of str to ndarray
        Simulated channels (SI); ``u_P`` is the held command.
    ok : bool
    message : str
    air_mass, exergy : float
        Mass drawn from supply over the test (kg) and its exergy (J).
    steps : list of StepMetrics
        Per reference step, as the closed-loop stage's.
    """

    time: np.ndarray
    y_ref: np.ndarray
    channels: dict[str, np.ndarray]
    ok: bool
    message: str
    air_mass: float
    exergy: float
    steps: list[StepMetrics]


def run_sampled(
    controller,
    plant_parameters: Mapping[str, float] | np.ndarray,
    *,
    y_mid: float,
    steps: Sequence[float] = (0.03, 0.0, -0.03, 0.0),
    hold: float = 2.5,
    plant: ModelStructure | str = "convection",
    initial: Mapping[str, float] | None = None,
    umax: float = 10.0,
    period: float = SAMPLE_INTERVAL,
) -> SampledRun:
    """The closed-loop stage's step test with a sampled controller.

    Same reference (:func:`step_reference`), plant and metrics as
    :func:`pneumafit.analysis.closed_loop.compare_controllers`; the
    controller (``controller(state, y_ref) -> u_P``, e.g. a
    :class:`ScheduledController` or the compiled C code) runs every
    ``period`` s and its command is held in between.
    """
    from pneumafit.analysis.closed_loop import CHANNELS
    from pneumafit.simulation.sampled import simulate_sampled

    p = np.asarray(plant_parameters, dtype=float) if isinstance(plant_parameters, np.ndarray) \
        else parameter_vector(plant_parameters)  # fmt: skip
    t, y_ref, starts = step_reference(y_mid, [float(s) for s in steps], hold=hold)
    if abs(period - SAMPLE_INTERVAL) > 1e-15:
        raise PneumafitInputError(
            f"period: expected {SAMPLE_INTERVAL} s (the step test's sample interval), "
            f"found {period}"
        )
    r = simulate_sampled(p, t, y_ref, controller, model=get_structure(plant),
                         initial=initial, channels=CHANNELS)  # fmt: skip
    if not r.ok:
        return SampledRun(t, y_ref, r.channels, False, r.message, math.nan, math.nan, [])
    metrics = _step_metrics(t, r.channels, y_ref, starts, umax, 0.0, p)
    return SampledRun(t, y_ref, r.channels, True, "ok", r.air.mass_supplied, r.air.exergy,
                      metrics)  # fmt: skip


def metrics_document(run: SampledRun) -> dict:
    """JSON-ready figures of a sampled run (SI; NaN as null)."""

    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {
        "ok": run.ok,
        "message": run.message,
        "air_mass_kg": num(run.air_mass),
        "exergy_J": num(run.exergy),
        "max_abs_u_V": num(float(np.max(np.abs(run.channels["u_P"])))) if run.ok else None,
        "steps": [{
            "start_s": s.start, "target_m": s.target, "size_m": s.size,
            "overshoot_m": s.overshoot, "settling_time_s": num(s.settling_time),
            "final_error_m": s.final_error, "air_mass_kg": s.air_mass, "exergy_J": s.exergy,
            "max_abs_u_V": s.max_abs_u, "saturation_fraction": s.saturation,
        } for s in run.steps],
    }  # fmt: skip
