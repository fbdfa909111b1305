"""A weakly informative prior on the breakaway: static over Coulomb friction.

Step tests resolve the Coulomb level (every sliding sample sets it) far
better than the static one: the breakaway force F_s shows only where the
piston starts from rest, and a closed-loop step test that starts while the
piston creeps, or a recording that never rests long enough, leaves it
unresolved. The least squares then take it anywhere along a flat valley; on
an independently written rig without a flow test (``power-valve``, sparse
plan less its flow test, seed 1) it ran to the actuator's force, 563 N
(the bound) for a Coulomb level of 29 N, and the held-out step, which
starts at rest, never broke away (241x the pressure noise).

The prior is an engineering judgement, not a measurement: a seal that
breaks away at several times its sliding level is not what pneumatic
cylinders show (the four measured seals of ``data/measured`` have their
fitted static level below their Coulomb level, docs/measured-data.md). It is flat up to
:data:`RATIO_TYPICAL` = 2 and falls off above it as a half-normal in
ln(F_s / F_c) of scale :data:`RATIO_SCALE` = ln 2: ratio 3 costs 0.17 in log
density, 4 costs 0.5, 8 costs 2, 20 costs 5.5. Where the step tests resolve
F_s the likelihood outweighs it by orders of magnitude; where they do not,
it keeps the estimate among real seals. It is flat over every ratio below
2, so it pulls no resolved estimate toward any particular value.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["RATIO_SCALE", "RATIO_TYPICAL", "breakaway_prior"]

#: Static over Coulomb friction up to which the prior is flat (-).
RATIO_TYPICAL = 2.0
#: Scale of the half-normal in ln(F_s / F_c) above it (-): a factor of 2.
RATIO_SCALE = math.log(2.0)


def breakaway_prior(values: Mapping[str, Any]) -> NDArray[np.float64]:
    """Whitened residual of the breakaway prior (module doc).

    Parameters
    ----------
    values : mapping
        ``friction_static`` and ``friction_coulomb`` (N), floats or arrays
        of n parameter sets.

    Returns
    -------
    ndarray (n, 1)
        max(0, ln(F_s / F_c) - ln :data:`RATIO_TYPICAL`) / :data:`RATIO_SCALE`;
        the log prior is minus half its square. A Coulomb level at 0 (or a
        non-finite ratio) gives 0: the prior says nothing there.
    """
    f_s = np.atleast_1d(np.asarray(values["friction_static"], dtype=float))
    f_c = np.atleast_1d(np.asarray(values["friction_coulomb"], dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = np.log(f_s / f_c) - math.log(RATIO_TYPICAL)
    r = np.where(np.isfinite(excess), np.maximum(excess, 0.0) / RATIO_SCALE, 0.0)
    return r.reshape(-1, 1)
