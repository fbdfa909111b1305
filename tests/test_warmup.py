"""The warm-up compiles what the simulator's entry points later call: after
it, a step test, a blocked charge, a batch, a step choice and a sampled loop
add no compiled signature, so nothing is compiled at first use."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneumafit.models import kernel
from pneumafit.models.parameters import parameter_vector
from pneumafit.simulation import Experiment, Simulator, choose_step, simulate_sampled
from pneumafit.warmup import warm_up

ENTRY_POINTS = (
    kernel.integrate_many, kernel.integrate_many_serial, kernel.integrate_jobs,
    kernel.stiffness_bound, kernel.static_valve_flows, kernel.check_parameters,
)  # fmt: skip


def _signatures() -> dict[str, int]:
    return {f.__name__: len(f.signatures) for f in ENTRY_POINTS}


def test_after_the_warm_up_nothing_compiles_at_first_use(
    step_experiment: Experiment, charge_experiment: Experiment
) -> None:
    seconds = warm_up()
    assert {"simulate (serial)", "simulate_batch (parallel)", "simulate_sampled"} <= set(seconds)
    warmed = _signatures()
    assert all(n >= 1 for n in warmed.values()), warmed
    sim = Simulator("convection", channels=["y", "p_P"])
    assert sim.simulate({}, step_experiment).ok
    assert sim.simulate({"xi": 0.4}, charge_experiment).ok
    sets = np.tile(parameter_vector({}), (3, 1))
    _, status = sim.simulate_batch(sets, [step_experiment, charge_experiment])
    assert np.all(status == 0)
    # one set on two experiments, and fitted initial states (read-only inputs
    # would be another compiled type: the simulator makes them writable)
    packed = sim.pack([step_experiment, charge_experiment])
    sim.simulate_batch(np.broadcast_to(sets[0], (1, sets.shape[1])), packed)
    x0s = np.broadcast_to(packed.x0s, (1, *packed.x0s.shape))
    sim.simulate_batch(sets[:1], packed, initial_states=x0s)
    sim.simulate_batch(sets[:1], sim.pack([step_experiment]), initial_states=x0s[:, :1])
    # a Jacobian's batch: pairs shared with the first set, fitted initial states
    same = np.array([[False, False], [True, False], [False, True]])
    x0s3 = np.repeat(x0s, 3, axis=0)
    sim.simulate_batch(sets, packed, initial_states=x0s3, same_as_first=same)
    choose_step({}, y_range=(0.1, 0.4))
    t = step_experiment.time[:200]
    simulate_sampled({}, t, np.full(t.size, 0.26), lambda x, r: 50.0 * (r - x[0]))
    assert _signatures() == warmed


#: Compiles the warm-up with numba's compile events recorded, from an empty
#: cache, and prints how often each kernel function was compiled.
_COUNT_COMPILES = """
import collections, json
from numba.core import event
from pneumafit.warmup import warm_up
with event.install_recorder("numba:compile") as rec:
    warm_up()
counts = collections.Counter(
    ev.data["dispatcher"].py_func.__qualname__
    for _, ev in rec.buffer
    if ev.is_start and ev.data["dispatcher"].py_func.__module__ == "pneumafit.models.kernel"
)
print(json.dumps(counts))
"""


@pytest.mark.slow  # slow job: a compilation from an empty cache (about 45 s)
def test_the_warm_up_compiles_each_kernel_function_once(tmp_path: Path) -> None:
    """A call with a constant argument (``rhs(x, 0, ...)``) is typed as that
    literal and numba compiles the callee, and all it calls, once more for
    it (README, "Performance": rk_step was compiled six times, the serial
    simulation took 33 s to compile instead of 15). From an empty cache, the
    warm-up compiles every function of the kernel once. ``_fail`` (two
    lines, its status codes module constants) is the one function allowed
    more. A test that cannot pass by accident: a literal argument put back
    at any call of the integration loop compiles its callee twice."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "NUMBA_NUM_THREADS": "1"}
    run = subprocess.run(
        [sys.executable, "-c", _COUNT_COMPILES], env=env, capture_output=True, text=True,
        timeout=600, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    counts = json.loads(run.stdout.strip().splitlines()[-1])
    for name in ("rhs", "rk_step", "integrate_from", "integrate", "_run_job"):
        assert counts.get(name) == 1, counts
    twice = {name: n for name, n in counts.items() if n > 1 and name != "_fail"}
    assert not twice, twice
