"""Recovery on mismatched truths: fit campaigns whose truth the model does not share.

Each case records a campaign on the virtual rig with an independently
written truth simulator (``pneumafit.virtual_rig.truth``: its own valve, friction,
leak, heat-area and sensor laws, a finer solver, sensor noise), fits the
convection model to it as a user would (``identify``, no MCMC by default)
and reports:

- per recording and channel, the residual RMS over the sensor noise (fit and
  held-out recordings; the fit's own quality check);
- lambda at the reference state (5 bar, 50 degC gas, 20 degC wall; fit and
  truth by their full-area equivalents at mid-stroke, lambda A_P / A_P,full,
  whatever walls each counts), the static friction and the Coulomb friction
  (both sides' steady sliding friction at 50 mm/s less its viscous part,
  the truth's definition), against the truth's figures, and whether
  the 90 % intervals contain them;
- estimates outside their own interval, estimates at a bound;
- the held-out figure once more, with each closed-loop step test whose
  misfit at rest the verdict explains by where its piston rests replayed
  with the recorded commands instead of the model's controller
  (``quality.recorded_commands``): not a target, the share of the held-out
  misfit that is the loop's answer to the stop.

Prints one JSON line (the targets of the robust-identification issue as
booleans) and, with ``--table FILE``, writes the case x figure table in
Markdown.

    python benchmarks/bench_recovery.py [--seeds 1 2 3] [--cases NAME ...]
           [--valve iso6358|map] [--friction auto|switch|lugre] [--mcmc] [--no-robust]
           [--offset-scope sensor|recording]
           [--table docs/recovery-table.md]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from pneumafit.campaign import read_campaign
from pneumafit.identification import FitOptions, identify
from pneumafit.identification.problem import OFFSET_SCOPE, OFFSET_SCOPES
from pneumafit.identification.segments import SEGMENT_MODES
from pneumafit.models.structure import INPUT_MODE, INPUT_MODES
from pneumafit.virtual_rig import VirtualRig, get_protocol

#: (truth preset, protocol) pairs of the matrix.
#: Every case fits step tests (the friction figures need them), so the quick
#: protocol (its step test is held out) is not used; ``fit-laws`` is the
#: control: the truth simulator with the fitted laws, which must reach the noise.
CASES: tuple[tuple[str, str], ...] = (
    ("fit-laws", "sparse"),
    ("power-valve", "sparse"),
    ("table-valve-asym", "sparse"),
    ("lugre-pressure", "sparse"),
    ("dahl-bump-leak", "sparse"),
    ("mixed", "sparse"),
    ("mixed", "demo"),
    ("demo-clean", "demo"),
    ("demo", "demo"),
    ("novel", "sparse-long"),
)
#: Truths outside the rig's presets, by case name: written apart from the
#: presets the matrix was tuned on, as the team's hidden campaigns are
#: (docs/identification.md, "Which part of the novel truth costs what").
TRUTH_FILES: dict[str, Path] = {"novel": Path(__file__).parent / "truths" / "novel.toml"}
#: The control case: truth laws the fit shares (not counted in the targets).
CONTROL = "fit-laws"
#: The bundled demo's truth: ``demo-clean`` plus an external leak that its
#: campaign does not declare (docs/effects.md). The fitted models have no
#: such leak, so their residual cannot reach the noise there: that is
#: discovery's case (``pneumafit discover``), reported here but not counted
#: in the targets of the fit, which ``demo-clean`` measures on the same rig.
UNDECLARED = "demo"
#: Targets of the issue.
RATIO_TARGET = 3.0
REL_TARGET = 0.25
COVERAGE_TARGET = 0.80
#: The fitted parameters behind each compared figure (a figure counts as
#: resting on one recording when any of them does, quality.one_recording).
FIGURE_PARAMETERS = {
    "lambda_reference": ("xi", "beta", "lambda", "heat_area_ends"),
    "friction_static": ("friction_static",),
    "friction_coulomb": ("friction_coulomb",),
}


def _interval(p: Any) -> tuple[float, float] | None:
    iv = getattr(p, "interval_90", None)
    return (float(iv[0]), float(iv[1])) if iv is not None else None


def run_case(
    preset: str,
    protocol: str,
    seed: int,
    *,
    valve: str,
    mcmc: bool,
    friction: str = "auto",
    seal: str = "off",
    noise_pooling: str = "recording",
    offset_scope: str = OFFSET_SCOPE,
    inputs: str = INPUT_MODE,
    robust: bool = True,
    segments: str = "auto",
) -> dict[str, Any]:
    """Record, fit and score one case."""
    from pneumafit.virtual_rig.truth import reference_quantities

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / f"{preset}-{seed}"
        rig = VirtualRig(truth=str(TRUTH_FILES.get(preset, preset)), seed=seed)
        run = rig.write(folder, protocol)
        truth_ref = reference_quantities(rig.truth, rig.parameters)
        camp = read_campaign(folder)
        t_rec = time.perf_counter() - t0
        options = FitOptions(
            mcmc=mcmc,
            valve=valve,
            friction=friction,
            seal=seal,
            noise_pooling=noise_pooling,
            offset_scope=offset_scope,
            inputs=inputs,
            robust=robust,
            segments=segments,
        )
        result = identify(camp, "convection", options=options, seed=seed)
    p = result.parameters
    q = result.quality
    lam = result.metrics.get("lambda_reference") or {}
    # fit and truth may count different walls in the exchange area (the fit's
    # heat_area_ends): both compared by their full-area equivalents, lambda
    # A_P / A_P,full at mid-stroke (lambda A is what the pressures see;
    # virtual_rig.truth.reference_quantities, staged._lambda_reference)
    lam = lam.get("full_area_equivalent") or lam
    truths = {
        "lambda_reference": float(truth_ref["lambda_full_area_equivalent"]),
        "friction_static": float(truth_ref["friction_static"]),
        "friction_coulomb": float(truth_ref["friction_coulomb"]),
    }
    # friction with both chambers at mid pressure, as the truth's reference
    # (metrics.friction_reference: with the seal-friction effect the levels
    # grow with the pressures; without it they are the parameters)
    fr = result.metrics.get("friction_reference") or {}
    est = {
        "lambda_reference": (lam.get("value"), lam.get("interval_90")),
        "friction_static": (
            (fr["static"]["value"], fr["static"]["interval_90"]) if fr
            else (p["friction_static"].value, _interval(p["friction_static"]))
        ),
        # the truth's Coulomb figure is its steady sliding friction at 50 mm/s
        # less the viscous part (virtual_rig.truth.reference_quantities): the
        # fit's same figure, its Coulomb level plus what remains of its
        # Stribeck drop there (0.04 N on the fitted laws' own truth, whose
        # F_c intervals of +-0.01 N missed it)
        "friction_coulomb": (
            (fr["sliding"]["value"], fr["sliding"]["interval_90"]) if fr
            else (p["friction_coulomb"].value, _interval(p["friction_coulomb"]))
        ),
    }  # fmt: skip
    figures: dict[str, Any] = {}
    alone = set(q.one_recording)
    for name, (value, iv) in est.items():
        true = truths[name]
        rel = (value - true) / true if value is not None and true else math.nan
        inside = bool(iv is not None and iv[0] <= true <= iv[1])
        figures[name] = {"truth": true, "estimate": value, "interval_90": iv,
                         "rel_error": rel, "contains_truth": inside,
                         "one_recording": bool(alone & set(FIGURE_PARAMETERS[name]))}  # fmt: skip
    ratios = {
        role: max((c.ratio for c in q.channels if c.role == role and c.ratio is not None
                   and c.channel.startswith("p_")), default=math.nan)
        for role in ("fit", "validate")
    }  # fmt: skip
    # the held-out figure with each closed-loop step test whose misfit at rest
    # the verdict explains by where its piston rests replayed with the recorded
    # commands instead of the model's controller (quality.recorded_commands):
    # what the held-out pressures miss once the loop's answer to the stick
    # position is taken out; the target stays pressure_ratio_validate
    opened = {f: r for f, r in q.recorded_commands.items() if r is not None}
    recorded = max(
        (opened.get(c.recording, c.ratio) for c in q.channels
         if c.role == "validate" and c.ratio is not None and c.channel.startswith("p_")),
        default=math.nan,
    )  # fmt: skip
    # each pressure sensor's offset as the fit saw it, against the truth's
    # (problem.pressure_offsets: applied only where the fit recordings agree
    # on it and pin it down)
    true_offsets = (run.truth.get("sensors") or {}).get("pressure_offsets") or {}
    offsets = {
        c: {"estimate": o.get("value"), "standard_error": o.get("standard_error"),
            "applied": o.get("applied"), "truth": true_offsets.get(c)}
        for c, o in (result.metrics.get("sensor_offsets") or {}).items()
    }  # fmt: skip
    return {
        "sensor_offsets": offsets,
        "pressure_ratio_validate_recorded_commands": recorded,
        "stops_elsewhere": [r.describe() for r in q.stops_elsewhere()],
        "case": preset, "protocol": protocol, "seed": seed, "valve": valve,
        "friction_law": result.structure.friction
        + ("+seal" if result.structure.effects.get("seal_friction") else ""),
        "record_s": round(t_rec, 1), "fit_s": round(result.seconds, 1),
        # the final estimate's log-likelihood (fit recordings; comparable
        # between two fits of the same campaign and structure)
        "log_likelihood": result.metrics.get("log_likelihood"),
        "pressure_ratio_fit": ratios["fit"], "pressure_ratio_validate": ratios["validate"],
        "recordings": [c.as_dict() for c in q.channels],
        "figures": figures, "verdict": q.verdict(), "problems": q.problems(),
        "outside_interval": list(q.outside_interval), "at_bounds": list(q.at_bounds),
        "undetermined": [item.split(" ", 1)[0] for item in q.undetermined],
        "one_recording": q.as_dict()["one_recording"],
        "recording_kinds": sorted({r.kind for r in camp.recordings}),
        "truth_file": run.truth.get("truth_model", {}).get("name", preset),
    }  # fmt: skip


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    tmp = path.with_name(path.name + ".partial")
    tmp.write_text(text)
    tmp.replace(path)


def _short(item: str) -> str:
    """An at-bound item without its explanation (the table cell stays short)."""
    return item.split(":")[0] + ")" if ":" in item else item


def table(rows: list[dict[str, Any]]) -> str:
    """Case x figure table in Markdown."""
    head = (
        "| case | protocol | seed | friction law | p RMS/noise fit | p RMS/noise held-out "
        "| held-out, recorded commands | lambda_ref err | F_s err | F_c err "
        "| truth in 90 % (of 3) | at bound | not determined | verdict |"
    )
    lines = [head, "|" + "---|" * 14]
    for r in rows:
        f = r["figures"]
        inside = sum(bool(v["contains_truth"]) for v in f.values())
        lines.append(
            f"| {r['case']} | {r['protocol']} | {r['seed']} | {r.get('friction_law', '-')} | "
            f"{r['pressure_ratio_fit']:.1f} | "
            f"{r['pressure_ratio_validate']:.1f} | "
            f"{r.get('pressure_ratio_validate_recorded_commands', math.nan):.1f} | "
            + " | ".join(f"{100 * f[k]['rel_error']:+.0f} %" for k in
                         ("lambda_reference", "friction_static", "friction_coulomb"))
            + f" | {inside} | {', '.join(_short(a) for a in r['at_bounds']) or '-'} | "
            f"{', '.join(r.get('undetermined', ())) or '-'} | "
            f"{'ok' if not r['problems'] else 'flagged'} |"
        )  # fmt: skip
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument(
        "--cases", nargs="+", default=None, help="truth presets or PRESET/PROTOCOL (default: all)"
    )
    ap.add_argument("--valve", default="iso6358", choices=("iso6358", "map"))
    ap.add_argument("--friction", default="auto", choices=("auto", "switch", "lugre"))
    ap.add_argument("--seal", default="long", choices=("long", "off", "auto", "on"))
    ap.add_argument("--noise-pooling", default="recording", choices=("recording", "sensor"))
    ap.add_argument("--inputs", default=INPUT_MODE, choices=INPUT_MODES)
    ap.add_argument("--offset-scope", default=OFFSET_SCOPE, choices=OFFSET_SCOPES)
    ap.add_argument("--mcmc", action="store_true", help="sample the posteriors (slow)")
    ap.add_argument(
        "--segments",
        default="auto",
        choices=SEGMENT_MODES,
        help="long closed-loop step tests fitted in segments (FitOptions.segments)",
    )
    ap.add_argument(
        "--no-robust",
        action="store_true",
        help="intervals without the robust widening (FitOptions.robust=False)",
    )
    ap.add_argument("--table", type=Path, default=None, help="write the Markdown table here")
    ap.add_argument("--json", type=Path, default=None, help="write every case's details here")
    args = ap.parse_args(argv)
    cases = [c for c in CASES if args.cases is None or c[0] in args.cases
             or f"{c[0]}/{c[1]}" in args.cases]  # fmt: skip
    # a PRESET/PROTOCOL outside the matrix (e.g. power-valve/sparse-long) is
    # recorded and fitted like the matrix's own cases
    for name in args.cases or ():
        preset, _, protocol = name.partition("/")
        if protocol and (preset, protocol) not in cases:
            get_protocol(protocol)  # an unknown protocol is named before any fit
            cases.append((preset, protocol))
    rows = []
    t0 = time.perf_counter()
    for preset, protocol in cases:
        for seed in args.seeds:
            print(f"{preset}/{protocol}/seed {seed}: recording and fitting ...", file=sys.stderr)
            row = run_case(preset, protocol, seed, valve=args.valve, mcmc=args.mcmc,
                           friction=args.friction, seal=args.seal,
                           noise_pooling=args.noise_pooling, inputs=args.inputs,
                           offset_scope=args.offset_scope,
                           robust=not args.no_robust, segments=args.segments)  # fmt: skip
            rows.append(row)
            if args.json is not None:  # every finished case kept, also if interrupted
                _write_atomic(args.json, json.dumps(rows, indent=1, default=float))
            fit_r, val_r = row["pressure_ratio_fit"], row["pressure_ratio_validate"]
            print(f"{preset}/{protocol}/seed {seed}: p RMS/noise fit {fit_r:.1f}, "
                  f"held-out {val_r:.1f}; {row['fit_s']:.0f} s", file=sys.stderr)  # fmt: skip
    control = [r for r in rows if r["case"] == CONTROL]
    undeclared = [r for r in rows if r["case"] == UNDECLARED]
    # the targets are on mismatched truths whose effects the models have
    rows_m = [r for r in rows if r["case"] not in (CONTROL, UNDECLARED)]
    pairs = [v for r in rows_m for v in r["figures"].values()]
    ratios = [r[k] for r in rows_m for k in ("pressure_ratio_fit", "pressure_ratio_validate")
              if np.isfinite(r[k])]  # fmt: skip
    coverage = float(np.mean([v["contains_truth"] for v in pairs])) if pairs else math.nan
    summary = {
        "cases": len(rows_m),
        "control_cases": len(control),
        "seconds": round(time.perf_counter() - t0, 1),
        "valve": args.valve,
        "friction": args.friction, "seal": args.seal, "noise_pooling": args.noise_pooling,
        "offset_scope": args.offset_scope,
        "inputs": args.inputs,
        "segments": args.segments, "mcmc": args.mcmc, "robust": not args.no_robust,
        "worst_pressure_ratio": max(ratios, default=math.nan),
        "median_pressure_ratio": float(np.median(ratios)) if ratios else math.nan,
        "pressure_within_3x": float(np.mean([x <= RATIO_TARGET for x in ratios])) if ratios
        else math.nan,
        # held-out figures with the recorded commands (not a target: the
        # share of the held-out misfit that is the loop's answer to the stop)
        "held_out_within_3x": float(np.mean([r["pressure_ratio_validate"] <= RATIO_TARGET
                                             for r in rows_m])) if rows_m else math.nan,
        "held_out_within_3x_recorded_commands": float(np.mean(
            [r["pressure_ratio_validate_recorded_commands"] <= RATIO_TARGET for r in rows_m]
        )) if rows_m else math.nan,
        "within_25_percent": float(np.mean([abs(v["rel_error"]) <= REL_TARGET for v in pairs]))
        if pairs else math.nan,
        "coverage_90": coverage,
        "coverage_target_met": bool(coverage >= COVERAGE_TARGET),
        "misses": sum(not v["contains_truth"] for v in pairs),
        # of those, the figures whose interval the fit said rests on one recording
        "misses_said_one_recording": sum(
            not v["contains_truth"] and v.get("one_recording", False) for v in pairs
        ),
        "said_one_recording": sum(v.get("one_recording", False) for v in pairs),
        # free parameters the fit said the recordings do not determine
        # (quality.undetermined_problems), over the mismatched cases
        "undetermined": sum(len(r.get("undetermined", ())) for r in rows_m),
        "estimates_outside_interval": sum(len(r["outside_interval"]) for r in rows),
        "flagged": sum(bool(r["problems"]) for r in rows_m),
        "control_pressure_ratio": max((r[k] for r in control for k in
                                       ("pressure_ratio_fit", "pressure_ratio_validate")),
                                      default=math.nan),
        "undeclared_cases": len(undeclared),
        "undeclared_pressure_ratio": max((r[k] for r in undeclared for k in
                                          ("pressure_ratio_fit", "pressure_ratio_validate")),
                                         default=math.nan),
    }  # fmt: skip
    if args.table is not None:
        args.table.write_text(table(rows))
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
