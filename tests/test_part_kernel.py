"""Parts registered from outside the package with kernel code of their own.

A heat law and effects defined here, in the test module (outside
``pneumafit``), with ``@njit`` code: ``pneumafit.models.part_kernel`` runs
their structures on a copy of the kernel whose hooks call them.

What kind of tests these are:

- *identity* (not recovery): the outside parts here are the built-in laws
  written again (lambda constant; the external leakage; an external force),
  so a structure using them must give the built-in twin's simulation bit for
  bit: the same arithmetic reached through the hooks. A hook that dropped a
  term, mixed the chambers, lost the air to atmosphere or the force's sign
  would differ by far more than rounding;
- *identity to rounding*: the ISO 6358 valve law written again from the
  physics module's scalar functions, as a valve law of one's own, against
  the kernel's branch for it (the same law from precomputed constants:
  rounding apart, 6e-10 Pa);
- *plumbing* (slow): a heat law that is not built in (lambda growing as the
  square root of the pressure) and a leak across the piston, fitted,
  compared, discovered and reported through ``import pneumafit as pf``, on a
  campaign of the virtual rig with its own laws and a leak across the piston
  (an inverse crime as to the leak, on purpose: the check is that the part
  reaches every stage, not that a law is recovered). The outside leak is
  the built-in chamber leakage written again, so discovery must refit both
  to the same optimum.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from pneumafit.errors import PneumafitInputError
from pneumafit.models import kernel, layout, parts
from pneumafit.models.layout import ParameterSpec
from pneumafit.models.parameters import default_parameters, parameter_dict, parameter_vector
from pneumafit.models.part_kernel import kernel_for
from pneumafit.models.structure import ModelStructure
from pneumafit.physics.friction import lugre_friction, sliding_friction
from pneumafit.simulation import Experiment, Simulator
from pneumafit.simulation.reference import solve_reference

_LAM = layout.P["lambda"]
_GEL = layout.P["external_leak_conductance"]
_GES = layout.P["external_leak_split"]
_GCL = layout.P["chamber_leak_conductance"]
_PE = layout.P["exhaust_pressure"]
_TAMB = layout.P["ambient_temperature"]
_FEXT = layout.P["external_force"]
_XPP, _XPN, _XTP, _XTN = layout.X_PP, layout.X_PN, layout.X_TP, layout.X_TN


@functools.cache
def constant_lambda_again(index: int) -> object:
    """lambda = p[index]: the constant-lambda law on a parameter of its own."""

    @njit
    def law(p, pres, temp, t_wall):
        return p[index]

    return law


@njit
def external_leak_again(x, p):
    # the kernel's external leakage: G (1 + s) (P_P - P_e) out of P, G (1 - s)
    # (P_N - P_e) out of N, inflows at ambient temperature
    q1 = p[_GEL] * (1.0 + p[_GES]) * (x[_XPP] - p[_PE])
    t1 = x[_XTP] if q1 > 0.0 else p[_TAMB]
    q2 = p[_GEL] * (1.0 - p[_GES]) * (x[_XPN] - p[_PE])
    t2 = x[_XTN] if q2 > 0.0 else p[_TAMB]
    return -q1, -q1 * t1, -q2, -q2 * t2, q1 + q2, 0.0


@njit
def load_again(x, p):
    return 0.0, 0.0, 0.0, 0.0, 0.0, -p[_FEXT]


@functools.cache
def root_pressure_lambda(index: int) -> object:
    """lambda = p[index] sqrt(P / 1 bar)."""

    @njit
    def law(p, pres, temp, t_wall):
        return p[index] * math.sqrt(pres / 1.0e5)

    return law


@functools.cache
def orifice_leak(index: int) -> object:
    """The orifice leak of docs/effects.md: q = K dP / sqrt(|dP| + 1 kPa), P to N."""

    @njit
    def law(x, p):
        dp = x[_XPP] - x[_XPN]
        q = p[index] * dp / math.sqrt(abs(dp) + 1.0e3)
        t = x[_XTP] if q > 0.0 else x[_XTN]
        return -q, -q * t, q, q * t, 0.0, 0.0

    return law


def _coefficient(name: str) -> int:
    """Register a heat parameter of one's own (W/m^2/K); its index in the vector."""
    parts.register_parameter(
        ParameterSpec(name, "W/m^2/K", 10.0, 0.1, 1000.0, "heat", f"{name} (test part)")
    )
    return layout.P[name]


def _root_p() -> parts.HeatLaw:
    """The heat law lambda = c sqrt(P / 1 bar), c a parameter of its own, registered."""
    index = _coefficient("root_p_coefficient")
    return parts.register_heat_law(
        _heat_law("root-p", 8, root_pressure_lambda(index), "lambda growing as sqrt(P / 1 bar)",
                  ("root_p_coefficient",))
    )  # fmt: skip


@njit
def piston_leak_again(x, p):
    q = p[_GCL] * (x[_XPP] - x[_XPN])
    t = x[_XTP] if q > 0.0 else x[_XTN]
    return -q, -q * t, q, q * t, 0.0, 0.0


def _heat_law(
    name: str, code: int, function: object, description: str,
    parameters: tuple[str, ...] = ("lambda",),
) -> parts.HeatLaw:  # fmt: skip
    (first,) = parameters
    return parts.HeatLaw(
        name=name, code=code, parameters=parameters, description=description,
        label=name, colour="tab:purple", order=5, starts=({first: 7.0}, {first: 20.0}),
        extensions=("heat_area_ends",), kernel=function,
    )  # fmt: skip


def _effect(name: str, principal: str, parameters: tuple[str, ...], function: object,
            fit: tuple[parts.FitRange, ...], law: str,
            rig_default: float | None = None) -> parts.Effect:  # fmt: skip
    default = layout.SPECS[principal].default or 1e-11
    return parts.Effect(
        name=name, slot=None, parameters=parameters, description=f"{name} (test part)",
        law=law, principal=principal, rig_default=default if rig_default is None else rig_default,
        fit=fit, coefficient_unit="kg/s/Pa", phases=("relaxation", "rest"), kernel=function,
    )  # fmt: skip


@pytest.fixture
def registered(outside_parts: object) -> Iterator[None]:
    """Register the outside parts of a test; remove them afterwards (conftest's
    ``outside_parts``)."""
    yield


def _register_twins() -> None:
    index = _coefficient("lambda_copy")
    parts.register_heat_law(
        _heat_law("lambda-again", 7, constant_lambda_again(index),
                  "constant lambda on a parameter of its own", ("lambda_copy",))
    )  # fmt: skip
    parts.register_effect(
        _effect(
            "leak_again", "external_leak_conductance",
            ("external_leak_conductance", "external_leak_split"), external_leak_again,
            (parts.FitRange("external_leak_conductance", 1e-13, 1e-9),
             parts.FitRange("external_leak_split", -1.0, 1.0, "uniform", signed=True)),
            "the external leakage, written again",
        )
    )  # fmt: skip
    parts.register_effect(
        _effect(
            "load_again",
            "external_force",
            ("external_force",),
            load_again,
            (parts.FitRange("external_force", -100.0, 100.0, "uniform", signed=True),),
            "the external force, written again",
        )
    )


def test_outside_parts_simulate_bit_for_bit_as_their_builtin_twins(
    registered: None, step_experiment: Experiment, charge_experiment: Experiment
) -> None:
    _register_twins()
    values = default_parameters()
    values["lambda"] = values["lambda_copy"] = 12.0
    values["external_leak_conductance"] = 4e-11
    values["external_leak_split"] = 0.3
    vec = parameter_vector(values)
    builtin = Simulator(ModelStructure("constant-lambda", effects={"external_leakage": 1}))
    outside = Simulator(ModelStructure("lambda-again", effects={"leak_again": 1}))
    assert builtin._kernel is kernel and outside._kernel is not kernel
    assert kernel_for(ModelStructure("convection")) is kernel  # built-in parts: the cached one
    exps = [step_experiment, charge_experiment]
    ref, st_ref = builtin.simulate_batch(vec[None], exps)
    out, st_out = outside.simulate_batch(vec[None], exps)
    assert (st_ref == 0).all() and (st_out == 0).all()
    # same operations in the same order (q - q_l is q + (-q_l) exactly)
    assert np.array_equal(out, ref, equal_nan=True)
    # not a vacuous check: the leak moves the charge test's pressure and the
    # air sent to atmosphere
    tight = parameter_vector({**values, "external_leak_conductance": 0.0})
    no_leak, _ = builtin.simulate_batch(tight[None], exps)
    p_p = builtin.channels.index("p_P")
    m_e = builtin.channels.index("m_exhaust")
    assert np.nanmax(np.abs(ref[0, :, p_p] - no_leak[0, :, p_p])) > 1e3  # Pa
    assert np.nanmax(np.abs(ref[0, :, m_e] - no_leak[0, :, m_e])) > 1e-6  # kg


def test_an_outside_force_acts_on_the_piston(registered: None, step_experiment: Experiment) -> None:
    _register_twins()
    values = default_parameters()
    values["external_force"] = 25.0
    once = parameter_vector(values)
    twice = parameter_vector({**values, "external_force": 50.0})
    builtin = Simulator(ModelStructure("constant-lambda"))
    outside = Simulator(ModelStructure("constant-lambda", effects={"load_again": 1}))
    # the load's hook adds -F to the drive that already holds -F: the
    # built-in structure at 2F. Not bit for bit: a - (b + 2F) and
    # (a - (b + F)) - F round differently
    ref1, _ = builtin.simulate_batch(once[None], [step_experiment])
    ref2, _ = builtin.simulate_batch(twice[None], [step_experiment])
    out, status = outside.simulate_batch(once[None], [step_experiment])
    assert (status == 0).all()
    y = builtin.channels.index("y")
    # rounding only: measured 1.1e-16 m; 1e-12 m leaves room for a stick
    # event moved by a rounding of the force, and is far below the 1-um
    # encoder step of the campaigns; the force itself moves the piston by
    # more than 0.1 mm
    assert np.nanmax(np.abs(out[0, :, y] - ref2[0, :, y])) < 1e-12
    assert np.nanmax(np.abs(ref1[0, :, y] - ref2[0, :, y])) > 1e-4


def test_the_reference_solver_runs_outside_parts(
    registered: None, charge_experiment: Experiment
) -> None:
    _register_twins()
    values = default_parameters()
    values["lambda"] = values["lambda_copy"] = 12.0
    values["external_leak_conductance"] = 4e-11
    builtin = ModelStructure("constant-lambda", effects={"external_leakage": 1})
    outside = ModelStructure("lambda-again", effects={"leak_again": 1})
    a = solve_reference(builtin, values, charge_experiment, rtol=1e-8)
    b = solve_reference(outside, values, charge_experiment, rtol=1e-8)
    # the same right-hand side compiled twice (the cached kernel and its
    # copy, in another inlining context): measured 5.8e-15 relative at most
    # (p_P); 1e-12 allows a step of Radau accepted differently after a rounding
    for ch in ("p_P", "T_P", "m_exhaust"):
        assert np.allclose(a[ch], b[ch], rtol=1e-12, atol=0.0), ch


def test_lambda_at_the_reference_state_comes_from_the_law_s_kernel(registered: None) -> None:
    from pneumafit.identification.reference import REFERENCE_STATE, reference_lambda

    _root_p()
    expected = 10.0 * math.sqrt(REFERENCE_STATE["pressure"] / 1e5)
    c = "root_p_coefficient"
    assert reference_lambda({c: 10.0}, "root-p") == pytest.approx(expected, rel=1e-15)
    draws = reference_lambda({c: np.array([10.0, 20.0])}, "root-p")
    assert np.allclose(draws, [expected, 2.0 * expected], rtol=1e-15)


