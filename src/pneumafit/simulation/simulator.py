"""Front end of the compiled simulator.

>>> from pneumafit.simulation import Simulator, Experiment, PD
>>> sim = Simulator("convection")
>>> result = sim.simulate(params, experiment)       # doctest: +SKIP
>>> result["p_P"], result.status, result.air        # doctest: +SKIP

:meth:`Simulator.simulate_batch` runs many parameter sets over many
experiments in one parallel compiled call (emcee's ``vectorize=True``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numba
import numpy as np

from pneumafit import first_use
from pneumafit.errors import PneumafitInputError
from pneumafit.models import kernel
from pneumafit.models.layout import (
    CHANNEL_UNITS,
    CHANNELS,
    FRICTION_LAWS,
    NCTRL,
    NX,
    VALVE_LAWS,
    P,
    n_parameters,
)
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.part_kernel import kernel_for, kernel_for_laws
from pneumafit.models.structure import ModelStructure, get_structure
from pneumafit.simulation import counter
from pneumafit.simulation.experiment import Experiment
from pneumafit.simulation.tableau import KUTTA3, TABLEAUS, Tableau

STATUS_MESSAGES = {
    kernel.STATUS_OK: "ok",
    kernel.STATUS_NONFINITE: "the state became non-finite (NaN or inf)",
    kernel.STATUS_NONPHYSICAL: "a pressure or temperature fell to zero or below",
    kernel.STATUS_BAD_PARAMETERS: "the parameters are not physically admissible",
    kernel.STATUS_BAD_INPUT: "an input is not physical (e.g. a non-positive held pressure)",
}

#: Default largest step (s). Kutta's RK3 (the default method) at 1 ms: 0.6 Pa
#: and 0.1 um largest error on the benchmark's 4-s closed-loop step test with
#: stick-slip (against Radau at rtol 1e-10); RK4: 0.4 Pa at 4/3 the cost. The
#: accuracy target is 50 Pa, far below sensor noise (~400 Pa). Checked against
#: the stiffness bound by :func:`choose_step`.
DEFAULT_STEP = 1.0e-3

#: Default method: Kutta's third-order Runge-Kutta (3 stages per step).
DEFAULT_METHOD = KUTTA3

#: Largest change of a valve command within one step (V): a sample interval in
#: which a command (or kp times the reference) jumps is cut into more steps.
COMMAND_RESOLUTION = 0.5

#: Fraction of the method's real-axis stability limit that h times the fastest
#: rate may use (10 % margin; the rate is already an upper bound: full
#: opening, smallest volume and hottest gas at once).
STABILITY_MARGIN = 0.9


@dataclass(frozen=True)
class AirConsumption:
    """Air used by a simulated test.

    Attributes
    ----------
    mass_supplied : float
        Net mass drawn from the supply (kg).
    mass_exhausted : float
        Net mass sent to exhaust, leaks to atmosphere included (kg).
    exergy : float
        Exergy of the supplied air, isothermal compression work from
        atmosphere m r T_atm ln(P_S / P_atm) (J) (Cai and Kagawa's air power
        integrated over the test; physics notes).
    """

    mass_supplied: float
    mass_exhausted: float
    exergy: float

    @classmethod
    def from_mass(cls, m_supply: float, m_exhaust: float, params: np.ndarray) -> AirConsumption:
        from pneumafit.physics.air import R_AIR

        p_s = params[P["supply_pressure"]]
        p_atm = params[P["exhaust_pressure"]]
        t_atm = params[P["ambient_temperature"]]
        exergy = m_supply * R_AIR * t_atm * math.log(p_s / p_atm)
        return cls(float(m_supply), float(m_exhaust), float(exergy))


@dataclass(frozen=True)
class Simulation:
    """Result of one simulation.

    Attributes
    ----------
    time : ndarray
        Sample times (s).
    channels : dict of str to ndarray
        Simulated channels (SI, see ``units``), NaN after a failure.
    units : dict of str to str
    status : int
        0 when the simulation succeeded.
    message : str
        What went wrong, in words ("ok" otherwise).
    air : AirConsumption or None
        Air used (None when the simulation failed).
    """

    time: np.ndarray
    channels: dict[str, np.ndarray]
    units: dict[str, str]
    status: int
    message: str
    air: AirConsumption | None

    @property
    def ok(self) -> bool:
        return self.status == kernel.STATUS_OK

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]


@dataclass
class PackedExperiments:
    """Experiments concatenated into the flat arrays the kernel reads."""

    experiments: tuple[Experiment, ...]
    cfgs: np.ndarray
    ctrls: np.ndarray
    x0s: np.ndarray
    t_all: np.ndarray
    inp_all: np.ndarray
    nsub_all: np.ndarray
    offsets: np.ndarray

    def slices(self) -> list[slice]:
        return [slice(self.offsets[r], self.offsets[r + 1]) for r in range(len(self.experiments))]


class Simulator:
    """Compiled fixed-step simulator of one model structure.

    Parameters
    ----------
    model : str or ModelStructure
        ``"convection"``, ``"constant-lambda"``, ``"polytropic"`` or a structure.
    step : float
        Largest integration step (s). Every sample interval is split into
        equal steps no larger than this; the step never depends on the
        parameters, so the log-likelihood is smooth in them.
    method : str or Tableau
        ``"kutta3"`` (default, 3rd order), ``"rk4"``, ``"dp5"`` (5th order) or
        ``"heun"`` (2nd order).
    channels : sequence of str, optional
        Channels to return (default: all of :data:`CHANNELS`).
    dense : bool
        Let one step span several sample intervals where ``step`` allows it
        and the inputs (commands, reference, chamber pressure) do not change
        over them, and give the samples inside it by cubic Hermite
        interpolation between its ends (states and derivatives). Fewer
        evaluations at a step longer than the sampling interval, e.g. the
        stable step of :func:`choose_step`; the samples within a step are
        interpolated, not integrated, so default off: every sample interval
        then has its own steps and the samples are the integrator's states.
    """

    def __init__(
        self,
        model: str | ModelStructure = "convection",
        *,
        step: float = DEFAULT_STEP,
        method: str | Tableau = DEFAULT_METHOD,
        channels: Sequence[str] | None = None,
        dense: bool = False,
    ) -> None:
        first_use.due()  # a deferred warm-up (pneumafit.first_use), once input is read
        self.structure = get_structure(model)
        self.dense = bool(dense)
        # the cached kernel, or its copy bound to outside parts (models.part_kernel)
        self._kernel = kernel_for(self.structure)
        if not step > 0:
            raise PneumafitInputError(
                f"simulator: step: expected a positive step in s, found {step}"
            )
        self.step = float(step)
        self.tableau = TABLEAUS[method] if isinstance(method, str) else method
        if self.tableau.c[-1] != 1.0:
            raise PneumafitInputError(
                "simulator: method: expected a method whose last stage sits at the step's end "
                f"(c = 1), found c = {self.tableau.c[-1]:g}"
            )
        names = tuple(channels) if channels is not None else CHANNELS
        unknown = [c for c in names if c not in CHANNELS]
        if unknown:
            raise PneumafitInputError(
                f"simulator: channels: expected names in {CHANNELS}, found {unknown}"
            )
        self.channels = names
        self._ch_sel = np.array([CHANNELS.index(c) for c in names], dtype=np.int64)

    # ------------------------------------------------------------------ packing
    def pack(
        self, experiments: Sequence[Experiment], steps: Sequence[float] | None = None
    ) -> PackedExperiments:
        """Concatenate experiments for :meth:`simulate_batch` (do it once per fit).

        Parameters
        ----------
        experiments : sequence of Experiment
        steps : sequence of float, optional
            Largest step (s) for each experiment, e.g. from :func:`choose_step`
            with the positions that experiment visits (a blocked test at
            mid-stroke allows a larger step than one near an end). Default:
            the simulator's ``step`` for all.
        """
        exps = tuple(experiments)
        if not exps:
            raise PneumafitInputError("simulator: expected at least one experiment, found none")
        if steps is None:
            steps = [self.step] * len(exps)
        if len(steps) != len(exps) or not all(s > 0 for s in steps):
            raise PneumafitInputError(
                f"simulator: steps: expected {len(exps)} positive steps, found {list(steps)}"
            )
        n_rec = len(exps)
        cfgs = np.zeros((n_rec, self.structure.config().size), dtype=np.int64)
        ctrls = np.zeros((n_rec, NCTRL))
        nx = self._kernel.NX  # longer than layout.NX for outside effects' states
        x0s = np.zeros((n_rec, nx))
        offsets = np.zeros(n_rec + 1, dtype=np.int64)
        for r, e in enumerate(exps):
            cfgs[r] = self.structure.config(
                blocked=e.blocked,
                chamber=e.chamber,
                closed_loop=e.controller.law if e.closed_loop else 0,
                static_flow=e.kind == "flow",
            )
            if e.controller is not None:
                ctrls[r] = e.controller.as_array()
            x0s[r] = e.initial_state(nx)
            offsets[r + 1] = offsets[r] + e.n_samples
        t_all = np.concatenate([e.time for e in exps])
        inp_all = np.concatenate([e.inputs() for e in exps])
        nsub_all = np.concatenate(
            [substeps(e, h, span=self.dense) for e, h in zip(exps, steps, strict=True)]
        )
        return PackedExperiments(exps, cfgs, ctrls, x0s, t_all, inp_all, nsub_all, offsets)

    # -------------------------------------------------------------- simulation
    def simulate_batch(
        self,
        parameter_sets: np.ndarray,
        experiments: Sequence[Experiment] | PackedExperiments,
        *,
        initial_states: np.ndarray | None = None,
        nsub: np.ndarray | None = None,
        tableau: Tableau | None = None,
        same_as_first: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Simulate every parameter set on every experiment, in parallel.

        Parameters
        ----------
        parameter_sets : ndarray, shape (n_sets, NP)
            Full parameter vectors (see :func:`parameter_vector`).
        experiments : sequence of Experiment or PackedExperiments
        initial_states : ndarray, shape (n_sets, n_experiments, NX), optional
            An initial state per parameter set and experiment (when initial
            states are fitted); default the experiments' own. NX is the
            kernel's (``self._kernel.NX``); states of ``layout.NX`` are
            taken too, the outside effects' states past it from 0.
        nsub : ndarray of int, optional
            Steps per sample interval, rows as ``packed.t_all`` (default the
            packed ones).
        tableau : Tableau, optional
            Method for this call (default the simulator's).
        same_as_first : ndarray of bool, shape (n_sets, n_experiments), optional
            Pairs the caller knows to give exactly the first set's result
            (they differ from it only in parameters that experiment does not
            use, e.g. another experiment's initial state): not simulated, they
            take the first set's rows and status. The first set is always
            simulated. A finite-difference Jacobian skips most of its
            simulations this way.

        Returns
        -------
        out : ndarray, shape (n_sets, n_rows, n_channels)
            Simulated channels (order ``self.channels``), experiments stacked
            along rows (``packed.slices()``); NaN after a failure.
        status : ndarray of int, shape (n_sets, n_experiments)
            0 where the simulation succeeded. Failures never raise.
        """
        packed = (
            experiments if isinstance(experiments, PackedExperiments) else self.pack(experiments)
        )
        # writable C arrays only: numba compiles a read-only array as another
        # type, so a read-only input would compile the integrator a second time
        params = np.require(np.atleast_2d(parameter_sets), dtype=float, requirements="CW")
        if params.shape[1] != n_parameters():
            raise PneumafitInputError(
                f"simulator: parameter sets: expected shape (n, {n_parameters()}), "
                f"found {params.shape}"
            )
        n_sets = params.shape[0]
        n_exp = len(packed.experiments)
        out = np.empty((n_sets, packed.t_all.size, self._ch_sel.size))
        status = np.zeros((n_sets, n_exp), dtype=np.int64)
        tab = self.tableau if tableau is None else tableau
        nx = self._kernel.NX
        if initial_states is None:
            x0s = np.broadcast_to(_sized(packed.x0s, nx), (n_sets, n_exp, nx)).copy()  # writable
        else:
            x0s = _sized(np.require(initial_states, dtype=float, requirements="CW"), nx)
            if x0s.shape != (n_sets, n_exp, nx):
                raise PneumafitInputError(
                    f"simulator: initial_states: expected shape {(n_sets, n_exp, nx)}, "
                    f"found {x0s.shape}"
                )
        nsub_all = packed.nsub_all if nsub is None else nsub
        if same_as_first is not None:
            same = np.asarray(same_as_first, dtype=bool)
            if same.shape != (n_sets, n_exp):
                raise PneumafitInputError(
                    f"simulator: same_as_first: expected shape {(n_sets, n_exp)}, "
                    f"found {same.shape}"
                )
            same = same.copy()
            same[0] = False
            if same.any():
                jobs = _balanced_jobs(~same, packed.offsets, nsub_all)
                self._kernel.integrate_jobs(
                    jobs, params, packed.cfgs, packed.ctrls, x0s, packed.t_all,
                    packed.inp_all, nsub_all, packed.offsets, tab.a, tab.b, tab.c,
                    self._ch_sel, out, status,
                )  # fmt: skip
                for r in range(n_exp):
                    rows = np.flatnonzero(same[:, r])
                    if rows.size:
                        a, b = packed.offsets[r], packed.offsets[r + 1]
                        out[rows, a:b] = out[0, a:b]
                        status[rows, r] = status[0, r]
                counter.add(int(jobs.size))
                return out, status
        run = (
            self._kernel.integrate_many
            if n_sets * len(packed.experiments) > 1
            else (self._kernel.integrate_many_serial)
        )
        run(
            params, packed.cfgs, packed.ctrls, x0s, packed.t_all, packed.inp_all,
            nsub_all, packed.offsets, tab.a, tab.b, tab.c, self._ch_sel, out, status,
        )  # fmt: skip
        counter.add(n_sets * n_exp)
        return out, status

    def simulate(
        self, parameters: Mapping[str, float] | np.ndarray, experiment: Experiment
    ) -> Simulation:
        """Simulate one experiment with one parameter set.

        Parameters
        ----------
        parameters : mapping of str to float, or ndarray (NP,)
            Named SI values (defaults for the rest) or a full vector.
        experiment : Experiment

        Returns
        -------
        Simulation
        """
        vec = (
            np.asarray(parameters, dtype=float)
            if isinstance(parameters, np.ndarray)
            else parameter_vector(parameters)
        )
        out, status = self.simulate_batch(vec[None, :], [experiment])
        st = int(status[0, 0])
        chans = {name: out[0, :, j].copy() for j, name in enumerate(self.channels)}
        units = {name: CHANNEL_UNITS[CHANNELS.index(name)] for name in self.channels}
        air = None
        if st == kernel.STATUS_OK and "m_supply" in chans and "m_exhaust" in chans:
            air = AirConsumption.from_mass(chans["m_supply"][-1], chans["m_exhaust"][-1], vec)
        return Simulation(experiment.time, chans, units, st, STATUS_MESSAGES[st], air)


