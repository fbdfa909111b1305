"""Reference solutions with scipy's ``solve_ivp`` on the same hybrid model.

Independent of the compiled integrator: scipy chooses the steps (Radau,
LSODA, ...) and locates the friction mode changes with its own event finder
(v = 0 while sliding; |F_d| = F_s while stuck), restarting the solver at each
event and at each kink of the inputs (sample times where the interpolated
commands or reference change slope). The LuGre friction law has no modes and
no events; here its bristle relaxation rate is not limited (the compiled
integrator limits it to its step), so this is the exact LuGre model.

The right-hand side is the model's own :func:`pneumafit.models.kernel.rhs`,
either compiled or as pure Python (:func:`pure_python`). The benchmark
(``benchmarks/bench_simulate.py``) times both as scipy's peers of the
compiled simulator:

- ``compiled=False``: the "straightforward" reference, the RHS's own source
  run by CPython;
- ``compiled=True``: what a user would wire up instead, one compiled call per
  right-hand-side evaluation (:func:`_evaluate`: sample lookup, valve
  commands and RHS in one numba function, compiled once and cached), so that
  scipy's own stepping and event handling are what remains in Python.
"""

from __future__ import annotations

import types
from collections.abc import Callable, Mapping

import numpy as np
from numba.core.dispatcher import Dispatcher
from scipy.integrate import solve_ivp

from pneumafit.errors import PneumafitComputationError, PneumafitInputError
from pneumafit.models import kernel
from pneumafit.models.layout import C_VALVE_ORDER, NCTRL, X_E0, X_UN, X_UP, X_V, X_Z
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.part_kernel import kernel_for, rebound
from pneumafit.models.parts import FRICTION_LAWS
from pneumafit.models.structure import ModelStructure, get_structure
from pneumafit.numba_stamp import njit
from pneumafit.simulation.experiment import Experiment


def pure_python(fn: Callable) -> Callable:
    """Pure-Python twin of a numba-compiled function and everything it calls.

    Rebuilds ``fn.py_func`` with globals in which every compiled function is
    replaced, recursively, by its own pure-Python twin. Same source, run by
    the CPython interpreter.
    """
    memo: dict[int, Callable] = {}

    def convert(f: Callable) -> Callable:
        if id(f) in memo:
            return memo[id(f)]
        py = f.py_func
        env: dict = dict(py.__globals__)
        new = types.FunctionType(py.__code__, env, py.__name__, py.__defaults__, py.__closure__)
        memo[id(f)] = new
        for name in py.__code__.co_names:
            value = env.get(name)
            if isinstance(value, Dispatcher):
                env[name] = convert(value)
        return new

    return convert(fn)


@njit(cache=True)
def _evaluate(
    tt: float, xx: np.ndarray, mode: int, t: np.ndarray, inp: np.ndarray, cfg: np.ndarray,
    ctrl: np.ndarray, p: np.ndarray, d: np.ndarray, aux: np.ndarray, k_lo: int, k_hi: int,
) -> np.ndarray:  # fmt: skip
    """dx/dt at time ``tt`` in friction mode ``mode``, in one compiled call.

    The same arithmetic as the pure-Python ``evaluate`` of
    :func:`solve_reference` (sample interval, linear interpolation weight,
    :func:`~pneumafit.models.kernel.commands`, :func:`~pneumafit.models.kernel.rhs`);
    fills ``aux`` (friction forces for the event functions) and returns a new
    array, as scipy keeps what the RHS returns. The sample interval is kept in
    [k_lo, k_hi], the segment being integrated: held inputs jump at its ends,
    and the solver's evaluations there belong to it.
    """
    k = np.searchsorted(t, tt, side="right") - 1
    k = min(max(k, k_lo), k_hi)
    w = (tt - t[k]) / (t[k + 1] - t[k])
    u_p, u_n = kernel.commands(xx, inp, k, w, cfg, ctrl)
    dx = np.empty(xx.size)
    kernel.rhs(xx, mode, u_p, u_n, p, d, cfg, dx, aux)
    return dx


