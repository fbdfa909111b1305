"""Progress of long loops: rate-limited lines in a log, a live line on a terminal.

Every loop that can run for more than a few seconds (the least-squares
solves of each stage, the MCMC chains, discovery's refits) reports through
one :class:`Progress`, made by the command's :class:`Reporter`:

- in a log (standard output not a terminal: a file, a pipe, CI), a line
  ``<label>: <status>, <elapsed> s`` at most every :data:`LOG_INTERVAL`
  seconds, at the first update after that interval (so a loop whose updates
  come every few seconds is never silent for much longer than the interval);
- on a terminal, one live line ``<label> (<elapsed> s): <status>`` (rich's
  status spinner) updated at most every :data:`LIVE_INTERVAL` seconds and
  removed when the loop ends.

The status is a string or a callable returning one; a callable is called only
when a line is due, so an expensive status (an autocorrelation time) costs
nothing between lines. Reporting never changes what the loop computes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

__all__ = ["LIVE_INTERVAL", "LOG_INTERVAL", "Progress", "Reporter"]

#: Seconds between two progress lines of one loop in a log.
LOG_INTERVAL = 5.0
#: Seconds between two refreshes of the live line on a terminal.
LIVE_INTERVAL = 0.25

Status = str | Callable[[], str]


def _silent(_line: str) -> None:
    return None


class Progress:
    """The progress of one long loop (see the module docstring).

    Parameters
    ----------
    label : str
        Starts every line (e.g. ``joint`` or ``mcmc friction``).
    say : callable, optional
        Receives each line (log mode).
    interval : float
        Least number of seconds between two lines (or live refreshes).
    clock : callable
        Seconds, monotonic (a fake clock in tests).
    live : optional
        A rich ``Status`` to update instead of printing lines (terminal mode).

    Attributes
    ----------
    updates : int
        Calls of :meth:`update` so far.
    lines : int
        Lines said (or live refreshes) so far.
    """

    def __init__(
        self,
        label: str,
        say: Callable[[str], None] | None = None,
        *,
        interval: float = LOG_INTERVAL,
        clock: Callable[[], float] = time.monotonic,
        live: Any = None,
    ) -> None:
        self.label = label
        self.say = say or _silent
        self.interval = float(interval)
        self.clock = clock
        self.live = live
        self.started = self.last = clock()
        self.updates = 0
        self.lines = 0

    @property
    def elapsed(self) -> float:
        """Seconds since the loop started."""
        return self.clock() - self.started

    def line(self, status: Status) -> str:
        """The line for ``status`` now: ``label: status, elapsed s``."""
        text = status() if callable(status) else status
        return f"{self.label}: {text}, {self.elapsed:.0f} s"

    def due(self) -> bool:
        """True when a line would be said by the next :meth:`update`."""
        return self.clock() - self.last >= self.interval

    def update(self, status: Status) -> None:
        """Say ``status`` if :attr:`interval` seconds passed since the last line."""
        self.updates += 1
        now = self.clock()
        if now - self.last < self.interval:
            return
        self.last = now
        self.lines += 1
        if self.live is not None:
            # the elapsed time first: a narrow terminal cuts the line's end
            text = status() if callable(status) else status
            self.live.update(f"{self.label} ({self.elapsed:.0f} s): {text}")
        else:
            self.say(self.line(status))

    def close(self) -> None:
        """End the loop: the live line is removed (a log gets nothing more)."""
        if self.live is not None:
            self.live.stop()
            self.live = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Reporter:
    """Makes the :class:`Progress` of each long loop of one command.

    Parameters
    ----------
    say : callable, optional
        Receives the lines in a log (the command's own line printer).
    console : rich.console.Console, optional
        When it is a terminal, each loop gets a live line on it instead of
        lines (``console.is_terminal``; ``--quiet`` makes it not one).
    interval : float, optional
        Seconds between two lines in a log (default :data:`LOG_INTERVAL`).
    clock : callable
        Seconds, monotonic.
    """

    def __init__(
        self,
        say: Callable[[str], None] | None = None,
        *,
        console: Any = None,
        interval: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.say = say or _silent
        self.console = console
        self.interval = LOG_INTERVAL if interval is None else float(interval)
        self.clock = clock

    @property
    def live(self) -> bool:
        """True when loops are shown as a live line (a terminal), not lines."""
        return self.console is not None and bool(self.console.is_terminal)

    def task(self, label: str) -> Progress:
        """The progress of a new loop; close it (or use ``with``) when the loop ends."""
        if self.live:
            status = self.console.status(label)
            status.start()
            return Progress(label, self.say, interval=LIVE_INTERVAL, clock=self.clock,
                            live=status)  # fmt: skip
        return Progress(label, self.say, interval=self.interval, clock=self.clock)
