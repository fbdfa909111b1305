"""Friction that grows with the chamber pressures (``--seal-friction``) in the staged fit."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import read_campaign
from pneumafit.cli.rig import run_rig
from pneumafit.identification.starts import SEAL_LEVELS, SEAL_NESTED, seal_start, seal_starts

SEAL = "seal_friction_coefficient"


def _record(folder: Path, truth: str, protocol: str, seed: int = 1) -> Path:
    quiet = Console(file=io.StringIO(), width=200, color_system=None)
    assert run_rig(folder, seed=seed, console=quiet, protocol=protocol, truth=truth) == 0
    return folder


def test_the_seal_fit_starts_from_the_fit_without_it(tmp_path: Path) -> None:
    """Exact: the first start is the fit without the effect, the coefficient
    at SEAL_NESTED (so the fit with it can only end higher); the second is
    the force balance's coefficient c0 with the static and Coulomb levels
    lowered by c0 times the step tests' mean pressure sum, the other values
    unchanged."""
    camp = read_campaign(_record(tmp_path / "c", "lugre-pressure", "sparse"))
    steps = [r for r in camp.recordings if r.kind == "step" and r.role == "fit"]
    rig = camp.rig.as_parameters()
    values = {"friction_static": 52.0, "friction_coulomb": 31.0, "friction_viscous": 60.0}
    starts = seal_starts(steps, rig, values, SEAL)
    assert starts[0] == {**values, SEAL: SEAL_NESTED}
    c0 = seal_start(steps, rig)
    assert c0 > SEAL_NESTED and len(starts) == 2
    sums = np.concatenate([r.channels["p_P"] + r.channels["p_N"] - 2 * rig["exhaust_pressure"]
                           for r in steps])  # fmt: skip
    shift = c0 * float(np.mean(sums))
    assert 1.0 < shift < 30.0  # newtons: a seal term of the size the truth has
    for name in SEAL_LEVELS:
        assert starts[1][name] == pytest.approx(values[name] - shift, rel=1e-12)
    assert starts[1][SEAL] == c0 and starts[1]["friction_viscous"] == 60.0
    # without a step test's sliding samples there is only the nested start
    assert seal_starts([], rig, values, SEAL) == [{**values, SEAL: SEAL_NESTED}]


def test_the_default_leaves_short_step_tests_without_the_term(tmp_path: Path) -> None:
    """Plumbing: the default ``long`` does not try the seal friction where no
    fit step test is cut into segments (the sparse plan's 2-s tests), and
    the friction-test command's ``long`` is ``off``."""
    from pneumafit.api import fit
    from pneumafit.cli.friction import _EFFECTS
    from pneumafit.identification import FitOptions

    assert FitOptions().seal == "long" and _EFFECTS["long"] == "off"
    camp = read_campaign(_record(tmp_path / "s", "lugre-pressure", "sparse"))
    result = fit(camp, "convection", mcmc=False, seed=1)
    assert not result.structure.effects.get("seal_friction")
    assert not any("seal friction" in (s.note or "") for s in result.stages)


@pytest.mark.slow
def test_friction_growing_with_pressure_is_found_on_a_truth_of_another_law(
    tmp_path: Path,
) -> None:
    """Mismatched truth: ``lugre-pressure`` (LuGre whose levels *multiply*
    by 1 + k_p (P_P + P_N - 2 P_atm), k_p 4.2e-7 /Pa, against the fit's
    *additive* c (P_P + P_N - 2 P_atm); its own valve paths and centre-leak
    bump), recorded by the independent truth simulator (LSODA, rtol 1e-8)
    with sensor noise, on the sparse-long plan (8-s closed-loop steps, fitted
    in segments), ``--no-mcmc --seed 1`` with the default ``--seal-friction
    long`` (auto for step tests fitted in segments).

    Measured 2026-11-30: before the nested start the seal fit ended 1205
    below the fit without it and the effect was rejected (first segment of
    the fit step test at 30.9x the pressure noise, held-out step 15.7x);
    now kept (gain 6003), first segment 2.3x, held-out 4.2x, friction at mid
    pressure static -0.7 % and Coulomb -2.2 % from the truth's reference.
    Held to: kept; first segment within 4x and held-out within 8x (half
    way, in ratio, between the two outcomes); static and Coulomb within 5 %
    (the truth's multiplicative law is not the fit's additive one; 5 % is
    twice the worst error measured).

    Since 2026-12-04 (night) the verdict takes one zero per pressure sensor
    off every recording (not each recording's own mean): measured then,
    kept first segment 4.42x and held-out 8.49x (p_N), and the fit without
    the effect (``FitOptions(seal="off")``, the rejected outcome) 31.95x and
    18.79x. The same rule, half way in ratio between the two outcomes, gives
    11.9x and 12.6x: the bounds are 11.9 and 12.6."""
    from pneumafit.api import fit
    from pneumafit.identification import FitOptions

    folder = _record(tmp_path / "lp", "lugre-pressure", "sparse-long")
    camp = read_campaign(folder)
    truth = json.loads((folder / "truth.json").read_text())["truth_model"]["reference_quantities"]
    result = fit(camp, "convection", mcmc=False, seed=1, options=FitOptions())
    assert result.structure.effects.get("seal_friction"), "the seal friction was not kept"

    def worst(recording: str) -> float:
        return max(c.ratio for c in result.quality.channels
                   if c.recording == recording and c.channel in ("p_P", "p_N"))  # fmt: skip

    assert worst("step_1.h5@0.000s") < 11.9
    assert worst("step_2.h5") < 12.6
    ref = result.metrics["friction_reference"]
    assert ref["static"]["value"] == pytest.approx(truth["friction_static"], rel=0.05)
    assert ref["coulomb"]["value"] == pytest.approx(truth["friction_coulomb"], rel=0.05)


@pytest.mark.slow
def test_no_seal_friction_on_the_rigs_own_laws(tmp_path: Path) -> None:
    """Control: the rig's ``fit-laws`` truth (the fit's laws, no seal term:
    c = 0), recorded by the truth simulator with noise, sparse-long plan,
    ``--no-mcmc --seed 1`` with the default ``--seal-friction long``. Measured 2026-11-30: while
    the gain was counted against the friction stage's optimum in its own
    problem, the term was kept for a gain of 1162 with the coefficient at
    1e-10 N/Pa (the trial had found a better optimum of the law without
    it); counted in the trial's problem against the better point without
    the term, the gain is 0.0. Held to: not kept."""
    from pneumafit.api import fit
    from pneumafit.identification import FitOptions

    camp = read_campaign(_record(tmp_path / "fl", "fit-laws", "sparse-long"))
    result = fit(camp, "convection", mcmc=False, seed=1, options=FitOptions())
    assert not result.structure.effects.get("seal_friction")
    notes = " ".join(s.note for s in result.stages if s.note)
    assert "seal friction not kept" in notes  # tried (the default on segments), not kept
