"""One replay of a fit: every recording simulated once, compared once.

The fit's metrics (``fit.json: metrics.rmse`` and the quality verdict),
the model comparison, the report's overlays and discovery's attribution all
read the same :class:`Replay`, made here and nowhere else:

- the recordings are bound to a :class:`~pneumafit.identification.Problem`
  with every comparable channel, no averaging at rest, no flow-level means,
  no profiled offsets, at the identification's largest step: that gives the
  compared samples (every k-th sample with k dt <= ``COMPARE_SPACING``; flow tests on
  settled samples), the initial states (the fitted ones, ``initial:FILE:STATE``
  entries of the values, for ``fit`` recordings; estimated from the data, a
  line intercept over the first 50 ms, for the others, a step or free
  test's gas temperatures ahead of the probe's reading,
  :func:`_gas_ahead_of_probe`) and the parameter vector;
- each recording is simulated once on **every sample** of the recording with
  the reference solver (DP5 at a quarter of the problem's step: what the
  fit's defect-corrected predictions reproduce), so the traces serve the
  figures and attribution's rates as they are, and the compared samples are
  read off them;
- temperatures are compared through the temperature probe (two lags in
  series, :class:`~pneumafit.simulation.sensor.TemperatureProbe`): the fit's,
  or the one that best fits the replay's own temperatures, or none; the
  probe starts where the recording's reading starts, not settled on the
  simulated gas (:attr:`Problem.reading_starts`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from pneumafit.campaign.model import Campaign, Recording
from pneumafit.identification.problem import (
    COMPARABLE_CHANNELS,
    INITIAL_PREFIX,
    MAX_STEP,
    OFFSET_LIMIT,
    QUANTITIES,
    Problem,
    fit_temperature_probe,
)
from pneumafit.models.layout import CHANNELS, X_TN, X_TP
from pneumafit.models.structure import ModelStructure
from pneumafit.simulation import Experiment, PackedExperiments, Simulator
from pneumafit.simulation.sensor import TemperatureProbe

__all__ = [
    "REFERENCE_METHOD",
    "REFERENCE_REFINE",
    "Compared",
    "RecordingReplay",
    "Replay",
    "plausible_zero",
    "replay",
    "with_recorded_commands",
]

#: Reference solver of every replay: method and step refinement over the
#: problem's steps (the identification's defect correction uses the same).
REFERENCE_METHOD = "dp5"
REFERENCE_REFINE = 4


@dataclass(frozen=True)
class Compared:
    """One measured channel of a recording against the replay.

    Attributes
    ----------
    channel, quantity : str
    rows : ndarray of int
        Indices of the compared samples in the recording.
    time : ndarray
        Their times (s).
    measured : ndarray
        The measurement (SI).
    predicted : ndarray
        The replay at those samples (SI), temperatures through the probe.
    """

    channel: str
    quantity: str
    rows: NDArray[np.int64]
    time: NDArray[np.float64]
    measured: NDArray[np.float64]
    predicted: NDArray[np.float64]

    @property
    def residual(self) -> NDArray[np.float64]:
        """measured - predicted (SI)."""
        return self.measured - self.predicted


@dataclass(frozen=True)
class RecordingReplay:
    """One recording replayed.

    Attributes
    ----------
    file, kind, role : str
    time : ndarray
        Every sample time of the recording (s).
    simulated : dict of str to ndarray
        Simulated channels on every sample (SI; temperatures are the gas's,
        not through the probe). NaN after a failure.
    status : int
        The simulator's status, 0 on success.
    compared : dict of str to Compared
        The compared channels.
    """

    file: str
    kind: str
    role: str
    time: NDArray[np.float64]
    simulated: dict[str, NDArray[np.float64]]
    status: int
    compared: dict[str, Compared] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """The simulation succeeded."""
        return self.status == 0


@dataclass(frozen=True)
class Replay:
    """A fit replayed on a set of recordings (see the module doc).

    Attributes
    ----------
    structure : ModelStructure
    recordings : tuple of RecordingReplay
        In the order of the campaign.
    probe : TemperatureProbe or None
        Temperature probe through which the compared temperatures are read.
    lag_source : str
        ``"fit"`` (given), ``"estimated"`` or ``"none"``.
    """

    structure: ModelStructure
    recordings: tuple[RecordingReplay, ...]
    probe: TemperatureProbe | None
    lag_source: str

    @property
    def lag(self) -> float | None:
        """The probe's total lag (s; its one-lag equivalent), None without a probe."""
        return self.probe.total_lag if self.probe is not None else None

    def recording(self, file: str) -> RecordingReplay:
        """The replay of one recording, by file name."""
        for r in self.recordings:
            if r.file == file:
                return r
        raise KeyError(f"replay: recording {file!r} was not replayed")  # a bug, not bad input

    @property
    def residuals(self) -> dict[str, list[tuple[str, str, str, NDArray[np.int64], NDArray]]]:
        """Per role: (file, channel, quantity, sample rows, measured - predicted)."""
        out: dict[str, list[tuple[str, str, str, NDArray[np.int64], NDArray]]] = {}
        for r in self.recordings:
            items = out.setdefault(r.role, [])
            for c in r.compared.values():
                items.append((r.file, c.channel, c.quantity, c.rows, c.residual))
        return out

    def rmse(self, remove_offsets: bool = False) -> dict[str, dict[str, float]]:
        """``{role: {channel: RMSE}}`` pooled over the role's recordings (SI).

        Parameters
        ----------
        remove_offsets : bool
            Remove the mean of each recording's pressure residual first (the
            sensor offset the fit profiles per recording).
        """
        out: dict[str, dict[str, float]] = {}
        for role, items in self.residuals.items():
            sums: dict[str, list[float]] = {}
            for _file, channel, quantity, _idx, res in items:
                if not np.all(np.isfinite(res)):
                    continue
                if remove_offsets and quantity == "pressure":
                    res = res - np.mean(res)
                acc = sums.setdefault(channel, [0.0, 0.0])
                acc[0] += float(np.sum(res * res))
                acc[1] += res.size
            out[role] = {c: math.sqrt(s / n) for c, (s, n) in sums.items() if n > 0}
        return out

    def offset_free(self) -> list[tuple[str, str, NDArray[np.int64], NDArray[np.float64]]]:
        """Every role's residuals, each recording's own pressure offset removed
        (the mean of its pressure residual: what the likelihood profiles on a
        fit recording). On a held-out recording that is a constant fitted to
        the recording itself; the quality check uses
        :meth:`sensor_offset_free` instead."""
        out = []
        for items in self.residuals.values():
            for file, channel, quantity, idx, res in items:
                if quantity == "pressure":
                    good = np.isfinite(res)
                    res = res - (np.mean(res[good]) if np.any(good) else 0.0)
                out.append((file, channel, idx, res))
        return out

    def sensor_zeros(self, role: str = "fit") -> dict[str, float]:
        """One zero per pressure sensor (Pa, measured less predicted), from the
        ``role`` recordings only.

        A transducer has one zero for the campaign, so the fit recordings'
        pressure residuals of one channel, pooled sample by sample, give it
        (their mean: the least-squares constant over all of them), held
        within what a transducer's zero can be (:func:`plausible_zero`): a
        mean residual beyond :data:`~pneumafit.identification.problem.OFFSET_LIMIT`
        is the model's, as a sensor offset that large is
        (:attr:`~pneumafit.identification.problem.SensorOffset.plausible`),
        and only the limit is taken off. A channel no ``role`` recording
        compares has no entry.
        """
        sums: dict[str, list[float]] = {}
        for _file, channel, quantity, _idx, res in self.residuals.get(role, []):
            if quantity != "pressure":
                continue
            r = np.asarray(res, dtype=float)
            r = r[np.isfinite(r)]
            acc = sums.setdefault(channel, [0.0, 0.0])
            acc[0] += float(np.sum(r))
            acc[1] += r.size
        return {c: plausible_zero(s / n) for c, (s, n) in sums.items() if n > 0}

    def verdict_zeros(self, offsets: Mapping[str, float]) -> dict[str, float]:
        """The zero the fit's verdict takes off each pressure sensor (Pa):
        its offset where ``offsets`` gives one (pressure channel -> Pa, those
        that apply), else :meth:`sensor_zeros` of the fit recordings."""
        return {**self.sensor_zeros(), **{c: float(v) for c, v in offsets.items()}}

    def sensor_offset_free(
        self, zeros: Mapping[str, float] | None = None
    ) -> list[tuple[str, str, NDArray[np.int64], NDArray[np.float64]]]:
        """Every role's residuals less one zero per pressure sensor (the quality check).

        Parameters
        ----------
        zeros : mapping of str to float, optional
            Pressure channel -> the sensor's zero (Pa); default
            :meth:`sensor_zeros` of this replay's fit recordings. A sensor
            without one (no fit recording reads it: its zero is unknown) is
            taken less each recording's own mean residual, so that an
            unknowable zero is not counted as the model's error; before
            2026-12-05 it was compared as read (on the quick plan of the
            kernel's own truth, whose fit tests are all of chamber P, a
            held-out p_N then read 2057 Pa, 5.1x the noise, of which the
            level was 1865 Pa: the rig's sensor offset, 1500 Pa). That
            mean is held within a transducer's zero too
            (:func:`plausible_zero`).
        """
        zeros = self.sensor_zeros() if zeros is None else zeros
        out = []
        for items in self.residuals.values():
            for file, channel, quantity, idx, res in items:
                if quantity == "pressure":
                    if channel in zeros:
                        res = res - float(zeros[channel])
                    else:
                        good = np.isfinite(res)
                        own = float(np.mean(res[good])) if np.any(good) else 0.0
                        res = res - plausible_zero(own)
                out.append((file, channel, idx, res))
        return out


