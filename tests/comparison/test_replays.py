"""The fits' replays saved by the comparison for the report (comparison/replays.npz).

Kind: file-format and control-flow checks (round trip, bad files named, the
report reading the saved traces instead of simulating); the traces
themselves are the simulator's, checked elsewhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneumafit.comparison.replays import (
    REPLAYS_FILE,
    ModelReplay,
    load_replays,
    replay_fingerprint,
    save_replays,
)
from pneumafit.errors import PneumafitInputError

CAMPAIGN = {"name": "c", "path": "/data/c", "sha256": {"campaign.toml": "ab", "a.h5": "cd"}}


def _replays() -> list[ModelReplay]:
    rng = np.random.default_rng(0)
    a = ModelReplay(
        model="convection", structure="convection", sensor_lag=0.4, fingerprint="f1",
        channels={f"r{k}.h5": {"p_P": rng.normal(size=50), "y": rng.normal(size=50)}
                  for k in range(12)},
        air={"r0.h5": (1e-4, 9e-5, 12.5)}, failed={"bad.h5": "step size too small"},
    )  # fmt: skip
    b = ModelReplay(model="polytropic", structure="polytropic", fingerprint="f2")
    return [a, b]


def test_round_trip_keeps_every_trace_and_field(tmp_path: Path) -> None:
    path = save_replays(tmp_path / REPLAYS_FILE, _replays(), CAMPAIGN)
    assert sorted(p.name for p in tmp_path.iterdir()) == [REPLAYS_FILE]  # no temp file left
    back, identity = load_replays(path)
    assert identity == CAMPAIGN
    for want, got in zip(_replays(), back, strict=True):
        assert (got.model, got.structure, got.sensor_lag, got.fingerprint) == (
            want.model, want.structure, want.sensor_lag, want.fingerprint
        )  # fmt: skip
        assert got.failed == want.failed and got.air == want.air
        assert got.channels.keys() == want.channels.keys()  # r1 and r10 kept apart
        for f, chans in want.channels.items():
            assert got.channels[f].keys() == chans.keys()
            for name, values in chans.items():
                np.testing.assert_array_equal(got.channels[f][name], values)


@pytest.mark.parametrize("content", [b"not a zip file", b""])
def test_an_unreadable_file_is_an_input_error_naming_it(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / REPLAYS_FILE
    path.write_bytes(content)
    with pytest.raises(PneumafitInputError, match=REPLAYS_FILE):
        load_replays(path)


def test_another_format_is_named(tmp_path: Path) -> None:
    path = tmp_path / REPLAYS_FILE
    np.savez(path, meta=np.array('{"format": "other"}'))
    with pytest.raises(PneumafitInputError, match="expected 'pneumafit-replays', found 'other'"):
        load_replays(path)


def test_the_fingerprint_follows_what_the_replay_depends_on() -> None:
    doc = {
        "structure": {"heat": "convection"},
        "parameters": {"xi": {"value": 0.4, "std": 0.01}, "beta": {"value": 0.27}},
        "nuisance": {"initial_states": {"a.h5": {"p_P": 1e5}}},
        "metrics": {"temperature_sensor_lag": 0.4, "rmse": {"fit": 1.0}},
    }
    same = {
        **doc,
        "metrics": {"temperature_sensor_lag": 0.4, "rmse": {"fit": 2.0}},
        "parameters": {"beta": {"value": 0.27}, "xi": {"value": 0.4, "std": 0.5}},
    }
    assert replay_fingerprint(same) == replay_fingerprint(doc)  # uncertainty, metrics: no
    moved = {**doc, "parameters": {"xi": {"value": 0.41}, "beta": {"value": 0.27}}}
    lagged = {**doc, "metrics": {"temperature_sensor_lag": 0.5}}
    started = {**doc, "nuisance": {"initial_states": {"a.h5": {"p_P": 1.1e5}}}}
    probe = {"time_constant": 0.4, "second_time_constant": 0.0, "offset": 0.0}
    # the probe and the one lag it replaces are one and the same replay
    same_probe = {**doc, "metrics": {"temperature_probe": probe}}
    assert replay_fingerprint(same_probe) == replay_fingerprint(doc)
    offset = {**doc, "metrics": {"temperature_probe": {**probe, "offset": 0.2}}}
    for other in (moved, lagged, started, offset):
        assert replay_fingerprint(other) != replay_fingerprint(doc)
