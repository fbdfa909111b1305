"""Controller export (schema v2): the validated design in every format.

JSON/YAML round trips, a C header and controller source that compile, the
MAT file's model arrays, the CSV schedule, the command line (which design,
``--format fmu`` dispatch), and the linear model as scipy / python-control
objects.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
from scipy.io import loadmat

from pneumafit.analysis.closed_loop import design_controller
from pneumafit.analysis.controller import ScheduledController
from pneumafit.analysis.linear import linearize
from pneumafit.models import parameter_vector
from pneumafit.outputs.export import build_export, read_export, write_export

DETAILS = {
    "rod": {"value": 0.02, "std": None, "interval_90": None, "fixed": False},
    "xi": {"value": 0.41, "std": 0.02, "interval_90": [0.38, 0.44], "fixed": False},
}
POSITIONS = np.array([0.05, 0.2, 0.45])
Y_MID = 0.25
W0 = 15.0


@pytest.fixture(scope="module")
def doc() -> dict:
    return build_export(DETAILS, model="convection", source="fit.json", positions=POSITIONS,
                        order=6, w0=W0, lambda_e=15.0, operating_position=Y_MID,
                        w0_rule="given", validated=True)  # fmt: skip


def test_document_content(doc):
    assert doc["format"] == "pneumafit-controller-export" and doc["version"] == 2
    assert doc["parameters"]["xi"]["interval_90"] == [0.38, 0.44]
    assert doc["parameters"]["bore"]["fixed"] is True  # default, not from the fit
    grid = doc["grid"]
    # the operating position is inserted as a breakpoint
    assert grid["positions"] == [0.05, 0.2, 0.25, 0.45]
    assert np.array(grid["A"]).shape == (4, 6, 6) and np.array(grid["K"]).shape == (4, 6)
    assert np.array(grid["poles"]).shape == (4, 6, 2)
    design = doc["design"]
    assert design["placement"] == "dominant" and design["compensation"] is True
    assert design["validated"] is True and "validated" in design["description"]
    assert doc["controller"]["deadband_amplitude"] > 0 and doc["controller"]["umax"] == 10.0
    assert doc["linear_model"]["C"] == np.eye(6).tolist()


def test_schedule_at_the_operating_position_is_the_closed_loop_design(doc):
    """Exactly (bit for bit) the design the closed-loop stage runs at that position."""
    p = parameter_vector({k: v["value"] for k, v in DETAILS.items()})
    d = design_controller(p, Y_MID, order=6, w0=W0, lambda_e=15.0)
    k = doc["grid"]["positions"].index(Y_MID)
    assert doc["grid"]["K"][k] == d.gain.tolist()
    assert doc["grid"]["v_e"][k] == d.model.v_e
    assert doc["grid"]["deadband_width"][k] == d.compensation.width
    assert doc["controller"]["deadband_amplitude"] == d.compensation.amplitude


@pytest.mark.parametrize("fmt", ["json", "yaml"])
def test_text_round_trip_is_exact(tmp_path, doc, fmt):
    path = write_export(doc, tmp_path / f"ctrl.{fmt}", fmt)
    assert read_export(path) == json.loads(json.dumps(doc))


def test_read_export_reads_version_1_and_refuses_others(tmp_path):
    old = {"format": "pneumafit-controller-export", "version": 1, "grid": {"K": [[1.0]]}}
    (tmp_path / "v1.json").write_text(json.dumps(old))
    assert read_export(tmp_path / "v1.json") == old
    (tmp_path / "v9.json").write_text(json.dumps({**old, "version": 9}))
    with pytest.raises(ValueError, match="version"):
        read_export(tmp_path / "v9.json")
    (tmp_path / "other.json").write_text("{}")
    with pytest.raises(ValueError, match="format"):
        read_export(tmp_path / "other.json")


def test_mat_layout_for_matlab(tmp_path, doc):
    """A (6, 6, n) and B (6, 1, n) as MATLAB model arrays expect; C, D, breakpoints."""
    path = write_export(doc, tmp_path / "ctrl.mat", "mat")
    m = loadmat(path)
    n = len(doc["grid"]["positions"])
    assert m["A"].shape == (6, 6, n) and m["B"].shape == (6, 1, n)
    for i in range(n):
        np.testing.assert_array_equal(m["A"][:, :, i], np.array(doc["grid"]["A"][i]))
        np.testing.assert_array_equal(m["B"][:, 0, i], np.array(doc["grid"]["B"][i]))
    np.testing.assert_array_equal(m["C"], np.eye(6))
    np.testing.assert_array_equal(m["D"], np.zeros((6, 1)))
    np.testing.assert_array_equal(m["breakpoints"].ravel(), doc["grid"]["positions"])
    np.testing.assert_array_equal(m["K"], np.array(doc["grid"]["K"]))
    assert m["deadband_width"].shape == (n, 1) and m["Ts"].item() == 1e-3
    s = loadmat(path, squeeze_me=True, struct_as_record=False)["pneumafit"]
    assert s.parameters.xi.value == 0.41 and s.design.order == 6


def test_csv_schedule(tmp_path, doc):
    path = write_export(doc, tmp_path / "ctrl.csv", "csv")
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    assert [float(r["position_m"]) for r in rows] == doc["grid"]["positions"]
    assert [float(r["K_y_V_per_m"]) for r in rows] == [k[0] for k in doc["grid"]["K"]]
    assert [float(r["deadband_width_V"]) for r in rows] == doc["grid"]["deadband_width"]
    assert "deadband_amplitude" in path.read_text().splitlines()[3]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) on this machine")
def test_c_header_and_source_compile_and_hold_the_numbers(tmp_path, doc):
    header = write_export(doc, tmp_path / "controller.h", "c")
    source = tmp_path / "controller.c"
    assert source.is_file() and '#include "controller.h"' in source.read_text()
    grid = doc["grid"]
    state = [0.23, 0.01, grid["p_N_e"][1], grid["p_P_e"][1], 293.0, 294.0]
    expected = ScheduledController.from_export(doc).command(state, 0.25)[0]
    main = tmp_path / "main.c"
    main.write_text(
        '#include <stdio.h>\n#include "controller.h"\n'
        "int main(void) {\n"
        f"  pf_state x = {{{', '.join(f'{v:.17g}' for v in state)}}};\n"
        "  pf_command c;\n"
        "  pf_controller_step(&x, 0.25, &c);\n"
        '  printf("%.17g %.17g %d %.17g\\n", pf_K[1][0], PF_XI, PF_N_POSITIONS, c.u_P);\n'
        "  return 0;\n}\n"
    )
    subprocess.run(["cc", "-std=c99", "-c", "-Wall", "-Wextra", "-Werror", "-o",
                    str(tmp_path / "h.o"), "-x", "c", str(header)], check=True)  # fmt: skip
    exe = tmp_path / "main"
    subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-o", str(exe), str(main),
                    str(source), "-lm"], check=True)  # fmt: skip
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    assert float(out[0]) == doc["grid"]["K"][1][0]  # exact: 17 significant digits
    assert float(out[1]) == 0.41 and int(out[2]) == 4
    assert float(out[3]) == expected and expected > 0.0  # below the reference: opens to P


def test_c_output_must_name_the_header(tmp_path, doc):
    with pytest.raises(ValueError, match="header"):
        write_export(doc, tmp_path / "controller.c", "c")


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pneumafit", *args], capture_output=True,
                          text=True)  # fmt: skip


def test_export_command(tmp_path):
    params = tmp_path / "p.json"
    params.write_text('{"model": "convection", "parameters": {"rod": "20 mm"}}')
    names = {"json": "x.json", "yaml": "x.yaml", "c": "x.h", "mat": "x.mat", "csv": "x.csv"}
    for fmt, name in names.items():
        w0 = [] if fmt == "json" else ["--w0", "15"]  # largest_w0 (2 s) once
        res = _cli("export", str(params), "--format", fmt, "--out", str(tmp_path / name),
                   "--positions", "100,400 mm", *w0)  # fmt: skip
        assert res.returncode == 0, res.stderr
        assert (tmp_path / name).stat().st_size > 500
    assert (tmp_path / "x.c").is_file()
    doc = read_export(tmp_path / "x.json")
    # the closed-loop stage's defaults: dominant, compensated, largest_w0, half stroke
    assert doc["design"]["validated"] and doc["design"]["w0_rule"].startswith("largest_w0")
    assert doc["grid"]["positions"] == [0.1, 0.25, 0.4]
    res = _cli("export", str(params), "--format", "xml", "--out", str(tmp_path / "x.xml"))
    assert res.returncode == 2 and "--format" in res.stderr


def test_export_command_says_when_the_design_is_not_the_validated_one(tmp_path):
    params = tmp_path / "p.json"
    params.write_text('{"model": "convection", "parameters": {"rod": "20 mm"}}')
    res = _cli("export", str(params), "--format", "json", "--out", str(tmp_path / "x.json"),
               "--placement", "itae", "--order", "4", "--w0", "8",
               "--positions", "250 mm")  # fmt: skip
    assert res.returncode == 0, res.stderr
    doc = read_export(tmp_path / "x.json")
    assert doc["design"]["validated"] is False and doc["design"]["placement"] == "itae"
    assert doc["design"]["w0"] == 8.0 and "not the design" in res.stdout


FMU_INSTALLED = importlib.util.find_spec("pneumafit.outputs.fmu") is not None


@pytest.mark.skipif(FMU_INSTALLED, reason="the FMU exporter is installed: its tests cover it")
def test_export_fmu_without_the_exporter_says_so(tmp_path):
    params = tmp_path / "p.json"
    params.write_text('{"model": "convection"}')
    res = _cli("export", str(params), "--format", "fmu", "--out", str(tmp_path / "plant.fmu"))
    assert res.returncode == 2 and "FMU exporter" in res.stderr


def test_linear_model_to_scipy_state_space():
    p = parameter_vector({"rod": 0.02})
    lin = linearize(p, 0.25, order=6)
    ss = lin.to_ss()
    np.testing.assert_array_equal(ss.A, lin.A)
    np.testing.assert_array_equal(ss.B, lin.B)
    np.testing.assert_array_equal(ss.C, np.eye(6))
    np.testing.assert_array_equal(ss.D, np.zeros((6, 1)))


def test_linear_model_to_python_control():
    control = pytest.importorskip("control", reason="python-control not installed")
    d = design_controller(parameter_vector({"rod": 0.02}), 0.25, order=4, w0=W0)
    sys_ = d.model.to_control()
    assert isinstance(sys_, control.StateSpace)
    np.testing.assert_array_equal(sys_.A, d.model.A)
    assert sys_.input_labels == ["v"] and sys_.output_labels == ["y", "v", "p_N", "p_P"]


def test_to_control_without_python_control_says_how_to_get_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)  # import control -> ImportError
    lin = linearize(parameter_vector({}), 0.25, order=4)
    with pytest.raises(ImportError, match="pip install control"):
        lin.to_control()