def plausible_zero(mean_residual: float) -> float:
    """A pressure sensor's zero (Pa) from a mean residual, held within
    +-:data:`~pneumafit.identification.problem.OFFSET_LIMIT`.

    A transducer's zero is at most a few times its static error band
    (7.5 kPa); a mean pressure residual beyond that is the model's, as the
    fit already says of a sensor offset that large. Taking the whole mean
    off hid it from the verdict: on a rig with a bore 1.5 % wider than
    declared (benchmarks/truths/novel.toml, sparse-long plan, seed 2;
    convection fit, --no-mcmc --seed 2) chamber N read 10.2 kPa below the
    model over the fit recordings, against the sensor's true offset of
    -0.3 kPa. The verdict took all of it off: the fit step test's four
    segments showed p_N at 4.3-6.4x the noise; held at 7.5 kPa, 5.7-10.6x.
    The held-out step test's own mean is nearer the limit than the fit
    recordings' (its p_N went from 19.2x to 13.6x).
    """
    return float(np.clip(mean_residual, -OFFSET_LIMIT, OFFSET_LIMIT))


def _gas_temperature_blocks(
    problem: Problem, have: set[tuple[int, str]]
) -> list[tuple[int, str, NDArray[np.float64], NDArray[np.float64]]]:
    """Measured gas temperatures the problem leaves out (the polytropic structure's)."""
    blocks = []
    for i, rec in enumerate(problem.recordings):
        if rec.kind == "flow":
            continue
        ref = next((o for o in problem.observations if o.index == i), None)
        if ref is None:
            continue
        for c in ("T_P", "T_N"):
            if (i, c) in have or c not in rec.channels:
                continue
            if rec.kind in ("charge", "discharge") and c[-1] != rec.chamber:
                continue
            idx = np.searchsorted(rec.time, ref.time)
            keep = rec.mask.get(c, np.ones(rec.n_samples, bool))[idx]
            if keep.sum() >= 3:
                blocks.append((i, c, ref.time[keep], rec.channels[c][idx][keep]))
    return blocks


