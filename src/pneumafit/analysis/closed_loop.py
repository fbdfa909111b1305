"""Controllers designed on the linear models, run on the nonlinear model.

The paper's section "Simulation": state-feedback gains computed at half
stroke on the 4th-order (polytropic, eq. 14) and 6th-order (heat, eq. 13)
linear models drive the full nonlinear model (variable lambda of eq. 8,
stiction with Stribeck, the valve characteristic with its dead band and
leakage); step responses around that position are compared in position,
pressures, temperatures and heat-transfer coefficient (Figs. 9-11), and in
the air each controller consumes (mass drawn from supply and its exergy, per
step): the paper's aim, minimum-energy actuation, made measurable.

Two design choices make the paper's designs usable on a valve with an
overlap (docs/physics.md, "State feedback on the nonlinear model"):

- dead-band compensation u = v + a tanh(v / w) before the valve, with w such
  that the compensated plant's linear input gain equals the open valve's
  (:func:`pneumafit.analysis.linear.deadband_compensation`);
- ``placement="dominant"``: ITAE poles of order 3 on the position-force chain,
  the n - 3 slow open-loop modes (pressure sum; with heat, the two thermal
  modes) kept where they are. The single input barely moves those modes:
  placing them too (the paper's ITAE of order n, ``placement="itae"``) needs
  gains 5e2 (order 4) to 6e5 (order 6) times larger at w0 = 20 rad/s on the
  demo rig, and a y_ref -> y response through a near-cancelled slow zero that
  overshoots the step many times over.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pneumafit.analysis.linear import (
    DeadbandCompensation,
    LinearModel,
    deadband_compensation,
    itae_poles,
    linearize,
    place,
)
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.structure import ModelStructure, get_structure
from pneumafit.physics.air import R_AIR
from pneumafit.simulation import Experiment, Simulator, StateFeedback

CHANNELS = ("y", "v", "p_P", "p_N", "T_P", "T_N", "lambda_P", "lambda_N", "u_P", "m_supply",
            "m_exhaust")  # fmt: skip

#: ITAE prototype of order 3 (Graham and Lathrop), w0 = 1 rad/s.
ITAE_3 = (1.0, 1.75, 2.15, 1.0)

PLACEMENTS = ("dominant", "itae")

#: Settling band: 2 % of the step (m per m).
SETTLING_FRACTION = 0.02

#: Sample interval of the simulated tests (s).
SAMPLE_INTERVAL = 1e-3


@dataclass(frozen=True)
class ControllerDesign:
    """One state-feedback design at the operating position.

    Attributes
    ----------
    name : str
        ``"order 4"`` or ``"order 6"``.
    order : int
        4 (polytropic model, eq. 14) or 6 (heat model, eq. 13).
    w0 : float
        ITAE frequency scale (rad/s).
    placement : str
        ``"dominant"`` or ``"itae"`` (see the module docstring).
    poles : ndarray
        Requested closed-loop poles (1/s).
    gain : ndarray, shape (order,)
        K in V per SI state unit (input v, the compensated command).
    model : LinearModel
        The linear model designed on (its B includes the compensation).
    compensation : DeadbandCompensation or None
    """

    name: str
    order: int
    w0: float
    placement: str
    poles: np.ndarray
    gain: np.ndarray
    model: LinearModel
    compensation: DeadbandCompensation | None

    def controller(self, umax: float) -> StateFeedback:
        """The simulator's state-feedback law for this design (command limit umax, V)."""
        comp = self.compensation
        return StateFeedback(
            gain=self.gain, x_e=self.model.equilibrium.state(), u_e=self.model.v_e, umax=umax,
            deadband=comp.amplitude if comp else 0.0, deadband_width=comp.width if comp else 0.0,
        )  # fmt: skip


