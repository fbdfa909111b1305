"""Bad input over every command (issue 17, part 6).

Property-based damage (hypothesis) to parameter files, fit.json, campaigns
and option values. Each case runs the command line in-process through
:func:`pneumafit.cli.main` (the installed ``pneumafit`` entry point, so its
handlers for input errors, usage errors and bugs are the ones tested) and
asserts that it:

- exits with status 2 (``check`` says 1 for an invalid campaign, its documented
  verdict);
- prints no traceback and no "internal error";
- names the culprit (the file, key or option) in its message;
- leaves every input file unchanged and writes no output (the whole working
  folder is hashed before and after).

Example counts are small (``max_examples``) so that the suite stays under
about a minute and a half; the heavy commands (fit, compare, discover, run)
are only given input that they must refuse before any work.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import io
import json
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneumafit.campaign import read_campaign
from pneumafit.cli import main
from pneumafit.cli.fit import MAX_SAMPLED
from pneumafit.models.layout import SPECS
from pneumafit.models.structure import MODELS
from pneumafit.parameters_io import PARAMETER_FILE_KEYS

HERE = Path(__file__).resolve().parent
SETTINGS = settings(
    max_examples=30, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)  # fmt: skip


def _campaign_builder() -> Callable[[Path], Path]:
    """The hand-written valid campaign of ``tests/campaign/conftest.py``."""
    spec = importlib.util.spec_from_file_location("_campaign_conftest", HERE / "campaign" /
                                                  "conftest.py")  # fmt: skip
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.build_valid_campaign


# --------------------------------------------------------------------------- running


def run_cli(*args: object) -> tuple[int, str]:
    """Run ``pneumafit ARGS`` in this process: exit status and everything printed."""
    out, err = io.StringIO(), io.StringIO()
    argv = sys.argv
    sys.argv = ["pneumafit", *(str(a) for a in args)]
    code: int = 0
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            main()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        sys.argv = argv
    return code, out.getvalue() + err.getvalue()


def snapshot(folder: Path) -> dict[str, str]:
    """Every file and folder under ``folder``: relative path -> SHA-256 (or 'dir')."""
    tree = {}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder).as_posix()
        tree[rel] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return tree


def squeeze(text: str) -> str:
    """Text without whitespace: a message wrapped by the console still matches."""
    return "".join(text.split())


def assert_refused(
    work: Path, args: list[object], culprits: list[str], codes: tuple[int, ...] = (2,)
) -> str:
    """Run the command on the damaged input in ``work`` and check the contract."""
    before = snapshot(work)
    code, text = run_cli(*args)
    shown = f"pneumafit {' '.join(map(str, args))}\n exit {code}\n{text[-2000:]}"
    assert code in codes, shown
    assert "Traceback" not in text and "internal error" not in text, shown
    assert any(squeeze(c) in squeeze(text) for c in culprits), f"culprit {culprits}: {shown}"
    after = snapshot(work)
    assert after == before, f"inputs changed or output written: {set(after) ^ set(before)}"
    return text


# --------------------------------------------------------------------------- inputs

PARAMS = {
    "model": "convection",
    "parameters": {"bore": "32 mm", "rod": "20 mm", "supply_pressure": "7 bar", "xi": 0.4},
}


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A valid campaign, a parameter file and a fit.json of that campaign."""
    folder = tmp_path_factory.mktemp("bad-input") / "base"
    campaign = _campaign_builder()(folder / "campaign")
    camp = read_campaign(campaign)
    (folder / "params.json").write_text(json.dumps(PARAMS, indent=1))
    fit = {
        "format": "pneumafit-fit", "version": 1, "model": "convection",
        "structure": {"name": "convection", "heat": "convection",
                      "air_properties": "sutherland", "valve": "iso6358",
                      "friction": "switch", "effects": {}},
        "campaign": {"name": camp.name, "path": str(campaign), "sha256": dict(camp.sha256)},
        "parameters": {n: {"value": SPECS[n].default, "unit": SPECS[n].unit}
                       for n in ("bore", "rod", "xi", "beta")},
        "nuisance": {"initial_states": {}}, "metrics": {}, "mcmc": None,
    }  # fmt: skip
    (folder / "fit").mkdir()
    (folder / "fit" / "fit.json").write_text(json.dumps(fit, indent=1))
    return folder


