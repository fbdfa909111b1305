"""Does the fit reach the noise? Residuals over sensor noise, per recording, channel and phase.

A fit whose model cannot follow the rig still ends with numbers: this module
says, where the user looks first, whether those numbers can be trusted.

Noise, estimated from the data alone (never from the fit's residual, which
absorbs every misfit into "noise"): in the *quiet windows* of a recording,
windows of :data:`WINDOW` s in which every recorded command is constant
(rest phases of charge/discharge and step tests, the levels of flow tests),
the signal is smooth on the window's scale (thermal relaxation takes
0.7-25 s, leakage longer), so a quadratic fitted per window leaves the
sensor noise. The per-window variances (n - 3 degrees of freedom) are pooled
by their median, corrected by the chi-square median factor
(1 - 2 / (9 k))^3 so that a window caught in a transient cannot inflate it.
Quantised readings (an encoder) get at least the quantisation noise
q / sqrt(12). A recording without three quiet windows for a channel takes
the pooled estimate of the same channel from the campaign's other
recordings (same sensor).

Residual: data minus the model replayed at the reported values on every
sample (:func:`pneumafit.identification.staged.replay_residuals`), pressure
residuals with their mean removed (the fit profiles one sensor offset per
recording). The ratio RMS / noise is 1 for a model that follows the rig;
above :data:`THRESHOLD` the fit "does not reach the noise", and the phases
(``rest``, ``filling``, ``motion``, ``flow``) that fail are named.

Where a step test does not reach the noise, the fit also says where the
model's piston came to rest against the measured one (:func:`rest_offsets`):
a piston held by static friction stops where its speed first falls to zero
with the drive below the breakaway force, a position that depends on the
friction law and on the whole motion before it. A stop a millimetre away
changes the chamber volumes at rest and, in closed loop, the controller's
command there (kp times the offset: 0.06 V per mm at 60 V/m), which near
the valve's null moves the pressures at rest by tens of kPa over a second
(measured on the mixed truth's held-out step test,
``docs/identification.md``, "Where held-out step tests fail").

Besides the residuals, :class:`FitQuality` collects the other reasons not to
trust a result: an estimate at a bound, an estimate outside its own 90 %
interval, and MCMC chains shorter than 50 autocorrelation times or with
R-hat above 1.01.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.identification.noise import detect_resolution
from pneumafit.identification.parameters import CONSTRAINTS
from pneumafit.identification.problem import OFFSET_LIMIT, QUANTITIES

__all__ = [
    "THRESHOLD",
    "WINDOW",
    "ChannelQuality",
    "FitQuality",
    "RestOffset",
    "assess_residuals",
    "estimate_noise",
    "one_recording_caveat",
    "parameter_flags",
    "phases",
    "rest_offsets",
    "undetermined_problems",
    "zeros_phrase",
]

#: RMS residual over noise above which a recording "does not reach the noise".
#: A model that follows the rig gives 1; the issue's measured failures were
#: 10-200. 3 leaves room for a noise estimate off by tens of percent and for
#: small unmodelled details (the flow meter's lag), and still flags a misfit
#: that is a few times the noise.
THRESHOLD = 3.0
#: A fit recording whose residual the joint refinement multiplies by more
#: than this (and takes above :data:`THRESHOLD`) was given up for the others
#: (:meth:`FitQuality.given_up`). Twice: the staged estimates are each
#: stage's optimum with the other groups held, so the joint refinement
#: moves every recording's ratio, and a recording that stays below 3x is
#: not named at all. Measured (convection, ``--no-mcmc --seed 1``): on
#: ``data/demo-clean`` no fit recording rose by more than 2 % (step_2 55.4x
#: -> 56.3x), on ``data/demo`` (an undeclared leak) by at most 1.4 times
#: (step_2 90x -> 123x); a table-valve truth whose joint fit left its
#: discharge test at 12.1x had it at 5.5x staged (docs/identification.md).
TRADE_FACTOR = 2.0
#: Duration (s) of the quiet windows of :func:`estimate_noise`.
WINDOW = 0.05
#: Fewest and most samples in one window.
MIN_WINDOW, MAX_WINDOW = 9, 101
#: Position rate (m/s) above which a step-test sample counts as ``motion``.
MOTION_SPEED = 5e-3
#: Time (s) a phase change is extended by (valve closing, stop of the piston).
PHASE_MARGIN = 0.05
#: R-hat above which a chain is called unreliable (issue: <= 1.01 to stop).
MAX_RHAT = 1.01
#: Chain length in autocorrelation times below which it is unreliable.
MIN_TAU = 50.0
#: A positive parameter whose 90 % interval's ends are further apart than
#: this factor (or whose interval reaches 0) is not determined by the fit
#: recordings (:func:`undetermined_problems`): its order of magnitude is
#: open. Measured on fits of the virtual rig (2026-12-05, ``--no-mcmc``):
#: on data/demo (MCMC) and on the mixed truth's demo plan every interval
#: spans less than a factor 7 (heat_area_ends, 6.8); on the novel truth's
#: sparse-long plan the Stribeck velocity spans its range [1e-4, 1] m/s,
#: and with ``--valve map`` xi [0.0015, 0.68] and friction_coulomb [0.072,
#: 278] N, reported as 0.032 and 4.5 N with an empty flag column.
UNDETERMINED_FACTOR = 10.0
#: A parameter that may be negative is not determined when its 90 %
#: interval covers more than this share of its range.
UNDETERMINED_SHARE = 0.5

PHASES = ("rest", "filling", "motion", "flow")
#: Shortest rest phase (s) of a step test whose rest position is compared
#: (:func:`rest_offsets`): long enough for the median to see past the
#: encoder's quantisation and the phase margin, shorter than the rests
#: between set-points of the virtual rig's plans (0.3 s sparse, 0.6-1.2 s demo).
MIN_REST = 0.2


def _commands(rec: Recording) -> list[NDArray[np.float64]]:
    return [np.asarray(v, float) for k, v in rec.channels.items() if k.startswith("u_")]


def _quiet_windows(rec: Recording) -> list[NDArray[np.int64]]:
    """Sample windows of :data:`WINDOW` s in which every command is constant."""
    n = rec.n_samples
    rate = rec.sample_rate if n > 1 else 1.0
    w = int(min(MAX_WINDOW, max(MIN_WINDOW, round(WINDOW * rate))))
    if n < w:
        return []
    cmds = _commands(rec)
    out = []
    for a in range(0, n - w + 1, w):
        sl = slice(a, a + w)
        quiet = True
        for u in cmds:
            span = float(np.ptp(u)) if u.size else 0.0
            if float(np.ptp(u[sl])) > 1e-6 + 0.01 * span:
                quiet = False
                break
        if quiet:
            out.append(np.arange(a, a + w))
    return out


def _window_variances(
    time: NDArray[np.float64], values: NDArray[np.float64], windows: Iterable[NDArray[np.int64]]
) -> tuple[list[float], int]:
    """Residual variance of a quadratic in time fitted to each window (windows
    with a non-finite value left out), and the residual's degrees of freedom
    (window length - 3) of the last one.

    Windows of one length are fitted together: the least squares of each is
    solved through the stacked QR factorisation of its centred, scaled
    Vandermonde matrix (the residual x - Q Q^T x is what ``np.polyfit``'s
    would be, to rounding; tests/identification/test_quality.py checks
    it against a loop of ``np.polyfit``).
    """
    wins = [np.asarray(w) for w in windows]
    var = np.full(len(wins), np.nan)
    for size in sorted({w.size for w in wins}):
        rows = [i for i, w in enumerate(wins) if w.size == size]
        idx = np.stack([wins[i] for i in rows])
        x = values[idx]
        ok = np.all(np.isfinite(x), axis=1)
        if not ok.any():
            continue
        x, t = x[ok], time[idx[ok]]
        t = t - t.mean(axis=1, keepdims=True)
        half = np.max(np.abs(t), axis=1, keepdims=True)
        t = t / np.where(half > 0.0, half, 1.0)
        q, _r = np.linalg.qr(np.stack([t * t, t, np.ones_like(t)], axis=2))
        r = x - np.einsum("mij,mj->mi", q, np.einsum("mij,mi->mj", q, x))
        var[np.asarray(rows)[ok]] = np.sum(r * r, axis=1) / (size - 3)
    kept = [i for i in range(len(wins)) if np.isfinite(var[i])]
    k = wins[kept[-1]].size - 3 if kept else 0
    return [float(var[i]) for i in kept], k


def estimate_noise(
    rec: Recording, channel: str, windows: Sequence[NDArray[np.int64]] | None = None
) -> tuple[float | None, int]:
    """Sensor noise (SI standard deviation) of one channel from its quiet windows.

    Returns
    -------
    sigma : float or None
        None when fewer than three quiet windows exist.
    n_windows : int
    """
    if channel not in rec.channels:
        return None, 0
    wins = _quiet_windows(rec) if windows is None else windows
    values = np.asarray(rec.channels[channel], float)
    var, k = _window_variances(np.asarray(rec.time, float), values, wins)
    if len(var) < 3:
        return None, len(var)
    median_factor = (1.0 - 2.0 / (9.0 * k)) ** 3
    sigma = math.sqrt(float(np.median(var)) / median_factor)
    q = detect_resolution(values)
    if q is not None:
        sigma = max(sigma, q / math.sqrt(12.0))
    return sigma, len(var)


def noise_estimates(
    campaign: Campaign, kinds: Sequence[str] | None = None
) -> dict[tuple[str, str], float | None]:
    """Each recording's own sensor-noise estimate, per measured channel.

    :func:`estimate_noise` on the recording's quiet windows (None with fewer
    than three) for every channel but the commands (``u_P``, ``u_N``,
    ``y_ref``), of the recordings of ``kinds`` (default: all). The one noise
    estimator of the workbench: the fit's quality and discovery use it.

    Returns
    -------
    dict of (recording file, channel) to float or None
        Noise standard deviation in the channel's SI unit.
    """
    out: dict[tuple[str, str], float | None] = {}
    for rec in campaign.recordings:
        if kinds is not None and rec.kind not in kinds:
            continue
        windows = _quiet_windows(rec)
        for ch in rec.channels:
            if not ch.startswith("u_") and ch != "y_ref":
                out[(rec.file, ch)] = estimate_noise(rec, ch, windows)[0]
    return out


def campaign_noise(campaign: Campaign, kinds: Sequence[str] | None = None) -> dict[str, float]:
    """Sensor noise per channel: the median of the recordings' own estimates.

    The pooled estimate of a sensor (:func:`noise_estimates`; recordings
    without three quiet windows for it left out), in the channel's SI unit.
    """
    found: dict[str, list[float]] = {}
    for (_file, ch), sigma in noise_estimates(campaign, kinds).items():
        if sigma is not None:
            found.setdefault(ch, []).append(sigma)
    return {ch: float(np.median(v)) for ch, v in found.items()}


def phases(rec: Recording) -> NDArray[np.str_]:
    """Phase of every sample: ``flow``, ``filling``/``rest`` or ``motion``/``rest``."""
    n = rec.n_samples
    t = np.asarray(rec.time, float)
    out = np.full(n, "rest", dtype="<U7")
    if rec.kind == "flow":
        out[:] = "flow"
        return out
    if rec.kind in ("charge", "discharge"):
        u = rec.channels.get(f"u_{rec.chamber}")
        if u is None:
            return out
        u = np.asarray(u, float)
        rest = float(np.median(u))
        active = np.abs(u - rest) > 0.05
        label = "filling"
    else:
        y = rec.channels.get("y")
        if y is None or n < 3:
            return out
        # position rate over ~20 ms, robust to the encoder's quantisation
        span = max(1, round(0.01 * rec.sample_rate))
        yy = np.asarray(y, float)
        v = np.zeros(n)
        v[span:-span] = (yy[2 * span :] - yy[: -2 * span]) / (t[2 * span :] - t[: -2 * span])
        active = np.abs(v) > MOTION_SPEED
        label = "motion"
    if np.any(active):
        # extend each active stretch by PHASE_MARGIN on its end (closing, stopping)
        last = np.where(active, t, -np.inf)
        last = np.maximum.accumulate(last)
        active = active | ((t - last) <= PHASE_MARGIN)
    out[active] = label
    return out


@dataclass(frozen=True)
class RestOffset:
    """The model's piston against the measured one in one rest phase of a step test.

    Attributes
    ----------
    recording : str
    start, end : float
        The rest phase (s, recording time; :func:`phases`).
    measured, model : float
        Median positions over the phase (m).
    command : float or None
        Median of the model's valve-P command minus the recorded one over the
        phase (V): in closed loop the controller's answer to the offset
        (-kp times it for a PD law), 0 in open loop; None without recorded
        or simulated commands.
    """

    recording: str
    start: float
    end: float
    measured: float
    model: float
    command: float | None

    @property
    def offset(self) -> float:
        """Model minus measured position (m)."""
        return self.model - self.measured

    def describe(self) -> str:
        """``step_4.csv +2.03 mm at 1.4-2.5 s, command -0.12 V``."""
        tail = f", command {self.command:+.2f} V" if self.command is not None else ""
        return (
            f"{self.recording} {self.offset * 1e3:+.2f} mm at {self.start:.1f}-{self.end:.1f} s"
            + tail
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "recording": self.recording, "start": self.start, "end": self.end,
            "measured": self.measured, "model": self.model, "offset": self.offset,
            "command": self.command,
        }  # fmt: skip


def rest_offsets(rec: Recording, simulated: Mapping[str, NDArray[np.float64]]) -> list[RestOffset]:
    """Where the model's piston rests against the measured one, per rest phase.

    Parameters
    ----------
    rec : Recording
        A step test with a measured position ``y``.
    simulated : mapping of str to ndarray
        The model's channels on every sample of ``rec`` (SI; the replay's
        ``RecordingReplay.simulated``): ``y`` and, when present, ``u_P``.

    Returns
    -------
    list of RestOffset
        One per rest phase (:func:`phases`) of at least :data:`MIN_REST` s
        in which both positions are finite, in time order; empty for other
        kinds of test or without positions.
    """
    if rec.kind != "step" or "y" not in rec.channels or "y" not in simulated:
        return []
    t = np.asarray(rec.time, float)
    y = np.asarray(rec.channels["y"], float)
    ym = np.asarray(simulated["y"], float)
    u = rec.channels.get("u_P")
    um = simulated.get("u_P")
    rest = phases(rec) == "rest"
    # contiguous rest runs: [starts[i], ends[i])
    edges = np.diff(np.concatenate(([0], rest.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out = []
    for a, b in zip(starts, ends, strict=True):
        if t[b - 1] - t[a] < MIN_REST:
            continue
        good = np.isfinite(y[a:b]) & np.isfinite(ym[a:b])
        if not np.any(good):
            continue
        command = None
        if u is not None and um is not None:
            du = np.asarray(um[a:b], float) - np.asarray(u[a:b], float)
            du = du[np.isfinite(du)]
            command = float(np.median(du)) if du.size else None
        out.append(
            RestOffset(
                recording=rec.file,
                start=float(t[a]),
                end=float(t[b - 1]),
                measured=float(np.median(y[a:b][good])),
                model=float(np.median(ym[a:b][good])),
                command=command,
            )
        )
    return out


@dataclass
class ChannelQuality:
    """Residual against noise for one recording and channel.

    Attributes
    ----------
    recording, role, kind, channel : str
    fitted : bool
        The channel is in the fit's likelihood (else compared for validation).
    n : int
        Samples compared.
    rms : float
        RMS residual (SI, pressure offset removed).
    noise : float or None
        Sensor noise (SI standard deviation), None when it could not be estimated.
    noise_source : str
        ``rest`` (this recording's quiet windows) or ``campaign`` (the same
        channel in other recordings) or ``none``.
    phases : dict of str to dict
        Per phase: ``n``, ``rms`` and ``ratio``.
    """

    recording: str
    role: str
    kind: str
    channel: str
    fitted: bool
    n: int
    rms: float
    noise: float | None
    noise_source: str
    phases: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def ratio(self) -> float | None:
        """RMS residual over noise (None without a noise estimate)."""
        if self.noise is None:
            return None
        return self.rms / self.noise if self.noise > 0 else math.inf

    @property
    def fails(self) -> bool:
        r = self.ratio
        return r is not None and r > THRESHOLD

    def failing_phases(self) -> list[str]:
        return [p for p, v in self.phases.items() if (v.get("ratio") or 0.0) > THRESHOLD]

    def as_dict(self) -> dict[str, Any]:
        return {
            "recording": self.recording, "role": self.role, "kind": self.kind,
            "channel": self.channel, "fitted": self.fitted, "n": self.n, "rms": self.rms,
            "noise": self.noise, "noise_source": self.noise_source, "ratio": self.ratio,
            "reaches_noise": not self.fails, "phases": self.phases,
        }  # fmt: skip


@dataclass
class FitQuality:
    """Everything that says whether a fit can be trusted.

    Attributes
    ----------
    channels : list of ChannelQuality
    at_bounds : list of str
        ``"name (lower bound)"`` for every free estimate at a bound,
        ``"name (= other: meaning)"`` for one on a :data:`CONSTRAINTS` partner.
    outside_interval : list of str
        Estimates outside their own 90 % interval (a defect).
    unreliable : list of str
        Parameters whose chain is shorter than 50 tau or has R-hat > 1.01.
    unconverged : list of str
        Least-squares stages that stopped at their iteration limit.
    not_identified : list of str
        Parameter groups no fit recording informs, held at the rig's
        defaults (e.g. ``"friction (no fit step test)"``): the fit reports,
        exports and designs on values it did not estimate.
    undetermined : list of str
        Free parameters whose 90 % interval leaves their order of magnitude
        open (:func:`undetermined_problems`), each with its value and
        interval. A caveat (:meth:`caveats`): the model's predictions may
        not depend on them, but their values mean little on their own.
    one_recording : dict of str to str
        Parameter -> the recording its interval rests on, for every parameter
        whose information comes from one recording
        (:attr:`~pneumafit.identification.optimise.RobustCovariance.informing`;
        in fit.json a list of ``"name (recording)"``): no other recording can
        show the error of a law that is not the rig's, so the interval holds
        only as far as the model is right. A caveat (:meth:`caveats`), not a reason to distrust
        the fit.
    rest_positions : list of RestOffset
        Every rest phase of the step tests (:func:`rest_offsets`). The one
        with the largest offset of each step test whose pressures do not
        reach the noise at rest is named in :meth:`problems` when its offset
        exceeds :data:`THRESHOLD` times the position noise
        (:meth:`stops_elsewhere`).
    recorded_commands : dict of str to float or None
        For those closed-loop step tests: the largest pressure RMS over noise
        of the same replay with the model's valves driven by the recorded
        commands instead of its controller (the loop opened; the position
        then follows the model's forces). Far below the closed loop's, the
        misfit is the loop's answer to where the piston rests; about equal,
        it is in the valves, chambers or forces themselves. None where that
        replay failed.
    staged : dict of str to float
        For every fit recording: the largest RMS over noise of its fitted
        channels at the staged estimate, before the joint refinement (each
        recording then fitted by its own stage). A recording the joint
        refinement takes above :data:`THRESHOLD` and :data:`TRADE_FACTOR`
        times this was given up for the others (:meth:`given_up`): under the
        model's laws the recordings disagree. Empty when not computed.
    refused_offsets : list of str
        Pressure sensors whose offset the fit did not apply to the held-out
        recordings, each described (:meth:`SensorOffset.describe
        <pneumafit.identification.problem.SensorOffset.describe>`): the fit
        recordings' initial pressures disagree on it, agree on more than a
        transducer's zero can be off, or leave it within 1.4 standard errors
        of 0. A caveat: the model bends its initial pressures to follow
        recordings it cannot, or they do not tell its zero.
    sensor_zeros : dict of str to float
        Pressure channel -> the zero (Pa) taken off every recording's
        pressure residual before its RMS (``channels``). A fit takes the
        sensor's offset where its fit recordings agree on one, the same that
        its held-out recordings' starts take off
        (:func:`~pneumafit.identification.problem.pressure_offsets`;
        ``zeros_applied``), else the mean of the fit recordings' residuals
        of that channel, pooled
        (:meth:`~pneumafit.identification.replay.Replay.sensor_zeros`); a
        sensor no fit recording reads has no zero, and each of its
        recordings is judged less its own mean. One per
        sensor, as a transducer has: a held-out recording's figure includes
        its own mean error, and a fit recording's the part of the offset the
        likelihood profiles on it that the other fit recordings do not share.
    zeros_applied : list of str
        The channels of ``sensor_zeros`` that are the sensor's offset, also
        taken off the held-out recordings' initial readings.
    threshold : float
    """

    channels: list[ChannelQuality]
    at_bounds: list[str] = field(default_factory=list)
    outside_interval: list[str] = field(default_factory=list)
    unreliable: list[str] = field(default_factory=list)
    unconverged: list[str] = field(default_factory=list)
    not_identified: list[str] = field(default_factory=list)
    undetermined: list[str] = field(default_factory=list)
    one_recording: dict[str, str] = field(default_factory=dict)
    rest_positions: list[RestOffset] = field(default_factory=list)
    recorded_commands: dict[str, float | None] = field(default_factory=dict)
    staged: dict[str, float] = field(default_factory=dict)
    refused_offsets: list[str] = field(default_factory=list)
    sensor_zeros: dict[str, float] = field(default_factory=dict)
    zeros_applied: list[str] = field(default_factory=list)
    threshold: float = THRESHOLD

    def failing(self, role: str | None = None) -> list[ChannelQuality]:
        return [c for c in self.channels if c.fails and (role is None or c.role == role)]

    @property
    def reaches_noise(self) -> bool:
        """Every recording and channel within :data:`THRESHOLD` of its noise."""
        return not self.failing()

    @property
    def trustworthy(self) -> bool:
        """Reaches the noise, no estimate at a bound or outside its interval,
        chains long, every parameter group identified."""
        return (
            self.reaches_noise
            and not self.at_bounds
            and not self.outside_interval
            and not self.unreliable
            and not self.unconverged
            and not self.not_identified
        )

    def problems(self) -> list[str]:
        """One sentence per reason not to trust the fit (empty when trustworthy)."""
        out = []
        for role in ("fit", "validate"):
            bad = self.failing(role)
            if not bad:
                continue
            worst = max(bad, key=lambda c: c.ratio or 0.0)
            items = []
            for c in sorted(bad, key=lambda c: -(c.ratio or 0.0)):
                ph = c.failing_phases()
                items.append(
                    f"{c.recording} {c.channel} {c.ratio:.1f}x"
                    + (f" ({', '.join(ph)})" if ph else "")
                )
            recs = sorted({c.recording for c in bad})
            out.append(
                f"does not reach the noise on {len(recs)} {role} recording"
                f"{'s' if len(recs) > 1 else ''} (residual RMS up to {worst.ratio:.1f}x the "
                f"sensor noise, threshold {self.threshold:g}x): " + "; ".join(items)
            )
        stops = self.stops_elsewhere()
        if stops:
            items = []
            for r in stops:
                text = r.describe()
                opened = self.recorded_commands.get(r.recording)
                closed = max(
                    (c.ratio or 0.0 for c in self.channels
                     if c.recording == r.recording and c.channel.startswith("p_")),
                    default=0.0,
                )  # fmt: skip
                if opened is not None and math.isfinite(opened):
                    text += f", pressures {closed:.1f}x, {opened:.1f}x with the recorded commands"
                items.append(text)
            out.append(
                "the model's piston comes to rest elsewhere than the rig's (model minus "
                "measured position where they differ most, and the model's command minus "
                "the recorded one there; where a piston sticks depends on the friction law "
                "and the motion before, and a closed loop answers the offset with its "
                "command; with the recorded commands instead of the model's controller, a "
                "misfit far smaller than in closed loop is the loop's, one about as large is "
                "in the valves, chambers or forces): " + "; ".join(items)
            )
        given_up, gained = self.given_up()
        if given_up:
            final = self.worst_fitted()

            def item(file: str) -> str:
                return f"{file} ({self.staged[file]:.1f}x -> {final[file]:.1f}x)"

            out.append(
                "the joint refinement gave up "
                + ", ".join(item(f) for f in given_up)
                + (" to follow " + ", ".join(item(f) for f in gained) if gained else "")
                + " (the largest RMS over noise of the fitted channels, at the staged "
                "estimate, where each recording was fitted by its own stage, and at the "
                "final one): under this model's laws these recordings disagree; a law "
                "or an effect the model lacks shows in them (compare the staged and the "
                "joint estimates, or run discover)"
            )
        if self.not_identified:
            out.append(
                "not identified, held at the rig's defaults (the reported parameters, the "
                "linear analysis, the closed loop and the exports use these values): "
                + "; ".join(self.not_identified)
            )
        if self.unconverged:
            out.append(
                "least squares stopped before converging (the estimate may not be the "
                "optimum): " + "; ".join(self.unconverged)
            )
        if self.at_bounds:
            out.append("estimate at a bound or constraint: " + ", ".join(self.at_bounds))
        if self.outside_interval:
            out.append(
                "estimate outside its own 90 % interval: " + ", ".join(self.outside_interval)
            )
        if self.unreliable:
            out.append(
                "chains too short or not mixed (< 50 tau or R-hat > 1.01), intervals "
                "unreliable: " + ", ".join(self.unreliable)
            )
        return out

    def worst_fitted(self) -> dict[str, float]:
        """Largest RMS over noise of the fitted channels per fit recording
        (of the estimate these channels were assessed at)."""
        worst: dict[str, float] = {}
        for c in self.channels:
            if c.role == "fit" and c.fitted and c.ratio is not None:
                worst[c.recording] = max(worst.get(c.recording, 0.0), c.ratio)
        return worst

    def given_up(self) -> tuple[list[str], list[str]]:
        """Fit recordings the joint refinement gave up, and those it followed better.

        Given up: above :data:`THRESHOLD` at the final estimate and
        :data:`TRADE_FACTOR` times its ratio at the staged one
        (:attr:`staged`), worst first. Followed better: every other fit
        recording whose ratio fell, most improved first. Both empty when
        none was given up or :attr:`staged` is empty.
        """
        final = self.worst_fitted()
        both = [f for f in final if f in self.staged and self.staged[f] > 0.0]
        given_up = [
            f for f in both
            if final[f] > self.threshold and final[f] > TRADE_FACTOR * self.staged[f]
        ]  # fmt: skip
        if not given_up:
            return [], []
        given_up.sort(key=lambda f: -final[f] / self.staged[f])
        gained = [f for f in both if f not in given_up and final[f] < self.staged[f]]
        gained.sort(key=lambda f: final[f] / self.staged[f])
        return given_up, gained

    def stops_elsewhere(self) -> list[RestOffset]:
        """Per step test whose pressures do not reach the noise at rest, its
        rest phase with the largest offset, when that exceeds
        :data:`THRESHOLD` times the recording's position noise (largest
        offset first): the rest positions that can explain a pressure misfit
        at rest."""
        failing = {
            c.recording
            for c in self.failing()
            if c.channel.startswith("p_") and "rest" in c.failing_phases()
        }
        noise = {c.recording: c.noise for c in self.channels if c.channel == "y" and c.noise}
        worst: dict[str, RestOffset] = {}
        for r in self.rest_positions:
            if r.recording in failing and r.recording in noise:
                if r.recording not in worst or abs(r.offset) > abs(worst[r.recording].offset):
                    worst[r.recording] = r
        named = [r for r in worst.values() if abs(r.offset) > self.threshold * noise[r.recording]]
        return sorted(named, key=lambda r: -abs(r.offset))

    def caveats(self) -> list[str]:
        """One sentence per limit of the intervals that does not make the fit
        untrustworthy (empty when there is none)."""
        out = [one_recording_caveat(self.one_recording)] if self.one_recording else []
        if self.undetermined:
            out.append(
                "not determined by the fit recordings (90 % interval over a factor "
                f"{UNDETERMINED_FACTOR:g} or reaching 0; for a signed parameter, over "
                f"{UNDETERMINED_SHARE:.0%} of its range): "
                + "; ".join(self.undetermined)
                + ": these values mean little on their own (a combination with a "
                "correlated partner may still be determined, as lambda at the "
                "reference state can be for xi and beta: see the posterior "
                "correlation); a test that moves them would determine them"
            )
        out += [
            f"sensor offset {line}; the held-out recordings start from this sensor's "
            "readings as they are"
            for line in self.refused_offsets
        ]
        return out

    def verdict(self) -> str:
        """One line for the top of the console summary and the report."""
        if self.trustworthy:
            worst = max((c.ratio for c in self.channels if c.ratio is not None), default=None)
            tail = f" (worst recording {worst:.2f}x the sensor noise)" if worst else ""
            return "reaches the noise on every recording and channel" + tail
        if not self.reaches_noise:
            return "DOES NOT REACH THE NOISE: the model does not follow these recordings"
        return "reaches the noise, but: " + "; ".join(self.problems())

    def as_dict(self) -> dict[str, Any]:
        return {
            "threshold": self.threshold,
            "reaches_noise": self.reaches_noise,
            "trustworthy": self.trustworthy,
            "verdict": self.verdict(),
            "problems": self.problems(),
            "at_bounds": list(self.at_bounds),
            "outside_interval": list(self.outside_interval),
            "unreliable": list(self.unreliable),
            "unconverged": list(self.unconverged),
            "not_identified": list(self.not_identified),
            "undetermined": list(self.undetermined),
            "one_recording": [f"{n} ({f})" for n, f in self.one_recording.items()],
            "caveats": self.caveats(),
            "rest_positions": [r.as_dict() for r in self.rest_positions],
            "recorded_commands": dict(self.recorded_commands),
            "staged": dict(self.staged),
            "refused_offsets": list(self.refused_offsets),
            "sensor_zeros": dict(self.sensor_zeros),
            "zeros_applied": list(self.zeros_applied),
            "recordings": [c.as_dict() for c in self.channels],
        }


def parameter_flags(quality: FitQuality | Mapping[str, Any]) -> dict[str, str]:
    """The flag of every flagged parameter, for the console's and the
    report's parameter tables: ``at bound``, ``outside interval``, ``not
    determined`` (:func:`undetermined_problems`), ``chain short`` (its chain
    under 50 tau) or ``not mixed`` (long enough, R-hat above 1.01;
    :func:`chain_problems`), the first that applies in that order.

    Parameters
    ----------
    quality : FitQuality or mapping
        A fit's quality, or its fit.json ``quality`` section
        (:meth:`FitQuality.as_dict`; a key a file lacks counts as empty).
    """

    def items(key: str) -> list[str]:
        if isinstance(quality, Mapping):
            found = quality.get(key)
            return [str(i) for i in found] if isinstance(found, list) else []
        return list(getattr(quality, key))

    flagged: dict[str, str] = {}
    for key, flag in (("at_bounds", "at bound"), ("outside_interval", "outside interval"),
                      ("undetermined", "not determined")):  # fmt: skip
        for item in items(key):
            flagged.setdefault(item.split(" ", 1)[0], flag)
    for item in items("unreliable"):
        # "NAME (STAGE: 31 tau, R-hat 1.020)" or "NAME (STAGE: R-hat 1.020)"
        why = "chain short" if " tau" in item else "not mixed"
        flagged.setdefault(item.split(" ", 1)[0], why)
    return flagged


def zeros_phrase(
    zeros: Mapping[str, float], applied: Sequence[str] = (), channels: Iterable[str] = ()
) -> str:
    """How the pressure residuals of the quality table were taken
    (:attr:`FitQuality.sensor_zeros`, ``zeros_applied``), e.g. ``"pressures
    less one zero per sensor: p_N +457 Pa (the fit recordings' mean
    residual), p_P -827 Pa (its offset)"``; empty when none of the table's
    ``channels`` is a pressure."""
    pressures = sorted({c for c in channels if QUANTITIES.get(c) == "pressure"})
    if not pressures:
        return ""
    unknown = [c for c in pressures if c not in zeros]
    tail = (
        "; " + ", ".join(unknown) + ": no fit recording reads "
        + ("it" if len(unknown) == 1 else "them")
        + f", so each recording less its own mean (at most {OFFSET_LIMIT:.0f} Pa)"
        if unknown
        else ""
    )  # fmt: skip
    if not zeros:
        return "pressures: " + tail.removeprefix("; ")

    def source(c: str, v: float) -> str:
        if c in applied:
            return "its offset"
        if abs(v) >= OFFSET_LIMIT:
            # Replay.sensor_zeros holds a mean residual within a transducer's
            # zero (replay.plausible_zero): the rest is the model's misfit
            return (
                "the fit recordings' mean residual is beyond what a transducer's zero can "
                f"be, {OFFSET_LIMIT:.0f} Pa: the rest counts as the model's misfit"
            )
        return "the fit recordings' mean residual"

    return (
        "pressures less one zero per sensor: "
        + ", ".join(f"{c} {v:+.0f} Pa ({source(c, v)})" for c, v in sorted(zeros.items()))
        + tail
    )


def one_recording_caveat(one_recording: Mapping[str, str]) -> str:
    """The sentence on intervals that rest on one recording, grouped by
    recording; ``one_recording`` as :attr:`FitQuality.one_recording`."""
    by_file: dict[str, list[str]] = {}
    for name, file in one_recording.items():
        by_file.setdefault(file, []).append(name)
    return (
        "intervals resting on one recording, which no other can contradict (they hold only "
        "as far as the model's laws are the rig's; add a test that informs them): "
        + "; ".join(f"{file}: {', '.join(names)}" for file, names in by_file.items())
    )


def assess_residuals(
    campaign: Campaign,
    residuals: Sequence[tuple[str, str, NDArray[np.float64], NDArray[np.float64]]],
    fitted_channels: Sequence[str],
) -> list[ChannelQuality]:
    """Residual over noise for each (recording, channel).

    Parameters
    ----------
    campaign : Campaign
    residuals : sequence of (recording file, channel, sample indices, residual)
        The replay's residuals on the recording's own samples (SI), the
        pressure sensors' zeros already taken off
        (:meth:`~pneumafit.identification.replay.Replay.sensor_offset_free`).
    fitted_channels : sequence of str
        Channels of the likelihood.

    Returns
    -------
    list of ChannelQuality
    """
    recs = {r.file: r for r in campaign.recordings}
    own = noise_estimates(campaign)
    pooled = campaign_noise(campaign)
    out = []
    for file, channel, idx, res in residuals:
        rec = recs[file]
        res = np.asarray(res, float)
        good = np.isfinite(res)
        if not np.any(good):
            continue
        idx, res = np.asarray(idx)[good], res[good]
        sigma = own.get((file, channel))
        source = "rest" if rec.kind != "flow" else "levels"
        if sigma is None:
            sigma = pooled.get(channel)
            source = "campaign" if sigma is not None else "none"
        rms = float(np.sqrt(np.mean(res * res)))
        labels = phases(rec)[idx]
        per = {}
        for ph in PHASES:
            m = labels == ph
            if np.any(m):
                r = float(np.sqrt(np.mean(res[m] ** 2)))
                per[ph] = {"n": int(m.sum()), "rms": r, "ratio": r / sigma if sigma else None}
        out.append(
            ChannelQuality(
                recording=file,
                role=rec.role,
                kind=rec.kind,
                channel=channel,
                fitted=channel in fitted_channels,
                n=int(res.size),
                rms=rms,
                noise=sigma,
                noise_source=source,
                phases=per,
            )
        )
    return out


#: Bounds that are the value of the law a parameter extends (name -> which
#: bound): a valve path's knee exponent at 1 is the power law (no knee), its
#: full-opening fraction at 1 the law that opens fully at u_sat. The valve
#: stage holds an extension that ends there at that value; when the joint
#: stage takes one back to it, the fit is that nested law, not an estimate
#: leaning on a wall, and it is not named. The exchange area's share of heads,
#: faces and rod at 0 is likewise a convention of its own (the bore wall only).
NESTING_BOUNDS: dict[str, str] = {
    "valve_knee_supply": "lower", "valve_knee_exhaust": "lower",
    "valve_full_supply": "upper", "valve_full_exhaust": "upper",
    "heat_area_ends": "lower",
}  # fmt: skip


def bound_problems(parameters: Iterable[Any], free: Iterable[str], rtol: float = 1e-4) -> list[str]:
    """Free estimates within ``rtol`` of their range (log range for log scale) of a
    bound, or of a :data:`CONSTRAINTS` partner; not those on a
    :data:`NESTING_BOUNDS` bound."""
    names = set(free)
    parameters = list(parameters)
    values = {p.name: p.value for p in parameters}
    out = []
    for big, small, meaning in CONSTRAINTS:
        if {big, small} <= names and values[big] <= values[small] * (1.0 + rtol):
            out.append(f"{big} (= {small}: {meaning})")
    for p in parameters:
        if p.name not in names or p.group == "initial":
            continue
        lo, hi = p.lower, p.upper
        if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
            continue
        if p.scale == "log" and lo > 0:
            lo, hi, v = math.log(lo), math.log(hi), math.log(max(p.value, 1e-300))
        else:
            v = p.value
        tol = rtol * (hi - lo)
        nesting = NESTING_BOUNDS.get(p.name)
        if v <= lo + tol and nesting != "lower":
            out.append(f"{p.name} (lower bound {p.lower:g})")
        elif v >= hi - tol and nesting != "upper":
            out.append(f"{p.name} (upper bound {p.upper:g})")
    return out


def interval_problems(parameters: Iterable[Any]) -> list[str]:
    """Estimates outside their own 90 % interval."""
    out = []
    for p in parameters:
        iv = p.interval_90
        if iv is None or p.group == "initial":
            continue
        lo, hi = iv
        slack = 1e-9 * max(abs(lo), abs(hi), 1e-300)
        if not (lo - slack <= p.value <= hi + slack):
            out.append(f"{p.name} {p.value:.6g} not in [{lo:.6g}, {hi:.6g}]")
    return out


def undetermined_problems(
    parameters: Iterable[Any], free: Iterable[str], at_bounds: Iterable[str]
) -> list[str]:
    """Free estimates whose 90 % interval leaves their order of magnitude open.

    A parameter that cannot be negative (lower bound >= 0) with a positive
    estimate: its interval reaches 0 or its ends are more than
    :data:`UNDETERMINED_FACTOR` apart. Any other with finite bounds: its
    interval covers more than :data:`UNDETERMINED_SHARE` of its range.
    Initial states, rig constants and the parameters named in
    ``at_bounds`` (the items of :func:`bound_problems` for the same
    parameters: a bound, or a constraint such as the static friction on its
    Coulomb level) are not judged. Each item is ``"name value unit, 90 %
    [lo, hi]: why"``.
    """
    names = set(free) - {item.split(" ", 1)[0] for item in at_bounds}
    out = []
    for p in parameters:
        iv = p.interval_90
        if p.name not in names or iv is None or p.group in ("initial", "rig"):
            continue
        lo, hi = float(iv[0]), float(iv[1])
        if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
            continue
        why = ""
        if p.lower >= 0.0 and p.value > 0.0:
            if lo <= 0.0:
                why = "reaches 0"
            elif hi / lo > UNDETERMINED_FACTOR:
                why = f"a factor {hi / lo:.3g}"
        elif math.isfinite(p.lower) and math.isfinite(p.upper) and p.upper > p.lower:
            share = (hi - lo) / (p.upper - p.lower)
            if share > UNDETERMINED_SHARE:
                why = f"{share:.0%} of its range"
        if why:
            unit = f" {p.unit}" if p.unit and p.unit != "-" else ""
            out.append(f"{p.name} {p.value:.4g}{unit}, 90 % [{lo:.3g}, {hi:.3g}]: {why}")
    return out


def chain_problems(runs: Iterable[Any]) -> list[str]:
    """Sampled parameters whose chain is < 50 tau long or has R-hat > 1.01."""
    out = []
    for run in runs:
        for n in run.names:
            tau = run.tau.get(n, math.nan)
            kept = run.n_steps - run.discard
            mult = kept / tau if tau and math.isfinite(tau) and tau > 0 else math.nan
            rhat = run.rhat.get(n, math.nan)
            why = []
            if not (math.isfinite(mult) and mult >= MIN_TAU):
                why.append(f"{mult:.0f} tau" if math.isfinite(mult) else "tau unknown")
            if not (math.isfinite(rhat) and rhat <= MAX_RHAT):
                why.append(f"R-hat {rhat:.3f}")
            if why:
                out.append(f"{n} ({run.name}: {', '.join(why)})")
    return out
