"""The main job, ``pneumafit run``: from a campaign to a report.

Stages, in order, each writing into ``OUT``:

1. ``check``: the campaign is validated; nothing runs on an invalid one.
2. ``fits/<model>``: the staged fit with MCMC of the convection,
   constant-lambda and polytropic models (``pneumafit fit``).
3. ``comparison``: the three fitted models on every recording
   (``pneumafit compare`` with those fits), and each fit's replay of every
   recording saved for the report (``comparison/replays.npz``).
4. ``discovery``: residual analysis of the convection fit, attribution to
   catalog effects, refits (``pneumafit discover``).
5. ``linear``: equilibria, linear models, open-loop poles and both
   state-feedback gain schedules at the convection fit (``pneumafit linear``
   and ``design``).
6. ``closed_loop``: both controllers on the nonlinear model, air and exergy
   per step (``pneumafit closed-loop``); the plant is the campaign's
   ``truth.json`` where it has one that the compiled model can run (a rig
   recorded with the fitted laws), else the convection fit (also for an
   independent truth such as the bundled demo's).
7. ``export``: the controller the closed-loop stage validated (its order-6
   design repeated over a grid of positions: placement, w0 and dead-band
   compensation from ``closed_loop.json``) as JSON, YAML, a C header with
   its controller source, a MATLAB file and a CSV schedule (``pneumafit
   export``); the C code, compiled, is run in the loop on the closed-loop
   stage's plant beside the Python law (``export/sil.json``); the fitted
   plant as an FMI 2.0 FMU (``export/plant.fmu``, where a C compiler is there).
8. ``report.html``: the self-contained validation report, from the saved
   results of the stages above (it simulates nothing).

Re-running reuses what is finished. A fit is reused when its fit.json
belongs to the same campaign (file hashes) and model; an interrupted MCMC
resumes from its ``chains.partial.h5``. Every other stage is reused when
``OUT/stages.json`` records it as done with the same fingerprint (hashes of
the campaign, of the fit files it read, and the pneumafit version) and its
outputs are still there. Each stage writes its files atomically, so an
interrupted run never leaves a half-written file that a re-run would trust.

Where the time goes: ``OUT/summary.json`` gives each stage's wall time
(``seconds``), the simulations it ran in this process (``simulations``, one
parameter set on one recording, :mod:`pneumafit.simulation.counter`) and
their rate (``simulations_per_second``); the run's last console lines print
the same table. A reused stage counts 0 s and no simulations.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.text import Text

from pneumafit import __version__
from pneumafit.campaign import Campaign, check_campaign, read_campaign
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_UNTRUSTWORTHY,
    ShownWarnings,
    console_log,
    folder_problem,
    int_problem,
    report_problems,
    run_guarded,
)
from pneumafit.comparison.replays import REPLAYS_FILE
from pneumafit.comparison.result import COMPARISON_FILE
from pneumafit.errors import PneumafitComputationError
from pneumafit.fileio import write_text_atomic
from pneumafit.models.parts import MODEL_NAMES
from pneumafit.models.structure import INPUT_MODE, INPUT_MODES
from pneumafit.outputs.residual_file import RESIDUALS_FILE
from pneumafit.progress import Reporter
from pneumafit.simulation import counter

#: The bundled demo campaign: a virtual-rig recording of a rig like the paper's,
#: whose valve, leak, friction and probe laws are not the fitted models'
#: (the independent truth preset ``demo``, docs/virtual-rig.md).
DEMO = Path(__file__).resolve().parents[2] / "data" / "demo"

#: Models fitted and compared, in the order of the paper (simplest first: the
#: heat laws of ``models.parts`` in reverse model-list order).
RUN_MODELS = tuple(reversed(MODEL_NAMES))
#: Order in which the models are fitted: the full heat law first (the model
#: list's order). With ``--friction auto`` its friction law, chosen by BIC on
#: the step tests, is then the law of the others, so the three fits differ
#: in their heat law only, and the simpler ones skip the second law's fit.
FIT_ORDER = tuple(MODEL_NAMES)

#: Formats of the controller export.
EXPORT_FORMATS = {"json": "controller.json", "yaml": "controller.yaml", "c": "controller.h",
                  "mat": "controller.mat", "csv": "controller.csv"}  # fmt: skip

#: The fitted plant as an FMU (export stage; written when a C compiler is there).
PLANT_FMU = "plant.fmu"

#: The exported C controller run in the loop (export stage): figures and command difference.
SIL_FILE = "sil.json"

STAGES_FILE = "stages.json"


class StageFailed(PneumafitComputationError):
    """A stage ended with a non-zero status; the run stops there."""

    def __init__(self, stage: str, status: int) -> None:
        super().__init__(f"stage {stage!r} failed (status {status})")
        self.stage = stage
        self.status = status


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fit_is_reusable(
    folder: Path, campaign: Campaign, model: str, valve: str | None = None,
    inputs: str | None = None, *, friction: str | None = None,
) -> bool:  # fmt: skip
    """True when ``folder/fit.json`` is a finished fit of ``model`` on this
    campaign (and with the valve law ``valve``, the input reading ``inputs``
    and the friction law ``friction``, when given: a fit.json without
    ``structure.inputs`` interpolated them), made with the same parts from
    outside the package as are registered now (``provenance.parts``,
    :func:`pneumafit.models.part_kernel.parts_digest`; a fit.json without it
    had none): an edited law of one's own is fitted again."""
    from pneumafit.identification.staged import FitResult
    from pneumafit.models.part_kernel import parts_digest

    try:
        fit = FitResult.load(folder / "fit.json")
    except PneumafitInputError:  # absent, unreadable or not a fit: fit again
        return False
    return (
        fit.model == model
        and isinstance(fit.document.get("campaign"), dict)
        and fit.campaign_sha256 == campaign.sha256
        and (valve is None or fit.structure.valve == valve)
        and (inputs is None or fit.structure.inputs == inputs)
        and (friction is None or fit.structure.friction == friction)
        and (fit.document.get("provenance") or {}).get("parts", "") == parts_digest()
    )


