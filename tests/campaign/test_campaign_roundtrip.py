"""Write -> read round trips, property-based and on the example campaign.

Tolerance: the CSV text itself is exact (floats are written with ``repr``,
which reads back to the same float64), and HDF5 stores float64. What remains
is the unit conversion SI -> file unit -> SI: one or two multiplications by a
pint factor, plus, for gauge pressures and degC/degF, one subtraction and
addition of an offset (exhaust pressure, 273.15 K). Each step is exact to half
an ulp of the larger operand, so values agree to a few ulp of the channel's
magnitude: ``rtol = 1e-12`` and ``atol = 1e-12 * max|x|`` leave a margin of
about 1000 over the worst case, while any real mistake (a wrong factor, a
missing offset) is off by far more. Below the smallest normal float
(2.2e-308) a product keeps an absolute precision only, and a subnormal value
written in kN (5e-324 N -> 0 kN) reads back as 0: ``atol`` has a floor of
1e-300 in SI units, far below any measured quantity (hypothesis drew such a
channel once; it is not a unit error).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pneumafit.campaign import (
    CHANNELS,
    Campaign,
    PDController,
    PneumafitInputError,
    Recording,
    Rig,
    parse_unit,
    read_campaign,
    read_recording,
    write_campaign,
    write_recording_csv,
    write_recording_h5,
)

RTOL = 1e-12
#: Absolute floor (SI) of the comparison: subnormal values (see the module doc).
TINY = 1e-300
EXHAUST = 101_325.0

UNITS = {
    "voltage": ["V", "mV"],
    "pressure": ["Pa", "bar", "kPa", "psi", "MPa", "barg", "psig", "kPag", "bar (gauge)"],
    "temperature": ["K", "degC", "degF"],
    "length": ["m", "mm", "cm", "inch"],
    "velocity": ["m/s", "mm/s"],
    "mass flow": ["kg/s", "g/s"],
    "force": ["N", "kN", "lbf"],
}
RANGES = {
    "voltage": (-10.0, 10.0),
    "pressure": (2e4, 1e6),  # absolute, above 0 even as gauge (exhaust 1 atm)
    "temperature": (250.0, 400.0),
    "length": (0.0, 0.5),
    "velocity": (-2.0, 2.0),
    "mass flow": (-0.01, 0.01),
    "force": (-500.0, 500.0),
    None: (-5.0, 5.0),  # the unknown channel "aux", in mA
}
OPTIONAL = sorted(set(CHANNELS) - {"y", "u_P", "u_N"})


def assert_close(actual: np.ndarray, expected: np.ndarray) -> None:
    scale = float(np.max(np.abs(expected))) if expected.size else 0.0
    np.testing.assert_allclose(actual, expected, rtol=RTOL, atol=RTOL * scale + TINY)


@st.composite
def recordings(draw: st.DrawFn) -> tuple[Recording, dict[str, str], bool]:
    """A free-motion recording with random channels, units and sampling."""
    n = draw(st.integers(2, 30))
    if draw(st.booleans()):  # uneven time steps
        steps = draw(arrays(np.float64, n - 1, elements=st.floats(1e-4, 0.1)))
    else:
        steps = np.full(n - 1, draw(st.sampled_from([1e-3, 0.01, 0.1])))
    time = draw(st.floats(0.0, 100.0)) + np.concatenate([[0.0], np.cumsum(steps)])
    names = ["y", "u_P", "u_N", *sorted(draw(st.sets(st.sampled_from(OPTIONAL))))]
    if draw(st.booleans()):
        names.append("aux")
    uneven_sampling = draw(st.booleans())
    channels, masks, units = {}, {}, {"time": draw(st.sampled_from(["s", "ms"]))}
    for name in names:
        kind = CHANNELS.get(name)
        low, high = RANGES[kind]
        channels[name] = draw(arrays(np.float64, n, elements=st.floats(low, high)))
        units[name] = draw(st.sampled_from(UNITS[kind])) if kind else "mA"
        mask = np.ones(n, bool)
        if uneven_sampling:
            mask = draw(arrays(np.bool_, n))
            two = draw(st.lists(st.integers(0, n - 1), min_size=2, max_size=2, unique=True))
            mask[two] = True  # inputs need at least 2 real samples
        masks[name] = mask
    recording = Recording.from_arrays(
        time, channels, kind="free", mask=masks, units=units, description="random"
    )
    return recording, units, uneven_sampling


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=recordings(), fmt=st.sampled_from(["csv", "h5"]))
def test_recording_round_trip(tmp_path: Path, data, fmt: str) -> None:
    recording, units, _ = data
    path = tmp_path / f"rec.{fmt}"
    if fmt == "csv":
        write_recording_csv(path, recording, units, exhaust_pressure=EXHAUST)
    else:
        write_recording_h5(path, recording, units, exhaust_pressure=EXHAUST)
    back = read_recording(path, kind="free", exhaust_pressure=EXHAUST)

    assert_close(back.time, recording.time)
    assert set(back.channels) == set(recording.channels)
    assert back.unknown_channels == (["aux"] if "aux" in recording.channels else [])
    for name, values in recording.channels.items():
        if fmt == "csv":  # CSV keeps "not sampled" as empty cells
            mask = recording.mask[name]
            np.testing.assert_array_equal(back.mask[name], mask)
            # Where not sampled, the reader interpolates at the times it read; the
            # times moved by a few ulp (s -> ms -> s), which an interpolated value
            # amplifies by t/dt. So compare with the interpolation at those times.
            values = np.interp(back.time, back.time[mask], values[mask])
        else:  # HDF5 has every channel at every time
            assert back.mask[name].all()
        assert_close(back.channels[name], values)
        written, read = parse_unit(units[name]), parse_unit(back.units[name])
        assert (written.unit, written.gauge) == (read.unit, read.gauge)
    assert back.description == "random"


@pytest.mark.parametrize("fmt", [None, "csv", "h5"])
def test_campaign_round_trip(campaign_dir: Path, tmp_path: Path, fmt: str | None) -> None:
    original = read_campaign(campaign_dir)
    write_campaign(tmp_path / "copy", original, formats=fmt)
    copy = read_campaign(tmp_path / "copy")

    assert copy.name == original.name
    assert copy.description == original.description
    assert copy.rig == original.rig  # exact: rig values are written as repr(float) m, Pa, K
    assert copy.warnings == []
    for a, b in zip(original.recordings, copy.recordings, strict=True):
        assert (b.kind, b.role, b.chamber, b.piston_position, b.controller) == (
            a.kind,
            a.role,
            a.chamber,
            a.piston_position,
            a.controller,
        )
        assert b.description == a.description
        assert b.derived == a.derived
        assert_close(b.time, a.time)
        assert set(b.channels) == set(a.channels)
        for name in a.channels:
            assert_close(b.channels[name], a.channels[name])
            if b.file.endswith(".csv") and a.file.endswith(".csv"):
                np.testing.assert_array_equal(b.mask[name], a.mask[name])


def test_same_format_copy_keeps_units_and_columns(campaign_dir: Path, tmp_path: Path) -> None:
    write_campaign(tmp_path / "copy", read_campaign(campaign_dir))
    step = (tmp_path / "copy" / "step_1.csv").read_text().splitlines()
    assert step[:2] == ["# step test under PD control", "# second comment line"]
    assert step[2] == "time [s],Pos [mm],y_ref [mm],p_P [bar],p_N [bar],u_P [V]"
    assert step[4].split(",")[2] == ""  # y_ref not sampled on that row
    assert (tmp_path / "copy" / "flow_N_1.csv").read_text().splitlines()[1] == (
        "time [ms],u_N [V],p_N [barg],qm_N [g/s]"
    )


def test_virtual_rig_campaign(tmp_path: Path) -> None:
    """A campaign built in memory (e.g. by a virtual rig) is written and read back."""
    rig = Rig(
        bore=0.032,
        rod=0.016,
        stroke=0.5,
        dead_volume_P=2e-5,
        dead_volume_N=2e-5,
        moving_mass=17.0,
        supply_pressure=7e5,
        exhaust_pressure=1.013e5,
        ambient_temperature=293.15,
        wall_temperature=293.15,
        characteristic_length=0.032,
        mounting_angle=0.1,
        external_force=-5.0,
    )
    t = np.linspace(0.0, 1.0, 11)
    charge = Recording.from_arrays(
        t,
        {"u_P": np.full(11, 5.0), "p_P": 1e5 + 1e5 * t},
        kind="charge",
        chamber="P",
        piston_position=0.25,
        units={"p_P": "barg"},
    )
    step = Recording.from_arrays(
        t,
        {"y": 0.1 * t, "y_ref": np.full(11, 0.1), "p_P": 3e5 + 0 * t, "p_N": 3e5 + 0 * t},
        kind="step",
        role="validate",
        file="step.csv",
        controller=PDController(kp=60.0, kd=4.0, u0=0.0, umax=10.0),
    )
    campaign = Campaign(None, "virtual", "made in memory", rig, [charge, step])
    write_campaign(tmp_path / "virtual", campaign)
    back = read_campaign(tmp_path / "virtual")
    assert back.rig == rig
    assert [r.file for r in back.recordings] == ["charge_1.h5", "step.csv"]
    assert back.recording("step.csv").controller == step.controller
    assert back.by_role("validate") == [back.recording("step.csv")]
    assert back.by_kind("charge")[0].units["p_P"] == "bar (gauge)"
    assert_close(back.recordings[0].channels["p_P"], charge.channels["p_P"])
    assert set(back.sha256) == {"campaign.toml", "charge_1.h5", "step.csv"}


def test_from_arrays_rejects_bad_arrays() -> None:
    t = np.array([0.0, 1.0, 2.0])
    with pytest.raises(PneumafitInputError, match="strictly increasing"):
        Recording.from_arrays([0.0, 0.0, 1.0], {"y": t}, kind="free")
    with pytest.raises(PneumafitInputError, match="y: expected 3 samples"):
        Recording.from_arrays(t, {"y": [1.0, 2.0]}, kind="free")
    with pytest.raises(PneumafitInputError, match="kind"):
        Recording.from_arrays(t, {"y": t}, kind="walk")
    with pytest.raises(PneumafitInputError, match="finite"):
        Recording.from_arrays(t, {"y": [0.0, np.nan, 1.0]}, kind="free")


def test_from_arrays_interpolates_unsampled_values() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    rec = Recording.from_arrays(
        t, {"y": [1.0, 99.0, 3.0, 99.0]}, kind="free", mask={"y": [True, False, True, False]}
    )
    np.testing.assert_array_equal(rec.channels["y"], [1.0, 2.0, 3.0, 3.0])
    assert rec.n_samples == 4 and rec.duration == 3.0 and rec.sample_rate == 1.0


def test_writer_rejects_wrong_unit_kind(tmp_path: Path) -> None:
    rec = Recording.from_arrays([0.0, 1.0], {"y": [0.0, 0.1]}, kind="free")
    with pytest.raises(PneumafitInputError, match="units\\['y'\\]"):
        write_recording_csv(tmp_path / "r.csv", rec, {"y": "bar"})
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_gauge_writing_needs_exhaust(tmp_path: Path) -> None:
    rec = Recording.from_arrays([0.0, 1.0], {"p_P": [2e5, 3e5]}, kind="free")
    with pytest.raises(PneumafitInputError, match="exhaust"):
        write_recording_h5(tmp_path / "r.h5", rec, {"p_P": "barg"})
    assert list(tmp_path.iterdir()) == []  # the temporary file is removed