def replay(
    recordings: Campaign | Sequence[Recording],
    structure: ModelStructure,
    values: Mapping[str, float],
    *,
    channels: Sequence[str] = COMPARABLE_CHANNELS,
    trace_channels: Sequence[str] | None = None,
    lag: float | TemperatureProbe | None = None,
    estimate_lag: bool = True,
    gas_temperatures: bool = False,
    max_step: float | None = MAX_STEP,
    lead: TemperatureProbe | None = None,
) -> Replay:
    """Simulate recordings with a fit and compare them (the module doc).

    Parameters
    ----------
    recordings : Campaign or sequence of Recording
        A campaign (every recording) or some of its recordings.
    structure : ModelStructure
    values : mapping of str to float
        Model parameters (SI) and fitted initial states (``initial:FILE:STATE``).
    channels : sequence of str
        Measured channels to compare (those the recordings have).
    trace_channels : sequence of str, optional
        Simulated channels kept on every sample (default: all the simulator's).
    lag : float or TemperatureProbe, optional
        Temperature probe, or a one-lag probe's time constant (s); default
        ``values["temperature_sensor_lag"]`` (a fit that had the temperatures
        in its likelihood, with that lag).
    estimate_lag : bool
        Without a probe, fit one (two lags in series,
        :func:`~pneumafit.identification.problem.fit_temperature_probe`) to
        the replay's temperatures (the ``fit`` recordings' if they have any),
        except for the polytropic structure.
    gas_temperatures : bool
        Also compare the measured gas temperatures that the problem leaves
        out (the polytropic structure predicts the gas at the wall
        temperature throughout; the comparison shows that error).
    max_step : float or None
        The identification's largest step (s): sets the compared samples and
        the reference solver's step (a quarter of it).
    lead : TemperatureProbe, optional
        The probe whose lags set how far a step or free test's gas starts
        ahead of its reading (:func:`_gas_ahead_of_probe`); default the
        replay's own probe. Discovery gives every model it compares the base
        model's, so that they start each held-out test from the same gas.

    Returns
    -------
    Replay
        Recordings without a comparable channel are left out.

    Raises
    ------
    PneumafitInputError, ValueError
        No recording with a comparable channel, or unusable values.
    """
    recs = list(recordings.recordings if isinstance(recordings, Campaign) else recordings)
    problem = Problem(
        recs, structure, values, channels=tuple(channels), max_step=max_step,
        initial_nuisance=False, offsets=(), rest_spacing=None, flow_average=False,
    )  # fmt: skip
    one = {k: np.array([float(v)]) for k, v in values.items()}
    vec = problem.model_vectors(one, 1)
    x0s = problem.initial_states(one, 1)

    names = tuple(CHANNELS if trace_channels is None else trace_channels)
    need = tuple(dict.fromkeys([*names, *channels, "T_P", "T_N"]))
    sim = Simulator(structure, method=REFERENCE_METHOD, channels=need)
    packed = sim.pack(
        [Experiment.from_recording(r) for r in problem.recordings],
        [s / REFERENCE_REFINE for s in problem.steps],
    )
    out, status = sim.simulate_batch(vec, packed, initial_states=x0s)
    col = {c: j for j, c in enumerate(need)}
    slices = packed.slices()

    # the compared blocks: the problem's observations (and the gas temperatures)
    blocks = [(o.index, o.channel, o.time, o.data) for o in problem.observations]
    if gas_temperatures:
        have = {(o.index, o.channel) for o in problem.observations}
        blocks += _gas_temperature_blocks(problem, have)

    def at(i: int, c: str, t: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray]:
        rec_time = problem.recordings[i].time
        rows = np.clip(np.searchsorted(rec_time, t - 1e-9), 0, rec_time.size - 1)
        return rows, out[0, slices[i], col[c]][rows]

    def start(i: int, c: str, t: NDArray[np.float64]) -> tuple[float, float] | None:
        # the reading's line (value, rate) at the block's first time: where
        # the probe was at the start of the recording (Problem.reading_starts)
        line = problem.reading_starts.get(problem.experiments[i].name, {}).get(c)
        if line is None or not math.isfinite(line[0]):
            return None
        return line[0] + line[1] * (float(t[0]) - float(problem.recordings[i].time[0])), line[1]

    lag = values.get("temperature_sensor_lag", lag)
    probe = lag if isinstance(lag, TemperatureProbe) else None
    if probe is None and isinstance(lag, int | float) and lag > 0:
        probe = TemperatureProbe(float(lag))
    lag_source = "fit" if probe is not None else "none"
    if probe is None and estimate_lag and structure.heat != "polytropic":
        temps = [
            (i, t, d, at(i, c, t)[1], start(i, c, t))
            for i, c, t, d in blocks
            if QUANTITIES[c] == "temperature" and status[0, i] == 0
        ]
        fitted = [b for b in temps if problem.recordings[b[0]].role == "fit"] or temps
        probe = fit_temperature_probe(
            [(t, d, p, s) for _i, t, d, p, s in fitted if np.all(np.isfinite(p))]
        )
        lag_source = "estimated" if probe is not None else "none"
    ahead = lead if lead is not None else probe
    moved = _gas_ahead_of_probe(problem, values, ahead, x0s) if ahead is not None else []
    if moved:
        _simulate_again(sim, vec, packed, problem, x0s, moved, out, status)

    replays = []
    for i, rec in enumerate(problem.recordings):
        compared: dict[str, Compared] = {}
        for j, c, t, d in blocks:
            if j != i:
                continue
            rows, pred = at(i, c, t)
            if QUANTITIES[c] == "temperature" and probe is not None and np.all(np.isfinite(pred)):
                pred = probe.read(pred, t, start(i, c, t))
            compared[c] = Compared(c, QUANTITIES[c], rows, t, np.asarray(d), np.asarray(pred))
        simulated = {c: out[0, slices[i], col[c]].copy() for c in names}
        replays.append(
            RecordingReplay(rec.file, rec.kind, rec.role, rec.time, simulated,
                            int(status[0, i]), compared)
        )  # fmt: skip
    return Replay(structure, tuple(replays), probe, lag_source)


