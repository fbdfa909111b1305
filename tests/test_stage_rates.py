"""Where the main job's time goes: the simulation counter and the per-stage
wall time and simulation rate in ``summary.json`` and on the console."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from rich.console import Console

from pneumafit.models.parameters import parameter_vector
from pneumafit.pipeline import _print_stage_times, _summary
from pneumafit.simulation import Experiment, Simulator, counter


def test_the_counter_counts_every_parameter_set_on_every_experiment(
    charge_experiment: Experiment,
) -> None:
    sim = Simulator("convection", channels=["p_P"])
    params = parameter_vector({})
    n0 = counter.simulations()
    sim.simulate(params, charge_experiment)
    assert counter.simulations() - n0 == 1
    sim.simulate_batch(np.tile(params, (3, 1)), [charge_experiment, charge_experiment])
    assert counter.simulations() - n0 == 1 + 3 * 2


def test_the_summary_gives_each_stage_its_time_and_simulation_rate(tmp_path: Path) -> None:
    campaign = SimpleNamespace(name="c", sha256={"a.h5": "0"})
    timings = {"fit convection": 2.0, "comparison": 0.0, "linear": 0.5}
    sims = {"fit convection": 300, "linear": 0}  # comparison reused: 0 s, not counted
    total = _summary(tmp_path, campaign, tmp_path, timings, time.perf_counter() - 3.0, sims)
    doc = json.loads((tmp_path / "summary.json").read_text())
    assert total >= 3.0
    assert doc["seconds"] == timings
    assert doc["simulations"] == {"fit convection": 300, "comparison": 0, "linear": 0}
    assert doc["simulations_per_second"] == {"fit convection": 150.0, "comparison": None,
                                             "linear": 0.0}  # fmt: skip
    assert doc["total_simulations"] == 300

    console = Console(file=io.StringIO(), width=120, color_system=None)
    _print_stage_times(console, timings, sims)
    lines = console.file.getvalue().splitlines()
    assert "simulations" in lines[0] and "per second" in lines[0]
    assert lines[1].split() == ["fit", "convection", "2.0", "300", "150"]
    assert lines[2].split() == ["comparison", "0.0", "0", "reused"]
