"""MCMC part of the validation report: corner plots, traces, diagnostics.

Reads a fit's ``chains.h5`` (emcee ``HDFBackend``, one group per sampled
stage, written by :func:`pneumafit.identification.sampling.run_mcmc`) with
the stage's summary from ``fit.json`` (``mcmc.stages.NAME``: chain order of
the parameters, burn-in ``discard``, diagnostics). Chains hold internal
coordinates (the log for log-scale parameters); they are turned back into
values with each parameter's ``scale`` from fit.json.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.errors import PneumafitInputError
from pneumafit.outputs.report_html import embed_figure, esc, fmt, note, table

__all__ = ["MAX_CORNER_SAMPLES", "read_stage_chain", "render_chains"]

#: Samples drawn in a corner plot at most (the kept chain is thinned to this).
MAX_CORNER_SAMPLES = 4000
#: Steps drawn per walker in a trace plot at most (strided beyond).
MAX_TRACE_STEPS = 1500


def _entry_text(fit: dict[str, Any], name: str, key: str, default: str) -> str:
    """``key`` of parameter ``name``'s entry in a fit document (its parameters,
    then its nuisance), as text; ``default`` where it has none."""
    for group in ("parameters", "nuisance"):
        entry = (fit.get(group) or {}).get(name)
        if isinstance(entry, dict):
            return str(entry.get(key) or default)
    return default


def _scale_of(fit: dict[str, Any], name: str) -> str:
    return _entry_text(fit, name, "scale", "linear")


def _unit_of(fit: dict[str, Any], name: str) -> str:
    return _entry_text(fit, name, "unit", "")


def read_stage_chain(
    chains: Path, stage: str, names: list[str], scales: list[str]
) -> tuple[NDArray[np.float64], int]:
    """All steps of one stage's chain, as parameter values.

    Parameters
    ----------
    chains : Path
        ``chains.h5``.
    stage : str
        Group name (``heat``, ``friction``, ``valve``).
    names, scales : list of str
        Parameters in chain order and their scales (``log`` or ``linear``).

    Returns
    -------
    values : ndarray (n_steps, n_walkers, n_parameters)
    iterations : int
        Steps stored.

    Raises
    ------
    PneumafitInputError
        A group that is missing or whose width is not ``len(names)``.
    """
    import emcee

    try:
        backend = emcee.backends.HDFBackend(str(chains), name=stage, read_only=True)
        iterations = int(backend.iteration)
        chain = np.asarray(backend.get_chain(), dtype=float)
    except (OSError, KeyError, AttributeError) as exc:
        raise PneumafitInputError(
            f"{chains}: group {stage!r}: expected a readable chain, found {exc}"
        ) from None
    if chain.ndim != 3 or chain.shape[2] != len(names):
        raise PneumafitInputError(
            f"{chains}: group {stage!r}: expected a chain of {len(names)} parameters "
            f"({', '.join(names)}), found shape {chain.shape}"
        )
    values = chain.copy()
    for j, scale in enumerate(scales):
        if scale == "log":
            values[:, :, j] = np.exp(chain[:, :, j])
    return values, iterations


def _bulk(samples: NDArray[np.float64], width: float) -> tuple[float, float]:
    """Median +- ``width`` robust standard deviations (1.4826 MAD), within the
    samples' extent: axes that show the bulk of a posterior, not its stragglers."""
    x = samples[np.isfinite(samples)]
    if x.size == 0:
        return -1.0, 1.0
    med = float(np.median(x))
    sigma = 1.4826 * float(np.median(np.abs(x - med)))
    if not sigma > 0:
        sigma = float(np.std(x)) or 1e-6 * max(abs(med), 1e-12)
    lo, hi = max(float(x.min()), med - width * sigma), min(float(x.max()), med + width * sigma)
    if not hi > lo:
        lo, hi = med - sigma, med + sigma
    return lo, hi