def _breakpoints(t: np.ndarray, inp: np.ndarray, hold: bool) -> np.ndarray:
    """Sample indices where an input held between samples jumps (``hold``)
    or a linearly interpolated one changes slope."""
    if hold:
        idx = np.flatnonzero(np.any(np.diff(inp, axis=0) != 0.0, axis=1)) + 1
        return np.unique(np.concatenate([[0], idx, [t.size - 1]]))
    slope = np.diff(inp, axis=0) / np.diff(t)[:, None]
    kink = np.any(np.abs(np.diff(slope, axis=0)) > 1e-12 * (1 + np.abs(slope[1:])), axis=1)
    idx = np.flatnonzero(kink) + 1
    return np.unique(np.concatenate([[0], idx, [t.size - 1]]))


def solve_reference(
    model: str | ModelStructure,
    parameters: Mapping[str, float] | np.ndarray,
    experiment: Experiment,
    *,
    method: str = "Radau",
    rtol: float = 1e-10,
    atol: float | None = None,
    compiled: bool = True,
) -> dict[str, np.ndarray]:
    """Solve an experiment with ``scipy.integrate.solve_ivp``.

    Parameters
    ----------
    model : str or ModelStructure
    parameters : mapping or ndarray
        Named SI values or a full parameter vector.
    experiment : Experiment
        A blocked or moving-piston test (flow tests have no dynamics).
    method : str
        Any ``solve_ivp`` method; ``"Radau"`` by default.
    rtol : float
        Relative tolerance.
    atol : float, optional
        Absolute tolerance per state; default ``rtol`` times a typical scale
        of each state (0.5 m, 1 m/s, 1e5 Pa, 300 K, 1e-3 kg, 10 V).
    compiled : bool
        Use the compiled right-hand side (True) or its pure-Python twin.

    Returns
    -------
    dict of str to ndarray
        y, v, p_N, p_P, T_N, T_P, m_supply, m_exhaust and the LuGre bristle
        deflection z_f (0 for the switch model) at the sample times.

    Raises
    ------
    PneumafitInputError
        A flow test (static: nothing to integrate).
    PneumafitComputationError
        The integrator failed.
    """
    structure = get_structure(model)
    p = (
        np.asarray(parameters, dtype=float)
        if isinstance(parameters, np.ndarray)
        else parameter_vector(parameters)
    )
    if experiment.kind == "flow":
        raise PneumafitInputError(
            f"solve_reference: experiment {experiment.name!r}: kind: expected a dynamic test "
            "(flow tests are static; nothing to integrate), found 'flow'"
        )
    # a structure with outside parts (models.part_kernel) runs on the kernel's
    # copy bound to them
    kern = kernel_for(structure)
    rhs = kern.rhs if compiled else pure_python(kern.rhs)
    commands = kern.commands if compiled else pure_python(kern.commands)
    law = experiment.controller.law if experiment.closed_loop else 0
    cfg = structure.config(blocked=experiment.blocked, chamber=experiment.chamber, closed_loop=law)
    ctrl = experiment.controller.as_array() if experiment.controller else np.zeros(NCTRL)
    t = experiment.time
    inp = experiment.inputs()
    d = np.empty(kernel.ND)
    kernel.derive(p, d)
    nx = kern.NX  # the copy's for outside effects' states past layout.NX
    x = np.empty(nx)
    kern._initial_state(experiment.initial_state(nx), p, cfg, x)
    if cfg[C_VALVE_ORDER] > 0:  # valve dynamics: the spool starts at the first command
        x[X_UP], x[X_UN] = commands(x, inp, 0, 0.0, cfg, ctrl)
    dx = np.empty(nx)
    aux = np.empty(kernel.NAUX)
    if atol is None:
        scale = np.ones(nx)  # the outside effects' states (X_E0 on): 1 in their unit
        scale[:X_E0] = [0.5, 1.0, 1e5, 1e5, 300, 300, 1e-3, 1e-3, 300, 300, 10, 10, 1e3, 1e3, 1e-4]
        atol_v = rtol * scale
    else:
        atol_v = np.full(nx, atol)

    span = [0, t.size - 2]  # the sample intervals evaluate() may use
    if compiled:
        inp_c = np.ascontiguousarray(inp, dtype=float)
        evaluate_c = rebound(_evaluate, kern)

        def evaluate(tt: float, xx: np.ndarray, mode: int) -> np.ndarray:
            return evaluate_c(tt, xx, mode, t, inp_c, cfg, ctrl, p, d, aux, span[0], span[1])

    else:

        def evaluate(tt: float, xx: np.ndarray, mode: int) -> np.ndarray:
            k = int(np.clip(np.searchsorted(t, tt, side="right") - 1, span[0], span[1]))
            w = (tt - t[k]) / (t[k + 1] - t[k])
            u_p, u_n = commands(xx, inp, k, w, cfg, ctrl)
            rhs(xx, mode, u_p, u_n, p, d, cfg, dx, aux)
            return dx.copy()

    blocked = experiment.blocked
    lugre = structure.friction == "lugre" and not blocked
    # no stuck mode and no events but in the switch model and the laws from
    # outside in its modes (FrictionLaw.stuck); LuGre and the other laws
    # registered from outside are smooth
    smooth = not FRICTION_LAWS[structure.friction].modes and not blocked
    if lugre and not np.isfinite(x[X_Z]):
        x[X_Z] = 0.0
        evaluate(t[0], x, 0)
        x[X_Z] = kernel.initial_deflection(x, p, cfg, aux[kernel.A_FD])
    evaluate(t[0], x, 0)
    mode = 0
    if not blocked and not smooth:
        if x[X_V] != 0.0:
            mode = 1 if x[X_V] > 0 else -1
        else:
            mode = kernel.next_mode(aux[kernel.A_FD], aux[kernel.A_FS])

    out = np.full((t.size, nx), np.nan)
    out[0] = x
    hold = structure.inputs == "hold"
    bps = _breakpoints(t, inp[:, :3], hold)
    t_now = t[0]
    for seg in range(bps.size - 1):
        t_end = t[bps[seg + 1]]
        if hold:  # the segment's own held value, also at its end
            span[0], span[1] = int(bps[seg]), int(bps[seg + 1]) - 1
        while t_now < t_end:
            current = mode

            def f(tt, xx, current=current):
                return evaluate(tt, xx, current)

            events = []
            if not blocked and not smooth:
                if current != 0:

                    def stop(tt, xx):
                        return xx[X_V]

                    stop.terminal = True
                    stop.direction = -current
                    events.append(stop)
                else:

                    def slip(tt, xx):
                        evaluate(tt, xx, 0)
                        return abs(aux[kernel.A_FD]) - aux[kernel.A_FS]

                    slip.terminal = True
                    slip.direction = 1
                    events.append(slip)
            mask = (t > t_now) & (t <= t_end)
            sol = solve_ivp(
                f, (t_now, t_end), x, method=method, rtol=rtol, atol=atol_v,
                events=events or None, dense_output=True,
            )  # fmt: skip
            if sol.status == -1:
                raise PneumafitComputationError(f"solve_reference: {method} failed: {sol.message}")
            t_stop = sol.t[-1]
            sel = mask & (t <= t_stop)
            if np.any(sel):
                out[sel] = sol.sol(t[sel]).T
            x = sol.y[:, -1].copy()
            if sol.status == 1:  # an event: decide the new mode at rest
                x[X_V] = 0.0
                evaluate(t_stop, x, 0)
                if current == 0:
                    mode = 1 if aux[kernel.A_FD] > 0 else -1
                else:
                    mode = kernel.next_mode(aux[kernel.A_FD], aux[kernel.A_FS])
                if sel.any() and t[sel][-1] == t_stop:
                    out[np.flatnonzero(sel)[-1], X_V] = 0.0
            t_now = t_stop
    names = ("y", "v", "p_N", "p_P", "T_N", "T_P", "m_supply", "m_exhaust")
    result = {name: out[:, i] for i, name in enumerate(names)}
    result["z_f"] = out[:, X_Z]
    return result


__all__ = ["pure_python", "solve_reference"]
