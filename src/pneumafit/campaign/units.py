"""Unit parsing and conversion to SI, all through one pint registry.

Values in campaign files are a bare number (already SI) or a string with a
unit (``"32 mm"``, ``"6 bar"``, ``"20 degC"``). Units are parsed by pint; this
module only adds the notion of *quantity kind* (what a value must measure) and
of *gauge* pressure, which pint does not know.

Gauge notation (see ``docs/campaign-format.md``):

- a pressure unit followed by ``g`` that pint does not know as such:
  ``"barg"``, ``"psig"``, ``"kPag"``, ``"mbarg"``;
- any pressure unit followed by ``(gauge)``, ``(g)`` or the word ``gauge``:
  ``"bar (gauge)"``, ``"bar(g)"``, ``"psi gauge"``;
- in HDF5, the dataset attribute ``reference = "gauge"``.

Likewise a trailing ``a`` (``"bara"``, ``"psia"``), ``(absolute)`` or ``(a)`` says
explicitly that a pressure is absolute, which is the default anyway.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import pint
from numpy.typing import ArrayLike, NDArray

from pneumafit.campaign.errors import PneumafitInputError

__all__ = [
    "DISPLAY_UNITS",
    "QUANTITY_KINDS",
    "ParsedUnit",
    "QuantityKind",
    "UnitError",
    "describe_unit",
    "display_unit",
    "format_value",
    "from_si",
    "parse_quantity",
    "parse_unit",
    "parse_value",
    "split_header",
    "to_si",
    "ureg",
]

#: The one unit registry of the package.
ureg = pint.UnitRegistry()


@dataclass(frozen=True)
class QuantityKind:
    """What a value measures, and how to talk about it in messages.

    Parameters
    ----------
    name : str
        Kind name used in messages, e.g. ``"length"``.
    article : str
        ``"a"`` or ``"an"``.
    dimensionality : str
        pint dimensionality expression, e.g. ``"[length]"``.
    example : str
        An example value with a unit, e.g. ``"32 mm"``.
    si_unit : str
        The SI unit used inside the program, e.g. ``"m"``.
    """

    name: str
    article: str
    dimensionality: str
    example: str
    si_unit: str

    @property
    def expected(self) -> str:
        """Phrase for error messages, e.g. ``'a length (e.g. "32 mm")'``."""
        return f'{self.article} {self.name} (e.g. "{self.example}")'

    def matches(self, unit: pint.Unit) -> bool:
        """True when ``unit`` measures this kind of quantity."""
        return ureg.Quantity(1.0, unit).dimensionality == ureg.get_dimensionality(
            self.dimensionality
        )


#: Kinds of quantity found in campaigns, by name. Order matters for
#: :func:`describe_unit` (first match wins).
QUANTITY_KINDS: dict[str, QuantityKind] = {
    k.name: k
    for k in (
        QuantityKind("length", "a", "[length]", "32 mm", "m"),
        QuantityKind("volume", "a", "[length]**3", "20 cm^3", "m^3"),
        QuantityKind("mass", "a", "[mass]", "17 kg", "kg"),
        QuantityKind("pressure", "a", "[pressure]", "6 bar", "Pa"),
        QuantityKind("temperature", "a", "[temperature]", "20 degC", "K"),
        QuantityKind("time", "a", "[time]", "10 ms", "s"),
        QuantityKind("force", "a", "[force]", "50 N", "N"),
        QuantityKind("voltage", "a", "[electric_potential]", "10 V", "V"),
        QuantityKind("velocity", "a", "[velocity]", "0.5 m/s", "m/s"),
        QuantityKind("mass flow", "a", "[mass]/[time]", "5 g/s", "kg/s"),
        QuantityKind("proportional gain", "a", "[electric_potential]/[length]", "60 V/m", "V/m"),
        QuantityKind(
            "derivative gain", "a", "[electric_potential]*[time]/[length]", "4 V s/m", "V s/m"
        ),
        QuantityKind("angle", "an", "[]", "90 deg", "rad"),
        QuantityKind("frequency", "a", "1/[time]", "1 kHz", "Hz"),
    )
}


class UnitError(PneumafitInputError):
    """A value or unit could not be converted.

    Parameters
    ----------
    expected : str
        What was expected, e.g. ``'a length (e.g. "32 mm")'``.
    found : str
        What was found, e.g. ``'"6 bar" (a pressure)'``.
    """

    def __init__(self, expected: str, found: str) -> None:
        self.expected = expected
        self.found = found
        super().__init__(f"expected {expected}, found {found}")


@dataclass(frozen=True)
class ParsedUnit:
    """A unit string understood by pint, plus its pressure reference.

    Parameters
    ----------
    text : str
        The unit as written, e.g. ``"barg"``.
    unit : pint.Unit
        The pint unit without the gauge/absolute marker, e.g. ``bar``.
    gauge : bool
        True for a gauge pressure (the exhaust pressure is added to get an
        absolute pressure).
    plain_text : str
        The unit text without its gauge/absolute marker, e.g. ``"bar"``.
    """

    text: str
    unit: pint.Unit
    gauge: bool = False
    plain_text: str = ""


_REFERENCE_WORD = re.compile(
    r"^(?P<unit>.*?)\s*(?:\(\s*(?P<ref>gauge|absolute|g|a)\s*\)|\s(?P<word>gauge|absolute))$"
)
#: Short reference marks: ``"bar(g)"``, ``"psi (a)"`` (data sheets and loggers).
_REFERENCE_MARKS = {"g": "gauge", "a": "absolute"}
_NUMBER = re.compile(r"^\s*(?P<num>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)(?P<unit>.*)$")
_HEADER = re.compile(r"^\s*(?P<name>[^\[\]]*?)\s*\[(?P<unit>[^\[\]]*)\]\s*$")


#: Temperature units written as their symbol alone, which pint reads as others.
_NOT_DEGREES = {
    "C": '"C" is the coulomb: degrees Celsius are "degC" or "°C"',
    "F": '"F" is the farad: degrees Fahrenheit are "degF" or "°F"',
}


def _strip_reference(text: str) -> tuple[str, str | None]:
    """Split ``"bar (gauge)"``, ``"bar(g)"`` or ``"bar gauge"`` into ``("bar",
    "gauge")`` (likewise absolute, ``(a)``); no marker gives ``None``."""
    match = _REFERENCE_WORD.match(text.strip())
    if match and match["unit"]:
        ref = match["ref"] or match["word"]
        return match["unit"], _REFERENCE_MARKS.get(ref, ref)
    return text.strip(), None


def _pint_unit(text: str) -> pint.Unit | None:
    """pint's reading of ``text``, or None if pint cannot read it."""
    try:
        unit = ureg.parse_units(text)
    except Exception:  # pint raises several unrelated types on bad input
        return None
    return unit if isinstance(unit, pint.Unit) else None


