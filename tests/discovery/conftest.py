"""Shared virtual-rig runs for the discovery tests."""

from __future__ import annotations

import pytest
from discovery_helpers import SEED

from pneumafit.rig import RigRun, VirtualRig


@pytest.fixture(scope="session")
def clean_rig() -> VirtualRig:
    """The demo truth without optional effects."""
    return VirtualRig(seed=SEED)


@pytest.fixture(scope="session")
def clean_run(clean_rig: VirtualRig) -> RigRun:
    """Quick campaign of the truth without effects."""
    return clean_rig.run("quick")


@pytest.fixture(scope="session")
def leak_run() -> RigRun:
    """Quick campaign with an undeclared chamber leakage (default size, 5e-11 kg/s/Pa)."""
    return VirtualRig(effects={"chamber_leakage": None}, seed=SEED).run("quick")
