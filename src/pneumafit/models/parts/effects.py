"""The built-in optional effects: slot, parameters, law, rig default, discovery facts.

Each :class:`~pneumafit.models.parts.Effect` here is read by the structure's
``EFFECT_SLOTS``, the virtual rig's ``PRINCIPAL_PARAMETERS`` and
``EFFECT_DEFAULTS``, the discovery catalog (:mod:`pneumafit.discovery.catalog`)
and attribution's coefficient units and refit starts. The three seal and
barrel effects take their law, parameter, bounds, prior and typical size from
:mod:`pneumafit.physics.seal_effects`, which the friction-test bench shares.

The rig defaults are chosen so that each effect is clearly visible in the
pressures of the demo protocol (largest change against the truth without it,
pressure noise 400 Pa): chamber/external leakage 91 kPa in ``charge_P_1``,
valve lag 122 kPa, wall thermal mass 23 kPa, forced convection 20 kPa,
supply-line drop 34 kPa; seal friction 121 kPa and 20 mm in ``step_1``
(docs/virtual-rig.md). The seal and barrel effects take their shared
typical sizes: seal friction 1.5e-5 N/Pa, a friction asymmetry of 0.2
(levels 1.2 and 0.8 times the symmetric ones), an area factor of 1.05 (a
bore 2.5 % larger than nominal). The wall capacity is deliberately small (a
real wall's is thousands of J/K/m^2) so that the effect shows. The other
parameters' typical values are their table defaults.
"""

from __future__ import annotations

from pneumafit.models.layout import (
    C_AREA_FACTOR,
    C_CHAMBER_LEAK,
    C_EXTERNAL_LEAK,
    C_FORCED_CONV,
    C_FRICTION_ASYM,
    C_SEAL_FRICTION,
    C_SUPPLY_DROP,
    C_VALVE_ORDER,
    C_WALL_MASS,
)
from pneumafit.models.parts.registry import Effect, FitRange, SignatureTerm, register_effect
from pneumafit.physics.seal_effects import SEAL_EFFECTS

__all__ = ["seal_effect_part"]

register_effect(
    Effect(
        name="chamber_leakage",
        slot=C_CHAMBER_LEAK,
        parameters=("chamber_leak_conductance",),
        description="laminar leakage between the chambers across the piston seal",
        law=(
            "q_l = G_cl (P_P - P_N)  [kg/s, from P to N across the piston seal];\n"
            "m_P loses q_l and m_N gains it; the enthalpy flow q_l T_up leaves P and enters N,\n"
            "T_up = T_P if q_l > 0 else T_N (laminar: linear in the pressure difference)."
        ),
        principal="chamber_leak_conductance",
        rig_default=5.0e-11,  # kg/s/Pa
        fit=(
            FitRange(
                "chamber_leak_conductance",
                1e-13,
                1e-9,
                "log-uniform",
                description="laminar conductance G_cl of the piston seal",
            ),
        ),
        coefficient_unit="kg/s/Pa",
        signature=(
            SignatureTerm(
                regressor="P_P - P_N",
                enters="dP_P/dt, dP_N/dt",
                note="coefficient -gamma r T_up G_cl / V_P in dP_P/dt and +gamma r T_up G_cl / "
                "V_N in dP_N/dt: opposite signs, volume-weighted (what sets it apart from "
                "external leakage)",
            ),
        ),
        phases=("relaxation", "rest"),
    )
)

register_effect(
    Effect(
        name="external_leakage",
        slot=C_EXTERNAL_LEAK,
        parameters=("external_leak_conductance", "external_leak_split"),
        description="laminar leakage of each chamber to atmosphere, shared 1 + s : 1 - s",
        law=(
            "q_P = G_el (1 + s) (P_P - P_atm), q_N = G_el (1 - s) (P_N - P_atm)  [kg/s, out of\n"
            "each chamber to atmosphere; s = 0: the same conductance, s = -1: only N leaks];\n"
            "an outflow carries T_X, an inflow (P_X < P_atm) T_atm; both count as exhausted air."
        ),
        principal="external_leak_conductance",
        rig_default=5.0e-11,  # kg/s/Pa
        fit=(
            FitRange(
                "external_leak_conductance",
                1e-13,
                1e-9,
                "log-uniform",
                description="laminar conductance G_el of each chamber to atmosphere (mean)",
            ),
            FitRange(
                "external_leak_split",
                -1.0,
                1.0,
                "uniform",
                description="how the chambers share it: G_P = G_el (1 + s), G_N = G_el (1 - s)",
                signed=True,
            ),
        ),
        coefficient_unit="kg/s/Pa",
        signature=(
            SignatureTerm("P_P - P_atm", "dP_P/dt", "coefficient -gamma r T_P G_el (1 + s) / V_P"),
            SignatureTerm("P_N - P_atm", "dP_N/dt", "coefficient -gamma r T_N G_el (1 - s) / V_N"),
        ),
        phases=("relaxation", "rest"),
    )
)

