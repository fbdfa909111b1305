"""Sensors of the models' side (the fit, the replay, the report).

A first-order sensor, tau dy/dt = x - y, settled at the start (y_0 = x_0),
discretised exactly for an input linear between samples, so uneven grids
are fine; and a temperature probe (:class:`TemperatureProbe`): two such lags
in series and a constant offset (the replay fits the lags). The virtual rig,
the truth's side, keeps its own sensor laws on purpose
(``virtual_rig.held_input_lag``, ``virtual_rig.truth.probe``): the data must
not be made with the fitted models' code.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.numba_stamp import njit

__all__ = ["TemperatureProbe", "first_order_lag"]


@njit(cache=True)
def _lag_kernel(x: np.ndarray, t: np.ndarray, tau: np.ndarray, y: np.ndarray) -> None:
    n_sets, n = x.shape
    for i in range(n_sets):
        y[i, 0] = x[i, 0]
        ti = tau[i]
        for k in range(1, n):
            dt = t[k] - t[k - 1]
            if ti <= 0.0:
                y[i, k] = x[i, k]
                continue
            a = math.exp(-dt / ti)
            slope = (x[i, k] - x[i, k - 1]) / dt
            # exact for an input linear over the interval
            y[i, k] = a * y[i, k - 1] + x[i, k] - a * x[i, k - 1] - ti * slope * (1.0 - a)


def first_order_lag(
    signal: ArrayLike, time: ArrayLike, time_constant: ArrayLike
) -> NDArray[np.float64]:
    """Reading of a first-order sensor, tau dy/dt = x - y, settled at the start.

    Discretised exactly for an input linear between samples (so uneven grids
    are fine): y_k = a y_(k-1) + x_k - a x_(k-1) - tau s (1 - a), with
    a = exp(-dt / tau) and s the input's slope over the interval.

    Parameters
    ----------
    signal : array_like, shape (n,) or (n_sets, n)
        True signal x.
    time : array_like, shape (n,)
        Sample times (s).
    time_constant : float or array_like, shape (n_sets,)
        tau (s); 0 returns the signal.

    Returns
    -------
    ndarray, same shape as ``signal``.
    """
    x = np.asarray(signal, dtype=float)
    x2 = np.atleast_2d(x)
    tau = np.broadcast_to(np.asarray(time_constant, dtype=float), (x2.shape[0],)).copy()
    y = np.empty_like(x2)
    _lag_kernel(np.ascontiguousarray(x2), np.asarray(time, dtype=float), tau, y)
    return y.reshape(x.shape)


@dataclass(frozen=True)
class TemperatureProbe:
    """A gas-temperature probe: two first-order lags in series and an offset.

    A sheathed thermocouple or RTD reads the gas through its own heat
    capacity (the first lag) and, in a well or a fitting, through the well's
    (the second); its calibration leaves a constant offset. The reading of a
    gas temperature x(t) is

        tau_1 dy_1/dt = x - y_1,   tau_2 dy_2/dt = y_1 - y_2,   reading = y_2 + offset,

    settled at the start (y_1 = y_2 = x_0). The two lags commute, so they are
    stored largest first. The replay fits the lags
    (:func:`~pneumafit.identification.problem.fit_temperature_probe`) and
    leaves the offset at 0: fitted, it takes up a model's error in the gas
    temperature as readily as a calibration error. One lag is ``second_time_constant = 0``; the bare
    gas temperature is ``TemperatureProbe(0.0)``.

    Attributes
    ----------
    time_constant : float
        The larger lag tau_1 (s, >= 0).
    second_time_constant : float
        The smaller lag tau_2 (s, 0 <= tau_2 <= tau_1).
    offset : float
        Reading minus the settled gas temperature (K).
    """

    time_constant: float
    second_time_constant: float = 0.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        lags = sorted((float(self.time_constant), float(self.second_time_constant)), reverse=True)
        if not (all(math.isfinite(v) and v >= 0.0 for v in lags) and math.isfinite(self.offset)):
            raise ValueError(
                f"temperature probe: expected finite time constants >= 0 s and a finite "
                f"offset, found {self.time_constant!r}, {self.second_time_constant!r}, "
                f"{self.offset!r}"
            )
        object.__setattr__(self, "time_constant", lags[0])
        object.__setattr__(self, "second_time_constant", lags[1])
        object.__setattr__(self, "offset", float(self.offset))

    @property
    def total_lag(self) -> float:
        """tau_1 + tau_2 (s): the probe's mean delay, its one-lag equivalent."""
        return self.time_constant + self.second_time_constant

    def read(
        self,
        signal: ArrayLike,
        time: ArrayLike,
        start: tuple[float, float] | None = None,
    ) -> NDArray[np.float64]:
        """The probe's reading (K) of a gas temperature ``signal`` (K) at ``time`` (s).

        ``signal`` has shape (n,) or (n_sets, n); the result has its shape.

        Parameters
        ----------
        signal : array_like
            Gas temperature (K).
        time : array_like, shape (n,)
            Sample times (s).
        start : (float, float), optional
            The measured reading at the first sample (K) and its rate there
            (K/s): a probe that is not settled on the gas, as at the start of
            a recording cut from a run in motion. Its states are then
            y_2 = reading - offset and y_1 = y_2 + tau_2 rate (the second
            lag's equation), and the reading is the settled one plus the
            chain's free response to the difference (:meth:`release`).
            Default: settled on the gas at the first sample.
        """
        y = first_order_lag(signal, time, self.time_constant)
        if self.second_time_constant > 0.0:
            y = first_order_lag(y, time, self.second_time_constant)
        if start is not None:
            x = np.asarray(signal, dtype=float)
            y2 = float(start[0]) - self.offset
            y1 = y2 + self.second_time_constant * float(start[1])
            x0 = x[..., :1]
            t = np.asarray(time, dtype=float)
            y = y + self.release(y1 - x0, y2 - x0, t - t[0])
        return y + self.offset

    def release(
        self, first: ArrayLike, second: ArrayLike, elapsed: ArrayLike
    ) -> NDArray[np.float64]:
        """Free response of the two lags (K) to initial states off a constant gas.

        With the gas held, the deviations d_1 = y_1 - x and d_2 = y_2 - x
        obey tau_1 d_1' = -d_1, tau_2 d_2' = d_1 - d_2, whose solution is

            d_2(t) = C e^(-t/tau_1) + (d_2(0) - C) e^(-t/tau_2),
            C = d_1(0) tau_1 / (tau_1 - tau_2),

        and, for tau_1 = tau_2 = tau, (d_2(0) + d_1(0) t / tau) e^(-t/tau);
        d_1 itself with one lag (tau_2 = 0). By linearity the reading of any
        gas signal from such states is the settled reading plus d_2 (or d_1).

        Parameters
        ----------
        first, second : array_like
            d_1(0) and d_2(0) (K), broadcast against ``elapsed``.
        elapsed : array_like
            Time since the start (s, >= 0).
        """
        d1 = np.asarray(first, dtype=float)
        d2 = np.asarray(second, dtype=float)
        t = np.asarray(elapsed, dtype=float)
        t1, t2 = self.time_constant, self.second_time_constant
        shape = np.broadcast_shapes(d1.shape, d2.shape, t.shape)
        if t1 <= 0.0:
            return np.zeros(shape)
        if t2 <= 0.0:
            return np.broadcast_to(d1 * np.exp(-t / t1), shape).copy()
        if t1 - t2 <= 1e-3 * t1:
            # equal lags (C's two terms cancel): the limit at their mean, off
            # by O((tau_1 - tau_2) / tau_1) of d, 1e-3 at most
            tau = 0.5 * (t1 + t2)
            return (d2 + d1 * t / tau) * np.exp(-t / tau)
        c = d1 * t1 / (t1 - t2)
        return c * np.exp(-t / t1) + (d2 - c) * np.exp(-t / t2)

    def as_dict(self) -> dict[str, float]:
        """``time_constant``, ``second_time_constant`` (s) and ``offset`` (K), for fit.json."""
        return {
            "time_constant": self.time_constant,
            "second_time_constant": self.second_time_constant,
            "offset": self.offset,
        }

    @classmethod
    def from_metrics(cls, metrics: Mapping[str, Any] | None) -> TemperatureProbe | None:
        """The probe a fit's ``metrics`` name, or None.

        ``metrics.temperature_probe`` (a mapping as :meth:`as_dict` writes),
        else the one lag ``metrics.temperature_sensor_lag`` (s; fits written
        before the probe had an offset and a second lag). Unusable entries
        count as none.
        """
        metrics = metrics or {}
        entry = metrics.get("temperature_probe")
        if isinstance(entry, Mapping):
            try:
                probe = cls(
                    float(entry["time_constant"]),
                    float(entry.get("second_time_constant", 0.0)),
                    float(entry.get("offset", 0.0)),
                )
            except (KeyError, TypeError, ValueError):
                probe = None
            if probe is not None and probe.total_lag > 0.0:
                return probe
        lag = metrics.get("temperature_sensor_lag")
        if isinstance(lag, int | float) and not isinstance(lag, bool) and math.isfinite(lag):
            return cls(float(lag)) if lag > 0 else None
        return None
