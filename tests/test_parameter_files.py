"""Parameter files in TOML as well as JSON (plumbing, no simulation).

The same document written both ways must give the same structure and SI
values through every reader (``read_parameter_file``, ``read_structure``,
the plant reader of the closed loop and the FMU); a broken TOML file is
refused with the file and the line named, as a broken JSON file is.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pneumafit.analysis.closed_loop import read_plant_file
from pneumafit.errors import PneumafitInputError
from pneumafit.models.layout import SPECS
from pneumafit.parameters_io import read_parameter_file, read_structure

TOML = """\
model = "convection"
friction = "lugre"
description = "a rig of 32 mm bore"

[effects]
external_leakage = 1

[parameters]
bore = "32mm"
supply_pressure = "7 barg"
xi = 0.4
external_leak_conductance = 3e-11
"""

DOCUMENT = {
    "model": "convection", "friction": "lugre", "description": "a rig of 32 mm bore",
    "effects": {"external_leakage": 1},
    "parameters": {"bore": "32mm", "supply_pressure": "7 barg", "xi": 0.4,
                   "external_leak_conductance": 3e-11},
}  # fmt: skip


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    toml = tmp_path / "rig.toml"
    toml.write_text(TOML, encoding="utf-8")
    js = tmp_path / "rig.json"
    js.write_text(json.dumps(DOCUMENT), encoding="utf-8")
    return toml, js


def test_a_toml_parameter_file_reads_as_its_json_twin(files: tuple[Path, Path]) -> None:
    toml, js = files
    assert read_parameter_file(toml) == read_parameter_file(js)
    s_toml, v_toml = read_structure(toml)
    s_json, v_json = read_structure(js)
    assert s_toml == s_json and v_toml == v_json
    assert s_toml.friction == "lugre" and s_toml.effects == {"external_leakage": 1}
    # units through the campaign's parser: 32 mm, and 7 bar gauge (absolute:
    # the rig's atmosphere more, its exhaust pressure, 1.013 bar by default)
    assert v_toml["bore"] == pytest.approx(0.032, rel=1e-12)
    p_atm = SPECS["exhaust_pressure"].default
    assert v_toml["supply_pressure"] == pytest.approx(7e5 + p_atm, rel=1e-12)
    assert read_plant_file(toml) == read_plant_file(js)


def test_a_broken_toml_file_is_refused_naming_file_and_line(tmp_path: Path) -> None:
    bad = tmp_path / "rig.toml"
    bad.write_text('model = "convection"\n[parameters]\nbore = 32 mm\n', encoding="utf-8")
    with pytest.raises(PneumafitInputError, match=r"rig\.toml: expected valid TOML.*line 3"):
        read_parameter_file(bad)
    # a key the format does not have is named, as in JSON
    bad.write_text('model = "convection"\n[paramters]\nbore = "32 mm"\n', encoding="utf-8")
    with pytest.raises(PneumafitInputError, match="paramters"):
        read_parameter_file(bad)
    # bytes that are not text: a clear error, not an internal one
    bad.write_bytes(b"\xff\xfe\x00model")
    with pytest.raises(PneumafitInputError, match="UTF-8"):
        read_parameter_file(bad)
    with pytest.raises(PneumafitInputError, match="UTF-8"):
        read_plant_file(tmp_path / "rig.toml")
