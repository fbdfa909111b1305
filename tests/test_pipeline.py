"""The main job end to end (``pneumafit run``) on a small virtual-rig campaign.

Without MCMC (the fits' samplers are tested in tests/identification), the
whole chain runs in about a minute: three fits, comparison, discovery,
linear analysis, closed loop, export and report. The second run must reuse
every stage.
"""

from __future__ import annotations

import io
import json
import time
import zipfile
from pathlib import Path

import pytest
from rich.console import Console

from pneumafit.pipeline import FIT_ORDER, RUN_MODELS, StageBook, fit_is_reusable
from pneumafit.pipeline import run as run_pipeline
from pneumafit.virtual_rig import VirtualRig
from pneumafit.virtual_rig.protocol import quick_protocol


def _console() -> Console:
    return Console(file=io.StringIO(), width=140, color_system=None)


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str, float]:
    root = tmp_path_factory.mktemp("pipeline")
    campaign = root / "campaign"
    VirtualRig(seed=4).write(campaign, quick_protocol())
    out = root / "run"
    console = _console()
    t0 = time.perf_counter()
    code = run_pipeline(campaign, out, console, mcmc=False)
    seconds = time.perf_counter() - t0
    assert code == 0, console.file.getvalue()[-3000:]
    return campaign, out, console.file.getvalue(), seconds


def test_every_stage_writes_its_outputs(finished_run: tuple) -> None:
    campaign, out, log, _ = finished_run
    for model in RUN_MODELS:
        fit = json.loads((out / "fits" / model / "fit.json").read_text())
        assert fit["model"] == model
    # the convection fit chooses the friction law (auto); the others use it
    # (the same law in all three, without fitting the second law again). The
    # quick plan has no fit step test, so this checks the plumbing, not the
    # choice (tests/test_friction_lugre.py and test_mismatched.py do that)
    first, *later = FIT_ORDER
    law = json.loads((out / "fits" / first / "fit.json").read_text())["structure"]["friction"]
    for model in later:
        fit = json.loads((out / "fits" / model / "fit.json").read_text())
        assert fit["structure"]["friction"] == law
        assert f"--friction {law}" in fit["provenance"]["command"]
        assert "LuGre log-likelihood gain" not in (fit["stages"]["friction"].get("note") or "")
    assert f"friction law {law}, as chosen by the {first} fit" in log
    comparison = json.loads((out / "comparison" / "comparison.json").read_text())
    assert set(comparison["models"]) == set(RUN_MODELS)
    discovery = json.loads((out / "discovery" / "discovery.json").read_text())
    assert discovery["format"] == "pneumafit-discovery"
    assert (out / "linear" / "linear.json").exists()
    assert (out / "linear" / "design_6.json").exists()
    closed = json.loads((out / "closed_loop" / "closed_loop.json").read_text())
    assert len(closed["controllers"]) == 2
    for name in ("controller.json", "controller.yaml", "controller.h", "controller.c",
                 "controller.mat", "controller.csv", "sil.json"):  # fmt: skip
        assert (out / "export" / name).stat().st_size > 0
    exported = json.loads((out / "export" / "controller.json").read_text())
    assert exported["design"]["validated"] is True  # the closed-loop stage's design
    assert exported["design"]["w0"] == closed["inputs"]["w0_rad_s"]
    sil = json.loads((out / "export" / "sil.json").read_text())
    if sil["run"]:  # a C compiler was found: the plant FMU is built too
        assert sil["max_command_difference_V"] <= 1e-9 and sil["identical_figures"]
        with zipfile.ZipFile(out / "export" / "plant.fmu") as fmu:
            assert "modelDescription.xml" in fmu.namelist()
    html = (out / "report.html").read_text()
    assert "The exported controller in the loop" in html
    # the report reads what the comparison saved: no replay, no residual analysis
    assert (out / "comparison" / "residuals.json").is_file()
    assert "report: simulated" not in log
    assert "comparison/residuals.json</code> (the convection fit's residual analysis" in html
    assert "run here (" not in html
    assert html.lstrip().lower().startswith("<!doctype html")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failed_stage"] is None
    assert summary["campaign"]["path"] == str(campaign)
    assert "xi" in summary["convection"] and "total time" in log
    # where the time went: every stage's wall time, simulations and their rate
    assert set(summary["simulations"]) == set(summary["seconds"])
    assert set(summary["simulations_per_second"]) == set(summary["seconds"])
    for model in RUN_MODELS:
        assert summary["simulations"][f"fit {model}"] > 0
        assert summary["simulations_per_second"][f"fit {model}"] > 0
    assert summary["total_simulations"] == sum(summary["simulations"].values())
    assert "simulations" in log and "per second" in log
    # what the comparison and discovery concluded, at the end, where one looks first
    tail = log[log.rindex("done") :]
    assert "comparison: held-out pressure RMSE" in tail
    assert all(f"{m} " in tail for m in RUN_MODELS)
    assert "discovery: selected" in tail and discovery["statement"][:40] in tail


