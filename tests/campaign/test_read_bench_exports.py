"""Bench exports with decimal commas, a preamble of their own and a Windows encoding.

Many benches (LabVIEW and spreadsheet exports in most of Europe) write
"3,25" for 3.25, with ";" or tabs between the fields, start the file with
lines of their own (the program, the date, the operator) that are not
"#"-comments, and write them in cp1252. ``[read]``'s ``decimal = ","``,
``skip_lines = N`` and ``encoding`` read such files unchanged
(docs/campaign-format.md, "`[read]`"). Each test compares
with the same numbers written the format's own way: the values must be
equal to the bit, not close, since both go through the same float parser.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from pneumafit.campaign import CampaignError, check_campaign, inspect_campaign, read_campaign

#: The bench's own preamble: three lines that are not "#"-comments.
PREAMBLE = "Prüfstand 2;Zylinder DNC-32-500\nDatum;04.12.2026\nBediener;M. Muster\n"

READ_TABLE = """\
[recording.read]
separator = ";"
decimal = ","
skip_lines = 3
"""


def european(csv_text: str) -> str:
    """The same table with ";" between fields and "," as the decimal mark."""
    out = []
    for line in csv_text.splitlines():
        if line.startswith("#"):
            out.append(line)
        else:
            out.append(line.replace(",", ";").replace(".", ","))
    return PREAMBLE + "\n".join(out) + "\n"


def with_read_table(folder: Path, table: str = READ_TABLE) -> None:
    """Give the step recording (the third entry) its own read table."""
    toml = folder / "campaign.toml"
    text = toml.read_text()
    anchor = '[recording.columns]\n"Pos [mm]" = "y"\n'
    assert anchor in text
    toml.write_text(text.replace(anchor, anchor + table))


def errors_of(folder: Path) -> list[str]:
    with pytest.raises(CampaignError) as info:
        read_campaign(folder)
    return [str(p) for p in info.value.errors]


def test_a_european_export_reads_as_the_same_numbers(campaign_dir: Path) -> None:
    reference = read_campaign(campaign_dir).recording("step_1.csv")
    path = campaign_dir / "step_1.csv"
    path.write_text(european(path.read_text()))
    with_read_table(campaign_dir)
    step = read_campaign(campaign_dir).recording("step_1.csv")
    np.testing.assert_array_equal(step.time, reference.time)
    assert set(step.channels) == set(reference.channels)
    for name, values in reference.channels.items():
        np.testing.assert_array_equal(step.channels[name], values, err_msg=name)
        np.testing.assert_array_equal(step.mask[name], reference.mask[name], err_msg=name)
    # the "#" lines after the skipped block are still the description
    assert step.description == reference.description
    status, out = _check(campaign_dir)
    assert status == 0, out


def test_a_headerless_whitespace_export_with_decimal_commas(tmp_path: Path) -> None:
    """The measured seals' layout (columns by position), written with commas."""
    from test_friction_campaign import ROWS, SMALL_TOML, small_campaign  # this folder, on sys.path

    reference = read_campaign(small_campaign(tmp_path / "a")).recordings[0]
    rows = [row.replace(".", ",") for row in ROWS]
    toml = SMALL_TOML.replace('separator = "whitespace"', 'separator = "whitespace"\ndecimal = ","')
    comma = read_campaign(small_campaign(tmp_path / "b", toml, rows)).recordings[0]
    np.testing.assert_array_equal(comma.time, reference.time)
    for name, values in reference.channels.items():
        np.testing.assert_array_equal(comma.channels[name], values, err_msg=name)


def _check(folder: Path) -> tuple[int, str]:
    out = io.StringIO()
    status = check_campaign(folder, console=Console(file=out, width=200))
    return status, " ".join(out.getvalue().split())


def test_a_point_in_a_decimal_comma_file_is_refused(campaign_dir: Path) -> None:
    """ "1.234" may be 1234 grouped in thousands or 1.234: not guessed."""
    path = campaign_dir / "step_1.csv"
    path.write_text(european(path.read_text()).replace("100,5", "100.5"))
    with_read_table(campaign_dir)
    assert errors_of(campaign_dir) == [
        'step_1.csv: y: expected numbers with a decimal comma (decimal = ","), no points, '
        'found "100.5" at line 9'
    ]


