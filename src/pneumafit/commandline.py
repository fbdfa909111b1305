"""What every command of the command line shares: exit statuses, bad options.

Each command (``fit``, ``compare``, ``discover``, ``fit-many``, ...) checks
all of its options first and reports every problem at once, one line each
(the option, what was expected, what was found), then exits with
:data:`EXIT_BAD_INPUT` before any work is done.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.text import Text

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_UNTRUSTWORTHY",
    "folder_problem",
    "int_problem",
    "report_problems",
]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
#: The result is not trustworthy (a fit that does not reach the noise, an
#: estimate at a bound, short chains) and ``--strict`` was given.
EXIT_UNTRUSTWORTHY = 3
EXIT_INTERRUPTED = 130


def folder_problem(path: str | os.PathLike[str], option: str = "--out") -> str | None:
    """The problem of an output folder option naming an existing file, or None."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        return f"option {option} {os.fspath(path)!r}: expected a folder, found a file"
    return None


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