def describe_unit(unit: pint.Unit) -> str:
    """Say in words what ``unit`` measures, e.g. ``"a pressure"``.

    Parameters
    ----------
    unit : pint.Unit
        Any pint unit.

    Returns
    -------
    str
        ``"a pressure"``, ``"a length"``, ... or the pint dimensionality when
        no known kind matches.
    """
    dims = ureg.Quantity(1.0, unit).dimensionality
    if not dims:
        return "a dimensionless number"
    for kind in QUANTITY_KINDS.values():
        if kind.name != "angle" and kind.matches(unit):
            return f"{kind.article} {kind.name}"
    return f"a quantity of dimension {dims}"


def parse_unit(text: str, kind: str | None = None) -> ParsedUnit:
    """Parse a unit string, optionally checking what it measures.

    Parameters
    ----------
    text : str
        Unit as written in a file: ``"mm"``, ``"bar"``, ``"barg"``,
        ``"bar (gauge)"``, ``"degC"``, ``"V s/m"``. An empty string means a
        dimensionless number.
    kind : str, optional
        Name of a :data:`QUANTITY_KINDS` entry the unit must measure.

    Returns
    -------
    ParsedUnit
        The pint unit and whether it is a gauge pressure.

    Raises
    ------
    UnitError
        Unknown unit, a unit of the wrong kind, or a gauge marker on something
        that is not a pressure.
    """
    expected_kind = QUANTITY_KINDS[kind] if kind is not None else None
    expected = expected_kind.expected if expected_kind else 'a unit (e.g. "bar", "mm")'
    body, reference = _strip_reference(text)
    unit = _pint_unit(body)
    if unit is None and reference is None and len(body) > 1 and body[-1] in "ga":
        candidate = _pint_unit(body[:-1])
        if candidate is not None and QUANTITY_KINDS["pressure"].matches(candidate):
            unit, reference = candidate, ("gauge" if body[-1] == "g" else "absolute")
            body = body[:-1]
    if unit is None:
        raise UnitError(expected, f'unit "{text}", which is not a known unit')
    if reference is not None and not QUANTITY_KINDS["pressure"].matches(unit):
        raise UnitError(expected, f'unit "{text}" ({reference} applies to pressures only)')
    if expected_kind is not None and not expected_kind.matches(unit):
        found = f'unit "{text}" ({describe_unit(unit)})'
        if expected_kind.name == "temperature" and body.strip() in _NOT_DEGREES:
            found += f"; {_NOT_DEGREES[body.strip()]}"
        raise UnitError(expected, found)
    return ParsedUnit(text=text.strip(), unit=unit, gauge=reference == "gauge", plain_text=body)


