"""One parameter-set type for every identification stage (lmfit's ``Parameters``).

A :class:`Parameter` holds a name, a unit, a value, bounds, a prior, a
sampling scale (``"linear"`` or ``"log"``), whether it is fixed, and after a
fit its uncertainty summary. A :class:`ParameterSet` is an ordered collection
of them; it maps the *free* parameters to the internal coordinates the
optimisers and samplers work in (log of the value for log-scale parameters)
and back, and is saved to and reloaded from JSON without loss.

Model parameters use the canonical names of
:data:`pneumafit.models.PARAMETER_SPECS`; a set may also hold nuisance
parameters of the measurement (e.g. ``temperature_sensor_lag``).

>>> ps = ParameterSet.for_model("convection")          # doctest: +SKIP
>>> ps["xi"].value, ps["xi"].scale, ps["xi"].fixed     # doctest: +SKIP
(0.4, 'log', False)
>>> ps.save("start.json"); ParameterSet.load("start.json") == ps   # doctest: +SKIP
True
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pneumafit.errors import PneumafitInputError
from pneumafit.fileio import write_text_atomic
from pneumafit.models.layout import NP, PARAMETER_NAMES, SPECS, P
from pneumafit.models.parts import FRICTION_LAWS, VALVE_LAWS
from pneumafit.models.structure import (
    FRICTION_PARAMETERS,
    VALVE_PARAMETERS,
    ModelStructure,
    get_structure,
)

__all__ = [
    "CONSTRAINTS",
    "FORMAT",
    "NUISANCE_SPECS",
    "LogNormal",
    "LogUniform",
    "Normal",
    "Parameter",
    "ParameterSet",
    "Prior",
    "Uniform",
    "prior_from_dict",
]

#: ``format`` key of a saved parameter set.
FORMAT = "pneumafit-parameters"
VERSION = 1

SCALES = ("linear", "log")

#: Inequality constraints between parameters (larger, smaller, what an
#: estimate on the constraint means) that the kernel enforces by rejecting
#: the parameter set (``kernel.check_parameters``: static friction below the
#: Coulomb level). An estimate on one is as untrustworthy as one on a bound
#: (its Laplace interval is squeezed by the wall, its partner unidentified:
#: :func:`pneumafit.identification.quality.bound_problems`); the
#: covariances' finite-difference steps do not cross one
#: (:meth:`pneumafit.identification.optimise._Whitened.fun_and_jac`), and the
#: Laplace draws behind the reference figures stay on its allowed side.
CONSTRAINTS: tuple[tuple[str, str, str], ...] = (
    ("friction_static", "friction_coulomb",
     "no Stribeck drop resolved, stribeck_velocity not identified"),
)  # fmt: skip


# --------------------------------------------------------------------- JSON
def _num(value: float) -> float | str:
    """A float for JSON: non-finite values as the strings 'inf', '-inf', 'nan'."""
    value = float(value)
    if math.isfinite(value):
        return value
    return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")


def _float(value: Any, where: str) -> float:
    if isinstance(value, bool):
        raise PneumafitInputError(f"{where}: expected a number, found {value!r}")
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str) and value in ("inf", "-inf", "nan"):
        return float(value)
    raise PneumafitInputError(f"{where}: expected a number, found {value!r}")


# ------------------------------------------------------------------- priors
class Prior:
    """Prior density of a parameter's *value* (not of its internal coordinate).

    Subclasses implement :meth:`logpdf` (vectorised, -inf outside the
    support), :meth:`as_dict` and optionally :meth:`residual` (a Gaussian
    prior's contribution to a least-squares problem).
    """

    kind: ClassVar[str] = ""

    def logpdf(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        raise NotImplementedError

    def residual(self, value: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Whitened residual r with logpdf = -r^2 / 2 + const, or None (flat)."""
        return None

    def as_dict(self) -> dict[str, Any]:
        raise NotImplementedError


@dataclass(frozen=True)
class Uniform(Prior):
    """Flat density on [lower, upper]."""

    lower: float
    upper: float
    kind: ClassVar[str] = "uniform"

    def logpdf(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.asarray(value, dtype=float)
        width = self.upper - self.lower
        inside = (v >= self.lower) & (v <= self.upper)
        dens = -math.log(width) if math.isfinite(width) and width > 0 else 0.0
        return np.where(inside, dens, -np.inf)

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "lower": _num(self.lower), "upper": _num(self.upper)}


@dataclass(frozen=True)
class LogUniform(Prior):
    """Density proportional to 1 / value on [lower, upper], lower > 0 (scale-free)."""

    lower: float
    upper: float
    kind: ClassVar[str] = "log-uniform"

    def __post_init__(self) -> None:
        if not (self.lower > 0.0 and self.upper > self.lower):
            raise PneumafitInputError(
                f"log-uniform prior: expected 0 < lower < upper, found [{self.lower}, {self.upper}]"
            )

    def logpdf(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.asarray(value, dtype=float)
        inside = (v >= self.lower) & (v <= self.upper)
        norm = math.log(math.log(self.upper / self.lower)) if math.isfinite(self.upper) else 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(inside, -np.log(np.where(inside, v, 1.0)) - norm, -np.inf)

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "lower": _num(self.lower), "upper": _num(self.upper)}


@dataclass(frozen=True)
class Normal(Prior):
    """Gaussian density of the value: mean, standard deviation (same unit)."""

    mean: float
    std: float
    kind: ClassVar[str] = "normal"

    def __post_init__(self) -> None:
        if not self.std > 0.0:
            raise PneumafitInputError(f"normal prior: expected std > 0, found {self.std}")

    def logpdf(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        z = (np.asarray(value, dtype=float) - self.mean) / self.std
        return -0.5 * z * z - math.log(self.std * math.sqrt(2.0 * math.pi))

    def residual(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        return (np.asarray(value, dtype=float) - self.mean) / self.std

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "mean": _num(self.mean), "std": _num(self.std)}


@dataclass(frozen=True)
class LogNormal(Prior):
    """log(value) ~ Normal(log(median), sigma): a factor exp(sigma) per std."""

    median: float
    sigma: float
    kind: ClassVar[str] = "log-normal"

    def __post_init__(self) -> None:
        if not (self.median > 0.0 and self.sigma > 0.0):
            raise PneumafitInputError(
                f"log-normal prior: expected median > 0 and sigma > 0, found "
                f"{self.median}, {self.sigma}"
            )

    def logpdf(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.asarray(value, dtype=float)
        pos = v > 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            lv = np.log(np.where(pos, v, 1.0))
        z = (lv - math.log(self.median)) / self.sigma
        out = -0.5 * z * z - lv - math.log(self.sigma * math.sqrt(2.0 * math.pi))
        return np.where(pos, out, -np.inf)

    def residual(self, value: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.maximum(np.asarray(value, dtype=float), 1e-300)
        return (np.log(v) - math.log(self.median)) / self.sigma

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "median": _num(self.median), "sigma": _num(self.sigma)}


_PRIORS: dict[str, type[Prior]] = {
    cls.kind: cls for cls in (Uniform, LogUniform, Normal, LogNormal)
}


def prior_from_dict(data: Mapping[str, Any], where: str = "prior") -> Prior:
    """Inverse of ``Prior.as_dict``.

    Raises
    ------
    PneumafitInputError
        Unknown kind, missing or bad fields (message names ``where``).
    """
    if not isinstance(data, Mapping):
        raise PneumafitInputError(f"{where}: expected an object, found {data!r}")
    kind = data.get("kind")
    cls = _PRIORS.get(str(kind))
    if cls is None:
        raise PneumafitInputError(
            f"{where}.kind: expected one of {', '.join(_PRIORS)}, found {kind!r}"
        )
    names = [f for f in cls.__dataclass_fields__ if f != "kind"]
    try:
        args = {n: _float(data[n], f"{where}.{n}") for n in names}
    except KeyError as exc:
        raise PneumafitInputError(f"{where}: expected key {exc.args[0]!r}, found none") from None
    try:
        return cls(**args)
    except ValueError as exc:
        raise PneumafitInputError(f"{where}: {exc}") from None


# ---------------------------------------------------------------- parameter
@dataclass(frozen=True)
class NuisanceSpec:
    """Definition of a measurement (nuisance) parameter, like ParameterSpec."""

    name: str
    unit: str
    default: float
    lower: float
    upper: float
    scale: str
    description: str


#: Nuisance parameters of the measurement that the identification knows.
NUISANCE_SPECS: dict[str, NuisanceSpec] = {
    "temperature_sensor_lag": NuisanceSpec(
        "temperature_sensor_lag", "s", 0.3, 1e-3, 10.0, "log",
        "first-order time constant of the gas-temperature sensors",
    ),
}  # fmt: skip


@dataclass(frozen=True)
class Parameter:
    """One named parameter.

    Parameters
    ----------
    name : str
        Canonical name (``xi``, ``friction_static``, ``valve_C_supply``, ...).
    value : float
        Value in ``unit``: the start of a fit, then its point estimate.
    unit : str
        SI unit (pint syntax; "" for dimensionless).
    lower, upper : float
        Bounds of the value (inclusive); fits stay inside.
    scale : {"linear", "log"}
        Internal coordinate of optimisers and samplers: the value or its
        natural logarithm (log needs lower > 0).
    fixed : bool
        Held at ``value`` (not fitted).
    prior : Prior, optional
        Prior density of the value. Default: flat in the internal coordinate
        between the bounds (:class:`Uniform` for linear, :class:`LogUniform`
        for log scale).
    group : str
        ``rig``, ``valve``, ``heat``, ``friction``, ``effect``, ``numerics``
        or ``sensor`` (nuisance).
    description : str
        One line for tables.
    std : float or None
        After a fit: posterior standard deviation (MCMC) or its Laplace
        approximation (least squares), in ``unit``.
    interval_90 : (float, float) or None
        After a fit: central 90 % credible interval (5 % and 95 % quantiles).
    median : float or None
        After MCMC: posterior median.
    uncertainty : str or None
        Where ``std`` and ``interval_90`` come from: ``"mcmc"`` or
        ``"laplace"``.
    """

    name: str
    value: float
    unit: str = ""
    lower: float = -math.inf
    upper: float = math.inf
    scale: str = "linear"
    fixed: bool = False
    prior: Prior | None = None
    group: str = ""
    description: str = ""
    std: float | None = None
    interval_90: tuple[float, float] | None = None
    median: float | None = None
    uncertainty: str | None = None

    def __post_init__(self) -> None:
        where = f"parameter {self.name!r}"
        if not isinstance(self.name, str) or not self.name:
            raise PneumafitInputError(
                f"parameter: name: expected a non-empty string, found {self.name!r}"
            )
        if self.scale not in SCALES:
            raise PneumafitInputError(
                f"{where}: scale: expected one of {SCALES}, found {self.scale!r}"
            )
        if not self.lower <= self.upper:
            raise PneumafitInputError(
                f"{where}: bounds: expected lower <= upper, found [{self.lower}, {self.upper}]"
            )
        if self.scale == "log" and not self.lower > 0.0:
            raise PneumafitInputError(
                f"{where}: scale 'log': expected a lower bound > 0, found {self.lower:g}"
            )
        if not math.isfinite(self.value):
            raise PneumafitInputError(
                f"{where}: value: expected a finite number, found {self.value}"
            )
        if not self.lower <= self.value <= self.upper:
            raise PneumafitInputError(
                f"{where}: value: expected a value in [{self.lower:g}, {self.upper:g}] "
                f"{self.unit}, found {self.value:g}"
            )
        if self.interval_90 is not None:
            object.__setattr__(self, "interval_90", tuple(float(v) for v in self.interval_90))

    @property
    def effective_prior(self) -> Prior:
        """The prior, or the default flat one in the internal coordinate."""
        if self.prior is not None:
            return self.prior
        if self.scale == "log":
            return LogUniform(self.lower, self.upper)
        return Uniform(self.lower, self.upper)

    def to_internal(self, value: ArrayLike) -> NDArray[np.float64]:
        """Value(s) -> internal coordinate(s)."""
        v = np.asarray(value, dtype=float)
        return np.log(v) if self.scale == "log" else v

    def to_value(self, internal: ArrayLike) -> NDArray[np.float64]:
        """Internal coordinate(s) -> value(s)."""
        z = np.asarray(internal, dtype=float)
        if self.scale != "log":
            return z
        # a trial step far outside the bounds overflows to inf: the set is
        # then refused as out of bounds (-inf), not reported as a warning
        with np.errstate(over="ignore"):
            return np.exp(z)

    @property
    def internal_bounds(self) -> tuple[float, float]:
        """Bounds of the internal coordinate."""
        if self.scale == "log":
            return math.log(self.lower), (
                math.log(self.upper) if self.upper < math.inf else math.inf
            )
        return self.lower, self.upper

    def log_prior_internal(self, internal: ArrayLike) -> NDArray[np.float64]:
        """log density of the internal coordinate (prior plus log Jacobian)."""
        z = np.asarray(internal, dtype=float)
        value = self.to_value(z)
        lp = self.effective_prior.logpdf(value)
        lo, hi = self.lower, self.upper
        lp = np.where((value >= lo) & (value <= hi), lp, -np.inf)
        return lp + z if self.scale == "log" else lp

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (non-finite numbers as strings)."""
        out: dict[str, Any] = {
            "value": _num(self.value),
            "unit": self.unit,
            "lower": _num(self.lower),
            "upper": _num(self.upper),
            "scale": self.scale,
            "fixed": bool(self.fixed),
            "prior": None if self.prior is None else self.prior.as_dict(),
            "group": self.group,
            "description": self.description,
            "std": None if self.std is None else _num(self.std),
            "interval_90": None
            if self.interval_90 is None
            else [_num(v) for v in self.interval_90],
            "median": None if self.median is None else _num(self.median),
            "uncertainty": self.uncertainty,
        }
        return out

    @classmethod
    def from_dict(cls, name: str, data: Mapping[str, Any], where: str = "") -> Parameter:
        """Inverse of :meth:`as_dict`; ``where`` prefixes messages (file name).

        Raises
        ------
        PneumafitInputError
            Missing keys, wrong types, values out of bounds.
        """
        here = f"{where}parameters.{name}"
        if not isinstance(data, Mapping):
            raise PneumafitInputError(f"{here}: expected an object, found {data!r}")
        if "value" not in data:
            raise PneumafitInputError(f"{here}: expected key 'value', found none")
        kwargs: dict[str, Any] = {"name": name, "value": _float(data["value"], f"{here}.value")}
        for key in ("lower", "upper", "std", "median"):
            if data.get(key) is not None:
                kwargs[key] = _float(data[key], f"{here}.{key}")
        for key in ("unit", "scale", "group", "description", "uncertainty"):
            if data.get(key) is not None:
                if not isinstance(data[key], str):
                    raise PneumafitInputError(
                        f"{here}.{key}: expected a string, found {data[key]!r}"
                    )
                kwargs[key] = data[key]
        if "fixed" in data:
            if not isinstance(data["fixed"], bool):
                raise PneumafitInputError(
                    f"{here}.fixed: expected true or false, found {data['fixed']!r}"
                )
            kwargs["fixed"] = data["fixed"]
        if data.get("prior") is not None:
            kwargs["prior"] = prior_from_dict(data["prior"], f"{here}.prior")
        if data.get("interval_90") is not None:
            iv = data["interval_90"]
            if not isinstance(iv, list | tuple) or len(iv) != 2:
                raise PneumafitInputError(
                    f"{here}.interval_90: expected [lower, upper], found {iv!r}"
                )
            kwargs["interval_90"] = tuple(_float(v, f"{here}.interval_90") for v in iv)
        try:
            return cls(**kwargs)
        except ValueError as exc:
            raise PneumafitInputError(f"{here}: {exc}") from None


# ------------------------------------------------------------ parameter set
@dataclass
class ParameterSet:
    """Ordered collection of :class:`Parameter`, the single source of truth.

    Parameters
    ----------
    parameters : iterable of Parameter
        Names unique.
    correlation : (names, matrix), optional
        After a fit: posterior correlation matrix of the named (free)
        parameters' internal coordinates.

    Notes
    -----
    The free parameters, in set order, define the internal vector ``z``
    (:meth:`to_internal`, :meth:`to_values`) that optimisers and samplers
    move; fixed ones keep their value.
    """

    parameters: list[Parameter] = field(default_factory=list)
    correlation: tuple[tuple[str, ...], NDArray[np.float64]] | None = None

    def __post_init__(self) -> None:
        self.parameters = list(self.parameters)
        names = [p.name for p in self.parameters]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise PneumafitInputError(
                f"parameter set: expected unique names, found {dupes} repeated"
            )

    def __repr__(self) -> str:
        """One short line: counts and the first free parameters (see :meth:`summary`)."""
        free = self.free
        shown = ", ".join(f"{p.name}={p.value:.4g}" for p in free[:4])
        more = f", ... ({len(free) - 4} more)" if len(free) > 4 else ""
        return f"ParameterSet({len(self.parameters)} parameters, {len(free)} free" + (
            f": {shown}{more})" if free else ")"
        )

    def summary(self, *, free_only: bool = True) -> str:
        """A plain-text table: name, value, unit, 90 % interval, where it comes from.

        Parameters
        ----------
        free_only : bool
            Only the free parameters (default), else every one.
        """
        rows = [("parameter", "value", "unit", "90 % interval", "uncertainty")]
        for p in self.free if free_only else self.parameters:
            lo_hi = p.interval_90
            iv = "" if lo_hi is None else f"[{lo_hi[0]:.4g}, {lo_hi[1]:.4g}]"
            rows.append((p.name, f"{p.value:.6g}", p.unit, iv, p.uncertainty or ""))
        widths = [max(len(r[j]) for r in rows) for j in range(len(rows[0]))]
        return "\n".join(
            "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows
        )

    def to_dataframe(self, *, free_only: bool = False) -> Any:
        """The parameters as a :class:`pandas.DataFrame`, one row per parameter.

        Columns: ``value``, ``unit``, ``std``, ``interval_lower``,
        ``interval_upper`` (90 %), ``median``, ``uncertainty``, ``lower``,
        ``upper`` (bounds), ``fixed``, ``group``; index ``parameter``. Units
        as in :attr:`Parameter.unit` (SI).
        """
        import pandas as pd

        rows = []
        for p in self.free if free_only else self.parameters:
            lo, hi = p.interval_90 if p.interval_90 is not None else (math.nan, math.nan)
            rows.append({
                "parameter": p.name, "value": p.value, "unit": p.unit,
                "std": math.nan if p.std is None else p.std,
                "interval_lower": lo, "interval_upper": hi,
                "median": math.nan if p.median is None else p.median,
                "uncertainty": p.uncertainty or "", "lower": p.lower, "upper": p.upper,
                "fixed": p.fixed, "group": p.group,
            })  # fmt: skip
        return pd.DataFrame(rows).set_index("parameter")

    def _repr_html_(self) -> str:
        cols = ["value", "unit", "interval_lower", "interval_upper", "uncertainty"]
        return str(self.to_dataframe(free_only=True)[cols].to_html())

    # ---------------------------------------------------------- mapping view
    def __iter__(self) -> Iterator[Parameter]:
        return iter(self.parameters)

    def __len__(self) -> int:
        return len(self.parameters)

    def __contains__(self, name: object) -> bool:
        return any(p.name == name for p in self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"parameter set: no parameter {name!r} (have {', '.join(self.names)})")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ParameterSet):
            return NotImplemented
        if [p.as_dict() | {"name": p.name} for p in self] != [
            p.as_dict() | {"name": p.name} for p in other
        ]:
            return False
        if (self.correlation is None) != (other.correlation is None):
            return False
        if self.correlation is None or other.correlation is None:
            return True
        return self.correlation[0] == other.correlation[0] and np.array_equal(
            self.correlation[1], other.correlation[1], equal_nan=True
        )

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def free_names(self) -> tuple[str, ...]:
        """Names of the free parameters, in internal-vector order."""
        return tuple(p.name for p in self.parameters if not p.fixed)

    @property
    def free(self) -> list[Parameter]:
        return [p for p in self.parameters if not p.fixed]

    @property
    def n_free(self) -> int:
        return len(self.free_names)

    def values(self) -> dict[str, float]:
        """name -> value of every parameter."""
        return {p.name: p.value for p in self.parameters}

    def copy(self) -> ParameterSet:
        return ParameterSet(list(self.parameters), self.correlation)

    # ---------------------------------------------------------- edits
    def replace(self, name: str, **changes: Any) -> ParameterSet:
        """A copy with parameter ``name`` changed (``value=..., fixed=...``)."""
        out = []
        for p in self.parameters:
            out.append(replace(p, **changes) if p.name == name else p)
        if name not in self:
            raise KeyError(f"parameter set: no parameter {name!r}")
        return ParameterSet(out, self.correlation)

    def with_values(self, values: Mapping[str, float]) -> ParameterSet:
        """A copy with new values (clipped into the bounds)."""
        out = []
        for p in self.parameters:
            if p.name in values:
                v = float(np.clip(float(values[p.name]), p.lower, p.upper))
                p = replace(p, value=v)
            out.append(p)
        unknown = set(values) - set(self.names)
        if unknown:
            raise KeyError(f"parameter set: no parameters {sorted(unknown)}")
        return ParameterSet(out, self.correlation)

    def with_fixed(self, names: Iterable[str], fixed: bool = True) -> ParameterSet:
        """A copy with ``names`` fixed (or freed with ``fixed=False``)."""
        names = set(names)
        unknown = names - set(self.names)
        if unknown:
            raise KeyError(f"parameter set: no parameters {sorted(unknown)}")
        return ParameterSet(
            [replace(p, fixed=fixed) if p.name in names else p for p in self.parameters],
            self.correlation,
        )

    def only_free(self, names: Iterable[str]) -> ParameterSet:
        """A copy where exactly ``names`` are free (the others fixed)."""
        keep = set(names)
        unknown = keep - set(self.names)
        if unknown:
            raise KeyError(f"parameter set: no parameters {sorted(unknown)}")
        return ParameterSet([replace(p, fixed=p.name not in keep) for p in self.parameters], None)

    def add(self, parameter: Parameter) -> ParameterSet:
        """A copy with one more parameter (name must be new)."""
        return ParameterSet([*self.parameters, parameter], self.correlation)

    # ---------------------------------------------------------- transforms
    def to_internal(self, values: Mapping[str, float] | None = None) -> NDArray[np.float64]:
        """Internal vector z of the free parameters (from the set's values)."""
        vals = values or {}
        return np.array(
            [float(p.to_internal(vals.get(p.name, p.value))) for p in self.free], dtype=float
        )

    def to_values(self, z: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Internal vectors (n, n_free) or (n_free,) -> name -> values (n,) for all.

        Fixed parameters are broadcast to the batch size.
        """
        zz = np.atleast_2d(np.asarray(z, dtype=float))
        if zz.shape[1] != self.n_free:
            raise PneumafitInputError(
                f"parameter set: expected internal vectors of length {self.n_free}, "
                f"found shape {np.shape(z)}"
            )
        n = zz.shape[0]
        out: dict[str, NDArray[np.float64]] = {}
        j = 0
        for p in self.parameters:
            if p.fixed:
                out[p.name] = np.full(n, p.value)
            else:
                out[p.name] = p.to_value(zz[:, j])
                j += 1
        return out

    def internal_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lower, upper) of the internal coordinates of the free parameters."""
        b = [p.internal_bounds for p in self.free]
        return np.array([x[0] for x in b]), np.array([x[1] for x in b])

    def log_prior(self, z: ArrayLike) -> NDArray[np.float64]:
        """log prior density of internal vectors (n, n_free) -> (n,).

        Each free parameter's own prior, plus the joint priors of the laws
        with a free parameter here (:meth:`_joint_priors`: a valve law's
        smoothness prior, e.g. the measured map's; a friction law's
        breakaway prior).
        """
        zz = np.atleast_2d(np.asarray(z, dtype=float))
        total = np.zeros(zz.shape[0])
        for j, p in enumerate(self.free):
            total = total + p.log_prior_internal(zz[:, j])
        priors = self._joint_priors()
        if priors and np.any(np.isfinite(total)):
            with np.errstate(invalid="ignore", divide="ignore"):
                r = self._joint_residuals(zz, priors)
                total = total - 0.5 * np.sum(r * r, axis=1)
            total = np.where(np.isnan(total), -np.inf, total)
        return total

    def _joint_residuals(
        self, zz: NDArray[np.float64], priors: Sequence[Callable[[Mapping[str, Any]], Any]]
    ) -> NDArray[np.float64]:
        """Whitened residuals (n, n_terms) of the joint ``priors``
        (:meth:`_joint_priors`) at internal vectors (n, n_free); (n, 0)
        without one."""
        if not priors:
            return np.zeros((zz.shape[0], 0))
        values = self.to_values(zz)
        parts = [np.asarray(prior(values), dtype=float) for prior in priors]
        return np.concatenate([p.reshape(zz.shape[0], -1) for p in parts], axis=1)

    def _joint_priors(self) -> list[Callable[[Mapping[str, Any]], Any]]:
        """The joint priors of the laws all of whose parameters are in this
        set and one of them free: each valve law's smoothness prior
        (``ValveLaw.roughness``) and each friction law's joint prior
        (``FrictionLaw.joint_prior``), each prior once (the LuGre law shares
        the switch law's)."""
        free, names = set(self.free_names), set(self.names)
        laws = [(law.parameters, law.roughness) for law in VALVE_LAWS.values()] + [
            (law.parameters, law.joint_prior) for law in FRICTION_LAWS.values()
        ]
        chosen = [
            prior for parameters, prior in laws
            if prior is not None and free.intersection(parameters)
            and names.issuperset(parameters)
        ]  # fmt: skip
        return list(dict.fromkeys(chosen))

    def prior_residuals(self, z: ArrayLike) -> NDArray[np.float64]:
        """Whitened residuals of the Gaussian priors, each free parameter's
        and the laws' joint priors (:meth:`log_prior` is minus half their sum
        of squares, plus constants).

        Parameters
        ----------
        z : array_like (n_free,) or (n, n_free)
            Internal vectors.

        Returns
        -------
        ndarray (n_res,) or (n, n_res)
            One row per vector, in the shape of ``z``; one batch costs about
            one vector (the least-squares batches call it once).
        """
        arr = np.asarray(z, dtype=float)
        zz = np.atleast_2d(arr)
        res = []
        for j, p in enumerate(self.free):
            if p.prior is not None:
                r = p.prior.residual(p.to_value(zz[:, j]))
                if r is not None:
                    res.append(np.asarray(r, dtype=float).reshape(zz.shape[0], -1))
        res.append(self._joint_residuals(zz, self._joint_priors()))
        # C order, as rows stacked one by one. The least-squares residual
        # matrix takes its blocks' layout: a Fortran-ordered block (the map's
        # roughness is a transpose) made it Fortran-ordered and the Jacobian
        # C-ordered, and the solver's linear algebra, summing in another
        # order, took a map fit to another local optimum (the same values)
        out = np.ascontiguousarray(np.concatenate(res, axis=1))
        return out[0] if arr.ndim == 1 else out

    # ---------------------------------------------------------- (de)serialise
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ``{"format", "version", "parameters": {name: {...}}, ...}``."""
        out: dict[str, Any] = {
            "format": FORMAT,
            "version": VERSION,
            "parameters": {p.name: p.as_dict() for p in self.parameters},
        }
        if self.correlation is not None:
            names, matrix = self.correlation
            out["correlation"] = {
                "names": list(names),
                "matrix": [[_num(v) for v in row] for row in np.asarray(matrix)],
            }
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "") -> ParameterSet:
        """Inverse of :meth:`to_dict`. Also reads a ``fit.json`` (its parameters).

        Raises
        ------
        PneumafitInputError
            Messages name the key, what was expected and what was found.
        """
        if not isinstance(data, Mapping):
            raise PneumafitInputError(f"{where}expected a JSON object, found {type(data).__name__}")
        fmt = data.get("format")
        if fmt not in (FORMAT, "pneumafit-fit"):
            raise PneumafitInputError(
                f"{where}format: expected {FORMAT!r} or 'pneumafit-fit', found {fmt!r}"
            )
        params = data.get("parameters")
        if not isinstance(params, Mapping):
            raise PneumafitInputError(f"{where}parameters: expected an object, found {params!r}")
        plist = [Parameter.from_dict(str(name), d, where) for name, d in params.items()]
        correlation = None
        corr = data.get("correlation")
        if corr is not None:
            try:
                names = tuple(str(n) for n in corr["names"])
                matrix = np.array(
                    [
                        [_float(v, f"{where}correlation.matrix") for v in row]
                        for row in corr["matrix"]
                    ],
                    dtype=float,
                )
            except (KeyError, TypeError) as exc:
                raise PneumafitInputError(
                    f"{where}correlation: expected {{'names': [...], 'matrix': [[...]]}}, "
                    f"found {corr!r} ({exc})"
                ) from None
            if matrix.shape != (len(names), len(names)):
                raise PneumafitInputError(
                    f"{where}correlation.matrix: expected shape ({len(names)}, {len(names)}), "
                    f"found {matrix.shape}"
                )
            correlation = (names, matrix)
        try:
            return cls(plist, correlation)
        except ValueError as exc:
            raise PneumafitInputError(f"{where}{exc}") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n"

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the set as JSON, atomically."""
        write_text_atomic(path, self.to_json())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ParameterSet:
        """Read a set written by :meth:`save` (or the parameters of a fit.json).

        A fit.json is read by its one reader
        (:meth:`~pneumafit.identification.fitfile.SavedFit.from_document`):
        the model parameters (``parameters``) with the joint Laplace
        correlation.

        Raises
        ------
        PneumafitInputError
            Unreadable file, bad JSON, or bad content; the message names the file.
        """
        where = f"{os.fspath(path)}: "
        try:
            text = open(path, encoding="utf-8").read()
        except OSError as exc:
            raise PneumafitInputError(f"{where}expected a readable file, found {exc}") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise PneumafitInputError(f"{where}expected JSON, found an error: {exc}") from None
        if isinstance(data, Mapping) and data.get("format") == "pneumafit-fit":
            from pneumafit.identification.fitfile import SavedFit  # above this module

            return SavedFit.from_document(data, os.fspath(path)).parameters
        return cls.from_dict(data, where)

    # ---------------------------------------------------------- construction
    @classmethod
    def for_model(
        cls,
        model: str | ModelStructure = "convection",
        rig: Mapping[str, float] | None = None,
        *,
        free: Sequence[str] | None = None,
        nuisance: Sequence[str] = (),
    ) -> ParameterSet:
        """Every model parameter of a structure, with the fitting defaults.

        Rig parameters are fixed (values from ``rig``, e.g.
        ``campaign.rig.as_parameters()``); the valve, the structure's heat
        parameters and the friction parameters are free, except the valve's
        laminar onset ratio and full-opening command (not identifiable from
        commands that never exceed it: fixed at their defaults). Conductances,
        ``xi``, ``lambda``, the Stribeck velocity and friction coefficients
        are sampled in log scale; ``beta``, ``k``, critical ratios, the
        subsonic index and the overlap in linear scale. Effect parameters of
        the structure are included, fixed at their defaults. Friction
        parameters are those of the structure's friction law
        (:attr:`ModelStructure.friction_parameter_names`); the LuGre bristle
        stiffness (log scale) and damping (linear) are included fixed at
        their defaults (pass them in ``free`` to fit them; the staged fit
        frees them in its friction and joint stages).

        Values start at the :data:`PARAMETER_SPECS` defaults; the staged fit
        replaces them by data-driven starts (:mod:`.staged`).

        Parameters
        ----------
        model : str or ModelStructure
        rig : mapping, optional
            Rig parameter values (SI).
        free : sequence of str, optional
            Names to leave free (default as described above).
        nuisance : sequence of str
            Nuisance parameters to add (:data:`NUISANCE_SPECS`), free.
        """
        structure = get_structure(model)
        rig = dict(rig or {})
        heat_used = set(structure.parameter_names)
        default_free = set(DEFAULT_FREE_VALVE + _FRICTION) | (
            heat_used & {"xi", "beta", "lambda", "k"}
        )
        free_set = set(free) if free is not None else default_free
        values = {n: SPECS[n].default for n in PARAMETER_NAMES}
        values.update(rig)
        if "wall_temperature" not in rig and "ambient_temperature" in rig:
            values["wall_temperature"] = rig["ambient_temperature"]
        if "characteristic_length" not in rig and "bore" in rig:
            values["characteristic_length"] = rig["bore"]
        plist: list[Parameter] = []
        valve_used = set(structure.valve_parameter_names)
        friction_used = set(structure.friction_parameter_names)
        if structure.valve == "map" and free is None:
            free_set = (free_set - set(DEFAULT_FREE_VALVE)) | set(_map_free())
        elif VALVE_LAWS[structure.valve].kernel is not None and free is None:
            # a law from outside the package: its own parameters (group
            # "valve", registered with it) and the shared ones the ISO law fits
            free_set = (free_set - set(DEFAULT_FREE_VALVE)) | _outside_valve_free(structure.valve)
        for name in PARAMETER_NAMES:
            spec = SPECS[name]
            if spec.group == "heat" and name not in heat_used:
                continue
            if spec.group == "effect" and name not in heat_used:
                continue
            if spec.group in ("valve", "valve_map") and name not in valve_used:
                continue
            if spec.group == "friction" and name not in friction_used:
                continue
            scale = "log" if name in _LOG_SCALE or name.startswith(_MAP_C_PREFIX) else "linear"
            if P[name] >= NP and 0.0 < spec.lower and spec.upper >= _LOG_SPAN * spec.lower:
                scale = "log"  # a part's own parameter spanning decades (a conductance)
            lower, upper = _FIT_BOUNDS.get(name, (spec.lower, spec.upper))
            if name in _FORCE_BOUNDED:
                upper = min(upper, max(force_ceiling(values), 2.0 * lower))
            value = float(np.clip(values[name], lower, upper))
            plist.append(
                Parameter(
                    name=name, value=value, unit=spec.unit, lower=lower, upper=upper,
                    scale=scale, fixed=name not in free_set, group=spec.group,
                    description=spec.description,
                )
            )  # fmt: skip
        for name in nuisance:
            ns = NUISANCE_SPECS[name]
            plist.append(
                Parameter(
                    name=name, value=ns.default, unit=ns.unit, lower=ns.lower, upper=ns.upper,
                    scale=ns.scale, fixed=False, group="sensor", description=ns.description,
                )
            )  # fmt: skip
        return cls(plist)


#: ISO 6358 valve parameters held by default: x_laminar and u_sat are not
#: identifiable from flow tests whose commands stop at full scale.
_HELD_VALVE = ("valve_x_laminar", "valve_u_sat")
#: Valve parameters fitted by default (the valve stage's, stage a): the ISO
#: 6358 law's own list (:data:`pneumafit.models.structure.VALVE_PARAMETERS`)
#: without :data:`_HELD_VALVE`.
DEFAULT_FREE_VALVE: tuple[str, ...] = tuple(
    n for n in VALVE_PARAMETERS["iso6358"] if n not in _HELD_VALVE
)
_FRICTION = FRICTION_PARAMETERS["switch"]


def _outside_valve_free(valve: str) -> set[str]:
    """Parameters of a valve law from outside the package fitted by default:
    those of the group ``"valve"`` it names, less the held ones
    (:data:`_HELD_VALVE`, as for the ISO 6358 law)."""
    return {
        n for n in VALVE_LAWS[valve].parameters
        if SPECS[n].group == "valve" and n not in _HELD_VALVE
    }  # fmt: skip


#: Prefix of the valve map's knot conductances (log scale).
_MAP_C_PREFIX = ("valve_map_CS_", "valve_map_CE_")


def _map_free() -> tuple[str, ...]:
    """Valve-map parameters free by default: each path's knots from the centre
    (its leakage) to full opening, every critical-ratio knot and m. A path's
    knots on its closed side (|u| >= 0.1 u_sat away from opening) carry less
    than the centre leakage (the map is monotone), which no flow test
    resolves; they are held at their start."""
    from pneumafit.physics.valve_map import (
        MAP_BE_NAMES,
        MAP_BS_NAMES,
        MAP_CE_NAMES,
        MAP_CS_NAMES,
        MAP_KNOTS,
    )

    cs = [n for n, f in zip(MAP_CS_NAMES, MAP_KNOTS, strict=True) if f > -0.1]
    ce = [n for n, f in zip(MAP_CE_NAMES, MAP_KNOTS, strict=True) if f < 0.1]
    return (*cs, *ce, *MAP_BS_NAMES, *MAP_BE_NAMES, "valve_m")


#: Friction levels bounded by the actuator's largest force
#: (:func:`force_ceiling`).
_FORCE_BOUNDED = ("friction_static", "friction_coulomb")


def force_ceiling(values: Mapping[str, float]) -> float:
    """The largest force the actuator's air can exert (N): supply pressure on
    the whole bore, P_s pi D^2 / 4, with vacuum on the other side.

    A friction level above it would hold the piston against any command, so
    a rig whose recordings show it moving bounds its static and Coulomb
    friction by it. Without it a fit whose valve law misses the rig's could
    send the LuGre breakaway force to its generic bound (1e4 N against a
    32-mm bore's 560 N: table-valve-asym, sparse plan, seed 1), and the
    held-out steps stuck.
    """
    bore = float(values.get("bore", SPECS["bore"].default))
    return float(values.get("supply_pressure", SPECS["supply_pressure"].default)) * (
        math.pi * bore * bore / 4.0
    )


#: A parameter of a part from outside the package is sampled in log scale
#: when its bounds are positive and span this factor or more (two decades:
#: conductances, coefficients), as the table's own such parameters are.
_LOG_SPAN = 100.0
_LOG_SCALE = {
    "valve_C_supply", "valve_C_exhaust", "valve_C_leak", "valve_leak_width", "xi", "lambda",
    "friction_static", "friction_coulomb", "friction_viscous", "stribeck_velocity",
    "friction_stiffness",
}  # fmt: skip
#: Fit bounds narrower than the physical bounds of PARAMETER_SPECS where the
#: latter are open-ended or zero (log scale needs a positive lower bound).
#: They are wide: decades around any plausible cylinder of 8..100 mm bore.
_FIT_BOUNDS: dict[str, tuple[float, float]] = {
    "valve_C_supply": (1e-11, 1e-6),
    "valve_C_exhaust": (1e-11, 1e-6),
    "valve_C_leak": (1e-15, 1e-8),
    "valve_leak_width": (1e-3, 10.0),
    "valve_b_supply": (0.01, 0.9),
    "valve_b_exhaust": (0.01, 0.9),
    "valve_overlap": (0.0, 3.0),
    "valve_n_supply": (0.4, 3.0),
    "valve_n_exhaust": (0.4, 3.0),
    "valve_full_supply": (0.3, 1.0),
    "valve_full_exhaust": (0.3, 1.0),
    "valve_null_offset": (-0.25, 0.25),
    "valve_knee_supply": (1.0, 12.0),
    "valve_knee_exhaust": (1.0, 12.0),
    "xi": (1e-3, 10.0),
    "beta": (0.05, 0.6),
    "lambda": (0.01, 1e4),
    "heat_area_ends": (0.0, 3.0),
    "friction_static": (0.01, 1e4),
    "friction_coulomb": (0.01, 1e4),
    "friction_viscous": (0.01, 1e5),
    "stribeck_velocity": (1e-4, 1.0),
}
