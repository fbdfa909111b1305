"""Sensor models of the virtual rig: what turns true signals into recordings.

Every random draw comes from a :class:`numpy.random.Generator` passed in by
the caller; nothing here seeds or keeps a generator.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pneumafit.errors import PneumafitInputError
from pneumafit.simulation.sensor import first_order_lag

__all__ = ["SensorModel"]


def _lag(signal: NDArray[np.float64], dt: float, time_constant: float) -> NDArray[np.float64]:
    """A uniformly sampled signal through the shared first-order sensor (s)."""
    x = np.asarray(signal, dtype=float)
    if x.size == 0:
        return x.copy()
    return first_order_lag(x, dt * np.arange(x.size), time_constant)


@dataclass(frozen=True)
class SensorModel:
    """Noise, offsets, resolution and lags of the rig's sensors (SI units).

    Parameters
    ----------
    pressure_noise : float
        Standard deviation of the white noise of each pressure sensor (Pa).
    pressure_offset : float
        Standard deviation of the offset of each pressure sensor (Pa), drawn
        once per campaign for the sensors of chambers P and N (the same sensor
        reads a chamber in every test), saved in ``truth.json``.
    position_resolution : float
        Quantisation step of the position encoder (m).
    position_noise : float
        Standard deviation of the position noise before quantisation (m).
    temperature_time_constant : float
        First-order lag of the (slow) gas temperature sensor (s).
    temperature_noise : float
        Standard deviation of the temperature noise (K).
    flow_time_constant : float
        First-order lag of the flow meter of flow tests (s).
    flow_noise : float
        Standard deviation of the flow-meter noise (kg/s).
    """

    pressure_noise: float = 400.0
    pressure_offset: float = 1500.0
    position_resolution: float = 1.0e-5
    position_noise: float = 3.0e-6
    temperature_time_constant: float = 0.4
    temperature_noise: float = 0.05
    flow_time_constant: float = 0.03
    flow_noise: float = 2.0e-5

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value >= 0.0):
                raise PneumafitInputError(
                    f"sensor model: {name}: expected a finite value >= 0, found {value!r}"
                )

    def as_dict(self) -> dict[str, Any]:
        """Settings by name (SI), for ``truth.json``."""
        return asdict(self)

    def draw_offsets(self, rng: np.random.Generator) -> dict[str, float]:
        """Offsets (Pa) of the pressure sensors of chambers P and N."""
        draws = rng.normal(0.0, self.pressure_offset, size=2)
        return {"p_P": float(draws[0]), "p_N": float(draws[1])}

    def pressure(
        self, true: NDArray[np.float64], offset: float, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """Reading of a pressure sensor (Pa): true value + offset + noise."""
        return true + offset + rng.normal(0.0, self.pressure_noise, size=true.shape)

    def position(self, true: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
        """Reading of the position encoder (m): noise, then quantisation."""
        noisy = true + rng.normal(0.0, self.position_noise, size=true.shape)
        q = self.position_resolution
        return np.round(noisy / q) * q if q > 0.0 else noisy

    def temperature(
        self, true: NDArray[np.float64], dt: float, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """Reading of the slow gas-temperature sensor (K): lag, then noise."""
        lagged = _lag(true, dt, self.temperature_time_constant)
        return lagged + rng.normal(0.0, self.temperature_noise, size=true.shape)

    def flow(
        self, true: NDArray[np.float64], dt: float, rng: np.random.Generator, every: int = 1
    ) -> NDArray[np.float64]:
        """Reading of the flow meter (kg/s): lag, sampling, then noise.

        Parameters
        ----------
        true : ndarray
            True mass flow (kg/s) sampled every ``dt`` (s), fine enough for the lag.
        dt : float
            Sample interval of ``true`` (s).
        rng : numpy.random.Generator
        every : int
            Keep one sample in ``every`` (the recording's rate).
        """
        lagged = _lag(true, dt, self.flow_time_constant)[::every]
        return lagged + rng.normal(0.0, self.flow_noise, size=lagged.shape)
