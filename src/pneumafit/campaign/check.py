"""The ``pneumafit check CAMPAIGN`` report: recordings table, then problems."""

from __future__ import annotations

import math
import os
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

from pneumafit.campaign.errors import Problem
from pneumafit.campaign.reader import CampaignReport, inspect_campaign, summarize

__all__ = ["check_campaign"]


def _number(value: float, digits: int) -> str:
    return "-" if not math.isfinite(value) else f"{value:.{digits}g}"


#: Narrower consoles get the channels and setup listed under the table.
WIDE_CONSOLE = 120


def _render(report: CampaignReport, console: Console) -> None:
    title = f"Campaign {report.campaign.name}" if report.campaign else f"Campaign {report.path}"
    wide = console.width >= WIDE_CONSOLE
    table = Table(title=Text(title), show_lines=False)
    table.add_column("File", overflow="fold")
    table.add_column("Kind", no_wrap=True)
    table.add_column("Role", no_wrap=True)
    table.add_column("Duration [s]", justify="right", no_wrap=True)
    table.add_column("Rate [Hz]", justify="right", no_wrap=True)
    table.add_column("Samples", justify="right", no_wrap=True)
    if wide:
        table.add_column("Channels [file unit]", ratio=2)
        table.add_column("Setup", ratio=1)
    details: list[Text] = []
    for row in summarize(report.recordings):
        channels = ", ".join(f"{name} [{unit}]" for name, unit in row["channels"].items())
        cells = [
            row["file"],
            row["kind"],
            row["role"],
            _number(row["duration_s"], 6),
            _number(row["sample_rate_Hz"], 6),
            row["n_samples"],
        ]
        if wide:
            cells += [channels, row["setup"]]
        else:
            line = Text(f"{row['file']}: ", style="bold")
            line.append(f"{channels}; {row['setup']}")
            details.append(line)
        table.add_row(*(Text(str(cell)) for cell in cells))
    console.print(table)
    for line in details:
        console.print(line)
    for problem in report.problems:
        style = "bold red" if problem.is_error else "yellow"
        line = Text(f"{problem.severity}: ", style=style)
        line.append(str(problem))
        console.print(line)
    n_errors, n_warnings = len(report.errors), len(report.warnings)
    counts = (
        f"{n_errors} error{'s' * (n_errors != 1)}, {n_warnings} warning{'s' * (n_warnings != 1)}"
    )
    if n_errors:
        console.print(Text(f"invalid campaign: {counts}", style="bold red"))
    else:
        console.print(Text(f"valid campaign: {counts}", style="bold green"))


def check_campaign(path: str | os.PathLike[str], console: Console | None = None) -> int:
    """Print a campaign's recordings and problems; return the exit status.

    Never raises on bad input: anything unexpected is reported as a problem.

    Parameters
    ----------
    path : str or os.PathLike
        Campaign folder, or its campaign.toml.
    console : rich.console.Console, optional
        Where to print; default a new console on standard output.

    Returns
    -------
    int
        0 for a valid campaign (warnings allowed), 1 for an invalid one.
    """
    console = console if console is not None else Console()
    try:
        report = inspect_campaign(path)
    except Exception as exc:  # the boundary: a check never crashes
        report = CampaignReport(path=Path(str(path)))
        report.problems.append(
            Problem(str(path), "", "a readable campaign", f"{type(exc).__name__}: {exc}")
        )
    try:
        _render(report, console)
    except Exception as exc:  # rendering must not hide the verdict
        console.print(Text(f"could not render the report ({type(exc).__name__}: {exc})"))
        for problem in report.problems:
            console.print(Text(f"{problem.severity}: {problem}"))
    return 0 if report.ok else 1