def design_poles(model: LinearModel, w0: float, placement: str = "dominant") -> np.ndarray:
    """Closed-loop poles (1/s) for a design on ``model``.

    ``"itae"``: the ITAE prototype of the model's order scaled by w0 (the
    paper's table). ``"dominant"``: ITAE of order 3 scaled by w0 for the
    position integrator and the mechanical pair, and the n - 3 slowest stable
    open-loop poles other than the integrator kept unchanged.

    Raises
    ------
    PneumafitInputError
        Unknown placement, or a kept mode that is not stable (a ValueError).
    """
    n = model.A.shape[0]
    if placement == "itae":
        return itae_poles(n, w0)
    if placement != "dominant":
        raise PneumafitInputError(f"placement: expected one of {PLACEMENTS}, found {placement!r}")
    if not w0 > 0:
        raise PneumafitInputError(f"w0: expected a positive frequency in rad/s, found {w0}")
    open_loop = model.poles[np.argsort(np.abs(model.poles))]
    kept = open_loop[1 : n - 2]  # skip the integrator (|s| smallest), keep n - 3
    if np.any(kept.real >= 0.0):
        raise PneumafitInputError(
            f"placement 'dominant': the slow open-loop modes to keep are not all stable: {kept}"
        )
    return np.concatenate([np.roots(ITAE_3) * w0, kept])


def design_controller(
    parameters: Mapping[str, float] | np.ndarray,
    y: float,
    *,
    order: int,
    w0: float,
    lambda_e: float = 15.0,
    compensate: bool = True,
    placement: str = "dominant",
    valve: str = "iso6358",
) -> ControllerDesign:
    """State-feedback design of one order at position y (m).

    Parameters
    ----------
    parameters : mapping or ndarray
        SI parameter values the design uses (fitted, or a rig's truth).
    y : float
        Operating position (m).
    order : {4, 6}
        Design model.
    w0 : float
        ITAE frequency scale (rad/s).
    lambda_e : float
        Nominal lambda of the order-6 model (W/m^2/K).
    compensate : bool
        Put the dead-band compensation before the valve and design on the
        compensated plant.
    placement : {"dominant", "itae"}
        Pole choice (:func:`design_poles`).
    valve : {"iso6358", "map"}
        Valve law of the parameters (a fit's ``structure.valve``).
    """
    p = parameters if isinstance(parameters, np.ndarray) else parameter_vector(parameters)
    comp = deadband_compensation(p, y, valve=valve) if compensate else None
    model = linearize(p, y, order=order, lambda_e=lambda_e, compensation=comp, valve=valve)
    poles = design_poles(model, w0, placement)
    gain = place(model, poles)[0]
    return ControllerDesign(f"order {order}", order, w0, placement, poles, gain, model, comp)


@dataclass(frozen=True)
class StepMetrics:
    """One reference step of a closed-loop test.

    Attributes
    ----------
    start : float
        Time of the step (s).
    target : float
        Reference after the step (m).
    size : float
        Target minus the position at the step (m).
    overshoot : float
        Largest excursion past the target (m), >= 0.
    settling_time : float
        Time after the step of the last exit from the band 2 % |size| around
        the position at the end of the hold (s), as MATLAB's ``stepinfo``:
        the time the motion takes to settle, wherever stiction stops it.
    final_error : float
        y - target at the end of the hold (m): with stiction and no integral
        action, anywhere within the stiction band (:func:`stiction_band`).
    air_mass : float
        Mass drawn from supply during the hold (kg).
    leakage_mass : float
        What the valves' centre leakage alone draws at the equilibrium over
        the same time (kg): the baseline of a piston at rest.
    exergy : float
        Exergy of ``air_mass`` (J), m r T_atm ln(P_S / P_atm).
    max_abs_u : float
        Largest |u_P| (V).
    saturation : float
        Fraction of samples with |u_P| at the limit (-).
    """

    start: float
    target: float
    size: float
    overshoot: float
    settling_time: float
    final_error: float
    air_mass: float
    leakage_mass: float
    exergy: float
    max_abs_u: float
    saturation: float


