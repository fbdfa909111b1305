"""The fit service: staged identification of a campaign, written to a folder.

:func:`fit_folder` is ``pneumafit fit`` without its console: it runs
:func:`~pneumafit.identification.staged.identify` and writes ``OUT``::

    OUT/fit.json            the result (format pneumafit-fit, see fitfile.py)
    OUT/chains.h5           emcee HDF5 backend, one group per sampled stage
    OUT/chains.partial.h5   chains of a run in progress (renamed when done)
    OUT/chains.<stage>.nc   each sampled stage's kept chain as ArviZ InferenceData

Both final files appear atomically (renamed into place). A partial chains
file is resumed only when it was made with the same campaign (SHA-256 of
its files), model, seed, walkers, steps, laws and pneumafit version; an
interrupted fit (``KeyboardInterrupt``) keeps it, and
:func:`interrupted_message` says what is kept.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py

from pneumafit.campaign.model import Campaign
from pneumafit.errors import PneumafitComputationError
from pneumafit.identification.fitfile import CHAINS_FILE, FIT_FILE, _version
from pneumafit.identification.problem import OFFSET_SCOPE
from pneumafit.identification.replay import replay, with_recorded_commands
from pneumafit.identification.segments import segment_step_tests
from pneumafit.identification.staged import FitOptions, FitResult, identify
from pneumafit.models.structure import INPUT_MODE
from pneumafit.outputs.rest_figure import REST_FIGURE, rest_position_figure
from pneumafit.progress import Reporter

__all__ = [
    "PARTIAL_FILE",
    "fit_command_line",
    "fit_folder",
    "interrupted_message",
    "output_folder",
    "partial_path",
    "write_inference_data",
    "written_line",
]

PARTIAL_FILE = "chains.partial.h5"


def partial_path(out: str | os.PathLike[str]) -> Path:
    """The chains file of a fit in progress in folder ``out``."""
    return Path(out) / PARTIAL_FILE


def _fingerprint(
    campaign_sha: dict[str, str], model: str, seed: int, walkers: Any, steps: Any
) -> str:
    text = json.dumps(
        {"sha256": campaign_sha, "model": model, "seed": seed, "walkers": walkers,
         "steps": steps, "version": _version()},
        sort_keys=True,
    )  # fmt: skip
    return hashlib.sha256(text.encode()).hexdigest()


def _prepare_partial(partial: Path, fingerprint: str, log: Callable[[str], None]) -> None:
    """Keep a partial chains file made by the same run; otherwise remove it."""
    if not partial.exists():
        return
    try:
        with h5py.File(partial, "r") as f:
            same = f.attrs.get("pneumafit_fingerprint") == fingerprint
    except OSError:
        same = False
    if same:
        log(f"resuming the chains in {partial}")
        return
    log(f"{partial}: made by another run (campaign, model, seed or settings differ): "
        "starting afresh")  # fmt: skip
    partial.unlink()


def _stamp(partial: Path, fingerprint: str) -> None:
    with h5py.File(partial, "a") as f:
        f.attrs["pneumafit_fingerprint"] = fingerprint


def interrupted_message(partial: Path | None) -> str:
    """What an interrupted fit keeps, in words that hold.

    Least-squares stages save nothing: a re-run does them again. Only MCMC
    steps are stored (``partial``, one group per sampled stage) and resumed.

    Parameters
    ----------
    partial : Path or None
        The fit's partial chains file (:func:`partial_path`), None for a fit
        without MCMC.
    """
    if partial is None:
        return (
            "interrupted: nothing is kept (a fit with --no-mcmc stores no intermediate "
            "state); the same command starts again from the beginning"
        )
    try:
        with h5py.File(partial, "r") as f:
            stages = [
                f"{name} {int(f[name].attrs.get('iteration', 0))} steps"
                for name in f
                if isinstance(f[name], h5py.Group) and f[name].attrs.get("iteration", 0) > 0
            ]
    except OSError:
        stages = []
    if not stages:
        return (
            f"interrupted before any MCMC step was stored: nothing is kept ({partial} holds "
            "no chain yet); the same command starts again from the beginning"
        )
    return (
        f"interrupted: the MCMC chains sampled so far are kept in {partial} "
        f"({', '.join(stages)}); the same command redoes the least-squares stages and "
        "resumes the chains where they stopped"
    )


def write_inference_data(result: FitResult, out: Path) -> list[Path]:
    """Each sampled stage's chain as ArviZ netCDF, ``OUT/chains.<stage>.nc`` (atomic).

    The emcee HDF5 file stays the resumable record; these are for ArviZ and
    xarray (:meth:`~pneumafit.identification.sampling.MCMCResult.to_inference_data`).
    A stage whose file cannot be written is skipped (the fit is complete
    without it).
    """
    from pneumafit.fileio import atomic_path

    written = []
    for stage in result.stages:
        if stage.mcmc is None:
            continue
        target = out / f"chains.{stage.name}.nc"
        try:
            with atomic_path(target) as tmp:
                stage.mcmc.to_inference_data().to_netcdf(str(tmp), engine="h5netcdf")
        except (OSError, ValueError, ImportError):
            continue
        written.append(target)
    return written


def output_folder(out: str | os.PathLike[str]) -> Path:
    """The output folder ``out``, created (with its parents) if need be.

    Raises
    ------
    PneumafitInputError
        It cannot be created (names the ``--out`` option and why).
    """
    from pneumafit.errors import PneumafitInputError

    folder = Path(out)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PneumafitInputError(
            f"option --out {os.fspath(folder)!r}: cannot be created: {exc}"
        ) from exc
    return folder


def written_line(out: Path) -> str:
    """What a fit folder holds, as the commands print it: 'wrote OUT/fit.json
    and OUT/chains.h5 (chains.heat.nc, ...: ArviZ)'."""
    chains = out / CHAINS_FILE
    netcdf = sorted(out.glob("chains.*.nc")) if chains.exists() else []
    arviz = f" ({', '.join(p.name for p in netcdf)}: ArviZ)" if netcdf else ""
    return f"wrote {out / FIT_FILE}" + (f" and {chains}" if chains.exists() else "") + arviz


