"""Truth configurations, the VirtualRig hook, the sparse protocol and ``pneumafit rig --truth``."""

from __future__ import annotations

import copy
import dataclasses
import io
import json
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console
from typer.testing import CliRunner

from pneumafit.campaign import PneumafitInputError, read_campaign, validate_campaign
from pneumafit.cli.rig import run_rig
from pneumafit.virtual_rig import TRUTH_FILE, RigRun, VirtualRig, get_protocol
from pneumafit.virtual_rig.truth import PRESETS, TruthConfig, get_truth, reference_quantities


@pytest.fixture(scope="module")
def sparse_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sparse protocol on the ``dahl-bump-leak`` preset (probes, Dahl), via run_rig."""
    out = tmp_path_factory.mktemp("truth") / "sparse"
    quiet = Console(file=io.StringIO(), width=200, color_system=None)
    status = run_rig(out, seed=3, console=quiet, protocol="sparse",
                     truth="dahl-bump-leak")  # fmt: skip
    assert status == 0
    return out


@pytest.mark.parametrize("name", list(PRESETS))
def test_presets_round_trip_and_reference_quantities(name: str) -> None:
    """Every preset builds, survives as_dict -> from_dict exactly, and has sane references.

    Reference values are checked against the physically plausible ranges of
    the physics notes (lambda 5..30 W/m^2/K at 5 bar and 30 K; friction of a
    32-mm cylinder tens of newtons), not against themselves.
    """
    cfg = get_truth(name)
    assert TruthConfig.from_dict(cfg.as_dict()) == cfg
    assert TruthConfig.from_dict(json.loads(json.dumps(cfg.as_dict()))) == cfg
    ref = reference_quantities(cfg, VirtualRig().parameters)
    assert 5.0 < ref["lambda_reference"] < 30.0
    assert ref["lambda_full_area_equivalent"] <= ref["lambda_reference"]
    assert 15.0 < ref["friction_coulomb"] <= ref["friction_static"] < 80.0
    assert 5e-9 < ref["valve_C_supply_max"] < 2e-8
    assert 5e-9 < ref["valve_C_exhaust_max"] < 2e-8


def test_config_from_toml_file_and_errors(tmp_path: Path) -> None:
    """A TOML file reads like the dict; bad keys and values are named in the message."""
    text = """
