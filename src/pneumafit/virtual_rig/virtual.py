"""The virtual rig: a stand-in for a real bench, as the paper's AMESim prototype was.

From a true parameter set it produces a whole campaign as a rig engineer
would record it (docs/virtual-rig.md):

- the truth is richer than the fitted structures: full-convection heat
  transfer (variable lambda, paper eq. 8) with Sutherland air properties at
  the gas temperature, stiction with a Stribeck curve, valve centre leakage,
  and any optional effect switched on by name (:mod:`.effects`);
- it is simulated with a 5th-order method (Dormand-Prince) at a 0.1-ms step,
  ten times finer than the fitting simulator's default (Kutta RK3 at 1 ms);
- sensors add noise, offsets, quantisation and lags (:class:`SensorModel`);
- the true parameters, effects, seed and sensor settings go to a separate
  ``truth.json``, never to ``campaign.toml``.

>>> rig = VirtualRig(effects={"chamber_leakage": None}, seed=7)   # doctest: +SKIP
>>> run = rig.run("quick")                                         # doctest: +SKIP
>>> rig.write("my-campaign", "demo")                               # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, fields
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign import (
    Campaign,
    PDController,
    PneumafitInputError,
    Recording,
    Rig,
    write_campaign,
)
from pneumafit.errors import PneumafitComputationError
from pneumafit.fileio import temporary_folder
from pneumafit.models import (
    PARAMETER_SPECS,
    ModelStructure,
    parameter_dict,
    parameter_vector,
)
from pneumafit.models.layout import SPECS
from pneumafit.models.structure import INPUT_MODE
from pneumafit.physics.geometry import piston_areas
from pneumafit.simulation import (
    PD,
    Experiment,
    Simulation,
    Simulator,
    choose_step,
    spool_mode,
)
from pneumafit.virtual_rig.effects import resolve_effects
from pneumafit.virtual_rig.protocol import (
    FLOW_COMPUTE_RATE,
    PROTOCOLS,
    BlockedTest,
    FlowTest,
    Protocol,
    StepTest,
    Test,
    get_protocol,
)
from pneumafit.virtual_rig.sensors import SensorModel
from pneumafit.virtual_rig.truth import (
    PRESETS,
    TRUTH_FORMAT,
    TruthConfig,
    TruthSimulation,
    TruthSimulator,
    get_truth,
    reference_quantities,
)

__all__ = [
    "DEMO_SEED",
    "DEMO_TRUTH",
    "DEMO_TRUTH_PRESET",
    "TRUTH_FILE",
    "TRUTH_FORMAT",
    "TRUTH_METHOD",
    "TRUTH_STEP",
    "RigError",
    "RigRun",
    "TruthTrace",
    "VirtualRig",
]

#: True parameters of the demo rig (SI): the paper's bench (17 kg, 0.5 m
#: stroke, 7 bar absolute supply) with a 32/20 mm cylinder; everything not
#: listed takes its :data:`pneumafit.models.PARAMETER_SPECS` default (valve,
#: numerics), ``wall_temperature`` follows ``ambient_temperature`` and
#: ``characteristic_length`` the bore.
DEMO_TRUTH: dict[str, float] = {
    "bore": 0.032,
    "rod": 0.020,
    "stroke": 0.5,
    "dead_volume_P": 2.5e-5,
    "dead_volume_N": 3.0e-5,
    "moving_mass": 17.0,
    "supply_pressure": 7.0e5,
    "exhaust_pressure": 1.013e5,
    "ambient_temperature": 293.15,
    "xi": 0.4,
    "beta": 0.27,
    "friction_static": 50.0,
    "friction_coulomb": 30.0,
    "friction_viscous": 60.0,
    "stribeck_velocity": 0.02,
}

#: Seed of the committed demo campaign.
DEMO_SEED = 2026
#: Independent truth of the committed demo campaign (a preset of
#: :data:`pneumafit.virtual_rig.truth.PRESETS`): data/demo is
#: ``pneumafit rig --out data/demo --seed 2026 --truth demo``, a rig whose
#: valve, leak, friction and probes are not the fitted models' laws and whose
#: chambers leak to the atmosphere (an effect campaign.toml does not declare).
DEMO_TRUTH_PRESET = "demo"
#: Independent truth of the clean demo campaign: data/demo-clean is
#: ``pneumafit rig --out data/demo-clean --seed 2026 --truth demo-clean``, the
#: same rig without the undeclared leak (its recordings are those of data/demo
#: before commit ab282c3 of 2026-11-25).
DEMO_CLEAN_TRUTH_PRESET = "demo-clean"
#: Largest integration step of the truth (s); the fitting default is 1 ms.
TRUTH_STEP = 1.0e-4
#: Integration method of the truth (fixed-step Dormand-Prince, 5th order).
TRUTH_METHOD = "dp5"
#: Name of the truth file in a campaign folder (not listed in campaign.toml).
TRUTH_FILE = "truth.json"
#: ``version`` of the truth file (its ``format``: :data:`TRUTH_FORMAT`).
TRUTH_VERSION = 1
#: Version of the virtual rig's protocols and sensor models; bump it when the
#: same seed would give a different campaign.
RIG_VERSION = 1

_RIG_FIELDS = tuple(f.name for f in fields(Rig))


class RigError(PneumafitComputationError):
    """The virtual rig could not make a campaign (a simulation failed)."""


@dataclass(frozen=True)
class TruthTrace:
    """Noise-free signals of one test at its recorded sample times.

    Attributes
    ----------
    time : ndarray
        Recording times (s).
    channels : dict of str to ndarray
        True SI values: pressures (Pa), gas temperatures (K), position (m),
        velocity (m/s), commands as sent (V), valve flows (kg/s), lambda
        (W/m^2/K), friction (N), as the test provides them.
    """

    time: NDArray[np.float64]
    channels: dict[str, NDArray[np.float64]]


@dataclass
class RigRun:
    """What one run of the virtual rig produced.

    Attributes
    ----------
    campaign : Campaign
        The recordings as measured (``path`` set once written).
    truth : dict
        Content of ``truth.json`` (see :meth:`VirtualRig.truth_record`).
    traces : dict of str to TruthTrace
        True signals by recording file name.
    """

    campaign: Campaign
    truth: dict[str, Any]
    traces: dict[str, TruthTrace]


def _version() -> str:
    try:
        return metadata.version("pneumafit")
    except metadata.PackageNotFoundError:
        return "unknown"


class VirtualRig:
    """A simulated bench that records campaigns.

    Parameters
    ----------
    truth_parameters : mapping of str to float, optional
        True parameter values (SI, names of
        :data:`pneumafit.models.PARAMETER_SPECS`) overriding
        :data:`DEMO_TRUTH`.
    effects : mapping of str to float or None, optional
        Optional effects of the truth: effect name (value sets its principal
        parameter) or effect parameter name -> SI value, None for the default
        magnitude (:func:`pneumafit.virtual_rig.effects.resolve_effects`). They win
        over ``truth_parameters``.
    sensors : SensorModel, optional
        Sensor noise, offsets, resolution and lags; default
        :class:`SensorModel` ().
    seed : int or None
        Seed of the one random generator every draw comes from (offsets,
        noise); None draws fresh entropy, kept in :attr:`seed` and in
        ``truth.json``. Same seed, same campaign.
    step : float
        Largest truth integration step (s); reduced if the model's stiffness
        bound asks for it.
    method : str
        Truth integration method (``"dp5"``).
    air_properties : {"sutherland", "constant"}
        Air viscosity and conductivity in the Grashof number.
    truth : TruthConfig, str or None
        An independently simulated truth (:mod:`pneumafit.virtual_rig.truth`): a
        configuration, a preset name or a TOML/JSON file. Its valve,
        friction, heat and probe parts replace the fitted laws, its
        ``parameters`` table overrides ``truth_parameters``; the rig's
        geometry and conditions come from the parameter set. None (default)
        simulates the truth with the fitting kernel, as before.
    truth_rtol : float
        Relative tolerance of the independent truth's integrator.
    inputs : {"hold", "linear"}
        How the fitting kernel, when it is the truth (``truth`` None), reads
        the tests' sampled commands and set-points between samples
        (:attr:`pneumafit.models.ModelStructure.inputs`); an independent
        truth always holds them.

    Raises
    ------
    PneumafitInputError
        Unknown parameter or effect name, a value out of bounds, a negative
        seed, an unknown method, a bad truth configuration, or effects
        requested together with an independent truth.
    """

    def __init__(
        self,
        truth_parameters: Mapping[str, float] | None = None,
        effects: Mapping[str, float | None] | None = None,
        *,
        sensors: SensorModel | None = None,
        seed: int | None = DEMO_SEED,
        step: float = TRUTH_STEP,
        method: str = TRUTH_METHOD,
        air_properties: str = "sutherland",
        truth: TruthConfig | str | None = None,
        truth_rtol: float = 1e-8,
        inputs: str = INPUT_MODE,
    ) -> None:
        if seed is None:
            seed = int(np.random.SeedSequence().entropy)  # type: ignore[arg-type]
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise PneumafitInputError(f"seed: expected an integer >= 0, found {seed!r}")
        self.seed = int(seed)
        self.sensors = sensors if sensors is not None else SensorModel()
        self.effects_requested = dict(effects or {})
        resolved = resolve_effects(self.effects_requested)
        self.truth: TruthConfig | None = None
        if truth is not None:
            if self.effects_requested:
                raise PneumafitInputError(
                    "--truth: an independent truth has its own parts; expected no --effect "
                    f"with it, found {', '.join(self.effects_requested)}"
                )
            self.truth = get_truth(truth)
        own = dict(self.truth.parameters) if self.truth is not None else {}
        values = {**DEMO_TRUTH, **dict(truth_parameters or {}), **resolved.parameters, **own}
        try:
            vector = parameter_vector(values)
        except ValueError as exc:
            raise PneumafitInputError(f"truth parameters: {exc}") from None
        self.parameters: dict[str, float] = parameter_dict(vector)
        try:
            self.structure = ModelStructure(
                "convection",
                air_properties=air_properties,
                effects=resolved.structure,
                inputs=inputs,
            )
        except ValueError as exc:
            raise PneumafitInputError(str(exc)) from None
        self.structure = self.structure.with_effects()  # name lists the effects
        mode = spool_mode(self.structure, vector)
        self.step = float(min(step, choose_step(vector, default=step, spool=mode)))
        self.method = method
        try:
            self.simulator = Simulator(self.structure, step=self.step, method=method)
        except (KeyError, ValueError) as exc:
            raise PneumafitInputError(
                f"truth simulator: expected a method of pneumafit.simulation (e.g. 'dp5') and a "
                f"step > 0, found method={method!r}, step={step!r} ({exc})"
            ) from None
        self.truth_simulator: TruthSimulator | None = None
        if self.truth is not None:
            try:
                self.truth_simulator = TruthSimulator(self.truth, rtol=truth_rtol)
            except ValueError as exc:
                raise PneumafitInputError(str(exc)) from None

    # ------------------------------------------------------------------ campaign
    @property
    def rig(self) -> Rig:
        """The rig as declared in campaign.toml (true geometry and conditions)."""
        return Rig(**{name: self.parameters[name] for name in _RIG_FIELDS})

    def run(self, protocol: str | Protocol = "demo") -> RigRun:
        """Record every test of a protocol.

        Parameters
        ----------
        protocol : str or Protocol
            ``"demo"``, ``"quick"`` or a protocol.

        Returns
        -------
        RigRun
            The campaign (in memory), the truth record and the true signals.

        Raises
        ------
        RigError
            A truth simulation failed.
        """
        proto = get_protocol(protocol).for_stroke(self.parameters["stroke"])
        root = np.random.default_rng(self.seed)
        children = root.spawn(len(proto.tests) + 1)
        offsets = self.sensors.draw_offsets(children[0])
        recordings: list[Recording] = []
        traces: dict[str, TruthTrace] = {}
        for test, rng in zip(proto.tests, children[1:], strict=True):
            if isinstance(test, FlowTest):
                rec, trace = self._flow(test, rng, offsets)
            elif isinstance(test, BlockedTest):
                rec, trace = self._blocked(test, rng, offsets)
            else:
                rec, trace = self._step(test, rng, offsets)
            if test.columns:
                rec.columns = {column: ch for ch, column in test.columns.items()}
            recordings.append(rec)
            traces[test.file] = trace
        label = proto.name if self.truth is None else f"{proto.name}-{self.truth.name}"
        campaign = Campaign(
            path=None,
            name=f"virtual-rig-{label}-seed-{self.seed}",
            description=proto.description,
            rig=self.rig,
            recordings=recordings,
        )
        truth = self.truth_record(proto, offsets, traces)
        return RigRun(campaign=campaign, truth=truth, traces=traces)

    def campaign(self, protocol: str | Protocol = "demo") -> Campaign:
        """The campaign of a protocol, in memory (see :meth:`run`)."""
        return self.run(protocol).campaign

    def write(self, out: str | os.PathLike[str], protocol: str | Protocol = "demo") -> RigRun:
        """Record a protocol and write the campaign folder, atomically.

        Writes ``campaign.toml`` and the recordings, ``truth.json`` and a
        ``README.md`` listing the true parameters, all into a temporary folder
        next to ``out`` that is then renamed to ``out``: a reader never sees a
        half-written campaign. An existing ``out`` is replaced only when it is
        empty or was written by the virtual rig (it holds a ``truth.json``).

        Parameters
        ----------
        out : str or os.PathLike
            Campaign folder to create or replace.
        protocol : str or Protocol

        Returns
        -------
        RigRun
            With ``campaign.path`` set to ``out``.

        Raises
        ------
        PneumafitInputError
            ``out`` is a file, or a folder with other content.
        RigError
            A truth simulation failed.
        """
        target = Path(out)
        check_output_folder(target)
        run = self.run(protocol)
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = temporary_folder(target)
        try:
            write_campaign(tmp, run.campaign)
            _write_text(tmp / TRUTH_FILE, json.dumps(run.truth, indent=2) + "\n")
            _write_text(tmp / "README.md", truth_readme(run))
            _replace_folder(tmp, target)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
        run.campaign.path = target
        return run

    # ------------------------------------------------------------------ tests
    @property
    def wall_temperature(self) -> float:
        """True wall temperature (K): the independent truth's, else the parameter set's."""
        if self.truth is not None and self.truth.heat.wall_temperature is not None:
            return float(self.truth.heat.wall_temperature)
        return self.parameters["wall_temperature"]

    def _temperature(
        self, true: NDArray[np.float64], dt: float, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """Reading of a gas-temperature sensor: the truth's probe if it names one."""
        if self.truth is not None and self.truth.probe is not None:
            return self.truth.probe.read(true, dt, rng)
        return self.sensors.temperature(true, dt, rng)

    def _simulate(self, experiment: Experiment) -> Simulation | TruthSimulation:
        if self.truth_simulator is not None:
            sim = self.truth_simulator.simulate(self.parameters, experiment)
        else:
            sim = self.simulator.simulate(self.parameters, experiment)
        if not sim.ok:
            raise RigError(
                f"virtual rig: test {experiment.name!r}: the truth simulation failed "
                f"({sim.message}); check the true parameters and effects"
            )
        return sim

    def _flow(
        self, test: FlowTest, rng: np.random.Generator, offsets: Mapping[str, float]
    ) -> tuple[Recording, TruthTrace]:
        ch = test.chamber
        dt = 1.0 / FLOW_COMPUTE_RATE
        every = round(FLOW_COMPUTE_RATE / test.sample_rate)
        n_level = round(test.dwell * FLOW_COMPUTE_RATE)
        levels = [(p, u) for p in test.pressures for u in test.commands]
        p_held = np.repeat([p for p, _ in levels], n_level).astype(float)
        command = np.repeat([u for _, u in levels], n_level).astype(float)
        time = np.arange(p_held.size) * dt
        exp = Experiment(
            time, "flow", chamber=ch, p_chamber=p_held, name=test.file, **{f"u_{ch}": command}
        )
        sim = self._simulate(exp)
        q_true = sim[f"qm_{ch}"]
        q_meas = self.sensors.flow(q_true, dt, rng, every)
        t_rec = np.arange(q_meas.size) / test.sample_rate
        p_true = p_held[::every]
        p_meas = self.sensors.pressure(p_true, offsets[f"p_{ch}"], rng)
        u_rec = command[::every]
        channels = {f"u_{ch}": u_rec, f"p_{ch}": p_meas, f"qm_{ch}": q_meas}
        description = test.description or (
            f"flow test of valve {ch}: {len(test.commands)} commands from "
            f"{min(test.commands):g} to {max(test.commands):g} V at {len(test.pressures)} held "
            f"pressures, {test.dwell:g} s each"
        )
        rec = Recording.from_arrays(
            t_rec, channels, kind="flow", role=test.role, file=test.file, chamber=ch,
            units=test.units, description=description,
        )  # fmt: skip
        trace = TruthTrace(
            t_rec, {f"u_{ch}": u_rec, f"p_{ch}": p_true, f"qm_{ch}": q_true[::every].copy()}
        )
        return rec, trace

    def _blocked(
        self, test: BlockedTest, rng: np.random.Generator, offsets: Mapping[str, float]
    ) -> tuple[Recording, TruthTrace]:
        ch = test.chamber
        rate = test.sample_rate
        dt = 1.0 / rate
        n = round(test.duration * rate) + 1
        time = np.arange(n) * dt
        command = np.full(n, float(test.rest_command))
        k_open = round(test.delay * rate)
        k_close = k_open + round(test.opening_time * rate)
        command[k_open:k_close] = test.command
        p_start = (
            self.parameters["exhaust_pressure"]
            if test.kind == "charge"
            else self.parameters["supply_pressure"]
        )
        exp = Experiment(
            time, test.kind, chamber=ch, name=test.file,
            initial={"y": test.position, f"p_{ch}": p_start}, **{f"u_{ch}": command},
        )  # fmt: skip
        sim = self._simulate(exp)
        p_true = sim[f"p_{ch}"]
        channels = {
            f"u_{ch}": command,
            f"p_{ch}": self.sensors.pressure(p_true, offsets[f"p_{ch}"], rng),
        }
        if test.temperature:
            channels[f"T_{ch}"] = self._temperature(sim[f"T_{ch}"], dt, rng)
        description = test.description or (
            f"{test.kind} of chamber {ch}, piston blocked at {test.position * 1e3:g} mm: "
            f"{test.command:+g} V for {test.opening_time:g} s after {test.delay:g} s, "
            f"then {test.rest_command:g} V"
        )
        rec = Recording.from_arrays(
            time, channels, kind=test.kind, role=test.role, file=test.file, chamber=ch,
            piston_position=test.position, units=test.units, description=description,
        )  # fmt: skip
        trace = TruthTrace(
            time,
            {
                f"u_{ch}": command,
                f"p_{ch}": p_true,
                f"T_{ch}": sim[f"T_{ch}"],
                f"qm_{ch}": sim[f"qm_{ch}"],
                f"lambda_{ch}": sim[f"lambda_{ch}"],
            },
        )
        return rec, trace

    def _settled_pressures(self) -> tuple[float, float]:
        """Chamber pressures (Pa) that balance the piston at mid supply in N."""
        par = self.parameters
        s_p, s_n = piston_areas(par["bore"], par["rod"])
        p_e = par["exhaust_pressure"]
        p_n = 0.5 * (par["supply_pressure"] + p_e)
        p_p = (p_n * s_n + p_e * (s_p - s_n)) / s_p
        return p_p, p_n

    def _step(
        self, test: StepTest, rng: np.random.Generator, offsets: Mapping[str, float]
    ) -> tuple[Recording, TruthTrace]:
        rate = test.sample_rate
        dt = 1.0 / rate
        n_pre = round(test.preroll * rate)
        n = round(test.duration * rate) + 1
        y_ref_all = np.full(n_pre + n, float(test.start))
        for when, position in sorted(test.steps):
            y_ref_all[n_pre + round(when * rate) :] = position
        p_p0, p_n0 = self._settled_pressures()
        controller = PD(kp=test.kp, kd=test.kd, u0=test.u0, umax=test.umax)
        exp = Experiment(
            np.arange(n_pre + n) * dt, "step", y_ref=y_ref_all, controller=controller,
            initial={"y": test.start, "p_P": p_p0, "p_N": p_n0}, name=test.file,
        )  # fmt: skip
        sim = self._simulate(exp)
        rec_part = slice(n_pre, n_pre + n)
        time = np.arange(n) * dt
        true = {name: sim[name][rec_part].copy() for name in ("y", "v", "p_P", "p_N", "T_P", "T_N")}
        true.update({f"lambda_{c}": sim[f"lambda_{c}"][rec_part].copy() for c in ("P", "N")})
        true["F_f"] = sim["F_f"][rec_part].copy()
        y_ref = y_ref_all[rec_part].copy()
        # the controller's output as commanded (with spool dynamics the
        # simulated u_P channel is the spool position, not the command)
        u_p = np.clip(
            test.u0 + test.kp * (y_ref - true["y"]) - test.kd * true["v"], -test.umax, test.umax
        )
        u_n = 0.0 - u_p  # not -u_p: no "-0.0" in the files
        true.update({"u_P": u_p, "u_N": u_n, "y_ref": y_ref})
        channels = {
            "y": self.sensors.position(true["y"], rng),
            "y_ref": y_ref,
            "p_P": self.sensors.pressure(true["p_P"], offsets["p_P"], rng),
            "p_N": self.sensors.pressure(true["p_N"], offsets["p_N"], rng),
            "u_P": u_p,
            "u_N": u_n,
        }
        if test.temperature:
            for c in ("P", "N"):
                # the sensor has followed the gas through the pre-roll
                reading = self._temperature(sim[f"T_{c}"], dt, rng)
                channels[f"T_{c}"] = reading[rec_part].copy()
        steps = ", ".join(f"{pos * 1e3:g} mm at {when:g} s" for when, pos in test.steps)
        description = test.description or (
            f"closed-loop steps from {test.start * 1e3:g} mm: {steps} "
            f"(recorded after a {test.preroll:g}-s pre-roll)"
        )
        rec = Recording.from_arrays(
            time, channels, kind="step", role=test.role, file=test.file,
            controller=PDController(kp=test.kp, kd=test.kd, u0=test.u0, umax=test.umax),
            units=test.units, description=description,
        )  # fmt: skip
        return rec, TruthTrace(time, true)

    # ------------------------------------------------------------------ truth
    def truth_record(
        self,
        protocol: Protocol,
        offsets: Mapping[str, float],
        traces: Mapping[str, TruthTrace],
    ) -> dict[str, Any]:
        """Content of ``truth.json`` (format ``pneumafit-truth``, version 1).

        Keys: ``format``, ``version``, ``generator`` (program, pneumafit and
        rig versions), ``seed``, ``protocol``, ``model`` (heat law, air
        properties, effects, the structure's own parameter names),
        ``effects_requested``, ``simulator`` (method, step), ``parameters``
        (every true parameter, SI, by name) and ``units``, ``sensors``
        (settings and the drawn pressure offsets), ``recordings`` (file, kind,
        role, setup, and the true state at the first recorded sample) and
        ``diagnostics``: ``lambda_equivalent``, the constant
        heat-transfer coefficient (W/m^2/K) that would exchange the same heat
        as the true, variable one over the relaxation phases (valve back at
        rest) of the charge/discharge tests, sum(lambda |T - T_w|) /
        sum(|T - T_w|), overall and by recording.

        With an independent truth (``truth``), ``truth_model`` holds its
        configuration (``config``, :meth:`TruthConfig.as_dict`), its
        ``reference_quantities`` (:func:`pneumafit.virtual_rig.truth.reference_quantities`),
        the simulator settings and the names of the parameters it took from
        ``parameters`` (the rig's geometry and conditions; the valve,
        friction and heat entries of ``parameters`` are then not the truth).
        """
        per_test: dict[str, float] = {}
        heat_weighted = 0.0
        weights = 0.0
        t_wall = self.wall_temperature
        for test in protocol.tests:
            if not isinstance(test, BlockedTest):
                continue
            chans = traces[test.file].channels
            k = round((test.delay + test.opening_time) * test.sample_rate)
            lam = chans[f"lambda_{test.chamber}"][k:]
            d_t = np.abs(chans[f"T_{test.chamber}"][k:] - t_wall)
            if d_t.sum() > 0.0:
                per_test[test.file] = float(np.sum(lam * d_t) / np.sum(d_t))
                heat_weighted += float(np.sum(lam * d_t))
                weights += float(np.sum(d_t))
        diagnostics: dict[str, Any] = {}
        if weights > 0.0:
            diagnostics["lambda_equivalent"] = heat_weighted / weights
            diagnostics["lambda_equivalent_by_recording"] = per_test
        record = {
            "format": TRUTH_FORMAT,
            "version": TRUTH_VERSION,
            "generator": {
                "program": "pneumafit virtual rig",
                "pneumafit_version": _version(),
                "rig_version": RIG_VERSION,
            },
            "seed": self.seed,
            "protocol": protocol.name,
            "model": {
                "name": self.structure.name,
                "heat": self.structure.heat,
                "air_properties": self.structure.air_properties,
                "effects": dict(self.structure.effects),
                "parameter_names": list(self.structure.parameter_names),
            },
            "effects_requested": self.effects_requested,
            "simulator": {"method": self.method, "step": self.step},
            "parameters": dict(self.parameters),
            "units": {name: SPECS[name].unit for name in self.parameters},
            "sensors": {**self.sensors.as_dict(), "pressure_offsets": dict(offsets)},
            "recordings": [_test_summary(test, traces[test.file]) for test in protocol.tests],
            "diagnostics": diagnostics,
        }
        if self.truth is not None and self.truth_simulator is not None:
            cfg = self.truth
            record["model"] = {
                "name": f"truth:{cfg.name}",
                "heat": f"{cfg.heat.name} ({cfg.heat.area} area)",
                "air_properties": cfg.heat.air,
                "effects": {},
                "parameter_names": [],
            }
            record["simulator"] = {
                "method": f"scipy solve_ivp {self.truth_simulator.method}",
                "rtol": self.truth_simulator.rtol,
            }
            record["truth_model"] = {
                "config": cfg.as_dict(),
                "reference_quantities": reference_quantities(cfg, self.parameters),
                "simulator": {
                    "program": "pneumafit.virtual_rig.truth",
                    "method": self.truth_simulator.method,
                    "rtol": self.truth_simulator.rtol,
                },
                "parameters_used": list(_TRUTH_RIG_PARAMETERS),
                "wall_temperature": self.wall_temperature,
            }
        return record


