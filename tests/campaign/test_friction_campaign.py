"""Friction tests in the campaign format: the shipped bench recordings and bad input.

The shipped campaigns (``data/measured/<seal>``) read the bench's own files
unchanged: headerless, whitespace-separated, columns by position, units and
the start-up cut declared in ``campaign.toml`` (``[read]``).
"""

from __future__ import annotations

import hashlib
import io
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import CampaignError, check_campaign, read_campaign

ROOT = Path(__file__).resolve().parents[2]
MEASURED = ROOT / "data" / "measured"
SEALS = ("NAP310", "O-ring257", "X-ring257", "Kidney_lc")
ATM = 101325.0

SMALL_TOML = """\
format = "pneumatic-campaign"
version = 1

[rig]
acting = "single"
bore = "25 mm"
exhaust_pressure = "1.01325 bar"
ambient_temperature = "20 degC"

[read]
header = false
separator = "whitespace"
start = "20 ms"
[read.channels]
time = {column = 1, unit = "ms"}
y = {column = 5, unit = "mm", reversed = true}
p_P = {column = 6, unit = "bar", gauge = true}
F = {column = 7, unit = "N"}

[[recording]]
file = "a_1bar.csv"
kind = "friction"
"""

ROWS = [
    "0.000\t3.401\t0.499\t1.041\t0.000\t0.998\t48.449",
    "10.000\t3.402\t0.499\t1.041\t0.013\t0.998\t48.434",
    "20.000\t3.401\t0.498\t1.040\t0.104\t0.996\t48.403",
    "30.000\t3.402\t0.501\t1.039\t0.213\t1.001\t48.357",
    "40.000\t3.402\t0.501\t1.041\t0.309\t1.002\t48.434",
    "50.000\t3.402\t0.502\t1.041\t0.409\t1.004\t48.418",
]


def run_check(path: Path) -> tuple[int, str]:
    out = io.StringIO()
    status = check_campaign(path, console=Console(file=out, width=200))
    return status, " ".join(out.getvalue().split())


def small_campaign(tmp_path: Path, toml: str = SMALL_TOML, rows: list[str] = ROWS) -> Path:
    folder = tmp_path / "bench"
    folder.mkdir(parents=True)
    (folder / "campaign.toml").write_text(toml)
    (folder / "a_1bar.csv").write_text("\n".join(rows) + "\n")
    return folder


@pytest.mark.parametrize("seal", SEALS)
def test_shipped_campaign_reads_and_checks(seal: str) -> None:
    folder = MEASURED / seal
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()}
    campaign = read_campaign(folder)
    assert campaign.name == seal and not campaign.warnings
    assert campaign.rig.acting == "single"
    assert campaign.rig.bore == pytest.approx(0.0257 if "257" in seal else 0.025)
    assert np.isnan(campaign.rig.stroke)  # not given: a friction test does not use it
    validate = campaign.by_role("validate")
    assert f"{seal}_7bar.csv" in [r.file for r in validate]
    assert len(campaign.by_role("fit")) == 3
    for rec in campaign.recordings:
        assert rec.kind == "friction"
        assert set(rec.channels) == {"y", "p_P", "F"}
        assert rec.time[0] >= 0.5  # [read] start = "0.5 s": the start-up left out
        set_point = float(rec.file.split("_")[-1].removesuffix("bar.csv")) * 1e5
        # gauge bar -> Pa absolute; the regulator holds the set point within ~0.2 bar
        assert np.median(rec.channels["p_P"]) - ATM == pytest.approx(set_point, abs=0.2e5)
        # y reversed: extending (y rising) the pressure helps and friction opposes
        # the motion, so the rod force is below p A; retracting it is above
        v = np.gradient(rec.channels["y"], rec.time)
        area = np.pi * campaign.rig.bore**2 / 4.0
        push = (rec.channels["p_P"] - ATM) * area
        excess = rec.channels["F"] - push
        if "Kidney" not in seal:  # its area is not the nominal one: offsets shift both ways
            assert np.median(excess[v > 3e-3]) < 0.0 < np.median(excess[v < -3e-3])
        assert np.median(excess[v < -3e-3]) > np.median(excess[v > 3e-3])
    status, text = run_check(folder)
    assert status == 0, text
    after = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()}
    assert after == before  # reading never changes a file