@pytest.mark.parametrize(
    ("table", "message"),
    [
        (
            'separator = ","\ndecimal = ","\n',
            "campaign.toml: recording[3].read.decimal: expected another separator with a "
            'decimal comma (e.g. separator = ";"), found decimal = "," and separator ","',
        ),
        (
            'decimal = "comma"\n',
            'campaign.toml: recording[3].read.decimal: expected "." or "," (the decimal '
            'mark), found "comma"',
        ),
        (
            "skip_lines = -1\n",
            "campaign.toml: recording[3].read.skip_lines: expected a number of lines (an "
            "integer, 0 or more) to leave out at the top of the file, found -1",
        ),
        (
            "skip_lines = 40\n",
            "step_1.csv: recording[3].read.skip_lines: expected more than the 40 lines that "
            "read.skip_lines leaves out, found 8 lines",
        ),
    ],
)
def test_bad_decimal_and_skip_lines(campaign_dir: Path, table: str, message: str) -> None:
    with_read_table(campaign_dir, "[recording.read]\n" + table)
    assert message in errors_of(campaign_dir)


def test_the_csv_keys_on_an_hdf5_recording_are_ignored_with_a_warning(
    campaign_dir: Path,
) -> None:
    toml = campaign_dir / "campaign.toml"
    text = toml.read_text()
    anchor = 'piston_position = "250 mm"\n'
    toml.write_text(
        text.replace(anchor, anchor + '[recording.read]\nseparator = ";"\ndecimal = ","\n')
    )
    campaign = read_campaign(campaign_dir)
    charge = campaign.recording("charge_P_1.h5")
    assert charge.channels["p_P"][0] == pytest.approx(1.013e5)
    _, out = _check(campaign_dir)
    assert "recording[1].read.decimal" in out and "CSV files only" in out, out


def test_a_decimal_comma_without_the_key_is_named(tmp_path: Path) -> None:
    from test_friction_campaign import ROWS, small_campaign  # this folder, on sys.path

    rows = [row.replace(".", ",") for row in ROWS]
    errors = errors_of(small_campaign(tmp_path, rows=rows))
    assert errors[0] == (
        'a_1bar.csv: time: expected numbers (a decimal comma as in this cell needs decimal = "," '
        'in [read]), found "0,000" at line 1 (and 5 more)'
    ), errors


@pytest.mark.parametrize(
    ("time_cells", "hint"),
    [
        # every comma cell reads both ways: both named, neither chosen
        (["1,000", "1,010", "1,020"],
         '"1,000" is a decimal comma, which needs decimal = "," in [read], or thousands '
         "grouping, which is not read: export the numbers without it"),
        # a later cell that no grouping writes settles it
        (["1,000", "1,010", "1,02"], 'a decimal comma as in "1,02" needs decimal = "," in [read]'),
        # grouped beyond doubt (a point after the groups): not a decimal comma
        (["1,000.0", "1,010.0", "1,020.0"],
         "thousands separators are not read: export the numbers without grouping"),
    ],
)  # fmt: skip
def test_thousands_grouping_is_not_taken_for_a_decimal_comma(
    tmp_path: Path, time_cells: list[str], hint: str
) -> None:
    """A time column in milliseconds grouped in thousands ("1,010" ms) must
    not be pointed to decimal = ",", which would read it 1000 times too
    small; the hint says what the commas show, from every unreadable cell."""
    from test_friction_campaign import ROWS, small_campaign  # this folder, on sys.path

    rows = [row.replace("\t", ";") for row in ROWS[:3]]
    rows = [cell + row[row.index(";") :] for cell, row in zip(time_cells, rows, strict=True)]
    folder = small_campaign(tmp_path, rows=rows)
    toml = folder / "campaign.toml"
    toml.write_text(toml.read_text().replace('"whitespace"', '";"'))
    errors = errors_of(folder)
    assert errors[0].startswith(f"a_1bar.csv: time: expected numbers ({hint}), found "), errors


@pytest.mark.parametrize("where", ["every line", "data rows only", "two in a row"])
def test_empty_separators_of_a_logger_export_read_as_nothing(
    campaign_dir: Path, where: str
) -> None:
    """A separator at the end of every line (on the header too, or not) and an
    unnamed column with no value in any row (two separators in a row) hold
    nothing: the recording reads to the same floats as without them. A
    column with a header and no unit is still an error (the next test's
    file), and an extra field in one row only is one too."""
    step = campaign_dir / "step_1.csv"
    lines = step.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    if where == "every line":
        lines[first:] = [line + "," for line in lines[first:]]
    elif where == "data rows only":
        lines[first + 1 :] = [line + "," for line in lines[first + 1 :]]
    else:
        lines[first:] = [line.replace(",", ",,", 1) for line in lines[first:]]
    original = read_campaign(campaign_dir)
    step.write_text("\n".join(lines) + "\n")
    read = read_campaign(campaign_dir)
    a, b = original.recordings[2], read.recordings[2]
    assert a.file == b.file == "step_1.csv"
    assert np.array_equal(a.time, b.time)
    assert set(a.channels) == set(b.channels)
    for name in a.channels:
        assert np.array_equal(a.channels[name], b.channels[name]), name
    lines[first + 5] += ",1.5"
    step.write_text("\n".join(lines) + "\n")
    assert any("fields, like the header" in e for e in errors_of(campaign_dir))


