"""Benchmark of the MCMC moves on the demo's friction posterior.

Runs the staged fit of ``data/demo`` (polytropic, the fastest heat law; the
friction stage is the longest MCMC of every fit) up to its friction MCMC and
samples that posterior twice with the same budget and seed, from the same
wide initial ensemble:

- ``de``: emcee's differential-evolution moves alone (80 % DE, 20 % snooker);
- ``adapted``: the same for ``--adapt`` steps, then the Student-t
  independence proposal fitted to the walkers, 90 % of the moves
  (``run_mcmc(adapt=)``, :mod:`pneumafit.identification.sampling`).

It prints, per configuration, one JSON line: seconds, acceptance over the
kept steps, the largest tau (steps), the kept chain in tau, the largest
R-hat and every 90 % interval; the last line compares them (``tau_ratio``,
``max_interval_shift``: the largest change of an interval end between the
two, as a fraction of the interval's width). The posterior is the same, so
the intervals should agree to Monte-Carlo error.

Run: ``python benchmarks/bench_moves.py [--steps 800] [--adapt 300]``
(about 4 minutes on the 2-core machine).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import pneumafit.identification.staged as staged
from pneumafit.campaign import read_campaign
from pneumafit.identification import FitOptions

DEMO = Path(__file__).resolve().parent.parent / "data" / "demo"


class _Done(Exception):
    """Stops the fit once the friction posterior has been sampled."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=800, help="steps after the adaptation")
    ap.add_argument("--adapt", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rows: list[dict[str, Any]] = []
    original = staged.run_mcmc

    def measured(post: Any, ps: Any, start: Any, cov: Any, **kw: Any) -> Any:
        if kw.get("name") != "friction":
            return original(post, ps, start, cov, **kw)
        kw.update(backend=None, max_steps=None, min_steps=None, report=None, log=None)
        kw["n_steps"] = args.adapt + args.steps
        for label, adapt in (("de", 0), ("adapted", args.adapt)):
            t0 = time.perf_counter()
            res = original(post, ps, start, cov, **{**kw, "adapt": adapt})
            row = {
                "moves": label, "seconds": round(time.perf_counter() - t0, 1),
                "steps": res.n_steps, "walkers": res.n_walkers, "discard": res.discard,
                "acceptance": round(res.acceptance, 3), "tau_max": round(max(res.tau.values()), 2),
                "tau_multiple": round(res.tau_multiple, 1),
                "rhat_max": round(max(res.rhat.values()), 4),
                "intervals": {p.name: p.interval_90 for p in res.parameters.free},
            }  # fmt: skip
            print(json.dumps(row), flush=True)
            rows.append(row)
        raise _Done

    staged.run_mcmc = measured
    try:
        staged.identify(
            read_campaign(DEMO), "polytropic", options=FitOptions(sample=("friction",)),
            seed=args.seed,
        )  # fmt: skip
    except _Done:
        pass
    finally:
        staged.run_mcmc = original
    de, ad = rows
    shift = max(
        max(abs(a - b) for a, b in zip(ad["intervals"][n], de["intervals"][n], strict=True))
        / (de["intervals"][n][1] - de["intervals"][n][0])
        for n in de["intervals"]
    )
    print(json.dumps({
        "tau_ratio": round(de["tau_max"] / ad["tau_max"], 2),
        "acceptance": [de["acceptance"], ad["acceptance"]],
        "max_interval_shift": round(shift, 3), "seconds": [de["seconds"], ad["seconds"]],
    }))  # fmt: skip


if __name__ == "__main__":
    main()
