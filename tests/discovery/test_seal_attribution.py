"""Attribution of the seal and barrel effects (no fit).

Friction effects do not enter the chambers' pressure rates at the measured
state, so attribution also regresses the piston's acceleration residual
while it slides (``motion`` rows); the effective area enters both. A quick
virtual-rig campaign with one hidden effect, attributed against the rig's
own model without it, must rank that effect first and support it, with a
coefficient near the hidden size; without a hidden effect none of the three
is supported.

The campaigns here are recorded and attributed with the step tests'
set-point interpolated linearly between samples (``INPUTS``), not held (the
default since 2026-11-28). Held, the 2.5-s step of the quick plan stops the
piston for a few milliseconds at each reversal of its overshoot, the rows
sliding faster than ``MIN_SLIDING_SPEED`` over two windows fall from 247 to
187, and with them the evidence that tells the direction asymmetry from the
effective area: the asymmetry alone still explains 99.8 % of the residual
acceleration, but the bootstrap sparse fit keeps the effective area (score
0.58) and never the asymmetry (measured 2026-11-28). What the test checks,
that attribution ranks a seal effect first where the campaign holds its
evidence, is the same either way; a plan for the asymmetry needs reversals
at speed (docs/effects.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from discovery_helpers import SEED

from pneumafit.discovery import EFFECTS
from pneumafit.discovery.attribution import (
    ANALYTIC_SIGNATURES,
    _sparse_fit,
    attribute,
    build_rows,
)
from pneumafit.physics.seal_effects import SEAL_EFFECTS
from pneumafit.virtual_rig import EFFECT_DEFAULTS, RigRun, VirtualRig

SEAL = tuple(SEAL_EFFECTS)
#: How the rig's kernel reads the steps' set-point (module docstring).
INPUTS = "linear"


def test_every_catalog_effect_has_a_regressor() -> None:
    """No effect is silently left out: those without a written-out pressure
    regressor get the kernel's own derivative (``ANALYTIC_SIGNATURES``)."""
    assert set(ANALYTIC_SIGNATURES) <= set(EFFECTS)
    assert set(EFFECTS) - set(ANALYTIC_SIGNATURES) == set(SEAL)


def test_signed_columns_keep_negative_coefficients() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((500, 2))
    y = -0.8 * x[:, 0] + 0.5 * x[:, 1] + 0.01 * rng.standard_normal(500)
    one_sided = _sparse_fit(x, y, 0.05)
    assert one_sided[0] == 0.0 and one_sided[1] > 0.0
    signed = _sparse_fit(x, y, 0.05, np.array([True, False]))
    assert signed[0] == pytest.approx(-0.8, abs=0.01) and signed[1] == pytest.approx(0.5, abs=0.01)


def _rows(run: RigRun, model: VirtualRig):  # type: ignore[no-untyped-def]
    return build_rows(run.campaign, model.structure, model.parameters)


@pytest.fixture(scope="module")
def model() -> VirtualRig:
    """The rig's truth without effects: the model the campaigns are attributed with."""
    return VirtualRig(seed=SEED, inputs=INPUTS)


def test_rows_of_both_channels(model: VirtualRig) -> None:
    rows = _rows(model.run("quick"), model)
    chan = rows.channels()
    assert {"pressure", "motion"} <= set(chan)
    motion = chan == "motion"
    for name in ANALYTIC_SIGNATURES:  # chamber effects: no term in dv/dt
        assert not np.any(rows.features[name][motion])
    for name in ("seal_friction", "friction_asymmetry"):  # no term in dP/dt
        assert not np.any(rows.features[name][~motion])
        assert np.all(np.isfinite(rows.features[name])) and np.any(rows.features[name][motion])
    for part in (motion, ~motion):  # the area enters both
        assert np.any(rows.features["effective_area"][part])
    result = attribute(rows, rng=np.random.default_rng(0), n_bootstrap=30)
    assert {c.effect for c in result.candidates} == set(EFFECTS)
    for c in result.candidates:
        if c.effect in SEAL:
            assert not c.supported, c


@pytest.mark.parametrize("name", SEAL)
def test_hidden_seal_effect_is_proposed(name: str, model: VirtualRig) -> None:
    e = SEAL_EFFECTS[name]
    run = VirtualRig(effects={name: None}, seed=SEED, inputs=INPUTS).run("quick")
    result = attribute(_rows(run, model), rng=np.random.default_rng(0), n_bootstrap=30)
    best = result.candidates[0]
    assert best.effect == name and best.supported, [
        (c.effect, round(c.score, 3), round(c.variance_explained, 3)) for c in result.candidates
    ]
    hidden = EFFECT_DEFAULTS[e.parameter] - e.neutral
    assert 0.5 < best.coefficient / hidden < 2.0, best.coefficient
    assert best.suggested[e.parameter] == pytest.approx(e.neutral + best.coefficient)


def test_lugre_model_sees_the_friction_effects(model: VirtualRig) -> None:
    """A LuGre base model (bristle state not measured: set to its steady
    sliding value per row) gives the friction effects the same evidence as
    the switch model: the hidden asymmetry first, a within 20 %."""
    from pneumafit.models import ModelStructure

    lugre = ModelStructure("convection", air_properties=model.structure.air_properties,
                           friction="lugre", inputs=INPUTS)  # fmt: skip
    run = VirtualRig(effects={"friction_asymmetry": None}, seed=SEED, inputs=INPUTS).run("quick")
    rows = build_rows(run.campaign, lugre, model.parameters)
    best = attribute(rows, rng=np.random.default_rng(0), n_bootstrap=30).candidates[0]
    assert best.effect == "friction_asymmetry" and best.supported
    assert best.coefficient == pytest.approx(0.2, rel=0.2)