def substeps(experiment: Experiment, step: float, *, span: bool = False) -> np.ndarray:
    """Number of integration steps in each sample interval of an experiment.

    At least ceil(dt / step), and enough that no valve command changes by more
    than :data:`COMMAND_RESOLUTION` within a step: a command that jumps within
    one sample (a valve opening, a reference step under a ``pd`` law, where
    the jump is kp |delta y_ref|) sweeps the dead band and the flow regimes in
    microseconds, which one 1-ms step cannot follow (39 Pa of error on the
    benchmark step test, against 3 Pa with the split). Depends on the inputs
    only, never on the parameters.

    With ``span``, where the step allows m >= 2 sample intervals and the
    inputs do not change over them, they are merged into one step (dense
    output, :class:`Simulator`'s ``dense``).

    Returns
    -------
    ndarray of int64, shape (n,)
        Steps in interval k at index k; the last entry is unused (0). A
        step that spans m >= 2 intervals from interval k: -m at k (the
        entries of the other intervals it covers are not read).
    """
    t = experiment.time
    dt = np.diff(t)
    n = np.ceil(dt / step - 1e-9)
    inp = experiment.inputs()
    jump = np.max(np.abs(np.diff(inp[:, :2], axis=0)), axis=1)
    if experiment.closed_loop:
        gain = experiment.controller.reference_gain
        jump = np.maximum(jump, gain * np.abs(np.diff(inp[:, 2])))
    n = np.maximum(n, np.ceil(jump / COMMAND_RESOLUTION))
    nsub = np.concatenate([np.maximum(n, 1), [0]]).astype(np.int64)
    if span:
        same = np.all((inp[1:] == inp[:-1]) | (np.isnan(inp[1:]) & np.isnan(inp[:-1])), axis=1)
        nsub = _spans(t, nsub, same, step)
    return nsub


