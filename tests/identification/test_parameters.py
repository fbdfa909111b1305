"""ParameterSet: one type for every stage, saved and reloaded without loss."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pneumafit.campaign import PneumafitInputError
from pneumafit.identification import (
    LogNormal,
    LogUniform,
    Normal,
    Parameter,
    ParameterSet,
    Uniform,
)
from pneumafit.models import PARAMETER_NAMES

RIG = {"bore": 0.032, "rod": 0.02, "stroke": 0.5, "ambient_temperature": 293.15}


def _rich_set() -> ParameterSet:
    """A set using every feature: priors of each kind, fixed, infinite bounds,
    posterior summaries and a correlation matrix."""
    ps = ParameterSet(
        [
            Parameter("xi", 0.4, "", 1e-3, 10.0, scale="log", group="heat", std=0.01,
                      interval_90=(0.38, 0.42), median=0.401, uncertainty="mcmc"),
            Parameter("beta", 0.27, "", 0.05, 0.6, prior=Normal(0.27, 0.05), group="heat"),
            Parameter("friction_static", 50.0, "N", 0.01, 1e4, scale="log",
                      prior=LogNormal(40.0, 1.0)),
            Parameter("friction_coulomb", 30.0, "N", 0.01, 1e4, prior=LogUniform(0.01, 1e4)),
            Parameter("external_force", 0.0, "N", -math.inf, math.inf, fixed=True),
            Parameter("lambda", 15.0, "W/m^2/K", 0.0, 100.0, prior=Uniform(0.0, 100.0),
                      description="constant heat-transfer coefficient"),
        ]
    )  # fmt: skip
    ps.correlation = (("xi", "beta"), np.array([[1.0, -0.999], [-0.999, 1.0]]))
    return ps


def test_save_load_round_trip_is_lossless(tmp_path: Path) -> None:
    ps = _rich_set()
    path = tmp_path / "params.json"
    ps.save(path)
    back = ParameterSet.load(path)
    assert back == ps
    assert back["external_force"].lower == -math.inf
    assert back["xi"].interval_90 == (0.38, 0.42)
    assert back["beta"].prior == Normal(0.27, 0.05)
    # strict JSON: no NaN or Infinity literals
    json.loads(path.read_text(), parse_constant=lambda c: pytest.fail(f"non-standard {c}"))


@settings(max_examples=60, deadline=None)
@given(
    value=st.floats(min_value=1e-12, max_value=1e12, allow_nan=False),
    std=st.floats(min_value=0.0, max_value=1e12, allow_nan=False),
    scale=st.sampled_from(["linear", "log"]),
)
def test_round_trip_keeps_every_float_bit(value: float, std: float, scale: str) -> None:
    p = Parameter("k", value, "", value / 3.0, value * 7.0, scale=scale, std=std,
                  interval_90=(value / 2.0, value * 2.0))  # fmt: skip
    ps = ParameterSet([p])
    back = ParameterSet.from_dict(json.loads(ps.to_json()))
    assert back == ps
    assert back["k"].value == value and back["k"].std == std


def test_internal_coordinates_invert_and_priors_include_the_jacobian() -> None:
    ps = _rich_set()
    z = ps.to_internal()
    assert ps.free_names == ("xi", "beta", "friction_static", "friction_coulomb", "lambda")
    values = ps.to_values(z)
    for name in ps.free_names:
        assert values[name][0] == pytest.approx(ps[name].value, rel=1e-14)
    # a log-uniform prior on a log-scale parameter is flat in log(value)
    flat = ParameterSet([Parameter("xi", 0.4, "", 1e-3, 10.0, scale="log")])
    lp = flat.log_prior(np.log([[0.01], [0.4], [5.0]]))
    assert np.allclose(lp, lp[0])
    # outside the bounds: zero prior density
    assert flat.log_prior(np.log([[20.0]]))[0] == -np.inf
    # a Gaussian prior gives a least-squares residual
    assert ps.prior_residuals(z).size == 2


def test_for_model_fixes_the_rig_and_frees_valve_heat_friction() -> None:
    ps = ParameterSet.for_model("convection", RIG, nuisance=["temperature_sensor_lag"])
    assert set(ps.names) >= {"xi", "beta", "temperature_sensor_lag", "valve_C_leak"}
    assert "lambda" not in ps and "k" not in ps
    assert ps["bore"].fixed and ps["bore"].value == 0.032
    assert ps["wall_temperature"].value == 293.15  # follows ambient
    assert not ps["xi"].fixed and ps["xi"].scale == "log"
    assert ps["beta"].scale == "linear"
    assert ps["valve_u_sat"].fixed and ps["valve_x_laminar"].fixed
    assert set(ps.free_names) >= {"friction_static", "stribeck_velocity", "valve_overlap"}
    poly = ParameterSet.for_model("polytropic", RIG)
    assert "k" in poly.free_names and "xi" not in poly
    assert set(ParameterSet.for_model("constant-lambda").names) <= set(PARAMETER_NAMES)


def test_friction_levels_are_bounded_by_the_actuators_largest_force() -> None:
    """Static and Coulomb friction may not exceed P_s pi D^2 / 4, the most the
    air can push (the rig's supply pressure and bore): 7 bar on 32 mm is
    563 N, 10 bar on 80 mm 5027 N; the valve's full-opening fractions are
    free and bounded by 1 (fully open at u_sat at the latest)."""
    for bore, ps_abs in ((0.032, 7.0e5), (0.080, 10.0e5)):
        ps = ParameterSet.for_model("convection", {**RIG, "bore": bore, "supply_pressure": ps_abs})
        ceiling = ps_abs * math.pi * bore**2 / 4.0
        assert ps["friction_static"].upper == pytest.approx(ceiling, rel=1e-12)
        assert ps["friction_coulomb"].upper == pytest.approx(ceiling, rel=1e-12)
    assert ps["friction_viscous"].upper == 1e5  # not a force level
    for name in ("valve_full_supply", "valve_full_exhaust"):
        assert not ps[name].fixed and ps[name].upper == 1.0 and ps[name].value == 1.0
    for name in ("valve_knee_supply", "valve_knee_exhaust"):  # 1: the power law
        assert not ps[name].fixed and ps[name].lower == 1.0 and ps[name].value == 1.0


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ({"format": "other"}, "format: expected"),
        ({"format": "pneumafit-parameters", "parameters": []}, "parameters: expected an object"),
        ({"format": "pneumafit-parameters", "parameters": {"xi": {}}}, "parameters.xi"),
        ({"format": "pneumafit-parameters", "parameters": {"xi": {"value": "a"}}},
         "parameters.xi.value: expected a number"),
        ({"format": "pneumafit-parameters",
          "parameters": {"xi": {"value": 0.4, "prior": {"kind": "cauchy"}}}},
         "prior.kind: expected one of"),
        ({"format": "pneumafit-parameters",
          "parameters": {"xi": {"value": 20.0, "lower": 0.0, "upper": 10.0}}},
         "expected a value in [0, 10]"),
    ],
)  # fmt: skip
def test_bad_files_raise_readable_errors(
    tmp_path: Path, document: dict[str, object], message: str
) -> None:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(PneumafitInputError) as info:
        ParameterSet.load(path)
    assert message in str(info.value)
    assert str(path) in str(info.value)


def test_load_reports_missing_file_and_bad_json(tmp_path: Path) -> None:
    with pytest.raises(PneumafitInputError, match="expected a readable file"):
        ParameterSet.load(tmp_path / "none.json")
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(PneumafitInputError, match="expected JSON"):
        ParameterSet.load(tmp_path / "x.json")


def test_parameter_rejects_inconsistent_definitions() -> None:
    with pytest.raises(ValueError, match="lower bound > 0"):
        Parameter("xi", 0.4, lower=0.0, upper=1.0, scale="log")
    with pytest.raises(ValueError, match="expected a value in"):
        Parameter("xi", 2.0, lower=0.0, upper=1.0)
    with pytest.raises(ValueError, match="unique names"):
        ParameterSet([Parameter("a", 1.0), Parameter("a", 2.0)])


def test_repr_is_one_short_line_and_summary_is_a_table() -> None:
    from pneumafit.identification import fit_structure

    ps = ParameterSet.for_model(fit_structure("convection"), {})
    text = repr(ps)
    assert "\n" not in text and len(text) < 200, text
    assert text.startswith(f"ParameterSet({len(list(ps))} parameters, {ps.n_free} free")
    table = ps.summary().splitlines()
    assert table[0].split()[0] == "parameter"
    assert [line.split()[0] for line in table[1:]] == list(ps.free_names)