name = "my-rig"
[valve.supply]
family = "power"
C_max = 9.0e-9
u0 = 0.4
[valve.exhaust]
family = "iso_linear"
C_max = 1.1e-8
[valve.leak]
shape = "constant"
C0 = 1e-11
[friction]
model = "dahl"
sigma0 = 1.5e5
F_c = 30.0
[heat]
model = "nusselt"
xi = 0.4
beta = 0.27
area = "barrel_only"
"""
    path = tmp_path / "truth.toml"
    path.write_text(text, encoding="utf-8")
    cfg = get_truth(str(path))
    assert cfg.name == "my-rig" and cfg.heat.area == "barrel_only"
    assert cfg.valve.supply.n == 1.6  # the family's default
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("u0 = 0.4", "u0 = 0.4\nslope = 2.0"), encoding="utf-8")
    with pytest.raises(PneumafitInputError, match=r"valve\.supply\.slope: unknown key"):
        get_truth(str(bad))
    bad.write_text(text.replace('model = "dahl"', 'model = "karnopp"'), encoding="utf-8")
    with pytest.raises(PneumafitInputError, match=r"friction\.model: expected one of lugre, dahl"):
        get_truth(str(bad))
    bad.write_text(text.replace("beta = 0.27", "beta = 2.0"), encoding="utf-8")
    with pytest.raises(PneumafitInputError, match=r"heat.*beta"):
        get_truth(str(bad))
    with pytest.raises(PneumafitInputError, match="--truth: expected a preset"):
        get_truth("no-such-preset")
    with pytest.raises(PneumafitInputError, match="--effect"):
        VirtualRig(effects={"chamber_leakage": None}, truth="mixed")


def test_sparse_protocol_shape() -> None:
    """The sparse protocol: one flow test (P, no 0 V), chamber P only, two short steps."""
    proto = get_protocol("sparse")
    kinds = [t.kind for t in proto.tests]
    assert kinds.count("flow") == 1 and kinds.count("step") == 2
    flow = proto.tests[0]
    assert flow.chamber == "P" and 0.0 not in flow.commands
    blocked = [t for t in proto.tests if t.kind in ("charge", "discharge")]
    assert len(blocked) == 4 and {t.chamber for t in blocked} == {"P"}
    assert sorted(t.role for t in blocked) == ["fit", "fit", "validate", "validate"]
    assert sorted(t.role for t in proto.tests if t.kind == "step") == ["fit", "validate"]


def test_preset_campaign_passes_check(sparse_folder: Path) -> None:
    """A campaign from a preset reads back cleanly and truth.json records the truth model."""
    assert validate_campaign(sparse_folder) == []
    campaign = read_campaign(sparse_folder)
    assert len(campaign.recordings) == 7
    truth = json.loads((sparse_folder / TRUTH_FILE).read_text(encoding="utf-8"))
    model = truth["truth_model"]
    assert model["config"]["name"] == "dahl-bump-leak"
    assert TruthConfig.from_dict(model["config"]) == get_truth("dahl-bump-leak")
    assert set(model["reference_quantities"]) >= {"lambda_reference", "friction_static",
                                                  "friction_coulomb"}  # fmt: skip
    readme = (sparse_folder / "README.md").read_text(encoding="utf-8")
    assert "--truth dahl-bump-leak" in readme and "friction: `dahl`" in readme


def test_truth_drives_the_recordings() -> None:
    """With a truth, the signals come from it: flow = its valve, probes = its probe.

    The flow test's true flow is compared exactly with the configured valve
    (same code path, no integration). The temperature recording minus the
    noiseless probe reading leaves the noise: mean within 0.01 K (4.5
    standard errors of 2001 samples at 0.05 K) and standard deviation within
    10 % of 0.05 K (the sampling spread of a standard deviation over 2001
    samples is 1.6 %).
    """
    rig = VirtualRig(seed=4, truth="dahl-bump-leak")
    run: RigRun = rig.run("sparse")
    trace = run.traces["flow_P.h5"].channels
    cfg = rig.truth
    assert cfg is not None
    par = rig.parameters
    k = 40
    expected = cfg.valve.net_flow(trace["u_P"][k], trace["p_P"][k], par["ambient_temperature"],
                                  par["supply_pressure"], par["exhaust_pressure"],
                                  par["ambient_temperature"])  # fmt: skip
    assert trace["qm_P"][k] == expected
    rec = next(r for r in run.campaign.recordings if r.file == "charge_P_1.h5")
    true_t = run.traces["charge_P_1.h5"].channels["T_P"]
    quiet = dataclasses.replace(cfg.probe, noise=0.0)
    expected = quiet.read(true_t, 1e-3, np.random.default_rng(0))
    residual = rec.channels["T_P"] - expected
    # the recording is the truth's probe: two lags, +0.6 K, and 0.05 K of noise
    assert abs(float(np.mean(residual))) < 0.01
    assert float(np.std(residual)) == pytest.approx(0.05, rel=0.1)
    assert expected[0] - true_t[0] == pytest.approx(0.6, abs=1e-9)  # settled: the offset
    assert float(np.max(true_t - expected)) > 5.0  # the probe lags the heating gas


def test_cli_truth_option(tmp_path: Path, console: Console) -> None:
    """``pneumafit rig --truth``: a bad name or file exits 2 naming the key, no traceback."""
    status = run_rig(tmp_path / "a", console=console, protocol="sparse", truth="nope")
    assert status == 2
    assert "--truth: expected a preset" in console.file.getvalue()  # type: ignore[attr-defined]
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps({**PRESETS["mixed"], "friction": {"model": "lugre"}}))
    runner = CliRunner()
    from pneumafit.cli import app

    result = runner.invoke(app, ["rig", "--out", str(tmp_path / "b"), "--truth", str(bad),
                                 "--protocol", "sparse"])  # fmt: skip
    assert result.exit_code == 2
    assert "friction.sigma0: missing" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "b").exists()


def test_a_campaign_is_recorded_again_from_its_truth_json(tmp_path: Path, console: Console) -> None:
    """A truth given as a file: README.md's command names the campaign's own
    truth.json, which ``--truth`` reads back (its ``truth_model.config``), and
    the campaign recorded from it again is the same, file for file. A preset
    stays named (``test_preset_campaign_passes_check``)."""
    custom = copy.deepcopy(dict(PRESETS["mixed"]))
    custom["name"] = "not-a-preset"
    custom["friction"] = {**custom["friction"], "F_c": 33.3}
    given = tmp_path / "given.json"
    given.write_text(json.dumps(custom))
    first, again = tmp_path / "first", tmp_path / "again"
    assert run_rig(first, seed=4, console=console, protocol="sparse", truth=str(given)) == 0
    readme = (first / "README.md").read_text(encoding="utf-8")
    assert f"pneumafit rig --out DIR --truth {TRUTH_FILE} --protocol sparse --seed 4" in readme
    assert get_truth(first / TRUTH_FILE) == TruthConfig.from_dict(custom)
    assert run_rig(again, seed=4, console=console, protocol="sparse",
                   truth=str(first / TRUTH_FILE)) == 0  # fmt: skip
    assert read_campaign(again).sha256 == read_campaign(first).sha256


def test_a_truth_json_without_an_independent_truth_is_refused(tmp_path: Path) -> None:
    """truth.json of a campaign recorded with the fitted models' own laws holds
    no truth configuration: ``--truth`` says so and what to do instead."""
    path = tmp_path / TRUTH_FILE
    path.write_text(json.dumps({"format": "pneumafit-truth", "version": 1, "parameters": {}}))
    with pytest.raises(PneumafitInputError, match=r"truth_model\.config: expected the independent"):
        get_truth(path)


def test_named_protocols_scale_to_the_stroke_and_others_are_checked() -> None:
    """The named protocols are written for the demo rig's 500-mm stroke: on a
    100-mm cylinder their positions scale by 0.2 and the PD gains by 5 (the
    same commands for the same share of the stroke); at 500 mm they are
    unchanged. A protocol of the user's own keeps its metres, and one that
    leaves the stroke is refused naming the test (before: a truth simulation
    that failed with non-finite states)."""
    sparse = get_protocol("sparse")
    assert sparse.for_stroke(0.5) is sparse
    short = sparse.for_stroke(0.1)
    for old, new in zip(sparse.tests, short.tests, strict=True):
        if hasattr(old, "position"):
            assert new.position == pytest.approx(0.2 * old.position, rel=1e-9)
        if hasattr(old, "start"):
            assert new.start == pytest.approx(0.2 * old.start, rel=1e-9)
            assert [y for _t, y in new.steps] == pytest.approx([0.2 * y for _t, y in old.steps])
            assert (new.kp, new.kd) == pytest.approx((5.0 * old.kp, 5.0 * old.kd))
    own = dataclasses.replace(sparse, design_stroke=None)
    refused = r"test 'charge_P_1\.h5': position: expected a position within the rig's stroke"
    with pytest.raises(PneumafitInputError, match=refused + r" \[0, 100\] mm, found 120 mm"):
        own.for_stroke(0.1)


def test_a_short_cylinder_records_the_sparse_plan(tmp_path: Path, console: Console) -> None:
    """``pneumafit rig --protocol sparse`` on a truth file with a 100-mm stroke
    writes a valid campaign whose positions lie within the stroke."""
    custom = copy.deepcopy(dict(PRESETS["mixed"]))
    custom["parameters"] = {**custom.get("parameters", {}), "stroke": 0.1}
    given = tmp_path / "short.json"
    given.write_text(json.dumps(custom))
    out = tmp_path / "short"
    assert run_rig(out, seed=2, console=console, protocol="sparse", truth=str(given)) == 0
    assert validate_campaign(out) == []
    campaign = read_campaign(out)
    assert campaign.rig.stroke == pytest.approx(0.1)
    for rec in campaign.recordings:
        if "y" in rec.channels:
            y = rec.channels["y"]
            assert 0.0 <= float(np.min(y)) and float(np.max(y)) <= 0.1


#: The truth files of docs/examples and the figures docs/identification.md
#: quotes for them ("A rig of another size and mounting"): lambda_ref
#: (W/m^2/K), static and Coulomb friction at mid pressure (N), and the rig.
EXAMPLES = {
    "truth-big-inclined.toml": ((17.70, 71.50, 47.00), {"bore": 0.05, "stroke": 0.3,
                                                         "mounting_angle": 0.35}),
    "truth-small-steep.toml": ((20.45, 17.00, 11.50), {"bore": 0.02, "stroke": 0.1,
                                                        "mounting_angle": 1.22}),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_the_example_truth_files_record_the_rigs_the_docs_describe(
    name: str, tmp_path: Path
) -> None:
    """Each example file records a valid sparse campaign of its own rig (the
    geometry and mounting in campaign.toml, the protocol scaled to its
    stroke), whose reference quantities are the ones the docs quote (to the
    quoted digits)."""
    path = Path(__file__).resolve().parents[2] / "docs" / "examples" / name
    quiet = Console(file=io.StringIO(), width=200, color_system=None)
    out = tmp_path / "camp"
    assert run_rig(out, seed=4, console=quiet, protocol="sparse", truth=str(path)) == 0
    campaign = read_campaign(out)
    assert validate_campaign(out) == []
    (lam, f_s, f_c), rig = EXAMPLES[name]
    declared = campaign.rig.as_parameters()
    for key, value in rig.items():
        assert declared[key] == pytest.approx(value), key
    ref = json.loads((out / TRUTH_FILE).read_text())["truth_model"]["reference_quantities"]
    assert round(ref["lambda_reference"], 2) == lam
    assert round(ref["friction_static"], 2) == f_s
    assert round(ref["friction_coulomb"], 2) == f_c
    stroke = rig["stroke"]
    for rec in campaign.recordings:
        if "y" in rec.channels:
            assert np.nanmax(rec.channels["y"]) <= stroke + 1e-3, rec.file