def step_ends(nsub: np.ndarray) -> tuple[np.ndarray, int]:
    """Which samples of one experiment's ``nsub`` (:func:`substeps`) the
    integrator steps to, and how many steps it takes.

    Returns
    -------
    ends : ndarray of bool, shape (n,)
        False for the samples inside a spanning step (dense output: their
        values are interpolated), True for the others.
    steps : int
        Integration steps: nsub[k] in a plain interval, one per span.
    """
    ends = np.ones(nsub.size, dtype=bool)
    steps, k = 0, 0
    while k < nsub.size - 1:
        m = -int(nsub[k]) if nsub[k] < -1 else 1
        ends[k + 1 : k + m] = False
        steps += 1 if m > 1 else max(int(nsub[k]), 1)
        k += m
    return ends, steps


def _spans(t: np.ndarray, nsub: np.ndarray, same: np.ndarray, step: float) -> np.ndarray:
    """Merge runs of one-step sample intervals into steps of up to ``step``
    (s) where the inputs are constant: rows k .. k+m equal (``same[j]``: row
    j+1 equals row j), so that held and interpolated inputs alike are
    constant over the merged step. The merged step's first interval gets
    -m, the others keep 1 (not read)."""
    out = nsub.copy()
    n = t.size
    k = 0
    while k < n - 1:
        m = 0
        while (k + m < n - 1 and nsub[k + m] == 1 and same[k + m]
               and t[k + m + 1] - t[k] <= step * (1.0 + 1e-9)):  # fmt: skip
            m += 1
        if m >= 2:
            out[k] = -m
            k += m
        else:
            k += 1
    return out


