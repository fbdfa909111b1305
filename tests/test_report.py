"""The validation report: one self-contained HTML file from a run folder.

The run folder is built from real outputs: a tiny virtual-rig campaign, a
convection fit with a short MCMC (``identify``: fit.json and chains.h5 as
``pneumafit fit`` writes them), a polytropic fit without MCMC, and the
linear analysis and designs of the main job. Comparison, discovery and
closed-loop files come from engineers' stages not run here: their sections
are checked as "not run", and separately on documents of their documented
formats and on malformed files.
"""

from __future__ import annotations

import html
import io
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import read_campaign
from pneumafit.campaign.errors import PneumafitInputError
from pneumafit.identification import FitOptions, fit_document, identify, write_fit_json
from pneumafit.identification.fitfile import WIDENING_SHOWN, widening_label
from pneumafit.identification.quality import one_recording_caveat, parameter_flags
from pneumafit.outputs.report import SECTIONS, write_report
from pneumafit.virtual_rig import BlockedTest, FlowTest, Protocol, StepTest, VirtualRig

#: Short chains: these tests check the report, not the posteriors.
WALKERS, STEPS = 8, 20


def _tiny_protocol() -> Protocol:
    """A small flow test, a charge test with a temperature sensor, a held-out
    discharge, one closed-loop step test.

    The flow test is there for speed: without one the fit tries the valve
    law's extensions on the joint problem (five more least-squares stages),
    which took the two fits 104 s against 24 s with it (measured 2026-12-01).
    """
    tests = (
        FlowTest(file="flow_P.h5", chamber="P", commands=(-10.0, -6.0, -3.0, 0.0, 3.0, 6.0, 10.0),
                 pressures=(2e5, 4e5, 6e5), dwell=0.3),
        BlockedTest(file="charge_P.h5", kind="charge", chamber="P", position=0.1, amplitude=10.0,
                    opening_time=0.2, duration=1.2, temperature=True),
        BlockedTest(file="discharge_N.h5", kind="discharge", chamber="N", position=0.2,
                    amplitude=10.0, opening_time=0.2, duration=1.0, role="validate"),
        StepTest(file="step_1.h5", start=0.25, steps=((0.2, 0.32), (0.9, 0.22)), duration=1.6,
                 preroll=1.0),
    )  # fmt: skip
    return Protocol(name="report-tiny", description="tiny campaign for the report", tests=tests)


def _sections(html: str) -> dict[str, str]:
    """Section anchor -> its status (data-status attribute)."""
    return dict(re.findall(r'<section id="([^"]+)" data-status="([^"]+)"', html))


