"""A first-order sensor: the one lag of the models' side (the fit, the replay, the report).

tau dy/dt = x - y, settled at the start (y_0 = x_0), discretised exactly for
an input linear between samples, so uneven grids are fine. The virtual rig,
the truth's side, keeps its own sensor laws on purpose
(``virtual_rig.held_input_lag``, ``virtual_rig.truth.probe``): the data must
not be made with the fitted models' code.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.numba_stamp import njit

__all__ = ["first_order_lag"]


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