def test_a_parameter_of_one_s_own_extends_the_table_at_its_end(registered: None) -> None:
    n, bore = layout.n_parameters(), layout.P["bore"]
    index = _coefficient("my_coefficient")
    assert index == n and layout.n_parameters() == n + 1 and layout.P["bore"] == bore
    assert layout.PARAMETER_NAMES[-1] == "my_coefficient" == layout.PARAMETER_SPECS[-1].name
    vec = parameter_vector({"my_coefficient": 3.0})
    assert vec.shape == (n + 1,) and vec[index] == 3.0
    assert parameter_dict(vec)["my_coefficient"] == 3.0
    # a part uses it: it cannot go before the part
    parts.register_heat_law(
        _heat_law("mine", 9, constant_lambda_again(index), "mine", ("my_coefficient",))
    )
    with pytest.raises(ValueError, match="used by"):
        parts.unregister_parameter("my_coefficient")
    parts.unregister_heat_law("mine")
    parts.unregister_parameter("my_coefficient")
    assert layout.n_parameters() == n and "my_coefficient" not in layout.P


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        (ParameterSpec("bore", "m", 0.03, 0.01, 0.1, "heat", ""), "new name"),
        (ParameterSpec("my c", "m", 0.03, 0.01, 0.1, "heat", ""), "identifier"),
        (ParameterSpec("my_c", "m", 0.03, 0.01, 0.1, "rig", ""), "group"),
        (ParameterSpec("my_c", "wombats", 1.0, 0.1, 2.0, "heat", ""), "not a known unit"),
        (ParameterSpec("my_c", "mm", 1.0, 0.1, 2.0, "heat", ""), "SI unit"),
        (ParameterSpec("my_c", "m", 1.0, 0.1, math.inf, "heat", ""), "finite bounds"),
        (ParameterSpec("my_c", "m", 5.0, 0.1, 2.0, "heat", ""), "default inside"),
    ],
)
def test_a_bad_parameter_is_refused(registered: None, spec: ParameterSpec, message: str) -> None:
    n = layout.n_parameters()
    with pytest.raises(ValueError, match=message):
        parts.register_parameter(spec)
    assert layout.n_parameters() == n


@pytest.mark.parametrize(
    ("kind", "changes", "message"),
    [
        ("heat", {"kernel": math.sqrt}, "numba @njit function"),
        ("effect", {"kernel": math.sqrt}, "numba @njit function"),
        ("effect", {"slot": layout.C_CHAMBER_LEAK + 100}, "slot=None"),
        ("effect", {"options": {0: ("chamber_leak_conductance",)}}, "option 0"),
    ],
)
def test_bad_kernel_code_is_refused(
    registered: None, kind: str, changes: dict[str, object], message: str
) -> None:
    if kind == "heat":
        law = _heat_law("bad-heat", 9, root_pressure_lambda(_LAM), "bad")
        with pytest.raises(ValueError, match=message):
            parts.register_heat_law(parts.HeatLaw(**{**law.__dict__, **changes}))
        assert "bad-heat" not in parts.HEAT_LAWS
        return
    effect = _effect(
        "bad_leak", "chamber_leak_conductance", ("chamber_leak_conductance",),
        piston_leak_again, (parts.FitRange("chamber_leak_conductance", 1e-13, 1e-9),), "bad",
    )  # fmt: skip
    fields = {k: v for k, v in effect.__dict__.items()}
    fields.update(changes)
    with pytest.raises(ValueError, match=message):
        parts.register_effect(parts.Effect(**fields))
    assert "bad_leak" not in parts.EFFECTS


@njit
def leak_where(x, p, option):
    # option 1: the kernel's chamber leakage (P to N across the piston);
    # option 2: its external leakage (each chamber to atmosphere). Written
    # out here, not called, so that both compile with the kernel's flags
    if option == 1:
        q = p[_GCL] * (x[_XPP] - x[_XPN])
        t = x[_XTP] if q > 0.0 else x[_XTN]
        return -q, -q * t, q, q * t, 0.0, 0.0
    q1 = p[_GEL] * (1.0 + p[_GES]) * (x[_XPP] - p[_PE])
    t1 = x[_XTP] if q1 > 0.0 else p[_TAMB]
    q2 = p[_GEL] * (1.0 - p[_GES]) * (x[_XPN] - p[_PE])
    t2 = x[_XTN] if q2 > 0.0 else p[_TAMB]
    return -q1, -q1 * t1, -q2, -q2 * t2, q1 + q2, 0.0


def _register_leak_where() -> None:
    """The two leaks as one outside effect with options 1 and 2, registered
    after the twins' two one-bit effects and before a third (a load again,
    whose field then starts past leak_where's two bits)."""
    _register_twins()
    names = ("chamber_leak_conductance", "external_leak_conductance", "external_leak_split")
    effect = _effect(
        "leak_where", "chamber_leak_conductance", names, leak_where,
        (parts.FitRange("chamber_leak_conductance", 1e-13, 1e-9),
         parts.FitRange("external_leak_conductance", 0.0, 1e-9, "uniform"),  # typical 0: off
         parts.FitRange("external_leak_split", -1.0, 1.0, "uniform", signed=True)),
        "1: across the piston; 2: to atmosphere",
    )  # fmt: skip
    parts.register_effect(replace(effect, options={1: names[:1], 2: names[1:]}))
    parts.register_effect(replace(parts.EFFECTS["load_again"], name="load_late"))


def test_an_outside_effect_with_options_runs_each_as_its_builtin_twin(
    registered: None, step_experiment: Experiment, charge_experiment: Experiment
) -> None:
    """Identity: one outside effect whose kernel code takes the structure's
    option (``Effect.options``), option 1 the chamber leakage and option 2
    the external leakage written again, must give the built-in effect's
    simulation bit for bit for each option (the arithmetic is the same, in
    the same order: one outside effect adds -q where the kernel subtracts
    q). An option read from the wrong bits (another effect's field, or 0)
    runs the other leak or none: the two leaks differ by kPa here."""
    _register_leak_where()
    from pneumafit.models.part_kernel import effect_fields

    # twins' effects first (one bit each), then leak_where's two bits, then load_late
    fields = effect_fields()
    assert fields["leak_where"] == (2, 2) and fields["load_late"] == (4, 1)
    values = default_parameters()
    values.update(chamber_leak_conductance=6e-11, external_leak_conductance=4e-11,
                  external_leak_split=0.3)  # fmt: skip
    vec = parameter_vector(values)
    exps = [step_experiment, charge_experiment]
    runs = {}
    for name, effects in (
        ("piston", {"chamber_leakage": 1}),
        ("atm", {"external_leakage": 1}),
        ("own-1", {"leak_where": 1}),
        ("own-2", {"leak_where": 2}),
    ):
        structure = ModelStructure("constant-lambda", effects=effects)
        out, status = Simulator(structure).simulate_batch(vec[None], exps)
        assert (status == 0).all(), name
        runs[name] = out
    assert ModelStructure("constant-lambda", effects={"leak_where": 2}).config()[
        layout.C_PART_EFFECTS] == 2 << 2  # fmt: skip
    assert np.array_equal(runs["own-1"], runs["piston"], equal_nan=True)
    assert np.array_equal(runs["own-2"], runs["atm"], equal_nan=True)
    p_p = Simulator(ModelStructure("constant-lambda")).channels.index("p_P")
    assert np.nanmax(np.abs(runs["piston"][0, :, p_p] - runs["atm"][0, :, p_p])) > 1e3  # Pa
    # beside an effect whose bit follows its field: the leak to atmosphere and
    # the load both act, against the built-in structure at twice the force (as
    # in test_an_outside_force_acts_on_the_piston, rounding only: measured
    # 3.3e-16 m and 6.4e-10 Pa; held to 1e-12 m and 1e-6 Pa)
    values["external_force"] = 25.0
    both = ModelStructure("constant-lambda", effects={"leak_where": 2, "load_late": 1})
    assert both.config()[layout.C_PART_EFFECTS] == (2 << 2) | (1 << 4)
    out, status = Simulator(both).simulate_batch(parameter_vector(values)[None], exps)
    twice = parameter_vector({**values, "external_force": 50.0})
    ref, _ = Simulator(ModelStructure("constant-lambda", effects={"external_leakage": 1})
                       ).simulate_batch(twice[None], exps)  # fmt: skip
    y = Simulator(both).channels.index("y")
    assert (status == 0).all()
    assert np.nanmax(np.abs(out[0, :, y] - ref[0, :, y])) < 1e-12
    assert np.nanmax(np.abs(out[0, :, p_p] - ref[0, :, p_p])) < 1e-6  # Pa


def test_an_outside_effect_s_option_is_checked(registered: None) -> None:
    _register_leak_where()
    from pneumafit.models.part_kernel import effect_field

    with pytest.raises(PneumafitInputError, match=r"expected one of \[0, 1, 2\], found 3"):
        effect_field("leak_where", 3)
    with pytest.raises(ValueError, match="leak_where"):
        ModelStructure("constant-lambda", effects={"leak_where": 3})
    assert effect_field("leak_where", 0) == 0
    # options are part of the parts' fingerprint: a fit saved with option 2
    # meaning the leak to atmosphere is not reused when it means another law
    from pneumafit.models.part_kernel import parts_digest

    before, effect = parts_digest(), parts.EFFECTS["leak_where"]
    renumbered = {1: effect.options[1], 3: effect.options[2]}
    parts.register_effect(replace(effect, options=renumbered), replace=True)
    assert parts_digest() != before
    assert effect_field("leak_where", 3) == 3 << 2


def test_a_built_in_heat_code_cannot_take_kernel_code(registered: None) -> None:
    from dataclasses import replace

    with pytest.raises(ValueError, match="code outside"):
        parts.register_heat_law(
            replace(parts.HEAT_LAWS["convection"], kernel=root_pressure_lambda(_LAM)),
            replace=True,
        )
    assert parts.HEAT_LAWS["convection"].kernel is None


# ----------------------------------------------------------------- the workbench (slow)
@pytest.mark.slow
def test_an_outside_heat_law_and_effect_are_fitted_compared_discovered_and_reported(
    registered: None, tmp_path: Path
) -> None:
    import pneumafit as pf
    from pneumafit.identification.reference import reference_lambda
    from pneumafit.virtual_rig import VirtualRig

    _root_p()
    parts.register_effect(
        _effect(
            "piston_leak_again", "chamber_leak_conductance", ("chamber_leak_conductance",),
            piston_leak_again, (parts.FitRange("chamber_leak_conductance", 1e-13, 1e-9),),
            "the chamber leakage, written again",
        )
    )  # fmt: skip
    folder = tmp_path / "campaign"
    VirtualRig(effects={"chamber_leakage": 4e-11}, seed=3).write(folder, protocol="quick")
    campaign = pf.read_campaign(folder)
    fit = pf.fit(campaign, model="root-p", mcmc=False, seed=0)
    assert fit.structure.heat == "root-p"
    # lambda at the reference state through the law's own code: lambda sqrt(5)
    # at the estimate; the reported value is the Laplace draws' median, inside
    # its interval with the point's
    values = fit.parameters.values()
    point = float(reference_lambda(values, "root-p"))
    assert point == pytest.approx(values["root_p_coefficient"] * math.sqrt(5.0), rel=1e-14)
    reported = fit.metrics["lambda_reference"]
    lo, hi = reported["interval_90"]
    assert lo <= point <= hi and lo <= reported["value"] <= hi
    other = pf.fit(campaign, model="constant-lambda", mcmc=False, seed=0)
    comparison = pf.compare(campaign, [fit, other])
    assert "root-p" in comparison.summary() and "constant-lambda" in comparison.summary()
    discovery = pf.discover(campaign, fit, rounds=1)
    tried = {s.effect: s for s in discovery.steps if s.model is not None}
    assert "piston_leak_again" in tried and "chamber_leakage" in tried
    # the same law reached through the hook and through the kernel's slot:
    # the same optimum. Not to the last digit: the refits start from
    # different points (the built-in's written regressor, the outside
    # part's kernel derivative) and stop at the least squares' tolerance.
    # Measured: 2.4e-7 in log-likelihood and 2e-7 relative in the
    # conductance (1.4e-5 in log-likelihood with lambda itself as the heat
    # law's parameter); 1e-4 is seven times the worst seen, and far inside
    # the information criteria's decisions (units)
    a, b = tried["piston_leak_again"].model, tried["chamber_leakage"].model
    assert a.log_likelihood == pytest.approx(b.log_likelihood, abs=1e-4)
    g = "chamber_leak_conductance"
    assert a.values[g] == pytest.approx(b.values[g], rel=1e-4)
    html = pf.report(tmp_path / "run", campaign, fits=[fit, other], comparison=comparison,
                     discovery=discovery).read_text(encoding="utf-8")  # fmt: skip
    assert "root-p" in html and "piston_leak_again" in html


