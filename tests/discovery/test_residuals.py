"""Residual analysis: statistics on sampled points, phases, summary, plots,
and what it finds on virtual-rig campaigns."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from discovery_helpers import truth_residuals, white_noise
from scipy import stats

from pneumafit.campaign import PDController, Recording
from pneumafit.discovery import (
    EFFECTS,
    autocorrelation,
    format_summary,
    get_effect,
    ljung_box,
    plot_residuals,
    residual_analysis,
    summarize,
    whiteness_band,
)
from pneumafit.virtual_rig import RigRun, VirtualRig, held_input_lag

T = np.arange(0.0, 2.0005, 1e-3)
NOISE = 400.0  # Pa


def synthetic_charge(seed: int = 0, **kwargs: object) -> tuple[Recording, dict[str, np.ndarray]]:
    """A charge-like recording: smooth pressure plus white noise, and the
    noise-free pressure as the "simulation"."""
    u = np.where((T >= 0.5) & (T < 0.8), 8.0, 0.0)
    p = 1e5 + 5e5 * (1.0 - np.exp(-np.clip(T - 0.5, 0.0, None) / 0.1))
    measured = p + NOISE * white_noise(seed, T.size)
    rec = Recording.from_arrays(
        T, {"u_P": u, "p_P": measured}, kind="charge", chamber="P", piston_position=0.2,
        file="synthetic.h5", **kwargs,  # type: ignore[arg-type]
    )  # fmt: skip
    return rec, {"p_P": p, "u_P": u}


# ----------------------------------------------------------- on synthetic data
def test_white_residual_report() -> None:
    rec, sim = synthetic_charge()
    report = residual_analysis(rec, sim)
    assert list(report.channels) == ["p_P"]  # u_P is an input, not an output
    ch = report.channels["p_P"]
    e = rec.channels["p_P"] - sim["p_P"]
    np.testing.assert_array_equal(ch.residual, e)
    assert (ch.n, ch.unit, report.max_lag) == (T.size, "Pa", 25)
    assert ch.rms == pytest.approx(math.sqrt(np.mean(e**2)))
    np.testing.assert_allclose(ch.autocorrelation.values, autocorrelation(e, 25))
    assert ch.autocorrelation.band == whiteness_band(T.size, 0.01)
    assert ch.ljung_box == ljung_box(e, 25)
    assert ch.white
    assert list(ch.cross_correlation) == ["u_P"]
    assert ch.cross_correlation["u_P"].lags.tolist() == list(range(-25, 26))
    assert ch.cross_correlation["u_P"].tested.all()  # open loop: every lag
    assert ch.autocorrelation.lag_times[-1] == pytest.approx(0.025)
    assert sum(s.n for s in ch.phases.values()) == ch.n
    assert sum(s.share for s in ch.phases.values() if s.n) == pytest.approx(1.0)


def test_white_residuals_stay_inside_the_bands() -> None:
    # 100 seeded white residuals: the ACF lags outside the 99 % band follow
    # Binomial(2500, 0.01) (checked at 0.001), the CCF with the command at
    # lag 0 is outside in at most 5 of 100 (Binomial(100, 0.01) exceeds 5 with
    # probability 6e-4), and Ljung-Box rejects at 1 % in at most 5.
    acf_out = ccf_out = rejected = 0
    for seed in range(100):
        rec, sim = synthetic_charge(seed)
        ch = residual_analysis(rec, sim).channels["p_P"]
        acf_out += round(ch.autocorrelation.fraction_outside * 25)
        cc = ch.cross_correlation["u_P"]
        ccf_out += abs(cc.values[25]) > cc.band
        rejected += not ch.white
    assert stats.binomtest(acf_out, 2500, 0.01).pvalue > 1e-3, acf_out
    assert ccf_out <= 5
    assert rejected <= 5


def test_only_sampled_points_count() -> None:
    # p_P sampled every other row (e.g. a CSV with empty cells); the simulation
    # is wrong by 1 MPa exactly where nothing was measured: no effect.
    mask = np.arange(T.size) % 2 == 0
    rec, sim = synthetic_charge(mask={"p_P": mask})
    bad = sim["p_P"] + np.where(mask, 0.0, 1e6)
    ch = residual_analysis(rec, {"p_P": bad}).channels["p_P"]
    e = rec.channels["p_P"][mask] - sim["p_P"][mask]
    assert ch.n == mask.sum()
    np.testing.assert_array_equal(ch.time, T[mask])
    np.testing.assert_array_equal(ch.residual, e)
    assert ch.ljung_box == ljung_box(e, 25)
    assert ch.rms < 2 * NOISE
    assert ch.autocorrelation.sample_interval == pytest.approx(2e-3)


def test_coloured_residual_and_where_it_concentrates() -> None:
    # a slow error added after the valve closes (a missing leak): not white,
    # largest (and made) in the relaxation
    rec, sim = synthetic_charge()
    drift = np.where(T > 0.8, -2e4 * (T - 0.8), 0.0)
    ch = residual_analysis(rec, {"p_P": sim["p_P"] + drift}).channels["p_P"]
    assert not ch.white and ch.violation > 100
    assert ch.autocorrelation.fraction_outside == 1.0
    assert ch.concentrated_in == "relaxation"
    assert ch.changes_in == "relaxation"
    assert ch.phases["relaxation"].share > 0.99
    assert ch.phases["motion"].n == 0 and math.isnan(ch.phases["motion"].rms)


def test_closed_loop_tests_only_causal_cross_correlation_lags() -> None:
    rec, sim = synthetic_charge()
    y = 0.1 + 0.05 * (T > 1.0)
    step = Recording.from_arrays(
        T, {"y": y, "y_ref": y, "p_P": rec.channels["p_P"], "p_N": rec.channels["p_P"],
            "u_P": sim["u_P"], "u_N": -sim["u_P"]},
        kind="step", controller=PDController(kp=60.0, kd=4.0, u0=0.0, umax=10.0),
    )  # fmt: skip
    report = residual_analysis(step, {"p_P": sim["p_P"], "p_N": sim["p_P"]}, max_lag=10)
    assert report.closed_loop
    cc = report.channels["p_N"].cross_correlation
    assert list(cc) == ["u_P", "u_N", "y_ref"]
    assert cc["y_ref"].tested.tolist() == [False] * 10 + [True] * 11


def test_max_lag_is_capped_for_short_channels() -> None:
    rec, sim = synthetic_charge(mask={"p_P": np.arange(T.size) % 100 == 0})  # 21 points
    ch = residual_analysis(rec, sim, max_lag=25).channels["p_P"]
    assert ch.n == 21 and ch.ljung_box.lags == 5


def test_accepts_a_simulation_object() -> None:
    from pneumafit.simulation import Experiment, Simulator

    rec, _ = synthetic_charge()
    sim = Simulator("convection").simulate({}, Experiment.from_recording(rec))
    report = residual_analysis(rec, sim)
    assert list(report.channels) == ["p_P"]


@pytest.mark.parametrize(
    ("kwargs", "simulated", "match"),
    [
        ({"channels": ["T_P"]}, {"p_P": np.zeros(T.size)}, "'T_P': expected it recorded"),
        ({"channels": ["p_P"]}, {"T_P": np.zeros(T.size)}, "'p_P': expected it simulated"),
        ({}, {"T_P": np.zeros(T.size)}, "no channel is both recorded and simulated"),
        ({}, {"p_P": np.zeros(10)}, "expected 2001 simulated samples"),
        ({}, {"p_P": np.full(T.size, np.nan)}, r"did it fail\?"),
        ({"alpha": 0.0}, {"p_P": np.zeros(T.size)}, "alpha"),
        ({"max_lag": 0}, {"p_P": np.zeros(T.size)}, "max_lag"),
    ],
)
def test_bad_input(kwargs: dict[str, object], simulated: dict[str, np.ndarray], match: str) -> None:
    rec, _ = synthetic_charge()
    with pytest.raises(ValueError, match=match):
        residual_analysis(rec, simulated, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="mapping"):
        residual_analysis(rec, [1.0, 2.0])


def test_summary_ranks_the_least_white_first() -> None:
    rec, sim = synthetic_charge()
    white = residual_analysis(rec, sim)
    coloured = residual_analysis(rec, {"p_P": sim["p_P"] + 3e3 * np.sin(T)})
    rows = summarize([white, coloured])
    assert [r.white for r in rows] == [False, True]
    assert rows[0].violation > rows[1].violation
    assert summarize(white)[0].channel == "p_P"
    text = format_summary(rows)
    assert len(text.splitlines()) == 4 and "synthetic.h5" in text


def test_plot_residuals(tmp_path: Path) -> None:
    rec, sim = synthetic_charge()
    report = residual_analysis(rec, sim)
    out = plot_residuals(report, tmp_path / "figs" / "residuals.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in out.parent.iterdir()) == ["residuals.png"]  # no temp file
    with pytest.raises(ValueError, match="channels"):
        plot_residuals(report, tmp_path / "x.png", channels=["T_N"])
    assert not (tmp_path / "x.png").exists()


# ------------------------------------------------------------ virtual rig
def test_truth_leaves_white_pressure_and_position_residuals() -> None:
    """Ten quick campaigns without effects, each simulated with the rig's
    truth (structure and parameters; RK3 at 1 ms instead of DP5 at 0.1 ms,
    < 1 Pa apart) from the true initial states, the sensor offsets added: the
    residual is then the sensor noise. Its 50 Ljung-Box p-values (p_P, p_N,
    y) must look uniform (KS at 0.001) with at most 3 rejections at 1 %
    (Binomial(50, 0.01) reaches 4 with probability 0.0016)."""
    p_values = []
    for seed in range(1, 11):
        rig = VirtualRig(seed=seed)
        for report in truth_residuals(rig.run("quick"), rig).values():
            p_values += [ch.ljung_box.p_value for ch in report.channels.values()]
    assert len(p_values) == 50
    assert stats.kstest(p_values, "uniform").pvalue > 1e-3
    assert sum(p < 0.01 for p in p_values) <= 3


def test_sensor_offset_alone_keeps_residuals_white(
    clean_run: RigRun, clean_rig: VirtualRig
) -> None:
    """Offsets unknown but the true initial state: the residual is noise plus
    a constant, white once the mean is removed; the mean is the offset
    (+-4 sigma / sqrt(n): 36 Pa for 2001 samples). One campaign, four
    channels: whiteness is asked at 0.1 % (a white channel fails with
    probability 0.001; this seed's step p_N has p = 0.0097, a 1-in-100 draw
    that the 10-seed test above allows for)."""
    offsets = clean_run.truth["sensors"]["pressure_offsets"]
    reports = truth_residuals(clean_run, clean_rig, offsets=False, channels=("p_P", "p_N"))
    for report in reports.values():
        for ch in report.channels.values():
            assert ch.ljung_box.p_value > 1e-3, (report.recording, ch.channel)
            assert ch.mean == pytest.approx(offsets[ch.channel], abs=4 * NOISE / math.sqrt(ch.n))


def test_start_from_the_first_sample_breaks_whiteness() -> None:
    """What a real bench gives: the simulation starts from the first measured
    pressure, which carries the sensor offset and one noise sample. Until the
    valve opens the simulation keeps that start error, so the residual there
    is offset - start error (= minus the first noise sample); the fill to
    supply pressure erases most of the start error and the residual jumps
    towards the offset: the charge test's pressure residual is not white,
    even for the truth. Seed 6 draws a 1.4-kPa offset on p_P."""
    rig = VirtualRig(seed=6)
    run = rig.run("quick")
    rec = next(r for r in run.campaign.recordings if r.file == "charge_P.h5")
    start_error = rec.channels["p_P"][0] - run.traces[rec.file].channels["p_P"][0]
    offset = run.truth["sensors"]["pressure_offsets"]["p_P"]
    report = truth_residuals(run, rig, initial="recording", offsets=False)["charge_P.h5"]
    ch = report.channels["p_P"]
    assert ch.ljung_box.p_value < 1e-6
    labels = report.phase_labels
    before = np.arange(labels.size) < np.argmax(labels == "filling")
    # 4 sigma / sqrt(n) of noise, plus 50 Pa for the centre-leakage drift
    tolerance = 4 * NOISE / math.sqrt(before.sum()) + 50.0
    assert ch.residual[before].mean() == pytest.approx(offset - start_error, abs=tolerance)
    assert abs(ch.phases["relaxation"].mean - offset) < 0.5 * abs(start_error)


def test_temperature_residuals_show_the_sensor_lag(
    clean_run: RigRun, clean_rig: VirtualRig
) -> None:
    """The model simulates the gas temperature, the sensor lags it by 0.4 s:
    the residual is far from white even for the truth, and white again once
    the simulation goes through the same sensor lag."""
    report = truth_residuals(clean_run, clean_rig, channels=("T_P",))["charge_P.h5"]
    ch = report.channels["T_P"]
    assert not ch.white and ch.autocorrelation.values[1] > 0.99
    rec = next(r for r in clean_run.campaign.recordings if r.file == "charge_P.h5")
    gas = ch.residual + 0.0  # measured - simulated gas temperature
    simulated = rec.channels["T_P"] - gas
    lagged = held_input_lag(simulated, 1e-3, clean_rig.sensors.temperature_time_constant)
    assert residual_analysis(rec, {"T_P": lagged}).channels["T_P"].white


def test_undeclared_chamber_leakage_shows_in_relaxation_and_rest(
    leak_run: RigRun, clean_rig: VirtualRig
) -> None:
    """A quick campaign with a chamber leakage nobody declared, analysed with
    the truth without it (true initial states and offsets, so that only the
    leak differs): every pressure residual is far from white and largest
    where the valves are closed, as the catalog says."""
    reports = truth_residuals(leak_run, clean_rig, channels=("p_P", "p_N"))
    expected = set(get_effect("chamber_leakage").phases)
    for report in reports.values():
        for ch in report.channels.values():
            where = (report.recording, ch.channel)
            assert ch.ljung_box.p_value < 1e-10, where
            assert ch.concentrated_in in expected, where
    charge = reports["charge_P.h5"].channels["p_P"]
    assert charge.phases["relaxation"].share > 0.9
    assert charge.phases["relaxation"].rms > 10 * charge.phases["rest"].rms
    # the ranking puts these above the clean campaign's
    rows = summarize(list(reports.values()))
    assert all(not r.white for r in rows)


@pytest.mark.parametrize("name", list(EFFECTS))
def test_each_catalog_effect_shows_in_its_phases(name: str, clean_rig: VirtualRig) -> None:
    """The catalog's ``phases`` agree with residual analysis: a quick campaign
    with one undeclared effect (rig default size), its charge test analysed
    with the truth without the effect. The residual's rate is largest in a
    phase the catalog lists (the level can lag behind: an error made while
    filling persists into the relaxation)."""
    run = VirtualRig(effects={name: None}, seed=5).run("quick")
    if get_effect(name).phases == ("motion",):
        # an effect on the piston alone (seal friction, asymmetry): the step
        # test's position, which moves most of the test
        reports = truth_residuals(run, clean_rig, channels=("y",))
        ch = reports["step_1.csv"].channels["y"]
    else:
        ch = truth_residuals(run, clean_rig, channels=("p_P",))["charge_P.h5"].channels["p_P"]
    assert ch.ljung_box.p_value < 1e-10
    assert ch.changes_in in get_effect(name).phases
