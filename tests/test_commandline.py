"""The command line's shared option reporting."""

from __future__ import annotations

import io
from pathlib import Path

from rich.console import Console

from pneumafit.commandline import folder_problem, int_problem, report_problems


def test_every_problem_is_one_line_and_none_is_skipped(tmp_path: Path) -> None:
    console = Console(file=io.StringIO(), width=200, color_system=None)
    a_file = tmp_path / "fit.json"
    a_file.write_text("{}")
    problems = [None, folder_problem(a_file), "option --seed: expected an integer >= 0, found -1"]
    assert report_problems(console, problems)
    lines = console.file.getvalue().splitlines()
    assert lines == [
        f"option --out {str(a_file)!r}: expected a folder, found a file",
        "option --seed: expected an integer >= 0, found -1",
    ]
    assert folder_problem(tmp_path) is None and folder_problem(tmp_path / "new") is None
    assert not report_problems(console, [None, None])


def test_integer_options_are_checked_and_defaults_pass() -> None:
    assert int_problem("--steps", None, 1) is None
    assert int_problem("--steps", 1, 1) is None
    for bad in (0, True, 2.0, "3"):
        assert int_problem("--steps", bad, 1) == (
            f"option --steps: expected an integer >= 1, found {bad!r}"
        )