@pytest.fixture
def workdir(base: Path, tmp_path: Path) -> Callable[[], Path]:
    """A fresh copy of the base inputs for each hypothesis example."""

    def fresh() -> Path:
        work = Path(tempfile.mkdtemp(dir=tmp_path))
        shutil.copytree(base, work, dirs_exist_ok=True)
        return work

    return fresh


def test_the_undamaged_inputs_are_accepted(base: Path, tmp_path: Path) -> None:
    """The baseline is valid: what the cases below break is the damage, not the base."""
    work = tmp_path / "w"
    shutil.copytree(base, work)
    code, text = run_cli("check", work / "campaign")
    assert code == 0, text
    for source in (work / "params.json", work / "fit" / "fit.json"):
        out = tmp_path / f"lin-{source.parent.name}"
        code, text = run_cli("linear", source, "--positions", "250 mm", "--out", out)
        assert code == 0, text
        assert (out / "linear.json").exists()


# --------------------------------------------------------------------------- parameter files

NAMES = sorted(PARAMS["parameters"])
#: units no parameter has (amount of substance, luminous intensity) or none at all
ALIEN_UNITS = ("mol", "cd", "mol/s", "kg^7", "bogus_unit", "")
WRONG_TYPES = st.one_of(
    st.none(), st.booleans(), st.lists(st.integers(0, 9), max_size=2),
    st.fixed_dictionaries({"unit": st.sampled_from(["m", "bar"])}),
    st.fixed_dictionaries({"value": st.one_of(st.none(), st.lists(st.integers(), max_size=1))}),
)  # fmt: skip
WORD = st.text(alphabet="abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12)


@st.composite
def damaged_parameter_file(draw: st.DrawFn) -> tuple[str, list[str]]:
    """JSON text of a broken parameter file and the words naming the culprit."""
    doc = json.loads(json.dumps(PARAMS))
    kind = draw(st.sampled_from(["type", "unit", "range", "name", "key", "model", "friction",
                                 "effects", "truncated", "not-object"]))  # fmt: skip
    name = draw(st.sampled_from(NAMES))
    culprit = [f"parameters.{name}"]
    if kind == "type":
        doc["parameters"][name] = draw(WRONG_TYPES)
    elif kind == "unit":
        magnitude = draw(st.floats(0.01, 100.0))
        unit = draw(st.sampled_from(ALIEN_UNITS))
        if SPECS[name].unit == "" and unit == "":
            unit = "mol"
        doc["parameters"][name] = f"{magnitude:g} {unit}" if unit else f"{magnitude:g} x y"
    elif kind == "range":
        doc["parameters"][name] = draw(
            st.sampled_from([float("nan"), float("inf"), -float("inf"), -1e30, 1e30])
        )
    elif kind == "name":
        unknown = draw(WORD.filter(lambda w: w not in SPECS))
        doc["parameters"][unknown] = 1.0
        culprit = [unknown]
    elif kind == "key":
        unknown = draw(WORD.filter(lambda w: w not in PARAMETER_FILE_KEYS and w != "format"))
        doc[unknown] = draw(st.one_of(st.just({"xi": 0.5}), st.integers(), st.text(max_size=4)))
        culprit = [unknown]
    elif kind == "model":
        doc["model"] = draw(st.one_of(WORD.filter(lambda w: w not in MODELS), st.integers()))
        culprit = ["model"]
    elif kind == "friction":
        doc["friction"] = draw(st.one_of(WORD.filter(lambda w: w not in ("switch", "lugre")),
                                         st.integers(), st.none()))  # fmt: skip
        culprit = ["friction"]
    elif kind == "effects":
        doc["effects"] = draw(st.one_of(
            st.dictionaries(WORD.filter(lambda w: w not in ("seal_friction",)), st.just(1),
                            min_size=1, max_size=1),
            st.lists(st.integers(), max_size=2), st.integers(1, 9),
        ))  # fmt: skip
        culprit = ["effects"]
    if kind == "truncated":
        text = json.dumps(doc, indent=1)
        text = text[: draw(st.integers(0, len(text) - 1))]
        return text, ["params.json"]
    if kind == "not-object":
        return json.dumps(draw(st.one_of(st.lists(st.integers(), max_size=2), st.integers(),
                                         st.text(max_size=5)))), ["params.json"]  # fmt: skip
    return json.dumps(doc), culprit


def _parameter_command(which: str, params: Path, out: Path) -> list[object]:
    return {
        "simulate": ["simulate", params, "--kind", "charge", "--duration", "0.05 s",
                     "--out", out / "sim.h5"],
        "linear": ["linear", params, "--positions", "250 mm", "--out", out / "linear"],
        "design": ["design", params, "--positions", "250 mm", "--out", out / "design"],
        "export": ["export", params, "--format", "json", "--out", out / "export.json"],
        "closed-loop": ["closed-loop", params, "--out", out / "closed_loop"],
    }[which]  # fmt: skip


@SETTINGS
@given(
    damage=damaged_parameter_file(),
    command=st.sampled_from(["simulate", "linear", "design", "export", "closed-loop"]),
)
def test_damaged_parameter_files_are_refused(
    workdir: Callable[[], Path], damage: tuple[str, list[str]], command: str
) -> None:
    work = workdir()
    text, culprits = damage
    (work / "params.json").write_text(text)
    said = assert_refused(work, _parameter_command(command, work / "params.json", work),
                          culprits)  # fmt: skip
    assert "params.json" in said  # and always the file


# --------------------------------------------------------------------------- fit.json

#: The keys of fit.json each command needs, so that removing one is bad input:
#: compare replays a fit written before ``structure`` existed, and linear and
#: export read a fit.json as a parameter file (its campaign does not matter).
NEEDED = {
    "discover": ("format", "model", "parameters", "campaign", "structure"),
    "compare": ("format", "model", "parameters", "campaign"),
    "linear": ("format", "model", "parameters"),
    "export": ("format", "model", "parameters"),
}
#: The keys whose wrong type (a number, a list, a string) each command must refuse.
TYPED = {
    **NEEDED,
    "compare": (*NEEDED["compare"], "structure"),
    "linear": ("format", "model", "parameters", "structure"),
    "export": ("format", "model", "parameters", "structure"),
}


@st.composite
def damaged_fit(draw: st.DrawFn, text: str, command: str) -> tuple[str, list[str]]:
    """A broken fit.json (from its text) and the words naming the culprit."""
    doc = json.loads(text)
    kind = draw(st.sampled_from(["truncated", "removed", "type", "parameter"]))
    if kind == "truncated":
        return text[: draw(st.integers(0, len(text) - 1))], ["fit.json"]
    if kind == "removed":
        key = draw(st.sampled_from(NEEDED[command]))
        del doc[key]
    elif kind == "type":
        key = draw(st.sampled_from(TYPED[command]))
        wrong = [st.integers(), st.lists(st.integers(), max_size=2)]
        if key != "format" or command in ("discover", "compare"):  # any format string is
            wrong.append(st.just("x"))  # accepted by a parameter-file reader
        if key in NEEDED[command]:
            wrong.append(st.none())
        doc[key] = draw(st.one_of(*wrong))
    else:
        key = draw(st.sampled_from(["xi", "beta", "bore"]))
        doc["parameters"][key] = draw(st.one_of(WRONG_TYPES, st.just({"value": "abc"}),
                                                st.just({"value": float("nan")})))  # fmt: skip
    return json.dumps(doc), [key, "fit.json"]


@SETTINGS
@given(data=st.data(), command=st.sampled_from(["discover", "compare", "linear", "export"]))
def test_damaged_fit_json_is_refused(
    workdir: Callable[[], Path], data: st.DataObject, command: str
) -> None:
    work = workdir()
    fit = work / "fit" / "fit.json"
    text, culprits = data.draw(damaged_fit(fit.read_text(), command))
    fit.write_text(text)
    if command in ("linear", "export") and '"format"' not in text and text.count("{") > 1:
        # without its format key the file is read as a hand-written parameter file,
        # whose unknown top-level keys (campaign, nuisance, ...) are the culprits
        culprits = [*culprits, "campaign", "nuisance", "metrics", "mcmc", "version"]
    args = {
        "discover": ["discover", work / "campaign", "--fit", fit, "--out", work / "disc"],
        "compare": ["compare", work / "campaign", "--fits", fit, "--out", work / "cmp",
                    "--no-mcmc"],
        "linear": _parameter_command("linear", fit, work),
        "export": _parameter_command("export", fit, work),
    }[command]  # fmt: skip
    assert_refused(work, args, culprits)


@pytest.mark.parametrize("content", ["{trunc", '{"format": "pneumafit-fit", "model": 3}'])
def test_report_refuses_a_damaged_fit_json(base: Path, tmp_path: Path, content: str) -> None:
    work = tmp_path / "w"
    shutil.copytree(base, work)
    fits = work / "run" / "fits" / "convection"
    fits.mkdir(parents=True)
    (fits / "fit.json").write_text(content)
    assert_refused(work, ["report", work / "run", "--campaign", work / "campaign"], ["fit.json"])


# --------------------------------------------------------------------------- campaigns

#: (old, new, culprit) edits of campaign.toml that make it invalid
TOML_EDITS = [
    ('format = "pneumatic-campaign"\n', "", "format"),
    ("version = 1\n", "", "version"),
    ('bore = "32 mm"\n', "", "bore"),
    ('supply_pressure = "7 bar"\n', "", "supply_pressure"),
    ('file = "flow_N_1.csv"\n', "", "file"),
    ('kind = "flow"\n', "", "kind"),
    ('bore = "32 mm"', 'bore = "32 bar"', "bore"),
    ('supply_pressure = "7 bar"', 'supply_pressure = "7 kg"', "supply_pressure"),
    ('piston_position = "250 mm"', 'piston_position = "250 s"', "piston_position"),
    ('moving_mass = "17 kg"', 'moving_mass = "17 mol"', "moving_mass"),
    ('bore = "32 mm"', "bore = true", "bore"),
    ('bore = "32 mm"', "bore = [32, 33]", "bore"),
    ('stroke = "500 mm"', "stroke = { a = 1 }", "stroke"),
    ("version = 1", 'version = "one"', "version"),
    ('kind = "flow"', "kind = 3", "kind"),
    ('kind = "flow"', 'kind = "floww"', "kind"),
    ('chamber = "N"', 'chamber = "Q"', "chamber"),
    ('"Pos [mm]" = "y"', '"Pos [mm]" = "zz"', "zz"),
    ('"Pos [mm]" = "y"', '"Nowhere [mm]" = "y"', "Nowhere"),
    ('kp = "60 V/m"', 'kp = "60 V/s"', "kp"),
]
#: (file, old, new, culprit) edits of a recording that make it invalid
CSV_EDITS = [
    ("free_1.csv", "y [m]", "y [kg]", "free_1.csv"),
    ("free_1.csv", "0.2,0.11,1.0,0.1", "0.2,abc,1.0,0.1", "free_1.csv"),
    ("flow_N_1.csv", "time [ms]", "time [bar]", "flow_N_1.csv"),
    ("step_1.csv", "0.03,102.0,", "0.01,102.0,", "step_1.csv"),
]
RECORDINGS = ("flow_N_1.csv", "step_1.csv", "free_1.csv", "charge_P_1.h5")


@st.composite
def damaged_campaign(draw: st.DrawFn) -> Callable[[Path], list[str]]:
    """A function breaking the campaign in a folder; it returns the culprit words."""
    kind = draw(st.sampled_from(["toml", "toml", "missing", "truncated", "toml-syntax", "csv"]))
    if kind == "csv":
        name, before, after, where = draw(st.sampled_from(CSV_EDITS))

        def edit_csv(folder: Path) -> list[str]:
            path = folder / name
            text = path.read_text()
            assert before in text, before  # a broken test, not a broken campaign
            path.write_text(text.replace(before, after, 1))
            return [where]

        return edit_csv
    if kind == "toml":
        old, new, culprit = draw(st.sampled_from(TOML_EDITS))

        def edit(folder: Path) -> list[str]:
            path = folder / "campaign.toml"
            text = path.read_text()
            assert old in text, old  # a broken test, not a broken campaign
            path.write_text(text.replace(old, new, 1))
            return [culprit]

        return edit
    file = draw(st.sampled_from(RECORDINGS))
    if kind == "missing":

        def remove(folder: Path) -> list[str]:
            (folder / file).unlink()
            return [file]

        return remove
    if kind == "toml-syntax":
        cut = draw(st.sampled_from(['name = "test-rig"', "[[recording]]", 'kind = "charge"']))

        def syntax(folder: Path) -> list[str]:
            path = folder / "campaign.toml"
            path.write_text(path.read_text().replace(cut, cut[:-2], 1))
            return ["campaign.toml"]

        return syntax
    fraction = draw(st.floats(0.0, 0.99))

    def truncate(folder: Path) -> list[str]:
        path = folder / file
        data = path.read_bytes()
        if file.endswith(".csv"):  # cut inside the header line (the data rows may be optional)
            end = data.index(b"\n", data.index(b"time"))
            path.write_bytes(data[: data.index(b"time") + int(fraction * 0.9 * (end - 3))])
        else:
            path.write_bytes(data[: int(fraction * len(data))])
        return [file]

    return truncate


@SETTINGS
@given(damage=damaged_campaign(), command=st.sampled_from(["check", "fit", "compare",
                                                          "discover", "run"]))  # fmt: skip
def test_damaged_campaigns_are_refused(
    workdir: Callable[[], Path], damage: Callable[[Path], list[str]], command: str
) -> None:
    work = workdir()
    culprits = damage(work / "campaign")
    camp, fit = work / "campaign", work / "fit" / "fit.json"
    args: list[object] = {
        "check": ["check", camp],
        "fit": ["fit", camp, "--no-mcmc", "--out", work / "fitted"],
        "compare": ["compare", camp, "--fits", fit, "--no-mcmc", "--out", work / "cmp"],
        "discover": ["discover", camp, "--fit", fit, "--out", work / "disc"],
        "run": ["run", camp, "--no-mcmc", "--out", work / "run"],
    }[command]  # fmt: skip
    # check's exit status is its verdict: 1 for an invalid campaign (documented)
    assert_refused(work, args, culprits, codes=(1, 2) if command == "check" else (2,))


# --------------------------------------------------------------------------- options

NEGATIVE = st.integers(-1000, 0)


@st.composite
def bad_option(draw: st.DrawFn) -> tuple[str, list[str], str]:
    """(command, options, culprit) for a bad option value of a heavy command."""
    command = draw(st.sampled_from(["fit", "compare", "discover"]))
    choices = {
        "fit": ["--steps", "--walkers", "--seed", "--model", "--valve", "--friction",
                "--seal-friction", "--noise-pooling", "--inputs", "--segments",
                "--offset-scope"],
        "compare": ["--steps", "--walkers", "--seed"],
        "discover": ["--rounds", "--per-round", "--seed"],
    }[command]  # fmt: skip
    option = draw(st.sampled_from(choices))
    if option in ("--model", "--valve", "--friction", "--seal-friction", "--noise-pooling",
                  "--inputs", "--segments", "--offset-scope"):  # fmt: skip
        known = (*MODELS, "iso6358", "map", "auto", "switch", "lugre", "on", "off", "recording",
                 "sensor", "hold", "linear")  # fmt: skip
        value = draw(WORD.filter(lambda w: w not in known))
    elif option == "--walkers":
        value = str(draw(st.integers(-1000, 2 * MAX_SAMPLED - 1)))
    elif option == "--seed":
        value = str(draw(st.integers(-1000, -1)))
    else:
        value = str(draw(st.one_of(NEGATIVE, st.sampled_from(["x", "1.5", "", "1e3"]))))
    return command, [f"{option}={value}"], option


@SETTINGS
@given(case=bad_option())
def test_bad_options_of_the_heavy_commands_are_refused(
    workdir: Callable[[], Path], case: tuple[str, list[str], str]
) -> None:
    work = workdir()
    command, options, culprit = case
    camp, fit = work / "campaign", work / "fit" / "fit.json"
    args: list[object] = {
        "fit": ["fit", camp, "--no-mcmc", "--out", work / "fitted"],
        "compare": ["compare", camp, "--fits", fit, "--no-mcmc", "--out", work / "cmp"],
        "discover": ["discover", camp, "--fit", fit, "--out", work / "disc"],
    }[command]  # fmt: skip
    assert_refused(work, [*args, *options], [culprit])


BAD_POSITIONS = st.one_of(
    st.sampled_from(["", "1,,2 mm", "nan", "inf", "600 mm", "-1", "250 bar", "250 mol", "x mm",
                     "[1] mm", "0.1;0.2", "1e9"]),
    st.text(alphabet="abcxyz[]{};#!", min_size=1, max_size=8),
    st.floats(0.51, 1e6).map(lambda v: f"{v:g}"),
    st.floats(501.0, 1e6).map(lambda v: f"{v:g} mm"),
)  # fmt: skip


@SETTINGS
@given(positions=BAD_POSITIONS, command=st.sampled_from(["linear", "design", "export"]))
def test_bad_positions_are_refused(
    workdir: Callable[[], Path], positions: str, command: str
) -> None:
    work = workdir()
    args = _parameter_command(command, work / "params.json", work)
    args = [a for a in args if a not in ("--positions", "250 mm")]
    assert_refused(work, [*args, f"--positions={positions}"], ["--positions"])


@st.composite
def bad_light_option(draw: st.DrawFn) -> tuple[str, list[str], str]:
    """(command, options, culprit) for the commands that read a parameter file."""
    command, option, value = draw(st.sampled_from([
        ("simulate", "--kind", draw(WORD.filter(lambda w: w not in ("charge", "discharge",
                                                                    "step")))),
        ("simulate", "--chamber", draw(WORD.filter(lambda w: w not in ("P", "N")))),
        ("simulate", "--duration", draw(st.sampled_from(["x s", "3 bar", "1 mol", "s"]))),
        ("simulate", "--position", draw(st.sampled_from(["250 bar", "abc", "1 mol"]))),
        ("simulate", "--amplitude", draw(st.sampled_from(["10 m", "ten V"]))),
        ("design", "--order", str(draw(st.integers(-10, 10).filter(lambda n: n not in (4, 6))))),
        ("design", "--w0", draw(st.sampled_from(["0", "-1", "nan", "x"]))),
        ("export", "--format", draw(WORD.filter(lambda w: w not in ("json", "yaml", "c", "mat",
                                                                    "csv", "fmu")))),
        ("export", "--order", str(draw(st.integers(-10, 10).filter(lambda n: n not in (4, 6))))),
        ("export", "--placement", draw(WORD.filter(lambda w: w not in ("dominant", "itae")))),
        ("export", "--w0", draw(st.sampled_from(["0", "-1", "nan"]))),
        ("closed-loop", "--steps", draw(st.sampled_from(["x mm", "3,,4 mm", "30 bar", ""]))),
        ("closed-loop", "--placement", draw(WORD.filter(lambda w: w not in ("dominant",
                                                                            "itae")))),
        ("closed-loop", "--w0", draw(st.sampled_from(["0", "-1", "nan"]))),
    ]))  # fmt: skip
    return command, [f"{option}={value}"], option


@SETTINGS
@given(case=bad_light_option())
def test_bad_options_of_the_parameter_commands_are_refused(
    workdir: Callable[[], Path], case: tuple[str, list[str], str]
) -> None:
    work = workdir()
    command, options, culprit = case
    args = _parameter_command(command, work / "params.json", work)
    if command == "simulate":  # the option under test replaces the base's
        name = options[0].split("=", 1)[0]
        if name in args:
            i = args.index(name)
            del args[i : i + 2]
    assert_refused(work, [*args, *options], [culprit])


# --------------------------------------------------------------------------- known bugs

KNOWN = [
    pytest.param(["simulate", "P", "--kind", "charge", "--rate", "0 Hz", "--out", "O/s.h5"],
                 "--rate", id="simulate-rate-zero"),
    pytest.param(["simulate", "P", "--kind", "charge", "--duration", "-1 s", "--out", "O/s.h5"],
                 "--duration", id="simulate-negative-duration"),
    pytest.param(["simulate", "P", "--kind", "charge", "--open-time", "nan s", "--out",
                  "O/s.h5"], "--open-time", id="simulate-nan-open-time"),
    pytest.param(["linear", "P", "--positions", "250 mm", "--lambda-e=-5", "--out", "O/lin"],
                 "--lambda-e", id="linear-negative-lambda"),
    pytest.param(["closed-loop", "P", "--position", "9 m", "--out", "O/cl"], "--position",
                 id="closed-loop-position-outside"),
    pytest.param(["closed-loop", "P", "--umax", "-3 V", "--out", "O/cl"], "--umax",
                 id="closed-loop-negative-umax"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "culprit"), KNOWN)
def test_known_bad_options(base: Path, tmp_path: Path, args: list[str], culprit: str) -> None:
    work = tmp_path / "w"
    shutil.copytree(base, work)
    params = work / "params.json"
    resolved: list[object] = [
        params if a == "P" else (work / a[2:] if a.startswith("O/") else a) for a in args
    ]
    assert_refused(work, resolved, [culprit])


@pytest.mark.parametrize(
    ("args", "culprit"),
    [
        (["rig", "--out", "O/rig", "--protocol", "bogus"], "protocol"),
        (["rig", "--out", "O/rig", "--truth", "bogus"], "--truth"),
        (["rig", "--out", "O/rig", "--truth", "O/campaign/campaign.toml"], "campaign.toml"),
        (["rig", "--out", "O/rig", "--effect", "warp=1"], "warp"),
        (["rig", "--out", "O/rig", "--seed=-1"], "--seed"),
        (["fit-many", "O/campaign", "--out", "O/many", "--workers", "0"], "--workers"),
        (["fit-many", "O/campaign", "--out", "O/many", "--model", "bogus"], "--model"),
        (["fit-many", "O/campaign", "--out", "O/many", "--steps=-2"], "--steps"),
    ],
)
def test_bad_options_of_rig_and_fit_many(
    base: Path, tmp_path: Path, args: list[str], culprit: str
) -> None:
    """The other commands: refused before a rig is simulated or a cluster started."""
    work = tmp_path / "w"
    shutil.copytree(base, work)
    resolved: list[object] = [work / a[2:] if a.startswith("O/") else a for a in args]
    assert_refused(work, resolved, [culprit])


@pytest.mark.parametrize(
    ("file", "content", "culprit"),
    [
        ("params.json", '{"parameters": {"x[i]y[/i]": 1}}', "x[i]y[/i]"),
        ("[bold]params.json", "{", "[bold]params.json"),
    ],
)
def test_culprits_with_square_brackets_are_shown_as_written(
    base: Path, tmp_path: Path, file: str, content: str, culprit: str
) -> None:
    work = tmp_path / "w"
    shutil.copytree(base, work)
    (work / file).write_text(content)
    assert_refused(work, _parameter_command("linear", work / file, work), [culprit])