@dataclass(frozen=True)
class ClosedLoopResult:
    """One controller's step responses on the nonlinear model.

    Attributes
    ----------
    design : ControllerDesign
    time : ndarray
        s.
    y_ref : ndarray
        Reference position (m).
    channels : dict of str to ndarray
        Simulated channels (SI).
    ok : bool
        The simulation succeeded (no non-finite or non-physical state).
    message : str
    air_mass : float
        Mass drawn from supply over the test (kg).
    exergy : float
        Its exergy (J).
    steps : list of StepMetrics
    max_abs_u : float
        Largest |u_P| over the test (V).
    saturation : float
        Fraction of samples at the command limit (-).
    stiction_band : float
        Largest position error at which the loop can hold the piston stuck
        (m, :func:`stiction_band`).
    """

    design: ControllerDesign
    time: np.ndarray
    y_ref: np.ndarray
    channels: dict[str, np.ndarray]
    ok: bool
    message: str
    air_mass: float
    exergy: float
    steps: list[StepMetrics] = field(default_factory=list)
    max_abs_u: float = float("nan")
    saturation: float = float("nan")
    stiction_band: float = float("nan")

    @property
    def name(self) -> str:
        return self.design.name


def exergy_of(mass: float, parameters: np.ndarray) -> float:
    """Exergy (J) of a mass (kg) of supply air: m r T_atm ln(P_S / P_atm)."""
    p_s = parameters[P["supply_pressure"]]
    p_atm = parameters[P["exhaust_pressure"]]
    return float(mass * R_AIR * parameters[P["ambient_temperature"]] * math.log(p_s / p_atm))


def _step_metrics(
    t: np.ndarray,
    ch: dict[str, np.ndarray],
    y_ref: np.ndarray,
    starts: Sequence[float],
    umax: float,
    leak_rate: float,
    p: np.ndarray,
) -> list[StepMetrics]:
    out = []
    bounds = [*starts, t[-1] + 0.5 * SAMPLE_INTERVAL]
    y, u, ms = ch["y"], ch["u_P"], ch["m_supply"]
    for a, b in itertools.pairwise(bounds):
        idx = np.flatnonzero((t >= a - 1e-12) & (t < b))
        target = float(y_ref[idx[-1]])
        size = target - float(y[idx[0]])
        err = y[idx] - target
        overshoot = max(0.0, float(np.max(np.sign(size) * err))) if size != 0 else 0.0
        band = SETTLING_FRACTION * abs(size)
        outside = np.flatnonzero(np.abs(y[idx] - y[idx[-1]]) > band)
        if outside.size == 0:
            settle = 0.0
        elif outside[-1] == idx.size - 1:
            settle = float("nan")
        else:
            settle = float(t[idx[outside[-1] + 1]] - a)
        i0 = max(idx[0] - 1, 0)  # mass at the step instant (sample before the segment)
        mass = float(ms[idx[-1]] - ms[i0])
        out.append(StepMetrics(
            start=float(a), target=target, size=size, overshoot=overshoot,
            settling_time=settle, final_error=float(err[-1]), air_mass=mass,
            leakage_mass=leak_rate * float(t[idx[-1]] - t[i0]), exergy=exergy_of(mass, p),
            max_abs_u=float(np.max(np.abs(u[idx]))),
            saturation=float(np.mean(np.abs(u[idx]) >= umax * (1 - 1e-12))),
        ))  # fmt: skip
    return out