def _magnitude_to_si(values: NDArray[np.float64], unit: pint.Unit) -> NDArray[np.float64]:
    quantity = ureg.Quantity(values, unit).to_base_units()
    return np.asarray(quantity.magnitude, dtype=np.float64)


def to_si(
    values: ArrayLike, unit: ParsedUnit, *, exhaust_pressure: float | None = None
) -> NDArray[np.float64]:
    """Convert values written in ``unit`` to SI (absolute pressures).

    Parameters
    ----------
    values : array_like
        Values in the file's unit.
    unit : ParsedUnit
        Their unit (from :func:`parse_unit`).
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute], added to gauge pressures.

    Returns
    -------
    numpy.ndarray
        float64 values in SI base units (m, kg, s, K, Pa, V, ...).

    Raises
    ------
    UnitError
        A gauge unit with no exhaust pressure to refer it to.
    """
    si = _magnitude_to_si(np.asarray(values, dtype=np.float64), unit.unit)
    if unit.gauge:
        if exhaust_pressure is None:
            raise UnitError(
                "an absolute pressure (gauge pressures need a valid rig.exhaust_pressure)",
                f'unit "{unit.text}" (a gauge pressure)',
            )
        si = si + exhaust_pressure
    return si


def from_si(
    values: ArrayLike, unit: ParsedUnit, *, exhaust_pressure: float | None = None
) -> NDArray[np.float64]:
    """Convert SI values (absolute pressures) to ``unit``; inverse of :func:`to_si`.

    Parameters
    ----------
    values : array_like
        Values in SI base units.
    unit : ParsedUnit
        Target unit.
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute], subtracted for gauge units.

    Returns
    -------
    numpy.ndarray
        float64 values in ``unit``.
    """
    si = np.asarray(values, dtype=np.float64)
    if unit.gauge:
        if exhaust_pressure is None:
            raise UnitError("an exhaust pressure to write gauge pressures", f'unit "{unit.text}"')
        si = si - exhaust_pressure
    base = ureg.Quantity(1.0, unit.unit).to_base_units().units
    return np.asarray(ureg.Quantity(si, base).to(unit.unit).magnitude, dtype=np.float64)


def _shown(value: object) -> str:
    return f'"{value}"' if isinstance(value, str) else repr(value)


def parse_value(value: object, kind: str, *, exhaust_pressure: float | None = None) -> float:
    """Read one campaign.toml value as an SI float.

    Parameters
    ----------
    value : str or float or int
        A bare number (SI) or a string ``"<number> <unit>"``, e.g. ``"32 mm"``,
        ``"6 barg"``, ``"20 degC"``.
    kind : str
        Name of the :data:`QUANTITY_KINDS` entry the value must measure.
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute], the reference of gauge values. When
        None, a gauge value is an error.

    Returns
    -------
    float
        The value in SI units (pressures absolute, temperatures in K).

    Raises
    ------
    UnitError
        Not a number, unknown unit, wrong kind, or non-finite value.
    """
    expected_kind = QUANTITY_KINDS[kind]
    expected = expected_kind.expected
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise UnitError(expected, f"{_shown(value)} (a {type(value).__name__})")
    if isinstance(value, int | float):
        number = float(value)
        if not math.isfinite(number):
            raise UnitError(expected, f"{value!r} (not a finite number)")
        return number
    match = _NUMBER.match(value)
    if match is None:
        raise UnitError(expected, f'"{value}" (no number in front)')
    number = float(match["num"])
    unit_text = match["unit"].strip()
    if not unit_text:
        return number
    try:
        unit = parse_unit(unit_text, kind)
        return float(to_si(number, unit, exhaust_pressure=exhaust_pressure))
    except UnitError as exc:
        raise UnitError(exc.expected, f'"{value}" ({_reason(exc, unit_text)})') from None