def test_a_windows_export_reads_with_its_encoding(campaign_dir: Path) -> None:
    """cp1252 (Windows in Western Europe): "ü" and "°" are single bytes that
    are not UTF-8. Without the key the error names the line and suggests it;
    with it the file reads as the same numbers."""
    reference = read_campaign(campaign_dir).recording("step_1.csv")
    path = campaign_dir / "step_1.csv"
    path.write_bytes(european(path.read_text()).encode("cp1252"))
    toml = campaign_dir / "campaign.toml"
    original = toml.read_text()
    with_read_table(campaign_dir)
    (error,) = errors_of(campaign_dir)
    assert error == (
        'step_1.csv: line 1, byte 2: expected UTF-8 text (a Windows export? encoding = "cp1252" '
        "in [read] reads it), found a byte that is not UTF-8 (0xfc)"
    )
    toml.write_text(original)
    with_read_table(campaign_dir, READ_TABLE + 'encoding = "cp1252"\n')
    step = read_campaign(campaign_dir).recording("step_1.csv")
    for name, values in reference.channels.items():
        np.testing.assert_array_equal(step.channels[name], values, err_msg=name)


def test_an_unknown_encoding_is_named(campaign_dir: Path) -> None:
    with_read_table(campaign_dir, '[recording.read]\nencoding = "klingon"\n')
    assert errors_of(campaign_dir) == [
        'campaign.toml: recording[3].read.encoding: expected a text encoding (e.g. "utf-8", '
        'the default, "cp1252" or "latin-1"), found "klingon"'
    ]


def test_a_header_in_another_notation_is_skipped_and_read_by_position(tmp_path: Path) -> None:
    """Names on one row and units on the next ("Zeit;Weg;Druck A" / "ms;mm;bar"),
    which the header row's "name [unit]" cannot take: ``header = false``,
    ``skip_lines`` over both rows, the columns by position."""
    from test_friction_campaign import ROWS, SMALL_TOML, small_campaign  # this folder, on sys.path

    reference = read_campaign(small_campaign(tmp_path / "a")).recordings[0]
    head = ["Zeit;U1;U2;U3;Weg;Druck;Kraft", "ms;V;V;V;mm;bar;N"]
    rows = head + [row.replace("\t", ";").replace(".", ",") for row in ROWS]
    toml = SMALL_TOML.replace(
        'separator = "whitespace"', 'separator = ";"\ndecimal = ","\nskip_lines = 2'
    )
    exported = read_campaign(small_campaign(tmp_path / "b", toml, rows)).recordings[0]
    np.testing.assert_array_equal(exported.time, reference.time)
    for name, values in reference.channels.items():
        np.testing.assert_array_equal(exported.channels[name], values, err_msg=name)


def test_a_utf16_export_is_named_and_read_with_its_encoding(campaign_dir: Path) -> None:
    """Some Windows tools write UTF-16 with a byte-order mark: the hint names
    it (not cp1252, which would decode it into text with NUL characters)."""
    reference = read_campaign(campaign_dir).recording("step_1.csv")
    path = campaign_dir / "step_1.csv"
    path.write_bytes(path.read_text().encode("utf-16"))
    (error,) = errors_of(campaign_dir)
    assert error == (
        'step_1.csv: line 1, byte 0: expected UTF-8 text (a UTF-16 file: encoding = "utf-16" '
        "in [read] reads it), found a byte that is not UTF-8 (0xff)"
    )
    with_read_table(campaign_dir, '[recording.read]\nencoding = "utf-16"\n')
    step = read_campaign(campaign_dir).recording("step_1.csv")
    for name, values in reference.channels.items():
        np.testing.assert_array_equal(step.channels[name], values, err_msg=name)


# --- max_rate: a fast bench's recordings thinned where they are read

DEMO = Path(__file__).resolve().parents[2] / "data" / "demo"


