"""Residual analysis after a fit: whiteness, independence from the inputs,
and where in a test the misfit sits.

For every recording and output channel, :func:`residual_analysis` computes
the residual e = measured - simulated on the truly sampled points and tests
it as MATLAB's ``resid`` does (Ljung, *System Identification*, sec. 16.6):

- the autocorrelation r_e(k), k = 0..M, against the white-noise band
  +-z_{1-alpha/2} / sqrt(n), and the Ljung-Box statistic over k = 1..M;
- the cross-correlation r_eu(tau), tau = -M..M, with each input present
  (u_P, u_N, y_ref), against the band z_{1-alpha/2} sqrt(P / n),
  P = sum_k r_e(k) r_u(k) (the input is *not* prewhitened, as in
  ``resid``; a white residual gives P = 1 whatever the input);
- the RMS residual in each phase of the test (:mod:`.phases`) and the phase
  where it concentrates.

:func:`summarize` ranks channels of many reports by how far they are from
white; :func:`plot_residuals` draws one report.

>>> sim = Simulator(structure).simulate(params, Experiment.from_recording(rec))  # doctest: +SKIP
>>> report = residual_analysis(rec, sim.channels)                                 # doctest: +SKIP
>>> p_P = report.channels["p_P"]                                                  # doctest: +SKIP
>>> p_P.ljung_box.p_value, p_P.white, p_P.concentrated_in                         # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.campaign.model import INPUT_CHANNELS
from pneumafit.discovery.correlation import (
    LjungBox,
    autocorrelation,
    cross_correlation,
    cross_correlation_band,
    ljung_box,
    whiteness_band,
)
from pneumafit.discovery.phases import (
    PHASES,
    PhaseRules,
    label_phases,
    phase_interior,
    smoothed_rate,
    window_samples,
)
from pneumafit.errors import PneumafitInputError
from pneumafit.fileio import atomic_path
from pneumafit.models.layout import CHANNEL_UNITS
from pneumafit.models.layout import CHANNELS as SIMULATED_CHANNELS

if TYPE_CHECKING:
    from pneumafit.campaign.model import Recording

__all__ = [
    "DEFAULT_MAX_LAG",
    "OUTPUT_CHANNELS",
    "ChannelResiduals",
    "Correlation",
    "PhaseStats",
    "ResidualReport",
    "SummaryRow",
    "format_summary",
    "plot_residuals",
    "residual_analysis",
    "summarize",
]

#: Default largest lag (samples), ``resid``'s default (``residOptions.MaxLag``).
DEFAULT_MAX_LAG = 25
#: Measured channels a simulation can be compared with, in report order.
OUTPUT_CHANNELS: tuple[str, ...] = ("p_P", "p_N", "T_P", "T_N", "y", "v", "qm_P", "qm_N")
#: A phase enters the "concentrated in" choice only with at least this many
#: sampled points and this fraction of them: an RMS over a handful of samples
#: says little.
MIN_PHASE_SAMPLES = 20
MIN_PHASE_FRACTION = 0.02

_UNITS = dict(zip(SIMULATED_CHANNELS, CHANNEL_UNITS, strict=True))


@dataclass(frozen=True)
class Correlation:
    """A normalised correlation and its band.

    Attributes
    ----------
    lags : ndarray of int
        Lags (samples): 0..M for an autocorrelation, -M..M for a
        cross-correlation (positive: residual after input).
    values : ndarray
        Normalised correlation at each lag (dimensionless).
    band : float
        Half-width of the band (dimensionless): inside it the correlation is
        compatible with whiteness (autocorrelation) or independence
        (cross-correlation) at level alpha.
    tested : ndarray of bool
        Lags counted in :attr:`fraction_outside` (k >= 1 for an
        autocorrelation; for a cross-correlation every lag in open loop, tau
        >= 0 in closed loop, where feedback correlates the residual with
        later inputs: Ljung sec. 16.6).
    fraction_outside : float
        Fraction of the tested lags with |value| > band; alpha is expected
        for a white (independent) residual.
    sample_interval : float
        Median time between the samples (s): lag k is k times this.
    """

    lags: NDArray[np.int64]
    values: NDArray[np.float64]
    band: float
    tested: NDArray[np.bool_]
    fraction_outside: float
    sample_interval: float

    @property
    def lag_times(self) -> NDArray[np.float64]:
        """Lags in seconds (approximate for uneven sampling)."""
        return self.lags * self.sample_interval


@dataclass(frozen=True)
class PhaseStats:
    """Residual of one channel within one phase of the test.

    Attributes
    ----------
    phase : str
        One of :data:`pneumafit.discovery.phases.PHASES`.
    n : int
        Sampled points in the phase.
    rms : float
        Root-mean-square residual (channel unit); NaN when n = 0.
    mean : float
        Mean residual (channel unit); NaN when n = 0.
    share : float
        Fraction of the channel's sum of squared residuals in this phase.
    rate_rms : float
        Root-mean-square rate of change of the residual (channel unit per s),
        fitted over the phase rules' ``smoothing`` window, over the samples
        at least half a window inside the phase (NaN when there are none).
    """

    phase: str
    n: int
    rms: float
    mean: float
    share: float
    rate_rms: float


@dataclass(frozen=True)
class ChannelResiduals:
    """Residual analysis of one channel of one recording.

    Attributes
    ----------
    channel, unit : str
        Channel name and its SI unit.
    time : ndarray
        Times of the truly sampled points (s).
    residual : ndarray
        Measured minus simulated at those points (channel unit).
    n : int
        Number of sampled points.
    mean, rms, std : float
        Mean, root-mean-square and standard deviation of the residual
        (channel unit). The correlations remove the mean (e.g. a pressure
        sensor's offset); it is reported here.
    autocorrelation : Correlation
        r_e(k), k = 0..M, with the white-noise band.
    ljung_box : LjungBox
        Q over k = 1..M and its p-value.
    cross_correlation : dict of str to Correlation
        Input name -> r_eu(tau), tau = -M..M, with the independence band.
        Inputs that are constant over the sampled points are left out.
    phases : dict of str to PhaseStats
        Every phase of :data:`PHASES`, including empty ones.
    concentrated_in : str
        Phase with the largest RMS residual among phases with enough points
        (:data:`MIN_PHASE_SAMPLES` and :data:`MIN_PHASE_FRACTION`).
    changes_in : str
        Phase with the largest RMS *rate* of the residual, among the same
        phases. A simulation's error accumulates: a term missing while a
        chamber fills leaves an error that persists into the relaxation, so
        the level says where the error *is*, the rate where it is *made*.
    white : bool
        Ljung-Box does not reject whiteness at level alpha (p >= alpha).
    """

    channel: str
    unit: str
    time: NDArray[np.float64]
    residual: NDArray[np.float64]
    n: int
    mean: float
    rms: float
    std: float
    autocorrelation: Correlation
    ljung_box: LjungBox
    cross_correlation: dict[str, Correlation]
    phases: dict[str, PhaseStats]
    concentrated_in: str
    changes_in: str
    white: bool

    @property
    def violation(self) -> float:
        """Standardised Ljung-Box statistic (Q - M) / sqrt(2 M): ~N(0, 1) when white."""
        return self.ljung_box.violation


@dataclass(frozen=True)
class ResidualReport:
    """Residual analysis of one recording.

    Attributes
    ----------
    recording : str
        File name of the recording.
    kind : str
        Recording kind (charge, discharge, flow, step, free).
    alpha : float
        Significance level of the bands and of :attr:`ChannelResiduals.white`.
    max_lag : int
        Largest lag M requested (samples); a channel with few points uses
        at most n // 4.
    time : ndarray
        All sample times of the recording (s).
    phase_labels : ndarray of str
        Phase of every sample (:func:`pneumafit.discovery.phases.label_phases`).
    closed_loop : bool
        The recording declares a controller (its inputs depend on the output).
    channels : dict of str to ChannelResiduals
        Analysed channels, in :data:`OUTPUT_CHANNELS` order.
    """

    recording: str
    kind: str
    alpha: float
    max_lag: int
    time: NDArray[np.float64]
    phase_labels: NDArray[np.str_]
    closed_loop: bool
    channels: dict[str, ChannelResiduals]


def _simulated(simulated: Mapping[str, ArrayLike] | Any) -> Mapping[str, ArrayLike]:
    if hasattr(simulated, "channels") and not isinstance(simulated, Mapping):
        return simulated.channels  # a Simulation
    if not isinstance(simulated, Mapping):
        raise TypeError(
            "residual analysis: simulated_channels: expected a mapping of channel name to "
            f"array (Simulation.channels), found {type(simulated).__name__}"
        )
    return simulated


def _correlation(
    lags: NDArray[np.int64],
    values: NDArray[np.float64],
    band: float,
    tested: NDArray[np.bool_],
    dt: float,
) -> Correlation:
    outside = np.abs(values[tested]) > band
    frac = float(outside.mean()) if outside.size and np.all(np.isfinite(values)) else math.nan
    return Correlation(lags, values, float(band), tested, frac, dt)


def _rms(values: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan


def _phase_stats(
    residual: NDArray[np.float64],
    rate: NDArray[np.float64],
    interior: NDArray[np.bool_],
    labels: NDArray[np.str_],
) -> tuple[dict[str, PhaseStats], str, str]:
    total = float(residual @ residual)
    out: dict[str, PhaseStats] = {}
    n = residual.size
    for phase in PHASES:
        inside = labels == phase
        part = residual[inside]
        if part.size:
            ss = float(part @ part)
            out[phase] = PhaseStats(
                phase=phase,
                n=int(part.size),
                rms=math.sqrt(ss / part.size),
                mean=float(part.mean()),
                share=ss / total if total > 0.0 else math.nan,
                rate_rms=_rms(rate[inside & interior]),
            )
        else:
            out[phase] = PhaseStats(phase, 0, math.nan, math.nan, 0.0, math.nan)
    need = max(MIN_PHASE_SAMPLES, math.ceil(MIN_PHASE_FRACTION * n))
    candidates = [s for s in out.values() if s.n >= need] or [s for s in out.values() if s.n]
    level = max(candidates, key=lambda s: s.rms).phase
    with_rate = [s for s in candidates if math.isfinite(s.rate_rms)] or candidates
    change = max(with_rate, key=lambda s: s.rate_rms).phase
    return out, level, change


def _channel(
    name: str,
    recording: Recording,
    simulated: NDArray[np.float64],
    labels: NDArray[np.str_],
    max_lag: int,
    alpha: float,
    rules: PhaseRules,
) -> ChannelResiduals:
    where = f"residual analysis of {recording.file or recording.kind!r}, channel {name}"
    mask = recording.mask.get(name, np.ones(recording.time.size, dtype=bool))
    if simulated.shape != recording.time.shape:
        raise PneumafitInputError(
            f"{where}: expected {recording.time.size} simulated samples like the recording, "
            f"found shape {simulated.shape}"
        )
    if not np.all(np.isfinite(simulated[mask])):
        raise PneumafitInputError(
            f"{where}: simulated values: expected finite values, found NaN or infinity "
            "(did it fail? check Simulation.status and .message)"
        )
    e = recording.channels[name][mask] - simulated[mask]
    t = recording.time[mask]
    n = e.size
    if n < 8:
        raise PneumafitInputError(f"{where}: expected at least 8 sampled points, found {n}")
    m = max(1, min(max_lag, n // 4))
    dt = float(np.median(np.diff(t)))
    acf = autocorrelation(e, m)
    band = whiteness_band(n, alpha)
    lags = np.arange(m + 1)
    auto = _correlation(lags, acf, band, lags >= 1, dt)
    lb = ljung_box(e, m)

    cross: dict[str, Correlation] = {}
    ccf_lags = np.arange(-m, m + 1)
    tested = ccf_lags >= 0 if recording.controller is not None else np.ones(2 * m + 1, bool)
    for inp in INPUT_CHANNELS:
        if inp not in recording.channels:
            continue
        u = recording.channels[inp][mask]
        if np.ptp(u) == 0.0:
            continue
        values = cross_correlation(e, u, m)
        ccf_band = cross_correlation_band(acf, autocorrelation(u, m), n, alpha)
        cross[inp] = _correlation(ccf_lags, values, ccf_band, tested, dt)

    rate = smoothed_rate(t, e, rules.smoothing)
    own = labels[mask]
    interior = phase_interior(own, window_samples(t, rules.smoothing) // 2)
    phases, concentrated, changes = _phase_stats(e, rate, interior, own)
    return ChannelResiduals(
        channel=name,
        unit=_UNITS.get(name, ""),
        time=t,
        residual=e,
        n=n,
        mean=float(e.mean()),
        rms=float(math.sqrt(e @ e / n)),
        std=float(e.std()),
        autocorrelation=auto,
        ljung_box=lb,
        cross_correlation=cross,
        phases=phases,
        concentrated_in=concentrated,
        changes_in=changes,
        white=bool(lb.p_value >= alpha),
    )


def residual_analysis(
    recording: Recording,
    simulated_channels: Mapping[str, ArrayLike] | Any,
    *,
    channels: Sequence[str] | None = None,
    max_lag: int | None = None,
    alpha: float = 0.01,
    phase_rules: PhaseRules | None = None,
) -> ResidualReport:
    """Analyse the residuals of one recording against one simulation of it.

    Parameters
    ----------
    recording : Recording
        The measured test (SI units). Only truly sampled points
        (``recording.mask``) enter the statistics; a channel sampled on a
        coarser grid is analysed on its own samples (lag k = k of them).
    simulated_channels : mapping of str to array_like, or Simulation
        Simulated channels at the recording's sample times, e.g.
        ``Simulator(...).simulate(params, Experiment.from_recording(rec)).channels``.
    channels : sequence of str, optional
        Channels to analyse; default every channel of :data:`OUTPUT_CHANNELS`
        both recorded and simulated. Inputs (u_P, u_N, y_ref) are not outputs.
    max_lag : int, optional
        Largest lag M (samples), default :data:`DEFAULT_MAX_LAG` (25, as
        ``resid``); capped at n // 4 for a channel of n points. Note that at
        1 kHz 25 lags span 25 ms, short beside the pneumatic time constants:
        a slow misfit shows as r(k) near 1 at every lag.
    alpha : float
        Significance level of the bands and of the Ljung-Box decision
        (default 0.01: ``resid``'s 99 % region).
    phase_rules : PhaseRules, optional
        Thresholds of the phase labelling.

    Returns
    -------
    ResidualReport

    Raises
    ------
    PneumafitInputError
        A requested channel that is not recorded or not simulated, simulated
        arrays of the wrong length or with NaN (a failed simulation), fewer
        than 8 sampled points, or a bad ``max_lag``/``alpha``.
    """
    sim = _simulated(simulated_channels)
    where = f"residual analysis of {recording.file or recording.kind!r}"
    if not 0.0 < alpha < 1.0:
        raise PneumafitInputError(f"{where}: alpha: expected a level in (0, 1), found {alpha!r}")
    lag = DEFAULT_MAX_LAG if max_lag is None else max_lag
    if isinstance(lag, bool) or not isinstance(lag, int | np.integer) or lag < 1:
        raise PneumafitInputError(f"{where}: max_lag: expected an integer >= 1, found {max_lag!r}")
    if channels is None:
        names = [c for c in OUTPUT_CHANNELS if c in recording.channels and c in sim]
        if not names:
            raise PneumafitInputError(
                f"{where}: no channel is both recorded and simulated (recorded: "
                f"{sorted(recording.channels)}, simulated: {sorted(sim)})"
            )
    else:
        names = list(channels)
        for name in names:
            if name not in recording.channels or name not in sim:
                missing = "recorded" if name not in recording.channels else "simulated"
                raise PneumafitInputError(
                    f"{where}: channel {name!r}: expected it {missing}, found none"
                )
    rules = phase_rules if phase_rules is not None else PhaseRules()
    labels = label_phases(recording, rules)
    results = {
        name: _channel(
            name, recording, np.asarray(sim[name], dtype=float), labels, int(lag), alpha, rules
        )
        for name in names
    }
    return ResidualReport(
        recording=recording.file,
        kind=recording.kind,
        alpha=float(alpha),
        max_lag=int(lag),
        time=recording.time,
        phase_labels=labels,
        closed_loop=recording.controller is not None,
        channels=results,
    )


# ---------------------------------------------------------------------- summary
@dataclass(frozen=True)
class SummaryRow:
    """One channel of one recording in a whiteness ranking.

    Attributes
    ----------
    recording, channel, unit : str
    n : int
        Sampled points.
    rms, mean : float
        Residual RMS and mean (channel unit).
    violation : float
        Standardised Ljung-Box statistic (Q - M) / sqrt(2 M) (the ranking key).
    p_value : float
        Ljung-Box p-value.
    acf_outside : float
        Fraction of autocorrelation lags outside the white-noise band.
    ccf_outside : float
        Largest fraction of tested cross-correlation lags outside the band,
        over the inputs (NaN with no varying input).
    concentrated_in : str
        Phase with the largest RMS residual.
    white : bool
        Ljung-Box does not reject whiteness at the report's alpha.
    """

    recording: str
    channel: str
    unit: str
    n: int
    rms: float
    mean: float
    violation: float
    p_value: float
    acf_outside: float
    ccf_outside: float
    concentrated_in: str
    white: bool


def summarize(reports: ResidualReport | Iterable[ResidualReport]) -> list[SummaryRow]:
    """Rank every channel of every report, furthest from white first.

    The key is the standardised Ljung-Box statistic (Q - M) / sqrt(2 M),
    comparable across channels with different lag counts and still ordered
    where p-values underflow to 0.

    Parameters
    ----------
    reports : ResidualReport or iterable of them

    Returns
    -------
    list of SummaryRow
    """
    if isinstance(reports, ResidualReport):
        reports = [reports]
    rows = []
    for report in reports:
        for ch in report.channels.values():
            ccf = [c.fraction_outside for c in ch.cross_correlation.values()]
            rows.append(
                SummaryRow(
                    recording=report.recording,
                    channel=ch.channel,
                    unit=ch.unit,
                    n=ch.n,
                    rms=ch.rms,
                    mean=ch.mean,
                    violation=ch.violation,
                    p_value=ch.ljung_box.p_value,
                    acf_outside=ch.autocorrelation.fraction_outside,
                    ccf_outside=max(ccf) if ccf else math.nan,
                    concentrated_in=ch.concentrated_in,
                    white=ch.white,
                )
            )
    return sorted(rows, key=lambda r: -r.violation if math.isfinite(r.violation) else math.inf)


def format_summary(rows: Sequence[SummaryRow]) -> str:
    """A plain-text table of :func:`summarize` rows (one line per channel)."""
    header = (
        f"{'recording':<22} {'channel':<7} {'rms':>11} {'unit':<8} {'LB z':>9} {'p':>9} "
        f"{'acf out':>7} {'ccf out':>7} {'worst phase':<11} white"
    )
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(
            f"{r.recording[:22]:<22} {r.channel:<7} {r.rms:>11.4g} {r.unit:<8} "
            f"{r.violation:>9.1f} {r.p_value:>9.2g} {r.acf_outside:>7.0%} "
            f"{r.ccf_outside:>7.0%} {r.concentrated_in:<11} {'yes' if r.white else 'no'}"
        )
    return "\n".join(lines)


# ---------------------------------------------------------------------- plots
_PHASE_COLOURS = {
    "motion": "tab:blue",
    "filling": "tab:red",
    "emptying": "tab:green",
    "relaxation": "tab:orange",
    "rest": "none",
}


def plot_residuals(
    report: ResidualReport,
    path: str | os.PathLike[str],
    *,
    channels: Sequence[str] | None = None,
) -> Path:
    """Draw a residual report: per channel, the residual over time on the
    phases, its autocorrelation and its cross-correlations with the bands.

    Parameters
    ----------
    report : ResidualReport
    path : str or os.PathLike
        Output file; the format follows the suffix (``.png``, ``.pdf``,
        ``.svg``). Written atomically (no half-written file on failure).
    channels : sequence of str, optional
        Channels to draw; default all of the report's.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(channels) if channels is not None else list(report.channels)
    unknown = [c for c in names if c not in report.channels]
    if unknown or not names:
        raise PneumafitInputError(
            f"plot_residuals: channels: expected some of {list(report.channels)}, found {names}"
        )
    target = Path(path)
    fmt = target.suffix.lstrip(".").lower() or "png"
    fig, axes = plt.subplots(len(names), 3, figsize=(15, 3.2 * len(names)), squeeze=False)
    try:
        for row, name in zip(axes, names, strict=True):
            _plot_channel(row, report, report.channels[name])
        fig.suptitle(f"Residuals of {report.recording} ({report.kind}), alpha = {report.alpha:g}")
        fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.35 / fig.get_figheight()))
        with atomic_path(target) as tmp:
            fig.savefig(tmp, format=fmt, dpi=110)
    finally:
        plt.close(fig)
    return target