def fit_command_line(
    campaign: str | os.PathLike[str], model: str, out: str | os.PathLike[str],
    walkers: int | None, steps: int | None, seed: int, mcmc: bool, *, strict: bool = False,
    valve: str = "iso6358", friction: str = "auto", seal: str = "long",
    noise_pooling: str = "recording", inputs: str = INPUT_MODE, segments: str = "auto",
    offset_scope: str = OFFSET_SCOPE,
) -> str:  # fmt: skip
    """The ``pneumafit fit`` command line of these options (fit.json's
    ``provenance.command``): the defaults are left out."""
    return (
        f"pneumafit fit {os.fspath(campaign)} --model {model} --out {os.fspath(out)}"
        + (f" --walkers {walkers}" if walkers is not None else "")
        + (f" --steps {steps}" if steps is not None else "")
        + f" --seed {seed}"
        + ("" if mcmc else " --no-mcmc")
        + (" --strict" if strict else "")
        + (f" --valve {valve}" if valve != "iso6358" else "")
        + (f" --friction {friction}" if friction != "auto" else "")
        + (f" --seal-friction {seal}" if seal != "long" else "")
        + (f" --noise-pooling {noise_pooling}" if noise_pooling != "recording" else "")
        + (f" --inputs {inputs}" if inputs != INPUT_MODE else "")
        + (f" --segments {segments}" if segments != "auto" else "")
        + (f" --offset-scope {offset_scope}" if offset_scope != OFFSET_SCOPE else "")
    )


