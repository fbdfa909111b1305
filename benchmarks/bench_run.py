"""Benchmark of the main job, ``pneumafit run``, on the bundled demo campaign.

Runs ``python -m pneumafit run [CAMPAIGN] --out OUT`` in a new process (a new
temporary folder unless ``--out`` is given: a folder with finished stages
would reuse them and time nothing), then reads ``OUT/summary.json`` and every
fit's ``mcmc`` block, and prints one JSON line:

- ``total_s``: the run's own total (``summary.json`` ``total_seconds``);
  ``wall_s``: the process's wall time, with the interpreter start, the
  imports and any simulator compilation (a cold numba cache);
- ``seconds``: wall time per stage; ``simulations_per_second`` per stage
  (simulations run in the run's process: one parameter set on one recording);
- ``shortest_chain_tau``: the shortest MCMC chain of all fits in units of its
  integrated autocorrelation time (``tau_multiple``; None without MCMC), with
  ``tau_multiple`` per fit and sampled stage;
- ``reused``: stages that were reused (0 s), which a timing should not have;
- ``cpu_model`` and ``steal_share``: the CPU the run had and the share of
  its CPU time the hypervisor stole (``benchmarks/machine.py``), so that
  totals of different runs are read with the machine they came from.

The run's own console output goes to ``OUT/run.log``. The main job took
7.3 min from a fresh clone on the 2-core machine (2026-11-27, README); the
speed issue's goal is 3 min. ``--no-mcmc`` is far shorter.

Run: ``python benchmarks/bench_run.py [--out DIR] [--campaign DIR] [--seed N]
[--no-mcmc] [--walkers N] [--steps N]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import cpu_model, cpu_times, steal_share  # benchmarks/machine.py


def chain_lengths(out: Path) -> dict[str, dict[str, float]]:
    """``tau_multiple`` per fitted model and sampled stage (empty without MCMC)."""
    found = {}
    for fit in sorted((out / "fits").glob("*/fit.json")):
        mcmc = json.loads(fit.read_text()).get("mcmc") or {}
        if mcmc.get("tau_multiple"):
            found[fit.parent.name] = {k: float(v) for k, v in mcmc["tau_multiple"].items()}
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="run folder (default: temp)")
    parser.add_argument("--campaign", type=Path, default=None, help="default: the demo")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-mcmc", action="store_true")
    parser.add_argument("--walkers", type=int, default=None)
    parser.add_argument("--steps", type=int, default=None)
    args = parser.parse_args()

    out = args.out or Path(tempfile.mkdtemp(prefix="bench-run-")) / "run"
    command = [sys.executable, "-m", "pneumafit", "run", "--out", str(out),
               "--seed", str(args.seed)]  # fmt: skip
    if args.campaign is not None:
        command.insert(4, str(args.campaign))
    if args.no_mcmc:
        command.append("--no-mcmc")
    for option, value in (("--walkers", args.walkers), ("--steps", args.steps)):
        if value is not None:
            command += [option, str(value)]
    print(f"pneumafit bench_run: {' '.join(command)} ({os.cpu_count()} CPUs)", flush=True)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "run.log"
    t0 = time.perf_counter()
    ticks = cpu_times()
    with open(log, "w") as f:
        code = subprocess.call(command, stdout=f, stderr=subprocess.STDOUT)
    wall = time.perf_counter() - t0
    steal = steal_share(ticks, cpu_times())
    try:
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        summary = {}
    tail = log.read_text(errors="replace").splitlines()[-25:]
    print("\n".join(tail))
    chains = chain_lengths(out)
    multiples = [m for stages in chains.values() for m in stages.values()]
    seconds = summary.get("seconds", {})
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    print(json.dumps({
        "exit_status": code,
        "total_s": summary.get("total_seconds"),
        "wall_s": round(wall, 1),
        "seconds": seconds,
        "simulations_per_second": summary.get("simulations_per_second", {}),
        "total_simulations": summary.get("total_simulations"),
        "shortest_chain_tau": round(min(multiples), 1) if multiples else None,
        "tau_multiple": chains,
        "reused": [name for name, s in seconds.items() if s == 0.0],
        "failed_stage": summary.get("failed_stage"),
        "out": str(out),
        "cpus": os.cpu_count(),
        "load_average_end": round(load, 2) if load is not None else None,
        "steal_share": None if steal is None else round(steal, 4),
        "cpu_model": cpu_model(),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
