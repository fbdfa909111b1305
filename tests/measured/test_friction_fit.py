"""The friction-test fit (``--model friction``): recovery on synthetic data, a shipped seal.

Recovery, not an inverse crime: the synthetic bench uses a *different* law
from the fitted one (a smooth tanh friction, F_f = (F_c0 + c p_g) tanh(v /
v_e) + b v, with no bristle state and no Stribeck drop), is integrated on a
ten times finer time grid (1 kHz, decimated to 100 Hz), and the fit sees
only noisy positions (laser noise 5 um) from which it estimates the velocity
itself, plus load-cell noise (0.05 N). The fitted LuGre/static law can match
the tanh law only approximately near reversals (over v_e = 0.5 mm/s, ~5 % of
a stroke's duration), so the tolerances are those of a good approximation,
not of round-off.
"""

from __future__ import annotations

import io
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import Campaign, Recording, Rig, read_campaign
from pneumafit.frictiontest import identify_friction
from pneumafit.frictiontest.fit import FrictionTestProblem, _fit, _structure_set
from pneumafit.frictiontest.model import default_parameters, friction_test_force, prepare

ROOT = Path(__file__).resolve().parents[2]
ATM = 101325.0
BORE = 0.025
AREA = math.pi * BORE**2 / 4.0
FC0, GAIN, VISC, V_E = 3.0, 1.5e-5, 40.0, 5e-4  # N, N/Pa, N s/m, m/s


def synthetic_test(p_gauge: float, role: str, rng: np.random.Generator) -> Recording:
    fine = np.arange(0.0, 24.0, 1e-3)
    y = 0.018 * np.sin(2.0 * np.pi * fine / 6.0)  # four strokes, peak 19 mm/s
    v = np.gradient(y, fine)
    p = p_gauge + 0.02e5 * np.sign(v)  # the regulator moves with the direction
    friction = (FC0 + GAIN * p) * np.tanh(v / V_E) + VISC * v
    force = p * AREA - friction
    keep = slice(None, None, 10)
    t = fine[keep]
    return Recording.from_arrays(
        t,
        {
            "y": y[keep] + rng.normal(0.0, 5e-6, t.size),
            "p_P": p[keep] + ATM + rng.normal(0.0, 200.0, t.size),
            "F": force[keep] + rng.normal(0.0, 0.05, t.size),
        },
        kind="friction", role=role, file=f"syn_{p_gauge / 1e5:.0f}bar.csv",
    )  # fmt: skip


def synthetic_campaign() -> Campaign:
    rng = np.random.default_rng(20261125)
    nan = math.nan
    rig = Rig(bore=BORE, rod=nan, stroke=nan, dead_volume_P=nan, dead_volume_N=nan,
              moving_mass=nan, supply_pressure=nan, exhaust_pressure=ATM,
              ambient_temperature=293.15, wall_temperature=293.15,
              characteristic_length=BORE).with_acting("single")  # fmt: skip
    recs = [synthetic_test(p * 1e5, "fit", rng) for p in (1.0, 3.0, 5.0)]
    recs.append(synthetic_test(7e5, "validate", rng))
    return Campaign(path=None, name="synthetic", description="", rig=rig, recordings=recs)


def test_recovery_on_a_different_law() -> None:
    campaign = synthetic_campaign()
    start = time.perf_counter()
    result = identify_friction(campaign, effects="auto", mcmc=False)
    seconds = time.perf_counter() - start
    values = {p.name: p.value for p in result.parameters}
    kept = result.metrics["effects"]["kept"]
    # the pressure growth is the largest signal (7.5 N over 5 bar): BIC must take it
    assert "seal_friction_coefficient" in kept
    # Coulomb level at ambient pressure and its growth: the tanh law's
    # plateau is reached within 2 % at |v| > 2.3 v_e = 1.2 mm/s, so the
    # levels agree within ~5 %; 10 % allows the velocity estimate's lag at
    # reversals (Savitzky-Golay over 0.11 s)
    assert values["friction_coulomb"] == pytest.approx(FC0, rel=0.10)
    assert values["seal_friction_coefficient"] == pytest.approx(GAIN, rel=0.10)
    # viscous: 40 N s/m gives 0.76 N at peak speed; it trades against the
    # level near reversals, where the laws differ: 25 % (measured: -0.5 %)
    assert values["friction_viscous"] == pytest.approx(VISC, rel=0.25)
    # no asymmetry and the nominal area in the truth: either not kept or near neutral
    assert abs(values["friction_asymmetry"]) < 0.05
    assert values["area_factor"] == pytest.approx(1.0, abs=0.01)
    # held-out 7 bar, 2 bar beyond the fit: the truth's friction vanishes at
    # v = 0 and ramps over +-2 v_e (~3 % of the samples), the fitted law keeps
    # c_p p there; at 7 bar (13.5 N of friction) that alone is ~0.7 N RMS
    # (measured 0.73 N). 1 N separates it from the law without pressure
    # dependence (~4 N at 7 bar)
    rmse = result.metrics["rmse_by_recording"]
    assert rmse["syn_7bar.csv"] < 1.0, rmse
    # the noise estimate from quiet windows finds the load cell's 0.05 N
    # within 20 % (windows of 9 samples; the signal is smooth inside)
    assert result.metrics["noise_F"]["syn_1bar.csv"] == pytest.approx(0.05, rel=0.2)
    assert seconds < 120