class StageBook:
    """Which stages of a run folder are done, with the fingerprint of their inputs.

    Parameters
    ----------
    out : Path
        The run folder; the book is ``out/stages.json``.
    """

    def __init__(self, out: Path) -> None:
        self.path = out / STAGES_FILE
        try:
            self.done: dict[str, Any] = json.loads(self.path.read_text()).get("stages", {})
        except (OSError, ValueError, AttributeError):
            self.done = {}

    def fingerprint(self, campaign: Campaign, files: Sequence[Path], extra: str = "") -> str:
        """Hash of the campaign's file hashes, the given files, the version
        and ``extra`` (another input of the stage, as text; "" adds nothing).

        A missing file (a stage skipped, e.g. discovery on a campaign of
        flow tests alone, or a comparison whose residual analysis failed)
        counts as missing, so that it appearing later changes the hash."""
        h = hashlib.sha256(json.dumps(campaign.sha256, sort_keys=True).encode())
        for f in files:
            h.update((_sha256(f) if Path(f).is_file() else f"missing:{Path(f).name}").encode())
        h.update(__version__.encode())
        h.update(extra.encode())
        return h.hexdigest()

    def is_done(self, stage: str, fingerprint: str, outputs: Sequence[Path]) -> bool:
        entry = self.done.get(stage) or {}
        return entry.get("fingerprint") == fingerprint and all(p.exists() for p in outputs)

    def mark(self, stage: str, fingerprint: str, seconds: float) -> None:
        self.done[stage] = {"fingerprint": fingerprint, "seconds": round(seconds, 2)}
        doc = {"format": "pneumafit-stages", "version": 1, "stages": self.done}
        write_text_atomic(self.path, json.dumps(doc, indent=2) + "\n")


