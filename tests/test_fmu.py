"""The fitted plant as an FMI 2.0 co-simulation FMU (pneumafit.outputs.fmu).

Each FMU is built from a parameter file with ``build_fmu``, validated with
``fmpy.validation.validate_fmu`` and run with ``fmpy.simulate_fmu`` on an
open-loop 4-s step test of the valve commands (0, +3, 0, -3, +0.2, -0.8 V on
u_P, u_N = -u_P, held between steps: FMI's zero-order hold), then compared
with the compiled simulator on the same commands and step. Target: pressures
within 100 Pa, position within 10 um. Measured on 2026-11-25 (gcc 12 -O2,
integration step from choose_step), largest differences over the 4 s:

    convection-switch      0.585 ms  0.0081 Pa  0.00046 um  1.4e-6 K
    convection-lugre       0.458 ms  0.0030 Pa  0.00031 um  6e-7 K
    polytropic-switch      0.585 ms  0.0065 Pa  0.00039 um
    constant-lambda-lugre  0.585 ms  0.0084 Pa  0.00047 um  1.4e-6 K
    convection-map         0.492 ms  0.0069 Pa  0.00045 um  3.1e-6 K  (measured valve map)
    convection-effects     0.585 ms  0.0038 Pa  0.00036 um  7.1e-7 K  (all seven effects)

and after the seal and barrel effects joined (2026-11-25, the same machine):

    convection-effects     0.585 ms  0.0025 Pa  0.00034 um  9.3e-8 K  (all nine effects)
    lugre-seal             0.585 ms  0.0063 Pa  0.00038 um  1.2e-7 K  (LuGre, seal friction,
                                                          asymmetry -0.25, area factor 0.93)

(the C code is the kernel's arithmetic; what is left is rounding, numba
fusing multiply-adds where gcc does not); 0.0005 Pa with Sutherland air.

Against ``pneumafit simulate --kind step`` (closed-loop pd inside the
simulator's stages, 1 kHz), the FMU replaying the simulated commands with
their first derivatives (``fmi2SetRealInputDerivatives``, first-order hold)
at the simulator's 1-ms step: 8 Pa and 2.8 um with the switch model, 112 Pa
and 32 um with LuGre; that is the 1-kHz sampling of a closed-loop command
(the simulator's own open-loop replay of those samples is the FMU's to
1e-8 Pa), and it falls to 0.1 Pa / 0.04 um and 1.1 Pa / 0.3 um at 10 kHz.
Without the derivatives (zero-order hold) the replay is off by 2 kPa and
0.4 mm: half a sample of delay in a position loop.
"""

from __future__ import annotations

import dataclasses
import json
import zipfile

import numpy as np
import pytest

from pneumafit.analysis.closed_loop import read_plant_file
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.outputs.fmu import FmuBuildError, build_fmu, find_compiler
from pneumafit.simulation import Experiment, Simulator

fmpy = pytest.importorskip("fmpy", reason="fmpy is not installed (pip install fmpy)")
from fmpy.validation import validate_fmu  # noqa: E402

pytestmark = pytest.mark.skipif(
    find_compiler() is None, reason="no C compiler: the FMU cannot be built"
)

#: Open-loop command steps (time s, u_P V); u_N = -u_P. The piston runs into
#: the end stop at +3 V, sticks at 0 V and creeps through the dead band.
STEPS = [(0.0, 0.0), (0.2, 3.0), (0.7, 0.0), (1.5, -3.0), (2.0, 0.2), (3.0, -0.8)]
INITIAL = {"y": 0.25, "p_P": 4.0e5, "p_N": 4.5e5}
DURATION = 4.0
H = 1e-3  # communication step and output interval (s)

