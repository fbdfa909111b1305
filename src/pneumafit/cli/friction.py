"""Body of ``pneumafit fit CAMPAIGN --model friction``: the friction law on friction tests.

The work and the files are the service's
(:func:`pneumafit.services.friction.friction_fit_folder`). Same contract as
the other models' ``fit`` (:mod:`pneumafit.cli.fit`):
``OUT/fit.json`` (format ``pneumafit-fit``, written by the same writer) and,
with MCMC, ``OUT/chains.h5``; exit 0 done, 1 failed, 2 bad input (one
message, no traceback), 3 untrustworthy under ``--strict``, 130 interrupted.

Options shared with the other models keep their meaning where they have one
here: ``--friction auto|switch|lugre`` picks the law (``switch``: the static
Stribeck law without pre-sliding; ``auto``: by BIC among Coulomb-viscous,
Stribeck and LuGre); ``--seal-friction off|auto|on`` the optional terms
(pressure-dependent friction, direction asymmetry, effective area): none,
BIC-selected, or all; ``long``, the fit command's default, is ``off`` here
(a friction test has no closed-loop step tests to fit in segments).
``--valve`` has no meaning for a friction test.
"""

from __future__ import annotations

import os
from pathlib import Path

from rich.console import Console
from rich.text import Text

from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    console_log,
    folder_problem,
    int_problem,
    read_campaign_or_report,
    report_problems,
    run_guarded,
)
from pneumafit.cli.fit import _summary, fit_status
from pneumafit.identification.staged import FitResult
from pneumafit.services.fit import fit_command_line, written_line
from pneumafit.services.friction import friction_fit_folder

__all__ = ["MIN_FRICTION_WALKERS", "friction_fit_command", "report_friction_fit"]

#: The fewest walkers the friction-test fit accepts (``--walkers``).
MIN_FRICTION_WALKERS = 16
#: --friction value -> law of the friction-test fit
_LAW = {"auto": "auto", "switch": "stribeck", "lugre": "lugre"}
#: --seal-friction value -> effects of the friction-test fit
_EFFECTS = {"long": "off", "auto": "auto", "on": "on", "off": "off"}


def friction_fit_command(
    campaign: Path,
    out: Path,
    walkers: int | None,
    steps: int | None,
    seed: int,
    mcmc: bool,
    console: Console,
    strict: bool = False,
    friction: str = "auto",
    seal: str = "long",
) -> int:
    """Fit the friction law to a campaign's friction tests; see the module docstring."""
    problems = [
        int_problem("--walkers", walkers, MIN_FRICTION_WALKERS),
        int_problem("--steps", steps, 1),
        int_problem("--seed", seed, 0),
        folder_problem(out),
    ]
    if friction not in _LAW:
        problems.append(
            f"option --friction: expected one of auto, switch, lugre, found {friction!r}"
        )
    if seal not in _EFFECTS:
        problems.append(
            f"option --seal-friction: expected one of {', '.join(_EFFECTS)}, found {seal!r}"
        )
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    camp = read_campaign_or_report(campaign, console)
    if camp is None:
        return EXIT_BAD_INPUT
    out = Path(out)
    command = fit_command_line(campaign, "friction", out, walkers, steps, seed, mcmc,
                               strict=strict, friction=friction, seal=seal)  # fmt: skip
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        console.print(Text(f"option --out {os.fspath(out)!r}: cannot be created: {exc}", "red"))
        return EXIT_BAD_INPUT
    n_fit = len([r for r in camp.by_kind("friction") if r.role == "fit"])
    console.print(f"fitting friction to {camp.name} ({n_fit} fit friction tests)")
    result, status = run_guarded(
        console,
        lambda: friction_fit_folder(
            camp, out, law=_LAW[friction], effects=_EFFECTS[seal], mcmc=mcmc, walkers=walkers,
            steps=steps, seed=seed, command=command, log=console_log(console),
        ),
        campaign=campaign, failed="fit failed", interrupted="interrupted",
    )  # fmt: skip
    if status is not None or result is None:
        return status if status is not None else EXIT_FAILED
    report_friction_fit(result, out, console)
    return fit_status(result, strict)


def report_friction_fit(result: FitResult, out: Path, console: Console) -> None:
    """The console output of a friction fit written to ``out`` (also the main job's)."""
    _summary(result, console)
    m = result.metrics
    console.print(
        f"law {m['law']}; effects kept: {', '.join(m['effects']['kept']) or 'none'}; "
        "force RMSE by recording: "
        + ", ".join(f"{f} {v:.3g} N" for f, v in m["rmse_by_recording"].items())
    )
    console.print(written_line(out))
    quality = result.quality
    if quality is not None and not quality.trustworthy:
        console.print(Text(f"NOT TRUSTWORTHY: {quality.verdict()}", style="bold red"))