def step_reference(
    y_mid: float, steps: Sequence[float], *, rest: float = 0.5, hold: float = 2.5
) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Sample times (s), reference y_ref (m) and step instants (s) of a test.

    The reference sits at y_mid for ``rest`` s, then at y_mid + steps[k] for
    ``hold`` s each.
    """
    duration = rest + hold * len(steps)
    t = np.arange(0.0, duration + 0.5 * SAMPLE_INTERVAL, SAMPLE_INTERVAL)
    starts = [rest + k * hold for k in range(len(steps))]
    y_ref = np.full(t.size, y_mid)
    for start, offset in zip(starts, steps, strict=True):
        y_ref[t >= start - 1e-12] = y_mid + offset
    return t, y_ref, starts


def stiction_band(
    design: ControllerDesign, parameters: np.ndarray, valve: str = "iso6358"
) -> float:
    """Largest |y - y_ref| (m) at which the closed loop holds a stuck piston.

    With the piston stuck (v = 0, y fixed) the valves settle at zero flow:
    each chamber pressure moves with the command by its static gain
    G_X = dP_X/dv = -(dq_X/du) / (dq_X/dP_X) c'(v_e) (the ratio of the gains
    of eq. 12, times the compensation's slope), and the law
    dv = -K_y e - K_PN dP_N - K_PP dP_P gives dv = -K_y e / (1 + K_PN G_N +
    K_PP G_P). The drive force changes by (S_P G_P - S_N G_N) dv; the piston
    stays stuck while it is below the static friction F_s, that is while

        |e| <= F_s (1 + K_PN G_N + K_PP G_P) / (K_y |S_P G_P - S_N G_N|).

    Linear in the valve's static characteristic around the equilibrium;
    temperatures return to the wall's, so their gains drop out.
    """
    from pneumafit.analysis.linear import _gains, valve_law
    from pneumafit.physics.geometry import piston_areas

    law = valve_law(valve)
    eq = design.model.equilibrium
    slope = 1.0 if design.compensation is None else design.compensation.slope(design.model.v_e)
    qp_p, qu_p = _gains(parameters, eq.u, eq.p_P, law)
    qp_n, qu_n = _gains(parameters, -eq.u, eq.p_N, law)
    g_p = -qu_p / qp_p * slope
    g_n = qu_n / qp_n * slope  # u_N = -u
    s_p, s_n = piston_areas(parameters[P["bore"]], parameters[P["rod"]])
    k = design.gain
    loop = 1.0 + k[2] * g_n + k[3] * g_p
    force = abs(s_p * g_p - s_n * g_n)
    return float(parameters[P["friction_static"]] * abs(loop) / (abs(k[0]) * force))


def peak_command(design: ControllerDesign, step: float) -> float:
    """Largest |v - v_e| (V) of the designed linear closed loop for a reference step (m).

    Linear closed loop dx/dt = (A - B K) x + B K_y dy_ref, v - v_e = K_y dy_ref - K x,
    over 30 / w0 s.
    """
    from scipy.signal import StateSpace
    from scipy.signal import step as step_response

    model, k = design.model, design.gain[None, :]
    n = model.A.shape[0]
    system = StateSpace(model.A - model.B @ k, model.B * k[0, 0],
                        np.vstack([np.eye(n)[:1], -k]), np.array([[0.0], [k[0, 0]]]))  # fmt: skip
    _, out = step_response(system, T=np.linspace(0.0, 30.0 / design.w0, 3001))
    return float(np.max(np.abs(out[:, 1])) * abs(step))


def largest_w0(
    parameters: Mapping[str, float] | np.ndarray,
    y: float,
    step: float,
    *,
    umax: float = 10.0,
    fraction: float = 0.9,
    orders: tuple[int, ...] = (4, 6),
    lambda_e: float = 15.0,
    compensate: bool = True,
    placement: str = "dominant",
    valve: str = "iso6358",
) -> float:
    """Largest ITAE w0 (rad/s) whose designs keep the command within the limit.

    For every order, the designed linear closed loop's peak command for a
    reference step of ``step`` m, plus the compensation's amplitude, must stay
    below ``fraction`` times umax (V); the common w0 is the smallest over the
    orders (bisection on log w0 within [0.1, 1000] rad/s, 1 % resolution).
    """
    p = parameters if isinstance(parameters, np.ndarray) else parameter_vector(parameters)

    def fits(w0: float, order: int) -> bool:
        d = design_controller(p, y, order=order, w0=w0, lambda_e=lambda_e,
                              compensate=compensate, placement=placement,
                              valve=valve)  # fmt: skip
        extra = d.compensation.amplitude if d.compensation else 0.0
        return peak_command(d, step) + extra <= fraction * umax

    best = math.inf
    for order in orders:
        lo, hi = math.log(0.1), math.log(1000.0)
        if not fits(math.exp(lo), order):
            raise PneumafitInputError(
                f"w0: no design of order {order} keeps a {step * 1e3:g} mm step within "
                f"{fraction * umax:g} V, even at w0 = 0.1 rad/s"
            )
        while hi - lo > 0.01:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if fits(math.exp(mid), order) else (lo, mid)
        best = min(best, math.exp(lo))
    return float(best)


def compare_controllers(
    parameters: Mapping[str, float] | np.ndarray,
    *,
    w0: float = 10.0,
    y_mid: float | None = None,
    steps: Sequence[float] = (0.03, 0.0, -0.03, 0.0),
    hold: float = 2.5,
    lambda_e: float = 15.0,
    umax: float = 10.0,
    plant: ModelStructure | str = "convection",
    plant_parameters: Mapping[str, float] | np.ndarray | None = None,
    orders: tuple[int, ...] = (4, 6),
    compensate: bool = True,
    placement: str = "dominant",
    valve: str | None = None,
) -> list[ClosedLoopResult]:
    """Step responses of the order-4 and order-6 designs on the nonlinear plant.

    Parameters
    ----------
    parameters : mapping or ndarray
        SI parameter values the designs use (fitted values, or a rig's truth).
    w0 : float
        ITAE frequency scale of both designs (rad/s): equal closed-loop speed,
        so that the air each consumes compares like with like.
    y_mid : float, optional
        Design and operating position (m); default half stroke.
    steps : sequence of float
        Reference offsets from y_mid (m), one per hold, after 0.5 s at y_mid.
    hold : float
        Time at each reference (s).
    lambda_e : float
        Nominal lambda of the order-6 design (W/m^2/K).
    umax : float
        Command limit (V).
    plant : ModelStructure or str
        The nonlinear model the controllers drive (``"convection"``: variable
        lambda, stiction; a rig's truth structure where there is one).
    plant_parameters : mapping or ndarray, optional
        The plant's parameters (e.g. a rig's truth when designing on a fit);
        default ``parameters``.
    orders : tuple of int
        Designs to compare.
    compensate : bool
        Dead-band compensation (module docstring).
    placement : {"dominant", "itae"}
        Pole choice (:func:`design_poles`).
    valve : {"iso6358", "map"}, optional
        Valve law of ``parameters``; default the plant's (when the designs
        use the plant's parameters, the plant's law is theirs).

    Returns
    -------
    list of ClosedLoopResult
        One per order; a design that fails on the plant has ``ok`` False.
    """
    p = parameters if isinstance(parameters, np.ndarray) else parameter_vector(parameters)
    if plant_parameters is None:
        p_plant = p
    elif isinstance(plant_parameters, np.ndarray):
        p_plant = plant_parameters
    else:
        p_plant = parameter_vector(plant_parameters)
    stroke = float(p[P["stroke"]])
    y_mid = 0.5 * stroke if y_mid is None else float(y_mid)
    offsets = [float(s) for s in steps]
    if not offsets:
        raise PneumafitInputError("steps: expected at least one reference step, found none")
    for s in offsets:
        if not 0.0 < y_mid + s < stroke:
            raise PneumafitInputError(
                f"steps: expected references inside the stroke (0, {stroke:g}) m, "
                f"found {y_mid + s:g} m (offset {s:+g} m from {y_mid:g} m)"
            )
    if not hold > 0:
        raise PneumafitInputError(f"hold: expected a positive time in s, found {hold}")
    t, y_ref, starts = step_reference(y_mid, offsets, hold=hold)
    plant_structure = get_structure(plant)
    design_valve = plant_structure.valve if valve is None else valve
    sim = Simulator(plant_structure, channels=CHANNELS)
    results = []
    for order in orders:
        design = design_controller(p, y_mid, order=order, w0=w0, lambda_e=lambda_e,
                                   compensate=compensate, placement=placement,
                                   valve=design_valve)  # fmt: skip
        eq = design.model.equilibrium
        exp = Experiment(time=t, kind="step", y_ref=y_ref, controller=design.controller(umax),
                         initial={"y": y_mid, "p_P": eq.p_P, "p_N": eq.p_N, "T_P": eq.T,
                                  "T_N": eq.T}, name=design.name)  # fmt: skip
        r = sim.simulate(p_plant, exp)
        if not r.ok:
            results.append(ClosedLoopResult(design, t, y_ref, r.channels, False, r.message,
                                            float("nan"), float("nan")))  # fmt: skip
            continue
        leak = eq.leakage_P + eq.leakage_N
        metrics = _step_metrics(t, r.channels, y_ref, starts, umax, leak, p_plant)
        u = np.abs(r["u_P"])
        results.append(ClosedLoopResult(
            design=design, time=t, y_ref=y_ref, channels=r.channels, ok=True,
            message="ok", air_mass=r.air.mass_supplied, exergy=r.air.exergy, steps=metrics,
            max_abs_u=float(u.max()), saturation=float(np.mean(u >= umax * (1 - 1e-12))),
            stiction_band=stiction_band(design, p_plant, plant_structure.valve),
        ))  # fmt: skip
    return results


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


def result_document(result: ClosedLoopResult) -> dict:
    """JSON-ready summary of one controller's test (SI units, NaN as null)."""
    d = result.design
    comp = d.compensation
    doc = {
        "name": d.name,
        "order": d.order,
        "design_model": "polytropic (eq. 14)" if d.order == 4 else "heat, lambda frozen (eq. 13)",
        "w0_rad_s": d.w0,
        "placement": d.placement,
        "poles": [[float(z.real), float(z.imag)] for z in d.poles],
        "states": list(d.model.states),
        "K": [float(k) for k in d.gain],
        "K_units": ["V/m", "V s/m", "V/Pa", "V/Pa", "V/K", "V/K"][: d.order],
        "u_e_V": float(d.model.equilibrium.u),
        "v_e_V": float(d.model.v_e),
        "compensation": (
            None if comp is None else {"amplitude_V": comp.amplitude, "width_V": comp.width}
        ),
        "ok": result.ok,
        "message": result.message,
    }
    if not result.ok:
        return doc
    doc.update({
        "air_mass_kg": _num(result.air_mass),
        "exergy_J": _num(result.exergy),
        "max_abs_u_V": _num(result.max_abs_u),
        "stiction_band_m": _num(result.stiction_band),
        "saturation_fraction": _num(result.saturation),
        "steps": [{
            "start_s": s.start, "target_m": s.target, "size_m": s.size,
            "overshoot_m": s.overshoot, "settling_time_s": _num(s.settling_time),
            "final_error_m": s.final_error, "air_mass_kg": s.air_mass,
            "leakage_mass_kg": s.leakage_mass, "exergy_J": s.exergy,
            "max_abs_u_V": s.max_abs_u, "saturation_fraction": s.saturation,
        } for s in result.steps],
    })  # fmt: skip
    return doc


