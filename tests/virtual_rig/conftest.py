"""Shared virtual-rig runs: the quick protocol, written once per session."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console

from pneumafit.cli.rig import run_rig
from pneumafit.virtual_rig import RigRun, VirtualRig


def quiet_console() -> Console:
    """A console printing into memory (``console.file.getvalue()``)."""
    return Console(file=io.StringIO(), width=200, color_system=None)


@pytest.fixture
def console() -> Console:
    """A fresh console printing into memory (``console.file.getvalue()``)."""
    return quiet_console()


@pytest.fixture(scope="session")
def quick_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Quick campaign with a hidden chamber leakage, written by ``run_rig``."""
    out = tmp_path_factory.mktemp("rig") / "quick"
    status = run_rig(out, ["chamber_leakage"], seed=11, console=quiet_console(), protocol="quick")
    assert status == 0
    return out


@pytest.fixture(scope="session")
def quick_run() -> RigRun:
    """Quick campaign without effects, in memory, with its true signals."""
    return VirtualRig(seed=5).run("quick")