_STATE_CHANNELS = ("y", "v", "p_P", "p_N", "T_P", "T_N")
#: Parameters an independent truth takes from the parameter set.
_TRUTH_RIG_PARAMETERS = (
    "bore", "rod", "stroke", "dead_volume_P", "dead_volume_N", "moving_mass", "supply_pressure",
    "exhaust_pressure", "ambient_temperature", "wall_temperature", "characteristic_length",
    "mounting_angle", "external_force",
)  # fmt: skip


def _test_summary(test: Test, trace: TruthTrace) -> dict[str, Any]:
    out: dict[str, Any] = {"file": test.file, "kind": test.kind, "role": test.role}
    if isinstance(test, FlowTest):
        out.update(chamber=test.chamber, commands=list(test.commands),
                   pressures=list(test.pressures), dwell=test.dwell)  # fmt: skip
    elif isinstance(test, BlockedTest):
        out.update(chamber=test.chamber, position=test.position, command=test.command,
                   opening_time=test.opening_time, delay=test.delay,
                   rest_command=test.rest_command, temperature=test.temperature)  # fmt: skip
    elif isinstance(test, StepTest):
        out.update(start=test.start, steps=[list(s) for s in test.steps], preroll=test.preroll,
                   controller={"kp": test.kp, "kd": test.kd, "u0": test.u0, "umax": test.umax},
                   temperature=test.temperature)  # fmt: skip
    out.update(sample_rate=test.sample_rate)
    if not isinstance(test, FlowTest):
        out["initial_state"] = {
            name: float(trace.channels[name][0])
            for name in _STATE_CHANNELS
            if name in trace.channels
        }
    return out


