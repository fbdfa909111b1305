"""The truth simulator: chamber balance, mechanics and parts, integrated by scipy.

State of a moving-piston test: x = [y, v, z, P_P, P_N, T_P, T_N, m_P, m_N]
(m, m/s, m, Pa, Pa, K, K, kg, kg): position, velocity, friction bristle
state, chamber pressures and gas temperatures, and the mass each valve has
let into its chamber since the start (for bookkeeping and mass checks). A
blocked-piston test (charge, discharge) integrates only its chamber,
x = [P, T, m].

Chamber balance (physics notes; perfect gas, homogeneous chamber), with
inflows q_in carrying their upstream temperatures (H_in = sum q_in,i T_in,i),
outflow q_out at the chamber temperature T (through the valve and, when the
configuration has one, the external leak to the atmosphere), volume V(y)
and wall heat flow Q = lambda A (T_w - T):

    dP/dt = gamma r / V (H_in - q_out T) - gamma P / V dV/dt + (gamma - 1) / V Q
    dT/dt = (gamma - 1) T / (P V) [c_v (gamma H_in - T q_in) - (gamma - 1) c_v T q_out
                                   - P dV/dt + Q]

The second line was derived here, not copied: from P V = m r T,
dT/dt = T (dP/dt / P + dV/dt / V - (dm/dt) / m) with dm/dt = q_in - q_out
and m = P V / (r T); substituting dP/dt and c_v (gamma - 1) = r gives the
bracket above (it agrees with the notes' line with T_in q_in -> H_in).

Mechanics (horizontal unless the parameter set says otherwise):

    M dv/dt = S_P P_P - S_N P_N - P_atm (S_P - S_N) - F_load - M g sin(angle)
              - F_friction + F_stop

S_P = pi D^2 / 4, S_N = pi (D^2 - d^2) / 4, V_P = V_0P + S_P y,
V_N = V_0N + S_N (L - y). Supply and atmospheric air are at the ambient
temperature.

Commands replayed from a recording are held constant between samples (zero
order hold) and the integration restarts at each change; a closed-loop test
evaluates its ``pd`` law continuously, u_P = clip(u0 + kp (y_ref - y) - kd v,
+-umax), u_N = -u_P, with y_ref held between samples. Integration:
:func:`scipy.integrate.solve_ivp` (LSODA by default, rtol 1e-8, absolute
tolerances scaled per state). Flow tests evaluate the static valve flow
q_m(P_held, u) directly, gas at ambient temperature.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from pneumafit.errors import PneumafitInputError
from pneumafit.simulation import Experiment
from pneumafit.virtual_rig.truth.constants import CV, GAMMA, GRAVITY, R_GAS
from pneumafit.virtual_rig.truth.heat import exchange_area

if TYPE_CHECKING:
    from pneumafit.virtual_rig.truth.config import TruthConfig

__all__ = ["CHANNELS", "TruthSimulation", "TruthSimulator"]

#: Channels of a truth simulation (SI): see :class:`TruthSimulation`.
CHANNELS = (
    "y", "v", "z", "p_P", "p_N", "T_P", "T_N", "qm_P", "qm_N", "u_P", "u_N",
    "lambda_P", "lambda_N", "F_f", "m_P", "m_N",
)  # fmt: skip

# absolute tolerances per state, for rtol ~1e-8: position, velocity, bristle,
# pressures, temperatures, masses
_ATOL_MOVING = np.array([1e-10, 1e-9, 1e-12, 1e-3, 1e-3, 1e-6, 1e-6, 1e-13, 1e-13])
_ATOL_BLOCKED = np.array([1e-3, 1e-6, 1e-13])


@dataclass
class TruthSimulation:
    """Result of one truth simulation.

    Attributes
    ----------
    time : ndarray
        Sample times (s), those of the experiment.
    channels : dict of str to ndarray
        Position y (m), velocity v (m/s), bristle state z (m), pressures p_P,
        p_N (Pa), gas temperatures T_P, T_N (K), net valve mass flows into the
        chambers qm_P, qm_N (kg/s), commands u_P, u_N (V), heat-transfer
        coefficients lambda_P, lambda_N (W/m^2/K), friction F_f (N), mass let
        in by each valve since the start m_P, m_N (kg). NaN after a failure.
    ok : bool
        True when the integration succeeded.
    message : str
        What went wrong, in words ("ok" otherwise).
    n_evaluations : int
        Right-hand-side evaluations used.
    """

    time: NDArray[np.float64]
    channels: dict[str, NDArray[np.float64]]
    ok: bool
    message: str
    n_evaluations: int = 0

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        return self.channels[name]


class _Plant:
    """The rig with its parts at one parameter set (SI)."""

    def __init__(self, config: TruthConfig, par: Mapping[str, float]) -> None:
        self.valve = config.valve
        self.friction = config.friction
        self.heat = config.heat
        self.stops = config.end_stops
        self.leak = config.external_leak
        # the real bore (a barrel part), else the declared one
        barrel = getattr(config, "barrel", None)
        real = None if barrel is None else barrel.bore
        self.bore = float(par["bore"] if real is None else real)
        self.rod = float(par["rod"])
        self.stroke = float(par["stroke"])
        self.v0_p = float(par["dead_volume_P"])
        self.v0_n = float(par["dead_volume_N"])
        self.mass = float(par["moving_mass"])
        self.p_s = float(par["supply_pressure"])
        self.p_e = float(par["exhaust_pressure"])
        self.t_amb = float(par["ambient_temperature"])
        hw = self.heat.wall_temperature
        self.t_wall = float(par["wall_temperature"] if hw is None else hw)
        hl = self.heat.length
        self.length = float(par["characteristic_length"] if hl is None else hl)
        self.s_p = 0.25 * math.pi * self.bore**2
        self.s_n = 0.25 * math.pi * (self.bore**2 - self.rod**2)
        self.f_ext = (
            self.p_e * (self.s_p - self.s_n)
            + float(par.get("external_force", 0.0))
            + self.mass * GRAVITY * math.sin(float(par.get("mounting_angle", 0.0)))
        )

    # ------------------------------------------------------------------ parts
    def volume(self, chamber: str, y: float) -> float:
        """Chamber volume (m^3) at position y (m)."""
        if chamber == "P":
            return self.v0_p + self.s_p * y
        return self.v0_n + self.s_n * (self.stroke - y)

    def area(self, chamber: str, y: float) -> float:
        """Exchange area (m^2) of a chamber at position y (m)."""
        v0 = self.v0_p if chamber == "P" else self.v0_n
        return exchange_area(self.heat.area, chamber, y, self.bore, self.rod, self.stroke, v0)

    def lam(self, pressure: float, temperature: float) -> float:
        """Heat-transfer coefficient (W/m^2/K)."""
        return self.heat.coefficient(pressure, temperature, self.t_wall, self.length)

    def valve_flows(self, u: float, pres: float, temp: float) -> tuple[float, float, float]:
        """(q_in (kg/s), H_in (kg K/s), q_out (kg/s)) of one valve into its chamber."""
        q_s, t_s, q_e, t_e = self.valve.flows(u, pres, temp, self.p_s, self.p_e, self.t_amb)
        q_in = h_in = q_out = 0.0
        if q_s >= 0.0:
            q_in += q_s
            h_in += q_s * t_s
        else:
            q_out -= q_s
        if q_e >= 0.0:
            q_out += q_e
        else:
            q_in -= q_e
            h_in -= q_e * t_e
        return q_in, h_in, q_out

    def chamber(
        self, u: float, pres: float, temp: float, vol: float, dvol: float, area: float,
        name: str = "P",
    ) -> tuple[float, float, float, float]:  # fmt: skip
        """(dP/dt (Pa/s), dT/dt (K/s), net valve inflow (kg/s), lambda) of chamber ``name``.

        The external leak (if any) enters the balance but not the returned
        valve inflow (the flow meter's quantity and the m_P, m_N states).
        """
        q_in, h_in, q_out = self.valve_flows(u, pres, temp)
        q_valve = q_in - q_out
        if self.leak is not None:
            q_l, t_l = self.leak.flow(name, pres, temp, self.p_e, self.t_amb)
            if q_l >= 0.0:
                q_out += q_l
            else:
                q_in -= q_l
                h_in -= q_l * t_l
        lam = self.lam(pres, temp)
        heat = lam * area * (self.t_wall - temp)
        dp = (
            GAMMA * R_GAS / vol * (h_in - q_out * temp)
            - GAMMA * pres / vol * dvol
            + (GAMMA - 1.0) / vol * heat
        )
        dt = (GAMMA - 1.0) * temp / (pres * vol) * (
            CV * (GAMMA * h_in - temp * q_in)
            - (GAMMA - 1.0) * CV * temp * q_out
            - pres * dvol
            + heat
        )  # fmt: skip
        return dp, dt, q_valve, lam

    def delta(self, p_p: float, p_n: float) -> float:
        """Pressure excess of the seals, P_P + P_N - 2 P_atm (Pa)."""
        return p_p + p_n - 2.0 * self.p_e

    # ------------------------------------------------------------------ rhs
    def moving(self, x: NDArray[np.float64], u_p: float, u_n: float) -> tuple[list[float], float]:
        """dx/dt of a moving-piston test and the friction force (N)."""
        y, v, z, p_p, p_n, t_p, t_n = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
        dp_p, dt_p, q_p, _ = self.chamber(
            u_p, p_p, t_p, self.volume("P", y), self.s_p * v, self.area("P", y), "P"
        )
        dp_n, dt_n, q_n, _ = self.chamber(
            u_n, p_n, t_n, self.volume("N", y), -self.s_n * v, self.area("N", y), "N"
        )
        dz, f_f = self.friction.rates(v, z, self.delta(p_p, p_n))
        force = (
            self.s_p * p_p - self.s_n * p_n - self.f_ext - f_f
            + self.stops.force(y, v, self.stroke)
        )  # fmt: skip
        return [v, force / self.mass, dz, dp_p, dp_n, dt_p, dt_n, q_p, q_n], f_f

    def blocked(self, x: NDArray[np.float64], u: float, chamber: str, y: float) -> list[float]:
        """dx/dt of a blocked-piston test, x = [P, T, m]."""
        dp, dt, q, _ = self.chamber(u, x[0], x[1], self.volume(chamber, y), 0.0,
                                    self.area(chamber, y), chamber)  # fmt: skip
        return [dp, dt, q]


def _segments(values: NDArray[np.float64]) -> list[tuple[int, int]]:
    """Index ranges [k0, k1) over which ``values`` is constant."""
    change = np.flatnonzero(np.diff(values) != 0.0) + 1
    bounds = [0, *change.tolist(), values.size]
    return [(a, b) for a, b in itertools.pairwise(bounds) if b > a]


class TruthSimulator:
    """Independent truth simulator of the virtual rig (see the module docstring).

    Parameters
    ----------
    config : TruthConfig
        The truth's parts (valve, friction, heat, end stops).
    rtol : float
        Relative tolerance of :func:`scipy.integrate.solve_ivp`.
    method : {"LSODA", "Radau", "BDF"}
        Integration method.
    """

    def __init__(self, config: TruthConfig, rtol: float = 1e-8, method: str = "LSODA") -> None:
        if method not in ("LSODA", "Radau", "BDF"):
            raise PneumafitInputError(
                f"truth simulator: method: expected LSODA, Radau or BDF, found {method!r}"
            )
        if not 1e-13 <= rtol <= 1e-3:
            raise PneumafitInputError(
                f"truth simulator: rtol: expected a value in [1e-13, 1e-3], found {rtol!r}"
            )
        self.config = config
        self.rtol = float(rtol)
        self.method = method

    def simulate(self, parameters: Mapping[str, float], experiment: Experiment) -> TruthSimulation:
        """Simulate one experiment at a parameter set (SI, PARAMETER_SPECS names).

        Parameters
        ----------
        parameters : mapping of str to float
            Rig geometry and conditions (bore, rod, stroke, dead volumes,
            moving mass, supply and exhaust pressures, ambient and wall
            temperatures, characteristic length, external force, mounting
            angle); the valve, friction and heat parameters of the set are
            not used, the truth's parts are.
        experiment : Experiment
            ``flow``, ``charge``, ``discharge`` or ``step`` (``pd`` law).

        Returns
        -------
        TruthSimulation
            Channels at ``experiment.time``; ``ok`` False with a message
            when the integration failed.
        """
        plant = _Plant(self.config, parameters)
        time = experiment.time
        try:
            if experiment.kind == "flow":
                return self._flow(plant, experiment)
            if experiment.blocked:
                return self._blocked(plant, experiment)
            if experiment.closed_loop:
                return self._closed_loop(plant, experiment)
            return self._open_loop(plant, experiment)
        except (ArithmeticError, ValueError, _Failure) as exc:
            nan = np.full(time.size, np.nan)
            return TruthSimulation(time, {c: nan.copy() for c in CHANNELS}, False, str(exc))

    # ------------------------------------------------------------------ kinds
    def _flow(self, plant: _Plant, exp: Experiment) -> TruthSimulation:
        ch = exp.chamber or "P"
        other = "N" if ch == "P" else "P"
        u = _command(exp, ch)
        assert exp.p_chamber is not None  # checked by Experiment
        held = exp.p_chamber
        cache: dict[tuple[float, float], float] = {}
        q = np.empty(held.size)
        for k in range(held.size):
            key = (float(held[k]), float(u[k]))
            if key not in cache:
                if not key[0] > 0.0:
                    raise _Failure(f"held pressure {key[0]!r} Pa at sample {k}: expected > 0")
                cache[key] = plant.valve.net_flow(
                    key[1], key[0], plant.t_amb, plant.p_s, plant.p_e, plant.t_amb
                )
            q[k] = cache[key]
        n = held.size
        chans = _blank(n, plant, exp)
        chans[f"p_{ch}"] = held.copy()
        chans[f"T_{ch}"] = np.full(n, plant.t_amb)
        chans[f"qm_{ch}"] = q
        chans[f"u_{ch}"] = u.copy()
        chans[f"u_{other}"] = np.zeros(n)
        return TruthSimulation(exp.time, chans, True, "ok", 0)

    def _blocked(self, plant: _Plant, exp: Experiment) -> TruthSimulation:
        ch = exp.chamber or "P"
        y = float(exp.initial.get("y", 0.0))
        u = _command(exp, ch)
        x = np.array([
            float(exp.initial.get(f"p_{ch}", plant.p_e)),
            float(exp.initial.get(f"T_{ch}", plant.t_wall)),
            0.0,
        ])  # fmt: skip
        t = exp.time
        out = np.empty((t.size, 3))
        nfev = 0
        for k0, k1 in _segments(u):
            uk = float(u[k0])

            def rhs(_t: float, s: NDArray[np.float64], uk: float = uk) -> list[float]:
                return plant.blocked(s, uk, ch, y)

            x, seg, n_f = self._solve(rhs, t, k0, k1, x, _ATOL_BLOCKED)
            out[k0:k1] = seg
            nfev += n_f
        n = t.size
        chans = _blank(n, plant, exp)
        chans[f"p_{ch}"] = out[:, 0]
        chans[f"T_{ch}"] = out[:, 1]
        chans[f"m_{ch}"] = out[:, 2]
        chans[f"u_{ch}"] = u.copy()
        chans["y"] = np.full(n, y)
        q = np.empty(n)
        lam = np.empty(n)
        for k in range(n):
            q_in, _, q_out = plant.valve_flows(float(u[k]), out[k, 0], out[k, 1])
            q[k] = q_in - q_out
            lam[k] = plant.lam(out[k, 0], out[k, 1])
        chans[f"qm_{ch}"] = q
        chans[f"lambda_{ch}"] = lam
        return _checked(TruthSimulation(t, chans, True, "ok", nfev))

    def _open_loop(self, plant: _Plant, exp: Experiment) -> TruthSimulation:
        u_p = _command(exp, "P")
        u_n = _command(exp, "N")
        both = np.stack([u_p, u_n])

        def law(k: int) -> Callable[[float, NDArray[np.float64]], tuple[float, float]]:
            a, b = float(u_p[k]), float(u_n[k])
            return lambda _t, _x: (a, b)

        change = np.flatnonzero(np.any(np.diff(both, axis=1) != 0.0, axis=0)) + 1
        return self._moving(plant, exp, change, law)

    def _closed_loop(self, plant: _Plant, exp: Experiment) -> TruthSimulation:
        c = exp.controller
        if c is None or not hasattr(c, "kp"):
            raise _Failure("closed loop: only the 'pd' law is simulated by the truth")
        assert exp.y_ref is not None  # checked by Experiment
        y_ref = exp.y_ref
        kp, kd, u0, umax = float(c.kp), float(c.kd), float(c.u0), float(c.umax)

        def law(k: int) -> Callable[[float, NDArray[np.float64]], tuple[float, float]]:
            r = float(y_ref[k])

            def pd(_t: float, x: NDArray[np.float64]) -> tuple[float, float]:
                u = min(max(u0 + kp * (r - x[0]) - kd * x[1], -umax), umax)
                return u, -u

            return pd

        change = np.flatnonzero(np.diff(y_ref) != 0.0) + 1
        return self._moving(plant, exp, change, law)

    def _moving(
        self,
        plant: _Plant,
        exp: Experiment,
        change: NDArray[np.int64],
        law: Callable[[int], Callable[[float, NDArray[np.float64]], tuple[float, float]]],
    ) -> TruthSimulation:
        ini = exp.initial
        x = np.array([
            float(ini.get("y", 0.0)), float(ini.get("v", 0.0)), float(ini.get("z", 0.0)),
            float(ini.get("p_P", plant.p_e)), float(ini.get("p_N", plant.p_e)),
            float(ini.get("T_P", plant.t_wall)), float(ini.get("T_N", plant.t_wall)), 0.0, 0.0,
        ])  # fmt: skip
        t = exp.time
        bounds = [0, *change.tolist(), t.size]
        out = np.empty((t.size, 9))
        cmd = np.empty((t.size, 2))
        nfev = 0
        for k0, k1 in itertools.pairwise(bounds):
            if k1 <= k0:
                continue
            u_of = law(k0)

            def rhs(tt: float, s: NDArray[np.float64], u_of: Any = u_of) -> list[float]:
                up, un = u_of(tt, s)
                return plant.moving(s, up, un)[0]

            x, seg, n_f = self._solve(rhs, t, k0, k1, x, _ATOL_MOVING)
            out[k0:k1] = seg
            nfev += n_f
            for k in range(k0, k1):
                cmd[k] = u_of(float(t[k]), out[k])
        n = t.size
        names = ("y", "v", "z", "p_P", "p_N", "T_P", "T_N", "m_P", "m_N")
        chans = {name: out[:, i].copy() for i, name in enumerate(names)}
        chans["u_P"] = cmd[:, 0].copy()
        chans["u_N"] = cmd[:, 1].copy()
        f_f = np.empty(n)
        aux = {key: np.empty(n) for key in ("qm_P", "qm_N", "lambda_P", "lambda_N")}
        for k in range(n):
            row = out[k]
            f_f[k] = plant.moving(row, cmd[k, 0], cmd[k, 1])[1]
            for c, i, j in (("P", 3, 5), ("N", 4, 6)):
                q_in, _, q_out = plant.valve_flows(float(cmd[k, 0 if c == "P" else 1]), row[i],
                                                   row[j])  # fmt: skip
                aux[f"qm_{c}"][k] = q_in - q_out
                aux[f"lambda_{c}"][k] = plant.lam(row[i], row[j])
        chans.update(aux)
        chans["F_f"] = f_f
        return _checked(TruthSimulation(t, chans, True, "ok", nfev))

    # ------------------------------------------------------------------ solver
    def _solve(
        self,
        rhs: Callable[[float, NDArray[np.float64]], list[float]],
        t: NDArray[np.float64],
        k0: int,
        k1: int,
        x: NDArray[np.float64],
        atol: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
        """Integrate from t[k0] over samples k0..k1-1 and on to t[k1] (if any).

        Returns the state at the segment's end, the states at its samples
        (k1 - k0, n_states) and the evaluations used.
        """
        t_end = float(t[k1]) if k1 < t.size else float(t[k1 - 1])
        t_eval = t[k0:k1]
        if t_end <= t[k0]:
            return x, x[None, :].copy(), 0
        if k1 < t.size:
            t_eval = np.append(t_eval, t_end)
        sol = solve_ivp(rhs, (float(t[k0]), t_end), x, method=self.method, t_eval=t_eval,
                        rtol=self.rtol, atol=atol)  # fmt: skip
        if not sol.success:
            raise _Failure(f"solve_ivp ({self.method}) failed at t = {t[k0]:g} s: {sol.message}")
        states = sol.y.T
        if not np.all(np.isfinite(states)):
            raise _Failure(f"non-finite state after t = {t[k0]:g} s")
        return states[-1].copy(), states[: k1 - k0], int(sol.nfev)


class _Failure(RuntimeError):
    """A truth simulation could not be completed."""


def _command(exp: Experiment, chamber: str) -> NDArray[np.float64]:
    """The replayed command of one valve (V); the other's negative if absent."""
    own = exp.u_P if chamber == "P" else exp.u_N
    other = exp.u_N if chamber == "P" else exp.u_P
    if own is not None:
        return np.asarray(own, dtype=float)
    if other is not None:
        return 0.0 - np.asarray(other, dtype=float)
    return np.zeros(exp.time.size)


def _blank(n: int, plant: _Plant, exp: Experiment) -> dict[str, NDArray[np.float64]]:
    ini = exp.initial
    return {
        "y": np.full(n, float(ini.get("y", 0.0))),
        "v": np.zeros(n),
        "z": np.zeros(n),
        "p_P": np.full(n, float(ini.get("p_P", plant.p_e))),
        "p_N": np.full(n, float(ini.get("p_N", plant.p_e))),
        "T_P": np.full(n, plant.t_wall),
        "T_N": np.full(n, plant.t_wall),
        "qm_P": np.zeros(n),
        "qm_N": np.zeros(n),
        "u_P": np.zeros(n),
        "u_N": np.zeros(n),
        "lambda_P": np.zeros(n),
        "lambda_N": np.zeros(n),
        "F_f": np.zeros(n),
        "m_P": np.zeros(n),
        "m_N": np.zeros(n),
    }


def _checked(sim: TruthSimulation) -> TruthSimulation:
    for name in ("p_P", "p_N", "T_P", "T_N"):
        if not np.all(sim.channels[name] > 0.0):
            k = int(np.flatnonzero(~(sim.channels[name] > 0.0))[0])
            nan = np.full(sim.time.size, np.nan)
            return TruthSimulation(
                sim.time, {c: nan.copy() for c in CHANNELS}, False,
                f"{name} <= 0 at t = {sim.time[k]:g} s (non-physical state)", sim.n_evaluations,
            )  # fmt: skip
    return sim
