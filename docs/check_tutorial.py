"""Run docs/tutorial.md and check its figures, so that they cannot drift.

The figures the tutorial quotes sit between markers::

    <!-- check:NAME -->
    ...generated text...
    <!-- /check:NAME -->

This script runs the tutorial's commands as written (in a work folder, so
that the paths they print are the tutorial's), renders every marked block
from what the commands wrote (fit.json, comparison.json, discovery.json,
truth.json), in the units and number formats the console prints, and
either compares it with the text (a unified diff for each block that
differs; exit status 1) or, with ``--update``, rewrites the blocks.

Modes:

- ``--quick`` (seconds; run by ``tests/test_tutorial.py`` in CI): every
  ``pneumafit`` command in the tutorial parses (its options exist), the CSV
  excerpt is the first lines of the practice rig's ``steps_1.csv``, the unit
  column of the parameter table is each parameter's unit as ``pneumafit fit``
  prints it, and the comparison's units are those of ``pneumafit compare``'s
  console table;
- full (default; several minutes on a 2-core machine: the rig, three fits
  without MCMC, compare, discover, export, report): also every figure
  block. Timings depend on the machine's load: ``--update`` writes them with
  the date they were measured, and the check does not compare them (it
  prints the measured ones beside the documented ones).

Usage::

    python docs/check_tutorial.py --quick
    python docs/check_tutorial.py [--work DIR] [--reuse] [--update]

``--reuse`` skips a command whose outputs already exist in ``--work`` (for
editing the text; a check that proves anything starts from an empty folder).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import difflib
import json
import re
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

DOC = Path(__file__).resolve().parent / "tutorial.md"
MARK = re.compile(r"<!-- check:(?P<name>[\w-]+) -->\n(?P<body>.*?)<!-- /check:(?P=name) -->",
                  re.S)  # fmt: skip
#: Blocks whose figures depend on the machine's load: rewritten, never compared.
TIMING_BLOCKS = ("timings",)
#: The parameters of the tutorial's table, in its order.
TABLE = ("xi", "beta", "friction_static", "friction_coulomb", "friction_viscous",
         "stribeck_velocity", "valve_C_supply", "valve_overlap")  # fmt: skip
MODELS = ("convection", "constant-lambda", "polytropic")

#: The tutorial's commands, in order: (name, command line, an output it writes).
COMMANDS = [
    ("rig", "pneumafit rig --protocol tutorial --out my_rig --seed 7", "my_rig/truth.json"),
    ("check", "pneumafit check my_rig", None),
    *((f"fit {m}",
       f"pneumafit fit my_rig --model {m} --out out/my_rig/fits/{m} --no-mcmc",
       f"out/my_rig/fits/{m}/fit.json") for m in MODELS),
    ("compare", "pneumafit compare my_rig --fits out/my_rig/fits/convection "
                "--fits out/my_rig/fits/constant-lambda --fits out/my_rig/fits/polytropic "
                "--out out/my_rig/comparison", "out/my_rig/comparison/comparison.json"),
    ("discover", "pneumafit discover my_rig --fit out/my_rig/fits/convection "
                 "--out out/my_rig/discovery", "out/my_rig/discovery/discovery.json"),
    ("export", "pneumafit export out/my_rig/fits/convection/fit.json --format c "
               "--out out/my_rig/export/controller.h", "out/my_rig/export/controller.h"),
    ("report", "pneumafit report out/my_rig --campaign my_rig", "out/my_rig/report.html"),
]  # fmt: skip


# --------------------------------------------------------------------------- the text


def blocks(text: str) -> dict[str, str]:
    """Marked blocks of the tutorial: name -> body."""
    return {m["name"]: m["body"] for m in MARK.finditer(text)}


def replace_blocks(text: str, rendered: dict[str, str]) -> str:
    def sub(m: re.Match[str]) -> str:
        body = rendered.get(m["name"], m["body"])
        return f"<!-- check:{m['name']} -->\n{body}<!-- /check:{m['name']} -->"

    return MARK.sub(sub, text)


def tutorial_commands(text: str) -> list[list[str]]:
    """Every ``pneumafit ...`` command of the tutorial's code blocks (continuations joined)."""
    commands = []
    for block in re.findall(r"```\n(.*?)```", text, re.S):
        for line in block.replace("\\\n", " ").splitlines():
            if line.strip().startswith("pneumafit "):
                commands.append(shlex.split(line.strip())[1:])
    return commands


# --------------------------------------------------------------------------- quick checks


