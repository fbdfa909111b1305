"""The command line's shared option reporting, output-path check and log console."""

from __future__ import annotations

import io
import logging
import sys
from pathlib import Path

import pytest
from rich.console import Console
from rich.table import Table

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.cli.console import (
    LOG_RULE_WIDTH,
    LogConsole,
    ShownWarnings,
    configure_output,
    folder_problem,
    int_problem,
    release_output,
    report_problems,
)
from pneumafit.fileio import check_output, output_problem


def test_every_problem_is_one_line_and_none_is_skipped(tmp_path: Path) -> None:
    console = Console(file=io.StringIO(), width=200, color_system=None)
    a_file = tmp_path / "fit.json"
    a_file.write_text("{}")
    problems = [None, folder_problem(a_file), "option --seed: expected an integer >= 0, found -1"]
    assert report_problems(console, problems)
    lines = console.file.getvalue().splitlines()
    assert lines == [
        f"cannot write {a_file}: option --out expected a folder, found a file; give a new or "
        "existing folder, or move the file away",
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


def test_output_paths_of_the_wrong_kind_or_under_a_file(tmp_path: Path) -> None:
    a_file, a_folder = tmp_path / "a.json", tmp_path / "folder"
    a_file.write_text("{}")
    a_folder.mkdir()
    assert output_problem(a_file, "folder") == (
        f"cannot write {a_file}: option --out expected a folder, found a file; give a new or "
        "existing folder, or move the file away"
    )
    assert output_problem(a_folder, "file", "--html") == (
        f"cannot write {a_folder}: option --html expected a file name, found a folder; give a "
        f"file path (for example {a_folder / 'NAME'})"
    )
    for kind in ("file", "folder"):
        under = a_file / "sub" / "out"
        assert output_problem(under, kind) == (
            f"cannot write {under}: {a_file} is a file, so no folder can be created under it; "
            "choose another --out"
        )
    with pytest.raises(PneumafitInputError, match=r"cannot write .*expected a folder"):
        check_output(a_file, "folder")


def test_missing_parents_are_created_later_not_a_problem(tmp_path: Path) -> None:
    """Missing parent folders are no problem for files and folders alike (they
    are created when writing, as mkdir -p); the check itself creates nothing."""
    (tmp_path / "old.h5").write_text("x")
    assert output_problem(tmp_path / "new" / "deeper" / "x.h5", "file") is None
    assert output_problem(tmp_path / "new" / "deeper", "folder") is None
    assert output_problem(tmp_path / "old.h5", "file") is None  # replaced when written
    assert output_problem(tmp_path, "folder") is None
    assert output_problem("relative-out", "folder") is None  # under the working folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.h5"]


def test_a_folder_without_write_permission(tmp_path: Path, monkeypatch) -> None:
    """Permission is asked of the nearest existing folder (os.access, write and
    search). Tests run as root, which passes every permission check, so the
    refusal is simulated here; tests/test_cli.py checks a real read-only
    folder when not root, and the probe below a folder that refuses even root."""
    import os

    locked = tmp_path / "locked"
    locked.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == locked else real(p, mode))
    for target, kind in ((locked / "a" / "b", "folder"), (locked, "folder"),
                         (locked / "x.h5", "file")):  # fmt: skip
        assert output_problem(target, kind) == (
            f"cannot write {target}: permission denied in {locked}; choose another --out or "
            "make that folder writable"
        )
    assert output_problem(tmp_path / "free", "folder") is None


def test_the_log_console_prints_tables_in_full() -> None:
    """A table wider than any terminal is printed whole (no ellipsis, no
    wrapped cell) when the output is not a terminal; rules stay short."""
    console = LogConsole(file=io.StringIO(), color_system=None)
    table = Table(title="wide")
    for i in range(12):
        table.add_column(f"column {i}", no_wrap=True)
    table.add_row(*(f"value_{i}_" + "x" * 30 for i in range(12)))
    console.print(table)
    console.rule("stage")
    lines = console.file.getvalue().splitlines()
    assert "…" not in console.file.getvalue()
    assert all(f"value_{i}_" + "x" * 30 in lines[4] for i in range(12))
    assert len(lines[-1]) == LOG_RULE_WIDTH and "stage" in lines[-1]


def test_quiet_holds_the_output_back_and_shows_it_on_failure(capsys) -> None:
    logger = logging.getLogger("pneumafit.test")
    console = Console(file=sys.stdout, color_system=None)
    configure_output(console, quiet=True, verbose=False)
    console.print("progress")
    logger.info("an info record")
    logger.warning("a warning record")
    release_output(console, failed=False)
    captured = capsys.readouterr()
    assert captured.out == "" and "progress" not in captured.err
    assert "WARNING pneumafit.test: a warning record" in captured.err
    assert "info record" not in captured.err
    tty = Console(file=sys.stdout, force_terminal=True)
    configure_output(tty, quiet=True, verbose=False)
    assert not tty.is_terminal  # no progress bars while quiet
    tty.print("why it failed")
    release_output(tty, failed=True)
    assert tty.is_terminal
    captured = capsys.readouterr()
    assert captured.out == "" and "why it failed" in captured.err
    configure_output(console, quiet=False, verbose=True)
    logger.debug("a debug record")
    console.print("shown")
    assert "DEBUG pneumafit.test: a debug record" in capsys.readouterr().err
    configure_output(console, quiet=False, verbose=False)
    with pytest.raises(PneumafitInputError, match="--quiet and --verbose"):
        configure_output(console, quiet=True, verbose=True)


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_a_folder_that_refuses_even_root_is_found_by_the_probe() -> None:
    """/proc passes os.access for root but creates no folder: the probe says so."""
    problem = output_problem("/proc/pneumafit-out", "folder")
    assert problem is not None and problem.startswith("cannot write /proc/pneumafit-out: ")
    assert "/proc refuses new files (" in problem and "choose another --out" in problem


def test_a_warning_already_shown_is_counted_not_repeated() -> None:
    """``pneumafit run``'s three fits judge one campaign: its warnings are
    printed by the first fit, and a later fit's repeats become one count
    line, printed before the next other line."""
    lines: list[str] = []
    memo = ShownWarnings()
    say = memo.log(lines.append)
    for line in ("warning: a", "warning: b", "valve: 1.5 s", "warning: a", "warning: b",
                 "warning: c", "warning: a", "heat: 2.0 s"):  # fmt: skip
        say(line)
    assert lines == [
        "warning: a", "warning: b", "valve: 1.5 s",
        "(2 warnings as printed above, not repeated)", "warning: c",
        "(1 warning as printed above, not repeated)", "heat: 2.0 s",
    ]  # fmt: skip
    memo.flush(lines.append)  # nothing held: nothing printed
    assert len(lines) == 7
