"""Benchmark of the compiled simulator against a straightforward scipy solver.

One run, one machine, ratios: on the same 4-s closed-loop step test with
1 kHz output (half stroke, stick-slip), it times

- the compiled simulator (default method, Kutta's RK3) as the package runs
  it in fits and replays: at the stable step :func:`choose_step` gives for
  the positions the test visits (from the tight reference's y), 3.03 ms
  with the defaults on 1-ms samples, with dense output
  (``Simulator(dense=True)``: a step spans three sample intervals, the
  samples inside it by cubic Hermite interpolation) -- ``ms_per_sim``; and
  at the default fixed 1-ms step, every sample integrated --
  ``ms_per_sim_default_step``; single runs and,
  at the stable step, batched over 64 parameter sets;
- two scipy peers, both ``solve_ivp(method="LSODA", rtol=1e-6)`` with the
  same events, breakpoints and tolerances
  (:func:`pneumafit.simulation.reference.solve_reference`):

  - the straightforward reference (``speedup``): a pure-Python right-hand
    side of the same model, the compiled RHS's own source run by CPython
    (:func:`pneumafit.simulation.reference.pure_python`);
  - the fair peer (``speedup_compiled``): the same model's compiled RHS,
    what a user would wire up instead: one compiled numba call per
    evaluation (sample lookup, valve commands and RHS), compiled before the
    timing (one warm-up call, not timed), so that only scipy's own stepping
    and event handling run in Python. It is timed interleaved with the
    compiled simulator (each round: the simulator at the stable step twice,
    at the default step once, the peer once), so that a change of the
    machine's load does not bias their ratios.

  The model has stick-slip, so scipy must be given its events (v = 0 while
  sliding, |F_d| = F_s while stuck) to solve it at all: a version that takes
  the friction direction from sign(v) chatters about v = 0 and did not finish
  in minutes, which would make any "speedup" meaningless;

and checks them against a tight reference (Radau, rtol 1e-10, events
located, compiled RHS): ``max_error_Pa`` (compiled simulator at the stable
step, over every sample, interpolated or not; ``max_error_Pa_default_step``
at 1 ms),
``reference_max_error_Pa`` and ``compiled_reference_max_error_Pa``. For
information it also times the pure-Python reference at rtol 1e-8, where it
is about as accurate as the compiled simulator. Every time is the median of
repeated calls after one untimed call. The machine's load average, its
CPU's model (``cpu_model``) and the share of CPU time the hypervisor stole
over the run (``steal_share``; ``benchmarks/machine.py``) are printed with
the figures: the ratios are measured within one run, absolute times
depend on the machine and its load; the CPU times of the single-threaded
runs (``cpu_ms_per_sim``, ``compiled_reference_cpu_ms_per_sim`` and their
ratio ``speedup_compiled_cpu``) are less disturbed by other processes. The
last line printed is one JSON object.

Targets (issue 15, 2-core machine, quiet): ``ms_per_sim`` <= 1.2 and
``speedup_compiled`` >= 25.

Run: ``python benchmarks/bench_simulate.py [--repeats N]``
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from machine import cpu_model, cpu_times, steal_share  # benchmarks/machine.py

from pneumafit.models.layout import P
from pneumafit.models.parameters import parameter_vector
from pneumafit.simulation import PD, Experiment, Simulator, choose_step
from pneumafit.simulation.reference import solve_reference
from pneumafit.simulation.simulator import step_ends


def step_test() -> Experiment:
    t = np.arange(0.0, 4.0005, 1e-3)
    y_ref = np.where(t < 0.2, 0.25, np.where(t < 2.0, 0.35, 0.25))
    return Experiment(
        time=t, kind="step", y_ref=y_ref, controller=PD(kp=60.0, kd=4.0),
        initial={"y": 0.25, "p_P": 4.0e5, "p_N": 4.0e5 * 0.8 / 0.6}, name="bench-step",
    )  # fmt: skip


def timed(fn, repeats: int) -> tuple[float, object]:
    """Median wall time (s) of ``repeats`` calls, and the last result."""
    times = []
    result = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), result


def timed_interleaved(fns: list, rounds: int) -> list[tuple[float, float, object]]:
    """Median wall and CPU times (s) and last result of each function, called
    in turn ``rounds`` times: a change of the machine's load hits all alike,
    so their ratios hold on a shared machine."""
    wall: list[list[float]] = [[] for _ in fns]
    cpu: list[list[float]] = [[] for _ in fns]
    results: list[object] = [None] * len(fns)
    for _ in range(rounds):
        for i, fn in enumerate(fns):
            c0, t0 = time.process_time(), time.perf_counter()
            results[i] = fn()
            wall[i].append(time.perf_counter() - t0)
            cpu[i].append(time.process_time() - c0)
    return [(float(np.median(w)), float(np.median(c)), r)
            for w, c, r in zip(wall, cpu, results, strict=True)]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    ticks = cpu_times()

    exp = step_test()
    params = parameter_vector({})
    print("tight reference: scipy Radau, rtol 1e-10, events located ...", flush=True)
    ref = solve_reference("convection", params, exp, method="Radau", rtol=1e-10)

    # the step the package takes for this test (fits and replays choose it
    # from the positions a recording visits: here the reference's)
    step = choose_step(params, default=1.0,
                       y_range=(float(ref["y"].min()), float(ref["y"].max())))  # fmt: skip
    sim = Simulator("convection", channels=["y", "p_P", "p_N"], step=step, dense=True)
    packed = sim.pack([exp])
    sim.simulate_batch(params, packed)  # compile or load from cache
    fixed = Simulator("convection", channels=["y", "p_P", "p_N"])
    packed_fixed = fixed.pack([exp])

    def lsoda(compiled: bool, rtol: float = 1e-6) -> dict:
        return solve_reference("convection", params, exp, method="LSODA", rtol=rtol,
                               compiled=compiled)  # fmt: skip

    print("fair peer: scipy LSODA rtol 1e-6 over the compiled RHS, interleaved with the "
          "compiled simulator ...", flush=True)  # fmt: skip
    lsoda(True)  # compile (or load from cache) the RHS call: not timed

    def single() -> tuple[np.ndarray, np.ndarray]:
        return sim.simulate_batch(params, packed)

    def single_fixed() -> tuple[np.ndarray, np.ndarray]:
        return fixed.simulate_batch(params, packed_fixed)

    # each round: the compiled simulator twice, at the default step once,
    # the fair peer once
    timings = timed_interleaved([single, single, single_fixed, lambda: lsoda(True)],
                                max(5, args.repeats // 2))  # fmt: skip
    single_s = float(np.mean([timings[0][0], timings[1][0]]))
    single_cpu = float(np.mean([timings[0][1], timings[1][1]]))
    out, status = timings[0][2]
    fixed_s, fixed_cpu, (out_fixed, status_fixed) = timings[2]
    comp_s, comp_cpu, comp = timings[3]
    assert status[0, 0] == 0 and status_fixed[0, 0] == 0, "compiled simulation failed"
    y, p_p, p_n = out[0].T
    err_pa = float(max(np.abs(p_p - ref["p_P"]).max(), np.abs(p_n - ref["p_N"]).max()))
    err_mm = float(np.abs(y - ref["y"]).max() * 1e3)
    _, p_p_f, p_n_f = out_fixed[0].T
    err_fixed = float(max(np.abs(p_p_f - ref["p_P"]).max(), np.abs(p_n_f - ref["p_N"]).max()))

    rng = np.random.default_rng(64)
    sets = np.tile(params, (64, 1))
    sets[:, P["xi"]] *= rng.uniform(0.8, 1.2, 64)
    sets[:, P["beta"]] *= rng.uniform(0.9, 1.1, 64)
    sets[:, P["friction_static"]] = rng.uniform(45.0, 60.0, 64)
    sets[:, P["friction_coulomb"]] = rng.uniform(25.0, 40.0, 64)
    sim.simulate_batch(sets, packed)
    batch_s, (_, bstatus) = timed(
        lambda: sim.simulate_batch(sets, packed), max(3, args.repeats // 5)
    )
    assert np.all(bstatus == 0), "a batched simulation failed"

    def pressure_error(sol: dict) -> float:
        return float(max(np.abs(sol["p_P"] - ref["p_P"]).max(),
                         np.abs(sol["p_N"] - ref["p_N"]).max()))  # fmt: skip

    comp_err = pressure_error(comp)
    comp_err_mm = float(np.abs(comp["y"] - ref["y"]).max() * 1e3)

    print("reference: scipy LSODA rtol 1e-6 over the pure-Python RHS ...", flush=True)
    lsoda(False)  # the same untimed first call
    lsoda_s, lsoda_sol = timed(lambda: lsoda(False), 5)
    lsoda_err = pressure_error(lsoda_sol)
    lsoda_err_mm = float(np.abs(lsoda_sol["y"] - ref["y"]).max() * 1e3)
    # the same reference tightened until it is as accurate as the compiled
    # simulator (rtol 1e-8: ~0.1 Pa), for a comparison at equal accuracy
    tight_s, tight = timed(lambda: lsoda(False, rtol=1e-8), 3)
    tight_err = pressure_error(tight)

    ms = single_s * 1e3
    rows = [
        (f"compiled {sim.tableau.name}, {step * 1e3:.2f}-ms step, dense output", ms, err_pa,
         err_mm),
        (f"compiled {sim.tableau.name}, default 1-ms step", fixed_s * 1e3, err_fixed,
         float("nan")),
        (f"compiled {sim.tableau.name}, batched x64 (per set)", batch_s * 1e3 / 64, float("nan"),
         float("nan")),
        ("scipy LSODA rtol 1e-6, compiled RHS (fair peer)", comp_s * 1e3, comp_err, comp_err_mm),
        ("scipy LSODA rtol 1e-6, pure Python (reference)", lsoda_s * 1e3, lsoda_err, lsoda_err_mm),
        ("scipy LSODA rtol 1e-8, pure Python (equal accuracy)", tight_s * 1e3, tight_err,
         float("nan")),
    ]  # fmt: skip
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    steal = steal_share(ticks, cpu_times())
    stolen = "not known" if steal is None else f"{steal:.1%}"
    model = cpu_model()
    print(f"{os.cpu_count()} CPUs ({model or 'model not known'}), load average {load:.2f} over "
          f"the last minute, CPU time stolen by the hypervisor over this run {stolen} "
          f"(benchmarks/machine.py); CPU time per simulation: compiled "
          f"{single_cpu * 1e3:.2f} ms, LSODA over the compiled RHS "
          f"{comp_cpu * 1e3:.2f} ms")  # fmt: skip
    print(f"{'simulator':50s} {'ms/sim':>9s} {'max err Pa':>11s} {'max err mm':>11s}")
    for name, t_ms, e_pa, e_mm in rows:
        print(f"{name:50s} {t_ms:9.2f} {e_pa:11.3g} {e_mm:11.3g}")
    result = {
        "ms_per_sim": round(ms, 3),
        "ms_per_sim_batched": round(batch_s * 1e3 / 64, 3),
        "reference_ms_per_sim": round(lsoda_s * 1e3, 1),
        "speedup": round(lsoda_s * 1e3 / ms, 1),
        "speedup_compiled": round(comp_s * 1e3 / ms, 1),
        "max_error_Pa": round(err_pa, 3),
        "max_error_mm": round(err_mm, 5),
        "reference_max_error_Pa": round(lsoda_err, 1),
        "compiled_reference_ms_per_sim": round(comp_s * 1e3, 2),
        "compiled_reference_max_error_Pa": round(comp_err, 1),
        "speedup_equal_accuracy": round(tight_s * 1e3 / ms, 1),
        "ms_per_sim_default_step": round(fixed_s * 1e3, 3),
        "speedup_compiled_default_step": round(comp_s / fixed_s, 1),
        "max_error_Pa_default_step": round(err_fixed, 3),
        "cpu_ms_per_sim_default_step": round(fixed_cpu * 1e3, 3),
        "step_ms": round(step * 1e3, 3),
        "steps_per_sim": step_ends(packed.nsub_all)[1],
        "steps_per_sim_default_step": step_ends(packed_fixed.nsub_all)[1],
        "method": sim.tableau.name,
        "targets_met": bool(ms <= 1.2 and comp_s / single_s >= 25.0),
        "cpu_ms_per_sim": round(single_cpu * 1e3, 3),
        "compiled_reference_cpu_ms_per_sim": round(comp_cpu * 1e3, 2),
        "speedup_compiled_cpu": round(comp_cpu / single_cpu, 1),
        "cpus": os.cpu_count(),
        "load_average": round(load, 2),
        "steal_share": None if steal is None else round(steal, 4),
        "cpu_model": model,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