def test_a_second_run_reuses_every_stage(finished_run: tuple) -> None:
    campaign, out, _, _ = finished_run
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.json")}
    console = _console()
    assert run_pipeline(campaign, out, console, mcmc=False) == 0
    log = console.file.getvalue()
    for model in RUN_MODELS:
        assert f"fit {model}: reused" in log
    for stage in ("comparison", "discovery", "linear", "closed_loop", "export", "report"):
        assert f"{stage}: reused" in log
    # nothing but the run's own bookkeeping was rewritten
    changed = [p.name for p, t in before.items() if p.stat().st_mtime_ns != t]
    assert set(changed) <= {"summary.json"}, changed
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["simulations_per_second"].values()) == {None}  # all reused
    assert summary["total_simulations"] == 0


def test_a_changed_fit_reruns_the_stages_that_read_it(finished_run: tuple, tmp_path: Path) -> None:
    campaign, out, _, _ = finished_run
    book = StageBook(out)
    from pneumafit.campaign import read_campaign

    camp = read_campaign(campaign)
    conv = out / "fits" / "convection" / "fit.json"
    fp = book.fingerprint(camp, [conv])
    assert book.is_done("discovery", fp, [out / "discovery" / "discovery.json"])
    copy = tmp_path / "fit.json"
    copy.write_text(conv.read_text().replace('"pneumafit-fit"', '"pneumafit-fit" ', 1))
    assert book.fingerprint(camp, [copy]) != fp
    assert fit_is_reusable(conv.parent, camp, "convection")
    assert not fit_is_reusable(conv.parent, camp, "polytropic")
    # a run with the other valve law (run --valve map) fits again
    assert fit_is_reusable(conv.parent, camp, "convection", "iso6358")
    assert not fit_is_reusable(conv.parent, camp, "convection", "map")
    # ... and with the inputs read the other way (run --inputs linear)
    assert fit_is_reusable(conv.parent, camp, "convection", "iso6358", "hold")
    assert not fit_is_reusable(conv.parent, camp, "convection", "iso6358", "linear")


def test_an_invalid_campaign_runs_nothing(tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "campaign.toml").write_text("this is not toml = = =\n")
    console = _console()
    assert run_pipeline(bad, tmp_path / "out", console, mcmc=False) == 2  # bad input
    assert not (tmp_path / "out" / "fits").exists()


def test_a_campaign_of_flow_tests_alone_runs_without_discovery(tmp_path: Path) -> None:
    """A valve characterised on its own: discovery, which analyses the
    residual pressure rates of charge/discharge and step tests, is skipped
    with a line that says why, and the run ends with its report (exit 0; it
    stopped at discovery with status 2 before)."""
    import re

    campaign = tmp_path / "campaign"
    VirtualRig(seed=4).write(campaign, quick_protocol())
    toml = campaign / "campaign.toml"
    head, *blocks = re.split(r"(?=^\[\[recording\]\]\n)", toml.read_text(), flags=re.M)
    flows = [b for b in blocks if 'kind = "flow"' in b]
    assert flows and len(flows) < len(blocks)
    toml.write_text(head + "".join(flows))
    out = tmp_path / "run"
    console = _console()
    assert run_pipeline(campaign, out, console, mcmc=False) == 0, console.file.getvalue()[-3000:]
    text = console.file.getvalue()
    assert "discovery skipped: the campaign has no charge/discharge or step recording" in text
    assert (out / "report.html").is_file() and not (out / "discovery").exists()
    assert run_pipeline(campaign, out, console, mcmc=False) == 0  # the re-run reuses the stages


