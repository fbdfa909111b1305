"""``python -m pneumafit`` is the same command line as the ``pneumafit`` script."""

from __future__ import annotations

import subprocess
import sys


def test_python_dash_m_runs_the_command_line() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "pneumafit", "--help"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert "fit" in done.stdout and "run" in done.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "pneumafit", "linear", "/nonexistent/params.json", "--out", "x"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert bad.returncode == 2 and "Traceback" not in bad.stderr + bad.stdout


def test_version_prints_the_installed_version() -> None:
    from pneumafit import __version__

    done = subprocess.run(
        [sys.executable, "-m", "pneumafit", "--version"], capture_output=True, text=True,
        timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"pneumafit {__version__}"
