"""The command line as a user runs it: exit status, messages, no tracebacks."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneumafit.campaign import read_recording

DEMO = Path(__file__).resolve().parents[1] / "data" / "demo"


def cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pneumafit", *args],
        capture_output=True, text=True, cwd=cwd, timeout=600,
    )  # fmt: skip


@pytest.fixture
def params_file(tmp_path: Path) -> Path:
    path = tmp_path / "params.json"
    path.write_text(json.dumps({"model": "convection", "parameters": {
        "bore": "32 mm", "rod": "20 mm", "supply_pressure": "7 bar", "xi": 0.4}}))  # fmt: skip
    return path


def test_simulate_charge_writes_a_campaign_recording(tmp_path, params_file):
    out = tmp_path / "charge.h5"
    res = cli("simulate", str(params_file), "--kind", "charge", "--chamber", "N",
              "--position", "100 mm", "--duration", "2 s", "--out", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "exergy" in res.stdout and "mass drawn from supply" in res.stdout
    rec = read_recording(out, kind="charge", chamber="N", piston_position=0.1)
    assert rec.n_samples == 2001
    assert rec.channels["p_N"][0] == pytest.approx(1.013e5)
    assert rec.channels["p_N"].max() > 6e5  # filled towards the 7 bar supply
    assert np.all(rec.channels["y"] == pytest.approx(0.1))


def test_simulate_step(tmp_path, params_file):
    out = tmp_path / "step.h5"
    res = cli("simulate", str(params_file), "--kind", "step", "--y-ref", "300 mm",
              "--duration", "2 s", "--out", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    rec = read_recording(out, kind="step")
    assert abs(rec.channels["y"][-1] - 0.30) < 0.01  # reached the reference


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--kind", "jump"], "--kind"),
        (["--kind", "step", "--y-ref", "3 bar"], "--y-ref"),
        (["--kind", "charge", "--chamber", "Q"], "--chamber"),
        (["--kind", "charge", "--rate", "0 Hz"], "--rate"),
        (["--kind", "charge", "--model", "isothermal"], "--model"),
        (["--kind", "charge", "--position", "900 mm"], "--position"),
    ],
)
def test_simulate_bad_options_are_messages(tmp_path, params_file, args, needle):
    res = cli("simulate", str(params_file), "--out", str(tmp_path / "x.h5"), *args)
    assert res.returncode == 2
    assert needle in res.stderr and "Traceback" not in res.stderr + res.stdout
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("{not json", "line 1"),
        ('{"parameters": {"bore": "6 bar"}}', "parameters.bore"),
        ('{"parameters": {"bogus": 1}}', "bogus"),
        ('{"model": "isothermal"}', "model"),
    ],
)
def test_bad_parameter_files_are_messages(tmp_path, content, needle):
    path = tmp_path / "p.json"
    path.write_text(content)
    res = cli("simulate", str(path), "--kind", "charge", "--out", str(tmp_path / "x.h5"))
    assert res.returncode == 2
    assert needle in res.stderr and "p.json" in res.stderr
    assert "Traceback" not in res.stderr + res.stdout


def test_check_demo_is_clean_and_bad_campaign_fails(tmp_path):
    res = cli("check", str(DEMO))
    assert res.returncode == 0, res.stdout
    assert "valid campaign: 0 errors" in res.stdout
    res = cli("check", str(tmp_path))
    assert res.returncode == 1
    assert "campaign.toml" in res.stdout + res.stderr
    assert "Traceback" not in res.stdout + res.stderr


def test_rig_quick_campaign_and_bad_effect(tmp_path):
    out = tmp_path / "camp"
    res = cli("rig", "--out", str(out), "--protocol", "quick", "--seed", "5")
    assert res.returncode == 0, res.stdout + res.stderr
    assert (out / "campaign.toml").exists() and (out / "truth.json").exists()
    res = cli("check", str(out))
    assert res.returncode == 0
    # stdout is a pipe (as in a log or CI): the table is printed whole, each
    # row on one line (at 200 columns the step test's channels were wrapped)
    row = next(line for line in res.stdout.splitlines() if "step_1.csv" in line)
    assert "T_N [degC]" in row and "umax=10 V" in row and "…" not in res.stdout
    res = cli("rig", "--out", str(tmp_path / "b"), "--protocol", "quick", "--effect", "warp=1")
    assert res.returncode == 2
    assert "warp" in res.stdout + res.stderr and "Traceback" not in res.stdout + res.stderr


def test_run_on_a_missing_campaign_is_a_message(tmp_path):
    """The main job end to end is tests/test_pipeline.py (the demo with MCMC
    takes minutes); here only its command-line contract."""
    res = cli("run", str(tmp_path / "nowhere"), "--out", str(tmp_path / "run"))
    assert res.returncode == 2
    assert "nowhere" in res.stdout + res.stderr
    assert "Traceback" not in res.stdout + res.stderr
    assert not (tmp_path / "run" / "fits").exists()


@pytest.mark.parametrize(
    ("option", "value", "allowed"),
    [("--valve", "linear", ("iso6358", "map")), ("--inputs", "zoh", ("hold", "linear"))],
)
def test_run_refuses_an_unknown_law_before_fitting(tmp_path, option, value, allowed):
    """``pneumafit run --valve`` and ``--inputs`` take the fit command's
    values; another value is bad input (exit 2) naming the option, the
    allowed values and the value, and nothing is fitted."""
    res = cli("run", str(DEMO), "--no-mcmc", option, value, "--out", str(tmp_path / "run"))
    text = res.stdout + res.stderr
    assert res.returncode == 2
    assert option in text and value in text and all(a in text for a in allowed)
    assert "Traceback" not in text
    assert not (tmp_path / "run" / "fits").exists()


def test_linear_and_export_use_a_fitted_valve_map(tmp_path):
    """A fit of the measured valve map (fit.json ``structure.valve = "map"``)
    is analysed and exported with its map: here a map whose supply knots are
    three times those of the ISO valve it was sampled from, so that the map's
    equilibrium differs from the ISO parameters' (by 12 % in P_P)."""
    from pneumafit.analysis import equilibrium
    from pneumafit.models.parameters import parameter_dict, parameter_vector
    from pneumafit.physics.valve_map import MAP_CS_NAMES, map_from_iso

    base = parameter_dict(parameter_vector({}))
    knots = map_from_iso(base)
    knots.update({k: 3.0 * knots[k] for k in MAP_CS_NAMES[7:]})
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps({"model": "convection", "structure": {"valve": "map"},
                               "parameters": knots}))  # fmt: skip
    out = tmp_path / "lin"
    res = cli("linear", str(fit), "--positions", "250 mm", "--out", str(out))
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "linear.json").read_text())
    expected = equilibrium(parameter_vector(knots), 0.25, valve="map")
    assert doc["valve"] == "map"
    assert doc["positions"][0]["equilibrium"]["p_P"] == pytest.approx(expected.p_P, rel=1e-9)
    assert expected.p_P > 1.05 * equilibrium(parameter_vector({}), 0.25).p_P
    res = cli("export", str(fit), "--format", "json", "--out", str(tmp_path / "x.json"))
    assert res.returncode == 0, res.stderr
    exported = json.loads((tmp_path / "x.json").read_text())
    assert exported["source"]["valve"] == "map"
    assert exported["parameters"][MAP_CS_NAMES[10]]["value"] == pytest.approx(
        knots[MAP_CS_NAMES[10]]
    )


