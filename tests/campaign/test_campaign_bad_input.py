"""Bad input: one malformed campaign per rule, each message checked.

Every case starts from the valid campaign of ``conftest.py`` and breaks one
thing. The test asserts that a problem names the right file and key (or
channel), with the right severity, and that its text says what was expected
and what was found. The same case is run through ``check_campaign``, which
must return 1 for an error (0 for a warning only) and print the problem.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import (
    CampaignError,
    check_campaign,
    read_campaign,
    validate_campaign,
)

# --------------------------------------------------------------------------- helpers


def replace_in(folder: Path, name: str, old: str, new: str) -> None:
    """Replace the first ``old`` by ``new`` in a text file of the campaign."""
    path = folder / name
    text = path.read_text()
    if old not in text:
        raise LookupError(f"{old!r} not in {name}")  # a broken test, not a broken campaign
    path.write_text(text.replace(old, new, 1))


def toml(old: str, new: str) -> Callable[[Path], None]:
    return lambda folder: replace_in(folder, "campaign.toml", old, new)


def text(name: str, old: str, new: str) -> Callable[[Path], None]:
    return lambda folder: replace_in(folder, name, old, new)


def overwrite(name: str, content: str) -> Callable[[Path], None]:
    return lambda folder: (folder / name).write_text(content)


def delete(name: str) -> Callable[[Path], None]:
    return lambda folder: (folder / name).unlink()


def h5(edit: Callable[[h5py.File], None]) -> Callable[[Path], None]:
    def breaker(folder: Path) -> None:
        with h5py.File(folder / "charge_P_1.h5", "r+") as f:
            edit(f)

    return breaker


def _set_inf(f: h5py.File) -> None:
    data = f["channels/u_P"][()]
    data[3] = np.inf
    f["channels/u_P"][...] = data


def _shorten_T_P(f: h5py.File) -> None:
    data = f["channels/T_P"][()][:-1]
    del f["channels/T_P"]
    f["channels"].create_dataset("T_P", data=data).attrs["unit"] = "degC"


def _set_attr(path: str, name: str, value: object) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        f[path].attrs[name] = value

    return edit


def _delete(path: str) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        del f[path]

    return edit


def _del_attr(path: str, name: str) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        del f[path].attrs[name]

    return edit


def _other_suffix(folder: Path) -> None:
    (folder / "free_1.csv").rename(folder / "free_1.txt")
    replace_in(folder, "campaign.toml", 'file = "free_1.csv"', 'file = "free_1.txt"')


def _drop_all_recordings(folder: Path) -> None:
    path = folder / "campaign.toml"
    content = path.read_text()
    path.write_text(content[: content.index("[[recording]]")])


def _one_y_ref_sample(folder: Path) -> None:
    replace_in(folder, "step_1.csv", "0.00,100.0,100.0,", "0.00,100.0,,")
    replace_in(folder, "step_1.csv", "0.02,100.5,200.0,", "0.02,100.5,,")


def _add_unknown_channel(folder: Path) -> None:
    replace_in(folder, "free_1.csv", "v [m/s]", "v [m/s],aux [mA]")
    replace_in(folder, "free_1.csv", "0.0,0.10,0.0,0.0", "0.0,0.10,0.0,0.0,3")


FREE_HEADER = "time [s],y [m],u_P [V],v [m/s]"

# --------------------------------------------------------------------------- cases
# (breaker, file, key, fragments of str(problem), severity)

CASES = [
    # campaign.toml as a whole
    pytest.param(
        delete("campaign.toml"),
        "campaign.toml",
        "",
        [
            "no such file",
            "but 4 data files (charge_P_1.h5, ",
            "write a campaign.toml that names them",
        ],
        "error",
        id="missing-campaign-toml",
    ),
    pytest.param(
        overwrite("campaign.toml", ""),
        "campaign.toml",
        "",
        ["empty file (0 bytes)"],
        "error",
        id="empty-campaign-toml",
    ),
    pytest.param(
        toml('moving_mass = "17 kg"', 'moving_mass = "17 kg'),
        "campaign.toml",
        "line 12",
        ["expected valid TOML"],
        "error",
        id="toml-syntax-error",
    ),
    pytest.param(
        toml('format = "pneumatic-campaign"', 'format = "pneumatic-campain"'),
        "campaign.toml",
        "format",
        ['"pneumatic-campaign"', 'found "pneumatic-campain"'],
        "error",
        id="wrong-format",
    ),
    pytest.param(
        toml("version = 1", "version = 2"),
        "campaign.toml",
        "version",
        ["expected 1", "found 2 (a newer format"],
        "error",
        id="newer-version",
    ),
    pytest.param(
        toml('format = "pneumatic-campaign"\n', ""),
        "campaign.toml",
        "format",
        ["missing"],
        "error",
        id="missing-format",
    ),
    pytest.param(
        toml("version = 1\n", 'version = 1\noperator = "me"\n'),
        "campaign.toml",
        "operator",
        ['unknown key "operator"'],
        "warning",
        id="unknown-top-level-key",
    ),
    # rig
    pytest.param(
        toml("[rig]", "[rigg]"),
        "campaign.toml",
        "rig",
        ["a [rig] table", "no [rig]"],
        "error",
        id="missing-rig-table",
    ),
    pytest.param(
        toml('bore = "32 mm"\n', ""),
        "campaign.toml",
        "rig.bore",
        ['a length (e.g. "32 mm")', "the key is missing"],
        "error",
        id="missing-rig-key",
    ),
    pytest.param(
        toml('bore = "32 mm"', 'bore = "32 furlongz"'),
        "campaign.toml",
        "rig.bore",
        ['found "32 furlongz"', "not a known unit"],
        "error",
        id="unknown-unit",
    ),
    pytest.param(
        toml('bore = "32 mm"', 'bore = "6 bar"'),
        "campaign.toml",
        "rig.bore",
        ['expected a length (e.g. "32 mm"), found "6 bar" (a pressure)'],
        "error",
        id="wrong-unit-kind",
    ),
    pytest.param(
        toml('bore = "32 mm"', "bore = true"),
        "campaign.toml",
        "rig.bore",
        ["a length", "True"],
        "error",
        id="value-not-a-quantity",
    ),
    pytest.param(
        toml('rod = "16 mm"', 'rod = "32 mm"'),
        "campaign.toml",
        "rig.rod",
        ["smaller than the bore", '"32 mm"'],
        "error",
        id="rod-not-below-bore",
    ),
    # a bare number is SI: out of a cylinder's range it was meant in another unit
    pytest.param(
        toml('bore = "32 mm"', "bore = 32"),
        "campaign.toml",
        "rig.bore",
        ["a bore of 0.002 to 0.5 m", "found 32 (= 32 m)", 'e.g. "32 mm"'],
        "error",
        id="bare-bore-in-mm",
    ),
    pytest.param(
        toml('ambient_temperature = "20 degC"', "ambient_temperature = 20"),
        "campaign.toml",
        "rig.ambient_temperature",
        ["an ambient temperature of 223.15 to 423.15 K", 'e.g. "20 degC"'],
        "error",
        id="bare-temperature-in-degc",
    ),
    pytest.param(
        toml('supply_pressure = "7 bar"', "supply_pressure = 7"),
        "campaign.toml",
        "rig.supply_pressure",
        ["above the exhaust pressure", 'e.g. "7 bar"'],
        "error",
        id="bare-supply-in-bar",
    ),
    # with its unit out of range it is used, with a warning
    pytest.param(
        toml('bore = "32 mm"', 'bore = "1 m"'),
        "campaign.toml",
        "rig.bore",
        [
            "a bore of 0.002 to 0.5 m (pneumatic cylinders; the value is used as written)",
            '"1 m" (= 1 m)',
        ],
        "warning",
        id="bore-with-unit-out-of-range",
    ),
    pytest.param(
        toml('stroke = "500 mm"', 'stroke = "0 mm"'),
        "campaign.toml",
        "rig.stroke",
        ["a positive length", '"0 mm"'],
        "error",
        id="zero-stroke",
    ),
    pytest.param(
        toml('moving_mass = "17 kg"', 'moving_mass = "-1 kg"'),
        "campaign.toml",
        "rig.moving_mass",
        ["a positive mass", '"-1 kg"'],
        "error",
        id="negative-mass",
    ),
    pytest.param(
        toml('dead_volume_P = "20 cm^3"', "dead_volume_P = 0"),
        "campaign.toml",
        "rig.dead_volume_P",
        ["a positive volume", "found 0"],
        "error",
        id="zero-dead-volume",
    ),
    pytest.param(
        toml('supply_pressure = "7 bar"', 'supply_pressure = "1 bar"'),
        "campaign.toml",
        "rig.supply_pressure",
        ["above the exhaust pressure"],
        "error",
        id="supply-not-above-exhaust",
    ),
    pytest.param(
        toml('exhaust_pressure = "1.013 bar"', 'exhaust_pressure = "0 barg"'),
        "campaign.toml",
        "rig.exhaust_pressure",
        ["an absolute pressure", '"0 barg" (a gauge pressure)'],
        "error",
        id="gauge-exhaust-pressure",
    ),
    pytest.param(
        toml('ambient_temperature = "20 degC"', 'ambient_temperature = "-300 degC"'),
        "campaign.toml",
        "rig.ambient_temperature",
        ["above absolute zero"],
        "error",
        id="below-absolute-zero",
    ),
    pytest.param(
        toml('rod = "16 mm"', 'rod = "16 mm"\ncolour = "blue"'),
        "campaign.toml",
        "rig.colour",
        ['unknown key "colour"'],
        "warning",
        id="unknown-rig-key",
    ),
    # [[recording]] entries
    pytest.param(
        _drop_all_recordings,
        "campaign.toml",
        "recording",
        ["at least one [[recording]]"],
        "error",
        id="no-recordings",
    ),
    pytest.param(
        toml('kind = "charge"', 'kind = "charging"'),
        "campaign.toml",
        "recording[1].kind",
        ["one of charge, discharge", 'found "charging"'],
        "error",
        id="unknown-kind",
    ),
    pytest.param(
        toml('role = "validate"', 'role = "test"'),
        "campaign.toml",
        "recording[3].role",
        ["fit or validate", 'found "test"'],
        "error",
        id="unknown-role",
    ),
    pytest.param(
        toml('chamber = "P"', 'chamber = "X"'),
        "campaign.toml",
        "recording[1].chamber",
        ['"P"', '"N"', 'found "X"'],
        "error",
        id="chamber-not-P-or-N",
    ),
    pytest.param(
        toml('chamber = "N"\n', ""),
        "campaign.toml",
        "recording[2].chamber",
        ["flow test names its chamber", "missing"],
        "error",
        id="missing-chamber",
    ),
    pytest.param(
        toml('piston_position = "250 mm"\n', ""),
        "campaign.toml",
        "recording[1].piston_position",
        ["piston blocked", "missing"],
        "error",
        id="missing-piston-position",
    ),
    pytest.param(
        toml('piston_position = "250 mm"', 'piston_position = "600 mm"'),
        "campaign.toml",
        "recording[1].piston_position",
        ["between 0 and the stroke", '"600 mm"'],
        "error",
        id="piston-outside-stroke",
    ),
    pytest.param(
        toml('kp = "60 V/m"\n', ""),
        "campaign.toml",
        "recording[3].controller.kp",
        ['a proportional gain (e.g. "60 V/m")', "missing"],
        "error",
        id="controller-missing-gain",
    ),
    pytest.param(
        toml('kd = "4 V s/m"', 'kd = "4 V/m"'),
        "campaign.toml",
        "recording[3].controller.kd",
        ["a derivative gain", '"4 V/m"'],
        "error",
        id="controller-gain-wrong-unit",
    ),
    pytest.param(
        toml('law = "pd"', 'law = "pid"'),
        "campaign.toml",
        "recording[3].controller.law",
        ['"pd"', 'found "pid"'],
        "error",
        id="controller-unknown-law",
    ),
    pytest.param(
        toml('umax = "10 V"', 'umax = "0 V"'),
        "campaign.toml",
        "recording[3].controller.umax",
        ["a positive saturation"],
        "error",
        id="controller-zero-umax",
    ),
    pytest.param(
        toml('file = "free_1.csv"', 'file = "flow_N_1.csv"'),
        "campaign.toml",
        "recording[4].file",
        ["each file listed once", "recording[2]"],
        "error",
        id="duplicate-file-entry",
    ),
    pytest.param(
        toml('"Pos [mm]" = "y"', '"Position [mm]" = "y"'),
        "campaign.toml",
        'recording[3].columns."Position [mm]"',
        ["a column of step_1.csv", 'no column "Position [mm]"'],
        "error",
        id="mapping-names-absent-column",
    ),
    pytest.param(
        toml('"Pos [mm]" = "y"', '"Pos [mm]" = "position"'),
        "campaign.toml",
        'recording[3].columns."Pos [mm]"',
        ["a channel name", 'found "position"'],
        "error",
        id="mapping-onto-unknown-target",
    ),
    pytest.param(
        toml('file = "free_1.csv"', 'file = "free_1.csv"\nspeed = 3'),
        "campaign.toml",
        "recording[4].speed",
        ['unknown key "speed"'],
        "warning",
        id="unknown-recording-key",
    ),
    pytest.param(
        toml('chamber = "N"', 'chamber = "N"\npiston_position = "1 m"'),
        "campaign.toml",
        "recording[2].piston_position",
        ["between 0 and the stroke"],
        "error",
        id="flow-position-outside-stroke",
    ),
    # recording files, any format
    pytest.param(
        delete("free_1.csv"),
        "free_1.csv",
        "",
        ["recording[4]", "no such file"],
        "error",
        id="recording-listed-but-absent",
    ),
    pytest.param(
        _other_suffix, "free_1.txt", "", ['a ".txt" file'], "error", id="unsupported-suffix"
    ),
    pytest.param(
        overwrite("free_1.csv", ""),
        "free_1.csv",
        "",
        ["empty file (0 bytes)"],
        "error",
        id="empty-recording",
    ),
    # CSV
    pytest.param(
        overwrite("free_1.csv", FREE_HEADER + "\n"),
        "free_1.csv",
        "",
        ["at least 2 samples", "no data rows"],
        "error",
        id="csv-header-only",
    ),
    pytest.param(
        overwrite("free_1.csv", FREE_HEADER + "\n0.0,0.1,1.0,0.0\n"),
        "free_1.csv",
        "time",
        ["at least 2 samples", "a single sample"],
        "error",
        id="single-sample",
    ),
    pytest.param(
        text("free_1.csv", "0.2,0.11", "0.1,0.11"),
        "free_1.csv",
        "time",
        ["strictly increasing", "0.1 s then 0.1 s at line 4"],
        "error",
        id="non-monotonic-time",
    ),
    pytest.param(
        text("free_1.csv", "0.2,0.11", ",0.11"),
        "free_1.csv",
        "time",
        ["a time in every row", "empty cell at line 4"],
        "error",
        id="empty-time-cell",
    ),
    pytest.param(
        text("flow_N_1.csv", "10,1.0,2.0", "10,1.0,nan"),
        "flow_N_1.csv",
        "p_N",
        ["finite numbers", '"nan" at line 4'],
        "error",
        id="nan-sample-csv",
    ),
    pytest.param(
        text("free_1.csv", "0.2,0.11", "0.2,abc"),
        "free_1.csv",
        "y",
        ["numbers", '"abc" at line 4'],
        "error",
        id="garbage-cell",
    ),
    pytest.param(
        text("flow_N_1.csv", "30,2.0,3.0", "30,2.0,-2.0"),
        "flow_N_1.csv",
        "p_N",
        ["pressure >= 0 Pa absolute", "-2.0 barg", "line 6"],
        "error",
        id="pressure-below-zero",
    ),
    pytest.param(
        overwrite("free_1.csv", "time [s],y [m],u_P [V],y [mm]\n0,0.1,0,100\n1,0.1,1,100\n"),
        "free_1.csv",
        "y",
        ["each channel in one column", '"y [m]" and "y [mm]"'],
        "error",
        id="duplicate-csv-header",
    ),
    pytest.param(
        toml('"Pos [mm]" = "y"', '"Pos [mm]" = "y"\n"u_P" = "y"'),
        "step_1.csv",
        "y",
        ['"Pos [mm]" and "u_P [V]" both give y'],
        "error",
        id="two-columns-mapped-to-one-channel",
    ),
    pytest.param(
        text("step_1.csv", "p_P [bar],", "p_P [bar,"),
        "step_1.csv",
        "p_P [bar",
        ['a header cell "name [unit]"', 'found "p_P [bar"'],
        "error",
        id="unparseable-header-cell",
    ),
    pytest.param(
        text("free_1.csv", "y [m]", "y [bar]"),
        "free_1.csv",
        "y",
        ["a length", 'unit "bar" (a pressure)'],
        "error",
        id="channel-wrong-unit-kind",
    ),
    pytest.param(
        text("free_1.csv", "y [m]", "y [mx]"),
        "free_1.csv",
        "y",
        ['unit "mx", which is not a known unit'],
        "error",
        id="channel-unknown-unit",
    ),
    pytest.param(
        text("flow_N_1.csv", "time [ms]", "time [mm]"),
        "flow_N_1.csv",
        "time",
        ['a time (e.g. "10 ms")', "a length"],
        "error",
        id="time-unit-not-a-time",
    ),
    pytest.param(
        overwrite("free_1.csv", FREE_HEADER + "\n0,0.1,0,\n1,0.1,1,\n"),
        "free_1.csv",
        "v",
        ["at least one sample", "only empty cells"],
        "error",
        id="channel-never-sampled",
    ),
    pytest.param(
        _one_y_ref_sample,
        "step_1.csv",
        "y_ref",
        ["at least 2 samples", "a single sample"],
        "error",
        id="input-one-sample",
    ),
    pytest.param(
        text("free_1.csv", "0.3,0.13,-1.0,0.2", "0.3,0.13,-1.0,0.2,7"),
        "free_1.csv",
        "line 5",
        ["4 comma-separated fields", "found 5 fields"],
        "error",
        id="csv-ragged-row",
    ),
    pytest.param(
        _add_unknown_channel,
        "free_1.csv",
        "aux",
        ['unknown channel "aux" (kept'],
        "warning",
        id="unknown-channel",
    ),
    pytest.param(
        text("free_1.csv", "u_P [V]", "u_X [V]"),
        "free_1.csv",
        "u_P",
        ["needed by a free test", "no such channel", "u_X"],
        "error",
        id="free-lacks-command",
    ),
    pytest.param(
        text("step_1.csv", "p_N [bar]", "p_X [bar]"),
        "step_1.csv",
        "p_N",
        ["needed by a step test with a controller"],
        "error",
        id="step-lacks-p_N",
    ),
    pytest.param(
        text("flow_N_1.csv", "qm_N [g/s]", "q [g/s]"),
        "flow_N_1.csv",
        "qm_N",
        ["needed by a flow test of chamber N"],
        "error",
        id="flow-lacks-mass-flow",
    ),
    # HDF5
    pytest.param(
        h5(_delete("channels/p_P")),
        "charge_P_1.h5",
        "p_P",
        ["needed by a charge test of chamber P", "no such channel"],
        "error",
        id="charge-lacks-pressure",
    ),
    pytest.param(
        h5(_set_inf),
        "charge_P_1.h5",
        "u_P",
        ["finite numbers", "inf at sample 3"],
        "error",
        id="infinite-sample-h5",
    ),
    pytest.param(
        h5(_shorten_T_P),
        "charge_P_1.h5",
        "T_P",
        ["101 samples, like /time", "found 100 samples"],
        "error",
        id="channels-of-unequal-length",
    ),
    pytest.param(
        h5(_set_attr("/", "kind", "discharge")),
        "charge_P_1.h5",
        "kind",
        ['kind "charge", as in campaign.toml', 'found "discharge"'],
        "error",
        id="h5-kind-disagrees",
    ),
    pytest.param(
        h5(_set_attr("/", "format", "something-else")),
        "charge_P_1.h5",
        "format",
        ['"pneumatic-recording"', '"something-else"'],
        "error",
        id="h5-wrong-format",
    ),
    pytest.param(
        h5(_set_attr("/", "version", 3)),
        "charge_P_1.h5",
        "version",
        ["version = 1", "found 3"],
        "error",
        id="h5-wrong-version",
    ),
    pytest.param(
        h5(_delete("time")),
        "charge_P_1.h5",
        "/time",
        ["no /time dataset"],
        "error",
        id="h5-missing-time",
    ),
    pytest.param(
        h5(_delete("channels")),
        "charge_P_1.h5",
        "/channels",
        ["no /channels group"],
        "error",
        id="h5-missing-channels",
    ),
    pytest.param(
        h5(_del_attr("channels/p_P", "unit")),
        "charge_P_1.h5",
        "p_P",
        ['a "unit" attribute'],
        "error",
        id="h5-channel-without-unit",
    ),
    pytest.param(
        h5(_set_attr("channels/p_N", "reference", "relative")),
        "charge_P_1.h5",
        "p_N",
        ['reference = "gauge" or "absolute"', '"relative"'],
        "error",
        id="h5-unknown-reference",
    ),
    pytest.param(
        h5(_set_attr("time", "unit", "furlong")),
        "charge_P_1.h5",
        "time",
        ["a time", "a length"],
        "error",
        id="h5-time-unit-not-a-time",
    ),
    pytest.param(
        overwrite("charge_P_1.h5", "time,p_P\n0,1\n"),
        "charge_P_1.h5",
        "",
        ["an HDF5 file", "cannot open"],
        "error",
        id="not-hdf5",
    ),
]


def _matching(problems, file: str, key: str, severity: str) -> list:
    return [p for p in problems if p.file == file and p.key == key and p.severity == severity]


@pytest.mark.parametrize(("breaker", "file", "key", "fragments", "severity"), CASES)
def test_bad_input_is_reported(
    campaign_dir: Path,
    breaker: Callable[[Path], None],
    file: str,
    key: str,
    fragments: list[str],
    severity: str,
) -> None:
    breaker(campaign_dir)
    problems = validate_campaign(campaign_dir)
    candidates = _matching(problems, file, key, severity)
    listing = "\n".join(f"{p.severity}: {p}" for p in problems)
    assert candidates, f"no {severity} for {file}: {key!r}; problems:\n{listing}"
    assert any(all(f in str(p) for f in fragments) for p in candidates), (
        f"no message with {fragments}; problems:\n{listing}"
    )

    out = io.StringIO()
    status = check_campaign(campaign_dir, console=Console(file=out, width=200))
    assert status == (1 if severity == "error" else 0)
    printed = " ".join(out.getvalue().split())
    assert str(candidates[0]).split(":")[0] in printed

    if severity == "error":
        with pytest.raises(CampaignError) as info:
            read_campaign(campaign_dir)
        assert any(p in info.value.errors for p in candidates)
    else:
        campaign = read_campaign(campaign_dir)
        assert any(p in campaign.warnings for p in candidates)


def test_message_format(campaign_dir: Path) -> None:
    replace_in(campaign_dir, "campaign.toml", 'bore = "32 mm"', 'bore = "6 bar"')
    messages = [str(p) for p in validate_campaign(campaign_dir)]
    assert messages == [
        'campaign.toml: rig.bore: expected a length (e.g. "32 mm"), found "6 bar" (a pressure)'
    ]


def test_all_problems_are_collected(campaign_dir: Path) -> None:
    """Several broken things in several files are all reported at once."""
    replace_in(campaign_dir, "campaign.toml", 'stroke = "500 mm"', 'stroke = "500 bar"')
    replace_in(campaign_dir, "campaign.toml", 'role = "validate"', 'role = "x"')
    replace_in(campaign_dir, "flow_N_1.csv", "10,1.0,2.0", "10,1.0,nan")
    replace_in(campaign_dir, "free_1.csv", "0.2,0.11", "0.1,0.11")
    (campaign_dir / "charge_P_1.h5").unlink()
    where = {(p.file, p.key) for p in validate_campaign(campaign_dir) if p.is_error}
    assert where >= {
        ("campaign.toml", "rig.stroke"),
        ("campaign.toml", "recording[3].role"),
        ("flow_N_1.csv", "p_N"),
        ("free_1.csv", "time"),
        ("charge_P_1.h5", ""),
    }


def test_missing_folder(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere"
    (problem,) = validate_campaign(missing)
    assert problem.file == str(missing)
    assert "no such folder" in str(problem)
    with pytest.raises(CampaignError, match="no such folder"):
        read_campaign(missing)


def test_a_recording_given_for_its_campaign(campaign_dir: Path) -> None:
    """A recording's file where its campaign is expected: named, with what
    to give instead, not read as TOML (the message was "expected valid
    TOML" at line 1)."""
    given = campaign_dir / "step_1.csv"
    (problem,) = validate_campaign(given)
    assert problem.file == str(given)
    assert "expected a campaign folder or its campaign.toml" in str(problem)
    assert "found a .csv file" in str(problem)
    with pytest.raises(CampaignError, match=r"found a \.csv file"):
        read_campaign(given)
    # the campaign.toml itself is still a way to name the campaign
    assert read_campaign(campaign_dir / "campaign.toml").recordings


def test_an_empty_folder_is_told_only_what_is_missing(tmp_path: Path) -> None:
    (problem,) = validate_campaign(tmp_path)
    assert str(problem).endswith("found no such file")


def test_campaign_error_is_a_value_error(campaign_dir: Path) -> None:
    (campaign_dir / "step_1.csv").unlink()
    with pytest.raises(ValueError, match=r"step_1\.csv: expected the recording"):
        read_campaign(campaign_dir)


def test_suite_has_at_least_30_cases() -> None:
    assert len(CASES) >= 30