PLANTS = {
    "convection-switch": {
        "model": "convection",
        "parameters": {"xi": 0.35, "beta": 0.28, "bore": "32 mm", "supply_pressure": "7 bar"},
    },
    "convection-lugre": {
        "model": "convection",
        "friction": "lugre",
        "parameters": {
            "xi": 0.45,
            "valve_n_supply": 1.4,
            "valve_n_exhaust": 0.8,
            "valve_full_supply": 0.25,  # fully open from 2.5 V: the +3 V step saturates
            "valve_full_exhaust": 0.6,
            "valve_null_offset": 0.15,
            "valve_knee_supply": 2.5,
            "valve_m": 0.45,
            "heat_area_ends": 0.4,  # the exchange area's convention
            "friction_static": "60 N",
            "friction_stiffness": 2e5,
            "mounting_angle": 0.2,
        },
    },
    "polytropic-switch": {"model": "polytropic", "parameters": {"k": 1.25}},
    "constant-lambda-lugre": {
        "model": "constant-lambda",
        "friction": "lugre",
        "parameters": {"lambda": "20 W/m^2/K"},
    },
    "convection-map": {
        "model": "convection",
        "structure": {"valve": "map"},
        "parameters": {
            "valve_map_CS_12": 6e-9,
            "valve_map_CE_03": 4e-9,
            "valve_map_CE_09": 3e-11,
            "valve_map_bS_2": 0.35,
            "valve_map_bE_1": 0.4,
            "valve_m": 0.48,
        },
    },
    "convection-effects": {
        "model": "convection",
        "effects": {
            "chamber_leakage": 1,
            "external_leakage": 1,
            "valve_dynamics": 1,
            "wall_thermal_mass": 1,
            "forced_convection": 1,
            "supply_pressure_drop": 1,
            "seal_friction": 1,
            "friction_asymmetry": 1,
            "effective_area": 1,
        },
        "parameters": {
            "chamber_leak_conductance": 2e-10,
            "external_leak_conductance": 1e-10,
            "external_leak_split": -0.35,
            "valve_time_constant": "5 ms",
            "wall_heat_capacity": 2000.0,
            "forced_convection_gain": 2000.0,
            "supply_line_resistance": 2e7,
            "seal_friction_coefficient": 2e-5,
            "friction_asymmetry": 0.3,
            "area_factor": 1.08,
        },
    },
    "lugre-seal": {
        "model": "constant-lambda",
        "friction": "lugre",
        "effects": {"seal_friction": 1, "friction_asymmetry": 1, "effective_area": 1},
        "parameters": {
            "lambda": "20 W/m^2/K",
            "seal_friction_coefficient": 1.5e-5,
            "friction_asymmetry": -0.25,
            "area_factor": 0.93,
        },
    },
}


@pytest.fixture(scope="module")
def plants(tmp_path_factory):
    """Parameter file and built FMU of each plant."""
    root = tmp_path_factory.mktemp("fmu")
    built = {}
    for name, document in PLANTS.items():
        params = root / f"{name}.json"
        params.write_text(json.dumps(document), encoding="utf-8")
        built[name] = (params, build_fmu(params, root / f"{name}.fmu"))
    return built


def _integration_step(fmu) -> float:
    md = fmpy.read_model_description(str(fmu))
    return float(next(v.start for v in md.modelVariables if v.name == "integration_step"))


def _run_fmu(fmu) -> np.ndarray:
    rows = []
    for i, (t, u) in enumerate(STEPS):
        if i > 0:  # a repeated time is an input event: the old value, then the new one
            rows.append((t, STEPS[i - 1][1], -STEPS[i - 1][1]))
        rows.append((t, u, -u))
    rows.append((DURATION, STEPS[-1][1], -STEPS[-1][1]))
    signal = np.array(rows, dtype=[("time", float), ("u_P", float), ("u_N", float)])
    return fmpy.simulate_fmu(
        str(fmu), stop_time=DURATION, output_interval=H, input=signal,
        start_values={f"{k}_start": v for k, v in INITIAL.items()},
        output=["y", "v", "p_P", "p_N", "T_P", "T_N"],
    )  # fmt: skip


