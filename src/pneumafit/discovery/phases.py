"""Phases of a test: where in a recording the actuator fills, empties, relaxes,
moves or rests.

Every sample of a recording gets one label of :data:`PHASES`, from the
recorded channels alone (never from a model), by the rules of
:func:`label_phases`. Residual analysis (:mod:`.residuals`) reports the RMS
residual per phase, so that a misfit can be traced to the physics active in
that phase (docs/effects.md lists which effect shows where).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from pneumafit.errors import PneumafitInputError

if TYPE_CHECKING:
    from pneumafit.campaign.model import Recording

__all__ = [
    "PHASES",
    "PhaseRules",
    "label_phases",
    "phase_interior",
    "smoothed_rate",
    "window_samples",
]

#: Phase labels, in order of precedence (a sample takes the first that applies).
PHASES: tuple[str, ...] = ("motion", "filling", "emptying", "relaxation", "rest")


@dataclass(frozen=True)
class PhaseRules:
    """Thresholds of the phase labelling (SI units).

    Parameters
    ----------
    open_command : float
        A valve counts as open when its command exceeds this in magnitude (V).
        The default 0.5 V lies just beyond the demo valve's 0.3-V overlap.
    speed : float
        The piston moves when its speed exceeds this (m/s): the measured
        ``v``, or else the rate of the measured ``y`` fitted over
        ``smoothing``. The default 2 mm/s is ~100 times the rate noise of a
        10-um encoder over 50 ms.
    pressure_rate : float
        A chamber pressure rises (falls) when its rate, fitted over
        ``smoothing``, exceeds +this (is below -this) (Pa/s). The default
        0.2 bar/s is ~4 standard deviations of that rate for 400-Pa white
        sensor noise at 1 kHz over 50 ms.
    smoothing : float
        Window of the local straight-line fits that estimate rates (s).
    relaxation_time : float or None
        Longest relaxation after the last opening or motion (s); later
        samples are ``rest``. None: relaxation lasts until the next opening
        or motion.
    """

    open_command: float = 0.5
    speed: float = 2.0e-3
    pressure_rate: float = 2.0e4
    smoothing: float = 0.05
    relaxation_time: float | None = None

    def __post_init__(self) -> None:
        for name in ("open_command", "speed", "pressure_rate", "smoothing"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise PneumafitInputError(
                    f"phase rules: {name}: expected a number > 0, found {value!r}"
                )
        if self.relaxation_time is not None and not self.relaxation_time > 0.0:
            raise PneumafitInputError(
                "phase rules: relaxation_time: expected None or a number > 0 (s), "
                f"found {self.relaxation_time!r}"
            )


def window_samples(time: NDArray[np.float64], window: float) -> int:
    """Odd number of samples (>= 3, <= n) spanning ``window`` seconds at the
    median sample interval of ``time``; 0 when there are fewer than 3 samples."""
    n = time.size
    if n < 3:
        return 0
    dt = float(np.median(np.diff(time)))
    width = max(3, round(window / dt) | 1)
    return min(width, n if n % 2 else n - 1)


def smoothed_rate(
    time: NDArray[np.float64], values: NDArray[np.float64], window: float
) -> NDArray[np.float64]:
    """Rate of change by a local straight-line fit (Savitzky-Golay, order 1).

    Parameters
    ----------
    time : ndarray, shape (n,)
        Sample times (s); the median interval is taken as the spacing.
    values : ndarray, shape (n,)
        Signal (any unit U).
    window : float
        Width of the fit window (s); at least 3 samples are used, at most n.

    Returns
    -------
    ndarray, shape (n,)
        Rate (U/s); zeros when n < 3.
    """
    width = window_samples(time, window)
    if width == 0:
        return np.zeros(values.size)
    dt = float(np.median(np.diff(time)))
    return savgol_filter(values, width, 1, deriv=1, delta=dt, mode="interp")


def phase_interior(labels: NDArray[np.str_], margin: int) -> NDArray[np.bool_]:
    """True where a sample lies at least ``margin`` samples inside its run of
    equal labels (a rate fitted there does not straddle a phase change); the
    ends of the recording count as inside."""
    n = labels.size
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [n]])
    inside = np.ones(n, dtype=bool)
    for a, b in zip(starts, ends, strict=True):
        if a > 0:
            inside[a : min(a + margin, b)] = False
        if b < n:
            inside[max(b - margin, a) : b] = False
    return inside


def label_phases(recording: Recording, rules: PhaseRules | None = None) -> NDArray[np.str_]:
    """Label every sample of a recording with a phase of :data:`PHASES`.

    Rules, in order of precedence (the first that applies wins):

    1. ``motion``: the piston moves, ``|v| > speed`` (``|dy/dt|`` fitted over
       ``smoothing`` when ``v`` was not recorded). Never in charge,
       discharge and flow tests (piston blocked or absent).
    2. ``filling``: a valve opens its chamber to supply, ``u_X >
       open_command``, and that chamber's pressure rises, ``dp_X/dt >
       pressure_rate`` (the pressure condition is dropped when ``p_X`` was
       not recorded).
    3. ``emptying``: a valve opens its chamber to exhaust, ``u_X <
       -open_command``, and the pressure falls, ``dp_X/dt < -pressure_rate``.
    4. ``relaxation``: every valve near its centre (``|u| <= open_command``),
       piston at rest, after an opening or a motion (and, with
       ``relaxation_time``, at most that long after it): heat exchange and
       leakage move the pressures.
    5. ``rest``: everything else: before the first opening, and a valve open
       on a chamber whose pressure no longer changes (saturated).

    Flow tests hold the chamber pressure with a regulator, so there
    ``filling`` is ``u > open_command`` and ``emptying`` ``u <
    -open_command`` (the valve's flow is the measured quantity), else
    ``rest``. Labels come from the recorded channels as interpolated onto
    the common time grid (``Recording.channels``); residual statistics then
    count only truly sampled points.

    Parameters
    ----------
    recording : Recording
        A campaign recording (SI units).
    rules : PhaseRules, optional
        Thresholds; default :class:`PhaseRules` ().

    Returns
    -------
    ndarray of str, shape (n_samples,)
        One label of :data:`PHASES` per sample.
    """
    rules = rules if rules is not None else PhaseRules()
    t = recording.time
    ch = recording.channels
    n = t.size
    labels = np.full(n, "rest", dtype="<U10")
    chambers = [c for c in ("P", "N") if f"u_{c}" in ch]
    if recording.kind in ("charge", "discharge", "flow") and recording.chamber is not None:
        chambers = [c for c in chambers if c == recording.chamber]

    if recording.kind == "flow":
        for c in chambers:
            u = ch[f"u_{c}"]
            labels[(labels == "rest") & (u > rules.open_command)] = "filling"
            labels[(labels == "rest") & (u < -rules.open_command)] = "emptying"
        return labels

    moving = np.zeros(n, dtype=bool)
    if recording.kind in ("step", "free"):
        if "v" in ch:
            moving = np.abs(ch["v"]) > rules.speed
        elif "y" in ch:
            moving = np.abs(smoothed_rate(t, ch["y"], rules.smoothing)) > rules.speed

    filling = np.zeros(n, dtype=bool)
    emptying = np.zeros(n, dtype=bool)
    valve_open = np.zeros(n, dtype=bool)
    for c in chambers:
        u = ch[f"u_{c}"]
        valve_open |= np.abs(u) > rules.open_command
        if f"p_{c}" in ch:
            rate = smoothed_rate(t, ch[f"p_{c}"], rules.smoothing)
            rising, falling = rate > rules.pressure_rate, rate < -rules.pressure_rate
        else:
            rising = falling = np.ones(n, dtype=bool)
        filling |= (u > rules.open_command) & rising
        emptying |= (u < -rules.open_command) & falling

    # time of the last opening or motion at or before each sample
    active = valve_open | moving
    last_active = np.where(active, t, -np.inf)
    last_active = np.maximum.accumulate(last_active)
    after = np.isfinite(last_active)
    if rules.relaxation_time is not None:
        after &= t - last_active <= rules.relaxation_time
    relaxation = after & ~valve_open & ~moving

    labels[relaxation] = "relaxation"
    labels[emptying] = "emptying"
    labels[filling] = "filling"
    labels[moving] = "motion"
    return labels
