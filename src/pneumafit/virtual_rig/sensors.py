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
from scipy.signal import lfilter

from pneumafit.errors import PneumafitInputError

__all__ = ["SensorModel", "held_input_lag"]


def held_input_lag(
    signal: NDArray[np.float64], dt: float, time_constant: float
) -> NDArray[np.float64]:
    """Reading of the rig's first-order sensors, tau dy/dt = x - y, settled at the start.

    The virtual rig's own sensor law, on the truth's side of every recording:
    discretised exactly for an input *held* over each sample interval,
    y[k] = a y[k-1] + (1 - a) x[k] with a = exp(-dt / tau), y[0] = x[0]. The
    fit's lag (:func:`pneumafit.simulation.sensor.first_order_lag`, exact for
    an input linear between samples) differs from it by about half a sample
    on purpose: the data are not made with the fitted model's code.

    Parameters
    ----------
    signal : ndarray
        True signal x, uniformly sampled.
    dt : float
        Sample interval (s).
    time_constant : float
        tau (s); 0 returns the signal unchanged.

    Returns
    -------
    ndarray
        The sensor's reading y, same shape as ``signal``.
    """
    x = np.asarray(signal, dtype=float)
    if time_constant <= 0.0 or x.size == 0:
        return x.copy()
    a = math.exp(-dt / time_constant)
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    return np.asarray(y, dtype=float)


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
        lagged = held_input_lag(true, dt, self.temperature_time_constant)
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
        lagged = held_input_lag(true, dt, self.flow_time_constant)[::every]
        return lagged + rng.normal(0.0, self.flow_noise, size=lagged.shape)
