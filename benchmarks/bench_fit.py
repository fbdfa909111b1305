"""Benchmark of the full staged fit of the demo campaign, MCMC included.

Runs :func:`pneumafit.identification.identify` on ``data/demo`` with the
default settings (the ``pneumafit fit data/demo --model convection``
defaults: least-squares stages a-d with the solver's defect correction, then
emcee on the heat and friction groups) and prints

- the wall time of each stage and of the whole fit;
- likelihood evaluations (parameter sets simulated) per second, for the
  least-squares stages and for each MCMC stage (each set simulates every
  recording of its stage);
- the chain length in units of the integrated autocorrelation time, per
  sampled stage (goal: at least 50), with R-hat and ESS;
- the estimates against ``data/demo/truth.json`` (the virtual rig's truth;
  for an independent truth, its reference quantities: see :func:`_truth`).

The goal on the 2-core reference machine: the convection fit with MCMC in
at most 60 s with chains of at least 50 tau (the speed issue; it was 5
minutes before). Within the main job of 2026-11-26 (68b3452, the valve stage
shared with the earlier fits) it took 214 s, its chains 22 s (heat) and 49 s
(friction). Alone, on another machine about twice as fast (2026-11-27,
0e9f5ca): 90 s, of which least squares 35 s, the heat chain 14 s (103 tau)
and the friction chain 27 s (116 tau); not met. The last line printed is one
JSON object.

Run: ``python benchmarks/bench_fit.py [--model convection] [--seed 0]
[--steps N] [--walkers N] [--chains PATH]``
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from pneumafit.campaign import read_campaign
from pneumafit.identification import FitOptions, identify

#: The speed issue's goal for a convection fit with MCMC on the demo (s).
GOAL_SECONDS = 60.0
DEMO = Path(__file__).resolve().parent.parent / "data" / "demo"
CHECKED = (
    "xi", "beta", "lambda", "k", "friction_static", "friction_coulomb", "friction_viscous",
    "stribeck_velocity", "valve_C_supply", "valve_C_exhaust", "valve_C_leak", "valve_overlap",
)  # fmt: skip


def _truth(path: Path) -> dict[str, float]:
    """True values to compare with, by fitted-parameter name.

    A rig recorded with the fitted laws gives its parameters. An independent
    truth (``truth_model``; the demo since 2026-11-25) has other laws: only
    the figures with a counterpart in the fitted models are compared, from
    its reference quantities (static and Coulomb friction at 4 bar in both
    chambers, viscous friction, full-opening conductances, centre leak) and
    its Nusselt coefficients when the heat law is the paper's.
    """
    if not path.exists():
        return {}
    doc = json.loads(path.read_text())
    if "truth_model" not in doc:
        return dict(doc["parameters"])
    ref = doc["truth_model"]["reference_quantities"]
    out = {
        "friction_static": ref["friction_static"],
        "friction_coulomb": ref["friction_coulomb"],
        "friction_viscous": ref["friction_viscous"],
        "valve_C_supply": ref["valve_C_supply_max"],
        "valve_C_exhaust": ref["valve_C_exhaust_max"],
        "valve_C_leak": ref["valve_C_leak_centre"],
    }
    heat = doc["truth_model"]["config"]["heat"]
    if heat.get("model") == "nusselt" and heat.get("area") == "full":
        out.update(xi=heat["xi"], beta=heat["beta"])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", default="convection")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--walkers", type=int, default=None)
    parser.add_argument("--chains", type=Path, default=None, help="HDF5 file (default: temp)")
    parser.add_argument("--no-mcmc", action="store_true")
    args = parser.parse_args()

    campaign = read_campaign(DEMO)
    truth = _truth(DEMO / "truth.json")
    tmp = Path(tempfile.mkdtemp(prefix="bench-fit-"))
    chains = args.chains or tmp / "chains.h5"
    if chains.exists():
        os.remove(chains)  # a benchmark never resumes
    options = FitOptions(mcmc=not args.no_mcmc, steps=args.steps, walkers=args.walkers)
    print(f"pneumafit bench_fit: {args.model} on {DEMO} ({os.cpu_count()} CPUs)")
    t0 = time.perf_counter()
    result = identify(campaign, args.model, options=options, seed=args.seed, chains=chains,
                      log=lambda line: print("  " + line, flush=True))  # fmt: skip
    wall = time.perf_counter() - t0

    ls_evals = sum(s.estimate.n_evaluations for s in result.stages if s.estimate is not None)
    ls_time = sum(s.seconds for s in result.stages)
    print(f"\nwall time: {wall:.1f} s (least squares {ls_time:.1f} s, "
          f"{ls_evals} sets, {ls_evals / max(ls_time, 1e-9):.0f} evaluations/s)")  # fmt: skip
    mcmc_report = {}
    for run in result.mcmc:
        rate = run.evaluations / max(run.seconds, 1e-9)
        print(
            f"mcmc {run.name}: {run.n_walkers} walkers x {run.n_steps} steps, {run.seconds:.1f} s, "
            f"{rate:.0f} evaluations/s, acceptance {run.acceptance:.2f}, "
            f"chain {run.tau_multiple:.1f} tau (largest tau {max(run.tau.values()):.1f}), "
            f"R-hat <= {max(run.rhat.values()):.3f}, ESS >= {min(run.ess.values()):.0f}"
        )
        mcmc_report[run.name] = {
            "walkers": run.n_walkers, "steps": run.n_steps, "seconds": run.seconds,
            "evaluations_per_second": rate, "tau": run.tau, "tau_multiple": run.tau_multiple,
            "acceptance": run.acceptance, "rhat_max": max(run.rhat.values()),
            "ess_min": min(run.ess.values()),
        }  # fmt: skip
    print("\nparameter            estimate      90 % interval                truth   inside")
    inside = {}
    for name in CHECKED:
        if name not in result.parameters:
            continue
        p = result.parameters[name]
        lo, hi = p.interval_90 or (float("nan"), float("nan"))
        tv = truth.get(name)
        ok = tv is not None and lo <= tv <= hi
        inside[name] = ok
        print(f"{name:20s} {p.value:12.6g}  [{lo:12.6g}, {hi:12.6g}]  {tv!s:>10}  "
              f"{'yes' if ok else 'no'} ({p.uncertainty})")  # fmt: skip
    for w in result.warnings:
        print(f"warning: {w}")
    goal = wall <= GOAL_SECONDS and all(r["tau_multiple"] >= 50.0 for r in mcmc_report.values())
    print(
        f"\ngoal (MCMC fit <= {GOAL_SECONDS:.0f} s, chains >= 50 tau): "
        f"{'met' if goal else 'NOT met'}"
    )
    print(json.dumps({
        "model": args.model, "wall_seconds": wall, "least_squares_seconds": ls_time,
        "least_squares_evaluations_per_second": ls_evals / max(ls_time, 1e-9),
        "evaluations": result.evaluations, "mcmc": mcmc_report, "inside_90": inside,
        "goal_met": goal, "cpus": os.cpu_count(),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
