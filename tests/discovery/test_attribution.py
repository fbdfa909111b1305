"""Attribution pieces that need no fit: the rate smoothing and the signatures."""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.discovery import attribution as att
from pneumafit.discovery.phases import window_samples
from pneumafit.models import default_parameters


def test_smoothed_model_rate_equals_the_sg_slope_of_its_integral() -> None:
    """The model's rate is smoothed with the weights the Savitzky-Golay slope
    puts on a derivative: for a signal whose increments are the rate times
    dt, both sides agree to round-off (a kink included)."""
    t = np.arange(0.0, 1.0, 1e-3)
    rate = np.where(t < 0.4, 3.0e5, -2.0e4) + 1.0e4 * np.sin(20 * t)
    signal = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * 1e-3)])
    width = window_samples(t, 0.05)
    slope = att._rate(signal, width, 1e-3)
    smooth = att._smooth_rate(rate, width)
    inside = np.isfinite(smooth)
    assert inside.sum() == t.size - 2 * (width // 2)
    assert np.max(np.abs(slope[inside] - smooth[inside])) < 1e-6 * np.max(np.abs(rate))


def test_rate_noise_matches_white_noise() -> None:
    """The SG slope's noise predicted from the sensor's sigma is the measured
    spread of the slope of pure white noise (to 5 %: the spread of a standard
    deviation over ~20000 / 51 independent slopes is ~3.6 %)."""
    rng = np.random.default_rng(1)
    x = 400.0 * rng.standard_normal(20000)
    width = 51
    predicted = att._rate_noise(400.0, width, 1e-3)
    measured = float(np.std(att._rate(x, width, 1e-3)[100:-100]))
    assert predicted == pytest.approx(measured, rel=0.05)


def _state(n: int, p_p: float, p_n: float) -> dict[str, np.ndarray]:
    return {
        "y": np.full(n, 0.2), "p_P": np.full(n, p_p), "p_N": np.full(n, p_n),
        "T_P": np.full(n, 300.0), "T_N": np.full(n, 290.0), "qm_P": np.full(n, 2e-3),
        "qm_N": np.full(n, -1e-3), "lambda_P": np.full(n, 30.0), "lambda_N": np.full(n, 20.0),
    }  # fmt: skip


def test_signatures_have_the_laws_signs_and_sizes() -> None:
    """Per unit parameter, each term has the sign of its law (P above N and
    above the atmosphere, P filling and hotter than the wall) and the
    leakage terms the size gamma r T dP / V."""
    values = default_parameters()
    n = 101
    t = np.arange(n) * 1e-3
    s = _state(n, 5e5, 2e5)
    f_p = att.signature_features(s, "P", values, t, 11)
    f_n = att.signature_features(s, "N", values, t, 11)
    v_p = values["dead_volume_P"] + 0.25 * np.pi * values["bore"] ** 2 * 0.2
    assert f_p["chamber_leakage"][0] == pytest.approx(-1.4 * 287.058 * 300.0 * 3e5 / v_p)
    assert f_n["chamber_leakage"][0] > 0  # N gains what P loses
    assert f_p["external_leakage"][0] < 0 and f_n["external_leakage"][0] < 0
    assert f_p["supply_pressure_drop"][0] < 0  # a drawn flow lowers the supply
    assert f_n["supply_pressure_drop"][0] == 0.0  # N is not filling
    assert f_p["forced_convection"][0] < 0  # gas hotter than the wall: more cooling
    # steady flow: no lag term (round-off of the valve term's slope only)
    h_p = 1.4 * 287.058 * values["ambient_temperature"] * 2e-3 / v_p
    assert np.max(np.abs(f_p["valve_dynamics"])) < 1e-9 * h_p
    warm = f_p["wall_thermal_mass"]
    assert warm[0] == 0.0 and np.all(np.diff(warm) > 0)  # the wall warms, less cooling


def _quiet_rows(leak: float, seed: int) -> att.Rows:
    """Synthetic pressure rows: 8 s of filling, where a misfit no catalog
    effect makes (a valve law's, shaped unlike every regressor) dominates,
    then 8 s of rest, where the same leak regressor acts (1 row per 5 ms,
    one bootstrap block per 0.2 s)."""
    rng = np.random.default_rng(seed)
    n = 1600
    t = np.arange(2 * n) * 5e-3
    phase = np.array(["filling"] * n + ["rest"] * n)
    gauge = 3e5 + 1e5 * np.cos(0.7 * t)  # chamber gauge pressure (Pa)
    features = {
        "external_leakage": -1.4 * 287.0 * 293.0 * gauge / 1e-4,  # Pa/s per kg/s/Pa
        "forced_convection": np.where(phase == "filling", 50.0 * np.sin(3.1 * t), 0.0),
        "valve_dynamics": np.where(phase == "filling", 2e5 * np.cos(5.3 * t) ** 3, 0.0),
    }
    wave = np.sin(1.9 * t)
    misfit = np.where(phase == "filling", 5e4 * np.sign(wave) * np.abs(wave) ** 0.3, 0.0)
    rate = misfit + leak * features["external_leakage"] + 300.0 * rng.standard_normal(2 * n)
    return att.Rows(
        rate=rate,
        features=features,
        phase=phase,
        group=np.arange(2 * n) // 40,
        weight=np.ones(2 * n),
        channel=np.full(2 * n, "pressure"),
    )


def test_a_leak_is_judged_on_the_rest_phases_where_it_acts() -> None:
    """Mechanism, synthetic rows: a leak that makes 100 % of the rest phases'
    residual rate but 0.4 % of the whole (the filling phases' misfit, which
    no catalog effect makes, dominates, as on a rig whose valve law is not
    the model's) is unsupported on all pressure rows and supported on the
    quiet row set, with its coefficient (without the quiet row set it is
    unsupported); without the leak nothing is supported
    there, and an effect that does not act at rest (forced convection, the
    spool lag) is never judged on those rows."""
    leak = 2e-11
    rows = _quiet_rows(leak, seed=3)
    everything = np.ones(rows.n, bool)
    pressure_only = att._attribute_channel(
        rows, everything, list(rows.features), np.random.default_rng(0), 60, 0.05, label="pressure"
    )[0]
    on_all = {c.effect: c for c in pressure_only}["external_leakage"]
    assert not on_all.supported and on_all.variance_explained < att.MIN_VARIANCE
    result = att.attribute(rows, rng=np.random.default_rng(0), n_bootstrap=60)
    found = {c.effect: c for c in result.candidates}
    assert found["external_leakage"].rows == "quiet" and found["external_leakage"].supported
    # the rest rows' noise (300 Pa/s against a leak rate of ~3e5 Pa/s): the
    # coefficient to 1 %
    assert found["external_leakage"].coefficient == pytest.approx(leak, rel=0.01)
    assert found["forced_convection"].rows == "pressure"
    assert found["valve_dynamics"].rows == "pressure"
    # both readings are kept: the pressure rows' is the one the whole-row
    # regression above gives (the same rows, effects and seed)
    other = result.other_evidence("external_leakage")
    assert [c.rows for c in other] == ["pressure"] and not other[0].supported
    assert other[0].variance_explained == pytest.approx(on_all.variance_explained)
    assert set(result.by_rows["external_leakage"]) == {"pressure", "quiet"}
    assert "quiet" not in result.by_rows["forced_convection"]
    clean = att.attribute(_quiet_rows(0.0, seed=3), rng=np.random.default_rng(0), n_bootstrap=60)
    assert not {c.effect: c for c in clean.candidates}["external_leakage"].supported


def test_the_quiet_rows_need_enough_blocks() -> None:
    """Fewer than MIN_QUIET_BLOCKS blocks of rest: no quiet row set (its
    bootstrap could not give an inclusion probability)."""
    rows = _quiet_rows(2e-11, seed=4)
    rest = np.flatnonzero(rows.phase == "rest")
    keep = np.ones(rows.n, bool)
    keep[rest[(att.MIN_QUIET_BLOCKS - 1) * 40 :]] = False
    short = att.Rows(
        rate=rows.rate[keep], features={k: v[keep] for k, v in rows.features.items()},
        phase=rows.phase[keep], group=rows.group[keep], weight=rows.weight[keep],
        channel=rows.channel[keep],
    )  # fmt: skip
    assert np.unique(short.group[short.phase == "rest"]).size == att.MIN_QUIET_BLOCKS - 1
    result = att.attribute(short, rng=np.random.default_rng(0), n_bootstrap=20)
    assert "quiet" not in result.channels
    assert all(c.rows == "pressure" for c in result.candidates)


def _candidate(rows: str, score: float, supported: bool) -> att.Candidate:
    return att.Candidate(
        effect="external_leakage", score=score, inclusion_probability=0.9 if supported else 0.4,
        variance_explained=score, phase_match=1.0, coefficient=1e-11,
        coefficient_interval=(5e-12, 2e-11), coefficient_unit="kg/s/Pa", suggested={},
        phases={}, supported=supported, rows=rows,
    )  # fmt: skip


def test_the_quiet_rows_are_a_second_route_to_support() -> None:
    """Merging the quiet row set's evidence: a supported one replaces an
    unsupported channel evidence even with a lower score, an unsupported
    one never replaces a supported one, and otherwise the better rank wins
    (as between the two channels)."""
    best = {"external_leakage": _candidate("pressure", 0.20, False)}
    att._keep_best(best, [_candidate("quiet", 0.06, True)], supported_first=True)
    assert best["external_leakage"].rows == "quiet"
    best = {"external_leakage": _candidate("pressure", 0.03, True)}
    att._keep_best(best, [_candidate("quiet", 0.20, False)], supported_first=True)
    assert best["external_leakage"].rows == "pressure"
    att._keep_best(best, [_candidate("quiet", 0.05, True)], supported_first=True)
    assert best["external_leakage"].rows == "quiet"
    # between channels, rank alone (the rule before the quiet rows)
    best = {"external_leakage": _candidate("pressure", 0.20, False)}
    att._keep_best(best, [_candidate("motion", 0.06, True)])
    assert best["external_leakage"].rows == "pressure"
