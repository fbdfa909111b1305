"""Long closed-loop step tests fitted in segments (``identification.segments``)."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import PneumafitInputError, read_campaign
from pneumafit.cli.rig import run_rig
from pneumafit.identification.problem import (
    MIN_MOVING,
    MOVING_AT_START,
    OFFSET_AGREEMENT,
    OFFSET_DETERMINED,
    OFFSET_LIMIT,
    OFFSET_PREFIX,
    Problem,
    SensorOffset,
    initial_velocity,
    pressure_offsets,
    started_moving,
)
from pneumafit.identification.segments import (
    AUTO_DURATION,
    LEAD,
    segment_name,
    segment_step_tests,
)
from pneumafit.identification.staged import fit_structure


def _record(folder: Path, truth: str, seed: int = 1) -> Path:
    quiet = Console(file=io.StringIO(), width=200, color_system=None)
    assert run_rig(folder, seed=seed, console=quiet, protocol="sparse-long", truth=truth) == 0
    return folder


@pytest.fixture(scope="module")
def long_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sparse-long plan (8-s step tests, set-point changes at 0.5, 2.5,
    4.5 and 6.5 s) on the rig's control truth (the fit's laws)."""
    return _record(tmp_path_factory.mktemp("segments") / "long", "fit-laws")


def test_a_long_fit_step_test_is_cut_at_its_set_point_changes(long_campaign: Path) -> None:
    """Plumbing, exact: the fit step test is cut LEAD before each set-point
    change at least a second from the segment's start (the change at 0.5 s
    stays in the first); each segment is the recording's samples from there,
    its time from 0; the held-out step test, the flow and charge/discharge
    tests are the same objects."""
    camp = read_campaign(long_campaign)
    cut, lines = segment_step_tests(camp, "auto")
    whole = next(r for r in camp.recordings if r.file == "step_1.h5")
    assert whole.time[-1] - whole.time[0] >= AUTO_DURATION
    segs = [r for r in cut.recordings if r.file.startswith("step_1.h5@")]
    starts = [2.5 - LEAD, 4.5 - LEAD, 6.5 - LEAD]
    assert [r.file for r in segs] == [segment_name("step_1.h5", t) for t in (0.0, *starts)]
    assert [r.file for r in segs][1] == "step_1.h5@2.450s"
    joined = np.concatenate([r.channels["p_N"] for r in segs])
    np.testing.assert_array_equal(joined, whole.channels["p_N"])
    for seg, t0 in zip(segs, (0.0, *starts), strict=True):
        assert seg.time[0] == 0.0
        k = int(np.argmin(np.abs(whole.time - t0)))
        np.testing.assert_array_equal(seg.channels["y"][:5], whole.channels["y"][k : k + 5])
        np.testing.assert_allclose(seg.time[:5] + whole.time[k], whole.time[k : k + 5])
        assert seg.role == "fit" and seg.controller == whole.controller
    others = [r for r in cut.recordings if not r.file.startswith("step_1.h5@")]
    assert [r.file for r in others] == [r.file for r in camp.recordings if r.file != "step_1.h5"]
    kept = [r for r in camp.recordings if r is not whole]
    assert all(a is b for a, b in zip(others, kept, strict=True))
    assert len(lines) == 1 and "step_1.h5 (8.0 s, closed loop) fitted in 4 segments" in lines[0]
    assert segment_step_tests(camp, "off") == (camp, [])
    with pytest.raises(PneumafitInputError, match="segments: expected one of auto, on, off"):
        segment_step_tests(camp, "sometimes")