@pytest.mark.parametrize("args", [[], ["bogus"], ["simulate"], ["rig"]])
def test_usage_errors_have_no_traceback(args):
    res = cli(*args)
    assert res.returncode == 2
    assert "Traceback" not in res.stdout + res.stderr


def test_linear_and_design_commands(tmp_path, params_file):
    out = tmp_path / "lin"
    res = cli("linear", str(params_file), "--positions", "50,250,450 mm", "--out", str(out))
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "linear.json").read_text())
    assert [round(e["y"], 3) for e in doc["positions"]] == [0.05, 0.25, 0.45]
    assert len(doc["positions"][1]["order_6"]["A"]) == 6
    assert (out / "open_loop_poles.png").stat().st_size > 10_000
    res = cli("design", str(params_file), "--order", "4", "--w0", "15", "--out", str(out))
    assert res.returncode == 0, res.stderr
    design = json.loads((out / "design_4.json").read_text())
    assert len(design["schedule"]) == 25 and all(e["K"] for e in design["schedule"])
    res = cli("design", str(params_file), "--order", "5", "--out", str(out))
    assert res.returncode == 2 and "--order" in res.stderr
    res = cli("linear", str(params_file), "--positions", "0.9", "--out", str(out))
    assert res.returncode == 2 and "--positions" in res.stderr