def test_a_truth_naming_unknown_parameters_is_not_the_closed_loop_s_plant(
    finished_run: tuple, tmp_path: Path
) -> None:
    """The closed loop's plant is the campaign's truth.json only when this
    process can run it: a rig recorded with parts from outside the package
    names their parameters, which a run without them cannot read (it then
    simulates the convection fit and says why, instead of failing)."""
    import json

    from pneumafit.pipeline import _unrunnable_truth

    campaign = finished_run[0]
    truth = campaign / "truth.json"
    assert _unrunnable_truth(truth) is None  # the virtual rig's own laws
    doc = json.loads(truth.read_text(encoding="utf-8"))
    doc["parameters"]["my_C_supply"] = 1e-8
    other = tmp_path / "truth.json"
    other.write_text(json.dumps(doc), encoding="utf-8")
    why = _unrunnable_truth(other)
    assert why is not None and "my_C_supply" in why
    assert _unrunnable_truth(tmp_path / "missing.json") == "cannot be read"


def test_a_fit_made_with_other_outside_parts_is_not_reused(
    finished_run: tuple, tmp_path: Path
) -> None:
    """``fit_is_reusable`` compares the fit's ``provenance.parts`` with the
    parts registered now: a fit of an edited law of one's own is made again."""
    import json
    import shutil

    from pneumafit.campaign import read_campaign
    from pneumafit.models.part_kernel import parts_digest
    from pneumafit.pipeline import fit_is_reusable

    campaign_path, out = finished_run[0], finished_run[1]
    campaign = read_campaign(campaign_path)
    folder = tmp_path / "fit"
    shutil.copytree(out / "fits" / "convection", folder)
    doc = json.loads((folder / "fit.json").read_text())
    assert doc["provenance"]["parts"] == parts_digest()
    assert fit_is_reusable(folder, campaign, "convection")
    doc["provenance"]["parts"] = "0" * 64  # made with another law of one's own
    (folder / "fit.json").write_text(json.dumps(doc))
    assert not fit_is_reusable(folder, campaign, "convection")


def test_run_takes_a_friction_law(finished_run: tuple, tmp_path: Path) -> None:
    """``run --friction``: a name no law has is bad input before anything
    runs; the law the convection fit chose, named, reuses every fit (they
    were all made with it), and another law would not
    (``fit_is_reusable(friction=...)``)."""
    from pneumafit.campaign import read_campaign
    from pneumafit.identification.staged import FitResult

    campaign, out, _, _ = finished_run
    console = _console()
    assert run_pipeline(campaign, tmp_path / "out", console, mcmc=False,
                        friction="karnopp") == 2  # fmt: skip
    log = console.file.getvalue()
    assert "option --friction: expected one of auto, switch, lugre" in log and "--parts" in log
    assert not (tmp_path / "out" / "fits").exists()
    chosen = FitResult.load(out / "fits" / "convection" / "fit.json").structure.friction
    console = _console()
    assert run_pipeline(campaign, out, console, mcmc=False, friction=chosen) == 0
    log = console.file.getvalue()
    assert all(f"fit {model}: reused" in log for model in RUN_MODELS)
    other = "switch" if chosen == "lugre" else "lugre"
    camp = read_campaign(campaign)
    assert not fit_is_reusable(out / "fits" / "convection", camp, "convection", friction=other)


