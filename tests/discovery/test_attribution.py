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