def test_auto_leaves_short_step_tests_whole_and_on_cuts_them(tmp_path: Path) -> None:
    """Plumbing: the demo plan's 4.5-s step tests stay whole under auto;
    ``on`` cuts each fit one 50 ms before each set-point change. The sparse
    plan's 2-s tests (changes at 0.3 and 1.2 s) stay whole under ``on`` too:
    a cut at 1.15 s would leave a last segment shorter than 1 s."""
    quiet = Console(file=io.StringIO(), width=200, color_system=None)
    assert run_rig(tmp_path / "d", seed=1, console=quiet, protocol="demo", truth="fit-laws") == 0
    camp = read_campaign(tmp_path / "d")
    assert segment_step_tests(camp, "auto") == (camp, [])
    cut, lines = segment_step_tests(camp, "on")
    fit_steps = [r.file for r in camp.recordings if r.kind == "step" and r.role == "fit"]
    assert fit_steps and len(lines) == len(fit_steps)
    # step_3's set-point changes at 0.5, 1.5, 2.5 and 3.5 s, the others' at 0.5 and 2.5 s
    expected = {"step_3.h5": (0.0, 1.45, 2.45, 3.45)}
    for name in fit_steps:
        segs = [r.file for r in cut.recordings if r.file.startswith(name + "@")]
        starts = expected.get(name, (0.0, 2.45))
        assert segs == [segment_name(name, t) for t in starts], segs
    held = [r for r in camp.recordings if r.role == "validate"]
    assert all(any(c is r for c in cut.recordings) for r in held)
    assert run_rig(tmp_path / "s", seed=1, console=quiet, protocol="sparse", truth="fit-laws") == 0
    sparse = read_campaign(tmp_path / "s")
    assert segment_step_tests(sparse, "on") == (sparse, [])


def test_the_initial_velocity_is_read_from_the_first_samples() -> None:
    """Synthetic, truth known: 50 samples over 49 ms of y = y0 + v0 t + a t^2 / 2
    (v0 65 mm/s, a -3 m/s^2, as a segment starting on a piston that still
    settles) with 3 um of Gaussian noise and a 10 um resolution (the virtual
    rig's position sensor). The velocity comes back within 2 %: over 400
    noise draws its spread is 0.16 mm/s (0.25 %) and its largest error
    0.8 %, so 2 % fails on a wrong slope (a linear fit's, a wrong time
    origin), not on the noise. At rest (noise and
    resolution only), on a creep of one count over the window and on a
    stick-slip creep of 5 mm/s (below MIN_MOVING, 20 mm/s; the mismatched
    truths' segments start so) it is None: the simulation starts at rest,
    as before."""
    rng = np.random.default_rng(7)
    t = np.arange(50) * 1e-3
    window = np.ones(t.size, bool)

    def sensed(y: np.ndarray) -> np.ndarray:
        return np.round((y + rng.normal(0.0, 3e-6, y.size)) / 1e-5) * 1e-5

    v = initial_velocity(t, sensed(0.3428 + 0.065 * t - 1.5 * t**2), window)
    assert v == pytest.approx(0.065, rel=0.02)
    assert initial_velocity(t, sensed(np.full(t.size, 0.25)), window) is None
    creep = 0.25 + 1e-5 * (t > 0.025)
    assert initial_velocity(t, creep, window) is None
    assert initial_velocity(t, sensed(0.25 - 0.005 * t), window) is None
    assert MOVING_AT_START >= 5.0 and MIN_MOVING == pytest.approx(0.02)
    assert initial_velocity(t[:5], sensed(0.3 + 0.065 * t[:5]), window[:5]) is None


def test_a_segment_that_starts_on_a_moving_piston_starts_moving(long_campaign: Path) -> None:
    """Plumbing, on the control truth's sparse-long plan (seed 1): at 2.45 s,
    the second segment's start, the piston still moves toward its last
    set-point (its position rises 2.7 mm in the 50 ms before the next change).
    That segment's experiment starts at that velocity (positive, 30-100 mm/s:
    65 mm/s measured by the derivative of a quadratic over those 50 ms; the
    bounds only say "moving up, at a piston's speed"); the whole tests and the
    segments starting at rest start at rest. Before, every segment started at
    rest, and this one's position misfit was 162x the noise after the fit."""
    cut, _ = segment_step_tests(read_campaign(long_campaign), "auto")
    recs = [r for r in cut.recordings if r.kind == "step"]
    prob = Problem(recs, fit_structure("convection"), {}, channels=("p_P", "p_N", "y"))
    pairs = zip(prob.recordings, prob.experiments, strict=True)
    v0 = {r.file: e.initial.get("v") for r, e in pairs}
    assert 0.03 < v0.pop("step_1.h5@2.450s") < 0.1
    assert v0 == dict.fromkeys(v0), v0
    assert set(v0) == {"step_1.h5@0.000s", "step_1.h5@4.450s", "step_1.h5@6.450s", "step_2.h5"}


