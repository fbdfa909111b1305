"""Helpers of the discovery tests (imported by name: pytest puts this folder on sys.path)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pneumafit.discovery import ResidualReport, residual_analysis
from pneumafit.simulation import Experiment, Simulator
from pneumafit.virtual_rig import RigRun, VirtualRig

#: Seed of the single-campaign rig tests.
SEED = 5


def truth_residuals(
    run: RigRun,
    model: VirtualRig,
    *,
    initial: str = "truth",
    offsets: bool = True,
    channels: Sequence[str] = ("p_P", "p_N", "y"),
    **options: Any,
) -> dict[str, ResidualReport]:
    """Residual reports of a rig run's charge, discharge and step tests,
    simulated with ``model``'s structure and parameters (Kutta RK3, 1 ms).

    Parameters
    ----------
    initial : {"truth", "recording"}
        Start each simulation from the true initial state of the test
        (truth.json), or from the first recorded samples
        (``Experiment.from_recording``, as for a real bench).
    offsets : bool
        Add the drawn pressure-sensor offsets to the simulated pressures.

    With ``initial="truth"`` and ``offsets`` the residual is the sensor noise
    plus whatever the model leaves out.
    """
    sim = Simulator(model.structure)
    drawn: Mapping[str, float] = run.truth["sensors"]["pressure_offsets"]
    states = {r["file"]: r.get("initial_state", {}) for r in run.truth["recordings"]}
    reports = {}
    for rec in run.campaign.recordings:
        if rec.kind == "flow":
            continue
        exp = Experiment.from_recording(rec)
        if initial == "truth":
            exp = dataclasses.replace(exp, initial={**exp.initial, **states[rec.file]})
        result = sim.simulate(model.parameters, exp)
        assert result.ok, result.message
        simulated = dict(result.channels)
        if offsets:
            for name, offset in drawn.items():
                simulated[name] = simulated[name] + offset
        names = [c for c in channels if c in rec.channels]
        reports[rec.file] = residual_analysis(rec, simulated, channels=names, **options)
    return reports


def white_noise(seed: int, n: int) -> np.ndarray:
    """Standard white noise from a seeded generator."""
    return np.random.default_rng(seed).standard_normal(n)


def ar1(seed: int, n: int, phi: float) -> np.ndarray:
    """AR(1) series x_t = phi x_{t-1} + w_t, started in its stationary law."""
    w = white_noise(seed, n)
    x = np.empty(n)
    x[0] = w[0] / np.sqrt(1.0 - phi**2)
    for t in range(1, n):
        x[t] = phi * x[t - 1] + w[t]
    return x


# ------------------------------------------------------------ discovery loop
BAR = 1.0e5
#: Seed of the discovery-loop campaigns.
LOOP_SEED = 5

#: Effect sizes used by the loop tests (None: the rig's EFFECT_DEFAULTS, all
#: clearly visible on :func:`discovery_protocol`; see tests/discovery/test_loop.py).
LOOP_EFFECTS: dict[str, float | None] = {
    "chamber_leakage": None,
    "external_leakage": None,
    "valve_dynamics": None,
    "wall_thermal_mass": None,
    "forced_convection": None,
    "supply_pressure_drop": None,
    "seal_friction": None,
    "friction_asymmetry": None,
    "effective_area": None,
}


def _fit_laws_truth(**parts: Any) -> dict[str, Any]:
    """The independent truth's ``fit-laws`` preset (the fitted laws where the
    truth can express them; LuGre bristle friction) with some parts changed."""
    import copy

    from pneumafit.virtual_rig.truth import PRESETS

    data = copy.deepcopy(dict(PRESETS["fit-laws"]))
    for key, value in parts.items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    return data


#: Campaigns recorded by the *independent* truth (:mod:`pneumafit.virtual_rig.truth`,
#: written apart from the fitting kernel): the ``fit-laws`` preset with one
#: seal or barrel effect at the catalog's typical size, the preset itself
#: (nothing hidden), and a valve law no catalog effect describes (power-law
#: supply path: the effect outside the catalog). Keys name the cases.
TRUTH_CASES: dict[str, dict[str, Any]] = {
    "truth:seal_friction": _fit_laws_truth(friction={"seal": "additive", "c_p": 1.5e-5}),
    "truth:friction_asymmetry": _fit_laws_truth(friction={"asymmetry": 0.2}),
    # a bore 2.5 % wider than the declared 32 mm: area factor 1.0506
    "truth:effective_area": _fit_laws_truth(barrel={"bore": 0.0328}),
    "truth:clean": _fit_laws_truth(),
    "truth:outside": _fit_laws_truth(
        valve={"supply": {"family": "power", "C_max": 1.0e-8, "u0": 0.3, "u_sat": 10.0,
                          "n": 1.6, "b": 0.3}},
    ),
}  # fmt: skip


def discovery_protocol() -> Any:
    """Small protocol where every catalog effect shows in the pressures.

    Fit: flow tests of both valves (valve stage), a charge of P at 0.1 m, a
    discharge of P at 0.3 m and a charge of N at 0.3 m (2 s: filling,
    emptying and 1.5 s of relaxation: leakages, wall mass, forced convection,
    spool lag, supply drop), one closed-loop step test (2.5 s: friction, and
    both chambers at once, which sets chamber leakage apart from external
    leakage). Validate: a charge of P at another position and amplitude, a
    discharge of N, a second step test (2 s).

    A shorter version (1.5-s tests, one 1.5-s step test) was tried first: its
    base fits landed in a poor friction optimum (position RMSE 2.3 mm against
    0.2 mm here) from which no refit recovers the hidden effect.
    """
    from pneumafit.virtual_rig import BlockedTest, FlowTest, Protocol, StepTest

    cmds = (-10.0, -3.0, -0.4, -0.2, 0.0, 0.2, 0.4, 3.0, 10.0)
    pressures = (2.0 * BAR, 4.0 * BAR, 6.0 * BAR)
    tests = (
        FlowTest(file="flow_P.h5", chamber="P", commands=cmds, pressures=pressures, dwell=0.4),
        FlowTest(file="flow_N.h5", chamber="N", commands=cmds, pressures=pressures, dwell=0.4),
        BlockedTest(file="charge_P.h5", kind="charge", chamber="P", position=0.1,
                    amplitude=10.0, opening_time=0.3, duration=2.0),
        BlockedTest(file="discharge_P.h5", kind="discharge", chamber="P", position=0.3,
                    amplitude=8.0, opening_time=0.5, duration=2.0),
        BlockedTest(file="charge_N.h5", kind="charge", chamber="N", position=0.3,
                    amplitude=10.0, opening_time=0.25, duration=2.0),
        StepTest(file="step_1.h5", start=0.25, steps=((0.3, 0.35), (1.4, 0.18)), duration=2.5,
                 preroll=2.0),
        BlockedTest(file="charge_P_v.h5", kind="charge", chamber="P", position=0.25,
                    amplitude=6.0, opening_time=0.4, duration=2.0, role="validate"),
        BlockedTest(file="discharge_N_v.h5", kind="discharge", chamber="N", position=0.2,
                    amplitude=10.0, opening_time=0.4, duration=2.0, role="validate"),
        StepTest(file="step_v.h5", start=0.3, steps=((0.3, 0.2), (1.2, 0.32)), duration=2.0,
                 preroll=2.0, role="validate"),
    )  # fmt: skip
    return Protocol(name="discovery-small", description="discovery loop tests", tests=tests)


@dataclasses.dataclass
class DiscoveryCase:
    """A campaign with a hidden effect, its base fit and the discovery result."""

    effect: str | None
    folder: Any
    campaign: Any
    truth: dict[str, Any]
    fit_path: Any
    result: Any
    seconds: float


def run_case(root: Any, effect: str | None, value: float | None = None) -> DiscoveryCase:
    """Record the campaign (virtual rig: DP5 0.1 ms truth, sensor noise), fit
    the base convection model (no MCMC, no solver correction: faster, and
    discovery reads the option from fit.json), write fit.json, discover."""
    import time

    from pneumafit.campaign import read_campaign
    from pneumafit.discovery.refit import BaseFit, discover
    from pneumafit.identification import FitOptions, fit_document, identify, write_fit_json

    t0 = time.perf_counter()
    name = (effect or "clean").replace(":", "_")
    folder = root / name
    if effect in TRUTH_CASES:
        rig = VirtualRig(seed=LOOP_SEED, truth=TRUTH_CASES[effect])
    else:
        if effect is None:
            effects: dict[str, float | None] = {}
        else:
            effects = {effect: LOOP_EFFECTS.get(effect) if value is None else value}
        rig = VirtualRig(seed=LOOP_SEED, effects=effects)
    run = rig.write(folder, discovery_protocol())
    campaign = read_campaign(folder)
    options = FitOptions(mcmc=False, correct_solver=False)
    fit = identify(campaign, "convection", options=options, seed=0)
    fit_path = root / f"{name}_fit" / "fit.json"
    fit_path.parent.mkdir(parents=True, exist_ok=True)
    write_fit_json(fit_path, fit_document(fit, campaign, seed=0, options=options))
    import json

    base = BaseFit.from_document(json.loads(fit_path.read_text()))
    result = discover(campaign, base, seed=0)
    _record(effect, result, dict(run.truth), time.perf_counter() - t0)
    return DiscoveryCase(
        effect=effect, folder=folder, campaign=campaign, truth=dict(run.truth),
        fit_path=fit_path, result=result, seconds=time.perf_counter() - t0,
    )  # fmt: skip


#: Every campaign of the loop tests, longest first (two workers share them).
LOOP_CASES: tuple[str | None, ...] = (
    "forced_convection", "seal_friction", "external_leakage", "valve_dynamics",
    "chamber_leakage", "supply_pressure_drop", "wall_thermal_mass", "friction_asymmetry",
    "effective_area", None,
)  # fmt: skip


def _case_worker(args: tuple[Any, str | None]) -> DiscoveryCase:
    return run_case(*args)


def run_cases(root: Any, effects: Sequence[str | None], workers: int = 2) -> dict:
    """:func:`run_case` for several campaigns, in ``workers`` processes.

    Each process runs its compiled simulations on one thread
    (``NUMBA_NUM_THREADS=1``): the base fits and refits are mostly serial
    Python between batched simulations, so two processes use two cores far
    better than one process with two threads (measured: 6 min 52 s of CPU for
    10 min 15 s of wall time, one process on two loaded cores).
    """
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    effects = list(effects)
    workers = max(1, min(workers, len(effects), os.cpu_count() or 1))
    if workers == 1:
        return {e: run_case(root, e) for e in effects}
    old = os.environ.get("NUMBA_NUM_THREADS")
    os.environ["NUMBA_NUM_THREADS"] = "1"
    try:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            done = list(pool.map(_case_worker, [(root, e) for e in effects]))
    finally:
        if old is None:
            os.environ.pop("NUMBA_NUM_THREADS", None)
        else:
            os.environ["NUMBA_NUM_THREADS"] = old
    return dict(zip(effects, done, strict=True))


def _record(effect: str | None, result: Any, truth: dict[str, Any], seconds: float) -> None:
    """Append the case's numbers to $DISCOVERY_SUMMARY (JSON lines), if set:
    the measured table of docs/effects.md comes from there."""
    import json
    import os

    target = os.environ.get("DISCOVERY_SUMMARY")
    if not target:
        return
    final = result.final
    line = {
        "effect": effect,
        "selected": result.selected,
        "unexplained": result.unexplained,
        "statement": result.statement,
        "seconds": seconds,
        "discover_seconds": result.seconds,
        "validate_before": result.base.rmse.get("validate"),
        "validate_after": final.rmse.get("validate"),
        "fit_before": result.base.rmse.get("fit"),
        "fit_after": final.rmse.get("fit"),
        "noise": result.noise,
        "ranking": [
            [c.effect, c.score, c.inclusion_probability, c.variance_explained, c.phase_match]
            for c in result.attributions[0].candidates
        ] if result.attributions else [],
        "steps": [[s.round, s.effect, s.start, s.reason] for s in result.steps],
        "values": {k: final.values[k] for e in final.effects
                   for k in EFFECT_PARAMETERS.get(e, ())},
        "truth": {k: truth["parameters"].get(k) for k in truth["parameters"]
                  if k in {p for v in EFFECT_PARAMETERS.values() for p in v}},
    }  # fmt: skip
    with open(target, "a", encoding="utf-8") as f:
        f.write(json.dumps(line, default=float) + "\n")


#: Principal parameters reported per effect.
EFFECT_PARAMETERS = {
    "chamber_leakage": ("chamber_leak_conductance",),
    "external_leakage": ("external_leak_conductance",),
    "valve_dynamics": ("valve_time_constant",),
    "wall_thermal_mass": ("wall_heat_capacity", "wall_outer_coefficient"),
    "forced_convection": ("forced_convection_gain",),
    "supply_pressure_drop": ("supply_line_resistance",),
    "seal_friction": ("seal_friction_coefficient",),
    "friction_asymmetry": ("friction_asymmetry",),
    "effective_area": ("area_factor",),
}
