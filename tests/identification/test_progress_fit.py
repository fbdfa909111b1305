"""Progress of a fit in a log: lines inside the least-squares and MCMC stages,
and the same fit.json numbers and chains with and without them."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from pneumafit import progress as progress_module
from pneumafit.cli.console import LogConsole
from pneumafit.cli.fit import fit_command

#: Short chains: the plumbing, not the posteriors.
WALKERS, STEPS = 8, 12


def _fit(folder: Path, out: Path) -> str:
    console = LogConsole(file=io.StringIO(), color_system=None)
    assert not console.is_terminal
    code = fit_command(folder, "convection", out, WALKERS, STEPS, 7, True, console,
                       friction="switch")  # fmt: skip
    assert code == 0
    return console.file.getvalue()


#: What may differ between the two fits: wall times, the date, the --out folder.
VARYING = ("seconds", "created", "command")


def _numbers(doc: object) -> object:
    """The document without :data:`VARYING` entries."""
    if isinstance(doc, dict):
        return {k: _numbers(v) for k, v in doc.items() if k not in VARYING}
    if isinstance(doc, list):
        return [_numbers(v) for v in doc]
    return doc


def _chains(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        return {name: np.asarray(f[name]["chain"]) for name in f}


@pytest.mark.slow  # two fits with MCMC: about 80 s on the 2-core machine
def test_a_fit_logs_progress_inside_its_stages_and_the_same_numbers(
    small: tuple, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder, _, _ = small
    # a line at every update (the log interval is the reporter's default)
    monkeypatch.setattr(progress_module, "LOG_INTERVAL", 0.0)
    logged = _fit(folder, tmp_path / "with")
    lines = logged.splitlines()
    point = re.compile(
        r"^(\w+[\w ()]*): (start \d+/\d+, )?round \d+: \d+ points \(\d+ simulations\), "
        r"log-likelihood -?\d+\.\d \([+-]\d+\.\d this round\), \d+ s$"
    )
    stages = {m.group(1) for m in map(point.match, lines) if m}
    # every least-squares stage, not only the joint (the valve stage may come
    # from this process's cache of an earlier fit of the campaign)
    assert {"heat", "friction", "joint", "joint (corrected)"} <= stages
    step = re.compile(
        r"^mcmc (heat|friction): step (\d+) of \d+.*, acceptance \d\.\d\d, tau .*, "
        r"\d+ evaluations, \d+ s$"
    )
    steps = [m for m in map(step.match, lines) if m]
    assert {m.group(1) for m in steps} == {"heat", "friction"}
    assert [int(m.group(2)) for m in steps if m.group(1) == "heat"] == list(range(1, STEPS + 1))

    monkeypatch.setattr(progress_module, "LOG_INTERVAL", 1e9)
    quiet = _fit(folder, tmp_path / "without")
    assert not any(point.match(x) or step.match(x) for x in quiet.splitlines())
    with_doc = json.loads((tmp_path / "with" / "fit.json").read_text())
    without_doc = json.loads((tmp_path / "without" / "fit.json").read_text())
    assert _numbers(with_doc) == _numbers(without_doc)
    a, b = _chains(tmp_path / "with" / "chains.h5"), _chains(tmp_path / "without" / "chains.h5")
    assert a.keys() == b.keys() == {"heat", "friction"}
    assert all(np.array_equal(a[k], b[k]) for k in a)