def choose_step(
    parameters: Mapping[str, float] | np.ndarray,
    *,
    default: float = DEFAULT_STEP,
    y_range: tuple[float, float] | None = None,
    method: str | Tableau = DEFAULT_METHOD,
    valve: str = "iso6358",
    friction: str = "switch",
    spool: tuple[float, float] | None = None,
) -> float:
    """Largest fixed step (s) that is stable for a parameter set.

    The step is ``min(default, STABILITY_MARGIN * limit / rate)`` where
    ``limit`` is the method's real-axis stability limit and ``rate`` bounds
    the model's fastest mode (:func:`pneumafit.models.kernel.stiffness_bound`)
    over the piston positions ``y_range`` (default: the whole stroke). Choose
    it once per fit from nominal parameters, so that it never varies with the
    parameters being fitted.

    Parameters
    ----------
    parameters : mapping or ndarray
        Nominal parameter values (SI).
    default : float
        Step (s) used when stability allows it.
    y_range : (float, float), optional
        Positions (m) the piston visits.
    method : str or Tableau
        Integration method the step is for.
    valve : str
        Valve law of the model (:attr:`ModelStructure.valve`, a registered
        name): the rate bound takes that law's largest conductance (a law
        from outside the package: its largest slope on a grid).
    friction : str
        Friction law of the model (:attr:`ModelStructure.friction`, a
        registered name): LuGre adds its bristle mode (stiffness and damping
        over the moving mass), a law from outside the package the mode of
        its force and state at rest, by central differences.
    spool : (float, float), optional
        The spool's fastest mode as (|lambda| in 1/s, direction in rad)
        (:func:`spool_mode`: a first-order lag's is 1 / tau on the negative
        real axis, a second-order spool's is oscillatory), which the model's
        rate bound leaves out: the step keeps h |lambda| within the method's
        stability radius in that direction (:meth:`Tableau.stability_radius`,
        the real-axis limit at pi). None: no such mode.
    """
    first_use.due()
    if valve not in VALVE_LAWS:
        raise PneumafitInputError(
            f"choose_step: valve: expected one of {sorted(VALVE_LAWS)}, found {valve!r}"
        )
    if friction not in FRICTION_LAWS:
        raise PneumafitInputError(
            f"choose_step: friction: expected one of {sorted(FRICTION_LAWS)}, found {friction!r}"
        )
    tableau = TABLEAUS[method] if isinstance(method, str) else method
    vec = (
        np.asarray(parameters, dtype=float)
        if isinstance(parameters, np.ndarray)
        else parameter_vector(parameters)
    )
    stroke = vec[P["stroke"]]
    lo, hi = y_range if y_range is not None else (0.0, stroke)
    rate = kernel_for_laws(VALVE_LAWS[valve], FRICTION_LAWS[friction]).stiffness_bound(
        vec, max(lo, 0.0), min(hi, stroke), VALVE_LAWS[valve], FRICTION_LAWS[friction]
    )
    step = min(default, STABILITY_MARGIN * tableau.stability / rate)
    if spool is not None and spool[0] > 0.0:
        radius = tableau.stability_radius(spool[1])
        if radius < 1e-2:
            raise PneumafitInputError(
                f"choose_step: method {tableau.name!r} is unstable for the spool's mode at "
                f"{math.degrees(spool[1]):.1f} deg (an undamped oscillation): expected a "
                "method stable on the imaginary axis (kutta3, rk4) or a damped spool"
            )
        step = min(step, STABILITY_MARGIN * radius / spool[0])
    return float(step)