def check_commands_parse(text: str) -> list[str]:
    """Every tutorial command names a command and options that exist."""
    import click
    import typer

    from pneumafit.cli import app

    group = typer.main.get_command(app)
    problems = []
    for args in tutorial_commands(text):
        try:
            ctx = click.Context(group, info_name="pneumafit")
            cmd = group.get_command(ctx, args[0])
            if cmd is None:
                raise click.UsageError(f"no such command {args[0]!r}")
            cmd.make_context(args[0], list(args[1:]), parent=ctx)
        except click.exceptions.ClickException as exc:
            problems.append(
                f"tutorial command 'pneumafit {shlex.join(args)}': {exc.format_message()}"
            )
    return problems


def render_csv_excerpt(work: Path) -> str:
    lines = (work / "my_rig" / "steps_1.csv").read_text().splitlines()
    return "```\n" + "\n".join(lines[:3]) + "\n```\n"


def write_rig(work: Path) -> None:
    """The practice rig, as the tutorial's first command writes it (the noise of
    each file depends on the whole protocol, so not one file alone)."""
    from pneumafit.virtual_rig import VirtualRig, tutorial_protocol

    VirtualRig(seed=7).write(work / "my_rig", tutorial_protocol())


def check_units(text: str) -> list[str]:
    """The units the tutorial's tables give are those the program prints."""
    from pneumafit.models.layout import SPECS

    problems = []
    table = blocks(text).get("fit-table", "")
    for row in table.splitlines()[2:]:
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) < 4:
            continue
        name = cells[0].strip("`")
        if name not in SPECS:
            problems.append(f"fit-table: {name!r} is not a model parameter")
        elif cells[3] != (printed := SPECS[name].unit or "-"):
            problems.append(
                f"fit-table: {name}: unit {cells[3]!r}, pneumafit fit prints {printed!r}"
            )
    units = blocks(text).get("compare-units", "")
    expected = render_compare_units()
    if units != expected:
        problems.append(f"compare-units: {units!r}, pneumafit compare prints {expected!r}")
    return problems


def render_compare_units() -> str:
    from pneumafit.campaign.units import display_unit

    return (f"Held-out RMSE on the practice campaign, as `pneumafit compare` prints it "
            f"(pressures in {display_unit('p_P')[1]}, position in {display_unit('y')[1]}, "
            f"temperatures in {display_unit('T_P')[1]} through each fit's probe; the best in "
            f"bold, starred on the console):\n")  # fmt: skip


# --------------------------------------------------------------------------- full run


def run_commands(work: Path, reuse: bool, say: Callable[[str], None]) -> dict[str, float]:
    """Run the tutorial's commands in ``work``: wall seconds by command (kept in
    ``work/seconds.json``, so that a ``--reuse`` run still knows them)."""
    record = work / "seconds.json"
    seconds = json.loads(record.read_text()) if reuse and record.exists() else {}
    for name, line, output in COMMANDS:
        if reuse and output and (work / output).exists():
            say(f"{name}: reused {output}")
            continue
        t0 = time.perf_counter()
        argv = [sys.executable, "-m", "pneumafit", *shlex.split(line)[1:]]
        res = subprocess.run(argv, cwd=work, capture_output=True, text=True)
        seconds[name] = time.perf_counter() - t0
        (work / f"{name.replace(' ', '_')}.log").write_text(res.stdout + res.stderr)
        record.write_text(json.dumps(seconds, indent=1))
        say(f"{name}: exit {res.returncode}, {seconds[name]:.0f} s")
        if res.returncode != 0:
            raise SystemExit(f"tutorial command failed: {line}\n{res.stdout[-3000:]}"
                             f"{res.stderr[-3000:]}")  # fmt: skip
    return seconds