def run(
    campaign_path: Path | None,
    out: Path,
    console: Console,
    *,
    seed: int = 0,
    mcmc: bool = True,
    walkers: int | None = None,
    steps: int | None = None,
    strict: bool = False,
    valve: str = "iso6358",
    inputs: str = INPUT_MODE,
    friction: str = "auto",
) -> int:
    """Run the main job; returns the exit status (0 ok, 1 a stage failed, 2 bad input,
    3 a fit is not trustworthy under ``strict``).

    Parameters
    ----------
    campaign_path : Path or None
        Campaign folder; None runs the bundled demo (:data:`DEMO`).
    out : Path
        Run folder (created).
    console : rich.console.Console
    seed : int
        Seed of every fit, sampler and bootstrap.
    mcmc : bool
        Sample the posteriors (False: Laplace intervals only, faster).
    walkers, steps : int, optional
        MCMC settings of the fits (default: those of ``pneumafit fit``).
    strict : bool
        Return 3 when a fit is not trustworthy (fit.json ``quality``); every
        stage still runs, and the verdicts are printed at the end either way.
    valve : {"iso6358", "map"}
        Valve law of the three fits (``pneumafit fit --valve``); every later
        stage reads it from the fits. A finished fit of the other law is
        not reused.
    inputs : {"hold", "linear"}
        How the fits read the recorded commands and set-points between
        samples (``pneumafit fit --inputs``); a finished fit read the other
        way (a fit.json without the key interpolated) is not reused.
    friction : str
        Friction law of the three fits (``pneumafit fit --friction``): "auto",
        the convection fit chooses and the other two use its law, or a
        registered law's name, which all three use (a finished fit of another
        law is not reused).
    """
    started = time.perf_counter()
    path = Path(campaign_path) if campaign_path is not None else DEMO
    job = _friction_job(path, out, console, seed, mcmc, walkers, steps, strict)
    if job is not None:
        return job
    console.rule(f"[bold]pneumafit run[/bold]: {path}")
    status = check_campaign(path, console=console)
    if status != 0:
        console.print("[red]the campaign is not valid; nothing was run[/red]")
        return EXIT_BAD_INPUT  # check's own status is 1: problems found
    campaign = read_campaign(path)
    out = Path(out)
    from pneumafit.cli.fit import MAX_SAMPLED, law_problems

    problems = [
        folder_problem(out),
        int_problem("--walkers", walkers, 2 * MAX_SAMPLED),
        int_problem("--steps", steps, 1),
        int_problem("--seed", seed, 0),
        *law_problems(valve, friction),
        None
        if inputs in INPUT_MODES
        else f"option --inputs: expected one of {', '.join(INPUT_MODES)}, found {inputs!r}",
    ]
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    out.mkdir(parents=True, exist_ok=True)
    book = StageBook(out)
    timings: dict[str, float] = {}
    sims: dict[str, int] = {}  # simulations run by each stage (not reused)

    def stage(name: str, inputs: Sequence[Path], outputs: Sequence[Path],
              body: Callable[[], int], extra: str = "") -> None:  # fmt: skip
        fp = book.fingerprint(campaign, inputs, extra)
        if book.is_done(name, fp, outputs):
            console.print(f"[dim]{name}: reused (inputs unchanged)[/dim]")
            timings[name] = 0.0
            return
        console.rule(name)
        t0, n0 = time.perf_counter(), counter.simulations()
        code = body()
        if code != 0:
            raise StageFailed(name, code)
        timings[name] = time.perf_counter() - t0
        sims[name] = counter.simulations() - n0
        book.mark(name, fp, timings[name])

    try:
        fit_files = _fits(campaign, path, out, console, seed, mcmc, walkers, steps, timings,
                          sims, valve, inputs, friction)  # fmt: skip
        for model, file in fit_files.items():  # fit times, for the report
            seconds = timings.get(f"fit {model}")
            if seconds:
                book.mark(f"fit {model}", book.fingerprint(campaign, [file]), seconds)
        conv = fit_files["convection"]
        _analyses(campaign, path, out, console, seed, fit_files, stage)
        # the summary first: the report shows the stages and their times
        _summary(out, campaign, path, timings, started, sims, conv_fit=conv)
        _report(out, path, fit_files, console, stage)
    except StageFailed as exc:
        console.print(f"[red]{exc}; the finished stages are kept and reused next time[/red]")
        _summary(out, campaign, path, timings, started, sims, failed=exc.stage)
        _print_stage_times(console, timings, sims)
        return 1 if exc.status not in (2, 130) else exc.status
    except KeyboardInterrupt:
        console.print("[yellow]interrupted: the finished stages are kept and reused next "
                      "time[/yellow]")  # fmt: skip
        return 130
    total = _summary(out, campaign, path, timings, started, sims, conv_fit=conv)
    console.rule("done")
    trusted = _verdicts(fit_files, console)
    print_conclusions(out, console)
    console.print(f"report: {out / 'report.html'}")
    _print_stage_times(console, timings, sims)
    console.print(f"total time {total:.0f} s ({total / 60:.1f} min)")
    return EXIT_UNTRUSTWORTHY if strict and not trusted else 0