def test_shipped_files_are_the_bench_originals() -> None:
    shared = ROOT.parent / "shared" / "data" / "measured" / "zillen-2021-friction"
    if not shared.is_dir():
        pytest.skip("the shared copy of the bench data is not on this machine")
    for seal in SEALS:
        for path in (MEASURED / seal).glob("*.csv"):
            assert path.read_bytes() == (shared / path.name).read_bytes(), path.name


def test_small_headerless_file(tmp_path: Path) -> None:
    rec = read_campaign(small_campaign(tmp_path)).recordings[0]
    np.testing.assert_allclose(rec.time, [0.02, 0.03, 0.04, 0.05])
    np.testing.assert_allclose(rec.channels["y"], [-1.04e-4, -2.13e-4, -3.09e-4, -4.09e-4])
    np.testing.assert_allclose(rec.channels["p_P"], [0.996e5 + ATM, 1.001e5 + ATM,
                                                     1.002e5 + ATM, 1.004e5 + ATM])  # fmt: skip
    np.testing.assert_allclose(rec.channels["F"], [48.403, 48.357, 48.434, 48.418])


def _errors(folder: Path) -> list[str]:
    with pytest.raises(CampaignError) as info:
        read_campaign(folder)
    return [str(p) for p in info.value.errors]


def test_wrong_column_count(tmp_path: Path) -> None:
    rows = list(ROWS)
    rows[3] = "30.000\t3.402\t0.501\t1.039\t0.213\t1.001"
    errors = _errors(small_campaign(tmp_path, rows=rows))
    assert errors == [
        "a_1bar.csv: line 4: expected 7 whitespace-separated fields, like line 1, found 6 fields"
    ]
    short = [r.rsplit("\t", 1)[0] for r in ROWS]
    errors = _errors(small_campaign(tmp_path / "b", rows=short))
    assert errors == [
        "a_1bar.csv: line 1: expected at least 7 whitespace-separated fields "
        "(read.channels.F is column 7), found 6 fields"
    ]


def test_non_numeric_cell(tmp_path: Path) -> None:
    rows = list(ROWS)
    rows[4] = rows[4].replace("48.434", "4B.434")
    assert _errors(small_campaign(tmp_path, rows=rows)) == [
        'a_1bar.csv: F: expected numbers, found "4B.434" at line 5'
    ]


def test_missing_or_wrong_unit(tmp_path: Path) -> None:
    toml = SMALL_TOML.replace('F = {column = 7, unit = "N"}', "F = {column = 7}")
    assert _errors(small_campaign(tmp_path, toml)) == [
        'campaign.toml: read.channels.F.unit: expected a unit of force (e.g. "N"), '
        "found nothing (the key is missing)"
    ]
    toml = SMALL_TOML.replace('unit = "N"}', 'unit = "bar"}')
    (error,) = _errors(small_campaign(tmp_path / "b", toml))
    assert error.startswith("campaign.toml: read.channels.F.unit: expected a force")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("header = false\n", "", "read.channels: expected channels by column number only in"),
        ('separator = "whitespace"', 'separator = " "', "read.separator: expected one of"),
        ("column = 5,", "column = 0,", "read.channels.y.column: expected a column number"),
        ("column = 5,", "column = 1,", "read.channels.y.column: expected each column read as"),
        ('time = {column = 1, unit = "ms"}\n', "", "read.channels: expected a time column"),
        ("F = {", "Force = {", "read.channels.Force: expected a channel name"),
        ('start = "20 ms"', 'start = "1 s"', "read.start: expected a start time that leaves"),
        ('start = "20 ms"', 'start = "20 mm"', "read.start: expected a time"),
        ("gauge = true", "gauge = 1", "read.channels.p_P.gauge: expected true or false"),
        ('unit = "N"}', 'unit = "N", reversed = "yes"}', "read.channels.F.reversed: expected"),
        ('acting = "single"', 'acting = "one"', 'rig.acting: expected "double"'),
        ('bore = "25 mm"\n', "", "rig.bore: expected a length"),
    ],
)
def test_bad_read_table(tmp_path: Path, old: str, new: str, message: str) -> None:
    assert old in SMALL_TOML
    errors = _errors(small_campaign(tmp_path, SMALL_TOML.replace(old, new)))
    assert any(message in e for e in errors), errors
    assert all(e.startswith(("campaign.toml: ", "a_1bar.csv: ")) for e in errors), errors


