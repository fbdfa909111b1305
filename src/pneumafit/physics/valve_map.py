"""Measured (non-parametric) valve map: a second servo-valve law.

The ISO 6358 law of :mod:`pneumafit.physics.valve` prescribes how the sonic
conductances grow with the command (a linear ramp past the overlap, a
sigmoid centre leakage). Real servo-valves do not follow that ramp. The map
law keeps the ISO 6358 restriction of each path (flow function phi with the
same subsonic index m and laminar tail above x_l, see
:mod:`pneumafit.physics.valve`) and replaces the command dependence by
measured tables.

Conductances. Knots at fixed fractions of the full-opening command u_sat,

    u_k = f_k u_sat,   f = (-1, -0.7, -0.4, -0.2, -0.1, -0.05, -0.025, 0,
                            0.025, 0.05, 0.1, 0.2, 0.4, 0.7, 1)

(:data:`MAP_KNOTS`; with u_sat = 10 V: 0, +-0.25, +-0.5, +-1, +-2, +-4, +-7,
+-10 V), dense near the centre where leakage and overlap live. Each path has
one sonic conductance per knot (m^3/s/Pa), ``valve_map_CS_00..14`` (supply)
and ``valve_map_CE_00..14`` (exhaust); the values at u = 0 (knot 7) are the
centre leakages of the two paths and may differ.

- Monotonicity is enforced, not assumed: C_S is replaced by its running
  maximum from the most negative knot upwards and C_E by its running maximum
  from the most positive knot downwards, so any parameter vector (a sampler's
  proposal, a noisy measurement) gives C_S non-decreasing and C_E
  non-increasing in u.
- Between knots, log C is interpolated by the monotone piecewise-cubic Hermite
  interpolant of Fritsch and Carlson (PCHIP): interior slopes are the
  weighted harmonic mean of the adjacent secant slopes (zero where they
  change sign or vanish), so the interpolant never overshoots the data and
  stays monotone. Interpolating log C rather than C follows the four decades
  between the centre leakage and full opening without a cubic undershooting
  below zero, and gives C = exp(...) > 0 by construction.
- Beyond +-u_sat C is constant (the spool is at its stop). The end slopes
  are zero, so C(u) is continuously differentiable (C^1) everywhere,
  including at +-u_sat. C^1 matters twice: a kink in C(u) costs the
  fixed-step Runge-Kutta integrator two orders of accuracy each time a
  command crosses it (the ISO law's unrounded dead-band corner gave 1.2 Pa
  instead of 0.05 Pa at 0.5 ms on a charge test, see
  :mod:`pneumafit.physics.valve`), and it makes the likelihood non-smooth in
  the parameters, which gradient-based optimisers and Laplace approximations
  see.
- Evaluation keeps C exact at the knots: C = C_k exp(t (a_1 + t (a_2 +
  t a_3))) on [u_k, u_k+1], t = (u - u_k) / (u_k+1 - u_k), with the cubic's
  coefficients (from the PCHIP slopes, per interval and path) computed once
  per simulation (:func:`map_constants`): one knot search and one exp per
  path per evaluation.

Critical ratios. b of each path varies with the opening: ``valve_map_bS_0,
_1, _2`` at u / u_sat = 0, 0.3, 1 on the opening side of the supply path
(u >= 0; the value at 0 holds for u < 0, constant beyond u_sat), linear in
between; ``valve_map_bE_0..2`` likewise for the exhaust path with -u. b(u)
is continuous but, being piecewise linear, has corners at the b knots (none
when the three values are equal, as from :func:`map_from_iso`). The laminar
tail's coefficients (a, c) depend on b, so they are computed per evaluation
from b (only when x >= x_l, where the tail is used), not tabulated: exact, so
phi and its slope stay continuous at x_l for every b.

The default map (:data:`pneumafit.models.layout.PARAMETER_SPECS`) holds the
knot values of the default ISO valve; :func:`map_from_iso` samples any ISO
parameter set. At the knots the map reproduces the ISO flows to rounding;
between knots it is a smooth version of the ISO ramp (it rounds the ISO
law's corners at the overlap and at u_sat).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from pneumafit.errors import PneumafitInputError
from pneumafit.numba_stamp import njit
from pneumafit.physics.air import RHO0
from pneumafit.physics.friction import FASTMATH
from pneumafit.physics.valve import (
    VC_IPE,
    VC_M,
    VC_PE,
    VC_RTA,
    VC_TA,
    VC_XLAM,
    conductances,
    flow_function,
)

#: Knot positions as fractions of ``valve_u_sat`` (-).
MAP_KNOTS: tuple[float, ...] = (
    -1.0, -0.7, -0.4, -0.2, -0.1, -0.05, -0.025, 0.0, 0.025, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0,
)  # fmt: skip
#: Number of conductance knots per path.
N_KNOTS = len(MAP_KNOTS)
#: Index of the centre knot (u = 0).
CENTRE_KNOT = MAP_KNOTS.index(0.0)
#: Opening fractions |u| / u_sat of the critical-ratio knots (-).
MAP_B_FRACTIONS: tuple[float, float, float] = (0.0, 0.3, 1.0)
#: Parameter names of the knot values, supply and exhaust paths.
MAP_CS_NAMES: tuple[str, ...] = tuple(f"valve_map_CS_{i:02d}" for i in range(N_KNOTS))
MAP_CE_NAMES: tuple[str, ...] = tuple(f"valve_map_CE_{i:02d}" for i in range(N_KNOTS))
MAP_BS_NAMES: tuple[str, ...] = tuple(f"valve_map_bS_{i}" for i in range(3))
MAP_BE_NAMES: tuple[str, ...] = tuple(f"valve_map_bE_{i}" for i in range(3))
#: All map parameter names, in parameter-vector order.
MAP_PARAMETER_NAMES: tuple[str, ...] = MAP_CS_NAMES + MAP_CE_NAMES + MAP_BS_NAMES + MAP_BE_NAMES
#: Bounds of a knot conductance (m^3/s/Pa): positive, for the logarithm.
MAP_C_BOUNDS = (1.0e-15, 1.0e-5)

_KNOTS = np.array(MAP_KNOTS)
_B1 = MAP_B_FRACTIONS[1]
_FLOOR = 1e-300  # keeps log() finite for inadmissible input (check_parameters rejects it)

# Layout of the map constants array (length NVM), filled by map_constants()
VM_IUSAT = 0  # 1 / u_sat (1/V)
VM_CS_LO, VM_CS_HI, VM_CE_LO, VM_CE_HI = 1, 2, 3, 4  # C at u <= -u_sat, u >= u_sat
VM_BS, VM_BE = 5, 8  # three critical-ratio knots per path
VM_DBS, VM_DBE = 11, 13  # slopes d b / d(u / u_sat) on [0, 0.3] and [0.3, 1]
VM_U = 15  # knot positions u_k (V), N_KNOTS of them
VM_IH = VM_U + N_KNOTS  # 1 / (u_k+1 - u_k) (1/V), N_KNOTS - 1
VM_CK_S = VM_IH + N_KNOTS - 1  # knot conductances after the running maximum, supply
VM_CK_E = VM_CK_S + N_KNOTS  # exhaust
VM_COEF_S = VM_CK_E + N_KNOTS  # per interval a_1, a_2, a_3 of log C, supply
VM_COEF_E = VM_COEF_S + 3 * (N_KNOTS - 1)  # exhaust
NVM = VM_COEF_E + 3 * (N_KNOTS - 1)


@njit(cache=True)
def pchip_slopes(x: np.ndarray, y: np.ndarray, slopes: np.ndarray) -> None:
    """Fritsch-Carlson (PCHIP) slopes of monotone data, zero at both ends.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Strictly increasing abscissae.
    y : ndarray, shape (n,)
        Ordinates, monotone (non-decreasing or non-increasing).
    slopes : ndarray, shape (n,)
        Output: dy/dx at each knot. Interior slopes are the weighted harmonic
        mean of the adjacent secants (w_1 = 2 h_k + h_k-1, w_2 = h_k +
        2 h_k-1, as scipy's ``PchipInterpolator``), zero where a secant is
        zero or they differ in sign; end slopes are zero (the law is
        constant beyond the end knots, so the zero slope makes it C^1).
    """
    n = x.shape[0]
    slopes[0] = 0.0
    slopes[n - 1] = 0.0
    for k in range(1, n - 1):
        h0 = x[k] - x[k - 1]
        h1 = x[k + 1] - x[k]
        d0 = (y[k] - y[k - 1]) / h0
        d1 = (y[k + 1] - y[k]) / h1
        if d0 * d1 <= 0.0:
            slopes[k] = 0.0
        else:
            w1 = 2.0 * h1 + h0
            w2 = h1 + 2.0 * h0
            slopes[k] = (w1 + w2) / (w1 / d0 + w2 / d1)


@njit(cache=True)
def _fill_path(
    u: np.ndarray, c: np.ndarray, vm: np.ndarray, ck: int, coef: int, slopes: np.ndarray
) -> None:
    # log C, PCHIP slopes, per-interval cubic of log(C / C_k) in local t
    n = u.shape[0]
    logc = np.empty(n)
    for k in range(n):
        vm[ck + k] = c[k]
        logc[k] = math.log(c[k])
    pchip_slopes(u, logc, slopes)
    for k in range(n - 1):
        h = u[k + 1] - u[k]
        delta = logc[k + 1] - logc[k]
        m0 = h * slopes[k]
        m1 = h * slopes[k + 1]
        j = coef + 3 * k
        vm[j] = m0
        vm[j + 1] = 3.0 * delta - 2.0 * m0 - m1
        vm[j + 2] = m0 + m1 - 2.0 * delta


@njit(cache=True)
def map_constants(
    c_supply: np.ndarray,
    c_exhaust: np.ndarray,
    b_supply: np.ndarray,
    b_exhaust: np.ndarray,
    u_sat: float,
    vm: np.ndarray,
) -> None:
    """Fill ``vm`` (length NVM) with the constants of :func:`flows_core_map`.

    Parameters
    ----------
    c_supply, c_exhaust : ndarray, shape (N_KNOTS,)
        Sonic conductances (m^3/s/Pa) of the supply and exhaust paths at the
        knots u_k = MAP_KNOTS[k] u_sat, as given (made monotone here by a
        running maximum: upwards for the supply, downwards for the exhaust).
    b_supply, b_exhaust : ndarray, shape (3,)
        Critical ratios (-) at opening fractions MAP_B_FRACTIONS.
    u_sat : float
        Command of full opening (V), > 0.
    vm : ndarray, shape (NVM,)
        Output.
    """
    n = N_KNOTS
    u = np.empty(n)
    cs = np.empty(n)
    ce = np.empty(n)
    for k in range(n):
        u[k] = _KNOTS[k] * u_sat
        cs[k] = c_supply[k] if c_supply[k] > _FLOOR else _FLOOR
        ce[k] = c_exhaust[k] if c_exhaust[k] > _FLOOR else _FLOOR
    for k in range(1, n):  # supply: non-decreasing in u
        if cs[k] < cs[k - 1]:
            cs[k] = cs[k - 1]
    for k in range(n - 2, -1, -1):  # exhaust: non-increasing in u
        if ce[k] < ce[k + 1]:
            ce[k] = ce[k + 1]
    vm[VM_IUSAT] = 1.0 / u_sat
    vm[VM_CS_LO] = cs[0]
    vm[VM_CS_HI] = cs[n - 1]
    vm[VM_CE_LO] = ce[0]
    vm[VM_CE_HI] = ce[n - 1]
    for i in range(3):
        vm[VM_BS + i] = b_supply[i]
        vm[VM_BE + i] = b_exhaust[i]
    vm[VM_DBS] = (b_supply[1] - b_supply[0]) / _B1
    vm[VM_DBS + 1] = (b_supply[2] - b_supply[1]) / (1.0 - _B1)
    vm[VM_DBE] = (b_exhaust[1] - b_exhaust[0]) / _B1
    vm[VM_DBE + 1] = (b_exhaust[2] - b_exhaust[1]) / (1.0 - _B1)
    for k in range(n):
        vm[VM_U + k] = u[k]
    for k in range(n - 1):
        vm[VM_IH + k] = 1.0 / (u[k + 1] - u[k])
    slopes = np.empty(n)
    _fill_path(u, cs, vm, VM_CK_S, VM_COEF_S, slopes)
    _fill_path(u, ce, vm, VM_CK_E, VM_COEF_E, slopes)


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def map_conductances(u: float, vm: np.ndarray) -> tuple[float, float]:
    """Sonic conductances (C_S(u), C_E(u)) (m^3/s/Pa) from the map constants.

    One knot search (from the centre outwards, at most 7 comparisons) and one
    exp per path.
    """
    if u <= vm[VM_U]:
        return vm[VM_CS_LO], vm[VM_CE_LO]
    if u >= vm[VM_U + N_KNOTS - 1]:
        return vm[VM_CS_HI], vm[VM_CE_HI]
    k = CENTRE_KNOT
    if u >= 0.0:
        while u >= vm[VM_U + k + 1]:
            k += 1
    else:
        k -= 1
        while u < vm[VM_U + k]:
            k -= 1
    t = (u - vm[VM_U + k]) * vm[VM_IH + k]
    j = VM_COEF_S + 3 * k
    c_s = vm[VM_CK_S + k] * math.exp(t * (vm[j] + t * (vm[j + 1] + t * vm[j + 2])))
    j = VM_COEF_E + 3 * k
    c_e = vm[VM_CK_E + k] * math.exp(t * (vm[j] + t * (vm[j + 1] + t * vm[j + 2])))
    return c_s, c_e


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def _ratio(f: float, vm: np.ndarray, i0: int, di: int) -> float:
    # piecewise-linear b over the opening fraction f (b_0 for f <= 0)
    if f <= 0.0:
        return vm[i0]
    if f < _B1:
        return vm[i0] + f * vm[di]
    if f < 1.0:
        return vm[i0 + 1] + (f - _B1) * vm[di + 1]
    return vm[i0 + 2]


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def map_critical_ratios(u: float, vm: np.ndarray) -> tuple[float, float]:
    """Critical ratios (b_S(u), b_E(u)) (-) from the map constants."""
    f = u * vm[VM_IUSAT]
    return _ratio(f, vm, VM_BS, VM_DBS), _ratio(-f, vm, VM_BE, VM_DBE)


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def flows_core_map(
    u: float,
    pres: float,
    inv_pres: float,
    temp: float,
    rt: float,
    p_supply: float,
    inv_p_supply: float,
    vc: np.ndarray,
    vm: np.ndarray,
) -> tuple[float, float, float]:
    """Flows of one 3-way valve into its chamber under the map law.

    Same arguments and results as :func:`pneumafit.physics.valve.flows_core`
    (``vc`` supplies m, x_l, the exhaust pressure and the ambient
    temperature), plus ``vm`` from :func:`map_constants` for C_S(u), C_E(u)
    and b_S(u), b_E(u).
    """
    c_s, c_e = map_conductances(u, vm)
    b_s, b_e = map_critical_ratios(u, vm)
    m = vc[VC_M]
    x_lam = vc[VC_XLAM]
    k = RHO0
    # supply path, supply -> chamber
    if p_supply >= pres:
        q_s = c_s * k * p_supply * vc[VC_RTA] * flow_function(pres * inv_p_supply, b_s, m, x_lam)
        t_s = vc[VC_TA]
    else:
        q_s = -c_s * k * pres * rt * flow_function(p_supply * inv_pres, b_s, m, x_lam)
        t_s = temp
    # exhaust path, chamber -> exhaust
    p_e = vc[VC_PE]
    if pres >= p_e:
        q_e = c_e * k * pres * rt * flow_function(p_e * inv_pres, b_e, m, x_lam)
        t_e = temp
    else:
        q_e = -c_e * k * p_e * vc[VC_RTA] * flow_function(pres * vc[VC_IPE], b_e, m, x_lam)
        t_e = vc[VC_TA]
    return q_s - q_e, q_s * t_s - q_e * t_e, q_s


_ISO_KEYS = (
    "valve_C_supply", "valve_b_supply", "valve_C_exhaust", "valve_b_exhaust", "valve_overlap",
    "valve_u_sat", "valve_C_leak", "valve_leak_width",
)  # fmt: skip


def sample_iso(
    c_supply: float,
    b_supply: float,
    c_exhaust: float,
    b_exhaust: float,
    overlap: float,
    u_sat: float,
    c_leak: float,
    leak_width: float,
    n_supply: float = 1.0,
    n_exhaust: float = 1.0,
    full_supply: float = 1.0,
    full_exhaust: float = 1.0,
    null_offset: float = 0.0,
    knee_supply: float = 1.0,
    knee_exhaust: float = 1.0,
) -> tuple[list[float], list[float]]:
    """Knot conductances of an ISO 6358 valve (see :func:`map_from_iso`).

    Returns
    -------
    c_s, c_e : list of float
        C_S(u_k), C_E(u_k) (m^3/s/Pa) at u_k = MAP_KNOTS[k] u_sat, raised to
        the lower bound MAP_C_BOUNDS[0] (an ISO valve without leakage has
        C = 0 on its closed side, which has no logarithm).
    """
    del b_supply, b_exhaust  # the ratios do not depend on u in the ISO law
    lo = MAP_C_BOUNDS[0]
    c_s, c_e = [], []
    for f in MAP_KNOTS:
        cs, ce = conductances.py_func(f * u_sat, c_supply, c_exhaust, overlap, u_sat, c_leak,
                                      leak_width, n_supply, n_exhaust, full_supply,
                                      full_exhaust, null_offset, knee_supply,
                                      knee_exhaust)  # fmt: skip
        c_s.append(max(float(cs), lo))
        c_e.append(max(float(ce), lo))
    return c_s, c_e


def map_from_iso(values: Mapping[str, float]) -> dict[str, float]:
    """Map parameters that sample an ISO 6358 valve at the knots.

    Parameters
    ----------
    values : mapping of str to float
        ISO valve parameters by canonical name (SI): ``valve_C_supply``,
        ``valve_b_supply``, ``valve_C_exhaust``, ``valve_b_exhaust``,
        ``valve_overlap``, ``valve_u_sat``, ``valve_C_leak``,
        ``valve_leak_width``; other names (e.g. a whole parameter set) are
        ignored.

    Returns
    -------
    dict of str to float
        ``valve_map_CS_00..14`` and ``valve_map_CE_00..14`` = C_S(u_k),
        C_E(u_k) of the ISO law (m^3/s/Pa, at least 1e-15), and
        ``valve_map_bS_0..2``, ``valve_map_bE_0..2`` = the ISO critical ratios.
        Use them with the same ``valve_u_sat`` (the knots scale with it);
        ``valve_m`` and ``valve_x_laminar`` are shared by both laws.

    Raises
    ------
    PneumafitInputError
        When one of the ISO names is missing.
    """
    missing = [k for k in _ISO_KEYS if k not in values]
    if missing:
        raise PneumafitInputError(
            f"map_from_iso: expected the ISO valve parameters {list(_ISO_KEYS)}, "
            f"found none for {missing}"
        )
    iso = {k: float(values[k]) for k in _ISO_KEYS}
    shape = (
        *(float(values.get(n, 1.0)) for n in
          ("valve_n_supply", "valve_n_exhaust", "valve_full_supply", "valve_full_exhaust")),
        float(values.get("valve_null_offset", 0.0)),
        *(float(values.get(n, 1.0)) for n in ("valve_knee_supply", "valve_knee_exhaust")),
    )  # fmt: skip
    c_s, c_e = sample_iso(*iso.values(), *shape)
    out = dict(zip(MAP_CS_NAMES, c_s, strict=True))
    out.update(zip(MAP_CE_NAMES, c_e, strict=True))
    out.update({n: iso["valve_b_supply"] for n in MAP_BS_NAMES})
    out.update({n: iso["valve_b_exhaust"] for n in MAP_BE_NAMES})
    return out


#: Prior scale of one second difference of ln C between neighbouring knots
#: (-): the map's smoothness prior (:func:`map_roughness`). Measured curves
#: bend by 0.2-0.4 per knot over their opening range (the catalogue-table
#: valve of the virtual rig's ``table-valve-asym`` truth, sampled at the
#: knots) and by up to ~3.4 once, at the dead-band edge where the opening
#: takes over from the centre leak; a scale of 1 costs that edge ~8 in
#: log-posterior, nothing against the thousands a flow or charge test
#: carries, and holds a knot no recording informs near the smooth line
#: through its neighbours (within a factor e ~ 2.7 at one standard deviation).
MAP_SMOOTHNESS_SCALE = 1.0

#: Knot index triples (k - 1, k, k + 1) of the smoothness prior, per path:
#: the opening side and the centre (u >= 0 for the supply path, u <= 0 for
#: the exhaust path). The closed side carries less than the centre leakage,
#: is cut off by the running maximum (:func:`map_constants`), and is not
#: fitted; it has no smoothness to keep.
_SMOOTH_S = tuple((k - 1, k, k + 1) for k in range(CENTRE_KNOT + 1, N_KNOTS - 1))
_SMOOTH_E = tuple((k - 1, k, k + 1) for k in range(1, CENTRE_KNOT))


def map_roughness(values: Mapping[str, object]) -> NDArray[np.float64]:
    """Whitened residuals of the map's smoothness prior.

    A Gaussian prior on the second differences of ln C over the knot index,
    per path on its opening side and centre (:data:`_SMOOTH_S`,
    :data:`_SMOOTH_E`): r = (ln C_k-1 - 2 ln C_k + ln C_k+1) / s, s =
    :data:`MAP_SMOOTHNESS_SCALE`. The knots are nearly geometric in u from
    2.5 % to 40 % of u_sat, so a power-law opening C ~ u^n is a straight line
    in these coordinates and costs nothing. The prior is improper (a
    straight line in ln C has zero roughness at any level and slope); the
    data set those. Its log density is -sum(r^2) / 2.

    Parameters
    ----------
    values : mapping of str to float or ndarray (n,)
        Knot conductances ``valve_map_CS_00..14``, ``valve_map_CE_00..14``
        (m^3/s/Pa), scalars or one value per parameter set.

    Returns
    -------
    ndarray (n, n_terms)
        One row per parameter set (n = 1 for scalars).
    """
    cs = np.log([np.atleast_1d(np.asarray(values[n], float)) for n in MAP_CS_NAMES])
    ce = np.log([np.atleast_1d(np.asarray(values[n], float)) for n in MAP_CE_NAMES])
    terms = [cs[a] - 2.0 * cs[b] + cs[c] for a, b, c in _SMOOTH_S]
    terms += [ce[a] - 2.0 * ce[b] + ce[c] for a, b, c in _SMOOTH_E]
    return np.asarray(terms).T / MAP_SMOOTHNESS_SCALE
