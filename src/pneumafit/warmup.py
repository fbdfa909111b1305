"""Compile the simulator once, ahead of its first use.

The compiled simulator (:mod:`pneumafit.models.kernel`) is compiled by numba
at its first call and kept in numba's on-disk cache (``__pycache__`` next to
the modules, or ``NUMBA_CACHE_DIR``); on a fresh clone that first call takes
about a minute on the 2-core reference machine. Running

    python -m pneumafit.warmup

right after the install (the README's main command does) compiles every
entry point the commands call, with the argument types they call it with,
so the first ``pneumafit run``, ``fit`` or ``simulate`` only loads them from
the cache (about a second). On a warm cache it only loads them, so running
it twice costs nothing. Nothing is run in the background: the warm-up is one
ordinary process that compiles one function at a time, so it never races a
simulation, a test or a worker process over the cache.

A finished warm-up leaves a mark in the kernel's cache folder
(:func:`marker`: one file per package source stamp, numba version, Python
version and CPU, the things numba's cache is valid for). The commands that
simulate (``pneumafit run``, ``fit``, ``compare``, ``discover``,
``simulate``, ...) call :func:`ensure_warm` just before their first
simulation (:mod:`pneumafit.first_use`; their input read and checked by
then): without the mark they run the warm-up in their own process, with its
lines on the console, so that a user who skipped this command sees what the
first minute is spent on instead of a silent first simulation; with it they
do nothing.
``PNEUMAFIT_AUTO_WARMUP=0`` turns that off (the test suite does: its
commands must print only their own output).

Entry points: the serial and parallel batch integrators
(:meth:`Simulator.simulate`, :meth:`Simulator.simulate_batch`, with and
without pairs shared with the first set), the sampled
closed loop (:func:`simulate_sampled`), the stiffness bound
(:func:`choose_step` and the fits' step choice), the static valve flows
(linear analysis), the parameter check, and the small kernels of the fits,
the linear analysis and discovery. Each is called once on a short test; the
models differ only in configuration values, not in compiled code.
"""

from __future__ import annotations

import hashlib
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np


def warm_up(log: Callable[[str], None] | None = None) -> dict[str, float]:
    """Compile (or load from the cache) every simulator entry point.

    Parameters
    ----------
    log : callable, optional
        Called with one line per entry point (name and seconds).

    Returns
    -------
    dict of str to float
        Wall time (s) of each entry point's first call in this process.
    """
    from pneumafit.models import kernel
    from pneumafit.models.layout import P
    from pneumafit.models.parameters import parameter_vector
    from pneumafit.simulation.experiment import PD, Experiment
    from pneumafit.simulation.sampled import simulate_sampled
    from pneumafit.simulation.simulator import Simulator, choose_step

    params = parameter_vector({})
    t = np.arange(0.0, 0.0505, 1e-3)
    step = Experiment(
        time=t, kind="step", y_ref=np.where(t < 0.01, 0.25, 0.26), controller=PD(kp=60.0, kd=4.0),
        initial={"y": 0.25, "p_P": 4.0e5, "p_N": 4.0e5 * 0.8 / 0.6}, name="warm-up",
    )  # fmt: skip
    sim = Simulator("convection")
    seconds: dict[str, float] = {}

    def timed(name: str, call: Callable[[], object]) -> None:
        t0 = time.perf_counter()
        call()
        seconds[name] = time.perf_counter() - t0
        if log is not None:
            log(f"{name:<28s} {seconds[name]:7.1f} s")

    timed("check_parameters", lambda: kernel.check_parameters(params))
    stroke, wall = params[P["stroke"]], params[P["wall_temperature"]]
    # choose_step's call, and the fits' own (default valve and friction laws)
    # (every argument passed: an omitted one compiles another version)
    timed(
        "stiffness_bound",
        lambda: (
            choose_step(params),
            kernel.stiffness_bound(
                params, 0.0, stroke, kernel.VALVE_ISO6358, kernel.FRICTION_SWITCH
            ),
        ),
    )
    timed("static_valve_flows", lambda: kernel.static_valve_flows(params, 0, 1.0, 4e5, wall))
    timed("simulate (serial)", lambda: sim.simulate(params, step))
    timed("simulate_batch (parallel)", lambda: sim.simulate_batch(np.tile(params, (2, 1)), [step]))
    # the finite-difference Jacobians' batches (pairs shared with the first set)
    same = np.array([[False], [True], [False]])
    timed("simulate_batch (shared)", lambda: sim.simulate_batch(np.tile(params, (3, 1)), [step],
                                                                same_as_first=same))  # fmt: skip
    timed("simulate_sampled", lambda: simulate_sampled(params, t, step.y_ref,
                                                       lambda x, r: 60.0 * (r - x[0])))  # fmt: skip
    timed("small kernels", lambda: _small_kernels(params))
    _mark(seconds)
    return seconds