def independent_truth(document: object) -> str | None:
    """Name of the independent truth a virtual rig's truth.json describes
    (key ``truth_model``, :mod:`pneumafit.virtual_rig.truth`: laws the compiled model
    does not have, so it cannot run it as a plant), or None."""
    if not isinstance(document, dict) or "truth_model" not in document:
        return None
    model = document["truth_model"]
    config = model.get("config") if isinstance(model, dict) else None
    return str((config or {}).get("name", "?"))


def read_plant_file(path: str | Path) -> tuple[ModelStructure, dict[str, float]]:
    """Structure and SI parameters of a plant: a parameter file, a fit.json,
    or a virtual rig's ``truth.json`` (its structure, e.g. Sutherland air).

    Raises
    ------
    PneumafitInputError
        Unreadable file or bad entries.
    """
    from pneumafit.parameters_io import parse_parameters, parse_structure, read_document

    file = Path(path)
    document = read_document(file)  # JSON or TOML; a fit.json checked by its reader
    if isinstance(document, dict) and document.get("format") == "pneumafit-truth":
        name = independent_truth(document)
        if name is not None:
            raise PneumafitInputError(
                f"{file}: expected the truth of a rig simulated with the fitted models' laws, "
                f"found an independent truth ({name!r}: its own valve, friction and heat laws, "
                "key truth_model) that the compiled model cannot run; give a fit.json or a "
                "parameter file as the plant"
            )
        spec = document.get("model", {})
        try:
            structure = ModelStructure(
                heat=spec["heat"], air_properties=spec.get("air_properties", "constant"),
                effects=spec.get("effects", {}), name="rig truth",
                valve=spec.get("valve", "iso6358"), friction=spec.get("friction", "switch"),
            )  # fmt: skip
        except (KeyError, TypeError, ValueError) as exc:
            raise PneumafitInputError(
                f"{file}: model: expected a truth model (heat, air_properties), found {exc}"
            ) from None
        values = document.get("parameters", {})
        _, values = parse_parameters({"model": spec["heat"], "parameters": values}, str(file))
        return structure, values
    model, values = parse_parameters(document, str(file))
    # valve law, friction law, effects and air properties of a fit.json
    structure = parse_structure(document, model, str(file))
    return structure, values
