"""Fixtures: a small virtual-rig campaign of blocked tests and fits of the three models.

The comparison needs fits of all three structures. The identification
tests' small campaign costs 45-120 s per model without MCMC (the joint stage
of a structure that cannot follow the data converges slowly), too much for
three models in the suite budget. The campaign here keeps only the tests
that separate the heat-transfer laws: charge and discharge tests, piston
blocked (the valve is held at its defaults, the rig's truth, for every model
alike, and the stages that need flow and step tests are skipped). Two tests
are held out for validation, one with the slow temperature sensor.
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console

from pneumafit.campaign import Campaign, read_campaign
from pneumafit.identification import FitOptions, fit_document, identify, write_fit_json
from pneumafit.virtual_rig import BlockedTest, Protocol, VirtualRig

#: Seed of the comparison campaign.
SEED = 5
MODELS = ("convection", "constant-lambda", "polytropic")


def blocked_protocol() -> Protocol:
    """Three fit and two validation charge/discharge tests (2-2.5 s each)."""
    tests = (
        BlockedTest(file="charge_P.h5", kind="charge", chamber="P", position=0.1, amplitude=10.0,
                    opening_time=0.3, duration=2.5, temperature=True),
        BlockedTest(file="discharge_P.h5", kind="discharge", chamber="P", position=0.3,
                    amplitude=8.0, opening_time=0.5, duration=2.5),
        BlockedTest(file="charge_N.h5", kind="charge", chamber="N", position=0.3, amplitude=10.0,
                    opening_time=0.25, duration=2.5),
        BlockedTest(file="discharge_N.h5", kind="discharge", chamber="N", position=0.2,
                    amplitude=10.0, opening_time=0.4, duration=2.0, role="validate"),
        BlockedTest(file="charge_P_2.h5", kind="charge", chamber="P", position=0.35,
                    amplitude=6.0, opening_time=0.6, duration=2.5, temperature=True,
                    role="validate"),
    )  # fmt: skip
    return Protocol(name="comparison-small", description="blocked tests only", tests=tests)


@pytest.fixture(scope="session")
def blocked_campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Campaign]:
    """Folder and campaign of :func:`blocked_protocol` (seed :data:`SEED`)."""
    folder = tmp_path_factory.mktemp("comparison") / "blocked"
    VirtualRig(seed=SEED).write(folder, blocked_protocol())
    return folder, read_campaign(folder)


@pytest.fixture(scope="session")
def blocked_fits(
    blocked_campaign: tuple[Path, Campaign], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, Path]:
    """Fit folders (fit.json, no MCMC) of the three models on the blocked campaign."""
    _folder, campaign = blocked_campaign
    root = tmp_path_factory.mktemp("fits")
    out: dict[str, Path] = {}
    for model in MODELS:
        options = FitOptions(mcmc=False)
        result = identify(campaign, model, options=options, seed=0)
        folder = root / model
        folder.mkdir()
        write_fit_json(folder / "fit.json", fit_document(result, campaign, seed=0, options=options))
        out[model] = folder
    return out


@pytest.fixture
def console() -> Console:
    """A console printing into memory (``console.file.getvalue()``)."""
    return Console(file=io.StringIO(), width=200, color_system=None)
