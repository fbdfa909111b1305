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


def test_version_does_not_load_the_models() -> None:
    """``--version`` is answered before the app is imported: neither numba nor
    the model registry (which the app's choices come from) is loaded, so it
    costs what the interpreter's start costs (it took 1.4 s with them)."""
    code = (
        "import sys; sys.argv = ['pneumafit', '--version']\n"
        "from pneumafit.__main__ import main\n"
        "main()\n"
        "print(sorted(m for m in ('numba', 'pneumafit.models', 'pneumafit.cli.app') "
        "if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "[]"