def _simulate_again(
    sim: Simulator,
    vec: NDArray[np.float64],
    first: PackedExperiments,
    problem: Problem,
    x0s: NDArray[np.float64],
    moved: Sequence[int],
    out: NDArray[np.float64],
    status: NDArray[np.int64],
) -> None:
    """Simulate again only the recordings ``moved`` (indices into
    ``problem.recordings`` and the first simulation's pack ``first``), from
    their new initial states ``x0s``, and write
    their rows of ``out`` and their ``status`` in place (the others keep the
    first simulation: each recording is simulated on its own, so theirs would
    come out the same). On a campaign of many recordings with one or two
    step tests held out, this is one or two simulations instead of all."""
    idx = list(moved)
    packed = sim.pack(
        [first.experiments[i] for i in idx], [problem.steps[i] / REFERENCE_REFINE for i in idx]
    )
    slices = first.slices()
    again, again_status = sim.simulate_batch(vec, packed, initial_states=x0s[:, idx])
    for k, (i, rows) in enumerate(zip(idx, packed.slices(), strict=True)):
        out[:, slices[i]] = again[:, rows]
        status[:, i] = again_status[:, k]


def _gas_ahead_of_probe(
    problem: Problem, values: Mapping[str, float], probe: TemperatureProbe, x0s: NDArray
) -> list[int]:
    """Start each gas temperature of a step or free test that the data set
    (none fitted) ahead of its probe: gas = reading - offset + (tau_1 +
    tau_2) x rate, with the reading's line at the start
    (:attr:`Problem.reading_starts`). ``x0s`` (1, n_recordings, NX) is
    changed in place; returns the indices of the recordings whose state moved.

    Why: a probe that lags the gas by tau reads, while the gas moves at rate
    r, about tau r behind it, so the reading's intercept is the gas of tau
    seconds before. The first-order inversion of the two lags, x = y_2 +
    (tau_1 + tau_2) y_2' + tau_1 tau_2 y_2'', without the second derivative
    (which a noisy line cannot give). A held-out step test whose recording
    starts as the gas still relaxes from the run before (the rig's own laws,
    sparse plan, seed 3: reading rising at 0.9 K/s, probe 0.40 s) began 0.35 K
    below the gas, and its T_P then missed the reading by 0.19 K RMS, 3.9x
    the probe's noise; from the gas ahead, and the probe started where it
    read (:meth:`TemperatureProbe.read`), by 0.053 K, 1.1x.
    """
    lead = probe.total_lag
    if lead <= 0.0:
        return []
    moved: list[int] = []
    for i, exp in enumerate(problem.experiments):
        if exp.kind not in ("step", "free"):
            continue  # a blocked test starts from rest, its probe settled
        for c, (reading, rate) in problem.reading_starts.get(exp.name, {}).items():
            if f"{INITIAL_PREFIX}{exp.name}:{c}" in values or not math.isfinite(reading):
                continue
            if rate != 0.0 and math.isfinite(rate):
                x0s[:, i, X_TP if c == "T_P" else X_TN] = reading - probe.offset + lead * rate
                if not moved or moved[-1] != i:
                    moved.append(i)
    return moved


def with_recorded_commands(recording: Recording) -> Recording | None:
    """A closed-loop test replayed open loop: the model's valves get the
    recorded commands instead of its controller's (the position then follows
    the model's forces). None when ``recording`` declares no controller or
    does not record both commands (a closed loop may leave them out: then
    there is nothing to drive the valves with)."""
    if recording.controller is None or not {"u_P", "u_N"} <= set(recording.channels):
        return None
    return replace(recording, controller=None)