def _trace_figure(values: NDArray[np.float64], names: list[str], units: list[str],
                  discard: int, title: str) -> Any:  # fmt: skip
    import matplotlib.pyplot as plt

    n_steps, _, n_par = values.shape
    stride = max(1, math.ceil(n_steps / MAX_TRACE_STEPS))
    steps = np.arange(0, n_steps, stride)
    fig, axes = plt.subplots(n_par, 1, figsize=(9, 1.7 * n_par + 0.6), sharex=True,
                             squeeze=False)  # fmt: skip
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(steps, values[::stride, :, j], lw=0.5, alpha=0.6)
        ax.axvline(discard, color="k", ls="--", lw=0.8)
        lo, hi = _bulk(values[discard:, :, j], 8.0)
        ax.set_ylim(lo, hi)  # the bulk of the kept chain; the burn-in may leave the axes
        ax.set_ylabel(f"{names[j]}\n[{units[j] or '-'}]", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[-1, 0].set_xlabel("step (dashed: end of the discarded burn-in)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def _corner_figure(samples: NDArray[np.float64], names: list[str], units: list[str],
                   title: str) -> Any:  # fmt: skip
    import corner
    import matplotlib.pyplot as plt

    labels = [f"{n} [{u}]" if u else n for n, u in zip(names, units, strict=True)]
    quiet = logging.getLogger()  # corner warns on the root logger about sparse contours
    size = max(5.5, 2.2 * len(names))
    fig = plt.figure(figsize=(size, size))
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        corner.corner(
            samples, labels=labels, quantiles=[0.05, 0.5, 0.95], show_titles=True,
            title_fmt=".4g", title_kwargs={"fontsize": 7}, label_kwargs={"fontsize": 8},
            fig=fig, plot_datapoints=samples.shape[0] <= 2000, max_n_ticks=3,
            range=[_bulk(samples[:, j], 6.0) for j in range(len(names))],
        )  # fmt: skip
    except Exception:
        plt.close(fig)
        raise
    finally:
        quiet.setLevel(level)
    for ax in fig.get_axes():
        ax.tick_params(labelsize=6)
    fig.suptitle(title, fontsize=10, y=1.02)
    return fig


def _diagnostics_table(stage: str, info: dict[str, Any], names: list[str]) -> str:
    tau = info.get("tau") or {}
    rhat = info.get("rhat") or {}
    ess = info.get("ess") or {}
    rows = [
        [esc(n), fmt(tau.get(n), "steps", 3), fmt(rhat.get(n), "", 3), fmt(ess.get(n), "", 3)]
        for n in names
    ]
    head = table(
        ["stage", "walkers", "steps", "burn-in discarded", "acceptance", "kept chain / tau",
         "seconds"],
        [[esc(stage), fmt(info.get("walkers")), fmt(info.get("steps")),
          fmt(info.get("discard"), "steps"), fmt(info.get("acceptance"), "", 3),
          fmt(info.get("tau_multiple"), "tau", 3), fmt(info.get("seconds"), "s", 3)]],
    )  # fmt: skip
    return head + table(
        ["parameter", "tau (integrated autocorrelation)", "R-hat (walkers as chains)",
         "bulk ESS"],
        rows,
    )  # fmt: skip


def render_chains(fit: dict[str, Any], folder: Path) -> tuple[str, str]:
    """HTML of every sampled stage of one fit; and a status.

    Parameters
    ----------
    fit : dict
        The parsed fit.json.
    folder : Path
        Its folder (holding ``chains.h5`` or the file named in
        ``mcmc.chains.file``).

    Returns
    -------
    html : str
    status : {"ok", "partial", "not run", "error"}
    """
    mcmc = fit.get("mcmc")
    if not isinstance(mcmc, dict):
        return note("not run: this fit has no MCMC (fit.json <code>mcmc</code> is null: "
                    "a <code>--no-mcmc</code> fit; its intervals are Laplace ones).",
                    "notrun"), "not run"  # fmt: skip
    stages = mcmc.get("stages") or {}
    chains_info = mcmc.get("chains") or {}
    chains = folder / str(chains_info.get("file") or "chains.h5")
    parts: list[str] = []
    note_text = mcmc.get("walker_chains_note")
    if note_text:
        parts.append(note(esc(note_text)))
    if not chains.is_file():
        parts.append(note(f"not run: the chains file {esc(chains)} is missing; only the "
                          "diagnostics stored in fit.json are shown.", "notrun"))  # fmt: skip
    status = "ok" if chains.is_file() else "partial"
    if not stages:
        parts.append(note("fit.json <code>mcmc.stages</code> is empty.", "warn"))
        return "\n".join(parts), "partial"
    for stage, info in stages.items():
        if not isinstance(info, dict):
            parts.append(note(f"stage {esc(stage)}: unreadable summary {esc(info)}", "error"))
            status = "partial"
            continue
        names = [str(n) for n in info.get("parameters") or []]
        units = [_unit_of(fit, n) for n in names]
        parts.append(f"<h4>stage {esc(stage)}: {esc(', '.join(names))}</h4>")
        parts.append(_diagnostics_table(stage, info, names))
        for w in info.get("warnings") or []:
            parts.append(note(esc(w), "warn"))
        if not chains.is_file() or not names:
            continue
        try:
            values, _ = read_stage_chain(chains, stage, names, [_scale_of(fit, n) for n in names])
        except ValueError as exc:
            parts.append(note(esc(exc), "error"))
            status = "partial"
            continue
        n_steps = values.shape[0]
        discard = int(info.get("discard") or 0)
        discard = min(max(discard, 0), max(n_steps - 1, 0))
        parts.append(embed_figure(
            _trace_figure(values, names, units, discard,
                          f"{fit.get('model', '?')}: {stage} stage, {values.shape[1]} walkers"),
            f"MCMC traces {fit.get('model')} {stage}",
            "Every walker's trace; the steps left of the dashed line are discarded as burn-in "
            "(vertical axes: the bulk of the kept steps, median +- 8 robust standard "
            "deviations).",
        ))  # fmt: skip
        kept = values[discard:].reshape(-1, len(names))
        thin = max(1, math.ceil(kept.shape[0] / MAX_CORNER_SAMPLES))
        samples = kept[::thin]
        samples = samples[np.all(np.isfinite(samples), axis=1)]
        spread = np.ptp(samples, axis=0) if samples.size else np.zeros(len(names))
        if samples.shape[0] <= len(names) or not np.all(spread > 0):
            parts.append(note(
                f"stage {esc(stage)}: no corner plot: {samples.shape[0]} kept samples, "
                "some parameter never moved.", "warn"))  # fmt: skip
            status = "partial"
            continue
        out_of_axes = np.zeros(samples.shape[0], bool)
        for j in range(len(names)):
            lo, hi = _bulk(samples[:, j], 6.0)
            out_of_axes |= (samples[:, j] < lo) | (samples[:, j] > hi)
        outside = int(out_of_axes.sum())
        try:
            fig = _corner_figure(samples, names, units,
                                 f"{fit.get('model', '?')}: {stage} stage posterior")  # fmt: skip
        except (ValueError, np.linalg.LinAlgError) as exc:
            parts.append(note(f"stage {esc(stage)}: corner plot failed: {esc(exc)}", "warn"))
            status = "partial"
            continue
        parts.append(embed_figure(
            fig, f"corner plot {fit.get('model')} {stage}",
            f"Posterior of the {stage} stage, conditional on the other groups at the joint "
            f"estimate ({samples.shape[0]} samples after burn-in, thinned by {thin}; axes span "
            f"the median +- 6 robust standard deviations, {outside} samples outside); lines at "
            "the 5, 50 and 95 % quantiles. The reported intervals add the other groups' "
            "uncertainty to first order (docs/identification.md).",
        ))  # fmt: skip
    return "\n".join(parts), status
