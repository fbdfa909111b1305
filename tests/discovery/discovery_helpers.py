"""Helpers of the discovery tests (imported by name: pytest puts this folder on sys.path)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pneumafit.discovery import ResidualReport, residual_analysis
from pneumafit.rig import RigRun, VirtualRig
from pneumafit.simulation import Experiment, Simulator

#: Seed of the single-campaign rig tests.
SEED = 5


def truth_residuals(
    run: RigRun,
    model: VirtualRig,
    *,
    initial: str = "truth",
    offsets: bool = True,
    channels: Sequence[str] = ("p_P", "p_N", "y"),
    **options: Any,
) -> dict[str, ResidualReport]:
    """Residual reports of a rig run's charge, discharge and step tests,
    simulated with ``model``'s structure and parameters (Kutta RK3, 1 ms).

    Parameters
    ----------
    initial : {"truth", "recording"}
        Start each simulation from the true initial state of the test
        (truth.json), or from the first recorded samples
        (``Experiment.from_recording``, as for a real bench).
    offsets : bool
        Add the drawn pressure-sensor offsets to the simulated pressures.

    With ``initial="truth"`` and ``offsets`` the residual is the sensor noise
    plus whatever the model leaves out.
    """
    sim = Simulator(model.structure)
    drawn: Mapping[str, float] = run.truth["sensors"]["pressure_offsets"]
    states = {r["file"]: r.get("initial_state", {}) for r in run.truth["recordings"]}
    reports = {}
    for rec in run.campaign.recordings:
        if rec.kind == "flow":
            continue
        exp = Experiment.from_recording(rec)
        if initial == "truth":
            exp = dataclasses.replace(exp, initial={**exp.initial, **states[rec.file]})
        result = sim.simulate(model.parameters, exp)
        assert result.ok, result.message
        simulated = dict(result.channels)
        if offsets:
            for name, offset in drawn.items():
                simulated[name] = simulated[name] + offset
        names = [c for c in channels if c in rec.channels]
        reports[rec.file] = residual_analysis(rec, simulated, channels=names, **options)
    return reports


def white_noise(seed: int, n: int) -> np.ndarray:
    """Standard white noise from a seeded generator."""
    return np.random.default_rng(seed).standard_normal(n)


def ar1(seed: int, n: int, phi: float) -> np.ndarray:
    """AR(1) series x_t = phi x_{t-1} + w_t, started in its stationary law."""
    w = white_noise(seed, n)
    x = np.empty(n)
    x[0] = w[0] / np.sqrt(1.0 - phi**2)
    for t in range(1, n):
        x[t] = phi * x[t - 1] + w[t]
    return x