def fit_folder(
    campaign: Campaign,
    model: str,
    out: str | os.PathLike[str],
    *,
    options: FitOptions | None = None,
    seed: int = 0,
    command: str = "",
    log: Callable[[str], None] | None = None,
    progress: Reporter | None = None,
) -> FitResult:
    """Fit ``model`` to ``campaign`` and write the fit folder ``out``.

    Parameters
    ----------
    campaign : Campaign
        The campaign (:func:`~pneumafit.campaign.read_campaign`).
    model : {"convection", "constant-lambda", "polytropic"}
    out : path
        Output folder (created; its fit.json and chains.h5 are replaced).
    options : FitOptions, optional
        Laws, MCMC settings (default :class:`FitOptions`); with MCMC the
        chains are stored, and resumed from a partial file of the same run.
    seed : int
        Same seed, same numbers.
    command : str, optional
        The command line recorded in fit.json's provenance.
    log : callable, optional
        Receives the fit's progress lines (the resumed chains, each stage).
    progress : Reporter, optional
        Rate-limited progress of the long loops.

    Returns
    -------
    FitResult
        The fit, as saved in ``out/fit.json``.

    Raises
    ------
    PneumafitInputError
        The campaign or the options cannot be fitted (names what and why),
        or ``out`` cannot be created.
    PneumafitComputationError
        The fit failed, or its files cannot be written.
    KeyboardInterrupt
        Interrupted: with MCMC the chains sampled so far are kept
        (:func:`interrupted_message`).
    """
    options = options or FitOptions()
    say = log or (lambda _line: None)
    out = output_folder(out)
    partial = partial_path(out)
    chains_path: Path | None = None
    if options.mcmc:
        variant = (
            ("" if options.valve == "iso6358" else "+" + options.valve)
            + ("" if options.friction == "auto" else "+friction-" + options.friction)
            + ("" if options.seal == "long" else "+seal-" + options.seal)
        )
        fingerprint = _fingerprint(
            dict(campaign.sha256), model + variant, seed, options.walkers, options.steps
        )
        _prepare_partial(partial, fingerprint, say)
        _stamp(partial, fingerprint)
        chains_path = partial
    result = identify(campaign, model, options=options, seed=seed, chains=chains_path, log=say,
                      progress=progress)  # fmt: skip
    try:
        if options.mcmc:
            os.replace(partial, out / CHAINS_FILE)
        else:
            (out / CHAINS_FILE).unlink(missing_ok=True)  # no stale chains beside a new fit
        result.save(out / FIT_FILE, command=command,
                    chains=CHAINS_FILE if options.mcmc else None)  # fmt: skip
        _rest_figure(campaign, result, out / REST_FIGURE)
    except OSError as exc:
        raise PneumafitComputationError(
            f"{os.fspath(out)}: cannot write the results: {exc}"
        ) from exc
    if options.mcmc:
        write_inference_data(result, out)
    return result


def _rest_figure(campaign: Campaign, result: FitResult, path: Path) -> None:
    """The step test whose piston the verdict names first as resting elsewhere
    (:meth:`~pneumafit.identification.quality.FitQuality.stops_elsewhere`),
    drawn with the fit's closed loop and its replay on the recorded commands
    (:func:`~pneumafit.outputs.rest_figure.rest_position_figure`) at ``path``;
    a figure of an earlier fit there is removed when none is named."""
    stops = result.quality.stops_elsewhere() if result.quality is not None else []
    opts = result.options if isinstance(result.options, FitOptions) else FitOptions()
    # the recordings as fitted: a long step test's segments by their names
    recs = {r.file: r for r in segment_step_tests(campaign, opts.segments)[0].recordings}
    if not stops or stops[0].recording not in recs:
        path.unlink(missing_ok=True)  # no stale figure beside a new fit
        return
    stop, rec = stops[0], recs[stops[0].recording]
    values = result.parameters.values()
    closed = replay([rec], result.structure, values, max_step=opts.max_step).recordings[0]
    looped = with_recorded_commands(rec)
    opened = (
        None if looped is None
        else replay([looped], result.structure, values, max_step=opts.max_step).recordings[0]
    )  # fmt: skip
    rest_position_figure(rec, closed.simulated, opened.simulated if opened else None, stop, path)
