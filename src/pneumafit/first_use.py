"""One action deferred to the first compiled simulation of a process.

The command line's warm-up at first use (:func:`pneumafit.warmup.ensure_warm`)
compiles the simulator for about a minute on a fresh install. Run at the
start of a command, it made a user wait that minute before learning that the
campaign path was mistyped or an option was refused. Instead the command
line :func:`defer`\\ s it, and the simulation layer calls :func:`due` where a
compiled simulation is about to start (a :class:`~pneumafit.simulation.
simulator.Simulator` made, the stable step chosen, a sampled closed loop, the
linear analysis's static valve flows): the input has been read and checked
by then, and a command that fails before simulating compiles nothing.

This module imports nothing of pneumafit (layer 0): the layers that simulate
only look down to it, and the command line above hands it the action.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["cancel", "defer", "due"]

_pending: list[Callable[[], object]] = []


def defer(action: Callable[[], object]) -> None:
    """Run ``action`` once, at the next :func:`due` of this process (it
    replaces an action deferred before and not yet run)."""
    _pending[:] = [action]


def cancel() -> None:
    """Drop the deferred action, if it has not run (a command that ended
    without simulating)."""
    _pending.clear()


def due() -> None:
    """Run the deferred action, if any, and forget it (before it runs: an
    action that simulates does not run itself again)."""
    if _pending:
        action = _pending.pop()
        action()
