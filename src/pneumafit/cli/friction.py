"""Body of ``pneumafit fit CAMPAIGN --model friction``: the friction law on friction tests.

Same contract as the other models' ``fit`` (:mod:`pneumafit.cli.fit`):
``OUT/fit.json`` (format ``pneumafit-fit``, written by the same writer) and,
with MCMC, ``OUT/chains.h5``; exit 0 done, 1 failed, 2 bad input (one
message, no traceback), 3 untrustworthy under ``--strict``, 130 interrupted.

Options shared with the other models keep their meaning where they have one
here: ``--friction auto|switch|lugre`` picks the law (``switch``: the static
Stribeck law without pre-sliding; ``auto``: by BIC among Coulomb-viscous,
Stribeck and LuGre); ``--seal-friction off|auto|on`` the optional terms
(pressure-dependent friction, direction asymmetry, effective area): none,
BIC-selected, or all. ``--valve`` has no meaning for a friction test.
"""

from __future__ import annotations

import os
from pathlib import Path

from rich.console import Console
from rich.text import Text

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    EXIT_UNTRUSTWORTHY,
    folder_problem,
    int_problem,
    report_problems,
    run_guarded,
)
from pneumafit.frictiontest.fit import identify_friction
from pneumafit.identification.fitfile import CHAINS_FILE, FIT_FILE

__all__ = ["friction_fit_command"]

PARTIAL_FILE = "chains.partial.h5"
#: --friction value -> law of the friction-test fit
_LAW = {"auto": "auto", "switch": "stribeck", "lugre": "lugre"}
#: --seal-friction value -> effects of the friction-test fit
_EFFECTS = {"off": "off", "auto": "auto", "on": "on"}


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
    seal: str = "off",
) -> int:
    """Fit the friction law to a campaign's friction tests; see the module docstring."""
    from pneumafit.campaign import read_campaign

    problems = [
        int_problem("--walkers", walkers, 16),
        int_problem("--steps", steps, 1),
        int_problem("--seed", seed, 0),
        folder_problem(out),
    ]
    if friction not in _LAW:
        problems.append(
            f"option --friction: expected one of auto, switch, lugre, found {friction!r}"
        )
    if seal not in _EFFECTS:
        problems.append(f"option --seal-friction: expected one of auto, on, off, found {seal!r}")
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    try:
        camp = read_campaign(campaign)
    except PneumafitInputError as exc:
        console.print(Text(str(exc), style="bold red"))
        return EXIT_BAD_INPUT
    out = Path(out)
    command = (
        f"pneumafit fit {os.fspath(campaign)} --model friction --out {os.fspath(out)}"
        + (f" --walkers {walkers}" if walkers is not None else "")
        + (f" --steps {steps}" if steps is not None else "")
        + f" --seed {seed}"
        + ("" if mcmc else " --no-mcmc")
        + (" --strict" if strict else "")
        + (f" --friction {friction}" if friction != "auto" else "")
        + (f" --seal-friction {seal}" if seal != "off" else "")
    )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        console.print(Text(f"option --out {os.fspath(out)!r}: cannot be created: {exc}", "red"))
        return EXIT_BAD_INPUT
    partial = out / PARTIAL_FILE
    partial.unlink(missing_ok=True)  # the friction chain is short: always afresh
    n_fit = len([r for r in camp.by_kind("friction") if r.role == "fit"])
    console.print(f"fitting friction to {camp.name} ({n_fit} fit friction tests)")
    result, status = run_guarded(
        console,
        lambda: identify_friction(
            camp, law=_LAW[friction], effects=_EFFECTS[seal], mcmc=mcmc, walkers=walkers,
            steps=steps, seed=seed, chains=partial if mcmc else None,
            log=lambda line: console.print(Text(line)),
        ),
        campaign=campaign, failed="fit failed", interrupted="interrupted",
    )  # fmt: skip
    if status is not None:
        return status
    # fit.json through the common writer: the effect parameters are model
    # parameters here (not nuisance), the options the law and effects fitted
    try:
        if mcmc:
            os.replace(partial, out / CHAINS_FILE)
        else:
            (out / CHAINS_FILE).unlink(missing_ok=True)
        result.save(out / FIT_FILE, command=command, chains=CHAINS_FILE if mcmc else None)
    except OSError as exc:
        console.print(Text(f"{os.fspath(out)}: cannot write the results: {exc}", "bold red"))
        return EXIT_FAILED
    from pneumafit.cli.fit import _summary, write_inference_data

    netcdf = write_inference_data(result, out) if mcmc else []
    _summary(result, console)
    m = result.metrics
    console.print(
        f"law {m['law']}; effects kept: {', '.join(m['effects']['kept']) or 'none'}; "
        "force RMSE by recording: "
        + ", ".join(f"{f} {v:.3g} N" for f, v in m["rmse_by_recording"].items())
    )
    arviz = f" ({', '.join(p.name for p in netcdf)}: ArviZ)" if netcdf else ""
    console.print(f"wrote {out / FIT_FILE}" + (f" and {out / CHAINS_FILE}" if mcmc else "") + arviz)
    quality = result.quality
    if quality is not None and not quality.trustworthy:
        console.print(Text(f"NOT TRUSTWORTHY: {quality.verdict()}", style="bold red"))
        if strict:
            return EXIT_UNTRUSTWORTHY
    return EXIT_OK
