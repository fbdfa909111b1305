"""Temperature probes of the truth: the gas-temperature sensor's own lag and offset.

A probe reads the true gas temperature T (K) sampled every dt (s) through one
or two first-order lags in series (sheathed thermocouple and its well), adds
a constant offset (calibration error) and white noise:

    tau_1 dT_1/dt = T - T_1,   tau_2 dT_2/dt = T_1 - T_2,   reading = T_2 + offset + noise

Each lag starts settled at the first sample. Used by
:class:`pneumafit.virtual_rig.VirtualRig` in place of
:meth:`pneumafit.virtual_rig.SensorModel.temperature` when a truth configuration
names a probe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from pneumafit.errors import PneumafitInputError

__all__ = ["PROBE_MODELS", "LaggedProbe"]


def _lag(x: NDArray[np.float64], dt: float, tau: float) -> NDArray[np.float64]:
    # exact for a signal held over each sample interval, settled at x[0]
    if tau <= 0.0 or x.size == 0:
        return x.copy()
    a = math.exp(-dt / tau)
    out, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    return np.asarray(out, dtype=float)


@dataclass(frozen=True, kw_only=True)
class LaggedProbe:
    """A gas-temperature probe with one or two lags, an offset and noise.

    Parameters
    ----------
    time_constant : float
        First lag tau_1 (s), >= 0.
    second_time_constant : float
        Second lag tau_2 (s), >= 0 (0: a first-order probe).
    offset : float
        Constant reading error (K).
    noise : float
        Standard deviation of the white noise (K), >= 0.
    """

    name: ClassVar[str] = "lagged"
    time_constant: float
    second_time_constant: float = 0.0
    offset: float = 0.0
    noise: float = 0.05

    def __post_init__(self) -> None:
        for key in ("time_constant", "second_time_constant", "noise"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0.0):
                raise PneumafitInputError(
                    f"probe 'lagged': {key}: expected a value >= 0, found {value!r}"
                )
        if not (math.isfinite(self.offset) and abs(self.offset) < 50.0):
            raise PneumafitInputError(
                f"probe 'lagged': offset: expected |offset| < 50 K, found {self.offset!r}"
            )

    def read(
        self, true: NDArray[np.float64], dt: float, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """The probe's reading (K) of the true temperature ``true`` sampled every dt (s)."""
        x = np.asarray(true, dtype=float)
        lagged = _lag(_lag(x, dt, self.time_constant), dt, self.second_time_constant)
        return lagged + self.offset + rng.normal(0.0, self.noise, size=x.shape)


#: Temperature-probe models by name.
PROBE_MODELS: dict[str, type[Any]] = {LaggedProbe.name: LaggedProbe}