def test_segment_names_and_the_line_read_the_files_time_axis(long_campaign: Path) -> None:
    """Plumbing, exact: a recording whose time axis starts at 12.345 s (a
    logger's clock) is cut at the same samples; the segments' names and the
    console line give the cuts on the file's axis, the same numbers (the
    line gave them from the recording's start before 2026-12-01, so a user
    read 2.45 s there and 14.795 s in the names)."""
    import dataclasses

    camp = read_campaign(long_campaign)
    shifted = dataclasses.replace(
        camp,
        recordings=[dataclasses.replace(r, time=r.time + 12.345) for r in camp.recordings],
    )
    cut, lines = segment_step_tests(shifted, "auto")
    names = [r.file for r in cut.recordings if r.file.startswith("step_1.h5@")]
    assert names == [segment_name("step_1.h5", 12.345 + t) for t in (0.0, 2.45, 4.45, 6.45)]
    assert lines and "from 12.345, 14.795, 16.795, 18.795 s" in lines[0], lines


def test_held_out_recordings_start_from_readings_less_the_sensor_offsets(
    long_campaign: Path,
) -> None:
    """Plumbing, exact: a problem given ``offset:p_P`` / ``offset:p_N``
    takes them off the initial pressures it reads from the data (the
    held-out step test's, and any recording's whose initial state is not
    fitted), keeps the readings in ``measured_initial``, and leaves
    positions and temperatures alone; without them nothing changes.
    ``pressure_offsets`` is the median, per channel, of reading less fitted
    initial pressure over the recordings that have one (made-up fitted
    values for three of the five step recordings, the fit step test's
    segments and the held-out test: readings less 900, 1000 and 5000 Pa
    give 1000); with two, none (``MIN_OFFSET_RECORDINGS``)."""
    cut, _ = segment_step_tests(read_campaign(long_campaign), "auto")
    recs = [r for r in cut.recordings if r.kind == "step"]
    kw = {"channels": ("p_P", "p_N", "y")}
    plain = Problem(recs, fit_structure("convection"), {}, **kw)
    offsets = {f"{OFFSET_PREFIX}p_P": -960.0, f"{OFFSET_PREFIX}p_N": 590.0}
    shifted = Problem(recs, fit_structure("convection"), offsets, **kw)
    for a, b in zip(plain.experiments, shifted.experiments, strict=True):
        read = shifted.measured_initial[a.name]
        assert read["p_P"] == a.initial["p_P"] and read["p_N"] == a.initial["p_N"]
        assert b.initial["p_P"] == pytest.approx(a.initial["p_P"] + 960.0, abs=1e-6)
        assert b.initial["p_N"] == pytest.approx(a.initial["p_N"] - 590.0, abs=1e-6)
        assert b.initial["y"] == a.initial["y"]
    names = _at_rest(plain)
    fitted = {
        f"initial:{n}:p_P": plain.measured_initial[n]["p_P"] - d
        for n, d in zip(names, (900.0, 1000.0, 5000.0), strict=False)
    }
    est = pressure_offsets(plain, fitted)
    assert len(names) >= 3 and set(est) == {"p_P"}
    assert (est["p_P"].value, est["p_P"].n) == (pytest.approx(1000.0), 3)
    assert est["p_P"].agrees and est["p_P"].p_value is None  # no sds, no test
    # fewer than MIN_OFFSET_RECORDINGS (3): no offset, the readings as they are
    assert pressure_offsets(plain, dict(list(fitted.items())[:2])) == {}
    # a segment that starts on a moving piston is left out (its intercept is
    # read on a changing pressure): with it as the third, two remain, none
    moving = sorted(started_moving(plain))
    assert moving and moving[0] not in names
    third = {f"initial:{moving[0]}:p_P": plain.measured_initial[moving[0]]["p_P"] - 1000.0}
    assert pressure_offsets(plain, {**dict(list(fitted.items())[:2]), **third}) == {}


def _at_rest(problem: Problem) -> list[str]:
    """The problem's recordings (segments) that start with the piston at rest."""
    moving = started_moving(problem)
    return [n for n in problem.measured_initial if n not in moving]