def _section_html(html: str, anchor: str) -> str:
    start = html.index(f'<section id="{anchor}"')
    return html[start : html.index("</section>", start)]


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A run folder from real outputs (see the module docstring): (run, campaign)."""
    from pneumafit.models import parameter_vector
    from pneumafit.outputs.linear_report import write_design, write_linear

    root = tmp_path_factory.mktemp("report")
    folder = root / "campaign"
    VirtualRig(seed=3).write(folder, _tiny_protocol())
    campaign = read_campaign(folder)
    run = root / "run"
    for model, mcmc in (("convection", True), ("polytropic", False)):
        out = run / "fits" / model
        out.mkdir(parents=True)
        options = FitOptions(mcmc=mcmc, walkers=WALKERS, steps=STEPS, correct_solver=False)
        chains = out / "chains.h5" if mcmc else None
        result = identify(campaign, model, options=options, seed=1, chains=chains)
        doc = fit_document(result, campaign, seed=1, options=options,
                           chains="chains.h5" if mcmc else None)  # fmt: skip
        write_fit_json(out / "fit.json", doc)
    params = parameter_vector(campaign.rig.as_parameters())  # nominal: the rig + defaults
    ys = np.linspace(0.1, 0.9, 5) * campaign.rig.stroke
    write_linear(params, ys, run / "linear", lambda_e=15.0)
    write_design(params, ys, run / "linear", order=4, w0=12.0, lambda_e=15.0)
    return run, folder


@pytest.fixture(scope="module")
def report(run_folder: tuple[Path, Path]) -> tuple[Path, str]:
    run, _ = run_folder
    console = Console(file=io.StringIO(), width=160)
    path = write_report(run, run / "report.html", console=console)
    return path, path.read_text(encoding="utf-8")


def test_one_self_contained_file_with_every_section(
    run_folder: tuple[Path, Path], report: tuple[Path, str]
) -> None:
    run, campaign = run_folder
    path, html = report
    assert path == run / "report.html" and path.is_file()
    assert not list(run.glob(".report.html.*"))  # written atomically, nothing left over
    for anchor, title in SECTIONS:
        assert f"<h2>{title}" in html, title
        assert f'href="#{anchor}"' in html  # table of contents
    # nothing from the network: every src/href is a data URI or an anchor
    refs = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)""", html)
    assert refs and all(r.startswith(("data:", "#")) for r in refs), refs
    assert not re.search(r"https?://", html)
    assert "@import" not in html and "url(" not in html
    images = re.findall(r'<img class="fig"[^>]*src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)
    # 4 overlays (one per recording) + 3 residual figures + (trace + corner) x 2 stages
    # + 3 linear figures
    assert len(images) == 4 + 3 + 4 + 3, len(images)
    assert all(len(b) > 1000 for b in images)
    # the campaign came from fit.json's campaign.path
    assert str(campaign) in html
    for file in ("flow_P.h5", "charge_P.h5", "discharge_N.h5", "step_1.h5"):
        assert file in _section_html(html, "campaign")
        assert f"<h3>{file}" in _section_html(html, "measurement")


def test_sections_render_what_the_run_holds(
    run_folder: tuple[Path, Path], report: tuple[Path, str]
) -> None:
    run, _ = run_folder
    _, html = report
    status = _sections(html)
    assert status == {
        "campaign": "ok",
        "measurement": "partial",  # constant-lambda was not fitted
        "residuals": "ok",
        "parameters": "partial",
        "mcmc": "partial",  # the polytropic fit has no MCMC
        "comparison": "not run",
        "linear": "partial",  # design_6.json was not written
        "discovery": "not run",
        "closed-loop": "not run",  # never run here: not "partial"
        "air": "ok",  # the air each fit draws on the recorded tests
    }
    fit = json.loads((run / "fits" / "convection" / "fit.json").read_text())
    params = _section_html(html, "parameters")
    xi = fit["parameters"]["xi"]
    assert f"{xi['value']:.4g}" in params and f"{xi['interval_90'][0]:.4g}" in params
    assert "N s/m" in params  # units next to the numbers
    widened = [e["interval_widening"] for e in fit["parameters"].values()
               if e.get("interval_widening", 1.0) >= WIDENING_SHOWN]  # fmt: skip
    assert all(f"<td>{widening_label(f)}</td>" in params for f in widened)
    mcmc = _section_html(html, "mcmc")
    assert "corner plot convection heat" in mcmc and "corner plot convection friction" in mcmc
    assert "MCMC traces convection friction" in mcmc
    assert f"{fit['mcmc']['stages']['heat']['acceptance']:.3g}" in mcmc
    assert "a <code>--no-mcmc</code> fit" in mcmc  # polytropic
    measurement = _section_html(html, "measurement")
    assert "not run for constant-lambda" in measurement
    assert "RMSE p_P" in measurement and "kPa" in measurement
    assert "Ljung-Box" in _section_html(html, "residuals")
    assert "closed_loop.json</code> not found" in _section_html(html, "closed-loop")
    assert "air supplied" in _section_html(html, "air")
    linear = _section_html(html, "linear")
    assert "open_loop_poles.png" in linear and "gain_schedule_4.png" in linear


def test_the_parameter_table_shows_the_interval_widening(
    run_folder: tuple[Path, Path], tmp_path: Path
) -> None:
    """fit.json's ``interval_widening`` (written only where the robust
    covariance widened an interval) is the table's "widened" column: a copy
    of the run whose xi was widened 3.47x shows "x3.5" on xi's row; the
    quality's caveats are shown under its verdict; the last column is the
    flag the console's table gives (quality.parameter_flags): xi made
    "not determined" in the copy's quality shows it, beta its own."""
    run, _ = run_folder
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    path = copy / "fits" / "convection" / "fit.json"
    fit = json.loads(path.read_text())
    fit["parameters"]["xi"]["interval_widening"] = 3.47
    fit["parameters"]["beta"].pop("interval_widening", None)
    caveat = one_recording_caveat({"friction_static": "step_1.h5"})
    fit["quality"]["caveats"] = [caveat]
    fit["quality"]["undetermined"] = ["xi 0.4, 90 % [0.01, 0.9]: a factor 90"]
    path.write_text(json.dumps(fit))
    params = _section_html(write_report(copy, tmp_path / "r.html").read_text(), "parameters")
    rows = {re.sub("<[^>]+>", "", row.split("</td>", 1)[0]): row
            for row in params.split("<tr>")[1:]}  # fmt: skip
    assert "widened" in params
    assert "<td>x3.5</td>" in rows["xi"]
    assert html.escape(caveat) in params  # the quality's caveats, under its verdict
    assert "<td>x3.5</td><td><strong>not determined</strong></td></tr>" in rows["xi"]
    assert "<td>x3.5</td>" not in rows["beta"]
    # beta's flag is its own fit's (the test run's short chains: "chain short")
    flag = parameter_flags(fit["quality"]).get("beta")
    cell = f"<td><strong>{flag}</strong></td>" if flag else "<td></td>"
    assert rows["beta"].rstrip().endswith(f"<td>-</td>{cell}</tr>")


def test_an_empty_run_folder_gives_not_run_sections(tmp_path: Path) -> None:
    out = write_report(tmp_path, tmp_path / "r" / "report.html")
    html = out.read_text(encoding="utf-8")
    assert set(_sections(html).values()) == {"not run"}
    assert html.count('class="notrun"') >= len(SECTIONS)
    for anchor, _ in SECTIONS:
        assert "not run" in _section_html(html, anchor), anchor


def test_a_report_on_another_campaign_is_refused_or_says_so(
    run_folder: tuple[Path, Path], tmp_path: Path
) -> None:
    """Fits made from other campaign files than --campaign (here the same
    protocol recorded with another seed): an input error before anything is
    written unless allowed, and then said at the top and in the campaign
    section. The fits' own campaign passes."""
    run, campaign = run_folder
    other = tmp_path / "other"
    VirtualRig(seed=4).write(other, _tiny_protocol())
    target = tmp_path / "report.html"
    with pytest.raises(PneumafitInputError, match=r"fits/convection/fit.json was made from"):
        write_report(run, target, campaign=other, allow_partial=False)
    assert not target.exists()
    html = write_report(run, target, campaign=other).read_text(encoding="utf-8")
    assert "<strong>Inputs disagree</strong>" in html
    assert "inputs disagree: fits/polytropic/fit.json" in _section_html(html, "campaign")
    assert str(campaign) in _section_html(html, "campaign")  # where the fits came from
    html = write_report(run, target, campaign=campaign, allow_partial=False).read_text("utf-8")
    assert "Inputs disagree" not in html


def test_bad_run_folder_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(PneumafitInputError, match=r"nowhere: expected a folder.*found nothing"):
        write_report(tmp_path / "nowhere", tmp_path / "r.html")
    (tmp_path / "file").write_text("x")
    with pytest.raises(PneumafitInputError, match="file: expected a folder, found a file"):
        write_report(tmp_path / "file", tmp_path / "r.html")
    with pytest.raises(PneumafitInputError, match="--campaign"):
        write_report(tmp_path, tmp_path / "r.html", campaign=tmp_path / "no-campaign")
    res = subprocess.run(
        [sys.executable, "-m", "pneumafit", "report", str(tmp_path / "nowhere")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert res.returncode == 2
    assert "nowhere" in res.stderr and "found nothing" in res.stderr
    assert "Traceback" not in res.stderr + res.stdout


def test_malformed_inputs_are_reported_not_raised(
    run_folder: tuple[Path, Path], tmp_path: Path
) -> None:
    run, _ = run_folder
    bad = tmp_path / "run"
    shutil.copytree(run / "fits" / "convection", bad / "fits" / "convection")
    (bad / "fits" / "convection" / "chains.h5").write_bytes(b"not an HDF5 file")
    (bad / "fits" / "polytropic").mkdir(parents=True)
    (bad / "fits" / "polytropic" / "fit.json").write_text("{broken")
    (bad / "fits" / "constant-lambda").mkdir(parents=True)
    (bad / "fits" / "constant-lambda" / "fit.json").write_text('{"format": "other"}')
    for name, text in (("comparison/comparison.json", "[1, 2]"),
                       ("discovery/discovery.json", '{"candidates": [3, {"effect": 1}], '
                                                    '"rmse_before": 7}'),
                       ("closed_loop/closed_loop.json", '{"controllers": "none"}'),
                       ("linear/linear.json", "")):  # fmt: skip
        (bad / name).parent.mkdir(parents=True, exist_ok=True)
        (bad / name).write_text(text)
    html = write_report(bad, bad / "report.html").read_text(encoding="utf-8")
    status = _sections(html)
    assert status["comparison"] == "error" and "expected a JSON object" in html
    assert status["mcmc"] == "partial"
    assert "fit polytropic" in html and "not readable as JSON" in html
    assert "expected &#x27;pneumafit-fit&#x27;, found &#x27;other&#x27;" in html
    assert status["linear"] == "partial"
    assert status["discovery"] == "ok"  # whatever keys exist, read defensively
    assert status["measurement"] == "partial" and "corner plot convection" not in html


def test_documented_formats_of_other_stages_render(tmp_path: Path) -> None:
    """comparison.json, discovery.json, closed_loop.json in their documented
    formats (format fixtures, not results) render as tables with units."""
    docs = {
        "comparison/comparison.json": {
            "format": "pneumafit-comparison", "version": 1,
            "models": ["convection", "polytropic"],
            "convection": {"rmse": {"fit": {"p_P": 420.0, "y": 1.4e-5}}, "aic": 10.0,
                           "bic": 12.0, "log_likelihood": -3.0},
            "polytropic": {"rmse": {"fit": {"p_P": 4.2e4, "y": 7.0e-3}}, "aic": 99.0,
                           "bic": 101.0},
            "best": {"aic": "convection"},
        },
        "discovery/discovery.json": {
            "format": "pneumafit-discovery",
            "candidates": [{"effect": "chamber_leakage", "score": 0.93,
                            "evidence": {"variance_explained": 0.81}},
                           {"effect": "valve_dynamics", "score": 0.12, "evidence": {}}],
            "selected": ["chamber_leakage"],
            "rmse_before": {"fit": {"p_P": 2000.0}}, "rmse_after": {"fit": {"p_P": 500.0}},
            "aic_before": 500.0, "aic_after": 100.0,
            "effect_parameters": {"chamber_leak_conductance": {
                "value": 2e-11, "unit": "kg/s/Pa", "interval_90": [1.8e-11, 2.2e-11]}},
        },
        "closed_loop/closed_loop.json": {
            "format": "pneumafit-closed-loop",
            "controllers": [{"name": "order 6", "order": 6, "ok": True, "air_mass_kg": 4.3e-4,
                             "exergy_J": 69.8, "steps": [{"start_s": 0.5,
                                                          "air_mass_kg": 2.3e-4}]}],
        },
    }  # fmt: skip
    for name, doc in docs.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(json.dumps(doc))
    html = write_report(tmp_path, tmp_path / "report.html").read_text(encoding="utf-8")
    status = _sections(html)
    assert status["comparison"] == "ok" and status["discovery"] == "ok"
    comparison = _section_html(html, "comparison")
    assert "0.42&nbsp;kPa" in comparison and "42&nbsp;kPa" in comparison
    assert "0.014&nbsp;mm" in comparison
    discovery = _section_html(html, "discovery")
    assert "<strong>chamber_leakage</strong>" in discovery
    assert "-75&nbsp;%" in discovery  # RMSE 2 kPa -> 0.5 kPa
    assert "2.000e-11&nbsp;kg/s/Pa" in discovery
    closed_loop = _section_html(html, "closed-loop")
    assert status["closed-loop"] == "ok"
    assert "0.43&nbsp;g" in closed_loop and "69.8&nbsp;J" in closed_loop
    assert "air mass [g]" in closed_loop


def _chromium() -> str | None:
    for name in ("/usr/bin/chromium", "chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


def test_the_report_renders_in_headless_chromium(report: tuple[Path, str], tmp_path: Path) -> None:
    browser = _chromium()
    if browser is None:
        pytest.skip(
            "chromium not installed: no /usr/bin/chromium, chromium or chromium-browser on "
            "PATH (.ci/run installs Debian's chromium where apt-get can)"
        )
    path, text = report
    n_figures = len(re.findall(r'<img class="fig"', text))  # 14, counted by the first test
    common = [
        browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
        "--no-first-run", "--disable-background-networking", "--disable-component-update",
        "--disable-sync", "--disable-dev-shm-usage", "--enable-logging=stderr", "--v=0",
    ]  # fmt: skip
    shot = tmp_path / "shot.png"
    res = subprocess.run(
        [*common, f"--user-data-dir={tmp_path / 'profile-1'}", f"--screenshot={shot}",
         "--window-size=1280,2000", path.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    dom = subprocess.run(
        [*common, f"--user-data-dir={tmp_path / 'profile-2'}", "--dump-dom",
         path.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert dom.returncode == 0, dom.stderr[-2000:]
    # console messages of the page are logged as "CONSOLE(line)"; the page logs a
    # console error for a figure that does not decode
    for err in (res.stderr, dom.stderr):
        page_lines = [line for line in err.splitlines() if "CONSOLE" in line]
        assert not page_lines, page_lines
        assert "Uncaught" not in err
    # the DOM is complete and every figure decoded (set by the page's load handler)
    assert 'id="report-end"' in dom.stdout
    figures = re.search(r'data-figures="(\d+)"', dom.stdout)
    assert figures is not None and int(figures.group(1)) == n_figures
    assert 'data-figures-bad="0"' in dom.stdout
    # the check can fail: a figure that does not decode is reported by the page
    broken = tmp_path / "broken.html"
    html = path.read_text(encoding="utf-8")
    broken.write_text(re.sub(r"base64,[A-Za-z0-9+/=]+", "base64,AAAA", html, count=1))
    bad = subprocess.run(
        [*common, f"--user-data-dir={tmp_path / 'profile-3'}", "--dump-dom",
         broken.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert "figure did not decode" in bad.stderr and 'data-figures-bad="1"' in bad.stdout
    # a real screenshot: a PNG of the window size, not blank
    from PIL import Image

    assert shot.is_file() and shot.stat().st_size > 20_000
    with Image.open(shot) as image:
        assert image.size == (1280, 2000)
        pixels = np.asarray(image.convert("L"))
    assert pixels.std() > 10.0


def test_the_report_reads_the_saved_replays_and_simulates_nothing(
    run_folder: tuple[Path, Path], report: tuple[Path, str], tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """With comparison/replays.npz holding these fits of this campaign, the
    report reads the traces (the same RMSE as when it simulated them) and
    simulates nothing; a fit the file does not hold (here: refitted, so its
    fingerprint changed) is simulated, and the source line says which."""
    from pneumafit.comparison import replays as replays_module
    from pneumafit.identification.staged import campaign_identity

    run, folder = run_folder
    campaign = read_campaign(folder)
    copy = tmp_path / "run"
    shutil.copytree(run / "fits", copy / "fits")
    saved = []
    for model in ("convection", "polytropic"):
        path = copy / "fits" / model / "fit.json"
        doc = json.loads(path.read_text())
        saved.append(replays_module.replay_model(campaign, doc, str(path), model))
    replays_module.save_replays(
        copy / "comparison" / replays_module.REPLAYS_FILE, saved, campaign_identity(campaign)
    )

    def no_simulation(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("the report simulated a fit whose replay was saved")

    monkeypatch.setattr(replays_module, "replay_model", no_simulation)
    console = Console(file=io.StringIO(), width=160)
    html = write_report(copy, copy / "report.html", campaign=folder, console=console)
    html = html.read_text(encoding="utf-8")
    assert "report: simulated" not in console.file.getvalue()
    measurement, first = _section_html(html, "measurement"), _section_html(report[1], "measurement")
    assert "comparison/replays.npz</code> (" in measurement
    rmse = re.compile(r"<td class=\"n\">([0-9.e+-]+&nbsp;[a-zA-Z/]+)</td>")
    assert rmse.findall(measurement) == rmse.findall(first) and rmse.findall(first)
    assert _sections(html)["residuals"] == "ok" and _sections(html)["air"] == "ok"

    # the polytropic fit changed after the comparison: simulated here, and said
    monkeypatch.undo()
    path = copy / "fits" / "polytropic" / "fit.json"
    doc = json.loads(path.read_text())
    doc["parameters"]["k"]["value"] *= 0.99
    path.write_text(json.dumps(doc))
    console = Console(file=io.StringIO(), width=160)
    html = write_report(copy, copy / "report.html", campaign=folder, console=console)
    html = html.read_text(encoding="utf-8")
    assert "simulated the campaign with the polytropic fit" in console.file.getvalue()
    assert "simulated the campaign with the convection fit" not in console.file.getvalue()
    assert "replays.npz</code> for convection; the other fits simulated here" in html


def test_the_report_reads_the_saved_residual_analysis(
    run_folder: tuple[Path, Path], report: tuple[Path, str], tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """With comparison/residuals.json (written by the comparison service from
    its replays) holding this convection fit, the report's residual section
    runs no residual analysis: the same table as when it computed one, its
    figures, and a source line naming the file. A file saved for another fit
    (its fingerprint differs) is not used, and the source line says why."""
    from pneumafit import discovery
    from pneumafit.comparison import replays as replays_module
    from pneumafit.identification.staged import campaign_identity
    from pneumafit.outputs.residual_file import RESIDUALS_FILE, save_residuals

    run, folder = run_folder
    campaign = read_campaign(folder)
    copy = tmp_path / "run"
    shutil.copytree(run / "fits", copy / "fits")
    path = copy / "fits" / "convection" / "fit.json"
    saved = [replays_module.replay_model(campaign, json.loads(path.read_text()), str(path),
                                         "convection")]  # fmt: skip
    comparison = copy / "comparison"
    replays_module.save_replays(comparison / replays_module.REPLAYS_FILE, saved,
                                campaign_identity(campaign))  # fmt: skip
    save_residuals(comparison, campaign, saved)
    assert (comparison / RESIDUALS_FILE).is_file()
    assert sorted(p.name for p in (comparison / "residuals").iterdir())  # its figures

    def no_analysis(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("the report ran a residual analysis that was saved")

    monkeypatch.setattr(discovery, "residual_analysis", no_analysis)
    quiet = Console(file=io.StringIO())
    html = write_report(copy, copy / "report.html", campaign=folder, console=quiet)
    html = html.read_text(encoding="utf-8")
    section, first = _section_html(html, "residuals"), _section_html(report[1], "residuals")
    assert _sections(html)["residuals"] == "ok"
    assert "comparison/residuals.json</code> (the convection fit's residual analysis" in section
    row = re.compile(r"<tr><td>([^<]+)</td><td>([^<]+)</td>")
    assert row.findall(section) == row.findall(first) and row.findall(first)
    assert section.count("<img") == first.count("<img") > 0

    # saved for another fit: not used; computed here, and the source says why
    monkeypatch.undo()
    doc = json.loads((comparison / RESIDUALS_FILE).read_text())
    doc["models"]["convection"]["fingerprint"] = "another fit"
    (comparison / RESIDUALS_FILE).write_text(json.dumps(doc))
    quiet = Console(file=io.StringIO())
    html = write_report(copy, copy / "report.html", campaign=folder, console=quiet)
    html = html.read_text(encoding="utf-8")
    section = _section_html(html, "residuals")
    assert "run here (comparison/residuals.json was saved for another convection fit)" in section
    assert row.findall(section) == row.findall(first)


def test_a_fit_folders_rest_figure_is_shown_under_its_verdict(
    run_folder: tuple[Path, Path], tmp_path: Path
) -> None:
    """A fit folder's rest_position.png (the fit service draws it when the
    verdict names a step test's rest position) is embedded in that fit's part
    of the parameter section, under its verdict; without one, nothing is."""
    from pneumafit.identification.quality import RestOffset
    from pneumafit.outputs.rest_figure import REST_FIGURE, rest_position_figure

    run, folder = run_folder
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    before = _section_html(write_report(copy, tmp_path / "a.html").read_text(), "parameters")
    rec = next(r for r in read_campaign(folder).recordings if r.kind == "step")
    shifted = {"y": rec.channels["y"] + 2e-3, "p_P": rec.channels["p_P"],
               "p_N": rec.channels["p_N"], "u_P": rec.channels["u_P"] - 0.12}  # fmt: skip
    stop = RestOffset(rec.file, 1.0, 1.5, 0.22, 0.222, -0.12)
    rest_position_figure(rec, shifted, None, stop, copy / "fits" / "convection" / REST_FIGURE)
    after = _section_html(write_report(copy, tmp_path / "b.html").read_text(), "parameters")
    assert after.count("data:image/png;base64") == before.count("data:image/png;base64") + 1
    verdict = after.index("<h3>convection")
    assert verdict < after.index("data:image/png;base64") < after.index("<h3>polytropic")
