"""Does a recording's measured supply pressure agree with the declared one?

The models take the supply pressure as a constant, the rig's declared
``supply_pressure``; a recording's ``p_S`` channel (the measured supply
pressure, optional in the campaign format) is read and kept but is not an
input of any simulation. Where it disagrees with the declared value the
valves' supply flows are simulated at the wrong upstream pressure, which no
fitted parameter of the valve, heat or friction laws represents:

- choked, a path's mass flow is proportional to its upstream absolute
  pressure (ISO 6358, eq. 3 of the paper), so a supply pressure off by a
  share e of the gauge supply P_S - P_e changes the filling flows by
  e (P_S - P_e) / P_S: 0.86 % for e = 1 % on a 7-bar rig, which on a charge
  rising by 5 bar is ~4 kPa of pressure, ten times a 400-Pa sensor's
  noise. :data:`TOLERANCE` = 1 % is therefore where the mismatch starts to
  show in a fit's residuals;
- a median far off the declared value most often is a gauge reading
  declared as absolute (``supply_pressure = "7 bar"`` for a regulator set to
  7 bar gauge, 8.013 bar absolute) or a regulator set elsewhere than
  written: the campaign's value is what to correct;
- a wide spread within one recording is the supply sagging while the
  valves draw air (a regulator's droop, a long or narrow line): the catalog
  effect ``supply_pressure_drop`` of ``pneumafit discover`` models it as a
  line resistance.

:func:`supply_mismatch` judges one channel; the campaign reader reports it
as a warning of ``pneumafit check`` (and of the main job's check stage), and
the fit adds the same sentence to its warnings (:func:`supply_warnings`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Campaign, Recording

__all__ = ["SPREAD_QUANTILES", "TOLERANCE", "supply_mismatch", "supply_warnings"]

#: Largest difference, as a share of the gauge supply P_S - P_e, between the
#: measured supply pressure (its median, or the width of its central 90 %)
#: and the declared one before it is reported (module doc: 1 % changes a
#: charge's pressure by ~10 sensor noise levels).
TOLERANCE = 0.01
#: Quantiles whose distance is a recording's spread of p_S: the central
#: 90 % (white sensor noise of standard deviation s alone spans 3.3 s, 1.3
#: kPa for the 400-Pa sensors of the virtual rig, a fifth of 1 % of 6 bar).
SPREAD_QUANTILES = (0.05, 0.95)


def _bar(pressure: float) -> str:
    return f"{pressure / 1e5:.3f} bar"


def supply_mismatch(
    p_s: NDArray[np.float64], supply: float, exhaust: float
) -> tuple[str, str] | None:
    """What a measured supply pressure should be and what it is, or None.

    Parameters
    ----------
    p_s : ndarray
        The recording's ``p_S`` channel (Pa absolute).
    supply, exhaust : float
        The rig's declared supply and exhaust pressures (Pa absolute).

    Returns
    -------
    (expected, found) or None
        None when the channel's median lies within :data:`TOLERANCE` of the
        gauge supply of the declared value and its central 90 % spans less
        than that; else the two halves of a problem message (the module doc
        says what each case usually means).
    """
    x = np.asarray(p_s, dtype=float)
    x = x[np.isfinite(x)]
    span = supply - exhaust
    if x.size < 2 or not span > 0.0:
        return None
    allowed = TOLERANCE * span
    median = float(np.median(x))
    lo, hi = (float(q) for q in np.quantile(x, SPREAD_QUANTILES))
    off = median - supply
    wide = hi - lo > allowed
    if abs(off) <= allowed and not wide:
        return None
    expected = (
        f"a measured supply pressure within {100 * TOLERANCE:g} % of the gauge supply "
        f"({allowed / 1e3:.3g} kPa) of the declared supply_pressure {_bar(supply)} absolute "
        "(the models simulate the declared value; p_S is not an input)"
    )
    found = f"median {_bar(median)}, central 90 % {_bar(lo)} to {_bar(hi)}"
    causes = []
    if abs(off) > allowed:
        hint = (
            f" (the declared value plus the exhaust pressure is {_bar(supply + exhaust)}: a "
            "gauge reading declared as absolute?)"
            if abs(median - (supply + exhaust)) <= allowed
            else ""
        )
        causes.append(
            f"{off / 1e3:+.1f} kPa from the declared value{hint}: correct supply_pressure in "
            "campaign.toml if the rig ran there"
        )
    if wide:
        causes.append(
            "the supply sags while the valves draw air (the catalog effect "
            "supply_pressure_drop of pneumafit discover models a line resistance)"
        )
    return expected, found + ": " + "; ".join(causes)


def supply_warnings(campaign: Campaign, recordings: Sequence[Recording] | None = None) -> list[str]:
    """One sentence per recording whose ``p_S`` disagrees with the rig's
    declared supply pressure (:func:`supply_mismatch`), in campaign order.

    Parameters
    ----------
    campaign : Campaign
    recordings : sequence of Recording, optional
        Those to judge (default: every recording of the campaign).
    """
    rig = campaign.rig
    out = []
    for rec in campaign.recordings if recordings is None else recordings:
        p_s = rec.channels.get("p_S")
        if p_s is None:
            continue
        found = supply_mismatch(p_s, rig.supply_pressure, rig.exhaust_pressure)
        if found is not None:
            out.append(f"{rec.file}: p_S: expected {found[0]}; found {found[1]}")
    return out