def _friction_job(
    path: Path, out: Path, console: Console, seed: int, mcmc: bool,
    walkers: int | None, steps: int | None, strict: bool,
) -> int | None:  # fmt: skip
    """A campaign of friction tests runs its own job (check, fit, discover, report);
    its exit status, or None for any other campaign."""
    from pneumafit.friction_pipeline import is_friction_campaign, run_friction

    if not is_friction_campaign(path):
        return None
    return run_friction(path, out, console, seed=seed, mcmc=mcmc, walkers=walkers,
                        steps=steps, strict=strict)  # fmt: skip


def _verdicts(fit_files: dict[str, Path], console: Console) -> bool:
    """Print each fit's quality verdict; True when every fit is trustworthy."""
    from pneumafit.identification.staged import FitResult

    trusted = True
    for model, file in fit_files.items():
        try:
            quality = dict(FitResult.load(file).quality or {})
        except PneumafitInputError:
            quality = {}
        ok = bool(quality.get("trustworthy", False))
        trusted = trusted and ok
        style = "green" if ok else "red"
        verdict = quality.get("verdict", "no quality in fit.json (an older fit)")
        console.print(Text(f"fit {model}: {verdict}", style=style))
        if not ok:
            for line in quality.get("problems") or []:
                console.print(Text(f"  - {line}", style="red"))
    return trusted


#: Relative gap between discovery's held-out figure of its base model and the
#: comparison's of the same fit above which the conclusions say why they
#: differ (a rounding of the printed figures is far below it).
BASIS_GAP = 0.01


def print_conclusions(out: Path, console: Console) -> None:
    """Print what the comparison and discovery concluded, from their saved
    files (nothing for a stage that wrote none): the held-out pressure RMSE
    of each model with the lowest named, and discovery's selection, its
    held-out pressure (a friction-test job's: force) RMSE before and after,
    and its statement."""
    try:
        comp = json.loads((out / "comparison" / "comparison.json").read_text())
        held = {
            m: comp[m]["rmse_by_quantity"]["validate"]["pressure"]
            for m in comp.get("models") or ()
            if "pressure" in ((comp.get(m) or {}).get("rmse_by_quantity") or {}).get("validate", {})
        }
    except (OSError, ValueError, KeyError, TypeError):
        held = {}
    if held:
        best = min(held, key=lambda m: held[m])
        console.print(
            "comparison: held-out pressure RMSE "
            + ", ".join(f"{m} {v:.0f} Pa" for m, v in held.items())
            + f"; lowest: {best}"
        )
    try:
        disc = json.loads((out / "discovery" / "discovery.json").read_text())
        selected = ", ".join(disc.get("selected") or ()) or "none"
        statement = str(disc["statement"])
        unexplained = bool(disc.get("unexplained"))
    except (OSError, ValueError, KeyError, TypeError):
        return
    # the chamber models' held-out pressures; a friction-test job's force
    if "pressure_rmse_before" in disc:
        what, unit, digits = "pressure", "Pa", 0
        before = (disc.get("pressure_rmse_before") or {}).get("validate")
        after = (disc.get("pressure_rmse_after") or {}).get("validate")
    else:
        what, unit, digits = "force", "N", 3
        before = ((disc.get("rmse_before") or {}).get("validate") or {}).get("F")
        after = ((disc.get("rmse_after") or {}).get("validate") or {}).get("F")
    line = f"discovery: selected {selected}"
    if isinstance(before, (int, float)) and isinstance(after, (int, float)):
        line += f"; held-out {what} RMSE {before:.{digits}f} -> {after:.{digits}f} {unit}"
        # the same base model, another figure: discovery judges its refits
        # by the RMS of the pressure channels' RMSEs, held-out recordings
        # replayed from the sensors' readings; the comparison pools every
        # pressure sample and starts from the fit's sensor offsets. Measured
        # on the novel truth's sparse-long campaign: 6055 Pa pooled with the
        # offsets, 5552 Pa pooled from the readings, 5217 Pa over channels
        # from the readings. Say so rather than print two numbers for one fit
        base = held.get(str(disc.get("base_model") or ""))
        if what == "pressure" and base is not None and abs(before - base) > BASIS_GAP * base:
            line += (
                " (over the pressure channels, replayed from the sensors' readings, as "
                f"discovery judges its refits; the comparison's {base:.0f} Pa pools every "
                "sample and starts from the fit's sensor offsets)"
            )
    console.print(Text(line, style="yellow" if unexplained else "green"))
    console.print(Text(f"  {statement}", style="yellow" if unexplained else "green"))


