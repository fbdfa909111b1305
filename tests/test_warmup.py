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


# ------------------------------------------------------- the warm-up at first use


def _fake_warm_up(calls: list[int]):  # type: ignore[no-untyped-def]
    """A warm-up that only leaves the mark, as the real one does when it ends."""
    from pneumafit import warmup

    def fake(log=None):  # type: ignore[no-untyped-def]
        calls.append(1)
        warmup._mark({"fake": 0.0})
        return {"fake": 0.0}

    return fake


def test_a_command_warms_up_once_at_first_use(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without the mark the command's warm-up runs (and says so), leaves the
    mark and is not run again; the real warm-up's mark and compile are the
    slow test below. A synthetic check of the logic: the warm-up is faked."""
    from pneumafit import warmup

    mark = tmp_path / "cache" / "pneumafit-warm-test.txt"
    calls: list[int] = []
    monkeypatch.setattr(warmup, "marker", lambda: mark)
    monkeypatch.setattr(warmup, "warm_up", _fake_warm_up(calls))
    monkeypatch.setenv(warmup.AUTO_ENV, "1")
    lines: list[str] = []
    assert warmup.ensure_warm(lines.append) is not None
    assert calls == [1] and mark.exists()
    assert lines[0].startswith("first use of this install: compiling the simulator")
    assert lines[-1].startswith("simulator ready")
    assert warmup.ensure_warm(lines.append) is None
    assert calls == [1]
    # off by the environment, or where numba does not say where its cache is
    mark.unlink()
    monkeypatch.setenv(warmup.AUTO_ENV, "0")
    assert warmup.ensure_warm(lines.append) is None
    monkeypatch.setenv(warmup.AUTO_ENV, "1")
    monkeypatch.setattr(warmup, "marker", lambda: None)
    assert warmup.ensure_warm(lines.append) is None
    assert calls == [1]


def test_the_simulating_commands_warm_up_and_check_does_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From the command line: ``simulate`` prints the first-use lines before its
    own output, ``check`` (which simulates nothing) never runs the warm-up, and
    a simulating command whose input is refused ends before its first
    simulation without it (the warm-up waits for that simulation,
    :mod:`pneumafit.first_use`): a mistyped path costs no compile."""
    from typer.testing import CliRunner

    from pneumafit import warmup
    from pneumafit.cli.app import app
    from pneumafit.errors import PneumafitInputError

    mark = tmp_path / "cache" / "pneumafit-warm-test.txt"
    calls: list[int] = []
    monkeypatch.setattr(warmup, "marker", lambda: mark)
    monkeypatch.setattr(warmup, "warm_up", _fake_warm_up(calls))
    monkeypatch.setenv(warmup.AUTO_ENV, "1")
    runner = CliRunner()
    checked = runner.invoke(app, ["check", str(tmp_path / "no-campaign")])
    assert calls == [] and "first use" not in checked.output
    # refused by the commands themselves (typer already refuses a missing path)
    (tmp_path / "empty-campaign").mkdir()
    (tmp_path / "bad-params.json").write_text("{not json")
    for refused in (["fit", str(tmp_path / "empty-campaign"), "--out", str(tmp_path / "f")],
                    ["simulate", str(tmp_path / "bad-params.json"), "--kind", "charge",
                     "--out", str(tmp_path / "s.h5")]):  # fmt: skip
        result = runner.invoke(app, refused)
        # exit 2, or the input error that pneumafit's entry point turns into it
        assert result.exit_code == 2 or isinstance(result.exception, PneumafitInputError), (
            result.output
        )
        assert calls == [] and "first use" not in result.output, result.output
    params = tmp_path / "params.json"
    params.write_text(json.dumps({"model": "convection", "parameters": {"xi": 0.4}}))
    command = ["simulate", str(params), "--kind", "charge", "--duration", "0.05 s",
               "--out", str(tmp_path / "sim.h5")]  # fmt: skip
    result = runner.invoke(app, command)
    assert result.exit_code == 0, result.output
    assert calls == [1]
    assert result.output.index("first use of this install") < result.output.index("simulator ready")
    again = runner.invoke(app, command)
    assert again.exit_code == 0 and "first use" not in again.output and calls == [1]


@pytest.mark.slow  # slow job: two commands, the first from an empty cache (about 50 s)
def test_the_first_command_of_an_install_compiles_in_the_warm_up(tmp_path: Path) -> None:
    """The real thing, from an empty numba cache in a subprocess: the first
    ``pneumafit simulate`` runs the warm-up (its lines, then the mark in the
    kernel's cache folder); the second finds the mark and prints only its own
    output. Can fail: a mark not written, or written where ``marker`` does
    not look, runs the warm-up twice."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "NUMBA_NUM_THREADS": "1",
           "PNEUMAFIT_AUTO_WARMUP": "1"}  # fmt: skip
    params = tmp_path / "params.json"
    params.write_text(json.dumps({"model": "convection", "parameters": {"xi": 0.4}}))
    command = [sys.executable, "-m", "pneumafit", "simulate", str(params), "--kind", "charge",
               "--duration", "0.05 s", "--out", str(tmp_path / "sim.h5")]  # fmt: skip
    first = subprocess.run(command, env=env, capture_output=True, text=True, timeout=900,
                           check=False)  # fmt: skip
    assert first.returncode == 0, first.stderr[-2000:]
    assert "first use of this install" in first.stdout, first.stdout
    assert "simulate (serial)" in first.stdout
    marks = list((tmp_path / "cache").rglob("pneumafit-warm-*.txt"))
    assert len(marks) == 1, marks
    second = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300,
                            check=False)  # fmt: skip
    assert second.returncode == 0, second.stderr[-2000:]
    assert "first use" not in second.stdout, second.stdout
