"""Discovery on friction tests (``pneumafit discover`` on a friction fit) and ``run``.

Synthetic benches as in ``test_friction_fit.py``, not an inverse crime: the
truth is a smooth tanh friction, F_f = (F_c0 + c p_g) tanh(v / v_e) + b v
(no bristle state, no Stribeck drop), integrated on a 1-kHz grid and
decimated to 100 Hz; the fit sees noisy positions (it estimates the velocity
itself), noisy pressures and load-cell noise. With c > 0 the discovery must
select the seal friction and lower the held-out (7-bar) force RMSE; with
c = 0 and the nominal area it must select nothing.
"""

from __future__ import annotations

import io
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import Campaign, Recording, Rig
from pneumafit.frictiontest import identify_friction
from pneumafit.frictiontest.discover import FRICTION_EFFECTS, discover_friction, signature
from pneumafit.frictiontest.model import default_parameters, prepare
from pneumafit.identification.fitfile import fit_document

ROOT = Path(__file__).resolve().parents[2]
ATM = 101325.0
BORE = 0.025
AREA = math.pi * BORE**2 / 4.0
FC0, VISC, V_E = 3.0, 40.0, 5e-4  # N, N s/m, m/s


def _test(p_gauge: float, role: str, gain: float, rng: np.random.Generator) -> Recording:
    fine = np.arange(0.0, 12.0, 1e-3)
    y = 0.018 * np.sin(2.0 * np.pi * fine / 6.0)  # two strokes, peak 19 mm/s
    v = np.gradient(y, fine)
    p = p_gauge + 0.02e5 * np.sign(v)  # the regulator moves with the direction
    force = p * AREA - ((FC0 + gain * p) * np.tanh(v / V_E) + VISC * v)
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


def campaign(gain: float, seed: int = 20261125) -> Campaign:
    rng = np.random.default_rng(seed)
    nan = math.nan
    rig = Rig(bore=BORE, rod=nan, stroke=nan, dead_volume_P=nan, dead_volume_N=nan,
              moving_mass=nan, supply_pressure=nan, exhaust_pressure=ATM,
              ambient_temperature=293.15, wall_temperature=293.15,
              characteristic_length=BORE).with_acting("single")  # fmt: skip
    recs = [_test(p * 1e5, "fit", gain, rng) for p in (1.0, 3.0, 5.0)]
    recs.append(_test(7e5, "validate", gain, rng))
    return Campaign(path=None, name="synthetic", description="", rig=rig, recordings=recs)


def _base_doc(camp: Campaign) -> dict:
    result = identify_friction(camp, effects="off", mcmc=False)
    return fit_document(result, camp, seed=0, command="test", options=None)


def test_signatures_are_the_steady_sliding_derivatives() -> None:
    """On steady sliding the signatures have closed forms (module docstring of discover)."""
    camp = campaign(0.0)
    test = prepare(camp)[1]
    values = default_parameters().values()
    values.update(friction_coulomb=3.0, friction_static=3.0, stribeck_velocity=1e-5)
    sliding = np.abs(test.velocity) > 5e-3
    sv = np.sign(test.velocity[sliding])
    seal = signature(test, values, FRICTION_EFFECTS["seal_friction_coefficient"])[sliding]
    # the static law is linear in c_p on sliding samples: exact up to round-off
    np.testing.assert_allclose(seal, -sv * test.gauge_pressure[sliding], rtol=1e-6, atol=1e-9)
    area = signature(test, values, FRICTION_EFFECTS["area_factor"])
    np.testing.assert_allclose(area, test.push, rtol=1e-9)
    asym = signature(test, values, FRICTION_EFFECTS["friction_asymmetry"])[sliding]
    np.testing.assert_allclose(asym, -3.0, rtol=1e-6)


def test_discovery_selects_the_seal_friction_and_lowers_the_held_out_error() -> None:
    camp = campaign(1.5e-5)  # 7.5 N of extra friction over 5 bar
    t0 = time.perf_counter()
    doc = _base_doc(camp)
    result = discover_friction(camp, doc, rounds=3)
    seconds = time.perf_counter() - t0
    assert "seal_friction_coefficient" in result.selected
    # the area is nominal in the truth: its factor, if kept, within 2 % of 1
    assert abs(result.values_after["area_factor"] - 1.0) < 0.02
    before = result.rmse_before["role"]["validate"]
    after = result.rmse_after["role"]["validate"]
    # the base law misses 10.5 N x (7 bar) of growth in half the 7-bar test's
    # friction: the seal term removes most of it (the tanh-vs-LuGre mismatch at
    # reversals is what stays)
    assert after < 0.5 * before
    c = result.values_after["seal_friction_coefficient"]
    assert 1.5e-5 * 0.8 < c < 1.5e-5 * 1.2  # the velocity estimate's lag at reversals
    assert seconds < 40.0


