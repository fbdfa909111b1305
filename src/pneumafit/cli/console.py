"""What every command of the command line shares: exit statuses, bad options.

Each command (``fit``, ``compare``, ``discover``, ``fit-many``, ...) checks
all of its options first and reports every problem at once, one line each
(the option, what was expected, what was found), then exits with
:data:`EXIT_BAD_INPUT` before any work is done.

Output paths (``--out``) are checked the same way by every command that
writes (:func:`output_problem`): a folder where a file is expected or the
reverse, a path under a file, or a folder that cannot be written is bad input
(exit status 2, "cannot write PATH: ..." with what to do). Missing parent
folders are not a problem: they are created, for file and folder outputs
alike (as ``mkdir -p``).
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, TypeVar

from rich.console import Console
from rich.text import Text

from pneumafit.fileio import check_output, output_problem

if TYPE_CHECKING:
    from pneumafit.campaign.model import Campaign

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_UNTRUSTWORTHY",
    "LOGGER",
    "LogConsole",
    "ShownWarnings",
    "check_output",
    "configure_output",
    "console_log",
    "folder_problem",
    "int_problem",
    "make_console",
    "output_problem",
    "read_campaign_or_report",
    "release_output",
    "report_problems",
    "run_guarded",
]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
#: The result is not trustworthy (a fit that does not reach the noise, an
#: estimate at a bound, short chains) and ``--strict`` was given.
EXIT_UNTRUSTWORTHY = 3
EXIT_INTERRUPTED = 130


def folder_problem(path: str | os.PathLike[str], option: str = "--out") -> str | None:
    """The problem of an output folder option, or None: :func:`output_problem`
    with ``kind="folder"``."""
    return output_problem(path, "folder", option)


def int_problem(option: str, value: Any, minimum: int) -> str | None:
    """The problem of an integer option below ``minimum`` (or not an integer), or None.

    None (an option left at its default) is not a problem.
    """
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        return f"option {option}: expected an integer >= {minimum}, found {value!r}"
    return None


def report_problems(console: Console, problems: Iterable[str | None]) -> bool:
    """Print each problem (None entries skipped) in bold red; True if there was one."""
    found = [p for p in problems if p]
    for p in found:
        console.print(Text(p, style="bold red"))
    return bool(found)


def read_campaign_or_report(campaign: str | os.PathLike[str], console: Console) -> Campaign | None:
    """The campaign of a command's ``CAMPAIGN`` argument, or None once the console says why not.

    Parameters
    ----------
    campaign : path
        Campaign folder, or its campaign.toml.
    console : rich.console.Console
        Where a campaign that cannot be read is reported (one message, bold red).

    Returns
    -------
    Campaign or None
        None: the campaign is bad input (the command returns :data:`EXIT_BAD_INPUT`).
    """
    from pneumafit.campaign import read_campaign
    from pneumafit.campaign.errors import PneumafitInputError

    try:
        return read_campaign(campaign)
    except PneumafitInputError as exc:
        console.print(Text(str(exc), style="bold red"))
        return None


# --------------------------------------------------------------- logs, --quiet, --verbose
#: Width of the console when its output is not a terminal (a log file, a pipe,
#: CI): wide enough that no table is cut (no ellipses) or has its cells wrapped;
#: a table takes its natural width, a message stays on its own line.
LOG_WIDTH = 100_000
#: Width of the horizontal rules (``console.rule``) in a log.
LOG_RULE_WIDTH = 100
#: The logger of every pneumafit module (``logging.getLogger(__name__)``).
LOGGER = "pneumafit"


class LogConsole(Console):
    """A rich console for output that is not a terminal: tables in full.

    Tables and messages are never cut at a width (:data:`LOG_WIDTH`); rules,
    which fill the width, are drawn :data:`LOG_RULE_WIDTH` characters wide.
    """

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("width", LOG_WIDTH)
        kwargs.setdefault("soft_wrap", True)
        super().__init__(**kwargs)

    def rule(self, title: Any = "", *, characters: str = "─", style: Any = "rule.line",
             align: Any = "center") -> None:  # fmt: skip
        from rich.rule import Rule

        rule = Rule(title, characters=characters, style=style, align=align)
        self.print(rule, width=min(self.width, LOG_RULE_WIDTH))


_T = TypeVar("_T")


def console_log(console: Console) -> Callable[[str], None]:
    """A service's ``log``: each line printed as plain text (no rich markup)."""

    def say(line: str) -> None:
        console.print(Text(line))

    return say


