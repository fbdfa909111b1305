"""Closed loop with a sampled controller outside the compiled simulator.

A digital controller reads the state at the sampling instants t_k and holds
its command until t_k+1 (zero-order hold). :func:`simulate_sampled` runs
one: at every sample it calls ``controller(state, y_ref)`` (any Python
callable: a Python law, or compiled C code through ctypes for software in
the loop), then advances the compiled simulator over one sample interval
with that command held, carrying the whole integrator state (every state
slot, the friction mode and the event-location memory) from one interval
to the next. Inside an interval the integration is the kernel's own
(:func:`pneumafit.models.kernel.integrate`: the same Runge-Kutta steps,
friction-mode events and health checks): an open-loop test whose command
is constant over each interval gives the same numbers either way (tested).

Why not inside the kernel: the kernel's closed-loop laws are evaluated at
every Runge-Kutta stage (a continuous controller, the paper's); a sampled
controller written in another language can only be called between
intervals.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from pneumafit import first_use
from pneumafit.models import kernel
from pneumafit.models.kernel import (
    commands,
    initial_mode,
    integrate_from,
    rhs,
)
from pneumafit.models.layout import (
    CHANNEL_UNITS,
    CHANNELS,
    NCTRL,
)
from pneumafit.models.parameters import parameter_vector
from pneumafit.models.part_kernel import kernel_for, rebound
from pneumafit.models.structure import ModelStructure, get_structure
from pneumafit.numba_stamp import njit
from pneumafit.simulation import counter
from pneumafit.simulation.simulator import (
    DEFAULT_METHOD,
    DEFAULT_STEP,
    STATUS_MESSAGES,
    AirConsumption,
    Simulation,
)
from pneumafit.simulation.tableau import TABLEAUS, Tableau

#: Indices of the measured state handed to the controller: [y, v, p_N, p_P, T_N, T_P].
MEASURED = slice(0, 6)

# slots of the integer and float memory carried between intervals
_MODE = 0
_FD, _FS = 0, 1


@njit(cache=True)
def _start(x0, p, d, cfg, ctrl, inp, h0, x, mem_i, mem_f, dx, aux) -> int:
    """Initial state, LuGre deflection and friction mode (``kernel.initial_mode``,
    as ``kernel.integrate`` starts).

    ``inp`` holds the first held command; returns a status code."""
    if not kernel.admissible(p, cfg):
        return kernel.STATUS_BAD_PARAMETERS
    kernel.derive(p, d)
    kernel._initial_state(x0, p, cfg, x)
    mode, fd, fs = initial_mode(x, inp, h0, p, d, cfg, ctrl, dx, aux)
    mem_i[_MODE] = mode
    mem_f[_FD] = fd
    mem_f[_FS] = fs
    return kernel.STATUS_OK


@njit(cache=True)
def _advance(x, mem_i, mem_f, inp, dt, n_sub, p, d, cfg, ctrl, tab_a, tab_b, tab_c,
             kk, xs, xn, xe, dx, aux) -> int:  # fmt: skip
    """One sample interval of ``kernel.integrate`` (``kernel.integrate_from``
    over a two-row input table holding the command, no channels recorded),
    updating x and the memory; returns a status code."""
    t2 = np.empty(2)
    t2[0] = 0.0
    t2[1] = dt
    nsub2 = np.full(2, n_sub, dtype=np.int64)
    status, mode, fd, fs = integrate_from(
        t2, inp, nsub2, x, mem_i[_MODE], mem_f[_FD], mem_f[_FS], p, d, cfg, ctrl,
        tab_a, tab_b, tab_c, np.empty(0, dtype=np.int64), np.empty((2, 0)), kernel._FALSE,
        kk, xs, xn, xe, dx, aux,
    )  # fmt: skip
    mem_i[_MODE] = mode
    mem_f[_FD] = fd
    mem_f[_FS] = fs
    return status


@njit(cache=True)
def _observe(x, mem_i, inp, p, d, cfg, ctrl, dx, aux, ch_sel, out, row) -> None:
    """Record the channels at a sample, with the command just decided."""
    u_p, u_n = commands(x, inp, kernel._I0, 0.0, cfg, ctrl)
    rhs(x, mem_i[_MODE], u_p, u_n, p, d, cfg, dx, aux)
    kernel._record(out, row, x, aux, ch_sel)


def simulate_sampled(
    parameters: Mapping[str, float] | np.ndarray,
    time: np.ndarray,
    y_ref: np.ndarray,
    controller: Callable[[np.ndarray, float], float],
    *,
    model: str | ModelStructure = "convection",
    initial: Mapping[str, float] | None = None,
    step: float = DEFAULT_STEP,
    method: str | Tableau = DEFAULT_METHOD,
    channels: Sequence[str] | None = None,
) -> Simulation:
    """Closed loop with a controller sampled at the time grid, command held.

    Parameters
    ----------
    parameters : mapping or ndarray
        Plant parameters (SI).
    time : ndarray, shape (n,)
        Sampling instants (s), strictly increasing: the controller runs at
        each and its command is held until the next.
    y_ref : ndarray, shape (n,)
        Reference position at the samples (m).
    controller : callable
        ``controller(state, y_ref) -> u_P`` (V) with ``state`` the measured
        [y, v, p_N, p_P, T_N, T_P] (SI, a fresh array); u_N = -u_P.
    model : str or ModelStructure
        The plant's structure.
    initial : mapping, optional
        Initial values by state name, as :class:`Experiment`'s ``initial``.
    step : float
        Largest integration step (s); each interval is cut into
        ceil(dt / step) equal steps (the command does not change inside).
    method : str or Tableau
        Runge-Kutta method.
    channels : sequence of str, optional
        Channels to record (default all); ``u_P`` is the command held from
        each sample.

    Returns
    -------
    Simulation
        As :meth:`Simulator.simulate`; a failure leaves NaN from the failing
        sample on and a status other than 0.
    """
    from pneumafit.simulation.experiment import Experiment

    first_use.due()
    structure = get_structure(model)
    # the cached kernel's steps, or the same steps on its copy bound to
    # outside parts (models.part_kernel)
    kern = kernel_for(structure)
    start, advance, observe = (rebound(f, kern) for f in (_start, _advance, _observe))
    t = np.asarray(time, dtype=float)
    ref = np.asarray(y_ref, dtype=float)
    exp = Experiment(time=t, kind="step", y_ref=ref, u_P=np.zeros_like(t),
                     initial=dict(initial or {}), name="sampled loop")  # fmt: skip
    names = tuple(channels) if channels is not None else CHANNELS
    ch_sel = np.array([CHANNELS.index(c) for c in names], dtype=np.int64)
    tab = TABLEAUS[method] if isinstance(method, str) else method
    p = np.asarray(parameters, dtype=float) if isinstance(parameters, np.ndarray) else (
        parameter_vector(parameters))  # fmt: skip
    cfg = structure.config(blocked=False, chamber=None, closed_loop=0, static_flow=False)
    ctrl = np.zeros(NCTRL)
    n = t.size
    nsub = np.maximum(np.ceil(np.diff(t) / step - 1e-9), 1).astype(np.int64)
    d = np.empty(kernel.ND)
    nx = kern.NX  # the copy's for outside effects' states past layout.NX
    x = np.empty(nx)
    xs, xn, xe, dx = (np.empty(nx) for _ in range(4))
    kk = np.empty((tab.b.shape[0], nx))
    aux = np.zeros(kernel.NAUX)
    mem_i = np.zeros(1, dtype=np.int64)
    mem_f = np.zeros(2)
    inp = np.zeros((2, 4))
    out = np.full((n, ch_sel.size), np.nan)
    x0 = exp.initial_state(nx)
    kern._initial_state(x0, p, cfg, x)  # the state the controller first reads
    status = kernel.STATUS_OK
    for k in range(n):
        u = float(controller(x[MEASURED].copy(), float(ref[k])))
        inp[:, 0] = u
        inp[:, 1] = -u
        if k == 0:
            status = start(x0, p, d, cfg, ctrl, inp, (t[1] - t[0]) / nsub[0], x, mem_i,
                            mem_f, dx, aux)  # fmt: skip
            if status != kernel.STATUS_OK:
                break
        observe(x, mem_i, inp, p, d, cfg, ctrl, dx, aux, ch_sel, out, k)
        if k == n - 1:
            break
        status = advance(x, mem_i, mem_f, inp, t[k + 1] - t[k], int(nsub[k]), p, d, cfg,
                          ctrl, tab.a, tab.b, tab.c, kk, xs, xn, xe, dx, aux)  # fmt: skip
        if status != kernel.STATUS_OK:
            break
    counter.add(1)
    chans = {name: out[:, j].copy() for j, name in enumerate(names)}
    units = {name: CHANNEL_UNITS[CHANNELS.index(name)] for name in names}
    air = None
    if status == kernel.STATUS_OK and "m_supply" in chans and "m_exhaust" in chans:
        air = AirConsumption.from_mass(chans["m_supply"][-1], chans["m_exhaust"][-1], p)
    return Simulation(t, chans, units, int(status), STATUS_MESSAGES[int(status)], air)


__all__ = ["MEASURED", "simulate_sampled"]