def _fits(
    campaign: Campaign, path: Path, out: Path, console: Console, seed: int, mcmc: bool,
    walkers: int | None, steps: int | None, timings: dict[str, float], sims: dict[str, int],
    valve: str = "iso6358", inputs: str = INPUT_MODE, friction: str = "auto",
) -> dict[str, Path]:  # fmt: skip
    """Fit the three models (or reuse finished fits); fit.json path per model.
    Each fit's wall time goes into ``timings`` and its simulations into ``sims``.
    ``friction`` "auto": the first fit chooses the friction law and the others
    use it; a law's name: every fit uses it."""
    from pneumafit.cli.fit import report_fit
    from pneumafit.identification.staged import FitOptions, FitResult
    from pneumafit.services.fit import (
        fit_command_line,
        fit_folder,
        interrupted_message,
        partial_path,
    )

    # the campaign's warnings, which every fit judges again, printed once
    live, summaries = ShownWarnings(), ShownWarnings()
    raw = console_log(console)
    say = live.log(raw)
    options = FitOptions(
        mcmc=mcmc,
        walkers=walkers,
        steps=steps,
        progress=console.is_terminal,
        valve=valve,
        inputs=inputs,
    )
    files = {}
    # the friction law asked for, else the first fit's, the others' too
    law: str | None = None if friction == "auto" else friction
    asked = law is not None
    for model in FIT_ORDER:
        folder = out / "fits" / model
        name = f"fit {model}"
        if fit_is_reusable(folder, campaign, model, valve, inputs, friction=law):
            console.print(f"[dim]{name}: reused {folder / 'fit.json'}[/dim]")
            timings[name] = 0.0
            if law is None:
                law = FitResult.load(folder / "fit.json").structure.friction
        else:
            console.rule(name)
            t0, n0 = time.perf_counter(), counter.simulations()
            console.print(f"fitting {model} to {campaign.name} "
                          f"({len(campaign.by_role('fit'))} fit recordings)")  # fmt: skip
            if asked:
                console.print(f"friction law {law}, as asked (--friction)")
            elif law is not None:
                console.print(f"friction law {law}, as chosen by the {FIT_ORDER[0]} fit")
            command = fit_command_line(path, model, folder, walkers, steps, seed, mcmc,
                                       valve=valve, inputs=inputs,
                                       friction=law or "auto")  # fmt: skip
            chosen = options if law is None else replace(options, friction=law)
            result = run_service(
                console, name,
                lambda m=model, f=folder, c=command, o=chosen: fit_folder(
                    campaign, m, f, options=o, seed=seed, command=c, log=say,
                    progress=Reporter(say, console=console),
                ),
                campaign=path, failed="fit failed",
                interrupted=lambda f=folder: interrupted_message(
                    partial_path(f) if mcmc else None
                ),
            )  # fmt: skip
            live.flush(raw)
            report_fit(result, folder, console, summaries)
            timings[name] = time.perf_counter() - t0
            sims[name] = counter.simulations() - n0
            if law is None:
                law = result.structure.friction
        files[model] = folder / "fit.json"
    return {m: files[m] for m in RUN_MODELS}


def run_service(
    console: Console, stage: str, work: Callable[[], Any], *, campaign: Path, failed: str,
    interrupted: str | Callable[[], str] = "interrupted",
) -> Any:  # fmt: skip
    """A service's result; its bad input, failure or interruption printed (as
    the command line prints them) and raised as :class:`StageFailed` with the
    command's exit status."""
    result, status = run_guarded(console, work, campaign=campaign, failed=failed,
                                 interrupted=interrupted)  # fmt: skip
    if status is not None:
        raise StageFailed(stage, status)
    return result


