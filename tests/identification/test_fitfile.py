"""fit.json read back: FitResult.save / FitResult.load (identification.fitfile).

Documents are written by the current writer from a result built without a
fit (a parameter set and a structure), so these tests run in milliseconds;
the round trip of a real fit is in test_command.py.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest

from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.identification import FitResult, ParameterSet
from pneumafit.identification.fitfile import SavedFit, fit_document, load_fit
from pneumafit.models.structure import ModelStructure

CAMPAIGN = {"name": "bench", "path": None, "sha256": {"step_1.h5": "0" * 64}}


def _result(structure: ModelStructure, model: str | None = None) -> FitResult:
    return FitResult(
        model=model or structure.heat, structure=structure,
        parameters=ParameterSet.for_model(structure), laplace=None, stages=[],
        metrics={"temperature_sensor_lag": 0.4}, seed=11, campaign=dict(CAMPAIGN),
        options={"mcmc": False},
    )  # fmt: skip


def _write(path: Path, doc: dict) -> Path:
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_a_version_1_file_of_the_current_writer_reads(tmp_path: Path) -> None:
    structure = ModelStructure("convection", air_properties="sutherland", friction="lugre")
    structure = structure.with_effects(seal_friction=1)
    path = _result(structure).save(tmp_path / "fit.json")
    fit = FitResult.load(tmp_path)  # the folder holding fit.json
    assert isinstance(fit, SavedFit) and fit.path == path
    assert fit.model == "convection" and fit.version == 1
    assert fit.structure == structure  # name, laws, air properties, effects
    assert fit.seed == 11 and fit.options == {"mcmc": False}
    assert fit.campaign_sha256 == CAMPAIGN["sha256"]
    assert fit.metrics["temperature_sensor_lag"] == 0.4
    assert fit.mcmc is None and fit.quality is None and fit.warnings == ()
    xi = fit.document["parameters"]["xi"]["value"]
    assert fit.values["xi"] == fit.parameters["xi"].value == xi
    # load -> save writes the same file
    fit.save(tmp_path / "again.json")
    assert (tmp_path / "again.json").read_text() == path.read_text()


@pytest.mark.parametrize(
    ("model", "air"), [("convection", "sutherland"), ("polytropic", "constant"),
                       ("constant-lambda", "constant")],
)  # fmt: skip
def test_missing_structure_keys_read_as_the_version_1_writer_wrote_them(
    tmp_path: Path, model: str, air: str
) -> None:
    """No ``friction`` (fits before the LuGre law): switch; no ``air_properties``:
    what fit_structure gave every version-1 fit (Sutherland for convection);
    no ``inputs`` (fits before the held inputs): linear interpolation."""
    from pneumafit.identification import fit_structure

    doc = fit_document(_result(fit_structure(model)))
    assert doc["structure"]["air_properties"] == air  # what the writer writes
    assert doc["structure"]["inputs"] == "hold"
    assert load_fit(_write(tmp_path / "held.json", doc)).structure == fit_structure(model)
    old = dataclasses.replace(fit_structure(model), inputs="linear")
    del doc["structure"]["friction"], doc["structure"]["air_properties"]
    del doc["structure"]["inputs"]
    fit = load_fit(_write(tmp_path / "fit.json", doc))
    assert fit.structure == old
    assert fit.structure.air_properties == air and fit.friction == "switch"
    del doc["structure"]  # no structure at all: the model's, as version 1 replayed it
    assert SavedFit.from_document(doc).structure == old
    for key in ("version", "nuisance", "metrics", "provenance", "campaign", "mcmc"):
        doc.pop(key)
    fit = SavedFit.from_document(doc)
    assert fit.version == 1 and fit.seed is None and fit.options is None
    assert fit.metrics == {} and fit.mcmc is None and fit.campaign_sha256 == {}


def test_a_friction_test_fit_has_no_actuator_structure(tmp_path: Path) -> None:
    doc = {
        "format": "pneumafit-fit", "version": 1, "model": "friction",
        "structure": {"name": "friction-test", "heat": None, "air_properties": None,
                      "valve": None, "friction": "lugre", "effects": {"seal_friction_c": 2e-5}},
        "parameters": {"friction_static": {"value": 6.0, "unit": "N"}},
        "nuisance": {"initial_states": {}},
    }  # fmt: skip
    fit = load_fit(_write(tmp_path / "fit.json", doc))
    assert fit.structure is None and fit.friction == "lugre"
    assert fit.effects == {"seal_friction_c": 2e-5} and fit.values == {"friction_static": 6.0}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"format": "other"}, "format: expected 'pneumafit-fit', found 'other'"),
        ({"version": 2}, "version: expected an integer up to 1, found 2"),
        ({"model": 3}, "model: expected one of convection, .*found 3"),
        ({"parameters": []}, r"parameters: expected an object .*found \[\]"),
        (
            {"parameters": {"xi": {"value": "0.4"}}},
            r"parameters\.xi\.value: expected a finite number, "
            "found '0.4'",
        ),
        (
            {"structure": {"air_properties": "wall"}},
            r"structure\.air_properties: expected one of "
            "constant, sutherland, found 'wall'",
        ),
        ({"structure": {"heat": "adiabatic"}}, r"structure\.heat: expected one of .*'adiabatic'"),
        ({"structure": {"effects": {"seal": 1}}}, r"structure\.effects\.seal: expected one of"),
        ({"nuisance": []}, "nuisance: expected an object, found list"),
    ],
)
def test_a_bad_document_names_file_key_expected_and_found(
    tmp_path: Path, change: dict, message: str
) -> None:
    doc = {**fit_document(_result(ModelStructure("convection"))), **change}
    path = _write(tmp_path / "fit.json", doc)
    with pytest.raises(PneumafitInputError, match=f"^{re.escape(str(path))}: {message}"):
        load_fit(path)


def test_unreadable_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(PneumafitInputError, match=r"none\.json: expected a fit\.json .*no such"):
        load_fit(tmp_path / "none.json")
    bad = tmp_path / "fit.json"
    bad.write_text('{"format": "pneumafit-fit",\n  "model": }')
    with pytest.raises(PneumafitInputError, match=r"fit\.json: line 2: expected valid JSON"):
        FitResult.load(bad)
    with pytest.raises(PneumafitInputError, match=r"format: expected a JSON object .*found a list"):
        load_fit(_write(bad, []))  # type: ignore[arg-type]


def test_save_needs_the_campaign_and_seed_identify_records() -> None:
    result = _result(ModelStructure("polytropic"))
    result.campaign = None
    with pytest.raises(ValueError, match="expected a campaign"):
        result.save("never.json")
    result.campaign, result.seed = dict(CAMPAIGN), None
    with pytest.raises(ValueError, match="expected a seed"):
        result.save("never.json")


def test_a_fit_json_is_a_parameter_file(tmp_path: Path) -> None:
    """ParameterSet.load and the parameter-file readers read a fit.json through
    its reader: the fitted structure (with the v1 fallbacks) and the values."""
    from pneumafit.parameters_io import read_parameter_file, read_structure, read_valve_law

    structure = ModelStructure("convection", air_properties="sutherland", valve="map")
    path = _result(structure).save(tmp_path / "fit.json")
    ps = ParameterSet.load(path)
    assert ps["xi"].value == load_fit(path).values["xi"]
    model, values = read_parameter_file(path)
    assert model == "convection" and values["xi"] == ps["xi"].value
    assert read_structure(path)[0] == structure and read_valve_law(path) == "map"
    doc = json.loads(path.read_text())
    del doc["structure"]["air_properties"]  # the v1 writer's Sutherland air
    assert read_structure(_write(path, doc))[0].air_properties == "sutherland"
    _write(path, {**doc, "model": "friction"})  # a friction-test fit is not a plant
    with pytest.raises(PneumafitInputError, match=r"model: expected one of .*found 'friction'"):
        read_parameter_file(path)
