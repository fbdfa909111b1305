"""Attribution: which catalog effect the residual of a fit asks for.

After a fit, the measured pressure of each chamber changes at a rate the
fitted model does not give. For every recording with a moving or relaxing
chamber (charge, discharge, step tests; fit and validate: attribution only
ranks, the refit uses the fit recordings) this module forms the
*derivative-level residual*

    r_X(t) = SG slope of P_X,measured - (dP_X/dt of the model at the measured state)  (Pa/s)

(:func:`model_rates`: the kernel's right-hand side at the measured
pressures, position and velocity, the simulated gas temperatures, smoothed
with the weights the Savitzky-Golay slope puts on a derivative), weights
each row by the inverse of its expected spread (sensor noise, and the
rate's sensitivity to the measured pressure), projects out what the base
model's own valve and heat parameters could change (their rate
sensitivities, Frisch-Waugh), and regresses the rest on the *signature* of
each catalog effect (:data:`~.catalog.EFFECTS`, docs/effects.md): the term
the effect adds to dP_X/dt (paper eq. 9, docs/physics.md), evaluated at the
same state and written so that its coefficient is the effect's own
parameter, in its SI unit:

=====================  ==============================================  ===========================
effect                 regressor in dP_X/dt (per unit parameter)       coefficient
=====================  ==============================================  ===========================
chamber_leakage        -+ gamma r T_up (P_P - P_N) / V_X                G_cl (kg/s/Pa)
external_leakage       - gamma r T_l (P_X - P_atm) / V_X                G_el (kg/s/Pa)
valve_dynamics         - d/dt [gamma r T_in q_X / V_X]                  tau (s)
wall_thermal_mass      (gamma - 1) lambda A / V_X * int lambda (T - T_w) dt   1 / C_w (m^2 K/J)
forced_convection      (gamma - 1) max(q_X, 0) A (T_w - T) / V_X        K_fc (W/m^2/K/(kg/s))
supply_pressure_drop   - gamma r T_atm q_s,X (q_s,P + q_s,N) / (P_S V_X) R (Pa/(kg/s))
=====================  ==============================================  ===========================

(first order in the effect: the spool lag as q(u_s) = q(u) - tau dq/dt, the
wall warming as T_w - T_w0 = int lambda (T - T_w0) dt / C_w, the supply drop
through the sonic sensitivity dq/dP_S = q / P_S). Every physical coefficient
is positive: a regression that needs a negative one says the effect acts the
other way round, which no value of it can do.

The columns are standardised and regressed with sequentially thresholded
least squares (``pysindy.STLSQ``) with negative coefficients removed; a
moving-block bootstrap of the rows (blocks of ``block`` seconds, the residual
rate being correlated over the window) gives each effect's *inclusion
probability* and a spread of its coefficient. Each effect's evidence:

- ``inclusion_probability``: fraction of bootstrap fits keeping it (> 0);
- ``variance_explained``: R^2 of the residual rate by that effect alone
  (non-negative coefficient), weighted rows;
- ``phase_match``: cosine between the residual rate's sum of squares per
  phase (:mod:`.phases`) and that of the effect's fitted term: 1 when the
  effect acts where the misfit is made;
- ``coefficient``: median bootstrap coefficient, the suggested start of the
  refit (SI, the effect's principal parameter; for the wall, C_w = 1/coef).

``score = inclusion_probability * variance_explained * phase_match``; the
candidates are ranked by it. A candidate is *supported* when its inclusion
probability is at least :data:`MIN_INCLUSION` and it explains at least
:data:`MIN_VARIANCE` of the residual rate; supported candidates are
refitted first (:mod:`.refit`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.discovery.catalog import EFFECTS, get_effect
from pneumafit.discovery.phases import PHASES, label_phases, window_samples
from pneumafit.errors import PneumafitInputError
from pneumafit.identification.quality import campaign_noise, noise_estimates
from pneumafit.identification.replay import replay
from pneumafit.models import kernel, layout, parts
from pneumafit.models.part_kernel import kernel_for_config, rebound
from pneumafit.models.parts import RegistryView
from pneumafit.models.structure import ModelStructure
from pneumafit.numba_stamp import njit
from pneumafit.physics.air import GAMMA, R_AIR  # the kernel's constants (docs/physics.md)
from pneumafit.physics.geometry import exchange_areas
from pneumafit.simulation import Experiment

__all__ = [
    "ANALYSED_KINDS",
    "GAMMA",
    "MIN_INCLUSION",
    "MIN_VARIANCE",
    "R_AIR",
    "Attribution",
    "Candidate",
    "Rows",
    "analysable",
    "attribute",
    "build_rows",
    "signature_features",
]

#: A candidate is refitted only with at least this inclusion probability ...
MIN_INCLUSION = 0.5
#: ... and this share of the residual rate's (weighted) sum of squares explained alone.
MIN_VARIANCE = 0.05
#: A signed effect (a neutral value inside its bounds: friction asymmetry,
#: area factor) is supported only when its coefficient departs from the
#: neutral value by at least this fraction of the half-range on its side
#: (|a| >= 0.05, |k_A - 1| >= 0.02), the size below which the refit loop
#: calls it vanished (refit.VANISHING). Below it the acceleration rows cannot
#: tell the effect from a pressure-sensor offset: on quick campaigns without
#: any effect (seeds 5-7, offsets of the order of 1 kPa) the area factor
#: explained 5-54 % of the acceleration residual with |k_A - 1| = 0.001-0.010.
MIN_SIGNED_DEPARTURE = 0.1
#: Width (s) of the Savitzky-Golay window of the residual rate.
WINDOW = 0.05
#: Rows kept: one sample in ``DECIMATE`` (the rate is smooth over the window).
DECIMATE = 5
#: Length (s) of the bootstrap blocks.
BLOCK = 0.2
#: Smallest spool time constant (s) a refit starts from: the fitting
#: problem integrates with fixed steps up to 4 ms (Kutta RK3, stable for
#: tau > ~1.6 ms); the valve_dynamics part's ``start_floor``.
MIN_SPOOL_START = parts.EFFECTS["valve_dynamics"].start_floor
#: Pressure step (Pa) of the finite-difference sensitivity d(dP/dt)/dP.
SENS_STEP = 200.0
#: Rows where the model's rate changes by more than this per pascal of its
#: own pressure (1/s) are left out: there (a chamber about to reach supply or
#: exhaust pressure with the valve open) a kilopascal of sensor error moves
#: the model's rate by more than a missing effect does.
MAX_SENSITIVITY = 100.0
#: Uncertainty (Pa) of the measured pressure at which the model's rate is
#: evaluated (sensor offset left after the median correction, smoothed
#: noise): a row's weight is 1 / sqrt(s_rate^2 + (S * PRESSURE_UNCERTAINTY)^2),
#: S the rate's sensitivity to the pressure (1/s).
PRESSURE_UNCERTAINTY = 1000.0
#: Rows of the piston's acceleration are kept where the measured speed stays
#: above this (m/s) over the whole window: the switch friction model's
#: acceleration at the measured state means something only while sliding
#: (a stuck piston's friction balances whatever drives it). The motion phase's
#: threshold (:class:`~.phases.PhaseRules`).
MIN_SLIDING_SPEED = 2.0e-3
#: Smallest position noise (m) assumed for the acceleration's noise (an
#: encoder's quantisation makes the robust estimate 0 at rest).
MIN_POSITION_NOISE = 1.0e-6
#: Effects whose pressure-rate regressor is written out in
#: :func:`signature_features`; every other catalog effect gets the kernel's
#: own derivative at the measured state (:func:`model_rates`, ``effects``).
ANALYTIC_SIGNATURES: tuple[str, ...] = (
    "chamber_leakage", "external_leakage", "valve_dynamics", "wall_thermal_mass",
    "forced_convection", "supply_pressure_drop",
)  # fmt: skip
#: Channels of the regression rows: the chambers' pressure rates and the
#: piston's acceleration.
ROW_CHANNELS: tuple[str, ...] = ("pressure", "motion")
#: Phases in which both valves rest at their centre and the piston stands
#: still (:data:`~.phases.PHASES`): only the centre leakage, the wall heat
#: and whatever the model lacks move the pressures there. The valves'
#: opening characteristic and the friction law, which a real rig never
#: shares with the model, do not act, so an effect whose catalog phases are
#: all among these is also judged on the pressure rows of these phases
#: alone (:func:`attribute`, the ``quiet`` row set).
QUIET_PHASES: tuple[str, ...] = ("relaxation", "rest")
#: The quiet row set is regressed only with at least this many bootstrap
#: blocks (:data:`BLOCK` s each): fewer cannot give an inclusion probability
#: (with 4 blocks there are only 35 distinct resamples).
MIN_QUIET_BLOCKS = 10


# ----------------------------------------------------------------- rows
@dataclass
class Rows:
    """The regression data: one row per kept sample, chamber and recording.

    Attributes
    ----------
    rate : ndarray, shape (n,)
        Residual rate r_X (Pa/s).
    features : dict of str to ndarray, shape (n,)
        Effect name -> its signature regressor (Pa/s per unit coefficient).
    phase : ndarray of str, shape (n,)
        Phase of the row's sample (:data:`~.phases.PHASES`).
    group : ndarray of int, shape (n,)
        Bootstrap block of the row.
    weight : ndarray, shape (n,)
        Row weight (s/Pa): the inverse of the residual rate's expected
        spread without a missing effect (noise, and the model's sensitivity
        to the measured pressure times :data:`PRESSURE_UNCERTAINTY`).
    nuisance : dict of str to ndarray, shape (n,)
        Base-model parameter -> the rate's sensitivity to it (Pa/s per
        unit): what a refit of the base parameters alone could change.
    source : list of str
        ``"<file>:<chamber>"`` per segment (for messages), ``"<file>:v"``
        for the acceleration rows.
    channel : ndarray of str, shape (n,), optional
        ``pressure`` (r_X, Pa/s) or ``motion`` (the acceleration residual,
        m/s^2) per row; None: all ``pressure``.
    nuisance_values : dict of str to float
        The base model's value of each nuisance parameter (SI).
    """

    rate: NDArray[np.float64]
    features: dict[str, NDArray[np.float64]]
    phase: NDArray[np.str_]
    group: NDArray[np.int64]
    weight: NDArray[np.float64]
    source: list[str] = field(default_factory=list)
    nuisance: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    channel: NDArray[np.str_] | None = None
    nuisance_values: dict[str, float] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.rate.size)

    def channels(self) -> NDArray[np.str_]:
        """Channel of each row (:data:`ROW_CHANNELS`; all ``pressure`` if not set)."""
        if self.channel is None:
            return np.full(self.n, "pressure")
        return self.channel


def _rate(values: NDArray[np.float64], width: int, dt: float) -> NDArray[np.float64]:
    if width < 3:
        return np.gradient(values, dt)
    return savgol_filter(values, width, 1, deriv=1, delta=dt, mode="interp")


def signature_features(
    sim: Mapping[str, NDArray[np.float64]],
    chamber: str,
    values: Mapping[str, float],
    time: NDArray[np.float64],
    width: int,
) -> dict[str, NDArray[np.float64]]:
    """Each catalog effect's term in dP_X/dt per unit of its parameter.

    Parameters
    ----------
    sim : mapping of str to ndarray
        Simulated channels along the recording (SI): ``y``, ``p_P``,
        ``p_N``, ``T_P``, ``T_N``, ``qm_P``, ``qm_N``, ``lambda_P``,
        ``lambda_N``.
    chamber : {"P", "N"}
        Chamber X whose pressure rate the terms enter.
    values : mapping of str to float
        Model parameters (SI): geometry, supply and exhaust pressures,
        ambient and wall temperatures.
    time : ndarray
        Sample times (s).
    width : int
        Savitzky-Golay window (samples) for the rate in the valve term.

    Returns
    -------
    dict of str to ndarray
        Effect name -> regressor (Pa/s per unit coefficient, see the module
        table).
    """
    bore, rod, stroke = values["bore"], values["rod"], values["stroke"]
    v0p, v0n = values["dead_volume_P"], values["dead_volume_N"]
    p_atm, p_s = values["exhaust_pressure"], values["supply_pressure"]
    t_atm, t_w = values["ambient_temperature"], values["wall_temperature"]
    s_p = 0.25 * math.pi * bore * bore
    s_n = 0.25 * math.pi * (bore * bore - rod * rod)
    y = np.asarray(sim["y"], float)
    # the kernel's areas (physics.geometry), evaluated on the arrays in Python
    areas = exchange_areas.py_func(
        y, stroke, bore, rod, v0p, v0n, float(values.get("heat_area_ends", 1.0))
    )
    if chamber == "P":
        vol = v0p + s_p * y
        area = areas[0]
    else:
        vol = v0n + s_n * (stroke - y)
        area = areas[1]
    p_p, p_n = np.asarray(sim["p_P"], float), np.asarray(sim["p_N"], float)
    pres = p_p if chamber == "P" else p_n
    temp = np.asarray(sim[f"T_{chamber}"], float)
    q = np.asarray(sim[f"qm_{chamber}"], float)
    lam = np.asarray(sim[f"lambda_{chamber}"], float)
    dt = float(np.median(np.diff(time)))
    out: dict[str, NDArray[np.float64]] = {}
    # chamber leakage P -> N at the upstream temperature, opposite signs
    t_up = np.where(p_p > p_n, sim["T_P"], sim["T_N"])
    sign = -1.0 if chamber == "P" else 1.0
    out["chamber_leakage"] = sign * GAMMA * R_AIR * t_up * (p_p - p_n) / vol
    # external leakage X -> atmosphere
    t_l = np.where(pres > p_atm, temp, t_atm)
    out["external_leakage"] = -GAMMA * R_AIR * t_l * (pres - p_atm) / vol
    # spool lag: q(u_s) ~ q(u) - tau dq/dt on the valve's enthalpy term
    t_in = np.where(q > 0.0, t_atm, temp)
    h = GAMMA * R_AIR * t_in * q / vol
    out["valve_dynamics"] = -_rate(h, width, dt)
    # wall thermal mass: T_w - T_w0 ~ int lambda (T - T_w0) dt / C_w
    flux = lam * (temp - t_w)
    warm = np.concatenate([[0.0], np.cumsum(0.5 * (flux[1:] + flux[:-1]) * np.diff(time))])
    out["wall_thermal_mass"] = (GAMMA - 1.0) * lam * area * warm / vol
    # forced convection: lambda += K_fc q_s while filling
    q_in = np.maximum(q, 0.0)
    out["forced_convection"] = (GAMMA - 1.0) * q_in * area * (t_w - temp) / vol
    # supply line drop: P_S' = P_S - R q_draw, sonic dq/dP_S = q / P_S
    q_draw = np.maximum(np.asarray(sim["qm_P"], float), 0.0) + np.maximum(
        np.asarray(sim["qm_N"], float), 0.0
    )
    out["supply_pressure_drop"] = -GAMMA * R_AIR * t_atm * q_in * q_draw / (p_s * vol)
    return {k: v for k, v in out.items() if k in EFFECTS}


def _initial(rec: Recording, values: Mapping[str, float]) -> dict[str, float]:
    prefix = f"initial:{rec.file}:"
    return {k[len(prefix) :]: float(v) for k, v in values.items() if k.startswith(prefix)}


def model_values(values: Mapping[str, float]) -> dict[str, float]:
    """The model parameters among fitted values (initial states and
    measurement parameters, e.g. sensor lags and offsets, dropped)."""
    return {k: float(v) for k, v in values.items() if k in layout.P}


def simulate_recording(
    rec: Recording, structure: ModelStructure, values: Mapping[str, float]
) -> dict[str, NDArray[np.float64]] | None:
    """Simulate one recording with the fitted values and initial states.

    The one replay of a fit (:func:`pneumafit.identification.replay.replay`:
    fitted initial states, reference solver, every sample).

    Returns the simulated channels (SI) or None when the simulation failed.
    """
    try:
        rep = replay([rec], structure, values, estimate_lag=False)
    except ValueError:  # no channel to compare: nothing to attribute
        return None
    if not rep.recordings or not rep.recordings[0].ok:
        return None
    return rep.recordings[0].simulated


def _slope_kernel(width: int) -> NDArray[np.float64]:
    """Weights that turn a rate sampled at the samples into the
    Savitzky-Golay (order 1) slope of its integral over ``width`` samples.

    The order-1 slope over k = -M..M is sum k x_k / sum k^2; by parts it is
    a weighted mean of the increments x_j - x_{j-1}, weight
    (M (M + 1) - j (j - 1)) / 2 / sum k^2, j = -M+1..M: a parabola.
    """
    m = width // 2
    j = np.arange(-m + 1, m + 1)
    w = (m * (m + 1) - j * (j - 1)) / 2.0
    return w / w.sum()


def _smooth_rate(values: NDArray[np.float64], width: int) -> NDArray[np.float64]:
    """A rate smoothed as the Savitzky-Golay slope smooths a derivative."""
    if width < 3:
        return values
    mid = 0.5 * (values[1:] + values[:-1])  # rate over each sample interval
    w = _slope_kernel(width)
    m = width // 2
    out = np.full(values.size, np.nan)
    conv = np.convolve(mid, w[::-1], mode="valid")  # increments j = n-m+1 .. n+m
    out[m : m + conv.size] = conv
    return out


def _rate_noise(sigma: float, width: int, dt: float) -> float:
    """Standard deviation (Pa/s) of the Savitzky-Golay slope from white sensor noise.

    ``sigma`` is the pressure sensor's noise (Pa; the workbench's one
    estimator, :func:`~pneumafit.identification.quality.noise_estimates`),
    the slope's follows from its weights: sigma / (dt sqrt(sum k^2)).
    """
    m = width // 2
    return sigma / (dt * math.sqrt(m * (m + 1) * (2 * m + 1) / 3.0)) if m else sigma / dt


@njit(cache=True)
def _rates_along(
    xs: np.ndarray, modes: np.ndarray, cmds: np.ndarray, p: np.ndarray, d: np.ndarray,
    cfg: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """dP_P/dt, dP_N/dt, q_P, q_N, lambda_P, lambda_N, dv/dt at each state row (kernel rhs).

    With the LuGre law (cfg's friction slot) a moving row's bristle deflection
    is set to its steady sliding value sign(v) g(v) / sigma0 for these
    parameters (:func:`~pneumafit.models.kernel.initial_deflection`, seal and
    asymmetry included): the measurement does not give z, and after the
    pre-sliding travel g / sigma0 (~0.1 mm) a sliding piston's bristles sit
    there, so the LuGre friction is the switch model's s g(v) + b v. A law
    from outside the package with a state of its own: the state where its
    rate vanishes at that speed
    (:func:`~pneumafit.models.kernel.steady_friction_state`).
    """
    n = xs.shape[0]
    out = np.empty((n, 7))
    dx = np.empty(xs.shape[1])
    aux = np.empty(kernel.NAUX)
    x = np.empty(xs.shape[1])
    smooth = not kernel.friction_modes(cfg)
    for k in range(n):
        for i in range(xs.shape[1]):
            x[i] = xs[k, i]
        if smooth and x[layout.X_V] != 0.0:
            x[layout.X_Z] = kernel.steady_friction_state(x, p, cfg)
        kernel.rhs(x, modes[k], cmds[k, 0], cmds[k, 1], p, d, cfg, dx, aux)
        out[k, 0] = dx[layout.X_PP]
        out[k, 1] = dx[layout.X_PN]
        out[k, 2] = aux[kernel.A_QP]
        out[k, 3] = aux[kernel.A_QN]
        out[k, 4] = aux[kernel.A_LAMP]
        out[k, 5] = aux[kernel.A_LAMN]
        out[k, 6] = dx[layout.X_V]
    return out


def _smooth_max(values: NDArray[np.float64], width: int) -> NDArray[np.float64]:
    """Largest value over a centred window of ``width`` samples."""
    from scipy.ndimage import maximum_filter1d

    return maximum_filter1d(np.nan_to_num(values, nan=np.inf), size=max(width, 1), mode="nearest")


def model_rates(
    rec: Recording,
    structure: ModelStructure,
    values: Mapping[str, float],
    sim: Mapping[str, NDArray[np.float64]],
    width: int,
    parameters: Sequence[str] = (),
    effects: Sequence[str] = (),
) -> dict[str, NDArray[np.float64]]:
    """The model's pressure rates at the measured state, and its flows there.

    The kernel's right-hand side (:func:`pneumafit.models.kernel.rhs`) is
    evaluated at every sample with the *measured* pressures (smoothed over
    the window), position and velocity (step tests; Savitzky-Golay slope of
    the position), the simulated gas temperatures (the sensors are too slow
    to give them) and the measured commands. Unlike the rate of the output
    residual, this rate carries no feedback of an error accumulated
    earlier (e.g. a flow that depends on an already wrong pressure).

    Returns
    -------
    dict of str to ndarray
        ``dp_P``, ``dp_N`` (Pa/s), the valve flows ``qm_P``, ``qm_N``
        (kg/s), ``lambda_P``, ``lambda_N`` (W/m^2/K) at the measured state,
        the rates' sensitivities to their own pressure ``sens_P``,
        ``sens_N`` (1/s) and to each of ``parameters``
        (``param:<name>:P``, ``param:<name>:N``, ``param:<name>:v`` for
        the acceleration; central differences), the acceleration ``dv``
        (m/s^2) at the measured state with the pressures as recorded (no
        offset removed, see the code) and the velocity used ``v`` (m/s,
        Savitzky-Golay slope of the position; 0 in blocked tests), each of
        ``effects``' *kernel signature* (``effect:<name>:P``, ``:N``, ``:v``:
        the derivative of dP_P/dt, dP_N/dt and dv/dt with respect to the
        effect's principal parameter with the effect switched on, at its
        neutral value, or at the current one if the structure has the effect:
        central differences for a signed parameter, forward ones from 0 for
        a one-sided one; per unit parameter), and the state used: ``p_P``,
        ``p_N``, ``T_P``, ``T_N``, ``y``.
    """
    from pneumafit.models.layout import (
        X_PN,
        X_PP,
        X_TN,
        X_TP,
        X_TWN,
        X_TWP,
        X_UN,
        X_UP,
        X_V,
        X_Y,
    )  # fmt: skip
    from pneumafit.models.parameters import parameter_vector

    model = model_values(values)
    p = parameter_vector(model)
    d = np.empty(kernel.ND)
    kernel.derive(p, d)
    exp = Experiment.from_recording(rec)
    cfg = structure.config(blocked=exp.blocked, chamber=exp.chamber, closed_loop=0)
    t = rec.time
    n = t.size
    dt = float(np.median(np.diff(t)))
    inp = exp.inputs()

    short = max(3, (width // 4) | 1)

    def smooth(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return savgol_filter(x, short, 1, mode="interp") if n > short else x

    state: dict[str, NDArray[np.float64]] = {}
    raw: dict[str, NDArray[np.float64]] = {}
    for ch in ("p_P", "p_N"):
        meas = rec.channels.get(ch)
        if meas is None:
            state[ch] = np.asarray(sim[ch], float)
            raw[ch] = state[ch]
            continue
        # the sensor's offset (the fit profiles one per recording) is not in the gas
        resid = np.asarray(meas, float) - sim[ch]
        offset = float(np.nanmedian(resid)) if np.isfinite(resid).any() else 0.0
        state[ch] = smooth(np.asarray(meas, float) - offset)
        raw[ch] = smooth(np.asarray(meas, float))
    for ch in ("T_P", "T_N"):
        state[ch] = np.asarray(sim[ch], float)
    if exp.blocked:
        state["y"] = np.asarray(sim["y"], float)
        vel = np.zeros(n)
    else:
        ymeas = np.asarray(rec.channels.get("y", sim["y"]), float)
        state["y"] = smooth(ymeas)
        vel = _rate(ymeas, width, dt)
    # wall temperatures (effect wall_thermal_mass): integrate their ODE along
    # the simulated gas temperature and heat-transfer coefficient
    t_wall = {"P": np.full(n, model.get("wall_temperature", p[kernel.P_TW])),
              "N": np.full(n, model.get("wall_temperature", p[kernel.P_TW]))}  # fmt: skip
    if structure.effects.get("wall_thermal_mass"):
        c_w = p[kernel.P_WCAP]
        h_o = p[kernel.P_WOUT]
        t_amb = p[kernel.P_TAMB]
        for ch in ("P", "N"):
            lam = np.asarray(sim[f"lambda_{ch}"], float)
            gas = state[f"T_{ch}"]
            tw = t_wall[ch]
            for k in range(1, n):
                rate_k = (lam[k - 1] + h_o) / c_w
                target = (lam[k - 1] * gas[k - 1] + h_o * t_amb) / (lam[k - 1] + h_o)
                tw[k] = target + (tw[k - 1] - target) * math.exp(-rate_k * (t[k] - t[k - 1]))
    # the state vector of the kernel that runs it (longer than layout.NX
    # for outside effects with states past the first slot; those at 0 here)
    xs = np.zeros((n, kernel_for_config(cfg).NX))
    xs[:, X_Y] = state["y"]
    xs[:, X_V] = vel
    xs[:, X_PP] = state["p_P"]
    xs[:, X_PN] = state["p_N"]
    xs[:, X_TP] = state["T_P"]
    xs[:, X_TN] = state["T_N"]
    xs[:, X_TWP] = t_wall["P"]
    xs[:, X_TWN] = t_wall["N"]
    xs[:, X_UP] = np.asarray(sim.get("u_P", inp[:, 0]), float)
    xs[:, X_UN] = np.asarray(sim.get("u_N", inp[:, 1]), float)
    modes = np.where(vel > 0.0, 1, np.where(vel < 0.0, -1, 0)).astype(np.int64)
    if exp.blocked:
        modes[:] = 0
    cmds = np.ascontiguousarray(inp[:, :2])
    # The measured rates are slopes of the samples: p_k+1 - p_k integrates
    # the rate over [t_k, t_k+1]. With commands held between samples
    # (ModelStructure.inputs, open-loop replays) that is the rate at the held
    # u_k, so a slope centred on t_k weighs the intervals k-1 and k alike:
    # the model's rate at t_k is then the mean of its rates at u_k-1 and u_k.
    # Interpolated commands, and a controller's (continuous in the closed
    # loop, which only holds y_ref), are centred on t_k already.
    held = structure.inputs == "hold" and not exp.closed_loop
    cmds_before = np.ascontiguousarray(np.vstack([cmds[:1], cmds[:-1]])) if held else cmds

    def rates_along(
        xs_: NDArray[np.float64], q: NDArray[np.float64], dq: NDArray[np.float64],
        cfg_: NDArray[np.int64],
    ) -> NDArray[np.float64]:  # fmt: skip
        # the cached kernel, or its copy for parts from outside (models.part_kernel)
        along = rebound(_rates_along, kernel_for_config(cfg_))
        r = along(xs_, modes, cmds, q, dq, cfg_)
        if held:
            r = 0.5 * (r + along(xs_, modes, cmds_before, q, dq, cfg_))
        return r

    base = rates_along(xs, p, d, cfg)
    out: dict[str, NDArray[np.float64]] = {
        "dp_P": base[:, 0], "dp_N": base[:, 1], "qm_P": base[:, 2], "qm_N": base[:, 3],
        "lambda_P": base[:, 4], "lambda_N": base[:, 5],
    }  # fmt: skip
    # sensitivity of each chamber's rate to its own pressure (1/s)
    for slot, col, key in ((X_PP, 0, "sens_P"), (X_PN, 1, "sens_N")):
        hi, lo = xs.copy(), xs.copy()
        hi[:, slot] += SENS_STEP
        lo[:, slot] -= SENS_STEP
        out[key] = (rates_along(hi, p, d, cfg)[:, col] - rates_along(lo, p, d, cfg)[:, col]) / (
            2.0 * SENS_STEP
        )
    # the acceleration at the measured pressures as recorded: the median
    # offset above also takes in any constant pressure shift the missing
    # effect caused in closed loop, and a constant force offset is what a
    # friction asymmetry looks like while sliding (dF_f/da = g both ways).
    # A real sensor offset d biases the force by S d instead (0.2 N for the
    # virtual rig's 236 Pa on p_P; 1.2 N for 1.5 kPa), which the rows'
    # weight allows for (PRESSURE_UNCERTAINTY).
    xr = xs.copy()
    xr[:, X_PP] = raw["p_P"]
    xr[:, X_PN] = raw["p_N"]
    out["dv"] = base[:, 6] if exp.blocked else rates_along(xr, p, d, cfg)[:, 6]
    out["v"] = vel
    # sensitivities to the base model's own parameters (Pa/s per unit)
    from pneumafit.models.layout import SPECS
    from pneumafit.models.layout import P as P_INDEX

    for name in parameters:
        j = P_INDEX.get(name)
        if j is None:
            continue
        h = 1e-3 * abs(p[j]) if p[j] != 0.0 else 1e-6
        rates = []
        for sign in (1.0, -1.0):
            q = p.copy()
            q[j] += sign * h
            dq = np.empty(kernel.ND)
            kernel.derive(q, dq)
            rates.append(rates_along(xs, q, dq, cfg))
        out[f"param:{name}:P"] = (rates[0][:, 0] - rates[1][:, 0]) / (2.0 * h)
        out[f"param:{name}:N"] = (rates[0][:, 1] - rates[1][:, 1]) / (2.0 * h)
        out[f"param:{name}:v"] = (rates[0][:, 6] - rates[1][:, 6]) / (2.0 * h)
    # kernel signatures of effects without a written-out regressor: the
    # right-hand side's own derivative with respect to the effect's parameter
    for name in effects:
        eff = get_effect(name)
        principal = eff.parameter_names()[0]
        par = eff.parameter(principal)
        j = P_INDEX[principal]
        neutral = par.neutral if par.neutral is not None else SPECS[principal].default
        on = bool(structure.effects.get(name))
        theta = float(model.get(principal, neutral)) if on else float(neutral)
        cfg_e = structure.with_effects(**{name: eff.option}).config(
            blocked=exp.blocked, chamber=exp.chamber, closed_loop=0
        )
        size = abs(par.typical - neutral) or abs(par.typical) or 1.0
        h = 1e-2 * size
        points = (
            (theta + h, theta - h) if par.signed or theta - h >= par.lower else (theta + h, theta)
        )
        rates = []
        for value in points:
            q = p.copy()
            q[j] = value
            dq = np.empty(kernel.ND)
            kernel.derive(q, dq)
            rates.append(rates_along(xs, q, dq, cfg_e))
        span = points[0] - points[1]
        for col, key in ((0, "P"), (1, "N"), (6, "v")):
            out[f"effect:{name}:{key}"] = (rates[0][:, col] - rates[1][:, col]) / span
    out.update(state)
    return out


#: Recording kinds whose residual pressure rates attribution analyses.
ANALYSED_KINDS = ("charge", "discharge", "step")


def analysable(campaign: Campaign) -> bool:
    """True when the campaign has a recording attribution can analyse: one of
    :data:`ANALYSED_KINDS` with a chamber pressure (a campaign of flow tests
    alone has none, and discovery has nothing to work on)."""
    return any(
        r.kind in ANALYSED_KINDS and {"p_P", "p_N"} & set(r.channels) for r in campaign.recordings
    )


def build_rows(
    campaign: Campaign,
    structure: ModelStructure,
    values: Mapping[str, float],
    *,
    role: str | None = None,
    window: float = WINDOW,
    decimate: int = DECIMATE,
    block: float = BLOCK,
    max_sensitivity: float = MAX_SENSITIVITY,
    parameters: Sequence[str] = (),
) -> Rows:
    """Residual rates and signature regressors of a campaign's recordings.

    For each recording and chamber: r_X = SG slope of the measured P_X minus
    the model's dP_X/dt at the measured state (:func:`model_rates`),
    smoothed the same way; the regressors are the effects' terms
    (:func:`signature_features`) at that state, smoothed alike.

    Parameters
    ----------
    campaign : Campaign
    structure : ModelStructure
        The fitted structure.
    values : mapping of str to float
        Fitted values (SI), with the initial states as
        ``initial:<file>:<state>`` (fit.json's ``nuisance.initial_states``).
    role : str, optional
        Recordings used: ``fit``, ``validate`` or None for every recording
        (default). Attribution only ranks candidates; the refit uses the fit
        recordings only and the held-out ones judge it.
    window : float
        Savitzky-Golay window (s) of the rates.
    decimate : int
        Keep one sample in ``decimate``.
    block : float
        Bootstrap block length (s).
    max_sensitivity : float
        Rows whose window holds a sample where the model's rate is more
        sensitive than this to its own pressure (1/s) are left out
        (:data:`MAX_SENSITIVITY`).
    parameters : sequence of str
        Base-model parameters (valve, heat) whose rate sensitivities become
        nuisance regressors (:attr:`Rows.nuisance`): a base fit may have bent
        them to mimic the missing effect, and a refit moves them again.

    Returns
    -------
    Rows
    """
    rates: list[NDArray[np.float64]] = []
    feats: dict[str, list[NDArray[np.float64]]] = {name: [] for name in EFFECTS}
    kernel_effects = [name for name in EFFECTS if name not in ANALYTIC_SIGNATURES]
    channels: list[NDArray[np.str_]] = []
    phases: list[NDArray[np.str_]] = []
    groups: list[NDArray[np.int64]] = []
    weights: list[NDArray[np.float64]] = []
    nuis: dict[str, list[NDArray[np.float64]]] = {}
    sources: list[str] = []
    next_group = 0

    def tag(
        keep: NDArray[np.bool_],
        t: NDArray[np.float64],
        labels: NDArray[np.str_],
        source: str,
        kind: str,
    ) -> None:
        """Phase, bootstrap block, source and kind of the rows ``keep`` just added."""
        nonlocal next_group
        phases.append(labels[keep])
        blk = np.floor((t[keep] - t[0]) / block).astype(np.int64)
        groups.append(blk + next_group)
        next_group += int(blk.max(initial=0)) + 1
        sources.append(source)
        channels.append(np.full(int(keep.sum()), kind))

    model = model_values(values)
    recordings = campaign.recordings if role is None else campaign.by_role(role)
    own_noise = noise_estimates(campaign, ANALYSED_KINDS)
    pooled_noise = campaign_noise(campaign)
    for rec in recordings:
        if rec.kind not in ANALYSED_KINDS:
            continue
        sim = simulate_recording(rec, structure, values)
        if sim is None:
            continue
        t = rec.time
        width = window_samples(t, window)
        if width < 3:
            continue
        dt = float(np.median(np.diff(t)))
        at = model_rates(rec, structure, values, sim, width, parameters, kernel_effects)
        labels = label_phases(rec)
        chambers = [rec.chamber] if rec.kind in ("charge", "discharge") else ["P", "N"]
        for ch in chambers:
            name = f"p_{ch}"
            if ch is None or name not in rec.channels:
                continue
            meas = np.asarray(rec.channels[name], float)
            mask = rec.mask.get(name, np.ones(rec.n_samples, bool)) & np.isfinite(meas)
            if mask.sum() < 3 * width:
                continue
            meas = np.where(mask, meas, np.interp(t, t[mask], meas[mask]))
            rate = _rate(meas, width, dt) - _smooth_rate(at[f"dp_{ch}"], width)
            terms = signature_features(at, ch, model, t, width)
            for k in kernel_effects:
                terms[k] = at[f"effect:{k}:{ch}"]
            keep = mask & np.isfinite(rate)
            sens = _smooth_max(np.abs(at[f"sens_{ch}"]), width)
            keep &= sens <= max_sensitivity
            sigma = own_noise.get((rec.file, name))
            if sigma is None:
                sigma = pooled_noise.get(name, math.nan)
            if not math.isfinite(sigma):
                # no quiet window for this sensor in any recording: its noise,
                # hence the weight of its rates, is unknown
                continue
            noise = _rate_noise(sigma, width, dt)
            weight = 1.0 / np.sqrt(noise**2 + (sens * PRESSURE_UNCERTAINTY) ** 2)
            keep &= np.arange(t.size) % max(int(decimate), 1) == 0
            smoothed = {k: _smooth_rate(v, width) for k, v in terms.items()}
            for v in smoothed.values():
                keep &= np.isfinite(v)
            for name in parameters:
                col = at.get(f"param:{name}:{ch}")
                if col is not None:
                    sm = _smooth_rate(col, width)
                    keep &= np.isfinite(sm)
            rates.append(rate[keep])
            weights.append(weight[keep])
            for name in parameters:
                col = at.get(f"param:{name}:{ch}")
                col = np.zeros(t.size) if col is None else _smooth_rate(col, width)
                nuis.setdefault(name, []).append(col[keep])
            for k in feats:
                feats[k].append(smoothed[k][keep])
            tag(keep, t, labels, f"{rec.file}:{ch}", "pressure")
        if exp_moving(rec) and "y" in rec.channels:
            got = _motion_rows(rec, at, model, t, width, dt, parameters, feats, decimate)
            if got is not None:
                rate_m, weight_m, keep, nuis_m = got
                rates.append(rate_m)
                weights.append(weight_m)
                for name in parameters:
                    nuis.setdefault(name, []).append(nuis_m[name])
                tag(keep, t, labels, f"{rec.file}:v", "motion")
    if not rates:
        raise PneumafitInputError(
            f"campaign {campaign.name!r}: attribution: expected {role or 'any'} charge, discharge "
            "or step recordings with pressures, found none"
        )
    return Rows(
        rate=np.concatenate(rates),
        features={k: np.concatenate(v) for k, v in feats.items()},
        phase=np.concatenate(phases),
        group=np.concatenate(groups),
        weight=np.concatenate(weights),
        source=sources,
        nuisance={k: np.concatenate(v) for k, v in nuis.items()},
        channel=np.concatenate(channels),
        nuisance_values={k: float(model[k]) for k in nuis if k in model},
    )


def exp_moving(rec: Recording) -> bool:
    """True for a recording whose piston moves (a step test)."""
    return rec.kind == "step"


def _filter_norm(width: int, dt: float) -> float:
    """Noise gain of the acceleration estimate: the Savitzky-Golay slope of
    the slope of the position, sum of its squared weights to the root (1/s^2)."""
    n = 6 * width + 1
    impulse = np.zeros(n)
    impulse[n // 2] = 1.0
    kern = _rate(_rate(impulse, width, dt), width, dt)[2 * width : n - 2 * width]
    return float(np.sqrt(np.sum(kern * kern)))


def _motion_rows(
    rec: Recording,
    at: Mapping[str, NDArray[np.float64]],
    model: Mapping[str, float],
    t: NDArray[np.float64],
    width: int,
    dt: float,
    parameters: Sequence[str],
    feats: dict[str, list[NDArray[np.float64]]],
    decimate: int,
) -> tuple[Any, Any, Any, dict[str, NDArray[np.float64]]] | None:
    """The acceleration residual of a moving-piston recording, while sliding.

    a_meas = SG slope of v (v the SG slope of the measured position: the
    position's second derivative, smoothed twice); the model's dv/dt at the
    measured state (pressures, position, velocity; the friction mode the
    sign of v) smoothed twice with the weights of :func:`_smooth_rate`, so
    both sides see the same filter. Rows: sliding at more than
    :data:`MIN_SLIDING_SPEED` over two windows, away from the end stops.
    Weight 1 / sqrt(s_a^2 + (PRESSURE_UNCERTAINTY (S_P + S_N) / M)^2): the
    estimate's noise (position noise times the filter's gain) and the
    acceleration error of a pressure error as large as the one the pressure
    rows allow for. Each effect's regressor is its kernel signature on dv/dt
    (0 for the chambers' effects: they act on the motion only through the
    pressures, which are measured). Appends to ``feats``; returns the rate,
    weight, kept mask and nuisance columns, or None when nothing is kept.
    """
    from scipy.ndimage import minimum_filter1d

    vel = np.asarray(at["v"], float)
    acc = _rate(vel, width, dt) - _smooth_rate(_smooth_rate(at["dv"], width), width)
    y = np.asarray(at["y"], float)
    stroke = float(model.get("stroke", 0.5))
    margin = 1.0e-3
    inside = (y > margin) & (y < stroke - margin)
    sliding = minimum_filter1d(np.abs(vel), size=2 * width + 1, mode="nearest")
    keep = np.isfinite(acc) & (sliding > MIN_SLIDING_SPEED)
    keep &= minimum_filter1d(inside.astype(np.int64), size=2 * width + 1, mode="nearest") > 0
    keep &= np.arange(t.size) % max(int(decimate), 1) == 0

    def column(key: str) -> NDArray[np.float64]:
        raw = at.get(key)
        return np.zeros(t.size) if raw is None else _smooth_rate(_smooth_rate(raw, width), width)

    cols = {k: column(f"effect:{k}:v") for k in feats}
    nuis = {name: column(f"param:{name}:v") for name in parameters}
    for col in (*cols.values(), *nuis.values()):
        keep &= np.isfinite(col)
    if keep.sum() < 3:
        return None
    ymeas = np.asarray(rec.channels["y"], float)
    d2 = np.diff(ymeas, 2)
    sigma_y = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
    sigma_a = max(sigma_y, MIN_POSITION_NOISE) * _filter_norm(width, dt)
    bore, rod = float(model.get("bore", 0.032)), float(model.get("rod", 0.016))
    s_sum = 0.25 * math.pi * (2.0 * bore * bore - rod * rod)
    mass = float(model.get("moving_mass", 17.0))
    spread = math.sqrt(sigma_a**2 + (PRESSURE_UNCERTAINTY * s_sum / mass) ** 2)
    weight = np.full(t.size, 1.0 / spread)
    for k in feats:
        feats[k].append(cols[k][keep])
    return acc[keep], weight[keep], keep, {k: v[keep] for k, v in nuis.items()}


# ----------------------------------------------------------------- regression
@dataclass(frozen=True)
class Candidate:
    """One catalog effect's evidence in the residual.

    Attributes
    ----------
    effect : str
        Effect name (:data:`~.catalog.EFFECTS`).
    score : float
        inclusion_probability * variance_explained * phase_match (0..1).
    inclusion_probability : float
        Fraction of bootstrap sparse fits keeping the effect with a positive
        coefficient.
    variance_explained : float
        R^2 of the residual rate by the effect alone (coefficient >= 0).
    phase_match : float
        Cosine between the per-phase sums of squares of the residual rate and
        of the effect's fitted term.
    coefficient : float
        Median bootstrap coefficient (SI unit of :attr:`coefficient_unit`),
        NaN when never kept.
    coefficient_interval : tuple of float
        5 % and 95 % bootstrap quantiles of the coefficient (over fits that
        kept it).
    coefficient_unit : str
    suggested : dict of str to float
        Start values of the effect's parameters for the refit (SI), the
        regression's where it is physical and inside the catalog bounds, else
        the catalog's typical values.
    phases : dict of str to float
        Share of the effect's fitted term (sum of squares) in each phase.
    supported : bool
        inclusion_probability >= :data:`MIN_INCLUSION` and
        variance_explained >= :data:`MIN_VARIANCE` (and, for a signed
        effect, a coefficient at least :data:`MIN_SIGNED_DEPARTURE` of its
        half-range away from the neutral value).
    rows : str
        Row set the evidence was read on: a channel of
        :data:`ROW_CHANNELS`, or ``quiet`` (the pressure rows of
        :data:`QUIET_PHASES`).
    """

    effect: str
    score: float
    inclusion_probability: float
    variance_explained: float
    phase_match: float
    coefficient: float
    coefficient_interval: tuple[float, float]
    coefficient_unit: str
    suggested: dict[str, float]
    phases: dict[str, float]
    supported: bool
    rows: str = "pressure"

    def evidence(self) -> dict[str, Any]:
        """JSON-ready evidence (discovery.json ``candidates[].evidence``)."""
        return {
            "inclusion_probability": self.inclusion_probability,
            "variance_explained": self.variance_explained,
            "phase_match": self.phase_match,
            "coefficient": _finite(self.coefficient),
            "coefficient_interval_90": [_finite(x) for x in self.coefficient_interval],
            "coefficient_unit": self.coefficient_unit,
            "suggested_start": dict(self.suggested),
            "phase_share": dict(self.phases),
            "catalog_phases": list(get_effect(self.effect).phases),
            "supported": self.supported,
            "rows": self.rows,
        }


@dataclass
class Attribution:
    """Result of :func:`attribute`.

    Attributes
    ----------
    candidates : list of Candidate
        Every catalog effect, best score first.
    n_rows : int
        Rows regressed.
    rate_rms : float
        RMS residual rate (Pa/s).
    residual_phases : dict of str to float
        Share of the residual rate's sum of squares per phase.
    explained : float
        R^2 of the full sparse model (all effects kept by the full-data fit).
    n_bootstrap : int
    channels : dict of str to dict
        Per row set (``pressure``, ``motion``, ``quiet``): ``n_rows``,
        ``rate_rms``, ``residual_phases``, ``explained``.
    by_rows : dict of str to dict of str to Candidate
        Every effect's evidence on each row set it was regressed on (effect
        -> row set -> candidate); ``candidates`` holds the one that ranks it
        (:func:`attribute`). The quiet rows' is kept for the effects judged
        there only (:data:`QUIET_PHASES`).
    """

    candidates: list[Candidate]
    n_rows: int
    rate_rms: float
    residual_phases: dict[str, float]
    explained: float
    n_bootstrap: int
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)
    by_rows: dict[str, dict[str, Candidate]] = field(default_factory=dict)

    def supported(self) -> list[Candidate]:
        """Supported candidates, best first."""
        return [c for c in self.candidates if c.supported]

    def other_evidence(self, effect: str) -> list[Candidate]:
        """``effect``'s evidence on the row sets other than the one that
        ranks it (:attr:`by_rows`), in the order the sets are regressed."""
        ranked = next((c.rows for c in self.candidates if c.effect == effect), None)
        return [c for rows, c in self.by_rows.get(effect, {}).items() if rows != ranked]

    def as_dict(self) -> dict[str, Any]:
        return {
            "n_rows": self.n_rows,
            "rate_rms": self.rate_rms,
            "residual_phases": self.residual_phases,
            "explained": self.explained,
            "n_bootstrap": self.n_bootstrap,
            "channels": self.channels,
        }


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


#: Unit of each effect's regression coefficient (its part's ``coefficient_unit``).
_COEFFICIENT_UNIT: RegistryView[parts.Effect, str] = RegistryView(
    parts.EFFECTS, lambda e: e.coefficient_unit
)


def _sparse_fit(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    threshold: float,
    signed: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """STLSQ (pysindy) on standardised columns with negative coefficients removed.

    Columns marked ``signed`` keep a coefficient of either sign. Returns
    coefficients in the standardised units (0 where dropped).
    """
    one_sided = np.ones(x.shape[1], dtype=bool) if signed is None else ~np.asarray(signed)
    import warnings

    import pysindy as ps

    active = np.ones(x.shape[1], dtype=bool)
    coef = np.zeros(x.shape[1])
    for _ in range(x.shape[1]):
        if not active.any():
            break
        opt = ps.STLSQ(threshold=threshold, alpha=1e-6, max_iter=20)
        with warnings.catch_warnings():
            # "eliminated all coefficients" is an answer here, not a problem
            warnings.simplefilter("ignore", UserWarning)
            opt.fit(x[:, active], y[:, None])
        c = np.asarray(opt.coef_, float).reshape(-1)
        coef[:] = 0.0
        coef[active] = c
        negative = (coef < 0.0) & one_sided
        if not negative.any():
            break
        active &= ~negative
        coef[negative] = 0.0
    return coef


def _phase_shares(values: NDArray[np.float64], phase: NDArray[np.str_]) -> NDArray[np.float64]:
    ss = np.array([float(np.sum(values[phase == p] ** 2)) for p in PHASES])
    total = ss.sum()
    return ss / total if total > 0 else ss


def attribute(
    rows: Rows,
    *,
    rng: np.random.Generator,
    n_bootstrap: int = 100,
    threshold: float = 0.05,
    effects: Sequence[str] | None = None,
) -> Attribution:
    """Rank the catalog effects by their evidence in the residual rates.

    The rows of each channel (:data:`ROW_CHANNELS`: the chambers' pressure
    rates, the piston's acceleration) are regressed separately, each on the
    effects whose regressor is not zero there (the pressure channel on every
    effect, as without acceleration rows); an effect's evidence is that of
    its best channel (highest score). A signed effect (a parameter with a
    neutral value inside its bounds, :attr:`~.catalog.EffectParameter.signed`)
    may take a coefficient of either sign; every other coefficient must be
    positive.

    An effect whose catalog phases all lie in :data:`QUIET_PHASES` (a leak,
    the wall's heat capacity) is also judged on the ``quiet`` row set: the
    pressure rows of those phases, regressed on every effect, drawn after
    the channels (so their evidence does not depend on it); its evidence
    there is kept when it is supported and the channels' is not, else by
    rank. Where the
    model's laws are not the rig's, the valves' and the friction's misfit
    makes most of the residual rate while the valves open and the piston
    moves, and a leak explains only a few % of it; at rest, where those
    laws do not act, the same leak is judged against what the rest phases
    leave (docs/effects.md, "Judged where it acts").

    Parameters
    ----------
    rows : Rows
        From :func:`build_rows`.
    rng : numpy.random.Generator
        Draws the bootstrap blocks (pressure channel first).
    n_bootstrap : int
        Bootstrap sparse fits.
    threshold : float
        STLSQ threshold on the standardised coefficients (the share of the
        residual rate's standard deviation a term must carry per standard
        deviation of its regressor).
    effects : sequence of str, optional
        Effects to consider (default: the whole catalog).

    Returns
    -------
    Attribution
        Its summary (``n_rows``, ``rate_rms``, ``residual_phases``,
        ``explained``) is the pressure channel's; ``channels`` has each
        channel's.
    """
    names = [n for n in (effects or list(EFFECTS)) if n in rows.features]
    chan = rows.channels()
    best: dict[str, Candidate] = {}
    by_rows: dict[str, dict[str, Candidate]] = {}
    summaries: dict[str, dict[str, Any]] = {}
    for channel in ROW_CHANNELS:
        sel = chan == channel
        if not sel.any():
            continue
        if channel == "pressure":
            used = names
        else:
            used = [n for n in names if np.any(rows.features[n][sel] != 0.0)]
        if not used:
            continue
        cands, summary = _attribute_channel(
            rows, sel, used, rng, n_bootstrap, threshold, label=channel
        )
        summaries[channel] = summary
        _keep_best(best, cands)
        for c in cands:
            by_rows.setdefault(c.effect, {})[channel] = c
    local = [n for n in names if set(get_effect(n).phases) <= set(QUIET_PHASES)]
    quiet = (chan == "pressure") & np.isin(rows.phase, QUIET_PHASES)
    if local and np.unique(rows.group[quiet]).size >= MIN_QUIET_BLOCKS:
        cands, summary = _attribute_channel(
            rows, quiet, names, rng, n_bootstrap, threshold, label="quiet"
        )
        summaries["quiet"] = summary
        judged = [c for c in cands if c.effect in local]
        # a second route to "supported": supported evidence first, then rank
        _keep_best(best, judged, supported_first=True)
        for c in judged:
            by_rows.setdefault(c.effect, {})["quiet"] = c
    out = sorted(best.values(), key=_rank_key)
    head = summaries.get("pressure") or next(iter(summaries.values()))
    return Attribution(
        candidates=out,
        n_rows=head["n_rows"],
        rate_rms=head["rate_rms"],
        residual_phases=head["residual_phases"],
        explained=head["explained"],
        n_bootstrap=n_bootstrap,
        channels=summaries,
        by_rows=by_rows,
    )


def _rank_key(c: Candidate) -> tuple[float, float, float, str]:
    return (-c.score, -c.inclusion_probability, -c.variance_explained, c.effect)


def _keep_best(
    best: dict[str, Candidate], cands: Sequence[Candidate], *, supported_first: bool = False
) -> None:
    """Keep in ``best`` each effect's better-ranked evidence (with
    ``supported_first``, a supported evidence before an unsupported one)."""

    def key(c: Candidate) -> tuple[Any, ...]:
        return ((not c.supported) if supported_first else False, *_rank_key(c))

    for c in cands:
        old = best.get(c.effect)
        if old is None or key(c) < key(old):
            best[c.effect] = c


#: Base parameters a friction effect's refit may start shifted: the Coulomb
#: level and the viscous coefficient, which enter the sliding acceleration
#: linearly; the static level moves with the Coulomb one (the seal friction
#: adds the same to both, the asymmetry scales both; alone, F_s is poorly
#: conditioned on sliding rows: a free shift started it at 332 N on the
#: asymmetry campaign). The Stribeck velocity and the bristle constants enter
#: nonlinearly: a first-order shift is not trusted.
LEVEL_PARAMETERS: tuple[str, ...] = ("friction_coulomb", "friction_viscous")


def _level_starts(
    rows: Rows,
    sel: NDArray[np.bool_],
    name: str,
    coefficient: float,
    w: NDArray[np.float64],
    y_raw: NDArray[np.float64],
) -> dict[str, float]:
    """Refit starts of the friction levels that go with an effect's coefficient.

    A base fit without a friction effect absorbs its mean into the levels
    (a hidden seal friction c Delta raised F_c and F_s by c mean(Delta):
    30 -> 39 N on the seal campaign), and a refit that adds the effect on
    top of them starts with the friction counted twice (the piston sticks;
    measured: BIC +36000 from there). On the acceleration rows the least
    squares of (residual - coefficient x effect) on the level parameters'
    sensitivities gives the shift of each level that the effect replaces
    (Frisch-Waugh's other half): the start is the base value plus that
    shift (F_c, b; F_s by F_c's shift), clipped to the physical bounds and
    F_s >= F_c. Motion rows with
    the levels among the nuisance parameters only; empty otherwise.
    """
    from pneumafit.models.layout import SPECS

    names = [k for k in LEVEL_PARAMETERS if k in rows.nuisance and k in rows.nuisance_values]
    chan = rows.channels()[sel]
    if not names or not math.isfinite(coefficient) or not np.all(chan == "motion"):
        return {}
    n_mat = np.column_stack([rows.nuisance[k][sel] * w for k in names])
    if not np.any(n_mat):
        return {}
    resid = y_raw - coefficient * rows.features[name][sel] * w
    shift, *_ = np.linalg.lstsq(n_mat, resid, rcond=None)
    out = {}
    for k, dv in zip(names, shift, strict=True):
        spec = SPECS[k]
        out[k] = float(np.clip(rows.nuisance_values[k] + dv, spec.lower, spec.upper))
    if "friction_coulomb" in out and "friction_static" in rows.nuisance_values:
        shift_c = out["friction_coulomb"] - rows.nuisance_values["friction_coulomb"]
        f_s = rows.nuisance_values["friction_static"] + shift_c
        out["friction_static"] = float(max(f_s, out["friction_coulomb"]))
    return out


def _departs(name: str, coefficient: float) -> bool:
    """A signed effect's coefficient departs from neutral by MIN_SIGNED_DEPARTURE."""
    eff = get_effect(name)
    par = eff.parameter(eff.parameter_names()[0])
    if par.neutral is None or not math.isfinite(coefficient):
        return par.neutral is None
    half = par.upper - par.neutral if coefficient >= 0 else par.neutral - par.lower
    return abs(coefficient) >= MIN_SIGNED_DEPARTURE * half


def _signed(name: str) -> bool:
    eff = get_effect(name)
    return eff.parameter(eff.parameter_names()[0]).signed


def _attribute_channel(
    rows: Rows,
    sel: NDArray[np.bool_],
    names: Sequence[str],
    rng: np.random.Generator,
    n_bootstrap: int,
    threshold: float,
    *,
    label: str,
) -> tuple[list[Candidate], dict[str, Any]]:
    """Sparse regression and bootstrap on the rows ``sel`` of one row set ``label``."""
    w = rows.weight[sel]
    y = rows.rate[sel] * w
    y_raw = y.copy()
    phase = rows.phase[sel]
    group = rows.group[sel]
    cols = np.column_stack([rows.features[n][sel] * w for n in names])
    signed = np.array([_signed(n) for n in names], dtype=bool)
    if rows.nuisance:
        # Frisch-Waugh: what the base parameters could absorb is projected
        # out of the residual rate and of every regressor
        nmat = np.column_stack([v[sel] * w for v in rows.nuisance.values()])
        nscale = np.std(nmat, axis=0)
        nmat = nmat[:, nscale > 0] / nscale[nscale > 0]
        if nmat.size:
            q, _r = np.linalg.qr(nmat)
            y = y - q @ (q.T @ y)
            cols = cols - q @ (q.T @ cols)
    ys = float(np.std(y)) or 1.0
    scale = np.std(cols, axis=0)
    usable = scale > 0
    scale = np.where(usable, scale, 1.0)
    x = cols / scale
    z = y / ys
    full = _sparse_fit(x[:, usable], z, threshold, signed[usable])
    coef_full = np.zeros(len(names))
    coef_full[usable] = full
    fitted = x @ coef_full
    explained = 1.0 - float(np.sum((z - fitted) ** 2)) / float(np.sum(z * z))

    blocks = np.unique(group)
    index = [np.flatnonzero(group == b) for b in blocks]
    boot = np.zeros((n_bootstrap, len(names)))
    for i in range(n_bootstrap):
        pick = rng.integers(0, len(index), len(index))
        rsel = np.concatenate([index[j] for j in pick])
        c = np.zeros(len(names))
        c[usable] = _sparse_fit(x[rsel][:, usable], z[rsel], threshold, signed[usable])
        boot[i] = c
    resid_share = _phase_shares(y, phase)
    out: list[Candidate] = []
    for j, name in enumerate(names):
        f = x[:, j]
        fy, ff = float(f @ z), float(f @ f)
        if signed[j]:
            alone = fy / ff if ff > 0 else 0.0
        else:
            alone = fy / ff if ff > 0 and fy > 0 else 0.0
        r2 = alone * fy / float(z @ z) if alone != 0 else 0.0
        share = _phase_shares(alone * f, phase) if alone != 0 else np.zeros(len(PHASES))
        norm = float(np.linalg.norm(share) * np.linalg.norm(resid_share))
        match = float(share @ resid_share) / norm if norm > 0 else 0.0
        kept = boot[:, j] != 0 if signed[j] else boot[:, j] > 0
        prob = float(kept.mean())
        phys = boot[kept, j] * ys / scale[j]
        if phys.size:
            coef = float(np.median(phys))
            lo, hi = (float(v) for v in np.quantile(phys, [0.05, 0.95]))
        else:
            coef, lo, hi = math.nan, math.nan, math.nan
        out.append(
            Candidate(
                effect=name,
                score=prob * r2 * match,
                inclusion_probability=prob,
                variance_explained=r2,
                phase_match=match,
                coefficient=coef,
                coefficient_interval=(lo, hi),
                coefficient_unit=_COEFFICIENT_UNIT.get(name, ""),
                suggested={
                    **suggested_start(name, coef),
                    **_level_starts(rows, sel, name, coef, w, y_raw),
                },
                phases=dict(zip(PHASES, (float(s) for s in share), strict=True)),
                supported=prob >= MIN_INCLUSION
                and r2 >= MIN_VARIANCE
                and (not signed[j] or _departs(name, coef)),
                rows=label,
            )
        )
    summary = {
        "n_rows": int(sel.sum()),
        "rate_rms": float(np.sqrt(np.mean(y * y))),
        "residual_phases": dict(zip(PHASES, (float(s) for s in resid_share), strict=True)),
        "explained": explained,
    }
    return out, summary


def suggested_start(effect: str, coefficient: float) -> dict[str, float]:
    """Refit start of an effect's parameters from a regression coefficient.

    The coefficient is the principal parameter itself (its inverse for a
    part with ``inverse_coefficient``, the wall capacity; a signed effect's
    departure from its neutral value, e.g. k_A - 1); it is used when finite,
    positive (either sign for a signed effect) and inside the catalog's
    fitting bounds, else the catalog's typical value. A start below the
    part's ``start_floor`` is raised to it (the spool: a spool faster than
    the fitting integrator's step cannot be simulated by it, fixed-step RK3
    at up to 4 ms is stable for tau > ~1.6 ms).
    """
    eff = get_effect(effect)
    start = eff.typical_values()
    signed = eff.parameter(eff.parameter_names()[0]).signed
    if not (math.isfinite(coefficient) and (coefficient > 0.0 or signed)):
        return start
    principal = eff.parameter_names()[0]
    par = eff.parameter(principal)
    if par.neutral is not None:
        # a signed effect: the coefficient is the departure from the neutral value
        value = par.neutral + coefficient
        if math.isfinite(value) and par.lower <= value <= par.upper:
            start[principal] = float(value)
        return start
    part = parts.EFFECTS[effect]
    value = 1.0 / coefficient if part.inverse_coefficient else coefficient
    if part.start_floor > 0.0:
        value = max(value, part.start_floor)
    if par.lower <= value <= par.upper:
        start[principal] = float(value)
    return start