def _g(x: float | None, digits: int) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def render_full(work: Path, seconds: dict[str, float]) -> dict[str, str]:
    """Every figure block, from the files the commands wrote."""
    from pneumafit.campaign.units import display_unit
    from pneumafit.comparison.report import CHANNEL_ORDER

    out = work / "out" / "my_rig"
    fits = {m: json.loads((out / "fits" / m / "fit.json").read_text()) for m in MODELS}
    truth = json.loads((work / "my_rig" / "truth.json").read_text())["parameters"]
    conv = fits["convection"]
    rendered: dict[str, str] = {"csv-excerpt": render_csv_excerpt(work)}
    rows = ["| parameter | value | 90 % interval | unit | truth |",
            "|---|---:|---|---|---:|"]  # fmt: skip
    errors, missed = {}, []
    for name in TABLE:
        p = conv["parameters"][name]
        lo, hi = p["interval_90"]
        rows.append(f"| `{name}` | {_g(p['value'], 7)} | [{_g(lo, 7)}, {_g(hi, 7)}] | "
                    f"{p['unit'] or '-'} | {_g(truth[name], 7)} |")  # fmt: skip
        errors[name] = abs(p["value"] / truth[name] - 1.0)
        if not lo <= truth[name] <= hi:
            missed.append(name)
    rendered["fit-table"] = "\n".join(rows) + "\n"
    worst = max(errors, key=errors.get)
    inside = len(TABLE) - len(missed)
    rendered["fit-accuracy"] = (
        f"Every estimate is within {100 * errors[worst]:.2g} % of the truth (the largest "
        f"error: `{worst}`); the 90 % intervals (Laplace, `--no-mcmc`) contain the truth for "
        f"{inside} of the {len(TABLE)} parameters"
        + (f" (not for {', '.join(f'`{n}`' for n in missed)})" if missed else "") + ".\n"
    )  # fmt: skip
    quality = conv["quality"]
    rendered["fit-verdict"] = (
        f"The summary starts with the verdict, here `{quality['verdict']}`"
        + (": " + "; ".join(quality["problems"]) if quality["problems"] else "") + ".\n"
    )  # fmt: skip
    comparison = json.loads((out / "comparison" / "comparison.json").read_text())
    best = comparison["best"]["validate"]
    rows = ["| channel | unit | " + " | ".join(MODELS) + " |",
            "|---|---|" + "---:|" * len(MODELS)]  # fmt: skip
    for channel in CHANNEL_ORDER:
        if channel not in best:
            continue
        scale, unit = display_unit(channel)
        cells = []
        for m in MODELS:
            v = comparison[m]["rmse"]["validate"].get(channel)
            text = _g(None if v is None else v * scale, 4)
            cells.append(f"**{text}**" if best[channel] == m else text)
        rows.append(f"| `{channel}` | {unit} | " + " | ".join(cells) + " |")
    rendered["compare-table"] = "\n".join(rows) + "\n"
    rendered["compare-units"] = render_compare_units()
    discovery = json.loads((out / "discovery" / "discovery.json").read_text())
    rendered["discovery-statement"] = f'"{discovery["statement"]}"\n'
    day = _dt.date.today().isoformat()
    fit_s = {m: fits[m]["provenance"]["seconds"] for m in MODELS}
    rendered["timings"] = (
        f"Measured on {day} on this project's 2-core machine (other jobs sharing it, so "
        f"expect other times; `--update` of `docs/check_tutorial.py` rewrites this line): "
        f"the fits without MCMC took {fit_s['convection']:.0f} s (convection), "
        f"{fit_s['constant-lambda']:.0f} s (constant-lambda) and "
        f"{fit_s['polytropic']:.0f} s (polytropic), as their `fit.json` "
        f"(`provenance.seconds`) records"
        + (f"; the comparison {seconds['compare']:.0f} s and the discovery "
           f"{seconds['discover']:.0f} s" if "compare" in seconds and "discover" in seconds
           else "")
        + (f"; every command of this page, from the rig to the report, "
           f"{sum(seconds.values()) / 60:.0f} min" if len(seconds) == len(COMMANDS) else "")
        + ".\n"
    )  # fmt: skip
    return rendered


# --------------------------------------------------------------------------- main


def diff(name: str, documented: str, produced: str) -> str:
    return "".join(difflib.unified_diff(
        documented.splitlines(True), produced.splitlines(True),
        f"tutorial.md ({name}, documented)", f"{name} (produced)",
    ))  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="options, units and the CSV only")
    parser.add_argument("--update", action="store_true", help="rewrite the marked blocks")
    parser.add_argument("--work", type=Path, help="work folder (default: a temporary one)")
    parser.add_argument("--reuse", action="store_true", help="keep outputs found in --work")
    parser.add_argument("--doc", type=Path, default=DOC, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    text = args.doc.read_text()
    documented = blocks(text)
    problems = check_commands_parse(text)
    with tempfile.TemporaryDirectory() as tmp:
        work = (args.work or Path(tmp)).resolve()
        work.mkdir(parents=True, exist_ok=True)
        if args.quick:
            write_rig(work)
            produced = {"csv-excerpt": render_csv_excerpt(work)}
        else:
            seconds = run_commands(work, args.reuse, lambda s: print(s, flush=True))
            produced = render_full(work, seconds)
    if not args.update:
        problems += check_units(text)
    for name, body in produced.items():
        if name not in documented:
            problems.append(f"tutorial.md has no block <!-- check:{name} -->")
        elif name in TIMING_BLOCKS and not args.update:
            print(f"{name} (not compared, depends on the load):\n  documented: "
                  f"{documented[name].strip()}\n  measured:   {body.strip()}")  # fmt: skip
        elif body != documented[name] and not args.update:
            problems.append(diff(name, documented[name], body))
    if args.update:
        args.doc.write_text(replace_blocks(text, produced))
        problems += check_units(args.doc.read_text())
        print(f"rewrote {len(produced)} blocks of {args.doc}")
    for p in problems:
        print(p, file=sys.stderr)
    checked = "quick" if args.quick else "full"
    print(f"tutorial check ({checked}): {len(problems)} problem(s), {len(produced)} blocks")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