def spool_lag(structure: ModelStructure, parameters: np.ndarray) -> float | None:
    """Time constant (s) of the structure's first-order spool lag (effect
    ``valve_dynamics``, option 1) in a full parameter vector, for
    :func:`choose_step`; None without one (or with tau <= 0)."""
    if structure.effects.get("valve_dynamics") != 1:
        return None
    tau = float(parameters[P["valve_time_constant"]])
    return tau if tau > 0.0 else None


def spool_mode(structure: ModelStructure, parameters: np.ndarray) -> tuple[float, float] | None:
    """The spool's fastest mode, for :func:`choose_step`'s ``spool``.

    With ``valve_dynamics`` = 1, u_s' = (u - u_s) / tau has the eigenvalue
    -1 / tau (modulus 1 / tau, angle pi; :func:`spool_lag` gives tau). With
    ``valve_dynamics`` = 2, u_s'' = w_n^2 (u - u_s) - 2 zeta w_n u_s' has
    the eigenvalues w_n (-zeta +- i sqrt(1 - zeta^2)) (modulus w_n, angle
    pi - arccos zeta) when zeta < 1, and -w_n (zeta +- sqrt(zeta^2 - 1))
    on the real axis otherwise (the faster one is returned).

    Returns
    -------
    (float, float) or None
        (|lambda| in 1/s, angle in rad); None without spool dynamics, with a
        non-positive time constant or a non-positive natural frequency.
    """
    order = structure.effects.get("valve_dynamics")
    if order == 1:
        tau = spool_lag(structure, parameters)
        return None if tau is None else (1.0 / tau, math.pi)
    if order != 2:
        return None
    w_n = float(parameters[P["valve_natural_frequency"]])
    zeta = max(float(parameters[P["valve_damping_ratio"]]), 0.0)
    if not w_n > 0.0:
        return None
    if zeta >= 1.0:
        return w_n * (zeta + math.sqrt(zeta * zeta - 1.0)), math.pi
    return w_n, math.pi - math.acos(zeta)