class ShownWarnings:
    """Warning lines a command has already printed, so that a repeat is
    counted instead of printed again.

    ``pneumafit run`` fits three models to one campaign, and every fit
    judges the campaign again (commands no flow test measured, valve edges
    between flow levels): without this the same lines filled its console six
    times. Each fit's fit.json keeps all of its own warnings.
    """

    def __init__(self) -> None:
        self.seen: set[str] = set()
        self.held = 0

    def new(self, line: str) -> bool:
        """True (and remembered) for a line not shown before; a repeat is counted."""
        if line in self.seen:
            self.held += 1
            return False
        self.seen.add(line)
        return True

    def flush(self, say: Callable[[str], None]) -> None:
        """One line for the repeats counted since the last flush, if any."""
        if self.held:
            n, self.held = self.held, 0
            say(f"({n} warning{'s' if n > 1 else ''} as printed above, not repeated)")

    def log(self, say: Callable[[str], None]) -> Callable[[str], None]:
        """``say`` with its repeated ``warning:`` lines counted instead."""

        def out(line: str) -> None:
            if line.startswith("warning: ") and not self.new(line):
                return
            self.flush(say)
            say(line)

        return out


def run_guarded(
    console: Console, work: Callable[[], _T], *, campaign: object, failed: str,
    interrupted: str | Callable[[], str],
) -> tuple[_T | None, int | None]:  # fmt: skip
    """Run a command's long service and turn its ends into exit statuses.

    Returns ``(result, None)``, or ``(None, status)`` after one console line:
    Ctrl-C (``interrupted``, or what it returns when called then: what was
    kept, :data:`EXIT_INTERRUPTED`), bad input found while
    working (``"CAMPAIGN: message"``, :data:`EXIT_BAD_INPUT`) or a failure of
    the work (``"FAILED: message"``, :data:`EXIT_FAILED`). Anything else is a
    bug and propagates.
    """
    from pneumafit.campaign.errors import PneumafitInputError

    try:
        return work(), None
    except KeyboardInterrupt:
        said = interrupted if isinstance(interrupted, str) else interrupted()
        console.print(Text(said, "yellow"))
        return None, EXIT_INTERRUPTED
    except PneumafitInputError as exc:
        console.print(Text(f"{campaign}: {exc}", style="bold red"))
        return None, EXIT_BAD_INPUT
    except RuntimeError as exc:
        console.print(Text(f"{failed}: {exc}", style="bold red"))
        return None, EXIT_FAILED


def make_console(*, stderr: bool = False) -> Console:
    """The command line's console: rich's own on a terminal, else a :class:`LogConsole`."""
    stream = sys.stderr if stderr else sys.stdout
    return Console(stderr=stderr) if stream.isatty() else LogConsole(stderr=stderr)


class _StderrHandler(logging.Handler):
    """Log records to the current ``sys.stderr`` (looked up at each record, so
    that a test runner's capture is honoured)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(self.format(record) + "\n")
        except Exception:  # logging must never raise
            self.handleError(record)


def configure_output(console: Console, *, quiet: bool, verbose: bool) -> None:
    """Apply ``--quiet`` / ``--verbose`` to ``console`` and the ``pneumafit`` logger.

    Default: the console's output as usual, log records of level INFO and above
    on standard error. ``--verbose``: DEBUG records too (each command's
    options, its exit status and time). ``--quiet``: the console's output is
    held back (``console.begin_capture``) and shown on standard error only if
    the command fails (:func:`release_output`), log records of level WARNING
    and above only, and the console is not a terminal (no progress bars).
    Error messages of the command line itself always show.

    Raises
    ------
    PneumafitInputError
        Both ``--quiet`` and ``--verbose`` were given.
    """
    from pneumafit.campaign.errors import PneumafitInputError

    if quiet and verbose:
        raise PneumafitInputError("options --quiet and --verbose: expected one at most, found both")
    logger = logging.getLogger(LOGGER)
    logger.setLevel(logging.DEBUG if verbose else logging.WARNING if quiet else logging.INFO)
    if not any(isinstance(h, _StderrHandler) for h in logger.handlers):
        handler = _StderrHandler()
        handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        logger.addHandler(handler)
    if quiet:
        console.begin_capture()
        console._pneumafit_quiet = True  # type: ignore[attr-defined]
        # not a terminal while quiet, so that no progress bar is drawn (the fit
        # asks console.is_terminal); rich has no public setter for it
        console._pneumafit_terminal = console._force_terminal  # type: ignore[attr-defined]
        console._force_terminal = False


def release_output(console: Console, *, failed: bool) -> None:
    """End ``--quiet``'s capture: the held-back output goes to standard error
    when the command failed (so that its messages explain the exit status),
    else it is dropped."""
    if not getattr(console, "_pneumafit_quiet", False):
        return
    console._pneumafit_quiet = False  # type: ignore[attr-defined]
    console._force_terminal = console._pneumafit_terminal  # type: ignore[attr-defined]
    held = console.end_capture()
    if failed and held:
        sys.stderr.write(held)
        sys.stderr.flush()
