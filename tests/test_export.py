"""Controller export: JSON/YAML round trips, a C header that compiles, .mat."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat

from pneumafit.outputs.export import build_export, read_export, write_export

DETAILS = {
    "rod": {"value": 0.02, "std": None, "interval_90": None, "fixed": False},
    "xi": {"value": 0.41, "std": 0.02, "interval_90": [0.38, 0.44], "fixed": False},
}


@pytest.fixture(scope="module")
def doc() -> dict:
    return build_export(DETAILS, model="convection", source="fit.json",
                        positions=np.array([0.05, 0.25, 0.45]), order=6, w0=10.0,
                        lambda_e=15.0)  # fmt: skip


def test_document_content(doc):
    assert doc["format"] == "pneumafit-controller-export" and doc["version"] == 1
    assert doc["parameters"]["xi"]["interval_90"] == [0.38, 0.44]
    assert doc["parameters"]["bore"]["fixed"] is True  # default, not from the fit
    grid = doc["grid"]
    assert len(grid["positions"]) == 3
    assert np.array(grid["A"]).shape == (3, 6, 6) and np.array(grid["K"]).shape == (3, 6)


@pytest.mark.parametrize("fmt", ["json", "yaml"])
def test_text_round_trip_is_exact(tmp_path, doc, fmt):
    path = write_export(doc, tmp_path / f"ctrl.{fmt}", fmt)
    assert read_export(path) == json.loads(json.dumps(doc))


def test_mat_round_trip(tmp_path, doc):
    path = write_export(doc, tmp_path / "ctrl.mat", "mat")
    m = loadmat(path, squeeze_me=True, struct_as_record=False)["pneumafit"]
    np.testing.assert_array_equal(m.grid.K, np.array(doc["grid"]["K"]))
    np.testing.assert_array_equal(m.grid.A, np.array(doc["grid"]["A"]))
    assert m.parameters.xi.value == 0.41
    assert m.design.order == 6


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) on this machine")
def test_c_header_compiles_and_holds_the_numbers(tmp_path, doc):
    header = write_export(doc, tmp_path / "pneumafit_export.h", "c")
    main = tmp_path / "main.c"
    main.write_text(
        '#include <stdio.h>\n#include "pneumafit_export.h"\n'
        "int main(void) {\n"
        '  printf("%.17g %.17g %d\\n", pf_K[1][0], PF_XI, PF_N_POSITIONS);\n'
        "  return 0;\n}\n"
    )
    subprocess.run(["cc", "-c", "-Wall", "-Werror", "-o", str(tmp_path / "h.o"), "-x", "c",
                    str(header)], check=True)  # fmt: skip
    exe = tmp_path / "main"
    subprocess.run(["cc", "-Wall", "-Werror", "-o", str(exe), str(main)], check=True)
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    assert float(out[0]) == doc["grid"]["K"][1][0]  # exact: 17 significant digits
    assert float(out[1]) == 0.41 and int(out[2]) == 3


def test_export_command(tmp_path):
    import sys

    params = tmp_path / "p.json"
    params.write_text('{"model": "convection", "parameters": {"rod": "20 mm"}}')
    for fmt in ("json", "yaml", "c", "mat"):
        args = ["export", str(params), "--format", fmt, "--out", str(tmp_path / f"x.{fmt}"),
                "--positions", "100,400 mm"]  # fmt: skip
        res = subprocess.run([sys.executable, "-m", "pneumafit.cli", *args],
                             capture_output=True, text=True)  # fmt: skip
        assert res.returncode == 0, res.stderr
        assert Path(tmp_path / f"x.{fmt}").stat().st_size > 1000
    res = subprocess.run([sys.executable, "-m", "pneumafit.cli", "export", str(params),
                          "--format", "xml", "--out", str(tmp_path / "x.xml")],
                         capture_output=True, text=True)  # fmt: skip
    assert res.returncode == 2 and "--format" in res.stderr