# ------------------------------------------------------ output paths (issue 17)
#: Every command that writes: (arguments before --out, whether --out is a file
#: or a folder). Each fails on --out before any heavy work.
WRITERS = {
    "run": (lambda d: [str(DEMO)], "folder"),
    "fit": (lambda d: [str(DEMO), "--no-mcmc"], "folder"),
    "compare": (lambda d: [str(DEMO), "--no-mcmc"], "folder"),
    "fit-many": (lambda d: [str(DEMO), "--no-mcmc"], "folder"),
    "discover": (lambda d: [str(DEMO), "--fit", str(d / "params.json")], "folder"),
    "report": (lambda d: [str(d)], "file"),
    "rig": (lambda d: ["--protocol", "quick"], "folder"),
    "simulate": (lambda d: [str(d / "params.json"), "--kind", "charge"], "file"),
    "linear": (lambda d: [str(d / "params.json")], "folder"),
    "export": (lambda d: [str(d / "params.json"), "--format", "json"], "file"),
    "design": (lambda d: [str(d / "params.json")], "folder"),
    "closed-loop": (lambda d: [str(d / "params.json")], "folder"),
}


def run_main(args: list[str], monkeypatch, capsys) -> tuple[int, str]:
    """``pneumafit ARGS`` in this process (fast: the imports are paid once):
    (exit status, stdout + stderr)."""
    from pneumafit import cli as cli_module

    monkeypatch.setattr(sys, "argv", ["pneumafit", *args])
    with pytest.raises(SystemExit) as stopped:
        cli_module.main()
    captured = capsys.readouterr()
    code = stopped.value.code
    return (0 if code is None else code), captured.out + captured.err


def _files(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("case", ["wrong kind", "under a file", "not writable"])
@pytest.mark.parametrize("command", list(WRITERS))
def test_every_writing_command_checks_its_output_path(
    tmp_path, params_file, monkeypatch, capsys, command, case
):
    """Exit 2 and "cannot write PATH" before any work: nothing created, no
    traceback, never "internal error". The refused permission is simulated
    (tests run as root, which passes every permission check); a real
    read-only folder is the next test's."""
    from pneumafit import fileio

    arguments, kind = WRITERS[command]
    (tmp_path / "a_file").write_text("x")
    (tmp_path / "a_folder").mkdir()
    (tmp_path / "locked").mkdir()
    if case == "wrong kind":
        out = tmp_path / ("a_folder" if kind == "file" else "a_file")
    elif case == "under a file":
        out = tmp_path / "a_file" / "sub" / ("out.h5" if kind == "file" else "out")
    else:
        out = tmp_path / "locked" / "sub" / ("out.h5" if kind == "file" else "out")
        locked = tmp_path / "locked"
        refuse = lambda d: "permission denied" if d == locked else None  # noqa: E731
        monkeypatch.setattr(fileio, "_refusal", refuse)
    before = _files(tmp_path)
    code, text = run_main([command, *arguments(tmp_path), "--out", str(out)], monkeypatch, capsys)
    assert code == 2, text
    assert f"cannot write {out}" in text
    assert "Traceback" not in text and "internal error" not in text
    assert _files(tmp_path) == before


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() == 0,
    reason="root passes every permission check: a chmod 0o555 folder stays writable",
)
@pytest.mark.parametrize("command", ["linear", "simulate", "report"])
def test_a_real_read_only_folder(tmp_path, params_file, monkeypatch, capsys, command):
    arguments, kind = WRITERS[command]
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        out = locked / ("x.h5" if kind == "file" else "out")
        code, text = run_main([command, *arguments(tmp_path), "--out", str(out)], monkeypatch,
                              capsys)  # fmt: skip
        assert code == 2 and f"cannot write {out}: permission denied" in text
    finally:
        locked.chmod(0o755)


@pytest.mark.parametrize("command", [*WRITERS, "check"])
def test_every_command_takes_quiet_and_verbose(command):
    from typer.testing import CliRunner

    from pneumafit.cli import app

    res = CliRunner().invoke(app, [command, "--help"], terminal_width=200)
    assert res.exit_code == 0
    assert "--quiet" in res.output and "--verbose" in res.output


def test_quiet_verbose_and_exit_statuses_on_a_real_command(tmp_path, params_file):
    """--quiet: nothing on stdout when it works, the reason on stderr when it
    fails; --verbose: debug records on stderr; the exit statuses in --help."""
    out = tmp_path / "lin"
    res = cli("linear", str(params_file), "--positions", "250 mm", "--out", str(out), "--quiet")
    assert res.returncode == 0 and res.stdout == "" and res.stderr == ""
    assert (out / "linear.json").is_file()
    res = cli("linear", str(params_file), "--positions", "250 mm", "--out", str(out), "-v")
    assert res.returncode == 0 and "wrote" in res.stdout
    assert "DEBUG pneumafit: pneumafit linear" in res.stderr and "exit status 0" in res.stderr
    res = cli("check", str(tmp_path), "--quiet")
    assert res.returncode == 1 and res.stdout == "" and "campaign.toml" in res.stderr
    res = cli("check", str(tmp_path), "--quiet", "--verbose")
    assert res.returncode == 2 and "--quiet and --verbose" in res.stderr
    res = cli("--help")
    assert res.returncode == 0
    for status in ("0 done", "2 bad input", "3 an untrustworthy result", "130 interrupted"):
        assert status in " ".join(res.stdout.split())