def test_the_conclusions_read_what_the_stages_saved(tmp_path: Path) -> None:
    """The end of the run's console: each model's held-out pressure RMSE
    from comparison.json with the lowest named, discovery's selection, its
    held-out figures and statement; nothing for a stage that saved nothing
    (a run without held-out recordings, or stopped before discovery)."""
    from pneumafit.pipeline import print_conclusions

    console = _console()
    print_conclusions(tmp_path, console)
    assert console.file.getvalue() == ""
    (tmp_path / "comparison").mkdir()
    (tmp_path / "discovery").mkdir()
    by_model = {"convection": 2500.0, "constant-lambda": 1900.0, "polytropic": 4100.0}
    comparison = {"models": list(by_model)} | {
        m: {"rmse_by_quantity": {"validate": {"pressure": v}}} for m, v in by_model.items()
    }
    (tmp_path / "comparison" / "comparison.json").write_text(json.dumps(comparison))
    discovery = {
        "selected": ["external_leakage"], "unexplained": True, "statement": "partly explained.",
        "pressure_rmse_before": {"validate": 12145.5}, "pressure_rmse_after": {"validate": 2536.6},
    }  # fmt: skip
    (tmp_path / "discovery" / "discovery.json").write_text(json.dumps(discovery))
    print_conclusions(tmp_path, console)
    text = console.file.getvalue()
    assert (
        "comparison: held-out pressure RMSE convection 2500 Pa, constant-lambda 1900 Pa, "
        "polytropic 4100 Pa; lowest: constant-lambda" in text
    )
    assert "discovery: selected external_leakage; held-out pressure RMSE 12146 -> 2537 Pa" in text
    assert "partly explained." in text
    assert "sensors' readings" not in text  # no base model named: nothing to reconcile


def test_the_conclusions_say_why_discovery_and_comparison_differ(tmp_path: Path) -> None:
    """One fit, two held-out figures: discovery's is the RMS of the pressure
    channels' RMSEs, replayed from the sensors' readings; the comparison's
    pools every sample and starts from the fit's sensor offsets. Where they
    differ (a truth outside the presets, the sparse-long plan: 5222 against
    6056 Pa) the line says which is which; where they agree (the bundled
    demo) nothing is added."""
    from pneumafit.pipeline import print_conclusions

    (tmp_path / "comparison").mkdir()
    (tmp_path / "discovery").mkdir()
    held = {"rmse_by_quantity": {"validate": {"pressure": 6056.0}}}
    comparison = {"models": ["convection"], "convection": held}
    (tmp_path / "comparison" / "comparison.json").write_text(json.dumps(comparison))
    for before, said in ((5222.3, True), (6080.0, False)):
        discovery = {
            "base_model": "convection", "selected": ["effective_area"], "unexplained": True,
            "statement": "partly explained.", "pressure_rmse_before": {"validate": before},
            "pressure_rmse_after": {"validate": 3279.4},
        }  # fmt: skip
        (tmp_path / "discovery" / "discovery.json").write_text(json.dumps(discovery))
        console = _console()
        print_conclusions(tmp_path, console)
        text = " ".join(console.file.getvalue().split())
        assert f"held-out pressure RMSE {before:.0f} -> 3279 Pa" in text
        said_why = "the comparison's 6056 Pa pools every sample and starts from the fit's sensor"
        assert (said_why in text) is said


def test_a_friction_jobs_conclusion_gives_the_held_out_force(tmp_path: Path) -> None:
    """A friction-test job saves no comparison and a force, not pressures."""
    from pneumafit.pipeline import print_conclusions

    (tmp_path / "discovery").mkdir()
    discovery = {
        "selected": ["seal_pressure"], "unexplained": False, "statement": "explained.",
        "rmse_before": {"fit": {"F": 2.4}, "validate": {"F": 5.934}},
        "rmse_after": {"fit": {"F": 0.3}, "validate": {"F": 0.412}},
    }  # fmt: skip
    (tmp_path / "discovery" / "discovery.json").write_text(json.dumps(discovery))
    console = _console()
    print_conclusions(tmp_path, console)
    text = console.file.getvalue()
    assert "comparison" not in text
    assert "discovery: selected seal_pressure; held-out force RMSE 5.934 -> 0.412 N" in text
