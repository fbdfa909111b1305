"""Test protocols of the virtual rig: which tests a campaign holds, and how each is run.

A :class:`Protocol` is a named list of tests. Three kinds of test exist, one
per campaign kind they produce:

- :class:`FlowTest` (``flow``): a staircase of commands at several held
  chamber pressures, read by a lagging, noisy flow meter;
- :class:`BlockedTest` (``charge`` / ``discharge``): piston blocked, the
  valve opened for an opening time, then back to its rest command while the
  chamber relaxes thermally for seconds;
- :class:`StepTest` (``step``): position steps under a declared ``pd``
  controller, recorded after a pre-roll that lets the rig settle.

:func:`demo_protocol` makes the committed demo campaign (``data/demo``),
:func:`quick_protocol` a small campaign for tests (a few seconds of
simulation). All values are SI (m, Pa absolute, V, s, Hz).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import PurePosixPath
from types import MappingProxyType

from pneumafit.errors import PneumafitInputError

__all__ = [
    "PROTOCOLS",
    "BlockedTest",
    "FlowTest",
    "Protocol",
    "StepTest",
    "demo_protocol",
    "get_protocol",
    "quick_protocol",
    "sparse_long_protocol",
    "sparse_protocol",
]

#: Rate (Hz) at which flow tests are computed before the flow meter's lag;
#: a flow test's recording rate must divide it.
FLOW_COMPUTE_RATE = 1000.0

_ROLES = ("fit", "validate")
_SUFFIXES = (".h5", ".hdf5", ".csv")


def _frozen(mapping: Mapping[str, str] | None) -> Mapping[str, str]:
    return MappingProxyType(dict(mapping or {}))


@dataclass(frozen=True, kw_only=True)
class _Test:
    """Fields shared by every test.

    Parameters
    ----------
    file : str
        File name in the campaign folder; ``.h5`` or ``.csv``.
    role : {"fit", "validate"}
        ``validate`` recordings are held out from fitting.
    sample_rate : float
        Recording rate (Hz).
    units : mapping of str to str
        Channel (or ``"time"``) -> unit written in the file, e.g.
        ``{"y": "mm", "p_P": "bar"}``; SI where absent.
    columns : mapping of str to str
        Channel -> the file's own column name (CSV only), e.g.
        ``{"y": "Position"}``; mapped back in ``[recording.columns]``.
    description : str
        Free text for the recording; a default one is made from the settings.
    """

    file: str
    role: str = "fit"
    sample_rate: float = 1000.0
    units: Mapping[str, str] = field(default_factory=dict)
    columns: Mapping[str, str] = field(default_factory=dict)
    description: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "units", _frozen(self.units))
        object.__setattr__(self, "columns", _frozen(self.columns))
        where = f"test {self.file!r}"
        if PurePosixPath(self.file).suffix.lower() not in _SUFFIXES or "/" in self.file:
            raise PneumafitInputError(
                f"{where}: file: expected a plain .h5 or .csv file name, found {self.file!r}"
            )
        if self.role not in _ROLES:
            raise PneumafitInputError(
                f"{where}: role: expected one of {_ROLES}, found {self.role!r}"
            )
        _positive(where, "sample_rate", self.sample_rate)
        if self.columns and not self.file.lower().endswith(".csv"):
            raise PneumafitInputError(
                f"{where}: columns: expected only on a .csv file, found {self.file!r}"
            )


def _positive(where: str, name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise PneumafitInputError(f"{where}: {name}: expected a finite value > 0, found {value!r}")


def _chamber(where: str, chamber: str) -> None:
    if chamber not in ("P", "N"):
        raise PneumafitInputError(f"{where}: chamber: expected 'P' or 'N', found {chamber!r}")


@dataclass(frozen=True, kw_only=True)
class FlowTest(_Test):
    """Static flow test of one valve: command staircase at held pressures.

    For each held pressure in turn, every command is applied for ``dwell``
    seconds while a regulator holds the chamber (or line) at that pressure
    and a flow meter (first-order lag and noise, :class:`SensorModel`)
    measures the mass flow into it. The true flow is the valve's static
    characteristic q_m(P, u).

    Parameters
    ----------
    chamber : {"P", "N"}
        Valve (and pressure sensor) under test.
    commands : tuple of float
        Command levels (V), negative ones open the exhaust path.
    pressures : tuple of float
        Held pressures (Pa absolute), each strictly between exhaust and supply.
    dwell : float
        Time at each level (s), several flow-meter time constants.
    """

    chamber: str
    commands: tuple[float, ...]
    pressures: tuple[float, ...]
    dwell: float = 0.5
    sample_rate: float = 100.0

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"test {self.file!r}"
        _chamber(where, self.chamber)
        _positive(where, "dwell", self.dwell)
        if not self.commands or not self.pressures:
            raise PneumafitInputError(f"{where}: expected at least one command and one pressure")
        for p in self.pressures:
            _positive(where, "pressures", p)
        ratio = FLOW_COMPUTE_RATE / self.sample_rate
        if abs(ratio - round(ratio)) > 1e-9 or round(self.dwell * self.sample_rate) < 1:
            raise PneumafitInputError(
                f"{where}: sample_rate: expected a divisor of {FLOW_COMPUTE_RATE:g} Hz with at "
                f"least one sample per dwell, found {self.sample_rate:g} Hz"
            )

    @property
    def kind(self) -> str:
        return "flow"

    @property
    def duration(self) -> float:
        """Length of the staircase (s)."""
        return len(self.commands) * len(self.pressures) * self.dwell


@dataclass(frozen=True, kw_only=True)
class BlockedTest(_Test):
    """Charge or discharge of one chamber, piston blocked.

    The chamber starts at rest at the wall temperature, at exhaust pressure
    (charge) or supply pressure (discharge). The command sits at
    ``rest_command`` for ``delay`` s, is set to +``amplitude`` (charge) or
    -``amplitude`` (discharge) for ``opening_time`` s, then returns to
    ``rest_command`` for the rest of the test: the pressure relaxes as the
    gas returns to the wall temperature (plus the valve's centre leakage).

    Parameters
    ----------
    kind : {"charge", "discharge"}
    chamber : {"P", "N"}
    position : float
        Blocked piston position (m).
    amplitude : float
        Command magnitude (V), > 0.
    opening_time : float
        Time the valve is open (s).
    duration : float
        Length of the recording (s).
    delay : float
        Time before opening (s).
    rest_command : float
        Command before and after the opening (V), near the valve centre.
    temperature : bool
        Record the slow gas-temperature sensor ``T_<chamber>``.
    """

    kind: str
    chamber: str
    position: float
    amplitude: float
    opening_time: float
    duration: float = 6.0
    delay: float = 0.2
    rest_command: float = 0.0
    temperature: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"test {self.file!r}"
        if self.kind not in ("charge", "discharge"):
            raise PneumafitInputError(
                f"{where}: kind: expected 'charge' or 'discharge', found {self.kind!r}"
            )
        _chamber(where, self.chamber)
        for name in ("amplitude", "opening_time", "duration"):
            _positive(where, name, getattr(self, name))
        if not (math.isfinite(self.position) and self.position >= 0.0):
            raise PneumafitInputError(
                f"{where}: position: expected a value >= 0 m, found {self.position!r}"
            )
        if not (self.delay >= 0.0 and self.delay + self.opening_time < self.duration):
            raise PneumafitInputError(
                f"{where}: expected delay + opening_time < duration, found "
                f"{self.delay:g} + {self.opening_time:g} >= {self.duration:g} s"
            )

    @property
    def command(self) -> float:
        """Signed opening command (V)."""
        return self.amplitude if self.kind == "charge" else -self.amplitude


@dataclass(frozen=True, kw_only=True)
class StepTest(_Test):
    """Closed-loop position steps under the campaign format's ``pd`` law.

    ``u_P = clip(u0 + kp (y_ref - y) - kd v, -umax, umax)``, ``u_N = -u_P``.
    The rig first runs ``preroll`` s at y_ref = ``start`` (not recorded), so
    the recording starts from a settled, usually stuck, piston.

    Parameters
    ----------
    start : float
        Reference position during the pre-roll and until the first step (m).
    steps : tuple of (float, float)
        (time (s) from the start of the recording, new reference (m)).
    duration : float
        Length of the recording (s).
    kp, kd, u0, umax : float
        Controller gains: V/m, V s/m, V, V.
    preroll : float
        Settling time before the recording (s).
    temperature : bool
        Record the slow gas-temperature sensors ``T_P`` and ``T_N``.
    """

    start: float
    steps: tuple[tuple[float, float], ...]
    duration: float
    kp: float = 60.0
    kd: float = 4.0
    u0: float = 0.0
    umax: float = 10.0
    preroll: float = 5.0
    temperature: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        where = f"test {self.file!r}"
        for name in ("duration", "umax", "preroll"):
            _positive(where, name, getattr(self, name))
        for name in ("start", "kp", "kd", "u0"):
            if not math.isfinite(getattr(self, name)):
                raise PneumafitInputError(f"{where}: {name}: expected a finite value")
        for when, pos in self.steps:
            if not (0.0 <= when < self.duration and math.isfinite(pos)):
                raise PneumafitInputError(
                    f"{where}: steps: expected (time in [0, duration), position), "
                    f"found ({when!r}, {pos!r})"
                )

    @property
    def kind(self) -> str:
        return "step"


Test = FlowTest | BlockedTest | StepTest


@dataclass(frozen=True)
class Protocol:
    """A named list of tests making up one campaign.

    Parameters
    ----------
    name : str
        Protocol name (``pneumafit rig --protocol``; written to truth.json).
    description : str
        One line, used as the campaign description.
    tests : tuple of FlowTest, BlockedTest or StepTest
        In campaign order; file names unique.
    design_stroke : float or None
        Stroke (m) the positions are written for; a rig of another stroke
        records them scaled (:meth:`for_stroke`). None: positions in the
        rig's own metres, only checked against its stroke.
    """

    name: str
    description: str
    tests: tuple[Test, ...]
    design_stroke: float | None = None

    def __post_init__(self) -> None:
        if not self.tests:
            raise PneumafitInputError(f"protocol {self.name!r}: expected at least one test")
        seen: set[str] = set()
        for test in self.tests:
            if test.file.lower() in seen:
                raise PneumafitInputError(
                    f"protocol {self.name!r}: file {test.file!r} is used twice"
                )
            seen.add(test.file.lower())

    def for_stroke(self, stroke: float) -> Protocol:
        """The protocol on a rig of stroke ``stroke`` (m).

        A protocol written for a stroke (``design_stroke``, the named ones:
        the demo rig's 500 mm) is scaled to it: piston positions and
        set-points by stroke / design_stroke, the ``pd`` gains kp and kd by
        its inverse, so that the commands are the design's. Without a
        ``design_stroke`` the positions are the rig's own and are only
        checked.

        Raises
        ------
        PneumafitInputError
            A position or set-point outside [0, stroke], naming the test.
        """
        out = self
        if self.design_stroke is not None and stroke != self.design_stroke:
            k = stroke / self.design_stroke

            def scaled(x: float, factor: float) -> float:
                # nine digits: 0.07 m, not 0.06999999999999999 m in campaign.toml
                return float(f"{x * factor:.9g}")

            tests: list[Test] = []
            for test in self.tests:
                if isinstance(test, BlockedTest):
                    test = replace(test, position=scaled(test.position, k))
                elif isinstance(test, StepTest):
                    test = replace(
                        test, start=scaled(test.start, k), kp=scaled(test.kp, 1.0 / k),
                        kd=scaled(test.kd, 1.0 / k),
                        steps=tuple((t, scaled(y, k)) for t, y in test.steps),
                    )  # fmt: skip
                tests.append(test)
            out = replace(self, tests=tuple(tests), design_stroke=stroke)
        for test in out.tests:
            where = f"protocol {self.name!r}, test {test.file!r}"
            if isinstance(test, BlockedTest):
                positions = [("position", test.position)]
            elif isinstance(test, StepTest):
                positions = [("start", test.start)] + [("steps", y) for _t, y in test.steps]
            else:
                positions = []
            for key, y in positions:
                if not 0.0 <= y <= stroke:
                    raise PneumafitInputError(
                        f"{where}: {key}: expected a position within the rig's stroke "
                        f"[0, {stroke * 1e3:g}] mm, found {y * 1e3:g} mm"
                    )
        return out


#: Stroke (m) the named protocols' positions are written for (the demo
#: rig's); :meth:`Protocol.for_stroke` scales them to another rig's. The
#: tutorial's are not scaled: its file names give its positions in mm.
DESIGN_STROKE = 0.5

_CSV_UNITS = {"y": "mm", "y_ref": "mm", "p_P": "bar", "p_N": "bar", "T_P": "degC", "T_N": "degC"}
_CSV_COLUMNS = {
    "y": "Position",
    "y_ref": "Setpoint",
    "p_P": "Pressure P",
    "p_N": "Pressure N",
    "u_P": "Valve P",
    "u_N": "Valve N",
    "T_P": "Temperature P",
    "T_N": "Temperature N",
}
_BAR = 1.0e5
_FLOW_COMMANDS = (
    -10.0, -6.0, -3.0, -1.5, -0.8, -0.4, -0.2, 0.0, 0.2, 0.4, 0.8, 1.5, 3.0, 6.0, 10.0,
)  # fmt: skip
_FLOW_UNITS = {"p_P": "bar", "p_N": "bar", "qm_P": "g/s", "qm_N": "g/s"}
_BLOCKED_UNITS = {"p_P": "bar", "p_N": "bar"}


def demo_protocol() -> Protocol:
    """The protocol of the committed demo campaign (``data/demo``).

    Two flow tests (one per valve), eight charge/discharge tests at three
    piston positions, several amplitudes and opening times (two held out),
    four closed-loop step tests (one held out, written as CSV with its own
    column names in mm, bar and degC). Durations: flow 45 s at 100 Hz,
    charge/discharge 6 s at 1 kHz, steps 4.5 s at 1 kHz after a 5-s pre-roll.
    """
    pressures = tuple(p * _BAR for p in (1.5, 2.5, 3.5, 4.5, 5.5, 6.5))
    flows = tuple(
        FlowTest(
            file=f"flow_{ch}.h5",
            chamber=ch,
            commands=_FLOW_COMMANDS,
            pressures=pressures,
            dwell=0.5,
            units=_FLOW_UNITS,
        )
        for ch in ("P", "N")
    )
    b = BlockedTest
    u = _BLOCKED_UNITS
    blocked = (
        b(file="charge_P_1.h5", kind="charge", chamber="P", position=0.10, amplitude=10.0,
          opening_time=0.30, temperature=True, units=u),
        b(file="discharge_P_1.h5", kind="discharge", chamber="P", position=0.10,
          amplitude=10.0, opening_time=0.40, temperature=True, units=u),
        b(file="charge_P_2.h5", kind="charge", chamber="P", position=0.40, amplitude=5.0,
          opening_time=0.80, units=u),
        b(file="discharge_P_2.h5", kind="discharge", chamber="P", position=0.40, amplitude=6.0,
          opening_time=0.80, units=u),
        b(file="charge_N_1.h5", kind="charge", chamber="N", position=0.40, amplitude=10.0,
          opening_time=0.25, temperature=True, units=u),
        b(file="discharge_N_1.h5", kind="discharge", chamber="N", position=0.10,
          amplitude=10.0, opening_time=0.60, units=u),
        b(file="charge_N_2.h5", kind="charge", chamber="N", position=0.25, amplitude=4.0,
          opening_time=0.80, temperature=True, role="validate", units=u),
        b(file="discharge_P_3.h5", kind="discharge", chamber="P", position=0.25, amplitude=8.0,
          opening_time=0.50, role="validate", units=u),
    )  # fmt: skip
    steps = (
        StepTest(file="step_1.h5", start=0.25, steps=((0.5, 0.35), (2.5, 0.15)), duration=4.5),
        StepTest(file="step_2.h5", start=0.10, steps=((0.5, 0.40), (2.5, 0.20)), duration=4.5,
                 kp=40.0, kd=2.5),
        StepTest(file="step_3.h5", start=0.30,
                 steps=((0.5, 0.32), (1.5, 0.29), (2.5, 0.31), (3.5, 0.30)), duration=4.5),
        StepTest(file="step_4.csv", start=0.20, steps=((0.5, 0.42), (2.5, 0.28)), duration=4.5,
                 temperature=True, role="validate", units=_CSV_UNITS, columns=_CSV_COLUMNS),
    )  # fmt: skip
    return Protocol(
        name="demo",
        description="Virtual rig demo campaign: flow, charge/discharge and closed-loop step tests",
        tests=flows + blocked + steps,
        design_stroke=DESIGN_STROKE,
    )


def quick_protocol() -> Protocol:
    """A small protocol for tests: one test of each kind, a few seconds each.

    A 3-s flow test of valve P, a charge of P with the temperature sensor, a
    held-out discharge of N, and a held-out closed-loop step test as CSV with
    its own column names (mm, bar, degC).
    """
    tests: tuple[Test, ...] = (
        FlowTest(file="flow_P.h5", chamber="P", commands=(-10.0, -2.0, 0.0, 2.0, 10.0),
                 pressures=(2.0 * _BAR, 5.0 * _BAR), dwell=0.3, units=_FLOW_UNITS),
        BlockedTest(file="charge_P.h5", kind="charge", chamber="P", position=0.2,
                    amplitude=10.0, opening_time=0.25, duration=2.0, temperature=True),
        BlockedTest(file="discharge_N.h5", kind="discharge", chamber="N", position=0.2,
                    amplitude=10.0, opening_time=0.3, duration=2.0, role="validate"),
        StepTest(file="step_1.csv", start=0.25, steps=((0.3, 0.33), (1.5, 0.20)), duration=2.5,
                 preroll=2.0, temperature=True, role="validate", units=_CSV_UNITS,
                 columns=_CSV_COLUMNS),
    )  # fmt: skip
    return Protocol(name="quick", description="Virtual rig quick campaign (tests)", tests=tests,
                    design_stroke=DESIGN_STROKE)  # fmt: skip


#: Column names of the tutorial's "new rig" (its acquisition software's own).
_TUTORIAL_COLUMNS = {
    "y": "pos_mm", "y_ref": "pos_set_mm", "p_P": "PT1_bar", "p_N": "PT2_bar",
    "u_P": "servo_A_V", "u_N": "servo_B_V", "T_P": "TC1_degC", "T_N": "TC2_degC",
    "qm_P": "FM1_gps", "qm_N": "FM2_gps",
}  # fmt: skip
_TUTORIAL_UNITS = {**_CSV_UNITS, "qm_P": "g/s", "qm_N": "g/s"}


def tutorial_protocol() -> Protocol:
    """A new rig's campaign as CSV files with its own column names (docs/tutorial.md).

    Every stage of the identification has its tests, all short: flow tests
    of both valves, charge and discharge tests of both chambers (one with the
    temperature sensor, one held out), two closed-loop step tests to fit the
    friction and one held out. Every file is CSV with the acquisition
    software's column names (``PT1_bar``, ``pos_mm``, ...) in bar, mm, degC
    and g/s.
    """
    kw = {"units": _TUTORIAL_UNITS}
    cmds = (-10.0, -3.0, -0.4, -0.2, 0.0, 0.2, 0.4, 3.0, 10.0)

    def cols(*names: str) -> dict[str, str]:
        return {n: _TUTORIAL_COLUMNS[n] for n in names}

    tests: tuple[Test, ...] = (
        FlowTest(file="valve_A_flow.csv", chamber="P", commands=cmds,
                 pressures=(2.0 * _BAR, 4.0 * _BAR, 6.0 * _BAR), dwell=0.4,
                 columns=cols("u_P", "p_P", "qm_P"), **kw),
        FlowTest(file="valve_B_flow.csv", chamber="N", commands=cmds,
                 pressures=(2.0 * _BAR, 4.0 * _BAR, 6.0 * _BAR), dwell=0.4,
                 columns=cols("u_N", "p_N", "qm_N"), **kw),
        BlockedTest(file="fill_A_100mm.csv", kind="charge", chamber="P", position=0.1,
                    amplitude=10.0, opening_time=0.3, duration=2.5, temperature=True,
                    columns=cols("u_P", "p_P", "T_P"), **kw),
        BlockedTest(file="empty_A_300mm.csv", kind="discharge", chamber="P", position=0.3,
                    amplitude=8.0, opening_time=0.5, duration=2.5,
                    columns=cols("u_P", "p_P"), **kw),
        BlockedTest(file="fill_B_300mm.csv", kind="charge", chamber="N", position=0.3,
                    amplitude=10.0, opening_time=0.25, duration=2.5,
                    columns=cols("u_N", "p_N"), **kw),
        BlockedTest(file="empty_B_200mm.csv", kind="discharge", chamber="N", position=0.2,
                    amplitude=10.0, opening_time=0.4, duration=2.0, role="validate",
                    columns=cols("u_N", "p_N"), **kw),
        StepTest(file="steps_1.csv", start=0.25, steps=((0.3, 0.35), (1.4, 0.18)), duration=2.5,
                 preroll=2.0, columns=cols("y", "y_ref", "p_P", "p_N", "u_P", "u_N"), **kw),
        StepTest(file="steps_2.csv", start=0.3, steps=((0.3, 0.32), (1.1, 0.29), (1.8, 0.31)),
                 duration=2.5, preroll=2.0,
                 columns=cols("y", "y_ref", "p_P", "p_N", "u_P", "u_N"), **kw),
        StepTest(file="steps_check.csv", start=0.25, steps=((0.3, 0.33), (1.5, 0.20)),
                 duration=2.5, preroll=2.0, temperature=True, role="validate",
                 columns=cols("y", "y_ref", "p_P", "p_N", "u_P", "u_N", "T_P", "T_N"), **kw),
    )  # fmt: skip
    return Protocol(
        name="tutorial",
        description="A new rig's first campaign, as its acquisition software wrote it (CSV)",
        tests=tests,
    )


def _sparse_flow_and_blocked(duration: float) -> tuple[Test, ...]:
    """The sparse plans' flow test of valve P (no 0-V level) and chamber P's
    charge/discharge tests (two to fit, two held out), each ``duration`` s."""
    cmds = (-10.0, -4.0, -1.5, -0.6, 0.6, 1.5, 4.0, 10.0)
    u = _BLOCKED_UNITS
    return (
        FlowTest(file="flow_P.h5", chamber="P", commands=cmds,
                 pressures=(2.0 * _BAR, 4.0 * _BAR, 6.0 * _BAR), dwell=0.3, units=_FLOW_UNITS),
        BlockedTest(file="charge_P_1.h5", kind="charge", chamber="P", position=0.12,
                    amplitude=10.0, opening_time=0.3, duration=duration, temperature=True,
                    units=u),
        BlockedTest(file="discharge_P_1.h5", kind="discharge", chamber="P", position=0.12,
                    amplitude=10.0, opening_time=0.4, duration=duration, units=u),
        BlockedTest(file="charge_P_2.h5", kind="charge", chamber="P", position=0.35,
                    amplitude=6.0, opening_time=0.6, duration=duration, role="validate",
                    units=u),
        BlockedTest(file="discharge_P_2.h5", kind="discharge", chamber="P", position=0.35,
                    amplitude=7.0, opening_time=0.6, duration=duration, role="validate",
                    units=u),
    )  # fmt: skip


def sparse_protocol() -> Protocol:
    """A deliberately thin campaign, to test what identification can do with little.

    One flow test of valve P only, at three held pressures and without a 0-V
    command level (the centre leak is never measured directly); charge and
    discharge tests of chamber P only (one of each to fit, one of each held
    out); two short closed-loop step tests (one to fit, one held out).
    Chamber N's valve and heat exchange are seen only through the steps.
    """
    tests: tuple[Test, ...] = (
        *_sparse_flow_and_blocked(2.0),
        StepTest(file="step_1.h5", start=0.25, steps=((0.3, 0.34), (1.2, 0.19)), duration=2.0,
                 preroll=1.0),
        StepTest(file="step_2.h5", start=0.30, steps=((0.3, 0.22), (1.2, 0.31)), duration=2.0,
                 preroll=1.0, kp=45.0, kd=3.0, temperature=True, role="validate"),
    )  # fmt: skip
    return Protocol(
        name="sparse",
        description="Virtual rig sparse campaign: one flow test (valve P, no 0 V), chamber P "
        "charge/discharge only, two short steps",
        tests=tests,
        design_stroke=DESIGN_STROKE,
    )


def sparse_long_protocol() -> Protocol:
    """The sparse plan with long tests: what a rig's first short session records.

    As :func:`sparse_protocol` (one flow test of valve P without a 0-V level,
    chamber P's charge/discharge tests only) but each charge/discharge test
    rests 3 s after its valve closes (the centre leak and the wall's heat
    alone act then), and the two closed-loop step tests last 8 s with four
    set-point changes each, the held-out one with other gains. The rests
    weigh the leak and the heat law more than the short plan's; the long
    steps give the friction more breakaways.
    """
    tests: tuple[Test, ...] = (
        *_sparse_flow_and_blocked(3.5),
        StepTest(file="step_1.h5", start=0.25,
                 steps=((0.5, 0.34), (2.5, 0.19), (4.5, 0.30), (6.5, 0.22)), duration=8.0,
                 preroll=1.0),
        StepTest(file="step_2.h5", start=0.30,
                 steps=((0.5, 0.22), (2.5, 0.31), (4.5, 0.17), (6.5, 0.27)), duration=8.0,
                 preroll=1.0, kp=45.0, kd=3.0, temperature=True, role="validate"),
    )  # fmt: skip
    return Protocol(
        name="sparse-long",
        description="Virtual rig sparse campaign with long tests: one flow test (valve P, no "
        "0 V), chamber P charge/discharge with 3-s rests, two 8-s closed-loop step tests",
        tests=tests,
        design_stroke=DESIGN_STROKE,
    )


#: Protocols by name.
PROTOCOLS = {
    "demo": demo_protocol,
    "quick": quick_protocol,
    "tutorial": tutorial_protocol,
    "sparse": sparse_protocol,
    "sparse-long": sparse_long_protocol,
}


def get_protocol(protocol: str | Protocol) -> Protocol:
    """Return a registered protocol by name, or the protocol itself.

    Raises
    ------
    ValueError
        Unknown name.
    """
    if isinstance(protocol, Protocol):
        return protocol
    try:
        return PROTOCOLS[protocol]()
    except KeyError:
        raise PneumafitInputError(
            f"protocol: expected one of {', '.join(PROTOCOLS)}, found {protocol!r}"
        ) from None