def test_discovery_without_an_effect_selects_nothing() -> None:
    camp = campaign(0.0, seed=7)
    doc = _base_doc(camp)
    result = discover_friction(camp, doc, rounds=3)
    assert result.selected == []
    assert result.rmse_after == result.rmse_before


@pytest.mark.slow
def test_discover_command_writes_the_report(tmp_path: Path) -> None:
    """``pneumafit discover`` on a shipped seal's base fit: the before/after table."""
    pytest.importorskip("matplotlib")
    from pneumafit.campaign import read_campaign
    from pneumafit.cli.discover import discover_command

    path = ROOT / "data" / "measured" / "NAP310"
    camp = read_campaign(path)
    # a quick base fit: the Coulomb-viscous law only (the law stage is not under test)
    result = identify_friction(camp, law="coulomb-viscous", effects="off", mcmc=False)
    doc = fit_document(result, camp, seed=0, command="test", options=None)
    (tmp_path / "fit").mkdir()
    (tmp_path / "fit" / "fit.json").write_text(json.dumps(doc))
    console = Console(file=io.StringIO(), width=140)
    code = discover_command(path, tmp_path / "fit", tmp_path / "disc", seed=0, rounds=2,
                            per_round=3, console=console)  # fmt: skip
    text = console.file.getvalue()
    assert code == 0, text
    disc = json.loads((tmp_path / "disc" / "discovery.json").read_text())
    assert "seal-friction" in disc["selected"]
    b = disc["rmse_before"]["validate"]["F"]
    a = disc["rmse_after"]["validate"]["F"]
    assert a < b / 1.5, (b, a)
    assert "force RMSE (N): before -> after discovery" in text
    assert (tmp_path / "disc" / "discovery.md").read_text().count("NAP310_7bar.csv") >= 1


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pneumafit", *args],
                          capture_output=True, text=True, timeout=600)  # fmt: skip


@pytest.mark.slow
def test_run_on_a_shipped_seal(tmp_path: Path) -> None:
    from pneumafit.pipeline import run

    console = Console(file=io.StringIO(), width=140)
    code = run(ROOT / "data" / "measured" / "NAP310", tmp_path / "run", console, mcmc=False)
    text = console.file.getvalue()
    assert code == 0, text
    for f in ("fits/friction/fit.json", "discovery/discovery.json", "report.html",
              "stages.json"):  # fmt: skip
        assert (tmp_path / "run" / f).exists(), f
    html = (tmp_path / "run" / "report.html").read_text()
    assert "before and after discovery" in html
    # a re-run reuses the fit and the discovery
    console2 = Console(file=io.StringIO(), width=140)
    assert run(ROOT / "data" / "measured" / "NAP310", tmp_path / "run", console2, mcmc=False) == 0
    assert "reused" in console2.file.getvalue()
    # pneumafit report on the folder writes the friction-test report, not an empty chamber one
    result = _cli("report", str(tmp_path / "run"), "--out", str(tmp_path / "again.html"))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "friction-test report" in result.stdout
    assert "before and after discovery" in (tmp_path / "again.html").read_text()


def test_report_of_a_friction_run_without_its_campaign(tmp_path: Path) -> None:
    """A friction run folder whose fit names a campaign that is gone: exit 2, the path named."""
    fit = tmp_path / "run" / "fits" / "friction" / "fit.json"
    fit.parent.mkdir(parents=True)
    fit.write_text(json.dumps({"format": "pneumafit-fit", "version": 1, "model": "friction",
                               "campaign": {"path": str(tmp_path / "gone")}}))  # fmt: skip
    result = _cli("report", str(tmp_path / "run"))
    out = result.stdout + result.stderr
    assert result.returncode == 2, out
    assert str(tmp_path / "gone") in out and "--campaign" in out
    assert "Traceback" not in out
    assert not (tmp_path / "run" / "report.html").exists()
