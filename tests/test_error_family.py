"""The domain packages raise the one error family (issue 13, pneumafit/errors.py).

These are plumbing tests: for one or two representative sites per package
converted from a bare ``ValueError`` / ``RuntimeError``, a public function
given bad input raises :class:`PneumafitInputError` (still a ``ValueError``)
whose message names the key and the value found, and a computation that
fails raises :class:`PneumafitComputationError` (still a ``RuntimeError``).
The behaviour of each check is tested beside its module; here only the type
and the message's key and found value are.
"""

from __future__ import annotations

import re
from contextlib import AbstractContextManager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pneumafit.errors import PneumafitComputationError, PneumafitError, PneumafitInputError


def raises_input(*words: str) -> AbstractContextManager[pytest.ExceptionInfo[PneumafitInputError]]:
    """``pytest.raises`` of an input error whose message holds every word, in order."""
    return pytest.raises(PneumafitInputError, match=".*".join(re.escape(w) for w in words))


# ------------------------------------------------------------ identification
def test_parameter_out_of_bounds() -> None:
    from pneumafit.identification.parameters import Parameter

    with raises_input("parameter 'xi'", "value", "[0, 1]", "found 2"):
        Parameter(name="xi", value=2.0, lower=0.0, upper=1.0)


def test_unknown_noise_model() -> None:
    from pneumafit.identification.noise import noise_model

    with raises_input("noise model", "expected one of", "found 'cauchy'"):
        noise_model("cauchy")


def test_problem_without_recordings_and_with_unknown_channels() -> None:
    from pneumafit.campaign.model import Recording
    from pneumafit.identification.problem import Problem

    with raises_input("problem", "recording", "found none"):
        Problem([])
    t = np.linspace(0.0, 1.0, 11)
    rec = Recording.from_arrays(t, {"y": t}, kind="free")
    with raises_input("problem: channels", "found ['q']"):
        Problem([rec], channels=["y", "q"])


def test_fit_document_without_seed() -> None:
    from pneumafit.identification.fitfile import fit_document

    result = SimpleNamespace(campaign={"name": "demo"}, seed=None)
    with raises_input("fit document", "expected a seed", "found none"):
        fit_document(result, None)  # type: ignore[arg-type]


# ---------------------------------------------------------------- simulation
def test_simulator_step_and_channels() -> None:
    from pneumafit.simulation import Simulator

    with raises_input("simulator: step", "found -0.001"):
        Simulator("convection", step=-1e-3)
    with raises_input("simulator: channels", "found ['q']"):
        Simulator("convection", channels=["y", "q"])


def test_experiment_time_not_increasing() -> None:
    from pneumafit.simulation import Experiment

    t = np.array([0.0, 0.1, 0.1, 0.2])
    with raises_input("experiment 'x'", "time", "strictly increasing", "found 0.1 s followed by"):
        Experiment(time=t, kind="free", u_P=np.zeros(4), name="x")


def test_blocked_test_kind() -> None:
    from pneumafit.simulation.scenarios import blocked_test

    with raises_input("blocked test: kind", "found 'leak'"):
        blocked_test("leak", {}, chamber="P", position=0.1)


# ------------------------------------------------------------------ analysis
def test_controller_from_an_old_export() -> None:
    from pneumafit.analysis.controller import ScheduledController

    with raises_input("export", "version-2", "found version 1"):
        ScheduledController.from_export({"version": 1})


# ------------------------------------------------------------------- outputs
def test_export_format_and_file(tmp_path: Path) -> None:
    from pneumafit.outputs.export import read_export, write_export

    with raises_input("export: format", "found 'docx'"):
        write_export({}, tmp_path / "out.docx", "docx")
    other = tmp_path / "other.json"
    other.write_text('{"format": "pneumafit-fit"}', encoding="utf-8")
    with raises_input(str(other), "format", "found 'pneumafit-fit'"):
        read_export(other)


def test_a_failed_compilation_is_a_computation_error(tmp_path: Path) -> None:
    from pneumafit.outputs.c_controller import compile_controller

    source = tmp_path / "controller.c"
    source.write_text("int main(void) { return 0; }\n", encoding="utf-8")
    false = Path("/bin/false")
    if not false.exists():
        pytest.skip("no /bin/false to play a failing compiler")
    with pytest.raises(PneumafitComputationError, match=r"compiling .*controller\.c failed"):
        compile_controller(source, tmp_path / "controller.so", compiler=str(false))


# ----------------------------------------------------------------- discovery
def test_correlation_lag_and_phase_rules() -> None:
    from pneumafit.discovery.correlation import autocorrelation
    from pneumafit.discovery.phases import PhaseRules

    with raises_input("max_lag", "[1, 3]", "found 0"):
        autocorrelation([1.0, 2.0, 0.0, 1.0], 0)
    with raises_input("phase rules: speed", "found -1.0"):
        PhaseRules(speed=-1.0)


# ---------------------------------------------------------------- comparison
def test_pointwise_likelihood_of_a_student_t_block() -> None:
    from pneumafit.comparison.information import pointwise_log_likelihood
    from pneumafit.identification.noise import StudentT

    block = SimpleNamespace(noise=StudentT(), floor=0.0, weight=None, recording="a.h5",
                            channel="p_P")  # fmt: skip
    problem = SimpleNamespace(
        predict=lambda values, n: SimpleNamespace(ok=np.ones(n, dtype=bool)),
        residuals=lambda pred: [np.arange(1.0, 6.0)[None, :]],
        observations=[block],
        tempering=np.ones(1),
    )
    with raises_input("a.h5 p_P", "expected a Gaussian or AR(1)", "found student-t"):
        pointwise_log_likelihood(problem, {}, 1)  # type: ignore[arg-type]


# ----------------------------------------------------- campaign and physics
def test_recording_time_and_valve_map() -> None:
    from pneumafit.campaign.model import Recording
    from pneumafit.physics.valve_map import map_from_iso

    with raises_input("time", "strictly increasing", "found 1 s followed by 1 s"):
        Recording.from_arrays([0.0, 1.0, 1.0], {"y": [0.0, 0.0, 0.0]}, kind="free")
    with raises_input("map_from_iso", "found none for", "valve_C_supply"):
        map_from_iso({})


def test_the_family_is_caught_as_one() -> None:
    from pneumafit.discovery.correlation import whiteness_band

    with pytest.raises(PneumafitError):
        whiteness_band(100, alpha=2.0)
    with pytest.raises(ValueError, match="alpha"):  # callers that catch ValueError still do
        whiteness_band(100, alpha=2.0)


@pytest.mark.parametrize(("name", "text"), [("c.json", "{not json"), ("c.yaml", "a: [1, 2")])
def test_a_controller_export_that_does_not_parse_is_bad_input(
    tmp_path: Path, name: str, text: str
) -> None:
    """Plumbing: a syntax error in a controller export names the file (bad input, not a bug)."""
    from pneumafit.outputs.export import read_export

    (tmp_path / name).write_text(text)
    with pytest.raises(PneumafitInputError, match=name):
        read_export(tmp_path / name)