register_effect(
    Effect(
        name="valve_dynamics",
        slot=C_VALVE_ORDER,
        parameters=("valve_time_constant", "valve_natural_frequency", "valve_damping_ratio"),
        description="spool lag: first order (value 1) or second order (value 2)",
        law=(
            "The valve flows see a spool position u_s instead of the command u, per valve:\n"
            "order 1: tau du_s/dt = u - u_s;\n"
            "order 2: d2u_s/dt2 = w_n^2 (u - u_s) - 2 zeta w_n du_s/dt;\n"
            "u_s starts at the first command, at rest."
        ),
        principal="valve_time_constant",
        rig_default=0.015,  # s
        fit=(
            # from one sample of 1-kHz recordings: a shorter lag is not
            # identifiable in them, and the fits' fixed-step solver would need
            # steps below its valve mode's stability limit (identification.
            # problem.valve_lag_floor caps the step at this floor)
            FitRange(
                "valve_time_constant",
                1e-3,
                0.1,
                "log-uniform",
                description="first-order spool time constant tau",
            ),
            FitRange(
                "valve_natural_frequency",
                30.0,
                1e4,
                "log-uniform",
                description="second-order spool natural frequency w_n",
            ),
            FitRange(
                "valve_damping_ratio",
                0.1,
                2.0,
                "log-uniform",
                description="second-order spool damping ratio zeta",
            ),
        ),
        coefficient_unit="s",
        options={
            1: ("valve_time_constant",),
            2: ("valve_natural_frequency", "valve_damping_ratio"),
        },
        signature=(
            SignatureTerm(
                regressor="d/dt [gamma r T_up q_valve(u, P) / V]",
                enters="dP_P/dt, dP_N/dt",
                note="to first order in tau, q(u_s) = q(u) - tau dq/dt: the rate of the static "
                "valve-flow term, coefficient -tau (order 2: tau = 2 zeta / w_n)",
            ),
        ),
        phases=("filling", "emptying", "motion"),
        # the fitting problem integrates with fixed steps up to 4 ms (Kutta
        # RK3, stable for tau > ~1.6 ms): a refit starts from tau >= 2 ms
        start_floor=2.0e-3,
    )
)

register_effect(
    Effect(
        name="wall_thermal_mass",
        slot=C_WALL_MASS,
        parameters=("wall_heat_capacity", "wall_outer_coefficient"),
        description="a wall temperature state per chamber instead of a wall at ambient",
        law=(
            "Per chamber a wall temperature state T_w,X (starting at the wall temperature):\n"
            "C_w dT_w,X/dt = lambda_X (T_X - T_w,X) + h_o (T_atm - T_w,X)  [per unit area];\n"
            "the gas exchanges Q_X = lambda_X A_X (T_w,X - T_X) with it instead of the fixed\n"
            "wall. No effect in the polytropic structure (no wall exchange)."
        ),
        principal="wall_heat_capacity",
        rig_default=100.0,  # J/K/m^2
        fit=(
            FitRange(
                "wall_heat_capacity",
                10.0,
                1e5,
                "log-uniform",
                description="heat capacity C_w of the wall per unit exchange area",
                vanishes_at_upper=True,
            ),
            FitRange(
                "wall_outer_coefficient",
                0.0,
                200.0,
                "half-normal",
                scale=20.0,
                description="wall-to-ambient heat-transfer coefficient h_o",
            ),
        ),
        coefficient_unit="m^2 K/J (1/C_w)",
        signature=(
            SignatureTerm(
                regressor="lambda A (T_wf - T_w0)",
                enters="dP_X/dt, dT_X/dt",
                note="T_wf: the gas temperature low-pass filtered with time constant "
                "C_w / lambda (the wall warming up), T_w0 the fixed wall; coefficient "
                "(gamma - 1) / V_X in dP_X/dt",
            ),
        ),
        phases=("relaxation",),
        inverse_coefficient=True,
    )
)

register_effect(
    Effect(
        name="forced_convection",
        slot=C_FORCED_CONV,
        parameters=("forced_convection_gain",),
        description="filling jet raises lambda in proportion to the inflow",
        law=(
            "lambda_X = lambda_law + K_fc q_s,X while q_s,X > 0, q_s,X the mass flow through\n"
            "the supply path of valve X into chamber X (the filling jet, centre leakage\n"
            "included; kg/s); not in the polytropic structure (no wall exchange)."
        ),
        principal="forced_convection_gain",
        rig_default=2.0e4,  # W/m^2/K per kg/s
        fit=(
            FitRange(
                "forced_convection_gain",
                100.0,
                1e6,
                "log-uniform",
                description="increase K_fc of lambda per unit supply inflow",
            ),
        ),
        coefficient_unit="W/m^2/K/(kg/s)",
        signature=(
            SignatureTerm(
                regressor="max(q_s,X, 0) A_X (T_w - T_X)",
                enters="dP_X/dt, dT_X/dt",
                note="coefficient (gamma - 1) K_fc / V_X in dP_X/dt; non-zero only while filling",
            ),
        ),
        phases=("filling",),
    )
)

