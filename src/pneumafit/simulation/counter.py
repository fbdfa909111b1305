"""How many simulations this process has run.

A simulation is one parameter set on one experiment: :meth:`Simulator.simulate_batch`
adds ``n_sets * n_experiments`` per call (:meth:`Simulator.simulate` one),
:func:`~pneumafit.simulation.sampled.simulate_sampled` one. The main job
(:mod:`pneumafit.pipeline`) reads the count before and after each stage to
report simulations per second. Simulations run in other processes (Dask
workers, ``pneumafit fit-many``) are counted there, not here.
"""

from __future__ import annotations

import threading

_lock = threading.Lock()
_count = 0


def add(n: int) -> None:
    """Count ``n`` more simulations (thread-safe)."""
    global _count
    with _lock:
        _count += int(n)


def simulations() -> int:
    """Simulations run by this process since it started."""
    return _count


__all__ = ["add", "simulations"]