def test_a_sensor_offset_is_applied_only_where_its_recordings_agree(
    long_campaign: Path,
) -> None:
    """Plumbing and arithmetic, exact: given the fitted initial pressures'
    sds, ``pressure_offsets`` tests whether the recordings' estimates
    (reading less fitted initial pressure) are one offset's: chi-square
    about their inverse-variance weighted mean on n - 1 degrees of freedom.
    Made-up fits of three recordings: 900, 1000, 1100 Pa with sds 100 Pa
    give chi-square 2 (chance e^-1 = 0.37 on 2 dof) and agree; -7000, +1000,
    -6000 Pa with sds 1000 Pa (the demo's charges and discharges,
    2026-12-04) give chi-square 38 (chance 5.6e-9) and do not, so their
    mean is not applied (:data:`OFFSET_AGREEMENT`, 1e-4). The readings'
    own standard errors (the line's intercept, ~110 Pa here) are set to
    zero, so that the arithmetic is the sds'."""
    cut, _ = segment_step_tests(read_campaign(long_campaign), "auto")
    recs = [r for r in cut.recordings if r.kind == "step"]
    plain = Problem(recs, fit_structure("convection"), {}, channels=("p_P", "p_N", "y"))
    assert plain.measured_initial_se and all(
        50.0 < se["p_P"] < 250.0 for se in plain.measured_initial_se.values()
    )  # 400 Pa of noise, a line through 50 samples: ~2 x 400 / sqrt(50) = 113 Pa
    plain.measured_initial_se.clear()
    names = _at_rest(plain)[:3]
    assert len(names) == 3

    def offsets(diffs: tuple[float, ...], sd: float) -> SensorOffset:
        keys = [f"initial:{n}:p_P" for n in names]
        fitted = {k: plain.measured_initial[n]["p_P"] - d
                  for k, n, d in zip(keys, names, diffs, strict=True)}  # fmt: skip
        return pressure_offsets(plain, fitted, dict.fromkeys(keys, sd))["p_P"]

    good = offsets((900.0, 1000.0, 1100.0), 100.0)
    assert good.chi_square == pytest.approx(2.0)
    assert good.p_value == pytest.approx(math.exp(-1.0))
    assert good.agrees and good.value == pytest.approx(1000.0)
    bad = offsets((-7000.0, 1000.0, -6000.0), 1000.0)
    # weighted mean -4000: (9 + 25 + 4) = 38
    assert bad.chi_square == pytest.approx(38.0)
    assert bad.p_value == pytest.approx(math.exp(-19.0))
    assert bad.p_value < OFFSET_AGREEMENT and not bad.agrees
    assert "not applied" in bad.describe() and "not applied" not in good.describe()
    assert good.applies and not bad.applies
    # agreeing on more than OFFSET_LIMIT (7.5 kPa, three times a transducer's
    # static error band): not a sensor's zero (the practice rig's polytropic
    # fit, chamber N, 2026-12-04: -18.0 to -5.1 kPa agreeing on -10.9 kPa)
    far = offsets((-11000.0, -10000.0, -9000.0), 3000.0)
    assert far.agrees and not far.plausible and not far.applies
    assert far.value == pytest.approx(-10000.0) and OFFSET_LIMIT == 7500.0
    assert "not applied" in far.describe() and "7500 Pa" in far.describe()
    # the weighted mean's standard error: 1 / sqrt(sum of the weights), times
    # the Birge ratio sqrt(chi-square / (n - 1)) when that exceeds 1
    assert good.standard_error == pytest.approx(100.0 / math.sqrt(3.0))
    assert good.determined and far.determined
    spread = offsets((1000.0, 2000.0, 3000.0), 500.0)  # chi-square 8 on 2 dof
    assert spread.p_value == pytest.approx(math.exp(-4.0)) and spread.agrees
    assert spread.standard_error == pytest.approx(math.sqrt(4.0 * 500.0**2 / 3.0))
    assert spread.applies
    # estimates that agree only because each is wide do not tell the zero from
    # 0 (the novel truth's chamber N, 2026-12-05: +5.1, -5.4, +3.4, +1.2 kPa
    # with sds 13-101 kPa applied at +3486 Pa against the truth's -304 Pa):
    # not applied (OFFSET_DETERMINED, sqrt 2 standard errors)
    wide = offsets((5000.0, -5000.0, 3000.0), 20000.0)
    assert wide.value == pytest.approx(1000.0) and wide.agrees and wide.plausible
    assert wide.standard_error == pytest.approx(20000.0 / math.sqrt(3.0))
    assert not wide.determined and not wide.applies
    assert "not told from 0" in wide.describe() and "not applied" in wide.describe()
    assert OFFSET_DETERMINED == pytest.approx(math.sqrt(2.0))
    # the fit's verdict carries a refused offset as a caveat (console summary
    # in yellow, the report's notes, fit.json quality.caveats)
    from pneumafit.identification.quality import FitQuality

    quality = FitQuality(channels=[], refused_offsets=[bad.describe()])
    (caveat,) = quality.caveats()
    assert caveat.startswith("sensor offset p_P -4000 Pa (3 recordings") and "disagree" in caveat
    assert quality.as_dict()["refused_offsets"] == [bad.describe()]


