"""Body of ``pneumafit fit``: staged identification of a campaign, with MCMC.

The work and the files are the service's
(:func:`pneumafit.services.fit.fit_folder`); this module checks the options,
prints the fit's progress and summary (:func:`report_fit`, also used by the
main job) and turns the service's ends into exit statuses.

``fit_command`` never lets a traceback out for bad input: it prints one
message naming the file or option, what was expected and what was found,
and returns 2. It returns 1 when the fit itself fails (every simulation
failed), 130 when interrupted (with MCMC the chains sampled so far are kept
and the same command resumes them after redoing the least-squares stages;
with ``--no-mcmc`` nothing is kept), 0 on success.

Output folder ``OUT``::

    OUT/fit.json            the result (format pneumafit-fit, see fitfile.py)
    OUT/chains.h5           emcee HDF5 backend, one group per sampled stage
    OUT/chains.partial.h5   chains of a run in progress (renamed when done)
    OUT/chains.<stage>.nc   each sampled stage's kept chain as ArviZ InferenceData

Both final files appear atomically (renamed into place). A partial chains
file is resumed only when it was made with the same campaign (SHA-256 of
its files), model, seed, walkers, steps and pneumafit version.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

from pneumafit.campaign.units import display_unit
from pneumafit.cli.console import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_UNTRUSTWORTHY,
    ShownWarnings,
    console_log,
    folder_problem,
    int_problem,
    read_campaign_or_report,
    report_problems,
    run_guarded,
)
from pneumafit.identification.fitfile import widening_label
from pneumafit.identification.problem import NOISE_POOLINGS, OFFSET_SCOPE, OFFSET_SCOPES, QUANTITIES
from pneumafit.identification.quality import parameter_flags, zeros_phrase
from pneumafit.identification.segments import SEGMENT_MODES
from pneumafit.identification.staged import (
    FRICTION_PARAMETERS,
    SEAL_MODES,
    FitOptions,
    FitResult,
)
from pneumafit.models.layout import FRICTION_LAWS, VALVE_LAWS
from pneumafit.models.structure import INPUT_MODE, INPUT_MODES, MODELS
from pneumafit.progress import Reporter
from pneumafit.services.fit import (
    fit_command_line,
    fit_folder,
    interrupted_message,
    partial_path,
    written_line,
)
from pneumafit.simulation.sensor import TemperatureProbe

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "fit_command",
    "law_problems",
    "report_fit",
]


#: The largest stage sampled by default has this many parameters (friction).
MAX_SAMPLED = len(FRICTION_PARAMETERS)


def law_problems(valve: str, friction: str) -> list[str]:
    """What is wrong with the options ``--valve`` and ``--friction`` (none: []):
    a name no registered law has, with the hint to load one's own first."""
    problems = []
    if valve not in VALVE_LAWS:
        problems.append(
            f"option --valve: expected one of {', '.join(VALVE_LAWS)}, found {valve!r} "
            "(a valve law of your own: load its file first, pneumafit --parts FILE.py fit ...)"
        )
    if friction not in ("auto", *FRICTION_LAWS):
        problems.append(
            f"option --friction: expected one of auto, {', '.join(FRICTION_LAWS)}, "
            f"found {friction!r} (a friction law of your own: load its file first, "
            "pneumafit --parts FILE.py fit ...)"
        )
    return problems


