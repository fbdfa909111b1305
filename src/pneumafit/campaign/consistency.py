"""Do the recordings agree with the declared rig? Supply, exhaust, stroke, controller.

Consistency checks of a campaign's recordings against its ``[rig]``
table and their controllers, each a warning (not an error: a sensor may be off) that names the
recording, the channel, what the declaration implies and what was read.

**The measured supply pressure.**
The models take the supply pressure as a constant, the rig's declared
``supply_pressure``; a recording's ``p_S`` channel (the measured supply
pressure, optional in the campaign format) is read and kept but is not an
input of any simulation. Where it disagrees with the declared value the
valves' supply flows are simulated at the wrong upstream pressure, which no
fitted parameter of the valve, heat or friction laws represents:

- choked, a path's mass flow is proportional to its upstream absolute
  pressure (ISO 6358, eq. 3 of the paper), so a supply pressure off by a
  share e of the gauge supply P_S - P_e changes the filling flows by
  e (P_S - P_e) / P_S: 0.86 % for e = 1 % on a 7-bar rig, which on a charge
  rising by 5 bar is ~4 kPa of pressure, ten times a 400-Pa sensor's
  noise. :data:`TOLERANCE` = 1 % is therefore where the mismatch starts to
  show in a fit's residuals;
- a median far off the declared value most often is a gauge reading
  declared as absolute (``supply_pressure = "7 bar"`` for a regulator set to
  7 bar gauge, 8.013 bar absolute) or a regulator set elsewhere than
  written: the campaign's value is what to correct;
- a wide spread within one recording is the supply sagging while the
  valves draw air (a regulator's droop, a long or narrow line): the catalog
  effect ``supply_pressure_drop`` of ``pneumafit discover`` models it as a
  line resistance.

**The held chambers.** The chamber pressures of the tests with the piston
held (charge, discharge and flow tests) say the same without a ``p_S`` channel: with the piston
blocked nothing compresses the gas but the valve, whose flow reverses once
the chamber passes its upstream pressure, so such a chamber stays between
the exhaust and the supply pressure (a moving piston may compress a
chamber past the supply for a moment: step and free tests are not judged).
A chamber read above the declared supply (:func:`chamber_beyond_bounds`,
its 99th percentile more than :data:`BOUND_TOLERANCE` of the gauge supply
above it) means a supply declared too low, most often a gauge setting
written as absolute (``supply_pressure = "6 bar"`` on a regulator at 6 bar
gauge: the charges plateau at 7.013 bar, and no valve law can fill the
model's chambers past its 6 bar, so the fit fails on every charge test
without saying why); one read below the exhaust pressure, a pressure
channel in gauge declared as absolute.

**The moved chambers and the temperatures.** A chamber the piston moves
(step, free and friction tests) may pass the supply and exhaust pressures,
but a bulk below 0.3 exhausts or above 2 supplies (:data:`MOVED_BOUNDS`,
:func:`moved_chamber_out_of_range`) is a channel in another unit than its
header says or gauge declared as absolute; a temperature channel outside
:data:`TEMPERATURE_BOUNDS` (:func:`temperature_out_of_range`) likewise.

**The position.** The format's piston position runs from 0 (retracted) to
the stroke; the end stops hold it there. A recording whose position passes
either end by more than :data:`STROKE_TOLERANCE` of the stroke
(:func:`position_beyond_stroke`) has a stroke declared too short, a
position in other units than its header says, a sensor counting the other
way (negative positions; the ``[read]`` table's ``reversed = true`` negates
it) or its zero elsewhere than at the retracted end.

**The controller.** A step test's closed-loop replays (every fit, the
comparison, discovery) run the recording's declared PD law on the model's
position, so its gains must be the ones that produced the recorded
commands. :func:`controller_mismatch` fits u = u0 + kp (y_ref - y) - kd v
by least squares to the recorded commands where they are not saturated (v
by central differences of the position over +-:data:`VELOCITY_WINDOW`) and
reports a declared law whose kp is off by more than :data:`GAIN_TOLERANCE`
(a factor of 1.25 either way), whose kd is off by more than a factor of 2,
or which misses the commands by more than :data:`LAW_TOLERANCE` of their
RMS: a gain written in other units (V/mm for V/m is a factor of 1000), a
mistyped gain, or another controller than the one declared. The virtual
rig's commands follow their declared law to 0.5 % of their RMS, with the
gains recovered to 0.1 % (136 step tests); a real controller's velocity
filter and sampling delay leave more, which the loose tolerances allow.

:func:`supply_mismatch`, :func:`chamber_beyond_bounds`,
:func:`position_beyond_stroke` and :func:`controller_mismatch` judge one
recording's channel; the campaign reader reports them as warnings of
``pneumafit check`` (and of the main job's check stage), and the fit adds
the same sentences to its warnings (:func:`consistency_warnings`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.campaign.units import DISPLAY_UNITS

__all__ = [
    "BOUND_QUANTILES",
    "BOUND_TOLERANCE",
    "GAIN_TOLERANCE",
    "HELD_KINDS",
    "LAW_TOLERANCE",
    "MAX_GAIN_CORRELATION",
    "SPREAD_QUANTILES",
    "STROKE_TOLERANCE",
    "TOLERANCE",
    "VELOCITY_WINDOW",
    "chamber_beyond_bounds",
    "consistency_warnings",
    "controller_mismatch",
    "median_interval",
    "moved_chamber_out_of_range",
    "position_beyond_stroke",
    "recording_findings",
    "sampled_too_slowly",
    "supply_mismatch",
    "temperature_out_of_range",
]

#: Largest difference, as a share of the gauge supply P_S - P_e, between the
#: measured supply pressure (its median, or the width of its central 90 %)
#: and the declared one before it is reported (module doc: 1 % changes a
#: charge's pressure by ~10 sensor noise levels).
TOLERANCE = 0.01
#: Quantiles whose distance is a recording's spread of p_S: the central
#: 90 % (white sensor noise of standard deviation s alone spans 3.3 s, 1.3
#: kPa for the 400-Pa sensors of the virtual rig, a fifth of 1 % of 6 bar).
SPREAD_QUANTILES = (0.05, 0.95)


#: Kinds of tests whose chambers the piston does not compress (module doc).
HELD_KINDS = ("charge", "discharge", "flow")
#: How far (share of the gauge supply) a held chamber's pressure may pass the
#: declared supply or exhaust pressure before it is reported: 2 %, 12 kPa on
#: a 7-bar rig, above a sensor's offset (the virtual rig draws them with a
#: standard deviation of 1.5 kPa; 0.1 % of a 10-bar sensor's span is 1 kPa)
#: and its noise at the quantiles below, and far below the 101 kPa of a
#: gauge value written as absolute.
BOUND_TOLERANCE = 0.02
#: Quantiles of a held chamber's pressure compared with the bounds: the
#: extremes of the bulk, not single noisy samples.
BOUND_QUANTILES = (0.01, 0.99)
#: A chamber the piston moves (step, free and friction tests) may pass the
#: supply and exhaust pressures (compressed, or expanded behind a closed
#: valve), but not by these factors of the absolute pressures: below 0.3 of
#: the exhaust (30 kPa absolute, a vacuum no pneumatic drive pulls) or above
#: 2 supplies, the channel is in another unit than its header says (bar
#: labelled Pa reads 1e5 times too low, Pa labelled bar as much too high)
#: or gauge declared as absolute (a chamber at the exhaust reads ~0).
MOVED_BOUNDS = (0.3, 2.0)
#: Gas and wall temperatures of a pneumatic rig (K). A fast discharge cools
#: the gas toward the adiabatic limit (293 K (1/7)^(2/7) = 168 K from 7 bar;
#: the virtual rig's 1st percentiles reach 217 K) and filling heats it up to
#: gamma T_supply (410 K): 120-450 K takes both. A temperature channel whose
#: bulk lies outside is in another unit than its header says (degC labelled
#: K reads ~20 K; K labelled degC ~566 K).
TEMPERATURE_BOUNDS = (120.0, 450.0)
#: Kinds of tests whose transients the fits follow sample by sample (a free
#: test's slow drift may be logged slowly, and a flow test holds its levels).
DYNAMIC_KINDS = ("charge", "discharge", "step")
#: Longest median sample interval (s) of such a test: its transients last
#: 10-100 ms (a charge's time constant, a step's rise), so 20 ms already
#: leaves few samples on them; a longer one is most often a time axis in
#: another unit than its header says (ms under "[s]" makes a 4-s test last
#: 4000 s, through which every simulation of a fit steps at 1 ms).
MAX_INTERVAL = 0.02
#: How far (share of the stroke) a recorded position may pass either end
#: before it is reported: 2 %, 10 mm of a 0.5-m stroke, above an encoder
#: zeroed a little off the end stop and the end stops' compliance, far below
#: a position read in the wrong unit or from the other end of a longer
#: travel.
STROKE_TOLERANCE = 0.02
#: Largest factor between a declared proportional gain and the one the
#: recorded commands follow (module doc); the derivative gain may be off by
#: a factor of 2, its regressor (a differentiated position) being the
#: noisier one and a real controller's velocity filter lowering it.
GAIN_TOLERANCE = 1.25
#: Largest RMS of the recorded commands less the declared law, as a share of
#: the commands' RMS (unsaturated samples; module doc).
LAW_TOLERANCE = 0.2
#: Half-width (s) of the central difference giving v from the position:
#: 5 ms, over which a 10-um encoder's step is 1 mm/s of velocity noise.
VELOCITY_WINDOW = 0.005
#: Fewest unsaturated samples, with the piston moving, for the gains to be
#: judged.
MIN_CONTROL_SAMPLES = 20
#: Largest correlation between y_ref - y and v over the judged samples for
#: the gains to be judged one by one (beyond it the split between kp and kd
#: is not determined and only the law's misfit is judged).
MAX_GAIN_CORRELATION = 0.9


def _shown(value: float, kind: str = "pressure", spec: str = ".1f") -> str:
    """An SI value of ``kind`` in its one display unit (:data:`DISPLAY_UNITS`)."""
    factor, unit = DISPLAY_UNITS[kind]
    return f"{value * factor:{spec}} {unit}"


#: Why a pressure reads below the exhaust: gauge values declared absolute.
_GAUGE_HINT = (
    "a channel in gauge pressure declared as absolute? (a unit such as barg, or "
    'reference = "gauge" in HDF5)'
)


def _bulk(values: NDArray[np.float64]) -> tuple[float, float] | None:
    """The 1st and 99th percentiles (:data:`BOUND_QUANTILES`) of a channel's
    finite samples: its extremes without single noisy samples; None with
    fewer than two."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 2:
        return None
    lo, hi = np.quantile(x, BOUND_QUANTILES)
    return float(lo), float(hi)