@pytest.mark.slow
def test_fit_of_a_shipped_seal(tmp_path: Path) -> None:
    """``pneumafit fit data/measured/NAP310 --model friction --no-mcmc`` end to end."""
    from pneumafit.cli.fit import fit_command

    out = io.StringIO()
    status = fit_command(
        ROOT / "data" / "measured" / "NAP310", "friction", tmp_path / "fit", None, None, 0,
        False, Console(file=out, width=160), friction="switch",
    )  # fmt: skip
    assert status == 0, out.getvalue()
    doc = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert doc["model"] == "friction" and doc["format"] == "pneumafit-fit"
    assert doc["structure"]["friction"] == "stribeck"
    assert {"friction_coulomb", "friction_static", "area_factor"} <= set(doc["parameters"])
    assert doc["quality"]["recordings"][0]["channel"] == "F"
    rmse = doc["metrics"]["rmse_by_recording"]
    # a pressure-independent law on 1-5 bar whose friction grows from ~2 N
    # to ~8 N: one level in between, which with one sigma for all tests sits
    # where the summed squares are least (measured 2.40, 2.25, 3.66 N at 1, 3,
    # 5 bar; with a sigma per test it sat near the 1-bar level: 1.0, 2.7, 4.8),
    # and worse still on the held-out 7 bar (measured 5.90 N). The bounds are
    # the level's reach, half-way to the friction's spread, not the figures
    assert max(rmse[f"NAP310_{p}bar.csv"] for p in (1, 3, 5)) < 5.0
    assert rmse["NAP310_3bar.csv"] < rmse["NAP310_5bar.csv"]
    assert rmse["NAP310_7bar.csv"] > rmse["NAP310_5bar.csv"]
    # the load-cell noise estimated from the data: ~0.03 N
    assert 0.01 < doc["metrics"]["noise_F"]["NAP310_7bar.csv"] < 0.1


def test_bad_input_exits_2(tmp_path: Path) -> None:
    from pneumafit.cli.fit import fit_command

    folder = tmp_path / "bench"
    folder.mkdir()
    (folder / "campaign.toml").write_text(
        (ROOT / "data" / "measured" / "NAP310" / "campaign.toml").read_text()
    )
    out = io.StringIO()
    status = fit_command(folder, "friction", tmp_path / "fit", None, None, 0, False,
                         Console(file=out, width=200))  # fmt: skip
    text = " ".join(out.getvalue().split())
    assert status == 2
    assert "NAP310_1bar.csv: expected the recording listed as recording[1]" in text
    assert "Traceback" not in text


@pytest.mark.parametrize(
    ("walkers", "friction", "seal", "message"),
    [
        (3, "auto", "off", "option --walkers: expected an integer >= 16, found 3"),
        (None, "karnopp", "off", "option --friction: expected one of auto, switch, lugre"),
        (None, "auto", "maybe", "option --seal-friction: expected one of long, auto, on, off"),
    ],
)
def test_bad_options_exit_2(
    tmp_path: Path, walkers: int | None, friction: str, seal: str, message: str
) -> None:
    from pneumafit.cli.fit import fit_command

    out = io.StringIO()
    status = fit_command(
        ROOT / "data" / "measured" / "NAP310", "friction", tmp_path / "fit", walkers, None, 0,
        True, Console(file=out, width=200), friction=friction, seal=seal,
    )  # fmt: skip
    assert status == 2
    assert message in " ".join(out.getvalue().split())
    assert not (tmp_path / "fit").exists()


@pytest.mark.parametrize("pooled", [True, False])
def test_one_load_cell_one_sigma(pooled: bool) -> None:
    """Measured data (Kidney_lc, a structure the fit shares with a regression, not
    a recovery test): the tests share one load cell, so one profiled sigma.

    Coulomb-viscous friction with seal friction and an area factor is linear in
    its parameters, so the pooled fit must be the plain least-squares regression
    F = k_A p_g A - (c0 + c1 p_g) sign(v) - b v on the 1, 3, 5-bar samples. Per-test
    sigmas weigh each test by its own misfit (the 5-bar test, fitted worst,
    counts least) and extrapolate worse to 7 bar: 7.64 N against the regression's
    7.13 N (measured 2026-11-25). The 1 % bound is the fit's own tolerance (the
    law's kernel smooths sign(v) over the bristle deflection, ~1e-6 m, and the
    solver stops at its tolerances); the per-test case shows the bound can fail.
    """
    campaign = read_campaign(ROOT / "data" / "measured" / "Kidney_lc")
    fit = prepare(campaign, [r for r in campaign.by_kind("friction") if r.role == "fit"])
    held = next(t for t in prepare(campaign) if t.file.endswith("7bar.csv"))

    def regressors(t):
        s = np.sign(t.velocity)
        return np.column_stack([t.push, -s, -s * t.gauge_pressure, -t.velocity])

    theta = np.linalg.lstsq(
        np.vstack([regressors(t) for t in fit]), np.concatenate([t.force for t in fit]), rcond=None
    )[0]
    rmse_regression = float(np.sqrt(np.mean((held.force - regressors(held) @ theta) ** 2)))

    ps = _structure_set(
        default_parameters(), "coulomb-viscous", ("area_factor", "seal_friction_coefficient")
    )
    _, est = _fit(FrictionTestProblem(fit, pooled=pooled), ps)
    values = est.parameters.values()
    rmse = float(np.sqrt(np.mean((held.force - friction_test_force(held, values)[0]) ** 2)))
    if pooled:
        assert rmse == pytest.approx(rmse_regression, rel=0.01)
    else:
        assert rmse > 1.03 * rmse_regression
