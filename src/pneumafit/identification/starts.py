"""Data-driven start values for the staged fit (never the parameter defaults).

A rig engineer reads first estimates off the recordings before fitting:
the full-opening conductances from the largest measured flows, the friction
from the force balance of the step tests. Starting there (plus a few generic
starts) keeps the least-squares fits away from the parameter defaults, which
for the virtual rig happen to be the truth.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from pneumafit.campaign.model import Recording
from pneumafit.errors import PneumafitInputError
from pneumafit.models.parts import FRICTION_LAWS, HEAT_LAWS
from pneumafit.physics.air import G0, RHO0, T_REF
from pneumafit.physics.geometry import piston_areas

__all__ = ["friction_starts", "heat_starts", "seal_start", "seal_starts", "valve_starts"]


def valve_starts(flows: Sequence[Recording], rig: Mapping[str, float]) -> list[dict[str, float]]:
    """Starts of the servo-distributor characteristic from flow tests.

    Full-opening conductances from the largest inflow (supply path, choked
    at low chamber pressure) and outflow (exhaust path, choked at high
    pressure), ISO 6358 q = C rho0 P_up sqrt(T_ref / T); the centre leakage
    from the flow at the smallest command; generic critical ratio, index,
    dead band and leakage width. Two starts differ in b and m.
    """
    p_s = rig["supply_pressure"]
    t_a = rig["ambient_temperature"]
    rt = math.sqrt(T_REF / t_a)
    c_s, c_e, leak = [], [], []
    for rec in flows:
        ch = rec.chamber
        u = rec.channels[f"u_{ch}"]
        p = rec.channels[f"p_{ch}"]
        q = rec.channels[f"qm_{ch}"]
        top = u >= 0.9 * u.max() if u.max() > 0 else np.zeros(u.size, bool)
        bottom = u <= 0.9 * u.min() if u.min() < 0 else np.zeros(u.size, bool)
        if top.any():
            c_s.append(float(np.max(q[top])) / (RHO0 * p_s * rt))
        if bottom.any():
            c_e.append(float(np.max(-q[bottom] / (RHO0 * p[bottom] * rt))))
        small = np.abs(u) <= np.min(np.abs(u)) + 1e-9
        if small.any():
            leak.append(float(np.median(np.abs(q[small]))) / (RHO0 * p_s * rt) * 2.0)
    cs = float(np.clip(max(c_s) if c_s else 1e-8, 1e-11, 1e-6))
    ce = float(np.clip(max(c_e) if c_e else cs, 1e-11, 1e-6))
    cl = float(np.clip(max(leak) if leak else 1e-3 * cs, 1e-14, 1e-9))
    common = {"valve_C_supply": cs, "valve_C_exhaust": ce, "valve_C_leak": cl,
              "valve_overlap": 0.5, "valve_leak_width": 1.0, "valve_n_supply": 1.0,
              "valve_n_exhaust": 1.0, "valve_full_supply": 1.0,
              "valve_full_exhaust": 1.0, "valve_null_offset": 0.0, "valve_knee_supply": 1.0,
              "valve_knee_exhaust": 1.0}  # fmt: skip
    return [
        {**common, "valve_b_supply": 0.4, "valve_b_exhaust": 0.4, "valve_m": 0.5},
        {**common, "valve_b_supply": 0.2, "valve_b_exhaust": 0.2, "valve_m": 0.7},
    ]


def heat_starts(heat: str) -> list[dict[str, float]]:
    """Textbook starts of the heat law (physics notes): its part's ``starts``.

    Convection: laminar (xi 0.59, beta 1/4) and turbulent (0.10, 1/3) free
    convection and one in between; constant lambda: 5, 15 and 40 W/m^2/K;
    polytropic: k = 1.05, 1.2, 1.35 (:mod:`pneumafit.models.parts.laws`).

    Raises
    ------
    ValueError
        ``heat`` is not a registered heat law.
    """
    law = HEAT_LAWS.get(heat)
    if law is None:
        raise PneumafitInputError(f"heat law: expected one of {sorted(HEAT_LAWS)}, found {heat!r}")
    return [dict(start) for start in law.starts]


def friction_starts(
    steps: Sequence[Recording], rig: Mapping[str, float], law: str = "switch"
) -> list[dict[str, float]]:
    """Friction starts from the force balance of step tests, plus a generic one.

    For the LuGre law (``law="lugre"``) each start also gets a bristle
    stiffness sigma0 (N/m; 2e5 for the data start, 1e6 for the generic one:
    seals hold 0.05-0.5 mm of pre-sliding at breakaway) and a bristle damping
    sigma1 = 2 zeta sqrt(sigma0 M) with zeta = 0.3 (N s/m; LuGre's
    pre-sliding oscillation lightly damped, Canudas de Wit et al. 1995).

    Drive force F_d = S_P P_P - S_N P_N - P_atm (S_P - S_N) - F_ext - M g
    sin(angle); velocity and acceleration from a Savitzky-Golay filter of
    the position. On sliding samples (|v| > 20 mm/s) F_d - M a = sign(v)
    (F_c + b |v|) gives the Coulomb and viscous terms by linear least
    squares; while the piston is stuck |F_d| stays below F_s, so the 99th
    percentile of |F_d| on stuck samples is a lower estimate of F_s.
    """
    m = rig["moving_mass"]
    rows_v, rows_f, stuck = [], [], []
    for _ch, v, a, f_d in _force_balance(steps, rig):
        slide = np.abs(v) > 0.02
        rows_v.append(v[slide])
        rows_f.append((f_d - m * a)[slide])
        stuck.append(np.abs(f_d[np.abs(v) < 1e-4]))
    generic = {"friction_static": 40.0, "friction_coulomb": 20.0, "friction_viscous": 50.0,
               "stribeck_velocity": 0.01}  # fmt: skip
    if law == "lugre":
        generic |= _bristle_start(1.0e6, m)
    if not rows_v:
        return _for_law([generic], law)
    v = np.concatenate(rows_v)
    f = np.concatenate(rows_f) * np.sign(v)
    if v.size < 10:
        return _for_law([generic], law)
    design = np.stack([np.ones(v.size), np.abs(v)], axis=1)
    (f_c, b), *_ = np.linalg.lstsq(design, f, rcond=None)
    f_c = float(np.clip(f_c, 0.5, 5e3))
    b = float(np.clip(b, 0.5, 5e4))
    st = np.concatenate(stuck) if stuck else np.zeros(0)
    f_s = float(np.percentile(st, 99)) if st.size > 10 else 1.5 * f_c
    f_s = max(f_s, 1.1 * f_c)
    data = {"friction_static": f_s, "friction_coulomb": f_c, "friction_viscous": b,
            "stribeck_velocity": 0.01}  # fmt: skip
    if law == "lugre":
        data |= _bristle_start(2.0e5, m)
    return _for_law([data, generic], law)


def _for_law(starts: list[dict[str, float]], law: str) -> list[dict[str, float]]:
    """The starts as a law registered from outside takes them: the levels it
    shares with the switch model, each start once with every one of the
    law's own starts (``FrictionLaw.starts``) laid over it. The built-in laws
    take them as they are."""
    if law in ("switch", "lugre"):
        return starts
    part = FRICTION_LAWS.get(law)
    if part is None:
        raise PneumafitInputError(
            f"friction law: expected one of {sorted(FRICTION_LAWS)}, found {law!r}"
        )
    shared = [{n: v for n, v in start.items() if n in part.parameters} for start in starts]
    own = [dict(s) for s in part.starts] or [{}]
    return [base | extra for base in shared for extra in own]


#: Static-over-Coulomb ratios and Stribeck velocities (m/s) of the screened
#: friction starts (:func:`stribeck_candidates`): bumps 1.4-2.4x the Coulomb
#: level decaying over 5 or 20 mm/s, within the range reported for
#: pneumatic seals (Armstrong-Helouvry et al. 1994). Six candidates cost
#: 5-9 s per friction law on the demo plan. A 4 x 4 grid (1.3-2.5x,
#: 3-50 mm/s) gave the same optima on the recovery matrix's power-valve,
#: lugre-pressure and dahl-bump-leak cases (seeds 1-3) for 940 s of fitting
#: in all against 838 s (before the screen: 638 s).
STRIBECK_RATIOS = (1.4, 1.8, 2.4)
STRIBECK_VELOCITIES = (0.005, 0.02)


def stribeck_candidates(start: Mapping[str, float]) -> list[dict[str, float]]:
    """Friction starts with a Stribeck bump, to be screened (one evaluation each).

    The data start of :func:`friction_starts` puts the static level at the
    99th percentile of the drive force on stuck samples. In closed-loop step
    tests the piston rarely rests near breakaway, so that start sits barely
    above the Coulomb level; from there the bump collapses onto the Coulomb
    level, where the Stribeck velocity has no gradient, and the fit stays in
    that basin (independently written LuGre rig, truth F_s = 1.6 F_c: the
    fit held F_s = F_c, step-test position 1 mm RMS against 0.1 mm from a
    bump start). Each candidate is ``start`` with F_s = r F_c and
    v_s = v for r in :data:`STRIBECK_RATIOS`, v in
    :data:`STRIBECK_VELOCITIES`.
    """
    f_c = float(start["friction_coulomb"])
    return [
        {**start, "friction_static": r * f_c, "stribeck_velocity": v}
        for r in STRIBECK_RATIOS
        for v in STRIBECK_VELOCITIES
    ]


def seal_start(steps: Sequence[Recording], rig: Mapping[str, float]) -> float:
    """Start of the seal-friction coefficient (N/Pa) from the force balance of step tests.

    The seal friction of :data:`~pneumafit.models.structure.EFFECT_SLOTS`
    ``seal_friction`` adds c (P_P + P_N - 2 P_atm) to the friction levels.
    On sliding samples (as in :func:`friction_starts`) sign(v) (F_d - M a) =
    F_c + c (P_P + P_N - 2 P_atm) + b |v| gives c by linear least squares
    with F_c and b; clipped to [0, 1e-4] (at 1e-4 N/Pa a 25-mm piston would
    double its friction every 0.1 bar). 0.0 without sliding samples.
    """
    m = rig["moving_mass"]
    p_e = rig["exhaust_pressure"]
    rows: list[NDArray[np.float64]] = []
    for ch, v, a, f_d in _force_balance(steps, rig):
        slide = np.abs(v) > 0.02
        dp = ch["p_P"] + ch["p_N"] - 2.0 * p_e
        rows.append(
            np.stack([np.sign(v) * (f_d - m * a), np.ones(v.size), dp, np.abs(v)], axis=1)[slide]
        )
    if not rows:
        return 0.0
    x = np.concatenate(rows)
    if x.shape[0] < 10:
        return 0.0
    coef, *_ = np.linalg.lstsq(x[:, 1:], x[:, 0], rcond=None)
    return float(np.clip(coef[1], 0.0, 1e-4))


#: Seal-friction coefficient (N/Pa) of the nested start of :func:`seal_starts`:
#: 6e-4 N at a pressure sum of 6 bar, a thousandth of a typical static level,
#: so that start is the fit without the effect to within its noise.
SEAL_NESTED = 1.0e-9

#: The friction levels that the seal friction's c (P_P + P_N - 2 P_atm) adds to.
SEAL_LEVELS = ("friction_static", "friction_coulomb")


def seal_starts(
    steps: Sequence[Recording],
    rig: Mapping[str, float],
    values: Mapping[str, float],
    name: str = "seal_friction_coefficient",
) -> list[dict[str, float]]:
    """Starts of the friction fit with the seal friction, from the fit without it.

    Two starts. First the nested one: the friction fit without the effect
    (``values``) with the coefficient at :data:`SEAL_NESTED`, so that the
    fit with the effect ends at least as high as the one without it (a least
    squares started only from the force balance's coefficient, with the
    levels of the fit without it, ended 1205 in log-likelihood *below* it on
    a LuGre truth whose friction grows with the pressures, and the effect
    was rejected on a negative gain). Then the force balance's coefficient
    c0 (:func:`seal_start`) with the static and Coulomb levels lowered by
    c0 times the step tests' mean pressure sum (P_P + P_N - 2 P_atm over
    their samples), so that the friction at the tests' mean pressures is
    that of the fit without the effect. The second start is left out when
    c0 is 0 (no sliding samples) or the tests have no pressures.

    Parameters
    ----------
    steps : sequence of Recording
        The fit step tests.
    rig : mapping of str to float
        Rig parameters (SI): ``exhaust_pressure`` (Pa) among them.
    values : mapping of str to float
        The fit without the effect (SI), friction levels (N) included.
    name : str
        The coefficient's parameter name (N/Pa).

    Returns
    -------
    list of dict of str to float
    """
    starts = [{**values, name: SEAL_NESTED}]
    c0 = seal_start(steps, rig)
    p_e = rig["exhaust_pressure"]
    sums = [
        np.asarray(r.channels["p_P"]) + np.asarray(r.channels["p_N"]) - 2.0 * p_e
        for r in steps if "p_P" in r.channels and "p_N" in r.channels
    ]  # fmt: skip
    if c0 <= SEAL_NESTED or not sums:
        return starts
    shift = c0 * max(float(np.nanmean(np.concatenate(sums))), 0.0)
    lowered = {k: max(values[k] - shift, 0.1 * values[k]) for k in SEAL_LEVELS if k in values}
    starts.append({**values, **lowered, name: c0})
    return starts


def _force_balance(
    steps: Sequence[Recording], rig: Mapping[str, float]
) -> Iterator[
    tuple[
        Mapping[str, NDArray[np.float64]],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
    ]
]:
    """Per step test with position and both pressures: its channels, the velocity
    and acceleration (quadratic Savitzky-Golay over ~21 ms, m/s and m/s^2) and
    the drive force F_d = S_P P_P - S_N P_N - P_atm (S_P - S_N) - F_ext - M g
    sin(angle) (N). Recordings shorter than the filter window are skipped."""
    s_p, s_n = piston_areas(rig["bore"], rig["rod"])
    m = rig["moving_mass"]
    f_ext = (
        rig["exhaust_pressure"] * (s_p - s_n)
        + rig.get("external_force", 0.0)
        + m * G0 * math.sin(rig.get("mounting_angle", 0.0))
    )
    for rec in steps:
        ch = rec.channels
        if not all(k in ch for k in ("y", "p_P", "p_N")):
            continue
        dt = float(np.median(np.diff(rec.time)))
        win = max(5, round(0.021 / dt) | 1)
        if rec.n_samples <= win:
            continue
        v = savgol_filter(ch["y"], win, 2, deriv=1, delta=dt)
        a = savgol_filter(ch["y"], win, 2, deriv=2, delta=dt)
        yield ch, v, a, s_p * ch["p_P"] - s_n * ch["p_N"] - f_ext


def _bristle_start(sigma0: float, mass: float, zeta: float = 0.3) -> dict[str, float]:
    """LuGre bristle start: stiffness sigma0 (N/m) and damping 2 zeta sqrt(sigma0 M) (N s/m)."""
    return {"friction_stiffness": sigma0, "friction_damping": 2.0 * zeta * math.sqrt(sigma0 * mass)}