def median_interval(time: NDArray[np.float64]) -> float | None:
    """A recording's median sample interval (s), None with fewer than 3 samples."""
    t = np.asarray(time, dtype=float)
    return float(np.median(np.diff(t))) if t.size >= 3 else None


def _finite(
    values: NDArray[np.float64], supply: float, exhaust: float
) -> tuple[NDArray[np.float64], float] | None:
    """A pressure channel's finite samples and the gauge supply (Pa), or
    None when fewer than two samples or no positive gauge supply remain."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    span = supply - exhaust
    return (x, span) if x.size >= 2 and span > 0.0 else None


def supply_mismatch(
    p_s: NDArray[np.float64], supply: float, exhaust: float
) -> tuple[str, str] | None:
    """What a measured supply pressure should be and what it is, or None.

    Parameters
    ----------
    p_s : ndarray
        The recording's ``p_S`` channel (Pa absolute).
    supply, exhaust : float
        The rig's declared supply and exhaust pressures (Pa absolute).

    Returns
    -------
    (expected, found) or None
        None when the channel's median lies within :data:`TOLERANCE` of the
        gauge supply of the declared value and its central 90 % spans less
        than that; else the two halves of a problem message (the module doc
        says what each case usually means).
    """
    ready = _finite(p_s, supply, exhaust)
    if ready is None:
        return None
    x, span = ready
    allowed = TOLERANCE * span
    median = float(np.median(x))
    lo, hi = (float(q) for q in np.quantile(x, SPREAD_QUANTILES))
    off = median - supply
    wide = hi - lo > allowed
    if abs(off) <= allowed and not wide:
        return None
    expected = (
        f"a measured supply pressure within {100 * TOLERANCE:g} % of the gauge supply "
        f"({_shown(allowed, spec='.3g')}) of the declared supply_pressure {_shown(supply)} "
        "absolute (the models simulate the declared value; p_S is not an input)"
    )
    found = f"median {_shown(median)}, central 90 % {_shown(lo)} to {_shown(hi)}"
    causes = []
    if abs(off) > allowed:
        hint = (
            f" (the declared value plus the exhaust pressure is {_shown(supply + exhaust)}: a "
            "gauge reading declared as absolute?)"
            if abs(median - (supply + exhaust)) <= allowed
            else ""
        )
        causes.append(
            f"{_shown(off, spec='+.1f')} from the declared value{hint}: correct supply_pressure "
            "in campaign.toml if the rig ran there"
        )
    if wide:
        causes.append(
            "the supply sags while the valves draw air (the catalog effect "
            "supply_pressure_drop of pneumafit discover models a line resistance)"
        )
    return expected, found + ": " + "; ".join(causes)


def chamber_beyond_bounds(
    pressure: NDArray[np.float64], supply: float, exhaust: float
) -> tuple[str, str] | None:
    """What a held chamber's pressure should be and what it is, or None.

    Parameters
    ----------
    pressure : ndarray
        A chamber pressure channel of a charge, discharge or flow test (Pa
        absolute).
    supply, exhaust : float
        The rig's declared supply and exhaust pressures (Pa absolute).

    Returns
    -------
    (expected, found) or None
        None when the channel's 1st and 99th percentiles lie within
        :data:`BOUND_TOLERANCE` of the gauge supply of [exhaust, supply];
        else the two halves of a problem message (module doc).
    """
    ready = _finite(pressure, supply, exhaust)
    if ready is None:
        return None
    x, span = ready
    allowed = BOUND_TOLERANCE * span
    lo, hi = (float(q) for q in np.quantile(x, BOUND_QUANTILES))
    if exhaust - allowed <= lo and hi <= supply + allowed:
        return None
    expected = (
        f"a chamber the piston does not compress between the declared exhaust_pressure "
        f"{_shown(exhaust)} and supply_pressure {_shown(supply)} absolute (within "
        f"{100 * BOUND_TOLERANCE:g} % of the gauge supply, {_shown(allowed, spec='.3g')}, for "
        "the sensor's offset)"
    )
    found = []
    if hi > supply + allowed:
        gauge = (
            f"; {_shown(supply)} gauge is {_shown(supply + exhaust)} absolute: a gauge "
            "setting declared as absolute?"
            if abs(hi - (supply + exhaust)) <= allowed
            else ""
        )
        found.append(
            f"99th percentile {_shown(hi)}, {_shown(hi - supply)} above the supply: "
            f"no valve fills the models' chamber past the declared supply_pressure, correct "
            f"it in campaign.toml if the rig's supply was higher{gauge}"
        )
    if lo < exhaust - allowed:
        found.append(
            f"1st percentile {_shown(lo)}, {_shown(exhaust - lo)} below the exhaust: {_GAUGE_HINT}"
        )
    return expected, "; ".join(found)


def moved_chamber_out_of_range(
    pressure: NDArray[np.float64], supply: float, exhaust: float
) -> tuple[str, str] | None:
    """What a moved chamber's pressure should be and what it is, or None.

    Parameters
    ----------
    pressure : ndarray
        A chamber pressure channel of a test whose piston moves (Pa absolute).
    supply, exhaust : float
        The rig's declared supply and exhaust pressures (Pa absolute); a
        supply that is not finite (friction-only campaigns) skips the upper
        bound.

    Returns
    -------
    (expected, found) or None
        None when the channel's 1st and 99th percentiles lie within
        :data:`MOVED_BOUNDS` times the exhaust and the supply; else the two
        halves of a problem message.
    """
    bulk = _bulk(pressure)
    if bulk is None or not exhaust > 0.0:
        return None
    lo, hi = bulk
    low = MOVED_BOUNDS[0] * exhaust
    high = MOVED_BOUNDS[1] * supply if np.isfinite(supply) and supply > 0.0 else np.inf
    if low <= lo and hi <= high:
        return None
    expected = f"absolute pressures from {_shown(low)} ({MOVED_BOUNDS[0]:g} of the exhaust)" + (
        f" to {_shown(high)} ({MOVED_BOUNDS[1]:g} supplies)" if np.isfinite(high) else ""
    )
    why = (
        "a channel in another unit than its header says (bar labelled Pa?)"
        if hi < low
        else _GAUGE_HINT
        if lo < low
        else "a channel in another unit than its header says (Pa labelled bar?)"
    )
    return expected, (
        f"1st to 99th percentile {_shown(lo, spec='.4g')} to {_shown(hi, spec='.4g')}: {why}"
    )


def sampled_too_slowly(time: NDArray[np.float64], kind: str) -> tuple[str, str] | None:
    """What a dynamic test's sample interval should be and what it is, or None.

    Parameters
    ----------
    time : ndarray
        The recording's time (s).
    kind : str
        Its kind; only :data:`DYNAMIC_KINDS` are judged.

    Returns
    -------
    (expected, found) or None
        None when the median interval is at most :data:`MAX_INTERVAL`.
    """
    dt = median_interval(time) if kind in DYNAMIC_KINDS else None
    if dt is None or dt <= MAX_INTERVAL:
        return None
    return (
        f"a sample interval of at most {MAX_INTERVAL * 1e3:g} ms for a {kind} test (its "
        "transients last 10-100 ms)",
        f"{dt:.4g} s ({time[-1] - time[0]:.4g} s in all): a time axis in another unit than its "
        "header says (ms under [s]?)",
    )


def temperature_out_of_range(temperature: NDArray[np.float64]) -> tuple[str, str] | None:
    """What a temperature channel should be and what it is, or None.

    Parameters
    ----------
    temperature : ndarray
        A gas or wall temperature channel (K).

    Returns
    -------
    (expected, found) or None
        None when the channel's 1st and 99th percentiles lie within
        :data:`TEMPERATURE_BOUNDS`; else the two halves of a problem message.
    """
    bulk = _bulk(temperature)
    if bulk is None:
        return None
    lo, hi = bulk
    low, high = TEMPERATURE_BOUNDS
    if low <= lo and hi <= high:
        return None
    return (
        f"temperatures of a pneumatic rig, {low:g} to {high:g} K",
        f"1st to 99th percentile {lo:.1f} to {hi:.1f} K: a channel in another unit than its "
        "header says (" + ("degC labelled K?)" if hi < low else "K labelled degC?)"),
    )


def position_beyond_stroke(position: NDArray[np.float64], stroke: float) -> tuple[str, str] | None:
    """What a recorded piston position should be and what it is, or None.

    Parameters
    ----------
    position : ndarray
        The recording's ``y`` channel (m).
    stroke : float
        The rig's declared stroke (m).

    Returns
    -------
    (expected, found) or None
        None when every sample lies within :data:`STROKE_TOLERANCE` of the
        stroke of [0, stroke]; else the two halves of a problem message.
    """
    x = np.asarray(position, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0 or not stroke > 0.0:
        return None
    allowed = STROKE_TOLERANCE * stroke
    lo, hi = float(x.min()), float(x.max())
    if -allowed <= lo and hi <= stroke + allowed:
        return None
    expected = (
        "a piston position from 0 (retracted) to the declared stroke "
        f"{_shown(stroke, 'length', '.4g')} (within {100 * STROKE_TOLERANCE:g} % of it, "
        f"{_shown(allowed, 'length', '.3g')})"
    )
    factor, unit = DISPLAY_UNITS["length"]
    found = (
        f"positions from {factor * lo:.6g} to {factor * hi:.6g} {unit}: a stroke declared too "
        "short, a position in another unit than its header says, a sensor counting the other way "
        "(the [read] table's reversed = true negates it) or its zero elsewhere than at the "
        "retracted end"
    )
    return expected, found


def controller_mismatch(recording: Recording) -> tuple[str, str] | None:
    """What a step test's recorded commands should follow and what they
    follow, or None (module doc).

    Parameters
    ----------
    recording : Recording
        A recording with a declared controller, ``y``, ``y_ref`` and ``u_P``
        (or ``u_N``); any other returns None, as does one with fewer than
        :data:`MIN_CONTROL_SAMPLES` unsaturated samples or a piston that
        does not move.

    Returns
    -------
    (expected, found) or None
    """
    c = recording.controller
    ch = recording.channels
    u = ch.get("u_P")
    if u is None and ch.get("u_N") is not None:
        u = -ch["u_N"]
    if c is None or u is None or "y" not in ch or "y_ref" not in ch or recording.n_samples < 3:
        return None
    t, y = recording.time, ch["y"]
    w = max(1, round(VELOCITY_WINDOW / float(np.median(np.diff(t)))))
    if t.size <= 2 * w:
        return None
    v = np.full(t.size, np.nan)
    v[w:-w] = (y[2 * w :] - y[: -2 * w]) / (t[2 * w :] - t[: -2 * w])
    e = ch["y_ref"] - y
    ok = np.isfinite(v) & np.isfinite(u) & np.isfinite(e) & (np.abs(u) < 0.95 * c.umax)
    if ok.sum() < MIN_CONTROL_SAMPLES or not np.ptp(y) > 0.0:
        return None
    design = np.c_[np.ones(ok.sum()), e[ok], -v[ok]]
    (u0, kp, kd), *_ = np.linalg.lstsq(design, u[ok], rcond=None)
    declared = np.clip(c.u0 + c.kp * e[ok] - c.kd * v[ok], -c.umax, c.umax)
    scale = float(np.sqrt(np.mean(u[ok] ** 2)))
    miss = float(np.sqrt(np.mean((u[ok] - declared) ** 2))) / scale if scale > 0 else 0.0
    # a motion along which y_ref - y and v are nearly proportional (a first-
    # order approach) leaves the two gains' split unknown: judged by the law
    # alone then
    with np.errstate(invalid="ignore"):
        collinear = not abs(float(np.corrcoef(e[ok], v[ok])[0, 1])) < MAX_GAIN_CORRELATION
    kp_off = not (c.kp / GAIN_TOLERANCE <= kp <= c.kp * GAIN_TOLERANCE)
    kd_off = c.kd > 0.0 and not (c.kd / 2.0 <= kd <= 2.0 * c.kd)
    if not (miss > LAW_TOLERANCE or (not collinear and (kp_off or kd_off))):
        return None
    expected = (
        f"commands that follow the declared pd law, kp {c.kp:.4g} V/m, kd {c.kd:.4g} V s/m, "
        f"u0 {c.u0:.4g} V (kp within a factor {GAIN_TOLERANCE:g}, kd within 2, the law within "
        f"{100 * LAW_TOLERANCE:g} % of the commands' RMS): the closed-loop replays run it"
    )
    found = (
        f"the recorded commands follow kp {kp:.4g} V/m, kd {kd:.4g} V s/m, u0 {u0:.3g} V "
        f"(least squares over {int(ok.sum())} unsaturated samples, v from the position), and "
        f"the declared law misses them by {100 * miss:.3g} % of their RMS: a gain in other "
        "units (V/mm for V/m?), a mistyped gain, or another controller than declared"
    )
    return expected, found


def recording_findings(
    recording: Recording, supply: float, exhaust: float, stroke: float | None = None
) -> list[tuple[str, str, str]]:
    """Every finding of this module on one recording: (channel, expected,
    found), a dynamic test sampled too slowly first (:func:`sampled_too_slowly`),
    its ``p_S`` (:func:`supply_mismatch`), then the chambers of
    a test with the piston held (:func:`chamber_beyond_bounds`) or moved
    (:func:`moved_chamber_out_of_range`), its temperatures
    (:func:`temperature_out_of_range`), then its
    position (:func:`position_beyond_stroke`, when ``stroke`` is given),
    then its commands against its controller (:func:`controller_mismatch`).

    Parameters
    ----------
    recording : Recording
    supply, exhaust : float
        The rig's declared supply and exhaust pressures (Pa absolute).
    stroke : float, optional
        The rig's declared stroke (m); None skips the position's check.

    Returns
    -------
    list of (str, str, str)
        The channel judged, what the declaration implies, what was read.
    """
    out = []
    found = sampled_too_slowly(recording.time, recording.kind)
    if found is not None:
        out.append(("time", *found))
    p_s = recording.channels.get("p_S")
    if p_s is not None:
        found = supply_mismatch(p_s, supply, exhaust)
        if found is not None:
            out.append(("p_S", *found))
    held = recording.kind in HELD_KINDS
    judge = chamber_beyond_bounds if held else moved_chamber_out_of_range
    for name in ("p_P", "p_N"):
        channel = recording.channels.get(name)
        if channel is None:
            continue
        found = judge(channel, supply, exhaust)
        if found is not None:
            out.append((name, *found))
    for name in ("T_P", "T_N"):
        channel = recording.channels.get(name)
        if channel is None:
            continue
        found = temperature_out_of_range(channel)
        if found is not None:
            out.append((name, *found))
    y = recording.channels.get("y")
    if y is not None and stroke is not None:
        found = position_beyond_stroke(y, stroke)
        if found is not None:
            out.append(("y", *found))
    found = controller_mismatch(recording)
    if found is not None:
        out.append(("u_P" if "u_P" in recording.channels else "u_N", *found))
    return out


def consistency_warnings(
    campaign: Campaign, recordings: Sequence[Recording] | None = None
) -> list[str]:
    """One sentence per finding of :func:`recording_findings` (a ``p_S``
    that disagrees with the declared supply pressure, a held chamber beyond
    the declared supply or exhaust pressure, a position beyond the stroke,
    commands that do not follow the declared controller), in campaign order.

    Parameters
    ----------
    campaign : Campaign
    recordings : sequence of Recording, optional
        Those to judge (default: every recording of the campaign).
    """
    rig = campaign.rig
    out = []
    for rec in campaign.recordings if recordings is None else recordings:
        for name, expected, found in recording_findings(
            rec, rig.supply_pressure, rig.exhaust_pressure, rig.stroke
        ):
            out.append(f"{rec.file}: {name}: expected {expected}; found {found}")
    return out