def _analyses(
    campaign: Campaign, path: Path, out: Path, console: Console, seed: int,
    fits: dict[str, Path], stage: Callable[..., None],
) -> None:  # fmt: skip
    """Comparison, discovery, linear analysis, closed loop, export and report."""
    conv = fits["convection"]
    all_fits = [fits[m] for m in RUN_MODELS]

    def compare() -> int:
        from pneumafit.comparison.report import print_table
        from pneumafit.services.compare import compare_folder, read_fit

        folder = out / "comparison"
        fit_options = "".join(f" --fits {f.parent}" for f in all_fits)
        command = f"pneumafit compare {path} --out {folder}{fit_options} --seed {seed}"
        comparison = run_service(
            console, "comparison",
            lambda: compare_folder(
                campaign, folder, {m: read_fit(fits[m]) for m in RUN_MODELS}, seed=seed,
                command=command, log=console_log(console),
            ),
            campaign=path, failed="comparison failed",
        )  # fmt: skip
        print_table(comparison.document, console)
        console.print(f"wrote {folder / COMPARISON_FILE}")
        return 0

    # residuals.json is not required: a comparison whose residual analysis
    # failed is done (the report runs the analysis and shows what fails)
    stage("comparison", all_fits,
          [out / "comparison" / COMPARISON_FILE, out / "comparison" / REPLAYS_FILE],
          compare)  # fmt: skip

    def discover() -> int:
        from pneumafit.cli.discover import report_discovery
        from pneumafit.services.discover import discover_folder

        folder = out / "discovery"
        say = console_log(console)
        console.print(f"discovery on {campaign.name}: base model convection from {conv}")
        done = run_service(
            console, "discovery",
            lambda: discover_folder(
                campaign, conv, folder, seed=seed, rounds=2, per_round=3,
                command=(f"pneumafit discover {path} --fit {conv} --out {folder} --seed {seed} "
                         "--rounds 2 --per-round 3"),
                log=say, progress=Reporter(say, console=console),
            ),
            campaign=path, failed="discovery failed", interrupted="interrupted: nothing written",
        )  # fmt: skip
        report_discovery(done.document, console)
        console.print("wrote " + ", ".join(str(p) for p in done.files))
        return 0

    # discovery analyses the residual pressure rates of charge/discharge and
    # step tests: a campaign of flow tests alone (a valve characterised on
    # its own) has none, and skipping it is not a failure of the run
    from pneumafit.discovery.attribution import analysable

    if analysable(campaign):
        stage("discovery", [conv], [out / "discovery" / "discovery.json"], discover)
    else:
        console.rule("discovery")
        console.print(
            "discovery skipped: the campaign has no charge/discharge or step recording with "
            "chamber pressures, whose residuals it analyses"
        )

    lambda_file = fits["constant-lambda"]

    def linear() -> int:
        _linear(conv, lambda_file, out / "linear", console)
        return 0

    stage("linear", [conv, lambda_file], [out / "linear" / "linear.json"], linear)

    truth = path / "truth.json"
    why_not = _unrunnable_truth(truth)
    plant = truth if why_not is None else None

    def closed_loop() -> int:
        from pneumafit.outputs.closed_loop_report import run_closed_loop

        if plant is None and truth.exists():
            console.print(f"closed loop: {truth} {why_not}; the plant is the convection fit")

        results = run_closed_loop(conv, out / "closed_loop", plant=plant,
                                  lambda_e=_lambda_e(lambda_file), console=console)  # fmt: skip
        return 0 if all(r.ok for r in results) else 1

    inputs = [conv, lambda_file] + ([truth] if plant else [])
    stage("closed_loop", inputs, [out / "closed_loop" / "closed_loop.json"], closed_loop)

    closed_loop_file = out / "closed_loop" / "closed_loop.json"

    def export() -> int:
        return _export(conv, closed_loop_file, out / "export", console)

    # the plant FMU holds the C code of parts from outside the package: an
    # edit of that code alone (the fits unchanged) builds it again
    from pneumafit.outputs.fmu import c_code_digest

    stage("export", [conv, lambda_file, closed_loop_file],
          [out / "export" / f for f in (*EXPORT_FORMATS.values(), "controller.c", SIL_FILE)],
          export, c_code_digest())  # fmt: skip


