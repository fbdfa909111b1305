"""The progress reporter: rate-limited lines in a log, a live line on a terminal;
MCMC chains identical with and without progress."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from rich.console import Console

from pneumafit.identification import Parameter, ParameterSet, run_mcmc
from pneumafit.progress import Progress, Reporter


class FakeClock:
    """A clock that only moves when told."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_lines_at_most_every_interval_and_at_the_first_update_after_it() -> None:
    clock, lines, calls = FakeClock(), [], []

    def status() -> str:
        calls.append(clock.now)
        return f"at {clock.now - 100.0:.0f}"

    task = Progress("joint", lines.append, interval=5.0, clock=clock)
    for _ in range(23):  # an update every 1 s for 22 s
        clock.now += 1.0
        task.update(status)
    assert lines == ["joint: at 5, 5 s", "joint: at 10, 10 s", "joint: at 15, 15 s",
                     "joint: at 20, 20 s"]  # fmt: skip
    assert len(calls) == 4  # the status is computed only when a line is due
    assert task.updates == 23 and task.lines == 4
    # updates 4 s apart (the last line at 20 s, the last update at 23 s): a
    # line at the first update 5 s or more after the last line, so never more
    # than the interval plus one update's time without a line
    for status in "abc":
        clock.now += 4.0
        task.update(status)
    assert lines[4:] == ["joint: a, 27 s", "joint: c, 35 s"]


def test_reporter_in_a_log_says_lines_and_on_a_terminal_draws_a_live_line() -> None:
    clock, lines = FakeClock(), []
    log = Reporter(lines.append, console=Console(file=io.StringIO()), interval=2.0, clock=clock)
    assert not log.live
    with log.task("mcmc heat") as task:
        clock.now += 2.0
        task.update("step 10 of 100")
    assert lines == ["mcmc heat: step 10 of 100, 2 s"]

    lines.clear()
    screen = Console(file=io.StringIO(), force_terminal=True, width=80)
    live = Reporter(lines.append, console=screen, clock=clock)
    assert live.live
    with live.task("joint") as task:
        clock.now += 1.0
        task.update("12 points")
        assert task.live is not None
    assert task.live is None  # the live line is gone with the loop
    assert lines == []  # nothing said as a line on a terminal
    assert "joint (1 s): 12 points" in screen.file.getvalue()


MEAN = np.array([1.0, -2.0])
PREC = np.linalg.inv(np.array([[1.0, 0.9], [0.9, 4.0]]))


def gaussian(z: np.ndarray) -> np.ndarray:
    d = np.atleast_2d(z) - MEAN
    return -0.5 * np.einsum("ij,jk,ik->i", d, PREC, d)


def params() -> ParameterSet:
    return ParameterSet(
        [Parameter("a", 1.0, "", -50.0, 50.0), Parameter("b", -2.0, "", -50.0, 50.0)]
    )


def test_mcmc_chain_is_bit_identical_with_and_without_progress(tmp_path: Path) -> None:
    # extension rounds (max_steps) and checks (min_steps): every path that
    # continues a chain; a line at every step (interval 0)
    kw = {"n_walkers": 8, "n_steps": 30, "seed": 3, "max_steps": 300, "min_steps": 10}
    plain = run_mcmc(gaussian, params(), MEAN, None, **kw)
    lines: list[str] = []
    task = Progress("mcmc test", lines.append, interval=0.0)
    reported = run_mcmc(gaussian, params(), MEAN, None, report=task, **kw)
    assert np.array_equal(plain.chain, reported.chain)
    assert np.array_equal(plain.log_prob, reported.log_prob)
    assert plain.n_steps == reported.n_steps > 30 and plain.evaluations == reported.evaluations
    assert len(lines) == reported.n_steps
    assert lines[0].startswith("mcmc test: step 1 of 10 (limit 300), acceptance ")
    assert "tau not yet known" in lines[0]
    assert "tau " in lines[-1] and "steps (largest, chain so far)" in lines[-1]

    # an interrupted run with progress resumes (HDF5) to the same chain
    path = tmp_path / "chains.h5"
    calls = {"n": 0}

    def flaky(z: np.ndarray) -> np.ndarray:
        calls["n"] += 1
        if calls["n"] == 25:
            raise KeyboardInterrupt
        return gaussian(z)

    try:
        run_mcmc(flaky, params(), MEAN, None, backend=path, report=task, **kw)
    except KeyboardInterrupt:
        pass
    resumed = run_mcmc(gaussian, params(), MEAN, None, backend=path, report=task, **kw)
    assert resumed.resumed_from > 0
    assert np.array_equal(plain.chain, resumed.chain)