register_effect(
    Effect(
        name="supply_pressure_drop",
        slot=C_SUPPLY_DROP,
        parameters=("supply_line_resistance",),
        description="supply pressure drops with the drawn flow (line resistance)",
        law=(
            "P_S' = max(P_S - R (q_s,P + q_s,N)^+, P_atm): the valves see the supply pressure\n"
            "behind a line resistance R, q_s the supply-path flows first evaluated at P_S\n"
            "(one fixed-point iteration); not applied in flow tests (static characteristic)."
        ),
        principal="supply_line_resistance",
        rig_default=6.0e6,  # Pa/(kg/s)
        fit=(
            FitRange(
                "supply_line_resistance",
                1e4,
                1e8,
                "log-uniform",
                description="supply pressure drop R per unit drawn flow",
            ),
        ),
        coefficient_unit="Pa/(kg/s)",
        signature=(
            SignatureTerm(
                regressor="q_s dq_valve/dP_S",
                enters="dP_P/dt, dP_N/dt",
                note="drawn flow times the valve flow's sensitivity to supply pressure (sonic: "
                "q_valve / P_S), coefficient -R gamma r T_atm / V_X; only with a supply path open",
            ),
        ),
        phases=("filling", "motion"),
    )
)


# ----------------------------------------------------------------- seal and barrel
def seal_effect_part(
    name: str,
    slot: int,
    coefficient_unit: str,
    signature: tuple[SignatureTerm, ...],
    phases: tuple[str, ...],
    moves: frozenset[str] = frozenset({"blocked", "motion"}),
) -> Effect:
    """The :class:`Effect` of a shared seal or barrel effect (:data:`SEAL_EFFECTS`)."""
    e = SEAL_EFFECTS[name]
    return Effect(
        name=e.name,
        slot=slot,
        parameters=(e.parameter,),
        description=e.description,
        law=e.law,
        principal=e.parameter,
        rig_default=e.typical,
        fit=(
            FitRange(
                e.parameter,
                e.fit_lower,
                e.fit_upper,
                e.prior,
                description=e.description,
                signed=e.signed,
                negligible=e.negligible,
            ),
        ),
        coefficient_unit=coefficient_unit,
        signature=signature,
        phases=phases,
        moves=moves,
    )


register_effect(
    seal_effect_part(
        "seal_friction",
        C_SEAL_FRICTION,
        "N/Pa",
        (
            SignatureTerm(
                regressor="-sign(v) max(P_P + P_N - 2 P_atm, 0) / M",
                enters="dv/dt",
                note="coefficient c_p; only while sliding (a stuck piston's friction balances "
                "the drive); the chambers' rates do not see it at the measured state",
            ),
        ),
        ("motion",),
        # a friction term: the kernel skips it with the piston clamped
        frozenset({"motion"}),
    )
)
register_effect(
    seal_effect_part(
        "friction_asymmetry",
        C_FRICTION_ASYM,
        "- (a)",
        (
            SignatureTerm(
                regressor="-g(v) / M, g the friction level (static, Coulomb, seal)",
                enters="dv/dt",
                note="coefficient a (either sign); F_f = sign(v) g (1 + a sign v) + b v, so "
                "dF_f/da = g in both directions: an offset of the sliding force that a constant "
                "load cannot mimic while the piston is stuck (break-away at F_s (1 +- a))",
            ),
        ),
        ("motion",),
        # a friction term: the kernel skips it with the piston clamped
        frozenset({"motion"}),
    )
)
register_effect(
    seal_effect_part(
        "effective_area",
        C_AREA_FACTOR,
        "- (k_A - 1)",
        (
            SignatureTerm(
                regressor="S_bore (P_P - P_N) / M (the force k_A S_bore (P_P - P_N) + S_rod P_N)",
                enters="dv/dt",
                note="coefficient k_A - 1 (either sign): the pressure force on the bore's area",
            ),
            SignatureTerm(
                regressor="d(dP_X/dt)/dk_A: -+gamma P_X S_bore v / V_X and the volume change "
                "S_bore y (resp. L - y) in 1/V_X",
                enters="dP_P/dt, dP_N/dt",
                note="coefficient k_A - 1; the kernel's own derivative at the measured state "
                "(central difference), blocked tests included (the chamber volume changes)",
            ),
        ),
        ("motion", "filling", "emptying"),
    )
)