def _unrunnable_truth(truth: Path) -> str | None:
    """Why a campaign's truth.json cannot be the closed loop's plant, or None
    for a virtual rig's truth the compiled model can run: one recorded with
    the fitted models' laws (not an independent truth: key ``truth_model``,
    :mod:`pneumafit.virtual_rig.truth`) whose parameters and structure this
    process knows (a rig recorded with parts from outside the package names
    theirs)."""
    from pneumafit.analysis.closed_loop import independent_truth, read_plant_file

    try:
        doc = json.loads(truth.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "cannot be read"
    if not isinstance(doc, dict) or independent_truth(doc) is not None:
        return "is an independent truth the compiled model cannot run"
    try:
        read_plant_file(truth)  # the closed loop's own reader
    except PneumafitInputError as exc:
        return f"names what this process does not know ({exc})"
    return None


def _report(out: Path, path: Path, fits: dict[str, Path], console: Console,
            stage: Callable[..., None]) -> None:  # fmt: skip
    """The validation report, from every stage's outputs (and summary.json)."""

    def report() -> int:
        from pneumafit.outputs.report import write_report

        write_report(out, out / "report.html", campaign=path, console=console)
        return 0

    # the report reads every stage's outputs: any change rebuilds it
    report_inputs = [
        *(fits[m] for m in RUN_MODELS),
        out / "comparison" / COMPARISON_FILE,
        out / "comparison" / REPLAYS_FILE,
        out / "comparison" / RESIDUALS_FILE,
        out / "discovery" / "discovery.json",
        out / "linear" / "linear.json",
        out / "closed_loop" / "closed_loop.json",
        out / "export" / EXPORT_FORMATS["json"],
        out / "export" / SIL_FILE,
    ]
    stage("report", report_inputs, [out / "report.html"], report)


def _lambda_e(constant_lambda_fit: Path) -> float:
    """Nominal lambda of the linear models: the constant-lambda fit's value (W/m^2/K)."""
    from pneumafit.parameters_io import read_parameter_file

    _, values = read_parameter_file(constant_lambda_fit)
    return float(values.get("lambda", 15.0))


def _design_frequency(params: Any, valve: str = "iso6358") -> float:
    """w0 of the gain schedule: the open-loop natural frequency at half stroke (rad/s)."""
    import numpy as np

    from pneumafit.analysis import linearize
    from pneumafit.models.layout import P

    mid = linearize(params, 0.5 * params[P["stroke"]], order=4, valve=valve).poles
    return float(np.abs(mid[np.abs(mid.imag) > 0]).max())


def _grid(params: Any) -> Any:
    import numpy as np

    from pneumafit.models.layout import P

    return np.linspace(0.02, 0.98, 25) * params[P["stroke"]]


def _linear(fit: Path, lambda_fit: Path, out: Path, console: Console) -> None:
    """Linear analysis and both designs at the fitted parameters."""
    from pneumafit.models import parameter_vector
    from pneumafit.outputs.linear_report import write_design, write_linear
    from pneumafit.parameters_io import read_parameter_file, read_valve_law

    _, values = read_parameter_file(fit)
    valve = read_valve_law(fit)
    params = parameter_vector(values)
    lam = _lambda_e(lambda_fit)
    ys = _grid(params)
    w0 = _design_frequency(params, valve)
    write_linear(params, ys, out, lambda_e=lam, valve=valve)
    for order in (4, 6):
        write_design(params, ys, out, order=order, w0=w0, lambda_e=lam, valve=valve)
    console.print(f"linear analysis and designs (w0 = {w0:.1f} rad/s, lambda_e = {lam:.1f} "
                  f"W/m^2/K) in {out}")  # fmt: skip


def _export(fit: Path, closed_loop: Path, out: Path, console: Console) -> int:
    """The controller the closed-loop stage validated, in every export format,
    and its C code run in the loop on the closed-loop stage's plant
    (``sil.json``; skipped, and said, without a C compiler)."""
    from pneumafit.outputs.c_controller import find_compiler, sil_from_closed_loop
    from pneumafit.outputs.export import export_document, write_export
    from pneumafit.outputs.fmu import build_fmu

    doc = export_document(fit, closed_loop=closed_loop)
    for fmt, name in EXPORT_FORMATS.items():
        write_export(doc, out / name, fmt)
    console.print(f"controller export ({', '.join(EXPORT_FORMATS)}, controller.c) in {out}: "
                  f"{doc['design']['description']}")  # fmt: skip
    # the fitted plant for Simulink, AMESim, Dymola, OpenModelica (FMI 2.0
    # co-simulation); not a stage output: a machine without a C compiler, or
    # a structure the FMU does not have, still gets everything else
    try:
        build_fmu(fit, out / PLANT_FMU)
        console.print(f"plant FMU (FMI 2.0 co-simulation) of the convection fit: {out / PLANT_FMU}")
    except PneumafitInputError as exc:
        console.print(f"plant FMU not written: {exc}")
    if find_compiler() is None:
        sil = {"format": "pneumafit-sil", "version": 1, "run": False,
               "reason": "no C compiler found (set CC, or install cc/gcc/clang)"}  # fmt: skip
        console.print("software in the loop: skipped, no C compiler")
        write_text_atomic(out / SIL_FILE, json.dumps(sil, indent=2) + "\n")
        return 0
    sil = sil_from_closed_loop(doc, out / EXPORT_FORMATS["c"], closed_loop)
    write_text_atomic(out / SIL_FILE, json.dumps(sil, indent=2, allow_nan=False) + "\n")
    console.print(f"software in the loop: the compiled controller.c on the nonlinear model, "
                  f"largest command difference from the Python law "
                  f"{sil['max_command_difference_V']} V over {sil['samples']} samples; "
                  f"figures identical: {sil['identical_figures']}")  # fmt: skip
    ok = sil["python"]["ok"] and sil["c"]["ok"] and sil["identical_figures"]
    return 0 if ok else 1


def _rates(timings: dict[str, float], sims: dict[str, int]) -> dict[str, float | None]:
    """Simulations per second of each stage (None for a reused stage, 0 s)."""
    return {
        name: round(sims.get(name, 0) / seconds, 1) if seconds > 0 else None
        for name, seconds in timings.items()
    }


def _print_stage_times(console: Console, timings: dict[str, float], sims: dict[str, int]) -> None:
    """The run's stages with wall time, simulations and simulations per second."""
    rates = _rates(timings, sims)
    console.print(f"{'stage':<26s} {'time (s)':>9s} {'simulations':>12s} {'per second':>11s}")
    for name, seconds in timings.items():
        rate = rates[name]
        shown = "reused" if rate is None else f"{rate:11.0f}"
        console.print(Text(f"{name:<26s} {seconds:9.1f} {sims.get(name, 0):12d} {shown:>11s}"))


def _summary(
    out: Path, campaign: Campaign, path: Path, timings: dict[str, float], started: float,
    sims: dict[str, int] | None = None, *, conv_fit: Path | None = None,
    failed: str | None = None,
) -> float:  # fmt: skip
    """Write ``OUT/summary.json`` (stages, their times and simulation rates, the
    headline results).

    ``seconds``: wall time per stage (0 for a reused one); ``simulations``:
    simulations it ran in this process (one parameter set on one recording);
    ``simulations_per_second``: their ratio (None for a reused stage).
    """
    total = time.perf_counter() - started
    sims = sims or {}
    doc: dict[str, Any] = {
        "format": "pneumafit-run",
        "version": 2,
        "pneumafit_version": __version__,
        "campaign": {"name": campaign.name, "path": str(path), "sha256": campaign.sha256},
        "seconds": {k: round(v, 2) for k, v in timings.items()},
        "simulations": {k: int(sims.get(k, 0)) for k in timings},
        "simulations_per_second": _rates(timings, sims),
        "total_seconds": round(total, 2),
        "total_simulations": int(sum(sims.values())),
        "failed_stage": failed,
        "outputs": {
            "fits": "fits/<model>/fit.json",
            "comparison": "comparison/comparison.json",
            "discovery": "discovery/discovery.json",
            "linear": "linear/",
            "closed_loop": "closed_loop/closed_loop.json",
            "export": "export/",
            "report": "report.html",
        },
    }
    if conv_fit is not None and conv_fit.exists():
        from pneumafit.identification.staged import FitResult

        fit = FitResult.load(conv_fit).document
        doc["convection"] = {
            name: {k: p.get(k) for k in ("value", "unit", "interval_90")}
            for name, p in fit.get("parameters", {}).items()
            if not p.get("fixed")
        }
    write_text_atomic(out / "summary.json", json.dumps(doc, indent=2) + "\n")
    return total