def _plot_channel(axes: Any, report: ResidualReport, ch: ChannelResiduals) -> None:
    ax_e, ax_acf, ax_ccf = axes
    t = report.time
    labels = report.phase_labels
    # shade the phases as runs of equal labels
    edges = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [t.size]])
    seen: set[str] = set()
    for a, b in zip(starts, ends, strict=True):
        phase = str(labels[a])
        colour = _PHASE_COLOURS[phase]
        if colour == "none":
            continue
        ax_e.axvspan(
            t[a],
            t[b - 1],
            color=colour,
            alpha=0.12,
            lw=0,
            label=phase if phase not in seen else None,
        )
        seen.add(phase)
    ax_e.plot(ch.time, ch.residual, lw=0.6, color="k")
    ax_e.set_xlabel("time [s]")
    ax_e.set_ylabel(f"{ch.channel} residual [{ch.unit}]")
    ax_e.set_title(
        f"rms {ch.rms:.3g} {ch.unit}, mean {ch.mean:.3g}; largest in {ch.concentrated_in}, "
        f"made in {ch.changes_in}"
    )
    if seen:
        ax_e.legend(loc="best", fontsize=7)

    acf = ch.autocorrelation
    ax_acf.bar(acf.lags, acf.values, width=0.6, color="tab:gray")
    ax_acf.axhspan(-acf.band, acf.band, color="tab:blue", alpha=0.15)
    ax_acf.set_xlabel("lag [samples]")
    ax_acf.set_ylabel("autocorrelation")
    lb = ch.ljung_box
    ax_acf.set_title(f"Ljung-Box Q = {lb.statistic:.3g} (M = {lb.lags}), p = {lb.p_value:.2g}")

    if not ch.cross_correlation:
        ax_ccf.set_axis_off()
        ax_ccf.set_title("no varying input")
        return
    for (inp, cc), colour in zip(
        ch.cross_correlation.items(), ("tab:red", "tab:green", "tab:purple"), strict=False
    ):
        ax_ccf.plot(cc.lags, cc.values, marker=".", lw=0.8, color=colour, label=inp)
        ax_ccf.hlines([-cc.band, cc.band], cc.lags[0], cc.lags[-1], colors=colour, ls="--", lw=0.8)
    ax_ccf.set_xlabel("lag [samples] (> 0: residual after input)")
    ax_ccf.set_ylabel("cross-correlation")
    ax_ccf.legend(loc="best", fontsize=7)
