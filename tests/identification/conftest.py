"""Shared fixtures: small virtual-rig campaigns with a known truth."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console

from pneumafit.campaign import Campaign, read_campaign
from pneumafit.virtual_rig import BlockedTest, FlowTest, Protocol, StepTest, VirtualRig

BAR = 1.0e5
#: Seed of the shared small campaign.
SMALL_SEED = 3


def small_protocol() -> Protocol:
    """Every stage's tests, short: two flow tests, three charge/discharge
    tests (2.5 s, one with the slow temperature sensor), two closed-loop step
    tests (2.5 s) and a held-out discharge. About 1 s of truth simulation."""
    cmds = (-10.0, -3.0, -0.4, -0.2, 0.0, 0.2, 0.4, 3.0, 10.0)
    pressures = (2.0 * BAR, 4.0 * BAR, 6.0 * BAR)
    units = {"p_P": "bar", "p_N": "bar", "qm_P": "g/s", "qm_N": "g/s"}
    tests = (
        FlowTest(file="flow_P.h5", chamber="P", commands=cmds, pressures=pressures, dwell=0.4,
                 units=units),
        FlowTest(file="flow_N.h5", chamber="N", commands=cmds, pressures=pressures, dwell=0.4,
                 units=units),
        BlockedTest(file="charge_P.h5", kind="charge", chamber="P", position=0.1, amplitude=10.0,
                    opening_time=0.3, duration=2.5, temperature=True),
        BlockedTest(file="discharge_P.h5", kind="discharge", chamber="P", position=0.3,
                    amplitude=8.0, opening_time=0.5, duration=2.5),
        BlockedTest(file="charge_N.h5", kind="charge", chamber="N", position=0.3, amplitude=10.0,
                    opening_time=0.25, duration=2.5),
        BlockedTest(file="discharge_N.h5", kind="discharge", chamber="N", position=0.2,
                    amplitude=10.0, opening_time=0.4, duration=2.0, role="validate"),
        StepTest(file="step_1.h5", start=0.25, steps=((0.3, 0.35), (1.4, 0.18)), duration=2.5,
                 preroll=2.0),
        StepTest(file="step_2.h5", start=0.3, steps=((0.3, 0.32), (1.1, 0.29), (1.8, 0.31)),
                 duration=2.5, preroll=2.0),
    )  # fmt: skip
    return Protocol(name="identification-small", description="small identification", tests=tests)


def make_campaign(folder: Path, seed: int) -> tuple[Campaign, dict[str, float]]:
    """Write the small protocol with ``seed`` into ``folder``; campaign and truth."""
    run = VirtualRig(seed=seed).write(folder, small_protocol())
    return read_campaign(folder), dict(run.truth["parameters"])


@pytest.fixture(scope="session")
def small(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Campaign, dict[str, float]]:
    """The small campaign (seed :data:`SMALL_SEED`): folder, campaign, truth."""
    folder = tmp_path_factory.mktemp("ident") / "small"
    campaign, truth = make_campaign(folder, SMALL_SEED)
    return folder, campaign, truth


@pytest.fixture(scope="session")
def campaign_factory() -> object:
    """:func:`make_campaign`, for tests that need a campaign of their own seed."""
    return make_campaign


@pytest.fixture
def console() -> Console:
    """A console printing into memory (``console.file.getvalue()``)."""
    return Console(file=io.StringIO(), width=160, color_system=None)
