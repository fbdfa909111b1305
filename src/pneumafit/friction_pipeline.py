"""``pneumafit run`` on a campaign of friction tests: check, fit, discover, report.

Stages, each writing into ``OUT`` and reused on a re-run as the main job's
(:class:`pneumafit.pipeline.StageBook`, ``OUT/stages.json``):

1. ``check``: the campaign is validated; nothing runs on an invalid one.
2. ``fits/friction``: the friction law without effects
   (``pneumafit fit --model friction``; with MCMC unless ``--no-mcmc``: the
   base law's two to six parameters mix, the refits with effects get Laplace
   intervals only, see ``docs/measured-data.md``).
3. ``discovery``: ``pneumafit discover`` on the base fit: the force
   residual, the effects' signatures, refits, the before/after table.
4. ``report.html``: :func:`pneumafit.outputs.friction_report.write_friction_report`.
"""

from __future__ import annotations

import time
from pathlib import Path

from rich.console import Console
from rich.text import Text

from pneumafit.campaign import Campaign, check_campaign, read_campaign
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_UNTRUSTWORTHY,
    console_log,
    folder_problem,
    int_problem,
    report_problems,
)

__all__ = ["is_friction_campaign", "run_friction"]


def is_friction_campaign(path: Path) -> bool:
    """True when the campaign at ``path`` can be read and holds only friction tests."""
    try:
        campaign = read_campaign(path)
    except Exception:  # an unreadable campaign is the main job's check to report
        return False
    kinds = {r.kind for r in campaign.recordings}
    return kinds == {"friction"}


def run_friction(
    path: Path,
    out: Path,
    console: Console,
    *,
    seed: int = 0,
    mcmc: bool = True,
    walkers: int | None = None,
    steps: int | None = None,
    strict: bool = False,
) -> int:
    """The friction-test job; same exit statuses as :func:`pneumafit.pipeline.run`."""
    from pneumafit.cli.friction import MIN_FRICTION_WALKERS, report_friction_fit
    from pneumafit.outputs.friction_report import write_friction_report
    from pneumafit.pipeline import StageBook, StageFailed, fit_is_reusable, run_service
    from pneumafit.services.fit import fit_command_line
    from pneumafit.services.friction import friction_fit_folder

    started = time.perf_counter()
    console.rule(f"[bold]pneumafit run[/bold] (friction tests): {path}")
    if check_campaign(path, console=console) != 0:
        console.print("[red]the campaign is not valid; nothing was run[/red]")
        return EXIT_BAD_INPUT
    campaign: Campaign = read_campaign(path)
    out = Path(out)
    problems = [
        folder_problem(out),
        int_problem("--walkers", walkers, MIN_FRICTION_WALKERS),
        int_problem("--steps", steps, 1),
        int_problem("--seed", seed, 0),
    ]
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    out.mkdir(parents=True, exist_ok=True)
    book = StageBook(out)
    fit_dir = out / "fits" / "friction"
    fit_file = fit_dir / "fit.json"
    timings: dict[str, float] = {}
    try:
        if fit_is_reusable(fit_dir, campaign, "friction"):
            console.print(f"[dim]fit friction: reused {fit_file}[/dim]")
        else:
            console.rule("fit friction")
            t0 = time.perf_counter()
            n_fit = len([r for r in campaign.by_kind("friction") if r.role == "fit"])
            console.print(f"fitting friction to {campaign.name} ({n_fit} fit friction tests)")
            command = fit_command_line(path, "friction", fit_dir, walkers, steps, seed, mcmc)
            result = run_service(
                console, "fit friction",
                lambda: friction_fit_folder(
                    campaign, fit_dir, mcmc=mcmc, walkers=walkers, steps=steps, seed=seed,
                    command=command, log=console_log(console),
                ),
                campaign=path, failed="fit failed",
            )  # fmt: skip
            report_friction_fit(result, fit_dir, console)
            timings["fit friction"] = time.perf_counter() - t0
            book.mark("fit friction", book.fingerprint(campaign, [fit_file]),
                      timings["fit friction"])  # fmt: skip
        for name, inputs, outputs, body in (
            ("discovery", [fit_file], [out / "discovery" / "discovery.json"],
             lambda: _friction_discovery(path, campaign, fit_file, out / "discovery", seed,
                                         console)),
        ):  # fmt: skip
            fp = book.fingerprint(campaign, inputs)
            if book.is_done(name, fp, outputs):
                console.print(f"[dim]{name}: reused (inputs unchanged)[/dim]")
                continue
            console.rule(name)
            t0 = time.perf_counter()
            body()
            timings[name] = time.perf_counter() - t0
            book.mark(name, fp, timings[name])
        console.rule("report")
        report = write_friction_report(out, campaign, out / "report.html")
    except StageFailed as exc:
        console.print(f"[red]{exc}; the finished stages are kept and reused next time[/red]")
        return 1 if exc.status not in (2, 130) else exc.status
    except KeyboardInterrupt:
        console.print("[yellow]interrupted: the finished stages are kept and reused next "
                      "time[/yellow]")  # fmt: skip
        return 130
    from pneumafit.identification.staged import FitResult

    quality = FitResult.load(fit_file).quality or {}
    ok = bool(quality.get("trustworthy", False))
    console.rule("done")
    console.print(Text(f"fit friction: {quality.get('verdict', '-')}",
                       style="green" if ok else "red"))  # fmt: skip
    from pneumafit.pipeline import print_conclusions

    print_conclusions(out, console)
    console.print(f"report: {report}")
    total = time.perf_counter() - started
    console.print(f"total time {total:.0f} s ({total / 60:.1f} min)")
    return EXIT_UNTRUSTWORTHY if strict and not ok else 0


def _friction_discovery(
    path: Path, campaign: Campaign, fit_file: Path, folder: Path, seed: int, console: Console
) -> None:
    """The discovery stage of the friction-test job: the service, then its summary."""
    from pneumafit.cli.friction_discover import report_friction_discovery
    from pneumafit.pipeline import run_service
    from pneumafit.services.friction import friction_discover_folder

    command = (f"pneumafit discover {path} --fit {fit_file} --out {folder} --seed {seed} "
               "--rounds 3 --per-round 3")  # fmt: skip
    done = run_service(
        console, "discovery",
        lambda: friction_discover_folder(campaign, fit_file, folder, seed=seed, rounds=3,
                                         per_round=3, command=command, log=console_log(console)),
        campaign=path, failed="discovery failed", interrupted="interrupted: nothing written",
    )  # fmt: skip
    report_friction_discovery(done.document, console)
    console.print("wrote " + ", ".join(str(p) for p in done.files))
