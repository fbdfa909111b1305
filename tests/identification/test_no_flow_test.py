"""A campaign without a flow test: the valve from the tests that open its paths.

Many rigs have no flow meter. Without a fit flow test the fit used to hold
every valve parameter at its default (a generic 10-V servo-valve), and on an
independently written rig (below, seed 1) its fit recordings' pressures then
missed the noise by 3.9-62x, the held-out ones by 4.5-119x.
The conductances are now fitted with the heat law from the charge/discharge
tests (stage b) and with everything else in the joint stage, where the
steps' commands, which sweep the valve's range, also decide the dead band,
the opening shape, the knee, the full-opening fractions, the critical ratios
and the null offset, each by a likelihood-ratio test.

Tests of two kinds:

- which paths a recording opens (:func:`coverage.opened_paths`), on
  hand-made recordings;
- recovery without an inverse crime: the sparse plan of the ``mixed`` truth
  (a tabulated supply path, a power-law exhaust, a Gaussian leak bump, LuGre
  friction with a seal term, barrel-only heat, lagging probes; LSODA at rtol
  1e-8 with sensor noise) less its flow test, fitted as a user would.
"""

from __future__ import annotations

import numpy as np
import pytest

from pneumafit.campaign import read_campaign
from pneumafit.campaign.model import Campaign, Recording
from pneumafit.identification import FitOptions, identify
from pneumafit.identification.coverage import opened_paths
from pneumafit.virtual_rig import VirtualRig
from pneumafit.virtual_rig.truth import reference_quantities

VALUES = {"valve_overlap": 0.3, "valve_u_sat": 10.0}


def _recording(kind: str, channels: dict[str, np.ndarray], chamber: str | None = "P") -> Recording:
    n = next(iter(channels.values())).size
    return Recording(
        file=f"{kind}.csv", path=None, kind=kind, role="fit", chamber=chamber,
        piston_position=None, controller=None, time=np.arange(n) * 1e-3, channels=channels,
        mask={}, units={}, unknown_channels=[],
    )  # fmt: skip


def test_a_charge_opens_the_supply_a_discharge_the_exhaust() -> None:
    """The command's sign past the dead band selects the path; a rest at 0 V
    (the centre leakage) and a command inside the dead band open neither."""
    rest = np.zeros(1000)
    charge = np.where(np.arange(1000) < 500, 10.0, 0.0)
    assert opened_paths([_recording("charge", {"u_P": charge})], VALUES) == {
        "supply": True, "exhaust": False,
    }  # fmt: skip
    assert opened_paths([_recording("discharge", {"u_P": -charge})], VALUES) == {
        "supply": False, "exhaust": True,
    }  # fmt: skip
    inside = np.full(1000, 0.6)  # within u_0 + 5 % of u_sat = 0.8 V
    for u in (rest, inside):
        assert opened_paths([_recording("charge", {"u_P": u})], VALUES) == {
            "supply": False, "exhaust": False,
        }  # fmt: skip


def test_a_moving_step_opens_both_paths() -> None:
    """One chamber fills while the other empties, also without recorded commands."""
    y = np.linspace(0.25, 0.34, 1000)
    step = _recording("step", {"y": y}, chamber=None)
    assert opened_paths([step], VALUES) == {"supply": True, "exhaust": True}
    still = _recording("step", {"y": np.full(1000, 0.25)}, chamber=None)
    assert opened_paths([still], VALUES) == {"supply": False, "exhaust": False}


@pytest.mark.slow
def test_the_valve_without_a_flow_test_on_a_mismatched_truth(tmp_path: object) -> None:
    """Recovery, not an inverse crime (module doc). Seed 1 of the sparse plan.

    - every fit recording's pressure within 3x the noise (the issue's target;
      measured 1.0-2.0x here; 3.9-62x with the valve at its defaults);
    - the full-opening conductances within 5 % of the truth's (the +-10-V
      charge and discharge measure them directly; measured -0.1 % and
      +0.0 %, and +0.7 % and -0.4 % on seed 5), from defaults 4 % and 9 %
      off;
    - the joint stage kept the dead band and opening shape (the table's
      progressive opening, which the steps' small commands live in), and the
      stage's note and the fit's warning say where the valve came from.
    """
    rig = VirtualRig(truth="mixed", seed=1)
    rig.write(tmp_path, "sparse")
    full = read_campaign(tmp_path)
    kept = [r for r in full.recordings if r.kind != "flow"]
    assert len(kept) < len(full.recordings)
    campaign = Campaign(path=None, name="mixed", description="", rig=full.rig, recordings=kept)
    result = identify(campaign, "convection", options=FitOptions(mcmc=False), seed=1)
    truth = reference_quantities(rig.truth, rig.parameters)

    fitted = [c for c in result.quality.channels if c.role == "fit" and c.channel.startswith("p_")]
    assert len(fitted) == 4  # charge, discharge, the step's two chambers
    assert max(c.ratio for c in fitted) < 3.0, [(c.recording, c.channel, c.ratio) for c in fitted]
    values = result.parameters.values()
    for path in ("supply", "exhaust"):
        got, want = values[f"valve_C_{path}"], truth[f"valve_C_{path}_max"]
        assert got == pytest.approx(want, rel=0.05), path
    joint = result.stage("joint")
    assert "valve dead band and opening shape (no flow test) kept" in joint.note
    assert {"valve_overlap", "valve_n_supply", "valve_n_exhaust"} <= set(joint.free)
    assert any("no fit flow test: the valve's sonic conductances" in w for w in result.warnings)
