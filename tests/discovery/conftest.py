"""Shared virtual-rig runs for the discovery tests."""

from __future__ import annotations

import pytest
from discovery_helpers import SEED

from pneumafit.virtual_rig import RigRun, VirtualRig


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


# ------------------------------------------------------------ discovery loop
# One small campaign per hidden effect, fitted once (base convection model,
# no MCMC) and run through discovery once per session: see discovery_helpers.


@pytest.fixture(scope="session")
def discovery_cases(tmp_path_factory: pytest.TempPathFactory) -> object:
    """``case(effect)``: the :class:`DiscoveryCase` of a hidden effect (None: none).

    The first request makes every campaign of :data:`LOOP_CASES` at once, in
    two processes (:func:`run_cases`); they are kept for the session.
    """
    from discovery_helpers import LOOP_CASES, run_cases

    root = tmp_path_factory.mktemp("discover")
    cache: dict[str | None, object] = {}

    def case(effect: str | None) -> object:
        if effect not in cache:
            wanted = [e for e in LOOP_CASES if e not in cache] if effect in LOOP_CASES else [effect]
            cache.update(run_cases(root, wanted))
        return cache[effect]

    return case
