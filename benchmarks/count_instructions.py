"""A fixed workload for counting the compiled simulator's instructions.

Timings on a shared 2-core machine move by several per cent from one run to
the next; an instruction count does not. This script runs 48 simulations --
a 4-s closed-loop step test and a 3-s charge test, eight parameter sets each,
with the switch model, LuGre, and the switch model with the wall's thermal
mass (a structure that integrates the states past the first eight) -- and
prints the sum of the simulated outputs (the same to the last digit when a
change must not move the results). Count it with callgrind on a numba cache
compiled for a generic x86-64 CPU (valgrind does not run every instruction
set extension, and the same machine code makes two trees comparable)::

    export NUMBA_CPU_NAME=generic NUMBA_CPU_FEATURES= NUMBA_CACHE_DIR=/tmp/cg-cache
    python benchmarks/count_instructions.py          # compiles the cache (~1 min)
    valgrind --tool=callgrind --callgrind-out-file=cg.out \\
        python benchmarks/count_instructions.py
    callgrind_annotate --threshold=100 cg.out | \\
        awk '/\\?\\?\\?:0x.*\\[\\?\\?\\?\\]/ {gsub(",", "", $1); s += $1} END {print s / 1e6, "M"}'

The compiled (numba) code has neither symbols nor an object file under
valgrind: its lines are the ``???:0x... [???]`` ones, summed by the last
command (stripped system libraries, e.g. libcrypto hashing the numba cache's
stamp, show as ``???`` too, with their file named). Run it for two trees with
``PYTHONPATH=<tree>/src`` and separate caches to compare a change.
"""

from __future__ import annotations

import numpy as np

from pneumafit.models.parameters import default_parameters, parameter_vector
from pneumafit.models.structure import ModelStructure
from pneumafit.simulation import Experiment, Simulator
from pneumafit.simulation.experiment import PD


def main() -> None:
    t = np.arange(0.0, 4.0005, 1e-3)
    y_ref = np.where(t < 0.2, 0.25, np.where(t < 2.0, 0.35, 0.25))
    step = Experiment(time=t, kind="step", y_ref=y_ref, controller=PD(kp=60.0, kd=4.0),
                      initial={"y": 0.25, "p_P": 4.0e5, "p_N": 4.0e5 * 0.8 / 0.6},
                      name="step")  # fmt: skip
    tc = np.arange(0.0, 3.0005, 1e-3)
    u = np.where((tc > 0.1) & (tc < 0.4), 8.0, 0.0)
    charge = Experiment(time=tc, kind="charge", chamber="P", u_P=u,
                        initial={"y": 0.2, "p_P": 1.013e5}, name="charge")  # fmt: skip
    vec = parameter_vector(default_parameters())
    total = 0.0
    for structure in (
        ModelStructure("convection"),
        ModelStructure("convection", friction="lugre"),
        ModelStructure("convection", effects={"wall_thermal_mass": 1}),
    ):
        sim = Simulator(structure, channels=("y", "p_P", "p_N"))
        out, status = sim.simulate_batch(np.repeat(vec[None], 8, axis=0), [step, charge])
        if not (status == 0).all():
            raise SystemExit(f"a simulation failed: {structure.name}, status {status.tolist()}")
        total += float(np.nansum(out))
    print(repr(total))


if __name__ == "__main__":
    main()