def _run_simulator(params, step: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    # the same held commands: the simulator interpolates linearly between
    # samples, so a sample 1 ns before each step keeps the old value
    structure, values = read_plant_file(params)
    t = np.arange(round(DURATION / H) + 1) * H
    u = np.zeros(t.size)
    for t_step, value in STEPS:
        u[t >= t_step - 1e-12] = value
    jumps = np.flatnonzero(np.diff(u)) + 1
    times = np.concatenate([t, t[jumps] - 1e-9])
    commands = np.concatenate([u, u[jumps - 1]])
    order = np.argsort(times, kind="stable")
    experiment = Experiment(
        time=times[order], kind="free", u_P=commands[order], u_N=-commands[order],
        initial=dict(INITIAL),
    )  # fmt: skip
    result = Simulator(structure, step=step).simulate(values, experiment)
    assert result.ok, result.message
    rows = np.searchsorted(times[order], t)
    return t, {name: result[name][rows] for name in ("y", "v", "p_P", "p_N", "T_P", "T_N")}


def test_fmpy_validation_passes(plants):
    for _, fmu in plants.values():
        assert validate_fmu(str(fmu)) == []


@pytest.mark.parametrize("plant", list(PLANTS))
def test_step_test_matches_simulator(plants, plant):
    """4-s open-loop step test, FMU (fmpy.simulate_fmu) against the compiled
    simulator at the FMU's integration step: 100 Pa and 10 um are the
    targets; measured 0.008 Pa and 0.0005 um (module docstring)."""
    params, fmu = plants[plant]
    result = _run_fmu(fmu)
    t, reference = _run_simulator(params, _integration_step(fmu))
    assert result.shape == t.shape
    np.testing.assert_allclose(result["time"], t, atol=1e-9)
    assert np.ptp(reference["y"]) > 0.1  # the piston really moves (0.25 to the stop)
    for name in ("p_P", "p_N"):
        assert np.max(np.abs(result[name] - reference[name])) <= 100.0
    assert np.max(np.abs(result["y"] - reference["y"])) <= 10e-6
    # far tighter in fact: the same arithmetic up to rounding
    assert np.max(np.abs(result["p_P"] - reference["p_P"])) <= 1.0
    assert np.max(np.abs(result["T_P"] - reference["T_P"])) <= 1e-3


def _slave(fmu, unzipped):
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=unzipped,
        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="plant",
    )  # fmt: skip
    slave.instantiate()
    return slave, refs


def test_replays_pneumafit_simulate_step_with_input_derivatives(plants, tmp_path):
    """The commands of ``pneumafit simulate --kind step`` (closed-loop pd,
    1 kHz), replayed with fmi2SetRealInputDerivatives at the simulator's
    1-ms step: equal to the simulator's open-loop replay with the commands
    interpolated linearly between samples, which is what the derivatives
    give the FMU (``inputs="linear"``; measured 5e-10 Pa; 0.01 Pa allows
    rounding), and within the targets of the closed loop itself (measured
    8 Pa, 2.8 um: the commands' 1-kHz sampling)."""
    from pneumafit.simulation.scenarios import step_test

    params, fmu = plants["convection-switch"]
    structure, values = read_plant_file(params)
    experiment = step_test(structure, values)
    linear = dataclasses.replace(structure, inputs="linear")  # y_ref too, as before
    closed = Simulator(linear).simulate(values, experiment)
    t, u = experiment.time, closed["u_P"]
    replay = Experiment(time=t, kind="free", u_P=u, u_N=-u, initial=experiment.initial)
    open_loop = Simulator(linear).simulate(values, replay)

    slave, refs = _slave(fmu, fmpy.extract(str(fmu), unzipdir=str(tmp_path / "unzip")))
    slave.setupExperiment(startTime=0.0)
    names = [k for k in experiment.initial if f"{k}_start" in refs]
    slave.setReal([refs[f"{k}_start"] for k in names], [experiment.initial[k] for k in names])
    slave.setReal([refs["integration_step"]], [1e-3])
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    out = np.empty((t.size, 3))
    channels = [refs["y"], refs["p_P"], refs["p_N"]]
    out[0] = slave.getReal(channels)
    inputs = [refs["u_P"], refs["u_N"]]
    for k in range(t.size - 1):
        step = t[k + 1] - t[k]
        slope = (u[k + 1] - u[k]) / step
        slave.setReal(inputs, [u[k], -u[k]])
        slave.setRealInputDerivatives(inputs, [1, 1], [slope, -slope])
        slave.doStep(t[k], step)
        out[k + 1] = slave.getReal(channels)
    slave.terminate()
    slave.freeInstance()
    for reference, pressure, position in ((open_loop, 0.01, 1e-9), (closed, 100.0, 10e-6)):
        assert np.max(np.abs(out[:, 0] - reference["y"])) <= position
        for j, name in ((1, "p_P"), (2, "p_N")):
            assert np.max(np.abs(out[:, j] - reference[name])) <= pressure


