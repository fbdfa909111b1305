"""Which valve commands did the flow tests measure, and which do the other tests use?

The valve characteristic is measured by the flow tests at a few command
levels; every other test drives the valves with commands of its own (the
0-V rest of charge/discharge tests, the controller's output in step tests).
Where a test spends time at commands that no flow level is close to, its
valve flows are an extrapolation of the fitted characteristic (on an
independently written rig: a flow test without a 0-V level, and a discharge
whose rest-phase drift the fit then blamed on the heat law). This module
names those commands and the recordings that use them.

A command u used by a recording is *covered* by the flow-test levels of the
same valve (or, without a flow test of that valve, of the other one, whose
characteristic the fit shares) when a level lies within :data:`TOLERANCE` x
u_sat of it, or, away from the centre (|u| > 2 :data:`TOLERANCE` u_sat,
beyond the dead band and the centre leakage, where the characteristic
changes fastest), when it lies between two levels at most :data:`MAX_GAP` x
u_sat apart. Commands are binned at the tolerance; a bin counts when it
holds at least :data:`MIN_SHARE` of the recording's samples.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from pneumafit.campaign.model import Campaign, Recording

__all__ = [
    "MAX_GAP",
    "MIN_SHARE",
    "TOLERANCE",
    "centre_measured",
    "extrapolation_spread",
    "opened_paths",
    "unbracketed_edges",
    "uncovered_commands",
    "uncovered_ranges",
]

#: Largest distance (fraction of u_sat) from a flow level for a command to
#: count as measured: 0.5 V of a 10-V valve, the width of its dead band.
TOLERANCE = 0.05
#: Largest gap (fraction of u_sat) between two flow levels that a command
#: between them may be interpolated over (4 V of a 10-V valve: the demo plan
#: spaces its top levels 6 and 10 V apart).
MAX_GAP = 0.4
#: Smallest share of a recording's samples in a command bin that is reported.
MIN_SHARE = 0.01
#: Widest gap (fraction of u_sat) between the two flow levels around a
#: path's fitted dead-band edge for the edge to count as measured
#: (:func:`unbracketed_edges`): 1 V of a 10-V valve, twice the tolerance.
#: Between them the conductance rises from the centre leakage to the next
#: level's, by the law's opening shape alone; a closed loop holds its
#: piston with commands there.
EDGE_GAP = 0.1
#: Command bins (fraction of u_sat) of :func:`unbracketed_edges`: 0.1 V of a
#: 10-V valve, finer than a dead band.
EDGE_BIN = 0.01
#: Commands compared per range by :func:`extrapolation_spread`.
SPREAD_POINTS = 5
#: Share of the full-opening flow below which :func:`extrapolation_spread`
#: compares flows to it rather than to the kept law's own flow: 1 %, about a
#: centre leakage's share of a servo-valve's rated flow.
SPREAD_FLOOR = 0.01


def _levels(campaign: Campaign) -> dict[str, np.ndarray]:
    out: dict[str, list[float]] = {"P": [], "N": []}
    for rec in campaign.recordings:
        if rec.kind != "flow" or rec.chamber not in out:
            continue
        u = np.asarray(rec.channels.get(f"u_{rec.chamber}", []), float)
        if u.size:
            out[rec.chamber].extend(np.unique(np.round(u, 6)).tolist())
    return {c: np.unique(v) for c, v in out.items()}


def _covered(u: float, levels: np.ndarray, width: float, u_sat: float) -> bool:
    if np.min(np.abs(levels - u)) <= width:
        return True
    if abs(u) <= 2.0 * width:
        return False
    below, above = levels[levels <= u], levels[levels >= u]
    return bool(below.size and above.size and above.min() - below.max() <= MAX_GAP * u_sat)


#: Distinct opening levels (beyond the tolerance of 0 V) a path needs in the
#: fit flow tests before its opening shape exponent is fitted: with the
#: full-opening conductance and the overlap, the exponent is the third unknown
#: of the path's C(u).
SHAPE_LEVELS = 3


def opening_levels(campaign: Campaign, values: Mapping[str, float]) -> dict[str, int]:
    """Distinct opening levels of each path in the fit flow tests.

    Both valves share one characteristic, so the levels of every fit flow test
    count: positive commands open the supply path, negative ones the exhaust
    path; levels within the tolerance of 0 V count for neither.

    Returns
    -------
    dict
        ``{"supply": int, "exhaust": int}``.
    """
    width = TOLERANCE * float(values.get("valve_u_sat", 10.0))
    levels: set[float] = set()
    for rec in campaign.by_role("fit"):
        if rec.kind == "flow" and f"u_{rec.chamber}" in rec.channels:
            levels.update(np.unique(np.round(np.asarray(rec.channels[f"u_{rec.chamber}"]), 3)))
    lv = np.array(sorted(levels))
    return {"supply": int(np.sum(lv > width)), "exhaust": int(np.sum(lv < -width))}


def shape_informed(
    campaign: Campaign, values: Mapping[str, float], levels: int = SHAPE_LEVELS
) -> dict[str, bool]:
    """Which paths' opening shapes (``valve_n_supply``, ``valve_n_exhaust``) the fit
    flow tests resolve.

    Parameters
    ----------
    campaign : Campaign
    values : mapping
        Model values (``valve_u_sat`` sets the tolerance of 0 V, V).
    levels : int
        Distinct levels a path needs (:data:`SHAPE_LEVELS`; :func:`full_informed`
        asks for :data:`FULL_LEVELS`).

    Returns
    -------
    dict
        ``{"supply": bool, "exhaust": bool}``: at least ``levels`` distinct
        levels on that side (:func:`opening_levels`).
    """
    return {path: n >= levels for path, n in opening_levels(campaign, values).items()}


#: Distinct opening levels a path needs before its full-opening fraction
#: (``valve_full_supply``, ``valve_full_exhaust``) is fitted: one more than
#: the exponent, the fourth unknown of the path's C(u).
FULL_LEVELS = SHAPE_LEVELS + 1


def full_informed(campaign: Campaign, values: Mapping[str, float]) -> dict[str, bool]:
    """Which paths' full-opening fractions the fit flow tests resolve: at least
    :data:`FULL_LEVELS` distinct levels on that side (:func:`shape_informed`)."""
    return shape_informed(campaign, values, FULL_LEVELS)


def centre_measured(campaign: Campaign, values: Mapping[str, float]) -> bool:
    """True when a flow test has a level within the tolerance of 0 V (centre leakage)."""
    width = TOLERANCE * float(values.get("valve_u_sat", 10.0))
    return any(v.size and np.min(np.abs(v)) <= width for v in _levels(campaign).values())


def opened_paths(recordings: Sequence[Recording], values: Mapping[str, float]) -> dict[str, bool]:
    """Which valve paths the recordings open past the dead band.

    Used without a flow test: the charge/discharge and step tests then
    measure the valve's conductances instead. A charge or discharge opens
    the path its command's sign selects (u > +u_0: supply, u < -u_0:
    exhaust, u_0 = ``valve_overlap``) on at least :data:`MIN_SHARE` of its
    samples; a step or free test opens both whenever it moves (one chamber
    fills through its supply path while the other empties through its
    exhaust path), also when its closed loop's commands are not recorded.

    Parameters
    ----------
    recordings : sequence of Recording
    values : mapping
        Model values (``valve_overlap``, V; ``valve_u_sat`` sets the margin).

    Returns
    -------
    dict
        ``{"supply": bool, "exhaust": bool}``.
    """
    edge = float(values.get("valve_overlap", 0.0)) + TOLERANCE * float(
        values.get("valve_u_sat", 10.0)
    )
    out = {"supply": False, "exhaust": False}
    for rec in recordings:
        if rec.kind in ("step", "free"):
            y = np.asarray(rec.channels.get("y", []), float)
            y = y[np.isfinite(y)]
            if y.size and np.ptp(y) > 0.0:
                out = {"supply": True, "exhaust": True}
            continue
        if rec.kind not in ("charge", "discharge"):
            continue
        u = np.asarray(rec.channels.get(f"u_{rec.chamber}", []), float)
        u = u[np.isfinite(u)]
        if not u.size:
            continue
        out["supply"] |= bool(np.mean(u > edge) >= MIN_SHARE)
        out["exhaust"] |= bool(np.mean(u < -edge) >= MIN_SHARE)
    return out


def uncovered_commands(campaign: Campaign, values: Mapping[str, float]) -> list[str]:
    """One warning per valve and command range not covered by a flow test.

    Parameters
    ----------
    campaign : Campaign
    values : mapping
        Model values (``valve_u_sat`` sets the tolerance, V).

    Returns
    -------
    list of str
        E.g. ``"valve P: commands -0.25..0.25 V (rest of discharge_P_1.h5 ...)
        were not measured by a flow test ..."``; empty when all are covered.
    """
    u_sat = float(values.get("valve_u_sat", 10.0))
    width = TOLERANCE * u_sat
    levels = _levels(campaign)
    if not any(v.size for v in levels.values()):
        return _unused_without_flow(campaign, width)
    return [
        f"valve {valve}: commands {lo:+.2f}..{hi:+.2f} V, used by {shown}, were not "
        f"measured by any flow test{source}: the valve flows there are extrapolated "
        "from the fitted characteristic"
        for valve, lo, hi, shown, source in uncovered_ranges(campaign, values)
    ]


def uncovered_ranges(
    campaign: Campaign, values: Mapping[str, float]
) -> list[tuple[str, float, float, str, str]]:
    """The command ranges of :func:`uncovered_commands` (campaigns with a flow test).

    Returns
    -------
    list of (str, float, float, str, str)
        Valve (``"P"`` or ``"N"``), lowest and highest command (V), the
        recordings that use them (shown), and the source of the levels
        (empty, or a parenthesis naming the other valve's flow test).
    """
    u_sat = float(values.get("valve_u_sat", 10.0))
    width = TOLERANCE * u_sat
    levels = _levels(campaign)
    out = []
    for valve in ("P", "N"):
        own = levels[valve]
        ref = own if own.size else levels["N" if valve == "P" else "P"]
        if not ref.size:
            continue
        source = "" if own.size else f" (no flow test of valve {valve}: valve "
        if not own.size:
            source += f"{'N' if valve == 'P' else 'P'}'s levels used)"
        users: dict[int, list[str]] = {}
        for rec in campaign.recordings:
            if rec.kind == "flow":
                continue
            for b in _bins(rec, valve, width):
                if not _covered(b * width, ref, width, u_sat):
                    users.setdefault(b, []).append(rec.file)
        out.extend((valve, lo, hi, shown, source) for lo, hi, shown in _ranges(users, width))
    return out


def extrapolation_spread(
    campaign: Campaign,
    kept: Mapping[str, float],
    alternative: Mapping[str, float],
    *,
    valve_law: int = 0,
    points: int = SPREAD_POINTS,
) -> list[tuple[str, float, float, str, float, float]]:
    """How far apart two valve characteristics are where no flow test measured.

    Two laws that the flow tests fit about equally (a knee and a corner at
    full opening: :func:`pneumafit.identification.staged.identify`'s valve
    stage) may still differ between the flow levels, where the other tests
    use the valve: by as much as the flows there are uncertain, which no
    interval of the kept law's parameters shows.

    Parameters
    ----------
    campaign : Campaign
    kept, alternative : mapping of str to float
        Model values (SI) of the two characteristics (rig values included).
    valve_law : int
        Kernel code of their valve law (0: ISO 6358).
    points : int
        Commands compared per range, evenly spaced from its lowest to its
        highest.

    Returns
    -------
    list of (str, float, float, str, float, float)
        Per range of :func:`uncovered_ranges`: valve, lowest and highest
        command (V), the recordings that use it (shown), the largest
        difference |q_alt - q_kept| of the valve's net mass flow into a
        chamber at the mean of the supply and exhaust pressures and at the
        ambient temperature, over |q_kept| or :data:`SPREAD_FLOOR` times the
        flow at full opening on the same side (u_sat or -u_sat), whichever
        is larger (-): near the centre the net flow crosses zero and a ratio
        to it means nothing; and the command where it is (V).
    """
    from pneumafit.models.kernel import static_valve_flows
    from pneumafit.models.parameters import parameter_vector

    pk, pa = parameter_vector(kept), parameter_vector(alternative)
    pres = 0.5 * (float(kept["supply_pressure"]) + float(kept["exhaust_pressure"]))
    temp = float(kept["ambient_temperature"])
    u_sat = float(kept.get("valve_u_sat", 10.0))
    full = {
        side: abs(static_valve_flows(pk, valve_law, side * u_sat, pres, temp)[0])
        for side in (-1.0, 1.0)
    }  # fmt: skip
    out = []
    for valve, lo, hi, shown, _ in uncovered_ranges(campaign, kept):
        worst, where = 0.0, lo
        for u in np.linspace(lo, hi, max(int(points), 2)):
            q_k = static_valve_flows(pk, valve_law, float(u), pres, temp)[0]
            q_a = static_valve_flows(pa, valve_law, float(u), pres, temp)[0]
            scale = max(abs(q_k), SPREAD_FLOOR * full[1.0 if u >= 0.0 else -1.0])
            if scale > 0.0 and abs(q_a - q_k) / scale > worst:
                worst, where = abs(q_a - q_k) / scale, float(u)
        out.append((valve, lo, hi, shown, worst, where))
    return out


def _bins(rec: Recording, valve: str, width: float) -> list[int]:
    """The command bins of width ``width`` (V) holding at least
    :data:`MIN_SHARE` of ``rec``'s samples of ``u_<valve>``."""
    u = rec.channels.get(f"u_{valve}")
    if u is None:
        return []
    u = np.asarray(u, float)
    u = u[np.isfinite(u)]
    if not u.size:
        return []
    ids, counts = np.unique(np.round(u / width).astype(int), return_counts=True)
    return [int(b) for b, n in zip(ids, counts, strict=True) if n >= MIN_SHARE * u.size]


def _ranges(users: Mapping[int, list[str]], width: float) -> list[tuple[float, float, str]]:
    """Neighbouring bins merged: (lowest command, highest command, the
    recordings that use them, shown)."""
    if not users:
        return []
    keys = sorted(users)
    ranges: list[list[int]] = [[keys[0], keys[0]]]
    for k in keys[1:]:
        if k == ranges[-1][1] + 1:
            ranges[-1][1] = k
        else:
            ranges.append([k, k])
    out = []
    for a, b in ranges:
        recs = sorted({f for k in range(a, b + 1) for f in users.get(k, [])})
        shown = ", ".join(recs[:4]) + (f" and {len(recs) - 4} more" if len(recs) > 4 else "")
        out.append(((a - 0.5) * width, (b + 0.5) * width, shown))
    return out


def _unused_without_flow(campaign: Campaign, width: float) -> list[str]:
    """Without a flow test: the commands of the other recordings that no fit
    recording used (either valve: the fit shares one characteristic), within
    one bin of ``width`` (V). The fit's valve comes from the fit tests' own
    commands (:func:`opened_paths`); elsewhere it is extrapolated."""
    used: set[int] = set()
    for rec in campaign.recordings:
        if rec.role == "fit" and rec.kind != "flow":
            for valve in ("P", "N"):
                used.update(_bins(rec, valve, width))
    out = []
    for valve in ("P", "N"):
        users: dict[int, list[str]] = {}
        for rec in campaign.recordings:
            if rec.role == "fit" or rec.kind == "flow":
                continue
            for b in _bins(rec, valve, width):
                if not {b - 1, b, b + 1} & used:
                    users.setdefault(b, []).append(rec.file)
        for lo, hi, shown in _ranges(users, width):
            out.append(
                f"valve {valve}: commands {lo:+.2f}..{hi:+.2f} V, used by {shown}, were used "
                "by no fit recording and there is no flow test: the valve flows there are "
                "extrapolated from the fitted characteristic"
            )
    return out


def unbracketed_edges(campaign: Campaign, values: Mapping[str, float]) -> list[str]:
    """One warning per valve path whose opening edge no pair of close flow
    levels brackets, naming the commands there that other tests use.

    A path starts to open at the fitted dead-band edge (``valve_null_offset
    +- valve_overlap``). When the flow levels on either side of it are more
    than :data:`EDGE_GAP` x u_sat apart, the conductance between them (from
    the centre leakage to the next level's) is the law's opening shape,
    fitted elsewhere; the commands other tests use strictly between those
    levels, binned at :data:`EDGE_BIN` x u_sat, rest on it. Independent of
    :func:`uncovered_commands`, whose tolerance counts a command half a dead
    band from a level as measured.

    Parameters
    ----------
    campaign : Campaign
    values : mapping
        Fitted values: ``valve_overlap`` (V; without it, e.g. the measured
        map, nothing is said), ``valve_null_offset`` (V, default 0),
        ``valve_u_sat`` (V, default 10).

    Returns
    -------
    list of str
        Empty without flow tests, without an overlap, or when every edge is
        bracketed or no test uses commands around it.
    """
    if "valve_overlap" not in values:
        return []
    u_sat = float(values.get("valve_u_sat", 10.0))
    overlap = float(values["valve_overlap"])
    offset = float(values.get("valve_null_offset", 0.0))
    levels = _levels(campaign)
    if not any(v.size for v in levels.values()):
        return []
    width = EDGE_BIN * u_sat
    out = []
    for path, edge, sign in (("supply", offset + overlap, 1.0),
                             ("exhaust", offset - overlap, -1.0)):  # fmt: skip
        # per gap around the edge (the valves may differ in levels): the valves,
        # and the commands used there (bins) with their recordings
        gaps: dict[tuple[float, float], tuple[list[str], dict[int, set[str]]]] = {}
        for valve in ("P", "N"):
            ref = levels[valve] if levels[valve].size else levels["N" if valve == "P" else "P"]
            inner = ref[sign * ref <= sign * edge]
            outer = ref[sign * ref > sign * edge]
            near = float(inner[np.argmax(sign * inner)]) if inner.size else -math.inf * sign
            far = float(outer[np.argmin(sign * outer)]) if outer.size else math.inf * sign
            if abs(far - near) <= EDGE_GAP * u_sat:
                continue
            lo, hi = min(near, far), max(near, far)
            valves, users = gaps.setdefault((lo, hi), ([], {}))
            for rec in campaign.recordings:
                if rec.kind == "flow":
                    continue
                for b in _bins(rec, valve, width):
                    # strictly between the levels, on the path's side of the centre
                    if lo < b * width < hi and sign * (b * width - offset) > 0.0:
                        users.setdefault(b, set()).add(rec.file)
                        if valve not in valves:
                            valves.append(valve)
        for (lo, hi), (valves, users) in gaps.items():
            if not users:
                continue
            between = " and ".join(f"{x:+.2f} V" for x in (lo, hi) if math.isfinite(x))
            where = (f"between flow levels {between}" if math.isfinite(lo + hi)
                     else f"beyond every flow level on that side (nearest {between})")  # fmt: skip
            recs = sorted(set().union(*users.values()))
            shown = ", ".join(recs[:4]) + (f" and {len(recs) - 4} more" if len(recs) > 4 else "")
            a, z = (min(users) - 0.5) * width, (max(users) + 0.5) * width
            out.append(
                f"valve{'s' if len(valves) > 1 else ''} {' and '.join(valves)}: the {path} "
                f"path's opening edge (fitted {edge:+.2f} V) lies {where}; commands "
                f"{a:+.2f}..{z:+.2f} V, used by {shown}, rest on the fitted law there, not on a "
                "measured flow (a flow level between them would measure it)"
            )
    return out