# ------------------------------------------------------------ report (issue 17)
def _fake_fit(run: Path, model: str, campaign: dict) -> None:
    """A fit.json as far as the report's checks read it (they run before any
    simulation)."""
    folder = run / "fits" / model
    folder.mkdir(parents=True)
    doc = {"format": "pneumafit-fit", "model": model, "parameters": {}, "campaign": campaign}
    (folder / "fit.json").write_text(json.dumps(doc))


def test_report_of_another_campaign_or_of_nothing_is_bad_input(tmp_path):
    """A run folder whose fits were made from another campaign than
    --campaign, and a folder without any result, exit 2 with the reason and
    write nothing; --allow-partial writes the empty folder's report."""
    run = tmp_path / "run"
    _fake_fit(run, "convection", {"name": "other", "path": str(tmp_path / "gone"),
                                   "sha256": {"step_1.h5": "0" * 64}})  # fmt: skip
    res = cli("report", str(run), "--campaign", str(DEMO))
    assert res.returncode == 2, res.stdout + res.stderr
    message = " ".join(res.stderr.split())
    assert "fits/convection/fit.json was made from campaign 'other'" in message
    assert "--allow-partial" in message and "Traceback" not in res.stderr
    # the campaign the fit recorded is gone and none was given: missing input
    res = cli("report", str(run))
    assert res.returncode == 2 and "gone" in res.stderr
    assert not (run / "report.html").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    res = cli("report", str(empty))
    assert res.returncode == 2 and "found none of" in " ".join(res.stderr.split())
    assert _files(empty) == []
    res = cli("report", str(empty), "--allow-partial", "--quiet")
    assert res.returncode == 0, res.stderr
    assert (empty / "report.html").is_file()


def test_an_interrupt_exits_130_with_a_word(tmp_path, params_file, monkeypatch, capsys):
    """typer turns Ctrl-C into exit status 130 silently; every command says it."""
    from pneumafit.outputs import linear_report

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(linear_report, "write_linear", interrupted)
    code, text = run_main(["linear", str(params_file), "--out", str(tmp_path / "lin")],
                          monkeypatch, capsys)  # fmt: skip
    assert code == 130 and "interrupted" in text and "Traceback" not in text


def test_a_bug_is_an_internal_error_not_bad_input(tmp_path, params_file, monkeypatch, capsys):
    """A ValueError that is not a PneumafitInputError is a bug (numpy's
    broadcasting errors are ValueErrors too): exit 1, "internal error" and
    how to report it; PNEUMAFIT_DEBUG=1 gives the traceback."""
    from pneumafit.outputs import linear_report

    def broken(*args, **kwargs):
        raise ValueError("operands could not be broadcast together with shapes (3,) (4,)")

    monkeypatch.setattr(linear_report, "write_linear", broken)
    args = ["linear", str(params_file), "--out", str(tmp_path / "lin")]
    code, text = run_main(args, monkeypatch, capsys)
    assert code == 1 and "internal error: ValueError: operands" in text
    assert "please report it" in text and "PNEUMAFIT_DEBUG=1" in text
    monkeypatch.setenv("PNEUMAFIT_DEBUG", "1")
    monkeypatch.setattr(sys, "argv", ["pneumafit", *args])
    from pneumafit import cli as cli_module

    with pytest.raises(ValueError, match="operands"):
        cli_module.main()


def test_a_refusal_while_writing_is_bad_input(tmp_path, params_file, monkeypatch, capsys):
    """Permissions or a full disk found only while writing (after the check):
    exit 2 naming the file, not "internal error"."""
    import errno

    from pneumafit.outputs import linear_report

    target = str(tmp_path / "lin" / "linear.json")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", target)

    monkeypatch.setattr(linear_report, "write_linear", full)
    code, text = run_main(["linear", str(params_file), "--out", str(tmp_path / "lin")],
                          monkeypatch, capsys)  # fmt: skip
    assert code == 2 and f"cannot write or read {target}: No space left" in " ".join(text.split())
    assert "internal error" not in text