def test_the_sampled_closed_loop_runs_outside_parts(registered: None) -> None:
    from pneumafit.simulation import simulate_sampled

    _register_twins()
    values = default_parameters()
    values["lambda"] = values["lambda_copy"] = 12.0
    values["external_leak_conductance"] = 4e-11
    t = np.arange(0.0, 1.0005, 1e-3)
    ref = np.where(t < 0.1, 0.25, 0.30)

    def pd(state: np.ndarray, y_ref: float) -> float:  # a P law on the sampled position
        return float(np.clip(60.0 * (y_ref - state[0]), -10.0, 10.0))

    runs = [
        simulate_sampled(parameter_vector(values), t, ref, pd, model=m,
                         initial={"y": 0.25, "p_P": 4.0e5, "p_N": 5.3e5})
        for m in (ModelStructure("constant-lambda", effects={"external_leakage": 1}),
                  ModelStructure("lambda-again", effects={"leak_again": 1}))
    ]  # fmt: skip
    assert runs[0].status == runs[1].status == 0
    # the same steps, compiled in another inlining context (the cached
    # loop's steps against their copy bound to the outside parts): under the
    # kernel's fastmath the compiler may contract a multiply-add differently,
    # so equal to rounding, not bit for bit. Measured: y, p_P, p_N and
    # m_exhaust bit for bit, T_P within 5.7e-14 K (one ulp at 310 K);
    # 1e-13 relative is 500 ulps, far below any sensor
    for ch in ("y", "p_P", "p_N", "T_P", "m_exhaust"):
        np.testing.assert_allclose(runs[1][ch], runs[0][ch], rtol=1e-13, atol=0.0, err_msg=ch)
    assert np.ptp(runs[0]["y"]) > 0.02  # the loop moved the piston


def test_a_friction_law_without_kernel_code_is_refused(registered: None) -> None:
    from dataclasses import replace

    law = replace(parts.FRICTION_LAWS["switch"], name="toy-friction", code=5)
    parts.register_friction_law(law)
    with pytest.raises(ValueError, match=r"FrictionLaw\.kernel"):
        ModelStructure("convection", friction="toy-friction").config()
    # a built-in law's code is the kernel's own branch: replacing the law by
    # one with kernel code there is refused (the registry keeps the original)
    switch = parts.FRICTION_LAWS["switch"]
    with pytest.raises(ValueError, match="expected a code outside"):
        parts.register_friction_law(replace(switch, kernel=smooth_coulomb(1e-3)), replace=True)
    assert parts.FRICTION_LAWS["switch"] is switch


# ------------------------------------------------------------ a friction law
_FS_I, _FC_I = layout.P["friction_static"], layout.P["friction_coulomb"]
_FV_I, _VST_I = layout.P["friction_viscous"], layout.P["stribeck_velocity"]


@functools.cache
def smooth_coulomb(v_eps: float) -> object:
    """A smooth Stribeck law: (F_c + (F_s - F_c) exp(-(v / v_st)^2)) tanh(v / v_eps) + b v
    (N), the switch model's levels with the sign function smoothed over
    ``v_eps`` (m/s): no stuck mode, no events."""

    @njit
    def law(v, f_s, f_c, x, p):
        g = f_c + (f_s - f_c) * math.exp(-((v / p[_VST_I]) ** 2))
        return g * math.tanh(v / v_eps) + p[_FV_I] * v

    return law


def _register_smooth(name: str = "smooth-coulomb", v_eps: float = 1e-3) -> parts.FrictionLaw:
    return parts.register_friction_law(
        parts.FrictionLaw(
            name=name, code=6,
            parameters=("friction_static", "friction_coulomb", "friction_viscous",
                        "stribeck_velocity"),
            description="Stribeck levels, the sign smoothed by tanh(v / 1 mm/s)",
            kernel=smooth_coulomb(v_eps),
        )
    )  # fmt: skip


