"""Parts of one's own on the command line: ``pneumafit --parts FILE`` and ``PNEUMAFIT_PARTS``.

Plumbing tests: a file that registers a heat law is loaded once, named in
the environment for the command's workers, and bad files are named in the
error. The slow test fits the heat law from the command line.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from pneumafit.cli import plugins
from pneumafit.errors import PneumafitInputError
from pneumafit.models import layout, parts

PARTS_FILE = '''
"""A heat law of my own: lambda growing as the square root of the pressure."""
import math

from numba import njit

from pneumafit.models import ParameterSpec, layout, parts

parts.register_parameter(ParameterSpec(
    "root_p_coefficient", "W/m^2/K", 10.0, 0.1, 1000.0, "heat",
    "lambda at 1 bar of the square-root law",
))
C = layout.P["root_p_coefficient"]


@njit
def root_pressure(p, pres, temp, t_wall):
    return p[C] * math.sqrt(pres / 1.0e5)


parts.register_heat_law(parts.HeatLaw(
    name="root-p", code=8, parameters=("root_p_coefficient",),
    description="lambda ~ sqrt(P / 1 bar)", label="root-p", colour="tab:purple", order=5,
    starts=({"root_p_coefficient": 7.0}, {"root_p_coefficient": 20.0}), kernel=root_pressure,
))
'''


@pytest.fixture
def clean() -> Iterator[None]:
    """No PNEUMAFIT_PARTS, nothing loaded before; the test's parts removed after.

    ``load_parts`` sets the variable itself (for the command's workers), so
    it is restored by hand: left set, every later command run in this
    process would load the test's file again.
    """
    saved = os.environ.pop(plugins.ENVIRONMENT_VARIABLE, None)
    loaded = dict(plugins._LOADED)
    heat = set(parts.HEAT_LAWS)
    n = layout.n_parameters()
    yield
    for name in set(parts.HEAT_LAWS) - heat:
        parts.unregister_heat_law(name)
    while layout.n_parameters() > n:
        parts.unregister_parameter(layout.PARAMETER_NAMES[-1])
    plugins._LOADED.clear()
    plugins._LOADED.update(loaded)
    os.environ.pop(plugins.ENVIRONMENT_VARIABLE, None)
    if saved is not None:
        os.environ[plugins.ENVIRONMENT_VARIABLE] = saved


def test_a_parts_file_is_loaded_once_and_named_for_workers(clean: None, tmp_path: Path) -> None:
    path = tmp_path / "root_p.py"
    path.write_text(PARTS_FILE, encoding="utf-8")
    assert "root-p" not in parts.HEAT_LAWS
    plugins.load_parts([str(path)])
    assert parts.HEAT_LAWS["root-p"].kernel is not None
    assert os.environ[plugins.ENVIRONMENT_VARIABLE] == str(path.resolve())
    # a second load (another command in the same process, or the variable
    # naming it again) does not register it twice, which the registry refuses
    plugins.load_parts([str(path)])
    plugins.load_parts()
    assert os.environ[plugins.ENVIRONMENT_VARIABLE] == str(path.resolve())


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (None, "no such file"),
        ("def broken(:\n", "SyntaxError"),
        ("import not_a_module_anywhere\n", "ModuleNotFoundError"),
        (PARTS_FILE.replace("code=8", "code=2"), "code 2: expected a code no other heat law has"),
        (PARTS_FILE.replace('"W/m^2/K"', '"W/cm^2/K"'), "expected an SI unit"),
    ],
)
def test_a_bad_parts_file_is_named(
    clean: None, tmp_path: Path, text: str | None, message: str
) -> None:
    path = tmp_path / "mine.py"
    if text is not None:
        path.write_text(text, encoding="utf-8")
    with pytest.raises(PneumafitInputError, match=r"option --parts '.*mine\.py'") as info:
        plugins.load_parts([str(path)])
    assert message in str(info.value)
    assert "root-p" not in parts.HEAT_LAWS


def test_the_command_line_names_a_missing_parts_file(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != plugins.ENVIRONMENT_VARIABLE}
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "--parts", str(tmp_path / "gone.py"), "--help"],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    # --help is eager: it prints before the parts load
    assert res.returncode == 0
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "--parts", str(tmp_path / "gone.py"), "check",
         str(tmp_path)],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    assert res.returncode == 2
    assert "option --parts" in res.stderr and "gone.py" in res.stderr
    assert "Traceback" not in res.stderr


@pytest.mark.slow
def test_a_heat_law_of_one_s_own_is_fitted_from_the_command_line(tmp_path: Path) -> None:
    from pneumafit.virtual_rig import VirtualRig

    path = tmp_path / "root_p.py"
    path.write_text(PARTS_FILE, encoding="utf-8")
    campaign = tmp_path / "campaign"
    VirtualRig(seed=3).write(campaign, protocol="quick")
    env = {k: v for k, v in os.environ.items() if k != plugins.ENVIRONMENT_VARIABLE}
    out = tmp_path / "fit"
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "--parts", str(path), "fit", str(campaign),
         "--model", "root-p", "--no-mcmc", "--seed", "0", "--out", str(out)],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    document = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    assert document["model"] == "root-p"
    assert document["structure"]["heat"] == "root-p"
    # without the file the command names what to do
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "fit", str(campaign), "--model", "root-p",
         "--no-mcmc", "--out", str(tmp_path / "again")],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    assert res.returncode == 2 and "--parts FILE.py" in res.stdout + res.stderr


def test_a_fit_many_task_names_a_parts_file_it_cannot_load(
    clean: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pneumafit.distributed import _fit_one

    monkeypatch.setenv(plugins.ENVIRONMENT_VARIABLE, str(tmp_path / "gone.py"))
    result = _fit_one(str(tmp_path), "convection", str(tmp_path / "out"), None, None, 0, False)
    assert result["code"] == 2 and result["fit"] is None
    assert "PNEUMAFIT_PARTS" in result["error"] and "gone.py" in result["error"]


def test_pneumafit_parts_lists_what_a_file_registered(tmp_path: Path) -> None:
    path = tmp_path / "root_p.py"
    path.write_text(PARTS_FILE, encoding="utf-8")
    env = {k: v for k, v in os.environ.items() if k != plugins.ENVIRONMENT_VARIABLE}
    env["COLUMNS"] = "250"
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "--parts", str(path), "parts"],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    rows = {line.split("│")[1].strip(): line for line in res.stdout.splitlines() if "│" in line}
    assert "its own (@njit)" in rows["root-p"] and "built in" in rows["convection"]
    assert "root_p_coefficient" in rows and "W/m^2/K" in rows["root_p_coefficient"]
    assert "slot 5" in rows["chamber_leakage"]
