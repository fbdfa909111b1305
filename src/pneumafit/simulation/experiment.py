"""Experiments: what the simulator needs from a recording."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from pneumafit.errors import PneumafitInputError
from pneumafit.models.layout import (
    CTRL_DB_AMPLITUDE,
    CTRL_DB_WIDTH,
    LAW_PD,
    LAW_STATE_FEEDBACK,
    NCTRL,
    NX,
    X_PN,
    X_PP,
    X_TN,
    X_TP,
    X_V,
    X_Y,
    X_Z,
)

if TYPE_CHECKING:
    from pneumafit.campaign.model import Recording

KINDS = ("charge", "discharge", "flow", "step", "free")


@dataclass(frozen=True)
class PD:
    """The campaign format's ``pd`` law, u_P = clip(u0 + kp (y_ref - y) - kd v, +-umax).

    Attributes: kp (V/m), kd (V s/m), u0 (V), umax (V).
    """

    kp: float
    kd: float
    u0: float = 0.0
    umax: float = 10.0

    law = LAW_PD

    @property
    def reference_gain(self) -> float:
        """Command change per metre of reference change (V/m)."""
        return abs(self.kp)

    def as_array(self) -> np.ndarray:
        """Controller vector of the kernel (layout.NCTRL)."""
        out = np.zeros(NCTRL)
        out[:4] = self.kp, self.kd, self.u0, self.umax
        return out


@dataclass(frozen=True)
class StateFeedback:
    """Full-state feedback around an equilibrium (paper's design):
    u_P = clip(c(v), -umax, umax), v = u_e - K (x - x_e), x = [y, v, P_N, P_P,
    T_N, T_P], u_N = -u_P.

    The position entry of x_e follows the reference y_ref(t); the other
    entries are the equilibrium's. A gain for the 4-state (polytropic) model
    has zeros on the temperatures. c is the dead-band compensation
    c(v) = v + a tanh(v / w) (a = ``deadband``, w = ``deadband_width``), the
    identity when w = 0; with it on, ``u_e`` is the controller-side
    equilibrium v_e, c(v_e) being the valve's equilibrium command
    (:func:`pneumafit.analysis.linear.deadband_compensation`).

    Attributes: gain K (6,) in V per SI state unit, x_e (6,) SI, u_e (V),
    umax (V), deadband a (V), deadband_width w (V).
    """

    gain: tuple[float, ...]
    x_e: tuple[float, ...]
    u_e: float
    umax: float = 10.0
    deadband: float = 0.0
    deadband_width: float = 0.0

    law = LAW_STATE_FEEDBACK

    def __post_init__(self) -> None:
        gain = tuple(float(v) for v in np.ravel(self.gain))
        x_e = tuple(float(v) for v in np.ravel(self.x_e))
        if len(gain) not in (4, 6) or len(x_e) != 6:
            raise PneumafitInputError(
                f"state feedback: expected 4 or 6 gains and 6 equilibrium states, found "
                f"{len(gain)} and {len(x_e)}"
            )
        gain = gain + (0.0,) * (6 - len(gain))  # a 4-state gain ignores temperatures
        if not (self.deadband >= 0.0 and self.deadband_width >= 0.0):
            raise PneumafitInputError(
                f"state feedback: dead-band compensation: expected a >= 0 and w >= 0 V, "
                f"found {self.deadband} and {self.deadband_width}"
            )
        object.__setattr__(self, "gain", gain)
        object.__setattr__(self, "x_e", x_e)

    @property
    def reference_gain(self) -> float:
        """Command change per metre of reference change (V/m)."""
        return abs(self.gain[0])

    def as_array(self) -> np.ndarray:
        """Controller vector of the kernel (layout.NCTRL)."""
        out = np.zeros(NCTRL)
        out[2], out[3] = self.u_e, self.umax
        if self.deadband_width > 0.0:
            out[CTRL_DB_AMPLITUDE] = self.deadband
            out[CTRL_DB_WIDTH] = self.deadband_width
        out[4:10] = self.gain
        out[10:16] = self.x_e
        return out


@dataclass(frozen=True)
class Experiment:
    """Inputs and initial state of one test, in SI units.

    Parameters
    ----------
    time : ndarray, shape (n,)
        Sample times (s), strictly increasing, n >= 2.
    kind : {"charge", "discharge", "flow", "step", "free"}
        Test kind (campaign format). Charge and discharge tests block the
        piston; flow tests evaluate the static valve characteristic.
    u_P, u_N : ndarray, optional
        Measured commands (V), replayed open loop (linear between samples).
        A missing ``u_N`` is -``u_P`` (single-input rig).
    y_ref : ndarray, optional
        Reference position (m) for closed-loop tests.
    controller : PD or StateFeedback, optional
        The law that produced the commands; when given, the test is simulated
        closed loop.
    chamber : {"P", "N"}, optional
        Chamber under test (charge, discharge, flow).
    p_chamber : ndarray, optional
        Held chamber pressure (Pa) of a flow test.
    initial : dict, optional
        Initial values by state name (y, v, p_P, p_N, T_P, T_N, z_f);
        pressures default to exhaust, temperatures to the wall, v to 0, y to
        0, the LuGre bristle deflection z_f (m) to static equilibrium (or
        steady sliding) at the initial state.
    name : str
        For messages and reports.
    """

    time: np.ndarray
    kind: str
    u_P: np.ndarray | None = None
    u_N: np.ndarray | None = None
    y_ref: np.ndarray | None = None
    controller: PD | StateFeedback | None = None
    chamber: str | None = None
    p_chamber: np.ndarray | None = None
    initial: dict[str, float] = field(default_factory=dict)
    name: str = "experiment"

    def __post_init__(self) -> None:
        t = np.asarray(self.time, dtype=float)
        object.__setattr__(self, "time", t)
        where = f"experiment {self.name!r}"
        if self.kind not in KINDS:
            raise PneumafitInputError(
                f"{where}: kind: expected one of {KINDS}, found {self.kind!r}"
            )
        if t.ndim != 1 or t.size < 2:
            raise PneumafitInputError(f"{where}: time: expected at least 2 samples, found {t.size}")
        if not np.all(np.isfinite(t)):
            raise PneumafitInputError(f"{where}: time: expected finite samples, found NaN/inf")
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0))
            raise PneumafitInputError(
                f"{where}: time: expected strictly increasing samples, found "
                f"{t[i]:g} s followed by {t[i + 1]:g} s (samples {i} and {i + 1})"
            )
        for name in ("u_P", "u_N", "y_ref", "p_chamber"):
            arr = getattr(self, name)
            if arr is None:
                continue
            arr = np.asarray(arr, dtype=float)
            if arr.shape != t.shape:
                raise PneumafitInputError(
                    f"{where}: {name}: expected {t.size} samples like time, found {arr.size}"
                )
            if not np.all(np.isfinite(arr)):
                raise PneumafitInputError(
                    f"{where}: {name}: expected finite samples, found NaN/inf"
                )
            object.__setattr__(self, name, arr)
        if self.kind in ("charge", "discharge", "flow") and self.chamber not in ("P", "N"):
            raise PneumafitInputError(
                f"{where}: chamber: expected 'P' or 'N' for a {self.kind} test, "
                f"found {self.chamber!r}"
            )
        if self.kind == "flow" and self.p_chamber is None:
            raise PneumafitInputError(
                f"{where}: p_{self.chamber}: expected the held pressure of a flow test, found none"
            )
        if self.closed_loop and self.y_ref is None:
            raise PneumafitInputError(
                f"{where}: y_ref: expected the reference position of a closed-loop test, found none"
            )
        if not self.closed_loop and self.kind != "flow":
            needed = "u_" + self.chamber if self.blocked else "u_P"
            if (self.u_P is None and self.u_N is None) or (
                self.blocked and getattr(self, needed) is None
            ):
                raise PneumafitInputError(
                    f"{where}: {needed}: expected the commands of an open-loop test, found none"
                )

    @property
    def blocked(self) -> bool:
        """True for charge and discharge tests (piston blocked)."""
        return self.kind in ("charge", "discharge")

    @property
    def closed_loop(self) -> bool:
        """True when the commands come from the declared controller."""
        return self.controller is not None and self.kind in ("step", "free")

    @property
    def n_samples(self) -> int:
        return int(self.time.size)

    def inputs(self) -> np.ndarray:
        """Input table (n, 4): u_P, u_N, y_ref, p_chamber."""
        n = self.time.size
        inp = np.zeros((n, 4))
        u_p = self.u_P if self.u_P is not None else None
        u_n = self.u_N if self.u_N is not None else None
        if u_p is None and u_n is not None:
            u_p = -u_n
        if u_n is None and u_p is not None:
            u_n = -u_p
        if u_p is not None:
            inp[:, 0] = u_p
            inp[:, 1] = u_n
        if self.y_ref is not None:
            inp[:, 2] = self.y_ref
        if self.p_chamber is not None:
            inp[:, 3] = self.p_chamber
        return inp

    def initial_state(self, size: int = NX) -> np.ndarray:
        """Initial state vector (size,); NaN where the kernel takes a default.

        ``size`` is the state vector's length of the kernel that runs it
        (``kernel_for(structure).NX``: longer than ``layout.NX`` for outside
        effects with states past the first slot; those start at 0)."""
        x0 = np.full(size, np.nan)
        x0[X_Y] = self.initial.get("y", 0.0)
        x0[X_V] = self.initial.get("v", 0.0)
        for name, idx in (("p_N", X_PN), ("p_P", X_PP), ("T_N", X_TN), ("T_P", X_TP)):
            if name in self.initial:
                x0[idx] = self.initial[name]
        x0[10:] = 0.0
        # NaN: the kernel starts the LuGre bristles in equilibrium (kernel.initial_deflection)
        x0[X_Z] = self.initial.get("z_f", np.nan)
        return x0

    @classmethod
    def from_recording(cls, recording: Recording) -> Experiment:
        """Build the experiment of a campaign recording (SI arrays).

        The initial state is taken from the first sample of the measured
        channels (position, pressures; temperatures only when measured).
        """
        ch = recording.channels
        initial: dict[str, float] = {}
        for name in ("y", "v", "p_P", "p_N"):
            if name in ch:
                initial[name] = float(ch[name][0])
        if recording.kind in ("charge", "discharge") and recording.piston_position is not None:
            initial["y"] = float(recording.piston_position)
        controller = None
        if recording.controller is not None:
            c = recording.controller
            controller = PD(kp=c.kp, kd=c.kd, u0=c.u0, umax=c.umax)
        p_chamber = None
        if recording.kind == "flow" and recording.chamber is not None:
            p_chamber = ch.get("p_" + recording.chamber)
        return cls(
            time=recording.time,
            kind=recording.kind,
            u_P=ch.get("u_P"),
            u_N=ch.get("u_N"),
            y_ref=ch.get("y_ref"),
            controller=controller,
            chamber=recording.chamber,
            p_chamber=p_chamber,
            initial=initial,
            name=recording.file,
        )