def test_fmu_state_and_reset(plants, tmp_path):
    _, fmu = plants["convection-lugre"]
    slave, refs = _slave(fmu, fmpy.extract(str(fmu), unzipdir=str(tmp_path / "unzip")))

    def start():
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.setReal([refs["u_P"], refs["u_N"]], [2.0, -2.0])

    start()
    for k in range(50):
        slave.doStep(k * H, H)
    state = slave.getFMUstate()
    for k in range(50, 100):
        slave.doStep(k * H, H)
    first = slave.getReal([refs["y"], refs["p_P"]])
    slave.setFMUstate(state)
    for k in range(50, 100):
        slave.doStep(k * H, H)
    assert slave.getReal([refs["y"], refs["p_P"]]) == first
    slave.freeFMUstate(state)
    slave.reset()
    start()
    for k in range(100):
        slave.doStep(k * H, H)
    assert slave.getReal([refs["y"], refs["p_P"]]) == first
    slave.terminate()
    slave.freeInstance()


def test_first_order_valve_without_time_constant_is_refused(plants, tmp_path):
    """A first-order valve's rate is (u_cmd - u) / tau: tau = 0 is refused as
    inadmissible (kernel.admissible), by the builder and by the FMU itself
    when an importer sets it before initialisation (the C model's
    pf_admissible), instead of dividing by zero in the plant."""
    from fmpy.fmi1 import FMICallException

    params, fmu = plants["convection-effects"]
    zero = json.loads(params.read_text(encoding="utf-8"))
    zero["parameters"]["valve_time_constant"] = 0.0
    bad = tmp_path / "tau0.json"
    bad.write_text(json.dumps(zero), encoding="utf-8")
    with pytest.raises(PneumafitInputError, match="valve_time_constant 0"):
        build_fmu(bad, tmp_path / "tau0.fmu")
    assert not (tmp_path / "tau0.fmu").exists()

    slave, refs = _slave(fmu, fmpy.extract(str(fmu), unzipdir=str(tmp_path / "unzip")))
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([refs["valve_time_constant"]], [0.0])
    with pytest.raises(FMICallException):
        slave.exitInitializationMode()
    slave.freeInstance()


