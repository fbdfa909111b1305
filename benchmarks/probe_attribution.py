"""Round 1 of discovery's attribution for pairs of campaign and fit.

Usage::

    python benchmarks/probe_attribution.py CAMPAIGN FIT.json [CAMPAIGN FIT.json ...]

Prints, per campaign, the number of rows of the ``quiet`` row set (the
pressure rows of the rest and relaxation phases) and the six best-ranked
candidates with the row set their evidence was read on, as
:func:`pneumafit.discovery.refit.discover` ranks them in its first round
(100 bootstrap fits, seed 0; docs/effects.md, "Judged where it acts").
"""

from __future__ import annotations

import sys

import numpy as np

from pneumafit import FitResult, read_campaign
from pneumafit.discovery.refit import BaseFit, attribute_residual
from pneumafit.identification.segments import segment_step_tests


def main(argv: list[str]) -> int:
    if len(argv) < 2 or len(argv) % 2:
        print(__doc__)
        return 2
    for folder, fit in zip(argv[::2], argv[1::2], strict=True):
        base = BaseFit.from_document(FitResult.load(fit))
        # the step tests cut as the base fit cut them, as discover does
        campaign = segment_step_tests(read_campaign(folder), base.segments)[0]
        att = attribute_residual(campaign, base, rng=np.random.default_rng(0), n_bootstrap=100)
        print(f"{folder}: {att.channels.get('quiet', {}).get('n_rows', 0)} quiet rows")
        for c in att.candidates[:6]:
            print(
                f"  {c.effect:22s} {c.rows:8s} score {c.score:.3f} inclusion "
                f"{c.inclusion_probability:.2f} R2 {c.variance_explained:.3f} match "
                f"{c.phase_match:.2f} coefficient {c.coefficient:.3g}"
                + (" supported" if c.supported else "")
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
