"""Long closed-loop step tests fitted in segments (multiple shooting).

A closed-loop step test replays the model's own controller: every error of
the model feeds back into its valve commands. Where the piston sticks and
slips, an error of a newton in the force at which it breaks away, or of a
few per cent in the flow through a valve just past its dead band (where a
controller holding a set-point against friction sits), moves a breakaway by
tens of milliseconds; the loop then follows another trajectory, and after a
few set-point changes the model and the rig are centimetres apart, also
with the rig's own laws. The likelihood of such a recording is a landscape
of cliffs (each breakaway that moves from one sample to the next), and least
squares stop on one of them far from the truth.

Measured (``pneumafit rig --truth fit-laws --protocol sparse-long --seed 1``,
the fit's own laws, 8-s tests with four set-point changes; convection,
``--no-mcmc --seed 1``): fitted whole, the fit step test ended at 7.2x the
pressure noise and 222x the position noise, the held-out one at 10.6x, and
the LuGre law lost to the switch model. Fitted in segments, the fit
recording's segments reach 1.0-3.2x in pressure, the held-out step test,
replayed whole, 1.3x / 1.4x (p_P / p_N), and the static and Coulomb
friction are within 0.4 % and 0.1 % of the truth.

This is multiple shooting (Bock and Plitt 1984; for system identification,
Ribeiro, Tiels, Umenberger, Schön and Aguirre 2020, "On the smoothness of
nonlinear system identification", Automatica 121): each segment starts from
its own initial state, fitted like a recording's (the measured position and
pressures, the gas temperatures; nuisance parameters with the sensors'
priors), so a model error cannot carry from one segment into the next.
A segment whose first 50 ms show the piston still moving starts at that
velocity (:func:`~pneumafit.identification.problem.initial_velocity`),
not at rest. The
segments are the step test's stretches between set-point changes, each
starting :data:`LEAD` before its change (the piston then rests or creeps
near its set-point), the first with the recording's start; no segment is
shorter than :data:`MIN_SEGMENT`.

Only ``fit`` step tests are cut: held-out recordings are always predicted
whole, from their first sample, so the validation figures are those of a
whole-recording prediction. ``auto`` cuts step tests of at least
:data:`AUTO_DURATION`: the demo plan's 4.5-s step tests fit whole to 1.6x
on ``data/demo-clean`` (a truth unlike the fit's), and their closed loops
make two to four breakaways; the sparse-long plan's 8-s tests do not.
"""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.errors import PneumafitInputError

__all__ = [
    "AUTO_DURATION",
    "LEAD",
    "MIN_SEGMENT",
    "SEGMENT_MODES",
    "segment_name",
    "segment_step_tests",
    "source_recording",
]

#: ``FitOptions.segments``: ``auto`` (step tests of at least
#: :data:`AUTO_DURATION`), ``on`` (every fit step test with a set-point
#: change after its first :data:`MIN_SEGMENT`), ``off``.
SEGMENT_MODES = ("auto", "on", "off")
#: Shortest fit step test (s) that ``auto`` cuts.
AUTO_DURATION = 6.0
#: Time (s) before a set-point change at which its segment starts: a few
#: samples of the piston at rest for the initial state's estimate.
LEAD = 0.05
#: Shortest segment (s): a change closer than this to the segment's start
#: stays inside the segment.
MIN_SEGMENT = 1.0


def segment_name(file: str, start: float) -> str:
    """Name of the segment of recording ``file`` that starts at ``start`` s."""
    return f"{file}@{start:.3f}s"


_SEGMENT = re.compile(r"^(?P<file>.+)@\d+\.\d{3}s$")


def source_recording(name: str) -> str:
    """The recording a segment was cut from (:func:`segment_name`); any other
    name as it is. The segments of one test share its conditions (supply,
    controller, the gas's history), so the sandwich over recordings and the
    one-recording caveat count them as one recording, not as independent
    tests that could contradict each other."""
    m = _SEGMENT.match(name)
    return m.group("file") if m else name


def _cuts(rec: Recording) -> list[int]:
    """Sample indices where the segments of ``rec`` start (the first is 0)."""
    t = rec.time
    y_ref = np.asarray(rec.channels["y_ref"], dtype=float)
    changes = np.nonzero(np.abs(np.diff(y_ref)) > 0.0)[0] + 1
    starts = [0]
    for k in changes:
        lead = int(np.searchsorted(t, t[k] - LEAD))
        if t[lead] - t[starts[-1]] >= MIN_SEGMENT and t[-1] - t[lead] >= MIN_SEGMENT:
            starts.append(lead)
    return starts


def _segment(rec: Recording, a: int, b: int) -> Recording:
    t0 = float(rec.time[a])
    return replace(
        rec,
        file=segment_name(rec.file, t0),
        time=rec.time[a:b] - t0,
        channels={k: np.asarray(v)[a:b].copy() for k, v in rec.channels.items()},
        mask={k: np.asarray(v)[a:b].copy() for k, v in rec.mask.items()},
        description=f"{rec.file} from {t0:.3f} s"
        + (f"; {rec.description}" if rec.description else ""),
    )


def segment_step_tests(campaign: Campaign, mode: str = "auto") -> tuple[Campaign, list[str]]:
    """The campaign with its long ``fit`` step tests cut into segments (module doc).

    Parameters
    ----------
    campaign : Campaign
    mode : {"auto", "on", "off"}
        :data:`SEGMENT_MODES`.

    Returns
    -------
    Campaign
        The same campaign (the same object with ``off`` or nothing to cut),
        with each cut recording replaced by its segments, named
        ``FILE@STARTs`` (:func:`segment_name`), times from 0.
    list of str
        One line per cut recording, for the fit's log.

    Raises
    ------
    PneumafitInputError
        An unknown mode.
    """
    if mode not in SEGMENT_MODES:
        raise PneumafitInputError(
            f"segments: expected one of {', '.join(SEGMENT_MODES)}, found {mode!r}"
        )
    if mode == "off":
        return campaign, []
    out: list[Recording] = []
    lines: list[str] = []
    for rec in campaign.recordings:
        duration = float(rec.time[-1] - rec.time[0]) if rec.time.size else 0.0
        if (
            rec.role != "fit"
            or rec.kind != "step"
            or rec.controller is None
            or "y_ref" not in rec.channels
            or (mode == "auto" and duration < AUTO_DURATION)
        ):
            out.append(rec)
            continue
        starts = _cuts(rec)
        if len(starts) == 1:
            out.append(rec)
            continue
        ends = [*starts[1:], rec.time.size]
        out.extend(_segment(rec, a, b) for a, b in zip(starts, ends, strict=True))
        lines.append(
            f"{rec.file} ({duration:.1f} s, closed loop) fitted in {len(starts)} segments from "
            # on the file's time axis, as the segments' names (segment_name)
            + ", ".join(f"{rec.time[a]:.3f}" for a in starts)
            + " s, each from its own initial state (multiple shooting)"
        )
    if not lines:
        return campaign, []
    return replace(campaign, recordings=out), lines