def fit_command(
    campaign: Path,
    model: str,
    out: Path,
    walkers: int | None,
    steps: int | None,
    seed: int,
    mcmc: bool,
    console: Console,
    strict: bool = False,
    valve: str = "iso6358",
    friction: str = "auto",
    seal: str = "long",
    noise_pooling: str = "recording",
    inputs: str = INPUT_MODE,
    segments: str = "auto",
    offset_scope: str = OFFSET_SCOPE,
) -> int:
    """Fit a model to a campaign and write ``OUT/fit.json`` and ``OUT/chains.h5``.

    Parameters
    ----------
    campaign : Path
        Campaign folder (or its campaign.toml).
    model : {"convection", "constant-lambda", "polytropic", "friction"}
        ``friction``: the friction law on a campaign of friction tests
        (:mod:`pneumafit.cli.friction`).
    out : Path
        Output folder (created; its fit.json and chains.h5 are replaced).
    walkers, steps : int or None
        Walkers and steps of every sampled stage (None: the defaults).
    seed : int
        Same seed, same numbers.
    mcmc : bool
        False for point estimates with Laplace uncertainties only.
    console : rich.console.Console
    strict : bool
        Return 3 when the fit is not trustworthy (:class:`FitQuality`).
    valve : {"iso6358", "map"}
        Valve law (:class:`FitOptions`).
    friction : {"auto", "switch", "lugre"}
        Friction law (:class:`FitOptions`).
    seal : {"long", "auto", "on", "off"}
        Pressure-dependent seal friction (:class:`FitOptions`).
    noise_pooling : {"recording", "sensor"}
        Noise level per recording and channel, or per sensor
        (:class:`FitOptions`).
    inputs : {"hold", "linear"}
        ``--inputs``: the recorded commands and set-points between samples.
    segments : {"auto", "on", "off"}
        ``--segments``: long closed-loop step tests fitted in segments
        (:class:`FitOptions`).
    offset_scope : {"sensor", "recording"}
        ``--offset-scope``: one profiled pressure offset per sensor or per
        recording (:class:`FitOptions`).

    Returns
    -------
    int
        0 ok, 1 the fit failed, 2 bad input, 3 untrustworthy under ``strict``,
        130 interrupted (MCMC chains resumable).
    """
    if model == "friction":  # friction tests: the friction law on the rod-force balance
        from pneumafit.cli.friction import friction_fit_command

        return friction_fit_command(
            campaign, out, walkers, steps, seed, mcmc, console, strict, friction, seal
        )
    problems = [
        int_problem("--walkers", walkers, 2 * MAX_SAMPLED),
        int_problem("--steps", steps, 1),
        int_problem("--seed", seed, 0),
    ]
    if model not in MODELS:
        problems.append(
            f"option --model: expected one of {', '.join(MODELS)}, friction, found {model!r} "
            "(a heat law of your own: load its file first, pneumafit --parts FILE.py fit ...)"
        )
    problems += law_problems(valve, friction)
    if seal not in SEAL_MODES:
        problems.append(
            f"option --seal-friction: expected one of {', '.join(SEAL_MODES)}, found {seal!r}"
        )
    if noise_pooling not in NOISE_POOLINGS:
        problems.append(
            f"option --noise-pooling: expected one of {', '.join(NOISE_POOLINGS)}, "
            f"found {noise_pooling!r}"
        )
    if inputs not in INPUT_MODES:
        problems.append(
            f"option --inputs: expected one of {', '.join(INPUT_MODES)}, found {inputs!r}"
        )
    if segments not in SEGMENT_MODES:
        problems.append(
            f"option --segments: expected one of {', '.join(SEGMENT_MODES)}, found {segments!r}"
        )
    if offset_scope not in OFFSET_SCOPES:
        problems.append(
            f"option --offset-scope: expected one of {', '.join(OFFSET_SCOPES)}, "
            f"found {offset_scope!r}"
        )
    out = Path(out)
    problems.append(folder_problem(out))
    if report_problems(console, problems):
        return EXIT_BAD_INPUT
    camp = read_campaign_or_report(campaign, console)
    if camp is None:
        return EXIT_BAD_INPUT
    command = fit_command_line(campaign, model, out, walkers, steps, seed, mcmc, strict=strict,
                               valve=valve, friction=friction, seal=seal,
                               noise_pooling=noise_pooling, inputs=inputs,
                               segments=segments, offset_scope=offset_scope)  # fmt: skip
    options = FitOptions(
        mcmc=mcmc, walkers=walkers, steps=steps, progress=console.is_terminal, valve=valve,
        friction=friction, seal=seal, noise_pooling=noise_pooling, inputs=inputs,
        segments=segments, offset_scope=offset_scope,
    )  # fmt: skip
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        console.print(
            Text(f"option --out {os.fspath(out)!r}: cannot be created: {exc}", "bold red")
        )
        return EXIT_BAD_INPUT
    partial = partial_path(out) if mcmc else None
    console.print(f"fitting {model} to {camp.name} ({len(camp.by_role('fit'))} fit recordings)")

    say = console_log(console)

    result, status = run_guarded(
        console,
        lambda: fit_folder(camp, model, out, options=options, seed=seed, command=command,
                           log=say, progress=Reporter(say, console=console)),
        campaign=campaign, failed="fit failed",
        interrupted=lambda: interrupted_message(partial),
    )  # fmt: skip
    if status is not None or result is None:
        return status if status is not None else EXIT_FAILED
    report_fit(result, out, console)
    return fit_status(result, strict)