# ---------------------------------------------------------------------- files
def _write_text(path: Path, text: str) -> None:
    with open(path, "w", encoding="utf-8", newline="\n") as stream:
        stream.write(text)


def _is_rig_output(folder: Path) -> bool:
    try:
        doc = json.loads((folder / TRUTH_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("format") == TRUTH_FORMAT


def check_output_folder(out: Path) -> None:
    """Raise unless ``out`` may receive a campaign (absent, empty or a rig output).

    Raises
    ------
    PneumafitInputError
        ``out`` is a file, or a folder holding anything but a previous
        virtual-rig campaign.
    """
    if not out.exists():
        return
    if not out.is_dir():
        raise PneumafitInputError(
            f"--out {os.fspath(out)!r}: expected a folder to create, found a file"
        )
    if any(out.iterdir()) and not _is_rig_output(out):
        raise PneumafitInputError(
            f"--out {os.fspath(out)!r}: expected a new or empty folder, or one written by the "
            f"virtual rig (with a {TRUTH_FILE}), found a folder with other files"
        )


def _replace_folder(new: Path, target: Path) -> None:
    """Move the finished folder ``new`` to ``target``, replacing a previous one."""
    if not target.exists():
        os.replace(new, target)
        return
    check_output_folder(target)
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
    os.rmdir(old)
    os.replace(target, old)
    try:
        os.replace(new, target)
    except OSError:
        os.replace(old, target)  # put the previous campaign back
        raise
    shutil.rmtree(old, ignore_errors=True)


# ---------------------------------------------------------------------- README
def _fmt(value: float) -> str:
    if value == 0.0:
        return "0"
    if 1e-3 <= abs(value) < 1e5:
        return f"{value:.6g}"
    return f"{value:.4g}"


def _independent_truth_lines(independent: Mapping[str, Any]) -> list[str]:
    cfg = independent["config"]
    valve = cfg["valve"]

    def part(table: Mapping[str, Any], selector: str) -> str:
        rest = ", ".join(f"{k} = {v}" for k, v in table.items() if k != selector)
        return f"`{table[selector]}` ({rest})"

    ref = independent["reference_quantities"]
    lines = [
        f"- independent truth `{cfg['name']}` ({cfg.get('description', '')}), written "
        "apart from the fitting code (`pneumafit.virtual_rig.truth`), simulated with scipy "
        f"`{independent['simulator']['method']}` at rtol {independent['simulator']['rtol']:g}",
        f"- valve supply path: {part(valve['supply'], 'family')}",
        f"- valve exhaust path: {part(valve['exhaust'], 'family')}",
        f"- centre leak: {part(valve['leak'], 'shape')}; m = {valve['m']}, laminar above "
        f"x = {valve['x_laminar']}",
        f"- friction: {part(cfg['friction'], 'model')}",
        f"- heat: {part(cfg['heat'], 'model')}",
        "- temperature probes: " + (part(cfg["probe"], "model") if "probe" in cfg else
                                    "the sensor model's"),
        *(
            [
                "- external leak, **an undeclared effect** (campaign.toml does not name it; "
                "the fitted models have no leak to the atmosphere unless discovery adds "
                f"`external_leakage`): {part(cfg['external_leak'], 'model')}"
            ]
            if "external_leak" in cfg
            else []
        ),
        "- reference quantities: "
        + ", ".join(f"{k} = {_fmt(v)}" for k, v in ref.items()),
        "- the valve, heat and friction entries of the parameter set are not used by this "
        f"truth (only the rig's geometry and conditions, listed below); see `{TRUTH_FILE}` "
        "key `truth_model`",
    ]  # fmt: skip
    return lines


def _rig_command(truth: Mapping[str, Any]) -> str:
    """The ``pneumafit rig`` command that records the campaign of ``truth``
    (truth.json's content) again: a preset truth by name, any other by this
    folder's truth.json; a protocol the command does not name, as a comment."""
    protocol = truth["protocol"]
    head = "" if protocol in PROTOCOLS else f"# protocol {protocol!r}: a Python Protocol, run_rig\n"
    command = "pneumafit rig --out DIR"
    model = truth.get("truth_model")
    if model is not None:
        name = model["config"].get("name")
        preset = name in PRESETS and TruthConfig.from_dict(model["config"]) == get_truth(name)
        command += f" --truth {name}" if preset else f" --truth {TRUTH_FILE}"
    if protocol in PROTOCOLS and protocol != "demo":
        command += f" --protocol {protocol}"
    command += "".join(
        f" --effect {name}" + ("" if value is None else f"={value!r}")
        for name, value in truth["effects_requested"].items()
    )
    return head + command + f" --seed {truth['seed']}"


def truth_readme(run: RigRun) -> str:
    """The campaign folder's README.md: how it was made and the true parameters."""
    truth = run.truth
    specs = {s.name: s for s in PARAMETER_SPECS}
    used_groups = ("rig", "valve", "heat", "friction")
    heat_used = {"xi", "beta"}
    lines = [
        f"# Virtual-rig campaign `{run.campaign.name}`",
        "",
        "Generated by the pneumafit virtual rig "
        f"(pneumafit {truth['generator']['pneumafit_version']}, rig version "
        f"{truth['generator']['rig_version']}) with protocol `{truth['protocol']}` and seed "
        f"{truth['seed']}:",
        "",
        "```",
        _rig_command(truth),
        "```",
        "",
        "`campaign.toml` and the recordings are what a rig engineer would hand over. "
        f"`{TRUTH_FILE}` (format `{TRUTH_FORMAT}`, not listed in campaign.toml) holds the "
        "true model, every true parameter in SI units, the seed and the sensor model. "
        "See docs/virtual-rig.md.",
        "",
        "## Truth model",
        "",
        f"- structure: `{truth['model']['name']}`, heat law `{truth['model']['heat']}` "
        f"(paper eq. 8), air properties `{truth['model']['air_properties']}`",
        "- optional effects: "
        + (
            ", ".join(f"`{k}` = {v}" for k, v in truth["model"]["effects"].items())
            if truth["model"]["effects"]
            else "none"
            if "truth_model" not in truth
            else "none of `--effect`'s (the independent truth's own parts are listed below)"
        ),
    ]
    independent = truth.get("truth_model")
    if independent is None:
        lines.append(
            f"- simulated with `{truth['simulator']['method']}` at a fixed step of "
            f"{truth['simulator']['step']:g} s (the fitting default is Kutta RK3 at 1 ms)"
        )
    else:
        lines += _independent_truth_lines(independent)
    lam = truth["diagnostics"].get("lambda_equivalent")
    if lam is not None:
        by_rec = truth["diagnostics"]["lambda_equivalent_by_recording"]
        lines.append(
            f"- equivalent constant heat-transfer coefficient over the relaxation phases of "
            f"the charge/discharge tests (heat-weighted mean of the true lambda): {lam:.1f} "
            f"W/m^2/K, from {min(by_rec.values()):.1f} to {max(by_rec.values()):.1f} by "
            "recording (the paper's constant model: 15)"
        )
    lines += ["", "## True parameters (SI)", "", "| name | value | unit | meaning |"]
    lines.append("|---|---|---|---|")
    effect_params = set(truth["model"]["parameter_names"]) - heat_used
    for name, value in truth["parameters"].items():
        spec = specs[name]
        if independent is not None:
            if name not in independent["parameters_used"]:
                continue  # the independent truth's own parts replace these
        elif spec.group in used_groups and (spec.group != "heat" or name in heat_used):
            pass
        elif name not in effect_params:
            continue
        unit = spec.unit or "-"
        lines.append(f"| `{name}` | {_fmt(value)} | {unit} | {spec.description} |")
    sensors = truth["sensors"]
    lines += [
        "",
        "## Sensor model",
        "",
        "| setting | value | unit |",
        "|---|---|---|",
        f"| pressure noise (std) | {_fmt(sensors['pressure_noise'])} | Pa |",
        f"| pressure offset, sensor P | {_fmt(sensors['pressure_offsets']['p_P'])} | Pa |",
        f"| pressure offset, sensor N | {_fmt(sensors['pressure_offsets']['p_N'])} | Pa |",
        f"| position resolution | {_fmt(sensors['position_resolution'])} | m |",
        f"| position noise (std) | {_fmt(sensors['position_noise'])} | m |",
        f"| temperature sensor lag | {_fmt(sensors['temperature_time_constant'])} | s |",
        f"| temperature noise (std) | {_fmt(sensors['temperature_noise'])} | K |",
        f"| flow-meter lag | {_fmt(sensors['flow_time_constant'])} | s |",
        f"| flow-meter noise (std) | {_fmt(sensors['flow_noise'])} | kg/s |",
        "",
        "## Recordings",
        "",
        "| file | kind | role | duration [s] | rate [Hz] | channels | setup |",
        "|---|---|---|---|---|---|---|",
    ]
    for rec in run.campaign.recordings:
        chans = ", ".join(
            f"{ch} [{rec.units.get(ch, '')}]" for ch in rec.channels if ch not in rec.derived
        )
        lines.append(
            f"| {rec.file} | {rec.kind} | {rec.role} | {rec.duration:g} | "
            f"{rec.sample_rate:.0f} | {chans} | {rec.description} |"
        )
    csv = [rec for rec in run.campaign.recordings if rec.columns]
    for rec in csv:
        mapped = ", ".join(f'"{col}" -> {ch}' for col, ch in rec.columns.items())
        lines += ["", f"`{rec.file}` uses its own column names, mapped in campaign.toml: {mapped}."]
    return "\n".join(lines) + "\n"