#: Environment variable: "0" turns off the commands' warm-up at first use
#: (:func:`ensure_warm`).
AUTO_ENV = "PNEUMAFIT_AUTO_WARMUP"


def marker() -> Path | None:
    """The file a finished warm-up leaves in the kernel's cache folder.

    Its name holds a hash of what numba's cache is valid for: the package's
    compiled sources (:func:`pneumafit.numba_stamp.package_stamp`), numba's
    version, Python's and the CPU's name; after a ``git pull`` that changes
    the kernel, or in another environment, the mark is another file. None
    where numba does not say where it keeps the cache (its private
    ``FunctionCache._cache_path``): then nothing is marked or checked.
    """
    import llvmlite.binding as llvm
    import numba

    from pneumafit.models import kernel
    from pneumafit.numba_stamp import package_stamp

    folder = getattr(getattr(kernel.integrate, "_cache", None), "_cache_path", None)
    if not folder:
        return None
    key = hashlib.sha256(
        package_stamp()
        + f"|{numba.__version__}|{platform.python_version()}|{llvm.get_host_cpu_name()}".encode()
    ).hexdigest()[:16]
    return Path(folder) / f"pneumafit-warm-{key}.txt"


def _mark(seconds: dict[str, float]) -> None:
    """Leave the mark (written to a temporary file, then renamed); a cache
    folder that cannot be written is not an error: the warm-up then runs
    again at the next command's first use, and loads from the cache."""
    path = marker()
    if path is None:
        return
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text("".join(f"{name}\t{s:.2f}\n" for name, s in seconds.items()))
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)


def ensure_warm(log: Callable[[str], None]) -> float | None:
    """Run the warm-up here if no finished warm-up has marked the cache.

    Parameters
    ----------
    log : callable
        Called with the lines to show (what is compiled, and why now).

    Returns
    -------
    float or None
        Wall time of the warm-up (s), None when it was not needed (marked,
        no mark known, or ``PNEUMAFIT_AUTO_WARMUP=0``).
    """
    if os.environ.get(AUTO_ENV, "1") == "0":
        return None
    path = marker()
    if path is None or path.exists():
        return None
    log(
        "first use of this install: compiling the simulator into numba's cache, once "
        "(about a minute on 2 cores; python -m pneumafit.warmup does it ahead)"
    )
    t0 = time.perf_counter()
    warm_up(log=lambda line: log("  " + line))
    seconds = time.perf_counter() - t0
    log(f"simulator ready ({seconds:.1f} s)")
    return seconds


def _small_kernels(params: np.ndarray) -> None:
    """The other compiled functions a run calls: the sensor lag of the fits
    (its time array writable or read-only, both occur), the heat-exchange
    areas of the linear analysis and discovery's rates along a trajectory."""
    from pneumafit.discovery import attribution
    from pneumafit.identification.problem import first_order_lag
    from pneumafit.models import kernel
    from pneumafit.models.layout import NX, P
    from pneumafit.models.structure import get_structure
    from pneumafit.physics.geometry import exchange_areas

    t = np.linspace(0.0, 0.01, 11)
    first_order_lag(np.ones((2, t.size)), t, 0.1)
    t.flags.writeable = False
    first_order_lag(np.ones((2, t.size)), t, 0.1)
    names = ("stroke", "stroke", "bore", "rod", "dead_volume_P", "dead_volume_N", "heat_area_ends")
    exchange_areas(*(float(params[P[name]]) for name in names))
    rates_along = getattr(attribution, "_rates_along", None)
    if rates_along is not None:
        d = np.empty(kernel.ND)
        kernel.derive(params, d)
        xs = np.zeros((2, NX))
        kernel._initial_state(np.full(NX, np.nan), params, get_structure("convection").config(),
                              xs[0])  # fmt: skip
        xs[1] = xs[0]
        cfg = get_structure("convection").config()
        rates_along(xs, np.zeros(2, dtype=np.int64), np.zeros((2, 2)), params, d, cfg)


def main() -> int:
    """``python -m pneumafit.warmup``: compile, print the times."""
    print("pneumafit: compiling the simulator into numba's cache (once per install) ...",
          flush=True)  # fmt: skip
    t0 = time.perf_counter()
    warm_up(log=lambda line: print("  " + line, flush=True))
    print(f"pneumafit: simulator ready ({time.perf_counter() - t0:.1f} s)")
    return 0


__all__ = ["AUTO_ENV", "ensure_warm", "marker", "warm_up"]

if __name__ == "__main__":
    sys.exit(main())
