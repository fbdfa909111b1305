"""Named parameter values <-> the kernel's flat parameter vector."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from pneumafit.errors import PneumafitInputError
from pneumafit.models.layout import PARAMETER_NAMES, SPECS, P, n_parameters


def default_parameters() -> dict[str, float]:
    """Default value (SI) of every model parameter, by name."""
    return {name: SPECS[name].default for name in PARAMETER_NAMES}


def parameter_vector(
    values: Mapping[str, float] | None = None, base: np.ndarray | None = None
) -> np.ndarray:
    """Build the kernel's parameter vector from named SI values.

    Parameters
    ----------
    values : mapping of str to float, optional
        Values by canonical name (SI units); unnamed parameters keep ``base``
        or their defaults. ``wall_temperature`` and ``characteristic_length``
        follow ``ambient_temperature`` and ``bore`` unless given.
    base : ndarray, optional
        Vector to start from instead of the defaults.

    Returns
    -------
    ndarray, shape (NP,)

    Raises
    ------
    ValueError
        On an unknown name, a non-finite value or a value outside its bounds.
    """
    values = dict(values or {})
    vec = (
        np.array(base, dtype=float)
        if base is not None
        else np.array([SPECS[n].default for n in PARAMETER_NAMES], dtype=float)
    )
    if base is None:
        if "ambient_temperature" in values and "wall_temperature" not in values:
            values["wall_temperature"] = values["ambient_temperature"]
        if "bore" in values and "characteristic_length" not in values:
            values["characteristic_length"] = values["bore"]
    for name, value in values.items():
        if name not in P:
            raise PneumafitInputError(
                f"parameter {name!r}: expected one of the model parameters "
                f"({', '.join(PARAMETER_NAMES)}), found an unknown name"
            )
        value = float(value)
        spec = SPECS[name]
        if not math.isfinite(value) and not (spec.lower == -math.inf):
            raise PneumafitInputError(f"parameter {name!r}: expected a finite value, found {value}")
        if not spec.lower <= value <= spec.upper:
            raise PneumafitInputError(
                f"parameter {name!r}: expected a value in [{spec.lower:g}, {spec.upper:g}] "
                f"{spec.unit}, found {value:g}"
            )
        vec[P[name]] = value
    return vec


def parameter_dict(vector: np.ndarray) -> dict[str, float]:
    """Inverse of :func:`parameter_vector`: name -> value (SI)."""
    vector = np.asarray(vector, dtype=float)
    n = n_parameters()
    if vector.shape != (n,):
        raise PneumafitInputError(f"parameter vector: expected shape ({n},), found {vector.shape}")
    return {name: float(vector[i]) for i, name in enumerate(PARAMETER_NAMES)}