def fit_status(result: FitResult, strict: bool) -> int:
    """The exit status of a finished fit: 3 when it is not trustworthy under
    ``--strict``, else 0."""
    quality = result.quality
    if strict and quality is not None and not quality.trustworthy:
        return EXIT_UNTRUSTWORTHY
    return EXIT_OK


def report_fit(
    result: FitResult, out: Path, console: Console, shown: ShownWarnings | None = None
) -> None:
    """The console output of a finished fit written to ``out``: the summary,
    the files written and, for a fit that is not trustworthy, why. With
    ``shown`` (``pneumafit run``'s fits) a warning an earlier summary printed
    is counted, not printed again."""
    _summary(result, console, shown)
    console.print(written_line(out))
    quality = result.quality
    if quality is not None and not quality.trustworthy:
        console.print(Text(f"NOT TRUSTWORTHY: {quality.verdict()}", style="bold red"))


def _fmt(x: float | None, digits: int = 4) -> str:
    if x is None or not math.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"


def _with_unit(channel: str, value: float | None) -> str:
    """'p_P 1.03 kPa': an SI RMSE in the units of the residual table (fit.json keeps SI)."""
    scale, unit = display_unit(channel)
    return f"{channel} {_fmt(None if value is None else value * scale)} {unit}".rstrip()


def _quality_table(result: FitResult, console: Console) -> None:
    """Residual RMS over sensor noise, per recording and channel (worst first per role)."""
    quality = result.quality
    if quality is None or not quality.channels:
        return
    zeros = zeros_phrase(
        quality.sensor_zeros, quality.zeros_applied, (c.channel for c in quality.channels)
    )
    table = Table(
        title=Text(
            f"residual over sensor noise (noise from the recordings' quiet windows; "
            f"above {quality.threshold:g}x: does not reach the noise"
            + (f"; {zeros}" if zeros else "")
            + ")"
        )
    )
    for col in ("recording", "role", "channel", "RMS", "noise", "RMS/noise", "phases over"):
        table.add_column(col, justify="left" if col in ("recording", "role", "channel",
                                                         "phases over") else "right")  # fmt: skip
    order = {"fit": 0, "validate": 1}
    rows = sorted(quality.channels, key=lambda c: (order.get(c.role, 2), c.recording, c.channel))
    for c in rows:
        scale, unit = display_unit(c.channel)
        ratio = c.ratio
        style = "bold red" if c.fails else None
        table.add_row(
            c.recording, c.role, c.channel + ("" if c.fitted else " (not fitted)"),
            f"{_fmt(c.rms * scale, 3)} {unit}",
            f"{_fmt(c.noise * scale, 3)} {unit}" if c.noise is not None else "-",
            Text(f"{ratio:.2f}" if ratio is not None else "-", style=style or ""),
            ", ".join(f"{p} {c.phases[p]['ratio']:.1f}x" for p in c.failing_phases()),
        )  # fmt: skip
    console.print(table)
    probe = TemperatureProbe.from_metrics(result.metrics)
    if probe is not None and any(QUANTITIES.get(c.channel) == "temperature" for c in rows):
        console.print(
            "temperatures compared through the fit's temperature probe: lags "
            f"{probe.time_constant:.3g} s and {probe.second_time_constant:.3g} s in series"
            + (f", offset {probe.offset:+.2f} K" if probe.offset else "")
        )


def _figure(entry: dict[str, Any], unit: str) -> str:
    """'16.1 W/m^2/K [16.0, 16.2]' from a reference figure of fit.json's metrics."""
    iv = entry.get("interval_90")
    text = f"{_fmt(entry.get('value'), 4)} {unit}"
    return text + (f" [{_fmt(iv[0], 4)}, {_fmt(iv[1], 4)}]" if iv else "")