def _balanced_jobs(run: np.ndarray, offsets: np.ndarray, nsub_all: np.ndarray) -> np.ndarray:
    """Job indices (set * n_experiments + experiment) of the pairs ``run``
    (n_sets, n_experiments) marks, ordered so that numba's static schedule,
    which gives each thread an equal run of them, gives the threads equal
    work: by cost (integration steps of the experiment), then dealt in turn.
    """
    n_exp = run.shape[1]
    steps = np.add.reduceat(np.abs(nsub_all), offsets[:-1]) if nsub_all.size else np.zeros(n_exp)
    sets, exps = np.nonzero(run)
    jobs = sets * n_exp + exps
    order = np.argsort(-steps[exps], kind="stable")
    jobs = jobs[order]
    threads = max(int(numba.get_num_threads()), 1)
    # thread t takes jobs t, t + threads, ... of the sorted list, as a run
    return np.concatenate([jobs[t::threads] for t in range(threads)]).astype(np.int64)


def _sized(x0s: np.ndarray, nx: int) -> np.ndarray:
    """States of ``layout.NX`` (the cached kernel's) made ``nx`` long for a
    kernel copy with outside effects' states past it: those start at 0, as
    the kernel's own default. Any other length is returned as it is."""
    if x0s.ndim >= 1 and x0s.shape[-1] == NX < nx:
        pad = np.zeros((*x0s.shape[:-1], nx - NX))
        return np.require(np.concatenate([x0s, pad], axis=-1), requirements="CW")
    return x0s
