"""The workbench from Python: read a campaign, fit, save, load, discover.

The command line's main steps as functions that take and return objects::

    import pneumafit as pf

    campaign = pf.read_campaign("data/measured/NAP310")
    fit = pf.fit(campaign, "friction", mcmc=False)
    fit.save("out/NAP310/fit.json")
    found = pf.discover(campaign, fit)  # or pf.discover(campaign, "out/NAP310")
    print(found.statement)

    # the chamber models: pf.compare(campaign, [fit_a, fit_b, "out/fits/polytropic"])

:func:`fit` returns a :class:`~pneumafit.identification.staged.FitResult`
(with ``summary()``, ``save()``); :func:`load_fit` reads a saved fit.json
back as a :class:`~pneumafit.identification.fitfile.SavedFit`; :func:`discover`
takes either, or the path of a fit.json (or its folder), and uses the fit's
own seed and options unless told otherwise. This module is the top layer
beside the command line: it only calls the domain packages below it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pneumafit.campaign import read_campaign
from pneumafit.identification.fitfile import SavedFit, fit_document, load_fit
from pneumafit.identification.staged import FitOptions, FitResult
from pneumafit.models.parts import LiveTuple, model_names

if TYPE_CHECKING:
    from pneumafit.campaign.model import Campaign
    from pneumafit.comparison.result import Comparison
    from pneumafit.discovery.refit import Discovery
    from pneumafit.frictiontest.discover import FrictionDiscovery

__all__ = [
    "FitResult", "SavedFit", "compare", "discover", "fit", "load_fit", "read_campaign", "report",
]  # fmt: skip

#: The models :func:`fit` knows: the chamber models (one per heat law,
#: :data:`pneumafit.models.parts.MODEL_NAMES`, live) and the friction-test law.
MODELS = LiveTuple(lambda: (*model_names(), "friction"))


def fit(
    campaign: Campaign,
    model: str = "convection",
    *,
    mcmc: bool = True,
    seed: int = 0,
    options: FitOptions | None = None,
    chains: str | os.PathLike[str] | None = None,
    log: Callable[[str], None] | None = None,
    **friction: Any,
) -> FitResult:
    """Fit one model to a campaign, as ``pneumafit fit CAMPAIGN --model MODEL``.

    Parameters
    ----------
    campaign : Campaign
        From :func:`read_campaign`.
    model : str
        ``convection``, ``constant-lambda``, ``polytropic`` (the staged fit,
        :func:`~pneumafit.identification.staged.identify`) or ``friction``
        (imposed-motion friction tests,
        :func:`~pneumafit.frictiontest.fit.identify_friction`).
    mcmc : bool
        Sample the posterior (emcee) after the joint estimate; False gives
        Laplace intervals only. Overrides ``options.mcmc``.
    seed : int
        Seeds every random choice; same seed, same numbers.
    options : FitOptions, optional
        The staged fit's options (chamber models only).
    chains : path, optional
        HDF5 file of the MCMC chains; an interrupted run resumes from it.
    log : callable, optional
        Receives one line per step of progress.
    **friction
        For ``model="friction"``: ``law`` (``auto``, ``coulomb-viscous``,
        ``stribeck``, ``lugre``), ``effects`` (``off``, ``auto``, ``on``),
        ``walkers``, ``steps``.

    Returns
    -------
    FitResult
        With its seed, options and campaign, so :meth:`FitResult.save` and
        :func:`discover` need nothing else.

    Raises
    ------
    PneumafitInputError
        An unknown model, options that do not apply to it, or a campaign the
        model cannot be fitted to.
    """
    from dataclasses import replace

    from pneumafit.campaign.errors import PneumafitInputError

    if model not in MODELS:
        raise PneumafitInputError(f"model: expected one of {', '.join(MODELS)}, found {model!r}")
    if model == "friction":
        if options is not None:
            raise PneumafitInputError(
                "options: the friction-test fit takes law=, effects=, walkers=, steps=, "
                "found a FitOptions"
            )
        from pneumafit.frictiontest.fit import identify_friction

        return identify_friction(campaign, mcmc=mcmc, seed=seed, chains=chains, log=log, **friction)
    if friction:
        raise PneumafitInputError(
            f"{', '.join(sorted(friction))}: expected no such option for model {model!r} "
            "(give the staged fit's options as options=FitOptions(...))"
        )
    from pneumafit.identification.staged import identify

    opts = replace(options or FitOptions(), mcmc=mcmc)
    return identify(campaign, model, options=opts, seed=seed, chains=chains, log=log)


def discover(
    campaign: Campaign,
    fit: FitResult | SavedFit | str | os.PathLike[str],
    *,
    seed: int | None = None,
    rounds: int | None = None,
    log: Callable[[str], None] | None = None,
) -> Discovery | FrictionDiscovery:
    """Find the effect the fit's residual asks for, refit with it, as ``pneumafit discover``.

    Parameters
    ----------
    campaign : Campaign
        The campaign the fit was made on.
    fit : FitResult or SavedFit or path
        The base fit: in memory (from :func:`fit`), loaded (:func:`load_fit`)
        or the path of its fit.json or folder.
    seed : int, optional
        Default the fit's own seed (0 when it has none).
    rounds : int, optional
        Largest number of effects added (default: the command line's).
    log : callable, optional
        Receives one line per step.

    Returns
    -------
    Discovery or FrictionDiscovery
        The chamber models' :class:`~pneumafit.discovery.refit.Discovery`, or
        the friction tests' result; both have ``selected`` and ``statement``.
    """
    saved = _saved(campaign, fit)
    use_seed = seed if seed is not None else (saved.seed if saved.seed is not None else 0)
    extra: dict[str, Any] = {} if rounds is None else {"rounds": rounds}
    if saved.model == "friction":
        from pneumafit.frictiontest.discover import discover_friction

        return discover_friction(campaign, saved, seed=use_seed, log=log, **extra)
    from pneumafit.discovery.refit import BaseFit
    from pneumafit.discovery.refit import discover as discover_effects

    return discover_effects(campaign, BaseFit.from_document(saved), seed=use_seed, log=log, **extra)


def _saved(campaign: Campaign, fit: FitResult | SavedFit | str | os.PathLike[str]) -> SavedFit:
    """A fit in memory, loaded or by path, as the loaded view."""
    if isinstance(fit, FitResult):
        return SavedFit.from_document(fit_document(fit, campaign), "the fit in memory")
    if isinstance(fit, SavedFit):
        return fit
    return load_fit(fit)


def compare(
    campaign: Campaign,
    fits: Sequence[FitResult | SavedFit | str | os.PathLike[str]],
    *,
    draws: int | None = None,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
) -> Comparison:
    """Replay chamber-model fits on every recording and score them, as ``pneumafit compare``.

    Parameters
    ----------
    campaign : Campaign
        The campaign the fits were made on (its held-out recordings are scored
        apart).
    fits : sequence of FitResult or SavedFit or path
        One fit per model (in memory, loaded, or the path of a fit.json or its
        folder); WAIC and PSIS-LOO where a loaded fit has its chains beside it.
    draws : int, optional
        Posterior draws per model for WAIC/LOO (default the command line's).
    seed : int
        Seeds the draws.
    log : callable, optional
        One line per model replayed.

    Returns
    -------
    Comparison
        ``summary()`` (the table), ``to_dataframe()`` (model x recording x
        channel), ``save(path)`` (comparison.json), ``document``.

    Raises
    ------
    PneumafitInputError
        Two fits of one model, or a friction-test fit (nothing to replay).
    """
    from pneumafit.campaign.errors import PneumafitInputError
    from pneumafit.comparison.information import DEFAULT_DRAWS
    from pneumafit.comparison.result import compare_fits

    loaded: dict[str, SavedFit] = {}
    for fit in fits:
        saved = _saved(campaign, fit)
        if saved.model == "friction" or saved.model in loaded:
            raise PneumafitInputError(
                f"{saved.source}: model: expected one chamber-model fit per model, found "
                + (
                    "a friction-test fit"
                    if saved.model == "friction"
                    else f"a second {saved.model}"
                )
            )
        loaded[saved.model] = saved
    return compare_fits(
        campaign, loaded, draws=DEFAULT_DRAWS if draws is None else draws, seed=seed, log=log
    )


def report(
    run_dir: str | os.PathLike[str],
    campaign: Campaign | str | os.PathLike[str] | None = None,
    *,
    fits: Sequence[FitResult | SavedFit] = (),
    comparison: Comparison | None = None,
    discovery: Discovery | None = None,
    out: str | os.PathLike[str] | None = None,
) -> Path:
    """The validation report of a run folder, with results in memory saved into it first.

    The report only reads saved results (:func:`pneumafit.outputs.report.write_report`):
    each fit given is saved as ``RUN/fits/<model>/fit.json`` and the
    comparison as ``RUN/comparison/comparison.json``, then the report is
    written from the folder (a discovery is read from ``RUN/discovery/``,
    written there by ``pneumafit discover --out RUN/discovery``, or given
    here with its base fit among ``fits``).

    Parameters
    ----------
    run_dir : path
        The run folder (created if needed).
    campaign : Campaign or path, optional
        The campaign (default: the one the fits recorded).
    fits : sequence of FitResult or SavedFit
        Chamber-model fits to save into the folder (one per model).
    comparison : Comparison, optional
        :func:`compare`'s result, to save into the folder.
    discovery : Discovery, optional
        :func:`discover`'s result on one of ``fits`` (its base), saved as
        ``RUN/discovery/discovery.json`` with its figures.
    out : path, optional
        The HTML file (default ``RUN/report.html``).

    Returns
    -------
    pathlib.Path
        The report.

    Raises
    ------
    PneumafitInputError
        Two fits of one model, a friction-test fit, a discovery whose base
        fit is not among ``fits``, or a folder or file that cannot be written.
    """
    from pneumafit.campaign.errors import PneumafitInputError
    from pneumafit.campaign.model import Campaign
    from pneumafit.comparison.result import COMPARISON_FILE
    from pneumafit.identification.fitfile import FIT_FILE
    from pneumafit.outputs.report import write_report

    run = Path(run_dir)
    models: set[str] = set()
    for f in fits:
        if f.model == "friction" or f.model in models:
            raise PneumafitInputError(
                "fits: expected one chamber-model fit per model, found "
                + ("a friction-test fit" if f.model == "friction" else f"a second {f.model}")
            )
        models.add(f.model)
        f.save(run / "fits" / f.model / FIT_FILE)
    if comparison is not None:
        comparison.save(run / "comparison" / COMPARISON_FILE)
    where = campaign.path if isinstance(campaign, Campaign) else campaign
    if discovery is not None:
        from pneumafit.services.discover import discovery_document
        from pneumafit.services.discover import write_report as write_discovery

        base = discovery.base.structure.heat  # the model name of its base fit
        if base not in models:
            raise PneumafitInputError(
                f"discovery: expected its base fit (model {base}) among fits, found "
                + (", ".join(sorted(models)) or "none")
            )
        fit_path = run / "fits" / base / FIT_FILE
        camp = campaign if isinstance(campaign, Campaign) else read_campaign(where)
        doc = discovery_document(
            discovery, camp, fit_path, load_fit(fit_path).document, command="pf.report"
        )
        write_discovery(run / "discovery", doc, discovery, camp)
    return write_report(run, Path(out) if out is not None else run / "report.html", campaign=where)