def _reference_lines(metrics: dict[str, Any]) -> list[str]:
    """The figures that compare a fit with other models and rigs (fit.json's
    metrics.lambda_reference and friction_reference), with 90 % intervals."""
    lines = []
    lam = metrics.get("lambda_reference")
    if lam and lam.get("value") is not None:
        s = lam["state"]
        line = (
            f"lambda at {s['pressure'] / 1e5:g} bar, gas {s['gas_temperature'] - 273.15:g} degC, "
            f"wall {s['wall_temperature'] - 273.15:g} degC: {_figure(lam, 'W/m^2/K')}"
        )
        full = lam.get("full_area_equivalent")
        if full and full.get("value") is not None and full["value"] != lam["value"]:
            line += f"; on every wall's area (chamber P, mid-stroke): {_figure(full, 'W/m^2/K')}"
        lines.append(line)
    fr = metrics.get("friction_reference")
    if fr and (fr.get("static") or fr.get("coulomb")):
        parts = [
            f"{label} {_figure(fr[key], 'N')}"
            for key, label in (("static", "static"), ("coulomb", "Coulomb"))
            if fr.get(key)
        ]
        if fr.get("sliding"):
            v = fr["sliding"]["velocity"] * 1e3
            parts.append(f"sliding at {v:g} mm/s less viscous {_figure(fr['sliding'], 'N')}")
        lines.append("friction at mid pressure: " + ", ".join(parts))
    return lines


def _summary(result: FitResult, console: Console, shown: ShownWarnings | None = None) -> None:
    """The verdict first, then the fitted parameters with their uncertainty and
    MCMC diagnostics, and the residual over noise per recording."""
    quality = result.quality
    if quality is not None:
        style = "bold green" if quality.trustworthy else "bold red"
        console.print(Text(f"{result.model}: {quality.verdict()}", style=style))
        for line in quality.problems():
            console.print(Text(f"  - {line}", style="red"))
        for line in quality.caveats():
            console.print(Text(f"  - {line}", style="yellow"))
    flagged = parameter_flags(quality) if quality is not None else {}
    diag: dict[str, tuple[float, float, float]] = {}
    for run in result.mcmc:
        for n in run.names:
            diag[n] = (run.tau[n], run.rhat[n], run.ess[n])
    table = Table(title=Text(f"{result.model}: estimates (90 % intervals)"))
    for col in (
        "parameter",
        "value",
        "unit",
        "std",
        "90 % interval",
        "from",
        "tau",
        "R-hat",
        "ESS",
        "widened",
        "flag",
    ):
        table.add_column(
            col, justify="left" if col in ("parameter", "unit", "from", "flag") else "right"
        )
    for p in result.parameters:
        if p.std is None or p.group in ("initial", "rig"):
            continue
        lo, hi = p.interval_90 or (math.nan, math.nan)
        tau, rhat, ess = diag.get(p.name, (math.nan, math.nan, math.nan))
        table.add_row(
            p.name, _fmt(p.value, 7), p.unit or "-", _fmt(p.std, 3),
            f"[{_fmt(lo, 7)}, {_fmt(hi, 7)}]",
            p.uncertainty or "-", _fmt(tau), _fmt(rhat), _fmt(ess),
            widening_label(result.widening.get(p.name)),
            Text(flagged.get(p.name, ""), style="bold red"),
        )  # fmt: skip
    console.print(table)
    for line in _reference_lines(result.metrics):
        console.print(line)
    _quality_table(result, console)
    for run in result.mcmc:
        if len(run.names) >= 2 and run.name == "heat":
            names = run.names
            console.print(f"posterior correlation ({run.name}): " + ", ".join(
                f"{names[i]}/{names[j]} {run.correlation[i, j]:+.3f}"
                for i in range(len(names)) for j in range(i + 1, len(names))
            ))  # fmt: skip
    rmse = result.metrics.get("rmse", {})
    for role in ("fit", "validate"):
        if rmse.get(role):
            console.print(
                f"RMSE {role}: " + ", ".join(_with_unit(c, v) for c, v in rmse[role].items())
            )
    for w in result.warnings:
        if shown is None or shown.new(w):
            console.print(Text(f"warning: {w}", style="yellow"))
    if shown is not None:
        shown.flush(lambda line: console.print(Text(line, style="yellow")))
    console.print(f"{result.seconds:.1f} s, {result.evaluations} parameter sets simulated")