@pytest.mark.slow
def test_segments_let_the_fit_follow_its_own_laws_on_long_closed_loops(
    long_campaign: Path,
) -> None:
    """Control (the rig's ``fit-laws`` truth: the fit's laws, recorded by the
    independent truth simulator, LSODA at rtol 1e-8, with sensor noise; an
    identity of the laws, not of the numerics), sparse-long plan, seed 1,
    ``--no-mcmc --seed 1``. Measured 2026-11-30: fitted whole, the fit chose
    the switch law (LuGre's stage stuck 3573 below it), the held-out step
    test replayed at 7.8x / 10.6x the pressure noise (p_P / p_N); in
    segments, LuGre, the held-out test at 1.3x / 1.4x, static and Coulomb
    friction 0.3 % and 0.1 % from the truth (50 and 30 N); each segment
    starting at its measured velocity since 2026-11-30, late (below). Held to: LuGre
    chosen, held-out pressures within 2x in segments and above 5x whole,
    static and Coulomb friction within 2 %: the tolerances sit between the
    two measured outcomes, so either regressing fails the test."""
    from pneumafit.api import fit

    camp = read_campaign(long_campaign)
    out = {}
    for mode in ("auto", "off"):
        from pneumafit.identification import FitOptions

        result = fit(camp, "convection", mcmc=False, seed=1, options=FitOptions(segments=mode))
        held = max(
            c.ratio
            for c in result.quality.channels
            if c.recording == "step_2.h5" and c.channel in ("p_P", "p_N")
        )
        out[mode] = (result, held)
    seg, held = out["auto"]
    assert seg.structure.friction == "lugre"
    assert held < 2.0, held
    ref = seg.metrics["friction_reference"]
    assert ref["static"]["value"] == pytest.approx(50.0, rel=0.02)
    assert ref["coulomb"]["value"] == pytest.approx(30.0, rel=0.02)
    assert any(c.recording == "step_1.h5@2.450s" for c in seg.quality.channels)
    # the segment that starts on a moving piston (65 mm/s at 2.45 s): started
    # at rest, it fitted at 3.2x (p_N) and 162x (y) the noise, the others at
    # 1.0-1.9x; started at its measured velocity, 1.07x and 16x (2026-11-30, late).
    # Bounds between the two outcomes.
    fitted = [c for c in seg.quality.channels if c.recording.startswith("step_1.h5@")]
    assert max(c.ratio for c in fitted if c.channel in ("p_P", "p_N")) < 2.0
    assert max(c.ratio for c in fitted if c.channel == "y") < 50.0
    assert seg.campaign == out["off"][0].campaign  # the campaign as read, not its segments
    # the pressure sensors' offsets (truth -960 and +589 Pa; estimated -961 and
    # +543 Pa, 2026-12-01, as medians; -935 and +482 Pa since 2026-12-04, the
    # weighted means of the segments started at rest, which agree: chi-square
    # 0.9 on 4 and 2.1 on 2 dof): the held-out test started from its readings
    # (the offsets in its initial pressures) missed the position noise 28.7x
    # (32x on 2026-12-04), its piston up to 0.7 mm off in its first 2 s; from
    # its readings less the estimated offsets, 2.8x (5.4x since 2026-12-04;
    # p_P, p_N 1.0x). Bounds: 150 Pa (a third of the pressure noise, 400 Pa)
    # and 10x, between the two outcomes.
    truth = json.loads((long_campaign / "truth.json").read_text())["sensors"]
    for c, true in truth["pressure_offsets"].items():
        assert seg.parameters[f"{OFFSET_PREFIX}{c}"].value == pytest.approx(true, abs=150.0)
    held_y = [
        c.ratio for c in seg.quality.channels if c.recording == "step_2.h5" and c.channel == "y"
    ]
    assert held_y and max(held_y) < 10.0, held_y
    assert out["off"][1] > 5.0, out["off"][1]