def parse_quantity(value: str, si_unit: str, *, exhaust_pressure: float | None = None) -> float:
    """Read ``"<number> <unit>"`` as a float in ``si_unit``, as campaigns are read.

    The same reading as :func:`parse_value` (a space between number and unit
    is optional: ``"32mm"``; gauge pressures such as ``"7 barg"``), for
    quantities that are not one of :data:`QUANTITY_KINDS` (a heat-transfer
    coefficient in W/m^2/K, a conductance in m^3/(s Pa)): parameter files and
    command-line options.

    Parameters
    ----------
    value : str
        The value with its unit; no unit means a number already in ``si_unit``.
    si_unit : str
        Unit of the result, pint syntax or ``^`` for powers (``"W/m^2/K"``);
        ``""`` for a dimensionless number.
    exhaust_pressure : float, optional
        Exhaust pressure [Pa absolute], the reference of gauge pressures.

    Returns
    -------
    float

    Raises
    ------
    UnitError
        No number in front, an unknown unit, a unit of another dimension, a
        gauge pressure without a reference, or a non-finite value.
    """
    target = si_unit.replace("^", "**") if si_unit else "dimensionless"
    expected = f"a value in {si_unit or 'no unit'}"
    match = _NUMBER.match(value)
    if match is None:
        raise UnitError(expected, f'"{value}" (no number in front)')
    number = float(match["num"])
    unit_text = match["unit"].strip()
    if unit_text:
        try:
            unit = parse_unit(unit_text)
            number = float(to_si(number, unit, exhaust_pressure=exhaust_pressure))
            # to_si gives base units: convert them to the target (e.g. W, not kg m^2/s^3)
            base = ureg.Quantity(1.0, unit.unit).to_base_units().units
            number = float(ureg.Quantity(number, base).to(target).magnitude)
        except UnitError as exc:
            raise UnitError(expected, f'"{value}" ({_reason(exc, unit_text)})') from None
        except pint.errors.DimensionalityError:
            raise UnitError(
                expected, f'"{value}" ({describe_unit(unit.unit)}, not {si_unit or "a number"})'
            ) from None
    if not math.isfinite(number):
        raise UnitError(expected, f'"{value}" (not a finite number)')
    return number


def _reason(exc: UnitError, unit_text: str) -> str:
    """Short reason from a unit error, for a message quoting the whole value."""
    found = exc.found
    prefix = f'unit "{unit_text}" ('
    if found.startswith(prefix) and found.endswith(")"):
        return found[len(prefix) : -1]
    if "not a known unit" in found:
        return f'"{unit_text}" is not a known unit'
    return found


def format_value(value: float, kind: str) -> str:
    """Write an SI float as an exact, readable string, e.g. ``"0.032 m"``.

    Parameters
    ----------
    value : float
        Value in SI units.
    kind : str
        Name of its :data:`QUANTITY_KINDS` entry.

    Returns
    -------
    str
        ``repr(value)`` followed by the SI unit; :func:`parse_value` reads it
        back exactly.
    """
    return f"{float(value)!r} {QUANTITY_KINDS[kind].si_unit}"


def split_header(cell: str) -> tuple[str, str] | None:
    """Split a CSV header cell ``"p_P [bar]"`` into ``("p_P", "bar")``.

    Parameters
    ----------
    cell : str
        One header cell.

    Returns
    -------
    tuple of (str, str) or None
        Name and unit text, or None when the cell is not ``name [unit]``.
    """
    match = _HEADER.match(cell)
    if match is None or not match["name"]:
        return None
    return match["name"], match["unit"].strip()


#: The one display-unit table: every console table, report and figure shows a
#: quantity of this kind in this unit (factor from SI, unit). fit.json and
#: every other file keep SI.
DISPLAY_UNITS: dict[str, tuple[float, str]] = {
    "voltage": (1.0, "V"),
    "pressure": (1e-3, "kPa"),
    "temperature": (1.0, "K"),
    "length": (1e3, "mm"),
    "velocity": (1e3, "mm/s"),
    "mass flow": (1e3, "g/s"),
    "force": (1.0, "N"),
}
#: Quantity names used by the comparison's tables and figures, as kinds.
_QUANTITY_ALIASES = {"position": "length", "flow": "mass flow"}


def display_unit(name: str) -> tuple[float, str]:
    """Display factor from SI and unit of a channel, quantity or kind.

    Parameters
    ----------
    name : str
        A campaign channel (``"p_P"``), a comparison quantity (``"flow"``) or
        a kind of quantity (``"mass flow"``).

    Returns
    -------
    factor : float
        Multiply an SI value by it.
    unit : str
        The display unit; ``""`` (factor 1) for an unknown name.
    """
    from pneumafit.campaign.model import CHANNELS

    kind = CHANNELS.get(name) or _QUANTITY_ALIASES.get(name, name)
    return DISPLAY_UNITS.get(kind, (1.0, ""))