def test_an_outside_friction_law_gives_the_force_it_computes(
    registered: None, step_experiment: Experiment
) -> None:
    """Identity of the hook (not recovery): the recorded friction force F_f is
    the law's formula at the recorded speed, for every sample, written again
    here in numpy (1e-12 relative: the same formula in numba and numpy,
    exp and tanh of one libm; 1e-9 N absolute where the force crosses
    zero). A hook that lost the sign, a level or the viscous term would
    differ by newtons. The piston moves and stops by the
    law (no stuck mode: it creeps at |v| << v_eps instead)."""
    _register_smooth()
    values = default_parameters()
    run = Simulator(ModelStructure("convection", friction="smooth-coulomb")).simulate(
        values, step_experiment
    )
    assert run.ok and np.ptp(run["y"]) > 0.02
    v = run["v"]
    f_s, f_c = values["friction_static"], values["friction_coulomb"]
    g = f_c + (f_s - f_c) * np.exp(-((v / values["stribeck_velocity"]) ** 2))
    expected = g * np.tanh(v / 1e-3) + values["friction_viscous"] * v
    np.testing.assert_allclose(run["F_f"], expected, rtol=1e-12, atol=1e-9)
    # the switch model on the same test sticks; the smooth law never stops
    # exactly but creeps below the smoothing speed
    assert np.min(np.abs(v[len(v) // 2 :])) < 1e-3


@njit
def switch_again(v, s, f_s, f_c, x, p):
    """The switch model's sliding force (physics.friction.sliding_friction),
    as a law of one's own in the switch model's modes (FrictionLaw.stuck)."""
    return sliding_friction(v, s, f_s, f_c, p[_FV_I], p[_VST_I])


def _register_switch_again(**more: object) -> parts.FrictionLaw:
    return parts.register_friction_law(
        parts.FrictionLaw(
            name="switch-again", code=9, parameters=parts.FRICTION_LAWS["switch"].parameters,
            description="the switch model's sliding force, in its stuck mode",
            kernel=switch_again, stuck=True, **more,
        )
    )  # fmt: skip


def test_an_outside_friction_law_in_the_stuck_mode_runs_as_the_switch_model(
    registered: None, step_experiment: Experiment, charge_experiment: Experiment
) -> None:
    """Identity (not recovery): the switch model's sliding force registered
    from outside the package with ``stuck=True`` runs in the kernel's stuck
    mode and events, so it must give the built-in switch model's simulation
    bit for bit (the same force through the hook, the same mode logic),
    with the seal friction and the asymmetry on (levels passed to the law)
    and off. Not vacuous: the piston of the step test sticks (v exactly 0
    over many samples), and the same force as a smooth law (stuck=False,
    its direction sign(v)) cannot stick there."""
    _register_switch_again()
    values = default_parameters()
    values.update(seal_friction_coefficient=1.5e-5, friction_asymmetry=0.2)
    exps = [step_experiment, charge_experiment]
    for effects in ({}, {"seal_friction": 1, "friction_asymmetry": 1}):
        ref = Simulator(ModelStructure("convection", effects=effects))
        own = Simulator(ModelStructure("convection", friction="switch-again", effects=effects))
        assert own._kernel is not kernel
        vec = parameter_vector(values)[None]
        a, st_a = ref.simulate_batch(vec, exps)
        b, st_b = own.simulate_batch(vec, exps)
        assert (st_a == 0).all() and (st_b == 0).all()
        assert np.array_equal(a, b, equal_nan=True), effects
    run = Simulator(ModelStructure("convection", friction="switch-again")).simulate(
        values, step_experiment
    )
    assert run.ok and np.sum(run["v"] == 0.0) > 100  # samples stuck
    # the reference solver (scipy Radau with events) runs the same modes
    # against the built-in switch model: the same right-hand side compiled
    # twice (the kernel and its copy). Measured 0 difference on y and p_P;
    # held, as the heat law's twin (test_the_reference_solver_runs_outside_parts,
    # 5.8e-15 there), to 1e-12 relative: rounding of another inlining context
    # and a Radau step accepted differently after it
    from pneumafit.simulation.reference import solve_reference

    r_own = solve_reference(ModelStructure("convection", friction="switch-again"), values,
                            step_experiment, rtol=1e-8)  # fmt: skip
    r_ref = solve_reference(ModelStructure("convection"), values, step_experiment, rtol=1e-8)
    for ch in ("y", "p_P"):
        np.testing.assert_allclose(r_own[ch], r_ref[ch], rtol=1e-12, atol=0.0, err_msg=ch)


def test_a_law_in_the_stuck_mode_is_checked_and_named(registered: None) -> None:
    law = _register_switch_again()
    cases = [
        (replace(law, name="s1", code=10, kernel=None), "found no kernel"),
        (replace(law, name="s2", code=11, state_rate=lugre_again_rate), "found a state_rate"),
        (
            replace(law, name="s3", code=12, c_state_rate="return 0.0;", c_code="return 0.0;"),
            "c_state_rate: expected it only with a state of its own",
        ),
        (replace(law, name="s4", code=13, stuck="yes"), "expected True or False"),
    ]
    for bad, message in cases:
        with pytest.raises(PneumafitInputError, match=message):
            parts.register_friction_law(bad)
        assert bad.name not in parts.FRICTION_LAWS
    assert law.modes and parts.FRICTION_LAWS["switch"].modes
    assert not parts.FRICTION_LAWS["lugre"].modes
    from pneumafit.outputs.fmu.builder import check_structure

    # without C code the FMU names the field (with it: tests/test_fmu.py)
    with pytest.raises(PneumafitInputError, match=r"without its C code: FrictionLaw\.c_code"):
        check_structure(ModelStructure("convection", friction="switch-again"))
    # a kernel copy that knows the law: part_friction_stuck says so
    module = kernel_for(ModelStructure("convection", friction="switch-again"))
    assert module.part_friction_stuck(9) and not module.part_friction_stuck(0)
    assert not kernel.part_friction_stuck(9)  # the cached kernel knows none


def test_an_outside_friction_law_matches_the_reference_solver(
    registered: None, step_experiment: Experiment
) -> None:
    """The fixed-step kernel (its copy with the hook bound) against scipy's
    Radau on the same right-hand side (an independent, adaptive integrator,
    rtol 1e-8; neither has the switch model's stuck mode for this law): a
    law with a 5-mm/s smoothing, which Kutta's method follows at the fitting
    step (h dF/dv / M = 0.35 against its stability limit 2.51). Measured 13
    Pa and 4.0 um at most (the switch model 0.2 Pa and 0.1 um, LuGre 4 Pa and
    1.3 um on the same test); the bounds are a tenth of the pressure
    sensors' noise (400 Pa) and the encoder's 10-um step, far below what a
    piston stuck by mistake in one of the two would give (millimetres)."""
    _register_smooth(v_eps=5e-3)
    structure = ModelStructure("convection", friction="smooth-coulomb")
    values = default_parameters()
    fixed = Simulator(structure).simulate(values, step_experiment)
    ref = solve_reference(structure, values, step_experiment, rtol=1e-8)
    assert fixed.ok
    assert np.max(np.abs(fixed["p_P"] - ref["p_P"])) < 40.0
    assert np.max(np.abs(fixed["y"] - ref["y"])) < 10e-6


@pytest.mark.slow  # slow job (50 s)
def test_the_step_bound_keeps_a_steep_outside_friction_law_stable(
    registered: None, step_experiment: Experiment
) -> None:
    """Independent solver (Radau, rtol 1e-8, on the same right-hand side): a
    law smoothed over 0.2 mm/s (h dF/dv / M = 15 at the 1-ms default step,
    beyond Kutta's 2.51) chatters at 1 ms, and the step ``choose_step`` now
    takes from the law's slope at rest (0.154 ms) follows it. Measured
    2026-11-30: 2833 Pa and 0.93 mm from Radau at 1 ms; 8.7 Pa and 2.9 um at
    the bound's step. Held: within 40 Pa and 10 um at the bound's step (as
    the test above: a tenth of the pressure noise and of the encoder step),
    and the 1-ms run over 1 kPa (the bound is what makes the difference)."""
    from pneumafit.simulation import choose_step

    _register_smooth(v_eps=2e-4)
    structure = ModelStructure("convection", friction="smooth-coulomb")
    values = default_parameters()
    step = choose_step(parameter_vector(values), friction="smooth-coulomb")
    assert step < 0.2e-3
    ref = solve_reference(structure, values, step_experiment, rtol=1e-8)
    bounded = Simulator(structure, step=step).simulate(values, step_experiment)
    assert bounded.ok
    assert np.max(np.abs(bounded["p_P"] - ref["p_P"])) < 40.0
    assert np.max(np.abs(bounded["y"] - ref["y"])) < 10e-6
    coarse = Simulator(structure, step=1e-3).simulate(values, step_experiment)
    assert np.nanmax(np.abs(coarse["p_P"] - ref["p_P"])) > 1e3


def test_an_outside_friction_law_has_parameters_of_its_own(
    registered: None, step_experiment: Experiment, charge_experiment: Experiment
) -> None:
    """Plumbing: a friction law's own parameter (group "friction", here the
    smoothing speed) reaches the kernel (the simulation is bit for bit the
    law with the value written in), is sampled in log scale (its bounds
    span three decades), starts the friction stage at the law's start, and
    excuses the blocked tests in the sparse Jacobian (friction acts on a
    moving piston only)."""
    from pneumafit.identification import ParameterSet
    from pneumafit.identification.problem import Problem
    from pneumafit.identification.starts import friction_starts

    parts.register_parameter(
        ParameterSpec("my_v_eps", "m/s", 1e-3, 1e-4, 1e-1, "friction", "smoothing speed")
    )
    i_eps, i_vst, i_fv = layout.P["my_v_eps"], _VST_I, _FV_I

    @njit
    def law(v, f_s, f_c, x, p):
        g = f_c + (f_s - f_c) * math.exp(-((v / p[i_vst]) ** 2))
        return g * math.tanh(v / p[i_eps]) + p[i_fv] * v

    shared = ("friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity")
    parts.register_friction_law(
        parts.FrictionLaw(name="own-eps", code=8, parameters=(*shared, "my_v_eps"),
                          description="smooth Stribeck law, its smoothing a parameter",
                          kernel=law, starts=({"my_v_eps": 5e-3},))
    )  # fmt: skip
    _register_smooth(v_eps=5e-3)
    values = {**default_parameters(), "my_v_eps": 5e-3}
    vec = parameter_vector(values)
    own = Simulator(ModelStructure("convection", friction="own-eps"))
    fixed = Simulator(ModelStructure("convection", friction="smooth-coulomb"))
    a, st_a = own.simulate_batch(vec[None], [step_experiment])
    b, st_b = fixed.simulate_batch(vec[None], [step_experiment])
    assert (st_a == 0).all() and (st_b == 0).all()
    assert np.array_equal(a, b, equal_nan=True)
    structure = ModelStructure("convection", friction="own-eps")
    ps = ParameterSet.for_model(structure)
    assert ps["my_v_eps"].scale == "log"
    assert friction_starts([], default_parameters(), "own-eps")[0]["my_v_eps"] == 5e-3
    import pneumafit as pf

    demo = pf.read_campaign(Path(__file__).resolve().parents[1] / "data" / "demo")
    recs = [next(r for r in demo.by_role("fit") if r.kind == k) for k in ("charge", "step")]
    problem = Problem(recs, structure, {**ps.values(), **demo.rig.as_parameters()})
    assert problem.unaffected(["my_v_eps"])[0].tolist() == [True, False]


def test_an_outside_friction_law_takes_the_switch_model_s_levels_as_starts(
    registered: None,
) -> None:
    """The friction stage's starts for an outside law: the levels it shares
    with the switch model, each with every one of the law's own starts."""
    from dataclasses import replace

    from pneumafit.identification.starts import friction_starts

    law = _register_smooth()
    parts.register_friction_law(replace(law, starts=({"stribeck_velocity": 0.05},)),
                                replace=True)  # fmt: skip
    rig = default_parameters()
    starts = friction_starts([], rig, "smooth-coulomb")
    switch = friction_starts([], rig, "switch")
    assert starts == [switch[0] | {"stribeck_velocity": 0.05}]
    assert set(starts[0]) == set(law.parameters)


@pytest.mark.slow
def test_an_outside_friction_law_is_fitted_and_saved(registered: None, tmp_path: Path) -> None:
    """Plumbing (not recovery): the staged fit with a friction law registered
    from outside (``FitOptions(friction=NAME)``) on a campaign of the virtual
    rig, whose friction is the switch model: the fit runs the law's kernel
    in every stage, reports its levels, and its fit.json reads back with the
    law registered. The smooth law is not the rig's, so no level is asked to
    match the truth; only that the fit is finite and lands on levels of the
    truth's size (the Coulomb level within a factor of two of 30 N). With
    ``--friction auto`` the law is compared with the built-in law chosen, by
    BIC in effective samples, and the fit says which it kept."""
    import pneumafit as pf
    from pneumafit.identification.staged import FitOptions, FitResult
    from pneumafit.virtual_rig import VirtualRig

    _register_smooth(v_eps=5e-3)
    folder = tmp_path / "campaign"
    VirtualRig(seed=3).write(folder, protocol="sparse")  # one fit step test
    campaign = pf.read_campaign(folder)
    fit = pf.fit(campaign, "convection", mcmc=False, seed=0,
                 options=FitOptions(friction="smooth-coulomb"))  # fmt: skip
    assert fit.structure.friction == "smooth-coulomb"
    friction = next(s for s in fit.stages if s.name == "friction")
    assert friction.estimate is not None  # solved on the step test, not held
    assert set(friction.free) == set(parts.FRICTION_LAWS["smooth-coulomb"].parameters)
    values = fit.parameters.values()
    assert all(math.isfinite(values[n]) for n in parts.FRICTION_LAWS["smooth-coulomb"].parameters)
    assert 15.0 < values["friction_coulomb"] < 60.0
    fit.save(tmp_path / "fit.json")
    again = FitResult.load(tmp_path / "fit.json")
    assert again.structure.friction == "smooth-coulomb"
    assert again.parameters.values()["friction_coulomb"] == values["friction_coulomb"]
    # --friction auto compares the registered law with the built-in one it
    # chooses, by BIC in effective samples, and says which it kept
    lines: list[str] = []
    auto = pf.fit(campaign, "convection", mcmc=False, seed=0, log=lines.append)
    said = [line for line in lines if line.startswith("friction (smooth-coulomb): BIC")]
    assert len(said) == 1 and ("kept" in said[0])
    note = next(s for s in auto.stages if s.name == "friction").note
    if auto.structure.friction == "smooth-coulomb":
        assert note.startswith("friction law smooth-coulomb: BIC in effective samples")
    else:
        assert "not kept" in said[0] and note.startswith(f"friction law {auto.structure.friction}")


def _register_orifice(name: str, law: Callable[[int], object], text: str) -> None:
    """Register an orifice-law effect with its coefficient ``NAME_coefficient``
    (kg/s/Pa^0.5, fitted in [1e-10, 1e-6], rig default 3e-8)."""
    coefficient = f"{name}_coefficient"
    parts.register_parameter(
        ParameterSpec(coefficient, "kg/s/Pa^0.5", 0.0, 0.0, 1e-5, "effect", text)
    )
    parts.register_effect(
        _effect(name, coefficient, (coefficient,), law(layout.P[coefficient]),
                (parts.FitRange(coefficient, 1e-10, 1e-6),), text, rig_default=3e-8)
    )  # fmt: skip


@pytest.mark.slow
def test_an_outside_effect_the_rig_hides_is_discovered(registered: None, tmp_path: Path) -> None:
    """The worked example of docs/effects.md: an orifice leak, parameter included.

    The virtual rig records it with its own laws (an inverse crime on
    purpose: the test is that discovery reaches the part, through
    attribution's kernel derivative, not that a law is recovered);
    discovery, offered the whole catalog, must keep it and bring the
    residual to the noise.
    """
    import pneumafit as pf
    from pneumafit.virtual_rig import VirtualRig

    _register_orifice("orifice_leak", orifice_leak, "q = K dP / sqrt(|dP| + 1 kPa), P to N")
    folder = tmp_path / "campaign"
    VirtualRig(effects={"orifice_leak": 3e-8}, seed=4).write(folder, protocol="quick")
    campaign = pf.read_campaign(folder)
    fit = pf.fit(campaign, "convection", mcmc=False, seed=0)
    found = pf.discover(campaign, fit, rounds=1)
    assert found.selected == ["orifice_leak"]
    assert not found.unexplained  # measured: 1054 -> 396 Pa against 403 Pa of noise
    k = found.final.values["orifice_leak_coefficient"]
    # the rig's own law: measured 3.037e-8, 1.2 % off; 5 % is about four
    # times that, for another platform's rounding of the fits
    assert k == pytest.approx(3e-8, rel=0.05)


@functools.cache
def atm_orifice(index: int) -> object:
    """An orifice leak of each chamber to atmosphere: q = K dP / sqrt(|dP| + 1 kPa)."""
    pe, ta = layout.P["exhaust_pressure"], layout.P["ambient_temperature"]

    @njit
    def law(x, p):
        d1 = x[_XPP] - p[pe]
        q1 = p[index] * d1 / math.sqrt(abs(d1) + 1.0e3)
        t1 = x[_XTP] if q1 > 0.0 else p[ta]
        d2 = x[_XPN] - p[pe]
        q2 = p[index] * d2 / math.sqrt(abs(d2) + 1.0e3)
        t2 = x[_XTN] if q2 > 0.0 else p[ta]
        return -q1, -q1 * t1, -q2, -q2 * t2, q1 + q2, 0.0

    return law


@pytest.mark.slow
def test_attribution_reaches_an_outside_effect_on_a_mismatched_truth(
    registered: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The bundled demo: an independent truth whose chambers leak to atmosphere
    through ISO 6358 restrictions (choked), which neither the built-in laminar
    external_leakage nor this outside orifice law is. Attribution must weigh
    the outside effect through the kernel's derivative like a built-in one:
    both describe the same leak, so on the same rows each explains a like
    share of the residual's rates (all pressure rows: measured 0.058 and
    0.054; the bootstrap then keeps the built-in one, inclusion 0.67 against
    0.35, and discovery refits it). Both act at rest, so each is also judged
    on the quiet rows (docs/effects.md, "Judged where it acts"), where the
    outside effect's evidence is its best: the shares are compared with
    that row set off, so that they are read on the same rows.
    """
    import pneumafit as pf
    from pneumafit.discovery import attribution

    _register_orifice("atm_orifice", atm_orifice,
                      "q = K dP / sqrt(|dP| + 1 kPa) out of each chamber")  # fmt: skip
    campaign = pf.read_campaign(Path(__file__).resolve().parents[1] / "data" / "demo")
    fit = pf.fit(campaign, "convection", mcmc=False, seed=0)
    found = pf.discover(campaign, fit, rounds=1)
    assert found.selected == ["external_leakage"]
    candidates = {c.effect: c for a in found.attributions for c in a.candidates}
    # its coefficient, from its best row set: the demo's leaks (1.1 and 0.6
    # l/min ANR at 7 bar, about 2e-5 and 1e-5 kg/s at 6 bar over atmosphere)
    # are K of 1-3e-8 in this law
    lo, hi = candidates["atm_orifice"].coefficient_interval
    assert 5e-9 < lo <= candidates["atm_orifice"].coefficient <= hi < 1e-7
    monkeypatch.setattr(attribution, "MIN_QUIET_BLOCKS", 10**9)
    on_pressure = pf.discover(campaign, fit, rounds=1)
    candidates = {c.effect: c for a in on_pressure.attributions for c in a.candidates}
    mine, builtin = candidates["atm_orifice"], candidates["external_leakage"]
    assert mine.rows == builtin.rows == "pressure"
    # a like share: within a factor 2 of the built-in law's (the other
    # candidates explain 0.01 or less)
    assert 0.5 < mine.variance_explained / builtin.variance_explained < 2.0
    lo, hi = mine.coefficient_interval  # measured 1.85e-8 [1.47e-8, 2.47e-8]
    assert 5e-9 < lo <= mine.coefficient <= hi < 1e-7


# ----------------------------------------------------------------- a valve law from outside
# The ISO 6358 law written again from the physics module's scalar functions
# (conductances, path_flow: no arrays), as a valve law of one's own. Its
# sonic conductances are read from ``c_s`` and ``c_e`` (the built-in names for
# the twin, parameters of its own for the fitted law); the rest of the ISO
# parameters are the table's.
_ISO = {n: layout.P[n] for n in parts.VALVE_LAWS["iso6358"].parameters}
_PS, _PEX = layout.P["supply_pressure"], layout.P["exhaust_pressure"]


def iso_again(c_s: int, c_e: int) -> object:
    """The ISO 6358 law's flows with its conductances at indices c_s, c_e of p."""
    from pneumafit.physics.air import T_REF
    from pneumafit.physics.valve import conductances, path_flow

    i = _ISO
    ov, us, cl, lw = i["valve_overlap"], i["valve_u_sat"], i["valve_C_leak"], i["valve_leak_width"]
    ns, ne, fs, fe = (i["valve_n_supply"], i["valve_n_exhaust"], i["valve_full_supply"],
                      i["valve_full_exhaust"])  # fmt: skip
    nu, ks, ke = i["valve_null_offset"], i["valve_knee_supply"], i["valve_knee_exhaust"]
    vm, xl, bs, be = i["valve_m"], i["valve_x_laminar"], i["valve_b_supply"], i["valve_b_exhaust"]
    ta, pe = _TAMB, _PEX

    @njit
    def flows(u, pres, temp, p_s, p):
        cs, ce = conductances(u, p[c_s], p[c_e], p[ov], p[us], p[cl], p[lw], p[ns], p[ne],
                              p[fs], p[fe], p[nu], p[ks], p[ke])  # fmt: skip
        t_a = p[ta]
        rt_a = math.sqrt(T_REF / t_a)
        rt = math.sqrt(T_REF / temp)
        q_s, t_s = path_flow(cs, p[bs], p[vm], p[xl], p_s, t_a, rt_a, pres, temp, rt)
        q_e, t_e = path_flow(ce, p[be], p[vm], p[xl], pres, temp, rt, p[pe], t_a, rt_a)
        return q_s - q_e, q_s * t_s - q_e * t_e, q_s

    return flows


def _register_iso_again(name: str = "iso-again", own: bool = False) -> parts.ValveLaw:
    names = ["valve_C_supply", "valve_C_exhaust"]
    if own:
        names = ["my_C_supply", "my_C_exhaust"]
        for n in names:
            parts.register_parameter(
                ParameterSpec(n, "m^3/s/Pa", 1e-8, 1e-10, 1e-7, "valve", f"{n} (test part)")
            )
    iso = parts.VALVE_LAWS["iso6358"]
    rest = [n for n in iso.parameters if n not in ("valve_C_supply", "valve_C_exhaust")]
    return parts.register_valve_law(
        parts.ValveLaw(
            name=name, code=7, parameters=(*names, *rest),
            description="ISO 6358 written again (test part)",
            kernel=iso_again(layout.P[names[0]], layout.P[names[1]]),
            starts=({names[0]: 2e-8, names[1]: 2e-8},) if own else (),
        )
    )  # fmt: skip


def _flow_experiment() -> Experiment:
    t = np.linspace(0.0, 1.0, 201)
    return Experiment(time=t, kind="flow", chamber="P", u_P=np.linspace(-10.0, 10.0, 201),
                      p_chamber=np.linspace(1.2e5, 6.9e5, 201), name="flow")  # fmt: skip


def test_an_outside_valve_law_simulates_as_its_builtin_twin(
    registered: None, step_experiment: Experiment, charge_experiment: Experiment
) -> None:
    """Identity to rounding: the ISO 6358 law written again from the physics
    module's scalar functions, reached through ``kernel.part_valve``. The
    kernel's own branch (``flows_core``) computes the same law from
    precomputed constants, so the two differ by rounding only: a hook that
    mixed the chambers, lost the supply draw or the enthalpy's temperatures
    would differ by kPa and grams. Tolerances: measured 2026-11-30, max |dp|
    5.8e-10 Pa over the step and charge tests and 5e-12 relative on the
    flow test's mass flow; held to 1e-6 Pa and 1e-9 relative (rounding of
    other arithmetic orders, under fastmath, with margin; a pressure
    sensor's noise is 150 Pa). The twin's rate bound, on a grid, came out
    1.09x the ISO law's analytic one in step size."""
    from pneumafit.analysis.linear import equilibrium, overlap
    from pneumafit.simulation import choose_step

    _register_iso_again()
    values = default_parameters()
    values["valve_C_leak"] = 2e-10
    vec = parameter_vector(values)
    builtin = Simulator(ModelStructure("convection"))
    outside = Simulator(ModelStructure("convection", valve="iso-again"))
    assert builtin._kernel is kernel and outside._kernel is not kernel
    exps = [step_experiment, charge_experiment, _flow_experiment()]
    ref, st_ref = builtin.simulate_batch(vec[None], exps)
    out, st_out = outside.simulate_batch(vec[None], exps)
    assert (st_ref == 0).all() and (st_out == 0).all()
    channels = builtin.channels
    for name in ("p_P", "p_N"):
        j = channels.index(name)
        assert np.nanmax(np.abs(out[0, :, j] - ref[0, :, j])) < 1e-6  # Pa
    for name in ("qm_P", "m_supply"):
        j = channels.index(name)
        np.testing.assert_allclose(out[0, :, j], ref[0, :, j], rtol=1e-9, atol=1e-15)
    # the rate bound: the twin's on a grid is at most the ISO law's analytic
    # bound (which counts the leak twice over) and not far below it
    h_ref = choose_step(vec, default=1.0)
    h_out = choose_step(vec, default=1.0, valve="iso-again")
    assert h_ref <= h_out < 1.5 * h_ref
    # the linear analysis: the same equilibrium and dead band
    eq_ref = equilibrium(vec, 0.2)
    eq_out = equilibrium(vec, 0.2, valve="iso-again")
    assert eq_out.exists and eq_ref.exists
    np.testing.assert_allclose([eq_out.p_P, eq_out.p_N], [eq_ref.p_P, eq_ref.p_N], rtol=1e-9)
    # the dead band by the map's edge rule on the law's flows: the ISO
    # overlap to the rule's 1-mV grid without a centre leakage; with the
    # table's leakage (1e-11, shifting over 0.3 V) 0.282 V, as the map
    # sampled from this valve (0.283 V, docs/physics.md)
    tight = parameter_vector({**default_parameters(), "valve_C_leak": 0.0})
    assert abs(overlap(tight, "iso-again") - values["valve_overlap"]) < 1e-3  # V
    nominal = parameter_vector(default_parameters())
    assert abs(overlap(nominal, "iso-again") - 0.283) < 2e-3  # V


def test_an_outside_valve_law_s_parameters_are_fitted_from_the_flow_tests(
    registered: None,
) -> None:
    """Plumbing: the law's own parameters (group "valve") are free by default,
    flow tests depend on them (the sparse Jacobian must not skip them), the
    valve stage starts from ``ValveLaw.starts``, and a kernel code on a
    built-in code or a law without kernel code is refused."""
    from dataclasses import replace

    from pneumafit.identification import ParameterSet
    from pneumafit.identification.problem import Problem

    law = _register_iso_again("mine", own=True)
    structure = ModelStructure("convection", valve="mine")
    ps = ParameterSet.for_model(structure)
    free = set(ps.free_names)
    assert {"my_C_supply", "my_C_exhaust", "valve_b_supply", "valve_overlap"} <= free
    assert not {"valve_C_supply", "valve_x_laminar", "valve_u_sat"} & free
    import pneumafit as pf

    demo = pf.read_campaign(Path(__file__).resolve().parents[1] / "data" / "demo")
    rec = next(r for r in demo.by_role("fit") if r.kind == "flow")
    problem = Problem([rec], structure, {**ps.values(), **demo.rig.as_parameters()})
    skipped = problem.unaffected(["my_C_supply", "valve_b_supply", "friction_static"])
    assert skipped[:, 0].tolist() == [False, False, True]
    assert law.starts == ({"my_C_supply": 2e-8, "my_C_exhaust": 2e-8},)
    with pytest.raises(ValueError, match="code outside"):
        parts.register_valve_law(replace(parts.VALVE_LAWS["map"], kernel=law.kernel),
                                 replace=True)  # fmt: skip
    assert parts.VALVE_LAWS["map"].kernel is None
    parts.register_valve_law(replace(law, name="python-only", code=8, kernel=None, starts=()))
    with pytest.raises(ValueError, match=r"ValveLaw\.kernel"):
        ModelStructure("convection", valve="python-only").config()


@pytest.mark.slow
def test_an_outside_valve_law_is_fitted_saved_and_linearised(
    registered: None, tmp_path: Path
) -> None:
    """Plumbing, an inverse crime on purpose: the ISO 6358 law with sonic
    conductances of its own (``my_C_supply``, ``my_C_exhaust``, log scale by
    their bounds' span), fitted with ``FitOptions(valve=NAME)`` on the
    virtual rig's quick plan, whose valve is the ISO law. The check is that
    the law reaches every stage (valve stage from its starts, joint stage,
    fit.json, the linear analysis), so its conductances must land on the
    rig's: measured 2026-11-30 at 9.998e-9 and 1.0976e-8 against 1e-8 and
    1.1e-8 (0.02 % and 0.2 %); held to 3 %, a few of the flow levels'
    noise-limited standard errors."""
    import pneumafit as pf
    from pneumafit.analysis.linear import equilibrium
    from pneumafit.identification.staged import FitOptions, FitResult
    from pneumafit.virtual_rig import VirtualRig

    _register_iso_again("mine", own=True)
    folder = tmp_path / "campaign"
    VirtualRig(seed=3).write(folder, protocol="quick")
    campaign = pf.read_campaign(folder)
    fit = pf.fit(campaign, "convection", mcmc=False, seed=0, options=FitOptions(valve="mine"))
    assert fit.structure.valve == "mine"
    valve = next(s for s in fit.stages if s.name == "valve")
    assert {"my_C_supply", "my_C_exhaust"} <= set(valve.free)
    values = fit.parameters.values()
    assert values["my_C_supply"] == pytest.approx(1e-8, rel=0.03)
    assert values["my_C_exhaust"] == pytest.approx(1.1e-8, rel=0.03)
    fit.save(tmp_path / "fit.json")
    again = FitResult.load(tmp_path / "fit.json")
    assert again.structure.valve == "mine"
    assert again.parameters.values()["my_C_supply"] == values["my_C_supply"]
    model = {n: v for n, v in values.items() if n in layout.P}  # less the initial states
    eq = equilibrium(parameter_vector(model), 0.2, valve="mine")
    assert eq.exists and 1e5 < eq.p_N < values["supply_pressure"]


def test_the_parts_digest_follows_the_law_s_code(registered: None) -> None:
    """A saved fit is reused by a run only with the same outside parts
    (``provenance.parts``): the digest changes with a law's kernel code (its
    closure's constants here, the paths' conductances swapped) and comes
    back with the same code compiled again."""
    from dataclasses import replace

    from pneumafit.models.part_kernel import parts_digest

    before = parts_digest()
    law = _register_iso_again("mine", own=True)
    one = parts_digest()
    assert one != before
    c_s, c_e = layout.P["my_C_supply"], layout.P["my_C_exhaust"]
    parts.register_valve_law(replace(law, kernel=iso_again(c_e, c_s)), replace=True)
    assert parts_digest() != one
    parts.register_valve_law(replace(law, kernel=iso_again(c_s, c_e)), replace=True)
    assert parts_digest() == one


# --------------------------------------------- a friction law with a state of its own
_SIG0_I, _SIG1_I = layout.P["friction_stiffness"], layout.P["friction_damping"]


@njit
def lugre_again_force(v, f_s, f_c, x, p):
    """The LuGre force from the bristle slot, its relaxation not limited."""
    _dz, f = lugre_friction(v, x[layout.X_Z], f_s, f_c, p[_FV_I], p[_VST_I], p[_SIG0_I],
                            p[_SIG1_I], math.inf)  # fmt: skip
    return f


@njit
def lugre_again_rate(v, f_s, f_c, x, p, max_rate):
    """The LuGre bristle rate, limited as the kernel limits its own."""
    dz, _f = lugre_friction(v, x[layout.X_Z], f_s, f_c, p[_FV_I], p[_VST_I], p[_SIG0_I],
                            p[_SIG1_I], max_rate)  # fmt: skip
    return dz


def _register_lugre_again() -> None:
    parts.register_friction_law(
        parts.FrictionLaw(
            name="lugre-again", code=7, parameters=parts.FRICTION_LAWS["lugre"].parameters,
            description="LuGre written again, its bristle state through state_rate",
            kernel=lugre_again_force, state_rate=lugre_again_rate,
        )
    )  # fmt: skip


def test_an_outside_friction_law_with_a_state_simulates_as_lugre(
    registered: None, step_experiment: Experiment
) -> None:
    """Identity (not recovery): LuGre written again from outside, its bristle
    deflection a state of its own (``FrictionLaw.state_rate``, the bristle
    slot), against the kernel's LuGre on the step test, both from z = 0.
    The force function does not get the step's rate limit, so the bristles
    are made soft enough (sigma0 = 2e4 N/m) that the limit never acts on
    this test (checked: the relaxation rate stays below 1 / h), and then the
    same arithmetic runs through the hooks: measured bit for bit (the
    frozen state: 64 mm apart); held to
    1e-6 Pa, 1e-12 m and 1e-9 N (rounding of another inlining, with margin). Without
    the state's rate (the state frozen at 0) the piston obeys F = (sigma1 +
    b) v and ends millimetres elsewhere, so the check is not vacuous. The
    step bound from central differences equals the LuGre law's analytic
    one to 1e-6 (differences are exact for the law's linear dependence on v
    and z at rest, up to rounding)."""
    import dataclasses

    from pneumafit.simulation import choose_step

    values = default_parameters()
    values["friction_stiffness"] = 2.0e4
    vec = parameter_vector(values)
    exp = dataclasses.replace(step_experiment, initial={**step_experiment.initial, "z_f": 0.0})
    channels = ("y", "v", "p_P", "p_N", "F_f")
    builtin = Simulator(ModelStructure("convection", friction="lugre"), channels=channels)
    _register_lugre_again()
    outside = Simulator(ModelStructure("convection", friction="lugre-again"), channels=channels)
    assert outside._kernel is not kernel
    ref, st_ref = builtin.simulate_batch(vec[None], [exp])
    out, st_out = outside.simulate_batch(vec[None], [exp])
    assert (st_ref == 0).all() and (st_out == 0).all()
    v = ref[0, :, channels.index("v")]
    assert np.ptp(ref[0, :, channels.index("F_f")]) > 30.0  # N: friction both ways
    # the relaxation rate sigma0 |v| / g stays below the limit 1 / h (g >= F_c)
    assert np.max(np.abs(v)) * values["friction_stiffness"] / values["friction_coulomb"] < 1e3
    for name in ("p_P", "p_N"):
        j = channels.index(name)
        assert np.nanmax(np.abs(out[0, :, j] - ref[0, :, j])) < 1e-6  # Pa
    j = channels.index("y")
    assert np.nanmax(np.abs(out[0, :, j] - ref[0, :, j])) < 1e-12  # m
    j = channels.index("F_f")  # sigma0 z + sigma1 dz/dt + b v: the state itself
    assert np.nanmax(np.abs(out[0, :, j] - ref[0, :, j])) < 1e-9  # N
    # the state's rate matters: frozen, the piston ends elsewhere
    parts.register_friction_law(
        dataclasses.replace(parts.FRICTION_LAWS["lugre-again"], name="lugre-frozen", code=8,
                            state_rate=None)
    )  # fmt: skip
    frozen, _ = Simulator(
        ModelStructure("convection", friction="lugre-frozen"), channels=channels
    ).simulate_batch(vec[None], [exp])
    y = channels.index("y")
    assert np.nanmax(np.abs(frozen[0, :, y] - ref[0, :, y])) > 1e-3  # m
    # the step bound from the hooks at rest against LuGre's analytic bound,
    # with bristles stiff enough that their mode sets the step (measured:
    # equal to the last digit, 0.344 ms against the chambers' 0.585 ms);
    # frozen, the state's mode is not counted
    stiff = parameter_vector({**values, "friction_stiffness": 1e8, "friction_damping": 5e4})
    h_ref = choose_step(stiff, default=1.0, friction="lugre")
    h_out = choose_step(stiff, default=1.0, friction="lugre-again")
    assert h_ref < 0.9 * choose_step(stiff, default=1.0, friction="switch")
    assert abs(h_out / h_ref - 1.0) < 1e-6
    assert choose_step(stiff, default=1.0, friction="lugre-frozen") > 1.5 * h_ref


def test_a_state_rate_needs_the_force_that_reads_it(registered: None) -> None:
    """Plumbing: the checks of ``register_friction_law`` on ``state_rate``, and
    the parts' fingerprint (``pipeline.fit_is_reusable``) follows it: a law
    that gains or loses its state is another law."""
    import dataclasses

    from pneumafit.models.part_kernel import parts_digest

    _register_lugre_again()
    with_state = parts_digest()
    law = parts.FRICTION_LAWS["lugre-again"]
    parts.register_friction_law(dataclasses.replace(law, state_rate=None), replace=True)
    assert parts_digest() != with_state
    parts.register_friction_law(law, replace=True)
    assert parts_digest() == with_state
    with pytest.raises(PneumafitInputError, match="state_rate: expected it only with kernel"):
        parts.register_friction_law(
            parts.FrictionLaw(name="rate-only", code=9, parameters=("friction_coulomb",),
                              description="no force", state_rate=lugre_again_rate)
        )  # fmt: skip
    with pytest.raises(PneumafitInputError, match="state_rate: expected a numba @njit"):
        parts.register_friction_law(
            parts.FrictionLaw(name="rate-python", code=9, parameters=("friction_coulomb",),
                              description="a Python rate", kernel=lugre_again_force,
                              state_rate=lugre_again_rate.py_func)
        )  # fmt: skip


def test_attribution_rebuilds_the_state_of_an_outside_friction_law(registered: None) -> None:
    """Identity to rounding: discovery's rates along a recording rebuild a
    sliding piston's friction state, which measurements do not give. For
    LuGre written again the root of its rate (bisection on the hook) is the
    kernel's analytic sign(v) g(v) / sigma0, so the acceleration column
    equals the built-in LuGre's (measured: 2.4e-16 relative at most; held to 1e-9).
    With z left at 0, as before, the outside law's force would miss the
    whole sliding level g(v), about 30 N / 17 kg = 1.8 m/s^2."""
    from pneumafit.discovery.attribution import _rates_along
    from pneumafit.models.part_kernel import rebound

    _register_lugre_again()
    vec = parameter_vector(default_parameters())
    d = np.empty(kernel.ND)
    kernel.derive(vec, d)
    speeds = np.array([-0.4, -0.02, -1e-4, 0.0, 3e-3, 0.05, 0.6])  # m/s
    xs = np.zeros((speeds.size, layout.NX))
    xs[:, layout.X_Y] = 0.25
    xs[:, layout.X_V] = speeds
    xs[:, layout.X_PP], xs[:, layout.X_PN] = 5.0e5, 3.0e5
    xs[:, layout.X_TP] = xs[:, layout.X_TN] = 293.15
    modes = np.zeros(speeds.size, dtype=np.int64)
    cmds = np.zeros((speeds.size, 2))
    ref_cfg = ModelStructure("convection", friction="lugre").config()
    out_structure = ModelStructure("convection", friction="lugre-again")
    ref = _rates_along(xs, modes, cmds, vec, d, ref_cfg)
    out = rebound(_rates_along, kernel_for(out_structure))(
        xs, modes, cmds, vec, d.copy(), out_structure.config()
    )
    np.testing.assert_allclose(out[:, 6], ref[:, 6], rtol=1e-9, atol=1e-9)
    sliding = np.abs(speeds) > 0.01
    # the level the root carries: LuGre's g(v) over the mass, far above rounding
    assert np.min(np.abs(ref[sliding, 6] - ref[speeds == 0.0, 6])) > 0.5  # m/s^2


# -------------------------------------------------- an effect with a state of its own
@functools.cache
def _drain_functions(
    c_index: int, tau_index: int, slot: int = layout.X_E0, chamber: str = "P"
) -> tuple[object, object]:
    """A drain out of chamber P (or N) whose mass flow e (kg/s), a state in
    ``slot``, opens towards c with time constant tau: de/dt = (c - e) / tau."""
    if chamber == "P":

        @njit
        def drain(x, p):
            e = x[slot]
            return -e, -e * x[_XTP], 0.0, 0.0, e, 0.0

    else:

        @njit
        def drain(x, p):
            e = x[slot]
            return 0.0, 0.0, -e, -e * x[_XTN], e, 0.0

    @njit
    def rate(x, p):
        return (p[c_index] - x[slot]) / p[tau_index]

    return drain, rate


def _drain_parameters(name: str, flow: float, time: float) -> tuple[int, int]:
    """Register a drain's final flow ``NAME_flow`` (kg/s) and opening time
    ``NAME_time`` (s) with these defaults; their indices in the vector."""
    for spec in (
        ParameterSpec(f"{name}_flow", "kg/s", flow, 1e-9, 1e-3, "effect", "final flow"),
        ParameterSpec(f"{name}_time", "s", time, 1e-3, 10.0, "effect", "opening time"),
    ):
        parts.register_parameter(spec)
    return layout.P[f"{name}_flow"], layout.P[f"{name}_time"]


def _register_drain_effect(
    name: str, flow: float, time: float, functions: Callable[..., tuple[object, object]],
    states: tuple[int, ...], description: str,
) -> parts.Effect:  # fmt: skip
    """Register a drain effect: its parameters (:func:`_drain_parameters`),
    its law and rate from ``functions(c_index, tau_index)``, its states."""
    drain, rate = functions(*_drain_parameters(name, flow, time))
    effect = _effect(
        name, f"{name}_flow", (f"{name}_flow", f"{name}_time"), drain,
        (parts.FitRange(f"{name}_flow", 1e-9, 1e-4), parts.FitRange(f"{name}_time", 1e-2, 5.0)),
        description,
    )  # fmt: skip
    return parts.register_effect(replace(effect, states=states, state_rate=rate))


def _register_drain() -> None:
    _register_drain_effect(
        "drain",
        2e-6,
        0.3,
        _drain_functions,
        (layout.X_E0,),
        "a drain out of chamber P opening over time (state e in slot X_E0)",
    )


def test_an_outside_effect_with_a_state_of_its_own(registered: None) -> None:
    """Analytic (not recovery): the drain's flow e obeys de/dt = (c - e) /
    tau from e = 0, so the air it sends to atmosphere is m(t) = c (t - tau (1
    - exp(-t / tau))); the valve is closed and leak-free, so m_exhaust is that
    integral alone. Kutta's RK3 at 1 ms on this linear state: measured 1.3e-11
    relative at 1.5 s, 9e-7 relative after the first step (3e-18 kg: the
    step's O(h^4) error against an integral still O(h^2)); held to 1e-6
    relative plus 1e-15 kg (4e-10 of the final value). A state integrated at
    the wrong rate, frozen, or taken as instantaneous (c t: 25 % off at 1.5
    s) fails by far."""
    _register_drain()
    values = default_parameters()
    values["valve_C_leak"] = 0.0
    c, tau = values["drain_flow"], values["drain_time"]
    t = np.arange(0.0, 1.5005, 1e-3)
    exp = Experiment(time=t, kind="charge", chamber="P", u_P=np.zeros(t.size),
                     initial={"y": 0.2, "p_P": 3.0e5}, name="drain")  # fmt: skip
    structure = ModelStructure("convection", effects={"drain": 1})
    assert structure.state_names[-1] == "e_0"
    run = Simulator(structure).simulate(values, exp)
    assert run.ok
    expected = c * (t - tau * (1.0 - np.exp(-t / tau)))
    np.testing.assert_allclose(run["m_exhaust"], expected, rtol=1e-6, atol=1e-15)
    assert abs(c * t[-1] - expected[-1]) > 0.2 * expected[-1]
    # the chamber loses that air: its pressure falls
    assert run["p_P"][-1] < run["p_P"][0] - 1e3


def test_outside_effects_with_a_state_each_run_together(registered: None) -> None:
    """Analytic (not recovery): three drains, each with its flow a state of
    its own in a slot of its own (X_E0 out of chamber P, X_E2 and X_E1 out
    of chamber N, registered in that order), with other final flows and
    opening times; valves closed and leak-free, so the air sent to
    atmosphere is the sum of c_k (t - tau_k (1 - exp(-t / tau_k))). Held to
    1e-6 relative plus 1e-15 kg, as the one drain above (Kutta's RK3 on
    linear states; measured 5.7e-7 relative at most, 1.9e-11 at 1.5 s).
    Slots X_E1 and X_E2 lie past the cached kernel's state vector: the copy
    is compiled with 18 states (``layout.state_size``). A slot whose rate
    went to another slot, or was left at 0, fails: each drain alone is a
    quarter or more of the sum (checked). The same on the reference solver
    and the sampled closed loop, which size their state vectors alike."""
    _register_drain()
    # opening times no shorter than the one drain's (0.3 s): the same RK3
    # error argument, and so the same tolerance, holds for each
    drains = {"drain_n": (layout.X_E2, 2e-6, 0.5), "drain_m": (layout.X_E1, 3e-6, 1.0)}
    for name, (slot, flow, time) in drains.items():
        functions = functools.partial(_drain_functions, slot=slot, chamber="N")
        _register_drain_effect(name, flow, time, functions, (slot,), "a drain out of chamber N")
    values = default_parameters()
    values["valve_C_leak"] = 0.0
    t = np.arange(0.0, 1.5005, 1e-3)
    exp = Experiment(time=t, kind="charge", chamber="P", u_P=np.zeros(t.size),
                     initial={"y": 0.2, "p_P": 3.0e5, "p_N": 3.0e5}, name="drains")  # fmt: skip
    structure = ModelStructure("convection", effects={"drain": 1, "drain_n": 1, "drain_m": 1})
    assert structure.state_names[-3:] == ("e_0", "e_2", "e_1")
    run = Simulator(structure).simulate(values, exp)
    assert run.ok
    each = [
        values[f"{n}_flow"] * (t - values[f"{n}_time"] * (1.0 - np.exp(-t / values[f"{n}_time"])))
        for n in ("drain", "drain_n", "drain_m")
    ]
    np.testing.assert_allclose(run["m_exhaust"], sum(each), rtol=1e-6, atol=1e-15)
    assert min(e[-1] for e in each) > 0.25 * sum(each)[-1]
    # chamber P loses the first drain's air (a blocked test of chamber P
    # holds chamber N's pressure: its drains show in the air sent out only)
    assert run["p_P"][-1] < run["p_P"][0] - 1e3
    # the reference solver (Radau) on the same copy's state vector: measured
    # 3.2e-12 kg at most, held to its own absolute tolerance on the air
    # accounts (1e-3 kg * rtol = 1e-11 kg)
    ref = solve_reference(structure, values, exp, rtol=1e-8)
    np.testing.assert_allclose(ref["m_exhaust"], sum(each), rtol=0.0, atol=1e-11)
    # the sampled closed loop on the same copy (its own buffers sized alike):
    # a controller that holds the valves shut, the piston free; the drains'
    # air does not depend on the motion
    from pneumafit.simulation import simulate_sampled

    assert kernel_for(structure).NX == 18
    loop = simulate_sampled(parameter_vector(values), t, np.full(t.size, 0.2),
                            lambda state, y_ref: 0.0, model=structure,
                            initial={"y": 0.2, "p_P": 3.0e5, "p_N": 3.0e5})  # fmt: skip
    assert loop.status == 0
    np.testing.assert_allclose(loop["m_exhaust"], sum(each), rtol=1e-6, atol=1e-15)


def _second_order_drain(
    c_index: int, tau_index: int, slots: tuple[int, int] = (layout.X_E2, layout.X_E0)
) -> tuple[object, object]:
    """A drain out of chamber P whose flow e (kg/s) opens towards c as a
    critically damped second-order system of time constant tau: two states
    of one effect, e in ``slots[0]`` and w = de/dt in ``slots[1]``, de/dt =
    w, dw/dt = (c - e) / tau^2 - 2 w / tau."""

    @njit
    def drain(x, p):
        e = x[slots[0]]
        return -e, -e * x[_XTP], 0.0, 0.0, e, 0.0

    @njit
    def rate(x, p):
        tau = p[tau_index]
        e, w = x[slots[0]], x[slots[1]]
        return w, (p[c_index] - e) / (tau * tau) - 2.0 * w / tau

    return drain, rate


def test_an_outside_effect_with_two_states_of_its_own(registered: None) -> None:
    """Analytic (not recovery): a drain whose flow e opens towards c as a
    critically damped second-order system (two states of one effect: e in
    slot X_E2, w = de/dt in X_E0, in that order, so that a rate written to
    the wrong slot shows), e(t) = c (1 - (1 + t / tau) exp(-t / tau)) from
    rest, beside the one-state drain of chamber N in the remaining slot
    X_E1; valves closed and leak-free, so the air sent to atmosphere is m(t)
    = c (t - 2 tau + (2 tau + t) exp(-t / tau)) plus the first-order drain's
    c' (t - tau' (1 - exp(-t / tau'))). Kutta's RK3 on linear states with
    time constants of 0.3 s and more, as the drains above: held to 1e-6
    relative plus 1e-15 kg (measured 3.9e-11 relative at 1.5 s; 3.8e-6
    relative over the first steps, where the air sent is ~1e-12 kg and the
    error within the 1e-15 kg). The reference solver (Radau) measured 2.7e-12
    kg, held to its own absolute tolerance on the air accounts, 1e-11 kg.
    Not vacuous: the second-order opening differs from a first-order one of
    the same tau by over 20 % of the air sent, and each drain is a quarter
    or more of the sum (checked on the closed forms), so a rate written to
    the wrong slot, or a state left at 0, fails."""
    _register_drain_effect(
        "drain2",
        2e-6,
        0.3,
        _second_order_drain,
        (layout.X_E2, layout.X_E0),
        "a drain out of chamber P opening in second order",
    )
    functions = functools.partial(_drain_functions, slot=layout.X_E1, chamber="N")
    _register_drain_effect(
        "drain_n", 1.5e-6, 0.5, functions, (layout.X_E1,), "a drain out of chamber N"
    )
    values = default_parameters()
    values["valve_C_leak"] = 0.0
    t = np.arange(0.0, 1.5005, 1e-3)
    exp = Experiment(time=t, kind="charge", chamber="P", u_P=np.zeros(t.size),
                     initial={"y": 0.2, "p_P": 3.0e5, "p_N": 3.0e5}, name="drains")  # fmt: skip
    structure = ModelStructure("convection", effects={"drain2": 1, "drain_n": 1})
    assert structure.state_names[-3:] == ("e_2", "e_0", "e_1")
    assert kernel_for(structure).NX == 18
    c, tau = values["drain2_flow"], values["drain2_time"]
    c_n, tau_n = values["drain_n_flow"], values["drain_n_time"]
    second = c * (t - 2.0 * tau + (2.0 * tau + t) * np.exp(-t / tau))
    first_n = c_n * (t - tau_n * (1.0 - np.exp(-t / tau_n)))
    expected = second + first_n
    run = Simulator(structure).simulate(values, exp)
    assert run.ok
    np.testing.assert_allclose(run["m_exhaust"], expected, rtol=1e-6, atol=1e-15)
    # what a miswired state would give, on the closed forms
    first = c * (t - tau * (1.0 - np.exp(-t / tau)))
    assert np.max(np.abs(first - second)) > 0.2 * second[-1]
    assert second[-1] > 0.25 * expected[-1] and first_n[-1] > 0.25 * expected[-1]
    ref = solve_reference(structure, values, exp, rtol=1e-8)
    np.testing.assert_allclose(ref["m_exhaust"], expected, rtol=0.0, atol=1e-11)


def test_an_effect_s_states_are_checked_at_registration(registered: None) -> None:
    _register_drain()
    effect = parts.EFFECTS["drain"]
    _drain, rate = _drain_functions(layout.P["drain_flow"], layout.P["drain_time"])
    _drain2, two_rates = _second_order_drain(layout.P["drain_flow"], layout.P["drain_time"])
    cases = [
        (replace(effect, name="other", states=(layout.X_E0,)), "found 15 taken by 'drain'"),
        (replace(effect, name="other", states=(layout.X_Z,)), "expected distinct slots among"),
        (replace(effect, name="other", states=(layout.X_E1, layout.X_E1)),
         "expected distinct slots among"),
        # one rate for two states, two rates for one state
        (replace(effect, name="other", states=(layout.X_E1, layout.X_E2)),
         r"state_rate: expected a tuple of 2 numbers \(one per state, in the order of states\), "
         "found a number"),
        (replace(effect, name="other", states=(layout.X_E1,), state_rate=two_rates),
         "state_rate: expected one number, found a tuple of 2"),
        (replace(effect, name="other", state_rate=None), "found no state_rate"),
        (replace(effect, name="other", states=()), "state_rate: expected it only with states"),
        (replace(effect, name="other", state_rate=rate.py_func),
         "state_rate: expected a numba @njit"),
    ]  # fmt: skip
    for bad, message in cases:
        with pytest.raises(PneumafitInputError, match=message):
            parts.register_effect(bad)
    assert "other" not in parts.EFFECTS


@njit
def _five_terms(x, p):
    return 0.0, 0.0, 0.0, 0.0, 0.0


@njit
def _two_flows(u, pres, temp, p_s, p):
    return 0.0, 0.0


@njit
def _force_and_rate(v, f_s, f_c, x, p):
    return f_c, 0.0


@njit
def _lambda_pair(p, pres, temp, t_wall):
    return 1.0, 2.0


def test_what_a_part_s_compiled_code_returns_is_checked_at_registration(
    registered: None,
) -> None:
    """A part's kernel code that returns the wrong number of terms is named
    at registration (its Python function called once on a plausible
    operating point), not left to a typing error of the compiled simulator
    (which the command line reported as an internal error); nothing is
    registered. The parts of this file that return the right terms register
    (the other tests)."""
    leak = _effect("five", "external_leak_conductance", ("external_leak_conductance",),
                   _five_terms, (parts.FitRange("external_leak_conductance", 1e-12, 1e-8),),
                   "five terms instead of six")  # fmt: skip
    iso = parts.VALVE_LAWS["iso6358"]
    cases = [
        (parts.register_effect, leak,
         r"effect 'five': kernel: expected a tuple of 6 numbers \(q_P, H_P, q_N, H_N, q_atm, F\), "
         "found a tuple of 5"),
        (parts.register_valve_law,
         parts.ValveLaw(name="two-flows", code=7, parameters=iso.parameters,
                        description="two flows", kernel=_two_flows),
         r"kernel: expected a tuple of 3 numbers \(q_net, h_in, q_supply\), found a tuple of 2"),
        (parts.register_friction_law,
         parts.FrictionLaw(name="pair", code=7, parameters=("friction_coulomb",),
                           description="a pair", kernel=_force_and_rate),
         r"kernel: expected one number \(the friction force\), found a tuple of 2"),
        (parts.register_heat_law, _heat_law("pair", 7, _lambda_pair, "a pair"),
         r"kernel: expected one number \(lambda\), found a tuple of 2"),
    ]  # fmt: skip
    for register, part, message in cases:
        with pytest.raises(PneumafitInputError, match=message):
            register(part)
    assert "five" not in parts.EFFECTS and "two-flows" not in parts.VALVE_LAWS
    assert "pair" not in parts.FRICTION_LAWS and "pair" not in parts.HEAT_LAWS


@njit
def _not_compilable(x, p):
    return 0.0, 0.0, 0.0, 0.0, 0.0, NO_SUCH_NAME * p[0]  # noqa: F821 - on purpose


def test_a_part_numba_cannot_compile_is_named_before_a_simulation(registered: None) -> None:
    """Code that passes registration (its Python call fails, so the return
    check leaves it to the compiler) but that numba cannot compile is named
    as the parts' fault when the kernel's copy is built: an input error with
    numba's own line (the command line's exit 2 and message), not a typing
    error in the middle of a simulation that the command line reported as
    an internal error. The broken copy is not kept: the part registered
    again with code that compiles runs."""
    leak = _effect("broken", "external_leak_conductance", ("external_leak_conductance",),
                   _not_compilable, (parts.FitRange("external_leak_conductance", 1e-12, 1e-8),),
                   "a name numba does not know")  # fmt: skip
    parts.register_effect(leak)
    structure = ModelStructure("convection", effects={"broken": 1})
    with pytest.raises(PneumafitInputError, match=r"\(effect 'broken'\) does not compile with "
                       r"numba: NameError: name 'NO_SUCH_NAME' is not defined"):  # fmt: skip
        kernel_for(structure)
    parts.register_effect(replace(leak, kernel=external_leak_again), replace=True)
    assert kernel_for(structure).NX == layout.NX


def test_c_code_for_the_fmu_is_checked_at_registration(registered: None) -> None:
    """An outside part's C code (``c_code``, ``c_state_rate``: the FMU's
    port of its kernel code, tests/test_fmu.py) is a non-empty string beside
    kernel code, and an effect's state needs its rate in C too."""
    _register_drain()
    effect = parts.EFFECTS["drain"]
    body = "out[0] = out[1] = out[2] = out[3] = out[4] = out[5] = 0.0;"
    rate = "return 0.0;"
    cases = [
        (replace(effect, name="other", states=(), state_rate=None, c_code="  "),
         "c_code: expected the body of a C function as a non-empty string"),
        (replace(effect, name="other", kernel=None, states=(), state_rate=None, c_code=body),
         "c_code: expected it only with kernel code"),
        (replace(effect, name="other", states=(), state_rate=None, c_code=body,
                 c_state_rate=rate),
         "c_state_rate: expected it only with a state of its own and c_code"),
        # the drain's own state (slot X_E0) in C without its rate
        (replace(effect, c_code=body), "c_code: expected a c_state_rate with it"),
    ]  # fmt: skip
    for bad, message in cases:
        with pytest.raises(PneumafitInputError, match=message):
            parts.register_effect(bad, replace=bad.name == "drain")
    assert "other" not in parts.EFFECTS
    assert parts.EFFECTS["drain"].c_code is None  # the refused one left the drain as it was
    parts.register_effect(replace(effect, c_code=body, c_state_rate=rate), replace=True)
    law = _heat_law("lambda-c", 7, constant_lambda_again(_LAM), "constant lambda")
    with pytest.raises(PneumafitInputError, match="c_code: expected the body of a C function"):
        parts.register_heat_law(replace(law, c_code=3))
    with pytest.raises(PneumafitInputError, match="c_code: expected it only with kernel code"):
        parts.register_heat_law(replace(law, kernel=None, c_code="return 1.0;"))
    assert "lambda-c" not in parts.HEAT_LAWS
    parts.register_heat_law(replace(law, c_code="return p[PF_P_lambda];"))


def test_building_the_kernel_copy_says_so(registered: None, caplog) -> None:
    """The copy of the kernel for outside parts is compiled at its first use
    in each process (not in numba's disk cache): the command line's log says
    so once, naming the parts, instead of a silent wait. Building the copy
    compiles nothing (numba compiles at the first call), so this is cheap."""
    import logging

    index = _coefficient("lambda_logged")
    parts.register_heat_law(
        _heat_law("lambda-logged", 7, constant_lambda_again(index), "constant lambda, logged",
                  ("lambda_logged",))
    )  # fmt: skip
    structure = ModelStructure("lambda-logged")
    with caplog.at_level(logging.INFO, logger="pneumafit"):
        first = kernel_for(structure)
        again = kernel_for(structure)
    assert first is again and first is not kernel
    said = [r.getMessage() for r in caplog.records if r.name == "pneumafit.models.part_kernel"]
    assert len(said) == 1, said
    assert "heat law 'lambda-logged'" in said[0] and "compiled at its first use" in said[0]


def test_pneumafit_parts_names_the_states_of_one_s_own(registered: None) -> None:
    """``pneumafit parts`` says which state a law or an effect of one's own
    carries (the bristle slot, the effect slot)."""
    from rich.console import Console

    from pneumafit.cli.plugins import parts_tables

    _register_lugre_again()
    _register_drain()
    console = Console(width=250, color_system=None, record=True)
    for table in parts_tables():
        console.print(table)
    text = console.export_text()
    rows = {line.split("│")[1].strip(): line for line in text.splitlines() if "│" in line}
    assert "its own (@njit), state z_f" in rows["lugre-again"]
    assert "its own (@njit), state e_0" in rows["drain"]
    # a part that brings its C code too: the FMU export takes it
    law = parts.FRICTION_LAWS["lugre-again"]
    parts.register_friction_law(replace(law, c_code="return 0.0;", c_state_rate="return 0.0;"),
                                replace=True)  # fmt: skip
    console = Console(width=250, color_system=None, record=True)
    for table in parts_tables():
        console.print(table)
    rows = {line.split("│")[1].strip(): line for line in console.export_text().splitlines()
            if "│" in line}  # fmt: skip
    assert "its own (@njit) and C (FMU), state z_f" in rows["lugre-again"]


# ------------------------------------------- a Dahl law of one's own on a Dahl rig
_DAHL_S0, _DAHL_S1 = layout.P["friction_stiffness"], layout.P["friction_damping"]


@njit
def dahl_rate(v, f_s, f_c, x, p, max_rate):
    a = min(p[_DAHL_S0] * abs(v) / f_c, max_rate)
    z_ss = math.copysign(f_c / p[_DAHL_S0], v) if v != 0.0 else x[layout.X_Z]
    return a * (z_ss - x[layout.X_Z])


@njit
def dahl_force(v, f_s, f_c, x, p):
    dz = v - p[_DAHL_S0] * abs(v) * x[layout.X_Z] / f_c
    return p[_DAHL_S0] * x[layout.X_Z] + p[_DAHL_S1] * dz + p[_FV_I] * v


@pytest.mark.slow
def test_a_dahl_law_of_one_s_own_on_a_dahl_rig(registered: None, tmp_path: Path) -> None:
    """Mismatched (not an inverse crime): docs/architecture.md's Dahl law,
    with a state of its own (exponent 1, no seal term), fitted to the
    virtual rig's Dahl truth (exponent 1.5, an additive seal term, power-law
    valves, a shifted leak, lagging probes; sparse plan, seed 1), with the
    rig's finer solver and sensor noise. Measured 2026-11-30: held-out step
    test p_N 2.85x and p_P 2.50x the noise (LuGre, the built-in law auto
    keeps: 3.48x and 3.24x), Coulomb level at mid pressure 37.05 N against
    the truth's 37.59 N. Held: the held-out step test within the issue's
    3x, and the Coulomb level within 5 % (the seal term the law lacks costs
    1.4 %). Also the plumbing of a law without a static level: the fit's
    reference figures quote its Coulomb level only (the fit crashed there
    before 2026-11-30).

    Since 2026-12-04 (night) the verdict judges pressures less one zero per
    sensor: the offset the held-out starts take off where the fit
    recordings agree on one (chamber P here, -996 Pa against the truth's
    -960), else the fit recordings' mean residual (chamber N, one step
    test: -105 Pa against the truth's +589). The held-out step test is then
    p_P 2.3x and p_N 3.6x (with the truth's zeros 2.3x and 3.0x). What this
    test holds is the law's: the held-out pressures' shape within 3x (each
    recording's own mean off, as the figures above were measured; 2.50x
    and 2.85x), and chamber P's, whose zero the recordings agree on,
    within 3x in the verdict."""
    import pneumafit as pf
    from pneumafit.identification.staged import FitOptions
    from pneumafit.virtual_rig import VirtualRig
    from pneumafit.virtual_rig.truth import reference_quantities

    parts.register_friction_law(
        parts.FrictionLaw(
            name="dahl-own", code=10, kernel=dahl_force, state_rate=dahl_rate,
            parameters=("friction_coulomb", "friction_stiffness", "friction_damping",
                        "friction_viscous"),
            description="Dahl (1968): a bristle that yields to F_c, no Stribeck drop",
        )
    )  # fmt: skip
    rig = VirtualRig(truth="dahl-bump-leak", seed=1)
    rig.write(tmp_path / "campaign", protocol="sparse")
    truth = reference_quantities(rig.truth, rig.parameters)
    campaign = pf.read_campaign(tmp_path / "campaign")
    fit = pf.fit(campaign, "convection", mcmc=False, seed=1,
                 options=FitOptions(friction="dahl-own"))  # fmt: skip
    reference = fit.metrics["friction_reference"]
    assert "static" not in reference and "sliding" not in reference
    coulomb = reference["coulomb"]["value"]
    assert abs(coulomb / truth["friction_coulomb"] - 1.0) < 0.05
    held_out = {
        c.channel: c for c in fit.quality.channels
        if c.role == "validate" and c.kind == "step" and c.channel in ("p_P", "p_N")
    }  # fmt: skip
    assert set(held_out) == {"p_P", "p_N"} and fit.quality.zeros_applied == ["p_P"]
    assert held_out["p_P"].ratio is not None and held_out["p_P"].ratio < 3.0
    # the shape: the replay's residuals less each recording's own mean
    from pneumafit.identification.replay import replay

    rep = replay(campaign, fit.structure, fit.parameters.values())
    shape = {
        (f, c): float(np.sqrt(np.nanmean(r * r))) / held_out[c].noise
        for f, c, _i, r in rep.offset_free()
        if f == held_out["p_P"].recording and c in held_out
    }  # fmt: skip
    assert len(shape) == 2 and all(v < 3.0 for v in shape.values()), shape