def test_max_rate_keeps_every_kth_sample_of_csv_and_hdf5(tmp_path: Path) -> None:
    """``max_rate = "250 Hz"`` in the campaign's [read] keeps one sample in 4
    of the demo's 1-kHz recordings (CSV and HDF5), the file's own samples
    bit for bit, and leaves its 100-Hz flow tests whole. Can fail: any
    averaging, an off-by-one start or a thinned slower file."""
    import shutil

    folder = tmp_path / "demo"
    shutil.copytree(DEMO, folder)
    toml = folder / "campaign.toml"
    toml.write_text(
        toml.read_text().replace("[[recording]]", '[read]\nmax_rate = "250 Hz"\n\n[[recording]]', 1)
    )
    whole, thinned = read_campaign(DEMO), read_campaign(folder)
    kinds = set()
    for a, b in zip(whole.recordings, thinned.recordings, strict=True):
        rate = 1.0 / float(np.median(np.diff(a.time)))
        k = 4 if rate > 250.0 else 1
        kinds.add((a.file.rsplit(".", 1)[1], k))
        assert np.array_equal(a.time[::k], b.time), a.file
        assert set(a.channels) == set(b.channels)
        for name in a.channels:
            assert np.array_equal(a.channels[name][::k], b.channels[name]), (a.file, name)
            assert np.array_equal(a.mask[name][::k], b.mask[name]), (a.file, name)
    assert kinds == {("h5", 1), ("h5", 4), ("csv", 4)}, kinds


def test_max_rate_keeps_a_sparse_channel_where_its_block_has_a_sample(campaign_dir: Path) -> None:
    """The conftest's step test (100 Hz) has y_ref on rows 0, 2 and 4 only.
    Thinned to one row in 3 (max_rate 34 Hz), row 0's block (rows 0-2) and
    row 3's (rows 3-4) each hold a real y_ref, so both kept rows are
    sampled, row 3 at its value interpolated between rows 2 and 4."""
    with_read_table(campaign_dir, '[recording.read]\nmax_rate = "34 Hz"\n')
    step = read_campaign(campaign_dir).recordings[2]
    assert step.file == "step_1.csv"
    assert np.allclose(step.time, [0.0, 0.03])
    assert step.mask["y_ref"].tolist() == [True, True]
    assert np.allclose(step.channels["y_ref"], [0.1, 0.2])
    assert np.allclose(step.channels["y"], [0.1, 0.102])


def test_a_fast_recording_is_named_with_max_rate(campaign_dir: Path) -> None:
    """A step test at 10 kHz without max_rate is a warning of check naming
    its rate and the key; with ``max_rate = "1 kHz"`` it is read one sample
    in 10, without the warning."""
    step = campaign_dir / "step_1.csv"
    lines = step.read_text().splitlines()
    out = []
    for line in lines:
        if line[:1].isdigit():
            t, rest = line.split(",", 1)
            line = f"{float(t) / 100.0!r},{rest}"
        out.append(line)
    # 10 kHz over 50 rows, so that one in 10 leaves 5
    body = [line for line in out if line[:1].isdigit()]
    head = [line for line in out if not line[:1].isdigit()]
    rows = [f"{i * 1e-4!r}," + body[i % len(body)].split(",", 1)[1] for i in range(50)]
    step.write_text("\n".join(head + rows) + "\n")
    report = inspect_campaign(campaign_dir)
    fast = [p for p in report.problems if p.file == "step_1.csv" and p.key == "time"]
    assert len(fast) == 1 and not fast[0].is_error, report.problems
    assert fast[0].found.startswith(
        '1e+04 Hz, 10 times a 1-kHz recording\'s cost; max_rate = "1 kHz"'
    )
    with_read_table(campaign_dir, '[recording.read]\nmax_rate = "1 kHz"\n')
    report = inspect_campaign(campaign_dir)
    assert not [p for p in report.problems if p.file == "step_1.csv" and p.key == "time"]
    assert report.campaign is not None
    assert report.campaign.recordings[2].time.size == 5


@pytest.mark.parametrize(
    ("value", "expected"),
    [('"0 Hz"', 'a positive frequency (e.g. "1 kHz")'), ('"1 kg"', 'a frequency (e.g. "1 kHz")')],
)
def test_a_bad_max_rate_is_named(campaign_dir: Path, value: str, expected: str) -> None:
    with_read_table(campaign_dir, f"[recording.read]\nmax_rate = {value}\n")
    errors = errors_of(campaign_dir)
    assert any("read.max_rate" in e and f"expected {expected}" in e for e in errors), errors