def test_model_description_carries_fitted_values_and_units(plants):
    _, fmu = plants["convection-lugre"]
    md = fmpy.read_model_description(str(fmu))
    by_name = {v.name: v for v in md.modelVariables}
    assert {by_name[n].causality for n in ("u_P", "u_N")} == {"input"}
    for name in ("p_P", "p_N", "T_P", "T_N", "y", "v", "z_f"):
        assert by_name[name].causality == "output"
    assert float(by_name["xi"].start) == 0.45
    assert float(by_name["friction_static"].start) == 60.0
    assert by_name["friction_static"].unit == "N"
    assert by_name["valve_C_supply"].unit == "m^3/s/Pa"
    assert by_name["p_P"].unit == "Pa"
    assert by_name["friction_stiffness"].causality == "parameter"
    assert "k" not in by_name  # the polytropic index is not this structure's
    units = {u.name: u for u in md.unitDefinitions}
    pa = units["Pa"].baseUnit
    assert (pa.kg, pa.m, pa.s) == (1, -1, -2)
    assert units["V"].baseUnit.A == -1
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
    assert f"binaries/linux64/{md.coSimulation.modelIdentifier}.so" in names
    assert "sources/pneumafit_model.c" in names

    _, poly = plants["polytropic-switch"]
    names = {v.name for v in fmpy.read_model_description(str(poly)).modelVariables}
    assert "k" in names and "xi" not in names and "T_P_start" not in names
    assert "z_f" not in names and "Tw_P" not in names

    _, effects = plants["convection-effects"]
    names = {v.name for v in fmpy.read_model_description(str(effects)).modelVariables}
    assert {"Tw_N", "Tw_P", "us_N", "us_P", "seal_friction_coefficient"} <= names
    assert "valve_time_constant" in names and "valve_natural_frequency" not in names

    _, valve_map = plants["convection-map"]
    md = fmpy.read_model_description(str(valve_map))
    names = {v.name for v in md.modelVariables}
    assert {"valve_map_CS_00", "valve_map_bE_2", "valve_u_sat"} <= names
    assert "valve_C_supply" not in names and "valve law map" in md.description


def test_unsupported_structures_are_refused(tmp_path, monkeypatch):
    # every law and effect of the simulator is in the C model today; one the C
    # model does not know (here: the map, as if it were new) is refused by name
    from pneumafit.outputs.fmu import builder

    monkeypatch.setattr(builder, "SUPPORTED_VALVES", ("iso6358",))
    monkeypatch.setattr(builder, "SUPPORTED_EFFECTS", ("seal_friction",))
    fit = tmp_path / "fit.json"
    fit.write_text(
        json.dumps({"format": "pneumafit-fit", "model": "convection",
                    "structure": {"valve": "map", "effects": {"chamber_leakage": 1}},
                    "parameters": {"xi": {"value": 0.4}}}),
        encoding="utf-8",
    )  # fmt: skip
    with pytest.raises(PneumafitInputError, match="valve law 'map'; effects chamber_leakage"):
        build_fmu(fit, tmp_path / "map.fmu")
    with pytest.raises(PneumafitInputError, match="expected a parameter file"):
        build_fmu(tmp_path / "missing.json", tmp_path / "missing.fmu")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"parameters": {"rod": "40 mm", "bore": "32 mm"}}), "utf-8")
    with pytest.raises(PneumafitInputError, match="not physically admissible"):
        build_fmu(bad, tmp_path / "bad.fmu")
    assert not list(tmp_path.glob("*.fmu"))


def test_no_compiler_says_so(tmp_path, monkeypatch):
    params = tmp_path / "plant.json"
    params.write_text(json.dumps({"model": "convection"}), encoding="utf-8")
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(FmuBuildError, match=r"^cannot build the FMU: no C compiler found \("):
        build_fmu(params, tmp_path / "plant.fmu")
    assert not (tmp_path / "plant.fmu").exists()
    assert issubclass(FmuBuildError, PneumafitInputError)


def test_fit_json_keeps_the_fitted_air_properties(tmp_path):
    # a convection fit is made with Sutherland air (identification.staged.fit_structure)
    fit = tmp_path / "fit.json"
    document = {
        "format": "pneumafit-fit",
        "model": "convection",
        "structure": {"heat": "convection", "air_properties": "sutherland", "valve": "iso6358",
                      "friction": "switch", "effects": {}},
        "parameters": {"xi": {"value": 0.38, "unit": ""}, "bore": {"value": 0.032, "unit": "m"}},
    }  # fmt: skip
    fit.write_text(json.dumps(document), encoding="utf-8")
    md = fmpy.read_model_description(str(build_fmu(fit, tmp_path / "plant.fmu")))
    assert "air properties sutherland" in md.description
    assert float(next(v.start for v in md.modelVariables if v.name == "xi")) == 0.38