def test_missing_channel_of_a_friction_test(tmp_path: Path) -> None:
    toml = SMALL_TOML.replace('F = {column = 7, unit = "N"}\n', "")
    assert _errors(small_campaign(tmp_path, toml)) == [
        "a_1bar.csv: F: expected a channel F (needed by a friction test), found no such "
        "channel (channels: p_P, y)"
    ]


def test_other_rig_keys_still_required_with_other_kinds(tmp_path: Path) -> None:
    toml = SMALL_TOML + '\n[[recording]]\nfile = "a_1bar.csv"\nkind = "free"\n'
    errors = _errors(small_campaign(tmp_path, toml))
    assert any("rig.stroke: expected a length" in e for e in errors), errors


def test_bad_file_exits_2_without_traceback(tmp_path: Path) -> None:
    folder = tmp_path / "NAP310"
    shutil.copytree(MEASURED / "NAP310", folder)
    path = folder / "NAP310_3bar.csv"
    lines = path.read_text().splitlines()
    lines[199] = lines[199].rsplit("\t", 1)[0] + "\tabc"
    path.write_text("\n".join(lines) + "\n")
    env_python = sys.executable
    out = subprocess.run(
        [env_python, "-m", "pneumafit", "check", str(folder)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert out.returncode == 1
    assert 'NAP310_3bar.csv: F: expected numbers, found "abc" at line 200' in " ".join(
        out.stdout.split()
    )
    assert "Traceback" not in out.stdout + out.stderr


def test_friction_campaign_round_trip(tmp_path: Path) -> None:
    from pneumafit.campaign import write_campaign

    campaign = read_campaign(small_campaign(tmp_path))
    write_campaign(tmp_path / "copy", campaign, formats="h5")
    back = read_campaign(tmp_path / "copy")
    assert back.rig.acting == "single" and np.isnan(back.rig.stroke)
    a, b = campaign.recordings[0], back.recordings[0]
    np.testing.assert_allclose(b.time, a.time, rtol=1e-12)
    for name in ("y", "p_P", "F"):
        np.testing.assert_allclose(b.channels[name], a.channels[name], rtol=1e-12)


@pytest.mark.parametrize(
    ("where", "old", "new", "message"),
    [
        ("NAP310_3bar.csv", "\t54.369\n", "\t54.369\t7\n",
         "NAP310_1bar.csv: line 12: expected 7 whitespace-separated fields, like line 1, found 8"),
        ("NAP310_3bar.csv", None, None, 'NAP310_3bar.csv: F: expected numbers, found "abc"'),
        ("campaign.toml", 'F = {column = 7, unit = "N"}', "F = {column = 7}",
         "campaign.toml: read.channels.F.unit: expected a unit of force"),
    ],
)  # fmt: skip
def test_fit_on_a_bad_file_exits_2(
    tmp_path: Path, where: str, old: str | None, new: str | None, message: str
) -> None:
    folder = tmp_path / "NAP310"
    shutil.copytree(MEASURED / "NAP310", folder)
    if where == "NAP310_3bar.csv" and old is not None:
        path = folder / "NAP310_1bar.csv"
        text = path.read_text()
        assert old in text
        path.write_text(text.replace(old, new, 1))
    elif where == "NAP310_3bar.csv":
        path = folder / where
        lines = path.read_text().splitlines()
        lines[199] = lines[199].rsplit("\t", 1)[0] + "\tabc"
        path.write_text("\n".join(lines) + "\n")
    else:
        path = folder / where
        path.write_text(path.read_text().replace(old, new))
    out = subprocess.run(
        [sys.executable, "-m", "pneumafit", "fit", str(folder), "--model", "friction",
         "--out", str(tmp_path / "fit"), "--no-mcmc"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    text = " ".join((out.stdout + out.stderr).split())
    assert out.returncode == 2, text
    assert message in text
    assert "Traceback" not in text
